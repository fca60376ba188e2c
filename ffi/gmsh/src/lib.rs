//! Safe layer over the gmsh C API.
//!
//! gmsh is one global, non-thread-safe library: a [`Gmsh`] holds a process-wide lock from
//! `gmshInitialize` to `gmshFinalize` (run by `Drop`), so two sessions never overlap.

mod sys;

use std::ffi::{CStr, CString};
use std::os::raw::{c_char, c_int};
use std::path::Path;
use std::ptr;
use std::sync::{Mutex, MutexGuard};

/// A gmsh call failed; `message` is gmsh's own last error.
#[derive(Debug, thiserror::Error)]
#[error("gmsh {call} failed: {message}")]
pub struct GmshError {
    /// The C function that failed.
    pub call: &'static str,
    /// gmsh's message (or the reason it is missing).
    pub message: String,
}

/// Result of a gmsh call.
pub type Result<T> = std::result::Result<T, GmshError>;

static GMSH_LOCK: Mutex<()> = Mutex::new(());

type Job = Box<dyn FnOnce() + Send>;

/// Runs `f` on the one thread that makes every gmsh call of the process, and waits for it.
///
/// gmsh keeps per-thread state (its mesher gave a slightly different mesh for the same input
/// when called from another thread, even one session at a time), so a reproducible mesh needs
/// every session on the same thread.
pub fn on_gmsh_thread<R: Send + 'static>(f: impl FnOnce() -> R + Send + 'static) -> R {
    static WORKER: std::sync::OnceLock<Mutex<std::sync::mpsc::Sender<Job>>> = std::sync::OnceLock::new();
    let sender = WORKER.get_or_init(|| {
        let (tx, rx) = std::sync::mpsc::channel::<Job>();
        std::thread::Builder::new()
            .name("gmsh".into())
            .spawn(move || {
                for job in rx {
                    // A panicking job must not take the worker down with it.
                    let _ = std::panic::catch_unwind(std::panic::AssertUnwindSafe(job));
                }
            })
            .unwrap_or_else(|e| panic!("cannot start the gmsh thread: {e}"));
        Mutex::new(tx)
    });
    let (rtx, rrx) = std::sync::mpsc::channel();
    let job: Job = Box::new(move || {
        let _ = rtx.send(f());
    });
    sender
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .send(job)
        .unwrap_or_else(|_| panic!("the gmsh thread is gone"));
    rrx.recv().unwrap_or_else(|_| panic!("a gmsh job panicked"))
}

/// Element type codes of gmsh.
pub mod element_type {
    /// 3-node triangle.
    pub const TRIANGLE3: i32 = 2;
    /// 6-node triangle (the faces of 10-node tets).
    pub const TRIANGLE6: i32 = 9;
    /// 4-node tetrahedron.
    pub const TET4: i32 = 4;
    /// 10-node tetrahedron.
    pub const TET10: i32 = 11;
}

/// One initialised gmsh library; finalised on drop.
pub struct Gmsh {
    _lock: MutexGuard<'static, ()>,
    api: &'static sys::Api,
}

fn cstring(call: &'static str, s: &str) -> Result<CString> {
    CString::new(s).map_err(|_| GmshError {
        call,
        message: format!("argument {s:?} contains a NUL byte"),
    })
}

/// Turns a non-zero `ierr` into an error carrying gmsh's last message.
fn check(api: &sys::Api, call: &'static str, ierr: c_int) -> Result<()> {
    if ierr == 0 {
        return Ok(());
    }
    let mut msg: *mut c_char = ptr::null_mut();
    let mut ierr2 = 0;
    // SAFETY: gmsh allocates the string; we copy it and free it with gmshFree.
    let message = unsafe {
        (api.gmshLoggerGetLastError)(&mut msg, &mut ierr2);
        if ierr2 == 0 && !msg.is_null() {
            let s = CStr::from_ptr(msg).to_string_lossy().into_owned();
            (api.gmshFree)(msg.cast());
            s
        } else {
            String::new()
        }
    };
    let message = if message.is_empty() {
        format!("error code {ierr} (gmsh gave no message)")
    } else {
        message
    };
    Err(GmshError { call, message })
}

/// Copies a gmsh-owned array into a `Vec` and frees the original.
///
/// # Safety
/// `p` must be null or point to `n` initialised values allocated by gmsh.
unsafe fn take<T: Copy>(api: &sys::Api, p: *mut T, n: usize) -> Vec<T> {
    if p.is_null() {
        return Vec::new();
    }
    // SAFETY: guaranteed by the caller.
    let v = unsafe { std::slice::from_raw_parts(p, n).to_vec() };
    // SAFETY: p was allocated by gmsh.
    unsafe { (api.gmshFree)(p.cast()) };
    v
}

/// Axis-aligned bounding box `[min, max]`.
pub type BoundingBox = ([f64; 3], [f64; 3]);

impl Gmsh {
    /// Initialises gmsh (waiting for any other session to finish), silenced and without
    /// reading the user's configuration files, so runs are reproducible.
    pub fn start() -> Result<Gmsh> {
        let api = sys::api().map_err(|reason| GmshError {
            call: "initialize",
            message: format!(
                "gmsh's library could not be loaded ({reason}); install it (Debian 12: apt-get install libgmsh4.8)"
            ),
        })?;
        let lock = GMSH_LOCK.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        let mut ierr = 0;
        // SAFETY: argc = 0 with a null argv is accepted by gmshInitialize.
        unsafe { (api.gmshInitialize)(0, ptr::null_mut(), 0, &mut ierr) };
        check(api, "initialize", ierr)?;
        let session = Gmsh { _lock: lock, api };
        session.set_number("General.Terminal", 0.0)?;
        // Keep gmsh's messages: they name the curves and surfaces behind a failure.
        // SAFETY: plain call.
        unsafe { (api.gmshLoggerStart)(&mut ierr) };
        check(api, "logger/start", ierr)?;
        Ok(session)
    }

    /// gmsh's messages since `start` ("Info: …", "Warning: …", "Error: …").
    pub fn log(&self) -> Vec<String> {
        let (mut p, mut n, mut ierr) = (ptr::null_mut(), 0usize, 0);
        // SAFETY: gmsh allocates an array of n strings; each and the array are freed with gmshFree.
        unsafe {
            (self.api.gmshLoggerGet)(&mut p, &mut n, &mut ierr);
            if ierr != 0 || p.is_null() {
                return Vec::new();
            }
            let lines = take(self.api, p, n);
            lines
                .into_iter()
                .map(|l| {
                    let s = if l.is_null() {
                        String::new()
                    } else {
                        CStr::from_ptr(l).to_string_lossy().into_owned()
                    };
                    (self.api.gmshFree)(l.cast());
                    s
                })
                .collect()
        }
    }

    /// Sets a numeric option, e.g. `Mesh.MeshSizeMax`.
    pub fn set_number(&self, name: &str, value: f64) -> Result<()> {
        let c = cstring("option/setNumber", name)?;
        let mut ierr = 0;
        // SAFETY: valid C string; gmsh initialised while self lives.
        unsafe { (self.api.gmshOptionSetNumber)(c.as_ptr(), value, &mut ierr) };
        check(self.api, "option/setNumber", ierr).map_err(|e| GmshError {
            message: format!("{name}: {}", e.message),
            ..e
        })
    }

    /// Sets a string option, e.g. `Geometry.OCCTargetUnit`.
    pub fn set_string(&self, name: &str, value: &str) -> Result<()> {
        let c = cstring("option/setString", name)?;
        let v = cstring("option/setString", value)?;
        let mut ierr = 0;
        // SAFETY: valid C strings.
        unsafe { (self.api.gmshOptionSetString)(c.as_ptr(), v.as_ptr(), &mut ierr) };
        check(self.api, "option/setString", ierr).map_err(|e| GmshError {
            message: format!("{name}: {}", e.message),
            ..e
        })
    }

    /// Opens a geometry file (STEP, BREP, GEO, …) into a fresh model. gmsh does not fail on a
    /// missing file, so existence is checked here.
    pub fn open(&self, path: &Path) -> Result<()> {
        if !path.is_file() {
            return Err(GmshError {
                call: "open",
                message: format!("{}: no such file", path.display()),
            });
        }
        let c = cstring("open", &path.to_string_lossy())?;
        let mut ierr = 0;
        // SAFETY: valid C string.
        unsafe {
            (self.api.gmshClear)(&mut ierr);
            check(self.api, "clear", ierr)?;
            (self.api.gmshOpen)(c.as_ptr(), &mut ierr);
        }
        check(self.api, "open", ierr)
    }

    /// `(dim, tag)` of every entity of dimension `dim` (-1: all).
    pub fn entities(&self, dim: i32) -> Result<Vec<(i32, i32)>> {
        let mut p: *mut c_int = ptr::null_mut();
        let mut n = 0usize;
        let mut ierr = 0;
        // SAFETY: out-pointers valid; the array is copied and freed by `take`.
        let flat = unsafe {
            (self.api.gmshModelGetEntities)(&mut p, &mut n, dim, &mut ierr);
            check(self.api, "model/getEntities", ierr)?;
            take(self.api, p, n)
        };
        Ok(flat.chunks_exact(2).map(|c| (c[0], c[1])).collect())
    }

    /// Bounding box of the whole model.
    pub fn bounding_box(&self) -> Result<BoundingBox> {
        let (mut a, mut b) = ([0.0; 3], [0.0; 3]);
        let mut ierr = 0;
        // SAFETY: six valid out-pointers.
        unsafe {
            let [x0, y0, z0] = &mut a;
            let [x1, y1, z1] = &mut b;
            (self.api.gmshModelGetBoundingBox)(-1, -1, x0, y0, z0, x1, y1, z1, &mut ierr);
        }
        check(self.api, "model/getBoundingBox", ierr)?;
        Ok((a, b))
    }

    /// Generates the mesh up to dimension `dim`.
    pub fn generate(&self, dim: i32) -> Result<()> {
        let mut ierr = 0;
        // SAFETY: plain call.
        unsafe { (self.api.gmshModelMeshGenerate)(dim, &mut ierr) };
        check(self.api, "model/mesh/generate", ierr)
    }

    /// Raises the mesh to element order `order` (2: 10-node tets).
    pub fn set_order(&self, order: i32) -> Result<()> {
        let mut ierr = 0;
        // SAFETY: plain call.
        unsafe { (self.api.gmshModelMeshSetOrder)(order, &mut ierr) };
        check(self.api, "model/mesh/setOrder", ierr)
    }

    /// Optimises the mesh with gmsh's `method` ("HighOrder", "HighOrderElastic", "Netgen", …)
    /// over the whole model, `niter` times.
    pub fn optimize(&self, method: &str, niter: i32) -> Result<()> {
        let m = cstring("model/mesh/optimize", method)?;
        let mut ierr = 0;
        // SAFETY: valid C string; no entity list (whole model).
        unsafe { (self.api.gmshModelMeshOptimize)(m.as_ptr(), 0, niter, ptr::null_mut(), 0, &mut ierr) };
        check(self.api, "model/mesh/optimize", ierr)
    }

    /// All mesh nodes: gmsh tags and coordinates (x, y, z per node).
    pub fn nodes(&self) -> Result<(Vec<usize>, Vec<f64>)> {
        let (mut tags, mut ntags) = (ptr::null_mut(), 0usize);
        let (mut coord, mut ncoord) = (ptr::null_mut(), 0usize);
        let (mut par, mut npar) = (ptr::null_mut(), 0usize);
        let mut ierr = 0;
        // SAFETY: out-pointers valid; arrays copied and freed.
        unsafe {
            (self.api.gmshModelMeshGetNodes)(
                &mut tags,
                &mut ntags,
                &mut coord,
                &mut ncoord,
                &mut par,
                &mut npar,
                -1,
                -1,
                0,
                0,
                &mut ierr,
            );
            let (t, c) = (take(self.api, tags, ntags), take(self.api, coord, ncoord));
            drop(take(self.api, par, npar));
            check(self.api, "model/mesh/getNodes", ierr)?;
            Ok((t, c))
        }
    }

    /// Elements of one gmsh type over the whole model: element tags and node tags (flat,
    /// `nodes_per_element` per element, gmsh node order).
    pub fn elements_by_type(&self, ty: i32) -> Result<(Vec<usize>, Vec<usize>)> {
        self.elements_by_type_on(ty, -1)
    }

    /// [`Gmsh::elements_by_type`] of the elements classified on one entity: `tag` of the
    /// dimension of type `ty` (a surface's tag for triangles); -1: the whole model.
    pub fn elements_by_type_on(&self, ty: i32, tag: i32) -> Result<(Vec<usize>, Vec<usize>)> {
        let (mut et, mut net) = (ptr::null_mut(), 0usize);
        let (mut nt, mut nnt) = (ptr::null_mut(), 0usize);
        let mut ierr = 0;
        // SAFETY: out-pointers valid; arrays copied and freed.
        unsafe {
            (self.api.gmshModelMeshGetElementsByType)(ty, &mut et, &mut net, &mut nt, &mut nnt, tag, 0, 1, &mut ierr);
            let (e, n) = (take(self.api, et, net), take(self.api, nt, nnt));
            check(self.api, "model/mesh/getElementsByType", ierr)?;
            Ok((e, n))
        }
    }

    /// Adds a mesh size field of type `kind` (e.g. "Box", "Min") and returns its tag.
    pub fn field_add(&self, kind: &str) -> Result<i32> {
        let c = cstring("model/mesh/field/add", kind)?;
        let mut ierr = 0;
        // SAFETY: valid C string; tag -1 lets gmsh choose.
        let tag = unsafe { (self.api.gmshModelMeshFieldAdd)(c.as_ptr(), -1, &mut ierr) };
        check(self.api, "model/mesh/field/add", ierr)?;
        Ok(tag)
    }

    /// Sets a numeric option of a size field.
    pub fn field_set_number(&self, tag: i32, option: &str, value: f64) -> Result<()> {
        let c = cstring("model/mesh/field/setNumber", option)?;
        let mut ierr = 0;
        // SAFETY: valid C string.
        unsafe { (self.api.gmshModelMeshFieldSetNumber)(tag, c.as_ptr(), value, &mut ierr) };
        check(self.api, "model/mesh/field/setNumber", ierr)
    }

    /// Sets a list option of a size field (e.g. "FieldsList").
    pub fn field_set_numbers(&self, tag: i32, option: &str, values: &[f64]) -> Result<()> {
        let c = cstring("model/mesh/field/setNumbers", option)?;
        let mut v = values.to_vec();
        let mut ierr = 0;
        // SAFETY: valid C string and buffer of v.len() values (gmsh copies it).
        unsafe { (self.api.gmshModelMeshFieldSetNumbers)(tag, c.as_ptr(), v.as_mut_ptr(), v.len(), &mut ierr) };
        check(self.api, "model/mesh/field/setNumbers", ierr)
    }

    /// Uses size field `tag` as the background mesh size.
    pub fn field_set_as_background(&self, tag: i32) -> Result<()> {
        let mut ierr = 0;
        // SAFETY: plain call.
        unsafe { (self.api.gmshModelMeshFieldSetAsBackgroundMesh)(tag, &mut ierr) };
        check(self.api, "model/mesh/field/setAsBackgroundMesh", ierr)
    }

    /// Adds a list-based view of scalar values on tetrahedra ("SS") and returns its tag: per
    /// tet, the x of its four corners, their y, their z, then the four values. A "PostView" size
    /// field reads it (option "ViewTag").
    pub fn view_scalar_tets(&self, name: &str, data: &[f64]) -> Result<i32> {
        const PER_TET: usize = 16;
        if !data.len().is_multiple_of(PER_TET) {
            return Err(GmshError {
                call: "view/addListData",
                message: format!("{} values is not 16 per tet", data.len()),
            });
        }
        let count = i32::try_from(data.len() / PER_TET).map_err(|_| GmshError {
            call: "view/addListData",
            message: format!("{} tets is more than a view holds", data.len() / PER_TET),
        })?;
        let c = cstring("view/add", name)?;
        let mut ierr = 0;
        // SAFETY: valid C string; tag -1 lets gmsh choose.
        let tag = unsafe { (self.api.gmshViewAdd)(c.as_ptr(), -1, &mut ierr) };
        check(self.api, "view/add", ierr)?;
        let kind = cstring("view/addListData", "SS")?;
        let mut v = data.to_vec();
        // SAFETY: valid C string; a buffer of v.len() values, 16 per tet as counted (gmsh copies it).
        unsafe { (self.api.gmshViewAddListData)(tag, kind.as_ptr(), count, v.as_mut_ptr(), v.len(), &mut ierr) };
        check(self.api, "view/addListData", ierr)?;
        Ok(tag)
    }
}

impl Drop for Gmsh {
    fn drop(&mut self) {
        let mut ierr = 0;
        // SAFETY: gmsh was initialised by `start`; the lock is released after this. The logger
        // outlives finalize otherwise: the next session would see this one's messages.
        unsafe {
            (self.api.gmshLoggerStop)(&mut ierr);
            (self.api.gmshFinalize)(&mut ierr);
        }
    }
}
