//! Validity of curved 10-node tets. gmsh's order-2 step puts mid-edge nodes on curved faces, and
//! on holes and fillets that can turn a thin element inside out. The measure is gmsh's "scaled
//! Jacobian": the smallest det J over the element divided by det J of the straight tet on the
//! same corners (1 for a straight tet, ≤ 0 inverted).

use super::{Mesh, TET10_EDGES};
use nalgebra::{Matrix3, Vector3};

/// Below this scaled Jacobian a curved tet is repaired: inverted (≤ 0) or so distorted that
/// its stiffness would be meaningless.
pub const MIN_SCALED_JACOBIAN: f64 = 0.1;

/// Barycentric sample points: the order-4 lattice (35 points, vertices, edges, faces and
/// interior) and the centroid.
fn samples() -> impl Iterator<Item = [f64; 4]> {
    const N: usize = 4;
    let lattice = (0..=N).flat_map(|i| {
        (0..=N - i).flat_map(move |j| {
            (0..=N - i - j).map(move |k| {
                let l = N - i - j - k;
                [i, j, k, l].map(|v| v as f64 / N as f64)
            })
        })
    });
    lattice.chain(std::iter::once([0.25; 4]))
}

/// det J of a 10-node tet (gmsh node order) at barycentric point `l`.
fn det_j(x: &[[f64; 3]], l: [f64; 4]) -> f64 {
    // ∂N/∂L: corner a: (4L_a − 1) e_a; mid-edge (a, b): 4(L_b e_a + L_a e_b). ∂/∂ξ_k = ∂/∂L_{k+1} − ∂/∂L_0.
    let mut j = Matrix3::<f64>::zeros();
    let mut add = |xa: [f64; 3], dl: [f64; 4]| {
        let d = Vector3::new(dl[1] - dl[0], dl[2] - dl[0], dl[3] - dl[0]);
        j += Vector3::from(xa) * d.transpose();
    };
    for a in 0..4 {
        let mut dl = [0.0; 4];
        dl[a] = 4.0 * l[a] - 1.0;
        add(x[a], dl);
    }
    for (e, &(a, b)) in TET10_EDGES.iter().enumerate() {
        let mut dl = [0.0; 4];
        dl[a] = 4.0 * l[b];
        dl[b] = 4.0 * l[a];
        add(x[4 + e], dl);
    }
    j.determinant()
}

pub use super::is_curved;

/// Smallest det J over the element relative to the straight tet's; 1 for a straight tet.
pub fn min_scaled_jacobian(x: &[[f64; 3]]) -> f64 {
    let v = |i: usize| Vector3::from(x[i]);
    let straight = (v(1) - v(0)).dot(&(v(2) - v(0)).cross(&(v(3) - v(0))));
    if straight <= 0.0 || !straight.is_finite() {
        return f64::NEG_INFINITY;
    }
    samples().map(|l| det_j(x, l) / straight).fold(f64::INFINITY, f64::min)
}

impl Mesh {
    /// Node coordinates of tet `t`, in its node order.
    fn tet_coords(&self, t: usize) -> Vec<[f64; 3]> {
        self.tet(t).iter().map(|&n| self.nodes[n as usize]).collect()
    }

    /// The 10-node tets with a mid-edge node off its edge's midpoint (see [`is_curved`]).
    pub fn curved_tets(&self) -> Vec<usize> {
        if self.kind != super::Kind::Tet10 {
            return Vec::new();
        }
        (0..self.tet_count())
            .filter(|&t| is_curved(&self.tet_coords(t)))
            .collect()
    }

    /// The curved tets whose scaled Jacobian is below `min` (none for 4-node meshes).
    pub fn distorted_tets(&self, min: f64) -> Vec<usize> {
        if self.kind != super::Kind::Tet10 {
            return Vec::new();
        }
        (0..self.tet_count())
            .filter(|&t| min_scaled_jacobian(&self.tet_coords(t)) < min)
            .collect()
    }

    /// Straightens the mid-edge nodes of every tet below `min` (each moves to the midpoint of
    /// its edge; a neighbour sharing that edge becomes straighter there), repeating until every
    /// tet passes. A straight 10-node tet has the scaled Jacobian of its corner tet (positive),
    /// so this always ends. Returns the number of tets straightened; the price is a faceted
    /// surface at those elements.
    pub fn straighten_distorted(&mut self, min: f64) -> usize {
        let mut straightened = std::collections::BTreeSet::new();
        for _ in 0..self.tet_count().max(1) {
            let bad = self.distorted_tets(min);
            if bad.is_empty() {
                break;
            }
            for t in bad {
                let tet: Vec<u32> = self.tet(t).to_vec();
                for (e, &(a, b)) in TET10_EDGES.iter().enumerate() {
                    let (pa, pb) = (self.nodes[tet[a] as usize], self.nodes[tet[b] as usize]);
                    self.nodes[tet[4 + e] as usize] = std::array::from_fn(|c| (pa[c] + pb[c]) / 2.0);
                }
                straightened.insert(t);
            }
        }
        straightened.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn straight_tets_score_one_and_a_folded_mid_edge_node_scores_below_zero() {
        let mut m = Mesh::structured_box([1, 1, 1], 1.0, ves_format::ElementKind::Tet10, |_, p| p);
        assert!(m.distorted_tets(0.999).is_empty(), "straight tets score 1");
        // Push one mid-edge node far across its tet: the element folds over.
        let t = 0;
        let tet = m.tet(t).to_vec();
        let (a, b) = TET10_EDGES[0];
        let (pa, pb, opposite) = (
            m.nodes[tet[a] as usize],
            m.nodes[tet[b] as usize],
            m.nodes[tet[3] as usize],
        );
        m.nodes[tet[4] as usize] = std::array::from_fn(|c| (pa[c] + pb[c]) / 2.0 + 1.5 * (opposite[c] - pa[c]));
        assert!(min_scaled_jacobian(&m.tet_coords(t)) < 0.0);
        assert!(m.distorted_tets(MIN_SCALED_JACOBIAN).contains(&t));
        let n = m.straighten_distorted(MIN_SCALED_JACOBIAN);
        assert!(n >= 1);
        assert!(m.distorted_tets(MIN_SCALED_JACOBIAN).is_empty());
        // Straightened exactly back to the midpoint.
        let mid: [f64; 3] = std::array::from_fn(|c| (pa[c] + pb[c]) / 2.0);
        assert_eq!(m.nodes[tet[4] as usize], mid);
    }

    #[test]
    fn a_gently_curved_edge_stays_valid() {
        let mut m = Mesh::structured_box([1, 1, 1], 1.0, ves_format::ElementKind::Tet10, |_, p| p);
        let tet = m.tet(0).to_vec();
        let p = m.nodes[tet[4] as usize];
        m.nodes[tet[4] as usize] = [p[0] + 0.02, p[1] + 0.02, p[2] - 0.02];
        assert!(m.distorted_tets(MIN_SCALED_JACOBIAN).is_empty());
    }
}
