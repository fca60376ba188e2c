//! The haptic step: nearest surface vertex, implicit virtual coupling, force limit, modal
//! integration, quarantine of non-finite state. Allocation-free and lock-free after `new`.
//!
//! Coupling is solved implicitly: over a step the vertex moves by p = p₀ + G F (G = Σ gⱼ φⱼφⱼᵀ,
//! gⱼ the exact force gain of mode j), so the spring-damper force F = k(x − p) + b(ẋ − ṗ) is
//! found from a 3×3 system. That keeps the loop stable for any coupling stiffness, part
//! stiffness or time step (an explicit coupling goes unstable once √(k/m_eff)·dt > 2).

use crate::basis::Basis;
use crate::integrator::{ModalState, Scheme};
use crate::kdtree::KdTree;

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
    /// Position and velocity gains of the vertex to its own force over one step.
    g: [[f64; 3]; 3],
    h: [[f64; 3]; 3],
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
                h: [[0.0; 3]; 3],
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
            quarantined: 0,
        }
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
        let (mut g, mut h) = ([[0.0; 3]; 3], [[0.0; 3]; 3]);
        for j in 0..r {
            let (gj, hj) = self.state.transition(j).force_gains();
            for a in 0..3 {
                for b in 0..3 {
                    let pp = hd.rows[a * r + j] * hd.rows[b * r + j];
                    g[a][b] += gj * pp;
                    h[a][b] += hj * pp;
                }
            }
        }
        hd.vertex = Some(vertex);
        hd.g = g;
        hd.h = h;
    }

    /// One haptic step for every hand in `inputs` (at most the number given to `new`).
    pub fn step(&mut self, inputs: &[HandInput], outputs: &mut [HandOutput]) {
        let r = self.state.q.len();
        self.f.fill(0.0);
        let c = self.coupling;
        for (k, input) in inputs.iter().enumerate().take(self.hands.len()) {
            let out = &mut outputs[k];
            *out = HandOutput::default();
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
            // Free prediction of the vertex at the end of the step.
            let (mut p0, mut v0, mut p_now) = ([0.0; 3], [0.0; 3], [0.0; 3]);
            for j in 0..r {
                let (qf, vf) = self.state.transition(j).free(self.state.q[j], self.state.v[j]);
                for a in 0..3 {
                    let phi = hd.rows[a * r + j];
                    p0[a] += phi * qf;
                    v0[a] += phi * vf;
                    p_now[a] += phi * self.state.q[j];
                }
            }
            let rest = self.basis.rest[vertex as usize];
            for a in 0..3 {
                p0[a] += rest[a];
                p_now[a] += rest[a];
            }
            let x = input.position;
            let xd = input.velocity;
            let force = if hd.grabbed {
                // (I + kG + bH) F = k(x − p₀) + b(ẋ − v₀)
                let m: [[f64; 3]; 3] = std::array::from_fn(|a| {
                    std::array::from_fn(|b| {
                        c.stiffness * hd.g[a][b] + c.damping * hd.h[a][b] + f64::from(u8::from(a == b))
                    })
                });
                let rhs: [f64; 3] = std::array::from_fn(|a| c.stiffness * (x[a] - p0[a]) + c.damping * (xd[a] - v0[a]));
                solve3(m, rhs)
            } else {
                // Press: only along the outward normal n, only pushing.
                let n = self.basis.normals[vertex as usize];
                let depth = (0..3).map(|a| (p0[a] - x[a]) * n[a]).sum::<f64>();
                if depth > 0.0 {
                    let rate = (0..3).map(|a| (v0[a] - xd[a]) * n[a]).sum::<f64>();
                    let ngn = (0..3)
                        .flat_map(|a| (0..3).map(move |b| (a, b)))
                        .map(|(a, b)| n[a] * hd.g[a][b] * n[b])
                        .sum::<f64>();
                    let nhn = (0..3)
                        .flat_map(|a| (0..3).map(move |b| (a, b)))
                        .map(|(a, b)| n[a] * hd.h[a][b] * n[b])
                        .sum::<f64>();
                    let fn_ = ((c.stiffness * depth + c.damping * rate) / (1.0 + c.stiffness * ngn + c.damping * nhn))
                        .max(0.0);
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
            out.force = force.map(|v| -v);
            out.vertex = vertex;
            out.contact = hd.grabbed || mag > 0.0;
            out.vertex_position = p_now;
        }
        self.saved.0.copy_from_slice(&self.state.q);
        self.saved.1.copy_from_slice(&self.state.v);
        self.state.step(&self.f);
        let finite = self.state.q.iter().chain(&self.state.v).all(|v| v.is_finite());
        if !finite {
            // Roll back; never send a non-finite or stale-state force.
            self.state.q.copy_from_slice(&self.saved.0);
            self.state.v.copy_from_slice(&self.saved.1);
            for o in outputs.iter_mut() {
                o.force = [0.0; 3];
            }
            self.quarantined += 1;
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
