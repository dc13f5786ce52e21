//! The torque feedforward compensator: per compensator tick, a torque prediction
//! from the identified dynamics model and (optionally) the LSTM behind the
//! [`TorquePredictor`] trait, with a fallback chain LSTM -> model only -> zero,
//! a watchdog on the other joints' states, rate and magnitude limits, and a
//! warm-up after every reset. The result is a q-current held until the next tick.

use super::faults::FaultFlags;
use super::message::{JointState, JointStateMessage, StateLimits};

/// What a predictor sees: every modelled joint's latest valid state (this joint's
/// own from its sensors, the others' from the state bus) and, for the LSTM stage,
/// the model stage's torques.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PredictorInput<const J: usize> {
    /// States of the modelled joints, in model order.
    pub joints: [JointState; J],
    /// Index of this MCU's joint among them.
    pub own_joint: usize,
    /// The model stage's joint torques, N*m (zero in the model stage itself).
    pub model_nm: [f32; J],
}

/// A torque predictor for `J` modelled joints: the identified dynamics model, or the
/// LSTM that corrects it (which reads `input.model_nm`).
///
/// Implementations must run in bounded time and never panic; they may return any
/// value: the compensator rejects non-finite and out-of-range predictions.
pub trait TorquePredictor<const J: usize> {
    /// False for the placeholder [`NoPredictor`] (a model-only compensator).
    const PRESENT: bool = true;
    /// The predicted joint-side torque of every modelled joint, N*m (for the `paper`
    /// preset the LSTM's next-step torque, for `feedforward` tau_model + residual).
    fn predict_nm(&mut self, input: &PredictorInput<J>) -> [f32; J];
    /// Forget the internal state (the LSTM's h and c); a no-op for stateless models.
    fn reset(&mut self);
}

/// No predictor: use as the LSTM stage of a model-only compensator.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoPredictor;

impl<const J: usize> TorquePredictor<J> for NoPredictor {
    const PRESENT: bool = false;
    fn predict_nm(&mut self, _input: &PredictorInput<J>) -> [f32; J] {
        [0.0; J]
    }
    fn reset(&mut self) {}
}

/// Which stage the feedforward came from this tick.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FeedforwardSource {
    /// No usable prediction: the target is zero.
    #[default]
    Zero,
    /// The dynamics model only.
    Model,
    /// The model corrected by the LSTM.
    ModelLstm,
}

/// Configuration of the compensator.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CompensatorConfig {
    /// Compensator tick rate, Hz (100 Hz in the paper, up to several kHz).
    pub rate_hz: f32,
    /// This MCU's joint index among the modelled joints.
    pub own_joint: usize,
    /// Bounds on accepted joint states.
    pub state_limits: StateLimits,
    /// Watchdog: another joint's state is stale once more than this many consecutive
    /// compensator ticks passed without a fresh message from it.
    pub watchdog_ticks: u16,
    /// Watchdog: a message whose sender timestamp is more than this far from the
    /// local bus time (either way) is stale, microseconds.
    pub max_message_age_us: u32,
    /// Magnitude limit of the torque feedforward, N*m (joint side).
    pub max_torque_nm: f32,
    /// Rate limit of the torque feedforward, N*m per second.
    pub max_torque_rate_nm_s: f32,
    /// Largest plausible LSTM correction |tau_lstm - tau_model|, N*m.
    pub max_lstm_correction_nm: f32,
    /// Ticks over which the feedforward (after zero) or the LSTM's share (after an
    /// LSTM reset) is blended in linearly.
    pub warmup_ticks: u16,
    /// Ticks the LSTM stays off after it was rejected, before it is reset and
    /// warmed up again.
    pub lstm_retry_ticks: u16,
    /// Drive gain: joint-side torque per A of motor q current, N*m/A (motor torque
    /// constant * gear ratio * gear efficiency).
    pub drive_gain_nm_per_a: f32,
    /// Limit of the feedforward q current, A.
    pub max_current_a: f32,
}

/// Why a configuration was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ConfigError {
    /// `own_joint` is not below the number of modelled joints.
    OwnJointOutOfRange,
    /// A rate, gain or limit is not finite and positive.
    NonPositive,
}

impl CompensatorConfig {
    fn check<const J: usize>(&self) -> Result<(), ConfigError> {
        if self.own_joint >= J {
            return Err(ConfigError::OwnJointOutOfRange);
        }
        let positive = |x: f32| x > 0.0 && x.is_finite();
        let ok = positive(self.rate_hz)
            && positive(self.max_torque_nm)
            && positive(self.max_torque_rate_nm_s)
            && positive(self.max_lstm_correction_nm)
            && positive(self.drive_gain_nm_per_a)
            && positive(self.max_current_a)
            && self.warmup_ticks > 0
            && self.watchdog_ticks > 0;
        if ok {
            Ok(())
        } else {
            Err(ConfigError::NonPositive)
        }
    }
}

/// One compensator tick's result.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CompensatorOutput {
    /// Torque feedforward after all limits, N*m (joint side).
    pub torque_nm: f32,
    /// The same as a q-current feedforward, A (hold it until the next tick).
    pub current_a: f32,
    /// The stage the target came from.
    pub source: FeedforwardSource,
    /// Faults of this tick (and of messages received since the last tick).
    pub faults: FaultFlags,
}

/// The per-joint feedforward compensator for `J` modelled joints with a model stage
/// `M` and an LSTM stage `L` (use [`NoPredictor`] for model only).
pub struct Compensator<const J: usize, M, L> {
    config: CompensatorConfig,
    model: M,
    lstm: L,
    dt_s: f32,
    states: [JointState; J],
    last_sequence: [u16; J],
    last_timestamp_us: [u32; J],
    received: [bool; J],
    ticks_since_rx: [u16; J],
    rx_faults: FaultFlags,
    latched: FaultFlags,
    torque_nm: f32,
    ff_blend_ticks: u16,
    lstm_blend_ticks: u16,
    lstm_off_ticks: u16,
    inputs_were_ok: bool,
}

impl<const J: usize, M: TorquePredictor<J>, L: TorquePredictor<J>> Compensator<J, M, L> {
    /// A compensator; its feedforward starts at zero and warms up.
    pub fn new(config: CompensatorConfig, model: M, lstm: L) -> Result<Self, ConfigError> {
        config.check::<J>()?;
        Ok(Self {
            config,
            model,
            lstm,
            dt_s: 1.0 / config.rate_hz,
            states: [JointState::default(); J],
            last_sequence: [0; J],
            last_timestamp_us: [0; J],
            received: [false; J],
            ticks_since_rx: [u16::MAX; J],
            rx_faults: FaultFlags::NONE,
            latched: FaultFlags::NONE,
            torque_nm: 0.0,
            ff_blend_ticks: 0,
            lstm_blend_ticks: 0,
            lstm_off_ticks: 0,
            inputs_were_ok: false,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &CompensatorConfig {
        &self.config
    }

    /// The model stage.
    pub fn model_mut(&mut self) -> &mut M {
        &mut self.model
    }

    /// The LSTM stage.
    pub fn lstm_mut(&mut self) -> &mut L {
        &mut self.lstm
    }

    /// Every fault seen since the last [`Compensator::clear_latched`].
    pub fn latched_faults(&self) -> FaultFlags {
        self.latched
    }

    /// Clear the latched faults.
    pub fn clear_latched(&mut self) {
        self.latched = FaultFlags::NONE;
    }

    /// The last feedforward torque, N*m.
    pub fn torque_nm(&self) -> f32 {
        self.torque_nm
    }

    /// Reset the LSTM's state explicitly; its share is blended in again over the
    /// warm-up.
    pub fn reset_lstm(&mut self) {
        self.lstm.reset();
        self.lstm_blend_ticks = 0;
        self.lstm_off_ticks = 0;
    }

    /// Accept another joint's state from the bus (call on reception, any time
    /// between ticks). Rejected messages leave the last good state in place and
    /// set a fault reported by the next tick.
    pub fn receive(&mut self, msg: &JointStateMessage) -> FaultFlags {
        let j = msg.joint as usize;
        let mut f = FaultFlags::NONE;
        if j >= J || j == self.config.own_joint || !self.config.state_limits.accepts(&msg.state) {
            f = FaultFlags::STATE_REJECTED;
        } else if self.received[j] && (msg.sequence.wrapping_sub(self.last_sequence[j]) as i16) <= 0
        {
            f = FaultFlags::STATE_OUT_OF_ORDER;
        } else if let (Some(s), Some(seq), Some(ts), Some(rx), Some(age)) = (
            self.states.get_mut(j),
            self.last_sequence.get_mut(j),
            self.last_timestamp_us.get_mut(j),
            self.received.get_mut(j),
            self.ticks_since_rx.get_mut(j),
        ) {
            *s = msg.state;
            *seq = msg.sequence;
            *ts = msg.timestamp_us;
            *rx = true;
            *age = 0;
        }
        self.rx_faults |= f;
        f
    }

    /// One compensator tick: this joint's own state and the local bus time ->
    /// the limited feedforward torque and q current.
    pub fn tick(&mut self, own: &JointState, now_us: u32) -> CompensatorOutput {
        let cfg = self.config;
        let own_j = cfg.own_joint;
        let mut faults = self.rx_faults;
        self.rx_faults = FaultFlags::NONE;

        // Inputs: own state valid, every other joint fresh.
        let mut inputs_ok = true;
        if !cfg.state_limits.accepts(own) {
            faults |= FaultFlags::OWN_STATE_INVALID;
            inputs_ok = false;
        }
        for j in 0..J {
            let age = self.ticks_since_rx[j];
            self.ticks_since_rx[j] = age.saturating_add(1);
            if j == own_j {
                continue;
            }
            let skew_us = now_us.wrapping_sub(self.last_timestamp_us[j]) as i32;
            let too_old = skew_us.unsigned_abs() > cfg.max_message_age_us;
            if !self.received[j] || age > cfg.watchdog_ticks || too_old {
                faults |= FaultFlags::STATE_STALE;
                inputs_ok = false;
            }
        }

        let mut target = 0.0f32;
        let mut source = FeedforwardSource::Zero;
        if inputs_ok {
            if !self.inputs_were_ok {
                // The input stream was broken: restart the LSTM's state and blend
                // the feedforward in from zero.
                self.lstm.reset();
                self.lstm_blend_ticks = 0;
                self.ff_blend_ticks = 0;
            }
            if let Some(slot) = self.states.get_mut(own_j) {
                *slot = *own;
            }
            let mut input = PredictorInput {
                joints: self.states,
                own_joint: own_j,
                model_nm: [0.0; J],
            };
            let model_nm = self.model.predict_nm(&input);
            // (own_joint < J is checked by `new`; a miss would read as invalid.)
            let model = model_nm.get(own_j).copied().unwrap_or(f32::NAN);
            if !super::within(model, cfg.state_limits.max_abs_tau_nm) {
                faults |= FaultFlags::MODEL_INVALID;
                self.ff_blend_ticks = 0;
            } else {
                target = model;
                source = FeedforwardSource::Model;
                if L::PRESENT {
                    target = self.lstm_stage(&mut input, model_nm, &mut faults, &mut source);
                }
                // Blend the whole feedforward in after a fallback to zero.
                let w = self.ff_blend_ticks as f32 / cfg.warmup_ticks as f32;
                if self.ff_blend_ticks < cfg.warmup_ticks {
                    self.ff_blend_ticks += 1;
                    faults |= FaultFlags::FF_WARMUP;
                    target *= w;
                }
            }
        } else {
            self.ff_blend_ticks = 0;
        }
        self.inputs_were_ok = inputs_ok;

        // Magnitude, then rate limit; the last output is always finite.
        let max = cfg.max_torque_nm;
        if target.abs() > max {
            faults |= FaultFlags::FF_MAGNITUDE_LIMITED;
            target = super::clamp_abs(target, max);
        }
        let step = cfg.max_torque_rate_nm_s * self.dt_s;
        let delta = target - self.torque_nm;
        let torque = if delta.abs() > step {
            faults |= FaultFlags::FF_RATE_LIMITED;
            self.torque_nm + super::clamp_abs(delta, step)
        } else {
            target
        };
        self.torque_nm = if torque.is_finite() {
            super::clamp_abs(torque, max)
        } else {
            0.0
        };
        let mut current_a = self.torque_nm / cfg.drive_gain_nm_per_a;
        if current_a.abs() > cfg.max_current_a {
            faults |= FaultFlags::FF_MAGNITUDE_LIMITED;
        }
        current_a = super::clamp_abs(current_a, cfg.max_current_a);
        self.latched |= faults;
        CompensatorOutput {
            torque_nm: self.torque_nm,
            current_a,
            source,
            faults,
        }
    }

    /// The LSTM stage: the model's torque corrected by the LSTM, or the model alone
    /// when the LSTM is off, invalid or implausible.
    fn lstm_stage(
        &mut self,
        input: &mut PredictorInput<J>,
        model_nm: [f32; J],
        faults: &mut FaultFlags,
        source: &mut FeedforwardSource,
    ) -> f32 {
        let cfg = self.config;
        let model = model_nm.get(cfg.own_joint).copied().unwrap_or(f32::NAN);
        if self.lstm_off_ticks > 0 {
            self.lstm_off_ticks -= 1;
            if self.lstm_off_ticks == 0 {
                self.reset_lstm();
            }
            return model;
        }
        input.model_nm = model_nm;
        let lstm = self
            .lstm
            .predict_nm(input)
            .get(cfg.own_joint)
            .copied()
            .unwrap_or(f32::NAN);
        let rejected = if !super::within(lstm, cfg.state_limits.max_abs_tau_nm) {
            FaultFlags::LSTM_INVALID
        } else if !super::within(lstm - model, cfg.max_lstm_correction_nm) {
            FaultFlags::LSTM_IMPLAUSIBLE
        } else {
            FaultFlags::NONE
        };
        if !rejected.is_empty() {
            *faults |= rejected;
            self.lstm.reset();
            self.lstm_blend_ticks = 0;
            self.lstm_off_ticks = cfg.lstm_retry_ticks.max(1);
            return model;
        }
        *source = FeedforwardSource::ModelLstm;
        let w = self.lstm_blend_ticks as f32 / cfg.warmup_ticks as f32;
        if self.lstm_blend_ticks < cfg.warmup_ticks {
            self.lstm_blend_ticks += 1;
            *faults |= FaultFlags::FF_WARMUP;
            model + w * (lstm - model)
        } else {
            lstm
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Model: torque = 2 * own q_ref (or a forced value).
    struct TestModel {
        forced: Option<f32>,
    }
    impl TorquePredictor<3> for TestModel {
        fn predict_nm(&mut self, input: &PredictorInput<3>) -> [f32; 3] {
            let t = input.joints.map(|s| 2.0 * s.q_ref_rad);
            match self.forced {
                Some(x) => [x; 3],
                None => t,
            }
        }
        fn reset(&mut self) {}
    }
    /// LSTM: model + 1 N*m (or a forced value); counts resets.
    struct TestLstm {
        forced: Option<f32>,
        resets: u32,
    }
    impl TorquePredictor<3> for TestLstm {
        fn predict_nm(&mut self, input: &PredictorInput<3>) -> [f32; 3] {
            match self.forced {
                Some(x) => [x; 3],
                None => input.model_nm.map(|m| m + 1.0),
            }
        }
        fn reset(&mut self) {
            self.resets += 1;
        }
    }

    pub(crate) fn config() -> CompensatorConfig {
        CompensatorConfig {
            rate_hz: 1000.0,
            own_joint: 1,
            state_limits: StateLimits {
                max_abs_q_rad: 10.0,
                max_abs_qd_rad_s: 10.0,
                max_abs_qdd_rad_s2: 100.0,
                max_abs_tau_nm: 200.0,
            },
            watchdog_ticks: 5,
            max_message_age_us: 20_000,
            max_torque_nm: 50.0,
            max_torque_rate_nm_s: 10_000.0,
            max_lstm_correction_nm: 5.0,
            warmup_ticks: 10,
            lstm_retry_ticks: 20,
            drive_gain_nm_per_a: 10.0,
            max_current_a: 4.0,
        }
    }

    type Comp = Compensator<3, TestModel, TestLstm>;

    fn new() -> Comp {
        Compensator::new(
            config(),
            TestModel { forced: None },
            TestLstm {
                forced: None,
                resets: 0,
            },
        )
        .unwrap()
    }

    fn state(q: f32) -> JointState {
        JointState {
            q_ref_rad: q,
            ..Default::default()
        }
    }

    /// Sends fresh states of joints 0 and 2 and ticks once.
    fn tick(c: &mut Comp, k: u32, own_q: f32) -> CompensatorOutput {
        for j in [0u8, 2] {
            c.receive(&JointStateMessage {
                joint: j,
                sequence: k as u16,
                timestamp_us: k * 1000,
                state: state(0.5),
            });
        }
        c.tick(&state(own_q), k * 1000)
    }

    /// Ticks until the output settles at `want` from `source`; returns the tick reached.
    fn settle(c: &mut Comp, mut k: u32, want: f32, source: FeedforwardSource) -> u32 {
        for _ in 0..100 {
            k += 1;
            let o = tick(c, k, 3.0);
            if o.source == source && (o.torque_nm - want).abs() < 1e-5 && o.faults.is_empty() {
                return k;
            }
        }
        panic!("did not settle at {want} from {source:?}");
    }

    #[test]
    fn warms_up_then_model_plus_lstm() {
        let mut c = new();
        let o = tick(&mut c, 1, 3.0);
        assert!(o.faults.contains(FaultFlags::FF_WARMUP) && o.torque_nm == 0.0);
        let k = settle(&mut c, 1, 7.0, FeedforwardSource::ModelLstm);
        assert!(k > 5);
        let o = tick(&mut c, k + 1, 3.0);
        assert_eq!((o.current_a, o.source), (0.7, FeedforwardSource::ModelLstm));
    }

    #[test]
    fn stale_state_falls_back_to_zero_and_recovers() {
        let mut c = new();
        let mut k = settle(&mut c, 0, 7.0, FeedforwardSource::ModelLstm);
        // Joint 2 goes silent: the watchdog trips after 5 ticks.
        let mut tripped = 0;
        for i in 0..10 {
            k += 1;
            c.receive(&JointStateMessage {
                joint: 0,
                sequence: k as u16,
                timestamp_us: k * 1000,
                state: state(0.5),
            });
            let o = c.tick(&state(3.0), k * 1000);
            if o.faults.contains(FaultFlags::STATE_STALE) {
                assert_eq!((o.source, o.torque_nm), (FeedforwardSource::Zero, 0.0));
                tripped += 1;
            } else {
                assert!(i < 5);
            }
        }
        assert_eq!(tripped, 5);
        let resets = c.lstm_mut().resets;
        let o = tick(&mut c, k + 1, 3.0);
        assert!(
            o.faults.contains(FaultFlags::FF_WARMUP) && o.source == FeedforwardSource::ModelLstm
        );
        assert_eq!(
            c.lstm_mut().resets,
            resets + 1,
            "LSTM restarts after the gap"
        );
        settle(&mut c, k + 1, 7.0, FeedforwardSource::ModelLstm);
        assert!(c.latched_faults().contains(FaultFlags::STATE_STALE));
    }

    #[test]
    fn old_timestamp_is_stale() {
        let mut c = new();
        let k = settle(&mut c, 0, 7.0, FeedforwardSource::ModelLstm);
        // Messages keep coming, but their sender time lags 30 ms.
        let mut o = CompensatorOutput::default();
        for i in 0..3 {
            for j in [0u8, 2] {
                let m = JointStateMessage {
                    joint: j,
                    sequence: (k + 1 + i) as u16,
                    timestamp_us: 0,
                    state: state(0.5),
                };
                c.receive(&m);
            }
            o = c.tick(&state(3.0), 30_000 + k * 1000);
        }
        assert!(o.faults.contains(FaultFlags::STATE_STALE) && o.source == FeedforwardSource::Zero);
        settle(&mut c, 40, 7.0, FeedforwardSource::ModelLstm);
    }

    #[test]
    fn rejected_and_out_of_order_messages_keep_the_last_good_state() {
        let mut c = new();
        let k = settle(&mut c, 0, 7.0, FeedforwardSource::ModelLstm);
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 1e30] {
            let m = JointStateMessage {
                joint: 0,
                sequence: (k + 1) as u16,
                timestamp_us: k * 1000,
                state: state(bad),
            };
            assert_eq!(c.receive(&m), FaultFlags::STATE_REJECTED);
        }
        // A wrong joint index and this joint's own index are rejected too.
        let m = JointStateMessage {
            joint: 7,
            sequence: 1,
            timestamp_us: 0,
            state: state(0.0),
        };
        assert_eq!(c.receive(&m), FaultFlags::STATE_REJECTED);
        let m = JointStateMessage {
            joint: 1,
            sequence: 1,
            timestamp_us: 0,
            state: state(0.0),
        };
        assert_eq!(c.receive(&m), FaultFlags::STATE_REJECTED);
        // A replayed sequence number.
        let m = JointStateMessage {
            joint: 0,
            sequence: k as u16,
            timestamp_us: 0,
            state: state(0.0),
        };
        assert_eq!(c.receive(&m), FaultFlags::STATE_OUT_OF_ORDER);
        let o = tick(&mut c, k + 1, 3.0);
        assert!(
            o.faults
                .contains(FaultFlags::STATE_REJECTED | FaultFlags::STATE_OUT_OF_ORDER)
        );
        assert_eq!((o.source, o.torque_nm), (FeedforwardSource::ModelLstm, 7.0));
        settle(&mut c, k + 1, 7.0, FeedforwardSource::ModelLstm);
    }

    #[test]
    fn invalid_own_state_falls_back_to_zero_and_recovers() {
        let mut c = new();
        let k = settle(&mut c, 0, 7.0, FeedforwardSource::ModelLstm);
        let o = tick(&mut c, k + 1, f32::NAN);
        assert!(o.faults.contains(FaultFlags::OWN_STATE_INVALID));
        assert_eq!((o.source, o.torque_nm), (FeedforwardSource::Zero, 0.0));
        settle(&mut c, k + 1, 7.0, FeedforwardSource::ModelLstm);
    }

    #[test]
    fn invalid_model_falls_back_to_zero_and_recovers() {
        let mut c = new();
        let k = settle(&mut c, 0, 7.0, FeedforwardSource::ModelLstm);
        for bad in [f32::NAN, f32::INFINITY, -1e9] {
            c.model_mut().forced = Some(bad);
            let o = tick(&mut c, k + 1, 3.0);
            assert!(o.faults.contains(FaultFlags::MODEL_INVALID));
            assert_eq!((o.source, o.torque_nm), (FeedforwardSource::Zero, 0.0));
        }
        c.model_mut().forced = None;
        settle(&mut c, k + 5, 7.0, FeedforwardSource::ModelLstm);
    }

    #[test]
    fn invalid_or_implausible_lstm_falls_back_to_model_and_recovers() {
        for (bad, flag) in [
            (f32::NAN, FaultFlags::LSTM_INVALID),
            (f32::NEG_INFINITY, FaultFlags::LSTM_INVALID),
            (1e20, FaultFlags::LSTM_INVALID),
            (20.0, FaultFlags::LSTM_IMPLAUSIBLE),
        ] {
            let mut c = new();
            let k = settle(&mut c, 0, 7.0, FeedforwardSource::ModelLstm);
            c.lstm_mut().forced = Some(bad);
            let resets = c.lstm_mut().resets;
            let o = tick(&mut c, k + 1, 3.0);
            assert!(o.faults.contains(flag), "{:?}", o.faults);
            assert_eq!((o.source, o.torque_nm), (FeedforwardSource::Model, 6.0));
            assert_eq!(c.lstm_mut().resets, resets + 1);
            c.lstm_mut().forced = None;
            // Model only for the retry period, then the LSTM blends back in.
            for i in 0..19 {
                let o = tick(&mut c, k + 2 + i, 3.0);
                assert_eq!((o.source, o.torque_nm), (FeedforwardSource::Model, 6.0));
            }
            settle(&mut c, k + 21, 7.0, FeedforwardSource::ModelLstm);
        }
    }

    #[test]
    fn explicit_lstm_reset_blends_the_correction_in() {
        let mut c = new();
        let k = settle(&mut c, 0, 7.0, FeedforwardSource::ModelLstm);
        let resets = c.lstm_mut().resets;
        c.reset_lstm();
        assert_eq!(c.lstm_mut().resets, resets + 1);
        let mut last = 0.0;
        for i in 0..10 {
            let o = tick(&mut c, k + 1 + i, 3.0);
            assert!(o.faults.contains(FaultFlags::FF_WARMUP));
            let want = 6.0 + i as f32 / 10.0;
            assert!(
                (o.torque_nm - want).abs() < 1e-5,
                "{} vs {want}",
                o.torque_nm
            );
            assert!(o.torque_nm >= last);
            last = o.torque_nm;
        }
        settle(&mut c, k + 11, 7.0, FeedforwardSource::ModelLstm);
    }

    #[test]
    fn rate_and_magnitude_limits() {
        let mut cfg = config();
        cfg.max_torque_rate_nm_s = 1000.0; // 1 N*m per tick
        cfg.warmup_ticks = 1;
        let mut c: Comp = Compensator::new(
            cfg,
            TestModel {
                forced: Some(100.0),
            },
            TestLstm {
                forced: Some(101.0),
                resets: 0,
            },
        )
        .unwrap();
        let mut prev = 0.0;
        for k in 1..80 {
            let o = tick(&mut c, k, 3.0);
            assert!((o.torque_nm - prev).abs() <= 1.0 + 1e-4 && o.torque_nm <= 50.0);
            assert!(o.current_a <= 4.0);
            if k > 1 && o.torque_nm < 50.0 {
                assert!(o.faults.contains(FaultFlags::FF_RATE_LIMITED));
            }
            assert!(k == 1 || o.faults.contains(FaultFlags::FF_MAGNITUDE_LIMITED));
            prev = o.torque_nm;
        }
        assert_eq!(prev, 50.0);
    }

    #[test]
    fn bad_configs_are_refused() {
        let mut cfg = config();
        cfg.own_joint = 3;
        assert!(matches!(
            Comp::new(
                cfg,
                TestModel { forced: None },
                TestLstm {
                    forced: None,
                    resets: 0
                }
            ),
            Err(ConfigError::OwnJointOutOfRange)
        ));
        let mut cfg = config();
        cfg.drive_gain_nm_per_a = f32::NAN;
        assert!(matches!(
            Comp::new(
                cfg,
                TestModel { forced: None },
                TestLstm {
                    forced: None,
                    resets: 0
                }
            ),
            Err(ConfigError::NonPositive)
        ));
    }

    #[test]
    fn model_only_compensator() {
        let mut c: Compensator<3, TestModel, NoPredictor> =
            Compensator::new(config(), TestModel { forced: None }, NoPredictor).unwrap();
        let mut o = CompensatorOutput::default();
        for k in 1..30 {
            for j in [0u8, 2] {
                c.receive(&JointStateMessage {
                    joint: j,
                    sequence: k as u16,
                    timestamp_us: k * 1000,
                    state: state(0.5),
                });
            }
            o = c.tick(&state(3.0), k * 1000);
        }
        assert_eq!((o.source, o.torque_nm), (FeedforwardSource::Model, 6.0));
    }
}
