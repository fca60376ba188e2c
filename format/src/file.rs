//! Opening and creating HDF5 files the way every VES reader and writer does: without HDF5's
//! file lock, and with the descriptor closed on exec.
//!
//! Why no lock: libhdf5 (≥ 1.10) takes a `flock` on every file it opens, shared to read and
//! exclusive to write, and fails the open with errno 11 when it cannot. A basis is written under
//! a temporary name and renamed into place (`ves precompute`, the workshop), so a reader never
//! sees a file being written and needs no lock; a lock only adds a way to fail.
//!
//! Why close-on-exec: libhdf5 opens its descriptor without `O_CLOEXEC`, so every child process
//! started while a file is open (mesh workers, reference solvers, another thread's `ves` run in a
//! test) inherits it — and with it the lock, which then lives as long as that child. That was the
//! root cause of the `unable to lock file, errno = 11` failures seen in test runs.

use std::path::Path;

/// Opens an existing file read-only.
pub fn open(path: &Path) -> hdf5::Result<hdf5::File> {
    let file = hdf5::File::with_options()
        .with_fapl(|p| p.file_locking(false))
        .open(path)?;
    close_on_exec(path);
    Ok(file)
}

/// Opens an existing file to read and write (strong close: closing really closes).
pub fn open_rw(path: &Path) -> hdf5::Result<hdf5::File> {
    let file = hdf5::File::with_options()
        .with_fapl(|p| p.file_locking(false).fclose_degree(hdf5::file::FileCloseDegree::Strong))
        .open_rw(path)?;
    close_on_exec(path);
    Ok(file)
}

/// Creates (or truncates) a file. Strong close: closing the file closes everything in it and
/// really closes it, so its errors are the caller's and a reader opening the path next reads the
/// disk, not this handle's cache. `v18`: the 1.8+ file format, which checksums every piece of
/// metadata (a damaged header is then refused by libhdf5 instead of parsed).
pub fn create(path: &Path, v18: bool) -> hdf5::Result<hdf5::File> {
    let file = hdf5::File::with_options()
        .with_fapl(|p| {
            let p = p.file_locking(false).fclose_degree(hdf5::file::FileCloseDegree::Strong);
            if v18 { p.libver_v18() } else { p }
        })
        .create(path)?;
    close_on_exec(path);
    Ok(file)
}

/// Marks the descriptors of `path` that this process holds close-on-exec. libhdf5 gives no
/// descriptor through a safe API, so they are found by what they are: `/proc/self/fd` entries
/// whose device and inode are the file's (another descriptor of the same file gains the flag too,
/// which is what every descriptor of a basis should have). Where /proc cannot be read, nothing is
/// done.
fn close_on_exec(path: &Path) {
    use std::os::unix::fs::MetadataExt;
    let Ok(meta) = std::fs::metadata(path) else {
        return;
    };
    let Ok(fds) = std::fs::read_dir("/proc/self/fd") else {
        return;
    };
    for fd in fds
        .flatten()
        .filter_map(|e| e.file_name().to_str()?.parse::<libc::c_int>().ok())
    {
        let mut st = std::mem::MaybeUninit::<libc::stat>::uninit();
        // SAFETY: fstat writes the struct given or fails (a descriptor closed meanwhile, such as
        // the listing's own); fcntl changes only the descriptor's flags, and only on this file's.
        unsafe {
            if libc::fstat(fd, st.as_mut_ptr()) != 0 {
                continue;
            }
            let st = st.assume_init();
            if st.st_dev == meta.dev() && st.st_ino == meta.ino() {
                let flags = libc::fcntl(fd, libc::F_GETFD);
                if flags >= 0 && flags & libc::FD_CLOEXEC == 0 {
                    libc::fcntl(fd, libc::F_SETFD, flags | libc::FD_CLOEXEC);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The descriptors of files open in this process, as the paths they name, seen by a child
    /// process started now.
    fn inherited_by_a_child() -> Vec<String> {
        let out = std::process::Command::new("sh")
            .arg("-c")
            .arg("for f in /proc/self/fd/*; do readlink \"$f\"; done")
            .output()
            .expect("sh runs");
        String::from_utf8_lossy(&out.stdout)
            .lines()
            .map(str::to_string)
            .collect()
    }

    /// A child started while a file is open (created, reopened to write, opened to read) does not
    /// hold its descriptor — the lock it would carry failed another process's open with errno 11.
    #[test]
    fn children_inherit_no_descriptor_of_an_open_file() {
        let dir = std::env::temp_dir().join(format!("ves-file-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("a.h5");
        let name = path.display().to_string();
        let f = create(&path, true).unwrap();
        f.create_group("g").unwrap();
        assert!(!inherited_by_a_child().contains(&name), "created file inherited");
        f.close().unwrap();
        let f = open_rw(&path).unwrap();
        assert!(!inherited_by_a_child().contains(&name), "file open to write inherited");
        f.close().unwrap();
        let f = open(&path).unwrap();
        assert!(f.group("g").is_ok());
        assert!(!inherited_by_a_child().contains(&name), "file open to read inherited");
        drop(f);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A file another process holds an exclusive HDF5 lock on (a writer, or a child that inherited
    /// a writer's descriptor) still opens to read.
    #[test]
    fn a_file_locked_elsewhere_still_opens() {
        let dir = std::env::temp_dir().join(format!("ves-file-lock-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("locked.h5");
        create(&path, true).unwrap().close().unwrap();
        // The lock libhdf5 takes to write, held by another open file description.
        let held = std::fs::File::open(&path).unwrap();
        use std::os::fd::AsRawFd;
        // SAFETY: flock on a descriptor this test owns.
        assert_eq!(
            unsafe { libc::flock(held.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) },
            0
        );
        let f = open(&path).expect("opens without taking the lock");
        drop(f);
        drop(held);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
