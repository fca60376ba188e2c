//! Raw declarations from `gmshc.h` (gmsh 4.8.4), written by hand: only what VES calls.
//! Every function ends with `int *ierr`; arrays returned by gmsh are gmsh's and must be freed
//! with `gmshFree`.

use std::os::raw::{c_char, c_double, c_int, c_void};

#[link(name = "gmsh")]
unsafe extern "C" {
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
