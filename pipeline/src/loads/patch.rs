//! The hand's contact patch (`[contact] radius`, docs/scene.md): a fingertip's force spread over
//! the surface around the touched point instead of one vertex.
//!
//! A point load in a 3-D solid has no converged displacement (it grows without bound as the mesh
//! is refined), so a hand acting on one vertex feels a stiffness set by the mesh. The patch spreads
//! the force F as a pressure p(ρ) = (1 − ρ²)² (ρ = distance / radius: largest at the centre,
//! falling smoothly to zero at the rim, as under a fingertip) and loads node a with the consistent
//! share wₐ F, wₐ = ∫ Nₐ p dA / ∫ p dA over the surface triangles the patch covers (Nₐ the
//! triangle's 3- or 6-node shape functions). The coupling reads the displacement with the same
//! weights, ū = Σ wₐ uₐ, so the work done is F·ū and the felt compliance W K⁻¹ Wᵀ converges
//! under refinement to that of the real part under a finger.
//!
//! The patch covers the surface triangles connected to the centre whose flat normal faces within
//! [`MAX_TURN`] of the centre's normal and that come within the radius: it does not reach around
//! a thin wall to the other side.

use super::vector::{DEGREE_5_RULE, TRIANGLE_RULE, area_vector, triangle_nodes};
use crate::tet_mesh::Mesh;
use rayon::prelude::*;
use std::collections::HashMap;

/// A triangle joins the patch when its normal is within this cosine of the centre's normal
/// (about 78°: both faces at a box edge or corner, not the far side of a thin wall).
const MAX_TURN: f64 = 0.2;

/// Sub-triangles per patch radius along an edge when integrating the pressure.
const SUBDIVISIONS_PER_RADIUS: f64 = 6.0;

/// Largest subdivision of a triangle edge (a triangle 8 radii long is integrated at 1/48 of it).
const MAX_SUBDIVISION: usize = 48;

/// Where a cell of a triangle lies against a patch's disk.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Place {
    /// Wholly outside: skipped.
    Outside,
    /// Wholly inside: the pressure is smooth there, the cell is integrated whole.
    Inside,
    /// Across the rim: split in four.
    Rim,
}

/// One patch: the loaded nodes and their weights (summing to 1).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Patch {
    /// Node indices (corner vertices and, with 10-node tets, mid-edge nodes), ascending.
    pub nodes: Vec<u32>,
    /// Share of the force at each node; they sum to 1 (some may be negative: the corner shape
    /// functions of a 6-node triangle are).
    pub weights: Vec<f64>,
}

impl Patch {
    /// A point contact at `node`.
    pub fn point(node: u32) -> Patch {
        Patch {
            nodes: vec![node],
            weights: vec![1.0],
        }
    }

    /// Σ wₐ uₐ for a full displacement vector (3n, row 3i+c).
    pub fn average(&self, u: &[f64]) -> [f64; 3] {
        let mut out = [0.0; 3];
        for (&a, &w) in self.nodes.iter().zip(&self.weights) {
            for (c, o) in out.iter_mut().enumerate() {
                *o += w * u[3 * a as usize + c];
            }
        }
        out
    }
}

/// The patches of every surface vertex, as stored in a basis (`contact/`).
pub type Patches = ves_format::Contact;

/// The surface of a mesh as the patches need it: each triangle's nodes, flat normal and
/// neighbours across its edges, and the triangles around each corner vertex.
pub struct Surface<'a> {
    mesh: &'a Mesh,
    nodes: Vec<Vec<u32>>,
    normals: Vec<[f64; 3]>,
    neighbours: Vec<[usize; 3]>,
    around: HashMap<u32, Vec<usize>>,
    /// The triangles binned in space, made on the first search.
    grid: std::sync::OnceLock<super::nearest::TriangleGrid>,
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn unit(v: [f64; 3]) -> [f64; 3] {
    let n = dot(v, v).sqrt();
    if n > 0.0 { v.map(|c| c / n) } else { [0.0; 3] }
}

/// Distance from `p` to the segment ab.
fn segment_distance(p: [f64; 3], a: [f64; 3], b: [f64; 3]) -> f64 {
    let (ab, ap) = (sub(b, a), sub(p, a));
    let t = (dot(ap, ab) / dot(ab, ab).max(f64::MIN_POSITIVE)).clamp(0.0, 1.0);
    let d = sub(ap, ab.map(|c| c * t));
    dot(d, d).sqrt()
}

/// The closest point to `p` on triangle abc and its distance.
fn closest_on_triangle(p: [f64; 3], [a, b, c]: [[f64; 3]; 3]) -> ([f64; 3], f64) {
    let n = unit(cross(sub(b, a), sub(c, a)));
    let h = dot(sub(p, a), n);
    let q = sub(p, n.map(|x| x * h));
    let inside = [(a, b), (b, c), (c, a)]
        .iter()
        .all(|&(u, v)| dot(cross(sub(v, u), sub(q, u)), n) >= 0.0);
    if inside {
        return (q, h.abs());
    }
    [(a, b), (b, c), (c, a)]
        .iter()
        .map(|&(u, v)| {
            let uv = sub(v, u);
            let t = (dot(sub(p, u), uv) / dot(uv, uv).max(f64::MIN_POSITIVE)).clamp(0.0, 1.0);
            let x = [u[0] + t * uv[0], u[1] + t * uv[1], u[2] + t * uv[2]];
            let d = sub(p, x);
            (x, dot(d, d).sqrt())
        })
        .fold(([0.0; 3], f64::INFINITY), |best, x| if x.1 < best.1 { x } else { best })
}

/// The pressure profile at ρ = distance / radius.
fn profile(rho2: f64) -> f64 {
    if rho2 >= 1.0 { 0.0 } else { (1.0 - rho2) * (1.0 - rho2) }
}

impl<'a> Surface<'a> {
    /// Indexes `mesh`'s surface.
    pub fn new(mesh: &'a Mesh) -> Surface<'a> {
        let all: Vec<usize> = (0..mesh.surface.len()).collect();
        let nodes = triangle_nodes(mesh, &all);
        let corner = |t: &[u32; 3]| t.map(|v| mesh.nodes[v as usize]);
        let normals = mesh
            .surface
            .iter()
            .map(|t| {
                let [a, b, c] = corner(t);
                unit(cross(sub(b, a), sub(c, a)))
            })
            .collect();
        let mut edges: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
        let mut around: HashMap<u32, Vec<usize>> = HashMap::new();
        for (k, t) in mesh.surface.iter().enumerate() {
            for e in 0..3 {
                let (a, b) = (t[e], t[(e + 1) % 3]);
                edges.entry((a.min(b), a.max(b))).or_default().push(k);
                around.entry(a).or_default().push(k);
            }
        }
        let neighbours = mesh
            .surface
            .iter()
            .enumerate()
            .map(|(k, t)| {
                std::array::from_fn(|e| {
                    let (a, b) = (t[e], t[(e + 1) % 3]);
                    edges[&(a.min(b), a.max(b))]
                        .iter()
                        .copied()
                        .find(|&o| o != k)
                        .unwrap_or(usize::MAX)
                })
            })
            .collect();
        Surface {
            mesh,
            nodes,
            normals,
            neighbours,
            around,
            grid: std::sync::OnceLock::new(),
        }
    }

    /// The outward unit normal at corner vertex `v`: its triangles' normals, weighted by area
    /// through the unit normals' mean (zero when `v` is on no surface triangle).
    pub fn normal_at(&self, v: u32) -> [f64; 3] {
        let Some(around) = self.around.get(&v) else {
            return [0.0; 3];
        };
        let sum = around.iter().fold([0.0; 3], |acc, &t| {
            let [a, b, c] = self.corners(t);
            let n = cross(sub(b, a), sub(c, a));
            [acc[0] + n[0], acc[1] + n[1], acc[2] + n[2]]
        });
        unit(sum)
    }

    fn corners(&self, t: usize) -> [[f64; 3]; 3] {
        self.mesh.surface[t].map(|v| self.mesh.nodes[v as usize])
    }

    /// The patch of radius `radius` centred on surface vertex `v` (a point contact when the
    /// radius is 0 or the vertex is on no surface triangle).
    pub fn at_vertex(&self, v: u32, radius: f64) -> Patch {
        let Some(seeds) = self.around.get(&v) else {
            return Patch::point(v);
        };
        let normal = unit(seeds.iter().fold([0.0; 3], |n, &t| {
            let [a, b, c] = self.corners(t);
            let area = cross(sub(b, a), sub(c, a));
            [n[0] + area[0], n[1] + area[1], n[2] + area[2]]
        }));
        let centre = self.mesh.nodes[v as usize];
        self.spread(centre, normal, seeds, radius)
            .unwrap_or_else(|| Patch::point(v))
    }

    /// The patch of radius `radius` centred on the surface point closest to `point`, that centre,
    /// and how far `point` is from it.
    pub fn at_point(&self, point: [f64; 3], radius: f64) -> Option<(Patch, [f64; 3], f64)> {
        let (t, (centre, distance)) = self.closest(point, |_| true)?;
        let patch = match self.spread(centre, self.normals[t], &[t], radius) {
            Some(p) => p,
            // Radius 0: the nearest corner of that triangle.
            None => {
                let v = *self.mesh.surface[t].iter().min_by(|&&a, &&b| {
                    let d = |v: u32| {
                        let x = sub(self.mesh.nodes[v as usize], centre);
                        dot(x, x)
                    };
                    d(a).total_cmp(&d(b))
                })?;
                Patch::point(v)
            }
        };
        Some((patch, centre, distance))
    }

    /// [`Surface::at_point`] on the triangles facing within [`MAX_TURN`] of `normal`, and spread
    /// as a patch facing `normal`: the same patch as a vertex's of that normal on another mesh of
    /// the part (at a hole's rim the closest triangle may be the bore's wall, whose patch is
    /// another one), and its centre. `None` when no triangle faces that way or nothing is loaded.
    pub fn at_point_facing(&self, point: [f64; 3], normal: [f64; 3], radius: f64) -> Option<(Patch, [f64; 3])> {
        let (t, (centre, _)) = self.closest(point, |t| dot(self.normals[t], normal) > MAX_TURN)?;
        self.spread(centre, normal, &[t], radius).map(|p| (p, centre))
    }

    /// The surface triangle closest to `point` among those `eligible` takes: its index, the
    /// closest point on it and the distance.
    fn closest(&self, point: [f64; 3], eligible: impl Fn(usize) -> bool) -> Option<(usize, ([f64; 3], f64))> {
        self.grid
            .get_or_init(|| super::nearest::TriangleGrid::new(self.mesh.surface.len(), |t| self.corners(t)))
            .closest(point, eligible, |t| closest_on_triangle(point, self.corners(t)))
    }

    /// The pressure around `centre` integrated over the triangles reached from `seeds`;
    /// `None` when nothing is loaded (radius 0).
    fn spread(&self, centre: [f64; 3], normal: [f64; 3], seeds: &[usize], radius: f64) -> Option<Patch> {
        if radius.is_nan() || radius <= 0.0 {
            return None;
        }
        let mut seen: std::collections::HashSet<usize> = seeds.iter().copied().collect();
        let mut stack: Vec<usize> = seeds.to_vec();
        let mut loads: HashMap<u32, f64> = HashMap::new();
        while let Some(t) = stack.pop() {
            self.integrate(t, centre, radius, &mut loads);
            for &o in &self.neighbours[t] {
                if o == usize::MAX || seen.contains(&o) {
                    continue;
                }
                let [a, b, c] = self.corners(o);
                let near = [(a, b), (b, c), (c, a)]
                    .iter()
                    .any(|&(u, v)| segment_distance(centre, u, v) < radius);
                if near && dot(self.normals[o], normal) > MAX_TURN {
                    seen.insert(o);
                    stack.push(o);
                }
            }
        }
        // Summed in node order: a HashMap's order changes from run to run, and so did the
        // weights' last bits (1.4e-16 between two runs of the ribplate).
        let mut pairs: Vec<(u32, f64)> = loads.into_iter().collect();
        pairs.sort_unstable_by_key(|p| p.0);
        let total: f64 = pairs.iter().map(|p| p.1).sum();
        if total.is_nan() || total <= 0.0 {
            return None;
        }
        pairs.iter_mut().for_each(|p| p.1 /= total);
        Some(Patch {
            nodes: pairs.iter().map(|p| p.0).collect(),
            weights: pairs.iter().map(|p| p.1).collect(),
        })
    }

    /// Adds ∫ Nₐ p dA over triangle `t` to `loads`, on sub-triangles small against the radius:
    /// those wholly outside the patch skipped, those wholly inside integrated whole (the pressure
    /// is smooth there), those the rim cuts split in four (the rim is where p is least smooth:
    /// the interior's cells at half that size cost three quarters of the time, the mould's
    /// contact stage 2.1 s of a 9.8 s precompute).
    fn integrate(&self, t: usize, centre: [f64; 3], radius: f64, loads: &mut HashMap<u32, f64>) {
        let ids = &self.nodes[t];
        let mut x = [[0.0; 3]; 6];
        let x = &mut x[..ids.len().min(6)];
        for (xa, &v) in x.iter_mut().zip(ids) {
            *xa = self.mesh.nodes[v as usize];
        }
        let x = &*x;
        let [a, b, c] = self.corners(t);
        let longest = [sub(b, a), sub(c, b), sub(a, c)]
            .iter()
            .map(|e| dot(*e, *e).sqrt())
            .fold(0.0, f64::max);
        // Cells of a third of the radius, those on the rim split into sixths.
        let m = ((0.5 * SUBDIVISIONS_PER_RADIUS * longest / radius).ceil() as usize).clamp(1, MAX_SUBDIVISION / 2);
        let h = 1.0 / m as f64;
        // The chord triangle at reference point (ξ, η), for the skip test.
        let flat = |(xi, eta): (f64, f64)| -> [f64; 3] {
            std::array::from_fn(|k| a[k] + xi * (b[k] - a[k]) + eta * (c[k] - a[k]))
        };
        // A curved 6-node triangle bulges off its chord by at most this much.
        let bulge = if x.len() == 6 {
            [(0, 1, 3), (1, 2, 4), (2, 0, 5)]
                .iter()
                .map(|&(p, q, mid)| {
                    let chord: [f64; 3] = std::array::from_fn(|k| 0.5 * (x[p][k] + x[q][k]));
                    let e = sub(x[mid], chord);
                    dot(e, e).sqrt()
                })
                .fold(0.0, f64::max)
        } else {
            0.0
        };
        // Where a cell lies against the patch.
        let place = |p: &[(f64, f64); 3]| -> Place {
            let xs = p.map(flat);
            let mid: [f64; 3] = std::array::from_fn(|k| (xs[0][k] + xs[1][k] + xs[2][k]) / 3.0);
            let reach = xs
                .iter()
                .map(|q| {
                    let d = sub(*q, mid);
                    dot(d, d).sqrt()
                })
                .fold(0.0, f64::max);
            let d = sub(mid, centre);
            let d = dot(d, d).sqrt();
            if d > radius + reach + 2.0 * bulge {
                Place::Outside
            } else if d + reach + 2.0 * bulge < radius {
                Place::Inside
            } else {
                Place::Rim
            }
        };
        let mut w = [0.0; 6];
        // A 3-node triangle is flat: its area vector is the same at every point (the same bits
        // as evaluated at each), and its shape functions are its barycentric coordinates.
        let flat_da = (x.len() == 3).then(|| area_vector(x, 0.0, 0.0).0);
        // The rule `points` on cell `p` (reference points), of reference area `area`.
        let mut rule = |p: &[(f64, f64); 3], area: f64, points: &[(f64, f64, f64)]| {
            for &(s, r, weight) in points {
                let xi = p[0].0 + s * (p[1].0 - p[0].0) + r * (p[2].0 - p[0].0);
                let eta = p[0].1 + s * (p[1].1 - p[0].1) + r * (p[2].1 - p[0].1);
                let (da, n) = match flat_da {
                    Some(da) => (da, [1.0 - xi - eta, xi, eta, 0.0, 0.0, 0.0]),
                    None => area_vector(x, xi, eta),
                };
                let at: [f64; 3] = std::array::from_fn(|k| n.iter().zip(x).map(|(na, xa)| na * xa[k]).sum());
                let d = sub(at, centre);
                let pressure = profile(dot(d, d) / (radius * radius));
                if pressure == 0.0 {
                    continue;
                }
                // Rule weights sum to 1 on a cell of reference area `area`.
                let scale = weight * area * dot(da, da).sqrt() * pressure;
                for (wa, na) in w.iter_mut().zip(&n) {
                    *wa += scale * na;
                }
            }
        };
        // The m² cells of the reference triangle: m(m+1)/2 upright, m(m−1)/2 inverted.
        let cells = (0..m).flat_map(|i| {
            (0..m - i).flat_map(move |j| {
                let inverted = (i + j + 1 < m).then_some([(i + 1, j), (i + 1, j + 1), (i, j + 1)]);
                std::iter::once([(i, j), (i + 1, j), (i, j + 1)]).chain(inverted)
            })
        });
        // A flat 3-node triangle wholly inside the patch's ball (its corners are: a ball is convex)
        // carries a polynomial of degree 5 (the quartic pressure times a linear shape
        // function): one degree-5 rule on the whole triangle is exact, where its m² cells took
        // 6 points each.
        let reach2 = [a, b, c]
            .iter()
            .map(|q| {
                let d = sub(*q, centre);
                dot(d, d)
            })
            .fold(0.0, f64::max);
        if flat_da.is_some() && reach2 < radius * radius {
            rule(&[(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)], 0.5, &DEGREE_5_RULE);
        } else {
            for cell in cells {
                let p = cell.map(|(u, v)| (u as f64 * h, v as f64 * h));
                match place(&p) {
                    Place::Outside => {}
                    Place::Inside => rule(&p, 0.5 * h * h, &TRIANGLE_RULE),
                    Place::Rim => {
                        let half = |i: usize, j: usize| ((p[i].0 + p[j].0) / 2.0, (p[i].1 + p[j].1) / 2.0);
                        let (m01, m12, m20) = (half(0, 1), half(1, 2), half(2, 0));
                        for q in [[p[0], m01, m20], [m01, p[1], m12], [m20, m12, p[2]], [m12, m20, m01]] {
                            if place(&q) != Place::Outside {
                                rule(&q, 0.125 * h * h, &TRIANGLE_RULE);
                            }
                        }
                    }
                }
            }
        }
        for (&a, wa) in ids.iter().zip(w) {
            if wa != 0.0 {
                *loads.entry(a).or_insert(0.0) += wa;
            }
        }
    }
}

/// The patch of every surface vertex of `mesh` (`fixed(v)`: a vertex with a supported component,
/// which keeps a point contact: it does not move, and its compliance block stays zero in the
/// supported rows).
pub fn vertex_patches(mesh: &Mesh, radius: f64, fixed: impl Fn(u32) -> bool + Sync) -> Patches {
    let surface = Surface::new(mesh);
    let centres = mesh.surface_vertices();
    let patches: Vec<Patch> = centres
        .par_iter()
        .map(|&v| {
            if fixed(v) {
                Patch::point(v)
            } else {
                surface.at_vertex(v, radius)
            }
        })
        .collect();
    let mut out = Patches {
        radius,
        centres,
        offsets: vec![0],
        nodes: Vec::new(),
        weights: Vec::new(),
    };
    for p in patches {
        out.nodes.extend(p.nodes);
        out.weights.extend(p.weights);
        out.offsets.push(out.nodes.len() as u32);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::element::Kind;

    fn plate(kind: Kind, cells: usize) -> Mesh {
        // 40 × 40 × 10 mm, refined `cells` per 10 mm.
        let h = 0.01 / cells as f64;
        Mesh::structured_box([4 * cells, 4 * cells, cells], h, kind, |_, x| x)
    }

    /// The same patch twice is the same to the last bit (each HashMap hashes in its own order,
    /// which summed the weights' total differently from one patch to the next).
    #[test]
    fn a_patch_is_the_same_to_the_last_bit_every_time() {
        for kind in [Kind::Tet4, Kind::Tet10] {
            let mesh = plate(kind, 4);
            let s = Surface::new(&mesh);
            let first = s.at_point([0.02, 0.02, 0.01], 0.005).expect("a patch").0;
            assert!(first.nodes.len() > 8, "{}", first.nodes.len());
            for _ in 0..20 {
                let again = s.at_point([0.02, 0.02, 0.01], 0.005).expect("a patch").0;
                assert_eq!(again.nodes, first.nodes);
                let bits = |p: &Patch| p.weights.iter().map(|w| w.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&again), bits(&first), "{kind:?}");
            }
        }
    }

    #[test]
    fn weights_sum_to_one_and_centre_on_the_point() {
        for kind in [Kind::Tet4, Kind::Tet10] {
            for cells in [1, 2, 4] {
                let mesh = plate(kind, cells);
                let s = Surface::new(&mesh);
                let (p, _, d) = s.at_point([0.02, 0.02, 0.01], 0.005).expect("a patch");
                assert!(d < 1e-12, "{d}");
                let sum: f64 = p.weights.iter().sum();
                assert!((sum - 1.0).abs() < 1e-12, "{sum}");
                // The load's centre of pressure is the centre (the plate is symmetric about it).
                let x: Vec<f64> = mesh.nodes.iter().flatten().copied().collect();
                let c = p.average(&x);
                for (k, want) in [0.02, 0.02, 0.01].iter().enumerate() {
                    assert!((c[k] - want).abs() < 1e-9, "{kind:?} {cells}: {c:?}");
                }
                // Only the top face is loaded.
                assert!(
                    p.nodes
                        .iter()
                        .all(|&a| (mesh.nodes[a as usize][2] - 0.01).abs() < 1e-12)
                );
            }
        }
    }

    /// On 4-node tets (flat triangles: those wholly inside the patch take one degree-5 rule, the
    /// rest cells) the weights are those of a brute-force integration of Nₐ p over the top face's
    /// triangles: 96² centroid cells each, off the plate's symmetry so no error cancels.
    #[test]
    fn flat_triangle_weights_match_a_brute_force_integration() {
        let (a, centre) = (0.005, [0.0213, 0.0187, 0.01]);
        let mesh = plate(Kind::Tet4, 4);
        let (p, _, _) = Surface::new(&mesh).at_point(centre, a).expect("a patch");
        let mut brute: HashMap<u32, f64> = HashMap::new();
        let n = 96;
        for t in mesh
            .surface
            .iter()
            .filter(|t| t.iter().all(|&v| (mesh.nodes[v as usize][2] - 0.01).abs() < 1e-12))
        {
            let x = t.map(|v| mesh.nodes[v as usize]);
            let area = 0.5 * dot(cross(sub(x[1], x[0]), sub(x[2], x[0])), [0.0, 0.0, 1.0]).abs();
            for i in 0..n {
                for j in 0..n - i {
                    // The upright cell's centroid, and the inverted one's beside it.
                    let mut cells = vec![((i as f64 + 1.0 / 3.0) / n as f64, (j as f64 + 1.0 / 3.0) / n as f64)];
                    if i + j + 1 < n {
                        cells.push(((i as f64 + 2.0 / 3.0) / n as f64, (j as f64 + 2.0 / 3.0) / n as f64));
                    }
                    for (xi, eta) in cells {
                        let l = [1.0 - xi - eta, xi, eta];
                        let at: [f64; 3] = std::array::from_fn(|k| (0..3).map(|c| l[c] * x[c][k]).sum());
                        let d = sub(at, centre);
                        let pressure = profile(dot(d, d) / (a * a));
                        for c in 0..3 {
                            *brute.entry(t[c]).or_insert(0.0) += l[c] * pressure * area / (n * n) as f64;
                        }
                    }
                }
            }
        }
        let total: f64 = brute.values().sum();
        for (node, w) in p.nodes.iter().zip(&p.weights) {
            let want = brute.get(node).copied().unwrap_or(0.0) / total;
            assert!(
                (w - want).abs() < 2e-4 * p.weights.iter().fold(0.0, |m: f64, x| m.max(*x)),
                "node {node}: {w} vs {want}"
            );
        }
        let loaded: usize = brute.values().filter(|&&w| w > 0.0).count();
        assert_eq!(
            p.nodes.len(),
            loaded,
            "the patch loads other nodes than the pressure reaches"
        );
    }

    #[test]
    fn the_second_moment_matches_the_profile() {
        // ∫ r² p dA / ∫ p dA for p = (1 − r²/a²)² on a disk is a²/4; a fine mesh reproduces it.
        let a = 0.005;
        let mesh = plate(Kind::Tet10, 8);
        let s = Surface::new(&mesh);
        let (p, _, _) = s.at_point([0.02, 0.02, 0.01], a).expect("a patch");
        let r2: Vec<f64> = mesh
            .nodes
            .iter()
            .flat_map(|x| {
                let d = (x[0] - 0.02).powi(2) + (x[1] - 0.02).powi(2);
                [d, 0.0, 0.0]
            })
            .collect();
        let m2 = p.average(&r2)[0];
        assert!((m2 / (a * a / 4.0) - 1.0).abs() < 1e-3, "{m2} vs {}", a * a / 4.0);
    }

    #[test]
    fn a_thin_wall_keeps_its_far_side_unloaded() {
        // 2 mm thick plate: a 5 mm patch on top must not load the bottom face.
        let mesh = Mesh::structured_box([20, 20, 1], 0.002, Kind::Tet4, |_, x| x);
        let s = Surface::new(&mesh);
        let (p, _, _) = s.at_point([0.02, 0.02, 0.002], 0.005).expect("a patch");
        assert!(p.nodes.iter().all(|&a| mesh.nodes[a as usize][2] > 0.001));
        assert!(p.nodes.len() > 10);
    }

    #[test]
    fn a_vertex_on_an_edge_spreads_over_both_faces_and_radius_zero_is_a_point() {
        let mesh = plate(Kind::Tet4, 2);
        let s = Surface::new(&mesh);
        let v = mesh
            .nodes
            .iter()
            .position(|x| (x[0] - 0.02).abs() < 1e-12 && x[1].abs() < 1e-12 && (x[2] - 0.01).abs() < 1e-12)
            .expect("an edge vertex") as u32;
        let p = s.at_vertex(v, 0.005);
        let side = p.nodes.iter().any(|&a| mesh.nodes[a as usize][2] < 0.009);
        let top = p.nodes.iter().any(|&a| mesh.nodes[a as usize][1] > 0.001);
        assert!(side && top, "{p:?}");
        assert_eq!(s.at_vertex(v, 0.0), Patch::point(v));
    }
}
