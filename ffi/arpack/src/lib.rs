//! Safe layer over ARPACK's symmetric driver (`dsaupd`/`dseupd`) in generalized shift-invert
//! mode (mode 3): the eigenvalues λ of K φ = λ M φ nearest a shift σ, given two operators the
//! caller supplies, `y = (K − σM)⁻¹ x` and `y = M x`.
//!
//! ARPACK keeps its iteration state in Fortran `SAVE` variables, so two runs at once in one
//! process corrupt each other (seen as info = 3 when two tests solved in parallel): one lock
//! serialises whole runs.
//!
//! LAPACK, which ARPACK calls, reports an illegal argument through XERBLA; the reference one
//! ends the process. [`xerbla`] defines a non-fatal one and the solver returns what it recorded
//! as [`ArpackError::Lapack`].

mod sys;
pub mod xerbla;

use std::os::raw::c_int;
use std::sync::Mutex;

static ARPACK_LOCK: Mutex<()> = Mutex::new(());

/// ARPACK failed; the text explains the `info` code in words.
#[derive(Debug, thiserror::Error)]
pub enum ArpackError {
    /// A size or parameter does not fit ARPACK's limits.
    #[error("invalid ARPACK input: {0}")]
    Input(String),
    /// LAPACK, inside ARPACK, was handed an illegal value (its XERBLA was called): the problem's
    /// numbers left double precision.
    #[error("{0}: the problem's numbers are out of double-precision range; check the material constants and units")]
    Lapack(String),
    /// `dsaupd` returned an error code.
    #[error("ARPACK dsaupd failed (info = {info}): {reason}")]
    Saupd {
        /// ARPACK's info code.
        info: i32,
        /// What it means.
        reason: &'static str,
    },
    /// The iteration limit was reached before all requested eigenpairs converged.
    #[error(
        "ARPACK did not converge: {converged} of {requested} eigenpairs after {iterations} restarts \
         (raise the iteration limit or the Lanczos basis size, or request fewer modes)"
    )]
    NotConverged {
        /// Eigenpairs that converged.
        converged: usize,
        /// Eigenpairs requested.
        requested: usize,
        /// Restarts done.
        iterations: usize,
    },
    /// `dseupd` returned an error code.
    #[error("ARPACK dseupd failed (info = {info}): {reason}")]
    Seupd {
        /// ARPACK's info code.
        info: i32,
        /// What it means.
        reason: &'static str,
    },
    /// The caller's operator failed (e.g. a non-finite solve).
    #[error("operator failed inside the ARPACK loop: {0}")]
    Operator(String),
}

fn saupd_reason(info: i32) -> &'static str {
    match info {
        3 => "no shifts could be applied during an implicit restart; increase the Lanczos basis size (ncv)",
        -1 => "n must be positive",
        -2 => "nev must be positive",
        -3 => "ncv must satisfy nev < ncv <= n",
        -4 => "the maximum number of iterations must be positive",
        -5 => "`which` is not one of LM, SM, LA, SA, BE",
        -6 => "bmat must be I or G",
        -7 => "the private work array workl is too short",
        -8 => "LAPACK's tridiagonal eigen-solver (dsteqr) failed",
        -9 => "the starting vector is zero",
        -10 => "iparam[6] (mode) must be 1 to 5",
        -11 => "mode 1 is incompatible with bmat = G",
        -12 => "iparam[0] must be 0 or 1",
        -13 => "nev and which = BE are incompatible",
        -9999 => "could not build a Lanczos factorization (the operator may be singular or indefinite)",
        _ => "unknown ARPACK error code",
    }
}

fn seupd_reason(info: i32) -> &'static str {
    match info {
        -1 => "n must be positive",
        -2 => "nev must be positive",
        -3 => "ncv must satisfy nev < ncv <= n",
        -5 => "`which` is not one of LM, SM, LA, SA, BE",
        -6 => "bmat must be I or G",
        -7 => "the private work array workl is too short",
        -8 => "LAPACK's tridiagonal eigen-solver (dsteqr) failed",
        -9 => "the starting vector is zero",
        -10 => "iparam[6] (mode) must be 1 to 5",
        -11 => "mode 1 is incompatible with bmat = G",
        -12 => "nev and which = BE are incompatible",
        -14 => "dsaupd did not find any eigenvalue to sufficient accuracy",
        -15 => "howmny must be A or S when vectors are wanted",
        -16 => "howmny = S is not implemented",
        -17 => "dseupd found a different number of converged Ritz values than dsaupd",
        _ => "unknown ARPACK error code",
    }
}

/// Settings of one shift-invert run.
#[derive(Clone, Debug)]
pub struct ShiftInvert {
    /// Number of eigenpairs wanted (those nearest `sigma`).
    pub nev: usize,
    /// Lanczos basis size; `0` chooses `min(n, max(2 nev + 1, 20))`.
    pub ncv: usize,
    /// Shift σ (the same one the caller factorised K − σM with).
    pub sigma: f64,
    /// Relative accuracy of the Ritz values (ARPACK `tol`; 0 = machine precision).
    pub tol: f64,
    /// Maximum number of implicit restarts.
    pub max_restarts: usize,
}

/// Eigenpairs found.
#[derive(Clone, Debug)]
pub struct Eigenpairs {
    /// Eigenvalues λ, ascending.
    pub values: Vec<f64>,
    /// Eigenvectors, column-major `n × nev`, in the order of `values`, M-orthonormal.
    pub vectors: Vec<f64>,
    /// Restarts ARPACK took.
    pub restarts: usize,
    /// Applications of (K − σM)⁻¹.
    pub solves: usize,
}

/// Deterministic start vector, so two runs on the same matrices give the same modes.
fn start_vector(n: usize) -> Vec<f64> {
    let mut s: u64 = 0x9E37_79B9_7F4A_7C15;
    (0..n)
        .map(|_| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        })
        .collect()
}

fn as_int(what: &str, v: usize) -> Result<c_int, ArpackError> {
    c_int::try_from(v).map_err(|_| ArpackError::Input(format!("{what} = {v} exceeds ARPACK's 32-bit index range")))
}

/// Solves K φ = λ M φ for the `nev` eigenvalues nearest σ (ARPACK mode 3).
///
/// `solve(x, y)` must set `y = (K − σM)⁻¹ x`; `mass(x, y)` must set `y = M x`. Either may
/// report failure, which stops the iteration.
pub fn shift_invert<S, B>(n: usize, cfg: &ShiftInvert, mut solve: S, mut mass: B) -> Result<Eigenpairs, ArpackError>
where
    S: FnMut(&[f64], &mut [f64]) -> Result<(), String>,
    B: FnMut(&[f64], &mut [f64]) -> Result<(), String>,
{
    let nev = cfg.nev;
    if nev == 0 || nev >= n {
        return Err(ArpackError::Input(format!(
            "{nev} eigenpairs requested of a problem of size {n}: need 0 < nev < n"
        )));
    }
    let ncv = if cfg.ncv == 0 {
        (2 * nev + 1).max(20).min(n)
    } else {
        cfg.ncv.min(n)
    };
    if ncv <= nev {
        return Err(ArpackError::Input(format!(
            "Lanczos basis size {ncv} must exceed nev = {nev}"
        )));
    }
    let _serial = ARPACK_LOCK.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    let lworkl = ncv * (ncv + 8);
    let (n_i, nev_i, ncv_i, lworkl_i) = (
        as_int("n", n)?,
        as_int("nev", nev)?,
        as_int("ncv", ncv)?,
        as_int("lworkl", lworkl)?,
    );
    let max_restarts = as_int("max_restarts", cfg.max_restarts.max(1))?;

    let mut resid = start_vector(n);
    let mut v = vec![0.0; n * ncv];
    let mut workd = vec![0.0; 3 * n];
    let mut workl = vec![0.0; lworkl];
    let mut iparam = [0 as c_int; 11];
    iparam[0] = 1; // exact shifts
    iparam[2] = max_restarts;
    iparam[6] = 3; // generalized shift-invert
    let mut ipntr = [0 as c_int; 11];
    let mut ido: c_int = 0;
    let mut info: c_int = 1; // resid holds our start vector
    let bmat = c"G";
    let which = c"LM";
    let mut tmp = vec![0.0; n];
    let mut solves = 0usize;
    let _ = crate::xerbla::take_error();

    loop {
        // SAFETY: every buffer has the length ARPACK documents for these n, ncv, lworkl.
        unsafe {
            sys::dsaupd_c(
                &mut ido,
                bmat.as_ptr(),
                n_i,
                which.as_ptr(),
                nev_i,
                cfg.tol,
                resid.as_mut_ptr(),
                ncv_i,
                v.as_mut_ptr(),
                n_i,
                iparam.as_mut_ptr(),
                ipntr.as_mut_ptr(),
                workd.as_mut_ptr(),
                workl.as_mut_ptr(),
                lworkl_i,
                &mut info,
            );
        }
        if let Some(e) = crate::xerbla::take_error() {
            return Err(ArpackError::Lapack(e));
        }
        // ipntr is 1-based into workd.
        let at = |k: usize| (ipntr[k] - 1) as usize;
        match ido {
            -1 => {
                // y = (K − σM)⁻¹ M x
                let (x0, y0) = (at(0), at(1));
                mass(&workd[x0..x0 + n], &mut tmp).map_err(ArpackError::Operator)?;
                solve(&tmp, &mut workd[y0..y0 + n]).map_err(ArpackError::Operator)?;
                solves += 1;
            }
            1 => {
                // y = (K − σM)⁻¹ z with z = M x already at ipntr[2]
                let (y0, z0) = (at(1), at(2));
                tmp.copy_from_slice(&workd[z0..z0 + n]);
                solve(&tmp, &mut workd[y0..y0 + n]).map_err(ArpackError::Operator)?;
                solves += 1;
            }
            2 => {
                let (x0, y0) = (at(0), at(1));
                tmp.copy_from_slice(&workd[x0..x0 + n]);
                mass(&tmp, &mut workd[y0..y0 + n]).map_err(ArpackError::Operator)?;
            }
            99 => break,
            other => {
                return Err(ArpackError::Operator(format!(
                    "unexpected ARPACK request ido = {other}"
                )));
            }
        }
    }
    let restarts = iparam[2].max(0) as usize;
    match info {
        0 => {}
        1 => {
            return Err(ArpackError::NotConverged {
                converged: iparam[4].max(0) as usize,
                requested: nev,
                iterations: restarts,
            });
        }
        _ => {
            return Err(ArpackError::Saupd {
                info,
                reason: saupd_reason(info),
            });
        }
    }

    let select = vec![0 as c_int; ncv];
    let mut d = vec![0.0; nev];
    let mut z = vec![0.0; n * nev];
    let mut info_e: c_int = 0;
    // SAFETY: buffers as in dsaupd plus d (nev), z (n × nev), select (ncv).
    unsafe {
        sys::dseupd_c(
            1,
            c"A".as_ptr(),
            select.as_ptr(),
            d.as_mut_ptr(),
            z.as_mut_ptr(),
            n_i,
            cfg.sigma,
            bmat.as_ptr(),
            n_i,
            which.as_ptr(),
            nev_i,
            cfg.tol,
            resid.as_mut_ptr(),
            ncv_i,
            v.as_mut_ptr(),
            n_i,
            iparam.as_mut_ptr(),
            ipntr.as_mut_ptr(),
            workd.as_mut_ptr(),
            workl.as_mut_ptr(),
            lworkl_i,
            &mut info_e,
        );
    }
    if let Some(e) = crate::xerbla::take_error() {
        return Err(ArpackError::Lapack(e));
    }
    if info_e != 0 {
        return Err(ArpackError::Seupd {
            info: info_e,
            reason: seupd_reason(info_e),
        });
    }
    let converged = (iparam[4].max(0) as usize).min(nev);
    if converged < nev {
        return Err(ArpackError::NotConverged {
            converged,
            requested: nev,
            iterations: restarts,
        });
    }
    // Sort ascending (dseupd's order depends on mode and `which`).
    let mut order: Vec<usize> = (0..nev).collect();
    order.sort_by(|&a, &b| d[a].total_cmp(&d[b]));
    let values = order.iter().map(|&k| d[k]).collect();
    let mut vectors = Vec::with_capacity(n * nev);
    for &k in &order {
        vectors.extend_from_slice(&z[k * n..(k + 1) * n]);
    }
    Ok(Eigenpairs {
        values,
        vectors,
        restarts,
        solves,
    })
}
