//! `ves precompute`: scene → mesh → K, M → modes → HDF5, for the global space and each VOI.

mod advice;
pub mod instant;
mod stages;

pub use stages::{Checks, solve_space};

use crate::fem::Dofs;
use crate::fem::{self, MassProperties};
use crate::modes::{self, Modes, SolverChoice};
use crate::output::Overwrite;
use crate::scene::{Scene, Voi};
use crate::store;
use crate::tet_mesh::Mesh;
use anyhow::{Context, Result};
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// Seconds per stage.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct Timings {
    /// Meshing (gmsh).
    pub mesh: f64,
    /// Assembly of K and M.
    pub assemble: f64,
    /// Ordering and factorisation of K − σM.
    pub factorize: f64,
    /// Lanczos iteration and checks.
    pub eigensolve: f64,
    /// Static correction blocks (when the scene asks for them).
    pub static_correction: f64,
    /// State-transfer matrices between spaces (VOI scenes).
    pub transfer: f64,
    /// The error estimate: the recovery estimate and, when solved, its coarser meshes.
    pub error_estimate: f64,
    /// Modal stress at the vertices (when the scene asks for it).
    pub stress: f64,
    /// Sturm count of each space's spectrum (one LDLᵀ of K − σM).
    pub sturm: f64,
    /// The static load cases (when the scene has any).
    pub loads: f64,
    /// The hand's contact patches of the surface vertices (with a contact radius).
    pub contact: f64,
    /// What each support carries per mode (held parts).
    pub reactions: f64,
    /// The nonlinear model: modal derivatives and the reduced energy's coefficients.
    pub nonlinear: f64,
    /// The felt compliance's truncation at sampled surface points (held parts).
    pub felt_compliance: f64,
    /// The load cases' peak stresses solved again on meshes refined around them.
    pub peak_stress: f64,
    /// Writing the file.
    pub write: f64,
    /// Everything.
    pub total: f64,
}

impl Timings {
    fn add(&mut self, o: &Timings) {
        self.mesh += o.mesh;
        self.assemble += o.assemble;
        self.factorize += o.factorize;
        self.eigensolve += o.eigensolve;
        self.static_correction += o.static_correction;
        self.error_estimate += o.error_estimate;
        self.stress += o.stress;
        self.sturm += o.sturm;
        self.loads += o.loads;
        self.contact += o.contact;
        self.reactions += o.reactions;
        self.nonlinear += o.nonlinear;
        self.felt_compliance += o.felt_compliance;
        self.peak_stress += o.peak_stress;
    }
}

/// One solved modal space.
pub struct SolvedSpace {
    /// "global" or the VOI name.
    pub name: String,
    /// The VOI, if any.
    pub voi: Option<Voi>,
    /// The mesh.
    pub mesh: Mesh,
    /// DOF numbering.
    pub dofs: Dofs,
    /// Elastic modes.
    pub modes: Modes,
    /// Mass properties.
    pub mass: MassProperties,
    /// Static compliance blocks, when the scene asks for a static correction.
    pub compliance: Option<crate::compliance::Compliance>,
    /// The hand's contact patches (none for a point contact).
    pub contact: Option<crate::loads::patch::Patches>,
    /// Stage times.
    pub timings: Timings,
    /// K and M (kept for the state transfer between spaces); `None` when SLEPc left them on the
    /// MPI ranks (no later stage needed them here).
    pub system: Option<fem::Assembled>,
    /// Transfer matrices from the other spaces (name, row-major `r × r_from`).
    pub transfers: Vec<(String, Vec<f64>)>,
    /// Repairs of curved tets the order-2 mesh needed.
    pub meshing: crate::mesh::Meshing,
    /// Each mode's estimated discretization error, when the scene asks for it.
    pub error: Option<crate::accuracy::ErrorEstimate>,
    /// The meshes of a `target_error` refinement, coarsest first.
    pub refinement: Option<Vec<crate::accuracy::refine::Step>>,
    /// Modal stress at the corner vertices, row-major [6·nv, r] (`[stress] enabled`).
    pub stress: Option<Vec<f64>>,
    /// The Sturm count at the top of the spectrum (not under MPI).
    pub sturm: Option<modes::SturmCount>,
    /// The scene's static load cases solved on this space (none: empty).
    pub loads: Vec<crate::loads::LoadResult>,
    /// What each support carries per unit modal coordinate (held parts' global space).
    pub reactions: Option<crate::loads::ModalReactions>,
    /// The nonlinear model (`[model] kind = "nonlinear"`): `modes` then holds the derivatives
    /// after the eigenmodes.
    pub nonlinear: Option<crate::nonlinear::NonlinearModel>,
    /// The felt compliance's modal truncation at sampled surface points (held parts).
    pub felt: Option<crate::accuracy::felt::FeltTruncation>,
}

impl SolvedSpace {
    /// What the file writer needs of this space.
    pub fn view(&self) -> store::Space<'_> {
        store::Space {
            name: &self.name,
            voi: self.voi.as_ref(),
            mesh: &self.mesh,
            dofs: &self.dofs,
            modes: &self.modes,
            mass: &self.mass,
            compliance: self.compliance.as_ref(),
            contact: self.contact.as_ref(),
            felt: self.felt.as_ref().and_then(|f| f.map.as_ref()),
            meshing_strategy: Some(self.meshing.strategy),
            transfers: &self.transfers,
            estimated_relative_error: self.error.as_ref().map(|e| {
                // The derivatives after the eigenmodes have no estimate (NaN).
                let mut v = e.relative();
                v.resize(self.modes.eigenvalues.len(), f64::NAN);
                v
            }),
            stress: self.stress.as_deref(),
            loads: &self.loads,
            reactions: self.reactions.as_ref(),
            nonlinear: self.nonlinear.as_ref(),
        }
    }
}

/// Whether a stage after the eigen-solve needs the whole K and M of a space on this process: the
/// error estimate (it pairs modes in the M-inner product), static correction and load cases (they
/// factor K) and the transfers between VOI spaces (M-projections). Without them SLEPc leaves K and M on the
/// ranks that assembled them, and rank 0 never holds them whole; with them rank 0 assembles them
/// after the solve.
pub fn needs_whole_system(scene: &Scene) -> bool {
    scene.mesh.error_estimate.on()
        || scene.static_correction.is_some()
        || scene.nonlinear.is_some()
        || !scene.voi.is_empty()
        || !scene.loads.is_empty()
}

/// The `--json` summary (README, `--json`).
#[derive(Debug, Serialize)]
pub struct Summary {
    /// Output file.
    pub output: String,
    /// Spaces, global first.
    pub spaces: Vec<SpaceSummary>,
    /// Stage times summed over spaces.
    pub timings_s: Timings,
    /// Peak resident memory of this process so far, bytes (Linux `VmHWM`; 0 where unknown); with
    /// `mesh.target_error`, since its refinement began (the forecasts reset it there).
    pub peak_rss_bytes: u64,
    /// The warnings given while reading the scene and computing, one line each, in order
    /// (gathered by a front end that collects them, [`crate::notices`]: `ves precompute
    /// --json`, Python; empty otherwise).
    pub warnings: Vec<String>,
}

/// One space in the summary.
#[derive(Debug, Serialize)]
pub struct SpaceSummary {
    /// Name.
    pub name: String,
    /// Mesh nodes.
    pub nodes: usize,
    /// Tets.
    pub tets: usize,
    /// Free DOFs.
    pub dofs: usize,
    /// Elastic frequencies.
    pub frequencies_hz: Vec<f64>,
    /// Largest relative residual (of the eigenmodes, when a nonlinear model adds derivatives).
    pub max_relative_residual: f64,
    /// The nonlinear model, if the scene asks for one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub nonlinear: Option<crate::nonlinear::Summary>,
    /// max |ΦᵀMΦ − I|.
    pub orthonormality_error: f64,
    /// Rigid modes dropped.
    pub rigid_modes_dropped: usize,
    /// Worst tet shape quality (6√2·V/l_rms³: 1 regular, → 0 sliver).
    pub min_tet_quality: f64,
    /// How many tets have a shape quality in each tenth of [0, 1] (the first also flat ones).
    pub tet_quality_histogram: [u64; 10],
    /// Corner vertices (what the runtime draws and picks).
    pub vertices: usize,
    /// Seconds this space took (mesh to eigen-solve, and static correction).
    pub seconds: f64,
    /// Curved (10-node) tets that were invalid after gmsh's order-2 step, how many gmsh's
    /// optimisation repaired and how many were made straight-sided.
    pub meshing: crate::mesh::Meshing,
    /// Per kept mode, the estimated relative frequency error against the mesh-converged answer
    /// (absent when the scene turns the estimate off or no coarser mesh could be solved).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub estimated_relative_error: Option<Vec<f64>>,
    /// How the estimate was made: per mode the rate and whether it is reliable, and the
    /// coarser meshes.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error_estimate: Option<crate::accuracy::ErrorEstimate>,
    /// With `mesh.target_error`: every mesh of the refinement (size, nodes, dofs, seconds,
    /// frequencies, largest estimated error), coarsest first.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub refinements: Option<Vec<crate::accuracy::refine::Step>>,
    /// Sturm count at the top of the spectrum: eigenvalues below σ against modes found there
    /// (equal: none skipped). Absent under MPI.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sturm_count: Option<modes::SturmCount>,
    /// The scene's static load cases on this space (empty without `[[load]]` or `[gravity]`).
    pub loads: Vec<crate::loads::LoadSummary>,
    /// How much of the exact static compliance at sampled contact patches the kept modes miss
    /// (held parts; absent for a free body): the error of what a hand feels, on this mesh.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub felt_compliance: Option<crate::accuracy::felt::FeltTruncation>,
}

/// Runs the whole pipeline for a scene and writes `out` (which may not be a symlink).
pub fn run(scene: &Scene, out: &Path, choice: SolverChoice) -> Result<Summary> {
    run_with(scene, out, choice, Overwrite::default())
}

/// [`run`], saying what the output may replace.
pub fn run_with(scene: &Scene, out: &Path, choice: SolverChoice, overwrite: Overwrite) -> Result<Summary> {
    Ok(run_checked(scene, out, choice, overwrite, Checks::WithSolve, "-o")?.summary)
}

/// [`run`] of an output a command names by option `flag` (`ves batch`'s `--out`): a refused
/// output path's advice names that option.
pub fn run_for(scene: &Scene, out: &Path, choice: SolverChoice, flag: &str) -> Result<Summary> {
    Ok(run_checked(scene, out, choice, Overwrite::default(), Checks::WithSolve, flag)?.summary)
}

/// [`run`] for someone waiting to use the basis (the viewer): when the scene's mesh size is fixed
/// and the solve runs here, the basis is written without its checks (Sturm count, error
/// estimate), which [`Written::check`] then makes, writing the file again with them: same modes,
/// same frequencies, the estimate added. Otherwise the checks are made with the solve and
/// [`Written::check`] has nothing left to do.
pub fn run_first<'s>(scene: &'s Scene, out: &Path, choice: SolverChoice) -> Result<Written<'s>> {
    let checks = if scene.mesh.target_error.is_none() && !choice.is_slepc() {
        Checks::Later
    } else {
        Checks::WithSolve
    };
    run_checked(scene, out, choice, Overwrite::default(), checks, "-o")
}

/// A basis written, its checks made or still to come ([`run_first`]).
pub struct Written<'s> {
    /// What the file holds now.
    pub summary: Summary,
    later: Option<Later<'s>>,
}

/// What the checks after a first basis need: the solved spaces, K and M kept.
struct Later<'s> {
    scene: &'s Scene,
    out: std::path::PathBuf,
    choice: SolverChoice,
    spaces: Vec<SolvedSpace>,
    transfer_s: f64,
    start: Instant,
}

impl Written<'_> {
    /// Whether checks are still to come.
    pub fn checks_pending(&self) -> bool {
        self.later.is_some()
    }

    /// Makes the checks still to come and writes the basis again with them; returns the final
    /// summary.
    pub fn check(self) -> Result<Summary> {
        let Some(mut l) = self.later else {
            return Ok(self.summary);
        };
        let n = l.spaces.len() as f64;
        for (i, s) in l.spaces.iter_mut().enumerate() {
            crate::progress::span(i as f64 / n, (i + 1) as f64 / n);
            let name = s.name.clone();
            stages::check_later(l.scene, s, l.choice).with_context(|| format!("space {name:?}"))?;
        }
        crate::progress::span(0.0, 1.0);
        crate::progress::stage("writing the estimate", 0.99)?;
        write_all(l.scene, &l.out, &l.spaces, l.transfer_s, l.start)
    }
}

fn run_checked<'s>(
    scene: &'s Scene,
    out: &Path,
    choice: SolverChoice,
    overwrite: Overwrite,
    checks: Checks,
    flag: &str,
) -> Result<Written<'s>> {
    let start = Instant::now();
    // Under MPI rank 0 runs the pipeline and the other ranks serve its eigen-solves. Every rank
    // checks the output (the same answer on a shared file system) and they agree, so that a
    // refusal stops them all before any work.
    let root = modes::mpi_job::rank() == 0;
    let distributed = choice.is_slepc() && modes::mpi_job::ranks() > 1;
    modes::mpi_job::agree((|| {
        crate::output::check_as(out, &scene.inputs(), overwrite, flag)?;
        if store::sidecar_path(out) == out {
            anyhow::bail!(
                "{}: the basis is an HDF5 file and its XDMF sidecar takes the .xdmf name; name the output .h5",
                out.display()
            );
        }
        Ok(crate::output::check_as(
            &store::sidecar_path(out),
            &scene.inputs(),
            overwrite,
            flag,
        )?)
    })())?;
    if distributed && !root {
        modes::mpi_job::serve()?;
        return Ok(Written {
            summary: Summary {
                output: out.display().to_string(),
                spaces: Vec::new(),
                timings_s: Timings::default(),
                peak_rss_bytes: crate::memory::peak_rss_bytes(),
                warnings: Vec::new(),
            },
            later: None,
        });
    }
    if distributed && needs_whole_system(scene) {
        let mut stages = Vec::new();
        if scene.mesh.error_estimate.on() {
            stages.push("the error estimate (set mesh.error_estimate = false)");
        }
        if scene.static_correction.is_some() {
            stages.push("static correction (it also factors K on rank 0; remove [static_correction])");
        }
        if !scene.voi.is_empty() {
            stages.push("the VOI transfers (remove the [[voi]] spaces)");
        }
        if !scene.loads.is_empty() {
            stages.push("the load cases (they factor K on rank 0; remove [[load]] and [gravity])");
        }
        tracing::warn!(
            "{}: under MPI rank 0 assembles each space's whole K and M for {}: its memory then grows with the part \
             as on one machine; turn them off for parts that need the ranks' memory",
            scene.path.display(),
            stages.join(", ")
        );
    }
    let result = pipeline(scene, out, choice, start, checks);
    if distributed {
        modes::mpi_job::release(result)
    } else {
        result
    }
}

/// Everything after the output check: each space solved, transfers, the basis written (its
/// checks made, or kept for [`Written::check`]).
fn pipeline<'s>(
    scene: &'s Scene,
    out: &Path,
    choice: SolverChoice,
    start: Instant,
    checks: Checks,
) -> Result<Written<'s>> {
    let mut spaces = solve_all(scene, choice, checks)?;
    crate::progress::span(0.0, 1.0);
    crate::progress::stage("writing", 0.95)?;
    let t = Instant::now();
    add_transfers(&mut spaces)?;
    let transfer_s = t.elapsed().as_secs_f64();
    let summary = write_all(scene, out, &spaces, transfer_s, start)?;
    let later = (checks == Checks::Later).then(|| Later {
        scene,
        out: out.to_path_buf(),
        choice,
        spaces,
        transfer_s,
        start,
    });
    Ok(Written { summary, later })
}

/// Each space solved (its checks `checks`), global first.
fn solve_all(scene: &Scene, choice: SolverChoice, checks: Checks) -> Result<Vec<SolvedSpace>> {
    let mut spaces = Vec::with_capacity(1 + scene.voi.len());
    let targets: Vec<Option<&Voi>> = std::iter::once(None).chain(scene.voi.iter().map(Some)).collect();
    let bar = crate::progress::count(targets.len() as u64, "spaces");
    let n = targets.len() as f64;
    for (i, voi) in targets.into_iter().enumerate() {
        let name = voi.map_or("global", |v| v.name.as_str());
        bar.message(&format!("space {name}"));
        // Each space a share of the whole; transfers and writing the last 5 %.
        crate::progress::span(0.95 * i as f64 / n, 0.95 * (i + 1) as f64 / n);
        let s = stages::solve_space_checked(scene, voi, choice, checks).with_context(|| format!("space {name:?}"))?;
        tracing::info!(
            space = name,
            f1_hz = s.modes.frequencies_hz().first().copied().unwrap_or(0.0),
            "solved"
        );
        spaces.push(s);
        bar.inc(1);
    }
    Ok(spaces)
}

/// Writes the basis of solved spaces (transfers filled) and sums it up.
fn write_all(scene: &Scene, out: &Path, spaces: &[SolvedSpace], transfer_s: f64, start: Instant) -> Result<Summary> {
    let t = Instant::now();
    let views: Vec<store::Space<'_>> = spaces.iter().map(SolvedSpace::view).collect();
    store::write(out, scene, &views)?;
    let mut timings = Timings::default();
    for s in spaces {
        timings.add(&s.timings);
    }
    timings.write = t.elapsed().as_secs_f64();
    timings.transfer = transfer_s;
    timings.total = start.elapsed().as_secs_f64();
    Ok(Summary {
        output: out.display().to_string(),
        spaces: spaces
            .iter()
            .map(|s| SpaceSummary {
                name: s.name.clone(),
                nodes: s.mesh.nodes.len(),
                tets: s.mesh.tet_count(),
                dofs: s.dofs.free_count(),
                frequencies_hz: s.modes.frequencies_hz(),
                max_relative_residual: crate::nonlinear::max_residual(
                    &s.modes.residuals,
                    s.nonlinear.as_ref().map(|n| n.eigenmodes),
                ),
                nonlinear: s.nonlinear.as_ref().map(|n| crate::nonlinear::Summary {
                    eigenmodes: n.eigenmodes,
                    derivatives_of: n.derivatives_of,
                    derivatives: n.reduced.r - n.eigenmodes,
                    coupling: Some(n.coupling),
                }),
                orthonormality_error: s.modes.orthonormality_error,
                rigid_modes_dropped: s.modes.rigid_dropped,
                min_tet_quality: s.mesh.worst_quality().0,
                tet_quality_histogram: s.mesh.quality_histogram(),
                vertices: s.mesh.vertex_count,
                meshing: s.meshing,
                estimated_relative_error: s.error.as_ref().map(|e| e.relative()),
                error_estimate: s.error.clone(),
                refinements: s.refinement.clone(),
                sturm_count: s.sturm,
                loads: s
                    .loads
                    .iter()
                    .map(|l| l.summary(scene.material.yield_strength))
                    .collect(),
                felt_compliance: s.felt.clone(),
                seconds: s.timings.mesh
                    + s.timings.assemble
                    + s.timings.factorize
                    + s.timings.eigensolve
                    + s.timings.static_correction,
            })
            .collect(),
        timings_s: timings,
        peak_rss_bytes: crate::memory::peak_rss_bytes(),
        warnings: Vec::new(),
    })
}

/// Fills each space's transfer matrices from every other space (VOI switching at run time).
/// Every space needs its K and M here (SLEPc assembles them on rank 0 when a scene has VOIs).
pub fn add_transfers(spaces: &mut [SolvedSpace]) -> Result<()> {
    if spaces.len() < 2 {
        return Ok(());
    }
    let mut all = Vec::with_capacity(spaces.len());
    for b in spaces.iter() {
        let mut list = Vec::new();
        for a in spaces.iter().filter(|a| a.name != b.name) {
            let (t, outside) = crate::transfer::transfer_matrix(&space_view(a)?, &space_view(b)?);
            if outside > 1e-3 {
                tracing::warn!(
                    from = a.name,
                    to = b.name,
                    outside,
                    "nodes of one space lie outside the other's mesh (curved boundary): transfer extrapolates there"
                );
            }
            list.push((a.name.clone(), t));
        }
        all.push(list);
    }
    for (s, list) in spaces.iter_mut().zip(all) {
        s.transfers = list;
    }
    Ok(())
}

fn space_view(s: &SolvedSpace) -> Result<crate::transfer::SpaceView<'_>> {
    let system = s.system.as_ref().with_context(|| {
        format!(
            "space {:?}: the transfers between spaces need its K and M, which were left on the MPI ranks",
            s.name
        )
    })?;
    Ok(crate::transfer::SpaceView::of(
        &s.mesh,
        &s.dofs,
        system,
        &s.modes,
        usize::MAX,
    ))
}
