//! The C ABI from a real C program: compiled with the system C compiler against the committed
//! header and libves_runtime.so, run on a basis, and checked against the Rust API.

use std::path::PathBuf;
use std::process::Command;
use std::sync::Arc;
use ves_runtime::LoadOptions;
use ves_runtime::haptic::{Coupling, HandInput, HandOutput, Haptics};
use ves_runtime::integrator::Scheme;
use ves_tests::precompute_case;

#[test]
fn c_program_loads_a_basis_and_runs_a_session() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let lib_dir = root
        .join("target")
        .join(if cfg!(debug_assertions) { "debug" } else { "release" });
    assert!(
        lib_dir.join("libves_runtime.so").is_file(),
        "{} missing: build it with `cargo build --release -p ves-runtime --features capi` (scripts/test does)",
        lib_dir.join("libves_runtime.so").display()
    );
    let dir = tempfile::tempdir().expect("temp dir");
    let basis = precompute_case("cantilever", 0.05, 1, 8, dir.path());
    let exe = dir.path().join("session");
    let cc = Command::new("cc")
        .arg(root.join("runtime/examples/c/session.c"))
        .arg("-I")
        .arg(root.join("runtime/include"))
        .arg("-L")
        .arg(&lib_dir)
        .arg(format!("-Wl,-rpath,{}", lib_dir.display()))
        .args(["-lves_runtime", "-Wall", "-Werror", "-o"])
        .arg(&exe)
        .output()
        .expect("cc runs");
    assert!(
        cc.status.success(),
        "C build failed: {}",
        String::from_utf8_lossy(&cc.stderr)
    );
    let run = Command::new(&exe).arg(&basis).output().expect("C program runs");
    assert!(
        run.status.success(),
        "C program failed: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    let text = String::from_utf8_lossy(&run.stdout);
    let field = |name: &str, k: usize| -> f64 {
        let words: Vec<&str> = text.split_whitespace().collect();
        let i = words
            .iter()
            .position(|w| *w == name)
            .unwrap_or_else(|| panic!("{name} missing in {text}"));
        words[i + 1 + k]
            .parse()
            .unwrap_or_else(|_| panic!("bad {name} in {text}"))
    };
    assert_eq!(field("errors_ok", 0), 1.0, "error paths: {text}");

    // The same scenario through the Rust API gives the same force.
    let b = Arc::new(
        ves_runtime::basis::load(
            &basis,
            &LoadOptions {
                surface_only: true,
                ..Default::default()
            },
        )
        .expect("loads"),
    );
    assert_eq!(field("vertices", 0) as usize, b.vertex_count());
    let mut h = Haptics::new(
        b,
        Coupling {
            stiffness: 2e4,
            damping: 50.0,
            max_force: 1000.0,
        },
        1e-3,
        Scheme::Exact,
        1,
    );
    let mut out = [HandOutput::default()];
    for k in 0..3000 {
        let s = if k < 500 { k as f64 / 500.0 } else { 1.0 };
        let input = HandInput {
            position: [1.0, 0.05, 0.05 - 0.005 * s],
            velocity: [0.0; 3],
            button: true,
        };
        h.step(&[input], &mut out);
    }
    for c in 0..3 {
        let fc = field("force", c);
        assert!(
            (fc - out[0].force[c]).abs() <= 1e-9 * out[0].force[2].abs() + 1e-12,
            "force {c}: C {fc} vs Rust {}",
            out[0].force[c]
        );
    }
    // Pulling the tip down: the beam pulls the hand back up, and the drawn tip goes below z = 0.
    assert!(field("force", 2) > 1.0, "{text}");
    assert!(field("lowest_z", 0) < -1e-5, "{text}");
}
