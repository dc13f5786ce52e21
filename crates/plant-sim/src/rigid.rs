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

impl DhLink {
    /// Standard parameters about the DH frame origin, DH axes:
    /// `[m, m cx, m cy, m cz, Ixx, Iyy, Izz, Ixy, Ixz, Iyz]` (parallel-axis theorem).
    pub fn standard_parameters(&self) -> [f64; 10] {
        let m = self.mass_kg;
        let [cx, cy, cz] = self.com_m;
        let [ixx, iyy, izz, ixy, ixz, iyz] = self.inertia_com_kgm2;
        [
            m,
            m * cx,
            m * cy,
            m * cz,
            ixx + m * (cy * cy + cz * cz),
            iyy + m * (cx * cx + cz * cz),
            izz + m * (cx * cx + cy * cy),
            ixy - m * cx * cy,
            ixz - m * cx * cz,
            iyz - m * cy * cz,
        ]
    }
}

impl DhArm {
    /// All links' standard parameters, link after link (10 per link).
    pub fn standard_parameters(&self) -> Vec<f64> {
        self.links
            .iter()
            .flat_map(|l| l.standard_parameters())
            .collect()
    }

    /// Recursive Newton-Euler with the links' inertia given as standard parameters
    /// (`params`: 10 per link, see [`DhLink::standard_parameters`]); linear in `params`.
    pub fn inverse_dynamics_with(
        &self,
        params: &[f64],
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        tau_nm: &mut [f64],
    ) {
        const MAX: usize = 16;
        let n = self.links.len();
        assert!(n <= MAX, "at most {MAX} links");
        let z = Vector3::z();
        let mut rot = [Matrix3::zeros(); MAX];
        let mut pstar = [Vector3::zeros(); MAX];
        let mut force = [Vector3::zeros(); MAX];
        let mut moment = [Vector3::zeros(); MAX];
        let mut w = Vector3::zeros();
        let mut wd = Vector3::zeros();
        let mut vd = Vector3::new(0.0, 0.0, GRAVITY_M_S2);
        for i in 0..n {
            let l = &self.links[i];
            let (sa, ca) = l.alpha_rad.sin_cos();
            let (st, ct) = (q[i] + l.theta_offset_rad).sin_cos();
            let r = Matrix3::new(ct, -st * ca, st * sa, st, ct * ca, -ct * sa, 0.0, sa, ca);
            let rt = r.transpose();
            let p = Vector3::new(l.a_m, l.d_m * sa, l.d_m * ca);
            let w_new = rt * (w + z * qd[i]);
            wd = rt * (wd + z * qdd[i] + w.cross(&(z * qd[i])));
            w = w_new;
            vd = rt * vd + wd.cross(&p) + w.cross(&w.cross(&p));
            let k = &params[10 * i..10 * i + 10];
            let h = Vector3::new(k[1], k[2], k[3]);
            let io = Matrix3::new(k[4], k[7], k[8], k[7], k[5], k[9], k[8], k[9], k[6]);
            force[i] = vd * k[0] + wd.cross(&h) + w.cross(&w.cross(&h));
            moment[i] = io * wd + w.cross(&(io * w)) + h.cross(&vd);
            rot[i] = r;
            pstar[i] = p;
        }
        let mut f = Vector3::zeros();
        let mut nm = Vector3::zeros();
        for i in (0..n).rev() {
            let (f_c, n_c) = if i + 1 < n {
                (rot[i + 1] * f, rot[i + 1] * (nm + pstar[i + 1].cross(&f)))
            } else {
                (f * 0.0, nm * 0.0)
            };
            f = f_c + force[i];
            nm = n_c + moment[i];
            let (sa, ca) = self.links[i].alpha_rad.sin_cos();
            tau_nm[i] = (nm + pstar[i].cross(&f)).dot(&Vector3::new(0.0, sa, ca));
        }
    }
}

impl RigidBodyModel for DhArm {
    fn dof(&self) -> usize {
        self.links.len()
    }

    fn inverse_dynamics(&self, q: &[f64], qd: &[f64], qdd: &[f64], tau_nm: &mut [f64]) {
        let params = self.standard_parameters();
        self.inverse_dynamics_with(&params, q, qd, qdd, tau_nm);
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
