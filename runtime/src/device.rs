//! Haptic devices: position (and button) in, force out, SI units. A scripted device replays a
//! trajectory file so sessions are reproducible.

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

/// A haptic device. `read` and `write` are called from the haptic thread at its rate: they must
/// not block.
pub trait Device: Send {
    /// State at session time `t` (s).
    fn read(&mut self, t: f64) -> DeviceState;
    /// Force to render, N (already limited by the runtime).
    fn write(&mut self, force: [f64; 3]);
    /// Everything the step gave this hand (vertex, contact, strain, stress), after `write`.
    fn observe(&mut self, _out: &crate::haptic::HandOutput) {}
}

/// A trajectory read from CSV `t, x, y, z[, button]` (SI units, rows in increasing t; `#` lines
/// and a header line are skipped). Positions are interpolated linearly; the script holds its
/// last point after the end.
#[derive(Clone, Debug)]
pub struct ScriptedDevice {
    t: Vec<f64>,
    p: Vec<[f64; 3]>,
    b: Vec<bool>,
    cursor: usize,
    /// Largest force magnitude written, N.
    pub peak_force: f64,
    /// Last force written.
    pub last_force: [f64; 3],
}

/// The script could not be used; the message names the file and line.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {message}")]
pub struct ScriptError {
    /// The script.
    pub path: String,
    /// What is wrong.
    pub message: String,
}

impl ScriptedDevice {
    /// Parses a trajectory; `path` names it in errors.
    pub fn parse(path: &str, text: &str) -> Result<ScriptedDevice, ScriptError> {
        let err = |line: usize, message: String| ScriptError {
            path: path.into(),
            message: format!("line {line}: {message}"),
        };
        let mut d = ScriptedDevice {
            t: vec![],
            p: vec![],
            b: vec![],
            cursor: 0,
            peak_force: 0.0,
            last_force: [0.0; 3],
        };
        for (k, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let fields: Vec<&str> = line.split(',').map(str::trim).collect();
            let nums: Result<Vec<f64>, _> = fields.iter().map(|f| f.parse::<f64>()).collect();
            let Ok(nums) = nums else {
                if d.t.is_empty() && k == 0 {
                    continue; // header
                }
                return Err(err(
                    k + 1,
                    format!("expected numbers `t, x, y, z[, button]`, got {line:?}"),
                ));
            };
            if !(nums.len() == 4 || nums.len() == 5) || nums.iter().any(|v| !v.is_finite()) {
                return Err(err(k + 1, format!("expected 4 or 5 finite numbers, got {line:?}")));
            }
            if d.t.last().is_some_and(|&last| nums[0] <= last) {
                return Err(err(k + 1, format!("time {} does not increase", nums[0])));
            }
            d.t.push(nums[0]);
            d.p.push([nums[1], nums[2], nums[3]]);
            d.b.push(nums.get(4).is_some_and(|&b| b != 0.0));
        }
        if d.t.is_empty() {
            return Err(ScriptError {
                path: path.into(),
                message: "no trajectory rows".into(),
            });
        }
        Ok(d)
    }

    /// Reads a trajectory file.
    pub fn load(path: &Path) -> Result<ScriptedDevice, ScriptError> {
        let p = path.display().to_string();
        if path.is_dir() {
            return Err(ScriptError {
                path: p,
                message: "is a directory; give a CSV file of rows t, x, y, z[, button]".into(),
            });
        }
        let text = std::fs::read_to_string(path).map_err(|e| ScriptError {
            path: p.clone(),
            message: format!("cannot read the device script ({e})"),
        })?;
        Self::parse(&p, &text)
    }

    /// Time of the last row, s.
    pub fn duration(&self) -> f64 {
        self.t.last().copied().unwrap_or(0.0)
    }
}

impl Device for ScriptedDevice {
    fn read(&mut self, t: f64) -> DeviceState {
        let n = self.t.len();
        while self.cursor + 1 < n && self.t[self.cursor + 1] <= t {
            self.cursor += 1;
        }
        let i = self.cursor;
        if i + 1 >= n || t <= self.t[0] {
            let k = if t <= self.t[0] { 0 } else { n - 1 };
            return DeviceState {
                position: self.p[k],
                velocity: [0.0; 3],
                button: self.b[k],
            };
        }
        let (t0, t1) = (self.t[i], self.t[i + 1]);
        let s = (t - t0) / (t1 - t0);
        let (a, b) = (self.p[i], self.p[i + 1]);
        DeviceState {
            position: std::array::from_fn(|c| a[c] + s * (b[c] - a[c])),
            velocity: std::array::from_fn(|c| (b[c] - a[c]) / (t1 - t0)),
            button: self.b[i],
        }
    }

    fn write(&mut self, force: [f64; 3]) {
        let m = (force[0] * force[0] + force[1] * force[1] + force[2] * force[2]).sqrt();
        self.peak_force = self.peak_force.max(m);
        self.last_force = force;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolates_and_rejects_bad_rows() {
        let mut d = ScriptedDevice::parse("s.csv", "t,x,y,z,button\n0,0,0,0,0\n1,1,2,3,1\n").expect("valid");
        let s = d.read(0.5);
        assert_eq!(s.position, [0.5, 1.0, 1.5]);
        assert_eq!(s.velocity, [1.0, 2.0, 3.0]);
        assert_eq!(d.read(5.0).position, [1.0, 2.0, 3.0]);
        assert!(ScriptedDevice::parse("s.csv", "0,0,0,0\n0,1,1,1\n").is_err());
        assert!(ScriptedDevice::parse("s.csv", "0,0,0\n").is_err());
        assert!(ScriptedDevice::parse("s.csv", "0,0,0,nan\n").is_err());
        assert!(ScriptedDevice::parse("s.csv", "").is_err());
    }
}
