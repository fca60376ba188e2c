//! Support kinds (`[[fixed]] kind`, docs/scene.md): a sliding face against removing the same
//! component, a part on soft elastic mounts against its rigid-body frequencies on springs, and
//! a shaft in two bearings against the pinned–pinned beam.

mod common;

use common::*;

/// The cantilever with 10-node tets held as `fixed` says, `count` modes.
fn beam(fixed: &str, count: usize) -> String {
    GOOD.replace(
        "size = 0.05\norder = 1",
        "size = 0.025\norder = 2\nerror_estimate = false",
    )
    .replace("[[fixed]]\nplane = { axis = \"x\", value = 0.0 }\n", fixed)
    .replace("count = 4", &format!("count = {count}"))
}

/// Sliding faces (held along their normals by stiff springs) against the same faces' normal
/// components removed: the root face alone leaves three rigid motions; the root and the bottom
/// face leave one (sliding along y: each face blocks the turns its normal motion would take),
/// and the same modes to 1e-3.
#[test]
fn a_sliding_face_holds_its_normal_as_removing_it_does() {
    let root = |how: &str| format!("[[fixed]]\nplane = {{ axis = \"x\", value = 0.0 }}\n{how}\n");
    let bottom = |how: &str| format!("[[fixed]]\nplane = {{ axis = \"z\", value = 0.0 }}\n{how}\n");
    for (name, removed, sliding, rigid) in [
        ("root", root("components = [\"x\"]"), root("kind = \"sliding\""), 3),
        (
            "root and bottom",
            root("components = [\"x\"]") + &bottom("components = [\"z\"]"),
            root("kind = \"sliding\"") + &bottom("kind = \"sliding\""),
            1,
        ),
    ] {
        let (dir, exact) = workdir(&beam(&removed, 6));
        let slid = write_file(dir.path(), "sliding.toml", &beam(&sliding, 6));
        let a = precompute_json(&exact, &dir.path().join("exact.h5"));
        let b = precompute_json(&slid, &dir.path().join("sliding.h5"));
        assert_eq!(a["spaces"][0]["rigid_modes_dropped"], rigid, "{name}");
        assert_eq!(b["spaces"][0]["rigid_modes_dropped"], rigid, "{name}");
        for (i, (x, y)) in frequencies(&a).iter().zip(frequencies(&b)).enumerate() {
            let rel = (y - x) / x;
            println!("{name}, mode {i}: removed {x:.4} Hz, sliding {y:.4} Hz ({rel:+.2e})");
            assert!(rel.abs() < 1e-3, "{name}, mode {i}: {x} against {y}");
        }
    }
}

/// The beam (1.0 × 0.1 × 0.05 m steel, 39.25 kg) on soft springs along z under its whole bottom
/// face: x, y and the turn about z stay free (3 rigid motions); the first three modes are the
/// rigid body on the springs, ω² = kA/m × b²/(b² + h²) (roll about x, about the centre of mass:
/// the horizontal motion is free), × L²/(L² + h²) (pitch), × 1 (bounce).
#[test]
fn a_part_on_soft_mounts_rocks_and_bounces_at_the_rigid_body_frequencies() {
    let (m, a, b, h, l) = (7850.0 * 0.005, 0.1, 0.1, 0.05, 1.0);
    let k = 1e6; // N/m³: ~16 Hz, far below the free beam's first bending (~260 Hz).
    let fixed = format!(
        "[[fixed]]\nplane = {{ axis = \"z\", value = 0.0 }}\nkind = \"elastic\"\nstiffness = {k:e}\ncomponents = [\"z\"]\n"
    );
    let (dir, path) = workdir(&beam(&fixed, 3));
    let got = precompute_json(&path, &dir.path().join("mounts.h5"));
    assert_eq!(got["spaces"][0]["rigid_modes_dropped"], 3);
    let w = |factor: f64| (k * a / m * factor).sqrt() / (2.0 * std::f64::consts::PI);
    let want = [w(b * b / (b * b + h * h)), w(l * l / (l * l + h * h)), w(1.0)];
    for (i, (g, x)) in frequencies(&got).iter().zip(want).enumerate() {
        let rel = (g - x) / x;
        println!("mode {i}: {g:.4} Hz against {x:.4} Hz ({rel:+.2e})");
        assert!(rel.abs() < 5e-3, "mode {i}: {g} Hz against {x} Hz");
    }
}

/// A steel shaft (0.5 m, 40 mm across) in two 10 mm bearings at its ends: two rigid motions
/// left (the turn about its axis and the slide along it: floating bearings), and the first
/// bending pair at the pinned–pinned beam's
/// f = π/(2S²)·√(EI/ρA) over the span S between the bearings' middles (0.486 m).
#[test]
fn a_shaft_in_two_bearings_bends_as_a_pinned_beam() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("shaft.geo"),
        "SetFactory(\"OpenCASCADE\");\nCylinder(1) = {0, 0, 0, 500, 0, 0, 20};\n",
    )
    .unwrap();
    let bearing = |x0: f64| {
        format!(
            "[[fixed]]\nbox = {{ min = [{x0}, -0.03, -0.03], max = [{}, 0.03, 0.03] }}\nkind = \"bearing\"\n",
            x0 + 0.01
        )
    };
    let scene = format!(
        "name = \"shaft\"\n[geometry]\nstep = \"shaft.geo\"\nunit = \"mm\"\n[material]\nyoung = 2.1e11\npoisson = 0.3\n\
         density = 7850.0\n[mesh]\nsize = 0.008\norder = 2\nerror_estimate = false\n{}{}[modes]\ncount = 2\n",
        bearing(0.002),
        bearing(0.488)
    );
    let path = write_file(dir.path(), "shaft.toml", &scene);
    let out = dir.path().join("shaft.h5");
    let got = precompute_json_with(&path, &out, &["--allow-geo-scripts"]);
    assert_eq!(got["spaces"][0]["rigid_modes_dropped"], 2, "{got}");
    let (e, rho, d, span) = (2.1e11f64, 7850.0f64, 0.04f64, 0.486f64);
    let want = std::f64::consts::PI / (2.0 * span * span) * (e / rho).sqrt() * d / 4.0;
    for (i, g) in frequencies(&got).iter().enumerate() {
        let rel = (g - want) / want;
        println!("bending {i}: {g:.2} Hz against the pinned beam's {want:.2} Hz ({rel:+.2e})");
        assert!((0.0..0.2).contains(&rel), "mode {i}: {g} Hz against {want} Hz");
    }
}

/// What each support carries while a hand pushes (`support_reactions` of `ves session --json`):
/// a beam clamped at both ends, pressed at mid-span until it settles. By symmetry the two ends
/// carry half each; together they carry the hand's force less what the modes left out carry
/// (the static response's part outside the first 20 modes: 10 % here), and each end's moment
/// about its face centre is the clamped–clamped beam's end moment F·L/8 (measured within 1 %;
/// opposite signs at the two ends).
#[test]
fn the_supports_carry_the_hands_force_in_a_session() {
    let ends = "[[fixed]]\nplane = { axis = \"x\", value = 0.0 }\n[[fixed]]\nplane = { axis = \"x\", value = 1.0 }\n";
    let scene = beam(ends, 20).replace("[modes]", "[damping]\nalpha = 2000.0\n[modes]");
    let (dir, path) = workdir(&scene);
    let basis = dir.path().join("beam.h5");
    precompute_json(&path, &basis);
    let script = dir.path().join("press.csv");
    std::fs::write(
        &script,
        "t,x,y,z,button\n0,0.5,0.05,0.05,1\n0.05,0.5,0.05,0.0495,1\n0.6,0.5,0.05,0.0495,1\n",
    )
    .unwrap();
    let v = session_json_with(&basis, &script, &["--no-realtime"]);
    let hand = numbers(&v["final_forces_n"][0]);
    let supports = v["support_reactions"].as_array().expect("support_reactions");
    assert_eq!(supports.len(), 2, "{v}");
    let force = |k: usize| numbers(&supports[k]["final_force_n"]);
    let moment = |k: usize| numbers(&supports[k]["final_moment_nm"]);
    let (a, b) = (force(0), force(1));
    // The force on the part from the hand is −(force on the device).
    let pushed = -hand[2];
    assert!(pushed < 0.0, "the hand pushes down: {hand:?}");
    // 0.90 measured: the contact's local deformation is in the modes left out.
    let carried = -(a[2] + b[2]) / pushed;
    assert!(
        (0.85..=1.001).contains(&carried),
        "the ends carry {carried:.3} of the hand's force"
    );
    assert!((a[2] / b[2] - 1.0).abs() < 0.03, "ends {a:?} and {b:?}");
    let fl8 = pushed.abs() * 1.0 / 8.0;
    for (k, support) in supports.iter().enumerate() {
        let m = moment(k)[1].abs();
        assert!(
            (m / fl8 - 1.0).abs() < 0.05,
            "end {k}: |M_y| {m:.4} N·m against F·L/8 = {fl8:.4}"
        );
        assert!(support["force_max_n"].as_f64().unwrap() >= force(k)[2].abs() * 0.999);
    }
}
