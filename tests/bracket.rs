//! The free bracket: six rigid modes found and dropped, and the sparse shift-invert path
//! equal to an independent dense generalized solve on the same mesh.

use ves_pipeline::modes::{SolverChoice, solve};
use ves_pipeline::problem::discretize;
use ves_tests::load_case;

#[test]
fn free_bracket_drops_six_rigid_modes_and_arpack_equals_dense() {
    let scene = load_case("bracket");
    let d = discretize(&scene, None).expect("bracket discretizes");
    assert!(d.dofs.fixed.is_empty(), "the bracket is a free body");
    assert_eq!(d.rigid, 6);
    let count = scene.modes.count;
    let (sparse, _) = solve(d.space(), count, SolverChoice::Arpack).expect("ARPACK solves");
    let (dense, _) = solve(d.space(), count, SolverChoice::Dense).expect("dense solves");
    for m in [&sparse, &dense] {
        assert_eq!(m.rigid_dropped, 6);
        assert_eq!(m.eigenvalues.len(), count);
        assert!(m.residuals.iter().all(|&r| r <= 1e-8), "residuals {:?}", m.residuals);
        assert!(m.orthonormality_error <= 1e-10);
    }
    // First elastic mode far above the rigid ones: they were really set apart, not truncated.
    assert!(sparse.eigenvalues[0] > 1e6);
    for (i, (a, b)) in sparse.eigenvalues.iter().zip(&dense.eigenvalues).enumerate() {
        assert!((a - b).abs() <= 1e-8 * b, "mode {i}: ARPACK {a} vs dense {b}");
    }

    // Mass properties against the CAD solid: 80×60×8 base + 8×60×52 upright − Ø20 hole
    // through the 8 mm upright. The faceted hole is a polygon inscribed in the circle, so the
    // meshed volume is slightly larger; 0.5 % bounds it at this mesh size.
    let mm3 = 80.0 * 60.0 * 8.0 + 8.0 * 60.0 * 52.0 - std::f64::consts::PI * 100.0 * 8.0;
    let mass = scene.material.density * mm3 * 1e-9;
    let got = d.system.mass.mass;
    assert!((got - mass).abs() < 5e-3 * mass, "mass {got} vs {mass}");
    assert!((d.system.mass.center[1] - 0.030).abs() < 1e-6, "symmetric in y");
    let inertia = d.system.mass.inertia;
    for i in 0..3 {
        assert!(inertia[i][i] > 0.0);
        for j in 0..3 {
            assert!((inertia[i][j] - inertia[j][i]).abs() < 1e-12 * inertia[0][0]);
        }
    }
}
