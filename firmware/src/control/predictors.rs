//! Predictors that plug into the [`TorquePredictor`] trait:
//! - [`RigidBodyModel`] (the identified dynamics, all its joints compensated) and
//!   [`SubsetModel`] (a larger model of which `J` joints are compensated, the others
//!   held at fixed positions, e.g. the wrist of a 6-joint arm): the model stage;
//! - [`LstmPredictor`]: the exported LSTM in any precision behind [`TorqueNetwork`],
//!   for the `paper` preset (next-step torque from model torque, measured torque and
//!   position), the `feedforward` preset (model torque + learned
//!   residual) or the `drive` preset (model torque + residual learned from the drive's
//!   own features, `crate::features`): the LSTM stage;
//! - [`DecoupledJointModel`]: a per-joint model without coupling (tests, bring-up).
//!
//! All run in fixed time, without heap or panic paths.

use super::compensator::{PredictorInput, TorquePredictor};
use crate::dynamics::RigidBodyModel;
use crate::envelope::{self, JointEnvelope};
use crate::features::{self, DRIVE_INPUTS_PER_JOINT, FRICTION_FEATURES, MotionMemory};
use crate::math;
use crate::nn::format::{FeaturePreset, QuantFormat, QuantState};
use crate::nn::kernels::{F32Lstm, F32State, InputLayer, QuantLstm};
use core::borrow::Borrow;

/// The model's torques on every joint's reference (`q_ref`, `qd_ref`, `qdd_ref`).
impl<const J: usize> TorquePredictor<J> for RigidBodyModel<J> {
    fn predict_nm(&mut self, input: &PredictorInput<J>) -> [f32; J] {
        self.torques(
            &input.joints.map(|s| s.q_ref_rad),
            &input.joints.map(|s| s.qd_ref_rad_s),
            &input.joints.map(|s| s.qdd_ref_rad_s2),
        )
    }
    fn reset(&mut self) {}
}

/// `J` compensated joints of an `N`-joint rigid-body model: joint `k` of the
/// compensator is model joint `joints[k]`; every other model joint stays at
/// `fixed_q_rad` (at rest). `M` is the model or a reference to it (a `static`).
#[derive(Clone, Copy, Debug)]
pub struct SubsetModel<M, const N: usize, const J: usize> {
    /// The model.
    pub model: M,
    /// Model joint index of each compensated joint (out-of-range indices are ignored:
    /// that joint's torque is NaN, which the compensator rejects).
    pub joints: [usize; J],
    /// Positions of the model's joints, rad (the compensated ones are overwritten).
    pub fixed_q_rad: [f32; N],
}

impl<M: Borrow<RigidBodyModel<N>>, const N: usize, const J: usize> TorquePredictor<J>
    for SubsetModel<M, N, J>
{
    fn predict_nm(&mut self, input: &PredictorInput<J>) -> [f32; J] {
        let mut q = self.fixed_q_rad;
        let mut qd = [0.0f32; N];
        let mut qdd = [0.0f32; N];
        for (s, &m) in input.joints.iter().zip(self.joints.iter()) {
            if let (Some(a), Some(b), Some(c)) = (q.get_mut(m), qd.get_mut(m), qdd.get_mut(m)) {
                *a = s.q_ref_rad;
                *b = s.qd_ref_rad_s;
                *c = s.qdd_ref_rad_s2;
            }
        }
        let tau = self.model.borrow().torques(&q, &qd, &qdd);
        self.joints.map(|m| tau.get(m).copied().unwrap_or(f32::NAN))
    }
    fn reset(&mut self) {}
}

/// A recurrent network stepped once per compensator tick, `I` raw inputs to `O`
/// de-normalised outputs: the exported LSTM in any precision.
pub trait TorqueNetwork<const I: usize, const O: usize> {
    /// Its recurrent state.
    type State;
    /// The zero state a sequence starts from.
    fn zero_state(&self) -> Self::State;
    /// One step: advances `state` by `input`, returns the outputs.
    fn step(&self, state: &mut Self::State, input: &[f32; I]) -> [f32; O];
}

impl<
    F: QuantFormat,
    const I: usize,
    const IQ: usize,
    const EB: usize,
    const H: usize,
    const HQ: usize,
    const ZQ: usize,
    const O: usize,
    const OB: usize,
> TorqueNetwork<I, O> for QuantLstm<F, I, IQ, EB, H, HQ, ZQ, O, OB>
{
    type State = QuantState<ZQ, H>;
    fn zero_state(&self) -> Self::State {
        QuantState::new()
    }
    fn step(&self, state: &mut Self::State, input: &[f32; I]) -> [f32; O] {
        QuantLstm::step(self, state, input)
    }
}

impl<
    const I: usize,
    const E: usize,
    const EB: usize,
    const H: usize,
    const Z: usize,
    const O: usize,
    const OB: usize,
    A: InputLayer,
> TorqueNetwork<I, O> for F32Lstm<I, E, EB, H, Z, O, OB, A>
{
    type State = F32State<Z, H>;
    fn zero_state(&self) -> Self::State {
        F32State::new()
    }
    fn step(&self, state: &mut Self::State, input: &[f32; I]) -> [f32; O] {
        F32Lstm::step(self, state, input)
    }
}

impl<T: TorqueNetwork<I, O> + ?Sized, const I: usize, const O: usize> TorqueNetwork<I, O> for &T {
    type State = T::State;
    fn zero_state(&self) -> Self::State {
        (**self).zero_state()
    }
    fn step(&self, state: &mut Self::State, input: &[f32; I]) -> [f32; O] {
        (**self).step(state, input)
    }
}

/// The LSTM stage for `J` joints (`I` = the preset's inputs per joint x `J` inputs, `J`
/// outputs), in the feature layout of its preset (all joints of one kind, then the next):
///
/// - `paper`: inputs `tau_model`, `tau_meas`, `q` -> the torque one tick later. The
///   network was trained on (inputs at step k, torque at k+1), so each tick pairs the
///   model torque and position of the *previous* tick (the instant the feedforward was
///   computed for then) with the torque measured since (`tau_meas`, e.g. the mean over
///   the last compensator period): the output is the torque for this tick's instant.
///   Positions are the references (`q_ref`), which the joint tracks to encoder level.
/// - `paper_relative`: as `paper` with the measured residual `tau_meas - tau_model` in
///   place of `tau_meas` -> the residual one tick later, added to this tick's model torque.
/// - `feedforward`: inputs `tau_model`, `q`, `qd` -> residual; the prediction is
///   `tau_model + residual` on this tick's references.
/// - `drive`: inputs [`features::drive_inputs`] of this tick's references and the residual
///   measured since the previous tick (`tau_meas` minus that tick's model torque) -> residual,
///   added to `tau_model` like `feedforward`, plus the preset's linear stage
///   ([`features::linear_correction_nm`] of the same inputs, [`Self::with_linear_stage`]).
///
/// Each joint's training envelope ([`Self::with_envelope`], `crate::envelope`) fades
/// everything learned (the network's correction to the model torque and the linear
/// stage) by its weight at this tick's state, and clamps the linear stage's features to
/// their recorded ranges; without one ([`JointEnvelope::UNBOUNDED`]) nothing is faded.
pub struct LstmPredictor<N: TorqueNetwork<I, J>, const J: usize, const I: usize> {
    network: N,
    state: N::State,
    preset: FeaturePreset,
    previous: Option<([f32; J], [f32; J])>,
    motion: [MotionMemory; J],
    linear: [[f32; FRICTION_FEATURES]; J],
    envelope: [JointEnvelope; J],
    weight: [f32; J],
}

impl<N: TorqueNetwork<I, J>, const J: usize, const I: usize> LstmPredictor<N, J, I> {
    /// The stage for a network trained with `preset`; `None` for `Custom` (no known
    /// layout) or when `I` is not the preset's inputs per joint times `J`.
    pub fn new(network: N, preset: FeaturePreset) -> Option<Self> {
        if preset == FeaturePreset::Custom || !preset.fits(J, I, J) {
            return None;
        }
        let state = network.zero_state();
        Some(Self {
            network,
            state,
            preset,
            previous: None,
            motion: [MotionMemory::new(); J],
            linear: [[0.0; FRICTION_FEATURES]; J],
            envelope: [JointEnvelope::UNBOUNDED; J],
            weight: [1.0; J],
        })
    }

    /// The `drive` preset's linear stage: per joint, coefficients of
    /// [`features::FRICTION_FEATURE_NAMES`] (the model file's `LINEAR_STAGE`). Other
    /// presets ignore it.
    pub fn with_linear_stage(mut self, coefficients: [[f32; FRICTION_FEATURES]; J]) -> Self {
        self.linear = coefficients;
        self
    }

    /// Each joint's training envelope (the model file's `ENVELOPE`): the learned
    /// stages fade by its weight outside it, the linear stage's features are clamped
    /// to its ranges.
    pub fn with_envelope(mut self, envelope: [JointEnvelope; J]) -> Self {
        self.envelope = envelope;
        self
    }

    /// Each joint's envelope weight at the last prediction (1 before the first).
    pub fn envelope_weights(&self) -> [f32; J] {
        self.weight
    }

    /// The network.
    pub fn network(&self) -> &N {
        &self.network
    }
}

impl<N: TorqueNetwork<I, J>, const J: usize, const I: usize> TorquePredictor<J>
    for LstmPredictor<N, J, I>
{
    fn predict_nm(&mut self, input: &PredictorInput<J>) -> [f32; J] {
        let q_ref = input.joints.map(|s| s.q_ref_rad);
        let tau_meas = input.joints.map(|s| s.tau_meas_nm);
        let mut x = [0.0f32; I];
        let mut linear_nm = [0.0f32; J];
        // The previous tick's model torque and position (on the first tick, this one's),
        // and the residual measured since: the torque measured over that tick minus the
        // model torque predicted for it.
        let (model_prev, q_prev) = self.previous.unwrap_or((input.model_nm, q_ref));
        self.previous = Some((input.model_nm, q_ref));
        let measured_residual: [f32; J] = core::array::from_fn(|j| tau_meas[j] - model_prev[j]);
        if self.preset == FeaturePreset::Drive {
            for (j, (s, motion)) in input.joints.iter().zip(self.motion.iter_mut()).enumerate() {
                let f = features::drive_inputs(
                    s.q_ref_rad,
                    s.qd_ref_rad_s,
                    s.qdd_ref_rad_s2,
                    input.model_nm[j],
                    motion.update(s.q_ref_rad, s.qd_ref_rad_s),
                    measured_residual[j],
                );
                for (kind, v) in f.iter().enumerate().take(DRIVE_INPUTS_PER_JOINT) {
                    if let Some(slot) = x.get_mut(kind * J + j) {
                        *slot = *v;
                    }
                }
                linear_nm[j] =
                    features::linear_correction_nm(&self.linear[j], &self.envelope[j], &f);
            }
        } else if self.preset == FeaturePreset::Feedforward {
            let qd_ref = input.joints.map(|s| s.qd_ref_rad_s);
            let features = input.model_nm.iter().chain(&q_ref).chain(&qd_ref);
            for (v, f) in x.iter_mut().zip(features) {
                *v = *f;
            }
        } else {
            let measured = if self.preset == FeaturePreset::PaperRelative {
                &measured_residual
            } else {
                &tau_meas
            };
            let features = model_prev.iter().chain(measured).chain(&q_prev);
            for (v, f) in x.iter_mut().zip(features) {
                *v = *f;
            }
        }
        let y = self.network.step(&mut self.state, &x);
        let mut out = [0.0f32; J];
        for (j, o) in out.iter_mut().enumerate() {
            let s = &input.joints[j];
            let w = self.envelope[j].weight(
                s.q_ref_rad,
                s.qd_ref_rad_s,
                s.qdd_ref_rad_s2,
                input.model_nm[j],
                measured_residual[j],
            );
            self.weight[j] = w;
            let full = self.preset.torque_nm(y[j], input.model_nm[j]) + linear_nm[j];
            *o = envelope::fade_nm(w, input.model_nm[j], full);
        }
        out
    }

    fn reset(&mut self) {
        self.state = self.network.zero_state();
        self.previous = None;
        self.motion = [MotionMemory::new(); J];
    }

    fn envelope_weight(&self, joint_index: usize) -> f32 {
        self.weight.get(joint_index).copied().unwrap_or(1.0)
    }
}

/// tau_j = I_j qdd_j + D_j qd_j + mu_j tanh(qd_j / v_j) + g_j sin(q_j + phi_j) on each
/// joint's reference, ignoring the coupling between joints.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DecoupledJointModel<const J: usize> {
    /// Joint-side inertia (load + rotor * ratio^2), kg*m^2.
    pub inertia_kg_m2: [f32; J],
    /// Viscous friction, N*m*s/rad.
    pub viscous_nm_s_rad: [f32; J],
    /// Coulomb friction, N*m.
    pub coulomb_nm: [f32; J],
    /// Velocity over which the Coulomb term changes sign, rad/s (> 0).
    pub coulomb_smoothing_rad_s: [f32; J],
    /// Gravity torque amplitude, N*m.
    pub gravity_nm: [f32; J],
    /// Gravity phase, rad.
    pub gravity_phase_rad: [f32; J],
}

impl<const J: usize> TorquePredictor<J> for DecoupledJointModel<J> {
    fn predict_nm(&mut self, input: &PredictorInput<J>) -> [f32; J] {
        let mut out = [0.0f32; J];
        for (j, (o, s)) in out.iter_mut().zip(input.joints.iter()).enumerate() {
            let smooth = self.coulomb_smoothing_rad_s[j].max(1e-6);
            *o = self.inertia_kg_m2[j] * s.qdd_ref_rad_s2
                + self.viscous_nm_s_rad[j] * s.qd_ref_rad_s
                + self.coulomb_nm[j] * math::tanh(s.qd_ref_rad_s / smooth)
                + self.gravity_nm[j] * math::sin(s.q_ref_rad + self.gravity_phase_rad[j]);
        }
        out
    }
    fn reset(&mut self) {}
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::JointState;

    fn input1(q: f32, qd: f32, tau_meas: f32, model: f32) -> PredictorInput<1> {
        PredictorInput {
            joints: [JointState {
                q_ref_rad: q,
                qd_ref_rad_s: qd,
                tau_meas_nm: tau_meas,
                ..Default::default()
            }],
            own_joint: 0,
            model_nm: [model],
        }
    }

    /// A network that returns its `pick`-th input (the drive stage's layout check).
    struct Pick(usize);

    impl<const I: usize> TorqueNetwork<I, 1> for Pick {
        type State = ();
        fn zero_state(&self) {}
        fn step(&self, _: &mut (), x: &[f32; I]) -> [f32; 1] {
            [x[self.0]]
        }
    }

    #[test]
    fn drive_stage_feeds_the_drive_features_and_adds_the_residual() {
        // Moving, then at rest after moving backwards: the rest direction is -1, and
        // 0.2 rad backwards saturates every presliding element at -1.
        let ticks = [(0.4f32, -0.3f32, 2.0f32, 5.0f32), (0.2, 0.0, 0.0, 4.0)];
        let (s, c) = math::sin_cos(0.2);
        // The residual measured since the first tick: 9 - 5.
        let want = [s, c, 0.0, 0.0, 4.0, -1.0, -1.0, -1.0, -1.0, -1.0, 9.0 - 5.0];
        for (pick, w) in want.iter().enumerate() {
            let mut p = LstmPredictor::<_, 1, DRIVE_INPUTS_PER_JOINT>::new(
                Pick(pick),
                FeaturePreset::Drive,
            )
            .unwrap();
            let mut y = [0.0];
            for &(q, qd, qdd, m) in &ticks {
                let mut input = input1(q, qd, 9.0, m);
                input.joints[0].qdd_ref_rad_s2 = qdd;
                y = p.predict_nm(&input);
            }
            assert_eq!(y, [4.0 + w], "input {pick}");
        }
        // The linear stage adds its correction of the same inputs.
        let mut w = [[0.0; FRICTION_FEATURES]; 1];
        (w[0][0], w[0][4]) = (0.25, 3.0);
        let mut p =
            LstmPredictor::<_, 1, DRIVE_INPUTS_PER_JOINT>::new(Pick(5), FeaturePreset::Drive)
                .unwrap()
                .with_linear_stage(w);
        let y = p.predict_nm(&input1(0.2, 0.5, 9.0, 4.0));
        let tanh = math::tanh(0.5 * 5.0);
        assert_eq!(y, [4.0 + 0.0 + (0.25 + 3.0 * tanh)]);
        // A network of another width does not fit the drive layout.
        assert!(LstmPredictor::<_, 1, 3>::new(Pick(0), FeaturePreset::Drive).is_none());
    }

    #[test]
    fn the_envelope_fades_the_learned_share_to_the_model_and_clamps_the_linear_stage() {
        // Network output 2 (a residual), linear stage 0.5 + 1 * qd: at qd = 0.5 inside
        // the envelope the prediction is model + 2 + 0.5 + 0.5.
        let mut w = [[0.0; FRICTION_FEATURES]; 1];
        (w[0][0], w[0][6]) = (0.5, 1.0);
        let mut e = JointEnvelope::UNBOUNDED;
        e.drive[2] = envelope::Range::new(-0.5, 0.5);
        e.friction[6] = envelope::Range::new(-0.5, 0.5);
        struct Two;
        impl TorqueNetwork<DRIVE_INPUTS_PER_JOINT, 1> for Two {
            type State = ();
            fn zero_state(&self) {}
            fn step(&self, _: &mut (), _: &[f32; DRIVE_INPUTS_PER_JOINT]) -> [f32; 1] {
                [2.0]
            }
        }
        let mut p = LstmPredictor::<_, 1, DRIVE_INPUTS_PER_JOINT>::new(Two, FeaturePreset::Drive)
            .unwrap()
            .with_linear_stage(w)
            .with_envelope([e]);
        assert_eq!(p.predict_nm(&input1(0.0, 0.5, 0.0, 4.0)), [4.0 + 2.0 + 1.0]);
        assert_eq!(p.envelope_weights(), [1.0]);
        // Half a fade width out (fade width 0.25 * 1 + 0.05 = 0.3): weight 0.5, and the
        // qd feature clamped at 0.5.
        let y = p.predict_nm(&input1(0.0, 0.65, 0.0, 4.0));
        let wt = p.envelope_weight(0);
        assert!((wt - 0.5).abs() < 1e-5, "{wt}");
        assert_eq!(y, [envelope::fade_nm(wt, 4.0, 4.0 + 2.0 + 1.0)]);
        // Beyond the fade: the model alone.
        assert_eq!(p.predict_nm(&input1(0.0, 3.0, 0.0, 4.0)), [4.0]);
        assert_eq!(p.envelope_weight(0), 0.0);
    }

    #[test]
    fn paper_stages_pair_the_previous_tick_with_the_torque_measured_since() {
        // Tick 1: model 5, q 0.4, measured 9; tick 2: model 4, q 0.2, measured 7.
        let ticks = [(0.4f32, 9.0f32, 5.0f32), (0.2, 7.0, 4.0)];
        for (preset, want) in [
            // `paper`: [model, measured, q] of the previous tick and the torque since;
            // the output is the torque.
            (FeaturePreset::Paper, [5.0, 7.0, 0.4]),
            // `paper_relative`: the measured residual 7 - 5 in place of the torque; the
            // output is added to this tick's model torque 4.
            (
                FeaturePreset::PaperRelative,
                [4.0 + 5.0, 4.0 + 2.0, 4.0 + 0.4],
            ),
        ] {
            for (pick, w) in want.iter().enumerate() {
                let mut p = LstmPredictor::<_, 1, 3>::new(Pick(pick), preset).unwrap();
                let mut y = [0.0];
                for &(q, tau_meas, model) in &ticks {
                    y = p.predict_nm(&input1(q, 0.0, tau_meas, model));
                }
                assert_eq!(y, [*w], "{preset:?} input {pick}");
            }
        }
    }

    #[test]
    fn decoupled_model_terms() {
        let mut m = DecoupledJointModel::<2> {
            inertia_kg_m2: [2.0, 0.0],
            viscous_nm_s_rad: [3.0, 0.0],
            coulomb_nm: [5.0, 1.0],
            coulomb_smoothing_rad_s: [1e-3, 0.0],
            gravity_nm: [10.0, 0.0],
            gravity_phase_rad: [0.0, 0.0],
        };
        let s = JointState {
            q_ref_rad: core::f32::consts::FRAC_PI_2,
            qd_ref_rad_s: 1.0,
            qdd_ref_rad_s2: 4.0,
            ..Default::default()
        };
        let out = m.predict_nm(&PredictorInput {
            joints: [s, JointState::default()],
            own_joint: 0,
            model_nm: [0.0; 2],
        });
        assert!((out[0] - (8.0 + 3.0 + 5.0 + 10.0)).abs() < 1e-4, "{out:?}");
        assert_eq!(out[1], 0.0);
        // The gravity phase adds to the angle: 10 sin(0.3 + 0.5), not 10 sin(0.3 - 0.5).
        m.gravity_phase_rad = [0.5, 0.0];
        let s = JointState {
            q_ref_rad: 0.3,
            ..Default::default()
        };
        let out = m.predict_nm(&PredictorInput {
            joints: [s, JointState::default()],
            own_joint: 0,
            model_nm: [0.0; 2],
        });
        assert!((out[0] - 10.0 * libm::sinf(0.8)).abs() < 1e-3, "{out:?}");
    }
}
