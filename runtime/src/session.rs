//! A real-time session: a haptic thread at a fixed rate (devices in, forces out, modal state
//! published lock-free) beside a visualization thread computing the whole deformed part.

use crate::basis::Basis;
use crate::device::Device;
use crate::haptic::{Coupling, HandInput, HandOutput, InvalidSetting, StrainWatch};
use crate::integrator::Scheme;
use crate::snapshot::Snapshot;
use crate::switching::{SpaceInput, SwitchConfig, Switcher};
use crate::visual;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

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
    pub strain: StrainWatch,
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
            strain: StrainWatch::default(),
            realtime: false,
        }
    }
}

/// What a session measured.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct SessionStats {
    /// Haptic steps run.
    pub steps: u64,
    /// Steps per wall-clock second.
    pub achieved_rate_hz: f64,
    /// Whole haptic step (devices, simulation, publishing), ns: median.
    pub step_ns_median: u64,
    /// 99th percentile step time, ns.
    pub step_ns_p99: u64,
    /// Longest step, ns.
    pub step_ns_max: u64,
    /// Median of the simulation part alone (picking, coupling, integration), ns.
    pub haptic_compute_ns_median: u64,
    /// |wake-up time − deadline|, µs: 99.9th percentile.
    pub period_error_us_p999: f64,
    /// Largest period error, µs.
    pub period_error_us_max: f64,
    /// Steps that finished after the next deadline.
    pub missed_deadlines: u64,
    /// Full-field updates done.
    pub visual_updates: u64,
    /// Full-field updates per second.
    pub visual_rate_hz: f64,
    /// Largest force sent to a device, N.
    pub peak_force_n: f64,
    /// Steps where the force limit acted.
    pub clamped_steps: u64,
    /// Largest modal energy seen (½Σ(v² + λq²)), J.
    pub max_energy_j: f64,
    /// Modal energy at the end, J.
    pub final_energy_j: f64,
    /// Steps rolled back for non-finite state.
    pub quarantined: u64,
    /// Modal spaces in the session (1 + volumes of interest).
    pub spaces: usize,
    /// Switches between spaces.
    pub switches: u64,
    /// Longest switch in the haptic thread (state transfer, hand-over), µs.
    pub switch_us_max: f64,
    /// Largest strain seen at a hand's vertex.
    pub strain_max: f64,
    /// Hand-steps past the strain limit.
    pub strain_exceeded_steps: u64,
    /// Largest surface-edge strain of the drawn part (visualization thread, every frame).
    pub strain_max_surface: f64,
    /// Largest von Mises stress over the whole drawn part, Pa (visualization thread, every
    /// frame; null when the basis has no modal stress).
    pub von_mises_max: Option<f64>,
    /// Largest von Mises stress at a hand's vertex, Pa (null without modal stress).
    pub von_mises_max_hands: Option<f64>,
    /// Yield strength over `von_mises_max`: the whole part's smallest safety factor (null
    /// without stress or yield strength).
    pub safety_factor_min: Option<f64>,
    /// Hand-steps past the stress criterion: the safety factor at the hand's vertex, or the
    /// whole part's, below the watch's minimum.
    pub stress_exceeded_steps: u64,
    /// Drawn frames in which the whole part's safety factor was below the watch's minimum.
    pub safety_factor_below_min_frames: u64,
    /// Largest principal stress over the whole drawn part, Pa (null without modal stress).
    pub principal_stress_max: Option<f64>,
    /// Largest principal strain over the whole drawn part (null without modal stress).
    pub principal_strain_max: Option<f64>,
    /// The force on each device at the last step, N.
    pub final_forces_n: Vec<[f64; 3]>,
    /// What real-time hygiene the session got (null when not asked for).
    pub realtime: Option<crate::realtime::Realtime>,
}

/// Nanosecond timings streamed into a histogram (3 significant digits, 1 ns to 1 h): memory is
/// fixed whatever the session's length, and recording never allocates.
/// How long before a deadline a sleeping haptic thread wakes to spin (sleep overshoots by ~60 µs).
const SLEEP_WINDOW: Duration = Duration::from_micros(150);

/// The spin window of `--spin` under SCHED_FIFO with real-time throttling (at most 30 % of the
/// period): far below the 95 % the kernel allows, wide enough that a FIFO wake-up is never late.
const SPIN_WINDOW: Duration = Duration::from_micros(300);

struct Timings(hdrhistogram::Histogram<u64>);

impl Timings {
    fn new() -> Result<Timings, String> {
        hdrhistogram::Histogram::new_with_bounds(1, 3_600_000_000_000, 3)
            .map(Timings)
            .map_err(|e| format!("timing histogram: {e}"))
    }

    fn record(&mut self, ns: u64) {
        self.0.saturating_record(ns.max(1));
    }

    fn quantile(&self, q: f64) -> u64 {
        if self.0.is_empty() {
            0
        } else {
            self.0.value_at_quantile(q)
        }
    }

    fn max(&self) -> u64 {
        if self.0.is_empty() { 0 } else { self.0.max() }
    }
}

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
        let limit = self.strain.limit;
        InvalidSetting::check("strain-limit", limit, "", "> 0, e.g. 0.02", limit > 0.0)?;
        let sf = self.strain.min_safety_factor;
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
    /// Deformed, posed vertex positions of the space, x y z per vertex.
    pub positions: &'a [f32],
    /// Stress per vertex (6 Voigt components, Pa), when the space has modal stress.
    pub stress: Option<&'a [f32]>,
    /// The whole part's safety factor is below the watch's minimum.
    pub alarm: bool,
    /// The part's largest von Mises stress (Pa) and its vertex, when the space has stress.
    pub von_mises_max: Option<(f64, usize)>,
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
/// elapsed. A part whose basis holds mass properties moves as a free body when `cfg.free_body`
/// is set.
pub fn run(basis: Arc<Basis>, devices: Vec<Box<dyn Device>>, cfg: &SessionConfig) -> Result<SessionStats, String> {
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
) -> Result<SessionStats, String> {
    run_spaces_with(spaces, devices, cfg, Hooks::default())
}

/// [`run_spaces`] with hooks: an external stop and a frame observer (the viewer's path).
pub fn run_spaces_with(
    spaces: Vec<SpaceInput>,
    mut devices: Vec<Box<dyn Device>>,
    cfg: &SessionConfig,
    hooks: Hooks,
) -> Result<SessionStats, String> {
    cfg.validate().map_err(|e| e.to_string())?;
    let hands = devices.len().max(1);
    let rate = cfg.rate_hz;
    let dt = 1.0 / rate;
    // Saturates at u64::MAX for an infinite session.
    let steps = (cfg.duration_s * rate).round().max(1.0) as u64;
    let external_stop = hooks.stop.unwrap_or_default();
    let reset = hooks.reset.unwrap_or_default();
    let bases: Vec<Arc<Basis>> = spaces.iter().map(|s| s.basis.clone()).collect();
    let mut haptics =
        Switcher::new(spaces, cfg.coupling, dt, cfg.scheme, hands, cfg.switching).map_err(|e| e.to_string())?;
    if let (Some((gravity, damping)), Some(_)) = (cfg.free_body, bases[0].rigid) {
        for sim in haptics.sims_mut() {
            sim.set_free_body(gravity, damping)?;
        }
    }
    for sim in haptics.sims_mut() {
        sim.set_strain_watch(cfg.strain);
    }
    let (mut strain_max, mut strain_steps) = (0.0f64, 0u64);
    let (mut vm_hands, mut stress_steps) = (0.0f64, 0u64);
    // Published: the active space's index, the pose (7), then that space's q.
    let r_max = bases.iter().map(|b| b.mode_count()).max().unwrap_or(0);
    let mut published = vec![0.0; 8 + r_max];
    let snapshot = Arc::new(Snapshot::new(published.len()));
    let stop = Arc::new(AtomicBool::new(false));
    let visual_count = Arc::new(AtomicU64::new(0));
    let surface_strain = Arc::new(AtomicU64::new(0f64.to_bits()));
    let part_von_mises = Arc::new(AtomicU64::new(0f64.to_bits()));
    // Largest principal stress and strain of the part, drawing thread.
    let part_principal = Arc::new([AtomicU64::new(0f64.to_bits()), AtomicU64::new(0f64.to_bits())]);
    // Set by the drawing thread while the whole part's safety factor is below the minimum.
    let part_alarm = Arc::new(AtomicBool::new(false));
    let alarm_frames = Arc::new(AtomicU64::new(0));
    let min_sf = cfg.strain.min_safety_factor;

    let viz = {
        let (bases, snapshot, stop, count) = (bases.clone(), snapshot.clone(), stop.clone(), visual_count.clone());
        let (strain, von_mises, principal) = (surface_strain.clone(), part_von_mises.clone(), part_principal.clone());
        let (alarm, frames) = (part_alarm.clone(), alarm_frames.clone());
        let cap = cfg.visual_hz.map(|hz| Duration::from_secs_f64(1.0 / hz.max(1.0)));
        let mut observer = hooks.frame;
        std::thread::spawn(move || {
            let mut q = vec![0.0; 8 + r_max];
            // One position buffer per space, made before the loop.
            let mut pos: Vec<Vec<f32>> = bases.iter().map(|b| vec![0.0f32; 3 * b.vertex_count()]).collect();
            let mut sigma: Vec<Vec<f32>> = bases
                .iter()
                .map(|b| vec![0.0f32; if b.stress.is_some() { 6 * b.vertex_count() } else { 0 }])
                .collect();
            let start = Instant::now();
            while !stop.load(Ordering::Relaxed) {
                let t = Instant::now();
                let (time, _) = snapshot.read(&mut q);
                let i = (q[0] as usize).min(bases.len() - 1);
                let r = bases[i].mode_count();
                visual::posed_positions_of(&bases[i], &q[8..8 + r], &q[1..8], &mut pos[i]);
                std::hint::black_box(&pos[i]);
                // Whole-part validity: the largest surface-edge strain drawn so far.
                let s = visual::max_edge_strain(&bases[i], &pos[i]);
                if s > f64::from_bits(strain.load(Ordering::Relaxed)) {
                    strain.store(s.to_bits(), Ordering::Relaxed);
                }
                // And the largest von Mises stress (rigid motion carries no stress: q alone).
                let has_stress = visual::stresses(&bases[i], &q[8..8 + r], &mut sigma[i]);
                let mut below = false;
                let mut peak = None;
                if has_stress {
                    let (vm, at) = visual::max_von_mises(&sigma[i]);
                    peak = Some((vm, at));
                    if vm > f64::from_bits(von_mises.load(Ordering::Relaxed)) {
                        von_mises.store(vm.to_bits(), Ordering::Relaxed);
                    }
                    below = bases[i].yield_strength.is_some_and(|y| y < min_sf * vm);
                    let (p_stress, p_strain) = visual::max_principal(&sigma[i], bases[i].elastic);
                    for (slot, v) in principal.iter().zip([Some(p_stress), p_strain]) {
                        if let Some(v) = v.filter(|&v| v > f64::from_bits(slot.load(Ordering::Relaxed))) {
                            slot.store(v.to_bits(), Ordering::Relaxed);
                        }
                    }
                    alarm.store(below, Ordering::Relaxed);
                    frames.fetch_add(u64::from(below), Ordering::Relaxed);
                }
                if let Some(f) = observer.as_mut() {
                    f(&Frame {
                        space: i,
                        modal: &q[8..8 + r],
                        pose: &q[1..8],
                        positions: &pos[i],
                        stress: has_stress.then_some(&sigma[i][..]),
                        alarm: below,
                        von_mises_max: peak,
                        time,
                    });
                }
                count.fetch_add(1, Ordering::Relaxed);
                if let Some(c) = cap {
                    std::thread::sleep(c.saturating_sub(t.elapsed()));
                }
            }
            start.elapsed().as_secs_f64()
        })
    };

    let (mut step_ns, mut period_err_ns, mut compute_ns) = (Timings::new()?, Timings::new()?, Timings::new()?);
    let mut inputs = vec![HandInput::default(); hands];
    let mut outputs = vec![HandOutput::default(); hands];
    let (mut missed, mut peak, mut clamped, mut max_energy) = (0u64, 0.0f64, 0u64, 0.0f64);
    let period = Duration::from_secs_f64(dt);
    let mut rt = cfg
        .realtime
        .then(|| crate::realtime::haptic_thread(crate::realtime::haptic_core()));
    // Sleep to just before each deadline, then spin: sleep alone overshoots by ~60 µs. `--spin`
    // spins the whole period, except under SCHED_FIFO with the kernel's real-time throttling,
    // which would stop a thread that never sleeps for 50 ms of every second (measured: 486
    // deadlines missed in 10 s): it then keeps a wider spin window and sleeps the rest.
    let window = match &mut rt {
        Some(r) if !cfg.sleep && r.sched_fifo && crate::realtime::rt_throttled() => {
            let w = SPIN_WINDOW.min(period.mul_f64(0.3));
            r.spin_window_us = Some(w.as_micros() as u64);
            Some(w)
        }
        _ => cfg.sleep.then_some(SLEEP_WINDOW),
    };
    let start = Instant::now();
    let mut next = start;
    let mut done_steps = 0;
    for k in 0..steps {
        if external_stop.load(Ordering::Relaxed) {
            break;
        }
        done_steps = k + 1;
        let now = Instant::now();
        if let Some(w) = window
            && next > now + w + Duration::from_micros(50)
        {
            std::thread::sleep(next - now - w);
        }
        while Instant::now() < next {
            std::hint::spin_loop();
        }
        let woke = Instant::now();
        period_err_ns.record(woke.duration_since(next).as_nanos() as u64);
        let t = k as f64 * dt;
        for (inp, dev) in inputs.iter_mut().zip(devices.iter_mut()) {
            let s = dev.read(t);
            *inp = HandInput {
                position: s.position,
                velocity: s.velocity,
                button: s.button,
            };
        }
        if reset.load(Ordering::Relaxed) && reset.swap(false, Ordering::Relaxed) {
            haptics.reset();
        }
        let alarm = part_alarm.load(Ordering::Relaxed);
        for sim in haptics.sims_mut() {
            sim.set_part_alarm(alarm);
        }
        let c0 = Instant::now();
        haptics.step(&inputs, &mut outputs);
        compute_ns.record(c0.elapsed().as_nanos() as u64);
        for (out, dev) in outputs.iter().zip(devices.iter_mut()) {
            dev.write(out.force);
            dev.observe(out);
            let m = (out.force[0].powi(2) + out.force[1].powi(2) + out.force[2].powi(2)).sqrt();
            peak = peak.max(m);
            clamped += u64::from(out.clamped);
            strain_max = strain_max.max(out.strain);
            strain_steps += u64::from(out.strain_exceeded);
            vm_hands = vm_hands.max(out.von_mises);
            stress_steps += u64::from(out.stress_exceeded);
        }
        let active = haptics.sim(haptics.active());
        let q = &active.state().q;
        published[0] = haptics.active() as f64;
        published[1..8].copy_from_slice(&active.pose());
        published[8..8 + q.len()].copy_from_slice(q);
        snapshot.publish(&published, t);
        max_energy = max_energy.max(active.state().energy());
        let done = Instant::now();
        step_ns.record(done.duration_since(woke).as_nanos() as u64);
        next += period;
        if done > next {
            missed += 1;
        }
    }
    let wall = start.elapsed().as_secs_f64();
    stop.store(true, Ordering::Relaxed);
    if let Some(r) = &rt {
        crate::realtime::restore(r);
    }
    let has_stress = bases.iter().any(|b| b.stress.is_some());
    let viz_wall = viz.join().unwrap_or(wall);
    let updates = visual_count.load(Ordering::Relaxed);
    Ok(SessionStats {
        steps: done_steps,
        achieved_rate_hz: done_steps as f64 / wall,
        step_ns_median: step_ns.quantile(0.5),
        step_ns_p99: step_ns.quantile(0.99),
        step_ns_max: step_ns.max(),
        haptic_compute_ns_median: compute_ns.quantile(0.5),
        period_error_us_p999: period_err_ns.quantile(0.999) as f64 / 1e3,
        period_error_us_max: period_err_ns.max() as f64 / 1e3,
        missed_deadlines: missed,
        visual_updates: updates,
        visual_rate_hz: updates as f64 / viz_wall.max(1e-9),
        peak_force_n: peak,
        clamped_steps: clamped,
        max_energy_j: max_energy,
        final_energy_j: haptics.sim(haptics.active()).state().energy(),
        quarantined: (0..bases.len()).map(|i| haptics.sim(i).quarantined).sum(),
        spaces: bases.len(),
        switches: haptics.switches,
        switch_us_max: haptics.max_switch_ns as f64 / 1e3,
        strain_max,
        strain_exceeded_steps: strain_steps,
        strain_max_surface: f64::from_bits(surface_strain.load(Ordering::Relaxed)),
        von_mises_max: has_stress.then(|| f64::from_bits(part_von_mises.load(Ordering::Relaxed))),
        von_mises_max_hands: has_stress.then_some(vm_hands),
        safety_factor_min: match (has_stress, bases[0].yield_strength) {
            (true, Some(y)) => Some(y / f64::from_bits(part_von_mises.load(Ordering::Relaxed)).max(f64::MIN_POSITIVE)),
            _ => None,
        },
        stress_exceeded_steps: stress_steps,
        safety_factor_below_min_frames: alarm_frames.load(Ordering::Relaxed),
        principal_stress_max: has_stress.then(|| f64::from_bits(part_principal[0].load(Ordering::Relaxed))),
        principal_strain_max: (has_stress && bases[0].elastic.is_some())
            .then(|| f64::from_bits(part_principal[1].load(Ordering::Relaxed))),
        final_forces_n: outputs.iter().map(|o| o.force).collect(),
        realtime: rt,
    })
}
