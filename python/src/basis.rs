//! `ves.Basis`: a modal-basis file read through the guarded reader (`ves_format`), every array
//! handed to numpy without a copy (the vectors read become the arrays' memory) and read-only.

use crate::errors;
use numpy::IntoPyArray;
use numpy::ndarray::{Array1, Array2, Array3};
use numpy::{PyArray1, PyArray2, PyArray3};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use ves_format::{BasisReader, ReadError};
use ves_runtime::basis::{LoadError, LoadOptions};

/// Static compliance as numpy arrays: node indices (p,), blocks (p, 3, 3).
type ComplianceArrays = (Py<PyArray1<u32>>, Py<PyArray3<f64>>);

/// One space as read from the file, before it becomes numpy arrays.
struct SpaceData {
    name: String,
    element_order: u8,
    rigid_modes_dropped: u32,
    voi: Option<[[f64; 3]; 2]>,
    vertex_count: usize,
    meshing_strategy: Option<String>,
    nodes: Vec<f64>,
    tets: Vec<u32>,
    nodes_per_tet: usize,
    triangles: Vec<u32>,
    faces: Option<Vec<u32>>,
    fixed_dofs: Vec<u32>,
    eigenvalues: Vec<f64>,
    frequencies_hz: Vec<f64>,
    residuals: Vec<f64>,
    modes: Vec<f64>,
    mode_count: usize,
    stress: Option<Vec<f64>>,
    estimated_error: Option<Vec<f64>>,
    compliance: Option<ves_format::Compliance>,
    rigid: Option<ves_format::RigidProperties>,
    loads: Vec<ves_format::read::LoadCase>,
    runtime: Arc<ves_runtime::Basis>,
}

/// The whole file as read.
struct FileData {
    generator: String,
    scene_toml: String,
    default_space: String,
    material: ves_format::Material,
    bytes: u64,
    spaces: Vec<SpaceData>,
    /// `transfers[to][from]`: the VOI state transfer, row-major r_to × r_from (None on the
    /// diagonal, or where the file has none).
    transfers: Transfers,
}

/// `transfers[to][from]`, as the runtime's `SpaceInput` holds them.
pub(crate) type Transfers = Vec<Vec<Option<Vec<f64>>>>;

fn load_error(e: LoadError) -> ReadError {
    ReadError {
        path: e.path,
        message: e.message,
    }
}

/// Reads and checks every dataset of every space (what `ves info` checks), and the runtime's
/// view of each space (surface vertices, every mode) from the same open file.
fn read_file(path: &Path) -> Result<FileData, ReadError> {
    let file = BasisReader::open(path)?;
    let material = file.material()?;
    let mut spaces = Vec::new();
    for name in file.space_names()? {
        let s = file.space(&name)?;
        let n = s.node_count;
        let r = s.mode_count;
        let nodes: Vec<f64> = s.nodes(n)?.into_iter().flatten().collect();
        let tets = s.tets()?;
        let triangles: Vec<u32> = s.surface_triangles()?.into_iter().flatten().collect();
        let faces = s.surface_faces()?;
        let fixed_dofs = s.fixed_dofs()?;
        let eigenvalues = s.eigenvalues()?;
        s.check_damping(material.alpha, material.beta, &eigenvalues)?;
        let frequencies_hz = s.frequencies_hz()?;
        let residuals = s.relative_residuals()?;
        let modes = if r > 0 { s.basis_rows(0..3 * n, r)? } else { Vec::new() };
        let stress = s.stress_rows(0..s.vertex_count, r)?;
        let estimated_error = s.estimated_relative_error()?;
        let compliance = s.compliance()?;
        let rigid = s.rigid()?;
        let loads = s.loads()?;
        let runtime = ves_runtime::basis::load_space(
            &file,
            &LoadOptions {
                space: Some(name.clone()),
                modes: None,
                surface_only: true,
            },
        )
        .map_err(load_error)?;
        spaces.push(SpaceData {
            name,
            element_order: s.kind.order(),
            rigid_modes_dropped: s.rigid_modes_dropped,
            voi: s.voi,
            vertex_count: s.vertex_count,
            meshing_strategy: s.meshing_strategy.clone(),
            nodes,
            tets,
            nodes_per_tet: s.kind.nodes(),
            triangles,
            faces,
            fixed_dofs,
            eigenvalues,
            frequencies_hz,
            residuals,
            modes,
            mode_count: r,
            stress,
            estimated_error,
            compliance,
            rigid,
            loads,
            runtime: Arc::new(runtime),
        });
    }
    let mut transfers = Vec::with_capacity(spaces.len());
    for to in &spaces {
        let reader = file.space(&to.name)?;
        let mut row = Vec::with_capacity(spaces.len());
        for from in &spaces {
            row.push(if from.name == to.name {
                None
            } else {
                reader.transfer(&from.name, to.mode_count, from.mode_count)?
            });
        }
        transfers.push(row);
    }
    Ok(FileData {
        generator: file.string(ves_format::names::root::GENERATOR).unwrap_or_default(),
        scene_toml: file.string(ves_format::names::root::SCENE_TOML).unwrap_or_default(),
        default_space: file.default_space()?,
        material,
        bytes: file.file_bytes(),
        spaces,
        transfers,
    })
}

/// The path of a file named by a str or os.PathLike, or of an open `Basis`; TypeError `what`
/// otherwise.
pub(crate) fn path_of(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<PathBuf> {
    match obj.cast::<Basis>() {
        Ok(b) => Ok(b.get().path.clone()),
        Err(_) => obj
            .extract()
            .map_err(|_| pyo3::exceptions::PyTypeError::new_err(what.to_string())),
    }
}

/// Marks an array read-only: the arrays are shared by every access to the property.
fn frozen<T>(a: Bound<'_, T>) -> PyResult<Py<T>> {
    a.as_any().getattr("flags")?.setattr("writeable", false)?;
    Ok(a.unbind())
}

fn matrix<'py, T: numpy::Element>(py: Python<'py>, v: Vec<T>, rows: usize, cols: usize) -> PyResult<Py<PyArray2<T>>> {
    let a = Array2::from_shape_vec((rows, cols), v)
        .map_err(|e| errors::BasisError::new_err(format!("inconsistent array shape: {e}")))?;
    frozen(a.into_pyarray(py))
}

fn vector<T: numpy::Element>(py: Python<'_>, v: Vec<T>) -> PyResult<Py<PyArray1<T>>> {
    frozen(Array1::from(v).into_pyarray(py))
}

/// One space of a basis: the global mesh, or the finer mesh of one volume of interest.
#[pyclass(frozen, module = "ves")]
pub struct Space {
    /// Space name ("global", or the VOI's name).
    #[pyo3(get)]
    name: String,
    /// 1 (4-node tets) or 2 (10-node tets).
    #[pyo3(get)]
    element_order: u8,
    /// Rigid modes found and dropped (6 for a free body, 0 for a supported part).
    #[pyo3(get)]
    rigid_modes_dropped: u32,
    /// The VOI box ((xmin, ymin, zmin), (xmax, ymax, zmax)), m; None for "global".
    #[pyo3(get)]
    voi: Option<[[f64; 3]; 2]>,
    /// The first `vertex_count` nodes are corner vertices (all that is drawn or picked).
    #[pyo3(get)]
    vertex_count: usize,
    /// The meshing strategy that worked, when the file records it.
    #[pyo3(get)]
    meshing_strategy: Option<String>,
    nodes: Py<PyArray2<f64>>,
    tets: Py<PyArray2<u32>>,
    surface_triangles: Py<PyArray2<u32>>,
    surface_faces: Option<Py<PyArray1<u32>>>,
    fixed_dofs: Py<PyArray1<u32>>,
    eigenvalues: Py<PyArray1<f64>>,
    frequencies_hz: Py<PyArray1<f64>>,
    relative_residuals: Py<PyArray1<f64>>,
    modes: Py<PyArray2<f64>>,
    stress: Option<Py<PyArray2<f64>>>,
    estimated_relative_error: Option<Py<PyArray1<f64>>>,
    compliance: Option<ComplianceArrays>,
    rigid: Option<ves_format::RigidProperties>,
    loads: Vec<ves_format::read::LoadCase>,
    pub(crate) runtime: Arc<ves_runtime::Basis>,
}

impl Space {
    fn new(py: Python<'_>, d: SpaceData) -> PyResult<Space> {
        let n = d.nodes.len() / 3;
        let r = d.mode_count;
        let k = d.triangles.len() / 3;
        let compliance = match d.compliance {
            Some((nodes, blocks)) => {
                let p = nodes.len();
                let flat: Vec<f64> = blocks.into_iter().flatten().flatten().collect();
                let a = Array3::from_shape_vec((p, 3, 3), flat)
                    .map_err(|e| errors::BasisError::new_err(format!("compliance blocks: {e}")))?;
                Some((vector(py, nodes)?, frozen(a.into_pyarray(py))?))
            }
            None => None,
        };
        Ok(Space {
            name: d.name,
            element_order: d.element_order,
            rigid_modes_dropped: d.rigid_modes_dropped,
            voi: d.voi,
            vertex_count: d.vertex_count,
            meshing_strategy: d.meshing_strategy,
            nodes: matrix(py, d.nodes, n, 3)?,
            tets: matrix(
                py,
                d.tets.clone(),
                d.tets.len() / d.nodes_per_tet.max(1),
                d.nodes_per_tet,
            )?,
            surface_triangles: matrix(py, d.triangles, k, 3)?,
            surface_faces: d.faces.map(|f| vector(py, f)).transpose()?,
            fixed_dofs: vector(py, d.fixed_dofs)?,
            eigenvalues: vector(py, d.eigenvalues)?,
            frequencies_hz: vector(py, d.frequencies_hz)?,
            relative_residuals: vector(py, d.residuals)?,
            modes: matrix(py, d.modes, 3 * n, r)?,
            stress: d.stress.map(|s| matrix(py, s, 6 * d.vertex_count, r)).transpose()?,
            estimated_relative_error: d.estimated_error.map(|e| vector(py, e)).transpose()?,
            compliance,
            rigid: d.rigid,
            loads: d.loads,
            runtime: d.runtime,
        })
    }
}

#[pymethods]
impl Space {
    /// Node coordinates, m, shape (n, 3): corner vertices first, then mid-edge nodes.
    #[getter]
    fn nodes(&self, py: Python<'_>) -> Py<PyArray2<f64>> {
        self.nodes.clone_ref(py)
    }

    /// Tetrahedra, shape (m, 4) or (m, 10), gmsh node order.
    #[getter]
    fn tets(&self, py: Python<'_>) -> Py<PyArray2<u32>> {
        self.tets.clone_ref(py)
    }

    /// Boundary triangles on corner vertices, outward, shape (k, 3).
    #[getter]
    fn surface_triangles(&self, py: Python<'_>) -> Py<PyArray2<u32>> {
        self.surface_triangles.clone_ref(py)
    }

    /// CAD face tag of each surface triangle, shape (k,); None when the file has none.
    #[getter]
    fn surface_faces(&self, py: Python<'_>) -> Option<Py<PyArray1<u32>>> {
        self.surface_faces.as_ref().map(|a| a.clone_ref(py))
    }

    /// Supported DOFs, index 3i + c, shape (c,).
    #[getter]
    fn fixed_dofs(&self, py: Python<'_>) -> Py<PyArray1<u32>> {
        self.fixed_dofs.clone_ref(py)
    }

    /// Elastic eigenvalues λ = ω², rad²/s², ascending, shape (r,).
    #[getter]
    fn eigenvalues(&self, py: Python<'_>) -> Py<PyArray1<f64>> {
        self.eigenvalues.clone_ref(py)
    }

    /// Frequencies, Hz, shape (r,).
    #[getter]
    fn frequencies_hz(&self, py: Python<'_>) -> Py<PyArray1<f64>> {
        self.frequencies_hz.clone_ref(py)
    }

    /// ‖Kφ − λMφ‖ / ‖Kφ‖ of each mode, shape (r,).
    #[getter]
    fn relative_residuals(&self, py: Python<'_>) -> Py<PyArray1<f64>> {
        self.relative_residuals.clone_ref(py)
    }

    /// M-normalised mode shapes, shape (3n, r): row 3i + c is component c of node i.
    #[getter]
    fn modes(&self, py: Python<'_>) -> Py<PyArray2<f64>> {
        self.modes.clone_ref(py)
    }

    /// Modal stress at corner vertices, Pa per unit modal coordinate, shape (6·nv, r): row
    /// 6i + k is Voigt component k (xx, yy, zz, yz, xz, xy) at vertex i; None without
    /// `[stress] enabled`.
    #[getter]
    fn stress(&self, py: Python<'_>) -> Option<Py<PyArray2<f64>>> {
        self.stress.as_ref().map(|a| a.clone_ref(py))
    }

    /// The names of the space's static load cases (`[[load]]`, `[gravity]`), in the file's
    /// order; empty when the scene had none.
    #[getter]
    fn load_cases(&self) -> Vec<String> {
        self.loads.iter().map(|l| l.name.clone()).collect()
    }

    /// One static load case as a dict: `kind` ("force", "pressure", "gravity"), `displacement`
    /// (n, 3) m, `von_mises` (n,) Pa at every node, `stress` (nv, 6) Pa at the corner vertices
    /// (Voigt xx yy zz yz xz xy), `total_force` and `reaction` (3,) N, `balance_residual`,
    /// `max_displacement` m, `max_von_mises` Pa. KeyError naming the cases there are.
    fn load<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyDict>> {
        let Some(l) = self.loads.iter().find(|l| l.name == name) else {
            return Err(pyo3::exceptions::PyKeyError::new_err(format!(
                "no load case {name:?} in space {:?}; it has {:?}",
                self.name,
                self.load_cases()
            )));
        };
        let n = l.von_mises.len();
        let d = PyDict::new(py);
        d.set_item("name", &l.name)?;
        d.set_item("kind", &l.kind)?;
        d.set_item("displacement", matrix(py, l.displacement.clone(), n, 3)?)?;
        d.set_item("von_mises", vector(py, l.von_mises.clone())?)?;
        d.set_item("stress", matrix(py, l.stress.clone(), l.stress.len() / 6, 6)?)?;
        d.set_item("total_force", l.total_force.to_vec())?;
        d.set_item("reaction", l.reaction.to_vec())?;
        d.set_item("balance_residual", l.balance_residual)?;
        d.set_item("max_displacement", l.max_displacement)?;
        d.set_item("max_von_mises", l.max_von_mises)?;
        d.set_item("peak", peak(py, l.peak.as_ref())?)?;
        d.set_item("regular_peak", peak(py, l.regular_peak.as_ref())?)?;
        Ok(d)
    }

    /// Each mode's estimated relative discretization error, shape (r,); None when not stored.
    #[getter]
    fn estimated_relative_error(&self, py: Python<'_>) -> Option<Py<PyArray1<f64>>> {
        self.estimated_relative_error.as_ref().map(|a| a.clone_ref(py))
    }

    /// Exact static compliance: (node indices (p,), blocks (p, 3, 3) m/N); None when not stored.
    #[getter]
    fn compliance(&self, py: Python<'_>) -> Option<ComplianceArrays> {
        self.compliance
            .as_ref()
            .map(|(n, b)| (n.clone_ref(py), b.clone_ref(py)))
    }

    /// The mass properties of a part that can move as a whole: dict with mass (kg),
    /// center_of_mass (m), inertia (kg·m², about the centre of mass) and free_motions (k, 6):
    /// the rigid motions its supports leave free as twists (v, ω) about the centre of mass
    /// (the identity's six rows for a free body); None for a part held in every direction.
    #[getter]
    fn rigid<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(r) = self.rigid else { return Ok(None) };
        let d = PyDict::new(py);
        d.set_item("mass", r.mass)?;
        d.set_item("center_of_mass", r.center)?;
        d.set_item("inertia", r.inertia)?;
        d.set_item("free_motions", r.free.twists().to_vec())?;
        Ok(Some(d))
    }

    /// Number of modes r.
    #[getter]
    fn mode_count(&self) -> usize {
        self.runtime.mode_count()
    }

    /// The space as a `meshio.Mesh` (needs meshio): tets in VTK node order, each mode shape as
    /// point data `mode_1`, `mode_2`, … (the first `modes`, default all).
    #[pyo3(signature = (modes=None))]
    fn to_meshio<'py>(slf: &Bound<'py, Self>, modes: Option<usize>) -> PyResult<Bound<'py, PyAny>> {
        let py = slf.py();
        py.import("ves._meshio")?.call_method1("to_meshio", (slf, modes))
    }

    fn __repr__(&self, py: Python<'_>) -> String {
        format!(
            "<ves.Space {:?}: {} nodes, {} vertices, {} modes>",
            self.name,
            self.nodes.bind(py).len().unwrap_or(0),
            self.vertex_count,
            self.runtime.mode_count()
        )
    }
}

/// A modal-basis file (HDF5, format version 1), read whole and checked when opened: the file
/// may change or disappear afterwards without affecting this object.
#[pyclass(frozen, module = "ves")]
pub struct Basis {
    /// The file it was read from.
    #[pyo3(get)]
    path: PathBuf,
    /// What wrote it (the `generator` attribute).
    #[pyo3(get)]
    generator: String,
    /// The scene file's text stored in the basis.
    #[pyo3(get)]
    scene_toml: String,
    /// Name of the space used when none is named ("global").
    #[pyo3(get)]
    default_space: String,
    /// Size of the file, bytes.
    #[pyo3(get)]
    file_bytes: u64,
    material: ves_format::Material,
    spaces: Vec<Py<Space>>,
    transfers: Transfers,
    /// What `ves.precompute` reported (its `--json` summary), None for an opened file.
    #[pyo3(get)]
    summary: Option<Py<PyAny>>,
}

impl Basis {
    /// Reads `path` with the GIL released.
    pub(crate) fn read(py: Python<'_>, path: PathBuf, summary: Option<Py<PyAny>>) -> PyResult<Basis> {
        let p = path.clone();
        let data = py
            // The reader refuses a file written over while it reads it (see BasisReader).
            .detach(move || ves_format::guarded(&p, || read_file(&p)))
            .map_err(errors::basis)?;
        let default_space = data.default_space.clone();
        let spaces = data
            .spaces
            .into_iter()
            .map(|s| Py::new(py, Space::new(py, s)?))
            .collect::<PyResult<Vec<_>>>()?;
        Ok(Basis {
            path,
            generator: data.generator,
            scene_toml: data.scene_toml,
            default_space,
            file_bytes: data.bytes,
            material: data.material,
            spaces,
            transfers: data.transfers,
            summary,
        })
    }

    /// The file it was read from.
    pub(crate) fn path_ref(&self) -> &Path {
        &self.path
    }

    /// Every space's runtime basis with its transfers from the others, global first.
    pub(crate) fn all_spaces(&self) -> Vec<ves_runtime::switching::SpaceInput> {
        self.spaces
            .iter()
            .zip(&self.transfers)
            .map(|(s, t)| ves_runtime::switching::SpaceInput {
                basis: s.get().runtime.clone(),
                transfers: t.clone(),
            })
            .collect()
    }

    /// The space named `name`, or the default one.
    pub(crate) fn space_ref(&self, py: Python<'_>, name: Option<&str>) -> PyResult<&Py<Space>> {
        let want = name.unwrap_or(&self.default_space);
        self.spaces.iter().find(|s| s.get().name == want).ok_or_else(|| {
            let names: Vec<&str> = self.spaces.iter().map(|s| s.get().name.as_str()).collect();
            let _ = py;
            pyo3::exceptions::PyKeyError::new_err(format!(
                "{}: no space {want:?}; the file has {names:?}",
                self.path.display()
            ))
        })
    }

    fn default(&self, py: Python<'_>) -> PyResult<&Space> {
        Ok(self.space_ref(py, None)?.get())
    }
}

#[pymethods]
impl Basis {
    /// Opens a basis file written by `ves precompute` (or `ves.precompute`), checking every
    /// value in it; raises `ves.BasisError` naming the file when it is missing, foreign,
    /// truncated or damaged.
    #[staticmethod]
    fn open(py: Python<'_>, path: PathBuf) -> PyResult<Basis> {
        Basis::read(py, path, None)
    }

    /// Names of the spaces, "global" first.
    #[getter]
    fn spaces(&self) -> Vec<String> {
        self.spaces.iter().map(|s| s.get().name.clone()).collect()
    }

    /// The space named `name` (a VOI's name or "global"); KeyError when there is none.
    fn space(&self, py: Python<'_>, name: &str) -> PyResult<Py<Space>> {
        Ok(self.space_ref(py, Some(name))?.clone_ref(py))
    }

    /// Material and damping: dict with young (Pa), poisson, density (kg/m³), rayleigh_alpha
    /// (1/s), rayleigh_beta (s) and yield_strength (Pa or None).
    #[getter]
    fn material<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let m = self.material;
        let d = PyDict::new(py);
        d.set_item("young", m.young)?;
        d.set_item("poisson", m.poisson)?;
        d.set_item("density", m.density)?;
        d.set_item("rayleigh_alpha", m.alpha)?;
        d.set_item("rayleigh_beta", m.beta)?;
        d.set_item("yield_strength", m.yield_strength)?;
        Ok(d)
    }

    /// Frequencies of the default space, Hz, shape (r,).
    #[getter]
    fn frequencies_hz(&self, py: Python<'_>) -> PyResult<Py<PyArray1<f64>>> {
        Ok(self.default(py)?.frequencies_hz(py))
    }

    /// Eigenvalues λ = ω² of the default space, shape (r,).
    #[getter]
    fn eigenvalues(&self, py: Python<'_>) -> PyResult<Py<PyArray1<f64>>> {
        Ok(self.default(py)?.eigenvalues(py))
    }

    /// Mode shapes of the default space, shape (3n, r), M-normalised.
    #[getter]
    fn modes(&self, py: Python<'_>) -> PyResult<Py<PyArray2<f64>>> {
        Ok(self.default(py)?.modes(py))
    }

    /// Node coordinates of the default space, m, shape (n, 3).
    #[getter]
    fn nodes(&self, py: Python<'_>) -> PyResult<Py<PyArray2<f64>>> {
        Ok(self.default(py)?.nodes(py))
    }

    /// Corner vertices of the default space (the first rows of `nodes`).
    #[getter]
    fn vertex_count(&self, py: Python<'_>) -> PyResult<usize> {
        Ok(self.default(py)?.vertex_count)
    }

    /// Tetrahedra of the default space, shape (m, 4|10).
    #[getter]
    fn tets(&self, py: Python<'_>) -> PyResult<Py<PyArray2<u32>>> {
        Ok(self.default(py)?.tets(py))
    }

    /// Surface triangles of the default space, shape (k, 3).
    #[getter]
    fn surface_triangles(&self, py: Python<'_>) -> PyResult<Py<PyArray2<u32>>> {
        Ok(self.default(py)?.surface_triangles(py))
    }

    /// CAD face tag per surface triangle of the default space, or None.
    #[getter]
    fn surface_faces(&self, py: Python<'_>) -> PyResult<Option<Py<PyArray1<u32>>>> {
        Ok(self.default(py)?.surface_faces(py))
    }

    /// Supported DOFs of the default space (3i + c).
    #[getter]
    fn fixed_dofs(&self, py: Python<'_>) -> PyResult<Py<PyArray1<u32>>> {
        Ok(self.default(py)?.fixed_dofs(py))
    }

    /// The default space's static load cases, by name.
    #[getter]
    fn load_cases(&self, py: Python<'_>) -> PyResult<Vec<String>> {
        Ok(self.default(py)?.load_cases())
    }

    /// One static load case of the default space (see `Space.load`).
    fn load<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyDict>> {
        self.default(py)?.load(py, name)
    }

    /// Modal stress of the default space, shape (6·nv, r), or None.
    #[getter]
    fn stress(&self, py: Python<'_>) -> PyResult<Option<Py<PyArray2<f64>>>> {
        Ok(self.default(py)?.stress(py))
    }

    /// Estimated relative discretization error per mode of the default space, or None.
    #[getter]
    fn estimated_relative_error(&self, py: Python<'_>) -> PyResult<Option<Py<PyArray1<f64>>>> {
        Ok(self.default(py)?.estimated_relative_error(py))
    }

    /// Relative residual per mode of the default space.
    #[getter]
    fn relative_residuals(&self, py: Python<'_>) -> PyResult<Py<PyArray1<f64>>> {
        Ok(self.default(py)?.relative_residuals(py))
    }

    /// Static compliance of the default space (nodes, blocks), or None.
    #[getter]
    fn compliance(&self, py: Python<'_>) -> PyResult<Option<ComplianceArrays>> {
        Ok(self.default(py)?.compliance(py))
    }

    /// Free-body mass properties of the default space, or None.
    #[getter]
    fn rigid<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        self.default(py)?.rigid(py)
    }

    /// The default space (or `space`) as a `meshio.Mesh`: see `Space.to_meshio`.
    #[pyo3(signature = (modes=None, space=None))]
    fn to_meshio<'py>(
        &self,
        py: Python<'py>,
        modes: Option<usize>,
        space: Option<&str>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let s = self.space_ref(py, space)?.bind(py);
        py.import("ves._meshio")?.call_method1("to_meshio", (s, modes))
    }

    fn __repr__(&self) -> String {
        format!("<ves.Basis {} ({} spaces)>", self.path.display(), self.spaces.len())
    }
}

/// A studied von Mises peak as a dict (verdict, value and error in Pa — error None when none is
/// stated — refined values, position in m), or None.
fn peak<'py>(py: Python<'py>, p: Option<&ves_format::PeakRecord>) -> PyResult<Option<Bound<'py, PyDict>>> {
    let Some(p) = p else {
        return Ok(None);
    };
    let d = PyDict::new(py);
    d.set_item("verdict", &p.verdict)?;
    d.set_item("value", p.value)?;
    d.set_item("error", p.error)?;
    d.set_item("refined", p.refined.to_vec())?;
    d.set_item("position", p.position.to_vec())?;
    Ok(Some(d))
}
