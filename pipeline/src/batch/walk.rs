//! The scene files a batch is given: directories walked once each, links handled as `find`
//! does, each file listed once.

use anyhow::{Result, bail};
use std::path::{Path, PathBuf};

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
