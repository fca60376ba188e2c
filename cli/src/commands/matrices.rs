//! `ves matrices`.

use anyhow::Result;
use std::path::PathBuf;
use ves_pipeline::output;
use ves_pipeline::scene::Scene;

/// Arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Scene file (TOML, version 1).
    scene: PathBuf,
    /// Output file (HDF5).
    #[arg(short, long)]
    output: PathBuf,
    #[command(flatten)]
    write: super::WriteFlags,
}

impl Args {
    pub fn run(self) -> Result<()> {
        let scene = Scene::load_with(&self.scene, self.write.scene())?;
        output::check(&self.output, &scene.inputs(), self.write.overwrite())?;
        let d = ves_pipeline::problem::discretize(&scene, None)?;
        ves_pipeline::matrices::write_matrices(&self.output, &d)?;
        println!(
            "wrote {} ({} unknowns, {} rigid modes)",
            self.output.display(),
            d.dofs.free_count(),
            d.rigid
        );
        Ok(())
    }
}
