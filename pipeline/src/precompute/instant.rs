//! An instant basis: when only the supports, the material or the mode count change, the part's
//! mesh is the one the previous basis holds, and its modes are a good start. No meshing, no
//! refinement, no converged eigen-solve: the previous basis's mesh is read back, K and M
//! assembled for the new supports, and the modes found in a few block solves from the previous
//! ones ([`crate::modes::warm`]), each with a bound on its error. The converged compute follows
//! and replaces it.

use super::{Summary, stages, write_all};
use crate::fem::Dofs;
use crate::scene::Scene;
use anyhow::{Context, Result};
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// Krylov stages beyond the start (on a bar moved between supports, 3 gave eigenvalue errors
/// ≤ 8.5e-4: numerics' warm tests).
const BLOCKS: usize = 3;

/// How an instant basis was made and how far it may be from the converged one.
#[derive(Clone, Debug, Serialize)]
pub struct InstantCheck {
    /// The basis whose mesh and modes it started from.
    pub from: String,
    /// Per mode, a rigorous bound on the relative frequency error against the converged solve
    /// on the same mesh (half the eigenvalue bound, to first order).
    pub frequency_bound: Vec<f64>,
    /// Per mode, the expected relative frequency change when the converged modes arrive
    /// (Kato–Temple, the Ritz gaps standing in for the exact ones).
    pub frequency_estimate: Vec<f64>,
    /// Right-hand sides solved with the one factor.
    pub solves: usize,
    /// Vectors in the space searched.
    pub basis: usize,
    /// Whether the scene refines to a target error: the converged compute may then choose
    /// another mesh, whose frequencies the bound does not cover.
    pub mesh_may_change: bool,
}

impl InstantCheck {
    /// What the bound says, in words, for a summary line.
    pub fn text(&self) -> String {
        let largest = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
        if self.solves == 0 {
            return format!(
                "the previous modes rescaled exactly to the new material (the same Poisson's ratio, mesh and supports): \
                 no solve, frequencies within {:.1e} from the modes' residuals{}",
                largest(&self.frequency_bound),
                if self.mesh_may_change {
                    "; the converged compute refines to the target error and may choose a finer mesh"
                } else {
                    ""
                }
            );
        }
        format!(
            "frequencies at most {:.3} % above the converged solve's on this mesh (expected {:.3} %){}",
            100.0 * largest(&self.frequency_bound),
            100.0 * largest(&self.frequency_estimate),
            if self.mesh_may_change {
                "; the converged compute refines to the target error and may choose a finer mesh, which the bound does not cover"
            } else {
                ""
            }
        )
    }
}

/// Why no instant basis: the scene changed more than supports, material or modes, or the
/// previous basis cannot serve. Not an error: the converged compute runs as always.
pub fn applicable(scene: &Scene, previous_scene: &str) -> Result<(), String> {
    if !scene.voi.is_empty() {
        return Err("the scene has volumes of interest".into());
    }
    let table = |text: &str| toml::from_str::<toml::Table>(text).map_err(|e| e.to_string());
    let (now, before) = (table(&scene.toml)?, table(previous_scene)?);
    for key in ["geometry", "mesh", "voi"] {
        if now.get(key) != before.get(key) {
            return Err(format!("[{key}] changed"));
        }
    }
    Ok(())
}

/// Writes to `out` an instant basis of `scene` from the basis `previous` (same geometry and
/// mesh settings: see [`applicable`]); None, with the reason in the log, when it cannot.
pub fn run(scene: &Scene, previous: &Path, out: &Path) -> Result<Option<(Summary, InstantCheck)>> {
    let start = Instant::now();
    crate::output::check(out, &scene.inputs(), Default::default())?;
    let stored = crate::store::read_global(previous, None)?;
    tracing::info!(seconds = start.elapsed().as_secs_f64(), "instant: previous basis read");
    let before = stored.scene_toml.as_deref().unwrap_or_default();
    if let Err(why) = applicable(scene, before) {
        tracing::info!("no instant basis: {why}");
        return Ok(None);
    }
    let scale = material_scale(scene, before, &stored);
    crate::progress::stage("assembling on the previous mesh", 0.1)?;
    let t = Instant::now();
    let mesh = stored.mesh;
    // The mesh's ordering, kept when it was made (or by the last basis on it), is not made again.
    crate::mesh::keep_orderings();
    let dofs = crate::supports::select(&mesh, &scene.fixed)?;
    let springs: Vec<_> = crate::supports::springs(&mesh, &scene.fixed, scene.material.young)?
        .into_iter()
        .flatten()
        .collect();
    let model = crate::modes::Model::assemble_with(mesh, dofs, scene.material, &springs)
        .with_context(|| format!("{}: assembling on its mesh", previous.display()))?;
    let d = crate::problem::Discretized {
        model,
        mesh_s: 0.0,
        meshing: Default::default(),
        assemble_s: 0.0,
    };
    let assemble_s = t.elapsed().as_secs_f64();
    let start_vectors = carried(&stored.rows, stored.r, &d.dofs);
    crate::progress::stage("instant modes", 0.4)?;
    let warm = match scale {
        Some((lambda, phi)) => {
            // The same mesh, supports and Poisson's ratio: the previous modes, scaled, exactly.
            let count = scene.modes.count;
            let eigenvalues = stored.eigenvalues[..count].iter().map(|l| l * lambda).collect();
            let n = d.dofs.free_count();
            let vectors = start_vectors[..n * count].iter().map(|v| v * phi).collect();
            crate::modes::warm::scaled(d.space(), eigenvalues, vectors)?
        }
        None => crate::modes::warm::warm_start(d.space(), scene.modes.count, &start_vectors, BLOCKS)?,
    };
    drop(start_vectors);
    let check = InstantCheck {
        from: previous.display().to_string(),
        frequency_bound: warm.bounds.iter().map(|b| 0.5 * b).collect(),
        frequency_estimate: warm.estimates.iter().map(|e| 0.5 * e).collect(),
        solves: warm.solves,
        basis: warm.basis,
        mesh_may_change: scene.mesh.target_error.is_some(),
    };
    let mut d = d;
    d.assemble_s = assemble_s;
    tracing::info!(seconds = start.elapsed().as_secs_f64(), "instant: modes found");
    let space = stages::space_from_modes(scene, d, warm.modes, warm.stiffness_factor.as_ref())?;
    drop(warm.stiffness_factor);
    tracing::info!(seconds = start.elapsed().as_secs_f64(), "instant: patches and stress");
    crate::progress::stage("writing", 0.9)?;
    let summary = write_all(scene, out, std::slice::from_ref(&space), 0.0, start)?;
    Ok(Some((summary, check)))
}

/// When `scene` differs from the previous basis's (`before`, its TOML) in its material's Young's
/// modulus or density alone — the same supports (no elastic mount if E changed), the same
/// Poisson's ratio, no more modes than stored — its modes are the stored ones scaled exactly (K ∝ E, M ∝ ρ): the factors of the
/// eigenvalues, E'/E·ρ/ρ', and of the M-normalised vectors, √(ρ/ρ').
fn material_scale(scene: &Scene, before: &str, stored: &crate::store::StoredSpace) -> Option<(f64, f64)> {
    let (now, then) = (
        toml::from_str::<toml::Table>(&scene.toml).ok()?,
        toml::from_str::<toml::Table>(before).ok()?,
    );
    let (m, was) = (&scene.material, &stored.material);
    // An elastic mount's springs are given in N/m³, not in E: K then scales with E no more.
    let mounts = scene
        .fixed
        .iter()
        .any(|f| matches!(f.kind, crate::scene::SupportKind::Elastic { .. }));
    let same = now.get("fixed") == then.get("fixed")
        && m.poisson == was.poisson
        && (m.young == was.young || !mounts)
        && scene.modes.count <= stored.r
        && stored.eigenvalues.len() == stored.r;
    same.then(|| {
        (
            (m.young / was.young) * (was.density / m.density),
            (was.density / m.density).sqrt(),
        )
    })
}

/// The stored modes (row-major `3·nodes × r`) on `dofs`' free DOFs, column-major.
fn carried(rows: &[f64], r: usize, dofs: &Dofs) -> Vec<f64> {
    (0..r)
        .flat_map(|j| dofs.free.iter().map(move |&g| rows[g as usize * r + j]))
        .collect()
}
