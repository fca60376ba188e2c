//! What physics requires of the values a basis file holds, beyond their being finite: one place,
//! used by the guarded reader and by the runtime's in-memory bases. Each check returns a
//! [`CheckError`] saying what is wrong (the caller names the file and the dataset).

use crate::Block3;

/// A stored value that physics does not allow; the message says what is wrong, without the file
/// and the dataset (the caller adds them).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CheckError {
    /// Rayleigh damping with a negative or non-finite coefficient.
    #[error("Rayleigh damping (α {alpha}, β {beta}) must be finite and ≥ 0")]
    DampingSign {
        /// α, 1/s.
        alpha: f64,
        /// β, s.
        beta: f64,
    },
    /// Rayleigh damping whose damping ratio exceeds [`MAX_DAMPING_RATIO`] at a stored mode.
    #[error(
        "Rayleigh damping (α {alpha} 1/s, β {beta} s) gives a damping ratio of {ratio:.3e} at {hz:.4e} Hz, \
         above {MAX_DAMPING_RATIO:e}: no solid is damped so; check the units of rayleigh_alpha/rayleigh_beta"
    )]
    DampingRatio {
        /// α, 1/s.
        alpha: f64,
        /// β, s.
        beta: f64,
        /// The damping ratio ζ at that mode.
        ratio: f64,
        /// The mode's frequency, Hz.
        hz: f64,
    },
    /// An eigenvalue that is not finite and positive.
    #[error("eigenvalue {index} is {value}: elastic eigenvalues are finite and > 0")]
    Eigenvalue {
        /// Its index.
        index: usize,
        /// Its value.
        value: f64,
    },
    /// An eigenvalue below the one before it.
    #[error("eigenvalue {index} ({value}) is below eigenvalue {} ({previous}): they must be ascending", .index - 1)]
    Descending {
        /// Its index (≥ 1).
        index: usize,
        /// Its value.
        value: f64,
        /// The value of eigenvalue `index − 1`.
        previous: f64,
    },
    /// Not one frequency per eigenvalue.
    #[error("{frequencies} frequencies for {eigenvalues} eigenvalues")]
    FrequencyCount {
        /// Frequencies stored.
        frequencies: usize,
        /// Eigenvalues stored.
        eigenvalues: usize,
    },
    /// A frequency that is not √λ/2π of its eigenvalue.
    #[error("frequency {index} is {hz} Hz but its eigenvalue {eigenvalue} gives {expected} Hz (√λ/2π)")]
    Frequency {
        /// Its index.
        index: usize,
        /// The frequency stored, Hz.
        hz: f64,
        /// Its eigenvalue.
        eigenvalue: f64,
        /// √λ/2π, Hz.
        expected: f64,
    },
    /// A 3×3 block with a value that is not finite.
    #[error("a value is not finite")]
    NotFinite,
    /// A zero block at a node with a free component.
    #[error("the block is zero at a node that is not fully supported")]
    ZeroBlock,
    /// A block that is not symmetric.
    #[error("not symmetric: entry ({i}, {j}) is {ij} and ({j}, {i}) is {ji}")]
    Asymmetric {
        /// Row.
        i: usize,
        /// Column.
        j: usize,
        /// Entry (i, j).
        ij: f64,
        /// Entry (j, i).
        ji: f64,
    },
    /// A block with a non-zero entry in a supported component's row or column.
    #[error("entry ({i}, {j}) is {value} but component {component} is supported (must be 0)")]
    Supported {
        /// Row.
        i: usize,
        /// Column.
        j: usize,
        /// The entry.
        value: f64,
        /// The supported component.
        component: usize,
    },
    /// A block that is not positive definite on its free components.
    #[error("not positive definite (pivot {pivot} is {value:.3e}): it must be positive in every unsupported direction")]
    NotPositiveDefinite {
        /// The pivot of the Cholesky factorisation that failed.
        pivot: usize,
        /// Its value (in the block's units).
        value: f64,
    },
    /// A load case's stated largest value that its data does not reach.
    #[error("says {stated:e} but its data's largest value is {found:e}")]
    StatedMax {
        /// The attribute's value.
        stated: f64,
        /// The data's largest value.
        found: f64,
    },
    /// A surface triangle with a repeated corner.
    #[error("triangle {index} {corners:?} repeats a vertex: a triangle has three distinct corners")]
    Triangle {
        /// Its index.
        index: usize,
        /// Its corners.
        corners: [u32; 3],
    },
    /// A tet with a repeated node.
    #[error("tet {index} {nodes:?} repeats node {node}: a tet has distinct nodes")]
    Tet {
        /// Its index.
        index: usize,
        /// Its nodes.
        nodes: Vec<u32>,
        /// The node it holds twice.
        node: u32,
    },
}

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
pub fn damping(alpha: f64, beta: f64, eigenvalues: &[f64]) -> Result<(), CheckError> {
    if !(alpha.is_finite() && beta.is_finite() && alpha >= 0.0 && beta >= 0.0) {
        return Err(CheckError::DampingSign { alpha, beta });
    }
    // ζ(ω) is convex in ω: its largest value over the modes is at the lowest or the highest.
    let ratio = |l: f64| {
        let w = l.sqrt();
        alpha / (2.0 * w) + beta * w / 2.0
    };
    for l in [eigenvalues.first(), eigenvalues.last()].into_iter().flatten() {
        let z = ratio(*l);
        if z.is_nan() || z > MAX_DAMPING_RATIO {
            return Err(CheckError::DampingRatio {
                alpha,
                beta,
                ratio: z,
                hz: l.sqrt() / (2.0 * std::f64::consts::PI),
            });
        }
    }
    Ok(())
}

/// Elastic eigenvalues: finite, > 0, ascending (equal neighbours allowed: repeated modes).
pub fn eigenvalues(lambda: &[f64]) -> Result<(), CheckError> {
    if let Some((index, &value)) = lambda.iter().enumerate().find(|(_, l)| !(l.is_finite() && **l > 0.0)) {
        return Err(CheckError::Eigenvalue { index, value });
    }
    if let Some(index) = (1..lambda.len()).find(|&i| lambda[i] < lambda[i - 1]) {
        return Err(CheckError::Descending {
            index,
            value: lambda[index],
            previous: lambda[index - 1],
        });
    }
    Ok(())
}

/// Frequencies (Hz) equal to √λ/2π to [`RELATIVE_TOLERANCE`].
pub fn frequencies(lambda: &[f64], hz: &[f64]) -> Result<(), CheckError> {
    if lambda.len() != hz.len() {
        return Err(CheckError::FrequencyCount {
            frequencies: hz.len(),
            eigenvalues: lambda.len(),
        });
    }
    for (index, (&l, &f)) in lambda.iter().zip(hz).enumerate() {
        let want = l.sqrt() / (2.0 * std::f64::consts::PI);
        if f.is_nan() || (f - want).abs() > RELATIVE_TOLERANCE * want {
            return Err(CheckError::Frequency {
                index,
                hz: f,
                eigenvalue: l,
                expected: want,
            });
        }
    }
    Ok(())
}

/// A 3×3 block that is finite, symmetric to [`RELATIVE_TOLERANCE`], zero in the rows and columns
/// of the components not in `free`, and positive definite on the others (Cholesky of the block
/// scaled to unit largest entry, so tiny or huge values neither underflow nor overflow).
/// Returns the largest diagonal entry.
pub fn symmetric_positive_definite(b: &Block3, free: [bool; 3]) -> Result<f64, CheckError> {
    if b.iter().flatten().any(|v| !v.is_finite()) {
        return Err(CheckError::NotFinite);
    }
    let scale = b.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    if scale == 0.0 {
        return if free.iter().any(|&f| f) {
            Err(CheckError::ZeroBlock)
        } else {
            Ok(0.0)
        };
    }
    for i in 0..3 {
        for j in 0..3 {
            if (b[i][j] - b[j][i]).abs() > RELATIVE_TOLERANCE * scale {
                return Err(CheckError::Asymmetric {
                    i,
                    j,
                    ij: b[i][j],
                    ji: b[j][i],
                });
            }
            if (!free[i] || !free[j]) && b[i][j].abs() > RELATIVE_TOLERANCE * scale {
                return Err(CheckError::Supported {
                    i,
                    j,
                    value: b[i][j],
                    component: if free[i] { j } else { i },
                });
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
                    return Err(CheckError::NotPositiveDefinite {
                        pivot: a,
                        value: s * scale,
                    });
                }
                l[a][a] = s.sqrt();
            } else {
                l[a][c] = s / l[c][c];
            }
        }
    }
    Ok((0..3).map(|i| b[i][i]).fold(0.0, f64::max))
}

/// Whether these vectors are linearly independent: Gram–Schmidt, each vector's part outside the
/// ones before it at least 1e-9 of its own length.
pub fn independent<const N: usize>(vectors: &[[f64; N]]) -> bool {
    let mut basis: Vec<[f64; N]> = Vec::with_capacity(vectors.len());
    for v in vectors {
        let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        let mut w = *v;
        for _ in 0..2 {
            for b in &basis {
                let d: f64 = w.iter().zip(b).map(|(x, y)| x * y).sum();
                w.iter_mut().zip(b).for_each(|(x, y)| *x -= d * y);
            }
        }
        let left = w.iter().map(|x| x * x).sum::<f64>().sqrt();
        if left.is_nan() || left <= 1e-9 * norm {
            return false;
        }
        basis.push(w.map(|x| x / left));
    }
    true
}

/// A load case's stated largest value `stated` (attribute `max_displacement` or `max_von_mises`)
/// equal to the largest of its data, `found`, to [`RELATIVE_TOLERANCE`].
pub fn stated_max(stated: f64, found: f64) -> Result<(), CheckError> {
    if (stated - found).abs() <= RELATIVE_TOLERANCE * stated.abs().max(found.abs()) {
        Ok(())
    } else {
        Err(CheckError::StatedMax { stated, found })
    }
}

/// Surface triangles: three distinct corner vertices each (a repeated index is no triangle).
pub fn triangles(t: &[u32]) -> Result<(), CheckError> {
    match t
        .chunks_exact(3)
        .position(|t| t[0] == t[1] || t[1] == t[2] || t[0] == t[2])
    {
        Some(index) => Err(CheckError::Triangle {
            index,
            corners: [t[3 * index], t[3 * index + 1], t[3 * index + 2]],
        }),
        None => Ok(()),
    }
}

/// Tets of `per` nodes each: no node twice in one tet (a degenerate element has no volume).
pub fn tets(t: &[u32], per: usize) -> Result<(), CheckError> {
    for (index, e) in t.chunks_exact(per.max(1)).enumerate() {
        for a in 0..e.len() {
            if e[a + 1..].contains(&e[a]) {
                return Err(CheckError::Tet {
                    index,
                    nodes: e.to_vec(),
                    node: e[a],
                });
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
                .to_string()
                .contains("symmetric")
        );
        let neg = [[-1e-9, 0.0, 0.0], [0.0, 1e-9, 0.0], [0.0, 0.0, 1e-9]];
        assert!(
            symmetric_positive_definite(&neg, [true; 3])
                .unwrap_err()
                .to_string()
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
