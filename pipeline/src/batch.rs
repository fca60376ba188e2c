//! `ves batch`: precompute many scenes unattended. Scenes whose output is up to date (same
//! content hash of tool version, scene, mode count and geometry) are skipped, a bad scene is
//! reported and the batch goes on, and because every output is written to a temporary name and
//! renamed, an interrupted batch resumes where it stopped (stale temporary files are removed).

use crate::modes::SolverChoice;
use crate::precompute;
use crate::scene::Scene;
use crate::store;
use anyhow::{Result, bail};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

/// Batch settings.
#[derive(Clone, Debug)]
pub struct BatchOptions {
    /// Scenes precomputed at once.
    pub jobs: usize,
    /// Output directory (default: beside each scene).
    pub out: Option<PathBuf>,
    /// Eigen-solver.
    pub solver: SolverChoice,
    /// Accept .geo geometries (gmsh scripts).
    pub allow_geo_scripts: bool,
}

/// What happened to one scene.
#[derive(Clone, Debug, Serialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum Status {
    /// Precomputed now.
    Done,
    /// Its output was up to date.
    UpToDate,
    /// It failed; see the error.
    Failed,
}

/// One scene's outcome.
#[derive(Clone, Debug, Serialize)]
pub struct Outcome {
    /// Scene file.
    pub scene: String,
    /// Output file (when one could be named).
    pub output: Option<String>,
    /// What happened.
    pub status: Status,
    /// The one-line error of a failed scene.
    pub error: Option<String>,
    /// Seconds spent.
    pub seconds: f64,
}

/// Scene files named by `inputs`, each file once: files as given, directories searched
/// recursively for `*.toml` (each directory's scenes sorted by name). A path that does not exist
/// is an error.
///
/// Symbolic links: an input named on the command line is followed, whatever it points to.
/// Inside a directory, links to files are listed and links to directories are not entered (as
/// `find` does), so a link loop cannot make the walk endless and no directory is walked twice.
/// A file reached under several names (hard or symbolic links, overlapping inputs) is listed
/// once, under the first name met.
pub fn collect(inputs: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut walk = Walk::default();
    for p in inputs {
        let meta = std::fs::metadata(p).map_err(|e| match e.kind() {
            std::io::ErrorKind::NotFound => anyhow::anyhow!("{}: no such scene file or directory", p.display()),
            _ => anyhow::anyhow!("{}: cannot read it: {e}", p.display()),
        })?;
        if meta.is_dir() {
            walk.dir(p, &meta)?;
        } else if meta.is_file() {
            walk.file(p.clone(), &meta);
        } else {
            bail!(
                "{}: not a scene file or directory (a device, pipe or socket); give *.toml files or directories",
                p.display()
            );
        }
    }
    if walk.found.is_empty() {
        bail!("no scene files (*.toml) found in {inputs:?}");
    }
    Ok(walk.found)
}

/// A file's or directory's identity: device and inode.
type FileId = (u64, u64);

fn id_of(meta: &std::fs::Metadata) -> FileId {
    use std::os::unix::fs::MetadataExt;
    (meta.dev(), meta.ino())
}

/// The state of [`collect`]: what was listed, and what was seen (by identity, not by name).
#[derive(Default)]
struct Walk {
    found: Vec<PathBuf>,
    files: std::collections::HashSet<FileId>,
    dirs: std::collections::HashSet<FileId>,
}

impl Walk {
    fn file(&mut self, path: PathBuf, meta: &std::fs::Metadata) {
        if self.files.insert(id_of(meta)) {
            self.found.push(path);
        }
    }

    /// Lists the scenes under `dir` (already known to be a directory, `meta` its metadata).
    fn dir(&mut self, dir: &Path, meta: &std::fs::Metadata) -> Result<()> {
        // A directory met again (a bind mount inside itself, overlapping inputs) is not walked
        // again: this also bounds the walk.
        if !self.dirs.insert(id_of(meta)) {
            return Ok(());
        }
        let cannot = |e: std::io::Error| anyhow::anyhow!("{}: cannot read the directory: {e}", dir.display());
        let mut entries = Vec::new();
        for e in std::fs::read_dir(dir).map_err(cannot)? {
            let e = e.map_err(cannot)?;
            let ty = e.file_type().map_err(cannot)?;
            entries.push((e.path(), ty));
        }
        entries.sort_by(|a, b| a.0.cmp(&b.0));
        for (path, ty) in entries {
            if ty.is_dir() {
                let meta = std::fs::symlink_metadata(&path)
                    .map_err(|e| anyhow::anyhow!("{}: cannot read it: {e}", path.display()))?;
                self.dir(&path, &meta)?;
            } else if ty.is_symlink() && path.is_dir() {
                tracing::warn!(
                    "{}: a link to a directory, not entered; name it on the command line to include its scenes",
                    path.display()
                );
            } else if path.extension().is_some_and(|x| x == "toml") {
                // A link to a file counts as that file.
                match std::fs::metadata(&path) {
                    Ok(meta) if meta.is_file() => self.file(path, &meta),
                    _ => tracing::warn!(
                        "{}: not a regular file (a device, pipe, socket or dangling link); skipped",
                        path.display()
                    ),
                }
            }
        }
        Ok(())
    }
}

/// Precomputes every scene; never stops at a failed one.
pub fn run(scenes: &[PathBuf], opts: &BatchOptions) -> Result<Vec<Outcome>> {
    if let Some(dir) = &opts.out {
        std::fs::create_dir_all(dir)
            .map_err(|e| anyhow::anyhow!("{}: cannot create the output directory: {e}", dir.display()))?;
    }
    let outer = crate::progress::innermost();
    let note = |line: String| {
        if let Some(w) = &outer {
            w.note(&line);
        }
    };
    let bar = crate::progress::count(scenes.len() as u64, "scenes");
    // The scenes' own stages and counts are not drawn: the batch's count is.
    let _quiet = outer
        .clone()
        .map(|w| crate::progress::watch(std::sync::Arc::new(crate::progress::Quiet(w))));
    let next = AtomicUsize::new(0);
    let results: Mutex<Vec<Option<Outcome>>> = Mutex::new(vec![None; scenes.len()]);
    // Outputs claimed so far: two scenes may not write one file.
    let claimed: Mutex<Vec<(PathBuf, String)>> = Mutex::new(Vec::new());
    std::thread::scope(|s| {
        for _ in 0..opts.jobs.clamp(1, 64) {
            s.spawn(|| {
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    let Some(path) = scenes.get(i) else { break };
                    bar.message(&path.display().to_string());
                    let o = one(path, opts, &claimed);
                    // Told as it happens (the terminal prints it above the batch's bar).
                    match &o.status {
                        Status::Failed => note(format!("failed: {}: {}", o.scene, o.error.as_deref().unwrap_or(""))),
                        Status::Done => note(format!("done: {} → {}", o.scene, o.output.as_deref().unwrap_or(""))),
                        Status::UpToDate => {}
                    }
                    results.lock().unwrap_or_else(|p| p.into_inner())[i] = Some(o);
                    bar.inc(1);
                }
            });
        }
    });
    Ok(results
        .into_inner()
        .unwrap_or_else(|p| p.into_inner())
        .into_iter()
        .flatten()
        .collect())
}

fn one(path: &Path, opts: &BatchOptions, claimed: &Mutex<Vec<(PathBuf, String)>>) -> Outcome {
    let start = Instant::now();
    let mut outcome = Outcome {
        scene: path.display().to_string(),
        output: None,
        status: Status::Failed,
        error: None,
        seconds: 0.0,
    };
    let result = (|| -> Result<Status> {
        let scene = Scene::load_with(
            path,
            crate::scene::SceneOptions {
                allow_geo_scripts: opts.allow_geo_scripts,
            },
        )?;
        let out = match &opts.out {
            Some(dir) => dir.join(format!("{}.h5", scene.name)),
            None => scene.path.with_file_name(format!("{}.h5", scene.name)),
        };
        outcome.output = Some(out.display().to_string());
        {
            let mut c = claimed.lock().unwrap_or_else(|p| p.into_inner());
            let key = std::path::absolute(&out).unwrap_or(out.clone());
            if let Some((_, other)) = c.iter().find(|(o, _)| *o == key) {
                bail!(
                    "output {} is also written by {other}; give one of the scenes another `name`",
                    out.display()
                );
            }
            c.push((key, outcome.scene.clone()));
        }
        crate::output::remove_stale_temps(&out);
        let hash = store::source_hash(&scene)?;
        if out.is_file() && store::stored_source_hash(&out).as_deref() == Some(hash.as_str()) {
            if store::repair_sidecar(&out)? {
                tracing::warn!(output = %out.display(), "the XDMF sidecar did not match its basis; rewritten");
            }
            return Ok(Status::UpToDate);
        }
        precompute::run(&scene, &out, opts.solver)?;
        Ok(Status::Done)
    })();
    match result {
        Ok(s) => outcome.status = s,
        Err(e) => outcome.error = Some(format!("{e:#}").replace('\n', " ")),
    }
    outcome.seconds = start.elapsed().as_secs_f64();
    outcome
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::fs::symlink;

    /// [`collect`] on a thread; fails instead of hanging when it does not return in 20 s.
    fn collect_within_seconds(inputs: Vec<PathBuf>) -> Result<Vec<PathBuf>> {
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let _ = tx.send(collect(&inputs));
        });
        rx.recv_timeout(std::time::Duration::from_secs(20))
            .expect("collect did not return within 20 s (a symlink loop followed?)")
    }

    /// Two link loops made the walk endless (it doubles at every level); one listed the same
    /// scene 41 times, under ever longer names, until the kernel's ELOOP.
    #[test]
    fn link_loops_are_not_followed_and_each_scene_is_listed_once() {
        let dir = tempfile::tempdir().expect("tempdir");
        let d = dir.path();
        std::fs::create_dir(d.join("sub")).expect("mkdir");
        std::fs::write(d.join("a.toml"), "x").expect("write");
        std::fs::write(d.join("sub/b.toml"), "x").expect("write");
        symlink(d, d.join("sub/up")).expect("loop 1");
        symlink(".", d.join("self")).expect("loop 2");
        // A link to a scene is that scene; a hard link too; a dangling link is none.
        symlink(d.join("a.toml"), d.join("sub/a-link.toml")).expect("file link");
        std::fs::hard_link(d.join("sub/b.toml"), d.join("sub/c.toml")).expect("hard link");
        symlink(d.join("gone.toml"), d.join("dangling.toml")).expect("dangling");
        let found = collect_within_seconds(vec![d.to_path_buf()]).expect("scenes");
        assert_eq!(found, [d.join("a.toml"), d.join("sub/b.toml")], "{found:?}");
        // Overlapping inputs, and a linked directory named on the command line, add nothing new.
        let found = collect_within_seconds(vec![d.to_path_buf(), d.join("sub"), d.join("self"), d.join("a.toml")])
            .expect("scenes");
        assert_eq!(found.len(), 2, "{found:?}");
        // A linked directory named on the command line is walked.
        let found = collect_within_seconds(vec![d.join("sub/up")]).expect("scenes");
        assert_eq!(found.len(), 2, "{found:?}");
        // A FIFO named like a scene is no scene (reading it would block).
        let fifo = d.join("sub/pipe.toml");
        crate::make_fifo(&fifo);
        assert_eq!(collect_within_seconds(vec![d.to_path_buf()]).expect("scenes").len(), 2);
        assert!(collect_within_seconds(vec![fifo]).is_err());
    }
}
