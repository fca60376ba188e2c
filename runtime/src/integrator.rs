//! Modal time integration: each mode q̈ + (α + βλ) q̇ + λ q = f is advanced *exactly* over a step
//! with f held constant, by a 2×2 state transition computed once per mode. Unconditionally
//! stable and exact for any dt; Newmark average acceleration is the alternative the chapter used.

/// Integration scheme.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Scheme {
    /// Exact transition with the force held over the step (default).
    #[default]
    Exact,
    /// Newmark average acceleration (trapezoidal; unconditionally stable, period error O(dt²)).
    Newmark,
}

/// Per-mode coefficients: q' = a q + b v + g f, v' = c q + d v + h f.
#[derive(Clone, Copy, Debug, Default)]
pub struct Transition {
    a: f64,
    b: f64,
    c: f64,
    d: f64,
    g: f64,
    h: f64,
}

/// e^{s t}·cosh(δ t) and e^{s t}·sinh(δ t)/δ for δ² = `delta2` (negative: oscillatory), computed
/// without overflow or cancellation for any step.
fn damped_cosh_sinhc(s: f64, delta2: f64, t: f64) -> (f64, f64) {
    if delta2 < 0.0 {
        let w = (-delta2).sqrt();
        let e = (s * t).exp();
        (e * (w * t).cos(), e * (w * t).sin() / w)
    } else {
        let dl = delta2.sqrt();
        if dl * t < 1e-5 {
            // Series: cosh ≈ 1 + x²/2, sinh(x)/δ ≈ t (1 + x²/6).
            let x2 = delta2 * t * t;
            let e = (s * t).exp();
            (e * (1.0 + x2 / 2.0), e * t * (1.0 + x2 / 6.0))
        } else {
            // Both exponents s ± δ are ≤ 0 for a stable mode: no overflow.
            let (ep, em) = (((s + dl) * t).exp(), ((s - dl) * t).exp());
            ((ep + em) / 2.0, (ep - em) / (2.0 * dl))
        }
    }
}

impl Transition {
    /// Exact transition for stiffness λ > 0, damping c ≥ 0 and step dt.
    pub fn exact(lambda: f64, c: f64, dt: f64) -> Transition {
        // State matrix A = [[0, 1], [−λ, −c]]; e^{A t} = e^{st}[cosh(δt) I + sinh(δt)/δ (A − sI)],
        // s = −c/2, δ² = c²/4 − λ.
        let s = -c / 2.0;
        let (ch, sh) = damped_cosh_sinhc(s, c * c / 4.0 - lambda, dt);
        let (a, b) = (ch - s * sh, sh);
        let (cc, d) = (-lambda * sh, ch + (-c - s) * sh);
        // Constant force: particular solution q = f/λ, so x' = Φ(x − x_p) + x_p.
        Transition {
            a,
            b,
            c: cc,
            d,
            g: (1.0 - a) / lambda,
            h: -cc / lambda,
        }
    }

    /// Newmark average-acceleration step written as the same linear map.
    pub fn newmark(lambda: f64, c: f64, dt: f64) -> Transition {
        // (1 + c dt/2 + λ dt²/4) a' = f − λ(q + dt v + dt²/4 a) − c(v + dt/2 a), eliminate a via
        // the equation of motion at the start (a = f − c v − λ q), f held over the step.
        let den = 1.0 + c * dt / 2.0 + lambda * dt * dt / 4.0;
        // Accelerations: a0 = f − c v − λ q; a1 = (f − λ(q + dt v + dt²/4 a0) − c(v + dt/2 a0)) / den.
        // Coefficients of a0 and a1 in (q, v, f):
        let a0 = [-lambda, -c, 1.0];
        let mut a1 = [0.0; 3];
        for k in 0..3 {
            let base = [-lambda, -lambda * dt - c, 1.0][k];
            a1[k] = (base - (lambda * dt * dt / 4.0 + c * dt / 2.0) * a0[k]) / den;
        }
        // q' = q + dt v + dt²/4 (a0 + a1); v' = v + dt/2 (a0 + a1)
        let q = |k: usize| dt * dt / 4.0 * (a0[k] + a1[k]);
        let v = |k: usize| dt / 2.0 * (a0[k] + a1[k]);
        Transition {
            a: 1.0 + q(0),
            b: dt + q(1),
            c: v(0),
            d: 1.0 + v(1),
            g: q(2),
            h: v(2),
        }
    }

    /// How far one unit of modal force held over a step moves q.
    #[inline(always)]
    pub fn force_gain(&self) -> f64 {
        self.g
    }

    /// Free response: (q, v) after one step without force.
    #[inline(always)]
    pub fn free(&self, q: f64, v: f64) -> (f64, f64) {
        (self.a * q + self.b * v, self.c * q + self.d * v)
    }

    /// Advances (q, v) by one step under modal force f.
    #[inline(always)]
    pub fn step(&self, q: f64, v: f64, f: f64) -> (f64, f64) {
        (
            self.a * q + self.b * v + self.g * f,
            self.c * q + self.d * v + self.h * f,
        )
    }
}

/// All modes of a basis, with their state.
#[derive(Clone, Debug)]
pub struct ModalState {
    /// Modal displacements.
    pub q: Vec<f64>,
    /// Modal velocities.
    pub v: Vec<f64>,
    trans: Vec<Transition>,
    lambda: Vec<f64>,
    dt: f64,
}

impl ModalState {
    /// State at rest for eigenvalues λᵢ, Rayleigh damping (α, β) and time step dt.
    pub fn new(lambda: &[f64], alpha: f64, beta: f64, dt: f64, scheme: Scheme) -> ModalState {
        let damping = lambda.iter().map(|l| alpha + beta * l);
        let trans = lambda
            .iter()
            .zip(damping)
            .map(|(&l, c)| match scheme {
                Scheme::Exact => Transition::exact(l, c, dt),
                Scheme::Newmark => Transition::newmark(l, c, dt),
            })
            .collect();
        let r = lambda.len();
        ModalState {
            q: vec![0.0; r],
            v: vec![0.0; r],
            trans,
            lambda: lambda.to_vec(),
            dt,
        }
    }

    /// Time step.
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// Advances every mode one step under modal forces `f` (length r). No allocation.
    #[inline]
    pub fn step(&mut self, f: &[f64]) {
        for (((q, v), t), &fi) in self.q.iter_mut().zip(self.v.iter_mut()).zip(&self.trans).zip(f) {
            (*q, *v) = t.step(*q, *v, fi);
        }
    }

    /// Modal energy ½ Σ (v² + λ q²) (mass-normalised modes).
    pub fn energy(&self) -> f64 {
        self.q
            .iter()
            .zip(&self.v)
            .zip(&self.lambda)
            .map(|((q, v), l)| 0.5 * (v * v + l * q * q))
            .sum()
    }

    /// Transition of mode j.
    #[inline(always)]
    pub fn transition(&self, j: usize) -> &Transition {
        &self.trans[j]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference by fine RK4 on the same ODE.
    fn rk4(lambda: f64, c: f64, f: f64, q0: f64, v0: f64, t: f64) -> (f64, f64) {
        let n = 200_000;
        let h = t / n as f64;
        let (mut q, mut v) = (q0, v0);
        let acc = |q: f64, v: f64| f - c * v - lambda * q;
        for _ in 0..n {
            let (k1q, k1v) = (v, acc(q, v));
            let (k2q, k2v) = (v + h / 2.0 * k1v, acc(q + h / 2.0 * k1q, v + h / 2.0 * k1v));
            let (k3q, k3v) = (v + h / 2.0 * k2v, acc(q + h / 2.0 * k2q, v + h / 2.0 * k2v));
            let (k4q, k4v) = (v + h * k3v, acc(q + h * k3q, v + h * k3v));
            q += h / 6.0 * (k1q + 2.0 * k2q + 2.0 * k3q + k4q);
            v += h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
        }
        (q, v)
    }

    #[test]
    fn exact_transition_matches_a_fine_reference_in_every_damping_regime() {
        let lambda = 400.0; // ω = 20
        for (c, what) in [
            (0.0, "undamped"),
            (4.0, "under"),
            (40.0, "critical"),
            (40.0 + 1e-9, "near-critical"),
            (200.0, "over"),
        ] {
            let dt = 0.05;
            let t = Transition::exact(lambda, c, dt);
            let (mut q, mut v) = (0.01, -0.3);
            for _ in 0..10 {
                (q, v) = t.step(q, v, 3.0);
            }
            let (rq, rv) = rk4(lambda, c, 3.0, 0.01, -0.3, 0.5);
            assert!(
                (q - rq).abs() < 1e-9 && (v - rv).abs() < 1e-8,
                "{what}: ({q}, {v}) vs ({rq}, {rv})"
            );
        }
    }

    #[test]
    fn newmark_is_second_order_and_conserves_energy_undamped() {
        let lambda = 100.0;
        let (rq, _) = rk4(lambda, 0.0, 0.0, 1.0, 0.0, 1.0);
        let err = |dt: f64| {
            let t = Transition::newmark(lambda, 0.0, dt);
            let (mut q, mut v) = (1.0, 0.0);
            for _ in 0..(1.0 / dt).round() as usize {
                (q, v) = t.step(q, v, 0.0);
            }
            let e = 0.5 * (v * v + lambda * q * q);
            assert!((e - 50.0).abs() < 1e-9 * 50.0, "energy drift {e}");
            (q - rq).abs()
        };
        let (e1, e2) = (err(0.01), err(0.005));
        assert!((e1 / e2 - 4.0).abs() < 0.3, "order: {e1} / {e2}");
    }

    #[test]
    fn held_force_converges_to_static_response() {
        let mut s = ModalState::new(&[10.0, 1e4, 1e8], 1.0, 1e-3, 1e-3, Scheme::Exact);
        let f = [2.0, 3.0, 5.0];
        for _ in 0..100_000 {
            s.step(&f);
        }
        for (i, l) in [10.0, 1e4, 1e8].iter().enumerate() {
            assert!(
                (s.q[i] - f[i] / l).abs() < 1e-9 * (f[i] / l),
                "mode {i}: {} vs {}",
                s.q[i],
                f[i] / l
            );
        }
    }

    #[test]
    fn stays_bounded_for_huge_omega_dt_and_damped_energy_never_grows() {
        for scheme in [Scheme::Exact, Scheme::Newmark] {
            // ω dt up to 1e4.
            let lambda = [1.0, 1e6, 1e14];
            let mut s = ModalState::new(&lambda, 0.5, 1e-6, 1e-3, scheme);
            s.q = vec![1.0, 1e-3, 1e-7];
            s.v = vec![0.0, 1.0, 1.0];
            let mut e = s.energy();
            for _ in 0..10_000 {
                s.step(&[0.0; 3]);
                let e1 = s.energy();
                assert!(
                    e1.is_finite() && e1 <= e * (1.0 + 1e-12),
                    "{scheme:?}: energy grew {e} -> {e1}"
                );
                e = e1;
            }
        }
    }
}
