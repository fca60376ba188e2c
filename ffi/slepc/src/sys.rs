//! Raw declarations of the PETSc 3.18 / SLEPc 3.18 C API used by VES (Debian
//! `libslepc-real-dev`: real scalars, 32-bit `PetscInt`, OpenMPI). Values of the enums are
//! those of the 3.18 headers.

#![allow(non_camel_case_types, non_upper_case_globals, dead_code, clippy::upper_case_acronyms)]

use std::os::raw::{c_char, c_int, c_void};

pub type PetscErrorCode = c_int;
pub type PetscInt = i32;
pub type PetscMPIInt = c_int;
pub type PetscScalar = f64;
pub type PetscReal = f64;
pub type PetscBool = c_int;
/// OpenMPI's `MPI_Comm` is a pointer to its communicator struct.
pub type MPI_Comm = *mut c_void;
pub type Mat = *mut c_void;
pub type PetscVec = *mut c_void;
pub type EPS = *mut c_void;
pub type ST = *mut c_void;
pub type KSP = *mut c_void;
pub type PC = *mut c_void;
pub type VecScatter = *mut c_void;
pub type MatNullSpace = *mut c_void;

pub const PETSC_TRUE: PetscBool = 1;
pub const PETSC_FALSE: PetscBool = 0;
pub const PETSC_DECIDE: PetscInt = -1;
pub const PETSC_DEFAULT: PetscInt = -2;
pub const INSERT_VALUES: c_int = 1;
pub const SCATTER_FORWARD: c_int = 0;
pub const MAT_FINAL_ASSEMBLY: c_int = 0;
pub const MAT_SYMMETRIC: c_int = 1;
pub const EPS_GHEP: c_int = 2;
pub const EPS_TARGET_MAGNITUDE: c_int = 7;
pub const EPS_ERROR_RELATIVE: c_int = 1;
/// `SAME_NONZERO_PATTERN` of `MatStructure` (petscmat.h: DIFFERENT = 0, SUBSET = 1, SAME = 2).
pub const SAME_NONZERO_PATTERN: c_int = 2;
pub const NORM_2: c_int = 1;

pub type ErrorHandler = unsafe extern "C" fn(
    MPI_Comm,
    c_int,
    *const c_char,
    *const c_char,
    PetscErrorCode,
    c_int,
    *const c_char,
    *mut c_void,
) -> PetscErrorCode;

#[link(name = "slepc_real")]
unsafe extern "C" {
    pub fn SlepcInitialize(
        argc: *mut c_int,
        args: *mut *mut *mut c_char,
        file: *const c_char,
        help: *const c_char,
    ) -> PetscErrorCode;
    pub fn SlepcFinalize() -> PetscErrorCode;

    pub fn EPSCreate(comm: MPI_Comm, eps: *mut EPS) -> PetscErrorCode;
    pub fn EPSSetOperators(eps: EPS, a: Mat, b: Mat) -> PetscErrorCode;
    pub fn EPSSetProblemType(eps: EPS, t: c_int) -> PetscErrorCode;
    pub fn EPSSetType(eps: EPS, t: *const c_char) -> PetscErrorCode;
    pub fn EPSSetDimensions(eps: EPS, nev: PetscInt, ncv: PetscInt, mpd: PetscInt) -> PetscErrorCode;
    pub fn EPSSetTarget(eps: EPS, target: PetscScalar) -> PetscErrorCode;
    pub fn EPSSetWhichEigenpairs(eps: EPS, which: c_int) -> PetscErrorCode;
    pub fn EPSSetTolerances(eps: EPS, tol: PetscReal, maxits: PetscInt) -> PetscErrorCode;
    pub fn EPSGetST(eps: EPS, st: *mut ST) -> PetscErrorCode;
    pub fn EPSSetFromOptions(eps: EPS) -> PetscErrorCode;
    pub fn EPSSetUp(eps: EPS) -> PetscErrorCode;
    pub fn EPSSolve(eps: EPS) -> PetscErrorCode;
    pub fn EPSGetConverged(eps: EPS, nconv: *mut PetscInt) -> PetscErrorCode;
    pub fn EPSGetIterationNumber(eps: EPS, its: *mut PetscInt) -> PetscErrorCode;
    pub fn EPSGetEigenpair(
        eps: EPS,
        i: PetscInt,
        kr: *mut PetscScalar,
        ki: *mut PetscScalar,
        xr: PetscVec,
        xi: PetscVec,
    ) -> PetscErrorCode;
    pub fn EPSComputeError(eps: EPS, i: PetscInt, t: c_int, error: *mut PetscReal) -> PetscErrorCode;
    pub fn EPSDestroy(eps: *mut EPS) -> PetscErrorCode;
    pub fn STSetType(st: ST, t: *const c_char) -> PetscErrorCode;
    pub fn STGetKSP(st: ST, ksp: *mut KSP) -> PetscErrorCode;
    pub fn STSetMatStructure(st: ST, s: c_int) -> PetscErrorCode;
}

#[link(name = "petsc_real")]
unsafe extern "C" {
    pub static PETSC_COMM_WORLD: MPI_Comm;
    pub static PetscGlobalRank: PetscMPIInt;
    pub static PetscGlobalSize: PetscMPIInt;

    pub fn PetscErrorMessage(code: c_int, text: *mut *const c_char, specific: *mut *mut c_char) -> PetscErrorCode;
    pub fn PetscPushErrorHandler(handler: ErrorHandler, ctx: *mut c_void) -> PetscErrorCode;
    pub fn PetscReturnErrorHandler(
        comm: MPI_Comm,
        line: c_int,
        func: *const c_char,
        file: *const c_char,
        n: PetscErrorCode,
        p: c_int,
        mess: *const c_char,
        ctx: *mut c_void,
    ) -> PetscErrorCode;

    pub fn MatCreate(comm: MPI_Comm, a: *mut Mat) -> PetscErrorCode;
    pub fn MatSetSizes(a: Mat, m: PetscInt, n: PetscInt, gm: PetscInt, gn: PetscInt) -> PetscErrorCode;
    pub fn MatSetType(a: Mat, t: *const c_char) -> PetscErrorCode;
    pub fn MatSeqAIJSetPreallocation(a: Mat, nz: PetscInt, nnz: *const PetscInt) -> PetscErrorCode;
    pub fn MatMPIAIJSetPreallocation(
        a: Mat,
        d_nz: PetscInt,
        d_nnz: *const PetscInt,
        o_nz: PetscInt,
        o_nnz: *const PetscInt,
    ) -> PetscErrorCode;
    pub fn MatGetOwnershipRange(a: Mat, lo: *mut PetscInt, hi: *mut PetscInt) -> PetscErrorCode;
    pub fn MatSetValues(
        a: Mat,
        m: PetscInt,
        idxm: *const PetscInt,
        n: PetscInt,
        idxn: *const PetscInt,
        v: *const PetscScalar,
        mode: c_int,
    ) -> PetscErrorCode;
    pub fn MatAssemblyBegin(a: Mat, t: c_int) -> PetscErrorCode;
    pub fn MatAssemblyEnd(a: Mat, t: c_int) -> PetscErrorCode;
    pub fn MatSetOption(a: Mat, op: c_int, flg: PetscBool) -> PetscErrorCode;
    pub fn MatMult(a: Mat, x: PetscVec, y: PetscVec) -> PetscErrorCode;
    pub fn MatCreateVecs(a: Mat, right: *mut PetscVec, left: *mut PetscVec) -> PetscErrorCode;
    pub fn MatDestroy(a: *mut Mat) -> PetscErrorCode;

    pub fn VecScatterCreateToAll(vin: PetscVec, ctx: *mut VecScatter, vout: *mut PetscVec) -> PetscErrorCode;
    pub fn VecScatterCreateToZero(vin: PetscVec, ctx: *mut VecScatter, vout: *mut PetscVec) -> PetscErrorCode;
    pub fn VecScatterBegin(ctx: VecScatter, x: PetscVec, y: PetscVec, mode: c_int, smode: c_int) -> PetscErrorCode;
    pub fn VecScatterEnd(ctx: VecScatter, x: PetscVec, y: PetscVec, mode: c_int, smode: c_int) -> PetscErrorCode;
    pub fn VecScatterDestroy(ctx: *mut VecScatter) -> PetscErrorCode;
    pub fn VecGetArrayRead(x: PetscVec, a: *mut *const PetscScalar) -> PetscErrorCode;
    pub fn VecRestoreArrayRead(x: PetscVec, a: *mut *const PetscScalar) -> PetscErrorCode;
    pub fn VecGetSize(x: PetscVec, n: *mut PetscInt) -> PetscErrorCode;
    pub fn VecGetLocalSize(x: PetscVec, n: *mut PetscInt) -> PetscErrorCode;
    pub fn VecDestroy(x: *mut PetscVec) -> PetscErrorCode;
    pub fn VecDuplicate(v: PetscVec, out: *mut PetscVec) -> PetscErrorCode;
    pub fn VecGetArray(x: PetscVec, a: *mut *mut PetscScalar) -> PetscErrorCode;
    pub fn VecRestoreArray(x: PetscVec, a: *mut *mut PetscScalar) -> PetscErrorCode;
    pub fn VecDot(x: PetscVec, y: PetscVec, val: *mut PetscScalar) -> PetscErrorCode;
    pub fn VecAXPY(y: PetscVec, alpha: PetscScalar, x: PetscVec) -> PetscErrorCode;
    pub fn VecNorm(x: PetscVec, t: c_int, val: *mut PetscReal) -> PetscErrorCode;
    pub fn VecScale(x: PetscVec, alpha: PetscScalar) -> PetscErrorCode;
    pub fn VecMDot(x: PetscVec, nv: PetscInt, y: *const PetscVec, val: *mut PetscScalar) -> PetscErrorCode;
    pub fn VecNormalize(x: PetscVec, norm: *mut PetscReal) -> PetscErrorCode;
    pub fn MatNullSpaceCreate(
        comm: MPI_Comm,
        has_cnst: PetscBool,
        n: PetscInt,
        vecs: *const PetscVec,
        sp: *mut MatNullSpace,
    ) -> PetscErrorCode;
    pub fn MatNullSpaceDestroy(sp: *mut MatNullSpace) -> PetscErrorCode;
    pub fn MatSetNearNullSpace(a: Mat, sp: MatNullSpace) -> PetscErrorCode;

    pub fn KSPSetType(ksp: KSP, t: *const c_char) -> PetscErrorCode;
    pub fn KSPSetTolerances(
        ksp: KSP,
        rtol: PetscReal,
        abstol: PetscReal,
        dtol: PetscReal,
        maxits: PetscInt,
    ) -> PetscErrorCode;
    pub fn KSPGetPC(ksp: KSP, pc: *mut PC) -> PetscErrorCode;
    pub fn PCSetType(pc: PC, t: *const c_char) -> PetscErrorCode;
    pub fn PCFactorSetMatSolverType(pc: PC, t: *const c_char) -> PetscErrorCode;
}

// MPI itself (Open MPI, Debian's `libopenmpi-dev`): the few calls that make an error on one rank
// every rank's. Open MPI's predefined handles are the addresses of these globals (`MPI_INT` is
// `&ompi_mpi_int`, `MPI_SUM` is `&ompi_mpi_op_sum`): checked against mpi.h by the header test.
#[link(name = "mpi")]
unsafe extern "C" {
    pub static ompi_mpi_int: u8;
    pub static ompi_mpi_op_sum: u8;
    pub static ompi_mpi_op_min: u8;
    pub static ompi_mpi_op_max: u8;
    pub static ompi_mpi_double: u8;
    pub static ompi_mpi_byte: u8;
    pub fn MPI_Allreduce(
        sendbuf: *const c_void,
        recvbuf: *mut c_void,
        count: c_int,
        datatype: *const c_void,
        op: *const c_void,
        comm: MPI_Comm,
    ) -> c_int;
    pub fn MPI_Abort(comm: MPI_Comm, errorcode: c_int) -> c_int;
    pub fn MPI_Send(
        buf: *const c_void,
        count: c_int,
        datatype: *const c_void,
        dest: c_int,
        tag: c_int,
        comm: MPI_Comm,
    ) -> c_int;
    /// `status` may be null: Open MPI's `MPI_STATUS_IGNORE` (checked by the header test).
    pub fn MPI_Recv(
        buf: *mut c_void,
        count: c_int,
        datatype: *const c_void,
        source: c_int,
        tag: c_int,
        comm: MPI_Comm,
        status: *mut c_void,
    ) -> c_int;
}
