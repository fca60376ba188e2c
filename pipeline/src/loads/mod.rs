//! Service loads (`[[load]]`, `[gravity]`, docs/scene.md): each load case solved statically on
//! the full model, K u = f, with the factorisation the static correction uses; its displacement,
//! nodal stress and von Mises stress, and the supports' reaction checked against the applied
//! total.

pub mod influence;
pub mod nearest;
pub mod patch;
pub mod peak;
pub mod vector;

pub use vector::LoadCaseError;

use crate::fem::element::Lame;
use crate::linsolve::Cholesky;
use crate::problem::Discretized;
use crate::scene::Scene;
use anyhow::{Context, Result, bail};

/// One load case solved.
#[derive(Clone, Debug)]
pub struct LoadResult {
    /// The case's name.
    pub name: String,
    /// `force`, `pressure` or `gravity`.
    pub kind: &'static str,
    /// Sum of the applied nodal loads, N.
    pub total_force: [f64; 3],
    /// Displacement of every node, 3n (row 3i+c), m.
    pub displacement: Vec<f64>,
    /// Stress at the corner vertices, [nv, 6] row-major, Voigt order xx yy zz yz xz xy, Pa.
    pub stress: Vec<f64>,
    /// Von Mises stress of every node, Pa: at corner vertices from `stress`, at mid-edge nodes
    /// from the mean of their edge's two corner tensors.
    pub von_mises: Vec<f64>,
    /// Total force the supports exert, N.
    pub reaction: [f64; 3],
    /// What each `[[fixed]]` support carries, in the scene's order.
    pub support_reactions: Vec<SupportReaction>,
    /// |reaction + applied| over the sum of the nodal loads' magnitudes: 0 in exact arithmetic.
    pub balance_residual: f64,
    /// Largest nodal displacement magnitude, m.
    pub max_displacement: f64,
    /// Largest von Mises stress over the corner vertices, Pa.
    pub max_von_mises: f64,
    /// Its peaks studied on meshes refined around them (the largest first;
    /// `accuracy/peak.rs`); empty when not studied.
    pub peaks: Vec<peak::PeakStress>,
}

/// One load case in the `--json` summary of `ves precompute` (docs/scene.md).
#[derive(Clone, Debug, serde::Serialize)]
pub struct LoadSummary {
    /// The case's name.
    pub name: String,
    /// `force`, `pressure` or `gravity`.
    pub kind: &'static str,
    /// Largest nodal displacement magnitude, m.
    pub max_displacement_m: f64,
    /// Largest von Mises stress at a corner vertex, Pa.
    pub max_von_mises_pa: f64,
    /// Yield strength over the largest von Mises stress, when the scene gives a yield strength
    /// (`null` without one, or when the load leaves the part unstressed).
    pub safety_factor: Option<f64>,
    /// Sum of the applied nodal loads, N.
    pub total_force_n: [f64; 3],
    /// Total force the supports exert, N: −`total_force_n` at equilibrium.
    pub reaction_n: [f64; 3],
    /// What each `[[fixed]]` support carries (scene order): force and moment about its centre
    /// (the middle of its held nodes' bounding box).
    pub support_reactions: Vec<SupportReaction>,
    /// |reaction + applied| over the sum of the nodal loads' magnitudes.
    pub balance_residual: f64,
    /// Its von Mises peaks studied on meshes refined around them, the largest first: value,
    /// error or `singular` (`accuracy/peak.rs`); empty when not studied.
    pub peaks: Vec<peak::PeakStress>,
    /// When the largest peak is singular (its `safety_factor` then falls as the mesh is refined):
    /// the yield strength over the largest studied peak that is not, the figure to judge the
    /// part by (`null` otherwise, or without a yield strength).
    pub safety_factor_away_from_singular: Option<f64>,
    /// What that says in a line: the largest peak's value and error, or that it is singular and
    /// the largest peak that is not (absent when not studied).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub peak_stress: Option<String>,
}

/// The force and moment one support exerts on the part in a load case. A DOF held by two
/// supports counts for the first: the supports' forces add up to `reaction_n`.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SupportReaction {
    /// The support, counted from 0 as `fixed[i]` in messages.
    pub support: usize,
    /// The middle of the bounding box of the nodes it holds, m: the point the moment is about.
    pub centre_m: [f64; 3],
    /// Force, N.
    pub force_n: [f64; 3],
    /// Moment about `centre_m`, N·m.
    pub moment_nm: [f64; 3],
}

/// The springs' restoring force K_s u, told DOF by DOF to `add` (a DOF may be told several
/// times): each block couples node `a`'s row with node `b`'s column, and the other way round.
fn spring_forces(springs: &[crate::fem::springs::NodeSpring], u: &[f64], mut add: impl FnMut(usize, f64)) {
    for sp in springs {
        let (a, b) = (sp.a as usize, sp.b as usize);
        for r in 0..3 {
            for c in 0..3 {
                add(3 * a + r, sp.block[r][c] * u[3 * b + c]);
                if a != b {
                    add(3 * b + c, sp.block[r][c] * u[3 * a + r]);
                }
            }
        }
    }
}

/// An element whose Jacobian is not positive, as the load stage says it.
pub(crate) fn degenerate(e: crate::fem::element::BadJacobian) -> anyhow::Error {
    anyhow::anyhow!("an element is degenerate (det J = {:.3e})", e.det)
}

/// Each support's share of the reaction: `k_u − f` at the DOFs it removes (`held`, full-length
/// vectors), −K_s u of its springs (`springs`), of `mesh`'s nodes.
fn support_reactions(
    mesh: &crate::tet_mesh::Mesh,
    held: &[Vec<u32>],
    springs: &[Vec<crate::fem::springs::NodeSpring>],
    u: &[f64],
    k_u: &[f64],
    f: &[f64],
) -> Vec<SupportReaction> {
    held.iter()
        .zip(springs)
        .enumerate()
        .map(|(support, (dofs, springs))| {
            // Per node, the force this support exerts on it.
            let mut at: std::collections::BTreeMap<usize, [f64; 3]> = std::collections::BTreeMap::new();
            for &g in dofs {
                at.entry(g as usize / 3).or_default()[g as usize % 3] += k_u[g as usize] - f[g as usize];
            }
            spring_forces(springs, u, |g, v| at.entry(g / 3).or_default()[g % 3] -= v);
            // The middle of their bounding box: a face's centre, a bore's axis (a mean of the
            // nodes would follow where the mesh happens to be finer).
            let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
            for &i in at.keys() {
                for c in 0..3 {
                    lo[c] = lo[c].min(mesh.nodes[i][c]);
                    hi[c] = hi[c].max(mesh.nodes[i][c]);
                }
            }
            let centre = [0, 1, 2].map(|c| if at.is_empty() { 0.0 } else { 0.5 * (lo[c] + hi[c]) });
            let (mut force, mut moment) = ([0.0; 3], [0.0; 3]);
            for (&i, v) in &at {
                let x = [0, 1, 2].map(|k| mesh.nodes[i][k] - centre[k]);
                for c in 0..3 {
                    force[c] += v[c];
                }
                moment[0] += x[1] * v[2] - x[2] * v[1];
                moment[1] += x[2] * v[0] - x[0] * v[2];
                moment[2] += x[0] * v[1] - x[1] * v[0];
            }
            SupportReaction {
                support,
                centre_m: centre,
                force_n: force,
                moment_nm: moment,
            }
        })
        .collect()
}

/// The elements of `mesh` that touch a node `held` removes a DOF of: K u at the held DOFs, and
/// at the free DOFs for a u that is zero off the held ones, comes from them alone (on the
/// ribplate held on its base, the whole mesh took 0.86 s for 30 modes' reactions).
fn near_held(mesh: &crate::tet_mesh::Mesh, held: &[Vec<u32>]) -> crate::tet_mesh::Mesh {
    let mut held_node = vec![false; mesh.nodes.len()];
    for &g in held.iter().flatten() {
        held_node[g as usize / 3] = true;
    }
    crate::tet_mesh::Mesh {
        nodes: mesh.nodes.clone(),
        vertex_count: mesh.vertex_count,
        kind: mesh.kind,
        tets: mesh
            .tets
            .chunks_exact(mesh.nodes_per_tet())
            .filter(|t| t.iter().any(|&v| held_node[v as usize]))
            .flatten()
            .copied()
            .collect(),
        surface: Vec::new(),
        surface_faces: Vec::new(),
    }
}

/// Bytes of the element forces made at once by [`modal_reactions`] (modes × DOFs × threads).
const GROUP_BYTES: usize = 256 << 20;

/// What each `[[fixed]]` support carries per unit of each mode's coordinate: the reactions of
/// u = Φq are Σ_j q_j R_j, exactly those of the FE model in that displacement (K u at the DOFs
/// a support removes, its springs' forces). How a session reports what the held faces carry.
pub struct ModalReactions {
    /// Per support, the point its moment is about (the middle of its held nodes' bounding box).
    pub centres: Vec<[f64; 3]>,
    /// Row-major [6·s, r]: row 6k+c is component c (force x y z, N; moment x y z, N·m) of
    /// support k.
    pub per_mode: Vec<f64>,
    /// Each support's reaction per newton of a static load at each surface vertex, when made
    /// ([`with_influence`]): two to [`influence::MAX_SUPPORTS`] supports holding every rigid
    /// motion. One support needs none: it carries the whole load.
    pub influence: Option<influence::Influence>,
}

/// `reactions` with their influence coefficients (`influence.rs`), for a part held by two to
/// [`influence::MAX_SUPPORTS`] supports that leave no rigid motion (`rigid_dropped` 0); as
/// given otherwise. One factorisation of K and 6 solves a support.
pub fn with_influence(
    scene: &Scene,
    d: &Discretized,
    rigid_dropped: usize,
    mut reactions: ModalReactions,
    factor: Option<&Cholesky>,
) -> Result<ModalReactions> {
    if !wants_influence(rigid_dropped, reactions.centres.len()) {
        return Ok(reactions);
    }
    let path = || scene.path.display().to_string();
    let held = crate::supports::held_by_each(&d.mesh, &scene.fixed).with_context(path)?;
    let springs = crate::supports::springs(&d.mesh, &scene.fixed, scene.material.young).with_context(path)?;
    let mut own = None;
    let made = crate::linsolve::given_or_made(&d.system, &d.dofs, factor, &mut own)
        .map_err(anyhow::Error::from)
        .and_then(|chol| {
            influence::support_influence(
                &d.mesh,
                &near_held(&d.mesh, &held),
                &Lame::of(&scene.material),
                &d.dofs,
                chol,
                &held,
                &springs,
                &reactions.centres,
            )
        });
    // An extra, not the basis: without it a session's reactions are the modes' share.
    match made {
        Ok(i) => reactions.influence = Some(i),
        Err(e) => tracing::warn!(
            "{}: the supports' influence coefficients were not made ({e:#}); a session's support reactions \
             are the modes' share of the hands' loads",
            path()
        ),
    }
    Ok(reactions)
}

/// The modal reactions of `modes` (on `dofs`' free DOFs) for `scene`'s supports; none for a
/// free body or without modes.
pub fn modal_reactions(
    scene: &Scene,
    mesh: &crate::tet_mesh::Mesh,
    dofs: &crate::fem::Dofs,
    modes: &crate::modes::Modes,
) -> Result<Option<ModalReactions>> {
    use rayon::prelude::*;
    let r = modes.eigenvalues.len();
    if scene.fixed.is_empty() || r == 0 {
        return Ok(None);
    }
    let path = || scene.path.display().to_string();
    let held = crate::supports::held_by_each(mesh, &scene.fixed).with_context(path)?;
    let springs = crate::supports::springs(mesh, &scene.fixed, scene.material.young).with_context(path)?;
    let lame = Lame::of(&scene.material);
    let nf = dofs.free_count();
    let n3 = 3 * mesh.nodes.len();
    let zero = vec![0.0; n3];
    let near = near_held(mesh, &held);
    // The modes in groups whose element forces are made together (each element's matrices once
    // per group); a group's partial sums, one per thread, stay within GROUP_BYTES.
    let group = (GROUP_BYTES / (8 * n3 * rayon::current_num_threads()).max(1)).clamp(1, r);
    let mut each: Vec<Vec<SupportReaction>> = Vec::with_capacity(r);
    for start in (0..r).step_by(group) {
        let us: Vec<Vec<f64>> = (start..(start + group).min(r))
            .into_par_iter()
            .map(|j| dofs.expand(&modes.vectors[j * nf..(j + 1) * nf]))
            .collect();
        let refs: Vec<&[f64]> = us.iter().map(Vec::as_slice).collect();
        let k_us = vector::internal_forces_many(&near, &lame, &refs).map_err(degenerate)?;
        each.par_extend(
            us.par_iter()
                .zip(k_us.par_chunks(n3.max(1)))
                .map(|(u, k_u)| support_reactions(mesh, &held, &springs, u, k_u, &zero)),
        );
    }
    let s = scene.fixed.len();
    let mut per_mode = vec![0.0; 6 * s * r];
    for (j, supports) in each.iter().enumerate() {
        for (k, sr) in supports.iter().enumerate() {
            for c in 0..3 {
                per_mode[(6 * k + c) * r + j] = sr.force_n[c];
                per_mode[(6 * k + 3 + c) * r + j] = sr.moment_nm[c];
            }
        }
    }
    Ok(Some(ModalReactions {
        centres: each[0].iter().map(|sr| sr.centre_m).collect(),
        per_mode,
        influence: None,
    }))
}

impl LoadResult {
    /// Its summary, with the safety factor against `yield_strength` (Pa) when there is one.
    pub fn summary(&self, yield_strength: Option<f64>) -> LoadSummary {
        LoadSummary {
            name: self.name.clone(),
            kind: self.kind,
            max_displacement_m: self.max_displacement,
            max_von_mises_pa: self.max_von_mises,
            safety_factor: yield_strength
                .filter(|_| self.max_von_mises > 0.0)
                .map(|y| y / self.max_von_mises),
            total_force_n: self.total_force,
            reaction_n: self.reaction,
            support_reactions: self.support_reactions.clone(),
            balance_residual: self.balance_residual,
            peaks: self.peaks.clone(),
            safety_factor_away_from_singular: yield_strength
                .zip(peak::regular(&self.peaks))
                .filter(|(_, p)| p.value_pa > 0.0)
                .map(|(y, p)| y / p.value_pa),
            peak_stress: peak::case_text(
                self.peaks.first().map(|p| p.record()).as_ref(),
                peak::regular(&self.peaks).map(|p| p.record()).as_ref(),
            ),
        }
    }
}

/// Von Mises stress of a Voigt tensor (xx yy zz yz xz xy).
pub fn von_mises(s: &[f64]) -> f64 {
    let d = (s[0] - s[1]).powi(2) + (s[1] - s[2]).powi(2) + (s[2] - s[0]).powi(2);
    (0.5 * d + 3.0 * (s[3] * s[3] + s[4] * s[4] + s[5] * s[5])).sqrt()
}

/// Refuses loads on a part its supports do not hold: K is singular, and inertia relief (the
/// rigid motions projected out of a self-equilibrated load) is not implemented.
fn require_supported(scene: &Scene, d: &Discretized) -> Result<()> {
    require_held(scene, d.rigid)
}

/// The checks of the scene's loads a meshed part allows, made before the eigen-solve: every
/// surface region selects triangles of `mesh`, and the supports leave no rigid motion (`rigid`)
/// free.
pub fn check_before_solve(scene: &Scene, mesh: &crate::tet_mesh::Mesh, rigid: usize) -> Result<()> {
    if scene.loads.is_empty() {
        return Ok(());
    }
    require_held(scene, rigid)?;
    for (i, case) in scene.loads.iter().enumerate() {
        if let Some(region) = case.applied.region() {
            crate::supports::region_triangles(mesh, &format!("load[{i}]"), region)
                .with_context(|| scene.path.display().to_string())?;
        }
    }
    Ok(())
}

fn require_held(scene: &Scene, rigid: usize) -> Result<()> {
    if rigid > 0 {
        bail!(
            "{}: load cases need a supported part: the supports leave {} rigid motions free (a free body's static \
             displacement under a load is not defined); add [[fixed]] regions, or remove the [[load]] and [gravity] \
             entries",
            scene.path.display(),
            rigid
        );
    }
    Ok(())
}

/// The nodal load vectors (3n each) of the scene's load cases on `d`'s mesh.
pub fn load_vectors(scene: &Scene, d: &Discretized) -> Result<Vec<Vec<f64>>> {
    let m = &scene.material;
    let lame = Lame::of(m);
    // The [[load]] entries come first, in the scene's order, then [gravity].
    scene
        .loads
        .iter()
        .enumerate()
        .map(|(i, case)| {
            let key = match case.applied.region() {
                Some(_) => format!("load[{i}]"),
                None => "gravity".to_string(),
            };
            vector::nodal_loads(&d.mesh, &lame, case, &key).with_context(|| scene.path.display().to_string())
        })
        .collect()
}

/// Solves K u = f for every load vector (3n each) on `d`, supported DOFs held at zero: one
/// factorisation, all right-hand sides at once. Returns the displacements (3n each).
pub fn solve_static(d: &Discretized, loads: &[Vec<f64>]) -> Result<Vec<Vec<f64>>> {
    solve_static_with(d, loads, None)
}

/// Whether `supports` supports leaving `rigid_dropped` rigid motions get influence
/// coefficients ([`with_influence`]): two to six, holding every rigid motion.
pub fn wants_influence(rigid_dropped: usize, supports: usize) -> bool {
    // The reader's rule (what a session believes), and at most six supports (the writer's cost).
    let rule = ves_format::read::ReactionStatics::of(supports, rigid_dropped.min(6) as u32, true);
    supports <= influence::MAX_SUPPORTS && rule == ves_format::read::ReactionStatics::Influence
}

/// [`solve_static`] with K's factor when an earlier stage made it (`None`: made here).
pub fn solve_static_with(d: &Discretized, loads: &[Vec<f64>], factor: Option<&Cholesky>) -> Result<Vec<Vec<f64>>> {
    let mut own = None;
    let chol = crate::linsolve::given_or_made(&d.system, &d.dofs, factor, &mut own)?;
    let nf = d.dofs.free_count();
    let mut x = vec![0.0; nf * loads.len()];
    for (j, f) in loads.iter().enumerate() {
        for (k, &g) in d.dofs.free.iter().enumerate() {
            x[j * nf + k] = f[g as usize];
        }
    }
    chol.solve_many_in_place(&mut x, loads.len());
    Ok((0..loads.len())
        .map(|j| d.dofs.expand(&x[j * nf..(j + 1) * nf]))
        .collect())
}

/// The load stage: every load case of the scene solved on `d` (none: an empty list): K u = f
/// for a linear model; for a nonlinear one ([`crate::nonlinear`]) the static equilibrium of
/// the reduced model the runtime uses, with the Cauchy stress of its displacement.
pub fn solve_loads(
    scene: &Scene,
    d: &Discretized,
    nonlinear: Option<(&crate::nonlinear::NonlinearModel, &crate::modes::Modes)>,
    factor: Option<&Cholesky>,
) -> Result<Vec<LoadResult>> {
    if scene.loads.is_empty() {
        return Ok(Vec::new());
    }
    require_supported(scene, d)?;
    let f = load_vectors(scene, d)?;
    let m = &scene.material;
    let lame = Lame::of(m);
    let held =
        crate::supports::held_by_each(&d.mesh, &scene.fixed).with_context(|| scene.path.display().to_string())?;
    let springs = crate::supports::springs(&d.mesh, &scene.fixed, scene.material.young)
        .with_context(|| scene.path.display().to_string())?;
    if let Some((model, modes)) = nonlinear {
        let basis = crate::nonlinear::full_columns(d, modes);
        let points = crate::fem::stvk::Points::of(&d.mesh)?;
        let mut own = None;
        let chol = crate::linsolve::given_or_made(&d.system, &d.dofs, factor, &mut own)?;
        return scene
            .loads
            .iter()
            .zip(&f)
            .map(|(case, f)| {
                let (u, internal, _) = crate::nonlinear::static_response(d, model, &basis, f, &points)
                    .with_context(|| format!("load case {}", case.name))?;
                let reacting = one_newton_step(d, &lame, chol, &springs, f, &u, &internal)?;
                let s = crate::fem::stress::vertex_stress_cauchy(&d.mesh, &lame, &u);
                finish(d, case, f, u, (&reacting.0, &reacting.1), s, (&held, &springs))
            })
            .collect();
    }
    let u = solve_static_with(d, &f, factor)?;
    let r = f.len();
    // Stress of all cases at once: fields side by side, as the modal stress is recovered.
    let fields = crate::fem::stress::Fields::from_each(&u);
    let stress = crate::fem::stress::vertex_stress(&d.mesh, &lame, &fields);
    scene
        .loads
        .iter()
        .enumerate()
        .map(|(j, case)| {
            let nv = d.mesh.vertex_count;
            let s: Vec<f64> = (0..6 * nv).map(|row| stress[row * r + j]).collect();
            let k_u = vector::internal_forces(&d.mesh, &lame, &u[j]).map_err(degenerate)?;
            finish(d, case, &f[j], u[j].clone(), (&u[j], &k_u), s, (&held, &springs))
        })
        .collect()
}

/// The state the supports' reactions of a nonlinear load case are read from: the reduced
/// equilibrium `u` (its full internal force `internal`) is in balance only along the basis, so
/// the supports read there missed the applied load by 12–24 % on the soft cantilever. One
/// Newton step of the full model with the linear stiffness, δ = K⁻¹(f − f_int(u) − K_spr u)
/// on the free DOFs, gives the state (u + δ, f_int(u) + K δ) whose reactions balance the
/// applied force exactly (K and f_int carry no net force along a translation): the first
/// correction towards the full model's equilibrium. Moments balance about the undeformed
/// shape only to first order.
pub(crate) fn one_newton_step(
    d: &Discretized,
    lame: &Lame,
    chol: &crate::linsolve::Cholesky,
    springs: &[Vec<crate::fem::springs::NodeSpring>],
    f: &[f64],
    u: &[f64],
    internal: &[f64],
) -> Result<(Vec<f64>, Vec<f64>)> {
    let mut total = internal.to_vec();
    for s in springs {
        spring_forces(s, u, |g, v| total[g] += v);
    }
    let mut residual: Vec<f64> = d.dofs.free.iter().map(|&g| f[g as usize] - total[g as usize]).collect();
    chol.solve_many_in_place(&mut residual, 1);
    let delta = d.dofs.expand(&residual);
    let k_delta = vector::internal_forces(&d.mesh, lame, &delta).map_err(degenerate)?;
    Ok((
        u.iter().zip(&delta).map(|(a, b)| a + b).collect(),
        internal.iter().zip(&k_delta).map(|(a, b)| a + b).collect(),
    ))
}

/// The supports' summed force and its gap to the applied load `f`, over the sum of the nodal
/// loads' magnitudes (0 in exact arithmetic).
fn balance(support_reactions: &[SupportReaction], f: &[f64]) -> ([f64; 3], f64) {
    let reaction = [0, 1, 2].map(|c| support_reactions.iter().map(|r| r.force_n[c]).sum::<f64>());
    let mut total = [0.0; 3];
    let mut magnitude = 0.0;
    for node in f.chunks_exact(3) {
        for c in 0..3 {
            total[c] += node[c];
        }
        magnitude += (node[0] * node[0] + node[1] * node[1] + node[2] * node[2]).sqrt();
    }
    let gap = (0..3).map(|c| (reaction[c] + total[c]).powi(2)).sum::<f64>().sqrt();
    (reaction, gap / magnitude.max(f64::MIN_POSITIVE))
}

/// One case's summary: reaction and balance, von Mises at every node, the largest values, for
/// the displacement `u`. `(reacting, k_u)`: the state the supports' reactions are read from and
/// the internal force it makes (u and K u for a linear model; [`one_newton_step`]'s for a
/// nonlinear one).
fn finish(
    d: &Discretized,
    case: &crate::scene::LoadCase,
    f: &[f64],
    u: Vec<f64>,
    (reacting, k_u): (&[f64], &[f64]),
    stress: Vec<f64>,
    (held, springs): (&[Vec<u32>], &[Vec<crate::fem::springs::NodeSpring>]),
) -> Result<LoadResult> {
    let support_reactions = support_reactions(&d.mesh, held, springs, reacting, k_u, f);
    // The supports' forces: at the DOFs they remove and in their springs.
    let (reaction, balance_residual) = balance(&support_reactions, f);
    let total = [0, 1, 2].map(|c| f.iter().skip(c).step_by(3).sum::<f64>());
    let von_mises = nodal_von_mises(&d.mesh, &stress);
    let max_displacement = u
        .chunks_exact(3)
        .map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
        .fold(0.0, f64::max);
    let max_von_mises = von_mises[..d.mesh.vertex_count].iter().copied().fold(0.0, f64::max);
    Ok(LoadResult {
        name: case.name.clone(),
        kind: case.applied.kind(),
        total_force: total,
        displacement: u,
        stress,
        von_mises,
        reaction,
        support_reactions,
        balance_residual,
        max_displacement,
        max_von_mises,
        peaks: Vec::new(),
    })
}

/// Von Mises at every node from the corner vertices' tensors ([nv, 6]): a mid-edge node takes
/// the mean of its edge's two corner tensors (the field ParaView draws on the corners, linear
/// along the edge).
fn nodal_von_mises(mesh: &crate::tet_mesh::Mesh, stress: &[f64]) -> Vec<f64> {
    let nv = mesh.vertex_count;
    let mut out = vec![0.0; mesh.nodes.len()];
    for (v, s) in stress.chunks_exact(6).enumerate() {
        out[v] = von_mises(s);
    }
    if mesh.kind == crate::fem::element::Kind::Tet10 {
        for e in 0..mesh.tet_count() {
            let t = mesh.tet(e);
            for (k, (a, b)) in crate::tet_mesh::TET10_EDGES.iter().enumerate() {
                let (a, b) = (t[*a] as usize, t[*b] as usize);
                let mean: Vec<f64> = (0..6).map(|c| 0.5 * (stress[6 * a + c] + stress[6 * b + c])).collect();
                let m = t[4 + k] as usize;
                if m >= nv {
                    out[m] = von_mises(&mean);
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn von_mises_of_uniaxial_and_pure_shear() {
        assert!((von_mises(&[100.0, 0.0, 0.0, 0.0, 0.0, 0.0]) - 100.0).abs() < 1e-12);
        assert!((von_mises(&[0.0, 0.0, 0.0, 0.0, 0.0, 10.0]) - 10.0 * 3f64.sqrt()).abs() < 1e-12);
        assert!(von_mises(&[5.0, 5.0, 5.0, 0.0, 0.0, 0.0]).abs() < 1e-12);
    }
}
