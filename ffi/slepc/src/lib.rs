//! Safe layer over SLEPc/PETSc: an initialisation token ([`Slepc`], finalised on `Drop`), and a
//! generalized symmetric eigen-solve K x = λ M x in shift-invert around a target with a parallel
//! direct factorisation (MUMPS Cholesky), over every rank of `PETSC_COMM_WORLD`.
//!
//! Each rank inserts the rows it owns ([`LocalRows`], which it builds from its own part of the
//! problem) into distributed AIJ matrices ([`Operators`]); the modes are checked on every rank
//! (residuals, M-inner products) and the eigenvectors gathered to rank 0 only. Every PETSc error
//! code becomes a [`PetscError`] carrying PETSc's own
//! message (its printing error handler is replaced by the silent one). Options can still be
//! overridden from the environment (`PETSC_OPTIONS="-eps_ncv 80 -st_pc_factor_mat_solver_type
//! superlu_dist"`), since the solver calls `EPSSetFromOptions`.
//!
//! Everything is behind the `slepc` feature: without it the crate is empty and links nothing.
#![cfg(feature = "slepc")]

/// Raw declarations (public so a test can check them against the installed headers).
pub mod sys;

use std::ffi::CStr;
use std::os::raw::{c_char, c_int};
use std::ptr;
use std::sync::atomic::{AtomicBool, Ordering};
use sys::*;

/// A PETSc/SLEPc call failed.
#[derive(Debug, thiserror::Error)]
#[error("PETSc error {code} in {call}: {message}")]
pub struct PetscError {
    /// The call that failed.
    pub call: &'static str,
    /// PETSc's error code.
    pub code: i32,
    /// PETSc's message.
    pub message: String,
}

fn check(call: &'static str, code: PetscErrorCode) -> Result<(), PetscError> {
    if code == 0 {
        return Ok(());
    }
    let mut text: *const c_char = ptr::null();
    let mut specific: *mut c_char = ptr::null_mut();
    // SAFETY: PetscErrorMessage fills two pointers to static or PETSc-owned strings.
    unsafe { PetscErrorMessage(code, &mut text, &mut specific) };
    let read = |p: *const c_char| {
        if p.is_null() {
            String::new()
        } else {
            // SAFETY: a NUL-terminated string owned by PETSc.
            unsafe { CStr::from_ptr(p) }.to_string_lossy().trim().to_string()
        }
    };
    let (generic, detail) = (read(text), read(specific));
    let message = match (generic.is_empty(), detail.is_empty()) {
        (_, false) if !generic.is_empty() => format!("{generic}: {detail}"),
        (_, false) => detail,
        _ => generic,
    };
    Err(PetscError {
        call,
        code,
        message: message.replace('\n', " "),
    })
}

static INITIALISED: AtomicBool = AtomicBool::new(false);

/// SLEPc (and PETSc, and MPI) initialised for this process; finalised when dropped. MPI allows
/// one initialisation per process, so a second token is refused even after the first is gone.
pub struct Slepc {
    _not_send: std::marker::PhantomData<*const ()>,
}

impl Slepc {
    /// Initialises SLEPc (MPI_Init included), without PETSc's signal handlers.
    pub fn init() -> Result<Slepc, PetscError> {
        if INITIALISED.swap(true, Ordering::SeqCst) {
            return Err(PetscError {
                call: "SlepcInitialize",
                code: -1,
                message: "SLEPc can be initialised once per process".into(),
            });
        }
        let args = [c"ves", c"-no_signal_handler"];
        let mut argv: Vec<*mut c_char> = args.iter().map(|a| a.as_ptr() as *mut c_char).collect();
        argv.push(ptr::null_mut());
        let mut argc = args.len() as c_int;
        let mut argv_ptr = argv.as_mut_ptr();
        // SAFETY: argc/argv describe NUL-terminated strings that outlive the call (PETSc copies
        // the options it parses).
        check("SlepcInitialize", unsafe {
            SlepcInitialize(&mut argc, &mut argv_ptr, ptr::null(), ptr::null())
        })?;
        // SAFETY: after initialisation; the handler is PETSc's own silent one.
        check("PetscPushErrorHandler", unsafe {
            PetscPushErrorHandler(PetscReturnErrorHandler, ptr::null_mut())
        })?;
        Ok(Slepc {
            _not_send: std::marker::PhantomData,
        })
    }

    /// This process's rank in `PETSC_COMM_WORLD`.
    pub fn rank(&self) -> usize {
        // SAFETY: set by SlepcInitialize, read-only afterwards.
        unsafe { PetscGlobalRank as usize }
    }

    /// Number of ranks.
    pub fn size(&self) -> usize {
        // SAFETY: as above.
        unsafe { PetscGlobalSize as usize }
    }

    /// Element-wise sum of `values` over every rank, in place. Collective: every rank must call
    /// it with the same length.
    pub fn sum_over_ranks<T: Reducible>(&self, values: &mut [T]) -> Result<(), PetscError> {
        self.all_reduce(values, &raw const ompi_mpi_op_sum)
    }

    /// Element-wise minimum of `values` over every rank, in place. Collective.
    pub fn min_over_ranks<T: Reducible>(&self, values: &mut [T]) -> Result<(), PetscError> {
        self.all_reduce(values, &raw const ompi_mpi_op_min)
    }

    /// Element-wise maximum of `values` over every rank, in place. Collective.
    pub fn max_over_ranks<T: Reducible>(&self, values: &mut [T]) -> Result<(), PetscError> {
        self.all_reduce(values, &raw const ompi_mpi_op_max)
    }

    fn all_reduce<T: Reducible>(&self, values: &mut [T], op: *const u8) -> Result<(), PetscError> {
        let count = c_int::try_from(values.len()).map_err(|_| PetscError {
            call: "MPI_Allreduce",
            code: -1,
            message: format!("{} values is more than one call reduces", values.len()),
        })?;
        let send = values.to_vec();
        // SAFETY: MPI is initialised (a token exists); both buffers hold `count` values of the
        // type `T::datatype` names; the handles are Open MPI's predefined ones (MPI_INT,
        // MPI_DOUBLE, MPI_SUM/MIN/MAX), checked against mpi.h by the header test.
        let code = unsafe {
            MPI_Allreduce(
                send.as_ptr().cast(),
                values.as_mut_ptr().cast(),
                count,
                T::datatype(),
                op.cast(),
                PETSC_COMM_WORLD,
            )
        };
        mpi_check("MPI_Allreduce", code)
    }

    /// Ends every process of the job with exit status `code` (`MPI_Abort`): for an error on
    /// some ranks only, which would leave the others waiting in a collective call forever.
    pub fn abort(&self, code: i32) -> ! {
        // SAFETY: MPI is initialised; MPI_Abort does not return (Open MPI kills every rank).
        unsafe { MPI_Abort(PETSC_COMM_WORLD, code) };
        std::process::exit(code)
    }

    /// Sends `data` to rank `dest` (a matching [`Slepc::receive`] of the same length and type
    /// must be posted there). Large arrays go in pieces of at most 1 GiB (MPI counts are ints).
    pub fn send<T: Plain>(&self, dest: usize, data: &[T]) -> Result<(), PetscError> {
        // SAFETY: `Plain` types are plain old data without padding: their bytes can be sent.
        let bytes = unsafe { std::slice::from_raw_parts(data.as_ptr().cast::<u8>(), std::mem::size_of_val(data)) };
        for piece in bytes.chunks(PIECE) {
            // SAFETY: MPI is initialised; `piece` holds `len` bytes; MPI_BYTE is Open MPI's
            // predefined handle (checked against mpi.h by the header test).
            let code = unsafe {
                MPI_Send(
                    piece.as_ptr().cast(),
                    piece.len() as c_int,
                    (&raw const ompi_mpi_byte).cast(),
                    dest as c_int,
                    TAG,
                    PETSC_COMM_WORLD,
                )
            };
            mpi_check("MPI_Send", code)?;
        }
        Ok(())
    }

    /// Receives `len` values sent by rank `from` with [`Slepc::send`].
    pub fn receive<T: Plain>(&self, from: usize, len: usize) -> Result<Vec<T>, PetscError> {
        let mut data = vec![T::default(); len];
        // SAFETY: as in `send`; every bit pattern is a valid `Plain` value.
        let bytes =
            unsafe { std::slice::from_raw_parts_mut(data.as_mut_ptr().cast::<u8>(), std::mem::size_of_val(&data[..])) };
        for piece in bytes.chunks_mut(PIECE) {
            // SAFETY: `piece` has room for `len` bytes; a null status is MPI_STATUS_IGNORE.
            let code = unsafe {
                MPI_Recv(
                    piece.as_mut_ptr().cast(),
                    piece.len() as c_int,
                    (&raw const ompi_mpi_byte).cast(),
                    from as c_int,
                    TAG,
                    PETSC_COMM_WORLD,
                    ptr::null_mut(),
                )
            };
            mpi_check("MPI_Recv", code)?;
        }
        Ok(data)
    }

    /// K and M over every rank, of which this rank holds the rows `rows` (a contiguous range of
    /// an order-`n` problem, the ranks' ranges adjacent in rank order, of any sizes; freed once
    /// PETSc has copied them), with K's near-null space when the rows carry one. Collective: every rank calls it with its own rows.
    pub fn operators(&self, n: usize, rows: LocalRows) -> Result<Operators, PetscError> {
        let size_err = |what: String| PetscError {
            call: "operators",
            code: -1,
            message: what,
        };
        if n == 0 || n > i32::MAX as usize / 2 {
            return Err(size_err(format!("an order-{n} problem")));
        }
        // Any contiguous split in rank order (PETSc checks that the ranks' counts add up to n;
        // `DistMatrix::from_rows` that this rank got the range it was given).
        if rows.lo > rows.hi || rows.hi > n {
            return Err(size_err(format!(
                "rows {}..{} of an order-{n} problem",
                rows.lo, rows.hi
            )));
        }
        // SAFETY: set by SlepcInitialize.
        let world = unsafe { PETSC_COMM_WORLD };
        let k = DistMatrix::from_rows(world, n, &rows, &rows.k)?;
        let m = DistMatrix::from_rows(world, n, &rows, &rows.m)?;
        // The preconditioner's near-null space (GAMG builds its coarse spaces from it): kept
        // alive with K.
        let near_null = match rows.near_null.is_empty() {
            true => None,
            false => Some(NearNull::attach(&k, &rows)?),
        };
        Ok(Operators {
            n,
            k,
            m,
            _near_null: near_null,
        })
    }

    /// The `nev` eigenpairs of K x = λ M x nearest `target` (below the spectrum: the lowest),
    /// by Krylov–Schur in shift-invert with a MUMPS Cholesky factorisation of K − σM (or the
    /// iterative `method`), then checked where the vectors live: each one M-normalised, its
    /// relative residual ‖Kx − λMx‖/‖Kx‖ and the M-inner products of all pairs computed on every
    /// rank's rows. Collective: every rank calls it with its own [`Operators`] and the same
    /// other arguments. The eigenvectors are gathered to rank 0 only (column-major `n × nev`;
    /// empty on other ranks).
    pub fn lowest_eigenpairs(
        &self,
        ops: &Operators,
        nev: usize,
        target: f64,
        tol: f64,
        method: Method,
    ) -> Result<Eigenpairs, PetscError> {
        let n = ops.n;
        let size_err = |what: &str| PetscError {
            call: "lowest_eigenpairs",
            code: -1,
            message: what.to_string(),
        };
        if nev == 0 || nev >= n {
            return Err(size_err(&format!("{nev} eigenpairs of an order-{n} problem")));
        }
        // SAFETY: set by SlepcInitialize.
        let world = unsafe { PETSC_COMM_WORLD };
        let (k, m) = (&ops.k, &ops.m);
        let mut eps = Eps(ptr::null_mut());
        let (eps_type, st_type, ksp_type, pc_type) = match method {
            Method::ShiftInvert => (c"krylovschur", c"sinvert", c"preonly", c"cholesky"),
            Method::Iterative => (c"jd", c"precond", c"bcgsl", c"gamg"),
        };
        let t0 = std::time::Instant::now();
        // SAFETY: every handle below is created here, checked, and destroyed by its guard.
        unsafe {
            check("EPSCreate", EPSCreate(world, &mut eps.0))?;
            check("EPSSetType", EPSSetType(eps.0, eps_type.as_ptr()))?;
            check("EPSSetOperators", EPSSetOperators(eps.0, k.0, m.0))?;
            check("EPSSetProblemType", EPSSetProblemType(eps.0, EPS_GHEP))?;
            check(
                "EPSSetDimensions",
                EPSSetDimensions(eps.0, nev as PetscInt, PETSC_DEFAULT, PETSC_DEFAULT),
            )?;
            check("EPSSetTarget", EPSSetTarget(eps.0, target))?;
            check(
                "EPSSetWhichEigenpairs",
                EPSSetWhichEigenpairs(eps.0, EPS_TARGET_MAGNITUDE),
            )?;
            let max_it = if method == Method::Iterative { 10_000 } else { 1000 };
            check("EPSSetTolerances", EPSSetTolerances(eps.0, tol, max_it))?;
            let mut st = ptr::null_mut();
            check("EPSGetST", EPSGetST(eps.0, &mut st))?;
            check("STSetType", STSetType(st, st_type.as_ptr()))?;
            check("STSetMatStructure", STSetMatStructure(st, SAME_NONZERO_PATTERN))?;
            let mut ksp = ptr::null_mut();
            check("STGetKSP", STGetKSP(st, &mut ksp))?;
            check("KSPSetType", KSPSetType(ksp, ksp_type.as_ptr()))?;
            if method == Method::Iterative {
                // Jacobi–Davidson needs the correction equation only roughly solved.
                check(
                    "KSPSetTolerances",
                    KSPSetTolerances(ksp, 1e-3, PETSC_DEFAULT as f64, PETSC_DEFAULT as f64, 40),
                )?;
            }
            let mut pc = ptr::null_mut();
            check("KSPGetPC", KSPGetPC(ksp, &mut pc))?;
            check("PCSetType", PCSetType(pc, pc_type.as_ptr()))?;
            if method == Method::ShiftInvert {
                check(
                    "PCFactorSetMatSolverType",
                    PCFactorSetMatSolverType(pc, c"mumps".as_ptr()),
                )?;
            }
            check("EPSSetFromOptions", EPSSetFromOptions(eps.0))?;
            check("EPSSetUp", EPSSetUp(eps.0))?;
        }
        let setup_s = t0.elapsed().as_secs_f64();
        let t1 = std::time::Instant::now();
        let (mut nconv, mut its) = (0, 0);
        // SAFETY: as above.
        unsafe {
            check("EPSSolve", EPSSolve(eps.0))?;
            check("EPSGetConverged", EPSGetConverged(eps.0, &mut nconv))?;
            check("EPSGetIterationNumber", EPSGetIterationNumber(eps.0, &mut its))?;
        }
        if (nconv as usize) < nev {
            return Err(PetscError {
                call: "EPSSolve",
                code: -1,
                message: format!(
                    "{nconv} of {nev} eigenpairs converged after {its} iterations; ask fewer modes or raise -eps_max_it / -eps_ncv in PETSC_OPTIONS"
                ),
            });
        }
        let root = self.rank() == 0;
        let (mut kx, mut mx) = (Vector(ptr::null_mut()), Vector(ptr::null_mut()));
        let mut all = Vector(ptr::null_mut());
        let mut scatter = Scatter(ptr::null_mut());
        let mut values = Vec::with_capacity(nev);
        let mut vectors = if root { vec![0.0; n * nev] } else { Vec::new() };
        let mut errors = Vec::with_capacity(nev);
        let mut residuals = Vec::with_capacity(nev);
        // Every vector is kept (distributed) for the M-inner products with the later ones.
        let mut xs: Vec<Vector> = Vec::with_capacity(nev);
        let mut gram = vec![0.0; nev * nev];
        // SAFETY: as above; every vector has K's layout; the gathered one has n entries on rank
        // 0 and none elsewhere.
        unsafe {
            check("MatCreateVecs", MatCreateVecs(k.0, &mut kx.0, &mut mx.0))?;
            check(
                "VecScatterCreateToZero",
                VecScatterCreateToZero(kx.0, &mut scatter.0, &mut all.0),
            )?;
            for i in 0..nev {
                let mut x = Vector(ptr::null_mut());
                check("MatCreateVecs", MatCreateVecs(k.0, &mut x.0, ptr::null_mut()))?;
                let (mut kr, mut ki) = (0.0, 0.0);
                check(
                    "EPSGetEigenpair",
                    EPSGetEigenpair(eps.0, i as PetscInt, &mut kr, &mut ki, x.0, ptr::null_mut()),
                )?;
                let mut err = 0.0;
                check(
                    "EPSComputeError",
                    EPSComputeError(eps.0, i as PetscInt, EPS_ERROR_RELATIVE, &mut err),
                )?;
                // M-normalised (SLEPc normalises in the B-norm too; made exact here).
                check("MatMult", MatMult(m.0, x.0, mx.0))?;
                let mut xmx = 0.0;
                check("VecDot", VecDot(x.0, mx.0, &mut xmx))?;
                if xmx > 0.0 && xmx.is_finite() {
                    let s = 1.0 / xmx.sqrt();
                    check("VecScale", VecScale(x.0, s))?;
                    check("VecScale", VecScale(mx.0, s))?;
                }
                // ‖Kx − λMx‖ / ‖Kx‖.
                check("MatMult", MatMult(k.0, x.0, kx.0))?;
                let (mut kn, mut rn) = (0.0, 0.0);
                check("VecNorm", VecNorm(kx.0, NORM_2, &mut kn))?;
                check("VecAXPY", VecAXPY(kx.0, -kr, mx.0))?;
                check("VecNorm", VecNorm(kx.0, NORM_2, &mut rn))?;
                residuals.push(rn / kn);
                xs.push(x);
                // Row i of XᵀMX against every vector so far (itself included).
                let handles: Vec<PetscVec> = xs.iter().map(|v| v.0).collect();
                let mut row = vec![0.0; i + 1];
                check(
                    "VecMDot",
                    VecMDot(mx.0, (i + 1) as PetscInt, handles.as_ptr(), row.as_mut_ptr()),
                )?;
                for (j, &g) in row.iter().enumerate() {
                    gram[i * nev + j] = g;
                    gram[j * nev + i] = g;
                }
                let x = &xs[i];
                check(
                    "VecScatterBegin",
                    VecScatterBegin(scatter.0, x.0, all.0, INSERT_VALUES, SCATTER_FORWARD),
                )?;
                check(
                    "VecScatterEnd",
                    VecScatterEnd(scatter.0, x.0, all.0, INSERT_VALUES, SCATTER_FORWARD),
                )?;
                if root {
                    let mut len = 0;
                    check("VecGetLocalSize", VecGetLocalSize(all.0, &mut len))?;
                    let mut data: *const f64 = ptr::null();
                    check("VecGetArrayRead", VecGetArrayRead(all.0, &mut data))?;
                    if len as usize != n || data.is_null() {
                        return Err(size_err("gathered eigenvector has the wrong length"));
                    }
                    vectors[i * n..(i + 1) * n].copy_from_slice(std::slice::from_raw_parts(data, n));
                    check("VecRestoreArrayRead", VecRestoreArrayRead(all.0, &mut data))?;
                }
                values.push(kr);
                errors.push(err);
            }
        }
        Ok(Eigenpairs {
            values,
            vectors,
            relative_errors: errors,
            residuals,
            gram,
            iterations: its as usize,
            setup_s,
            solve_s: t1.elapsed().as_secs_f64(),
        })
    }
}

/// How the eigenpairs are found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Krylov–Schur in shift-invert, K − σM factored by MUMPS (Cholesky): the reference; its
    /// factor is the memory wall of very large parts.
    ShiftInvert,
    /// Jacobi–Davidson with an algebraic multigrid preconditioner (GAMG, given the rows'
    /// near-null space: rigid-body motions): no factorisation, memory about that of K and M.
    Iterative,
}

/// The near-null space set on K, orthonormalised (PETSc requires it), destroyed with its
/// vectors.
struct NearNull {
    space: MatNullSpace,
    vectors: Vec<Vector>,
}

impl NearNull {
    /// The `rows.near_null_count` vectors of `rows` (this rank's entries of each) set as K's
    /// near-null space.
    fn attach(k: &DistMatrix, rows: &LocalRows) -> Result<NearNull, PetscError> {
        let (count, local) = (rows.near_null_count, rows.hi - rows.lo);
        let mut vectors: Vec<Vector> = Vec::with_capacity(count);
        // SAFETY: vectors are created from K's layout (local length `local`), filled through
        // their arrays, and destroyed by their guards; the space is destroyed by `Drop`.
        unsafe {
            for v in 0..count {
                let mut x = Vector(ptr::null_mut());
                check("MatCreateVecs", MatCreateVecs(k.0, &mut x.0, ptr::null_mut()))?;
                let mut data: *mut f64 = ptr::null_mut();
                check("VecGetArray", VecGetArray(x.0, &mut data))?;
                let out = std::slice::from_raw_parts_mut(data, local);
                for (r, o) in out.iter_mut().enumerate() {
                    *o = rows.near_null[r * count + v];
                }
                check("VecRestoreArray", VecRestoreArray(x.0, &mut data))?;
                // Modified Gram–Schmidt against the vectors before it.
                for prev in &vectors {
                    let mut dot = 0.0;
                    check("VecDot", VecDot(x.0, prev.0, &mut dot))?;
                    check("VecAXPY", VecAXPY(x.0, -dot, prev.0))?;
                }
                let mut norm = 0.0;
                check("VecNormalize", VecNormalize(x.0, &mut norm))?;
                if !(norm > 0.0 && norm.is_finite()) {
                    return Err(PetscError {
                        call: "VecNormalize",
                        code: -1,
                        message: format!("near-null vector {v} is dependent on the others"),
                    });
                }
                vectors.push(x);
            }
            let handles: Vec<PetscVec> = vectors.iter().map(|v| v.0).collect();
            let mut space = ptr::null_mut();
            check(
                "MatNullSpaceCreate",
                MatNullSpaceCreate(
                    PETSC_COMM_WORLD,
                    PETSC_FALSE,
                    count as PetscInt,
                    handles.as_ptr(),
                    &mut space,
                ),
            )?;
            let near = NearNull { space, vectors };
            check("MatSetNearNullSpace", MatSetNearNullSpace(k.0, near.space))?;
            Ok(near)
        }
    }
}

impl Drop for NearNull {
    fn drop(&mut self) {
        if !self.space.is_null() {
            // SAFETY: created by MatNullSpaceCreate (K holds its own reference).
            unsafe { MatNullSpaceDestroy(&mut self.space) };
        }
        self.vectors.clear();
    }
}

/// Largest piece one MPI message carries, bytes.
const PIECE: usize = 1 << 30;

/// The tag of every message [`Slepc::send`] sends (PETSc's own messages travel on duplicated
/// communicators, so they cannot be confused with these).
const TAG: c_int = 7017;

fn mpi_check(call: &'static str, code: c_int) -> Result<(), PetscError> {
    if code == 0 {
        Ok(())
    } else {
        Err(PetscError {
            call,
            code,
            message: format!("MPI error {code}"),
        })
    }
}

/// Types whose values can travel between ranks as raw bytes: no padding, every bit pattern
/// valid.
pub trait Plain: Copy + Default + private::Sealed {}
impl Plain for f64 {}
impl Plain for u64 {}
impl Plain for i32 {}
impl Plain for u32 {}
mod private {
    pub trait Sealed {}
    impl Sealed for f64 {}
    impl Sealed for u64 {}
    impl Sealed for i32 {}
    impl Sealed for u32 {}
}

/// [`Plain`] types MPI can reduce (sum, min, max), with their MPI datatype.
pub trait Reducible: Plain {
    /// The predefined MPI datatype of `Self`.
    fn datatype() -> *const std::os::raw::c_void;
}

impl Reducible for i32 {
    fn datatype() -> *const std::os::raw::c_void {
        (&raw const ompi_mpi_int).cast()
    }
}

impl Reducible for f64 {
    fn datatype() -> *const std::os::raw::c_void {
        (&raw const ompi_mpi_double).cast()
    }
}

/// One rank's rows `lo..hi` of the full (both triangles) symmetric K and M, as CSR with global
/// column indices: what the rank inserts into PETSc's distributed matrices.
pub struct LocalRows {
    /// First row.
    pub lo: usize,
    /// One past the last row.
    pub hi: usize,
    /// Row pointers (hi − lo + 1).
    pub row_ptr: Vec<u64>,
    /// Column of each entry.
    pub cols: Vec<PetscInt>,
    /// K's values.
    pub k: Vec<f64>,
    /// M's values.
    pub m: Vec<f64>,
    /// For [`Method::Iterative`]: each row's entries of the near-null space vectors (the
    /// rigid-body motions), `near_null_count` per row; empty otherwise.
    pub near_null: Vec<f64>,
    /// Vectors in `near_null`.
    pub near_null_count: usize,
}

impl LocalRows {
    /// Rows `lo..hi` of the full matrices whose lower triangles `a` holds in a local numbering:
    /// local index `i` is global row and column `global[i]` (`a` may be a part of the whole
    /// problem holding every entry of the rows `lo..hi`; rows outside are skipped).
    pub fn from_lower(a: &SymmetricPair<'_>, global: &[u32], lo: usize, hi: usize) -> LocalRows {
        let n = a.n;
        let owned = |i: usize| (lo..hi).contains(&i);
        let g = |i: usize| global[i] as usize;
        // (i, j) for each stored (i ≥ j), and (j, i).
        let mut count = vec![0u64; hi - lo + 1];
        for j in 0..n {
            for &i in &a.row_idx[a.col_ptr[j]..a.col_ptr[j + 1]] {
                if owned(g(i)) {
                    count[g(i) - lo + 1] += 1;
                }
                if i != j && owned(g(j)) {
                    count[g(j) - lo + 1] += 1;
                }
            }
        }
        for r in 0..hi - lo {
            count[r + 1] += count[r];
        }
        let nnz = count[hi - lo] as usize;
        let mut fill: Vec<usize> = count.iter().map(|&c| c as usize).collect();
        let (mut cols, mut k, mut m) = (vec![0 as PetscInt; nnz], vec![0.0; nnz], vec![0.0; nnz]);
        for j in 0..n {
            for e in a.col_ptr[j]..a.col_ptr[j + 1] {
                let i = a.row_idx[e];
                let mut put = |row: usize, col: usize| {
                    let at = fill[row - lo];
                    (cols[at], k[at], m[at]) = (col as PetscInt, a.k[e], a.m[e]);
                    fill[row - lo] += 1;
                };
                if owned(g(i)) {
                    put(g(i), g(j));
                }
                if i != j && owned(g(j)) {
                    put(g(j), g(i));
                }
            }
        }
        LocalRows {
            lo,
            hi,
            row_ptr: count,
            cols,
            k,
            m,
            near_null: Vec::new(),
            near_null_count: 0,
        }
    }
}

impl Drop for Slepc {
    fn drop(&mut self) {
        // SAFETY: initialised by `init`; nothing PETSc-owned outlives the token (guards below
        // are dropped inside `lowest_eigenpairs`).
        unsafe { SlepcFinalize() };
    }
}

/// K and M of one symmetric problem, lower triangles (with diagonal) on one CSC pattern.
pub struct SymmetricPair<'a> {
    /// Order.
    pub n: usize,
    /// Column pointers (n + 1).
    pub col_ptr: &'a [usize],
    /// Row indices, ≥ the column in each column.
    pub row_idx: &'a [usize],
    /// K's values on the pattern.
    pub k: &'a [f64],
    /// M's values on the pattern.
    pub m: &'a [f64],
}

/// Eigenpairs from SLEPc.
pub struct Eigenpairs {
    /// Eigenvalues, nearest the target first.
    pub values: Vec<f64>,
    /// Column-major `n × nev`, M-normalised (rank 0 only; empty elsewhere).
    pub vectors: Vec<f64>,
    /// SLEPc's relative error estimate ‖Kx − λMx‖/‖λx‖ per pair.
    pub relative_errors: Vec<f64>,
    /// ‖Kx − λMx‖ / ‖Kx‖ per pair, as the pipeline's mode checks define it.
    pub residuals: Vec<f64>,
    /// XᵀMX, `nev × nev` (column-major, symmetric).
    pub gram: Vec<f64>,
    /// Krylov–Schur restarts.
    pub iterations: usize,
    /// Seconds in `EPSSetUp` (the factorisation).
    pub setup_s: f64,
    /// Seconds in `EPSSolve` and gathering.
    pub solve_s: f64,
}

/// K and M distributed over the ranks ([`Slepc::operators`]), kept for every eigen-solve of one
/// problem (the shift may change between solves; the matrices do not).
pub struct Operators {
    n: usize,
    k: DistMatrix,
    m: DistMatrix,
    _near_null: Option<NearNull>,
}

impl Operators {
    /// Order of the problem.
    pub fn size(&self) -> usize {
        self.n
    }
}

struct DistMatrix(Mat);

impl DistMatrix {
    /// An order-`n` distributed AIJ matrix of which this rank inserts `rows` (with `values` on
    /// their pattern), preallocated exactly.
    fn from_rows(world: MPI_Comm, n: usize, rows: &LocalRows, values: &[f64]) -> Result<DistMatrix, PetscError> {
        let (lo, hi) = (rows.lo, rows.hi);
        let owned = |c: PetscInt| (lo..hi).contains(&(c as usize));
        let span = |r: usize| rows.row_ptr[r] as usize..rows.row_ptr[r + 1] as usize;
        let mut d_nnz = vec![0 as PetscInt; hi - lo];
        let mut o_nnz = vec![0 as PetscInt; hi - lo];
        for r in 0..hi - lo {
            let d = rows.cols[span(r)].iter().filter(|&&c| owned(c)).count() as PetscInt;
            d_nnz[r] = d;
            o_nnz[r] = span(r).len() as PetscInt - d;
        }
        let mut mat = DistMatrix(ptr::null_mut());
        let local = (hi - lo) as PetscInt;
        // SAFETY: the matrix is created here and destroyed by the guard; index and value arrays
        // have the lengths passed.
        unsafe {
            check("MatCreate", MatCreate(world, &mut mat.0))?;
            check(
                "MatSetSizes",
                MatSetSizes(mat.0, local, local, n as PetscInt, n as PetscInt),
            )?;
            check("MatSetType", MatSetType(mat.0, c"aij".as_ptr()))?;
            check(
                "MatSeqAIJSetPreallocation",
                MatSeqAIJSetPreallocation(mat.0, 0, d_nnz.as_ptr()),
            )?;
            check(
                "MatMPIAIJSetPreallocation",
                MatMPIAIJSetPreallocation(mat.0, 0, d_nnz.as_ptr(), 0, o_nnz.as_ptr()),
            )?;
            let (mut rlo, mut rhi) = (0, 0);
            check("MatGetOwnershipRange", MatGetOwnershipRange(mat.0, &mut rlo, &mut rhi))?;
            if (rlo as usize, rhi as usize) != (lo, hi) {
                return Err(PetscError {
                    call: "MatGetOwnershipRange",
                    code: -1,
                    message: format!("rows {rlo}..{rhi} owned, {lo}..{hi} expected"),
                });
            }
            for r in 0..hi - lo {
                let row = (lo + r) as PetscInt;
                let e = span(r);
                check(
                    "MatSetValues",
                    MatSetValues(
                        mat.0,
                        1,
                        &row,
                        e.len() as PetscInt,
                        rows.cols[e.clone()].as_ptr(),
                        values[e].as_ptr(),
                        INSERT_VALUES,
                    ),
                )?;
            }
            check("MatAssemblyBegin", MatAssemblyBegin(mat.0, MAT_FINAL_ASSEMBLY))?;
            check("MatAssemblyEnd", MatAssemblyEnd(mat.0, MAT_FINAL_ASSEMBLY))?;
            check("MatSetOption", MatSetOption(mat.0, MAT_SYMMETRIC, PETSC_TRUE))?;
        }
        Ok(mat)
    }
}

impl Drop for DistMatrix {
    fn drop(&mut self) {
        if !self.0.is_null() {
            // SAFETY: created by MatCreate.
            unsafe { MatDestroy(&mut self.0) };
        }
    }
}

struct Eps(EPS);
impl Drop for Eps {
    fn drop(&mut self) {
        if !self.0.is_null() {
            // SAFETY: created by EPSCreate.
            unsafe { EPSDestroy(&mut self.0) };
        }
    }
}

struct Vector(PetscVec);
impl Drop for Vector {
    fn drop(&mut self) {
        if !self.0.is_null() {
            // SAFETY: created by MatCreateVecs / VecScatterCreateToZero.
            unsafe { VecDestroy(&mut self.0) };
        }
    }
}

struct Scatter(VecScatter);
impl Drop for Scatter {
    fn drop(&mut self) {
        if !self.0.is_null() {
            // SAFETY: created by VecScatterCreateToZero.
            unsafe { VecScatterDestroy(&mut self.0) };
        }
    }
}
