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
    /// Its name in the STEP file (`ADVANCED_FACE('name', …)`), where the file gives faces
    /// names and gmsh's numbering is confirmed to be the file's order ([`name_from_step`]).
    pub name: Option<String>,
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
    let mut faces = of_mesh(&mesh);
    if let Some(text) = step_text(&scene.geometry)
        && let Err(why) = name_from_step(&mut faces, &text)
    {
        tracing::warn!(
            "{}: its face names are not given: {why}; the faces are known by number",
            scene.geometry.display()
        );
    }
    Ok(faces)
}

/// The text of a STEP file (`None` for another kind of file, or one that does not read).
pub fn step_text(path: &Path) -> Option<String> {
    let ext = path.extension()?.to_string_lossy().to_ascii_lowercase();
    if ext != "step" && ext != "stp" {
        return None;
    }
    let bytes = crate::input::read(path).ok()?;
    Some(String::from_utf8_lossy(&bytes).into_owned())
}

/// A plane's or an axis' direction agrees with the file's within this (1 − |cos|: 2.6°).
const DIRECTION_TOL: f64 = 1e-3;
/// A face's position agrees with the file's within this share of the part's size.
const POSITION_TOL: f64 = 1e-4;

/// Names `faces` (a STEP part's, as gmsh numbered them) with the names the STEP file gives
/// its faces ([`crate::step_faces`]): gmsh numbers the faces in the order of the file's shells
/// (OpenCASCADE builds the shape in that order), which is believed only when the counts agree
/// and every plane and cylinder the file states is the face of that number here — the plane
/// through the same point with the same normal, the cylinder of the same radius about the same
/// axis (a cylinder meshed too coarsely to read as one, a narrow strip, only has its centroid
/// within the cylinder). A name every
/// face shares (a body's name copied onto each), "NONE", or the face's own entity number
/// (`'#520'`) is not a face's name. Where OpenCASCADE split faces (the mesh has more), the
/// order is matched with the pieces ([`split_alignment`]). Returns how many faces were named, or
/// why none were: a mesh made on a healed geometry may have renumbered its faces, a file with
/// several solids may be ordered otherwise.
pub fn name_from_step(faces: &mut [Face], text: &str) -> Result<usize, String> {
    use crate::step_faces::Surface;
    let stated = crate::step_faces::faces(text);
    if stated.is_empty() {
        return Err("the file has no solid with faces".into());
    }
    let named = |s: &crate::step_faces::StepFace| {
        let shared = stated.len() > 1 && stated.iter().all(|o| o.name == s.name);
        !(s.name.is_empty() || shared || s.name.eq_ignore_ascii_case("NONE") || s.name == format!("#{}", s.id))
    };
    if !stated.iter().any(named) {
        return Ok(0);
    }
    let (n, m) = (faces.len(), stated.len());
    if n < m || n > m + MAX_SPLITS || faces.iter().enumerate().any(|(k, f)| f.tag as usize != k + 1) {
        return Err(format!("the file has {m} faces, the mesh {n}"));
    }
    let metres = crate::step_units::length_unit(text).map_or(1e-3, |u| u.metres);
    let (mut lo, mut hi) = (Vector3::repeat(f64::INFINITY), Vector3::repeat(f64::NEG_INFINITY));
    for f in faces.iter() {
        lo = lo.inf(&Vector3::from(f.centroid_m));
        hi = hi.sup(&Vector3::from(f.centroid_m));
    }
    let size = (hi - lo)
        .norm()
        .max(faces.iter().map(|f| f.area_m2.sqrt()).fold(0.0, f64::max));
    let fit = |f: &Face, s: &crate::step_faces::StepFace| fits(f, &s.surface, metres, size);
    let assigned: Vec<usize> = if n == m {
        // One face each: face k is the file's k-th, said by the first that is not.
        for (f, s) in faces.iter().zip(&stated) {
            if fit(f, s) == Fit::No {
                let said = match s.surface {
                    Surface::Plane { .. } => "a plane",
                    Surface::Cylinder { .. } => "a cylinder",
                    Surface::Other => "another surface",
                };
                let here = match f.kind {
                    "plane" => "a plane",
                    "cylinder" => "a cylinder",
                    _ => "another surface",
                };
                return Err(format!(
                    "face {} here ({here}) is not the file's face {} (#{}, {said})",
                    f.tag, f.tag, s.id
                ));
            }
        }
        (0..m).collect()
    } else {
        split_alignment(n, m, |i, j| fit(&faces[i], &stated[j]))?
    };
    let checked = faces
        .iter()
        .zip(&assigned)
        .filter(|(f, j)| fit(f, &stated[**j]) == Fit::Same)
        .count();
    if checked == 0 {
        return Err("it has no plane or cylinder to check gmsh's numbering by".into());
    }
    let mut count = 0;
    for (f, &j) in faces.iter_mut().zip(&assigned) {
        if named(&stated[j]) {
            f.name = Some(stated[j].name.clone());
            count += 1;
        }
    }
    Ok(count)
}

/// Most faces OpenCASCADE may have split in two (or more) for names still to be given.
const MAX_SPLITS: usize = 16;

/// How a face found in the mesh fits a face the file states.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Fit {
    /// The same plane or cylinder.
    Same,
    /// Nothing against it (a surface of another kind, a cylinder too coarse to read as one).
    Possible,
    /// Not that face.
    No,
}

fn fits(f: &Face, surface: &crate::step_faces::Surface, metres: f64, size: f64) -> Fit {
    use crate::step_faces::Surface;
    let parallel = |a: [f64; 3], b: [f64; 3]| Vector3::from(a).dot(&Vector3::from(b)).abs() >= 1.0 - DIRECTION_TOL;
    let same = |yes: bool| if yes { Fit::Same } else { Fit::No };
    match (surface, f.kind) {
        (Surface::Plane { point, normal }, "plane") => {
            let off = Vector3::from(f.centroid_m) - metres * Vector3::from(*point);
            let n = f.normal.unwrap_or_default();
            same(parallel(*normal, n) && Vector3::from(*normal).dot(&off).abs() <= POSITION_TOL * size)
        }
        (Surface::Cylinder { point, axis, radius }, "cylinder") => {
            let (r, a) = (metres * radius, Vector3::from(*axis));
            let off = Vector3::from(f.axis_point_m.unwrap_or_default()) - metres * Vector3::from(*point);
            let from_axis = (off - off.dot(&a) * a).norm();
            same(
                (f.radius_m.unwrap_or_default() - r).abs() <= RADIUS_TOL * r
                    && parallel(*axis, f.axis.unwrap_or_default())
                    && from_axis <= POSITION_TOL * size + RADIUS_TOL * r,
            )
        }
        // A cylinder meshed coarsely reads as a plane (a narrow strip: one row of facets) or
        // as other: its facets' centroid lies within the cylinder.
        (Surface::Cylinder { point, axis, radius }, _) => {
            let a = Vector3::from(*axis);
            let off = Vector3::from(f.centroid_m) - metres * Vector3::from(*point);
            let within = (off - off.dot(&a) * a).norm() <= (1.0 + RADIUS_TOL) * metres * radius + POSITION_TOL * size;
            if within { Fit::Possible } else { Fit::No }
        }
        (Surface::Plane { .. }, _) => Fit::No,
        (Surface::Other, _) => Fit::Possible,
    }
}

/// The file's face of each of `n` mesh faces (in tag order) when OpenCASCADE split some of the
/// `m` the file states: the faces keep the file's order, each file face gets one or more
/// consecutive mesh faces, and a piece after the first must be the same plane or cylinder. Only
/// an alignment that is the one possible is taken (counted by dynamic programming, capped at
/// two).
fn split_alignment(n: usize, m: usize, fit: impl Fn(usize, usize) -> Fit) -> Result<Vec<usize>, String> {
    // ways[i][j]: alignments of the first i mesh faces onto the first j file faces (capped).
    // Only i - (n - m) ≤ j ≤ i can be reached: a band of n - m + 1 per row (≤ MAX_SPLITS + 1),
    // not a square sized by the file's face count.
    let band = n - m + 1;
    let at = |i: usize, j: usize| i * band + (j + band - 1 - i);
    let mut ways = vec![0u8; (n + 1) * band];
    ways[at(0, 0)] = 1;
    for i in 0..n {
        for j in i.saturating_sub(n - m)..=i.min(m) {
            let w = ways[at(i, j)];
            if w == 0 {
                continue;
            }
            if j < m && fit(i, j) != Fit::No {
                ways[at(i + 1, j + 1)] = (ways[at(i + 1, j + 1)] + w).min(2);
            }
            // A piece keeps j: reachable only while n - m pieces are not all used.
            if j > 0 && j + (n - m) > i && fit(i, j - 1) == Fit::Same {
                ways[at(i + 1, j)] = (ways[at(i + 1, j)] + w).min(2);
            }
        }
    }
    match ways[at(n, m)] {
        0 => {
            return Err(format!(
                "the file has {m} faces, the mesh {n}, and no split of the file's faces fits"
            ));
        }
        1 => {}
        _ => {
            return Err(format!(
                "the file has {m} faces, the mesh {n}, matched more than one way"
            ));
        }
    }
    let mut assigned = vec![0; n];
    let mut j = m;
    for i in (0..n).rev() {
        // The one path: its step into (i + 1, j) came from a new face or from a piece.
        if j > 0 && ways[at(i, j - 1)] > 0 && fit(i, j - 1) != Fit::No {
            j -= 1;
            assigned[i] = j;
        } else {
            assigned[i] = j - 1;
        }
    }
    Ok(assigned)
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
        name: None,
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A STEP file (millimetres) with faces `(name, surface)` in one shell; surfaces are
    /// `p z` (the plane z = z, normal +z) or `c r` (the cylinder of radius r about z).
    fn step(faces: &[(&str, &str)]) -> String {
        let mut data = String::from(
            "#1=DIRECTION('',(0.,0.,1.));\n#9=(LENGTH_UNIT()NAMED_UNIT(*)SI_UNIT(.MILLI.,.METRE.));\n\
             #8=(GEOMETRIC_REPRESENTATION_CONTEXT(3)GLOBAL_UNIT_ASSIGNED_CONTEXT((#9))REPRESENTATION_CONTEXT('',''));\n",
        );
        let mut refs = Vec::new();
        for (i, (name, surface)) in faces.iter().enumerate() {
            let n = 100 + 10 * i;
            let (kind, value) = surface.split_once(' ').unwrap();
            let value: f64 = value.parse().unwrap();
            let z = if kind == "p" { value } else { 0.0 };
            data += &format!("#{}=CARTESIAN_POINT('',(0.,0.,{z:?}));\n", n + 1);
            data += &format!("#{}=AXIS2_PLACEMENT_3D('',#{},#1,$);\n", n + 2, n + 1);
            data += &match kind {
                "p" => format!("#{}=PLANE('',#{});\n", n + 3, n + 2),
                _ => format!("#{}=CYLINDRICAL_SURFACE('',#{},{value:?});\n", n + 3, n + 2),
            };
            data += &format!("#{n}=ADVANCED_FACE('{name}',(#5),#{},.T.);\n", n + 3);
            refs.push(format!("#{n}"));
        }
        data += &format!(
            "#2=CLOSED_SHELL('',({}));\n#3=MANIFOLD_SOLID_BREP('',#2);\n",
            refs.join(",")
        );
        format!("ISO-10303-21;\nHEADER;\nENDSEC;\nDATA;\n{data}ENDSEC;\n")
    }

    /// A face as the mesh would list it (metres).
    fn face(tag: u32, kind: &'static str, at: f64) -> Face {
        let mut f = Face {
            tag,
            kind,
            area_m2: 1e-4,
            centroid_m: [0.01, 0.0, at],
            normal: None,
            axis: None,
            axis_point_m: None,
            radius_m: None,
            concave: None,
            triangles: 10,
            name: None,
        };
        if kind == "plane" {
            f.normal = Some([0.0, 0.0, -1.0]);
        } else if kind == "cylinder" {
            (f.axis, f.axis_point_m, f.radius_m) = (Some([0.0, 0.0, 1.0]), Some([0.0, 0.0, 0.02]), Some(at));
        }
        f
    }

    #[test]
    fn names_follow_the_file_s_order_only_where_its_geometry_agrees() {
        let text = step(&[("bottom", "p 0"), ("bore", "c 5"), ("top", "p 40"), ("", "p 20")]);
        let listed = || {
            vec![
                face(1, "plane", 0.0),
                face(2, "cylinder", 0.005),
                face(3, "plane", 0.04),
                face(4, "plane", 0.02),
            ]
        };
        let mut faces = listed();
        assert_eq!(name_from_step(&mut faces, &text), Ok(3));
        let names: Vec<_> = faces.iter().map(|f| f.name.as_deref()).collect();
        assert_eq!(names, [Some("bottom"), Some("bore"), Some("top"), None]);
        // A narrow strip of the bore, meshed too coarsely to read as a cylinder, is held only to
        // lie within it.
        for kind in ["other", "plane"] {
            let mut faces = listed();
            faces[1] = face(2, kind, 0.0);
            faces[1].centroid_m = [0.0049, 0.0, 0.02];
            assert_eq!(name_from_step(&mut faces, &text), Ok(3));
        }
        // Numbered otherwise (two planes swapped, the bore's radius, one face fewer): no names.
        for change in [
            |f: &mut Vec<Face>| (f[0].tag, f[2].tag) = (3, 1),
            |f: &mut Vec<Face>| f[1].radius_m = Some(0.006),
            |f: &mut Vec<Face>| f[1] = face(2, "plane", 0.0),
            |f: &mut Vec<Face>| drop(f.pop()),
        ] {
            let mut faces = listed();
            change(&mut faces);
            assert!(name_from_step(&mut faces, &text).is_err());
            assert!(faces.iter().all(|f| f.name.is_none()));
        }
        // OpenCASCADE split the bottom in two (tags shift after it): both pieces are the bottom.
        let mut split = listed();
        split.insert(1, face(2, "plane", 0.0));
        for (k, f) in split.iter_mut().enumerate() {
            f.tag = k as u32 + 1;
        }
        assert_eq!(name_from_step(&mut split, &text), Ok(4));
        let names: Vec<_> = split.iter().map(|f| f.name.as_deref()).collect();
        assert_eq!(names, [Some("bottom"), Some("bottom"), Some("bore"), Some("top"), None]);
        // Two faces of the file on one plane and three pieces on it here: which piece is whose
        // is not known, so none is named.
        let twins = step(&[("left", "p 0"), ("right", "p 0"), ("bore", "c 5")]);
        let mut three = vec![
            face(1, "plane", 0.0),
            face(2, "plane", 0.0),
            face(3, "plane", 0.0),
            face(4, "cylinder", 0.005),
        ];
        assert!(name_from_step(&mut three, &twins).is_err());
        assert!(three.iter().all(|f| f.name.is_none()));
        // No name worth giving: a body's name on every face, NONE, the face's own number.
        let shared = step(&[("Body", "p 0"), ("Body", "c 5"), ("Body", "p 40"), ("Body", "p 20")]);
        let own = step(&[("#100", "p 0"), ("NONE", "c 5"), ("#120", "p 40"), ("", "p 20")]);
        for text in [shared, own] {
            let mut faces = listed();
            assert_eq!(name_from_step(&mut faces, &text), Ok(0));
        }
    }
}
