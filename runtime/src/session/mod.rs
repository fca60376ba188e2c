//! A real-time session: a haptic thread at a fixed rate (devices in, forces out, modal state
//! published lock-free; [`haptic_loop`]) beside a drawing thread making the whole deformed part
//! ([`drawing`]), each keeping its own statistics ([`stats`]). The session owns its devices and
//! closes them when it ends, whichever way; a device's fault ends it early and is reported in
//! [`SessionStats::device_fault`].

mod drawing;
mod haptic_loop;
mod stats;
#[cfg(test)]
mod tests;

pub use stats::{DeviceFaultReport, HandReport, SessionStats};

use crate::basis::Basis;
use crate::device::Device;
use crate::haptic::{Coupling, InvalidSetting, ValidityWatch};
use crate::integrator::Scheme;
use crate::snapshot::{Published, Snapshot};
use crate::switching::{SpaceInput, SwitchConfig, SwitchError, Switcher};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

/// Session settings.
#[derive(Clone, Copy, Debug)]
pub struct SessionConfig {
    /// Haptic rate, Hz (1–10 kHz).
    pub rate_hz: f64,
    /// Length, s.
    pub duration_s: f64,
    /// Virtual coupling.
    pub coupling: Coupling,
    /// Integration scheme.
    pub scheme: Scheme,
    /// Visualization rate cap, Hz (`None`: as fast as it goes).
    pub visual_hz: Option<f64>,
    /// Sleep between haptic steps (frees the core, costs wake-up jitter); `false` spins.
    pub sleep: bool,
    /// For a free part (a basis with mass properties): gravity (m/s²) and momentum damping (1/s).
    pub free_body: Option<([f64; 3], f64)>,
    /// Volume-of-interest switching (sessions over several spaces).
    pub switching: SwitchConfig,
    /// Validity watch of the linear model at the hands.
    pub watch: ValidityWatch,
    /// Real-time hygiene ([`crate::realtime`]): SCHED_FIFO, memory locking and a core of its
    /// own for the haptic thread. Off in the library by default
    /// (it changes the calling thread and the process); `ves session` and `ves view` turn it on.
    pub realtime: bool,
}

impl Default for SessionConfig {
    fn default() -> Self {
        SessionConfig {
            rate_hz: 1000.0,
            duration_s: 1.0,
            coupling: Coupling::default(),
            scheme: Scheme::Exact,
            visual_hz: Some(60.0),
            sleep: true,
            free_body: Some(([0.0, 0.0, -9.81], 1.0)),
            switching: SwitchConfig::default(),
            watch: ValidityWatch::default(),
            realtime: false,
        }
    }
}

/// Why a session could not run.
#[derive(Debug)]
pub enum SessionError {
    /// A setting out of range; names the setting as `ves session`'s flag does.
    Setting(InvalidSetting),
    /// The spaces cannot be switched between (a transfer missing or of the wrong size).
    Spaces(SwitchError),
    /// The part cannot move as a free body (its mass properties are unusable).
    FreeBody(crate::haptic::FreeBodyError),
    /// The timing statistics could not be set up.
    Statistics(String),
}

impl std::fmt::Display for SessionError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SessionError::Setting(e) => write!(f, "{e}"),
            SessionError::Spaces(e) => write!(f, "{e}"),
            SessionError::FreeBody(e) => write!(f, "free body: {e}"),
            SessionError::Statistics(e) => write!(f, "timing histogram: {e}"),
        }
    }
}

impl std::error::Error for SessionError {}

impl SessionConfig {
    /// Checks the settings a user gives (rate, duration, coupling, strain limit) before a
    /// session starts; the error names the setting as `ves session`'s flag does.
    pub fn validate(&self) -> Result<(), InvalidSetting> {
        let (rate, duration) = (self.rate_hz, self.duration_s);
        InvalidSetting::check(
            "rate",
            rate,
            "Hz",
            "between 1 and 10000",
            (1.0..=10_000.0).contains(&rate),
        )?;
        // The step count must fit in a u64 (statistics stream, so memory does not grow with it);
        // an infinite session runs until stopped (see [`Hooks::stop`]).
        if duration != f64::INFINITY {
            let steps_fit = duration * rate < u64::MAX as f64 / 2.0;
            InvalidSetting::check("duration", duration, "s", "> 0", duration > 0.0 && steps_fit)?;
        }
        self.coupling.validate()?;
        let limit = self.watch.limit;
        InvalidSetting::check("strain-limit", limit, "", "> 0, e.g. 0.02", limit > 0.0)?;
        let sf = self.watch.min_safety_factor;
        InvalidSetting::check("min-safety-factor", sf, "", "> 0, e.g. 1.5", sf > 0.0 && sf.is_finite())
    }
}

/// One drawn state, handed to [`Hooks::frame`] by the visualization thread.
pub struct Frame<'a> {
    /// The active space (index into the session's spaces).
    pub space: usize,
    /// Its modal coordinates.
    pub modal: &'a [f64],
    /// The part's pose (position, then unit quaternion w, x, y, z); identity for a held part.
    pub pose: &'a [f64],
    /// Elastic displacement u = Φq of every vertex of the space, part frame, x y z per vertex
    /// (drawn at rest + u, or posed: x + R(rest + u − c) for a free body).
    pub displacements: &'a [f32],
    /// Stress per vertex (6 Voigt components, Pa), when the space has modal stress.
    pub stress: Option<&'a [f32]>,
    /// The whole part's safety factor is below the watch's minimum.
    pub alarm: bool,
    /// The part's largest von Mises stress (Pa) and its vertex, when the space has stress.
    pub von_mises_max: Option<(f64, usize)>,
    /// What each `[[fixed]]` support exerts on the part in this state (force x y z, N; moment
    /// x y z about its centre, N·m), when the basis stores it.
    pub reactions: Option<&'a [[f64; 6]]>,
    /// Session time of the state, s.
    pub time: f64,
}

/// Receives every drawn frame (in the visualization thread).
pub type FrameObserver = Box<dyn FnMut(&Frame) + Send>;

/// What an embedding application adds to a session: a way to stop it, and the drawn frames.
#[derive(Default)]
pub struct Hooks {
    /// Ends the session when set (besides `duration_s`, which may then be infinite).
    pub stop: Option<Arc<AtomicBool>>,
    /// Called by the visualization thread with every frame it draws.
    pub frame: Option<FrameObserver>,
    /// When set, the haptic thread brings the part back to rest (hands let go, a free body
    /// where it started) at its next step and clears it.
    pub reset: Option<Arc<AtomicBool>>,
}

/// Runs a session on one space with one hand per device; returns when `duration_s` has
/// elapsed or a device faults. A part whose basis holds mass properties moves as a free body
/// when `cfg.free_body` is set.
pub fn run(
    basis: Arc<Basis>,
    devices: Vec<Box<dyn Device>>,
    cfg: &SessionConfig,
) -> Result<SessionStats, SessionError> {
    run_spaces(
        vec![SpaceInput {
            basis,
            transfers: vec![None],
        }],
        devices,
        cfg,
    )
}

/// Runs a session over every space of a part (global first), switching to the volume of
/// interest that holds the hands (see [`crate::switching`]).
pub fn run_spaces(
    spaces: Vec<SpaceInput>,
    devices: Vec<Box<dyn Device>>,
    cfg: &SessionConfig,
) -> Result<SessionStats, SessionError> {
    run_spaces_with(spaces, devices, cfg, Hooks::default())
}

/// [`run_spaces`] with hooks: an external stop and a frame observer (the viewer's path).
pub fn run_spaces_with(
    spaces: Vec<SpaceInput>,
    devices: Vec<Box<dyn Device>>,
    cfg: &SessionConfig,
    hooks: Hooks,
) -> Result<SessionStats, SessionError> {
    let mut devices = Devices(devices);
    cfg.validate().map_err(SessionError::Setting)?;
    let hands = devices.0.len().max(1);
    // Saturates at u64::MAX for an infinite session.
    let steps = (cfg.duration_s * cfg.rate_hz).round().max(1.0) as u64;
    let bases: Vec<Arc<Basis>> = spaces.iter().map(|s| s.basis.clone()).collect();
    let mut haptics = switcher(spaces, cfg, hands, bases[0].rigid.is_some())?;
    let r_max = bases.iter().map(|b| b.mode_count()).max().unwrap_or(0);
    let snapshot = Arc::new(Snapshot::for_state(&Published::with_hands(r_max, hands)));
    let part = Arc::new(stats::PartRecord {
        support_force: (0..bases[0].support_reactions.as_ref().map_or(0, |r| r.count()))
            .map(|_| stats::AtomicMax::default())
            .collect(),
        ..Default::default()
    });
    let stop_drawing = Arc::new(AtomicBool::new(false));
    let drawing = drawing::Drawing {
        bases: bases.clone(),
        snapshot: snapshot.clone(),
        state: Published::with_hands(r_max, hands),
        part: part.clone(),
        stop: stop_drawing.clone(),
        cap: cfg.visual_hz.map(|hz| Duration::from_secs_f64(1.0 / hz.max(1.0))),
        min_safety_factor: cfg.watch.min_safety_factor,
        observer: hooks.frame,
    }
    .spawn();
    let mut rt = cfg
        .realtime
        .then(|| crate::realtime::haptic_thread(crate::realtime::haptic_core()));
    let ran = haptic_loop::HapticLoop {
        haptics: &mut haptics,
        devices: &mut devices.0,
        snapshot: &snapshot,
        part: &part,
        stop: &hooks.stop.unwrap_or_default(),
        reset: &hooks.reset.unwrap_or_default(),
    }
    .run(cfg, steps, hands, rt.as_mut());
    stop_drawing.store(true, std::sync::atomic::Ordering::Relaxed);
    if let Some(r) = &rt {
        crate::realtime::restore(r);
    }
    devices.close();
    let drawing_wall = drawing.join();
    let ran = ran?;
    let device_fault = ran.fault.map(|f| DeviceFaultReport {
        hand: f.hand,
        device: devices
            .0
            .get(f.hand)
            .map(|d| d.info().name.to_string())
            .unwrap_or_default(),
        fault: f.fault,
        time_s: f.time_s,
        step: f.step,
    });
    Ok(SessionStats::from_parts(
        stats::HapticSide {
            timings: &ran.timings,
            tally: &ran.tally,
            switcher: &haptics,
            final_forces: ran.outputs.iter().map(|o| o.force).collect(),
            device_fault,
            realtime: rt,
        },
        stats::DrawingSide {
            part: &part,
            wall_s: drawing_wall.unwrap_or(ran.timings.wall_s),
            has_stress: bases.iter().any(|b| b.stress.is_some()),
            yield_strength: bases[0].yield_strength,
            elastic: bases[0].elastic.is_some(),
            final_reactions: final_reactions(&bases[0], &haptics),
            reactions_corrected: bases[0]
                .support_reactions
                .as_ref()
                .is_some_and(|r| r.statics != crate::basis::StaticReactions::Unknown),
        },
    ))
}

/// Per support of the first space, its centre and its reactions at the session's last state
/// (none while another space is active at the end: its modal state is not the first's).
fn final_reactions(first: &Basis, haptics: &crate::switching::Switcher) -> Vec<([f64; 3], [f64; 6])> {
    let Some(r) = first.support_reactions.as_ref().filter(|_| haptics.active() == 0) else {
        return Vec::new();
    };
    let out = haptics.sim(0).support_reactions().unwrap_or_default();
    r.centres.iter().copied().zip(out).collect()
}

/// A session's devices, closed when it ends: explicitly after the haptic loop, or when dropped
/// on any other way out (an error before the loop, a panic).
struct Devices(Vec<Box<dyn Device>>);

impl Devices {
    fn close(&mut self) {
        for d in &mut self.0 {
            d.close();
        }
    }
}

impl Drop for Devices {
    fn drop(&mut self) {
        self.close();
    }
}

/// The simulations of every space, with the session's free body and validity watch.
fn switcher(spaces: Vec<SpaceInput>, cfg: &SessionConfig, hands: usize, rigid: bool) -> Result<Switcher, SessionError> {
    let dt = 1.0 / cfg.rate_hz;
    let mut haptics =
        Switcher::new(spaces, cfg.coupling, dt, cfg.scheme, hands, cfg.switching).map_err(SessionError::Spaces)?;
    for sim in haptics.sims_mut() {
        if let (Some((gravity, damping)), true) = (cfg.free_body, rigid) {
            sim.set_free_body(gravity, damping).map_err(SessionError::FreeBody)?;
        }
        sim.set_validity_watch(cfg.watch);
    }
    Ok(haptics)
}
