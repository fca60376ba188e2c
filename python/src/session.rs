//! `ves.session`: a real-time haptic session replaying device scripts, as `ves session` does.

use crate::pipeline::run_long;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use ves_runtime::basis::LoadOptions;
use ves_runtime::device::{Device, ScriptedDevice};
use ves_runtime::haptic::{Coupling, ValidityWatch};
use ves_runtime::session::{Hooks, SessionConfig};
use ves_runtime::switching::SpaceInput;

/// Runs a haptic session on a basis (a path or an open `Basis`) with one hand per device
/// script (CSV rows `t, x, y, z[, button]`, SI units), at `rate` Hz for `duration` s (default:
/// the longest script), in real time; returns what `ves session --json` prints, as a dict.
/// Every space is simulated, switching to the volume of interest that holds the hands, unless
/// `space` names one. `realtime=True` asks for SCHED_FIFO, memory locking and a core of its own
/// for the haptic thread (they affect the whole process). Ctrl-C ends the session early.
#[pyfunction]
#[pyo3(signature = (basis, devices, *, rate=1000.0, duration=None, stiffness=500.0, damping=None, max_force=10.0, strain_limit=0.02, strain_policy="flag", min_safety_factor=1.0, spin=false, realtime=false, modes=None, space=None))]
#[allow(clippy::too_many_arguments)]
pub fn session<'py>(
    py: Python<'py>,
    basis: &Bound<'py, PyAny>,
    devices: Vec<PathBuf>,
    rate: f64,
    duration: Option<f64>,
    stiffness: f64,
    damping: Option<f64>,
    max_force: f64,
    strain_limit: f64,
    strain_policy: &str,
    min_safety_factor: f64,
    spin: bool,
    realtime: bool,
    modes: Option<usize>,
    space: Option<String>,
) -> PyResult<Bound<'py, PyAny>> {
    let path = crate::basis::path_of(basis, "basis: give the path of a basis file or a ves.Basis")?;
    let policy = crate::haptics::strain_policy("strain_policy", strain_policy)?;
    if modes == Some(0) {
        return Err(PyValueError::new_err("modes=0: simulate at least one mode"));
    }
    let (scripts, duration) = load_scripts(py, &devices, rate, duration)?;
    let mut coupling = Coupling::critically_damped(stiffness, max_force);
    if let Some(c) = damping {
        coupling.damping = c;
    }
    let cfg = SessionConfig {
        rate_hz: rate,
        duration_s: duration,
        coupling,
        sleep: !spin,
        realtime,
        watch: ValidityWatch {
            limit: strain_limit,
            policy,
            min_safety_factor,
        },
        ..Default::default()
    };
    cfg.validate().map_err(|e| PyValueError::new_err(e.to_string()))?;
    let stop = Arc::new(AtomicBool::new(false));
    let hooks = Hooks {
        stop: Some(stop.clone()),
        ..Default::default()
    };
    let what = format!("session {}", path.display());
    let stats = run_long(py, false, &what, Some(stop), move || {
        let spaces = load(&path, modes, space)?;
        let bytes: usize = spaces.iter().map(|s| s.basis.bytes_loaded).sum();
        let devices: Vec<Box<dyn Device>> = scripts.into_iter().map(|s| Box::new(s) as Box<dyn Device>).collect();
        let stats = ves_runtime::session::run_spaces_with(spaces, devices, &cfg, hooks)
            .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        let mut v = serde_json::to_value(&stats)?;
        v["bytes_loaded"] = bytes.into();
        Ok(v.to_string())
    })?;
    py.import("json")?.call_method1("loads", (stats,))
}

/// The device scripts, and the session's length: `duration`, or the longest script's (at
/// least one step at `rate`).
fn load_scripts(
    py: Python<'_>,
    devices: &[PathBuf],
    rate: f64,
    duration: Option<f64>,
) -> PyResult<(Vec<ScriptedDevice>, f64)> {
    if devices.is_empty() || devices.len() > 16 {
        return Err(PyValueError::new_err(format!(
            "devices: give 1 to 16 device scripts (got {})",
            devices.len()
        )));
    }
    if !(rate.is_finite() && rate > 0.0) {
        return Err(PyValueError::new_err(format!(
            "rate={rate}: must be finite and > 0 (Hz)"
        )));
    }
    let scripts = py
        .detach(|| {
            devices
                .iter()
                .map(|d| ScriptedDevice::load(d).map_err(|e| e.to_string()))
                .collect::<Result<Vec<_>, String>>()
        })
        .map_err(PyValueError::new_err)?;
    let longest = scripts.iter().map(|s| s.duration()).fold(0.0f64, f64::max);
    let duration = duration.unwrap_or(longest.max(1.0 / rate));
    if !duration.is_finite() {
        return Err(PyValueError::new_err(format!(
            "duration={duration}: must be finite and > 0 (s)"
        )));
    }
    Ok((scripts, duration))
}

/// The spaces a session simulates (surface vertices only): one when named, else all.
fn load(path: &Path, modes: Option<usize>, space: Option<String>) -> anyhow::Result<Vec<SpaceInput>> {
    Ok(match space {
        Some(space) => vec![SpaceInput {
            basis: Arc::new(ves_runtime::basis::load(
                path,
                &LoadOptions {
                    space: Some(space),
                    modes,
                    surface_only: true,
                },
            )?),
            transfers: vec![None],
        }],
        None => ves_runtime::switching::load_spaces(path, modes, true)?,
    })
}
