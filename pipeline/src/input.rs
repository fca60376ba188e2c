//! Input files (the geometry, the scene): what kind of file each is and how large, checked
//! before a byte is read (a FIFO would block the reader forever, `/dev/zero` or a sparse
//! multi-gigabyte file would be read until memory runs out), and its bytes read once.

use std::fs::{File, Metadata};
use std::io::Read;
use std::os::unix::fs::{FileTypeExt, OpenOptionsExt};
use std::path::{Path, PathBuf};

/// Largest geometry file accepted: 1 GiB. The largest STEP files of single parts are tens of
/// megabytes; a gigabyte is a whole assembly or not a part at all, and reading it (OpenCASCADE
/// holds several times the file in memory) would take minutes before failing.
pub const MAX_GEOMETRY_BYTES: u64 = 1 << 30;

/// Largest scene file accepted: 1 MiB (a scene is a page of TOML; the basis stores its text).
pub const MAX_SCENE_BYTES: u64 = 1 << 20;

/// What a file that is not a regular file is, in words (None: a regular file).
pub fn kind(meta: &Metadata) -> Option<&'static str> {
    let t = meta.file_type();
    if t.is_file() {
        None
    } else if t.is_dir() {
        Some("a directory")
    } else if t.is_fifo() {
        Some("a FIFO (named pipe)")
    } else if t.is_char_device() {
        Some("a character device")
    } else if t.is_block_device() {
        Some("a block device")
    } else if t.is_socket() {
        Some("a socket")
    } else {
        Some("not a file")
    }
}

/// Which input a file is: its largest size and what to give instead of a wrong file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileKind {
    /// The part's geometry (STEP, IGES, BREP), at most [`MAX_GEOMETRY_BYTES`].
    Geometry,
    /// A scene file (TOML), at most [`MAX_SCENE_BYTES`].
    Scene,
}

impl FileKind {
    /// The largest file of this kind accepted, bytes.
    pub fn max_bytes(self) -> u64 {
        match self {
            FileKind::Geometry => MAX_GEOMETRY_BYTES,
            FileKind::Scene => MAX_SCENE_BYTES,
        }
    }

    /// What to give instead of something that is not a regular file.
    fn instead(self) -> &'static str {
        match self {
            FileKind::Geometry => "give the part's STEP file itself",
            FileKind::Scene => "give the scene's TOML file",
        }
    }

    /// Why a file over the limit is refused and what to give instead.
    fn too_big(self) -> &'static str {
        match self {
            FileKind::Geometry => {
                "(a single part's STEP file is far smaller): give the one part's file, or simplify or defeature it in CAD"
            }
            FileKind::Scene => "(a scene is a page of TOML): give the scene file itself",
        }
    }
}

/// An input file that cannot be read: one line naming it, saying what it is and what to give
/// instead.
#[derive(Debug, thiserror::Error)]
pub enum InputError {
    /// Nothing at the path.
    #[error("file not found at {}", path.display())]
    NotFound {
        /// The path given.
        path: PathBuf,
        /// Which input.
        file: FileKind,
    },
    /// The system refused to examine, open or read it.
    #[error("{}: cannot be read: {error}", path.display())]
    Unreadable {
        /// The path given.
        path: PathBuf,
        /// Which input.
        file: FileKind,
        /// The system's error (in the message, so not also a `source`).
        error: std::io::Error,
    },
    /// A directory, FIFO, device or socket.
    #[error("{} is {what}, not a regular file; {}", path.display(), file.instead())]
    NotRegular {
        /// The path given.
        path: PathBuf,
        /// Which input.
        file: FileKind,
        /// What it is instead, in words (see [`kind`]).
        what: &'static str,
    },
    /// Larger than inputs of its kind may be.
    #[error(
        "{} is {}; files over {} of this kind are refused {}",
        path.display(), bytes(*len, false), bytes(file.max_bytes(), true), file.too_big()
    )]
    TooLarge {
        /// The path given.
        path: PathBuf,
        /// Which input.
        file: FileKind,
        /// Its size, bytes.
        len: u64,
    },
    /// It grew past the limit while it was read.
    #[error("{} grew past {} while it was read; give a finished file", path.display(), bytes(file.max_bytes(), true))]
    Grew {
        /// The path given.
        path: PathBuf,
        /// Which input.
        file: FileKind,
    },
    /// A scene file that is not UTF-8.
    #[error("{}: is not UTF-8 text; save the scene as UTF-8", path.display())]
    NotUtf8 {
        /// The path given.
        path: PathBuf,
    },
}

impl InputError {
    /// Which input failed.
    pub fn file(&self) -> FileKind {
        match self {
            InputError::NotFound { file, .. }
            | InputError::Unreadable { file, .. }
            | InputError::NotRegular { file, .. }
            | InputError::TooLarge { file, .. }
            | InputError::Grew { file, .. } => *file,
            InputError::NotUtf8 { .. } => FileKind::Scene,
        }
    }
}

fn check(path: &Path, meta: &Metadata, file: FileKind) -> Result<u64, InputError> {
    if let Some(what) = kind(meta) {
        return Err(InputError::NotRegular {
            path: path.to_path_buf(),
            file,
            what,
        });
    }
    let len = meta.len();
    if len > file.max_bytes() {
        return Err(InputError::TooLarge {
            path: path.to_path_buf(),
            file,
            len,
        });
    }
    Ok(len)
}

/// A size in GiB or MiB, as a message shows it: two decimals, or whole units for a limit.
fn bytes(n: u64, whole: bool) -> String {
    let (unit, name) = if n >= 1 << 30 {
        (1u64 << 30, "GiB")
    } else {
        (1u64 << 20, "MiB")
    };
    if whole {
        format!("{} {name}", n / unit)
    } else {
        format!("{:.2} {name}", n as f64 / unit as f64)
    }
}

/// Opens `path` for reading if it is a regular file (symlinks followed) of at most
/// [`MAX_GEOMETRY_BYTES`]; else one line saying what it is. The type is checked before opening
/// (a device is never opened) and again on the open file (it may have been replaced between).
pub fn open(path: &Path) -> Result<(File, u64), InputError> {
    open_as(path, FileKind::Geometry)
}

fn open_as(path: &Path, file: FileKind) -> Result<(File, u64), InputError> {
    let unreadable = |error| InputError::Unreadable {
        path: path.to_path_buf(),
        file,
        error,
    };
    let meta = std::fs::metadata(path).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => InputError::NotFound {
            path: path.to_path_buf(),
            file,
        },
        _ => unreadable(e),
    })?;
    check(path, &meta, file)?;
    // Non-blocking: opening a FIFO put there meanwhile returns at once (and fstat refuses it).
    let opened = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK)
        .open(path)
        .map_err(unreadable)?;
    let meta = opened.metadata().map_err(unreadable)?;
    let len = check(path, &meta, file)?;
    Ok((opened, len))
}

/// The bytes of the geometry file at `path`, read once, after the checks of [`open`].
pub fn read(path: &Path) -> Result<Vec<u8>, InputError> {
    read_as(path, FileKind::Geometry)
}

/// The text of the scene file at `path` (a regular file of at most [`MAX_SCENE_BYTES`], UTF-8).
pub fn read_scene(path: &Path) -> Result<String, InputError> {
    String::from_utf8(read_as(path, FileKind::Scene)?).map_err(|_| InputError::NotUtf8 {
        path: path.to_path_buf(),
    })
}

fn read_as(path: &Path, file: FileKind) -> Result<Vec<u8>, InputError> {
    let (opened, len) = open_as(path, file)?;
    let max = file.max_bytes();
    let mut bytes = Vec::with_capacity(len as usize);
    // A file that grows while read is cut one byte past the limit, and refused.
    opened
        .take(max + 1)
        .read_to_end(&mut bytes)
        .map_err(|error| InputError::Unreadable {
            path: path.to_path_buf(),
            file,
            error,
        })?;
    if bytes.len() as u64 > max {
        return Err(InputError::Grew {
            path: path.to_path_buf(),
            file,
        });
    }
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A FIFO, a character device and a sparse file over the limit are refused at once (none
    /// is read); a small regular file is read.
    #[test]
    fn only_regular_files_of_sane_size_are_read() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("part.step");
        crate::make_fifo(&fifo);
        let t = std::time::Instant::now();
        let e = read(&fifo).unwrap_err().to_string();
        assert!(e.contains("FIFO") && e.contains("not a regular file"), "{e}");
        let e = read(Path::new("/dev/zero")).unwrap_err().to_string();
        assert!(e.contains("character device"), "{e}");
        let big = dir.path().join("big.step");
        File::create(&big).unwrap().set_len(2 << 30).unwrap();
        let e = read(&big).unwrap_err().to_string();
        assert!(e.contains("2.00 GiB") && e.contains("over 1 GiB"), "{e}");
        assert!(t.elapsed().as_secs_f64() < 2.0, "{:?}", t.elapsed());
        let small = dir.path().join("small.step");
        std::fs::write(&small, b"ISO-10303-21;").unwrap();
        assert_eq!(read(&small).unwrap(), b"ISO-10303-21;");
        assert!(
            read(&dir.path().join("none.step"))
                .unwrap_err()
                .to_string()
                .contains("file not found")
        );
        // The scene file: the same checks, its own limit.
        let scene_fifo = dir.path().join("s.toml");
        crate::make_fifo(&scene_fifo);
        assert!(read_scene(&scene_fifo).unwrap_err().to_string().contains("TOML"));
        assert!(
            read_scene(Path::new("/dev/zero"))
                .unwrap_err()
                .to_string()
                .contains("character device")
        );
        File::create(&big).unwrap().set_len(2 << 20).unwrap();
        assert!(read_scene(&big).unwrap_err().to_string().contains("2.00 MiB"));
    }
}
