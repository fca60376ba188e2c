//! A session whose device faults, or that fails before it starts, ends cleanly with its devices
//! let go and closed.

use super::*;
use crate::device::{DeviceFault, DeviceInfo, DeviceState};
use std::sync::Mutex;

/// What the session did to a device, seen from the test.
#[derive(Default)]
struct Seen {
    reads: u64,
    forces: Vec<[f64; 3]>,
    closes: u32,
}

/// A hand that grabs the grid's centre and pulls 1 mm along x, faulting from its read
/// `fault_after` on (`None`: never).
struct Hand {
    fault_after: Option<u64>,
    seen: Arc<Mutex<Seen>>,
}

impl Hand {
    fn boxed(fault_after: Option<u64>) -> (Box<dyn Device>, Arc<Mutex<Seen>>) {
        let seen = Arc::new(Mutex::new(Seen::default()));
        let hand = Hand {
            fault_after,
            seen: seen.clone(),
        };
        (Box::new(hand), seen)
    }
}

impl Device for Hand {
    fn info(&self) -> DeviceInfo<'_> {
        DeviceInfo {
            name: if self.fault_after.is_some() { "faulty" } else { "steady" },
            length_s: None,
            file: None,
        }
    }

    fn read(&mut self, t: f64) -> Result<DeviceState, DeviceFault> {
        let mut seen = self.seen.lock().expect("not poisoned");
        assert_eq!(seen.closes, 0, "read after close");
        if self.fault_after.is_some_and(|n| seen.reads >= n) {
            return Err(DeviceFault::Disconnected);
        }
        seen.reads += 1;
        let pull = if t > 0.0 { 1e-3 } else { 0.0 };
        Ok(DeviceState {
            position: [0.01 + pull, 0.01, 0.0],
            velocity: [0.0; 3],
            button: true,
        })
    }

    fn write(&mut self, force: [f64; 3]) {
        self.seen.lock().expect("not poisoned").forces.push(force);
    }

    fn close(&mut self) {
        self.seen.lock().expect("not poisoned").closes += 1;
    }
}

fn grid() -> Arc<Basis> {
    Arc::new(crate::basis::stretch_grid(100.0, 1e4, 100.0))
}

fn config() -> SessionConfig {
    SessionConfig {
        rate_hz: 1000.0,
        duration_s: 1.0,
        free_body: None,
        ..Default::default()
    }
}

/// A device that faults after 50 reads ends a 1000-step session at step 50: no panic, no error,
/// zero force written to every device at that step, the fault in the statistics, every device
/// closed. Either hand may be the one.
#[test]
fn a_device_fault_ends_the_session_with_zero_force() {
    const N: u64 = 50;
    for faulty in 0..2 {
        let (a, seen_a) = Hand::boxed((faulty == 0).then_some(N));
        let (b, seen_b) = Hand::boxed((faulty == 1).then_some(N));
        let stats = run(grid(), vec![a, b], &config()).expect("a fault is no error");
        assert_eq!(stats.steps, N, "the faulted step is not counted");
        let f = stats.device_fault.clone().expect("the fault is reported");
        assert_eq!(
            (f.hand, f.device.as_str(), f.fault, f.step),
            (faulty, "faulty", DeviceFault::Disconnected, N)
        );
        assert!((f.time_s - N as f64 * 1e-3).abs() < 1e-12, "{f:?}");
        assert_eq!(stats.final_forces_n, vec![[0.0; 3]; 2], "the last force sent is zero");
        for seen in [&seen_a, &seen_b] {
            let seen = seen.lock().expect("not poisoned");
            let forces = &seen.forces;
            assert_eq!(forces.len() as u64, N + 1, "a force per step, then the zero");
            assert!(
                forces[forces.len() - 2].iter().any(|&c| c != 0.0),
                "the pull was felt: {forces:?}"
            );
            assert_eq!(forces[forces.len() - 1], [0.0; 3], "let go at the fault");
            assert!(seen.closes >= 1, "closed");
        }
        let v = serde_json::to_value(&stats).expect("serializes");
        assert_eq!(v["device_fault"]["fault"], "disconnected", "{v}");
    }
}

/// Without a fault the session runs its length and reports none; its devices are closed too.
#[test]
fn a_session_without_fault_reports_none_and_closes_its_devices() {
    let (a, seen) = Hand::boxed(None);
    let cfg = SessionConfig {
        duration_s: 0.02,
        ..config()
    };
    let stats = run(grid(), vec![a], &cfg).expect("runs");
    assert_eq!(stats.steps, 20);
    assert!(stats.device_fault.is_none());
    assert!(seen.lock().expect("not poisoned").closes >= 1);
}

/// A session refused before it starts (a bad setting) still closes the devices it was given.
#[test]
fn a_refused_session_closes_its_devices() {
    let (a, seen) = Hand::boxed(None);
    let cfg = SessionConfig {
        rate_hz: 0.0,
        ..config()
    };
    assert!(matches!(run(grid(), vec![a], &cfg), Err(SessionError::Setting(_))));
    let seen = seen.lock().expect("not poisoned");
    assert_eq!((seen.reads, seen.closes), (0, 1));
}
