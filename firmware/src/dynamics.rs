//! Identified rigid-body model of the modelled joints, evaluated in f32 with a fixed
//! operation count: `tau = RNEA(q, qd, qdd; equivalent standard parameters) +
//! fv*qd + fc*sgn(qd) + fo + Ia*qdd` plus the extended friction basis (linear in its
//! coefficients, zero in the paper's model): velocity-weakening (Stribeck-shaped) terms
//! `fs_k*tanh(qd/v_k)` at the fixed speeds [`STRIBECK_SPEEDS_RAD_S`] and a quadratic drag
//! `fq*qd*|qd|`. A term whose coefficient is zero is skipped: the work is fixed for a
//! given model.
//!
//! [`RigidBodyModel<N>`] holds, per modelled joint, the fixed transform from the
//! previous modelled body (locked joints folded in), the rotation axis, the body-frame
//! standard parameters `[m, m*cx, m*cy, m*cz, Ixx, Iyy, Izz, Ixy, Ixz, Iyz]` (inertia
//! about the body origin; the "equivalent standard parameters" of the identified base
//! parameters, dependent ones zero), and the friction and rotor terms. The host builds
//! it (`model_export::dynamics::firmware_model`) and calls this same
//! [`RigidBodyModel::torques`] for its reports.
//!
//! Frames: body `i` = body `i-1` x `(origin_rotation, origin_translation)` x
//! `Rot(axis, q_i)`; body `-1` is the base, where `gravity_m_s2` is expressed.
use crate::math;

/// Number of velocity-weakening friction terms per joint.
pub const STRIBECK_TERMS: usize = 3;

/// Speeds `v_k` [rad/s] of the velocity-weakening terms `tanh(qd / v_k)`.
pub const STRIBECK_SPEEDS_RAD_S: [f32; STRIBECK_TERMS] = [0.05, 0.2, 1.0];

/// `1 / v_k` [s/rad] of [`STRIBECK_SPEEDS_RAD_S`] (exact in f32).
pub const STRIBECK_INV_SPEEDS_S_RAD: [f32; STRIBECK_TERMS] = [20.0, 5.0, 1.0];

/// One modelled joint and its (merged) link.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointModel {
    /// Rotation of the fixed transform from the previous body, row-major
    /// (`x_prev = R x_joint + p`).
    pub origin_rotation: [[f32; 3]; 3],
    /// Translation [m] of the fixed transform, previous body frame.
    pub origin_translation_m: [f32; 3],
    /// Unit rotation axis, joint frame.
    pub axis: [f32; 3],
    /// Body-frame standard parameters `[m, mx, my, mz, Ixx, Iyy, Izz, Ixy, Ixz, Iyz]`
    /// [kg, kg*m, kg*m^2], inertia about the body origin.
    pub inertial: [f32; 10],
    /// Viscous friction [N*m*s/rad].
    pub viscous_nm_s_rad: f32,
    /// Coulomb friction [N*m].
    pub coulomb_nm: f32,
    /// Constant torque offset [N*m].
    pub offset_nm: f32,
    /// Reflected rotor inertia [kg*m^2].
    pub rotor_inertia_kg_m2: f32,
    /// Velocity-weakening friction per [`STRIBECK_SPEEDS_RAD_S`] entry [N*m].
    pub stribeck_nm: [f32; STRIBECK_TERMS],
    /// Quadratic drag `qd*|qd|` [N*m*s^2/rad^2].
    pub quadratic_nm_s2_rad2: f32,
    /// `[min, max]` of the joint angle seen by identification [rad]
    /// (`[-f32::MAX, f32::MAX]`: not recorded).
    pub q_range_rad: [f32; 2],
    /// `[min, max]` of the joint speed seen by identification [rad/s]; the extended
    /// friction terms are continued along their tangent beyond it.
    pub qd_range_rad_s: [f32; 2],
    /// `[min, max]` of the joint acceleration seen by identification [rad/s^2].
    pub qdd_range_rad_s2: [f32; 2],
}

/// The range of a joint input nothing was recorded for (every finite value is inside).
pub const UNBOUNDED_RANGE: [f32; 2] = [-f32::MAX, f32::MAX];

impl JointModel {
    /// The extended friction basis' torque [N*m] at speed `qd` [rad/s]: the
    /// Stribeck-shaped terms (those with a non-zero coefficient) and the quadratic drag,
    /// evaluated at `qd` clamped to [`JointModel::qd_range_rad_s`] and continued beyond
    /// it along the tangent at the edge (so it grows at most linearly outside the
    /// identified speeds; inside, the slope term is an exact `+ 0`).
    #[inline]
    pub fn extended_friction_nm(&self, qd_rad_s: f32) -> f32 {
        let [lo, hi] = self.qd_range_rad_s;
        // A NaN speed stays NaN (both comparisons are false).
        let v = if qd_rad_s < lo {
            lo
        } else if qd_rad_s > hi {
            hi
        } else {
            qd_rad_s
        };
        let mut tau = self.quadratic_nm_s2_rad2 * v * v.abs();
        let mut slope = 2.0 * self.quadratic_nm_s2_rad2 * v.abs();
        for (f, inv) in self.stribeck_nm.iter().zip(STRIBECK_INV_SPEEDS_S_RAD) {
            if *f != 0.0 {
                let t = math::tanh(v * inv);
                tau += f * t;
                slope += f * inv * (1.0 - t * t);
            }
        }
        tau + slope * (qd_rad_s - v)
    }

    /// A massless, frictionless joint about z at the previous body's origin.
    pub const ZERO: JointModel = JointModel {
        origin_rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        origin_translation_m: [0.0; 3],
        axis: [0.0, 0.0, 1.0],
        inertial: [0.0; 10],
        viscous_nm_s_rad: 0.0,
        coulomb_nm: 0.0,
        offset_nm: 0.0,
        rotor_inertia_kg_m2: 0.0,
        stribeck_nm: [0.0; STRIBECK_TERMS],
        quadratic_nm_s2_rad2: 0.0,
        q_range_rad: UNBOUNDED_RANGE,
        qd_range_rad_s: UNBOUNDED_RANGE,
        qdd_range_rad_s2: UNBOUNDED_RANGE,
    };
}

/// The model of `N` modelled joints.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigidBodyModel<const N: usize> {
    /// Joints from base to tip.
    pub joints: [JointModel; N],
    /// Gravity [m/s^2] in the base frame.
    pub gravity_m_s2: [f32; 3],
    /// `1/eps` of the smoothed Coulomb sign `tanh(qd/eps)` [s/rad]; `0` = hard sign.
    pub coulomb_inv_eps_s_rad: f32,
}

type V3 = [f32; 3];

#[inline]
fn cross(a: &V3, b: &V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[inline]
fn add(a: &V3, b: &V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

#[inline]
fn scale(a: &V3, s: f32) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}

#[inline]
fn dot3(a: &V3, b: &V3) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `R v`.
#[inline]
fn mul(r: &[[f32; 3]; 3], v: &V3) -> V3 {
    [dot3(&r[0], v), dot3(&r[1], v), dot3(&r[2], v)]
}

/// `R^T v`.
#[inline]
fn mul_t(r: &[[f32; 3]; 3], v: &V3) -> V3 {
    [
        r[0][0] * v[0] + r[1][0] * v[1] + r[2][0] * v[2],
        r[0][1] * v[0] + r[1][1] * v[1] + r[2][1] * v[2],
        r[0][2] * v[0] + r[1][2] * v[1] + r[2][2] * v[2],
    ]
}

/// `I v` for the symmetric inertia `[Ixx, Iyy, Izz, Ixy, Ixz, Iyz]` at `p[4..10]`.
#[inline]
fn inertia_mul(p: &[f32; 10], v: &V3) -> V3 {
    [
        p[4] * v[0] + p[7] * v[1] + p[8] * v[2],
        p[7] * v[0] + p[5] * v[1] + p[9] * v[2],
        p[8] * v[0] + p[9] * v[1] + p[6] * v[2],
    ]
}

/// `R0 * Rot(a, q)` (Rodrigues) from `(sin q, cos q)`, row-major.
#[inline]
fn joint_rotation(r0: &[[f32; 3]; 3], a: &V3, (s, c): (f32, f32)) -> [[f32; 3]; 3] {
    let t = 1.0 - c;
    let rq = [
        [
            c + t * a[0] * a[0],
            t * a[0] * a[1] - s * a[2],
            t * a[0] * a[2] + s * a[1],
        ],
        [
            t * a[1] * a[0] + s * a[2],
            c + t * a[1] * a[1],
            t * a[1] * a[2] - s * a[0],
        ],
        [
            t * a[2] * a[0] - s * a[1],
            t * a[2] * a[1] + s * a[0],
            c + t * a[2] * a[2],
        ],
    ];
    let mut r = [[0.0f32; 3]; 3];
    for (i, row) in r.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = r0[i][0] * rq[0][j] + r0[i][1] * rq[1][j] + r0[i][2] * rq[2][j];
        }
    }
    r
}

impl<const N: usize> RigidBodyModel<N> {
    /// Joint torques [N*m] for positions [rad], speeds [rad/s], accelerations [rad/s^2].
    /// Fixed operation count: two passes over `N` joints, no data-dependent loops.
    pub fn torques(&self, q: &[f32; N], qd: &[f32; N], qdd: &[f32; N]) -> [f32; N] {
        /// One link of the forward recursion, in its own frame.
        #[derive(Clone, Copy)]
        struct Link {
            rot: [[f32; 3]; 3],
            w: V3,
            wd: V3,
            acc: V3,
        }
        // Forward recursion: each link's rotation, angular velocity and acceleration
        // and linear acceleration, in its own frame. `None` until written (setting the
        // tags is cheaper than zeroing 72 floats per 6 links that are all overwritten).
        let mut links: [Option<Link>; N] = [None; N];
        let mut w_p: V3 = [0.0; 3];
        let mut wd_p: V3 = [0.0; 3];
        let g = self.gravity_m_s2;
        let mut acc_p: V3 = [-g[0], -g[1], -g[2]];
        for (i, link) in links.iter_mut().enumerate() {
            let j = &self.joints[i];
            let r = joint_rotation(&j.origin_rotation, &j.axis, math::sin_cos(q[i]));
            let p = &j.origin_translation_m;
            // Linear acceleration of the new origin, in the new frame.
            let a_p = add(
                &add(&acc_p, &cross(&wd_p, p)),
                &cross(&w_p, &cross(&w_p, p)),
            );
            let w_in = mul_t(&r, &w_p);
            let qa = scale(&j.axis, qd[i]);
            w_p = add(&w_in, &qa);
            wd_p = add(
                &add(&mul_t(&r, &wd_p), &cross(&w_in, &qa)),
                &scale(&j.axis, qdd[i]),
            );
            acc_p = mul_t(&r, &a_p);
            *link = Some(Link {
                rot: r,
                w: w_p,
                wd: wd_p,
                acc: acc_p,
            });
        }
        let mut tau = [0.0f32; N];
        let mut f_c: V3 = [0.0; 3];
        let mut n_c: V3 = [0.0; 3];
        for k in (0..N).rev() {
            let j = &self.joints[k];
            let ph = &j.inertial;
            let h = [ph[1], ph[2], ph[3]];
            // Every link was written by the forward recursion.
            let Some(Link { w, wd, acc, .. }) = &links[k] else {
                continue;
            };
            let mut f = add(
                &add(&scale(acc, ph[0]), &cross(wd, &h)),
                &cross(w, &cross(w, &h)),
            );
            let mut n = add(
                &add(&inertia_mul(ph, wd), &cross(w, &inertia_mul(ph, w))),
                &cross(&h, acc),
            );
            if let Some(Link { rot: r, .. }) = links.get(k + 1).and_then(Option::as_ref) {
                let rf = mul(r, &f_c);
                f = add(&f, &rf);
                n = add(
                    &add(&n, &mul(r, &n_c)),
                    &cross(&self.joints[k + 1].origin_translation_m, &rf),
                );
            }
            let sgn = if self.coulomb_inv_eps_s_rad > 0.0 {
                math::tanh(qd[k] * self.coulomb_inv_eps_s_rad)
            } else if qd[k] > 0.0 {
                1.0
            } else if qd[k] < 0.0 {
                -1.0
            } else {
                0.0
            };
            tau[k] = dot3(&j.axis, &n)
                + j.viscous_nm_s_rad * qd[k]
                + j.coulomb_nm * sgn
                + j.offset_nm
                + j.rotor_inertia_kg_m2 * qdd[k]
                + j.extended_friction_nm(qd[k]);
            f_c = f;
            n_c = n;
        }
        tau
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A single pendulum about z with gravity along -y: tau = m*g*l*cos(q) + (I + m l^2) qdd.
    #[test]
    fn pendulum_matches_closed_form() {
        let (m, l, izz) = (2.0f32, 0.5f32, 0.1f32);
        let mut j = JointModel::ZERO;
        j.inertial = [
            m,
            m * l,
            0.0,
            0.0,
            0.0,
            izz + m * l * l,
            izz + m * l * l,
            0.0,
            0.0,
            0.0,
        ];
        let model = RigidBodyModel {
            joints: [j],
            gravity_m_s2: [0.0, -9.81, 0.0],
            coulomb_inv_eps_s_rad: 0.0,
        };
        for &(q, qdd) in &[(0.0f32, 0.0f32), (0.7, 1.5), (-2.0, -3.0)] {
            let tau = model.torques(&[q], &[0.3], &[qdd])[0];
            let expect = m * 9.81 * l * libm::cosf(q) + (izz + m * l * l) * qdd;
            assert!(
                (tau - expect).abs() < 1e-4 * (1.0 + expect.abs()),
                "{tau} {expect}"
            );
        }
    }

    /// Inside the identified speeds the extended terms are the plain basis, bit for bit;
    /// beyond, they grow linearly with the slope they have at the edge, on both sides.
    #[test]
    fn extended_friction_is_continued_linearly_beyond_the_identified_speeds() {
        let mut j = JointModel::ZERO;
        j.stribeck_nm = [0.4, -0.3, 0.8];
        j.quadratic_nm_s2_rad2 = 2.5;
        let plain = |v: f32| {
            let mut t = j.quadratic_nm_s2_rad2 * v * v.abs();
            for (f, inv) in j.stribeck_nm.iter().zip(STRIBECK_INV_SPEEDS_S_RAD) {
                t += f * math::tanh(v * inv);
            }
            t
        };
        // Unbounded range: the plain basis everywhere.
        for v in [-3.0f32, -0.1, 0.0, 0.02, 1.7] {
            assert_eq!(j.extended_friction_nm(v).to_bits(), plain(v).to_bits());
        }
        j.qd_range_rad_s = [-0.4, 0.6];
        for v in [-0.4f32, -0.1, 0.0, 0.3, 0.6] {
            assert_eq!(
                j.extended_friction_nm(v).to_bits(),
                plain(v).to_bits(),
                "{v}"
            );
        }
        for (edge, dir) in [(0.6f32, 1.0f32), (-0.4, -1.0)] {
            let at = |d: f32| j.extended_friction_nm(edge + dir * d);
            let step = 0.01;
            let s_edge = (plain(edge + dir * step) - plain(edge)) / step;
            // Equal increments beyond the edge: equal torque increments (a straight line)
            // with the edge's slope, where the plain quadratic would grow as qd².
            let d1 = at(1.0) - at(0.0);
            let d2 = at(2.0) - at(1.0);
            assert!((d1 - d2).abs() < 1e-4, "{d1} {d2}");
            assert!((d1 - s_edge).abs() < 0.05 * s_edge.abs(), "{d1} {s_edge}");
            assert!(plain(edge + dir * 10.0).abs() > 5.0 * at(10.0).abs());
        }
        assert!(j.extended_friction_nm(f32::NAN).is_nan());
    }
}
