//! What a drive knows of its own joint before a compensator tick, as the `drive` feature
//! preset feeds it to the network: the reference angle as its sine and cosine (bounded,
//! so poses outside the training range stay in distribution), the reference velocity
//! and acceleration, the first-stage model torque, and the direction of the last motion
//! while the joint is at rest (held friction and backlash keep the side the joint came
//! from). The host writes the same columns into its datasets with these functions, so
//! training and the drive see the same bits.

use crate::math;

/// Speed [rad/s] at or below which a joint counts as at rest.
pub const REST_BAND_RAD_S: f32 = 0.005;

/// Inputs per joint of the `drive` preset, in this order: `sin q`, `cos q`, `qd`
/// [rad/s], `qdd` [rad/s^2], model torque [N*m], rest direction (-1, 0, +1).
pub const DRIVE_INPUTS_PER_JOINT: usize = 6;

/// Names of the `drive` preset's per-joint dataset columns (suffix `_j<N>`), in input
/// order.
pub const DRIVE_COLUMNS: [&str; DRIVE_INPUTS_PER_JOINT] =
    ["sin_q", "cos_q", "qd", "qdd", "tau_model", "rest_dir"];

/// Number of friction features of the `drive` preset's linear stage.
pub const FRICTION_FEATURES: usize = 16;

/// `1 / v0` [s/rad] of the `tanh(qd / v0)` features, v0 = 0.01, 0.05, 0.2, 1 rad/s.
pub const FRICTION_TANH_INV_SPEEDS_S_RAD: [f32; 4] = [100.0, 20.0, 5.0, 1.0];

/// `1 / v` [s/rad] of the load-dependent friction feature `|tau_model| tanh(qd / v)`,
/// v = 0.05 rad/s.
pub const LOAD_FRICTION_INV_SPEED_S_RAD: f32 = 20.0;

/// Names of the friction features, in coefficient order.
pub const FRICTION_FEATURE_NAMES: [&str; FRICTION_FEATURES] = [
    "1",
    "tau_model",
    "tanh(qd/0.01)",
    "tanh(qd/0.05)",
    "tanh(qd/0.2)",
    "tanh(qd/1)",
    "qd",
    "qd*|qd|",
    "sqrt(|qd|)*sign(qd)",
    "qdd",
    "sin(q)",
    "cos(q)",
    "sin(2q)",
    "cos(2q)",
    "rest_dir",
    "|tau_model|*tanh(qd/0.05)",
];

/// The friction features of one joint from its `drive` inputs ([`DRIVE_COLUMNS`]):
/// what the built-in linear baseline fits and the `drive` preset's linear stage
/// evaluates (Coulomb and Stribeck-shaped `tanh` terms, viscous, quadratic and
/// square-root drag, inertia, pose terms of the joint's own angle, the rest direction
/// and load-dependent friction).
#[inline]
pub fn friction_features(x: &[f32; DRIVE_INPUTS_PER_JOINT]) -> [f32; FRICTION_FEATURES] {
    let [s, c, qd, qdd, model, rest] = *x;
    let th = FRICTION_TANH_INV_SPEEDS_S_RAD.map(|inv| math::tanh(qd * inv));
    let sign = if qd > 0.0 {
        1.0
    } else if qd < 0.0 {
        -1.0
    } else {
        0.0
    };
    [
        1.0,
        model,
        th[0],
        th[1],
        th[2],
        th[3],
        qd,
        qd * qd.abs(),
        math::sqrt(qd.abs()) * sign,
        qdd,
        s,
        c,
        2.0 * s * c,
        c * c - s * s,
        rest,
        model.abs() * th[1],
    ]
}

/// Joint `joint`'s `drive` inputs out of a row of `joints` joints laid out kind-major
/// (all joints' `sin q`, then all `cos q`, ...), as the predictor and the datasets lay
/// them out; a row too short for them gives 0.
pub fn joint_drive_inputs(
    row: &[f32],
    joints: usize,
    joint: usize,
) -> [f32; DRIVE_INPUTS_PER_JOINT] {
    core::array::from_fn(|kind| row.get(kind * joints + joint).copied().unwrap_or(0.0))
}

/// The linear stage's correction [N*m]: `coefficients . friction_features(x)`.
#[inline]
pub fn linear_correction_nm(
    coefficients: &[f32; FRICTION_FEATURES],
    x: &[f32; DRIVE_INPUTS_PER_JOINT],
) -> f32 {
    math::dot(coefficients, &friction_features(x))
}

/// The direction of the last motion, remembered while a joint is at rest.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RestDirection {
    last: f32,
}

impl RestDirection {
    /// No motion seen yet.
    pub const fn new() -> Self {
        Self { last: 0.0 }
    }

    /// Advances by one tick's velocity [rad/s]: `+1` or `-1` (the last direction of
    /// motion) while `|qd| <= REST_BAND_RAD_S`, `0` while moving or before any motion.
    /// A non-finite `qd` counts as rest and does not change the memory.
    pub fn update(&mut self, qd_rad_s: f32) -> f32 {
        if qd_rad_s > REST_BAND_RAD_S {
            self.last = 1.0;
            0.0
        } else if qd_rad_s < -REST_BAND_RAD_S {
            self.last = -1.0;
            0.0
        } else {
            self.last
        }
    }
}

/// One joint's `drive` inputs ([`DRIVE_COLUMNS`] order).
#[inline]
pub fn drive_inputs(
    q_rad: f32,
    qd_rad_s: f32,
    qdd_rad_s2: f32,
    model_nm: f32,
    rest_direction: f32,
) -> [f32; DRIVE_INPUTS_PER_JOINT] {
    let (s, c) = math::sin_cos(q_rad);
    [s, c, qd_rad_s, qdd_rad_s2, model_nm, rest_direction]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rest_direction_remembers_the_last_motion_only_at_rest() {
        let mut d = RestDirection::new();
        let seq = [0.0, 0.3, 0.001, 0.0, -0.2, -0.004, 0.0, f32::NAN, 0.01];
        let got: [f32; 9] = core::array::from_fn(|k| d.update(seq[k]));
        assert_eq!(got, [0.0, 0.0, 1.0, 1.0, 0.0, -1.0, -1.0, -1.0, 0.0]);
    }

    #[test]
    fn friction_features_follow_their_names() {
        let (q, qd) = (0.4f32, -0.3f32);
        let x = drive_inputs(q, qd, 2.0, -5.0, 1.0);
        let f = friction_features(&x);
        let close = |a: f32, b: f64| (f64::from(a) - b).abs() < 1e-6;
        let qd64 = f64::from(qd);
        assert!(close(f[0], 1.0) && close(f[1], -5.0));
        assert!(close(f[3], (qd64 / 0.05).tanh()) && close(f[5], qd64.tanh()));
        assert!(close(f[7], qd64 * qd64.abs()) && close(f[8], -qd64.abs().sqrt()));
        assert!(close(f[9], 2.0) && close(f[12], (2.0 * f64::from(q)).sin()));
        assert!(close(f[13], (2.0 * f64::from(q)).cos()) && close(f[14], 1.0));
        assert!(close(f[15], 5.0 * (qd64 / 0.05).tanh()));
        let mut w = [0.0; FRICTION_FEATURES];
        w[1] = 2.0;
        w[0] = 0.5;
        assert_eq!(linear_correction_nm(&w, &x), 0.5 + 2.0 * -5.0);
    }

    #[test]
    fn drive_inputs_bound_the_angle() {
        let x = drive_inputs(100.0, 1.0, 2.0, 3.0, -1.0);
        assert!(x[0].abs() <= 1.0 && x[1].abs() <= 1.0);
        assert!((x[0] * x[0] + x[1] * x[1] - 1.0).abs() < 1e-6);
        assert_eq!(&x[2..], &[1.0, 2.0, 3.0, -1.0]);
    }
}
