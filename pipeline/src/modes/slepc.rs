//! SLEPc Krylov–Schur in shift-invert with a MUMPS factorisation, over every MPI rank
//! (`ves precompute --solver slepc`, alone or under `mpirun -n N`).
//!
//! Under MPI rank 0 runs the pipeline alone (meshing, assembly, checks, error estimate,
//! writing) and the other ranks only [`serve`] its eigen-solves: for each one rank 0 sends every
//! other rank its share of the rows of K and M and nothing else, all ranks factor and iterate
//! together, and the eigenvectors come back to rank 0 only. So the memory of ranks 1.. is their
//! share of the matrices, the factor and the Krylov vectors, and falls with the number of ranks;
//! rank 0 holds in addition what the whole pipeline needs (mesh, K, M, basis).

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
    /// `None`: shift-invert with MUMPS. Some: Jacobi–Davidson with GAMG, given this near-null
    /// space ([`crate::rigid_motions::on_free_dofs`], 6 values per unknown).
    pub near_null: Option<Vec<f64>>,
}

impl EigenSolver for Slepc {
    #[cfg(feature = "slepc")]
    fn lowest(&self, problem: &EigenProblem<'_>, nev: usize, sigma: f64) -> Result<Spectrum, ModesError> {
        TOKEN.with(|t| {
            let t = t.borrow();
            let token = t
                .as_ref()
                .ok_or_else(|| ModesError::Slepc("SLEPc is not initialised (SlepcGuard::init)".into()))?;
            let n = problem.size();
            let pair = ves_ffi::slepc::SymmetricPair {
                n,
                col_ptr: problem.pattern.col_ptr(),
                row_idx: problem.pattern.row_idx(),
                k: problem.k,
                m: problem.m,
            };
            let e = distribute(token, &pair, self.near_null.as_deref(), nev, sigma, self.tol)
                .map_err(|e| ModesError::Slepc(e.to_string()))?;
            tracing::debug!(iterations = e.iterations, errors = ?e.relative_errors, "SLEPc converged");
            // Ascending (nearest a target below the spectrum is already ascending; make sure).
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
                symbolic: None,
            })
        })
    }

    #[cfg(not(feature = "slepc"))]
    fn lowest(&self, _: &EigenProblem<'_>, _: usize, _: f64) -> Result<Spectrum, ModesError> {
        Err(not_built())
    }
}

/// What rank 0 tells the other ranks (the first word of a [`HEADER`]-word message).
#[cfg(feature = "slepc")]
mod message {
    /// The pipeline is done: return.
    pub const STOP: u64 = 0;
    /// An eigen-solve: its rows follow.
    pub const SOLVE: u64 = 1;
    /// Rank 0 failed outside a solve (and says why itself): return that error.
    pub const FAIL: u64 = 2;
}

/// Words of a message header: kind, order, eigenpairs, entries of the rows sent, target and
/// tolerance (as f64 bits), near-null vectors (0: shift-invert; > 0: the iterative method).
#[cfg(feature = "slepc")]
const HEADER: usize = 7;

/// Near-null vectors per unknown of the iterative method (the rigid-body motions).
#[cfg(feature = "slepc")]
const NEAR_NULL: usize = 6;

/// This rank's rows of `pair`, with their near-null entries when given (iterative method).
#[cfg(feature = "slepc")]
fn rows_of(
    pair: &ves_ffi::slepc::SymmetricPair<'_>,
    near_null: Option<&[f64]>,
    (lo, hi): (usize, usize),
) -> ves_ffi::slepc::LocalRows {
    let mut rows = ves_ffi::slepc::LocalRows::from_lower(pair, lo, hi);
    if let Some(v) = near_null {
        rows.near_null = v[NEAR_NULL * lo..NEAR_NULL * hi].to_vec();
        rows.near_null_count = NEAR_NULL;
    }
    rows
}

/// The method the rows ask for.
#[cfg(feature = "slepc")]
fn method_of(rows: &ves_ffi::slepc::LocalRows) -> ves_ffi::slepc::Method {
    if rows.near_null_count > 0 {
        ves_ffi::slepc::Method::Iterative
    } else {
        ves_ffi::slepc::Method::ShiftInvert
    }
}

/// True while rank 0 is inside a solve the other ranks take part in: an error then may leave
/// them in a collective call, so it must end the job ([`finish`]) rather than be told to them.
#[cfg(feature = "slepc")]
static IN_SOLVE: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Rank 0's side of a solve: every other rank (waiting in [`serve`]) gets its rows, then all
/// solve together.
#[cfg(feature = "slepc")]
fn distribute(
    token: &ves_ffi::slepc::Slepc,
    pair: &ves_ffi::slepc::SymmetricPair<'_>,
    near_null: Option<&[f64]>,
    nev: usize,
    sigma: f64,
    tol: f64,
) -> Result<ves_ffi::slepc::Eigenpairs, ves_ffi::slepc::PetscError> {
    use ves_ffi::slepc::ownership;
    let (n, size) = (pair.n, token.size());
    IN_SOLVE.store(true, std::sync::atomic::Ordering::SeqCst);
    // One rank's rows at a time: rank 0 never holds more than its own and one other share.
    for r in 1..size {
        let rows = rows_of(pair, near_null, ownership(n, size, r));
        let header = [
            message::SOLVE,
            n as u64,
            nev as u64,
            rows.cols.len() as u64,
            sigma.to_bits(),
            tol.to_bits(),
            rows.near_null_count as u64,
        ];
        token.send(r, &header)?;
        token.send(r, &rows.row_ptr)?;
        token.send(r, &rows.cols)?;
        token.send(r, &rows.k)?;
        token.send(r, &rows.m)?;
        token.send(r, &rows.near_null)?;
    }
    let rows = rows_of(pair, near_null, ownership(n, size, 0));
    let method = method_of(&rows);
    let e = token.lowest_eigenpairs(n, rows, nev, sigma, tol, method)?;
    IN_SOLVE.store(false, std::sync::atomic::Ordering::SeqCst);
    Ok(e)
}

/// The life of ranks 1.. under MPI: take part in each eigen-solve rank 0 starts, until it says
/// the pipeline is done (Ok) or failed (an error that rank 0 reports: nothing to print here).
pub fn serve() -> anyhow::Result<()> {
    #[cfg(feature = "slepc")]
    {
        TOKEN.with(|t| -> anyhow::Result<()> {
            let guard = t.borrow();
            let token = guard
                .as_ref()
                .ok_or_else(|| anyhow::anyhow!("SLEPc is not initialised (SlepcGuard::init)"))?;
            loop {
                let h: Vec<u64> = token.receive(0, HEADER)?;
                match h[0] {
                    message::STOP => return Ok(()),
                    message::FAIL => {
                        AGREED.store(true, std::sync::atomic::Ordering::SeqCst);
                        anyhow::bail!("rank 0 failed");
                    }
                    message::SOLVE => {}
                    other => anyhow::bail!("rank 0 sent message kind {other}, which this ves does not know"),
                }
                let (n, nev, nnz) = (h[1] as usize, h[2] as usize, h[3] as usize);
                let (sigma, tol) = (f64::from_bits(h[4]), f64::from_bits(h[5]));
                let (lo, hi) = ves_ffi::slepc::ownership(n, token.size(), token.rank());
                let near_null_count = h[6] as usize;
                let rows = ves_ffi::slepc::LocalRows {
                    lo,
                    hi,
                    row_ptr: token.receive(0, hi - lo + 1)?,
                    cols: token.receive(0, nnz)?,
                    k: token.receive(0, nnz)?,
                    m: token.receive(0, nnz)?,
                    near_null: token.receive(0, near_null_count * (hi - lo))?,
                    near_null_count,
                };
                let method = method_of(&rows);
                token.lowest_eigenpairs(n, rows, nev, sigma, tol, method)?;
            }
        })
    }
    #[cfg(not(feature = "slepc"))]
    Err(not_built().into())
}

/// Rank 0's end of the pipeline under MPI: tells the ranks in [`serve`] to return, with the
/// pipeline's outcome (an error is then every rank's, reported once by rank 0). An error inside
/// a solve is left to [`finish`], which ends the job.
pub fn release<T>(result: anyhow::Result<T>) -> anyhow::Result<T> {
    #[cfg(feature = "slepc")]
    {
        use std::sync::atomic::Ordering::SeqCst;
        if ranks() <= 1 || rank() != 0 || IN_SOLVE.load(SeqCst) {
            return result;
        }
        let kind = if result.is_ok() { message::STOP } else { message::FAIL };
        let told = TOKEN.with(|t| -> Result<(), ves_ffi::slepc::PetscError> {
            if let Some(token) = t.borrow().as_ref() {
                for r in 1..token.size() {
                    token.send(r, &[kind, 0, 0, 0, 0, 0, 0])?;
                }
            }
            Ok(())
        });
        match told {
            Ok(()) => {
                if result.is_err() {
                    AGREED.store(true, SeqCst);
                }
                result
            }
            Err(e) => Err(anyhow::anyhow!("{e}")),
        }
    }
    #[cfg(not(feature = "slepc"))]
    result
}
