//! Static correction on the ribplate: a lateral force at each rib tip, 30 modes, against the full
//! sparse solve K u = F on the same mesh.

use ves_pipeline::linsolve::factor_stiffness;
use ves_pipeline::precompute::{SolverChoice, Timings, discretize, solve};
use ves_pipeline::scene::{CorrectionRegion, StaticCorrection};
use ves_tests::load_case;

#[test]
fn rib_tip_displacement_is_exact_with_correction_and_reported_without() {
    let mut scene = load_case("ribplate");
    scene.static_correction = Some(StaticCorrection {
        region: CorrectionRegion::Surface,
    });
    let d = discretize(&scene, None, &mut Timings::default()).expect("discretize");
    let (modes, _) = solve(&d, 30, SolverChoice::Arpack).expect("modes");
    let compliance = ves_pipeline::compliance::surface_compliance(&d).expect("compliance");
    let chol = factor_stiffness(&d.system, &d.dofs).expect("factor");
    let nf = d.dofs.free_count();
    // Rib tips (top centres, metres) and a lateral unit force across each rib.
    let tips = [
        ([0.050, 0.024, 0.048], [0.0, 1.0, 0.0]),
        ([0.150, 0.024, 0.038], [0.0, 1.0, 0.0]),
        ([0.024, 0.120, 0.058], [1.0, 0.0, 0.0]),
        ([0.145, 0.1125, 0.043], [1.0, 0.0, 0.0]),
    ];
    for (k, (at, dir)) in tips.iter().enumerate() {
        let node = (0..d.mesh.vertex_count)
            .min_by(|&a, &b| {
                let dist = |i: usize| (0..3).map(|c| (d.mesh.nodes[i][c] - at[c]).powi(2)).sum::<f64>();
                dist(a).total_cmp(&dist(b))
            })
            .expect("vertices");
        let mut f = vec![0.0; nf];
        for c in 0..3 {
            f[d.dofs.free_of[3 * node + c] as usize] = dir[c];
        }
        let mut x = f.clone();
        chol.solve_many_in_place(&mut x, 1);
        let exact: Vec<f64> = (0..3).map(|c| x[d.dofs.free_of[3 * node + c] as usize]).collect();
        // Truncated modal response Σ φφᵀF/λ, and the correction (G − ΦΛ⁻¹Φᵀ)F on top.
        let mut modal = [0.0; 3];
        for (j, lambda) in modes.eigenvalues.iter().enumerate().take(30) {
            let v = &modes.vectors[j * nf..(j + 1) * nf];
            let phi: [f64; 3] = std::array::from_fn(|c| v[d.dofs.free_of[3 * node + c] as usize]);
            let fj = (0..3).map(|c| phi[c] * dir[c]).sum::<f64>();
            for c in 0..3 {
                modal[c] += phi[c] * fj / lambda;
            }
        }
        let block = compliance.blocks[compliance
            .nodes
            .binary_search(&(node as u32))
            .expect("tip on the surface")];
        let corrected: Vec<f64> = (0..3)
            .map(|a| (0..3).map(|b| block[a][b] * dir[b]).sum::<f64>())
            .collect();
        let norm = exact.iter().map(|v| v * v).sum::<f64>().sqrt();
        let err = |u: &[f64]| (0..3).map(|c| (u[c] - exact[c]).powi(2)).sum::<f64>().sqrt() / norm;
        let (e_modal, e_corr) = (err(&modal), err(&corrected));
        println!(
            "rib {}: |u| {norm:.4e} m/N, 30 modes error {:.2} %, with static correction {e_corr:.1e}",
            k + 1,
            100.0 * e_modal
        );
        assert!(e_corr < 1e-8, "corrected {e_corr}");
    }
}
