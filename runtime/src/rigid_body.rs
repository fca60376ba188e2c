//! Rigid-body motion of a free part (Newton–Euler, eq. 1.18 of the chapter) from the basis's
//! mass, centre of mass and inertia. Semi-implicit Euler on momenta: with no force the linear
//! and angular momenta are kept exactly.

use crate::basis::RigidProperties;

type M3 = [[f64; 3]; 3];

fn mul(a: &M3, b: &M3) -> M3 {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
}

fn mulv(a: &M3, v: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| (0..3).map(|k| a[i][k] * v[k]).sum())
}

fn transpose(a: &M3) -> M3 {
    std::array::from_fn(|i| std::array::from_fn(|j| a[j][i]))
}

/// Rotation matrix of a unit quaternion (w, x, y, z).
pub fn rotation_matrix([w, x, y, z]: [f64; 4]) -> M3 {
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

/// a × b.
pub fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn inverse(a: &M3) -> Option<M3> {
    let det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
        + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
    if det.is_nan() || det.abs() < 1e-300 {
        return None;
    }
    Some(std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            let (i1, i2, j1, j2) = ((j + 1) % 3, (j + 2) % 3, (i + 1) % 3, (i + 2) % 3);
            (a[i1][j1] * a[i2][j2] - a[i1][j2] * a[i2][j1]) / det
        })
    }))
}

/// Pose and momenta of a free body.
#[derive(Clone, Copy, Debug)]
pub struct RigidBody {
    /// kg.
    pub mass: f64,
    /// Inverse of the body-frame inertia about the centre of mass.
    inv_inertia: M3,
    /// Centre of mass in the part (body) frame, m.
    pub center_body: [f64; 3],
    /// Centre of mass in the world, m.
    pub position: [f64; 3],
    /// Its velocity, m/s.
    pub velocity: [f64; 3],
    /// Orientation, unit quaternion (w, x, y, z), body → world.
    pub orientation: [f64; 4],
    /// Angular momentum about the centre of mass, world frame, kg·m²/s.
    pub angular_momentum: [f64; 3],
    /// Gravity, m/s².
    pub gravity: [f64; 3],
    /// Damping of both momenta, 1/s (air drag, hand friction; 0 keeps them exactly).
    pub damping: f64,
}

impl RigidBody {
    /// At rest, placed where the part was meshed (identity pose).
    pub fn new(p: &RigidProperties, gravity: [f64; 3]) -> Option<RigidBody> {
        let inv = inverse(&p.inertia)?;
        Some(RigidBody {
            mass: p.mass,
            inv_inertia: inv,
            center_body: p.center,
            position: p.center,
            velocity: [0.0; 3],
            orientation: [1.0, 0.0, 0.0, 0.0],
            angular_momentum: [0.0; 3],
            gravity,
            damping: 0.0,
        })
    }

    /// Rotation matrix body → world.
    pub fn rotation(&self) -> M3 {
        rotation_matrix(self.orientation)
    }

    /// World inverse inertia R I⁻¹ Rᵀ.
    pub fn inv_inertia_world(&self) -> M3 {
        let r = self.rotation();
        mul(&mul(&r, &self.inv_inertia), &transpose(&r))
    }

    /// Angular velocity, world frame.
    pub fn angular_velocity(&self) -> [f64; 3] {
        mulv(&self.inv_inertia_world(), self.angular_momentum)
    }

    /// World position of body-frame point `p`.
    pub fn to_world(&self, p: [f64; 3]) -> [f64; 3] {
        let r = self.rotation();
        let d = mulv(
            &r,
            [
                p[0] - self.center_body[0],
                p[1] - self.center_body[1],
                p[2] - self.center_body[2],
            ],
        );
        [
            self.position[0] + d[0],
            self.position[1] + d[1],
            self.position[2] + d[2],
        ]
    }

    /// Body-frame position of world point `x`.
    pub fn to_body(&self, x: [f64; 3]) -> [f64; 3] {
        let rt = transpose(&self.rotation());
        let d = mulv(
            &rt,
            [
                x[0] - self.position[0],
                x[1] - self.position[1],
                x[2] - self.position[2],
            ],
        );
        [
            self.center_body[0] + d[0],
            self.center_body[1] + d[1],
            self.center_body[2] + d[2],
        ]
    }

    /// World vector → body frame.
    pub fn vector_to_body(&self, v: [f64; 3]) -> [f64; 3] {
        mulv(&transpose(&self.rotation()), v)
    }

    /// Body vector → world frame.
    pub fn vector_to_world(&self, v: [f64; 3]) -> [f64; 3] {
        mulv(&self.rotation(), v)
    }

    /// Velocity of the material point at world position `x`.
    pub fn point_velocity(&self, x: [f64; 3]) -> [f64; 3] {
        let w = self.angular_velocity();
        let r = [
            x[0] - self.position[0],
            x[1] - self.position[1],
            x[2] - self.position[2],
        ];
        let c = cross(w, r);
        [
            self.velocity[0] + c[0],
            self.velocity[1] + c[1],
            self.velocity[2] + c[2],
        ]
    }

    /// Compliance of the rigid motion at body point `p` over one step, body frame: how far the
    /// point moves per newton applied there (semi-implicit Euler: dt²(1/m − [r]× I⁻¹ [r]×)).
    pub fn step_compliance_body(&self, p: [f64; 3], dt: f64) -> M3 {
        let r = [
            p[0] - self.center_body[0],
            p[1] - self.center_body[1],
            p[2] - self.center_body[2],
        ];
        let rx: M3 = [[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]];
        let t = mul(&mul(&transpose(&rx), &self.inv_inertia), &rx);
        std::array::from_fn(|i| {
            std::array::from_fn(|j| dt * dt * (if i == j { 1.0 / self.mass } else { 0.0 } + t[i][j]))
        })
    }

    /// Advances by `dt` under a world force and a torque about the centre of mass (plus gravity).
    pub fn step(&mut self, force: [f64; 3], torque: [f64; 3], dt: f64) {
        if self.damping > 0.0 {
            let k = (-self.damping * dt).exp();
            self.velocity = self.velocity.map(|v| v * k);
            self.angular_momentum = self.angular_momentum.map(|l| l * k);
        }
        for c in 0..3 {
            self.velocity[c] += dt * (force[c] / self.mass + self.gravity[c]);
            self.position[c] += dt * self.velocity[c];
            self.angular_momentum[c] += dt * torque[c];
        }
        let w = self.angular_velocity();
        // q ← exp(½ dt ω) q, exact rotation by the step's angle.
        let angle = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt() * dt;
        if angle > 0.0 {
            let axis = w.map(|x| x * dt / angle);
            let (s, c) = (angle / 2.0).sin_cos();
            let d = [c, axis[0] * s, axis[1] * s, axis[2] * s];
            let q = self.orientation;
            let mut n = [
                d[0] * q[0] - d[1] * q[1] - d[2] * q[2] - d[3] * q[3],
                d[0] * q[1] + d[1] * q[0] + d[2] * q[3] - d[3] * q[2],
                d[0] * q[2] - d[1] * q[3] + d[2] * q[0] + d[3] * q[1],
                d[0] * q[3] + d[1] * q[2] - d[2] * q[1] + d[3] * q[0],
            ];
            let len = n.iter().map(|x| x * x).sum::<f64>().sqrt();
            n.iter_mut().for_each(|x| *x /= len);
            self.orientation = n;
        }
    }

    /// Kinetic energy, J.
    pub fn kinetic_energy(&self) -> f64 {
        let w = self.angular_velocity();
        let v2 = self.velocity.iter().map(|v| v * v).sum::<f64>();
        0.5 * self.mass * v2 + 0.5 * (0..3).map(|i| w[i] * self.angular_momentum[i]).sum::<f64>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn body() -> RigidBody {
        let p = RigidProperties {
            mass: 2.0,
            center: [0.1, 0.2, 0.3],
            inertia: [[0.02, 0.001, 0.0], [0.001, 0.05, 0.002], [0.0, 0.002, 0.08]],
        };
        RigidBody::new(&p, [0.0; 3]).expect("invertible inertia")
    }

    #[test]
    fn free_body_keeps_its_momenta_and_energy_while_tumbling() {
        let mut b = body();
        b.velocity = [0.3, -0.1, 0.2];
        b.angular_momentum = [0.01, 0.03, -0.02];
        let (p0, l0, e0) = (b.velocity.map(|v| v * b.mass), b.angular_momentum, b.kinetic_energy());
        for _ in 0..100_000 {
            b.step([0.0; 3], [0.0; 3], 1e-3);
        }
        for c in 0..3 {
            assert!((b.velocity[c] * b.mass - p0[c]).abs() < 1e-12);
            assert!((b.angular_momentum[c] - l0[c]).abs() < 1e-15);
        }
        let q = b.orientation.iter().map(|x| x * x).sum::<f64>();
        assert!((q - 1.0).abs() < 1e-12);
        // The explicit rotation update drifts the energy slowly (not the momenta): bound it.
        assert!(
            (b.kinetic_energy() - e0).abs() < 0.02 * e0,
            "{} vs {e0}",
            b.kinetic_energy()
        );
    }

    #[test]
    fn frames_round_trip() {
        let mut b = body();
        b.angular_momentum = [0.02, -0.01, 0.05];
        for _ in 0..500 {
            b.step([1.0, 0.0, 0.0], [0.0; 3], 1e-3);
        }
        let p = [0.4, -0.3, 0.9];
        let back = b.to_body(b.to_world(p));
        for c in 0..3 {
            assert!((back[c] - p[c]).abs() < 1e-12);
        }
    }
}

#[cfg(test)]
mod compliance_tests {
    use super::*;

    #[test]
    fn step_compliance_predicts_the_motion_of_the_pushed_point() {
        let p = RigidProperties {
            mass: 0.5,
            center: [0.0, 0.0, 0.0],
            inertia: [[2e-3, 1e-4, 0.0], [1e-4, 3e-3, 2e-4], [0.0, 2e-4, 4e-3]],
        };
        let mut b = RigidBody::new(&p, [0.0; 3]).expect("invertible");
        b.angular_momentum = [1e-3, -2e-3, 5e-4];
        let dt = 1e-3;
        let point = [0.06, -0.02, 0.03];
        let f = [1.0, -2.0, 0.5];
        let mut free = b;
        free.step([0.0; 3], [0.0; 3], dt);
        let mut pushed = b;
        let arm: [f64; 3] = std::array::from_fn(|c| b.to_world(point)[c] - b.position[c]);
        pushed.step(f, cross(arm, f), dt);
        let moved: [f64; 3] = std::array::from_fn(|c| pushed.to_world(point)[c] - free.to_world(point)[c]);
        let cmat = b.step_compliance_body(point, dt);
        let predicted = mulv(&cmat, f);
        for c in 0..3 {
            assert!(
                (moved[c] - predicted[c]).abs() < 1e-3 * predicted.iter().map(|x| x.abs()).fold(0.0, f64::max),
                "{moved:?} vs {predicted:?}"
            );
        }
    }
}

#[cfg(test)]
mod pendulum_tests {
    use super::*;

    /// A body hanging from an anchor by an implicit spring-damper at one body point.
    #[test]
    fn implicit_spring_damper_pendulum_is_stable() {
        let p = RigidProperties {
            mass: 0.165,
            center: [0.027, 0.03, 0.015],
            inertia: [[9e-5, 0.0, 1e-5], [0.0, 1.2e-4, 0.0], [1e-5, 0.0, 8e-5]],
        };
        let mut b = RigidBody::new(&p, [0.0, 0.0, -9.81]).expect("invertible");
        b.damping = 3.0;
        let point = [0.08, 0.06, 0.008];
        let anchor = [0.08, 0.06, 0.1];
        let (k, c, dt) = (3000.0, 60.0, 1e-3);
        let mut fmax: f64 = 0.0;
        for step in 0..6000 {
            let mut pred = b;
            pred.step([0.0; 3], [0.0; 3], dt);
            let xb = pred.to_body(anchor);
            let vb = pred.vector_to_body(pred.point_velocity(anchor).map(|v| -v));
            let cr = b.step_compliance_body(point, dt);
            let m: M3 = std::array::from_fn(|i| {
                std::array::from_fn(|j| k * cr[i][j] + c * cr[i][j] / dt + if i == j { 1.0 } else { 0.0 })
            });
            let rhs: [f64; 3] = std::array::from_fn(|i| k * (xb[i] - point[i]) + c * vb[i]);
            let f_body = mulv(&inverse(&m).expect("solvable"), rhs);
            let f = b.vector_to_world(f_body);
            let pw = b.to_world(point);
            let arm: [f64; 3] = std::array::from_fn(|i| pw[i] - b.position[i]);
            b.step(f, cross(arm, f), dt);
            if step > 3000 {
                fmax = fmax.max(f.iter().map(|x| x * x).sum::<f64>().sqrt());
            }
        }
        assert!(fmax < 2.0 * 0.165 * 9.81, "pendulum force {fmax}");
    }
}
