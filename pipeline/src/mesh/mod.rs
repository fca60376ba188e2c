//! Meshing with gmsh: geometry file → tetrahedral mesh in metres, corner vertices numbered first.

use crate::scene::{LengthUnit, Scene, Voi};

mod cache;
pub mod field;
mod isolation;
pub mod remembered;
use crate::fem::element::Kind;
pub(crate) use crate::tet_mesh::signed_volume;
// Element quality and wall thickness are the mesh type's own (the numerics core).
pub use crate::tet_mesh::{Mesh, TET10_EDGES, quality, walls};
pub use isolation::{WorkerError, isolate_with, serve as serve_rung};
use std::collections::HashMap;
use ves_gmsh::{self as gmsh, element_type};

/// Meshing failed.
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    /// gmsh reported an error.
    #[error("{path}: {cause}")]
    Gmsh {
        /// Geometry file.
        path: String,
        /// gmsh's error (in the message, so not also a `source`).
        cause: gmsh::GmshError,
    },
    /// The file opened but holds no usable solid.
    #[error("{path}: {message}")]
    Geometry {
        /// Geometry file.
        path: String,
        /// What is wrong.
        message: String,
    },
}

impl MeshError {
    /// What went wrong, without the file name.
    pub fn cause(&self) -> String {
        match self {
            MeshError::Gmsh { cause, .. } => cause.to_string(),
            MeshError::Geometry { message, .. } => message.clone(),
        }
    }
}

/// Most tets a mesh may have: beyond it gmsh's memory (≈ 1 kB per tet while meshing) and the
/// eigen-solve's outgrow a workstation, and a too-small `mesh.size` ends gmsh with bad_alloc.
pub const MAX_TETS: f64 = 10.0e6;

/// Volume of a regular tet of edge `h` (gmsh aims at such tets).
fn regular_tet_volume(h: f64) -> f64 {
    h * h * h / (6.0 * std::f64::consts::SQRT_2)
}

/// Upper estimate of the tets of a box of extent `e` (m) filled with regular tets of edge `h`; a
/// flat or thin box gets at least one element across each direction. Decreases as `h` grows.
fn tets_in(e: [f64; 3], h: f64) -> f64 {
    e.iter().map(|&x| x.max(h)).product::<f64>() / regular_tet_volume(h)
}

/// The smallest size, as printed with three significant digits (`{:.2e}`), whose [`tets_in`] `e`
/// is at most `budget` (which must exceed the 8.5 tets of one element filling the box).
fn size_for_budget(e: [f64; 3], budget: f64) -> f64 {
    let (mut lo, mut hi) = (f64::MIN_POSITIVE, e.iter().copied().fold(0.0, f64::max));
    // Bisection in log space: the sizes asked of it span many decades.
    for _ in 0..200 {
        let mid = (lo * hi).sqrt();
        if tets_in(e, mid) > budget {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    // Up, so that the size as printed (and read back by the user) still keeps to the budget.
    let scale = 10f64.powi(hi.log10().floor() as i32 - 2);
    let printed = |h: f64| format!("{h:.2e}").parse::<f64>().unwrap_or(h);
    let mut h = printed((hi / scale).ceil() * scale);
    // 1 % up is at least one step of the third digit: each turn prints a larger size.
    for _ in 0..100 {
        if tets_in(e, h) <= budget {
            break;
        }
        h = printed(h * 1.01);
    }
    h
}

/// Refuses, before meshing, a size that would make far too many tets: an upper estimate from
/// the bounding box (`extent`, m) filled with regular tets of the requested sizes. The advice
/// names the sizes to change (only the VOI's when the VOI alone is too fine) and is checked
/// against the same estimate before it is given.
fn check_element_budget(path: &str, extent: [f64; 3], size: f64, voi: Option<&Voi>) -> Result<(), MeshError> {
    // Scale mistakes first (a size in mm written as m, or the other way round).
    let largest = extent.iter().copied().fold(0.0, f64::max);
    if size > largest {
        return Err(MeshError::Geometry {
            path: path.to_string(),
            message: format!(
                "mesh.size = {size:e} m is larger than the part ({:.4e} × {:.4e} × {:.4e} m); sizes are in metres: \
                 use about {:.2e} m (1/15 of its largest extent)",
                extent[0],
                extent[1],
                extent[2],
                largest / 15.0
            ),
        });
    }
    let global = tets_in(extent, size);
    // The VOI's share: its box clipped to the part's extent.
    let inside = voi.map(|v| {
        let e: [f64; 3] = std::array::from_fn(|c| (v.bbox.max[c] - v.bbox.min[c]).min(extent[c]).max(0.0));
        (v, e, tets_in(e, v.size))
    });
    let tets = global + inside.map_or(0.0, |(_, _, t)| t);
    if tets <= MAX_TETS {
        return Ok(());
    }
    // Whichever part is within half the budget keeps its size; the other gets the rest.
    let half = MAX_TETS / 2.0;
    let (advice, estimate) = match inside {
        None => {
            let h = size_for_budget(extent, MAX_TETS);
            (format!("use mesh.size ≥ {h:.2e} m"), tets_in(extent, h))
        }
        Some((v, e, fine)) => {
            let keep_global = global <= half;
            let keep_voi = fine <= half;
            let h = if keep_global {
                size
            } else {
                size_for_budget(extent, MAX_TETS - fine.min(half))
            };
            let hv = if keep_voi {
                v.size
            } else {
                size_for_budget(e, MAX_TETS - global.min(half))
            };
            let advice = match (keep_global, keep_voi) {
                (true, _) => format!(
                    "use voi {:?} size ≥ {hv:.2e} m (the VOI makes {fine:.1e} of them)",
                    v.name
                ),
                (false, true) => format!("use mesh.size ≥ {h:.2e} m"),
                (false, false) => format!("use mesh.size ≥ {h:.2e} m and voi {:?} size ≥ {hv:.2e} m", v.name),
            };
            (advice, tets_in(extent, h) + tets_in(e, hv))
        }
    };
    // The advice keeps to the budget by construction; an advice that does not is a bug here.
    debug_assert!(estimate <= MAX_TETS, "advice {advice} gives {estimate:e} tets");
    let sizes = match voi {
        Some(v) => format!("mesh.size = {size:e} m and voi {:?} size = {:e} m", v.name, v.size),
        None => format!("mesh.size = {size:e} m"),
    };
    Err(MeshError::Geometry {
        path: path.to_string(),
        message: format!(
            "{sizes} would make about {tets:.1e} tets in a part of {:.3e} × {:.3e} × {:.3e} m \
             (limit {MAX_TETS:.0e}); {advice}",
            extent[0], extent[1], extent[2]
        ),
    })
}

/// Refuses every VOI whose size would make too many tets in the part of extent `extent` (m),
/// once the extent is known (the whole part meshed): before the first solve, not after it when
/// that VOI's own space is meshed. An automatic `mesh.size` is left to the meshing itself.
pub fn check_voi_budgets(scene: &Scene, extent: [f64; 3]) -> Result<(), MeshError> {
    if scene.mesh.size <= 0.0 {
        return Ok(());
    }
    let path = scene.geometry.display().to_string();
    for v in &scene.voi {
        check_element_budget(&path, extent, scene.mesh.size, Some(v))?;
    }
    Ok(())
}

/// Meshes the scene's geometry (with the finer size inside `voi`, if given), on gmsh's own
/// thread so the same input always gives the same mesh.
pub fn generate(scene: &Scene, voi: Option<&Voi>) -> Result<(Mesh, Meshing), MeshError> {
    generate_with(scene, voi, None, false)
}

/// Meshes ahead into the mesh cache, so a later [`generate_with`] of the same input is a
/// cache hit; false (and nothing done) unless the cache is on and meshing runs in child
/// processes (in-process gmsh gave other meshes while other threads of the process were busy).
/// Errors are left to the later call, which meets them again and reports them.
pub fn warm_cache(scene: &Scene, voi: Option<&Voi>, field: Option<&field::SizeField>) -> bool {
    if !isolation::is_on() {
        return false;
    }
    let Ok(mut part) = Part::read(Request::new(scene, voi, field, true)) else {
        return false;
    };
    let Some(key) = part.key.clone() else {
        return false;
    };
    if part.cached().is_none()
        && let Ok((mesh, meshing)) = part.mesh()
    {
        cache::store(&key, &mesh, &meshing);
    }
    true
}

/// The solvers of a mesh (made here, or read back from a basis) reuse its fill-reducing
/// ordering from the mesh cache's folder, keyed by the mesh's node graph.
pub fn keep_orderings() {
    crate::linsolve::keep_orderings_in(&cache::Orderings);
}

/// [`generate`], with the sizes of `field` instead of the scene's and the VOI's when given
/// (local refinement); `quiet` turns its warnings into info lines (a helper mesh, such as a
/// coarser one for the error estimate, is not what the user asked about).
pub fn generate_with(
    scene: &Scene,
    voi: Option<&Voi>,
    field: Option<&field::SizeField>,
    quiet: bool,
) -> Result<(Mesh, Meshing), MeshError> {
    keep_orderings();
    let mut part = Part::read(Request::new(scene, voi, field, quiet))?;
    if let Some((mesh, mut meshing)) = part.cached() {
        tracing::info!(nodes = mesh.nodes.len(), "mesh cache hit");
        // Its warnings were said in full on the run that made it; the caller sums them up in
        // one line (`problem::mesh_with_supports`), and VES_LOG=info has them here.
        if meshing.straightened > 0 || meshing.rung > 0 {
            tracing::info!(
                "{}: (cached mesh) meshed on rung {} ({}); {} of {} curved tets were invalid after order 2, \
                 gmsh repaired {}, {} tets in all were made straight-sided",
                part.request.geometry.display(),
                meshing.rung,
                meshing.strategy,
                meshing.distorted,
                mesh.tet_count(),
                meshing.repaired_by_gmsh,
                meshing.straightened
            );
        }
        meshing.cached = true;
        return Ok((mesh, meshing));
    }
    let made = part.mesh()?;
    if let Some(k) = &part.key {
        cache::store(k, &made.0, &made.1);
    }
    Ok(made)
}

/// A part to mesh: its geometry's bytes, read once, and the cache key computed from them. gmsh
/// meshes a private copy of those same bytes, so the mesh stored under the key is the mesh of
/// the bytes in the key even if the file is replaced meanwhile.
struct Part {
    request: Request,
    /// None for a `.geo` script (gmsh reads it and the files it names itself; never cached).
    bytes: Option<Vec<u8>>,
    key: Option<std::path::PathBuf>,
}

impl Part {
    fn read(request: Request) -> Result<Part, MeshError> {
        let is_geo = request
            .geometry
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("geo"));
        let bytes = if is_geo {
            None
        } else {
            Some(crate::input::read(&request.geometry).map_err(|e| MeshError::Geometry {
                path: request.geometry.display().to_string(),
                message: e.to_string(),
            })?)
        };
        let key = bytes.as_deref().and_then(|b| cache::key(&request, b));
        Ok(Part { request, bytes, key })
    }

    /// The cached mesh, if a whole entry is there; a damaged one is a miss, said in one line.
    fn cached(&self) -> Option<(Mesh, Meshing)> {
        let key = self.key.as_deref()?;
        match cache::lookup(key) {
            cache::Found::Hit(mesh, meshing) => Some((mesh, meshing)),
            cache::Found::Absent => None,
            cache::Found::Bad(why) => {
                tracing::warn!(
                    "{}: damaged mesh cache entry ignored ({why}); the part is meshed again and the entry replaced",
                    key.display()
                );
                None
            }
        }
    }

    /// Meshes the bytes read, from a copy in a private directory. An input whose every rung
    /// failed earlier while a [`FailureMemory`] lives fails again at once, with the same message.
    fn mesh(&mut self) -> Result<(Mesh, Meshing), MeshError> {
        if let Some(message) = self.key.as_deref().and_then(failed_before) {
            tracing::info!("meshing failed before in this run on every rung: not tried again");
            return Err(MeshError::Geometry {
                path: self.request.geometry.display().to_string(),
                message,
            });
        }
        let (work, request) = self.private_copy()?;
        let walked = if isolation::is_on() {
            // Each rung runs in its own process: the ladder itself needs no gmsh.
            walk_ladder(&request, work.path())
        } else {
            let dir = work.path().to_path_buf();
            gmsh::on_gmsh_thread(move || walk_ladder(&request, &dir))
        };
        walked.map_err(|e| match e {
            Ladder::Fatal(e) => e,
            Ladder::Exhausted(e) => {
                if let Some(key) = &self.key {
                    remember_failure(key, e.cause());
                }
                e
            }
        })
    }

    /// A private directory holding the bytes read (once: they are not kept), and the request
    /// that makes gmsh read that copy.
    fn private_copy(&mut self) -> Result<(crate::workdir::WorkDir, Request), MeshError> {
        let path = self.request.geometry.display().to_string();
        let failed = |what: &str, e: std::io::Error| MeshError::Geometry {
            path: path.clone(),
            message: format!("cannot {what} for meshing: {e}"),
        };
        let work =
            crate::workdir::WorkDir::new("mesh").map_err(|e| failed("create a private temporary directory", e))?;
        let mut request = self.request.clone();
        if let Some(bytes) = self.bytes.take() {
            let ext = request
                .geometry
                .extension()
                .map(|e| e.to_string_lossy().to_ascii_lowercase())
                .unwrap_or_default();
            let copy = work.path().join(format!("geometry.{ext}"));
            crate::workdir::write(&copy, &bytes).map_err(|e| failed("copy the geometry", e))?;
            request.source = Some(copy);
        }
        Ok((work, request))
    }
}

/// All that meshing needs of a scene (and all a meshing process is sent).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Request {
    /// Geometry file.
    pub geometry: std::path::PathBuf,
    /// Unit of a geometry file without its own (BREP, GEO).
    pub unit: LengthUnit,
    /// Size and order.
    pub mesh: crate::scene::MeshSettings,
    /// A volume of interest meshed finer, if any.
    pub voi: Option<Voi>,
    /// A size that varies over the part: replaces `mesh.size` and the VOI's size.
    pub field: Option<field::SizeField>,
    /// Warnings as info lines.
    pub quiet: bool,
    /// The file gmsh opens, when not `geometry` itself: a private copy of the bytes read.
    #[serde(default)]
    pub source: Option<std::path::PathBuf>,
    /// The global size (the scene's, or the automatic one) times this: a trial of a finer
    /// size for advice, never stored in the cache.
    #[serde(default)]
    pub size_factor: Option<f64>,
}

impl Request {
    fn new(scene: &Scene, voi: Option<&Voi>, field: Option<&field::SizeField>, quiet: bool) -> Request {
        Request {
            geometry: scene.geometry.clone(),
            unit: scene.unit,
            mesh: scene.mesh,
            voi: voi.cloned(),
            field: field.cloned(),
            quiet,
            source: None,
            size_factor: None,
        }
    }
}

/// A warning, or an info line for a quiet request.
/// The straightened tets in words: the `left` gmsh could not repair, and the neighbours that
/// straightening their shared edges made invalid in turn (why the count can exceed `left`:
/// 37 invalid, 10 repaired, 37 straightened did not add up as written before).
fn straightened_words(left: usize, straightened: usize) -> String {
    if straightened > left {
        format!(
            "the {left} left and {} neighbours that straightening their shared edges made invalid in turn, {straightened} in all,",
            straightened - left
        )
    } else {
        format!("the {straightened} left")
    }
}

/// How to get a closer curved surface, in terms of the settings the scene has.
fn closer_surface_advice(req: &Request) -> String {
    match (req.mesh.target_error, req.mesh.size) {
        (Some(t), _) => {
            format!("a smaller [mesh] target_error than {t} refines further, or give a mesh.size for a closer surface")
        }
        (None, size) if size > 0.0 => format!("a mesh.size below {size:e} m gives a closer surface"),
        _ => "give a mesh.size for a closer surface".into(),
    }
}

fn notice(req: &Request, message: String) {
    if req.quiet {
        tracing::info!("{message}");
    } else {
        tracing::warn!("{message}");
    }
}

/// One way of meshing a part. The ladder is tried in this fixed order until a rung gives a
/// valid mesh, so the same input always ends on the same rung (a basis stays reproducible).
#[derive(Clone, Copy, Debug)]
struct Rung {
    name: &'static str,
    /// gmsh `Mesh.Algorithm`: 6 Frontal-Delaunay (gmsh's default), 5 Delaunay, 1 MeshAdapt.
    surface: f64,
    /// gmsh `Mesh.Algorithm3D`: 1 Delaunay (reproducible).
    volume: f64,
    /// OpenCASCADE healing on import: degenerated edges, small edges and faces, sewing, solids.
    heal: bool,
}

// No Frontal 3D rung (`Mesh.Algorithm3D` 4): Debian's libgmsh is built without Netgen, and
// gmsh answers "Frontal algorithm requires Netgen" on every part. HXT (10) is not one either:
// as gmsh calls it, its mesh changes from run to run (gmsh hands it the surface nodes ordered by
// memory address); made reproducible, it was 2–10× slower than Delaunay on the corpus parts with
// slivers (its optimiser) and failed where Delaunay fails (docs/benchmarks.md, "On the corpus").
// R-tree (9) crashed; MMG3D (7) is not built in.
const LADDER: [Rung; 5] = [
    Rung {
        name: "default",
        surface: 6.0,
        volume: 1.0,
        heal: false,
    },
    Rung {
        name: "delaunay-2d",
        surface: 5.0,
        volume: 1.0,
        heal: false,
    },
    Rung {
        name: "meshadapt-2d",
        surface: 1.0,
        volume: 1.0,
        heal: false,
    },
    Rung {
        name: "healed",
        surface: 6.0,
        volume: 1.0,
        heal: true,
    },
    Rung {
        name: "healed-delaunay-2d",
        surface: 5.0,
        volume: 1.0,
        heal: true,
    },
];

/// How the ladder failed.
enum Ladder {
    /// Something no rung changes (no solid, a size beyond the budget, a cancel): it ended there.
    Fatal(MeshError),
    /// Every rung failed to mesh.
    Exhausted(MeshError),
}

/// Inputs (cache keys) whose every rung failed, with the message said, while some
/// [`FailureMemory`] lives. The coarser meshes of a part gmsh cannot mesh at that size were
/// walked down the ladder twice per solve of a space, by the error estimate and again by the
/// felt check (3.5–3.8 s each on the crankshaft at 4 mm, whose solve took 0.2 s). Only an
/// exhausted ladder is remembered, never a fatal or passing error, and only for as long as the
/// stages that ask for the same meshes run: a process that lives on (a Python session, the
/// page's server) tries again the next time, when a failure that came from the machine (a
/// meshing process killed) may be gone.
#[derive(Default)]
struct Failures {
    /// Live [`FailureMemory`] guards.
    scopes: usize,
    failed: Vec<(std::path::PathBuf, String)>,
}

impl Failures {
    fn enter(&mut self) {
        self.scopes += 1;
    }

    fn leave(&mut self) {
        self.scopes = self.scopes.saturating_sub(1);
        if self.scopes == 0 {
            self.failed.clear();
        }
    }

    fn remember(&mut self, key: &std::path::Path, message: String) {
        if self.scopes > 0 && !self.failed.iter().any(|(k, _)| k == key) {
            self.failed.push((key.to_path_buf(), message));
        }
    }

    fn before(&self, key: &std::path::Path) -> Option<String> {
        self.failed.iter().find(|(k, _)| k == key).map(|(_, m)| m.clone())
    }
}

static FAILED: std::sync::Mutex<Failures> = std::sync::Mutex::new(Failures {
    scopes: 0,
    failed: Vec::new(),
});

fn failures() -> std::sync::MutexGuard<'static, Failures> {
    FAILED.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

fn failed_before(key: &std::path::Path) -> Option<String> {
    failures().before(key)
}

fn remember_failure(key: &std::path::Path, message: String) {
    failures().remember(key, message);
}

/// While it lives, a mesh every rung failed to make fails again at once when asked for again
/// (see [`Failures`]); the last one dropped forgets them.
pub struct FailureMemory(());

/// Remembers exhausted ladders until the guard is dropped.
pub fn remember_failures() -> FailureMemory {
    failures().enter();
    FailureMemory(())
}

impl Drop for FailureMemory {
    fn drop(&mut self) {
        failures().leave();
    }
}

/// Walks the ladder; a failure of gmsh's meshing or a degenerate element sends it one rung
/// further, anything else (no solid, a size beyond the budget) ends it.
fn walk_ladder(req: &Request, work: &std::path::Path) -> Result<(Mesh, Meshing), Ladder> {
    let mut first: Option<(MeshError, Vec<String>)> = None;
    for (i, rung) in LADDER.iter().enumerate() {
        match isolation::attempt(req, i, &work.join(format!("rung{i}"))) {
            Ok((mesh, mut report)) => {
                report.strategy = rung.name;
                report.rung = i;
                if i > 0 {
                    notice(
                        req,
                        format!(
                            "{}: meshed on rung {i} ({}) of the meshing ladder; the default failed: {}",
                            req.geometry.display(),
                            rung.name,
                            first.as_ref().map(|(e, _)| e.to_string()).unwrap_or_default()
                        ),
                    );
                }
                return Ok((mesh, report));
            }
            Err(Attempt::Fatal(e)) => return Err(Ladder::Fatal(e)),
            Err(Attempt::Retry(e, log)) => {
                // gmsh's own words, for VES_LOG=info.
                for line in &log {
                    tracing::info!(target: "gmsh", rung = rung.name, "{line}");
                }
                tracing::info!(rung = rung.name, "meshing failed: {e}");
                first.get_or_insert((e, log));
            }
        }
    }
    let (e, log) = first.expect("the ladder has rungs");
    let message = if is_intersection(&e, &log) {
        intersection_advice(&e, &log, req, work)
    } else {
        ladder_advice(&e, &log, req)
    };
    Err(Ladder::Exhausted(MeshError::Geometry {
        path: req.geometry.display().to_string(),
        message,
    }))
}

/// Whether gmsh failed because its surface mesh crosses itself: tetgen's "PLC Error: A segment
/// and a facet intersect", "Invalid boundary mesh (segment-facet intersection | overlapping
/// facets)".
fn is_intersection(e: &MeshError, log: &[String]) -> bool {
    let cause = e.cause();
    cause.contains("PLC Error")
        || cause.contains("intersect")
        || log
            .iter()
            .any(|l| l.contains("segment-facet intersection") || l.contains("overlapping facets"))
}

/// The point of an intersection as gmsh's log gives it ("…, intersection (x,y,z)"), in the
/// units gmsh works in.
fn intersection_point(log: &[String]) -> Option<[f64; 3]> {
    log.iter().find_map(|l| {
        let inner = l.split("intersection (").nth(1)?.split(')').next()?;
        let v: Vec<f64> = inner.split(',').map(|x| x.trim().parse().ok()).collect::<Option<_>>()?;
        (v.len() == 3 && v.iter().all(|x| x.is_finite())).then(|| [v[0], v[1], v[2]])
    })
}

/// The entities gmsh's error lines name, in lines like "… on surface 70 surface 235" or
/// "curve 12": ("surface" or "curve", tag), sorted, each once.
fn entities_named(log: &[String]) -> Vec<(&'static str, u64)> {
    let mut named: Vec<(&'static str, u64)> = log
        .iter()
        .filter(|l| l.contains("Error") || l.contains("intersect") || l.contains("overlapping"))
        .flat_map(|l| {
            let words: Vec<&str> = l.split_whitespace().collect();
            words
                .windows(2)
                .filter_map(|w| {
                    let kind = match w[0] {
                        "surface" | "Surface" => "surface",
                        "curve" | "Curve" => "curve",
                        _ => return None,
                    };
                    let tag = w[1].trim_matches(|c: char| !c.is_ascii_digit()).parse().ok()?;
                    Some((kind, tag))
                })
                .collect::<Vec<_>>()
        })
        .collect();
    named.sort_unstable();
    named.dedup();
    named
}

/// The CAD faces (gmsh's surface tags as imported, what a support's `faces = […]` names) that
/// gmsh's error lines name.
fn faces_named(log: &[String]) -> Vec<u64> {
    entities_named(log)
        .into_iter()
        .filter_map(|(kind, tag)| (kind == "surface").then_some(tag))
        .collect()
}

/// The one line when every rung failed because the surface mesh crosses itself: where, what
/// that means, and what to do. Whether a finer mesh cures it is tried (half the size, on the
/// default rung), not guessed: on a thin wall it does; where faces of the part really intersect
/// no size does, and only repairing the faces in CAD helps.
fn intersection_advice(e: &MeshError, log: &[String], req: &Request, work: &std::path::Path) -> String {
    let faces = faces_named(log);
    let on = match faces.as_slice() {
        [] => String::new(),
        [f] => format!(" on CAD face {f}"),
        fs => format!(
            " on CAD faces {}",
            fs.iter().map(u64::to_string).collect::<Vec<_>>().join(", ")
        ),
    };
    let scale = gmsh_scale(req);
    let near = intersection_point(log)
        .map(|p| {
            format!(
                " near ({:.6}, {:.6}, {:.6}) m",
                p[0] * scale,
                p[1] * scale,
                p[2] * scale
            )
        })
        .unwrap_or_default();
    let repair = "repair those faces in CAD (its geometry check finds self-intersecting and overlapping faces; \
                  rebuild, trim or sew them) or defeature there (remove the small feature), then export the part again";
    let head = format!(
        "gmsh could not mesh it with any of its {} strategies: its surface mesh crosses itself{on}{near} ({})",
        LADDER.len(),
        e.cause()
    );
    // A helper mesh's failure (an estimate's coarser mesh, a check's) is logged, not advice to
    // act on: the trials below meshed the thin cone cover's coarser meshes at half their size,
    // 4–5 s each, for a line no one reads.
    if req.field.is_some() || req.quiet {
        return format!(
            "{head}: faces of the part intersect or overlap there, or lie closer than the mesh resolves; {repair}"
        );
    }
    // Finer sizes, tried on the default rung: a thin wall meshes at one of them, faces that
    // really intersect at none (a size beyond the tet budget ends the trials).
    let mut failed = Vec::new();
    for (factor, name) in [(0.5, "half"), (0.25, "a quarter")] {
        let mut finer = req.clone();
        finer.quiet = true;
        finer.size_factor = Some(factor);
        if let Some(v) = &mut finer.voi {
            v.size *= factor;
        }
        match isolation::attempt(&finer, 0, &work.join(format!("size-{factor}"))) {
            Ok((_, meshing)) => {
                return format!(
                    "{head}: two faces there lie closer than the mesh resolves (a thin wall); mesh.size = {:.3e} m \
                     ({name} of the size used) meshes it (tried): use that size, or {repair}",
                    meshing.size
                );
            }
            Err(Attempt::Retry(..)) => failed.push(name),
            Err(Attempt::Fatal(_)) => break,
        }
    }
    match failed.as_slice() {
        [] => format!(
            "{head}: faces of the part intersect or overlap there, or lie closer than the mesh resolves; {repair}"
        ),
        tried => format!(
            "{head}: the faces there intersect or overlap ({} of the mesh size {} too, tried); {repair}",
            tried.join(" and "),
            if tried.len() > 1 { "fail" } else { "fails" }
        ),
    }
}

/// Metres per unit of the coordinates gmsh works in: STEP/IGES are converted to millimetres,
/// BREP and GEO are in the scene's `unit`.
fn gmsh_scale(req: &Request) -> f64 {
    let ext = req
        .geometry
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    if matches!(ext.as_str(), "step" | "stp" | "iges" | "igs") {
        LengthUnit::Millimetre.to_metres()
    } else {
        req.unit.to_metres()
    }
}

/// The one line when every rung failed: where (gmsh's entities), and what to change.
fn ladder_advice(e: &MeshError, log: &[String], req: &Request) -> String {
    let cause = e.cause();
    let places: Vec<String> = entities_named(log)
        .into_iter()
        .map(|(kind, tag)| format!("{kind} {tag}"))
        .collect();
    let at = if places.is_empty() {
        String::new()
    } else {
        format!(" at {}", places.join(", "))
    };
    if cause.contains(isolation::WHILE_READING) {
        // Nothing about meshing would change this.
        return format!(
            "gmsh could not read it with any of its {} strategies: {cause}; export the part again (STEP AP214 or \
             AP242, one solid), or for a .geo script remove what ends gmsh (Exit, Abort)",
            LADDER.len()
        );
    }
    let size = if req.mesh.size > 0.0 {
        format!("mesh.size = {:.3e} m (half)", req.mesh.size / 2.0)
    } else {
        format!(
            "a mesh.size below 1/{} of the part's largest extent",
            2.0 * AUTO_SIZE_FRACTION
        )
    };
    format!(
        "gmsh could not mesh it with any of its {} strategies (default, other surface and volume algorithms, \
         OpenCASCADE healing); the first failure{at}: {cause}; try {size}, or repair or defeature those faces in CAD",
        LADDER.len(),
    )
}

/// How one rung failed.
enum Attempt {
    /// Meshing failed: the next rung may do better (with gmsh's log).
    Retry(MeshError, Vec<String>),
    /// Nothing another rung would change.
    Fatal(MeshError),
}

/// One rung; `phase` is told what gmsh is doing (for a report if the process dies in it).
fn attempt(req: &Request, rung: &Rung, phase: &mut dyn FnMut(&str)) -> Result<(Mesh, Meshing), Attempt> {
    match attempt_once(req, rung, phase, false) {
        // gmsh stops at its first error, but the point and the face of a PLC error come in the
        // lines after it: the default rung (whose failure is reported) once more, to the end.
        Err(Attempt::Retry(e, log))
            if e.cause().contains("PLC Error")
                && rung.name == LADDER[0].name
                && req.size_factor.is_none()
                && !req.quiet =>
        {
            let log = match attempt_once(req, rung, phase, true) {
                Err(Attempt::Retry(_, full)) => full,
                _ => log,
            };
            Err(Attempt::Retry(e, log))
        }
        made => made,
    }
}

/// [`attempt`] once; `keep_going`: gmsh goes on after errors, and only its log is returned.
fn attempt_once(
    req: &Request,
    rung: &Rung,
    phase: &mut dyn FnMut(&str),
    keep_going: bool,
) -> Result<(Mesh, Meshing), Attempt> {
    let voi = req.voi.as_ref();
    let path = req.geometry.display().to_string();
    let g = |cause| {
        Attempt::Fatal(MeshError::Gmsh {
            path: path.clone(),
            cause,
        })
    };
    let fatal = Attempt::Fatal;
    let session = gmsh::Gmsh::start().map_err(g)?;
    if rung.heal {
        for opt in [
            "Geometry.OCCFixDegenerated",
            "Geometry.OCCFixSmallEdges",
            "Geometry.OCCFixSmallFaces",
            "Geometry.OCCSewFaces",
            "Geometry.OCCMakeSolids",
        ] {
            session.set_number(opt, 1.0).map_err(g)?;
        }
    }
    // STEP/IGES carry their own unit: OpenCASCADE converts it, always to millimetres, so the
    // mesh is the same whatever `unit` the scene gives (results independent of units to round-off).
    // BREP/GEO have no unit: the scene's `unit` says what their numbers are.
    let scale = gmsh_scale(req);
    session.set_string("Geometry.OCCTargetUnit", "MM").map_err(g)?;
    phase(isolation::READING);
    let source = req.source.as_deref().unwrap_or(req.geometry.as_path());
    session.open(source).map_err(|e| {
        // gmsh names the private copy it read: the user knows the file by its own name.
        let cause = e.to_string().replace(&source.display().to_string(), &path);
        Attempt::Fatal(MeshError::Geometry {
            path: path.clone(),
            message: format!(
                "gmsh could not read it ({cause}): the file may be cut short or damaged; export the part again \
                 from its CAD system (STEP AP214 or AP242, one solid)"
            ),
        })
    })?;
    let volumes = session.entities(3).map_err(g)?;
    if volumes.is_empty() {
        let faces = session.entities(2).map_err(g)?.len();
        let message = if faces == 0 {
            "OpenCASCADE read no geometry from it: the file is empty, truncated or not a STEP/IGES/BREP file; \
             export the part again"
                .to_string()
        } else {
            format!(
                "it holds {faces} surfaces but no closed solid; export the part as a solid (or sew its faces in CAD)"
            )
        };
        let e = MeshError::Geometry { path, message };
        // Healing can lose a solid that opened fine without it: then that rung just failed.
        return Err(if rung.heal {
            Attempt::Retry(e, session.log())
        } else {
            fatal(e)
        });
    }
    let (lo, hi) = session.bounding_box().map_err(g)?;
    let extent: [f64; 3] = std::array::from_fn(|c| (hi[c] - lo[c]) * scale);
    let size = if let Some(f) = &req.field {
        f.largest()
    } else if req.mesh.size > 0.0 {
        req.mesh.size
    } else {
        extent.iter().copied().fold(0.0, f64::max) / AUTO_SIZE_FRACTION
    } * req.size_factor.unwrap_or(1.0);
    let h = size / scale;
    match &req.field {
        Some(f) => check_field_budget(&path, f).map_err(fatal)?,
        None => check_element_budget(&path, extent, size, voi).map_err(fatal)?,
    }
    session.set_number("Mesh.MeshSizeMax", h).map_err(g)?;
    session.set_number("Mesh.MeshSizeMin", 0.0).map_err(g)?;
    // Delaunay (1) gives the same mesh on every run; HXT (10) is faster on clean parts (the
    // mould, the ribplate) but not reproducible as called here and slower on parts with slivers
    // (see LADDER); a basis must be reproducible (regression numbers, batch up-to-date checks).
    session.set_number("Mesh.Algorithm", rung.surface).map_err(g)?;
    session.set_number("Mesh.Algorithm3D", rung.volume).map_err(g)?;
    session.set_number("Mesh.RandomSeed", 1.0).map_err(g)?;
    session.set_number("Mesh.ElementOrder", 1.0).map_err(g)?;
    for opt in ["Mesh.MaxNumThreads1D", "Mesh.MaxNumThreads2D", "Mesh.MaxNumThreads3D"] {
        session.set_number(opt, 1.0).map_err(g)?;
    }
    if let Some(field) = &req.field {
        // The field came from a mesh of this space: it already holds the VOI's sizes.
        let view = session.view_scalar_tets("size", &field.list_data(scale)).map_err(g)?;
        let f = session.field_add("PostView").map_err(g)?;
        session.field_set_number(f, "ViewTag", view as f64).map_err(g)?;
        session.field_set_as_background(f).map_err(g)?;
        only_background_sizes(&session).map_err(g)?;
    } else if let Some(v) = voi {
        let f = session.field_add("Box").map_err(g)?;
        session.field_set_number(f, "VIn", v.size / scale).map_err(g)?;
        session.field_set_number(f, "VOut", h).map_err(g)?;
        for (c, axis) in ["X", "Y", "Z"].iter().enumerate() {
            session
                .field_set_number(f, &format!("{axis}Min"), v.bbox.min[c] / scale)
                .map_err(g)?;
            session
                .field_set_number(f, &format!("{axis}Max"), v.bbox.max[c] / scale)
                .map_err(g)?;
        }
        // Grade from the fine to the global size over about two global elements.
        session.field_set_number(f, "Thickness", 2.0 * h).map_err(g)?;
        session.field_set_as_background(f).map_err(g)?;
        only_background_sizes(&session).map_err(g)?;
    }
    let retry = |e: MeshError, session: &gmsh::Gmsh| Attempt::Retry(e, session.log());
    phase("meshing");
    if keep_going {
        session.set_number("General.AbortOnError", 0.0).map_err(g)?;
        let _ = session.generate(3);
        return Err(retry(
            MeshError::Geometry {
                path: path.clone(),
                message: "gmsh's log to its end".into(),
            },
            &session,
        ));
    }
    let generating = std::time::Instant::now();
    if let Err(cause) = session.generate(3) {
        return Err(retry(
            MeshError::Gmsh {
                path: path.clone(),
                cause,
            },
            &session,
        ));
    }
    let kind = req.mesh.kind();
    let mut meshing = Meshing {
        size,
        ..Meshing::default()
    };
    if kind == Kind::Tet10 {
        phase("making the elements order 2");
        session.set_order(2).map_err(g)?;
    }
    let mut mesh = extract(&session, kind, scale, &path).map_err(fatal)?;
    if let Some((q, at)) = mesh.degenerate_tet() {
        return Err(retry(
            MeshError::Geometry {
                path: path.clone(),
                message: format!(
                    "gmsh made a flat tet (shape quality {q:.1e}) near ({:.6}, {:.6}, {:.6}) m",
                    at[0], at[1], at[2]
                ),
            },
            &session,
        ));
    }
    if kind == Kind::Tet10 {
        meshing.distorted = mesh.distorted_tets(quality::MIN_SCALED_JACOBIAN).len();
        if meshing.distorted > 0 {
            // gmsh's elastic smoother moves the curved nodes into the volume: seconds, bounded.
            let t = std::time::Instant::now();
            phase("optimising the curved elements");
            session.set_number("Mesh.HighOrderNumLayers", 3.0).map_err(g)?;
            // `mesh.smooth_curved = false` (the page's first look): straightened at once.
            if req.mesh.smooth_curved {
                match session.optimize(HIGH_ORDER_METHOD, 1) {
                    Ok(()) => mesh = extract(&session, kind, scale, &path).map_err(fatal)?,
                    Err(e) => tracing::info!("gmsh {HIGH_ORDER_METHOD} failed ({e}); straightening instead"),
                }
            }
            meshing.optimize_s = t.elapsed().as_secs_f64();
            let left = mesh.distorted_tets(quality::MIN_SCALED_JACOBIAN).len();
            meshing.repaired_by_gmsh = meshing.distorted.saturating_sub(left);
            meshing.straightened = mesh.straighten_distorted(quality::MIN_SCALED_JACOBIAN);
            if meshing.straightened > 0 {
                notice(
                    req,
                    format!(
                        "{path}: {} of {} curved tets were invalid after order 2; {}; {} were made \
                         straight-sided (their faces are flat there: {})",
                        meshing.distorted,
                        mesh.tet_count(),
                        if req.mesh.smooth_curved {
                            format!("gmsh repaired {}", meshing.repaired_by_gmsh)
                        } else {
                            "not smoothed first (mesh.smooth_curved = false)".to_string()
                        },
                        straightened_words(left, meshing.straightened),
                        closer_surface_advice(req)
                    ),
                );
            }
        }
    }
    meshing.generate_s = generating.elapsed().as_secs_f64();
    drop(session);
    Ok((mesh, meshing))
}

/// Sizes come from the background field alone (not from the boundary, points or curvature).
fn only_background_sizes(session: &gmsh::Gmsh) -> gmsh::Result<()> {
    for opt in [
        "Mesh.MeshSizeExtendFromBoundary",
        "Mesh.MeshSizeFromPoints",
        "Mesh.MeshSizeFromCurvature",
    ] {
        session.set_number(opt, 0.0)?;
    }
    Ok(())
}

/// A size field that would make more tets than [`MAX_TETS`] is refused before meshing.
fn check_field_budget(path: &str, field: &field::SizeField) -> Result<(), MeshError> {
    let tets = field.expected_tets();
    if tets > MAX_TETS || field.smallest().partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return Err(MeshError::Geometry {
            path: path.to_string(),
            message: format!(
                "the refined size field ({:.2e}…{:.2e} m) would make about {tets:.1e} tets (limit {MAX_TETS:.0e}); \
                 lower mesh.max_dofs or raise mesh.target_error",
                field.smallest(),
                field.largest()
            ),
        });
    }
    Ok(())
}

/// gmsh's optimiser for curved elements. "HighOrder" (the direct optimiser) takes 10–90 s on
/// real parts and sometimes never finishes; the elastic smoother is bounded, and what it leaves
/// is straightened.
const HIGH_ORDER_METHOD: &str = "HighOrderElastic";

/// How the mesh was made: the ladder's rung, and what making it order 2 needed.
#[derive(Clone, Copy, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct Meshing {
    /// The meshing strategy that worked (the ladder's rung name; "default" normally).
    #[serde(skip_deserializing)]
    pub strategy: &'static str,
    /// Its place on the ladder (0: the default).
    pub rung: usize,
    /// Curved tets below the validity threshold right after gmsh's order-2 step.
    pub distorted: usize,
    /// Of those, repaired by gmsh's high-order optimisation.
    pub repaired_by_gmsh: usize,
    /// Made straight-sided (mid-edge nodes at edge midpoints) because nothing else repaired them.
    pub straightened: usize,
    /// Seconds spent in gmsh's optimisation.
    pub optimize_s: f64,
    /// The element size used, m (the scene's, or the one picked when it left it open).
    pub size: f64,
    /// Seconds gmsh spent making the mesh itself (3-D mesh, order 2, optimisation): what grows
    /// with the mesh, apart from starting gmsh and reading the geometry.
    #[serde(default)]
    pub generate_s: f64,
    /// Read from the mesh cache (made by an earlier run, which said its warnings in full).
    #[serde(default)]
    pub cached: bool,
}

impl Meshing {
    /// The warnings the making of this mesh gave, in a few words each (meshed on a later rung
    /// of the ladder, curved tets made straight-sided): what a cached run sums up in one line.
    pub fn warnings_when_made(&self) -> Vec<String> {
        let mut w = Vec::new();
        if self.rung > 0 {
            w.push(format!(
                "meshed on rung {} ({}) of the meshing ladder",
                self.rung, self.strategy
            ));
        }
        if self.straightened > 0 {
            w.push(format!("{} curved tets made straight-sided", self.straightened));
        }
        w
    }
}

/// A scene without `mesh.size` starts at this fraction of the part's largest extent.
pub const AUTO_SIZE_FRACTION: f64 = 15.0;

/// The current gmsh mesh as a [`Mesh`] in metres.
fn extract(session: &gmsh::Gmsh, kind: Kind, scale: f64, path: &str) -> Result<Mesh, MeshError> {
    let g = |cause| MeshError::Gmsh {
        path: path.to_string(),
        cause,
    };
    let (tags, coords) = session.nodes().map_err(g)?;
    let (_, tet_tags) = session.elements_by_type(kind.gmsh_type()).map_err(g)?;
    if tet_tags.is_empty() {
        return Err(MeshError::Geometry {
            path: path.to_string(),
            message: "gmsh produced no tetrahedra; check that the solid is closed".into(),
        });
    }
    let max_tag = tags.iter().copied().max().unwrap_or(0);
    let mut slot = vec![u32::MAX; max_tag + 1];
    let mut xyz = Vec::with_capacity(tags.len());
    for (i, &t) in tags.iter().enumerate() {
        slot[t] = i as u32;
        xyz.push([
            coords[3 * i] * scale,
            coords[3 * i + 1] * scale,
            coords[3 * i + 2] * scale,
        ]);
    }
    let mut tets = Vec::with_capacity(tet_tags.len());
    for &t in &tet_tags {
        let s = slot.get(t).copied().unwrap_or(u32::MAX);
        if s == u32::MAX {
            return Err(MeshError::Geometry {
                path: path.to_string(),
                message: format!("gmsh returned a tet on unknown node {t}"),
            });
        }
        tets.push(s);
    }
    let (mut mesh, new_index) = Mesh::from_raw_numbered(&xyz, &tets, kind);
    // Each boundary triangle's CAD face: gmsh's triangles of each surface entity, matched by
    // their sorted corner nodes (a 6-node triangle's first three nodes are its corners).
    let (triangle, per) = match kind {
        Kind::Tet10 => (element_type::TRIANGLE6, 6),
        Kind::Tet4 => (element_type::TRIANGLE3, 3),
    };
    let mut face_of: HashMap<[u32; 3], u32> = HashMap::with_capacity(mesh.surface.len());
    for (_, tag) in session.entities(2).map_err(g)? {
        let Ok(face) = u32::try_from(tag) else { continue };
        let (_, nodes) = session.elements_by_type_on(triangle, tag).map_err(g)?;
        for t in nodes.chunks_exact(per) {
            let corner = |k: usize| {
                slot.get(t[k])
                    .and_then(|&s| new_index.get(s as usize))
                    .copied()
                    .unwrap_or(u32::MAX)
            };
            let mut key = [corner(0), corner(1), corner(2)];
            key.sort_unstable();
            if key[2] != u32::MAX {
                face_of.insert(key, face);
            }
        }
    }
    for (f, tag) in mesh.surface.iter().zip(&mut mesh.surface_faces) {
        let mut key = *f;
        key.sort_unstable();
        *tag = face_of.get(&key).copied().unwrap_or(0);
    }
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An exhausted ladder is remembered only while a scope lives, and forgotten with the last.
    #[test]
    fn failures_are_remembered_only_within_a_scope() {
        let key = std::path::Path::new("k");
        let mut f = Failures::default();
        f.remember(key, "outside".into());
        assert_eq!(f.before(key), None);
        f.enter();
        f.enter();
        f.remember(key, "first".into());
        f.remember(key, "second".into());
        assert_eq!(f.before(key).as_deref(), Some("first"));
        f.leave();
        assert_eq!(f.before(key).as_deref(), Some("first"), "an inner scope ended");
        f.leave();
        assert_eq!(f.before(key), None);
        f.leave();
        assert_eq!(f.scopes, 0);
    }

    /// The straightened tets add up: those gmsh left, plus the neighbours straightened after them.
    #[test]
    fn straightened_tets_are_told_so_that_they_add_up() {
        assert_eq!(
            straightened_words(27, 37),
            "the 27 left and 10 neighbours that straightening their shared edges made invalid in turn, 37 in all,"
        );
        assert_eq!(straightened_words(5, 5), "the 5 left");
    }

    /// The part's file replaced by another part after it was read (between the cache key and
    /// gmsh): the key is of the bytes read, and gmsh reads a private copy of those same bytes,
    /// never the file the other part now fills.
    #[test]
    fn the_key_and_the_copy_meshed_are_of_the_same_bytes() {
        let dir = tempfile::tempdir().unwrap();
        let step = dir.path().join("part.step");
        std::fs::write(&step, b"first part").unwrap();
        let scene = dir.path().join("s.toml");
        let text = "[geometry]\nstep = \"part.step\"\nunit = \"mm\"\n[material]\nyoung = 2e11\npoisson = 0.3\ndensity = 7800.0\n\
                    [mesh]\nsize = 0.01\norder = 1\n[modes]\ncount = 4\n";
        let scene = Scene::parse(&scene, text).unwrap();
        let request = Request::new(&scene, None, None, false);
        let mut part = Part::read(request.clone()).unwrap();
        std::fs::write(&step, b"second part, another shape").unwrap();
        let (work, meshed) = part.private_copy().unwrap();
        let copy = meshed.source.clone().expect("gmsh reads a copy");
        assert!(copy.starts_with(work.path()), "{}", copy.display());
        assert_eq!(std::fs::read(&copy).unwrap(), b"first part");
        assert_eq!(meshed.geometry, step, "messages still name the user's file");
        if part.key.is_some() {
            assert_eq!(part.key, cache::key(&request, b"first part"));
            assert_ne!(part.key, cache::key(&request, b"second part, another shape"));
        }
    }

    #[test]
    fn shape_quality_is_one_for_a_regular_tet_and_tiny_for_a_sliver() {
        let regular = [[1.0, 1.0, 1.0], [1.0, -1.0, -1.0], [-1.0, 1.0, -1.0], [-1.0, -1.0, 1.0]];
        let m = Mesh::from_raw(&regular, &[0, 1, 2, 3], Kind::Tet4);
        assert!((m.worst_quality().0 - 1.0).abs() < 1e-12);
        let sliver = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 1e-4]];
        let m = Mesh::from_raw(&sliver, &[0, 1, 2, 3], Kind::Tet4);
        let (q, at) = m.worst_quality();
        assert!(q > 0.0 && q < 1e-3, "{q}");
        assert!((at[0] - 0.5).abs() < 1e-12 && (at[1] - 0.5).abs() < 1e-12);
        assert_eq!(m.surface.len(), 4, "a single tet is all boundary");
        // Both in one mesh (the sliver's corners moved beside the regular tet): one in the
        // lowest tenth, one in the highest.
        let both: Vec<[f64; 3]> = regular
            .iter()
            .chain(
                sliver
                    .iter()
                    .map(|p| [p[0] + 3.0, p[1], p[2]])
                    .collect::<Vec<_>>()
                    .iter(),
            )
            .copied()
            .collect();
        let m = Mesh::from_raw(&both, &[0, 1, 2, 3, 4, 5, 6, 7], Kind::Tet4);
        assert_eq!(m.quality_histogram(), [1, 0, 0, 0, 0, 0, 0, 0, 0, 1]);
    }

    /// The size after `marker` in a budget message (`… ≥ 1.23e-3 m`).
    fn advised(message: &str, marker: &str) -> Option<f64> {
        message.split(marker).nth(1)?.split_whitespace().next()?.parse().ok()
    }

    fn budget_message(extent: [f64; 3], size: f64, voi: Option<&Voi>) -> String {
        match check_element_budget("beam.step", extent, size, voi) {
            Err(MeshError::Geometry { message, .. }) => message,
            other => panic!("expected a budget refusal, got {other:?}"),
        }
    }

    /// `voi.size = 1e-5` in a 1 m beam advised "mesh.size ≥ 4.73 m" (larger than the part, and
    /// the VOI still too fine): the advice must name the size at fault and work when followed.
    #[test]
    fn element_budget_advice_names_the_size_at_fault_and_keeps_to_the_budget() {
        let extent = [1.0, 0.1, 0.05];
        let voi = |size: f64| Voi {
            name: "rib".into(),
            bbox: crate::scene::BoxRegion {
                min: [0.0; 3],
                max: [0.1, 0.1, 0.05],
            },
            size,
        };
        // Only the VOI is too fine: mesh.size stays, the VOI's size is advised.
        let m = budget_message(extent, 0.05, Some(&voi(1e-5)));
        assert!(!m.contains("mesh.size ≥"), "{m}");
        let hv = advised(&m, "size ≥ ").expect("a VOI size");
        assert!(hv > 1e-5 && hv < 0.05, "{m}");
        check_element_budget("beam.step", extent, 0.05, Some(&voi(hv))).expect("the advice works");
        // Both too fine: both advised, and together they fit.
        let m = budget_message(extent, 1e-4, Some(&voi(1e-5)));
        let h = advised(&m, "mesh.size ≥ ").expect("a mesh size");
        let hv = advised(&m, "\"rib\" size ≥ ").expect("a VOI size");
        assert!(h <= 1.0 && hv <= h, "{m}");
        check_element_budget("beam.step", extent, h, Some(&voi(hv))).expect("the advice works");
        // Without a VOI the global size, which fits (and is as printed: three digits).
        let m = budget_message(extent, 1e-9, None);
        let h = advised(&m, "mesh.size ≥ ").expect("a mesh size");
        check_element_budget("beam.step", extent, h, None).expect("the advice works");
        assert!(
            tets_in(extent, h) > 0.9 * MAX_TETS,
            "the advice is far from the limit: {m}"
        );
    }
}
