//! The viewer's compute: the basis is written first without its checks (the Sturm count, the
//! error estimate), the session moves to it, then the checks run and the same file is written
//! again with them. Both files must hold what `ves precompute` writes for the same scene.

use std::path::Path;
use ves_format::read::BasisReader;
use ves_pipeline::modes::SolverChoice;
use ves_pipeline::precompute::{self, Summary};
use ves_pipeline::scene::Scene;
use ves_tests::{case_path, serial};

/// The cantilever, coarse, 10-node tets, 8 modes, the error estimate on (the default).
fn scene(dir: &Path) -> Scene {
    let text = format!(
        "name = \"later\"\n[geometry]\nstep = {:?}\nunit = \"mm\"\n[material]\nyoung = 2.1e11\npoisson = 0.3\n\
         density = 7850.0\n[mesh]\nsize = 0.05\norder = 2\n[[fixed]]\nplane = {{ axis = \"x\", value = 0.0 }}\n\
         [modes]\ncount = 8\n",
        case_path("cantilever/cantilever.step").display().to_string()
    );
    let path = dir.join("scene.toml");
    std::fs::write(&path, &text).expect("write the scene");
    Scene::parse(&path, &text).unwrap_or_else(|e| panic!("{e}"))
}

fn frequencies_in(file: &Path) -> (Vec<f64>, Option<Vec<f64>>) {
    let r = BasisReader::open(file).unwrap_or_else(|e| panic!("{e}"));
    let s = r.space("global").unwrap_or_else(|e| panic!("{e}"));
    let f = s.frequencies_hz().unwrap_or_else(|e| panic!("{e}"));
    (f, s.estimated_relative_error().unwrap_or_else(|e| panic!("{e}")))
}

#[test]
fn the_viewer_s_basis_comes_first_and_its_estimate_after_with_the_same_modes() {
    let _one = serial();
    let dir = tempfile::tempdir().unwrap();
    let s = scene(dir.path());
    let whole =
        precompute::run(&s, &dir.path().join("whole.h5"), SolverChoice::Auto).unwrap_or_else(|e| panic!("{e:#}"));

    let later = dir.path().join("later.h5");
    let first = precompute::run_first(&s, &later, SolverChoice::Auto).unwrap_or_else(|e| panic!("{e:#}"));
    assert!(first.checks_pending(), "a fixed mesh size: the checks come after");
    // What the session loads at this moment: the file as written, without the estimate.
    let (first_f, first_e) = frequencies_in(&later);
    assert_eq!(
        first.summary.spaces[0].frequencies_hz, first_f,
        "the summary is the file's"
    );
    assert!(
        first_e.is_none() && first.summary.spaces[0].sturm_count.is_none(),
        "the first basis comes before its checks"
    );
    let last: Summary = first.check().unwrap_or_else(|e| panic!("{e:#}"));
    let first_f = &first_f;
    let want = &whole.spaces[0];
    let got = &last.spaces[0];
    for (a, b) in want.frequencies_hz.iter().zip(first_f) {
        assert!(
            (a - b).abs() <= 1e-9 * a,
            "first basis: {b} Hz where ves precompute gives {a} Hz"
        );
    }
    assert_eq!(got.frequencies_hz, *first_f, "the checks leave the modes as they are");
    let (file_f, file_e) = frequencies_in(&later);
    assert_eq!(file_f, *first_f);
    let (want_e, file_e) = (
        want.estimated_relative_error.as_ref().expect("estimate"),
        file_e.expect("estimate in the file"),
    );
    assert_eq!(want_e.len(), file_e.len());
    for (a, b) in want_e.iter().zip(&file_e) {
        assert!(
            (a - b).abs() <= 1e-6 * a.abs().max(1e-12),
            "estimate {b} where ves precompute gives {a}"
        );
    }
    let sturm = got.sturm_count.expect("Sturm count after the checks");
    assert_eq!(sturm.below, sturm.found, "{sturm:?}");
}
