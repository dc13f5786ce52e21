//! One simulated joint-drive board and the loop every closed-loop simulation runs.
//!
//! A [`SimulatedJoint`] starts as the board does: its configuration block (encoded
//! bytes) goes through `firmware::control::plan_startup` against the image's
//! compensated joints and [`JointProfile`]s, which gives its drive and compensator
//! configurations (or the refusal: no feedforward, no state frames, the fault kept in
//! the report). Its motor is built from the profile of the joint it physically is
//! ([`JointPlantConfig::from_profile`]), so the simulated motor and gear are the ones
//! the drive is configured for; what only a simulation has (rotor inertia, bus
//! voltage, sensor noise, seed) is [`SimulatedHardware`].
//!
//! [`SimulatedJoint::step_joint`] is one PWM period of one joint's firmware (the
//! compensator at its rate, sensors -> `JointDrive::pwm_tick` -> duties applied from
//! the next period) and [`SimulatedJoint::motor_substep`] its motor's currents and
//! torque; [`run_joints`] steps every joint so, integrates the joint-side mechanics
//! behind [`Mechanism`] and measures the tracking. The single-joint, coupled-joint and
//! wrist simulations all run through it.

use crate::StateBus;
use crate::plant::{
    JointPlantConfig, motor_electrical_step, noise, phase_voltages, q_current_a, sense_joint,
};
use firmware::adaptation::AdaptationConfig;
use firmware::control::{
    Compensator, DriveOutput, FaultFlags, FeedforwardSource, JointConfigBlock, JointConfigFault,
    JointDrive, JointProfile, JointReference, JointSlot, JointState, JointStateMessage,
    SensorSample, StartupPlan, TorquePredictor, plan_startup,
};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::Normal;

/// The joint-drive board's PWM (current-loop) rate, Hz (TIM1 on the board).
pub const BOARD_PWM_HZ: f64 = 20_000.0;

/// The parts of a simulated joint no profile describes: the rotor's inertia, the
/// supply, the sensors' noise and steps, the integration and the seed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimulatedHardware {
    /// Rotor inertia, kg*m^2 (motor side).
    pub rotor_inertia_kg_m2: f64,
    /// Bus (supply) voltage, V.
    pub bus_v: f64,
    /// PWM frequency, Hz.
    pub pwm_hz: f64,
    /// Integration steps per PWM period.
    pub substeps: u32,
    /// Encoder resolution, bits per motor turn.
    pub encoder_bits: u32,
    /// Current-sensor noise, A (standard deviation).
    pub current_noise_a: f64,
    /// Current ADC step, A.
    pub current_lsb_a: f64,
    /// Bus-voltage sensor noise, V (standard deviation).
    pub bus_noise_v: f64,
    /// Seed of the sensor noise.
    pub seed: u64,
}

impl JointPlantConfig {
    /// The simulated motor, gear and encoder mounting of a joint whose drive profile
    /// is `profile` (pole pairs, R, L, flux linkage, gear ratio and efficiency,
    /// encoder offset), with the simulation's own `hardware`.
    pub fn from_profile(profile: &JointProfile, hardware: &SimulatedHardware) -> Self {
        let m = profile.motor;
        Self {
            pole_pairs: m.pole_pairs,
            phase_resistance_ohm: f64::from(m.phase_resistance_ohm),
            phase_inductance_h: f64::from(m.phase_inductance_h),
            flux_linkage_wb: f64::from(m.flux_linkage_wb),
            rotor_inertia_kg_m2: hardware.rotor_inertia_kg_m2,
            gear_ratio: f64::from(profile.gear_ratio),
            gear_efficiency: f64::from(profile.gear_efficiency),
            bus_v: hardware.bus_v,
            pwm_hz: hardware.pwm_hz,
            substeps: hardware.substeps,
            encoder_bits: hardware.encoder_bits,
            encoder_offset_rad: f64::from(profile.encoder_offset_rad),
            current_noise_a: hardware.current_noise_a,
            current_lsb_a: hardware.current_lsb_a,
            bus_noise_v: hardware.bus_noise_v,
            seed: hardware.seed,
        }
    }

    /// Rotor inertia reflected to the joint side (rotor x ratio^2), kg*m^2.
    pub fn reflected_rotor_inertia_kg_m2(&self) -> f64 {
        self.rotor_inertia_kg_m2 * self.gear_ratio * self.gear_ratio
    }
}

/// The state-bus key the simulated robot's drives are provisioned with.
pub const SIL_BUS_KEY: [u8; 16] = *b"sil-robot-bus-k1";

/// The configuration block of robot joint `joint_number` (counted from 1), as it is
/// written into a board's configuration page (with [`SIL_BUS_KEY`]).
pub fn config_block(joint_number: u8) -> [u8; JointConfigBlock::LEN] {
    JointConfigBlock {
        joint_number,
        bus_key: SIL_BUS_KEY,
    }
    .encode()
}

/// The configuration block naming the 0-based robot joint `joint_index` (naming joint 0,
/// which no image compensates, when its number does not fit the block's byte).
pub fn config_block_of_index(joint_index: usize) -> [u8; JointConfigBlock::LEN] {
    config_block(
        joint_index
            .checked_add(1)
            .and_then(|n| u8::try_from(n).ok())
            .unwrap_or(0),
    )
}

/// The joint-side mechanics the simulated motors drive: accelerations from the
/// motors' joint-side torques.
pub trait Mechanism<const J: usize> {
    /// Start of a PWM period at `t_s` in state (`q_rad`, `qd_rad_s`), with each
    /// motor's rotor inertia reflected to its joint (what is held over the period is
    /// computed here).
    fn begin_period(
        &mut self,
        _t_s: f64,
        _q_rad: &[f64; J],
        _qd_rad_s: &[f64; J],
        _rotor_reflected_kg_m2: &[f64; J],
    ) -> anyhow::Result<()> {
        Ok(())
    }
    /// Joint accelerations, rad/s^2, at one integration step of `dt_s` under the
    /// motors' joint-side torques `motor_torque_nm`.
    fn accelerations(
        &mut self,
        t_s: f64,
        q_rad: &[f64; J],
        qd_rad_s: &[f64; J],
        motor_torque_nm: &[f64; J],
        rotor_reflected_kg_m2: &[f64; J],
        dt_s: f64,
    ) -> anyhow::Result<[f64; J]>;
    /// End of a PWM period of `period_s` with the true q currents `iq_a` (for
    /// effects that evolve per period, such as the drives' temperature).
    fn end_period(&mut self, _iq_a: &[f64; J], _period_s: f64) {}
}

/// A compensator tick of one joint: the bus time and the joint's reference for this
/// tick (the middle of the period the feedforward is held for) and for the receivers'
/// next tick (what its state frame carries).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CompensatorTick {
    /// Local bus time, us.
    pub now_us: u32,
    /// Reference (q rad, qd rad/s, qdd rad/s^2) for this tick.
    pub reference: (f64, f64, f64),
    /// Reference one compensator period later, for the frame sent to the others.
    pub next_reference: (f64, f64, f64),
    /// Whether this is the first tick (the others have not been heard from yet: its
    /// compensator faults are not counted).
    pub first: bool,
}

/// What one PWM period of a joint's firmware gave.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointStep {
    /// The drive's output (its duties apply from the next period).
    pub drive: DriveOutput,
    /// The feedforward q current held by the drive, A.
    pub feedforward_a: f32,
    /// The source of the feedforward, when the compensator ticked this period (a board
    /// without a configured joint counts as `Zero`).
    pub source: Option<FeedforwardSource>,
    /// Faults of the drive and of the compensator (but on its first tick).
    pub faults: FaultFlags,
    /// The do-no-harm monitor's gain on the compensation beyond the model, in [0, 1],
    /// when the compensator ticked this period (1 with the monitor off).
    pub monitor_gain: Option<f32>,
}

/// One simulated joint-drive board on its motor: the firmware's `JointDrive` and
/// `Compensator` from its start-up plan, the motor's currents and sensors.
pub struct SimulatedJoint<const J: usize, M, L> {
    plant: JointPlantConfig,
    startup: Result<JointSlot, JointConfigFault>,
    drive: Option<JointDrive>,
    compensator: Option<Compensator<J, M, L>>,
    drive_gain_nm_per_a: f32,
    i_abc_a: [f64; 3],
    rng: ChaCha8Rng,
    current_noise: Normal<f64>,
    bus_noise: Normal<f64>,
    duties: [f64; 3],
    voltages_v: [f64; 3],
    last: DriveOutput,
    feedforward_a: f32,
    iq_meas_sum_a: f64,
    iq_meas_count: u32,
}

impl<const J: usize, M: TorquePredictor<J>, L: TorquePredictor<J>> SimulatedJoint<J, M, L> {
    /// The same board with its compensator's friction adaptation off: a run without
    /// any feedforward (the adaptation alone is a feedforward).
    pub fn without_adaptation(mut self) -> Self {
        self.compensator = self
            .compensator
            .map(|c| c.with_adaptation(AdaptationConfig::OFF));
        self
    }

    /// A board with configuration block `block` running an image whose compensated
    /// joints are `joint_indices` (0-based robot joints) with `profiles`, its
    /// compensator at `compensator_hz`, on the motor `plant` at rest at `q0_rad`.
    /// `predictors(slot)` gives the model and LSTM stages of a configured joint; its
    /// compensator runs the profile's friction adaptation after them, unless it has
    /// neither stage (no feedforward at all).
    pub fn start(
        block: &[u8; JointConfigBlock::LEN],
        joint_indices: &[usize; J],
        profiles: &[JointProfile; J],
        compensator_hz: u32,
        plant: JointPlantConfig,
        q0_rad: f64,
        predictors: impl FnOnce(usize) -> anyhow::Result<(M, L)>,
    ) -> anyhow::Result<Self> {
        let StartupPlan {
            joint,
            drive,
            compensator,
            adaptation,
            monitor,
        } = plan_startup(
            block,
            joint_indices,
            profiles,
            plant.pwm_hz as f32,
            compensator_hz,
        );
        let compensator = match (joint, compensator) {
            (Ok(slot), Some(config)) => {
                let (m, l) = predictors(slot.slot)?;
                let c = Compensator::new(config, m, l).map_err(|e| {
                    anyhow::anyhow!("compensator of joint {}: {e:?}", slot.joint_number)
                })?;
                // Without a model or an LSTM stage there is no feedforward at all (the
                // adaptation alone would be one).
                let stages =
                    <M as TorquePredictor<J>>::PRESENT || <L as TorquePredictor<J>>::PRESENT;
                // The profile's do-no-harm monitor after every stage, as on the board.
                Some(
                    c.with_adaptation(if stages {
                        adaptation
                    } else {
                        AdaptationConfig::OFF
                    })
                    .with_monitor(monitor),
                )
            }
            _ => None,
        };
        let drive_gain_nm_per_a = compensator
            .as_ref()
            .map_or(0.0, |c| c.config().drive_gain_nm_per_a);
        let drive = drive.map(|config| {
            let mut d = JointDrive::new(config);
            d.set_position_origin(q0_rad as f32);
            d
        });
        Ok(Self {
            plant,
            startup: joint,
            drive,
            compensator,
            drive_gain_nm_per_a,
            i_abc_a: [0.0; 3],
            rng: ChaCha8Rng::seed_from_u64(plant.seed),
            current_noise: noise(plant.current_noise_a),
            bus_noise: noise(plant.bus_noise_v),
            duties: [0.5; 3],
            voltages_v: [0.0; 3],
            last: DriveOutput::default(),
            feedforward_a: 0.0,
            iq_meas_sum_a: 0.0,
            iq_meas_count: 0,
        })
    }
}

impl<const J: usize, M, L> SimulatedJoint<J, M, L> {
    /// The joint the board was configured for, or why its block was refused.
    pub fn startup(&self) -> Result<JointSlot, JointConfigFault> {
        self.startup
    }

    /// The motor, gear and sensors.
    pub fn plant(&self) -> &JointPlantConfig {
        &self.plant
    }

    /// The board's compensator, when its joint is configured.
    pub fn compensator(&self) -> Option<&Compensator<J, M, L>> {
        self.compensator.as_ref()
    }

    /// True q current at joint position `q_rad`, A.
    pub fn iq_a(&self, q_rad: f64) -> f64 {
        q_current_a(self.i_abc_a, self.electrical_angle_rad(q_rad))
    }

    fn electrical_angle_rad(&self, q_rad: f64) -> f64 {
        let c = &self.plant;
        c.pole_pairs as f64 * (q_rad * c.gear_ratio - c.encoder_offset_rad)
    }
}

impl<const J: usize, M: TorquePredictor<J>, L: TorquePredictor<J>> SimulatedJoint<J, M, L> {
    /// Passes a state frame from the bus to the compensator (a board ignores its own).
    pub fn receive(&mut self, msg: &JointStateMessage) {
        if let (Some(c), Ok(slot)) = (self.compensator.as_mut(), self.startup)
            && usize::from(msg.joint) != slot.slot
        {
            c.receive(msg);
        }
    }

    /// One PWM period of this joint's firmware, with the joint at `q_rad`: at a
    /// compensator tick (`tick`), the compensator on this joint's state (measured
    /// torque: drive gain x the mean measured q current since the last tick) sets the
    /// feedforward and the joint's state frame goes onto `bus`; then the reference,
    /// the sensors -> `JointDrive::pwm_tick` -> the duties, which the motor gets from
    /// the next period on (as on the MCU).
    pub fn step_joint(
        &mut self,
        tick: Option<&CompensatorTick>,
        reference: &JointReference,
        q_rad: f64,
        bus: &mut StateBus,
    ) -> JointStep {
        let mut faults = FaultFlags::NONE;
        let mut source = None;
        let mut monitor_gain = None;
        if let Some(t) = tick {
            let tau_meas_nm = if self.iq_meas_count > 0 {
                (self.iq_meas_sum_a / f64::from(self.iq_meas_count)) as f32
                    * self.drive_gain_nm_per_a
            } else {
                0.0
            };
            let state = |r: (f64, f64, f64)| JointState {
                q_ref_rad: r.0 as f32,
                qd_ref_rad_s: r.1 as f32,
                qdd_ref_rad_s2: r.2 as f32,
                q_meas_rad: self.last.q_rad,
                qd_meas_rad_s: self.last.qd_rad_s,
                tau_meas_nm,
            };
            let (own, next) = (state(t.reference), state(t.next_reference));
            match (self.compensator.as_mut(), self.startup) {
                (Some(c), Ok(slot)) => {
                    let o = c.tick(&own, t.now_us);
                    self.feedforward_a = o.current_a;
                    if !t.first {
                        faults |= o.faults;
                    }
                    source = Some(o.source);
                    monitor_gain = Some(o.monitor_gain);
                    bus.send_frame(slot.slot, t.now_us, next, o.faults, o.torque_nm);
                }
                // No configured joint: no feedforward, no state frames.
                _ => {
                    self.feedforward_a = 0.0;
                    source = Some(FeedforwardSource::Zero);
                }
            }
            self.iq_meas_sum_a = 0.0;
            self.iq_meas_count = 0;
        }
        self.duties = self.last.duties.map(f64::from);
        let s = sense_joint(
            &self.plant,
            self.i_abc_a,
            q_rad * self.plant.gear_ratio,
            &mut self.rng,
            &self.current_noise,
            &self.bus_noise,
        );
        if let Some(d) = self.drive.as_mut() {
            d.set_reference(reference);
            d.set_feedforward_current(self.feedforward_a);
            self.last = d.pwm_tick(&SensorSample {
                phase_current_a: [s.phase_current_a[0] as f32, s.phase_current_a[1] as f32],
                motor_angle_rad: s.motor_angle_rad as f32,
                bus_v: s.bus_v as f32,
            });
            faults |= self.last.faults;
            self.iq_meas_sum_a += f64::from(self.last.iq_meas_a);
            self.iq_meas_count += 1;
        }
        self.voltages_v = phase_voltages(&self.plant, self.duties);
        JointStep {
            drive: self.last,
            feedforward_a: self.feedforward_a,
            source,
            faults,
            monitor_gain,
        }
    }
}

impl<const J: usize, M, L> SimulatedJoint<J, M, L> {
    /// One integration step of `dt_s` of the motor's currents under the duties of
    /// this period, the joint at (`q_rad`, `qd_rad_s`): the joint-side torque, N*m.
    /// Without a drive (a refused block whose joints' drives differ) the bridge is
    /// off and no current flows.
    pub fn motor_substep(&mut self, q_rad: f64, qd_rad_s: f64, dt_s: f64) -> f64 {
        if self.drive.is_none() {
            self.i_abc_a = [0.0; 3];
            return 0.0;
        }
        let c = self.plant;
        let th = self.electrical_angle_rad(q_rad);
        motor_electrical_step(
            &c,
            &mut self.i_abc_a,
            self.voltages_v,
            th,
            qd_rad_s * c.gear_ratio,
            dt_s,
        );
        let t_motor = 1.5 * c.pole_pairs as f64 * c.flux_linkage_wb * q_current_a(self.i_abc_a, th);
        t_motor * c.gear_ratio * c.gear_efficiency
    }
}

/// One joint's figures over a [`run_joints`] run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointRun {
    /// RMS position-tracking error (reference - true position, at the end of each PWM
    /// period), rad.
    pub rms_error_rad: f64,
    /// Largest |tracking error|, rad.
    pub max_error_rad: f64,
    /// RMS true q current, A.
    pub rms_iq_a: f64,
    /// RMS of the q current the outer loops commanded on top of the feedforward, A.
    pub rms_feedback_current_a: f64,
    /// Faults of the drive and (after its first tick) the compensator.
    pub faults: FaultFlags,
    /// Compensator ticks by feedforward source: zero, model, model + LSTM.
    pub source_ticks: [u64; 3],
    /// Compensator ticks outside the training envelope (`ENVELOPE_OUTSIDE`: the learned
    /// share faded).
    pub outside_envelope_ticks: u64,
    /// Compensator ticks whose do-no-harm monitor held the compensation's gain below 1
    /// (`COMPENSATION_FADED`).
    pub faded_ticks: u64,
    /// Mean of the do-no-harm monitor's gain over the compensator's ticks (1 with the
    /// monitor off or without a compensator).
    pub mean_monitor_gain: f64,
    /// Smallest do-no-harm monitor gain of any tick (1 with the monitor off).
    pub min_monitor_gain: f64,
    /// The joint the board was configured for, or why its block was refused.
    pub startup: Result<JointSlot, JointConfigFault>,
    /// PWM periods simulated.
    pub pwm_ticks: u64,
}

/// Runs `joints` on `mechanism` for `duration_s` from rest at `q0_rad`: each PWM
/// period every joint's [`SimulatedJoint::step_joint`] (the compensators at
/// `compensator_hz`, their frames delivered one tick later by a [`StateBus`]), then
/// the motors and the mechanics integrated over the period's substeps. `reference(t)`
/// gives each joint's (q rad, qd rad/s, qdd rad/s^2) at time `t` s.
pub fn run_joints<const J: usize, M, L>(
    joints: &mut [SimulatedJoint<J, M, L>],
    mechanism: &mut impl Mechanism<J>,
    reference: impl Fn(f64) -> [(f64, f64, f64); J],
    compensator_hz: u32,
    duration_s: f64,
) -> anyhow::Result<Vec<JointRun>>
where
    M: TorquePredictor<J>,
    L: TorquePredictor<J>,
{
    let mut bus = StateBus::default();
    run_joints_on(
        joints,
        mechanism,
        reference,
        compensator_hz,
        duration_s,
        &mut bus,
    )
}

/// [`run_joints`] on the state bus `bus` (one that records: the run's frames in the
/// drive's output format, [`StateBus::recording`]).
pub fn run_joints_on<const J: usize, M, L>(
    joints: &mut [SimulatedJoint<J, M, L>],
    mechanism: &mut impl Mechanism<J>,
    reference: impl Fn(f64) -> [(f64, f64, f64); J],
    compensator_hz: u32,
    duration_s: f64,
    bus: &mut StateBus,
) -> anyhow::Result<Vec<JointRun>>
where
    M: TorquePredictor<J>,
    L: TorquePredictor<J>,
{
    anyhow::ensure!(joints.len() == J, "{} joints for {J} slots", joints.len());
    let pwm_hz = joints[0].plant.pwm_hz;
    let substeps = joints[0].plant.substeps.max(1);
    anyhow::ensure!(
        joints
            .iter()
            .all(|j| j.plant.pwm_hz == pwm_hz && j.plant.substeps.max(1) == substeps),
        "all joints need one PWM rate and step count"
    );
    anyhow::ensure!(
        pwm_hz.is_finite() && pwm_hz > 0.0 && compensator_hz > 0,
        "PWM rate {pwm_hz} Hz, compensator {compensator_hz} Hz"
    );
    let comp_every = (pwm_hz / f64::from(compensator_hz)).round().max(1.0) as u64;
    let period_s = comp_every as f64 / pwm_hz;
    let n = (duration_s * pwm_hz).floor() as u64;
    let dt = 1.0 / (pwm_hz * substeps as f64);
    let reflected: [f64; J] =
        std::array::from_fn(|j| joints[j].plant.reflected_rotor_inertia_kg_m2());
    let r0 = reference(0.0);
    let mut q: [f64; J] = r0.map(|r| r.0);
    let mut qd: [f64; J] = r0.map(|r| r.1);
    let (mut se, mut max_e, mut siq, mut sfb) = ([0.0f64; J], [0.0f64; J], [0.0; J], [0.0; J]);
    let mut faults = [FaultFlags::NONE; J];
    let mut sources = [[0u64; 3]; J];
    let mut outside = [0u64; J];
    let mut faded = [0u64; J];
    let (mut gain_sum, mut gain_ticks, mut gain_min) = ([0.0f64; J], [0u64; J], [1.0f64; J]);
    let mut t = 0.0f64;
    for k in 0..n {
        let t_tick = k as f64 / pwm_hz;
        let ticks: Option<[CompensatorTick; J]> = if k % comp_every == 0 {
            for msg in bus.deliver()? {
                for j in joints.iter_mut() {
                    j.receive(&msg);
                }
            }
            // The feedforward is held for one period: it is computed for the period's
            // middle (the reference is known ahead).
            let t_mid = t_tick + 0.5 * period_s;
            let (now, next) = (reference(t_mid), reference(t_mid + period_s));
            Some(std::array::from_fn(|j| CompensatorTick {
                now_us: (t_tick * 1e6) as u32,
                reference: now[j],
                next_reference: next[j],
                first: k == 0,
            }))
        } else {
            None
        };
        let r = reference(t_tick);
        for (j, joint) in joints.iter_mut().enumerate() {
            let step = joint.step_joint(
                ticks.as_ref().map(|t| &t[j]),
                &JointReference {
                    q_rad: r[j].0 as f32,
                    qd_rad_s: r[j].1 as f32,
                    qdd_rad_s2: r[j].2 as f32,
                },
                q[j],
                bus,
            );
            faults[j] |= step.faults;
            if step.source.is_some() && step.faults.contains(FaultFlags::ENVELOPE_OUTSIDE) {
                outside[j] += 1;
            }
            if step.source.is_some() && step.faults.contains(FaultFlags::COMPENSATION_FADED) {
                faded[j] += 1;
            }
            if let Some(g) = step.monitor_gain {
                gain_sum[j] += f64::from(g);
                gain_ticks[j] += 1;
                gain_min[j] = gain_min[j].min(f64::from(g));
            }
            if let Some(s) = step.source {
                sources[j][match s {
                    FeedforwardSource::Zero => 0,
                    FeedforwardSource::Model => 1,
                    FeedforwardSource::ModelLstm => 2,
                }] += 1;
            }
            sfb[j] += f64::from(step.drive.iq_ref_a - step.feedforward_a).powi(2);
        }
        mechanism.begin_period(t, &q, &qd, &reflected)?;
        for _ in 0..substeps {
            let mut tau = [0.0f64; J];
            for (j, joint) in joints.iter_mut().enumerate() {
                tau[j] = joint.motor_substep(q[j], qd[j], dt);
            }
            let qdd = mechanism.accelerations(t, &q, &qd, &tau, &reflected, dt)?;
            for j in 0..J {
                // Semi-implicit Euler: velocity first, then position.
                qd[j] += qdd[j] * dt;
                q[j] += qd[j] * dt;
            }
            t += dt;
        }
        let iq: [f64; J] = std::array::from_fn(|j| joints[j].iq_a(q[j]));
        mechanism.end_period(&iq, 1.0 / pwm_hz);
        let r_end = reference((k + 1) as f64 / pwm_hz);
        for j in 0..J {
            let e = r_end[j].0 - q[j];
            se[j] += e * e;
            max_e[j] = max_e[j].max(e.abs());
            siq[j] += iq[j] * iq[j];
        }
    }
    let nf = n.max(1) as f64;
    Ok((0..J)
        .map(|j| JointRun {
            rms_error_rad: (se[j] / nf).sqrt(),
            max_error_rad: max_e[j],
            rms_iq_a: (siq[j] / nf).sqrt(),
            rms_feedback_current_a: (sfb[j] / nf).sqrt(),
            faults: faults[j],
            source_ticks: sources[j],
            outside_envelope_ticks: outside[j],
            faded_ticks: faded[j],
            mean_monitor_gain: if gain_ticks[j] > 0 {
                gain_sum[j] / gain_ticks[j] as f64
            } else {
                1.0
            },
            min_monitor_gain: gain_min[j],
            startup: joints[j].startup,
            pwm_ticks: n,
        })
        .collect())
}
