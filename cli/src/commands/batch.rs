//! `ves batch`.

use anyhow::Result;
use std::path::PathBuf;
use ves_pipeline::batch::{self, BatchOptions, Status};
use ves_pipeline::modes::SolverChoice;

/// Arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Scene files or directories (searched recursively for *.toml). Each scene is done once,
    /// however many names reach it. Links named here are followed; inside a directory, links to
    /// scene files are followed but links to directories are not entered (a link loop cannot
    /// make the search endless): name such a directory here to include it.
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    /// Scenes precomputed at once.
    #[arg(short = 'j', long, default_value_t = 1)]
    jobs: usize,
    /// Output directory (default: beside each scene, <name>.h5).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Eigen-solver.
    #[arg(long, default_value = "auto", value_parser = super::solver_parser())]
    solver: SolverChoice,
    /// Accept .geo geometries (gmsh scripts, which can run shell commands): only for scenes you trust.
    #[arg(long)]
    allow_geo_scripts: bool,
    /// Print the outcomes as JSON (last line of stdout).
    #[arg(long)]
    json: bool,
}

impl Args {
    pub fn run(self) -> Result<()> {
        anyhow::ensure!(
            (1..=64).contains(&self.jobs),
            "-j {}: give 1 to 64 parallel scenes",
            self.jobs
        );
        anyhow::ensure!(
            !self.solver.is_slepc(),
            "--solver slepc: not available in ves batch (MPI runs one scene at a time); use `mpirun ves precompute` per scene"
        );
        let scenes = batch::collect(&self.inputs)?;
        let opts = BatchOptions {
            jobs: self.jobs,
            out: self.out,
            solver: self.solver,
            allow_geo_scripts: self.allow_geo_scripts,
        };
        let outcomes = batch::run(&scenes, &opts)?;
        let count = |s: Status| outcomes.iter().filter(|o| o.status == s).count();
        let (done, fresh, failed) = (count(Status::Done), count(Status::UpToDate), count(Status::Failed));
        if self.json {
            super::print_json(&outcomes)?;
        } else {
            for o in &outcomes {
                let what = match o.status {
                    Status::Done => format!("done in {:.1} s", o.seconds),
                    Status::UpToDate => "up to date".into(),
                    Status::Failed => format!("FAILED: {}", o.error.as_deref().unwrap_or("")),
                };
                println!("{}: {what}", o.scene);
            }
            println!("{done} done, {fresh} up to date, {failed} failed");
        }
        if failed > 0 {
            let names: Vec<&str> = outcomes
                .iter()
                .filter(|o| o.status == Status::Failed)
                .map(|o| o.scene.as_str())
                .collect();
            anyhow::bail!("{failed} of {} scenes failed: {}", outcomes.len(), names.join(", "));
        }
        Ok(())
    }
}
