//! VES numerics core: what turns a tetrahedral mesh, a material and its supported DOFs into
//! checked modes, with no gmsh and no scene file (`ves-pipeline` adds those).
//!
//! Layers, lowest first (README.md; `tests/structure.rs` checks them): [`os`], [`memory`],
//! [`tall`] → [`material`], [`tet_mesh`], [`fem`], [`rigid_motions`] → [`linsolve`], [`modes`].

pub mod fem;
pub mod linsolve;
pub mod material;
pub mod memory;
pub mod modes;
pub mod os;
pub mod rigid_motions;
pub mod tall;
pub mod tet_mesh;
