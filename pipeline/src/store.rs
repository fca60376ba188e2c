//! Modal basis file, version 1 (HDF5; docs/format.md). Written under a temporary name and renamed
//! when complete, so a killed run never leaves a half-written basis under the final name.

use crate::fem::Dofs;
use crate::fem::MassProperties;
use crate::modes::Modes;
use crate::scene::{Scene, Voi};
use crate::tet_mesh::Mesh;
use anyhow::{Context, Result};
use std::path::Path;

pub use ves_format::{FORMAT, VERSION};

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
    /// The hand's contact patches (`contact/`), if any.
    pub contact: Option<&'a crate::loads::patch::Patches>,
    /// What a hand feels wrong at surface vertices (`felt/`), if estimated.
    pub felt: Option<&'a ves_format::FeltErrors>,
    /// The meshing ladder's rung that made the mesh, if known.
    pub meshing_strategy: Option<&'a str>,
    /// State-transfer matrices from the other spaces (`transfer/<from>`, row-major
    /// `r × r_from`): modal coordinates of `from` → this space's (see `transfer.rs`).
    pub transfers: &'a [(String, Vec<f64>)],
    /// Each mode's estimated discretization error, if estimated.
    pub estimated_relative_error: Option<Vec<f64>>,
    /// Modal stress at the corner vertices, row-major [6·nv, r], if computed.
    pub stress: Option<&'a [f64]>,
    /// The static load cases solved (none: empty).
    pub loads: &'a [crate::loads::LoadResult],
    /// What each support carries per unit modal coordinate, if computed.
    pub reactions: Option<&'a crate::loads::ModalReactions>,
    /// The nonlinear model, if any.
    pub nonlinear: Option<&'a crate::nonlinear::NonlinearModel>,
}

impl Space<'_> {
    /// The file writer's view: plain slices, the basis scattered to all 3n rows.
    fn file_data<'b>(&'b self, basis: &'b [f64], loads: &'b [ves_format::LoadData<'b>]) -> ves_format::SpaceData<'b> {
        ves_format::SpaceData {
            name: self.name,
            kind: self.mesh.kind,
            rigid_modes_dropped: self.modes.rigid_dropped as u32,
            voi: self.voi.map(|v| [v.bbox.min, v.bbox.max]),
            vertex_count: self.mesh.vertex_count,
            meshing_strategy: self.meshing_strategy,
            nodes: &self.mesh.nodes,
            tets: &self.mesh.tets,
            surface_triangles: &self.mesh.surface,
            surface_faces: Some(&self.mesh.surface_faces),
            fixed_dofs: &self.dofs.fixed,
            eigenvalues: &self.modes.eigenvalues,
            relative_residuals: &self.modes.residuals,
            estimated_relative_error: self.estimated_relative_error.as_deref(),
            stress: self.stress,
            basis,
            compliance: self.compliance.map(|c| (c.nodes.as_slice(), c.blocks.as_slice())),
            contact: self.contact,
            felt: self.felt,
            transfers: self.transfers,
            support_reactions: self.reactions.map(|r| (r.centres.as_slice(), r.per_mode.as_slice())),
            support_influence: self
                .reactions
                .and_then(|r| r.influence.as_ref())
                .map(|i| (i.nodes.as_slice(), i.values.as_slice())),
            loads,
            nonlinear: self.nonlinear.map(|n| ves_format::NonlinearData {
                eigenmodes: n.eigenmodes,
                derivatives_of: n.derivatives_of,
                cubic: &n.reduced.t,
                quartic: &n.reduced.h,
            }),
            rigid: self.free_motions().map(|free| ves_format::RigidProperties {
                mass: self.mass.mass,
                center: self.mass.center,
                inertia: self.mass.inertia,
                free,
            }),
        }
    }

    /// The rigid motions left free, when there are any: as many as the eigen-solve dropped (a
    /// file whose `rigid/free_motions` disagreed with `rigid_modes_dropped` would be refused by
    /// every reader, so a mismatch writes no `rigid/`: the part is then simulated held).
    fn free_motions(&self) -> Option<ves_format::FreeMotions> {
        let dropped = self.modes.rigid_dropped;
        match dropped {
            0 => None,
            6 => Some(ves_format::FreeMotions::all()),
            _ if self.mass.free.count() == dropped => Some(self.mass.free),
            _ => {
                tracing::warn!(
                    "space {}: {dropped} rigid motions dropped but {} found free by the supports: its rigid motions \
                     are not stored, and a session holds the part in place",
                    self.name,
                    self.mass.free.count()
                );
                None
            }
        }
    }

    /// The load cases as the file writer takes them.
    fn load_data(&self) -> Vec<ves_format::LoadData<'_>> {
        self.loads
            .iter()
            .map(|l| ves_format::LoadData {
                name: &l.name,
                kind: l.kind,
                total_force: l.total_force,
                reaction: l.reaction,
                balance_residual: l.balance_residual,
                max_displacement: l.max_displacement,
                max_von_mises: l.max_von_mises,
                displacement: &l.displacement,
                von_mises: &l.von_mises,
                stress: &l.stress,
                peak: l.peaks.first().map(crate::loads::peak::PeakStress::record),
                regular_peak: crate::loads::peak::regular(&l.peaks).map(crate::loads::peak::PeakStress::record),
            })
            .collect()
    }

    /// Mode shapes over all 3n DOFs, row-major [3n, r] (zero at supported DOFs).
    fn full_basis(&self) -> Vec<f64> {
        let (n, r, nf) = (
            self.mesh.nodes.len(),
            self.modes.eigenvalues.len(),
            self.dofs.free_count(),
        );
        let mut basis = vec![0.0; 3 * n * r];
        for j in 0..r {
            let col = &self.modes.vectors[j * nf..(j + 1) * nf];
            for (v, &d) in col.iter().zip(&self.dofs.free) {
                basis[d as usize * r + j] = *v;
            }
        }
        basis
    }
}

/// Writes all spaces of a scene to `out` and its XDMF sidecar beside it, together: both are
/// written in full under temporary names, flushed and checked before either is renamed, so a
/// failure (a full disk, a kill) leaves the old pair as it was. The caller checked both paths
/// first ([`crate::output::check`]).
pub fn write(out: &Path, scene: &Scene, spaces: &[Space<'_>]) -> Result<()> {
    let bases: Vec<Vec<f64>> = spaces.iter().map(Space::full_basis).collect();
    let loads: Vec<Vec<ves_format::LoadData<'_>>> = spaces.iter().map(Space::load_data).collect();
    let generator = format!("ves {}", env!("CARGO_PKG_VERSION"));
    // What this file was made from (`ves batch` skips scenes whose output is up to date).
    let hash = source_hash(scene)?;
    let data = ves_format::FileData {
        generator: &generator,
        scene_toml: &scene.toml,
        source_hash: Some(&hash),
        material: ves_format::Material {
            young: scene.material.young,
            poisson: scene.material.poisson,
            density: scene.material.density,
            alpha: scene.damping.alpha,
            beta: scene.damping.beta,
            yield_strength: scene.material.yield_strength,
        },
        spaces: spaces
            .iter()
            .zip(&bases)
            .zip(&loads)
            .map(|((s, b), l)| s.file_data(b, l))
            .collect(),
    };
    let mut staging = crate::output::Staging::default();
    let mut sidecar_text = String::new();
    staging
        .stage(out, |tmp| {
            ves_format::write_file(tmp, &data)?;
            // What was written is read back through the guarded reader: a write the disk
            // could not hold, whatever layer swallowed its error, is found before the rename.
            let reader = ves_format::BasisReader::open(tmp)?;
            reader.validate()?;
            sidecar_text = sidecar_of(&reader, out)?;
            Ok(())
        })
        .context("writing the basis failed")?;
    let sidecar = sidecar_path(out);
    staging
        .stage(&sidecar, |tmp| Ok(std::fs::write(tmp, sidecar_text.as_bytes())?))
        .with_context(|| format!("{}: writing the XDMF sidecar failed", sidecar.display()))?;
    // The last moment a stop asked for while the file was written can still leave nothing:
    // the staged files are removed when `staging` drops.
    if crate::progress::cancelled() {
        anyhow::bail!("cancelled while writing: nothing was written");
    }
    Ok(staging.commit()?)
}

/// The XDMF file ParaView opens beside a basis `B.h5`: `B.xdmf`.
pub fn sidecar_path(out: &Path) -> std::path::PathBuf {
    out.with_extension("xdmf")
}

/// Rewrites the XDMF sidecar of the basis at `out` when it is missing or does not describe the
/// file (a run stopped between the two renames leaves the new basis beside the old sidecar).
/// Returns whether it was rewritten.
pub fn repair_sidecar(out: &Path) -> Result<bool> {
    let text = sidecar_of(&ves_format::BasisReader::open(out)?, out)?;
    let path = sidecar_path(out);
    if std::fs::read(&path).is_ok_and(|b| b == text.as_bytes()) {
        return Ok(false);
    }
    crate::output::check(&path, &[out], crate::output::Overwrite::default())?;
    crate::output::write_atomically(&path, |tmp| Ok(std::fs::write(tmp, text.as_bytes())?))?;
    Ok(true)
}

/// The XDMF sidecar's text for the basis `reader` reads, which will be found at `out` (the
/// sidecar points into it by file name).
fn sidecar_of(reader: &ves_format::BasisReader, out: &Path) -> Result<String> {
    /// What the sidecar shows of one space, read from the file.
    struct Grid {
        name: String,
        nodes: usize,
        vertices: usize,
        tets: usize,
        kind: ves_format::ElementKind,
        frequencies: Vec<f64>,
        stress: bool,
        fixed: bool,
        loads: Vec<String>,
    }
    let mut spaces = Vec::new();
    for name in reader.space_names()? {
        let s = reader.space(&name)?;
        spaces.push(Grid {
            frequencies: s.frequencies_hz()?,
            stress: s.stress_rows(0..0, 0)?.is_some(),
            fixed: s.fixed_mask()?.is_some(),
            loads: s.load_names()?,
            nodes: s.node_count,
            vertices: s.vertex_count,
            tets: s.tet_count,
            kind: s.kind,
            name,
        });
    }
    let views: Vec<ves_format::xdmf::XdmfSpace<'_>> = spaces
        .iter()
        .map(|g| ves_format::xdmf::XdmfSpace {
            name: &g.name,
            nodes: g.nodes,
            vertices: g.vertices,
            tets: g.tets,
            kind: g.kind,
            frequencies_hz: &g.frequencies,
            stress: g.stress,
            fixed: g.fixed,
            loads: &g.loads,
        })
        .collect();
    Ok(ves_format::xdmf::sidecar(&file_name(out), &views))
}

fn file_name(out: &Path) -> String {
    out.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// A content hash of what a basis depends on: the tool version, the scene text, the effective
/// mode count and the geometry file's bytes (FNV-1a, 64 bits: change detection, not security).
pub fn source_hash(scene: &Scene) -> Result<String> {
    let geometry = crate::input::read(&scene.geometry)?;
    let h = crate::fingerprint::Fingerprint::default()
        .field(concat!("ves ", env!("CARGO_PKG_VERSION")).as_bytes())
        .field(scene.toml.as_bytes())
        .field(&(scene.modes.count as u64).to_le_bytes())
        .field(&geometry)
        .value();
    Ok(format!("fnv1a64:{h:016x}"))
}

/// The `source_hash` stored in an existing basis file, if it is one.
pub fn stored_source_hash(path: &Path) -> Option<String> {
    ves_format::BasisReader::open(path)
        .ok()?
        .string(ves_format::names::root::SOURCE_HASH)
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
    /// Largest stored relative residual (of the eigenmodes, in a nonlinear model's basis).
    pub max_relative_residual: f64,
    /// The nonlinear model, when the file has one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub nonlinear: Option<crate::nonlinear::Summary>,
    /// Rigid modes dropped.
    pub rigid_modes_dropped: u32,
    /// The rigid motions the supports leave free (`rigid/free_motions`, or all six of a free
    /// body), as slides along directions and turns (or screws) about axes; empty for a held part.
    pub free_motions: Vec<crate::rigid_motions::FreeMotion>,
    /// Vertices with a static-correction block (0: none stored).
    pub static_correction_vertices: usize,
    /// The hand's contact patch radius, m (0: a point contact; files without `contact/`).
    pub contact_radius_m: f64,
    /// What a hand feels wrong where the file states it (`felt/`), when it does.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub felt_error: Option<FeltInfo>,
    /// What the supports carry during a session, when the file stores their reactions (held
    /// parts): how many, and at how many surface vertices their influence coefficients are
    /// stated (0: none stored).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub supports: Option<SupportsInfo>,
    /// How the mesh was made (the meshing ladder's rung), when the file says.
    pub meshing_strategy: Option<String>,
    /// Each mode's estimated relative discretization error, when the file has it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub estimated_relative_error: Option<Vec<f64>>,
    /// The static load cases stored (empty: none).
    pub loads: Vec<LoadInfo>,
}

/// What `ves info` shows of a space's supports (`modes/support_reactions`,
/// `modes/support_influence`).
#[derive(Clone, Debug, serde::Serialize)]
pub struct SupportsInfo {
    /// `[[fixed]]` supports whose reactions are stored.
    pub count: usize,
    /// Surface vertices with influence coefficients (0: none stored).
    pub influence_vertices: usize,
    /// A hand's load held steady is carried whole by the supports in a session: one support
    /// holding every rigid motion, or influence coefficients for several.
    pub carried_whole: bool,
}

impl SupportsInfo {
    /// Its words in `ves info`'s line.
    pub fn text(&self) -> String {
        let how = match (self.carried_whole, self.influence_vertices) {
            (false, _) => "a session's reactions are the modes' share of a hand's load".to_string(),
            (true, 0) => "a hand's load carried whole (equilibrium)".to_string(),
            (true, v) => format!("a hand's load carried whole (influence coefficients at {v} vertices)"),
        };
        format!(
            ", {} support{}: {how}",
            self.count,
            if self.count == 1 { "" } else { "s" }
        )
    }
}

/// What `ves info` shows of a space's felt errors (`felt/`): the modes' share and the mesh's
/// error together at each vertex stated.
#[derive(Debug, serde::Serialize)]
pub struct FeltInfo {
    /// The modes the truncation was measured with.
    pub modes: u32,
    /// Their spread over the vertices stated.
    #[serde(flatten)]
    pub spread: crate::accuracy::felt::Spread,
}

impl FeltInfo {
    fn of(f: &ves_format::FeltErrors) -> Option<FeltInfo> {
        let spread = crate::accuracy::felt::Spread::of((0..f.nodes.len()).map(|k| f.total(k)).collect())?;
        Some(FeltInfo { modes: f.modes, spread })
    }
}

/// What `ves info` shows of one load case.
#[derive(Debug, serde::Serialize)]
pub struct LoadInfo {
    /// Its name.
    pub name: String,
    /// `force`, `pressure` or `gravity`.
    pub kind: String,
    /// Sum of the applied nodal loads, N.
    pub total_force_n: [f64; 3],
    /// Largest nodal displacement magnitude, m.
    pub max_displacement_m: f64,
    /// Largest corner-vertex von Mises stress, Pa.
    pub max_von_mises_pa: f64,
    /// Total support reaction, N.
    pub reaction_n: [f64; 3],
    /// |reaction + applied| over the sum of the nodal loads' magnitudes.
    pub balance_residual: f64,
    /// The largest von Mises peak's value and error, or that it is singular and the largest
    /// that is not, when the file has the study.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub peak_stress: Option<String>,
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

/// Reads the summary of a basis file after checking everything in it (the reader the runtime
/// uses, plus the rows and arrays the runtime does not load).
pub fn info(path: &Path) -> Result<BasisInfo> {
    let file = ves_format::BasisReader::open(path)?;
    file.validate()?;
    let mut spaces = Vec::new();
    for name in file.space_names()? {
        let s = file.space(&name)?;
        let res = s.relative_residuals()?;
        let nonlinear = s.nonlinear()?.map(|n| crate::nonlinear::Summary {
            eigenmodes: n.eigenmodes,
            derivatives_of: n.derivatives_of,
            derivatives: s.mode_count - n.eigenmodes,
            coupling: None,
        });
        spaces.push(SpaceInfo {
            name: name.clone(),
            nodes: s.node_count,
            vertices: s.vertex_count,
            tets: s.tet_count,
            element_order: u32::from(s.kind.order()),
            modes: s.mode_count,
            frequencies_hz: s.frequencies_hz()?,
            max_relative_residual: crate::nonlinear::max_residual(&res, nonlinear.as_ref().map(|n| n.eigenmodes)),
            nonlinear,
            rigid_modes_dropped: s.rigid_modes_dropped,
            free_motions: s.rigid()?.map_or_else(Vec::new, |r| {
                // The part's size from its radius of gyration: ω is weighed against v at it.
                let length = ((r.inertia[0][0] + r.inertia[1][1] + r.inertia[2][2]) / r.mass).sqrt();
                crate::rigid_motions::describe(r.free.twists(), r.center, length)
            }),
            static_correction_vertices: s.compliance()?.map_or(0, |(n, _)| n.len()),
            contact_radius_m: s.contact()?.map_or(0.0, |c| c.radius),
            felt_error: s.felt()?.as_ref().and_then(FeltInfo::of),
            supports: match s.support_reactions()? {
                None => None,
                Some((centres, _)) => {
                    let influence = s.support_influence()?;
                    let carried_whole = ves_format::read::ReactionStatics::of(
                        centres.len(),
                        s.rigid_modes_dropped,
                        influence.is_some(),
                    ) != ves_format::read::ReactionStatics::Unknown;
                    let influence_vertices = influence.map_or(0, |(nodes, _)| nodes.len());
                    Some(SupportsInfo {
                        count: centres.len(),
                        influence_vertices,
                        carried_whole,
                    })
                }
            },
            meshing_strategy: s.meshing_strategy.clone(),
            estimated_relative_error: s.estimated_relative_error()?,
            loads: s
                .loads()?
                .into_iter()
                .map(|l| LoadInfo {
                    name: l.name,
                    kind: l.kind,
                    total_force_n: l.total_force,
                    max_displacement_m: l.max_displacement,
                    max_von_mises_pa: l.max_von_mises,
                    reaction_n: l.reaction,
                    balance_residual: l.balance_residual,
                    peak_stress: crate::loads::peak::case_text(l.peak.as_ref(), l.regular_peak.as_ref()),
                })
                .collect(),
        });
    }
    Ok(BasisInfo {
        path: path.display().to_string(),
        bytes: file.file_bytes(),
        generator: file.string(ves_format::names::root::GENERATOR).unwrap_or_default(),
        default_space: file.default_space()?,
        spaces,
    })
}

/// A basis file's global space as stored ([`read_global`]).
pub struct StoredSpace {
    /// Its mesh.
    pub mesh: crate::tet_mesh::Mesh,
    /// Its material.
    pub material: crate::material::Material,
    /// The supported DOFs, ascending.
    pub fixed: Vec<u32>,
    /// The eigenvalues of the modes read.
    pub eigenvalues: Vec<f64>,
    /// The modes read at every DOF, row-major `3·nodes × r`.
    pub rows: Vec<f64>,
    /// Modes read.
    pub r: usize,
    /// The scene it was computed from.
    pub scene_toml: Option<String>,
}

/// Reads a basis file's global space (its first `modes` modes, all without), the whole file
/// checked first by the one reader: a damaged or crafted basis ends in its one-line message
/// naming the file.
pub fn read_global(path: &Path, modes: Option<usize>) -> Result<StoredSpace> {
    let file = ves_format::BasisReader::open(path)?;
    file.validate()?;
    let material = crate::material::Material::from(&file.material()?);
    let g = file.space(ves_format::names::GLOBAL_SPACE)?;
    let n = g.node_count;
    let lam = g.eigenvalues()?;
    let r = modes.unwrap_or(lam.len()).min(lam.len());
    let rows = g.basis_rows(0..3 * n, r)?;
    let surface = g.surface_triangles()?;
    let surface_faces = g.surface_faces()?.unwrap_or_else(|| vec![0; surface.len()]);
    let mesh = crate::tet_mesh::Mesh {
        nodes: g.nodes(n)?,
        vertex_count: g.vertex_count,
        kind: g.kind,
        tets: g.tets()?,
        surface,
        surface_faces,
    };
    Ok(StoredSpace {
        mesh,
        material,
        fixed: g.fixed_dofs()?,
        eigenvalues: lam[..r].to_vec(),
        rows,
        r,
        scene_toml: file.string(ves_format::names::root::SCENE_TOML),
    })
}
