//! 4-node linear tetrahedron: N_a = L_a.

use super::Shape;
use crate::fem::quadrature::{self, Point};

/// Linear tetrahedron.
pub struct Tet4;

impl Shape for Tet4 {
    const NODES: usize = 4;
    fn values(l: [f64; 4], n: &mut [f64]) {
        n.copy_from_slice(&l);
    }
    fn bary_gradients(_l: [f64; 4], g: &mut [[f64; 4]]) {
        for (a, ga) in g.iter_mut().enumerate() {
            *ga = [0.0; 4];
            ga[a] = 1.0;
        }
    }
    fn stiffness_rule() -> Vec<Point> {
        quadrature::degree1()
    }
    fn mass_rule() -> Vec<Point> {
        quadrature::degree2()
    }
}
