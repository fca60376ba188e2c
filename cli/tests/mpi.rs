//! `--solver slepc` under `mpirun -n 2` when something goes wrong: an error on every rank, an
//! error on one rank only, a rank killed mid-run. Each must end the whole job with a non-zero
//! status, promptly (a rank left waiting in a collective call would hang forever: the tests
//! give up after a deadline and fail), and with no process of the job left behind.
#![cfg(feature = "slepc")]

mod common;

use common::*;
use std::path::Path;
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

/// How long a job that should end may take (MPI start-up is ~1 s here).
const DEADLINE: Duration = Duration::from_secs(90);

/// `mpirun` on one node with the environment the CI container needs, and `apps` as its
/// colon-separated application contexts (one per rank group, MPMD).
fn mpirun(apps: &[Vec<String>]) -> Command {
    let mut c = Command::new("mpirun");
    c.env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .env("OMPI_MCA_plm", "isolated")
        .arg("--oversubscribe");
    for (i, app) in apps.iter().enumerate() {
        if i > 0 {
            c.arg(":");
        }
        c.args(app);
    }
    c.stdout(Stdio::piped()).stderr(Stdio::piped());
    c
}

/// `-n ranks ves precompute SCENE --solver slepc -o OUT` as one application context.
fn app(ranks: usize, scene: &Path, out: &Path) -> Vec<String> {
    [
        "-n",
        &ranks.to_string(),
        env!("CARGO_BIN_EXE_ves"),
        "precompute",
        scene.to_str().unwrap(),
        "--solver",
        "slepc",
        "-o",
        out.to_str().unwrap(),
    ]
    .iter()
    .map(|s| s.to_string())
    .collect()
}

/// Waits for `child` to end, killing it (and failing) after [`DEADLINE`].
fn finish(mut child: Child, what: &str) -> (Output, Duration) {
    let start = Instant::now();
    loop {
        match child.try_wait().expect("wait") {
            Some(_) => return (child.wait_with_output().expect("output"), start.elapsed()),
            None if start.elapsed() > DEADLINE => {
                let pid = child.id();
                let _ = child.kill();
                let _ = child.wait();
                kill_children(pid);
                panic!("{what}: the job still ran after {DEADLINE:?} (a rank waits for another)");
            }
            None => std::thread::sleep(Duration::from_millis(50)),
        }
    }
}

/// The processes whose parent is `pid`.
fn children(pid: u32) -> Vec<u32> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir("/proc").expect("/proc").flatten() {
        let Ok(p) = entry.file_name().to_string_lossy().parse::<u32>() else {
            continue;
        };
        // /proc/P/stat: "P (comm) S PPID …"; comm may hold spaces, so split after its ')'.
        let Ok(stat) = std::fs::read_to_string(format!("/proc/{p}/stat")) else {
            continue;
        };
        let Some(rest) = stat.rsplit_once(')').map(|(_, r)| r) else {
            continue;
        };
        if rest.split_whitespace().nth(1).and_then(|s| s.parse::<u32>().ok()) == Some(pid) {
            out.push(p);
        }
    }
    out
}

fn kill_children(pid: u32) {
    for c in children(pid) {
        let _ = Command::new("kill").args(["-9", &c.to_string()]).status();
    }
}

/// Lines of `text` that report an error.
fn error_lines(text: &str) -> Vec<&str> {
    text.lines().filter(|l| l.starts_with("error:")).collect()
}

/// An output directory that does not exist: every rank finds it, they agree, and the job ends
/// with exactly one message (rank 0's) and status 1, before any meshing.
#[test]
fn an_error_on_every_rank_ends_the_job_with_one_message() {
    let (dir, scene) = workdir(GOOD);
    let out = dir.path().join("missing/out.h5");
    let child = mpirun(&[app(2, &scene, &out)]).spawn().expect("mpirun runs");
    let (o, took) = finish(child, "output refused on every rank");
    let err = stderr(&o);
    assert!(!o.status.success(), "{err}");
    let errors = error_lines(&err);
    assert_eq!(errors.len(), 1, "one message: {err}");
    assert!(
        errors[0].contains("missing") && errors[0].contains("output directory does not exist"),
        "{err}"
    );
    assert!(!err.contains("MPI_ABORT"), "{err}");
    eprintln!("ended in {took:?}");
}

/// One rank given a scene it cannot read (MPMD launch: rank 0 gets the good scene, rank 1 a
/// missing one): rank 0 must not go on into the eigen-solver's collective calls alone. Every
/// rank stops at the scene, with one message naming rank 1 and the file.
#[test]
fn an_error_on_one_rank_ends_every_rank() {
    let (dir, scene) = workdir(GOOD);
    let missing = dir.path().join("nowhere.toml");
    let out = dir.path().join("out.h5");
    let child = mpirun(&[app(1, &scene, &out), app(1, &missing, &out)])
        .spawn()
        .expect("mpirun runs");
    let (o, _) = finish(child, "scene missing on rank 1");
    let err = stderr(&o);
    assert!(!o.status.success(), "{err}");
    let errors = error_lines(&err);
    assert_eq!(errors.len(), 1, "one message: {err}");
    assert!(
        errors[0].contains("MPI rank 1") && errors[0].contains("nowhere.toml"),
        "{err}"
    );
    // A clean end agreed by the ranks, not MPI_Abort killing them.
    assert!(!err.contains("MPI_ABORT"), "{err}");
    assert!(!out.exists(), "nothing written");
}

/// An error that only rank 0 can meet (it alone meshes and selects the supports; here a
/// support plane beside the part) while the other rank waits to serve its eigen-solves: rank 0
/// tells it, and the job ends with one message and status 1, not with MPI_Abort.
#[test]
fn an_error_on_rank_0_while_the_others_serve_ends_the_job_with_one_message() {
    let scene = GOOD.replace("value = 0.0", "value = 5000.0");
    assert_ne!(scene, GOOD);
    let (dir, path) = workdir(&scene);
    let out = dir.path().join("out.h5");
    let child = mpirun(&[app(2, &path, &out)]).spawn().expect("mpirun runs");
    let (o, _) = finish(child, "support beside the part");
    let err = stderr(&o);
    assert!(!o.status.success(), "{err}");
    let errors = error_lines(&err);
    assert_eq!(errors.len(), 1, "one message: {err}");
    assert!(errors[0].contains("fixed"), "{err}");
    assert!(!errors[0].contains("MPI rank"), "rank 0's own error: {err}");
    assert!(!err.contains("MPI_ABORT"), "{err}");
    assert!(!out.exists(), "nothing written");
}

/// A rank killed while the job solves (SIGKILL: no chance to report): mpirun ends the other
/// rank and exits non-zero, and no process of the job is left.
#[test]
fn a_killed_rank_ends_the_job_and_leaves_no_process() {
    // Big enough to still be running when a rank is killed (~10 s on one core).
    let scene = GOOD
        .replace("count = 4", "count = 30")
        .replace("order = 1", "order = 2")
        .replace("size = 0.05", "size = 0.012");
    assert_ne!(scene, GOOD);
    let (dir, path) = workdir(&scene);
    let out = dir.path().join("out.h5");
    // Both ranks log when their operators are assembled: the solve (MUMPS, then the
    // eigen-solver, ~10 s) starts then, and the kill is sent into it.
    let mut job = mpirun(&[app(2, &path, &out)]);
    job.env("VES_LOG", "ves_numerics::modes::slepc=debug");
    let mut child = job.spawn().expect("mpirun runs");
    let launcher = child.id();
    let piped = child.stderr.take().expect("stderr piped");
    let (tx, rx) = std::sync::mpsc::channel();
    // Reads to the end (the job must not block on a full pipe); `finish` then sees no stderr.
    std::thread::spawn(move || {
        for line in std::io::BufRead::lines(std::io::BufReader::new(piped)).map_while(Result::ok) {
            if line.contains("operators assembled") {
                let _ = tx.send(line);
            }
        }
    });
    let start = Instant::now();
    for rank in 0..2 {
        let left = DEADLINE.saturating_sub(start.elapsed());
        if rx.recv_timeout(left).is_err() {
            let _ = child.kill();
            let _ = child.wait();
            kill_children(launcher);
            panic!("only {rank} of 2 ranks reported their operators assembled within {DEADLINE:?}");
        }
    }
    let ranks: Vec<u32> = children(launcher)
        .into_iter()
        .filter(|&p| std::fs::read_to_string(format!("/proc/{p}/comm")).is_ok_and(|c| c.trim() == "ves"))
        .collect();
    assert_eq!(ranks.len(), 2, "two ranks under mpirun: {ranks:?}");
    assert!(
        child.try_wait().expect("wait").is_none() && !out.exists(),
        "the job must still be solving when the rank is killed"
    );
    let status = Command::new("kill")
        .args(["-9", &ranks[1].to_string()])
        .status()
        .expect("kill");
    assert!(status.success());
    let (o, took) = finish(child, "rank 1 killed");
    assert!(!o.status.success(), "{}", stderr(&o));
    for p in &ranks {
        assert!(
            !Path::new(&format!("/proc/{p}")).exists()
                || std::fs::read_to_string(format!("/proc/{p}/stat")).is_ok_and(|s| s.contains(") Z ")),
            "rank process {p} is still running"
        );
    }
    assert!(!out.exists(), "nothing written");
    eprintln!("ended {took:?} after the kill");
}
