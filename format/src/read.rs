//! The one reader of basis files. Whatever it returns has been checked: dtypes exactly as the
//! format declares them (no silent conversion of an int32 basis), shapes against each other,
//! declared sizes against the file's size before anything is allocated, finite values, indices
//! in range, and what physics requires ([`crate::checks`]). Every method runs behind
//! [`guarded`]: a panic of the HDF5 layer on a damaged file is an error.
//!
//! Before any value of a dataset is read, its storage is checked: data held in the file itself
//! (contiguous, chunked or compact layout; no external raw storage, no virtual dataset, no link
//! into another file, which would read local files such as /etc/passwd into an export), only
//! the filters the writer uses (deflate, shuffle), and no object reached by two names. The work
//! per open file is bounded: at most [`names::MAX_SPACES`] spaces, and the stored bytes read at
//! most [`READ_PASSES`] times the file's size.

use crate::checks;
use crate::names::{self, material as mat, root, space as sp};
use crate::{Material, RigidProperties};
use hdf5::H5Type;
use hdf5::dataset::Layout;
use hdf5::filters::Filter;
use ndarray::s;
use std::cell::Cell;
use std::ops::Range;
use std::path::Path;

mod loads;
pub use loads::LoadCase;

/// Reading failed; the message names the file and what is wrong.
pub type ReadError = crate::InputError;

/// Runs `f`, turning a panic inside the HDF5 layer into an error: hdf5-metno 0.15 builds strings
/// from file bytes unchecked, and a corrupted name made it panic while formatting one (found by
/// the byte-flip test).
pub fn guarded<T, E: From<ReadError>>(path: &Path, f: impl FnOnce() -> Result<T, E>) -> Result<T, E> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).unwrap_or_else(|_| {
        Err(E::from(ReadError {
            path: path.display().to_string(),
            message: "damaged file: the HDF5 layer failed on its structure".into(),
        }))
    })
}

/// Deflate cannot shrink data more than about 1032:1: a compressed dataset that claims more than
/// this many times the file's size has a damaged header.
const MAX_COMPRESSION: u128 = 1100;

/// Per support the point its moments are about, and the row-major [6·s, r] reactions per unit
/// modal coordinate ([`sp::SUPPORT_REACTIONS`]).
pub type SupportReactions = (Vec<[f64; 3]>, Vec<f64>);

/// Each support's reaction per newton of a static load at surface corner vertices: the
/// vertices (strictly ascending) and the row-major [q, 18·s] coefficients.
pub type SupportInfluence = (Vec<u32>, Vec<f64>);

/// How a session knows the exact static reactions of a hand's load on a part held by
/// `supports` supports that leave `rigid_modes_dropped` rigid motions free, with or without
/// influence coefficients: the one rule the runtime and `ves info` read a file by.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReactionStatics {
    /// Not known (a rigid motion left free, no supports, or several without coefficients):
    /// the modes' share only.
    Unknown,
    /// One support holding every rigid motion: equilibrium (coefficients, if any, not read).
    Equilibrium,
    /// Several supports and their influence coefficients.
    Influence,
}

impl ReactionStatics {
    /// The rule.
    pub fn of(supports: usize, rigid_modes_dropped: u32, has_influence: bool) -> ReactionStatics {
        match (supports, rigid_modes_dropped, has_influence) {
            (0, _, _) | (_, 1.., _) => ReactionStatics::Unknown,
            (1, _, _) => ReactionStatics::Equilibrium,
            (_, _, true) => ReactionStatics::Influence,
            (_, _, false) => ReactionStatics::Unknown,
        }
    }
}

/// Supports a file may hold reactions for: far more than a scene of at most 64 KiB can name.
const MAX_SUPPORTS: usize = 4096;

/// Stored bytes one open file may read, in multiples of its size. Reading a whole basis once for
/// its check and once more for use costs about 2; a file whose spaces share their data through
/// links would cost one pass per link (2000 linked spaces took 31 s and 660 MB).
pub const READ_PASSES: u128 = 8;

/// An open basis file whose format and version were checked.
pub struct BasisReader {
    file: hdf5::File,
    path: std::path::PathBuf,
    file_bytes: u128,
    /// Identifies this file among those libhdf5 has open: an object elsewhere was reached
    /// through an external link.
    fileno: u64,
    /// Stored bytes read so far (see [`READ_PASSES`]).
    charged: Cell<u128>,
    /// The file as opened, and its size and times then: HDF5 reads past the end of a file as
    /// zeros, so a file truncated and rewritten in place (as `cp` does) while it is read would
    /// give zeros where data was. Each read is checked against them (a file replaced by a
    /// rename, as VES writes, leaves the opened one as it was).
    opened: Option<(std::fs::File, Stamp)>,
}

/// What writing a file changes: its size and modification time (not its change time, which a
/// rename over the file's name changes too: the file opened is then intact).
type Stamp = (u64, i64, i64);

fn stamp(m: &std::fs::Metadata) -> Stamp {
    use std::os::unix::fs::MetadataExt;
    (m.size(), m.mtime(), m.mtime_nsec())
}

impl BasisReader {
    /// Opens `path` and checks that it is a VES basis of a version this build reads.
    pub fn open(path: &Path) -> Result<BasisReader, ReadError> {
        let err = |message: &str| ReadError {
            path: path.display().to_string(),
            message: message.to_string(),
        };
        if path.is_dir() {
            return Err(err(
                "is a directory, not a basis file; give the .h5 file written by `ves precompute`",
            ));
        }
        let meta = std::fs::metadata(path).map_err(|e| {
            err(&match e.kind() {
                std::io::ErrorKind::NotFound => "no such file".to_string(),
                _ => format!("cannot read it ({e})"),
            })
        })?;
        if !meta.is_file() {
            return Err(err("not a regular file; give the .h5 file written by `ves precompute`"));
        }
        let opened = std::fs::File::open(path)
            .ok()
            .and_then(|f| f.metadata().ok().map(|m| (f, stamp(&m))));
        guarded(path, || {
            let file = crate::file::open(path).map_err(|e| {
                err(&format!(
                    "not a readable HDF5 file (truncated or another format): {}",
                    e.to_string().replace('\n', " ")
                ))
            })?;
            let fileno = file
                .loc_info()
                .map_err(|_| err("damaged file: the root group's header is unreadable"))?
                .fileno;
            let reader = BasisReader {
                file,
                path: path.to_path_buf(),
                file_bytes: u128::from(meta.len()),
                fileno,
                charged: Cell::new(0),
                opened,
            };
            let format = reader.string(root::FORMAT).ok_or_else(|| {
                err("not a VES modal basis (no `format` attribute); produce one with `ves precompute`")
            })?;
            if format != names::FORMAT {
                return Err(err(&format!(
                    "format is {format:?}, not {:?}; produce a basis with `ves precompute`",
                    names::FORMAT
                )));
            }
            let version: u32 = scalar_attr(&reader.file, root::VERSION)
                .ok_or_else(|| err("`version` attribute missing or not an unsigned 32-bit integer"))?;
            if version > names::VERSION {
                return Err(err(&format!(
                    "basis version {version} is newer than this build reads ({}); upgrade VES",
                    names::VERSION
                )));
            }
            Ok(reader)
        })
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The file's size, bytes.
    pub fn file_bytes(&self) -> u64 {
        self.file_bytes as u64
    }

    fn err(&self, message: impl Into<String>) -> ReadError {
        ReadError {
            path: self.path.display().to_string(),
            message: message.into(),
        }
    }

    fn guard<T>(&self, f: impl FnOnce() -> Result<T, ReadError>) -> Result<T, ReadError> {
        let out = guarded(&self.path, f)?;
        self.unchanged()?;
        Ok(out)
    }

    /// Fails when the file opened has been written since (see `opened`).
    pub fn unchanged(&self) -> Result<(), ReadError> {
        match &self.opened {
            Some((f, then)) if f.metadata().map(|m| stamp(&m)).ok().as_ref() != Some(then) => Err(self.err(
                "the file changed while it was read (another process is writing it in place); read it again once \
                 the writer is done, and write bases with `ves precompute`, which replaces a file whole",
            )),
            _ => Ok(()),
        }
    }

    /// A root string attribute (fixed- or variable-length), `None` when missing or not a string.
    pub fn string(&self, name: &str) -> Option<String> {
        guarded(&self.path, || {
            Ok::<_, ReadError>(crate::strings::read(&self.file, name))
        })
        .ok()
        .flatten()
    }

    /// Checks that `loc` (reached as `name`) lives in this file and has one name only: an
    /// external link would read another file, a hard link shares data between spaces.
    fn check_object(&self, loc: &hdf5::Location, name: &str) -> Result<(), ReadError> {
        let info = loc
            .loc_info()
            .map_err(|_| self.err(format!("{name}: object header unreadable; the file is damaged")))?;
        if info.fileno != self.fileno {
            return Err(self.err(format!(
                "{name} is a link into another file; a basis holds all its data itself (refused: it would read that file)"
            )));
        }
        if info.num_links != 1 {
            return Err(self.err(format!(
                "{name} has {} hard links; the writer gives every object one name (refused: shared data multiplies the work)",
                info.num_links
            )));
        }
        Ok(())
    }

    /// Checks, before any value is read, that dataset `name` keeps its data in this file in a way
    /// the writer uses: contiguous, chunked or compact layout, no external raw storage, no
    /// virtual mapping, no filter but deflate and shuffle.
    fn check_storage(&self, ds: &hdf5::Dataset, name: &str) -> Result<(), ReadError> {
        self.check_object(ds, name)?;
        let unreadable = |what: &str| self.err(format!("{name}: {what} unreadable; the file is damaged"));
        let dcpl = ds.dcpl().map_err(|_| unreadable("creation properties"))?;
        match dcpl.get_layout().map_err(|_| unreadable("layout"))? {
            Layout::Contiguous | Layout::Chunked | Layout::Compact => {}
            other => {
                return Err(self.err(format!(
                    "{name} is a {other:?} dataset (its data drawn from other datasets or files); a basis holds its data itself: refused"
                )));
            }
        }
        let external = dcpl.get_external().map_err(|_| unreadable("external storage list"))?;
        if let Some(e) = external.first() {
            return Err(self.err(format!(
                "{name} keeps its data in external file \"{}\"; a basis holds its data itself: refused (it would read that file)",
                names::escape_for_terminal(&e.name)
            )));
        }
        for f in dcpl.get_filters().map_err(|_| unreadable("filter pipeline"))? {
            if !matches!(f, Filter::Deflate(_) | Filter::Shuffle) {
                return Err(self.err(format!(
                    "{name} is stored through filter {f:?}; the format uses deflate and shuffle only: refused"
                )));
            }
        }
        Ok(())
    }

    /// Counts `bytes` of dataset `ds` (of `total` bytes) as read: at their share of its stored
    /// size, and at least 1/[`MAX_COMPRESSION`] of them; refuses once the file has been read
    /// [`READ_PASSES`] times over.
    fn charge(&self, name: &str, ds: &hdf5::Dataset, bytes: u128, total: u128) -> Result<(), ReadError> {
        let stored = u128::from(ds.storage_size());
        let share = if total == 0 {
            0
        } else {
            (bytes * stored).div_ceil(total)
        };
        let cost = share.max(bytes.div_ceil(MAX_COMPRESSION));
        let sum = self.charged.get().saturating_add(cost);
        let limit = READ_PASSES * self.file_bytes.max(1);
        if sum > limit {
            return Err(self.err(format!(
                "{name}: reading it would read {sum} stored bytes of a {}-byte file, more than {READ_PASSES} times its \
                 size; its spaces share data through links (refused)",
                self.file_bytes
            )));
        }
        self.charged.set(sum);
        Ok(())
    }

    /// The names listed under /spaces, checked (at most [`names::MAX_SPACES`], each a valid
    /// name), in the file's order.
    fn listed_spaces(&self) -> Result<Vec<String>, ReadError> {
        let g = self
            .file
            .group(names::SPACES)
            .map_err(|_| self.err("no /spaces group; the file is damaged"))?;
        self.check_object(&g, names::SPACES)?;
        let too_many = |count: usize| {
            self.err(format!(
                "/spaces holds {count} spaces, more than {}: refused before reading them",
                names::MAX_SPACES
            ))
        };
        // The link count is in the group's header: the names are not even listed.
        let count = usize::try_from(g.len()).unwrap_or(usize::MAX);
        if count > names::MAX_SPACES {
            return Err(too_many(count));
        }
        let listed = g
            .member_names()
            .map_err(|_| self.err("/spaces unreadable; the file is damaged"))?;
        if listed.len() > names::MAX_SPACES {
            return Err(too_many(listed.len()));
        }
        if listed.is_empty() {
            return Err(self.err("the file holds no space; the file is damaged"));
        }
        for n in &listed {
            names::check_space_name(n).map_err(|m| self.err(format!("/spaces: {m}")))?;
        }
        Ok(listed)
    }

    /// The space a reader opens when it names none ("global" when the attribute is missing),
    /// checked to exist.
    pub fn default_space(&self) -> Result<String, ReadError> {
        self.guard(|| {
            let listed = self.listed_spaces()?;
            self.default_among(&listed)
        })
    }

    fn default_among(&self, listed: &[String]) -> Result<String, ReadError> {
        let default = match self.string(root::DEFAULT_SPACE) {
            Some(d) => d,
            None if self.file.attr(root::DEFAULT_SPACE).is_ok() => {
                return Err(self.err(format!(
                    "attribute {} is not a string; the file is damaged",
                    root::DEFAULT_SPACE
                )));
            }
            None => names::GLOBAL_SPACE.into(),
        };
        if !listed.contains(&default) {
            return Err(self.err(format!(
                "attribute {} names space \"{}\", which the file does not hold (it holds {listed:?}); the file is damaged",
                root::DEFAULT_SPACE,
                names::escape_for_terminal(&default)
            )));
        }
        Ok(default)
    }

    /// Names of the spaces, the default space first, then by name.
    pub fn space_names(&self) -> Result<Vec<String>, ReadError> {
        self.guard(|| {
            let mut names = self.listed_spaces()?;
            let default = self.default_among(&names)?;
            names.sort_by_key(|n| (*n != default, n.clone()));
            Ok(names)
        })
    }

    /// The material constants and damping, checked (finite; E, ρ > 0; −1 < ν < 0.5; α, β ≥ 0).
    pub fn material(&self) -> Result<Material, ReadError> {
        self.guard(|| {
            let g = self
                .file
                .group(mat::GROUP)
                .map_err(|_| self.err("no /material group; the file is damaged"))?;
            self.check_object(&g, mat::GROUP)?;
            let get = |name: &str| {
                scalar_attr::<f64>(&g, name)
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| self.err(format!("material attribute {name} missing, not f64 or not finite")))
            };
            let m = Material {
                young: get(mat::YOUNG)?,
                poisson: get(mat::POISSON)?,
                density: get(mat::DENSITY)?,
                alpha: get(mat::ALPHA)?,
                beta: get(mat::BETA)?,
                yield_strength: match g.attr(mat::YIELD_STRENGTH) {
                    Ok(_) => Some(get(mat::YIELD_STRENGTH)?)
                        .filter(|y| *y > 0.0)
                        .map(Some)
                        .ok_or_else(|| self.err("material attribute yield_strength is not > 0; the file is damaged"))?,
                    Err(_) => None,
                },
            };
            if !(m.young > 0.0 && m.density > 0.0 && m.poisson > -1.0 && m.poisson < 0.5) {
                return Err(self.err(format!(
                    "material (E {}, ν {}, ρ {}) is not physical; the file is damaged",
                    m.young, m.poisson, m.density
                )));
            }
            if !(m.alpha >= 0.0 && m.beta >= 0.0) {
                return Err(self.err(format!("Rayleigh damping ({}, {}) must be ≥ 0", m.alpha, m.beta)));
            }
            Ok(m)
        })
    }

    /// Reads and checks everything in the file: the default space, the material and every
    /// space ([`SpaceReader::validate`]). The one validation every reader runs before it uses
    /// a file (`ves info`, `ves export`, the runtime's loader and through it `ves session`,
    /// `ves view`, the C ABI and Python).
    pub fn validate(&self) -> Result<(), ReadError> {
        self.default_space()?;
        self.material()?;
        for name in self.space_names()? {
            self.space(&name)?.validate()?;
        }
        Ok(())
    }

    /// Opens space `name`, checking its attributes and that its datasets' shapes agree.
    pub fn space(&self, name: &str) -> Result<SpaceReader<'_>, ReadError> {
        self.guard(|| SpaceReader::open(self, name))
    }
}

/// A scalar attribute of exactly type `T` (no conversion), if present.
fn scalar_attr<T: H5Type>(loc: &hdf5::Location, name: &str) -> Option<T> {
    let a = loc.attr(name).ok()?;
    if a.dtype().ok()?.to_descriptor().ok()? != T::type_descriptor() || a.size() != 1 {
        return None;
    }
    a.read_scalar().ok()
}

/// An f64 array attribute of `len` values, all finite, if present.
fn f64_array_attr(loc: &hdf5::Location, name: &str, len: usize) -> Option<Vec<f64>> {
    let a = loc.attr(name).ok()?;
    if a.dtype().ok()?.to_descriptor().ok()? != f64::type_descriptor() || a.size() != len {
        return None;
    }
    let v: Vec<f64> = a.read_raw().ok()?;
    (v.len() == len && v.iter().all(|x| x.is_finite())).then_some(v)
}

/// A space's reduced St. Venant–Kirchhoff model, as stored ([`sp::NONLINEAR`]).
#[derive(Clone, Debug)]
pub struct Nonlinear {
    /// The first basis columns that are eigenmodes.
    pub eigenmodes: usize,
    /// How many lowest modes' pairwise derivatives were added.
    pub derivatives_of: usize,
    /// T, row-major [r, P], P = r(r+1)/2.
    pub cubic: Vec<f64>,
    /// H, row-major [P, P].
    pub quartic: Vec<f64>,
}

/// One space of an open basis file, its header checked; its arrays are read on demand.
pub struct SpaceReader<'a> {
    file: &'a BasisReader,
    group: hdf5::Group,
    /// Space name.
    pub name: String,
    /// The element kind (the file's `element_order`: 1 or 2).
    pub kind: crate::ElementKind,
    /// Rigid modes dropped.
    pub rigid_modes_dropped: u32,
    /// The VOI this space refines (min, max corners), if any.
    pub voi: Option<[[f64; 3]; 2]>,
    /// Corner vertices (the first nodes).
    pub vertex_count: usize,
    /// How the mesh was made, when the file says.
    pub meshing_strategy: Option<String>,
    /// All nodes.
    pub node_count: usize,
    /// Tets.
    pub tet_count: usize,
    /// Surface triangles.
    pub triangle_count: usize,
    /// Elastic modes stored.
    pub mode_count: usize,
}

impl<'a> SpaceReader<'a> {
    fn open(file: &'a BasisReader, name: &str) -> Result<SpaceReader<'a>, ReadError> {
        names::check_space_name(name).map_err(|m| file.err(m.to_string()))?;
        let path = format!("{}/{name}", names::SPACES);
        let group = file
            .file
            .group(&path)
            .map_err(|_| file.err(format!("no space {name:?} in the file")))?;
        file.check_object(&group, &path)?;
        let bad = |what: &str| file.err(format!("space {name:?}: {what}"));
        let kind = scalar_attr::<u32>(&group, sp::ELEMENT_ORDER)
            .and_then(crate::ElementKind::of_order)
            .ok_or_else(|| bad("element_order missing or not 1 or 2"))?;
        let rigid_modes_dropped: u32 = scalar_attr(&group, sp::RIGID_MODES_DROPPED)
            .filter(|r| *r <= 6)
            .ok_or_else(|| bad("rigid_modes_dropped missing or above 6"))?;
        let mesh_group = group.group(sp::MESH).map_err(|_| bad("mesh group missing"))?;
        file.check_object(&mesh_group, &format!("{path}/{}", sp::MESH))?;
        let nv: u32 =
            scalar_attr(&mesh_group, sp::VERTEX_COUNT).ok_or_else(|| bad("mesh vertex_count missing or not u32"))?;
        let meshing_strategy = crate::strings::read(&mesh_group, sp::MESHING_STRATEGY);
        let voi = match (group.attr(sp::VOI_MIN).is_ok(), group.attr(sp::VOI_MAX).is_ok()) {
            (false, false) => None,
            _ => {
                let (a, b) = f64_array_attr(&group, sp::VOI_MIN, 3)
                    .zip(f64_array_attr(&group, sp::VOI_MAX, 3))
                    .ok_or_else(|| bad("voi_min/voi_max are not two finite f64[3]"))?;
                if (0..3).any(|c| a[c] >= b[c]) {
                    return Err(bad(&format!(
                        "voi_min {a:?} is not below voi_max {b:?} in every axis; the file is damaged"
                    )));
                }
                Some([[a[0], a[1], a[2]], [b[0], b[1], b[2]]])
            }
        };
        let mut s = SpaceReader {
            file,
            group,
            name: name.to_string(),
            kind,
            rigid_modes_dropped,
            voi,
            vertex_count: nv as usize,
            meshing_strategy,
            node_count: 0,
            tet_count: 0,
            triangle_count: 0,
            mode_count: 0,
        };
        let nodes = s.shape::<f64>(sp::NODES, 2)?;
        let (n, r) = (nodes[0], s.shape::<f64>(sp::EIGENVALUES, 1)?[0]);
        let per_tet = kind.nodes();
        let expect = |what: &str, got: Vec<usize>, want: &[Option<usize>]| {
            let ok = got.len() == want.len() && got.iter().zip(want).all(|(g, w)| w.is_none_or(|w| *g == w));
            if ok {
                Ok(got)
            } else {
                Err(bad(&format!(
                    "{what} has shape {got:?}, expected {want:?} (n = {n} nodes, r = {r} modes)"
                )))
            }
        };
        expect(sp::NODES, nodes.clone(), &[None, Some(3)])?;
        expect(sp::BASIS, s.shape::<f64>(sp::BASIS, 2)?, &[Some(3 * n), Some(r)])?;
        expect(sp::FREQUENCIES_HZ, s.shape::<f64>(sp::FREQUENCIES_HZ, 1)?, &[Some(r)])?;
        expect(
            sp::RELATIVE_RESIDUALS,
            s.shape::<f64>(sp::RELATIVE_RESIDUALS, 1)?,
            &[Some(r)],
        )?;
        let tets = expect(sp::TETS, s.shape::<u32>(sp::TETS, 2)?, &[None, Some(per_tet)])?;
        let tri = expect(
            sp::SURFACE_TRIANGLES,
            s.shape::<u32>(sp::SURFACE_TRIANGLES, 2)?,
            &[None, Some(3)],
        )?;
        s.shape::<u32>(sp::FIXED_DOFS, 1)?;
        // The tets are deflated: their count is bounded by the nodes' (stored uncompressed)
        // before they are read.
        if tets[0] > checks::MAX_TETS_PER_NODE * n {
            return Err(bad(&format!(
                "{} holds {} tets for {n} nodes, more than {} per node; the file is damaged",
                sp::TETS,
                tets[0],
                checks::MAX_TETS_PER_NODE
            )));
        }
        if nv == 0 || nv as usize > n || r == 0 || tets[0] == 0 {
            return Err(bad(&format!(
                "{nv} vertices of {n} nodes, {r} modes, {} tets: nothing to simulate or inconsistent",
                tets[0]
            )));
        }
        s.node_count = n;
        s.mode_count = r;
        s.tet_count = tets[0];
        s.triangle_count = tri[0];
        Ok(s)
    }

    fn err(&self, message: impl std::fmt::Display) -> ReadError {
        self.file.err(format!("space {:?}: {message}", self.name))
    }

    fn guard<T>(&self, f: impl FnOnce() -> Result<T, ReadError>) -> Result<T, ReadError> {
        self.file.guard(f)
    }

    /// Opens a dataset of exactly element type `T` and `rank` dimensions whose declared size the
    /// file can hold, and returns its shape.
    fn dataset<T: H5Type>(&self, name: &str, rank: usize) -> Result<(hdf5::Dataset, Vec<usize>), ReadError> {
        let ds = self
            .group
            .dataset(name)
            .map_err(|_| self.err(format!("{name} missing")))?;
        self.file
            .check_storage(&ds, &format!("{}/{}/{name}", names::SPACES, self.name))?;
        let ty = ds
            .dtype()
            .and_then(|t| t.to_descriptor())
            .map_err(|_| self.err(format!("{name}: unreadable element type")))?;
        if ty != T::type_descriptor() {
            return Err(self.err(format!(
                "{name} holds {ty}, the format declares {}; the file was not written by VES or is damaged",
                T::type_descriptor()
            )));
        }
        let shape = ds.shape();
        if shape.len() != rank {
            return Err(self.err(format!("{name} has {} dimensions, expected {rank}", shape.len())));
        }
        let bytes = shape.iter().map(|&d| d as u128).product::<u128>() * std::mem::size_of::<T>() as u128;
        if !ds.filters().is_empty() && !sp::COMPRESSED.contains(&name) {
            return Err(self.err(format!(
                "{name} is compressed; the format compresses only {} (refused: deflate lets a small file claim \
                 gigabytes of values)",
                sp::COMPRESSED.join(", ")
            )));
        }
        let limit = if ds.filters().is_empty() {
            self.file.file_bytes
        } else {
            self.file.file_bytes * MAX_COMPRESSION
        };
        if bytes > limit {
            return Err(self.err(format!(
                "{name} claims {bytes} bytes in a {}-byte file; the file is damaged",
                self.file.file_bytes
            )));
        }
        // What the dataset itself stores must hold its values (a file's size says nothing of a
        // sparse file: a dataset never written reads back at full size from a few kilobytes).
        let stored = u128::from(ds.storage_size());
        let holds = if ds.filters().is_empty() {
            stored
        } else {
            stored * MAX_COMPRESSION
        };
        if bytes > holds {
            return Err(self.err(format!(
                "{name} has {bytes} bytes of values but stores {stored}: it was never written in full; the file is damaged"
            )));
        }
        Ok((ds, shape))
    }

    /// Whether the space holds dataset `name` (an optional one): false when nothing has that
    /// name, an error when something else does (a reader taking it for absent would skip its
    /// checks).
    fn has_dataset(&self, name: &str) -> Result<bool, ReadError> {
        if !self.group.link_exists(name) {
            return Ok(false);
        }
        self.group.dataset(name).map(|_| true).map_err(|_| {
            self.err(format!(
                "{name} is not a dataset (the format declares one there); the file is damaged"
            ))
        })
    }

    /// The space's optional group `name`, checked ([`BasisReader::check_object`]): `None` when
    /// nothing has that name, an error when something else (a dataset) does.
    fn optional_group(&self, name: &str) -> Result<Option<hdf5::Group>, ReadError> {
        if !self.group.link_exists(name) {
            return Ok(None);
        }
        let g = self.group.group(name).map_err(|_| {
            self.err(format!(
                "{name} is not a group (the format declares a group there); the file is damaged"
            ))
        })?;
        self.file
            .check_object(&g, &format!("{}/{}/{name}", names::SPACES, self.name))?;
        Ok(Some(g))
    }

    /// The shape of 1-D dataset `name`, which must hold `want` values: checked before it is read.
    fn expect_len<T: H5Type>(&self, name: &str, want: usize, of: &str) -> Result<(), ReadError> {
        let got = self.shape::<T>(name, 1)?[0];
        if got != want {
            return Err(self.err(format!(
                "{name} holds {got} values for {want} {of}; the file is damaged"
            )));
        }
        Ok(())
    }

    fn shape<T: H5Type>(&self, name: &str, rank: usize) -> Result<Vec<usize>, ReadError> {
        self.dataset::<T>(name, rank).map(|(_, s)| s)
    }

    /// Counts `elements` of `T` read from dataset `name` of shape `shape` (see
    /// [`BasisReader::charge`]).
    fn charge<T>(&self, name: &str, ds: &hdf5::Dataset, shape: &[usize], elements: usize) -> Result<(), ReadError> {
        let size = std::mem::size_of::<T>() as u128;
        let total = shape.iter().map(|&d| d as u128).product::<u128>() * size;
        self.file.charge(name, ds, elements as u128 * size, total)
    }

    fn read_all<T: H5Type + Copy>(&self, name: &str, rank: usize) -> Result<Vec<T>, ReadError> {
        let (ds, shape) = self.dataset::<T>(name, rank)?;
        self.charge::<T>(name, &ds, &shape, shape.iter().product())?;
        ds.read_raw()
            .map_err(|_| self.err(format!("{name}: data unreadable (damaged)")))
    }

    fn finite(&self, name: &str, v: Vec<f64>) -> Result<Vec<f64>, ReadError> {
        match v.iter().position(|x| !x.is_finite()) {
            Some(i) => Err(self.err(format!(
                "{name} holds a non-finite value at entry {i}; the file is damaged"
            ))),
            None => Ok(v),
        }
    }

    fn indices(&self, name: &str, v: Vec<u32>, bound: usize) -> Result<Vec<u32>, ReadError> {
        match v.iter().find(|&&i| i as usize >= bound) {
            Some(i) => Err(self.err(format!(
                "{name} refers to index {i}, beyond {bound}; the file is damaged"
            ))),
            None => Ok(v),
        }
    }

    /// The first `count` nodes (m), finite.
    pub fn nodes(&self, count: usize) -> Result<Vec<[f64; 3]>, ReadError> {
        self.guard(|| {
            let count = count.min(self.node_count);
            let (ds, shape) = self.dataset::<f64>(sp::NODES, 2)?;
            self.charge::<f64>(sp::NODES, &ds, &shape, 3 * count)?;
            let a: ndarray::Array2<f64> = ds
                .read_slice(s![0..count, ..])
                .map_err(|_| self.err("mesh/nodes: data unreadable (damaged)"))?;
            let flat = self.finite(sp::NODES, a.iter().copied().collect())?;
            Ok(flat.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect())
        })
    }

    /// Tet connectivity, `nodes_per_tet` (4 or 10) indices per tet, all below the node count and
    /// distinct within a tet.
    pub fn tets(&self) -> Result<Vec<u32>, ReadError> {
        self.guard(|| {
            let v = self.read_all::<u32>(sp::TETS, 2)?;
            let v = self.indices(sp::TETS, v, self.node_count)?;
            let per = self.kind.nodes();
            checks::tets(&v, per).map_err(|m| self.err(format!("{}: {m}; the file is damaged", sp::TETS)))?;
            Ok(v)
        })
    }

    /// Surface triangles, on three distinct corner vertices each.
    pub fn surface_triangles(&self) -> Result<Vec<[u32; 3]>, ReadError> {
        self.guard(|| {
            let v = self.read_all::<u32>(sp::SURFACE_TRIANGLES, 2)?;
            let v = self.indices(sp::SURFACE_TRIANGLES, v, self.vertex_count)?;
            checks::triangles(&v)
                .map_err(|m| self.err(format!("{}: {m}; the file is damaged", sp::SURFACE_TRIANGLES)))?;
            Ok(v.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect())
        })
    }

    /// The CAD face of each surface triangle (0: unknown), one per triangle, when the file has
    /// them (files written before them do not).
    pub fn surface_faces(&self) -> Result<Option<Vec<u32>>, ReadError> {
        self.guard(|| {
            if !self.has_dataset(sp::SURFACE_FACES)? {
                return Ok(None);
            }
            // Deflated: its extent is checked against the triangles' before it is read.
            let got = self.shape::<u32>(sp::SURFACE_FACES, 1)?[0];
            if got != self.triangle_count {
                return Err(self.err(format!(
                    "{} holds {got} tags for {} surface triangles; the file is damaged",
                    sp::SURFACE_FACES,
                    self.triangle_count
                )));
            }
            Ok(Some(self.read_all::<u32>(sp::SURFACE_FACES, 1)?))
        })
    }

    /// Supported DOFs (3i+c), below 3n.
    pub fn fixed_dofs(&self) -> Result<Vec<u32>, ReadError> {
        self.guard(|| {
            let v = self.read_all::<u32>(sp::FIXED_DOFS, 1)?;
            self.indices(sp::FIXED_DOFS, v, 3 * self.node_count)
        })
    }

    /// Eigenvalues and frequencies, read together so that neither is used unchecked against the
    /// other: λ finite, > 0 and ascending; f = √λ/2π.
    fn modal(&self) -> Result<(Vec<f64>, Vec<f64>), ReadError> {
        let lam = self.finite(sp::EIGENVALUES, self.read_all(sp::EIGENVALUES, 1)?)?;
        checks::eigenvalues(&lam).map_err(|m| self.err(format!("{}: {m}; the file is damaged", sp::EIGENVALUES)))?;
        let hz = self.finite(sp::FREQUENCIES_HZ, self.read_all(sp::FREQUENCIES_HZ, 1)?)?;
        checks::frequencies(&lam, &hz)
            .map_err(|m| self.err(format!("{}: {m}; the file is damaged", sp::FREQUENCIES_HZ)))?;
        Ok((lam, hz))
    }

    /// Elastic eigenvalues λ = ω², finite, positive, ascending, agreeing with the frequencies.
    pub fn eigenvalues(&self) -> Result<Vec<f64>, ReadError> {
        self.guard(|| self.modal().map(|m| m.0))
    }

    /// Frequencies, Hz: √λ/2π of the checked eigenvalues.
    pub fn frequencies_hz(&self) -> Result<Vec<f64>, ReadError> {
        self.guard(|| self.modal().map(|m| m.1))
    }

    /// Relative residuals, finite and ≥ 0.
    pub fn relative_residuals(&self) -> Result<Vec<f64>, ReadError> {
        self.guard(|| {
            let v = self.finite(sp::RELATIVE_RESIDUALS, self.read_all(sp::RELATIVE_RESIDUALS, 1)?)?;
            match v.iter().position(|&x| x < 0.0) {
                Some(i) => Err(self.err(format!(
                    "{} holds {} at entry {i}: a residual norm is ≥ 0; the file is damaged",
                    sp::RELATIVE_RESIDUALS,
                    v[i]
                ))),
                None => Ok(v),
            }
        })
    }

    /// The modal stress of the first `cols` modes at corner vertices `vertices`, row-major
    /// [6·|vertices|, cols] (row 6i+k: component k of the i-th vertex asked), finite; None when
    /// the file has no stress.
    pub fn stress_rows(&self, vertices: Range<usize>, cols: usize) -> Result<Option<Vec<f64>>, ReadError> {
        self.guard(|| {
            if !self.has_dataset(sp::STRESS)? {
                return Ok(None);
            }
            let (ds, shape) = self.dataset::<f64>(sp::STRESS, 2)?;
            if shape != [6 * self.vertex_count, self.mode_count] {
                return Err(self.err(format!(
                    "{} has shape {shape:?}, expected [{}, {}] (6 per corner vertex, one column per mode)",
                    sp::STRESS,
                    6 * self.vertex_count,
                    self.mode_count
                )));
            }
            if vertices.end > self.vertex_count || vertices.start > vertices.end || cols > self.mode_count {
                return Err(self.err(format!(
                    "stress of vertices {vertices:?} × {cols} modes asked of {} × {}",
                    self.vertex_count, self.mode_count
                )));
            }
            self.charge::<f64>(sp::STRESS, &ds, &shape, 6 * vertices.len() * cols)?;
            let block: ndarray::Array2<f64> = ds
                .read_slice(ndarray::s![6 * vertices.start..6 * vertices.end, 0..cols])
                .map_err(|e| self.err(format!("{}: {e}", sp::STRESS)))?;
            let v: Vec<f64> = block.iter().copied().collect();
            self.finite(sp::STRESS, v).map(Some)
        })
    }

    /// What each support carries per unit modal coordinate, when the file has it (held parts
    /// written since issue 43): the points the moments are about ([s]) and the row-major
    /// [6·s, r] reactions ([`sp::SUPPORT_REACTIONS`]); both checked for shape and finiteness.
    pub fn support_reactions(&self) -> Result<Option<SupportReactions>, ReadError> {
        self.guard(|| {
            let (has, centred) = (
                self.has_dataset(sp::SUPPORT_REACTIONS)?,
                self.has_dataset(sp::SUPPORT_CENTRES)?,
            );
            if !has && !centred {
                return Ok(None);
            }
            if has != centred {
                return Err(self.err(format!(
                    "{} and {} come together, and only one is there; the file is damaged",
                    sp::SUPPORT_REACTIONS,
                    sp::SUPPORT_CENTRES
                )));
            }
            let shape = self.shape::<f64>(sp::SUPPORT_REACTIONS, 2)?;
            let centres = self.shape::<f64>(sp::SUPPORT_CENTRES, 2)?;
            let s = centres[0];
            // A scene holds at most 64 KiB of text, so far fewer supports than this.
            if shape != [6 * s, self.mode_count] || centres[1] != 3 || s > MAX_SUPPORTS {
                return Err(self.err(format!(
                    "{} is {shape:?} and {} {centres:?}: expected [6·s, {}] and [s, 3] with s ≤ {MAX_SUPPORTS}; \
                     the file is damaged",
                    sp::SUPPORT_REACTIONS,
                    sp::SUPPORT_CENTRES,
                    self.mode_count
                )));
            }
            let per_mode = self.finite(sp::SUPPORT_REACTIONS, self.read_all(sp::SUPPORT_REACTIONS, 2)?)?;
            let c = self.finite(sp::SUPPORT_CENTRES, self.read_all(sp::SUPPORT_CENTRES, 2)?)?;
            Ok(Some((
                c.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect(),
                per_mode,
            )))
        })
    }

    /// Each support's reaction per newton of a static load at surface corner vertices, when
    /// the file has it ([`sp::SUPPORT_INFLUENCE`]): the vertices (strictly ascending, below the
    /// corner vertex count) and the row-major [q, 18·s] values, s the supports of
    /// [`SpaceReader::support_reactions`]; extents checked before anything is read.
    pub fn support_influence(&self) -> Result<Option<SupportInfluence>, ReadError> {
        self.guard(|| {
            let (has, listed) = (
                self.has_dataset(sp::SUPPORT_INFLUENCE)?,
                self.has_dataset(sp::SUPPORT_INFLUENCE_NODES)?,
            );
            if !has && !listed {
                return Ok(None);
            }
            let bad = |what: String| Err(self.err(format!("{what}; the file is damaged")));
            if has != listed || !self.has_dataset(sp::SUPPORT_CENTRES)? {
                return bad(format!(
                    "{} and {} come together, and with {}",
                    sp::SUPPORT_INFLUENCE,
                    sp::SUPPORT_INFLUENCE_NODES,
                    sp::SUPPORT_REACTIONS
                ));
            }
            let s = self.shape::<f64>(sp::SUPPORT_CENTRES, 2)?[0];
            let shape = self.shape::<f64>(sp::SUPPORT_INFLUENCE, 2)?;
            let q = self.shape::<u32>(sp::SUPPORT_INFLUENCE_NODES, 1)?[0];
            if s > MAX_SUPPORTS || q > self.vertex_count || shape != [q, 18 * s] {
                return bad(format!(
                    "{} is {shape:?} for {q} vertices and {s} supports: expected [q, 18·s] with q ≤ {} \
                     corner vertices",
                    sp::SUPPORT_INFLUENCE,
                    self.vertex_count
                ));
            }
            let nodes = self.read_all::<u32>(sp::SUPPORT_INFLUENCE_NODES, 1)?;
            let nodes = self.indices(sp::SUPPORT_INFLUENCE_NODES, nodes, self.vertex_count)?;
            if nodes.windows(2).any(|w| w[0] >= w[1]) {
                return bad(format!("{} is not strictly ascending", sp::SUPPORT_INFLUENCE_NODES));
            }
            let values = self.finite(sp::SUPPORT_INFLUENCE, self.read_all(sp::SUPPORT_INFLUENCE, 2)?)?;
            Ok(Some((nodes, values)))
        })
    }

    /// Each mode's estimated relative discretization error, when the file has it: one
    /// non-negative value per mode (NaN where a mode had no estimate).
    pub fn estimated_relative_error(&self) -> Result<Option<Vec<f64>>, ReadError> {
        self.guard(|| {
            if !self.has_dataset(sp::ESTIMATED_RELATIVE_ERROR)? {
                return Ok(None);
            }
            self.expect_len::<f64>(sp::ESTIMATED_RELATIVE_ERROR, self.mode_count, "modes")?;
            let v: Vec<f64> = self.read_all(sp::ESTIMATED_RELATIVE_ERROR, 1)?;
            if v.len() != self.mode_count || v.iter().any(|e| *e < 0.0 || e.is_infinite()) {
                return Err(self.err(format!(
                    "{} holds {} values for {} modes, or a negative or infinite one",
                    sp::ESTIMATED_RELATIVE_ERROR,
                    v.len(),
                    self.mode_count
                )));
            }
            Ok(Some(v))
        })
    }

    /// Rows `rows` of the first `cols` modes, row-major (`out[k·cols + j]`), finite.
    pub fn basis_rows(&self, rows: Range<usize>, cols: usize) -> Result<Vec<f64>, ReadError> {
        self.basis_block(rows, 0..cols)
    }

    /// The three rows of each of `nodes` (in the order given) × the first `cols` modes,
    /// row-major (`out[(3k + c)·cols + j]` for `nodes[k]`), finite; read in blocks of nearby rows.
    pub fn node_rows(&self, nodes: &[u32], cols: usize) -> Result<Vec<f64>, ReadError> {
        const BLOCK_VALUES: usize = 1 << 20;
        let mut sorted: Vec<u32> = nodes.to_vec();
        sorted.sort_unstable();
        sorted.dedup();
        if let Some(&v) = sorted.last().filter(|&&v| v as usize >= self.node_count) {
            return Err(self.err(format!("node {v} asked of {} nodes", self.node_count)));
        }
        let span = (BLOCK_VALUES / (3 * cols.max(1))).max(1);
        let mut found: Vec<f64> = Vec::with_capacity(3 * cols * sorted.len());
        let mut k = 0;
        while k < sorted.len() {
            let lo = sorted[k] as usize;
            let end = sorted[k..].partition_point(|&v| (v as usize) < lo + span) + k;
            let hi = sorted[end - 1] as usize + 1;
            let block = self.basis_block(3 * lo..3 * hi, 0..cols)?;
            for &v in &sorted[k..end] {
                let at = 3 * (v as usize - lo) * cols;
                found.extend_from_slice(&block[at..at + 3 * cols]);
            }
            k = end;
        }
        let mut out = Vec::with_capacity(3 * cols * nodes.len());
        for v in nodes {
            let i = sorted.binary_search(v).unwrap_or(0);
            out.extend_from_slice(&found[3 * cols * i..3 * cols * (i + 1)]);
        }
        Ok(out)
    }

    /// Rows `rows` × modes `cols` of the basis, row-major, finite.
    fn basis_block(&self, rows: Range<usize>, cols: Range<usize>) -> Result<Vec<f64>, ReadError> {
        self.guard(|| {
            if rows.end > 3 * self.node_count || rows.start > rows.end || cols.is_empty() || cols.end > self.mode_count
            {
                return Err(self.err(format!(
                    "rows {rows:?} × modes {cols:?} asked of a {} × {} basis",
                    3 * self.node_count,
                    self.mode_count
                )));
            }
            let (ds, shape) = self.dataset::<f64>(sp::BASIS, 2)?;
            self.charge::<f64>(sp::BASIS, &ds, &shape, rows.len() * cols.len())?;
            let a: ndarray::Array2<f64> = ds
                .read_slice(s![rows, cols])
                .map_err(|_| self.err("modes/basis: data unreadable (damaged)"))?;
            self.finite(sp::BASIS, a.iter().copied().collect())
        })
    }

    /// Checks that rows `rows` × modes `cols` are finite, streaming a block of rows at a time so
    /// the memory used stays small.
    fn check_block_finite(&self, rows: Range<usize>, cols: Range<usize>) -> Result<(), ReadError> {
        const BLOCK_VALUES: usize = 1 << 20;
        if rows.is_empty() || cols.is_empty() {
            return Ok(());
        }
        let step = (BLOCK_VALUES / cols.len()).max(1);
        let mut start = rows.start;
        while start < rows.end {
            let end = (start + step).min(rows.end);
            self.basis_block(start..end, cols.clone()).map_err(|e| ReadError {
                message: format!("{} (rows {start}..{end})", e.message),
                ..e
            })?;
            start = end;
        }
        Ok(())
    }

    /// Checks that every value of the whole basis is finite.
    pub fn check_basis_finite(&self) -> Result<(), ReadError> {
        self.check_block_finite(0..3 * self.node_count, 0..self.mode_count)
    }

    /// Static compliance: node indices (below n) and their 3×3 blocks, if stored. Each block is
    /// finite, symmetric, zero in the supported components' rows and columns, positive definite
    /// in the others, and below [`checks::MAX_DIMENSIONLESS_COMPLIANCE`] / (E·L).
    pub fn compliance(&self) -> Result<Option<crate::Compliance>, ReadError> {
        self.guard(|| {
            if self.optional_group(sp::COMPLIANCE)?.is_none() {
                return Ok(None);
            }
            let nodes = self.read_all::<u32>(sp::COMPLIANCE_NODES, 1)?;
            let nodes = self.indices(sp::COMPLIANCE_NODES, nodes, self.node_count)?;
            let (_, shape) = self.dataset::<f64>(sp::COMPLIANCE_BLOCKS, 3)?;
            if shape != [nodes.len(), 3, 3] {
                return Err(self.err(format!(
                    "compliance/blocks has shape {shape:?} for {} nodes",
                    nodes.len()
                )));
            }
            let flat = self.finite(sp::COMPLIANCE_BLOCKS, self.read_all(sp::COMPLIANCE_BLOCKS, 3)?)?;
            let blocks: Vec<crate::Block3> = flat
                .chunks_exact(9)
                .map(|b| std::array::from_fn(|a| std::array::from_fn(|c| b[3 * a + c])))
                .collect();
            let mut supported = vec![false; 3 * self.node_count];
            for d in self.fixed_dofs()? {
                supported[d as usize] = true;
            }
            let young = self.file.material()?.young;
            let size = self.size()?;
            for (k, (&node, b)) in nodes.iter().zip(&blocks).enumerate() {
                let free = std::array::from_fn(|c| !supported[3 * node as usize + c]);
                let bad = |m: String| {
                    self.err(format!(
                        "{} block {k} (node {node}): {m}; the file is damaged",
                        sp::COMPLIANCE_BLOCKS
                    ))
                };
                let c = checks::symmetric_positive_definite(b, free).map_err(|e| bad(e.to_string()))?;
                let dimensionless = c * young * size;
                if dimensionless.is_nan() || dimensionless > checks::MAX_DIMENSIONLESS_COMPLIANCE {
                    return Err(bad(format!(
                        "compliance {c:e} m/N is {dimensionless:.1e} / (E·L) with E {young:e} Pa and the part's size L \
                         {size:e} m, above {:e}: no elastic part is so soft",
                        checks::MAX_DIMENSIONLESS_COMPLIANCE
                    )));
                }
            }
            Ok(Some((nodes, blocks)))
        })
    }

    /// What a hand feels wrong at surface vertices, if stored: as many entries in each dataset
    /// (at most one per corner vertex, checked before reading), vertices strictly ascending and
    /// below the corner count, truncations in [0, 1], mesh errors finite and ≥ 0.
    pub fn felt(&self) -> Result<Option<crate::FeltErrors>, ReadError> {
        self.guard(|| {
            let Some(group) = self.optional_group(sp::FELT)? else {
                return Ok(None);
            };
            let modes = scalar_attr::<u32>(&group, sp::FELT_MODES)
                .filter(|&m| m >= 1)
                .ok_or_else(|| self.err("felt/ has no modes attribute (≥ 1); the file is damaged"))?;
            let p = self.shape::<u32>(sp::FELT_NODES, 1)?[0];
            let t = self.shape::<f64>(sp::FELT_TRUNCATION, 1)?[0];
            let e = self.shape::<f64>(sp::FELT_MESH_ERROR, 1)?[0];
            if p > self.vertex_count || t != p || e != p {
                return Err(self.err(format!(
                    "felt/ holds {p} vertices, {t} truncations and {e} mesh errors for {} corner vertices; \
                     the file is damaged",
                    self.vertex_count
                )));
            }
            let nodes = self.read_all::<u32>(sp::FELT_NODES, 1)?;
            let nodes = self.indices(sp::FELT_NODES, nodes, self.vertex_count)?;
            if nodes.windows(2).any(|w| w[0] >= w[1]) {
                return Err(self.err("felt/nodes is not strictly ascending; the file is damaged"));
            }
            let truncation = self.finite(sp::FELT_TRUNCATION, self.read_all(sp::FELT_TRUNCATION, 1)?)?;
            if let Some(k) = truncation.iter().position(|&a| !(0.0..=1.0).contains(&a)) {
                return Err(self.err(format!(
                    "felt/truncation entry {k} is {}, outside [0, 1]; the file is damaged",
                    truncation[k]
                )));
            }
            let mesh_error = self.finite(sp::FELT_MESH_ERROR, self.read_all(sp::FELT_MESH_ERROR, 1)?)?;
            if let Some(k) = mesh_error.iter().position(|&e| e < 0.0) {
                return Err(self.err(format!(
                    "felt/mesh_error entry {k} is {}, below 0; the file is damaged",
                    mesh_error[k]
                )));
            }
            Ok(Some(crate::FeltErrors {
                modes,
                nodes,
                truncation,
                mesh_error,
            }))
        })
    }

    /// The hand's contact patches, if stored, checked ([`crate::Contact::check`]).
    pub fn contact(&self) -> Result<Option<crate::Contact>, ReadError> {
        self.guard(|| {
            let Some(group) = self.optional_group(sp::CONTACT)? else {
                return Ok(None);
            };
            let radius = scalar_attr::<f64>(&group, sp::CONTACT_RADIUS)
                .ok_or_else(|| self.err("contact/ has no radius attribute; the file is damaged"))?;
            // Extents against each other and the mesh before anything is read: one centre per
            // corner vertex at most, one more offset than centres, a weight per node.
            let p = self.shape::<u32>(sp::CONTACT_CENTRES, 1)?[0];
            if p > self.vertex_count {
                return Err(self.err(format!(
                    "{} holds {p} centres for {} corner vertices; the file is damaged",
                    sp::CONTACT_CENTRES,
                    self.vertex_count
                )));
            }
            self.expect_len::<u32>(sp::CONTACT_OFFSETS, p + 1, "centres + 1")?;
            let nnz = self.shape::<u32>(sp::CONTACT_NODES, 1)?[0];
            self.expect_len::<f64>(sp::CONTACT_WEIGHTS, nnz, &format!("nodes of {}", sp::CONTACT_NODES))?;
            let contact = crate::Contact {
                radius,
                centres: self.read_all(sp::CONTACT_CENTRES, 1)?,
                offsets: self.read_all(sp::CONTACT_OFFSETS, 1)?,
                nodes: self.read_all(sp::CONTACT_NODES, 1)?,
                weights: self.read_all(sp::CONTACT_WEIGHTS, 1)?,
            };
            contact
                .check(self.kind, self.vertex_count, self.node_count)
                .map_err(|m| self.err(format!("{}: {m}; the file is damaged", sp::CONTACT)))?;
            Ok(Some(contact))
        })
    }

    /// Mass properties of a part that can move as a whole, if stored (mass > 0, all finite),
    /// with the rigid motions its supports leave free. `None` too for a part held in some
    /// directions whose file does not say which motions are free (written before
    /// [`sp::FREE_MOTIONS`]): it is then simulated held in place rather than wholly free.
    pub fn rigid(&self) -> Result<Option<RigidProperties>, ReadError> {
        self.guard(|| {
            let Some(g) = self.optional_group(sp::RIGID)? else {
                return Ok(None);
            };
            let Some(free) = self.free_motions()? else {
                return Ok(None);
            };
            let mass = scalar_attr::<f64>(&g, sp::MASS).filter(|m| m.is_finite() && *m > 0.0);
            let c = f64_array_attr(&g, sp::CENTER_OF_MASS, 3);
            let i = f64_array_attr(&g, sp::INERTIA, 9);
            match (mass, c, i) {
                (Some(mass), Some(c), Some(i)) => {
                    let inertia = [[i[0], i[1], i[2]], [i[3], i[4], i[5]], [i[6], i[7], i[8]]];
                    checks::symmetric_positive_definite(&inertia, [true; 3])
                        .map_err(|m| self.err(format!("rigid/ inertia: {m}; the file is damaged")))?;
                    Ok(Some(RigidProperties {
                        mass,
                        center: [c[0], c[1], c[2]],
                        inertia,
                        free,
                    }))
                }
                _ => Err(self.err("rigid/ mass, center_of_mass or inertia missing or not finite")),
            }
        })
    }

    /// The rigid motions the supports leave free ([`sp::FREE_MOTIONS`]): all six for a free
    /// body (the dataset absent), the stored twists for a part held in some directions (shape
    /// [rigid_modes_dropped, 6] checked before reading, finite, independent); `None` when
    /// nothing is free or the file does not say which motions are.
    fn free_motions(&self) -> Result<Option<crate::FreeMotions>, ReadError> {
        let name = format!("{}/{}", sp::RIGID, sp::FREE_MOTIONS);
        let k = self.rigid_modes_dropped as usize;
        let has = self.has_dataset(&name)?;
        let bad = |what: String| Err(self.err(format!("{name}: {what}; the file is damaged")));
        match (k, has) {
            (0, _) | (1..=5, false) => return Ok(None),
            (6, false) => return Ok(Some(crate::FreeMotions::all())),
            (6, true) => return bad("present for a free body, whose six rigid motions are all free".into()),
            _ => {}
        }
        let shape = self.shape::<f64>(&name, 2)?;
        if shape != [k, 6] {
            return bad(format!(
                "shape {shape:?}, expected [{k}, 6] (rigid_modes_dropped = {k})"
            ));
        }
        let v = self.finite(&name, self.read_all(&name, 2)?)?;
        let rows: Vec<[f64; 6]> = v.chunks_exact(6).map(|r| std::array::from_fn(|j| r[j])).collect();
        if !checks::independent(&rows) {
            return bad("its twists are not independent".into());
        }
        Ok(crate::FreeMotions::new(&rows))
    }

    /// The reduced nonlinear model ([`sp::NONLINEAR`]), when the space has one: the model's
    /// name checked, eigenmodes ≤ r ≤ [`names::MAX_NONLINEAR_BASIS`], both coefficient arrays of
    /// their exact shapes (checked before they are read), finite, H symmetric.
    pub fn nonlinear(&self) -> Result<Option<Nonlinear>, ReadError> {
        self.guard(|| {
            let Some(g) = self.optional_group(sp::NONLINEAR)? else {
                return Ok(None);
            };
            let r = self.mode_count;
            let model = crate::strings::read(&g, sp::NONLINEAR_MODEL);
            if model.as_deref() != Some("stvk") {
                return Err(self.err(format!(
                    "{}/{} is {model:?}; this reader knows \"stvk\" (a newer VES may have written it)",
                    sp::NONLINEAR,
                    sp::NONLINEAR_MODEL
                )));
            }
            let m = scalar_attr::<u32>(&g, sp::EIGENMODES).map(|m| m as usize);
            let d = scalar_attr::<u32>(&g, sp::DERIVATIVES_OF).map(|d| d as usize);
            let (Some(m), Some(d)) = (m, d) else {
                return Err(self.err(format!(
                    "{} lacks its u32 attributes {} and {}; the file is damaged",
                    sp::NONLINEAR,
                    sp::EIGENMODES,
                    sp::DERIVATIVES_OF
                )));
            };
            if m == 0 || m > r || d > m || r > names::MAX_NONLINEAR_BASIS {
                return Err(self.err(format!(
                    "{}: {m} eigenmodes, derivatives of {d}, {r} vectors: expected 0 < derivatives ≤ eigenmodes ≤ \
                     vectors ≤ {}; the file is damaged",
                    sp::NONLINEAR,
                    names::MAX_NONLINEAR_BASIS
                )));
            }
            let np = r * (r + 1) / 2;
            for (name, want) in [(sp::NONLINEAR_CUBIC, [r, np]), (sp::NONLINEAR_QUARTIC, [np, np])] {
                let shape = self.shape::<f64>(name, 2)?;
                if shape != want {
                    return Err(self.err(format!("{name} has shape {shape:?}, expected {want:?} (r = {r})")));
                }
            }
            let cubic = self.finite(sp::NONLINEAR_CUBIC, self.read_all(sp::NONLINEAR_CUBIC, 2)?)?;
            let quartic = self.finite(sp::NONLINEAR_QUARTIC, self.read_all(sp::NONLINEAR_QUARTIC, 2)?)?;
            let scale = quartic.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            for i in 0..np {
                for j in 0..i {
                    if (quartic[i * np + j] - quartic[j * np + i]).abs() > 1e-9 * scale {
                        return Err(self.err(format!(
                            "{} is not symmetric at ({i}, {j}); the file is damaged",
                            sp::NONLINEAR_QUARTIC
                        )));
                    }
                }
            }
            Ok(Some(Nonlinear {
                eigenmodes: m,
                derivatives_of: d,
                cubic,
                quartic,
            }))
        })
    }

    /// The state-transfer matrix from space `from`, its first `r_to × r_from` block row-major,
    /// when the file holds one: finite, each entry at most [`checks::MAX_TRANSFER`] in magnitude.
    pub fn transfer(&self, from: &str, r_to: usize, r_from: usize) -> Result<Option<Vec<f64>>, ReadError> {
        self.guard(|| {
            names::check_space_name(from).map_err(|m| self.err(format!("transfer: {m}")))?;
            let name = format!("{}/{from}", sp::TRANSFER);
            if self.optional_group(sp::TRANSFER)?.is_none() || !self.has_dataset(&name)? {
                return Ok(None);
            }
            let (ds, shape) = self.dataset::<f64>(&name, 2)?;
            if shape[0] != self.mode_count || shape[0] < r_to || shape[1] < r_from {
                return Err(self.err(format!(
                    "transfer from {from} has shape {shape:?}; expected {} rows and at least {r_from} columns",
                    self.mode_count
                )));
            }
            self.charge::<f64>(&name, &ds, &shape, r_to * r_from)?;
            let a: ndarray::Array2<f64> = ds
                .read_slice(s![0..r_to, 0..r_from])
                .map_err(|_| self.err(format!("{name}: data unreadable (damaged)")))?;
            let t = self.finite(&name, a.iter().copied().collect())?;
            if let Some(i) = t.iter().position(|x| x.abs() > checks::MAX_TRANSFER) {
                return Err(self.err(format!(
                    "{name} holds {:e} at row {}, column {}: a transfer between M-normalised modes has entries \
                     of at most about 1 (refused above {}); the file is damaged",
                    t[i],
                    i / r_from.max(1),
                    i % r_from.max(1),
                    checks::MAX_TRANSFER
                )));
            }
            Ok(Some(t))
        })
    }

    /// Checks every `transfer/<from>`: `from` a space of the file other than this one, the
    /// matrix [r, r_from] (the two spaces' mode counts), finite and in range.
    pub fn check_transfers(&self) -> Result<(), ReadError> {
        self.guard(|| {
            let Some(g) = self.optional_group(sp::TRANSFER)? else {
                return Ok(());
            };
            let count = usize::try_from(g.len()).unwrap_or(usize::MAX);
            if count > names::MAX_SPACES {
                return Err(self.err(format!(
                    "{} holds {count} matrices, more than {} spaces: refused before reading them",
                    sp::TRANSFER,
                    names::MAX_SPACES
                )));
            }
            let spaces = self.file.listed_spaces()?;
            let listed = g
                .member_names()
                .map_err(|_| self.err(format!("{} unreadable; the file is damaged", sp::TRANSFER)))?;
            for from in &listed {
                let name = format!("{}/{from}", sp::TRANSFER);
                if *from == self.name || !spaces.contains(from) {
                    return Err(self.err(format!(
                        "{name}: the file holds no other space \"{}\" to transfer from; the file is damaged",
                        names::escape_for_terminal(from)
                    )));
                }
                let r_from = self.file.space(from)?.mode_count;
                let shape = self.shape::<f64>(&name, 2)?;
                if shape != [self.mode_count, r_from] {
                    return Err(self.err(format!(
                        "{name} has shape {shape:?}, expected [{}, {r_from}] (the two spaces' mode counts); the file \
                         is damaged",
                        self.mode_count
                    )));
                }
                self.transfer(from, self.mode_count, r_from)?;
            }
            Ok(())
        })
    }

    /// Checks Rayleigh damping (α, β) against eigenvalues `lam` of this space
    /// ([`checks::damping`]).
    pub fn check_damping(&self, alpha: f64, beta: f64, lam: &[f64]) -> Result<(), ReadError> {
        checks::damping(alpha, beta, lam).map_err(|m| {
            self.file
                .err(format!("{}/{} and {}: {m}", mat::GROUP, mat::ALPHA, mat::BETA))
        })
    }

    /// Diagonal of the bounding box of the space's nodes, m.
    fn size(&self) -> Result<f64, ReadError> {
        let nodes = self.nodes(self.node_count)?;
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in &nodes {
            for c in 0..3 {
                lo[c] = lo[c].min(p[c]);
                hi[c] = hi[c].max(p[c]);
            }
        }
        Ok((0..3).map(|c| (hi[c] - lo[c]).powi(2)).sum::<f64>().sqrt())
    }

    /// Reads and checks everything in the space (the full basis streamed): what `ves info` and
    /// `ves verify` ask before they trust a file.
    pub fn validate(&self) -> Result<(), ReadError> {
        self.nodes(self.node_count)?;
        self.tets()?;
        self.surface_triangles()?;
        self.surface_faces()?;
        self.fixed_dofs()?;
        let lam = self.eigenvalues()?;
        let m = self.file.material()?;
        self.check_damping(m.alpha, m.beta, &lam)?;
        self.relative_residuals()?;
        self.check_basis_finite()?;
        self.compliance()?;
        self.rigid()?;
        self.estimated_relative_error()?;
        self.stress_rows(0..self.vertex_count, self.mode_count)?;
        self.fixed_mask()?;
        self.loads()?;
        self.support_reactions()?;
        self.support_influence()?;
        self.contact()?;
        self.felt()?;
        self.check_transfers()?;
        self.nonlinear()?;
        Ok(())
    }
}
