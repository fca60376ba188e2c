//! Dense generalized eigen-solve: M = L Lᵀ, C = L⁻¹ K L⁻ᵀ, C = V Λ Vᵀ, Φ = L⁻ᵀ V.
//! O(n³): for small problems and as an independent oracle for the sparse path.

use super::{EigenProblem, EigenSolver, ModesError, Spectrum};
use faer::linalg::triangular_solve::{solve_lower_triangular_in_place, solve_upper_triangular_in_place};
use faer::{Mat, Par, Side};
use std::time::Instant;

/// Dense solver (use up to a few thousand unknowns).
pub struct Dense;

/// Full symmetric matrix from a lower-triangle sparse one.
fn densify(problem: &EigenProblem<'_>, values: &[f64]) -> Mat<f64> {
    let n = problem.size();
    let mut a = Mat::<f64>::zeros(n, n);
    let (cp, ri) = (problem.pattern.col_ptr(), problem.pattern.row_idx());
    for j in 0..n {
        for k in cp[j]..cp[j + 1] {
            a[(ri[k], j)] = values[k];
            a[(j, ri[k])] = values[k];
        }
    }
    a
}

impl EigenSolver for Dense {
    fn lowest(&self, problem: &EigenProblem<'_>, nev: usize, _sigma: f64) -> Result<Spectrum, ModesError> {
        let t = Instant::now();
        let n = problem.size();
        let m = densify(problem, problem.m);
        let mut c = densify(problem, problem.k);
        let llt = m
            .llt(Side::Lower)
            .map_err(|e| ModesError::Dense(format!("mass matrix is not positive definite: {e:?}")))?;
        let l = llt.L();
        // C = L⁻¹ K L⁻ᵀ: solve from the left, transpose, solve again (K symmetric).
        solve_lower_triangular_in_place(l, c.as_mut(), Par::Seq);
        let mut c = c.transpose().to_owned();
        solve_lower_triangular_in_place(l, c.as_mut(), Par::Seq);
        let factorize_s = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let eig = c
            .self_adjoint_eigen(Side::Lower)
            .map_err(|e| ModesError::Dense(format!("{e:?}")))?;
        let s = eig.S().column_vector();
        let mut v = eig.U().subcols(0, nev).to_owned();
        solve_upper_triangular_in_place(l.transpose(), v.as_mut(), Par::Seq);
        let values = (0..nev).map(|i| s[i]).collect();
        let mut vectors = Vec::with_capacity(n * nev);
        for j in 0..nev {
            vectors.extend((0..n).map(|i| v[(i, j)]));
        }
        Ok(Spectrum {
            values,
            vectors,
            factorize_s,
            eigensolve_s: t.elapsed().as_secs_f64(),
        })
    }
}
