//! The rigid-body part of the true plant: link-side inverse dynamics of a serial arm.
//!
//! The simulator only needs `tau = M(q) qdd + C(q, qd) qd + G(q)` at the joints; it takes
//! it through the [`RigidBodyModel`] trait so any implementation (the standard-DH
//! recursive Newton-Euler here, or the robot module's URDF/DH model) can drive it.
use nalgebra::{Matrix3, Vector3};

/// Standard gravity [m/s^2], acting along -z of the base frame.
pub const GRAVITY_M_S2: f64 = 9.81;

/// Link-side inverse dynamics of a serial arm (no friction, no drive effects).
pub trait RigidBodyModel {
    /// Number of joints.
    fn dof(&self) -> usize;
    /// Writes the joint torques [N*m] for positions [rad], velocities [rad/s] and
    /// accelerations [rad/s^2] into `tau_nm` (all slices of length [`Self::dof`]).
    fn inverse_dynamics(&self, q: &[f64], qd: &[f64], qdd: &[f64], tau_nm: &mut [f64]);
}

/// One link of a standard-DH arm: the transform from frame i-1 to frame i is
/// `Rz(theta) Tz(d) Tx(a) Rx(alpha)` with `theta = q + theta_offset`.
#[derive(Debug, Clone, PartialEq)]
pub struct DhLink {
    /// Offset along z_{i-1} [m].
    pub d_m: f64,
    /// Length along x_i [m].
    pub a_m: f64,
    /// Twist about x_i [rad].
    pub alpha_rad: f64,
    /// Joint angle offset [rad].
    pub theta_offset_rad: f64,
    /// Link mass [kg].
    pub mass_kg: f64,
    /// Centre of mass in frame i [m].
    pub com_m: [f64; 3],
    /// Inertia about the centre of mass, axes of frame i [kg*m^2]:
    /// `[ixx, iyy, izz, ixy, ixz, iyz]`.
    pub inertia_com_kgm2: [f64; 6],
}

/// A serial arm of revolute joints described by standard DH links, evaluated with the
/// recursive Newton-Euler algorithm (moments taken about each joint's origin).
#[derive(Debug, Clone, PartialEq)]
pub struct DhArm {
    /// Links from the base outwards.
    pub links: Vec<DhLink>,
}

struct LinkConst {
    r: Matrix3<f64>, // rotation part Rx(alpha) (the Rz(theta) part is per state)
    p_star: Vector3<f64>,
    axis_in_i: Vector3<f64>,
    c: Vector3<f64>,
    inertia: Matrix3<f64>,
}

impl DhArm {
    fn link_const(l: &DhLink) -> LinkConst {
        let (s, c) = l.alpha_rad.sin_cos();
        let [ixx, iyy, izz, ixy, ixz, iyz] = l.inertia_com_kgm2;
        LinkConst {
            r: Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c),
            p_star: Vector3::new(l.a_m, l.d_m * s, l.d_m * c),
            axis_in_i: Vector3::new(0.0, s, c),
            c: Vector3::from(l.com_m),
            inertia: Matrix3::new(ixx, ixy, ixz, ixy, iyy, iyz, ixz, iyz, izz),
        }
    }
}

impl RigidBodyModel for DhArm {
    fn dof(&self) -> usize {
        self.links.len()
    }

    fn inverse_dynamics(&self, q: &[f64], qd: &[f64], qdd: &[f64], tau_nm: &mut [f64]) {
        let n = self.links.len();
        let z = Vector3::z();
        let mut rot = Vec::with_capacity(n); // R_{i-1,i}
        let mut force = Vec::with_capacity(n);
        let mut moment = Vec::with_capacity(n);
        let mut consts = Vec::with_capacity(n);
        let mut w = Vector3::zeros();
        let mut wd = Vector3::zeros();
        let mut vd = Vector3::new(0.0, 0.0, GRAVITY_M_S2);
        for i in 0..n {
            let l = &self.links[i];
            let k = Self::link_const(l);
            let (st, ct) = (q[i] + l.theta_offset_rad).sin_cos();
            let rz = Matrix3::new(ct, -st, 0.0, st, ct, 0.0, 0.0, 0.0, 1.0);
            let r = rz * k.r;
            let rt = r.transpose();
            let w_new = rt * (w + z * qd[i]);
            wd = rt * (wd + z * qdd[i] + w.cross(&(z * qd[i])));
            w = w_new;
            vd = rt * vd + wd.cross(&k.p_star) + w.cross(&w.cross(&k.p_star));
            let ac = vd + wd.cross(&k.c) + w.cross(&w.cross(&k.c));
            force.push(ac * l.mass_kg);
            moment.push(k.inertia * wd + w.cross(&(k.inertia * w)));
            rot.push(r);
            consts.push(k);
        }
        let mut f_next = Vector3::zeros();
        let mut n_next = Vector3::zeros();
        for i in (0..n).rev() {
            let k = &consts[i];
            let (f_child, n_child) = if i + 1 < n {
                (rot[i + 1] * f_next, rot[i + 1] * n_next)
            } else {
                (Vector3::zeros(), Vector3::zeros())
            };
            let f = f_child + force[i];
            let nm =
                n_child + k.p_star.cross(&f_child) + (k.p_star + k.c).cross(&force[i]) + moment[i];
            tau_nm[i] = nm.dot(&k.axis_in_i);
            f_next = f;
            n_next = nm;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn single_pendulum(len: f64, mass: f64) -> DhArm {
        DhArm {
            links: vec![DhLink {
                d_m: 0.0,
                a_m: len,
                alpha_rad: std::f64::consts::FRAC_PI_2,
                theta_offset_rad: 0.0,
                mass_kg: mass,
                com_m: [0.0, 0.0, 0.0],
                inertia_com_kgm2: [0.0; 6],
            }],
        }
    }

    #[test]
    fn horizontal_axis_pendulum_matches_hand_derivation() {
        // Joint axis z0 is vertical, so a horizontal arm feels no gravity torque; its
        // torque is m l^2 qdd.
        let arm = single_pendulum(0.5, 2.0);
        let mut tau = [0.0];
        arm.inverse_dynamics(&[0.3], &[1.0], &[2.0], &mut tau);
        assert!((tau[0] - 2.0 * 0.25 * 2.0).abs() < 1e-12, "{tau:?}");
    }

    #[test]
    fn planar_two_link_gravity_matches_hand_derivation() {
        // First joint turned so the plane is vertical: alpha_0 = pi/2 on a zero-length
        // base link whose own joint is held at zero.
        let base = DhLink {
            d_m: 0.0,
            a_m: 0.0,
            alpha_rad: std::f64::consts::FRAC_PI_2,
            theta_offset_rad: 0.0,
            mass_kg: 0.0,
            com_m: [0.0; 3],
            inertia_com_kgm2: [0.0; 6],
        };
        let link = |a: f64, m: f64| DhLink {
            d_m: 0.0,
            a_m: a,
            alpha_rad: 0.0,
            theta_offset_rad: 0.0,
            mass_kg: m,
            com_m: [0.0; 3],
            inertia_com_kgm2: [0.0; 6],
        };
        let arm = DhArm {
            links: vec![base, link(0.4, 1.5), link(0.3, 0.7)],
        };
        let (q1, q2) = (0.4_f64, -0.9_f64);
        let mut tau = [0.0; 3];
        arm.inverse_dynamics(&[0.0, q1, q2], &[0.0; 3], &[0.0; 3], &mut tau);
        let g = GRAVITY_M_S2;
        let t2 = 0.7 * g * 0.3 * (q1 + q2).cos();
        let t1 = 1.5 * g * 0.4 * q1.cos() + 0.7 * g * (0.4 * q1.cos() + 0.3 * (q1 + q2).cos());
        assert!(
            (tau[1] - t1).abs() < 1e-12 && (tau[2] - t2).abs() < 1e-12,
            "{tau:?} {t1} {t2}"
        );
    }
}
