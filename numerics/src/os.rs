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

/// Kills this process's children (SIGKILL) and waits for each to end: its processes (a
/// compute, a mesh worker) stop writing into its folders before they are removed. Children are
/// found by their parent id in `/proc`.
pub fn kill_children() {
    let me = std::process::id();
    let Ok(entries) = std::fs::read_dir("/proc") else {
        return;
    };
    let children: Vec<libc::pid_t> = entries
        .flatten()
        .filter_map(|e| e.file_name().to_str()?.parse::<libc::pid_t>().ok())
        .filter(|&pid| {
            let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap_or_default();
            // The parent is the second field after the command name in parentheses.
            stat.rsplit_once(") ")
                .and_then(|(_, rest)| rest.split_whitespace().nth(1)?.parse::<u32>().ok())
                == Some(me)
        })
        .collect();
    for &pid in &children {
        // SAFETY: kill and waitpid on a child of this process; a null status pointer is allowed.
        unsafe {
            libc::kill(pid, libc::SIGKILL);
            libc::waitpid(pid, std::ptr::null_mut(), 0);
        }
    }
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

/// Lowers the scheduling priority of the whole process to nice 10 at least (its children
/// inherit it): a process already lower (nice 19, or SCHED_IDLE, where nice does not count)
/// stays as it is.
pub fn lower_process_priority() {
    if is_idle(0) {
        return;
    }
    // SAFETY: getpriority and setpriority on this process, no memory involved; errno is cleared
    // first because -1 is also a valid nice value.
    unsafe {
        *libc::__errno_location() = 0;
        let nice = libc::getpriority(libc::PRIO_PROCESS, 0);
        if nice == -1 && *libc::__errno_location() != 0 || nice < 10 {
            libc::setpriority(libc::PRIO_PROCESS, 0, 10);
        }
    }
}

/// Starts `command`'s process at the lowest ordinary priority from its first instruction (nice
/// 19), and on `cores` only (empty: wherever its parent may run). Both are inherited by what it
/// starts (gmsh's processes). Not SCHED_IDLE: measured beside other builds, a page's compute
/// under it took 128 s to a pullable part instead of 17–38 s, and with two busy loops at nice −8
/// (a browser's GPU process) it did not finish in 300 s; the haptic thread, under SCHED_FIFO,
/// preempts a nice-19 process as it would an idle one.
pub fn start_lowest(command: &mut std::process::Command, cores: &[usize]) {
    use std::os::unix::process::CommandExt;
    // The set is built here: the hook runs between fork and exec, where only async-signal-safe
    // calls (system calls, no allocation) are allowed.
    // SAFETY: a zeroed cpu_set_t is a valid empty set; CPU_SET writes within it (c is checked
    // against its size).
    let set = unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        for &c in cores.iter().filter(|&&c| c < libc::CPU_SETSIZE as usize) {
            libc::CPU_SET(c, &mut set);
        }
        set
    };
    let pin = !cores.is_empty();
    // SAFETY: the hook makes two system calls on the child itself (pid 0) with valid
    // arguments; it allocates nothing and touches no lock.
    unsafe {
        command.pre_exec(move || {
            if pin {
                // Best effort: a refused set leaves the parent's cores.
                libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set);
            }
            libc::setpriority(libc::PRIO_PROCESS, 0, 19);
            Ok(())
        });
    }
}

/// Whether process `pid` (0: the calling thread) runs under SCHED_IDLE.
pub fn is_idle(pid: u32) -> bool {
    let Ok(pid) = libc::pid_t::try_from(pid) else {
        return false;
    };
    // SAFETY: sched_getscheduler only reads the policy of the process named.
    unsafe { libc::sched_getscheduler(pid) == libc::SCHED_IDLE }
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The last core this thread may run on.
    fn some_core() -> usize {
        // SAFETY: a zeroed cpu_set_t is a valid empty set; sched_getaffinity fills it.
        unsafe {
            let mut set: libc::cpu_set_t = std::mem::zeroed();
            assert_eq!(
                libc::sched_getaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &mut set),
                0
            );
            (0..libc::CPU_SETSIZE as usize)
                .rev()
                .find(|&c| libc::CPU_ISSET(c, &set))
                .expect("a core")
        }
    }

    /// A process started lowest runs at nice 19 on the cores given, and so do the processes it
    /// starts and theirs (a compute's gmsh processes).
    #[test]
    fn a_child_started_lowest_and_its_descendants_run_at_nice_19_on_its_cores() {
        let core = some_core();
        // Each line: the allowed cores, then nice and policy (fields 19 and 41 of stat).
        let show = "grep '^Cpus_allowed_list' /proc/self/status; cut -d' ' -f19,41 /proc/self/stat";
        let mut command = std::process::Command::new("sh");
        command.arg("-c").arg(format!("{show}; sh -c \"{show}\""));
        start_lowest(&mut command, &[core]);
        let out = command.output().expect("sh runs");
        let text = String::from_utf8_lossy(&out.stdout);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 4, "{text}");
        for pair in lines.chunks(2) {
            assert_eq!(
                pair[0].split_whitespace().last(),
                Some(core.to_string().as_str()),
                "{text}"
            );
            // Nice 19 under SCHED_OTHER (0).
            assert_eq!(pair[1], "19 0", "{text}");
        }
    }
}
