//! Extreme cases (`cases/extreme/`): each against theory or an exact invariant.

use std::f64::consts::PI;
use ves_pipeline::modes::SolverChoice;
use ves_pipeline::precompute::solve_space;
use ves_pipeline::scene::Scene;
use ves_tests::{case_path, timoshenko_cantilever_f1};

fn scene(name: &str) -> Scene {
    Scene::load(&case_path(&format!("extreme/{name}.toml"))).unwrap_or_else(|e| panic!("{e}"))
}

fn freqs(s: &Scene) -> Vec<f64> {
    let solved = solve_space(s, None, SolverChoice::Arpack).unwrap_or_else(|e| panic!("{e:#}"));
    assert!(solved.modes.residuals.iter().all(|r| r.is_finite()));
    solved.modes.frequencies_hz()
}

/// First bending frequency of a square-section cantilever (side h, length l) by Timoshenko.
fn timoshenko_square(e: f64, nu: f64, rho: f64, l: f64, h: f64) -> f64 {
    let (a, i) = (h * h, h.powi(4) / 12.0);
    let kappa = 10.0 * (1.0 + nu) / (12.0 + 11.0 * nu);
    timoshenko_cantilever_f1(e * i, kappa * e / (2.0 * (1.0 + nu)) * a, rho * a, rho * i, l)
}

#[test]
fn millimetre_steel_beam_matches_timoshenko() {
    let _serial = ves_tests::serial();
    let s = scene("beam1mm");
    let f = freqs(&s);
    let t = timoshenko_square(2.1e11, 0.3, 7850.0, 0.02, 0.001);
    println!("1 mm beam: {:.2} Hz vs Timoshenko {t:.2} Hz", f[0]);
    assert!((f[0] - t).abs() < 0.01 * t && (f[1] - t).abs() < 0.01 * t);
}

#[test]
fn soft_foam_is_the_steel_beam_scaled_exactly() {
    let _serial = ves_tests::serial();
    let (steel, foam) = (freqs(&scene("beam1mm")), freqs(&scene("foam")));
    let ratio = ((2200.0_f64 / 1200.0) / (2.1e11 / 7850.0)).sqrt();
    for (a, b) in steel.iter().zip(&foam) {
        assert!((b / a - ratio).abs() < 1e-8 * ratio, "{b} / {a} vs {ratio}");
    }
}

#[test]
fn nearly_incompressible_beam_10_node_is_right_4_node_locks() {
    let _serial = ves_tests::serial();
    let s = scene("nu499");
    let f = freqs(&s);
    let t = timoshenko_square(2.1e11, 0.499, 7850.0, 0.02, 0.001);
    let mut s1 = s.clone();
    s1.mesh.order = 1;
    let f1 = freqs(&s1);
    println!(
        "ν = 0.499: 10-node {:.1} Hz, 4-node {:.1} Hz, Timoshenko {t:.1} Hz",
        f[0], f1[0]
    );
    assert!((f[0] - t).abs() < 0.015 * t, "10-node {} vs {t}", f[0]);
    assert!(f1[0] > 1.5 * t, "4-node tets should lock (much too stiff): {}", f1[0]);
}

#[test]
fn thin_plate_200_to_1_matches_kirchhoff() {
    let _serial = ves_tests::serial();
    let s = scene("plate200");
    let f = freqs(&s);
    let (e, nu, rho, a, h): (f64, f64, f64, f64, f64) = (2.1e11, 0.3, 7850.0, 0.2, 0.001);
    let d = e * h * h * h / (12.0 * (1.0 - nu * nu));
    // Leissa, square plate clamped on one edge (ν = 0.3): ω a² √(ρh/D) = 3.492.
    let leissa = 3.492 / (2.0 * PI * a * a) * (d / (rho * h)).sqrt();
    println!("200:1 plate: {:.3} Hz vs Kirchhoff {leissa:.3} Hz", f[0]);
    assert!((f[0] - leissa).abs() < 0.01 * leissa);
}

/// A structured 10-node beam mesh (0.4 × 0.1 × 0.1 m, 8 × 2 × 2 cubes of 6 tets), clamped at
/// x = 0, with interior node (x = 0.2, y = z = 0.05) moved by `shift` along y.
fn raw_beam(shift: f64) -> (ves_pipeline::mesh::Mesh, ves_pipeline::fem::Dofs) {
    let mesh = ves_pipeline::mesh::Mesh::structured_box(
        [8, 2, 2],
        0.05,
        ves_pipeline::fem::element::Kind::Tet10,
        |ijk, mut p| {
            if ijk == [4, 1, 1] {
                p[1] += shift;
            }
            p
        },
    );
    let mask: Vec<bool> = mesh.nodes.iter().flat_map(|p| [p[0] < 1e-9; 3]).collect();
    let dofs = ves_pipeline::fem::Dofs::from_mask(&mask);
    (mesh, dofs)
}

/// Sliver tets (an interior node pushed to 0.2 mm from a cube face): the quality measure finds
/// them where they are, and the basis stays right: residuals within bounds, the first
/// frequencies within 1 % of the regular mesh's.
#[test]
fn sliver_tets_are_located_and_the_modes_stay_right() {
    let solve = |shift: f64| {
        let (mesh, dofs) = raw_beam(shift);
        let (q, at) = mesh.worst_quality();
        let d = ves_pipeline::problem::Discretized::assemble(
            mesh,
            dofs,
            ves_pipeline::material::Material::elastic(2.1e11, 0.3, 7850.0),
        )
        .expect("assemble");
        let (modes, _) = ves_pipeline::modes::solve(d.space(), 6, SolverChoice::Arpack).expect("modes");
        (q, at, modes)
    };
    let (q0, _, regular) = solve(0.0);
    let (q1, at, sliver) = solve(0.0498);
    println!(
        "worst quality: regular {q0:.3}, sliver {q1:.2e} at ({:.4}, {:.4}, {:.4}); f1 {:.3} vs {:.3} Hz; max residual {:.1e}",
        at[0],
        at[1],
        at[2],
        regular.frequencies_hz()[0],
        sliver.frequencies_hz()[0],
        sliver.residuals.iter().fold(0.0f64, |a, &b| a.max(b))
    );
    assert!(q0 > 0.3, "the regular mesh has no sliver: {q0}");
    assert!(q1 < 0.02, "the sliver is detected: {q1}");
    assert!(
        (at[0] - 0.2).abs() < 0.05 && at[1] > 0.05,
        "located near the moved node: {at:?}"
    );
    for (a, b) in regular.frequencies_hz().iter().zip(sliver.frequencies_hz()) {
        assert!((b / a - 1.0).abs() < 0.01, "{a} vs {b}");
    }
    assert!(sliver.residuals.iter().all(|r| *r < 1e-6));
}
