//! The tetrahedral mesh every stage after the mesher works on (in the layout of the basis file),
//! apart from gmsh: fem, supports, transfer, store and the checks read it without depending on
//! the mesher (`mesh/`, which makes it).

pub mod quality;
pub mod walls;

use nalgebra::Vector3;
use std::collections::HashMap;
use ves_format::ElementKind as Kind;

/// Vertex pairs of the mid-edge nodes 4..9 of a 10-node tet, in gmsh's node order.
pub const TET10_EDGES: [(usize, usize); 6] = [(0, 1), (1, 2), (2, 0), (3, 0), (3, 2), (3, 1)];

/// A tetrahedral mesh in the layout of the basis file (docs/format.md).
#[derive(Clone, Debug)]
pub struct Mesh {
    /// Node coordinates, metres: corner vertices first, then mid-edge nodes.
    pub nodes: Vec<[f64; 3]>,
    /// The first `vertex_count` nodes are corner vertices.
    pub vertex_count: usize,
    /// The element kind (4- or 10-node tets).
    pub kind: Kind,
    /// Connectivity, `nodes_per_tet()` indices per tet, gmsh node order, positive orientation.
    pub tets: Vec<u32>,
    /// Boundary faces on corner vertices, counter-clockwise seen from outside.
    pub surface: Vec<[u32; 3]>,
    /// The CAD face (gmsh's surface tag as imported) each `surface` triangle lies on, one per
    /// triangle; 0: unknown (a mesh not made by gmsh, or a face gmsh did not classify).
    pub surface_faces: Vec<u32>,
}

impl Mesh {
    /// Nodes per tet: 4 or 10.
    pub fn nodes_per_tet(&self) -> usize {
        self.kind.nodes()
    }

    /// Number of tets.
    pub fn tet_count(&self) -> usize {
        self.tets.len() / self.nodes_per_tet()
    }

    /// Node indices of tet `e`.
    pub fn tet(&self, e: usize) -> &[u32] {
        let p = self.nodes_per_tet();
        &self.tets[e * p..(e + 1) * p]
    }

    /// Volume of the straight-sided tet on the corners of tet `e`, m³.
    pub fn corner_volume(&self, e: usize) -> f64 {
        signed_volume(&self.nodes, self.tet(e)).abs() / 6.0
    }

    /// The tets in the order of a Morton (Z-order) curve through their centroids: a loop over
    /// the tets in this order that reads or adds to rows of their vertices finds them in cache
    /// (gmsh numbers the surface vertices first, so a tet's four rows lie thousands of rows
    /// apart, and consecutive tets share none).
    pub fn tets_in_space_order(&self) -> Vec<u32> {
        let (lo, hi) = self.bounding_box();
        let extent = (0..3).map(|k| hi[k] - lo[k]).fold(f64::MIN_POSITIVE, f64::max);
        // 21 bits per axis, interleaved into 63.
        let spread = |x: u64| {
            let mut x = x & 0x1f_ffff;
            x = (x | x << 32) & 0x1f_0000_0000_ffff;
            x = (x | x << 16) & 0x1f_0000_ff00_00ff;
            x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
            x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
            (x | x << 2) & 0x1249_2492_4924_9249
        };
        let key = |e: usize| {
            let t = self.tet(e);
            let cell = |k: usize| {
                let c = t[..4].iter().map(|&n| self.nodes[n as usize][k]).sum::<f64>() / 4.0;
                let x = ((c - lo[k]) / extent * (1u64 << 21) as f64).clamp(0.0, ((1u64 << 21) - 1) as f64);
                spread(x as u64)
            };
            cell(0) | cell(1) << 1 | cell(2) << 2
        };
        let mut order: Vec<(u64, u32)> = (0..self.tet_count()).map(|e| (key(e), e as u32)).collect();
        order.sort_unstable();
        order.into_iter().map(|(_, e)| e).collect()
    }

    /// Bounding box of the nodes.
    pub fn bounding_box(&self) -> ([f64; 3], [f64; 3]) {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in &self.nodes {
            for c in 0..3 {
                lo[c] = lo[c].min(p[c]);
                hi[c] = hi[c].max(p[c]);
            }
        }
        (lo, hi)
    }

    /// Length of the bounding-box diagonal, metres.
    pub fn diameter(&self) -> f64 {
        let (lo, hi) = self.bounding_box();
        (0..3).map(|c| (hi[c] - lo[c]).powi(2)).sum::<f64>().sqrt()
    }

    /// The worst tet by shape, q = 6√2·V / l_rms³ (1 for a regular tet, → 0 for slivers), and
    /// its centroid.
    pub fn worst_quality(&self) -> (f64, [f64; 3]) {
        let mut worst = (f64::INFINITY, [0.0; 3]);
        for e in 0..self.tet_count() {
            let (q, x) = self.shape_quality(e);
            if q < worst.0 {
                worst = (q, std::array::from_fn(|c| x.iter().map(|p| p[c]).sum::<f64>() / 4.0));
            }
        }
        worst
    }

    /// Tet `e`'s shape quality q = 6√2·V / l_rms³ (signed: an inverted tet is negative), and its
    /// corners.
    fn shape_quality(&self, e: usize) -> (f64, [[f64; 3]; 4]) {
        let t = self.tet(e);
        let x: [[f64; 3]; 4] = std::array::from_fn(|k| self.nodes[t[k] as usize]);
        let vol = signed_volume(&self.nodes, t) / 6.0;
        let mut l2 = 0.0;
        for (a, b) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
            l2 += (0..3).map(|c| (x[a][c] - x[b][c]).powi(2)).sum::<f64>();
        }
        let lrms = (l2 / 6.0).sqrt();
        (6.0 * std::f64::consts::SQRT_2 * vol / lrms.powi(3), x)
    }

    /// How many tets have a shape quality in each tenth of [0, 1]: bin k counts
    /// k/10 ≤ q < (k+1)/10, the last also q = 1 (and round-off above), the first also q ≤ 0 or
    /// undefined (a flat or inverted tet).
    pub fn quality_histogram(&self) -> [u64; 10] {
        let mut bins = [0u64; 10];
        for e in 0..self.tet_count() {
            let q = self.shape_quality(e).0;
            let k = if q.is_nan() {
                0
            } else {
                (q * 10.0).floor().clamp(0.0, 9.0) as usize
            };
            bins[k] += 1;
        }
        bins
    }

    /// The worst tet when it has (numerically) no volume: gmsh's Delaunay can leave one flat tet
    /// on a thin wall. Its shape quality and centre.
    pub fn degenerate_tet(&self) -> Option<(f64, [f64; 3])> {
        let (q, at) = self.worst_quality();
        (q <= 1e-12 || q.is_nan()).then_some((q, at))
    }

    /// Corner vertices on the boundary, ascending, each once.
    pub fn surface_vertices(&self) -> Vec<u32> {
        let mut v: Vec<u32> = self.surface.iter().flatten().copied().collect();
        v.sort_unstable();
        v.dedup();
        v
    }

    /// A structured box of `cells` cubes of side `h` (corner at the origin), each cube split into
    /// six tets around its main diagonal (conforming between cubes), with mid-edge nodes when
    /// `kind` is [`Kind::Tet10`]. `displace` may move a grid vertex, given its grid index and position (mid-edge
    /// nodes follow). For tests and synthetic cases.
    pub fn structured_box(
        cells: [usize; 3],
        h: f64,
        kind: Kind,
        displace: impl Fn([usize; 3], [f64; 3]) -> [f64; 3],
    ) -> Mesh {
        let [nx, ny, nz] = cells;
        let id = |i: usize, j: usize, k: usize| ((k * (ny + 1) + j) * (nx + 1) + i) as u32;
        let mut pts = Vec::with_capacity((nx + 1) * (ny + 1) * (nz + 1));
        for k in 0..=nz {
            for j in 0..=ny {
                for i in 0..=nx {
                    pts.push(displace([i, j, k], [i as f64 * h, j as f64 * h, k as f64 * h]));
                }
            }
        }
        let mut tets = Vec::new();
        let mut mid = HashMap::new();
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let c = [
                        id(i, j, k),
                        id(i + 1, j, k),
                        id(i + 1, j + 1, k),
                        id(i, j + 1, k),
                        id(i, j, k + 1),
                        id(i + 1, j, k + 1),
                        id(i + 1, j + 1, k + 1),
                        id(i, j + 1, k + 1),
                    ];
                    for t in [
                        [0, 1, 2, 6],
                        [0, 2, 3, 6],
                        [0, 3, 7, 6],
                        [0, 7, 4, 6],
                        [0, 4, 5, 6],
                        [0, 5, 1, 6],
                    ] {
                        let v = t.map(|q| c[q]);
                        tets.extend(v);
                        if kind == Kind::Tet10 {
                            for (a, b) in TET10_EDGES {
                                let key = (v[a].min(v[b]), v[a].max(v[b]));
                                let m = *mid.entry(key).or_insert_with(|| {
                                    let (x, y) = (pts[key.0 as usize], pts[key.1 as usize]);
                                    pts.push(std::array::from_fn(|q| (x[q] + y[q]) / 2.0));
                                    (pts.len() - 1) as u32
                                });
                                tets.push(m);
                            }
                        }
                    }
                }
            }
        }
        Mesh::from_raw(&pts, &tets, kind)
    }

    /// Builds a mesh from raw connectivity: keeps only nodes used by tets, numbers corner
    /// vertices first, orients every tet positively and extracts the boundary.
    pub fn from_raw(coords: &[[f64; 3]], tets: &[u32], kind: Kind) -> Mesh {
        Mesh::from_raw_numbered(coords, tets, kind).0
    }

    /// [`Mesh::from_raw`], and the new index of each raw node (`u32::MAX`: used by no tet).
    /// [`Mesh::from_raw`], also returning each given node's new index (corner vertices are
    /// numbered first).
    pub fn from_raw_numbered(coords: &[[f64; 3]], tets: &[u32], kind: Kind) -> (Mesh, Vec<u32>) {
        let p = kind.nodes();
        let mut new_index = vec![u32::MAX; coords.len()];
        let mut nodes = Vec::new();
        let mut vertex_count = 0;
        // First pass numbers the corner vertices, second the mid-edge nodes.
        for range in [0..4, 4..p] {
            for tet in tets.chunks_exact(p) {
                for &n in &tet[range.clone()] {
                    if new_index[n as usize] == u32::MAX {
                        new_index[n as usize] = nodes.len() as u32;
                        nodes.push(coords[n as usize]);
                    }
                }
            }
            if vertex_count == 0 {
                vertex_count = nodes.len();
            }
        }
        let mut out: Vec<u32> = tets.iter().map(|&n| new_index[n as usize]).collect();
        for tet in out.chunks_exact_mut(p) {
            if signed_volume(&nodes, tet) < 0.0 {
                // Swap vertices 1 and 2; mid-edge nodes follow: e01↔e02 (4↔6), e31↔e32 (9↔8).
                tet.swap(1, 2);
                if kind == Kind::Tet10 {
                    tet.swap(4, 6);
                    tet.swap(8, 9);
                }
            }
        }
        let surface = boundary_faces(&out, p);
        let mesh = Mesh {
            nodes,
            vertex_count,
            kind,
            tets: out,
            surface_faces: vec![0; surface.len()],
            surface,
        };
        (mesh, new_index)
    }
}

/// Six times the signed volume of the corner tet.
pub fn signed_volume(nodes: &[[f64; 3]], tet: &[u32]) -> f64 {
    let x = |i: usize| Vector3::from(nodes[tet[i] as usize]);
    (x(1) - x(0)).dot(&(x(2) - x(0)).cross(&(x(3) - x(0))))
}

/// Faces that belong to exactly one tet, oriented with the normal away from that tet.
fn boundary_faces(tets: &[u32], p: usize) -> Vec<[u32; 3]> {
    // Faces of a positively oriented tet (0,1,2,3), outward.
    const FACES: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];
    let mut count: HashMap<[u32; 3], (u32, [u32; 3])> = HashMap::with_capacity(tets.len() / p * 2);
    for tet in tets.chunks_exact(p) {
        for f in FACES {
            let face = [tet[f[0]], tet[f[1]], tet[f[2]]];
            let mut key = face;
            key.sort_unstable();
            count.entry(key).and_modify(|e| e.0 += 1).or_insert((1, face));
        }
    }
    let mut faces: Vec<[u32; 3]> = count.into_values().filter(|(n, _)| *n == 1).map(|(_, f)| f).collect();
    faces.sort_unstable();
    faces
}

/// Whether a 10-node tet (gmsh order) has a mid-edge node off its edge's midpoint by more than
/// 1e-9 of the tet's size: where gmsh followed a curved face.
pub fn is_curved(x: &[[f64; 3]]) -> bool {
    let size = (1..4)
        .flat_map(|a| (0..3).map(move |c| (a, c)))
        .map(|(a, c)| (x[a][c] - x[0][c]).abs())
        .fold(0.0, f64::max);
    TET10_EDGES
        .iter()
        .enumerate()
        .any(|(e, &(a, b))| (0..3).any(|c| (x[4 + e][c] - (x[a][c] + x[b][c]) / 2.0).abs() > 1e-9 * size))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Morton order is a permutation of the tets that walks through space: consecutive
    /// tets lie a few cells apart on average, where the same tets listed in a scrambled order
    /// (as gmsh's numbering leaves them for the loops over vertex rows) lie a third of the box
    /// apart.
    #[test]
    fn tets_in_space_order_walk_through_space() {
        let mut mesh = Mesh::structured_box([12, 12, 12], 0.1, Kind::Tet4, |_, p| p);
        let n = mesh.tet_count();
        // Scramble: tet e goes to (e · 7919) mod n (7919 prime, n = 6 · 12³ not a multiple).
        let old = mesh.tets.clone();
        for e in 0..n {
            let to = e * 7919 % n;
            mesh.tets[4 * to..4 * to + 4].copy_from_slice(&old[4 * e..4 * e + 4]);
        }
        let centroid = |e: usize| -> [f64; 3] {
            let t = mesh.tet(e);
            std::array::from_fn(|k| t.iter().map(|&v| mesh.nodes[v as usize][k]).sum::<f64>() / 4.0)
        };
        let mean_step = |order: &[u32]| {
            order
                .windows(2)
                .map(|w| {
                    let (a, b) = (centroid(w[0] as usize), centroid(w[1] as usize));
                    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt()
                })
                .sum::<f64>()
                / (order.len() - 1) as f64
        };
        let order = mesh.tets_in_space_order();
        let mut sorted = order.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..n as u32).collect::<Vec<_>>(), "not a permutation");
        let listed: Vec<u32> = (0..n as u32).collect();
        let (walked, scrambled) = (mean_step(&order), mean_step(&listed));
        assert!(
            walked < 0.15,
            "consecutive tets {walked} m apart in Morton order (cells of 0.1 m)"
        );
        assert!(
            scrambled > 0.3,
            "the scrambled order is {scrambled} m a step: not scrambled"
        );
    }
}
