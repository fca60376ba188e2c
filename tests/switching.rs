//! VOI switching on the ribplate (global space and rib 3's refined space), driven through the
//! runtime's switcher. First a switch with no force on the part (the hand lets go of rib 3's
//! loaded tip and, while it swings back, leaves the VOI): the state the switcher's new simulation
//! holds after the switch step must be the free step of the M-orthogonal projection of the old
//! state, computed here from the two spaces' modes, mass matrix and interpolation (not from the
//! stored transfer matrix), and its drawn displacement must match the old model's at the new
//! mesh's surface vertices. Then a scripted grab-and-pull that leaves the VOI while the rib is
//! loaded: the device force's change per step across the switch, the time the switch takes.

use std::path::PathBuf;
use std::sync::OnceLock;
use ves_pipeline::modes::SolverChoice;
use ves_pipeline::precompute::{SolvedSpace, add_transfers, solve_space};
use ves_pipeline::scene::Scene;
use ves_pipeline::store;
use ves_pipeline::transfer;
use ves_runtime::haptic::{Coupling, HandInput, HandOutput};
use ves_runtime::integrator::Scheme;
use ves_runtime::switching::{SwitchConfig, Switcher, load_spaces};
use ves_tests::case_path;

/// The two solved spaces (global, rib 3) with their transfers, written to a basis file once for
/// every test of this binary.
struct Fixture {
    scene: Scene,
    spaces: Vec<SolvedSpace>,
    path: PathBuf,
    _dir: tempfile::TempDir,
}

fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let mut scene = Scene::load(&case_path("ribplate/scene-voi.toml")).expect("scene");
        scene.voi.retain(|v| v.name == "rib3");
        scene.modes.count = 30;
        let voi = scene.voi[0].clone();
        let mut spaces = vec![
            solve_space(&scene, None, SolverChoice::Auto).expect("global"),
            solve_space(&scene, Some(&voi), SolverChoice::Auto).expect("rib3"),
        ];
        add_transfers(&mut spaces).expect("every space has its K and M");
        let dir = tempfile::tempdir().expect("tmp");
        let path = dir.path().join("ribvoi.h5");
        let views: Vec<store::Space<'_>> = spaces.iter().map(SolvedSpace::view).collect();
        store::write(&path, &scene, &views).expect("write");
        Fixture {
            scene,
            spaces,
            path,
            _dir: dir,
        }
    })
}

/// Full displacement field (3 per node) of a space for modal coordinates q.
fn field(s: &SolvedSpace, q: &[f64]) -> Vec<f64> {
    let nf = s.dofs.free_count();
    let mut u = vec![0.0; nf];
    for (j, qj) in q.iter().enumerate() {
        for (ui, p) in u.iter_mut().zip(&s.modes.vectors[j * nf..(j + 1) * nf]) {
            *ui += qj * p;
        }
    }
    s.dofs.expand(&u)
}

/// `from`'s field for q interpolated onto `to`'s mesh (3 per node of `to`).
fn carried(from: &SolvedSpace, q: &[f64], to: &SolvedSpace) -> Vec<f64> {
    let interp = transfer::locate(&from.mesh, &to.mesh);
    let mut out = vec![0.0; 3 * to.mesh.nodes.len()];
    transfer::interpolate(&from.mesh, &interp, &field(from, q), &mut out);
    out
}

/// Modal coordinates in `to` of a full field u on `to`'s mesh: Φᵀ M u, with M applied here
/// from its stored lower triangle (the modes are M-orthonormal).
fn project(to: &SolvedSpace, u: &[f64]) -> Vec<f64> {
    let nf = to.dofs.free_count();
    let x: Vec<f64> = to.dofs.free.iter().map(|&g| u[g as usize]).collect();
    let system = to.system.as_ref().expect("the space keeps its K and M");
    let (p, m) = (&system.pattern, &system.m);
    let mut mx = vec![0.0; nf];
    for col in 0..nf {
        let range = p.col_ptr()[col]..p.col_ptr()[col + 1];
        for (&row, &mk) in p.row_idx()[range.clone()].iter().zip(&m[range]) {
            mx[row] += mk * x[col];
            if row != col {
                mx[col] += mk * x[row];
            }
        }
    }
    (0..to.modes.eigenvalues.len())
        .map(|j| {
            to.modes.vectors[j * nf..(j + 1) * nf]
                .iter()
                .zip(&mx)
                .map(|(a, b)| a * b)
                .sum()
        })
        .collect()
}

fn rel_diff(a: &[f64], b: &[f64]) -> f64 {
    let n = |v: &mut dyn Iterator<Item = f64>| v.map(|x| x * x).sum::<f64>().sqrt();
    n(&mut a.iter().zip(b).map(|(x, y)| x - y)) / n(&mut b.iter().copied())
}

/// Grab rib 3's tip inside its VOI, pull the hand 4 mm along +x and hold until the rib settles,
/// let go and let it swing for 0.5 ms, then put the hand 20 mm above and 30 mm beside the tip,
/// outside the VOI: the switcher switches to the global space in that step with no force on the
/// part. Its global
/// simulation must then hold the free step of (P q_old, P v_old), P the M-orthogonal projection
/// computed here; the drawn displacement matches the old model's at the global surface vertices.
#[test]
fn a_switch_carries_the_projected_state_into_the_new_space() {
    let _serial = ves_tests::serial();
    let fx = fixture();
    let tip = fx.scene.probes[2].at;
    let coupling = Coupling::critically_damped(500.0, 10.0);
    let inputs = load_spaces(&fx.path, None, true).expect("load");
    // A 10 µs step: the free step after the switch barely moves the field (rib 3's lowest mode
    // turns 0.02 rad in it), so the drawn fields of the two models can be compared after it.
    let dt = 1e-5;
    let mut sw = Switcher::new(inputs, coupling, dt, Scheme::Exact, 1, SwitchConfig::default()).expect("switcher");
    let mut out = [HandOutput::default()];
    let held = |pull: f64| HandInput {
        position: [tip[0] + pull, tip[1], tip[2]],
        velocity: [0.0; 3],
        button: true,
    };
    // Pull over 30 ms, hold 160 ms: the rib settles (its lowest mode decays in ~6 ms).
    for k in 0..20_000usize {
        let t = k as f64 * dt;
        sw.step(&[held(4e-3 * ((t - 0.01) / 0.03).clamp(0.0, 1.0))], &mut out);
    }
    assert_eq!(sw.active(), 1, "the hand stays inside rib 3's VOI while it pulls");
    assert_eq!(sw.switches, 1, "one switch: into the VOI at the grab");
    let pull_force = out[0].force.iter().map(|f| f * f).sum::<f64>().sqrt();
    assert!(pull_force > 0.5, "the rib is loaded before the switch: {pull_force} N");
    // Let go and lift the hand 2.5 mm above the tip, still inside the VOI: the rib swings back
    // freely for 0.5 ms (a sixth of its lowest period), so the state switched has velocity.
    let above = HandInput {
        position: [tip[0], tip[1], tip[2] + 2.5e-3],
        velocity: [0.0; 3],
        button: false,
    };
    for _ in 0..50 {
        sw.step(&[above], &mut out);
        assert_eq!(out[0].force, [0.0; 3], "the lifted hand does not touch the rib");
    }
    assert_eq!(sw.active(), 1, "still inside rib 3's VOI");
    let (q_old, v_old) = (sw.sim(1).state().q.clone(), sw.sim(1).state().v.clone());
    let away = HandInput {
        position: [tip[0] + 0.03, tip[1], tip[2] + 0.02],
        velocity: [0.0; 3],
        button: false,
    };
    sw.step(&[away], &mut out);
    assert_eq!(
        (sw.active(), sw.switches),
        (0, 2),
        "the hand left the VOI: global space"
    );
    assert_eq!(out[0].force, [0.0; 3], "no force on the part in the switch step");
    let (global, rib) = (&fx.spaces[0], &fx.spaces[1]);
    // Independent expectation: project the old fields, then one free step of each mode.
    let (pq, pv) = (
        project(global, &carried(rib, &q_old, global)),
        project(global, &carried(rib, &v_old, global)),
    );
    let state = sw.sim(0).state();
    let (eq, ev): (Vec<f64>, Vec<f64>) = (0..pq.len()).map(|j| state.transition(j).free(pq[j], pv[j])).unzip();
    let (e_q, e_v) = (rel_diff(&state.q, &eq), rel_diff(&state.v, &ev));
    // The projection is M-orthogonal: rib 3's first mode, carried onto the global mesh, keeps
    // almost all of its unit M-norm² in the global space's 30 modes, and never gains any.
    let kept = {
        let p = project(global, &carried(rib, &[1.0], global));
        p.iter().map(|x| x * x).sum::<f64>()
    };
    // The drawn field: the switcher's new simulation against the old model, which the blend
    // window stepped alongside with the same (forceless) hand, at the global surface vertices.
    let now_old = carried(rib, &sw.sim(1).state().q, global);
    let b = sw.sim(0).basis();
    // Normalised by the rib's deformation just before the switch.
    let loaded = carried(rib, &q_old, global);
    let (mut worst, mut peak) = (0.0f64, 0.0f64);
    for &v in &b.surface_vertices {
        let u_new = sw.sim(0).displacement(v as usize);
        let node = b.node_index[v as usize] as usize;
        let d = (0..3)
            .map(|c| (u_new[c] - now_old[3 * node + c]).powi(2))
            .sum::<f64>()
            .sqrt();
        worst = worst.max(d);
        peak = peak.max((0..3).map(|c| loaded[3 * node + c].powi(2)).sum::<f64>().sqrt());
    }
    println!(
        "switch rib3 → global after letting go of {pull_force:.3} N: state against the projection: q {e_q:.1e}, v {e_v:.1e}; drawn surface jump {:.3} % of the {:.3} mm there; rib3 mode 1 keeps {kept:.5} of its M-norm² in the global modes",
        100.0 * worst / peak,
        1e3 * peak
    );
    // f64 throughout (T stored as f64): agreement to rounding.
    assert!(
        e_q < 1e-9 && e_v < 1e-9,
        "switched state off the projection: q {e_q}, v {e_v}"
    );
    assert!(kept > 0.95 && kept < 1.0 + 1e-3, "{kept}");
    assert!(worst < 0.01 * peak, "drawn jump {} of {peak} m", worst);
}

#[test]
fn leaving_a_voi_while_pulling_a_rib_is_smooth() {
    let _serial = ves_tests::serial();
    let fx = fixture();
    let inputs = load_spaces(&fx.path, None, true).expect("load");
    assert_eq!(inputs.len(), 2);
    let voi = &fx.scene.voi[0];
    assert_eq!(inputs[1].basis.voi, Some([voi.bbox.min, voi.bbox.max]));
    let (scene, path) = (&fx.scene, &fx.path);
    let tip = scene.probes[2].at;
    let cfg = SwitchConfig::default();
    let blended = pull_out_of_voi(path, tip, cfg);
    // The same without blending: what the blend window is for.
    let raw = pull_out_of_voi(path, tip, SwitchConfig { blend_steps: 0, ..cfg });
    println!(
        "force {:.3} N at the switch; largest change per step across it {:.3} % with a {}-step blend, \
         {:.3} % without (pulling alone {:.3} %); switch took {:.1} µs in the haptic thread",
        blended.force_at_switch,
        100.0 * blended.worst_step,
        cfg.blend_steps,
        100.0 * raw.worst_step,
        100.0 * blended.ordinary_step,
        blended.switch_ns as f64 / 1e3
    );
    assert!(blended.force_at_switch > 1.0, "the rib is loaded at the switch");
    assert!(blended.worst_step < 0.01, "force step {}", blended.worst_step);
    assert!(blended.worst_step <= raw.worst_step, "blending must not make it worse");
}

struct Pulled {
    force_at_switch: f64,
    worst_step: f64,
    ordinary_step: f64,
    switch_ns: u64,
}

/// Rib 3 stands at x ∈ [0.015, 0.033]: grab its tip, hold, pull along +x out of the box
/// (x > 0.033 + margin) at 12 mm/s, hold outside.
fn pull_out_of_voi(path: &std::path::Path, tip: [f64; 3], cfg: SwitchConfig) -> Pulled {
    // A held grab keeps its space by default; the switch under load that the blend smooths (a
    // second hand leaving the box while the first still pulls) is made here by letting the
    // grabbing hand count at its position.
    let cfg = SwitchConfig {
        hold_grabs: false,
        ..cfg
    };
    let coupling = Coupling {
        stiffness: 500.0,
        damping: 2.0 * (500.0f64 * 1e-3).sqrt(),
        max_force: 10.0,
    };
    let inputs = load_spaces(path, None, true).expect("load");
    let mut sw = Switcher::new(inputs, coupling, 1e-3, Scheme::Exact, 1, cfg).expect("switcher");
    let mut out = [HandOutput::default()];
    let (mut forces, mut active) = (Vec::new(), Vec::new());
    let mut switch_step: Option<usize> = None;
    for k in 0..1500usize {
        let t = k as f64 * 1e-3;
        let pull = 0.012 * (t - 0.2).clamp(0.0, 1.0);
        let input = HandInput {
            position: [tip[0] + pull, tip[1], tip[2]],
            velocity: [if (0.2..1.2).contains(&t) { 0.012 } else { 0.0 }, 0.0, 0.0],
            button: true,
        };
        let was = sw.active();
        sw.step(&[input], &mut out);
        if sw.active() != was && k > 0 {
            assert!(switch_step.is_none(), "one switch expected on the way out");
            switch_step = Some(k);
        }
        assert!(out[0].force.iter().all(|f| f.is_finite()));
        forces.push(out[0].force);
        active.push(sw.active());
    }
    assert_eq!(active[1], 1, "the grab starts inside rib 3's VOI");
    let s = switch_step.expect("the pull leaves the VOI");
    assert_eq!(active[1499], 0, "outside the VOI the global space is active");
    let mag = |f: [f64; 3]| f.iter().map(|v| v * v).sum::<f64>().sqrt();
    let step_change = |k: usize| mag(std::array::from_fn(|c| forces[k][c] - forces[k - 1][c])) / mag(forces[k]);
    Pulled {
        force_at_switch: mag(forces[s]),
        worst_step: (s.saturating_sub(5)..(s + cfg.blend_steps + 5).min(1499))
            .map(step_change)
            .fold(0.0, f64::max),
        ordinary_step: (s - 300..s - 200).map(step_change).fold(0.0, f64::max),
        switch_ns: sw.max_switch_ns,
    }
}
