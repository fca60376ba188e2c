//! Python exceptions, one per kind of failure the pipeline and the reader tell apart. The
//! message is the line the `ves` CLI prints after `error: ` (the whole cause chain).

use pyo3::PyErr;
use pyo3::create_exception;
use pyo3::exceptions::PyException;

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
create_exception!(ves, MeshError, Error, "The geometry could not be read or meshed.");
create_exception!(
    ves,
    SupportError,
    Error,
    "A `[[fixed]]` region cannot be applied to the mesh."
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

/// The Python exception for a pipeline error: its kind from the first typed error in the cause
/// chain, its message the chain on one line, as the CLI prints it.
pub fn from_anyhow(e: &anyhow::Error) -> PyErr {
    let msg = format!("{e:#}");
    for cause in e.chain() {
        if cause.is::<ves_pipeline::scene::SceneError>() {
            return SceneError::new_err(msg);
        }
        if cause.is::<ves_pipeline::mesh::MeshError>() {
            return MeshError::new_err(msg);
        }
        if cause.is::<ves_pipeline::supports::SupportError>() {
            return SupportError::new_err(msg);
        }
        if cause.is::<ves_pipeline::fem::assembly::AssemblyError>() {
            return AssemblyError::new_err(msg);
        }
        if cause.is::<ves_pipeline::modes::ModesError>() || cause.is::<ves_pipeline::linsolve::FactorError>() {
            return SolverError::new_err(msg);
        }
        if cause.is::<ves_format::ReadError>() || cause.is::<ves_runtime::basis::LoadError>() {
            return BasisError::new_err(msg);
        }
    }
    Error::new_err(msg)
}

/// A basis file that could not be read.
pub fn basis(e: impl std::fmt::Display) -> PyErr {
    BasisError::new_err(e.to_string())
}
