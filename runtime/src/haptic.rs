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
use crate::kdtree::KdTree;
use crate::rigid::{RigidBody, cross};

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

/// What one hand gets back.
#[derive(Clone, Copy, Debug, Default)]
pub struct HandOutput {
    /// Force for the device, N (already limited).
    pub force: [f64; 3],
    /// Active vertex (index among the basis's kept vertices).
    pub vertex: u32,
    /// Grabbing, or pressing into the surface.
    pub contact: bool,
    /// The force limit cut the force this step.
    pub clamped: bool,
    /// Deformed position of the active vertex, m.
    pub vertex_position: [f64; 3],
}

struct Hand {
    vertex: Option<u32>,
    grabbed: bool,
    rows: Vec<f64>,
    /// How far the vertex moves per newton of its own force over one step (modal part).
    g: [[f64; 3]; 3],
    /// Static correction Gᵢᵢ − Φᵢ Λ⁻¹ Φᵢᵀ (zero when off or not stored): the compliance the
    /// truncated modes miss, added instantly.
    residual: [[f64; 3]; 3],
    /// Force applied to the part at the vertex last step (part frame).
    last_force: [f64; 3],
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
    static_correction: bool,
    /// Steps whose result was non-finite and was rolled back.
    pub quarantined: u64,
}

fn solve3(a: [[f64; 3]; 3], b: [f64; 3]) -> Option<[f64; 3]> {
    let det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
        + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
    if det.abs() < 1e-300 || !det.is_finite() {
        return None;
    }
    let mut x = [0.0; 3];
    for (k, xk) in x.iter_mut().enumerate() {
        let mut m = a;
        for r in 0..3 {
            m[r][k] = b[r];
        }
        *xk = (m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]))
            / det;
    }
    Some(x)
}

impl Haptics {
    /// A simulation at rest with time step `dt` and up to `hands` hands.
    pub fn new(basis: std::sync::Arc<Basis>, coupling: Coupling, dt: f64, scheme: Scheme, hands: usize) -> Haptics {
        let r = basis.mode_count();
        let pts: Vec<[f64; 3]> = basis.surface_vertices.iter().map(|&v| basis.rest[v as usize]).collect();
        let tree = KdTree::new(&pts, &basis.surface_vertices);
        let state = ModalState::new(&basis.eigenvalues, basis.alpha, basis.beta, dt, scheme);
        let hands = (0..hands)
            .map(|_| Hand {
                vertex: None,
                grabbed: false,
                rows: vec![0.0; 3 * r],
                g: [[0.0; 3]; 3],
                residual: [[0.0; 3]; 3],
                last_force: [0.0; 3],
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
            static_correction: true,
            quarantined: 0,
        }
    }

    /// Makes the part a free body moving under the hands' forces and `gravity` (m/s²), from the
    /// basis's mass properties; `damping` (1/s) bleeds both momenta, so a part hanging from a
    /// hand stops swinging. Inputs and outputs are then in the world frame, which starts equal
    /// to the part frame. Fails when the basis holds no mass properties (a supported part).
    pub fn set_free_body(&mut self, gravity: [f64; 3], damping: f64) -> Result<(), String> {
        let props = self
            .basis
            .rigid
            .ok_or("the basis has no rigid-body properties: the part is supported, not free")?;
        let mut body = RigidBody::new(&props, gravity).ok_or("the stored inertia tensor is singular")?;
        body.damping = damping.max(0.0);
        self.rigid = Some(body);
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
        basis.gather_rows(vertex as usize, &mut hd.rows);
        let rows = &hd.rows;
        let state = &self.state;
        let g: [[f64; 3]; 3] = std::array::from_fn(|a| {
            std::array::from_fn(|b| {
                (0..r)
                    .map(|j| state.transition(j).force_gain() * rows[a * r + j] * rows[b * r + j])
                    .sum()
            })
        });
        // Residual compliance: exact block minus what the loaded modes already give.
        let residual = match basis.compliance_of(vertex as usize).filter(|_| self.static_correction) {
            Some(exact) => std::array::from_fn(|a| {
                std::array::from_fn(|b| {
                    exact[a][b]
                        - (0..r)
                            .map(|j| rows[a * r + j] * rows[b * r + j] / basis.eigenvalues[j])
                            .sum::<f64>()
                })
            }),
            None => [[0.0; 3]; 3],
        };
        hd.vertex = Some(vertex);
        hd.g = g;
        hd.residual = residual;
        hd.last_force = [0.0; 3];
    }

    /// One haptic step for every hand in `inputs` (at most the number given to `new`).
    pub fn step(&mut self, inputs: &[HandInput], outputs: &mut [HandOutput]) {
        let r = self.state.q.len();
        self.f.fill(0.0);
        let c = self.coupling;
        let dt = self.state.dt();
        let (mut total_force, mut total_torque) = ([0.0; 3], [0.0; 3]);
        for (k, world) in inputs.iter().enumerate().take(self.hands.len()) {
            let out = &mut outputs[k];
            *out = HandOutput::default();
            // Everything below works in the part (body) frame.
            let input = match &self.rigid {
                None => *world,
                Some(body) => {
                    // Where the body will be after a step without the hand's force: the
                    // coupling is then solved at the end of the step, like the modes (implicit).
                    let mut rb = *body;
                    rb.step([0.0; 3], [0.0; 3], dt);
                    let pv = rb.point_velocity(world.position);
                    HandInput {
                        position: rb.to_body(world.position),
                        velocity: rb.vector_to_body(std::array::from_fn(|a| world.velocity[a] - pv[a])),
                        button: world.button,
                    }
                }
            };
            let input = &input;
            if !self.hands[k].grabbed {
                match self.tree.nearest(input.position) {
                    Some((v, _)) => self.select(k, v),
                    None => continue, // non-finite HIP: no force
                }
                self.hands[k].grabbed = input.button;
            } else if !input.button {
                self.hands[k].grabbed = false;
            }
            let hd = &self.hands[k];
            let Some(vertex) = hd.vertex else { continue };
            // The step compliance at the vertex: modes, static correction, and for a free body
            // the rigid motion.
            let cr = match &self.rigid {
                Some(rb) => rb.step_compliance_body(self.basis.rest[vertex as usize], dt),
                None => [[0.0; 3]; 3],
            };
            let g: [[f64; 3]; 3] =
                std::array::from_fn(|a| std::array::from_fn(|b| hd.g[a][b] + hd.residual[a][b] + cr[a][b]));
            // Free prediction of the vertex at the end of the step.
            let (mut p0, mut p_now) = (self.basis.rest[vertex as usize], self.basis.rest[vertex as usize]);
            for j in 0..r {
                let (qf, _) = self.state.transition(j).free(self.state.q[j], self.state.v[j]);
                for a in 0..3 {
                    let phi = hd.rows[a * r + j];
                    p0[a] += phi * qf;
                    p_now[a] += phi * self.state.q[j];
                }
            }
            // The static correction is quasi-static: it moved the vertex by R·F_last already.
            for a in 0..3 {
                let shift = (0..3).map(|b| hd.residual[a][b] * hd.last_force[b]).sum::<f64>();
                p_now[a] += shift;
                p0[a] += shift;
            }
            let x = input.position;
            let xd = input.velocity;
            // The damper acts on the vertex's mean velocity over the step, (p − p_now)/dt, not on
            // its end velocity: modes with ω·dt > π are undamped between samples and their end
            // velocity aliases, which a damper on it would pump. With p = p₀ + G F, the spring
            // and damper together give (I + (k + b/dt) G) F = k(x − p₀) + b(ẋ − (p₀ − p_now)/dt).
            let kb = c.stiffness + c.damping / dt;
            let force = if hd.grabbed {
                let m: [[f64; 3]; 3] =
                    std::array::from_fn(|a| std::array::from_fn(|b| kb * g[a][b] + f64::from(u8::from(a == b))));
                let rhs: [f64; 3] = std::array::from_fn(|a| {
                    c.stiffness * (x[a] - p0[a]) + c.damping * (xd[a] - (p0[a] - p_now[a]) / dt)
                });
                solve3(m, rhs)
            } else {
                // Press: only along the outward normal n, only pushing.
                let n = self.basis.normals[vertex as usize];
                let depth = (0..3).map(|a| (p0[a] - x[a]) * n[a]).sum::<f64>();
                if depth > 0.0 {
                    let rate = (0..3).map(|a| ((p0[a] - p_now[a]) / dt - xd[a]) * n[a]).sum::<f64>();
                    let ngn = (0..3)
                        .flat_map(|a| (0..3).map(move |b| (a, b)))
                        .map(|(a, b)| n[a] * g[a][b] * n[b])
                        .sum::<f64>();
                    let fn_ = ((c.stiffness * depth + c.damping * rate) / (1.0 + kb * ngn)).max(0.0);
                    Some(n.map(|x| -fn_ * x))
                } else {
                    Some([0.0; 3])
                }
            };
            let Some(mut force) = force.filter(|f| f.iter().all(|v| v.is_finite())) else {
                continue;
            };
            let mag = (force[0] * force[0] + force[1] * force[1] + force[2] * force[2]).sqrt();
            if mag > c.max_force {
                force = force.map(|v| v * c.max_force / mag);
                out.clamped = true;
            }
            for j in 0..r {
                self.f[j] += hd.rows[j] * force[0] + hd.rows[r + j] * force[1] + hd.rows[2 * r + j] * force[2];
            }
            let (force_w, p_w) = match &self.rigid {
                None => (force, p_now),
                Some(rb) => (rb.vector_to_world(force), rb.to_world(p_now)),
            };
            if let Some(rb) = &self.rigid {
                let arm = std::array::from_fn(|a| p_w[a] - rb.position[a]);
                let t = cross(arm, force_w);
                for a in 0..3 {
                    total_force[a] += force_w[a];
                    total_torque[a] += t[a];
                }
            }
            out.force = force_w.map(|v| -v);
            out.vertex = vertex;
            out.contact = hd.grabbed || mag > 0.0;
            self.hands[k].last_force = force;
            out.vertex_position = p_w;
        }
        self.saved.0.copy_from_slice(&self.state.q);
        self.saved.1.copy_from_slice(&self.state.v);
        self.saved_rigid = self.rigid;
        self.state.step(&self.f);
        if let Some(rb) = &mut self.rigid {
            rb.step(total_force, total_torque, dt);
        }
        let rigid_finite = self.rigid.is_none_or(|rb| {
            rb.position
                .iter()
                .chain(&rb.velocity)
                .chain(&rb.orientation)
                .chain(&rb.angular_momentum)
                .all(|v| v.is_finite())
        });
        let finite = rigid_finite && self.state.q.iter().chain(&self.state.v).all(|v| v.is_finite());
        if !finite {
            // Roll back; never send a non-finite or stale-state force.
            self.state.q.copy_from_slice(&self.saved.0);
            self.state.v.copy_from_slice(&self.saved.1);
            self.rigid = self.saved_rigid;
            for o in outputs.iter_mut() {
                o.force = [0.0; 3];
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
            }
        }
    }

    /// Length of the vector [`Haptics::write_published`] fills: r modal coordinates + 7 pose values.
    pub fn published_len(&self) -> usize {
        self.state.q.len() + 7
    }

    /// Writes what a drawing thread needs: q, then the pose (centre of mass in the world, unit
    /// quaternion body → world). A part that is not moving as a free body writes a zero
    /// quaternion: no pose, drawn where it was meshed.
    pub fn write_published(&self, out: &mut [f64]) {
        let r = self.state.q.len();
        out[..r].copy_from_slice(&self.state.q);
        let (x, o) = match &self.rigid {
            Some(rb) => (rb.position, rb.orientation),
            // No pose: drawn where it was meshed (see visual::posed_positions).
            None => ([0.0; 3], [0.0; 4]),
        };
        out[r..r + 3].copy_from_slice(&x);
        out[r + 3..r + 7].copy_from_slice(&o);
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
