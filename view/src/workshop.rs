//! The set-up panel's side of the server: a [`Workshop`] (given by whoever can mesh and solve —
//! the pipeline; the runtime cannot) turns the page's scene into a basis, with progress and a
//! way to cancel. One compute at a time; its progress goes to every page.

use serde::Serialize;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

/// Why a workshop could not compute a basis or open a part; each message is one line for the
/// page. The server answers a refused part with 422 and shows a failed compute on every page.
#[derive(Debug, thiserror::Error)]
pub enum WorkshopError {
    /// The page's scene is refused (malformed, or invalid as a scene): the scene checker's
    /// message, naming the file "scene".
    #[error("{message}")]
    Scene {
        /// What is wrong and what to change.
        message: String,
    },
    /// The scene's geometry is a gmsh script, which the page may not run.
    #[error("a .geo geometry is a gmsh script: open a STEP, IGES or BREP file")]
    Script,
    /// An uploaded `.geo` file.
    #[error("{file}: a .geo file is a gmsh script and can run commands; export the part as STEP, IGES or BREP")]
    GeoUpload {
        /// The file's name, escaped for a terminal.
        file: String,
    },
    /// An uploaded file whose extension is not a geometry's.
    #[error("{file}: open a STEP (.step, .stp), IGES (.iges, .igs) or BREP (.brep) file")]
    Extension {
        /// The file's name, escaped for a terminal.
        file: String,
    },
    /// An upload larger than [`MAX_UPLOAD`].
    #[error("{file}: {bytes} bytes, more than the {} MiB a page may send", MAX_UPLOAD >> 20)]
    TooLarge {
        /// The file's name, escaped for a terminal.
        file: String,
        /// Its size.
        bytes: usize,
    },
    /// An upload whose content is no STEP, IGES or BREP file.
    #[error(
        "{file}: not a STEP, IGES or BREP file (a STEP file starts with ISO-10303-21); export the part again from \
         its CAD system"
    )]
    NotGeometry {
        /// The file's name, escaped for a terminal.
        file: String,
    },
    /// A part opened while a compute runs.
    #[error("{file}: a compute is running: cancel it or wait, then open the part")]
    Busy {
        /// The file's name, escaped for a terminal.
        file: String,
    },
    /// The uploaded part cannot be stored.
    #[error("cannot keep the part: {0}")]
    KeepPart(std::io::Error),
    /// The basis computed cannot be kept (made private to its owner).
    #[error("cannot keep the basis: {0}")]
    KeepBasis(std::io::Error),
    /// The compute's files cannot be written.
    #[error("cannot start the compute: {0}")]
    Start(std::io::Error),
    /// The compute's process cannot be started.
    #[error("cannot start the compute process {}: {error}", exe.display())]
    StartProcess {
        /// The program.
        exe: PathBuf,
        /// Why.
        error: std::io::Error,
    },
    /// The pipeline failed: its error with the whole cause chain, on one line.
    #[error("{message}")]
    Failed {
        /// The line.
        message: String,
    },
    /// Cancelled from the page.
    #[error("{}", if *served { "cancelled: the part shown stays, without its checks" } else { "cancelled: nothing was written" })]
    Cancelled {
        /// Whether the basis was already served (only its checks were cancelled).
        served: bool,
    },
    /// The compute's process ended without a word about its outcome.
    #[error("the compute process ended: {how}{}", if last_words.is_empty() { String::new() } else { format!(": {last_words}") })]
    ProcessEnded {
        /// How it ended (signal, status), in words.
        how: String,
        /// The last line it wrote to stderr, if any.
        last_words: String,
    },
    /// The server could not serve the basis made (see the `ready` of [`Workshop::compute`]).
    #[error(transparent)]
    Serve(#[from] super::ViewError),
}

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
    /// Whether this is an instant basis (the previous basis's mesh, modes from a few block
    /// solves, each frequency with a bound): the converged basis follows and replaces it.
    pub instant: bool,
    /// The warnings the compute gave (one line each, as the CLI prints them): a thin wall, an
    /// estimate above its target, straightened tets, a refinement stopped by memory.
    pub warnings: Vec<String>,
    /// The first space's mesh for the page: `{nodes, tets, size_m, worst_quality,
    /// quality_histogram}` (tets by shape quality, a tenth of [0, 1] a bin), or null.
    pub mesh: serde_json::Value,
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
    /// An error from `ready` ends the compute with it ([`WorkshopError::Serve`]). Returns what
    /// the compute finally made.
    fn compute(
        &self,
        scene: &serde_json::Value,
        progress: Arc<dyn Fn(Progress) + Send + Sync>,
        cancel: Arc<AtomicBool>,
        ready: &mut dyn FnMut(&Computed) -> Result<(), WorkshopError>,
    ) -> Result<Computed, WorkshopError>;
    /// Makes the geometry file `name` (as the page's user picked it; only its file name
    /// counts) with content `bytes` the part from now on, with a fresh starting scene. Only
    /// STEP, IGES and BREP are taken, checked by content, never a `.geo` script.
    fn open(&self, name: &str, bytes: &[u8]) -> Result<(), WorkshopError>;
    /// The geometry file of the part set up now (its faces' names are read from it), if any.
    fn geometry(&self) -> Option<std::path::PathBuf> {
        None
    }
    /// The basis `basis` of a project is served (no compute made it): the next compute may
    /// start from it as from one it made.
    fn served_from_project(&self, _basis: &std::path::Path) {}
    /// After [`Workshop::open`], once the new part's first compute ended: `keep` (it made a
    /// basis) lets the part before go; otherwise the part before is the part again.
    fn settle(&self, _keep: bool) {}
}

/// Largest geometry file the page may send, bytes.
pub const MAX_UPLOAD: usize = 64 << 20;
