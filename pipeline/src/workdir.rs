//! Private work folders: the meshing's (gmsh's copy of the part, each rung's files), `ves
//! view`'s (uploaded parts, computed bases) and `ves verify`'s (the reference solvers' files).
//!
//! Each is `$TMPDIR/ves-KIND-pidPID-RANDOM`, mode 0700 (files written through [`write`] or
//! [`seal`]ed are 0600), and its owner holds a lock on a file inside for as long as it lives.
//! It is removed when dropped; in a program that asks for it ([`remove_on_signals`]: the `ves`
//! binary does), every live one is removed on SIGINT, SIGTERM and SIGHUP before the process ends;
//! one left by a process that ended otherwise (an abort, SIGKILL) is removed by the next process
//! that makes a work folder. The library itself installs no signal handler: in an embedding
//! program (Python, whose Ctrl-C must stay a KeyboardInterrupt) the signals stay its own.

use std::os::unix::fs::{DirBuilderExt, OpenOptionsExt, PermissionsExt};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, Once};

/// Names of work folders: `ves-KIND-pid<PID>-<random>`.
const PREFIX: &str = "ves-";
/// What follows the kind.
const PID: &str = "-pid";
/// Held (flock) by the owner of a work folder for as long as it lives.
const LOCK: &str = "owner.lock";

/// The work folders of this process that are alive, for the signal handler to remove.
static LIVE: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn live() -> MutexGuard<'static, Vec<PathBuf>> {
    LIVE.lock().unwrap_or_else(|p| p.into_inner())
}

/// A private work folder (mode 0700, in `$TMPDIR`), removed when dropped.
pub struct WorkDir {
    dir: tempfile::TempDir,
    _lock: std::fs::File,
}

impl WorkDir {
    /// A new work folder of `kind` (lower-case letters and `-`: `mesh`, `view`, `verify`). The
    /// first one of a process first removes those whose owners are gone.
    pub fn new(kind: &str) -> std::io::Result<WorkDir> {
        static SWEPT: Once = Once::new();
        SWEPT.call_once(|| remove_stale(&std::env::temp_dir()));
        let dir = tempfile::Builder::new()
            .prefix(&format!("{PREFIX}{kind}{PID}{}-", std::process::id()))
            .permissions(std::fs::Permissions::from_mode(0o700))
            .tempdir()?;
        let lock = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .mode(0o600)
            .open(dir.path().join(LOCK))?;
        // Exclusive until this process ends (the kernel drops it even on SIGKILL); children do
        // not inherit it (the descriptor is close-on-exec).
        if !crate::os::lock_exclusive(&lock, false) {
            return Err(std::io::Error::last_os_error());
        }
        live().push(dir.path().to_path_buf());
        Ok(WorkDir { dir, _lock: lock })
    }

    /// Its path.
    pub fn path(&self) -> &Path {
        self.dir.path()
    }

    /// Keeps the folder after all (to look into), even on a signal; returns its path.
    pub fn keep(mut self) -> PathBuf {
        self.dir.disable_cleanup(true);
        self.dir.path().to_path_buf()
    }
}

impl Drop for WorkDir {
    fn drop(&mut self) {
        let path = self.dir.path();
        live().retain(|p| p != path);
        // The TempDir, dropped next, removes the folder.
    }
}

/// Writes `bytes` to a new file `path` readable by its owner only (0600).
pub fn write(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    use std::io::Write;
    let mut f = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(0o600)
        .open(path)?;
    f.write_all(bytes)
}

/// Makes a file another library wrote (HDF5) readable by its owner only (0600).
pub fn seal(path: &Path) -> std::io::Result<()> {
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o600))
}

/// A folder inside a work folder (0700).
pub fn create_dir(path: &Path) -> std::io::Result<()> {
    std::fs::DirBuilder::new().mode(0o700).create(path)
}

/// Removes the work folders in `tmp` of processes that no longer run: only this user's, only
/// real directories (not symlinks), and not one whose lock is still held (its owner may run in
/// another PID namespace sharing `tmp`).
pub fn remove_stale(tmp: &Path) {
    use std::os::unix::fs::MetadataExt;
    let Ok(entries) = std::fs::read_dir(tmp) else { return };
    let me = std::process::id();
    let uid = crate::os::effective_uid();
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = name.to_str().and_then(owner) else {
            continue;
        };
        let path = entry.path();
        let Ok(meta) = std::fs::symlink_metadata(&path) else {
            continue;
        };
        if pid == me || !meta.is_dir() || meta.uid() != uid || crate::os::process_runs(pid) {
            continue;
        }
        if let Ok(lock) = std::fs::OpenOptions::new()
            .read(true)
            .custom_flags(libc::O_NOFOLLOW | libc::O_NONBLOCK)
            .open(path.join(LOCK))
            && !crate::os::lock_exclusive(&lock, false)
        {
            continue;
        }
        match std::fs::remove_dir_all(&path) {
            Ok(()) => tracing::info!("removed {}, left by process {pid} that no longer runs", path.display()),
            Err(e) => tracing::info!("cannot remove {} (left by process {pid}): {e}", path.display()),
        }
    }
}

/// The owner's process id in a work folder's name `ves-KIND-pid<PID>-<random>`.
fn owner(name: &str) -> Option<u32> {
    let rest = name.strip_prefix(PREFIX)?;
    let (kind, rest) = rest.split_once(PID)?;
    if kind.is_empty() || !kind.bytes().all(|b| b.is_ascii_lowercase() || b == b'-') {
        return None;
    }
    let (pid, random) = rest.split_once('-')?;
    (!random.is_empty() && pid.bytes().all(|b| b.is_ascii_digit()))
        .then(|| pid.parse().ok())
        .flatten()
}

/// Removes every live work folder of this process (at its end: threads still running, a
/// compute's, may hold some).
pub fn remove_all() {
    for p in live().drain(..) {
        let _ = std::fs::remove_dir_all(p);
    }
}

/// [`remove_all`], again while a folder comes back (a grandchild, killed by its parent's death,
/// may still finish a write into it): up to a second.
fn remove_settled() {
    let paths: Vec<PathBuf> = live().drain(..).collect();
    for _ in 0..20 {
        for p in &paths {
            let _ = std::fs::remove_dir_all(p);
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
        if paths.iter().all(|p| !p.exists()) {
            return;
        }
    }
}

/// Cleanups to run when a signal ends the process (see [`at_signal`]), by id.
type Cleanup = Box<dyn Fn() + Send>;
static AT_SIGNAL: Mutex<Vec<(u64, Cleanup)>> = Mutex::new(Vec::new());

/// While the returned guard lives, `cleanup` runs if SIGINT, SIGTERM or SIGHUP ends the process
/// (with [`remove_on_signals`] installed): a batch's claims are released when Slurm's time
/// limit or scancel ends it, so a requeued task elsewhere need not wait out their lease.
pub fn at_signal(cleanup: impl Fn() + Send + 'static) -> SignalGuard {
    static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let id = NEXT.fetch_add(1, Ordering::Relaxed);
    AT_SIGNAL
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .push((id, Box::new(cleanup)));
    SignalGuard(id)
}

/// Keeps a cleanup of [`at_signal`] registered; dropping it removes it.
pub struct SignalGuard(u64);

impl Drop for SignalGuard {
    fn drop(&mut self) {
        AT_SIGNAL
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .retain(|(id, _)| *id != self.0);
    }
}

/// Set by [`stop_on_interrupt`]: SIGINT asks this process to stop rather than ends it.
static GRACEFUL: Mutex<Option<Arc<AtomicBool>>> = Mutex::new(None);

/// Makes the first SIGINT set `stop` instead of ending the process (`ves view` then ends its
/// session, prints its statistics and removes its folders itself); a second one ends it.
pub fn stop_on_interrupt(stop: Arc<AtomicBool>) {
    *GRACEFUL.lock().unwrap_or_else(|p| p.into_inner()) = Some(stop);
}

/// On SIGINT, SIGTERM or SIGHUP, runs the [`at_signal`] cleanups and removes every live work
/// folder, then ends the process as the
/// signal would have (a SIGINT with a [`stop_on_interrupt`] flag asks it to stop instead). In
/// a thread of its own (signal-hook's self-pipe): removing folders is no work for a signal
/// handler. For programs that own their process (the `ves` binary calls it first thing), never
/// for a library's caller. Once per process; a handler that cannot be installed leaves the
/// signals as they were (the next run removes the folders).
pub fn remove_on_signals() {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    static INSTALLED: Once = Once::new();
    INSTALLED.call_once(|| {
        let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP]) else {
            return;
        };
        let spawned = std::thread::Builder::new().name("ves-signals".into()).spawn(move || {
            for signal in signals.forever() {
                if signal == SIGINT
                    && let Some(stop) = GRACEFUL.lock().unwrap_or_else(|p| p.into_inner()).take()
                {
                    stop.store(true, Ordering::Relaxed);
                    continue;
                }
                for (_, cleanup) in AT_SIGNAL.lock().unwrap_or_else(|p| p.into_inner()).iter() {
                    cleanup();
                }
                // Its children first (a page's compute, a mesh worker, which write into these
                // folders; their own children die with them), or a file they make while the
                // folder is removed leaves it behind (seen after SIGHUP once processes started
                // in 0.06 s instead of 0.3 s).
                crate::os::kill_children();
                remove_settled();
                let _ = signal_hook::low_level::emulate_default_handler(signal);
                // A signal whose default is not to end (none of these three): end anyway.
                std::process::exit(128 + signal);
            }
        });
        if spawned.is_err() {
            tracing::warn!("cannot watch for signals: work folders stay behind if this process is killed");
        }
    });
}

/// A child process's job that cannot be taken up (see [`child_job`]).
#[derive(Debug, thiserror::Error)]
pub enum WorkdirError {
    /// The job file cannot be read.
    #[error("{}: {error}", file.display())]
    Unreadable {
        /// The job file.
        file: PathBuf,
        /// The system's error (in the message, so not also a `source`).
        error: std::io::Error,
    },
    /// The job file is not a job of this kind.
    #[error("{}: {error}", file.display())]
    Malformed {
        /// The job file.
        file: PathBuf,
        /// The decoder's error (in the message).
        error: serde_json::Error,
    },
    /// The process that wrote the job is no longer this one's parent.
    #[error("the parent process {parent} is gone")]
    ParentGone {
        /// The parent the job names.
        parent: u32,
    },
}

/// A child process's side of a job (mesh worker, page compute): arms the parent-death signal
/// (a killed `ves` must not leave gmsh or a solve running for minutes), reads `dir/job.json`,
/// and checks that the parent it names is still this process's parent (if it died before the
/// signal was armed, the signal never comes). Errors name the job file.
pub fn child_job<T: serde::de::DeserializeOwned>(dir: &Path, parent_of: impl Fn(&T) -> u32) -> Result<T, WorkdirError> {
    crate::os::die_with_parent();
    let file = dir.join("job.json");
    let text = match std::fs::read_to_string(&file) {
        Ok(text) => text,
        Err(error) => return Err(WorkdirError::Unreadable { file, error }),
    };
    let job: T = match serde_json::from_str(&text) {
        Ok(job) => job,
        Err(error) => return Err(WorkdirError::Malformed { file, error }),
    };
    let parent = crate::os::parent_pid();
    if parent != parent_of(&job) {
        return Err(WorkdirError::ParentGone {
            parent: parent_of(&job),
        });
    }
    Ok(job)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::fs::MetadataExt;

    /// A process id that no process has now: a child's, once it has been waited for.
    fn dead_pid() -> u32 {
        let mut c = std::process::Command::new("true").spawn().expect("true");
        let pid = c.id();
        c.wait().expect("wait");
        pid
    }

    #[test]
    fn names_say_their_owner() {
        assert_eq!(owner("ves-view-pid123-abc"), Some(123));
        assert_eq!(owner("ves-verify-loads-pid7-x"), Some(7));
        assert_eq!(owner("ves-mesh-pid42-Zq9"), Some(42));
        for other in [
            "ves-view-abc",
            "ves-pid1-x",
            "ves-view-pid-x",
            "ves-view-pid12",
            "ves-view-pid1x-y",
            "vesx-view-pid1-a",
            "ves-Vi-pid1-a",
        ] {
            assert_eq!(owner(other), None, "{other}");
        }
    }

    /// The folder is 0700 and what [`write`] makes in it 0600; dropped, it is gone.
    #[test]
    fn a_work_folder_is_private_and_removed_when_dropped() {
        let w = WorkDir::new("test").unwrap();
        let meta = std::fs::metadata(w.path()).unwrap();
        assert_eq!(meta.mode() & 0o777, 0o700);
        let f = w.path().join("part.step");
        write(&f, b"ISO-10303-21;").unwrap();
        assert_eq!(std::fs::metadata(&f).unwrap().mode() & 0o777, 0o600);
        assert!(live().contains(&w.path().to_path_buf()));
        let path = w.path().to_path_buf();
        drop(w);
        assert!(!path.exists());
        assert!(!live().contains(&path));
    }

    /// Folders of dead owners go, of any kind; a live owner's, a held lock's, another name's
    /// stay.
    #[test]
    fn only_folders_of_dead_owners_are_removed() {
        let tmp = tempfile::tempdir().unwrap();
        let dead = dead_pid();
        let make = |name: &str| {
            let p = tmp.path().join(name);
            std::fs::create_dir(&p).unwrap();
            std::fs::write(p.join("basis-1.h5"), b"x").unwrap();
            p
        };
        let gone = [
            make(&format!("ves-view-pid{dead}-a")),
            make(&format!("ves-verify-loads-pid{dead}-b")),
        ];
        let parent = std::os::unix::process::parent_id();
        let kept = [
            make(&format!("ves-view-pid{parent}-c")),
            make(&format!("other-pid{dead}-d")),
        ];
        // A dead pid whose folder's lock is held (an owner in another PID namespace).
        let held = make(&format!("ves-mesh-pid{dead}-e"));
        let lock = std::fs::File::create(held.join(LOCK)).unwrap();
        assert!(crate::os::lock_exclusive(&lock, true));
        remove_stale(tmp.path());
        for p in gone {
            assert!(!p.exists(), "{} stays", p.display());
        }
        for p in kept.iter().chain([&held]) {
            assert!(p.exists(), "{} removed", p.display());
        }
    }
}
