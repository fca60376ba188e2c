//! The haptic step allocates nothing (hot paths get buffers sized up front): counted
//! by a global allocator over many steps of grabbing, pressing and a free body, with the
//! validity watch and its reactions on.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::Arc;
use ves_runtime::Basis;
use ves_runtime::basis::RigidProperties;
use ves_runtime::haptic::{Coupling, HandInput, HandOutput, Haptics, StrainPolicy, ValidityWatch};
use ves_runtime::integrator::Scheme;

struct Counting;

thread_local! {
    /// Allocations made by this thread (other test threads do not count).
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
}

// SAFETY: forwards to the system allocator; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|n| n.set(n.get() + 1));
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|n| n.set(n.get() + 1));
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static COUNTING: Counting = Counting;

fn allocations() -> u64 {
    ALLOCATIONS.with(Cell::get)
}

/// A flat 5 × 5 grid (1 cm spacing) with 3 bending-like modes and mass properties; with
/// `patches`, each vertex's contact patch shares half its weight among its neighbours (the rows
/// are then summed when a hand touches a vertex).
fn grid(patches: bool) -> Arc<Basis> {
    let n = 5u32;
    let rest: Vec<[f64; 3]> = (0..n * n)
        .map(|i| [0.01 * f64::from(i % n), 0.01 * f64::from(i / n), 0.0])
        .collect();
    let mut triangles = Vec::new();
    for y in 0..n - 1 {
        for x in 0..n - 1 {
            let v = y * n + x;
            triangles.push([v, v + 1, v + n + 1]);
            triangles.push([v, v + n + 1, v + n]);
        }
    }
    let rows: Vec<f64> = rest
        .iter()
        .flat_map(|p| {
            let (x, y) = (p[0] * 100.0, p[1] * 100.0);
            // (u_x, u_y, u_z) for modes 1..3, vertex-major rows 3i+c.
            [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [x * x, y * y, x * y]]
        })
        .flatten()
        .collect();
    let count = rest.len() as u32;
    // Modal stress too (6 per vertex × 3 modes), so that the stress watch runs in the loop.
    let stress: Vec<f64> = (0..6 * rest.len() * 3).map(|i| 1e5 * ((i % 7) as f64 - 3.0)).collect();
    let mut basis = Basis::new(
        "grid",
        "global",
        rest,
        (0..count).collect(),
        triangles,
        vec![1e4, 4e4, 9e4],
        &rows,
        (1.0, 1e-4),
        Some(RigidProperties {
            mass: 0.1,
            center: [0.02, 0.02, 0.0],
            inertia: [[1e-5, 0.0, 0.0], [0.0, 1e-5, 0.0], [0.0, 0.0, 2e-5]],
            free: ves_runtime::basis::FreeMotions::all(),
        }),
    )
    .expect("grid basis")
    .with_stress(&stress)
    .expect("stress");
    basis.yield_strength = Some(10.0);
    if patches {
        let weights = (0..basis.vertex_count())
            .flat_map(|i| {
                let count = basis.neighbour_ptr[i + 1] - basis.neighbour_ptr[i];
                (0..count).map(move |_| (0.5 * ves_runtime::basis::WEIGHT_UNIT / f64::from(count)) as u16)
            })
            .collect();
        basis = basis.with_contact_weights(0.005, weights).expect("patches");
    }
    Arc::new(basis)
}

/// A hand at time `t` over the grid at `x`, going down through it, its button as given.
fn input(t: f64, button: bool, x: f64) -> HandInput {
    HandInput {
        position: [x, 0.02, 0.001 - 0.01 * t],
        velocity: [0.0, 0.0, -0.01],
        button,
    }
}

#[test]
fn haptic_steps_allocate_nothing() {
    for (free, policy, patches) in [
        (false, StrainPolicy::Flag, false),
        (false, StrainPolicy::Stiffen, false),
        (false, StrainPolicy::Release, false),
        (true, StrainPolicy::Stiffen, false),
        (false, StrainPolicy::Flag, true),
        (true, StrainPolicy::Stiffen, true),
    ] {
        let mut h = Haptics::new(
            grid(patches),
            Coupling::critically_damped(500.0, 10.0),
            1e-3,
            Scheme::Exact,
            2,
        );
        if free {
            h.set_free_body([0.0, 0.0, -9.81], 1.0).expect("free body");
        }
        h.set_validity_watch(ValidityWatch {
            limit: 1e-3,
            policy,
            ..ValidityWatch::default()
        });
        let mut out = [HandOutput::default(); 2];
        // Warm-up: the first picks settle (nothing is sized lazily, but be fair to one-offs).
        h.step(&[input(0.0, false, 0.0), input(0.0, true, 0.04)], &mut out);
        let before = allocations();
        let mut stressed = false;
        for k in 0..2000 {
            let t = f64::from(k) * 1e-3;
            let inputs = [input(t, false, 0.01 * (k % 5) as f64), input(t, k % 700 < 500, 0.04)];
            h.step(&inputs, &mut out);
            stressed |= out.iter().any(|o| o.von_mises > 0.0 && o.stress_exceeded);
        }
        // A non-finite device position (rolled back, not allocated for) too.
        let bad = HandInput {
            position: [f64::NAN, 0.0, 0.0],
            ..Default::default()
        };
        h.step(&[bad, bad], &mut out);
        assert_eq!(
            allocations() - before,
            0,
            "free body {free}, {policy:?}, patches {patches}: the step allocated"
        );
        assert!(out.iter().all(|o| o.force.iter().all(|f| f.is_finite())));
        assert!(stressed, "the stress watch ran and tripped");
    }
}

/// A device read allocates nothing either, a fault included (it runs in the same loop): a
/// scripted device read through the trait over and past its trajectory, then closed.
#[test]
fn device_reads_allocate_nothing() {
    use ves_runtime::device::{Device, DeviceFault, ScriptedDevice};
    let script = ScriptedDevice::parse("hand.csv", "t,x,y,z,button\n0,0,0,0,1\n0.5,0.01,0,0,1\n1,0.01,0,0,0\n");
    let mut device: Box<dyn Device> = Box::new(script.expect("script parses"));
    let before = allocations();
    let mut moved = 0.0;
    for k in 0..2000 {
        let s = device.read(f64::from(k) * 1e-3).expect("open");
        moved += s.position[0];
        device.write([0.0, 0.0, -1.0]);
    }
    device.close();
    let fault = device.read(2.0);
    assert_eq!(allocations() - before, 0, "a device read allocated");
    assert!(moved > 0.0);
    assert_eq!(fault, Err(DeviceFault::Disconnected));
}

/// With a nonlinear basis the step (Newton on the reduced St. Venant–Kirchhoff model, its
/// tangent refreshed every few steps, the hands' compliance from its factor, the Green strain
/// watch) and the energy the haptic loop reads every step allocate nothing either.
#[test]
fn nonlinear_haptic_steps_allocate_nothing() {
    let mut basis = Arc::unwrap_or_clone(grid(false));
    let r = basis.mode_count();
    let np = r * (r + 1) / 2;
    let mut k = vec![0.0; r * r];
    for (i, l) in basis.eigenvalues.iter().enumerate() {
        k[i * r + i] = *l;
    }
    let t = (0..r * np).map(|i| 1e3 * ((i % 5) as f64 - 2.0)).collect();
    let h = (0..np * np)
        .map(|i| if i % (np + 1) == 0 { 1e6 } else { 1e4 })
        .collect();
    let model = ves_runtime::nonlinear::Polynomial::new(r, k, t, h);
    basis.nonlinear = Some(Arc::new(model.single_precision()));
    let mut h = Haptics::new(
        Arc::new(basis),
        Coupling::critically_damped(500.0, 10.0),
        1e-3,
        Scheme::Exact,
        2,
    );
    let mut out = [HandOutput::default(); 2];
    h.step(&[input(0.0, false, 0.0), input(0.0, true, 0.04)], &mut out);
    let before = allocations();
    let mut energy = 0.0f64;
    for k in 0..2000 {
        let t = f64::from(k) * 1e-3;
        let inputs = [input(t, false, 0.01 * (k % 5) as f64), input(t, k % 700 < 500, 0.04)];
        h.step(&inputs, &mut out);
        energy = energy.max(h.energy());
    }
    assert_eq!(allocations() - before, 0, "the nonlinear step allocated");
    assert!(energy > 0.0 && energy.is_finite());
    let counts = h.nonlinear_counts().expect("nonlinear");
    assert!(counts.iterations > 0 && counts.tangents > 0);
}
