//! SLEPc Krylov–Schur in shift-invert with a MUMPS factorisation, over every MPI rank
//! (`ves precompute --solver slepc`, alone or under `mpirun -n N`). Each rank holds the same
//! K and M (meshing and assembly are repeated on every rank: gmsh is deterministic) and inserts
//! its share of the rows into PETSc's distributed matrices; the factorisation and the
//! eigen-solve are distributed, the eigenvectors gathered back to every rank.

use super::{EigenProblem, EigenSolver, ModesError, Spectrum};

#[cfg(feature = "slepc")]
thread_local! {
    static TOKEN: std::cell::RefCell<Option<ves_ffi::slepc::Slepc>> = const { std::cell::RefCell::new(None) };
}

#[cfg(not(feature = "slepc"))]
fn not_built() -> ModesError {
    ModesError::Slepc(
        "this ves was built without SLEPc: install libslepc-real-dev and build with `--features slepc`".into(),
    )
}

/// SLEPc initialised on this thread for the life of the guard (MPI too; finalised on drop).
pub struct SlepcGuard(());

impl SlepcGuard {
    /// Initialises SLEPc and MPI (once per process).
    pub fn init() -> Result<SlepcGuard, ModesError> {
        #[cfg(feature = "slepc")]
        {
            let token = ves_ffi::slepc::Slepc::init().map_err(|e| ModesError::Slepc(e.to_string()))?;
            TOKEN.with(|t| *t.borrow_mut() = Some(token));
            Ok(SlepcGuard(()))
        }
        #[cfg(not(feature = "slepc"))]
        Err(not_built())
    }
}

impl Drop for SlepcGuard {
    fn drop(&mut self) {
        #[cfg(feature = "slepc")]
        TOKEN.with(|t| drop(t.borrow_mut().take()));
    }
}

/// This process's MPI rank (0 without SLEPc).
pub fn rank() -> usize {
    #[cfg(feature = "slepc")]
    {
        TOKEN.with(|t| t.borrow().as_ref().map_or(0, |s| s.rank()))
    }
    #[cfg(not(feature = "slepc"))]
    0
}

/// Number of MPI ranks (1 without SLEPc).
pub fn ranks() -> usize {
    #[cfg(feature = "slepc")]
    {
        TOKEN.with(|t| t.borrow().as_ref().map_or(1, |s| s.size()))
    }
    #[cfg(not(feature = "slepc"))]
    1
}

/// The SLEPc solver (needs a [`SlepcGuard`] on this thread).
pub struct Slepc {
    /// Relative tolerance of the eigenpairs.
    pub tol: f64,
}

impl EigenSolver for Slepc {
    #[cfg(feature = "slepc")]
    fn lowest(&self, problem: &EigenProblem<'_>, nev: usize, sigma: f64) -> Result<Spectrum, ModesError> {
        TOKEN.with(|t| {
            let t = t.borrow();
            let token = t
                .as_ref()
                .ok_or_else(|| ModesError::Slepc("SLEPc is not initialised (SlepcGuard::init)".into()))?;
            let pair = ves_ffi::slepc::SymmetricPair {
                n: problem.size(),
                col_ptr: problem.pattern.col_ptr(),
                row_idx: problem.pattern.row_idx(),
                k: problem.k,
                m: problem.m,
            };
            let e = token
                .lowest_eigenpairs(&pair, nev, sigma, self.tol)
                .map_err(|e| ModesError::Slepc(e.to_string()))?;
            tracing::debug!(iterations = e.iterations, errors = ?e.relative_errors, "SLEPc converged");
            // Ascending (nearest a target below the spectrum is already ascending; make sure).
            let n = problem.size();
            let mut order: Vec<usize> = (0..e.values.len()).collect();
            order.sort_by(|&a, &b| e.values[a].total_cmp(&e.values[b]));
            let values = order.iter().map(|&i| e.values[i]).collect();
            let vectors = order
                .iter()
                .flat_map(|&i| e.vectors[i * n..(i + 1) * n].iter().copied())
                .collect();
            Ok(Spectrum {
                values,
                vectors,
                factorize_s: e.setup_s,
                eigensolve_s: e.solve_s,
            })
        })
    }

    #[cfg(not(feature = "slepc"))]
    fn lowest(&self, _: &EigenProblem<'_>, _: usize, _: f64) -> Result<Spectrum, ModesError> {
        Err(not_built())
    }
}
