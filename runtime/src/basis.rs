//! A modal basis as the runtime holds it: corner vertices (optionally only the surface ones), the
//! first r modes in f32, mode-major so the full-field update is a sequence of axpys.

/// Small vectors for the reactions' arms.
type V3 = nalgebra::Vector3<f64>;

/// Loading failed; the message names the file and what is wrong.
pub type LoadError = ves_format::InputError;

/// Mass properties of a free body (defined with the file format).
pub use ves_format::{FreeMotions, RigidProperties};

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

/// The hand's contact patches as a basis holds them.
#[derive(Clone, Debug)]
pub enum Contact {
    /// Each kept vertex's patch rows Σ wₐ φₐ, vertex-major f32 (`rows[3r·i + c·r + j]`): for
    /// patches that reach beyond a vertex's surface neighbours (10-node tets, or a radius wider
    /// than the elements), whose rows would need nodes the basis does not keep.
    Rows(Vec<f32>),
    /// The weight of each surface neighbour in the vertex's patch, aligned with
    /// [`Basis::neighbours`], in units of 1/[`WEIGHT_UNIT`]; the vertex's own weight is the rest
    /// to 1. The rows are summed from `phi` when a hand touches the vertex: kept for all, the
    /// rows took as much memory as `phi` itself.
    Weights(Vec<u16>),
}

/// The unit of [`Contact::Weights`]: a weight is held to ±0.5/65535 (its error moves a contact
/// row by at most that times the difference between a neighbour's rows and the vertex's own).
pub const WEIGHT_UNIT: f64 = 65535.0;

/// What each `[[fixed]]` support exerts on the part per unit modal coordinate (held parts'
/// global space, files written since the support reactions were added).
#[derive(Clone, Debug)]
pub struct SupportReactions {
    /// Per support, the point its moment is about, m.
    pub centres: Vec<[f64; 3]>,
    /// Row-major [6·s, r]: row 6k+c is component c (force x y z, N; moment x y z, N·m) of
    /// support k per unit of each mode's coordinate.
    pub per_mode: Vec<f64>,
    /// What the supports carry of a static load at a vertex, exactly: the share the
    /// truncated modes leave out is added back from it ([`Basis::support_reactions_loaded`]).
    pub statics: StaticReactions,
}

/// How the exact static reactions of a load at a vertex are known.
#[derive(Clone, Debug, PartialEq)]
pub enum StaticReactions {
    /// Not known: the supports leave a rigid motion free (a load along it has no static
    /// answer), or the file does not say. The reactions are the modes' share only.
    Unknown,
    /// One support holds every rigid motion: by equilibrium it carries the whole load, force
    /// −f and moment −(x − c) × f about its centre c.
    Equilibrium,
    /// Several supports holding every rigid motion: each one's reaction per newton at the kept
    /// vertices the file states (the file's `modes/support_influence`), the last support's by
    /// equilibrium.
    Influence {
        /// Per kept vertex, its row in `values` (`u32::MAX`: not stated).
        row: Vec<u32>,
        /// Row-major [rows, 18·(s − 1)]: column (6k + c)·3 + d is component c of support k per
        /// newton along axis d, for every support but the last.
        values: Vec<f32>,
    },
}

/// Scratch for [`Basis::support_reactions_loaded`]: a vertex's contact rows and a modal state.
pub struct ReactionWork {
    rows: Vec<f64>,
    q: Vec<f64>,
    /// Per support, the static reactions of the loads.
    statics: Vec<[f64; 6]>,
}

impl ReactionWork {
    /// Room for `basis`'s modes.
    pub fn for_basis(basis: &Basis) -> ReactionWork {
        let r = basis.mode_count();
        ReactionWork {
            rows: vec![0.0; 3 * r],
            q: vec![0.0; r],
            statics: vec![[0.0; 6]; basis.support_reactions.as_ref().map_or(0, |s| s.count())],
        }
    }
}

impl SupportReactions {
    /// Supports.
    pub fn count(&self) -> usize {
        self.centres.len()
    }

    /// The reactions of modal state `q` (its first `r` entries, r the basis's modes) into
    /// `out`, one `[force x y z, moment x y z]` per support; allocation-free.
    pub fn of(&self, q: &[f64], out: &mut [[f64; 6]]) {
        let r = self.per_mode.len() / (6 * self.count()).max(1);
        let q = &q[..r.min(q.len())];
        for (k, o) in out.iter_mut().enumerate().take(self.count()) {
            for (c, v) in o.iter_mut().enumerate() {
                let row = &self.per_mode[(6 * k + c) * r..(6 * k + c + 1) * r];
                *v = row.iter().zip(q).map(|(a, b)| a * b).sum();
            }
        }
    }
}

/// What a hand feels wrong at the kept vertices, along each one's outward normal (the file's
/// `felt/`, docs/accuracy.md): NaN where not stated.
#[derive(Clone, Debug, Default)]
pub struct FeltAt {
    /// The modes the truncation was measured with.
    pub modes: usize,
    /// The share of the exact compliance those modes miss, per kept vertex.
    pub truncation: Vec<f32>,
    /// The mesh's relative error of the exact compliance, per kept vertex.
    pub mesh_error: Vec<f32>,
}

impl FeltAt {
    /// The file's table on `kept` vertices, `slot[node]` the kept vertex of a file node
    /// (`u32::MAX`: not kept).
    fn of_file(f: &ves_format::FeltErrors, slot: &[u32], kept: usize) -> FeltAt {
        let mut at = FeltAt {
            modes: f.modes as usize,
            truncation: vec![f32::NAN; kept],
            mesh_error: vec![f32::NAN; kept],
        };
        for (k, &node) in f.nodes.iter().enumerate() {
            if let Some(&i) = slot.get(node as usize).filter(|&&i| (i as usize) < kept) {
                at.truncation[i as usize] = f.truncation[k] as f32;
                at.mesh_error[i as usize] = f.mesh_error[k] as f32;
            }
        }
        at
    }

    /// What a hand at kept vertex `i` feels wrong: the modes' share (none when `corrected`, the
    /// static correction stored there) and the mesh's error, a + e − a·e; `None` where not
    /// stated, or when `modes` (those simulated) are fewer than measured with, uncorrected.
    pub fn error(&self, i: usize, corrected: bool, modes: usize) -> Option<f64> {
        let e = f64::from(*self.mesh_error.get(i)?);
        let a = if corrected {
            0.0
        } else if self.modes == modes {
            f64::from(self.truncation[i])
        } else {
            return None;
        };
        let total = a + e - a * e;
        total.is_finite().then_some(total)
    }
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
    /// The CAD face (gmsh's surface tag, what a scene's `[[fixed]] faces` names) of each of
    /// `triangles`, 0 where unknown; when the file has them (older files do not).
    pub surface_faces: Option<Vec<u32>>,
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
    /// What a hand feels wrong at each kept vertex where the file states it (`felt/`).
    pub felt: Option<FeltAt>,
    /// The hand's contact patch radius, m (0: a point contact at the vertex).
    pub contact_radius: f64,
    /// Per kept vertex, what gives the modal rows the hand's force acts through and its
    /// displacement is read with: the patch average Σ wₐ φₐ (`contact/` of the file); `None`:
    /// each vertex's own rows (a point contact). See [`Basis::gather_contact_rows`].
    pub contact: Option<Contact>,
    /// Bytes of basis data held in memory.
    pub bytes_loaded: usize,
    /// The volume of interest this space refines (min, max corners, m); `None` for "global".
    pub voi: Option<[[f64; 3]; 2]>,
    /// Modal stress, mode-major f32: mode j is `stress[j·6n .. (j+1)·6n]`, entry 6i+k = Voigt
    /// component k (xx yy zz yz xz xy) at kept vertex i, Pa per unit modal coordinate; when the
    /// file has it.
    pub stress: Option<Vec<f32>>,
    /// Yield strength, Pa, when the file gives it (safety factors).
    pub yield_strength: Option<f64>,
    /// Young's modulus (Pa) and Poisson's ratio, when loaded from a file (strains from stress).
    pub elastic: Option<(f64, f64)>,
    /// Supported components per kept vertex: bit c set when component c (x, y, z) is fixed
    /// (drawn as supports by the viewer).
    pub fixed: Vec<u8>,
    /// The file this basis was loaded from (`None`: built in memory). The viewer reads the
    /// space's static load cases from it when a page asks for one.
    pub source: Option<std::path::PathBuf>,
    /// What the supports carry per unit modal coordinate, when the file has it.
    pub support_reactions: Option<SupportReactions>,
    /// The reduced nonlinear model (`[model] kind = "nonlinear"`), on the modes kept; its
    /// linear part is diag(eigenvalues).
    pub nonlinear: Option<std::sync::Arc<crate::nonlinear::Polynomial>>,
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
        ves_format::checks::eigenvalues(&eigenvalues).map_err(|m| err(format!("space {space:?}: {m}")))?;
        ves_format::checks::damping(alpha, beta, &eigenvalues).map_err(|m| err(format!("space {space:?}: {m}")))?;
        ves_format::checks::triangles(triangles.as_flattened())
            .map_err(|m| err(format!("space {space:?}: surface {m}")))?;
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
            surface_faces: None,
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
            felt: None,
            contact_radius: 0.0,
            contact: None,
            bytes_loaded,
            voi: None,
            stress: None,
            yield_strength: None,
            elastic: None,
            fixed: vec![0; n],
            source: None,
            support_reactions: None,
            nonlinear: None,
        })
    }

    /// Attaches modal stress from vertex-major rows (`rows[(6i+k)·r + j]`, one block of six per
    /// kept vertex), checking shape, finiteness and single-precision range.
    pub fn with_stress(mut self, rows: &[f64]) -> Result<Basis, LoadError> {
        let (n, r) = (self.rest.len(), self.mode_count());
        let err = |message: String| LoadError {
            path: self.space.clone(),
            message,
        };
        if rows.len() != 6 * n * r {
            return Err(err(format!(
                "modal stress has {} values, expected 6 × {n} × {r}",
                rows.len()
            )));
        }
        if rows.iter().any(|v| !v.is_finite() || v.abs() > f64::from(f32::MAX)) {
            return Err(err(
                "modal stress not finite or beyond single precision: the file is damaged".into(),
            ));
        }
        let mut s = vec![0.0f32; 6 * n * r];
        for (k, row) in rows.chunks_exact(r).enumerate() {
            for (j, v) in row.iter().enumerate() {
                s[j * 6 * n + k] = *v as f32;
            }
        }
        self.bytes_loaded += s.len() * 4;
        self.stress = Some(s);
        Ok(self)
    }

    /// Mode j's stress over all kept vertices (6 values per vertex), when stored.
    pub fn stress_mode(&self, j: usize) -> Option<&[f32]> {
        let m = 6 * self.rest.len();
        self.stress.as_ref().map(|s| &s[j * m..(j + 1) * m])
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

    /// The largest static compliance over the surface vertices, m/N: the largest eigenvalue of
    /// each vertex's 3×3 block (stored, else the modal Σ φφᵀ/λ), and that vertex. The
    /// displacement a force F can give anywhere on the surface is at most F times this.
    pub fn largest_compliance(&self) -> (f64, u32) {
        let r = self.eigenvalues.len();
        let mut rows = vec![0.0; 3 * r];
        let mut best = (0.0, 0);
        for &v in &self.surface_vertices {
            let i = v as usize;
            let g = match self.compliance_of(i) {
                Some(g) => nalgebra::Matrix3::from_fn(|a, b| g[a][b]),
                None => {
                    self.gather_contact_rows(i, &mut rows);
                    nalgebra::Matrix3::from_fn(|a, b| {
                        (0..r)
                            .map(|j| rows[a * r + j] * rows[b * r + j] / self.eigenvalues[j])
                            .sum()
                    })
                }
            };
            let top = g.symmetric_eigenvalues().max();
            if top > best.0 {
                best = (top, v);
            }
        }
        best
    }

    /// Attaches the contact patches' modal rows (see [`Contact::Rows`]), checked finite.
    pub fn with_contact(mut self, radius: f64, rows: Vec<f32>) -> Result<Basis, LoadError> {
        let want = 3 * self.rest.len() * self.eigenvalues.len();
        if rows.len() != want || rows.iter().any(|v| !v.is_finite()) || !(radius.is_finite() && radius >= 0.0) {
            return Err(LoadError {
                path: self.space.clone(),
                message: format!(
                    "contact patches: {} rows for {want}, radius {radius}, or a non-finite value; the file is damaged",
                    rows.len()
                ),
            });
        }
        self.bytes_loaded += rows.len() * 4;
        self.contact_radius = radius;
        self.contact = Some(Contact::Rows(rows));
        Ok(self)
    }

    /// Attaches the contact patches as neighbour weights (see [`Contact::Weights`]), one per
    /// entry of [`Basis::neighbours`], each vertex's summing to 1 at most.
    pub fn with_contact_weights(mut self, radius: f64, weights: Vec<u16>) -> Result<Basis, LoadError> {
        let over = (0..self.rest.len()).any(|i| {
            let (lo, hi) = (self.neighbour_ptr[i] as usize, self.neighbour_ptr[i + 1] as usize);
            weights
                .get(lo..hi)
                .is_some_and(|w| w.iter().map(|&q| f64::from(q)).sum::<f64>() > WEIGHT_UNIT + 0.5 * w.len() as f64)
        });
        if weights.len() != self.neighbours.len() || over || !(radius.is_finite() && radius >= 0.0) {
            return Err(LoadError {
                path: self.space.clone(),
                message: format!(
                    "contact patches: {} weights for {} neighbours, radius {radius}, or a patch over 1; the file is damaged",
                    weights.len(),
                    self.neighbours.len()
                ),
            });
        }
        self.bytes_loaded += weights.len() * 2;
        self.contact_radius = radius;
        self.contact = Some(Contact::Weights(weights));
        Ok(self)
    }

    /// The modal rows the hand acts through at kept vertex `i` (`out[c·r + j]`, r = the mode
    /// count): its contact patch's average, or the vertex's own rows for a point contact. With
    /// [`Contact::Weights`] the rows are summed here, from the vertex's and its neighbours' rows
    /// (3r values each): no allocation, bounded by the vertex's neighbour count.
    pub fn gather_contact_rows(&self, i: usize, out: &mut [f64]) {
        match &self.contact {
            Some(Contact::Rows(rows)) => {
                let n = out.len();
                for (o, v) in out.iter_mut().zip(&rows[n * i..n * (i + 1)]) {
                    *o = f64::from(*v);
                }
            }
            Some(Contact::Weights(weights)) => {
                let (lo, hi) = (self.neighbour_ptr[i] as usize, self.neighbour_ptr[i + 1] as usize);
                let (neighbours, weights) = (&self.neighbours[lo..hi], &weights[lo..hi]);
                let own = 1.0 - weights.iter().map(|&q| f64::from(q)).sum::<f64>() / WEIGHT_UNIT;
                self.gather_rows(i, out);
                out.iter_mut().for_each(|o| *o *= own);
                let (m, r) = (3 * self.rest.len(), self.eigenvalues.len());
                for (&k, &q) in neighbours.iter().zip(weights).filter(|(_, q)| **q != 0) {
                    let w = f64::from(q) / WEIGHT_UNIT;
                    for c in 0..3 {
                        for j in 0..r {
                            out[c * r + j] += w * f64::from(self.phi[j * m + 3 * k as usize + c]);
                        }
                    }
                }
            }
            None => self.gather_rows(i, out),
        }
    }

    /// The compliance block of kept vertex `i`, if stored.
    pub fn compliance_of(&self, i: usize) -> Option<[[f64; 3]; 3]> {
        self.compliance
            .as_ref()
            .and_then(|c| c.get(i).copied())
            .filter(|b| b[0][0].is_finite())
    }

    /// What a hand at kept vertex `i` feels wrong, relative, along the vertex's normal: the
    /// modes' share (none with the static correction, which makes the felt compliance exact
    /// on the mesh at any mode count) and the mesh's own error together, a + e − a·e. `None`
    /// where the file does not state it, or with fewer modes than it was measured with and no
    /// static correction (fewer modes miss more).
    pub fn felt_error(&self, i: usize) -> Option<f64> {
        self.felt
            .as_ref()?
            .error(i, self.compliance_of(i).is_some(), self.eigenvalues.len())
    }

    /// The file's `felt/` for these kept vertices, read again: a compute's checks write it
    /// after the basis was first loaded (`ves view`). `None` without a source file or the group.
    pub fn read_felt(&self) -> Result<Option<FeltAt>, LoadError> {
        let Some(path) = &self.source else { return Ok(None) };
        let file = ves_format::BasisReader::open(path)?;
        let s = file.space(&self.space)?;
        let Some(f) = s.felt()? else { return Ok(None) };
        let mut slot = vec![u32::MAX; s.node_count];
        for (k, &v) in self.node_index.iter().enumerate() {
            if let Some(x) = slot.get_mut(v as usize) {
                *x = k as u32;
            }
        }
        Ok(Some(FeltAt::of_file(&f, &slot, self.rest.len())))
    }

    /// What each `[[fixed]]` support exerts on the part in modal state `q` with the hands'
    /// `loads` (kept vertex, force on the part, N) into `out` (one `[force x y z, moment x y z]`
    /// per support); allocation-free. Where the exact static reactions are known
    /// ([`StaticReactions`]) the truncated modes' share is added back (the mode-acceleration
    /// method): R = R_modal(q − Λ⁻¹Φᵥᵀf) + R_static(f), so a load held steady is carried
    /// whole, and while the part moves its inertia shows as the modes' own. Otherwise the modes'
    /// share, R_modal(q). Returns whether the share was added back; nothing is written when the
    /// basis stores no reactions.
    pub fn support_reactions_loaded(
        &self,
        q: &[f64],
        loads: impl Iterator<Item = (u32, [f64; 3])>,
        work: &mut ReactionWork,
        out: &mut [[f64; 6]],
    ) -> bool {
        let Some(sr) = &self.support_reactions else {
            return false;
        };
        let r = self.mode_count().min(q.len()).min(work.q.len());
        if sr.statics == StaticReactions::Unknown || sr.count() == 0 || work.statics.len() < sr.count() {
            sr.of(q, out);
            return false;
        }
        work.q[..r].copy_from_slice(&q[..r]);
        work.statics.iter_mut().for_each(|p| *p = [0.0; 6]);
        let mut loaded = false;
        for (v, f) in loads.filter(|(v, _)| (*v as usize) < self.rest.len()) {
            // Several supports: the vertex's coefficients (of all but the last); none stated
            // there leaves its load to the modes' share.
            let last = sr.count() - 1;
            let coefficients = match &sr.statics {
                StaticReactions::Influence { row, values } => {
                    let width = 18 * last;
                    let Some(&i) = row.get(v as usize).filter(|&&i| i != u32::MAX) else {
                        continue;
                    };
                    &values[i as usize * width..(i as usize + 1) * width]
                }
                _ => &[][..],
            };
            loaded = true;
            self.gather_contact_rows(v as usize, &mut work.rows);
            for j in 0..r {
                let rows = [work.rows[j], work.rows[r + j], work.rows[2 * r + j]];
                work.q[j] -= (rows[0] * f[0] + rows[1] * f[1] + rows[2] * f[2]) / self.eigenvalues[j];
            }
            // The last support carries what the others leave: the part is in equilibrium, so
            // its force is −(f + Σ F_k) and its moment about its centre c is
            // −((x − c) × f + Σ (M_k + (c_k − c) × F_k)).
            let c = V3::from(sr.centres[last]);
            let (mut force, mut moment) = (V3::from(f), (V3::from(self.rest[v as usize]) - c).cross(&V3::from(f)));
            for (k, part) in work.statics.iter_mut().enumerate().take(last) {
                let mut here = [0.0; 6];
                for (cpt, h) in here.iter_mut().enumerate() {
                    let g = &coefficients[(6 * k + cpt) * 3..(6 * k + cpt) * 3 + 3];
                    *h = (0..3).map(|d| f64::from(g[d]) * f[d]).sum::<f64>();
                }
                let (fk, mk) = (V3::new(here[0], here[1], here[2]), V3::new(here[3], here[4], here[5]));
                force += fk;
                moment += mk + (V3::from(sr.centres[k]) - c).cross(&fk);
                for (p, h) in part.iter_mut().zip(here) {
                    *p += h;
                }
            }
            for a in 0..3 {
                work.statics[last][a] -= force[a];
                work.statics[last][3 + a] -= moment[a];
            }
        }
        sr.of(&work.q[..r], out);
        for (o, p) in out.iter_mut().zip(&work.statics) {
            for (a, b) in o.iter_mut().zip(p) {
                *a += b;
            }
        }
        loaded
    }

    /// The same basis with only its first `r` modes (all of them when `r` is larger).
    pub fn first_modes(&self, r: usize) -> Basis {
        let (n, all) = (self.rest.len(), self.eigenvalues.len());
        let r = r.min(all);
        let mut t = self.clone();
        t.eigenvalues.truncate(r);
        t.phi.truncate(r * 3 * n);
        if let Some(s) = &mut t.stress {
            s.truncate(r * 6 * n);
        }
        if let Some(sr) = &mut t.support_reactions {
            sr.per_mode = sr.per_mode.chunks_exact(all).flat_map(|c| &c[..r]).copied().collect();
        }
        if let Some(p) = &mut t.nonlinear {
            *p = std::sync::Arc::new(p.first(r));
        }
        // Vertex-major: keep the first r of each (vertex, component)'s `all` values (weights
        // do not depend on the modes).
        if let Some(Contact::Rows(rows)) = &mut t.contact {
            *rows = rows.chunks_exact(all).flat_map(|c| &c[..r]).copied().collect();
        }
        t
    }

    /// The contact patches as neighbour weights ([`Contact::Weights`]), when every patch lies on
    /// its vertex and the vertex's surface neighbours with weights in [0, 1] (4-node tets with a
    /// radius within the elements); `None` otherwise. `slot[a]`: the kept vertex of node `a`
    /// (`u32::MAX`: none); `patch(k)`: kept vertex k's patch, nodes and weights (`None`: a point
    /// contact).
    fn neighbour_weights<'a>(
        &self,
        slot: &[u32],
        patch: impl Fn(usize) -> Option<(&'a [u32], &'a [f64])>,
    ) -> Option<Vec<u16>> {
        let mut q = vec![0u16; self.neighbours.len()];
        for k in 0..self.rest.len() {
            let Some((nodes, weights)) = patch(k) else {
                continue;
            };
            let lo = self.neighbour_ptr[k] as usize;
            let around = &self.neighbours[lo..self.neighbour_ptr[k + 1] as usize];
            for (&a, &w) in nodes.iter().zip(weights) {
                let ka = *slot.get(a as usize)?;
                if !(0.0..=1.0).contains(&w) {
                    return None;
                }
                if ka as usize != k {
                    // Neighbours are sorted (surface_neighbours).
                    let e = around.binary_search(&ka).ok()?;
                    q[lo + e] = (w * WEIGHT_UNIT).round() as u16;
                }
            }
        }
        Some(q)
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
    use nalgebra::Vector3;
    let mut sums = vec![Vector3::<f64>::zeros(); rest.len()];
    for t in triangles {
        let [a, b, c] = t.map(|v| Vector3::from(rest[v as usize]));
        let n = (b - a).cross(&(c - a));
        for &v in t {
            sums[v as usize] += n;
        }
    }
    let mut surface = Vec::new();
    let mut normals = vec![[0.0f64; 3]; rest.len()];
    for (i, n) in sums.iter().enumerate() {
        let len = n.norm();
        if len > 0.0 {
            normals[i] = (n / len).into();
            surface.push(i as u32);
        }
    }
    (normals, surface)
}

#[cfg(feature = "hdf5")]
mod file {
    use super::*;
    use std::path::Path;
    use ves_format::BasisReader;

    /// Loads what `opts` asks for from a v1 basis file: only corner-vertex rows of the first r
    /// modes are kept in memory. Every value of the space is checked first
    /// ([`ves_format::SpaceReader::validate`]: the basis streamed, contact, loads, transfers).
    pub fn load(path: &Path, opts: &LoadOptions) -> Result<Basis, LoadError> {
        let file = BasisReader::open(path)?;
        load_space(&file, opts)
    }

    /// [`load`] from an open file; the space loaded is validated whole, so every caller (the C
    /// ABI, `ves session`, `ves view`, Python) refuses what `ves info` refuses.
    pub fn load_space(file: &BasisReader, opts: &LoadOptions) -> Result<Basis, LoadError> {
        let p = file.path().display().to_string();
        let space = match &opts.space {
            Some(s) => s.clone(),
            None => file.default_space()?,
        };
        let s = file.space(&space)?;
        // The one validation of a space, before anything is kept; it streams the whole basis
        // (a NaN in rows the runtime does not keep is refused too).
        s.validate()?;
        let nv = s.vertex_count;
        let r = opts.modes.unwrap_or(s.mode_count);
        if r == 0 || r > s.mode_count {
            return Err(LoadError {
                path: p,
                message: format!("{r} modes asked, space {space:?} has {}", s.mode_count),
            });
        }
        let xyz = s.nodes(nv)?;
        let mut triangles = s.surface_triangles()?;
        let lam = s.eigenvalues()?;
        let rows = s.basis_rows(0..3 * nv, r)?;
        let mut keep: Vec<u32> = (0..nv as u32).collect();
        if opts.surface_only {
            let mut used = vec![false; nv];
            for &v in triangles.iter().flatten() {
                used[v as usize] = true;
            }
            keep = (0..nv as u32).filter(|&v| used[v as usize]).collect();
            let mut new = vec![u32::MAX; nv];
            for (k, &v) in keep.iter().enumerate() {
                new[v as usize] = k as u32;
            }
            for t in &mut triangles {
                *t = t.map(|v| new[v as usize]);
            }
        }
        let rest: Vec<[f64; 3]> = keep.iter().map(|&v| xyz[v as usize]).collect();
        let mut flat = Vec::with_capacity(3 * keep.len() * r);
        for &v in &keep {
            flat.extend_from_slice(&rows[3 * v as usize * r..3 * (v as usize + 1) * r]);
        }
        let m = file.material()?;
        let mut basis = Basis::new(
            &p,
            &space,
            rest,
            keep.clone(),
            triangles,
            lam[..r].to_vec(),
            &flat,
            (m.alpha, m.beta),
            s.rigid()?,
        )?;
        basis.voi = s.voi;
        basis.source = Some(file.path().to_path_buf());
        // One per file triangle, in the file's order: `triangles` keeps them all and in order
        // (surface_only renumbers their vertices only).
        if let Some(faces) = s.surface_faces()? {
            basis.bytes_loaded += faces.len() * 4;
            basis.surface_faces = Some(faces);
        }
        let mut slot = vec![u32::MAX; s.node_count];
        for (k, &v) in keep.iter().enumerate() {
            slot[v as usize] = k as u32;
        }
        for d in s.fixed_dofs()? {
            let (node, c) = (d as usize / 3, d % 3);
            if let Some(&k) = slot.get(node).filter(|&&k| k != u32::MAX) {
                basis.fixed[k as usize] |= 1 << c;
            }
        }
        basis.yield_strength = m.yield_strength;
        basis.elastic = Some((m.young, m.poisson));
        if let Some(all) = s.stress_rows(0..nv, r)? {
            let mut kept = Vec::with_capacity(6 * keep.len() * r);
            for &v in &keep {
                kept.extend_from_slice(&all[6 * v as usize * r..6 * (v as usize + 1) * r]);
            }
            basis = basis.with_stress(&kept)?;
        }
        if let Some((centres, per_mode)) = s.support_reactions()? {
            let all = s.mode_count;
            let per_mode: Vec<f64> = per_mode.chunks_exact(all).flat_map(|c| &c[..r]).copied().collect();
            basis.bytes_loaded += 8 * (per_mode.len() + 3 * centres.len());
            // One support holding every rigid motion carries any static load whole; several
            // share it as their influence coefficients say.
            let influence = s.support_influence()?;
            let rule = ves_format::read::ReactionStatics::of(centres.len(), s.rigid_modes_dropped, influence.is_some());
            let statics = match (rule, influence) {
                (ves_format::read::ReactionStatics::Unknown, _) => StaticReactions::Unknown,
                (ves_format::read::ReactionStatics::Equilibrium, _) => StaticReactions::Equilibrium,
                (_, None) => StaticReactions::Unknown,
                (_, Some((nodes, all))) => {
                    // All supports but the last: equilibrium gives the last (half the memory
                    // for two supports).
                    let (width, kept) = (18 * centres.len(), 18 * (centres.len() - 1));
                    let (mut row, mut values) = (vec![u32::MAX; keep.len()], Vec::new());
                    for (v, coefficients) in nodes.iter().zip(all.chunks_exact(width)) {
                        if let Some(&k) = slot.get(*v as usize).filter(|&&k| k != u32::MAX) {
                            row[k as usize] = (values.len() / kept) as u32;
                            values.extend(coefficients[..kept].iter().map(|&c| c as f32));
                        }
                    }
                    basis.bytes_loaded += 4 * (row.len() + values.len());
                    StaticReactions::Influence { row, values }
                }
            };
            basis.support_reactions = Some(SupportReactions {
                centres,
                per_mode,
                statics,
            });
        }
        if let Some(n) = s.nonlinear()? {
            // Held in f32: a finite f64 beyond f32's range would become infinite (as for φ).
            if n.quartic.iter().any(|v| v.abs() > f64::from(f32::MAX)) {
                return Err(LoadError {
                    path: p,
                    message: format!(
                        "space {space:?}: nonlinear/quartic holds values beyond single precision (> 3.4e38): \
                         the file is damaged"
                    ),
                });
            }
            let all = crate::nonlinear::Polynomial::of_file(&lam, n.cubic, n.quartic);
            // H in single precision: the step at r = 30 took 96 µs against 112–120 µs in double
            // (docs/nonlinear.md), and the basis half the bytes.
            let p = all.first(r).single_precision();
            basis.bytes_loaded += p.bytes();
            basis.nonlinear = Some(std::sync::Arc::new(p));
        }
        if let Some(contact) = s.contact()? {
            basis = with_contact_rows(basis, &s, &contact, &keep, &rows, r)?;
        }
        if let Some(f) = s.felt()? {
            basis.bytes_loaded += 8 * keep.len();
            basis.felt = Some(FeltAt::of_file(&f, &slot, keep.len()));
        }
        match s.compliance()? {
            Some((nodes, blocks)) => {
                let mut per_vertex = vec![[[f64::NAN; 3]; 3]; keep.len()];
                for (&node, block) in nodes.iter().zip(blocks) {
                    if let Some(&k) = slot.get(node as usize).filter(|&&k| k != u32::MAX) {
                        per_vertex[k as usize] = block;
                    }
                }
                basis.with_compliance(per_vertex)
            }
            None => Ok(basis),
        }
    }

    /// Attaches each kept vertex's patch (its own rows when it has none): as neighbour weights
    /// where every patch lies on its vertex's surface neighbours, else as the rows Σ wₐ φₐ.
    /// `rows`: the file's corner-vertex rows, `rows[(3v + c)·r + j]`; mid-edge nodes in a patch
    /// are read here.
    fn with_contact_rows(
        basis: Basis,
        s: &ves_format::SpaceReader<'_>,
        contact: &ves_format::Contact,
        keep: &[u32],
        rows: &[f64],
        r: usize,
    ) -> Result<Basis, LoadError> {
        let nv = rows.len() / (3 * r);
        let kept_centre = |v: u32| contact.centres.binary_search(&v).ok();
        let mut slot = vec![u32::MAX; nv];
        for (k, &v) in keep.iter().enumerate() {
            slot[v as usize] = k as u32;
        }
        if let Some(w) = basis.neighbour_weights(&slot, |k| kept_centre(keep[k]).map(|c| contact.patch(c))) {
            return basis.with_contact_weights(contact.radius, w);
        }
        let mut extra: Vec<u32> = keep
            .iter()
            .filter_map(|&v| kept_centre(v))
            .flat_map(|k| contact.patch(k).0.iter().copied())
            .filter(|&a| a as usize >= nv)
            .collect();
        extra.sort_unstable();
        extra.dedup();
        let extra_rows = s.node_rows(&extra, r)?;
        let row = |a: u32| -> &[f64] {
            match extra.binary_search(&a) {
                Ok(e) if a as usize >= nv => &extra_rows[3 * r * e..3 * r * (e + 1)],
                _ => &rows[3 * r * a as usize..3 * r * (a as usize + 1)],
            }
        };
        let mut out = vec![0f32; 3 * r * keep.len()];
        let mut acc = vec![0.0f64; 3 * r];
        for (k, &v) in keep.iter().enumerate() {
            acc.fill(0.0);
            match kept_centre(v) {
                Some(c) => {
                    let (nodes, weights) = contact.patch(c);
                    for (&a, &w) in nodes.iter().zip(weights) {
                        for (x, y) in acc.iter_mut().zip(row(a)) {
                            *x += w * y;
                        }
                    }
                }
                None => acc.copy_from_slice(row(v)),
            }
            // File rows are (3v + c)·r + j: the same layout as `Contact::Rows`.
            for (o, x) in out[3 * r * k..3 * r * (k + 1)].iter_mut().zip(&acc) {
                *o = *x as f32;
            }
        }
        basis.with_contact(contact.radius, out)
    }
}

#[cfg(feature = "hdf5")]
pub use file::{load, load_space};

#[cfg(test)]
mod tests {
    use super::*;

    /// The 3×3 grid with three modes of assorted values.
    fn grid_with_modes() -> (Basis, Vec<f64>) {
        let g = stretch_grid(1.0, 1.0, 0.0);
        let n = g.rest.len();
        let rows: Vec<f64> = (0..3 * n * 3).map(|k| ((k * 37 % 101) as f64 - 50.0) * 1e-3).collect();
        let b = Basis::new(
            "grid",
            "global",
            g.rest,
            g.node_index,
            g.triangles,
            vec![1.0, 2.0, 3.0],
            &rows,
            (0.0, 0.0),
            None,
        )
        .expect("grid basis");
        (b, rows)
    }

    /// Neighbour weights give the patch rows Σ wₐ φₐ that rows kept for every vertex gave, to
    /// the weights' rounding; a patch reaching past the neighbours keeps the rows.
    #[test]
    fn neighbour_weights_give_the_patch_rows() {
        let (b, rows) = grid_with_modes();
        let (n, r) = (b.rest.len(), 3);
        // Each vertex's patch: 0.4 on itself, the rest shared by its neighbours unevenly; vertex
        // 8 is a point contact.
        let patches: Vec<(Vec<u32>, Vec<f64>)> = (0..n)
            .map(|i| {
                let around = &b.neighbours[b.neighbour_ptr[i] as usize..b.neighbour_ptr[i + 1] as usize];
                let total: f64 = (1..=around.len()).map(|e| e as f64).sum();
                let mut nodes = vec![i as u32];
                let mut weights = vec![0.4];
                for (e, &k) in around.iter().enumerate() {
                    nodes.push(k);
                    weights.push(0.6 * (e + 1) as f64 / total);
                }
                (nodes, weights)
            })
            .collect();
        let slot: Vec<u32> = (0..n as u32).collect();
        let patch = |k: usize| (k != 8).then(|| (patches[k].0.as_slice(), patches[k].1.as_slice()));
        let weights = b.neighbour_weights(&slot, patch).expect("patches on neighbours");
        let lazy = b.clone().with_contact_weights(0.005, weights).expect("weights");
        let mut got = vec![0.0; 3 * r];
        for i in 0..n {
            let mut want = vec![0.0; 3 * r];
            match patch(i) {
                Some((nodes, ws)) => {
                    for (&a, &w) in nodes.iter().zip(ws) {
                        for (x, y) in want.iter_mut().zip(&rows[3 * r * a as usize..3 * r * (a as usize + 1)]) {
                            *x += w * y;
                        }
                    }
                }
                None => want.copy_from_slice(&rows[3 * r * i..3 * r * (i + 1)]),
            }
            lazy.gather_contact_rows(i, &mut got);
            for (e, (g, w)) in got.iter().zip(&want).enumerate() {
                // The weights' rounding (0.5/65535 each, times a neighbour's difference from the
                // vertex) and phi's f32.
                let own = rows[3 * r * i + e];
                let rounding: f64 = patch(i).map_or(0.0, |(nodes, _)| {
                    nodes
                        .iter()
                        .map(|&a| 0.5 / WEIGHT_UNIT * (rows[3 * r * a as usize + e] - own).abs())
                        .sum()
                });
                assert!(
                    (g - w).abs() <= rounding + 1e-7 * 0.05,
                    "vertex {i}: {got:?} against {want:?}"
                );
            }
        }
        // Vertex 0's patch reaching vertex 8 (not its neighbour): no weights.
        let far = (vec![0u32, 8], vec![0.5, 0.5]);
        let reaching = |k: usize| {
            Some(if k == 0 {
                (far.0.as_slice(), far.1.as_slice())
            } else {
                (patches[k].0.as_slice(), patches[k].1.as_slice())
            })
        };
        assert!(b.neighbour_weights(&slot, reaching).is_none());
    }
}
