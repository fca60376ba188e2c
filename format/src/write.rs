//! The one writer of basis files: plain slices in, a complete file out. Where the file goes
//! (temporary name, fsync, rename) is the caller's policy.

use crate::names::{self, material as mat, root, space as sp};
use crate::{Material, RigidProperties};
use ndarray::{Array1, Array2, Array3};
use std::path::Path;

mod loads;
pub use loads::{LoadData, PeakRecord};

/// Writing failed: what was being written and HDF5's message.
#[derive(Debug, thiserror::Error)]
#[error("writing {what}: {message}")]
pub struct WriteError {
    /// The dataset, attribute or group.
    pub what: String,
    /// HDF5's message.
    pub message: String,
}

/// A whole basis file.
pub struct FileData<'a> {
    /// The writing program, e.g. "ves 0.1.0".
    pub generator: &'a str,
    /// The scene's text.
    pub scene_toml: &'a str,
    /// Content hash of the inputs (optional).
    pub source_hash: Option<&'a str>,
    /// Material and damping.
    pub material: Material,
    /// Spaces; the first is the default.
    pub spaces: Vec<SpaceData<'a>>,
}

/// One space.
pub struct SpaceData<'a> {
    /// "global" or the VOI's name.
    pub name: &'a str,
    /// The element kind (stored as `element_order`).
    pub kind: crate::ElementKind,
    /// Rigid modes dropped (free bodies: 6).
    pub rigid_modes_dropped: u32,
    /// The VOI this space refines (min, max corners).
    pub voi: Option<[[f64; 3]; 2]>,
    /// Corner vertices: the first nodes.
    pub vertex_count: usize,
    /// How the mesh was made (optional attribute).
    pub meshing_strategy: Option<&'a str>,
    /// Node coordinates, m.
    pub nodes: &'a [[f64; 3]],
    /// Connectivity, `kind.nodes()` per tet (gmsh order).
    pub tets: &'a [u32],
    /// Surface triangles on corner vertices, outward.
    pub surface_triangles: &'a [[u32; 3]],
    /// The CAD face of each surface triangle (optional dataset; 0: unknown).
    pub surface_faces: Option<&'a [u32]>,
    /// Supported DOFs 3i+c.
    pub fixed_dofs: &'a [u32],
    /// λ, ascending.
    pub eigenvalues: &'a [f64],
    /// Relative residuals, one per mode.
    pub relative_residuals: &'a [f64],
    /// Estimated relative discretization error, one per mode (optional dataset).
    pub estimated_relative_error: Option<&'a [f64]>,
    /// Modal stress at the corner vertices, row-major [6·nv, r] (optional dataset).
    pub stress: Option<&'a [f64]>,
    /// Mode shapes, row-major [3n, r].
    pub basis: &'a [f64],
    /// Static compliance: nodes and blocks.
    pub compliance: Option<(&'a [u32], &'a [crate::Block3])>,
    /// The hand's contact patches (optional group).
    pub contact: Option<&'a crate::Contact>,
    /// What a hand feels wrong at surface vertices (optional group).
    pub felt: Option<&'a crate::FeltErrors>,
    /// Transfer matrices from other spaces, row-major [r, r_from].
    pub transfers: &'a [(String, Vec<f64>)],
    /// What each support carries per unit modal coordinate, with the points the moments are
    /// about: (centres [s], row-major [6·s, r]); none for a free body.
    pub support_reactions: Option<(&'a [[f64; 3]], &'a [f64])>,
    /// Each support's reaction per newton of a static load at surface corner vertices: (the
    /// vertices, ascending; row-major [q, 18·s]); only with `support_reactions`.
    pub support_influence: Option<(&'a [u32], &'a [f64])>,
    /// Static load cases (`loads/<name>/`); empty: none.
    pub loads: &'a [LoadData<'a>],
    /// The reduced nonlinear model, if any.
    pub nonlinear: Option<NonlinearData<'a>>,
    /// Mass properties of a free body.
    pub rigid: Option<RigidProperties>,
}

/// A space's reduced St. Venant–Kirchhoff model ([`sp::NONLINEAR`]).
#[derive(Clone, Copy, Debug)]
pub struct NonlinearData<'a> {
    /// The first basis columns that are eigenmodes.
    pub eigenmodes: usize,
    /// How many lowest modes' pairwise derivatives were added.
    pub derivatives_of: usize,
    /// T, row-major [r, P], P = r(r+1)/2.
    pub cubic: &'a [f64],
    /// H, row-major [P, P].
    pub quartic: &'a [f64],
}

trait Ctx<T> {
    fn ctx(self, what: &str) -> Result<T, WriteError>;
}

impl<T, E: std::fmt::Display> Ctx<T> for Result<T, E> {
    fn ctx(self, what: &str) -> Result<T, WriteError> {
        self.map_err(|e| WriteError {
            what: what.to_string(),
            message: one_line(&e.to_string()),
        })
    }
}

/// HDF5's message on one line; of a failed system call, only what the system said (HDF5 adds
/// the time, the buffer address and the byte counts).
pub fn one_line(message: &str) -> String {
    let flat = message.split_whitespace().collect::<Vec<_>>().join(" ");
    match flat
        .split_once("error message = '")
        .and_then(|(_, rest)| rest.split_once('\''))
    {
        Some((system, _)) => {
            let errno = flat
                .split_once("errno = ")
                .and_then(|(_, rest)| rest.split(',').next())
                .map(|n| format!(" (errno {n})"))
                .unwrap_or_default();
            format!("{system}{errno}")
        }
        None => flat,
    }
}

fn attr_f64(loc: &hdf5::Location, name: &str, value: f64) -> Result<(), WriteError> {
    loc.new_attr::<f64>()
        .create(name)
        .and_then(|a| a.write_scalar(&value))
        .ctx(name)
}

fn attr_u32(loc: &hdf5::Location, name: &str, value: u32) -> Result<(), WriteError> {
    loc.new_attr::<u32>()
        .create(name)
        .and_then(|a| a.write_scalar(&value))
        .ctx(name)
}

fn attr_vec3(loc: &hdf5::Location, name: &str, value: [f64; 3]) -> Result<(), WriteError> {
    loc.new_attr_builder()
        .with_data(&Array1::from(value.to_vec()))
        .create(name)
        .map(drop)
        .ctx(name)
}

fn attr_str(loc: &hdf5::Location, name: &str, value: &str) -> Result<(), WriteError> {
    crate::strings::write(loc, name, value).ctx(name)
}

/// Writes `data` to a new file at `path` (replacing any file there).
pub fn write_file(path: &Path, data: &FileData<'_>) -> Result<(), WriteError> {
    // The 1.8+ file format (v2 object headers, v3 superblock) checksums every piece of metadata:
    // a damaged header is refused by libhdf5 instead of parsed (the fuzzer found libhdf5 1.10
    // reading freed memory when parsing corrupted v1 headers). Strong close (crate::file).
    let file = crate::file::create(path, true).ctx(&path.display().to_string())?;
    attr_str(&file, root::FORMAT, names::FORMAT)?;
    attr_u32(&file, root::VERSION, names::VERSION)?;
    attr_str(&file, root::GENERATOR, data.generator)?;
    attr_str(&file, root::SCENE_TOML, data.scene_toml)?;
    let default = data.spaces.first().map_or(names::GLOBAL_SPACE, |s| s.name);
    attr_str(&file, root::DEFAULT_SPACE, default)?;
    if let Some(h) = data.source_hash {
        attr_str(&file, root::SOURCE_HASH, h)?;
    }
    let m = file.create_group(mat::GROUP).ctx(mat::GROUP)?;
    attr_f64(&m, mat::YOUNG, data.material.young)?;
    attr_f64(&m, mat::POISSON, data.material.poisson)?;
    attr_f64(&m, mat::DENSITY, data.material.density)?;
    attr_f64(&m, mat::ALPHA, data.material.alpha)?;
    attr_f64(&m, mat::BETA, data.material.beta)?;
    if let Some(y) = data.material.yield_strength {
        attr_f64(&m, mat::YIELD_STRENGTH, y)?;
    }
    for s in &data.spaces {
        write_space(&file, s).map_err(|e| WriteError {
            what: format!("space {:?}: {}", s.name, e.what),
            ..e
        })?;
    }
    // Errors of writes HDF5 deferred (metadata, cached raw data) surface here, not in a drop.
    file.flush().ctx("the file's cached data")?;
    file.close().ctx("the file's last data")
}

fn write_space(file: &hdf5::File, s: &SpaceData<'_>) -> Result<(), WriteError> {
    let g = file
        .create_group(&format!("{}/{}", names::SPACES, s.name))
        .ctx("group")?;
    attr_u32(&g, sp::ELEMENT_ORDER, u32::from(s.kind.order()))?;
    attr_u32(&g, sp::RIGID_MODES_DROPPED, s.rigid_modes_dropped)?;
    if let Some([lo, hi]) = s.voi {
        attr_vec3(&g, sp::VOI_MIN, lo)?;
        attr_vec3(&g, sp::VOI_MAX, hi)?;
    }
    let mesh = g.create_group(sp::MESH).ctx(sp::MESH)?;
    attr_u32(&mesh, sp::VERTEX_COUNT, s.vertex_count as u32)?;
    if let Some(m) = s.meshing_strategy {
        attr_str(&mesh, sp::MESHING_STRATEGY, m)?;
    }
    let n = s.nodes.len();
    let nodes = Array2::from_shape_fn((n, 3), |(i, c)| s.nodes[i][c]);
    g.new_dataset_builder()
        .with_data(&nodes)
        .create(sp::NODES)
        .ctx(sp::NODES)?;
    let p = s.kind.nodes();
    let tets = Array2::from_shape_vec((s.tets.len() / p.max(1), p), s.tets.to_vec()).ctx(sp::TETS)?;
    g.new_dataset_builder()
        .with_data(&tets)
        .chunk((tets.nrows().clamp(1, 16384), p))
        .shuffle()
        .deflate(4)
        .create(sp::TETS)
        .ctx(sp::TETS)?;
    let tri = Array2::from_shape_fn((s.surface_triangles.len(), 3), |(i, c)| s.surface_triangles[i][c]);
    g.new_dataset_builder()
        .with_data(&tri)
        .create(sp::SURFACE_TRIANGLES)
        .ctx(sp::SURFACE_TRIANGLES)?;
    if let Some(faces) = s.surface_faces {
        if faces.len() != s.surface_triangles.len() {
            return Err(WriteError {
                what: sp::SURFACE_FACES.into(),
                message: format!(
                    "{} face tags for {} surface triangles",
                    faces.len(),
                    s.surface_triangles.len()
                ),
            });
        }
        // Few distinct values (147 faces over 39 124 triangles on the mould): shuffled and
        // deflated it stores 14 % of its bytes there.
        g.new_dataset_builder()
            .with_data(&Array1::from(faces.to_vec()))
            .chunk(faces.len().clamp(1, 65536))
            .shuffle()
            .deflate(4)
            .create(sp::SURFACE_FACES)
            .ctx(sp::SURFACE_FACES)?;
    }
    vector(&g, sp::FIXED_DOFS, s.fixed_dofs)?;
    loads::write_fixed_mask(&g, n, s.fixed_dofs)?;
    loads::write_loads(&g, n, s.vertex_count, s.loads)?;
    g.create_group(sp::MODES).ctx(sp::MODES)?;
    vector(&g, sp::EIGENVALUES, s.eigenvalues)?;
    let freqs: Vec<f64> = s
        .eigenvalues
        .iter()
        .map(|&l| l.max(0.0).sqrt() / (2.0 * std::f64::consts::PI))
        .collect();
    vector(&g, sp::FREQUENCIES_HZ, &freqs)?;
    vector(&g, sp::RELATIVE_RESIDUALS, s.relative_residuals)?;
    if let Some(e) = s.estimated_relative_error {
        vector(&g, sp::ESTIMATED_RELATIVE_ERROR, e)?;
    }
    if let Some(stress) = s.stress {
        let r = s.eigenvalues.len();
        let a = Array2::from_shape_vec((6 * s.vertex_count, r), stress.to_vec()).ctx(sp::STRESS)?;
        let ds = g
            .new_dataset_builder()
            .with_data(&a)
            .chunk(((6 * s.vertex_count).clamp(1, 6 * 4096), r.clamp(1, 16)))
            .create(sp::STRESS)
            .ctx(sp::STRESS)?;
        attr_str(&ds, sp::STRESS_COMPONENTS, sp::STRESS_COMPONENT_ORDER)?;
    }
    let r = s.eigenvalues.len();
    if let Some((centres, per_mode)) = s.support_reactions {
        let a = Array2::from_shape_vec((6 * centres.len(), r), per_mode.to_vec()).ctx(sp::SUPPORT_REACTIONS)?;
        g.new_dataset_builder()
            .with_data(&a)
            .create(sp::SUPPORT_REACTIONS)
            .ctx(sp::SUPPORT_REACTIONS)?;
        let c = Array2::from_shape_fn((centres.len(), 3), |(k, c)| centres[k][c]);
        g.new_dataset_builder()
            .with_data(&c)
            .create(sp::SUPPORT_CENTRES)
            .ctx(sp::SUPPORT_CENTRES)?;
        if let Some((nodes, values)) = s.support_influence {
            let a = Array2::from_shape_vec((nodes.len(), 18 * centres.len()), values.to_vec())
                .ctx(sp::SUPPORT_INFLUENCE)?;
            g.new_dataset_builder()
                .with_data(&a)
                .create(sp::SUPPORT_INFLUENCE)
                .ctx(sp::SUPPORT_INFLUENCE)?;
            g.new_dataset_builder()
                .with_data(nodes)
                .create(sp::SUPPORT_INFLUENCE_NODES)
                .ctx(sp::SUPPORT_INFLUENCE_NODES)?;
        }
    }
    let basis = Array2::from_shape_vec((3 * n, r), s.basis.to_vec()).ctx(sp::BASIS)?;
    // Chunks of whole rows of a few modes: the runtime reads vertex rows of the first r modes.
    g.new_dataset_builder()
        .with_data(&basis)
        .chunk(((3 * n).clamp(1, 3 * 4096), r.clamp(1, 16)))
        .create(sp::BASIS)
        .ctx(sp::BASIS)?;
    if let Some(nl) = s.nonlinear {
        let ng = g.create_group(sp::NONLINEAR).ctx(sp::NONLINEAR)?;
        attr_str(&ng, sp::NONLINEAR_MODEL, "stvk")?;
        attr_u32(&ng, sp::EIGENMODES, nl.eigenmodes as u32)?;
        attr_u32(&ng, sp::DERIVATIVES_OF, nl.derivatives_of as u32)?;
        let np = r * (r + 1) / 2;
        let t = Array2::from_shape_vec((r, np), nl.cubic.to_vec()).ctx(sp::NONLINEAR_CUBIC)?;
        g.new_dataset_builder()
            .with_data(&t)
            .create(sp::NONLINEAR_CUBIC)
            .ctx(sp::NONLINEAR_CUBIC)?;
        let h = Array2::from_shape_vec((np, np), nl.quartic.to_vec()).ctx(sp::NONLINEAR_QUARTIC)?;
        g.new_dataset_builder()
            .with_data(&h)
            .create(sp::NONLINEAR_QUARTIC)
            .ctx(sp::NONLINEAR_QUARTIC)?;
    }
    if let Some((nodes, blocks)) = s.compliance {
        g.create_group(sp::COMPLIANCE).ctx(sp::COMPLIANCE)?;
        vector(&g, sp::COMPLIANCE_NODES, nodes)?;
        let b = Array3::from_shape_fn((blocks.len(), 3, 3), |(k, a, c)| blocks[k][a][c]);
        g.new_dataset_builder()
            .with_data(&b)
            .create(sp::COMPLIANCE_BLOCKS)
            .ctx(sp::COMPLIANCE_BLOCKS)?;
    }
    if let Some(f) = s.felt {
        let fg = g.create_group(sp::FELT).ctx(sp::FELT)?;
        attr_u32(&fg, sp::FELT_MODES, f.modes)?;
        vector(&g, sp::FELT_NODES, &f.nodes)?;
        vector(&g, sp::FELT_TRUNCATION, &f.truncation)?;
        vector(&g, sp::FELT_MESH_ERROR, &f.mesh_error)?;
    }
    if let Some(c) = s.contact {
        let cg = g.create_group(sp::CONTACT).ctx(sp::CONTACT)?;
        attr_f64(&cg, sp::CONTACT_RADIUS, c.radius)?;
        vector(&g, sp::CONTACT_CENTRES, &c.centres)?;
        vector(&g, sp::CONTACT_OFFSETS, &c.offsets)?;
        vector(&g, sp::CONTACT_NODES, &c.nodes)?;
        vector(&g, sp::CONTACT_WEIGHTS, &c.weights)?;
    }
    if !s.transfers.is_empty() {
        g.create_group(sp::TRANSFER).ctx(sp::TRANSFER)?;
        for (from, t) in s.transfers {
            let name = format!("{}/{from}", sp::TRANSFER);
            let m = Array2::from_shape_vec((r, t.len() / r.max(1)), t.clone()).ctx(&name)?;
            g.new_dataset_builder().with_data(&m).create(name.as_str()).ctx(&name)?;
        }
    }
    if let Some(rp) = s.rigid {
        let rg = g.create_group(sp::RIGID).ctx(sp::RIGID)?;
        attr_f64(&rg, sp::MASS, rp.mass)?;
        attr_vec3(&rg, sp::CENTER_OF_MASS, rp.center)?;
        let inertia = Array2::from_shape_fn((3, 3), |(i, j)| rp.inertia[i][j]);
        rg.new_attr_builder()
            .with_data(&inertia)
            .create(sp::INERTIA)
            .ctx(sp::INERTIA)?;
        if !rp.free.is_all() {
            let name = format!("{}/{}", sp::RIGID, sp::FREE_MOTIONS);
            let t = rp.free.twists();
            let m = Array2::from_shape_fn((t.len(), 6), |(i, j)| t[i][j]);
            g.new_dataset_builder().with_data(&m).create(name.as_str()).ctx(&name)?;
        }
    }
    Ok(())
}

fn vector<T: hdf5::H5Type + Clone>(g: &hdf5::Group, name: &str, v: &[T]) -> Result<(), WriteError> {
    g.new_dataset_builder()
        .with_data(&Array1::from(v.to_vec()))
        .create(name)
        .map(drop)
        .ctx(name)
}

#[cfg(test)]
mod tests {
    use crate::{BasisReader, FileData, Material, SpaceData, names::space as sp};

    /// One tet, its four faces tagged 3, 5, 5, 9, one mode.
    fn write_tet(path: &std::path::Path, faces: Option<&[u32]>) -> Result<(), super::WriteError> {
        write_tet_with(path, faces, &[])
    }

    /// [`write_tet`] with its first node held and load cases.
    fn write_tet_with(
        path: &std::path::Path,
        faces: Option<&[u32]>,
        loads: &[super::LoadData<'_>],
    ) -> Result<(), super::WriteError> {
        write_tet_edited(path, faces, loads, |_| {})
    }

    /// [`write_tet_with`], the space edited before it is written.
    fn write_tet_edited(
        path: &std::path::Path,
        faces: Option<&[u32]>,
        loads: &[super::LoadData<'_>],
        edit: impl FnOnce(&mut SpaceData<'_>),
    ) -> Result<(), super::WriteError> {
        let nodes = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let surface = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];
        let mut data = FileData {
            generator: "test",
            scene_toml: "",
            source_hash: None,
            material: Material {
                young: 2e11,
                poisson: 0.3,
                density: 7800.0,
                alpha: 0.0,
                beta: 0.0,
                yield_strength: None,
            },
            spaces: vec![SpaceData {
                name: "global",
                kind: crate::ElementKind::Tet4,
                rigid_modes_dropped: 0,
                voi: None,
                vertex_count: 4,
                meshing_strategy: None,
                nodes: &nodes,
                tets: &[0, 1, 2, 3],
                surface_triangles: &surface,
                surface_faces: faces,
                fixed_dofs: if loads.is_empty() { &[] } else { &[0, 1, 2] },
                eigenvalues: &[1.0],
                relative_residuals: &[0.0],
                estimated_relative_error: None,
                stress: None,
                basis: &[0.1; 12],
                compliance: None,
                felt: None,
                contact: None,
                transfers: &[],
                support_reactions: None,
                support_influence: None,
                nonlinear: None,
                loads,
                rigid: None,
            }],
        };
        edit(&mut data.spaces[0]);
        super::write_file(path, &data)
    }

    /// The rigid motions a part's supports leave: a free body's six without a dataset; a part
    /// held in some directions with its twists, read back as written; such a part's file
    /// without them (written before) gives no rigid motion, held in place; twists of the
    /// wrong count or dependent ones are refused (and by `validate`).
    #[test]
    fn free_motions_are_read_back_and_checked() {
        let path = temp("free");
        let props = |free: crate::FreeMotions| crate::RigidProperties {
            mass: 2.0,
            center: [0.25, 0.25, 0.25],
            inertia: [[0.1, 0.0, 0.0], [0.0, 0.1, 0.0], [0.0, 0.0, 0.1]],
            free,
        };
        let read = || BasisReader::open(&path).unwrap().space("global").unwrap().rigid();
        write_tet_edited(&path, None, &[], |s| {
            s.rigid_modes_dropped = 6;
            s.rigid = Some(props(crate::FreeMotions::all()));
        })
        .unwrap();
        assert_eq!(read().unwrap().map(|r| r.free), Some(crate::FreeMotions::all()));
        let turn = [[0.0, -0.25, 0.0, 1.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0, 0.0, 0.0]];
        let two = crate::FreeMotions::new(&turn).unwrap();
        write_tet_edited(&path, None, &[], |s| {
            s.rigid_modes_dropped = 2;
            s.rigid = Some(props(two));
        })
        .unwrap();
        assert_eq!(read().unwrap().map(|r| r.free.twists().to_vec()), Some(turn.to_vec()));
        let name = format!("{}/{}", sp::RIGID, sp::FREE_MOTIONS);
        {
            let f = crate::file::open_rw(&path).unwrap();
            f.group("spaces/global").unwrap().unlink(&name).unwrap();
        }
        assert_eq!(read().unwrap(), None, "older file: held in place");
        for (what, dropped, twists, says) in [
            ("count", 1u32, turn.to_vec(), "expected [1, 6]"),
            (
                "dependent",
                2,
                vec![turn[0], turn[0].map(|v| 2.0 * v)],
                "not independent",
            ),
            ("free body", 6, turn.to_vec(), "present for a free body"),
        ] {
            write_tet_edited(&path, None, &[], |s| {
                s.rigid_modes_dropped = dropped;
                s.rigid = Some(props(two));
            })
            .unwrap();
            {
                let f = crate::file::open_rw(&path).unwrap();
                let g = f.group("spaces/global").unwrap();
                let _ = g.unlink(&name);
                let m = ndarray::Array2::from_shape_fn((twists.len(), 6), |(i, j)| twists[i][j]);
                add_f64(&g, &name, Some(m));
            }
            let e = read().unwrap_err();
            assert!(e.message.contains(says), "{what}: {e}");
            let file = BasisReader::open(&path).unwrap();
            assert!(file.space("global").unwrap().validate().is_err(), "{what}");
        }
        let _ = std::fs::remove_file(path);
    }

    fn temp(name: &str) -> std::path::PathBuf {
        std::env::temp_dir().join(format!("ves-format-{}-{name}.h5", std::process::id()))
    }

    /// `mesh/surface_faces` is written and read back as given; a file without it (older) reads
    /// as none; a writer given the wrong count refuses, and a file holding the wrong count is
    /// refused by the reader.
    #[test]
    fn surface_faces_are_written_read_back_and_checked() {
        let path = temp("faces");
        write_tet(&path, Some(&[3, 5, 5, 9])).unwrap();
        let file = BasisReader::open(&path).unwrap();
        let space = file.space("global").unwrap();
        assert_eq!(space.surface_faces().unwrap(), Some(vec![3, 5, 5, 9]));
        space.validate().unwrap();
        drop(space);
        drop(file);
        let older = temp("older");
        write_tet(&older, None).unwrap();
        assert_eq!(
            BasisReader::open(&older)
                .unwrap()
                .space("global")
                .unwrap()
                .surface_faces()
                .unwrap(),
            None
        );
        let e = write_tet(&temp("short"), Some(&[3, 5])).unwrap_err();
        assert!(e.to_string().contains("2 face tags for 4 surface triangles"), "{e}");
        // A file whose dataset holds three tags for four triangles.
        {
            let f = crate::file::open_rw(&older).unwrap();
            let g = f.group("spaces/global").unwrap();
            g.new_dataset_builder()
                .with_data(&ndarray::Array1::from(vec![1u32, 2, 3]))
                .create(sp::SURFACE_FACES)
                .unwrap();
        }
        let file = BasisReader::open(&older).unwrap();
        let e = file.space("global").unwrap().surface_faces().unwrap_err();
        assert!(e.message.contains("3 tags for 4 surface triangles"), "{e}");
        for p in [path, older, temp("short")] {
            let _ = std::fs::remove_file(p);
        }
    }

    /// The test tet written to `path`, its space's group open for more datasets (with its file,
    /// which must outlive it).
    fn write_tet_group(path: &std::path::Path) -> (hdf5::File, hdf5::Group) {
        write_tet(path, None).unwrap();
        let f = crate::file::open_rw(path).unwrap();
        let g = f.group("spaces/global").unwrap();
        (f, g)
    }

    /// Adds dataset `name` holding `values` to `g`, when given.
    fn add_f64(g: &hdf5::Group, name: &str, values: Option<ndarray::Array2<f64>>) {
        if let Some(v) = values {
            g.new_dataset_builder().with_data(&v).create(name).unwrap();
        }
    }

    /// Support reactions are read back as stored; reactions without their centres, the wrong
    /// shape or a non-finite value are refused (and by `validate`).
    #[test]
    fn support_reactions_are_read_back_and_checked() {
        let path = temp("reactions");
        let add = |reactions: Option<ndarray::Array2<f64>>, centres: Option<ndarray::Array2<f64>>| {
            let (_file, g) = write_tet_group(&path);
            add_f64(&g, sp::SUPPORT_REACTIONS, reactions);
            add_f64(&g, sp::SUPPORT_CENTRES, centres);
        };
        let read = || {
            BasisReader::open(&path)
                .unwrap()
                .space("global")
                .unwrap()
                .support_reactions()
        };
        let six = ndarray::Array2::from_shape_fn((6, 1), |(i, _)| i as f64);
        let centre = ndarray::arr2(&[[0.5, 0.0, 0.0]]);
        add(Some(six.clone()), Some(centre.clone()));
        let (c, r) = read().unwrap().expect("stored");
        assert_eq!((c, r), (vec![[0.5, 0.0, 0.0]], vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0]));
        add(None, None);
        assert!(read().unwrap().is_none());
        let mut nan = six.clone();
        nan[[3, 0]] = f64::NAN;
        for (what, reactions, centres, says) in [
            ("alone", Some(six.clone()), None, "come together"),
            (
                "short",
                Some(ndarray::Array2::zeros((5, 1))),
                Some(centre.clone()),
                "expected [6·s, 1]",
            ),
            ("nan", Some(nan), Some(centre.clone()), "non-finite"),
        ] {
            add(reactions, centres);
            let e = read().unwrap_err();
            assert!(e.message.contains(says), "{what}: {e}");
            let file = BasisReader::open(&path).unwrap();
            assert!(file.space("global").unwrap().validate().is_err(), "{what}");
        }
        let _ = std::fs::remove_file(path);
    }

    /// Influence coefficients: read back as stored (two supports, two vertices); refused alone,
    /// without the reactions, of the wrong width, with a vertex out of range or out of order, or
    /// with a NaN (by the reader and by `validate`).
    #[test]
    fn support_influence_is_read_back_and_checked() {
        let path = temp("influence");
        let twelve = ndarray::Array2::from_shape_fn((12, 1), |(i, _)| i as f64);
        let centres = ndarray::arr2(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]);
        let add = |reactions: bool, values: Option<ndarray::Array2<f64>>, nodes: Option<Vec<u32>>| {
            let (_file, g) = write_tet_group(&path);
            add_f64(&g, sp::SUPPORT_REACTIONS, reactions.then(|| twelve.clone()));
            add_f64(&g, sp::SUPPORT_CENTRES, reactions.then(|| centres.clone()));
            add_f64(&g, sp::SUPPORT_INFLUENCE, values);
            if let Some(n) = nodes {
                g.new_dataset_builder()
                    .with_data(&n)
                    .create(sp::SUPPORT_INFLUENCE_NODES)
                    .unwrap();
            }
        };
        let read = || {
            BasisReader::open(&path)
                .unwrap()
                .space("global")
                .unwrap()
                .support_influence()
        };
        let values = ndarray::Array2::from_shape_fn((2, 36), |(i, j)| (36 * i + j) as f64);
        add(true, Some(values.clone()), Some(vec![1, 3]));
        let (nodes, v) = read().unwrap().expect("stored");
        assert_eq!((nodes, v.len(), v[37]), (vec![1, 3], 72, 37.0));
        add(true, None, None);
        assert!(read().unwrap().is_none());
        let mut nan = values.clone();
        nan[[1, 5]] = f64::NAN;
        for (what, reactions, values, nodes, says) in [
            ("alone", true, Some(values.clone()), None, "come together"),
            (
                "no reactions",
                false,
                Some(values.clone()),
                Some(vec![1, 3]),
                "come together",
            ),
            (
                "narrow",
                true,
                Some(ndarray::Array2::zeros((2, 18))),
                Some(vec![1, 3]),
                "expected [q, 18·s]",
            ),
            ("beyond", true, Some(values.clone()), Some(vec![1, 4]), "beyond"),
            (
                "order",
                true,
                Some(values.clone()),
                Some(vec![3, 1]),
                "strictly ascending",
            ),
            ("nan", true, Some(nan), Some(vec![1, 3]), "non-finite"),
        ] {
            add(reactions, values, nodes);
            let e = read().unwrap_err();
            assert!(e.message.contains(says), "{what}: {e}");
            let file = BasisReader::open(&path).unwrap();
            assert!(file.space("global").unwrap().validate().is_err(), "{what}");
        }
        let _ = std::fs::remove_file(path);
    }

    /// Load cases and the `fixed` mask are written and read back as given; a file without them
    /// reads as none; a load case of the wrong shape, a non-finite value or an unknown kind is
    /// refused by the reader (and by `validate`).
    #[test]
    fn load_cases_are_written_read_back_and_checked() {
        let u: Vec<f64> = (0..12).map(|i| 1e-6 * f64::from(i)).collect();
        let largest = u
            .chunks_exact(3)
            .map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
            .fold(0.0, f64::max);
        let (vm, stress) = ([1.0, 2.0, 3.0, 4.0], [5.0; 24]);
        let load = super::LoadData {
            name: "tip",
            kind: "force",
            total_force: [0.0, 0.0, -10.0],
            reaction: [0.0, 0.0, 10.0],
            balance_residual: 1e-12,
            max_displacement: largest,
            max_von_mises: 4.0,
            displacement: &u,
            von_mises: &vm,
            stress: &stress,
            peak: Some(super::PeakRecord {
                verdict: "singular".into(),
                value: 4.0,
                error: None,
                refined: [4.5, 5.1],
                position: [0.0, 1.0, 0.0],
            }),
            regular_peak: Some(super::PeakRecord {
                verdict: "converging".into(),
                value: 3.0,
                error: Some(0.1),
                refined: [3.05, 3.07],
                position: [1.0, 0.0, 0.0],
            }),
        };
        let path = temp("loads");
        write_tet_with(&path, None, std::slice::from_ref(&load)).unwrap();
        let file = BasisReader::open(&path).unwrap();
        let space = file.space("global").unwrap();
        space.validate().unwrap();
        assert_eq!(space.fixed_mask().unwrap(), Some(vec![1, 0, 0, 0]));
        let read = space.loads().unwrap();
        assert_eq!(read.len(), 1);
        let l = &read[0];
        assert_eq!((l.name.as_str(), l.kind.as_str()), ("tip", "force"));
        assert_eq!((l.displacement.clone(), l.von_mises.clone()), (u.clone(), vm.to_vec()));
        assert_eq!(
            (l.reaction, l.total_force, l.stress.len()),
            ([0.0, 0.0, 10.0], [0.0, 0.0, -10.0], 24)
        );
        assert_eq!((&l.peak, &l.regular_peak), (&load.peak, &load.regular_peak));
        drop(space);
        drop(file);
        // Older files, and scenes without loads: none.
        let older = temp("noloads");
        write_tet(&older, None).unwrap();
        assert!(
            BasisReader::open(&older)
                .unwrap()
                .space("global")
                .unwrap()
                .loads()
                .unwrap()
                .is_empty()
        );
        // Damage: a NaN, a wrong shape, an unknown kind; (issue 40) a value beyond single
        // precision, a `max_displacement` that is not the data's, `loads` stored as a dataset, a
        // `fixed_mask` that disagrees with `fixed_dofs`.
        for (what, says) in [
            ("nan", "non-finite value"),
            ("shape", "expected [4]"),
            ("kind", "kind missing or not one of"),
            ("huge", "beyond single precision"),
            ("max", "max_displacement says"),
            ("dataset", "loads is not a group"),
            ("mask", "mesh/fixed_mask is 0 at node 0 but mesh/fixed_dofs holds it"),
            ("verdict", "peak_verdict is \"sure\", not one of"),
            ("error", "regular_peak_error missing, negative"),
        ] {
            write_tet_with(&path, None, std::slice::from_ref(&load)).unwrap();
            {
                let f = crate::file::open_rw(&path).unwrap();
                let c = f.group("spaces/global/loads/tip").unwrap();
                match what {
                    "nan" => {
                        c.dataset("von_mises")
                            .unwrap()
                            .write(&ndarray::arr1(&[1.0, f64::NAN, 3.0, 4.0]))
                            .unwrap();
                    }
                    "shape" => {
                        c.unlink("von_mises").unwrap();
                        c.new_dataset_builder()
                            .with_data(&ndarray::arr1(&[1.0, 2.0]))
                            .create("von_mises")
                            .unwrap();
                    }
                    "huge" => {
                        c.dataset("von_mises")
                            .unwrap()
                            .write(&ndarray::arr1(&[1.0, 1e300, 3.0, 4.0]))
                            .unwrap();
                    }
                    "max" => {
                        c.delete_attr("max_displacement").unwrap();
                        super::attr_f64(&c, "max_displacement", 2.0 * largest).unwrap();
                    }
                    "dataset" => {
                        f.unlink("spaces/global/loads").unwrap();
                        f.group("spaces/global")
                            .unwrap()
                            .new_dataset_builder()
                            .with_data(&ndarray::arr1(&[0.0; 3]))
                            .create("loads")
                            .unwrap();
                    }
                    "verdict" => {
                        c.delete_attr("peak_verdict").unwrap();
                        crate::strings::write(&c, "peak_verdict", "sure").unwrap();
                    }
                    "error" => {
                        c.delete_attr("regular_peak_error").unwrap();
                        super::attr_f64(&c, "regular_peak_error", -1.0).unwrap();
                    }
                    "mask" => {
                        f.dataset("spaces/global/mesh/fixed_mask")
                            .unwrap()
                            .write(&ndarray::arr1(&[0u32, 1, 1, 1]))
                            .unwrap();
                    }
                    _ => {
                        c.delete_attr("kind").unwrap();
                        crate::strings::write(&c, "kind", "wind").unwrap();
                    }
                }
            }
            let file = BasisReader::open(&path).unwrap();
            let space = file.space("global").unwrap();
            let e = space.validate().unwrap_err();
            assert!(e.message.contains(says), "{what}: {e}");
        }
        for p in [path, older] {
            let _ = std::fs::remove_file(p);
        }
    }

    /// A file written over in place while a reader has it open (as `cp` does: same inode,
    /// truncated, new bytes) is refused at the next read, never read as zeros; a file replaced
    /// by a rename (as VES writes) leaves the open reader on the file it opened.
    #[test]
    fn a_file_written_over_while_read_is_refused() {
        let (path, other) = (temp("inplace"), temp("other"));
        write_tet(&path, Some(&[3, 5, 5, 9])).unwrap();
        write_tet(&other, None).unwrap();
        let file = BasisReader::open(&path).unwrap();
        assert_eq!(file.space("global").unwrap().frequencies_hz().unwrap().len(), 1);
        std::fs::write(&path, std::fs::read(&other).unwrap()).unwrap();
        let e = file.space("global").and_then(|s| s.frequencies_hz()).unwrap_err();
        assert!(e.message.contains("changed while it was read"), "{e}");
        drop(file);

        write_tet(&path, Some(&[3, 5, 5, 9])).unwrap();
        let file = BasisReader::open(&path).unwrap();
        std::fs::rename(&other, &path).unwrap();
        let space = file.space("global").unwrap();
        assert_eq!(
            space.surface_faces().unwrap(),
            Some(vec![3, 5, 5, 9]),
            "the file opened"
        );
        let _ = std::fs::remove_file(path);
    }

    #[test]
    fn a_failed_system_write_is_told_in_a_few_words() {
        let hdf5 = "H5Fflush(): unable to flush file's cached information: file write failed: time = Wed Nov 25 19:31:56 2026\n, filename = '/tmp/b.h5', file descriptor = 4, errno = 28, error message = 'No space left on device', buf = 0x55bf, total write size = 1395";
        assert_eq!(super::one_line(hdf5), "No space left on device (errno 28)");
        assert_eq!(super::one_line("bad\n  thing"), "bad thing");
    }
}
