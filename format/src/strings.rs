//! String attributes of a basis file, stored as *fixed-length* UTF-8 strings.
//!
//! libhdf5 1.10 copies a variable-length string out of the file's global heap without checking
//! the length stored in the (possibly corrupted) file: one flipped byte there made the loader
//! segfault inside `H5HG_read` (found by the byte-flip test). Fixed-length strings live in the
//! attribute itself, so reading them touches no heap. Files written before this change carry
//! variable-length strings; they are still read (with libhdf5's risk on a corrupted heap).

use hdf5::types::{FixedUnicode, TypeDescriptor, VarLenAscii, VarLenUnicode};

/// Longest string attribute written, bytes (64 KiB): the scene's text is one, so the pipeline
/// refuses a longer scene when it reads it.
pub const MAX_BYTES: usize = 65536;

/// Writes `value` as a fixed-length UTF-8 string attribute (sizes 64 B to [`MAX_BYTES`]).
pub fn write(loc: &hdf5::Location, name: &str, value: &str) -> hdf5::Result<()> {
    macro_rules! put {
        ($n:literal) => {{
            let v: FixedUnicode<$n> = value.parse().map_err(|e| hdf5::Error::from(format!("{name}: {e:?}")))?;
            loc.new_attr::<FixedUnicode<$n>>().create(name)?.write_scalar(&v)
        }};
    }
    match value.len() {
        0..=64 => put!(64),
        65..=1024 => put!(1024),
        1025..=16384 => put!(16384),
        16385..=MAX_BYTES => put!(65536),
        n => Err(hdf5::Error::from(format!(
            "{name}: a {n}-byte string is too long for an attribute"
        ))),
    }
}

/// Reads a string attribute, fixed- or variable-length; `None` when missing or not a string.
pub fn read(loc: &hdf5::Location, name: &str) -> Option<String> {
    let attr = loc.attr(name).ok()?;
    macro_rules! get {
        ($n:literal) => {
            attr.read_scalar::<FixedUnicode<$n>>()
                .ok()
                .map(|s| s.as_str().to_string())
        };
    }
    match attr.dtype().ok()?.to_descriptor().ok()? {
        TypeDescriptor::FixedUnicode(n) | TypeDescriptor::FixedAscii(n) => match n {
            0..=64 => get!(64),
            65..=1024 => get!(1024),
            1025..=16384 => get!(16384),
            16385..=65536 => get!(65536),
            _ => None,
        },
        TypeDescriptor::VarLenUnicode => attr.read_scalar::<VarLenUnicode>().ok().map(|s| s.as_str().to_string()),
        TypeDescriptor::VarLenAscii => attr.read_scalar::<VarLenAscii>().ok().map(|s| s.as_str().to_string()),
        _ => None,
    }
}
