//! Static correction on the ribplate: a lateral force at each rib tip (the scene's probes),
//! 30 modes, against the full sparse solve K u = F on the same mesh — in the global space and
//! in each rib's refined VOI space, where the coarse space's error is also measured against the
//! refined mesh's full solve.

use ves_pipeline::compliance::Compliance;
use ves_pipeline::linsolve::factor_stiffness;
use ves_pipeline::modes::{SolverChoice, solve};
use ves_pipeline::problem::{Discretized, discretize};
use ves_pipeline::scene::{CorrectionRegion, Scene, StaticCorrection};
use ves_tests::{case_path, load_case};

/// Tip responses on one space: (exact K⁻¹F, modal Σφφᵀ F/λ with 30 modes, corrected G F), m.
struct Tip {
    exact: [f64; 3],
    modal: [f64; 3],
    corrected: [f64; 3],
}

struct Space {
    d: Discretized,
    modes: ves_pipeline::modes::Modes,
    compliance: Compliance,
}

fn space(scene: &Scene, voi: Option<&str>) -> Space {
    let voi = voi.map(|n| scene.voi.iter().find(|v| v.name == n).expect("voi"));
    let d = discretize(scene, voi).expect("discretize");
    let (modes, _) = solve(&d, 30, SolverChoice::Arpack).expect("modes");
    let compliance = ves_pipeline::compliance::surface_compliance(&d).expect("compliance");
    Space { d, modes, compliance }
}

fn nearest_vertex(d: &Discretized, at: [f64; 3]) -> usize {
    (0..d.mesh.vertex_count)
        .min_by(|&a, &b| {
            let dist = |i: usize| (0..3).map(|c| (d.mesh.nodes[i][c] - at[c]).powi(2)).sum::<f64>();
            dist(a).total_cmp(&dist(b))
        })
        .expect("vertices")
}

fn tip(s: &Space, at: [f64; 3], dir: [f64; 3]) -> Tip {
    let d = &s.d;
    let nf = d.dofs.free_count();
    let node = nearest_vertex(d, at);
    let free = |c: usize| d.dofs.free_of[3 * node + c] as usize;
    let mut x = vec![0.0; nf];
    for c in 0..3 {
        x[free(c)] = dir[c];
    }
    factor_stiffness(&d.system, &d.dofs)
        .expect("factor")
        .solve_many_in_place(&mut x, 1);
    let exact = [0, 1, 2].map(|c| x[free(c)]);
    // Truncated modal response Σ φφᵀF/λ; the corrected one adds (G − ΦΛ⁻¹Φᵀ)F, i.e. is G F.
    let mut modal = [0.0; 3];
    for (j, lambda) in s.modes.eigenvalues.iter().enumerate() {
        let v = &s.modes.vectors[j * nf..(j + 1) * nf];
        let phi = [0, 1, 2].map(|c| v[free(c)]);
        let fj = (0..3).map(|c| phi[c] * dir[c]).sum::<f64>();
        for c in 0..3 {
            modal[c] += phi[c] * fj / lambda;
        }
    }
    let block = s.compliance.blocks[s
        .compliance
        .nodes
        .binary_search(&(node as u32))
        .expect("tip on the surface")];
    let corrected = [0, 1, 2].map(|a| (0..3).map(|b| block[a][b] * dir[b]).sum::<f64>());
    Tip {
        exact,
        modal,
        corrected,
    }
}

fn rel(u: [f64; 3], exact: [f64; 3]) -> f64 {
    let norm = exact.iter().map(|v| v * v).sum::<f64>().sqrt();
    (0..3).map(|c| (u[c] - exact[c]).powi(2)).sum::<f64>().sqrt() / norm
}

fn with_correction(mut scene: Scene) -> Scene {
    scene.static_correction = Some(StaticCorrection {
        region: CorrectionRegion::Surface,
    });
    scene
}

#[test]
fn rib_tip_displacement_is_exact_with_correction_and_reported_without() {
    let _serial = ves_tests::serial();
    let scene = with_correction(load_case("ribplate"));
    assert_eq!(scene.probes.len(), 4, "one probe per rib");
    let global = space(&scene, None);
    for (k, p) in scene.probes.iter().enumerate() {
        let t = tip(&global, p.at, p.force);
        let (e_modal, e_corr) = (rel(t.modal, t.exact), rel(t.corrected, t.exact));
        println!(
            "rib {}: |u| {:.4e} m/N, 30 modes error {:.2} %, with static correction {e_corr:.1e}",
            k + 1,
            t.exact.iter().map(|v| v * v).sum::<f64>().sqrt(),
            100.0 * e_modal
        );
        assert!(e_corr < 1e-8, "corrected {e_corr}");
        assert!(e_modal > 1e-3, "30 modes alone should miss some compliance: {e_modal}");
    }
}

/// Each rib's VOI space: the corrected tip response equals the full solve on the refined mesh;
/// the coarse global space, even corrected, carries its discretisation error against it.
#[test]
fn rib_tip_in_its_voi_space_against_the_refined_full_solve() {
    let _serial = ves_tests::serial();
    let scene = with_correction(Scene::load(&case_path("ribplate/scene-voi.toml")).expect("scene"));
    let global = space(&scene, None);
    for (k, p) in scene.probes.iter().enumerate() {
        let name = format!("rib{}", k + 1);
        let refined = space(&scene, Some(&name));
        let fine = tip(&refined, p.at, p.force);
        let coarse = tip(&global, p.at, p.force);
        let (e_modal, e_corr) = (rel(fine.modal, fine.exact), rel(fine.corrected, fine.exact));
        let (c_modal, c_corr) = (rel(coarse.modal, fine.exact), rel(coarse.corrected, fine.exact));
        println!(
            "{name}: refined |u| {:.4e} m/N; VOI space 30 modes {:.2} %, corrected {e_corr:.1e}; \
             global space 30 modes {:.2} %, corrected {:.2} % (coarse full solve {:.2} %)",
            fine.exact.iter().map(|v| v * v).sum::<f64>().sqrt(),
            100.0 * e_modal,
            100.0 * c_modal,
            100.0 * c_corr,
            100.0 * rel(coarse.exact, fine.exact),
        );
        assert!(e_corr < 1e-8, "{name}: corrected {e_corr}");
        // The refined mesh is softer at the tip: the coarse space underestimates the response.
        let norm = |u: [f64; 3]| u.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!(
            norm(coarse.exact) < norm(fine.exact),
            "{name}: refinement must soften the tip"
        );
    }
}
