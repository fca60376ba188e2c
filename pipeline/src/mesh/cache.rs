//! A cache of finished meshes, so that precomputing the same part again with another material,
//! support, mode count or damping — the everyday batch of scenarios — and the coarser meshes of
//! the error estimate skip gmsh entirely.
//!
//! Key: the geometry file's bytes, what shapes the mesh (unit, size, order, the VOI's box and
//! size), the VES version and the text of the meshing code itself (so any change to how meshes
//! are made misses the old entries without a version to bump). Entries live in
//! `$VES_CACHE_DIR/meshes`, else `$XDG_CACHE_HOME/ves/meshes`, else `~/.cache/ves/meshes`;
//! `VES_MESH_CACHE=off` turns the cache off. Each entry is one file written under a temporary
//! name and renamed, so concurrent runs and threads never read half an entry or a mix of two. A `.geo` script
//! is never cached (it may read other files). gmsh itself is not in the key: a rebuild against
//! another gmsh should start from an empty cache.
//!
//! The METIS node orderings of the meshes solved live beside them (`*.order`, keyed by the
//! node graph): a rerun, or another support of the same mesh, skips METIS too.

use super::{LADDER, Mesh, Meshing, Request, field, isolation};
use std::io::Write;
use std::path::PathBuf;

/// The meshing code: part of every key.
const SOURCES: [&str; 3] = [
    include_str!("mod.rs"),
    include_str!("quality.rs"),
    include_str!("isolation.rs"),
];

/// What the description of an entry holds besides the mesh file.
#[derive(serde::Serialize, serde::Deserialize)]
struct Entry {
    meshing: Meshing,
    vertex_count: usize,
    order: u8,
}

fn dir() -> Option<PathBuf> {
    if std::env::var("VES_MESH_CACHE").is_ok_and(|v| v.eq_ignore_ascii_case("off") || v == "0") {
        return None;
    }
    let base = std::env::var_os("VES_CACHE_DIR")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("XDG_CACHE_HOME").map(|d| PathBuf::from(d).join("ves")))
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache/ves")))?;
    Some(base.join("meshes"))
}

/// The entry a request would have (None: not cacheable, or the cache is off).
pub(super) fn key(req: &Request) -> Option<PathBuf> {
    let ext = req.geometry.extension()?.to_str()?.to_ascii_lowercase();
    if ext == "geo" {
        return None;
    }
    let geometry = std::fs::read(&req.geometry).ok()?;
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
    h.field(shape.as_bytes()).field(&geometry);
    Some(dir()?.join(format!("{:016x}.mesh", h.value())))
}

/// Longest description accepted when reading an entry (a damaged length is not allocated).
const MAX_DESCRIPTION: u64 = 1 << 16;

/// The cached mesh of `key`, if complete and readable.
pub(super) fn lookup(key: &std::path::Path) -> Option<(Mesh, Meshing)> {
    use std::io::Read;
    let file = std::fs::File::open(key).ok()?;
    let size = file.metadata().ok()?.len();
    let mut r = std::io::BufReader::new(file);
    let mut word = [0u8; 8];
    r.read_exact(&mut word).ok()?;
    let len = u64::from_le_bytes(word);
    if len > MAX_DESCRIPTION || 8 + len > size {
        return None;
    }
    let mut text = vec![0u8; len as usize];
    r.read_exact(&mut text).ok()?;
    let entry: Entry = serde_json::from_slice(&text).ok()?;
    let mesh = isolation::read_mesh_from(&mut r, size - 8 - len, entry.vertex_count, entry.order).ok()?;
    let mut meshing = entry.meshing;
    meshing.strategy = LADDER.get(meshing.rung)?.name;
    Some((mesh, meshing))
}

/// Stores a mesh under `key`; a failure only costs the next run its meshing (logged).
///
/// One file per entry (its description, then the mesh), written under a name no other process
/// or thread uses and renamed into place: a reader sees a whole entry or none. (Two files, one
/// renamed after the other, let a reader pair one run's description with another run's mesh
/// while both stored the same key: gmsh's meshes of one input can differ between runs.)
pub(super) fn store(key: &std::path::Path, mesh: &Mesh, meshing: &Meshing) {
    let entry = Entry {
        meshing: *meshing,
        vertex_count: mesh.vertex_count,
        order: mesh.order,
    };
    write_atomically(key, |w| {
        let text = serde_json::to_vec(&entry).map_err(std::io::Error::other)?;
        w.write_all(&(text.len() as u64).to_le_bytes())?;
        w.write_all(&text)?;
        isolation::write_mesh_to(w, mesh)
    });
}

/// Writes `key` under a name no other process or thread uses, then renames it into place; a
/// failure only costs the next run the work (logged).
fn write_atomically(
    key: &std::path::Path,
    body: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
) {
    use std::sync::atomic::{AtomicU64, Ordering};
    static SERIAL: AtomicU64 = AtomicU64::new(0);
    let result = (|| -> std::io::Result<()> {
        if let Some(d) = key.parent() {
            std::fs::create_dir_all(d)?;
        }
        let unique = format!("tmp{}.{}", std::process::id(), SERIAL.fetch_add(1, Ordering::Relaxed));
        let tmp = key.with_extension(unique);
        let written = (|| {
            let mut w = std::io::BufWriter::new(std::fs::File::create(&tmp)?);
            body(&mut w)?;
            w.flush()?;
            std::fs::rename(&tmp, key)
        })();
        if written.is_err() {
            let _ = std::fs::remove_file(&tmp);
        }
        written
    })();
    if let Err(e) = result {
        tracing::info!("cache: cannot store {}: {e}", key.display());
    }
}

/// Where the fill-reducing node ordering of a node graph (CSR `xadj`, `adj`) is cached: beside
/// the meshes, keyed by the graph itself and the ordering code, so the same mesh with other
/// supports (a batch of scenarios, a rerun) skips METIS. None when the cache is off.
pub(crate) fn ordering_key(xadj: &[i32], adj: &[i32]) -> Option<PathBuf> {
    let dir = dir()?;
    let bytes = |v: &[i32]| -> Vec<u8> { v.iter().flat_map(|x| x.to_le_bytes()).collect() };
    let mut h = crate::fingerprint::Fingerprint::default();
    h.field(env!("CARGO_PKG_VERSION").as_bytes())
        .field(include_str!("../linsolve.rs").as_bytes())
        .field(&bytes(xadj))
        .field(&bytes(adj));
    Some(dir.join(format!("{:016x}.order", h.value())))
}

/// The cached ordering under `key`: a permutation of 0..n, else None.
pub(crate) fn ordering_lookup(key: &std::path::Path, n: usize) -> Option<Vec<i32>> {
    let bytes = std::fs::read(key).ok()?;
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Threads storing two different meshes under one key (as two runs of one part can, since
    /// gmsh's meshes of one input differ) while another thread reads: every entry read is one
    /// of the two meshes whole, never one's description with the other's nodes.
    #[test]
    fn concurrent_stores_of_one_key_are_read_whole() {
        let a = Mesh::structured_box([3, 1, 1], 0.01, 2, |_, p| p);
        let b = Mesh::structured_box([5, 2, 1], 0.01, 2, |_, p| p);
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
                    if let Some((m, _)) = lookup(&key) {
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
        let (last, _) = lookup(&key).expect("the entry is readable after the writers");
        assert!(whole(&last));
        let left: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(left.len(), 1, "temporary files left: {left:?}");
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
