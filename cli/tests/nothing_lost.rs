//! Issue "Nothing lost, nobody in": inputs that hung `ves`, dropped data silently, failed only
//! after the whole solve, or let a write go where it must not. One regression test each; the
//! ones that hung run under a deadline, so a regression fails instead of hanging CI.

mod common;

use common::*;
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// `ves ARGS`, killed (and the test failed) when it runs longer than `seconds`.
fn ves_within(args: &[&str], seconds: u64) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_ves"))
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("ves runs");
    // Drained on threads: a full pipe would stall the child and look like a hang.
    let mut out = child.stdout.take().expect("stdout");
    let mut err = child.stderr.take().expect("stderr");
    let read_out = std::thread::spawn(move || {
        let mut v = Vec::new();
        let _ = std::io::Read::read_to_end(&mut out, &mut v);
        v
    });
    let read_err = std::thread::spawn(move || {
        let mut v = Vec::new();
        let _ = std::io::Read::read_to_end(&mut err, &mut v);
        v
    });
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().expect("wait") {
            break s;
        }
        if start.elapsed() > Duration::from_secs(seconds) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("ves {args:?} still running after {seconds} s: killed");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    Output {
        status,
        stdout: read_out.join().expect("stdout reader"),
        stderr: read_err.join().expect("stderr reader"),
    }
}

/// With two symlink loops in the directory `ves batch` hung silently (the walk doubles at each
/// level); with one it listed the same scene 41 times, each with a several-kB error line.
#[test]
fn batch_lists_each_scene_once_through_symlink_loops() {
    // A scene that fails at once (parse), so the test measures the walk, not a solve.
    let (dir, _) = workdir(&GOOD.replace("young = 2.1e11", "young = -1.0"));
    let d = dir.path();
    std::os::unix::fs::symlink(d, d.join("loop")).unwrap();
    std::os::unix::fs::symlink(".", d.join("again")).unwrap();
    let o = ves_within(&["batch", d.to_str().unwrap(), "--json"], 60);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let outcomes = last_json(&o);
    let outcomes = outcomes.as_array().expect("a list of outcomes");
    assert_eq!(outcomes.len(), 1, "{outcomes:?}");
    assert_eq!(outcomes[0]["scene"], d.join("scene.toml").to_str().unwrap());
    for line in stderr(&o).lines() {
        assert!(line.len() < 500, "a line of {} bytes: {line:.200}", line.len());
    }
}

/// `--device script:/dev/zero` read until memory ran out; a FIFO with no writer hung. Both are
/// refused before any read (the device scripts are opened before the basis, so none is needed).
#[test]
fn session_refuses_device_and_fifo_scripts_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("hand.csv");
    mkfifo(&fifo);
    let basis = dir.path().join("no-basis.h5");
    for script in [Path::new("/dev/zero"), fifo.as_path()] {
        let device = format!("script:{}", script.display());
        let o = ves_within(&["session", basis.to_str().unwrap(), "--device", &device], 30);
        assert_refused(&o, "not a regular file");
        assert!(stderr(&o).contains(script.to_str().unwrap()), "{}", stderr(&o));
    }
}

/// A NUL in a VOI name failed only when the basis was written, after the whole solve; a bidi
/// override would show another name than the one stored.
#[test]
fn voi_names_that_are_not_identifiers_are_refused_at_parse() {
    let voi = |name: &str| {
        GOOD.replace(
            "[modes]",
            &format!("[[voi]]\nname = \"{name}\"\nbox = {{ min = [0.0, 0.0, 0.0], max = [0.1, 0.1, 0.05] }}\nsize = 0.02\n[modes]"),
        )
    };
    fails(&voi("rib\\u0000one"), &["voi[0].name", "U+0000"]);
    fails(&voi("rib\\u202Eeno"), &["voi[0].name", "U+202E"]);
    fails(&voi("../rib"), &["voi[0].name"]);
    fails(&voi(""), &["voi[0].name", "empty"]);
}

/// VOI boxes and probe points 100 m away from a 1 m beam passed silently (a VOI space with no
/// refinement, a probe snapped to whatever vertex was nearest). Refused after meshing, before
/// the solve, naming the entry and the part's bounding box.
#[test]
fn voi_boxes_and_probes_off_the_part_are_refused_before_the_solve() {
    fails(
        &GOOD.replace(
            "[modes]",
            "[[voi]]\nname = \"far\"\nbox = { min = [100.0, 0.0, 0.0], max = [100.1, 0.1, 0.05] }\nsize = 0.02\n[modes]",
        ),
        &["voi[0]", "\"far\"", "does not overlap", "bounding box"],
    );
    fails(
        &GOOD.replace(
            "[modes]",
            "[[probe]]\nat = [1.0, 0.05, 0.05]\nforce = [0.0, 0.0, -1.0]\n[[probe]]\nat = [100.0, 0.05, 0.05]\nforce = [0.0, 0.0, -1.0]\n[modes]",
        ),
        &["probe[1]", "outside the part", "bounding box"],
    );
}

/// `ves export --vtu DIR` replaced a symbolic link at `DIR/global.vtu` without `--force`.
#[test]
fn export_refuses_a_symlink_output_unless_forced() {
    let (dir, basis) = good_basis();
    let vtu = dir.path().join("vtk");
    std::fs::create_dir(&vtu).unwrap();
    let target = dir.path().join("keep.txt");
    std::fs::write(&target, "keep me").unwrap();
    let link = vtu.join("global.vtu");
    std::os::unix::fs::symlink(&target, &link).unwrap();
    let o = ves(&["export", basis.to_str().unwrap(), "--vtu", vtu.to_str().unwrap()]);
    assert_refused(&o, "--force");
    assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
    assert_eq!(std::fs::read_to_string(&target).unwrap(), "keep me");
    let o = ves(&[
        "export",
        basis.to_str().unwrap(),
        "--vtu",
        vtu.to_str().unwrap(),
        "--force",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_file());
    assert_eq!(std::fs::read_to_string(&target).unwrap(), "keep me");
}
