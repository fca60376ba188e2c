//! This process's memory: resident and peak resident size (Linux /proc), what may still be
//! taken before an allocation is made ([`ensure_fits`]: a refusal in one line instead of an
//! abort), and giving malloc's free pages back to the system between stages.

/// Peak resident set size of this process (Linux `/proc/self/status`, `VmHWM`), bytes.
pub fn peak_rss_bytes() -> u64 {
    status_kb("VmHWM:") * 1024
}

/// Makes this process's peak resident size ([`peak_rss_bytes`]) its current size, so that the
/// next peak read is that of the work done after this call (Linux 4.0 and later:
/// `/proc/self/clear_refs`). False where it cannot; the peak then stays the process's.
pub fn reset_peak() -> bool {
    std::fs::write("/proc/self/clear_refs", b"5").is_ok()
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

/// Memory this process may still take, bytes: the least of what the system can give without
/// swapping (`MemAvailable`), what its cgroup (a container, a systemd slice) still allows
/// (`memory.max − memory.current`, v2), and what its address-space limit (`ulimit -v`) leaves.
/// `None` where none of them can be read.
/// [`CAP_VAR`], when set, caps what the process may hold in all (its resident size counts).
pub fn headroom_bytes() -> Option<u64> {
    let capped = cap_from_env().ok().flatten().map(|cap| cap.saturating_sub(rss_bytes()));
    [available_bytes(), cgroup_headroom(), address_space_headroom(), capped]
        .into_iter()
        .flatten()
        .min()
}

/// The environment variable that caps the memory a run may take (bytes, or with a K, M, G or T
/// suffix, powers of 1024): for a shared machine or a server whose computes must leave room for
/// the rest. `ves` refuses an unreadable value at its start ([`cap_from_env`]).
pub const CAP_VAR: &str = "VES_MAX_MEMORY";

/// [`CAP_VAR`] is set to something that is not a memory size.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "{CAP_VAR}={text:?}: not a memory size; give bytes or a number with K, M, G or T (e.g. {CAP_VAR}=8G), or unset it"
)]
pub struct MemoryCapError {
    /// The variable's value as given.
    pub text: String,
}

/// The cap [`CAP_VAR`] sets, `None` when unset; an error naming it when it is not a size.
pub fn cap_from_env() -> Result<Option<u64>, MemoryCapError> {
    let Some(v) = std::env::var_os(CAP_VAR) else {
        return Ok(None);
    };
    let text = v.to_string_lossy();
    let t = text.trim();
    let (digits, unit) = match t.char_indices().last() {
        Some((i, c)) if c.is_ascii_alphabetic() => (&t[..i], c.to_ascii_uppercase()),
        _ => (t, 'B'),
    };
    let scale: u64 = match unit {
        'B' => 1,
        'K' => 1 << 10,
        'M' => 1 << 20,
        'G' => 1 << 30,
        'T' => 1 << 40,
        _ => 0,
    };
    match digits.trim().parse::<f64>() {
        Ok(x) if scale > 0 && x.is_finite() && x > 0.0 && x * (scale as f64) < 2f64.powi(63) => {
            Ok(Some((x * scale as f64) as u64))
        }
        _ => Err(MemoryCapError {
            text: text.into_owned(),
        }),
    }
}

/// What the cgroup v2 of this process still allows (None without a limit or outside cgroup v2).
fn cgroup_headroom() -> Option<u64> {
    // "0::/path" is the v2 entry of /proc/self/cgroup.
    let own = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    let rel = own.lines().find_map(|l| l.strip_prefix("0::"))?.trim();
    let dir = std::path::Path::new("/sys/fs/cgroup").join(rel.trim_start_matches('/'));
    let read = |f: &str| std::fs::read_to_string(dir.join(f)).ok()?.trim().parse::<u64>().ok();
    // "max" (no limit) does not parse: None.
    let max = read("memory.max")?;
    Some(max.saturating_sub(read("memory.current").unwrap_or(0)))
}

/// What RLIMIT_AS leaves of the address space (None when unlimited).
fn address_space_headroom() -> Option<u64> {
    Some(crate::os::address_space_limit()?.saturating_sub(status_kb("VmSize:") * 1024))
}

/// An allocation that would not fit in the memory this process may still take.
#[derive(Debug, Clone, thiserror::Error)]
#[error("{what} needs {:.2} GB of memory, {:.2} GB available", *needed as f64 / 1e9, *available as f64 / 1e9)]
pub struct OutOfMemory {
    /// What the memory was for.
    pub what: String,
    /// Bytes asked.
    pub needed: u64,
    /// Bytes the process could still take ([`headroom_bytes`]).
    pub available: u64,
}

impl OutOfMemory {
    /// By how much the mesh size must grow for a sparse factor of `needed` bytes to fit in
    /// `available`: nested-dissection fill on a 3D mesh grows as n^{4/3} ∝ size⁻⁴; a tenth more
    /// for the margin [`ensure_fits`] keeps and the rule's roughness. Rounded up to 0.01.
    pub fn coarsening(&self) -> f64 {
        let ratio = self.needed as f64 / (0.9 * self.available.max(1) as f64);
        (1.1 * ratio.max(1.0).powf(0.25) * 100.0).ceil() / 100.0
    }
}

/// Checks, before allocating, that `bytes` more fit in what the process may still take (with a
/// tenth kept for everything else the step allocates). A failed allocation aborts the process
/// — every page of `ves view` with it — so each large allocation is asked for here first, and is
/// then made with `try_reserve` (the estimate can be beaten by another process meanwhile).
/// Passes where the headroom cannot be read.
pub fn ensure_fits(what: &str, bytes: u64) -> Result<(), OutOfMemory> {
    match headroom_bytes() {
        Some(free) if bytes > free / 10 * 9 => Err(OutOfMemory {
            what: what.to_string(),
            needed: bytes,
            available: free,
        }),
        _ => Ok(()),
    }
}

/// `n` zeros written, not only allocated, for sums added into at scattered places: a calloc'd
/// page is mapped on first touch, and read before it is written (`+=`) it faults twice (the
/// shared zero page, then a copy on write that flushes the other cores' TLBs). On the
/// ribplate's recovery estimate, 0.55–0.62 s calloc'd against 0.43–0.47 s written.
pub fn written_zeros(n: usize) -> Vec<f64> {
    let mut v = Vec::with_capacity(n);
    v.resize(n, 0.0);
    v
}

/// A zeroed vector of `len` values, or the error instead of an abort when memory is short
/// ([`ensure_fits`] first, then a fallible reservation).
pub fn try_zeros<T: Clone + Default>(what: &str, len: usize) -> Result<Vec<T>, OutOfMemory> {
    let bytes = (len as u64).saturating_mul(std::mem::size_of::<T>() as u64);
    ensure_fits(what, bytes)?;
    let mut v = Vec::new();
    v.try_reserve_exact(len).map_err(|_| OutOfMemory {
        what: what.to_string(),
        needed: bytes,
        available: headroom_bytes().unwrap_or(0),
    })?;
    v.resize(len, T::default());
    Ok(v)
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
    crate::os::trim_heap();
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What cannot fit is refused, naming it and both sizes; what fits passes.
    #[test]
    fn an_allocation_beyond_the_headroom_is_refused_not_attempted() {
        let free = headroom_bytes().expect("Linux reports the memory available");
        let e = ensure_fits("the test's factor", free.saturating_mul(2)).expect_err("twice the headroom");
        assert_eq!(e.needed, free.saturating_mul(2));
        let text = e.to_string();
        assert!(
            text.starts_with("the test's factor needs ") && text.contains("GB available"),
            "{text}"
        );
        ensure_fits("a kilobyte", 1024).expect("fits");
        let big = try_zeros::<f64>("the test's factor", usize::MAX / 16);
        assert!(big.is_err(), "an impossible size is an error, not an abort");
        assert_eq!(try_zeros::<f64>("small", 3).unwrap(), vec![0.0; 3]);
    }
}
