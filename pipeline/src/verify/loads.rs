//! `ves verify` of a scene's static load cases: the same mesh, supports and nodal loads through
//! a reference that solves load cases ([`Capability::LoadCases`]), and how far our displacement
//! field and support reaction are from its.

use super::error::VerifyError;
#[cfg(doc)]
use super::reference::Capability;
use super::reference::{LoadJob, Reference};
use crate::loads::{load_vectors, solve_static};
use crate::problem::Discretized;
use crate::scene::Scene;
use anyhow::Result;
use ndarray::Array2;
use serde::Serialize;
use std::path::Path;

/// One load case compared with the reference.
#[derive(Debug, Serialize)]
pub struct LoadComparison {
    /// The case's name.
    pub name: String,
    /// `force`, `pressure` or `gravity`.
    pub kind: &'static str,
    /// Largest displacement magnitude, ours, m.
    pub max_displacement_m: f64,
    /// max over DOFs |u_ours − u_ref| / max over DOFs |u_ref|.
    pub displacement_rel_diff: f64,
    /// Our total support reaction, N.
    pub reaction_n: [f64; 3],
    /// The reference's: its internal force K u summed over the supported DOFs (CalculiX's `RF`)
    /// less the loads applied at supported DOFs, N.
    pub reference_reaction_n: [f64; 3],
    /// |ours − the reference's| / |the reference's| of the reactions.
    pub reaction_rel_diff: f64,
    /// The tolerance applied to `displacement_rel_diff`.
    pub tolerance: f64,
    /// Within it.
    pub pass: bool,
}

/// Compares every load case of `scene` on `d` with `reference`; `tol` overrides its default
/// tolerance.
pub fn compare_loads(
    input: &str,
    scene: &Scene,
    d: &Discretized,
    reference: &dyn Reference,
    tol: Option<f64>,
) -> Result<Vec<LoadComparison>> {
    if scene.loads.is_empty() {
        return Ok(Vec::new());
    }
    let f = load_vectors(scene, d)?;
    let lame = crate::fem::element::Lame::of(&scene.material);
    // Ours, and the internal force it makes (K u, or the nonlinear force).
    let (ours, internal): (Vec<Vec<f64>>, Vec<Vec<f64>>) = match scene.nonlinear {
        None => {
            let u = solve_static(d, &f)?;
            let k_u = u
                .iter()
                .map(|u| {
                    crate::loads::vector::internal_forces(&d.mesh, &lame, u).map_err(|e| VerifyError::Degenerate {
                        input: input.to_string(),
                        det: e.det,
                    })
                })
                .collect::<Result<Vec<_>, _>>()?;
            (u, k_u)
        }
        Some(n) => nonlinear_responses(scene, d, n.derivatives, &f)?.into_iter().unzip(),
    };
    let theirs = solve_theirs(input, scene, d, reference, &f)?;
    let curved = !d.mesh.curved_tets().is_empty();
    let tolerance = match scene.nonlinear {
        // The reduced model against the full one: its truncation, not rounding (docs/nonlinear.md).
        Some(_) => tol.unwrap_or(NONLINEAR_TOLERANCE),
        None => tol.unwrap_or(reference.tolerances(d.mesh.kind.order(), curved).load),
    };
    let mut out = Vec::new();
    for (j, case) in scene.loads.iter().enumerate() {
        let reference_u = theirs.displacement.row(j);
        let scale = reference_u
            .iter()
            .fold(0.0f64, |a, v| a.max(v.abs()))
            .max(f64::MIN_POSITIVE);
        let gap = ours[j]
            .iter()
            .zip(reference_u)
            .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
        let k_u = &internal[j];
        let mut reaction = [0.0; 3];
        for &g in &d.dofs.fixed {
            reaction[g as usize % 3] += k_u[g as usize] - f[j][g as usize];
        }
        // The reference's reaction is its internal force K u at the supported DOFs; the load
        // applied at such a DOF goes straight into the support, so the support's force on the
        // part is K u − f there.
        let mut theirs_r = [0, 1, 2].map(|c| theirs.reaction[[j, c]]);
        for &g in &d.dofs.fixed {
            theirs_r[g as usize % 3] -= f[j][g as usize];
        }
        let norm = |v: [f64; 3]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
        let rel = displacement_gap(gap, scale);
        out.push(LoadComparison {
            name: case.name.clone(),
            kind: case.applied.kind(),
            max_displacement_m: ours[j]
                .chunks_exact(3)
                .map(|v| norm([v[0], v[1], v[2]]))
                .fold(0.0, f64::max),
            displacement_rel_diff: rel,
            reaction_n: reaction,
            reference_reaction_n: theirs_r,
            reaction_rel_diff: norm([0, 1, 2].map(|c| reaction[c] - theirs_r[c]))
                / norm(theirs_r).max(f64::MIN_POSITIVE),
            tolerance,
            pass: rel <= tolerance,
        });
    }
    Ok(out)
}

/// A nonlinear scene's load cases are compared with the reference's geometrically nonlinear
/// solve (CalculiX `*STEP, NLGEOM`): the reduced model differs from the full one by what its
/// basis leaves out: on the soft cantilever up to PL²/EI = 3 at most 0.71 %, on the soft block
/// pressed by 12 % 0.23 % (max-norm displacement).
pub const NONLINEAR_TOLERANCE: f64 = 0.03;

/// The nonlinear model's response to each load (as `ves precompute` makes it: modes,
/// derivatives, reduced equilibrium) with the full internal force at it.
fn nonlinear_responses(
    scene: &Scene,
    d: &Discretized,
    derivatives: usize,
    f: &[Vec<f64>],
) -> Result<Vec<(Vec<f64>, Vec<f64>)>> {
    let (mut modes, _) = crate::modes::solve(d.space(), scene.modes.count, crate::modes::SolverChoice::Auto)?;
    let model = crate::nonlinear::enrich(d, &mut modes, derivatives, f)?;
    let basis = crate::nonlinear::full_columns(d, &modes);
    let points = crate::fem::stvk::Points::of(&d.mesh)?;
    // The reactions as `ves precompute` reports them: after one Newton step of the full model.
    let chol = crate::linsolve::factor_stiffness(&d.system, &d.dofs)?;
    let springs = crate::supports::springs(&d.mesh, &scene.fixed, scene.material.young)?;
    let lame = crate::fem::element::Lame::of(&scene.material);
    f.iter()
        .zip(&scene.loads)
        .map(|(f, case)| {
            let (u, internal, _) = crate::nonlinear::static_response(d, &model, &basis, f, &points)
                .map_err(|e| e.context(format!("load case {}", case.name)))?;
            let (_, reacting) = crate::loads::one_newton_step(d, &lame, &chol, &springs, f, &u, &internal)?;
            Ok((u, reacting))
        })
        .collect()
}

/// The reference's solution of the load cases `f` (one full-DOF vector each), in a private work
/// folder, its shapes checked.
fn solve_theirs(
    input: &str,
    scene: &Scene,
    d: &Discretized,
    reference: &dyn Reference,
    f: &[Vec<f64>],
) -> Result<super::reference::LoadSolution, VerifyError> {
    let tmp = crate::workdir::WorkDir::new("verify-loads").map_err(|source| VerifyError::WorkDir {
        what: reference.label(),
        source,
    })?;
    let problem = tmp.path().join("loads.h5");
    write_problem(&problem, d, scene, f)?;
    let solved = reference.solve_loads(&LoadJob {
        input,
        problem: &problem,
        dir: tmp.path(),
    });
    if std::env::var_os("VES_KEEP_VERIFY").is_some() {
        eprintln!(
            "{}'s load-case files kept in {}",
            reference.label(),
            tmp.keep().display()
        );
    }
    let theirs = solved?;
    let n3 = 3 * d.mesh.nodes.len();
    if theirs.displacement.shape() != [f.len(), n3] || theirs.reaction.shape() != [f.len(), 3] {
        return Err(VerifyError::Unusable {
            path: theirs.source.clone(),
            detail: format!(
                "{}'s static results have shapes {:?} and {:?}, expected [{}, {n3}] and [{}, 3]",
                reference.label(),
                theirs.displacement.shape(),
                theirs.reaction.shape(),
                f.len(),
                f.len()
            ),
        });
    }
    Ok(theirs)
}

/// The relative max-norm difference (NaN, never a pass, when either field is not finite).
fn displacement_gap(gap: f64, scale: f64) -> f64 {
    if gap.is_finite() && scale.is_finite() {
        gap / scale
    } else {
        f64::NAN
    }
}

/// The load cases' problem as a reference reads it: the mesh, supports, nodal loads and the
/// elastic constants.
fn write_problem(path: &Path, d: &Discretized, scene: &Scene, loads: &[Vec<f64>]) -> Result<(), VerifyError> {
    let write = || -> hdf5::Result<()> {
        let f = ves_format::file::create(path, false)?;
        super::write_mesh(&f, d)?;
        let n = d.mesh.nodes.len();
        f.new_dataset_builder()
            .with_data(&Array2::from_shape_fn((loads.len(), 3 * n), |(j, i)| loads[j][i]))
            .create("loads")?;
        for (k, v) in [("young", scene.material.young), ("poisson", scene.material.poisson)] {
            f.new_attr::<f64>().create(k)?.write_scalar(&v)?;
        }
        let nlgeom = u32::from(scene.nonlinear.is_some());
        f.new_attr::<u32>().create("nlgeom")?.write_scalar(&nlgeom)?;
        Ok(())
    };
    super::seal_problem(path, write)
}
