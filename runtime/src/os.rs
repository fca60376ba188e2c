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

/// Σ aᵢ bᵢ of two single-precision vectors, eight lanes at a time, with AVX2 + FMA when the
/// processor has them (`None` otherwise). The products and the 32 running sums are single
/// precision, the final sum double: each product is rounded as the f32 coefficients already
/// were, so the error stays of the order of the one H in single precision carries.
#[inline]
pub fn dot32_simd(a: &[f32], b: &[f32]) -> Option<f64> {
    #[cfg(target_arch = "x86_64")]
    if simd::available() {
        // SAFETY: the processor has AVX2 and FMA (checked just above).
        return Some(unsafe { simd::dot32(a, b) });
    }
    let _ = (a, b);
    None
}

/// u = H s for a row-major single-precision n × n matrix `h` (n = `s.len()`), with AVX2 + FMA
/// when the processor has them (false otherwise: nothing done). Four rows at a time share each
/// load of s and one reduction, where a dot product a row spent as much on its reduction as on
/// its products (4.4–7.9 GMAC/s at n = 100–465, single-precision lanes or not).
#[inline]
pub fn matvec32_simd(h: &[f32], s: &[f32], u: &mut [f64]) -> bool {
    #[cfg(target_arch = "x86_64")]
    if simd::available() && h.len() >= s.len() * s.len() && u.len() >= s.len() {
        // SAFETY: AVX2 and FMA are there, and h holds n rows of n, u n values (checked above).
        unsafe { simd::matvec32(h, s, u) };
        return true;
    }
    let _ = (h, s, u);
    false
}

/// y += c x in double precision, with AVX2 + FMA when the processor has them (the crate is
/// built for plain x86-64: two lanes otherwise).
#[inline]
pub fn axpy64(c: f64, x: &[f64], y: &mut [f64]) {
    #[cfg(target_arch = "x86_64")]
    if simd::available() {
        // SAFETY: as in `dot_simd`.
        unsafe { simd::axpy64(c, x, y) };
        return;
    }
    for (yi, xi) in y.iter_mut().zip(x) {
        *yi += c * xi;
    }
}

/// y += c x in single precision, with AVX2 + FMA when the processor has them.
#[inline]
pub fn axpy32(c: f32, x: &[f32], y: &mut [f32]) {
    #[cfg(target_arch = "x86_64")]
    if simd::available() {
        // SAFETY: as in `dot_simd`.
        unsafe { simd::axpy32(c, x, y) };
        return;
    }
    for (yi, xi) in y.iter_mut().zip(x) {
        *yi += c * xi;
    }
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

    /// Four 8-wide single-precision FMA chains.
    #[target_feature(enable = "avx2,fma")]
    pub unsafe fn dot32(a: &[f32], b: &[f32]) -> f64 {
        use std::arch::x86_64::*;
        let n = a.len().min(b.len());
        let (pa, pb) = (a.as_ptr(), b.as_ptr());
        let mut acc = [_mm256_setzero_ps(); 4];
        let mut i = 0;
        // SAFETY: every load reads a[i..i + 32] and b[i..i + 32] with i + 32 ≤ n; AVX2 is there
        // (this function's feature).
        unsafe {
            while i + 32 <= n {
                for (k, lane) in acc.iter_mut().enumerate() {
                    let x = _mm256_loadu_ps(pa.add(i + 8 * k));
                    let y = _mm256_loadu_ps(pb.add(i + 8 * k));
                    *lane = _mm256_fmadd_ps(x, y, *lane);
                }
                i += 32;
            }
            let mut total = 0.0f64;
            for lane in acc {
                let mut v = [0.0f32; 8];
                _mm256_storeu_ps(v.as_mut_ptr(), lane);
                total += v.iter().map(|&x| f64::from(x)).sum::<f64>();
            }
            total
                + a[i..n]
                    .iter()
                    .zip(&b[i..n])
                    .map(|(x, y)| f64::from(*x) * f64::from(*y))
                    .sum::<f64>()
        }
    }

    /// u = H s, four rows at a time (two 8-wide chains a row: eight FMAs in flight).
    ///
    /// # Safety
    /// AVX2 and FMA must be there; `h.len() ≥ n²` and `u.len() ≥ n`, n = `s.len()`.
    #[target_feature(enable = "avx2,fma")]
    pub unsafe fn matvec32(h: &[f32], s: &[f32], u: &mut [f64]) {
        use std::arch::x86_64::*;
        let n = s.len();
        let (ph, ps) = (h.as_ptr(), s.as_ptr());
        let wide = n - n % 16;
        let sum8 = |v: __m256| -> f64 {
            let mut lanes = [0.0f32; 8];
            // SAFETY: eight f32 stored into an eight-f32 array.
            unsafe { _mm256_storeu_ps(lanes.as_mut_ptr(), v) };
            lanes.iter().map(|&x| f64::from(x)).sum()
        };
        let mut row = 0;
        // SAFETY: rows row..row + 4 < n and columns j..j + 16 ≤ wide ≤ n are inside h (n × n)
        // and s; the caller's contract for the features.
        unsafe {
            while row + 4 <= n {
                let mut acc = [[_mm256_setzero_ps(); 2]; 4];
                let mut j = 0;
                while j < wide {
                    let (s0, s1) = (_mm256_loadu_ps(ps.add(j)), _mm256_loadu_ps(ps.add(j + 8)));
                    for (k, a) in acc.iter_mut().enumerate() {
                        let r = ph.add((row + k) * n + j);
                        a[0] = _mm256_fmadd_ps(_mm256_loadu_ps(r), s0, a[0]);
                        a[1] = _mm256_fmadd_ps(_mm256_loadu_ps(r.add(8)), s1, a[1]);
                    }
                    j += 16;
                }
                for (k, a) in acc.iter().enumerate() {
                    let tail: f64 = (wide..n)
                        .map(|c| f64::from(*ph.add((row + k) * n + c)) * f64::from(*ps.add(c)))
                        .sum();
                    u[row + k] = sum8(_mm256_add_ps(a[0], a[1])) + tail;
                }
                row += 4;
            }
            while row < n {
                u[row] = dot32(&h[row * n..(row + 1) * n], s);
                row += 1;
            }
        }
    }

    /// y += c x in double precision, compiled for AVX2 + FMA (the compiler vectorises it).
    #[target_feature(enable = "avx2,fma")]
    pub unsafe fn axpy64(c: f64, x: &[f64], y: &mut [f64]) {
        for (yi, xi) in y.iter_mut().zip(x) {
            *yi = c.mul_add(*xi, *yi);
        }
    }

    /// y += c x in single precision, compiled for AVX2 + FMA (the compiler vectorises it).
    #[target_feature(enable = "avx2,fma")]
    pub unsafe fn axpy32(c: f32, x: &[f32], y: &mut [f32]) {
        for (yi, xi) in y.iter_mut().zip(x) {
            *yi = c.mul_add(*xi, *yi);
        }
    }
}
