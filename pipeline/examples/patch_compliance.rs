//! The compliance a hand feels at a scene's `[[probe]]` points, on several meshes: the force
//! spread over the scene's contact patch (`[contact] radius`) and, beside it, on one vertex.
//! Shows that the patch's compliance converges under refinement while the point's does not
//! (docs/accuracy.md "The felt stiffness"). Each probe gets its own meshes: the scene's size
//! everywhere and SIZE inside a box of ±3 radii around the probe (gmsh's box field, as a
//! `[[voi]]` is meshed), so the contact zone is refined without refining the whole part.
//!
//! Usage: cargo run --release -p ves-pipeline --features slepc --example patch_compliance --
//! SCENE SIZE [SIZE …]   (sizes in metres; prints one JSON line per probe and size)

use anyhow::{Context, Result};
use ves_pipeline::loads::patch::Surface;
use ves_pipeline::scene::Scene;

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (path, sizes) = args
        .split_first()
        .context("usage: patch_compliance SCENE SIZE [SIZE …]")?;
    let scene = Scene::load(std::path::Path::new(path))?;
    anyhow::ensure!(!scene.probes.is_empty(), "{path}: add [[probe]] points (at, force)");
    let sizes: Vec<f64> = sizes
        .iter()
        .map(|s| s.parse().with_context(|| format!("size {s:?}: give metres")))
        .collect::<Result<_>>()?;
    let reach = 3.0 * scene.contact_radius.max(scene.mesh.size / 4.0);
    for (k, p) in scene.probes.iter().enumerate() {
        let n = nalgebra::Vector3::from(p.force).normalize();
        for &size in &sizes {
            let mut s = scene.clone();
            s.mesh.target_error = None;
            let voi = ves_pipeline::scene::Voi {
                name: "contact".into(),
                bbox: ves_pipeline::scene::BoxRegion {
                    min: p.at.map(|c| c - reach),
                    max: p.at.map(|c| c + reach),
                },
                size,
            };
            let t = std::time::Instant::now();
            let d = ves_pipeline::problem::discretize(&s, Some(&voi))?;
            let chol = ves_pipeline::linsolve::factor_stiffness(&d.system, &d.dofs)?;
            let surface = Surface::new(&d.mesh);
            let mut felt = Vec::new();
            for radius in [scene.contact_radius, 0.0] {
                let (patch, _, _) = surface.at_point(p.at, radius).context("no surface")?;
                let block = ves_pipeline::compliance::patch_blocks(
                    &d.dofs,
                    &chol,
                    &[(patch.nodes.as_slice(), patch.weights.as_slice())],
                    || (),
                )?[0];
                let g = nalgebra::Matrix3::from_fn(|a, b| block[a][b]);
                felt.push((n.transpose() * g * n)[0]);
            }
            let line = serde_json::json!({
                "probe": k,
                "at": p.at,
                "direction": n.as_slice(),
                "size_m": size,
                "far_size_m": scene.mesh.size,
                "order": scene.mesh.order,
                "radius_m": scene.contact_radius,
                "unknowns": d.dofs.free_count(),
                "seconds": t.elapsed().as_secs_f64(),
                "patch_m_per_n": felt[0],
                "point_m_per_n": felt[1],
            });
            println!("{line}");
        }
    }
    Ok(())
}
