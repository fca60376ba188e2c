//! LAPACK reports an illegal argument through XERBLA, and the reference XERBLA (Debian's
//! liblapack, which ARPACK calls) prints a line and `STOP`s the program with exit status 0: a
//! scene with density = 1e120 ended `ves` silently "successfully", and a whole `ves batch` with
//! it. This crate defines XERBLA itself; the executable's definition takes precedence over the
//! shared library's (the binaries export it: see this crate's `build.rs` and `pipeline/build.rs`).
//! The error is recorded and the caller turns it into an error after the LAPACK-using call
//! returns.

use std::os::raw::{c_char, c_int};
use std::sync::Mutex;

static LAST: Mutex<Option<String>> = Mutex::new(None);

/// XERBLA: records "routine NAME: argument INFO had an illegal value" and returns to LAPACK,
/// which then returns to its caller with the error in its own `info`.
///
/// # Safety
/// Called by Fortran: `name` points to `name_len` bytes (not NUL-terminated), `info` to an int.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn xerbla_(name: *const c_char, info: *const c_int, name_len: usize) {
    let routine = if name.is_null() {
        String::from("?")
    } else {
        // SAFETY: Fortran passes the CHARACTER's length; LAPACK names are at most 32 bytes.
        let bytes = unsafe { std::slice::from_raw_parts(name.cast::<u8>(), name_len.min(32)) };
        String::from_utf8_lossy(bytes).trim().to_string()
    };
    // SAFETY: LAPACK passes a valid pointer to INFO.
    let arg = if info.is_null() { 0 } else { unsafe { *info } };
    let msg = format!("LAPACK {routine}: argument {arg} had an illegal value");
    *LAST.lock().unwrap_or_else(|p| p.into_inner()) = Some(msg);
}

/// Takes the error XERBLA recorded since the last call, if any.
pub fn take_error() -> Option<String> {
    LAST.lock().unwrap_or_else(|p| p.into_inner()).take()
}

#[cfg(test)]
mod tests {
    use crate::sys::dlascl_;
    use std::os::raw::c_int;

    /// cfrom = 0 is illegal (argument 4): what density = 1e120 provoked inside ARPACK. The
    /// process must still be running afterwards, with the error recorded.
    #[test]
    fn an_illegal_lapack_argument_is_recorded_not_fatal() {
        let (zero, one, m, mut info) = (0 as c_int, 1 as c_int, 1 as c_int, 0 as c_int);
        let (cfrom, cto) = (0.0f64, 1.0f64);
        let mut a = [1.0f64];
        // SAFETY: valid pointers for a 1×1 matrix; the type is one character.
        unsafe {
            dlascl_(
                c"G".as_ptr(),
                &zero,
                &zero,
                &cfrom,
                &cto,
                &m,
                &one,
                a.as_mut_ptr(),
                &one,
                &mut info,
                1,
            );
        }
        assert_eq!(info, -4);
        let e = super::take_error().expect("XERBLA recorded the error");
        assert!(e.contains("DLASCL") && e.contains("argument 4"), "{e}");
        assert!(super::take_error().is_none());
    }
}
