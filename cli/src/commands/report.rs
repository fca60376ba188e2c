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
    /// Element sizes in metres, comma-separated (default: 2, 1.5 and 1 × the scene's mesh.size;
    /// with mesh.target_error, the refinement's starting size and 1/1.5 and 1/2 of it).
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
        let sizes_given = self.sizes.is_some();
        let mut opts = ReportOptions::defaults(&scene, self.sizes)?;
        if !sizes_given {
            eprintln!("{}: {}", scene.path.display(), opts.sizes_from);
        }
        opts.modes = self.modes.unwrap_or(opts.modes);
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
