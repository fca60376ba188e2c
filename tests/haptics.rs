//! The runtime on a real basis: static response, energy, force limits, abuse.

use std::sync::Arc;
use ves_runtime::haptic::{Coupling, HandInput, HandOutput, Haptics};
use ves_runtime::integrator::Scheme;
use ves_runtime::{Basis, LoadOptions};
use ves_tests::precompute_case;

fn cantilever(modes: usize) -> (tempfile::TempDir, Arc<Basis>) {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = precompute_case("cantilever", 0.05, 1, modes, dir.path());
    let basis = ves_runtime::basis::load(&path, &LoadOptions::default()).expect("basis loads");
    (dir, Arc::new(basis))
}

/// Index of the kept vertex nearest p.
fn nearest(b: &Basis, p: [f64; 3]) -> usize {
    (0..b.vertex_count())
        .min_by(|&i, &j| {
            let d = |k: usize| (0..3).map(|c| (b.rest[k][c] - p[c]).powi(2)).sum::<f64>();
            d(i).total_cmp(&d(j))
        })
        .unwrap_or(0)
}

#[test]
fn grabbed_tip_settles_on_the_modal_static_response() {
    let (_d, basis) = cantilever(10);
    let tip = nearest(&basis, [1.0, 0.1, 0.05]);
    let target = basis.rest[tip];
    let coupling = Coupling {
        stiffness: 2e4,
        damping: 50.0,
        max_force: 1e3,
    };
    let mut h = Haptics::new(basis.clone(), coupling, 1e-3, Scheme::Exact, 1);
    let hip = [target[0], target[1], target[2] - 0.01]; // pull the tip down 10 mm
    let input = [HandInput {
        position: hip,
        velocity: [0.0; 3],
        button: true,
    }];
    let mut out = [HandOutput::default()];
    grab_at(&mut h, target, &mut out);
    for _ in 0..20_000 {
        h.step(&input, &mut out);
    }
    assert_eq!(out[0].vertex as usize, tip);
    // Force on the part F = −device force, spread over the tip's contact patch; the patch's
    // modal static displacement Σ φ̄φ̄ᵀF/λ (φ̄ the patch-averaged rows the coupling reads).
    let f = out[0].force.map(|v| -v);
    let r = basis.mode_count();
    let mut rows = vec![0.0; 3 * r];
    basis.gather_contact_rows(tip, &mut rows);
    assert!(basis.contact_radius > 0.0, "the default contact patch is stored");
    let mut u_static = [0.0; 3];
    for j in 0..r {
        let fj = (0..3).map(|c| rows[c * r + j] * f[c]).sum::<f64>();
        for c in 0..3 {
            u_static[c] += rows[c * r + j] * fj / basis.eigenvalues[j];
        }
    }
    let u: [f64; 3] = std::array::from_fn(|c| out[0].vertex_position[c] - target[c]);
    for c in 0..3 {
        assert!(
            (u[c] - u_static[c]).abs() < 1e-6 * u_static[2].abs() + 1e-12,
            "u {u:?} vs {u_static:?}"
        );
    }
    // The vertex itself moves with the modes (its own rows), close to its patch on a beam tip.
    let own = h.displacement(tip);
    assert!((own[2] / u[2] - 1.0).abs() < 0.05, "vertex {own:?} vs patch {u:?}");
    // And the coupling is in equilibrium: F = k (x − p).
    let fz = coupling.stiffness * (hip[2] - (target[2] + u[2]));
    assert!((f[2] - fz).abs() < 1e-6 * fz.abs(), "{} vs {fz}", f[2]);
    assert!(u[2] < 0.0 && f[2] < 0.0);
}

#[test]
fn released_part_loses_energy_and_forces_respect_the_limit() {
    let (_d, basis) = cantilever(10);
    let tip = nearest(&basis, [1.0, 0.05, 0.05]);
    let p = basis.rest[tip];
    let coupling = Coupling {
        stiffness: 1e5,
        damping: 0.0,
        max_force: 5.0,
    };
    let mut h = Haptics::new(basis.clone(), coupling, 1e-3, Scheme::Exact, 1);
    let mut out = [HandOutput::default()];
    grab_at(&mut h, p, &mut out);
    // A HIP 1 m below the tip: the spring wants 1e5 N, the device must never see more than 5 N.
    let pull = [HandInput {
        position: [p[0], p[1], p[2] - 1.0],
        velocity: [0.0; 3],
        button: true,
    }];
    for _ in 0..500 {
        h.step(&pull, &mut out);
        let mag = out[0].force.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!(mag <= 5.0 * (1.0 + 1e-12), "force {mag}");
        assert!(out[0].clamped);
    }
    // Release far away: no contact, the energy decays monotonically (β > 0 in the scene).
    let away = [HandInput {
        position: [10.0, 10.0, 10.0],
        velocity: [0.0; 3],
        button: false,
    }];
    h.step(&away, &mut out);
    let mut e = h.state().energy();
    assert!(e > 0.0);
    for _ in 0..2000 {
        h.step(&away, &mut out);
        assert_eq!(out[0].force, [0.0; 3]);
        let e1 = h.state().energy();
        assert!(e1 <= e * (1.0 + 1e-12), "energy grew {e} -> {e1}");
        e = e1;
    }
    assert_eq!(h.quarantined, 0);
}

#[test]
fn abuse_huge_steps_stiff_coupling_and_nan_input_stay_finite() {
    let (_d, basis) = cantilever(10);
    let tip = nearest(&basis, [1.0, 0.05, 0.05]);
    let p = basis.rest[tip];
    for dt in [1e-6, 1e-3, 0.1] {
        for scheme in [Scheme::Exact, Scheme::Newmark] {
            let coupling = Coupling {
                stiffness: 1e9,
                damping: 1e3,
                max_force: 20.0,
            };
            let mut h = Haptics::new(basis.clone(), coupling, dt, scheme, 2);
            let mut out = [HandOutput::default(); 2];
            for k in 0..2000 {
                let z = p[2] - 0.002 * ((k as f64) * 0.37).sin();
                let inputs = [
                    HandInput {
                        position: [p[0], p[1], z],
                        velocity: [0.0, 0.0, 1e3],
                        button: k % 300 < 150,
                    },
                    HandInput {
                        position: if k % 7 == 0 { [f64::NAN; 3] } else { [0.5, 0.05, 0.06] },
                        velocity: [0.0; 3],
                        button: false,
                    },
                ];
                h.step(&inputs, &mut out);
                for o in &out {
                    assert!(o.force.iter().all(|v| v.is_finite()));
                    assert!(o.force.iter().map(|v| v * v).sum::<f64>().sqrt() <= 20.0 * (1.0 + 1e-12));
                }
            }
            assert!(h.state().q.iter().all(|q| q.is_finite()), "dt {dt} {scheme:?}");
        }
    }
}

#[test]
fn scripted_session_runs_two_hands_and_reports() {
    use ves_runtime::device::{Device, ScriptedDevice};
    use ves_runtime::session::{SessionConfig, run};
    let (_d, basis) = cantilever(8);
    let tip = basis.rest[nearest(&basis, [1.0, 0.05, 0.05])];
    let mid = basis.rest[nearest(&basis, [0.5, 0.05, 0.05])];
    // Hand 1 grabs the tip and pulls it up 5 mm; hand 2 presses 1 mm into the middle.
    let script = |p: [f64; 3], dz: f64, button: u8| {
        let text = format!(
            "t,x,y,z,button\n0,{x},{y},{z0},{button}\n0.1,{x},{y},{z1},{button}\n0.3,{x},{y},{z1},{button}\n",
            x = p[0],
            y = p[1],
            z0 = p[2] + if button == 1 { 0.0 } else { 0.001 },
            z1 = p[2] + dz
        );
        ScriptedDevice::parse("hand.csv", &text).expect("script parses")
    };
    let devices: Vec<Box<dyn Device>> = vec![Box::new(script(tip, 0.005, 1)), Box::new(script(mid, -0.001, 0))];
    let cfg = SessionConfig {
        rate_hz: 1000.0,
        duration_s: 0.3,
        ..Default::default()
    };
    let stats = run(basis, devices, &cfg).expect("session runs");
    assert_eq!(stats.steps, 300);
    assert_eq!(stats.quarantined, 0);
    assert!(stats.peak_force_n > 0.1 && stats.peak_force_n <= cfg.coupling.max_force * (1.0 + 1e-12));
    assert!(stats.max_energy_j > 0.0 && stats.max_energy_j.is_finite());
    assert!(stats.visual_updates > 0);
}

#[test]
fn free_bracket_lifted_by_one_corner_hangs_below_the_hand() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = precompute_case("bracket", 0.008, 1, 8, dir.path());
    let basis = Arc::new(ves_runtime::basis::load(&path, &LoadOptions::default()).expect("loads"));
    let props = basis.rigid.expect("a free body stores its mass properties");
    let g = 9.81;
    let coupling = Coupling {
        stiffness: 3000.0,
        damping: 20.0,
        max_force: 50.0,
    };
    let mut h = Haptics::new(basis.clone(), coupling, 1e-3, Scheme::Exact, 1);
    h.set_free_body([0.0, 0.0, -g], 3.0).expect("free body");
    // Grab the far top corner of the base and lift it 0.1 m over 1 s, then hold for 5 s.
    let corner = basis.rest[nearest(&basis, [0.08, 0.06, 0.008])];
    let mut out = [HandOutput::default()];
    for k in 0..6000 {
        let s = (k as f64 / 1000.0).min(1.0);
        let hip = [corner[0], corner[1], corner[2] + 0.1 * s];
        h.step(
            &[HandInput {
                position: hip,
                velocity: [0.0; 3],
                button: true,
            }],
            &mut out,
        );
    }
    assert_eq!(h.quarantined, 0);
    let rb = h.rigid_body().expect("free");
    let weight = props.mass * g;
    // The hand carries the weight…
    assert!(
        (out[0].force[2] + weight).abs() < 0.05 * weight,
        "device force {:?}, weight {weight}",
        out[0].force
    );
    // …the part hangs: its centre of mass is straight below the grabbed point, and it has risen.
    let grab = out[0].vertex_position;
    let horizontal = ((rb.position[0] - grab[0]).powi(2) + (rb.position[1] - grab[1]).powi(2)).sqrt();
    assert!(
        horizontal < 0.005,
        "COM {horizontal} m off the vertical through the hand"
    );
    assert!(rb.position[2] < grab[2]);
    assert!(
        rb.position[2] > props.center[2] + 0.03,
        "part lifted: COM z {}",
        rb.position[2]
    );
}

#[test]
fn static_correction_makes_the_felt_stiffness_exact_with_few_modes() {
    use ves_pipeline::linsolve::factor_stiffness;
    let dir = tempfile::tempdir().expect("temp dir");
    let mut scene = ves_tests::load_case("cantilever");
    scene.mesh.size = 0.05;
    scene.mesh.order = 1;
    scene.modes.count = 6;
    scene.static_correction = Some(ves_pipeline::scene::StaticCorrection {
        region: ves_pipeline::scene::CorrectionRegion::Surface,
    });
    let path = dir.path().join("c.h5");
    ves_pipeline::precompute::run(&scene, &path, ves_pipeline::modes::SolverChoice::Auto).expect("precompute");
    let basis = Arc::new(ves_runtime::basis::load(&path, &LoadOptions::default()).expect("loads"));
    assert!(basis.compliance.is_some(), "blocks stored and loaded");
    // Full static solve on the basis file's own mesh for the settled force at the tip vertex.
    let (d, _) = ves_pipeline::verify::discretize_basis(&path, None).expect("the basis's mesh");
    let tip = nearest(&basis, [1.0, 0.1, 0.05]);
    let node = basis.node_index[tip] as usize;
    let chol = factor_stiffness(&d.system, &d.dofs).expect("factor");
    // The tip's contact patch as the file stores it: the force spread with its weights, the
    // displacement read with them.
    let contact = ves_format::BasisReader::open(&path)
        .and_then(|f| f.space("global")?.contact())
        .expect("read")
        .expect("contact patches stored");
    let k = contact
        .centres
        .binary_search(&(node as u32))
        .expect("the tip has a patch");
    let (nodes, weights) = contact.patch(k);
    let exact_u = |force: [f64; 3]| -> [f64; 3] {
        let mut f = vec![0.0; d.dofs.free_count()];
        for (&a, &w) in nodes.iter().zip(weights) {
            for (c, fc) in force.iter().enumerate() {
                let g = d.dofs.free_of[3 * a as usize + c];
                if g != u32::MAX {
                    f[g as usize] += w * fc;
                }
            }
        }
        chol.solve_many_in_place(&mut f, 1);
        let u = d.dofs.expand(&f);
        let mut out = [0.0; 3];
        for (&a, &w) in nodes.iter().zip(weights) {
            for c in 0..3 {
                out[c] += w * u[3 * a as usize + c];
            }
        }
        out
    };
    let settle = |correct: bool| {
        let coupling = Coupling {
            stiffness: 2e5,
            damping: 200.0,
            max_force: 1e4,
        };
        let mut h = Haptics::new(basis.clone(), coupling, 1e-3, Scheme::Exact, 1);
        h.set_static_correction(correct);
        let p = basis.rest[tip];
        let input = [HandInput {
            position: [p[0], p[1], p[2] - 1e-3],
            velocity: [0.0; 3],
            button: true,
        }];
        let mut out = [HandOutput::default()];
        grab_at(&mut h, p, &mut out);
        for _ in 0..20_000 {
            h.step(&input, &mut out);
        }
        let force = out[0].force.map(|v| -v); // on the part
        let u: [f64; 3] = std::array::from_fn(|c| out[0].vertex_position[c] - p[c]);
        let e = exact_u(force);
        let err = (0..3).map(|c| (u[c] - e[c]).powi(2)).sum::<f64>().sqrt()
            / (0..3).map(|c| e[c].powi(2)).sum::<f64>().sqrt();
        (u[2], e[2], err)
    };
    let ((u_with, exact, e_with), (u_without, _, e_without)) = (settle(true), settle(false));
    println!(
        "tip displacement: exact {exact:.6e} m, corrected {u_with:.6e} (error {e_with:.2e}), 6 modes only {u_without:.6e} (error {e_without:.2e})"
    );
    assert!(e_with.abs() < 1e-4, "corrected {e_with}");
    assert!(e_without.abs() > 10.0 * e_with.abs(), "the correction must matter here");
}

/// Truncated basis files (interrupted copies, full disks) are errors, never crashes. Byte flips
/// inside HDF5 metadata are not covered: one made the HDF5 library itself spin (noted for
/// issue 6).
#[test]
fn truncated_basis_files_are_errors_not_crashes() {
    let dir = tempfile::tempdir().expect("temp dir");
    let good = precompute_case("cantilever", 0.05, 1, 4, dir.path());
    let bytes = std::fs::read(&good).expect("basis bytes");
    let bad = dir.path().join("bad.h5");
    for k in 0..60 {
        let len = bytes.len() * k / 60;
        std::fs::write(&bad, &bytes[..len]).expect("write");
        match ves_runtime::basis::load(&bad, &LoadOptions::default()) {
            Ok(_) => panic!("a file cut at {len} of {} bytes loaded", bytes.len()),
            Err(e) => assert!(e.to_string().contains("bad.h5"), "{e}"),
        }
    }
}

/// Byte flips anywhere in a basis file: loading ends (error or a checked basis) and never
/// panics. 200 flips of 8 bytes each.
#[test]
fn corrupted_basis_files_are_errors_or_checked_bases() {
    let dir = tempfile::tempdir().expect("temp dir");
    let good = precompute_case("cantilever", 0.05, 1, 4, dir.path());
    let bytes = std::fs::read(&good).expect("basis bytes");
    let bad = dir.path().join("bad.h5");
    let mut seed = 0x9E37_79B9_7F4A_7C15u64;
    let (mut ok, mut err) = (0, 0);
    for _ in 0..200 {
        let mut b = bytes.clone();
        for _ in 0..8 {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            let at = (seed as usize) % b.len();
            b[at] ^= 0xA5;
        }
        std::fs::write(&bad, &b).expect("write");
        if std::env::var_os("VES_KEEP_BAD").is_some() {
            std::fs::write("/tmp/last-bad.h5", &b).expect("keep");
        }
        match ves_runtime::basis::load(&bad, &LoadOptions::default()) {
            Ok(basis) => {
                ok += 1;
                assert!(basis.phi.iter().all(|v| v.is_finite()) && basis.eigenvalues.iter().all(|l| *l > 0.0));
            }
            Err(e) => {
                err += 1;
                assert!(e.to_string().contains("bad.h5"), "{e}");
            }
        }
    }
    println!("byte flips: {ok} loaded (flips in unused bytes or plausible data), {err} refused");
    assert!(err > 10);
}

/// One step of a hand grabbing at `at` (a vertex's rest position): a grab holds the part where
/// it was grabbed, so a pull is the hand's motion from there.
fn grab_at(h: &mut Haptics, at: [f64; 3], out: &mut [HandOutput; 1]) {
    let grab = [HandInput {
        position: at,
        velocity: [0.0; 3],
        button: true,
    }];
    h.step(&grab, out);
}
