//! `ves batch` shared by many processes: shards of a job array and whole batches started at once
//! on one output folder compute every scene exactly once; a killed shard's scene is taken over
//! (at once on its host, after the lease from another); nothing temporary is left.

mod common;
use common::*;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// A light scene named `name` with `modes` modes.
fn light(name: &str, modes: usize) -> String {
    GOOD.replace("name = \"beam\"", &format!("name = \"{name}\""))
        .replace("count = 4", &format!("count = {modes}"))
}

/// A scene heavy enough (10-node tets, 20 modes: 3.5 s here) that its owner is stopped
/// (SIGSTOP) mid-compute, never racing its end.
fn heavy(name: &str) -> String {
    light(name, 20)
        .replace("order = 1", "order = 2")
        .replace("size = 0.05", "size = 0.012")
}

fn signal(pid: u32, sig: i32) {
    assert_eq!(unsafe { libc::kill(pid as i32, sig) }, 0, "kill({pid}, {sig})");
}

/// A folder of scenes beside the cantilever's STEP file.
fn scenes(texts: &[(&str, String)]) -> (tempfile::TempDir, PathBuf) {
    let (dir, first) = workdir(GOOD);
    std::fs::remove_file(first).expect("rm");
    let d = dir.path().join("scenes");
    std::fs::create_dir(&d).expect("mkdir");
    std::fs::rename(dir.path().join("beam.step"), d.join("beam.step")).expect("mv");
    for (file, text) in texts {
        std::fs::write(d.join(file), text).expect("scene");
    }
    (dir, d)
}

fn batch(dir: &Path, out: &Path, extra: &[&str]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_ves"));
    c.args(["batch", dir.to_str().unwrap(), "--out", out.to_str().unwrap(), "--json"])
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    c
}

/// The outcomes of a finished batch (it must have succeeded).
fn outcomes(child: Child) -> Vec<serde_json::Value> {
    let o = child.wait_with_output().expect("wait");
    last_json(&o).as_array().expect("an array of outcomes").clone()
}

fn status_of<'a>(v: &'a [serde_json::Value], output: &str) -> Option<&'a str> {
    v.iter()
        .find(|o| o["output"].as_str().is_some_and(|s| s.ends_with(output)))
        .and_then(|o| o["status"].as_str())
}

/// Claims and temporaries left in a folder.
fn leftovers(out: &Path) -> Vec<String> {
    std::fs::read_dir(out)
        .expect("ls")
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(".claim") || n.contains(".tmp-"))
        .collect()
}

/// Waits until `path` exists (or the deadline).
fn appears(path: &Path, within: Duration) -> bool {
    let t = Instant::now();
    while t.elapsed() < within {
        if path.exists() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    false
}

fn status_json(dir: &Path, out: &Path) -> serde_json::Value {
    let o = batch(dir, out, &["--status"]).output().expect("status");
    last_json(&o)
}

/// Three shards and two whole batches at once on one folder of eight scenes: every scene is
/// computed by exactly one process, the shards' shares are disjoint and cover the batch, the
/// whole batches end with every scene done (by them or by others), every output is readable and
/// no claim or temporary is left.
#[test]
fn three_shards_and_two_whole_batches_at_once_compute_each_scene_once() {
    let texts: Vec<(String, String)> = (0..8)
        .map(|i| (format!("s{i}.toml"), light(&format!("part{i}"), 4 + i)))
        .collect();
    let texts: Vec<(&str, String)> = texts.iter().map(|(f, t)| (f.as_str(), t.clone())).collect();
    let (_keep, dir) = scenes(&texts);
    let out = dir.join("../out");
    let mut children = Vec::new();
    for k in 1..=3 {
        let shard = format!("{k}/3");
        children.push((Some(k), batch(&dir, &out, &["--shard", &shard]).spawn().expect("spawn")));
    }
    for _ in 0..2 {
        children.push((None, batch(&dir, &out, &[]).spawn().expect("spawn")));
    }
    let mut done: HashMap<String, usize> = HashMap::new();
    let mut shares: Vec<Vec<String>> = Vec::new();
    for (shard, child) in children {
        let v = outcomes(child);
        let mut share = Vec::new();
        for o in &v {
            let output = o["output"].as_str().expect("output").to_string();
            let status = o["status"].as_str().expect("status");
            assert!(status == "done" || status == "up-to-date", "{shard:?}: {o}");
            if status == "done" {
                *done.entry(output.clone()).or_default() += 1;
            }
            // A shard lists its share, and the other shards' scenes it took and computed.
            match (shard, o["shard"].as_u64()) {
                (Some(k), Some(of)) if of != k => {
                    assert_eq!(status, "done", "a scene taken is reported when done: {o}")
                }
                (Some(_), None) => panic!("a shard's outcome names its shard: {o}"),
                _ => share.push(output),
            }
        }
        match shard {
            Some(_) => shares.push(share),
            None => assert_eq!(share.len(), 8, "a whole batch reports every scene: {v:?}"),
        }
    }
    assert_eq!(done.len(), 8, "every scene computed: {done:?}");
    assert!(done.values().all(|&n| n == 1), "a scene computed twice: {done:?}");
    let mut all: Vec<String> = shares.concat();
    all.sort();
    all.dedup();
    assert_eq!(all.len(), 8, "the shards cover the batch");
    assert_eq!(
        shares.iter().map(Vec::len).sum::<usize>(),
        8,
        "the shards' shares are disjoint: {shares:?}"
    );
    for f in done.keys() {
        assert!(ves(&["info", f]).status.success(), "{f} unreadable");
    }
    assert!(leftovers(&out).is_empty(), "left: {:?}", leftovers(&out));
    let s = status_json(&dir, &out);
    assert_eq!(
        (s["up_to_date"].as_u64(), s["left"].as_u64()),
        (Some(8), Some(0)),
        "{s}"
    );
}

/// A batch killed mid-scene leaves its claim; while it ran, another batch left that scene to it;
/// its restart takes the scene back at once (same host, the owner's pid is gone) and finishes it
/// once, removing the claim and the temporaries.
#[test]
fn a_batch_killed_mid_scene_is_finished_once_by_its_restart() {
    let (_keep, dir) = scenes(&[("a.toml", light("a", 4)), ("b.toml", heavy("b"))]);
    let out = dir.join("../out");
    let first = batch(&dir, &out, &["--shard", "1/1"]).spawn().expect("spawn");
    let pid = first.id();
    let claim = out.join("b.h5.claim");
    assert!(
        appears(&claim, Duration::from_secs(120)),
        "the heavy scene was never claimed"
    );
    // Frozen mid-compute (alive, its pid runs), so nothing below races its end.
    signal(pid, libc::SIGSTOP);
    // A batch started meanwhile leaves the claimed scene to its owner (not waiting for it).
    let o = batch(&dir, &out, &["--no-wait"]).output().expect("second batch");
    let v = last_json(&o).as_array().expect("outcomes").clone();
    assert_eq!(status_of(&v, "b.h5"), Some("claimed-elsewhere"), "{v:?}");
    let by = v
        .iter()
        .find_map(|o| o["claimed_by"].as_str())
        .expect("claimed_by")
        .to_string();
    assert!(by.contains(&format!("pid {pid}")) && by.contains("shard 1/1"), "{by}");
    let s = status_json(&dir, &out);
    assert_eq!(s["claimed"].as_u64(), Some(1), "{s}");
    // Killed (SIGKILL: nothing of it runs to clean up).
    signal(pid, libc::SIGKILL);
    let _ = first.wait_with_output();
    assert!(!out.join("b.h5").exists(), "killed while b ran");
    assert!(claim.exists(), "a killed owner leaves its claim");
    let s = status_json(&dir, &out);
    assert_eq!(
        (s["claimed"].as_u64(), s["left"].as_u64()),
        (Some(0), Some(1)),
        "a dead owner's scene is left: {s}"
    );
    // A temporary output of the killed batch, as a kill mid-write leaves it.
    let me = ves_pipeline::host::this().id.clone();
    let half = out.join(format!("b.h5.tmp-@{me}-{pid}.Ab3dEf9h"));
    std::fs::write(&half, b"half").expect("plant");
    let v = outcomes(batch(&dir, &out, &[]).spawn().expect("restart"));
    assert_eq!(
        (status_of(&v, "a.h5"), status_of(&v, "b.h5")),
        (Some("up-to-date"), Some("done")),
        "{v:?}"
    );
    assert!(ves(&["info", out.join("b.h5").to_str().unwrap()]).status.success());
    assert!(leftovers(&out).is_empty(), "left: {:?}", leftovers(&out));
}

/// Two "hosts": a batch in a PID and network namespace of its own (its pids mean nothing outside)
/// claims a scene with a 5-second lease and renews it. Another batch leaves the scene alone;
/// once the owner is silent (stopped, then killed), the other takes the scene over when the
/// lease and its clock allowance have run out, finishes it once and leaves nothing behind.
#[test]
fn a_claim_from_another_pid_namespace_is_taken_over_after_its_lease() {
    let ns = ["--pid", "--net", "--fork", "--kill-child", "--mount-proc"];
    if !Command::new("unshare")
        .args(ns)
        .arg("true")
        .status()
        .is_ok_and(|s| s.success())
    {
        eprintln!("SKIPPED: `unshare --pid --net --mount-proc` is not permitted here (needs root or user namespaces)");
        return;
    }
    let (_keep, dir) = scenes(&[("b.toml", heavy("b"))]);
    let out = dir.join("../out");
    std::fs::create_dir(&out).expect("mkdir");
    let mut elsewhere = Command::new("unshare")
        .args(ns)
        .arg(env!("CARGO_BIN_EXE_ves"))
        .args([
            "batch",
            dir.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--lease",
            "5",
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn in namespaces");
    let claim = out.join("b.h5.claim");
    assert!(appears(&claim, Duration::from_secs(120)), "never claimed");
    // Renewed from inside its namespace (every quarter lease).
    let record = || -> serde_json::Value {
        std::fs::read(&claim)
            .ok()
            .and_then(|b| serde_json::from_slice(&b).ok())
            .unwrap_or_default()
    };
    let t = Instant::now();
    while record()["renewed_unix"].as_f64() <= record()["started_unix"].as_f64() {
        assert!(t.elapsed() < Duration::from_secs(60), "never renewed: {}", record());
        std::thread::sleep(Duration::from_millis(50));
    }
    let owner = record();
    assert_ne!(owner["host_id"], ves_pipeline::host::this().id.as_str(), "{owner}");
    // Freeze the owner (the namespace's first process, a child of `unshare`).
    let children = std::fs::read_to_string(format!("/proc/{0}/task/{0}/children", elsewhere.id())).expect("children");
    let inner: u32 = children
        .split_whitespace()
        .next()
        .and_then(|p| p.parse().ok())
        .expect("the batch's pid");
    signal(inner, libc::SIGSTOP);
    let o = batch(&dir, &out, &["--no-wait"]).output().expect("batch");
    let v = last_json(&o).as_array().expect("outcomes").clone();
    assert_eq!(
        status_of(&v, "b.h5"),
        Some("claimed-elsewhere"),
        "within its lease: {v:?}"
    );
    let last = record()["renewed_unix"].as_f64().expect("renewed");
    let _ = elsewhere.kill();
    let _ = elsewhere.wait();
    assert!(!out.join("b.h5").exists(), "killed while b ran");
    let v = outcomes(batch(&dir, &out, &[]).spawn().expect("batch"));
    assert_eq!(status_of(&v, "b.h5"), Some("done"), "{v:?}");
    // Taken over (and then computed) only once the lease (5 s) and its clock allowance (5 s)
    // had run out since the last renewal.
    let ended = ves_pipeline::host::unix_now() - last;
    assert!(
        ended > 10.0,
        "done {ended:.1} s after the owner's last renewal: taken over too early"
    );
    assert!(ves(&["info", out.join("b.h5").to_str().unwrap()]).status.success());
    assert!(leftovers(&out).is_empty(), "left: {:?}", leftovers(&out));
}

/// Shards by hand and from a Slurm array agree; bad shard and lease values are one-line errors.
#[test]
fn shard_and_lease_values_are_checked() {
    let (_keep, dir) = scenes(&[("a.toml", light("a", 4))]);
    let out = dir.join("../out");
    for (args, expect) in [
        (vec!["--shard", "4/3"], "--shard"),
        (vec!["--shard", "auto"], "SLURM_ARRAY_TASK_ID"),
        (vec!["--lease", "0"], "--lease"),
    ] {
        let o = batch(&dir, &out, &args)
            .env_remove("SLURM_ARRAY_TASK_ID")
            .output()
            .expect("run");
        assert_refused(&o, expect);
    }
    // Task 7 of an array 5-7 is shard 3/3; with one scene the first shard has it: kept to its
    // share, this one computes nothing; by default it takes the scene shard 1 has not claimed.
    let task7 = |extra: &[&str]| {
        batch(&dir, &out, &[&["--shard", "auto"], extra].concat())
            .env("SLURM_ARRAY_TASK_ID", "7")
            .env("SLURM_ARRAY_TASK_COUNT", "3")
            .env("SLURM_ARRAY_TASK_MIN", "5")
            .output()
            .expect("run")
    };
    let o = task7(&["--no-steal"]);
    assert!(last_json(&o).as_array().expect("outcomes").is_empty(), "{o:?}");
    assert!(!out.join("a.h5").exists());
    let o = task7(&[]);
    let v = last_json(&o).as_array().expect("outcomes").clone();
    assert_eq!(
        (v.len(), v[0]["status"].as_str(), v[0]["shard"].as_u64()),
        (1, Some("done"), Some(1)),
        "{v:?}"
    );
    assert!(out.join("a.h5").exists());
}

/// Two scenes naming one output, on two shards: the first in the agreed order writes it, the
/// other fails on its shard with the reason (before, the later shard overwrote the first's
/// output).
#[test]
fn scenes_naming_one_output_are_refused_alike_on_every_shard() {
    let (_keep, dir) = scenes(&[("a.toml", light("same", 4)), ("b.toml", light("same", 5))]);
    let out = dir.join("../out");
    let mut all = Vec::new();
    for k in ["1/2", "2/2"] {
        let o = batch(&dir, &out, &["--shard", k, "--no-steal"]).output().expect("run");
        let stdout = String::from_utf8_lossy(&o.stdout);
        let line = stdout.lines().last().unwrap_or("[]");
        all.extend(serde_json::from_str::<Vec<serde_json::Value>>(line).expect("outcomes"));
    }
    assert_eq!(all.len(), 2, "{all:?}");
    let of = |scene: &str| {
        all.iter()
            .find(|o| o["scene"].as_str().is_some_and(|s| s.ends_with(scene)))
            .expect("scene")
    };
    assert_eq!(of("a.toml")["status"], "done", "{all:?}");
    assert_eq!(of("b.toml")["status"], "failed", "{all:?}");
    assert!(
        of("b.toml")["error"].as_str().unwrap_or("").contains("also written by"),
        "{all:?}"
    );
    let info = ves(&["info", out.join("same.h5").to_str().unwrap(), "--json"]);
    assert_eq!(frequencies(&last_json(&info)).len(), 4, "a.toml's 4 modes");
}

/// A scene that fails on two shards that take each other's scenes: only its own shard reports
/// it (and exits 1); the other computes the rest and exits 0; the failure is recorded beside the
/// output, `--status` says it, and a later batch tries it again.
#[test]
fn a_failing_scene_is_reported_by_its_own_shard_only() {
    let failing = light("bad", 4).replace("value = 0.0 }", "value = 9.0 }");
    let (_keep, dir) = scenes(&[
        ("a.toml", light("a", 4)),
        ("b.toml", light("b", 5)),
        ("c.toml", light("c", 6)),
        ("bad.toml", failing),
    ]);
    let out = dir.join("../out");
    let shards: Vec<_> = ["1/2", "2/2"]
        .iter()
        .map(|k| batch(&dir, &out, &["--shard", k]).spawn().expect("spawn"))
        .collect();
    let mut reported = 0;
    let mut exits = Vec::new();
    for child in shards {
        let o = child.wait_with_output().expect("wait");
        let stdout = String::from_utf8_lossy(&o.stdout);
        let v: Vec<serde_json::Value> = serde_json::from_str(stdout.lines().last().unwrap_or("[]")).expect("outcomes");
        let failed: Vec<_> = v.iter().filter(|o| o["status"] == "failed").collect();
        assert!(
            failed
                .iter()
                .all(|o| o["scene"].as_str().unwrap_or("").ends_with("bad.toml")),
            "{v:?}"
        );
        reported += failed.len();
        exits.push((o.status.code(), failed.len()));
    }
    assert_eq!(reported, 1, "reported once: {exits:?}");
    assert!(
        exits.iter().all(|(code, n)| *code == Some(if *n > 0 { 1 } else { 0 })),
        "{exits:?}"
    );
    for name in ["a", "b", "c"] {
        assert!(out.join(format!("{name}.h5")).exists());
    }
    let s = status_json(&dir, &out);
    assert_eq!(
        (s["up_to_date"].as_u64(), s["failed"].as_u64()),
        (Some(3), Some(1)),
        "{s}"
    );
    let bad = s["scenes"]
        .as_array()
        .expect("scenes")
        .iter()
        .find(|x| x["state"] == "failed")
        .expect("failed")
        .clone();
    assert!(bad["error"].as_str().unwrap_or("").contains("fixed[0]"), "{bad}");
    // A whole batch tries it again (and fails again, saying why).
    let o = batch(&dir, &out, &[]).output().expect("batch");
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("bad.toml"), "{}", stderr(&o));
    assert!(leftovers(&out).is_empty(), "left: {:?}", leftovers(&out));
}

/// Slurm's time limit and scancel end a task with SIGTERM: its claim is released on the way out,
/// so a requeue on another node need not wait out the lease.
#[test]
fn a_terminated_batch_releases_its_claim() {
    let (_keep, dir) = scenes(&[("b.toml", heavy("b"))]);
    let out = dir.join("../out");
    let child = batch(&dir, &out, &[]).spawn().expect("spawn");
    let claim = out.join("b.h5.claim");
    assert!(appears(&claim, Duration::from_secs(120)), "never claimed");
    signal(child.id(), libc::SIGTERM);
    let o = child.wait_with_output().expect("wait");
    assert!(!o.status.success());
    assert!(!out.join("b.h5").exists(), "terminated while b ran");
    assert!(!claim.exists(), "the claim outlived a SIGTERM");
}

/// A scene may be named like a temporary of another's output (`b.h5.tmp-4999999`): its finished
/// output (`b.h5.tmp-4999999.h5`) was removed as a dead process's leftover by the next batch that
/// wrote `b.h5`.
#[test]
fn outputs_named_like_temporaries_are_kept() {
    let (_keep, dir) = scenes(&[("a.toml", light("b.h5.tmp-4999999", 4)), ("b.toml", light("b", 4))]);
    let out = dir.join("../out");
    let o = batch(&dir, &out, &[]).output().expect("batch");
    assert!(o.status.success(), "{}", stderr(&o));
    let v = outcomes(batch(&dir, &out, &[]).spawn().expect("again"));
    assert!(v.iter().all(|o| o["status"] == "up-to-date"), "{v:?}");
    assert!(out.join("b.h5.tmp-4999999.h5").exists() && out.join("b.h5.tmp-4999999.xdmf").exists());
}
