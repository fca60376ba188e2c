//! The set-up panel's side of the server: a [`Workshop`] (given by whoever can mesh and solve —
//! the pipeline; the runtime cannot) turns the page's scene into a basis, with progress and a
//! way to cancel. One compute at a time; its progress goes to every page.

use serde::Serialize;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

/// What a compute made.
#[derive(Clone, Debug)]
pub struct Computed {
    /// The basis file (in the workshop's private directory).
    pub basis: PathBuf,
    /// The scene it was computed from, as saved (TOML), for "save scene".
    pub scene: String,
    /// One line for the page: sizes, frequencies, time, and the estimated error once known.
    pub summary: String,
    /// The largest estimated relative frequency error of the first space's modes, once known.
    pub estimated_error: Option<f64>,
}

/// Where a compute stands, for the page's progress bar.
#[derive(Clone, Debug, Serialize)]
pub struct Progress {
    /// Stage: "meshing", "assembling", "eigen-solving", "estimating", "writing", "loading".
    pub stage: String,
    /// Of the whole compute, 0 to 1.
    pub fraction: f64,
}

/// Makes bases from scenes for the viewer.
pub trait Workshop: Send + Sync {
    /// What the set-up panel starts from and offers (JSON: the scene as TOML text, the
    /// materials, units, limits), sent to every page in the hello.
    fn setup(&self) -> serde_json::Value;
    /// Computes a basis from `scene` (the page's scene: TOML tables as JSON, checked as any
    /// scene, its geometry always the workshop's own file, never a path the page names).
    /// `progress` is called at each stage; `cancel` set stops it at the next stage with an error.
    /// `ready` is called once, as soon as a basis the session can use is written; checks that
    /// leave its modes as they are (the error estimate) may follow and rewrite the same file.
    /// An error from `ready` ends the compute with it. Returns what the compute finally made.
    fn compute(
        &self,
        scene: &serde_json::Value,
        progress: Arc<dyn Fn(Progress) + Send + Sync>,
        cancel: Arc<AtomicBool>,
        ready: &mut dyn FnMut(&Computed) -> Result<(), String>,
    ) -> Result<Computed, String>;
    /// Makes the geometry file `name` (as the page's user picked it; only its file name
    /// counts) with content `bytes` the part from now on, with a fresh starting scene. Only
    /// STEP, IGES and BREP are taken, checked by content, never a `.geo` script.
    fn open(&self, name: &str, bytes: &[u8]) -> Result<(), String>;
}

/// Largest geometry file the page may send, bytes.
pub const MAX_UPLOAD: usize = 64 << 20;
