//! The `ves` binary end to end: a good run, and bad input that must give one clear line, a
//! non-zero exit and no output file (an existing one left untouched).

mod common;

use common::*;
use std::path::Path;
use std::process::{Command, Output};

#[test]
fn good_scene_writes_a_basis_and_json_summary() {
    let (dir, path) = workdir(GOOD);
    let out = dir.path().join("beam.h5");
    let o = ves(&[
        "precompute",
        path.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v = last_json(&o);
    assert_eq!(v["output"], out.to_str().unwrap());
    let space = &v["spaces"][0];
    assert_eq!(space["name"], "global");
    assert_eq!(space["frequencies_hz"].as_array().map(|a| a.len()), Some(4));
    assert!(space["max_relative_residual"].as_f64().unwrap() <= 1e-8);
    // The Sturm count: exactly the 4 modes found lie below σ (none skipped).
    let sturm = &space["sturm_count"];
    assert_eq!(
        (sturm["below"].as_u64(), sturm["found"].as_u64()),
        (Some(4), Some(4)),
        "{sturm}"
    );
    let q = space["min_tet_quality"].as_f64().unwrap();
    assert!(q > 0.01 && q <= 1.0, "worst tet quality {q}");
    for key in ["nodes", "tets", "dofs"] {
        assert!(space[key].as_u64().unwrap() > 0);
    }
    for key in ["mesh", "assemble", "factorize", "eigensolve", "write", "total"] {
        assert!(v["timings_s"][key].as_f64().is_some(), "timing {key}");
    }
    // The summary's peak resident memory: at least what the basis written occupies.
    let rss = v["peak_rss_bytes"].as_u64().expect("peak_rss_bytes");
    let file = std::fs::metadata(&out).expect("basis").len();
    assert!(rss > file && rss < 24 << 30, "peak RSS {rss} B for a {file}-byte basis");
    assert_eq!(space["meshing"]["strategy"], "default", "{space}");
    // 4-node tets on a beam in bending: the estimate says how far off, the warning what to do.
    let errors = space["estimated_relative_error"].as_array().expect("estimate");
    assert_eq!(errors.len(), 4);
    assert!(
        errors.iter().all(|e| e.as_f64().is_some_and(|e| e > 0.05)),
        "{errors:?}"
    );
    let err = stderr(&o);
    assert_eq!(err.matches("use mesh.order = 2").count(), 1, "{err}");
    // 50 mm tets in a 50 mm-thick beam: one element through it, which the estimate cannot see.
    assert_eq!(err.matches("walls one element thick").count(), 1, "{err}");
    let modes = space["error_estimate"]["modes"].as_array().expect("modes");
    assert!(modes.iter().all(|m| m["reliable"] == false), "{modes:?}");
    // Walls one element thick stay so on every coarser mesh: the Richardson estimate could not
    // be taken, so the coarser meshes are not solved and every number is the recovery one.
    let e = &space["error_estimate"];
    assert_eq!(e["coarser_meshes"], "thin_walls", "{e}");
    assert_eq!(e["levels"].as_array().map(Vec::len), Some(0), "{e}");
    assert!(modes.iter().all(|m| m["rule"] == "recovery"), "{modes:?}");

    let o = ves(&["info", out.to_str().unwrap(), "--json"]);
    assert!(o.status.success());
    let info: serde_json::Value = serde_json::from_slice(&o.stdout).expect("info JSON");
    assert_eq!(info["spaces"][0]["frequencies_hz"], space["frequencies_hz"]);
    assert_eq!(info["spaces"][0]["nodes"], space["nodes"]);
    assert_eq!(info["spaces"][0]["meshing_strategy"], "default");

    // The STEP file is in millimetres: a scene saying metres is told once that its unit is
    // ignored, and the result is the same part.
    assert!(!stderr(&o).contains("is ignored"));
    let metres = write_file(dir.path(), "m.toml", &GOOD.replace("unit = \"mm\"", "unit = \"m\""));
    let out_m = dir.path().join("m.h5");
    let o = ves(&[
        "precompute",
        metres.to_str().unwrap(),
        "-o",
        out_m.to_str().unwrap(),
        "--json",
    ]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert_eq!(err.matches("is ignored").count(), 1, "{err}");
    assert!(
        err.contains("geometry.unit = \"m\"") && err.contains("(millimetre)"),
        "{err}"
    );
    let f = |v: &serde_json::Value| -> Vec<f64> {
        v["spaces"][0]["frequencies_hz"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    for (a, b) in f(&last_json(&o)).iter().zip(f(&v)) {
        assert!((a - b).abs() <= 1e-9 * b, "{a} vs {b}");
    }
}

#[test]
fn missing_scene_file() {
    let o = ves(&["precompute", "/nonexistent/scene.toml"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("/nonexistent/scene.toml"));
}

#[test]
fn unknown_key_is_an_error() {
    fails(
        &GOOD.replace("young = 2.1e11", "young = 2.1e11\nyoungs = 1.0"),
        &["scene.toml", "youngs"],
    );
}

#[test]
fn poisson_of_one_half_is_refused() {
    fails(
        &GOOD.replace("poisson = 0.3", "poisson = 0.5"),
        &["material.poisson", "0.5"],
    );
}

#[test]
fn zero_and_negative_young_are_refused() {
    fails(&GOOD.replace("young = 2.1e11", "young = 0.0"), &["material.young"]);
    fails(&GOOD.replace("young = 2.1e11", "young = -2.1e11"), &["material.young"]);
}

#[test]
fn wrong_type_is_an_error() {
    fails(&GOOD.replace("count = 4", "count = \"four\""), &["scene.toml", "count"]);
}

#[test]
fn support_that_selects_no_node() {
    fails(
        &GOOD.replace("value = 0.0", "value = 5.0"),
        &["fixed[0]", "selects no node", "x from"],
    );
}

#[test]
fn missing_geometry_file() {
    fails(
        &GOOD.replace("beam.step", "nothere.step"),
        &["geometry.step", "nothere.step"],
    );
}

#[test]
fn broken_step_file() {
    let (dir, path) = workdir(&GOOD.replace("beam.step", "broken.step"));
    std::fs::write(
        dir.path().join("broken.step"),
        "ISO-10303-21;\nHEADER;\nthis is not a STEP file\n",
    )
    .unwrap();
    let out = dir.path().join("out.h5");
    let o = ves(&["precompute", path.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    let err = stderr(&o);
    assert!(!o.status.success());
    assert_eq!(err.lines().filter(|l| !l.trim().is_empty()).count(), 1, "{err}");
    assert!(err.contains("broken.step"), "{err}");
    // It is not a file of surfaces: say what it is.
    assert!(!err.contains("surfaces"), "{err}");
    assert!(!out.exists());
}

#[test]
fn info_refuses_foreign_and_truncated_files() {
    let dir = tempfile::tempdir().unwrap();
    let text = dir.path().join("notes.h5");
    std::fs::write(&text, "not hdf5").unwrap();
    let o = ves(&["info", text.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("not a readable HDF5 file"));

    let foreign = dir.path().join("foreign.h5");
    ves_format::file::create(&foreign, false)
        .unwrap()
        .create_group("data")
        .unwrap();
    let o = ves(&["info", foreign.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("not a VES modal basis"));

    let (wd, path) = workdir(GOOD);
    let good = wd.path().join("beam.h5");
    assert!(
        ves(&["precompute", path.to_str().unwrap(), "-o", good.to_str().unwrap()])
            .status
            .success()
    );
    let bytes = std::fs::read(&good).unwrap();
    let cut = dir.path().join("cut.h5");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let o = ves(&["info", cut.to_str().unwrap()]);
    assert!(!o.status.success(), "a truncated file must not read as a basis");
    assert_eq!(stderr(&o).lines().count(), 1);
}

#[test]
fn session_and_bench_report_json() {
    let (dir, basis) = good_basis();
    let script = dir.path().join("hand.csv");
    std::fs::write(&script, "t,x,y,z,button\n0,1.0,0.05,0.05,1\n0.2,1.0,0.05,0.045,1\n").unwrap();
    let v = session_json(&basis, &script);
    assert_eq!(v["steps"], 200);
    // Real-time hygiene: each measure either granted or refused with a reason, never silent.
    let rt = &v["realtime"];
    for (granted, what) in [(&rt["sched_fifo"], "SCHED_FIFO"), (&rt["memory_locked"], "mlockall")] {
        let refused = rt["refused"].as_array().expect("refused list");
        assert!(
            granted.as_bool() == Some(true) || refused.iter().any(|m| m.as_str().is_some_and(|m| m.starts_with(what))),
            "{rt}"
        );
    }
    let plain = session_json_with(&basis, &script, &["--no-realtime"]);
    assert!(plain["realtime"].is_null(), "--no-realtime: {plain}");
    for key in [
        "achieved_rate_hz",
        "step_ns_median",
        "step_ns_p99",
        "step_ns_max",
        "missed_deadlines",
        "visual_rate_hz",
        "peak_force_n",
        "max_energy_j",
        "bytes_loaded",
    ] {
        assert!(v[key].is_number(), "{key} missing: {v}");
    }
    assert!(v["peak_force_n"].as_f64().unwrap() > 0.0);

    let o = ves(&["bench", basis.to_str().unwrap(), "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("bench JSON");
    // Only 4 modes in this basis: r = 30 and 100 cannot be measured, the 4 it has are.
    for key in [
        "haptic_step_ns_median_r4",
        "haptic_press_step_ns_median_r4",
        "full_field_ms_median",
        "bytes_loaded",
    ] {
        assert!(v[key].as_f64().is_some_and(|x| x > 0.0), "{key} missing: {v}");
    }
    assert!(v.get("haptic_step_ns_median_r30").is_none(), "{v}");
    assert!(v["full_field_ms_median"].as_f64().unwrap() > 0.0);
    // No modal stress in this basis: its stress timings are null, not a made-up number.
    assert!(
        v["full_field_stress_ms_median"].is_null() && v["von_mises_ms_median"].is_null(),
        "{v}"
    );

    let bad = ves(&[
        "session",
        basis.to_str().unwrap(),
        "--device",
        "script:/nonexistent.csv",
    ]);
    assert!(!bad.status.success());
    assert!(stderr(&bad).contains("/nonexistent.csv"));
}

/// A hand that grabs 0.46 mm from the beam's tip corner and moves 1 mm further along the
/// beam's axis (where the beam barely gives: 4 bending modes, L/EA ~ 1e-9 m/N) feels
/// k · 1 mm = 0.5 N on the 500 N/m coupling, not k · 1.46 mm = 0.73 N; the JSON names the vertex,
/// the gap and how the vertex moved, and `--trace` has one row per step with the same numbers.
#[test]
fn a_session_says_what_each_hand_held_and_traces_it() {
    let (dir, basis) = good_basis();
    let script = dir.path().join("hand.csv");
    let (x0, y, z) = (1.0 + 0.46e-3, 0.1, 0.05);
    std::fs::write(
        &script,
        format!(
            "t,x,y,z,button\n0,{x0},{y},{z},1\n0.1,{},{y},{z},1\n0.4,{},{y},{z},1\n",
            x0 + 1e-3,
            x0 + 1e-3
        ),
    )
    .unwrap();
    let trace = dir.path().join("trace.csv");
    let v = session_json_with(&basis, &script, &["--trace", trace.to_str().unwrap(), "--no-realtime"]);
    let hand = &v["hands"][0];
    assert!((hand["grip_gap_m"].as_f64().unwrap() - 0.46e-3).abs() < 1e-9, "{hand}");
    let p = hand["first_vertex_position"].as_array().expect("position");
    assert!((p[0].as_f64().unwrap() - 1.0).abs() < 1e-9, "the tip corner: {hand}");
    let f = v["final_forces_n"][0].as_array().expect("force");
    let magnitude = f.iter().map(|c| c.as_f64().unwrap().powi(2)).sum::<f64>().sqrt();
    assert!(
        (magnitude - 0.5).abs() < 0.005,
        "{magnitude} N: the initial gap is pulled?"
    );
    let text = std::fs::read_to_string(&trace).expect("the trace");
    let rows: Vec<Vec<f64>> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|c| c.parse().expect("a number")).collect())
        .collect();
    assert!(text.starts_with("t_s,hand,x_m,"), "{}", &text[..80]);
    assert_eq!(rows.len() as u64, v["steps"].as_u64().unwrap());
    let last = rows.last().unwrap();
    assert_eq!(last[6], hand["last_vertex"].as_f64().unwrap());
    for c in 0..3 {
        assert_eq!(last[7 + c], hand["last_displacement_m"][c].as_f64().unwrap());
        assert_eq!(last[10 + c], f[c].as_f64().unwrap());
    }
}

#[test]
fn verify_against_scikit_fem_and_calculix_passes_and_tolerances_bite() {
    // 10-node tets so both references run their quadratic elements; small mesh.
    let (dir, path) = workdir(
        &GOOD
            .replace("order = 1", "order = 2")
            .replace("size = 0.05", "size = 0.06"),
    );
    let o = ves(&[
        "verify",
        path.to_str().unwrap(),
        "--against",
        "all",
        "--stress",
        "--json",
    ]);
    let err = stderr(&o);
    assert!(o.status.success(), "verify failed: {err}");
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("verify JSON");
    let refs = v["references"].as_array().expect("references");
    // scikit-fem and CalculiX always; FEniCSx too where it is installed.
    let find = |name: &str| {
        refs.iter()
            .find(|r| r["solver"].as_str().is_some_and(|s| s.contains(name)))
            .expect(name)
    };
    // Where FEniCSx is missing, `all` says so rather than leaving it out without a word.
    let with_fenicsx = refs
        .iter()
        .any(|r| r["solver"].as_str().is_some_and(|s| s.contains("FEniCSx")));
    assert_eq!(!with_fenicsx, err.contains("FEniCSx is not installed"), "{err}");
    // ... and lists it in the report, with how to install it.
    let skipped = v["skipped"].as_array().expect("skipped");
    assert_eq!(
        !with_fenicsx,
        skipped.iter().any(|s| s["solver"] == "FEniCSx"
            && s["reason"]
                .as_str()
                .is_some_and(|r| r.contains("apt-get install python3-dolfinx"))),
        "{skipped:?}"
    );
    // The progress lines (solver, size, expected time) are for a terminal only.
    assert!(!err.contains("unknowns, expected about"), "{err}");
    let skfem = find("scikit-fem");
    assert!(skfem["max_rel_freq_diff"].as_f64().unwrap() < 1e-6);
    assert!(skfem["min_mac_isolated"].as_f64().unwrap() > 0.999);
    assert!(skfem["static_rel_diff"].as_f64().unwrap() < 1e-6);
    let ccx = find("CalculiX");
    assert!(ccx["max_rel_freq_diff"].as_f64().unwrap() < 1e-3);
    assert!(ccx["static_rel_diff"].as_f64().unwrap() < 1e-5);
    // Nodal stress of CalculiX's own mode shapes: our recovery with its averaging is the same
    // field (measured 2e-5…2e-3 on the cantilever); the volume-weighted one a basis stores
    // differs by the averaging alone, a few percent on this coarse mesh.
    assert!(ccx["max_stress_rel_diff"].as_f64().unwrap() < 1e-2, "{ccx}");
    for m in ccx["modes"].as_array().unwrap() {
        let vw = m["stress_rel_diff_volume_weighted"].as_f64().unwrap();
        assert!(vw > 0.0 && vw < 0.1, "{m}");
    }
    assert!(skfem.get("max_stress_rel_diff").is_none(), "{skfem}");
    let o = ves(&["verify", path.to_str().unwrap(), "--against", "scikit-fem", "--stress"]);
    assert_refused(&o, "--against calculix");
    // An impossible tolerance must fail with exit status 2.
    let o = ves(&[
        "verify",
        path.to_str().unwrap(),
        "--against",
        "calculix",
        "--tol-freq",
        "1e-12",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let o = ves(&[
        "verify",
        path.to_str().unwrap(),
        "--against",
        "calculix",
        "--stress",
        "--tol-stress",
        "1e-9",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    drop(dir);
}

/// Malformed scene values: each must be one line naming the key, exit 1, output untouched.
#[test]
fn malformed_scene_values_are_refused_one_by_one() {
    let cases: &[(&str, &str, &[&str])] = &[
        ("young = 2.1e11", "young = nan", &["material.young"]),
        ("young = 2.1e11", "young = inf", &["material.young"]),
        ("density = 7850.0", "density = -1.0", &["material.density"]),
        ("poisson = 0.3", "poisson = -1.0", &["material.poisson"]),
        ("poisson = 0.3", "poisson = 0.7", &["material.poisson"]),
        ("order = 1", "order = 3", &["mesh.order"]),
        ("size = 0.05", "size = 0.0", &["mesh.size"]),
        ("size = 0.05", "size = -0.05", &["mesh.size"]),
        ("count = 4", "count = 0", &["modes.count"]),
        ("count = 4", "count = 1000000000", &["modes.count"]),
        ("count = 4", "count = -3", &["count"]),
        ("axis = \"x\"", "axis = \"w\"", &["fixed[0].plane.axis"]),
        ("[[fixed]]", "[[fixed]]\ncomponents = []", &["fixed[0].components"]),
        ("[[fixed]]", "[[fixed]]\ncomponents = [\"q\"]", &["fixed[0].components"]),
        (
            "plane = { axis = \"x\", value = 0.0 }",
            "box = { min = [1.0, 0.0, 0.0], max = [0.0, 1.0, 1.0] }",
            &["fixed[0].box"],
        ),
        (
            "plane = { axis = \"x\", value = 0.0 }",
            "",
            &["fixed[0]", "plane", "box"],
        ),
        ("unit = \"mm\"", "unit = \"inch\"", &["unit"]),
        ("size = 0.05\n", "", &["mesh.size missing", "target_error = 0.01"]),
        (
            "size = 0.05",
            "target_error = 2.0",
            &["mesh.target_error = 2", "1e-4 and 0.5"],
        ),
        (
            "size = 0.05",
            "target_error = 0.01\nerror_estimate = false",
            &["target_error", "error_estimate = false"],
        ),
        ("size = 0.05", "size = 0.05\nmax_dofs = 3", &["mesh.max_dofs = 3"]),
        (
            "size = 0.05",
            "size = 0.05\nerror_estimate = \"fast\"",
            &["error_estimate", "\"fast\"", "\"full\""],
        ),
        (
            "[material]",
            "[material]\nyield_strength = -1.0",
            &["material.yield_strength"],
        ),
        ("[modes]", "[stress]\nenabled = \"yes\"\n[modes]", &["enabled"]),
        ("[modes]", "[stress]\nenable = true\n[modes]", &["enable"]),
        ("beam.step", "beam.stl", &["geometry.step", "unsupported"]),
        ("[modes]", "[damping]\nbeta = -1.0\n[modes]", &["damping.beta"]),
        (
            "[modes]",
            "[[voi]]\nname = \"global\"\nbox = { min = [0.0, 0.0, 0.0], max = [0.1, 0.1, 0.1] }\nsize = 0.01\n[modes]",
            &["voi[0].name"],
        ),
        (
            "[modes]",
            "[[voi]]\nname = \"a\"\nbox = { min = [0.0, 0.0, 0.0], max = [0.1, 0.1, 0.1] }\nsize = 0.0\n[modes]",
            &["voi[0].size"],
        ),
        (
            "[modes]",
            "[static_correction]\nregion = \"everywhere\"\n[modes]",
            &["region"],
        ),
        ("[material]", "[material]\ncolour = \"red\"", &["colour"]),
        ("name = \"beam\"", "name = \"beam\"\nname = \"twice\"", &["name"]),
        (
            "[modes]",
            "[[probe]]\nat = [1.0, 0.0, 0.0]\nforce = [0.0, 0.0, 0.0]\n[modes]",
            &["probe[0]", "force"],
        ),
        (
            "[modes]",
            "[[probe]]\nat = [1.0, nan, 0.0]\nforce = [0.0, 0.0, 1.0]\n[modes]",
            &["probe[0]"],
        ),
        (
            "[modes]",
            "[[probe]]\nat = [1.0, 0.0]\nforce = [0.0, 0.0, 1.0]\n[modes]",
            &["at"],
        ),
    ];
    for (from, to, expect) in cases {
        assert!(GOOD.contains(from), "test case does not apply: {from}");
        fails(&GOOD.replacen(from, to, 1), expect);
    }
}

#[test]
fn garbage_and_empty_scene_files_are_refused() {
    fails("", &["scene.toml"]);
    fails("\u{0}\u{1}\u{2}binary", &["scene.toml"]);
    fails("[geometry\nstep = ", &["scene.toml"]);
}

#[test]
fn output_into_a_missing_directory_is_refused_before_work() {
    let (_dir, path) = workdir(GOOD);
    let o = ves(&["precompute", path.to_str().unwrap(), "-o", "/nonexistent/dir/out.h5"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("/nonexistent/dir"));
}

#[test]
fn basis_of_a_newer_version_or_missing_pieces_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    // A file that claims to be a basis of `version` and holds nothing else.
    let header_only = |name: &str, version: u32| {
        let path = dir.path().join(name);
        let f = ves_format::file::create(&path, false).unwrap();
        let v: hdf5::types::VarLenUnicode = "ves-modal-basis".parse().unwrap();
        f.new_attr::<hdf5::types::VarLenUnicode>()
            .create("format")
            .unwrap()
            .write_scalar(&v)
            .unwrap();
        f.new_attr::<u32>()
            .create("version")
            .unwrap()
            .write_scalar(&version)
            .unwrap();
        path
    };
    let newer = header_only("newer.h5", 2);
    let o = ves(&["info", newer.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("newer"));
    let hollow = header_only("hollow.h5", 1);
    for cmd in ["info", "bench"] {
        let o = ves(&[cmd, hollow.to_str().unwrap()]);
        assert!(!o.status.success(), "{cmd} accepted a hollow file");
        assert!(stderr(&o).contains("hollow.h5"), "{cmd}: {}", stderr(&o));
    }
}

#[test]
fn bad_device_scripts_and_session_settings_are_refused() {
    let (dir, basis) = good_basis();
    let b = basis.to_str().unwrap();
    for (name, text, expect) in [
        ("nan.csv", "0,0,0,nan\n", "line 1"),
        ("back.csv", "0,0,0,0\n0,1,1,1\n", "does not increase"),
        ("short.csv", "0,0,0\n", "4 or 5"),
        ("empty.csv", "", "no trajectory"),
    ] {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        let o = ves(&["session", b, "--device", &format!("script:{}", p.display())]);
        let err = stderr(&o);
        assert!(
            !o.status.success() && err.contains(name) && err.contains(expect),
            "{name}: {err}"
        );
    }
    let ok = dir.path().join("ok.csv");
    std::fs::write(&ok, "0,1,0.05,0.05\n").unwrap();
    let dev = format!("script:{}", ok.display());
    let o = ves(&["session", b, "--device", &dev, "--rate", "50000"]);
    assert!(!o.status.success() && stderr(&o).contains("--rate"));
    let o = ves(&["session", b, "--device", "mouse:0"]);
    assert!(!o.status.success() && stderr(&o).contains("script:"));
}

/// A small `ves report` (CI): every output is written, the static correction makes the probe
/// response exact, errors fall with the number of modes, 4-node tets lock where 10-node do not.
/// A second probe sits inside the beam, halfway between its top and bottom faces: each mesh snaps
/// it to a vertex half the thickness away (on either face), so it is flagged and left out of the
/// "vs finest" columns, while the first (on the tip's top edge) is not.
#[test]
fn report_sweeps_meshes_and_modes_and_writes_plots() {
    let scene = GOOD.replace(
        "count = 4",
        "count = 4\n[damping]\nbeta = 1.0e-5\n[[probe]]\nat = [1.0, 0.05, 0.05]\nforce = [0.0, 0.0, -1.0]\n\
         [[probe]]\nat = [0.5, 0.05, 0.025]\nforce = [0.0, 0.0, -1.0]",
    );
    let (dir, path) = workdir(&scene);
    let out = dir.path().join("report");
    let o = ves(&[
        "report",
        path.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--modes",
        "4,12",
        "--sizes",
        "0.06,0.04",
        "--orders",
        "1,2",
        "--duration",
        "0.1",
        "--json",
    ]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    for f in [
        "report.md",
        "report.json",
        "error_vs_online.png",
        "error_vs_offline.png",
        "error_vs_online.svg",
        "error_vs_offline.svg",
    ] {
        let bytes = std::fs::read(out.join(f)).unwrap_or_else(|e| panic!("{f}: {e}"));
        assert!(bytes.len() > 1000, "{f} is too small");
        if f.ends_with(".png") {
            assert_eq!(&bytes[1..4], b"PNG", "{f}");
        }
    }
    let r = last_json(&o);
    let meshes = r["meshes"].as_array().expect("meshes");
    assert_eq!(meshes.len(), 4);
    let reference = &meshes[r["reference_mesh"].as_u64().expect("reference") as usize];
    assert_eq!(
        (reference["order"].as_u64(), reference["size"].as_f64()),
        (Some(2), Some(0.04))
    );
    let f1 = |m: &serde_json::Value| m["frequencies_hz"][0].as_f64().expect("f1");
    for m in meshes {
        let points = m["points"].as_array().expect("points");
        assert_eq!(points.len(), 2, "two mode counts per mesh");
        let err = |p: &serde_json::Value, k: &str| p[k][0].as_f64().expect(k);
        for p in points {
            assert!(err(p, "static_error_corrected") < 1e-9, "correction must be exact: {p}");
            assert!(
                err(p, "dynamic_error_corrected") <= err(p, "dynamic_error") + 1e-12,
                "{p}"
            );
            assert!(p["haptic_step_ns"].as_f64().expect("ns") > 0.0);
            assert!(p["file_bytes"].as_u64().expect("bytes") > 0);
        }
        // More modes, smaller truncation error.
        assert!(err(&points[1], "static_error") < err(&points[0], "static_error"), "{m}");
        assert!(
            err(&points[1], "dynamic_error") < err(&points[0], "dynamic_error"),
            "{m}"
        );
        let e = m["probes"][0]["exact_displacement"].as_f64().expect("u");
        assert!(e.is_finite() && e > 0.0);
    }
    // Shear locking of 4-node tets in bending: their f1 is far above the 10-node one.
    let (p1, p2) = (&meshes[1], &meshes[3]);
    assert!(f1(p1) > 1.2 * f1(p2), "P1 {} vs P2 {}", f1(p1), f1(p2));
    assert!(meshes[2]["points"][0]["frequency_error"].as_f64().expect("freq err") < 0.01);
    assert!(reference["points"][0]["frequency_error"].is_null());
    // The estimate a basis of each mesh would carry, checked against the reference mesh: both
    // large for the locking 4-node tets, both small for the 10-node ones.
    let worst = |m: &serde_json::Value, k: &str| {
        m[k].as_array()
            .unwrap_or_else(|| panic!("{k}: {m}"))
            .iter()
            .filter_map(|x| x.as_f64())
            .fold(0.0, f64::max)
    };
    for m in &meshes[..2] {
        let (e, t) = (
            worst(m, "estimated_relative_error"),
            worst(m, "measured_relative_error"),
        );
        assert!(e > 0.05 && t > 0.05, "order 1: estimated {e}, measured {t}");
    }
    let (e, t) = (
        worst(&meshes[2], "estimated_relative_error"),
        worst(&meshes[2], "measured_relative_error"),
    );
    // Measured e / t = 0.95 (2.87 % against 3.01 %, both mode 10, torsion). The bound leaves
    // 1.36× below and 1.42× above it, and an estimate off by 2× either way (1.91 or 0.48) fails.
    // The measured error is against the 0.04 m mesh, itself 1.3 % off on that mode
    // (cases/cantilever/converged.json): against the converged frequency the estimate is 0.66×
    // the true error. So the bound pins what the estimate says of this pair of meshes; it is
    // not a check against the truth.
    assert!(
        e < 0.05 && t < 0.05 && (0.7..=1.35).contains(&(e / t)),
        "order 2: estimated {e}, measured {t}"
    );
    let md = std::fs::read_to_string(out.join("report.md")).expect("report.md");
    assert!(md.contains("the estimate against the measured"), "{md}");
    // The probe inside the beam is flagged and left out of "vs finest"; the tip probe is not.
    let checks = r["probe_checks"].as_array().expect("probe_checks");
    assert_eq!(checks.len(), 2);
    assert_eq!(checks[0]["flagged"].as_bool(), Some(false), "{}", checks[0]);
    assert_eq!(checks[1]["flagged"].as_bool(), Some(true), "{}", checks[1]);
    assert!(checks[1]["worst_snap_over_size"].as_f64().expect("ratio") > 0.5);
    assert!(md.contains("| ⚠ 2 |") && md.contains("leave out probe 2"), "{md}");
    let first_vs_finest = meshes[0]["points"][0]["static_error_total_corrected"][0]
        .as_f64()
        .expect("vs finest");
    assert!(
        md.contains(&format!("{:.3} |", 100.0 * first_vs_finest)),
        "the \"vs finest, corrected\" cell is probe 1's: {first_vs_finest}\n{md}"
    );
    // The corrected static error on its own mesh is exact by construction: said so, not a number.
    assert_eq!(r["exact_below"].as_f64(), Some(1e-12));
    assert!(md.contains("| exact |"), "{md}");
    // Timings carry their noise band and tier; the fastest point is in tier 1.
    let points: Vec<&serde_json::Value> = meshes
        .iter()
        .flat_map(|m| m["points"].as_array().expect("points"))
        .collect();
    for p in &points {
        let (lo, mid, hi) = (
            p["haptic_step_ns_p25"].as_f64().expect("p25"),
            p["haptic_step_ns"].as_f64().expect("median"),
            p["haptic_step_ns_p75"].as_f64().expect("p75"),
        );
        assert!(lo <= mid && mid <= hi, "{p}");
        assert!(p["haptic_step_tier"].as_u64().expect("tier") >= 1, "{p}");
    }
    let fastest = points
        .iter()
        .min_by(|a, b| {
            a["haptic_step_ns"]
                .as_f64()
                .unwrap_or(0.0)
                .total_cmp(&b["haptic_step_ns"].as_f64().unwrap_or(0.0))
        })
        .expect("a point");
    assert_eq!(fastest["haptic_step_tier"].as_u64(), Some(1));
    assert!(md.contains("step tier"), "{md}");
    // Nothing temporary left behind.
    let left: Vec<_> = std::fs::read_dir(&out)
        .expect("dir")
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.') || n.ends_with(".tmp"))
        .collect();
    assert!(left.is_empty(), "left behind: {left:?}");
}

/// `ves report` on a scene meshed to `target_error` (no `mesh.size`) said "--sizes [0.0, 0.0,
/// 0.0]: give element sizes > 0" where no sizes had been given. Without --sizes it now sweeps the
/// size the refinement starts from (1/15 of the beam's 1 m length) and two finer steps, and says so.
#[test]
fn report_without_sizes_on_a_target_error_scene_sweeps_the_refinements_sizes() {
    let (dir, scene) = workdir(&GOOD.replace("size = 0.05", "target_error = 0.05"));
    let out = dir.path().join("report");
    let o = ves(&[
        "report",
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--modes",
        "4",
        "--orders",
        "1",
        "--duration",
        "0.05",
        "--json",
    ]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("target_error") && err.contains("1/15") && err.contains("--sizes"),
        "{err}"
    );
    let r = last_json(&o);
    let sizes: Vec<f64> = r["sizes"]
        .as_array()
        .expect("sizes")
        .iter()
        .filter_map(|x| x.as_f64())
        .collect();
    let start = 1.0 / 15.0;
    assert_eq!(sizes.len(), 3, "{sizes:?}");
    for (h, want) in sizes.iter().zip([start, start / 1.5, start / 2.0]) {
        assert!((h / want - 1.0).abs() < 1e-6, "{sizes:?}");
    }
    assert!(r["sizes_from"].as_str().is_some_and(|s| s.contains("target_error")));
    assert_eq!(r["meshes"].as_array().map(Vec::len), Some(3));
    let md = std::fs::read_to_string(out.join("report.md")).expect("report.md");
    assert!(md.contains("target_error"), "{md}");
}

/// `ves faces`: each CAD face with its kind, against the CAD itself — the cantilever's six
/// planes (areas of the 1000 × 100 × 50 mm box), and on two public parts every cylinder's radius
/// one of the radii the STEP file's CYLINDRICAL_SURFACEs state, the block's bores concave.
#[test]
fn faces_are_listed_as_the_cad_states_them() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let faces = |file: &Path| -> Vec<serde_json::Value> {
        let o = ves(&["faces", file.to_str().unwrap(), "--json"]);
        last_json(&o).as_array().expect("a list of faces").clone()
    };
    let box_faces = faces(&root.join("cases/cantilever/cantilever.step"));
    assert_eq!(box_faces.len(), 6);
    let mut areas: Vec<f64> = box_faces.iter().map(|f| f["area_m2"].as_f64().expect("area")).collect();
    areas.sort_by(f64::total_cmp);
    for (got, want) in areas.iter().zip([0.005, 0.005, 0.05, 0.05, 0.1, 0.1]) {
        assert!((got - want).abs() < 1e-9 * want, "{areas:?}");
    }
    assert!(
        box_faces
            .iter()
            .all(|f| f["kind"] == "plane" && numbers(&f["normal"]).iter().filter(|c| c.abs() == 1.0).count() == 1)
    );
    for (part, concave) in [
        ("pmi_block_2holes.step", vec![2, 3, 24, 25, 27, 28, 29, 30]),
        ("crankshaft.step", vec![]),
    ] {
        let step = root.join("cases/corpus").join(part);
        let text = std::fs::read_to_string(&step).expect("step");
        // The radii the file states, mm: CYLINDRICAL_SURFACE('…',#placement,radius).
        let stated: Vec<f64> = text
            .split("CYLINDRICAL_SURFACE(")
            .skip(1)
            .filter_map(|s| s.split(')').next()?.rsplit(',').next()?.trim().parse().ok())
            .collect();
        assert!(!stated.is_empty());
        let listed = faces(&step);
        let cylinders: Vec<&serde_json::Value> = listed.iter().filter(|f| f["kind"] == "cylinder").collect();
        assert!(cylinders.len() >= 8, "{part}: {} cylinders", cylinders.len());
        for c in &cylinders {
            let r = 1e3 * c["radius_m"].as_f64().expect("radius");
            assert!(
                stated.iter().any(|s| (r - s).abs() < 1e-3 * s),
                "{part}: face {} r = {r} mm, stated {stated:?}",
                c["tag"]
            );
        }
        for tag in concave {
            let f = listed.iter().find(|f| f["tag"] == tag).expect("face");
            assert_eq!(
                (f["kind"].as_str(), f["concave"].as_bool()),
                (Some("cylinder"), Some(true)),
                "{f}"
            );
        }
    }
    let o = ves(&[
        "faces",
        root.join("cases/cantilever/scene.toml")
            .with_extension("txt")
            .to_str()
            .unwrap(),
    ]);
    assert_refused(&o, "give a STEP or IGES file");
}

/// `ves faces` names the faces as the STEP file does: the corpus block with each face named by
/// its place in the file's shell ("f1" … "f30") is listed with face k named "fk" — gmsh numbers
/// the faces in the file's order, and the names follow only because every plane and cylinder of
/// the file is the face of that number. The block as published names every face "PartBody"
/// (the body's name, not a face's) and is listed without names.
#[test]
fn faces_carry_the_names_the_step_file_gives_them() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let dir = tempfile::tempdir().unwrap();
    let copy = block_with_named_faces(dir.path(), "named block.step");
    let listed = |file: &Path| -> Vec<serde_json::Value> {
        let o = ves(&["faces", file.to_str().unwrap(), "--json"]);
        last_json(&o).as_array().expect("a list of faces").clone()
    };
    let faces = listed(&copy);
    assert_eq!(faces.len(), 30);
    for f in &faces {
        let tag = f["tag"].as_u64().expect("tag");
        assert_eq!(f["name"].as_str(), Some(format!("f{tag}").as_str()), "{f}");
    }
    // The bores keep their kind (the names did not move the faces).
    assert!(faces.iter().filter(|f| f["concave"] == true).count() >= 8);
    let text_out = ves(&["faces", copy.to_str().unwrap()]);
    assert!(String::from_utf8_lossy(&text_out.stdout).contains("\"f2\" cylinder (concave)"));
    let published = root.join("cases/corpus/pmi_block_2holes.step");
    assert!(listed(&published).iter().all(|f| f["name"].is_null()));
}

/// `--json` carries every warning of the run, one line each, whatever VES_LOG shows on stderr
/// (a unit the STEP file overrides, a 4-node mesh far too stiff in bending).
#[test]
fn json_lists_the_warnings_of_the_run() {
    let (dir, path) = workdir(&GOOD.replace("unit = \"mm\"", "unit = \"m\""));
    let out = dir.path().join("b.h5");
    let o = Command::new(env!("CARGO_BIN_EXE_ves"))
        .args([
            "precompute",
            path.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--json",
        ])
        .env("VES_LOG", "error")
        .output()
        .expect("ves runs");
    let v = last_json(&o);
    let warnings = warnings_of(&v);
    assert!(
        warnings.iter().any(|w| w.contains("geometry.unit = \"m\" is ignored")),
        "{warnings:?}"
    );
    assert!(
        warnings.iter().any(|w| w.contains("far too stiff in bending")),
        "{warnings:?}"
    );
    assert!(warnings.iter().all(|w| !w.contains('\n')));
    assert!(
        !stderr(&o).contains("WARN"),
        "VES_LOG=error shows none on stderr: {}",
        stderr(&o)
    );
}

/// Without a terminal (stderr piped, as in a batch job's log), a precompute logs each stage as
/// one line with the seconds since the start, and a stage that lasts again every
/// `VES_PROGRESS_EVERY` seconds; `--quiet` and `VES_LOG=warn` silence them. (A 25-minute run
/// printed nothing to a log before.)
#[test]
fn progress_is_logged_without_a_terminal() {
    let scene = GOOD
        .replace("order = 1", "order = 2")
        .replace("size = 0.05", "size = 0.012")
        .replace("count = 4", "count = 60");
    let (dir, path) = workdir(&scene);
    let out = dir.path().join("b.h5");
    let run = |extra: &[&str], env: &[(&str, &str)]| {
        let mut c = Command::new(env!("CARGO_BIN_EXE_ves"));
        c.args([
            "precompute",
            path.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--force",
        ])
        .args(extra)
        .env_remove("VES_LOG");
        for (k, v) in env {
            c.env(k, v);
        }
        c.output().expect("ves runs")
    };
    let o = run(&[], &[("VES_PROGRESS_EVERY", "1")]);
    assert!(o.status.success(), "{}", stderr(&o));
    let all = String::from_utf8_lossy(&o.stderr).into_owned();
    let lines: Vec<&str> = all.lines().filter(|l| l.contains(" INFO ves::progress: ")).collect();
    let seconds: Vec<f64> = lines.iter().map(|l| number_after(l, "ves::progress: ")).collect();
    assert!(lines.iter().any(|l| l.contains("meshing")), "{all}");
    assert!(lines.iter().any(|l| l.contains("eigen-solving")), "{all}");
    assert!(lines.iter().any(|l| l.contains("writing")), "{all}");
    assert!(
        seconds.windows(2).all(|w| w[1] >= w[0]),
        "seconds since the start, in order: {all}"
    );
    // The eigen-solve of 60 modes lasts seconds here: told again at least once.
    assert!(lines.iter().any(|l| l.ends_with("(still)")), "{all}");
    for (extra, env) in [(vec!["--quiet"], vec![]), (vec![], vec![("VES_LOG", "warn")])] {
        let o = run(&extra, &env);
        assert!(o.status.success());
        let all = String::from_utf8_lossy(&o.stderr);
        assert!(!all.contains("ves::progress"), "{extra:?} {env:?}: {all}");
    }
}

/// `ves batch`: good scenes done, a broken one named, a second run does nothing, a changed
/// scene is redone, a killed batch resumes without redoing finished work.
#[test]
fn batch_skips_up_to_date_survives_a_bad_scene_and_resumes() {
    let (dir, first) = workdir(GOOD);
    let d = dir.path();
    std::fs::rename(&first, d.join("a.toml")).expect("rename");
    std::fs::write(
        d.join("b.toml"),
        GOOD.replace("name = \"beam\"", "name = \"beam2\"")
            .replace("count = 4", "count = 5"),
    )
    .expect("b");
    std::fs::write(d.join("broken.toml"), GOOD.replace("poisson = 0.3", "poisson = 0.5")).expect("broken");
    let out = d.join("out");
    let run = || ves(&["batch", d.to_str().unwrap(), "--out", out.to_str().unwrap(), "--json"]);
    let parse =
        |o: &Output| -> Vec<serde_json::Value> { last_json(o).as_array().expect("an array of outcomes").clone() };
    let status = |v: &[serde_json::Value], scene: &str| -> String {
        v.iter()
            .find(|o| o["scene"].as_str().is_some_and(|s| s.ends_with(scene)))
            .map(|o| o["status"].as_str().unwrap_or("").to_string())
            .unwrap_or_default()
    };
    let o = run();
    assert_eq!(
        o.status.code(),
        Some(1),
        "a failed scene makes the batch fail at the end"
    );
    let err = stderr(&o);
    assert!(err.contains("broken.toml") && err.contains("poisson"), "{err}");
    let v = parse(&o);
    assert_eq!(
        (status(&v, "a.toml"), status(&v, "b.toml"), status(&v, "broken.toml")),
        ("done".into(), "done".into(), "failed".into())
    );
    let mtime = |f: &str| {
        std::fs::metadata(out.join(f))
            .and_then(|m| m.modified())
            .expect("output")
    };
    let (ta, tb) = (mtime("beam.h5"), mtime("beam2.h5"));
    // Second run: nothing redone.
    let v = parse(&run());
    assert_eq!(
        (status(&v, "a.toml"), status(&v, "b.toml")),
        ("up-to-date".into(), "up-to-date".into())
    );
    assert_eq!(
        (mtime("beam.h5"), mtime("beam2.h5")),
        (ta, tb),
        "up-to-date outputs must not be rewritten"
    );
    // A changed scene is redone, the other not.
    std::fs::write(
        d.join("b.toml"),
        GOOD.replace("name = \"beam\"", "name = \"beam2\"")
            .replace("count = 4", "count = 6"),
    )
    .expect("b");
    let v = parse(&run());
    assert_eq!(
        (status(&v, "a.toml"), status(&v, "b.toml")),
        ("up-to-date".into(), "done".into())
    );
    // Interrupted: kill a batch (one scene at a time, in name order) as soon as it reports a.toml
    // done, while it works on b.toml, which is made heavy enough (~4 s here) that the kill lands
    // mid-run; the rerun only does the rest.
    std::fs::remove_dir_all(&out).expect("clean");
    std::fs::remove_file(d.join("broken.toml")).expect("rm");
    std::fs::write(
        d.join("b.toml"),
        GOOD.replace("name = \"beam\"", "name = \"beam2\"")
            .replace("count = 4", "count = 20")
            .replace("order = 1", "order = 2")
            .replace("size = 0.05", "size = 0.02"),
    )
    .expect("b");
    let mut child = Command::new(env!("CARGO_BIN_EXE_ves"))
        .args([
            "batch",
            d.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--jobs",
            "1",
        ])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("spawn");
    let stderr = child.stderr.take().expect("stderr piped");
    let (tx, rx) = std::sync::mpsc::channel();
    // Not joined: a meshing worker of the killed batch may hold the pipe open a little longer.
    std::thread::spawn(move || {
        for line in std::io::BufRead::lines(std::io::BufReader::new(stderr)).map_while(Result::ok) {
            if line.starts_with("done:") && line.contains("a.toml") {
                let _ = tx.send(());
            }
        }
    });
    let reported = rx.recv_timeout(std::time::Duration::from_secs(120));
    let _ = child.kill();
    let _ = child.wait();
    assert!(reported.is_ok(), "the batch never reported a.toml done within 120 s");
    assert!(
        out.join("beam.h5").exists(),
        "a.toml's output exists once reported done"
    );
    assert!(
        !out.join("beam2.h5").exists(),
        "the kill must land while b.toml runs (its output must not exist yet)"
    );
    let ta = mtime("beam.h5");
    // A temporary file of a dead run, as a kill mid-write leaves it.
    std::fs::write(out.join("beam2.h5.tmp-4999999.Ab3dEf9h"), b"half").expect("stale");
    let v = parse(&run());
    assert_eq!(status(&v, "a.toml"), "up-to-date", "finished work is not redone");
    assert_eq!(mtime("beam.h5"), ta, "finished output not rewritten");
    assert_eq!(
        status(&v, "b.toml"),
        "done",
        "the interrupted scene is done by the rerun"
    );
    assert!(
        !out.join("beam2.h5.tmp-4999999.Ab3dEf9h").exists(),
        "stale temporary file removed"
    );
    assert!(ves(&["info", out.join("beam2.h5").to_str().unwrap()]).status.success());
}

/// SLEPc under `mpirun -n 2` against ARPACK on the same scene: frequencies to 1e-8, the same
/// modes (|cosine| of each pair of vectors ≥ 1 − 1e-8; the beam's modes are isolated). Here the
/// beam is free (six rigid modes, a second shift) and without the error estimate: K and M are
/// assembled only on the ranks, each its rows from its share of the mesh, the modes are checked
/// there, and the mass properties are the shares' moments summed over the ranks.
#[cfg(feature = "slepc")]
#[test]
fn slepc_on_two_mpi_ranks_matches_arpack() {
    slepc_matches_arpack("slepc", false);
}

/// The iterative method (Jacobi–Davidson + GAMG with the rigid-body near-null space) on two
/// ranks, against ARPACK the same way, with the error estimate (rank 0 then assembles the whole
/// K and M too, for the estimate).
#[cfg(feature = "slepc")]
#[test]
fn slepc_iterative_on_two_mpi_ranks_matches_arpack() {
    slepc_matches_arpack("slepc-iterative", true);
}

#[cfg(feature = "slepc")]
fn slepc_matches_arpack(solver: &str, error_estimate: bool) {
    let scene = GOOD.replace("count = 4", "count = 12");
    let scene = if error_estimate {
        scene.replace("order = 1", "order = 2")
    } else {
        scene
            .replace("order = 1", "order = 2\nerror_estimate = false")
            .replace("[[fixed]]\nplane = { axis = \"x\", value = 0.0 }\n", "")
    };
    assert_ne!(scene.contains("[[fixed]]"), !error_estimate);
    let (dir, path) = workdir(&scene);
    let (a, s) = (dir.path().join("arpack.h5"), dir.path().join("slepc.h5"));
    let o = ves(&[
        "precompute",
        path.to_str().unwrap(),
        "-o",
        a.to_str().unwrap(),
        "--solver",
        "arpack",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = Command::new("mpirun")
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        // One node: no ssh/rsh agent needed (a minimal machine may have none).
        .env("OMPI_MCA_plm", "isolated")
        .args(["-n", "2", "--oversubscribe", env!("CARGO_BIN_EXE_ves"), "precompute"])
        .args([
            path.to_str().unwrap(),
            "-o",
            s.to_str().unwrap(),
            "--solver",
            solver,
            "--json",
        ])
        .output()
        .expect("mpirun runs (apt-get install openmpi-bin)");
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}\n{stdout}", stderr(&o));
    assert_eq!(
        stdout.lines().filter(|l| l.starts_with('{')).count(),
        1,
        "rank 0 alone reports: {stdout}"
    );
    let read = |p: &Path| -> (Vec<f64>, ndarray::Array2<f64>, Vec<f64>) {
        let f = ves_format::file::open(p).expect("open");
        let g = f.group("spaces/global").expect("global");
        // A free body's mass, centre and inertia (none for the clamped one).
        let mut rigid = Vec::new();
        if let Ok(r) = g.group("rigid") {
            rigid.push(r.attr("mass").and_then(|a| a.read_scalar()).expect("mass"));
            for name in ["center_of_mass", "inertia"] {
                rigid.extend(r.attr(name).and_then(|a| a.read_raw::<f64>()).expect(name));
            }
        }
        (
            g.dataset("modes/eigenvalues")
                .and_then(|d| d.read_raw())
                .expect("eigenvalues"),
            g.dataset("modes/basis").and_then(|d| d.read_2d()).expect("basis"),
            rigid,
        )
    };
    let ((la, pa, ra), (ls, ps, rs)) = (read(&a), read(&s));
    assert_eq!(ra.len(), if error_estimate { 0 } else { 13 });
    assert_eq!(rs.len(), ra.len());
    for (x, y) in rs.iter().zip(&ra) {
        assert!(
            (x - y).abs() <= 1e-12 * ra[0].max(1.0) * (1.0 + y.abs()),
            "mass properties {rs:?} vs {ra:?}"
        );
    }
    assert_eq!(la.len(), 12);
    assert_eq!(ls.len(), 12);
    for j in 0..12 {
        let rel = (ls[j] / la[j] - 1.0).abs();
        assert!(rel < 1e-8, "mode {j}: λ {} vs {} ({rel:e})", ls[j], la[j]);
        let (x, y) = (pa.column(j), ps.column(j));
        let cos = x.dot(&y) / (x.dot(&x) * y.dot(&y)).sqrt();
        assert!(cos.abs() > 1.0 - 1e-8, "mode {j}: cosine {cos}");
    }
}

/// `ves session` on a basis with a volume of interest: the scripted pull of rib 3 starts inside
/// its VOI and leaves it loaded; the session switches spaces, reports it, and stays finite.
#[test]
fn session_switches_between_voi_spaces() {
    let cases = Path::new(env!("CARGO_MANIFEST_DIR")).join("../cases/ribplate");
    let text = std::fs::read_to_string(cases.join("scene-voi.toml")).expect("scene");
    // Keep only rib 3's VOI (the one the script touches).
    let head = text.split("[[voi]]").next().expect("head").to_string();
    let rib3 = text.split("[[voi]]").find(|s| s.contains("\"rib3\"")).expect("rib3");
    let scene = format!("{head}[[voi]]{rib3}").replace("count = 30", "count = 20");
    let dir = tempfile::tempdir().expect("tmp");
    std::fs::copy(cases.join("ribplate.step"), dir.path().join("ribplate.step")).expect("step");
    let path = dir.path().join("voi.toml");
    std::fs::write(&path, scene).expect("scene");
    let basis = dir.path().join("voi.h5");
    let o = ves(&["precompute", path.to_str().unwrap(), "-o", basis.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v = session_json(&basis, &cases.join("pull_rib3.csv"));
    assert_eq!(v["spaces"], 2, "{v}");
    // The grab pulls rib 3 out of its box and keeps its space while held (the switcher
    // follows the grabbed vertex); letting go out there returns to the global space.
    assert_eq!(
        v["switches"].as_u64().expect("switches"),
        2,
        "into rib3, held there while pulled out of the box, out on release: {v}"
    );
    // How long a switch takes is a benchmark figure (docs/benchmarks.md), not a test's.
    assert!(
        v["switch_us_max"].as_f64().is_some_and(|t| t.is_finite() && t >= 0.0),
        "{v}"
    );
    assert!(
        v["peak_force_n"].as_f64().expect("force") > 1.0,
        "the rib was pulled: {v}"
    );
    assert_eq!(v["quarantined"], 0);
    assert!(v["visual_updates"].as_u64().expect("visual") > 0);
}

/// The cantilever with `[mesh] target_error = 0.01`, no size and `extra` mesh lines, refined:
/// the run's JSON, its space, and the mesh-converged frequencies (cases/cantilever/
/// converged.json: Richardson over 66k–440k-unknown meshes, bench/converged.py).
/// `ves precompute --json` of the cantilever case with its scene edited by `edit`.
/// Also the directory holding its basis `b.h5`.
fn cantilever_case_json(edit: impl FnOnce(String) -> String) -> (tempfile::TempDir, serde_json::Value) {
    let dir = tempfile::tempdir().unwrap();
    let case = cantilever_dir();
    std::fs::copy(case.join("cantilever.step"), dir.path().join("cantilever.step")).unwrap();
    let scene = edit(std::fs::read_to_string(case.join("scene.toml")).unwrap());
    let path = write_file(dir.path(), "scene.toml", &scene);
    let v = precompute_json(&path, &dir.path().join("b.h5"));
    (dir, v)
}

fn cantilever_dir() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../cases/cantilever")
}

/// The `warnings` lines of a `--json` summary.
fn warnings_of(v: &serde_json::Value) -> Vec<&str> {
    v["warnings"]
        .as_array()
        .expect("warnings")
        .iter()
        .filter_map(|w| w.as_str())
        .collect()
}

/// [`cantilever_case_json`] with the mesh cache in `cache` (a refinement remembers the mesh it
/// chose there: in the user's cache a second run would start from it).
fn cantilever_case_json_cached(
    edit: impl FnOnce(String) -> String,
    cache: &Path,
) -> (tempfile::TempDir, serde_json::Value) {
    let dir = tempfile::tempdir().unwrap();
    let case = cantilever_dir();
    std::fs::copy(case.join("cantilever.step"), dir.path().join("cantilever.step")).unwrap();
    let scene = edit(std::fs::read_to_string(case.join("scene.toml")).unwrap());
    let path = write_file(dir.path(), "scene.toml", &scene);
    let json = precompute_json_cached(&path, &dir.path().join("b.h5"), cache);
    (dir, json)
}

fn refine_cantilever(extra: &str) -> (serde_json::Value, Vec<f64>, Vec<f64>, Vec<f64>) {
    let cache = tempfile::tempdir().unwrap();
    let (dir, v) = cantilever_case_json_cached(
        |scene| scene.replace("size = 0.025", &format!("target_error = 0.01\n{extra}")),
        cache.path(),
    );
    let (case, out) = (cantilever_dir(), dir.path().join("b.h5"));
    let s = v["spaces"][0].clone();
    let steps = s["refinements"].as_array().expect("refinement steps");
    assert!(steps.len() >= 2, "{steps:?}");
    let last = steps.last().unwrap();
    assert!(last["max_estimated_error"].as_f64().unwrap() <= 0.01, "{last}");
    assert_eq!(last["dofs"], s["dofs"]);
    // The file carries the same estimate.
    let o = ves(&["info", out.to_str().unwrap(), "--json"]);
    let info: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(
        info["spaces"][0]["estimated_relative_error"],
        s["estimated_relative_error"]
    );
    let reference: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(case.join("converged.json")).unwrap()).unwrap();
    let list =
        |v: &serde_json::Value| -> Vec<f64> { v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect() };
    let converged = list(&reference["frequencies_hz"]);
    let (f, estimate) = (list(&s["frequencies_hz"]), list(&s["estimated_relative_error"]));
    (s, f, estimate, converged)
}

/// Every mode within 1 % of converged, and the estimate within `ratio` of the true error
/// wherever that is above 0.1 %.
fn assert_within_one_percent(f: &[f64], estimate: &[f64], converged: &[f64], ratio: std::ops::RangeInclusive<f64>) {
    for i in 0..f.len() {
        let truth = (f[i] - converged[i]) / converged[i];
        assert!(
            truth.abs() < 0.01,
            "mode {}: {} Hz is {truth:.2e} from {}",
            i + 1,
            f[i],
            converged[i]
        );
        if truth.abs() > 1e-3 {
            assert!(
                ratio.contains(&(estimate[i] / truth.abs())),
                "mode {}: estimate {:.2e}, true {truth:.2e}",
                i + 1,
                estimate[i]
            );
        }
    }
}

/// `[mesh] target_error = 0.01` with no size: the cantilever is refined uniformly until its
/// estimate says 1 %, every mode then is within 1 % of the mesh-converged answer, and the
/// estimate tracks the true error: measured 0.67–1.39× on the 8 modes above 0.1 % (2.0k, 6.1k,
/// 32.8k unknowns; docs/accuracy.md). The recovery estimate alone decides (it vouches for every
/// mode): low on the bending modes (11, 14, 18, 20: 0.67–0.88×), high on the torsion ones (5, 10,
/// 13, 17: 1.33–1.39×). The bound 0.5–2.0 leaves 1.34× below the lowest and 1.44× above the
/// highest; the whole estimate halved (0.34–0.70) or doubled (1.34–2.78) fails it, and so does
/// any bending mode's halved or any torsion mode's doubled. With `error_estimate = "full"` the
/// bending modes take the Richardson estimate at the credited rate 2 (1.42–1.95× at 29.3k).
#[test]
fn target_error_refines_the_cantilever_to_within_one_percent_of_converged() {
    let (_, f, estimate, converged) = refine_cantilever("");
    assert_within_one_percent(&f, &estimate, &converged, 0.5..=2.0);
}

/// The cantilever at its default size (25 mm, 11.7k unknowns) against its mesh-converged
/// reference (cases/cantilever/converged.json), with the default estimate and with
/// `error_estimate = "full"`: the recovery estimate on the mesh itself is within 0.55–1.2× of
/// the true error of every mode off by more than 0.1 %, the number the basis carries within
/// 0.55–1.6×, no more than a fifth of the modes are flagged (measured none), and the JSON says
/// per mode which rule chose and why the coarser meshes were solved or not. By default the
/// recovery estimate vouches for every mode: no coarser mesh is solved and every number is the
/// recovery one. Measured on the 13 such modes: recovery 0.985–1.027× on the torsion modes (5,
/// 10, 13, 17) and 0.628–0.986× on the 9 bending ones (recovery is low on the solid beam's
/// bending, docs/accuracy.md); with "full" the number carried is the recovery one but for modes
/// 1 and 19, where the asymptotic Richardson estimate is larger (0.886×, 1.381×), so
/// 0.628–1.381×. Both bounds leave 1.14× below the lowest and 1.16–1.17× above the highest.
/// Recovery off by 2× on any one mode fails (halved: at most 0.51; doubled: at least 1.26), and
/// so does a number carried at 2× or ½ the truth, or the whole estimate doubled (2.76) or
/// halved (0.31).
#[test]
fn error_estimate_of_the_cantilever_tracks_its_true_error() {
    let case = cantilever_dir();
    let reference: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(case.join("converged.json")).unwrap()).unwrap();
    let recovery = cantilever_case_json(|scene| scene).1["spaces"][0].clone();
    let full =
        cantilever_case_json(|scene| scene.replace("order = 2", "order = 2\nerror_estimate = \"full\"")).1["spaces"][0]
            .clone();
    let e = &recovery["error_estimate"];
    assert_eq!(
        (e["mode"].as_str(), e["coarser_meshes"].as_str()),
        (Some("recovery"), Some("not_needed")),
        "{e}"
    );
    assert_eq!(e["levels"].as_array().map(Vec::len), Some(0), "{e}");
    let e = &full["error_estimate"];
    assert_eq!(
        (e["mode"].as_str(), e["coarser_meshes"].as_str()),
        (Some("full"), Some("always")),
        "{e}"
    );
    assert_eq!(e["levels"].as_array().map(Vec::len), Some(2), "{e}");
    // The same mesh and modes either way: only the estimate differs.
    assert_eq!(recovery["frequencies_hz"], full["frequencies_hz"]);
    for s in [recovery, full] {
        let rules: &[&str] = if s["error_estimate"]["mode"] == "full" {
            &["recovery", "larger_richardson"]
        } else {
            &["recovery"]
        };
        the_estimate_tracks_the_truth(&s, &reference, rules);
    }
}

fn the_estimate_tracks_the_truth(s: &serde_json::Value, reference: &serde_json::Value, rules: &[&str]) {
    let modes = s["error_estimate"]["modes"].as_array().expect("modes").clone();
    let flagged = modes.iter().filter(|m| m["reliable"] == false).count();
    assert!(5 * flagged <= modes.len(), "{flagged} of {} flagged", modes.len());
    for (i, m) in modes.iter().enumerate() {
        let f = s["frequencies_hz"][i].as_f64().unwrap();
        let converged = reference["frequencies_hz"][i].as_f64().unwrap();
        let truth = (f - converged) / converged;
        let kept = s["estimated_relative_error"][i].as_f64().unwrap();
        assert_eq!(m["relative"].as_f64(), Some(kept));
        assert!(rules.contains(&m["rule"].as_str().unwrap()), "{m}");
        if truth <= 1e-3 {
            continue;
        }
        let recovery = m["recovery"].as_f64().expect("recovery") / truth;
        assert!(
            (0.55..=1.2).contains(&recovery),
            "mode {}: recovery {recovery:.2}× the truth",
            i + 1
        );
        assert!(
            (0.55..=1.6).contains(&(kept / truth)),
            "mode {}: estimate {:.2}× the truth",
            i + 1,
            kept / truth
        );
    }
}

/// A `target_error` refinement remembers the mesh it chose for the geometry (beside the mesh
/// cache): the same beam clamped at its other end starts from that mesh, which meets the target
/// at once (one mesh instead of 2.0k, 6.1k and 32.8k unknowns), and is not meshed again; the
/// same scene run again gives the same frequencies (to 1e-9). A refinement stopped short
/// of its target (by `max_dofs` here) is remembered for its own rerun only: another support
/// starts afresh; the target its warning advises is met on that mesh at once.
#[test]
fn a_refinement_remembers_its_mesh_for_its_rerun_and_other_supports() {
    let cache = tempfile::tempdir().unwrap();
    let target = |scene: String| scene.replace("size = 0.025", "target_error = 0.01");
    let first = cantilever_case_json_cached(target, cache.path()).1["spaces"][0].clone();
    let steps = first["refinements"].as_array().expect("steps").clone();
    assert!(steps.len() >= 2, "{steps:?}");
    assert!(steps.iter().all(|s| s.get("remembered").is_none()), "{steps:?}");
    let other_end = |scene: String| target(scene).replace("value = 0.0 }", "value = 1.0 }");
    let (_, v) = cantilever_case_json_cached(other_end, cache.path());
    let second = &v["spaces"][0];
    let again = second["refinements"].as_array().expect("steps");
    assert_eq!(again.len(), 1, "{again:?}");
    assert_eq!(again[0]["remembered"], true, "{again:?}");
    assert_eq!(again[0]["dofs"], steps.last().unwrap()["dofs"]);
    assert!(again[0]["max_estimated_error"].as_f64().unwrap() <= 0.01, "{again:?}");
    // Its mesh came from the cache.
    assert!(v["timings_s"]["mesh"].as_f64().unwrap() < 0.5, "{}", v["timings_s"]);
    let rerun = cantilever_case_json_cached(target, cache.path()).1["spaces"][0].clone();
    assert_eq!(rerun["refinements"].as_array().map(Vec::len), Some(1), "{rerun}");
    let hz = |v: &serde_json::Value| -> Vec<f64> {
        v["frequencies_hz"]
            .as_array()
            .expect("frequencies")
            .iter()
            .filter_map(|f| f.as_f64())
            .collect()
    };
    let (a, b) = (hz(&rerun), hz(&first));
    assert!(
        a.len() == b.len() && a.iter().zip(&b).all(|(x, y)| (x / y - 1.0).abs() < 1e-9),
        "{a:?} vs {b:?}"
    );

    // Stopped short: 0.01 % cannot be met within 5000 unknowns.
    let cache = tempfile::tempdir().unwrap();
    let strict = |scene: String| scene.replace("size = 0.025", "target_error = 0.0001\nmax_dofs = 5000");
    let (_, v) = cantilever_case_json_cached(strict, cache.path());
    let stopped = v["spaces"][0]["refinements"].as_array().expect("steps").clone();
    assert!(
        stopped.last().unwrap()["max_estimated_error"].as_f64().unwrap() > 0.0001,
        "{stopped:?}"
    );
    let strict_other_end = |scene: String| strict(scene).replace("value = 0.0 }", "value = 1.0 }");
    let (_, v) = cantilever_case_json_cached(strict_other_end, cache.path());
    let fresh = v["spaces"][0]["refinements"].as_array().expect("steps").clone();
    assert!(fresh[0].get("remembered").is_none(), "{fresh:?}");
    assert_eq!(fresh[0]["dofs"], stopped[0]["dofs"], "{fresh:?}");
    let (_, v) = cantilever_case_json_cached(strict, cache.path());
    let resumed = v["spaces"][0]["refinements"].as_array().expect("steps").clone();
    assert_eq!(resumed[0]["remembered"], true, "{resumed:?}");
    assert_eq!(resumed[0]["dofs"], stopped.last().unwrap()["dofs"], "{resumed:?}");
    // Its advice taken (the page's "accept" button): the target it names is met on that mesh,
    // at once.
    let warnings = v["warnings"].as_array().expect("warnings");
    let advice = warnings
        .iter()
        .filter_map(|w| w.as_str()?.split("set mesh.target_error = ").nth(1))
        .find_map(|t| t.split(' ').next()?.parse::<f64>().ok())
        .unwrap_or_else(|| panic!("no target advised: {warnings:?}"));
    let accept = |scene: String| strict(scene).replace("target_error = 0.0001", &format!("target_error = {advice}"));
    let (_, v) = cantilever_case_json_cached(accept, cache.path());
    let accepted = v["spaces"][0]["refinements"].as_array().expect("steps").clone();
    assert_eq!(accepted.len(), 1, "{accepted:?}");
    assert_eq!(accepted[0]["remembered"], true, "{accepted:?}");
    assert_eq!(accepted[0]["dofs"], stopped.last().unwrap()["dofs"], "{accepted:?}");
    assert!(
        accepted[0]["max_estimated_error"].as_f64().unwrap() <= advice,
        "{accepted:?}"
    );
}

/// A support that holds an edge of the beam (its nodes on a line, no face) is warned of in
/// `--json`'s warnings, naming the support and what to hold instead; a face held is not.
#[test]
fn a_support_on_a_line_is_warned_of() {
    let cache = tempfile::tempdir().unwrap();
    let edge = |scene: String| {
        scene.replace(
            "plane = { axis = \"x\", value = 0.0 }",
            "box = { min = [0.0, -1.0, 0.0], max = [0.0, 1.0, 0.0] }\n[[fixed]]\nplane = { axis = \"x\", value = 1.0 }",
        )
    };
    let (_, v) = cantilever_case_json_cached(edge, cache.path());
    let warnings = warnings_of(&v);
    let line: Vec<&&str> = warnings
        .iter()
        .filter(|w| w.contains("only nodes on a line or at points"))
        .collect();
    assert_eq!(line.len(), 1, "{warnings:?}");
    assert!(
        line[0].starts_with("fixed[0] (box") && line[0].contains("faces = [...]"),
        "{line:?}"
    );
    let (_, v) = cantilever_case_json_cached(|s| s, cache.path());
    let warnings = v["warnings"].as_array().expect("warnings");
    assert!(
        warnings.iter().all(|w| !w.as_str().unwrap_or("").contains("on a line")),
        "{warnings:?}"
    );
}

/// `refinement = "local"`: the last mesh is graded (a gmsh background field from the element
/// error indicator: smaller elements at the clamped end), every mode is within 1 % of converged,
/// and the estimate does not fall below half the true error nor exceed it 6× (measured
/// 2.7–4.6×: the credited rate of 2 is pessimistic for the modes whose error dominates,
/// docs/accuracy.md). The upper bound is a regression bound, not a theorem: a mode converging
/// at the smooth rate 4 of 10-node tets between the fine mesh and the estimate's 1.5× coarser
/// one would be overestimated (1.5⁴ − 1)/(1.5² − 1) = 3.25×; the measured 4.6× means faster,
/// pre-asymptotic convergence there (rates of 3–10 are seen on those meshes), which theory
/// does not bound. 6× is 1.3× the worst measured: more pessimism than that is a change.
#[test]
fn local_refinement_grades_the_cantilever_mesh_and_stays_within_one_percent() {
    let (s, f, estimate, converged) = refine_cantilever("refinement = \"local\"\n");
    let last = s["refinements"].as_array().unwrap().last().unwrap().clone();
    let (largest, smallest) = (last["size"].as_f64().unwrap(), last["smallest_size"].as_f64().unwrap());
    assert!(smallest < 0.9 * largest, "not graded: {last}");
    assert_within_one_percent(&f, &estimate, &converged, 0.5..=6.0);
}

/// `[stress] enabled`: the cantilever (1 × 0.1 × 0.05 m, clamped at x = 0) under a 1 kN tip
/// load through its 20 modes, q = Λ⁻¹ΦᵀF, has the top-fibre bending stress of beam theory,
/// σxx = F (L − x) c / I, at every top vertex within 0.1 m of mid-span (measured: 0.991–1.013
/// of it; 5 modes: 0.96–1.06).
#[test]
fn modal_stress_under_a_static_tip_load_matches_beam_theory() {
    let dir = tempfile::tempdir().unwrap();
    let case = Path::new(env!("CARGO_MANIFEST_DIR")).join("../cases/cantilever");
    std::fs::copy(case.join("cantilever.step"), dir.path().join("cantilever.step")).unwrap();
    let scene = std::fs::read_to_string(case.join("scene.toml"))
        .unwrap()
        .replace("order = 2", "order = 2\nerror_estimate = false")
        + "[stress]\nenabled = true\n";
    let path = write_file(dir.path(), "scene.toml", &scene);
    let out = dir.path().join("b.h5");
    let o = ves(&["precompute", path.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let file = ves_format::BasisReader::open(&out).unwrap();
    let s = file.space("global").unwrap();
    let (nv, r) = (s.vertex_count, s.mode_count);
    let vertices = s.nodes(nv).unwrap();
    let lambda = s.eigenvalues().unwrap();
    let stress = s.stress_rows(0..nv, r).unwrap().expect("modes/stress");
    let dist = |p: [f64; 3], q: [f64; 3]| (0..3).map(|c| (p[c] - q[c]).powi(2)).sum::<f64>();
    let tip = (0..nv)
        .min_by(|&a, &b| dist(vertices[a], [1.0, 0.05, 0.025]).total_cmp(&dist(vertices[b], [1.0, 0.05, 0.025])))
        .unwrap();
    let phi_tip = s.basis_rows(3 * tip..3 * tip + 3, r).unwrap();
    let force = 1000.0;
    // Downward load F on the z components: q_j = φ_j(tip)·F / λ_j.
    let q: Vec<f64> = (0..r).map(|j| phi_tip[2 * r + j] * -force / lambda[j]).collect();
    let inertia = 0.1 * 0.05f64.powi(3) / 12.0;
    let mut checked = 0;
    for (i, p) in vertices.iter().enumerate() {
        if (p[2] - 0.05).abs() > 1e-9 || (p[0] - 0.5).abs() > 0.1 {
            continue;
        }
        let sxx: f64 = (0..r).map(|j| stress[6 * i * r + j] * q[j]).sum();
        let beam = force * (1.0 - p[0]) * 0.025 / inertia;
        assert!(
            (sxx / beam - 1.0).abs() < 0.03,
            "vertex {i} at {p:?}: σxx {sxx:.4e} Pa, beam theory {beam:.4e}"
        );
        checked += 1;
    }
    assert!(checked > 20, "{checked} top vertices near mid-span");
}

/// Every basis gets an XDMF sidecar `B.xdmf` pointing into `B.h5`. ParaView itself (Debian's
/// `paraview`, which scripts/setup installs) opens it headless and what it reads is compared
/// with the basis: node coordinates, 10-node cells in VTK order, every mode
/// shape and every stress tensor (XDMF Tensor6 order).
#[test]
fn xdmf_sidecar_shows_the_basis_to_paraview() {
    let scene = GOOD.replace("order = 1", "order = 2\nerror_estimate = false") + "[stress]\nenabled = true\n";
    let (dir, path) = workdir(&scene);
    let out = dir.path().join("beam.h5");
    let o = ves(&["precompute", path.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let sidecar = dir.path().join("beam.xdmf");
    let xml = std::fs::read_to_string(&sidecar).expect("sidecar written beside the basis");
    assert!(xml.contains("beam.h5:/spaces/global/modes/basis") && xml.contains("Tetrahedron_10"));
    assert_eq!(xml.matches(r#"AttributeType="Vector""#).count(), 4);
    assert_eq!(xml.matches(r#"AttributeType="Tensor6""#).count(), 4);
    // `ves export --vtu` for tools that want VTK files: meshio reads exactly the basis.
    export_vtu_and_check(&out, &dir.path().join("vtu"));
    let seen = pvpython_json("sidecar_dump.py", &[sidecar.as_os_str()]);
    let file = ves_format::BasisReader::open(&out).unwrap();
    let s = file.space("global").unwrap();
    let (n, nv, r) = (s.node_count, s.vertex_count, s.mode_count);
    let nodes = s.nodes(n).unwrap();
    let tets = s.tets().unwrap();
    let basis = s.basis_rows(0..3 * n, r).unwrap();
    let stress = s.stress_rows(0..nv, r).unwrap().expect("stress");
    let g = &seen["global"];
    let num = |v: &serde_json::Value| v.as_f64().expect("number");
    // The same double (serde_json parses decimal text to within an ulp or so).
    let same = |a: f64, b: f64| (a - b).abs() <= 1e-14 * b.abs().max(1e-300);
    for (i, p) in g["points"].as_array().unwrap().iter().enumerate() {
        for c in 0..3 {
            assert!(same(num(&p[c]), nodes[i][c]), "point {i}");
        }
    }
    assert_eq!(g["points"].as_array().unwrap().len(), n);
    assert_eq!(g["cell_type"], "vtkQuadraticTetra");
    for (e, ids) in g["cells"].as_object().unwrap() {
        let e: usize = e.parse().unwrap();
        let want: Vec<u64> = [0, 1, 2, 3, 4, 5, 6, 7, 9, 8]
            .iter()
            .map(|&k| tets[10 * e + k] as u64)
            .collect();
        let got: Vec<u64> = ids.as_array().unwrap().iter().map(|v| v.as_u64().unwrap()).collect();
        assert_eq!(got, want, "cell {e}");
    }
    // The modes by their plain names, in order; beside them `fixed`, 1 where a support holds.
    let named = |grid: &serde_json::Value, prefix: &str| -> Vec<serde_json::Value> {
        let all = grid["arrays"].as_array().unwrap().iter();
        all.filter(|a| a["name"].as_str().unwrap().starts_with(prefix))
            .cloned()
            .collect()
    };
    let arrays = named(g, "mode_");
    assert_eq!(arrays.len(), r);
    let fixed = s.fixed_dofs().unwrap();
    let held = named(g, "fixed");
    assert_eq!(held.len(), 1, "one `fixed` array");
    for (i, t) in held[0]["tuples"].as_object().unwrap() {
        let i: usize = i.parse().unwrap();
        let want = f64::from(u8::from(fixed.iter().any(|&d| d as usize / 3 == i)));
        assert_eq!(num(&t[0]), want, "fixed at node {i}");
    }
    for (j, a) in arrays.iter().enumerate() {
        assert_eq!(a["name"], format!("mode_{:02}_displacement", j + 1));
        for (i, t) in a["tuples"].as_object().unwrap() {
            let i: usize = i.parse().unwrap();
            for c in 0..3 {
                assert!(same(num(&t[c]), basis[(3 * i + c) * r + j]), "mode {j}, node {i}");
            }
        }
    }
    let v = &seen["global vertices"];
    assert_eq!(v["points"].as_array().unwrap().len(), nv);
    let arrays = named(v, "mode_");
    assert_eq!(arrays.len(), r);
    for (j, a) in arrays.iter().enumerate() {
        assert_eq!(a["name"], format!("mode_{:02}_stress", j + 1));
        assert_eq!(a["components"], 9);
        for (i, t) in a["tuples"].as_object().unwrap() {
            let i: usize = i.parse().unwrap();
            let k = |c: usize| stress[(6 * i + c) * r + j];
            // Voigt xx yy zz yz xz xy → the full symmetric tensor, row by row.
            let want = [k(0), k(5), k(4), k(5), k(1), k(3), k(4), k(3), k(2)];
            for (c, w) in want.iter().enumerate() {
                assert!(same(num(&t[c]), *w), "mode {j}, vertex {i}, component {c}");
            }
        }
    }
}

/// A session on a basis with modal stress and a yield strength reports the whole part's and
/// the hands' von Mises stress and the part's safety factor; the root stress of the pulled
/// cantilever is near beam theory's F L c / I; a minimum safety factor the hand's vertex cannot
/// meet trips the watch and the release policy lets go; one that only the clamped root misses
/// (the drawing thread sees it) trips it too, and stiffen holds the load there.
#[test]
fn session_reports_von_mises_and_the_safety_factor() {
    let scene = GOOD
        .replace("order = 1", "order = 2\nerror_estimate = false")
        .replace("density = 7850.0", "density = 7850.0\nyield_strength = 2.5e8")
        + "[stress]\nenabled = true\n";
    let (dir, path) = workdir(&scene);
    let basis = dir.path().join("beam.h5");
    let o = ves(&["precompute", path.to_str().unwrap(), "-o", basis.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let script = dir.path().join("hand.csv");
    // Pull the tip 5 mm down over 0.2 s, then hold.
    std::fs::write(
        &script,
        "t,x,y,z,button\n0,1.0,0.05,0.05,1\n0.2,1.0,0.05,0.045,1\n0.5,1.0,0.05,0.045,1\n",
    )
    .unwrap();
    let v = session_json(&basis, &script);
    let num = |v: &serde_json::Value, k: &str| v[k].as_f64().unwrap_or_else(|| panic!("{k}: {v}"));
    let (part, hands, sf) = (
        num(&v, "von_mises_max"),
        num(&v, "von_mises_max_hands"),
        num(&v, "safety_factor_min"),
    );
    assert!(part > 0.0 && hands > 0.0, "{v}");
    assert!((sf - 2.5e8 / part).abs() < 1e-9 * sf, "{v}");
    // Independently, from the basis file: the static field of the peak force (−z at the pulled
    // tip vertex), q = Λ⁻¹ΦᵀF, its von Mises stress by the textbook formula at every vertex.
    let force = num(&v, "peak_force_n");
    let file = ves_format::BasisReader::open(&basis).expect("basis");
    let s = file.space("global").expect("global");
    let (nv, r) = (s.vertex_count, s.mode_count);
    let vertices = s.nodes(nv).expect("nodes");
    let lambda = s.eigenvalues().expect("eigenvalues");
    let rows = s.stress_rows(0..nv, r).expect("stress").expect("modes/stress");
    let d2 = |p: [f64; 3], q: [f64; 3]| (0..3).map(|c| (p[c] - q[c]).powi(2)).sum::<f64>();
    let tip = (0..nv)
        .min_by(|&a, &b| d2(vertices[a], [1.0, 0.05, 0.05]).total_cmp(&d2(vertices[b], [1.0, 0.05, 0.05])))
        .expect("vertices");
    let phi_tip = s.basis_rows(3 * tip..3 * tip + 3, r).expect("tip rows");
    let q: Vec<f64> = (0..r).map(|j| phi_tip[2 * r + j] * -force / lambda[j]).collect();
    let von_mises = |i: usize| {
        let t: [f64; 6] = std::array::from_fn(|k| (0..r).map(|j| rows[(6 * i + k) * r + j] * q[j]).sum());
        (0.5 * ((t[0] - t[1]).powi(2) + (t[1] - t[2]).powi(2) + (t[2] - t[0]).powi(2))
            + 3.0 * (t[3].powi(2) + t[4].powi(2) + t[5].powi(2)))
        .sqrt()
    };
    let field_max = (0..nv).map(von_mises).fold(0.0, f64::max);
    // Beam theory σ = F (L − x) c / I on the top fibre, at the sections x ∈ [0.4, 0.6] m, away
    // from the clamp's singular corners and the load's local field.
    let inertia = 0.1 * 0.05f64.powi(3) / 12.0;
    let ratios: Vec<f64> = (0..nv)
        .filter(|&i| (vertices[i][2] - 0.05).abs() < 1e-9 && (vertices[i][0] - 0.5).abs() <= 0.1)
        .map(|i| von_mises(i) / (force * (1.0 - vertices[i][0]) * 0.025 / inertia))
        .collect();
    let (lo, hi) = ratios
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)));
    println!(
        "session von Mises max {part:.4e} Pa, static field at the peak force {field_max:.4e} Pa (ratio {:.4}); \
         mid-span top fibre / beam theory {lo:.3}–{hi:.3} over {} vertices",
        part / field_max,
        ratios.len()
    );
    assert!(!ratios.is_empty(), "no top vertex near mid-span");
    // 10-node tets give a linear stress inside each element: exact for the bending stress's
    // variation over the depth, not for its variation along the ~50 mm elements (up to
    // h / 2(L − x) ≈ 6 % at x = 0.6 m); the 4 modes' static field adds its truncation (measured
    // 0.944–1.064 together): 10 %.
    assert!(
        lo > 0.9 && hi < 1.1,
        "mid-span top fibre von Mises / beam theory {lo:.3}–{hi:.3}"
    );
    // The session's maximum is that static field's at the peak force, plus what the 0.2 s ramp
    // leaves ringing (no damping): a ramp of T leaves at most 2/(ωT) of the static response,
    // 3.8 % for the 42 Hz first mode and 0.6 % for the 259 Hz second bending mode; the
    // drawing thread samples frames, which can only lower it (measured 1.041).
    assert!(
        (0.95..=1.06).contains(&(part / field_max)),
        "session von Mises max {part} Pa against the static field's {field_max} Pa"
    );
    // Bending: the largest principal stress is the top fibre's tension, near von Mises at the
    // root; the largest principal strain of that nearly uniaxial state is close to σ₁/E.
    let (p1, e1) = (num(&v, "principal_stress_max"), num(&v, "principal_strain_max"));
    assert!(p1 > 0.8 * part && p1 < 1.2 * part, "σ₁ {p1} Pa vs von Mises {part} Pa");
    assert!(
        e1 > 0.7 * p1 / 2.1e11 && e1 < 1.3 * p1 / 2.1e11,
        "ε₁ {e1} vs σ₁/E {}",
        p1 / 2.1e11
    );
    assert_eq!(v["stress_exceeded_steps"], 0);
    // `ves bench` times the stress update on a basis that has it.
    let o = ves(&["bench", basis.to_str().unwrap(), "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let b = last_json(&o);
    assert!(
        num(&b, "full_field_stress_ms_median") > 0.0 && num(&b, "von_mises_ms_median") > 0.0,
        "{b}"
    );
    let device = format!("script:{}", script.display());
    let session = |extra: &[&str]| {
        let args = [
            &["session", basis.to_str().unwrap(), "--device", device.as_str()],
            extra,
        ]
        .concat();
        ves(&args)
    };
    let o = session(&["--min-safety-factor", "1e7", "--strain-policy", "release", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let w = last_json(&o);
    assert!(w["stress_exceeded_steps"].as_u64().unwrap() > 0, "{w}");
    assert!(num(&w, "peak_force_n") < num(&v, "peak_force_n"), "released: {w}");
    // The root's safety factor is ~4300, the tip vertex's ~2e6: 1e4 only the root misses. The
    // drawing thread sees the root (60 Hz) and raises the alarm the haptic thread reads: pulled
    // over 2 s, so a drawing thread delayed by a busy machine still catches the load well before
    // it is all there (over 0.2 s, CI once held it only at 88 %).
    let slow = dir.path().join("slow.csv");
    std::fs::write(
        &slow,
        "t,x,y,z,button\n0,1.0,0.05,0.05,1\n2.0,1.0,0.05,0.045,1\n2.3,1.0,0.05,0.045,1\n",
    )
    .unwrap();
    let o = ves(&[
        "session",
        basis.to_str().unwrap(),
        "--device",
        &format!("script:{}", slow.display()),
        "--min-safety-factor",
        "1e4",
        "--strain-policy",
        "stiffen",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let s = last_json(&o);
    assert!(s["safety_factor_below_min_frames"].as_u64().unwrap() > 0, "{s}");
    assert!(s["stress_exceeded_steps"].as_u64().unwrap() > 0, "{s}");
    assert!(num(&s, "von_mises_max") < 0.8 * part, "stiffen held the load: {s}");
    assert_refused(&session(&["--min-safety-factor", "0"]), "--min-safety-factor 0");
}

/// The mesh cache: a first precompute meshes the estimate's coarser meshes ahead into it (two
/// hits, and two more when the felt check's mesh error reads the same meshes), a second one of
/// the same part with another material meshes nothing (five hits: the mesh and the two coarser
/// ones twice, no new entries) and, on the same meshes, its frequencies scale exactly as √E;
/// `VES_MESH_CACHE=off` stores nothing. At 25 mm, two elements through the beam's 50 mm: at 50 mm
/// its walls are one element thick and the estimate solves no coarser mesh.
#[test]
fn a_second_scenario_of_the_same_part_reuses_its_meshes() {
    let good = GOOD.replace("size = 0.05", "size = 0.025");
    let (dir, path) = workdir(&good);
    let cache = dir.path().join("cache");
    let run = |scene: &Path, extra: &[(&str, &str)]| {
        let mut c = Command::new(env!("CARGO_BIN_EXE_ves"));
        c.args(["precompute", scene.to_str().unwrap(), "-o"])
            .arg(dir.path().join("b.h5"))
            .args(["--force", "--json"])
            .env("VES_CACHE_DIR", &cache)
            .env("VES_LOG", "info");
        for (k, v) in extra {
            c.env(k, v);
        }
        let o = c.output().expect("ves runs");
        assert!(o.status.success(), "{}", stderr(&o));
        let hits = stderr(&o).matches("mesh cache hit").count();
        let f: Vec<f64> = last_json(&o)["spaces"][0]["frequencies_hz"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        (hits, f)
    };
    // Files of one kind in the cache: `mesh` (a mesh each) or `order` (a node ordering each).
    let count = |kind: &str| {
        std::fs::read_dir(cache.join("meshes")).map_or(0, |d| {
            d.flatten()
                .filter(|e| e.path().extension().is_some_and(|x| x == kind))
                .count()
        })
    };
    let entries = || count("mesh");
    let (hits, f) = run(&path, &[]);
    // The estimate's two coarser meshes were made ahead while the fine one was solved
    // (`accuracy::Prefetch`): the estimate finds them in the cache, and the felt check after it.
    assert_eq!((hits, entries()), (4, 3), "three meshes, one file each");
    // The fine mesh's METIS ordering (the coarser ones are small enough for the dense solver).
    let orders = count("order");
    assert!(orders >= 1, "{orders} orderings");
    let stiffer = write_file(
        dir.path(),
        "stiff.toml",
        &good.replace("young = 2.1e11", "young = 8.4e11"),
    );
    let (hits, g) = run(&stiffer, &[]);
    assert_eq!((hits, entries()), (5, 3));
    assert_eq!(count("order"), orders, "the same graphs: the orderings are reused");
    for (a, b) in f.iter().zip(&g) {
        assert!((b / a - 2.0).abs() < 1e-9, "{a} → {b}");
    }
    std::fs::remove_dir_all(&cache).unwrap();
    let (hits, _) = run(&path, &[("VES_MESH_CACHE", "off")]);
    assert_eq!((hits, entries()), (0, 0));
}

/// A warning that belongs to a mesh is said in full on the run that made it, and a cached run
/// of the same part says it in one short line (not the full text again): the crankshaft of
/// cases/corpus at this size has curved tets made straight-sided. The JSON says which run read
/// the cache, and VES_LOG=info still has the full text.
#[test]
fn a_cached_mesh_says_its_warnings_once() {
    let step = Path::new(env!("CARGO_MANIFEST_DIR")).join("../cases/corpus/crankshaft.step");
    let (dir, scene) = workdir(&format!(
        "name = \"crank\"\n[geometry]\nstep = {:?}\nunit = \"mm\"\n[material]\nyoung = 2.1e11\n\
         poisson = 0.3\ndensity = 7850.0\n[mesh]\nsize = 0.0035\norder = 2\nerror_estimate = false\n\
         [modes]\ncount = 4\n",
        step.display().to_string()
    ));
    let cache = dir.path().join("cache");
    let run = |log: &str| {
        let o = Command::new(env!("CARGO_BIN_EXE_ves"))
            .args(["precompute", scene.to_str().unwrap(), "--force", "--json", "-o"])
            .arg(dir.path().join("c.h5"))
            .env("VES_CACHE_DIR", &cache)
            .env("VES_LOG", log)
            .output()
            .expect("ves runs");
        assert!(o.status.success(), "{}", stderr(&o));
        let cached = last_json(&o)["spaces"][0]["meshing"]["cached"]
            .as_bool()
            .expect("meshing.cached");
        (stderr(&o), cached)
    };
    let full = "were made straight-sided (their faces are flat there";
    let (made, cached) = run("warn");
    assert!(!cached);
    assert!(made.contains(full), "{made}");
    assert!(!made.contains("cached mesh"), "{made}");
    let (again, cached) = run("warn");
    assert!(cached);
    let warnings: Vec<&str> = again.lines().filter(|l| l.contains("WARN")).collect();
    assert_eq!(warnings.len(), 1, "{again}");
    assert!(
        warnings[0].contains("cached mesh: 1 warning(s) when it was made") && warnings[0].contains("straight-sided"),
        "{again}"
    );
    assert!(!again.contains(full), "{again}");
    let (info, _) = run("info");
    assert!(info.contains("(cached mesh) meshed on rung 0"), "{info}");
}

/// The tags survive the mesh cache: a mesh read back from a cache entry carries the tags of the
/// mesh stored (the same `ves precompute` twice, the second a cache hit, writes the same
/// `mesh/surface_faces`), and the runtime loads them (surface_only or not) one per triangle.
/// A point contact (`[contact] radius = 0`): the felt check then meshes no coarser meshes, so
/// the hits counted are the part's own mesh's.
#[test]
fn a_cached_mesh_carries_the_tags_of_a_fresh_one_into_the_basis_and_the_runtime() {
    let (dir, scene) = workdir(
        "name = \"faces\"\n[geometry]\nstep = \"beam.step\"\nunit = \"mm\"\n[material]\nyoung = 2.1e11\n\
         poisson = 0.3\ndensity = 7850.0\n[mesh]\nsize = 0.05\norder = 2\nerror_estimate = false\n[[fixed]]\n\
         faces = [1]\n[modes]\ncount = 8\n[contact]\nradius = 0.0\n",
    );
    let cache = dir.path().join("cache");
    let run = |out: &str| {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_ves"))
            .args(["precompute", scene.to_str().unwrap(), "--force", "-o"])
            .arg(dir.path().join(out))
            .env("VES_CACHE_DIR", &cache)
            .env("VES_LOG", "info")
            .output()
            .expect("ves runs");
        assert!(o.status.success(), "{}", stderr(&o));
        stderr(&o).matches("mesh cache hit").count()
    };
    assert_eq!(run("fresh.h5"), 0);
    assert_eq!(run("cached.h5"), 1);
    let load = |f: &str, surface_only| {
        ves_runtime::basis::load(
            &dir.path().join(f),
            &ves_runtime::basis::LoadOptions {
                surface_only,
                ..Default::default()
            },
        )
        .unwrap_or_else(|e| panic!("{e}"))
    };
    let fresh = load("fresh.h5", false);
    let cached = load("cached.h5", false);
    let tags = fresh.surface_faces.clone().expect("the basis has surface_faces");
    assert_eq!(tags.len(), fresh.triangles.len());
    assert_eq!(cached.surface_faces.as_ref(), Some(&tags));
    assert_eq!(cached.triangles, fresh.triangles);
    let mut distinct = tags.clone();
    distinct.sort_unstable();
    distinct.dedup();
    assert_eq!(distinct, (1..=6).collect::<Vec<u32>>());
    let surface = load("cached.h5", true);
    assert_eq!(
        surface.surface_faces.as_ref(),
        Some(&tags),
        "surface_only keeps every triangle's tag"
    );
    // Face 1's vertices are held, and only vertices on face-1 triangles are.
    let on1: std::collections::BTreeSet<u32> = surface
        .triangles
        .iter()
        .zip(&tags)
        .filter(|(_, t)| **t == 1)
        .flat_map(|(f, _)| f.iter().copied())
        .collect();
    let held: std::collections::BTreeSet<u32> = (0..surface.fixed.len() as u32)
        .filter(|&v| surface.fixed[v as usize] == 7)
        .collect();
    assert_eq!(held, on1);
}
