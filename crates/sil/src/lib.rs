//! Software in the loop: the firmware's own control functions (`firmware::control`)
//! drive a simulated joint plant through PWM duties, on the host.
//!
//! [`plant`] holds the motor, gear, sensors and the [`plant::JointLoad`] trait through
//! which a load plugs in (here a single joint with inertia, friction and gravity).
//! [`multi`] couples several joints through a test mechanism; [`wrist`] runs the
//! paper's wrist on the plant simulator's true dynamics, friction and ripple with
//! the identified model and the LSTM as feedforward (`model-export sil --model`). [`run_single_joint`]
//! closes the loop: sensors -> `JointDrive::pwm_tick` -> duties -> plant, with the
//! `Compensator` feeding the torque feedforward at its own rate.
#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod multi;
pub mod plant;
pub mod wrist;

use firmware::control::{
    BusClock, CascadeConfig, Compensator, CompensatorConfig, CurrentLoopConfig, DriveConfig,
    FaultFlags, JointDrive, JointReference, JointState, JointStateMessage, NoPredictor,
    PredictorInput, SensorSample, StateLimits, TorquePredictor,
};
use plant::{JointPlant, JointPlantConfig, SingleJointLoad};
use std::f64::consts::TAU;

/// A smooth periodic joint trajectory that starts at rest:
/// q(t) = offset + sum_k a_k (1 - cos(k w t)).
#[derive(Clone, Debug, PartialEq)]
pub struct Trajectory {
    /// Position at t = 0, rad.
    pub offset_rad: f64,
    /// Fundamental frequency, Hz.
    pub fundamental_hz: f64,
    /// Amplitude of harmonic k (k = 1, 2, ...), rad.
    pub amplitudes_rad: Vec<f64>,
}

impl Trajectory {
    /// Position, velocity and acceleration at time `t_s`.
    pub fn at(&self, t_s: f64) -> (f64, f64, f64) {
        let w = TAU * self.fundamental_hz;
        let (mut q, mut qd, mut qdd) = (self.offset_rad, 0.0, 0.0);
        for (k, a) in self.amplitudes_rad.iter().enumerate() {
            let kw = (k + 1) as f64 * w;
            q += a * (1.0 - (kw * t_s).cos());
            qd += a * kw * (kw * t_s).sin();
            qdd += a * kw * kw * (kw * t_s).cos();
        }
        (q, qd, qdd)
    }
}

/// Which torque feedforward the compensator gives.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FeedforwardMode {
    /// None: the cascade alone.
    None,
    /// The plant's exact inverse dynamics on the reference, scaled by a factor
    /// (1.0 = perfect).
    InverseDynamics(f64),
}

/// The perfect (or scaled) torque predictor of a single joint: the plant's own
/// inverse dynamics evaluated on the reference.
#[derive(Clone, Copy, Debug)]
pub struct InverseDynamicsPredictor {
    /// The load model.
    pub load: SingleJointLoad,
    /// Joint-side inertia including the rotor, kg*m^2.
    pub inertia_kg_m2: f64,
    /// Output scale (1.0 = exact).
    pub scale: f64,
}

impl TorquePredictor<1> for InverseDynamicsPredictor {
    fn predict_nm(&mut self, input: &PredictorInput<1>) -> [f32; 1] {
        let s = &input.joints[0];
        let (q, qd, qdd) = (
            s.q_ref_rad as f64,
            s.qd_ref_rad_s as f64,
            s.qdd_ref_rad_s2 as f64,
        );
        [(self.scale * (self.inertia_kg_m2 * qdd + self.load.torque_at(q, qd))) as f32]
    }
    fn reset(&mut self) {}
}

/// Everything a single-joint run needs.
#[derive(Clone, Debug)]
pub struct SingleJointSetup {
    /// Plant (motor, gear, sensors).
    pub plant: JointPlantConfig,
    /// Load.
    pub load: SingleJointLoad,
    /// Firmware drive configuration.
    pub drive: DriveConfig,
    /// Firmware compensator configuration.
    pub compensator: CompensatorConfig,
    /// Reference trajectory.
    pub trajectory: Trajectory,
    /// Simulated time, s.
    pub duration_s: f64,
}

impl SingleJointSetup {
    /// A wrist-sized joint: 7 pole pairs, 0.105 N*m/A motor, gear 100, 48 V bus,
    /// 20 kHz PWM, outer loops at 5 kHz, compensator at `compensator_hz`.
    pub fn wrist_joint(compensator_hz: f64, seed: u64) -> Self {
        let plant = JointPlantConfig {
            pole_pairs: 7,
            phase_resistance_ohm: 0.3,
            phase_inductance_h: 3e-4,
            flux_linkage_wb: 0.01,
            rotor_inertia_kg_m2: 3e-5,
            gear_ratio: 100.0,
            gear_efficiency: 1.0,
            bus_v: 48.0,
            pwm_hz: 20_000.0,
            substeps: 10,
            encoder_bits: 14,
            encoder_offset_rad: 0.05,
            current_noise_a: 0.05,
            current_lsb_a: 0.01,
            bus_noise_v: 0.1,
            seed,
        };
        let load = SingleJointLoad {
            inertia_kg_m2: 0.5,
            viscous_nm_s_rad: 3.0,
            coulomb_nm: 5.0,
            coulomb_smoothing_rad_s: 0.02,
            gravity_nm: 20.0,
        };
        let drive = DriveConfig {
            current: CurrentLoopConfig::tuned(plant.motor(), plant.pwm_hz as f32),
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
            gear_ratio: plant.gear_ratio as f32,
            encoder_offset_rad: plant.encoder_offset_rad as f32,
            max_current_a: 15.0,
            overcurrent_trip_a: 30.0,
            bus_min_v: 36.0,
            bus_max_v: 56.0,
            max_abs_q_ref_rad: 6.3,
        };
        let drive_gain = 1.5 * plant.pole_pairs as f64 * plant.flux_linkage_wb * plant.gear_ratio;
        let compensator = CompensatorConfig {
            rate_hz: compensator_hz as f32,
            own_joint: 0,
            state_limits: StateLimits {
                max_abs_q_rad: 6.3,
                max_abs_qd_rad_s: 5.0,
                max_abs_qdd_rad_s2: 200.0,
                max_abs_tau_nm: 300.0,
            },
            watchdog_ticks: 3,
            max_message_age_us: 50_000,
            bus_clock: BusClock::Synchronised,
            max_torque_nm: 120.0,
            max_torque_rate_nm_s: 2_000.0,
            max_lstm_correction_nm: 30.0,
            warmup_ticks: 10,
            lstm_retry_ticks: 50,
            drive_gain_nm_per_a: drive_gain as f32,
            max_current_a: 12.0,
        };
        let trajectory = Trajectory {
            offset_rad: 0.2,
            fundamental_hz: 0.4,
            amplitudes_rad: vec![0.5, 0.15, 0.05],
        };
        Self {
            plant,
            load,
            drive,
            compensator,
            trajectory,
            duration_s: 5.0,
        }
    }
}

/// Results of one closed-loop run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SilReport {
    /// RMS of the position-tracking error (reference - true position), rad.
    pub rms_error_rad: f64,
    /// Largest |tracking error|, rad.
    pub max_error_rad: f64,
    /// RMS of the true q current, A.
    pub rms_iq_a: f64,
    /// RMS of the q current the outer loops commanded on top of the feedforward, A.
    pub rms_feedback_current_a: f64,
    /// Every fault the drive and the compensator raised.
    pub faults: FaultFlags,
    /// PWM periods simulated.
    pub pwm_ticks: u64,
}

/// Run the closed loop: the firmware's `JointDrive` and `Compensator` (f32) against
/// the f64 plant, duties applied one PWM period after the sample they were computed
/// from (as on the MCU).
pub fn run_single_joint(
    setup: &SingleJointSetup,
    mode: FeedforwardMode,
) -> anyhow::Result<SilReport> {
    let mut plant = JointPlant::new(setup.plant, setup.load, setup.trajectory.offset_rad);
    let mut drive = JointDrive::new(setup.drive);
    drive.set_position_origin(setup.trajectory.offset_rad as f32);
    let predictor = InverseDynamicsPredictor {
        load: setup.load,
        inertia_kg_m2: plant.effective_inertia_kg_m2(),
        scale: match mode {
            FeedforwardMode::None => 0.0,
            FeedforwardMode::InverseDynamics(s) => s,
        },
    };
    let mut comp: Compensator<1, _, NoPredictor> =
        Compensator::new(setup.compensator, predictor, NoPredictor)
            .map_err(|e| anyhow::anyhow!("compensator configuration: {e:?}"))?;
    let pwm_hz = setup.plant.pwm_hz;
    let comp_every = (pwm_hz / setup.compensator.rate_hz as f64).round().max(1.0) as u64;
    let n = (setup.duration_s * pwm_hz).round() as u64;
    let mut duties = [0.5f64; 3];
    let (mut se, mut max_e, mut siq, mut sfb) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    let mut faults = FaultFlags::NONE;
    let mut last_out = firmware::control::DriveOutput::default();
    let gain = setup.compensator.drive_gain_nm_per_a;
    let mut ff_a = 0.0f32;
    for k in 0..n {
        let t = k as f64 / pwm_hz;
        let (q, qd, qdd) = setup.trajectory.at(t);
        let reference = JointReference {
            q_rad: q as f32,
            qd_rad_s: qd as f32,
            qdd_rad_s2: qdd as f32,
        };
        drive.set_reference(&reference);
        if k % comp_every == 0 {
            // The feedforward is held for one compensator period: predict for the
            // middle of that period (the reference is known ahead).
            let (qa, qda, qdda) = setup.trajectory.at(t + 0.5 * comp_every as f64 / pwm_hz);
            let own = JointState {
                q_ref_rad: qa as f32,
                qd_ref_rad_s: qda as f32,
                qdd_ref_rad_s2: qdda as f32,
                q_meas_rad: last_out.q_rad,
                qd_meas_rad_s: last_out.qd_rad_s,
                tau_meas_nm: last_out.iq_meas_a * gain,
            };
            let o = comp.tick(&own, (t * 1e6) as u32);
            ff_a = o.current_a;
            drive.set_feedforward_current(ff_a);
        }
        let s = plant.sense();
        let sample = SensorSample {
            phase_current_a: [s.phase_current_a[0] as f32, s.phase_current_a[1] as f32],
            motor_angle_rad: s.motor_angle_rad as f32,
            bus_v: s.bus_v as f32,
        };
        last_out = drive.pwm_tick(&sample);
        faults |= last_out.faults;
        plant.step_pwm_period(duties);
        duties = last_out.duties.map(f64::from);
        let e = setup.trajectory.at(plant.t_s()).0 - plant.q_rad();
        se += e * e;
        max_e = max_e.max(e.abs());
        siq += plant.iq_a().powi(2);
        sfb += ((last_out.iq_ref_a - ff_a) as f64).powi(2);
    }
    faults |= comp.latched_faults();
    let nf = n.max(1) as f64;
    Ok(SilReport {
        rms_error_rad: (se / nf).sqrt(),
        max_error_rad: max_e,
        rms_iq_a: (siq / nf).sqrt(),
        rms_feedback_current_a: (sfb / nf).sqrt(),
        faults,
        pwm_ticks: n,
    })
}

/// The state bus between the joints' firmware instances (as over EtherCAT): the frames
/// sent at one compensator tick travel as wire bytes and arrive at the next (one tick of
/// latency), at every compensator but the sender's.
#[derive(Debug, Default)]
pub struct StateBus {
    in_flight: Vec<[u8; JointStateMessage::WIRE_LEN]>,
    sequence: u16,
}

impl StateBus {
    /// Delivers the frames sent at the previous tick and opens a new tick (its sequence
    /// number).
    pub fn deliver<const J: usize, M: TorquePredictor<J>, L: TorquePredictor<J>>(
        &mut self,
        comps: &mut [Compensator<J, M, L>],
    ) -> anyhow::Result<()> {
        for frame in self.in_flight.drain(..) {
            let msg = JointStateMessage::decode(&frame)
                .ok_or_else(|| anyhow::anyhow!("corrupt frame"))?;
            for (j, c) in comps.iter_mut().enumerate() {
                if j != msg.joint as usize {
                    c.receive(&msg);
                }
            }
        }
        self.sequence = self.sequence.wrapping_add(1);
        Ok(())
    }

    /// Sends joint `joint`'s state of this tick.
    pub fn send(&mut self, joint: usize, timestamp_us: u32, state: JointState) {
        let msg = JointStateMessage {
            joint: joint as u8,
            session: 0,
            sequence: self.sequence,
            timestamp_us,
            state,
        };
        self.in_flight.push(msg.encode());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn current_loop_step_response_on_the_plant() {
        // Rotor held by a huge inertia; the firmware's FOC current loop alone, one PWM
        // period of delay: a 5 A q step settles in about 1 ms without ringing.
        let setup = SingleJointSetup::wrist_joint(1000.0, 1);
        let mut pc = setup.plant;
        pc.current_noise_a = 0.0;
        pc.current_lsb_a = 0.0;
        let load = SingleJointLoad {
            inertia_kg_m2: 1e9,
            ..setup.load
        };
        let mut plant = JointPlant::new(pc, load, 0.1);
        let mut cl = firmware::control::CurrentLoop::new(setup.drive.current);
        let mut duties = [0.5; 3];
        let mut peak: f64 = 0.0;
        let mut at_1ms = 0.0;
        for k in 0..100 {
            let s = plant.sense();
            let angle_el = 7.0 * (s.motor_angle_rad - pc.encoder_offset_rad);
            let out = cl.step(
                [s.phase_current_a[0] as f32, s.phase_current_a[1] as f32],
                angle_el as f32,
                0.0,
                s.bus_v as f32,
                firmware::control::foc::Dq { d: 0.0, q: 5.0 },
            );
            plant.step_pwm_period(duties);
            duties = out.duties.map(f64::from);
            peak = peak.max(plant.iq_a());
            if k == 19 {
                at_1ms = plant.iq_a();
            }
        }
        let end = plant.iq_a();
        println!("iq at 1 ms {at_1ms:.3} A, at 5 ms {end:.3} A, peak {peak:.3} A");
        assert!((at_1ms - 5.0).abs() < 0.25, "{at_1ms}");
        assert!((end - 5.0).abs() < 0.02, "{end}");
        assert!(peak < 5.5, "overshoot: {peak}");
    }

    #[test]
    fn loop_tracks_and_perfect_feedforward_reduces_the_error() {
        let setup = SingleJointSetup::wrist_joint(1000.0, 7);
        let none = run_single_joint(&setup, FeedforwardMode::None).unwrap();
        let perfect = run_single_joint(&setup, FeedforwardMode::InverseDynamics(1.0)).unwrap();
        println!("no ff: {none:?}\nperfect ff: {perfect:?}");
        // The cascade alone tracks (amplitude 0.7 rad) within a few milliradians.
        assert!(none.rms_error_rad < 0.01, "{none:?}");
        // Perfect torque feedforward: at least 3x smaller error, and the feedback
        // loops have far less to do.
        assert!(
            perfect.rms_error_rad < none.rms_error_rad / 3.0,
            "{perfect:?} vs {none:?}"
        );
        assert!(perfect.rms_feedback_current_a < none.rms_feedback_current_a / 3.0);
        let drive_faults =
            FaultFlags::SENSOR_INVALID | FaultFlags::OVERCURRENT | FaultFlags::BUS_VOLTAGE;
        assert!(!perfect.faults.intersects(drive_faults) && !none.faults.intersects(drive_faults));
    }
}
