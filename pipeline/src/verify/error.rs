//! What can go wrong in `ves verify` itself: a reference missing or not applicable, a reference
//! program that fails or writes something unusable, its files. The stages it borrows (the scene,
//! the mesh, our solve, a basis file) keep their own error types.

use std::path::PathBuf;

/// A failure of `ves verify`'s own: each message names the input (or the file) and what to do.
#[derive(Debug, thiserror::Error)]
pub enum VerifyError {
    /// `--against NAME` names no reference.
    #[error("unknown reference solver {name:?}: give {known}")]
    UnknownReference {
        /// What was given.
        name: String,
        /// The names there are, quoted, as a sentence.
        known: String,
    },
    /// The one reference asked for is not installed.
    #[error("{input}: {advice}")]
    NotInstalled {
        /// What is verified.
        input: String,
        /// What is missing and how to install it.
        advice: &'static str,
    },
    /// Of the references asked for, none could run (each missing or not applicable).
    #[error("{input}: no reference solver could run ({why})")]
    NoneCouldRun {
        /// What is verified.
        input: String,
        /// Each reference with its reason, `; `-separated.
        why: String,
    },
    /// `--stress` with references of which none compares nodal stresses.
    #[error("--stress compares nodal stresses with {labels}: use it with --against {names} (or all)")]
    StressNotCompared {
        /// The references that do, by label.
        labels: String,
        /// The same by their `--against` names.
        names: String,
    },
    /// A reference was asked for something it does not check.
    #[error("{input}: {reference} does not solve {what}")]
    NotCapable {
        /// What is verified.
        input: String,
        /// The reference.
        reference: &'static str,
        /// What it was asked for.
        what: &'static str,
    },
    /// No temporary folder for the reference's files.
    #[error("cannot create a temporary directory for {what}")]
    WorkDir {
        /// For whom.
        what: &'static str,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A file the reference reads could not be written.
    #[error("cannot write {}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The problem file (HDF5) the reference reads could not be written.
    #[error("cannot create {}", path.display())]
    WriteProblem {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: hdf5::Error,
    },
    /// A reference's program could not be started.
    #[error("{input}: cannot run {what}")]
    CannotRun {
        /// What is verified.
        input: String,
        /// The program or script.
        what: String,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A reference's program ended with an error.
    #[error("{input}: the reference solver {what} failed on it: {message}")]
    Failed {
        /// What is verified.
        input: String,
        /// The program or script.
        what: String,
        /// Its last line of stderr (a Python traceback's exception), made safe for a terminal.
        message: String,
    },
    /// A reference found installed when `ves verify` started is gone.
    #[error("{input}: {reference} disappeared while ves verify ran")]
    Disappeared {
        /// What is verified.
        input: String,
        /// The reference.
        reference: &'static str,
    },
    /// A reference's results could not be read.
    #[error("cannot read {}", path.display())]
    ReadResults {
        /// Its result file.
        path: PathBuf,
        /// Why.
        #[source]
        source: hdf5::Error,
    },
    /// A reference's results are there but cannot be compared (shapes, non-finite values).
    #[error("{}: {detail}", path.display())]
    Unusable {
        /// Its result file.
        path: PathBuf,
        /// What is wrong, in a sentence.
        detail: String,
    },
    /// Our own field of a load case meets a degenerate element.
    #[error("{input}: an element is degenerate (det J = {det:.3e})")]
    Degenerate {
        /// What is verified.
        input: String,
        /// The element's Jacobian determinant.
        det: f64,
    },
}
