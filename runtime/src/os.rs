//! The operating-system calls the runtime makes (libc), and what the processor offers beyond
//! plain x86-64 (AVX2 + FMA kernels of the nonlinear step, chosen at run time), each behind a
//! safe function: with the C ABI's exported functions (`capi`), the only `unsafe` of this crate.

/// The cores the calling thread may run on (empty if unknown).
pub fn allowed_cores() -> Vec<usize> {
    // SAFETY: a zeroed cpu_set_t is a valid empty set; sched_getaffinity fills it.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        if libc::sched_getaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &mut set) != 0 {
            return Vec::new();
        }
        (0..libc::CPU_SETSIZE as usize)
            .filter(|&c| libc::CPU_ISSET(c, &set))
            .collect()
    }
}

/// The cores this process's main thread may run on (empty if unknown): what the process was
/// given, whichever thread asks (the haptic thread narrows its own).
pub fn process_cores() -> Vec<usize> {
    // SAFETY: as in allowed_cores; getpid names this process (its main thread).
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        if libc::sched_getaffinity(libc::getpid(), std::mem::size_of::<libc::cpu_set_t>(), &mut set) != 0 {
            return Vec::new();
        }
        (0..libc::CPU_SETSIZE as usize)
            .filter(|&c| libc::CPU_ISSET(c, &set))
            .collect()
    }
}

/// Lets the calling thread run on `cores` only.
pub fn set_cores(cores: &[usize]) -> std::io::Result<()> {
    // SAFETY: the set is initialised before use; 0 = the calling thread.
    let rc = unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        for &c in cores.iter().filter(|&&c| c < libc::CPU_SETSIZE as usize) {
            libc::CPU_SET(c, &mut set);
        }
        libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set)
    };
    if rc == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

/// Puts the calling thread under SCHED_FIFO at `priority`, or back under SCHED_OTHER (None).
pub fn set_fifo(priority: Option<i32>) -> std::io::Result<()> {
    let (policy, p) = match priority {
        Some(p) => (libc::SCHED_FIFO, p),
        None => (libc::SCHED_OTHER, 0),
    };
    let param = libc::sched_param { sched_priority: p };
    // SAFETY: valid parameter for the calling thread.
    let rc = unsafe { libc::pthread_setschedparam(libc::pthread_self(), policy, &param) };
    if rc == 0 {
        Ok(())
    } else {
        Err(std::io::Error::from_raw_os_error(rc))
    }
}

/// Whether the calling thread runs under SCHED_FIFO.
pub fn is_fifo() -> bool {
    // SAFETY: sched_getscheduler(0) reads the calling thread's policy.
    unsafe { libc::sched_getscheduler(0) == libc::SCHED_FIFO }
}

/// Locks the process's memory, current and future (no page fault in the haptic loop), or
/// unlocks it (`false`).
pub fn lock_memory(lock: bool) -> std::io::Result<()> {
    // SAFETY: no arguments beyond the flags.
    let rc = unsafe {
        if lock {
            libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE)
        } else {
            libc::munlockall()
        }
    };
    if rc == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

/// The machine's host name, lower case, as other machines on the network may call it.
pub fn hostname() -> Option<String> {
    let mut buf = [0u8; 256];
    // SAFETY: the buffer is valid for its length; the name is NUL-terminated within it or the
    // call fails.
    let rc = unsafe { libc::gethostname(buf.as_mut_ptr().cast(), buf.len()) };
    if rc != 0 {
        return None;
    }
    let end = buf.iter().position(|&b| b == 0)?;
    std::str::from_utf8(&buf[..end])
        .ok()
        .filter(|h| !h.is_empty())
        .map(str::to_ascii_lowercase)
}

/// A coefficient the AVX2 kernels read: `f64`, or `f32` widened as it is loaded.
pub trait Coefficient: Copy + Into<f64> {
    /// Four values from `p` as four doubles.
    ///
    /// # Safety
    /// `p..p + 4` must be readable, and the processor must have AVX2.
    #[cfg(target_arch = "x86_64")]
    unsafe fn load4(p: *const Self) -> std::arch::x86_64::__m256d;
}

impl Coefficient for f64 {
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn load4(p: *const f64) -> std::arch::x86_64::__m256d {
        // SAFETY: the caller's contract.
        unsafe { std::arch::x86_64::_mm256_loadu_pd(p) }
    }
}

impl Coefficient for f32 {
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn load4(p: *const f32) -> std::arch::x86_64::__m256d {
        use std::arch::x86_64::*;
        // SAFETY: the caller's contract.
        unsafe { _mm256_cvtps_pd(_mm_loadu_ps(p)) }
    }
}

/// Σ aᵢ bᵢ with AVX2 + FMA when the processor has them (`None` otherwise: the caller's portable
/// loop). The crate is built for plain x86-64, so the check is at run time, once.
#[inline]
pub fn dot_simd<T: Coefficient>(a: &[T], b: &[f64]) -> Option<f64> {
    #[cfg(target_arch = "x86_64")]
    if simd::available() {
        // SAFETY: the processor has AVX2 and FMA (checked just above).
        return Some(unsafe { simd::dot(a, b) });
    }
    let _ = (a, b);
    None
}

/// y += c x with AVX2 + FMA when the processor has them; false otherwise (nothing done).
#[inline]
pub fn axpy_simd<T: Coefficient>(c: f64, x: &[T], y: &mut [f64]) -> bool {
    #[cfg(target_arch = "x86_64")]
    if simd::available() {
        // SAFETY: as in `dot_simd`.
        unsafe { simd::axpy(c, x, y) };
        return true;
    }
    let _ = (c, x, y);
    false
}

#[cfg(target_arch = "x86_64")]
mod simd {
    use std::sync::atomic::{AtomicU8, Ordering};

    /// 0 unknown, 1 no, 2 yes.
    static HAS: AtomicU8 = AtomicU8::new(0);

    /// Whether AVX2 and FMA are there (detected once, then one relaxed load).
    #[inline(always)]
    pub fn available() -> bool {
        match HAS.load(Ordering::Relaxed) {
            2 => true,
            1 => false,
            _ => {
                let yes = is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma");
                HAS.store(if yes { 2 } else { 1 }, Ordering::Relaxed);
                yes
            }
        }
    }

    /// Four 4-wide FMA chains (16 products in flight: the FMA latency is hidden).
    #[target_feature(enable = "avx2,fma")]
    pub unsafe fn dot<T: super::Coefficient>(a: &[T], b: &[f64]) -> f64 {
        use std::arch::x86_64::*;
        let n = a.len().min(b.len());
        let (pa, pb) = (a.as_ptr(), b.as_ptr());
        let mut acc = [_mm256_setzero_pd(); 4];
        let mut i = 0;
        // SAFETY: every load reads a[i..i + 16] and b[i..i + 16] with i + 16 ≤ n; AVX2 is there
        // (this function's feature).
        unsafe {
            while i + 16 <= n {
                for (k, lane) in acc.iter_mut().enumerate() {
                    let x = T::load4(pa.add(i + 4 * k));
                    let y = _mm256_loadu_pd(pb.add(i + 4 * k));
                    *lane = _mm256_fmadd_pd(x, y, *lane);
                }
                i += 16;
            }
            let s = _mm256_add_pd(_mm256_add_pd(acc[0], acc[1]), _mm256_add_pd(acc[2], acc[3]));
            let mut lanes = [0.0f64; 4];
            _mm256_storeu_pd(lanes.as_mut_ptr(), s);
            let tail: f64 = a[i..n].iter().zip(&b[i..n]).map(|(x, y)| (*x).into() * y).sum();
            lanes.iter().sum::<f64>() + tail
        }
    }

    /// y += c x, compiled for AVX2 + FMA (the compiler vectorises it).
    #[target_feature(enable = "avx2,fma")]
    pub unsafe fn axpy<T: super::Coefficient>(c: f64, x: &[T], y: &mut [f64]) {
        for (yi, xi) in y.iter_mut().zip(x) {
            *yi = c.mul_add((*xi).into(), *yi);
        }
    }
}
