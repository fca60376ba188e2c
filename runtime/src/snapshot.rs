//! Lock-free hand-over of the modal state from the haptic thread to the visualization thread:
//! a sequence lock. The writer never waits; a reader retries if a write overlapped its read.
//! What is handed over has one layout, [`Published`], for the session and the C ABI alike.

use std::sync::atomic::{AtomicU64, Ordering, fence};

/// A published copy of q (and the time it belongs to).
pub struct Snapshot {
    seq: AtomicU64,
    time: AtomicU64,
    values: Vec<AtomicU64>,
}

impl Snapshot {
    /// Room for `r` values, all zero.
    pub fn new(r: usize) -> Snapshot {
        Snapshot {
            seq: AtomicU64::new(0),
            time: AtomicU64::new(0),
            values: (0..r).map(|_| AtomicU64::new(0)).collect(),
        }
    }

    /// Publishes `q` at time `t` (single writer). Wait-free, no allocation.
    pub fn publish(&self, q: &[f64], t: f64) {
        let s = self.seq.load(Ordering::Relaxed);
        self.seq.store(s + 1, Ordering::Relaxed);
        fence(Ordering::Release);
        self.time.store(t.to_bits(), Ordering::Relaxed);
        for (slot, v) in self.values.iter().zip(q) {
            slot.store(v.to_bits(), Ordering::Relaxed);
        }
        self.seq.store(s + 2, Ordering::Release);
    }

    /// Copies the latest consistent q into `out` and returns its time and sequence number.
    pub fn read(&self, out: &mut [f64]) -> (f64, u64) {
        loop {
            let s1 = self.seq.load(Ordering::Acquire);
            if s1 % 2 == 1 {
                std::hint::spin_loop();
                continue;
            }
            let t = f64::from_bits(self.time.load(Ordering::Relaxed));
            for (o, slot) in out.iter_mut().zip(&self.values) {
                *o = f64::from_bits(slot.load(Ordering::Relaxed));
            }
            fence(Ordering::Acquire);
            if self.seq.load(Ordering::Relaxed) == s1 {
                return (t, s1 / 2);
            }
        }
    }
}

/// The state a haptic thread publishes for drawing: the active space, the part's pose, that
/// space's modal coordinates and each hand's load on the part, laid out once as
/// `[space, pose (7), q (r), per hand: vertex, force x y z]`.
#[derive(Clone, Debug)]
pub struct Published {
    values: Vec<f64>,
    /// Room for modal coordinates (the hands' loads follow them).
    modes: usize,
}

/// Where the pose starts and the modal coordinates start in [`Published`]'s values.
const POSE: usize = 1;
const MODAL: usize = POSE + 7;
/// Values per hand's load: its vertex (−1: none), then its force.
const HAND: usize = 4;

impl Published {
    /// Room for up to `modes` modal coordinates and no hand; space 0, no pose, q = 0.
    pub fn new(modes: usize) -> Published {
        Published::with_hands(modes, 0)
    }

    /// Room for up to `modes` modal coordinates and `hands` hands' loads; nothing loaded.
    pub fn with_hands(modes: usize, hands: usize) -> Published {
        let mut p = Published {
            values: vec![0.0; MODAL + modes + HAND * hands],
            modes,
        };
        p.clear_loads();
        p
    }

    /// Every hand's slot says "no load".
    fn clear_loads(&mut self) {
        for slot in self.values[MODAL + self.modes..].chunks_exact_mut(HAND) {
            slot.copy_from_slice(&[-1.0, 0.0, 0.0, 0.0]);
        }
    }

    /// Sets the hands' loads on the part: (kept vertex of the active space, force on the part
    /// in the part's frame, N); hands beyond the room are dropped, slots not given say none.
    pub fn set_loads(&mut self, loads: impl Iterator<Item = (u32, [f64; 3])>) {
        self.clear_loads();
        let slots = self.values[MODAL + self.modes..].chunks_exact_mut(HAND);
        for (slot, (v, f)) in slots.zip(loads) {
            slot.copy_from_slice(&[f64::from(v), f[0], f[1], f[2]]);
        }
    }

    /// The hands' loads as published: (kept vertex, force on the part, N), hands without one
    /// left out.
    pub fn loads(&self) -> impl Iterator<Item = (u32, [f64; 3])> + '_ {
        self.values[MODAL + self.modes..]
            .chunks_exact(HAND)
            .filter(|s| s[0] >= 0.0)
            .map(|s| (s[0] as u32, [s[1], s[2], s[3]]))
    }

    /// Sets the whole state (`q` may be shorter than the room: the rest is left as it was).
    pub fn set(&mut self, space: usize, pose: [f64; 7], q: &[f64]) {
        self.values[0] = space as f64;
        self.values[POSE..MODAL].copy_from_slice(&pose);
        let q = &q[..q.len().min(self.modes)];
        self.values[MODAL..MODAL + q.len()].copy_from_slice(q);
    }

    /// The active space's index.
    pub fn space(&self) -> usize {
        self.values[0] as usize
    }

    /// The pose: centre of mass in the world, then the unit quaternion body → world (w, x, y, z);
    /// all zero for a part that is not a free body (drawn where it was meshed).
    pub fn pose(&self) -> &[f64] {
        &self.values[POSE..MODAL]
    }

    /// The first `r` modal coordinates (at most the room).
    pub fn modal(&self, r: usize) -> &[f64] {
        &self.values[MODAL..MODAL + r.min(self.modes)]
    }

    /// Sets one modal coordinate (tests and examples).
    pub fn set_modal(&mut self, j: usize, q: f64) {
        self.values[MODAL + j] = q;
    }
}

impl Snapshot {
    /// A snapshot with room for `state`.
    pub fn for_state(state: &Published) -> Snapshot {
        Snapshot::new(state.values.len())
    }

    /// Publishes `state` at time `t` (single writer). Wait-free, no allocation.
    pub fn publish_state(&self, state: &Published, t: f64) {
        self.publish(&state.values, t);
    }

    /// Copies the latest consistent state into `out` (made for this snapshot) and returns its
    /// time and sequence number.
    pub fn read_state(&self, out: &mut Published) -> (f64, u64) {
        self.read(&mut out.values)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    #[test]
    fn readers_never_see_a_torn_state() {
        let snap = Arc::new(Snapshot::new(64));
        let writer = {
            let snap = snap.clone();
            std::thread::spawn(move || {
                let mut q = vec![0.0; 64];
                for k in 1..200_000u64 {
                    q.fill(k as f64);
                    snap.publish(&q, k as f64);
                }
            })
        };
        let mut out = vec![0.0; 64];
        let mut last = 0.0;
        while !writer.is_finished() {
            let (t, _) = snap.read(&mut out);
            assert!(out.iter().all(|&v| v == t), "torn read at {t}");
            assert!(t >= last);
            last = t;
        }
        writer.join().expect("writer");
    }

    #[test]
    fn a_published_state_reads_back_as_written() {
        let mut state = Published::new(3);
        let pose = [1.0, 2.0, 3.0, 1.0, 0.0, 0.0, 0.0];
        state.set(2, pose, &[0.5, -0.25, 4.0]);
        let snap = Snapshot::for_state(&state);
        snap.publish_state(&state, 0.75);
        let mut out = Published::new(3);
        assert_eq!(snap.read_state(&mut out).0, 0.75);
        assert_eq!(
            (out.space(), out.pose(), out.modal(3)),
            (2, &pose[..], &[0.5, -0.25, 4.0][..])
        );
        assert_eq!(out.modal(2), &[0.5, -0.25]);
    }

    #[test]
    fn the_hands_loads_follow_the_modes_and_only_those_given_are_read() {
        let mut state = Published::with_hands(2, 3);
        state.set(0, [0.0; 7], &[1.0, 2.0]);
        state.set_loads([(7, [1.0, -2.0, 3.0]), (0, [0.0, 0.0, 5.0])].into_iter());
        let snap = Snapshot::for_state(&state);
        snap.publish_state(&state, 0.0);
        let mut out = Published::with_hands(2, 3);
        snap.read_state(&mut out);
        assert_eq!(out.modal(5), &[1.0, 2.0]);
        let loads: Vec<_> = out.loads().collect();
        assert_eq!(loads, vec![(7, [1.0, -2.0, 3.0]), (0, [0.0, 0.0, 5.0])]);
        state.set_loads(std::iter::empty());
        assert_eq!(state.loads().count(), 0);
    }
}
