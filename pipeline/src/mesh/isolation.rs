//! Each rung of the meshing ladder in its own process, so that nothing gmsh or OpenCASCADE does
//! can end VES: an uncaught C++ exception, a segfault on a malformed file, or a `.geo` script's
//! `Exit;` (which calls `exit(0)`) ends the child, and the parent reports it as a failed rung.
//!
//! The `ves` binary turns this on ([`isolate_with`] its own path); a library user who links the
//! pipeline gets in-process meshing unless it does the same.

use super::{Attempt, LADDER, Mesh, MeshError, Meshing, Request};
use std::io::{BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

static WORKER: OnceLock<PathBuf> = OnceLock::new();

/// The phase of reading the geometry file.
pub(super) const READING: &str = "reading the geometry";
/// How a process that died reading the file is reported (the ladder's advice differs).
pub(super) const WHILE_READING: &str = "ended the meshing process while reading the geometry";

/// The hidden subcommand of the `ves` binary that serves one rung.
pub const WORKER_COMMAND: &str = "mesh-worker";

/// Meshes in child processes of `exe`, which must answer `exe mesh-worker DIR` with [`serve`].
pub fn isolate_with(exe: PathBuf) {
    let _ = WORKER.set(exe);
}

pub(super) fn is_on() -> bool {
    WORKER.get().is_some()
}

/// What the child says: its mesh is in `mesh.bin` beside it.
#[derive(serde::Serialize, serde::Deserialize)]
enum Reply {
    Meshed {
        meshing: Meshing,
        vertex_count: usize,
        order: u8,
    },
    Retry {
        cause: String,
        log: Vec<String>,
    },
    Fatal {
        cause: String,
    },
}

#[derive(serde::Serialize, serde::Deserialize)]
struct Job {
    request: Request,
    rung: usize,
    /// The parent's process id: the child ends at once if it already has another parent.
    parent: u32,
}

/// Runs rung `rung` of the ladder: in a child process when isolation is on.
/// `dir`: a new directory for the job's files, inside the meshing's private directory.
pub(super) fn attempt(req: &Request, rung: usize, dir: &Path) -> Result<(Mesh, Meshing), Attempt> {
    let Some(exe) = WORKER.get() else {
        return super::attempt(req, &LADDER[rung], &mut |_| {});
    };
    let path = req.geometry.display().to_string();
    let failed = |message: String| {
        Attempt::Retry(
            MeshError::Geometry {
                path: path.clone(),
                message,
            },
            Vec::new(),
        )
    };
    crate::workdir::create_dir(dir)
        .map_err(|e| failed(format!("cannot create the directory {}: {e}", dir.display())))?;
    let job = Job {
        request: req.clone(),
        rung,
        parent: std::process::id(),
    };
    let text = serde_json::to_string(&job).map_err(|e| failed(format!("cannot encode the meshing job: {e}")))?;
    std::fs::write(dir.join("job.json"), text)
        .map_err(|e| failed(format!("cannot write the meshing job to {}: {e}", dir.display())))?;
    let status = std::process::Command::new(exe)
        .arg(WORKER_COMMAND)
        .arg(dir)
        .stdin(std::process::Stdio::null())
        // gmsh may print to stdout; VES's stdout is for results (--json).
        .stdout(std::process::Stdio::null())
        .status()
        .map_err(|e| failed(format!("cannot start the meshing process {}: {e}", exe.display())))?;
    let reply = std::fs::read_to_string(dir.join("reply.json")).ok();
    let Some(reply) = reply.and_then(|r| serde_json::from_str::<Reply>(&r).ok()) else {
        let phase = std::fs::read_to_string(dir.join("phase")).unwrap_or_else(|_| "starting".into());
        let what = if phase == READING {
            WHILE_READING.to_string()
        } else {
            format!("ended the meshing process while {phase}")
        };
        return Err(failed(format!("gmsh {what} ({})", describe(status))));
    };
    let error = |cause| MeshError::Geometry {
        path: path.clone(),
        message: cause,
    };
    match reply {
        Reply::Meshed {
            meshing,
            vertex_count,
            order,
        } => {
            let mesh = read_mesh(&dir.join("mesh.bin"), vertex_count, order)
                .map_err(|e| failed(format!("the meshing process left an unreadable mesh: {e}")))?;
            Ok((mesh, meshing))
        }
        Reply::Retry { cause, log } => Err(Attempt::Retry(error(cause), log)),
        Reply::Fatal { cause } => Err(Attempt::Fatal(error(cause))),
    }
}

fn describe(status: std::process::ExitStatus) -> String {
    use std::os::unix::process::ExitStatusExt;
    match (status.code(), status.signal()) {
        (_, Some(6)) => "it aborted: an uncaught C++ exception or a failed assertion in gmsh/OpenCASCADE".into(),
        (_, Some(11)) => "it crashed: segmentation fault in gmsh/OpenCASCADE".into(),
        (_, Some(9)) => "it was killed (SIGKILL: out of memory?)".into(),
        (_, Some(s)) => format!("killed by signal {s}"),
        (Some(0), _) => "it exited with status 0 without a mesh: a .geo script's Exit, or gmsh's own exit".into(),
        (Some(c), _) => format!("exit status {c}"),
        (None, None) => "no status".into(),
    }
}

/// A meshing job the child cannot take up or answer: about the job's files only (the meshing's
/// own failures are replies).
#[derive(Debug, thiserror::Error)]
pub enum WorkerError {
    /// The job file cannot be read, or its parent is gone.
    #[error(transparent)]
    Job(#[from] crate::workdir::WorkdirError),
    /// The job names a rung the ladder does not have.
    #[error("{}: no rung {rung}", file.display())]
    NoRung {
        /// The job file.
        file: PathBuf,
        /// The rung it names.
        rung: usize,
    },
    /// The reply cannot be encoded.
    #[error("{0}")]
    Encode(serde_json::Error),
    /// The mesh or the reply cannot be written.
    #[error("{}: {error}", path.display())]
    Write {
        /// The file or folder written.
        path: PathBuf,
        /// The system's error (in the message, so not also a `source`).
        error: std::io::Error,
    },
}

/// The child's side: runs the job in `dir` and leaves its reply there. An error is about the
/// job's files only (the meshing's own failures are replies).
pub fn serve(dir: &Path) -> Result<(), WorkerError> {
    let job: Job = crate::workdir::child_job(dir, |j: &Job| j.parent)?;
    let rung = LADDER.get(job.rung).ok_or_else(|| WorkerError::NoRung {
        file: dir.join("job.json"),
        rung: job.rung,
    })?;
    let written = |path: &Path| {
        let path = path.to_path_buf();
        move |error| WorkerError::Write { path, error }
    };
    let phase_file = dir.join("phase");
    let mut phase = |p: &str| {
        // Best effort: only read when the process dies.
        let _ = std::fs::write(&phase_file, p);
    };
    let reply = match super::attempt(&job.request, rung, &mut phase) {
        Ok((mesh, meshing)) => {
            write_mesh(&dir.join("mesh.bin"), &mesh).map_err(written(dir))?;
            Reply::Meshed {
                meshing,
                vertex_count: mesh.vertex_count,
                order: mesh.kind.order(),
            }
        }
        Err(Attempt::Retry(e, log)) => Reply::Retry { cause: e.cause(), log },
        Err(Attempt::Fatal(e)) => Reply::Fatal { cause: e.cause() },
    };
    let text = serde_json::to_string(&reply).map_err(WorkerError::Encode)?;
    // Whole or absent: the parent takes a missing reply for a crash.
    let tmp = dir.join("reply.json.tmp");
    std::fs::write(&tmp, text).map_err(written(&tmp))?;
    std::fs::rename(&tmp, dir.join("reply.json")).map_err(written(dir))
}

pub(super) fn write_mesh(path: &Path, mesh: &Mesh) -> std::io::Result<()> {
    let mut w = BufWriter::new(std::fs::File::create(path)?);
    write_mesh_to(&mut w, mesh)?;
    w.flush()
}

/// The mesh as bytes: three counts, the node coordinates, the tet and surface indices, the
/// surface triangles' CAD faces.
pub(super) fn write_mesh_to(w: &mut impl Write, mesh: &Mesh) -> std::io::Result<()> {
    for n in [mesh.nodes.len(), mesh.tets.len(), mesh.surface.len()] {
        w.write_all(&(n as u64).to_le_bytes())?;
    }
    for v in mesh.nodes.iter().flatten() {
        w.write_all(&v.to_le_bytes())?;
    }
    for v in mesh.tets.iter().chain(mesh.surface.iter().flatten()) {
        w.write_all(&v.to_le_bytes())?;
    }
    if mesh.surface_faces.len() != mesh.surface.len() {
        return Err(std::io::Error::other(format!(
            "{} face tags for {} surface triangles",
            mesh.surface_faces.len(),
            mesh.surface.len()
        )));
    }
    for v in &mesh.surface_faces {
        w.write_all(&v.to_le_bytes())?;
    }
    Ok(())
}

pub(super) fn read_mesh(path: &Path, vertex_count: usize, order: u8) -> std::io::Result<Mesh> {
    let file = std::fs::File::open(path)?;
    let size = file.metadata()?.len();
    read_mesh_from(&mut BufReader::new(file), size, vertex_count, order)
}

/// Largest mesh file read: 4 GiB, several times the largest mesh [`super::MAX_TETS`] allows
/// (10⁷ 10-node tets and their nodes take about 0.8 GB).
const MAX_MESH_BYTES: u64 = 4 << 30;

/// Reads what [`write_mesh_to`] wrote, `size` bytes in all, checking counts and indices.
pub(super) fn read_mesh_from(r: &mut impl Read, size: u64, vertex_count: usize, order: u8) -> std::io::Result<Mesh> {
    let mut word = [0u8; 8];
    let mut counts = [0u64; 3];
    for c in &mut counts {
        r.read_exact(&mut word)?;
        *c = u64::from_le_bytes(word);
    }
    let [nodes, tets, faces] = counts;
    // Every count is bounded by the size before anything is allocated for it (checked
    // arithmetic: a damaged count must not wrap around to a size that matches).
    let expected = [(nodes, 24), (tets, 4), (faces, 16)]
        .iter()
        .try_fold(24u64, |sum, &(n, bytes)| n.checked_mul(bytes)?.checked_add(sum));
    let kind = crate::fem::element::Kind::of_order(u32::from(order))
        .ok_or_else(|| std::io::Error::other(format!("element order {order}, which is neither 1 nor 2")))?;
    let per_tet = kind.nodes() as u64;
    let bad = || {
        std::io::Error::other(format!(
            "{size} bytes for {nodes} nodes, {tets} tet indices, {faces} faces"
        ))
    };
    if expected != Some(size) || size > MAX_MESH_BYTES || vertex_count as u64 > nodes || tets % per_tet != 0 {
        return Err(bad());
    }
    let to_usize = |n: u64| usize::try_from(n).map_err(|_| bad());
    let (nodes, tets, faces, per_tet) = (to_usize(nodes)?, to_usize(tets)?, to_usize(faces)?, per_tet as usize);
    let f64s = (0..nodes)
        .map(|_| {
            let mut p = [0.0; 3];
            for v in &mut p {
                r.read_exact(&mut word)?;
                *v = f64::from_le_bytes(word);
            }
            Ok(p)
        })
        .collect::<std::io::Result<Vec<_>>>()?;
    let mut u32s = vec![0u32; tets + 3 * faces];
    let mut four = [0u8; 4];
    for v in &mut u32s {
        r.read_exact(&mut four)?;
        *v = u32::from_le_bytes(four);
        if *v as usize >= nodes {
            return Err(std::io::Error::other(format!("node index {v} of {nodes}")));
        }
    }
    // Corner vertices are numbered first: a description that does not match its mesh shows here.
    let corners = u32s[..tets].chunks_exact(per_tet).flat_map(|t| &t[..4]);
    if let Some(v) = corners.chain(&u32s[tets..]).find(|&&v| v as usize >= vertex_count) {
        return Err(std::io::Error::other(format!(
            "corner vertex {v} beyond the {vertex_count} corner vertices"
        )));
    }
    let surface = u32s[tets..].chunks_exact(3).map(|f| [f[0], f[1], f[2]]).collect();
    u32s.truncate(tets);
    // Any value is a tag (0: unknown).
    let surface_faces = (0..faces)
        .map(|_| {
            r.read_exact(&mut four)?;
            Ok(u32::from_le_bytes(four))
        })
        .collect::<std::io::Result<Vec<u32>>>()?;
    Ok(Mesh {
        nodes: f64s,
        vertex_count,
        kind,
        tets: u32s,
        surface,
        surface_faces,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 2^62 tet indices take 4·2^62 bytes, which wraps to 0 in 64 bits: the size of this
    /// 48-byte file (three counts, one node) seemed to match, and the allocation failed with
    /// "capacity overflow". Counts are bounded by the size with checked arithmetic.
    #[test]
    fn a_count_that_wraps_around_is_refused_before_allocating() {
        let mut bytes = Vec::new();
        for n in [1u64, 1 << 62, 0] {
            bytes.extend(n.to_le_bytes());
        }
        bytes.extend([0u8; 24]);
        let e = read_mesh_from(&mut &bytes[..], bytes.len() as u64, 1, 1).unwrap_err();
        assert!(e.to_string().contains("tet indices"), "{e}");
    }

    #[test]
    fn a_mesh_crosses_the_process_boundary_unchanged_and_a_short_file_is_refused() {
        let mut m = Mesh::structured_box([4, 1, 2], 0.01, crate::fem::element::Kind::Tet10, |_, p| p);
        // Distinct tags, so a shifted or dropped one shows.
        for (k, t) in m.surface_faces.iter_mut().enumerate() {
            *t = 7 + k as u32;
        }
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("mesh.bin");
        write_mesh(&p, &m).unwrap();
        let back = read_mesh(&p, m.vertex_count, m.kind.order()).unwrap();
        assert_eq!(back.nodes, m.nodes);
        assert_eq!(back.tets, m.tets);
        assert_eq!(back.surface, m.surface);
        assert_eq!(back.surface_faces, m.surface_faces);
        assert_eq!(back.vertex_count, m.vertex_count);
        let bytes = std::fs::read(&p).unwrap();
        std::fs::write(&p, &bytes[..bytes.len() - 4]).unwrap();
        assert!(read_mesh(&p, m.vertex_count, m.kind.order()).is_err());
    }
}
