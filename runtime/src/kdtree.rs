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
        let mut best = [(usize::MAX, f64::INFINITY)];
        self.k_nearest(q, &mut best)?;
        Some((self.ids[best[0].0], best[0].1))
    }

    /// The [`NEIGHBOURS`] points nearest `q` and the distance of the next one: enough to find
    /// the nearest point exactly, without a search, for queries that stay close to `q`
    /// (`None` if empty). No allocation.
    pub fn neighbourhood(&self, q: [f64; 3]) -> Option<Neighbourhood> {
        let mut best = [(usize::MAX, f64::INFINITY); NEIGHBOURS + 1];
        self.k_nearest(q, &mut best)?;
        let mut n = Neighbourhood {
            at: q,
            ids: [0; NEIGHBOURS],
            pts: [[0.0; 3]; NEIGHBOURS],
            len: 0,
            beyond: best[NEIGHBOURS].1.sqrt(),
        };
        for &(at, _) in best[..NEIGHBOURS].iter().take_while(|b| b.0 != usize::MAX) {
            (n.ids[n.len], n.pts[n.len]) = (self.ids[at], self.pts[at]);
            n.len += 1;
        }
        Some(n)
    }

    /// Fills `best` with the positions and squared distances of the `best.len()` points nearest
    /// `q`, nearest first (`usize::MAX` and infinity past the number of points); `None` if the
    /// tree is empty or `q` not finite.
    fn k_nearest(&self, q: [f64; 3], best: &mut [(usize, f64)]) -> Option<()> {
        if self.pts.is_empty() || best.is_empty() || q.iter().any(|v| !v.is_finite()) {
            return None;
        }
        self.search(0, self.pts.len(), q, best, 0.0, &mut [0.0; 3]);
        Some(())
    }

    /// Searches the subtree `lo..hi`, whose cell lies at squared distance `rd` from `q`, `off`
    /// being `q`'s offset from the cell along each axis (Arya & Mount's incremental distance: a
    /// far cell is pruned by its whole box, not only by its splitting plane).
    fn search(&self, lo: usize, hi: usize, q: [f64; 3], best: &mut [(usize, f64)], rd: f64, off: &mut [f64; 3]) {
        if lo >= hi {
            return;
        }
        let mid = lo + (hi - lo) / 2;
        let p = self.pts[mid];
        let d2 = dist2(p, q);
        let last = best.len() - 1;
        if d2 < best[last].1 {
            // Insert in order; a tie keeps the point found first ahead.
            let mut j = last;
            while j > 0 && best[j - 1].1 > d2 {
                best[j] = best[j - 1];
                j -= 1;
            }
            best[j] = (mid, d2);
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
        // Every point kept must be exact, the last one too: prune against it.
        if far_rd < best[last].1 {
            off[ax] = diff;
            self.search(far.0, far.1, q, best, far_rd, off);
            off[ax] = old;
        }
    }
}

/// How many nearest points a [`Neighbourhood`] keeps.
pub const NEIGHBOURS: usize = 8;

/// The points nearest a query point `at` and the distance beyond which all others lie.
#[derive(Clone, Copy, Debug)]
pub struct Neighbourhood {
    pub(crate) at: [f64; 3],
    ids: [u32; NEIGHBOURS],
    pts: [[f64; 3]; NEIGHBOURS],
    len: usize,
    /// Distance from `at` of the nearest point not kept (infinite when all are kept).
    beyond: f64,
}

impl Neighbourhood {
    /// The id of the point nearest `at`, where the neighbourhood was found.
    pub fn first(&self) -> u32 {
        self.ids[0]
    }

    /// The id of the point nearest `q` when this neighbourhood proves it, else `None` (search
    /// again). Exact: `q` moved by δ from `at`, every point not kept is at least `beyond − δ`
    /// from `q`, so the nearest kept point wins if it is closer than that.
    pub fn nearest(&self, q: [f64; 3]) -> Option<u32> {
        let (mut id, mut d2) = (None, f64::INFINITY);
        for i in 0..self.len {
            let di = dist2(self.pts[i], q);
            if di < d2 {
                (id, d2) = (Some(self.ids[i]), di);
            }
        }
        let reach = self.beyond - dist2(self.at, q).sqrt();
        (d2.sqrt() < reach).then_some(id).flatten()
    }
}

/// Squared distance between two points.
fn dist2(a: [f64; 3], b: [f64; 3]) -> f64 {
    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)
}

/// Axis-aligned bounding box (min, max corners) of some points.
pub fn bounds<'a>(points: impl IntoIterator<Item = &'a [f64; 3]>) -> [[f64; 3]; 2] {
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

    /// Uniform numbers in [0, 1) from a xorshift generator.
    fn uniform(mut s: u64) -> impl FnMut() -> f64 {
        move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    #[test]
    fn nearest_equals_brute_force_inside_and_far_outside() {
        let mut rnd = uniform(12345u64);
        let pts: Vec<[f64; 3]> = (0..2000).map(|_| [rnd(), 0.2 * rnd(), 0.05 * rnd()]).collect();
        let ids: Vec<u32> = (0..2000).map(|i| i * 7).collect();
        let tree = KdTree::new(&pts, &ids);
        for k in 0..500 {
            let scale = if k % 5 == 0 { 1e3 } else { 1.2 };
            let q = [scale * (rnd() - 0.5), scale * (rnd() - 0.5), scale * (rnd() - 0.5)];
            let (id, d2) = tree.nearest(q).expect("non-empty");
            let mut all: Vec<f64> = pts.iter().map(|&p| dist2(p, q)).collect();
            all.sort_by(f64::total_cmp);
            assert_eq!(d2, all[0]);
            let n = tree.neighbourhood(q).expect("non-empty");
            let mut kept: Vec<f64> = n.pts[..n.len].iter().map(|&p| dist2(p, q)).collect();
            kept.sort_by(f64::total_cmp);
            assert_eq!(kept, all[..NEIGHBOURS]);
            assert_eq!(n.beyond, all[NEIGHBOURS].sqrt());
            assert_eq!(dist2(pts[(id / 7) as usize], q), d2);
        }
        assert!(tree.nearest([f64::NAN, 0.0, 0.0]).is_none());
    }

    /// Answers from a neighbourhood are the exact nearest point or none: a slow jittered sweep
    /// through random points (across some 15 Voronoi cells), and a walk along the bisector of
    /// two points (a tie at every step, where half the gap to the second nearest point is
    /// zero), against brute force.
    #[test]
    fn a_neighbourhood_answers_exactly_or_not_at_all() {
        let mut rnd = uniform(777u64);
        let random: Vec<[f64; 3]> = (0..2000).map(|_| [rnd(), rnd(), 0.1 * rnd()]).collect();
        let lattice: Vec<[f64; 3]> = (0..400).map(|i| [(i % 20) as f64, (i / 20) as f64, 0.0]).collect();
        let mut walk = [0.1, 0.2, 0.2];
        let mut random_walk = Vec::new();
        for _ in 0..5000 {
            let drift = [1.5e-4, 1e-4, 0.0];
            walk = std::array::from_fn(|c| walk[c] + drift[c] + 2e-4 * (rnd() - 0.5));
            random_walk.push(walk);
        }
        let bisector: Vec<[f64; 3]> = (0..5000).map(|k| [7.5, 5.0 + 1e-4 * k as f64, 0.3]).collect();
        for (pts, queries) in [(random, random_walk), (lattice, bisector)] {
            let ids: Vec<u32> = (0..pts.len() as u32).collect();
            let tree = KdTree::new(&pts, &ids);
            let mut near = tree.neighbourhood(queries[0]).expect("points");
            let mut searches = 0;
            for &q in &queries {
                let id = near.nearest(q).unwrap_or_else(|| {
                    searches += 1;
                    near = tree.neighbourhood(q).expect("points");
                    near.first()
                });
                let brute = pts.iter().map(|&p| dist2(p, q)).fold(f64::INFINITY, f64::min);
                assert_eq!(dist2(pts[id as usize], q), brute, "at {q:?}");
            }
            assert!(
                searches < queries.len() / 20,
                "{searches} searches in {} steps",
                queries.len()
            );
        }
    }
}
