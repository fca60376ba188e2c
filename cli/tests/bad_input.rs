//! Inputs that hurt a new user (issue "One house, no sharp edges"), one regression test each:
//! every one must end in one clear line that names the input and what to change, a non-zero
//! exit status, and nothing overwritten.

mod common;

use common::*;
use std::path::Path;

/// LAPACK printed `On entry to DLASCL parameter number 4 had an illegal value` and the process
/// exited 0 with no output.
#[test]
fn density_1e120_and_moduli_beyond_real_materials_are_refused() {
    fails(
        &GOOD.replace("density = 7850.0", "density = 1e120"),
        &["material.density", "range of real materials", "kg/m³"],
    );
    fails(
        &GOOD.replace("young = 2.1e11", "young = 1e-200"),
        &["material.young", "range of real materials", "Pa"],
    );
    // Used to fail deep in ARPACK with "the starting vector is zero".
    fails(
        &GOOD.replace("young = 2.1e11", "young = 1e300"),
        &["material.young", "range of real materials"],
    );
}

/// Inside `ves batch` the LAPACK exit ended the whole batch silently with status 0.
#[test]
fn batch_with_an_absurd_density_reports_that_scene_and_finishes_the_others() {
    let (dir, good) = workdir(GOOD);
    let bad = write_file(
        dir.path(),
        "heavy.toml",
        &GOOD
            .replace("density = 7850.0", "density = 1e120")
            .replace("name = \"beam\"", "name = \"heavy\""),
    );
    let o = ves(&["batch", good.to_str().unwrap(), bad.to_str().unwrap()]);
    assert!(!o.status.success(), "the batch must fail");
    let err = stderr(&o);
    assert!(err.contains("heavy"), "{err}");
    assert!(dir.path().join("beam.h5").is_file(), "the good scene was not done");
    assert!(!dir.path().join("heavy.h5").exists());
}

/// `-o` equal to the scene or its STEP file overwrote the input with exit status 0.
#[test]
fn output_that_is_an_input_is_refused_and_the_input_kept() {
    let (dir, scene) = workdir(GOOD);
    let step = dir.path().join("beam.step");
    for target in [&scene, &step] {
        let before = std::fs::read(target).unwrap();
        let o = ves(&["precompute", scene.to_str().unwrap(), "-o", target.to_str().unwrap()]);
        assert!(!o.status.success());
        assert!(stderr(&o).contains("is an input"), "{}", stderr(&o));
        assert_eq!(std::fs::read(target).unwrap(), before, "{} changed", target.display());
    }
    // Through a symlink, even with --force.
    let link = dir.path().join("link.h5");
    std::os::unix::fs::symlink(&scene, &link).unwrap();
    let o = ves(&[
        "precompute",
        scene.to_str().unwrap(),
        "-o",
        link.to_str().unwrap(),
        "--force",
    ]);
    assert_refused(&o, "is an input");
    let o = ves(&["matrices", scene.to_str().unwrap(), "-o", step.to_str().unwrap()]);
    assert_refused(&o, "is an input");
}

/// A device node or a symlink as output was replaced by a regular file.
#[test]
fn symlink_and_device_outputs_are_refused_unless_forced() {
    let (dir, scene) = workdir(GOOD);
    let target = dir.path().join("elsewhere.txt");
    std::fs::write(&target, "keep me").unwrap();
    let link = dir.path().join("out.h5");
    std::os::unix::fs::symlink(&target, &link).unwrap();
    let o = ves(&["precompute", scene.to_str().unwrap(), "-o", link.to_str().unwrap()]);
    assert_refused(&o, "--force");
    assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
    let o = ves(&[
        "precompute",
        scene.to_str().unwrap(),
        "-o",
        link.to_str().unwrap(),
        "--force",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_file());
    assert_eq!(std::fs::read_to_string(&target).unwrap(), "keep me");
    let o = ves(&["precompute", scene.to_str().unwrap(), "-o", "/dev/null", "--force"]);
    assert_refused(&o, "not a regular file");
}

/// A read-only output directory was found only after the whole computation.
#[test]
fn unwritable_output_directory_is_found_before_meshing() {
    let (_dir, scene) = workdir(GOOD);
    // sysfs refuses new files even to root.
    let o = ves(&["precompute", scene.to_str().unwrap(), "-o", "/sys/ves-out.h5", "--json"]);
    assert!(!o.status.success());
    let err = stderr(&o);
    assert!(err.contains("cannot write in /sys") && err.contains("-o"), "{err}");
    assert!(o.stdout.is_empty());
}

/// A killed precompute left `OUT.tmp-PID` that only `ves batch` cleaned.
#[test]
fn precompute_removes_temporaries_of_killed_runs() {
    let (dir, scene) = workdir(GOOD);
    let out = dir.path().join("beam.h5");
    // pid_max is at most 2^22 on Linux: no process has this one.
    let stale = dir.path().join(format!(
        "beam.h5.tmp-@{}-4999999.Ab3dEf9h",
        ves_pipeline::host::this().id
    ));
    std::fs::write(&stale, "half a basis").unwrap();
    let o = ves(&["precompute", scene.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stale.exists(), "stale temporary left");
    assert!(out.is_file());
}

/// A .geo geometry is a gmsh script: `System "…"` runs shell commands.
#[test]
fn geo_scripts_run_only_with_an_explicit_flag() {
    let (dir, _) = workdir(GOOD);
    let marker = dir.path().join("ran");
    let geo = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../cases/cantilever/cantilever.geo"))
        .unwrap();
    std::fs::write(
        dir.path().join("beam.geo"),
        format!("{geo}\nSystem \"touch {}\";\n", marker.display()),
    )
    .unwrap();
    let scene = write_file(
        dir.path(),
        "geo.toml",
        &GOOD
            .replace("beam.step", "beam.geo")
            .replace("name = \"beam\"", "name = \"geo\""),
    );
    let s = scene.to_str().unwrap();
    for args in [
        vec!["precompute", s],
        vec!["batch", s],
        vec!["matrices", s, "-o", "m.h5"],
    ] {
        let o = ves(&args);
        assert!(!o.status.success(), "{args:?} accepted a script");
        assert!(stderr(&o).contains("--allow-geo-scripts"), "{args:?}: {}", stderr(&o));
        assert!(!marker.exists(), "{args:?} ran the script's command");
    }
    let o = ves(&["precompute", s, "--allow-geo-scripts"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(marker.exists(), "the trusted script ran");
}

/// gmsh runs in a child process: a script's `Exit;` (gmsh calls exit(0)) ended `ves precompute`
/// with status 0 and no output before; now it is one line, status 1, and the old output kept.
#[test]
fn gmsh_ending_its_process_is_an_error_not_a_success() {
    let (dir, _) = workdir(GOOD);
    std::fs::write(
        dir.path().join("exit.geo"),
        "SetFactory(\"OpenCASCADE\");\nBox(1) = {0, 0, 0, 1000, 100, 50};\nExit;\n",
    )
    .unwrap();
    let scene = write_file(dir.path(), "exit.toml", &GOOD.replace("beam.step", "exit.geo"));
    let out = dir.path().join("out.h5");
    std::fs::write(&out, b"previous result").unwrap();
    let o = ves(&[
        "precompute",
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--allow-geo-scripts",
    ]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(
        err.contains("while reading the geometry") && err.contains("remove what ends gmsh"),
        "{err}"
    );
    assert_eq!(std::fs::read(&out).unwrap(), b"previous result");
}

/// `mesh.size = 1e-9`: gmsh ate memory for 21 s and aborted with std::bad_alloc (exit 134).
#[test]
fn absurdly_small_mesh_size_is_refused_before_meshing_with_a_size_that_fits() {
    let (dir, scene) = workdir(&GOOD.replace("size = 0.05", "size = 1e-9"));
    let o = ves(&["precompute", scene.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(err.contains("mesh.size") && err.contains("use mesh.size ≥"), "{err}");
    assert!(!dir.path().join("beam.h5").exists());
    // Exit 1 (not gmsh's abort, 134) and a size to use: for this 1 m beam, the budget's bound
    // (following it meshes 10⁷ tets, too heavy for a test) lies between 0.1 mm and 5 cm.
    let suggested = number_after(&err, "use mesh.size ≥ ");
    assert!(suggested > 1e-4 && suggested < 0.05, "{suggested}");
}

/// `ves session --duration inf` panicked (capacity overflow); `nan`, `-1`, `0` ran one step and
/// exited 0.
#[test]
fn session_durations_that_are_not_a_positive_finite_time_are_refused() {
    let (dir, basis) = good_basis();
    let script = dir.path().join("hand.csv");
    std::fs::write(&script, "0,1,0.05,0.05\n0.01,1,0.05,0.05\n").unwrap();
    let dev = format!("script:{}", script.display());
    for d in ["inf", "nan", "-1", "0", "-inf"] {
        let arg = format!("--duration={d}");
        let o = ves(&["session", basis.to_str().unwrap(), "--device", &dev, &arg]);
        assert_eq!(o.status.code(), Some(1), "--duration {d}: {}", stderr(&o));
        assert!(stderr(&o).contains("--duration"), "--duration {d}: {}", stderr(&o));
    }
    for (flag, v) in [("--stiffness", "nan"), ("--max-force", "-1"), ("--damping", "inf")] {
        let arg = format!("{flag}={v}");
        let o = ves(&["session", basis.to_str().unwrap(), "--device", &dev, &arg]);
        assert_eq!(o.status.code(), Some(1), "{flag} {v}: {}", stderr(&o));
        assert!(stderr(&o).contains(flag), "{flag} {v}: {}", stderr(&o));
    }
}

/// `ves session --trace … --duration 1e7` reserved a row per step of every hand before the
/// session (1.7 TB at 1 kHz) and aborted; a trace longer than its stated limit is refused.
#[test]
fn a_trace_longer_than_its_limit_is_refused_before_anything_runs() {
    let (dir, basis) = good_basis();
    let script = dir.path().join("hand.csv");
    std::fs::write(&script, "0,1,0.05,0.05\n0.01,1,0.05,0.05\n").unwrap();
    let dev = format!("script:{}", script.display());
    let trace = dir.path().join("trace.csv");
    for d in ["1e7", "2000"] {
        let arg = format!("--duration={d}");
        let o = ves(&[
            "session",
            basis.to_str().unwrap(),
            "--device",
            &dev,
            &arg,
            "--trace",
            trace.to_str().unwrap(),
            "--no-realtime",
        ]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "--duration {d}: {err}");
        assert!(
            err.contains("--duration") && err.contains("--trace") && err.contains("1000000 steps"),
            "--duration {d}: {err}"
        );
        assert_eq!(err.trim().lines().count(), 1, "{err}");
        assert!(!trace.exists());
    }
}

/// Rewrites one dataset of a copy of `basis` and returns the copy.
fn damaged(basis: &Path, name: &str, edit: impl FnOnce(&hdf5::Group)) -> std::path::PathBuf {
    let copy = basis.with_file_name(name);
    std::fs::copy(basis, &copy).unwrap();
    // As VES opens files: no HDF5 lock (a `ves` child started by another test while this is
    // open would inherit it), strong close.
    let f = ves_format::file::open_rw(&copy).unwrap();
    edit(&f.group("spaces/global").unwrap());
    f.close().unwrap();
    copy
}

/// `ves info` exited 0 on files the runtime refuses; an int32 basis or a NaN in rows the runtime
/// does not load was converted or ignored.
#[test]
fn info_bench_session_and_verify_refuse_what_the_format_forbids() {
    let (dir, basis) = good_basis();
    let nan_eigen = damaged(&basis, "nan_eigen.h5", |g| {
        let ds = g.dataset("modes/eigenvalues").unwrap();
        let mut v: Vec<f64> = ds.read_raw().unwrap();
        v[1] = f64::NAN;
        ds.write_raw(&v).unwrap();
    });
    let bad_triangle = damaged(&basis, "bad_triangle.h5", |g| {
        let ds = g.dataset("mesh/surface_triangles").unwrap();
        let mut v: ndarray::Array2<u32> = ds.read_2d().unwrap();
        v[(0, 1)] = 4_000_000;
        ds.write(&v).unwrap();
    });
    // NaN in the last row: a mid-edge or interior node the runtime never loads.
    let nan_interior = damaged(&basis, "nan_interior.h5", |g| {
        let ds = g.dataset("modes/basis").unwrap();
        let mut v: ndarray::Array2<f64> = ds.read_2d().unwrap();
        let last = v.nrows() - 1;
        v[(last, 0)] = f64::NAN;
        ds.write(&v).unwrap();
    });
    let int_basis = damaged(&basis, "int_basis.h5", |g| {
        let v: ndarray::Array2<f64> = g.dataset("modes/basis").unwrap().read_2d().unwrap();
        g.unlink("modes/basis").unwrap();
        let ints = v.mapv(|x| (x * 1e3) as i32);
        g.new_dataset_builder().with_data(&ints).create("modes/basis").unwrap();
    });
    // A header that claims 4.8 GB (chunked, nothing written).
    let huge = damaged(&basis, "huge.h5", |g| {
        let rows = g.dataset("modes/basis").unwrap().shape()[0];
        g.unlink("modes/basis").unwrap();
        g.new_dataset::<f64>()
            .chunk((rows, 1))
            .shape((rows, 600_000_000 / rows + 1))
            .create("modes/basis")
            .unwrap();
    });
    let _ = dir;
    for (file, why) in [
        (&nan_eigen, "non-finite"),
        (&bad_triangle, "beyond"),
        (&nan_interior, "non-finite"),
        (&int_basis, "the format declares"),
        (&huge, "claims"),
    ] {
        let f = file.to_str().unwrap();
        for args in [vec!["info", f], vec!["bench", f], vec!["info", f, "--json"]] {
            let o = ves(&args);
            let err = stderr(&o);
            assert_eq!(o.status.code(), Some(1), "{args:?} accepted it: {err}");
            assert!(err.contains(f) && err.contains(why), "{args:?}: {err}");
            assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
        }
    }
    let o = ves(&["verify", nan_interior.to_str().unwrap(), "--against", "scikit-fem"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("non-finite"), "{}", stderr(&o));
}

/// A basis path that is a directory was reported as "no such file".
#[test]
fn a_directory_given_as_basis_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let o = ves(&["info", dir.path().to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("is a directory"), "{}", stderr(&o));
}

/// Two disjoint solids, one supported: the free one made K singular and the run failed with
/// "mode N failed its check … try a finer mesh".
#[test]
fn a_separate_body_the_supports_do_not_hold_is_named() {
    let (dir, _) = workdir(GOOD);
    std::fs::write(
        dir.path().join("two.geo"),
        "SetFactory(\"OpenCASCADE\");\nBox(1) = {0, 0, 0, 1000, 100, 50};\nBox(2) = {200, 300, 0, 500, 100, 50};\n",
    )
    .unwrap();
    let scene = write_file(dir.path(), "two.toml", &GOOD.replace("beam.step", "two.geo"));
    let o = ves(&["precompute", scene.to_str().unwrap(), "--allow-geo-scripts"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(
        err.contains("2 separate bodies") && err.contains("not held") && err.contains("[[fixed]]"),
        "{err}"
    );
    assert!(!err.contains("finer mesh"), "{err}");
}

/// A size written in millimetres where metres are meant: gmsh meshed the whole part with a few
/// tets (or failed) without a word. The advice, followed, works.
#[test]
fn a_mesh_size_larger_than_the_part_is_refused_and_the_advice_works() {
    let (dir, scene) = workdir(&GOOD.replace("size = 0.05", "size = 50.0"));
    let o = ves(&["precompute", scene.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(err.contains("larger than the part") && err.contains("metres"), "{err}");
    let advised = number_after(&err, "use about ");
    let fixed = write_file(
        dir.path(),
        "fixed.toml",
        &GOOD.replace("size = 0.05", &format!("size = {advised}")),
    );
    let o = ves(&["precompute", fixed.to_str().unwrap()]);
    assert!(o.status.success(), "following the advice: {}", stderr(&o));
}

/// A directory where a file is expected said "file not found" (geometry) or printed the OS
/// error alone (device script).
#[test]
fn directories_given_as_geometry_or_device_script_say_so() {
    let (dir, _) = workdir(GOOD);
    std::fs::create_dir(dir.path().join("part.step")).unwrap();
    let scene = write_file(dir.path(), "dir.toml", &GOOD.replace("beam.step", "part.step"));
    let o = ves(&["precompute", scene.to_str().unwrap()]);
    assert_refused(&o, "is a directory");
    let (dir, basis) = good_basis();
    let device = format!("script:{}", dir.path().display());
    let o = ves(&["session", basis.to_str().unwrap(), "--device", &device]);
    assert_refused(&o, "is a directory");
}

/// `-o b.xdmf` would have the sidecar overwrite the basis it describes.
#[test]
fn an_output_named_like_its_own_sidecar_is_refused() {
    let (dir, path) = workdir(GOOD);
    let out = dir.path().join("b.xdmf");
    let o = ves(&["precompute", path.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert_refused(&o, "name the output .h5");
    assert!(!out.exists());
}

/// Issue "Nothing lost, nobody in": a FIFO or /dev/zero as geometry said "file not found"; a
/// 2 GB sparse `.step` took 60 s and 4.25 GB of memory before failing. Each is refused at once
/// in one line saying what the file is.
#[test]
fn a_fifo_a_device_or_a_huge_file_as_geometry_is_refused_at_once() {
    let (dir, _) = workdir(GOOD);
    mkfifo(&dir.path().join("pipe.step"));
    std::os::unix::fs::symlink("/dev/zero", dir.path().join("zero.step")).unwrap();
    std::fs::File::create(dir.path().join("big.step"))
        .unwrap()
        .set_len(2 << 30)
        .unwrap();
    for (step, expect) in [
        ("pipe.step", &["pipe.step", "FIFO", "not a regular file"][..]),
        ("/dev/zero", &["/dev/zero", "character device", "not a regular file"]),
        ("zero.step", &["zero.step", "character device", "not a regular file"]),
        ("big.step", &["big.step", "2.00 GiB", "over 1 GiB"]),
    ] {
        let scene = write_file(dir.path(), "s.toml", &GOOD.replace("beam.step", step));
        let out = dir.path().join("out.h5");
        let t = std::time::Instant::now();
        let o = ves(&["precompute", scene.to_str().unwrap(), "-o", out.to_str().unwrap()]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{step}: {err}");
        assert_eq!(err.lines().count(), 1, "{step}: {err}");
        for e in expect {
            assert!(err.contains(e), "{step}: {e:?} not in {err}");
        }
        assert!(t.elapsed().as_secs_f64() < 10.0, "{step}: {:?}", t.elapsed());
        assert!(!out.exists());
    }
}

/// `ves precompute` with `VES_CACHE_DIR=cache` and `TMPDIR=tmp` in `dir`: its output.
fn precompute_in(dir: &Path, scene: &Path, extra: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_ves"))
        .args(["precompute", scene.to_str().unwrap(), "-o"])
        .arg(dir.join("b.h5"))
        .args(["--force", "--json"])
        .args(extra)
        .env("VES_CACHE_DIR", dir.join("cache"))
        .env("TMPDIR", dir.join("tmp"))
        .output()
        .expect("ves runs")
}

fn frequencies(o: &std::process::Output) -> Vec<f64> {
    last_json(o)["spaces"][0]["frequencies_hz"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

/// An edited mesh cache entry (one byte of a coordinate flipped) was used as it was: a wrong
/// basis, exit 0. Now it is a miss, said in one warning line naming it; the part is meshed
/// again (the same frequencies as the first run) and the entry replaced.
#[test]
fn a_damaged_cache_entry_is_a_miss_said_once_and_replaced() {
    let (dir, scene) = workdir(GOOD);
    std::fs::create_dir(dir.path().join("tmp")).unwrap();
    let o = precompute_in(dir.path(), &scene, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let first = frequencies(&o);
    // The fine mesh: the largest entry (the others are the error estimate's coarser meshes).
    let entry = std::fs::read_dir(dir.path().join("cache/meshes"))
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "mesh"))
        .max_by_key(|p| std::fs::metadata(p).unwrap().len())
        .expect("a mesh entry");
    let mut bytes = std::fs::read(&entry).unwrap();
    let at = bytes.len() / 2;
    bytes[at] ^= 0x40;
    std::fs::write(&entry, &bytes).unwrap();
    let o = precompute_in(dir.path(), &scene, &[]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    let name = entry.file_name().unwrap().to_str().unwrap();
    let warned: Vec<&str> = err.lines().filter(|l| l.contains(name)).collect();
    assert_eq!(warned.len(), 1, "{err}");
    assert!(warned[0].contains("damaged mesh cache entry"), "{err}");
    assert_eq!(frequencies(&o), first, "the same mesh, made again");
    assert_ne!(std::fs::read(&entry).unwrap(), bytes, "the entry was not replaced");
    let o = precompute_in(dir.path(), &scene, &[]);
    assert!(!stderr(&o).contains("damaged"), "{}", stderr(&o));
}

/// Processes whose parent is `pid`, from /proc (zombies excluded: they have ended).
fn children_of(pid: u32) -> Vec<u32> {
    let mut found = Vec::new();
    for e in std::fs::read_dir("/proc").unwrap().flatten() {
        let Ok(stat) = std::fs::read_to_string(e.path().join("stat")) else {
            continue;
        };
        // "pid (comm) state ppid …": the command may hold spaces and parentheses.
        let Some((_, rest)) = stat.rsplit_once(')') else {
            continue;
        };
        let fields: Vec<&str> = rest.split_whitespace().collect();
        if fields.len() > 1 && fields[1] == pid.to_string() && fields[0] != "Z" {
            found.push(stat.split_whitespace().next().unwrap().parse().unwrap());
        }
    }
    found
}

fn alive(pid: u32) -> bool {
    std::fs::read_to_string(format!("/proc/{pid}/stat"))
        .ok()
        .and_then(|s| {
            s.rsplit_once(')')
                .map(|(_, r)| r.split_whitespace().next() != Some("Z"))
        })
        .unwrap_or(false)
}

/// A `ves precompute` killed with SIGKILL while gmsh meshed left its `ves mesh-worker` running
/// (up to 40 s, parent 1) and its `ves-mesh-*` directory in $TMPDIR forever. Now the worker
/// dies with it, and the next run removes the directory.
#[test]
fn a_killed_precompute_leaves_no_worker_and_the_next_run_removes_its_directory() {
    let (dir, _) = workdir(GOOD);
    let tmp = dir.path().join("tmp");
    std::fs::create_dir(&tmp).unwrap();
    // A script that keeps gmsh busy far longer than the test waits.
    write_file(
        dir.path(),
        "slow.geo",
        "Sleep 120;\nSetFactory(\"OpenCASCADE\");\nBox(1) = {0, 0, 0, 1, 0.2, 0.2};\n",
    );
    let slow = write_file(dir.path(), "slow.toml", &GOOD.replace("beam.step", "slow.geo"));
    let mut parent = std::process::Command::new(env!("CARGO_BIN_EXE_ves"))
        .args(["precompute", slow.to_str().unwrap(), "--allow-geo-scripts", "-o"])
        .arg(dir.path().join("slow.h5"))
        .env("TMPDIR", &tmp)
        .env("VES_MESH_CACHE", "off")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let pid = parent.id();
    // Until the worker runs gmsh: its phase file (in the job's directory inside the private
    // one) is written after it has read its job. The only run using `tmp`: any name will do.
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    let private = loop {
        let found = std::fs::read_dir(&tmp)
            .unwrap()
            .flatten()
            .find(|e| e.file_name().to_string_lossy().starts_with("ves-mesh-"))
            .map(|e| e.path())
            .filter(|d| d.join("phase").exists() || d.join("rung0/phase").exists());
        if let Some(d) = found {
            break d;
        }
        assert!(std::time::Instant::now() < deadline, "no meshing process started");
        std::thread::sleep(std::time::Duration::from_millis(50));
    };
    let workers = children_of(pid);
    assert_eq!(workers.len(), 1, "{workers:?}");
    unsafe { libc::kill(pid as i32, libc::SIGKILL) };
    parent.wait().unwrap();
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
    while alive(workers[0]) {
        assert!(
            std::time::Instant::now() < deadline,
            "the meshing process {} outlived its parent by 10 s",
            workers[0]
        );
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    assert!(
        private.exists(),
        "a SIGKILL leaves the directory: the next run removes it"
    );
    let (good_dir, good) = workdir(GOOD);
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_ves"))
        .args(["precompute", good.to_str().unwrap(), "-o"])
        .arg(good_dir.path().join("b.h5"))
        .env("TMPDIR", &tmp)
        .env("VES_MESH_CACHE", "off")
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!private.exists(), "{} was left", private.display());
    let left: Vec<_> = std::fs::read_dir(&tmp)
        .unwrap()
        .flatten()
        .map(|e| e.file_name())
        .filter(|n| n.to_string_lossy().starts_with("ves-mesh-"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

/// A closed surface whose faces intersect (a box with one corner pushed through the opposite
/// face): gmsh's "PLC Error: A segment and a facet intersect" at every size. The line said
/// "try mesh.size = half", which fails the same way; now it names the face and the point, says
/// that the faces intersect (the half size was tried and failed too) and what to repair.
#[test]
fn intersecting_faces_are_named_and_no_size_is_advised() {
    let (dir, _) = workdir(GOOD);
    write_file(dir.path(), "self.geo", SELF_INTERSECTING_GEO);
    let scene = write_file(
        dir.path(),
        "self.toml",
        &GOOD
            .replace("beam.step", "self.geo")
            .replace("size = 0.05", "size = 0.00025"),
    );
    let o = ves(&["precompute", scene.to_str().unwrap(), "--allow-geo-scripts"]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    for e in [
        "self.geo",
        "crosses itself on CAD face",
        "near (0.000",
        "segment and a facet intersect",
        "half and a quarter of the mesh size fail too",
        "repair those faces in CAD",
        "defeature",
    ] {
        assert!(err.contains(e), "{e:?} not in {err}");
    }
    assert!(!err.contains("try mesh.size"), "{err}");
}

/// The unit box (mm) in triangles, corner (1, 1, 1) moved to (0.7, 0.7, −0.5): through the
/// bottom face. gmsh's boundary recovery fails on it at any element size (tried 2…0.0625 mm).
const SELF_INTERSECTING_GEO: &str = "\
Point(1) = {0, 0, 0, 0.5}; Point(2) = {1, 0, 0, 0.5}; Point(3) = {1, 1, 0, 0.5};
Point(4) = {0, 1, 0, 0.5}; Point(5) = {0, 0, 1, 0.5}; Point(6) = {1, 0, 1, 0.5};
Point(7) = {0.7, 0.7, -0.5, 0.5}; Point(8) = {0, 1, 1, 0.5};
Line(1) = {1, 4}; Line(2) = {4, 3}; Line(3) = {3, 1}; Line(4) = {3, 2}; Line(5) = {2, 1};
Line(6) = {5, 6}; Line(7) = {6, 7}; Line(8) = {7, 5}; Line(9) = {7, 8}; Line(10) = {8, 5};
Line(11) = {2, 6}; Line(12) = {6, 1}; Line(13) = {5, 1}; Line(14) = {3, 7}; Line(15) = {7, 2};
Line(16) = {4, 8}; Line(17) = {8, 3}; Line(18) = {5, 4};
Curve Loop(1) = {1, 2, 3}; Curve Loop(2) = {-3, 4, 5}; Curve Loop(3) = {6, 7, 8};
Curve Loop(4) = {-8, 9, 10}; Curve Loop(5) = {-5, 11, 12}; Curve Loop(6) = {-12, -6, 13};
Curve Loop(7) = {-4, 14, 15}; Curve Loop(8) = {-15, -7, -11}; Curve Loop(9) = {-2, 16, 17};
Curve Loop(10) = {-17, -9, -14}; Curve Loop(11) = {-1, -13, 18}; Curve Loop(12) = {-18, -10, -16};
For s In {1:12}
  Plane Surface(s) = {s};
EndFor
Surface Loop(1) = {1:12};
Volume(1) = {1};
";

/// The root cause of the `unable to lock file, errno = 11` failures of full test runs: libhdf5
/// locks every file it opens, without close-on-exec, so a child process started by any thread
/// while a file is open to write keeps its exclusive lock after the writer closed it (here the
/// test's own writer and a `sleep` in place of another test's `ves` run). A basis is renamed
/// into place whole, so `ves` reads without the lock.
#[test]
fn a_basis_whose_lock_a_child_inherited_still_reads() {
    let (_dir, basis) = good_basis();
    let copy = basis.with_file_name("locked.h5");
    std::fs::copy(&basis, &copy).unwrap();
    let writer = hdf5::File::open_rw(&copy).unwrap();
    let mut child = std::process::Command::new("sleep").arg("60").spawn().unwrap();
    writer.close().unwrap();
    let o = ves(&["info", copy.to_str().unwrap()]);
    let _ = child.kill();
    let _ = child.wait();
    assert!(o.status.success(), "{}", stderr(&o));
}

/// A mesh whose factorisation does not fit in memory ended in `memory allocation of … bytes
/// failed` and SIGABRT (exit 134), the page's server with it. Now it is refused before the
/// factor is allocated, in one line naming a mesh size that fits — and that size does fit.
/// `VES_MAX_MEMORY` stands in for a small machine (the headroom is the least of it, the
/// system's available memory, the cgroup's and `ulimit -v`).
#[test]
fn a_factor_beyond_memory_is_refused_with_a_size_that_fits() {
    let scene = GOOD
        .replace("size = 0.05", "size = 0.012")
        .replace("order = 1", "order = 2");
    let (dir, path) = workdir(&scene);
    let out = dir.path().join("out.h5");
    std::fs::write(&out, b"previous result").unwrap();
    let run = |scene: &Path| {
        std::process::Command::new(env!("CARGO_BIN_EXE_ves"))
            .args([
                "precompute",
                scene.to_str().unwrap(),
                "-o",
                out.to_str().unwrap(),
                "--force",
            ])
            .env("VES_MAX_MEMORY", "300M")
            .output()
            .unwrap()
    };
    let o = run(&path);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("sparse factor") && err.contains("GB available"), "{err}");
    assert_eq!(std::fs::read(&out).unwrap(), b"previous result", "output overwritten");
    let advised = number_after(&err, "set mesh.size = ");
    assert!(advised > 0.012, "{err}");
    let coarser = write_file(
        dir.path(),
        "coarser.toml",
        &scene.replace("size = 0.012", &format!("size = {advised}")),
    );
    let o = run(&coarser);
    assert!(
        o.status.success(),
        "the advised mesh.size = {advised} does not fit: {}",
        stderr(&o)
    );
    for bad in ["12Q", "-1G", "lots", ""] {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_ves"))
            .args(["info", out.to_str().unwrap()])
            .env("VES_MAX_MEMORY", bad)
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(1), "VES_MAX_MEMORY={bad:?}: {}", stderr(&o));
        assert!(stderr(&o).contains("VES_MAX_MEMORY"), "{}", stderr(&o));
    }
}
