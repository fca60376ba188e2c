//! Springs on the surface: what holds a part by a spring stiffness per area instead of removing
//! its DOFs — elastic mounts (rubber, a bolted flange's give), and the supports whose held
//! direction turns from node to node (sliding along a curved face, a bearing on a bore), held
//! by a stiff spring along the normal or the radial and axial directions.
//!
//! The energy of a spring field of stiffness k (N/m³) pulling the surface back along the
//! directions a projector P (3×3, symmetric) keeps is ½ ∫ k (Pu)·u dA; on each flat surface
//! triangle P is constant and u is interpolated by the triangle's own shape functions (3 corner
//! nodes, or 6 with the mid-edge nodes of a 10-node mesh), so the stiffness is k P ⊗ ∫ N Nᵀ dA:
//! the triangle's consistent mass matrix, exactly.

use crate::fem::element::Kind;
use crate::tet_mesh::{Mesh, TET10_EDGES};
use std::collections::HashMap;

/// A 3×3 block k·P·∫NₐN_b dA added to K between nodes `a` and `b` (`a ≥ b`: the lower triangle,
/// as the assembly stores K).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NodeSpring {
    /// Row node.
    pub a: u32,
    /// Column node (≤ `a`).
    pub b: u32,
    /// The block, row-major.
    pub block: [[f64; 3]; 3],
}

/// ∫ NₐN_b dA / A on a 3-node triangle.
const T3: [[f64; 3]; 3] = [
    [2.0 / 12.0, 1.0 / 12.0, 1.0 / 12.0],
    [1.0 / 12.0, 2.0 / 12.0, 1.0 / 12.0],
    [1.0 / 12.0, 1.0 / 12.0, 2.0 / 12.0],
];

/// ∫ NₐN_b dA / A on a flat 6-node triangle: corners 0, 1, 2, then the mid-edge nodes of the
/// edges 0–1, 1–2, 2–0.
const T6: [[f64; 6]; 6] = {
    let m = [
        [6.0, -1.0, -1.0, 0.0, -4.0, 0.0],
        [-1.0, 6.0, -1.0, 0.0, 0.0, -4.0],
        [-1.0, -1.0, 6.0, -4.0, 0.0, 0.0],
        [0.0, 0.0, -4.0, 32.0, 16.0, 16.0],
        [-4.0, 0.0, 0.0, 16.0, 32.0, 16.0],
        [0.0, -4.0, 0.0, 16.0, 16.0, 32.0],
    ];
    let mut out = [[0.0; 6]; 6];
    let mut i = 0;
    while i < 6 {
        let mut j = 0;
        while j < 6 {
            out[i][j] = m[i][j] / 180.0;
            j += 1;
        }
        i += 1;
    }
    out
};

/// A surface triangle's unit outward normal, centroid and area (on its corners).
pub fn triangle_frame(mesh: &Mesh, t: usize) -> ([f64; 3], [f64; 3], f64) {
    let [a, b, c] = mesh.surface[t].map(|v| mesh.nodes[v as usize]);
    let (u, v) = ([0, 1, 2].map(|k| b[k] - a[k]), [0, 1, 2].map(|k| c[k] - a[k]));
    let n = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    let twice = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    let centroid = [0, 1, 2].map(|k| (a[k] + b[k] + c[k]) / 3.0);
    (n.map(|x| x / twice.max(f64::MIN_POSITIVE)), centroid, 0.5 * twice)
}

/// The springs of `triangles` (indices into `mesh.surface`), stiffness `k` N/m³ (per area) along
/// `projector(normal, centroid)` of each triangle. Blocks of the same node pair are summed.
pub fn face_springs(
    mesh: &Mesh,
    triangles: &[usize],
    k: f64,
    projector: impl Fn([f64; 3], [f64; 3]) -> [[f64; 3]; 3],
) -> Vec<NodeSpring> {
    springs_of(mesh, triangles, k, |t| {
        let (n, c, _) = triangle_frame(mesh, t);
        let p = projector(n, c);
        move |_: u32, _: u32| p
    })
}

/// The springs of `triangles` holding each node along its own unit direction `dir(node)`
/// (stiffness `k` N/m³): energy ½ k ∫ (d·u)² dA with d·u interpolated from the nodes' d_a·u_a,
/// so a motion every node makes across its own direction (a shaft turning in its bearing, a
/// face sliding along a curved surface) stretches no spring at all — a direction per triangle
/// would, on a faceted surface.
pub fn face_springs_along(mesh: &Mesh, triangles: &[usize], k: f64, dir: impl Fn(u32) -> [f64; 3]) -> Vec<NodeSpring> {
    springs_of(mesh, triangles, k, |_| {
        let dir = &dir;
        move |a: u32, b: u32| {
            let (da, db) = (dir(a), dir(b));
            std::array::from_fn(|r| std::array::from_fn(|c| da[r] * db[c]))
        }
    })
}

/// A spring of stiffness `k` (N/m) on the mean displacement of `nodes` along the unit
/// direction `dir`: energy ½ k (Σ d·u_a / n)², coupling every pair of them. What locates a bearing
/// axially without holding its tilt: a ring of nodes turned about a transverse axis moves
/// forward on one side as much as back on the other, so their mean does not move.
pub fn mean_along(nodes: &[u32], dir: [f64; 3], k: f64) -> Vec<NodeSpring> {
    let mut nodes = nodes.to_vec();
    nodes.sort_unstable();
    nodes.dedup();
    let w = k / (nodes.len().max(1) as f64).powi(2);
    let block: [[f64; 3]; 3] = std::array::from_fn(|r| std::array::from_fn(|c| w * dir[r] * dir[c]));
    // Every pair a ≥ b once, in the order `sorted` gives: the diagonal block of (Σu)² is u_a²,
    // the off-diagonal pairs 2·u_a·u_b, half of it in each of K's two triangles.
    let mut out: Vec<NodeSpring> = nodes
        .iter()
        .enumerate()
        .flat_map(|(i, &a)| nodes[..=i].iter().map(move |&b| NodeSpring { a, b, block }))
        .collect();
    out.sort_by_key(|s| (s.b, s.a));
    out
}

/// k·A·∫NₐN_b dA/A · `direction(t)(a, b)` summed over `triangles` for every node pair (a ≥ b)
/// of each: the one assembly of both kinds of spring.
fn springs_of<F: Fn(u32, u32) -> [[f64; 3]; 3]>(
    mesh: &Mesh,
    triangles: &[usize],
    k: f64,
    direction: impl Fn(usize) -> F,
) -> Vec<NodeSpring> {
    let mids = mid_nodes(mesh);
    let mut sum: HashMap<(u32, u32), [[f64; 3]; 3]> = HashMap::new();
    for &t in triangles {
        let (_, _, area) = triangle_frame(mesh, t);
        let (nodes, weights) = triangle_nodes(&mids, mesh.surface[t]);
        let along = direction(t);
        for (i, &a) in nodes.iter().enumerate() {
            for (j, &b) in nodes.iter().enumerate() {
                if a < b {
                    continue;
                }
                let w = k * area * weights[i][j];
                let p = along(a, b);
                let block = sum.entry((a, b)).or_insert([[0.0; 3]; 3]);
                for r in 0..3 {
                    for c in 0..3 {
                        block[r][c] += w * p[r][c];
                    }
                }
            }
        }
    }
    sorted(sum)
}

/// A surface triangle's nodes (its mid-edge nodes too on a 10-node mesh) and ∫ NₐN_b dA / A.
pub fn triangle_nodes(mids: &HashMap<(u32, u32), u32>, [v0, v1, v2]: [u32; 3]) -> (Vec<u32>, Vec<Vec<f64>>) {
    let mid = |a: u32, b: u32| mids.get(&(a.min(b), a.max(b))).copied();
    match (mid(v0, v1), mid(v1, v2), mid(v2, v0)) {
        (Some(m01), Some(m12), Some(m20)) => (vec![v0, v1, v2, m01, m12, m20], T6.iter().map(|r| r.to_vec()).collect()),
        _ => (vec![v0, v1, v2], T3.iter().map(|r| r.to_vec()).collect()),
    }
}

/// The summed blocks in a fixed order: the assembly's sums must not depend on a hash map's.
fn sorted(sum: HashMap<(u32, u32), [[f64; 3]; 3]>) -> Vec<NodeSpring> {
    let mut out: Vec<NodeSpring> = sum
        .into_iter()
        .map(|((a, b), block)| NodeSpring { a, b, block })
        .collect();
    out.sort_by_key(|s| (s.b, s.a));
    out
}

/// The mid-edge node of each edge of a 10-node mesh, by its corner pair (smaller first); empty
/// for a 4-node mesh.
pub fn mid_nodes(mesh: &Mesh) -> HashMap<(u32, u32), u32> {
    let mut out = HashMap::new();
    if mesh.kind != Kind::Tet10 {
        return out;
    }
    for e in 0..mesh.tet_count() {
        let t = mesh.tet(e);
        for (k, (a, b)) in TET10_EDGES.iter().enumerate() {
            let (a, b) = (t[*a], t[*b]);
            out.insert((a.min(b), a.max(b)), t[4 + k]);
        }
    }
    out
}

/// ½ uᵀK_s u for each pair of the six rigid motions, `at(node)` giving their displacements
/// there (row r: motion r): the Gram matrix whose rank is the number of rigid motions the
/// springs hold.
pub fn rigid_gram(springs: &[NodeSpring], at: impl Fn(usize) -> [[f64; 3]; 6]) -> [[f64; 6]; 6] {
    // xᵀ B y for a spring's 3×3 block B.
    let form = |x: &[f64; 3], b: &[[f64; 3]; 3], y: &[f64; 3]| -> f64 {
        x.iter()
            .zip(b)
            .map(|(xr, row)| xr * row.iter().zip(y).map(|(bc, yc)| bc * yc).sum::<f64>())
            .sum()
    };
    let mut g = [[0.0; 6]; 6];
    for s in springs {
        let (ma, mb) = (at(s.a as usize), at(s.b as usize));
        for p in 0..6 {
            for q in 0..6 {
                // The block couples a's DOFs (rows) to b's (columns), and b's to a's by symmetry.
                let mut v = form(&ma[p], &s.block, &mb[q]);
                if s.a != s.b {
                    v += form(&ma[q], &s.block, &mb[p]);
                }
                g[p][q] += v;
            }
        }
    }
    g
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The springs of a face, summed, hold a rigid translation with k·A along the kept
    /// directions (the matrices integrate the shape functions' products exactly), for both
    /// element kinds.
    #[test]
    fn springs_integrate_to_k_times_area() {
        for kind in [Kind::Tet4, Kind::Tet10] {
            let mesh = Mesh::structured_box([4, 2, 1], 0.25, kind, |_, p| p);
            let top: Vec<usize> = (0..mesh.surface.len())
                .filter(|&t| triangle_frame(&mesh, t).0[2] > 0.99)
                .collect();
            let area: f64 = top.iter().map(|&t| triangle_frame(&mesh, t).2).sum();
            assert!((area - 0.5).abs() < 1e-12, "{kind:?}: {area}");
            let springs = face_springs(&mesh, &top, 1e6, |n, _| {
                std::array::from_fn(|r| std::array::from_fn(|c| n[r] * n[c]))
            });
            let g = rigid_gram(&springs, |i| {
                crate::rigid_motions::rigid_at(mesh.nodes[i], [0.0; 3], 1.0)
            });
            assert!((g[2][2] - 1e6 * 0.5).abs() < 1e-6, "{kind:?}: {}", g[2][2]);
            assert!(g[0][0].abs() < 1e-6 && g[1][1].abs() < 1e-6, "{kind:?}");
        }
    }
}
