//! What precompute tells the user about a solved space: the error estimate's verdict (and what
//! to change), thin walls, and the Sturm count's.

use crate::modes::SturmCount;
use crate::scene::Scene;
use crate::tet_mesh::Mesh;

/// One line when a space has no estimate or one above [`crate::accuracy::WARN_ABOVE`], and one
/// when its walls are one element thick and the estimate does not vouch for them.
pub(super) fn warn_about_error(
    scene: &Scene,
    name: &str,
    mesh: &Mesh,
    size: f64,
    error: Option<&crate::accuracy::ErrorEstimate>,
) {
    let worst = error.and_then(|e| crate::accuracy::worst(&e.relative()));
    let walls = mesh.walls();
    if walls.spanning_fraction > crate::mesh::walls::ONE_ELEMENT_THICK {
        // The coarser meshes are one element thick too, so the Richardson estimate cannot see
        // this (the cantilever at 50 mm: 0.85 %, 3.1 % off the 25 mm mesh); the recovery
        // estimate on the mesh itself is taken instead, measured within 0.7–1.2× on the 200:1
        // plate with 10-node tets (docs/accuracy.md).
        tracing::warn!(
            "space {name:?}: {:.0} % of the volume is in walls one element thick (walls ≈ {:.2e} m): bending across \
             them rests on one element and the coarser meshes of the error estimate cannot see that (the estimate \
             is the recovery one on this mesh); check with mesh.size ≤ {:.2e} m (two through the wall){}",
            100.0 * walls.spanning_fraction,
            walls.thickness,
            walls.thickness / 2.0,
            if scene.mesh.kind() == crate::fem::element::Kind::Tet4 {
                " and mesh.order = 2"
            } else {
                ""
            }
        );
    }
    if error.is_some() && scene.material.poisson > crate::accuracy::NEARLY_INCOMPRESSIBLE {
        tracing::warn!(
            "space {name:?}: material.poisson = {} is nearly incompressible: the error estimate is a rough guide \
             (marked unreliable){}; check with a mesh 1.5× finer",
            scene.material.poisson,
            if scene.mesh.kind() == crate::fem::element::Kind::Tet4 {
                ", and 4-node tets lock: use mesh.order = 2"
            } else {
                ""
            }
        );
    }
    match worst {
        None => tracing::warn!(
            space = name,
            "no error estimate: no coarser mesh of this space could be solved (see VES_LOG=info)"
        ),
        Some((mode, worst)) if worst > crate::accuracy::WARN_ABOVE => {
            let change = if scene.mesh.kind() == crate::fem::element::Kind::Tet4 {
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

/// One line on the Sturm count: info when no mode was skipped, a warning with the likely cause
/// otherwise.
pub(super) fn report_sturm(name: &str, s: &SturmCount) {
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

/// A solve that would not fit in memory, told with the mesh size that would (the scene's
/// `mesh.size` scaled by [`crate::memory::OutOfMemory::coarsening`]); any other error as it is.
pub(super) fn memory(e: crate::modes::ModesError, scene: &Scene) -> anyhow::Error {
    use crate::linsolve::FactorError;
    use crate::modes::ModesError;
    match (&e, scene.mesh.size) {
        (ModesError::Factor(FactorError::Memory(m)), size) if size > 0.0 => anyhow::anyhow!(
            "{m}: set mesh.size = {:.3e} m or more (now {size:.3e} m; a 3D factor grows about as size⁻⁴), \
             or free memory ({} caps what a run may take)",
            size * m.coarsening(),
            crate::memory::CAP_VAR
        ),
        _ => e.into(),
    }
}
