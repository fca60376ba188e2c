//! CAD faces as supports: every boundary triangle carries the gmsh surface tag it lies on, a
//! `[[fixed]] faces = [...]` support holds the nodes of those faces, and the tags reach the
//! basis file and the runtime.

use std::path::{Path, PathBuf};
use ves_pipeline::mesh::{self, Mesh};
use ves_pipeline::modes::SolverChoice;
use ves_pipeline::precompute::solve_space;
use ves_pipeline::scene::{Region, Scene, Support};
use ves_pipeline::supports::{self, SupportError};
use ves_tests::{case_path, serial};

/// A scene of `geometry` (absolute) in `dir`, 10-node tets of `size` m, with `fixed` (TOML of
/// `[[fixed]]` tables, or empty).
fn scene(dir: &Path, geometry: &Path, size: f64, fixed: &str) -> Scene {
    let text = format!(
        "name = \"faces\"\n[geometry]\nstep = {:?}\nunit = \"mm\"\n[material]\nyoung = 2.1e11\npoisson = 0.3\n\
         density = 7850.0\n[mesh]\nsize = {size:e}\norder = 2\nerror_estimate = false\n{fixed}[modes]\ncount = 8\n",
        geometry.display().to_string()
    );
    let path = dir.join("scene.toml");
    std::fs::write(&path, &text).expect("write the scene");
    Scene::parse(&path, &text).unwrap_or_else(|e| panic!("{e}"))
}

fn cantilever_step() -> PathBuf {
    case_path("cantilever/cantilever.step")
}

/// The tags on the triangles whose three corners satisfy `on`.
fn tags_where(m: &Mesh, on: impl Fn([f64; 3]) -> bool) -> Vec<u32> {
    let mut t: Vec<u32> = m
        .surface
        .iter()
        .zip(&m.surface_faces)
        .filter(|(f, _)| f.iter().all(|&v| on(m.nodes[v as usize])))
        .map(|(_, &t)| t)
        .collect();
    t.sort_unstable();
    t.dedup();
    t
}

/// The box 1 × 0.1 × 0.05 m has six faces; every boundary triangle carries one of them, each face
/// is one side of the box (all its triangles on one plane), and the six sides are six tags.
#[test]
fn every_triangle_of_the_cantilever_lies_on_one_of_its_six_faces() {
    let _one = serial();
    let dir = tempfile::tempdir().unwrap();
    let s = scene(dir.path(), &cantilever_step(), 0.05, "");
    let (m, _) = mesh::generate(&s, None).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(m.surface_faces.len(), m.surface.len());
    assert!(m.surface_faces.iter().all(|&t| t != 0), "a triangle without a face");
    assert_eq!(supports::mesh_faces(&m), (1..=6).collect::<Vec<u32>>());
    let ext = [1.0, 0.1, 0.05];
    let mut sides = Vec::new();
    for c in 0..3 {
        for at in [0.0, ext[c]] {
            let t = tags_where(&m, |p| (p[c] - at).abs() < 1e-9);
            assert_eq!(t.len(), 1, "side {c} = {at}: tags {t:?}");
            sides.push(t[0]);
        }
    }
    sides.sort_unstable();
    assert_eq!(sides, (1..=6).collect::<Vec<u32>>(), "each side its own tag");
}

/// Clamping the face at x = 0 by its tag holds exactly the DOFs `plane = { axis = "x", value =
/// 0 }` holds (corner and mid-edge nodes), and gives the same frequencies.
#[test]
fn the_end_face_by_tag_clamps_as_the_plane_does() {
    let _one = serial();
    let dir = tempfile::tempdir().unwrap();
    let plane = scene(
        dir.path(),
        &cantilever_step(),
        0.05,
        "[[fixed]]\nplane = { axis = \"x\", value = 0.0 }\n",
    );
    let (m, _) = mesh::generate(&plane, None).unwrap_or_else(|e| panic!("{e}"));
    let end = tags_where(&m, |p| p[0].abs() < 1e-9);
    assert_eq!(end.len(), 1, "{end:?}");
    let mut by_face = plane.clone();
    by_face.fixed = vec![Support {
        region: Region::Faces(end.clone()),
        components: [true; 3],
        kind: ves_pipeline::scene::SupportKind::Held,
    }];
    let a = supports::select(&m, &plane.fixed).unwrap();
    let b = supports::select(&m, &by_face.fixed).unwrap();
    assert_eq!(a.fixed, b.fixed, "the face and the plane hold different DOFs");
    // Every node at x = 0, corner and mid-edge alike, all three components: the face's
    // mid-edge nodes are held too (10-node tets).
    let at_end: Vec<usize> = (0..m.nodes.len()).filter(|&i| m.nodes[i][0].abs() < 1e-9).collect();
    assert!(at_end.iter().any(|&i| i >= m.vertex_count), "no mid-edge node at x = 0");
    let want: Vec<u32> = at_end
        .iter()
        .flat_map(|&i| (0..3).map(move |c| (3 * i + c) as u32))
        .collect();
    assert_eq!(b.fixed, want);
    let fa = solve_space(&plane, None, SolverChoice::Arpack).unwrap_or_else(|e| panic!("{e:#}"));
    let fb = solve_space(&by_face, None, SolverChoice::Arpack).unwrap_or_else(|e| panic!("{e:#}"));
    assert_eq!(fa.mesh.nodes, fb.mesh.nodes, "the two solves meshed differently");
    assert_eq!(fa.dofs.fixed, fb.dofs.fixed);
    assert_eq!(fa.modes.eigenvalues.len(), 8);
    for (x, y) in fa.modes.eigenvalues.iter().zip(&fb.modes.eigenvalues) {
        assert!((x - y).abs() <= 1e-9 * x.abs(), "λ {x} vs {y}");
    }
}

/// A tag the geometry does not have is refused in one line naming the tags it has; so is a
/// mesh without tags (one not made by gmsh).
#[test]
fn an_unknown_face_is_refused_naming_the_faces_there_are() {
    let _one = serial();
    let dir = tempfile::tempdir().unwrap();
    let s = scene(
        dir.path(),
        &cantilever_step(),
        0.05,
        "[[fixed]]\nplane = { axis = \"x\", value = 0.0 }\n[[fixed]]\nfaces = [99, 2]\n",
    );
    let (m, _) = mesh::generate(&s, None).unwrap_or_else(|e| panic!("{e}"));
    let e = supports::select(&m, &s.fixed).unwrap_err();
    assert!(matches!(e, SupportError::UnknownFaces { index: 1, .. }), "{e:?}");
    let line = e.to_string();
    assert_eq!(
        line,
        "fixed[1].faces = [2, 99]: the geometry has no face 99; it has faces 1..=6 (gmsh's surface tags of the \
         geometry as imported): use those"
    );
    let plain = Mesh::structured_box([2, 1, 1], 0.01, ves_pipeline::fem::element::Kind::Tet4, |_, p| p);
    let e = supports::select(&plain, &s.fixed[1..]).unwrap_err().to_string();
    assert!(e.contains("carries no CAD face tags") && !e.contains('\n'), "{e}");
}

/// A built-in-kernel (not OpenCASCADE) `.geo` box made by extrusions: gmsh still has its six
/// surface entities, and every boundary triangle is matched to one.
#[test]
fn a_geo_box_of_gmsh_s_own_kernel_gets_its_faces_too() {
    let _one = serial();
    let dir = tempfile::tempdir().unwrap();
    let geo = dir.path().join("box.geo");
    std::fs::write(
        &geo,
        "Point(1) = {0, 0, 0, 5};\nl[] = Extrude {40, 0, 0} { Point{1}; };\n\
         s[] = Extrude {0, 20, 0} { Line{l[1]}; };\nv[] = Extrude {0, 0, 10} { Surface{s[1]}; };\n",
    )
    .unwrap();
    let s = scene(dir.path(), &geo, 0.005, "");
    let (m, _) = mesh::generate(&s, None).unwrap_or_else(|e| panic!("{e}"));
    let unknown = m.surface_faces.iter().filter(|&&t| t == 0).count();
    assert_eq!(
        unknown,
        0,
        "{unknown} of {} triangles not matched to a surface",
        m.surface.len()
    );
    assert_eq!(supports::mesh_faces(&m).len(), 6, "{:?}", supports::mesh_faces(&m));
}

/// Unit normal, centroid and area of a triangle.
fn triangle(m: &Mesh, f: &[u32; 3]) -> ([f64; 3], [f64; 3], f64) {
    let p = f.map(|v| m.nodes[v as usize]);
    let (u, w) = (sub(p[1], p[0]), sub(p[2], p[0]));
    let n = [
        u[1] * w[2] - u[2] * w[1],
        u[2] * w[0] - u[0] * w[2],
        u[0] * w[1] - u[1] * w[0],
    ];
    let a = dot(n, n).sqrt();
    let c = std::array::from_fn(|k| (p[0][k] + p[1][k] + p[2][k]) / 3.0);
    (n.map(|x| x / a), c, a / 2.0)
}
fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|k| a[k] - b[k])
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|k| a[k] * b[k]).sum()
}

/// A hole's axis direction, a point on its axis (m) and its radius (m).
type Hole = ([f64; 3], [f64; 3], f64);

/// A face that is the inside of a cylinder (a hole): its axis direction, a point on the axis,
/// its radius. Found from its triangles alone: their normals span a plane (the axis is the one
/// direction no normal has), and each normal points at one common axis from a common radius.
fn hole(m: &Mesh, tag: u32) -> Option<Hole> {
    use nalgebra::{Matrix3, Vector3};
    let tris: Vec<_> = m
        .surface
        .iter()
        .zip(&m.surface_faces)
        .filter(|(_, t)| **t == tag)
        .map(|(f, _)| triangle(m, f))
        .collect();
    let mut cov = Matrix3::zeros();
    let mut area = 0.0;
    for (n, _, a) in &tris {
        let n = Vector3::from(*n);
        cov += *a * n * n.transpose();
        area += a;
    }
    let eig = (cov / area).symmetric_eigen();
    let mut order = [0, 1, 2];
    order.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
    // A plane: one normal direction; a cylinder: normals spread over a plane, (nearly) none
    // along its axis (a coarse mesh of a small hole tilts its triangles a little).
    if eig.eigenvalues[order[0]] > 0.05 || eig.eigenvalues[order[1]] < 0.1 {
        return None;
    }
    let axis: Vector3<f64> = eig.eigenvectors.column(order[0]).into();
    let mut lhs = axis * axis.transpose();
    let mut rhs = Vector3::zeros();
    for (n, c, a) in &tris {
        let n = Vector3::from(*n);
        let p = Matrix3::identity() - axis * axis.transpose() - n * n.transpose();
        lhs += *a * p;
        rhs += *a * p * Vector3::from(*c);
    }
    let at = lhs.lu().solve(&rhs)?;
    let mut radii = Vec::new();
    for (n, c, _) in &tris {
        let d = Vector3::from(*c) - at;
        let d = d - axis * axis.dot(&d);
        // Concave: the outward normal (out of the material) points at the axis.
        if Vector3::from(*n).dot(&d) / d.norm() > -0.8 {
            return None;
        }
        radii.push(d.norm());
    }
    let r = radii.iter().sum::<f64>() / radii.len() as f64;
    radii
        .iter()
        .all(|x| (x - r).abs() < 0.25 * r)
        .then(|| (axis.into(), at.into(), r))
}

/// The corpus block with two bolt holes (OCCT's test data), held by its hole faces alone (found
/// by their geometry, not by number): no rigid motion is left, and every frequency is positive.
#[test]
fn the_block_held_by_its_two_bolt_holes_has_no_rigid_mode() {
    let _one = serial();
    let dir = tempfile::tempdir().unwrap();
    let step = case_path("corpus/pmi_block_2holes.step");
    let s = scene(dir.path(), &step, 0.004, "");
    let (m, _) = mesh::generate(&s, None).unwrap_or_else(|e| panic!("{e}"));
    let faces = supports::mesh_faces(&m);
    let unknown = m.surface_faces.iter().filter(|&&t| t == 0).count();
    assert_eq!(unknown, 0, "{unknown} triangles without a face");
    let holes: Vec<(u32, Hole)> = faces.iter().filter_map(|&t| hole(&m, t).map(|h| (t, h))).collect();
    for (t, (a, p, r)) in &holes {
        eprintln!("face {t}: hole axis {a:.3?} through {p:.5?} m, radius {r:.5} m");
    }
    // Distinct holes: faces of one hole share its axis line (here each hole is a counterbore,
    // two radii, each cylinder split in two half faces: eight faces).
    let mut axes: Vec<([f64; 3], [f64; 3])> = Vec::new();
    for (_, (a, p, _)) in &holes {
        let same = |(b, q): &([f64; 3], [f64; 3])| {
            let d = sub(*p, *q);
            let off = sub(d, b.map(|x| x * dot(d, *b)));
            // Axes fitted to a coarse mesh of a small hole are off by a tenth of a millimetre.
            dot(*a, *b).abs() > 0.999 && dot(off, off).sqrt() < 1e-3
        };
        if !axes.iter().any(same) {
            axes.push((*a, *p));
        }
    }
    assert_eq!(
        axes.len(),
        2,
        "{} faces of {} holes among {} faces",
        holes.len(),
        axes.len(),
        faces.len()
    );
    let tags: Vec<u32> = holes.iter().map(|(t, _)| *t).collect();
    let list = tags.iter().map(u32::to_string).collect::<Vec<_>>().join(", ");
    let held = scene(dir.path(), &step, 0.004, &format!("[[fixed]]\nfaces = [{list}]\n"));
    let solved = solve_space(&held, None, SolverChoice::Arpack).unwrap_or_else(|e| panic!("{e:#}"));
    assert_eq!(solved.modes.rigid_dropped, 0, "the holes leave a rigid motion");
    let f: Vec<f64> = solved
        .modes
        .eigenvalues
        .iter()
        .map(|l| l.sqrt() / (2.0 * std::f64::consts::PI))
        .collect();
    eprintln!("held by faces {tags:?}: {f:.1?} Hz");
    assert_eq!(f.len(), 8);
    // A steel block of 20 × 10 × 6 mm held at both holes: its modes are at the scale of the
    // speed of sound over its size (5 km/s / 20 mm = 250 kHz); a rigid motion left would be ~0.
    assert!(f[0] > 10e3, "{f:?}");
    // Only the hole faces' nodes are held: every held node lies on a hole's cylinder.
    for &d in &solved.dofs.fixed {
        let x = solved.mesh.nodes[d as usize / 3];
        let on = holes.iter().any(|(_, (a, p, r))| {
            let v = sub(x, *p);
            let off = sub(v, a.map(|y| y * dot(v, *a)));
            // The fitted radius is of triangle centroids, inside the true one.
            (dot(off, off).sqrt() - r).abs() < 0.1 * r
        });
        assert!(on, "held node at {x:?} is on no hole");
    }
}

/// The preview a viewer shows before a compute: the surface vertices and triangles of the mesh
/// the compute makes, with the same tags, all six faces of the box there.
#[test]
fn the_surface_preview_is_the_surface_of_the_computed_mesh() {
    let _one = serial();
    let dir = tempfile::tempdir().unwrap();
    let s = scene(dir.path(), &cantilever_step(), 0.05, "");
    let p = ves_pipeline::preview::surface_preview(&s).unwrap_or_else(|e| panic!("{e:#}"));
    let (m, _) = mesh::generate(&s, None).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(p.vertices.len(), m.surface_vertices().len());
    assert_eq!(p.faces, m.surface_faces);
    assert_eq!(p.triangles.len(), m.surface.len());
    for (t, f) in p.triangles.iter().zip(&m.surface) {
        for k in 0..3 {
            assert_eq!(p.vertices[t[k] as usize], m.nodes[f[k] as usize]);
        }
    }
}
