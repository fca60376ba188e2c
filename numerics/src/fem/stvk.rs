//! St. Venant–Kirchhoff elasticity: large displacements and rotations with a linear material
//! (S = λ tr(E) I + 2μ E, E = ½(Fᵀ F − I)). The internal force of a displacement, its second
//! derivative at rest (the right-hand side of a modal derivative), and the reduced model of a
//! basis U ([`reduce`], evaluated by the runtime's [`Polynomial`]): the strain energy of u = U q is a quartic polynomial in q whose
//! coefficients are integrated once, so that its force and tangent stiffness cost a fixed
//! number of operations, whatever the mesh (Barbič & James 2005).
//!
//! The quadrature is the stiffness rule of the linear elements, so that the reduced model's
//! linear part is exactly Uᵀ K U.

use super::element::{BadJacobian, Kind, Lame, Shape, physical_gradients, tet4::Tet4, tet10::Tet10};
use crate::tet_mesh::Mesh;
use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};
use nalgebra::{DMatrix, Matrix3};
use rayon::prelude::*;
pub use ves_runtime::nonlinear::{Equilibrium, NotConverged, Polynomial};

/// The quadrature points of a mesh, each with its element, weight (w · det J) and the physical
/// gradients of its element's shape functions.
pub struct Points {
    per_element: usize,
    element: Vec<u32>,
    weight: Vec<f64>,
    grad: Vec<[f64; 3]>,
}

/// An element with a non-positive Jacobian at a quadrature point.
#[derive(Debug, Clone, Copy, thiserror::Error)]
#[error("element {element} is degenerate or inverted (det J = {det:.3e}); remesh the part")]
pub struct DegenerateElement {
    /// The element's index.
    pub element: usize,
    /// Its Jacobian determinant there.
    pub det: f64,
}

impl Points {
    /// Every quadrature point of `mesh` (the stiffness rule; the curved rule on curved tets).
    pub fn of(mesh: &Mesh) -> Result<Points, DegenerateElement> {
        match mesh.kind {
            Kind::Tet4 => Points::with::<Tet4>(mesh),
            Kind::Tet10 => Points::with::<Tet10>(mesh),
        }
    }

    fn with<S: Shape>(mesh: &Mesh) -> Result<Points, DegenerateElement> {
        let p = S::NODES;
        let mut gl = vec![[0.0; 4]; p];
        let mut grad = vec![[0.0; 3]; p];
        let mut out = Points {
            per_element: p,
            element: Vec::new(),
            weight: Vec::new(),
            grad: Vec::new(),
        };
        for e in 0..mesh.tet_count() {
            let x: Vec<[f64; 3]> = mesh.tet(e).iter().map(|&n| mesh.nodes[n as usize]).collect();
            for (l, w) in S::curved_stiffness_rule(&x).unwrap_or_else(S::stiffness_rule) {
                S::bary_gradients(l, &mut gl);
                let det = physical_gradients(&x, &gl, &mut grad)
                    .map_err(|BadJacobian { det }| DegenerateElement { element: e, det })?;
                out.element.push(e as u32);
                out.weight.push(w * det);
                out.grad.extend_from_slice(&grad);
            }
        }
        Ok(out)
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.weight.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.weight.is_empty()
    }

    fn grads(&self, g: usize) -> &[[f64; 3]] {
        &self.grad[g * self.per_element..(g + 1) * self.per_element]
    }

    /// ∇u (G_ij = ∂u_i/∂x_j) of the field `u` (3n) at point `g`.
    fn gradient(&self, mesh: &Mesh, g: usize, u: &[f64]) -> Matrix3<f64> {
        let t = mesh.tet(self.element[g] as usize);
        let mut h = Matrix3::zeros();
        for (&n, d) in t.iter().zip(self.grads(g)) {
            let n = n as usize;
            for i in 0..3 {
                for j in 0..3 {
                    h[(i, j)] += u[3 * n + i] * d[j];
                }
            }
        }
        h
    }

    /// Adds w Σ_j P_ij ∂N_a/∂x_j to node a's row i of `f` for the element of point `g`.
    fn scatter(&self, mesh: &Mesh, g: usize, p: &Matrix3<f64>, f: &mut [f64]) {
        let w = self.weight[g];
        let t = mesh.tet(self.element[g] as usize);
        for (&n, d) in t.iter().zip(self.grads(g)) {
            let n = n as usize;
            for i in 0..3 {
                f[3 * n + i] += w * (p[(i, 0)] * d[0] + p[(i, 1)] * d[1] + p[(i, 2)] * d[2]);
            }
        }
    }
}

/// S(E) = λ tr(E) I + 2μ E.
fn hooke(mat: &Lame, e: &Matrix3<f64>) -> Matrix3<f64> {
    Matrix3::identity() * (mat.lambda * e.trace()) + e * (2.0 * mat.mu)
}

/// First Piola–Kirchhoff stress P = F S(E) of the displacement gradient `h`.
pub fn first_piola(mat: &Lame, h: &Matrix3<f64>) -> Matrix3<f64> {
    let f = Matrix3::identity() + h;
    let e = 0.5 * (h + h.transpose() + h.transpose() * h);
    f * hooke(mat, &e)
}

/// Cauchy stress σ = F S Fᵀ / det F of the displacement gradient `h` (`None` where det F ≤ 0).
pub fn cauchy(mat: &Lame, h: &Matrix3<f64>) -> Option<Matrix3<f64>> {
    let f = Matrix3::identity() + h;
    let j = f.determinant();
    let e = 0.5 * (h + h.transpose() + h.transpose() * h);
    (j > 0.0).then(|| f * hooke(mat, &e) * f.transpose() / j)
}

/// The internal force of the displacement `u` (3n): ∫ Pᵀ ∇N.
pub fn internal_force(points: &Points, mesh: &Mesh, mat: &Lame, u: &[f64]) -> Vec<f64> {
    let mut f = vec![0.0; u.len()];
    for g in 0..points.len() {
        let p = first_piola(mat, &points.gradient(mesh, g, u));
        points.scatter(mesh, g, &p, &mut f);
    }
    f
}

/// The second derivative of the internal force at rest in the directions `a` and `b` (3n
/// each): with Gₐ = ∇a, εₐ = sym Gₐ, d²P = Gₐ S(ε_b) + G_b S(εₐ) + S(sym(Gₐᵀ G_b)).
/// −K⁻¹ of it is the modal derivative of `a` and `b`.
pub fn second_derivative(points: &Points, mesh: &Mesh, mat: &Lame, a: &[f64], b: &[f64]) -> Vec<f64> {
    let mut f = vec![0.0; a.len()];
    for g in 0..points.len() {
        let (ga, gb) = (points.gradient(mesh, g, a), points.gradient(mesh, g, b));
        let (ea, eb) = (0.5 * (ga + ga.transpose()), 0.5 * (gb + gb.transpose()));
        let x = ga.transpose() * gb;
        let p = ga * hooke(mat, &eb) + gb * hooke(mat, &ea) + hooke(mat, &(0.5 * (x + x.transpose())));
        points.scatter(mesh, g, &p, &mut f);
    }
    f
}

/// The reduced model of the basis `u` (column-major, `mesh.nodes.len()·3 × r`, zero at
/// supported DOFs) over `points`. Work O(points · P²), in blocks of points.
pub fn reduce(points: &Points, mesh: &Mesh, mat: &Lame, u: &[f64], r: usize) -> Polynomial {
    let n3 = 3 * mesh.nodes.len();
    let np = r * (r + 1) / 2;
    // C = L Lᵀ in engineering Voigt order (xx yy zz yz xz xy): ε·Cη = (Lᵀε)·(Lᵀη).
    let mut c = DMatrix::<f64>::zeros(6, 6);
    for i in 0..3 {
        for j in 0..3 {
            c[(i, j)] = mat.lambda + if i == j { 2.0 * mat.mu } else { 0.0 };
        }
        c[(3 + i, 3 + i)] = mat.mu;
    }
    let lt = c
        .cholesky()
        .map_or_else(|| DMatrix::zeros(6, 6), |ch| ch.l().transpose());
    let voigt = |y: &Matrix3<f64>| {
        [
            y[(0, 0)],
            y[(1, 1)],
            y[(2, 2)],
            2.0 * y[(1, 2)],
            2.0 * y[(0, 2)],
            2.0 * y[(0, 1)],
        ]
    };
    // Blocks of points in parallel, each product on one thread (faer's own parallel GEMM
    // synchronises with spinning barriers, which stall when anything else shares the cores:
    // tall.rs), summed over the threads at the end.
    const BLOCK: usize = 256;
    let starts: Vec<usize> = (0..points.len()).step_by(BLOCK).collect();
    let zero = || {
        (
            Mat::<f64>::zeros(r, r),
            Mat::<f64>::zeros(r, np),
            Mat::<f64>::zeros(np, np),
        )
    };
    let (kk, tt, hh) = starts
        .par_iter()
        .fold(zero, |(mut kk, mut tt, mut hh), &start| {
            let end = (start + BLOCK).min(points.len());
            let rows = 6 * (end - start);
            let mut a = Mat::<f64>::zeros(rows, r);
            let mut b = Mat::<f64>::zeros(rows, np);
            let mut d = vec![Matrix3::<f64>::zeros(); r];
            for g in start..end {
                let t = mesh.tet(points.element[g] as usize);
                for (k, dk) in d.iter_mut().enumerate() {
                    *dk = Matrix3::zeros();
                    let col = &u[k * n3..(k + 1) * n3];
                    for (&n, gr) in t.iter().zip(points.grads(g)) {
                        let n = n as usize;
                        for i in 0..3 {
                            for j in 0..3 {
                                dk[(i, j)] += col[3 * n + i] * gr[j];
                            }
                        }
                    }
                }
                let sw = points.weight[g].max(0.0).sqrt();
                let row0 = 6 * (g - start);
                let put = |m: &mut Mat<f64>, col: usize, y: &Matrix3<f64>| {
                    let v = voigt(y);
                    for i in 0..6 {
                        let mut s = 0.0;
                        for j in i..6 {
                            s += lt[(i, j)] * v[j];
                        }
                        m[(row0 + i, col)] = sw * s;
                    }
                };
                for (k, dk) in d.iter().enumerate() {
                    put(&mut a, k, &(0.5 * (dk + dk.transpose())));
                }
                let mut p = 0;
                for k in 0..r {
                    for l in k..r {
                        let x = d[k].transpose() * d[l];
                        let y = if k == l { 0.5 * x } else { 0.5 * (x + x.transpose()) };
                        put(&mut b, p, &y);
                        p += 1;
                    }
                }
            }
            let seq = Par::Seq;
            matmul(kk.as_mut(), Accum::Add, a.transpose(), a.as_ref(), 1.0, seq);
            matmul(tt.as_mut(), Accum::Add, a.transpose(), b.as_ref(), 1.0, seq);
            matmul(hh.as_mut(), Accum::Add, b.transpose(), b.as_ref(), 1.0, seq);
            (kk, tt, hh)
        })
        .reduce(zero, |(k1, t1, h1), (k2, t2, h2)| (k1 + k2, t1 + t2, h1 + h2));
    let rows = |m: MatRef<'_, f64>| {
        (0..m.nrows())
            .flat_map(|i| (0..m.ncols()).map(move |j| m[(i, j)]))
            .collect::<Vec<f64>>()
    };
    Polynomial::new(r, rows(kk.as_ref()), rows(tt.as_ref()), rows(hh.as_ref()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small 10-node beam and `r` smooth fields on it (zero at x = 0), column-major.
    fn beam_and_fields(r: usize) -> (Mesh, Vec<f64>) {
        let mesh = Mesh::structured_box([4, 1, 1], 0.1, Kind::Tet10, |_, p| p);
        let n3 = 3 * mesh.nodes.len();
        let mut u = vec![0.0; n3 * r];
        for k in 0..r {
            for (n, p) in mesh.nodes.iter().enumerate() {
                let s = p[0] / 0.4;
                let a = (k + 1) as f64;
                u[k * n3 + 3 * n] = 0.1 * s * (a * p[1] * 7.0).sin();
                u[k * n3 + 3 * n + 1] = 0.05 * s * s * (a * 0.7 + p[2] * 3.0).cos();
                u[k * n3 + 3 * n + 2] = 0.08 * s.powi((k % 3) as i32 + 1) * (1.0 + p[1]);
            }
        }
        (mesh, u)
    }

    fn dot(a: &[f64], b: &[f64]) -> f64 {
        a.iter().zip(b).map(|(x, y)| x * y).sum()
    }

    fn norm(a: &[f64]) -> f64 {
        dot(a, a).sqrt()
    }

    fn combine(u: &[f64], q: &[f64], n3: usize) -> Vec<f64> {
        (0..n3)
            .map(|i| q.iter().enumerate().map(|(k, qk)| qk * u[k * n3 + i]).sum())
            .collect()
    }

    /// The reduced force is the full St. Venant–Kirchhoff force projected on the basis, at
    /// displacements well into the nonlinear range (the polynomial is exact, not a fit).
    #[test]
    fn reduced_force_is_the_projected_full_force() {
        let r = 4;
        let (mesh, u) = beam_and_fields(r);
        let n3 = 3 * mesh.nodes.len();
        let mat = Lame::new(1.0e6, 0.3, 1000.0);
        let points = Points::of(&mesh).expect("valid mesh");
        let model = reduce(&points, &mesh, &mat, &u, r);
        let mut w = model.scratch();
        for q in [[0.3, -0.2, 0.5, 0.1], [1.5, 0.7, -1.1, 2.0]] {
            let full = internal_force(&points, &mesh, &mat, &combine(&u, &q, n3));
            let want: Vec<f64> = (0..r).map(|k| dot(&u[k * n3..(k + 1) * n3], &full)).collect();
            let mut f = vec![0.0; r];
            model.force(&q, &mut f, &mut w);
            let scale = norm(&want);
            for k in 0..r {
                assert!(
                    (f[k] - want[k]).abs() < 1e-10 * scale,
                    "q {q:?}, k {k}: {} vs {}",
                    f[k],
                    want[k]
                );
            }
        }
    }

    /// Force = ∂W/∂q and tangent = ∂f/∂q, by central differences.
    #[test]
    fn force_is_the_energy_gradient_and_tangent_its_jacobian() {
        let r = 5;
        let (mesh, u) = beam_and_fields(r);
        let mat = Lame::new(2.0e6, 0.35, 1000.0);
        let points = Points::of(&mesh).expect("valid mesh");
        let model = reduce(&points, &mesh, &mat, &u, r);
        let mut w = model.scratch();
        let q = [0.4, -0.3, 0.8, 0.2, -0.6];
        let (mut f, mut kt) = (vec![0.0; r], vec![0.0; r * r]);
        model.force_and_tangent(&q, &mut f, &mut kt, &mut w);
        let h = 1e-5;
        let fmax = f.iter().fold(0.0f64, |a, b| a.max(b.abs()));
        let kmax = kt.iter().fold(0.0f64, |a, b| a.max(b.abs()));
        for j in 0..r {
            let (mut qp, mut qm) = (q, q);
            qp[j] += h;
            qm[j] -= h;
            let de = (model.energy(&qp, &mut w) - model.energy(&qm, &mut w)) / (2.0 * h);
            assert!((de - f[j]).abs() < 1e-6 * fmax, "∂W/∂q{j}: {de} vs {}", f[j]);
            let (mut fp, mut fm) = (vec![0.0; r], vec![0.0; r]);
            model.force(&qp, &mut fp, &mut w);
            model.force(&qm, &mut fm, &mut w);
            for i in 0..r {
                let d = (fp[i] - fm[i]) / (2.0 * h);
                assert!(
                    (d - kt[i * r + j]).abs() < 1e-6 * kmax,
                    "K[{i},{j}]: {d} vs {}",
                    kt[i * r + j]
                );
            }
        }
    }

    /// ∂²f/∂a∂b at rest, against a mixed central difference of the full force (cubic in u, so the
    /// difference is exact up to rounding).
    #[test]
    fn second_derivative_matches_a_difference_of_the_force() {
        let (mesh, u) = beam_and_fields(2);
        let n3 = 3 * mesh.nodes.len();
        let mat = Lame::new(1.0e6, 0.3, 1000.0);
        let points = Points::of(&mesh).expect("valid mesh");
        let (a, b) = (&u[..n3], &u[n3..]);
        let d = second_derivative(&points, &mesh, &mat, a, b);
        let h = 1e-3;
        let at = |s: f64, t: f64| {
            let x: Vec<f64> = a.iter().zip(b).map(|(x, y)| s * x + t * y).collect();
            internal_force(&points, &mesh, &mat, &x)
        };
        let (pp, pm, mp, mm) = (at(h, h), at(h, -h), at(-h, h), at(-h, -h));
        let scale = d.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(scale > 0.0);
        for i in 0..n3 {
            let fd = (pp[i] - pm[i] - mp[i] + mm[i]) / (4.0 * h * h);
            assert!((fd - d[i]).abs() < 1e-6 * scale, "dof {i}: {fd} vs {}", d[i]);
        }
    }

    /// A rigid rotation by 90° strains nothing: the full force vanishes (a linear model's would
    /// not), and the Cauchy stress of a uniaxial stretch is the analytic one.
    #[test]
    fn rotation_is_strain_free_and_a_stretch_has_its_analytic_stress() {
        let mesh = Mesh::structured_box([2, 1, 1], 0.1, Kind::Tet10, |_, p| p);
        let mat = Lame::new(1.0e6, 0.3, 1000.0);
        let points = Points::of(&mesh).expect("valid mesh");
        // Rotation by 90° about z: (x, y) → (−y, x).
        let u: Vec<f64> = mesh
            .nodes
            .iter()
            .flat_map(|p| [-p[1] - p[0], p[0] - p[1], 0.0])
            .collect();
        let f = internal_force(&points, &mesh, &mat, &u);
        let lin_scale = mat.mu * 0.1; // force of a unit strain on a face of 0.1²…
        assert!(f.iter().all(|v| v.abs() < 1e-9 * lin_scale), "rotation gave force");
        // Stretch λ₁ = 1.2 along x, free laterally by ν-less stress: σ from F = diag(1.2, 1, 1).
        let h = Matrix3::new(0.2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        let s = cauchy(&mat, &h).expect("positive det");
        let e11 = 0.5 * (1.2f64 * 1.2 - 1.0);
        let s11 = (mat.lambda + 2.0 * mat.mu) * e11;
        assert!((s[(0, 0)] - 1.2 * s11 * 1.2 / 1.2).abs() < 1e-9 * s11);
        assert!((s[(1, 1)] - mat.lambda * e11 / 1.2).abs() < 1e-9 * s11);
    }
}
