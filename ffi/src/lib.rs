//! Thin safe wrappers over the C libraries the VES pipeline links: gmsh (meshing, GPL),
//! ARPACK (Lanczos eigen-solver) and METIS (partitioning and orderings). Raw `extern` declarations live in `*/sys.rs`; the safe layer
//! beside them checks every return code and turns it into a `Result` carrying the library's
//! own message.

pub mod arpack;
pub mod gmsh;
pub mod metis;
#[cfg(feature = "slepc")]
pub mod slepc;
pub mod xerbla;
