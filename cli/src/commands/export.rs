//! `ves export BASIS --vtu DIR [--force]`.

use anyhow::Result;
use std::path::PathBuf;

/// Arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Basis file (HDF5).
    basis: PathBuf,
    /// Directory for the .vtu files (created if missing; files of the same names replaced).
    #[arg(long, value_name = "DIR")]
    vtu: PathBuf,
    /// Replace a symbolic link at an output path (the link, not its target).
    #[arg(long)]
    force: bool,
}

impl Args {
    pub fn run(self) -> Result<()> {
        for f in ves_pipeline::export::export(
            &self.basis,
            &self.vtu,
            ves_pipeline::output::Overwrite { force: self.force },
        )? {
            println!("wrote {}", f.display());
        }
        Ok(())
    }
}
