//! How far a basis is from the mesh-converged answer: each kept mode's frequency is followed over
//! coarser meshes of the same space, paired by MAC (modes change order between meshes), and
//! extrapolated at the measured rate ([`richardson`]). docs/accuracy.md says how far to trust it.

pub mod indicator;
pub mod refine;
pub mod richardson;

use crate::mesh::field::SizeField;
use crate::modes::{self, SolverChoice};
use crate::problem::{Discretized, discretize_with};
use crate::scene::{Scene, Voi};
use crate::transfer::{SpaceView, projections};
use anyhow::Result;
use richardson::ModeError;
use std::time::Instant;

/// Each coarser level's element size is this many times the previous one's.
pub const COARSENING: f64 = 1.5;

/// Coarser meshes solved for the estimate: two measure the rate.
pub const LEVELS: usize = 2;

/// A mode pairs with a coarser mesh's modes when their MACs sum to at least this.
pub const MIN_COVERAGE: f64 = 0.7;

/// One mesh of the sequence.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Level {
    /// Nominal element size, m.
    pub size: f64,
    /// Mesh nodes.
    pub nodes: usize,
    /// Free unknowns.
    pub dofs: usize,
    /// Seconds to mesh, assemble and solve it.
    pub seconds: f64,
    /// Per kept mode of the finest mesh, the frequency of its partner on this mesh (Hz; None
    /// when no mode of this mesh resembles it).
    pub frequencies_hz: Vec<Option<f64>>,
}

/// The estimate of a space.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ErrorEstimate {
    /// Per kept mode.
    pub modes: Vec<ModeError>,
    /// The coarser meshes it came from, finest first.
    pub levels: Vec<Level>,
}

impl ErrorEstimate {
    /// Per kept mode, the estimated relative frequency error.
    pub fn relative(&self) -> Vec<f64> {
        self.modes.iter().map(|m| m.relative).collect()
    }
}

/// The largest estimated error and its mode (0-based), over the modes that have one.
pub fn worst(errors: &[f64]) -> Option<(usize, f64)> {
    errors
        .iter()
        .copied()
        .enumerate()
        .filter(|(_, e)| e.is_finite())
        .max_by(|a, b| a.1.total_cmp(&b.1))
}

/// ", estimated discretization error ≤ X % (mode k)" for a summary line; empty without one.
pub fn summary_text(errors: Option<&[f64]>) -> String {
    match errors.and_then(worst) {
        Some((mode, e)) => format!(
            ", estimated discretization error ≤ {:.2} % (mode {})",
            100.0 * e,
            mode + 1
        ),
        None => String::new(),
    }
}

/// Above this estimated error a basis gets a warning.
pub const WARN_ABOVE: f64 = 0.05;

/// The fastest convergence rate in h the estimate credits a mode with. The theory for smooth
/// modes is 2p (eigenvalue errors go as the square of energy-norm errors: h² for 4-node, h⁴ for
/// 10-node tets), but the edges of a clamped face and re-entrant edges make the modes singular
/// there, which caps the rate near 2α with α < 1 the singular exponent. Measured on the
/// cantilever with three fine meshes (docs/accuracy.md): 1.6–2.2 for most modes, 3.5 for a few,
/// with 10-node tets. The coarser meshes of the estimate are often not asymptotic and show rates
/// of 5–10: believing them underestimated the error 2–5×, so a measured rate above 2 is not
/// credited, and a lower one is.
pub fn max_rate(order: u8) -> f64 {
    (2.0 * order as f64).min(2.0)
}

/// Per mode of `fine`, the frequency of its partner among `coarse`'s modes: the MAC-weighted
/// mean of the eigenvalues of the coarse modes it resembles (a mode split over a degenerate
/// pair takes both), or None when they do not represent it.
pub fn partners(coarse: &SpaceView<'_>, coarse_lambda: &[f64], fine: &SpaceView<'_>) -> Vec<Option<f64>> {
    let p = projections(coarse, fine);
    (0..fine.r)
        .map(|i| {
            let mac: Vec<f64> = (0..coarse.r)
                .map(|j| p.t[i * coarse.r + j].powi(2) / p.norms[j].max(f64::MIN_POSITIVE))
                .collect();
            let coverage: f64 = mac.iter().sum();
            if coverage < MIN_COVERAGE {
                return None;
            }
            let (w, wl) = mac
                .iter()
                .zip(coarse_lambda)
                .filter(|(m, _)| **m >= 0.1)
                .fold((0.0, 0.0), |(w, wl), (m, l)| (w + m, wl + m * l));
            (w > 0.0).then(|| (wl / w).max(0.0).sqrt() / (2.0 * std::f64::consts::PI))
        })
        .collect()
}

/// Combines the finest mesh (`dofs`, frequencies) with coarser levels into per-mode errors.
pub fn combine(dofs: usize, frequencies_hz: &[f64], levels: &[Level], order: u8) -> Vec<ModeError> {
    let credited = max_rate(order);
    (0..frequencies_hz.len())
        .map(|i| {
            // The levels on which this mode was paired, in order.
            let mut n = vec![dofs];
            let mut f = vec![frequencies_hz[i]];
            for l in levels {
                match l.frequencies_hz[i] {
                    Some(v) => {
                        n.push(l.dofs);
                        f.push(v);
                    }
                    None => break,
                }
            }
            richardson::estimate(&n, &f, credited).unwrap_or(ModeError {
                relative: f64::NAN,
                measured_rate: None,
                rate: credited,
                reliable: false,
            })
        })
        .collect()
}

/// Meshes `fine`'s space [`LEVELS`] times coarser, solves each and estimates the error of each
/// of `fine`'s modes. A coarser mesh that fails (a size too large for the part) ends the
/// sequence: the estimate uses what was solved, and is None with no coarser mesh at all.
pub fn estimate(
    scene: &Scene,
    voi: Option<&Voi>,
    field: Option<&SizeField>,
    fine: &SpaceView<'_>,
    fine_lambda: &[f64],
    choice: SolverChoice,
) -> Option<ErrorEstimate> {
    let mut coarse = Vec::new();
    for k in 1..=LEVELS {
        if crate::progress::cancelled() {
            return None;
        }
        let factor = COARSENING.powi(k as i32);
        match Solved::at(scene, voi, field, factor, fine.r, choice, true) {
            Ok(s) => coarse.push(s),
            Err(e) => {
                tracing::info!("error estimate: the mesh {factor}× coarser failed: {e:#}");
                break;
            }
        }
    }
    from_coarser(scene.mesh.order, fine, fine_lambda, coarse.iter())
}

/// The inputs of a mesh `factor` × coarser than the scene's (its VOI's and size field's too).
fn coarser(
    scene: &Scene,
    voi: Option<&Voi>,
    field: Option<&SizeField>,
    factor: f64,
) -> (Scene, Option<Voi>, Option<SizeField>) {
    let mut at = scene.clone();
    at.mesh.size *= factor;
    let voi = voi.cloned().map(|mut v| {
        v.size *= factor;
        v
    });
    (at, voi, field.map(|f| f.scaled(factor)))
}

/// The coarser meshes of [`estimate`] made ahead on another thread (gmsh runs in child
/// processes) while the fine mesh is made and solved: [`estimate`] then finds them in the mesh
/// cache. On the mould this takes their meshing off the critical path. [`Prefetch::finish`]
/// waits for all of them; dropped unfinished (the fine mesh failed), it starts no further level
/// and waits only for the one under way.
pub struct Prefetch {
    handle: Option<std::thread::JoinHandle<()>>,
    cancel: std::sync::Arc<std::sync::atomic::AtomicBool>,
}

impl Prefetch {
    /// Starts meshing the coarser levels of a space (nothing when the mesh cache is off).
    pub fn start(scene: &Scene, voi: Option<&Voi>, field: Option<&SizeField>) -> Prefetch {
        use std::sync::atomic::Ordering;
        let levels: Vec<_> = (1..=LEVELS)
            .map(|k| coarser(scene, voi, field, COARSENING.powi(k as i32)))
            .collect();
        let cancel = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let stop = cancel.clone();
        let handle = std::thread::Builder::new()
            .name("ves-prefetch".into())
            .spawn(move || {
                for (at, voi, field) in &levels {
                    if stop.load(Ordering::Relaxed) || !crate::mesh::warm_cache(at, voi.as_ref(), field.as_ref()) {
                        return;
                    }
                }
            })
            .ok();
        Prefetch { handle, cancel }
    }

    /// Waits until every level is in the cache (or failed).
    pub fn finish(mut self) {
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
    }
}

impl Drop for Prefetch {
    fn drop(&mut self) {
        if let Some(h) = self.handle.take() {
            self.cancel.store(true, std::sync::atomic::Ordering::Relaxed);
            let _ = h.join();
        }
    }
}

/// The estimate of `fine`'s modes from solved coarser meshes, finest first (None without any).
fn from_coarser<'a>(
    order: u8,
    fine: &SpaceView<'_>,
    fine_lambda: &[f64],
    coarser: impl Iterator<Item = &'a Solved>,
) -> Option<ErrorEstimate> {
    let levels: Vec<Level> = coarser.map(|s| s.level(fine)).collect();
    if levels.is_empty() {
        return None;
    }
    let fine_f: Vec<f64> = fine_lambda
        .iter()
        .map(|l| l.max(0.0).sqrt() / (2.0 * std::f64::consts::PI))
        .collect();
    let mut modes = combine(fine.dofs.free_count(), &fine_f, &levels, order);
    // Walls one element thick stay one element thick on every coarser mesh: the error of that
    // is invisible to the comparison (docs/accuracy.md), so no mode's estimate is vouched for.
    if fine.mesh.walls().spanning_fraction > crate::mesh::walls::ONE_ELEMENT_THICK {
        for m in &mut modes {
            m.reliable = false;
        }
    }
    Some(ErrorEstimate { modes, levels })
}

/// One mesh of a space, solved.
pub struct Solved {
    /// Element size, m.
    pub size: f64,
    /// Mesh, DOFs, K and M.
    pub d: Discretized,
    /// Its modes (more than the scene keeps: a mode may move up the order between meshes).
    pub modes: modes::Modes,
    /// Seconds for ordering the unknowns (the rest is in `d` and `modes`).
    pub ordering_s: f64,
    /// Seconds to mesh, assemble and solve it.
    pub seconds: f64,
}

impl Solved {
    /// The space meshed with `factor` × the scene's size (its VOI's too; or × `field`'s sizes
    /// when given), solved for more than `kept` modes.
    pub fn at(
        scene: &Scene,
        voi: Option<&Voi>,
        field: Option<&SizeField>,
        factor: f64,
        kept: usize,
        choice: SolverChoice,
        quiet: bool,
    ) -> Result<Solved> {
        // A refinement or an estimate is many meshes: a cancel is seen before each.
        if crate::progress::cancelled() {
            anyhow::bail!("cancelled: nothing was written");
        }
        let t = Instant::now();
        let (at, voi, field) = coarser(scene, voi, field, factor);
        let d = discretize_with(&at, voi.as_ref(), field.as_ref(), quiet)?;
        let count = (kept + kept / 2 + 2).min(d.dofs.free_count() / 3).max(1);
        let (modes, ordering_s) = modes::solve(&d, count, choice)?;
        Ok(Solved {
            size: d.meshing.size,
            d,
            modes,
            ordering_s,
            seconds: t.elapsed().as_secs_f64(),
        })
    }

    /// Its first `r` modes as the transfer sees them.
    pub fn view(&self, r: usize) -> SpaceView<'_> {
        SpaceView::of(&self.d.mesh, &self.d.dofs, &self.d.system, &self.modes, r)
    }

    /// This mesh as a coarser level of `fine`: each of `fine`'s modes paired with its own.
    fn level(&self, fine: &SpaceView<'_>) -> Level {
        let all = self.modes.eigenvalues.len();
        Level {
            size: self.size,
            nodes: self.d.mesh.nodes.len(),
            dofs: self.d.dofs.free_count(),
            seconds: self.seconds,
            frequencies_hz: partners(&self.view(all), &self.modes.eigenvalues, fine),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problem::Discretized;
    use crate::supports::Dofs;
    use crate::tet_mesh::Mesh;

    /// A square-section cantilever 0.8 × 0.1 × 0.1 m clamped at x = 0, 10-node tets of side `h`.
    fn beam(h: f64) -> (Discretized, modes::Modes) {
        let n = (0.1 / h).round() as usize;
        let mesh = Mesh::structured_box([8 * n, n, n], h, crate::fem::element::Kind::Tet10, |_, p| p);
        let mask: Vec<bool> = mesh.nodes.iter().flat_map(|p| [p[0] < 1e-12; 3]).collect();
        let d = Discretized::assemble(
            mesh,
            Dofs::from_mask(&mask),
            crate::material::Material::elastic(2e11, 0.3, 7800.0),
        )
        .expect("assembles");
        let (m, _) = modes::solve(&d, 8, SolverChoice::Arpack).expect("solves");
        (d, m)
    }

    fn view<'a>(d: &'a Discretized, m: &'a modes::Modes) -> SpaceView<'a> {
        SpaceView::of(&d.mesh, &d.dofs, &d.system, m, usize::MAX)
    }

    /// Pairing finds each mode on the coarser mesh whatever order its modes come in, and a
    /// mode of a degenerate pair (the two bending directions of a square section) pairs with
    /// the pair.
    #[test]
    fn modes_pair_across_meshes_in_any_order() {
        let (fd, fm) = beam(0.05);
        let (cd, cm) = beam(0.1);
        let fine = view(&fd, &fm);
        let got = partners(&view(&cd, &cm), &cm.eigenvalues, &fine);
        let ff = fm.frequencies_hz();
        let cf = cm.frequencies_hz();
        for (i, p) in got.iter().enumerate() {
            let p = p.unwrap_or_else(|| panic!("mode {i} ({} Hz) unpaired", ff[i]));
            // The coarse mesh is stiffer, and close: a few % here.
            assert!(
                p >= ff[i] * (1.0 - 1e-9) && p < ff[i] * 1.1,
                "mode {i}: {p} vs {}",
                ff[i]
            );
            let nearest = cf.iter().map(|c| (c - p).abs()).fold(f64::INFINITY, f64::min);
            assert!(
                nearest < 1e-3 * p,
                "mode {i}: partner {p} Hz is no coarse frequency {cf:?}"
            );
        }
        // The same coarse modes, last first.
        let r = cm.eigenvalues.len();
        let nf = cd.dofs.free_count();
        let reversed: Vec<f64> = (0..r)
            .rev()
            .flat_map(|j| cm.vectors[j * nf..(j + 1) * nf].to_vec())
            .collect();
        let lambda: Vec<f64> = cm.eigenvalues.iter().rev().copied().collect();
        let shuffled = SpaceView {
            modes: &reversed,
            ..view(&cd, &cm)
        };
        let again = partners(&shuffled, &lambda, &fine);
        for (a, b) in got.iter().zip(&again) {
            assert!((a.unwrap() - b.unwrap()).abs() < 1e-9 * a.unwrap());
        }
    }
}
