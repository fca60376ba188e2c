//! A cache of finished meshes, so that precomputing the same part again with another material,
//! support, mode count or damping — the everyday batch of scenarios — and the coarser meshes of
//! the error estimate skip gmsh entirely.
//!
//! Key: the geometry file's bytes, what shapes the mesh (unit, size, order, the VOI's box and
//! size), the VES version and the text of the meshing code itself (so any change to how meshes
//! are made misses the old entries without a version to bump). Entries live in
//! `$VES_CACHE_DIR/meshes`, else `$XDG_CACHE_HOME/ves/meshes`, else `~/.cache/ves/meshes`;
//! `VES_MESH_CACHE=off` turns the cache off. Each entry is written to a temporary name and
//! renamed, the description last, so concurrent runs never read half an entry. A `.geo` script
//! is never cached (it may read other files). gmsh itself is not in the key: a rebuild against
//! another gmsh should start from an empty cache.

use super::{LADDER, Mesh, Meshing, Request, isolation};
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
    ))
    .ok()?;
    let mut h = crate::fingerprint::Fingerprint::default();
    h.field(env!("CARGO_PKG_VERSION").as_bytes());
    for s in SOURCES {
        h.field(s.as_bytes());
    }
    h.field(shape.as_bytes()).field(&geometry);
    Some(dir()?.join(format!("{:016x}", h.value())))
}

/// The cached mesh of `key`, if complete and readable.
pub(super) fn lookup(key: &std::path::Path) -> Option<(Mesh, Meshing)> {
    let text = std::fs::read_to_string(key.with_extension("json")).ok()?;
    let entry: Entry = serde_json::from_str(&text).ok()?;
    let mesh = isolation::read_mesh(&key.with_extension("bin"), entry.vertex_count, entry.order).ok()?;
    let mut meshing = entry.meshing;
    meshing.strategy = LADDER.get(meshing.rung)?.name;
    Some((mesh, meshing))
}

/// Stores a mesh under `key`; a failure only costs the next run its meshing (logged).
pub(super) fn store(key: &std::path::Path, mesh: &Mesh, meshing: &Meshing) {
    let result = (|| -> std::io::Result<()> {
        if let Some(d) = key.parent() {
            std::fs::create_dir_all(d)?;
        }
        let unique = format!("tmp{}", std::process::id());
        let bin = key.with_extension(format!("bin.{unique}"));
        isolation::write_mesh(&bin, mesh)?;
        std::fs::rename(&bin, key.with_extension("bin"))?;
        let entry = Entry {
            meshing: *meshing,
            vertex_count: mesh.vertex_count,
            order: mesh.order,
        };
        let json = key.with_extension(format!("json.{unique}"));
        std::fs::write(&json, serde_json::to_string(&entry).map_err(std::io::Error::other)?)?;
        std::fs::rename(&json, key.with_extension("json"))
    })();
    if let Err(e) = result {
        tracing::info!("mesh cache: cannot store {}: {e}", key.display());
    }
}
