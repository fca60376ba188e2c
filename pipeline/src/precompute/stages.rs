//! One space, stage by stage: discretize → solve → Sturm check → error estimate → static
//! correction → modal stress → what the file stores. Each stage is a function from what the
//! previous ones made; a stage's temporaries (factors, coarse meshes) are dropped when it
//! returns, and [`released`] gives their pages back before the next stage takes its own.

use super::{SolvedSpace, Timings, advice, needs_whole_system};
use crate::accuracy::{ErrorEstimate, Prefetch, refine};
use crate::compliance::Compliance;
use crate::fem::Dofs;
use crate::fem::MassProperties;
use crate::loads::patch::Patches;
use crate::modes::{self, Modes, SolverChoice, SturmCount};
use crate::problem::{Discretized, Meshed};
use crate::progress;
use crate::scene::{Scene, Voi};
use crate::tet_mesh::Mesh;
use anyhow::{Context, Result};
use std::time::Instant;

/// A space's discrete problem: K and M assembled on this process, or left to the MPI ranks
/// that solve it (SLEPc), which assemble their own rows from the mesh.
// One per space, moved a few times: the size difference of the variants costs nothing.
#[allow(clippy::large_enum_variant)]
pub(super) enum Problem {
    /// K and M here: every stage can use them.
    Here(Discretized),
    /// K and M only on the ranks (this process has the mesh and the supports).
    OnRanks(Meshed),
}

impl Problem {
    fn mesh(&self) -> &Mesh {
        match self {
            Problem::Here(d) => &d.mesh,
            Problem::OnRanks(m) => &m.mesh,
        }
    }

    fn dofs(&self) -> &Dofs {
        match self {
            Problem::Here(d) => &d.dofs,
            Problem::OnRanks(m) => &m.dofs,
        }
    }

    fn meshing(&self) -> &crate::mesh::Meshing {
        match self {
            Problem::Here(d) => &d.meshing,
            Problem::OnRanks(m) => &m.meshing,
        }
    }

    /// K and M, when they are on this process.
    fn here(&self) -> Option<&Discretized> {
        match self {
            Problem::Here(d) => Some(d),
            Problem::OnRanks(_) => None,
        }
    }
}

/// The solve stage's output.
pub(super) struct Solved {
    /// The problem (K and M here whenever a later stage needs them: [`needs_whole_system`]).
    pub problem: Problem,
    /// The part's mass properties (assembled here, or summed over the ranks).
    pub mass: MassProperties,
    /// The elastic modes, checked.
    pub modes: Modes,
    /// Seconds of the fill-reducing ordering before the solve (counted with the factorisation).
    pub ordering_s: f64,
}

/// The error-estimate stage's output (`Default`: none made).
#[derive(Default)]
pub(super) struct Estimated {
    /// Each mode's estimated discretization error, when the scene asks for it.
    pub error: Option<ErrorEstimate>,
    /// The meshes of a `target_error` refinement, coarsest first.
    pub refinement: Option<Vec<refine::Step>>,
    /// Seconds the estimate (and the refinement's coarser meshes) took.
    pub seconds: f64,
}

/// When the checks that leave the modes as they are (the Sturm count, the error estimate) run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Checks {
    /// With the solve, before the basis is written.
    WithSolve,
    /// After a first basis is written ([`check_later`]): the viewer pulls the part meanwhile.
    /// Only for a fixed mesh size on this process (a `target_error` refinement needs the
    /// estimate to choose its mesh; SLEPc checks its own).
    Later,
}

/// Where a fixed-size compute's stages start, as fractions of it (the progress bar): each
/// stage's share of the time measured on held corpus parts with a cold mesh cache — meshing and
/// assembling 0.45, the eigen-solve 0.30, the recovery estimate 0.10, the static correction
/// 0.20 (docs/view.md, "Progress") — over the stages this scene runs, up to the load cases at
/// 90 %. Fixed
/// fractions (the eigen-solve at 30 %, the correction at 85 %) left the bar at 0 % through a
/// meshing that took half the time, then at 85 % through a correction that took a fifth.
struct Shares {
    solve: f64,
    estimate: f64,
    correction: f64,
    loads: f64,
}

impl Shares {
    /// With or without the estimate before the basis is written and the static correction.
    fn of(estimated: bool, corrected: bool) -> Shares {
        const MESH: f64 = 0.45;
        const SOLVE: f64 = 0.30;
        let estimate = if estimated { 0.10 } else { 0.0 };
        let correction = if corrected { 0.20 } else { 0.0 };
        // Up to the load cases: 90 % of the bar, as before (the checks and the writing after).
        let scale = 0.9 / (MESH + SOLVE + estimate + correction);
        Shares {
            solve: scale * MESH,
            estimate: scale * (MESH + SOLVE),
            correction: scale * (MESH + SOLVE + estimate),
            loads: 0.9,
        }
    }
}

/// Meshes, assembles and solves one space (refining it first when the scene sets a target
/// error), and estimates its discretization error.
pub fn solve_space(scene: &Scene, voi: Option<&Voi>, choice: SolverChoice) -> Result<SolvedSpace> {
    solve_space_checked(scene, voi, choice, Checks::WithSolve)
}

/// [`solve_space`], with its checks now or later.
pub(super) fn solve_space_checked(
    scene: &Scene,
    voi: Option<&Voi>,
    choice: SolverChoice,
    checks: Checks,
) -> Result<SolvedSpace> {
    let name = voi.map_or("global".to_string(), |v| v.name.clone());
    // The estimate, the felt check and the prefetch ask for the same coarser meshes.
    let _failures = crate::mesh::remember_failures();
    // `run_first` asks for them later only on a fixed mesh size (a refinement needs them).
    let later = checks == Checks::Later;
    debug_assert!(!later || scene.mesh.target_error.is_none());
    let shares = Shares::of(
        !later && scene.mesh.error_estimate.on(),
        scene.static_correction.is_some(),
    );
    let (mut solved, estimated) = match scene.mesh.target_error {
        Some(target) => {
            progress::stage("meshing and solving until the estimate meets target_error", 0.0)?;
            refined(scene, voi, choice, target)?
        }
        None => {
            // The coarser meshes, when they will be needed whatever the modes, are made beside
            // the fine one (each gmsh in its own process, one core each), so the fine solve
            // later has both cores to itself.
            // The felt check's mesh error needs them too on a held part's whole-part space.
            let felt_needs = voi.is_none() && crate::accuracy::felt::needs_coarser_meshes(scene);
            let prefetch = ((crate::accuracy::coarser_meshes_expected(scene) || felt_needs) && !later)
                .then(|| Prefetch::start(scene, voi, None));
            progress::stage("meshing and assembling", 0.0)?;
            let problem = discretize(scene, voi, choice)?;
            progress::stage("eigen-solving", shares.solve)?;
            let mut solved = released(|| solve(scene, problem, choice))?;
            solved.modes.release_factor_unless_plentiful();
            if later {
                (solved, Estimated::default())
            } else {
                progress::stage("estimating the error", shares.estimate)?;
                let estimated = released(|| estimate(scene, voi, &solved, choice, prefetch))?;
                (solved, estimated)
            }
        }
    };
    if scene.mesh.error_estimate.on() && !later {
        let size = solved.problem.meshing().size;
        advice::warn_about_error(scene, &name, solved.problem.mesh(), size, estimated.error.as_ref());
    }
    let (nonlinear, nonlinear_s) = timed(|| nonlinear(scene, &mut solved));
    let nonlinear = nonlinear?;
    let refined = scene.mesh.target_error.is_some();
    progress::stage(
        "static correction and stress",
        if refined {
            crate::accuracy::refine::REFINEMENT_SHARE
        } else {
            shares.correction
        },
    )?;
    let (contact, contact_s) = timed(|| contact_patches(scene, &solved));
    // The modal stress (r fields over the mesh) before K's factor is made, not beside it.
    let (stress, stress_s) = timed(|| stress(scene, &solved));
    let shared = SharedFactor::of(&solved);
    let (compliance, static_correction_s) = timed(|| compliance(scene, &solved, contact.as_ref(), &shared));
    let compliance = compliance?;
    progress::stage("service loads", if refined { 0.9 } else { shares.loads })?;
    let factor = || if scene.loads.is_empty() { None } else { shared.get() };
    let (loads, loads_s) = timed(|| released(|| loads(scene, &solved, nonlinear.as_ref(), factor())));
    let loads = loads?;
    let (reactions, reactions_s) = timed(|| reactions(scene, voi, &solved, Influence::Made(&shared)));
    let reactions = reactions?;
    let factor = shared.into_made();
    let after = AfterSolve {
        sturm: None,
        estimated,
        compliance,
        contact,
        stress,
        static_correction_s,
        stress_s,
        loads,
        loads_s,
        reactions,
        contact_s,
        reactions_s,
        nonlinear,
        nonlinear_s,
    };
    let mut space = store(name, voi, solved, after);
    if !later {
        felt_truncation(scene, &mut space, factor)?;
        // After the last stage that solves with K's factor: the count's own factor (the same
        // size) is never held beside it.
        sturm_after(&mut space, choice)?;
        felt_mesh_error(scene, &mut space)?;
        peak_stress(scene, &mut space)?;
    }
    Ok(space)
}

/// The Sturm count of a stored space: proof that no mode below the last one was skipped. With
/// SLEPc, rank 0 would factor the whole matrix again on its own (the memory MPI is there to
/// share): left to SLEPc's checks.
fn sturm_after(s: &mut SolvedSpace, choice: SolverChoice) -> Result<()> {
    let Some(system) = s.system.as_ref().filter(|_| !choice.is_slepc()) else {
        return Ok(());
    };
    progress::stage("counting the eigenvalues below the last (Sturm)", 0.94)?;
    let sturm = released(|| modes::sturm_count(system, &s.dofs, &s.modes))?;
    if let Some(c) = &sturm {
        advice::report_sturm(&s.name, c);
    }
    s.timings.sturm = sturm.as_ref().map_or(0.0, |c| c.seconds);
    s.sturm = sturm;
    Ok(())
}

/// The load cases' peak stresses studied on meshes refined around them
/// (`accuracy::peak`), with its time: for the whole part's linear cases unless `[stress]
/// peak_error = false`. A check, not the basis: when it cannot be made (a refined mesh fails)
/// the cases are written without it and a warning says why.
fn peak_stress(scene: &Scene, s: &mut SolvedSpace) -> Result<()> {
    if !scene.peak_error || s.loads.is_empty() || s.voi.is_some() || s.nonlinear.is_some() {
        return Ok(());
    }
    progress::stage("the peak stresses, on meshes refined around them", 0.96)?;
    let (studied, seconds) =
        timed(|| released(|| crate::accuracy::peak::study(scene, &s.mesh, &s.dofs.fixed, &mut s.loads)));
    if let Err(e) = studied {
        tracing::warn!(
            "space \"{}\": the load cases' peak stresses were not studied ({e:#}); they are written without an error",
            s.name
        );
    }
    for l in &s.loads {
        let first = l.peaks.first().map(|p| p.record());
        let regular = crate::loads::peak::regular(&l.peaks).map(|p| p.record());
        if let Some(text) = crate::loads::peak::case_text(first.as_ref(), regular.as_ref()) {
            tracing::info!("load case \"{}\": {text}", l.name);
        }
    }
    s.timings.peak_stress = seconds;
    Ok(())
}

/// The felt compliance's truncation and its mesh error.
fn felt(scene: &Scene, s: &mut SolvedSpace, factor: Option<crate::linsolve::Cholesky>) -> Result<()> {
    felt_truncation(scene, s, factor)?;
    felt_mesh_error(scene, s)
}

/// The felt compliance's truncation (`accuracy::felt`), with its time. A check, not the basis:
/// when it cannot be made (K's factor does not fit in memory) the basis is written without it
/// and a warning says why.
/// `factor`: K's, when an earlier stage made it, or the solve's own (kept in the modes); its
/// numbers are released here whatever happens, the solve's symbolic analysis kept for the
/// Sturm count.
fn felt_truncation(scene: &Scene, s: &mut SolvedSpace, factor: Option<crate::linsolve::Cholesky>) -> Result<()> {
    progress::stage("the felt compliance's truncation", 0.93)?;
    let (factor, solves) = match s.modes.factored.take() {
        Some(modes::Factored::Stiffness(c)) => (Some(c), true),
        other => {
            s.modes.factored = other;
            (factor, false)
        }
    };
    let done = truncation(scene, s, factor.as_ref());
    if let Some(c) = factor.filter(|_| solves) {
        s.modes.factored = Some(modes::Factored::Symbolic(c.into_symbolic()));
    }
    done
}

fn truncation(scene: &Scene, s: &mut SolvedSpace, factor: Option<&crate::linsolve::Cholesky>) -> Result<()> {
    // A nonlinear model is felt through its own tangent; K on MPI ranks is not here.
    let Some(system) = s.system.as_ref().filter(|_| s.nonlinear.is_none()) else {
        return Ok(());
    };
    let space = crate::accuracy::felt::Space {
        mesh: &s.mesh,
        dofs: &s.dofs,
        system,
        modes: &s.modes,
        contact: s.contact.as_ref(),
        corrected: s.compliance.is_some(),
        first: scene
            .probes
            .iter()
            .map(|p| {
                let n = p.force.iter().map(|f| f * f).sum::<f64>().sqrt().max(f64::MIN_POSITIVE);
                (p.at, p.force.map(|f| -f / n))
            })
            .collect(),
        radius: scene.contact_radius,
        factor,
    };
    let (felt, seconds) = timed(|| released(|| crate::accuracy::felt::truncation(&space)));
    drop(space);
    match felt {
        Ok(f) => s.felt = f,
        Err(e) => tracing::warn!(
            "space \"{}\": the felt compliance's truncation was not computed ({e:#}); the basis is written without it",
            s.name
        ),
    }
    s.timings.felt_compliance = seconds;
    Ok(())
}

/// The felt compliance's mesh error, on two coarser meshes of the whole part.
fn felt_mesh_error(scene: &Scene, s: &mut SolvedSpace) -> Result<()> {
    if let Some(f) = s.felt.as_mut().filter(|_| s.voi.is_none()) {
        progress::stage("the felt compliance's mesh error", 0.95)?;
        let fine = s.dofs.free_count();
        // With the static correction the exact compliance is known at every vertex: the mesh
        // error is stated at each one a hand can touch.
        let everywhere = s
            .compliance
            .as_ref()
            .zip(s.contact.as_ref())
            .map(|(compliance, patches)| crate::accuracy::felt::Everywhere {
                compliance,
                patches,
                dofs: &s.dofs,
            });
        let size = s.meshing.size;
        let (done, more) =
            timed(|| released(|| crate::accuracy::felt::discretization(scene, &s.mesh, size, fine, f, everywhere)));
        if let Err(e) = done {
            tracing::warn!(
                "space \"{}\": the felt compliance's mesh error was not estimated ({e:#})",
                s.name
            );
        }
        s.timings.felt_compliance += more;
    }
    Ok(())
}

/// A space from modes found otherwise than by this module's solve (an instant basis on the
/// previous basis's mesh): its stress and the load cases of a linear model made as a solve's;
/// no checks, no static correction and no contact patches (the hand touches a point until the converged compute,
/// which makes them, follows: on the mould, on a loaded machine, they took 6.2 s beside 10.7 s
/// for the modes).
pub(super) fn space_from_modes(
    scene: &Scene,
    d: crate::problem::Discretized,
    modes: modes::Modes,
    stiffness: Option<&crate::linsolve::Cholesky>,
) -> Result<SolvedSpace> {
    let solved = Solved {
        mass: d.system.mass,
        problem: Problem::Here(d),
        modes,
        ordering_s: 0.0,
    };
    let (stress, stress_s) = timed(|| stress(scene, &solved));
    // K's factor, when the search made it, gives the supports' influence coefficients for a
    // few solves (6 a support) and answers the load cases.
    let influence = stiffness.map_or(Influence::Without, Influence::With);
    let (reactions, reactions_s) = timed(|| reactions(scene, None, &solved, influence));
    let reactions = reactions?;
    // The load cases of a linear model: K factored once and a solve each, so a load added to a
    // computed part is answered with the instant basis (its modes rescaled, no search).
    let (loads, loads_s) = match scene.nonlinear {
        None => timed(|| released(|| loads(scene, &solved, None, stiffness))),
        Some(_) => (Ok(Vec::new()), 0.0),
    };
    let later = AfterSolve {
        sturm: None,
        estimated: Estimated::default(),
        compliance: None,
        contact: None,
        stress,
        static_correction_s: 0.0,
        stress_s,
        loads: loads?,
        loads_s,
        reactions,
        contact_s: 0.0,
        reactions_s,
        nonlinear: None,
        nonlinear_s: 0.0,
    };
    Ok(store("global".to_string(), None, solved, later))
}

/// The checks [`Checks::Later`] left out, on a solved space (K and M kept): the Sturm count
/// and, when the scene asks for it, the error estimate (its coarser meshes, when needed, are
/// solved here, after the part is pullable).
pub(super) fn check_later(scene: &Scene, s: &mut SolvedSpace, choice: SolverChoice) -> Result<()> {
    let _failures = crate::mesh::remember_failures();
    let system = s
        .system
        .as_ref()
        .context("the checks after the solve need K and M, which were left on the MPI ranks")?;
    progress::stage("counting the eigenvalues below the last (Sturm)", 0.0)?;
    s.modes.release_factor_unless_plentiful();
    let sturm = released(|| modes::sturm_count(system, &s.dofs, &s.modes))?;
    if let Some(c) = &sturm {
        advice::report_sturm(&s.name, c);
    }
    s.timings.sturm = sturm.map_or(0.0, |c| c.seconds);
    s.sturm = sturm;
    if scene.mesh.error_estimate.on() {
        progress::stage("estimating the error", 0.2)?;
        let t = Instant::now();
        let view = crate::transfer::SpaceView::of(&s.mesh, &s.dofs, system, &s.modes, usize::MAX);
        s.error =
            released(|| crate::accuracy::estimate(scene, s.voi.as_ref(), None, &view, &s.modes.eigenvalues, choice));
        s.timings.error_estimate = t.elapsed().as_secs_f64();
        // A cancelled estimate is not reported.
        progress::stage("estimated", 0.95)?;
        advice::warn_about_error(scene, &s.name, &s.mesh, s.meshing.size, s.error.as_ref());
    }
    felt(scene, s, None)?;
    peak_stress(scene, s)
}

/// The `target_error` path: the refinement meshes, solves and estimates the space on finer
/// meshes until the estimate meets the target (the Sturm count is made on its last mesh, after
/// the stages that solve with K).
fn refined(scene: &Scene, voi: Option<&Voi>, choice: SolverChoice, target: f64) -> Result<(Solved, Estimated)> {
    let r = refine::refine(scene, voi, choice, target)?;
    let last = r.last;
    let mut solved = Solved {
        mass: last.d.system.mass,
        problem: Problem::Here(last.d),
        modes: last.modes,
        ordering_s: last.ordering_s,
    };
    solved.modes.release_factor_unless_plentiful();
    let estimated = Estimated {
        error: r.estimate,
        refinement: Some(r.steps),
        seconds: r.overhead_s,
    };
    Ok((solved, estimated))
}

/// Discretize: the mesh, the supports and (unless SLEPc's ranks assemble their own rows) K, M.
fn discretize(scene: &Scene, voi: Option<&Voi>, choice: SolverChoice) -> Result<Problem> {
    let problem = if choice.is_slepc() {
        // K and M are assembled on the ranks, each its rows, and stay there.
        let m = crate::problem::mesh_with_supports(scene, voi, None, false)?;
        // The ranks assemble their rows from the mesh and the removed DOFs only.
        anyhow::ensure!(
            m.springs.is_empty(),
            "{}: sliding, bearing and elastic supports are not assembled on MPI ranks; use a clamped support or \
             leave out --solver slepc",
            scene.path.display()
        );
        Problem::OnRanks(m)
    } else {
        Problem::Here(crate::problem::discretize(scene, voi)?)
    };
    // A load region that selects nothing, or supports that leave the part free to move, are
    // refused now, before the eigen-solve.
    let rigid = match &problem {
        Problem::Here(d) => d.rigid,
        Problem::OnRanks(m) => m.rigid(),
    };
    crate::loads::check_before_solve(scene, problem.mesh(), rigid)?;
    Ok(problem)
}

/// Solve: the lowest `modes.count` elastic modes. Under SLEPc, this process assembles K and M
/// whole after the solve, and only for a stage that needs them ([`needs_whole_system`]).
fn solve(scene: &Scene, problem: Problem, choice: SolverChoice) -> Result<Solved> {
    let count = scene.modes.count;
    match problem {
        Problem::Here(d) => {
            let (modes, ordering_s) = modes::solve(d.space(), count, choice).map_err(|e| advice::memory(e, scene))?;
            Ok(Solved {
                mass: d.system.mass,
                problem: Problem::Here(d),
                modes,
                ordering_s,
            })
        }
        Problem::OnRanks(mut m) => {
            let s = released(|| modes::solve_on_ranks(&m.mesh, &m.dofs, m.material, m.rigid(), count, choice))?;
            m.assemble_s += s.assemble_s;
            let (problem, mass) = if needs_whole_system(scene) {
                let d = m.assemble().with_context(|| scene.geometry.display().to_string())?;
                let mass = d.system.mass;
                (Problem::Here(d), mass)
            } else {
                let mut mass = s.moments.properties();
                mass.free = m.free.moved([0.0; 3], mass.center);
                (Problem::OnRanks(m), mass)
            };
            Ok(Solved {
                problem,
                mass,
                modes: s.modes,
                ordering_s: 0.0,
            })
        }
    }
}

/// Estimate: each mode's discretization error, when the scene asks for it: the recovery estimate
/// and, where needed, the coarser meshes (made beside the solve by `prefetch` when they were
/// known to be needed, by the estimate or the felt check: its time counts the wait for them).
fn estimate(
    scene: &Scene,
    voi: Option<&Voi>,
    solved: &Solved,
    choice: SolverChoice,
    prefetch: Option<Prefetch>,
) -> Result<Estimated> {
    let t = Instant::now();
    if let Some(p) = prefetch {
        p.finish();
    }
    let error = match (scene.mesh.error_estimate.on(), solved.problem.here()) {
        (false, _) => None,
        (true, Some(d)) => {
            let view = crate::transfer::SpaceView::of(&d.mesh, &d.dofs, &d.system, &solved.modes, usize::MAX);
            crate::accuracy::estimate(scene, voi, None, &view, &solved.modes.eigenvalues, choice)
        }
        (true, None) => anyhow::bail!("the error estimate needs K and M, which were left on the MPI ranks"),
    };
    Ok(Estimated {
        error,
        refinement: None,
        seconds: t.elapsed().as_secs_f64(),
    })
}

/// Contact patches: each surface vertex's, for the hand (none with `[contact] radius = 0`).
fn contact_patches(scene: &Scene, solved: &Solved) -> Option<Patches> {
    let (mesh, dofs) = (solved.problem.mesh(), solved.problem.dofs());
    let fixed = |v: u32| (0..3).any(|c| dofs.free_of[3 * v as usize + c] == u32::MAX);
    (scene.contact_radius > 0.0).then(|| crate::loads::patch::vertex_patches(mesh, scene.contact_radius, fixed))
}

/// Compliance: the static correction's blocks, when the scene asks for them, for the contact
/// patches (each vertex alone without them).
fn compliance(
    scene: &Scene,
    solved: &Solved,
    contact: Option<&Patches>,
    shared: &SharedFactor<'_>,
) -> Result<Option<Compliance>> {
    if scene.static_correction.is_none() {
        return Ok(None);
    }
    let d = solved
        .problem
        .here()
        .context("the static correction needs K, which was left on the MPI ranks")?;
    let points;
    let patches = match contact {
        Some(p) => p,
        None => {
            points = crate::loads::patch::vertex_patches(&d.mesh, 0.0, |_| true);
            &points
        }
    };
    // A free body's K is singular: no factor is tried, and the stage says why.
    let factor = (solved.modes.rigid_dropped == 0).then(|| shared.get()).flatten();
    Ok(Some(crate::compliance::surface_compliance(d, patches, factor)?))
}

/// Stress: each mode's stress at the corner vertices (`[stress] enabled`).
fn stress(scene: &Scene, solved: &Solved) -> Option<Vec<f64>> {
    if !scene.stress {
        return None;
    }
    let (dofs, modes) = (solved.problem.dofs(), &solved.modes);
    let r = modes.eigenvalues.len();
    let nf = dofs.free_count();
    let u = crate::fem::stress::Fields::from_free(dofs, &modes.vectors[..r * nf], r);
    let lame = crate::fem::element::Lame::of(&scene.material);
    Some(crate::fem::stress::vertex_stress(solved.problem.mesh(), &lame, &u))
}

/// K's factor, handed to the stages after the solve: the static correction, the load cases,
/// the supports' influence coefficients and the felt check each factorised K for itself before
/// (on the mould held by two faces, two factorisations of 0.4 s where one serves). A held
/// part's solve (σ = 0) factorised K itself and keeps it ([`modes::Factored`]); otherwise it is
/// made at the first request only, so a space whose stages need none makes none; a
/// factorisation that fails is remembered as none, and each stage then makes its own and says
/// why as before.
struct SharedFactor<'a> {
    d: Option<&'a crate::problem::Discretized>,
    solved_with: Option<&'a crate::linsolve::Cholesky>,
    made: std::cell::OnceCell<Option<crate::linsolve::Cholesky>>,
}

impl<'a> SharedFactor<'a> {
    fn of(solved: &'a Solved) -> SharedFactor<'a> {
        SharedFactor {
            d: solved.problem.here(),
            solved_with: solved.modes.factored.as_ref().and_then(|f| f.stiffness()),
            made: std::cell::OnceCell::new(),
        }
    }

    fn get(&self) -> Option<&crate::linsolve::Cholesky> {
        if self.solved_with.is_some() {
            return self.solved_with;
        }
        let d = self.d?;
        self.made
            .get_or_init(|| match crate::linsolve::factor_stiffness(&d.system, &d.dofs) {
                Ok(c) => Some(c),
                Err(e) => {
                    tracing::debug!("K's shared factor not made ({e}); each stage makes its own");
                    None
                }
            })
            .as_ref()
    }

    /// The factor, if it was made here (for a stage after the space is stored; the solve's own
    /// goes with the modes).
    fn into_made(self) -> Option<crate::linsolve::Cholesky> {
        self.made.into_inner().flatten()
    }
}

/// Whether a space's supports get their influence coefficients, and with which factor of K.
#[derive(Clone, Copy)]
enum Influence<'a> {
    /// None (an instant basis searched at a shift: the converged one that follows has them).
    Without,
    /// Made, with K's factor shared by the converged compute's stages.
    Made(&'a SharedFactor<'a>),
    /// Made with K's factor from an earlier stage (an instant basis of a held part: its
    /// search's own).
    With(&'a crate::linsolve::Cholesky),
}

/// What each support carries per unit modal coordinate, for the global space of a held part
/// with a linear model (a volume of interest's mesh need not hold the supports).
/// With `influence`, and K here, a part held by several supports gets their influence
/// coefficients too (what each carries of a load held steady).
fn reactions(
    scene: &Scene,
    voi: Option<&Voi>,
    solved: &Solved,
    influence: Influence<'_>,
) -> Result<Option<crate::loads::ModalReactions>> {
    // Reactions linear in q are wrong for a nonlinear model once it rotates (the page showed a
    // support carrying 2.75 N of a 10 N pull): none rather than a wrong one.
    if voi.is_some() || scene.nonlinear.is_some() {
        return Ok(None);
    }
    let modal = crate::loads::modal_reactions(scene, solved.problem.mesh(), solved.problem.dofs(), &solved.modes)?;
    let rigid = solved.modes.rigid_dropped;
    match (modal, solved.problem.here()) {
        (Some(m), Some(d)) if crate::loads::wants_influence(rigid, m.centres.len()) => {
            let factor = match influence {
                Influence::Without => return Ok(Some(m)),
                Influence::Made(shared) => shared.get(),
                Influence::With(chol) => Some(chol),
            };
            crate::loads::with_influence(scene, d, rigid, m, factor).map(Some)
        }
        (modal, _) => Ok(modal),
    }
}

/// The nonlinear model's basis and energy, when the scene asks for one: the modes get their
/// derivatives, and the load cases' responses and theirs, appended.
fn nonlinear(scene: &Scene, solved: &mut Solved) -> Result<Option<crate::nonlinear::NonlinearModel>> {
    let Some(n) = scene.nonlinear else { return Ok(None) };
    progress::stage("modal derivatives and the nonlinear model", 0.8)?;
    let Solved { problem, modes, .. } = solved;
    let d = problem
        .here()
        .context("the nonlinear model needs K, which was left on the MPI ranks")?;
    let loads = crate::loads::load_vectors(scene, d)?;
    let model =
        crate::nonlinear::enrich(d, modes, n.derivatives, &loads).with_context(|| scene.path.display().to_string())?;
    Ok(Some(model))
}

/// Loads: every static load case of the scene, solved on the full model (K factored once), or
/// as equilibria of the nonlinear model.
fn loads(
    scene: &Scene,
    solved: &Solved,
    nonlinear: Option<&crate::nonlinear::NonlinearModel>,
    stiffness: Option<&crate::linsolve::Cholesky>,
) -> Result<Vec<crate::loads::LoadResult>> {
    if scene.loads.is_empty() {
        return Ok(Vec::new());
    }
    let d = solved
        .problem
        .here()
        .context("the load cases need K, which was left on the MPI ranks")?;
    crate::loads::solve_loads(scene, d, nonlinear.map(|m| (m, &solved.modes)), stiffness)
}

/// What the stages after the solve made.
struct AfterSolve {
    sturm: Option<SturmCount>,
    estimated: Estimated,
    compliance: Option<Compliance>,
    contact: Option<Patches>,
    stress: Option<Vec<f64>>,
    static_correction_s: f64,
    stress_s: f64,
    loads: Vec<crate::loads::LoadResult>,
    loads_s: f64,
    reactions: Option<crate::loads::ModalReactions>,
    contact_s: f64,
    reactions_s: f64,
    nonlinear: Option<crate::nonlinear::NonlinearModel>,
    nonlinear_s: f64,
}

/// Store: what the file writer and the summary need of the space.
fn store(name: String, voi: Option<&Voi>, solved: Solved, later: AfterSolve) -> SolvedSpace {
    let Solved {
        problem,
        mass,
        modes,
        ordering_s,
    } = solved;
    let (mesh, dofs, system, meshing, mesh_s, assemble_s) = match problem {
        Problem::Here(d) => (
            d.model.mesh,
            d.model.dofs,
            Some(d.model.system),
            d.meshing,
            d.mesh_s,
            d.assemble_s,
        ),
        Problem::OnRanks(m) => (m.mesh, m.dofs, None, m.meshing, m.mesh_s, m.assemble_s),
    };
    let timings = Timings {
        mesh: mesh_s,
        assemble: assemble_s,
        factorize: ordering_s + modes.factorize_s,
        eigensolve: modes.eigensolve_s,
        error_estimate: later.estimated.seconds,
        static_correction: later.static_correction_s,
        stress: later.stress_s,
        sturm: later.sturm.map_or(0.0, |s| s.seconds),
        loads: later.loads_s,
        contact: later.contact_s,
        reactions: later.reactions_s,
        nonlinear: later.nonlinear_s,
        ..Timings::default()
    };
    SolvedSpace {
        name,
        voi: voi.cloned(),
        mesh,
        dofs,
        modes,
        mass,
        compliance: later.compliance,
        contact: later.contact,
        timings,
        system,
        transfers: Vec::new(),
        meshing,
        error: later.estimated.error,
        refinement: later.estimated.refinement,
        stress: later.stress,
        sturm: later.sturm,
        loads: later.loads,
        reactions: later.reactions,
        nonlinear: later.nonlinear,
        felt: None,
    }
}

/// Runs a stage, then gives the pages its dropped temporaries held back to the system (glibc
/// keeps them): the next stage's peak would otherwise add to this one's.
fn released<T>(stage: impl FnOnce() -> T) -> T {
    let out = stage();
    crate::memory::release_free_memory();
    out
}

/// A stage and its seconds.
fn timed<T>(stage: impl FnOnce() -> T) -> (T, f64) {
    let t = Instant::now();
    let out = stage();
    (out, t.elapsed().as_secs_f64())
}

#[cfg(test)]
mod tests {
    use super::Shares;

    /// The stages start in order, each after the last by its share, up to the load cases at 90 %.
    #[test]
    fn the_stages_start_in_order_by_their_measured_shares() {
        for (estimated, corrected) in [(false, false), (false, true), (true, false), (true, true)] {
            let s = Shares::of(estimated, corrected);
            let order = [0.0, s.solve, s.estimate, s.correction, s.loads];
            assert!(order.windows(2).all(|w| w[0] <= w[1]), "{order:?}");
            assert_eq!(s.loads, 0.9, "{order:?}");
            let same = |a: f64, b: f64| (a - b).abs() < 1e-12;
            assert_eq!(same(s.estimate, s.correction), !estimated, "{order:?}");
            assert_eq!(same(s.correction, s.loads), !corrected, "{order:?}");
        }
        // Held with the correction, no estimate (the page's first compute): the meshing is
        // 0.45 / 0.95 of 90 %.
        assert!((Shares::of(false, true).solve - 0.9 * 0.45 / 0.95).abs() < 1e-12);
    }
}
