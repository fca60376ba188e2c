//! `ves.precompute` and `ves.matrices`: the pipeline library called in a thread of its own while
//! the caller's thread, GIL released between polls, watches for Ctrl-C and shows progress.

use crate::basis::Basis;
use crate::errors;
use numpy::IntoPyArray;
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use ves_pipeline::modes::SolverChoice;
use ves_pipeline::scene::{Scene, SceneError, SceneOptions};

/// One long computation at a time: the pipeline's progress watcher is process-wide.
static LONG_CALL: Mutex<()> = Mutex::new(());

/// How often the waiting thread looks at signals: a Ctrl-C reaches the pipeline at most this
/// late, so a run that ends within it may still write its output.
const POLL: Duration = Duration::from_millis(10);

/// How often the progress bar is redrawn.
const REDRAW: Duration = Duration::from_millis(100);

/// Told each stage by the pipeline; asked whether to stop.
#[derive(Default)]
struct Watch {
    cancel: AtomicBool,
    stage: Mutex<Option<(String, f64)>>,
}

impl ves_pipeline::progress::Watcher for Watch {
    fn stage(&self, name: &str, fraction: f64) {
        if let Ok(mut s) = self.stage.lock() {
            *s = Some((name.to_string(), fraction));
        }
    }

    fn cancelled(&self) -> bool {
        self.cancel.load(Ordering::Relaxed)
    }
}

/// A tqdm bar when tqdm is installed and progress is asked for; nothing otherwise.
fn progress_bar<'py>(py: Python<'py>, wanted: bool, what: &str) -> Option<Bound<'py, PyAny>> {
    if !wanted {
        return None;
    }
    let tqdm = py.import("tqdm").ok()?;
    let kwargs = PyDict::new(py);
    kwargs.set_item("total", 100).ok()?;
    kwargs.set_item("desc", what).ok()?;
    kwargs.set_item("unit", "%").ok()?;
    kwargs
        .set_item("bar_format", "{desc}: {percentage:3.0f}%|{bar}| [{elapsed}] {postfix}")
        .ok()?;
    tqdm.getattr("tqdm").ok()?.call((), Some(&kwargs)).ok()
}

fn show(bar: &Bound<'_, PyAny>, stage: &str, fraction: f64) -> PyResult<()> {
    bar.setattr("n", (fraction.clamp(0.0, 1.0) * 100.0).round())?;
    bar.call_method1("set_postfix_str", (stage,))?;
    bar.call_method0("refresh")?;
    Ok(())
}

/// Runs `work` on a thread of its own, the GIL released; Ctrl-C (a pending KeyboardInterrupt)
/// asks the pipeline to stop at its next stage (and sets `stop`, for work that watches a flag
/// of its own) and is raised once it has stopped.
pub(crate) fn run_long<T: Send + 'static>(
    py: Python<'_>,
    progress: bool,
    what: &str,
    stop: Option<Arc<AtomicBool>>,
    work: impl FnOnce() -> anyhow::Result<T> + Send + 'static,
) -> PyResult<T> {
    let watch = Arc::new(Watch::default());
    let w = watch.clone();
    let handle = std::thread::Builder::new()
        .name("ves-pipeline".into())
        .spawn(move || {
            let _one = LONG_CALL.lock().unwrap_or_else(|p| p.into_inner());
            let _guard = ves_pipeline::progress::watch(w);
            std::panic::catch_unwind(std::panic::AssertUnwindSafe(work))
        })
        .map_err(|e| errors::Error::new_err(format!("cannot start the pipeline thread: {e}")))?;
    let bar = progress_bar(py, progress, what);
    let mut interrupt: Option<PyErr> = None;
    let mut drawn = std::time::Instant::now();
    while !handle.is_finished() {
        py.detach(|| std::thread::sleep(POLL));
        if interrupt.is_none()
            && let Err(e) = py.check_signals()
        {
            watch.cancel.store(true, Ordering::Relaxed);
            if let Some(stop) = &stop {
                stop.store(true, Ordering::Relaxed);
            }
            interrupt = Some(e);
        }
        if let Some(bar) = bar.as_ref().filter(|_| drawn.elapsed() >= REDRAW) {
            drawn = std::time::Instant::now();
            let stage = watch.stage.lock().ok().and_then(|s| s.clone());
            if let Some((name, fraction)) = stage {
                show(bar, &name, fraction)?;
            }
        }
    }
    let result = py.detach(|| handle.join());
    if let Some(bar) = &bar {
        if matches!(result, Ok(Ok(Ok(_)))) {
            show(bar, "done", 1.0)?;
        }
        bar.call_method0("close")?;
    }
    if let Some(e) = interrupt {
        return Err(e);
    }
    match result {
        Ok(Ok(r)) => r.map_err(|e| errors::from_anyhow(&e)),
        _ => Err(errors::Error::new_err(
            "internal error (please report): the pipeline panicked",
        )),
    }
}

/// How deep a scene dict may nest: a scene is at most three tables deep (`load[0].box.min`).
/// A dict that holds itself, or lists nested thousands deep, recursed until the interpreter's
/// stack overflowed.
const MAX_SCENE_DEPTH: usize = 16;

/// How many values a scene dict may hold in all: a scene's text is at most
/// [`ves_pipeline::scene::MAX_SCENE_TEXT_BYTES`], two bytes a value at the least.
const MAX_SCENE_VALUES: usize = ves_pipeline::scene::MAX_SCENE_TEXT_BYTES / 2;

/// `key` as an error quotes it: its first 120 characters.
fn shown(key: &str) -> String {
    match key.char_indices().nth(120) {
        Some((at, _)) => format!("{}…", &key[..at]),
        None => key.to_string(),
    }
}

/// A Python value of a scene dict as TOML; `key` names where it is, for the error; `depth` is
/// its nesting level, `left` how many more values the whole dict may hold.
fn to_toml(v: &Bound<'_, PyAny>, key: &str, depth: usize, left: &mut usize) -> PyResult<toml::Value> {
    if depth > MAX_SCENE_DEPTH {
        return Err(errors::SceneError::new_err(format!(
            "scene key {}: nested more than {MAX_SCENE_DEPTH} levels deep (a dict or list that holds itself?); a \
             scene is a few tables deep",
            shown(key)
        )));
    }
    *left = left.checked_sub(1).ok_or_else(|| {
        errors::SceneError::new_err(format!(
            "the scene dict holds more than {MAX_SCENE_VALUES} entries in all (at {}); a scene is at most {} KiB \
             of TOML",
            shown(key),
            ves_pipeline::scene::MAX_SCENE_TEXT_BYTES >> 10
        ))
    })?;
    if v.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(v.extract()?));
    }
    if v.is_instance_of::<PyInt>() {
        return v
            .extract::<i64>()
            .map(toml::Value::Integer)
            .map_err(|_| PyValueError::new_err(format!("scene key {key}: integer out of range")));
    }
    if v.is_instance_of::<PyFloat>() {
        return Ok(toml::Value::Float(v.extract()?));
    }
    if let Ok(s) = v.cast::<PyString>() {
        return Ok(toml::Value::String(s.extract::<String>()?));
    }
    if let Ok(d) = v.cast::<PyDict>() {
        let mut t = toml::map::Map::new();
        for (k, item) in d.iter() {
            let name: String = k
                .extract()
                .map_err(|_| PyTypeError::new_err(format!("scene key {key}: table keys must be strings")))?;
            let path = if key.is_empty() {
                name.clone()
            } else {
                format!("{key}.{name}")
            };
            t.insert(name, to_toml(&item, &path, depth + 1, left)?);
        }
        return Ok(toml::Value::Table(t));
    }
    if v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>() {
        let mut a = Vec::new();
        for (i, item) in v.try_iter()?.enumerate() {
            a.push(to_toml(&item?, &format!("{key}[{i}]"), depth + 1, left)?);
        }
        return Ok(toml::Value::Array(a));
    }
    if v.is_none() {
        return Err(PyTypeError::new_err(format!(
            "scene key {key}: None is not a TOML value; leave the key out"
        )));
    }
    // numpy scalars and other numbers.
    if let Ok(x) = v.extract::<f64>() {
        return Ok(toml::Value::Float(x));
    }
    Err(PyTypeError::new_err(format!(
        "scene key {key}: a {} is not a TOML value (give numbers, strings, booleans, lists and dicts)",
        v.get_type().name()?
    )))
}

/// A scene from a path to its TOML file, or from a dict of the TOML's structure (paths in it
/// relative to the current directory).
pub(crate) fn scene_from(scene: &Bound<'_, PyAny>, allow_geo_scripts: bool) -> PyResult<Scene> {
    let py = scene.py();
    let options = SceneOptions { allow_geo_scripts };
    let parsed = if let Ok(d) = scene.cast::<PyDict>() {
        let mut left = MAX_SCENE_VALUES;
        let value = to_toml(d.as_any(), "", 0, &mut left)?;
        let text = toml::to_string(&value)
            .map_err(|e| PyValueError::new_err(format!("the scene dict cannot be written as TOML: {e}")))?;
        let name = value
            .get("name")
            .and_then(|n| n.as_str())
            .filter(|n| ves_format::check_identifier("name", n).is_ok())
            .unwrap_or("scene")
            .to_string();
        let cwd = std::env::current_dir()
            .map_err(|e| errors::Error::new_err(format!("cannot read the current directory: {e}")))?;
        let path = cwd.join(format!("{name}.toml"));
        Scene::parse(&path, &text).and_then(|s| {
            if s.is_script() && !allow_geo_scripts {
                Err(SceneError {
                    file: path.clone(),
                    message: format!(
                        "geometry.step = {:?}: a .geo file is a gmsh script and can run shell commands; export the \
                         part as STEP, or pass allow_geo_scripts=True if you trust this scene",
                        s.geometry.display()
                    ),
                })
            } else {
                Ok(s)
            }
        })
    } else {
        let path: PathBuf = scene.extract().map_err(|_| {
            PyTypeError::new_err("scene: give the path of a scene file (str or os.PathLike) or a dict of its tables")
        })?;
        py.detach(|| Scene::load_with(&path, options))
    };
    parsed.map_err(|e| errors::SceneError::new_err(e.to_string()))
}

fn solver_choice(name: &str) -> PyResult<SolverChoice> {
    match name.to_ascii_lowercase().as_str() {
        "auto" => Ok(SolverChoice::Auto),
        "block" => Ok(SolverChoice::Block),
        "arpack" => Ok(SolverChoice::Arpack),
        "dense" => Ok(SolverChoice::Dense),
        "slepc" | "slepc-iterative" => Err(PyValueError::new_err(format!(
            "solver={name:?}: SLEPc runs under mpirun; use the `ves` command built with the slepc feature"
        ))),
        _ => Err(PyValueError::new_err(format!(
            "solver={name:?}: give \"auto\", \"block\", \"arpack\" or \"dense\""
        ))),
    }
}

/// Meshes the scene, assembles K and M, computes the lowest modes and writes a basis file
/// (default: beside the scene, `<name>.h5`); returns it opened.
#[pyfunction]
#[pyo3(signature = (scene, out=None, *, solver="auto", progress=true, modes=None, force=false, allow_geo_scripts=false))]
#[allow(clippy::too_many_arguments)]
pub fn precompute(
    py: Python<'_>,
    scene: &Bound<'_, PyAny>,
    out: Option<PathBuf>,
    solver: &str,
    progress: bool,
    modes: Option<usize>,
    force: bool,
    allow_geo_scripts: bool,
) -> PyResult<Basis> {
    let choice = solver_choice(solver)?;
    let (loaded, mut warnings) = ves_pipeline::notices::collect(|| scene_from(scene, allow_geo_scripts));
    let mut scene = loaded?;
    if let Some(m) = modes {
        if !(1..=2000).contains(&m) {
            return Err(PyValueError::new_err(format!("modes={m}: must be between 1 and 2000")));
        }
        scene.modes.count = m;
    }
    let out = out.unwrap_or_else(|| scene.path.with_file_name(format!("{}.h5", scene.name)));
    let target = out.clone();
    let what = format!("precompute {}", scene.name);
    let summary = run_long(py, progress, &what, None, move || {
        let overwrite = ves_pipeline::output::Overwrite { force };
        let (done, more) =
            ves_pipeline::notices::collect(|| ves_pipeline::precompute::run_with(&scene, &target, choice, overwrite));
        let mut summary = done?;
        warnings.extend(more);
        summary.warnings = warnings;
        Ok(serde_json::to_string(&summary)?)
    })?;
    let summary = py.import("json")?.call_method1("loads", (summary,))?;
    let listed: Vec<String> = summary.get_item("warnings")?.extract()?;
    errors::warn_all(py, &listed)?;
    let summary = summary.unbind();
    Basis::read(py, out, Some(summary))
}

/// K and M of a scene's global space on its free DOFs, as CSC lower triangles, with the map
/// from free to full DOF index (3·node + component), the nodes and the tets.
#[pyfunction]
#[pyo3(signature = (scene, *, progress=true, allow_geo_scripts=false))]
pub fn _matrices<'py>(
    py: Python<'py>,
    scene: &Bound<'py, PyAny>,
    progress: bool,
    allow_geo_scripts: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let scene = scene_from(scene, allow_geo_scripts)?;
    let what = format!("matrices {}", scene.name);
    let (col_ptr, row_idx, k, m, free, nodes, rigid) = run_long(py, progress, &what, None, move || {
        let d = ves_pipeline::problem::discretize(&scene, None)?;
        let p = &d.system.pattern;
        let as_i64 = |v: &[usize]| v.iter().map(|&x| x as i64).collect::<Vec<i64>>();
        let nodes: Vec<f64> = d.mesh.nodes.iter().flatten().copied().collect();
        Ok((
            as_i64(p.col_ptr()),
            as_i64(p.row_idx()),
            d.system.k.clone(),
            d.system.m.clone(),
            d.dofs.free.clone(),
            nodes,
            d.rigid,
        ))
    })?;
    let out = PyDict::new(py);
    out.set_item("col_ptr", col_ptr.into_pyarray(py))?;
    out.set_item("row_idx", row_idx.into_pyarray(py))?;
    out.set_item("k", k.into_pyarray(py))?;
    out.set_item("m", m.into_pyarray(py))?;
    out.set_item("free_dofs", free.into_pyarray(py))?;
    let n = nodes.len() / 3;
    let nodes = numpy::ndarray::Array2::from_shape_vec((n, 3), nodes)
        .map_err(|e| errors::Error::new_err(format!("node array: {e}")))?;
    out.set_item("nodes", nodes.into_pyarray(py))?;
    out.set_item("rigid_modes", rigid)?;
    Ok(out)
}

/// Cross-checks a scene (meshed and solved here) or a basis file (or an open `Basis`) against
/// independent solvers on the same mesh, as `ves verify --json`; returns its report as a dict
/// (`report["pass"]` says whether every tolerance held). `against`: "scikit-fem", "calculix",
/// "fenicsx" or "all" (those installed).
#[pyfunction]
#[pyo3(signature = (input, against="all", *, modes=None, tol_freq=None, min_mac=None, max_angle=None, tol_static=None, stress=false, tol_stress=None, progress=true))]
#[allow(clippy::too_many_arguments)]
pub fn verify<'py>(
    py: Python<'py>,
    input: &Bound<'py, PyAny>,
    against: &str,
    modes: Option<usize>,
    tol_freq: Option<f64>,
    min_mac: Option<f64>,
    max_angle: Option<f64>,
    tol_static: Option<f64>,
    stress: bool,
    tol_stress: Option<f64>,
    progress: bool,
) -> PyResult<Bound<'py, PyAny>> {
    use ves_pipeline::verify::{Against, ToleranceOverrides};
    let name = match against.to_ascii_lowercase() {
        short if short == "skfem" => "scikit-fem".to_string(),
        name => name,
    };
    let refs: Against = name.parse().map_err(|_| {
        PyValueError::new_err(format!(
            "against={against:?}: give {}",
            ves_pipeline::verify::reference::known_names()
        ))
    })?;
    if modes == Some(0) {
        return Err(PyValueError::new_err("modes=0: compare at least one mode"));
    }
    for (name, value) in [
        ("tol_freq", tol_freq),
        ("min_mac", min_mac),
        ("max_angle", max_angle),
        ("tol_static", tol_static),
        ("tol_stress", tol_stress),
    ] {
        if let Some(v) = value
            && !(v.is_finite() && v > 0.0)
        {
            return Err(PyValueError::new_err(format!("{name}={v}: must be finite and > 0")));
        }
    }
    let path = crate::basis::path_of(
        input,
        "input: give the path of a scene (.toml) or basis (.h5) file, or a ves.Basis",
    )?;
    let tol = ToleranceOverrides {
        freq: tol_freq,
        mac: min_mac,
        angle: max_angle,
        static_rel: tol_static,
        stress: tol_stress,
        load: None,
    };
    let what = format!("verify {}", path.display());
    let report = run_long(py, progress, &what, None, move || {
        let report = ves_pipeline::verify::verify_input(&path, refs, modes, &tol, stress)?;
        Ok(serde_json::to_string(&report)?)
    })?;
    py.import("json")?.call_method1("loads", (report,))
}

/// A part's CAD faces, as `ves faces --json`: a list of dicts (tag — what a scene's
/// `faces = [...]` names —, kind "plane" / "cylinder" / "other", area_m2, centroid_m, normal of a
/// plane; axis, axis_point_m, radius_m and concave of a cylinder; name, the STEP file's name of
/// the face where it gives one, else None). `path`: a STEP or IGES part, or a scene (.toml).
#[pyfunction]
#[pyo3(signature = (path, *, progress=true, allow_geo_scripts=false))]
pub fn faces<'py>(
    py: Python<'py>,
    path: PathBuf,
    progress: bool,
    allow_geo_scripts: bool,
) -> PyResult<Bound<'py, PyAny>> {
    let what = format!("faces of {}", path.display());
    let listed = run_long(py, progress, &what, None, move || {
        Ok(serde_json::to_string(&ves_pipeline::faces::list(
            &path,
            allow_geo_scripts,
        )?)?)
    })?;
    py.import("json")?.call_method1("loads", (listed,))
}

/// Makes meshing run in child processes started from `worker` (`worker mesh-worker DIR`), so
/// that nothing gmsh does can end the interpreter.
#[pyfunction]
pub fn _isolate_meshing(worker: PathBuf) {
    ves_pipeline::mesh::isolate_with(worker);
}

/// The child's side: meshes one rung of the ladder in `dir` (what `ves mesh-worker DIR` does).
#[pyfunction]
pub fn _serve_mesh_rung(py: Python<'_>, dir: PathBuf) -> PyResult<()> {
    py.detach(|| ves_pipeline::mesh::serve_rung(Path::new(&dir)))
        .map_err(|e| errors::MeshError::new_err(e.to_string()))
}
