//! The VES modal-basis file, version 1 (HDF5; docs/format.md), defined once: its names
//! ([`names`]), one guarded reader ([`read`]) and one writer ([`write`]), and the XDMF sidecar
//! that shows a basis to ParaView ([`xdmf`]).
//!
//! Permissive (MIT OR Apache-2.0): the runtime reads with it, the pipeline writes with it.

pub mod checks;
pub mod element;
pub mod identifier;
pub mod names;
#[cfg(feature = "hdf5")]
pub mod read;
#[cfg(feature = "hdf5")]
pub mod strings;
#[cfg(feature = "hdf5")]
pub mod write;
pub mod xdmf;

pub use element::ElementKind;
pub use identifier::check_identifier;
pub use names::{FORMAT, VERSION};
#[cfg(feature = "hdf5")]
pub use read::{BasisReader, ReadError, SpaceReader, guarded};
#[cfg(feature = "hdf5")]
pub use write::{FileData, LoadData, SpaceData, WriteError, write_file};

/// An input that cannot be used: the file (or other input) it came from and what is wrong and
/// what to change, shown as `path: message`. The one error of the readers of files (a basis, a
/// device script) in the format crate and the runtime.
#[derive(Debug, Clone, thiserror::Error)]
#[error("{path}: {message}")]
pub struct InputError {
    /// The input.
    pub path: String,
    /// What is wrong and what to do.
    pub message: String,
}

/// Material constants and Rayleigh damping (`/material`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// Young's modulus, Pa.
    pub young: f64,
    /// Poisson's ratio.
    pub poisson: f64,
    /// Density, kg/m³.
    pub density: f64,
    /// Rayleigh α, 1/s.
    pub alpha: f64,
    /// Rayleigh β, s.
    pub beta: f64,
    /// Yield strength, Pa (optional attribute): the runtime's safety factor.
    pub yield_strength: Option<f64>,
}

/// Mass properties of a free body (`rigid/`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigidProperties {
    /// kg.
    pub mass: f64,
    /// m.
    pub center: [f64; 3],
    /// kg·m², about the centre of mass.
    pub inertia: [[f64; 3]; 3],
}

/// A 3×3 static compliance block (K⁻¹)ᵢᵢ, m/N.
pub type Block3 = [[f64; 3]; 3];

/// Static compliance as stored: node indices and one block per node.
pub type Compliance = (Vec<u32>, Vec<Block3>);
