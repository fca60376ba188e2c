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

/// C ABI misuse that used to return Ok: more hands than the simulation has, NaN or 1e300
/// positions (force 0 at vertex 0); a larger view buffer was refused; a directory loaded as a
/// basis said "no such file".
#[test]
fn c_abi_refuses_bad_hands_and_positions_and_accepts_a_larger_view_buffer() {
    use std::ffi::{CStr, CString};
    use ves_runtime::capi::*;
    let last = || {
        unsafe { CStr::from_ptr(ves_last_error()) }
            .to_string_lossy()
            .into_owned()
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let basis = precompute_case("cantilever", 0.05, 1, 8, dir.path());
    let mut b: *mut VesBasis = std::ptr::null_mut();
    let d = CString::new(dir.path().to_str().unwrap()).unwrap();
    // SAFETY: valid C string and out-pointer.
    assert_eq!(unsafe { ves_basis_load(d.as_ptr(), 0, &mut b) }, VesStatus::Load);
    assert!(last().contains("is a directory"), "{}", last());
    let p = CString::new(basis.to_str().unwrap()).unwrap();
    // SAFETY: as above.
    let status = unsafe { ves_basis_load(p.as_ptr(), 0, &mut b) };
    assert_eq!(status, VesStatus::Ok, "{}", last());
    let mut h: *mut VesHaptics = std::ptr::null_mut();
    // SAFETY: live basis, valid out-pointer.
    assert_eq!(
        unsafe { ves_haptics_new(b, 1e-3, 500.0, 1.0, 10.0, 1, 0, &mut h) },
        VesStatus::Ok
    );
    let good = VesHandInput {
        position: [1.0, 0.05, 0.05],
        ..Default::default()
    };
    let mut out = [VesHandOutput::default(); 2];
    // SAFETY: arrays of 2 items, live simulation.
    let step = |inp: &[VesHandInput; 2], out: &mut [VesHandOutput; 2], n: u32| unsafe {
        ves_haptics_step(h, inp.as_ptr(), out.as_mut_ptr(), n)
    };
    assert_eq!(step(&[good, good], &mut out, 2), VesStatus::InvalidArgument);
    assert!(last().contains("1 ≤ n ≤ 1"), "{}", last());
    for bad in [[f64::NAN, 0.0, 0.0], [1e300, 0.0, 0.0], [0.0, f64::INFINITY, 0.0]] {
        let inp = VesHandInput {
            position: bad,
            ..Default::default()
        };
        assert_eq!(step(&[inp, good], &mut out, 1), VesStatus::InvalidArgument, "{bad:?}");
        assert!(last().contains("hand 0"), "{}", last());
    }
    assert_eq!(step(&[good, good], &mut out, 1), VesStatus::Ok, "{}", last());
    let mut v: *mut VesView = std::ptr::null_mut();
    // SAFETY: live simulation, valid out-pointer.
    assert_eq!(unsafe { ves_view_new(h, &mut v) }, VesStatus::Ok);
    let mut vertices = 0u32;
    // SAFETY: live basis; the other out-pointers may be null.
    let info = unsafe { ves_basis_info(b, &mut vertices, std::ptr::null_mut(), std::ptr::null_mut()) };
    assert_eq!(info, VesStatus::Ok);
    let need = 3 * vertices as usize;
    let mut buf = vec![f32::NAN; need + 7];
    // SAFETY: the buffer holds need + 7 floats.
    assert_eq!(
        unsafe { ves_view_positions(v, buf.as_mut_ptr(), buf.len()) },
        VesStatus::Ok,
        "{}",
        last()
    );
    assert!(buf[..need].iter().all(|x| x.is_finite()));
    assert!(buf[need..].iter().all(|x| x.is_nan()), "wrote past the vertices");
    // SAFETY: too short by one: refused before writing.
    assert_eq!(
        unsafe { ves_view_positions(v, buf.as_mut_ptr(), need - 1) },
        VesStatus::InvalidArgument
    );
    // SAFETY: handles from the calls above, freed once.
    unsafe {
        ves_view_free(v);
        ves_haptics_free(h);
        ves_basis_free(b);
    }
}
