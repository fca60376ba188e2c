//! A cache of finished meshes, so that precomputing the same part again with another material,
//! support, mode count or damping — the everyday batch of scenarios — and the coarser meshes of
//! the error estimate skip gmsh entirely.
//!
//! Key: the geometry file's bytes (read once; gmsh meshes a private copy of the same bytes),
//! what shapes the mesh (unit, size, order, the VOI's box and size), the VES version and the
//! text of the meshing code itself (so any change to how meshes are made misses the old entries
//! without a version to bump). Entries live in `$VES_CACHE_DIR/meshes`, else
//! `$XDG_CACHE_HOME/ves/meshes`, else `~/.cache/ves/meshes`; `VES_MESH_CACHE=off` turns the
//! cache off. Each entry is one file with a checksum, written under a new temporary name and
//! renamed, so concurrent runs and threads never read half an entry or a mix of two; anything
//! else at an entry's path (damaged, truncated, a FIFO, a symlink) is a miss and is replaced. A
//! `.geo` script is never cached (it may read other files). gmsh itself is not in the key: a
//! rebuild against another gmsh should start from an empty cache.
//!
//! The METIS node orderings of the meshes solved live beside them (`*.order`, keyed by the
//! node graph): a rerun, or another support of the same mesh, skips METIS too; so does the mesh
//! a `target_error` refinement chose (`*.chosen`, [`super::remembered`]).

use super::{LADDER, Mesh, Meshing, Request, field, isolation};
use std::fs::File;
use std::io::{Read, Write};
use std::os::unix::fs::OpenOptionsExt;
use std::path::{Path, PathBuf};

/// The meshing code and the entries' format: part of every key.
const SOURCES: [&str; 4] = [
    include_str!("mod.rs"),
    include_str!("../../../numerics/src/tet_mesh/quality.rs"),
    include_str!("isolation.rs"),
    include_str!("cache.rs"),
];

/// First bytes of a mesh entry. Version 3 added the surface triangles' CAD faces; an entry of
/// an older version is a miss (meshed again and replaced), never read as this one.
const MAGIC: &[u8; 8] = b"VESMESH\x03";

/// What the description of an entry holds besides the mesh file.
#[derive(serde::Serialize, serde::Deserialize)]
struct Entry {
    meshing: Meshing,
    vertex_count: usize,
    order: u8,
}

pub(super) fn dir() -> Option<PathBuf> {
    if std::env::var("VES_MESH_CACHE").is_ok_and(|v| v.eq_ignore_ascii_case("off") || v == "0") {
        return None;
    }
    let base = std::env::var_os("VES_CACHE_DIR")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("XDG_CACHE_HOME").map(|d| PathBuf::from(d).join("ves")))
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache/ves")))?;
    Some(base.join("meshes"))
}

/// The entry a request would have, from `geometry`: the bytes of the geometry file that are
/// meshed (read once; the file itself may change meanwhile). None: not cacheable (a `.geo`
/// script), or the cache is off.
pub(super) fn key(req: &Request, geometry: &[u8]) -> Option<PathBuf> {
    let ext = req.geometry.extension()?.to_str()?.to_ascii_lowercase();
    if ext == "geo" {
        return None;
    }
    let shape = serde_json::to_string(&(
        req.unit,
        req.mesh.size,
        req.mesh.order,
        req.voi.as_ref().map(|v| (v.bbox, v.size)),
        req.field.as_ref().map(field::SizeField::fingerprint),
    ))
    .ok()?;
    let mut h = crate::fingerprint::Fingerprint::default();
    h.field(env!("CARGO_PKG_VERSION").as_bytes());
    for s in SOURCES {
        h.field(s.as_bytes());
    }
    // The extension too: it picks gmsh's reader.
    h.field(shape.as_bytes()).field(ext.as_bytes()).field(geometry);
    // Curved tets straightened without gmsh's smoother: another mesh (the default's keys
    // stay as they were).
    if !req.mesh.smooth_curved {
        h.field(b"straightened");
    }
    Some(dir()?.join(format!("{:016x}.mesh", h.value())))
}

/// Why [`read_entry`] gave up on an entry of an older format (a miss, not damage).
const OLDER: &str = "an entry of an older format";

/// Longest description accepted when reading an entry (a damaged length is not allocated).
const MAX_DESCRIPTION: u64 = 1 << 16;

/// What a lookup found.
pub(super) enum Found {
    /// A whole entry whose checksum matches.
    Hit(Mesh, Meshing),
    /// No entry.
    Absent,
    /// Something at the entry's path that is not a whole entry: why.
    Bad(String),
}

/// Checksum of an entry's content: FNV-1a, 64 bits, over every byte before it. Against
/// corruption and edits that do not also recompute it (every change of one byte is detected,
/// since each step of FNV-1a is a bijection of its state; other damage slips through with
/// probability 2⁻⁶⁴). Not against deliberate forgery: the cache is the user's own directory,
/// and anyone who can write it can write a matching checksum.
#[derive(Clone, Copy)]
struct Checksum(u64);

impl Checksum {
    const fn new() -> Self {
        Checksum(0xcbf2_9ce4_8422_2325)
    }
    fn update(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
}

/// A reader or writer that checksums what passes through it.
struct Summed<T> {
    inner: T,
    sum: Checksum,
}

impl<R: Read> Read for Summed<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.sum.update(&buf[..n]);
        Ok(n)
    }
}

impl<W: Write> Write for Summed<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.sum.update(&buf[..n]);
        Ok(n)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

/// Opens the cache file `path` if it is a regular file: never through a symlink, and never
/// blocking (a FIFO there would hang the run). Ok(None): nothing there.
pub(super) fn open_entry(path: &Path) -> Result<Option<(File, u64)>, String> {
    // O_NOFOLLOW: a symlink is refused (ELOOP); O_NONBLOCK: opening a FIFO returns at once.
    // The type is then checked on the open file, so a swap after a check cannot slip through.
    let file = match std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NOFOLLOW | libc::O_NONBLOCK)
        .open(path)
    {
        Ok(f) => f,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) if e.raw_os_error() == Some(libc::ELOOP) => return Err("a symbolic link, not an entry".into()),
        Err(e) => return Err(format!("cannot be opened: {e}")),
    };
    let meta = file.metadata().map_err(|e| format!("cannot be examined: {e}"))?;
    if !meta.file_type().is_file() {
        let kind = crate::input::kind(&meta).unwrap_or("not a file");
        return Err(format!("{kind}, not a regular file"));
    }
    Ok(Some((file, meta.len())))
}

/// The cached mesh of `key`: [`Found::Hit`] only for a whole entry with the right checksum.
pub(super) fn lookup(key: &Path) -> Found {
    let (file, size) = match open_entry(key) {
        Ok(Some(f)) => f,
        Ok(None) => return Found::Absent,
        Err(why) => return Found::Bad(why),
    };
    match read_entry(file, size) {
        Ok(found) => Found::Hit(found.0, found.1),
        Err(why) if why == OLDER => Found::Absent,
        Err(why) => Found::Bad(why),
    }
}

fn read_entry(file: File, size: u64) -> Result<(Mesh, Meshing), String> {
    let short = |e: std::io::Error| format!("truncated or unreadable ({size} bytes): {e}");
    let mut r = Summed {
        inner: std::io::BufReader::new(file),
        sum: Checksum::new(),
    };
    let mut word = [0u8; 8];
    r.read_exact(&mut word).map_err(short)?;
    if word[..7] == MAGIC[..7] && word[7] < MAGIC[7] {
        tracing::info!(
            "mesh cache entry of an older format (version {}): meshed again",
            word[7]
        );
        return Err(OLDER.into());
    }
    if &word != MAGIC {
        return Err("not a mesh entry of this version (wrong first bytes)".into());
    }
    r.read_exact(&mut word).map_err(short)?;
    let len = u64::from_le_bytes(word);
    // Magic, length, description, mesh, checksum.
    if len > MAX_DESCRIPTION || 8 + 8 + len + 8 > size {
        return Err(format!("a description of {len} bytes in a file of {size}"));
    }
    let mut text = vec![0u8; len as usize];
    r.read_exact(&mut text).map_err(short)?;
    let entry: Entry = serde_json::from_slice(&text).map_err(|e| format!("unreadable description: {e}"))?;
    let mesh = isolation::read_mesh_from(&mut r, size - 8 - 8 - len - 8, entry.vertex_count, entry.order)
        .map_err(|e| format!("damaged mesh: {e}"))?;
    let computed = r.sum.0;
    r.inner.read_exact(&mut word).map_err(short)?;
    if u64::from_le_bytes(word) != computed {
        return Err(format!(
            "checksum mismatch (stored {:016x}, content {computed:016x})",
            u64::from_le_bytes(word)
        ));
    }
    let mut meshing = entry.meshing;
    meshing.strategy = LADDER
        .get(meshing.rung)
        .ok_or_else(|| format!("no meshing rung {}", meshing.rung))?
        .name;
    Ok((mesh, meshing))
}

/// Stores a mesh under `key`; a failure only costs the next run its meshing (logged).
///
/// One file per entry (its description, then the mesh, then the checksum), written under a
/// name no other process or thread uses and renamed into place: a reader sees a whole entry or
/// none. (Two files, one renamed after the other, let a reader pair one run's description with
/// another run's mesh while both stored the same key: gmsh's meshes of one input can differ
/// between runs.)
pub(super) fn store(key: &Path, mesh: &Mesh, meshing: &Meshing) {
    let entry = Entry {
        meshing: *meshing,
        vertex_count: mesh.vertex_count,
        order: mesh.kind.order(),
    };
    write_atomically(key, |w| {
        let text = serde_json::to_vec(&entry).map_err(std::io::Error::other)?;
        let mut s = Summed {
            inner: &mut *w,
            sum: Checksum::new(),
        };
        s.write_all(MAGIC)?;
        s.write_all(&(text.len() as u64).to_le_bytes())?;
        s.write_all(&text)?;
        isolation::write_mesh_to(&mut s, mesh)?;
        let sum = s.sum.0;
        w.write_all(&sum.to_le_bytes())
    });
}

/// Writes `key` through the one atomic writer of every output (a fresh temporary created
/// exclusively, never through a planted link, then renamed); temporaries that killed runs left
/// beside it are removed first. A failure only costs the next run the work (logged).
pub(super) fn write_atomically(key: &Path, body: impl FnOnce(&mut std::io::BufWriter<File>) -> std::io::Result<()>) {
    let result = (|| -> anyhow::Result<()> {
        if let Some(d) = key.parent() {
            std::fs::create_dir_all(d)?;
        }
        crate::output::remove_stale_temps(key);
        crate::output::write_atomically(key, |tmp| {
            let file = std::fs::OpenOptions::new()
                .write(true)
                .custom_flags(libc::O_NOFOLLOW)
                .open(tmp)?;
            let mut w = std::io::BufWriter::new(file);
            body(&mut w)?;
            w.flush()?;
            Ok(())
        })?;
        Ok(())
    })();
    if let Err(e) = result {
        tracing::info!("cache: cannot store {}: {e:#}", key.display());
    }
}

/// The key of a node graph's (CSR `xadj`, `adj`) fill-reducing ordering: the graph itself and
/// the ordering code, so the same mesh with other supports (a batch of scenarios, a rerun) skips
/// METIS. None when the cache is off.
fn ordering_hash(xadj: &[i32], adj: &[i32]) -> Option<u64> {
    dir()?;
    let bytes = |v: &[i32]| -> Vec<u8> { v.iter().flat_map(|x| x.to_le_bytes()).collect() };
    let mut h = crate::fingerprint::Fingerprint::default();
    h.field(env!("CARGO_PKG_VERSION").as_bytes())
        .field(include_str!("../../../numerics/src/linsolve.rs").as_bytes())
        .field(&bytes(xadj))
        .field(&bytes(adj));
    Some(h.value())
}

/// Where the ordering of key `hash` is cached: beside the meshes.
fn ordering_path(hash: u64) -> Option<PathBuf> {
    Some(dir()?.join(format!("{hash:016x}.order")))
}

/// The cached ordering under `key`: a permutation of 0..n, else None.
pub(crate) fn ordering_lookup(key: &std::path::Path, n: usize) -> Option<Vec<i32>> {
    let (file, size) = match open_entry(key) {
        Ok(Some(f)) => f,
        Ok(None) => return None,
        Err(why) => {
            tracing::warn!("{}: damaged cache entry ignored ({why}); it is replaced", key.display());
            return None;
        }
    };
    // The size first: nothing is read from (or allocated for) a file of another length.
    if size != 4 * n as u64 {
        return None;
    }
    let mut bytes = Vec::with_capacity(4 * n);
    file.take(size).read_to_end(&mut bytes).ok()?;
    if bytes.len() != 4 * n {
        return None;
    }
    let order: Vec<i32> = bytes
        .chunks_exact(4)
        .map(|c| i32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    let mut seen = vec![false; n];
    for &v in &order {
        let slot = usize::try_from(v).ok().and_then(|v| seen.get_mut(v))?;
        if std::mem::replace(slot, true) {
            return None;
        }
    }
    Some(order)
}

/// Stores an ordering under `key`.
pub(crate) fn ordering_store(key: &std::path::Path, order: &[i32]) {
    write_atomically(key, |w| order.iter().try_for_each(|v| w.write_all(&v.to_le_bytes())));
}

/// The cache as the solvers' [`crate::linsolve::OrderingStore`].
pub(crate) struct Orderings;

impl crate::linsolve::OrderingStore for Orderings {
    fn key(&self, xadj: &[i32], adj: &[i32]) -> Option<u64> {
        ordering_hash(xadj, adj)
    }

    fn lookup(&self, key: u64, n: usize) -> Option<Vec<i32>> {
        ordering_lookup(&ordering_path(key)?, n)
    }

    fn store(&self, key: u64, order: &[i32]) {
        if let Some(p) = ordering_path(key) {
            ordering_store(&p, order);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Threads storing two different meshes under one key (as two runs of one part can, since
    /// gmsh's meshes of one input differ) while another thread reads: every entry read is one
    /// of the two meshes whole, never one's description with the other's nodes.
    #[test]
    fn concurrent_stores_of_one_key_are_read_whole() {
        let a = Mesh::structured_box([3, 1, 1], 0.01, crate::fem::element::Kind::Tet10, |_, p| p);
        let b = Mesh::structured_box([5, 2, 1], 0.01, crate::fem::element::Kind::Tet10, |_, p| p);
        let meshing = Meshing::default();
        let dir = tempfile::tempdir().unwrap();
        let key = dir.path().join("0123456789abcdef.mesh");
        let whole = |m: &Mesh| {
            [&a, &b]
                .iter()
                .any(|x| x.nodes == m.nodes && x.tets == m.tets && x.vertex_count == m.vertex_count)
        };
        let writing = std::sync::atomic::AtomicUsize::new(4);
        std::thread::scope(|s| {
            for m in [&a, &b, &a, &b] {
                let (writing, key, meshing) = (&writing, &key, &meshing);
                s.spawn(move || {
                    for _ in 0..50 {
                        store(key, m, meshing);
                    }
                    writing.fetch_sub(1, std::sync::atomic::Ordering::Release);
                });
            }
            // Reads for as long as anyone writes (however the threads are scheduled).
            s.spawn(|| {
                while writing.load(std::sync::atomic::Ordering::Acquire) > 0 {
                    if let Found::Hit(m, _) = lookup(&key) {
                        assert!(
                            whole(&m),
                            "a mixed entry: {} vertices, {} nodes",
                            m.vertex_count,
                            m.nodes.len()
                        );
                    }
                }
            });
        });
        // After the writers, the entry is there and whole.
        let Found::Hit(last, _) = lookup(&key) else {
            panic!("the entry is not readable after the writers")
        };
        assert!(whole(&last));
        let left: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(left.len(), 1, "temporary files left: {left:?}");
    }

    fn stored(dir: &Path) -> (PathBuf, Mesh) {
        let m = Mesh::structured_box([3, 1, 1], 0.01, crate::fem::element::Kind::Tet10, |_, p| p);
        let key = dir.join("0123456789abcdef.mesh");
        store(&key, &m, &Meshing::default());
        (key, m)
    }

    fn bad(found: Found) -> String {
        match found {
            Found::Bad(why) => why,
            Found::Hit(m, _) => panic!("read as an entry: {} nodes, x₀ = {}", m.nodes.len(), m.nodes[0][0]),
            Found::Absent => panic!("read as absent"),
        }
    }

    /// An entry edited by hand (a coordinate doubled: one byte of its exponent) or cut short
    /// is not used: its checksum or its length says so.
    #[test]
    fn an_edited_or_truncated_entry_is_bad() {
        let dir = tempfile::tempdir().unwrap();
        let (key, m) = stored(dir.path());
        assert!(matches!(lookup(&key), Found::Hit(..)));
        let good = std::fs::read(&key).unwrap();
        // The last node's x: doubling it adds one to the exponent (bytes 6-7 of the f64).
        let len = u64::from_le_bytes(good[8..16].try_into().unwrap()) as usize;
        let x = 16 + len + 24 + 24 * (m.nodes.len() - 1);
        let mut edited = good.clone();
        let doubled = (f64::from_le_bytes(good[x..x + 8].try_into().unwrap()) * 2.0).to_le_bytes();
        assert_ne!(m.nodes.last().unwrap()[0], 0.0);
        edited[x..x + 8].copy_from_slice(&doubled);
        std::fs::write(&key, &edited).unwrap();
        assert!(bad(lookup(&key)).contains("checksum"));
        std::fs::write(&key, &good[..good.len() - 3]).unwrap();
        bad(lookup(&key));
    }

    /// A header that claims 2^62 more tet indices than it holds: 4 bytes each, the extra
    /// 2^64 bytes wrap around to a size that matches (it ended in "capacity overflow"). Refused
    /// from the file's size, not allocated.
    #[test]
    fn a_huge_count_in_an_entry_is_bad_not_an_allocation() {
        let dir = tempfile::tempdir().unwrap();
        let key = dir.path().join("0123456789abcdef.mesh");
        store(
            &key,
            &Mesh::structured_box([3, 1, 1], 0.01, crate::fem::element::Kind::Tet4, |_, p| p),
            &Meshing::default(),
        );
        let mut bytes = std::fs::read(&key).unwrap();
        let len = u64::from_le_bytes(bytes[8..16].try_into().unwrap()) as usize;
        let at = 16 + len + 8;
        let tets = u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap());
        bytes[at..at + 8].copy_from_slice(&(tets + (1u64 << 62)).to_le_bytes());
        std::fs::write(&key, &bytes).unwrap();
        bad(lookup(&key));
    }

    /// A FIFO, a symlink or a directory at an entry's path is a bad entry, found at once (a
    /// regression that blocks on the FIFO fails here after 10 s instead of hanging the suite).
    #[test]
    fn a_fifo_symlink_or_directory_at_an_entry_is_bad_without_blocking() {
        let dir = tempfile::tempdir().unwrap();
        let (good, _) = stored(dir.path());
        let fifo = dir.path().join("fifo.mesh");
        crate::make_fifo(&fifo);
        let link = dir.path().join("link.mesh");
        std::os::unix::fs::symlink(&good, &link).unwrap();
        let sub = dir.path().join("dir.mesh");
        std::fs::create_dir(&sub).unwrap();
        for (path, what) in [(fifo, "regular"), (link, "symbolic link"), (sub, "regular")] {
            let (tx, rx) = std::sync::mpsc::channel();
            let p = path.clone();
            std::thread::spawn(move || {
                let _ = tx.send(bad(lookup(&p)));
            });
            let why = rx
                .recv_timeout(std::time::Duration::from_secs(10))
                .unwrap_or_else(|_| panic!("lookup of {} blocked", path.display()));
            assert!(why.contains(what), "{why}");
        }
        // The ordering cache opens its files the same way.
        let order = dir.path().join("fifo.order");
        crate::make_fifo(&order);
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let _ = tx.send(ordering_lookup(&order, 4));
        });
        let found = rx.recv_timeout(std::time::Duration::from_secs(10));
        assert_eq!(found, Ok(None), "the ordering lookup blocked on a FIFO");
    }

    /// Symlinks planted at the temporary names a process could predict (a shared cache) are
    /// left alone: the file they point to is not written, and the entry is stored beside them.
    #[test]
    fn a_symlink_planted_at_the_temporary_name_is_not_followed() {
        let dir = tempfile::tempdir().unwrap();
        let victim = dir.path().join("victim");
        std::fs::write(&victim, b"someone else's file").unwrap();
        let key = dir.path().join("0123456789abcdef.mesh");
        // Predictable names: this process's, with serial numbers, and the older `.tmp<pid>`.
        let pid = std::process::id();
        for s in 0..500 {
            std::os::unix::fs::symlink(&victim, key.with_extension(format!("tmp{pid}.{s}"))).unwrap();
        }
        std::os::unix::fs::symlink(&victim, key.with_extension(format!("tmp{pid}"))).unwrap();
        let m = Mesh::structured_box([3, 1, 1], 0.01, crate::fem::element::Kind::Tet4, |_, p| p);
        store(&key, &m, &Meshing::default());
        assert_eq!(std::fs::read(&victim).unwrap(), b"someone else's file");
        assert!(std::fs::symlink_metadata(&key).unwrap().file_type().is_file());
        assert!(matches!(lookup(&key), Found::Hit(..)));
    }

    /// The surface triangles' CAD faces are part of an entry; an entry of the previous format
    /// (`VESMESH\x02`, no tags) is a miss, not a damaged entry and never a mesh without tags.
    #[test]
    fn tags_are_stored_and_an_entry_of_the_older_format_is_a_miss() {
        let dir = tempfile::tempdir().unwrap();
        let key = dir.path().join("0123456789abcdef.mesh");
        let mut m = Mesh::structured_box([3, 1, 1], 0.01, crate::fem::element::Kind::Tet10, |_, p| p);
        for (k, t) in m.surface_faces.iter_mut().enumerate() {
            *t = 1 + (k % 6) as u32;
        }
        store(&key, &m, &Meshing::default());
        let Found::Hit(back, _) = lookup(&key) else {
            panic!("the entry is not read back")
        };
        assert_eq!(back.surface_faces, m.surface_faces);
        let mut old = std::fs::read(&key).unwrap();
        old[7] = 2;
        std::fs::write(&key, &old).unwrap();
        assert!(matches!(lookup(&key), Found::Absent), "an older entry is not a miss");
        old[7] = 4;
        std::fs::write(&key, &old).unwrap();
        assert!(bad(lookup(&key)).contains("version"));
    }

    /// A stored ordering reads back; a file that is not a permutation of 0..n (a duplicate, a
    /// value out of range, the wrong length: damage, or another graph's) is not used.
    #[test]
    fn an_ordering_reads_back_only_as_a_permutation() {
        let dir = tempfile::tempdir().unwrap();
        let key = dir.path().join("0123456789abcdef.order");
        ordering_store(&key, &[2, 0, 3, 1]);
        assert_eq!(ordering_lookup(&key, 4), Some(vec![2, 0, 3, 1]));
        assert_eq!(ordering_lookup(&key, 5), None);
        for bad in [[2, 0, 2, 1], [2, 0, 4, 1], [2, 0, -1, 1]] {
            ordering_store(&key, &bad);
            assert_eq!(ordering_lookup(&key, 4), None, "{bad:?}");
        }
    }
}
