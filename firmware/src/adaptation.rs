//! Online friction adaptation: what a joint's friction and torque offset are today.
//!
//! A joint's friction drifts from run to run (temperature, lubrication, load history)
//! by as much as the whole learned correction, and nothing the drive knows before a
//! tick predicts that drift. The drive does measure what it got wrong: the torque of
//! its own q current a tick later. This stage fits, by recursive least squares with
//! exponential forgetting, three levels to that error: a torque offset, a Coulomb level
//! (`tanh(qd / 0.05)`) and the friction held at rest on the side the joint came from
//! (the rest direction): features 0, 3 and 14 of
//! [`features::friction_features`](crate::features::friction_features), the same bits.
//! It runs after every other stage and adds its correction to their prediction.
//!
//! Bounded by construction: three regressors in `[-1, 1]`, weights and correction
//! clamped to `max_correction_nm`, the covariance's trace capped (no wind-up in the
//! directions a motion does not excite), a sample whose torque or prediction is not
//! finite skipped, fixed work per tick.

use crate::{features, math};

/// Number of adapted levels.
pub const ADAPTED_LEVELS: usize = 3;

/// Indices of the adapted levels among the friction features
/// ([`features::FRICTION_FEATURE_NAMES`]): `1`, `tanh(qd/0.05)`, `rest_dir`.
pub const ADAPTED_FEATURES: [usize; ADAPTED_LEVELS] = [0, 3, 14];

/// Largest covariance per level (the regressors are in `[-1, 1]`): the initial
/// covariance and the cap of its trace divided by [`ADAPTED_LEVELS`].
pub const MAX_COVARIANCE: f32 = 1.0;

/// Settings of the adaptation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdaptationConfig {
    /// Forgetting time constant, s: the adaptation averages the error over about this
    /// long. Zero (or not finite and positive) turns the adaptation off.
    pub time_constant_s: f32,
    /// Largest |correction| and |level|, N*m.
    pub max_correction_nm: f32,
}

impl AdaptationConfig {
    /// No adaptation.
    pub const OFF: AdaptationConfig = AdaptationConfig {
        time_constant_s: 0.0,
        max_correction_nm: 0.0,
    };

    /// The forgetting factor per tick at `tick_hz`, `1 - 1 / (T f)` (at most one tick's
    /// memory lost per tick), or `None` when the adaptation is off.
    pub fn forgetting(&self, tick_hz: f32) -> Option<f32> {
        let ticks = self.time_constant_s * tick_hz;
        let on = ticks.is_finite()
            && ticks >= 2.0
            && self.max_correction_nm.is_finite()
            && self.max_correction_nm > 0.0;
        on.then(|| 1.0 - 1.0 / ticks)
    }
}

/// The adapted levels' regressors from the joint's reference velocity [rad/s] and
/// rest direction (-1, 0, +1): `[1, tanh(qd/0.05), rest_dir]`.
#[inline]
pub fn regressors(qd_rad_s: f32, rest_direction: f32) -> [f32; ADAPTED_LEVELS] {
    [
        1.0,
        math::tanh(qd_rad_s * features::FRICTION_TANH_INV_SPEEDS_S_RAD[1]),
        rest_direction,
    ]
}

/// The recursive least-squares state of one joint.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrictionAdaptation {
    forgetting: f32,
    max_nm: f32,
    levels_nm: [f32; ADAPTED_LEVELS],
    covariance: [[f32; ADAPTED_LEVELS]; ADAPTED_LEVELS],
    pending: Option<([f32; ADAPTED_LEVELS], f32)>,
}

impl FrictionAdaptation {
    /// A joint ticking at `tick_hz` with nothing learned yet (off if `config` is off).
    pub fn new(config: AdaptationConfig, tick_hz: f32) -> Self {
        let (forgetting, max_nm) = match config.forgetting(tick_hz) {
            Some(f) => (f, config.max_correction_nm),
            None => (1.0, 0.0),
        };
        Self {
            forgetting,
            max_nm,
            levels_nm: [0.0; ADAPTED_LEVELS],
            covariance: initial_covariance(),
            pending: None,
        }
    }

    /// True when the adaptation runs.
    pub fn is_on(&self) -> bool {
        self.max_nm > 0.0
    }

    /// The adapted levels (N*m): offset, Coulomb, held at rest.
    pub fn levels_nm(&self) -> [f32; ADAPTED_LEVELS] {
        self.levels_nm
    }

    /// One tick: learn from `measured_nm`, the torque measured since the previous tick
    /// (against that tick's prediction), then return this tick's correction (N*m) to
    /// add to `base_nm`, the other stages' prediction for this tick.
    pub fn step(&mut self, x: [f32; ADAPTED_LEVELS], base_nm: f32, measured_nm: f32) -> f32 {
        if !self.is_on() {
            return 0.0;
        }
        if let Some((x_prev, base_prev)) = self.pending.take() {
            self.learn(x_prev, measured_nm - base_prev);
        }
        let x_ok = x.iter().all(|v| v.is_finite() && v.abs() <= 1.0);
        if !(x_ok && base_nm.is_finite()) {
            return 0.0;
        }
        self.pending = Some((x, base_nm));
        clamp(math::dot(&self.levels_nm, &x), self.max_nm)
    }

    /// Forget the pairing with the previous tick (after a gap in the inputs); the
    /// levels learned so far stay.
    pub fn restart(&mut self) {
        self.pending = None;
    }

    fn learn(&mut self, x: [f32; ADAPTED_LEVELS], error_nm: f32) {
        let e = error_nm - math::dot(&self.levels_nm, &x);
        if !e.is_finite() {
            return;
        }
        let p = &self.covariance;
        let px: [f32; ADAPTED_LEVELS] = core::array::from_fn(|i| math::dot(&p[i], &x));
        let denominator = self.forgetting + math::dot(&x, &px);
        if !(denominator.is_finite() && denominator > 0.0) {
            self.covariance = initial_covariance();
            return;
        }
        let inv = 1.0 / denominator;
        let inv_forgetting = 1.0 / self.forgetting;
        let mut trace = 0.0f32;
        for i in 0..ADAPTED_LEVELS {
            self.levels_nm[i] = clamp(self.levels_nm[i] + px[i] * inv * e, self.max_nm);
            for j in 0..ADAPTED_LEVELS {
                self.covariance[i][j] =
                    (self.covariance[i][j] - px[i] * px[j] * inv) * inv_forgetting;
            }
            trace += self.covariance[i][i];
        }
        let cap = MAX_COVARIANCE * ADAPTED_LEVELS as f32;
        if !(trace.is_finite() && trace > 0.0) {
            self.covariance = initial_covariance();
        } else if trace > cap {
            let s = cap / trace;
            for row in &mut self.covariance {
                for v in row {
                    *v *= s;
                }
            }
        }
    }
}

fn initial_covariance() -> [[f32; ADAPTED_LEVELS]; ADAPTED_LEVELS] {
    core::array::from_fn(|i| core::array::from_fn(|j| if i == j { MAX_COVARIANCE } else { 0.0 }))
}

fn clamp(v: f32, max: f32) -> f32 {
    if v.is_finite() {
        v.clamp(-max, max)
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::features::{DRIVE_INPUTS_PER_JOINT, friction_features};

    const ON: AdaptationConfig = AdaptationConfig {
        time_constant_s: 2.0,
        max_correction_nm: 10.0,
    };

    #[test]
    fn the_regressors_are_the_friction_features_bits() {
        for (qd, rest) in [
            (0.0, 1.0),
            (0.013, 0.0),
            (-0.4, 0.0),
            (2.5, 0.0),
            (0.0, -1.0),
        ] {
            let mut x = [0.0f32; DRIVE_INPUTS_PER_JOINT];
            x[2] = qd;
            x[5] = rest;
            let f = friction_features(&x);
            let r = regressors(qd, rest);
            for (k, &i) in ADAPTED_FEATURES.iter().enumerate() {
                assert_eq!(
                    r[k].to_bits(),
                    f[i].to_bits(),
                    "qd {qd} rest {rest} level {k}"
                );
            }
        }
    }

    #[test]
    fn it_learns_a_drifted_offset_and_coulomb_level() {
        // The true error: 1.5 N*m offset + 2 N*m Coulomb, on a slow sine motion.
        let mut a = FrictionAdaptation::new(ON, 100.0);
        let mut rest = features::RestDirection::new();
        let mut measured = f32::NAN;
        let mut last_err = 0.0f32;
        for k in 0..3000 {
            let qd = 0.5 * math::sin_cos(k as f32 * 0.01).0;
            let x = regressors(qd, rest.update(qd));
            let corr = a.step(x, 0.0, measured);
            let truth = 1.5 + 2.0 * x[1];
            measured = truth;
            last_err = truth - corr;
        }
        assert!(last_err.abs() < 0.05, "error {last_err}");
        let l = a.levels_nm();
        assert!(
            (l[0] - 1.5).abs() < 0.1 && (l[1] - 2.0).abs() < 0.1,
            "{l:?}"
        );
    }

    #[test]
    fn it_is_bounded_and_skips_bad_samples() {
        let mut a = FrictionAdaptation::new(ON, 1000.0);
        for k in 0..5000 {
            let m = match k % 7 {
                0 => f32::NAN,
                1 => f32::INFINITY,
                _ => 1e9,
            };
            let c = a.step([1.0, (k % 3) as f32 - 1.0, 0.0], 0.0, m);
            assert!(c.abs() <= 10.0 && c.is_finite());
        }
        assert!(a.levels_nm().iter().all(|l| l.abs() <= 10.0));
        // Non-finite or out-of-range regressors or base: no correction, nothing paired.
        assert_eq!(a.step([f32::NAN, 0.0, 0.0], 0.0, 0.0), 0.0);
        assert_eq!(a.step([2.0, 0.0, 0.0], 0.0, 0.0), 0.0);
        assert_eq!(a.step([1.0, 0.0, 0.0], f32::NAN, 0.0), 0.0);
    }

    #[test]
    fn off_is_off() {
        for cfg in [
            AdaptationConfig::OFF,
            AdaptationConfig {
                time_constant_s: f32::NAN,
                ..ON
            },
            AdaptationConfig {
                max_correction_nm: 0.0,
                ..ON
            },
            AdaptationConfig {
                time_constant_s: 0.001,
                ..ON
            },
        ] {
            let mut a = FrictionAdaptation::new(cfg, 100.0);
            assert!(!a.is_on());
            for _ in 0..10 {
                assert_eq!(a.step([1.0, 0.0, 0.0], 0.0, 5.0), 0.0);
            }
        }
    }

    #[test]
    fn a_direction_without_excitation_does_not_wind_up() {
        // Long rest on one side: offset and held level are indistinguishable; the
        // covariance stays capped and the correction follows the measured error.
        let mut a = FrictionAdaptation::new(ON, 100.0);
        for _ in 0..100_000 {
            a.step([1.0, 0.0, 1.0], 0.0, 3.0);
        }
        let trace: f32 = (0..ADAPTED_LEVELS).map(|i| a.covariance[i][i]).sum();
        assert!(trace <= MAX_COVARIANCE * ADAPTED_LEVELS as f32 + 1e-6);
        let c = a.step([1.0, 0.0, 1.0], 0.0, 3.0);
        assert!((c - 3.0).abs() < 1e-3, "{c}");
    }
}
