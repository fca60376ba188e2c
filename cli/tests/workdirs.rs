//! Work folders (`ves view`'s uploaded parts and bases, the meshing's files): private to their
//! owner, removed when `ves view` gets SIGINT, SIGTERM or SIGHUP, and those a dead process left
//! removed by the next start.

mod common;

use common::start_view;
use std::os::unix::fs::MetadataExt;
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// The cantilever's STEP file in a folder of its own (`common::workdir`'s copy): `ves view`
/// keeps its project beside the part, and one left beside the case's own file (by an earlier
/// run, or by the other test of this file at the same time) is resumed without a compute.
fn step() -> (tempfile::TempDir, PathBuf) {
    let (dir, _) = common::workdir(common::GOOD);
    let path = dir.path().join("beam.step");
    (dir, path)
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
        let (_part, step) = step();
        let (mut server, _out, _url) = start_view(&step, "0", "60", &[("TMPDIR", tmp.path())], Stdio::null());
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

/// The children of process `pid` whose command line holds `word`.
fn children_running(pid: u32, word: &str) -> Vec<u32> {
    let Ok(entries) = std::fs::read_dir("/proc") else {
        return Vec::new();
    };
    entries
        .flatten()
        .filter_map(|e| e.file_name().to_str()?.parse::<u32>().ok())
        .filter(|&p| {
            let stat = std::fs::read_to_string(format!("/proc/{p}/stat")).unwrap_or_default();
            // The parent is the 2nd field after the command name in parentheses.
            let ppid = stat
                .rsplit_once(") ")
                .and_then(|(_, r)| r.split(' ').nth(1)?.parse::<u32>().ok());
            let cmd = std::fs::read(format!("/proc/{p}/cmdline")).unwrap_or_default();
            ppid == Some(pid) && String::from_utf8_lossy(&cmd).contains(word)
        })
        .collect()
}

/// GET / as the page would; the status.
fn page_status(port: u16) -> Option<u16> {
    use std::io::{Read, Write};
    let mut s = std::net::TcpStream::connect(("127.0.0.1", port)).ok()?;
    s.set_read_timeout(Some(std::time::Duration::from_secs(5))).ok()?;
    write!(
        s,
        "GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nConnection: close\r\n\r\n"
    )
    .ok()?;
    let mut head = [0u8; 12];
    s.read_exact(&mut head).ok()?;
    std::str::from_utf8(&head[9..12]).ok()?.parse().ok()
}

/// The page's compute runs in a child process: when it dies (as one whose factorisation does
/// not fit dies of `memory allocation … failed`), the compute fails in one line and the server
/// goes on serving, the compute's folder removed. Before, the compute ran in the server, whose
/// abort disconnected every page.
#[test]
fn a_compute_process_that_dies_fails_the_compute_and_the_server_stays_up() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let (_part, step) = step();
    let (mut server, mut out, url) = start_view(&step, "0", "60", &[("TMPDIR", tmp.path())], Stdio::piped());
    let port: u16 = url
        .trim_start_matches("http://127.0.0.1:")
        .split('/')
        .next()
        .and_then(|p| p.parse().ok())
        .unwrap_or_else(|| panic!("no port in {url:?}"));
    let pid = server.id();
    // The first compute starts at once.
    let t0 = std::time::Instant::now();
    let child = loop {
        if let Some(&c) = children_running(pid, "view-compute").first() {
            break c;
        }
        assert!(
            t0.elapsed().as_secs() < 20,
            "no compute process under ves view after 20 s"
        );
        std::thread::sleep(std::time::Duration::from_millis(20));
    };
    let view = owned_by(tmp.path(), pid);
    assert_eq!(view.len(), 1, "{view:?}");
    let compute_dirs = || -> Vec<PathBuf> {
        std::fs::read_dir(&view[0])
            .map(|d| {
                d.flatten()
                    .map(|e| e.path())
                    .filter(|p| p.to_string_lossy().contains("compute-"))
                    .collect()
            })
            .unwrap_or_default()
    };
    assert_eq!(compute_dirs().len(), 1, "the compute's folder while it runs");
    let killed = Command::new("kill").args(["-KILL", &child.to_string()]).status();
    assert!(killed.is_ok_and(|s| s.success()));
    // The compute thread notices, reports and removes the folder.
    let t0 = std::time::Instant::now();
    while !compute_dirs().is_empty() && t0.elapsed().as_secs() < 10 {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    assert!(
        compute_dirs().is_empty(),
        "the dead compute's folder stays: {:?}",
        compute_dirs()
    );
    assert_eq!(
        page_status(port),
        Some(200),
        "the server answers after its compute died"
    );
    assert!(server.try_wait().expect("try_wait").is_none(), "ves view ended");
    let _ = Command::new("kill").args(["-INT", &pid.to_string()]).status();
    let status = server.wait().expect("ves view ends");
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut out, &mut rest).expect("stdout");
    let mut err = String::new();
    server
        .stderr
        .take()
        .map(|mut e| std::io::Read::read_to_string(&mut e, &mut err));
    assert!(status.success(), "{status:?}: {err}");
    let stats: serde_json::Value = rest
        .lines()
        .rev()
        .find_map(|l| serde_json::from_str(l).ok())
        .unwrap_or_else(|| panic!("no JSON statistics in {rest:?}"));
    assert_eq!(stats["computes_failed"], 1, "{stats}");
    assert!(owned_by(tmp.path(), pid).is_empty(), "folders left after the end");
}
