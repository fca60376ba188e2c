//! The haptic thread's loop: wait for the deadline, read the devices, step the simulation,
//! write the forces, publish the state for drawing. A device that faults ends the loop with zero
//! force sent to every device.

use super::SessionConfig;
use super::stats::{HandTally, LoopTimings, PartRecord};
use crate::device::{Device, DeviceFault};
use crate::haptic::{HandInput, HandOutput};
use crate::snapshot::{Published, Snapshot};
use crate::switching::Switcher;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Periods (wake-up to wake-up) longer than this are counted (`periods_over_1_1_ms`): at the
/// default 1 kHz, a wake-up 10 % of a period late, which a missed deadline (a step that ended
/// after the next deadline) need not be.
const LONG_PERIOD: Duration = Duration::from_micros(1100);

/// How long before a deadline a sleeping haptic thread wakes to spin (sleep overshoots by ~60 µs).
const SLEEP_WINDOW: Duration = Duration::from_micros(150);

/// The spin window of `--spin` under SCHED_FIFO with real-time throttling (at most 30 % of the
/// period): far below the 95 % the kernel allows, wide enough that a FIFO wake-up is never late.
const SPIN_WINDOW: Duration = Duration::from_micros(300);

/// Keeps the loop on its deadlines.
struct Pacer {
    period: Duration,
    next: Instant,
    /// Sleep until this long before a deadline, then spin; `None` spins the whole period.
    window: Option<Duration>,
}

impl Pacer {
    /// Sleep to just before each deadline, then spin: sleep alone overshoots by ~60 µs. `--spin`
    /// spins the whole period, except under SCHED_FIFO with the kernel's real-time throttling,
    /// which would stop a thread that never sleeps for 50 ms of every second (measured: 486
    /// deadlines missed in 10 s): it then keeps a wider spin window and sleeps the rest.
    fn new(cfg: &SessionConfig, rt: Option<&mut crate::realtime::Realtime>, start: Instant) -> Pacer {
        let period = Duration::from_secs_f64(1.0 / cfg.rate_hz);
        let window = match rt {
            Some(r) if !cfg.sleep && r.sched_fifo && crate::realtime::rt_throttled() => {
                let w = SPIN_WINDOW.min(period.mul_f64(0.3));
                r.spin_window_us = Some(w.as_micros() as u64);
                Some(w)
            }
            _ => cfg.sleep.then_some(SLEEP_WINDOW),
        };
        Pacer {
            period,
            next: start,
            window,
        }
    }

    /// Waits for the next deadline; returns when it woke.
    fn wait(&self) -> Instant {
        let now = Instant::now();
        if let Some(w) = self.window
            && self.next > now + w + Duration::from_micros(50)
        {
            std::thread::sleep(self.next - now - w);
        }
        while Instant::now() < self.next {
            std::hint::spin_loop();
        }
        Instant::now()
    }
}

/// What the loop works with.
pub(super) struct HapticLoop<'a> {
    pub haptics: &'a mut Switcher,
    pub devices: &'a mut [Box<dyn Device>],
    pub snapshot: &'a Snapshot,
    pub part: &'a PartRecord,
    /// Ends the loop at its next step when set.
    pub stop: &'a AtomicBool,
    /// Brings the part back to rest at the next step when set (and clears it).
    pub reset: &'a AtomicBool,
}

/// What the loop leaves: its timings, its tallies, the last step's hand outputs (forces as last
/// sent) and the device fault that ended it, if one did.
pub(super) struct Ran {
    pub timings: LoopTimings,
    pub tally: HandTally,
    pub outputs: Vec<HandOutput>,
    pub fault: Option<Fault>,
}

/// A device read that failed.
#[derive(Clone, Copy, Debug)]
pub(super) struct Fault {
    /// The hand whose device it was.
    pub hand: usize,
    pub fault: DeviceFault,
    /// Session time of the read, s.
    pub time_s: f64,
    /// Steps completed before it.
    pub step: u64,
}

impl HapticLoop<'_> {
    /// Runs `steps` steps (or until stopped, or until a device faults) at the session's rate.
    /// Allocation-free per step.
    pub(super) fn run(
        self,
        cfg: &SessionConfig,
        steps: u64,
        hands: usize,
        rt: Option<&mut crate::realtime::Realtime>,
    ) -> Result<Ran, super::SessionError> {
        let dt = 1.0 / cfg.rate_hz;
        let mut timings = LoopTimings::new()?;
        let mut tally = HandTally {
            hands: vec![Default::default(); hands],
            ..Default::default()
        };
        let mut inputs = vec![HandInput::default(); hands];
        let mut outputs = vec![HandOutput::default(); hands];
        let r_max = self
            .haptics
            .sims()
            .iter()
            .map(|s| s.basis().mode_count())
            .max()
            .unwrap_or(0);
        let mut published = Published::with_hands(r_max, hands);
        let start = Instant::now();
        let mut pacer = Pacer::new(cfg, rt, start);
        let mut fault = None;
        let mut last_woke = None;
        for k in 0..steps {
            if self.stop.load(Ordering::Relaxed) {
                break;
            }
            timings.steps = k + 1;
            let woke = pacer.wait();
            if let Some(last) = last_woke.replace(woke) {
                timings.long_periods += u64::from(woke.duration_since(last) > LONG_PERIOD);
            }
            timings
                .period_error_ns
                .record(woke.duration_since(pacer.next).as_nanos() as u64);
            let t = k as f64 * dt;
            if let Err((hand, f)) = read_devices(self.devices, &mut inputs, t) {
                // Without that hand's position the step cannot be taken: the session ends here,
                // every device let go rather than left pushing with the last force.
                for (out, dev) in outputs.iter_mut().zip(self.devices.iter_mut()) {
                    out.force = [0.0; 3];
                    dev.write(out.force);
                }
                timings.steps = k;
                fault = Some(Fault {
                    hand,
                    fault: f,
                    time_s: t,
                    step: k,
                });
                break;
            }
            if self.reset.load(Ordering::Relaxed) && self.reset.swap(false, Ordering::Relaxed) {
                self.haptics.reset();
            }
            let alarm = self.part.alarm.load(Ordering::Relaxed);
            for sim in self.haptics.sims_mut() {
                sim.set_part_alarm(alarm);
            }
            let c0 = Instant::now();
            self.haptics.step(&inputs, &mut outputs);
            timings.compute_ns.record(c0.elapsed().as_nanos() as u64);
            for (k, (out, dev)) in outputs.iter().zip(self.devices.iter_mut()).enumerate() {
                dev.write(out.force);
                dev.observe(out);
                tally.add(k, out);
            }
            let active = self.haptics.sim(self.haptics.active());
            active.publish_into(self.haptics.active(), &mut published);
            self.snapshot.publish_state(&published, t);
            tally.max_energy = tally.max_energy.max(active.energy());
            let done = Instant::now();
            timings.step_ns.record(done.duration_since(woke).as_nanos() as u64);
            pacer.next += pacer.period;
            timings.missed += u64::from(done > pacer.next);
        }
        timings.wall_s = start.elapsed().as_secs_f64();
        Ok(Ran {
            timings,
            tally,
            outputs,
            fault,
        })
    }
}

/// Reads every device at `t` into its hand's input; the first fault stops the reads and names
/// its hand.
fn read_devices(devices: &mut [Box<dyn Device>], inputs: &mut [HandInput], t: f64) -> Result<(), (usize, DeviceFault)> {
    for (hand, (inp, dev)) in inputs.iter_mut().zip(devices.iter_mut()).enumerate() {
        let s = dev.read(t).map_err(|f| (hand, f))?;
        *inp = HandInput {
            position: s.position,
            velocity: s.velocity,
            button: s.button,
        };
    }
    Ok(())
}
