//! The scripted device (`script:FILE.csv`): replays a trajectory file, so sessions are
//! reproducible.

use super::{Device, DeviceFault, DeviceInfo, DeviceState, Kind};
use std::path::{Path, PathBuf};

/// `script:FILE.csv` in a device spec.
pub(super) const KIND: Kind = Kind {
    name: "script",
    argument: "FILE.csv",
    about: "t, x, y, z[, button] in SI units",
    open: |file| {
        if file.is_empty() {
            return Err(ScriptError {
                path: "device \"script:\"".into(),
                message: "no file after `script:`; give one, e.g. script:hand.csv".into(),
            });
        }
        Ok(Box::new(ScriptedDevice::load(Path::new(file))?))
    },
};

/// A trajectory read from CSV `t, x, y, z[, button]` (SI units, rows in increasing t; `#` lines,
/// a header line of column names before the first row and a leading byte-order mark are
/// skipped). Positions are interpolated linearly; the script holds its
/// last point after the end.
#[derive(Clone, Debug)]
pub struct ScriptedDevice {
    t: Vec<f64>,
    p: Vec<[f64; 3]>,
    b: Vec<bool>,
    cursor: usize,
    /// The file (or other source) it was read from, as given.
    name: String,
    /// The file, when read from one.
    file: Option<PathBuf>,
    /// Closed: reads fail.
    closed: bool,
    /// Largest force magnitude written, N.
    pub peak_force: f64,
    /// Last force written.
    pub last_force: [f64; 3],
}

/// Largest device script read, bytes: 64 MiB is over a million rows, half an hour at 1 kHz.
pub const MAX_SCRIPT_BYTES: u64 = 64 << 20;

/// The script could not be used; the message names the file and line.
pub type ScriptError = ves_format::InputError;

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
            name: path.into(),
            file: None,
            closed: false,
            peak_force: 0.0,
            last_force: [0.0; 3],
        };
        // Spreadsheets save CSV with a byte-order mark: it is no part of the first field.
        let text = text.strip_prefix('\u{FEFF}').unwrap_or(text);
        let mut header = false;
        for (k, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let fields: Vec<&str> = line.split(',').map(str::trim).collect();
            let nums: Result<Vec<f64>, _> = fields.iter().map(|f| f.parse::<f64>()).collect();
            let Ok(nums) = nums else {
                // A header names columns: a first line with a number in it is a row with a typo.
                if d.t.is_empty() && !header && fields.iter().all(|f| f.parse::<f64>().is_err()) {
                    header = true;
                    continue;
                }
                return Err(err(
                    k + 1,
                    format!("expected numbers `t, x, y, z[, button]`, got {:?}", excerpt(line)),
                ));
            };
            if !(nums.len() == 4 || nums.len() == 5) || nums.iter().any(|v| !v.is_finite()) {
                return Err(err(
                    k + 1,
                    format!("expected 4 or 5 finite numbers, got {:?}", excerpt(line)),
                ));
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

    /// Reads a trajectory file: a regular file of at most [`MAX_SCRIPT_BYTES`]. A device, a
    /// pipe or a socket is refused before any read (it could block or never end).
    pub fn load(path: &Path) -> Result<ScriptedDevice, ScriptError> {
        use std::io::Read;
        use std::os::unix::fs::OpenOptionsExt;
        let p = path.display().to_string();
        let err = |message: String| ScriptError {
            path: p.clone(),
            message,
        };
        // Non-blocking, so that opening a FIFO with no writer returns at once; then the open
        // file itself is checked, so it cannot change between the check and the read.
        let file = std::fs::OpenOptions::new()
            .read(true)
            .custom_flags(libc::O_NONBLOCK)
            .open(path)
            .map_err(|e| err(format!("cannot read the device script ({e})")))?;
        let meta = file
            .metadata()
            .map_err(|e| err(format!("cannot read the device script ({e})")))?;
        if meta.is_dir() {
            return Err(err(
                "is a directory; give a CSV file of rows t, x, y, z[, button]".into()
            ));
        }
        if !meta.is_file() {
            return Err(err(
                "is not a regular file (a device, pipe or socket); give a CSV file of rows t, x, y, z[, button]".into(),
            ));
        }
        let too_big = || {
            err(format!(
                "is larger than {} MiB, the limit for a device script; thin it out (positions are interpolated \
                 linearly, so a few hundred rows per second are plenty)",
                MAX_SCRIPT_BYTES >> 20
            ))
        };
        if meta.len() > MAX_SCRIPT_BYTES {
            return Err(too_big());
        }
        // Capped as well: a file that grows while it is read stops at the limit.
        let mut bytes = Vec::new();
        file.take(MAX_SCRIPT_BYTES + 1)
            .read_to_end(&mut bytes)
            .map_err(|e| err(format!("cannot read the device script ({e})")))?;
        if bytes.len() as u64 > MAX_SCRIPT_BYTES {
            return Err(too_big());
        }
        let text = String::from_utf8(bytes).map_err(|e| {
            err(format!(
                "is not UTF-8 text (byte {}); save it as a UTF-8 CSV file",
                e.utf8_error().valid_up_to()
            ))
        })?;
        let mut d = Self::parse(&p, &text)?;
        d.file = Some(path.to_path_buf());
        Ok(d)
    }

    /// Time of the last row, s.
    pub fn duration(&self) -> f64 {
        self.t.last().copied().unwrap_or(0.0)
    }
}

/// The start of a line, for a message that stays short whatever the file holds.
fn excerpt(line: &str) -> String {
    const MAX_CHARS: usize = 80;
    match line.char_indices().nth(MAX_CHARS) {
        Some((i, _)) => format!("{}…", &line[..i]),
        None => line.to_string(),
    }
}

impl Device for ScriptedDevice {
    fn info(&self) -> DeviceInfo<'_> {
        DeviceInfo {
            name: &self.name,
            length_s: Some(self.duration()),
            file: self.file.as_deref(),
        }
    }

    fn read(&mut self, t: f64) -> Result<DeviceState, DeviceFault> {
        if self.closed {
            return Err(DeviceFault::Disconnected);
        }
        let n = self.t.len();
        while self.cursor + 1 < n && self.t[self.cursor + 1] <= t {
            self.cursor += 1;
        }
        let i = self.cursor;
        if i + 1 >= n || t <= self.t[0] {
            let k = if t <= self.t[0] { 0 } else { n - 1 };
            return Ok(DeviceState {
                position: self.p[k],
                velocity: [0.0; 3],
                button: self.b[k],
            });
        }
        let (t0, t1) = (self.t[i], self.t[i + 1]);
        let s = (t - t0) / (t1 - t0);
        let (a, b) = (self.p[i], self.p[i + 1]);
        Ok(DeviceState {
            position: std::array::from_fn(|c| a[c] + s * (b[c] - a[c])),
            velocity: std::array::from_fn(|c| (b[c] - a[c]) / (t1 - t0)),
            button: self.b[i],
        })
    }

    fn write(&mut self, force: [f64; 3]) {
        let m = (force[0] * force[0] + force[1] * force[1] + force[2] * force[2]).sqrt();
        self.peak_force = self.peak_force.max(m);
        self.last_force = force;
    }

    fn close(&mut self) {
        self.closed = true;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolates_and_rejects_bad_rows() {
        let mut d = ScriptedDevice::parse("s.csv", "t,x,y,z,button\n0,0,0,0,0\n1,1,2,3,1\n").expect("valid");
        let s = d.read(0.5).expect("open");
        assert_eq!(s.position, [0.5, 1.0, 1.5]);
        assert_eq!(s.velocity, [1.0, 2.0, 3.0]);
        assert_eq!(d.read(5.0).expect("open").position, [1.0, 2.0, 3.0]);
        d.close();
        assert_eq!(d.read(0.5), Err(DeviceFault::Disconnected));
        d.close();
        assert!(ScriptedDevice::parse("s.csv", "0,0,0,0\n0,1,1,1\n").is_err());
        assert!(ScriptedDevice::parse("s.csv", "0,0,0\n").is_err());
        assert!(ScriptedDevice::parse("s.csv", "0,0,0,nan\n").is_err());
        assert!(ScriptedDevice::parse("s.csv", "").is_err());
    }

    /// A spreadsheet's byte-order mark made the first row look like a header: it was dropped.
    #[test]
    fn a_byte_order_mark_keeps_the_first_row() {
        let d = ScriptedDevice::parse("s.csv", "\u{FEFF}0,1,2,3\n1,1,2,3\n").expect("valid");
        assert_eq!(d.t, [0.0, 1.0]);
        assert_eq!(d.p[0], [1.0, 2.0, 3.0]);
        let d = ScriptedDevice::parse("s.csv", "\u{FEFF}t,x,y,z\n0,1,2,3\n").expect("valid");
        assert_eq!(d.t, [0.0]);
        // A header may follow comments; a first row with a typo is no header.
        let d = ScriptedDevice::parse("s.csv", "# hand\nt,x,y,z\n0,1,2,3\n").expect("valid");
        assert_eq!(d.t, [0.0]);
        let e = ScriptedDevice::parse("s.csv", "0,1,2,3O\n1,1,2,3\n").expect_err("typo");
        assert!(e.to_string().contains("line 1"), "{e}");
        let e = ScriptedDevice::parse("s.csv", &format!("0,1,2,{}\n", "9".repeat(100_000))).expect_err("long");
        assert!(e.to_string().len() < 300, "the message repeats the whole line");
    }

    /// Runs `load` on a thread and fails, instead of hanging, when it does not return in 10 s.
    fn load_within_seconds(path: &Path) -> Result<ScriptedDevice, ScriptError> {
        let (tx, rx) = std::sync::mpsc::channel();
        let path = path.to_path_buf();
        std::thread::spawn(move || {
            let _ = tx.send(ScriptedDevice::load(&path));
        });
        rx.recv_timeout(std::time::Duration::from_secs(10))
            .expect("ScriptedDevice::load did not return within 10 s")
    }

    /// `script:/dev/zero` read until memory ran out; a FIFO with no writer blocked forever.
    #[test]
    fn devices_pipes_and_huge_files_are_refused_before_reading() {
        let e = load_within_seconds(Path::new("/dev/zero")).expect_err("/dev/zero");
        assert!(e.to_string().contains("not a regular file"), "{e}");
        let dir = std::env::temp_dir().join(format!("ves-device-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let fifo = dir.join("hand.csv");
        let _ = std::fs::remove_file(&fifo);
        let c = std::ffi::CString::new(fifo.to_str().expect("utf-8 path")).expect("no NUL");
        // SAFETY: a valid NUL-terminated path.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0, "mkfifo");
        let e = load_within_seconds(&fifo).expect_err("FIFO");
        assert!(e.to_string().contains("not a regular file"), "{e}");
        // A sparse file beyond the limit: refused by its size, nothing read.
        let big = dir.join("big.csv");
        std::fs::File::create(&big)
            .and_then(|f| f.set_len(MAX_SCRIPT_BYTES + 1))
            .expect("sparse file");
        let e = load_within_seconds(&big).expect_err("too big");
        assert!(e.to_string().contains("64 MiB"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
