//! St. Venant–Kirchhoff elasticity: large displacements and rotations with a linear material
//! (S = λ tr(E) I + 2μ E, E = ½(Fᵀ F − I)). The internal force of a displacement, its second
//! derivative at rest (the right-hand side of a modal derivative), and the reduced model of a
//! basis U ([`Reduced`]): the strain energy of u = U q is a quartic polynomial in q whose
//! coefficients are integrated once, so that its force and tangent stiffness cost a fixed
//! number of operations, whatever the mesh (Barbič & James 2005).
//!
//! The quadrature is the stiffness rule of the linear elements, so that the reduced model's
//! linear part is exactly Uᵀ K U.

use super::element::{BadJacobian, Kind, Lame, Shape, physical_gradients, tet4::Tet4, tet10::Tet10};
use crate::tet_mesh::Mesh;
use faer::{Accum, Mat, MatRef, Par};
use nalgebra::{DMatrix, DVector, Matrix3};

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

/// Index of the pair (k, l), k ≤ l, among the r(r+1)/2 pairs ordered (0,0), (0,1), …, (1,1), …:
/// rows 0..k hold r, r−1, …, r−k+1 pairs.
#[inline(always)]
fn pair_index(r: usize, k: usize, l: usize) -> usize {
    k * r - k * k.saturating_sub(1) / 2 + (l - k)
}

/// The reduced St. Venant–Kirchhoff model of a basis U (n × r): for u = U q the strain energy
/// is W(q) = ½ qᵀ K q + qᵀ T s + ½ sᵀ H s with s the r(r+1)/2 products q_k q_l (k ≤ l). K, T, H
/// are integrated over every quadrature point once ([`Reduced::build`]); the force ∂W/∂q and
/// the tangent ∂²W/∂q² then cost O(P²) and O(P r²), P = r(r+1)/2.
#[derive(Clone, Debug)]
pub struct Reduced {
    /// Basis size r.
    pub r: usize,
    /// Uᵀ K U, r × r row-major.
    pub k: Vec<f64>,
    /// Cubic-energy coefficients, r × P row-major.
    pub t: Vec<f64>,
    /// Quartic-energy coefficients, P × P row-major (symmetric positive semi-definite).
    pub h: Vec<f64>,
}

/// Work space of [`Reduced`]'s evaluations (no allocation once made).
#[derive(Clone, Debug)]
pub struct Scratch {
    s: Vec<f64>,
    u: Vec<f64>,
    hj: Vec<f64>,
    row: Vec<f64>,
}

impl Reduced {
    /// Number of pairs P = r(r+1)/2.
    pub fn pairs(&self) -> usize {
        self.r * (self.r + 1) / 2
    }

    /// Integrates K, T and H of the basis `u` (column-major, `mesh.nodes.len()·3 × r`, zero at
    /// supported DOFs) over `points`. Work O(points · P²), in blocks of points.
    pub fn build(points: &Points, mesh: &Mesh, mat: &Lame, u: &[f64], r: usize) -> Reduced {
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
        let block = 256usize;
        let mut kk = Mat::<f64>::zeros(r, r);
        let mut tt = Mat::<f64>::zeros(r, np);
        let mut hh = Mat::<f64>::zeros(np, np);
        let mut d = vec![Matrix3::<f64>::zeros(); r];
        for start in (0..points.len()).step_by(block) {
            let end = (start + block).min(points.len());
            let rows = 6 * (end - start);
            let mut a = Mat::<f64>::zeros(rows, r);
            let mut b = Mat::<f64>::zeros(rows, np);
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
            let par = Par::rayon(0);
            faer::linalg::matmul::matmul(kk.as_mut(), Accum::Add, a.transpose(), a.as_ref(), 1.0, par);
            faer::linalg::matmul::matmul(tt.as_mut(), Accum::Add, a.transpose(), b.as_ref(), 1.0, par);
            faer::linalg::matmul::matmul(hh.as_mut(), Accum::Add, b.transpose(), b.as_ref(), 1.0, par);
        }
        let rows = |m: MatRef<'_, f64>| {
            (0..m.nrows())
                .flat_map(|i| (0..m.ncols()).map(move |j| m[(i, j)]))
                .collect::<Vec<f64>>()
        };
        Reduced {
            r,
            k: rows(kk.as_ref()),
            t: rows(tt.as_ref()),
            h: rows(hh.as_ref()),
        }
    }

    /// Work space for this model.
    pub fn scratch(&self) -> Scratch {
        let np = self.pairs();
        Scratch {
            s: vec![0.0; np],
            u: vec![0.0; np],
            hj: vec![0.0; np * self.r],
            row: vec![0.0; self.r],
        }
    }

    /// s = (q_k q_l)_{k ≤ l}.
    fn products(&self, q: &[f64], s: &mut [f64]) {
        let mut p = 0;
        for k in 0..self.r {
            for l in k..self.r {
                s[p] = q[k] * q[l];
                p += 1;
            }
        }
    }

    /// out += Jᵀ v, J = ∂s/∂q: (Jᵀ v)_i = Σ_{l≠i} v_(il) q_l + 2 v_(ii) q_i.
    fn add_jt(&self, v: &[f64], q: &[f64], out: &mut [f64]) {
        let mut p = 0;
        for k in 0..self.r {
            out[k] += 2.0 * v[p] * q[k];
            p += 1;
            for l in k + 1..self.r {
                out[k] += v[p] * q[l];
                out[l] += v[p] * q[k];
                p += 1;
            }
        }
    }

    /// The strain energy W(q).
    pub fn energy(&self, q: &[f64], w: &mut Scratch) -> f64 {
        let (r, np) = (self.r, self.pairs());
        self.products(q, &mut w.s);
        let mut e = 0.0;
        for i in 0..r {
            let ki = &self.k[i * r..(i + 1) * r];
            let ti = &self.t[i * np..(i + 1) * np];
            e += q[i] * (0.5 * dot(ki, q) + dot(ti, &w.s));
        }
        for p in 0..np {
            e += 0.5 * w.s[p] * dot(&self.h[p * np..(p + 1) * np], &w.s);
        }
        e
    }

    /// The reduced internal force f = ∂W/∂q = K q + T s + Jᵀ (Tᵀ q + H s) into `f`.
    pub fn force(&self, q: &[f64], f: &mut [f64], w: &mut Scratch) {
        let (r, np) = (self.r, self.pairs());
        self.products(q, &mut w.s);
        // u = Tᵀ q + H s.
        for p in 0..np {
            w.u[p] = dot(&self.h[p * np..(p + 1) * np], &w.s);
        }
        for i in 0..r {
            let ti = &self.t[i * np..(i + 1) * np];
            f[i] = dot(&self.k[i * r..(i + 1) * r], q) + dot(ti, &w.s);
            for (u, t) in w.u.iter_mut().zip(ti) {
                *u += t * q[i];
            }
        }
        self.add_jt(&w.u, q, f);
    }

    /// The force (as [`Reduced::force`]) and the tangent stiffness ∂f/∂q, r × r row-major:
    /// K + T J + (T J)ᵀ + A(Tᵀ q + H s) + Jᵀ H J, with A(v) q = Jᵀ v.
    pub fn force_and_tangent(&self, q: &[f64], f: &mut [f64], kt: &mut [f64], w: &mut Scratch) {
        let (r, np) = (self.r, self.pairs());
        self.force(q, f, w);
        kt.copy_from_slice(&self.k);
        // A(u): u_(kl) off the diagonal, 2 u_(kk) on it (w.u holds Tᵀq + Hs from force).
        let mut p = 0;
        for k in 0..r {
            kt[k * r + k] += 2.0 * w.u[p];
            p += 1;
            for l in k + 1..r {
                kt[k * r + l] += w.u[p];
                kt[l * r + k] += w.u[p];
                p += 1;
            }
        }
        // T J: row i is Jᵀ T_i; added with its transpose.
        for i in 0..r {
            w.row.fill(0.0);
            self.add_jt(&self.t[i * np..(i + 1) * np], q, &mut w.row);
            for m in 0..r {
                kt[i * r + m] += w.row[m];
                kt[m * r + i] += w.row[m];
            }
        }
        // H J column by column (column m: Σ_l H[:, (m l)] q_l, twice for l = m; H symmetric, so
        // row (m l) is read), then Jᵀ of it.
        for m in 0..r {
            let col = &mut w.hj[m * np..(m + 1) * np];
            col.fill(0.0);
            for (l, &ql) in q.iter().enumerate() {
                let c = if l == m { 2.0 * ql } else { ql };
                if c == 0.0 {
                    continue;
                }
                let pl = pair_index(r, m.min(l), m.max(l));
                for (x, h) in col.iter_mut().zip(&self.h[pl * np..(pl + 1) * np]) {
                    *x += c * h;
                }
            }
        }
        for m in 0..r {
            w.row.fill(0.0);
            self.add_jt(&w.hj[m * np..(m + 1) * np], q, &mut w.row);
            for i in 0..r {
                kt[i * r + m] += w.row[i];
            }
        }
    }

    /// The static equilibrium f(q) = g of the reduced model for the modal load `g`, reached in
    /// `steps` equal load increments, each by Newton's method with a backtracking line search on
    /// the energy W(q) − λ gᵀq. Fails (with the last residual) when an increment does not
    /// converge: a load past a limit point or a basis that cannot carry it.
    pub fn equilibrium(&self, g: &[f64], steps: usize) -> Result<Equilibrium, NotConverged> {
        let r = self.r;
        let mut w = self.scratch();
        let mut q = vec![0.0; r];
        let (mut f, mut kt) = (vec![0.0; r], vec![0.0; r * r]);
        let gnorm = norm(g).max(f64::MIN_POSITIVE);
        let mut iterations = 0;
        let mut residual = 0.0;
        for step in 1..=steps.max(1) {
            let scale = step as f64 / steps.max(1) as f64;
            let potential = |q: &[f64], w: &mut Scratch| self.energy(q, w) - scale * dot(g, q);
            let mut converged = false;
            for _ in 0..50 {
                iterations += 1;
                self.force_and_tangent(&q, &mut f, &mut kt, &mut w);
                let res: Vec<f64> = (0..r).map(|i| scale * g[i] - f[i]).collect();
                residual = norm(&res) / gnorm;
                if residual < 1e-10 {
                    converged = true;
                    break;
                }
                let a = DMatrix::from_row_slice(r, r, &kt);
                let dq = match a.clone().cholesky() {
                    Some(c) => c.solve(&DVector::from_vec(res.clone())),
                    None => match a.lu().solve(&DVector::from_vec(res.clone())) {
                        Some(x) => x,
                        None => return Err(NotConverged { residual, scale }),
                    },
                };
                let p0 = potential(&q, &mut w);
                let mut t = 1.0;
                loop {
                    let trial: Vec<f64> = q.iter().zip(dq.iter()).map(|(a, b)| a + t * b).collect();
                    if potential(&trial, &mut w) <= p0 + 1e-12 * p0.abs() || t < 1e-3 {
                        q = trial;
                        break;
                    }
                    t *= 0.5;
                }
                if q.iter().any(|v| !v.is_finite()) {
                    return Err(NotConverged { residual, scale });
                }
            }
            if !converged {
                return Err(NotConverged { residual, scale });
            }
        }
        Ok(Equilibrium {
            q,
            iterations,
            residual,
        })
    }
}

/// A static equilibrium of the reduced model.
#[derive(Clone, Debug)]
pub struct Equilibrium {
    /// The reduced coordinates.
    pub q: Vec<f64>,
    /// Newton iterations over all increments.
    pub iterations: usize,
    /// ‖g − f(q)‖ / ‖g‖ at the end.
    pub residual: f64,
}

/// An increment of a reduced static solve that did not converge.
#[derive(Clone, Copy, Debug, thiserror::Error)]
#[error(
    "the nonlinear static solve did not converge at {:.0} % of the load (residual {residual:.1e}); \
     lower the load or add modes (mesh.modes) so the basis can carry it",
    scale * 100.0
)]
pub struct NotConverged {
    /// Relative residual of the last iteration.
    pub residual: f64,
    /// Fraction of the load reached.
    pub scale: f64,
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn norm(a: &[f64]) -> f64 {
    dot(a, a).sqrt()
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

    fn combine(u: &[f64], q: &[f64], n3: usize) -> Vec<f64> {
        (0..n3)
            .map(|i| q.iter().enumerate().map(|(k, qk)| qk * u[k * n3 + i]).sum())
            .collect()
    }

    #[test]
    fn pairs_are_numbered_as_the_products_are_ordered() {
        let r = 7;
        let mut p = 0;
        for k in 0..r {
            for l in k..r {
                assert_eq!(pair_index(r, k, l), p, "({k}, {l})");
                p += 1;
            }
        }
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
        let model = Reduced::build(&points, &mesh, &mat, &u, r);
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
        let model = Reduced::build(&points, &mesh, &mat, &u, r);
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
