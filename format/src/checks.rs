//! What physics requires of the values a basis file holds, beyond their being finite: one place,
//! used by the guarded reader and by the runtime's in-memory bases. Each check returns `Err` with
//! what is wrong (the caller names the file and the dataset).

use crate::Block3;

/// Largest damping ratio ζ = α/(2ω) + βω/2 accepted at any stored mode. No solid damps a mode a
/// thousand times beyond critical (it would creep back over 2000/ω seconds); a larger ratio is a
/// unit mistake or a crafted file, and made every runtime step non-finite (β = 1e300).
pub const MAX_DAMPING_RATIO: f64 = 1e3;

/// Largest dimensionless static compliance c·E·L (c the largest diagonal entry of a block, m/N; E
/// Young's modulus; L the diagonal of the space's bounding box). The tip of a 500:1 slender
/// cantilever reaches about 4·500⁴ = 2.5e11; a larger value is no elastic part and makes the
/// felt force vanish.
pub const MAX_DIMENSIONLESS_COMPLIANCE: f64 = 1e12;

/// Most tets per node a mesh may hold (its nodes are uncompressed, its tets deflated: this bounds
/// what reading the tets allocates). A quality tet mesh has about 6 tets per corner vertex and
/// fewer per node with mid-edge nodes; 64 leaves room for any mesh gmsh makes.
pub const MAX_TETS_PER_NODE: usize = 64;

/// Largest magnitude of an entry of a transfer matrix T = Φᵀ M I Φ_from. Its entries are M-inner
/// products of unit modes with interpolated unit modes (Cauchy–Schwarz: |Tᵢⱼ| ≤ ‖I φⱼ‖_M, about
/// 1 up to the interpolation between the two meshes); 2 leaves room for a coarse `from` mesh.
pub const MAX_TRANSFER: f64 = 2.0;

/// Largest magnitude of a load case's value (displacement, von Mises, stress): the runtime and
/// the page hold them in single precision, where a larger one becomes infinite.
pub const MAX_SINGLE: f64 = f32::MAX as f64;

/// Relative tolerance of symmetry (of 3×3 blocks) and of frequencies against √λ/2π.
pub const RELATIVE_TOLERANCE: f64 = 1e-6;

/// Rayleigh damping (α ≥ 0, β ≥ 0, finite) whose damping ratio stays at most
/// [`MAX_DAMPING_RATIO`] at every mode of eigenvalues `eigenvalues` (λ = ω² > 0).
pub fn damping(alpha: f64, beta: f64, eigenvalues: &[f64]) -> Result<(), String> {
    if !(alpha.is_finite() && beta.is_finite() && alpha >= 0.0 && beta >= 0.0) {
        return Err(format!("Rayleigh damping (α {alpha}, β {beta}) must be finite and ≥ 0"));
    }
    // ζ(ω) is convex in ω: its largest value over the modes is at the lowest or the highest.
    let ratio = |l: f64| {
        let w = l.sqrt();
        alpha / (2.0 * w) + beta * w / 2.0
    };
    for l in [eigenvalues.first(), eigenvalues.last()].into_iter().flatten() {
        let z = ratio(*l);
        if z.is_nan() || z > MAX_DAMPING_RATIO {
            return Err(format!(
                "Rayleigh damping (α {alpha} 1/s, β {beta} s) gives a damping ratio of {z:.3e} at {:.4e} Hz, \
                 above {MAX_DAMPING_RATIO:e}: no solid is damped so; check the units of rayleigh_alpha/rayleigh_beta",
                l.sqrt() / (2.0 * std::f64::consts::PI)
            ));
        }
    }
    Ok(())
}

/// Elastic eigenvalues: finite, > 0, ascending (equal neighbours allowed: repeated modes).
pub fn eigenvalues(lambda: &[f64]) -> Result<(), String> {
    if let Some((i, l)) = lambda.iter().enumerate().find(|(_, l)| !(l.is_finite() && **l > 0.0)) {
        return Err(format!("eigenvalue {i} is {l}: elastic eigenvalues are finite and > 0"));
    }
    if let Some(i) = (1..lambda.len()).find(|&i| lambda[i] < lambda[i - 1]) {
        return Err(format!(
            "eigenvalue {i} ({}) is below eigenvalue {} ({}): they must be ascending",
            lambda[i],
            i - 1,
            lambda[i - 1]
        ));
    }
    Ok(())
}

/// Frequencies (Hz) equal to √λ/2π to [`RELATIVE_TOLERANCE`].
pub fn frequencies(lambda: &[f64], hz: &[f64]) -> Result<(), String> {
    if lambda.len() != hz.len() {
        return Err(format!("{} frequencies for {} eigenvalues", hz.len(), lambda.len()));
    }
    for (i, (&l, &f)) in lambda.iter().zip(hz).enumerate() {
        let want = l.sqrt() / (2.0 * std::f64::consts::PI);
        if f.is_nan() || (f - want).abs() > RELATIVE_TOLERANCE * want {
            return Err(format!(
                "frequency {i} is {f} Hz but its eigenvalue {l} gives {want} Hz (√λ/2π)"
            ));
        }
    }
    Ok(())
}

/// A 3×3 block that is finite, symmetric to [`RELATIVE_TOLERANCE`], zero in the rows and columns
/// of the components not in `free`, and positive definite on the others (Cholesky of the block
/// scaled to unit largest entry, so tiny or huge values neither underflow nor overflow).
/// Returns the largest diagonal entry.
pub fn symmetric_positive_definite(b: &Block3, free: [bool; 3]) -> Result<f64, String> {
    if b.iter().flatten().any(|v| !v.is_finite()) {
        return Err("a value is not finite".into());
    }
    let scale = b.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    if scale == 0.0 {
        return if free.iter().any(|&f| f) {
            Err("the block is zero at a node that is not fully supported".into())
        } else {
            Ok(0.0)
        };
    }
    for i in 0..3 {
        for j in 0..3 {
            if (b[i][j] - b[j][i]).abs() > RELATIVE_TOLERANCE * scale {
                return Err(format!(
                    "not symmetric: entry ({i}, {j}) is {} and ({j}, {i}) is {}",
                    b[i][j], b[j][i]
                ));
            }
            if (!free[i] || !free[j]) && b[i][j].abs() > RELATIVE_TOLERANCE * scale {
                return Err(format!(
                    "entry ({i}, {j}) is {} but component {} is supported (must be 0)",
                    b[i][j],
                    if free[i] { j } else { i }
                ));
            }
        }
    }
    let idx: Vec<usize> = (0..3).filter(|&i| free[i]).collect();
    let k = idx.len();
    let mut l = [[0.0f64; 3]; 3];
    for a in 0..k {
        for c in 0..=a {
            let s = 0.5 * (b[idx[a]][idx[c]] + b[idx[c]][idx[a]]) / scale
                - l[a][..c].iter().zip(&l[c][..c]).map(|(x, y)| x * y).sum::<f64>();
            if a == c {
                if s.is_nan() || s <= 0.0 {
                    return Err(format!(
                        "not positive definite (pivot {a} is {:.3e}): it must be positive in every unsupported direction",
                        s * scale
                    ));
                }
                l[a][a] = s.sqrt();
            } else {
                l[a][c] = s / l[c][c];
            }
        }
    }
    Ok((0..3).map(|i| b[i][i]).fold(0.0, f64::max))
}

/// A load case's stated largest value `stated` (attribute `max_displacement` or `max_von_mises`)
/// equal to the largest of its data, `found`, to [`RELATIVE_TOLERANCE`].
pub fn stated_max(stated: f64, found: f64) -> Result<(), String> {
    if (stated - found).abs() <= RELATIVE_TOLERANCE * stated.abs().max(found.abs()) {
        Ok(())
    } else {
        Err(format!("says {stated:e} but its data's largest value is {found:e}"))
    }
}

/// Surface triangles: three distinct corner vertices each (a repeated index is no triangle).
pub fn triangles(t: &[u32]) -> Result<(), String> {
    match t
        .chunks_exact(3)
        .position(|t| t[0] == t[1] || t[1] == t[2] || t[0] == t[2])
    {
        Some(i) => Err(format!(
            "triangle {i} {:?} repeats a vertex: a triangle has three distinct corners",
            &t[3 * i..3 * i + 3]
        )),
        None => Ok(()),
    }
}

/// Tets of `per` nodes each: no node twice in one tet (a degenerate element has no volume).
pub fn tets(t: &[u32], per: usize) -> Result<(), String> {
    for (i, e) in t.chunks_exact(per.max(1)).enumerate() {
        for a in 0..e.len() {
            if e[a + 1..].contains(&e[a]) {
                return Err(format!("tet {i} {e:?} repeats node {}: a tet has distinct nodes", e[a]));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_must_be_symmetric_positive_definite_and_zero_where_supported() {
        let good = [[2e-9, 1e-9, 0.0], [1e-9, 2e-9, 0.0], [0.0, 0.0, 1e-9]];
        assert_eq!(symmetric_positive_definite(&good, [true; 3]), Ok(2e-9));
        let anti = [[1e-9, 1e-9, 0.0], [-1e-9, 1e-9, 0.0], [0.0, 0.0, 1e-9]];
        assert!(
            symmetric_positive_definite(&anti, [true; 3])
                .unwrap_err()
                .contains("symmetric")
        );
        let neg = [[-1e-9, 0.0, 0.0], [0.0, 1e-9, 0.0], [0.0, 0.0, 1e-9]];
        assert!(
            symmetric_positive_definite(&neg, [true; 3])
                .unwrap_err()
                .contains("positive definite")
        );
        let indefinite = [[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert!(symmetric_positive_definite(&indefinite, [true; 3]).is_err());
        let z_fixed = [[2e-9, 0.0, 0.0], [0.0, 1e-9, 0.0], [0.0, 0.0, 0.0]];
        assert!(symmetric_positive_definite(&z_fixed, [true, true, false]).is_ok());
        assert!(symmetric_positive_definite(&z_fixed, [true; 3]).is_err());
        assert!(symmetric_positive_definite(&good, [true, true, false]).is_err());
        assert!(symmetric_positive_definite(&[[0.0; 3]; 3], [false; 3]).is_ok());
        let tiny = good.map(|r| r.map(|v| v * 1e-290));
        assert!(symmetric_positive_definite(&tiny, [true; 3]).is_ok());
    }

    #[test]
    fn damping_eigenvalues_frequencies_and_elements() {
        let lam = [1e4, 4e6, 4e6, 1e10];
        assert!(damping(0.1, 1e-5, &lam).is_ok());
        assert!(damping(0.0, 1e300, &lam).is_err());
        assert!(damping(1e300, 0.0, &lam).is_err());
        assert!(damping(-1.0, 0.0, &lam).is_err());
        assert!(eigenvalues(&lam).is_ok());
        assert!(eigenvalues(&[4.0, 1.0]).is_err());
        assert!(eigenvalues(&[-1.0]).is_err());
        let hz: Vec<f64> = lam.iter().map(|l| l.sqrt() / (2.0 * std::f64::consts::PI)).collect();
        assert!(frequencies(&lam, &hz).is_ok());
        assert!(frequencies(&lam, &hz.iter().map(|f| -f).collect::<Vec<_>>()).is_err());
        assert!(frequencies(&lam, &hz.iter().map(|f| f * 1.001).collect::<Vec<_>>()).is_err());
        assert!(triangles(&[0, 1, 2, 0, 0, 0]).is_err());
        assert!(triangles(&[0, 1, 2]).is_ok());
        assert!(tets(&[0, 1, 2, 3, 0, 1, 2, 2], 4).is_err());
        assert!(tets(&[0, 1, 2, 3], 4).is_ok());
    }
}
