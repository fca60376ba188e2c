//! `ves matrices`.

use anyhow::Result;
use std::path::PathBuf;
use ves_pipeline::output::{self, Overwrite};
use ves_pipeline::scene::{Scene, SceneOptions};

/// Arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Scene file (TOML, version 1).
    scene: PathBuf,
    /// Output file (HDF5).
    #[arg(short, long)]
    output: PathBuf,
    /// Replace a symbolic link at the output path (the link, not its target).
    #[arg(long)]
    force: bool,
    /// Accept a .geo geometry (a gmsh script, which can run shell commands).
    #[arg(long)]
    allow_geo_scripts: bool,
}

impl Args {
    pub fn run(self) -> Result<()> {
        let scene = Scene::load_with(
            &self.scene,
            SceneOptions {
                allow_geo_scripts: self.allow_geo_scripts,
            },
        )?;
        output::check(
            &self.output,
            &[&scene.path, &scene.geometry],
            Overwrite { force: self.force },
        )?;
        let d = ves_pipeline::problem::discretize(&scene, None)?;
        ves_pipeline::export::write_matrices(&self.output, &d)?;
        println!(
            "wrote {} ({} unknowns, {} rigid modes)",
            self.output.display(),
            d.dofs.free_count(),
            d.rigid
        );
        Ok(())
    }
}
