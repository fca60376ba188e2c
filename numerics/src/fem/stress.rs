//! Modal stress at the corner vertices: each tet's strain evaluated at its own corners (linear
//! inside a 10-node tet, constant in a 4-node one), σ = λ tr(ε) I + 2μ ε, averaged over the
//! tets that share a vertex with their volumes as weights. The average is what CalculiX does
//! too, but it extrapolates from the integration points instead; the two agree where the field
//! is smooth and differ at the vertices of a stress concentration.

use super::element::{Kind, Lame, Shape, physical_gradients, tet4::Tet4, tet10::Tet10};
use crate::tet_mesh::Mesh;
use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

/// Voigt order of the six stress components, as the basis file names them.
pub const COMPONENTS: &str = "xx yy zz yz xz xy";

/// The stress of the `r` displacement fields `u` (each 3n, column `j` at `u[j·3n..]`) at every
/// corner vertex, row-major [6·nv, r]: row 6i+k = component k (xx, yy, zz, yz, xz, xy) of
/// vertex i, Pa per unit of the field. A tet whose Jacobian is not positive at a corner is left
/// out of that vertex's average (the mesh checks keep there being none).
pub fn vertex_stress(mesh: &Mesh, mat: &Lame, u: &[f64], r: usize) -> Vec<f64> {
    vertex_stress_averaged(mesh, mat, u, r, Averaging::Volume)
}

/// The Cauchy stress of one displacement field `u` (3n) taken as large (St. Venant–Kirchhoff:
/// σ = F S Fᵀ / det F, S = λ tr(E) I + 2μE), at every corner vertex, row-major [6·nv]: what a
/// nonlinear model's load case reports. Corners where det F ≤ 0 are left out of the average.
pub fn vertex_stress_cauchy(mesh: &Mesh, mat: &Lame, u: &[f64]) -> Vec<f64> {
    match mesh.kind {
        Kind::Tet4 => accumulate_with::<Tet4>(mesh, mat, u, 1, Averaging::Volume, true),
        Kind::Tet10 => accumulate_with::<Tet10>(mesh, mat, u, 1, Averaging::Volume, true),
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
pub fn vertex_stress_averaged(mesh: &Mesh, mat: &Lame, u: &[f64], r: usize, how: Averaging) -> Vec<f64> {
    match mesh.kind {
        Kind::Tet4 => accumulate::<Tet4>(mesh, mat, u, r, how),
        Kind::Tet10 => accumulate::<Tet10>(mesh, mat, u, r, how),
    }
}

fn accumulate<S: Shape>(mesh: &Mesh, mat: &Lame, u: &[f64], r: usize, how: Averaging) -> Vec<f64> {
    accumulate_with::<S>(mesh, mat, u, r, how, false)
}

fn accumulate_with<S: Shape>(mesh: &Mesh, mat: &Lame, u: &[f64], r: usize, how: Averaging, large: bool) -> Vec<f64> {
    let nv = mesh.vertex_count;
    let threads = rayon::current_num_threads().max(1);
    let tets = mesh.tet_count();
    // Per thread: Σ w σ (6·nv·r) and Σ w (nv).
    let (sum, weight) = (0..tets)
        .into_par_iter()
        .with_min_len(tets.div_ceil(threads).max(1))
        .fold(
            || {
                let mut c = Corners::<S>::new(r);
                c.large = large;
                (vec![0.0; 6 * nv * r], vec![0.0; nv], c)
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
                    for j in 0..r {
                        for (k, value) in corners.at(corner, j).iter().enumerate() {
                            sum[(6 * v + k) * r + j] += volume * value;
                        }
                    }
                }
                (sum, weight, corners)
            },
        )
        .map(|(s, w, _)| (s, w))
        .reduce(
            || (vec![0.0; 6 * nv * r], vec![0.0; nv]),
            |(mut a, mut wa), (b, wb)| {
                a.iter_mut().zip(&b).for_each(|(x, y)| *x += y);
                wa.iter_mut().zip(&wb).for_each(|(x, y)| *x += y);
                (a, wa)
            },
        );
    let mut out = sum;
    for (v, w) in weight.iter().enumerate() {
        let inv = if *w > 0.0 { 1.0 / w } else { 0.0 };
        out[6 * v * r..6 * (v + 1) * r].iter_mut().for_each(|s| *s *= inv);
    }
    out
}

/// The stress of `r` displacement fields at the four corners of one tet at a time (strain at a
/// corner, σ = λ tr(ε) I + 2μ ε), with its scratch space.
pub struct Corners<S: Shape> {
    r: usize,
    gl: Vec<[f64; 4]>,
    grad: Vec<[f64; 3]>,
    /// [corner][field][component], Voigt order.
    stress: Vec<[f64; 6]>,
    /// Cauchy stress of large displacements instead of the linear stress.
    large: bool,
    shape: std::marker::PhantomData<fn() -> S>,
}

impl<S: Shape> Corners<S> {
    /// Scratch space for `r` fields.
    pub fn new(r: usize) -> Self {
        Corners {
            r,
            gl: vec![[0.0; 4]; S::NODES],
            grad: vec![[0.0; 3]; S::NODES],
            stress: vec![[0.0; 6]; 4 * r],
            large: false,
            shape: std::marker::PhantomData,
        }
    }

    /// Evaluates tet `e` of `mesh` for the fields `u` (each 3n, field `j` at `u[j·3n..]`); a
    /// corner whose Jacobian is not positive is reported false and left unset.
    pub fn evaluate(&mut self, mesh: &Mesh, mat: &Lame, u: &[f64], e: usize) -> [bool; 4] {
        let n3 = 3 * mesh.nodes.len();
        let t = mesh.tet(e);
        let x: Vec<[f64; 3]> = t.iter().map(|&n| mesh.nodes[n as usize]).collect();
        let mut valid = [false; 4];
        for (corner, ok) in valid.iter_mut().enumerate() {
            let mut l = [0.0; 4];
            l[corner] = 1.0;
            S::bary_gradients(l, &mut self.gl);
            if physical_gradients(&x, &self.gl, &mut self.grad).is_err() {
                continue;
            }
            *ok = true;
            for j in 0..self.r {
                let uj = &u[j * n3..(j + 1) * n3];
                // ∇u = Σ_a u_a ⊗ ∇N_a.
                let h: Matrix3<f64> = t
                    .iter()
                    .zip(&self.grad)
                    .map(|(&n, g)| {
                        let n = n as usize;
                        Vector3::new(uj[3 * n], uj[3 * n + 1], uj[3 * n + 2]) * Vector3::from(*g).transpose()
                    })
                    .sum();
                let s = if self.large {
                    match super::stvk::cauchy(mat, &h) {
                        Some(s) => s,
                        None => {
                            *ok = false;
                            break;
                        }
                    }
                } else {
                    let eps = 0.5 * (h + h.transpose());
                    Matrix3::identity() * (mat.lambda * eps.trace()) + eps * (2.0 * mat.mu)
                };
                self.stress[corner * self.r + j] = [s[(0, 0)], s[(1, 1)], s[(2, 2)], s[(1, 2)], s[(0, 2)], s[(0, 1)]];
            }
        }
        valid
    }

    /// The stress of field `j` at `corner` of the last tet evaluated.
    pub fn at(&self, corner: usize, j: usize) -> &[f64; 6] {
        &self.stress[corner * self.r + j]
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
            let s = vertex_stress(&mesh, &mat, &u, 1);
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
}
