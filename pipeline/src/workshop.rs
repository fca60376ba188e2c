//! The viewer's set-up panel, pipeline side: a scene edited in the page becomes a basis.
//!
//! The page sends the scene as JSON (the TOML's tables and keys); it is checked by the same
//! parser as every scene file. The geometry is always the workshop's own file: whatever the
//! page names as `geometry.step` is replaced, so a page cannot make the server read another
//! file. Bases go to a private temporary directory, removed when the viewer ends.

use crate::modes::SolverChoice;
use crate::precompute;
use crate::scene::{Scene, SceneOptions};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use ves_runtime::view::{Computed, Progress, Workshop};

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

/// Computes bases for one part (or the parts the page opens) in a private directory.
pub struct PartWorkshop {
    part: std::sync::Mutex<Part>,
    options: SceneOptions,
    dir: tempfile::TempDir,
    computed: AtomicU64,
    solver: SolverChoice,
    /// The compute's threads, below the session's in priority (see [`lower_priority`]).
    pool: rayon::ThreadPool,
}

/// The part being set up: its geometry file and the scene the page starts from.
struct Part {
    geometry: PathBuf,
    start: serde_json::Value,
}

/// One line for the page: the first space's size and frequencies, the time, and the largest
/// estimated error when the estimate is in.
fn summary_line(summary: &precompute::Summary) -> String {
    let Some(g) = summary.spaces.first() else {
        return String::new();
    };
    let mut line = format!(
        "{} nodes, {} modes, first {:.4} Hz, in {:.1} s",
        g.nodes,
        g.frequencies_hz.len(),
        g.frequencies_hz.first().copied().unwrap_or(0.0),
        summary.timings_s.total
    );
    if let Some(e) = worst_estimate(summary) {
        line.push_str(&format!("; estimated frequency error ≤ {:.2} %", 100.0 * e));
    }
    line
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
        "geometry": { "step": "", "unit": "mm" },
        "material": { "young": steel.young, "poisson": steel.poisson, "density": steel.density,
                      "yield_strength": steel.yield_strength },
        "mesh": { "order": 2, "target_error": 0.05 },
        "modes": { "count": 12 },
        "stress": { "enabled": true },
        "damping": { "alpha": 0.0, "beta": 1.0e-5 },
    })
}

/// A file's stem as a scene name and a file name: ASCII letters, digits, `-` and `_` (others
/// become `_`), at most 64 characters; "part" for none.
fn safe_stem(path: &Path) -> String {
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
    // SAFETY: setpriority on this thread's own id (Linux: PRIO_PROCESS with a thread id sets
    // that thread's nice value), no memory involved.
    #[cfg(target_os = "linux")]
    unsafe {
        let tid = libc::gettid();
        libc::setpriority(libc::PRIO_PROCESS, tid as libc::id_t, 10);
    }
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
        let dir = tempfile::Builder::new().prefix("ves-view-").tempdir()?;
        let pool = rayon::ThreadPoolBuilder::new()
            .thread_name(|i| format!("ves-compute-{i}"))
            .start_handler(|_| lower_priority())
            .build()?;
        Ok(PartWorkshop {
            pool,
            part: std::sync::Mutex::new(Part { geometry, start }),
            options,
            dir,
            computed: AtomicU64::new(0),
            solver,
        })
    }

    fn part(&self) -> std::sync::MutexGuard<'_, Part> {
        self.part.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// `scene` (JSON from the page) as scene text with `geometry`: `absolute` names the file by
    /// its full path (to compute), else by its name (to save beside it).
    fn text(file: &Path, scene: &serde_json::Value, absolute: bool) -> Result<String, String> {
        let mut table: toml::Table =
            serde_json::from_value(scene.clone()).map_err(|e| format!("the page's scene: {e}"))?;
        let geometry = table
            .entry("geometry")
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        let toml::Value::Table(geometry) = geometry else {
            return Err("the page's scene: geometry must be a table".into());
        };
        let file = if absolute {
            file.display().to_string()
        } else {
            file.file_name()
                .map_or(String::new(), |n| n.to_string_lossy().into_owned())
        };
        geometry.insert("step".into(), toml::Value::String(file));
        toml::to_string(&table).map_err(|e| format!("the page's scene: {e}"))
    }
}

/// Reports the pipeline's stages to the page and passes its Cancel on.
struct PageWatch {
    progress: Arc<dyn Fn(Progress) + Send + Sync>,
    cancel: Arc<AtomicBool>,
}

impl crate::progress::Watcher for PageWatch {
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

    fn compute(
        &self,
        scene: &serde_json::Value,
        progress: Arc<dyn Fn(Progress) + Send + Sync>,
        cancel: Arc<AtomicBool>,
        ready: &mut dyn FnMut(&Computed) -> Result<(), String>,
    ) -> Result<Computed, String> {
        let n = self.computed.fetch_add(1, Ordering::Relaxed) + 1;
        let geometry = self.part().geometry.clone();
        let text = Self::text(&geometry, scene, true)?;
        // Parsed as if it sat beside the geometry; its name in errors is the page's.
        let path = self.dir.path().join("page.toml");
        let parsed =
            Scene::parse(&path, &text).map_err(|e| e.to_string().replace(&path.display().to_string(), "scene"))?;
        if parsed.is_script() && !self.options.allow_geo_scripts {
            return Err("a .geo geometry is a gmsh script: open a STEP, IGES or BREP file".into());
        }
        let out = self.dir.path().join(format!("basis-{n}.h5"));
        let saved = Self::text(&geometry, scene, false)?;
        let computed = |summary: &precompute::Summary| Computed {
            basis: out.clone(),
            scene: saved.clone(),
            summary: summary_line(summary),
            estimated_error: worst_estimate(summary),
        };
        let message = |e: anyhow::Error| format!("{e:#}").replace('\n', " ");
        let _watch = crate::progress::watch(Arc::new(PageWatch { progress, cancel }));
        // In the workshop's pool: faer and rayon take their threads from it. `ready` runs here,
        // outside the pool: the session it starts must not inherit the pool's lower priority.
        let first = self
            .pool
            .install(|| precompute::run_first(&parsed, &out, self.solver))
            .map_err(message)?;
        ready(&computed(&first.summary))?;
        let summary = self.pool.install(|| first.check()).map_err(message)?;
        Ok(computed(&summary))
    }

    fn open(&self, name: &str, bytes: &[u8]) -> Result<(), String> {
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
            return Err(format!(
                "{shown}: a .geo file is a gmsh script and can run commands; export the part as STEP, IGES or BREP"
            ));
        }
        if !["step", "stp", "iges", "igs", "brep"].contains(&ext.as_str()) {
            return Err(format!(
                "{shown}: open a STEP (.step, .stp), IGES (.iges, .igs) or BREP (.brep) file"
            ));
        }
        if bytes.len() > ves_runtime::view::workshop::MAX_UPLOAD {
            return Err(format!(
                "{shown}: {} bytes, more than the {} MiB a page may send",
                bytes.len(),
                ves_runtime::view::workshop::MAX_UPLOAD >> 20
            ));
        }
        let kind = geometry_kind(bytes).ok_or_else(|| {
            format!("{shown}: not a STEP, IGES or BREP file (a STEP file starts with ISO-10303-21); export the part again from its CAD system")
        })?;
        let n = self.computed.fetch_add(1, Ordering::Relaxed) + 1;
        // Its own directory: the part keeps the name the user knows (in the title and in the
        // saved scene), and a later part of the same name cannot replace it.
        let safe = safe_stem(Path::new(&file));
        let dir = self.dir.path().join(format!("part-{n}"));
        std::fs::create_dir(&dir).map_err(|e| format!("cannot keep the part: {e}"))?;
        let path = dir.join(format!("{safe}.{}", if kind == "step" { ext.as_str() } else { kind }));
        crate::output::write_atomically(&path, |tmp| std::fs::write(tmp, bytes).map_err(Into::into))
            .map_err(|e| format!("cannot keep the part: {e:#}"))?;
        let mut part = self.part();
        part.start = starting_scene(&path);
        part.geometry = path;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The page's scene is checked by the scene parser, exact shapes included: a force of four
    /// numbers from the page was read as its first three and computed.
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
        assert!(
            e.starts_with("scene: ") && e.contains("force: ") && e.contains("exactly 3 numbers"),
            "{e}"
        );
    }
}
