//! The drawing thread: reads the latest published state, makes the whole part's displacement
//! and stress, keeps the whole-part maxima and hands each frame to the embedder's observer.

use super::stats::PartRecord;
use super::{Frame, FrameObserver};
use crate::basis::Basis;
use crate::snapshot::{Published, Snapshot};
use crate::visual;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// What the drawing thread is given.
pub(super) struct Drawing {
    pub bases: Vec<Arc<Basis>>,
    pub snapshot: Arc<Snapshot>,
    /// Room for the largest space's state.
    pub state: Published,
    pub part: Arc<PartRecord>,
    /// Ends the thread when set.
    pub stop: Arc<AtomicBool>,
    /// Shortest time between frames (`None`: as fast as it goes).
    pub cap: Option<Duration>,
    /// The whole part's safety factor below this sets the alarm.
    pub min_safety_factor: f64,
    pub observer: Option<FrameObserver>,
}

/// Per-space buffers, made before the loop: the loop never allocates.
struct Buffers {
    /// u = Φq, part frame, 3 per vertex.
    u: Vec<f32>,
    /// σ = Σ q_j σ_j, 6 per vertex (empty without modal stress).
    sigma: Vec<f32>,
    /// Per support, force and moment (empty without stored reactions).
    reactions: Vec<[f64; 6]>,
    /// Scratch for the reactions' static share.
    work: crate::basis::ReactionWork,
}

impl Drawing {
    /// Starts the thread; it returns its wall time, s, when stopped.
    pub(super) fn spawn(self) -> JoinHandle<f64> {
        std::thread::spawn(move || self.run())
    }

    fn run(mut self) -> f64 {
        let mut buffers: Vec<Buffers> = self
            .bases
            .iter()
            .map(|b| Buffers {
                u: vec![0.0; 3 * b.vertex_count()],
                sigma: vec![0.0; if b.stress.is_some() { 6 * b.vertex_count() } else { 0 }],
                reactions: vec![[0.0; 6]; b.support_reactions.as_ref().map_or(0, |r| r.count())],
                work: crate::basis::ReactionWork::for_basis(b),
            })
            .collect();
        let start = Instant::now();
        while !self.stop.load(Ordering::Relaxed) {
            let t = Instant::now();
            self.draw(&mut buffers);
            if let Some(c) = self.cap {
                std::thread::sleep(c.saturating_sub(t.elapsed()));
            }
        }
        start.elapsed().as_secs_f64()
    }

    /// One frame of the latest state.
    fn draw(&mut self, buffers: &mut [Buffers]) {
        let (time, _) = self.snapshot.read_state(&mut self.state);
        let i = self.state.space().min(self.bases.len() - 1);
        let (basis, buf) = (&self.bases[i], &mut buffers[i]);
        let q = self.state.modal(basis.mode_count());
        visual::displacements(basis, q, &mut buf.u);
        std::hint::black_box(&buf.u);
        // Whole-part validity: the largest surface-edge strain (rigid motion carries none: the
        // elastic displacement alone, against the rest lengths in f64).
        self.part.surface_strain.raise(visual::max_edge_strain(basis, &buf.u));
        let has_stress = visual::stresses(basis, q, &mut buf.sigma);
        let (mut below, mut peak) = (false, None);
        if has_stress {
            let (vm, at) = visual::max_von_mises(&buf.sigma);
            peak = Some((vm, at));
            self.part.von_mises.raise(vm);
            below = basis.yield_strength.is_some_and(|y| y < self.min_safety_factor * vm);
            let (p_stress, p_strain) = visual::max_principal(&buf.sigma, basis.elastic);
            self.part.principal_stress.raise(p_stress);
            if let Some(e) = p_strain {
                self.part.principal_strain.raise(e);
            }
            self.part.alarm.store(below, Ordering::Relaxed);
            self.part.alarm_frames.fetch_add(u64::from(below), Ordering::Relaxed);
        }
        let reactions = basis.support_reactions.as_ref().map(|_| {
            basis.support_reactions_loaded(q, self.state.loads(), &mut buf.work, &mut buf.reactions);
            &buf.reactions[..]
        });
        // The peaks are the first space's supports (a volume of interest's space has none).
        if i == 0 {
            for (max, r) in self.part.support_force.iter().zip(reactions.unwrap_or_default()) {
                max.raise((r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt());
            }
        }
        if let Some(f) = self.observer.as_mut() {
            f(&Frame {
                space: i,
                modal: q,
                pose: self.state.pose(),
                displacements: &buf.u,
                stress: has_stress.then_some(&buf.sigma[..]),
                alarm: below,
                von_mises_max: peak,
                reactions,
                time,
            });
        }
        self.part.frames.fetch_add(1, Ordering::Relaxed);
    }
}
