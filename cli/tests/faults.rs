//! Faults while writing results: a full disk (a file-size limit, which fails writes exactly as
//! ENOSPC does, at any chosen byte) must give a non-zero exit with one clear line, and leave the
//! old basis and its XDMF sidecar as they were, with no temporary left beside them.

mod common;

use common::*;
use std::os::unix::process::CommandExt;
use std::path::Path;
use std::process::{Command, Output};

/// `ves args…` with writes limited to files of `limit` bytes (SIGXFSZ ignored, so a write past
/// the limit fails with EFBIG instead of killing the process), the mesh cache in `cache`.
fn ves_limited(args: &[&str], limit: u64, cache: &Path) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_ves"));
    c.args(args).env("VES_CACHE_DIR", cache);
    // SAFETY: only async-signal-safe calls between fork and exec.
    unsafe {
        c.pre_exec(move || {
            libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
            let r = libc::rlimit {
                rlim_cur: limit,
                rlim_max: limit,
            };
            if libc::setrlimit(libc::RLIMIT_FSIZE, &r) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    c.output().expect("ves runs")
}

fn run(args: &[&str], cache: &Path) -> Output {
    ves_limited(args, libc::RLIM_INFINITY, cache)
}

fn names_in(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .expect("dir")
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn a_full_disk_leaves_the_old_basis_and_sidecar_and_fails() {
    let (dir, scene) = workdir(GOOD);
    let cache = dir.path().join("cache");
    let out = dir.path().join("beam.h5");
    let sidecar = dir.path().join("beam.xdmf");
    let (s, o) = (scene.to_str().unwrap(), out.to_str().unwrap());
    let first = run(&["precompute", s, "-o", o], &cache);
    assert!(first.status.success(), "{}", stderr(&first));
    let (old_basis, old_sidecar) = (
        std::fs::read(&out).expect("basis"),
        std::fs::read(&sidecar).expect("xdmf"),
    );
    let listing = names_in(dir.path());
    // A different result (three modes), the mesh from the cache: only the outputs are written.
    // Its size, from a run elsewhere, places the limits across the whole new file.
    std::fs::write(&scene, GOOD.replace("count = 4", "count = 3")).expect("scene");
    let elsewhere = dir.path().join("cache").join("new.h5");
    let r = run(&["precompute", s, "-o", elsewhere.to_str().unwrap()], &cache);
    assert!(r.status.success(), "{}", stderr(&r));
    let size = std::fs::metadata(&elsewhere).expect("new basis").len();
    let fractions = [0.25, 0.4, 0.5, 0.55, 0.6, 0.65, 0.7, 0.8, 0.9, 0.95, 0.99];
    let limits = [0, 4096].into_iter().chain(fractions.map(|f| (f * size as f64) as u64));
    for limit in limits {
        let e = ves_limited(&["precompute", s, "-o", o], limit, &cache);
        let err = stderr(&e);
        assert!(!e.status.success(), "limit {limit} B: exit 0 ({err})");
        // One line (warnings aside) that names the output and the cause.
        let errors: Vec<&str> = err
            .lines()
            .filter(|l| !l.contains(" WARN ") && !l.trim().is_empty())
            .collect();
        assert!(
            errors.len() == 1 && errors[0].contains("beam.h5") && errors[0].contains("free space"),
            "limit {limit} B: not one line naming the output and what to do: {err}"
        );
        assert_eq!(
            std::fs::read(&out).expect("basis"),
            old_basis,
            "limit {limit} B: basis replaced"
        );
        assert_eq!(
            std::fs::read(&sidecar).expect("xdmf"),
            old_sidecar,
            "limit {limit} B: sidecar replaced"
        );
        assert_eq!(names_in(dir.path()), listing, "limit {limit} B: files left behind");
    }
    // With room enough, the same run replaces both.
    let e = ves_limited(&["precompute", s, "-o", o], size + 4096, &cache);
    assert!(e.status.success(), "{}", stderr(&e));
    let info = run(&["info", o, "--json"], &cache);
    assert!(info.status.success(), "{}", stderr(&info));
    let v: serde_json::Value = serde_json::from_slice(&info.stdout).expect("info JSON");
    assert_eq!(v["spaces"][0]["modes"], 3);
    assert_ne!(
        std::fs::read(&sidecar).expect("xdmf"),
        old_sidecar,
        "sidecar not replaced"
    );
}

#[test]
fn a_full_disk_during_matrices_fails_and_keeps_the_old_file() {
    let (dir, scene) = workdir(GOOD);
    let cache = dir.path().join("cache");
    let out = dir.path().join("km.h5");
    let (s, o) = (scene.to_str().unwrap(), out.to_str().unwrap());
    let first = run(&["matrices", s, "-o", o], &cache);
    assert!(first.status.success(), "{}", stderr(&first));
    let old = std::fs::read(&out).expect("matrices");
    std::fs::write(&scene, GOOD.replace("young = 2.1e11", "young = 7.0e10")).expect("scene");
    let limits = [0.1, 0.3, 0.5, 0.6, 0.7, 0.8, 0.9, 0.99].map(|f| (f * old.len() as f64) as u64);
    for limit in limits {
        let e = ves_limited(&["matrices", s, "-o", o], limit, &cache);
        assert!(!e.status.success(), "limit {limit} B: exit 0 ({})", stderr(&e));
        assert_eq!(std::fs::read(&out).expect("matrices"), old, "limit {limit} B: replaced");
    }
}

/// A scene's `name` names its output file: `../x`, an absolute path, an empty name, a newline or
/// a bidi override must be refused before any work, and nothing outside `--out` touched.
#[test]
fn scene_names_that_are_paths_or_hide_characters_are_refused() {
    let (dir, _) = workdir(GOOD);
    let victim_dir = dir.path().join("victim");
    std::fs::create_dir(&victim_dir).expect("dir");
    let victim = victim_dir.join("important.h5");
    std::fs::write(&victim, "precious").expect("write");
    let abs = dir.path().join("abs");
    std::fs::write(abs.with_extension("h5"), "precious").expect("write");
    let out = dir.path().join("bout");
    std::fs::create_dir(&out).expect("dir");
    let names = [
        "../victim/important".to_string(),
        abs.display().to_string(),
        String::new(),
        "a\nb".to_string(),
        "evil\u{202E}5h.exe".to_string(),
        "..".to_string(),
    ];
    for name in &names {
        let text = GOOD.replace("name = \"beam\"", &format!("name = {name:?}"));
        let scene = write_file(dir.path(), "s.toml", &text);
        for args in [
            vec!["batch", scene.to_str().unwrap(), "--out", out.to_str().unwrap()],
            vec!["precompute", scene.to_str().unwrap()],
        ] {
            let o = ves(&args);
            let err = stderr(&o);
            assert!(!o.status.success(), "{args:?} with name {name:?}: exit 0 ({err})");
            assert!(err.contains("name"), "{name:?}: the error does not name the key: {err}");
            assert!(!err.contains('\u{202E}'), "the bidi override is printed raw: {err}");
        }
        assert_eq!(std::fs::read_to_string(&victim).expect("victim"), "precious");
        assert_eq!(
            std::fs::read_to_string(abs.with_extension("h5")).expect("abs"),
            "precious"
        );
        assert_eq!(
            std::fs::read_dir(&out).expect("out").count(),
            0,
            "{name:?} wrote into --out"
        );
    }
    // A scene file whose stem is not a name is told to set one; with a name it runs.
    let bad_stem = write_file(dir.path(), "a\u{202E}b.toml", &GOOD.replace("name = \"beam\"\n", ""));
    let o = ves(&[
        "precompute",
        bad_stem.to_str().unwrap(),
        "-o",
        out.join("x.h5").to_str().unwrap(),
    ]);
    let err = stderr(&o);
    assert!(!o.status.success() && err.contains("set name"), "{err}");
}
