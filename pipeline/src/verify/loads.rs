//! `ves verify` of a scene's static load cases: the same mesh, supports and nodal loads through
//! CalculiX `*STATIC` (one deck per case, `*CLOAD` at every loaded DOF), and how far our
//! displacement field and support reaction are from its.

use super::run_checked;
use crate::loads::{load_vectors, solve_static};
use crate::problem::Discretized;
use crate::scene::Scene;
use anyhow::{Context, Result};
use ndarray::Array2;
use serde::Serialize;
use std::path::Path;
use std::process::Command;

const CCX_STATIC: &str = include_str!("ccx_static.py");

/// Default tolerance of the relative max-norm displacement difference with CalculiX on
/// straight-sided elements (4-node tets, or 10-node tets whose mid-edge nodes sit on their
/// edges): both solve the same discrete problem exactly, and CalculiX prints 7 significant
/// digits (its .dat file), a rounding of at most 5e-7 of each value.
pub const LOAD_TOLERANCE: f64 = 1e-6;

/// On curved 10-node tets CalculiX integrates the stiffness with 4 points (exact only on straight
/// ones), VES with a degree-5 rule: the fields differ by up to about 1e-3 (as the modes do,
/// `Tolerances::resolve`).
pub const LOAD_TOLERANCE_CURVED: f64 = 1e-3;

/// One load case compared with CalculiX.
#[derive(Debug, Serialize)]
pub struct LoadComparison {
    /// The case's name.
    pub name: String,
    /// `force`, `pressure` or `gravity`.
    pub kind: &'static str,
    /// Largest displacement magnitude, ours, m.
    pub max_displacement_m: f64,
    /// max over DOFs |u_ours − u_ccx| / max over DOFs |u_ccx|.
    pub displacement_rel_diff: f64,
    /// Our total support reaction, N.
    pub reaction_n: [f64; 3],
    /// CalculiX's: its `RF` totals over the supported nodes less the loads applied at supported
    /// DOFs (which its `RF` leaves out), N.
    pub reference_reaction_n: [f64; 3],
    /// |ours − CalculiX's| / |CalculiX's| of the reactions (CalculiX's 7 digits).
    pub reaction_rel_diff: f64,
    /// The tolerance applied to `displacement_rel_diff`.
    pub tolerance: f64,
    /// Within it.
    pub pass: bool,
}

/// Compares every load case of `scene` on `d` with CalculiX; `tol` overrides the default
/// tolerance. The solver is named in `solver`.
pub fn compare_loads(input: &str, scene: &Scene, d: &Discretized, tol: Option<f64>) -> Result<Vec<LoadComparison>> {
    if scene.loads.is_empty() {
        return Ok(Vec::new());
    }
    let f = load_vectors(scene, d)?;
    let ours = solve_static(d, &f)?;
    let m = &scene.material;
    let lame = crate::fem::element::Lame::of(m);
    let tmp =
        crate::workdir::WorkDir::new("verify-loads").context("cannot create a temporary directory for CalculiX")?;
    let (problem, result) = (tmp.path().join("loads.h5"), tmp.path().join("ccx_loads.h5"));
    write_problem(&problem, d, scene, &f)?;
    crate::workdir::seal(&problem)?;
    let script = tmp.path().join("ccx_static.py");
    crate::workdir::write(&script, CCX_STATIC.as_bytes())?;
    // It writes the mesh and supports with the modal reference's functions.
    crate::workdir::write(&tmp.path().join("ccx_ref.py"), super::CCX.as_bytes())?;
    let ran = run_checked(
        input,
        "ccx_static.py",
        Command::new("python3")
            .arg(&script)
            .arg(&problem)
            .arg(&result)
            .arg(tmp.path()),
    );
    if std::env::var_os("VES_KEEP_VERIFY").is_some() {
        eprintln!("CalculiX's load-case files kept in {}", tmp.keep().display());
    }
    ran?;
    let r = ves_format::file::open(&result).context("reading CalculiX's static results")?;
    let theirs: Array2<f64> = r.dataset("displacement")?.read_2d()?;
    let reactions: Array2<f64> = r.dataset("reaction")?.read_2d()?;
    let n3 = 3 * d.mesh.nodes.len();
    if theirs.shape() != [f.len(), n3] || reactions.shape() != [f.len(), 3] {
        anyhow::bail!(
            "{input}: CalculiX's static results have shapes {:?} and {:?}, expected [{}, {n3}] and [{}, 3]",
            theirs.shape(),
            reactions.shape(),
            f.len(),
            f.len()
        );
    }
    let tolerance = tol.unwrap_or(if d.mesh.curved_tets().is_empty() {
        LOAD_TOLERANCE
    } else {
        LOAD_TOLERANCE_CURVED
    });
    let mut out = Vec::new();
    for (j, case) in scene.loads.iter().enumerate() {
        let ccx = theirs.row(j);
        let scale = ccx.iter().fold(0.0f64, |a, v| a.max(v.abs())).max(f64::MIN_POSITIVE);
        let gap = ours[j].iter().zip(ccx).fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
        let k_u = crate::loads::vector::internal_forces(&d.mesh, &lame, &ours[j])
            .map_err(|e| anyhow::anyhow!("{input}: an element is degenerate (det J = {:.3e})", e.det))?;
        let mut reaction = [0.0; 3];
        for &g in &d.dofs.fixed {
            reaction[g as usize % 3] += k_u[g as usize] - f[j][g as usize];
        }
        // CalculiX's RF at a supported DOF is its internal force K u there; the load applied at
        // that DOF goes straight into the support, so the support's force on the part is RF − f.
        let mut theirs_r = [0, 1, 2].map(|c| reactions[[j, c]]);
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

/// The relative max-norm difference (NaN, never a pass, when either field is not finite).
fn displacement_gap(gap: f64, scale: f64) -> f64 {
    if gap.is_finite() && scale.is_finite() {
        gap / scale
    } else {
        f64::NAN
    }
}

fn write_problem(path: &Path, d: &Discretized, scene: &Scene, loads: &[Vec<f64>]) -> Result<()> {
    let f = ves_format::file::create(path, false).with_context(|| format!("cannot create {}", path.display()))?;
    super::write_mesh(&f, d)?;
    let n = d.mesh.nodes.len();
    f.new_dataset_builder()
        .with_data(&Array2::from_shape_fn((loads.len(), 3 * n), |(j, i)| loads[j][i]))
        .create("loads")?;
    for (k, v) in [("young", scene.material.young), ("poisson", scene.material.poisson)] {
        f.new_attr::<f64>().create(k)?.write_scalar(&v)?;
    }
    Ok(())
}
