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
        let o = ves(&[
            "precompute",
            scene.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--instant-from",
            previous.to_str().unwrap(),
            "--json",
        ]);
        assert!(o.status.success(), "{name}: {}", String::from_utf8_lossy(&o.stderr));
        let got = last_json(&o);
        let (want, have) = (frequencies(&exact), frequencies(&got));
        assert_eq!(want.len(), have.len(), "{name}");
        let bounds = numbers(&got["instant"]["frequency_bound"]);
        for (i, ((w, h), b)) in want.iter().zip(&have).zip(&bounds).enumerate() {
            let err = (h - w) / w;
            assert!(err > -1e-8, "{name} mode {i}: {h} Hz below the converged {w} Hz");
            assert!(
                err <= 1.01 * b + 1e-9,
                "{name} mode {i}: {err:.2e} above its bound {b:.2e}"
            );
            assert!(err < 1e-3, "{name} mode {i}: {err:.2e}");
        }
        assert_eq!(
            got["spaces"][0]["rigid_modes_dropped"], exact["spaces"][0]["rigid_modes_dropped"],
            "{name}"
        );
        // The file is a basis like any other: `ves info` reads and checks it whole.
        let info = ves(&["info", out.to_str().unwrap(), "--json"]);
        assert!(
            info.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&info.stderr)
        );
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
