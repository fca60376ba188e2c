//! `ves`: the VES command line.

use anyhow::Result;
use clap::{Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;
use ves_pipeline::precompute::{self, SolverChoice};
use ves_pipeline::scene::Scene;
use ves_pipeline::store;

#[derive(Parser)]
#[command(
    name = "ves",
    version,
    about = "Feel and see a CAD part deform: offline modal precompute"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Mesh a scene, compute its lowest modes and write a modal-basis file.
    Precompute {
        /// Scene file (TOML, version 1).
        scene: PathBuf,
        /// Output basis file (default: beside the scene, <name>.h5).
        #[arg(short, long)]
        output: Option<PathBuf>,
        /// Print a JSON summary as the last line of stdout.
        #[arg(long)]
        json: bool,
        /// Eigen-solver.
        #[arg(long, value_enum, default_value_t = SolverChoice::Auto)]
        solver: SolverChoice,
    },
    /// Export the assembled K and M (global space, free DOFs) to HDF5 for external solvers.
    Matrices {
        /// Scene file (TOML, version 1).
        scene: PathBuf,
        /// Output file (HDF5).
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Summarise a modal-basis file.
    Info {
        /// Basis file (HDF5).
        basis: PathBuf,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Precompute {
            scene,
            output,
            json,
            solver,
        } => {
            let scene = Scene::load(&scene)?;
            let out = output.unwrap_or_else(|| scene.path.with_file_name(format!("{}.h5", scene.name)));
            let summary = precompute::run(&scene, &out, solver)?;
            if json {
                println!("{}", serde_json::to_string(&summary)?);
            } else {
                for s in &summary.spaces {
                    let f: Vec<String> = s.frequencies_hz.iter().take(6).map(|f| format!("{f:.4}")).collect();
                    println!(
                        "{}: {} nodes, {} tets, {} dofs, {} modes (first: {} Hz), max residual {:.1e}",
                        s.name,
                        s.nodes,
                        s.tets,
                        s.dofs,
                        s.frequencies_hz.len(),
                        f.join(", "),
                        s.max_relative_residual
                    );
                }
                println!("wrote {} in {:.2} s", summary.output, summary.timings_s.total);
            }
        }
        Command::Matrices { scene, output } => {
            let scene = Scene::load(&scene)?;
            let d = precompute::discretize(&scene, None, &mut precompute::Timings::default())?;
            ves_pipeline::export::write_matrices(&output, &d)?;
            println!(
                "wrote {} ({} unknowns, {} rigid modes)",
                output.display(),
                d.dofs.free_count(),
                d.rigid
            );
        }
        Command::Info { basis, json } => {
            let info = store::info(&basis)?;
            if json {
                println!("{}", serde_json::to_string(&info)?);
            } else {
                println!("{} ({} bytes, {})", info.path, info.bytes, info.generator);
                for s in &info.spaces {
                    println!(
                        "  {}: {} nodes ({} vertices), {} tets of order {}, {} modes {:.4}..{:.4} Hz, max residual {:.1e}, {} rigid dropped",
                        s.name,
                        s.nodes,
                        s.vertices,
                        s.tets,
                        s.element_order,
                        s.modes,
                        s.frequencies_hz.first().copied().unwrap_or(0.0),
                        s.frequencies_hz.last().copied().unwrap_or(0.0),
                        s.max_relative_residual,
                        s.rigid_modes_dropped
                    );
                }
            }
        }
    }
    Ok(())
}

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_writer(std::io::stderr)
        .with_env_filter(tracing_subscriber::EnvFilter::try_from_env("VES_LOG").unwrap_or_else(|_| "warn".into()))
        .init();
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(1)
        }
    }
}
