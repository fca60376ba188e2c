//! VES runtime: modal deformation and force feedback from a precomputed basis.
//!
//! Lean by design: no gmsh, no solver, no Python, nothing GPL. A haptic thread (≥ 1 kHz) touches
//! only the 3×r basis rows of the active vertex; a visualization thread computes the whole
//! deformed part from a lock-free snapshot of the modal state.

pub mod basis;
pub mod bench;
#[cfg(feature = "capi")]
pub mod capi;
pub mod device;
pub mod haptic;
pub mod integrator;
pub mod kdtree;
pub mod nonlinear;
pub mod os;
pub mod packed;
pub mod realtime;
pub mod rigid_body;
pub mod session;
pub mod snapshot;
pub mod switching;
pub mod visual;

pub use basis::{Basis, FeltAt, LoadError, LoadOptions};
