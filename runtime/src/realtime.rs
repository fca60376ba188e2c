//! Real-time hygiene for a session's haptic thread: it asks for SCHED_FIFO, the process locks
//! its memory (no page fault in the loop), and with two cores or more the haptic thread is
//! pinned to one. The drawing thread is left free: pinned to the other core of a 2-core machine
//! that also runs the browser, it could not use the haptic core's idle time (the FIFO thread
//! preempts it there anyway), and the viewer's frames suffered (docs/view.md). Each step is best
//! effort: what was not permitted is reported (one line, and in the session's statistics),
//! never fatal.

/// What the session got.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Realtime {
    /// The haptic thread runs under SCHED_FIFO (at [`PRIORITY`]).
    pub sched_fifo: bool,
    /// The process's memory is locked (mlockall, current and future).
    pub memory_locked: bool,
    /// The core the haptic thread is pinned to.
    pub haptic_core: Option<usize>,
    /// What was refused, and why (empty when everything was granted).
    pub refused: Vec<String>,
    /// With `--spin` under SCHED_FIFO and the kernel's real-time throttling on: the haptic
    /// thread sleeps until this many µs before each deadline instead of spinning the whole
    /// period (a FIFO thread that never sleeps is stopped for 50 ms of every second).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub spin_window_us: Option<u64>,
    /// The haptic thread's cores before pinning (restored afterwards).
    #[serde(skip)]
    original_cores: Vec<usize>,
}

/// SCHED_FIFO priority of the haptic thread: above ordinary threads, below the kernel's own
/// real-time threads (which run at 99 and 50).
pub const PRIORITY: i32 = 40;

/// Cores this process may run on.
fn allowed_cores() -> Vec<usize> {
    crate::os::allowed_cores()
}

/// Pins the calling thread to `core`.
fn pin(core: usize) -> Result<(), String> {
    crate::os::set_cores(&[core]).map_err(|e| format!("pinning to core {core}: {e}"))
}

/// Whether the kernel throttles real-time threads (`sched_rt_runtime_us` below
/// `sched_rt_period_us`; -1 turns it off): a SCHED_FIFO thread that never sleeps is then stopped
/// for the rest of each period (by default 50 ms of every second).
pub fn rt_throttled() -> bool {
    let read = |f: &str| {
        std::fs::read_to_string(format!("/proc/sys/kernel/{f}"))
            .ok()
            .and_then(|s| s.trim().parse::<i64>().ok())
    };
    match (read("sched_rt_runtime_us"), read("sched_rt_period_us")) {
        (Some(runtime), Some(period)) => runtime >= 0 && runtime < period,
        // Unknown: assume the default (throttled).
        _ => true,
    }
}

/// The core to pin the haptic thread to (the last allowed), when there are at least two.
pub fn haptic_core() -> Option<usize> {
    let c = allowed_cores();
    (c.len() >= 2).then(|| c[c.len() - 1])
}

/// The cores a compute beside a session may use: the process's, but [`haptic_core`] when
/// [`MIN_COMPUTE_CORES`] others are left (empty: no restriction). A compute on the haptic core can delay the haptic
/// thread's wake-ups even under SCHED_FIFO (kernel work done for it, such as page faults or
/// freeing its buffers, is not always preempted at once), and it shares the core's caches.
pub fn compute_cores() -> Vec<usize> {
    let c = crate::os::process_cores();
    match c.split_last() {
        // With fewer than three cores left the compute would lose too much: on the 2-core VM
        // a page's compute on one core took twice as long to a pullable part. There the
        // haptic thread's SCHED_FIFO is what keeps it first.
        Some((_, others)) if others.len() >= MIN_COMPUTE_CORES => others.to_vec(),
        _ => Vec::new(),
    }
}

/// A compute is kept off the haptic core only when this many cores are left to it.
pub const MIN_COMPUTE_CORES: usize = 3;

/// Called from the haptic thread before its loop: FIFO, memory lock, pin to `core`.
pub fn haptic_thread(core: Option<usize>) -> Realtime {
    let mut r = Realtime {
        original_cores: allowed_cores(),
        ..Default::default()
    };
    match crate::os::set_fifo(Some(PRIORITY)) {
        Ok(()) => r.sched_fifo = true,
        Err(e) => r.refused.push(format!(
            "SCHED_FIFO: {e} (run as root, or grant CAP_SYS_NICE / an rtprio limit)"
        )),
    }
    match crate::os::lock_memory(true) {
        Ok(()) => r.memory_locked = true,
        Err(e) => r
            .refused
            .push(format!("mlockall: {e} (raise the memlock limit, ulimit -l)")),
    }
    if let Some(c) = core {
        match pin(c) {
            Ok(()) => r.haptic_core = Some(c),
            Err(e) => r.refused.push(e),
        }
    }
    r
}

/// Undoes what [`haptic_thread`] did to the calling thread and process (the thread may be an
/// application's own, e.g. the main thread of `ves session`).
pub fn restore(r: &Realtime) {
    if r.sched_fifo {
        // Best effort: a thread that cannot go back keeps FIFO (nothing else to do).
        let _ = crate::os::set_fifo(None);
    }
    if r.memory_locked {
        let _ = crate::os::lock_memory(false);
    }
    if r.haptic_core.is_some() && !r.original_cores.is_empty() {
        let _ = crate::os::set_cores(&r.original_cores);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Whatever this machine permits, the report is consistent and the thread is back to normal
    /// scheduling afterwards.
    #[test]
    fn a_thread_gets_what_is_permitted_and_is_restored() {
        std::thread::spawn(|| {
            let r = haptic_thread(haptic_core());
            assert_eq!(
                r.sched_fifo,
                !r.refused.iter().any(|m| m.starts_with("SCHED_FIFO")),
                "{r:?}"
            );
            assert_eq!(crate::os::is_fifo(), r.sched_fifo, "{r:?}");
            if let Some(c) = r.haptic_core {
                assert_eq!(allowed_cores(), [c], "pinned: {r:?}");
            }
            let others = compute_cores();
            assert!(r.haptic_core.is_none_or(|c| !others.contains(&c)), "{others:?}, {r:?}");
            restore(&r);
            assert!(!crate::os::is_fifo(), "{r:?}");
            assert_eq!(allowed_cores(), r.original_cores, "affinity restored");
        })
        .join()
        .unwrap();
    }
}
