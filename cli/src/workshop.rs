//! The viewer's set-up panel, pipeline side: a scene edited in the page becomes a basis.
//!
//! The page sends the scene as JSON (the TOML's tables and keys); it is checked by the same
//! parser as every scene file. The geometry is always the workshop's own file: whatever the
//! page names as `geometry.step` is replaced, so a page cannot make the server read another
//! file. Uploaded parts and bases go to a private work folder ([`ves_pipeline::workdir`]), removed
//! when the viewer ends; a part or a basis replaced by a newer one is removed at once, so the
//! folder holds at most the part open, the basis served and the one being computed.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};
use ves_pipeline::accuracy::refine;
use ves_pipeline::modes::SolverChoice;
use ves_pipeline::precompute;
use ves_pipeline::scene::{Scene, SceneOptions};
use ves_view::{Computed, Progress, Workshop, WorkshopError};

/// A real material: name, Young's modulus (Pa), Poisson's ratio, density (kg/m³), yield
/// strength (Pa; for brittle PMMA its tensile strength).
pub struct MaterialPreset {
    /// What the list shows.
    pub name: &'static str,
    /// Pa.
    pub young: f64,
    /// —.
    pub poisson: f64,
    /// kg/m³.
    pub density: f64,
    /// Pa.
    pub yield_strength: f64,
}

/// The set-up panel's materials: room-temperature handbook values (steel S235/A36-class
/// structural steel; 6061-T6; Ti-6Al-4V annealed; the polymers as moulded, dry).
pub const MATERIALS: [MaterialPreset; 7] = [
    MaterialPreset {
        name: "structural steel",
        young: 2.1e11,
        poisson: 0.3,
        density: 7850.0,
        yield_strength: 2.5e8,
    },
    MaterialPreset {
        name: "stainless steel 304",
        young: 1.93e11,
        poisson: 0.29,
        density: 8000.0,
        yield_strength: 2.15e8,
    },
    MaterialPreset {
        name: "aluminium 6061-T6",
        young: 6.89e10,
        poisson: 0.33,
        density: 2700.0,
        yield_strength: 2.76e8,
    },
    MaterialPreset {
        name: "titanium Ti-6Al-4V",
        young: 1.138e11,
        poisson: 0.342,
        density: 4430.0,
        yield_strength: 8.8e8,
    },
    MaterialPreset {
        name: "ABS",
        young: 2.3e9,
        poisson: 0.35,
        density: 1050.0,
        yield_strength: 4.0e7,
    },
    MaterialPreset {
        name: "PA66 (dry)",
        young: 2.9e9,
        poisson: 0.39,
        density: 1140.0,
        yield_strength: 8.0e7,
    },
    MaterialPreset {
        name: "PMMA",
        young: 3.0e9,
        poisson: 0.37,
        density: 1180.0,
        yield_strength: 7.0e7,
    },
];

/// Computes bases for one part (or the parts the page opens) in a private work folder.
pub struct PartWorkshop {
    part: std::sync::Mutex<Part>,
    /// Held by a compute from start to end: a part is not opened under it (the server lets
    /// one of the two run at a time; this keeps a library user to it too).
    busy: std::sync::Mutex<()>,
    options: SceneOptions,
    dir: ves_pipeline::workdir::WorkDir,
    computed: AtomicU64,
    solver: SolverChoice,
    /// The compute's threads, below the session's in priority (see [`lower_priority`]).
    pool: rayon::ThreadPool,
    /// The basis served last (an instant basis starts from it).
    last: std::sync::Mutex<Option<PathBuf>>,
    /// Set-ups computed before, by [`setup_key`], with their converged bases, newest last:
    /// asking for one again serves its basis at once.
    kept: std::sync::Mutex<Vec<(String, Computed)>>,
    /// Whether an instant basis is served first when it can be (`ves view --instant`).
    instant: bool,
    /// The part before the one opened last, with the basis served then, until the new part's
    /// first compute ends ([`Workshop::settle`]).
    previous: std::sync::Mutex<Option<(Part, Option<PathBuf>)>>,
}

/// The part being set up: its geometry file and the scene the page starts from.
struct Part {
    geometry: PathBuf,
    start: serde_json::Value,
}

/// One line for the page: the first space's mesh (nodes, tets, element size, worst shape
/// quality: the mesh was hidden from the page) and frequencies, the time, and the largest
/// estimated error when the estimate is in.
fn summary_line(summary: &precompute::Summary) -> String {
    let Some(g) = summary.spaces.first() else {
        return String::new();
    };
    // The element size to three significant digits, when the mesh was made here (an instant
    // basis reads the previous mesh back, whose size it does not know).
    let mm = 1e3 * g.meshing.size;
    let size = if mm > 0.0 && mm.is_finite() {
        format!(", size {} mm", ves_pipeline::report::significant(mm, 3))
    } else {
        String::new()
    };
    // The first frequency to five digits (its estimated error is a percent or so; "10137.6657
    // Hz" claimed digits it does not have).
    let mut line = format!(
        "{} nodes, {} tets{size}, worst quality {:.2}, {} modes, first {} Hz, in {:.1} s",
        g.nodes,
        g.tets,
        g.min_tet_quality,
        g.frequencies_hz.len(),
        ves_pipeline::report::significant(g.frequencies_hz.first().copied().unwrap_or(0.0), 5),
        summary.timings_s.total
    );
    if let Some(e) = worst_estimate(summary) {
        line.push_str(&format!("; estimated frequency error ≤ {:.2} %", 100.0 * e));
    }
    if let Some(f) = summary.spaces.first().and_then(|s| s.felt_compliance.as_ref()) {
        line.push_str(&f.text());
    }
    line
}

/// The first space's mesh for the page (`Computed::mesh`): nodes, tets, element size (0 when
/// read back from a previous basis), worst shape quality and the tets by quality.
fn mesh_of(summary: &precompute::Summary) -> serde_json::Value {
    summary.spaces.first().map_or(serde_json::Value::Null, |g| {
        serde_json::json!({
            "nodes": g.nodes,
            "tets": g.tets,
            "size_m": g.meshing.size,
            "worst_quality": g.min_tet_quality,
            "quality_histogram": g.tet_quality_histogram,
        })
    })
}

/// The largest estimated relative error of the first space's modes, when estimated.
fn worst_estimate(summary: &precompute::Summary) -> Option<f64> {
    let e = summary.spaces.first()?.estimated_relative_error.as_ref()?;
    e.iter().copied().filter(|x| x.is_finite()).reduce(f64::max)
}

/// The scene a geometry file starts from: a free part in structural steel with 10-node tets,
/// 12 modes and stress, meshed until the error estimate is 5 %, with stiffness-proportional
/// damping β = 1e-5 s (as the cantilever case: without damping a part pulled at the device's
/// force limit rings for ever, its clamped force adding none).
fn starting_scene(geometry: &Path) -> serde_json::Value {
    let name = safe_stem(geometry);
    let steel = &MATERIALS[0];
    serde_json::json!({
        "name": name,
        "geometry": { "step": "" },
        "material": { "young": steel.young, "poisson": steel.poisson, "density": steel.density,
                      "yield_strength": steel.yield_strength },
        "mesh": { "order": 2, "target_error": 0.05 },
        "modes": { "count": 12 },
        "stress": { "enabled": true },
        "damping": { "alpha": 0.0, "beta": 1.0e-5 },
    })
}

/// A file's stem as a scene name and a file name: ASCII letters, digits, `-` and `_` (others
/// become `_`), at most 64 characters; "part" for none. (Also the folder name of a part opened
/// in the page, with its key.)
pub(crate) fn safe_stem(path: &Path) -> String {
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let safe: String = stem
        .chars()
        .take(64)
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect();
    if safe.is_empty() { "part".into() } else { safe }
}

/// What kind of geometry `bytes` hold, by content: a STEP, IGES or OpenCASCADE BREP file.
fn geometry_kind(bytes: &[u8]) -> Option<&'static str> {
    let head = String::from_utf8_lossy(&bytes[..bytes.len().min(4096)]);
    let text = head.trim_start_matches('\u{feff}').trim_start();
    if text.starts_with("ISO-10303-21") {
        Some("step")
    } else if text.starts_with("DBRep_DrawableShape") || text.starts_with("CASCADE Topology V") {
        Some("brep")
    } else if text
        .lines()
        .next()
        .is_some_and(|l| l.len() >= 73 && l.as_bytes()[72] == b'S')
    {
        Some("iges")
    } else {
        None
    }
}

/// Lowers the calling thread's priority (nice 10): a compute beside a live session must not take
/// the cores from its drawing and network threads (the haptic thread, under SCHED_FIFO, is above
/// every nice level anyway). Processes the thread starts (gmsh) inherit it. Best effort: a
/// refusal leaves the priority as it was.
fn lower_priority() {
    ves_pipeline::os::lower_thread_priority();
}

impl PartWorkshop {
    /// A workshop for `scene` (its geometry is the part from now on).
    pub fn for_scene(scene: &Scene, options: SceneOptions, solver: SolverChoice) -> anyhow::Result<PartWorkshop> {
        let table: toml::Table = toml::from_str(&scene.toml)?;
        let start = serde_json::to_value(&table)?;
        Self::new(scene.geometry.clone(), start, options, solver)
    }

    /// A workshop for a geometry file, starting from [`starting_scene`].
    pub fn for_geometry(geometry: &Path, solver: SolverChoice) -> anyhow::Result<PartWorkshop> {
        let geometry = std::path::absolute(geometry)?;
        let start = starting_scene(&geometry);
        Self::new(geometry, start, SceneOptions::default(), solver)
    }

    fn new(
        geometry: PathBuf,
        start: serde_json::Value,
        options: SceneOptions,
        solver: SolverChoice,
    ) -> anyhow::Result<PartWorkshop> {
        let dir = ves_pipeline::workdir::WorkDir::new("view")?;
        let pool = rayon::ThreadPoolBuilder::new()
            .thread_name(|i| format!("ves-compute-{i}"))
            .start_handler(|_| lower_priority())
            .build()?;
        Ok(PartWorkshop {
            pool,
            part: std::sync::Mutex::new(Part { geometry, start }),
            busy: std::sync::Mutex::new(()),
            options,
            dir,
            computed: AtomicU64::new(0),
            solver,
            last: std::sync::Mutex::new(None),
            kept: std::sync::Mutex::new(Vec::new()),
            instant: false,
            previous: std::sync::Mutex::new(None),
        })
    }

    /// Removes the bases computed here (and their sidecars, `basis-N.*`) but `keep`'s and the
    /// kept set-ups' ([`PartWorkshop::keep`]).
    fn remove_bases_but(&self, keep: &Path) {
        let Ok(entries) = std::fs::read_dir(self.dir.path()) else {
            return;
        };
        let kept: Vec<PathBuf> = self.kept().iter().map(|(_, c)| c.basis.clone()).collect();
        for e in entries.flatten() {
            let path = e.path();
            let stem = path.file_stem();
            if e.file_name().to_string_lossy().starts_with("basis-")
                && stem != keep.file_stem()
                && !kept.iter().any(|k| k.file_stem() == stem)
            {
                let _ = std::fs::remove_file(path);
            }
        }
    }

    fn kept(&self) -> std::sync::MutexGuard<'_, Vec<(String, Computed)>> {
        self.kept.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Keeps `computed`, the converged basis of the set-up `key` ([`setup_key`]), for a later request of the same
    /// set-up: the newest [`KEPT`] set-ups, at most [`KEPT_BYTES`] of bases (the oldest go first,
    /// their files with them).
    fn keep(&self, key: &str, computed: &Computed) {
        let mut kept = self.kept();
        kept.retain(|(k, _)| k != key);
        kept.push((key.to_string(), computed.clone()));
        let size = |c: &Computed| std::fs::metadata(&c.basis).map_or(0, |m| m.len());
        while kept.len() > 1 && (kept.len() > KEPT || kept.iter().map(|(_, c)| size(c)).sum::<u64>() > KEPT_BYTES) {
            let (_, old) = kept.remove(0);
            remove_basis(&old.basis);
        }
    }

    /// The converged basis of a set-up computed before ([`setup_key`]), if it is still there;
    /// it becomes the newest kept.
    fn kept_for(&self, key: &str) -> Option<Computed> {
        let mut kept = self.kept();
        let at = kept.iter().position(|(k, c)| k == key && c.basis.is_file())?;
        let entry = kept.remove(at);
        let computed = entry.1.clone();
        kept.push(entry);
        Some(computed)
    }

    /// Serve an instant basis first when only supports, material or modes changed.
    pub fn instant(self, on: bool) -> PartWorkshop {
        PartWorkshop { instant: on, ..self }
    }

    fn last(&self) -> std::sync::MutexGuard<'_, Option<PathBuf>> {
        self.last.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn part(&self) -> std::sync::MutexGuard<'_, Part> {
        self.part.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn previous(&self) -> std::sync::MutexGuard<'_, Option<(Part, Option<PathBuf>)>> {
        self.previous.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Removes a part uploaded before (not the user's own file): no compute can use it any more.
    fn forget(&self, part: &Part) {
        if let Some(dir) = part.geometry.parent().filter(|d| d.starts_with(self.dir.path())) {
            let _ = std::fs::remove_dir_all(dir);
        }
    }

    /// `scene` (JSON from the page) as scene text with `geometry`: `absolute` names the file by
    /// its full path (to compute), else by its name (to save beside it).
    fn text(file: &Path, scene: &serde_json::Value, absolute: bool) -> Result<String, WorkshopError> {
        let refused = |e: &dyn std::fmt::Display| WorkshopError::Scene {
            message: format!("the page's scene: {e}"),
        };
        let mut table: toml::Table = serde_json::from_value(scene.clone()).map_err(|e| refused(&e))?;
        let geometry = table
            .entry("geometry")
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        let toml::Value::Table(geometry) = geometry else {
            return Err(refused(&"geometry must be a table"));
        };
        let file_ext = |f: &str| {
            Path::new(f)
                .extension()
                .map(|e| e.to_string_lossy().to_ascii_lowercase())
                .unwrap_or_default()
        };
        let file = if absolute {
            file.display().to_string()
        } else {
            file.file_name()
                .map_or(String::new(), |n| n.to_string_lossy().into_owned())
        };
        let ext = file_ext(&file);
        geometry.insert("step".into(), toml::Value::String(file));
        // A STEP or IGES file carries its unit: a `unit` beside it would be ignored (and warned
        // about when it differs), so the scene the page saves leaves it out.
        if matches!(ext.as_str(), "step" | "stp" | "iges" | "igs") {
            geometry.remove("unit");
        }
        toml::to_string(&table).map_err(|e| refused(&e))
    }
}

/// Set by [`isolate_with`]: the `ves` binary that computes in a child process.
static CHILD: OnceLock<PathBuf> = OnceLock::new();

/// The hidden subcommand of the `ves` binary that runs one compute of the viewer.
pub const COMPUTE_COMMAND: &str = "view-compute";

/// Runs the viewer's computes in child processes of `exe`, which must answer
/// `exe view-compute DIR` with [`serve_compute`]: a compute that aborts (a factorisation that
/// does not fit in memory), crashes or is killed ends its process, not the server with every
/// page. The `ves` binary turns this on; a library user computes in-process unless it does too.
pub fn isolate_with(exe: PathBuf) {
    let _ = CHILD.set(exe);
}

/// What a compute process is given (`job.json` in its folder).
#[derive(serde::Serialize, serde::Deserialize)]
struct ComputeJob {
    /// The scene's text, its geometry named by its full path.
    scene: String,
    /// The path it is parsed as (errors name "scene" instead).
    path: PathBuf,
    /// The basis file to write.
    out: PathBuf,
    /// The solver, by its command-line name.
    solver: String,
    /// The parent's process id: the child ends at once if it already has another parent.
    parent: u32,
    /// The basis the session serves: when only supports, material or modes changed, an instant
    /// basis is made from it first.
    #[serde(default)]
    previous: Option<PathBuf>,
}

/// Set-ups whose bases are kept for a request of the same set-up ([`PartWorkshop::keep`]): an
/// engineer comparing how a part is held goes back and forth between a few.
const KEPT: usize = 8;

/// Bytes of kept bases at most (the newest is kept whatever its size): the mould's converged
/// basis of 30 modes is 22 MB.
const KEPT_BYTES: u64 = 2 << 30;

/// What identifies a set-up for [`PartWorkshop::keep`]: the page's scene with every number
/// read as a float (a page's `0` and a scene file's `0.0` are one value), the geometry's path and
/// a fingerprint of its bytes (a part exported again from CAD to the same file is another part).
/// None when the geometry cannot be read (the compute says why).
fn setup_key(scene: &serde_json::Value, geometry: &Path) -> Option<String> {
    fn floats(v: &serde_json::Value) -> serde_json::Value {
        use serde_json::Value;
        match v {
            Value::Number(n) => n
                .as_f64()
                .and_then(serde_json::Number::from_f64)
                .map_or_else(|| v.clone(), Value::Number),
            Value::Array(a) => Value::Array(a.iter().map(floats).collect()),
            Value::Object(o) => Value::Object(o.iter().map(|(k, v)| (k.clone(), floats(v))).collect()),
            _ => v.clone(),
        }
    }
    let bytes = std::fs::read(geometry).ok()?;
    let mut f = ves_pipeline::fingerprint::Fingerprint::default();
    f.field(&bytes);
    Some(format!("{:016x} {}\n{}", f.value(), geometry.display(), floats(scene)))
}

/// Removes a basis made here and its sidecars (`basis-N.*`).
fn remove_basis(basis: &Path) {
    let (Some(dir), Some(stem)) = (basis.parent(), basis.file_stem()) else {
        return;
    };
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        if e.path().file_stem() == Some(stem) {
            let _ = std::fs::remove_file(e.path());
        }
    }
}

/// Where a compute writing `out` puts its instant basis (`basis-N-instant.h5`).
fn instant_path(out: &Path) -> PathBuf {
    let stem = out
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    out.with_file_name(format!("{stem}-instant.h5"))
}

/// The page's line for an instant basis: what it is, its bound, and that the converged one follows.
fn instant_line(summary: &precompute::Summary, check: &precompute::instant::InstantCheck) -> String {
    format!(
        "instant basis in {:.2} s (the previous mesh, {} solves): {}; {} · the converged basis follows",
        summary.timings_s.total,
        check.solves,
        check.text(),
        summary_line(summary)
    )
}

/// By how much the converged frequencies differ from the instant ones, relative, the largest.
fn moved(instant: &[f64], converged: &[f64]) -> Option<f64> {
    instant
        .iter()
        .zip(converged)
        .map(|(a, b)| (b - a) / b)
        .max_by(|a, b| a.abs().total_cmp(&b.abs()))
}

/// What a compute process says, one JSON line each on its stdout.
#[derive(serde::Serialize, serde::Deserialize)]
enum ChildNote {
    /// A stage began.
    Progress { stage: String, fraction: f64 },
    /// An instant basis is written (beside the job's, [`instant_path`]); the converged compute
    /// goes on. `first_look`: it is the first mesh of a refinement, not the previous mesh's.
    Instant {
        summary: String,
        frequencies_hz: Vec<f64>,
        #[serde(default)]
        first_look: bool,
        /// [`mesh_of`] its summary.
        #[serde(default)]
        mesh: serde_json::Value,
    },
    /// The basis is written, its checks to come: the child waits for `check` on its stdin.
    First {
        summary: String,
        estimated_error: Option<f64>,
        #[serde(default)]
        frequencies_hz: Vec<f64>,
        /// The warnings so far.
        #[serde(default)]
        warnings: Vec<String>,
        #[serde(default)]
        mesh: serde_json::Value,
    },
    /// The checks are written too.
    Done {
        summary: String,
        estimated_error: Option<f64>,
        /// Every warning of the compute.
        #[serde(default)]
        warnings: Vec<String>,
        #[serde(default)]
        mesh: serde_json::Value,
    },
    /// The compute failed (one line).
    Error(String),
}

/// How a compute process ended, when it said nothing of it.
fn describe(status: Option<std::process::ExitStatus>) -> String {
    use std::os::unix::process::ExitStatusExt;
    let Some(status) = status else {
        return "its status is unknown".into();
    };
    match (status.code(), status.signal()) {
        (_, Some(6)) => "it aborted (out of memory? a smaller mesh or fewer modes need less)".into(),
        (_, Some(9)) => "it was killed (SIGKILL: out of memory?)".into(),
        (_, Some(11)) => "it crashed (segmentation fault)".into(),
        (_, Some(s)) => format!("it was killed by signal {s}"),
        (Some(c), _) => format!("it exited with status {c} without a basis"),
        (None, None) => "no status".into(),
    }
}

/// Makes a basis and its XDMF sidecar (written beside it) readable by their owner only.
fn seal_basis(out: &Path) -> std::io::Result<()> {
    let sidecar = out.with_extension("xdmf");
    if sidecar.exists() {
        ves_pipeline::workdir::seal(&sidecar)?;
    }
    ves_pipeline::workdir::seal(out)
}

/// Deletes a basis (and its sidecar) when dropped unless a session took it.
struct Unless<'a>(&'a Path, bool);

impl Drop for Unless<'_> {
    fn drop(&mut self) {
        if !self.1 {
            let _ = std::fs::remove_file(self.0);
            let _ = std::fs::remove_file(self.0.with_extension("xdmf"));
        }
    }
}

impl PartWorkshop {
    /// Runs `job` in a child process with its folder `dir` (its `$TMPDIR` too): its progress
    /// and basis come back as [`ChildNote`]s; Cancel kills it; its death is one line.
    #[allow(clippy::too_many_arguments)]
    fn compute_in_child(
        &self,
        exe: &Path,
        dir: &Path,
        job: &ComputeJob,
        saved: &str,
        progress: &Arc<dyn Fn(Progress) + Send + Sync>,
        cancel: &AtomicBool,
        ready: &mut dyn FnMut(&Computed) -> Result<(), WorkshopError>,
    ) -> Result<Computed, WorkshopError> {
        use std::io::{BufRead, Write};
        let mut served = Unless(&job.out, false);
        ves_pipeline::workdir::create_dir(dir).map_err(WorkshopError::Start)?;
        // serde_json's error as an io::Error keeps its message.
        let text = serde_json::to_string(job).map_err(|e| WorkshopError::Start(e.into()))?;
        ves_pipeline::workdir::write(&dir.join("job.json"), text.as_bytes()).map_err(WorkshopError::Start)?;
        let mut command = std::process::Command::new(exe);
        command
            .arg(COMPUTE_COMMAND)
            .arg(dir)
            .env("TMPDIR", dir)
            .stdin(std::process::Stdio::piped())
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped());
        // Beside a live session: below every other process, and off the haptic thread's core.
        // With the threads of an unrestricted run all the same: the assembly's partition follows
        // the thread count, and a rounding-level change can tip a target_error refinement, so
        // that the saved scene's `ves precompute` would not reproduce the page's basis.
        let cores = ves_runtime::realtime::compute_cores();
        if !cores.is_empty() && std::env::var_os("RAYON_NUM_THREADS").is_none() {
            let all = std::thread::available_parallelism().map_or(1, |n| n.get());
            command.env("RAYON_NUM_THREADS", all.to_string());
        }
        ves_pipeline::os::start_lowest(&mut command, &cores);
        let mut child = command.spawn().map_err(|error| WorkshopError::StartProcess {
            exe: exe.to_path_buf(),
            error,
        })?;
        let (tx, notes) = std::sync::mpsc::channel();
        let stdout = child.stdout.take();
        let reader = std::thread::spawn(move || {
            let Some(stdout) = stdout else { return };
            for line in std::io::BufReader::new(stdout).lines().map_while(Result::ok) {
                // Anything else a library prints there is not a note.
                if let Ok(n) = serde_json::from_str::<ChildNote>(&line)
                    && tx.send(n).is_err()
                {
                    break;
                }
            }
        });
        // Its warnings go on to the server's stderr; the last line says why it died, if it did
        // ("memory allocation of … bytes failed").
        let stderr = child.stderr.take();
        let last_words = std::thread::spawn(move || {
            let mut last = String::new();
            let Some(stderr) = stderr else { return last };
            for line in std::io::BufReader::new(stderr).lines().map_while(Result::ok) {
                eprintln!("{line}");
                if !line.trim().is_empty() {
                    last = line.trim().chars().take(300).collect();
                }
            }
            last
        });
        let mut stdin = child.stdin.take();
        let (mut outcome, mut killed) = (None, false);
        let mut instant: Option<Vec<f64>> = None;
        let mut first_look = false;
        let computed = |summary: String, estimated_error: Option<f64>, warnings: Vec<String>, mesh| Computed {
            basis: job.out.clone(),
            scene: saved.to_string(),
            summary,
            estimated_error,
            instant: false,
            warnings,
            mesh,
        };
        loop {
            let note = notes.recv_timeout(std::time::Duration::from_millis(50));
            match note {
                Ok(ChildNote::Progress { stage, fraction }) => progress(Progress { stage, fraction }),
                Ok(ChildNote::Instant {
                    summary,
                    frequencies_hz,
                    first_look: look,
                    mesh,
                }) => {
                    let basis = instant_path(&job.out);
                    let taken = seal_basis(&basis).map_err(WorkshopError::KeepBasis).and_then(|()| {
                        ready(&Computed {
                            basis: basis.clone(),
                            scene: saved.to_string(),
                            summary,
                            estimated_error: None,
                            instant: true,
                            warnings: Vec::new(),
                            mesh,
                        })
                    });
                    match taken {
                        Ok(()) => {
                            first_look = look;
                            instant = Some(frequencies_hz);
                            *self.last() = Some(basis);
                        }
                        // The converged basis may still be served.
                        Err(e) => tracing::warn!("the instant basis was not served: {e}"),
                    }
                }
                Ok(ChildNote::First {
                    summary,
                    estimated_error,
                    frequencies_hz,
                    warnings,
                    mesh,
                }) => {
                    let summary = match instant.as_deref().and_then(|i| moved(i, &frequencies_hz)) {
                        Some(m) => format!(
                            "{summary} · converged basis live: its frequencies differ from the {} by at most {:+.3} %",
                            if first_look { "first look's" } else { "instant ones" },
                            // A move below the last digit shown is no move ("-0.000 %" read as one).
                            if (100.0 * m).abs() < 5e-4 { 0.0 } else { 100.0 * m }
                        ),
                        None => summary,
                    };
                    let taken = seal_basis(&job.out)
                        .map_err(WorkshopError::KeepBasis)
                        .and_then(|()| ready(&computed(summary, estimated_error, warnings, mesh)));
                    match taken {
                        Ok(()) => {
                            served.1 = true;
                            *self.last() = Some(job.out.clone());
                            // The session serves this basis now: the ones before are of no more use.
                            self.remove_bases_but(&job.out);
                            if let Some(s) = stdin.as_mut() {
                                let _ = writeln!(s, "check").and_then(|()| s.flush());
                            }
                        }
                        Err(e) => {
                            outcome.get_or_insert(Err(e));
                            let _ = child.kill();
                        }
                    }
                }
                Ok(ChildNote::Done {
                    summary,
                    estimated_error,
                    warnings,
                    mesh,
                }) => {
                    let _ = seal_basis(&job.out);
                    outcome.get_or_insert(Ok(computed(summary, estimated_error, warnings, mesh)));
                }
                Ok(ChildNote::Error(message)) => {
                    outcome.get_or_insert(Err(WorkshopError::Failed { message }));
                }
                Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {
                    if cancel.load(Ordering::Relaxed) && !killed {
                        killed = true;
                        let _ = child.kill();
                    }
                }
                Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => break,
            }
        }
        drop(stdin);
        let status = child.wait().ok();
        let _ = reader.join();
        let last = last_words.join().unwrap_or_default();
        match outcome {
            Some(done) => done,
            None if killed => Err(WorkshopError::Cancelled {
                served: served.1 || instant.is_some(),
            }),
            None => Err(WorkshopError::ProcessEnded {
                how: describe(status),
                last_words: last,
            }),
        }
    }
}

/// The child's side of a compute: runs the job in `dir` and says how it goes on stdout
/// ([`ChildNote`] lines). An error is about the job's file only (the compute's own failures are
/// notes).
pub fn serve_compute(dir: &Path) -> anyhow::Result<()> {
    use anyhow::Context;
    use std::io::{BufRead, Write};
    let job: ComputeJob = ves_pipeline::workdir::child_job(dir, |j: &ComputeJob| j.parent)?;
    let file = dir.join("job.json");
    // Below the session in priority, the whole process (gmsh inherits it), as in-process
    // computes' pool is; started by a viewer, it is lower already (nice 19) and
    // stays so.
    ves_pipeline::os::lower_process_priority();
    let say = |n: ChildNote| {
        if let Ok(line) = serde_json::to_string(&n) {
            let mut out = std::io::stdout().lock();
            let _ = writeln!(out, "{line}").and_then(|()| out.flush());
        }
    };
    let solver: SolverChoice = job.solver.parse().with_context(|| file.display().to_string())?;
    let message = |e: anyhow::Error| format!("{e:#}").replace('\n', " ");
    let parsed = match Scene::parse(&job.path, &job.scene) {
        Ok(p) => p,
        Err(e) => {
            say(ChildNote::Error(
                e.to_string().replace(&job.path.display().to_string(), "scene"),
            ));
            return Ok(());
        }
    };
    let _watch = ves_pipeline::progress::watch(Arc::new(ChildWatch(say)));
    if let Some(previous) = &job.previous {
        match precompute::instant::run(&parsed, previous, &instant_path(&job.out)) {
            Ok(Some((summary, check))) => say(ChildNote::Instant {
                first_look: false,
                mesh: mesh_of(&summary),
                summary: instant_line(&summary, &check),
                frequencies_hz: summary
                    .spaces
                    .first()
                    .map(|s| s.frequencies_hz.clone())
                    .unwrap_or_default(),
            }),
            Ok(None) => {}
            // The converged compute still runs; it says what is wrong with the scene, if anything.
            Err(e) => tracing::info!("no instant basis: {}", message(e)),
        }
    }
    // A first look when a part is opened: a refinement may take minutes on a thin-walled part
    // (the corpus's cone cover: 4 meshes, 223 s), so its first mesh's basis, written without
    // its estimate, is served at once and the refined one replaces it.
    if job.previous.is_none() && parsed.mesh.target_error.is_some() && !refine::starts_remembered(&parsed) {
        let mut look = parsed.clone();
        look.mesh.target_error = None;
        // Its curved tets straightened at once: gmsh's smoother took 3.9 s of the cast
        // housing's 6.3 s meshing, for frequencies 0.06–0.22 % apart (the refinement smooths).
        look.mesh.smooth_curved = false;
        // A point contact, as an instant basis has: the contact patches of every surface vertex
        // took 0.75 s of the engine block's 8.5 s; the refined basis brings them.
        look.contact_radius = 0.0;
        match precompute::run_first(&look, &instant_path(&job.out), solver) {
            Ok(w) => say(ChildNote::Instant {
                first_look: true,
                mesh: mesh_of(&w.summary),
                summary: format!(
                    "first look: the first mesh, its error not estimated yet; {} · the refinement to {} % follows",
                    summary_line(&w.summary),
                    100.0 * parsed.mesh.target_error.unwrap_or(0.0)
                ),
                frequencies_hz: w
                    .summary
                    .spaces
                    .first()
                    .map(|s| s.frequencies_hz.clone())
                    .unwrap_or_default(),
            }),
            // The refinement still runs; it says what is wrong, if anything.
            Err(e) => tracing::info!("no first look: {}", message(e)),
        }
    }
    // The warnings go to the page too (they also go on to the server's stderr).
    let (first, warnings) = ves_pipeline::notices::collect(|| precompute::run_first(&parsed, &job.out, solver));
    let first = match first {
        Ok(f) => f,
        Err(e) => {
            say(ChildNote::Error(message(e)));
            return Ok(());
        }
    };
    say(ChildNote::First {
        mesh: mesh_of(&first.summary),
        summary: summary_line(&first.summary),
        estimated_error: worst_estimate(&first.summary),
        frequencies_hz: first
            .summary
            .spaces
            .first()
            .map(|s| s.frequencies_hz.clone())
            .unwrap_or_default(),
        warnings: warnings.clone(),
    });
    let mut go = String::new();
    let _ = std::io::stdin().lock().read_line(&mut go);
    if go.trim() != "check" {
        return Ok(());
    }
    let (checked, more) = ves_pipeline::notices::collect(|| first.check());
    match checked {
        Ok(s) => say(ChildNote::Done {
            mesh: mesh_of(&s),
            summary: summary_line(&s),
            estimated_error: worst_estimate(&s),
            warnings: warnings.into_iter().chain(more).collect(),
        }),
        Err(e) => say(ChildNote::Error(message(e))),
    }
    Ok(())
}

/// The child's stages, to its parent.
struct ChildWatch<F>(F);

impl<F: Fn(ChildNote) + Send + Sync> ves_pipeline::progress::Watcher for ChildWatch<F> {
    fn stage(&self, name: &str, fraction: f64) {
        (self.0)(ChildNote::Progress {
            stage: name.to_string(),
            fraction,
        });
    }
    fn cancelled(&self) -> bool {
        // The parent kills the process instead.
        false
    }
}

/// Reports the pipeline's stages to the page and passes its Cancel on.
struct PageWatch {
    progress: Arc<dyn Fn(Progress) + Send + Sync>,
    cancel: Arc<AtomicBool>,
}

impl ves_pipeline::progress::Watcher for PageWatch {
    fn stage(&self, name: &str, fraction: f64) {
        (self.progress)(Progress {
            stage: name.to_string(),
            fraction,
        });
    }
    fn cancelled(&self) -> bool {
        self.cancel.load(Ordering::Relaxed)
    }
}

impl Workshop for PartWorkshop {
    fn setup(&self) -> serde_json::Value {
        let materials: Vec<_> = MATERIALS
            .iter()
            .map(|m| {
                serde_json::json!({"name": m.name, "young": m.young, "poisson": m.poisson,
                                   "density": m.density, "yield_strength": m.yield_strength})
            })
            .collect();
        let part = self.part();
        serde_json::json!({
            "scene": part.start,
            "geometry": part.geometry.file_name().map(|n| n.to_string_lossy().into_owned()),
            "materials": materials,
        })
    }

    fn geometry(&self) -> Option<PathBuf> {
        Some(self.part().geometry.clone())
    }

    fn served_from_project(&self, basis: &Path) {
        *self.last() = Some(basis.to_path_buf());
    }

    fn compute(
        &self,
        scene: &serde_json::Value,
        progress: Arc<dyn Fn(Progress) + Send + Sync>,
        cancel: Arc<AtomicBool>,
        ready: &mut dyn FnMut(&Computed) -> Result<(), WorkshopError>,
    ) -> Result<Computed, WorkshopError> {
        let _busy = self.busy.lock().unwrap_or_else(|p| p.into_inner());
        let n = self.computed.fetch_add(1, Ordering::Relaxed) + 1;
        let geometry = self.part().geometry.clone();
        let text = Self::text(&geometry, scene, true)?;
        // Parsed as if it sat beside the geometry; its name in errors is the page's.
        let path = self.dir.path().join("page.toml");
        let parsed = Scene::parse(&path, &text).map_err(|e| WorkshopError::Scene {
            message: e.to_string().replace(&path.display().to_string(), "scene"),
        })?;
        if parsed.is_script() && !self.options.allow_geo_scripts {
            return Err(WorkshopError::Script);
        }
        let out = self.dir.path().join(format!("basis-{n}.h5"));
        let saved = Self::text(&geometry, scene, false)?;
        // The same set-up as a compute before: its basis, at once (the same scene, part and
        // solver make the same basis). Not for a script, which may read other files.
        let key = (!parsed.is_script()).then(|| setup_key(scene, &geometry)).flatten();
        if let Some(before) = key.as_deref().and_then(|k| self.kept_for(k)) {
            let again = Computed {
                summary: format!("{} · the same set-up as before: its basis served again", before.summary),
                ..before
            };
            ready(&again)?;
            *self.last() = Some(again.basis.clone());
            self.remove_bases_but(&again.basis);
            return Ok(again);
        }
        let computed = |summary: &precompute::Summary, warnings: &[String]| Computed {
            mesh: mesh_of(summary),
            basis: out.clone(),
            scene: saved.clone(),
            summary: summary_line(summary),
            estimated_error: worst_estimate(summary),
            instant: false,
            warnings: warnings.to_vec(),
        };
        if let Some(exe) = CHILD.get() {
            let job = ComputeJob {
                scene: text.clone(),
                path,
                out: out.clone(),
                solver: self.solver.name().to_string(),
                parent: std::process::id(),
                previous: self.last().clone().filter(|p| self.instant && p.exists()),
            };
            let dir = self.dir.path().join(format!("compute-{n}"));
            let done = self.compute_in_child(exe, &dir, &job, &saved, &progress, &cancel, ready);
            // Whatever happened: the child's own folders (meshing) are in there too.
            let _ = std::fs::remove_dir_all(&dir);
            if let (Ok(c), Some(k)) = (&done, &key) {
                self.keep(k, c);
            }
            // The page's user knows a part opened in the page by its name, not the folder the
            // server keeps it in.
            return done.map_err(|e| match e {
                WorkshopError::Failed { message } => WorkshopError::Failed {
                    message: message.replace(
                        &geometry.display().to_string(),
                        &geometry.file_name().unwrap_or_default().to_string_lossy(),
                    ),
                },
                e => e,
            });
        }
        let failed = |e: anyhow::Error| WorkshopError::Failed {
            message: format!("{e:#}").replace('\n', " "),
        };
        let _watch = ves_pipeline::progress::watch(Arc::new(PageWatch { progress, cancel }));
        // In the workshop's pool: faer and rayon take their threads from it. `ready` runs here,
        // outside the pool: the session it starts must not inherit the pool's lower priority.
        let (first, mut warnings) =
            ves_pipeline::notices::collect(|| self.pool.install(|| precompute::run_first(&parsed, &out, self.solver)));
        let first = match first {
            Ok(first) => first,
            Err(e) => {
                let _ = std::fs::remove_file(&out);
                return Err(failed(e));
            }
        };
        seal_basis(&out).map_err(WorkshopError::KeepBasis)?;
        if let Err(e) = ready(&computed(&first.summary, &warnings)) {
            let _ = std::fs::remove_file(&out);
            return Err(e);
        }
        // The session serves this basis now: the ones before are of no more use.
        self.remove_bases_but(&out);
        let (summary, more) = ves_pipeline::notices::collect(|| self.pool.install(|| first.check()));
        let summary = summary.map_err(failed)?;
        warnings.extend(more);
        // The checks wrote the file again.
        seal_basis(&out).map_err(WorkshopError::KeepBasis)?;
        let done = computed(&summary, &warnings);
        if let Some(k) = &key {
            self.keep(k, &done);
        }
        Ok(done)
    }

    fn open(&self, name: &str, bytes: &[u8]) -> Result<(), WorkshopError> {
        let file = Path::new(name)
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let ext = Path::new(&file)
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        let shown = ves_format::identifier::escape_for_terminal(&file);
        if ext == "geo" {
            return Err(WorkshopError::GeoUpload { file: shown });
        }
        if !["step", "stp", "iges", "igs", "brep"].contains(&ext.as_str()) {
            return Err(WorkshopError::Extension { file: shown });
        }
        if bytes.len() > ves_view::workshop::MAX_UPLOAD {
            return Err(WorkshopError::TooLarge {
                file: shown,
                bytes: bytes.len(),
            });
        }
        let Some(kind) = geometry_kind(bytes) else {
            return Err(WorkshopError::NotGeometry { file: shown });
        };
        let Ok(_busy) = self.busy.try_lock() else {
            return Err(WorkshopError::Busy { file: shown });
        };
        let n = self.computed.fetch_add(1, Ordering::Relaxed) + 1;
        // Its own directory: the part keeps the name the user knows (in the title and in the
        // saved scene), and a later part of the same name cannot replace it.
        let safe = safe_stem(Path::new(&file));
        let dir = self.dir.path().join(format!("part-{n}"));
        ves_pipeline::workdir::create_dir(&dir).map_err(WorkshopError::KeepPart)?;
        let path = dir.join(format!("{safe}.{}", if kind == "step" { ext.as_str() } else { kind }));
        if let Err(e) = ves_pipeline::workdir::write(&path, bytes) {
            let _ = std::fs::remove_dir_all(&dir);
            return Err(WorkshopError::KeepPart(e));
        }
        // Another part: no instant basis from the last one's.
        let last = self.last().take();
        let new = Part {
            start: starting_scene(&path),
            geometry: path,
        };
        let before = std::mem::replace(&mut *self.part(), new);
        // The part before is kept until the new one has made a basis; one kept from an opening
        // before is of no more use.
        if let Some((older, _)) = self.previous().replace((before, last)) {
            self.forget(&older);
        }
        Ok(())
    }

    fn settle(&self, keep: bool) {
        let Some((before, last)) = self.previous().take() else {
            return;
        };
        if keep {
            self.forget(&before);
        } else {
            let opened = std::mem::replace(&mut *self.part(), before);
            *self.last() = last;
            self.forget(&opened);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::fs::MetadataExt;

    fn mode(p: &Path) -> u32 {
        std::fs::metadata(p)
            .map(|m| m.mode() & 0o777)
            .unwrap_or_else(|e| panic!("{}: {e}", p.display()))
    }

    /// An uploaded part is readable by its owner only, in a folder only its owner can enter;
    /// the next part replaces it on disk too once that one has made a basis (before, every
    /// upload stayed until the end), and one that made none gives the part before back.
    #[test]
    fn uploaded_parts_are_private_and_a_replaced_one_is_removed() {
        let w = PartWorkshop::for_geometry(Path::new("part.step"), SolverChoice::Auto).unwrap();
        assert_eq!(mode(w.dir.path()), 0o700, "the work folder");
        let step = b"ISO-10303-21;\nHEADER;\n";
        w.open("first.step", step).unwrap();
        let first = w.part().geometry.clone();
        assert!(first.starts_with(w.dir.path()), "{}", first.display());
        assert_eq!(mode(&first), 0o600, "the uploaded part");
        assert_eq!(mode(first.parent().unwrap()), 0o700, "its folder");
        w.open("second.stp", step).unwrap();
        let second = w.part().geometry.clone();
        assert!(second.exists());
        // Kept until the second part's first compute ends.
        assert!(first.exists(), "the first part is gone before the second computed");
        w.settle(true);
        assert!(
            !first.exists() && !first.parent().unwrap().exists(),
            "the first part stays"
        );
        // A part that makes no basis: the one before is the part again, the new one removed.
        w.open("broken.step", step).unwrap();
        let broken = w.part().geometry.clone();
        w.settle(false);
        assert_eq!(w.part().geometry, second);
        assert!(!broken.exists() && !broken.parent().unwrap().exists());
        // A refused upload changes nothing.
        assert!(w.open("third.step", b"not a part").is_err());
        assert_eq!(w.part().geometry, second);
        let kept: Vec<_> = std::fs::read_dir(w.dir.path())
            .unwrap()
            .flatten()
            .map(|e| e.file_name())
            .collect();
        assert_eq!(kept.len(), 2, "the lock and the part open: {kept:?}");
    }

    /// A compute process's death is one line that says what it likely was.
    #[test]
    fn a_dead_compute_process_is_described_in_one_line() {
        use std::os::unix::process::ExitStatusExt;
        let status = |raw| Some(std::process::ExitStatus::from_raw(raw));
        assert!(
            describe(status(6)).contains("aborted (out of memory?"),
            "{}",
            describe(status(6))
        );
        assert!(describe(status(9)).contains("SIGKILL"));
        assert!(describe(status(1 << 8)).contains("status 1"));
        for raw in [6, 9, 11, 15, 1 << 8] {
            assert!(!describe(status(raw)).contains('\n'));
        }
    }

    /// While a compute holds the workshop, no part is opened.
    #[test]
    fn no_part_is_opened_while_a_compute_runs() {
        let w = PartWorkshop::for_geometry(Path::new("part.step"), SolverChoice::Auto).unwrap();
        let before = w.part().geometry.clone();
        let busy = w.busy.lock().unwrap();
        let e = w.open("other.step", b"ISO-10303-21;\n").unwrap_err().to_string();
        assert!(e.contains("compute is running"), "{e}");
        drop(busy);
        assert_eq!(w.part().geometry, before);
    }

    /// The page's scene is checked by the scene parser, exact shapes included: a force of four
    /// numbers from the page was read as its first three and computed.
    /// A STEP part's scene, as the page saves it, carries no `unit` (the file's own applies; a
    /// "mm" beside a part in metres drew a warning from the CLI); a BREP part's keeps it.
    #[test]
    fn the_saved_scene_of_a_step_part_leaves_the_unit_to_the_file() {
        let page = serde_json::json!({ "name": "p", "geometry": { "step": "", "unit": "mm" } });
        let saved = |file: &str| PartWorkshop::text(Path::new(file), &page, false).expect("scene text");
        for file in ["/parts/lever.step", "/parts/lever.STP", "/parts/lever.igs"] {
            let text = saved(file);
            assert!(!text.contains("unit"), "{file}: {text}");
        }
        assert!(saved("/parts/lever.brep").contains("unit = \"mm\""));
        // The page's starting scene says none either.
        assert!(
            starting_scene(Path::new("lever.step"))["geometry"]
                .get("unit")
                .is_none()
        );
    }

    /// A set-up asked for again is served from its kept basis, without a compute (the same
    /// file); another set-up in between is computed and
    /// kept too; the kept bases are bounded, the oldest removed with their files.
    #[test]
    fn a_set_up_asked_for_again_is_served_from_its_kept_basis() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../cases/cantilever/scene.toml");
        let scene = Scene::load(&root).expect("the cantilever scene");
        let w = PartWorkshop::for_scene(&scene, SceneOptions::default(), SolverChoice::Auto).expect("a workshop");
        let mut page = w.setup()["scene"].clone();
        page["mesh"] = serde_json::json!({ "size": 0.05, "order": 1, "error_estimate": false });
        page["modes"] = serde_json::json!({ "count": 4 });
        let clamped = page.clone();
        page["fixed"][0]["components"] = serde_json::json!(["z"]);
        let along_z = page;
        let mut served = Vec::new();
        let mut compute = |scene: &serde_json::Value| {
            let mut basis = None;
            let c = w
                .compute(scene, Arc::new(|_| {}), Arc::new(AtomicBool::new(false)), &mut |c| {
                    basis = Some(c.basis.clone());
                    Ok(())
                })
                .expect("computes");
            assert_eq!(basis.as_ref(), Some(&c.basis), "the basis served is the one returned");
            let f = ves_format::read::BasisReader::open(&c.basis)
                .and_then(|r| r.space("global")?.frequencies_hz())
                .expect("the basis reads");
            served.push((c, f));
        };
        compute(&clamped);
        compute(&along_z);
        compute(&clamped);
        // As a page sends it: the plane's 0.0 as 0.
        let mut integer = clamped.clone();
        integer["fixed"][0]["plane"]["value"] = serde_json::json!(0);
        compute(&integer);
        let [(first, f1), (other, f2), (again, _), (integer, _)] = &served[..] else {
            unreachable!()
        };
        assert_eq!(
            integer.basis, first.basis,
            "a number written as an integer is the same set-up"
        );
        assert_ne!(first.basis, other.basis);
        assert_ne!(f1, f2, "held along z only is another set-up");
        assert_eq!(again.basis, first.basis, "the kept basis is served again");
        assert!(again.summary.contains("served again"), "{}", again.summary);
        assert!(!other.summary.contains("served again"), "{}", other.summary);
        assert!(first.basis.is_file() && other.basis.is_file(), "both kept");
        // Bounded: more set-ups than kept push the oldest out, its file with it.
        for k in 0..KEPT {
            let fake = w.dir.path().join(format!("basis-fake-{k}.h5"));
            std::fs::write(&fake, b"x").expect("a stand-in file");
            w.keep(
                &format!("set-up {k}"),
                &Computed {
                    basis: fake,
                    ..first.clone()
                },
            );
        }
        assert_eq!(w.kept().len(), KEPT);
        assert!(!first.basis.exists() && !other.basis.exists(), "the oldest are removed");
        assert!(w.kept_for(&setup_key_of(&w, &clamped)).is_none());
    }

    /// The key [`PartWorkshop::compute`] keeps `scene` under.
    fn setup_key_of(w: &PartWorkshop, scene: &serde_json::Value) -> String {
        setup_key(scene, &w.part().geometry.clone()).expect("a key")
    }

    #[test]
    fn the_page_s_scene_is_refused_with_a_fourth_number() {
        let dir = tempfile::tempdir().expect("temp dir");
        let step = dir.path().join("part.step");
        std::fs::write(&step, "ISO-10303-21;").expect("geometry stub");
        let w = PartWorkshop::for_geometry(&step, SolverChoice::Auto).expect("a workshop");
        let mut scene = w.setup()["scene"].clone();
        scene["fixed"] = serde_json::json!([{ "plane": { "axis": "x", "value": 0.0 } }]);
        scene["load"] = serde_json::json!([{ "name": "tip", "faces": [1], "force": [0.0, 0.0, -1.0, 5.0] }]);
        let Err(e) = w.compute(&scene, Arc::new(|_| {}), Arc::new(AtomicBool::new(false)), &mut |_| {
            Ok(())
        }) else {
            panic!("a force of four numbers was computed");
        };
        let e = e.to_string();
        assert!(
            e.starts_with("scene: ") && e.contains("force: ") && e.contains("exactly 3 numbers"),
            "{e}"
        );
    }
}
