//! Nearest-vertex queries on a static point set: an implicit k-d tree (points reordered so each
//! subtree is a contiguous range, split at the median), queried without allocation.

/// A static 3D k-d tree over points, answering nearest-neighbour queries.
#[derive(Clone, Debug, Default)]
pub struct KdTree {
    /// Points in tree order.
    pts: Vec<[f64; 3]>,
    /// Caller's index of each point in tree order.
    ids: Vec<u32>,
    /// Split axis of the node whose median is at this position.
    axis: Vec<u8>,
}

impl KdTree {
    /// Builds the tree; `ids[i]` is returned for `points[i]`.
    pub fn new(points: &[[f64; 3]], ids: &[u32]) -> KdTree {
        let mut items: Vec<([f64; 3], u32)> = points.iter().copied().zip(ids.iter().copied()).collect();
        let mut axis = vec![0u8; items.len()];
        build(&mut items, &mut axis, 0);
        KdTree {
            pts: items.iter().map(|x| x.0).collect(),
            ids: items.iter().map(|x| x.1).collect(),
            axis,
        }
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.pts.len()
    }

    /// Whether the tree is empty.
    pub fn is_empty(&self) -> bool {
        self.pts.is_empty()
    }

    /// The id and squared distance of the point nearest `q` (`None` if empty). No allocation.
    pub fn nearest(&self, q: [f64; 3]) -> Option<(u32, f64)> {
        self.nearest_two(q).map(|n| (n.id, n.d2))
    }

    /// The point nearest `q` and the squared distance of the second nearest (`None` if empty).
    /// No allocation.
    pub fn nearest_two(&self, q: [f64; 3]) -> Option<Nearest> {
        if self.pts.is_empty() || q.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let mut best = Best {
            at: 0,
            d2: f64::INFINITY,
            second: f64::INFINITY,
        };
        self.search(0, self.pts.len(), q, &mut best, 0.0, &mut [0.0; 3]);
        Some(Nearest {
            id: self.ids[best.at],
            d2: best.d2,
            second_d2: best.second,
        })
    }

    /// Searches the subtree `lo..hi`, whose cell lies at squared distance `rd` from `q`, `off`
    /// being `q`'s offset from the cell along each axis (Arya & Mount's incremental distance: a
    /// far cell is pruned by its whole box, not only by its splitting plane).
    fn search(&self, lo: usize, hi: usize, q: [f64; 3], best: &mut Best, rd: f64, off: &mut [f64; 3]) {
        if lo >= hi {
            return;
        }
        let mid = lo + (hi - lo) / 2;
        let p = self.pts[mid];
        let d2 = (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2);
        if d2 < best.d2 {
            best.second = best.d2;
            (best.at, best.d2) = (mid, d2);
        } else if d2 < best.second {
            best.second = d2;
        }
        let ax = self.axis[mid] as usize;
        let diff = q[ax] - p[ax];
        let (near, far) = if diff < 0.0 {
            ((lo, mid), (mid + 1, hi))
        } else {
            ((mid + 1, hi), (lo, mid))
        };
        self.search(near.0, near.1, q, best, rd, off);
        let old = off[ax];
        let far_rd = rd - old * old + diff * diff;
        // The second nearest must be found too: prune against it.
        if far_rd < best.second {
            off[ax] = diff;
            self.search(far.0, far.1, q, best, far_rd, off);
            off[ax] = old;
        }
    }
}

/// The two best distances of a search so far.
struct Best {
    at: usize,
    d2: f64,
    second: f64,
}

/// A nearest-point query's answer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Nearest {
    /// Caller's id of the nearest point.
    pub id: u32,
    /// Its squared distance.
    pub d2: f64,
    /// Squared distance of the second nearest point (infinite with one point).
    pub second_d2: f64,
}

impl Nearest {
    /// How far a query may move from where this answer was found and keep the same nearest
    /// point: half the gap between the nearest and second nearest distances (every other
    /// point stays at least `√second − δ` away, the nearest at most `√d2 + δ`).
    pub fn stable_within(&self) -> f64 {
        0.5 * (self.second_d2.sqrt() - self.d2.sqrt())
    }
}

/// Axis-aligned bounding box (min, max corners) of some points.
pub(crate) fn bounds<'a>(points: impl IntoIterator<Item = &'a [f64; 3]>) -> [[f64; 3]; 2] {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in points {
        for c in 0..3 {
            lo[c] = lo[c].min(p[c]);
            hi[c] = hi[c].max(p[c]);
        }
    }
    [lo, hi]
}

fn build(items: &mut [([f64; 3], u32)], axis: &mut [u8], depth: usize) {
    if items.len() <= 1 {
        if let Some(a) = axis.first_mut() {
            *a = 0;
        }
        return;
    }
    // Split on the widest extent.
    let [lo, hi] = bounds(items.iter().map(|(p, _)| p));
    let ax = (0..3)
        .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])))
        .unwrap_or(depth % 3);
    let mid = items.len() / 2;
    items.select_nth_unstable_by(mid, |a, b| a.0[ax].total_cmp(&b.0[ax]));
    axis[mid] = ax as u8;
    let (left, right) = items.split_at_mut(mid);
    let (al, ar) = axis.split_at_mut(mid);
    build(left, al, depth + 1);
    build(&mut right[1..], &mut ar[1..], depth + 1);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_equals_brute_force_inside_and_far_outside() {
        let mut s = 12345u64;
        let mut rnd = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let pts: Vec<[f64; 3]> = (0..2000).map(|_| [rnd(), 0.2 * rnd(), 0.05 * rnd()]).collect();
        let ids: Vec<u32> = (0..2000).map(|i| i * 7).collect();
        let tree = KdTree::new(&pts, &ids);
        for k in 0..500 {
            let scale = if k % 5 == 0 { 1e3 } else { 1.2 };
            let q = [scale * (rnd() - 0.5), scale * (rnd() - 0.5), scale * (rnd() - 0.5)];
            let (id, d2) = tree.nearest(q).expect("non-empty");
            let brute = pts
                .iter()
                .map(|p| (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2))
                .fold(f64::INFINITY, f64::min);
            assert_eq!(d2, brute);
            let mut all: Vec<f64> = pts
                .iter()
                .map(|p| (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2))
                .collect();
            all.sort_by(f64::total_cmp);
            let two = tree.nearest_two(q).expect("non-empty");
            assert_eq!((two.d2, two.second_d2), (all[0], all[1]));
            let p = pts[(id / 7) as usize];
            assert_eq!(
                (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2),
                d2
            );
        }
        assert!(tree.nearest([f64::NAN, 0.0, 0.0]).is_none());
    }
}
