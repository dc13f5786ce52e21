//! The training envelope of one compensated joint: the range of every input the learned
//! stages read, as recorded over the training datasets (whole runs), and a coarse
//! coverage grid of the (angle, velocity) plane.
//!
//! The learned stages (the `drive` preset's linear stage and the LSTM's correction; for
//! the `paper`, `paper_relative` and `feedforward` presets the network's residual) know
//! nothing of states they never saw, and friction features such as `qd*|qd|` grow
//! without bound. So the firmware
//!
//! - clamps each friction feature to its recorded range before the linear stage's dot
//!   product ([`JointEnvelope::clamp_features`], used by
//!   [`crate::features::linear_correction_nm`]): no term grows beyond its value at the
//!   envelope's edge;
//! - multiplies everything learned beyond the identified model by
//!   [`JointEnvelope::weight`]: 1 inside the envelope, fading smoothly and monotonically
//!   to 0 as the joint's state leaves it, so that far outside the prediction is the
//!   identified model's ([`fade_nm`]).
//!
//! **The fade.** The weight reads the inputs of [`FADED_INPUT_NAMES`]: the angle, the
//! velocity, the acceleration, the model torque and the residual measured over the
//! previous tick. For each, `d` is the distance outside its recorded range `[lo, hi]`
//! (0 inside) and its fade width is `FADE_FRACTION * (hi - lo) + MIN_FADE[k]`: a quarter
//! of the range plus a small floor in the input's unit (so a joint recorded at one
//! speed still fades over a finite width). The input's weight is the smoothstep
//! `s^2 (3 - 2 s)` of `s = 1 - d / width` clamped to [0, 1]: 1 at the edge, 0 one fade
//! width beyond it, continuous with a continuous slope; the joint's weight is the
//! smallest of the five. A non-finite input gives weight 0. The other recorded inputs
//! (`sin q`, `cos q`, the rest direction, the presliding states) are bounded to [-1, 1]
//! by construction and are not faded; their ranges are recorded for the reports.
//!
//! **Coverage.** The recorded (q, qd) rectangle is cut into [`COVERAGE_CELLS_Q`] x
//! [`COVERAGE_CELLS_QD`] equal cells; bit `iq * COVERAGE_CELLS_QD + iqd` of
//! [`JointEnvelope::coverage`] is set when that cell held at least
//! [`COVERAGE_MIN_SAMPLES`] training samples. [`JointEnvelope::covered`] checks a state in
//! a few operations. Coverage is reported (how much of the envelope a run visits); the
//! fade uses the ranges only.
//!
//! **Unbounded.** [`JointEnvelope::UNBOUNDED`] has infinite ranges and every cell
//! covered: its weight is always 1 and it clamps nothing. It is the explicit choice for
//! models that carry no envelope: seeded test networks, and networks exported with
//! `export --no-envelope`.
//!
//! Everything here is fixed work (loops over const-size arrays), no heap, no panic path.

use crate::features::{DRIVE_INPUTS_PER_JOINT, FRICTION_FEATURES};

/// A closed range `[lo, hi]` of one input as recorded at training.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Range {
    /// Smallest value seen.
    pub lo: f32,
    /// Largest value seen.
    pub hi: f32,
}

impl Range {
    /// The range `[lo, hi]`.
    pub const fn new(lo: f32, hi: f32) -> Self {
        Self { lo, hi }
    }

    /// The whole real line: nothing is outside.
    pub const UNBOUNDED: Self = Self {
        lo: f32::NEG_INFINITY,
        hi: f32::INFINITY,
    };

    /// Whether the range is usable: `lo <= hi`, neither NaN (infinite ends allowed).
    pub const fn is_valid(&self) -> bool {
        self.lo <= self.hi
    }

    /// `x` limited to the range; NaN stays NaN.
    #[inline]
    pub fn clamp(&self, x: f32) -> f32 {
        if x < self.lo {
            self.lo
        } else if x > self.hi {
            self.hi
        } else {
            x
        }
    }

    /// The weight of `x` for a fade floor `min_fade` (module docs): 1 inside, the
    /// smoothstep down to 0 one fade width outside, 0 for a non-finite `x`.
    #[inline]
    pub fn fade_weight(&self, x: f32, min_fade: f32) -> f32 {
        if !x.is_finite() {
            return 0.0;
        }
        let d = if x < self.lo {
            self.lo - x
        } else if x > self.hi {
            x - self.hi
        } else {
            0.0
        };
        if d <= 0.0 {
            return 1.0;
        }
        let width = FADE_FRACTION * (self.hi - self.lo) + min_fade;
        let s = 1.0 - d / width;
        if s >= 1.0 {
            1.0
        } else if s > 0.0 {
            s * s * (3.0 - 2.0 * s)
        } else {
            0.0
        }
    }
}

/// Number of inputs the weight reads ([`FADED_INPUT_NAMES`]).
pub const FADED_INPUTS: usize = 5;

/// The inputs the weight reads, in [`JointEnvelope::weight`]'s argument order: angle
/// [rad], velocity [rad/s], acceleration [rad/s^2], model torque [N*m], the residual
/// measured over the previous tick [N*m].
pub const FADED_INPUT_NAMES: [&str; FADED_INPUTS] =
    ["q", "qd", "qdd", "tau_model", "tau_resid_prev"];

/// Index in `crate::features::DRIVE_COLUMNS` of the faded inputs after the angle (qd,
/// qdd, tau_model, tau_resid_prev).
pub const FADED_DRIVE_COLUMNS: [usize; FADED_INPUTS - 1] = [2, 3, 4, 10];

/// Fade width as a share of an input's recorded range.
pub const FADE_FRACTION: f32 = 0.25;

/// Floor of each faded input's fade width, in its unit ([`FADED_INPUT_NAMES`] order):
/// 0.05 rad, 0.05 rad/s, 0.5 rad/s^2, 0.5 N*m, 0.5 N*m.
pub const MIN_FADE: [f32; FADED_INPUTS] = [0.05, 0.05, 0.5, 0.5, 0.5];

/// Cells of the coverage grid along the angle.
pub const COVERAGE_CELLS_Q: usize = 8;
/// Cells of the coverage grid along the velocity.
pub const COVERAGE_CELLS_QD: usize = 8;
/// Training samples a coverage cell must hold to count as covered.
pub const COVERAGE_MIN_SAMPLES: usize = 20;

/// The training envelope of one compensated joint (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointEnvelope {
    /// Range of the joint angle [rad].
    pub q_rad: Range,
    /// Ranges of the `drive` preset's inputs (`crate::features::DRIVE_COLUMNS` order).
    pub drive: [Range; DRIVE_INPUTS_PER_JOINT],
    /// Ranges of the friction features (`crate::features::FRICTION_FEATURE_NAMES`
    /// order): the linear stage clamps each feature to its range.
    pub friction: [Range; FRICTION_FEATURES],
    /// Covered cells of the (q, qd) grid, bit `iq * COVERAGE_CELLS_QD + iqd`.
    pub coverage: u64,
}

impl JointEnvelope {
    /// No envelope: every range infinite, every cell covered; weight always 1, no
    /// clamping. Only for models that carry none by an explicit choice (module docs).
    pub const UNBOUNDED: Self = Self {
        q_rad: Range::UNBOUNDED,
        drive: [Range::UNBOUNDED; DRIVE_INPUTS_PER_JOINT],
        friction: [Range::UNBOUNDED; FRICTION_FEATURES],
        coverage: u64::MAX,
    };

    /// Whether every range is usable ([`Range::is_valid`]); checked at compile time for
    /// compiled-in models.
    pub const fn is_valid(&self) -> bool {
        if !self.q_rad.is_valid() {
            return false;
        }
        let mut k = 0;
        while k < DRIVE_INPUTS_PER_JOINT {
            if !self.drive[k].is_valid() {
                return false;
            }
            k += 1;
        }
        let mut k = 0;
        while k < FRICTION_FEATURES {
            if !self.friction[k].is_valid() {
                return false;
            }
            k += 1;
        }
        true
    }

    /// The ranges of the faded inputs ([`FADED_INPUT_NAMES`] order).
    #[inline]
    pub fn faded_ranges(&self) -> [Range; FADED_INPUTS] {
        let d = FADED_DRIVE_COLUMNS;
        [
            self.q_rad,
            self.drive[d[0]],
            self.drive[d[1]],
            self.drive[d[2]],
            self.drive[d[3]],
        ]
    }

    /// The weight in [0, 1] of the learned stages at this state (module docs): 1 inside
    /// the envelope, fading to 0 outside; 0 for any non-finite input. Fixed work.
    #[inline]
    pub fn weight(
        &self,
        q_rad: f32,
        qd_rad_s: f32,
        qdd_rad_s2: f32,
        model_nm: f32,
        measured_residual_nm: f32,
    ) -> f32 {
        let x = [q_rad, qd_rad_s, qdd_rad_s2, model_nm, measured_residual_nm];
        let ranges = self.faded_ranges();
        let mut w = 1.0f32;
        for k in 0..FADED_INPUTS {
            let wk = ranges[k].fade_weight(x[k], MIN_FADE[k]);
            if wk < w {
                w = wk;
            }
        }
        w
    }

    /// The friction features each limited to its recorded range (NaN stays NaN).
    #[inline]
    pub fn clamp_features(&self, f: &[f32; FRICTION_FEATURES]) -> [f32; FRICTION_FEATURES] {
        let mut out = *f;
        for (v, r) in out.iter_mut().zip(self.friction.iter()) {
            *v = r.clamp(*v);
        }
        out
    }

    /// The coverage cell of a state, `iq * COVERAGE_CELLS_QD + iqd`; `None` outside the
    /// recorded (q, qd) rectangle or for a non-finite input.
    #[inline]
    pub fn cell(&self, q_rad: f32, qd_rad_s: f32) -> Option<usize> {
        let iq = grid_index(self.q_rad, q_rad, COVERAGE_CELLS_Q)?;
        let iqd = grid_index(
            self.drive[FADED_DRIVE_COLUMNS[0]],
            qd_rad_s,
            COVERAGE_CELLS_QD,
        )?;
        Some(iq * COVERAGE_CELLS_QD + iqd)
    }

    /// Whether a state lies in a covered cell (an unbounded envelope covers all).
    #[inline]
    pub fn covered(&self, q_rad: f32, qd_rad_s: f32) -> bool {
        if self.coverage == u64::MAX && q_rad.is_finite() && qd_rad_s.is_finite() {
            return true;
        }
        match self.cell(q_rad, qd_rad_s) {
            Some(c) => self.coverage & (1u64 << (c as u32 & 63)) != 0,
            None => false,
        }
    }

    /// Number of covered cells.
    pub const fn covered_cells(&self) -> u32 {
        self.coverage.count_ones()
    }
}

/// Whether every envelope of a model is valid ([`JointEnvelope::is_valid`]; for
/// `check_model!`).
pub const fn all_valid(envelopes: &[JointEnvelope]) -> bool {
    let mut k = 0;
    while k < envelopes.len() {
        if !envelopes[k].is_valid() {
            return false;
        }
        k += 1;
    }
    true
}

/// Cell of `x` among `cells` equal cells of `r`; `None` outside or non-finite. A range
/// of zero width has its single value in cell 0.
#[inline]
fn grid_index(r: Range, x: f32, cells: usize) -> Option<usize> {
    if !(x >= r.lo && x <= r.hi) {
        return None;
    }
    let width = r.hi - r.lo;
    if !(width > 0.0 && width.is_finite()) {
        return Some(0);
    }
    // In [0, cells]; the saturating cast and the `min` keep the top edge in the last cell.
    let t = (x - r.lo) / width * cells as f32;
    Some((t as usize).min(cells - 1))
}

/// The faded prediction [N*m]: `full_nm` (model plus everything learned) when
/// `weight >= 1`, exactly `model_nm` when `weight <= 0` (or NaN), else
/// `model_nm + weight * (full_nm - model_nm)`.
#[inline]
pub fn fade_nm(weight: f32, model_nm: f32, full_nm: f32) -> f32 {
    if weight >= 1.0 {
        full_nm
    } else if weight > 0.0 {
        model_nm + weight * (full_nm - model_nm)
    } else {
        model_nm
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn envelope() -> JointEnvelope {
        let mut e = JointEnvelope::UNBOUNDED;
        e.q_rad = Range::new(-1.0, 1.0);
        e.drive[2] = Range::new(-0.5, 0.5);
        e.drive[3] = Range::new(-2.0, 2.0);
        e.drive[4] = Range::new(-10.0, 10.0);
        e.drive[10] = Range::new(-1.0, 1.0);
        e.coverage = 1;
        e
    }

    #[test]
    fn weight_is_one_inside_and_fades_monotonically_to_zero_outside() {
        let e = envelope();
        assert_eq!(e.weight(0.0, 0.0, 0.0, 0.0, 0.0), 1.0);
        assert_eq!(e.weight(1.0, 0.5, 2.0, 10.0, 1.0), 1.0);
        // qd: range 1 wide, fade width 0.25 + 0.05 = 0.3 beyond 0.5.
        let mut last = 1.0;
        for k in 1..=40 {
            let qd = 0.5 + 0.01 * k as f32;
            let w = e.weight(0.0, qd, 0.0, 0.0, 0.0);
            assert!(w <= last && (0.0..=1.0).contains(&w), "{qd} {w}");
            last = w;
        }
        assert_eq!(e.weight(0.0, 0.81, 0.0, 0.0, 0.0), 0.0);
        assert_eq!(e.weight(0.0, -0.81, 0.0, 0.0, 0.0), 0.0);
        let mid = e.weight(0.0, 0.65, 0.0, 0.0, 0.0);
        assert!((mid - 0.5).abs() < 1e-5, "{mid}");
        // The smallest input weight decides; a non-finite input gives 0.
        assert!(e.weight(1.4, 0.65, 0.0, 0.0, 0.0) < mid);
        assert_eq!(e.weight(f32::NAN, 0.0, 0.0, 0.0, 0.0), 0.0);
        assert_eq!(e.weight(0.0, 0.0, 0.0, f32::INFINITY, 0.0), 0.0);
        // Unbounded: always 1 for finite inputs.
        let u = JointEnvelope::UNBOUNDED;
        assert_eq!(u.weight(1e30, -1e30, 1e30, 1e30, 1e30), 1.0);
        assert!(u.is_valid() && e.is_valid());
    }

    #[test]
    fn features_clamp_to_their_ranges_and_fade_reaches_the_model() {
        let mut e = envelope();
        e.friction[7] = Range::new(-0.25, 0.25);
        let mut f = [3.0f32; FRICTION_FEATURES];
        f[7] = 9.0;
        let c = e.clamp_features(&f);
        assert_eq!(c[7], 0.25);
        assert_eq!(c[6], 3.0);
        assert!(e.clamp_features(&[f32::NAN; FRICTION_FEATURES])[0].is_nan());
        assert_eq!(fade_nm(1.0, 2.0, 5.0), 5.0);
        assert_eq!(fade_nm(0.0, 2.0, 5.0), 2.0);
        assert_eq!(fade_nm(0.5, 2.0, 5.0), 3.5);
        assert_eq!(fade_nm(f32::NAN, 2.0, 5.0), 2.0);
        assert_eq!(fade_nm(0.0, f32::INFINITY, 5.0), f32::INFINITY);
        let mut bad = e;
        bad.friction[0] = Range::new(1.0, 0.0);
        assert!(!bad.is_valid());
        bad.friction[0] = Range::new(f32::NAN, 0.0);
        assert!(!bad.is_valid());
    }

    #[test]
    fn coverage_cells_of_the_grid() {
        let e = envelope();
        assert_eq!(e.cell(-1.0, -0.5), Some(0));
        assert_eq!(e.cell(1.0, 0.5), Some(63));
        assert_eq!(e.cell(1.5, 0.0), None);
        assert_eq!(e.cell(f32::NAN, 0.0), None);
        assert!(e.covered(-0.9, -0.45));
        assert!(!e.covered(0.0, 0.0));
        assert!(JointEnvelope::UNBOUNDED.covered(5.0, 1.0));
        assert!(!JointEnvelope::UNBOUNDED.covered(f32::NAN, 1.0));
        assert_eq!(e.covered_cells(), 1);
    }
}
