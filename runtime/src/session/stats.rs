//! What a session measures: the haptic thread's timings and tallies, the drawing thread's
//! whole-part maxima (shared lock-free), and the [`SessionStats`] made from both.

use crate::haptic::HandOutput;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

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
    /// Periods (wake-up to wake-up) longer than 1.1 ms.
    pub periods_over_1_1_ms: u64,
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
    /// Largest surface-edge strain of the drawn part (visualization thread, every frame; from
    /// the elastic displacement and the rest lengths in f64).
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
    /// Per hand: the vertex it touched, where, from how far, and how that vertex moved.
    pub hands: Vec<HandReport>,
    /// The device fault that ended the session early (null: none did).
    pub device_fault: Option<DeviceFaultReport>,
    /// What real-time hygiene the session got (null when not asked for).
    pub realtime: Option<crate::realtime::Realtime>,
    /// What each `[[fixed]]` support carried (empty: a free body, or a basis written before
    /// supports' reactions were stored).
    pub support_reactions: Vec<SupportReport>,
}

/// What one support exerted on the part during a session: the reactions of the modal state
/// (u = Φq), exact for that displacement of the FE model, and — where the basis knows the
/// supports' static reactions (`corrected`) — the share of the hands' loads the truncated modes
/// leave out added back, so a load held steady is carried whole. Without that the supports
/// together carry less than a hand's static force (the modes left out carry the rest).
#[derive(Clone, Debug, serde::Serialize)]
pub struct SupportReport {
    /// The support, counted from 0 as `fixed[i]` in the scene.
    pub support: usize,
    /// The point the moments are about (the middle of its held nodes' bounding box), m.
    pub centre_m: [f64; 3],
    /// Force at the session's last state, N.
    pub final_force_n: [f64; 3],
    /// Moment about `centre_m` at the last state, N·m.
    pub final_moment_nm: [f64; 3],
    /// The largest force magnitude over the frames drawn, N.
    pub force_max_n: f64,
    /// The truncated modes' share of the hands' loads is added back: one support holding every
    /// rigid motion (equilibrium), or the file's influence coefficients for several. False: the
    /// modes' share only (supports that leave a rigid motion free, more than six supports, a
    /// file without coefficients).
    pub corrected: bool,
}

/// A device read that failed and ended the session: every device was sent zero force at that
/// step, and the session stopped.
#[derive(Clone, Debug, serde::Serialize)]
pub struct DeviceFaultReport {
    /// The hand whose device faulted (its index among the session's devices).
    pub hand: usize,
    /// That device's name (its file, or its kind).
    pub device: String,
    /// What went wrong: `disconnected`, `out_of_range`, `timeout` or `hardware`.
    pub fault: crate::device::DeviceFault,
    /// Session time of the failed read, s.
    pub time_s: f64,
    /// Steps completed before it.
    pub step: u64,
}

/// What one hand did over a session.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct HandReport {
    /// The vertex the hand first grabbed or pressed (index among the basis's kept vertices;
    /// null: never in contact).
    pub first_vertex: Option<u32>,
    /// That vertex's deformed position when the contact began, m.
    pub first_vertex_position: Option<[f64; 3]>,
    /// How far the hand was from the vertex when its first grab began, m (null: no grab). The
    /// grab holds the part where it was grabbed: this gap is carried, not pulled.
    pub grip_gap_m: Option<f64>,
    /// Steps in contact (grabbing or pressing).
    pub contact_steps: u64,
    /// Largest elastic displacement of the hand's vertex while in contact, m.
    pub max_displacement_m: f64,
    /// The hand's vertex at the last step in contact (null: never in contact).
    pub last_vertex: Option<u32>,
    /// Its elastic displacement then (part frame), m.
    pub last_displacement_m: [f64; 3],
    /// What the hand feels wrong at that vertex, relative, along its normal (the modes' share
    /// and the mesh's own error; docs/accuracy.md); null where the basis does not state it.
    pub felt_error: Option<f64>,
    /// The largest of the same over the vertices it touched (null: none stated).
    pub felt_error_max: Option<f64>,
}

impl HandReport {
    fn add(&mut self, out: &HandOutput) {
        if !out.contact {
            return;
        }
        if self.first_vertex.is_none() {
            self.first_vertex = Some(out.vertex);
            self.first_vertex_position = Some(out.vertex_position);
        }
        if self.grip_gap_m.is_none() && out.grabbing {
            self.grip_gap_m = Some(out.grip_gap);
        }
        self.contact_steps += 1;
        let u = out.displacement;
        self.max_displacement_m = self
            .max_displacement_m
            .max((u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt());
        self.last_vertex = Some(out.vertex);
        self.last_displacement_m = u;
        self.felt_error = out.felt_error.is_finite().then_some(out.felt_error);
        if let Some(e) = self.felt_error {
            self.felt_error_max = Some(self.felt_error_max.map_or(e, |m| m.max(e)));
        }
    }
}

/// Nanosecond timings streamed into a histogram (3 significant digits, 1 ns to 1 h): memory is
/// fixed whatever the session's length, and recording never allocates.
pub(super) struct Timings(hdrhistogram::Histogram<u64>);

impl Timings {
    pub(super) fn new() -> Result<Timings, super::SessionError> {
        hdrhistogram::Histogram::new_with_bounds(1, 3_600_000_000_000, 3)
            .map(Timings)
            .map_err(|e| super::SessionError::Statistics(e.to_string()))
    }

    pub(super) fn record(&mut self, ns: u64) {
        self.0.saturating_record(ns.max(1));
    }

    pub(super) fn quantile(&self, q: f64) -> u64 {
        if self.0.is_empty() {
            0
        } else {
            self.0.value_at_quantile(q)
        }
    }

    pub(super) fn max(&self) -> u64 {
        if self.0.is_empty() { 0 } else { self.0.max() }
    }
}

/// A running maximum of non-negative f64 values one thread writes and others read.
#[derive(Default)]
pub(super) struct AtomicMax(AtomicU64);

impl AtomicMax {
    /// Raises the maximum to `v` if larger (single writer: no compare-and-swap needed).
    pub(super) fn raise(&self, v: f64) {
        if v > self.get() {
            self.0.store(v.to_bits(), Ordering::Relaxed);
        }
    }

    pub(super) fn get(&self) -> f64 {
        f64::from_bits(self.0.load(Ordering::Relaxed))
    }
}

/// The whole part as the drawing thread saw it, read by the haptic thread (the alarm) and at
/// the end (the maxima).
#[derive(Default)]
pub(super) struct PartRecord {
    /// Frames drawn.
    pub frames: AtomicU64,
    /// Largest surface-edge strain.
    pub surface_strain: AtomicMax,
    /// Largest von Mises stress, Pa.
    pub von_mises: AtomicMax,
    /// Largest principal stress (Pa) and principal strain.
    pub principal_stress: AtomicMax,
    pub principal_strain: AtomicMax,
    /// Set while the whole part's safety factor is below the watch's minimum.
    pub alarm: AtomicBool,
    /// Frames drawn with the alarm set.
    pub alarm_frames: AtomicU64,
    /// Per support of the first space, the largest force magnitude drawn, N.
    pub support_force: Vec<AtomicMax>,
}

/// The haptic thread's own tallies over the hands and the steps.
#[derive(Default)]
pub(super) struct HandTally {
    /// Per hand (made before the loop).
    pub hands: Vec<HandReport>,
    pub peak_force: f64,
    pub clamped: u64,
    pub strain_max: f64,
    pub strain_steps: u64,
    pub von_mises: f64,
    pub stress_steps: u64,
    pub max_energy: f64,
}

impl HandTally {
    /// Counts hand `k`'s output of one step.
    pub(super) fn add(&mut self, k: usize, out: &HandOutput) {
        if let Some(h) = self.hands.get_mut(k) {
            h.add(out);
        }
        let f = out.force;
        self.peak_force = self.peak_force.max((f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt());
        self.clamped += u64::from(out.clamped);
        self.strain_max = self.strain_max.max(out.strain);
        self.strain_steps += u64::from(out.strain_exceeded);
        self.von_mises = self.von_mises.max(out.von_mises);
        self.stress_steps += u64::from(out.stress_exceeded);
    }
}

/// The haptic loop's timings.
pub(super) struct LoopTimings {
    pub step_ns: Timings,
    pub period_error_ns: Timings,
    pub compute_ns: Timings,
    pub missed: u64,
    pub long_periods: u64,
    pub steps: u64,
    pub wall_s: f64,
}

impl LoopTimings {
    pub(super) fn new() -> Result<LoopTimings, super::SessionError> {
        Ok(LoopTimings {
            step_ns: Timings::new()?,
            period_error_ns: Timings::new()?,
            compute_ns: Timings::new()?,
            missed: 0,
            long_periods: 0,
            steps: 0,
            wall_s: 0.0,
        })
    }
}

/// What the haptic side of a session hands to [`SessionStats::from_parts`].
pub(super) struct HapticSide<'a> {
    pub timings: &'a LoopTimings,
    pub tally: &'a HandTally,
    pub switcher: &'a crate::switching::Switcher,
    pub final_forces: Vec<[f64; 3]>,
    pub device_fault: Option<DeviceFaultReport>,
    pub realtime: Option<crate::realtime::Realtime>,
}

/// What the drawing side hands over: its record, its wall time, and what the part can show.
pub(super) struct DrawingSide<'a> {
    pub part: &'a PartRecord,
    pub wall_s: f64,
    /// Some space has modal stress.
    pub has_stress: bool,
    /// The part's yield strength, Pa, when known.
    pub yield_strength: Option<f64>,
    /// The part's elastic constants are known (principal strain from stress).
    pub elastic: bool,
    /// Per support: its centre and its force and moment at the last state.
    pub final_reactions: Vec<([f64; 3], [f64; 6])>,
    /// The reactions carry the truncated modes' share of the hands' loads.
    pub reactions_corrected: bool,
}

impl SessionStats {
    pub(super) fn from_parts(h: HapticSide, d: DrawingSide) -> SessionStats {
        let t = h.timings;
        let s = h.switcher;
        let updates = d.part.frames.load(Ordering::Relaxed);
        let von_mises = d.part.von_mises.get();
        let stress = |v: f64| d.has_stress.then_some(v);
        SessionStats {
            steps: t.steps,
            achieved_rate_hz: t.steps as f64 / t.wall_s,
            step_ns_median: t.step_ns.quantile(0.5),
            step_ns_p99: t.step_ns.quantile(0.99),
            step_ns_max: t.step_ns.max(),
            haptic_compute_ns_median: t.compute_ns.quantile(0.5),
            period_error_us_p999: t.period_error_ns.quantile(0.999) as f64 / 1e3,
            period_error_us_max: t.period_error_ns.max() as f64 / 1e3,
            missed_deadlines: t.missed,
            periods_over_1_1_ms: t.long_periods,
            visual_updates: updates,
            visual_rate_hz: updates as f64 / d.wall_s.max(1e-9),
            peak_force_n: h.tally.peak_force,
            clamped_steps: h.tally.clamped,
            max_energy_j: h.tally.max_energy,
            final_energy_j: s.sim(s.active()).energy(),
            quarantined: s.sims().iter().map(|sim| sim.quarantined).sum(),
            spaces: s.sims().len(),
            switches: s.switches,
            switch_us_max: s.max_switch_ns as f64 / 1e3,
            strain_max: h.tally.strain_max,
            strain_exceeded_steps: h.tally.strain_steps,
            strain_max_surface: d.part.surface_strain.get(),
            von_mises_max: stress(von_mises),
            von_mises_max_hands: stress(h.tally.von_mises),
            safety_factor_min: d
                .yield_strength
                .filter(|_| d.has_stress)
                .map(|y| y / von_mises.max(f64::MIN_POSITIVE)),
            stress_exceeded_steps: h.tally.stress_steps,
            safety_factor_below_min_frames: d.part.alarm_frames.load(Ordering::Relaxed),
            principal_stress_max: stress(d.part.principal_stress.get()),
            principal_strain_max: (d.has_stress && d.elastic).then(|| d.part.principal_strain.get()),
            final_forces_n: h.final_forces,
            hands: h.tally.hands.clone(),
            device_fault: h.device_fault,
            realtime: h.realtime,
            support_reactions: d
                .final_reactions
                .iter()
                .zip(&d.part.support_force)
                .enumerate()
                .map(|(support, ((centre, r), max))| SupportReport {
                    support,
                    centre_m: *centre,
                    final_force_n: [r[0], r[1], r[2]],
                    final_moment_nm: [r[3], r[4], r[5]],
                    force_max_n: max.get(),
                    corrected: d.reactions_corrected,
                })
                .collect(),
        }
    }
}
