//! Raw declarations of ARPACK-NG's C bindings (`arpack/arpack.h`, `a_int` = 32-bit int on
//! Debian 12). The `_c` variants take scalars by value and NUL-terminated strings, which avoids
//! gfortran's hidden string-length arguments.

use std::os::raw::{c_char, c_double, c_int};

#[link(name = "arpack")]
unsafe extern "C" {
    pub fn dsaupd_c(
        ido: *mut c_int,
        bmat: *const c_char,
        n: c_int,
        which: *const c_char,
        nev: c_int,
        tol: c_double,
        resid: *mut c_double,
        ncv: c_int,
        v: *mut c_double,
        ldv: c_int,
        iparam: *mut c_int,
        ipntr: *mut c_int,
        workd: *mut c_double,
        workl: *mut c_double,
        lworkl: c_int,
        info: *mut c_int,
    );
    pub fn dseupd_c(
        rvec: c_int,
        howmny: *const c_char,
        select: *const c_int,
        d: *mut c_double,
        z: *mut c_double,
        ldz: c_int,
        sigma: c_double,
        bmat: *const c_char,
        n: c_int,
        which: *const c_char,
        nev: c_int,
        tol: c_double,
        resid: *mut c_double,
        ncv: c_int,
        v: *mut c_double,
        ldv: c_int,
        iparam: *mut c_int,
        ipntr: *mut c_int,
        workd: *mut c_double,
        workl: *mut c_double,
        lworkl: c_int,
        info: *mut c_int,
    );
}

// LAPACK itself, for XERBLA's test only: an illegal argument must come back, not end the test.
#[cfg(test)]
#[link(name = "lapack")]
unsafe extern "C" {
    pub fn dlascl_(
        ty: *const c_char,
        kl: *const c_int,
        ku: *const c_int,
        cfrom: *const f64,
        cto: *const f64,
        m: *const c_int,
        n: *const c_int,
        a: *mut f64,
        lda: *const c_int,
        info: *mut c_int,
        ty_len: usize,
    );
}
