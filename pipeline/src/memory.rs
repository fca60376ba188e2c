//! This process's memory: resident and peak resident size (Linux /proc), and giving malloc's
//! free pages back to the system between stages.

/// Peak resident set size of this process (Linux `/proc/self/status`, `VmHWM`), bytes.
pub fn peak_rss_bytes() -> u64 {
    status_kb("VmHWM:") * 1024
}

/// Resident memory now, bytes (0 where /proc is not available).
pub fn rss_bytes() -> u64 {
    status_kb("VmRSS:") * 1024
}

/// Memory the system can still give without swapping (Linux `/proc/meminfo`, `MemAvailable`),
/// bytes; `None` where it cannot be read.
pub fn available_bytes() -> Option<u64> {
    Some(kb_field("/proc/meminfo", "MemAvailable:") * 1024).filter(|&b| b > 0)
}

/// A kB field of /proc/self/status.
fn status_kb(field: &str) -> u64 {
    kb_field("/proc/self/status", field)
}

/// A kB field of a /proc file (0 when missing).
fn kb_field(file: &str, field: &str) -> u64 {
    std::fs::read_to_string(file)
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix(field))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
        })
        .unwrap_or(0)
}

/// Gives the free heap pages back to the system (glibc keeps them, in every thread's arena):
/// the stages after a solve would otherwise add their peak on top of the solve's.
pub fn release_free_memory() {
    // SAFETY: malloc_trim only releases pages that malloc holds free; no pointer is touched.
    unsafe {
        libc::malloc_trim(0);
    }
}
