//! Real parts from other people's CAD systems at default settings: 10-node tets of a size 1/15
//! of the part's largest extent, clamped over its lowest 3 % along x, 10 modes. Every element
//! must be valid (scaled Jacobian > 0 everywhere it is sampled, checked on the file written),
//! every residual ≤ 1e-8, and the modes must equal scikit-fem's on the same (curved) mesh to its
//! tolerance for curved elements, 1e-4 (see `verify::Tolerances::resolve`).
//!
//! CI runs the three parts in `cases/corpus/` (copies); `VES_CORPUS=DIR` runs every `*.step` of DIR
//! (absolute, or relative to the workspace root) and prints a table row per part.

mod common;

use common::{number_after, stderr, ves};
use std::path::{Path, PathBuf};
use ves_pipeline::mesh::quality::min_scaled_jacobian;
use ves_pipeline::scene::Scene;

/// The default scene of a part, its clamp placed from the part's real (meshed) extent.
fn default_scene(step: &Path, dir: &Path) -> PathBuf {
    let name = step.file_stem().and_then(|s| s.to_str()).expect("a name");
    let text = |size: f64, clamp: &str| {
        format!(
            "name = \"{name}\"\n[geometry]\nstep = {:?}\nunit = \"mm\"\n[material]\nyoung = 2.1e11\npoisson = 0.3\n\
             density = 7850.0\n[mesh]\nsize = {size:e}\norder = 1\n{clamp}[modes]\ncount = 10\n",
            step.display().to_string()
        )
    };
    // OpenCASCADE's bounding box (mm, padded) sizes a first-order mesh, whose nodes give the
    // real extent.
    let path = step.to_path_buf();
    let (lo, hi) = ves_gmsh::on_gmsh_thread(move || {
        let g = ves_gmsh::Gmsh::start()?;
        g.set_string("Geometry.OCCTargetUnit", "MM")?;
        g.open(&path)?;
        g.bounding_box()
    })
    .unwrap_or_else(|e| panic!("{name}: {e}"));
    let padded = (0..3).map(|c| hi[c] - lo[c]).fold(0.0, f64::max) * 1e-3;
    let probe = dir.join(format!("{name}-probe.toml"));
    std::fs::write(&probe, text(padded / 15.0, "")).expect("write");
    let scene = Scene::load(&probe).expect("probe scene");
    let (mesh, _) = ves_pipeline::mesh::generate(&scene, None).unwrap_or_else(|e| panic!("{name}: {e}"));
    let (lo, hi) = mesh.bounding_box();
    let l = (0..3).map(|c| hi[c] - lo[c]).fold(0.0, f64::max);
    let clamp = format!(
        "[[fixed]]\nbox = {{ min = [{:e}, {:e}, {:e}], max = [{:e}, {:e}, {:e}] }}\n",
        lo[0] - 0.01 * l,
        lo[1] - 0.01 * l,
        lo[2] - 0.01 * l,
        lo[0] + 0.03 * l,
        hi[1] + 0.01 * l,
        hi[2] + 0.01 * l
    );
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, text(l / 15.0, &clamp).replace("order = 1", "order = 2")).expect("write");
    path
}

/// Precomputes one part and checks it; returns a table row.
fn check_part(step: &Path, dir: &Path, verify: bool) -> Result<String, String> {
    let name = step.file_stem().and_then(|s| s.to_str()).unwrap_or("part").to_string();
    let scene = default_scene(step, dir);
    let out = dir.join(format!("{name}.h5"));
    let t = std::time::Instant::now();
    let o = ves(&[
        "precompute",
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--json",
    ]);
    let seconds = t.elapsed().as_secs_f64();
    if !o.status.success() {
        return Err(format!("{name}: {}", stderr(&o).trim()));
    }
    let stdout = String::from_utf8_lossy(&o.stdout);
    let v: serde_json::Value = serde_json::from_str(stdout.lines().last().unwrap_or("")).map_err(|e| e.to_string())?;
    let s = &v["spaces"][0];
    let residual = s["max_relative_residual"].as_f64().unwrap_or(f64::NAN);
    // Validity on what was written, recomputed independently of the pipeline's own check.
    let file = ves_format::BasisReader::open(&out).map_err(|e| e.to_string())?;
    let space = file.space("global").map_err(|e| e.to_string())?;
    let nodes = space.nodes(space.node_count).map_err(|e| e.to_string())?;
    let tets = space.tets().map_err(|e| e.to_string())?;
    let worst = tets
        .chunks_exact(10)
        .map(|t| {
            let x: Vec<[f64; 3]> = t.iter().map(|&n| nodes[n as usize]).collect();
            min_scaled_jacobian(&x)
        })
        .fold(f64::INFINITY, f64::min);
    let c = &s["meshing"];
    let row = format!(
        "| {name} | {} | {} | {} | {} | {} | {worst:.3} | {residual:.1e} | {:.1} | {seconds:.1} |",
        s["nodes"],
        s["tets"],
        c["distorted"],
        c["repaired_by_gmsh"],
        c["straightened"],
        s["frequencies_hz"][0].as_f64().unwrap_or(f64::NAN),
    );
    if worst.is_nan() || worst <= 0.0 {
        return Err(format!(
            "{name}: an element with scaled Jacobian {worst} was written\n{row}"
        ));
    }
    if residual.is_nan() || residual > 1e-8 {
        return Err(format!("{name}: largest relative residual {residual:e} > 1e-8\n{row}"));
    }
    if verify {
        let o = ves(&["verify", out.to_str().unwrap(), "--against", "scikit-fem", "--json"]);
        if !o.status.success() {
            return Err(format!(
                "{name}: scikit-fem disagrees or failed: {}\n{row}",
                stderr(&o).trim()
            ));
        }
    }
    Ok(row)
}

const HEADER: &str = "| part | nodes | tets | distorted after order 2 | repaired by gmsh | straightened | min scaled Jacobian | max residual | f1 (Hz) | wall (s) |\n|---|---|---|---|---|---|---|---|---|---|";

#[test]
fn corpus_parts_precompute_at_default_settings_with_valid_elements() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (parts, verify): (Vec<PathBuf>, bool) = match std::env::var_os("VES_CORPUS") {
        Some(d) => {
            // A relative path is taken from the workspace root, where the docs' command runs
            // (cargo runs the test in the crate's folder).
            let d = Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(d);
            let mut v: Vec<PathBuf> = std::fs::read_dir(&d)
                .unwrap_or_else(|e| panic!("VES_CORPUS = {}: {e}", d.display()))
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|x| x.eq_ignore_ascii_case("step")))
                .collect();
            v.sort();
            (v, std::env::var_os("VES_CORPUS_VERIFY").is_some())
        }
        None => {
            let cases = Path::new(env!("CARGO_MANIFEST_DIR")).join("../cases/corpus");
            let v = ["crankshaft", "pmi_block_2holes", "bracket_ribbed_ap209"]
                .map(|n| cases.join(format!("{n}.step")))
                .to_vec();
            (v, true)
        }
    };
    let mut rows = Vec::new();
    let mut failures = Vec::new();
    for p in &parts {
        match check_part(p, dir.path(), verify) {
            Ok(r) => rows.push(r),
            Err(e) => failures.push(e),
        }
    }
    eprintln!("{HEADER}\n{}", rows.join("\n"));
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// A thin-walled cover at a coarse size: gmsh fails on every rung of the meshing ladder (a PLC
/// error: the surface meshes of the wall's two sides cross). One line says so, where, and gives
/// the size it tried and that meshed; following it works, and the basis records the strategy
/// that made its mesh.
#[test]
fn a_part_no_rung_can_mesh_gets_advice_that_works() {
    let dir = tempfile::tempdir().expect("temp dir");
    let step = Path::new(env!("CARGO_MANIFEST_DIR")).join("../cases/corpus/thin_cone_cover.step");
    let scene = |size: f64| {
        let path = dir.path().join(format!("cone-{size}.toml"));
        std::fs::write(
            &path,
            format!(
                "name = \"cone\"\n[geometry]\nstep = {:?}\nunit = \"mm\"\n[material]\nyoung = 2.1e11\npoisson = 0.3\n\
                 density = 7850.0\n[mesh]\nsize = {size:e}\norder = 1\n[[fixed]]\nbox = {{ min = [0.05, -0.14, 0.22], \
                 max = [0.0565, 0.03, 0.36] }}\n[modes]\ncount = 4\n",
                step.display().to_string()
            ),
        )
        .expect("write");
        path
    };
    // 1/8 of the cover's 161 mm extent.
    let coarse = scene(0.020166);
    let o = ves(&["precompute", coarse.to_str().unwrap()]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("any of its 5 strategies") && err.contains("PLC"), "{err}");
    assert!(
        err.contains("crosses itself on CAD face") && err.contains("meshes it (tried)"),
        "{err}"
    );
    let advised = number_after(&err, "mesh.size = ");
    let out = dir.path().join("cone.h5");
    let o = ves(&[
        "precompute",
        scene(advised).to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--json",
    ]);
    assert!(o.status.success(), "following the advice: {}", stderr(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    let v: serde_json::Value = serde_json::from_str(stdout.lines().last().unwrap_or("")).expect("JSON");
    let strategy = v["spaces"][0]["meshing"]["strategy"]
        .as_str()
        .expect("strategy")
        .to_string();
    let file = ves_format::BasisReader::open(&out).expect("basis");
    assert_eq!(
        file.space("global").expect("space").meshing_strategy.as_deref(),
        Some(strategy.as_str())
    );
}

/// The crankshaft's 10-node mesh at 4 mm solves, but gmsh meshes its part at 9 mm (the error
/// estimate's second coarser mesh) on no rung. The felt check asks for that same mesh again: it
/// is refused at once with the first failure's message, not walked down the ladder a second
/// time (3.5–3.8 s on this part, whose solve takes 0.2 s).
#[test]
fn a_coarser_mesh_no_rung_can_make_is_tried_once() {
    let dir = tempfile::tempdir().expect("temp dir");
    let step = Path::new(env!("CARGO_MANIFEST_DIR")).join("../cases/corpus/crankshaft.step");
    let scene = dir.path().join("crank.toml");
    std::fs::write(
        &scene,
        format!(
            "name = \"crank\"\n[geometry]\nstep = {:?}\nunit = \"mm\"\n[material]\nyoung = 2.1e11\npoisson = 0.3\n\
             density = 7850.0\n[mesh]\nsize = 0.004\norder = 2\n[[fixed]]\nfaces = [38, 39]\n[modes]\ncount = 10\n",
            step.display().to_string()
        ),
    )
    .expect("write");
    let out = dir.path().join("crank.h5");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_ves"))
        .args(["precompute", scene.to_str().unwrap(), "-o", out.to_str().unwrap()])
        .env("VES_LOG", "info")
        .env("VES_CACHE_DIR", dir.path().join("cache"))
        .output()
        .expect("ves runs");
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    // One walk down the five rungs (made ahead beside the solve, or by the estimate), however
    // many stages ask for that mesh.
    assert_eq!(err.matches("meshing failed: ").count(), 5, "{err}");
    assert!(err.contains("not tried again"), "{err}");
    let felt = err
        .lines()
        .find(|l| l.contains("felt compliance's mesh error was not estimated"))
        .unwrap_or_else(|| panic!("no felt warning: {err}"));
    assert!(felt.contains("any of its 5 strategies"), "{felt}");
}

/// `mesh.smooth_curved = false` (the page's first look): the thin cone cover's 10-node tets that
/// curving made invalid are all straightened at once, none by gmsh's smoother, and every element
/// is valid either way; the two meshes are cached apart.
#[test]
fn curved_tets_are_straightened_at_once_without_the_smoother() {
    let dir = tempfile::tempdir().expect("temp dir");
    let step = Path::new(env!("CARGO_MANIFEST_DIR")).join("../cases/corpus/thin_cone_cover.step");
    let smoothed = default_scene(&step, dir.path());
    let text = std::fs::read_to_string(&smoothed).expect("scene");
    let straight = dir.path().join("straight.toml");
    std::fs::write(&straight, text.replace("order = 2", "order = 2\nsmooth_curved = false")).expect("write");
    let mesh = |path: &Path| {
        let scene = Scene::load(path).expect("scene");
        ves_pipeline::mesh::generate(&scene, None).expect("meshes")
    };
    let ((a, ma), (b, mb)) = (mesh(&smoothed), mesh(&straight));
    println!("smoothed {ma:?}\nstraight {mb:?}");
    assert!(ma.distorted > 0 && ma.repaired_by_gmsh > 0, "{ma:?}");
    assert_eq!((mb.distorted, mb.repaired_by_gmsh), (ma.distorted, 0), "{mb:?}");
    assert!(mb.straightened >= mb.distorted, "{mb:?}");
    for (what, m) in [("smoothed", &a), ("straight", &b)] {
        let worst = m
            .tets
            .chunks_exact(10)
            .map(|t| min_scaled_jacobian(&t.iter().map(|&n| m.nodes[n as usize]).collect::<Vec<_>>()))
            .fold(f64::INFINITY, f64::min);
        assert!(worst > 0.0, "{what}: an invalid element (scaled Jacobian {worst})");
    }
}
