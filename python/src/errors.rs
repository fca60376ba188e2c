//! Python exceptions, one per kind of failure the pipeline and the reader tell apart. The
//! message is the line the `ves` CLI prints after `error: ` (the whole cause chain).

use pyo3::PyErr;
use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;

create_exception!(
    ves,
    Error,
    PyException,
    "Base of every VES error; the message is the CLI's one line."
);
create_exception!(
    ves,
    SceneError,
    Error,
    "The scene is malformed or asks for something invalid."
);
create_exception!(
    ves,
    VesWarning,
    pyo3::exceptions::PyUserWarning,
    "A warning of the pipeline (the line the `ves` CLI prints): a mesh too coarse for the error asked, a unit ignored, curved tets straightened. Also listed in the summary's `warnings`."
);
create_exception!(ves, MeshError, Error, "The geometry could not be read or meshed.");
create_exception!(
    ves,
    SupportError,
    Error,
    "A `[[fixed]]` or `[[load]]` region cannot be applied to the mesh, or the supports leave a body free."
);
create_exception!(
    ves,
    AssemblyError,
    Error,
    "An element of the mesh is degenerate or inverted."
);
create_exception!(ves, SolverError, Error, "The factorisation or the eigen-solve failed.");
create_exception!(
    ves,
    BasisError,
    Error,
    "A basis file is missing, foreign, damaged or inconsistent."
);
create_exception!(
    ves,
    OutputError,
    Error,
    "The output file cannot or must not be written; whatever was at its path is kept."
);
create_exception!(
    ves,
    VerifyError,
    Error,
    "A reference solver is missing, not applicable, or failed."
);

/// The exception class of each typed error of the pipeline, by kind of failure.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Scene,
    Mesh,
    Support,
    Assembly,
    Solver,
    Basis,
    Output,
    Verify,
}

impl Kind {
    /// The kind of `cause` if it is one of the pipeline's typed errors (an unreadable input
    /// file is the scene's or the geometry's; a load case's region is a support's, its
    /// degenerate element an assembly's).
    fn of(cause: &(dyn std::error::Error + 'static)) -> Option<Kind> {
        use ves_pipeline::input::{FileKind, InputError};
        use ves_pipeline::loads::LoadCaseError;
        if cause.is::<ves_pipeline::scene::SceneError>() {
            return Some(Kind::Scene);
        }
        if let Some(e) = cause.downcast_ref::<InputError>() {
            return Some(match e.file() {
                FileKind::Scene => Kind::Scene,
                FileKind::Geometry => Kind::Mesh,
            });
        }
        if cause.is::<ves_pipeline::mesh::MeshError>() {
            return Some(Kind::Mesh);
        }
        if cause.is::<ves_pipeline::supports::SupportError>() || cause.is::<ves_pipeline::supports::RegionError>() {
            return Some(Kind::Support);
        }
        if let Some(e) = cause.downcast_ref::<LoadCaseError>() {
            return Some(match e {
                LoadCaseError::Region(_) => Kind::Support,
                LoadCaseError::Degenerate { .. } => Kind::Assembly,
            });
        }
        if cause.is::<ves_pipeline::fem::assembly::AssemblyError>() {
            return Some(Kind::Assembly);
        }
        if cause.is::<ves_pipeline::modes::ModesError>() || cause.is::<ves_pipeline::linsolve::FactorError>() {
            return Some(Kind::Solver);
        }
        if cause.is::<ves_format::ReadError>() || cause.is::<ves_runtime::basis::LoadError>() {
            return Some(Kind::Basis);
        }
        if cause.is::<ves_pipeline::output::OutputError>() {
            return Some(Kind::Output);
        }
        if cause.is::<ves_pipeline::verify::VerifyError>() {
            return Some(Kind::Verify);
        }
        None
    }

    fn new_err(self, msg: String) -> PyErr {
        match self {
            Kind::Scene => SceneError::new_err(msg),
            Kind::Mesh => MeshError::new_err(msg),
            Kind::Support => SupportError::new_err(msg),
            Kind::Assembly => AssemblyError::new_err(msg),
            Kind::Solver => SolverError::new_err(msg),
            Kind::Basis => BasisError::new_err(msg),
            Kind::Output => OutputError::new_err(msg),
            Kind::Verify => VerifyError::new_err(msg),
        }
    }
}

/// The Python exception for a pipeline error: its kind from the first typed error in the cause
/// chain, its message the chain on one line, as the CLI prints it.
pub fn from_anyhow(e: &anyhow::Error) -> PyErr {
    let msg = format!("{e:#}");
    match e.chain().find_map(Kind::of) {
        Some(kind) => kind.new_err(msg),
        None => Error::new_err(msg),
    }
}

/// A basis file that could not be read.
pub fn basis(e: impl std::fmt::Display) -> PyErr {
    BasisError::new_err(e.to_string())
}

/// Gives each of `warnings` to Python's `warnings` machinery as a [`VesWarning`], pointing at
/// the caller's line.
pub fn warn_all(py: Python<'_>, warnings: &[String]) -> PyResult<()> {
    let kind = py.get_type::<VesWarning>();
    for w in warnings {
        let text = std::ffi::CString::new(w.replace('\0', " ")).unwrap_or_default();
        PyErr::warn(py, &kind, &text, 1)?;
    }
    Ok(())
}
