//! Isoparametric tetrahedra: shape functions ([`tet4`], [`tet10`]) and the element matrices
//! computed from them by quadrature.

pub mod tet10;
pub mod tet4;

/// The element kinds (4- and 10-node tets): node count, file value, gmsh and VTK codes, defined
/// once in the format crate (the runtime reads the same files).
pub use ves_format::ElementKind as Kind;

use super::quadrature::Point;
use nalgebra::{Matrix3, Vector3};

/// Shape functions of one element type, in barycentric coordinates.
pub trait Shape {
    /// Nodes per element.
    const NODES: usize;
    /// Values N_a(L).
    fn values(l: [f64; 4], n: &mut [f64]);
    /// Derivatives ∂N_a/∂L_j (with the L_j treated as independent).
    fn bary_gradients(l: [f64; 4], g: &mut [[f64; 4]]);
    /// Rule used for the stiffness (exact on straight-sided elements).
    fn stiffness_rule() -> Vec<Point>;
    /// Rule used for the consistent mass (exact on straight-sided elements).
    fn mass_rule() -> Vec<Point>;
    /// Rule for the stiffness of a curved element (node coordinates `x`), whose integrand is no
    /// longer a polynomial; `None` when the element is straight-sided.
    fn curved_stiffness_rule(_x: &[[f64; 3]]) -> Option<Vec<Point>> {
        None
    }
}

/// Isotropic material in the form the element loop uses.
#[derive(Clone, Copy, Debug)]
pub struct Lame {
    /// First Lamé parameter λ, Pa.
    pub lambda: f64,
    /// Shear modulus μ, Pa.
    pub mu: f64,
    /// Density, kg/m³.
    pub density: f64,
}

impl Lame {
    /// From Young's modulus, Poisson's ratio and density.
    pub fn new(young: f64, poisson: f64, density: f64) -> Lame {
        Lame {
            lambda: young * poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson)),
            mu: young / (2.0 * (1.0 + poisson)),
            density,
        }
    }

    /// Of a material.
    pub fn of(m: &crate::material::Material) -> Lame {
        Lame::new(m.young, m.poisson, m.density)
    }
}

/// The integrals one element contributes.
pub struct ElementMatrices {
    /// Stiffness, `3P × 3P` row-major (dof 3a+i).
    pub k: Vec<f64>,
    /// Scalar consistent mass `P × P` (the full mass is this ⊗ I₃).
    pub m: Vec<f64>,
    /// Mass, ∫ρ x dV, ∫ρ x xᵀ dV (for free-body inertia).
    pub moments: (f64, [f64; 3], [[f64; 3]; 3]),
}

/// A degenerate or inverted element was met.
#[derive(Debug, Clone, Copy)]
pub struct BadJacobian {
    /// det J at the offending quadrature point (≤ 0 or tiny).
    pub det: f64,
}

/// Jacobian J = ∂x/∂ξ at a point and the physical gradients of the shape functions.
pub(crate) fn physical_gradients(x: &[[f64; 3]], gl: &[[f64; 4]], grad: &mut [[f64; 3]]) -> Result<f64, BadJacobian> {
    // ∂N/∂ξ_k = ∂N/∂L_k − ∂N/∂L_0 (ξ = (L1, L2, L3)); J = Σ_a x_a (∂N_a/∂ξ)ᵀ.
    let dxi = |ga: &[f64; 4]| Vector3::new(ga[1] - ga[0], ga[2] - ga[0], ga[3] - ga[0]);
    let j: Matrix3<f64> = x
        .iter()
        .zip(gl)
        .map(|(xa, ga)| Vector3::from(*xa) * dxi(ga).transpose())
        .sum();
    let det = j.determinant();
    if det.is_nan() || det <= 0.0 || det.is_infinite() {
        return Err(BadJacobian { det });
    }
    // ∇N = J⁻ᵀ ∂N/∂ξ.
    let inv_t = j.try_inverse().ok_or(BadJacobian { det })?.transpose();
    for (g, ga) in grad.iter_mut().zip(gl) {
        *g = (inv_t * dxi(ga)).into();
    }
    Ok(det)
}

/// Stiffness, consistent mass and mass moments of one element with node coordinates `x`.
pub fn element_matrices<S: Shape>(x: &[[f64; 3]], mat: &Lame) -> Result<ElementMatrices, BadJacobian> {
    let p = S::NODES;
    let n3 = 3 * p;
    let mut k = vec![0.0; n3 * n3];
    let mut m = vec![0.0; p * p];
    let mut gl = vec![[0.0; 4]; p];
    let mut grad = vec![[0.0; 3]; p];
    let mut nv = vec![0.0; p];
    for (l, w) in S::curved_stiffness_rule(x).unwrap_or_else(S::stiffness_rule) {
        S::bary_gradients(l, &mut gl);
        let det = physical_gradients(x, &gl, &mut grad)?;
        let f = w * det;
        let (lam, mu) = (mat.lambda * f, mat.mu * f);
        for a in 0..p {
            let ga = grad[a];
            for b in 0..p {
                let gb = grad[b];
                let gg = mu * (ga[0] * gb[0] + ga[1] * gb[1] + ga[2] * gb[2]);
                for i in 0..3 {
                    let row = &mut k[(3 * a + i) * n3 + 3 * b..(3 * a + i) * n3 + 3 * b + 3];
                    for j in 0..3 {
                        row[j] += lam * ga[i] * gb[j] + mu * ga[j] * gb[i];
                    }
                    row[i] += gg;
                }
            }
        }
    }
    let mut mass = 0.0;
    let mut first = [0.0; 3];
    let mut second = [[0.0; 3]; 3];
    for (l, w) in S::mass_rule() {
        S::bary_gradients(l, &mut gl);
        let det = physical_gradients(x, &gl, &mut grad)?;
        S::values(l, &mut nv);
        let f = mat.density * w * det;
        for a in 0..p {
            for b in 0..p {
                m[a * p + b] += f * nv[a] * nv[b];
            }
        }
        let mut xq = [0.0; 3];
        for (xa, na) in x.iter().zip(&nv) {
            for c in 0..3 {
                xq[c] += na * xa[c];
            }
        }
        mass += f;
        for r in 0..3 {
            first[r] += f * xq[r];
            for c in 0..3 {
                second[r][c] += f * xq[r] * xq[c];
            }
        }
    }
    Ok(ElementMatrices {
        k,
        m,
        moments: (mass, first, second),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn random_tet() -> Vec<[f64; 3]> {
        vec![[0.1, 0.0, 0.05], [1.2, 0.1, -0.1], [0.2, 0.9, 0.1], [0.05, 0.2, 1.1]]
    }

    fn tet10_from(v: &[[f64; 3]]) -> Vec<[f64; 3]> {
        let mid = |a: usize, b: usize| {
            [
                (v[a][0] + v[b][0]) / 2.0,
                (v[a][1] + v[b][1]) / 2.0,
                (v[a][2] + v[b][2]) / 2.0,
            ]
        };
        let mut x = v.to_vec();
        for (a, b) in tet10::EDGES {
            x.push(mid(a, b));
        }
        x
    }

    /// K annihilates the six rigid motions; M integrates density to the element mass.
    fn check_invariants<S: Shape>(x: &[[f64; 3]]) {
        let mat = Lame::new(2.0e11, 0.3, 7800.0);
        let e = element_matrices::<S>(x, &mat).expect("valid element");
        let p = S::NODES;
        let n3 = 3 * p;
        let scale = e.k.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let rigid: Vec<Vec<f64>> = (0..6)
            .map(|r| {
                let mut u = vec![0.0; n3];
                for (a, xa) in x.iter().enumerate() {
                    let d = match r {
                        0..=2 => {
                            let mut d = [0.0; 3];
                            d[r] = 1.0;
                            d
                        }
                        3 => [0.0, -xa[2], xa[1]],
                        4 => [xa[2], 0.0, -xa[0]],
                        _ => [-xa[1], xa[0], 0.0],
                    };
                    u[3 * a..3 * a + 3].copy_from_slice(&d);
                }
                u
            })
            .collect();
        for u in &rigid {
            for i in 0..n3 {
                let f: f64 = (0..n3).map(|j| e.k[i * n3 + j] * u[j]).sum();
                assert!(f.abs() < 1e-9 * scale, "rigid motion gives force {f}");
            }
        }
        // Symmetry.
        for i in 0..n3 {
            for j in 0..n3 {
                assert!((e.k[i * n3 + j] - e.k[j * n3 + i]).abs() <= 1e-12 * scale);
            }
        }
        let vol = {
            let d = |a: usize| [x[a][0] - x[0][0], x[a][1] - x[0][1], x[a][2] - x[0][2]];
            let (u, v, w) = (d(1), d(2), d(3));
            (u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0])
                + u[2] * (v[0] * w[1] - v[1] * w[0]))
                / 6.0
        };
        let total: f64 = e.m.iter().sum();
        assert!((total - 7800.0 * vol).abs() < 1e-10 * total);
        assert!((e.moments.0 - 7800.0 * vol).abs() < 1e-10 * total);
    }

    #[test]
    fn tet4_is_rigid_invariant_and_mass_conserving() {
        check_invariants::<tet4::Tet4>(&random_tet());
    }

    #[test]
    fn tet10_is_rigid_invariant_and_mass_conserving() {
        check_invariants::<tet10::Tet10>(&tet10_from(&random_tet()));
    }

    #[test]
    fn tet4_mass_matches_closed_form() {
        // Consistent linear-tet mass: ρV/20 (1 + δ_ab).
        let x = random_tet();
        let e = element_matrices::<tet4::Tet4>(&x, &Lame::new(1.0, 0.25, 1.0)).expect("valid");
        let v = e.moments.0;
        for a in 0..4 {
            for b in 0..4 {
                let exact = v / 20.0 * if a == b { 2.0 } else { 1.0 };
                assert!((e.m[a * 4 + b] - exact).abs() < 1e-14);
            }
        }
    }

    #[test]
    fn tet10_reproduces_a_linear_strain_field_exactly() {
        // Patch-test flavour: under u = A x, K u equals the consistent nodal forces of a
        // constant stress, which sum to zero per direction and make uᵀKu = 2 V W(ε).
        let x = tet10_from(&random_tet());
        let mat = Lame::new(1.0e6, 0.3, 1.0);
        let e = element_matrices::<tet10::Tet10>(&x, &mat).expect("valid");
        let a = [[1e-3, 2e-4, 0.0], [0.0, -5e-4, 3e-4], [1e-4, 0.0, 2e-3]];
        let u: Vec<f64> = x
            .iter()
            .flat_map(|p| (0..3).map(move |i| a[i][0] * p[0] + a[i][1] * p[1] + a[i][2] * p[2]))
            .collect();
        let n = 30;
        let energy: f64 = (0..n)
            .map(|i| u[i] * (0..n).map(|j| e.k[i * n + j] * u[j]).sum::<f64>())
            .sum::<f64>()
            / 2.0;
        let eps = |i: usize, j: usize| 0.5 * (a[i][j] + a[j][i]);
        let tr = eps(0, 0) + eps(1, 1) + eps(2, 2);
        let w: f64 = 0.5 * mat.lambda * tr * tr
            + mat.mu
                * (0..3)
                    .flat_map(|i| (0..3).map(move |j| eps(i, j) * eps(i, j)))
                    .sum::<f64>();
        let vol = e.moments.0; // density 1
        assert!((energy - w * vol).abs() < 1e-10 * energy, "{energy} vs {}", w * vol);
    }

    #[test]
    fn inverted_element_is_rejected() {
        let mut x = random_tet();
        x.swap(1, 2);
        assert!(element_matrices::<tet4::Tet4>(&x, &Lame::new(1.0, 0.3, 1.0)).is_err());
    }
}
