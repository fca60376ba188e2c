//! The haptic step: nearest surface vertex, implicit virtual coupling, force limit, modal
//! integration, quarantine of non-finite state. Allocation-free and lock-free after `new`.
//!
//! Coupling is solved implicitly: over a step the vertex moves by p = p₀ + G F (G = Σ gⱼ φⱼφⱼᵀ,
//! gⱼ the exact force gain of mode j, plus the rigid compliance of a free body), so the
//! spring-damper force F = k(x − p) + b(ẋ − (p − p_now)/dt) is found from a 3×3 system. That
//! keeps the loop stable for any coupling stiffness, part stiffness or time step (an explicit
//! coupling goes unstable once √(k/m_eff)·dt > 2).

use crate::basis::Basis;
use crate::integrator::{ModalState, Scheme};
use crate::kdtree::{KdTree, Neighbourhood};
use crate::nonlinear::dot;
use crate::rigid_body::{M3, RigidBody, V3, m3};

/// Virtual coupling between the haptic interaction point (HIP) and the part.
#[derive(Clone, Copy, Debug)]
pub struct Coupling {
    /// Spring, N/m.
    pub stiffness: f64,
    /// Damper, N·s/m.
    pub damping: f64,
    /// Largest force sent to the device (and applied to the part), N.
    pub max_force: f64,
}

impl Default for Coupling {
    fn default() -> Self {
        Coupling {
            stiffness: 500.0,
            damping: 1.0,
            max_force: 10.0,
        }
    }
}

impl Coupling {
    /// Mass of a typical desktop device's handle, kg: what the coupling damper is tuned against.
    pub const DEVICE_MASS_KG: f64 = 1e-3;

    /// A coupling whose damper critically damps the spring against the device's handle mass
    /// (c = 2√(k·m)): the hand settles on the surface without ringing.
    pub fn critically_damped(stiffness: f64, max_force: f64) -> Coupling {
        Coupling {
            stiffness,
            damping: 2.0 * (stiffness * Self::DEVICE_MASS_KG).sqrt(),
            max_force,
        }
    }

    /// Checks that every parameter is finite and positive (damping ≥ 0).
    pub fn validate(&self) -> Result<(), InvalidSetting> {
        InvalidSetting::check("stiffness", self.stiffness, "N/m", "> 0", self.stiffness > 0.0)?;
        InvalidSetting::check("max-force", self.max_force, "N", "> 0", self.max_force > 0.0)?;
        InvalidSetting::check("damping", self.damping, "N·s/m", "≥ 0", self.damping >= 0.0)
    }
}

/// Why a part cannot move as a free body.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum FreeBodyError {
    /// The basis holds no mass properties: its part is held by supports.
    #[error("the basis has no rigid-body properties: the part is supported, not free")]
    Supported,
    /// The stored inertia tensor cannot be inverted.
    #[error("the stored inertia tensor is singular")]
    SingularInertia,
}

/// A setting out of its range: which one (named as `ves session`'s flag), its value and unit.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{setting} = {value} {unit}: out of range (finite, {requirement})")]
pub struct InvalidSetting {
    /// The setting, e.g. "duration".
    pub setting: &'static str,
    /// The value given.
    pub value: f64,
    /// Its unit.
    pub unit: &'static str,
    /// What it must be.
    pub requirement: &'static str,
}

impl InvalidSetting {
    /// `Ok` when `value` is finite and `in_range` (the test that `requirement` states).
    pub fn check(
        setting: &'static str,
        value: f64,
        unit: &'static str,
        requirement: &'static str,
        in_range: bool,
    ) -> Result<(), InvalidSetting> {
        if value.is_finite() && in_range {
            return Ok(());
        }
        Err(InvalidSetting {
            setting,
            value,
            unit,
            requirement,
        })
    }
}

/// What to do when the strain near a hand leaves the range of the linear model.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum StrainPolicy {
    /// Report it in [`HandOutput`] only.
    #[default]
    Flag,
    /// The part stops deforming further: once past the limit, the force applied to it is capped
    /// at the force whose static strain at the vertex equals the limit, while the device still
    /// gets the full coupling force (it feels the part go stiff).
    Stiffen,
    /// The hand lets go: no force this step, and a grab is released.
    Release,
}

/// Validity watch of the linear (small-strain) model at each hand's vertex: the strain along
/// the surface edges there, and with modal stress the safety factor there and of the whole part.
#[derive(Clone, Copy, Debug)]
pub struct ValidityWatch {
    /// Largest normal strain along the surface edges at the active vertex (e.g. 0.02 = 2 %).
    pub limit: f64,
    /// Reaction past the limit.
    pub policy: StrainPolicy,
    /// With a stress basis and a yield strength: the smallest safety factor (yield / von Mises)
    /// at the active vertex before the same reaction acts.
    pub min_safety_factor: f64,
}

impl Default for ValidityWatch {
    fn default() -> Self {
        ValidityWatch {
            limit: 0.02,
            policy: StrainPolicy::Flag,
            min_safety_factor: 1.0,
        }
    }
}

/// Surface neighbours of the active vertex used for its strain estimate.
const STRAIN_NEIGHBOURS: usize = 16;

/// The products q_k q_l of the largest nonlinear basis a file may hold: [`Haptics::energy`]
/// keeps them on the stack (9.4 kB).
const MAX_PAIRS: usize = ves_format::names::MAX_NONLINEAR_BASIS * (ves_format::names::MAX_NONLINEAR_BASIS + 1) / 2;

/// What one hand's device reports.
#[derive(Clone, Copy, Debug, Default)]
pub struct HandInput {
    /// HIP position, m (part frame).
    pub position: [f64; 3],
    /// HIP velocity, m/s.
    pub velocity: [f64; 3],
    /// Button held: grab the vertex picked when it was pressed; released: press on the surface.
    pub button: bool,
}

/// What a nonlinear part's steps took so far.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NewtonCounts {
    /// Newton iterations (each one force evaluation and one solve).
    pub iterations: u64,
    /// Tangent stiffnesses made and factored.
    pub tangents: u64,
    /// Steps whose tangent was not positive definite (the linear stiffness stood in).
    pub indefinite: u64,
}

/// What one hand gets back.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct HandOutput {
    /// Force for the device, N (already limited).
    pub force: [f64; 3],
    /// Active vertex (index among the basis's kept vertices).
    pub vertex: u32,
    /// Grabbing, or pressing into the surface.
    pub contact: bool,
    /// Grabbing (the button held on a picked vertex).
    pub grabbing: bool,
    /// The force limit cut the force this step.
    pub clamped: bool,
    /// Deformed position of the active vertex, m.
    pub vertex_position: [f64; 3],
    /// Elastic displacement of the active vertex (part frame, static correction included), m.
    pub displacement: [f64; 3],
    /// While grabbing: how far the hand was from the vertex when the grab began, m. The grab
    /// holds the part where it was grabbed, so this gap is carried, not pulled.
    pub grip_gap: f64,
    /// Largest normal strain along the surface edges at the active vertex, from the modal
    /// displacement at the start of the step.
    pub strain: f64,
    /// The strain passed the watch's limit (the configured reaction acted).
    pub strain_exceeded: bool,
    /// Von Mises stress at the active vertex, Pa (0 without modal stress in the basis).
    pub von_mises: f64,
    /// Yield strength over that von Mises stress (infinite without a yield strength or stress).
    pub safety_factor: f64,
    /// Largest principal stress at the active vertex, Pa (0 without modal stress).
    pub principal_stress: f64,
    /// Largest principal strain there (0 without modal stress or elastic constants).
    pub principal_strain: f64,
    /// The safety factor fell below the watch's minimum (the configured reaction acted).
    pub stress_exceeded: bool,
    /// What the hand feels wrong at the active vertex, relative, along its normal
    /// ([`crate::Basis::felt_error`]); NaN where the basis does not state it.
    pub felt_error: f64,
}

impl Default for HandOutput {
    /// Nothing touched: zeros, and no felt error stated (NaN, not an exact 0).
    fn default() -> Self {
        HandOutput {
            force: [0.0; 3],
            vertex: 0,
            contact: false,
            grabbing: false,
            clamped: false,
            vertex_position: [0.0; 3],
            displacement: [0.0; 3],
            grip_gap: 0.0,
            strain: 0.0,
            strain_exceeded: false,
            von_mises: 0.0,
            safety_factor: 0.0,
            principal_stress: 0.0,
            principal_strain: 0.0,
            stress_exceeded: false,
            felt_error: f64::NAN,
        }
    }
}

struct Hand {
    vertex: Option<u32>,
    /// The surface vertices nearest where the last search was made: pressing hands move
    /// micrometres per step, so most steps find their exact nearest vertex among these few
    /// instead of searching the tree (even on a tie between two vertices).
    near: Option<Neighbourhood>,
    grabbed: bool,
    /// While grabbing: the hand's offset from the vertex when the grab began (part frame); the
    /// spring pulls the vertex toward hand − grip. Set at the grab's first step.
    grip: Option<V3>,
    rows: Vec<f64>,
    /// How far the vertex moves per newton of its own force over one step: the modes, and for a
    /// free body the rigid motion (both fixed for a vertex, so computed when it is picked).
    g: M3,
    /// Static correction Gᵢᵢ − Φᵢ Λ⁻¹ Φᵢᵀ (zero when off or not stored): the compliance the
    /// truncated modes miss, added instantly.
    residual: M3,
    /// Force applied to the part at the vertex last step (part frame).
    last_force: V3,
    /// Force applied to the part this step (part frame): zero when the hand applied none.
    applied: V3,
    /// Per surface neighbour k: the modal row of the edge strain, (φ_k − φ_i)·d / |d|².
    edge_rows: Vec<f64>,
    /// A nonlinear basis: each edge's relative displacement rows, [edge][component][mode], and
    /// its rest vector, for its Green strain (rotation-free) instead of the linear one.
    edge_vectors: Vec<f64>,
    edge_rest: [V3; STRAIN_NEIGHBOURS],
    /// Neighbours in `edge_rows`.
    edges: usize,
    /// Per neighbour: static edge strain per newton at the vertex, Σ_j edge_j φ_j / λ_j.
    strain_per_newton: [V3; STRAIN_NEIGHBOURS],
    /// The stiffen cap acted last step (it stays on until the load falls below it).
    capped: bool,
    /// The vertex's modal stress rows, `stress_rows[k·r + j]` (Voigt component k of mode j).
    stress_rows: Vec<f64>,
    /// Per Voigt component: static stress per newton at the vertex, Σ_j σ_kj φ_j / λ_j.
    stress_per_newton: [V3; 6],
    /// The force on the part when the part alarm came on (stiffen holds it there).
    alarm_force: Option<f64>,
    /// Let go by the release policy: no force until the button is released (re-grabbing at once
    /// while it is still held made release/grab cycles that pumped the part).
    latched: bool,
}

/// Haptic simulation of one part.
pub struct Haptics {
    basis: std::sync::Arc<Basis>,
    tree: KdTree,
    state: ModalState,
    saved: (Vec<f64>, Vec<f64>),
    f: Vec<f64>,
    hands: Vec<Hand>,
    coupling: Coupling,
    rigid: Option<RigidBody>,
    saved_rigid: Option<RigidBody>,
    /// The free body as it started (what [`Haptics::reset`] returns to).
    initial_rigid: Option<RigidBody>,
    static_correction: bool,
    watch: ValidityWatch,
    /// Steps whose result was non-finite and was rolled back.
    pub quarantined: u64,
    /// The whole part's safety factor is below the watch's minimum (set by whoever computes the
    /// full stress field, e.g. the drawing thread): the hands' stress criterion is then met too.
    part_alarm: bool,
    /// The nonlinear model's implicit step, when the basis has one.
    nonlinear: Option<NonlinearStep>,
}

/// A nonlinear basis's step ([`crate::nonlinear::Stepper`]) and its scratch.
struct NonlinearStep {
    model: std::sync::Arc<crate::nonlinear::Polynomial>,
    stepper: crate::nonlinear::Stepper,
    /// One right-hand side (r).
    col: Vec<f64>,
    /// The acceleration before the step (a rollback restores it).
    saved_accel: Vec<f64>,
}

/// One hand's device state in the part (body) frame.
struct PartInput {
    position: V3,
    velocity: V3,
    button: bool,
}

/// The active vertex over the coming step.
struct Prediction {
    /// Where it ends the step if the hand applies no force (free modal motion, and the static
    /// correction's standing displacement), m.
    free_end: V3,
    /// Where it is now, m.
    now: V3,
    /// How far it moves per newton applied there over the step: modes, static correction and,
    /// for a free body, the rigid motion.
    compliance: M3,
}

/// Total force and torque (about the centre of mass) the hands apply to a free body, world frame.
#[derive(Default)]
struct Wrench {
    force: V3,
    torque: V3,
}

/// Stage 1: the device state in the part (body) frame; for a free body, relative to where the
/// body will be at the end of the step (`predicted`).
fn to_part_frame(world: &HandInput, predicted: Option<&RigidBody>) -> PartInput {
    let (x, v) = (V3::from(world.position), V3::from(world.velocity));
    match predicted {
        None => PartInput {
            position: x,
            velocity: v,
            button: world.button,
        },
        Some(rb) => PartInput {
            position: rb.to_body(x),
            velocity: rb.vector_to_body(v - rb.point_velocity(x)),
            button: world.button,
        },
    }
}

impl Haptics {
    /// A simulation at rest with time step `dt` and up to `hands` hands.
    pub fn new(basis: std::sync::Arc<Basis>, coupling: Coupling, dt: f64, scheme: Scheme, hands: usize) -> Haptics {
        let r = basis.mode_count();
        let pts: Vec<[f64; 3]> = basis.surface_vertices.iter().map(|&v| basis.rest[v as usize]).collect();
        let tree = KdTree::new(&pts, &basis.surface_vertices);
        let state = ModalState::new(&basis.eigenvalues, basis.alpha, basis.beta, dt, scheme);
        let nonlinear = basis.nonlinear.clone().map(|model| {
            let c: Vec<f64> = basis.eigenvalues.iter().map(|l| basis.alpha + basis.beta * l).collect();
            NonlinearStep {
                stepper: crate::nonlinear::Stepper::new(&model, &c, dt),
                model,
                col: vec![0.0; r],
                saved_accel: vec![0.0; r],
            }
        });
        let hands = (0..hands)
            .map(|_| Hand {
                vertex: None,
                near: None,
                grabbed: false,
                grip: None,
                rows: vec![0.0; 3 * r],
                g: M3::zeros(),
                residual: M3::zeros(),
                last_force: V3::zeros(),
                applied: V3::zeros(),
                edge_rows: vec![0.0; STRAIN_NEIGHBOURS * r],
                edge_vectors: vec![
                    0.0;
                    if basis.nonlinear.is_some() {
                        STRAIN_NEIGHBOURS * 3 * r
                    } else {
                        0
                    }
                ],
                edge_rest: [V3::zeros(); STRAIN_NEIGHBOURS],
                edges: 0,
                strain_per_newton: [V3::zeros(); STRAIN_NEIGHBOURS],
                capped: false,
                stress_rows: vec![0.0; 6 * r],
                stress_per_newton: [V3::zeros(); 6],
                alarm_force: None,
                latched: false,
            })
            .collect();
        Haptics {
            basis,
            tree,
            state,
            saved: (vec![0.0; r], vec![0.0; r]),
            f: vec![0.0; r],
            hands,
            coupling,
            rigid: None,
            saved_rigid: None,
            initial_rigid: None,
            static_correction: true,
            watch: ValidityWatch::default(),
            quarantined: 0,
            part_alarm: false,
            nonlinear,
        }
    }

    /// Makes the part a free body moving under the hands' forces and `gravity` (m/s²), from the
    /// basis's mass properties; `damping` (1/s) bleeds both momenta, so a part hanging from a
    /// hand stops swinging. Inputs and outputs are then in the world frame, which starts equal
    /// to the part frame; a part held in some directions moves along the rigid motions its
    /// supports leave only. Fails when the basis holds no mass properties (a part held in every
    /// direction).
    pub fn set_free_body(&mut self, gravity: [f64; 3], damping: f64) -> Result<(), FreeBodyError> {
        let props = self.basis.rigid.ok_or(FreeBodyError::Supported)?;
        let mut body = RigidBody::new(&props, gravity).ok_or(FreeBodyError::SingularInertia)?;
        body.damping = damping.max(0.0);
        self.rigid = Some(body);
        self.initial_rigid = Some(body);
        for h in &mut self.hands {
            h.vertex = None; // the step compliance gains the rigid part at the next pick
        }
        Ok(())
    }

    /// Uses the stored static compliance blocks at the active vertex (on by default when the
    /// basis has them): the felt stiffness is then exact whatever the number of modes.
    pub fn set_static_correction(&mut self, on: bool) {
        self.static_correction = on;
        for h in &mut self.hands {
            h.vertex = None; // recompute the residual at the next pick
        }
    }

    /// Sets the validity watch (default: flag past 2 % strain, or a safety factor below 1).
    pub fn set_validity_watch(&mut self, watch: ValidityWatch) {
        self.watch = watch;
    }

    /// The validity watch in force.
    pub fn validity_watch(&self) -> ValidityWatch {
        self.watch
    }

    /// Says whether the whole part's safety factor is below the watch's minimum (a stress peak
    /// away from the hands, which the haptic step does not compute): while on, every hand in
    /// contact counts as past the stress limit and the policy reacts (stiffen holds the force
    /// at what it was when the alarm came on).
    pub fn set_part_alarm(&mut self, on: bool) {
        self.part_alarm = on;
    }

    /// The rigid-body state of a free part.
    pub fn rigid_body(&self) -> Option<&RigidBody> {
        self.rigid.as_ref()
    }

    /// Modal state (q, v).
    pub fn state(&self) -> &ModalState {
        &self.state
    }

    /// The basis simulated.
    pub fn basis(&self) -> &Basis {
        &self.basis
    }

    /// A shared handle on the basis (for a drawing thread).
    pub fn basis_arc(&self) -> std::sync::Arc<Basis> {
        self.basis.clone()
    }

    fn select(&mut self, hand: usize, vertex: u32) {
        let r = self.state.q.len();
        let basis = &self.basis;
        let hd = &mut self.hands[hand];
        if hd.vertex == Some(vertex) {
            return;
        }
        basis.gather_contact_rows(vertex as usize, &mut hd.rows);
        let rows = &hd.rows;
        let state = &self.state;
        let modal = M3::from_fn(|a, b| {
            (0..r)
                .map(|j| state.transition(j).force_gain() * rows[a * r + j] * rows[b * r + j])
                .sum()
        });
        // A free body's rigid step compliance at this vertex is constant in the body frame.
        let rest = V3::from(basis.rest[vertex as usize]);
        let rigid = self
            .rigid
            .map_or(M3::zeros(), |rb| rb.step_compliance_body(rest, state.dt()));
        let g = modal + rigid;
        // Residual compliance: exact block minus what the loaded modes already give.
        let residual = match basis.compliance_of(vertex as usize).filter(|_| self.static_correction) {
            Some(exact) => {
                m3(&exact)
                    - M3::from_fn(|a, b| {
                        (0..r)
                            .map(|j| rows[a * r + j] * rows[b * r + j] / basis.eigenvalues[j])
                            .sum::<f64>()
                    })
            }
            None => M3::zeros(),
        };
        hd.vertex = Some(vertex);
        hd.g = g;
        hd.residual = residual;
        hd.last_force = V3::zeros();
        hd.capped = false;
        // Edge-strain rows: the axial strain of edge (i, k) is Σ_j q_j (φ_k − φ_i)_j·d / |d|².
        let i = vertex as usize;
        let (lo, hi) = (basis.neighbour_ptr[i] as usize, basis.neighbour_ptr[i + 1] as usize);
        let n3 = 3 * basis.rest.len();
        hd.edges = (hi - lo).min(STRAIN_NEIGHBOURS);
        for (e, &k) in basis.neighbours[lo..lo + hd.edges].iter().enumerate() {
            let k = k as usize;
            let d: [f64; 3] = std::array::from_fn(|c| basis.rest[k][c] - basis.rest[i][c]);
            let l2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            for j in 0..r {
                let col = &basis.phi[j * n3..(j + 1) * n3];
                hd.edge_rows[e * r + j] = (0..3)
                    .map(|c| (f64::from(col[3 * k + c]) - f64::from(col[3 * i + c])) * d[c])
                    .sum::<f64>()
                    / l2.max(f64::MIN_POSITIVE);
            }
            if !hd.edge_vectors.is_empty() {
                hd.edge_rest[e] = V3::from(d);
                for c in 0..3 {
                    for j in 0..r {
                        let col = &basis.phi[j * n3..(j + 1) * n3];
                        hd.edge_vectors[(3 * e + c) * r + j] = f64::from(col[3 * k + c]) - f64::from(col[3 * i + c]);
                    }
                }
            }
            let edge = &hd.edge_rows[e * r..(e + 1) * r];
            hd.strain_per_newton[e] = V3::from_fn(|a, _| {
                (0..r)
                    .map(|j| edge[j] * hd.rows[a * r + j] / basis.eigenvalues[j])
                    .sum()
            });
        }
        if basis.stress.is_some() {
            for j in 0..r {
                let mode = basis.stress_mode(j).unwrap_or(&[]);
                for k in 0..6 {
                    hd.stress_rows[k * r + j] = mode.get(6 * i + k).map_or(0.0, |v| f64::from(*v));
                }
            }
            for k in 0..6 {
                let row = &hd.stress_rows[k * r..(k + 1) * r];
                hd.stress_per_newton[k] =
                    V3::from_fn(|a, _| (0..r).map(|j| row[j] * hd.rows[a * r + j] / basis.eigenvalues[j]).sum());
            }
        }
    }

    /// Stress at hand `k`'s vertex for the current modal state (None without stress).
    fn vertex_stress(&self, k: usize) -> Option<[f64; 6]> {
        self.basis.stress.as_ref()?;
        let hd = &self.hands[k];
        let r = self.state.q.len();
        let s: [f64; 6] = std::array::from_fn(|c| {
            hd.stress_rows[c * r..(c + 1) * r]
                .iter()
                .zip(&self.state.q)
                .map(|(a, q)| a * q)
                .sum()
        });
        Some(s)
    }

    /// Largest |edge strain| at hand `k`'s vertex for the current modal state: the linear axial
    /// strain, or with a nonlinear basis the Green strain ((|d + Δu|² − |d|²) / 2|d|², blind to
    /// rotation, the strain St. Venant–Kirchhoff is linear in).
    fn edge_strain(&self, k: usize) -> f64 {
        let hd = &self.hands[k];
        let r = self.state.q.len();
        if !hd.edge_vectors.is_empty() {
            let q = &self.state.q;
            return (0..hd.edges)
                .map(|e| {
                    let du = V3::from_fn(|c, _| dot(&hd.edge_vectors[(3 * e + c) * r..(3 * e + c + 1) * r], q));
                    let d = hd.edge_rest[e];
                    ((d + du).norm_squared() - d.norm_squared()).abs() / (2.0 * d.norm_squared()).max(f64::MIN_POSITIVE)
                })
                .fold(0.0, f64::max);
        }
        (0..hd.edges)
            .map(|e| {
                hd.edge_rows[e * r..(e + 1) * r]
                    .iter()
                    .zip(&self.state.q)
                    .map(|(a, q)| a * q)
                    .sum::<f64>()
                    .abs()
            })
            .fold(0.0, f64::max)
    }

    /// Back to the start: the part at rest (and a free body where and as it started), every
    /// hand let go. No allocation (callable from the haptic thread).
    pub fn reset(&mut self) {
        self.state.q.fill(0.0);
        self.state.v.fill(0.0);
        if let Some(nl) = &mut self.nonlinear {
            nl.stepper.reset();
        }
        self.rigid = self.initial_rigid;
        for h in &mut self.hands {
            h.vertex = None;
            h.near = None;
            h.grabbed = false;
            h.grip = None;
            h.last_force = V3::zeros();
            h.capped = false;
            h.alarm_force = None;
            h.latched = false;
        }
    }

    /// The part's elastic and kinetic energy, J (mass-normalised modes): ½|v|² + W(q), with the
    /// nonlinear model's strain energy when the basis has one. No lock; no allocation for any
    /// basis a file holds (a nonlinear model of more than 48 vectors, built in code, allocates
    /// its products).
    pub fn energy(&self) -> f64 {
        match &self.nonlinear {
            None => self.state.energy(),
            Some(nl) => {
                let kinetic: f64 = self.state.v.iter().map(|v| 0.5 * v * v).sum();
                // The products q_k q_l on this thread's stack: no lock, no allocation for any
                // basis a file can hold (its vectors are bounded); a larger model built in code
                // takes a buffer from the heap.
                let mut stack = [0.0; MAX_PAIRS];
                let np = nl.model.pairs();
                let w = if np <= MAX_PAIRS {
                    nl.model.energy_in(&self.state.q, &mut stack)
                } else {
                    nl.model.energy_in(&self.state.q, &mut vec![0.0; np])
                };
                kinetic + w
            }
        }
    }

    /// The nonlinear step's counters: Newton iterations, tangents made, steps with an
    /// indefinite tangent (None for a linear basis).
    pub fn nonlinear_counts(&self) -> Option<NewtonCounts> {
        self.nonlinear.as_ref().map(|nl| NewtonCounts {
            iterations: nl.stepper.iterations,
            tangents: nl.stepper.tangents,
            indefinite: nl.stepper.indefinite,
        })
    }

    /// The vertex hand `k` holds by a grab, if it does.
    pub fn grabbed_vertex(&self, k: usize) -> Option<u32> {
        self.hands.get(k).filter(|h| h.grabbed).and_then(|h| h.vertex)
    }

    /// One haptic step for every hand in `inputs` (at most the number given to `new`), in named
    /// stages: each hand is brought into the part frame, picks or keeps its vertex, predicts
    /// that vertex's free motion, solves the coupling force, passes the validity watch and
    /// applies the force; then the modes (and a free body) advance, or roll back if non-finite.
    pub fn step(&mut self, inputs: &[HandInput], outputs: &mut [HandOutput]) {
        self.f.fill(0.0);
        for h in &mut self.hands {
            h.applied = V3::zeros();
        }
        let mut wrench = Wrench::default();
        // Where a free body will be after a step without the hands' forces: the coupling is
        // solved at the end of the step, like the modes (implicit). The same for every hand.
        let predicted = self.rigid.map(|mut rb| {
            rb.step(V3::zeros(), V3::zeros(), self.state.dt());
            rb
        });
        // The nonlinear model's free motion over the step (Newton, A factored for the hands).
        if let Some(nl) = &mut self.nonlinear {
            nl.stepper.free(&nl.model, &self.state.q, &self.state.v);
        }
        for (k, world) in inputs.iter().enumerate().take(self.hands.len()) {
            let out = &mut outputs[k];
            *out = HandOutput::default();
            let input = to_part_frame(world, predicted.as_ref());
            let Some(vertex) = self.pick(k, &input) else { continue };
            let prediction = self.predict(k, vertex);
            if self.hands[k].grabbed && self.hands[k].grip.is_none() {
                self.hands[k].grip = Some(input.position - prediction.now);
            }
            let Some((force, magnitude)) = self.coupling_force(k, vertex, &input, &prediction, out) else {
                continue;
            };
            let (force, device) = self.watch_strain(k, force, out);
            self.apply(k, vertex, (force, device, magnitude), &prediction, &mut wrench, out);
        }
        self.advance(&wrench, outputs);
    }

    /// Stage 2: the hand's active vertex: the nearest surface vertex unless it holds a grab (the
    /// button pressed while touching keeps the vertex until released). `None`: no vertex (a
    /// non-finite HIP), no force.
    fn pick(&mut self, k: usize, input: &PartInput) -> Option<u32> {
        if self.hands[k].latched {
            if input.button {
                return None;
            }
            self.hands[k].latched = false;
        }
        if !self.hands[k].grabbed {
            let q: [f64; 3] = input.position.into();
            let cached = self.hands[k].near.as_ref().and_then(|n| n.nearest(q));
            let v = match cached {
                Some(v) => v,
                None => {
                    let n = self.tree.neighbourhood(q)?;
                    self.hands[k].near = Some(n);
                    n.first()
                }
            };
            self.select(k, v);
            self.hands[k].grabbed = input.button;
        } else if !input.button {
            self.hands[k].grabbed = false;
        }
        if !self.hands[k].grabbed {
            self.hands[k].grip = None;
        }
        self.hands[k].vertex
    }

    /// Stage 3: the vertex's free motion over the step and its step compliance.
    fn predict(&mut self, k: usize, vertex: u32) -> Prediction {
        if self.nonlinear.is_some() {
            return self.predict_nonlinear(k, vertex);
        }
        let hd = &self.hands[k];
        let r = self.state.q.len();
        let rest = V3::from(self.basis.rest[vertex as usize]);
        let (mut free_end, mut now) = (rest, rest);
        for j in 0..r {
            let (qf, _) = self.state.transition(j).free(self.state.q[j], self.state.v[j]);
            let phi = V3::new(hd.rows[j], hd.rows[r + j], hd.rows[2 * r + j]);
            free_end += phi * qf;
            now += phi * self.state.q[j];
        }
        // The static correction is quasi-static: it moved the vertex by R·F_last already.
        let shift = hd.residual * hd.last_force;
        Prediction {
            free_end: free_end + shift,
            now: now + shift,
            compliance: hd.g + hd.residual,
        }
    }

    /// Stage 3 for a nonlinear basis: the free end from the Newton solve, and the step compliance
    /// Φᵥ A⁻¹ Φᵥᵀ from its factor (three solves).
    fn predict_nonlinear(&mut self, k: usize, vertex: u32) -> Prediction {
        let r = self.state.q.len();
        let rest = V3::from(self.basis.rest[vertex as usize]);
        let (hd, nl) = (&self.hands[k], self.nonlinear.as_mut().expect("a nonlinear basis"));
        let phi = |q: &[f64]| {
            V3::new(
                dot(&hd.rows[..r], q),
                dot(&hd.rows[r..2 * r], q),
                dot(&hd.rows[2 * r..], q),
            )
        };
        let free_end = rest + phi(nl.stepper.free_motion());
        let now = rest + phi(&self.state.q);
        let mut compliance = M3::zeros();
        for c in 0..3 {
            nl.col.copy_from_slice(&hd.rows[c * r..(c + 1) * r]);
            nl.stepper.solve(&mut nl.col);
            compliance.set_column(c, &phi(&nl.col));
        }
        Prediction {
            free_end,
            now,
            compliance,
        }
    }

    /// Stage 4: the coupling force on the part (grab: 3-D spring-damper; press: along the outward
    /// normal, pushing only), solved implicitly, then limited to the device's force. Returns the
    /// force and its magnitude before the limit; `None` when it is not finite (no force).
    fn coupling_force(
        &self,
        k: usize,
        vertex: u32,
        input: &PartInput,
        p: &Prediction,
        out: &mut HandOutput,
    ) -> Option<(V3, f64)> {
        let c = self.coupling;
        let dt = self.state.dt();
        let (x, xd) = (input.position, input.velocity);
        // The damper acts on the vertex's mean velocity over the step, (p − p_now)/dt, not on
        // its end velocity: modes with ω·dt > π are undamped between samples and their end
        // velocity aliases, which a damper on it would pump. With p = p₀ + G F, the spring
        // and damper together give (I + (k + b/dt) G) F = k(x − p₀) + b(ẋ − (p₀ − p_now)/dt).
        let kb = c.stiffness + c.damping / dt;
        let mean_velocity = (p.free_end - p.now) / dt;
        let force = if self.hands[k].grabbed {
            let x = x - self.hands[k].grip.unwrap_or_else(V3::zeros);
            let m = p.compliance * kb + M3::identity();
            let rhs = (x - p.free_end) * c.stiffness + (xd - mean_velocity) * c.damping;
            m.lu().solve(&rhs)
        } else {
            let n = V3::from(self.basis.normals[vertex as usize]);
            let depth = (p.free_end - x).dot(&n);
            if depth > 0.0 {
                let rate = (mean_velocity - xd).dot(&n);
                let ngn = n.dot(&(p.compliance * n));
                let fn_ = ((c.stiffness * depth + c.damping * rate) / (1.0 + kb * ngn)).max(0.0);
                Some(n * -fn_)
            } else {
                Some(V3::zeros())
            }
        };
        let mut force = force.filter(|f| f.iter().all(|v| v.is_finite()))?;
        let magnitude = force.norm();
        if magnitude > c.max_force {
            force *= c.max_force / magnitude;
            out.clamped = true;
        }
        Some((force, magnitude))
    }

    /// Stage 5: the validity watch of the linear model at this vertex and its reaction. Returns
    /// the force the part gets and the one the hand feels.
    fn watch_strain(&mut self, k: usize, force: V3, out: &mut HandOutput) -> (V3, V3) {
        let strain = self.edge_strain(k);
        let watch = self.watch;
        out.strain = strain;
        out.strain_exceeded = strain > watch.limit;
        // The stress criterion: yield / von Mises below the minimum safety factor.
        let allowed = self.basis.yield_strength.map(|y| y / watch.min_safety_factor);
        let stress = self.vertex_stress(k);
        out.von_mises = stress.map_or(0.0, crate::visual::von_mises);
        // One 3×3 eigenvalue problem per step serves both principal values.
        let principal = stress.map(crate::visual::principal_stresses);
        out.principal_stress = principal.map_or(0.0, |p| p[0]);
        out.principal_strain = match (principal, self.basis.elastic) {
            (Some(p), Some(e)) => crate::visual::principal_strain_max(p, e),
            _ => 0.0,
        };
        out.safety_factor = match self.basis.yield_strength {
            Some(y) if out.von_mises > 0.0 => y / out.von_mises,
            _ => f64::INFINITY,
        };
        out.stress_exceeded = allowed.is_some_and(|a| out.von_mises > a) || self.part_alarm;
        // A peak elsewhere in the part (the drawing thread's alarm) caps this hand's load at what
        // it was when the alarm came. The cap stays after the alarm clears until the hand pulls
        // less than it: held at the cap the part sits at the limit, the alarm flickers from
        // frame to frame, and a cap renewed at each flicker crept up with the pull.
        let now = force.norm();
        match self.hands[k].alarm_force {
            None if self.part_alarm => self.hands[k].alarm_force = Some(now),
            Some(a) if !self.part_alarm && now <= a => self.hands[k].alarm_force = None,
            _ => {}
        }
        let exceeded = out.strain_exceeded || out.stress_exceeded;
        let (mut force, mut device) = (force, force);
        match watch.policy {
            StrainPolicy::Flag => {}
            StrainPolicy::Stiffen if exceeded || self.hands[k].capped || self.hands[k].alarm_force.is_some() => {
                // Static strain per newton along this force's direction, over the edges.
                let hd = &self.hands[k];
                let dir = force / now.max(1e-300);
                let per_newton = hd.strain_per_newton[..hd.edges]
                    .iter()
                    .map(|c| c.dot(&dir).abs())
                    .fold(0.0, f64::max);
                let mut cap = watch.limit / per_newton.max(1e-300);
                // And the static von Mises stress per newton in that direction.
                if let (Some(a), Some(_)) = (allowed, self.basis.stress.as_ref()) {
                    let vm = crate::visual::von_mises(std::array::from_fn(|c| hd.stress_per_newton[c].dot(&dir)));
                    cap = cap.min(a / vm.max(1e-300));
                }
                // A peak elsewhere: no load through this vertex beyond what it carried then.
                if let Some(a) = hd.alarm_force {
                    cap = cap.min(a);
                }
                let capped = now > cap;
                if capped {
                    force *= cap / now;
                }
                self.hands[k].capped = capped;
            }
            StrainPolicy::Stiffen => {}
            StrainPolicy::Release if exceeded => {
                force = V3::zeros();
                device = V3::zeros();
                self.hands[k].grabbed = false;
                self.hands[k].latched = true;
            }
            StrainPolicy::Release => {}
        }
        (force, device)
    }

    /// Stage 6: the force into the modal load (and a free body's wrench), the device's force and
    /// the hand's report.
    fn apply(
        &mut self,
        k: usize,
        vertex: u32,
        (force, device, magnitude): (V3, V3, f64),
        p: &Prediction,
        wrench: &mut Wrench,
        out: &mut HandOutput,
    ) {
        let r = self.state.q.len();
        let hd = &self.hands[k];
        for j in 0..r {
            self.f[j] += hd.rows[j] * force.x + hd.rows[r + j] * force.y + hd.rows[2 * r + j] * force.z;
        }
        let (p_w, device_w) = match &self.rigid {
            None => (p.now, device),
            Some(rb) => {
                let (f, at) = (rb.vector_to_world(force), rb.to_world(p.now));
                wrench.force += f;
                wrench.torque += (at - rb.position).cross(&f);
                (at, rb.vector_to_world(device))
            }
        };
        out.force = (-device_w).into();
        out.vertex = vertex;
        out.felt_error = self.basis.felt_error(vertex as usize).unwrap_or(f64::NAN);
        out.contact = hd.grabbed || magnitude > 0.0;
        out.vertex_position = p_w.into();
        out.displacement = (p.now - V3::from(self.basis.rest[vertex as usize])).into();
        out.grip_gap = hd.grip.map_or(0.0, |g| g.norm());
        out.grabbing = hd.grabbed;
        self.hands[k].last_force = force;
        self.hands[k].applied = force;
    }

    /// Stage 7: advance the modes (and a free body); roll everything back if the result is not
    /// finite, and then send no force.
    fn advance(&mut self, wrench: &Wrench, outputs: &mut [HandOutput]) {
        self.saved.0.copy_from_slice(&self.state.q);
        self.saved.1.copy_from_slice(&self.state.v);
        self.saved_rigid = self.rigid;
        match &mut self.nonlinear {
            Some(nl) => {
                nl.saved_accel.copy_from_slice(nl.stepper.acceleration());
                nl.stepper.finish(&mut self.state.q, &mut self.state.v, &self.f);
            }
            None => self.state.step(&self.f),
        }
        let dt = self.state.dt();
        if let Some(rb) = &mut self.rigid {
            rb.step(wrench.force, wrench.torque, dt);
        }
        let finite = self.rigid.is_none_or(|rb| rb.is_finite())
            && self.state.q.iter().chain(&self.state.v).all(|v| v.is_finite());
        if !finite {
            self.state.q.copy_from_slice(&self.saved.0);
            self.state.v.copy_from_slice(&self.saved.1);
            self.rigid = self.saved_rigid;
            if let Some(nl) = &mut self.nonlinear {
                nl.stepper.set_acceleration(&nl.saved_accel);
            }
            for o in outputs.iter_mut() {
                o.force = [0.0; 3];
            }
            for h in &mut self.hands {
                h.applied = V3::zeros();
            }
            self.quarantined += 1;
        }
    }

    /// Takes over the state of `other`, a simulation of the same part in another modal space:
    /// q = T q_other and v = T v_other with T the stored transfer matrix (row-major
    /// `r × r_other`), each hand on the vertex nearest its old one with its grab and last force,
    /// the rigid-body state as is. Allocation-free: a switch can happen inside the haptic loop.
    pub fn transfer_from(&mut self, other: &Haptics, t: &[f64]) {
        let (r, ro) = (self.state.q.len(), other.state.q.len());
        debug_assert_eq!(t.len(), r * ro);
        for i in 0..r {
            let row = &t[i * ro..(i + 1) * ro];
            self.state.q[i] = row.iter().zip(&other.state.q).map(|(a, b)| a * b).sum();
            self.state.v[i] = row.iter().zip(&other.state.v).map(|(a, b)| a * b).sum();
        }
        if self.rigid.is_some() {
            self.rigid = other.rigid;
        }
        for k in 0..self.hands.len().min(other.hands.len()) {
            let oh = &other.hands[k];
            self.hands[k].vertex = None;
            self.hands[k].grabbed = false;
            if let Some(v) = oh.vertex
                && let Some((nv, _)) = self.tree.nearest(other.basis.rest[v as usize])
            {
                self.select(k, nv);
                self.hands[k].grabbed = oh.grabbed;
                self.hands[k].last_force = oh.last_force;
                // The hand keeps holding the same point of the part: the grip follows the
                // vertex's move from the old mesh's vertex to the new one's.
                let moved = V3::from(other.basis.rest[v as usize]) - V3::from(self.basis.rest[nv as usize]);
                self.hands[k].grip = oh.grip.map(|g| g + moved);
            }
        }
    }

    /// Writes what a drawing thread needs into `out` as space `space`: the pose, q and the
    /// hands' loads.
    pub fn publish_into(&self, space: usize, out: &mut crate::snapshot::Published) {
        out.set(space, self.pose(), &self.state.q);
        out.set_loads(self.hand_loads());
    }

    /// Each hand's load on the part this step: (its kept vertex, the force on the part, N, part
    /// frame); hands that applied none are left out.
    pub fn hand_loads(&self) -> impl Iterator<Item = (u32, [f64; 3])> + '_ {
        self.hands
            .iter()
            .filter(|h| h.applied != V3::zeros())
            .filter_map(|h| h.vertex.map(|v| (v, h.applied.into())))
    }

    /// What each `[[fixed]]` support exerts on the part now, the hands' loads included
    /// ([`Basis::support_reactions_loaded`]); `None` when the basis stores no reactions.
    pub fn support_reactions(&self) -> Option<Vec<[f64; 6]>> {
        let sr = self.basis.support_reactions.as_ref()?;
        let mut out = vec![[0.0; 6]; sr.count()];
        let mut work = crate::basis::ReactionWork::for_basis(&self.basis);
        self.basis
            .support_reactions_loaded(&self.state.q, self.hand_loads(), &mut work, &mut out);
        Some(out)
    }

    /// The pose a drawing thread needs: centre of mass in the world, then the unit quaternion
    /// body → world; all zero for a part that is not a free body (drawn where it was meshed).
    pub fn pose(&self) -> [f64; 7] {
        match &self.rigid {
            Some(rb) => {
                let (x, o) = (rb.position, rb.orientation);
                [x.x, x.y, x.z, o.w, o.i, o.j, o.k]
            }
            None => [0.0; 7],
        }
    }

    /// Displacement of kept vertex `i` now, m.
    pub fn displacement(&self, i: usize) -> [f64; 3] {
        let n3 = 3 * self.basis.vertex_count();
        let mut u = [0.0; 3];
        for (j, q) in self.state.q.iter().enumerate() {
            for (c, uc) in u.iter_mut().enumerate() {
                *uc += q * f64::from(self.basis.phi[j * n3 + 3 * i + c]);
            }
        }
        u
    }
}

#[cfg(test)]
mod strain_tests {
    use super::*;
    use std::sync::Arc;

    /// A flat 3×3 grid of vertices (z = 0, spacing 1 cm, 8 triangles) with one mode: a uniform
    /// stretch along x, u = (100 x, 0, 0) per unit q, so the strain is exactly 100 q; damped
    /// (α = 100/s, ζ = 0.5) so a held pull settles.
    fn stretch_basis() -> Arc<Basis> {
        Arc::new(crate::basis::stretch_grid(100.0, 1e4, 100.0))
    }

    fn grab_centre(policy: StrainPolicy, pull: f64, steps: usize) -> (Haptics, HandOutput) {
        let mut h = Haptics::new(stretch_basis(), Coupling::default(), 1e-3, Scheme::Exact, 1);
        h.set_validity_watch(ValidityWatch {
            limit: 0.02,
            policy,
            ..ValidityWatch::default()
        });
        let mut out = [HandOutput::default()];
        let centre = [0.01, 0.01, 0.0];
        for k in 0..steps {
            let dx = if k == 0 { 0.0 } else { pull };
            let input = HandInput {
                position: [centre[0] + dx, centre[1], centre[2]],
                velocity: [0.0; 3],
                button: true,
            };
            h.step(&[input], &mut out);
        }
        (h, out[0])
    }

    /// A grab holds the part where it was grabbed: a hand that starts 0.46 mm from the vertex
    /// and moves 1 mm along a direction no mode moves (y on the stretch grid: no compliance)
    /// feels k · 1 mm = 0.5 N on a 500 N/m coupling, not k · 1.46 mm = 0.73 N, and the gap is
    /// reported. Let go and grabbed again from elsewhere, the new gap is taken.
    #[test]
    fn a_grab_carries_the_initial_gap_instead_of_pulling_it() {
        let mut h = Haptics::new(stretch_basis(), Coupling::default(), 1e-3, Scheme::Exact, 1);
        assert_eq!(h.coupling.stiffness, 500.0);
        let mut out = [HandOutput::default()];
        let at = |y: f64, button: bool| HandInput {
            position: [0.01, 0.01 + y, 0.0],
            velocity: [0.0; 3],
            button,
        };
        for k in 0..300 {
            h.step(&[at(if k == 0 { 0.46e-3 } else { 1.46e-3 }, true)], &mut out);
        }
        assert_eq!(out[0].vertex, 4, "the centre vertex");
        assert!((out[0].grip_gap - 0.46e-3).abs() < 1e-12, "{}", out[0].grip_gap);
        assert!((-out[0].force[1] - 0.5).abs() < 1e-9, "{:?}", out[0].force);
        h.step(&[at(2e-3, false)], &mut out);
        for k in 0..300 {
            h.step(&[at(if k == 0 { 2e-3 } else { 2.5e-3 }, true)], &mut out);
        }
        assert!((out[0].grip_gap - 2e-3).abs() < 1e-12, "{}", out[0].grip_gap);
        assert!((-out[0].force[1] - 0.25).abs() < 1e-9, "{:?}", out[0].force);
    }

    /// A pressing hand skips most nearest-vertex searches (its nearest vertex is proven to be
    /// among the few found by the last search) and still gets the exact nearest vertex every step: a slow
    /// sweep above the grid, diagonally across every Voronoi boundary, against brute force.
    #[test]
    fn a_pressing_hand_gets_the_exact_nearest_vertex_every_step() {
        let basis = stretch_basis();
        let mut h = Haptics::new(basis.clone(), Coupling::default(), 1e-3, Scheme::Exact, 1);
        let mut out = [HandOutput::default()];
        let (mut searches, steps) = (0, 2000);
        for k in 0..steps {
            let t = k as f64 / steps as f64;
            let q = [-0.002 + 0.024 * t, 0.0213 * t, 0.003];
            let before = h.hands[0].near.map(|n| n.at);
            h.step(
                &[HandInput {
                    position: q,
                    velocity: [0.0; 3],
                    button: false,
                }],
                &mut out,
            );
            searches += usize::from(h.hands[0].near.map(|n| n.at) != before);
            let brute = basis
                .surface_vertices
                .iter()
                .copied()
                .min_by(|&a, &b| {
                    let d = |v: u32| {
                        let p = basis.rest[v as usize];
                        (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)
                    };
                    d(a).total_cmp(&d(b))
                })
                .expect("vertices");
            assert_eq!(out[0].vertex, brute, "step {k} at {q:?}");
        }
        assert!(searches < steps / 4, "{searches} searches in {steps} steps");
    }

    #[test]
    fn edge_strain_of_a_uniform_stretch_is_exact() {
        let mut h = Haptics::new(stretch_basis(), Coupling::default(), 1e-3, Scheme::Exact, 1);
        h.select(0, 4); // the centre vertex: edges along x, y and a diagonal
        for eps in [1e-4, 0.013, -0.05] {
            h.state.q[0] = eps / 100.0;
            let s = h.edge_strain(0);
            assert!((s - eps.abs()).abs() < 1e-6 * eps.abs(), "{s} vs {eps}");
        }
    }

    #[test]
    fn policies_flag_stiffen_and_release_past_the_limit() {
        // λ = 1e4 with φ = 1 at the centre: the 10 N force limit gives q ≈ 1e-3, a strain of
        // ~10 %, far past the 2 % limit.
        let (flag, out) = grab_centre(StrainPolicy::Flag, 0.05, 400);
        assert!(out.strain_exceeded && out.strain > 0.05, "flag: {out:?}");
        assert!(out.force.iter().any(|f| f.abs() > 0.1), "flag keeps the force: {out:?}");
        let (stiff, out) = grab_centre(StrainPolicy::Stiffen, 0.05, 400);
        assert!(
            (out.strain - 0.02).abs() < 0.002,
            "stiffen holds the strain at the limit: {out:?}"
        );
        assert!(stiff.state.q[0].abs() < flag.state.q[0].abs() / 2.0);
        let f_dev = out.force.iter().map(|f| f * f).sum::<f64>().sqrt();
        assert!(f_dev > 5.0, "the hand still feels the pull: {f_dev}");
        let (rel, out) = grab_centre(StrainPolicy::Release, 0.05, 400);
        assert_eq!(out.force, [0.0; 3], "released: {out:?}");
        assert!(!rel.hands[0].grabbed, "the grab is let go");
        // …and stays let go while the button is held: the part relaxes (it used to be grabbed
        // again at the next step).
        assert!(rel.hands[0].latched);
        assert!(
            rel.state.q[0].abs() < 0.2 * flag.state.q[0].abs(),
            "{} vs {}",
            rel.state.q[0],
            flag.state.q[0]
        );
    }
}
