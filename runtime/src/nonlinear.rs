//! The geometrically nonlinear reduced model (`[model] kind = "nonlinear"`, docs/nonlinear.md):
//! reduced St. Venant–Kirchhoff on the modes and their modal derivatives. [`Polynomial`] is
//! the strain energy of u = Φq, a quartic in q whose coefficients the basis file stores
//! (`spaces/X/nonlinear`); [`Stepper`] advances it by implicit Newmark (average acceleration)
//! with Newton iterations warm-started from the last step, allocation-free, and gives the hand
//! its step compliance from the same factor, so the coupling stays implicit.

use crate::packed::Panels;
use nalgebra::{DMatrix, DVector};

/// Index of the pair (k, l), k ≤ l, among the r(r+1)/2 pairs ordered (0,0), (0,1), …, (1,1), …:
/// rows 0..k hold r, r−1, …, r−k+1 pairs.
#[inline(always)]
fn pair_index(r: usize, k: usize, l: usize) -> usize {
    k * r - k * k.saturating_sub(1) / 2 + (l - k)
}

/// The reduced St. Venant–Kirchhoff model of a basis U (n × r): for u = U q the strain energy
/// is W(q) = ½ qᵀ K q + qᵀ T s + ½ sᵀ H s with s the r(r+1)/2 products q_k q_l (k ≤ l). K, T, H
/// are integrated over the mesh once (`ves_numerics::fem::stvk::reduce`); the force ∂W/∂q and
/// the tangent ∂²W/∂q² then cost O(P²) and O(P r²), P = r(r+1)/2.
#[derive(Clone, Debug)]
pub struct Polynomial {
    /// Basis size r.
    pub r: usize,
    /// Uᵀ K U, r × r row-major.
    pub k: Vec<f64>,
    /// Cubic-energy coefficients, r × P row-major.
    pub t: Vec<f64>,
    /// Quartic-energy coefficients, P × P row-major (symmetric positive semi-definite); empty
    /// once [`Polynomial::single_precision`] moved them to `h32`.
    pub h: Vec<f64>,
    /// H in single precision, row by row (the tangent's rows; the quartic energy then carries a
    /// relative rounding of about 1e-7, far below the model's own error). Empty: H is in `h`.
    h32: Vec<f32>,
    /// The same H stored by panels, each pair once: the force's product H s, the haptic step's
    /// largest cost, reads half the bytes (empty with `h32`).
    panels: Panels,
}

/// Work space of [`Polynomial`]'s evaluations (no allocation once made).
#[derive(Clone, Debug)]
pub struct Scratch {
    s: Vec<f64>,
    /// s in single precision (H s with H in single).
    s32: Vec<f32>,
    u: Vec<f64>,
    /// H J, column by column, in single precision: the tangent only steers Newton's iterations
    /// (the converged step is the force's), so its rounding costs nothing but a rate.
    hj: Vec<f32>,
    row: Vec<f64>,
    /// The panel product's row sums in single precision.
    panel_sums: Vec<f32>,
}

impl Polynomial {
    /// Number of pairs P = r(r+1)/2.
    pub fn pairs(&self) -> usize {
        self.r * (self.r + 1) / 2
    }

    /// The model of r vectors with K (r × r), T (r × P) and H (P × P), row-major, in double
    /// precision.
    pub fn new(r: usize, k: Vec<f64>, t: Vec<f64>, h: Vec<f64>) -> Polynomial {
        Polynomial {
            r,
            k,
            t,
            h,
            h32: Vec::new(),
            panels: Panels::default(),
        }
    }

    /// The model a basis file stores: linear part diag(λ), cubic T [r, P] and quartic H [P, P]
    /// row-major (shapes checked by the reader).
    pub fn of_file(eigenvalues: &[f64], cubic: Vec<f64>, quartic: Vec<f64>) -> Polynomial {
        let r = eigenvalues.len();
        let mut k = vec![0.0; r * r];
        for (i, l) in eigenvalues.iter().enumerate() {
            k[i * r + i] = *l;
        }
        Polynomial::new(r, k, cubic, quartic)
    }

    /// Bytes the coefficients take.
    pub fn bytes(&self) -> usize {
        8 * (self.k.len() + self.t.len() + self.h.len()) + 4 * self.h32.len() + self.panels.bytes()
    }

    /// The model of the first `r` vectors alone: the energy restricted to q_j = 0 for j ≥ r,
    /// which keeps exactly the coefficients of those vectors' products.
    pub fn first(&self, r: usize) -> Polynomial {
        let (all, np_all) = (self.r, self.pairs());
        let r = r.min(all);
        let pairs: Vec<usize> = (0..r)
            .flat_map(|k| (k..r).map(move |l| pair_index(all, k, l)))
            .collect();
        let k = (0..r)
            .flat_map(|i| (0..r).map(move |j| (i, j)))
            .map(|(i, j)| self.k[i * all + j])
            .collect();
        let t = (0..r)
            .flat_map(|i| pairs.iter().map(move |&p| self.t[i * np_all + p]))
            .collect();
        let pick = |h: &[f64]| -> Vec<f64> {
            pairs
                .iter()
                .flat_map(|&a| pairs.iter().map(move |&b| h[a * np_all + b]))
                .collect()
        };
        let pick32 = |h: &[f32]| -> Vec<f32> {
            pairs
                .iter()
                .flat_map(|&a| pairs.iter().map(move |&b| h[a * np_all + b]))
                .collect()
        };
        let h = if self.h.is_empty() { Vec::new() } else { pick(&self.h) };
        let p = Polynomial::new(r, k, t, h);
        if self.h32.is_empty() {
            p
        } else {
            p.with_single(pick32(&self.h32))
        }
    }

    /// The same model with H held in single precision (`h32`), as the runtime keeps it.
    pub fn single_precision(mut self) -> Polynomial {
        if self.h32.is_empty() {
            let h32 = self.h.iter().map(|&v| v as f32).collect();
            self.h = Vec::new();
            self = self.with_single(h32);
        }
        self
    }

    /// This model with H in single precision `h32` (P × P row-major), and its panels.
    fn with_single(mut self, h32: Vec<f32>) -> Polynomial {
        self.panels = Panels::of_rows(&h32, self.pairs());
        self.h32 = h32;
        self
    }

    /// H s into `u` (s in double; with H in single, by its panels from a single-precision copy
    /// `s32`, the products rounded as H's coefficients already are, `sums` their work space).
    fn quartic_times(&self, s: &[f64], s32: &mut [f32], u: &mut [f64], sums: &mut [f32]) {
        let np = self.pairs();
        if self.h32.is_empty() {
            for (p, up) in u.iter_mut().enumerate().take(np) {
                *up = dot(&self.h[p * np..(p + 1) * np], s);
            }
            return;
        }
        for (x, &v) in s32.iter_mut().zip(s) {
            *x = v as f32;
        }
        self.panels.times(s32, u, sums);
    }

    /// Row `p` of H dotted with `x`.
    #[inline]
    fn quartic_dot(&self, p: usize, x: &[f64]) -> f64 {
        let np = self.pairs();
        if self.h32.is_empty() {
            dot(&self.h[p * np..(p + 1) * np], x)
        } else {
            dot(&self.h32[p * np..(p + 1) * np], x)
        }
    }

    /// y += c · row `p` of H, in single precision (the tangent's kernel).
    #[inline]
    fn quartic_axpy(&self, c: f64, p: usize, y: &mut [f32]) {
        let np = self.pairs();
        if self.h32.is_empty() {
            for (yi, hi) in y.iter_mut().zip(&self.h[p * np..(p + 1) * np]) {
                *yi += (c * hi) as f32;
            }
        } else {
            crate::os::axpy32(c as f32, &self.h32[p * np..(p + 1) * np], y);
        }
    }

    /// y += a · row `p` of H and z += b · the same row, in single precision (the row read once).
    #[inline]
    fn quartic_axpy2(&self, p: usize, a: f64, y: &mut [f32], b: f64, z: &mut [f32]) {
        let np = self.pairs();
        if self.h32.is_empty() {
            for ((yi, zi), hi) in y.iter_mut().zip(z.iter_mut()).zip(&self.h[p * np..(p + 1) * np]) {
                *yi += (a * hi) as f32;
                *zi += (b * hi) as f32;
            }
        } else {
            crate::os::axpy2_32(&self.h32[p * np..(p + 1) * np], a as f32, y, b as f32, z);
        }
    }

    /// Work space for this model.
    pub fn scratch(&self) -> Scratch {
        let np = self.pairs();
        // The panel product reads and writes its padded length (zeros beyond P stay zeros).
        let padded = np.max(self.panels.padded());
        Scratch {
            s: vec![0.0; np],
            s32: vec![0.0; padded],
            u: vec![0.0; padded],
            hj: vec![0.0; np * self.r],
            row: vec![0.0; self.r],
            panel_sums: vec![0.0; padded],
        }
    }

    /// s = (q_k q_l)_{k ≤ l}.
    fn products(&self, q: &[f64], s: &mut [f64]) {
        let mut p = 0;
        for k in 0..self.r {
            for l in k..self.r {
                s[p] = q[k] * q[l];
                p += 1;
            }
        }
    }

    /// out += Jᵀ v, J = ∂s/∂q: (Jᵀ v)_i = Σ_{l≠i} v_(il) q_l + 2 v_(ii) q_i.
    fn add_jt<V: crate::os::Coefficient>(&self, v: &[V], q: &[f64], out: &mut [f64]) {
        if !crate::os::add_pairs_transposed_simd(v, &q[..self.r], out) {
            add_jt_portable(self.r, v, q, out);
        }
    }

    /// The strain energy W(q).
    pub fn energy(&self, q: &[f64], w: &mut Scratch) -> f64 {
        self.energy_in(q, &mut w.s)
    }

    /// The strain energy W(q), with `s` as the only work space: a caller without a [`Scratch`]
    /// at hand gives a buffer on its stack. Panics if `s` is shorter than
    /// [`Polynomial::pairs`].
    pub fn energy_in(&self, q: &[f64], s: &mut [f64]) -> f64 {
        let (r, np) = (self.r, self.pairs());
        let s = &mut s[..np];
        self.products(q, s);
        let mut e = 0.0;
        for i in 0..r {
            let ki = &self.k[i * r..(i + 1) * r];
            let ti = &self.t[i * np..(i + 1) * np];
            e += q[i] * (0.5 * dot(ki, q) + dot(ti, s));
        }
        for p in 0..np {
            e += 0.5 * s[p] * self.quartic_dot(p, s);
        }
        e
    }

    /// The reduced internal force f = ∂W/∂q = K q + T s + Jᵀ (Tᵀ q + H s) into `f`.
    pub fn force(&self, q: &[f64], f: &mut [f64], w: &mut Scratch) {
        let (r, np) = (self.r, self.pairs());
        self.products(q, &mut w.s);
        // u = Tᵀ q + H s.
        self.quartic_times(&w.s, &mut w.s32, &mut w.u, &mut w.panel_sums);
        // Four rows of T at a time (u read and written once for the four).
        for i in (0..r).step_by(4) {
            let m = (r - i).min(4);
            let d = crate::os::dots_and_axpy(&self.t[i * np..(i + m) * np], &w.s, &q[i..i + m], &mut w.u[..np]);
            for (a, da) in d.iter().enumerate().take(m) {
                f[i + a] = dot(&self.k[(i + a) * r..(i + a + 1) * r], q) + da;
            }
        }
        self.add_jt(&w.u, q, f);
    }

    /// The force (as [`Polynomial::force`]) and the tangent stiffness ∂f/∂q, r × r row-major:
    /// K + T J + (T J)ᵀ + A(Tᵀ q + H s) + Jᵀ H J, with A(v) q = Jᵀ v.
    pub fn force_and_tangent(&self, q: &[f64], f: &mut [f64], kt: &mut [f64], w: &mut Scratch) {
        let (r, np) = (self.r, self.pairs());
        self.force(q, f, w);
        kt.copy_from_slice(&self.k);
        // A(u): u_(kl) off the diagonal, 2 u_(kk) on it (w.u holds Tᵀq + Hs from force).
        let mut p = 0;
        for k in 0..r {
            kt[k * r + k] += 2.0 * w.u[p];
            p += 1;
            for l in k + 1..r {
                kt[k * r + l] += w.u[p];
                kt[l * r + k] += w.u[p];
                p += 1;
            }
        }
        // T J: row i is Jᵀ T_i; added with its transpose.
        for i in 0..r {
            w.row.fill(0.0);
            self.add_jt(&self.t[i * np..(i + 1) * np], q, &mut w.row);
            for m in 0..r {
                kt[i * r + m] += w.row[m];
                kt[m * r + i] += w.row[m];
            }
        }
        // H J column by column (column m: Σ_l H[:, (m l)] q_l, twice for l = m): row (k l) of H
        // (its column, H symmetric) read once for both columns it adds to, q_l times to column
        // k and q_k times to column l.
        w.hj.fill(0.0);
        let mut p = 0;
        for k in 0..r {
            for l in k..r {
                let (before, from_l) = w.hj.split_at_mut(l * np);
                if l == k {
                    self.quartic_axpy(2.0 * q[k], p, &mut from_l[..np]);
                } else if q[k] != 0.0 || q[l] != 0.0 {
                    let col_k = &mut before[k * np..(k + 1) * np];
                    self.quartic_axpy2(p, q[l], col_k, q[k], &mut from_l[..np]);
                }
                p += 1;
            }
        }
        for m in 0..r {
            w.row.fill(0.0);
            self.add_jt(&w.hj[m * np..(m + 1) * np], q, &mut w.row);
            for i in 0..r {
                kt[i * r + m] += w.row[i];
            }
        }
    }

    /// The static equilibrium f(q) = g of the reduced model for the modal load `g`, reached in
    /// `steps` equal load increments, each by Newton's method with a backtracking line search on
    /// the energy W(q) − λ gᵀq. Fails (with the last residual) when an increment does not
    /// converge: a load past a limit point or a basis that cannot carry it.
    pub fn equilibrium(&self, g: &[f64], steps: usize) -> Result<Equilibrium, NotConverged> {
        let r = self.r;
        let mut w = self.scratch();
        let mut q = vec![0.0; r];
        let (mut f, mut kt) = (vec![0.0; r], vec![0.0; r * r]);
        let gnorm = norm(g).max(f64::MIN_POSITIVE);
        let mut iterations = 0;
        let mut residual = 0.0;
        for step in 1..=steps.max(1) {
            let scale = step as f64 / steps.max(1) as f64;
            let potential = |q: &[f64], w: &mut Scratch| self.energy(q, w) - scale * dot(g, q);
            let mut converged = false;
            for _ in 0..50 {
                iterations += 1;
                self.force_and_tangent(&q, &mut f, &mut kt, &mut w);
                let res: Vec<f64> = (0..r).map(|i| scale * g[i] - f[i]).collect();
                residual = norm(&res) / gnorm;
                if residual < 1e-10 {
                    converged = true;
                    break;
                }
                let a = DMatrix::from_row_slice(r, r, &kt);
                let dq = match a.clone().cholesky() {
                    Some(c) => c.solve(&DVector::from_vec(res.clone())),
                    None => match a.lu().solve(&DVector::from_vec(res.clone())) {
                        Some(x) => x,
                        None => return Err(NotConverged { residual, scale }),
                    },
                };
                let p0 = potential(&q, &mut w);
                let mut t = 1.0;
                loop {
                    let trial: Vec<f64> = q.iter().zip(dq.iter()).map(|(a, b)| a + t * b).collect();
                    if potential(&trial, &mut w) <= p0 + 1e-12 * p0.abs() || t < 1e-3 {
                        q = trial;
                        break;
                    }
                    t *= 0.5;
                }
                if q.iter().any(|v| !v.is_finite()) {
                    return Err(NotConverged { residual, scale });
                }
            }
            if !converged {
                return Err(NotConverged { residual, scale });
            }
        }
        Ok(Equilibrium {
            q,
            iterations,
            residual,
        })
    }
}

/// A static equilibrium of the reduced model.
#[derive(Clone, Debug)]
pub struct Equilibrium {
    /// The reduced coordinates.
    pub q: Vec<f64>,
    /// Newton iterations over all increments.
    pub iterations: usize,
    /// ‖g − f(q)‖ / ‖g‖ at the end.
    pub residual: f64,
}

/// An increment of a reduced static solve that did not converge.
#[derive(Clone, Copy, Debug, thiserror::Error)]
#[error(
    "the nonlinear static solve did not converge at {:.0} % of the load (residual {residual:.1e}); \
     lower the load or add modes (mesh.modes) so the basis can carry it",
    scale * 100.0
)]
pub struct NotConverged {
    /// Relative residual of the last iteration.
    pub residual: f64,
    /// Fraction of the load reached.
    pub scale: f64,
}

/// Σ aᵢ bᵢ (a in double or single precision, summed in double): AVX2 + FMA where the processor
/// has them (`os::dot_simd`; the step at r = 30 took 173 µs without, 120 µs with), else in eight
/// independent sums (one running sum is bound by the adder's latency, and the compiler may not
/// reorder it).
pub(crate) fn dot<T: crate::os::Coefficient>(a: &[T], b: &[f64]) -> f64 {
    if let Some(d) = crate::os::dot_simd(a, b) {
        return d;
    }
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0f64; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for k in 0..8 {
            acc[k] += x[k].into() * y[k];
        }
    }
    let tail: f64 = ra.iter().zip(rb).map(|(x, y)| (*x).into() * y).sum();
    acc.iter().sum::<f64>() + tail
}

fn norm(a: &[f64]) -> f64 {
    dot(a, a).sqrt()
}

/// Most Newton iterations of one haptic step's free motion.
pub const STEP_ITERATIONS: usize = 3;

/// A haptic step's Newton iterations stop when the next correction (measured, or estimated
/// from the measured rate) is this small against the step's motion (each evaluation is
/// followed by its correction, so a linear model takes Newmark's step exactly). 1e-6 took 1.6×
/// the force evaluations for the same pull: the soft cantilever's tip pulled through 0.3 L
/// reached −0.27748 m against −0.27744 m, its energy after release held either way
/// (docs/nonlinear.md).
pub const STEP_TOLERANCE: f64 = 1e-4;

/// Steps a tangent stiffness is kept at most in the haptic step (32 ms at 1 kHz); it is made
/// again sooner when modified Newton on it converges slowly ([`SLOW_RATE`]).
pub const TANGENT_MAX_AGE: u32 = 32;

/// Every this many steps, one iterates to the tolerance and measures how fast its corrections
/// shrink; the steps between stop on that estimate.
pub const MEASURE_EVERY: u32 = 4;

/// A correction shrinking by less than this factor an iteration (measured) has the tangent made
/// again at the next step: the part has moved far from where it was made.
pub const SLOW_RATE: f64 = 0.25;

/// Implicit Newmark (β = ¼, γ = ½) for M q̈ + C q̇ + f(q) = g with M = I (mass-orthonormal
/// basis) and C = diag(α + βλᵢ): the step's residual
/// R(q₁) = (4/dt² + 2C/dt)(q₁ − q₀) − (4/dt + C) v₀ − a₀ + f(q₁) − g, its Jacobian
/// A = 4/dt² + 2C/dt + K_t(q₁). A step is [`Stepper::free`] (Newton on R = 0 with g = 0,
/// leaving A factored), then any number of [`Stepper::solve`] (the hands' compliance
/// Φᵥ A⁻¹ Φᵥᵀ), then [`Stepper::finish`] with the hands' modal force (q₁ = q_free + A⁻¹ g, the
/// linearisation the coupling used). No allocation after [`Stepper::new`].
#[derive(Clone, Debug)]
pub struct Stepper {
    dt: f64,
    /// (4/dt² + 2cᵢ/dt), the inertia and damping part of A.
    diag: Vec<f64>,
    c: Vec<f64>,
    /// Acceleration of the last step.
    accel: Vec<f64>,
    q_free: Vec<f64>,
    f: Vec<f64>,
    res: Vec<f64>,
    /// A, then its Cholesky factor L (lower, row-major).
    a: Vec<f64>,
    /// L⁻¹ (lower, row-major), on the way to `inverse`.
    l_inverse: Vec<f64>,
    /// A⁻¹, r × r: made once a tangent (every few dozen steps), it turns each of a step's half
    /// dozen solves (Newton's corrections, the hands' compliance, the step's end) into one
    /// product, where the two triangular solves were chains of dependent operations.
    inverse: Vec<f64>,
    /// A⁻¹ x before it is copied back.
    solved: Vec<f64>,
    /// The linear part of A, the fallback where the tangent is not positive definite.
    linear: Vec<f64>,
    work: Scratch,
    /// Steps since the tangent was last factored.
    age: u32,
    /// How much modified Newton on the current factor shrinks a correction from one iteration
    /// to the next, as last measured (infinite: not yet).
    rate: f64,
    /// A correction still above the tolerance shrank by less than [`SLOW_RATE`]: the factor is
    /// made again at the next step. (A correction already within the tolerance may be round-off
    /// and says nothing of the factor.)
    slow: bool,
    /// Newton iterations taken, over all steps.
    pub iterations: u64,
    /// Tangent stiffnesses made, over all steps.
    pub tangents: u64,
    /// Steps whose tangent was not positive definite (the linear stiffness stood in).
    pub indefinite: u64,
    /// Relative residual ‖R‖/‖(f, inertia)‖ at the last free step's last evaluation.
    pub last_residual: f64,
}

impl Stepper {
    /// At rest, for the model `p`, damping coefficients `c` (one per vector) and step `dt`.
    pub fn new(p: &Polynomial, c: &[f64], dt: f64) -> Stepper {
        let r = p.r;
        let diag: Vec<f64> = c.iter().map(|ci| 4.0 / (dt * dt) + 2.0 * ci / dt).collect();
        let mut linear = p.k.clone();
        for i in 0..r {
            linear[i * r + i] += diag[i];
        }
        Stepper {
            dt,
            diag,
            c: c.to_vec(),
            accel: vec![0.0; r],
            q_free: vec![0.0; r],
            f: vec![0.0; r],
            res: vec![0.0; r],
            a: vec![0.0; r * r],
            l_inverse: vec![0.0; r * r],
            inverse: vec![0.0; r * r],
            solved: vec![0.0; r],
            linear,
            work: p.scratch(),
            age: TANGENT_MAX_AGE,
            rate: f64::INFINITY,
            slow: false,
            iterations: 0,
            tangents: 0,
            indefinite: 0,
            last_residual: 0.0,
        }
    }

    /// Back to rest (accelerations zero).
    pub fn reset(&mut self) {
        self.accel.fill(0.0);
        self.age = TANGENT_MAX_AGE;
        self.rate = f64::INFINITY;
        self.slow = false;
    }

    /// The free motion over the step from (q₀, v₀): Newton on R(q₁) = 0 without the hands'
    /// force, from the constant-acceleration predictor; A is left factored at the last iterate.
    /// Returns q at the end of the step without the hands.
    pub fn free(&mut self, p: &Polynomial, q0: &[f64], v0: &[f64]) -> &[f64] {
        let (r, dt) = (p.r, self.dt);
        for i in 0..r {
            self.q_free[i] = q0[i] + dt * v0[i] + 0.25 * dt * dt * self.accel[i];
        }
        // The tangent costs O(P r²), a force O(P²): the iterations are modified Newton on the
        // last factor, made again when it is TANGENT_MAX_AGE steps old or converges slowly (as
        // stiff integrators keep their Jacobian).
        let refresh = self.age >= TANGENT_MAX_AGE || self.slow;
        // Every MEASURE_EVERY steps (and on a new factor) the step iterates to the tolerance and
        // measures how fast the corrections shrink; the others stop as soon as the next
        // correction, that rate times this one, would be below the tolerance: one force
        // evaluation a step instead of two where the model is nearly linear over a step.
        let measure = refresh || (self.age + 1).is_multiple_of(MEASURE_EVERY);
        let mut last = f64::INFINITY;
        let mut slowest: f64 = 0.0;
        if refresh {
            self.slow = false;
        }
        for it in 0..STEP_ITERATIONS {
            if it == 0 && refresh {
                p.force_and_tangent(&self.q_free, &mut self.f, &mut self.a, &mut self.work);
                self.tangents += 1;
                for i in 0..r {
                    self.a[i * r + i] += self.diag[i];
                }
                if !cholesky_in_place(&mut self.a, r) {
                    self.indefinite += 1;
                    self.a.copy_from_slice(&self.linear);
                    cholesky_in_place(&mut self.a, r);
                }
                inverse_of_factor(&self.a, r, &mut self.l_inverse, &mut self.inverse);
                self.age = 0;
            } else {
                p.force(&self.q_free, &mut self.f, &mut self.work);
            }
            let mut rn = 0.0;
            let mut fnorm = 0.0;
            for i in 0..r {
                let inertia = self.diag[i] * (self.q_free[i] - q0[i]) - (4.0 / dt + self.c[i]) * v0[i] - self.accel[i];
                self.res[i] = -(inertia + self.f[i]);
                rn += self.res[i] * self.res[i];
                fnorm += self.f[i] * self.f[i] + inertia * inertia;
            }
            self.last_residual = (rn / fnorm.max(f64::MIN_POSITIVE)).sqrt();
            if rn == 0.0 {
                break;
            }
            // Every evaluation is followed by its correction (a solve costs r², an evaluation
            // r⁴); a correction that small ends the step without evaluating again.
            self.iterations += 1;
            self.solve_res();
            let (mut dn, mut sn) = (0.0, 0.0);
            for ((qf, d), q) in self.q_free.iter_mut().zip(&self.res).zip(q0) {
                *qf += d;
                dn += d * d;
                sn += (*qf - q).powi(2);
            }
            let tolerance = STEP_TOLERANCE * STEP_TOLERANCE * sn;
            if it > 0 && last > 0.0 {
                let shrink = (dn / last).sqrt();
                slowest = slowest.max(shrink);
                self.slow |= dn > tolerance && shrink > SLOW_RATE;
            }
            last = dn;
            if dn <= tolerance || (!measure && self.rate * self.rate * dn <= tolerance) {
                break;
            }
        }
        // What this step measured (a step that stopped on the estimate measured nothing).
        if (measure && last.is_finite()) || slowest > self.rate {
            self.rate = slowest;
        }
        self.age += 1;
        &self.q_free
    }

    /// q at the end of the step without the hands (the last [`Stepper::free`]).
    pub fn free_motion(&self) -> &[f64] {
        &self.q_free
    }

    /// x ← A⁻¹ x with the factor of the last [`Stepper::free`].
    pub fn solve(&mut self, x: &mut [f64]) {
        symmetric_times(&self.inverse, x, &mut self.solved);
        x.copy_from_slice(&self.solved);
    }

    /// res ← A⁻¹ res.
    fn solve_res(&mut self) {
        symmetric_times(&self.inverse, &self.res, &mut self.solved);
        self.res.copy_from_slice(&self.solved);
    }

    /// Ends the step under the modal force `g`: q₁ = q_free + A⁻¹ g, then a₁ and v₁ by
    /// Newmark's formulas; `q` and `v` hold (q₀, v₀) and get (q₁, v₁).
    pub fn finish(&mut self, q: &mut [f64], v: &mut [f64], g: &[f64]) {
        let (r, dt) = (q.len(), self.dt);
        self.res.copy_from_slice(g);
        self.solve_res();
        for i in 0..r {
            let q1 = self.q_free[i] + self.res[i];
            let a1 = 4.0 / (dt * dt) * (q1 - q[i] - dt * v[i]) - self.accel[i];
            v[i] += 0.5 * dt * (self.accel[i] + a1);
            q[i] = q1;
            self.accel[i] = a1;
        }
    }

    /// The acceleration state (for a rollback).
    pub fn acceleration(&self) -> &[f64] {
        &self.accel
    }

    /// Sets the acceleration state (a rollback).
    pub fn set_acceleration(&mut self, a: &[f64]) {
        self.accel.copy_from_slice(a);
    }
}

/// In-place Cholesky A = L Lᵀ of a row-major r × r matrix (lower triangle written); false when a
/// pivot is not positive. Hand-written: the haptic step cannot allocate, and r ≤ 48.
fn cholesky_in_place(a: &mut [f64], r: usize) -> bool {
    for j in 0..r {
        let mut d = a[j * r + j];
        for k in 0..j {
            d -= a[j * r + k] * a[j * r + k];
        }
        if !(d > 0.0 && d.is_finite()) {
            return false;
        }
        let d = d.sqrt();
        a[j * r + j] = d;
        for i in j + 1..r {
            let mut s = a[i * r + j];
            for k in 0..j {
                s -= a[i * r + k] * a[j * r + k];
            }
            a[i * r + j] = s / d;
        }
    }
    true
}

/// [`Polynomial::add_jt`] a pair at a time (a processor without AVX2 and FMA).
fn add_jt_portable<V: Copy + Into<f64>>(r: usize, v: &[V], q: &[f64], out: &mut [f64]) {
    let mut p = 0;
    for k in 0..r {
        out[k] += 2.0 * v[p].into() * q[k];
        p += 1;
        for l in k + 1..r {
            let vp: f64 = v[p].into();
            out[k] += vp * q[l];
            out[l] += vp * q[k];
            p += 1;
        }
    }
}

/// A⁻¹ = L⁻ᵀ L⁻¹ from the Cholesky factor L (lower, row-major, r × r) into `inverse`, with
/// `l_inverse` as work space (L⁻¹ in its lower triangle): r³/3 products, no allocation.
fn inverse_of_factor(l: &[f64], r: usize, l_inverse: &mut [f64], inverse: &mut [f64]) {
    l_inverse.fill(0.0);
    for j in 0..r {
        l_inverse[j * r + j] = 1.0 / l[j * r + j];
        for i in j + 1..r {
            let s: f64 = (j..i).map(|k| l[i * r + k] * l_inverse[k * r + j]).sum();
            l_inverse[i * r + j] = -s / l[i * r + i];
        }
    }
    for i in 0..r {
        for j in 0..=i {
            let s: f64 = (i..r).map(|k| l_inverse[k * r + i] * l_inverse[k * r + j]).sum();
            inverse[i * r + j] = s;
            inverse[j * r + i] = s;
        }
    }
}

/// y = S x for a symmetric r × r row-major S: the sum of x_j times row j (= column j), each a
/// vector operation.
fn symmetric_times(s: &[f64], x: &[f64], y: &mut [f64]) {
    let r = x.len();
    y.fill(0.0);
    for (j, &xj) in x.iter().enumerate() {
        crate::os::axpy64(xj, &s[j * r..(j + 1) * r], y);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A made-up model of r vectors: diagonal K, smooth T and a symmetric H.
    fn model(r: usize) -> Polynomial {
        let np = r * (r + 1) / 2;
        let mut k = vec![0.0; r * r];
        for i in 0..r {
            k[i * r + i] = 10.0 * (1.0 + i as f64);
        }
        let t = (0..r * np).map(|i| ((i * 7919) % 101) as f64 * 1e-2 - 0.5).collect();
        let h = (0..np * np)
            .map(|i| {
                let (a, b) = (i / np, i % np);
                ((a.min(b) * 31 + a.max(b) * 17) % 97) as f64 * 1e-2 + if a == b { 5.0 } else { 0.0 }
            })
            .collect();
        Polynomial::new(r, k, t, h)
    }

    #[test]
    fn the_first_vectors_keep_their_energy_and_single_precision_only_rounds() {
        let full = model(7);
        let first = full.first(4);
        let q = [0.3, -0.2, 0.5, 0.1];
        let mut padded = q.to_vec();
        padded.resize(7, 0.0);
        let (e4, e7) = (
            first.energy(&q, &mut first.scratch()),
            full.energy(&padded, &mut full.scratch()),
        );
        assert!((e4 - e7).abs() < 1e-12 * e7.abs(), "{e4} vs {e7}");
        let single = full.clone().single_precision();
        assert!(single.h.is_empty() && single.h32.len() == 28 * 28);
        let (mut f, mut g) = (vec![0.0; 7], vec![0.0; 7]);
        let q7 = [0.3, -0.2, 0.5, 0.1, 0.7, -0.4, 0.2];
        full.force(&q7, &mut f, &mut full.scratch());
        single.force(&q7, &mut g, &mut single.scratch());
        let scale = f.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        for (a, b) in f.iter().zip(&g) {
            assert!((a - b).abs() < 1e-6 * scale, "{a} vs {b}");
        }
        // Its sub-model is the same sub-model, in single precision.
        let sub = single.first(4);
        assert!(sub.h.is_empty() && sub.h32.len() == 10 * 10);
        assert!((sub.energy(&q, &mut sub.scratch()) - e4).abs() < 1e-6 * e4.abs());
    }

    /// The single-precision kernels (H s by panels padded to whole blocks, H J in single
    /// precision) only round: at sizes whose pair counts leave 0–3 rows and 12–14 columns over,
    /// the force within 1e-6 and the tangent within 1e-5 of the double-precision model's.
    #[test]
    fn single_precision_kernels_only_round_at_any_size() {
        for r in [7, 9, 12] {
            let full = model(r);
            let single = full.clone().single_precision();
            let q: Vec<f64> = (0..r).map(|i| 0.3 * ((i * 7 % 5) as f64 - 2.0) + 0.05).collect();
            let (mut f, mut g) = (vec![0.0; r], vec![0.0; r]);
            let (mut kf, mut kg) = (vec![0.0; r * r], vec![0.0; r * r]);
            full.force_and_tangent(&q, &mut f, &mut kf, &mut full.scratch());
            single.force_and_tangent(&q, &mut g, &mut kg, &mut single.scratch());
            let scale = f.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            for (a, b) in f.iter().zip(&g) {
                assert!((a - b).abs() < 1e-6 * scale, "r {r}: force {a} vs {b}");
            }
            let scale = kf.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            for (a, b) in kf.iter().zip(&kg) {
                assert!((a - b).abs() < 1e-5 * scale, "r {r}: tangent {a} vs {b}");
            }
        }
    }

    /// The force is the energy's gradient and the tangent the force's Jacobian (central
    /// differences of the plainly summed energy), in double and single precision, at sizes with
    /// whole blocks of four rows of T and rows over.
    #[test]
    fn the_force_is_the_energy_gradient_and_the_tangent_its_jacobian() {
        for r in [4, 7, 9] {
            for p in [model(r), model(r).single_precision()] {
                let q: Vec<f64> = (0..r).map(|i| 0.2 * ((i * 5 % 7) as f64 - 3.0) + 0.05).collect();
                let mut w = p.scratch();
                let (mut f, mut kt) = (vec![0.0; r], vec![0.0; r * r]);
                p.force_and_tangent(&q, &mut f, &mut kt, &mut w);
                let h = 1e-4;
                let mut fs = vec![0.0; r];
                let scale = f.iter().fold(1.0f64, |a, v| a.max(v.abs()));
                for j in 0..r {
                    let mut at = |d: f64| {
                        let mut x = q.clone();
                        x[j] += d;
                        (p.energy(&x, &mut w), x)
                    };
                    let ((ep, xp), (em, xm)) = (at(h), at(-h));
                    let g = (ep - em) / (2.0 * h);
                    assert!((g - f[j]).abs() < 1e-5 * scale, "r {r}: dW/dq{j} {g} vs force {}", f[j]);
                    p.force(&xp, &mut fs, &mut w);
                    let mut fm = vec![0.0; r];
                    p.force(&xm, &mut fm, &mut w);
                    for i in 0..r {
                        let d = (fs[i] - fm[i]) / (2.0 * h);
                        let k = kt[i * r + j];
                        assert!((d - k).abs() < 1e-4 * scale, "r {r}: df{i}/dq{j} {d} vs tangent {k}");
                    }
                }
            }
        }
    }

    /// Jᵀ v in vector lanes equals it a pair at a time, for v in double and in single precision
    /// and rows of pairs shorter and longer than a lane.
    #[test]
    fn pairs_transposed_in_lanes_as_one_at_a_time() {
        for r in [1, 2, 5, 9, 30] {
            let np = r * (r + 1) / 2;
            let v: Vec<f64> = (0..np).map(|i| ((i * 37) % 17) as f64 * 0.1 - 0.8).collect();
            let v32: Vec<f32> = v.iter().map(|&x| x as f32).collect();
            let q: Vec<f64> = (0..r).map(|i| ((i * 13) % 7) as f64 * 0.2 - 0.6).collect();
            let p = model(r);
            let start: Vec<f64> = (0..r).map(|i| i as f64).collect();
            for single in [false, true] {
                let (mut lanes, mut one) = (start.clone(), start.clone());
                if single {
                    p.add_jt(&v32, &q, &mut lanes);
                    add_jt_portable(r, &v32, &q, &mut one);
                } else {
                    p.add_jt(&v, &q, &mut lanes);
                    add_jt_portable(r, &v, &q, &mut one);
                }
                for (a, b) in lanes.iter().zip(&one) {
                    assert!((a - b).abs() < 1e-12 * (1.0 + b.abs()), "r {r}: {a} vs {b}");
                }
            }
        }
    }

    /// The inverse made from the Cholesky factor times A is the identity, and applying it solves
    /// as the two triangular solves would (a made-up symmetric positive definite A, r = 13).
    #[test]
    fn the_inverse_from_the_factor_solves() {
        let r = 13;
        let a: Vec<f64> = (0..r * r)
            .map(|i| {
                let (p, q) = (i / r, i % r);
                ((p.min(q) * 7 + p.max(q) * 3) % 11) as f64 * 0.1 + if p == q { 4.0 + p as f64 } else { 0.0 }
            })
            .collect();
        let mut l = a.clone();
        assert!(cholesky_in_place(&mut l, r));
        let (mut li, mut inv) = (vec![f64::NAN; r * r], vec![f64::NAN; r * r]);
        inverse_of_factor(&l, r, &mut li, &mut inv);
        for i in 0..r {
            for j in 0..r {
                let p: f64 = (0..r).map(|k| inv[i * r + k] * a[k * r + j]).sum();
                let e = if i == j { 1.0 } else { 0.0 };
                assert!((p - e).abs() < 1e-13, "(A^-1 A)[{i}][{j}] = {p}");
            }
        }
        let b: Vec<f64> = (0..r).map(|i| (i as f64 * 0.7).sin()).collect();
        let mut x = vec![0.0; r];
        symmetric_times(&inv, &b, &mut x);
        for i in 0..r {
            let ax: f64 = (0..r).map(|k| a[i * r + k] * x[k]).sum();
            assert!((ax - b[i]).abs() < 1e-13, "row {i}: {ax} vs {}", b[i]);
        }
    }

    /// Without cubic and quartic terms the implicit step is Newmark's average acceleration on
    /// each mode: the linear runtime's `Transition::newmark`, step for step.
    #[test]
    fn a_linear_polynomial_steps_as_newmark() {
        let r = 3;
        let lambda = [4.0, 900.0, 1e6];
        let mut k = vec![0.0; r * r];
        for i in 0..r {
            k[i * r + i] = lambda[i];
        }
        let p = Polynomial::new(r, k, vec![0.0; r * 6], vec![0.0; 36]);
        let (alpha, beta, dt) = (0.5, 1e-4, 1e-3);
        let c: Vec<f64> = lambda.iter().map(|l| alpha + beta * l).collect();
        let mut stepper = Stepper::new(&p, &c, dt);
        let trans: Vec<_> = lambda
            .iter()
            .zip(&c)
            .map(|(l, ci)| crate::integrator::Transition::newmark(*l, *ci, dt))
            .collect();
        let (mut q, mut v) = (vec![0.01, -0.02, 1e-5], vec![0.0, 0.3, -0.1]);
        let (mut qr, mut vr) = (q.clone(), v.clone());
        // The linear scheme starts from the acceleration of the equation of motion.
        let g = [0.5, -1.0, 2.0];
        let a0: Vec<f64> = (0..r).map(|i| g[i] - c[i] * v[i] - lambda[i] * q[i]).collect();
        stepper.set_acceleration(&a0);
        for _ in 0..500 {
            stepper.free(&p, &q, &v);
            stepper.finish(&mut q, &mut v, &g);
            for i in 0..r {
                (qr[i], vr[i]) = trans[i].step(qr[i], vr[i], g[i]);
            }
        }
        for i in 0..r {
            assert!(
                (q[i] - qr[i]).abs() < 1e-9 * qr[i].abs().max(1e-6),
                "q{i}: {} vs {}",
                q[i],
                qr[i]
            );
            assert!(
                (v[i] - vr[i]).abs() < 1e-7 * vr[i].abs().max(1e-3),
                "v{i}: {} vs {}",
                v[i],
                vr[i]
            );
        }
    }

    #[test]
    fn pairs_are_numbered_as_the_products_are_ordered() {
        let r = 7;
        let mut p = 0;
        for k in 0..r {
            for l in k..r {
                assert_eq!(pair_index(r, k, l), p, "({k}, {l})");
                p += 1;
            }
        }
    }
}
