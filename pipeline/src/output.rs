//! Where results go: every output path is checked before any work (it must not be an input, a
//! directory, a device or a symlink, and its directory must be writable), and every file is
//! written under a temporary name, flushed to disk and renamed, so a killed run never leaves a
//! half-written file under the final name and never touches what was there.

use anyhow::{Context, Result, bail};
use std::path::{Path, PathBuf};

/// What an output may replace.
#[derive(Clone, Copy, Debug, Default)]
pub struct Overwrite {
    /// Replace a symbolic link at the output path (the link itself, never its target).
    pub force: bool,
}

fn directory_of(out: &Path) -> &Path {
    out.parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
}

/// Whether `a` and `b` name the same existing file (same device and inode).
fn same_file(a: &Path, b: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        (Ok(x), Ok(y)) => x.dev() == y.dev() && x.ino() == y.ino(),
        _ => false,
    }
}

/// Fails early, with what to change, when `out` cannot or must not be written: its directory is
/// missing or read-only, it is a directory, a device or other special file, a symlink (unless
/// `force`), or one of `inputs`. Removes temporaries that killed runs left beside it.
pub fn check(out: &Path, inputs: &[&Path], policy: Overwrite) -> Result<()> {
    let dir = directory_of(out);
    if !dir.is_dir() {
        bail!(
            "{}: the output directory does not exist; create it or choose another -o",
            out.display()
        );
    }
    if let Some(input) = inputs.iter().find(|i| same_file(out, i)) {
        bail!(
            "{}: is an input of this run ({}); choose another output path",
            out.display(),
            input.display()
        );
    }
    if let Ok(meta) = std::fs::symlink_metadata(out) {
        let ty = meta.file_type();
        if ty.is_symlink() && !policy.force {
            bail!(
                "{}: is a symbolic link; choose another output path, or pass --force to replace the link (its target is left alone)",
                out.display()
            );
        }
        if ty.is_dir() {
            bail!("{}: is a directory; give a file name with -o", out.display());
        }
        if !ty.is_file() && !ty.is_symlink() {
            bail!(
                "{}: is not a regular file (a device, pipe or socket); choose another output path",
                out.display()
            );
        }
    }
    // A read-only directory is found now, not after the whole computation.
    let probe = temp_name(out, "probe");
    std::fs::File::create(&probe).with_context(|| {
        format!(
            "{}: cannot write in {}; choose another -o",
            out.display(),
            dir.display()
        )
    })?;
    let _ = std::fs::remove_file(&probe);
    remove_stale_temps(out);
    Ok(())
}

/// `out` with `.tmp-<tag>-<pid>` appended, in the same directory (so the rename is atomic).
fn temp_name(out: &Path, tag: &str) -> PathBuf {
    let mut name = out.file_name().map(|n| n.to_os_string()).unwrap_or_default();
    name.push(format!(".tmp-{tag}-{}", std::process::id()));
    out.with_file_name(name)
}

/// Writes a file through `write` (given a temporary path beside `out`), flushes it to disk and
/// renames it to `out`. On failure nothing is left and whatever was at `out` is untouched.
pub fn write_atomically(out: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    let tmp = temp_name(out, "w");
    let result = write(&tmp).and_then(|()| {
        // The data reaches the disk before the name does: a crash leaves the old file or the
        // new one, never an empty one.
        std::fs::File::open(&tmp)
            .and_then(|f| f.sync_all())
            .with_context(|| format!("cannot flush {}", tmp.display()))?;
        std::fs::rename(&tmp, out).with_context(|| format!("cannot move {} to {}", tmp.display(), out.display()))?;
        if let Ok(d) = std::fs::File::open(directory_of(out)) {
            let _ = d.sync_all();
        }
        Ok(())
    });
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result.with_context(|| format!("{}: nothing was written", out.display()))
}

/// Removes temporary files a killed run left beside `out` (their process is gone).
pub fn remove_stale_temps(out: &Path) {
    let Some(name) = out.file_name() else {
        return;
    };
    let prefix = format!("{}.tmp-", name.to_string_lossy());
    let Ok(entries) = std::fs::read_dir(directory_of(out)) else {
        return;
    };
    for e in entries.flatten() {
        let file = e.file_name().to_string_lossy().into_owned();
        let Some(rest) = file.strip_prefix(&prefix) else {
            continue;
        };
        // `<tag>-<pid>`, or `<pid>` alone from earlier versions.
        let pid = rest.rsplit('-').next().and_then(|p| p.parse::<u32>().ok());
        if let Some(pid) = pid
            && !Path::new(&format!("/proc/{pid}")).exists()
        {
            tracing::info!(file, "removing a temporary file left by a killed run");
            let _ = std::fs::remove_file(e.path());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inputs_symlinks_devices_and_directories_are_refused() {
        let dir = tempfile::tempdir().expect("tempdir");
        let scene = dir.path().join("scene.toml");
        std::fs::write(&scene, "x").expect("write");
        let none = Overwrite::default();
        let e = check(&scene, &[&scene], none).expect_err("input");
        assert!(e.to_string().contains("is an input"), "{e}");
        let link = dir.path().join("link.h5");
        std::os::unix::fs::symlink(&scene, &link).expect("symlink");
        assert!(
            check(&link, &[], none)
                .expect_err("link")
                .to_string()
                .contains("symbolic link")
        );
        // Through the link, the scene is still an input.
        assert!(check(&link, &[&scene], Overwrite { force: true }).is_err());
        check(&link, &[], Overwrite { force: true }).expect("forced");
        assert!(check(Path::new("/dev/null"), &[], Overwrite { force: true }).is_err());
        assert!(check(dir.path(), &[], none).is_err());
        check(&dir.path().join("new.h5"), &[&scene], none).expect("a new file is fine");
    }

    #[test]
    fn atomic_write_leaves_the_old_file_on_failure_and_no_temporary() {
        let dir = tempfile::tempdir().expect("tempdir");
        let out = dir.path().join("out.h5");
        std::fs::write(&out, "old").expect("write");
        let r = write_atomically(&out, |tmp| {
            std::fs::write(tmp, "half")?;
            bail!("failed midway")
        });
        assert!(r.is_err());
        assert_eq!(std::fs::read_to_string(&out).expect("read"), "old");
        assert_eq!(std::fs::read_dir(dir.path()).expect("dir").count(), 1);
        write_atomically(&out, |tmp| Ok(std::fs::write(tmp, "new")?)).expect("write");
        assert_eq!(std::fs::read_to_string(&out).expect("read"), "new");
    }

    #[test]
    fn stale_temporaries_of_dead_processes_are_removed() {
        let dir = tempfile::tempdir().expect("tempdir");
        let out = dir.path().join("out.h5");
        // pid_max on Linux is at most 2^22: this process cannot exist.
        let dead = dir.path().join("out.h5.tmp-w-4999999");
        let old_style = dir.path().join("out.h5.tmp-4999998");
        let alive = dir.path().join(format!("out.h5.tmp-w-{}", std::process::id()));
        for f in [&dead, &old_style, &alive] {
            std::fs::write(f, "x").expect("write");
        }
        remove_stale_temps(&out);
        assert!(!dead.exists() && !old_style.exists() && alive.exists());
    }
}
