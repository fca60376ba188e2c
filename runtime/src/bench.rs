//! Micro-benchmarks of the two real-time paths, for `ves bench`: the haptic step and the
//! full-field update. Medians over batches, so one preempted batch does not skew the figure.

use crate::basis::Basis;
use crate::haptic::{Coupling, HandInput, HandOutput, Haptics};
use crate::integrator::Scheme;
use crate::visual;
use std::sync::Arc;
use std::time::Instant;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Median time of one haptic step (one hand grabbing a surface vertex and moving), ns.
pub fn haptic_step_ns(basis: Arc<Basis>, batches: usize, per_batch: usize) -> f64 {
    median(step_ns(basis, batches, per_batch, false))
}

/// The samples [`haptic_step_ns`] takes its median of: per batch, the mean time of one step, ns
/// (their spread is the timing's noise).
pub fn haptic_step_samples_ns(basis: Arc<Basis>, batches: usize, per_batch: usize) -> Vec<f64> {
    step_ns(basis, batches, per_batch, false)
}

/// Median time of one haptic step of a hand pressing 0.5 mm into the surface at a vertex while
/// sliding ±10 mm across it (button up: the nearest vertex is found every step), ns.
pub fn haptic_press_step_ns(basis: Arc<Basis>, batches: usize, per_batch: usize) -> f64 {
    median(step_ns(basis, batches, per_batch, true))
}

/// Per batch, the mean time of one step, ns (one NaN without a surface vertex).
fn step_ns(basis: Arc<Basis>, batches: usize, per_batch: usize, press: bool) -> Vec<f64> {
    let Some(&v) = basis.surface_vertices.first() else {
        return vec![f64::NAN];
    };
    let p = basis.rest[v as usize];
    let n = basis.normals.get(v as usize).copied().unwrap_or([0.0, 0.0, 1.0]);
    let mut h = Haptics::new(basis, Coupling::default(), 1e-3, Scheme::Exact, 1);
    timed_steps(&mut h, batches, per_batch, |k| {
        let s = (k % 1000) as f64 / 1000.0 - 0.5;
        let position = if press {
            // Across the vertex along a tangent, 0.5 mm inside.
            let tangent = if n[0].abs() < 0.9 {
                [0.0, -n[2], n[1]]
            } else {
                [-n[2], 0.0, n[0]]
            };
            let norm = tangent.iter().map(|x| x * x).sum::<f64>().sqrt().max(1e-300);
            std::array::from_fn(|c| p[c] - 5e-4 * n[c] + 2e-2 * s * tangent[c] / norm)
        } else {
            [p[0], p[1], p[2] + 1e-3 * s]
        };
        HandInput {
            position,
            velocity: [0.0; 3],
            button: !press,
        }
    })
}

/// Per batch of `per_batch` steps of `h` (one hand, its input at step k from `input`), the mean
/// time of a step, ns.
fn timed_steps(h: &mut Haptics, batches: usize, per_batch: usize, input: impl Fn(u64) -> HandInput) -> Vec<f64> {
    let mut out = [HandOutput::default()];
    let mut samples = Vec::with_capacity(batches);
    let mut k = 0u64;
    for _ in 0..batches {
        let t = Instant::now();
        for _ in 0..per_batch {
            k += 1;
            h.step(&[input(k)], &mut out);
        }
        std::hint::black_box(&out);
        samples.push(t.elapsed().as_nanos() as f64 / per_batch as f64);
    }
    samples
}

/// A nonlinear part bent far: one hand grabs the surface vertex the modes make most compliant
/// and moves along its normal through ±`amplitude` of the part's size (its bounding box's
/// diagonal) and back, once a second. Per batch the mean time of a step, and the whole run's
/// Newton iterations and tangents per step (`None` for a linear basis).
pub fn nonlinear_sweep(basis: Arc<Basis>, batches: usize, per_batch: usize, amplitude: f64) -> Option<Sweep> {
    basis.nonlinear.as_ref()?;
    let r = basis.mode_count();
    // Each vertex's modal compliance Σⱼ |φⱼ(v)|²/λⱼ, once.
    let soft = |v: u32| -> f64 {
        (0..r)
            .map(|j| {
                let m = basis.mode(j);
                (0..3).map(|c| f64::from(m[3 * v as usize + c]).powi(2)).sum::<f64>() / basis.eigenvalues[j]
            })
            .sum()
    };
    let (v, _) = basis
        .surface_vertices
        .iter()
        .map(|&v| (v, soft(v)))
        .max_by(|a, b| a.1.total_cmp(&b.1))?;
    let (lo, hi) = basis.rest.iter().fold(([f64::MAX; 3], [f64::MIN; 3]), |(lo, hi), p| {
        (
            std::array::from_fn(|c| lo[c].min(p[c])),
            std::array::from_fn(|c| hi[c].max(p[c])),
        )
    });
    let size = (0..3).map(|c| (hi[c] - lo[c]).powi(2)).sum::<f64>().sqrt();
    let (p, n) = (basis.rest[v as usize], basis.normals[v as usize]);
    let mut h = Haptics::new(basis, Coupling::default(), 1e-3, Scheme::Exact, 1);
    let samples = timed_steps(&mut h, batches, per_batch, |k| {
        let s = amplitude * size * (std::f64::consts::TAU * (k % 1000) as f64 / 1000.0).sin();
        HandInput {
            position: std::array::from_fn(|c| p[c] + s * n[c]),
            velocity: [0.0; 3],
            button: true,
        }
    });
    let k = (batches * per_batch).max(1) as u64;
    let c = h.nonlinear_counts()?;
    Some(Sweep {
        step_ns: median(samples),
        iterations_per_step: c.iterations as f64 / k as f64,
        tangents_per_step: c.tangents as f64 / k as f64,
    })
}

/// What [`nonlinear_sweep`] measured.
#[derive(Clone, Copy, Debug)]
pub struct Sweep {
    /// Median over batches of the mean step, ns.
    pub step_ns: f64,
    /// Newton iterations (force evaluations) per step.
    pub iterations_per_step: f64,
    /// Tangent stiffnesses made per step.
    pub tangents_per_step: f64,
}

/// Median and 99th percentile of the time of gathering a vertex's contact rows (what a hand
/// touching a new vertex costs the haptic step once), ns: over the surface vertices, visited in
/// a scattered order so that their rows are not already in the cache.
pub fn contact_rows_ns(basis: &Basis) -> (f64, f64) {
    let s = &basis.surface_vertices;
    if s.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    let mut rows = vec![0.0; 3 * basis.mode_count()];
    // A stride prime to the count visits every vertex once, far from the one before.
    let stride = (7919..).find(|p| gcd(*p, s.len()) == 1).unwrap_or(1);
    let samples: Vec<f64> = (0..s.len())
        .map(|k| {
            let v = s[k * stride % s.len()] as usize;
            let t = Instant::now();
            basis.gather_contact_rows(v, &mut rows);
            std::hint::black_box(&rows);
            t.elapsed().as_nanos() as f64
        })
        .collect();
    let mut sorted = samples;
    sorted.sort_by(f64::total_cmp);
    let p99 = sorted[(sorted.len() * 99 / 100).min(sorted.len() - 1)];
    (median(sorted), p99)
}

fn gcd(a: usize, b: usize) -> usize {
    if b == 0 { a } else { gcd(b, a % b) }
}

/// A modal state to time the full-field updates with.
fn some_state(basis: &Basis) -> Vec<f64> {
    (0..basis.mode_count()).map(|j| 1e-4 / (1.0 + j as f64)).collect()
}

/// Median of `repeats` timings of `f`, ms.
fn median_ms(repeats: usize, f: impl FnMut()) -> f64 {
    median(samples_ms(repeats, f))
}

/// `repeats` timings of `f`, ms.
fn samples_ms(repeats: usize, mut f: impl FnMut()) -> Vec<f64> {
    (0..repeats.max(1))
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64() * 1e3
        })
        .collect()
}

/// Median time of one full-field update (deformed positions of all kept vertices), ms.
pub fn full_field_ms(basis: &Basis, repeats: usize) -> f64 {
    median(full_field_samples_ms(basis, repeats))
}

/// The samples [`full_field_ms`] takes its median of: `repeats` timings of one update, ms.
pub fn full_field_samples_ms(basis: &Basis, repeats: usize) -> Vec<f64> {
    let q = some_state(basis);
    let mut pos = vec![0.0f32; 3 * basis.vertex_count()];
    samples_ms(repeats, || {
        visual::positions(basis, &q, &mut pos);
        std::hint::black_box(&pos);
    })
}

/// Median times of the full-field stress update σ = Σ qⱼσⱼ over all kept vertices, and of the
/// von Mises pass over its result, ms; `None` without modal stress.
pub fn full_field_stress_ms(basis: &Basis, repeats: usize) -> Option<(f64, f64)> {
    basis.stress.as_ref()?;
    let q = some_state(basis);
    let mut sigma = vec![0.0f32; 6 * basis.vertex_count()];
    let update = median_ms(repeats, || {
        visual::stresses(basis, &q, &mut sigma);
        std::hint::black_box(&sigma);
    });
    let von_mises = median_ms(repeats, || {
        std::hint::black_box(visual::max_von_mises(&sigma));
    });
    Some((update, von_mises))
}

/// A nonlinear basis's kernels, each timed alone at rest-like q (a small deflection of every
/// coordinate): the median of one force evaluation and of one force-and-tangent evaluation, ns
/// (`None` for a linear basis).
pub fn nonlinear_kernels_ns(basis: &Basis, batches: usize, per_batch: usize) -> Option<(f64, f64)> {
    let p = basis.nonlinear.as_ref()?;
    let r = p.r;
    let q: Vec<f64> = (0..r).map(|j| 1e-3 / (1.0 + j as f64)).collect();
    let mut w = p.scratch();
    let (mut f, mut kt) = (vec![0.0; r], vec![0.0; r * r]);
    let mut time = |tangent: bool| {
        let samples = (0..batches)
            .map(|_| {
                let t = Instant::now();
                for _ in 0..per_batch {
                    if tangent {
                        p.force_and_tangent(&q, &mut f, &mut kt, &mut w);
                    } else {
                        p.force(&q, &mut f, &mut w);
                    }
                }
                t.elapsed().as_nanos() as f64 / per_batch as f64
            })
            .collect();
        median(samples)
    };
    let force = time(false);
    Some((force, time(true)))
}
