//! The torque feedforward compensator: per compensator tick, a torque prediction
//! from the identified dynamics model and (optionally) the LSTM behind the
//! [`TorquePredictor`] trait, with a fallback chain LSTM -> model only -> zero,
//! a watchdog on the other joints' states, rate and magnitude limits, and a
//! warm-up after every reset; optionally the online friction adaptation
//! ([`crate::adaptation`]) after both stages, and the do-no-harm monitor
//! ([`crate::monitor`]) after all of them. The result is a q-current held until
//! the next tick.

use super::faults::FaultFlags;
use super::message::{JointState, JointStateMessage, SEQUENCE_WINDOW, StateLimits};
use crate::adaptation::{self, ADAPTED_LEVELS, AdaptationConfig, FrictionAdaptation};
use crate::features::RestDirection;
use crate::monitor::{DoNoHarmMonitor, MonitorConfig};

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
    /// The training-envelope weight in [0, 1] its learned share had for joint
    /// `joint_index` at the last prediction (`crate::envelope`); 1 for predictors that
    /// learned nothing or carry no envelope.
    fn envelope_weight(&self, joint_index: usize) -> f32 {
        let _ = joint_index;
        1.0
    }
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

/// How the compensator compares a sender's timestamp with its local bus time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BusClock {
    /// One clock for the whole bus (EtherCAT distributed clocks): a timestamp must
    /// be within `max_message_age_us` of the local bus time.
    Synchronised,
    /// Free-running clocks (a UART bus): each sender's clock offset is learned when
    /// its stream (re)synchronises and then follows the measured offset by at most
    /// `max_rate_error_ppm` of the elapsed time; a timestamp must be within
    /// `max_message_age_us` of the local time minus that offset.
    FreeRunning {
        /// Largest rate difference between two joints' clocks, parts per million.
        max_rate_error_ppm: u32,
    },
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
    /// compensator ticks passed without a fresh message from it; also the ticks the
    /// feedforward stays at zero after a sequence or session conflict.
    pub watchdog_ticks: u16,
    /// Watchdog: a message whose sender timestamp is more than this far from the
    /// local bus time (either way, see `bus_clock`) is stale, microseconds.
    pub max_message_age_us: u32,
    /// How sender timestamps are compared with the local bus time.
    pub bus_clock: BusClock,
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
    /// The training-envelope weight of the learned share this tick, in [0, 1]
    /// (`crate::envelope`; 1 when the learned stage did not run).
    pub envelope_weight: f32,
    /// The do-no-harm monitor's gain on the compensation beyond the model this tick, in
    /// [0, 1] (`crate::monitor`; 1 when it is off or the model stage did not run).
    pub monitor_gain: f32,
}

/// What the compensator knows of one other joint's sender: its latest accepted
/// state and the freshness of its stream.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Peer {
    /// The latest accepted state.
    state: JointState,
    /// Session of the stream.
    session: u16,
    /// Sequence number of the latest accepted frame.
    sequence: u16,
    /// Sender's timestamp of the latest accepted frame, microseconds.
    timestamp_us: u32,
    /// True once a frame was accepted.
    received: bool,
    /// Compensator ticks since the latest accepted frame (saturating).
    ticks_since_rx: u16,
    /// Compensator ticks since the latest sequence or session conflict (saturating).
    ticks_since_conflict: u16,
    /// Free-running clocks: local bus time minus the sender's clock, microseconds.
    clock_offset_us: u32,
    /// Free-running clocks: the session `clock_offset_us` was learned for, if any.
    /// The offset is learned once per sender session and then only followed
    /// within the rate tolerance: a stream that restarts within the same session
    /// (after silence or an over-age frame) keeps it, so no delay or replay can
    /// be learned into it.
    clock_session: Option<u16>,
    /// A frame was accepted since the last tick.
    new_frame: bool,
}

impl Peer {
    const NEW: Self = Self {
        state: JointState {
            q_ref_rad: 0.0,
            qd_ref_rad_s: 0.0,
            qdd_ref_rad_s2: 0.0,
            q_meas_rad: 0.0,
            qd_meas_rad_s: 0.0,
            tau_meas_nm: 0.0,
        },
        session: 0,
        sequence: 0,
        timestamp_us: 0,
        received: false,
        ticks_since_rx: u16::MAX,
        ticks_since_conflict: u16::MAX,
        clock_offset_us: 0,
        clock_session: None,
        new_frame: false,
    };

    /// Take a frame whose fields passed the limits (see [`Compensator::receive`]).
    fn accept(&mut self, msg: &JointStateMessage, watchdog_ticks: u16) -> FaultFlags {
        let live = self.received && self.ticks_since_rx <= watchdog_ticks;
        let same_session = msg.session == self.session;
        let step = msg.sequence.wrapping_sub(self.sequence);
        let in_window = (1..=SEQUENCE_WINDOW).contains(&step);
        if live && same_session && !in_window {
            self.ticks_since_conflict = 0;
            return FaultFlags::STATE_OUT_OF_ORDER;
        }
        self.state = msg.state;
        self.session = msg.session;
        self.sequence = msg.sequence;
        self.timestamp_us = msg.timestamp_us;
        self.received = true;
        self.ticks_since_rx = 0;
        self.new_frame = true;
        if live && !same_session {
            self.ticks_since_conflict = 0;
            FaultFlags::STATE_OUT_OF_ORDER
        } else {
            FaultFlags::NONE
        }
    }

    /// True when the latest frame's timestamp is more than `max_age_us` from the
    /// bus time `now_us`: against the bus time itself (`Synchronised`), or against
    /// the sender's clock offset (`FreeRunning`: learned at the first frame of each
    /// sender session, then followed by at most `slew_us` per new frame that is
    /// within the bound, so neither silence nor an over-age frame moves it).
    fn too_old(&mut self, now_us: u32, clock: BusClock, slew_us: u32, max_age_us: u32) -> bool {
        let skew_us = now_us.wrapping_sub(self.timestamp_us);
        let new_frame = core::mem::replace(&mut self.new_frame, false);
        match clock {
            BusClock::Synchronised => (skew_us as i32).unsigned_abs() > max_age_us,
            BusClock::FreeRunning { .. } => {
                if self.clock_session != Some(self.session) {
                    self.clock_offset_us = skew_us;
                    self.clock_session = Some(self.session);
                }
                let e = skew_us.wrapping_sub(self.clock_offset_us) as i32;
                let too_old = e.unsigned_abs() > max_age_us;
                if new_frame && !too_old {
                    // Follow the sender's clock within the rate tolerance.
                    let slew = slew_us.min(e.unsigned_abs());
                    self.clock_offset_us = if e >= 0 {
                        self.clock_offset_us.wrapping_add(slew)
                    } else {
                        self.clock_offset_us.wrapping_sub(slew)
                    };
                }
                too_old
            }
        }
    }
}

/// The per-joint feedforward compensator for `J` modelled joints with a model stage
/// `M` and an LSTM stage `L` (use [`NoPredictor`] for model only).
pub struct Compensator<const J: usize, M, L> {
    config: CompensatorConfig,
    model: M,
    lstm: L,
    dt_s: f32,
    /// What is known of each modelled joint's sender (this joint's own slot holds
    /// only its state, written by `tick`).
    peers: [Peer; J],
    clock_slew_us: u32,
    unauthenticated_frames: u32,
    rx_faults: FaultFlags,
    latched: FaultFlags,
    torque_nm: f32,
    ff_blend_ticks: u16,
    lstm_blend_ticks: u16,
    lstm_off_ticks: u16,
    inputs_were_ok: bool,
    adaptation: FrictionAdaptation,
    monitor: DoNoHarmMonitor,
    rest: RestDirection,
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
            peers: [Peer::NEW; J],
            unauthenticated_frames: 0,
            clock_slew_us: match config.bus_clock {
                BusClock::Synchronised => 0,
                // Saturating float-to-int cast: ppm of one tick period, microseconds.
                BusClock::FreeRunning { max_rate_error_ppm } => {
                    (max_rate_error_ppm as f32 / config.rate_hz) as u32
                }
            },
            rx_faults: FaultFlags::NONE,
            latched: FaultFlags::NONE,
            torque_nm: 0.0,
            ff_blend_ticks: 0,
            lstm_blend_ticks: 0,
            lstm_off_ticks: 0,
            inputs_were_ok: false,
            adaptation: FrictionAdaptation::new(AdaptationConfig::OFF, config.rate_hz),
            monitor: DoNoHarmMonitor::new(MonitorConfig::OFF, config.rate_hz),
            rest: RestDirection::new(),
        })
    }

    /// The same compensator with the online friction adaptation
    /// ([`crate::adaptation`]) after its model and LSTM stages: it learns this joint's
    /// friction and offset drift from the torque measured since each tick
    /// (`tau_meas_nm` of the own state) at the compensator's rate.
    pub fn with_adaptation(mut self, config: AdaptationConfig) -> Self {
        self.adaptation = FrictionAdaptation::new(config, self.config.rate_hz);
        self
    }

    /// The same compensator with the do-no-harm monitor ([`crate::monitor`]) after all
    /// its stages: it scores the model alone against the full compensation on the torque
    /// measured since each tick and fades the compensation's gain where it does harm.
    pub fn with_monitor(mut self, config: MonitorConfig) -> Self {
        self.monitor = DoNoHarmMonitor::new(config, self.config.rate_hz);
        self
    }

    /// The do-no-harm monitor (its gain and scores).
    pub fn monitor(&self) -> &DoNoHarmMonitor {
        &self.monitor
    }

    /// The adaptation's learned levels (N*m): offset, Coulomb, held at rest (zero when
    /// it is off).
    pub fn adapted_levels_nm(&self) -> [f32; ADAPTED_LEVELS] {
        self.adaptation.levels_nm()
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
    /// between ticks). A state with a bad field or joint index is dropped
    /// (`STATE_REJECTED`). Within a live stream (a state accepted within the last
    /// `watchdog_ticks` ticks) a frame of the same session must advance the sequence
    /// number by 1..=[`SEQUENCE_WINDOW`], else it is dropped; a frame of another
    /// session (the sender rebooted) restarts the stream. Either is a conflict
    /// (`STATE_OUT_OF_ORDER`): the feedforward is zero for the next
    /// `watchdog_ticks` ticks. A stream that is not live accepts the next valid
    /// frame whatever its session and sequence number.
    pub fn receive(&mut self, msg: &JointStateMessage) -> FaultFlags {
        self.receive_at(msg, None)
    }

    /// [`Compensator::receive`] at the local bus time `now_us` (`Synchronised` bus
    /// clock): a frame whose timestamp is already more than `max_message_age_us`
    /// from it is dropped (`STATE_REJECTED`) before it can restart or conflict
    /// with its sender's live stream, so a replayed old frame cannot even pause the
    /// feedforward. With a free-running clock (or no bus time) the same as `receive`.
    pub fn receive_at(&mut self, msg: &JointStateMessage, now_us: Option<u32>) -> FaultFlags {
        let j = msg.joint as usize;
        let cfg = self.config;
        let over_age = match (cfg.bus_clock, now_us) {
            (BusClock::Synchronised, Some(now)) => {
                (now.wrapping_sub(msg.timestamp_us) as i32).unsigned_abs() > cfg.max_message_age_us
            }
            _ => false,
        };
        let f = match self.peers.get_mut(j) {
            Some(p) if j != cfg.own_joint && cfg.state_limits.accepts(&msg.state) => {
                if over_age {
                    FaultFlags::STATE_REJECTED
                } else {
                    p.accept(msg, cfg.watchdog_ticks)
                }
            }
            // A bad field, this joint's own index or one beyond the modelled joints.
            _ => FaultFlags::STATE_REJECTED,
        };
        self.rx_faults |= f;
        f
    }

    /// Count a frame that failed its authentication (or was malformed) on the
    /// bus: it is never used, and the next tick reports `FRAME_UNAUTHENTICATED`.
    pub fn reject_frame(&mut self) -> FaultFlags {
        self.unauthenticated_frames = self.unauthenticated_frames.saturating_add(1);
        self.rx_faults |= FaultFlags::FRAME_UNAUTHENTICATED;
        FaultFlags::FRAME_UNAUTHENTICATED
    }

    /// Frames that failed authentication since start (saturating).
    pub fn unauthenticated_frames(&self) -> u32 {
        self.unauthenticated_frames
    }

    /// One compensator tick: this joint's own state and the local bus time ->
    /// the limited feedforward torque and q current. On the target it runs from CCM
    /// SRAM (`.ccmram_text`).
    #[cfg_attr(target_os = "none", unsafe(link_section = ".ccmram_text"))]
    pub fn tick(&mut self, own: &JointState, now_us: u32) -> CompensatorOutput {
        self.tick_at(own, Some(now_us))
    }

    /// One compensator tick while this node follows no bus time (no SYNC heard within
    /// its bound): no frame's age is known, so every other joint is stale and the
    /// feedforward falls back to zero (`STATE_STALE`).
    #[cfg_attr(target_os = "none", unsafe(link_section = ".ccmram_text"))]
    pub fn tick_without_bus_time(&mut self, own: &JointState) -> CompensatorOutput {
        self.tick_at(own, None)
    }

    #[inline(always)]
    fn tick_at(&mut self, own: &JointState, now_us: Option<u32>) -> CompensatorOutput {
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
        for (j, p) in self.peers.iter_mut().enumerate() {
            let age = p.ticks_since_rx;
            p.ticks_since_rx = age.saturating_add(1);
            let since_conflict = p.ticks_since_conflict;
            p.ticks_since_conflict = since_conflict.saturating_add(1);
            if j == own_j {
                continue;
            }
            if since_conflict < cfg.watchdog_ticks {
                faults |= FaultFlags::STATE_OUT_OF_ORDER;
                inputs_ok = false;
            }
            let too_old = match now_us {
                Some(now) => {
                    p.received
                        && p.too_old(
                            now,
                            cfg.bus_clock,
                            self.clock_slew_us,
                            cfg.max_message_age_us,
                        )
                }
                // No bus time: no frame's age is known.
                None => true,
            };
            if too_old {
                // The stream restarts: the next valid frame resynchronises it.
                p.ticks_since_rx = u16::MAX;
            }
            let silent = !p.received || age > cfg.watchdog_ticks;
            if silent {
                faults |= FaultFlags::SENDER_SILENT;
            }
            if silent || too_old {
                faults |= FaultFlags::STATE_STALE;
                inputs_ok = false;
            }
        }

        let mut target = 0.0f32;
        let mut source = FeedforwardSource::Zero;
        let mut envelope_weight = 1.0f32;
        let mut monitor_gain = 1.0f32;
        if inputs_ok {
            if !self.inputs_were_ok {
                // The input stream was broken: restart the LSTM's state and blend
                // the feedforward in from zero.
                self.lstm.reset();
                self.lstm_blend_ticks = 0;
                self.ff_blend_ticks = 0;
            }
            if let Some(slot) = self.peers.get_mut(own_j) {
                slot.state = *own;
            }
            let mut input = PredictorInput {
                joints: self.peers.map(|p| p.state),
                own_joint: own_j,
                model_nm: [0.0; J],
            };
            let model_nm = self.model.predict_nm(&input);
            // (own_joint < J is checked by `new`; a miss would read as invalid.)
            let model = model_nm.get(own_j).copied().unwrap_or(f32::NAN);
            if !super::within(model, cfg.state_limits.max_abs_tau_nm) {
                faults |= FaultFlags::MODEL_INVALID;
                self.ff_blend_ticks = 0;
                self.adaptation.restart();
                self.monitor.restart();
            } else {
                target = model;
                source = FeedforwardSource::Model;
                if L::PRESENT {
                    target = self.lstm_stage(&mut input, model_nm, &mut faults, &mut source);
                    if source == FeedforwardSource::ModelLstm {
                        envelope_weight = self.lstm.envelope_weight(own_j);
                        if envelope_weight < 1.0 {
                            faults |= FaultFlags::ENVELOPE_OUTSIDE;
                        }
                    }
                }
                // The adaptation learns from the torque measured since the last tick
                // and corrects this one (a no-op when off).
                let qd = own.qd_ref_rad_s;
                let x = adaptation::regressors(qd, self.rest.update(qd));
                target += self.adaptation.step(x, target, own.tau_meas_nm);
                // The monitor scores the model alone and the full compensation on the
                // same measured torque and scales what lies beyond the model.
                target = self.monitor.step(model, target, own.tau_meas_nm);
                monitor_gain = self.monitor.gain();
                if monitor_gain < 1.0 {
                    faults |= FaultFlags::COMPENSATION_FADED;
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
            self.adaptation.restart();
            self.monitor.restart();
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
            envelope_weight,
            monitor_gain,
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

    /// Model: torque = 2 * own q_ref + `coupling` * the others' q_ref (or a forced
    /// value); keeps the states it was last given.
    struct TestModel {
        forced: Option<f32>,
        coupling: f32,
        seen: [JointState; 3],
    }
    impl TestModel {
        fn new(forced: Option<f32>) -> Self {
            Self {
                forced,
                coupling: 0.0,
                seen: [JointState::default(); 3],
            }
        }
    }
    impl TorquePredictor<3> for TestModel {
        fn predict_nm(&mut self, input: &PredictorInput<3>) -> [f32; 3] {
            self.seen = input.joints;
            let sum: f32 = input.joints.iter().map(|s| s.q_ref_rad).sum();
            let t = input
                .joints
                .map(|s| 2.0 * s.q_ref_rad + self.coupling * (sum - s.q_ref_rad));
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
            bus_clock: BusClock::Synchronised,
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
        with_config(config()).unwrap()
    }

    /// The test stages (a model without a forced value, an LSTM without) under `cfg`.
    fn with_config(cfg: CompensatorConfig) -> Result<Comp, ConfigError> {
        Compensator::new(
            cfg,
            TestModel::new(None),
            TestLstm {
                forced: None,
                resets: 0,
            },
        )
    }

    fn state(q: f32) -> JointState {
        JointState {
            q_ref_rad: q,
            ..Default::default()
        }
    }

    /// Sends fresh states of joints 0 and 2 and ticks once.
    fn tick(c: &mut Comp, k: u32, own_q: f32) -> CompensatorOutput {
        tick_own(c, k, &state(own_q))
    }

    /// [`tick`] with the whole own state, for a compensator of any stages.
    fn tick_own<M: TorquePredictor<3>, L: TorquePredictor<3>>(
        c: &mut Compensator<3, M, L>,
        k: u32,
        own: &JointState,
    ) -> CompensatorOutput {
        for j in [0u8, 2] {
            c.receive(&JointStateMessage {
                joint: j,
                session: 0,
                sequence: k as u16,
                timestamp_us: k * 1000,
                state: state(0.5),
            });
        }
        c.tick(own, k * 1000)
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

    /// LSTM: model + 1 N*m, reporting a fixed envelope weight.
    struct WeightedLstm(f32);
    impl TorquePredictor<3> for WeightedLstm {
        fn predict_nm(&mut self, input: &PredictorInput<3>) -> [f32; 3] {
            input.model_nm.map(|m| m + 1.0)
        }
        fn reset(&mut self) {}
        fn envelope_weight(&self, _joint_index: usize) -> f32 {
            self.0
        }
    }

    #[test]
    fn the_envelope_weight_is_reported_and_flagged_below_one() {
        for (weight, flagged) in [(1.0f32, false), (0.25, true), (0.0, true)] {
            let mut c =
                Compensator::new(config(), TestModel::new(None), WeightedLstm(weight)).unwrap();
            let mut o = CompensatorOutput::default();
            for k in 1..40u32 {
                o = tick_own(&mut c, k, &state(3.0));
            }
            assert_eq!(o.source, FeedforwardSource::ModelLstm);
            assert_eq!(o.envelope_weight, weight);
            assert_eq!(
                o.faults.contains(FaultFlags::ENVELOPE_OUTSIDE),
                flagged,
                "{o:?}"
            );
        }
        // A model-only compensator reports 1 and never the flag.
        let mut c = Compensator::new(config(), TestModel::new(None), NoPredictor).unwrap();
        let o = c.tick(&state(3.0), 0);
        assert_eq!(o.envelope_weight, 1.0);
        assert!(!o.faults.contains(FaultFlags::ENVELOPE_OUTSIDE));
    }

    #[test]
    fn the_monitor_fades_a_harmful_lstm_and_flags_it() {
        // Model 2 q = 6 N*m at q = 3, the LSTM adds 1 N*m; the joint measures 5 N*m:
        // the LSTM's correction is harmful and the monitor fades it to the model.
        let cfg = MonitorConfig {
            window_s: 0.05,
            fade_s: 0.02,
            hysteresis: 0.05,
        };
        let mut c = new().with_monitor(cfg);
        let own = JointState {
            q_ref_rad: 3.0,
            tau_meas_nm: 5.0,
            ..Default::default()
        };
        let first = tick_own(&mut c, 1, &own);
        assert_eq!(first.monitor_gain, 1.0);
        let mut last = first;
        for k in 2..400 {
            last = tick_own(&mut c, k, &own);
        }
        assert_eq!(last.monitor_gain, 0.0, "{last:?}");
        assert!(last.faults.contains(FaultFlags::COMPENSATION_FADED));
        assert!((last.torque_nm - 6.0).abs() < 1e-5, "{last:?}");
        // Measured 7 N*m: the correction helps again and returns in full.
        let good = JointState {
            tau_meas_nm: 7.0,
            ..own
        };
        for k in 400..800 {
            last = tick_own(&mut c, k, &good);
        }
        assert_eq!(last.monitor_gain, 1.0, "{last:?}");
        assert!(!last.faults.contains(FaultFlags::COMPENSATION_FADED));
        assert!((last.torque_nm - 7.0).abs() < 1e-5, "{last:?}");
        // Off (the default): gain 1 whatever is measured.
        let mut off = new();
        for k in 1..100 {
            last = tick_own(&mut off, k, &own);
        }
        assert_eq!(last.monitor_gain, 1.0);
        assert!((last.torque_nm - 7.0).abs() < 1e-5, "{last:?}");
    }

    #[test]
    fn the_adaptation_learns_the_offset_the_stages_miss_and_stops_on_bad_input() {
        // Model + LSTM give 2 q + 2 + 1 = 7 N*m at q = 3 (others at 0.5: coupling 0);
        // the joint measures 8.5 N*m: 1.5 N*m of offset the stages do not know.
        let cfg = AdaptationConfig {
            time_constant_s: 0.2,
            max_correction_nm: 1.0,
        };
        let mut c = new().with_adaptation(cfg);
        let own = JointState {
            q_ref_rad: 3.0,
            tau_meas_nm: 8.5,
            ..Default::default()
        };
        let mut last = CompensatorOutput::default();
        for k in 1..2000 {
            last = tick_own(&mut c, k, &own);
        }
        // Learned up to its limit of 1 N*m, and no further.
        assert!((last.torque_nm - 8.0).abs() < 1e-3, "{last:?}");
        assert!((c.adapted_levels_nm()[0] - 1.0).abs() < 1e-3);
        // A non-finite measured torque is refused with the state: zero, nothing learned.
        let levels = c.adapted_levels_nm();
        let bad = JointState {
            tau_meas_nm: f32::NAN,
            ..own
        };
        let o = c.tick(&bad, 2000 * 1000);
        assert_eq!((o.source, o.torque_nm), (FeedforwardSource::Zero, 0.0));
        assert_eq!(c.adapted_levels_nm(), levels);
        // Off: the stages alone.
        let mut off = new().with_adaptation(AdaptationConfig::OFF);
        let k = settle(&mut off, 0, 7.0, FeedforwardSource::ModelLstm);
        assert!(k > 5 && off.adapted_levels_nm() == [0.0; ADAPTED_LEVELS]);
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
                session: 0,
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
                    session: 0,
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
                session: 0,
                sequence: (k + 1) as u16,
                timestamp_us: k * 1000,
                state: state(bad),
            };
            assert_eq!(c.receive(&m), FaultFlags::STATE_REJECTED);
        }
        // A wrong joint index and this joint's own index are rejected too.
        let m = JointStateMessage {
            joint: 7,
            session: 0,
            sequence: 1,
            timestamp_us: 0,
            state: state(0.0),
        };
        assert_eq!(c.receive(&m), FaultFlags::STATE_REJECTED);
        let m = JointStateMessage {
            joint: 1,
            session: 0,
            sequence: 1,
            timestamp_us: 0,
            state: state(0.0),
        };
        assert_eq!(c.receive(&m), FaultFlags::STATE_REJECTED);
        let o = tick(&mut c, k + 1, 3.0);
        assert!(o.faults.contains(FaultFlags::STATE_REJECTED));
        assert_eq!((o.source, o.torque_nm), (FeedforwardSource::ModelLstm, 7.0));
        assert_eq!(c.model_mut().seen[0], state(0.5), "the last good state");
        // A replayed sequence number: dropped, and a conflict (feedforward zero).
        let m = JointStateMessage {
            joint: 0,
            session: 0,
            sequence: (k + 1) as u16,
            timestamp_us: 0,
            state: state(0.0),
        };
        assert_eq!(c.receive(&m), FaultFlags::STATE_OUT_OF_ORDER);
        let o = tick(&mut c, k + 2, 3.0);
        assert!(o.faults.contains(FaultFlags::STATE_OUT_OF_ORDER));
        assert_eq!((o.source, o.torque_nm), (FeedforwardSource::Zero, 0.0));
        settle(&mut c, k + 2, 7.0, FeedforwardSource::ModelLstm);
        assert_eq!(c.model_mut().seen[0], state(0.5));
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
        for (i, bad) in [f32::NAN, f32::INFINITY, -1e9].into_iter().enumerate() {
            c.model_mut().forced = Some(bad);
            let o = tick(&mut c, k + 1 + i as u32, 3.0);
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
            TestModel::new(Some(100.0)),
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
            with_config(cfg),
            Err(ConfigError::OwnJointOutOfRange)
        ));
        let mut cfg = config();
        cfg.drive_gain_nm_per_a = f32::NAN;
        assert!(matches!(with_config(cfg), Err(ConfigError::NonPositive)));
        // Zero is not positive; infinity is not finite; zero tick counts are refused.
        for bad in [
            |c: &mut CompensatorConfig| c.rate_hz = 0.0,
            |c: &mut CompensatorConfig| c.max_torque_nm = f32::INFINITY,
            |c: &mut CompensatorConfig| c.warmup_ticks = 0,
            |c: &mut CompensatorConfig| c.watchdog_ticks = 0,
        ] {
            let mut cfg = config();
            bad(&mut cfg);
            assert!(matches!(with_config(cfg), Err(ConfigError::NonPositive)));
        }
    }

    #[test]
    fn warmup_blends_model_and_lstm_for_exactly_warmup_ticks() {
        let mut c = new();
        // An LSTM correction of 2 N*m (not 1, so that w * c and w / c differ).
        c.lstm_mut().forced = Some(8.0);
        let n = config().warmup_ticks;
        for k in 0..n + 5 {
            let o = tick(&mut c, u32::from(k) + 1, 3.0);
            // Model 6 N*m; the LSTM's share and the whole feedforward both ramp in.
            let w = (k.min(n) as f32) / n as f32;
            let want = (6.0 + w * (8.0 - 6.0)) * w;
            assert!(
                (o.torque_nm - want).abs() < 1e-5,
                "tick {k}: {o:?}, want {want}"
            );
            assert_eq!(o.faults.contains(FaultFlags::FF_WARMUP), k < n, "tick {k}");
        }
        assert_eq!(c.torque_nm(), 8.0);
    }

    #[test]
    fn limits_flag_only_what_exceeds_them() {
        // Exactly the torque limit (the current well within its own): not limited.
        let mut cfg = config();
        cfg.max_current_a = 10.0;
        let mut c = with_config(cfg).unwrap();
        c.lstm_mut().forced = Some(cfg.max_torque_nm);
        c.model_mut().forced = Some(cfg.max_torque_nm - 1.0);
        settle(&mut c, 0, 50.0, FeedforwardSource::ModelLstm);
        // Exactly the 4 A current limit (40 N*m at 10 N*m/A): not limited either.
        let mut c = new();
        c.lstm_mut().forced = Some(40.0);
        c.model_mut().forced = Some(39.0);
        let k = settle(&mut c, 0, 40.0, FeedforwardSource::ModelLstm);
        assert_eq!(tick(&mut c, k + 1, 3.0).current_a, 4.0);
        // 45 N*m is within the torque limit, but 4.5 A is above the 4 A current limit.
        let mut c = new();
        c.lstm_mut().forced = Some(45.0);
        c.model_mut().forced = Some(44.0);
        let mut o = CompensatorOutput::default();
        for k in 1..40 {
            o = tick(&mut c, k, 3.0);
        }
        assert_eq!((o.torque_nm, o.current_a), (45.0, 4.0));
        assert_eq!(o.faults, FaultFlags::FF_MAGNITUDE_LIMITED, "{o:?}");
    }

    #[test]
    fn latched_faults_are_kept_until_cleared() {
        let mut c = new();
        c.tick(&state(3.0), 0);
        assert!(c.latched_faults().contains(FaultFlags::STATE_STALE));
        c.clear_latched();
        assert_eq!(c.latched_faults(), FaultFlags::NONE);
    }

    #[test]
    fn model_only_compensator() {
        let mut c: Compensator<3, TestModel, NoPredictor> =
            Compensator::new(config(), TestModel::new(None), NoPredictor).unwrap();
        let mut o = CompensatorOutput::default();
        for k in 1..30 {
            o = tick_own(&mut c, k, &state(3.0));
        }
        assert_eq!((o.source, o.torque_nm), (FeedforwardSource::Model, 6.0));
    }

    fn msg(joint: u8, session: u16, sequence: u16, timestamp_us: u32, q: f32) -> JointStateMessage {
        JointStateMessage {
            joint,
            session,
            sequence,
            timestamp_us,
            state: state(q),
        }
    }

    /// Ticks `n` times with joints 0 and 2 sending (session 0, sequence `k`) and a
    /// forged frame before each tick from `forge(k)`; returns the outputs.
    fn run_with(
        c: &mut Comp,
        k0: u32,
        n: u32,
        mut forge: impl FnMut(u32) -> Option<JointStateMessage>,
    ) -> std::vec::Vec<CompensatorOutput> {
        (k0 + 1..=k0 + n)
            .map(|k| {
                if let Some(m) = forge(k) {
                    c.receive(&m);
                }
                tick(c, k, 3.0)
            })
            .collect()
    }

    #[test]
    fn a_far_ahead_forged_sequence_is_dropped_and_does_not_silence_the_sender() {
        let mut c = new();
        let k = settle(&mut c, 0, 7.0, FeedforwardSource::ModelLstm);
        let forged = msg(0, 0, (k as u16).wrapping_add(32_767), k * 1000, 5.0);
        assert_eq!(c.receive(&forged), FaultFlags::STATE_OUT_OF_ORDER);
        // The real sender's next frame is accepted; the forged state was never used.
        assert_eq!(
            c.receive(&msg(0, 0, k as u16 + 1, k * 1000, 0.5)),
            FaultFlags::NONE
        );
        let out = run_with(&mut c, k, 5, |_| None);
        assert!(out.iter().all(|o| o.source == FeedforwardSource::Zero));
        assert_eq!(c.model_mut().seen[0].q_ref_rad, 0.5);
        settle(&mut c, k + 5, 7.0, FeedforwardSource::ModelLstm);
    }

    #[test]
    fn an_in_window_forged_frame_silences_the_sender_for_at_most_the_watchdog() {
        let mut c = new();
        c.model_mut().coupling = 1.0; // joints 0 and 2 at 0.5: 2 * 3 + 1 (+1 LSTM)
        let k = settle(&mut c, 0, 8.0, FeedforwardSource::ModelLstm);
        let w = config().watchdog_ticks as u32;
        // One forged frame 60 sequence numbers ahead (within the window): accepted.
        let forged = msg(0, 0, k as u16 + 60, k * 1000, 2.5);
        assert_eq!(c.receive(&forged), FaultFlags::NONE);
        let mut accepted_at = None;
        let mut zero_ticks = 0;
        for i in 1..=40 {
            let f = c.receive(&msg(0, 0, (k + i) as u16, (k + i) * 1000, 0.5));
            if f.is_empty() && accepted_at.is_none() {
                accepted_at = Some(i);
            }
            c.receive(&msg(2, 0, (k + i) as u16, (k + i) * 1000, 0.5));
            let o = c.tick(&state(3.0), (k + i) * 1000);
            zero_ticks += u32::from(o.source == FeedforwardSource::Zero);
            if i > 1 && o.source != FeedforwardSource::Zero {
                // Once the feedforward is back, it comes from the real state.
                assert_eq!(c.model_mut().seen[0].q_ref_rad, 0.5, "tick {i}");
            }
        }
        // At most w + 1 of the real sender's frames are dropped.
        let accepted_at = accepted_at.expect("the real sender is resynchronised");
        assert!(accepted_at <= w + 2, "accepted at its frame {accepted_at}");
        assert!(zero_ticks <= 2 * w + 1, "zero for {zero_ticks} ticks");
        assert!(zero_ticks >= 1, "the conflict is acted upon");
        assert!(c.latched_faults().contains(FaultFlags::STATE_OUT_OF_ORDER));
        settle(&mut c, k + 40, 8.0, FeedforwardSource::ModelLstm);
    }

    #[test]
    fn a_rebooted_sender_is_resynchronised() {
        let mut c = new();
        let mut k = settle(&mut c, 0, 7.0, FeedforwardSource::ModelLstm);
        // Sender 0 far into its sequence (40 000), then it reboots with a new session
        // and starts again at 1: accepted at once, the stream restarts.
        for i in 1..=3u32 {
            k += 1;
            c.receive(&msg(0, 7, 40_000 + i as u16, k * 1000, 0.5));
            c.receive(&msg(2, 0, k as u16, k * 1000, 0.5));
            c.tick(&state(3.0), k * 1000);
        }
        let f = c.receive(&msg(0, 8, 1, k * 1000, 1.5));
        assert_eq!(
            f,
            FaultFlags::STATE_OUT_OF_ORDER,
            "a session change is reported"
        );
        for seq in 2..=40u16 {
            k += 1;
            assert_eq!(c.receive(&msg(0, 8, seq, k * 1000, 1.5)), FaultFlags::NONE);
            c.receive(&msg(2, 0, k as u16, k * 1000, 0.5));
            c.tick(&state(3.0), k * 1000);
        }
        assert_eq!(c.model_mut().seen[0].q_ref_rad, 1.5);
        // The same, but the sender comes back with its old session: its frames are
        // dropped while the old stream is live, accepted once it is stale.
        let w = config().watchdog_ticks as u32;
        let mut accepted_at = None;
        for i in 1..=20u32 {
            k += 1;
            let f = c.receive(&msg(0, 8, i as u16, k * 1000, 0.5));
            if f.is_empty() && accepted_at.is_none() {
                accepted_at = Some(i);
            }
            c.receive(&msg(2, 0, k as u16, k * 1000, 0.5));
            c.tick(&state(3.0), k * 1000);
        }
        assert!(accepted_at.is_some_and(|i| i <= w + 1), "{accepted_at:?}");
        settle(&mut c, k, 7.0, FeedforwardSource::ModelLstm);
    }

    #[test]
    fn a_persistent_spoofer_holds_the_feedforward_at_zero() {
        // The spoofed state would drive this joint's feedforward to its limit.
        for alternate_sessions in [false, true] {
            let mut c = new();
            c.model_mut().coupling = 30.0; // 2 * 3 + 30 * (0.5 + 0.5) + 1
            let k = settle(&mut c, 0, 37.0, FeedforwardSource::ModelLstm);
            let out = run_with(&mut c, k, 300, |i| {
                let (session, seq) = if alternate_sessions {
                    (99, i as u16)
                } else {
                    (0, i as u16 + 1) // one ahead of the real sender
                };
                Some(msg(0, session, seq, i * 1000, 1.5)) // 2 * 3 + 30 * 2 + 1 > 50
            });
            // Zero from the first conflict on (rate-limited on the way down).
            let mut last = 37.0;
            for (i, o) in out.iter().enumerate() {
                assert!(
                    o.faults.contains(FaultFlags::STATE_OUT_OF_ORDER),
                    "{i}: {o:?}"
                );
                assert_eq!(o.source, FeedforwardSource::Zero, "{i}: {o:?}");
                assert!(o.torque_nm <= last && o.torque_nm >= 0.0, "{i}: {o:?}");
                last = o.torque_nm;
            }
            assert_eq!(last, 0.0);
            assert!(
                !c.latched_faults()
                    .contains(FaultFlags::FF_MAGNITUDE_LIMITED)
            );
        }
    }

    #[test]
    fn free_running_clocks_are_followed_and_delays_are_stale() {
        let mut cfg = config();
        cfg.bus_clock = BusClock::FreeRunning {
            max_rate_error_ppm: 20_000,
        };
        cfg.max_message_age_us = 3000;
        let mut c = with_config(cfg).unwrap();
        // Sender clocks: offset by about 1.2e9 us and 1 % fast / slow.
        let sender = |j: u8, k: u32| {
            let t = k as f64 * 1000.0 * if j == 0 { 1.01 } else { 0.99 };
            (1_234_567_890u64 + t as u64) as u32
        };
        let mut k = 0;
        for _ in 0..3000 {
            k += 1;
            for j in [0u8, 2] {
                c.receive(&msg(j, 0, k as u16, sender(j, k), 0.5));
            }
            let o = c.tick(&state(3.0), k * 1000);
            if k > 20 {
                assert_eq!((o.source, o.torque_nm), (FeedforwardSource::ModelLstm, 7.0));
            }
        }
        // Joint 2's frames now arrive 10 ms late (delayed or replayed): stale.
        let mut stale = 0;
        for _ in 0..10 {
            k += 1;
            c.receive(&msg(0, 0, k as u16, sender(0, k), 0.5));
            c.receive(&msg(2, 0, k as u16, sender(2, k - 10), 0.5));
            let o = c.tick(&state(3.0), k * 1000);
            stale += u32::from(o.faults.contains(FaultFlags::STATE_STALE));
        }
        assert!(stale >= 1, "the delay is seen");
        // The same clocks with a synchronised-bus configuration are all stale.
        let mut c = new();
        for k in 1..50 {
            for j in [0u8, 2] {
                c.receive(&msg(j, 0, k as u16, sender(j, k), 0.5));
            }
            let o = c.tick(&state(3.0), k * 1000);
            assert!(o.faults.contains(FaultFlags::STATE_STALE));
        }
    }

    #[test]
    fn the_tick_watchdog_trips_without_the_timestamp_check() {
        let mut cfg = config();
        cfg.max_message_age_us = u32::MAX / 2;
        let mut c = with_config(cfg).unwrap();
        let mut k = settle(&mut c, 0, 7.0, FeedforwardSource::ModelLstm);
        let w = cfg.watchdog_ticks as u32;
        for i in 1..=w + 3 {
            k += 1;
            c.receive(&msg(0, 0, k as u16, k * 1000, 0.5));
            let o = c.tick(&state(3.0), k * 1000);
            let stale = i > w;
            assert_eq!(
                o.faults.contains(FaultFlags::STATE_STALE),
                stale,
                "tick {i}"
            );
            assert_eq!(o.source == FeedforwardSource::Zero, stale, "tick {i}");
        }
    }
}
