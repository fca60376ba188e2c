//! The `ves` Python package's native module (`ves._native`): the modal-basis reader, the
//! pipeline and the haptic runtime behind numpy arrays. The pure-Python layer in `ves/`
//! re-exports it and adds what scipy builds (`ves.matrices`).
//!
//! Every failure is a Python exception (`ves.Error` and one subclass per kind) carrying the
//! line the `ves` CLI prints; long calls release the GIL and stop on Ctrl-C.

mod basis;
mod errors;
mod haptics;
mod pipeline;
mod session;

use pyo3::prelude::*;

/// The native module.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    logging();
    m.add("Error", py.get_type::<errors::Error>())?;
    m.add("SceneError", py.get_type::<errors::SceneError>())?;
    m.add("MeshError", py.get_type::<errors::MeshError>())?;
    m.add("SupportError", py.get_type::<errors::SupportError>())?;
    m.add("AssemblyError", py.get_type::<errors::AssemblyError>())?;
    m.add("SolverError", py.get_type::<errors::SolverError>())?;
    m.add("BasisError", py.get_type::<errors::BasisError>())?;
    m.add("OutputError", py.get_type::<errors::OutputError>())?;
    m.add("VerifyError", py.get_type::<errors::VerifyError>())?;
    m.add("VesWarning", py.get_type::<errors::VesWarning>())?;
    m.add_class::<basis::Basis>()?;
    m.add_class::<basis::Space>()?;
    m.add_class::<haptics::Haptics>()?;
    m.add_function(wrap_pyfunction!(pipeline::precompute, m)?)?;
    m.add_function(wrap_pyfunction!(pipeline::_matrices, m)?)?;
    m.add_function(wrap_pyfunction!(pipeline::verify, m)?)?;
    m.add_function(wrap_pyfunction!(pipeline::faces, m)?)?;
    m.add_function(wrap_pyfunction!(session::session, m)?)?;
    m.add_function(wrap_pyfunction!(pipeline::_isolate_meshing, m)?)?;
    m.add_function(wrap_pyfunction!(pipeline::_serve_mesh_rung, m)?)?;
    m.add_function(wrap_pyfunction!(haptics::_rust_step_ns, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}

/// The pipeline's warnings are collected for each call (and become `VesWarning`s); with
/// `VES_LOG` set to a level (`warn`, `info`, …), its log lines go to stderr.
fn logging() {
    // Another extension may have set one first: then its own rules apply.
    let _ = tracing::subscriber::set_global_default(ves_pipeline::notices::Collector::from_env());
}
