//! Invariants of the assembled system on real meshes.

use ves_pipeline::linsolve::sym_matvec;
use ves_pipeline::precompute::{Timings, discretize};
use ves_pipeline::rigid::rigid_motions;
use ves_tests::load_case;

#[test]
fn stiffness_annihilates_rigid_motions_of_a_free_body() {
    let scene = load_case("bracket");
    let d = discretize(&scene, None, &mut Timings::default()).expect("bracket discretizes");
    assert!(d.dofs.fixed.is_empty());
    assert_eq!(d.rigid, 6);
    let n = d.dofs.free_count();
    let mut y = vec![0.0; n];
    let kmax = d.system.k.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let c = d.system.mass.center;
    for (r, u) in rigid_motions(&d.mesh.nodes, c, d.mesh.diameter()).iter().enumerate() {
        sym_matvec(&d.system.pattern, &d.system.k, u, &mut y);
        let worst = y.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let unorm = u.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        assert!(worst < 1e-10 * kmax * unorm, "rigid motion {r}: |K u| = {worst:e}");
    }
}
