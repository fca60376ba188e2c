//! 10-node quadratic tetrahedron, gmsh node order: vertices 0–3, then mid-edge nodes on the
//! edges 0-1, 1-2, 2-0, 3-0, 3-2, 3-1.

use super::Shape;
use crate::fem::quadrature::{self, Point};

/// Vertex pairs of the mid-edge nodes 4..9 (the mesh's node order, gmsh's).
pub use crate::tet_mesh::TET10_EDGES as EDGES;

/// Quadratic tetrahedron.
pub struct Tet10;

impl Shape for Tet10 {
    const NODES: usize = 10;
    fn values(l: [f64; 4], n: &mut [f64]) {
        for a in 0..4 {
            n[a] = l[a] * (2.0 * l[a] - 1.0);
        }
        for (k, (a, b)) in EDGES.iter().enumerate() {
            n[4 + k] = 4.0 * l[*a] * l[*b];
        }
    }
    fn bary_gradients(l: [f64; 4], g: &mut [[f64; 4]]) {
        for ga in g.iter_mut() {
            *ga = [0.0; 4];
        }
        for a in 0..4 {
            g[a][a] = 4.0 * l[a] - 1.0;
        }
        for (k, (a, b)) in EDGES.iter().enumerate() {
            g[4 + k][*a] = 4.0 * l[*b];
            g[4 + k][*b] = 4.0 * l[*a];
        }
    }
    fn stiffness_rule() -> Vec<Point> {
        quadrature::degree2()
    }
    fn mass_rule() -> Vec<Point> {
        quadrature::degree5()
    }
    /// Degree 2 is exact only while J is constant. On a curved tet (mid-edge nodes off their
    /// edge midpoints, as gmsh places them on curved faces) the degree-5 rule brings the
    /// frequencies to within ~1e-7 of a converged integration (scikit-fem at order 8 on the
    /// corpus' PMI block), where degree 2 was 6e-5 low.
    fn curved_stiffness_rule(x: &[[f64; 3]]) -> Option<Vec<Point>> {
        crate::tet_mesh::is_curved(x).then(quadrature::degree5)
    }
}
