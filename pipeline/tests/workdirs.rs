//! Work folders (`ves view`'s uploaded parts and bases, the meshing's files): private to their
//! owner, removed when `ves view` gets SIGINT, SIGTERM or SIGHUP, and those a dead process left
//! removed by the next start.

use std::io::{BufRead, BufReader};
use std::os::unix::fs::MetadataExt;
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

fn step() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../cases/cantilever/cantilever.step")
}

/// A process id no process has now: a child's, once waited for.
fn dead_pid() -> u32 {
    let mut c = Command::new("true").spawn().expect("true runs");
    let pid = c.id();
    c.wait().expect("wait");
    pid
}

/// The folders in `tmp` whose names say process `pid` owns them.
fn owned_by(tmp: &Path, pid: u32) -> Vec<PathBuf> {
    let mark = format!("-pid{pid}-");
    std::fs::read_dir(tmp)
        .expect("read the temporary folder")
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().contains(&mark))
        .map(|e| e.path())
        .collect()
}

/// A stale folder as a killed `ves` of another run leaves it.
fn stale(tmp: &Path, kind: &str, pid: u32) -> PathBuf {
    let p = tmp.join(format!("ves-{kind}-pid{pid}-Ab12Cd"));
    std::fs::create_dir(&p).expect("mkdir");
    std::fs::write(p.join("owner.lock"), "").expect("write");
    std::fs::write(p.join("basis-3.h5"), "an old basis").expect("write");
    p
}

/// For each signal: `ves view PART.step` (its first compute starting at once) removes at its
/// start the folders of processes gone, keeps its own folder private (0700), and leaves no
/// folder behind when the signal comes. Before, the folders were 0755, SIGTERM and SIGHUP left
/// them for ever (161 MB after a few uploads) and no later run removed them.
#[test]
fn ves_view_s_folder_is_private_gone_after_a_signal_and_stale_ones_are_removed_at_start() {
    for (signal, number) in [("TERM", 15), ("HUP", 1), ("INT", 2)] {
        let tmp = tempfile::tempdir().expect("tempdir");
        let dead = dead_pid();
        let stale = [stale(tmp.path(), "view", dead), stale(tmp.path(), "verify", dead)];
        let mut server = Command::new(env!("CARGO_BIN_EXE_ves"))
            .args(["view", step().to_str().unwrap(), "--port", "0", "--duration", "60"])
            .env("TMPDIR", tmp.path())
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("ves view starts");
        let mut line = String::new();
        BufReader::new(server.stdout.take().expect("stdout"))
            .read_line(&mut line)
            .expect("the URL line");
        assert!(line.contains("http://"), "{line:?}");
        let pid = server.id();
        let own: Vec<_> = owned_by(tmp.path(), pid)
            .into_iter()
            .filter(|p| {
                p.file_name()
                    .is_some_and(|n| n.to_string_lossy().starts_with("ves-view-"))
            })
            .collect();
        assert_eq!(own.len(), 1, "ves view's folder: {own:?}");
        let mode = std::fs::metadata(&own[0]).expect("stat").mode() & 0o777;
        assert_eq!(mode, 0o700, "{}: mode {mode:o}", own[0].display());
        for p in &stale {
            assert!(!p.exists(), "{} left by a dead process is still there", p.display());
        }
        let killed = Command::new("kill")
            .args([&format!("-{signal}"), &pid.to_string()])
            .status();
        assert!(killed.is_ok_and(|s| s.success()), "kill -{signal}");
        let status = server.wait().expect("ves view ends");
        if signal == "INT" {
            assert!(status.success(), "Ctrl-C ends ves view well: {status:?}");
        } else {
            assert_eq!(status.signal(), Some(number), "SIG{signal} ends ves view: {status:?}");
        }
        let left = owned_by(tmp.path(), pid);
        assert!(
            left.is_empty(),
            "after SIG{signal}, folders of ves view are left: {left:?}"
        );
    }
}
