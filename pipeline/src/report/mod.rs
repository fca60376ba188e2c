//! `ves report`: what a basis costs against how wrong it is, measured for a sweep of meshes
//! (element order × size) and mode counts, so a user can pick the cheapest basis that is
//! accurate enough.
//!
//! For every mesh: the exact point-load response at the probes (a sparse solve of K u = F), the
//! surface static-correction blocks, and a full-order Newmark integration of a step load. For
//! every mode count on it: offline time, file size, bytes the runtime loads, haptic step and
//! full-field times (measured on the written file through the runtime), frequency error against
//! the finest mesh, and the probe errors with and without static correction.

mod newmark;
mod render;

use crate::compliance::Compliance;
use crate::linsolve::factor_stiffness;
use crate::loads::patch::{Patch, Patches, Surface};
use crate::modes::{SolverChoice, solve};
use crate::problem::{Discretized, discretize};
use crate::scene::{Probe, Scene};
use crate::store;
use anyhow::{Context, Result, bail};
use nalgebra::{Matrix3, Vector3};
pub use newmark::{FullSystem, ModalSystem, Stepping, System, integrate_step_load};
pub use render::significant;
use serde::Serialize;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

/// What to sweep.
#[derive(Clone, Debug)]
pub struct ReportOptions {
    /// Mode counts.
    pub modes: Vec<usize>,
    /// Element sizes, m.
    pub sizes: Vec<f64>,
    /// Element orders (1, 2).
    pub orders: Vec<u8>,
    /// Length of the step-load response, s.
    pub duration: f64,
    /// Where `sizes` came from, in words (the report says it).
    pub sizes_from: String,
}

impl ReportOptions {
    /// The defaults for a scene: 5…200 modes, orders 1 and 2, and `sizes` when given, else
    /// [`default_sizes`] (which meshes the part once when the scene leaves the size to
    /// `target_error`).
    pub fn defaults(scene: &Scene, sizes: Option<Vec<f64>>) -> Result<ReportOptions> {
        let (sizes, sizes_from) = match sizes {
            Some(s) => (s, "given with --sizes".to_string()),
            None => default_sizes(scene)?,
        };
        Ok(ReportOptions {
            modes: vec![5, 10, 20, 30, 50, 100, 200],
            sizes,
            orders: vec![1, 2],
            duration: 0.5,
            sizes_from,
        })
    }
}

/// The sizes swept when `--sizes` is not given, and why, in one line.
///
/// A scene with `mesh.size` and no `target_error`: 2, 1.5 and 1 × that size. A scene with
/// `target_error`: the sizes its refinement works with, from the size it starts at (the scene's
/// `mesh.size`, or when it has none the size the mesher picks for it, found by meshing the part
/// once exactly as `ves precompute`'s first mesh is made) down to half of it (a refinement step at
/// most halves the size): 1, 1/1.5 and 1/2 × the starting size.
pub fn default_sizes(scene: &Scene) -> Result<(Vec<f64>, String)> {
    let h = scene.mesh.size;
    if scene.mesh.target_error.is_none() {
        return Ok((
            vec![2.0 * h, 1.5 * h, h],
            format!("2, 1.5 and 1 × the scene's mesh.size = {} m", render::size(h)),
        ));
    }
    let (start, whence) = if h > 0.0 {
        (h, format!("the scene's mesh.size = {} m", render::size(h)))
    } else {
        let mut first = scene.clone();
        first.mesh.order = 1;
        let (_, meshing) = crate::mesh::generate(&first, None).with_context(|| {
            format!(
                "{}: finding the size mesh.target_error's refinement starts from (to choose others, give --sizes in metres)",
                scene.path.display()
            )
        })?;
        (
            meshing.size,
            format!(
                "{} m = 1/{} of the part's largest extent, the first mesh `ves precompute` makes when mesh.size is left out",
                render::significant(meshing.size, 4),
                crate::mesh::AUTO_SIZE_FRACTION
            ),
        )
    };
    let sizes = vec![start, start / 1.5, start / 2.0];
    let why = format!(
        "mesh.target_error scene: sweeping sizes {} m: {whence} (where its refinement starts) and two finer \
         steps, 1/1.5 and 1/2 of it (a refinement step at most halves the size); give --sizes to sweep others",
        sizes
            .iter()
            .map(|&x| render::significant(x, 4))
            .collect::<Vec<_>>()
            .join(", "),
    );
    Ok((sizes, why))
}

/// Relative errors at or below this are reported as exact: zero up to rounding (the static
/// correction on its own mesh is K⁻¹F by construction; ~1e-15 is its rounding).
pub const EXACT_BELOW: f64 = 1e-12;

/// A probe is flagged when, on some mesh, it snapped farther than this fraction of that mesh's
/// element size from the point asked, or when the vertices it snapped to on two meshes are
/// farther apart than this fraction of the coarsest element size.
pub const SNAP_LIMIT: f64 = 0.5;

/// Timings are tied when their p25–p75 ranges over the timed batches overlap (see
/// [`Point::haptic_step_tier`]).
pub const TIE_RULE: &str =
    "a point's tier is the fastest tier whose fastest point's p25–p75 over the timed batches overlaps its own";

/// A probe as applied on one mesh.
#[derive(Clone, Debug, Serialize)]
pub struct ProbeOnMesh {
    /// The node carrying most of the probe's contact patch (the patch's vertex at radius 0).
    pub vertex: usize,
    /// Distance from the asked point to the patch's centre (the nearest surface point), m.
    pub snap_distance: f64,
    /// The patch's centre, m.
    pub position: [f64; 3],
    /// |u| of the full solve, m.
    pub exact_displacement: f64,
}

/// One (mesh, mode count) point of the sweep.
#[derive(Clone, Debug, Serialize)]
pub struct Point {
    /// Elastic modes.
    pub modes: usize,
    /// Mesh + assembly + factorisation + eigen-solve, s.
    pub offline_s: f64,
    /// The same plus the static-correction blocks, s (null for free bodies).
    pub offline_with_correction_s: Option<f64>,
    /// Size of the basis file (with compliance blocks when computed), bytes.
    pub file_bytes: u64,
    /// Bytes the runtime holds after loading it (all vertices).
    pub bytes_loaded: usize,
    /// Median haptic step, ns.
    pub haptic_step_ns: f64,
    /// 25th percentile of the timed batches' step times, ns (the noise band's low end).
    pub haptic_step_ns_p25: f64,
    /// 75th percentile of the timed batches' step times, ns.
    pub haptic_step_ns_p75: f64,
    /// 1 for the fastest tier: points whose p25–p75 band overlaps that of the tier's fastest
    /// point share its tier (their difference is within the timing noise, a tie).
    pub haptic_step_tier: usize,
    /// Median full-field update (all vertices), ms.
    pub full_field_ms: f64,
    /// 25th percentile of the timed full-field updates, ms.
    pub full_field_ms_p25: f64,
    /// 75th percentile of the timed full-field updates, ms.
    pub full_field_ms_p75: f64,
    /// Tier of `full_field_ms`, as `haptic_step_tier`.
    pub full_field_tier: usize,
    /// Largest relative frequency error over the first `frequencies_compared` modes against
    /// the finest mesh (null on the finest mesh itself, which is the reference).
    pub frequency_error: Option<f64>,
    /// How many modes that compares.
    pub frequencies_compared: usize,
    /// Per probe: |u_r − u| / |u| at the probe under its static force, modes only.
    pub static_error: Vec<f64>,
    /// The same with the static correction.
    pub static_error_corrected: Vec<f64>,
    /// Per probe: |u_r − u*| / |u*| against the *finest* mesh's full solve u* (truncation and
    /// discretisation together: what a user feels against the converged answer; empty on the
    /// finest mesh itself).
    pub static_error_total: Vec<f64>,
    /// The same with the static correction (the discretisation error alone).
    pub static_error_total_corrected: Vec<f64>,
    /// Per probe: max over time of |u_r(t) − u(t)| / max |u(t)| under the step load.
    pub dynamic_error: Vec<f64>,
    /// The same with the static correction of the truncated modes.
    pub dynamic_error_corrected: Vec<f64>,
    /// Per probe: RMS over time of |u_r(t) − u(t)| / RMS of |u(t)| (less driven by the first
    /// instants after the step, where the left-out stiff modes lag by ~β).
    pub dynamic_error_rms: Vec<f64>,
    /// The same with the static correction.
    pub dynamic_error_rms_corrected: Vec<f64>,
}

/// One mesh of the sweep.
#[derive(Clone, Debug, Serialize)]
pub struct MeshReport {
    /// 1 or 2.
    pub order: u8,
    /// Element size asked, m.
    pub size: f64,
    /// Nodes.
    pub nodes: usize,
    /// Corner vertices.
    pub vertices: usize,
    /// Tets.
    pub tets: usize,
    /// Free unknowns.
    pub dofs: usize,
    /// Meshing, s.
    pub mesh_s: f64,
    /// Assembly, s.
    pub assemble_s: f64,
    /// Surface static-correction blocks, s (null for free bodies).
    pub static_correction_s: Option<f64>,
    /// The full-order step response (the dynamic reference), s.
    pub full_dynamic_s: Option<f64>,
    /// Lowest frequencies computed on this mesh (for the largest mode count), Hz.
    pub frequencies_hz: Vec<f64>,
    /// Probes as applied on this mesh.
    pub probes: Vec<ProbeOnMesh>,
    /// VES's own estimate of the relative frequency error of the first modes (the one a basis
    /// of this mesh would carry; null when no coarser mesh could be solved).
    pub estimated_relative_error: Option<Vec<f64>>,
    /// The same modes' measured relative error against the reference mesh (empty on the
    /// reference itself): the check of the estimate.
    pub measured_relative_error: Vec<f64>,
    /// The sweep over mode counts.
    pub points: Vec<Point>,
}

/// How many of each mesh's lowest modes the error estimate is checked on.
pub const ESTIMATE_MODES: usize = 10;

/// Whether a probe lands on comparable places on every mesh.
#[derive(Clone, Debug, Serialize)]
pub struct ProbeCheck {
    /// The largest, over the meshes, of its snap distance over that mesh's element size.
    pub worst_snap_over_size: f64,
    /// The largest distance between the vertices it snapped to on two meshes, m.
    pub spread_m: f64,
    /// The coarsest element size of the sweep, m (what `spread_m` is compared with).
    pub coarsest_size: f64,
    /// Its errors against the finest mesh compare different places: left out of the "vs finest"
    /// worst values of the table and the plot (its own values stay in each point's arrays).
    pub flagged: bool,
    /// Why it is flagged (empty when it is not).
    pub why: String,
}

/// The whole report (`report.json`).
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// Scene name.
    pub scene: String,
    /// Scene file.
    pub scene_file: String,
    /// Probes (asked, or the default one).
    pub probes: Vec<Probe>,
    /// Whether the probes were the scene's own.
    pub probes_from_scene: bool,
    /// Per probe: how far apart its snapped vertices are (empty for a free body).
    pub probe_checks: Vec<ProbeCheck>,
    /// The rule that flags a probe, in words.
    pub probe_flag_rule: String,
    /// Element sizes swept, m, and where they came from.
    pub sizes: Vec<f64>,
    /// Where `sizes` came from, in words.
    pub sizes_from: String,
    /// Relative errors at or below this are reported as exact ([`EXACT_BELOW`]).
    pub exact_below: f64,
    /// When two timings are tied, in words.
    pub timing_tie_rule: String,
    /// Step-load length, s.
    pub duration_s: f64,
    /// Time step of both integrations, s.
    pub dt_s: f64,
    /// Index in `meshes` of the frequency reference (finest size, highest order).
    pub reference_mesh: usize,
    /// Meshes, in sweep order.
    pub meshes: Vec<MeshReport>,
    /// Free body (no static or dynamic errors: K is singular).
    pub free_body: bool,
    /// Wall time of the whole report, s.
    pub total_s: f64,
}

/// Runs the sweep and writes `report.json`, `report.md` and the plots into `dir`.
pub fn run(scene: &Scene, opts: &ReportOptions, dir: &Path) -> Result<Report> {
    let start = Instant::now();
    check_options(opts)?;
    check_plotting()?;
    if dir.exists() && !dir.is_dir() {
        bail!("{}: is a file; give a directory for the report with -o", dir.display());
    }
    std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create the report directory", dir.display()))?;
    let mut modes = opts.modes.clone();
    modes.sort_unstable();
    modes.dedup();
    let mut meshes_asked: Vec<(u8, f64)> = Vec::new();
    for &o in &opts.orders {
        for &h in &opts.sizes {
            meshes_asked.push((o, h));
        }
    }
    // The reference: the finest size at the highest order, computed first (its frequencies
    // and time step serve every other mesh).
    let reference = (0..meshes_asked.len())
        .min_by(|&a, &b| {
            let (oa, ha) = meshes_asked[a];
            let (ob, hb) = meshes_asked[b];
            ha.total_cmp(&hb).then(ob.cmp(&oa))
        })
        .unwrap_or(0);
    let bar = crate::progress::count((meshes_asked.len() * modes.len()) as u64, "bases");
    let tmp = dir.join(".report-basis.h5");
    let mut ctx = Sweep {
        scene,
        modes: &modes,
        duration: opts.duration,
        tmp: &tmp,
        bar: &*bar,
        reference_frequencies: Vec::new(),
        reference_statics: Vec::new(),
        dt: 0.0,
        probes: Vec::new(),
    };
    let mut meshes = vec![None; meshes_asked.len()];
    let order: Vec<usize> = std::iter::once(reference)
        .chain((0..meshes_asked.len()).filter(|&i| i != reference))
        .collect();
    for i in order {
        let (o, h) = meshes_asked[i];
        let r = ctx.mesh(o, h).with_context(|| format!("mesh order {o}, size {h} m"))?;
        meshes[i] = Some(r);
    }
    let _ = std::fs::remove_file(&tmp);
    let _ = std::fs::remove_file(store::sidecar_path(&tmp));
    let mut meshes: Vec<MeshReport> = meshes.into_iter().flatten().collect();
    assign_tiers(&mut meshes);
    let report = Report {
        scene: scene.name.clone(),
        scene_file: scene.path.display().to_string(),
        probes_from_scene: !scene.probes.is_empty(),
        probe_checks: check_probes(&meshes, ctx.probes.len()),
        probe_flag_rule: format!(
            "flagged when on some mesh it snapped farther than {SNAP_LIMIT} × that mesh's element size from the point \
             asked, or when its vertices on two meshes are farther apart than {SNAP_LIMIT} × the coarsest element size"
        ),
        sizes: opts.sizes.clone(),
        sizes_from: opts.sizes_from.clone(),
        exact_below: EXACT_BELOW,
        timing_tie_rule: TIE_RULE.to_string(),
        probes: ctx.probes.clone(),
        duration_s: opts.duration,
        dt_s: ctx.dt,
        reference_mesh: reference,
        free_body: meshes.iter().any(|m| m.static_correction_s.is_none()),
        meshes,
        total_s: start.elapsed().as_secs_f64(),
    };
    render::write_all(&report, dir)?;
    Ok(report)
}

/// Flags the probes whose snapped vertices are far from the point asked or from each other.
fn check_probes(meshes: &[MeshReport], count: usize) -> Vec<ProbeCheck> {
    let coarsest = meshes.iter().map(|m| m.size).fold(0.0, f64::max);
    (0..count)
        .filter_map(|k| {
            let on: Vec<(&MeshReport, &ProbeOnMesh)> =
                meshes.iter().filter_map(|m| m.probes.get(k).map(|p| (m, p))).collect();
            if on.is_empty() {
                return None;
            }
            let (worst_mesh, worst_snap_over_size) = on
                .iter()
                .map(|(m, p)| (*m, p.snap_distance / m.size))
                .max_by(|a, b| a.1.total_cmp(&b.1))?;
            let spread_m = on
                .iter()
                .flat_map(|(_, a)| on.iter().map(|(_, b)| dist(a.position, b.position)))
                .fold(0.0, f64::max);
            let mut why = Vec::new();
            if worst_snap_over_size > SNAP_LIMIT {
                why.push(format!(
                    "snapped {:.2} × the element size away on the order-{} {} m mesh",
                    worst_snap_over_size,
                    worst_mesh.order,
                    render::size(worst_mesh.size)
                ));
            }
            if spread_m > SNAP_LIMIT * coarsest {
                why.push(format!(
                    "its vertices on two meshes are {spread_m:.2e} m apart (> {SNAP_LIMIT} × the coarsest size {} m)",
                    render::size(coarsest)
                ));
            }
            Some(ProbeCheck {
                worst_snap_over_size,
                spread_m,
                coarsest_size: coarsest,
                flagged: !why.is_empty(),
                why: why.join("; "),
            })
        })
        .collect()
}

/// The 25th, 50th and 75th percentiles of timing samples (NaN when there are none).
fn percentiles(mut v: Vec<f64>) -> [f64; 3] {
    v.retain(|x| x.is_finite());
    if v.is_empty() {
        return [f64::NAN; 3];
    }
    v.sort_by(f64::total_cmp);
    let at = |q: f64| v[((q * (v.len() - 1) as f64).round() as usize).min(v.len() - 1)];
    [at(0.25), at(0.5), at(0.75)]
}

/// Ranks timings into tiers of ties: in order of median, a point joins the fastest tier whose
/// first (fastest) point's p25–p75 band overlaps its own, else it starts the next tier (1 =
/// fastest). Returns each band's tier, in the order given.
pub fn tiers(bands: &[[f64; 3]]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..bands.len()).collect();
    order.sort_by(|&a, &b| bands[a][1].total_cmp(&bands[b][1]));
    let mut tier = vec![0; bands.len()];
    // Each tier's fastest point.
    let mut leaders: Vec<usize> = Vec::new();
    for i in order {
        match leaders.iter().position(|&l| bands[i][0] <= bands[l][2]) {
            Some(t) => tier[i] = t + 1,
            None => {
                leaders.push(i);
                tier[i] = leaders.len();
            }
        }
    }
    tier
}

/// Fills each point's haptic-step and full-field tiers, over the whole sweep.
fn assign_tiers(meshes: &mut [MeshReport]) {
    let bands = |f: &dyn Fn(&Point) -> [f64; 3]| -> Vec<[f64; 3]> {
        meshes.iter().flat_map(|m| m.points.iter().map(f)).collect()
    };
    let haptic = tiers(&bands(&|p| {
        [p.haptic_step_ns_p25, p.haptic_step_ns, p.haptic_step_ns_p75]
    }));
    let field = tiers(&bands(&|p| [p.full_field_ms_p25, p.full_field_ms, p.full_field_ms_p75]));
    for (p, (h, f)) in meshes
        .iter_mut()
        .flat_map(|m| m.points.iter_mut())
        .zip(haptic.into_iter().zip(field))
    {
        p.haptic_step_tier = h;
        p.full_field_tier = f;
    }
}

fn check_options(o: &ReportOptions) -> Result<()> {
    if o.modes.is_empty() || o.modes.iter().any(|&r| r == 0 || r > 2000) {
        bail!("--modes {:?}: give mode counts between 1 and 2000", o.modes);
    }
    if o.sizes.is_empty() || o.sizes.iter().any(|h| !h.is_finite() || *h <= 0.0) {
        bail!("--sizes {:?}: give element sizes > 0 in metres", o.sizes);
    }
    if o.orders.is_empty() || o.orders.iter().any(|o| !matches!(o, 1 | 2)) {
        bail!("--orders {:?}: element orders are 1 and 2", o.orders);
    }
    if !o.duration.is_finite() || o.duration <= 0.0 || o.duration > 100.0 {
        bail!("--duration {}: give a step-load length in (0, 100] s", o.duration);
    }
    Ok(())
}

/// The plots need matplotlib: say so before an hour of work, not after.
fn check_plotting() -> Result<()> {
    let ok = std::process::Command::new("python3")
        .args(["-c", "import matplotlib"])
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false);
    if !ok {
        bail!("ves report draws its plots with matplotlib: run `pip install matplotlib` (or scripts/setup)");
    }
    Ok(())
}

struct Sweep<'a> {
    scene: &'a Scene,
    modes: &'a [usize],
    duration: f64,
    tmp: &'a Path,
    bar: &'a dyn crate::progress::Count,
    reference_frequencies: Vec<f64>,
    /// K⁻¹F at each probe on the finest mesh: the converged answer the total errors use.
    reference_statics: Vec<[f64; 3]>,
    dt: f64,
    probes: Vec<Probe>,
}

/// Exact responses at the probes on one mesh.
struct Exact {
    /// Per probe: its contact patch and force.
    at: Vec<(Patch, [f64; 3])>,
    /// Per probe: K⁻¹F averaged over the patch.
    statics: Vec<[f64; 3]>,
    /// Per probe: compliance block of the patch.
    blocks: Vec<[[f64; 3]; 3]>,
    /// Every surface vertex's block (written with each basis, as precompute does).
    surface: Compliance,
    /// Every surface vertex's patch (written with the blocks).
    contact: Patches,
    /// Per probe, per step: the full-order displacement at the vertex.
    dynamic: Vec<Vec<[f64; 3]>>,
}

impl Sweep<'_> {
    fn mesh(&mut self, order: u8, size: f64) -> Result<MeshReport> {
        let mut scene = self.scene.clone();
        scene.mesh.order = order;
        scene.mesh.size = size;
        let d = discretize(&scene, None)?;
        let supported = d.rigid == 0;
        let free = d.dofs.free_count();
        // Mode counts this mesh can give (Lanczos needs a Krylov space well inside the problem).
        let counts: Vec<usize> = self
            .modes
            .iter()
            .copied()
            .filter(|&r| 3 * (r + d.rigid) < free)
            .collect();
        let skipped = self.modes.len() - counts.len();
        if skipped > 0 {
            tracing::warn!(order, size, free, "mode counts above a third of the unknowns skipped");
            self.bar.inc(skipped as u64);
        }
        let Some(&rmax) = counts.last() else {
            bail!("{free} unknowns: too few for the mode counts asked; use smaller --sizes");
        };
        // The largest solve first: its modes choose the default probe and the time step.
        let (top, _) = solve(d.space(), rmax, SolverChoice::Auto)?;
        let freqs = top.frequencies_hz();
        let is_reference = self.reference_frequencies.is_empty();
        if is_reference {
            self.reference_frequencies = freqs.clone();
            let f1 = freqs.first().copied().unwrap_or(1.0).max(1e-9);
            let steps = (20.0 * f1 * self.duration).ceil().max(50.0);
            self.dt = self.duration / steps;
            self.probes = if self.scene.probes.is_empty() {
                vec![default_probe(&d, &top.vectors[..free])]
            } else {
                self.scene.probes.clone()
            };
        }
        // The estimate a basis of this mesh would carry, against the reference's frequencies.
        let k = ESTIMATE_MODES.min(top.eigenvalues.len());
        let view = crate::transfer::SpaceView::of(&d.mesh, &d.dofs, &d.system, &top, k);
        let estimated_relative_error =
            crate::accuracy::estimate(&scene, None, None, &view, &top.eigenvalues[..k], SolverChoice::Auto)
                .map(|e| e.relative());
        let measured_relative_error: Vec<f64> = if is_reference {
            Vec::new()
        } else {
            freqs
                .iter()
                .zip(&self.reference_frequencies)
                .take(k)
                .map(|(f, r)| (f - r).abs() / r)
                .collect()
        };
        let (exact, probes, correction_s, dynamic_s) = if supported {
            let (e, p, c, dy) = self.exact(&d)?;
            if is_reference {
                self.reference_statics = e.statics.clone();
            }
            (Some(e), p, Some(c), Some(dy))
        } else {
            (None, Vec::new(), None, None)
        };
        let mut points = Vec::with_capacity(counts.len());
        for &r in &counts {
            self.bar.message(&format!("order {order}, {:.4} m, {r} modes", size));
            let mut p = self.point(&scene, &d, r, exact.as_ref(), correction_s)?;
            if is_reference {
                // The reference against itself: nothing to report.
                p.frequency_error = None;
                p.static_error_total.clear();
                p.static_error_total_corrected.clear();
            }
            points.push(p);
            self.bar.inc(1);
        }
        Ok(MeshReport {
            order,
            size,
            nodes: d.mesh.nodes.len(),
            vertices: d.mesh.vertex_count,
            tets: d.mesh.tet_count(),
            dofs: free,
            mesh_s: d.mesh_s,
            assemble_s: d.assemble_s,
            static_correction_s: correction_s,
            full_dynamic_s: dynamic_s,
            frequencies_hz: freqs,
            probes,
            estimated_relative_error,
            measured_relative_error,
            points,
        })
    }

    /// Static and dynamic full-order responses at the probes, and the probes' compliance. Each
    /// probe's force is spread over the contact patch centred on the surface point nearest `at`
    /// (`[contact] radius`; one vertex at radius 0), and its displacement read with the same
    /// weights: what a hand on that patch feels, which converges under refinement.
    fn exact(&self, d: &Discretized) -> Result<(Exact, Vec<ProbeOnMesh>, f64, f64)> {
        let nf = d.dofs.free_count();
        let radius = self.scene.contact_radius;
        let index = Surface::new(&d.mesh);
        let mut at: Vec<(Patch, [f64; 3])> = Vec::new();
        let mut off_surface = Vec::new();
        for p in &self.probes {
            let (patch, centre, distance) = index
                .at_point(p.at, radius)
                .context("the mesh has no surface triangles to put a probe on")?;
            at.push((patch, p.force));
            off_surface.push((centre, distance));
        }
        let spread = |k: usize, patch: &Patch, f: [f64; 3], out: &mut [f64]| {
            for (&a, &w) in patch.nodes.iter().zip(&patch.weights) {
                for (c, fc) in f.iter().enumerate() {
                    let g = d.dofs.free_of[3 * a as usize + c];
                    if g != u32::MAX {
                        out[k * nf + g as usize] += w * fc;
                    }
                }
            }
        };
        let mut load = vec![0.0; nf * at.len()];
        for (k, (patch, f)) in at.iter().enumerate() {
            spread(k, patch, *f, &mut load);
        }
        // The offline cost of the correction is that of every surface vertex's patch with K's
        // factorisation, as precompute does it; the same factor gives the probes' own blocks and
        // the full solves the errors are measured against.
        let t = Instant::now();
        let chol = factor_stiffness(&d.system, &d.dofs)?;
        let fixed = |v: u32| (0..3).any(|c| d.dofs.free_of[3 * v as usize + c] == u32::MAX);
        let contact = crate::loads::patch::vertex_patches(&d.mesh, radius, fixed);
        let surface = crate::compliance::surface_compliance_with(d, &chol, &contact)?;
        let correction_s = t.elapsed().as_secs_f64();
        let mut x = load.clone();
        chol.solve_many_in_place(&mut x, at.len());
        let statics: Vec<[f64; 3]> = at
            .iter()
            .enumerate()
            .map(|(k, (patch, _))| patch_value(d, &x[k * nf..(k + 1) * nf], patch))
            .collect();
        let patches: Vec<(&[u32], &[f64])> = at
            .iter()
            .map(|(p, _)| (p.nodes.as_slice(), p.weights.as_slice()))
            .collect();
        let probe_blocks = crate::compliance::patch_blocks(&d.dofs, &chol, &patches, || ())?;
        let t = Instant::now();
        let stepping = self.stepping();
        let sys = FullSystem::new(d, stepping)?;
        let steps = (self.duration / self.dt).round() as usize;
        let mut dynamic = vec![Vec::with_capacity(steps); at.len()];
        integrate_step_load(&sys, stepping, &load, at.len(), steps, |u| {
            for (k, (patch, _)) in at.iter().enumerate() {
                dynamic[k].push(patch_value(d, &u[k * nf..(k + 1) * nf], patch));
            }
        });
        let dynamic_s = t.elapsed().as_secs_f64();
        let probes = at
            .iter()
            .zip(&off_surface)
            .zip(&statics)
            .map(|(((patch, _), &(centre, distance)), u)| ProbeOnMesh {
                vertex: heaviest(patch),
                snap_distance: distance,
                position: centre,
                exact_displacement: Vector3::from(*u).norm(),
            })
            .collect();
        Ok((
            Exact {
                at,
                statics,
                blocks: probe_blocks,
                surface,
                contact,
                dynamic,
            },
            probes,
            correction_s,
            dynamic_s,
        ))
    }

    fn stepping(&self) -> Stepping {
        Stepping {
            dt: self.dt,
            alpha: self.scene.damping.alpha,
            beta: self.scene.damping.beta,
        }
    }

    fn point(
        &self,
        scene: &Scene,
        d: &Discretized,
        r: usize,
        exact: Option<&Exact>,
        correction_s: Option<f64>,
    ) -> Result<Point> {
        let (modes, ordering_s) = solve(d.space(), r, SolverChoice::Auto)?;
        let offline_s = d.mesh_s + d.assemble_s + ordering_s + modes.factorize_s + modes.eigensolve_s;
        store::write(
            self.tmp,
            scene,
            &[store::Space {
                name: "global",
                voi: None,
                mesh: &d.mesh,
                dofs: &d.dofs,
                modes: &modes,
                mass: &d.system.mass,
                compliance: exact.map(|e| &e.surface),
                contact: exact.map(|e| &e.contact).filter(|c| c.radius > 0.0),
                felt: None,
                meshing_strategy: Some(d.meshing.strategy),
                transfers: &[],
                estimated_relative_error: None,
                stress: None,
                loads: &[],
                reactions: None,
                nonlinear: None,
            }],
        )?;
        let file_bytes = std::fs::metadata(self.tmp).map(|m| m.len()).unwrap_or(0);
        let basis = ves_runtime::basis::load(self.tmp, &ves_runtime::basis::LoadOptions::default())
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        let bytes_loaded = basis.bytes_loaded;
        let [field_p25, full_field_ms, field_p75] = percentiles(ves_runtime::bench::full_field_samples_ms(&basis, 30));
        let [step_p25, haptic_step_ns, step_p75] =
            percentiles(ves_runtime::bench::haptic_step_samples_ns(Arc::new(basis), 101, 2000));

        let freqs = modes.frequencies_hz();
        let compared = freqs.len().min(self.reference_frequencies.len());
        let frequency_error = (0..compared)
            .map(|j| (freqs[j] / self.reference_frequencies[j] - 1.0).abs())
            .fold(0.0, f64::max);

        let (mut se, mut sec, mut de, mut dec) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let (mut st, mut stc, mut dr, mut drc) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        if let Some(ex) = exact {
            let nf = d.dofs.free_count();
            let rows = |patch: &Patch| -> Vec<[f64; 3]> {
                (0..modes.eigenvalues.len())
                    .map(|j| patch_value(d, &modes.vectors[j * nf..(j + 1) * nf], patch))
                    .collect()
            };
            let stepping = self.stepping();
            let sys = ModalSystem::new(&modes.eigenvalues, stepping);
            for (k, (patch, f)) in ex.at.iter().enumerate() {
                let phi: Vec<Vector3<f64>> = rows(patch).into_iter().map(Vector3::from).collect();
                let f = Vector3::from(*f);
                // Modal static response Σ φφᵀF/λ, and the correction (G − ΦΛ⁻¹Φᵀ)F on top.
                let fj: Vec<f64> = phi.iter().map(|p| p.dot(&f)).collect();
                let modal: Vector3<f64> = phi
                    .iter()
                    .zip(&fj)
                    .zip(&modes.eigenvalues)
                    .map(|((p, fj), l)| p * (fj / l))
                    .sum();
                let block = Matrix3::from_fn(|a, b| ex.blocks[k][a][b]);
                let residual = block * f - modal;
                let corrected = modal + residual;
                let u = Vector3::from(ex.statics[k]);
                let rel = |a: Vector3<f64>, b: Vector3<f64>| (a - b).norm() / b.norm();
                se.push(rel(modal, u));
                sec.push(rel(corrected, u));
                if let Some(&converged) = self.reference_statics.get(k) {
                    let converged = Vector3::from(converged);
                    st.push(rel(modal, converged));
                    stc.push(rel(corrected, converged));
                }
                // Step load: modal response, and the same plus the residual held with the load.
                let (mut worst, mut worst_c, mut peak) = (0.0f64, 0.0f64, 0.0f64);
                let (mut sq, mut sq_c, mut sq_ref) = (0.0f64, 0.0f64, 0.0f64);
                let mut step = 0;
                integrate_step_load(&sys, stepping, &fj, 1, ex.dynamic[k].len(), |q| {
                    let ur: Vector3<f64> = phi.iter().zip(q).map(|(p, qj)| p * *qj).sum();
                    let full = Vector3::from(ex.dynamic[k][step]);
                    let (e, e_c) = ((ur - full).norm(), (ur + residual - full).norm());
                    worst = worst.max(e);
                    worst_c = worst_c.max(e_c);
                    peak = peak.max(full.norm());
                    sq += e * e;
                    sq_c += e_c * e_c;
                    sq_ref += full.norm_squared();
                    step += 1;
                });
                de.push(worst / peak);
                dec.push(worst_c / peak);
                dr.push((sq / sq_ref).sqrt());
                drc.push((sq_c / sq_ref).sqrt());
            }
        }
        Ok(Point {
            modes: r,
            offline_s,
            offline_with_correction_s: correction_s.map(|c| offline_s + c),
            file_bytes,
            bytes_loaded,
            haptic_step_ns,
            haptic_step_ns_p25: step_p25,
            haptic_step_ns_p75: step_p75,
            haptic_step_tier: 0,
            full_field_ms,
            full_field_ms_p25: field_p25,
            full_field_ms_p75: field_p75,
            full_field_tier: 0,
            frequency_error: Some(frequency_error),
            frequencies_compared: compared,
            static_error: se,
            static_error_corrected: sec,
            dynamic_error: de,
            dynamic_error_corrected: dec,
            static_error_total: st,
            static_error_total_corrected: stc,
            dynamic_error_rms: dr,
            dynamic_error_rms_corrected: drc,
        })
    }
}

/// With no probe in the scene: 1 N at the surface vertex that moves most in mode 1, along
/// that motion.
fn default_probe(d: &Discretized, phi1: &[f64]) -> Probe {
    let surface = surface_vertices(d);
    let v = surface
        .iter()
        .copied()
        .max_by(|&a, &b| norm(vertex_value(d, phi1, a)).total_cmp(&norm(vertex_value(d, phi1, b))))
        .unwrap_or(0);
    let u = vertex_value(d, phi1, v);
    let n = norm(u).max(f64::MIN_POSITIVE);
    Probe {
        at: d.mesh.nodes[v],
        force: u.map(|c| c / n),
    }
}

fn norm(a: [f64; 3]) -> f64 {
    Vector3::from(a).norm()
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    (Vector3::from(a) - Vector3::from(b)).norm()
}

fn surface_vertices(d: &Discretized) -> Vec<usize> {
    d.mesh.surface_vertices().into_iter().map(|i| i as usize).collect()
}

/// Σ wₐ uₐ over a patch of a free-DOF vector.
fn patch_value(d: &Discretized, x: &[f64], patch: &Patch) -> [f64; 3] {
    let mut out = [0.0; 3];
    for (&a, &w) in patch.nodes.iter().zip(&patch.weights) {
        let u = vertex_value(d, x, a as usize);
        for c in 0..3 {
            out[c] += w * u[c];
        }
    }
    out
}

/// The node carrying most of a patch's force.
fn heaviest(patch: &Patch) -> usize {
    patch
        .nodes
        .iter()
        .zip(&patch.weights)
        .max_by(|a, b| a.1.total_cmp(b.1))
        .map_or(0, |(&a, _)| a as usize)
}

/// The displacement of vertex `v` in a free-DOF vector (0 on supported components).
fn vertex_value(d: &Discretized, x: &[f64], v: usize) -> [f64; 3] {
    std::array::from_fn(|c| {
        let g = d.dofs.free_of[3 * v + c];
        if g == u32::MAX { 0.0 } else { x[g as usize] }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Step times of 143 and 150 ns whose batches spread over 140–160 ns are a tie, not a
    /// ranking; 300 ns with a tight spread is slower beyond the noise.
    #[test]
    fn timings_within_the_noise_are_tied() {
        let bands = [
            [140.0, 150.0, 160.0],
            [138.0, 143.0, 158.0],
            [295.0, 300.0, 310.0],
            // Overlaps the fastest point's band although a slower tier began before it.
            [155.0, 305.0, 400.0],
        ];
        assert_eq!(tiers(&bands), vec![1, 1, 2, 1]);
        // Without noise nothing ties.
        assert_eq!(tiers(&[[1.0, 1.0, 1.0], [2.0, 2.0, 2.0]]), vec![1, 2]);
    }

    #[test]
    fn percentiles_of_samples() {
        let v: Vec<f64> = (0..=100).map(f64::from).collect();
        assert_eq!(percentiles(v), [25.0, 50.0, 75.0]);
        assert!(percentiles(vec![f64::NAN]).iter().all(|x| x.is_nan()));
    }

    #[test]
    fn sizes_print_with_four_significant_digits() {
        assert_eq!(render::significant(1.0 / 15.0, 4), "0.06667");
        assert_eq!(render::significant(4e-4 / 3.0, 4), "0.0001333");
        // Other counts of digits, no exponent either way (the page's line: sizes to 3, the
        // first frequency to 5).
        assert_eq!(render::significant(10137.6657, 5), "10138");
        assert_eq!(render::significant(46.273784, 5), "46.274");
        assert_eq!(render::significant(116620.4, 5), "116620");
        assert_eq!(render::significant(1.3312, 3), "1.33");
        assert_eq!(render::significant(0.000123456, 3), "0.000123");
        assert_eq!(render::significant(0.0, 5), "0");
    }
}
