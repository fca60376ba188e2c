//! Richardson extrapolation of one mode's frequency over a sequence of meshes, at a convergence
//! rate measured from three of them (not assumed, unless only two exist).
//!
//! Model: f(h) = f* + C·h^q, with h = N^(-1/3) for a mesh of N unknowns (gmsh's meshes are not
//! nested and keep feature-driven sizes, so the unknowns say more about the resolution than the
//! nominal size does).

/// One mode's estimated discretization error on the finest mesh.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ModeError {
    /// |f_h − f*| / f*, f* the extrapolated (mesh-converged) frequency.
    pub relative: f64,
    /// The rate q measured from three meshes (None with two, or when it could not be measured).
    pub measured_rate: Option<f64>,
    /// The rate used: the measured one, capped at the element's theoretical rate.
    pub rate: f64,
    /// False when the meshes are not in the asymptotic range (frequencies not converging
    /// monotonically, or a rate far below theory), or fewer than three meshes had the mode:
    /// then `relative` extrapolates the change to the next coarser mesh at the credited rate, a
    /// rough guide only.
    pub reliable: bool,
}

/// Rates below this mean the meshes are not asymptotic (or the mode is not resolved).
pub const MIN_RATE: f64 = 0.5;

/// The slowest rate in h an eigenvalue of a 3D elastic solid converges with: at a crack front
/// (singular exponent α = 1/2) the energy error goes as h^α, the eigenvalue's as h^(2α) = h;
/// any other edge or corner of a solid is less singular. A measured rate between [`MIN_RATE`]
/// and this is a pre-asymptotic sequence (on thin walls: one element through the thickness on
/// the coarser meshes, two on the finer), not a physical rate: it is credited as this one and
/// the mode marked unreliable. Crediting it as measured overestimated 4–16× on the ribplate.
pub const SLOWEST_RATE: f64 = 1.0;

/// Estimates the error of `f[0]` (the finest mesh, `dofs[0]` unknowns) from the same mode on
/// coarser meshes `f[1..]` (`dofs` decreasing). `max_rate` is the fastest rate in h to credit
/// (see `accuracy::max_rate`): a measured rate above it is taken as noise, and it is the rate
/// used when none can be measured (then the estimate is marked unreliable).
pub fn estimate(dofs: &[usize], f: &[f64], max_rate: f64) -> Option<ModeError> {
    if f.len() < 2 || dofs.len() != f.len() || f.iter().any(|v| !v.is_finite() || *v <= 0.0) {
        return None;
    }
    let h: Vec<f64> = dofs.iter().map(|&n| (n.max(1) as f64).powf(-1.0 / 3.0)).collect();
    if h[1] <= h[0] * (1.0 + 1e-9) {
        return None;
    }
    let d1 = f[1] - f[0];
    let at_rate = |q: f64| -> f64 {
        let shift = d1 * h[0].powf(q) / (h[1].powf(q) - h[0].powf(q));
        let converged = f[0] - shift;
        (shift / converged).abs()
    };
    let rough = ModeError {
        relative: at_rate(max_rate),
        measured_rate: None,
        rate: max_rate,
        reliable: false,
    };
    if f.len() == 2 {
        // No rate can be measured: the theoretical one, and say the estimate is not checked.
        return Some(rough);
    }
    if h[2] <= h[1] * (1.0 + 1e-9) {
        return None;
    }
    let d2 = f[2] - f[1];
    if d1.abs() <= 1e-13 * f[0] && d2.abs() <= 1e-13 * f[0] {
        // Converged to round-off.
        return Some(ModeError {
            relative: 0.0,
            measured_rate: None,
            rate: max_rate,
            reliable: true,
        });
    }
    let Some(q) = measured_rate(&h, d1, d2) else {
        return Some(rough);
    };
    if q < MIN_RATE {
        return Some(ModeError {
            measured_rate: Some(q),
            ..rough
        });
    }
    // Above the credited maximum is noise from non-nested meshes: the theoretical rate is the safer one.
    let used = q.clamp(SLOWEST_RATE.min(max_rate), max_rate);
    Some(ModeError {
        relative: at_rate(used),
        measured_rate: Some(q),
        rate: used,
        reliable: q >= SLOWEST_RATE,
    })
}

/// The q with (h1^q − h0^q)/(h2^q − h1^q) = d1/d2, when the differences shrink with h.
fn measured_rate(h: &[f64], d1: f64, d2: f64) -> Option<f64> {
    let rho = d1 / d2;
    if !rho.is_finite() || rho <= 0.0 {
        return None;
    }
    let g = |q: f64| (h[1].powf(q) - h[0].powf(q)) / (h[2].powf(q) - h[1].powf(q)) - rho;
    // g decreases from ln(h1/h0)/ln(h2/h1) − ρ (q → 0) to −ρ (q → ∞).
    let (mut lo, mut hi) = (1e-3, 30.0);
    if g(lo) <= 0.0 {
        return None;
    }
    if g(hi) >= 0.0 {
        return Some(hi);
    }
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if g(mid) > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some(0.5 * (lo + hi))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn f_of(n: usize, q: f64) -> f64 {
        // f* = 100, C = 300: a few % on coarse meshes.
        100.0 + 300.0 * (n as f64).powf(-q / 3.0)
    }

    #[test]
    fn an_exact_power_law_gives_its_rate_and_its_error() {
        let dofs = [40_000, 12_000, 3_500];
        for q in [1.2, 2.0, 3.5] {
            let f: Vec<f64> = dofs.iter().map(|&n| f_of(n, q)).collect();
            let e = estimate(&dofs, &f, 4.0).unwrap();
            let truth = (f[0] - 100.0) / 100.0;
            assert!(e.reliable);
            assert!((e.measured_rate.unwrap() - q).abs() < 1e-6, "{e:?}");
            assert!((e.relative - truth).abs() < 1e-9 * truth.max(1e-3), "{e:?} vs {truth}");
        }
    }

    #[test]
    fn a_rate_above_theory_is_capped_and_overestimates_safely() {
        let dofs = [40_000, 12_000, 3_500];
        let f: Vec<f64> = dofs.iter().map(|&n| f_of(n, 6.0)).collect();
        let e = estimate(&dofs, &f, 4.0).unwrap();
        let truth = (f[0] - 100.0) / 100.0;
        assert_eq!(e.rate, 4.0);
        assert!(e.relative > truth, "{e:?} vs {truth}");
    }

    /// A rate below any physical one (here 0.7) is credited as the slowest physical rate, and
    /// not vouched for.
    #[test]
    fn a_rate_below_physics_is_credited_as_the_slowest_physical_one() {
        let dofs = [40_000, 12_000, 3_500];
        let f: Vec<f64> = dofs.iter().map(|&n| f_of(n, 0.7)).collect();
        let e = estimate(&dofs, &f, 2.0).unwrap();
        assert!((e.measured_rate.unwrap() - 0.7).abs() < 1e-6, "{e:?}");
        assert_eq!(e.rate, SLOWEST_RATE);
        assert!(!e.reliable);
        let h: Vec<f64> = dofs.iter().map(|&n| (n as f64).powf(-1.0 / 3.0)).collect();
        let shift = (f[1] - f[0]) * h[0] / (h[1] - h[0]);
        assert!((e.relative - shift / (f[0] - shift)).abs() < 1e-12, "{e:?}");
    }

    #[test]
    fn non_monotone_or_stalled_sequences_are_flagged() {
        let dofs = [40_000, 12_000, 3_500];
        let e = estimate(&dofs, &[101.0, 102.0, 101.5], 4.0).unwrap();
        assert!(!e.reliable && e.rate == 4.0);
        let h: Vec<f64> = dofs.iter().map(|&n| (n as f64).powf(-1.0 / 3.0)).collect();
        let shift = h[0].powi(4) / (h[1].powi(4) - h[0].powi(4));
        assert!((e.relative - shift / (101.0 - shift)).abs() < 1e-12, "{e:?}");
        // Differences that do not shrink: rate far below any element's.
        let e = estimate(&dofs, &[101.0, 102.0, 103.05], 4.0).unwrap();
        assert!(!e.reliable, "{e:?}");
        // Two meshes: the theoretical rate, not marked reliable.
        let e = estimate(&dofs[..2], &[f_of(40_000, 4.0), f_of(12_000, 4.0)], 4.0).unwrap();
        assert!(!e.reliable && e.measured_rate.is_none());
        assert!((e.relative - (f_of(40_000, 4.0) - 100.0) / 100.0).abs() < 1e-9);
        assert!(estimate(&dofs, &[f64::NAN, 1.0, 2.0], 4.0).is_none());
    }
}
