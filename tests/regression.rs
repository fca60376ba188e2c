//! Regression guard: every case's frequencies against the numbers recorded beside its scene
//! (`reference.json`, or `reference-<variant>.json` for `scene-<variant>.toml`). A code change
//! that moves a frequency by more than the recorded tolerance fails CI.
//!
//! After a deliberate change, re-record with
//! `VES_BLESS=1 cargo test --release -p ves-tests --test regression` and say why in the commit.

use std::path::PathBuf;
use ves_pipeline::modes::SolverChoice;
use ves_pipeline::precompute::solve_space;
use ves_pipeline::scene::Scene;
use ves_tests::case_path;

const CASES: &[&str] = &[
    "cantilever/scene.toml",
    "ribplate/scene.toml",
    "bracket/scene.toml",
    "fv52/scene.toml",
    "fv52/scene-hard.toml",
    "mould/scene.toml",
];

/// Meshes are reproducible (gmsh Delaunay) and the solve converges far below this.
const TOLERANCE: f64 = 1e-7;

fn reference_path(scene: &std::path::Path) -> PathBuf {
    let stem = scene.file_stem().and_then(|s| s.to_str()).unwrap_or("scene");
    scene.with_file_name(format!("{}.json", stem.replacen("scene", "reference", 1)))
}

#[test]
fn case_frequencies_match_their_recorded_references() {
    let bless = std::env::var_os("VES_BLESS").is_some();
    let mut failures = Vec::new();
    for case in CASES {
        let path = case_path(case);
        let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let s = solve_space(&scene, None, SolverChoice::Auto).unwrap_or_else(|e| panic!("{case}: {e:#}"));
        let f = s.modes.frequencies_hz();
        let refp = reference_path(&path);
        if bless {
            let v = serde_json::json!({
                "case": case,
                "nodes": s.mesh.nodes.len(),
                "tets": s.mesh.tet_count(),
                "rigid_modes_dropped": s.modes.rigid_dropped,
                "frequencies_hz": f,
            });
            std::fs::write(&refp, serde_json::to_string_pretty(&v).unwrap_or_default() + "\n")
                .expect("write reference");
            continue;
        }
        let text = std::fs::read_to_string(&refp)
            .unwrap_or_else(|e| panic!("{}: {e} (record it with VES_BLESS=1)", refp.display()));
        let v: serde_json::Value = serde_json::from_str(&text).expect("reference JSON");
        // The tolerance is this test's, never the blessed file's: a file cannot loosen its own check.
        let tol = TOLERANCE;
        if v["nodes"].as_u64() != Some(s.mesh.nodes.len() as u64) {
            failures.push(format!(
                "{case}: mesh changed ({} nodes, recorded {})",
                s.mesh.nodes.len(),
                v["nodes"]
            ));
            continue;
        }
        let recorded: Vec<f64> = v["frequencies_hz"]
            .as_array()
            .map(|a| a.iter().filter_map(|x| x.as_f64()).collect())
            .unwrap_or_default();
        if recorded.len() != f.len() {
            failures.push(format!("{case}: {} modes, recorded {}", f.len(), recorded.len()));
            continue;
        }
        for (i, (a, b)) in f.iter().zip(&recorded).enumerate() {
            if ((a - b) / b).abs() > tol {
                failures.push(format!("{case}: mode {} is {a} Hz, recorded {b} Hz", i + 1));
            }
        }
    }
    assert!(failures.is_empty(), "frequencies moved:\n{}", failures.join("\n"));
}
