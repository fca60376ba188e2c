//! Safe layer over SLEPc/PETSc: an initialisation token ([`Slepc`], finalised on `Drop`), and a
//! generalized symmetric eigen-solve K x = λ M x in shift-invert around a target with a parallel
//! direct factorisation (MUMPS Cholesky), over every rank of `PETSC_COMM_WORLD`.
//!
//! Each rank inserts the rows it owns into distributed AIJ matrices; the eigenvectors are
//! gathered to every rank. Every PETSc error code becomes a [`PetscError`] carrying PETSc's own
//! message (its printing error handler is replaced by the silent one). Options can still be
//! overridden from the environment (`PETSC_OPTIONS="-eps_ncv 80 -st_pc_factor_mat_solver_type
//! superlu_dist"`), since the solver calls `EPSSetFromOptions`.

/// Raw declarations (public so a test can check them against the installed headers).
pub mod sys;

use std::ffi::{CStr, CString};
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
    pub fn sum_over_ranks(&self, values: &mut [i32]) -> Result<(), PetscError> {
        self.all_reduce(values, &raw const ompi_mpi_op_sum)
    }

    /// Element-wise minimum of `values` over every rank, in place. Collective.
    pub fn min_over_ranks(&self, values: &mut [i32]) -> Result<(), PetscError> {
        self.all_reduce(values, &raw const ompi_mpi_op_min)
    }

    fn all_reduce(&self, values: &mut [i32], op: *const u8) -> Result<(), PetscError> {
        let count = c_int::try_from(values.len()).map_err(|_| PetscError {
            call: "MPI_Allreduce",
            code: -1,
            message: format!("{} values is more than one call reduces", values.len()),
        })?;
        let send = values.to_vec();
        // SAFETY: MPI is initialised (a token exists); both buffers hold `count` ints; the
        // handles are Open MPI's predefined ones (MPI_INT, MPI_SUM/MPI_MIN), checked against
        // mpi.h by the header test.
        let code = unsafe {
            MPI_Allreduce(
                send.as_ptr().cast(),
                values.as_mut_ptr().cast(),
                count,
                (&raw const ompi_mpi_int).cast(),
                op.cast(),
                PETSC_COMM_WORLD,
            )
        };
        if code == 0 {
            Ok(())
        } else {
            Err(PetscError {
                call: "MPI_Allreduce",
                code,
                message: format!("MPI error {code}"),
            })
        }
    }

    /// Ends every process of the job with exit status `code` (`MPI_Abort`): for an error on
    /// some ranks only, which would leave the others waiting in a collective call forever.
    pub fn abort(&self, code: i32) -> ! {
        // SAFETY: MPI is initialised; MPI_Abort does not return (Open MPI kills every rank).
        unsafe { MPI_Abort(PETSC_COMM_WORLD, code) };
        std::process::exit(code)
    }

    /// The `nev` eigenpairs of K x = λ M x nearest `target` (below the spectrum: the lowest),
    /// by Krylov–Schur in shift-invert with a MUMPS Cholesky factorisation of K − σM. Every
    /// rank must call it with the same arguments (it is collective); every rank gets all the
    /// eigenpairs: values ascending by distance to the target, vectors column-major `n × nev`.
    pub fn lowest_eigenpairs(
        &self,
        a: &SymmetricPair<'_>,
        nev: usize,
        target: f64,
        tol: f64,
    ) -> Result<Eigenpairs, PetscError> {
        let n = a.n;
        let size_err = |what: &str| PetscError {
            call: "lowest_eigenpairs",
            code: -1,
            message: what.to_string(),
        };
        if n == 0 || nev == 0 || nev >= n || n > i32::MAX as usize / 2 {
            return Err(size_err(&format!("{nev} eigenpairs of an order-{n} problem")));
        }
        let world = unsafe { PETSC_COMM_WORLD };
        let (rank, size) = (self.rank(), self.size().max(1));
        // PETSc's default split: the first n % size ranks get one row more.
        let local = n / size + usize::from(rank < n % size);
        let lo = rank * (n / size) + rank.min(n % size);
        let hi = lo + local;
        let k = DistMatrix::from_lower(world, a, a.k, lo, hi)?;
        let m = DistMatrix::from_lower(world, a, a.m, lo, hi)?;
        let mut eps = Eps(ptr::null_mut());
        let stype = CString::new("sinvert").expect("static");
        let (ksp_type, pc_type, solver) = (c"preonly", c"cholesky", c"mumps");
        let t0 = std::time::Instant::now();
        // SAFETY: every handle below is created here, checked, and destroyed by its guard.
        unsafe {
            check("EPSCreate", EPSCreate(world, &mut eps.0))?;
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
            check("EPSSetTolerances", EPSSetTolerances(eps.0, tol, 1000))?;
            let mut st = ptr::null_mut();
            check("EPSGetST", EPSGetST(eps.0, &mut st))?;
            check("STSetType", STSetType(st, stype.as_ptr()))?;
            check("STSetMatStructure", STSetMatStructure(st, SAME_NONZERO_PATTERN))?;
            let mut ksp = ptr::null_mut();
            check("STGetKSP", STGetKSP(st, &mut ksp))?;
            check("KSPSetType", KSPSetType(ksp, ksp_type.as_ptr()))?;
            let mut pc = ptr::null_mut();
            check("KSPGetPC", KSPGetPC(ksp, &mut pc))?;
            check("PCSetType", PCSetType(pc, pc_type.as_ptr()))?;
            check(
                "PCFactorSetMatSolverType",
                PCFactorSetMatSolverType(pc, solver.as_ptr()),
            )?;
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
        let mut x = Vector(ptr::null_mut());
        let mut all = Vector(ptr::null_mut());
        let mut scatter = Scatter(ptr::null_mut());
        let mut values = Vec::with_capacity(nev);
        let mut vectors = vec![0.0; n * nev];
        let mut errors = Vec::with_capacity(nev);
        // SAFETY: as above; the gathered vector has n entries on every rank.
        unsafe {
            check("MatCreateVecs", MatCreateVecs(k.0, &mut x.0, ptr::null_mut()))?;
            check(
                "VecScatterCreateToAll",
                VecScatterCreateToAll(x.0, &mut scatter.0, &mut all.0),
            )?;
            for i in 0..nev {
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
                check(
                    "VecScatterBegin",
                    VecScatterBegin(scatter.0, x.0, all.0, INSERT_VALUES, SCATTER_FORWARD),
                )?;
                check(
                    "VecScatterEnd",
                    VecScatterEnd(scatter.0, x.0, all.0, INSERT_VALUES, SCATTER_FORWARD),
                )?;
                let mut len = 0;
                check("VecGetSize", VecGetSize(all.0, &mut len))?;
                let mut data: *const f64 = ptr::null();
                check("VecGetArrayRead", VecGetArrayRead(all.0, &mut data))?;
                if len as usize != n || data.is_null() {
                    return Err(size_err("gathered eigenvector has the wrong length"));
                }
                vectors[i * n..(i + 1) * n].copy_from_slice(std::slice::from_raw_parts(data, n));
                check("VecRestoreArrayRead", VecRestoreArrayRead(all.0, &mut data))?;
                values.push(kr);
                errors.push(err);
            }
        }
        Ok(Eigenpairs {
            values,
            vectors,
            relative_errors: errors,
            iterations: its as usize,
            setup_s,
            solve_s: t1.elapsed().as_secs_f64(),
        })
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
    /// Column-major `n × nev`.
    pub vectors: Vec<f64>,
    /// SLEPc's relative error estimate ‖Kx − λMx‖/‖λx‖ per pair.
    pub relative_errors: Vec<f64>,
    /// Krylov–Schur restarts.
    pub iterations: usize,
    /// Seconds in `EPSSetUp` (the factorisation).
    pub setup_s: f64,
    /// Seconds in `EPSSolve` and gathering.
    pub solve_s: f64,
}

struct DistMatrix(Mat);

impl DistMatrix {
    /// The full symmetric matrix from its lower triangle; this rank inserts rows lo..hi.
    fn from_lower(
        world: MPI_Comm,
        a: &SymmetricPair<'_>,
        values: &[f64],
        lo: usize,
        hi: usize,
    ) -> Result<DistMatrix, PetscError> {
        let n = a.n;
        let owned = |i: usize| (lo..hi).contains(&i);
        // Rows lo..hi of the full matrix, as CSR: (i, j) for each stored (i ≥ j), and (j, i).
        let mut count = vec![0usize; hi - lo + 1];
        for j in 0..n {
            for &i in &a.row_idx[a.col_ptr[j]..a.col_ptr[j + 1]] {
                if owned(i) {
                    count[i - lo + 1] += 1;
                }
                if i != j && owned(j) {
                    count[j - lo + 1] += 1;
                }
            }
        }
        for r in 0..hi - lo {
            count[r + 1] += count[r];
        }
        let mut fill = count.clone();
        let mut cols = vec![0 as PetscInt; count[hi - lo]];
        let mut vals = vec![0.0; count[hi - lo]];
        for j in 0..n {
            let range = a.col_ptr[j]..a.col_ptr[j + 1];
            for (&i, &v) in a.row_idx[range.clone()].iter().zip(&values[range]) {
                if owned(i) {
                    cols[fill[i - lo]] = j as PetscInt;
                    vals[fill[i - lo]] = v;
                    fill[i - lo] += 1;
                }
                if i != j && owned(j) {
                    cols[fill[j - lo]] = i as PetscInt;
                    vals[fill[j - lo]] = v;
                    fill[j - lo] += 1;
                }
            }
        }
        let mut d_nnz = vec![0 as PetscInt; hi - lo];
        let mut o_nnz = vec![0 as PetscInt; hi - lo];
        for r in 0..hi - lo {
            for &c in &cols[count[r]..count[r + 1]] {
                if owned(c as usize) {
                    d_nnz[r] += 1;
                } else {
                    o_nnz[r] += 1;
                }
            }
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
                let (s, e) = (count[r], count[r + 1]);
                check(
                    "MatSetValues",
                    MatSetValues(
                        mat.0,
                        1,
                        &row,
                        (e - s) as PetscInt,
                        cols[s..e].as_ptr(),
                        vals[s..e].as_ptr(),
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
            // SAFETY: created by MatCreateVecs / VecScatterCreateToAll.
            unsafe { VecDestroy(&mut self.0) };
        }
    }
}

struct Scatter(VecScatter);
impl Drop for Scatter {
    fn drop(&mut self) {
        if !self.0.is_null() {
            // SAFETY: created by VecScatterCreateToAll.
            unsafe { VecScatterDestroy(&mut self.0) };
        }
    }
}
