//! Modal basis file, version 1 (HDF5; DESIGN.md §3). Written under a temporary name and renamed
//! when complete, so a killed run never leaves a half-written basis under the final name.

use crate::fem::MassProperties;
use crate::mesh::Mesh;
use crate::modes::Modes;
use crate::scene::{Scene, Voi};
use crate::supports::Dofs;
use anyhow::{Context, Result, bail};
use ndarray::{Array1, Array2};
use std::path::{Path, PathBuf};

pub use ves_runtime::basis::{FORMAT, VERSION};

/// One modal space, as written.
pub struct Space<'a> {
    /// "global" or the VOI's name.
    pub name: &'a str,
    /// The VOI this space refines, if any.
    pub voi: Option<&'a Voi>,
    /// Its mesh.
    pub mesh: &'a Mesh,
    /// Its free/fixed DOFs.
    pub dofs: &'a Dofs,
    /// Its elastic modes.
    pub modes: &'a Modes,
    /// Mass properties (stored under `rigid/` for free bodies).
    pub mass: &'a MassProperties,
    /// Static compliance blocks (`compliance/`), if computed.
    pub compliance: Option<&'a crate::compliance::Compliance>,
    /// State-transfer matrices from the other spaces (`transfer/<from>`, row-major
    /// `r × r_from`): modal coordinates of `from` → this space's (see `transfer.rs`).
    pub transfers: &'a [(String, Vec<f64>)],
}

fn attr_str(loc: &hdf5::Location, name: &str, value: &str) -> Result<()> {
    ves_runtime::h5str::write(loc, name, value).with_context(|| format!("attribute {name}"))
}

fn attr_f64(loc: &hdf5::Location, name: &str, value: f64) -> Result<()> {
    loc.new_attr::<f64>().create(name)?.write_scalar(&value)?;
    Ok(())
}

fn attr_u32(loc: &hdf5::Location, name: &str, value: u32) -> Result<()> {
    loc.new_attr::<u32>().create(name)?.write_scalar(&value)?;
    Ok(())
}

fn attr_vec3(loc: &hdf5::Location, name: &str, value: [f64; 3]) -> Result<()> {
    loc.new_attr_builder()
        .with_data(&Array1::from(value.to_vec()))
        .create(name)?;
    Ok(())
}

fn write_space(file: &hdf5::File, s: &Space<'_>) -> Result<()> {
    let g = file.create_group(&format!("spaces/{}", s.name))?;
    attr_u32(&g, "element_order", u32::from(s.mesh.order))?;
    attr_u32(&g, "rigid_modes_dropped", s.modes.rigid_dropped as u32)?;
    if let Some(v) = s.voi {
        attr_vec3(&g, "voi_min", v.bbox.min)?;
        attr_vec3(&g, "voi_max", v.bbox.max)?;
    }
    let mesh = g.create_group("mesh")?;
    attr_u32(&mesh, "vertex_count", s.mesh.vertex_count as u32)?;
    let n = s.mesh.nodes.len();
    let nodes = Array2::from_shape_fn((n, 3), |(i, c)| s.mesh.nodes[i][c]);
    mesh.new_dataset_builder().with_data(&nodes).create("nodes")?;
    let p = s.mesh.nodes_per_tet();
    let tets = Array2::from_shape_vec((s.mesh.tet_count(), p), s.mesh.tets.clone())?;
    mesh.new_dataset_builder()
        .with_data(&tets)
        .chunk((tets.nrows().clamp(1, 16384), p))
        .shuffle()
        .deflate(4)
        .create("tets")?;
    let tri = Array2::from_shape_fn((s.mesh.surface.len(), 3), |(i, c)| s.mesh.surface[i][c]);
    mesh.new_dataset_builder().with_data(&tri).create("surface_triangles")?;
    mesh.new_dataset_builder()
        .with_data(&Array1::from(s.dofs.fixed.clone()))
        .create("fixed_dofs")?;

    let modes = g.create_group("modes")?;
    let r = s.modes.eigenvalues.len();
    modes
        .new_dataset_builder()
        .with_data(&Array1::from(s.modes.eigenvalues.clone()))
        .create("eigenvalues")?;
    modes
        .new_dataset_builder()
        .with_data(&Array1::from(s.modes.frequencies_hz()))
        .create("frequencies_hz")?;
    modes
        .new_dataset_builder()
        .with_data(&Array1::from(s.modes.residuals.clone()))
        .create("relative_residuals")?;
    let nf = s.dofs.free_count();
    let mut basis = Array2::<f64>::zeros((3 * n, r));
    for j in 0..r {
        let col = &s.modes.vectors[j * nf..(j + 1) * nf];
        for (v, &d) in col.iter().zip(&s.dofs.free) {
            basis[(d as usize, j)] = *v;
        }
    }
    // Chunks of whole rows of a few modes: the runtime reads vertex rows of the first r modes.
    let chunk = ((3 * n).clamp(1, 3 * 4096), r.clamp(1, 16));
    modes
        .new_dataset_builder()
        .with_data(&basis)
        .chunk(chunk)
        .create("basis")?;

    if let Some(c) = s.compliance {
        let grp = g.create_group("compliance")?;
        grp.new_dataset_builder()
            .with_data(&Array1::from(c.nodes.clone()))
            .create("nodes")?;
        let blocks = ndarray::Array3::from_shape_fn((c.blocks.len(), 3, 3), |(k, a, b)| c.blocks[k][a][b]);
        grp.new_dataset_builder().with_data(&blocks).create("blocks")?;
    }
    if !s.transfers.is_empty() {
        let grp = g.create_group("transfer")?;
        for (from, t) in s.transfers {
            let cols = t.len() / r.max(1);
            let m = Array2::from_shape_vec((r, cols), t.clone())?;
            grp.new_dataset_builder().with_data(&m).create(from.as_str())?;
        }
    }
    if s.modes.rigid_dropped > 0 {
        let rigid = g.create_group("rigid")?;
        attr_f64(&rigid, "mass", s.mass.mass)?;
        attr_vec3(&rigid, "center_of_mass", s.mass.center)?;
        let inertia = Array2::from_shape_fn((3, 3), |(i, j)| s.mass.inertia[i][j]);
        rigid.new_attr_builder().with_data(&inertia).create("inertia")?;
    }
    Ok(())
}

/// Fails early when `out` cannot be written (its directory is missing, or it is a directory).
pub fn check_output(out: &Path) -> Result<()> {
    let dir = out
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    if !dir.is_dir() {
        bail!(
            "{}: the output directory does not exist; create it or choose another -o",
            out.display()
        );
    }
    if out.is_dir() {
        bail!("{}: is a directory; give a file name with -o", out.display());
    }
    Ok(())
}

/// Writes all spaces of a scene to `out` atomically (temporary file, then rename).
pub fn write(out: &Path, scene: &Scene, spaces: &[Space<'_>]) -> Result<()> {
    check_output(out)?;
    let tmp = temp_name(out);
    let result = (|| -> Result<()> {
        // The 1.8+ file format (v2 object headers, v3 superblock) checksums every piece of
        // metadata: a damaged header is refused by libhdf5 instead of parsed (the fuzzer found
        // libhdf5 1.10 reading freed memory when parsing corrupted v1 headers).
        let file = hdf5::File::with_options()
            .with_fapl(|p| p.libver_v18())
            .create(&tmp)
            .with_context(|| format!("cannot create {}", tmp.display()))?;
        attr_str(&file, "format", FORMAT)?;
        attr_u32(&file, "version", VERSION)?;
        attr_str(&file, "generator", &format!("ves {}", env!("CARGO_PKG_VERSION")))?;
        attr_str(&file, "scene_toml", &scene.toml)?;
        attr_str(&file, "default_space", "global")?;
        // What this file was made from (`ves batch` skips scenes whose output is up to date).
        attr_str(&file, "source_hash", &source_hash(scene)?)?;
        let mat = file.create_group("material")?;
        attr_f64(&mat, "young", scene.material.young)?;
        attr_f64(&mat, "poisson", scene.material.poisson)?;
        attr_f64(&mat, "density", scene.material.density)?;
        attr_f64(&mat, "rayleigh_alpha", scene.damping.alpha)?;
        attr_f64(&mat, "rayleigh_beta", scene.damping.beta)?;
        for s in spaces {
            write_space(&file, s).with_context(|| format!("writing space {:?}", s.name))?;
        }
        file.close()?;
        Ok(())
    })();
    match result {
        Ok(()) => {
            std::fs::rename(&tmp, out).with_context(|| format!("cannot move {} to {}", tmp.display(), out.display()))
        }
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            Err(e.context(format!(
                "{}: writing the basis failed, nothing was written",
                out.display()
            )))
        }
    }
}

/// A content hash of what a basis depends on: the tool version, the scene text, the effective
/// mode count and the geometry file's bytes (FNV-1a, 64 bits: change detection, not security).
pub fn source_hash(scene: &Scene) -> Result<String> {
    let geometry = std::fs::read(&scene.geometry)
        .with_context(|| format!("{}: cannot read the geometry", scene.geometry.display()))?;
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
        // Field separator, so "ab"+"c" and "a"+"bc" differ.
        h ^= 0xff;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    };
    eat(concat!("ves ", env!("CARGO_PKG_VERSION")).as_bytes());
    eat(scene.toml.as_bytes());
    eat(&(scene.modes.count as u64).to_le_bytes());
    eat(&geometry);
    Ok(format!("fnv1a64:{h:016x}"))
}

/// The `source_hash` stored in an existing basis file, if it is one.
pub fn stored_source_hash(path: &Path) -> Option<String> {
    ves_runtime::basis::guarded(path, || {
        let file = ves_runtime::basis::open_checked(path)?;
        Ok::<_, ves_runtime::LoadError>(read_attr_str(&file, "source_hash").ok())
    })
    .ok()
    .flatten()
}

/// Removes temporary files a killed run left beside `out` (their process is gone).
pub fn remove_stale_temps(out: &Path) {
    let (Some(dir), Some(name)) = (out.parent(), out.file_name()) else {
        return;
    };
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    let prefix = format!("{}.tmp-", name.to_string_lossy());
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let file = e.file_name().to_string_lossy().into_owned();
        if let Some(pid) = file.strip_prefix(&prefix).and_then(|p| p.parse::<u32>().ok())
            && !Path::new(&format!("/proc/{pid}")).exists()
        {
            tracing::info!(file, "removing a temporary file left by a killed run");
            let _ = std::fs::remove_file(e.path());
        }
    }
}

fn temp_name(out: &Path) -> PathBuf {
    let mut name = out.file_name().map(|n| n.to_os_string()).unwrap_or_default();
    name.push(format!(".tmp-{}", std::process::id()));
    out.with_file_name(name)
}

/// What `ves info` shows of one space.
#[derive(Debug, serde::Serialize)]
pub struct SpaceInfo {
    /// Space name.
    pub name: String,
    /// Mesh nodes.
    pub nodes: usize,
    /// Corner vertices.
    pub vertices: usize,
    /// Tets.
    pub tets: usize,
    /// 1 or 2.
    pub element_order: u32,
    /// Elastic modes stored.
    pub modes: usize,
    /// Their frequencies.
    pub frequencies_hz: Vec<f64>,
    /// Largest stored relative residual.
    pub max_relative_residual: f64,
    /// Rigid modes dropped.
    pub rigid_modes_dropped: u32,
    /// Vertices with a static-correction block (0: none stored).
    pub static_correction_vertices: usize,
}

/// What `ves info` shows of a basis file.
#[derive(Debug, serde::Serialize)]
pub struct BasisInfo {
    /// The file.
    pub path: String,
    /// File size, bytes.
    pub bytes: u64,
    /// Generator string.
    pub generator: String,
    /// Default space.
    pub default_space: String,
    /// Spaces, "global" first.
    pub spaces: Vec<SpaceInfo>,
}

fn read_attr_str(loc: &hdf5::Location, name: &str) -> Result<String> {
    ves_runtime::h5str::read(loc, name).ok_or_else(|| anyhow::anyhow!("string attribute {name} missing"))
}

/// Reads the summary of a basis file.
pub fn info(path: &Path) -> Result<BasisInfo> {
    // A panic of the HDF5 layer on a damaged file becomes an error (see basis::guarded).
    ves_runtime::basis::guarded(path, || info_unguarded(path))
}

fn info_unguarded(path: &Path) -> Result<BasisInfo> {
    let file = ves_runtime::basis::open_checked(path)?;
    let bad = |what: &str| anyhow::anyhow!("{}: damaged basis file: {what}", path.display());
    let spaces_group = file.group("spaces").map_err(|_| bad("no /spaces group"))?;
    let mut names = spaces_group.member_names().map_err(|_| bad("cannot list /spaces"))?;
    names.sort_by_key(|n| (n != "global", n.clone()));
    let mut spaces = Vec::new();
    for name in names {
        let g = spaces_group
            .group(&name)
            .map_err(|_| bad(&format!("space {name} is not a group")))?;
        let ctx = |what: &str| bad(&format!("space {name}: {what}"));
        let nodes = g.dataset("mesh/nodes").map_err(|_| ctx("mesh/nodes missing"))?.shape();
        let tets = g.dataset("mesh/tets").map_err(|_| ctx("mesh/tets missing"))?.shape();
        let vertices: u32 = g
            .group("mesh")?
            .attr("vertex_count")
            .and_then(|a| a.read_scalar())
            .map_err(|_| ctx("vertex_count missing"))?;
        let freqs: Vec<f64> = g
            .dataset("modes/frequencies_hz")
            .and_then(|d| d.read_raw())
            .map_err(|_| ctx("modes/frequencies_hz missing"))?;
        let res: Vec<f64> = g
            .dataset("modes/relative_residuals")
            .and_then(|d| d.read_raw())
            .map_err(|_| ctx("modes/relative_residuals missing"))?;
        let basis = g
            .dataset("modes/basis")
            .map_err(|_| ctx("modes/basis missing"))?
            .shape();
        if nodes.len() != 2 || nodes[1] != 3 || basis.len() != 2 || basis[0] != 3 * nodes[0] || basis[1] != freqs.len()
        {
            return Err(ctx("dataset shapes disagree (nodes, basis, frequencies)"));
        }
        spaces.push(SpaceInfo {
            name: name.clone(),
            nodes: nodes[0],
            vertices: vertices as usize,
            tets: tets.first().copied().unwrap_or(0),
            element_order: g
                .attr("element_order")
                .and_then(|a| a.read_scalar())
                .map_err(|_| ctx("element_order missing"))?,
            modes: freqs.len(),
            frequencies_hz: freqs,
            max_relative_residual: res.iter().fold(0.0, |a: f64, &b| a.max(b)),
            static_correction_vertices: g.dataset("compliance/nodes").map(|d| d.size()).unwrap_or(0),
            rigid_modes_dropped: g
                .attr("rigid_modes_dropped")
                .and_then(|a| a.read_scalar())
                .map_err(|_| ctx("rigid_modes_dropped missing"))?,
        });
    }
    Ok(BasisInfo {
        path: path.display().to_string(),
        bytes: std::fs::metadata(path).map(|m| m.len()).unwrap_or(0),
        generator: read_attr_str(&file, "generator").unwrap_or_default(),
        default_space: read_attr_str(&file, "default_space").unwrap_or_default(),
        spaces,
    })
}
