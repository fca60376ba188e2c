//! `ves session --trace FILE.csv`: every haptic step of every hand, written after the session.
//! A device wrapper records into rows made before the session starts, so the haptic thread
//! neither allocates nor waits (one uncontended lock per hand-step).

use anyhow::Result;
use std::sync::{Arc, Mutex};
use ves_runtime::device::{Device, DeviceState};
use ves_runtime::haptic::HandOutput;

/// One hand-step: time, hand position, the vertex, its elastic displacement, the force.
#[derive(Clone, Copy, Default)]
struct Row {
    t: f64,
    hand: usize,
    position: [f64; 3],
    out: HandOutput,
}

/// The rows of every hand, shared with the recording devices.
#[derive(Clone)]
pub struct Trace(Arc<Mutex<Vec<Row>>>);

impl Trace {
    /// Room for `steps` steps of `hands` hands (recording stops when it is full).
    pub fn with_room(steps: usize, hands: usize) -> Trace {
        Trace(Arc::new(Mutex::new(Vec::with_capacity(steps.saturating_mul(hands)))))
    }

    /// `device` as hand `hand`, recorded here.
    pub fn record(&self, hand: usize, device: Box<dyn Device>) -> Box<dyn Device> {
        Box::new(Recording {
            inner: device,
            trace: self.clone(),
            row: Row { hand, ..Row::default() },
        })
    }

    /// The rows as CSV, a header line first.
    pub fn csv(&self) -> String {
        let rows = self.0.lock().map(|r| r.clone()).unwrap_or_default();
        let mut s = String::from(
            "t_s,hand,x_m,y_m,z_m,contact,vertex,ux_m,uy_m,uz_m,fx_n,fy_n,fz_n,grip_gap_m,strain,von_mises_pa\n",
        );
        for r in rows {
            let (p, o) = (r.position, r.out);
            let (u, f) = (o.displacement, o.force);
            s += &format!(
                "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n",
                r.t,
                r.hand,
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
            );
        }
        s
    }
}

struct Recording {
    inner: Box<dyn Device>,
    trace: Trace,
    /// This step's row so far (time and position from `read`).
    row: Row,
}

impl Device for Recording {
    fn read(&mut self, t: f64) -> DeviceState {
        let s = self.inner.read(t);
        self.row.t = t;
        self.row.position = s.position;
        s
    }

    fn write(&mut self, force: [f64; 3]) {
        self.inner.write(force);
    }

    fn observe(&mut self, out: &HandOutput) {
        self.inner.observe(out);
        self.row.out = *out;
        if let Ok(mut rows) = self.trace.0.lock()
            && rows.len() < rows.capacity()
        {
            rows.push(self.row);
        }
    }
}

/// Writes the trace to `path` (atomically: a killed run leaves no half file).
pub fn write(trace: &Trace, path: &std::path::Path) -> Result<()> {
    let text = trace.csv();
    ves_pipeline::output::write_atomically(path, |tmp| Ok(std::fs::write(tmp, text)?))
}
