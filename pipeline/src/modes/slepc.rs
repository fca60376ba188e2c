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

/// Whether an error has been made every rank's by [`agree`] (then no rank waits for another,
/// and the job ends cleanly).
#[cfg(feature = "slepc")]
static AGREED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Longest error message [`agree`] passes between ranks, bytes (longer ones are cut).
#[cfg(feature = "slepc")]
const MESSAGE_BYTES: usize = 2048;

/// A step that may fail on some ranks and not others (reading the scene, checking the output),
/// made collective: every rank passes its own result of the same step, and if any rank failed,
/// every rank returns the error of the lowest failing rank (its message, prefixed with the rank
/// when it is not rank 0), so that all ranks stop together and rank 0 alone reports it. Without
/// MPI (or on one rank) the result is returned as it is. Collective: every rank must call it at
/// the same point.
pub fn agree<T>(result: anyhow::Result<T>) -> anyhow::Result<T> {
    #[cfg(feature = "slepc")]
    {
        if ranks() <= 1 {
            return result;
        }
        let me = rank();
        let failed = result.is_err();
        let reduced = TOKEN.with(|t| -> Result<Option<String>, ves_ffi::slepc::PetscError> {
            let guard = t.borrow();
            let Some(mpi) = guard.as_ref() else {
                return Ok(None);
            };
            let mut first = [if failed { me as i32 } else { i32::MAX }];
            mpi.min_over_ranks(&mut first)?;
            if first[0] == i32::MAX {
                return Ok(None);
            }
            // The failing rank's message, one byte per int, summed with everyone else's zeros.
            let mut text = vec![0i32; MESSAGE_BYTES];
            if let (true, Err(e)) = (first[0] as usize == me, &result) {
                let message = format!("{e:#}");
                let mut end = message.len().min(MESSAGE_BYTES);
                while !message.is_char_boundary(end) {
                    end -= 1;
                }
                for (slot, byte) in text.iter_mut().zip(message[..end].bytes()) {
                    *slot = byte as i32;
                }
            }
            mpi.sum_over_ranks(&mut text)?;
            let bytes: Vec<u8> = text.iter().take_while(|&&b| b != 0).map(|&b| b as u8).collect();
            let message = String::from_utf8_lossy(&bytes).into_owned();
            Ok(Some(if first[0] == 0 {
                message
            } else {
                format!("MPI rank {}: {message}", first[0])
            }))
        });
        match reduced {
            Ok(None) => result,
            Ok(Some(message)) => {
                AGREED.store(true, std::sync::atomic::Ordering::SeqCst);
                Err(anyhow::anyhow!(message))
            }
            // MPI itself failed: no agreement is possible; [`finish`] aborts the job.
            Err(e) => Err(anyhow::anyhow!("{e}")),
        }
    }
    #[cfg(not(feature = "slepc"))]
    result
}

/// The end of a command under MPI: an error that [`agree`] did not make every rank's may have
/// left other ranks waiting in a collective call, so it is printed here (with its rank) and the
/// whole job is ended (`MPI_Abort`, exit status 1 on every rank). Anything else is returned.
/// Call it before the [`SlepcGuard`] is dropped (finalising MPI would wait for the stuck ranks).
pub fn finish<T>(result: anyhow::Result<T>) -> anyhow::Result<T> {
    #[cfg(feature = "slepc")]
    if let Err(e) = &result
        && ranks() > 1
        && !AGREED.load(std::sync::atomic::Ordering::SeqCst)
    {
        eprintln!("error: MPI rank {} of {}: {e:#}; ending every rank", rank(), ranks());
        TOKEN.with(|t| {
            if let Some(mpi) = t.borrow().as_ref() {
                mpi.abort(1)
            }
        });
    }
    result
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
