//! `ves.Haptics`: the runtime's haptic simulation (the code the C ABI's `ves_haptics_*` wraps)
//! driven from Python, numpy arrays in and out.

use crate::basis::Basis;
use numpy::ndarray::Array2;
use numpy::{AllowTypeChange, IntoPyArray, PyArray1, PyArray2, PyArrayLike2, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::sync::Arc;
use ves_runtime::haptic::{Coupling, HandInput, HandOutput, StrainPolicy, ValidityWatch};
use ves_runtime::integrator::Scheme;
use ves_runtime::switching::{SpaceInput, SwitchConfig, Switcher};

/// Largest |coordinate| of a device position accepted, m (as the C ABI).
const MAX_POSITION_M: f64 = 1e6;
/// Most hands one simulation serves (as the C ABI).
const MAX_HANDS: usize = 16;

/// A haptic simulation of a basis: hands (haptic interaction points) pull or press the part
/// through a virtual spring-damper; each `step` advances the modes by `dt` exactly and returns
/// the force on each device. A basis with volumes of interest is simulated in every space, the
/// active one the VOI that holds the hands (as `ves session` does).
#[pyclass(module = "ves")]
pub struct Haptics {
    sw: Sim,
    /// The spaces simulated, global first.
    #[pyo3(get)]
    spaces: Vec<String>,
    inputs: Vec<HandInput>,
    outputs: Vec<HandOutput>,
    /// Simulated time, s.
    #[pyo3(get)]
    time: f64,
    /// Steps taken.
    #[pyo3(get)]
    steps: u64,
}

fn finite(name: &str, v: f64, ok: bool, requirement: &str) -> PyResult<f64> {
    if v.is_finite() && ok {
        Ok(v)
    } else {
        Err(PyValueError::new_err(format!(
            "{name} = {v}: must be finite and {requirement}"
        )))
    }
}

/// Copies a (n, 3) array of finite values within `limit` into `dst`, or raises naming `what`;
/// returns n. A C-contiguous float64 numpy array is read in place; anything else numpy can
/// turn into one (lists, other dtypes) is converted first.
fn read_rows(
    obj: &Bound<'_, PyAny>,
    what: &str,
    limit: f64,
    hands: usize,
    dst: &mut [[f64; 3]; MAX_HANDS],
) -> PyResult<usize> {
    let copy = |a: numpy::ndarray::ArrayView2<'_, f64>, dst: &mut [[f64; 3]; MAX_HANDS]| -> PyResult<usize> {
        let (n, c) = a.dim();
        if c != 3 || n == 0 || n > hands {
            return Err(PyValueError::new_err(format!(
                "{what}: shape ({n}, {c}); give shape (n, 3) with 1 ≤ n ≤ {hands} (the hands this simulation was made for)"
            )));
        }
        for (k, row) in a.outer_iter().enumerate() {
            for (j, &x) in row.iter().enumerate() {
                if !x.is_finite() || x.abs() > limit {
                    return Err(PyValueError::new_err(format!(
                        "{what}[{k}, {j}] = {x}: give finite values within {limit:e}"
                    )));
                }
                dst[k][j] = x;
            }
        }
        Ok(n)
    };
    if let Ok(a) = obj.cast::<PyArray2<f64>>() {
        // SAFETY: the GIL is held and no Rust code holds a mutable view of this array (this
        // crate makes none of caller-owned arrays); the values are copied before any Python
        // code can run. (The checked borrow costs more than the haptic step itself.)
        return copy(unsafe { a.as_array() }, dst);
    }
    let a: PyArrayLike2<'_, f64, AllowTypeChange> = obj.extract().map_err(|_| {
        PyValueError::new_err(format!(
            "{what}: give an array of shape (n, 3) (numpy array or nested lists of numbers)"
        ))
    })?;
    copy(a.as_array(), dst)
}

/// The strain watch's reaction named `name` (argument `arg`).
pub(crate) fn strain_policy(arg: &str, name: &str) -> PyResult<StrainPolicy> {
    match name {
        "flag" => Ok(StrainPolicy::Flag),
        "stiffen" => Ok(StrainPolicy::Stiffen),
        "release" => Ok(StrainPolicy::Release),
        _ => Err(PyValueError::new_err(format!(
            "{arg}={name:?}: give \"flag\", \"stiffen\" or \"release\""
        ))),
    }
}

#[pymethods]
impl Haptics {
    /// A simulation at rest on `basis` (its default space, or `space`), keeping its first
    /// `modes` modes (default all). `stiffness` (N/m) and `damping` (N·s/m; default: critical
    /// against a 1 g handle) make the virtual coupling, `max_force` (N) limits the force sent
    /// back; `dt` (s) is the time step, `hands` the most hands per step. `free_body` makes the
    /// part move rigidly under the hands and gravity (a free part's basis only).
    /// `static_correction` adds the stored exact compliance the truncated modes miss.
    #[new]
    #[pyo3(signature = (basis, stiffness=500.0, damping=None, *, max_force=10.0, dt=1e-3, hands=1, space=None, modes=None, free_body=false, static_correction=true))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        basis: &Basis,
        stiffness: f64,
        damping: Option<f64>,
        max_force: f64,
        dt: f64,
        hands: usize,
        space: Option<&str>,
        modes: Option<usize>,
        free_body: bool,
        static_correction: bool,
    ) -> PyResult<Haptics> {
        let mut coupling = Coupling::critically_damped(stiffness, max_force);
        if let Some(c) = damping {
            coupling.damping = c;
        }
        let invalid = |e: ves_runtime::haptic::InvalidSetting| PyValueError::new_err(e.to_string());
        ves_runtime::haptic::InvalidSetting::check("stiffness", stiffness, "N/m", "> 0", stiffness > 0.0)
            .map_err(invalid)?;
        coupling.validate().map_err(invalid)?;
        finite("dt", dt, dt > 0.0 && dt <= 1.0, "in (0, 1] s")?;
        if !(1..=MAX_HANDS).contains(&hands) {
            return Err(PyValueError::new_err(format!(
                "hands = {hands}: must be 1 to {MAX_HANDS}"
            )));
        }
        let spaces = spaces_for(py, basis, space, modes)?;
        let names = spaces.iter().map(|s| s.basis.space.clone()).collect();
        let mut sw = if spaces.len() == 1 {
            let basis = spaces[0].basis.clone();
            Sim::One(ves_runtime::haptic::Haptics::new(
                basis,
                coupling,
                dt,
                Scheme::Exact,
                hands,
            ))
        } else {
            Sim::Many(
                Switcher::new(spaces, coupling, dt, Scheme::Exact, hands, SwitchConfig::default())
                    .map_err(|e| crate::errors::BasisError::new_err(format!("{}: {e}", basis.path_ref().display())))?,
            )
        };
        for sim in sw.sims_mut() {
            sim.set_static_correction(static_correction);
            if free_body {
                sim.set_free_body([0.0, 0.0, -9.81], 1.0)
                    .map_err(|e| PyValueError::new_err(format!("free_body: {e}")))?;
            }
        }
        Ok(Haptics {
            sw,
            spaces: names,
            inputs: vec![HandInput::default(); hands],
            outputs: vec![HandOutput::default(); hands],
            time: 0.0,
            steps: 0,
        })
    }

    /// One haptic step. `hand_positions` (n, 3), m, one row per hand (n ≤ hands);
    /// `velocities` (n, 3), m/s (default zero); `buttons`: one bool for every hand or one per
    /// hand (held: grab the vertex picked when pressed; released: press on the surface).
    /// Returns the force on each device, N, shape (n, 3): a new array, or `out` (a writable
    /// float64 (n, 3) array) filled in place.
    #[pyo3(signature = (hand_positions, velocities=None, buttons=None, out=None))]
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        hand_positions: &Bound<'py, PyAny>,
        velocities: Option<&Bound<'py, PyAny>>,
        buttons: Option<&Bound<'py, PyAny>>,
        out: Option<Bound<'py, PyArray2<f64>>>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let hands = self.inputs.len();
        let mut x = [[0.0; 3]; MAX_HANDS];
        let n = read_rows(hand_positions, "hand_positions", MAX_POSITION_M, hands, &mut x)?;
        let mut v = [[0.0; 3]; MAX_HANDS];
        if let Some(vel) = velocities {
            let m = read_rows(vel, "velocities", f64::MAX, hands, &mut v)?;
            if m != n {
                return Err(PyValueError::new_err(format!(
                    "velocities: {m} rows for {n} hand positions"
                )));
            }
        }
        let mut pressed = [false; MAX_HANDS];
        if let Some(b) = buttons {
            if let Ok(all) = b.extract::<bool>() {
                pressed[..n].fill(all);
            } else {
                let each: Vec<bool> = b
                    .extract()
                    .map_err(|_| PyValueError::new_err("buttons: give a bool, or a sequence of one bool per hand"))?;
                if each.len() != n {
                    return Err(PyValueError::new_err(format!(
                        "buttons: {} values for {n} hand positions",
                        each.len()
                    )));
                }
                pressed[..n].copy_from_slice(&each);
            }
        }
        let forces = match out {
            Some(o) => {
                // SAFETY: a live array object (the GIL is held).
                let writeable = unsafe { (*o.as_array_ptr()).fields.flags } & numpy::npyffi::NPY_ARRAY_WRITEABLE != 0;
                if o.shape() != [n, 3] || !writeable {
                    return Err(PyValueError::new_err(format!(
                        "out: shape {:?}{}; give a writable float64 array of shape ({n}, 3)",
                        o.shape(),
                        if writeable { "" } else { ", read-only" }
                    )));
                }
                o
            }
            None => PyArray2::<f64>::zeros(py, [n, 3], false),
        };
        for k in 0..n {
            self.inputs[k] = HandInput {
                position: x[k],
                velocity: v[k],
                button: pressed[k],
            };
        }
        self.sw.step(&self.inputs[..n], &mut self.outputs[..n]);
        self.time += self.sim().state().dt();
        self.steps += 1;
        // SAFETY: a writable (n, 3) float64 array (new, or checked above); the GIL is held and
        // no other Rust view of it exists while these n × 3 values are written.
        let mut f = unsafe { forces.as_array_mut() };
        for (k, o) in self.outputs[..n].iter().enumerate() {
            for c in 0..3 {
                f[[k, c]] = o.force[c];
            }
        }
        Ok(forces)
    }

    /// What each hand got in the last step: a list of dicts with force (N), vertex (index
    /// among `vertex_nodes`), vertex_position (m), displacement (the vertex's elastic
    /// displacement, m), grip_gap (m, while grabbing: the hand's distance from the vertex when
    /// the grab began, carried rather than pulled), grabbing, contact, clamped, strain, strain_exceeded,
    /// von_mises (Pa), safety_factor, stress_exceeded, principal_stress (Pa), principal_strain,
    /// felt_error (what the hand feels wrong at its vertex, relative, along the normal: the
    /// modes' share and the mesh's own error; None where the basis does not state it).
    fn hand_outputs<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        self.outputs
            .iter()
            .map(|o| {
                let d = PyDict::new(py);
                d.set_item("force", o.force)?;
                d.set_item("vertex", o.vertex)?;
                d.set_item("vertex_position", o.vertex_position)?;
                d.set_item("displacement", o.displacement)?;
                d.set_item("grip_gap", o.grip_gap)?;
                d.set_item("grabbing", o.grabbing)?;
                d.set_item("contact", o.contact)?;
                d.set_item("clamped", o.clamped)?;
                d.set_item("strain", o.strain)?;
                d.set_item("strain_exceeded", o.strain_exceeded)?;
                d.set_item("von_mises", o.von_mises)?;
                d.set_item("safety_factor", o.safety_factor)?;
                d.set_item("stress_exceeded", o.stress_exceeded)?;
                d.set_item("principal_stress", o.principal_stress)?;
                d.set_item("principal_strain", o.principal_strain)?;
                d.set_item("felt_error", o.felt_error.is_finite().then_some(o.felt_error))?;
                Ok(d)
            })
            .collect()
    }

    /// Modal coordinates q, shape (r,) (a copy).
    #[getter]
    fn q<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.sim().state().q)
    }

    /// Modal velocities, shape (r,) (a copy).
    #[getter]
    fn qdot<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.sim().state().v)
    }

    /// Index in the file's nodes of each vertex the simulation keeps (the surface vertices),
    /// shape (nv,): row i of `displacements()` is node `vertex_nodes[i]`.
    #[getter]
    fn vertex_nodes<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u32>> {
        PyArray1::from_slice(py, &self.basis().node_index)
    }

    /// Rest positions of the kept vertices, m, shape (nv, 3).
    #[getter]
    fn rest_positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let rest = &self.basis().rest;
        let flat: Vec<f64> = rest.iter().flatten().copied().collect();
        let a = Array2::from_shape_vec((rest.len(), 3), flat).map_err(|e| PyValueError::new_err(e.to_string()))?;
        Ok(a.into_pyarray(py))
    }

    /// Displacement u = Φ q of every kept vertex now, m, shape (nv, 3), float32 (the drawing
    /// thread's full-field update).
    fn displacements<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let nv = self.basis().vertex_count();
        let mut u = vec![0.0f32; 3 * nv];
        ves_runtime::visual::displacements(self.basis(), &self.sim().state().q, &mut u);
        let a = Array2::from_shape_vec((nv, 3), u).map_err(|e| PyValueError::new_err(e.to_string()))?;
        Ok(a.into_pyarray(py))
    }

    /// Von Mises stress of every kept vertex now, Pa, shape (nv,), float32; None when the basis
    /// holds no modal stress.
    fn von_mises<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f32>>> {
        let nv = self.basis().vertex_count();
        let mut sigma = vec![0.0f32; 6 * nv];
        if !ves_runtime::visual::stresses(self.basis(), &self.sim().state().q, &mut sigma) {
            return None;
        }
        let vm: Vec<f32> = sigma
            .chunks_exact(6)
            .map(|s| ves_runtime::visual::von_mises(std::array::from_fn(|k| f64::from(s[k]))) as f32)
            .collect();
        Some(PyArray1::from_vec(py, vm))
    }

    /// What each `[[fixed]]` support exerts on the part now, the hands' loads included (a load
    /// held steady is carried whole where one support holds every rigid motion): shape (s, 6), per support force
    /// x y z (N) then moment x y z (N·m) about `support_centres`; None for a free body or a
    /// basis without stored reactions (or while a volume of interest's space is active).
    fn support_reactions<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyArray2<f64>>>> {
        let Some(out) = self.sim().support_reactions() else {
            return Ok(None);
        };
        let r = out.len();
        let flat: Vec<f64> = out.iter().flatten().copied().collect();
        let a = Array2::from_shape_vec((r, 6), flat).map_err(|e| PyValueError::new_err(e.to_string()))?;
        Ok(Some(a.into_pyarray(py)))
    }

    /// The point each support's moment is about, m, shape (s, 3); None as for
    /// `support_reactions()`.
    #[getter]
    fn support_centres<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyArray2<f64>>>> {
        let Some(r) = self.basis().support_reactions.as_ref() else {
            return Ok(None);
        };
        let flat: Vec<f64> = r.centres.iter().flatten().copied().collect();
        let a = Array2::from_shape_vec((r.count(), 3), flat).map_err(|e| PyValueError::new_err(e.to_string()))?;
        Ok(Some(a.into_pyarray(py)))
    }

    /// A free body's pose: centre of mass (m) then the unit quaternion (w, x, y, z) body →
    /// world, shape (7,); None for a supported part.
    #[getter]
    fn pose<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        let sim = self.sim();
        sim.rigid_body().map(|_| PyArray1::from_slice(py, &sim.pose()))
    }

    /// Steps whose result was non-finite and rolled back.
    #[getter]
    fn quarantined(&self) -> u64 {
        (0..self.spaces.len()).map(|i| self.sw.sim(i).quarantined).sum()
    }

    /// Number of modes simulated.
    #[getter]
    fn mode_count(&self) -> usize {
        self.basis().mode_count()
    }

    /// Name of the space simulated now ("global", or the VOI that holds the hands).
    #[getter]
    fn active_space(&self) -> String {
        self.basis().space.clone()
    }

    /// Switches between spaces so far.
    #[getter]
    fn switches(&self) -> u64 {
        self.sw.switches()
    }

    /// The validity watch of the linear model: past `limit` (normal strain along the surface
    /// edges at a hand's vertex) the step reports it and reacts: "flag", "stiffen" or "release".
    #[pyo3(signature = (limit, policy="flag"))]
    fn set_strain_watch(&mut self, limit: f64, policy: &str) -> PyResult<()> {
        finite("limit", limit, limit > 0.0, "> 0")?;
        let policy = strain_policy("policy", policy)?;
        for sim in self.sw.sims_mut() {
            let watch = sim.validity_watch();
            sim.set_validity_watch(ValidityWatch { limit, policy, ..watch });
        }
        Ok(())
    }

    /// Back to rest, every hand let go, time zero.
    fn reset(&mut self) {
        self.sw.reset();
        self.time = 0.0;
        self.steps = 0;
    }

    fn __repr__(&self) -> String {
        format!(
            "<ves.Haptics {:?}: {} modes, {} hands, t = {} s>",
            self.basis().space,
            self.basis().mode_count(),
            self.inputs.len(),
            self.time
        )
    }
}

/// One space's simulation (the C ABI's), or every space's with VOI switching.
// One per Python object, on the heap already: the size difference costs nothing, a box would
// cost the step a pointer chase.
#[allow(clippy::large_enum_variant)]
enum Sim {
    One(ves_runtime::haptic::Haptics),
    Many(Switcher),
}

impl Sim {
    fn step(&mut self, inputs: &[HandInput], outputs: &mut [HandOutput]) {
        match self {
            Sim::One(h) => h.step(inputs, outputs),
            Sim::Many(s) => s.step(inputs, outputs),
        }
    }

    fn active(&self) -> usize {
        match self {
            Sim::One(_) => 0,
            Sim::Many(s) => s.active(),
        }
    }

    fn sim(&self, i: usize) -> &ves_runtime::haptic::Haptics {
        match self {
            Sim::One(h) => h,
            Sim::Many(s) => s.sim(i),
        }
    }

    fn sims_mut(&mut self) -> &mut [ves_runtime::haptic::Haptics] {
        match self {
            Sim::One(h) => std::slice::from_mut(h),
            Sim::Many(s) => s.sims_mut(),
        }
    }

    fn switches(&self) -> u64 {
        match self {
            Sim::One(_) => 0,
            Sim::Many(s) => s.switches,
        }
    }

    fn reset(&mut self) {
        match self {
            Sim::One(h) => h.reset(),
            Sim::Many(s) => s.reset(),
        }
    }
}

impl Haptics {
    /// The active space's simulation.
    fn sim(&self) -> &ves_runtime::haptic::Haptics {
        self.sw.sim(self.sw.active())
    }

    /// The active space's basis.
    fn basis(&self) -> &ves_runtime::Basis {
        self.sim().basis()
    }
}

/// The spaces to simulate: `space` alone, or every space of the basis with its transfers; the
/// first `modes` modes of each (default all).
fn spaces_for(py: Python<'_>, basis: &Basis, space: Option<&str>, modes: Option<usize>) -> PyResult<Vec<SpaceInput>> {
    let all = match space {
        Some(name) => vec![SpaceInput {
            basis: basis.space_ref(py, Some(name))?.get().runtime.clone(),
            transfers: vec![None],
        }],
        None => basis.all_spaces(),
    };
    let counts: Vec<usize> = all.iter().map(|s| s.basis.mode_count()).collect();
    let fewest = counts.iter().copied().min().unwrap_or(0);
    let r = modes.unwrap_or(usize::MAX);
    if r == 0 || (modes.is_some() && r > fewest) {
        return Err(PyValueError::new_err(format!(
            "modes = {r}: the space{} {fewest} modes; give 1 to {fewest}",
            if all.len() > 1 { "s have at least" } else { " has" }
        )));
    }
    Ok(all
        .into_iter()
        .map(|SpaceInput { basis: b, transfers }| {
            let r_to = b.mode_count().min(r);
            let transfers = transfers
                .into_iter()
                .zip(&counts)
                .map(|(t, &r_from_all)| t.map(|t| truncated_transfer(&t, r_from_all, r_to, r_from_all.min(r))))
                .collect();
            let basis = if r_to < b.mode_count() {
                Arc::new(b.first_modes(r_to))
            } else {
                b
            };
            SpaceInput { basis, transfers }
        })
        .collect())
}

/// The first `rows` × `cols` block of a row-major matrix with `width` columns.
fn truncated_transfer(t: &[f64], width: usize, rows: usize, cols: usize) -> Vec<f64> {
    t.chunks_exact(width.max(1))
        .take(rows)
        .flat_map(|row| &row[..cols])
        .copied()
        .collect()
}

/// Median time of one haptic step in Rust alone (the loop of `ves bench`: one hand grabbing a
/// surface vertex and moving ±0.5 mm), ns, on the default space's first `modes` modes.
#[pyfunction]
#[pyo3(signature = (basis, modes=None, batches=200, per_batch=1000))]
pub fn _rust_step_ns(
    py: Python<'_>,
    basis: &Basis,
    modes: Option<usize>,
    batches: usize,
    per_batch: usize,
) -> PyResult<f64> {
    let rt = basis.space_ref(py, None)?.get().runtime.clone();
    let rt = match modes {
        Some(r) if r >= 1 && r < rt.mode_count() => Arc::new(rt.first_modes(r)),
        _ => rt,
    };
    Ok(py.detach(|| ves_runtime::bench::haptic_step_ns(rt, batches.max(1), per_batch.max(1))))
}
