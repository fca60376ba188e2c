//! The surface triangle closest to a point without measuring every one: triangles binned by
//! their bounding boxes in a uniform grid, searched in rings of cells around the point's. The
//! felt check places a patch at every surface vertex of a fine mesh on coarser meshes (19k
//! points on the mould): a scan of every triangle for each was seconds.

/// Rings searched before falling back to every triangle (a point whose nearest eligible triangle
/// is far away: a filter that few triangles pass).
const MAX_RINGS: usize = 8;

/// Cells along an axis at most.
const MAX_CELLS: usize = 256;

/// Triangles binned by the cells their bounding boxes overlap.
pub struct TriangleGrid {
    lo: [f64; 3],
    cell: f64,
    dims: [usize; 3],
    /// `items[start[c]..start[c + 1]]` are the triangles overlapping cell c.
    start: Vec<u32>,
    items: Vec<u32>,
    count: usize,
}

impl TriangleGrid {
    /// Bins `count` triangles whose corners `corners(t)` gives.
    pub fn new(count: usize, corners: impl Fn(usize) -> [[f64; 3]; 3]) -> TriangleGrid {
        let boxes: Vec<[[f64; 3]; 2]> = (0..count)
            .map(|t| {
                let c = corners(t);
                let lo = std::array::from_fn(|i| c[0][i].min(c[1][i]).min(c[2][i]));
                let hi = std::array::from_fn(|i| c[0][i].max(c[1][i]).max(c[2][i]));
                [lo, hi]
            })
            .collect();
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for b in &boxes {
            for i in 0..3 {
                lo[i] = lo[i].min(b[0][i]);
                hi[i] = hi[i].max(b[1][i]);
            }
        }
        if count == 0 || (0..3).any(|i| !(lo[i].is_finite() && hi[i].is_finite())) {
            return TriangleGrid {
                lo: [0.0; 3],
                cell: 1.0,
                dims: [1; 3],
                start: vec![0, 0],
                items: Vec::new(),
                count,
            };
        }
        // About one cell per triangle on a surface: a cell as large as a typical triangle.
        let mut extents: Vec<f64> = boxes
            .iter()
            .map(|b| (0..3).map(|i| b[1][i] - b[0][i]).fold(0.0, f64::max))
            .collect();
        let median = extents.select_nth_unstable_by(count / 2, f64::total_cmp).1.to_owned();
        let span = (0..3).map(|i| hi[i] - lo[i]).fold(0.0, f64::max);
        let cell = median.max(span / (MAX_CELLS - 1) as f64).max(f64::MIN_POSITIVE);
        let dims: [usize; 3] = std::array::from_fn(|i| (((hi[i] - lo[i]) / cell) as usize + 1).min(MAX_CELLS));
        let index = |p: f64, i: usize| (((p - lo[i]) / cell).max(0.0) as usize).min(dims[i] - 1);
        let cells = dims[0] * dims[1] * dims[2];
        let mut counts = vec![0u32; cells + 1];
        let each = |b: &[[f64; 3]; 2], f: &mut dyn FnMut(usize)| {
            for x in index(b[0][0], 0)..=index(b[1][0], 0) {
                for y in index(b[0][1], 1)..=index(b[1][1], 1) {
                    for z in index(b[0][2], 2)..=index(b[1][2], 2) {
                        f((x * dims[1] + y) * dims[2] + z);
                    }
                }
            }
        };
        for b in &boxes {
            each(b, &mut |c| counts[c + 1] += 1);
        }
        for c in 0..cells {
            counts[c + 1] += counts[c];
        }
        let mut fill = counts.clone();
        let mut items = vec![0u32; counts[cells] as usize];
        for (t, b) in boxes.iter().enumerate() {
            each(b, &mut |c| {
                items[fill[c] as usize] = t as u32;
                fill[c] += 1;
            });
        }
        TriangleGrid {
            lo,
            cell,
            dims,
            start: counts,
            items,
            count,
        }
    }

    /// The triangle `eligible` accepts with the smallest `distance(t).1`, ties to the lowest
    /// index (as a scan of every triangle in order finds), and what `distance` gave for it.
    pub fn closest<T: Copy>(
        &self,
        p: [f64; 3],
        eligible: impl Fn(usize) -> bool,
        distance: impl Fn(usize) -> (T, f64),
    ) -> Option<(usize, (T, f64))> {
        let mut best: Option<(usize, (T, f64))> = None;
        let consider = |t: usize, best: &mut Option<(usize, (T, f64))>| {
            if !eligible(t) {
                return;
            }
            let d = distance(t);
            let better = match best {
                None => true,
                Some((bt, bd)) => d.1 < bd.1 || (d.1 == bd.1 && t < *bt),
            };
            if better {
                *best = Some((t, d));
            }
        };
        let centre: [isize; 3] = std::array::from_fn(|i| {
            (((p[i] - self.lo[i]) / self.cell).max(0.0) as usize).min(self.dims[i] - 1) as isize
        });
        for k in 0..=MAX_RINGS as isize {
            for x in centre[0] - k..=centre[0] + k {
                for y in centre[1] - k..=centre[1] + k {
                    for z in centre[2] - k..=centre[2] + k {
                        let ring = (x - centre[0])
                            .abs()
                            .max((y - centre[1]).abs())
                            .max((z - centre[2]).abs());
                        let inside = [x, y, z]
                            .iter()
                            .zip(self.dims)
                            .all(|(&v, d)| v >= 0 && (v as usize) < d);
                        if ring != k || !inside {
                            continue;
                        }
                        let c = (x as usize * self.dims[1] + y as usize) * self.dims[2] + z as usize;
                        for &t in &self.items[self.start[c] as usize..self.start[c + 1] as usize] {
                            consider(t as usize, &mut best);
                        }
                    }
                }
            }
            // Every triangle not yet seen lies in cells k + 1 or more rings out: at least k cells away.
            if let Some((_, (_, d))) = best
                && d <= k as f64 * self.cell
            {
                return best;
            }
        }
        // Nothing eligible near: every triangle.
        let mut best = None;
        for t in 0..self.count {
            consider(t, &mut best);
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against a scan of every triangle: the same triangle for points on, inside and far
    /// outside a sphere's facets, with and without a filter.
    #[test]
    fn the_grid_finds_what_a_scan_of_every_triangle_finds() {
        // A faceted sphere: 40 × 20 quads in two triangles each.
        let (nu, nv) = (40, 20);
        let point = |i: usize, j: usize| {
            let (u, v) = (
                std::f64::consts::TAU * i as f64 / nu as f64,
                std::f64::consts::PI * j as f64 / nv as f64,
            );
            [v.sin() * u.cos(), v.sin() * u.sin(), v.cos()]
        };
        let mut tris: Vec<[[f64; 3]; 3]> = Vec::new();
        for i in 0..nu {
            for j in 0..nv {
                let (a, b, c, d) = (point(i, j), point(i + 1, j), point(i + 1, j + 1), point(i, j + 1));
                tris.push([a, b, c]);
                tris.push([a, c, d]);
            }
        }
        let grid = TriangleGrid::new(tris.len(), |t| tris[t]);
        let distance = |p: [f64; 3], t: usize| {
            let c = tris[t];
            let centroid: [f64; 3] = std::array::from_fn(|i| (c[0][i] + c[1][i] + c[2][i]) / 3.0);
            ((), (0..3).map(|i| (p[i] - centroid[i]).powi(2)).sum::<f64>().sqrt())
        };
        let mut seed = 7u64;
        let mut next = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        for scale in [0.3, 1.0, 5.0] {
            for _ in 0..200 {
                let p = [scale * next(), scale * next(), scale * next()];
                for filter in [false, true] {
                    let eligible = |t: usize| !filter || t.is_multiple_of(7);
                    let scan = (0..tris.len())
                        .filter(|&t| eligible(t))
                        .map(|t| (t, distance(p, t)))
                        .min_by(|a, b| a.1.1.total_cmp(&b.1.1).then(a.0.cmp(&b.0)))
                        .map(|(t, _)| t);
                    let found = grid.closest(p, eligible, |t| distance(p, t)).map(|(t, _)| t);
                    assert_eq!(found, scan, "point {p:?}, filtered {filter}");
                }
            }
        }
    }
}
