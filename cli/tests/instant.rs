//! Instant bases (`ves precompute --instant-from`, what `ves view` serves the moment the
//! supports change): the previous basis's mesh, modes from a few block solves. Against the
//! converged solve of the same scene on the same mesh: every frequency at or above it, within
//! its bound, and within 0.1 %; a changed mesh refused in one line.

mod common;

use common::*;

/// The cantilever (1.0 × 0.1 × 0.05 m steel) with 10-node tets, held as `fixed` says, 8 modes.
fn beam(fixed: &str) -> String {
    GOOD.replace(
        "size = 0.05\norder = 1",
        "size = 0.05\norder = 2\nerror_estimate = false",
    )
    .replace("[[fixed]]\nplane = { axis = \"x\", value = 0.0 }\n", fixed)
    .replace("count = 4", "count = 8")
}

const ROOT: &str = "[[fixed]]\nplane = { axis = \"x\", value = 0.0 }\n";
const TIP: &str = "[[fixed]]\nplane = { axis = \"x\", value = 1.0 }\n";
const SIDE_Z: &str = "[[fixed]]\nplane = { axis = \"y\", value = 0.0 }\ncomponents = [\"z\"]\n";

#[test]
fn instant_bases_match_the_converged_solve_within_their_bounds() {
    let (dir, root) = workdir(&beam(ROOT));
    let previous = dir.path().join("root.h5");
    precompute_json(&root, &previous);
    for (name, fixed) in [
        ("tip", TIP.to_string()),
        ("both", format!("{ROOT}{TIP}")),
        ("free", String::new()),
        ("side", SIDE_Z.to_string()),
    ] {
        let scene = write_file(dir.path(), &format!("{name}.toml"), &beam(&fixed));
        let exact = precompute_json(&scene, &dir.path().join(format!("{name}.h5")));
        let out = dir.path().join(format!("{name}-instant.h5"));
        let got = instant_within_bounds(name, &scene, &previous, &out, &exact, 1e-3);
        assert_eq!(
            got["spaces"][0]["rigid_modes_dropped"], exact["spaces"][0]["rigid_modes_dropped"],
            "{name}"
        );
        // The file is a basis like any other: `ves info` reads and checks it whole.
        let info = ves(&["info", out.to_str().unwrap(), "--json"]);
        assert!(info.status.success(), "{name}: {}", stderr(&info));
        // Held by both ends, the instant basis carries a hand's load whole at once: the
        // supports' influence coefficients come from its search's own factor of K, the same
        // as the converged basis's.
        let influence = |path: &std::path::Path| -> Option<Vec<f64>> {
            let f = ves_format::file::open(path).unwrap();
            let g = f.group("spaces/global").unwrap();
            g.dataset("modes/support_influence").ok().map(|d| d.read_raw().unwrap())
        };
        let (a, b) = (influence(&out), influence(&dir.path().join(format!("{name}.h5"))));
        assert_eq!(a.is_some(), name == "both", "{name}: instant influence {}", a.is_some());
        assert_eq!(
            b.is_some(),
            name == "both",
            "{name}: converged influence {}",
            b.is_some()
        );
        if let (Some(a), Some(b)) = (a, b) {
            let top = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let off = a.iter().zip(&b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs())) / top;
            println!("{name}: influence coefficients instant against converged, {off:.1e} of the largest");
            assert!(a.len() == b.len() && off < 1e-9, "{name}: {off:.1e}");
        }
    }
    // Another mesh size: no instant basis, said in one line, nothing written.
    let finer = write_file(
        dir.path(),
        "finer.toml",
        &beam(TIP).replace("size = 0.05", "size = 0.04"),
    );
    let out = dir.path().join("finer-instant.h5");
    let o = ves(&[
        "precompute",
        finer.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--instant-from",
        previous.to_str().unwrap(),
    ]);
    assert_refused(&o, "[mesh] changed");
    assert!(!out.exists());
}

/// Writes `out`, the instant basis of `scene` from `previous`, and checks every frequency
/// against `exact`'s (the converged solve on the same mesh): at or above it, within its bound,
/// and within `within`. Returns the instant run's `--json`.
fn instant_within_bounds(
    name: &str,
    scene: &std::path::Path,
    previous: &std::path::Path,
    out: &std::path::Path,
    exact: &serde_json::Value,
    within: f64,
) -> serde_json::Value {
    let got = precompute_json_with(scene, out, &["--instant-from", previous.to_str().unwrap()]);
    let (want, have) = (frequencies(exact), frequencies(&got));
    assert_eq!(want.len(), have.len(), "{name}");
    let bounds = numbers(&got["instant"]["frequency_bound"]);
    for (i, ((w, h), b)) in want.iter().zip(&have).zip(&bounds).enumerate() {
        let err = (h - w) / w;
        assert!(err > -1e-8, "{name} mode {i}: {h} Hz below the converged {w} Hz");
        assert!(
            err <= 1.01 * b + 1e-9,
            "{name} mode {i}: {err:.2e} above its bound {b:.2e}"
        );
        assert!(err < within, "{name} mode {i}: {err:.2e}");
    }
    got
}

/// The trace of the felt 3×3 point compliance Σ φφᵀ/λ at each of `nodes` (the modes kept).
fn point_compliance(basis: &std::path::Path, nodes: &[usize]) -> Vec<f64> {
    let f = ves_format::file::open(basis).unwrap();
    let g = f.group("spaces/global").unwrap();
    let lambda: Vec<f64> = g.dataset("modes/eigenvalues").unwrap().read_raw().unwrap();
    let phi: ndarray::Array2<f64> = g.dataset("modes/basis").unwrap().read_2d().unwrap();
    nodes
        .iter()
        .map(|&i| {
            (0..3)
                .flat_map(|c| lambda.iter().enumerate().map(move |(j, l)| (3 * i + c, j, l)))
                .map(|(row, j, l)| phi[[row, j]].powi(2) / l)
                .sum()
        })
        .collect()
}

/// A corpus part nobody tuned for (the block with two counterbored holes, 10-node tets), from
/// its free-body basis — the page's starting scene — to held by its largest flat face, and to
/// held in both holes as bearings (spring supports: a shift set from the start's Rayleigh
/// quotients, which the bearings' springs make huge, once missed 11 of the 12 modes): every
/// frequency within its bound and 1e-4 of the exact solve on the same mesh, and the felt
/// compliance at the most compliant surface points within 1e-3.
#[test]
fn instant_bases_of_a_corpus_part_held_anew_match_the_exact_solve() {
    let step = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../cases/corpus/pmi_block_2holes.step");
    let part = |fixed: &str| {
        format!(
            "[geometry]\nstep = {:?}\nunit = \"mm\"\n[material]\nyoung = 2.1e11\npoisson = 0.3\ndensity = 7850.0\n\
             [mesh]\nsize = 1.5e-3\norder = 2\nerror_estimate = false\n{fixed}[modes]\ncount = 12\n",
            step.to_str().unwrap()
        )
    };
    let (dir, free) = workdir(&part(""));
    let previous = dir.path().join("free.h5");
    precompute_json(&free, &previous);
    // Face tags as gmsh numbers this file's faces (the largest plane; the two halves of each hole).
    for (name, fixed) in [
        ("face", "[[fixed]]\nfaces = [4]\n"),
        (
            "bearings",
            "[[fixed]]\nfaces = [24, 25]\nkind = \"bearing\"\n[[fixed]]\nfaces = [27, 28]\nkind = \"bearing\"\n",
        ),
    ] {
        let scene = write_file(dir.path(), &format!("{name}.toml"), &part(fixed));
        let exact_h5 = dir.path().join(format!("{name}.h5"));
        let exact = precompute_json(&scene, &exact_h5);
        let out = dir.path().join(format!("{name}-instant.h5"));
        instant_within_bounds(name, &scene, &previous, &out, &exact, 1e-4);
        // The three most compliant nodes of the exact basis, and one of median compliance.
        let nodes = exact["spaces"][0]["nodes"].as_u64().unwrap() as usize;
        let all = point_compliance(&exact_h5, &(0..nodes).collect::<Vec<_>>());
        let mut order: Vec<usize> = (0..nodes).filter(|&i| all[i] > 0.0).collect();
        order.sort_by(|&a, &b| all[b].total_cmp(&all[a]));
        let picked = [order[0], order[1], order[2], order[order.len() / 2]];
        let instant = point_compliance(&out, &picked);
        for (k, &i) in picked.iter().enumerate() {
            let err = (instant[k] / all[i] - 1.0).abs();
            assert!(err < 1e-3, "{name} node {i}: compliance {err:.2e} from the exact");
        }
    }
}

/// Another material of the same Poisson's ratio on the same mesh and supports (steel to an
/// aluminium of ν = 0.3): the previous modes scaled exactly (λ by E'/E·ρ/ρ', φ by √(ρ/ρ')), no
/// solve at all, the frequencies those of the converged solve to 1e-9; another ν searches.
#[test]
fn a_new_material_rescales_the_modes_without_a_solve() {
    let (dir, root) = workdir(&beam(ROOT));
    let previous = dir.path().join("steel.h5");
    precompute_json(&root, &previous);
    let aluminium = beam(ROOT)
        .replace("young = 2.1e11", "young = 7.0e10")
        .replace("density = 7850.0", "density = 2700.0");
    let scene = write_file(dir.path(), "aluminium.toml", &aluminium);
    let exact = precompute_json(&scene, &dir.path().join("aluminium.h5"));
    let out = dir.path().join("aluminium-instant.h5");
    let got = instant_within_bounds("aluminium", &scene, &previous, &out, &exact, 1e-9);
    assert_eq!(got["instant"]["solves"], 0, "{got}");
    let other = write_file(
        dir.path(),
        "nu.toml",
        &aluminium.replace("poisson = 0.3", "poisson = 0.33"),
    );
    let exact = precompute_json(&other, &dir.path().join("nu.h5"));
    let got = instant_within_bounds("nu", &other, &previous, &dir.path().join("nu-instant.h5"), &exact, 1e-3);
    assert!(got["instant"]["solves"].as_u64() > Some(0), "{got}");
}

/// A load added to a computed part (the page's "+ load on faces…" and "+ gravity" on a held
/// beam): the instant basis rescales the modes without a solve and answers each load case
/// exactly as `ves precompute` of the same scene does — the same largest displacement and von
/// Mises stress, balanced by the reaction.
#[test]
fn a_load_added_is_answered_by_the_instant_basis() {
    let (dir, root) = workdir(&beam(ROOT));
    let previous = dir.path().join("root.h5");
    precompute_json(&root, &previous);
    let loaded = beam(ROOT).replace(
        "[modes]",
        "[[load]]\nname = \"tip\"\nplane = { axis = \"x\", value = 1.0 }\nforce = [0.0, 0.0, -1000.0]\n\
         [gravity]\nacceleration = [0.0, 0.0, -9.81]\n[modes]",
    );
    let scene = write_file(dir.path(), "loaded.toml", &loaded);
    let exact = precompute_json(&scene, &dir.path().join("loaded.h5"));
    let got = instant_within_bounds(
        "loaded",
        &scene,
        &previous,
        &dir.path().join("loaded-instant.h5"),
        &exact,
        1e-9,
    );
    assert_eq!(got["instant"]["solves"], 0, "{got}");
    let cases = |v: &serde_json::Value| v["spaces"][0]["loads"].as_array().cloned().unwrap_or_default();
    let (want, have) = (cases(&exact), cases(&got));
    assert_eq!(want.len(), 2, "{exact}");
    assert_eq!(have.len(), 2, "{got}");
    for (w, h) in want.iter().zip(&have) {
        assert_eq!(w["name"], h["name"]);
        for key in ["max_displacement_m", "max_von_mises_pa"] {
            let (a, b) = (w[key].as_f64().unwrap(), h[key].as_f64().unwrap());
            assert!((a / b - 1.0).abs() < 1e-9, "{} {key}: {b} against {a}", w["name"]);
        }
        assert!(h["balance_residual"].as_f64().unwrap() < 1e-9, "{h}");
    }
}
