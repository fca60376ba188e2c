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
