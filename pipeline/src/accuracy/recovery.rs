//! A second estimate of each mode's error, on the mesh itself: Zienkiewicz–Zhu recovery. The
//! element stress σ_h of an M-normalised mode is compared with the recovered, continuous σ* (the
//! volume-weighted vertex average, [`crate::fem::stress`]); the energy of the difference,
//! η² = Σ_e ∫_e (σ* − σ_h) : C⁻¹ : (σ* − σ_h) dV, estimates the energy norm of the mode's error,
//! and for an eigenpair that is the eigenvalue's error: λ_h − λ = ‖φ − φ_h‖²_K − λ ‖φ − φ_h‖²_M
//! ≈ η². The element loop is the local-refinement indicator's ([`super::indicator`]).

use super::indicator;
use crate::fem::element::Lame;
use crate::fem::stress::Fields;
use crate::tet_mesh::Mesh;

/// Per field `j` of `u`, its recovered error energy η²_j = Σ_e η²_ej.
pub fn energies(mesh: &Mesh, mat: &Lame, u: &Fields) -> Vec<f64> {
    let r = u.r;
    let eta = indicator::element_energies(mesh, mat, u);
    let mut sum = vec![0.0; r];
    for row in eta.chunks_exact(r.max(1)) {
        sum.iter_mut().zip(row).for_each(|(s, x)| *s += x);
    }
    sum
}

/// The relative frequency error |f_h − f*| / f* of an eigenpair with eigenvalue `lambda`
/// (λ_h = ω², mode M-normalised so that its energy is λ_h) whose error energy is `energy`:
/// λ* = λ_h − η², f_h / f* = √(λ_h / λ*). NaN without a positive eigenvalue. An error energy
/// near the eigenvalue itself (a mesh that far off: 4-node tets locking in bending) is taken as
/// [`LARGEST_SHARE`] of it, so the error is large (9×) but finite.
pub fn relative_frequency_error(lambda: f64, energy: f64) -> f64 {
    if lambda.is_nan() || lambda <= 0.0 || !energy.is_finite() {
        return f64::NAN;
    }
    let eps = (energy.max(0.0) / lambda).min(LARGEST_SHARE);
    (1.0 / (1.0 - eps)).sqrt() - 1.0
}

/// The largest share of a mode's energy taken as error.
pub const LARGEST_SHARE: f64 = 0.99;

/// Per mode, the recovery estimate of its relative frequency error: `modes` on the free DOFs
/// (column-major free × r, M-normalised), `lambda` their eigenvalues.
pub fn estimate(mesh: &Mesh, dofs: &crate::fem::Dofs, mat: &Lame, modes: &[f64], lambda: &[f64]) -> Vec<f64> {
    let nf = dofs.free_count();
    let r = lambda.len().min(modes.len() / nf.max(1));
    if r == 0 {
        return vec![f64::NAN; lambda.len()];
    }
    let energy = energies(mesh, mat, &Fields::from_free(dofs, modes, r));
    let mut out: Vec<f64> = energy
        .iter()
        .zip(lambda)
        .map(|(&e, &l)| relative_frequency_error(l, e))
        .collect();
    out.resize(lambda.len(), f64::NAN);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::element::Kind;

    /// Patch test: on a distorted mesh, a displacement whose stress the elements represent
    /// exactly (linear for 4-node tets: constant stress; quadratic for 10-node tets: linear
    /// stress) has a continuous σ_h, which the recovery reproduces: no recovered error, while a
    /// field one degree higher has some.
    #[test]
    fn recovered_error_vanishes_on_a_patch_test_and_not_beyond() {
        let mat = Lame::new(2.0e11, 0.3, 7800.0);
        // Interior vertices moved by up to 0.2 h: no two elements alike.
        let shake = |ijk: [usize; 3], p: [f64; 3]| {
            let inner = ijk.iter().all(|&i| i > 0 && i < 3);
            let s = |k: usize| {
                if inner {
                    0.01 * ((7 * ijk[k] + 3 * k) % 5) as f64 - 0.02
                } else {
                    0.0
                }
            };
            [p[0] + s(0), p[1] + s(1), p[2] + s(2)]
        };
        for (kind, degree) in [(Kind::Tet4, 1), (Kind::Tet10, 2)] {
            let mesh = Mesh::structured_box([3, 3, 3], 0.1, kind, shake);
            let field = |p: &[f64; 3], d: i32| {
                [
                    1e-3 * p[0].powi(d) + 2e-3 * p[1],
                    5e-4 * p[2].powi(d),
                    1e-3 * p[0] * p[1].powi(d - 1),
                ]
            };
            let energy = |d: i32| {
                let values: Vec<f64> = mesh.nodes.iter().flat_map(|p| field(p, d)).collect();
                energies(&mesh, &mat, &Fields::one(values))[0]
            };
            // The scale: the strain energy of a 1e-3 strain over the 0.3 m cube.
            let scale = mat.mu * 1e-6 * 0.027;
            let exact = energy(degree);
            assert!(
                exact < 1e-20 * scale,
                "{kind:?}: patch test shows {exact:e} (scale {scale:e})"
            );
            let beyond = energy(degree + 1);
            assert!(
                beyond > 1e-6 * scale,
                "{kind:?}: a field beyond the element shows {beyond:e}"
            );
        }
    }

    /// The conversion from error energy to frequency error: half the eigenvalue's relative
    /// error when small, exact (f_h / f* = √(λ_h / λ*)) when not, finite at any size.
    #[test]
    fn error_energy_converts_to_the_frequency_error() {
        let small = relative_frequency_error(1e6, 1e6 * 2e-3);
        assert!((small - 1e-3).abs() < 2e-6, "{small}");
        // λ* = λ_h / 4: f_h = 2 f*, 100 % off.
        let large = relative_frequency_error(4.0, 3.0);
        assert!((large - 1.0).abs() < 1e-12, "{large}");
        let huge = relative_frequency_error(1.0, 10.0);
        assert!(huge.is_finite() && huge > 5.0, "{huge}");
        assert!(relative_frequency_error(0.0, 1.0).is_nan());
        assert_eq!(relative_frequency_error(1.0, 0.0), 0.0);
    }
}
