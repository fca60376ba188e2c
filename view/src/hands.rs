//! The browser as a haptic device: a hand slot written by the client that owns it, read by the
//! haptic thread through the same [`Device`] trait as every other device.

use std::sync::Arc;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use ves_runtime::device::{Device, DeviceFault, DeviceInfo, DeviceState};
use ves_runtime::haptic::HandOutput;
use ves_runtime::snapshot::Snapshot;

/// Input layout in the snapshot: x, y, z, button, active, message sequence number.
const INPUT: usize = 6;
/// Output layout: force (3), vertex, contact, clamped, vertex position (3), strain, strain
/// exceeded, von Mises, safety factor, stress exceeded, message sequence read, principal
/// stress, principal strain, displacement (3), grip gap, grabbing, felt error.
const OUTPUT: usize = 23;

/// One hand shared between the web clients and the haptic thread.
pub struct HandSlot {
    input: Snapshot,
    output: Snapshot,
    /// The client driving this hand (0: none).
    owner: AtomicU64,
    /// One writer at a time for the input snapshot (clients are tasks on several threads).
    writer: Mutex<()>,
}

/// What a client asked of a hand.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HandCommand {
    /// Target position, m (part frame).
    pub position: [f64; 3],
    /// Grab (true) or press (false).
    pub button: bool,
    /// Driving the hand; false releases it.
    pub active: bool,
    /// The client's sequence number of this message.
    pub seq: u32,
}

/// What the status shows of a hand.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct HandStatus {
    /// The client driving it (0: none).
    pub owner: u64,
    /// Driven.
    pub active: bool,
    /// Grabbing (else pressing).
    pub button: bool,
    /// The position the client asked for, m.
    pub target: [f64; 3],
    /// The last of the owner's messages the haptic loop read.
    pub seq: u32,
    /// What the haptic loop last gave this hand (in JSON beside the fields above; an infinite
    /// safety factor is null).
    #[serde(flatten)]
    pub output: HandOutput,
}

/// A hand's output and the message it answered, as the snapshot holds them (the inverse of
/// [`decode`]).
fn encode(out: &HandOutput, seq: u32) -> [f64; OUTPUT] {
    let b = |x: bool| f64::from(u8::from(x));
    [
        out.force[0],
        out.force[1],
        out.force[2],
        f64::from(out.vertex),
        b(out.contact),
        b(out.clamped),
        out.vertex_position[0],
        out.vertex_position[1],
        out.vertex_position[2],
        out.strain,
        b(out.strain_exceeded),
        out.von_mises,
        out.safety_factor,
        b(out.stress_exceeded),
        f64::from(seq),
        out.principal_stress,
        out.principal_strain,
        out.displacement[0],
        out.displacement[1],
        out.displacement[2],
        out.grip_gap,
        b(out.grabbing),
        out.felt_error,
    ]
}

fn decode(o: &[f64; OUTPUT]) -> (HandOutput, u32) {
    let out = HandOutput {
        force: [o[0], o[1], o[2]],
        vertex: o[3] as u32,
        contact: o[4] != 0.0,
        clamped: o[5] != 0.0,
        vertex_position: [o[6], o[7], o[8]],
        strain: o[9],
        strain_exceeded: o[10] != 0.0,
        von_mises: o[11],
        safety_factor: o[12],
        stress_exceeded: o[13] != 0.0,
        principal_stress: o[15],
        principal_strain: o[16],
        displacement: [o[17], o[18], o[19]],
        grip_gap: o[20],
        grabbing: o[21] != 0.0,
        felt_error: o[22],
    };
    (out, o[14] as u32)
}

impl Default for HandSlot {
    fn default() -> Self {
        HandSlot {
            input: Snapshot::new(INPUT),
            output: Snapshot::new(OUTPUT),
            owner: AtomicU64::new(0),
            writer: Mutex::new(()),
        }
    }
}

impl HandSlot {
    /// Applies a client's command; false when another client drives this hand (dropped).
    pub fn command(&self, client: u64, c: &HandCommand) -> bool {
        let _w = self.writer.lock().unwrap_or_else(|p| p.into_inner());
        let owner = self.owner.load(Ordering::Acquire);
        if owner != 0 && owner != client {
            return false;
        }
        if !c.active && owner == 0 {
            return true;
        }
        let v = [
            c.position[0],
            c.position[1],
            c.position[2],
            f64::from(u8::from(c.button)),
            f64::from(u8::from(c.active)),
            f64::from(c.seq),
        ];
        self.input.publish(&v, 0.0);
        self.owner.store(if c.active { client } else { 0 }, Ordering::Release);
        true
    }

    /// Lets go of the hand if `client` drives it (the client left).
    pub fn release(&self, client: u64) {
        self.release_if(|owner| owner == client);
    }

    /// Lets go of the hand whoever drives it (a reset of the session).
    pub fn release_any(&self) {
        self.release_if(|_| true);
    }

    fn release_if(&self, whose: impl Fn(u64) -> bool) {
        let _w = self.writer.lock().unwrap_or_else(|p| p.into_inner());
        if whose(self.owner.load(Ordering::Acquire)) {
            let mut v = [0.0; INPUT];
            self.input.read(&mut v);
            v[4] = 0.0;
            self.input.publish(&v, 0.0);
            self.owner.store(0, Ordering::Release);
        }
    }

    /// The hand as the status shows it.
    pub fn status(&self) -> HandStatus {
        let (mut i, mut o) = ([0.0; INPUT], [0.0; OUTPUT]);
        self.input.read(&mut i);
        self.output.read(&mut o);
        let active = i[4] != 0.0;
        let (mut output, seq) = decode(&o);
        // A hand let go is not in contact, even before the haptic loop's next step says so.
        output.contact &= active;
        HandStatus {
            owner: self.owner.load(Ordering::Relaxed),
            active,
            button: i[3] != 0.0,
            target: [i[0], i[1], i[2]],
            seq,
            output,
        }
    }

    /// Haptic steps that reported on this hand so far.
    pub fn steps(&self) -> u64 {
        let mut o = [0.0; OUTPUT];
        self.output.read(&mut o).1
    }

    /// The last message sequence number the haptic loop read.
    pub fn seq_read(&self) -> u32 {
        let mut o = [0.0; OUTPUT];
        self.output.read(&mut o);
        decode(&o).1
    }
}

/// A hand driven from a browser: the pointer's target arrives at display rate (≈ 60 Hz) in
/// steps; the device follows it through a first-order filter (time constant `TAU`) so the
/// coupling spring sees a smooth path and a consistent velocity instead of 16 ms jumps.
pub struct WebHand {
    slot: Arc<HandSlot>,
    dt: f64,
    x: [f64; 3],
    v: [f64; 3],
    following: bool,
    seq: u32,
}

/// The hand's smoothing time constant, s.
pub const TAU: f64 = 0.015;

impl WebHand {
    /// A device reading `slot` at the haptic step `dt`.
    pub fn new(slot: Arc<HandSlot>, dt: f64) -> WebHand {
        WebHand {
            slot,
            dt,
            x: [0.0; 3],
            v: [0.0; 3],
            following: false,
            seq: 0,
        }
    }
}

impl Device for WebHand {
    fn info(&self) -> DeviceInfo<'_> {
        DeviceInfo {
            name: "page",
            length_s: None,
            file: None,
        }
    }

    /// Never faults: a hand no client drives is absent (no vertex, no force), not broken.
    fn read(&mut self, _t: f64) -> Result<DeviceState, DeviceFault> {
        let mut i = [0.0; INPUT];
        self.slot.input.read(&mut i);
        self.seq = i[5] as u32;
        if i[4] == 0.0 {
            // No hand: a non-finite position gives no vertex and no force.
            self.following = false;
            return Ok(DeviceState {
                position: [f64::NAN; 3],
                velocity: [0.0; 3],
                button: false,
            });
        }
        let target = [i[0], i[1], i[2]];
        if !self.following {
            // A new grab starts where it was asked, at rest.
            self.x = target;
            self.v = [0.0; 3];
            self.following = true;
        } else {
            let a = 1.0 - (-self.dt / TAU).exp();
            for ((x, v), t) in self.x.iter_mut().zip(&mut self.v).zip(target) {
                let step = a * (t - *x);
                *x += step;
                *v = step / self.dt;
            }
        }
        Ok(DeviceState {
            position: self.x,
            velocity: self.v,
            button: i[3] != 0.0,
        })
    }

    fn write(&mut self, _force: [f64; 3]) {}

    fn observe(&mut self, out: &HandOutput) {
        self.slot.output.publish(&encode(out, self.seq), 0.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every field crosses the snapshot to its own place (distinct values everywhere).
    #[test]
    fn a_hand_output_crosses_the_snapshot_unchanged() {
        let out = HandOutput {
            force: [1.0, 2.0, 3.0],
            vertex: 4,
            contact: true,
            clamped: false,
            vertex_position: [5.0, 6.0, 7.0],
            strain: 8.0,
            strain_exceeded: true,
            von_mises: 9.0,
            safety_factor: 10.0,
            stress_exceeded: false,
            principal_stress: 11.0,
            principal_strain: 12.0,
            displacement: [14.0, 15.0, 16.0],
            grip_gap: 17.0,
            grabbing: true,
            felt_error: 18.0,
        };
        let (back, seq) = decode(&encode(&out, 13));
        assert_eq!(seq, 13);
        assert_eq!(serde_json::to_value(back).unwrap(), serde_json::to_value(out).unwrap());
    }
}
