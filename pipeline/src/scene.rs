//! Scene file, version 1 (docs/scene.md): parsing and validation.
//!
//! Parsing is strict: unknown keys are errors, and every error names the file, the key and what
//! to change. A [`Scene`] that exists has passed validation, and its paths are absolute.

use serde::Deserialize;
use std::path::{Path, PathBuf};

/// A scene that failed to load; the message names the file, the key and the reason.
#[derive(Debug, thiserror::Error)]
#[error("{file}: {message}")]
pub struct SceneError {
    /// The scene file.
    pub file: PathBuf,
    /// What is wrong and what to change.
    pub message: String,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScene {
    name: Option<String>,
    geometry: RawGeometry,
    material: Material,
    mesh: MeshSettings,
    #[serde(default)]
    fixed: Vec<RawFixed>,
    modes: ModeSettings,
    #[serde(default)]
    damping: Damping,
    #[serde(default)]
    voi: Vec<Voi>,
    static_correction: Option<StaticCorrection>,
    model: Option<ModelSettings>,
    contact: Option<ContactSettings>,
    #[serde(default)]
    probe: Vec<Probe>,
    stress: Option<StressSettings>,
    #[serde(default)]
    load: Vec<RawLoad>,
    gravity: Option<RawGravity>,
}

/// Optional `[[load]]` entries (a compatible v1 extension): a service load on a surface region
/// selected as `[[fixed]]` selects its own, solved statically (the `loads` stage).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLoad {
    name: String,
    plane: Option<RawPlane>,
    #[serde(rename = "box")]
    bbox: Option<BoxRegion>,
    faces: Option<Vec<u32>>,
    #[serde(default, deserialize_with = "three::force_opt")]
    force: Option<[f64; 3]>,
    pressure: Option<f64>,
}

/// The scene's 3-vectors, read with exactly three numbers: serde's `[f64; 3]` through the toml
/// crate reads the first three elements of a longer array and ignores the rest. One function
/// per key, so that the refusal names it (toml adds the line).
mod three {
    use serde::Deserializer;
    use serde::de::{Error, IgnoredAny, SeqAccess, Visitor};
    use std::fmt;

    struct Exact(&'static str);

    impl<'de> Visitor<'de> for Exact {
        type Value = [f64; 3];

        fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
            write!(f, "exactly 3 numbers [x, y, z]")
        }

        fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<[f64; 3], A::Error> {
            let key = self.0;
            let mut v = [0.0; 3];
            for (i, x) in v.iter_mut().enumerate() {
                match seq.next_element::<f64>() {
                    Ok(Some(e)) => *x = e,
                    Ok(None) => {
                        let s = if i == 1 { "" } else { "s" };
                        return Err(A::Error::custom(format!(
                            "{key}: {i} element{s}; give exactly 3 numbers [x, y, z]"
                        )));
                    }
                    Err(e) => {
                        // toml's message ends in a line break.
                        let e = e.to_string();
                        return Err(A::Error::custom(format!(
                            "{key}[{i}]: {}; give exactly 3 numbers [x, y, z]",
                            e.trim()
                        )));
                    }
                }
            }
            // Counted, not kept: the rest may be of any type.
            let mut n = 3usize;
            while seq.next_element::<IgnoredAny>()?.is_some() {
                n += 1;
            }
            if n > 3 {
                return Err(A::Error::custom(format!(
                    "{key}: {n} elements; give exactly 3 numbers [x, y, z]"
                )));
            }
            Ok(v)
        }
    }

    macro_rules! keys {
        ($($key:ident),*) => {$(
            pub fn $key<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 3], D::Error> {
                d.deserialize_seq(Exact(stringify!($key)))
            }
        )*};
    }
    keys!(at, force, min, max, acceleration);

    /// `force` where the key may be left out (`#[serde(default)]` gives `None`).
    pub fn force_opt<'de, D: Deserializer<'de>>(d: D) -> Result<Option<[f64; 3]>, D::Error> {
        force(d).map(Some)
    }
}

/// Optional `[gravity]` table (a compatible v1 extension): the load case `gravity`, M·g.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawGravity {
    #[serde(deserialize_with = "three::acceleration")]
    acceleration: [f64; 3],
}

/// Optional `[stress]` table (a compatible v1 extension): store each mode's stress at the
/// corner vertices (`modes/stress`).
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct StressSettings {
    /// Compute and store the modal stress.
    #[serde(default)]
    pub enabled: bool,
    /// Study each load case's peak von Mises on meshes refined around it (its error, or that it
    /// is singular); default true.
    #[serde(default = "yes")]
    pub peak_error: bool,
}

fn yes() -> bool {
    true
}

/// Optional `[[probe]]` entries (a compatible v1 extension): a point force applied at the surface
/// vertex nearest `at`, where `ves report` measures the displacement error of a basis.
#[derive(Clone, Copy, Debug, Deserialize, serde::Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Probe {
    /// Where, m (snapped to the nearest surface vertex).
    #[serde(deserialize_with = "three::at")]
    pub at: [f64; 3],
    /// Force, N.
    #[serde(deserialize_with = "three::force")]
    pub force: [f64; 3],
}

/// Optional `[static_correction]` table (a compatible v1 extension): store the exact static
/// compliance blocks (K⁻¹)ᵢᵢ of the candidate contact vertices, so the runtime can make the
/// felt stiffness exact whatever the number of modes.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct StaticCorrection {
    /// Which vertices: `"surface"` (every corner vertex on the boundary).
    pub region: CorrectionRegion,
}

/// Optional `[model]` table (a compatible v1 extension): the part's mechanics.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct ModelSettings {
    /// `"linear"` (default) or `"nonlinear"`.
    #[serde(default)]
    pub kind: ModelKind,
    /// Nonlinear: the pairwise derivatives of this many lowest modes enrich the basis (default
    /// [`DEFAULT_DERIVATIVES`], at most `modes.count`).
    pub derivatives: Option<usize>,
}

/// Linear or geometrically nonlinear.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
pub enum ModelKind {
    /// u = Φq, small displacements (the default).
    #[default]
    #[serde(rename = "linear")]
    Linear,
    /// Reduced St. Venant–Kirchhoff: large displacements and rotations, small strains.
    #[serde(rename = "nonlinear")]
    Nonlinear,
}

/// Lowest modes whose derivatives a nonlinear model adds by default: 4 give 10 vectors, which
/// bring a soft cantilever to within 1 % of the elastica at PL²/EI = 3 (docs/nonlinear.md).
pub const DEFAULT_DERIVATIVES: usize = 4;

/// A nonlinear model as the scene sets it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Nonlinear {
    /// Lowest modes whose pairwise derivatives enrich the basis.
    pub derivatives: usize,
}

/// Optional `[contact]` table (a compatible v1 extension): the hand's contact patch.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ContactSettings {
    /// Radius of the patch the hand's force is spread over, m (0: one vertex).
    pub radius: f64,
}

/// Candidate contact vertices for the static correction.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
pub enum CorrectionRegion {
    /// Every corner vertex of the surface.
    #[serde(rename = "surface")]
    Surface,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawGeometry {
    step: PathBuf,
    #[serde(default)]
    unit: Option<LengthUnit>,
}

/// Unit of the geometry file's coordinates (BREP, gmsh scripts; a STEP or IGES file carries its
/// own, which is what is used).
#[derive(Clone, Copy, Debug, Deserialize, serde::Serialize, PartialEq, Eq)]
pub enum LengthUnit {
    /// Metres.
    #[serde(rename = "m")]
    Metre,
    /// Millimetres.
    #[serde(rename = "mm")]
    Millimetre,
}

impl LengthUnit {
    /// As a scene writes it.
    pub fn symbol(self) -> &'static str {
        match self {
            LengthUnit::Metre => "m",
            LengthUnit::Millimetre => "mm",
        }
    }

    /// Metres per unit.
    pub fn to_metres(self) -> f64 {
        match self {
            LengthUnit::Metre => 1.0,
            LengthUnit::Millimetre => 1e-3,
        }
    }
}

pub use crate::material::Material;

impl MeshSettings {
    /// The element kind of `order` (the scene parser admits 1 and 2 only; anything else would be
    /// 4-node tets).
    pub fn kind(&self) -> ves_format::ElementKind {
        ves_format::ElementKind::of_order(u32::from(self.order)).unwrap_or(ves_format::ElementKind::Tet4)
    }
}

/// Meshing settings.
#[derive(Clone, Copy, Debug, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct MeshSettings {
    /// Target element size, m (0 when the scene leaves it to `target_error`: then the mesher
    /// starts at 1/15 of the part's largest extent).
    #[serde(default)]
    pub size: f64,
    /// 1 = 4-node tets, 2 = 10-node tets.
    pub order: u8,
    /// Estimate each mode's discretization error (docs/accuracy.md): by default the recovery
    /// estimate on the mesh itself, with two coarser meshes only where it is not vouched for.
    #[serde(default)]
    pub error_estimate: EstimateMode,
    /// Refine until every kept mode's estimated error is below this (relative), starting at
    /// `size`; then the basis of the last mesh is written.
    #[serde(default)]
    pub target_error: Option<f64>,
    /// Refinement stops before a mesh would exceed this many unknowns.
    #[serde(default = "default_max_dofs")]
    pub max_dofs: usize,
    /// How `target_error` refines: everywhere alike (default) or where the error is.
    #[serde(default)]
    pub refinement: Refinement,
    /// 10-node tets made invalid by curving them to the CAD surface go through gmsh's elastic
    /// smoother first (default), or are made straight-sided at once (`false`: faster meshing of
    /// parts with many curved faces, the geometry flat on a few more elements).
    #[serde(default = "default_smooth_curved")]
    pub smooth_curved: bool,
}

fn default_smooth_curved() -> bool {
    true
}

/// Which error estimate `[mesh] error_estimate` asks for (docs/accuracy.md).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum EstimateMode {
    /// None (`false`, `"off"`).
    Off,
    /// The recovery estimate on the mesh itself decides; the two coarser meshes (Richardson)
    /// are solved only when it does not vouch for a mode (`true`, `"recovery"`; the default).
    #[default]
    Recovery,
    /// Both estimates on every mesh, the coarser meshes always solved (`"full"`): the estimate
    /// before issue 42, for batch runs that want the independent check everywhere.
    Full,
}

impl EstimateMode {
    /// Whether any estimate is made.
    pub fn on(self) -> bool {
        self != EstimateMode::Off
    }

    /// As a scene or the command line writes it.
    pub fn name(self) -> &'static str {
        match self {
            EstimateMode::Off => "off",
            EstimateMode::Recovery => "recovery",
            EstimateMode::Full => "full",
        }
    }
}

impl std::str::FromStr for EstimateMode {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "off" | "false" => Ok(EstimateMode::Off),
            "recovery" | "true" => Ok(EstimateMode::Recovery),
            "full" => Ok(EstimateMode::Full),
            _ => Err(format!(
                "{s:?}: one of \"recovery\", \"full\" or \"off\" (or true / false)"
            )),
        }
    }
}

impl<'de> Deserialize<'de> for EstimateMode {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct Visitor;
        impl serde::de::Visitor<'_> for Visitor {
            type Value = EstimateMode;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("true, false, \"recovery\", \"full\" or \"off\"")
            }
            fn visit_bool<E: serde::de::Error>(self, v: bool) -> std::result::Result<EstimateMode, E> {
                Ok(if v { EstimateMode::Recovery } else { EstimateMode::Off })
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> std::result::Result<EstimateMode, E> {
                v.parse().map_err(E::custom)
            }
        }
        d.deserialize_any(Visitor)
    }
}

/// Written as it was before the modes existed (true / false) where it means the same, so a
/// scene's echo in a basis changes only for `"full"`.
impl serde::Serialize for EstimateMode {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        match self {
            EstimateMode::Off => s.serialize_bool(false),
            EstimateMode::Recovery => s.serialize_bool(true),
            EstimateMode::Full => s.serialize_str("full"),
        }
    }
}

/// How `[mesh] target_error` makes each next mesh.
#[derive(Clone, Copy, Debug, Default, Deserialize, serde::Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum Refinement {
    /// The whole part at a smaller size. The default: measured cheaper than local refinement on
    /// the 200:1 plate and as accurate on the cantilever and the ribplate (docs/accuracy.md).
    #[default]
    Uniform,
    /// Smaller elements where an element error indicator says the error is (a gmsh background
    /// size field).
    Local,
}

/// About 10 GB of memory with 10-node tets (6.6 GB measured at 684k unknowns on the ribplate).
fn default_max_dofs() -> usize {
    1_000_000
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFixed {
    plane: Option<RawPlane>,
    #[serde(rename = "box")]
    bbox: Option<BoxRegion>,
    faces: Option<Vec<u32>>,
    components: Option<Vec<String>>,
    kind: Option<String>,
    stiffness: Option<f64>,
    located: Option<bool>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPlane {
    axis: String,
    value: f64,
    tol: Option<f64>,
}

/// Axis-aligned box, metres.
#[derive(Clone, Copy, Debug, Deserialize, serde::Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BoxRegion {
    /// Lower corner.
    #[serde(deserialize_with = "three::min")]
    pub min: [f64; 3],
    /// Upper corner.
    #[serde(deserialize_with = "three::max")]
    pub max: [f64; 3],
}

impl BoxRegion {
    /// Whether `p` lies in the box (boundary included, widened by `tol`).
    pub fn contains(&self, p: [f64; 3], tol: f64) -> bool {
        (0..3).all(|c| p[c] >= self.min[c] - tol && p[c] <= self.max[c] + tol)
    }
}

/// Where a support acts.
#[derive(Clone, Debug, PartialEq)]
pub enum Region {
    /// Nodes with |x[axis] − value| ≤ tol; `tol = None` means 1e-6 × part size.
    Plane {
        /// 0, 1, 2 for x, y, z.
        axis: usize,
        /// Coordinate of the plane, m.
        value: f64,
        /// Tolerance, m.
        tol: Option<f64>,
    },
    /// Nodes inside a box.
    Box(BoxRegion),
    /// The nodes of the surface triangles on these CAD faces (gmsh's surface tags of the
    /// geometry as imported), ascending, each once; mid-edge nodes of those triangles included.
    Faces(Vec<u32>),
}

/// One supported region: the nodes it selects have `components` fixed to zero (`kind` held),
/// or its surface is held by springs (the other kinds).
#[derive(Clone, Debug, PartialEq)]
pub struct Support {
    /// Selected nodes.
    pub region: Region,
    /// Fixed displacement components (x, y, z); for an elastic support, the directions its
    /// springs act along.
    pub components: [bool; 3],
    /// How it holds.
    pub kind: SupportKind,
}

/// How a `[[fixed]]` region holds the part (`kind` in the scene, docs/scene.md).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SupportKind {
    /// `"clamped"` (the default): the selected nodes' `components` removed.
    Held,
    /// `"sliding"`: the surface held along its normal only, free to slide along it
    /// (frictionless), by a stiff spring along each triangle's normal.
    Sliding,
    /// `"bearing"`: a cylindrical face held radially (the axis found from the face's normals),
    /// free to turn about its axis and to tilt, by stiff springs; free to slide along it too (a
    /// floating bearing) unless `located`, when a stiff spring holds the ring's mean axial
    /// displacement (a located bearing: holding the axial direction at every point of the ring
    /// would hold the tilt too).
    Bearing {
        /// Held along its axis too (`located = true`).
        located: bool,
    },
    /// `"elastic"`: springs of `stiffness` N/m³ (force per area per metre) along `components`.
    Elastic {
        /// N/m³.
        stiffness: f64,
    },
}

/// Largest elastic support stiffness accepted, N/m³ (steel's modulus over a micrometre).
pub const MAX_STIFFNESS: f64 = 1e18;

/// Modes to keep.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModeSettings {
    /// Number of elastic modes kept.
    pub count: usize,
}

/// Rayleigh damping D = αM + βK.
#[derive(Clone, Copy, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Damping {
    /// Mass-proportional coefficient, 1/s.
    #[serde(default)]
    pub alpha: f64,
    /// Stiffness-proportional coefficient, s.
    #[serde(default)]
    pub beta: f64,
}

/// A volume of interest: meshed finer, it yields its own modal space.
#[derive(Clone, Debug, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct Voi {
    /// Name of the space.
    pub name: String,
    /// Where it is, m.
    #[serde(rename = "box")]
    pub bbox: BoxRegion,
    /// Element size inside, m.
    pub size: f64,
}

/// A validated scene.
#[derive(Clone, Debug)]
pub struct Scene {
    /// Scene name (default: the file stem).
    pub name: String,
    /// The scene file itself.
    pub path: PathBuf,
    /// Its text, stored verbatim in the basis file.
    pub toml: String,
    /// Geometry file, absolute.
    pub geometry: PathBuf,
    /// Unit of the geometry file's coordinates.
    pub unit: LengthUnit,
    /// Whether the scene said `unit` (optional for STEP and IGES, which carry their own).
    pub unit_given: bool,
    /// Material.
    pub material: Material,
    /// Mesh settings.
    pub mesh: MeshSettings,
    /// Supports (empty: free body).
    pub fixed: Vec<Support>,
    /// Modes kept.
    pub modes: ModeSettings,
    /// Damping.
    pub damping: Damping,
    /// Volumes of interest.
    pub voi: Vec<Voi>,
    /// Static correction, if asked.
    pub static_correction: Option<StaticCorrection>,
    /// Radius of the hand's contact patch, m (`[contact] radius`; default
    /// [`DEFAULT_CONTACT_RADIUS_M`]; 0: a point contact at one vertex).
    pub contact_radius: f64,
    /// Whether each mode's stress is stored (`[stress] enabled = true`).
    pub stress: bool,
    /// Whether each load case's peak stress is studied on meshes refined around it
    /// (`[stress] peak_error`, default true).
    pub peak_error: bool,
    /// Probe points for `ves report`.
    pub probes: Vec<Probe>,
    /// Service load cases (`[[load]]`, then `[gravity]`), each solved statically.
    pub loads: Vec<LoadCase>,
    /// A geometrically nonlinear model (`[model] kind = "nonlinear"`); `None`: linear.
    pub nonlinear: Option<Nonlinear>,
}

/// One static load case of the scene.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadCase {
    /// Its name (an identifier; `gravity` for `[gravity]`).
    pub name: String,
    /// What acts.
    pub applied: Applied,
}

/// What a load case applies.
#[derive(Clone, Debug, PartialEq)]
pub enum Applied {
    /// A total force, N, spread over the region's surface in proportion to area.
    Force {
        /// The surface region (selected as a support's is).
        region: Region,
        /// Total force, N.
        total: [f64; 3],
    },
    /// A pressure, Pa, along the inward normal of each surface triangle of the region.
    Pressure {
        /// The surface region.
        region: Region,
        /// Pressure, Pa (positive pushes into the part).
        pascal: f64,
    },
    /// A uniform acceleration field on the whole part, m/s²: loads M·g.
    Gravity {
        /// Acceleration, m/s².
        acceleration: [f64; 3],
    },
}

impl Applied {
    /// `force`, `pressure` or `gravity`, as the basis file's `kind` attribute says.
    pub fn kind(&self) -> &'static str {
        match self {
            Applied::Force { .. } => "force",
            Applied::Pressure { .. } => "pressure",
            Applied::Gravity { .. } => "gravity",
        }
    }

    /// The surface region, for the surface loads.
    pub fn region(&self) -> Option<&Region> {
        match self {
            Applied::Force { region, .. } | Applied::Pressure { region, .. } => Some(region),
            Applied::Gravity { .. } => None,
        }
    }
}

const GEOMETRY_EXTENSIONS: [&str; 6] = ["step", "stp", "brep", "geo", "iges", "igs"];

/// What a scene may ask of the machine.
#[derive(Clone, Copy, Debug, Default)]
pub struct SceneOptions {
    /// Accept a `.geo` geometry. A .geo file is a gmsh script and can run shell commands
    /// (`System "…"`): a scene from someone else would be code. Off unless the user says so.
    pub allow_geo_scripts: bool,
}

impl Scene {
    /// Reads and validates a scene file whose geometry is data (STEP, IGES, BREP), not a script.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        Self::load_with(path, SceneOptions::default())
    }

    /// Reads and validates a scene file under `opts`.
    pub fn load_with(path: &Path, opts: SceneOptions) -> Result<Scene, SceneError> {
        let err = |message: String| SceneError {
            file: path.to_path_buf(),
            message,
        };
        let text = crate::input::read_scene(path).map_err(|e| err(e.to_string()))?;
        let scene = Self::parse(path, &text)?;
        if scene.is_script() && !opts.allow_geo_scripts {
            return Err(err(format!(
                "geometry.step = {:?}: a .geo file is a gmsh script and can run shell commands; export the part as STEP, \
                 or pass --allow-geo-scripts if you trust this scene",
                scene.geometry.display()
            )));
        }
        scene.notice_unit_override();
        if let Some(slip) = scene.material.unit_slip() {
            tracing::warn!("{}: {slip}", path.display());
        }
        Ok(scene)
    }

    /// A STEP file states its own length unit and OpenCASCADE applies it: a scene `unit` that
    /// differs is ignored, which the user should hear once.
    fn notice_unit_override(&self) {
        let is_step = self
            .geometry
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("step") || e.eq_ignore_ascii_case("stp"));
        let Some(bytes) = is_step.then(|| crate::input::read(&self.geometry).ok()).flatten() else {
            return;
        };
        let Some(file_unit) = crate::step_units::length_unit(&String::from_utf8_lossy(&bytes)) else {
            return;
        };
        if !self.unit_given {
            return;
        }
        let said = self.unit.to_metres();
        if (file_unit.metres - said).abs() > 1e-9 * said {
            tracing::warn!(
                "{}: geometry.unit = {:?} is ignored: {} states its own unit ({}), and that is what is used",
                self.path.display(),
                self.unit.symbol(),
                self.geometry.display(),
                file_unit.name.to_lowercase()
            );
        }
    }

    /// The files this scene is made from (no output may overwrite them).
    pub fn inputs(&self) -> [&std::path::Path; 2] {
        [&self.path, &self.geometry]
    }

    /// Whether the geometry is a gmsh script (.geo) rather than data.
    pub fn is_script(&self) -> bool {
        self.geometry.extension().is_some_and(|e| e.eq_ignore_ascii_case("geo"))
    }

    /// Parses scene text as if read from `path` (relative paths resolve beside it).
    pub fn parse(path: &Path, text: &str) -> Result<Scene, SceneError> {
        let err = |message: String| SceneError {
            file: path.to_path_buf(),
            message,
        };
        if text.len() > MAX_SCENE_TEXT_BYTES {
            return Err(err(format!(
                "the scene is {} bytes; a basis stores its scene's text in at most {} KiB: shorten it (long comments, \
                 long face lists)",
                text.len(),
                MAX_SCENE_TEXT_BYTES >> 10
            )));
        }
        let raw: RawScene = toml::from_str(text).map_err(|e| err(one_line_toml_error(text, &e)))?;
        let dir = path.parent().unwrap_or(Path::new("."));
        let dir = std::path::absolute(dir).unwrap_or_else(|_| dir.to_path_buf());

        let m = raw.material;
        finite_positive("material.young", m.young, "Pa").map_err(err)?;
        finite_positive("material.density", m.density, "kg/m³").map_err(err)?;
        // Beyond real materials the eigen-solve leaves double precision (LAPACK gave up on
        // density = 1e120): refuse what no part is made of, and say which unit is expected.
        within(
            "material.young",
            m.young,
            YOUNG_RANGE,
            "Pa",
            "steel 2.1e11, a soft foam 2e3",
        )
        .map_err(err)?;
        within(
            "material.density",
            m.density,
            DENSITY_RANGE,
            "kg/m³",
            "steel 7850, a polymer 1050",
        )
        .map_err(err)?;
        if let Some(y) = m.yield_strength {
            within(
                "material.yield_strength",
                y,
                YOUNG_RANGE,
                "Pa",
                "structural steel 2.5e8, an aluminium alloy 2.7e8",
            )
            .map_err(err)?;
        }
        if !m.poisson.is_finite() || m.poisson <= -1.0 || m.poisson >= 0.5 {
            return Err(err(format!(
                "material.poisson = {}: Poisson's ratio must lie in (-1, 0.5); use 0.49 or less for nearly incompressible materials",
                m.poisson
            )));
        }
        match raw.mesh.target_error {
            None if raw.mesh.size == 0.0 => {
                return Err(err(
                    "mesh.size missing: give the element size in metres (e.g. 1/15 of the part), or set \
                     mesh.target_error = 0.01 to let VES refine to 1 % from a size it picks"
                        .into(),
                ));
            }
            Some(t) if !(1e-4..=0.5).contains(&t) => {
                return Err(err(format!(
                    "mesh.target_error = {t}: a relative frequency error between 1e-4 and 0.5 (e.g. 0.01 for 1 %)"
                )));
            }
            _ => {}
        }
        if raw.mesh.size != 0.0 || raw.mesh.target_error.is_none() {
            element_size("mesh.size", raw.mesh.size).map_err(err)?;
        }
        if raw.mesh.target_error.is_some() && !raw.mesh.error_estimate.on() {
            return Err(err(
                "mesh.target_error needs the error estimate: remove error_estimate = false".into(),
            ));
        }
        if raw.mesh.max_dofs < 100 {
            return Err(err(format!(
                "mesh.max_dofs = {}: at least 100 unknowns",
                raw.mesh.max_dofs
            )));
        }
        if !matches!(raw.mesh.order, 1 | 2) {
            return Err(err(format!(
                "mesh.order = {}: must be 1 (4-node tets) or 2 (10-node tets)",
                raw.mesh.order
            )));
        }
        if raw.modes.count == 0 || raw.modes.count > 2000 {
            return Err(err(format!(
                "modes.count = {}: must be between 1 and 2000",
                raw.modes.count
            )));
        }
        for (key, v, max, unit) in [
            ("damping.alpha", raw.damping.alpha, MAX_DAMPING_ALPHA, "1/s"),
            ("damping.beta", raw.damping.beta, MAX_DAMPING_BETA, "s"),
        ] {
            if !(0.0..=max).contains(&v) {
                return Err(err(format!(
                    "{key} = {v:e}: Rayleigh coefficients are finite, ≥ 0 and at most {max:e} {unit} (beyond, every \
                     mode is overdamped thousands of times over; e.g. beta = 1e-5)"
                )));
            }
        }

        let geometry = dir.join(&raw.geometry.step);
        let ext = geometry
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .unwrap_or_default();
        let unsupported = || {
            err(format!(
                "geometry.step = {:?}: unsupported file type; use a .step/.stp, .iges, .brep or .geo file",
                shorten(&raw.geometry.step.to_string_lossy(), 200)
            ))
        };
        let supported = GEOMETRY_EXTENSIONS.contains(&ext.as_str());
        // Type and size before any byte is read: a FIFO or a device would block or never end.
        if let Err(e) = crate::input::open(&geometry) {
            if !supported && !geometry.exists() {
                return Err(unsupported());
            }
            return Err(err(format!(
                "geometry.step = {:?}: {}",
                shorten(&raw.geometry.step.to_string_lossy(), 200),
                shorten(&e.to_string(), 400)
            )));
        }
        if !supported {
            return Err(unsupported());
        }
        // STEP and IGES files carry their unit (OpenCASCADE applies it): `unit` is optional
        // there, and ignored. BREP and gmsh scripts are bare numbers: it is needed.
        let carries_unit = matches!(ext.as_str(), "step" | "stp" | "iges" | "igs");
        let unit = match (raw.geometry.unit, carries_unit) {
            (Some(u), _) => u,
            (None, true) => LengthUnit::Millimetre,
            (None, false) => {
                return Err(err(format!(
                    "geometry.unit: missing; a .{ext} file's coordinates carry no unit: add unit = \"mm\" or unit = \"m\" under [geometry]"
                )));
            }
        };

        let mut fixed = Vec::with_capacity(raw.fixed.len());
        for (i, f) in raw.fixed.iter().enumerate() {
            fixed.push(support(i, f).map_err(err)?);
        }
        if raw.voi.len() >= ves_format::names::MAX_SPACES {
            return Err(err(format!(
                "{} [[voi]]: a basis holds at most {} spaces (\"global\" and {} volumes of interest)",
                raw.voi.len(),
                ves_format::names::MAX_SPACES,
                ves_format::names::MAX_SPACES - 1
            )));
        }
        let mut names = vec!["global".to_string()];
        for (i, v) in raw.voi.iter().enumerate() {
            element_size(&format!("voi[{i}].size"), v.size).map_err(err)?;
            check_box(&format!("voi[{i}].box"), &v.bbox).map_err(err)?;
            // The name becomes an HDF5 group, a .vtu file name and part of messages.
            ves_format::check_identifier(&format!("voi[{i}].name"), &v.name).map_err(|e| err(e.to_string()))?;
            if names.contains(&v.name) {
                return Err(err(format!(
                    "voi[{i}].name = {:?}: names must be unique and not \"global\" (the whole part's space); \
                     rename this VOI",
                    v.name
                )));
            }
            names.push(v.name.clone());
        }
        for (i, p) in raw.probe.iter().enumerate() {
            point(&format!("probe[{i}].at"), p.at).map_err(err)?;
            force(&format!("probe[{i}].force"), p.force).map_err(err)?;
        }
        let nonlinear = nonlinear_model(&raw, fixed.is_empty()).map_err(err)?;
        // The name becomes the output's file name (`<name>.h5`, in `ves batch --out DIR` too):
        // an identifier, never a path.
        let name = match raw.name {
            Some(n) => {
                ves_format::check_identifier("name", &n).map_err(|e| err(e.to_string()))?;
                n
            }
            None => {
                let stem = path
                    .file_stem()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_default();
                ves_format::check_identifier("name (the scene file's name, its default)", &stem)
                    .map_err(|m| err(format!("{m}; or set name = \"…\" in the scene")))?;
                stem
            }
        };
        let fixed_empty = fixed.is_empty();
        Ok(Scene {
            name,
            path: path.to_path_buf(),
            toml: text.to_string(),
            geometry,
            unit,
            unit_given: raw.geometry.unit.is_some(),
            material: m,
            mesh: raw.mesh,
            fixed,
            modes: raw.modes,
            damping: raw.damping,
            voi: raw.voi,
            static_correction: raw.static_correction,
            contact_radius: contact_radius(raw.contact).map_err(err)?,
            stress: raw.stress.is_some_and(|s| s.enabled),
            peak_error: raw.stress.is_none_or(|s| s.peak_error),
            probes: raw.probe,
            loads: load_cases(&raw.load, raw.gravity.as_ref(), !fixed_empty).map_err(err)?,
            nonlinear,
        })
    }
}

/// The `[model]` table checked against the rest of the scene.
fn nonlinear_model(raw: &RawScene, free_body: bool) -> Result<Option<Nonlinear>, String> {
    let Some(m) = raw.model.filter(|m| m.kind == ModelKind::Nonlinear) else {
        if raw.model.is_some_and(|m| m.derivatives.is_some()) {
            return Err("model.derivatives is for model.kind = \"nonlinear\": remove it or set the kind".into());
        }
        return Ok(None);
    };
    let count = raw.modes.count;
    let d = m.derivatives.unwrap_or(DEFAULT_DERIVATIVES.min(count));
    if d == 0 || d > count {
        return Err(format!(
            "model.derivatives = {d}: the derivatives of 1 to modes.count = {count} lowest modes; use {}",
            DEFAULT_DERIVATIVES.min(count)
        ));
    }
    // Each load case adds its linear response and that response's derivative.
    let loads = 2 * (raw.load.len() + usize::from(raw.gravity.is_some()));
    let r = count + d * (d + 1) / 2 + loads;
    let max = ves_format::names::MAX_NONLINEAR_BASIS;
    if r > max {
        return Err(format!(
            "modes.count = {count} with model.derivatives = {d} and {} load case(s) (2 vectors each) makes a \
             nonlinear basis of {r} vectors, over {max} (the haptic step's cost grows as r⁴): lower modes.count or \
             model.derivatives, or move load cases to another scene",
            loads / 2
        ));
    }
    if free_body {
        return Err(
            "model.kind = \"nonlinear\" needs a held part: add a [[fixed]] support, or use kind = \"linear\"".into(),
        );
    }
    if !raw.voi.is_empty() {
        return Err(
            "model.kind = \"nonlinear\" has one space: remove the [[voi]] entries, or use kind = \"linear\"".into(),
        );
    }
    if raw.static_correction.is_some() {
        return Err(
            "[static_correction] is a linear correction: remove it from a model.kind = \"nonlinear\" scene".into(),
        );
    }
    if raw.stress.as_ref().is_some_and(|s| s.enabled) {
        return Err(
            "[stress] enabled stores each mode's linear stress, which reads a large rotation as stress: remove it \
             from a model.kind = \"nonlinear\" scene (its load cases carry their true Cauchy stress)"
                .into(),
        );
    }
    Ok(Some(Nonlinear { derivatives: d }))
}

/// Default radius of the hand's contact patch, m: a fingertip pressed on a part touches a disk
/// of about 1 cm (`loads::patch`).
pub const DEFAULT_CONTACT_RADIUS_M: f64 = 0.005;

/// The contact patch's radius: the scene's, or the default.
fn contact_radius(contact: Option<ContactSettings>) -> Result<f64, String> {
    match contact {
        None => Ok(DEFAULT_CONTACT_RADIUS_M),
        Some(c) if c.radius.is_finite() && (0.0..=1.0).contains(&c.radius) => Ok(c.radius),
        Some(c) => Err(format!(
            "contact.radius = {}: give the hand's contact patch radius in metres, 0 to 1 (e.g. 0.005 for a \
             fingertip, 0 for one vertex)",
            c.radius
        )),
    }
}

/// toml's messages span several lines (with a source excerpt); keep one line that shows the
/// offending line of the file, which names the key.
fn one_line_toml_error(text: &str, e: &toml::de::Error) -> String {
    let msg = e.message().trim().replace('\n', " ");
    match e.span() {
        Some(span) => {
            let start = span.start.min(text.len());
            let line_no = text[..start].matches('\n').count() + 1;
            let line = text.lines().nth(line_no - 1).unwrap_or("").trim();
            format!("line {line_no} (`{}`): {}", shorten(line, 80), shorten(&msg, 400))
        }
        None => format!("invalid scene: {msg}"),
    }
}

/// Longest scene text, bytes: the basis stores it verbatim in one string attribute
/// (`scene_toml`), which holds at most this much.
pub const MAX_SCENE_TEXT_BYTES: usize = ves_format::strings::MAX_BYTES;

/// Largest coordinate a scene may give (box corners, plane values, probe points), m, either
/// way. No part is a thousand kilometres long, a box meant to hold everything can say ±1e6, and
/// a coordinate stays finite through every product the pipeline forms (squares of differences,
/// the division by 1e-3 that hands a millimetre geometry its fields in millimetres).
pub const MAX_COORDINATE_M: f64 = 1e6;

/// Largest length a scene may give (element sizes, plane tolerances), m.
pub const MAX_LENGTH_M: f64 = 1e6;

/// Smallest element size, m: a nanometre, finer than any part is meshed. Far below it the
/// element-count estimate (size³) underflows to zero and its quotients become infinite.
pub const MIN_ELEMENT_SIZE_M: f64 = 1e-9;

/// Largest force component, N (a probe's, a load case's total): far beyond any service load
/// (a rocket engine's thrust is 1e7 N), small enough that stresses, their squares (von Mises)
/// and displacements on the softest, smallest part the scene admits stay finite, in f64 and in
/// the f32 the page is sent.
pub const MAX_FORCE_N: f64 = 1e12;

/// Largest pressure, Pa, either way: the top of the range of Young's moduli ([`YOUNG_RANGE`]).
pub const MAX_PRESSURE_PA: f64 = 1e13;

/// Largest acceleration component, m/s² (1e8 g): beyond any centrifuge or impact.
pub const MAX_ACCELERATION: f64 = 1e9;

/// Largest Rayleigh α, 1/s.
pub const MAX_DAMPING_ALPHA: f64 = 1e6;

/// Largest Rayleigh β, s.
pub const MAX_DAMPING_BETA: f64 = 1.0;

fn within_reach(x: f64) -> bool {
    x.abs() <= MAX_COORDINATE_M
}

fn point(key: &str, p: [f64; 3]) -> Result<(), String> {
    if p.iter().all(|&x| within_reach(x)) {
        Ok(())
    } else {
        Err(format!(
            "{key} = {p:?}: a point in m, finite and each coordinate within ±{MAX_COORDINATE_M:e} m"
        ))
    }
}

fn force(key: &str, f: [f64; 3]) -> Result<(), String> {
    if f.iter().all(|v| v.abs() <= MAX_FORCE_N) && f.iter().any(|&v| v != 0.0) {
        Ok(())
    } else {
        Err(format!(
            "{key} = {f:?}: a force in N, not all zero and each component at most {MAX_FORCE_N:e} N either way"
        ))
    }
}

fn element_size(key: &str, h: f64) -> Result<(), String> {
    if (MIN_ELEMENT_SIZE_M..=MAX_LENGTH_M).contains(&h) {
        Ok(())
    } else {
        Err(format!(
            "{key} = {h:e}: an element size in m, from {MIN_ELEMENT_SIZE_M:e} to {MAX_LENGTH_M:e} m"
        ))
    }
}

/// Face tags as an error quotes them: ` = [..]` when short; else their count and the first few,
/// so that the error stays one readable line.
pub fn quote_tags(tags: &[u32]) -> String {
    const SHOWN: usize = 8;
    if tags.len() <= SHOWN {
        format!(" = {tags:?}")
    } else {
        let first: Vec<String> = tags[..SHOWN].iter().map(u32::to_string).collect();
        format!(": {} entries, the first: [{}, …]", tags.len(), first.join(", "))
    }
}

/// `s` cut to its first `shown` characters (an ellipsis says so): what an error quotes of a
/// line or of toml's message (which may quote the value).
fn shorten(s: &str, shown: usize) -> String {
    match s.char_indices().nth(shown) {
        Some((at, _)) => format!("{}…", &s[..at]),
        None => s.to_string(),
    }
}

/// Young's moduli of real materials, Pa: from soft gels to diamond, with margin.
pub const YOUNG_RANGE: (f64, f64) = (1.0, 1e13);
/// Densities of real materials, kg/m³: from aerogels to osmium, with margin.
pub const DENSITY_RANGE: (f64, f64) = (0.1, 1e5);

fn within(key: &str, v: f64, (lo, hi): (f64, f64), unit: &str, examples: &str) -> Result<(), String> {
    if (lo..=hi).contains(&v) {
        Ok(())
    } else {
        Err(format!(
            "{key} = {v:e}: outside the range of real materials ({lo:e} to {hi:e} {unit}); give it in {unit} (e.g. {examples})"
        ))
    }
}

fn finite_positive(key: &str, v: f64, unit: &str) -> Result<(), String> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(format!("{key} = {v}: must be a finite number > 0 ({unit})"))
    }
}

/// How far a probe may lie outside the part's bounding box, as a fraction of the box's largest
/// extent: a probe is snapped to the nearest surface vertex, so a point just off the surface is
/// meant; one farther away is a mistake (another unit, a wrong sign).
pub const PROBE_OUTSIDE_FRACTION: f64 = 0.01;

impl Scene {
    /// Refuses a VOI box that does not overlap the part's bounding box `lo`–`hi` (m) and a probe
    /// farther than [`PROBE_OUTSIDE_FRACTION`] of the part outside it. The bounding box is known
    /// once the part is meshed: called then, before any solve.
    pub fn check_regions_on_part(&self, lo: [f64; 3], hi: [f64; 3]) -> Result<(), SceneError> {
        let err = |message: String| SceneError {
            file: self.path.clone(),
            message,
        };
        let largest = (0..3).map(|c| hi[c] - lo[c]).fold(0.0, f64::max);
        let part = format!(
            "the part's bounding box is min {} max {} m",
            fmt3(lo, largest),
            fmt3(hi, largest)
        );
        for (i, v) in self.voi.iter().enumerate() {
            let b = &v.bbox;
            if (0..3).any(|c| b.min[c] >= hi[c] || b.max[c] <= lo[c]) {
                return Err(err(format!(
                    "voi[{i}] ({:?}): box min {:?} max {:?} m does not overlap the part ({part}); \
                     move the box onto the part (in metres, as the part is placed in its geometry file)",
                    v.name, b.min, b.max
                )));
            }
        }
        let tol = PROBE_OUTSIDE_FRACTION * largest;
        for (i, p) in self.probes.iter().enumerate() {
            let outside = (0..3)
                .map(|c| (lo[c] - p.at[c]).max(p.at[c] - hi[c]).max(0.0))
                .map(|d| d * d)
                .sum::<f64>()
                .sqrt();
            if outside > tol {
                return Err(err(format!(
                    "probe[{i}]: at {:?} m lies {} m outside the part ({part}); \
                     give a point on the part's surface (in metres, as the part is placed in its geometry file)",
                    p.at,
                    fmt1(outside, largest)
                )));
            }
        }
        Ok(())
    }
}

/// A length on a part whose largest extent is `size`, to a thousandth of it or better.
fn fmt1(x: f64, size: f64) -> String {
    let decimals = if size > 0.0 && size.is_finite() {
        (3 - size.log10().floor() as i32).clamp(0, 12) as usize
    } else {
        6
    };
    format!("{x:.decimals$}")
}

/// A point on a part whose largest extent is `size` (see [`fmt1`]).
fn fmt3(p: [f64; 3], size: f64) -> String {
    format!("[{}, {}, {}]", fmt1(p[0], size), fmt1(p[1], size), fmt1(p[2], size))
}

fn check_box(key: &str, b: &BoxRegion) -> Result<(), String> {
    if b.min.iter().chain(&b.max).any(|v| !within_reach(*v)) || (0..3).any(|c| b.min[c] > b.max[c]) {
        return Err(format!(
            "{key}: min {:?} and max {:?} must be finite, within ±{MAX_COORDINATE_M:e} m, with min ≤ max on each axis",
            b.min, b.max
        ));
    }
    Ok(())
}

fn axis_index(key: &str, s: &str) -> Result<usize, String> {
    match s {
        "x" => Ok(0),
        "y" => Ok(1),
        "z" => Ok(2),
        _ => Err(format!("{key} = {:?}: must be \"x\", \"y\" or \"z\"", shorten(s, 24))),
    }
}

fn support(i: usize, f: &RawFixed) -> Result<Support, String> {
    let region = region(
        &format!("fixed[{i}]"),
        f.plane.as_ref(),
        f.bbox.as_ref(),
        f.faces.as_ref(),
    )?;
    let kind = match (f.kind.as_deref(), f.stiffness) {
        (None | Some("clamped"), None) => SupportKind::Held,
        (Some("sliding"), None) => SupportKind::Sliding,
        (Some("bearing"), None) => SupportKind::Bearing {
            located: f.located.unwrap_or(false),
        },
        (Some("elastic"), Some(k)) if k.is_finite() && k > 0.0 && k <= MAX_STIFFNESS => {
            SupportKind::Elastic { stiffness: k }
        }
        (Some("elastic"), Some(k)) => {
            return Err(format!(
                "fixed[{i}].stiffness = {k:e}: must be positive and at most {MAX_STIFFNESS:e} N/m³ (force per area per metre, e.g. 1e9 for a rubber mount)"
            ));
        }
        (Some("elastic"), None) => {
            return Err(format!(
                "fixed[{i}]: kind = \"elastic\" needs stiffness, in N/m³ (force per area per metre, e.g. 1e9 for a rubber mount)"
            ));
        }
        (None | Some("clamped" | "sliding" | "bearing"), Some(_)) => {
            return Err(format!(
                "fixed[{i}].stiffness: only an elastic support has one; add kind = \"elastic\" or remove stiffness"
            ));
        }
        (Some(other), _) => {
            return Err(format!(
                "fixed[{i}].kind = {:?}: must be \"clamped\", \"sliding\", \"bearing\" or \"elastic\"",
                shorten(other, 24)
            ));
        }
    };
    if f.located.is_some() && !matches!(kind, SupportKind::Bearing { .. }) {
        return Err(format!(
            "fixed[{i}].located: only a bearing is located; add kind = \"bearing\" or remove located"
        ));
    }
    if matches!(kind, SupportKind::Sliding | SupportKind::Bearing { .. }) && f.components.is_some() {
        return Err(format!(
            "fixed[{i}].components: a {} support holds its own directions; remove components",
            f.kind.as_deref().unwrap_or_default()
        ));
    }
    let mut components = [false; 3];
    match &f.components {
        None => components = [true; 3],
        Some(list) if list.is_empty() => {
            return Err(format!(
                "fixed[{i}].components: empty; list at least one of \"x\", \"y\", \"z\""
            ));
        }
        Some(list) => {
            for s in list {
                components[axis_index(&format!("fixed[{i}].components"), s)?] = true;
            }
        }
    }
    Ok(Support {
        region,
        components,
        kind,
    })
}

/// The region of a `[[fixed]]` or `[[load]]` entry (`key`: `fixed[0]`, `load[2]`): exactly one
/// of `plane`, `box` and `faces`.
fn region(
    key: &str,
    plane: Option<&RawPlane>,
    bbox: Option<&BoxRegion>,
    faces: Option<&Vec<u32>>,
) -> Result<Region, String> {
    Ok(match (plane, bbox, faces) {
        (Some(p), None, None) => {
            let axis = axis_index(&format!("{key}.plane.axis"), &p.axis)?;
            if !within_reach(p.value) {
                return Err(format!(
                    "{key}.plane.value = {:e}: a coordinate in m, finite and within ±{MAX_COORDINATE_M:e} m",
                    p.value
                ));
            }
            match p.tol {
                Some(t) if !(t > 0.0 && t <= MAX_LENGTH_M) => {
                    return Err(format!(
                        "{key}.plane.tol = {t:e}: a distance in m, > 0 and at most {MAX_LENGTH_M:e} m"
                    ));
                }
                _ => {}
            }
            Region::Plane {
                axis,
                value: p.value,
                tol: p.tol,
            }
        }
        (None, Some(b), None) => {
            check_box(&format!("{key}.box"), b)?;
            Region::Box(*b)
        }
        (None, None, Some(list)) => {
            if list.is_empty() {
                return Err(format!(
                    "{key}.faces: empty; list at least one CAD face tag (gmsh's surface tags of the geometry)"
                ));
            }
            if list.contains(&0) {
                return Err(format!(
                    "{key}.faces{}: face tags start at 1 (gmsh numbers the faces of the geometry from 1)",
                    quote_tags(list)
                ));
            }
            let mut tags = list.clone();
            tags.sort_unstable();
            tags.dedup();
            Region::Faces(tags)
        }
        _ => return Err(format!("{key}: give exactly one of `plane`, `box` or `faces`")),
    })
}

/// Most load cases a scene may have (each is a static solve and a field in the basis).
pub const MAX_LOAD_CASES: usize = 64;

/// The `[[load]]` entries, then `[gravity]` as the case named `gravity`, checked.
fn load_cases(raw: &[RawLoad], gravity: Option<&RawGravity>, held: bool) -> Result<Vec<LoadCase>, String> {
    if !held && (!raw.is_empty() || gravity.is_some()) {
        let what = if raw.is_empty() { "[gravity]" } else { "[[load]]" };
        return Err(format!(
            "{what}: a load case needs supports, and the part has no [[fixed]] region (a free body's static \
             displacement is not defined: inertia relief is not implemented); add a [[fixed]] region"
        ));
    }
    if raw.len() + usize::from(gravity.is_some()) > MAX_LOAD_CASES {
        return Err(format!(
            "{} load cases: at most {MAX_LOAD_CASES} (each is a static solve and a field in the basis)",
            raw.len() + usize::from(gravity.is_some())
        ));
    }
    let mut cases: Vec<LoadCase> = Vec::with_capacity(raw.len() + 1);
    for (i, l) in raw.iter().enumerate() {
        let key = format!("load[{i}]");
        load_name(&key, &l.name)?;
        if cases.iter().any(|c| c.name == l.name) || (gravity.is_some() && l.name == "gravity") {
            return Err(format!(
                "{key}.name = {:?}: another load case has that name (`gravity` is [gravity]'s); rename this one",
                l.name
            ));
        }
        let region = region(&key, l.plane.as_ref(), l.bbox.as_ref(), l.faces.as_ref())?;
        let applied = match (l.force, l.pressure) {
            (Some(f), None) => {
                force(&format!("{key}.force"), f)?;
                Applied::Force { region, total: f }
            }
            (None, Some(p)) => {
                if p == 0.0 || !(-MAX_PRESSURE_PA..=MAX_PRESSURE_PA).contains(&p) {
                    return Err(format!(
                        "{key}.pressure = {p:e}: a pressure in Pa, not zero and at most {MAX_PRESSURE_PA:e} Pa either way \
                         (positive pushes into the part)"
                    ));
                }
                Applied::Pressure { region, pascal: p }
            }
            _ => return Err(format!("{key}: give exactly one of `force` (N) or `pressure` (Pa)")),
        };
        cases.push(LoadCase {
            name: l.name.clone(),
            applied,
        });
    }
    if let Some(g) = gravity {
        let a = g.acceleration;
        if a.iter().any(|v| !(-MAX_ACCELERATION..=MAX_ACCELERATION).contains(v)) || a.iter().all(|&v| v == 0.0) {
            return Err(format!(
                "gravity.acceleration = {a:?}: an acceleration in m/s², not all zero and each component at most \
                 {MAX_ACCELERATION:e} m/s² either way (e.g. [0.0, 0.0, -9.81])"
            ));
        }
        cases.push(LoadCase {
            name: "gravity".into(),
            applied: Applied::Gravity { acceleration: a },
        });
    }
    Ok(cases)
}

/// A load case's name: a plain identifier (letters, digits, `_`, `-`, not starting with a digit
/// or `-`), as it becomes an HDF5 group and part of ParaView array names. Never a path.
fn load_name(key: &str, name: &str) -> Result<(), String> {
    let mut chars = name.chars();
    let plain = name.len() <= 64
        && chars.next().is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
    if plain {
        Ok(())
    } else {
        Err(format!(
            "{key}.name = \"{}\": a load name is a plain identifier (ASCII letters, digits, `_` and `-`, starting \
             with a letter or `_`, at most 64 bytes), e.g. \"tip\" or \"bolt_preload\"",
            ves_format::names::escape_for_terminal(&shorten(name, 80))
        ))
    }
}

#[cfg(test)]
mod mutation_tests {
    use super::*;

    const SCENE: &str = r#"name = "m"
[geometry]
step = "x.step"
unit = "mm"
[material]
young = 2.1e11
poisson = 0.3
density = 7850.0
[mesh]
size = 0.01
order = 2
[[fixed]]
plane = { axis = "x", value = 0.0, tol = 1e-6 }
components = ["x", "z"]
[[fixed]]
box = { min = [0.0, 0.0, 0.0], max = [1.0, 1.0, 1.0] }
[modes]
count = 10
[damping]
alpha = 0.1
beta = 1e-5
[[voi]]
name = "a"
box = { min = [0.0, 0.0, 0.0], max = [0.1, 0.1, 0.1] }
size = 0.001
[static_correction]
region = "surface"
[[probe]]
at = [0.1, 0.0, 0.05]
force = [0.0, 1.0, 0.0]
[[load]]
name = "tip"
box = { min = [0.9, 0.0, 0.0], max = [1.0, 1.0, 1.0] }
force = [0.0, 0.0, -100.0]
[gravity]
acceleration = [0.0, 0.0, -9.81]
"#;

    /// A bearing may be located (held along its axis too); `located` on another kind is refused
    /// with what to change.
    #[test]
    fn only_a_bearing_is_located() {
        let dir = tempfile::tempdir().expect("tempdir");
        std::fs::write(dir.path().join("x.step"), "ISO-10303-21;").expect("geometry stub");
        let path = dir.path().join("s.toml");
        let with = |lines: &str| Scene::parse(&path, &SCENE.replace("components = [\"x\", \"z\"]", lines));
        let kind = |lines: &str| with(lines).expect("a bearing").fixed[0].kind;
        assert_eq!(kind("kind = \"bearing\""), SupportKind::Bearing { located: false });
        assert_eq!(
            kind("kind = \"bearing\"\nlocated = true"),
            SupportKind::Bearing { located: true }
        );
        for lines in ["located = true", "kind = \"sliding\"\nlocated = false"] {
            let e = with(lines).expect_err(lines).to_string();
            assert!(
                e.contains("fixed[0].located: only a bearing is located; add kind = \"bearing\""),
                "{e}"
            );
        }
    }

    /// `geometry.unit` is optional for a STEP or IGES file (which carries its own unit) and
    /// required, with advice, for bare-number geometry (BREP).
    #[test]
    fn unit_is_optional_where_the_file_carries_its_own() {
        let dir = tempfile::tempdir().expect("tempdir");
        let dir = dir.path();
        std::fs::write(dir.join("x.step"), "ISO-10303-21;").expect("geometry stub");
        std::fs::write(dir.join("x.brep"), "DBRep_DrawableShape").expect("geometry stub");
        let path = dir.join("scene.toml");
        let without = SCENE.replace("unit = \"mm\"\n", "");
        let s = Scene::parse(&path, &without).expect("a STEP scene without unit");
        assert!(!s.unit_given);
        assert!(Scene::parse(&path, SCENE).expect("with unit").unit_given);
        let e = Scene::parse(&path, &without.replace("x.step", "x.brep")).expect_err("a BREP needs its unit");
        assert!(
            e.to_string().contains("unit = \"mm\"") && e.to_string().contains(".brep"),
            "{e}"
        );
        Scene::parse(&path, &SCENE.replace("x.step", "x.brep")).expect("a BREP with its unit");
    }

    /// `mesh.error_estimate` takes a bool (true: the default recovery estimate) or a mode's name,
    /// and a scene echoes it as it was written before the modes (true / false) unless "full".
    #[test]
    fn error_estimate_takes_a_bool_or_a_mode() {
        let dir = std::env::temp_dir().join(format!("ves-scene-estimate-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        std::fs::write(dir.join("x.step"), "ISO-10303-21;").expect("geometry stub");
        let path = dir.join("s.toml");
        let with = |line: &str| Scene::parse(&path, &SCENE.replace("order = 2", &format!("order = 2\n{line}")));
        for (line, mode, echo) in [
            ("", EstimateMode::Recovery, "true"),
            ("error_estimate = true", EstimateMode::Recovery, "true"),
            ("error_estimate = \"recovery\"", EstimateMode::Recovery, "true"),
            ("error_estimate = false", EstimateMode::Off, "false"),
            ("error_estimate = \"off\"", EstimateMode::Off, "false"),
            ("error_estimate = \"full\"", EstimateMode::Full, "\"full\""),
        ] {
            let s = with(line).unwrap_or_else(|e| panic!("{line}: {e}"));
            assert_eq!(s.mesh.error_estimate, mode, "{line}");
            assert_eq!(serde_json::to_string(&s.mesh.error_estimate).unwrap(), echo);
            let back: EstimateMode = serde_json::from_str(echo).unwrap();
            assert_eq!(back, mode);
        }
        for bad in ["error_estimate = \"fast\"", "error_estimate = 1"] {
            let e = with(bad).expect_err(bad).to_string();
            assert!(e.contains("error_estimate") && !e.contains('\n'), "{bad}: {e}");
        }
    }

    /// `faces` is a third region kind: sorted and each once; an empty list, tag 0, a negative
    /// tag or `faces` beside `plane` are refused in one line naming the key.
    #[test]
    fn faces_are_a_region_of_their_own() {
        let dir = std::env::temp_dir().join(format!("ves-scene-faces-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        std::fs::write(dir.join("x.step"), "ISO-10303-21;").expect("geometry stub");
        let path = dir.join("s.toml");
        let with = |fixed: &str| {
            let text = SCENE.replace("[modes]", &format!("[[fixed]]\n{fixed}\n[modes]"));
            Scene::parse(&path, &text)
        };
        let s = with("faces = [17, 3, 17]\ncomponents = [\"z\"]").expect("a face support");
        assert_eq!(s.fixed[2].region, Region::Faces(vec![3, 17]));
        assert_eq!(s.fixed[2].components, [false, false, true]);
        for (fixed, says) in [
            ("faces = []", "fixed[2].faces: empty"),
            ("faces = [0, 4]", "fixed[2].faces = [0, 4]: face tags start at 1"),
            ("faces = [-2]", "line "),
            (
                "faces = [1]\nplane = { axis = \"x\", value = 0.0 }",
                "exactly one of `plane`, `box` or `faces`",
            ),
        ] {
            let e = with(fixed).expect_err(fixed).to_string();
            assert!(e.contains(says) && !e.contains('\n'), "{fixed}: {e}");
        }
    }

    /// A load's region is parsed by the function that parses a support's (the same keys give
    /// the same region, the same refusals under its own key); names are plain identifiers;
    /// `[gravity]` is the case `gravity`, after the `[[load]]` entries.
    #[test]
    fn load_regions_are_parsed_as_support_regions() {
        let dir = std::env::temp_dir().join(format!("ves-scene-loads-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        std::fs::write(dir.join("x.step"), "ISO-10303-21;").expect("geometry stub");
        let path = dir.join("s.toml");
        let s = Scene::parse(&path, SCENE).expect("the base scene");
        assert_eq!(s.loads.len(), 2);
        assert_eq!(s.loads[1].name, "gravity");
        assert_eq!(s.loads[1].applied.kind(), "gravity");
        let with = |load: &str| {
            let text = SCENE.replace("[gravity]", &format!("[[load]]\n{load}\n[gravity]"));
            Scene::parse(&path, &text)
        };
        let same =
            with("name = \"q\"\nbox = { min = [0.0, 0.0, 0.0], max = [1.0, 1.0, 1.0] }\nforce = [1.0, 0.0, 0.0]");
        let same = same.expect("a box load");
        assert_eq!(same.loads[1].applied.region(), Some(&same.fixed[1].region));
        let s = with("name = \"p\"\nfaces = [4, 2, 4]\npressure = 1e5").expect("a face pressure");
        assert_eq!(
            s.loads[1].applied,
            Applied::Pressure {
                region: Region::Faces(vec![2, 4]),
                pascal: 1e5
            }
        );
        for (load, says) in [
            (
                "name = \"p\"\nfaces = [0]\npressure = 1e5",
                "load[1].faces = [0]: face tags start at 1",
            ),
            (
                "name = \"p\"\nplane = { axis = \"w\", value = 0.0 }\npressure = 1e5",
                "load[1].plane.axis",
            ),
            ("name = \"a b\"\nfaces = [1]\npressure = 1e5", "load[1].name"),
            ("name = \"C:x\"\nfaces = [1]\npressure = 1e5", "plain identifier"),
            ("name = \"tip\"\nfaces = [1]\npressure = 1e5", "another load case"),
            ("name = \"p\"\nfaces = [1]\npressure = nan", "load[1].pressure"),
        ] {
            let e = with(load).expect_err(load).to_string();
            assert!(e.contains(says) && !e.contains('\n'), "{load}: {e}");
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// A directory holding a geometry stub, and the path of a scene beside it.
    fn beside_stub(tag: &str) -> (PathBuf, PathBuf) {
        let dir = std::env::temp_dir().join(format!("ves-scene-{tag}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        std::fs::write(dir.join("x.step"), "ISO-10303-21;").expect("geometry stub");
        let path = dir.join("s.toml");
        (dir, path)
    }

    /// Every fixed-size array has exactly its length: a fourth element (or a fifth of another
    /// type) ran silently, the toml crate reading the first three; a refusal names the key.
    #[test]
    fn three_vectors_have_exactly_three_numbers() {
        let (dir, path) = beside_stub("shapes");
        for (from, to, key) in [
            (
                "force = [0.0, 0.0, -100.0]",
                "force = [0, 0, -1, \"junk\", true]",
                "force",
            ),
            ("force = [0.0, 0.0, -100.0]", "force = [0.0, -100.0]", "force"),
            ("at = [0.1, 0.0, 0.05]", "at = [0.1, 0.0, 0.05, 7.0]", "at"),
            ("force = [0.0, 1.0, 0.0]", "force = [0.0, 1.0, 0.0, 0.0]", "force"),
            ("max = [0.1, 0.1, 0.1] }", "max = [0.1, 0.1, 0.1, 0.1] }", "max"),
            (
                "{ min = [0.0, 0.0, 0.0], max = [1.0",
                "{ min = [0.0, 0.0, 0.0, 0.0], max = [1.0",
                "min",
            ),
            ("min = [0.9, 0.0, 0.0]", "min = [0.9, 0.0, 0.0, 0.0]", "min"),
            (
                "acceleration = [0.0, 0.0, -9.81]",
                "acceleration = [0.0, 0.0, -9.81, 1.0]",
                "acceleration",
            ),
            ("acceleration = [0.0, 0.0, -9.81]", "acceleration = []", "acceleration"),
            ("force = [0.0, 0.0, -100.0]", "force = [0, \"a\", 1]", "force[1]"),
        ] {
            let text = SCENE.replacen(from, to, 1);
            assert_ne!(text, SCENE, "{from}");
            let e = Scene::parse(&path, &text).expect_err(to).to_string();
            assert!(
                e.contains(&format!("{key}: "))
                    && e.contains("exactly 3 numbers")
                    && !e.contains('\n')
                    && !e.contains(" ;"),
                "{to}: {e}"
            );
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// Values no solve can use are refused when the scene is read, naming the key: a force of
    /// 1e308 N passed the parser and failed after the whole solve (its stress squared is
    /// infinite), and a box corner of 1e307 m becomes infinite in millimetres for gmsh.
    #[test]
    fn values_beyond_what_a_solve_can_hold_are_refused_at_parse() {
        let (dir, path) = beside_stub("ranges");
        for (from, to, key) in [
            ("force = [0.0, 0.0, -100.0]", "force = [0, 0, -1e308]", "load[0].force"),
            ("force = [0.0, 0.0, -100.0]", "force = [0, 0, -1e13]", "load[0].force"),
            ("force = [0.0, 1.0, 0.0]", "force = [0.0, 1e300, 0.0]", "probe[0]"),
            ("at = [0.1, 0.0, 0.05]", "at = [0.1, 1e307, 0.05]", "probe[0]"),
            (
                "acceleration = [0.0, 0.0, -9.81]",
                "acceleration = [0.0, 0.0, -1e300]",
                "gravity.acceleration",
            ),
            ("max = [0.1, 0.1, 0.1] }", "max = [0.1, 0.1, 1e307] }", "voi[0].box"),
            ("max = [1.0, 1.0, 1.0] }", "max = [1.0, 1.0, 1e307] }", "fixed[1].box"),
            ("min = [0.9, 0.0, 0.0]", "min = [-1e307, 0.0, 0.0]", "load[0].box"),
            (
                "value = 0.0, tol = 1e-6",
                "value = 1e307, tol = 1e-6",
                "fixed[0].plane.value",
            ),
            (
                "value = 0.0, tol = 1e-6",
                "value = 0.0, tol = 1e307",
                "fixed[0].plane.tol",
            ),
            ("size = 0.001", "size = 1e307", "voi[0].size"),
            ("size = 0.01", "size = 1e307", "mesh.size"),
            ("size = 0.01", "size = 1e-300", "mesh.size"),
            ("alpha = 0.1", "alpha = 1e300", "damping.alpha"),
            ("beta = 1e-5", "beta = 1e300", "damping.beta"),
        ] {
            let text = SCENE.replacen(from, to, 1);
            assert_ne!(text, SCENE, "{from}");
            let e = Scene::parse(&path, &text).expect_err(to).to_string();
            assert!(e.contains(key) && !e.contains('\n'), "{to}: {e}");
        }
        let with_load = |load: &str| {
            let text = SCENE.replace("[gravity]", &format!("[[load]]\n{load}\n[gravity]"));
            Scene::parse(&path, &text)
        };
        let e = with_load("name = \"p\"\nfaces = [1]\npressure = 1e300").expect_err("1e300 Pa");
        assert!(e.to_string().contains("load[1].pressure"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// The basis stores the scene's text in an attribute of at most 64 KiB: a longer scene was
    /// refused only when the basis was written, after the whole solve.
    #[test]
    fn a_scene_longer_than_the_basis_can_store_is_refused_at_parse() {
        let (dir, path) = beside_stub("long");
        let text = format!("{SCENE}\n# {}\n", "x".repeat(70_000));
        let e = Scene::parse(&path, &text).expect_err("70 kB").to_string();
        assert!(e.contains("64 KiB") && !e.contains('\n'), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// An error quotes a bounded part of what it names: a list of thousands of face tags (or a
    /// TOML error on a line that long, or a string of that length) gave one line of hundreds of
    /// kilobytes.
    #[test]
    fn errors_on_long_lists_stay_one_short_line() {
        let (dir, path) = beside_stub("longlist");
        let tags: Vec<String> = (0..8000).map(|t| t.to_string()).collect();
        let list = tags.join(", ");
        for (fixed, says) in [
            (format!("faces = [{list}]"), "fixed[2].faces: 8000 entries"),
            (format!("faces = [{list}, \"x\"]"), "line "),
            (
                format!("faces = [1]\ncomponents = [\"{}\"]", "q".repeat(40_000)),
                "fixed[2].components = \"qqq",
            ),
            (
                format!("plane = {{ axis = \"{}\", value = 0.0 }}", "w".repeat(40_000)),
                "fixed[2].plane.axis",
            ),
        ] {
            let text = SCENE.replace("[modes]", &format!("[[fixed]]\n{fixed}\n[modes]"));
            let e = Scene::parse(&path, &text).expect_err("long list").to_string();
            assert!(
                e.contains(says) && !e.contains('\n') && e.len() < 400,
                "{} bytes: {e:.600}",
                e.len()
            );
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// Deterministic mutations of a valid scene (byte flips, deletions, duplications, numeric
    /// swaps): parsing never panics, and every error is one line that names the file.
    #[test]
    fn mutated_scenes_never_panic_and_errors_stay_one_line() {
        let dir = std::env::temp_dir().join(format!("ves-scene-mutations-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        std::fs::write(dir.join("x.step"), "ISO-10303-21;").expect("geometry stub");
        let path = dir.join("s.toml");
        assert!(Scene::parse(&path, SCENE).is_ok(), "the base scene must be valid");
        let replacements = [
            "nan", "-inf", "0", "-1", "1e400", "\"x\"", "[]", "{}", "true", "0.5", "3", "\"\"",
        ];
        let mut seed = 0x2545_F491_4F6C_DD1Du64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        let (mut ok, mut err) = (0, 0);
        for _ in 0..3000 {
            let mut text: Vec<u8> = SCENE.as_bytes().to_vec();
            for _ in 0..1 + next() % 3 {
                let at = (next() as usize) % text.len();
                match next() % 5 {
                    0 => text[at] = (next() % 128) as u8,
                    1 => {
                        let end = (at + 1 + (next() as usize) % 12).min(text.len());
                        text.drain(at..end);
                    }
                    2 => {
                        let end = (at + 1 + (next() as usize) % 40).min(text.len());
                        let piece = text[at..end].to_vec();
                        text.splice(at..at, piece);
                    }
                    _ => {
                        // Replace the number or word starting here.
                        let end = text[at..]
                            .iter()
                            .position(|c| matches!(c, b'\n' | b',' | b' ' | b']' | b'}'))
                            .map_or(text.len(), |p| at + p);
                        let r = replacements[(next() as usize) % replacements.len()];
                        text.splice(at..end, r.bytes());
                    }
                }
                if text.is_empty() {
                    break;
                }
            }
            let s = String::from_utf8_lossy(&text);
            match Scene::parse(&path, &s) {
                Ok(scene) => {
                    ok += 1;
                    // Whatever parsed is valid.
                    assert!(scene.material.young > 0.0 && scene.material.young.is_finite());
                    assert!(scene.material.poisson > -1.0 && scene.material.poisson < 0.5);
                    assert!(scene.mesh.size > 0.0 && scene.mesh.size.is_finite());
                    assert!(matches!(scene.mesh.order, 1 | 2));
                }
                Err(e) => {
                    err += 1;
                    let msg = e.to_string();
                    assert!(!msg.contains('\n'), "multi-line error: {msg}");
                    assert!(msg.contains("s.toml"), "error does not name the file: {msg}");
                }
            }
        }
        let _ = std::fs::remove_dir_all(&dir);
        assert!(
            ok > 20 && err > 1000,
            "mutations should hit both outcomes: {ok} ok, {err} errors"
        );
    }
}
