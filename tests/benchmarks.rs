//! Published benchmarks as cases: NAFEMS FV52 (simply supported thick square plate).
//!
//! Published: 45.897, 109.44, 109.44, 167.89 (bending), 193.59 (in-plane), 206.19, 206.19 Hz
//! (the issue quotes 206.64; public copies of the benchmark give 206.19).

use ves_pipeline::modes::SolverChoice;
use ves_pipeline::precompute::solve_space;

fn frequencies(case: &str) -> (Vec<f64>, usize) {
    let path = ves_tests::case_path(case);
    let scene = ves_pipeline::scene::Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let s = solve_space(&scene, None, SolverChoice::Arpack).unwrap_or_else(|e| panic!("{e:#}"));
    (s.modes.frequencies_hz(), s.modes.rigid_dropped)
}

/// The model of ours nearest to a published frequency, and the relative difference.
fn nearest(ours: &[f64], published: f64) -> (f64, f64) {
    let f = ours
        .iter()
        .copied()
        .min_by(|a, b| (a - published).abs().total_cmp(&(b - published).abs()))
        .unwrap_or(f64::NAN);
    (f, (f - published) / published)
}

#[test]
fn fv52_hard_support_reproduces_the_published_bending_frequencies() {
    let _serial = ves_tests::serial();
    let (f, rigid) = frequencies("fv52/scene-hard.toml");
    assert_eq!(rigid, 0);
    for published in [45.897, 109.44, 167.89, 206.19] {
        let (ours, rel) = nearest(&f, published);
        println!(
            "FV52 hard: published {published} Hz, ours {ours:.3} Hz ({:+.2} %)",
            100.0 * rel
        );
        assert!(rel.abs() < 0.01, "{published} Hz: ours {ours} ({rel:+.4})");
    }
    // The 109.44 pair and the 206.19 pair are both present (square symmetry).
    assert!(f.iter().filter(|x| ((*x - 109.44) / 109.44).abs() < 0.01).count() == 2);
    assert!(f.iter().filter(|x| ((*x - 206.19) / 206.19).abs() < 0.01).count() == 2);
}

#[test]
fn fv52_line_support_keeps_three_rigid_modes_and_the_in_plane_mode() {
    let _serial = ves_tests::serial();
    let (f, rigid) = frequencies("fv52/scene.toml");
    assert_eq!(rigid, 3, "x, y translation and rotation about z remain");
    let (ours, rel) = nearest(&f, 193.59);
    println!(
        "FV52 line support: in-plane 193.59 Hz, ours {ours:.3} ({:+.2} %); first bending {:.3} Hz",
        100.0 * rel,
        f[0]
    );
    assert!(rel.abs() < 0.01);
    // A line support is softer than the thick-plate solution's (and singular in 3D): the first
    // bending frequency comes out below 45.897 Hz, by 5.6 % at this mesh, more when refined.
    assert!(f[0] < 45.897 && f[0] > 0.9 * 45.897, "first bending {}", f[0]);
}
