//! The MPI job in a ves built without the `slepc` feature: one rank, nothing to agree on, and
//! `--solver slepc` refused with what to install ([`not_built`]). The same functions as
//! `mpi_job.rs`, so callers need no `cfg`.

use super::ModesError;

/// Why `--solver slepc` cannot run in this build.
pub(super) fn not_built() -> ModesError {
    ModesError::Slepc(
        "this ves was built without SLEPc: install libslepc-real-dev and build with `--features slepc`".into(),
    )
}

/// Stands for SLEPc's initialisation, which this build cannot make.
pub struct SlepcGuard(());

impl SlepcGuard {
    /// Fails: this build has no SLEPc.
    pub fn init() -> Result<SlepcGuard, ModesError> {
        Err(not_built())
    }
}

/// This process's MPI rank: 0.
pub fn rank() -> usize {
    0
}

/// Number of MPI ranks: 1.
pub fn ranks() -> usize {
    1
}

/// The result as it is (one rank agrees with itself).
pub fn agree<T>(result: anyhow::Result<T>) -> anyhow::Result<T> {
    result
}

/// The result as it is (no other rank to end).
pub fn finish<T>(result: anyhow::Result<T>) -> anyhow::Result<T> {
    result
}

/// Fails: there are no eigen-solves to serve in this build.
pub fn serve() -> anyhow::Result<()> {
    Err(not_built().into())
}

/// The result as it is (no rank waits for rank 0).
pub fn release<T>(result: anyhow::Result<T>) -> anyhow::Result<T> {
    result
}
