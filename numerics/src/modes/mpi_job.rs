//! The MPI job of `ves precompute --solver slepc` (alone or under `mpirun -n N`): SLEPc and MPI
//! brought up and down ([`SlepcGuard`]), this process's rank, steps every rank must agree on
//! ([`agree`]), the life of ranks 1.. ([`serve`]) and the job's end ([`release`], [`finish`]).
//!
//! Under MPI rank 0 runs the pipeline (meshing, checks of the scene, writing) and the other
//! ranks only [`serve`] its eigen-solves ([`super::slepc`]): rank 0 tells them what to do in
//! messages of [`HEADER`] words, the first one of which is a [`message`] kind.
//!
//! Built only with the `slepc` feature; without it `mpi_job_off.rs` stands in (one rank, no MPI).

use super::ModesError;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering::SeqCst};

thread_local! {
    static TOKEN: std::cell::RefCell<Option<ves_slepc::Slepc>> = const { std::cell::RefCell::new(None) };
}

/// This process's MPI rank, set once MPI is up and kept after it is finalised (the last error
/// is reported by rank 0 alone, after the guard is gone).
static RANK: AtomicUsize = AtomicUsize::new(0);

/// SLEPc initialised on this thread for the life of the guard (MPI too; finalised on drop).
pub struct SlepcGuard(());

impl SlepcGuard {
    /// Initialises SLEPc and MPI (once per process).
    pub fn init() -> Result<SlepcGuard, ModesError> {
        let token = ves_slepc::Slepc::init().map_err(|e| ModesError::Slepc(e.to_string()))?;
        RANK.store(token.rank(), SeqCst);
        TOKEN.with(|t| *t.borrow_mut() = Some(token));
        Ok(SlepcGuard(()))
    }
}

impl Drop for SlepcGuard {
    fn drop(&mut self) {
        TOKEN.with(|t| drop(t.borrow_mut().take()));
    }
}

/// This process's MPI rank (0 without MPI).
pub fn rank() -> usize {
    RANK.load(SeqCst)
}

/// Number of MPI ranks (1 without MPI, or once it is finalised).
pub fn ranks() -> usize {
    TOKEN.with(|t| t.borrow().as_ref().map_or(1, |s| s.size()))
}

/// Runs `f` with SLEPc's handle (an error when [`SlepcGuard::init`] was not called).
pub(super) fn with_token<T>(f: impl FnOnce(&ves_slepc::Slepc) -> Result<T, ModesError>) -> Result<T, ModesError> {
    TOKEN.with(|t| {
        let guard = t.borrow();
        let token = guard
            .as_ref()
            .ok_or_else(|| ModesError::Slepc("SLEPc is not initialised (SlepcGuard::init)".into()))?;
        f(token)
    })
}

/// Whether an error has been made every rank's by [`agree`] (then no rank waits for another,
/// and the job ends cleanly).
static AGREED: AtomicBool = AtomicBool::new(false);

/// True while rank 0 is in a step every rank takes part in: an error then may leave the others
/// in a collective call, so it must end the job ([`finish`]) rather than be told to them.
pub(super) static IN_SOLVE: AtomicBool = AtomicBool::new(false);

/// Longest error message [`agree`] passes between ranks, bytes (longer ones are cut).
const MESSAGE_BYTES: usize = 2048;

/// What rank 0 tells the other ranks (the first word of a [`HEADER`]-word message).
pub(super) mod message {
    /// The pipeline is done: return.
    pub const STOP: u64 = 0;
    /// An eigen-solve on the operators assembled last: nev, σ, tolerance, method.
    pub const SOLVE: u64 = 1;
    /// Rank 0 failed outside a solve (and says why itself): return that error.
    pub const FAIL: u64 = 2;
    /// A share of a new problem follows: assemble its rows (the operators of the solves after).
    pub const ASSEMBLE: u64 = 3;
    /// The problem's solves are done: free its operators.
    pub const RELEASE: u64 = 4;
}

/// Words of a message header: its kind, then the kind's numbers.
pub(super) const HEADER: usize = 12;

/// A message header of `kind` with its numbers.
pub(super) fn header(kind: u64, words: &[u64]) -> [u64; HEADER] {
    let mut h = [0; HEADER];
    h[0] = kind;
    h[1..=words.len()].copy_from_slice(words);
    h
}

/// A step that may fail on some ranks and not others (reading the scene, checking the output),
/// made collective: every rank passes its own result of the same step, and if any rank failed,
/// every rank returns the error of the lowest failing rank (its message, prefixed with the rank
/// when it is not rank 0), so that all ranks stop together and rank 0 alone reports it. Without
/// MPI (or on one rank) the result is returned as it is. Collective: every rank must call it at
/// the same point.
pub fn agree<T>(result: anyhow::Result<T>) -> anyhow::Result<T> {
    if ranks() <= 1 {
        return result;
    }
    let me = rank();
    let failed = result.is_err();
    let reduced = TOKEN.with(|t| -> Result<Option<String>, ves_slepc::PetscError> {
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
            AGREED.store(true, SeqCst);
            Err(anyhow::anyhow!(message))
        }
        // MPI itself failed: no agreement is possible; [`finish`] aborts the job.
        Err(e) => Err(anyhow::anyhow!("{e}")),
    }
}

/// The end of a command under MPI: an error that [`agree`] did not make every rank's may have
/// left other ranks waiting in a collective call, so it is printed here (with its rank) and the
/// whole job is ended (`MPI_Abort`, exit status 1 on every rank). Anything else is returned.
/// Call it before the [`SlepcGuard`] is dropped (finalising MPI would wait for the stuck ranks).
pub fn finish<T>(result: anyhow::Result<T>) -> anyhow::Result<T> {
    if let Err(e) = &result
        && ranks() > 1
        && !AGREED.load(SeqCst)
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

/// The life of ranks 1.. under MPI: assemble each problem rank 0 sends a share of and take part
/// in its eigen-solves, until rank 0 says the pipeline is done (Ok) or failed (an error that rank
/// 0 reports: nothing to print here).
pub fn serve() -> anyhow::Result<()> {
    TOKEN.with(|t| {
        let guard = t.borrow();
        let token = guard
            .as_ref()
            .ok_or_else(|| anyhow::anyhow!("SLEPc is not initialised (SlepcGuard::init)"))?;
        serve_with(token)
    })
}

/// [`serve`] with SLEPc's handle.
fn serve_with(token: &ves_slepc::Slepc) -> anyhow::Result<()> {
    let mut ops = None;
    loop {
        let h: Vec<u64> = token.receive(0, HEADER)?;
        match h[0] {
            message::STOP => return Ok(()),
            message::FAIL => {
                AGREED.store(true, SeqCst);
                anyhow::bail!("rank 0 failed");
            }
            message::RELEASE => ops = None,
            message::ASSEMBLE => {
                // The last problem's matrices go before this one's are built.
                drop(ops.take());
                ops = Some(super::slepc::assemble_share(token, &h)?);
            }
            message::SOLVE => {
                let o = ops
                    .as_ref()
                    .ok_or_else(|| anyhow::anyhow!("rank 0 asked for a solve before an assembly"))?;
                let method = if h[4] == 1 {
                    ves_slepc::Method::Iterative
                } else {
                    ves_slepc::Method::ShiftInvert
                };
                let (nev, sigma, tol) = (h[1] as usize, f64::from_bits(h[2]), f64::from_bits(h[3]));
                token.lowest_eigenpairs(o, nev, sigma, tol, method)?;
            }
            other => anyhow::bail!("rank 0 sent message kind {other}, which this ves does not know"),
        }
    }
}

/// Rank 0's end of the pipeline under MPI: tells the ranks in [`serve`] to return, with the
/// pipeline's outcome (an error is then every rank's, reported once by rank 0). An error inside
/// a solve is left to [`finish`], which ends the job.
pub fn release<T>(result: anyhow::Result<T>) -> anyhow::Result<T> {
    if ranks() <= 1 || rank() != 0 || IN_SOLVE.load(SeqCst) {
        return result;
    }
    let kind = if result.is_ok() { message::STOP } else { message::FAIL };
    let told = TOKEN.with(|t| -> Result<(), ves_slepc::PetscError> {
        if let Some(token) = t.borrow().as_ref() {
            for r in 1..token.size() {
                token.send(r, &header(kind, &[]))?;
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
