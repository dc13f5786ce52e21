//! What a drive knows of its own joint before a compensator tick, as the `drive` feature
//! preset feeds it to the network: the reference angle as its sine and cosine (bounded,
//! so poses outside the training range stay in distribution), the reference velocity
//! and acceleration, the first-stage model torque, the direction of the last motion
//! while the joint is at rest (held friction and backlash keep the side the joint came
//! from), and the states of presliding (Maxwell-slip) elements: friction at a velocity
//! reversal builds up over the angle travelled since the reversal, not with the
//! velocity, so each element is a spring of a given span that saturates at +-1 (a
//! generalised Maxwell-slip friction model, linear in its weights and independent of
//! the sample rate); and the residual the drive measured over the previous tick (its
//! own torque minus the model torque it predicted for that tick: what the model missed
//! a tick ago, the strongest single predictor of what it misses now). The host writes
//! the same columns into its datasets with these functions (the measured residual it
//! derives when it reads a dataset, [`MEASURED_RESIDUAL_COLUMN`]), so training and the
//! drive see the same bits.

use crate::envelope::JointEnvelope;
use crate::math;

/// Speed [rad/s] at or below which a joint counts as at rest.
pub const REST_BAND_RAD_S: f32 = 0.005;

/// Presliding (Maxwell-slip) elements per joint.
pub const PRESLIDING_ELEMENTS: usize = 4;

/// `1 / span` [1/rad] of the presliding elements: spans of 1, 3, 10 and 30 mrad.
pub const PRESLIDING_INV_SPANS_PER_RAD: [f32; PRESLIDING_ELEMENTS] =
    [1000.0, 1000.0 / 3.0, 100.0, 1000.0 / 30.0];

/// Inputs per joint of the `drive` preset, in this order: `sin q`, `cos q`, `qd`
/// [rad/s], `qdd` [rad/s^2], model torque [N*m], rest direction (-1, 0, +1), the
/// presliding states (-1 ..= +1, spans [`PRESLIDING_INV_SPANS_PER_RAD`]), the residual
/// measured over the previous tick [N*m].
pub const DRIVE_INPUTS_PER_JOINT: usize = 7 + PRESLIDING_ELEMENTS;

/// The `drive` column of the residual measured over the previous tick: in a dataset,
/// `tau_meas - tau_model` of the previous row (of the first row, its own), in f32.
pub const MEASURED_RESIDUAL_COLUMN: &str = "tau_resid_prev";

/// Names of the `drive` preset's per-joint dataset columns (suffix `_j<N>`), in input
/// order.
pub const DRIVE_COLUMNS: [&str; DRIVE_INPUTS_PER_JOINT] = [
    "sin_q",
    "cos_q",
    "qd",
    "qdd",
    "tau_model",
    "rest_dir",
    "slip_1mrad",
    "slip_3mrad",
    "slip_10mrad",
    "slip_30mrad",
    MEASURED_RESIDUAL_COLUMN,
];

/// Number of friction features of the `drive` preset's linear stage.
pub const FRICTION_FEATURES: usize = 19 + 2 * PRESLIDING_ELEMENTS;

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
    "tau_model*tanh(qd/0.05)",
    "|tau_model|*tanh(qd/0.2)",
    "|tau_model|",
    "slip_1mrad",
    "slip_3mrad",
    "slip_10mrad",
    "slip_30mrad",
    "|tau_model|*slip_1mrad",
    "|tau_model|*slip_3mrad",
    "|tau_model|*slip_10mrad",
    "|tau_model|*slip_30mrad",
];

/// The friction features of one joint from its `drive` inputs ([`DRIVE_COLUMNS`]):
/// what the built-in linear baseline fits and the `drive` preset's linear stage
/// evaluates (Coulomb and Stribeck-shaped `tanh` terms, viscous, quadratic and
/// square-root drag, inertia, pose terms of the joint's own angle, the rest direction,
/// load-dependent friction, and the presliding states alone and scaled by the load).
#[inline]
pub fn friction_features(x: &[f32; DRIVE_INPUTS_PER_JOINT]) -> [f32; FRICTION_FEATURES] {
    let [
        s,
        c,
        qd,
        qdd,
        model,
        rest,
        p0,
        p1,
        p2,
        p3,
        _measured_residual,
    ] = *x;
    let th = FRICTION_TANH_INV_SPEEDS_S_RAD.map(|inv| math::tanh(qd * inv));
    let load = model.abs();
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
        load * th[1],
        model * th[1],
        load * th[2],
        load,
        p0,
        p1,
        p2,
        p3,
        load * p0,
        load * p1,
        load * p2,
        load * p3,
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

/// The linear stage's correction [N*m]: `coefficients . friction_features(x)`, each
/// feature first clamped to its range in the joint's training `envelope`
/// ([`JointEnvelope::clamp_features`]), so that no term grows beyond its value at the
/// envelope's edge.
#[inline]
pub fn linear_correction_nm(
    coefficients: &[f32; FRICTION_FEATURES],
    envelope: &JointEnvelope,
    x: &[f32; DRIVE_INPUTS_PER_JOINT],
) -> f32 {
    math::dot(
        coefficients,
        &envelope.clamp_features(&friction_features(x)),
    )
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

/// Presliding (Maxwell-slip) element states of one joint: each element follows the
/// joint's angle like a spring of span `1 / PRESLIDING_INV_SPANS_PER_RAD[k]` and
/// saturates at -1 and +1 (it slips), so after a reversal it sweeps from one side to
/// the other over its span of travel.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Presliding {
    last_q_rad: Option<f32>,
    state: [f32; PRESLIDING_ELEMENTS],
}

impl Presliding {
    /// All elements relaxed (0); the first angle seen is the start.
    pub const fn new() -> Self {
        Self {
            last_q_rad: None,
            state: [0.0; PRESLIDING_ELEMENTS],
        }
    }

    /// Advances by one tick's angle [rad] and returns the element states. A non-finite
    /// angle leaves the memory unchanged.
    pub fn update(&mut self, q_rad: f32) -> [f32; PRESLIDING_ELEMENTS] {
        if q_rad.is_finite() {
            let dq = self.last_q_rad.map_or(0.0, |last| q_rad - last);
            self.last_q_rad = Some(q_rad);
            for (s, inv) in self.state.iter_mut().zip(PRESLIDING_INV_SPANS_PER_RAD) {
                // Constant, ordered bounds: `clamp` cannot panic; `x` is never NaN.
                *s = (*s + dq * inv).clamp(-1.0, 1.0);
            }
        }
        self.state
    }
}

/// What a joint's drive remembers of its motion: the rest direction and the
/// presliding states.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MotionMemory {
    rest: RestDirection,
    presliding: Presliding,
}

impl MotionMemory {
    /// Nothing seen yet.
    pub const fn new() -> Self {
        Self {
            rest: RestDirection::new(),
            presliding: Presliding::new(),
        }
    }

    /// Advances by one tick's angle [rad] and velocity [rad/s]: the rest direction and
    /// the presliding states, as [`drive_inputs`] takes them.
    pub fn update(&mut self, q_rad: f32, qd_rad_s: f32) -> (f32, [f32; PRESLIDING_ELEMENTS]) {
        (self.rest.update(qd_rad_s), self.presliding.update(q_rad))
    }
}

/// One joint's `drive` inputs ([`DRIVE_COLUMNS`] order); `rest_direction` and
/// `presliding` from [`MotionMemory::update`]; `measured_residual_nm` the torque measured
/// over the previous tick minus the model torque predicted for it.
#[inline]
pub fn drive_inputs(
    q_rad: f32,
    qd_rad_s: f32,
    qdd_rad_s2: f32,
    model_nm: f32,
    (rest_direction, presliding): (f32, [f32; PRESLIDING_ELEMENTS]),
    measured_residual_nm: f32,
) -> [f32; DRIVE_INPUTS_PER_JOINT] {
    let (s, c) = math::sin_cos(q_rad);
    let [p0, p1, p2, p3] = presliding;
    [
        s,
        c,
        qd_rad_s,
        qdd_rad_s2,
        model_nm,
        rest_direction,
        p0,
        p1,
        p2,
        p3,
        measured_residual_nm,
    ]
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
        let slip = [0.5, -0.25, 1.0, -1.0];
        let x = drive_inputs(q, qd, 2.0, -5.0, (1.0, slip), 7.0);
        let f = friction_features(&x);
        let close = |a: f32, b: f64| (f64::from(a) - b).abs() < 1e-6;
        let qd64 = f64::from(qd);
        assert!(close(f[0], 1.0) && close(f[1], -5.0));
        assert!(close(f[3], (qd64 / 0.05).tanh()) && close(f[5], qd64.tanh()));
        assert!(close(f[7], qd64 * qd64.abs()) && close(f[8], -qd64.abs().sqrt()));
        assert!(close(f[9], 2.0) && close(f[12], (2.0 * f64::from(q)).sin()));
        assert!(close(f[13], (2.0 * f64::from(q)).cos()) && close(f[14], 1.0));
        assert!(close(f[15], 5.0 * (qd64 / 0.05).tanh()));
        assert!(close(f[16], -5.0 * (qd64 / 0.05).tanh()));
        assert!(close(f[17], 5.0 * (qd64 / 0.2).tanh()) && close(f[18], 5.0));
        for (k, &p) in slip.iter().enumerate() {
            assert!(close(f[19 + k], f64::from(p)) && close(f[23 + k], 5.0 * f64::from(p)));
        }
        assert_eq!(FRICTION_FEATURE_NAMES[19], "slip_1mrad");
        let mut w = [0.0; FRICTION_FEATURES];
        w[1] = 2.0;
        w[0] = 0.5;
        assert_eq!(
            linear_correction_nm(&w, &JointEnvelope::UNBOUNDED, &x),
            0.5 + 2.0 * -5.0
        );
        // Clamped to the envelope's range of tau_model: -1.
        let mut e = JointEnvelope::UNBOUNDED;
        e.friction[1] = crate::envelope::Range::new(-1.0, 1.0);
        assert_eq!(linear_correction_nm(&w, &e, &x), 0.5 - 2.0);
    }

    #[test]
    fn drive_inputs_bound_the_angle() {
        let x = drive_inputs(100.0, 1.0, 2.0, 3.0, (-1.0, [0.0, 0.1, 0.2, 0.3]), 7.0);
        assert!(x[0].abs() <= 1.0 && x[1].abs() <= 1.0);
        assert!((x[0] * x[0] + x[1] * x[1] - 1.0).abs() < 1e-6);
        assert_eq!(&x[2..], &[1.0, 2.0, 3.0, -1.0, 0.0, 0.1, 0.2, 0.3, 7.0]);
    }

    #[test]
    fn presliding_elements_saturate_over_their_span_after_a_reversal() {
        let mut p = Presliding::new();
        assert_eq!(p.update(1.0), [0.0; PRESLIDING_ELEMENTS]);
        // 0.5 mrad forward: the 1 mrad element is half way, the others in proportion.
        let s = p.update(1.0005);
        assert!((s[0] - 0.5).abs() < 1e-3 && (s[2] - 0.05).abs() < 1e-4);
        // 40 mrad forward: every element saturated at +1.
        assert_eq!(p.update(1.0405), [1.0; PRESLIDING_ELEMENTS]);
        // A reversal of 2 mrad: the 1 mrad element has swept to -1, the 10 mrad one
        // has moved 0.2 of its span back, the 30 mrad one about 0.067.
        let s = p.update(1.0385);
        assert_eq!(s[0], -1.0);
        assert!((s[2] - 0.8).abs() < 1e-3 && (s[3] - (1.0 - 2.0 / 30.0)).abs() < 1e-3);
        // A non-finite angle leaves it unchanged; an infinite jump saturates.
        assert_eq!(p.update(f32::NAN), s);
        assert_eq!(p.update(f32::MAX), [1.0; PRESLIDING_ELEMENTS]);
        assert_eq!(p.update(-f32::MAX), [-1.0; PRESLIDING_ELEMENTS]);
    }

    #[test]
    fn presliding_does_not_depend_on_the_sample_rate_along_one_direction() {
        let (mut coarse, mut fine) = (Presliding::new(), Presliding::new());
        coarse.update(0.0);
        fine.update(0.0);
        let a = coarse.update(0.002);
        let b = (1..=20).map(|k| fine.update(0.0001 * k as f32)).last();
        for (x, y) in a.iter().zip(b.unwrap_or_default()) {
            assert!((x - y).abs() < 1e-4, "{a:?} {b:?}");
        }
    }
}
