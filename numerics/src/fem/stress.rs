//! Modal stress at the corner vertices: each tet's strain evaluated at its own corners (linear
//! inside a 10-node tet, constant in a 4-node one), σ = λ tr(ε) I + 2μ ε, averaged over the
//! tets that share a vertex with their volumes as weights. The average is what CalculiX does
//! too, but it extrapolates from the integration points instead; the two agree where the field
//! is smooth and differ at the vertices of a stress concentration.

use super::element::{Kind, Lame, Shape, physical_gradients, tet4::Tet4, tet10::Tet10};
use crate::tet_mesh::Mesh;
use nalgebra::Matrix3;
use rayon::prelude::*;

/// Voigt order of the six stress components, as the basis file names them.
pub const COMPONENTS: &str = "xx yy zz yz xz xy";

/// `r` displacement fields interleaved DOF by DOF: field `j` at full DOF `i` (3·node + c) is
/// `values[i·r + j]`. An element reads its nodes' values of every field from a few contiguous
/// rows; side by side (each field 3n long) it read 3·r scattered places per node, and the
/// ribplate's recovery estimate (30 fields, 88k tets) spent most of its second there.
#[derive(Clone, Debug, Default)]
pub struct Fields {
    /// The values, [3n, r] row-major.
    pub values: Vec<f64>,
    /// Fields.
    pub r: usize,
}

impl Fields {
    /// One field (interleaved, it is the field itself).
    pub fn one(values: Vec<f64>) -> Fields {
        Fields { values, r: 1 }
    }

    /// From separate fields of equal length (the first's).
    pub fn from_each<F: AsRef<[f64]>>(fields: &[F]) -> Fields {
        let r = fields.len();
        let n3 = fields.first().map_or(0, |f| f.as_ref().len());
        let mut values = vec![0.0; n3 * r];
        for (j, field) in fields.iter().enumerate() {
            for (i, v) in field.as_ref().iter().enumerate().take(n3) {
                values[i * r + j] = *v;
            }
        }
        Fields { values, r }
    }

    /// The fields side by side again (field `j` at `j·3n ..`).
    pub fn side_by_side(&self) -> Vec<f64> {
        let n3 = self.values.len().checked_div(self.r).unwrap_or(0);
        let mut out = vec![0.0; self.values.len()];
        for (i, row) in self.values.chunks_exact(self.r.max(1)).enumerate() {
            for (j, v) in row.iter().enumerate() {
                out[j * n3 + i] = *v;
            }
        }
        out
    }

    /// From `r` fields over the free DOFs of `dofs` (column `j` at `reduced[j·nf..]`), zero at
    /// the supported DOFs.
    pub fn from_free(dofs: &super::Dofs, reduced: &[f64], r: usize) -> Fields {
        let nf = dofs.free_count();
        let mut values = vec![0.0; dofs.total * r];
        for j in 0..r {
            for (k, &i) in dofs.free.iter().enumerate() {
                values[i as usize * r + j] = reduced[j * nf + k];
            }
        }
        Fields { values, r }
    }

    /// The values of every field at full DOFs `3·node .. 3·node + 3`: x, y and z rows of r.
    fn node(&self, node: usize) -> (&[f64], &[f64], &[f64]) {
        let row = &self.values[3 * node * self.r..3 * (node + 1) * self.r];
        let (x, yz) = row.split_at(self.r);
        let (y, z) = yz.split_at(self.r);
        (x, y, z)
    }
}

/// The stress of the fields `u` at every corner vertex, row-major [6·nv, r]: row 6i+k =
/// component k (xx, yy, zz, yz, xz, xy) of vertex i, Pa per unit of the field. A tet whose
/// Jacobian is not positive at a corner is left out of that vertex's average (the mesh checks
/// keep there being none).
pub fn vertex_stress(mesh: &Mesh, mat: &Lame, u: &Fields) -> Vec<f64> {
    vertex_stress_averaged(mesh, mat, u, Averaging::Volume)
}

/// [`vertex_stress`], the tets visited in `order` (a permutation of them: the caller's
/// [`Mesh::tets_in_space_order`], made once for this and its own loop).
pub fn vertex_stress_in_order(mesh: &Mesh, mat: &Lame, u: &Fields, order: &[u32]) -> Vec<f64> {
    match mesh.kind {
        Kind::Tet4 => accumulate_with::<Tet4>(mesh, mat, u, Averaging::Volume, false, order),
        Kind::Tet10 => accumulate_with::<Tet10>(mesh, mat, u, Averaging::Volume, false, order),
    }
}

/// The Cauchy stress of one displacement field `u` (3n) taken as large (St. Venant–Kirchhoff:
/// σ = F S Fᵀ / det F, S = λ tr(E) I + 2μE), at every corner vertex, row-major [6·nv]: what a
/// nonlinear model's load case reports. Corners where det F ≤ 0 are left out of the average.
pub fn vertex_stress_cauchy(mesh: &Mesh, mat: &Lame, u: &[f64]) -> Vec<f64> {
    let u = Fields::one(u.to_vec());
    match mesh.kind {
        Kind::Tet4 => accumulate_with::<Tet4>(mesh, mat, &u, Averaging::Volume, true, &mesh.tets_in_space_order()),
        Kind::Tet10 => accumulate_with::<Tet10>(mesh, mat, &u, Averaging::Volume, true, &mesh.tets_in_space_order()),
    }
}

/// How the corner values of the elements at a vertex are averaged.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Averaging {
    /// Weighted by element volume (what a basis stores: a large element's corner value counts
    /// for the region it covers).
    Volume,
    /// Plain mean, as CalculiX averages its extrapolated nodal values (`ves verify --stress`
    /// compares like with like).
    Arithmetic,
}

/// [`vertex_stress`] with a choice of averaging.
pub fn vertex_stress_averaged(mesh: &Mesh, mat: &Lame, u: &Fields, how: Averaging) -> Vec<f64> {
    match mesh.kind {
        Kind::Tet4 => accumulate_with::<Tet4>(mesh, mat, u, how, false, &mesh.tets_in_space_order()),
        Kind::Tet10 => accumulate_with::<Tet10>(mesh, mat, u, how, false, &mesh.tets_in_space_order()),
    }
}

/// The tets are visited in `order` (Morton order: their vertices' rows stay in cache).
fn accumulate_with<S: Shape>(
    mesh: &Mesh,
    mat: &Lame,
    u: &Fields,
    how: Averaging,
    large: bool,
    order: &[u32],
) -> Vec<f64> {
    let nv = mesh.vertex_count;
    let r = u.r;
    let threads = rayon::current_num_threads().max(1);
    let tets = order.len();
    // Per thread: Σ w σ (6·nv·r) and Σ w (nv).
    let (sum, weight) = order
        .par_iter()
        .map(|&e| e as usize)
        .with_min_len(tets.div_ceil(threads).max(1))
        .fold(
            || {
                let mut c = Corners::<S>::new(r);
                c.large = large;
                (crate::memory::written_zeros(6 * nv * r), vec![0.0; nv], c)
            },
            |(mut sum, mut weight, mut corners), e| {
                let volume = match how {
                    Averaging::Volume => mesh.corner_volume(e),
                    Averaging::Arithmetic => 1.0,
                };
                let t = mesh.tet(e);
                let valid = corners.evaluate(mesh, mat, u, e);
                for corner in (0..4).filter(|&c| valid[c]) {
                    let v = t[corner] as usize;
                    weight[v] += volume;
                    let rows = &mut sum[6 * v * r..6 * (v + 1) * r];
                    rows.iter_mut()
                        .zip(corners.at(corner))
                        .for_each(|(s, value)| *s += volume * value);
                }
                (sum, weight, corners)
            },
        )
        .map(|(s, w, _)| (s, w))
        // Without an identity: one more zeroed 6·nv·r array per thread, and a pass adding it.
        .reduce_with(|(mut a, mut wa), (b, wb)| {
            a.iter_mut().zip(&b).for_each(|(x, y)| *x += y);
            wa.iter_mut().zip(&wb).for_each(|(x, y)| *x += y);
            (a, wa)
        })
        .unwrap_or_else(|| (vec![0.0; 6 * nv * r], vec![0.0; nv]));
    let mut out = sum;
    for (v, w) in weight.iter().enumerate() {
        let inv = if *w > 0.0 { 1.0 / w } else { 0.0 };
        out[6 * v * r..6 * (v + 1) * r].iter_mut().for_each(|s| *s *= inv);
    }
    out
}

/// The stress of `r` displacement fields at the four corners of one tet at a time (strain at a
/// corner, σ = λ tr(ε) I + 2μ ε), with its scratch space. A 4-node tet's strain is constant:
/// its corners share one evaluation. Everything is held component-major, r fields side by side:
/// each step is a loop over the fields the compiler vectorises, and a corner's stress is the
/// [6, r] block a vertex's row of [`vertex_stress`] adds to in one contiguous pass (held field
/// by field, with the 6 components of a field together, that sum went a stride at a time).
pub struct Corners<S: Shape> {
    r: usize,
    gl: Vec<[f64; 4]>,
    grad: Vec<[f64; 3]>,
    /// ∇u, [9, r]: row 3a + b is ∂u_a/∂x_b of every field.
    h: Vec<f64>,
    /// [corner][component][field], Voigt order (corner 0 only for a 4-node tet).
    stress: Vec<f64>,
    /// Cauchy stress of large displacements instead of the linear stress.
    large: bool,
    shape: std::marker::PhantomData<fn() -> S>,
}

impl<S: Shape> Corners<S> {
    /// Whether the element's strain is constant (its shape functions linear).
    const CONSTANT: bool = S::NODES == 4;

    /// Scratch space for `r` fields.
    pub fn new(r: usize) -> Self {
        Corners {
            r,
            gl: vec![[0.0; 4]; S::NODES],
            grad: vec![[0.0; 3]; S::NODES],
            h: vec![0.0; 9 * r],
            stress: vec![0.0; 4 * 6 * r],
            large: false,
            shape: std::marker::PhantomData,
        }
    }

    /// Evaluates tet `e` of `mesh` for the fields `u`; a corner whose Jacobian is not positive
    /// is reported false and left unset.
    pub fn evaluate(&mut self, mesh: &Mesh, mat: &Lame, u: &Fields, e: usize) -> [bool; 4] {
        debug_assert_eq!(u.r, self.r);
        let r = self.r;
        let t = mesh.tet(e);
        let mut x = [[0.0; 3]; 10];
        let x = &mut x[..t.len()];
        for (xa, &n) in x.iter_mut().zip(t) {
            *xa = mesh.nodes[n as usize];
        }
        let mut valid = [false; 4];
        let evaluated = if Self::CONSTANT { 1 } else { 4 };
        for corner in 0..evaluated {
            let mut l = [0.0; 4];
            l[corner] = 1.0;
            S::bary_gradients(l, &mut self.gl);
            if physical_gradients(x, &self.gl, &mut self.grad).is_err() {
                continue;
            }
            valid[corner] = true;
            // ∇u = Σ_a u_a ⊗ ∇N_a, every field at once.
            self.h.fill(0.0);
            for (&n, g) in t.iter().zip(&self.grad) {
                let (ux, uy, uz) = u.node(n as usize);
                for (c, uc) in [ux, uy, uz].into_iter().enumerate() {
                    for (b, gb) in g.iter().enumerate() {
                        let row = &mut self.h[(3 * c + b) * r..(3 * c + b + 1) * r];
                        row.iter_mut().zip(uc).for_each(|(h, u)| *h += u * gb);
                    }
                }
            }
            let out = &mut self.stress[corner * 6 * r..(corner + 1) * 6 * r];
            if self.large {
                for j in 0..r {
                    let h: [f64; 9] = std::array::from_fn(|i| self.h[i * r + j]);
                    match super::stvk::cauchy(mat, &Matrix3::from_row_slice(&h)) {
                        Some(s) => {
                            let s = [s[(0, 0)], s[(1, 1)], s[(2, 2)], s[(1, 2)], s[(0, 2)], s[(0, 1)]];
                            for (k, v) in s.into_iter().enumerate() {
                                out[k * r + j] = v;
                            }
                        }
                        None => {
                            valid[corner] = false;
                            break;
                        }
                    }
                }
            } else {
                let (lambda, mu) = (mat.lambda, mat.mu);
                let h = |i: usize| &self.h[i * r..(i + 1) * r];
                let (xx, yy, zz) = (h(0), h(4), h(8));
                let (xy, xz, yx, yz, zx, zy) = (h(1), h(2), h(3), h(5), h(6), h(7));
                let (normal, shear) = out.split_at_mut(3 * r);
                let (sxx, rest) = normal.split_at_mut(r);
                let (syy, szz) = rest.split_at_mut(r);
                for j in 0..r {
                    let tr = lambda * (xx[j] + yy[j] + zz[j]);
                    sxx[j] = tr + 2.0 * mu * xx[j];
                    syy[j] = tr + 2.0 * mu * yy[j];
                    szz[j] = tr + 2.0 * mu * zz[j];
                }
                let (syz, rest) = shear.split_at_mut(r);
                let (sxz, sxy) = rest.split_at_mut(r);
                for j in 0..r {
                    syz[j] = mu * (yz[j] + zy[j]);
                    sxz[j] = mu * (xz[j] + zx[j]);
                    sxy[j] = mu * (xy[j] + yx[j]);
                }
            }
        }
        if Self::CONSTANT {
            valid = [valid[0]; 4];
        }
        valid
    }

    /// The stress of every field at `corner` of the last tet evaluated, [6, r]: component k of
    /// field j at `k·r + j`.
    pub fn at(&self, corner: usize) -> &[f64] {
        let corner = if Self::CONSTANT { 0 } else { corner };
        &self.stress[corner * 6 * self.r..(corner + 1) * 6 * self.r]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A quadratic displacement has a linear strain, which 10-node tets represent exactly: the
    /// recovered stress equals the analytic one at every vertex (a linear field, for 4-node).
    #[test]
    fn stress_of_a_representable_field_is_exact_at_every_vertex() {
        let mat = Lame::new(2.0e11, 0.3, 7800.0);
        for kind in [Kind::Tet4, Kind::Tet10] {
            let mesh = Mesh::structured_box([3, 2, 2], 0.1, kind, |_, p| p);
            let (a, b) = (1e-3, if kind == Kind::Tet10 { 2e-2 } else { 0.0 });
            // u = (a x + b y², a z, b x z): ε = [[a, b y, b z / 2], [b y, 0, a / 2], [b z / 2, a / 2, b x]] (sym).
            let field = |p: [f64; 3]| [a * p[0] + b * p[1] * p[1], a * p[2], b * p[0] * p[2]];
            let u: Vec<f64> = mesh.nodes.iter().flat_map(|&p| field(p)).collect();
            let s = vertex_stress(&mesh, &mat, &Fields::one(u));
            for (i, p) in mesh.nodes[..mesh.vertex_count].iter().enumerate() {
                let eps = Matrix3::new(
                    a,
                    b * p[1],
                    0.5 * b * p[2],
                    b * p[1],
                    0.0,
                    0.5 * a,
                    0.5 * b * p[2],
                    0.5 * a,
                    b * p[0],
                );
                let e = Matrix3::identity() * (mat.lambda * eps.trace()) + eps * (2.0 * mat.mu);
                let want = [e[(0, 0)], e[(1, 1)], e[(2, 2)], e[(1, 2)], e[(0, 2)], e[(0, 1)]];
                for k in 0..6 {
                    assert!(
                        (s[6 * i + k] - want[k]).abs() < 1e-6 * mat.mu * a,
                        "{kind:?}, vertex {i}, component {k}: {} vs {}",
                        s[6 * i + k],
                        want[k]
                    );
                }
            }
        }
    }

    /// Fields interleaved give each field's stress as that field alone does, whichever way
    /// they were interleaved (separate, or side by side over the free DOFs with zeros where
    /// supported), on 4-node tets (one evaluation per tet) and 10-node ones (one per corner).
    #[test]
    fn fields_together_are_each_field_alone() {
        let mat = Lame::new(2.0e11, 0.3, 7800.0);
        for kind in [Kind::Tet4, Kind::Tet10] {
            let mesh = Mesh::structured_box([3, 2, 2], 0.1, kind, |ijk, p| {
                // Interior vertices moved: no two elements alike.
                let s = if ijk.iter().all(|&i| i > 0) && ijk[0] < 3 && ijk[1] < 2 && ijk[2] < 2 {
                    0.013
                } else {
                    0.0
                };
                [p[0] + s, p[1] - s, p[2] + 0.5 * s]
            });
            let n3 = 3 * mesh.nodes.len();
            let fields: Vec<Vec<f64>> = (0..3)
                .map(|j| {
                    mesh.nodes
                        .iter()
                        .flat_map(|p| {
                            let k = j as f64 + 1.0;
                            [
                                1e-3 * (k * p[0]).sin() * p[1],
                                2e-3 * p[2].powi(2) * k,
                                -1e-3 * p[0] * p[1] * p[2] / k,
                            ]
                        })
                        .collect()
                })
                .collect();
            let alone: Vec<Vec<f64>> = fields
                .iter()
                .map(|f| vertex_stress(&mesh, &mat, &Fields::one(f.clone())))
                .collect();
            let side_by_side: Vec<f64> = fields.iter().flatten().copied().collect();
            // Every DOF free: the free numbering is the full one.
            let dofs = super::super::Dofs::from_mask(&vec![false; n3]);
            for together in [Fields::from_each(&fields), Fields::from_free(&dofs, &side_by_side, 3)] {
                assert_eq!(together.side_by_side(), side_by_side, "{kind:?}: interleaved and back");
                let s = vertex_stress(&mesh, &mat, &together);
                for (j, a) in alone.iter().enumerate() {
                    let scale = a.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
                    assert!(scale > 0.0);
                    for (row, want) in a.iter().enumerate() {
                        let got = s[row * 3 + j];
                        assert!(
                            (got - want).abs() <= 1e-12 * scale,
                            "{kind:?} field {j} row {row}: {got} vs {want}"
                        );
                    }
                }
            }
        }
    }
}
