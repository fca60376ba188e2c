//! `ves precompute`: scene → mesh → K, M → modes → HDF5, for the global space and each VOI.

use crate::fem::{self, MassProperties};
use crate::mesh::Mesh;
use crate::modes::{self, Modes, SolverChoice};
use crate::output::Overwrite;
use crate::problem::{Discretized, discretize};
use crate::scene::{Scene, Voi};
use crate::store;
use crate::supports::Dofs;
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
    /// The coarser meshes of the error estimate.
    pub error_estimate: f64,
    /// Modal stress at the vertices (when the scene asks for it).
    pub stress: f64,
    /// Sturm count of each space's spectrum (one LDLᵀ of K − σM).
    pub sturm: f64,
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
    /// Stage times.
    pub timings: Timings,
    /// K and M (kept for the state transfer between spaces).
    pub system: fem::Assembled,
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
            meshing_strategy: Some(self.meshing.strategy),
            transfers: &self.transfers,
            estimated_relative_error: self.error.as_ref().map(|e| e.relative()),
            stress: self.stress.as_deref(),
        }
    }
}

/// Meshes, assembles and solves one space (refining it first when the scene sets a target
/// error), and estimates its discretization error.
pub fn solve_space(scene: &Scene, voi: Option<&Voi>, choice: SolverChoice) -> Result<SolvedSpace> {
    let name = voi.map_or("global".to_string(), |v| v.name.clone());
    let t = Instant::now();
    // Proof that no mode below the last one was skipped, made right after the solve (its
    // factor's memory is free again, the error estimate's not yet taken). With SLEPc rank 0
    // would factor the whole matrix again on its own (the memory MPI is there to share): left
    // to SLEPc's checks.
    let sturm_of = |d: &Discretized, modes: &modes::Modes| {
        if choice.is_slepc() {
            Ok(None)
        } else {
            modes::sturm_count(d, modes)
        }
    };
    let (d, modes, ordering_s, error, refinement, estimate_s, sturm) = match scene.mesh.target_error {
        Some(target) => {
            let r = crate::accuracy::refine::refine(scene, voi, choice, target)?;
            let s = r.last;
            let sturm = sturm_of(&s.d, &s.modes)?;
            (
                s.d,
                s.modes,
                s.ordering_s,
                r.estimate,
                Some(r.steps),
                r.overhead_s,
                sturm,
            )
        }
        None => {
            // The coarser meshes are made beside the fine one (each gmsh in its own process,
            // one core each), so the fine solve later has both cores to itself.
            let prefetch = scene
                .mesh
                .error_estimate
                .then(|| crate::accuracy::Prefetch::start(scene, voi, None));
            let (d, modes, ordering_s) = if choice.is_slepc() {
                // K and M are assembled on the ranks, each its rows, and stay there; rank 0
                // assembles them whole only after the solve, and only for a stage that needs them.
                let mut d = crate::problem::discretize_unassembled(scene, voi, None, false)?;
                let s = modes::slepc::solve(&d.mesh, &d.dofs, d.material, d.rigid, scene.modes.count, choice)?;
                d.system.mass = s.moments.properties();
                d.assemble_s += s.assemble_s;
                if needs_whole_system(scene) {
                    crate::memory::release_free_memory();
                    d.assemble_system()
                        .with_context(|| scene.geometry.display().to_string())?;
                }
                (d, s.modes, 0.0)
            } else {
                let d = discretize(scene, voi)?;
                let (modes, ordering_s) = modes::solve(&d, scene.modes.count, choice)?;
                (d, modes, ordering_s)
            };
            crate::memory::release_free_memory();
            let sturm = sturm_of(&d, &modes)?;
            let solved_s = t.elapsed().as_secs_f64();
            if let Some(p) = prefetch {
                p.finish();
            }
            let error = if scene.mesh.error_estimate {
                let view = crate::transfer::SpaceView::of(&d.mesh, &d.dofs, &d.system, &modes, usize::MAX);
                crate::accuracy::estimate(scene, voi, None, &view, &modes.eigenvalues, choice)
            } else {
                None
            };
            crate::memory::release_free_memory();
            (
                d,
                modes,
                ordering_s,
                error,
                None,
                t.elapsed().as_secs_f64() - solved_s,
                sturm,
            )
        }
    };
    if scene.mesh.error_estimate {
        warn_about_error(scene, &name, &d.mesh, d.meshing.size, error.as_ref());
    }
    let mut timings = Timings {
        mesh: d.mesh_s,
        assemble: d.assemble_s,
        factorize: ordering_s + modes.factorize_s,
        eigensolve: modes.eigensolve_s,
        error_estimate: estimate_s,
        ..Timings::default()
    };
    let t = Instant::now();
    let compliance = match scene.static_correction {
        Some(_) => Some(crate::compliance::surface_compliance(&d)?),
        None => None,
    };
    timings.static_correction = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let stress = scene.stress.then(|| {
        let r = modes.eigenvalues.len();
        let nf = d.dofs.free_count();
        let u: Vec<f64> = (0..r)
            .flat_map(|j| d.dofs.expand(&modes.vectors[j * nf..(j + 1) * nf]))
            .collect();
        let m = &scene.material;
        let lame = crate::fem::element::Lame::new(m.young, m.poisson, m.density);
        crate::fem::stress::vertex_stress(&d.mesh, &lame, &u, r)
    });
    timings.stress = t.elapsed().as_secs_f64();
    if let Some(s) = &sturm {
        timings.sturm = s.seconds;
        if s.complete() {
            tracing::info!(space = %name, sigma = s.sigma, below = s.below, "Sturm count: no mode skipped");
        } else {
            tracing::warn!(
                "space {name:?}: {} eigenvalues lie below σ = {:.6e} (just above the last mode found) but {} modes were \
                 found there: either the last mode has a partner within 1e-6 (a repeated frequency cut in two: set \
                 modes.count = {}) or the eigen-solver skipped {} (check with --solver dense on a small mesh, and report it)",
                s.below,
                s.sigma,
                s.found,
                s.below - s.rigid,
                s.below.saturating_sub(s.found)
            );
        }
    }
    Ok(SolvedSpace {
        name,
        voi: voi.cloned(),
        mass: d.system.mass,
        compliance,
        mesh: d.mesh,
        dofs: d.dofs,
        modes,
        timings,
        system: d.system,
        transfers: Vec::new(),
        meshing: d.meshing,
        error,
        refinement,
        stress,
        sturm,
    })
}

/// Whether a stage after the eigen-solve needs the whole K and M of a space on this process: the
/// error estimate (it pairs modes in the M-inner product), static correction (it factors K) and
/// the transfers between VOI spaces (M-projections). Without them SLEPc leaves K and M on the
/// ranks that assembled them, and rank 0 never holds them whole; with them rank 0 assembles them
/// after the solve.
pub fn needs_whole_system(scene: &Scene) -> bool {
    scene.mesh.error_estimate || scene.static_correction.is_some() || !scene.voi.is_empty()
}

/// One line when a space has no estimate or one above [`crate::accuracy::WARN_ABOVE`], and one
/// when its walls are one element thick and the estimate does not vouch for them.
fn warn_about_error(scene: &Scene, name: &str, mesh: &Mesh, size: f64, error: Option<&crate::accuracy::ErrorEstimate>) {
    let worst = error.and_then(|e| crate::accuracy::worst(&e.relative()));
    let walls = mesh.walls();
    if walls.spanning_fraction > crate::mesh::walls::ONE_ELEMENT_THICK {
        // Whatever the estimate says: coarser meshes are one element thick too, so it cannot
        // see this (the cantilever at 50 mm: estimated 0.85 %, 3.1 % off the 25 mm mesh).
        tracing::warn!(
            "space {name:?}: {:.0} % of the volume is in walls one element thick (walls ≈ {:.2e} m): bending across \
             them rests on one element and the error estimate cannot see that; check with mesh.size ≤ {:.2e} m (two \
             through the wall)",
            100.0 * walls.spanning_fraction,
            walls.thickness,
            walls.thickness / 2.0
        );
    }
    match worst {
        None => tracing::warn!(
            space = name,
            "no error estimate: no coarser mesh of this space could be solved (see VES_LOG=info)"
        ),
        Some((mode, worst)) if worst > crate::accuracy::WARN_ABOVE => {
            let change = if scene.mesh.order == 1 {
                "use mesh.order = 2 (4-node tets are far too stiff in bending)".to_string()
            } else if scene.mesh.target_error.is_some() {
                "raise mesh.max_dofs".to_string()
            } else {
                format!(
                    "try mesh.size = {:.3e} m, or set [mesh] target_error = 0.01",
                    size / 2.0
                )
            };
            tracing::warn!(
                "space {name:?}: mode {}'s frequency is estimated {:.1} % above the mesh-converged value; {change}",
                mode + 1,
                100.0 * worst
            );
        }
        Some(_) => {}
    }
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
    /// Peak resident memory of this process so far, bytes (Linux `VmHWM`; 0 where unknown).
    pub peak_rss_bytes: u64,
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
    /// Largest relative residual.
    pub max_relative_residual: f64,
    /// max |ΦᵀMΦ − I|.
    pub orthonormality_error: f64,
    /// Rigid modes dropped.
    pub rigid_modes_dropped: usize,
    /// Worst tet shape quality (6√2·V/l_rms³: 1 regular, → 0 sliver).
    pub min_tet_quality: f64,
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
}

/// Runs the whole pipeline for a scene and writes `out` (which may not be a symlink).
pub fn run(scene: &Scene, out: &Path, choice: SolverChoice) -> Result<Summary> {
    run_with(scene, out, choice, Overwrite::default())
}

/// [`run`], saying what the output may replace.
pub fn run_with(scene: &Scene, out: &Path, choice: SolverChoice, overwrite: Overwrite) -> Result<Summary> {
    let start = Instant::now();
    // Under MPI rank 0 runs the pipeline and the other ranks serve its eigen-solves. Every rank
    // checks the output (the same answer on a shared file system) and they agree, so that a
    // refusal stops them all before any work.
    let root = modes::slepc::rank() == 0;
    let distributed = choice.is_slepc() && modes::slepc::ranks() > 1;
    modes::slepc::agree((|| {
        crate::output::check(out, &scene.inputs(), overwrite)?;
        if store::sidecar_path(out) == out {
            anyhow::bail!(
                "{}: the basis is an HDF5 file and its XDMF sidecar takes the .xdmf name; name the output .h5",
                out.display()
            );
        }
        crate::output::check(&store::sidecar_path(out), &scene.inputs(), overwrite)
    })())?;
    if distributed && !root {
        modes::slepc::serve()?;
        return Ok(Summary {
            output: out.display().to_string(),
            spaces: Vec::new(),
            timings_s: Timings::default(),
            peak_rss_bytes: crate::memory::peak_rss_bytes(),
        });
    }
    if distributed && needs_whole_system(scene) {
        let mut stages = Vec::new();
        if scene.mesh.error_estimate {
            stages.push("the error estimate (set mesh.error_estimate = false)");
        }
        if scene.static_correction.is_some() {
            stages.push("static correction (it also factors K on rank 0; remove [static_correction])");
        }
        if !scene.voi.is_empty() {
            stages.push("the VOI transfers (remove the [[voi]] spaces)");
        }
        tracing::warn!(
            "{}: under MPI rank 0 assembles each space's whole K and M for {}: its memory then grows with the part \
             as on one machine; turn them off for parts that need the ranks' memory",
            scene.path.display(),
            stages.join(", ")
        );
    }
    let result = pipeline(scene, out, choice, start);
    if distributed {
        modes::slepc::release(result)
    } else {
        result
    }
}

/// Everything after the output check: each space solved, transfers, the basis written.
fn pipeline(scene: &Scene, out: &Path, choice: SolverChoice, start: Instant) -> Result<Summary> {
    let mut spaces = Vec::with_capacity(1 + scene.voi.len());
    let targets: Vec<Option<&Voi>> = std::iter::once(None).chain(scene.voi.iter().map(Some)).collect();
    let bar = crate::progress::bar(targets.len() as u64, "spaces");
    for voi in targets {
        let name = voi.map_or("global", |v| v.name.as_str());
        bar.set_message(format!("space {name}"));
        let s = solve_space(scene, voi, choice).with_context(|| format!("space {name:?}"))?;
        tracing::info!(
            space = name,
            f1_hz = s.modes.frequencies_hz().first().copied().unwrap_or(0.0),
            "solved"
        );
        spaces.push(s);
        bar.inc(1);
    }
    bar.finish_and_clear();
    let t = Instant::now();
    add_transfers(&mut spaces);
    let transfer_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let views: Vec<store::Space<'_>> = spaces.iter().map(SolvedSpace::view).collect();
    store::write(out, scene, &views)?;
    let mut timings = Timings::default();
    for s in &spaces {
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
                max_relative_residual: s.modes.residuals.iter().fold(0.0, |a: f64, &b| a.max(b)),
                orthonormality_error: s.modes.orthonormality_error,
                rigid_modes_dropped: s.modes.rigid_dropped,
                min_tet_quality: s.mesh.worst_quality().0,
                vertices: s.mesh.vertex_count,
                meshing: s.meshing,
                estimated_relative_error: s.error.as_ref().map(|e| e.relative()),
                error_estimate: s.error.clone(),
                refinements: s.refinement.clone(),
                sturm_count: s.sturm,
                seconds: s.timings.mesh
                    + s.timings.assemble
                    + s.timings.factorize
                    + s.timings.eigensolve
                    + s.timings.static_correction,
            })
            .collect(),
        timings_s: timings,
        peak_rss_bytes: crate::memory::peak_rss_bytes(),
    })
}

/// Fills each space's transfer matrices from every other space (VOI switching at run time).
pub fn add_transfers(spaces: &mut [SolvedSpace]) {
    if spaces.len() < 2 {
        return;
    }
    let mut all = Vec::with_capacity(spaces.len());
    for b in spaces.iter() {
        let mut list = Vec::new();
        for a in spaces.iter().filter(|a| a.name != b.name) {
            let (t, outside) = crate::transfer::transfer_matrix(&space_view(a), &space_view(b));
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
}

fn space_view(s: &SolvedSpace) -> crate::transfer::SpaceView<'_> {
    crate::transfer::SpaceView::of(&s.mesh, &s.dofs, &s.system, &s.modes, usize::MAX)
}
