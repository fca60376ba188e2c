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
    let ours = solve_static(d, &f)?;
    let lame = crate::fem::element::Lame::of(&scene.material);
    let theirs = solve_theirs(input, scene, d, reference, &f)?;
    let curved = !d.mesh.curved_tets().is_empty();
    let tolerance = tol.unwrap_or(reference.tolerances(d.mesh.kind.order(), curved).load);
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
        let k_u =
            crate::loads::vector::internal_forces(&d.mesh, &lame, &ours[j]).map_err(|e| VerifyError::Degenerate {
                input: input.to_string(),
                det: e.det,
            })?;
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
        Ok(())
    };
    super::seal_problem(path, write)
}
