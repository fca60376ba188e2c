//! `[mesh] target_error`: refine the whole space until every kept mode's estimated error is
//! below the target. Each mesh is estimated the same way as a basis without a target (the
//! recovery estimate, and where it is not vouched for two meshes 1.5× and 2.25× coarser than
//! itself). Each next mesh is the previous one's size times a factor predicted from each mode's
//! rate: the rate at which its estimate fell over the last step, or, on the first mesh and for a
//! mode whose estimate did not fall by more than its own noise ([`NOISE`]), the estimate's own
//! rate, at most a re-entrant edge's ([`GUESSED_RATE`]) where none was measured; such a mode asks
//! for at most twice the unknowns ([`UNMEASURED_GROWTH`]), so an estimate
//! that rises a little is not read as a stalled error worth a 4–8× jump. The earlier steps of
//! the refinement would be free coarser levels for Richardson, but they are too far apart and
//! too coarse: on the ribplate, steps of 12k, 59k and 684k unknowns gave a measured rate near 1
//! and an estimate of 5.5 % where the error was below 0.8 %.

use super::{ErrorEstimate, Solved, max_rate};
use crate::mesh::field::SizeField;
use crate::mesh::remembered;
use crate::modes::SolverChoice;
use crate::scene::{Refinement, Scene, Voi};
use anyhow::Result;

/// One mesh of the refinement.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Step {
    /// Element size, m (the largest, with a size field).
    pub size: f64,
    /// The smallest element size asked for (= `size` on a uniform mesh), m.
    pub smallest_size: f64,
    /// Mesh nodes.
    pub nodes: usize,
    /// Free unknowns.
    pub dofs: usize,
    /// Seconds to mesh, assemble and solve it (its estimate not included).
    pub seconds: f64,
    /// Of those, what every mesh pays whatever its size: starting gmsh and reading the
    /// geometry (0 for a mesh from the cache).
    pub fixed_s: f64,
    /// Its kept modes' frequencies.
    pub frequencies_hz: Vec<f64>,
    /// The largest estimated relative error of a kept mode (NaN without an estimate).
    pub max_estimated_error: f64,
    /// The mesh an earlier refinement of this geometry chose, started from
    /// ([`crate::mesh::remembered`]; absent when false).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub remembered: bool,
    /// What the step before forecast for this one when it chose it (none for the first): set
    /// beside `dofs`, `seconds` and `peak_rss_bytes` it says how good the forecasts that stop a
    /// refinement are.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub forecast: Option<Forecast>,
    /// This process's peak resident memory once the step was solved, bytes.
    pub peak_rss_bytes: u64,
}

/// A refinement step's forecast of the next mesh.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct Forecast {
    /// Free unknowns.
    pub dofs: f64,
    /// Seconds to mesh, assemble and solve it.
    pub seconds: f64,
    /// The process's peak memory with it, bytes.
    pub peak_bytes: f64,
}

/// The last mesh of a refinement, and how it got there.
pub struct Refined {
    /// The last mesh, solved (its modes cut to the kept count).
    pub last: Solved,
    /// Its error estimate.
    pub estimate: Option<ErrorEstimate>,
    /// Every mesh tried, coarsest first.
    pub steps: Vec<Step>,
    /// Whether every kept mode's estimate reached the target.
    pub reached: bool,
    /// Seconds spent on all but the last mesh (and on estimating the last).
    pub overhead_s: f64,
}

/// Refinement stops after this many meshes.
pub const MAX_STEPS: usize = 6;

/// A mode's estimate must fall by more than this factor over a step for the fall to be read as
/// its rate: a mode's recovery effectivity moves by 10–20 % between meshes of a sequence (the
/// cantilever's bending modes: 0.63–0.99 at 11.7k unknowns, 0.77–0.95 at 29.3k), and an L-bracket
/// whose estimate rose 1.27 → 1.32 % while its true error fell 1.20 → 0.77 % was refined 4× on
/// that rise (issue 42).
pub const NOISE: f64 = 1.2;

/// The most a mode whose rate was not measured over the last step (its estimate did not fall by
/// more than [`NOISE`]) lets the next mesh grow, in unknowns.
pub const UNMEASURED_GROWTH: f64 = 2.0;

/// Each mode's estimate on one mesh of the refinement, for the rate over the next step.
struct Seen {
    /// Free unknowns.
    dofs: usize,
    /// Per kept mode, its estimate (NaN: none).
    errors: Vec<f64>,
}

/// Refines `voi`'s space of `scene` (the global one with None) until every kept mode's estimated
/// frequency error is below `target`, or the next mesh would exceed `scene.mesh.max_dofs`.
pub fn refine(scene: &Scene, voi: Option<&Voi>, choice: SolverChoice, target: f64) -> Result<Refined> {
    // The forecasts scale this refinement's own peak: not one left by earlier work of the
    // process (the page's compute process solves the instant basis on the previous, often much
    // finer, mesh first; a Python session keeps its earlier computes' peak), which forecast
    // 32.6 GB for 9.8e4 unknowns and stopped the corpus block at 12 % for a 5 % target.
    // Free pages malloc kept from that work go back first, so that what stays resident (the
    // base the forecasts add to) is what is still in use.
    crate::memory::release_free_memory();
    crate::memory::reset_peak();
    let base = crate::memory::rss_bytes();
    let kept = scene.modes.count;
    let memory = remembered::Keys::of(scene, voi);
    let mut scene = scene.clone();
    let start = std::time::Instant::now();
    let voi_ratio = voi.map(|v| v.size / scene.mesh.size.max(f64::MIN_POSITIVE));
    let scaled_voi = |size: f64| {
        voi.cloned().map(|mut v| {
            if let Some(k) = voi_ratio.filter(|k| k.is_finite()) {
                v.size = k * size;
            }
            v
        })
    };
    // The size field of local refinement, once there is one (it then replaces the sizes).
    let mut field: Option<SizeField> = None;
    let (mut current, from_memory) = match first_mesh(&scene, memory.as_ref(), &scaled_voi, kept, choice, target) {
        Some((s, f)) => {
            field = f;
            (s, true)
        }
        None => (Solved::at(&scene, voi, None, 1.0, kept, choice, false)?, false),
    };
    // The size the mesher picked when the scene left it open; the VOI's keeps its ratio.
    scene.mesh.size = current.size;
    let remember = |current: &Solved, field: Option<&SizeField>, worst: f64, reached: bool| {
        if let Some(k) = &memory {
            let chosen = remembered::Chosen {
                size: current.size,
                field: field.cloned(),
                dofs: current.d.dofs.free_count(),
                estimated_error: worst,
                reached,
                target: Some(target),
            };
            k.store(&chosen);
        }
    };
    let estimate_of = |scene: &Scene, field: Option<&SizeField>, s: &Solved| {
        let lambda = &s.modes.eigenvalues[..kept.min(s.modes.eigenvalues.len())];
        super::estimate(scene, scaled_voi(s.size).as_ref(), field, &s.view(kept), lambda, choice)
    };
    let mut estimate = estimate_of(&scene, None, &current);
    let mut steps = Vec::new();
    let mut seen: Option<Seen> = None;
    let mut forecast: Option<Forecast> = None;
    loop {
        let worst = estimate
            .as_ref()
            .and_then(|e| super::worst(&e.relative()))
            .map_or(f64::NAN, |w| w.1);
        steps.push(Step {
            size: current.size,
            smallest_size: field.as_ref().map_or(current.size, |f| f.smallest()),
            nodes: current.d.mesh.nodes.len(),
            dofs: current.d.dofs.free_count(),
            seconds: current.seconds,
            fixed_s: current.d.fixed_mesh_s().min(current.seconds),
            frequencies_hz: current.modes.frequencies_hz()[..kept.min(current.modes.eigenvalues.len())].to_vec(),
            max_estimated_error: worst,
            remembered: from_memory && steps.is_empty(),
            forecast: forecast.take(),
            peak_rss_bytes: crate::memory::peak_rss_bytes(),
        });
        tracing::info!(
            size = current.size,
            dofs = current.d.dofs.free_count(),
            worst,
            "refinement step"
        );
        if worst <= target {
            remember(&current, field.as_ref(), worst, true);
            return Ok(finish(current, estimate, steps, true, start));
        }
        let next = Next::plan(
            &scene,
            &current,
            estimate.as_ref(),
            seen.as_ref(),
            (worst, target),
            kept,
            (&steps, base),
        );
        if let Some(why) = next.refused(&scene, &steps, (worst, target)) {
            tracing::warn!("{why}");
            remember(&current, field.as_ref(), worst, false);
            return Ok(finish(current, estimate, steps, false, start));
        }
        // The share of the refinement done: the time spent over that plus the next mesh's
        // forecast (the page showed 0 % for a minute, then jumped). A cancel stops it here.
        let spent = start.elapsed().as_secs_f64();
        crate::progress::stage(
            &next.announce(&steps, (worst, target)),
            REFINEMENT_SHARE * spent / (spent + next.cost.seconds.max(0.0)).max(f64::MIN_POSITIVE),
        )?;
        seen = estimate.as_ref().map(|e| Seen {
            dofs: current.d.dofs.free_count(),
            errors: e.relative(),
        });
        forecast = Some(Forecast {
            dofs: next.unknowns,
            seconds: next.cost.seconds,
            peak_bytes: next.cost.bytes,
        });
        let next_size = next.size;
        match next.local {
            Some(local) => field = Some(local.field),
            None => {
                field = None;
                scene.mesh.size = next_size;
            }
        }
        // The next mesh is larger: this one's factor of K is not held beside it.
        current.modes.release_factor();
        current = Solved::at(
            &scene,
            scaled_voi(next_size).as_ref(),
            field.as_ref(),
            1.0,
            kept,
            choice,
            false,
        )?;
        estimate = estimate_of(&scene, field.as_ref(), &current);
    }
}

/// The `target_error` that accepts a mesh estimated at `worst`: rounded up to three decimals
/// (the advice of a refinement that stops, which the page offers as one click).
fn accepting(worst: f64) -> f64 {
    (1000.0 * worst).ceil() / 1000.0
}

/// The share of a space's progress that meshing, solving and estimating cover, a refinement
/// included; the static correction, stress, loads and writing follow.
pub const REFINEMENT_SHARE: f64 = 0.85;

/// Whether a refinement of `scene`'s global space would start from a remembered mesh (this
/// scenario's, or a good one of its geometry): a caller then has no first mesh to show early.
pub fn starts_remembered(scene: &Scene) -> bool {
    let Some(target) = scene.mesh.target_error else {
        return false;
    };
    remembered::Keys::of(scene, None)
        .and_then(|k| remembered_start(&k, target))
        .is_some_and(|(_, _, starts)| starts)
}

/// The remembered mesh a refinement to `target` finds under `keys`, and whether it starts
/// there: this scenario's always (its rerun gives the same basis; with another target the
/// lookup only offers it when it is not far finer than needed), the geometry's when it is not.
fn remembered_start(keys: &remembered::Keys, target: f64) -> Option<(remembered::Chosen, remembered::Scope, bool)> {
    let (chosen, scope) = keys.lookup(target, |estimate| worth_starting_from(estimate, target))?;
    let starts = scope == remembered::Scope::Scenario || worth_starting_from(chosen.estimated_error, target);
    Some((chosen, scope, starts))
}

/// How much finer than the target a remembered mesh's estimate may be and still be the start:
/// frequencies of 10-node tets converge as h⁴, so 4× below the target is a size 1.4× finer
/// (2.8× the unknowns) than needed. Finer ones came from a stricter target (a 0.1 % run's
/// 333k unknowns for the page's 5 %, where the first mesh has a few thousand) and would cost
/// far more than the refinement they save.
const FINER_THAN_NEEDED: f64 = 4.0;

/// Whether a remembered mesh estimated at `remembered` is a good start for `target`.
fn worth_starting_from(remembered: f64, target: f64) -> bool {
    remembered * FINER_THAN_NEEDED >= target
}

/// The mesh an earlier refinement of this geometry chose (under `key`), solved, and its size
/// field; None when there is none, when it is far finer than `target` needs, or when it cannot
/// be made (the refinement then starts afresh).
fn first_mesh(
    scene: &Scene,
    keys: Option<&remembered::Keys>,
    scaled_voi: &dyn Fn(f64) -> Option<Voi>,
    kept: usize,
    choice: SolverChoice,
    target: f64,
) -> Option<(Solved, Option<SizeField>)> {
    let (chosen, scope, starts) = remembered_start(keys?, target)?;
    let whose = match scope {
        remembered::Scope::Scenario => "the last run of this scene",
        remembered::Scope::Geometry => "an earlier run of this geometry",
    };
    if !starts {
        crate::progress::say(&format!(
            "not starting from the mesh {whose} refined to ({} unknowns, estimated {:.2} %): \
             far finer than a target of {:.2} % needs",
            chosen.dofs,
            100.0 * chosen.estimated_error,
            100.0 * target
        ));
        return None;
    }
    crate::progress::say(&format!(
        "starting from the mesh {whose} {} (mesh.size {:.3e} m{}, {} unknowns, estimated {:.2} %)",
        if chosen.reached { "refined to" } else { "stopped at" },
        chosen.size,
        if chosen.field.is_some() { ", graded" } else { "" },
        chosen.dofs,
        100.0 * chosen.estimated_error
    ));
    let mut at = scene.clone();
    at.mesh.size = chosen.size;
    match Solved::at(
        &at,
        scaled_voi(chosen.size).as_ref(),
        chosen.field.as_ref(),
        1.0,
        kept,
        choice,
        false,
    ) {
        Ok(s) => Some((s, chosen.field)),
        Err(e) => {
            tracing::warn!("the remembered mesh could not be made ({e:#}): refining from the first size");
            None
        }
    }
}

/// The next mesh of a refinement, before it is made.
struct Next {
    /// A graded mesh's size field, with local refinement.
    local: Option<super::indicator::NextField>,
    /// The uniform size, m.
    size: f64,
    /// Unknowns of the next mesh over this one's.
    growth: f64,
    /// Unknowns expected.
    unknowns: f64,
    cost: NextCost,
}

impl Next {
    /// Each mode asks for the size that would bring it to 70 % of the target at its rate
    /// ([`step_rate`]; at most halving the size, at least 1.2× finer). Without an estimate (a
    /// mesh so coarse that gmsh's coarser ones are no coarser), a fixed step.
    fn plan(
        scene: &Scene,
        current: &Solved,
        estimate: Option<&ErrorEstimate>,
        seen: Option<&Seen>,
        (worst, target): (f64, f64),
        kept: usize,
        (steps, base): (&[Step], u64),
    ) -> Next {
        let local = match (scene.mesh.refinement, estimate) {
            (Refinement::Local, Some(e)) if worst.is_finite() => local_field(scene, current, e, kept, target),
            _ => None,
        };
        let dofs = current.d.dofs.free_count();
        let factor = match estimate {
            Some(e) if worst.is_finite() => e
                .modes
                .iter()
                .enumerate()
                .filter(|(_, m)| m.relative.is_finite() && m.relative > 0.0)
                .map(|(i, m)| {
                    let before = seen.and_then(|s| Some((s.dofs, *s.errors.get(i)?)));
                    mode_factor(
                        m.relative,
                        own_rate(m),
                        before,
                        dofs,
                        target,
                        max_rate(scene.mesh.order),
                    )
                })
                .fold(1.0, f64::min)
                .clamp(1.0 / 2.0, 1.0 / 1.2),
            _ => 1.0 / super::COARSENING,
        };
        // A fixed step instead, for the benchmark that compares this sizing with plain halving
        // (docs/accuracy.md "target_error").
        let factor = std::env::var("VES_REFINE_FACTOR")
            .ok()
            .and_then(|v| v.parse::<f64>().ok())
            .filter(|f| *f > 0.0 && *f < 1.0)
            .unwrap_or(factor);
        let growth = match (&local, steps) {
            (Some(n), _) => n.growth,
            // Before two meshes have measured how the unknowns grow, the first mesh's own tets
            // say which of them the smaller size refines.
            (None, [] | [_]) => super::indicator::uniform_growth(&current.d.mesh, current.size, factor),
            (None, _) => factor.powf(-size_exponent(steps)),
        };
        Next {
            local,
            size: crate::mesh::field::rounded_size(current.size * factor),
            growth,
            unknowns: current.d.dofs.free_count() as f64 * growth,
            cost: NextCost::of(steps, growth, base),
        }
    }

    /// Why the refinement stops here instead, if it does: the memory the next mesh needs is not
    /// there, its unknowns are above `mesh.max_dofs`, or the meshes are many enough.
    fn refused(&self, scene: &Scene, steps: &[Step], (worst, target): (f64, f64)) -> Option<String> {
        let now = steps.last().map_or(0, |s| s.dofs);
        let stopped = format!(
            "mesh.target_error = {target}: stopped at an estimated error of {:.2} % ({now} unknowns)",
            100.0 * worst
        );
        if let Some(short) = self.cost.beyond_memory() {
            // The mesh solved last is the finest and the best there is: its basis is written.
            return Some(format!(
                "{stopped}, the finest mesh that fits, whose basis is written: the next (about {:.2e} unknowns) \
                 would need about {short}; to go further run where that much is free, or set mesh.target_error = \
                 {} to accept this one",
                self.unknowns,
                accepting(worst)
            ));
        }
        let too_many = steps.len() >= MAX_STEPS;
        (self.unknowns > scene.mesh.max_dofs as f64 || too_many).then(|| {
            format!(
                "{stopped}: the next mesh would have about {:.2e} unknowns, above mesh.max_dofs = {}{}; raise \
                 mesh.max_dofs, or set mesh.target_error = {} to accept this one",
                self.unknowns,
                scene.mesh.max_dofs,
                if too_many {
                    format!(" or the limit of {MAX_STEPS} meshes was reached")
                } else {
                    String::new()
                },
                accepting(worst)
            )
        })
    }

    /// The line that announces it.
    fn announce(&self, steps: &[Step], (worst, target): (f64, f64)) -> String {
        format!(
            "mesh {}: estimated error {:.2} % > {:.2} %: next {}, about {:.0} unknowns ({:.1}× these), {}",
            steps.len() + 1,
            100.0 * worst,
            100.0 * target,
            if self.local.is_some() {
                "a graded mesh".to_string()
            } else {
                format!("mesh.size {:.3e} m", self.size)
            },
            self.unknowns,
            self.growth,
            self.cost.text()
        )
    }
}

/// Where a step aims each mode, as a fraction of the target: with the estimate's own rate (the
/// first mesh, or a mode whose estimate did not fall beyond its noise), well below it, since
/// that rate is a guess; with the rate measured over the last step, closer. On the gmsh
/// benchmark part (docs/accuracy.md) a step from 73k unknowns at 1.47 % with the measured rate
/// 1.71 aimed at 0.7 % landed at 0.78 % on 280k unknowns, where 189k had given 0.92 %.
pub const AIM_GUESSED: f64 = 0.7;

/// See [`AIM_GUESSED`].
pub const AIM_MEASURED: f64 = 0.8;

/// The rate a mode's error is guessed to fall at where no rate was measured (no coarser meshes
/// were solved, no earlier step): that of the error near a re-entrant edge (an eigenvalue's
/// error ∝ h^(2·2/3) beside a 270° edge), not the smooth field's 2 the element order credits.
/// Over the first step of the page's refinement (10-node, 5 %) of seven corpus parts the error
/// fell at h^0.75–h^2.03, median h^0.99 (docs/benchmarks.md); guessed at 2, four of the seven
/// landed just above the target (5.08–5.35 %) and paid one more mesh.
pub const GUESSED_RATE: f64 = 4.0 / 3.0;

/// The rate a step takes for a mode when its estimate did not fall measurably over the last
/// step (or there was none): the Richardson rate its coarser meshes measured, else the element
/// order's credited rate, at most [`GUESSED_RATE`].
fn own_rate(m: &super::ModeEstimate) -> f64 {
    match m.measured_rate {
        Some(_) => m.rate,
        None => m.rate.min(GUESSED_RATE),
    }
}

/// The size factor one mode asks of the next mesh: the one that brings its estimate `now` on
/// `dofs` unknowns below `target` ([`AIM_GUESSED`], [`AIM_MEASURED`]) at its rate. The rate is
/// the one its estimate fell at from `before` (unknowns, estimate on the previous mesh) when it
/// fell by more than [`NOISE`] (credited between 1 and `max_rate`, as a Richardson rate); 1 when
/// it rose by more than [`NOISE`]; otherwise `own` (the estimate's rate), and then the step is at
/// most [`UNMEASURED_GROWTH`] in unknowns when there was a previous mesh (the estimate moved
/// within its noise: one small step tells more than a large one). A corpus block with two holes
/// held at both ends (target 5 %) rose 7.0 → 11.0 % from 65k to 250k unknowns: read as noise it
/// went on in 2× steps for minutes; at rate 1 the next mesh is above `max_dofs` and it stops.
fn mode_factor(now: f64, own: f64, before: Option<(usize, f64)>, dofs: usize, target: f64, max_rate: f64) -> f64 {
    let step = before.filter(|&(n, e)| n > 0 && dofs > n && e.is_finite() && e > 0.0);
    let (rate, capped, aim) = match step {
        Some((n, e)) if e > NOISE * now => {
            let h_ratio = (dofs as f64 / n as f64).ln() / 3.0;
            (((e / now).ln() / h_ratio).clamp(1.0, max_rate), false, AIM_MEASURED)
        }
        // Risen beyond the noise: the error is not falling yet (pre-asymptotic, a singular
        // edge): the slowest physical rate, as a Richardson estimate credits a rate below 1.
        Some((_, e)) if now > NOISE * e => (1.0, false, AIM_GUESSED),
        Some(_) => (own, true, AIM_GUESSED),
        None => (own, false, AIM_GUESSED),
    };
    let goal = aim * target;
    let f = (goal / now).powf(1.0 / rate);
    if capped {
        f.max(UNMEASURED_GROWTH.powf(-1.0 / 3.0))
    } else {
        f
    }
}

/// How the unknowns grow as the element size shrinks, unknowns ∝ size^−p: p measured from the
/// last two uniform meshes plus a margin of 0.25, within [1, 3]; 3 (a volume filled) before
/// there are two. A part's first meshes are ruled by its surface and thin walls: on the
/// crankshaft halving the size gave 2.4× the unknowns, not 8× (p = 1.3, then 1.9 and 2.0), and a
/// cube law overstated the next mesh's unknowns, time and memory 1.3–7× (bench/forecast_vs_actual.py).
fn size_exponent(steps: &[Step]) -> f64 {
    match steps {
        [.., p, l] if l.size < p.size && l.dofs > p.dofs && p.dofs > 0 => {
            ((l.dofs as f64 / p.dofs as f64).ln() / (p.size / l.size).ln() + 0.25).clamp(1.0, 3.0)
        }
        _ => 3.0,
    }
}

/// What the next mesh of a refinement should cost, from the meshes made so far.
struct NextCost {
    /// Seconds, from the last mesh's at the measured growth of time with unknowns.
    seconds: f64,
    /// Peak memory, bytes: what this process held when the refinement began, plus what the
    /// refinement's peak added to it times the growth in unknowns.
    bytes: f64,
}

impl NextCost {
    /// Time beyond a mesh's fixed cost (starting gmsh, reading the geometry: the same for
    /// every mesh) grows as unknowns^a with a measured from the last two meshes (between 1 and
    /// 2), or as the unknowns with one mesh (a first mesh's time is mostly meshing and
    /// assembling, which grow so; the factorisation's faster growth shows later, where it is
    /// measured: with 1.3 the first forecasts of the page's refinement on seven corpus parts
    /// were 0.48–1.89× the time taken, with 1, from the same runs, 0.46–1.16×); memory beyond
    /// `base` (resident at the refinement's start: the page's compute process holds its previous
    /// basis) as the unknowns. Scaled whole, the first mesh's fixed cost (most of a small mesh's
    /// time) made the first forecast 1.4–4× the time taken (docs/accuracy.md).
    fn of(steps: &[Step], growth: f64, base: u64) -> NextCost {
        let grows = |s: &Step| (s.seconds - s.fixed_s).max(0.0);
        let (fixed, last_s) = steps.last().map_or((0.0, 0.0), |s| (s.fixed_s, grows(s)));
        let a = match steps {
            [.., p, l] if p.dofs > 0 && l.dofs > p.dofs && grows(p) > 0.0 && grows(l) > 0.0 => {
                ((grows(l) / grows(p)).ln() / (l.dofs as f64 / p.dofs as f64).ln()).clamp(1.0, 2.0)
            }
            _ => 1.0,
        };
        NextCost {
            seconds: fixed + last_s * growth.powf(a),
            bytes: base as f64 + crate::memory::peak_rss_bytes().saturating_sub(base) as f64 * growth,
        }
    }

    fn text(&self) -> String {
        format!("about {:.0} s and {:.1} GB", self.seconds, self.bytes / 1e9)
    }

    /// What the next mesh would need beyond the memory available, if it would.
    fn beyond_memory(&self) -> Option<String> {
        let free = crate::memory::available_bytes()? as f64 + crate::memory::rss_bytes() as f64;
        (self.bytes > free).then(|| format!("{:.1} GB, {:.1} GB available", self.bytes / 1e9, free / 1e9))
    }
}

/// The size field of the next mesh from the indicator of `current`'s kept modes, aiming each
/// mode at 70 % of the target.
fn local_field(
    scene: &Scene,
    current: &Solved,
    estimate: &ErrorEstimate,
    kept: usize,
    target: f64,
) -> Option<super::indicator::NextField> {
    let d = &current.d;
    let r = kept.min(current.modes.eigenvalues.len()).min(estimate.modes.len());
    let nf = d.dofs.free_count();
    let u = crate::fem::stress::Fields::from_free(&d.dofs, &current.modes.vectors[..r * nf], r);
    let lame = crate::fem::element::Lame::of(&scene.material);
    let shares = super::indicator::shares(&d.mesh, &lame, &u);
    let errors: Vec<f64> = estimate.modes[..r].iter().map(|m| m.relative).collect();
    let rates: Vec<f64> = estimate.modes[..r].iter().map(|m| m.rate).collect();
    let next = super::indicator::next_field(&d.mesh, &shares, &errors, &rates, 0.7 * target)?;
    tracing::info!(
        growth = next.growth,
        smallest = next.field.smallest(),
        largest = next.field.largest(),
        "local refinement: next size field"
    );
    Some(next)
}

fn finish(
    mut last: Solved,
    estimate: Option<ErrorEstimate>,
    steps: Vec<Step>,
    reached: bool,
    start: std::time::Instant,
) -> Refined {
    let kept = steps.last().map_or(0, |s| s.frequencies_hz.len());
    last.modes.truncate(kept);
    let overhead_s = (start.elapsed().as_secs_f64() - last.seconds).max(0.0);
    Refined {
        last,
        estimate,
        steps,
        reached,
        overhead_s,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A remembered mesh starts a refinement unless it is far finer than the target needs: the
    /// page's 5 % after a 0.11 % run (333k unknowns) starts afresh; a 2 % mesh for 5 % and a
    /// 1.3 % one for 5 % are kept (4× at most), a coarser one always.
    #[test]
    fn a_remembered_mesh_far_finer_than_the_target_needs_is_not_the_start() {
        assert!(!worth_starting_from(0.0011, 0.05));
        assert!(worth_starting_from(0.02, 0.05));
        assert!(worth_starting_from(0.0125, 0.05));
        assert!(!worth_starting_from(0.0124, 0.05));
        assert!(worth_starting_from(0.08, 0.05));
    }

    fn growth(factor: f64) -> f64 {
        factor.powi(-3)
    }

    /// The unknowns' growth with the size: the cube law before two meshes, then what the last two
    /// measured (the crankshaft's 4.2 → 2.1 mm gave 7671 → 18456 unknowns) plus 0.25.
    #[test]
    fn the_size_exponent_is_measured_from_the_last_two_meshes() {
        let step = |size: f64, dofs: usize| Step {
            size,
            smallest_size: size,
            nodes: 0,
            dofs,
            seconds: 1.0,
            fixed_s: 0.0,
            frequencies_hz: Vec::new(),
            max_estimated_error: 0.1,
            remembered: false,
            forecast: None,
            peak_rss_bytes: 0,
        };
        assert_eq!(size_exponent(&[step(4.2e-3, 7671)]), 3.0);
        let p = size_exponent(&[step(4.2e-3, 7671), step(2.1e-3, 18456)]);
        assert!((p - (18456.0f64 / 7671.0).log2() - 0.25).abs() < 1e-12, "{p}");
        // Within [1, 3] whatever the meshes did.
        assert_eq!(size_exponent(&[step(2e-3, 100), step(1e-3, 100_000)]), 3.0);
        assert_eq!(size_exponent(&[step(2e-3, 1000), step(1e-3, 1001)]), 1.0);
    }

    /// Where no rate was measured a step guesses a re-entrant edge's 4/3, never above the
    /// element order's credited rate; a rate the coarser meshes measured stands.
    #[test]
    fn a_rate_not_measured_is_guessed_as_a_re_entrant_edges() {
        let mode = |measured_rate: Option<f64>, rate: f64| super::super::ModeEstimate {
            relative: 0.07,
            measured_rate,
            rate,
            reliable: true,
            richardson: None,
            richardson_reliable: false,
            recovery: Some(0.07),
            rule: super::super::Rule::Recovery,
        };
        // 10-node tets credit 2; unmeasured, the step takes 4/3.
        assert_eq!(own_rate(&mode(None, 2.0)), GUESSED_RATE);
        // A rate the coarser meshes measured is the mode's own.
        assert_eq!(own_rate(&mode(Some(1.9), 1.9)), 1.9);
        // 4-node tets credit 1: never raised.
        assert_eq!(own_rate(&mode(None, 1.0)), 1.0);
        // 7.3 % towards 3.5 %: h × 0.58 instead of h × 0.69 (the flange's first step landed at
        // 5.08 % with the latter).
        let f = mode_factor(0.073, GUESSED_RATE, None, 21_879, 0.05, 2.0);
        assert!((f - (0.035f64 / 0.073).powf(0.75)).abs() < 1e-12, "{f}");
    }

    /// The first mesh steps at the estimate's own rate; later ones at the rate the estimate fell
    /// at over the last step (credited between 1 and 2); a mode whose estimate did not fall by
    /// more than NOISE asks for at most twice the unknowns.
    #[test]
    fn steps_follow_the_measured_fall_and_a_rise_in_the_noise_is_a_small_step() {
        // First mesh: 5 % at rate 2 towards 0.7 % asks (0.14)^(1/2).
        let f = mode_factor(0.05, 2.0, None, 2_000, 0.01, 2.0);
        assert!((f - 0.14f64.sqrt()).abs() < 1e-12, "{f}");
        // Halving h (8× the unknowns) divided the estimate by 4: rate 2, and 1 % → 0.25 % (the
        // aim with a measured rate) asks for another halving.
        let target = 0.0025 / AIM_MEASURED;
        let f = mode_factor(0.01, 1.0, Some((1_000, 0.04)), 8_000, target, 2.0);
        assert!((f - 0.5).abs() < 1e-12, "{f}");
        // Divided by 2 only: rate 1, the same goal asks for h / 4.
        let f = mode_factor(0.01, 2.0, Some((1_000, 0.02)), 8_000, target, 2.0);
        assert!((f - 0.25).abs() < 1e-12, "{f}");
        // A fall faster than rate 2 (pre-asymptotic) is credited as 2.
        let f = mode_factor(0.01, 2.0, Some((1_000, 0.2)), 8_000, target, 2.0);
        assert!((f - 0.5).abs() < 1e-12, "{f}");
        // The L-bracket of issue 42: 1.27 % at 77k, 1.32 % at 170k, target 1 %; with the slowest
        // rate 1.32 % → 0.7 % asked 6.7× the unknowns. Now at most 2×.
        let f = mode_factor(0.0132, 1.0, Some((77_000, 0.0127)), 170_000, 0.01, 2.0);
        assert!(growth(f) <= UNMEASURED_GROWTH * (1.0 + 1e-9), "{}", growth(f));
        assert!(growth(f) > 1.9, "{}", growth(f));
        // A fall within the noise (1.15×) is not read as a rate either.
        let f = mode_factor(0.01, 1.0, Some((1_000, 0.0115)), 2_000, 0.007, 2.0);
        assert!(growth(f) <= UNMEASURED_GROWTH * (1.0 + 1e-9));
        // Risen beyond the noise (7.0 → 11.0 %): rate 1, no cap, as large a step as the clamp lets.
        let f = mode_factor(0.11, 2.0, Some((65_000, 0.07)), 250_000, 0.05, 2.0);
        assert!((f - 0.7 * 0.05 / 0.11).abs() < 1e-12, "{f}");
        // A mode already below its goal asks for no refinement.
        assert!(mode_factor(0.001, 2.0, Some((1_000, 0.0011)), 2_000, 0.007, 2.0) >= 1.0);
    }
}
