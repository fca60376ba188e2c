//! Haptic devices: position (and button) in, force out, SI units.
//!
//! A device is open from the moment it exists: [`open`] makes one from a spec such as
//! `script:hand.csv` (or a type's own constructor does, e.g. [`ScriptedDevice::load`]), so there
//! is no half-open state to guard. The haptic thread then reads it — a read may fail with a
//! [`DeviceFault`] — and writes forces to it; the session closes it when it ends, whichever way
//! it ends.
//!
//! Adding a device: its own file in this folder (a type implementing [`Device`] and a `KIND`
//! saying how a spec opens it) and one line in [`KINDS`].

mod fault;
mod script;

pub use fault::DeviceFault;
pub use script::{MAX_SCRIPT_BYTES, ScriptError, ScriptedDevice};

use std::path::Path;
use ves_format::InputError;

/// The kinds of device a spec can name, each `name` or `name:ARGUMENT`.
pub static KINDS: &[Kind] = &[script::KIND];

/// What a device reports at one instant.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DeviceState {
    /// End-effector position, m.
    pub position: [f64; 3],
    /// End-effector velocity, m/s.
    pub velocity: [f64; 3],
    /// Button held.
    pub button: bool,
}

/// What a device says about itself (asked outside the haptic loop).
#[derive(Clone, Copy, Debug)]
pub struct DeviceInfo<'a> {
    /// What it is, for messages and statistics: its file, or its kind.
    pub name: &'a str,
    /// Length of a recorded motion, s: the session's length when none is given. `None`: a live
    /// device, which runs until the session is stopped.
    pub length_s: Option<f64>,
    /// A file it reads: a session's outputs must not overwrite it.
    pub file: Option<&'a Path>,
}

/// A haptic device, open from its construction until [`close`](Device::close). `read`, `write`
/// and `observe` are called from the haptic thread at its rate: they must neither block nor
/// allocate.
pub trait Device: Send {
    /// What the device says about itself.
    fn info(&self) -> DeviceInfo<'_> {
        DeviceInfo {
            name: "device",
            length_s: None,
            file: None,
        }
    }

    /// State at session time `t` (s), or why there is none. A session ends at a device's first
    /// fault, with zero force sent to every device.
    fn read(&mut self, t: f64) -> Result<DeviceState, DeviceFault>;

    /// Force to render, N (already limited by the runtime).
    fn write(&mut self, force: [f64; 3]);

    /// Everything the step gave this hand (vertex, contact, strain, stress), after `write`.
    fn observe(&mut self, _out: &crate::haptic::HandOutput) {}

    /// Stops the device: no force any more, its resources released; later reads fail with
    /// [`DeviceFault::Disconnected`]. A session closes its devices when it ends (also on an
    /// error or a fault); closing again does nothing. A device holding hardware also closes
    /// itself when dropped, for the embedder that drops it without a session.
    fn close(&mut self) {}
}

/// One kind of device: the name that starts a spec, and how the rest of the spec opens it.
pub struct Kind {
    /// The spec's name: `script` in `script:hand.csv`.
    pub name: &'static str,
    /// What follows `name:` (empty: the spec is the name alone), e.g. `FILE.csv`.
    pub argument: &'static str,
    /// What the device is or does, for usage lines.
    pub about: &'static str,
    /// Opens a device from the text after `name:` (empty when there is none).
    pub open: fn(&str) -> Result<Box<dyn Device>, InputError>,
}

impl Kind {
    /// How a spec of this kind is written, e.g. `` `script:FILE.csv` (t, x, y, z[, button] in SI
    /// units) ``.
    pub fn usage(&self) -> String {
        let colon = if self.argument.is_empty() { "" } else { ":" };
        format!("`{}{colon}{}` ({})", self.name, self.argument, self.about)
    }
}

/// Every kind's usage line, separated by `; `.
pub fn usage() -> String {
    KINDS.iter().map(Kind::usage).collect::<Vec<_>>().join("; ")
}

/// Opens the device a spec names: `name` or `name:ARGUMENT`, `name` one of [`KINDS`]. The one
/// place a spec is parsed.
pub fn open(spec: &str) -> Result<Box<dyn Device>, InputError> {
    let (name, argument) = spec.split_once(':').unwrap_or((spec, ""));
    match KINDS.iter().find(|k| k.name == name) {
        Some(kind) => (kind.open)(argument),
        None => Err(InputError {
            path: format!("device {spec:?}"),
            message: format!("not a kind of device; use {}", usage()),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A spec is looked up by its name alone; an unknown one is refused with every kind's usage.
    #[test]
    fn specs_open_their_kind_or_list_the_kinds() {
        let dir = std::env::temp_dir().join(format!("ves-device-spec-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let file = dir.join("hand.csv");
        std::fs::write(&file, "0,1,2,3\n2,1,2,3\n").expect("script");
        let d = open(&format!("script:{}", file.display())).expect("opens");
        let info = d.info();
        assert_eq!(info.length_s, Some(2.0));
        assert_eq!(info.file, Some(file.as_path()));
        assert_eq!(info.name, file.display().to_string());
        for bad in ["mouse:0", "mouse", "", "scripts:hand.csv"] {
            let e = open(bad).err().expect("refused").to_string();
            assert!(
                e.contains(&format!("{bad:?}")) && e.contains("`script:FILE.csv` (t, x, y, z"),
                "{e}"
            );
        }
        let e = open("script:/nonexistent.csv").err().expect("refused").to_string();
        assert!(e.contains("/nonexistent.csv"), "{e}");
        // No file at all: said so, not an error about a file named "".
        let e = open("script:").err().expect("refused").to_string();
        assert!(e.contains("no file after `script:`"), "{e}");
        // A file name that would drive the terminal is shown escaped.
        let e = open("script:a\u{1b}[31mb.csv").err().expect("refused").to_string();
        assert!(!e.contains('\u{1b}') && e.contains("a\\u{1b}[31mb.csv"), "{e:?}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
