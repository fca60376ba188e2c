//! Lock-free hand-over of the modal state from the haptic thread to the visualization thread:
//! a sequence lock. The writer never waits; a reader retries if a write overlapped its read.

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
}
