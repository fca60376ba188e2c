//! Haptic devices: position (and button) in, force out, SI units.
//!
//! A device is open from the moment it exists: its constructor (e.g. [`ScriptedDevice::load`])
//! opens it or says why not, so there is no half-open state to guard. The haptic thread then
//! reads it — a read may fail with a [`DeviceFault`] — and writes forces to it; the session
//! closes it when it ends, whichever way it ends.

mod fault;
mod script;

pub use fault::DeviceFault;
pub use script::{MAX_SCRIPT_BYTES, ScriptError, ScriptedDevice};

use std::path::Path;

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
