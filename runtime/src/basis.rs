//! A modal basis as the runtime holds it: corner vertices (optionally only the surface ones), the
//! first r modes in f32, mode-major so the full-field update is a sequence of axpys.

/// Value of the root `format` attribute of a v1 basis file.
pub const FORMAT: &str = "ves-modal-basis";
/// Newest file version this build reads.
pub const VERSION: u32 = 1;

/// Loading failed; the message names the file and what is wrong.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {message}")]
pub struct LoadError {
    /// The input.
    pub path: String,
    /// What is wrong and what to do.
    pub message: String,
}

/// Mass properties of a free body.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigidProperties {
    /// kg.
    pub mass: f64,
    /// m.
    pub center: [f64; 3],
    /// kg·m², about the centre of mass.
    pub inertia: [[f64; 3]; 3],
}

/// What to load from a basis file.
#[derive(Clone, Debug, Default)]
pub struct LoadOptions {
    /// Space name (default: the file's default space).
    pub space: Option<String>,
    /// Keep only the first r modes (default: all).
    pub modes: Option<usize>,
    /// Keep only surface vertices (enough to draw and touch the part).
    pub surface_only: bool,
}

/// A modal basis in memory.
#[derive(Clone, Debug)]
pub struct Basis {
    /// Space name.
    pub space: String,
    /// Rest positions of the kept vertices, m.
    pub rest: Vec<[f64; 3]>,
    /// Index of each kept vertex among the file's nodes.
    pub node_index: Vec<u32>,
    /// Surface triangles over kept vertices, outward.
    pub triangles: Vec<[u32; 3]>,
    /// Kept vertices on the surface (what the haptic point can touch).
    pub surface_vertices: Vec<u32>,
    /// Area-weighted outward unit normal per kept vertex (zero inside).
    pub normals: Vec<[f64; 3]>,
    /// Surface-edge neighbours of each kept vertex: `neighbours[neighbour_ptr[i]..neighbour_ptr[i + 1]]`.
    pub neighbour_ptr: Vec<u32>,
    /// See `neighbour_ptr`.
    pub neighbours: Vec<u32>,
    /// λᵢ = ωᵢ², ascending.
    pub eigenvalues: Vec<f64>,
    /// Mode-major f32 basis: mode j is `phi[j·3n .. (j+1)·3n]`, entry 3i+c.
    pub phi: Vec<f32>,
    /// Rayleigh α (1/s).
    pub alpha: f64,
    /// Rayleigh β (s).
    pub beta: f64,
    /// Mass properties, for free bodies.
    pub rigid: Option<RigidProperties>,
    /// Exact static compliance (K⁻¹)ᵢᵢ per kept vertex, m/N, when the file has it (NaN where a
    /// vertex has no block).
    pub compliance: Option<Vec<[[f64; 3]; 3]>>,
    /// Bytes of basis data held in memory.
    pub bytes_loaded: usize,
    /// The volume of interest this space refines (min, max corners, m); `None` for "global".
    pub voi: Option<[[f64; 3]; 2]>,
}

impl Basis {
    /// Builds a basis from vertex-major f64 rows (`rows[(3i+c)·r + j]`), checking shapes and
    /// finiteness. `path` names the source in errors.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        path: &str,
        space: &str,
        rest: Vec<[f64; 3]>,
        node_index: Vec<u32>,
        triangles: Vec<[u32; 3]>,
        eigenvalues: Vec<f64>,
        rows: &[f64],
        (alpha, beta): (f64, f64),
        rigid: Option<RigidProperties>,
    ) -> Result<Basis, LoadError> {
        let err = |message: String| LoadError {
            path: path.to_string(),
            message,
        };
        let (n, r) = (rest.len(), eigenvalues.len());
        if n == 0 || r == 0 {
            return Err(err(format!(
                "space {space:?} has {n} vertices and {r} modes; nothing to simulate"
            )));
        }
        if rows.len() != 3 * n * r {
            return Err(err(format!("basis has {} values, expected 3 × {n} × {r}", rows.len())));
        }
        if let Some(t) = triangles.iter().flatten().find(|&&v| v as usize >= n) {
            return Err(err(format!("a surface triangle refers to vertex {t} of {n}")));
        }
        if rest
            .iter()
            .flatten()
            .chain(rows)
            .chain(&eigenvalues)
            .any(|v| !v.is_finite())
        {
            return Err(err("non-finite values in nodes, modes or eigenvalues".into()));
        }
        // Held in f32: a finite f64 beyond f32's range would become infinite (found by fuzzing).
        if rows.iter().any(|v| v.abs() > f64::from(f32::MAX)) {
            return Err(err(
                "mode values beyond single precision (|φ| > 3.4e38): the file is damaged".into(),
            ));
        }
        if let Some(l) = eigenvalues.iter().find(|&&l| l <= 0.0) {
            return Err(err(format!("elastic eigenvalue {l} is not positive")));
        }
        if !(alpha >= 0.0 && beta >= 0.0) {
            return Err(err(format!(
                "Rayleigh damping ({alpha}, {beta}) must be finite and ≥ 0"
            )));
        }
        let mut phi = vec![0.0f32; 3 * n * r];
        for (k, row) in rows.chunks_exact(r).enumerate() {
            for (j, v) in row.iter().enumerate() {
                phi[j * 3 * n + k] = *v as f32;
            }
        }
        let (normals, surface_vertices) = vertex_normals(&rest, &triangles);
        let (neighbour_ptr, neighbours) = surface_neighbours(rest.len(), &triangles);
        let bytes_loaded = phi.len() * 4
            + rest.len() * 24
            + triangles.len() * 12
            + eigenvalues.len() * 8
            + normals.len() * 24
            + neighbour_ptr.len() * 4
            + neighbours.len() * 4;
        Ok(Basis {
            space: space.to_string(),
            rest,
            node_index,
            triangles,
            surface_vertices,
            normals,
            neighbour_ptr,
            neighbours,
            eigenvalues,
            phi,
            alpha,
            beta,
            rigid,
            compliance: None,
            bytes_loaded,
            voi: None,
        })
    }

    /// Attaches static compliance blocks, one per kept vertex (NaN: none for that vertex).
    pub fn with_compliance(mut self, blocks: Vec<[[f64; 3]; 3]>) -> Result<Basis, LoadError> {
        if blocks.len() != self.rest.len() {
            return Err(LoadError {
                path: self.space.clone(),
                message: format!("{} compliance blocks for {} vertices", blocks.len(), self.rest.len()),
            });
        }
        self.bytes_loaded += blocks.len() * 72;
        self.compliance = Some(blocks);
        Ok(self)
    }

    /// The compliance block of kept vertex `i`, if stored.
    pub fn compliance_of(&self, i: usize) -> Option<[[f64; 3]; 3]> {
        self.compliance
            .as_ref()
            .and_then(|c| c.get(i).copied())
            .filter(|b| b[0][0].is_finite())
    }

    /// Kept vertices.
    pub fn vertex_count(&self) -> usize {
        self.rest.len()
    }

    /// Modes.
    pub fn mode_count(&self) -> usize {
        self.eigenvalues.len()
    }

    /// Mode j over all kept vertices (3 values per vertex).
    pub fn mode(&self, j: usize) -> &[f32] {
        let m = 3 * self.rest.len();
        &self.phi[j * m..(j + 1) * m]
    }

    /// Copies the 3×r rows of vertex `i` into `out[c·r + j]` (f64).
    #[inline]
    pub fn gather_rows(&self, i: usize, out: &mut [f64]) {
        let (m, r) = (3 * self.rest.len(), self.eigenvalues.len());
        for c in 0..3 {
            for j in 0..r {
                out[c * r + j] = f64::from(self.phi[j * m + 3 * i + c]);
            }
        }
    }
}

/// A flat 3×3 grid of vertices (z = 0, spacing 1 cm, 8 triangles) with one mode, a uniform
/// stretch along x: u = (`scale`·x, 0, 0) per unit q, so every x edge strains by `scale`·q.
/// Eigenvalue `lambda`, Rayleigh α = `alpha`. For the strain tests of `haptic` and `visual`.
#[cfg(test)]
pub(crate) fn stretch_grid(scale: f64, lambda: f64, alpha: f64) -> Basis {
    let mut rest = Vec::new();
    for y in 0..3 {
        for x in 0..3 {
            rest.push([0.01 * x as f64, 0.01 * y as f64, 0.0]);
        }
    }
    let id = |x: u32, y: u32| y * 3 + x;
    let mut triangles = Vec::new();
    for y in 0..2 {
        for x in 0..2 {
            triangles.push([id(x, y), id(x + 1, y), id(x + 1, y + 1)]);
            triangles.push([id(x, y), id(x + 1, y + 1), id(x, y + 1)]);
        }
    }
    let rows: Vec<f64> = rest.iter().flat_map(|p| [scale * p[0], 0.0, 0.0]).collect();
    let n = rest.len() as u32;
    Basis::new(
        "grid",
        "global",
        rest,
        (0..n).collect(),
        triangles,
        vec![lambda],
        &rows,
        (alpha, 0.0),
        None,
    )
    .expect("grid basis")
}

/// Each vertex's neighbours along surface-triangle edges (CSR, sorted, no duplicates).
fn surface_neighbours(n: usize, triangles: &[[u32; 3]]) -> (Vec<u32>, Vec<u32>) {
    let mut pairs: Vec<(u32, u32)> = triangles
        .iter()
        .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
        .flat_map(|(a, b)| [(a, b), (b, a)])
        .collect();
    pairs.sort_unstable();
    pairs.dedup();
    let mut ptr = vec![0u32; n + 1];
    for &(a, _) in &pairs {
        ptr[a as usize + 1] += 1;
    }
    for i in 0..n {
        ptr[i + 1] += ptr[i];
    }
    (ptr, pairs.into_iter().map(|(_, b)| b).collect())
}

/// Area-weighted vertex normals, and the list of vertices on some triangle.
fn vertex_normals(rest: &[[f64; 3]], triangles: &[[u32; 3]]) -> (Vec<[f64; 3]>, Vec<u32>) {
    let mut normals = vec![[0.0f64; 3]; rest.len()];
    for t in triangles {
        let [a, b, c] = t.map(|v| rest[v as usize]);
        let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        let w = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
        let n = [
            u[1] * w[2] - u[2] * w[1],
            u[2] * w[0] - u[0] * w[2],
            u[0] * w[1] - u[1] * w[0],
        ];
        for &v in t {
            for k in 0..3 {
                normals[v as usize][k] += n[k];
            }
        }
    }
    let mut surface = Vec::new();
    for (i, n) in normals.iter_mut().enumerate() {
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        if len > 0.0 {
            *n = n.map(|x| x / len);
            surface.push(i as u32);
        }
    }
    (normals, surface)
}

#[cfg(feature = "hdf5")]
mod file {
    use super::*;
    use ndarray::s;
    use std::path::Path;

    fn read_str(loc: &hdf5::Location, name: &str) -> Option<String> {
        crate::h5str::read(loc, name)
    }

    /// Opens a basis file and checks that it is a VES basis of a version this build reads.
    pub fn open_checked(path: &Path) -> Result<hdf5::File, LoadError> {
        let err = |message: String| LoadError {
            path: path.display().to_string(),
            message,
        };
        if !path.is_file() {
            return Err(err("no such file".into()));
        }
        let file =
            hdf5::File::open(path).map_err(|_| err("not a readable HDF5 file (truncated or another format)".into()))?;
        let format = read_str(&file, "format").ok_or_else(|| {
            err("not a VES modal basis (no `format` attribute); produce one with `ves precompute`".into())
        })?;
        if format != FORMAT {
            return Err(err(format!(
                "format is {format:?}, not {FORMAT:?}; produce a basis with `ves precompute`"
            )));
        }
        let version: u32 = file
            .attr("version")
            .and_then(|a| a.read_scalar())
            .map_err(|_| err("`version` attribute missing or not an integer".into()))?;
        if version > VERSION {
            return Err(err(format!(
                "basis version {version} is newer than this runtime reads ({VERSION}); upgrade VES"
            )));
        }
        Ok(file)
    }

    /// Loads what `opts` asks for from a v1 basis file: only corner-vertex rows of the first r
    /// modes are read from disk.
    pub fn load(path: &Path, opts: &LoadOptions) -> Result<Basis, LoadError> {
        guarded(path, || load_unguarded(path, opts))
    }

    /// Runs `f`, turning a panic inside the HDF5 layer into an error: hdf5-metno 0.15 builds
    /// strings from file bytes unchecked, and a corrupted name made it panic while formatting
    /// one (found by the byte-flip test).
    pub fn guarded<T, E: From<LoadError>>(path: &Path, f: impl FnOnce() -> Result<T, E>) -> Result<T, E> {
        std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).unwrap_or_else(|_| {
            Err(E::from(LoadError {
                path: path.display().to_string(),
                message: "damaged file: the HDF5 layer failed on its structure".into(),
            }))
        })
    }

    fn load_unguarded(path: &Path, opts: &LoadOptions) -> Result<Basis, LoadError> {
        let p = path.display().to_string();
        let err = |message: String| LoadError {
            path: p.clone(),
            message,
        };
        let file = open_checked(path)?;
        let space = match &opts.space {
            Some(s) => s.clone(),
            None => read_str(&file, "default_space").unwrap_or_else(|| "global".into()),
        };
        let g = file
            .group(&format!("spaces/{space}"))
            .map_err(|_| err(format!("no space {space:?} in the file")))?;
        let h5 = |what: &str| err(format!("space {space:?}: {what} missing or damaged"));
        // Every dataset read is uncompressed: a declared size beyond the file's own is a damaged
        // header, refused before anything is allocated for it.
        let file_bytes = u128::from(std::fs::metadata(path).map(|m| m.len()).unwrap_or(0));
        let open = |grp: &hdf5::Group, name: &str| -> Result<hdf5::Dataset, LoadError> {
            let ds = grp.dataset(name).map_err(|_| h5(name))?;
            let elem = ds.dtype().map(|t| t.size()).unwrap_or(8) as u128;
            let bytes = ds.size() as u128 * elem;
            if bytes > file_bytes {
                return Err(err(format!(
                    "space {space:?}: {name} claims {bytes} bytes in a {file_bytes}-byte file; the file is damaged"
                )));
            }
            Ok(ds)
        };
        let nv: u32 = g
            .group("mesh")
            .and_then(|m| m.attr("vertex_count"))
            .and_then(|a| a.read_scalar())
            .map_err(|_| h5("mesh vertex_count"))?;
        let nv = nv as usize;
        let nodes = open(&g, "mesh/nodes")?;
        let basis = open(&g, "modes/basis")?;
        let (shape_n, shape_b) = (nodes.shape(), basis.shape());
        if shape_n.len() != 2
            || shape_n[1] != 3
            || nv == 0
            || nv > shape_n[0]
            || shape_b.len() != 2
            || shape_b[0] != 3 * shape_n[0]
        {
            return Err(err(format!(
                "space {space:?}: inconsistent shapes (nodes {shape_n:?}, basis {shape_b:?}, {nv} vertices)"
            )));
        }
        let r_all = shape_b[1];
        let r = opts.modes.unwrap_or(r_all);
        if r == 0 || r > r_all {
            return Err(err(format!("{r} modes asked, the space has {r_all}")));
        }
        let xyz: ndarray::Array2<f64> = nodes.read_slice(s![0..nv, ..]).map_err(|_| h5("mesh/nodes data"))?;
        let tri: ndarray::Array2<u32> = open(&g, "mesh/surface_triangles")?
            .read_2d()
            .map_err(|_| h5("mesh/surface_triangles"))?;
        let lam: Vec<f64> = open(&g, "modes/eigenvalues")?
            .read_raw()
            .map_err(|_| h5("modes/eigenvalues"))?;
        if lam.len() != r_all || tri.ncols() != 3 {
            return Err(err(format!(
                "space {space:?}: eigenvalues or triangles have the wrong shape"
            )));
        }
        let rows: ndarray::Array2<f64> = basis
            .read_slice(s![0..3 * nv, 0..r])
            .map_err(|_| h5("modes/basis data"))?;
        let mut triangles: Vec<[u32; 3]> = tri.rows().into_iter().map(|t| [t[0], t[1], t[2]]).collect();
        let mut keep: Vec<u32> = (0..nv as u32).collect();
        if opts.surface_only {
            let mut used = vec![false; nv];
            for t in &triangles {
                for &v in t {
                    if let Some(u) = used.get_mut(v as usize) {
                        *u = true;
                    }
                }
            }
            keep = (0..nv as u32).filter(|&v| used[v as usize]).collect();
            let mut new = vec![u32::MAX; nv];
            for (k, &v) in keep.iter().enumerate() {
                new[v as usize] = k as u32;
            }
            for t in &mut triangles {
                *t = t.map(|v| new.get(v as usize).copied().unwrap_or(u32::MAX));
            }
        }
        let rest: Vec<[f64; 3]> = keep
            .iter()
            .map(|&v| [xyz[(v as usize, 0)], xyz[(v as usize, 1)], xyz[(v as usize, 2)]])
            .collect();
        let mut flat = Vec::with_capacity(3 * keep.len() * r);
        for &v in &keep {
            for c in 0..3 {
                flat.extend(rows.row(3 * v as usize + c).iter());
            }
        }
        let mat = file.group("material").map_err(|_| err("no /material group".into()))?;
        let attr = |name: &str| {
            mat.attr(name)
                .and_then(|a| a.read_scalar::<f64>())
                .map_err(|_| err(format!("material attribute {name} missing")))
        };
        let damping = (attr("rayleigh_alpha")?, attr("rayleigh_beta")?);
        let rigid = match g.group("rigid") {
            Ok(rg) => {
                let mass: f64 = rg
                    .attr("mass")
                    .and_then(|a| a.read_scalar())
                    .map_err(|_| h5("rigid/mass"))?;
                let c: Vec<f64> = rg
                    .attr("center_of_mass")
                    .and_then(|a| a.read_raw())
                    .map_err(|_| h5("rigid/center_of_mass"))?;
                let i: Vec<f64> = rg
                    .attr("inertia")
                    .and_then(|a| a.read_raw())
                    .map_err(|_| h5("rigid/inertia"))?;
                if c.len() != 3 || i.len() != 9 || mass.is_nan() || mass <= 0.0 {
                    return Err(h5("rigid properties"));
                }
                Some(RigidProperties {
                    mass,
                    center: [c[0], c[1], c[2]],
                    inertia: [[i[0], i[1], i[2]], [i[3], i[4], i[5]], [i[6], i[7], i[8]]],
                })
            }
            Err(_) => None,
        };
        let voi = match (g.attr("voi_min"), g.attr("voi_max")) {
            (Ok(a), Ok(b)) => {
                let (a, b): (Vec<f64>, Vec<f64>) = (
                    a.read_raw().map_err(|_| h5("voi_min"))?,
                    b.read_raw().map_err(|_| h5("voi_max"))?,
                );
                if a.len() != 3 || b.len() != 3 || a.iter().chain(&b).any(|v| !v.is_finite()) {
                    return Err(h5("voi_min/voi_max"));
                }
                Some([[a[0], a[1], a[2]], [b[0], b[1], b[2]]])
            }
            _ => None,
        };
        let mut basis = Basis::new(
            &p,
            &space,
            rest,
            keep.clone(),
            triangles,
            lam[..r].to_vec(),
            &flat,
            damping,
            rigid,
        )?;
        basis.voi = voi;
        match g.group("compliance") {
            Ok(cg) => {
                let nodes: Vec<u32> = open(&cg, "nodes")?.read_raw().map_err(|_| h5("compliance/nodes"))?;
                let blocks: Vec<f64> = open(&cg, "blocks")?.read_raw().map_err(|_| h5("compliance/blocks"))?;
                if blocks.len() != 9 * nodes.len() {
                    return Err(h5("compliance blocks (shape)"));
                }
                let mut slot = vec![u32::MAX; nv];
                for (k, &v) in keep.iter().enumerate() {
                    slot[v as usize] = k as u32;
                }
                let mut per_vertex = vec![[[f64::NAN; 3]; 3]; keep.len()];
                for (j, &node) in nodes.iter().enumerate() {
                    if let Some(&k) = slot.get(node as usize).filter(|&&k| k != u32::MAX) {
                        per_vertex[k as usize] =
                            std::array::from_fn(|a| std::array::from_fn(|b| blocks[9 * j + 3 * a + b]));
                    }
                }
                basis.with_compliance(per_vertex)
            }
            Err(_) => Ok(basis),
        }
    }
}

#[cfg(feature = "hdf5")]
pub use file::{guarded, load, open_checked};

#[cfg(feature = "hdf5")]
impl Basis {
    /// Names of the spaces in a basis file, the default space first.
    pub fn space_names(path: &std::path::Path) -> Result<Vec<String>, LoadError> {
        let file = file::open_checked(path)?;
        let err = |message: String| LoadError {
            path: path.display().to_string(),
            message,
        };
        let mut names = file
            .group("spaces")
            .and_then(|g| g.member_names())
            .map_err(|_| err("no /spaces group".into()))?;
        let default = crate::h5str::read(&file, "default_space").unwrap_or_else(|| "global".into());
        names.sort_by_key(|n| *n != default);
        Ok(names)
    }

    /// The state-transfer matrix from space `from` (r_from modes loaded) to `to` (r_to), row-major
    /// `r_to × r_from`, when the file holds one (`spaces/<to>/transfer/<from>`).
    pub fn load_transfer(
        path: &std::path::Path,
        to: &str,
        from: &str,
        r_to: usize,
        r_from: usize,
    ) -> Result<Option<Vec<f64>>, LoadError> {
        let file = file::open_checked(path)?;
        let Ok(ds) = file.dataset(&format!("spaces/{to}/transfer/{from}")) else {
            return Ok(None);
        };
        let err = |message: String| LoadError {
            path: path.display().to_string(),
            message,
        };
        let shape = ds.shape();
        if shape.len() != 2 || shape[0] < r_to || shape[1] < r_from {
            return Err(err(format!(
                "transfer {from} → {to} has shape {shape:?}, fewer than the {r_to} × {r_from} modes loaded"
            )));
        }
        let m: ndarray::Array2<f64> = ds
            .read_slice(ndarray::s![0..r_to, 0..r_from])
            .map_err(|_| err(format!("transfer {from} → {to} is damaged")))?;
        let v: Vec<f64> = m.iter().copied().collect();
        if v.iter().any(|x| !x.is_finite()) {
            return Err(err(format!("transfer {from} → {to} holds non-finite values")));
        }
        Ok(Some(v))
    }
}
