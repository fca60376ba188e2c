//! Input files (the geometry, the scene): what kind of file each is and how large, checked
//! before a byte is read (a FIFO would block the reader forever, `/dev/zero` or a sparse
//! multi-gigabyte file would be read until memory runs out), and its bytes read once.

use std::fs::{File, Metadata};
use std::io::Read;
use std::os::unix::fs::{FileTypeExt, OpenOptionsExt};
use std::path::Path;

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

/// What is read: its largest size and what to give instead of a wrong file.
struct Kind {
    max: u64,
    instead: &'static str,
    too_big: &'static str,
}

const GEOMETRY: Kind = Kind {
    max: MAX_GEOMETRY_BYTES,
    instead: "give the part's STEP file itself",
    too_big: "(a single part's STEP file is far smaller): give the one part's file, or simplify or defeature it in CAD",
};

const SCENE: Kind = Kind {
    max: MAX_SCENE_BYTES,
    instead: "give the scene's TOML file",
    too_big: "(a scene is a page of TOML): give the scene file itself",
};

fn check(path: &Path, meta: &Metadata, what: &Kind) -> Result<u64, String> {
    if let Some(k) = kind(meta) {
        return Err(format!(
            "{} is {k}, not a regular file; {}",
            path.display(),
            what.instead
        ));
    }
    let len = meta.len();
    if len > what.max {
        return Err(format!(
            "{} is {}; files over {} of this kind are refused {}",
            path.display(),
            bytes(len, false),
            bytes(what.max, true),
            what.too_big
        ));
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
pub fn open(path: &Path) -> Result<(File, u64), String> {
    open_as(path, &GEOMETRY)
}

fn open_as(path: &Path, what: &Kind) -> Result<(File, u64), String> {
    let meta = std::fs::metadata(path).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => format!("file not found at {}", path.display()),
        _ => format!("{}: cannot be read: {e}", path.display()),
    })?;
    check(path, &meta, what)?;
    // Non-blocking: opening a FIFO put there meanwhile returns at once (and fstat refuses it).
    let file = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK)
        .open(path)
        .map_err(|e| format!("{}: cannot be read: {e}", path.display()))?;
    let meta = file
        .metadata()
        .map_err(|e| format!("{}: cannot be read: {e}", path.display()))?;
    let len = check(path, &meta, what)?;
    Ok((file, len))
}

/// The bytes of the geometry file at `path`, read once, after the checks of [`open`].
pub fn read(path: &Path) -> Result<Vec<u8>, String> {
    read_as(path, &GEOMETRY)
}

/// The text of the scene file at `path` (a regular file of at most [`MAX_SCENE_BYTES`], UTF-8).
pub fn read_scene(path: &Path) -> Result<String, String> {
    String::from_utf8(read_as(path, &SCENE)?)
        .map_err(|_| format!("{}: is not UTF-8 text; save the scene as UTF-8", path.display()))
}

fn read_as(path: &Path, what: &Kind) -> Result<Vec<u8>, String> {
    let (file, len) = open_as(path, what)?;
    let mut bytes = Vec::with_capacity(len as usize);
    // A file that grows while read is cut one byte past the limit, and refused.
    file.take(what.max + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| format!("{}: cannot be read: {e}", path.display()))?;
    if bytes.len() as u64 > what.max {
        return Err(format!(
            "{} grew past {} while it was read; give a finished file",
            path.display(),
            self::bytes(what.max, true)
        ));
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
        let e = read(&fifo).unwrap_err();
        assert!(e.contains("FIFO") && e.contains("not a regular file"), "{e}");
        let e = read(Path::new("/dev/zero")).unwrap_err();
        assert!(e.contains("character device"), "{e}");
        let big = dir.path().join("big.step");
        File::create(&big).unwrap().set_len(2 << 30).unwrap();
        let e = read(&big).unwrap_err();
        assert!(e.contains("2.00 GiB") && e.contains("over 1 GiB"), "{e}");
        assert!(t.elapsed().as_secs_f64() < 2.0, "{:?}", t.elapsed());
        let small = dir.path().join("small.step");
        std::fs::write(&small, b"ISO-10303-21;").unwrap();
        assert_eq!(read(&small).unwrap(), b"ISO-10303-21;");
        assert!(
            read(&dir.path().join("none.step"))
                .unwrap_err()
                .contains("file not found")
        );
        // The scene file: the same checks, its own limit.
        let scene_fifo = dir.path().join("s.toml");
        crate::make_fifo(&scene_fifo);
        assert!(read_scene(&scene_fifo).unwrap_err().contains("TOML"));
        assert!(
            read_scene(Path::new("/dev/zero"))
                .unwrap_err()
                .contains("character device")
        );
        File::create(&big).unwrap().set_len(2 << 20).unwrap();
        assert!(read_scene(&big).unwrap_err().contains("2.00 MiB"));
    }
}
