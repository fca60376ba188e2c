//! State transfer between modal spaces of one part (VOI switching; docs/format.md): the matrix
//! T = Φ_bᵀ M_b I_{a→b} Φ_a maps modal coordinates of space a to those of space b, where I_{a→b}
//! evaluates a's finite-element field (its own shape functions) at b's nodes. It is the
//! M_b-orthogonal projection of a's displacement onto b's modes — the best b can represent in
//! its energy-consistent norm — computed offline, so a switch at run time is an r×r product.

use crate::fem::Dofs;
use crate::fem::element::{Shape, tet4::Tet4, tet10::Tet10};
use crate::linsolve::sym_matmul;
use crate::tet_mesh::Mesh;
use faer::sparse::SymbolicSparseColMat;
use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

/// One space as the transfer sees it.
pub struct SpaceView<'a> {
    /// Mesh.
    pub mesh: &'a Mesh,
    /// DOF numbering.
    pub dofs: &'a Dofs,
    /// Modes on the free DOFs, column-major `free × r`.
    pub modes: &'a [f64],
    /// Number of modes.
    pub r: usize,
    /// Mass matrix pattern (lower triangle, free DOFs).
    pub pattern: &'a SymbolicSparseColMat<usize>,
    /// Mass matrix values.
    pub m: &'a [f64],
}

impl<'a> SpaceView<'a> {
    /// The first `r` (at most all) of `modes` on `mesh`, with `system`'s mass matrix.
    pub fn of(
        mesh: &'a Mesh,
        dofs: &'a Dofs,
        system: &'a crate::fem::Assembled,
        modes: &'a crate::modes::Modes,
        r: usize,
    ) -> SpaceView<'a> {
        SpaceView {
            mesh,
            dofs,
            modes: &modes.vectors,
            r: r.min(modes.eigenvalues.len()),
            pattern: &system.pattern,
            m: &system.m,
        }
    }
}

/// Where each node of one mesh lies in the tets of another.
pub struct Interpolation {
    /// Per target node: the source tet and the barycentric coordinates in it.
    pub at: Vec<(usize, [f64; 4])>,
    /// Largest distance, in barycentric units, of a target node outside its source tet (0 when
    /// every node is inside; small positive values come from curved boundaries meshed apart).
    pub worst_outside: f64,
}

/// Uniform grid over the tets' bounding boxes, for point location.
struct Grid {
    lo: [f64; 3],
    cell: f64,
    dims: [usize; 3],
    start: Vec<usize>,
    items: Vec<u32>,
}

impl Grid {
    fn new(mesh: &Mesh) -> Grid {
        let (lo, hi) = mesh.bounding_box();
        let m = mesh.tet_count().max(1);
        let vol = (0..3).map(|c| (hi[c] - lo[c]).max(1e-12)).product::<f64>();
        // About two tets per cell.
        let cell = (vol / m as f64 * 2.0).cbrt().max(1e-12);
        let dims: [usize; 3] = std::array::from_fn(|c| (((hi[c] - lo[c]) / cell).ceil() as usize).clamp(1, 512));
        let ncell = dims[0] * dims[1] * dims[2];
        let ranges: Vec<([usize; 3], [usize; 3])> = (0..mesh.tet_count())
            .map(|e| {
                let t = mesh.tet(e);
                let (mut a, mut b) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
                for &v in &t[..4] {
                    for c in 0..3 {
                        a[c] = a[c].min(mesh.nodes[v as usize][c]);
                        b[c] = b[c].max(mesh.nodes[v as usize][c]);
                    }
                }
                let ia = std::array::from_fn(|c| Self::index(lo[c], cell, dims[c], a[c]));
                let ib = std::array::from_fn(|c| Self::index(lo[c], cell, dims[c], b[c]));
                (ia, ib)
            })
            .collect();
        let mut count = vec![0usize; ncell + 1];
        let flat = |i: [usize; 3]| (i[2] * dims[1] + i[1]) * dims[0] + i[0];
        let each = |(a, b): &([usize; 3], [usize; 3]), f: &mut dyn FnMut(usize)| {
            for z in a[2]..=b[2] {
                for y in a[1]..=b[1] {
                    for x in a[0]..=b[0] {
                        f(flat([x, y, z]));
                    }
                }
            }
        };
        for r in &ranges {
            each(r, &mut |c| count[c + 1] += 1);
        }
        for i in 0..ncell {
            count[i + 1] += count[i];
        }
        let mut fill = count.clone();
        let mut items = vec![0u32; count[ncell]];
        for (e, r) in ranges.iter().enumerate() {
            each(r, &mut |c| {
                items[fill[c]] = e as u32;
                fill[c] += 1;
            });
        }
        Grid {
            lo,
            cell,
            dims,
            start: count,
            items,
        }
    }

    fn index(lo: f64, cell: f64, dim: usize, x: f64) -> usize {
        (((x - lo) / cell).floor().max(0.0) as usize).min(dim - 1)
    }

    /// Tets whose boxes meet the cells within `ring` of the cell holding `p`.
    fn candidates(&self, p: [f64; 3], ring: usize, mut f: impl FnMut(u32)) {
        let i: [usize; 3] = std::array::from_fn(|c| Self::index(self.lo[c], self.cell, self.dims[c], p[c]));
        let lo: [usize; 3] = std::array::from_fn(|c| i[c].saturating_sub(ring));
        let hi: [usize; 3] = std::array::from_fn(|c| (i[c] + ring).min(self.dims[c] - 1));
        for z in lo[2]..=hi[2] {
            for y in lo[1]..=hi[1] {
                for x in lo[0]..=hi[0] {
                    let c = (z * self.dims[1] + y) * self.dims[0] + x;
                    self.items[self.start[c]..self.start[c + 1]].iter().for_each(|&e| f(e));
                }
            }
        }
    }
}

/// Barycentric coordinates of `p` in the straight tet of corners `x`.
fn barycentric(x: [[f64; 3]; 4], p: [f64; 3]) -> [f64; 4] {
    let o = Vector3::from(x[0]);
    let d: [Vector3<f64>; 3] = std::array::from_fn(|k| Vector3::from(x[k + 1]) - o);
    let r = Vector3::from(p) - o;
    // Cramer's rule: each coordinate is a ratio of volumes.
    let det = |a: &Vector3<f64>, b: &Vector3<f64>, c: &Vector3<f64>| Matrix3::from_columns(&[*a, *b, *c]).determinant();
    let v = det(&d[0], &d[1], &d[2]);
    if v.abs() < 1e-300 {
        return [f64::NEG_INFINITY; 4];
    }
    let l1 = det(&r, &d[1], &d[2]) / v;
    let l2 = det(&d[0], &r, &d[2]) / v;
    let l3 = det(&d[0], &d[1], &r) / v;
    [1.0 - l1 - l2 - l3, l1, l2, l3]
}

/// Locates every node of `target` in the tets of `source`.
pub fn locate(source: &Mesh, target: &Mesh) -> Interpolation {
    let grid = Grid::new(source);
    let at: Vec<(usize, [f64; 4], f64)> = target
        .nodes
        .par_iter()
        .map(|&p| {
            let mut best = (0usize, [0.25; 4], f64::NEG_INFINITY);
            // Widen the search until a containing tet is found (or give the least-outside one).
            for ring in [0usize, 1, 3, 8] {
                grid.candidates(p, ring, |e| {
                    let t = source.tet(e as usize);
                    let x = std::array::from_fn(|k| source.nodes[t[k] as usize]);
                    let l = barycentric(x, p);
                    let worst = l.iter().copied().fold(f64::INFINITY, f64::min);
                    if worst > best.2 {
                        best = (e as usize, l, worst);
                    }
                });
                if best.2 >= -1e-9 {
                    break;
                }
            }
            best
        })
        .collect();
    let worst_outside = at.iter().map(|a| (-a.2).max(0.0)).fold(0.0, f64::max);
    // Outside nodes: clamp to the tet (project the barycentrics onto the simplex, roughly).
    let at = at
        .into_iter()
        .map(|(e, l, _)| {
            let c = l.map(|v| v.max(0.0));
            let s: f64 = c.iter().sum();
            (e, c.map(|v| v / s))
        })
        .collect();
    Interpolation { at, worst_outside }
}

/// The field `values` (3 per node of `source`, full numbering) evaluated at the target nodes.
pub fn interpolate(source: &Mesh, interp: &Interpolation, values: &[f64], out: &mut [f64]) {
    let mut n = [0.0; 10];
    for (i, &(e, l)) in interp.at.iter().enumerate() {
        let t = source.tet(e);
        let nodes = if source.kind == crate::fem::element::Kind::Tet10 {
            Tet10::values(l, &mut n);
            10
        } else {
            Tet4::values(l, &mut n[..4]);
            4
        };
        for c in 0..3 {
            out[3 * i + c] = (0..nodes).map(|a| n[a] * values[3 * t[a] as usize + c]).sum();
        }
    }
}

/// T (row-major `b.r × a.r`): modal coordinates of `a` → those of `b`, and how far outside
/// `a`'s mesh `b`'s nodes reached (barycentric units).
pub fn transfer_matrix(a: &SpaceView<'_>, b: &SpaceView<'_>) -> (Vec<f64>, f64) {
    let p = projections(a, b);
    (p.t, p.worst_outside)
}

/// `a`'s modes seen on `b`'s mesh.
pub struct Projections {
    /// T = Φ_bᵀ M_b I Φ_a, row-major `b.r × a.r`.
    pub t: Vec<f64>,
    /// ‖I φ_a,j‖² in b's mass norm, per mode of `a` (≈ 1: the MAC of modes i of b and j of a
    /// is T_ij² / norms_j, b's modes being M_b-orthonormal).
    pub norms: Vec<f64>,
    /// How far outside `a`'s mesh `b`'s nodes reached (barycentric units).
    pub worst_outside: f64,
}

/// Interpolates each mode of `a` onto `b`'s mesh and projects it on `b`'s modes.
pub fn projections(a: &SpaceView<'_>, b: &SpaceView<'_>) -> Projections {
    let interp = locate(a.mesh, b.mesh);
    let (nfa, nfb) = (a.dofs.free_count(), b.dofs.free_count());
    let column = nfb.max(1);
    // I Φ_a on b's free DOFs, column-major; then M_b I Φ_a for all columns at once (one pass
    // over M_b per few columns) and T as one product.
    let mut u = vec![0.0; nfb * a.r];
    u.par_chunks_mut(column).enumerate().for_each(|(j, col)| {
        let full = a.dofs.expand(&a.modes[j * nfa..(j + 1) * nfa]);
        let mut at_b = vec![0.0; b.dofs.total];
        interpolate(a.mesh, &interp, &full, &mut at_b);
        for (x, &g) in col.iter_mut().zip(&b.dofs.free) {
            *x = at_b[g as usize];
        }
    });
    let mut mu = vec![0.0; nfb * a.r];
    sym_matmul(b.pattern, b.m, &u, &mut mu);
    let norms: Vec<f64> = u
        .par_chunks(column)
        .zip(mu.par_chunks(column))
        .map(|(x, y)| x.iter().zip(y).map(|(x, y)| x * y).sum())
        .collect();
    // T (b.r × a.r) stored row-major = Tᵀ column-major = (M_b I Φ_a)ᵀ Φ_b.
    let product = crate::tall::t_times(
        faer::MatRef::from_column_major_slice(&mu, nfb, a.r),
        faer::MatRef::from_column_major_slice(&b.modes[..nfb * b.r], nfb, b.r),
    );
    let mut t = vec![0.0; b.r * a.r];
    for j in 0..b.r {
        for i in 0..a.r {
            t[i + j * a.r] = product[(i, j)];
        }
    }
    Projections {
        t,
        norms,
        worst_outside: interp.worst_outside,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A linear field is reproduced exactly by 4-node interpolation (this panicked: the 4-node
    /// shape functions were written into a 10-slot buffer).
    #[test]
    fn linear_field_interpolates_exactly_between_order_1_meshes() {
        let cube = |n: usize| Mesh::structured_box([n; 3], 1.0 / n as f64, crate::fem::element::Kind::Tet4, |_, p| p);
        let (a, b) = (cube(2), cube(3));
        let f = |p: [f64; 3]| [p[0] + 2.0 * p[1], 3.0 * p[2] - p[0], 1.0 - p[1]];
        let values: Vec<f64> = a.nodes.iter().flat_map(|&p| f(p)).collect();
        let mut out = vec![0.0; 3 * b.nodes.len()];
        interpolate(&a, &locate(&a, &b), &values, &mut out);
        for (i, &p) in b.nodes.iter().enumerate() {
            for c in 0..3 {
                assert!((out[3 * i + c] - f(p)[c]).abs() < 1e-12, "node {i}");
            }
        }
    }

    /// A quadratic field is reproduced exactly by 10-node interpolation between two meshes.
    #[test]
    fn quadratic_field_interpolates_exactly_between_meshes() {
        let cube = |n: usize| Mesh::structured_box([n; 3], 1.0 / n as f64, crate::fem::element::Kind::Tet10, |_, p| p);
        let (a, b) = (cube(2), cube(3));
        let f = |p: [f64; 3]| [p[0] * p[1], p[2] * p[2] - p[0], 1.0 + p[1] * p[2]];
        let values: Vec<f64> = a.nodes.iter().flat_map(|&p| f(p)).collect();
        let interp = locate(&a, &b);
        assert!(interp.worst_outside < 1e-9);
        let mut out = vec![0.0; 3 * b.nodes.len()];
        interpolate(&a, &interp, &values, &mut out);
        for (i, &p) in b.nodes.iter().enumerate() {
            let e = f(p);
            for c in 0..3 {
                assert!(
                    (out[3 * i + c] - e[c]).abs() < 1e-12,
                    "node {i}: {} vs {}",
                    out[3 * i + c],
                    e[c]
                );
            }
        }
    }
}
