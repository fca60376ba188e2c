//! VOI switching on the ribplate (global space and rib 3's refined space): the offline transfer
//! matrix, then a scripted grab-and-pull that leaves the VOI while the rib is loaded. Measured:
//! the drawn displacement's jump at the switch (old field interpolated exactly onto the new
//! mesh), the device force's change per step across it, the time the switch takes.

use ves_pipeline::modes::SolverChoice;
use ves_pipeline::precompute::{SolvedSpace, add_transfers, solve_space};
use ves_pipeline::scene::Scene;
use ves_pipeline::store;
use ves_pipeline::transfer;
use ves_runtime::haptic::{Coupling, HandInput, HandOutput};
use ves_runtime::integrator::Scheme;
use ves_runtime::switching::{SwitchConfig, Switcher, load_spaces};
use ves_tests::case_path;

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

/// max over `to`'s surface vertices of |u_to − I u_from| / max |I u_from|.
fn jump(from: &SolvedSpace, q_from: &[f64], to: &SolvedSpace, q_to: &[f64]) -> f64 {
    let interp = transfer::locate(&from.mesh, &to.mesh);
    let mut carried = vec![0.0; 3 * to.mesh.nodes.len()];
    transfer::interpolate(&from.mesh, &interp, &field(from, q_from), &mut carried);
    let now = field(to, q_to);
    let surface: Vec<usize> = to.mesh.surface_vertices().into_iter().map(|v| v as usize).collect();
    let norm = |u: &[f64], i: usize| (0..3).map(|c| u[3 * i + c].powi(2)).sum::<f64>().sqrt();
    let diff: Vec<f64> = (0..now.len()).map(|k| now[k] - carried[k]).collect();
    let peak = surface.iter().map(|&i| norm(&carried, i)).fold(0.0, f64::max);
    surface.iter().map(|&i| norm(&diff, i)).fold(0.0, f64::max) / peak
}

#[test]
fn leaving_a_voi_while_pulling_a_rib_is_smooth() {
    let _serial = ves_tests::serial();
    let mut scene = Scene::load(&case_path("ribplate/scene-voi.toml")).expect("scene");
    scene.voi.retain(|v| v.name == "rib3");
    scene.modes.count = 30;
    let voi = scene.voi[0].clone();
    let mut spaces = vec![
        solve_space(&scene, None, SolverChoice::Auto).expect("global"),
        solve_space(&scene, Some(&voi), SolverChoice::Auto).expect("rib3"),
    ];
    add_transfers(&mut spaces).expect("every space has its K and M");
    // T is an M-orthogonal projection: rib 3's first mode, carried onto the global mesh, keeps
    // almost all of its unit M-norm in the global space's 30 modes, and never gains any.
    let t = &spaces[0].transfers[0].1;
    let r = spaces[1].modes.eigenvalues.len();
    let kept: f64 = (0..spaces[0].modes.eigenvalues.len()).map(|i| t[i * r].powi(2)).sum();
    println!(
        "rib3 mode 1 carried to the global space keeps {:.5} of its M-norm²",
        kept
    );
    assert!(kept > 0.95 && kept < 1.0 + 1e-3, "{kept}");

    let dir = tempfile::tempdir().expect("tmp");
    let path = dir.path().join("ribvoi.h5");
    let views: Vec<store::Space<'_>> = spaces.iter().map(SolvedSpace::view).collect();
    store::write(&path, &scene, &views).expect("write");

    let inputs = load_spaces(&path, None, true).expect("load");
    assert_eq!(inputs.len(), 2);
    assert_eq!(inputs[1].basis.voi, Some([voi.bbox.min, voi.bbox.max]));
    let tip = scene.probes[2].at;
    let cfg = SwitchConfig::default();
    let blended = pull_out_of_voi(&path, tip, cfg, Some(&spaces));
    // The same without blending: what the blend window is for.
    let raw = pull_out_of_voi(&path, tip, SwitchConfig { blend_steps: 0, ..cfg }, None);
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
/// (x > 0.033 + margin) at 12 mm/s, hold outside. With `spaces`, also checks the drawn jump.
fn pull_out_of_voi(path: &std::path::Path, tip: [f64; 3], cfg: SwitchConfig, spaces: Option<&[SolvedSpace]>) -> Pulled {
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
        let q_was = sw.sim(was).state().q.clone();
        sw.step(&[input], &mut out);
        if sw.active() != was && k > 0 {
            assert!(switch_step.is_none(), "one switch expected on the way out");
            switch_step = Some(k);
            if let Some(spaces) = spaces {
                // The state the new space took over, before it stepped: T q_old.
                let (new, old) = (&spaces[sw.active()], &spaces[was]);
                let (rn, ro) = (new.modes.eigenvalues.len(), old.modes.eigenvalues.len());
                let tr = &new.transfers[0].1;
                let q_new: Vec<f64> = (0..rn)
                    .map(|i| (0..ro).map(|j| tr[i * ro + j] * q_was[j]).sum())
                    .collect();
                let j = jump(old, &q_was, new, &q_new);
                println!(
                    "switch {} → {} at t = {t:.3} s: drawn surface jump {:.3} % of the displacement",
                    old.name,
                    new.name,
                    100.0 * j
                );
                assert!(j < 0.01, "jump {j}");
            }
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
