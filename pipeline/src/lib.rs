//! VES offline pipeline: a scene (STEP geometry, material, supports) becomes a modal basis file.
//!
//! Data flows one way: [`scene`] → [`mesh`] → [`supports`] → [`fem`] (K, M) → [`modes`]
//! (eigen-solve) → [`store`] (HDF5). [`precompute`] strings the stages together.

// The numerics core, re-exported: the pipeline's modules and its users name it as before.
pub use ves_numerics::{fem, linsolve, material, memory, modes, os, rigid_motions, tall, tet_mesh};

pub mod accuracy;
pub mod batch;
pub mod compliance;
pub mod export;
pub mod faces;
pub mod fingerprint;
pub mod host;
pub mod input;
pub mod loads;
pub mod matrices;
pub mod mesh;
pub mod nonlinear;
pub mod notices;
pub mod output;
pub mod precompute;
pub mod preview;
pub mod problem;
pub mod progress;
pub mod report;
pub mod scene;
pub mod step_faces;
pub mod step_units;
pub mod store;
pub mod supports;
pub mod transfer;
pub mod verify;
pub mod workdir;

/// Makes a FIFO at `path`: the tests' stand-in for an input that would block a reader.
#[cfg(test)]
pub(crate) fn make_fifo(path: &std::path::Path) {
    os::make_fifo(path).unwrap_or_else(|e| panic!("mkfifo {}: {e}", path.display()));
}
