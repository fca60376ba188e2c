//! A part's CAD faces as a user sees them: each face's tag (what `[[fixed]] faces` and
//! `[[load]] faces` name), its kind — a plane with its normal, a cylinder with its axis, radius
//! and whether it is a hole, or other — its area and centroid. Read from the surface mesh of the
//! part (each triangle knows its CAD face): the nodes lie on the CAD surface, so a cylinder's
//! radius and axis are those of the CAD face; the area is the facets' (within a fraction of a
//! percent of the CAD area on a curved face, exact on a plane).

use crate::scene::Scene;
use anyhow::Result;
use nalgebra::{Matrix3, Vector3};
use serde::Serialize;
use std::path::Path;
use ves_numerics::tet_mesh::Mesh;

/// One CAD face.
#[derive(Clone, Debug, Serialize)]
pub struct Face {
    /// gmsh's surface tag: what a scene's `faces = [...]` names.
    pub tag: u32,
    /// "plane", "cylinder" or "other".
    pub kind: &'static str,
    /// Area, m² (of its facets).
    pub area_m2: f64,
    /// Area-weighted centroid, m.
    pub centroid_m: [f64; 3],
    /// A plane's outward unit normal.
    pub normal: Option<[f64; 3]>,
    /// A cylinder's axis (unit; its sign is arbitrary).
    pub axis: Option<[f64; 3]>,
    /// A point on a cylinder's axis (its least-squares circle's centre), m.
    pub axis_point_m: Option<[f64; 3]>,
    /// A cylinder's radius, m.
    pub radius_m: Option<f64>,
    /// Whether a cylinder is concave (its outward normals point at the axis: a bore, a concave
    /// fillet) rather than convex (a boss, a shaft, a rounded edge).
    pub concave: Option<bool>,
    /// Surface triangles of the mesh on it.
    pub triangles: usize,
}

/// A plane's normals agree within this (1 − the largest eigenvalue's share of Σ A n nᵀ).
const PLANE_TOL: f64 = 1e-6;
/// A cylinder's normals are across its axis within this (the smallest eigenvalue's share): a
/// facet through three points of a cylinder leans a little along it.
const ACROSS_TOL: f64 = 0.02;
/// A cylinder's nodes lie at its radius within this (spread over radius).
const RADIUS_TOL: f64 = 0.01;
/// A cylinder whose axis is not along x, y or z turns about it by at least ~45° (the middle
/// eigenvalue's share, ½(1 − sin Δ/Δ) for a turn Δ): a narrow strip of a cone or a torus (a
/// chamfer along an arc) fits a cylinder of a leaning axis as well, and is called other.
const TURN_MIN: f64 = 0.05;

/// The faces of a scene's part (its global space's mesh, through the mesh cache), or of a
/// geometry file given alone (STEP, IGES: meshed with 4-node tets at an automatic size).
pub fn list(input: &Path, allow_geo_scripts: bool) -> Result<Vec<Face>> {
    let is_scene = input.extension().is_some_and(|e| e.eq_ignore_ascii_case("toml"));
    let scene = if is_scene {
        Scene::load_with(input, crate::scene::SceneOptions { allow_geo_scripts })?
    } else {
        let ext = input
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        anyhow::ensure!(
            matches!(ext.as_str(), "step" | "stp" | "iges" | "igs"),
            "{}: give a STEP or IGES file, or a scene (.toml) for other geometry",
            input.display()
        );
        let absolute = std::path::absolute(input)?;
        let text = format!(
            "name = \"faces\"\n[geometry]\nstep = {}\n[material]\nyoung = 2.1e11\npoisson = 0.3\ndensity = 7850.0\n\
             [mesh]\norder = 1\ntarget_error = 0.05\n[modes]\ncount = 1\n",
            toml::Value::String(absolute.display().to_string())
        );
        let beside = absolute.with_file_name("faces.toml");
        Scene::parse(&beside, &text).map_err(|e| anyhow::anyhow!("{}", e.message))?
    };
    let (mesh, _) = crate::mesh::generate(&scene, None)?;
    Ok(of_mesh(&mesh))
}

/// The faces of a bare surface (a basis's: its corner vertices, triangles and each triangle's
/// face tag), as [`of_mesh`] finds them.
pub fn of_surface(vertices: &[[f64; 3]], triangles: &[[u32; 3]], faces: &[u32]) -> Vec<Face> {
    let mesh = Mesh {
        nodes: vertices.to_vec(),
        vertex_count: vertices.len(),
        kind: ves_format::ElementKind::Tet4,
        tets: Vec::new(),
        surface: triangles.to_vec(),
        surface_faces: faces.to_vec(),
    };
    of_mesh(&mesh)
}

/// The faces of a mesh's surface, by tag (triangles of no known face are left out).
pub fn of_mesh(mesh: &Mesh) -> Vec<Face> {
    let mut by_tag: std::collections::BTreeMap<u32, Vec<usize>> = std::collections::BTreeMap::new();
    for (t, &f) in mesh.surface_faces.iter().enumerate() {
        if f != 0 {
            by_tag.entry(f).or_default().push(t);
        }
    }
    by_tag.into_iter().map(|(tag, tris)| face(mesh, tag, &tris)).collect()
}

fn face(mesh: &Mesh, tag: u32, tris: &[usize]) -> Face {
    let frames: Vec<_> = tris
        .iter()
        .map(|&t| ves_numerics::fem::springs::triangle_frame(mesh, t))
        .collect();
    let (mut area, mut centroid, mut mean_n, mut s) = (0.0, Vector3::zeros(), Vector3::zeros(), Matrix3::zeros());
    for &(n, c, a) in &frames {
        let n = Vector3::from(n);
        area += a;
        centroid += a * Vector3::from(c);
        mean_n += a * n;
        s += a * n * n.transpose();
    }
    let centroid = centroid / area.max(f64::MIN_POSITIVE);
    let mut f = Face {
        tag,
        kind: "other",
        area_m2: area,
        centroid_m: centroid.into(),
        normal: None,
        axis: None,
        axis_point_m: None,
        radius_m: None,
        concave: None,
        triangles: tris.len(),
    };
    if area <= 0.0 {
        return f;
    }
    let e = nalgebra::SymmetricEigen::new(s);
    let (lo, hi) = (e.eigenvalues.min() / area, e.eigenvalues.max() / area);
    let mid = 1.0 - lo - hi;
    if hi > 1.0 - PLANE_TOL {
        f.kind = "plane";
        f.normal = Some(mean_n.normalize().into());
        return f;
    }
    if lo > ACROSS_TOL {
        return f;
    }
    let (axis, point) = crate::supports::cylinder_axis(mesh, tris);
    let along_xyz = axis.iter().any(|c| c.abs() == 1.0);
    if mid < TURN_MIN && !along_xyz {
        return f;
    }
    let (a, p) = (Vector3::from(axis), Vector3::from(point));
    let mut nodes: Vec<u32> = tris.iter().flat_map(|&t| mesh.surface[t]).collect();
    nodes.sort_unstable();
    nodes.dedup();
    let radii: Vec<f64> = nodes
        .iter()
        .map(|&i| {
            let d = Vector3::from(mesh.nodes[i as usize]) - p;
            (d - d.dot(&a) * a).norm()
        })
        .collect();
    let r = radii.iter().sum::<f64>() / radii.len().max(1) as f64;
    let spread = radii.iter().fold(0.0f64, |m, x| m.max((x - r).abs()));
    if r > 0.0 && spread <= RADIUS_TOL * r {
        // A concave face's outward normals point at its axis.
        let outward: f64 = frames
            .iter()
            .map(|&(n, c, a_t)| {
                let d = Vector3::from(c) - p;
                a_t * Vector3::from(n).dot(&(d - d.dot(&a) * a))
            })
            .sum();
        f.kind = "cylinder";
        f.axis = Some(axis);
        f.axis_point_m = Some(point);
        f.radius_m = Some(r);
        f.concave = Some(outward < 0.0);
    }
    f
}
