//! Newmark average-acceleration integration of M ü + D u̇ + K u = F(t), D = αM + βK, from rest,
//! for several load cases at once (columns). One stepper serves the full sparse model (the
//! reference) and the truncated modal model: with Rayleigh damping the scheme commutes with the
//! modal decomposition, so the two differ only by the modes left out — the error we report.

use crate::linsolve::{Cholesky, nested_dissection, sym_matvec};
use crate::problem::Discretized;
use anyhow::Result;

/// A linear second-order system on `n` unknowns.
pub trait System {
    /// Unknowns.
    fn size(&self) -> usize;
    /// y = M x.
    fn apply_m(&self, x: &[f64], y: &mut [f64]);
    /// y = K x.
    fn apply_k(&self, x: &[f64], y: &mut [f64]);
    /// X ← (c_k K + c_m M)⁻¹ X for `nrhs` columns (the effective matrix set by `prepare`).
    fn solve_effective(&self, x: &mut [f64], nrhs: usize);
}

/// Time step and damping of an integration.
#[derive(Clone, Copy, Debug)]
pub struct Stepping {
    /// Step, s.
    pub dt: f64,
    /// Rayleigh α, 1/s.
    pub alpha: f64,
    /// Rayleigh β, s.
    pub beta: f64,
}

impl Stepping {
    /// Coefficients (of K, of M) of the effective matrix K + (2/dt) D + (4/dt²) M.
    pub fn effective(&self) -> (f64, f64) {
        let dt = self.dt;
        (1.0 + 2.0 * self.beta / dt, 2.0 * self.alpha / dt + 4.0 / (dt * dt))
    }
}

/// Integrates from rest with the load F (columns of `load`, `n × nrhs`) applied from t = dt on
/// (zero at t = 0: a step), for `steps` steps. After each step `observe(u)` sees the
/// displacement (column-major `n × nrhs`).
pub fn integrate_step_load(
    sys: &dyn System,
    s: Stepping,
    load: &[f64],
    nrhs: usize,
    steps: usize,
    mut observe: impl FnMut(&[f64]),
) {
    let n = sys.size();
    let dt = s.dt;
    let len = n * nrhs;
    let (mut u, mut v, mut a) = (vec![0.0; len], vec![0.0; len], vec![0.0; len]);
    let (mut cm, mut ck, mut tmp) = (vec![0.0; len], vec![0.0; len], vec![0.0; n]);
    let mut rhs = vec![0.0; len];
    for _ in 0..steps {
        // rhs = F + M (4/dt² u + 4/dt v + a) + D (2/dt u + v), D = αM + βK.
        for i in 0..len {
            let w = 2.0 / dt * u[i] + v[i];
            cm[i] = 4.0 / (dt * dt) * u[i] + 4.0 / dt * v[i] + a[i] + s.alpha * w;
            ck[i] = s.beta * w;
        }
        rhs.copy_from_slice(load);
        for c in 0..nrhs {
            let col = c * n..(c + 1) * n;
            sys.apply_m(&cm[col.clone()], &mut tmp);
            rhs[col.clone()].iter_mut().zip(&tmp).for_each(|(r, t)| *r += t);
            if s.beta != 0.0 {
                sys.apply_k(&ck[col.clone()], &mut tmp);
                rhs[col].iter_mut().zip(&tmp).for_each(|(r, t)| *r += t);
            }
        }
        sys.solve_effective(&mut rhs, nrhs);
        for i in 0..len {
            let a_new = 4.0 / (dt * dt) * (rhs[i] - u[i]) - 4.0 / dt * v[i] - a[i];
            v[i] += dt / 2.0 * (a[i] + a_new);
            a[i] = a_new;
            u[i] = rhs[i];
        }
        observe(&u);
    }
}

/// The full sparse model of a discretized space, with K + (2/dt) D + (4/dt²) M factorised.
pub struct FullSystem<'a> {
    d: &'a Discretized,
    effective: Cholesky,
}

impl<'a> FullSystem<'a> {
    /// Factorises the effective matrix for this stepping.
    pub fn new(d: &'a Discretized, s: Stepping) -> Result<FullSystem<'a>> {
        let (ck, cm) = s.effective();
        let values: Vec<f64> = d
            .system
            .k
            .iter()
            .zip(&d.system.m)
            .map(|(k, m)| ck * k + cm * m)
            .collect();
        let ordering = nested_dissection(&d.system.graph, &d.dofs);
        let symbolic = Cholesky::analyse(&d.system.pattern, &ordering)?;
        let effective = Cholesky::factor(symbolic, &d.system.pattern, &values, 0.0)?;
        Ok(FullSystem { d, effective })
    }
}

impl System for FullSystem<'_> {
    fn size(&self) -> usize {
        self.d.dofs.free_count()
    }
    fn apply_m(&self, x: &[f64], y: &mut [f64]) {
        sym_matvec(&self.d.system.pattern, &self.d.system.m, x, y);
    }
    fn apply_k(&self, x: &[f64], y: &mut [f64]) {
        sym_matvec(&self.d.system.pattern, &self.d.system.k, x, y);
    }
    fn solve_effective(&self, x: &mut [f64], nrhs: usize) {
        self.effective.solve_many_in_place(x, nrhs);
    }
}

/// Decoupled modal coordinates: M = I, K = Λ.
pub struct ModalSystem {
    lambda: Vec<f64>,
    effective: Vec<f64>,
}

impl ModalSystem {
    /// Modes with eigenvalues `lambda`, for this stepping.
    pub fn new(lambda: &[f64], s: Stepping) -> ModalSystem {
        let (ck, cm) = s.effective();
        ModalSystem {
            lambda: lambda.to_vec(),
            effective: lambda.iter().map(|l| ck * l + cm).collect(),
        }
    }
}

impl System for ModalSystem {
    fn size(&self) -> usize {
        self.lambda.len()
    }
    fn apply_m(&self, x: &[f64], y: &mut [f64]) {
        y.copy_from_slice(x);
    }
    fn apply_k(&self, x: &[f64], y: &mut [f64]) {
        y.iter_mut()
            .zip(x.iter().zip(&self.lambda))
            .for_each(|(y, (x, l))| *y = x * l);
    }
    fn solve_effective(&self, x: &mut [f64], nrhs: usize) {
        let n = self.lambda.len();
        for c in 0..nrhs {
            x[c * n..(c + 1) * n]
                .iter_mut()
                .zip(&self.effective)
                .for_each(|(x, e)| *x /= e);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One undamped mode under a step force: u = (f/λ)(1 − cos ω t) to Newmark's period error.
    #[test]
    fn single_mode_step_response_matches_closed_form() {
        let lambda = (2.0 * std::f64::consts::PI * 10.0f64).powi(2);
        let s = Stepping {
            dt: 1e-4,
            alpha: 0.0,
            beta: 0.0,
        };
        let sys = ModalSystem::new(&[lambda], s);
        let mut k = 0;
        let mut worst = 0.0f64;
        integrate_step_load(&sys, s, &[2.0], 1, 2000, |u| {
            k += 1;
            // The load is on from t = dt: the response is that of a step at t = dt/2 for the trapezoid.
            let t = k as f64 * s.dt - s.dt / 2.0;
            let exact = 2.0 / lambda * (1.0 - (lambda.sqrt() * t).cos());
            worst = worst.max((u[0] - exact).abs());
        });
        // Amplitude 2 f/λ = 1.0e-3; period error (ω dt)²/12 ≈ 3e-5 relative per period.
        assert!(worst < 2e-3 * 2.0 / lambda, "worst {worst:e}");
    }
}
