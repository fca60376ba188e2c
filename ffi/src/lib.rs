//! Thin safe wrappers over the C libraries the VES pipeline links: gmsh (meshing, GPL) and
//! ARPACK (Lanczos eigen-solver). Raw `extern` declarations live in `*/sys.rs`; the safe layer
//! beside them checks every return code and turns it into a `Result` carrying the library's
//! own message.

pub mod arpack;
pub mod gmsh;
#[cfg(feature = "slepc")]
pub mod slepc;
pub mod xerbla;
