//! The operating-system calls the library makes (libc), each behind a safe function: the only
//! `unsafe` of this crate outside the FFI wrappers. The `ves` binary uses them too.

use std::os::fd::AsRawFd;

/// The address-space limit (RLIMIT_AS) in bytes; None when unlimited or unknown.
pub fn address_space_limit() -> Option<u64> {
    let mut limit = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: getrlimit writes the struct given; nothing else is touched.
    if unsafe { libc::getrlimit(libc::RLIMIT_AS, &mut limit) } != 0 || limit.rlim_cur == libc::RLIM_INFINITY {
        return None;
    }
    Some(limit.rlim_cur)
}

/// Gives the free heap pages back to the system (glibc keeps them, in every thread's arena).
pub fn trim_heap() {
    // SAFETY: malloc_trim only releases pages that malloc holds free; no pointer is touched.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// Takes an exclusive advisory lock on `file` (flock), waiting for it when `wait`; false when
/// another holder has it (and `wait` is off) or the call fails.
pub fn lock_exclusive(file: &impl AsRawFd, wait: bool) -> bool {
    let op = if wait {
        libc::LOCK_EX
    } else {
        libc::LOCK_EX | libc::LOCK_NB
    };
    // SAFETY: flock on a descriptor the caller owns (borrowed for the call).
    unsafe { libc::flock(file.as_raw_fd(), op) == 0 }
}

/// This process's effective user id.
pub fn effective_uid() -> u32 {
    // SAFETY: geteuid has no preconditions.
    unsafe { libc::geteuid() }
}

/// Whether process `pid` exists (kill(pid, 0): ESRCH means gone; EPERM, another user's).
pub fn process_runs(pid: u32) -> bool {
    let Ok(pid) = libc::pid_t::try_from(pid) else {
        return false;
    };
    // SAFETY: signal 0 only checks that the process exists.
    let found = unsafe { libc::kill(pid, 0) } == 0;
    found || std::io::Error::last_os_error().raw_os_error() == Some(libc::EPERM)
}

/// This process is killed when its parent dies (Linux's parent-death signal).
pub fn die_with_parent() {
    // SAFETY: prctl with these arguments only sets this process's parent-death signal.
    unsafe { libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL as libc::c_ulong, 0, 0, 0) };
}

/// This process's parent's id.
pub fn parent_pid() -> u32 {
    // SAFETY: getppid has no arguments and cannot fail.
    unsafe { libc::getppid() as u32 }
}

/// Lowers the scheduling priority (nice 10) of the calling thread only.
pub fn lower_thread_priority() {
    // SAFETY: setpriority on this thread's own id (Linux: PRIO_PROCESS with a thread id sets
    // that thread's nice value), no memory involved.
    unsafe {
        let tid = libc::gettid();
        libc::setpriority(libc::PRIO_PROCESS, tid as libc::id_t, 10);
    }
}

/// Lowers the scheduling priority (nice 10) of the whole process (its children inherit it).
pub fn lower_process_priority() {
    // SAFETY: setpriority on this process, no memory involved.
    unsafe { libc::setpriority(libc::PRIO_PROCESS, 0, 10) };
}

/// Makes a FIFO at `path` (mode 0600): the tests' stand-in for an input that would block a
/// reader.
pub fn make_fifo(path: &std::path::Path) -> std::io::Result<()> {
    let c = std::ffi::CString::new(path.as_os_str().as_encoded_bytes())
        .map_err(|_| std::io::Error::new(std::io::ErrorKind::InvalidInput, "a NUL in the path"))?;
    // SAFETY: a valid NUL-terminated path.
    if unsafe { libc::mkfifo(c.as_ptr(), 0o600) } != 0 {
        return Err(std::io::Error::last_os_error());
    }
    Ok(())
}
