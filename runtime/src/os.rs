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

/// y = H s for H stored by panels (the layout of `packed.rs`: `blocks` panels of eight
/// columns in `panels`), with AVX2 + FMA when the processor has them (false otherwise: nothing done).
/// `s`, `y` and the work space `w` hold at least 8 · `blocks` values.
#[inline]
pub fn panels_times_simd(panels: &[f32], blocks: usize, s: &[f32], y: &mut [f64], w: &mut [f32]) -> bool {
    #[cfg(target_arch = "x86_64")]
    if simd::available()
        && panels.len() >= blocks * (blocks + 1) * 32
        && s.len() >= 8 * blocks
        && y.len() >= 8 * blocks
        && w.len() >= 8 * blocks
    {
        // SAFETY: AVX2 and FMA are there, and every length the kernel reads (checked above).
        unsafe { simd::panels_times(panels, blocks, s, y, w) };
        return true;
    }
    let _ = (panels, blocks, s, y, w);
    false
}

/// out += Jᵀ v for the pairs of r = `q.len()` coordinates ordered (0,0), (0,1), …, (1,1), …
/// (J = ∂s/∂q, s the products q_k q_l, k ≤ l): out_k += 2 v_(kk) q_k + Σ_(l>k) v_(kl) q_l and
/// out_l += v_(kl) q_k, a row of pairs at a time in AVX2 lanes when the processor has them
/// (false otherwise: nothing done). A pair at a time, every product waited on the last.
#[inline]
pub fn add_pairs_transposed_simd<T: Coefficient>(v: &[T], q: &[f64], out: &mut [f64]) -> bool {
    let r = q.len();
    #[cfg(target_arch = "x86_64")]
    if simd::available() && v.len() >= r * (r + 1) / 2 && out.len() >= r {
        // SAFETY: AVX2 and FMA are there; v holds the r(r+1)/2 pairs and out r values.
        unsafe { simd::add_pairs_transposed(v, q, out) };
        return true;
    }
    let _ = (v, out, r);
    false
}

/// For m ≤ 4 rows tₐ (m = `c.len()`) of length n = `s.len()` held one after another in `rows`:
/// Σ tₐᵢ sᵢ for each (the first m values returned), and u += Σₐ cₐ tₐ, with AVX2 + FMA when the
/// processor has them — the nonlinear force's T s and Tᵀ q in one pass over T, u read and
/// written once for the m rows (a row at a time it was read and written four times). Panics if
/// `rows` or `u` is shorter than that.
#[inline]
pub fn dots_and_axpy(rows: &[f64], s: &[f64], c: &[f64], u: &mut [f64]) -> [f64; 4] {
    let (m, n) = (c.len().min(4), s.len());
    assert!(
        rows.len() >= m * n && u.len() >= n,
        "{m} rows of {n} and {n} values to add to"
    );
    #[cfg(target_arch = "x86_64")]
    if simd::available() {
        // SAFETY: AVX2 and FMA are there; rows holds m n values and u n (asserted above).
        return unsafe {
            match m {
                4 => simd::dots_and_axpy::<4>(rows, s, c, u),
                3 => simd::dots_and_axpy::<3>(rows, s, c, u),
                2 => simd::dots_and_axpy::<2>(rows, s, c, u),
                1 => simd::dots_and_axpy::<1>(rows, s, c, u),
                _ => [0.0; 4],
            }
        };
    }
    dots_and_axpy_portable(rows, s, &c[..m], u)
}

/// [`dots_and_axpy`] a value at a time (a processor without AVX2 and FMA).
fn dots_and_axpy_portable(rows: &[f64], s: &[f64], c: &[f64], u: &mut [f64]) -> [f64; 4] {
    let n = s.len();
    let mut out = [0.0; 4];
    for (a, (o, ca)) in out.iter_mut().zip(c).enumerate() {
        for ((t, si), ui) in rows[a * n..(a + 1) * n].iter().zip(s).zip(u.iter_mut()) {
            *o += t * si;
            *ui += ca * t;
        }
    }
    out
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

/// y += a x and z += b x in single precision (x read once), with AVX2 + FMA when the processor
/// has them.
#[inline]
pub fn axpy2_32(x: &[f32], a: f32, y: &mut [f32], b: f32, z: &mut [f32]) {
    #[cfg(target_arch = "x86_64")]
    if simd::available() {
        // SAFETY: as in `dot_simd`.
        unsafe { simd::axpy2_32(x, a, y, b, z) };
        return;
    }
    for ((yi, zi), xi) in y.iter_mut().zip(z.iter_mut()).zip(x) {
        *yi += a * xi;
        *zi += b * xi;
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

    /// y = H s by panels (the layout of `packed.rs`): for each half panel (four columns j),
    /// each block I above the diagonal adds Σ_c H[I, j_c] s_(j_c) to y_I and H[I, j_c] ⊙ s_I
    /// to four running column sums t_c; the diagonal block adds to the t_c alone, whose lanes
    /// are then summed into y_(j_c). A panel's first half leaves its row sums in `w`, the second adds them and
    /// the sum goes to y in double.
    ///
    /// # Safety
    /// AVX2 and FMA must be there; `panels` holds blocks(blocks + 1) · 32 values and `s`, `y`,
    /// `w` 8 · blocks each.
    #[target_feature(enable = "avx2,fma")]
    pub unsafe fn panels_times(panels: &[f32], blocks: usize, s: &[f32], y: &mut [f64], w: &mut [f32]) {
        use std::arch::x86_64::*;
        y[..8 * blocks].fill(0.0);
        let (ps, py, pw) = (s.as_ptr(), y.as_mut_ptr(), w.as_mut_ptr());
        let mut ph = panels.as_ptr();
        // SAFETY: the panels are read in order, 32 values a block, Σ_J 2(J + 1) blocks of 32 =
        // blocks(blocks + 1) · 32 values in all; s, y and w are indexed below 8 · blocks.
        unsafe {
            for jb in 0..blocks {
                for half in 0..2 {
                    let j0 = 8 * jb + 4 * half;
                    let b = [0, 1, 2, 3].map(|c| _mm256_broadcast_ss(&*ps.add(j0 + c)));
                    let mut t = [_mm256_setzero_ps(); 4];
                    for ib in 0..jb {
                        let si = _mm256_loadu_ps(ps.add(8 * ib));
                        let c = [0, 1, 2, 3].map(|k| _mm256_loadu_ps(ph.add(8 * k)));
                        // Two chains for y_I, so its four products do not wait on each other.
                        let ya = if half == 0 {
                            _mm256_mul_ps(c[0], b[0])
                        } else {
                            _mm256_fmadd_ps(c[0], b[0], _mm256_loadu_ps(pw.add(8 * ib)))
                        };
                        let yb = _mm256_mul_ps(c[1], b[1]);
                        let ya = _mm256_fmadd_ps(c[2], b[2], ya);
                        let yb = _mm256_fmadd_ps(c[3], b[3], yb);
                        let sum = _mm256_add_ps(ya, yb);
                        if half == 0 {
                            _mm256_storeu_ps(pw.add(8 * ib), sum);
                        } else {
                            let lo = _mm256_cvtps_pd(_mm256_castps256_ps128(sum));
                            let hi = _mm256_cvtps_pd(_mm256_extractf128_ps(sum, 1));
                            let at = py.add(8 * ib);
                            _mm256_storeu_pd(at, _mm256_add_pd(_mm256_loadu_pd(at), lo));
                            _mm256_storeu_pd(at.add(4), _mm256_add_pd(_mm256_loadu_pd(at.add(4)), hi));
                        }
                        for k in 0..4 {
                            t[k] = _mm256_fmadd_ps(c[k], si, t[k]);
                        }
                        ph = ph.add(32);
                    }
                    let si = _mm256_loadu_ps(ps.add(8 * jb));
                    for (k, tk) in t.iter_mut().enumerate() {
                        *tk = _mm256_fmadd_ps(_mm256_loadu_ps(ph.add(8 * k)), si, *tk);
                    }
                    ph = ph.add(32);
                    // The four column sums' lanes, summed at once.
                    let h = _mm256_hadd_ps(_mm256_hadd_ps(t[0], t[1]), _mm256_hadd_ps(t[2], t[3]));
                    let sums = _mm_add_ps(_mm256_castps256_ps128(h), _mm256_extractf128_ps(h, 1));
                    let at = py.add(j0);
                    _mm256_storeu_pd(at, _mm256_add_pd(_mm256_loadu_pd(at), _mm256_cvtps_pd(sums)));
                }
            }
        }
    }

    /// out += Jᵀ v by rows of pairs: row k's pairs (k, l > k) dotted with q_(k+1..) into out_k
    /// and added, times q_k, to out_(k+1..).
    ///
    /// # Safety
    /// AVX2 and FMA must be there; `v` holds r(r+1)/2 values and `out` r, r = `q.len()`.
    #[target_feature(enable = "avx2,fma")]
    pub unsafe fn add_pairs_transposed<T: super::Coefficient>(v: &[T], q: &[f64], out: &mut [f64]) {
        use std::arch::x86_64::*;
        let r = q.len();
        let (pv, pq, po) = (v.as_ptr(), q.as_ptr(), out.as_mut_ptr());
        let mut p = 0;
        // SAFETY: row k reads v[p..p + r − k] (p + r − k ≤ r(r+1)/2), q and out below r.
        unsafe {
            for k in 0..r {
                let qk = q[k];
                let qkv = _mm256_set1_pd(qk);
                let n = r - k - 1;
                let mut acc = _mm256_setzero_pd();
                let mut i = 0;
                while i + 4 <= n {
                    let x = T::load4(pv.add(p + 1 + i));
                    acc = _mm256_fmadd_pd(x, _mm256_loadu_pd(pq.add(k + 1 + i)), acc);
                    let o = po.add(k + 1 + i);
                    _mm256_storeu_pd(o, _mm256_fmadd_pd(x, qkv, _mm256_loadu_pd(o)));
                    i += 4;
                }
                let mut lanes = [0.0f64; 4];
                _mm256_storeu_pd(lanes.as_mut_ptr(), acc);
                let mut sum = 2.0 * v[p].into() * qk + (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]);
                while i < n {
                    let x: f64 = v[p + 1 + i].into();
                    sum += x * q[k + 1 + i];
                    out[k + 1 + i] += x * qk;
                    i += 1;
                }
                out[k] += sum;
                p += n + 1;
            }
        }
    }

    /// M rows' dot products with s and their combination added to u, four lanes at a time.
    ///
    /// # Safety
    /// AVX2 and FMA must be there; `rows` holds M n values, `c` M and `u` n, n = `s.len()`.
    #[target_feature(enable = "avx2,fma")]
    pub unsafe fn dots_and_axpy<const M: usize>(rows: &[f64], s: &[f64], c: &[f64], u: &mut [f64]) -> [f64; 4] {
        use std::arch::x86_64::*;
        let n = s.len();
        let (pt, ps, pu) = (rows.as_ptr(), s.as_ptr(), u.as_mut_ptr());
        let cc: [__m256d; M] = std::array::from_fn(|a| _mm256_set1_pd(c[a]));
        let mut acc = [_mm256_setzero_pd(); M];
        let mut i = 0;
        // SAFETY: row a's values are rows[a n..(a + 1) n]; every index is below n.
        unsafe {
            while i + 4 <= n {
                let sv = _mm256_loadu_pd(ps.add(i));
                let mut uv = _mm256_loadu_pd(pu.add(i));
                for a in 0..M {
                    let x = _mm256_loadu_pd(pt.add(a * n + i));
                    acc[a] = _mm256_fmadd_pd(x, sv, acc[a]);
                    uv = _mm256_fmadd_pd(x, cc[a], uv);
                }
                _mm256_storeu_pd(pu.add(i), uv);
                i += 4;
            }
            let mut out = [0.0f64; 4];
            for a in 0..M {
                let mut lanes = [0.0f64; 4];
                _mm256_storeu_pd(lanes.as_mut_ptr(), acc[a]);
                out[a] = (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]);
            }
            while i < n {
                for a in 0..M {
                    let x = rows[a * n + i];
                    out[a] += x * s[i];
                    u[i] = c[a].mul_add(x, u[i]);
                }
                i += 1;
            }
            out
        }
    }

    /// y += c x in double precision, compiled for AVX2 + FMA (the compiler vectorises it).
    #[target_feature(enable = "avx2,fma")]
    pub unsafe fn axpy64(c: f64, x: &[f64], y: &mut [f64]) {
        for (yi, xi) in y.iter_mut().zip(x) {
            *yi = c.mul_add(*xi, *yi);
        }
    }

    /// y += a x and z += b x in single precision, compiled for AVX2 + FMA.
    #[target_feature(enable = "avx2,fma")]
    pub unsafe fn axpy2_32(x: &[f32], a: f32, y: &mut [f32], b: f32, z: &mut [f32]) {
        for ((yi, zi), xi) in y.iter_mut().zip(z.iter_mut()).zip(x) {
            *yi = a.mul_add(*xi, *yi);
            *zi = b.mul_add(*xi, *zi);
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The rows' sums and the combination added to u, in vector lanes and a value at a time,
    /// for one to four rows and lengths with and without a tail.
    #[test]
    fn rows_dotted_and_combined_in_lanes_as_one_at_a_time() {
        for n in [1, 3, 4, 9, 45] {
            for m in 1..=4 {
                let rows: Vec<f64> = (0..m * n).map(|i| ((i * 37) % 17) as f64 * 0.1 - 0.8).collect();
                let s: Vec<f64> = (0..n).map(|i| ((i * 13) % 7) as f64 * 0.2 - 0.6).collect();
                let c: Vec<f64> = (0..m).map(|a| 0.5 - a as f64 * 0.3).collect();
                let start: Vec<f64> = (0..n).map(|i| i as f64 * 0.01).collect();
                let (mut u, mut v) = (start.clone(), start.clone());
                let d = dots_and_axpy(&rows, &s, &c, &mut u);
                let e = dots_and_axpy_portable(&rows, &s, &c, &mut v);
                for a in 0..4 {
                    let want: f64 = if a < m {
                        (0..n).map(|i| rows[a * n + i] * s[i]).sum()
                    } else {
                        0.0
                    };
                    assert!(
                        (d[a] - want).abs() < 1e-12 && (e[a] - want).abs() < 1e-12,
                        "n {n}, m {m}, row {a}"
                    );
                }
                for i in 0..n {
                    let want = start[i] + (0..m).map(|a| c[a] * rows[a * n + i]).sum::<f64>();
                    assert!(
                        (u[i] - want).abs() < 1e-12 && (v[i] - want).abs() < 1e-12,
                        "n {n}, m {m}, u[{i}]"
                    );
                }
            }
        }
    }
}
