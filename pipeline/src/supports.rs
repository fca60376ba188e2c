//! Supported degrees of freedom: which DOFs the scene's `[[fixed]]` regions remove.

use crate::fem::Dofs;
use crate::fem::springs::{NodeSpring, face_springs, face_springs_along, triangle_frame};
use crate::scene::{Region, Support};
use crate::tet_mesh::Mesh;

/// A support selects nothing; the message says where the part is.
#[derive(Debug, thiserror::Error)]
#[error("fixed[{index}] ({what}) selects no node of the mesh; {hint}")]
pub struct EmptySupport {
    /// Index of the `[[fixed]]` table.
    pub index: usize,
    /// The region, in words.
    pub what: String,
    /// Where the part lies, to help fix the value.
    pub hint: String,
}

/// A support the mesh cannot apply.
#[derive(Debug, thiserror::Error)]
pub enum SupportError {
    /// The region selects no node.
    #[error(transparent)]
    Empty(#[from] EmptySupport),
    /// `faces` names a tag the geometry does not have.
    #[error("fixed[{index}].faces{}: {message}", crate::scene::quote_tags(asked))]
    UnknownFaces {
        /// Index of the `[[fixed]]` table.
        index: usize,
        /// The tags as given (sorted, each once).
        asked: Vec<u32>,
        /// Which are unknown, and the tags the geometry has.
        message: String,
    },
    /// The geometry has separate bodies and the supports leave one of them free.
    #[error(
        "the geometry has {bodies} separate bodies and body {body} ({nodes} nodes, centred at ({:.4}, {:.4}, {:.4}) m) \
         is not held by the supports ({free} rigid motions left): add a [[fixed]] region that touches it, or join the \
         bodies in CAD",
        .centre[0], .centre[1], .centre[2]
    )]
    UnheldBody {
        /// Separate bodies in the mesh.
        bodies: usize,
        /// The body left free, counted from 1.
        body: usize,
        /// Its nodes.
        nodes: usize,
        /// Its centroid, m.
        centre: [f64; 3],
        /// Rigid motions the supports leave it.
        free: usize,
    },
}

/// A load's surface region (`[[load]]`) that the mesh cannot apply: the same faults as a
/// support's, for a region that selects surface triangles rather than nodes.
#[derive(Debug, thiserror::Error)]
pub enum RegionError {
    /// `faces` names a tag the geometry does not have.
    #[error("{key}.faces{}: {message}", crate::scene::quote_tags(asked))]
    UnknownFaces {
        /// The scene entry, e.g. `load[0]`.
        key: String,
        /// The tags as given (sorted, each once).
        asked: Vec<u32>,
        /// Which are unknown, and the tags the geometry has.
        message: String,
    },
    /// The region selects no surface triangle.
    #[error("{key} ({what}) selects no surface triangle of the mesh (a load acts on the surface); {hint}")]
    Empty {
        /// The scene entry, e.g. `load[0]`.
        key: String,
        /// The region, in words.
        what: String,
        /// Where the part lies, to help fix the value.
        hint: String,
    },
}

/// Whether a support region holds point `p` (`default_tol`: 1e-6 × part size); `Faces` selects
/// by triangles, not by position (see [`face_nodes`]).
fn selects(region: &Region, p: [f64; 3], default_tol: f64) -> bool {
    match region {
        Region::Plane { axis, value, tol } => (p[*axis] - value).abs() <= tol.unwrap_or(default_tol),
        Region::Box(b) => b.contains(p, default_tol),
        Region::Faces(_) => false,
    }
}

/// The region in words, and where the part lies so the user can fix the value.
fn describe(region: &Region, lo: [f64; 3], hi: [f64; 3], default_tol: f64) -> (String, String) {
    match region {
        Region::Plane { axis, value, tol } => {
            let name = ["x", "y", "z"][*axis];
            (
                format!("plane {name} = {value} m, tol {:.3e} m", tol.unwrap_or(default_tol)),
                format!(
                    "the part spans {name} from {:.6} to {:.6} m: change `value` (in metres) or raise `tol`",
                    lo[*axis], hi[*axis]
                ),
            )
        }
        Region::Box(b) => (
            format!("box {:?}..{:?} m", b.min, b.max),
            format!("the part spans {lo:.6?} to {hi:.6?} m: move or enlarge the box (in metres)"),
        ),
        Region::Faces(tags) => (
            format!("faces{}", crate::scene::quote_tags(tags)),
            "name faces the geometry has".to_string(),
        ),
    }
}

/// Sorted tags as ranges: `1..=6, 9, 11..=12`; past the first 12 ranges, how many more (an
/// error stays one readable line).
pub fn tag_ranges(tags: &[u32]) -> String {
    const SHOWN: usize = 12;
    let mut parts = Vec::new();
    let mut i = 0;
    while i < tags.len() {
        if parts.len() == SHOWN {
            return format!("{}, … ({} tags more)", parts.join(", "), tags.len() - i);
        }
        let mut j = i;
        while j + 1 < tags.len() && tags[j + 1] == tags[j] + 1 {
            j += 1;
        }
        parts.push(if j > i {
            format!("{}..={}", tags[i], tags[j])
        } else {
            tags[i].to_string()
        });
        i = j + 1;
    }
    parts.join(", ")
}

/// The CAD faces the mesh's surface carries (tags of its triangles, 0 left out), ascending.
pub fn mesh_faces(mesh: &Mesh) -> Vec<u32> {
    let mut tags: Vec<u32> = mesh.surface_faces.iter().copied().filter(|&t| t != 0).collect();
    tags.sort_unstable();
    tags.dedup();
    tags
}

/// The nodes on the surface triangles whose CAD face is in `tags` (sorted): their corners and,
/// for 10-node tets, the mid-edge nodes of their edges. Sorted, each once.
pub fn face_nodes(mesh: &Mesh, tags: &[u32]) -> Vec<u32> {
    let on: Vec<&[u32; 3]> = mesh
        .surface
        .iter()
        .zip(&mesh.surface_faces)
        .filter(|(_, t)| tags.binary_search(t).is_ok())
        .map(|(f, _)| f)
        .collect();
    let mut nodes: Vec<u32> = on.iter().flat_map(|f| f.iter().copied()).collect();
    if mesh.kind == ves_format::ElementKind::Tet10 {
        // Mid-edge nodes from the tets: the node of each triangle edge.
        let key = |a: u32, b: u32| (a.min(b), a.max(b));
        let mut edges: std::collections::HashSet<(u32, u32)> = on
            .iter()
            .flat_map(|f| [key(f[0], f[1]), key(f[1], f[2]), key(f[2], f[0])])
            .collect();
        for e in 0..mesh.tet_count() {
            let t = mesh.tet(e);
            for (k, (a, b)) in crate::tet_mesh::TET10_EDGES.iter().enumerate() {
                if edges.remove(&key(t[*a], t[*b])) {
                    nodes.push(t[4 + k]);
                }
            }
            if edges.is_empty() {
                break;
            }
        }
    }
    nodes.sort_unstable();
    nodes.dedup();
    nodes
}

/// Which of `tags` the mesh's surface does not carry, in words with the tags it has; `None` when
/// it carries them all.
fn unknown_faces(mesh: &Mesh, tags: &[u32]) -> Option<String> {
    let known = mesh_faces(mesh);
    let unknown: Vec<u32> = tags
        .iter()
        .copied()
        .filter(|t| known.binary_search(t).is_err())
        .collect();
    if unknown.is_empty() {
        return None;
    }
    let which = match unknown.as_slice() {
        [t] => format!("the geometry has no face {t}"),
        ts => format!("the geometry has no faces {}", tag_ranges(ts)),
    };
    Some(if known.is_empty() {
        format!("{which}: its mesh carries no CAD face tags (not made by gmsh from the geometry); use `plane` or `box`")
    } else {
        format!(
            "{which}; it has faces {} (gmsh's surface tags of the geometry as imported): use those",
            tag_ranges(&known)
        )
    })
}

/// The surface triangles (indices into `mesh.surface`) a load's region selects, by the same
/// rules a support's region selects nodes: `faces`, the triangles on those CAD faces; `plane` or
/// `box`, the triangles whose three corners it selects (so a region a support would hold is the
/// surface a load acts on). `key` names the scene entry (`load[0]`) in the one-line error for a
/// region that selects no triangle or names a face the geometry does not have.
pub fn region_triangles(mesh: &Mesh, key: &str, region: &Region) -> Result<Vec<usize>, RegionError> {
    let default_tol = 1e-6 * mesh.diameter();
    let picked: Vec<usize> = match region {
        Region::Faces(tags) => {
            if let Some(message) = unknown_faces(mesh, tags) {
                return Err(RegionError::UnknownFaces {
                    key: key.to_string(),
                    asked: tags.clone(),
                    message,
                });
            }
            (0..mesh.surface.len())
                .filter(|&t| tags.binary_search(&mesh.surface_faces[t]).is_ok())
                .collect()
        }
        _ => (0..mesh.surface.len())
            .filter(|&t| {
                mesh.surface[t]
                    .iter()
                    .all(|&v| selects(region, mesh.nodes[v as usize], default_tol))
            })
            .collect(),
    };
    if picked.is_empty() {
        let (lo, hi) = mesh.bounding_box();
        let (what, hint) = describe(region, lo, hi, default_tol);
        return Err(RegionError::Empty {
            key: key.to_string(),
            what,
            hint,
        });
    }
    Ok(picked)
}

/// Applies the supports to the mesh's nodes (corner and mid-edge alike).
pub fn select(mesh: &Mesh, supports: &[Support]) -> Result<Dofs, SupportError> {
    let mut fixed_mask = vec![false; 3 * mesh.nodes.len()];
    for held in held_by_each(mesh, supports)? {
        for g in held {
            fixed_mask[g as usize] = true;
        }
    }
    Ok(Dofs::from_mask(&fixed_mask))
}

/// Per support, the DOFs it holds (ascending) that no support before it holds: each held DOF
/// once, so the supports' reactions add up to the whole.
pub fn held_by_each(mesh: &Mesh, supports: &[Support]) -> Result<Vec<Vec<u32>>, SupportError> {
    let n = mesh.nodes.len();
    let mut taken = vec![false; 3 * n];
    let (lo, hi) = mesh.bounding_box();
    let default_tol = 1e-6 * mesh.diameter();
    let mut each = Vec::with_capacity(supports.len());
    for (index, s) in supports.iter().enumerate() {
        let mut nodes = vec![false; n];
        if let Region::Faces(tags) = &s.region {
            if let Some(message) = unknown_faces(mesh, tags) {
                return Err(SupportError::UnknownFaces {
                    index,
                    asked: tags.clone(),
                    message,
                });
            }
            for i in face_nodes(mesh, tags) {
                nodes[i as usize] = true;
            }
        }
        for (i, p) in mesh.nodes.iter().enumerate() {
            if selects(&s.region, *p, default_tol) {
                nodes[i] = true;
            }
        }
        if !nodes.iter().any(|&x| x) {
            let (what, hint) = describe(&s.region, lo, hi, default_tol);
            return Err(EmptySupport { index, what, hint }.into());
        }
        let mut held = Vec::new();
        // Springs hold the others: no DOF is removed.
        let removes = s.kind == crate::scene::SupportKind::Held;
        if removes && !holds_area(mesh, &nodes) {
            let (what, _) = describe(&s.region, lo, hi, default_tol);
            tracing::warn!(
                "fixed[{index}] ({what}) holds no face of the part, only nodes on a line or at points (a plane \
                 through a curved face's crest or along an edge): such a support is singular, its stiffness falls \
                 as the mesh is refined, so the frequencies do not converge and mesh.target_error may not be met; \
                 hold a face instead (`faces = [...]`, listed by `ves faces`, or a plane through a flat face)"
            );
        }
        for (i, _) in nodes.iter().enumerate().filter(|(_, x)| **x && removes) {
            for c in (0..3).filter(|&c| s.components[c]) {
                let g = 3 * i + c;
                if !taken[g] {
                    taken[g] = true;
                    held.push(g as u32);
                }
            }
        }
        each.push(held);
    }
    Ok(each)
}

/// Whether the nodes marked in `nodes` cover a surface triangle of the mesh (all three
/// corners): an area held, not only a line or points. A mesh without surface triangles is
/// taken as covered (nothing to tell from).
fn holds_area(mesh: &Mesh, nodes: &[bool]) -> bool {
    mesh.surface.is_empty()
        || mesh
            .surface
            .iter()
            .any(|t| t.iter().all(|&v| nodes.get(v as usize).copied().unwrap_or(false)))
}

/// Spring stiffness of a sliding support or a bearing per unit of the material's Young's
/// modulus over the mean edge length of its triangles: stiff enough that the held direction
/// moves ~1/PENALTY of what the part's own stiffness allows there, soft enough to leave the
/// factorisation well conditioned (checked against removing the same DOFs on the cantilever:
/// cli/tests/supports.rs).
pub const PENALTY: f64 = 1e4;

/// Per support, the springs it holds by (sliding, bearing, elastic; none for a support that
/// removes DOFs), for `young` (Pa) the material's modulus.
pub fn springs(mesh: &Mesh, supports: &[Support], young: f64) -> Result<Vec<Vec<NodeSpring>>, RegionError> {
    use crate::scene::SupportKind;
    let mut each = Vec::with_capacity(supports.len());
    for (i, s) in supports.iter().enumerate() {
        let mut out = Vec::new();
        if s.kind == SupportKind::Held {
            each.push(out);
            continue;
        }
        let triangles = region_triangles(mesh, &format!("fixed[{i}]"), &s.region)?;
        let edge = mean_edge(mesh, &triangles);
        match s.kind {
            SupportKind::Held => {}
            SupportKind::Sliding => {
                // Each node along the mean normal of its triangles in the region.
                let mut normal: std::collections::HashMap<u32, [f64; 3]> = std::collections::HashMap::new();
                let mids = crate::fem::springs::mid_nodes(mesh);
                for &t in &triangles {
                    let (n, _, area) = triangle_frame(mesh, t);
                    for v in crate::fem::springs::triangle_nodes(&mids, mesh.surface[t]).0 {
                        let e = normal.entry(v).or_insert([0.0; 3]);
                        for k in 0..3 {
                            e[k] += area * n[k];
                        }
                    }
                }
                out.extend(face_springs_along(mesh, &triangles, PENALTY * young / edge, |v| {
                    unit(normal.get(&v).copied().unwrap_or_default())
                }));
            }
            SupportKind::Bearing { located } => {
                let (axis, centre) = cylinder_axis(mesh, &triangles);
                // Radial only, node by node: turning about the axis stretches no spring, and
                // holding the axial direction at every point of the ring would hold the shaft's
                // tilt too (a clamp, not a bearing).
                out.extend(face_springs_along(mesh, &triangles, PENALTY * young / edge, |v| {
                    let x = mesh.nodes[v as usize];
                    let d = [0, 1, 2].map(|k| x[k] - centre[k]);
                    let along = d[0] * axis[0] + d[1] * axis[1] + d[2] * axis[2];
                    unit([0, 1, 2].map(|k| d[k] - along * axis[k]))
                }));
                if located {
                    // The ring's mean axial displacement, as stiff as the radial springs over
                    // the whole face.
                    let area: f64 = triangles.iter().map(|&t| triangle_frame(mesh, t).2).sum();
                    let ring = ring_nodes(mesh, &triangles, axis, centre);
                    out.extend(crate::fem::springs::mean_along(
                        &ring,
                        axis,
                        PENALTY * young / edge * area,
                    ));
                }
            }
            SupportKind::Elastic { stiffness } => {
                let p: [[f64; 3]; 3] =
                    std::array::from_fn(|r| std::array::from_fn(|c| if r == c && s.components[r] { 1.0 } else { 0.0 }));
                out.extend(face_springs(mesh, &triangles, stiffness, |_, _| p));
            }
        }
        each.push(out);
    }
    Ok(each)
}

/// Sectors of a located bearing's ring ([`ring_nodes`]).
const RING_SECTORS: usize = 36;

/// Nodes spread evenly around a cylindrical face: in each of [`RING_SECTORS`] sectors about the
/// axis, the corner node nearest the face's middle along the axis (a face narrower than a full
/// turn fills only its own sectors). At most 36 nodes, so their pairwise coupling stays small
/// whatever the mesh.
fn ring_nodes(mesh: &Mesh, triangles: &[usize], axis: [f64; 3], centre: [f64; 3]) -> Vec<u32> {
    use nalgebra::Vector3;
    let (axis, centre) = (Vector3::from(axis), Vector3::from(centre));
    let mut corners: Vec<u32> = triangles.iter().flat_map(|&t| mesh.surface[t]).collect();
    corners.sort_unstable();
    corners.dedup();
    let from_centre = |v: u32| Vector3::from(mesh.nodes[v as usize]) - centre;
    let middle = corners.iter().map(|&v| from_centre(v).dot(&axis)).sum::<f64>() / corners.len().max(1) as f64;
    // Two directions across the axis, for each node's angle about it.
    let across = axis
        .cross(&if axis.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() })
        .normalize();
    let third = axis.cross(&across);
    let mut best: Vec<Option<(f64, u32)>> = vec![None; RING_SECTORS];
    for &v in &corners {
        let d = from_centre(v);
        let angle = d.dot(&third).atan2(d.dot(&across));
        let sector = (((angle + std::f64::consts::PI) / std::f64::consts::TAU * RING_SECTORS as f64) as usize)
            .min(RING_SECTORS - 1);
        let off = (d.dot(&axis) - middle).abs();
        if best[sector].is_none_or(|(o, _)| off < o) {
            best[sector] = Some((off, v));
        }
    }
    best.into_iter().flatten().map(|(_, v)| v).collect()
}

/// The mean edge length of surface triangles, m.
fn mean_edge(mesh: &Mesh, triangles: &[usize]) -> f64 {
    let mut sum = 0.0;
    for &t in triangles {
        let v = mesh.surface[t].map(|i| mesh.nodes[i as usize]);
        for k in 0..3 {
            let (a, b) = (v[k], v[(k + 1) % 3]);
            sum += ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
        }
    }
    (sum / (3 * triangles.len()).max(1) as f64).max(f64::MIN_POSITIVE)
}

/// A fitted bearing axis within this angle of x, y or z is taken as that axis, radians.
const AXIS_SNAP: f64 = 0.05;

/// The axis of a cylindrical face and a point on it: the direction its normals are all
/// perpendicular to (the eigenvector of Σ A n nᵀ of the smallest eigenvalue), and its centre
/// (a circle fitted through the face's nodes).
pub(crate) fn cylinder_axis(mesh: &Mesh, triangles: &[usize]) -> ([f64; 3], [f64; 3]) {
    use nalgebra::{Matrix3, Vector3};
    let mut s = Matrix3::<f64>::zeros();
    for &t in triangles {
        let (n, _, area) = triangle_frame(mesh, t);
        let n = Vector3::from(n);
        s += area * n * n.transpose();
    }
    let e = nalgebra::SymmetricEigen::new(s);
    let mut a: Vector3<f64> = e.eigenvectors.column(e.eigenvalues.imin()).into();
    // A flat-faceted bore tilts the fitted axis by a little; two bearings of one shaft fitted
    // apart would then bind it like a misaligned shaft (a spin and a slide of 2 and 35 Hz on
    // the test shaft instead of free). A CAD bore along x, y or z is taken as that axis.
    if let Some(k) = (0..3).find(|&k| a[k].abs() > AXIS_SNAP.cos()) {
        a = Vector3::zeros();
        a[k] = 1.0;
    }
    // The centre: a least-squares circle through the face's nodes in the plane across the
    // axis (|p − c|² = R², linear in c and R² − |c|²). The nodes lie on the CAD surface, so two
    // bearings of one shaft find one axis: the facets' normal lines (the fit before) missed the
    // centre by ~1 % of the radius on a coarse mesh, and a crankshaft in two journal bearings
    // then turned at 216 Hz instead of freely.
    let u = a
        .cross(&if a[0].abs() < 0.9 { Vector3::x() } else { Vector3::y() })
        .normalize();
    let v = a.cross(&u);
    let mut nodes: Vec<u32> = triangles.iter().flat_map(|&t| mesh.surface[t]).collect();
    nodes.sort_unstable();
    nodes.dedup();
    let points: Vec<Vector3<f64>> = nodes.iter().map(|&i| Vector3::from(mesh.nodes[i as usize])).collect();
    let mean = points.iter().sum::<Vector3<f64>>() / points.len().max(1) as f64;
    let (mut q, mut rhs) = (Matrix3::<f64>::zeros(), Vector3::<f64>::zeros());
    for p in &points {
        let d = p - mean;
        let row = Vector3::new(d.dot(&u), d.dot(&v), 1.0);
        q += row * row.transpose();
        rhs += row * (row[0] * row[0] + row[1] * row[1]);
    }
    let fit = q.lu().solve(&rhs).unwrap_or_else(Vector3::zeros);
    let c = mean + 0.5 * fit[0] * u + 0.5 * fit[1] * v;
    ([a[0], a[1], a[2]], [c[0], c[1], c[2]])
}

/// A unit vector along `v` (zero for a zero vector).
fn unit(v: [f64; 3]) -> [f64; 3] {
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if n > 0.0 { v.map(|x| x / n) } else { [0.0; 3] }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A list of a hundred thousand unknown tags made a message of hundreds of kilobytes: past
    /// twelve ranges, the rest is counted.
    #[test]
    fn tag_ranges_stay_one_short_line() {
        assert_eq!(tag_ranges(&[1, 2, 3, 5, 7, 8]), "1..=3, 5, 7..=8");
        let many: Vec<u32> = (1..=200_000).step_by(2).collect();
        let s = tag_ranges(&many);
        assert!(s.len() < 200 && s.ends_with("… (99988 tags more)"), "{s:.300}");
    }
}

/// The rigid motions supports leave free, counted on selected nodes.
#[cfg(test)]
mod rigid_motions_left {
    use crate::rigid_motions::free_rigid_count;
    use crate::scene::{Region, Support};
    use crate::supports::select;
    use crate::tet_mesh::Mesh;

    fn cube() -> Mesh {
        // Unit cube split into 6 tets around the diagonal 0–6.
        let c: Vec<[f64; 3]> = (0..8)
            .map(|i| [(i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64])
            .collect();
        let tets = [0, 1, 3, 7, 0, 1, 5, 7, 0, 4, 5, 7, 0, 2, 3, 7, 0, 2, 6, 7, 0, 4, 6, 7];
        Mesh::from_raw(&c, &tets, ves_format::ElementKind::Tet4)
    }

    fn count(supports: &[Support]) -> usize {
        let m = cube();
        free_rigid_count(&m.nodes, &select(&m, supports).expect("supports select nodes"))
    }

    #[test]
    fn counts_rigid_motions_left_by_supports() {
        let plane = |axis, value, components| Support {
            region: Region::Plane { axis, value, tol: None },
            components,
            kind: crate::scene::SupportKind::Held,
        };
        assert_eq!(count(&[]), 6);
        assert_eq!(count(&[plane(2, 0.0, [true; 3])]), 0);
        // Out-of-plane support of a face: in-plane translations and the rotation about z remain.
        assert_eq!(count(&[plane(2, 0.0, [false, false, true])]), 3);
        // One clamped edge (x = 0, z = 0 is a line): rotation about it remains.
        let edge = Support {
            region: Region::Box(crate::scene::BoxRegion {
                min: [0.0, -1.0, 0.0],
                max: [0.0, 2.0, 0.0],
            }),
            components: [true; 3],
            kind: crate::scene::SupportKind::Held,
        };
        assert_eq!(count(&[edge]), 1);
    }

    /// A face held covers a surface triangle; an edge held (a line, the singular support the
    /// refinement warns of) covers none.
    #[test]
    fn a_face_holds_an_area_and_an_edge_does_not() {
        let m = cube();
        let marked = |f: &dyn Fn([f64; 3]) -> bool| m.nodes.iter().map(|p| f(*p)).collect::<Vec<bool>>();
        assert!(super::holds_area(&m, &marked(&|p| p[2] == 0.0)));
        assert!(!super::holds_area(&m, &marked(&|p| p[0] == 0.0 && p[2] == 0.0)));
        assert!(!super::holds_area(&m, &marked(&|p| p == [1.0, 1.0, 1.0])));
    }
}
