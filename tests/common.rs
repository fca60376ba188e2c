//! Helpers shared by the integration tests.

use std::path::PathBuf;
use ves_pipeline::scene::Scene;

/// Path of a file under `cases/`.
pub fn case_path(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("cases")
        .join(rel)
}

/// Loads `cases/<name>/scene.toml`.
pub fn load_case(name: &str) -> Scene {
    let path = case_path(&format!("{name}/scene.toml"));
    Scene::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

/// Lowest natural frequency (Hz) of a clamped-free Timoshenko beam, from a converged 1D finite
/// element model (linear elements, one-point shear integration, consistent mass with rotary
/// inertia; Richardson-extrapolated from 400 and 800 elements, error < 1e-7 relative).
///
/// `ei`: bending stiffness, `kga`: shear stiffness κGA, `rho_a`: mass per length, `rho_i`:
/// rotary inertia per length, `length`: span.
pub fn timoshenko_cantilever_f1(ei: f64, kga: f64, rho_a: f64, rho_i: f64, length: f64) -> f64 {
    let f = |n: usize| timoshenko_fe_f1(ei, kga, rho_a, rho_i, length, n);
    let (f1, f2) = (f(400), f(800));
    f2 + (f2 - f1) / 3.0
}

fn timoshenko_fe_f1(ei: f64, kga: f64, rho_a: f64, rho_i: f64, length: f64, n: usize) -> f64 {
    use faer::linalg::solvers::SolveCore;
    use faer::{Conj, Mat, Side};
    let h = length / n as f64;
    let dofs = 2 * n; // node 0 clamped: nodes 1..=n carry (w, θ)
    let mut k = Mat::<f64>::zeros(dofs, dofs);
    let mut m = Mat::<f64>::zeros(dofs, dofs);
    let b = [-1.0 / h, -0.5, 1.0 / h, -0.5];
    for e in 0..n {
        let idx = |local: usize| -> Option<usize> {
            let node = e + local / 2;
            if node == 0 {
                None
            } else {
                Some(2 * (node - 1) + local % 2)
            }
        };
        let mut ke = [[0.0; 4]; 4];
        let mut me = [[0.0; 4]; 4];
        for i in 0..4 {
            for j in 0..4 {
                ke[i][j] = kga * h * b[i] * b[j];
            }
        }
        ke[1][1] += ei / h;
        ke[3][3] += ei / h;
        ke[1][3] -= ei / h;
        ke[3][1] -= ei / h;
        for (c, rho) in [(0, rho_a), (1, rho_i)] {
            me[c][c] += rho * h / 3.0;
            me[c + 2][c + 2] += rho * h / 3.0;
            me[c][c + 2] += rho * h / 6.0;
            me[c + 2][c] += rho * h / 6.0;
        }
        for i in 0..4 {
            for j in 0..4 {
                if let (Some(a), Some(c)) = (idx(i), idx(j)) {
                    k[(a, c)] += ke[i][j];
                    m[(a, c)] += me[i][j];
                }
            }
        }
    }
    // Inverse iteration: the lowest mode is well separated (ratio ≈ 6).
    let llt = k.llt(Side::Lower).expect("clamped beam stiffness is SPD");
    let mut x = Mat::<f64>::from_fn(dofs, 1, |i, _| 1.0 + i as f64);
    let mut lambda = 0.0;
    for _ in 0..200 {
        let mut y = &m * &x;
        llt.solve_in_place_with_conj(Conj::No, y.as_mut());
        let ky = &k * &y;
        let my = &m * &y;
        let num = (y.transpose() * &ky)[(0, 0)];
        let den = (y.transpose() * &my)[(0, 0)];
        let next = num / den;
        let norm = den.sqrt();
        x = y * faer::Scale(1.0 / norm);
        if (next - lambda).abs() < 1e-14 * next {
            lambda = next;
            break;
        }
        lambda = next;
    }
    lambda.sqrt() / (2.0 * std::f64::consts::PI)
}

/// Saint-Venant torsion constant of a b × t rectangle (b ≥ t), series solution.
pub fn rectangle_torsion_constant(b: f64, t: f64) -> f64 {
    let mut s = 0.0;
    for k in 0..50 {
        let n = (2 * k + 1) as f64;
        s += (n * std::f64::consts::PI * b / (2.0 * t)).tanh() / n.powi(5);
    }
    b * t.powi(3) / 3.0 * (1.0 - 192.0 / std::f64::consts::PI.powi(5) * t / b * s)
}

/// Precomputes `cases/<name>` (overriding mesh size, order and mode count) into a basis file in
/// `dir` and returns its path.
pub fn precompute_case(name: &str, size: f64, order: u8, modes: usize, dir: &std::path::Path) -> PathBuf {
    let mut scene = load_case(name);
    scene.mesh.size = size;
    scene.mesh.order = order;
    scene.modes.count = modes;
    let out = dir.join(format!("{name}.h5"));
    // One in-process precompute at a time: two tests of the capi binary precomputing the same
    // case at once twice left a file that HDF5 then could not open (CI only, cause not found;
    // `ves precompute` runs one per process).
    static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|p| p.into_inner());
    ves_pipeline::precompute::run(&scene, &out, ves_pipeline::modes::SolverChoice::Auto)
        .unwrap_or_else(|e| panic!("{e:#}"));
    out
}

/// Serialises the tests of one binary that need bit-identical meshes: gmsh gave a slightly
/// different mesh for the same input while other threads of the process were busy.
pub fn serial() -> std::sync::MutexGuard<'static, ()> {
    static LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());
    LOCK.lock().unwrap_or_else(|p| p.into_inner())
}
