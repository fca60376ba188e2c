//! `ves session --trace FILE.csv`: every haptic step of every hand (at most [`MAX_STEPS`] each),
//! written after the session.
//! Each hand's recording device fills rows made before the session starts and hands them over
//! when the session drops it, so the haptic thread neither allocates nor locks.

use anyhow::Result;
use std::sync::mpsc;
use ves_runtime::device::{Device, DeviceFault, DeviceInfo, DeviceState};
use ves_runtime::haptic::HandOutput;

/// Most steps a trace records per hand: 1000 s at the default 1 kHz. Its rows are reserved
/// before the session starts, [`ROW_BYTES`] each.
pub const MAX_STEPS: usize = 1_000_000;

/// Bytes of one reserved row.
pub const ROW_BYTES: usize = std::mem::size_of::<Row>();

/// One hand-step: time, hand position, and what the step gave the hand.
#[derive(Clone, Copy, Default)]
struct Row {
    t: f64,
    position: [f64; 3],
    out: HandOutput,
}

/// The recorded hands: their rows arrive when the session ends.
pub struct Trace {
    steps: usize,
    tx: mpsc::Sender<(usize, Vec<Row>)>,
    rx: mpsc::Receiver<(usize, Vec<Row>)>,
}

impl Trace {
    /// Room for `steps` steps per hand, at most [`MAX_STEPS`] (recording stops when it is full).
    pub fn with_room(steps: usize) -> Trace {
        let steps = steps.min(MAX_STEPS);
        let (tx, rx) = mpsc::channel();
        Trace { steps, tx, rx }
    }

    /// `device` as hand `hand`, recorded.
    pub fn record(&self, hand: usize, device: Box<dyn Device>) -> Box<dyn Device> {
        Box::new(Recording {
            inner: device,
            hand,
            rows: Vec::with_capacity(self.steps),
            row: Row::default(),
            tx: self.tx.clone(),
        })
    }

    /// Writes the rows as CSV to `w`, a header line first, step by step and hand by hand within
    /// a step (streamed: a long trace is not held twice, as rows and as text).
    fn write_csv(&self, w: &mut impl std::io::Write) -> std::io::Result<()> {
        let mut hands: Vec<(usize, Vec<Row>)> = self.rx.try_iter().collect();
        hands.sort_by_key(|(hand, _)| *hand);
        w.write_all(
            b"t_s,hand,x_m,y_m,z_m,contact,vertex,ux_m,uy_m,uz_m,fx_n,fy_n,fz_n,grip_gap_m,strain,von_mises_pa\n",
        )?;
        let steps = hands.iter().map(|(_, rows)| rows.len()).max().unwrap_or(0);
        for i in 0..steps {
            for (hand, r) in hands.iter().filter_map(|(hand, rows)| rows.get(i).map(|r| (hand, r))) {
                let (p, o) = (r.position, r.out);
                let (u, f) = (o.displacement, o.force);
                writeln!(
                    w,
                    "{},{hand},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
                    r.t,
                    p[0],
                    p[1],
                    p[2],
                    u8::from(o.contact),
                    o.vertex,
                    u[0],
                    u[1],
                    u[2],
                    f[0],
                    f[1],
                    f[2],
                    o.grip_gap,
                    o.strain,
                    o.von_mises
                )?;
            }
        }
        Ok(())
    }
}

struct Recording {
    inner: Box<dyn Device>,
    hand: usize,
    /// Made with room for every step: pushing never allocates.
    rows: Vec<Row>,
    /// This step's row so far (time and position from `read`).
    row: Row,
    tx: mpsc::Sender<(usize, Vec<Row>)>,
}

impl Device for Recording {
    fn info(&self) -> DeviceInfo<'_> {
        self.inner.info()
    }

    fn read(&mut self, t: f64) -> Result<DeviceState, DeviceFault> {
        let s = self.inner.read(t)?;
        self.row.t = t;
        self.row.position = s.position;
        Ok(s)
    }

    fn write(&mut self, force: [f64; 3]) {
        self.inner.write(force);
    }

    fn observe(&mut self, out: &HandOutput) {
        self.inner.observe(out);
        self.row.out = *out;
        if self.rows.len() < self.rows.capacity() {
            self.rows.push(self.row);
        }
    }

    fn close(&mut self) {
        self.inner.close();
    }
}

impl Drop for Recording {
    /// The session is over (it drops its devices): the rows go to the trace.
    fn drop(&mut self) {
        let _ = self.tx.send((self.hand, std::mem::take(&mut self.rows)));
    }
}

/// Writes the trace to `path` (atomically: a killed run leaves no half file).
pub fn write(trace: &Trace, path: &std::path::Path) -> Result<()> {
    ves_pipeline::output::write_atomically(path, |tmp| {
        let mut w = std::io::BufWriter::new(std::fs::File::create(tmp)?);
        trace.write_csv(&mut w)?;
        // Flushed here; the staging syncs the file before renaming it.
        w.into_inner().map_err(|e| e.into_error())?;
        Ok(())
    })?;
    Ok(())
}
