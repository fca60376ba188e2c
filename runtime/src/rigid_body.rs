//! Rigid-body motion of a free part (Newton–Euler, eq. 1.18 of the chapter) from the basis's
//! mass, centre of mass and inertia. Semi-implicit Euler on momenta: with no force the linear
//! and angular momenta are kept exactly.

use crate::basis::RigidProperties;
use nalgebra::{Matrix3, Quaternion, UnitQuaternion, Vector3};

/// A 3-vector (stack only).
pub type V3 = Vector3<f64>;
/// A 3×3 matrix (stack only).
pub type M3 = Matrix3<f64>;

/// A row-major `[[f64; 3]; 3]` as a matrix.
pub fn m3(a: &[[f64; 3]; 3]) -> M3 {
    Matrix3::from_fn(|i, j| a[i][j])
}

/// The rotation of a published quaternion (w, x, y, z), normalised.
pub fn rotation_of([w, x, y, z]: [f64; 4]) -> UnitQuaternion<f64> {
    UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z))
}

/// Pose and momenta of a free body.
#[derive(Clone, Copy, Debug)]
pub struct RigidBody {
    /// kg.
    pub mass: f64,
    /// Inverse of the body-frame inertia about the centre of mass.
    inv_inertia: M3,
    /// Centre of mass in the part (body) frame, m.
    pub center_body: V3,
    /// Centre of mass in the world, m.
    pub position: V3,
    /// Its velocity, m/s.
    pub velocity: V3,
    /// Orientation, body → world.
    pub orientation: UnitQuaternion<f64>,
    /// Angular momentum about the centre of mass, world frame, kg·m²/s.
    pub angular_momentum: V3,
    /// Gravity, m/s².
    pub gravity: V3,
    /// Damping of both momenta, 1/s (air drag, hand friction; 0 keeps them exactly).
    pub damping: f64,
}

impl RigidBody {
    /// At rest, placed where the part was meshed (identity pose); `None` for a singular inertia.
    pub fn new(p: &RigidProperties, gravity: [f64; 3]) -> Option<RigidBody> {
        let inertia = m3(&p.inertia);
        let inv = inertia.try_inverse().filter(|m| m.iter().all(|v| v.is_finite()))?;
        let center = V3::from(p.center);
        Some(RigidBody {
            mass: p.mass,
            inv_inertia: inv,
            center_body: center,
            position: center,
            velocity: V3::zeros(),
            orientation: UnitQuaternion::identity(),
            angular_momentum: V3::zeros(),
            gravity: V3::from(gravity),
            damping: 0.0,
        })
    }

    /// Rotation matrix body → world.
    pub fn rotation(&self) -> M3 {
        self.orientation.to_rotation_matrix().into_inner()
    }

    /// World inverse inertia R I⁻¹ Rᵀ.
    pub fn inv_inertia_world(&self) -> M3 {
        let r = self.rotation();
        r * self.inv_inertia * r.transpose()
    }

    /// Angular velocity, world frame.
    pub fn angular_velocity(&self) -> V3 {
        self.inv_inertia_world() * self.angular_momentum
    }

    /// World position of body-frame point `p`.
    pub fn to_world(&self, p: V3) -> V3 {
        self.position + self.orientation * (p - self.center_body)
    }

    /// Body-frame position of world point `x`.
    pub fn to_body(&self, x: V3) -> V3 {
        self.center_body + self.orientation.inverse_transform_vector(&(x - self.position))
    }

    /// World vector → body frame.
    pub fn vector_to_body(&self, v: V3) -> V3 {
        self.orientation.inverse_transform_vector(&v)
    }

    /// Body vector → world frame.
    pub fn vector_to_world(&self, v: V3) -> V3 {
        self.orientation * v
    }

    /// Velocity of the material point at world position `x`.
    pub fn point_velocity(&self, x: V3) -> V3 {
        self.velocity + self.angular_velocity().cross(&(x - self.position))
    }

    /// Compliance of the rigid motion at body point `p` over one step, body frame: how far the
    /// point moves per newton applied there (semi-implicit Euler: dt²(1/m − [r]× I⁻¹ [r]×)).
    pub fn step_compliance_body(&self, p: V3, dt: f64) -> M3 {
        let rx = (p - self.center_body).cross_matrix();
        (M3::identity() / self.mass + rx.transpose() * self.inv_inertia * rx) * (dt * dt)
    }

    /// Advances by `dt` under a world force and a torque about the centre of mass (plus gravity).
    pub fn step(&mut self, force: V3, torque: V3, dt: f64) {
        if self.damping > 0.0 {
            let k = (-self.damping * dt).exp();
            self.velocity *= k;
            self.angular_momentum *= k;
        }
        self.velocity += (force / self.mass + self.gravity) * dt;
        self.position += self.velocity * dt;
        self.angular_momentum += torque * dt;
        // q ← exp(½ dt ω) q, exact rotation by the step's angle, renormalised against drift.
        let turn = UnitQuaternion::from_scaled_axis(self.angular_velocity() * dt);
        self.orientation = UnitQuaternion::new_normalize((turn * self.orientation).into_inner());
    }

    /// Kinetic energy, J.
    pub fn kinetic_energy(&self) -> f64 {
        0.5 * self.mass * self.velocity.norm_squared() + 0.5 * self.angular_velocity().dot(&self.angular_momentum)
    }

    /// Whether every state value is finite.
    pub fn is_finite(&self) -> bool {
        self.position
            .iter()
            .chain(self.velocity.iter())
            .chain(self.orientation.coords.iter())
            .chain(self.angular_momentum.iter())
            .all(|v| v.is_finite())
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
        b.velocity = V3::new(0.3, -0.1, 0.2);
        b.angular_momentum = V3::new(0.01, 0.03, -0.02);
        let (p0, l0, e0) = (b.velocity * b.mass, b.angular_momentum, b.kinetic_energy());
        for _ in 0..100_000 {
            b.step(V3::zeros(), V3::zeros(), 1e-3);
        }
        for c in 0..3 {
            assert!((b.velocity[c] * b.mass - p0[c]).abs() < 1e-12);
            assert!((b.angular_momentum[c] - l0[c]).abs() < 1e-15);
        }
        let q = b.orientation.coords.norm_squared();
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
        b.angular_momentum = V3::new(0.02, -0.01, 0.05);
        for _ in 0..500 {
            b.step(V3::x(), V3::zeros(), 1e-3);
        }
        let p = V3::new(0.4, -0.3, 0.9);
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
        b.angular_momentum = V3::new(1e-3, -2e-3, 5e-4);
        let dt = 1e-3;
        let point = V3::new(0.06, -0.02, 0.03);
        let f = V3::new(1.0, -2.0, 0.5);
        let mut free = b;
        free.step(V3::zeros(), V3::zeros(), dt);
        let mut pushed = b;
        let arm = b.to_world(point) - b.position;
        pushed.step(f, arm.cross(&f), dt);
        let moved = pushed.to_world(point) - free.to_world(point);
        let predicted = b.step_compliance_body(point, dt) * f;
        assert!(
            (moved - predicted).amax() < 1e-3 * predicted.amax(),
            "{moved:?} vs {predicted:?}"
        );
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
        let point = V3::new(0.08, 0.06, 0.008);
        let anchor = V3::new(0.08, 0.06, 0.1);
        let (k, c, dt) = (3000.0, 60.0, 1e-3);
        let mut fmax: f64 = 0.0;
        for step in 0..6000 {
            let mut pred = b;
            pred.step(V3::zeros(), V3::zeros(), dt);
            let xb = pred.to_body(anchor);
            let vb = pred.vector_to_body(-pred.point_velocity(anchor));
            let cr = b.step_compliance_body(point, dt);
            let m = cr * (k + c / dt) + M3::identity();
            let rhs = (xb - point) * k + vb * c;
            let f_body = m.lu().solve(&rhs).expect("solvable");
            let f = b.vector_to_world(f_body);
            let arm = b.to_world(point) - b.position;
            b.step(f, arm.cross(&f), dt);
            if step > 3000 {
                fmax = fmax.max(f.norm());
            }
        }
        assert!(fmax < 2.0 * 0.165 * 9.81, "pendulum force {fmax}");
    }
}
