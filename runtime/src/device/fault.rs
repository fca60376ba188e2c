//! Why a device read gave no sample.

/// A device's fault. Plain and `Copy`: it is made on the haptic thread, which must not allocate;
/// a device with more to say (a driver's code) logs it itself.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, thiserror::Error)]
#[serde(rename_all = "snake_case")]
pub enum DeviceFault {
    /// The device is gone: unplugged, its connection lost, or closed.
    #[error("the device is disconnected (unplugged, its connection lost, or closed)")]
    Disconnected,
    /// The device reports a position outside its workspace or one it cannot measure.
    #[error("the device reports a position outside its workspace")]
    OutOfRange,
    /// The device did not answer within its deadline.
    #[error("the device did not answer in time")]
    Timeout,
    /// The device reports a fault of its own (amplifier, encoder, safety switch).
    #[error("the device reports a fault of its own (amplifier, encoder, safety switch)")]
    Hardware,
}
