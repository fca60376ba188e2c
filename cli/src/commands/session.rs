//! `ves session`.

use anyhow::{Context, Result};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use ves_runtime::LoadOptions;
use ves_runtime::device::{self, Device};
use ves_runtime::haptic::{Coupling, StrainPolicy, ValidityWatch};
use ves_runtime::session::{self, SessionConfig};
use ves_runtime::switching::{self, SpaceInput};

/// Reaction past the strain limit.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum StrainReaction {
    /// Report it only.
    Flag,
    /// The part stops deforming further; the hand feels it stiffen.
    Stiffen,
    /// The hand lets go.
    Release,
}

/// Arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Basis file (HDF5).
    basis: PathBuf,
    // Help: every kind of device the runtime can open, e.g. `script:FILE.csv`.
    #[arg(long = "device", required = true, help = format!("A device per hand: {}", device::usage()))]
    devices: Vec<String>,
    /// Session length, s (default: the longest script).
    #[arg(long)]
    duration: Option<f64>,
    #[command(flatten)]
    settings: Settings,
    /// Print the statistics as JSON.
    #[arg(long)]
    json: bool,
    /// Write every haptic step of every hand to this CSV file (time, hand position, contact,
    /// vertex, its elastic displacement, force, grip gap, strain, von Mises).
    #[arg(long, value_name = "FILE.csv")]
    trace: Option<PathBuf>,
}

/// What a session is made of besides its devices: shared by `ves session` and `ves view`.
#[derive(clap::Args)]
pub struct Settings {
    /// Haptic rate, Hz.
    #[arg(long, default_value_t = 1000.0)]
    rate: f64,
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
    /// Coupling damping, N·s/m (default: critical damping of the coupling spring against a 1 g
    /// device handle, 2√(k·m)).
    #[arg(long)]
    damping: Option<f64>,
    /// Force limit of the device, N.
    #[arg(long, default_value_t = 10.0)]
    max_force: f64,
    /// Busy-wait between steps instead of sleeping (lower jitter, one core fully used).
    #[arg(long)]
    spin: bool,
    /// Validity limit of the linear model: normal strain along the surface edges at a hand.
    #[arg(long, default_value_t = 0.02)]
    strain_limit: f64,
    /// What to do past the strain limit (or below the minimum safety factor).
    #[arg(long, value_enum, default_value_t = StrainReaction::Flag)]
    strain_policy: StrainReaction,
    /// With a basis holding modal stress and a yield strength: the smallest safety factor
    /// (yield / von Mises) at a hand before the strain policy acts.
    #[arg(long, default_value_t = 1.0)]
    min_safety_factor: f64,
    /// Leave the haptic thread at normal priority: no SCHED_FIFO, no memory lock, no pinning
    /// (what was granted otherwise is in the JSON's `realtime`).
    #[arg(long)]
    no_realtime: bool,
}

impl Settings {
    /// The session settings for a session of `duration_s`, checked before anything is loaded;
    /// `command` names the command in the advice.
    pub fn config(&self, duration_s: f64, command: &str) -> Result<SessionConfig> {
        let mut coupling = Coupling::critically_damped(self.stiffness, self.max_force);
        if let Some(c) = self.damping {
            coupling.damping = c;
        }
        let cfg = SessionConfig {
            rate_hz: self.rate,
            duration_s,
            coupling,
            sleep: !self.spin,
            realtime: !self.no_realtime,
            watch: ValidityWatch {
                limit: self.strain_limit,
                policy: match self.strain_policy {
                    StrainReaction::Flag => StrainPolicy::Flag,
                    StrainReaction::Stiffen => StrainPolicy::Stiffen,
                    StrainReaction::Release => StrainPolicy::Release,
                },
                min_safety_factor: self.min_safety_factor,
            },
            ..Default::default()
        };
        cfg.validate().map_err(|e| {
            let unit = if e.unit.is_empty() {
                String::new()
            } else {
                format!(" ({})", e.unit)
            };
            anyhow::anyhow!(
                "--{} {}: must be finite and {}{unit}; see ves {command} --help",
                e.setting,
                short(e.value),
                e.requirement
            )
        })?;
        Ok(cfg)
    }

    /// The spaces of `basis` this session simulates (surface vertices only).
    pub fn spaces(&self, basis: &Path) -> Result<Vec<SpaceInput>> {
        Ok(match &self.space {
            Some(space) => vec![SpaceInput {
                basis: Arc::new(ves_runtime::basis::load(
                    basis,
                    &LoadOptions {
                        space: Some(space.clone()),
                        modes: self.modes,
                        surface_only: true,
                    },
                )?),
                transfers: vec![None],
            }],
            None => switching::load_spaces(basis, self.modes, true)?,
        })
    }
}

/// One line per real-time measure the system refused (the session ran without it).
pub fn warn_refused(stats: &session::SessionStats) {
    for m in stats.realtime.iter().flat_map(|r| &r.refused) {
        tracing::warn!("real-time: {m}; the haptic loop ran without it");
    }
}

impl Args {
    pub fn run(self) -> Result<()> {
        let mut devices: Vec<Box<dyn Device>> = Vec::new();
        let mut longest = 0.0f64;
        for d in &self.devices {
            let dev = device::open(d)?;
            longest = longest.max(dev.info().length_s.unwrap_or(0.0));
            devices.push(dev);
        }
        // A duration given is checked as given; the scripts' length gets at least one step.
        let duration = self.duration.unwrap_or(longest.max(1.0 / self.settings.rate));
        // The runtime runs an infinite session until stopped (ves view); scripts end.
        if !duration.is_finite() {
            anyhow::bail!(
                "--duration {}: must be finite and > 0 (s); see ves session --help",
                short(duration)
            );
        }
        let cfg = self.settings.config(duration, "session")?;
        let trace = match &self.trace {
            Some(path) => {
                // Every row is reserved before the session (the haptic thread must not allocate):
                // a bound on the steps bounds that memory.
                let steps = (duration * cfg.rate_hz).round() + 1.0;
                let max = super::trace::MAX_STEPS;
                if steps > max as f64 {
                    anyhow::bail!(
                        "--duration {duration}: --trace records at most {max} steps per hand ({} s at --rate {} Hz, \
                         {} MB a hand); give a shorter --duration, or leave out --trace",
                        max as f64 / cfg.rate_hz,
                        cfg.rate_hz,
                        max * super::trace::ROW_BYTES / 1_000_000
                    );
                }
                let steps = steps as usize;
                let mut inputs = vec![self.basis.as_path()];
                inputs.extend(devices.iter().filter_map(|d| d.info().file));
                ves_pipeline::output::check_as(
                    path,
                    &inputs,
                    ves_pipeline::output::Overwrite { force: false },
                    "--trace",
                )?;
                let trace = super::trace::Trace::with_room(steps);
                devices = devices
                    .into_iter()
                    .enumerate()
                    .map(|(k, d)| trace.record(k, d))
                    .collect();
                Some((trace, path))
            }
            None => None,
        };
        let spaces = self.settings.spaces(&self.basis)?;
        let bytes: usize = spaces.iter().map(|s| s.basis.bytes_loaded).sum();
        let stats = session::run_spaces(spaces, devices, &cfg)
            .map_err(|e| anyhow::anyhow!(e))
            .with_context(|| self.basis.display().to_string())?;
        warn_refused(&stats);
        if let Some((trace, path)) = trace {
            super::trace::write(&trace, path)?;
        }
        if self.json {
            let mut v = serde_json::to_value(&stats)?;
            v["bytes_loaded"] = bytes.into();
            println!("{v}");
        } else {
            println!("{stats:#?}");
        }
        Ok(())
    }
}

/// A number as a user wrote it, short: `1e300` is not printed as 301 digits.
fn short(x: f64) -> String {
    if x != 0.0 && x.is_finite() && !(1e-3..1e6).contains(&x.abs()) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}
