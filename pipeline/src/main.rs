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
        /// Elastic modes to keep (overrides the scene's modes.count).
        #[arg(long)]
        modes: Option<usize>,
    },
    /// Precompute many scenes (files, or directories searched for *.toml): up-to-date outputs
    /// are skipped, a failed scene is reported and the rest go on (exit status 1 at the end),
    /// an interrupted batch resumes where it stopped.
    Batch {
        /// Scene files or directories.
        #[arg(required = true)]
        inputs: Vec<PathBuf>,
        /// Scenes precomputed at once.
        #[arg(short = 'j', long, default_value_t = 1)]
        jobs: usize,
        /// Output directory (default: beside each scene, <name>.h5).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Eigen-solver.
        #[arg(long, value_enum, default_value_t = SolverChoice::Auto)]
        solver: SolverChoice,
        /// Print the outcomes as JSON (last line of stdout).
        #[arg(long)]
        json: bool,
    },
    /// Run a real-time haptic session on a basis with scripted devices, and report its timing.
    Session {
        /// Basis file (HDF5).
        basis: PathBuf,
        /// A device per hand: `script:FILE.csv` (t, x, y, z[, button] in SI units).
        #[arg(long = "device", required = true)]
        devices: Vec<String>,
        /// Haptic rate, Hz.
        #[arg(long, default_value_t = 1000.0)]
        rate: f64,
        /// Session length, s (default: the longest script).
        #[arg(long)]
        duration: Option<f64>,
        /// Modes used (default: all in the file).
        #[arg(long)]
        modes: Option<usize>,
        /// Simulate only this space (default: every space, switching to the volume of interest
        /// that holds the hands).
        #[arg(long)]
        space: Option<String>,
        /// Coupling stiffness, N/m.
        #[arg(long, default_value_t = 500.0)]
        stiffness: f64,
        /// Force limit of the device, N.
        #[arg(long, default_value_t = 10.0)]
        max_force: f64,
        /// Busy-wait between steps instead of sleeping (lower jitter, one core fully used).
        #[arg(long)]
        spin: bool,
        /// Validity limit of the linear model: normal strain along the surface edges at a hand.
        #[arg(long, default_value_t = 0.02)]
        strain_limit: f64,
        /// What to do past the strain limit.
        #[arg(long, value_enum, default_value_t = StrainReaction::Flag)]
        strain_policy: StrainReaction,
        /// Print the statistics as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Benchmark the runtime on a basis: haptic step (r = 30 and 100) and full-field update.
    Bench {
        /// Basis file (HDF5).
        basis: PathBuf,
        /// Print JSON.
        #[arg(long)]
        json: bool,
    },
    /// Export the assembled K and M (global space, free DOFs) to HDF5 for external solvers.
    Matrices {
        /// Scene file (TOML, version 1).
        scene: PathBuf,
        /// Output file (HDF5).
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Cross-check the modes and static response of a scene or a basis file against independent
    /// solvers on the same mesh. Exit status 2 when a tolerance is exceeded.
    Verify {
        /// Scene file (TOML, version 1) or basis file (HDF5).
        input: PathBuf,
        /// Reference solver.
        #[arg(long, value_enum, default_value_t = ves_pipeline::verify::Reference::All)]
        against: ves_pipeline::verify::Reference,
        /// Modes compared (default: the scene's count).
        #[arg(long)]
        modes: Option<usize>,
        /// Largest relative frequency difference (default: 1e-6 for scikit-fem; CalculiX 1e-3
        /// with 10-node tets, 0.1 with 4-node: its mass integration differs).
        #[arg(long)]
        tol_freq: Option<f64>,
        /// Smallest MAC of an isolated mode (default 0.999; CalculiX 4-node 0.99).
        #[arg(long)]
        min_mac: Option<f64>,
        /// Largest principal angle of a group of close frequencies, rad (default 1e-3; CalculiX 1e-2).
        #[arg(long)]
        max_angle: Option<f64>,
        /// Largest relative difference of the static displacement at the load node (default 1e-6).
        #[arg(long)]
        tol_static: Option<f64>,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Measure accuracy against cost over a sweep of meshes and mode counts: writes report.md,
    /// report.json and Pareto plots (PNG, SVG) into a directory.
    Report {
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
            modes,
        } => {
            // SLEPc brings MPI up first: under mpirun every rank runs this command.
            let _slepc = match solver {
                SolverChoice::Slepc => {
                    let s = ves_pipeline::modes::slepc::Session::init()?;
                    RANK.store(ves_pipeline::modes::slepc::rank(), std::sync::atomic::Ordering::Relaxed);
                    if ves_pipeline::modes::slepc::rank() != 0 {
                        ves_pipeline::progress::hide_inner(true);
                    }
                    Some(s)
                }
                _ => None,
            };
            let mut scene = Scene::load(&scene)?;
            if let Some(m) = modes {
                anyhow::ensure!((1..=2000).contains(&m), "--modes {m}: must be between 1 and 2000");
                scene.modes.count = m;
            }
            let out = output.unwrap_or_else(|| scene.path.with_file_name(format!("{}.h5", scene.name)));
            let summary = precompute::run(&scene, &out, solver)?;
            if ves_pipeline::modes::slepc::rank() != 0 {
                return Ok(());
            }
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
        Command::Batch {
            inputs,
            jobs,
            out,
            solver,
            json,
        } => {
            anyhow::ensure!((1..=64).contains(&jobs), "-j {jobs}: give 1 to 64 parallel scenes");
            let scenes = ves_pipeline::batch::collect(&inputs)?;
            let opts = ves_pipeline::batch::BatchOptions { jobs, out, solver };
            let outcomes = ves_pipeline::batch::run(&scenes, &opts)?;
            use ves_pipeline::batch::Status;
            let count = |s: Status| outcomes.iter().filter(|o| o.status == s).count();
            let (done, fresh, failed) = (count(Status::Done), count(Status::UpToDate), count(Status::Failed));
            if json {
                println!("{}", serde_json::to_string(&outcomes)?);
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
                anyhow::bail!(
                    "{failed} of {} scenes failed: {}",
                    outcomes.len(),
                    outcomes
                        .iter()
                        .filter(|o| o.status == Status::Failed)
                        .map(|o| o.scene.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                );
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
        Command::Session {
            basis,
            devices,
            rate,
            duration,
            modes,
            space,
            stiffness,
            max_force,
            spin,
            strain_limit,
            strain_policy,
            json,
        } => {
            anyhow::ensure!(
                strain_limit > 0.0 && strain_limit.is_finite(),
                "--strain-limit {strain_limit}: must be a finite strain > 0 (e.g. 0.02)"
            );
            anyhow::ensure!(
                (1.0..=10_000.0).contains(&rate),
                "--rate {rate}: must be between 1 and 10000 Hz"
            );
            anyhow::ensure!(
                stiffness > 0.0 && max_force > 0.0,
                "--stiffness and --max-force must be > 0"
            );
            let spaces = match space {
                Some(space) => vec![ves_runtime::switching::SpaceInput {
                    basis: std::sync::Arc::new(ves_runtime::basis::load(
                        &basis,
                        &ves_runtime::LoadOptions {
                            space: Some(space),
                            modes,
                            surface_only: true,
                        },
                    )?),
                    transfers: vec![None],
                }],
                None => ves_runtime::switching::load_spaces(&basis, modes, true)?,
            };
            let mut devs: Vec<Box<dyn ves_runtime::device::Device>> = Vec::new();
            let mut longest = 0.0f64;
            for d in &devices {
                let file = d
                    .strip_prefix("script:")
                    .ok_or_else(|| anyhow::anyhow!("--device {d:?}: use script:FILE.csv"))?;
                let dev = ves_runtime::device::ScriptedDevice::load(std::path::Path::new(file))?;
                longest = longest.max(dev.duration());
                devs.push(Box::new(dev));
            }
            let cfg = ves_runtime::session::SessionConfig {
                rate_hz: rate,
                duration_s: duration.unwrap_or(longest).max(1.0 / rate),
                coupling: ves_runtime::haptic::Coupling {
                    stiffness,
                    damping: 2.0 * (stiffness * 1e-3).sqrt(),
                    max_force,
                },
                sleep: !spin,
                strain: ves_runtime::haptic::StrainWatch {
                    limit: strain_limit,
                    policy: match strain_policy {
                        StrainReaction::Flag => ves_runtime::haptic::StrainPolicy::Flag,
                        StrainReaction::Stiffen => ves_runtime::haptic::StrainPolicy::Stiffen,
                        StrainReaction::Release => ves_runtime::haptic::StrainPolicy::Release,
                    },
                },
                ..Default::default()
            };
            let bytes: usize = spaces.iter().map(|s| s.basis.bytes_loaded).sum();
            let stats = ves_runtime::session::run_spaces(spaces, devs, &cfg)
                .map_err(|e| anyhow::anyhow!("{}: {e}", basis.display()))?;
            if json {
                let mut v = serde_json::to_value(&stats)?;
                v["bytes_loaded"] = bytes.into();
                println!("{v}");
            } else {
                println!("{stats:#?}");
            }
        }
        Command::Bench { basis, json } => {
            let mut report = serde_json::Map::new();
            for r in [30usize, 100] {
                let opts = ves_runtime::LoadOptions {
                    modes: Some(r),
                    surface_only: true,
                    ..Default::default()
                };
                match ves_runtime::basis::load(&basis, &opts) {
                    Ok(b) => {
                        let ns = ves_runtime::bench::haptic_step_ns(std::sync::Arc::new(b), 201, 2000);
                        report.insert(format!("haptic_step_ns_median_r{r}"), ns.into());
                    }
                    Err(e) => {
                        tracing::warn!("r = {r}: {e}");
                        report.insert(format!("haptic_step_ns_median_r{r}"), serde_json::Value::Null);
                    }
                }
            }
            let opts = ves_runtime::LoadOptions {
                modes: Some(30),
                ..Default::default()
            };
            let b = ves_runtime::basis::load(&basis, &opts)
                .or_else(|_| ves_runtime::basis::load(&basis, &ves_runtime::LoadOptions::default()))?;
            report.insert("full_field_modes".into(), b.mode_count().into());
            report.insert("full_field_vertices".into(), b.vertex_count().into());
            report.insert(
                "full_field_ms_median".into(),
                ves_runtime::bench::full_field_ms(&b, 301).into(),
            );
            report.insert("bytes_loaded".into(), b.bytes_loaded.into());
            let v = serde_json::Value::Object(report);
            if json {
                println!("{v}");
            } else {
                println!("{}", serde_json::to_string_pretty(&v)?);
            }
        }
        Command::Verify {
            input,
            against,
            modes,
            tol_freq,
            min_mac,
            max_angle,
            tol_static,
            json,
        } => {
            let tol = ves_pipeline::verify::ToleranceOverrides {
                freq: tol_freq,
                mac: min_mac,
                angle: max_angle,
                static_rel: tol_static,
            };
            let report = ves_pipeline::verify::verify_input(&input, against, modes, &tol)?;
            if json {
                println!("{}", serde_json::to_string(&report)?);
            } else {
                println!(
                    "{}: {} nodes, {} tets (order {}), {} unknowns",
                    report.input, report.nodes, report.tets, report.element_order, report.dofs
                );
                for r in &report.references {
                    println!(
                        "\n{} ({:.1} s): {}",
                        r.solver,
                        r.seconds,
                        if r.pass { "PASS" } else { "FAIL" }
                    );
                    println!(
                        "  mode     ours (Hz)      reference (Hz)   rel. diff      MAC          group angle (rad)"
                    );
                    for m in &r.modes {
                        println!(
                            "  {:>4} {:>14.6} {:>18.6} {:>12.2e} {:>14.10} {:>6} {:.2e}",
                            m.mode + 1,
                            m.ours_hz,
                            m.reference_hz,
                            m.rel_diff,
                            m.mac,
                            m.group,
                            m.group_angle_rad
                        );
                    }
                    let st = r
                        .static_rel_diff
                        .map_or("n/a (free body)".to_string(), |s| format!("{s:.2e}"));
                    println!(
                        "  max rel. freq. diff {:.2e}, min MAC (isolated) {:.10}, max group angle {:.2e} rad, static {st}",
                        r.max_rel_freq_diff, r.min_mac_isolated, r.max_group_angle_rad
                    );
                }
            }
            if !report.pass {
                return Err(VerifyFailed.into());
            }
        }
        Command::Report {
            scene,
            output,
            modes,
            sizes,
            orders,
            duration,
            json,
        } => {
            let scene = Scene::load(&scene)?;
            let mut opts = ves_pipeline::report::ReportOptions::defaults(&scene);
            opts.modes = modes.unwrap_or(opts.modes);
            opts.sizes = sizes.unwrap_or(opts.sizes);
            opts.orders = orders.unwrap_or(opts.orders);
            opts.duration = duration;
            let report = ves_pipeline::report::run(&scene, &opts, &output)?;
            if json {
                println!("{}", serde_json::to_string(&report)?);
            } else {
                println!(
                    "wrote {}/report.md, report.json, error_vs_online.{{png,svg}}, error_vs_offline.{{png,svg}} ({:.1} s)",
                    output.display(),
                    report.total_s
                );
            }
        }
        Command::Info { basis, json } => {
            let info = store::info(&basis)?;
            if json {
                println!("{}", serde_json::to_string(&info)?);
            } else {
                println!("{} ({} bytes, {})", info.path, info.bytes, info.generator);
                for s in &info.spaces {
                    println!(
                        "  {}: {} nodes ({} vertices), {} tets of order {}, {} modes {:.4}..{:.4} Hz, max residual {:.1e}, {} rigid dropped{}",
                        s.name,
                        s.nodes,
                        s.vertices,
                        s.tets,
                        s.element_order,
                        s.modes,
                        s.frequencies_hz.first().copied().unwrap_or(0.0),
                        s.frequencies_hz.last().copied().unwrap_or(0.0),
                        s.max_relative_residual,
                        s.rigid_modes_dropped,
                        if s.static_correction_vertices > 0 {
                            format!(", static correction at {} vertices", s.static_correction_vertices)
                        } else {
                            String::new()
                        }
                    );
                }
            }
        }
    }
    Ok(())
}

/// Reaction of `ves session` past the strain limit.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum StrainReaction {
    /// Report it only.
    Flag,
    /// The part stops deforming further; the hand feels it stiffen.
    Stiffen,
    /// The hand lets go.
    Release,
}

/// Verification ran but a tolerance was exceeded (exit status 2).
#[derive(Debug)]
struct VerifyFailed;

impl std::fmt::Display for VerifyFailed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "verification failed: a reference differs beyond the tolerances (see the report)"
        )
    }
}

impl std::error::Error for VerifyFailed {}

/// MPI rank of this process (0 unless `--solver slepc` under mpirun): only rank 0 reports.
static RANK: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_writer(std::io::stderr)
        .with_env_filter(tracing_subscriber::EnvFilter::try_from_env("VES_LOG").unwrap_or_else(|_| "warn".into()))
        .init();
    // A panic is a bug, but the user still gets one line (set VES_LOG=debug for the default
    // report with its location).
    if std::env::var_os("VES_LOG").is_none() {
        std::panic::set_hook(Box::new(|info| {
            let msg = info
                .payload()
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| info.payload().downcast_ref::<String>().cloned())
                .unwrap_or_default();
            eprintln!("internal error (please report): {}", msg.replace('\n', " "));
        }));
    }
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            if RANK.load(std::sync::atomic::Ordering::Relaxed) == 0 {
                eprintln!("error: {e:#}");
            }
            ExitCode::from(if e.is::<VerifyFailed>() { 2 } else { 1 })
        }
    }
}
