//! The `ves` subcommands, one module each: arguments are checked into a config, then one call
//! into the library does the work and the module prints its result.

pub mod batch;
pub mod bench;
pub mod export;
pub mod faces;
pub mod info;
pub mod matrices;
pub mod precompute;
pub mod report;
pub mod session;
mod trace;
pub mod verify;
pub mod view;

use clap::{Parser, Subcommand};

/// The command line.
#[derive(Parser)]
#[command(
    name = "ves",
    version,
    about = "Feel and see a CAD part deform: offline modal precompute"
)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Mesh a scene, compute its lowest modes and write a modal-basis file.
    Precompute(precompute::Args),
    /// Precompute many scenes (files, or directories searched for *.toml): up-to-date outputs
    /// are skipped, a failed scene is reported and the rest go on (exit status 1 at the end),
    /// an interrupted batch resumes where it stopped.
    Batch(batch::Args),
    /// Run a real-time haptic session on a basis with scripted devices, and report its timing.
    Session(session::Args),
    /// Serve the part to a web browser: see it deform, pull it with the mouse (the page is the
    /// haptic device), browse its modes. Prints the URL.
    View(view::Args),
    /// Benchmark the runtime on a basis: haptic step (r = 30 and 100) and full-field update.
    Bench(bench::Args),
    /// Export the assembled K and M (global space, free DOFs) to HDF5 for external solvers.
    Matrices(matrices::Args),
    /// Cross-check the modes and static response of a scene or a basis file against independent
    /// solvers on the same mesh. Exit status 2 when a tolerance is exceeded.
    Verify(verify::Args),
    /// Measure accuracy against cost over a sweep of meshes and mode counts: writes report.md,
    /// report.json and Pareto plots (PNG, SVG) into a directory.
    Report(report::Args),
    /// Summarise a modal-basis file (after checking everything in it).
    Info(info::Args),
    /// Write a basis as VTK files (`--vtu DIR`: one .vtu per space, and one of its corner
    /// vertices with the modal stress) for tools that do not read the XDMF sidecar.
    Export(export::Args),
    /// List a part's CAD faces: tag (what a scene's `faces = [...]` names), kind (plane with its
    /// normal, cylinder with axis, radius and whether it is a hole, other), area and centroid.
    Faces(faces::Args),
    /// Internal: mesh one rung of the meshing ladder for a parent `ves` (gmsh in its own process).
    #[command(name = "mesh-worker", hide = true)]
    MeshWorker {
        /// The job's directory.
        dir: std::path::PathBuf,
    },
    /// Internal: one compute of `ves view`'s set-up panel for a parent `ves view`.
    #[command(name = "view-compute", hide = true)]
    ViewCompute {
        /// The job's directory.
        dir: std::path::PathBuf,
    },
}

/// `--solver`'s parser: the library's names, each with its line of help.
fn solver_parser() -> impl clap::builder::TypedValueParser<Value = ves_pipeline::modes::SolverChoice> {
    use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
    use ves_pipeline::modes::SolverChoice;
    PossibleValuesParser::new(SolverChoice::ALL.map(|c| PossibleValue::new(c.name()).help(c.about())))
        .try_map(|s| s.parse::<SolverChoice>())
}

/// Runs the parsed command.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    // gmsh runs in child processes of this binary, so that nothing it does can end `ves` (a
    // crash, an abort, a script's exit(0)). Not under MPI, where a rank must not fork.
    if std::env::var_os("OMPI_COMM_WORLD_SIZE").is_none()
        && std::env::var_os("PMI_SIZE").is_none()
        && let Ok(exe) = std::env::current_exe()
    {
        // The viewer's computes too: one that aborts (out of memory) must not end the server.
        crate::workshop::isolate_with(exe.clone());
        ves_pipeline::mesh::isolate_with(exe);
    }
    // This program owns its process: a signal removes its work folders before it ends.
    ves_pipeline::workdir::remove_on_signals();
    ves_pipeline::memory::cap_from_env()?;
    // Counts (a batch's scenes, a report's bases) as bars; a command with stages of its own
    // (precompute, verify) puts its terminal, quiet or not, above this one.
    let _terminal = ves_pipeline::progress::watch(crate::terminal::Terminal::on_stderr(true));
    match cli.command {
        Command::MeshWorker { dir } => Ok(ves_pipeline::mesh::serve_rung(&dir)?),
        Command::ViewCompute { dir } => crate::workshop::serve_compute(&dir),
        Command::Precompute(a) => a.run(),
        Command::Batch(a) => a.run(),
        Command::Session(a) => a.run(),
        Command::View(a) => a.run(),
        Command::Bench(a) => a.run(),
        Command::Matrices(a) => a.run(),
        Command::Verify(a) => a.run(),
        Command::Report(a) => a.run(),
        Command::Info(a) => a.run(),
        Command::Export(a) => a.run(),
        Command::Faces(a) => a.run(),
    }
}

/// The basis file a reading command takes, and its output form.
#[derive(clap::Args)]
pub struct BasisFile {
    /// Basis file (HDF5).
    basis: std::path::PathBuf,
    /// Print JSON (the last line of stdout) instead of text.
    #[arg(long)]
    json: bool,
}

/// Flags of the commands that read a scene and write a file.
#[derive(clap::Args)]
pub struct WriteFlags {
    /// Replace a symbolic link at the output path (the link, not its target).
    #[arg(long)]
    force: bool,
    /// Accept a .geo geometry: a gmsh script, which can run shell commands. Only for scenes you trust.
    #[arg(long)]
    allow_geo_scripts: bool,
}

impl WriteFlags {
    fn overwrite(&self) -> ves_pipeline::output::Overwrite {
        ves_pipeline::output::Overwrite { force: self.force }
    }

    fn scene(&self) -> ves_pipeline::scene::SceneOptions {
        ves_pipeline::scene::SceneOptions {
            allow_geo_scripts: self.allow_geo_scripts,
        }
    }
}

/// Verification ran but a tolerance was exceeded (exit status 2).
#[derive(Debug)]
pub struct VerifyFailed;

impl std::fmt::Display for VerifyFailed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "verification failed: a reference differs beyond the tolerances (see the report)"
        )
    }
}

impl std::error::Error for VerifyFailed {}

/// This process's MPI rank (0 unless `--solver slepc` under mpirun): only rank 0 reports.
pub fn rank() -> usize {
    ves_pipeline::modes::mpi_job::rank()
}

/// Prints `value` as one JSON line (the last line of stdout, README `--json`).
fn print_json<T: serde::Serialize>(value: &T) -> anyhow::Result<()> {
    print_text(&format!("{}\n", serde_json::to_string(value)?))
}

/// Writes `text` to stdout: a closed pipe or a full disk is an error of one line (println!
/// panics on them, after the work was done).
fn print_text(text: &str) -> anyhow::Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())
        .and_then(|()| out.flush())
        .map_err(|e| anyhow::anyhow!("cannot write to stdout: {e}"))
}
