//! Raw declarations from `gmshc.h` (gmsh 4.8.4), written by hand: only what VES calls.
//! Every function ends with `int *ierr`; arrays returned by gmsh are gmsh's and must be freed
//! with `gmshFree`.
//!
//! The library is opened when a session first needs it, not linked: loading gmsh with its
//! OpenCASCADE, FLTK and GL dependencies cost every `ves` process ~0.1 s at start (an empty
//! program linked to libgmsh alone: 0.10 s against 0.00 s), and most of them (sessions, the
//! viewer's instant bases, reports) never mesh.

use std::os::raw::{c_char, c_double, c_int, c_void};

/// The names the library is tried under: gmsh 4.8's soname, then any (its C API is stable).
const LIBRARY: [&str; 2] = ["libgmsh.so.4.8", "libgmsh.so"];

/// Declares [`Api`], one function pointer per C function, resolved by name from the library.
macro_rules! api {
    ($(pub fn $name:ident($($arg:ident: $ty:ty),* $(,)?) $(-> $ret:ty)?;)*) => {
        /// gmsh's C functions that VES calls, resolved from the loaded library.
        #[allow(non_snake_case)]
        pub struct Api {
            $(pub $name: unsafe extern "C" fn($($arg: $ty),*) $(-> $ret)?,)*
            _library: libloading::Library,
        }

        impl Api {
            /// Resolves every function from `library`.
            ///
            /// # Safety
            /// `library` must be gmsh's, whose functions have the signatures declared here.
            unsafe fn resolve(library: libloading::Library) -> Result<Api, libloading::Error> {
                // SAFETY: the signatures are gmshc.h's (the caller's promise).
                unsafe {
                    Ok(Api {
                        $($name: *library.get(concat!(stringify!($name), "\0").as_bytes())?,)*
                        _library: library,
                    })
                }
            }
        }
    };
}

/// gmsh's functions, the library loaded on the first call (and kept for the process); the
/// reason it could not be, if so.
pub fn api() -> Result<&'static Api, String> {
    static API: std::sync::OnceLock<Result<Api, String>> = std::sync::OnceLock::new();
    API.get_or_init(|| {
        let mut reasons = Vec::new();
        for name in LIBRARY {
            // SAFETY: loading gmsh runs its static constructors, which have no preconditions.
            match unsafe { libloading::Library::new(name) } {
                // SAFETY: a library of this name is gmsh's.
                Ok(library) => return unsafe { Api::resolve(library) }.map_err(|e| format!("{name}: {e}")),
                Err(e) => reasons.push(e.to_string()),
            }
        }
        Err(reasons.join("; "))
    })
    .as_ref()
    .map_err(Clone::clone)
}

api! {
    pub fn gmshInitialize(argc: c_int, argv: *mut *mut c_char, read_config_files: c_int, ierr: *mut c_int);
    pub fn gmshFinalize(ierr: *mut c_int);
    pub fn gmshOpen(file_name: *const c_char, ierr: *mut c_int);
    pub fn gmshClear(ierr: *mut c_int);
    pub fn gmshOptionSetNumber(name: *const c_char, value: c_double, ierr: *mut c_int);
    pub fn gmshOptionSetString(name: *const c_char, value: *const c_char, ierr: *mut c_int);
    pub fn gmshLoggerGetLastError(error: *mut *mut c_char, ierr: *mut c_int);
    pub fn gmshFree(p: *mut c_void);
    pub fn gmshLoggerStart(ierr: *mut c_int);
    pub fn gmshLoggerStop(ierr: *mut c_int);
    pub fn gmshLoggerGet(log: *mut *mut *mut c_char, log_n: *mut usize, ierr: *mut c_int);
    pub fn gmshModelGetEntities(dim_tags: *mut *mut c_int, dim_tags_n: *mut usize, dim: c_int, ierr: *mut c_int);
    pub fn gmshModelGetBoundingBox(
        dim: c_int,
        tag: c_int,
        xmin: *mut c_double,
        ymin: *mut c_double,
        zmin: *mut c_double,
        xmax: *mut c_double,
        ymax: *mut c_double,
        zmax: *mut c_double,
        ierr: *mut c_int,
    );
    pub fn gmshModelMeshGenerate(dim: c_int, ierr: *mut c_int);
    pub fn gmshModelMeshSetOrder(order: c_int, ierr: *mut c_int);
    pub fn gmshModelMeshOptimize(
        method: *const c_char,
        force: c_int,
        niter: c_int,
        dim_tags: *mut c_int,
        dim_tags_n: usize,
        ierr: *mut c_int,
    );
    pub fn gmshModelMeshGetNodes(
        node_tags: *mut *mut usize,
        node_tags_n: *mut usize,
        coord: *mut *mut c_double,
        coord_n: *mut usize,
        parametric_coord: *mut *mut c_double,
        parametric_coord_n: *mut usize,
        dim: c_int,
        tag: c_int,
        include_boundary: c_int,
        return_parametric_coord: c_int,
        ierr: *mut c_int,
    );
    pub fn gmshModelMeshGetElementsByType(
        element_type: c_int,
        element_tags: *mut *mut usize,
        element_tags_n: *mut usize,
        node_tags: *mut *mut usize,
        node_tags_n: *mut usize,
        tag: c_int,
        task: usize,
        num_tasks: usize,
        ierr: *mut c_int,
    );
    pub fn gmshModelMeshFieldAdd(field_type: *const c_char, tag: c_int, ierr: *mut c_int) -> c_int;
    pub fn gmshModelMeshFieldSetNumber(tag: c_int, option: *const c_char, value: c_double, ierr: *mut c_int);
    pub fn gmshModelMeshFieldSetNumbers(
        tag: c_int,
        option: *const c_char,
        value: *mut c_double,
        value_n: usize,
        ierr: *mut c_int,
    );
    pub fn gmshModelMeshFieldSetAsBackgroundMesh(tag: c_int, ierr: *mut c_int);
    pub fn gmshViewAdd(name: *const c_char, tag: c_int, ierr: *mut c_int) -> c_int;
    pub fn gmshViewAddListData(
        tag: c_int,
        data_type: *const c_char,
        num_ele: c_int,
        data: *mut c_double,
        data_n: usize,
        ierr: *mut c_int,
    );
}
