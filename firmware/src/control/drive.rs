//! One joint drive: sensor checks, encoder unwrapping, the outer cascade at a
//! decimation of the PWM rate, the held torque feedforward and the FOC current loop.

use super::cascade::{CascadeConfig, JointReference, PositionVelocityCascade};
use super::faults::FaultFlags;
use super::foc::{CurrentLoop, CurrentLoopConfig, CurrentLoopOutput, Dq};

const TAU: f32 = core::f32::consts::TAU;
const PI: f32 = core::f32::consts::PI;

/// Configuration of a joint drive.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveConfig {
    /// The current loop (motor, PWM rate, bandwidth, modulation).
    pub current: CurrentLoopConfig,
    /// The position and velocity loops (their rate sets the decimation).
    pub cascade: CascadeConfig,
    /// Gear ratio: motor turns per joint turn.
    pub gear_ratio: f32,
    /// Encoder reading (motor mechanical angle, rad) at electrical angle zero.
    pub encoder_offset_rad: f32,
    /// Limit of the q-current reference (outer loops + feedforward), A.
    pub max_current_a: f32,
    /// A phase current beyond this trips the bridge off for the tick, A.
    pub overcurrent_trip_a: f32,
    /// Bus voltage operating range, V.
    pub bus_min_v: f32,
    /// Bus voltage operating range, V.
    pub bus_max_v: f32,
    /// Largest accepted |joint position reference|, rad.
    pub max_abs_q_ref_rad: f32,
}

impl DriveConfig {
    /// PWM ticks per outer-loop tick (at least 1).
    pub fn outer_decimation(&self) -> u32 {
        let n = libm::roundf(self.current.pwm_hz / self.cascade.rate_hz);
        if (1.0..=1.0e6).contains(&n) {
            n as u32
        } else {
            1
        }
    }
}

/// One PWM period's sensor readings.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SensorSample {
    /// Phase currents a and b (c = -a - b), A.
    pub phase_current_a: [f32; 2],
    /// Motor mechanical angle from the encoder, rad in [0, 2 pi).
    pub motor_angle_rad: f32,
    /// Bus voltage, V.
    pub bus_v: f32,
}

/// One PWM period's output.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DriveOutput {
    /// Duty cycles of phases a, b, c in [0, 1] (0.5 each when the bridge is off).
    pub duties: [f32; 3],
    /// False when a sensor or bus fault requires the bridge switched off.
    pub bridge_enabled: bool,
    /// The q-current reference applied this tick, A.
    pub iq_ref_a: f32,
    /// Measured q current, A.
    pub iq_meas_a: f32,
    /// Joint position, rad.
    pub q_rad: f32,
    /// Joint velocity estimate, rad/s.
    pub qd_rad_s: f32,
    /// Faults of this tick.
    pub faults: FaultFlags,
}

/// A joint drive's real-time part, called at the PWM rate.
#[derive(Clone, Debug)]
pub struct JointDrive {
    config: DriveConfig,
    current: CurrentLoop,
    cascade: PositionVelocityCascade,
    decimation: u32,
    phase: u32,
    reference: JointReference,
    pending: FaultFlags,
    feedforward_a: f32,
    iq_cmd_a: f32,
    turns: i32,
    last_angle_rad: f32,
    angle_known: bool,
    turn_origin_rad: f32,
    q_rad: f32,
    q_prev_outer_rad: f32,
    qd_rad_s: f32,
    latched: FaultFlags,
}

impl JointDrive {
    /// A drive at rest; the first valid encoder reading sets the turn origin.
    pub fn new(config: DriveConfig) -> Self {
        Self {
            config,
            current: CurrentLoop::new(config.current),
            cascade: PositionVelocityCascade::new(config.cascade),
            decimation: config.outer_decimation(),
            phase: 0,
            reference: JointReference::default(),
            pending: FaultFlags::NONE,
            feedforward_a: 0.0,
            iq_cmd_a: 0.0,
            turns: 0,
            last_angle_rad: 0.0,
            angle_known: false,
            turn_origin_rad: 0.0,
            q_rad: 0.0,
            q_prev_outer_rad: 0.0,
            qd_rad_s: 0.0,
            latched: FaultFlags::NONE,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &DriveConfig {
        &self.config
    }

    /// The current loop.
    pub fn current_loop(&self) -> &CurrentLoop {
        &self.current
    }

    /// Every fault since the last [`JointDrive::clear_latched`].
    pub fn latched_faults(&self) -> FaultFlags {
        self.latched
    }

    /// Clear the latched faults.
    pub fn clear_latched(&mut self) {
        self.latched = FaultFlags::NONE;
    }

    /// Joint position, rad.
    pub fn q_rad(&self) -> f32 {
        self.q_rad
    }

    /// Joint velocity estimate, rad/s.
    pub fn qd_rad_s(&self) -> f32 {
        self.qd_rad_s
    }

    /// The reference in use.
    pub fn reference(&self) -> &JointReference {
        &self.reference
    }

    /// Set the trajectory point to follow; a non-finite or out-of-range reference is
    /// refused (the last one is held) and flagged on the next tick.
    pub fn set_reference(&mut self, r: &JointReference) {
        let lim = self.config.cascade.max_velocity_rad_s;
        let ok = r.q_rad.abs() <= self.config.max_abs_q_ref_rad
            && r.qd_rad_s.abs() <= lim
            && r.qdd_rad_s2.is_finite();
        if ok {
            self.reference = *r;
        } else {
            self.pending |= FaultFlags::REFERENCE_INVALID;
        }
    }

    /// Set the q-current feedforward (from the compensator), held until replaced; a
    /// non-finite value is replaced by zero and flagged.
    pub fn set_feedforward_current(&mut self, current_a: f32) {
        if current_a.is_finite() {
            self.feedforward_a = current_a;
        } else {
            self.feedforward_a = 0.0;
            self.pending |= FaultFlags::REFERENCE_INVALID;
        }
    }

    /// Restart the joint position at `q_rad` (after homing).
    pub fn set_position_origin(&mut self, q_rad: f32) {
        if q_rad.is_finite() {
            self.turns = 0;
            self.angle_known = false;
            self.q_prev_outer_rad = q_rad;
            self.q_rad = q_rad;
        }
    }

    fn bridge_off(&mut self, faults: FaultFlags) -> DriveOutput {
        self.current.reset();
        self.cascade.reset();
        self.latched |= faults;
        DriveOutput {
            duties: [0.5; 3],
            bridge_enabled: false,
            iq_ref_a: 0.0,
            iq_meas_a: 0.0,
            q_rad: self.q_rad,
            qd_rad_s: self.qd_rad_s,
            faults,
        }
    }

    /// One PWM period: sensors -> three duties. Fixed work per call (the outer loops
    /// run on every `decimation`-th call).
    pub fn pwm_tick(&mut self, s: &SensorSample) -> DriveOutput {
        let cfg = self.config;
        let mut faults = self.pending;
        self.pending = FaultFlags::NONE;
        let [ia, ib] = s.phase_current_a;
        let ic = -ia - ib;
        let sensors_ok = ia.is_finite()
            && ib.is_finite()
            && s.motor_angle_rad.abs() <= 2.0 * TAU
            && s.bus_v.is_finite();
        if !sensors_ok {
            return self.bridge_off(faults | FaultFlags::SENSOR_INVALID);
        }
        let trip = cfg.overcurrent_trip_a;
        if ia.abs() > trip || ib.abs() > trip || ic.abs() > trip {
            return self.bridge_off(faults | FaultFlags::OVERCURRENT);
        }
        if !(s.bus_v >= cfg.bus_min_v && s.bus_v <= cfg.bus_max_v) {
            return self.bridge_off(faults | FaultFlags::BUS_VOLTAGE);
        }

        // Encoder: count motor turns, joint position = motor angle / gear.
        let angle = s.motor_angle_rad;
        if self.angle_known {
            let delta = angle - self.last_angle_rad;
            if delta > PI {
                self.turns = self.turns.saturating_sub(1);
            } else if delta < -PI {
                self.turns = self.turns.saturating_add(1);
            }
        } else {
            // First reading: keep the current joint position as the origin.
            self.turns = 0;
            self.angle_known = true;
            self.turn_origin_rad = self.q_rad * cfg.gear_ratio - angle;
        }
        self.last_angle_rad = angle;
        let motor_rad = self.turns as f32 * TAU + angle + self.turn_origin_rad;
        self.q_rad = motor_rad / cfg.gear_ratio;

        // Outer loops at the decimated rate.
        if self.phase == 0 {
            let dt = 1.0 / cfg.cascade.rate_hz;
            let raw = (self.q_rad - self.q_prev_outer_rad) / dt;
            self.q_prev_outer_rad = self.q_rad;
            self.qd_rad_s += cfg.cascade.velocity_filter_alpha * (raw - self.qd_rad_s);
            if !self.qd_rad_s.is_finite() {
                self.qd_rad_s = 0.0;
            }
            self.iq_cmd_a = self
                .cascade
                .step(&self.reference, self.q_rad, self.qd_rad_s);
        }
        self.phase += 1;
        if self.phase >= self.decimation {
            self.phase = 0;
        }

        // q-current reference: outer loops + held feedforward, clamped.
        let unclamped = self.iq_cmd_a + self.feedforward_a;
        let max = cfg.max_current_a;
        let iq_ref = super::clamp_abs(unclamped, max);
        if iq_ref != unclamped {
            faults |= FaultFlags::IQ_CLAMPED;
        }
        let pole_pairs = cfg.current.motor.pole_pairs as f32;
        let angle_el = pole_pairs * (angle - cfg.encoder_offset_rad);
        let speed_el = pole_pairs * cfg.gear_ratio * self.qd_rad_s;
        let out: CurrentLoopOutput = self.current.step(
            [ia, ib],
            angle_el,
            speed_el,
            s.bus_v,
            Dq { d: 0.0, q: iq_ref },
        );
        if out.voltage_limited {
            faults |= FaultFlags::VOLTAGE_LIMITED;
        }
        self.latched |= faults;
        DriveOutput {
            duties: out.duties,
            bridge_enabled: true,
            iq_ref_a: iq_ref,
            iq_meas_a: out.i_dq_a.q,
            q_rad: self.q_rad,
            qd_rad_s: self.qd_rad_s,
            faults,
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::control::foc::MotorParameters;

    pub(crate) fn config() -> DriveConfig {
        DriveConfig {
            current: CurrentLoopConfig::tuned(MotorParameters::BOARD, 20_000.0),
            cascade: CascadeConfig {
                rate_hz: 5000.0,
                position_kp: 50.0,
                position_ki: 0.0,
                position_kd: 0.0,
                max_velocity_rad_s: 3.0,
                velocity_kp: 5.0,
                velocity_ki: 50.0,
                velocity_kd: 0.0,
                max_current_a: 10.0,
                velocity_filter_alpha: 0.2,
            },
            gear_ratio: 100.0,
            encoder_offset_rad: 0.1,
            max_current_a: 10.0,
            overcurrent_trip_a: 20.0,
            bus_min_v: 18.0,
            bus_max_v: 60.0,
            max_abs_q_ref_rad: 7.0,
        }
    }

    fn ok_sample(angle: f32) -> SensorSample {
        SensorSample {
            phase_current_a: [0.1, -0.2],
            motor_angle_rad: angle,
            bus_v: 48.0,
        }
    }

    #[test]
    fn decimation_and_encoder_unwrapping() {
        let cfg = config();
        assert_eq!(cfg.outer_decimation(), 4);
        let mut d = JointDrive::new(cfg);
        d.set_position_origin(0.5);
        // Spin the motor forward 3.5 turns in small steps through the wrap.
        let steps = 3500;
        let mut out = DriveOutput::default();
        for k in 0..=steps {
            let motor = 0.2 + k as f32 * (3.5 * TAU / steps as f32);
            out = d.pwm_tick(&ok_sample(motor % TAU));
        }
        let want = 0.5 + 3.5 * TAU / 100.0;
        assert!((out.q_rad - want).abs() < 1e-4, "{} vs {want}", out.q_rad);
        // and back
        for k in (0..=steps).rev() {
            let motor = 0.2 + k as f32 * (3.5 * TAU / steps as f32);
            out = d.pwm_tick(&ok_sample(motor % TAU));
        }
        assert!((out.q_rad - 0.5).abs() < 1e-4, "{}", out.q_rad);
    }

    #[test]
    fn sensor_faults_switch_the_bridge_off_and_back_on() {
        let cases: [(SensorSample, FaultFlags); 6] = [
            (
                SensorSample {
                    phase_current_a: [f32::NAN, 0.0],
                    ..ok_sample(1.0)
                },
                FaultFlags::SENSOR_INVALID,
            ),
            (
                SensorSample {
                    motor_angle_rad: f32::INFINITY,
                    ..ok_sample(1.0)
                },
                FaultFlags::SENSOR_INVALID,
            ),
            (
                SensorSample {
                    motor_angle_rad: 1e9,
                    ..ok_sample(1.0)
                },
                FaultFlags::SENSOR_INVALID,
            ),
            (
                SensorSample {
                    bus_v: f32::NEG_INFINITY,
                    ..ok_sample(1.0)
                },
                FaultFlags::SENSOR_INVALID,
            ),
            (
                SensorSample {
                    phase_current_a: [15.0, 15.0],
                    ..ok_sample(1.0)
                },
                FaultFlags::OVERCURRENT,
            ),
            (
                SensorSample {
                    bus_v: 90.0,
                    ..ok_sample(1.0)
                },
                FaultFlags::BUS_VOLTAGE,
            ),
        ];
        for (bad, flag) in cases {
            let mut d = JointDrive::new(config());
            d.set_reference(&JointReference {
                q_rad: 0.3,
                qd_rad_s: 0.0,
                qdd_rad_s2: 0.0,
            });
            for _ in 0..10 {
                assert!(d.pwm_tick(&ok_sample(1.0)).bridge_enabled);
            }
            let o = d.pwm_tick(&bad);
            assert!(
                !o.bridge_enabled && o.faults.contains(flag) && o.duties == [0.5; 3],
                "{o:?}"
            );
            let o = d.pwm_tick(&ok_sample(1.0));
            assert!(o.bridge_enabled && o.faults.is_empty(), "{o:?}");
            assert!(d.latched_faults().contains(flag));
        }
    }

    #[test]
    fn bad_reference_is_held_and_bad_feedforward_zeroed() {
        let mut d = JointDrive::new(config());
        let good = JointReference {
            q_rad: 0.3,
            qd_rad_s: 0.1,
            qdd_rad_s2: 0.0,
        };
        d.set_reference(&good);
        d.set_reference(&JointReference {
            q_rad: f32::NAN,
            ..good
        });
        d.set_feedforward_current(f32::INFINITY);
        let o = d.pwm_tick(&ok_sample(1.0));
        assert!(o.faults.contains(FaultFlags::REFERENCE_INVALID));
        assert_eq!(*d.reference(), good);
        d.set_feedforward_current(1e6);
        let o = d.pwm_tick(&ok_sample(1.0));
        assert!(
            o.faults.contains(FaultFlags::IQ_CLAMPED) && o.iq_ref_a == 10.0,
            "{o:?}"
        );
        d.set_feedforward_current(0.0);
        let o = d.pwm_tick(&ok_sample(1.0));
        assert!(!o.faults.contains(FaultFlags::REFERENCE_INVALID));
    }
}
