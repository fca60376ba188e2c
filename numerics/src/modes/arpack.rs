//! ARPACK shift-invert Lanczos; each step solves with one sparse Cholesky factor of K − σM.

use super::{EigenProblem, EigenSolver, ModesError, Spectrum};
use crate::linsolve::sym_matvec;
use std::time::Instant;
use ves_arpack::{ShiftInvert, shift_invert};

/// ARPACK with a METIS-ordered sparse Cholesky factorisation.
pub struct Arpack<'g> {
    /// K and M.
    pub problem: &'g EigenProblem<'g>,
    /// Fill-reducing ordering of the free DOFs (new→old, old→new).
    pub ordering: &'g (Vec<usize>, Vec<usize>),
    /// ARPACK tolerance on the Ritz values.
    pub tol: f64,
}

impl EigenSolver for Arpack<'_> {
    fn lowest(&self, nev: usize, sigma: f64) -> Result<Spectrum, ModesError> {
        let problem = self.problem;
        let t = Instant::now();
        let mut chol = super::factor_shifted(problem, self.ordering, sigma)?;
        let factorize_s = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let cfg = ShiftInvert {
            nev,
            ncv: 0,
            sigma,
            tol: self.tol,
            max_restarts: 1000,
        };
        let check = |y: &[f64]| {
            if y.iter().all(|v| v.is_finite()) {
                Ok(())
            } else {
                Err("non-finite value in a solve".to_string())
            }
        };
        let pairs = shift_invert(
            problem.size(),
            &cfg,
            |x, y| {
                y.copy_from_slice(x);
                chol.solve_in_place(y);
                check(y)
            },
            |x, y| {
                sym_matvec(problem.pattern, problem.m, x, y);
                Ok(())
            },
        )?;
        tracing::debug!(restarts = pairs.restarts, solves = pairs.solves, "ARPACK converged");
        Ok(Spectrum {
            values: pairs.values,
            vectors: pairs.vectors,
            factorize_s,
            eigensolve_s: t.elapsed().as_secs_f64(),
            factored: Some(super::Factored::of(chol, sigma)),
            checked: None,
        })
    }
}
