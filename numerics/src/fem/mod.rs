//! Linear elasticity on tetrahedra: element matrices and their assembly into sparse K and M.

pub mod assembly;
pub mod dofs;
pub mod element;
pub mod quadrature;
pub mod share;
pub mod springs;
pub mod stress;
pub mod stvk;

pub use assembly::{Assembled, MassProperties, Moments, assemble};
pub use dofs::Dofs;
