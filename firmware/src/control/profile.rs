//! One joint's configuration: motor, gear, limits, gains and bus settings in one
//! [`JointProfile`], with the builders of the [`DriveConfig`] and
//! [`CompensatorConfig`] the control code takes.
//!
//! The exporter writes the profiles of a robot's compensated joints into the
//! generated model file (`JOINT_PROFILES`, from the robot description's
//! `[joint.profile]` tables, [`JointProfile::BOARD`] where a field is not given); the
//! board picks its own at start-up ([`super::startup`]); the closed-loop simulations
//! build their drives and compensators from the same profiles.

use super::cascade::CascadeConfig;
use super::compensator::{BusClock, CompensatorConfig};
use super::drive::DriveConfig;
use super::foc::{CurrentLoopConfig, MotorParameters};
use super::message::StateLimits;
use crate::adaptation::AdaptationConfig;
use crate::monitor::MonitorConfig;

/// Everything one joint's drive and compensator need beyond the compiled-in model
/// and the board's own constants (PWM rate, ADC scales).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointProfile {
    /// The joint's motor (current-loop gains follow from it, `CurrentLoopConfig::tuned`).
    pub motor: MotorParameters,
    /// Gear ratio: motor turns per joint turn.
    pub gear_ratio: f32,
    /// Gear efficiency in (0, 1]: joint torque = motor torque x ratio x efficiency.
    pub gear_efficiency: f32,
    /// Encoder reading (motor mechanical angle, rad) at electrical angle zero.
    pub encoder_offset_rad: f32,
    /// Position and velocity loops: rate, gains and limits.
    pub cascade: CascadeConfig,
    /// Limit of the q-current reference (outer loops + feedforward), A.
    pub max_current_a: f32,
    /// A phase current beyond this trips the bridge off for the tick, A.
    pub overcurrent_trip_a: f32,
    /// Lowest bus voltage of the operating range, V.
    pub bus_min_v: f32,
    /// Highest bus voltage of the operating range, V.
    pub bus_max_v: f32,
    /// Largest accepted |joint position reference|, rad.
    pub max_abs_q_ref_rad: f32,
    /// Bounds on the joint states the compensator accepts.
    pub state_limits: StateLimits,
    /// Compensator ticks without a fresh message before another joint is stale.
    pub watchdog_ticks: u16,
    /// Largest distance of a sender's timestamp from the local bus time, in
    /// compensator ticks (`max_message_age_us` at the model's control rate).
    pub max_message_age_ticks: u16,
    /// How sender timestamps are compared with the local bus time.
    pub bus_clock: BusClock,
    /// Magnitude limit of the torque feedforward, N*m (joint side).
    pub max_torque_nm: f32,
    /// Rate limit of the torque feedforward, N*m per second.
    pub max_torque_rate_nm_s: f32,
    /// Largest plausible LSTM correction |tau_lstm - tau_model|, N*m.
    pub max_lstm_correction_nm: f32,
    /// Ticks over which the feedforward is blended in after a reset.
    pub warmup_ticks: u16,
    /// Ticks the LSTM stays off after a rejection.
    pub lstm_retry_ticks: u16,
    /// Limit of the feedforward q current, A.
    pub feedforward_max_current_a: f32,
    /// State-bus line rate, baud (the board's UART; 8N1).
    pub bus_baud: u32,
    /// The online friction adaptation after the model and LSTM stages
    /// ([`crate::adaptation`]; a zero time constant turns it off).
    pub adaptation: AdaptationConfig,
    /// The online do-no-harm monitor after every other stage ([`crate::monitor`]; a
    /// zero window turns it off).
    pub monitor: MonitorConfig,
}

impl JointProfile {
    /// The joint-drive board's values: the wrist motor ([`MotorParameters::BOARD`]),
    /// a 100:1 gear, the cascade at 5 kHz, the state bus on the SYNC master's bus
    /// time (CAN-FD; a frame's age is bounded, [`super::canfd`]), 2 Mbaud where a
    /// board uses the UART, the friction adaptation off (+-10 N*m when a time constant
    /// turns it on). The default of every field a robot description leaves out.
    pub const BOARD: JointProfile = JointProfile {
        motor: MotorParameters::BOARD,
        gear_ratio: 100.0,
        gear_efficiency: 1.0,
        encoder_offset_rad: 0.0,
        cascade: CascadeConfig {
            rate_hz: 5000.0,
            position_kp: 40.0,
            position_ki: 0.0,
            position_kd: 0.0,
            max_velocity_rad_s: 4.0,
            velocity_kp: 12.0,
            velocity_ki: 400.0,
            velocity_kd: 0.0,
            max_current_a: 15.0,
            velocity_filter_alpha: 0.3,
        },
        max_current_a: 15.0,
        overcurrent_trip_a: 30.0,
        bus_min_v: 36.0,
        bus_max_v: 56.0,
        max_abs_q_ref_rad: 6.3,
        state_limits: StateLimits {
            max_abs_q_rad: 6.3,
            max_abs_qd_rad_s: 5.0,
            max_abs_qdd_rad_s2: 200.0,
            max_abs_tau_nm: 300.0,
        },
        watchdog_ticks: 3,
        // Each sender's clock followed within the oscillators' tolerance: the generic
        // board's UART carries no SYNC, so the board image asserts this mode. A CAN-FD
        // drive (the moteus image) selects one bus time for every node per joint
        // (`bus_clock = "synchronised"`: SYNC every tick, `canfd::BusTime`), where a
        // frame more than 3 ticks older than the local bus time is stale.
        max_message_age_ticks: 3,
        bus_clock: JointProfile::FREE_RUNNING,
        max_torque_nm: 120.0,
        max_torque_rate_nm_s: 2_000.0,
        max_lstm_correction_nm: 30.0,
        warmup_ticks: 10,
        lstm_retry_ticks: 50,
        feedforward_max_current_a: 12.0,
        bus_baud: 2_000_000,
        // Off: in the wrist SIL it raises the tracking error by a few per cent
        // (docs/studies/sil-paper-network.md); a robot description turns it on per joint.
        adaptation: AdaptationConfig {
            time_constant_s: 0.0,
            max_correction_nm: 10.0,
        },
        // Off unless a robot description gives a window; when on, a full fade takes
        // 0.5 s and the gain holds within 0.05 of the window's best blend.
        monitor: MonitorConfig::OFF,
    };

    /// The free-running bus clock (no SYNC): each sender's clock offset learned when
    /// its stream starts and followed within the two HSI16 oscillators' tolerance
    /// (+-1 % each). What it cannot catch: the board README, "Free-running mode".
    pub const FREE_RUNNING: BusClock = BusClock::FreeRunning {
        max_rate_error_ppm: 20_000,
    };

    /// The do-no-harm monitor of the deployed drive compensator: `export` writes it into
    /// the profile of every joint of a `drive` network whose description leaves the
    /// monitor off. The design rule: the window equals the friction adaptation's time
    /// constant as the study runs it (2 s: the horizon over which the drive already
    /// trusts what it measured; a shorter window would judge the adaptation's own
    /// transients, a longer one leaves harm in place longer than the adaptation takes
    /// to correct a drift), a full fade in a quarter of the window (0.5 s: several
    /// window-lengths of evidence are never needed to remove a harm, and the gain cannot
    /// step), hysteresis 0.05 (the gain's estimation noise over a 2 s window at the
    /// UR10e's 100 Hz, about 200 samples). Not fitted to any run's score.
    pub const DRIVE_MONITOR: MonitorConfig = MonitorConfig {
        window_s: 2.0,
        fade_s: 0.5,
        hysteresis: 0.05,
    };

    /// Joint-side torque per A of motor q current, N*m/A (motor torque constant x
    /// gear ratio x gear efficiency).
    pub const fn drive_gain_nm_per_a(&self) -> f32 {
        self.motor.torque_constant_nm_per_a() * self.gear_ratio * self.gear_efficiency
    }

    /// The drive's configuration with the PWM (current-loop) rate `pwm_hz`.
    pub const fn drive_config(&self, pwm_hz: f32) -> DriveConfig {
        DriveConfig {
            current: CurrentLoopConfig::tuned(self.motor, pwm_hz),
            cascade: self.cascade,
            gear_ratio: self.gear_ratio,
            encoder_offset_rad: self.encoder_offset_rad,
            max_current_a: self.max_current_a,
            overcurrent_trip_a: self.overcurrent_trip_a,
            bus_min_v: self.bus_min_v,
            bus_max_v: self.bus_max_v,
            max_abs_q_ref_rad: self.max_abs_q_ref_rad,
        }
    }

    /// The compensator's configuration at `rate_hz` ticks per second, for the joint at
    /// `own_joint` among the modelled joints (a zero rate gives a zero message age,
    /// which `Compensator::new` accepts but every message then fails).
    pub const fn compensator_config(&self, rate_hz: u32, own_joint: usize) -> CompensatorConfig {
        let tick_period_us = match 1_000_000u32.checked_div(rate_hz) {
            Some(p) => p,
            None => 0,
        };
        CompensatorConfig {
            rate_hz: rate_hz as f32,
            own_joint,
            state_limits: self.state_limits,
            watchdog_ticks: self.watchdog_ticks,
            max_message_age_us: (self.max_message_age_ticks as u32).saturating_mul(tick_period_us),
            bus_clock: self.bus_clock,
            max_torque_nm: self.max_torque_nm,
            max_torque_rate_nm_s: self.max_torque_rate_nm_s,
            max_lstm_correction_nm: self.max_lstm_correction_nm,
            warmup_ticks: self.warmup_ticks,
            lstm_retry_ticks: self.lstm_retry_ticks,
            drive_gain_nm_per_a: self.drive_gain_nm_per_a(),
            max_current_a: self.feedforward_max_current_a,
        }
    }

    /// The name (as in a robot description's `[joint.profile]` table) of the first
    /// field out of its range, or `None` when every field is usable: rates, limits,
    /// motor constants and the gear positive and finite, gains finite and not
    /// negative, the efficiency and the velocity filter in (0, 1], the bus range
    /// ordered, the trip above the current limit, tick counts at least 1.
    pub const fn invalid_field(&self) -> Option<&'static str> {
        const fn pos(x: f32) -> bool {
            x > 0.0 && x < f32::INFINITY
        }
        const fn gain(x: f32) -> bool {
            x >= 0.0 && x < f32::INFINITY
        }
        const fn unit(x: f32) -> bool {
            x > 0.0 && x <= 1.0
        }
        let m = &self.motor;
        let c = &self.cascade;
        let s = &self.state_limits;
        let a = &self.adaptation;
        let mo = &self.monitor;
        let checks: [(bool, &'static str); 40] = [
            (m.pole_pairs >= 1, "pole_pairs"),
            (pos(m.phase_resistance_ohm), "phase_resistance_ohm"),
            (pos(m.phase_inductance_h), "phase_inductance_h"),
            (pos(m.flux_linkage_wb), "flux_linkage_wb"),
            (pos(self.gear_ratio), "gear_ratio"),
            (unit(self.gear_efficiency), "gear_efficiency"),
            (
                self.encoder_offset_rad.abs() < f32::INFINITY,
                "encoder_offset_rad",
            ),
            (pos(c.rate_hz), "cascade_rate_hz"),
            (gain(c.position_kp), "position_kp"),
            (gain(c.position_ki), "position_ki"),
            (gain(c.position_kd), "position_kd"),
            (pos(c.max_velocity_rad_s), "max_velocity_rad_s"),
            (gain(c.velocity_kp), "velocity_kp"),
            (gain(c.velocity_ki), "velocity_ki"),
            (gain(c.velocity_kd), "velocity_kd"),
            (pos(c.max_current_a), "cascade_max_current_a"),
            (unit(c.velocity_filter_alpha), "velocity_filter_alpha"),
            (pos(self.max_current_a), "max_current_a"),
            (
                pos(self.overcurrent_trip_a) && self.overcurrent_trip_a > self.max_current_a,
                "overcurrent_trip_a",
            ),
            (pos(self.bus_min_v), "bus_min_v"),
            (
                pos(self.bus_max_v) && self.bus_max_v > self.bus_min_v,
                "bus_max_v",
            ),
            (pos(self.max_abs_q_ref_rad), "max_abs_q_ref_rad"),
            (pos(s.max_abs_q_rad), "max_abs_q_rad"),
            (pos(s.max_abs_qd_rad_s), "max_abs_qd_rad_s"),
            (pos(s.max_abs_qdd_rad_s2), "max_abs_qdd_rad_s2"),
            (pos(s.max_abs_tau_nm), "max_abs_tau_nm"),
            (self.watchdog_ticks >= 1, "watchdog_ticks"),
            (self.max_message_age_ticks >= 1, "max_message_age_ticks"),
            (
                match self.bus_clock {
                    BusClock::Synchronised => true,
                    BusClock::FreeRunning { max_rate_error_ppm } => max_rate_error_ppm < 1_000_000,
                },
                "max_rate_error_ppm",
            ),
            (pos(self.max_torque_nm), "max_torque_nm"),
            (pos(self.max_torque_rate_nm_s), "max_torque_rate_nm_s"),
            (pos(self.max_lstm_correction_nm), "max_lstm_correction_nm"),
            (self.warmup_ticks >= 1, "warmup_ticks"),
            (
                pos(self.feedforward_max_current_a),
                "feedforward_max_current_a",
            ),
            (self.bus_baud >= 1, "bus_baud"),
            (gain(a.time_constant_s), "adaptation_time_constant_s"),
            (gain(a.max_correction_nm), "max_adaptation_nm"),
            (gain(mo.window_s), "monitor_window_s"),
            (pos(mo.fade_s), "monitor_fade_s"),
            (
                mo.hysteresis >= 0.0 && mo.hysteresis < 1.0,
                "monitor_hysteresis",
            ),
        ];
        let mut k = 0;
        while k < checks.len() {
            if !checks[k].0 {
                return Some(checks[k].1);
            }
            k += 1;
        }
        None
    }
}

/// Whether every profile of `profiles` is usable ([`JointProfile::invalid_field`]);
/// the compiled-in models are checked with it at compile time.
pub const fn all_valid(profiles: &[JointProfile]) -> bool {
    let mut k = 0;
    while k < profiles.len() {
        if profiles[k].invalid_field().is_some() {
            return false;
        }
        k += 1;
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_board_profile_builds_the_boards_configurations() {
        let p = JointProfile::BOARD;
        assert_eq!(p.invalid_field(), None);
        let d = p.drive_config(20_000.0);
        assert_eq!(
            d.current,
            CurrentLoopConfig::tuned(MotorParameters::BOARD, 20_000.0)
        );
        assert_eq!(d.gear_ratio, 100.0);
        assert_eq!(d.cascade.velocity_kp, 12.0);
        assert_eq!(d.overcurrent_trip_a, 30.0);
        let c = p.compensator_config(100, 2);
        assert_eq!(c.own_joint, 2);
        assert_eq!(c.rate_hz, 100.0);
        // 3 ticks of 10 000 us at 100 Hz.
        assert_eq!(c.max_message_age_us, 30_000);
        // The board's drive gain, the same bits as 1.5 x 7 x 0.01 x 100 in f32.
        let expected: f32 = 1.5 * 7.0 * 0.01 * 100.0;
        assert_eq!(c.drive_gain_nm_per_a.to_bits(), expected.to_bits());
        assert_eq!(c.max_current_a, 12.0);
        // A zero rate does not divide by zero.
        assert_eq!(p.compensator_config(0, 0).max_message_age_us, 0);
        // Free-running is the default (the generic board's UART); SYNC stays
        // selectable and valid.
        assert_eq!(
            c.bus_clock,
            BusClock::FreeRunning {
                max_rate_error_ppm: 20_000
            }
        );
        let sync = JointProfile {
            bus_clock: BusClock::Synchronised,
            ..p
        };
        assert_eq!(sync.invalid_field(), None);
        assert_eq!(
            sync.compensator_config(100, 0).bus_clock,
            BusClock::Synchronised
        );
    }

    #[test]
    fn an_unusable_field_is_named() {
        let mut p = JointProfile::BOARD;
        p.motor.phase_inductance_h = f32::NAN;
        assert_eq!(p.invalid_field(), Some("phase_inductance_h"));
        let mut p = JointProfile::BOARD;
        p.overcurrent_trip_a = p.max_current_a;
        assert_eq!(p.invalid_field(), Some("overcurrent_trip_a"));
        let mut p = JointProfile::BOARD;
        p.bus_max_v = p.bus_min_v;
        assert_eq!(p.invalid_field(), Some("bus_max_v"));
        let mut p = JointProfile::BOARD;
        p.gear_efficiency = 1.5;
        assert_eq!(p.invalid_field(), Some("gear_efficiency"));
        let mut p = JointProfile::BOARD;
        p.cascade.velocity_kp = -1.0;
        assert_eq!(p.invalid_field(), Some("velocity_kp"));
        let mut p = JointProfile::BOARD;
        p.bus_baud = 0;
        assert_eq!(p.invalid_field(), Some("bus_baud"));
        let mut p = JointProfile::BOARD;
        p.feedforward_max_current_a = f32::INFINITY;
        assert_eq!(p.invalid_field(), Some("feedforward_max_current_a"));
        let mut p = JointProfile::BOARD;
        p.watchdog_ticks = 0;
        assert_eq!(p.invalid_field(), Some("watchdog_ticks"));
        assert!(all_valid(&[JointProfile::BOARD; 3]));
        assert!(!all_valid(&[JointProfile::BOARD, p]));
    }
}
