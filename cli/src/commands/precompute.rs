//! `ves precompute`.

use anyhow::Result;
use std::path::PathBuf;
use ves_pipeline::modes::{SolverChoice, mpi_job};
use ves_pipeline::notices;
use ves_pipeline::precompute;
use ves_pipeline::scene::{EstimateMode, Scene};

/// Arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Scene file (TOML, version 1).
    scene: PathBuf,
    /// Output basis file (default: beside the scene, <name>.h5).
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Print a JSON summary as the last line of stdout.
    #[arg(long)]
    json: bool,
    /// Eigen-solver.
    #[arg(long, default_value = "auto", value_parser = super::solver_parser())]
    solver: SolverChoice,
    /// Elastic modes to keep (overrides the scene's modes.count).
    #[arg(long)]
    modes: Option<usize>,
    /// The error estimate (overrides the scene's mesh.error_estimate): "recovery" decides on
    /// the mesh itself and solves the two coarser meshes only where it is not vouched for;
    /// "full" always solves them too; "off" makes none.
    #[arg(long, value_parser = clap::builder::PossibleValuesParser::new(["recovery", "full", "off"]))]
    estimate: Option<String>,
    /// No progress lines on stderr (they are shown only on a terminal anyway).
    #[arg(long, short)]
    quiet: bool,
    /// Write an instant basis instead: the mesh and modes of this basis (same geometry and mesh
    /// settings; only supports, material or mode count changed), modes from a few block solves,
    /// each frequency with a bound (`instant` in the JSON). What `ves view` serves while the
    /// converged compute runs.
    #[arg(long, value_name = "BASIS")]
    instant_from: Option<PathBuf>,
    #[command(flatten)]
    write: super::WriteFlags,
}

/// `--json` of an instant basis: the summary and how far it may be from the converged one.
#[derive(serde::Serialize)]
struct InstantJson {
    #[serde(flatten)]
    summary: precompute::Summary,
    instant: precompute::instant::InstantCheck,
}

impl Args {
    pub fn run(self) -> Result<()> {
        if let Some(m) = self.modes {
            anyhow::ensure!((1..=2000).contains(&m), "--modes {m}: must be between 1 and 2000");
        }
        // SLEPc brings MPI up first: under mpirun every rank runs this command.
        let _slepc = match self.solver {
            SolverChoice::Slepc | SolverChoice::SlepcIterative => Some(mpi_job::SlepcGuard::init()?),
            _ => None,
        };
        // Under MPI an error on one rank must end all of them (before the guard finalises MPI).
        mpi_job::finish(self.solve())
    }

    fn solve(self) -> Result<()> {
        // A scene one rank cannot read (an MPMD launch, a file system that differs between
        // nodes) stops every rank here, not in the eigen-solver's collective calls.
        let (loaded, mut warnings) = notices::collect(|| Scene::load_with(&self.scene, self.write.scene()));
        let mut scene = mpi_job::agree(loaded.map_err(Into::into))?;
        if let Some(m) = self.modes {
            scene.modes.count = m;
        }
        if let Some(e) = &self.estimate {
            let mode: EstimateMode = e.parse().map_err(|e: String| anyhow::anyhow!("--estimate {e}"))?;
            anyhow::ensure!(
                mode.on() || scene.mesh.target_error.is_none(),
                "--estimate off: the scene's mesh.target_error needs the error estimate"
            );
            scene.mesh.error_estimate = mode;
        }
        let out = self
            .output
            .unwrap_or_else(|| scene.path.with_file_name(format!("{}.h5", scene.name)));
        if let Some(previous) = &self.instant_from {
            anyhow::ensure!(
                !self.solver.is_slepc(),
                "--instant-from runs on one process: leave out --solver {}",
                self.solver.name()
            );
            let visible = !self.quiet;
            let _watching = ves_pipeline::progress::watch(crate::terminal::Terminal::on_stderr(visible));
            let (instant_run, more) = notices::collect(|| precompute::instant::run(&scene, previous, &out));
            warnings.extend(more);
            let Some((mut summary, instant)) = instant_run? else {
                let stored = ves_pipeline::store::read_global(previous, None)?;
                let why = precompute::instant::applicable(&scene, stored.scene_toml.as_deref().unwrap_or_default())
                    .err()
                    .unwrap_or_default();
                anyhow::bail!(
                    "{}: no instant basis for {} ({why}): only supports, material and modes may change; run without \
                     --instant-from",
                    previous.display(),
                    scene.path.display()
                );
            };
            if self.json {
                summary.warnings = warnings;
                return super::print_json(&InstantJson { summary, instant });
            }
            println!(
                "instant basis: {} modes in {} solves, {}; wrote {} in {:.2} s",
                instant.frequency_bound.len(),
                instant.solves,
                instant.text(),
                summary.output,
                summary.timings_s.total
            );
            return Ok(());
        }
        let mut summary = {
            let visible = !self.quiet && mpi_job::rank() == 0;
            let _watching = ves_pipeline::progress::watch(crate::terminal::Terminal::on_stderr(visible));
            let (done, more) =
                notices::collect(|| precompute::run_with(&scene, &out, self.solver, self.write.overwrite()));
            warnings.extend(more);
            done?
        };
        summary.warnings = warnings;
        if mpi_job::rank() != 0 {
            return Ok(());
        }
        if self.json {
            return super::print_json(&summary);
        }
        for s in &summary.spaces {
            let f: Vec<String> = s.frequencies_hz.iter().take(6).map(|f| format!("{f:.4}")).collect();
            println!(
                "{}: {} nodes, {} tets, {} dofs, {} modes (first: {} Hz), max residual {:.1e}{}{}{}",
                s.name,
                s.nodes,
                s.tets,
                s.dofs,
                s.frequencies_hz.len(),
                f.join(", "),
                s.max_relative_residual,
                ves_pipeline::accuracy::summary_text(s.estimated_relative_error.as_deref()),
                s.felt_compliance.as_ref().map_or(String::new(), |f| f.text()),
                s.nonlinear.map_or(String::new(), |n| n.text())
            );
            for l in &s.loads {
                println!(
                    "  load {}: max displacement {:.4e} m, max von Mises {:.4e} Pa{}{}",
                    l.name,
                    l.max_displacement_m,
                    l.max_von_mises_pa,
                    l.safety_factor
                        .map_or(String::new(), |f| match l.safety_factor_away_from_singular {
                            Some(away) =>
                                format!(" (safety factor {f:.3} from a singular peak; {away:.3} away from it)"),
                            None => format!(" (safety factor {f:.3})"),
                        }),
                    l.peak_stress.as_ref().map_or(String::new(), |t| format!("; {t}"))
                );
            }
        }
        println!("wrote {} in {:.2} s", summary.output, summary.timings_s.total);
        Ok(())
    }
}
