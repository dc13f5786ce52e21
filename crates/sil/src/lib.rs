//! Software in the loop: the firmware's own control functions (`firmware::control`)
//! drive a simulated joint plant through PWM duties, on the host.
//!
//! Every simulated joint is a board as the product runs it: its configuration block
//! goes through the firmware's start-up (`plan_startup`) against the image's joint
//! profiles, which configure its drive and compensator and describe its motor and
//! gear ([`joint`]). [`joint::run_joints`] is the one loop of every setup: per PWM
//! period each joint's [`joint::SimulatedJoint::step_joint`] (sensors ->
//! `JointDrive::pwm_tick` -> duties, the `Compensator` feeding the torque feedforward
//! at its own rate), then the motors and the mechanics behind [`joint::Mechanism`].
//!
//! [`plant`] holds the motor and sensor models and a single joint's load;
//! [`run_single_joint`] runs one joint on it. [`multi`] couples several joints through
//! a test mechanism; [`wrist`] runs the paper's wrist on the plant simulator's true
//! dynamics, friction and ripple with the identified model and the LSTM as
//! feedforward (`model-export sil --model`).
#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod candump;
pub mod joint;
pub mod multi;
pub mod plant;
pub mod wrist;

use firmware::control::{
    FaultFlags, JointConfigBlock, JointProfile, JointState, JointStateMessage, NoPredictor,
    PredictorInput, StartupPlan, TorquePredictor, plan_startup,
};
use joint::{BOARD_PWM_HZ, Mechanism, SimulatedHardware, SimulatedJoint};
use plant::{JointPlantConfig, SingleJointLoad};
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

/// Everything a single-joint run needs: the image's joint (its index and profile), the
/// board's configuration block, the simulated hardware and the load.
#[derive(Clone, Debug)]
pub struct SingleJointSetup {
    /// The compensated joint of the image (0-based robot joint, `JOINT_INDICES`).
    pub joint_indices: [usize; 1],
    /// Its drive profile (`JOINT_PROFILES`): the drive, the compensator and the
    /// simulated motor and gear.
    pub profiles: [JointProfile; 1],
    /// The board's configuration block (encoded).
    pub config_block: [u8; JointConfigBlock::LEN],
    /// What only the simulation has: rotor inertia, bus voltage, PWM, sensors, seed.
    pub hardware: SimulatedHardware,
    /// Load.
    pub load: SingleJointLoad,
    /// Compensator rate, Hz.
    pub compensator_hz: u32,
    /// Reference trajectory.
    pub trajectory: Trajectory,
    /// Simulated time, s.
    pub duration_s: f64,
}

impl SingleJointSetup {
    /// The first compensated joint of the compiled-in model (the wrist's joint 4: the
    /// board's wrist motor, 100:1 gear, cascade at 5 kHz), configured as that joint,
    /// on the board's 20 kHz PWM and a 48 V bus, its compensator at `compensator_hz`,
    /// driving 0.5 kg*m^2 with viscous and Coulomb friction and 20 N*m of gravity.
    pub fn wrist_joint(compensator_hz: u32, seed: u64) -> Self {
        use firmware::model::default as compiled;
        let joint = compiled::JOINT_INDICES[0];
        let hardware = SimulatedHardware {
            rotor_inertia_kg_m2: 3e-5,
            bus_v: 48.0,
            pwm_hz: BOARD_PWM_HZ,
            substeps: 10,
            encoder_bits: 14,
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
        let trajectory = Trajectory {
            offset_rad: 0.2,
            fundamental_hz: 0.4,
            amplitudes_rad: vec![0.5, 0.15, 0.05],
        };
        Self {
            joint_indices: [joint],
            profiles: [compiled::JOINT_PROFILES[0]],
            config_block: joint::config_block_of_index(joint),
            hardware,
            load,
            compensator_hz,
            trajectory,
            duration_s: 5.0,
        }
    }

    /// The simulated motor, gear and sensors: the joint's profile and the hardware.
    pub fn plant(&self) -> JointPlantConfig {
        JointPlantConfig::from_profile(&self.profiles[0], &self.hardware)
    }

    /// The board's start-up decision on this setup (`firmware::control::plan_startup`).
    pub fn plan(&self) -> StartupPlan {
        plan_startup(
            &self.config_block,
            &self.joint_indices,
            &self.profiles,
            self.hardware.pwm_hz as f32,
            self.compensator_hz,
        )
    }
}

/// A single joint's load as the mechanism of [`joint::run_joints`].
struct SingleJointMechanism(SingleJointLoad);

impl Mechanism<1> for SingleJointMechanism {
    fn accelerations(
        &mut self,
        _t_s: f64,
        q: &[f64; 1],
        qd: &[f64; 1],
        tau: &[f64; 1],
        reflected: &[f64; 1],
        _dt_s: f64,
    ) -> anyhow::Result<[f64; 1]> {
        let inertia = self.0.inertia_kg_m2 + reflected[0];
        Ok([(tau[0] - self.0.torque_at(q[0], qd[0])) / inertia])
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

/// Run the closed loop: the board's start-up on the setup's configuration block, then
/// the firmware's `JointDrive` and `Compensator` (f32) against the f64 plant through
/// [`joint::run_joints`], duties applied one PWM period after the sample they were
/// computed from (as on the MCU).
pub fn run_single_joint(
    setup: &SingleJointSetup,
    mode: FeedforwardMode,
) -> anyhow::Result<SilReport> {
    let plant = setup.plant();
    let predictor = InverseDynamicsPredictor {
        load: setup.load,
        inertia_kg_m2: setup.load.inertia_kg_m2 + plant.reflected_rotor_inertia_kg_m2(),
        scale: match mode {
            FeedforwardMode::None => 0.0,
            FeedforwardMode::InverseDynamics(s) => s,
        },
    };
    let joint = SimulatedJoint::<1, _, NoPredictor>::start(
        &setup.config_block,
        &setup.joint_indices,
        &setup.profiles,
        setup.compensator_hz,
        plant,
        setup.trajectory.offset_rad,
        |_| Ok((predictor, NoPredictor)),
    )?;
    let mut joints = [match mode {
        FeedforwardMode::None => joint.without_adaptation(),
        FeedforwardMode::InverseDynamics(_) => joint,
    }];
    let r = joint::run_joints(
        &mut joints,
        &mut SingleJointMechanism(setup.load),
        |t| [setup.trajectory.at(t)],
        setup.compensator_hz,
        setup.duration_s,
    )?;
    let r = r[0];
    Ok(SilReport {
        rms_error_rad: r.rms_error_rad,
        max_error_rad: r.max_error_rad,
        rms_iq_a: r.rms_iq_a,
        rms_feedback_current_a: r.rms_feedback_current_a,
        faults: r.faults,
        pwm_ticks: r.pwm_ticks,
    })
}

/// The state bus between the joints' firmware instances (as over EtherCAT): the frames
/// sent at one compensator tick travel as wire bytes and arrive at the next (one tick of
/// latency), at every compensator but the sender's.
#[derive(Default)]
pub struct StateBus {
    in_flight: Vec<[u8; JointStateMessage::WIRE_LEN]>,
    sequence: u16,
    recorder: Option<candump::CandumpRecorder>,
}

impl std::fmt::Debug for StateBus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StateBus")
            .field("in_flight", &self.in_flight.len())
            .field("sequence", &self.sequence)
            .field("recording", &self.recorder.is_some())
            .finish()
    }
}

impl StateBus {
    /// The frames sent at the previous tick, decoded (each goes to every board but its
    /// sender's), and a new tick opened (its sequence number).
    pub fn deliver(&mut self) -> anyhow::Result<Vec<JointStateMessage>> {
        let msgs = self
            .in_flight
            .drain(..)
            .map(|frame| {
                JointStateMessage::decode(&frame).ok_or_else(|| anyhow::anyhow!("corrupt frame"))
            })
            .collect::<anyhow::Result<Vec<_>>>()?;
        self.sequence = self.sequence.wrapping_add(1);
        Ok(msgs)
    }

    /// A bus that also records every state frame sent, as the drives would put it on
    /// the CAN-FD bus ([`candump::CandumpRecorder`]).
    pub fn recording(recorder: candump::CandumpRecorder) -> Self {
        Self {
            recorder: Some(recorder),
            ..Self::default()
        }
    }

    /// The recorder, if this bus records.
    pub fn recorder(&self) -> Option<&candump::CandumpRecorder> {
        self.recorder.as_ref()
    }

    /// Sends joint `joint`'s state of this tick with its compensator's `faults` and
    /// feedforward `feedforward_nm` (recorded when the bus records).
    pub fn send_frame(
        &mut self,
        joint: usize,
        timestamp_us: u32,
        state: JointState,
        faults: FaultFlags,
        feedforward_nm: f32,
    ) {
        if let Some(r) = self.recorder.as_mut() {
            r.record(joint, timestamp_us, state, faults, feedforward_nm);
        }
        self.send(joint, timestamp_us, state);
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
    use crate::plant::JointPlant;

    #[test]
    fn current_loop_step_response_on_the_plant() {
        // Rotor held by a huge inertia; the firmware's FOC current loop alone, one PWM
        // period of delay: a 5 A q step settles in about 1 ms without ringing.
        let setup = SingleJointSetup::wrist_joint(1000, 1);
        let mut pc = setup.plant();
        pc.current_noise_a = 0.0;
        pc.current_lsb_a = 0.0;
        let load = SingleJointLoad {
            inertia_kg_m2: 1e9,
            ..setup.load
        };
        let mut plant = JointPlant::new(pc, load, 0.1);
        let drive = setup
            .plan()
            .drive
            .expect("the board's block configures a drive");
        let mut cl = firmware::control::CurrentLoop::new(drive.current);
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
        let setup = SingleJointSetup::wrist_joint(1000, 7);
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
