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
        println!(
            "{name}: largest residual, removed {} and sliding {}",
            a["spaces"][0]["max_relative_residual"], b["spaces"][0]["max_relative_residual"]
        );
        for (i, (x, y)) in frequencies(&a).iter().zip(frequencies(&b)).enumerate() {
            let rel = (y - x) / x;
            println!("{name}, mode {i}: removed {x:.4} Hz, sliding {y:.4} Hz ({rel:+.2e})");
            assert!(rel.abs() < 1e-3, "{name}, mode {i}: {x} against {y}");
        }
    }
}

/// The rigid motions a basis says its supports leave free (`rigid/free_motions`, twists (v, ω)
/// about the centre of mass), or `None` when the file stores none.
fn free_motions(basis: &std::path::Path) -> Option<Vec<[f64; 6]>> {
    let f = hdf5::File::open(basis).unwrap();
    let ds = f.dataset("spaces/global/rigid/free_motions").ok()?;
    let v: Vec<f64> = ds.read_raw().unwrap();
    Some(v.chunks_exact(6).map(|r| std::array::from_fn(|j| r[j])).collect())
}

/// How far each of `got` lies outside the span of the unit twists `want` (orthonormal),
/// relative to its length: 0 when the two span the same motions (same count).
fn outside_span(got: &[[f64; 6]], want: &[[f64; 6]]) -> f64 {
    assert_eq!(got.len(), want.len(), "{got:?} against {want:?}");
    got.iter()
        .map(|t| {
            let mut r = *t;
            for w in want {
                let d: f64 = r.iter().zip(w).map(|(a, b)| a * b).sum();
                r.iter_mut().zip(w).for_each(|(a, b)| *a -= d * b);
            }
            let norm = |x: &[f64; 6]| x.iter().map(|v| v * v).sum::<f64>().sqrt();
            norm(&r) / norm(t)
        })
        .fold(0.0, f64::max)
}

/// The beam held by sliding root and bottom faces may only slide along y. In a session under
/// gravity (on by default when a part can move) the supports carry its 385 N weight: a hand
/// holding a point of its top face still feels nothing. Before, a part held in some directions
/// was simulated as a wholly free body, and it hung from the hand (the device's whole 10 N).
#[test]
fn a_part_held_in_some_directions_moves_only_along_the_others() {
    let fixed = "[[fixed]]\nplane = { axis = \"x\", value = 0.0 }\nkind = \"sliding\"\n\
                 [[fixed]]\nplane = { axis = \"z\", value = 0.0 }\nkind = \"sliding\"\n";
    let (dir, path) = workdir(&beam(fixed, 4));
    let basis = dir.path().join("slides.h5");
    let got = precompute_json(&path, &basis);
    assert_eq!(got["spaces"][0]["rigid_modes_dropped"], 1);
    let free = free_motions(&basis).expect("rigid/free_motions stored");
    let off = outside_span(&free, &[[0.0, 1.0, 0.0, 0.0, 0.0, 0.0]]);
    println!("free motion {:?}: {off:.1e} outside the slide along y", free[0]);
    assert!(off < 1e-6, "{free:?}");
    let script = dir.path().join("hold.csv");
    std::fs::write(&script, "t,x,y,z,button\n0,0.7,0.05,0.05,1\n0.5,0.7,0.05,0.05,1\n").unwrap();
    let v = session_json_with(&basis, &script, &["--no-realtime"]);
    let hand = numbers(&v["final_forces_n"][0]);
    let felt = hand.iter().map(|f| f * f).sum::<f64>().sqrt();
    println!("the hand holding still feels {felt:.2e} N ({hand:?})");
    assert!(felt < 0.01, "the hand carries the part: {hand:?}");
    // Pulled 2 cm along y and held there, it slides after the hand (held, the coupling would
    // pull with 500 N/m × 2 cm = 10 N for ever); the momenta's damping settles it.
    std::fs::write(
        &script,
        "t,x,y,z,button\n0,0.7,0.05,0.05,1\n0.5,0.7,0.07,0.05,1\n12,0.7,0.07,0.05,1\n",
    )
    .unwrap();
    let v = session_json_with(&basis, &script, &["--no-realtime"]);
    let hand = numbers(&v["final_forces_n"][0]);
    println!("pulled 2 cm along y and held, the hand feels {hand:?} N");
    assert!(hand.iter().all(|f| f.abs() < 0.5), "it did not slide: {hand:?}");
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
/// f = π/(2S²)·√(EI/ρA) over the span S between the bearings' middles (0.486 m). With the first
/// bearing located (`located = true`: its ring's mean axial displacement held), one rigid motion
/// is left, the turn, and the bending is the same pinned beam's: the located bearing holds no
/// tilt.
#[test]
fn a_shaft_in_two_bearings_bends_as_a_pinned_beam() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("shaft.geo"),
        "SetFactory(\"OpenCASCADE\");\nCylinder(1) = {0, 0, 0, 500, 0, 0, 20};\n",
    )
    .unwrap();
    let bearing = |x0: f64, extra: &str| {
        format!(
            "[[fixed]]\nbox = {{ min = [{x0}, -0.03, -0.03], max = [{}, 0.03, 0.03] }}\nkind = \"bearing\"\n{extra}",
            x0 + 0.01
        )
    };
    let shaft = |name: &str, first: &str| {
        let scene = format!(
            "name = \"shaft\"\n[geometry]\nstep = \"shaft.geo\"\nunit = \"mm\"\n[material]\nyoung = 2.1e11\npoisson = 0.3\n\
             density = 7850.0\n[mesh]\nsize = 0.008\norder = 2\nerror_estimate = false\n{}{}[modes]\ncount = 2\n",
            bearing(0.002, first),
            bearing(0.488, "")
        );
        let path = write_file(dir.path(), &format!("{name}.toml"), &scene);
        let out = dir.path().join(format!("{name}.h5"));
        let got = precompute_json_with(&path, &out, &["--allow-geo-scripts"]);
        (got, out)
    };
    let (e, rho, d, span) = (2.1e11f64, 7850.0f64, 0.04f64, 0.486f64);
    let want = std::f64::consts::PI / (2.0 * span * span) * (e / rho).sqrt() * d / 4.0;
    let pinned = |got: &serde_json::Value| {
        for (i, g) in frequencies(got).iter().enumerate() {
            let rel = (g - want) / want;
            println!("bending {i}: {g:.2} Hz against the pinned beam's {want:.2} Hz ({rel:+.2e})");
            assert!((0.0..0.2).contains(&rel), "mode {i}: {g} Hz against {want} Hz");
        }
    };
    let (got, out) = shaft("floating", "");
    assert_eq!(got["spaces"][0]["rigid_modes_dropped"], 2, "{got}");
    // What is free: the slide along the axis and the turn about it (the centre of mass is on
    // the axis, so both twists are pure).
    let free = free_motions(&out).expect("rigid/free_motions stored");
    let axis = [[1.0, 0.0, 0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0, 0.0, 0.0]];
    let off = outside_span(&free, &axis);
    println!("free motions {free:?}: {off:.1e} outside the slide along and the turn about x");
    assert!(off < 1e-3, "{free:?}");
    // `ves info` names them as an engineer would: a slide along the axis and a turn about it,
    // the axis through y = z = 0.
    let info = last_json(&ves(&["info", out.to_str().unwrap(), "--json"]));
    let motions = &info["spaces"][0]["free_motions"];
    println!("ves info: {motions}");
    let along_x = |m: &serde_json::Value| (numbers(&m["direction"])[0].abs() - 1.0).abs() < 1e-3;
    assert_eq!(motions[0]["kind"], "slide", "{motions}");
    assert!(along_x(&motions[0]), "{motions}");
    assert_eq!(motions[1]["kind"], "turn", "{motions}");
    assert!(along_x(&motions[1]), "{motions}");
    let point = numbers(&motions[1]["point"]);
    assert!(
        point[1].abs() < 1e-4 && point[2].abs() < 1e-4,
        "the axis through {point:?}"
    );
    let text = String::from_utf8_lossy(&ves(&["info", out.to_str().unwrap()]).stdout).into_owned();
    assert!(
        text.contains("free to slide along") && text.contains(" and turn about "),
        "{text}"
    );
    pinned(&got);
    // Located: the slide is held, the turn left, the bending as pinned.
    let (located, out) = shaft("located", "located = true\n");
    assert_eq!(located["spaces"][0]["rigid_modes_dropped"], 1, "{located}");
    let free = free_motions(&out).expect("rigid/free_motions stored");
    let off = outside_span(&free, &axis[1..]);
    println!("located: free motion {free:?}, {off:.1e} outside the turn about x");
    assert!(off < 1e-3, "{free:?}");
    pinned(&located);
    for (f, l) in frequencies(&got).iter().zip(frequencies(&located)) {
        assert!(((l - f) / f).abs() < 0.01, "located {l} Hz against floating {f} Hz");
    }
}

/// What each support carries while a hand pushes (`support_reactions` of `ves session --json`):
/// a beam clamped at both ends, pressed at mid-span until it settles. By symmetry the two ends
/// carry half each; together they carry the hand's whole force (the modes' reactions with the
/// share the 20 modes leave out, 10 % here, added back from the supports' influence
/// coefficients), and each end's moment about its face centre is the clamped–clamped beam's end
/// moment F·L/8 (measured within 0.4 %; opposite signs at the two ends).
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
    // The modes alone carried 0.90 (the contact's local deformation is in the modes left out);
    // the influence coefficients add back the rest, so a load held steady is carried whole.
    let carried = -(a[2] + b[2]) / pushed;
    assert!(
        (carried - 1.0).abs() < 1e-4,
        "the ends carry {carried:.6} of the hand's force"
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
        assert_eq!(support["corrected"], true, "{support}");
    }
}

/// The supports' influence coefficients (`modes/support_influence`, from constraint modes by
/// Betti's theorem) against the static solve of a load case: a 4-node beam clamped at its root
/// and on an elastic mount at its tip, a force spread over its top face. Summed over the face's
/// nodal loads (a third of each triangle's share at each corner), the coefficients give what
/// each support carries as the load case's own solve does (K u − f at the held DOFs, the
/// springs' forces): to 1e-8 of the load.
#[test]
fn influence_coefficients_give_each_support_its_load_case_reaction() {
    let (force, top) = ([0.0, 300.0, -1000.0], 0.05);
    let fixed = "[[fixed]]\nplane = { axis = \"x\", value = 0.0 }\n[[fixed]]\nplane = { axis = \"x\", value = 1.0 }\n\
                 kind = \"elastic\"\nstiffness = 1e10\n";
    let scene = GOOD
        .replace("[[fixed]]\nplane = { axis = \"x\", value = 0.0 }\n", fixed)
        .replace("order = 1", "order = 1\nerror_estimate = false")
        + &format!(
            "[[load]]\nname = \"top\"\nplane = {{ axis = \"z\", value = {top} }}\nforce = [{}, {}, {}]\n",
            force[0], force[1], force[2]
        );
    let (dir, path) = workdir(&scene);
    let out = dir.path().join("beam.h5");
    let summary = precompute_json(&path, &out);
    let file = ves_format::BasisReader::open(&out).unwrap();
    let s = file.space("global").unwrap();
    let nodes = s.nodes(s.node_count).unwrap();
    let (rows, g) = s
        .support_influence()
        .unwrap()
        .expect("two supports: influence coefficients");
    assert_eq!(g.len(), rows.len() * 36);
    let row_of: std::collections::HashMap<u32, usize> = rows.iter().enumerate().map(|(i, &v)| (v, i)).collect();
    // The top face's nodal loads: the traction F/A, a third of each triangle's share per corner.
    let on_top = |t: &[u32; 3]| t.iter().all(|&v| (nodes[v as usize][2] - top).abs() < 1e-9);
    let area = |t: &[u32; 3]| {
        let [a, b, c] = t.map(|v| nodes[v as usize]);
        let (u, w) = ([0, 1, 2].map(|k| b[k] - a[k]), [0, 1, 2].map(|k| c[k] - a[k]));
        0.5 * (u[1] * w[2] - u[2] * w[1])
            .hypot(u[2] * w[0] - u[0] * w[2])
            .hypot(u[0] * w[1] - u[1] * w[0])
    };
    let triangles: Vec<[u32; 3]> = s.surface_triangles().unwrap().into_iter().filter(on_top).collect();
    let total: f64 = triangles.iter().map(area).sum();
    assert!((total - 0.1).abs() < 1e-9, "the top face is 1.0 × 0.1 m: {total}");
    let mut carried = [[0.0; 6]; 2];
    for t in &triangles {
        let share = area(t) / total / 3.0;
        for v in t {
            let row = &g[row_of[v] * 36..row_of[v] * 36 + 36];
            for (k, support) in carried.iter_mut().enumerate() {
                for (c, value) in support.iter_mut().enumerate() {
                    *value += (0..3).map(|d| row[(6 * k + c) * 3 + d] * force[d] * share).sum::<f64>();
                }
            }
        }
    }
    let case = &summary["spaces"][0]["loads"][0]["support_reactions"];
    let load = force.iter().map(|f| f * f).sum::<f64>().sqrt();
    for (k, support) in carried.iter().enumerate() {
        let solved: Vec<f64> = numbers(&case[k]["force_n"])
            .into_iter()
            .chain(numbers(&case[k]["moment_nm"]))
            .collect();
        println!("support {k}: influence {support:?}, load case {solved:?}");
        for c in 0..6 {
            assert!(
                (support[c] - solved[c]).abs() < 1e-8 * load,
                "support {k}, component {c}: {} against the solve's {}",
                support[c],
                solved[c]
            );
        }
    }
    // Both carry a real share: the elastic tip is not a bystander.
    assert!(carried[1][2] > 0.1 * load, "{carried:?}");
    // `ves info` says so.
    let info = ves(&["info", out.to_str().unwrap(), "--json"]);
    let info: serde_json::Value = serde_json::from_slice(&info.stdout).expect("info JSON");
    let supports = &info["spaces"][0]["supports"];
    assert_eq!(supports["count"], 2, "{info}");
    assert_eq!(
        supports["influence_vertices"].as_u64(),
        Some(rows.len() as u64),
        "{info}"
    );
    assert_eq!(supports["carried_whole"], true, "{info}");
    let text = String::from_utf8_lossy(&ves(&["info", out.to_str().unwrap()]).stdout).to_string();
    assert!(
        text.contains(&format!(
            "2 supports: a hand's load carried whole (influence coefficients at {} vertices)",
            rows.len()
        )),
        "{text}"
    );
}
