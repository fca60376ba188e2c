//! `ves report`.

use anyhow::Result;
use std::path::PathBuf;
use ves_pipeline::report::{self, ReportOptions};
use ves_pipeline::scene::Scene;

/// Arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Scene file (TOML, version 1); its `[[probe]]` points are where errors are measured.
    scene: PathBuf,
    /// Output directory (created if missing).
    #[arg(short, long)]
    output: PathBuf,
    /// Mode counts, comma-separated (default 5,10,20,30,50,100,200).
    #[arg(long, value_delimiter = ',')]
    modes: Option<Vec<usize>>,
    /// Element sizes in metres, comma-separated (default: 2, 1.5 and 1 × the scene's size).
    #[arg(long, value_delimiter = ',')]
    sizes: Option<Vec<f64>>,
    /// Element orders, comma-separated (default 1,2).
    #[arg(long, value_delimiter = ',')]
    orders: Option<Vec<u8>>,
    /// Length of the step-load response, s.
    #[arg(long, default_value_t = 0.5)]
    duration: f64,
    /// Print report.json's content as the last line of stdout.
    #[arg(long)]
    json: bool,
}

impl Args {
    pub fn run(self) -> Result<()> {
        let scene = Scene::load(&self.scene)?;
        // The default sizes scale the scene's own; a scene meshed to target_error has none.
        if self.sizes.is_none() && scene.mesh.size <= 0.0 {
            anyhow::bail!(
                "{}: the scene sets mesh.target_error, not mesh.size, so there is no size to sweep around; \
                 give --sizes in metres (e.g. --sizes 0.02,0.015,0.01; `ves precompute --json` lists the sizes its \
                 refinement used)",
                scene.path.display()
            );
        }
        let mut opts = ReportOptions::defaults(&scene);
        opts.modes = self.modes.unwrap_or(opts.modes);
        opts.sizes = self.sizes.unwrap_or(opts.sizes);
        opts.orders = self.orders.unwrap_or(opts.orders);
        opts.duration = self.duration;
        let report = report::run(&scene, &opts, &self.output)?;
        if self.json {
            return super::print_json(&report);
        }
        println!(
            "wrote {}/report.md, report.json, error_vs_online.{{png,svg}}, error_vs_offline.{{png,svg}} ({:.1} s)",
            self.output.display(),
            report.total_s
        );
        Ok(())
    }
}
