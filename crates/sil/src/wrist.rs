//! The paper's wrist in the loop: joints 4-6 of the default robot moving, 1-3 locked at
//! 0. The true plant is the plant simulator's: the arm's coupled rigid-body
//! dynamics (forward, through its inverse dynamics) plus, per joint, the drive's true
//! friction (Stribeck, LuGre presliding, load-dependent, thermal drift) and ripple
//! through [`plant_sim::drive::drive_torque_step`] (the same function the simulator
//! steps), the reflected rotor inertia in the mass matrix; per joint a motor (R, L,
//! back-EMF, Kt, gear: the joint's drive profile) driven through PWM duties, a
//! quantised encoder and noisy, quantised current sensing ([`super::plant`]). One
//! simulated board per joint ([`super::joint`]): its configuration block through the
//! firmware's start-up against the image's joints and profiles, then a firmware
//! `JointDrive` + `Compensator<3, _, _>`; each compensator receives the other joints'
//! states as `JointStateMessage` wire frames one compensator tick late.
//!
//! Feedforward ([`WristFeedforward`]): none, the identified model (the firmware's f32
//! `RigidBodyModel` built by `dynamics::firmware_model`), or model + LSTM in f32 or
//! int16 (the firmware kernels through `firmware::control::LstmPredictor`, networks
//! arranged/quantised at run time by `fw_export`).

use super::joint::{
    BOARD_PWM_HZ, Mechanism, SimulatedHardware, SimulatedJoint, config_block_of_index,
    run_joints_on,
};
use super::plant::JointPlantConfig;
use crate::StateBus;
use anyhow::{Context, bail, ensure};
use compnet::data::FeatureSpec;
use compnet::model::LstmModel;
use firmware::control::{
    JointConfigBlock, JointProfile, LstmPredictor, NoPredictor, TorqueNetwork, TorquePredictor,
};
use firmware::dynamics::RigidBodyModel;
use firmware::envelope::JointEnvelope;
use firmware::features::{DRIVE_INPUTS_PER_JOINT, FRICTION_FEATURES};
use firmware::nn::format::{FeaturePreset, I16Weights};
use fw_export::{F32Net, QuantNet};
use nalgebra::{Matrix3, Vector3};
use plant_sim::{CommandedTrajectory, DriveState, PlantEffects, PlantParameters};

/// The wrist's robot joints (0-based): the paper's joints 4, 5, 6.
pub const WRIST_JOINTS: [usize; 3] = [3, 4, 5];
/// Joints of the wrist.
pub const J: usize = 3;

/// Which feedforward the three compensators give.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WristFeedforward {
    /// None: the cascade alone.
    None,
    /// The identified model only.
    Model,
    /// Model + LSTM, f32 kernels.
    ModelLstmF32,
    /// Model + LSTM, int16 kernels.
    ModelLstmInt16,
}

impl WristFeedforward {
    /// All four, in table order.
    pub const ALL: [WristFeedforward; 4] = [
        WristFeedforward::None,
        WristFeedforward::Model,
        WristFeedforward::ModelLstmF32,
        WristFeedforward::ModelLstmInt16,
    ];

    /// Label in the tables.
    pub fn name(self) -> &'static str {
        match self {
            WristFeedforward::None => "none",
            WristFeedforward::Model => "model",
            WristFeedforward::ModelLstmF32 => "model + LSTM f32",
            WristFeedforward::ModelLstmInt16 => "model + LSTM int16",
        }
    }
}

/// A network of run-time sizes (built from a trained model) stepped by the firmware's
/// kernels through their shape-erased views (`F32View::step`, `QuantView::step`, the
/// functions the fixed-size firmware networks call).
pub enum HostNetwork {
    /// f32.
    F32(F32Net),
    /// int16 weights.
    Int16(QuantNet<I16Weights>),
}

/// The recurrent state and scratch of a [`HostNetwork`].
pub enum HostState {
    /// f32: `z`, `c`, normalised input, gate accumulators.
    F32(Vec<f32>, Vec<f32>, Vec<f32>, Vec<[f32; 4]>),
    /// int16: `z`, `c`, quantised input, new `h`, gate accumulators.
    Int16(
        Vec<[u32; 2]>,
        Vec<i16>,
        Vec<[u32; 2]>,
        Vec<[u32; 2]>,
        Vec<[i32; 4]>,
    ),
}

impl<const I: usize, const O: usize> TorqueNetwork<I, O> for HostNetwork {
    type State = HostState;
    fn zero_state(&self) -> HostState {
        match self {
            HostNetwork::F32(n) => {
                let d = n.dims;
                HostState::F32(
                    vec![0.0; 4 * d.embed_blocks + d.hidden],
                    vec![0.0; d.hidden],
                    vec![0.0; d.input],
                    vec![[0.0; 4]; d.hidden],
                )
            }
            HostNetwork::Int16(n) => {
                let d = n.dims;
                HostState::Int16(
                    vec![[0; 2]; d.z_quads()],
                    vec![0; d.hidden],
                    vec![[0; 2]; d.input_quads],
                    vec![[0; 2]; d.hidden / 4],
                    vec![[0; 4]; d.hidden],
                )
            }
        }
    }
    fn step(&self, state: &mut HostState, input: &[f32; I]) -> [f32; O] {
        let mut y = [f32::NAN; O];
        match (self, state) {
            (HostNetwork::F32(n), HostState::F32(z, c, xn, acc))
                if n.dims.input == I && n.dims.output == O =>
            {
                n.view().step(z, c, xn, acc, input, &mut y);
            }
            (HostNetwork::Int16(n), HostState::Int16(z, c, xq, hn, acc))
                if n.dims.input == I && n.dims.output == O =>
            {
                n.view().step(z, c, xq, hn, acc, input, &mut y);
            }
            _ => {}
        }
        y
    }
}

/// A trained LSTM checked against the wrist's feature layout.
pub struct WristLstm {
    /// The model.
    pub model: LstmModel,
    /// Its preset (`Paper` or `Feedforward`).
    pub preset: FeaturePreset,
}

impl WristLstm {
    /// Reads a trained model (safetensors, or a directory holding exactly one) and
    /// checks that it is a `paper` or `feedforward` network of joints 4, 5, 6.
    pub fn load(path: &std::path::Path) -> anyhow::Result<Self> {
        let file = if path.is_dir() {
            let found: Vec<_> = std::fs::read_dir(path)
                .with_context(|| format!("{}: cannot list", path.display()))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|e| e == "safetensors"))
                .collect();
            ensure!(
                found.len() == 1,
                "{}: {} .safetensors files, need exactly one",
                path.display(),
                found.len()
            );
            found[0].clone()
        } else {
            path.to_path_buf()
        };
        let model = compnet::io::read_model(&file)?;
        let numbers = WRIST_JOINTS.map(|j| j + 1);
        let preset = match FeaturePreset::from_name(&model.preset) {
            Some(p) if p != FeaturePreset::Custom => p,
            _ => bail!(
                "{}: preset `{}`; the SIL runs `paper`, `paper_relative`, `feedforward` or \
                 `drive` networks",
                file.display(),
                model.preset
            ),
        };
        let spec = FeatureSpec::for_preset(&model.preset, &numbers)
            .context("every SIL preset has a feature spec")?;
        // Same inputs and outputs (for `paper`: the increment over the measured torque
        // that the firmware's predictor adds back) as the wrist's preset.
        spec.check_model(&model)
            .with_context(|| format!("{} (train with --joints 4,5,6)", file.display()))?;
        Ok(Self { model, preset })
    }

    /// The network in `precision` (f32: arranged; int16: quantised), as the firmware
    /// kernels take it.
    pub fn network(&self, int16: bool) -> anyhow::Result<HostNetwork> {
        Ok(if int16 {
            HostNetwork::Int16(QuantNet::quantise(&self.model)?)
        } else {
            HostNetwork::F32(F32Net::arrange(&self.model)?)
        })
    }
}

/// Everything a wrist run needs: the true plant, the image's joints and profiles, each
/// board's configuration block and what only the simulation has.
#[derive(Clone, Debug)]
pub struct WristSetup {
    /// Rigid body of the arm (all joints).
    pub robot: robot::Robot,
    /// True drives and sensors (the plant simulator's parameters).
    pub plant: PlantParameters,
    /// Effects of the true plant (sensing effects are the SIL's own sensor models).
    pub effects: PlantEffects,
    /// The reference of joints 4-6.
    pub trajectory: CommandedTrajectory,
    /// Simulated seconds (at most the trajectory's duration).
    pub duration_s: f64,
    /// The compensated joints of the image (0-based robot joints, a model file's
    /// `JOINT_INDICES`).
    pub joint_indices: [usize; J],
    /// Their drive profiles (a model file's `JOINT_PROFILES`); simulated joint `k` is
    /// robot joint `WRIST_JOINTS[k]`, its motor and gear those of `profiles[k]`.
    pub profiles: [JointProfile; J],
    /// Each simulated board's configuration block (encoded).
    pub config_blocks: [[u8; JointConfigBlock::LEN]; J],
    /// Per joint: what only the simulation has (rotor inertia, bus, sensors, seed).
    pub hardware: [SimulatedHardware; J],
    /// Compensator rate, Hz.
    pub compensator_hz: u32,
}

impl WristSetup {
    /// The wrist of `robot`: its joints 4-6 as the exporter writes them into a model
    /// file (each joint's drive profile from the description, the board's where it gives
    /// none), each board configured as its joint; the true plant's rotor inertia and
    /// current sensing (noise, ADC step) from `plant`, 48 V, the board's 20 kHz PWM,
    /// 14-bit encoder; compensator at `compensator_hz`.
    pub fn new(
        robot: robot::Robot,
        plant: PlantParameters,
        trajectory: CommandedTrajectory,
        compensator_hz: u32,
        seed: u64,
    ) -> anyhow::Result<Self> {
        ensure!(
            robot.dof() == 6 && plant.joints.len() == 6,
            "the wrist SIL needs a 6-joint robot and plant"
        );
        ensure!(
            trajectory.joint_count() == J,
            "the trajectory moves {} joints; the wrist needs 3",
            trajectory.joint_count()
        );
        let profiles = WRIST_JOINTS.map(|j| robot.joints[j].drive_profile());
        let hardware: [SimulatedHardware; J] = std::array::from_fn(|k| {
            let d = &plant.joints[WRIST_JOINTS[k]];
            SimulatedHardware {
                rotor_inertia_kg_m2: d.rotor_inertia_kgm2,
                bus_v: 48.0,
                pwm_hz: BOARD_PWM_HZ,
                substeps: 10,
                encoder_bits: 14,
                current_noise_a: plant.sensor.current_noise_a,
                current_lsb_a: 2.0 * d.adc_full_scale_a / (1u64 << plant.sensor.adc_bits) as f64,
                bus_noise_v: 0.1,
                seed: seed.wrapping_mul(31).wrapping_add(k as u64),
            }
        });
        let duration_s = trajectory.duration_s();
        Ok(Self {
            robot,
            plant,
            effects: PlantEffects::all(),
            trajectory,
            duration_s,
            joint_indices: WRIST_JOINTS,
            profiles,
            config_blocks: WRIST_JOINTS.map(config_block_of_index),
            hardware,
            compensator_hz,
        })
    }

    /// Simulated joint `k`'s motor, gear and sensors.
    pub fn motor(&self, k: usize) -> JointPlantConfig {
        JointPlantConfig::from_profile(&self.profiles[k], &self.hardware[k])
    }
}

/// Per-joint results of a wrist run.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct WristJointReport {
    /// Robot joint (1-based).
    pub joint: usize,
    /// RMS position-tracking error (reference - true position), rad.
    pub rms_error_rad: f64,
    /// Largest |tracking error|, rad.
    pub max_error_rad: f64,
    /// RMS true q current, A.
    pub rms_iq_a: f64,
    /// Faults of the drive and (after its first tick) the compensator, as bits.
    pub fault_bits: u32,
    /// Compensator ticks by feedforward source: zero, model, model + LSTM (a board
    /// whose configuration block was refused counts every tick as zero).
    pub source_ticks: [u64; 3],
    /// Share of the compensator ticks outside the training envelope (the learned share
    /// faded, `ENVELOPE_OUTSIDE`).
    #[serde(default)]
    pub outside_envelope_share: f64,
    /// Share of the compensator ticks whose do-no-harm monitor held the compensation's
    /// gain below 1 (`COMPENSATION_FADED`; 0 with the monitor off).
    #[serde(default)]
    pub faded_share: f64,
    /// Mean of the do-no-harm monitor's gain on the compensation beyond the model over
    /// the compensator ticks (1: full compensation throughout, or the monitor off).
    #[serde(default = "full_gain")]
    pub mean_monitor_gain: f64,
    /// Smallest monitor gain of any tick.
    #[serde(default = "full_gain")]
    pub min_monitor_gain: f64,
    /// Why the board's configuration block was refused (it then runs without
    /// feedforward and sends no state frames); absent when it was accepted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub startup_fault: Option<String>,
}

/// A monitor gain of 1 (reports written before the monitor gain was recorded).
fn full_gain() -> f64 {
    1.0
}

/// The true wrist: arm rigid body (f64 Newton-Euler of the robot file) and the
/// drives' friction, ripple and temperature (the plant simulator's).
struct TrueWrist<'a> {
    arm: plant_sim::RobotRigidBody,
    effects: PlantEffects,
    drives: [&'a plant_sim::JointDrive; J],
    states: [DriveState; J],
    ambient_c: f64,
    /// Held over a PWM period: link mass matrix, rigid bias, inverse of the mass
    /// matrix with the rotors.
    m_links: Matrix3<f64>,
    h_rigid: [f64; J],
    m_inv: Matrix3<f64>,
    /// Accelerations of the last step (the torque the links transmit).
    qdd: [f64; J],
    /// Friction power x time over the period, J.
    friction_energy_j: [f64; J],
}

impl TrueWrist<'_> {
    fn rigid(&self, q: &[f64; J], qd: &[f64; J], qdd: &[f64; J]) -> [f64; J] {
        use plant_sim::RigidBodyModel as _;
        let mut fq = [0.0; 6];
        let mut fqd = [0.0; 6];
        let mut fqdd = [0.0; 6];
        for (k, &j) in WRIST_JOINTS.iter().enumerate() {
            fq[j] = q[k];
            fqd[j] = qd[k];
            fqdd[j] = qdd[k];
        }
        let mut tau = [0.0; 6];
        self.arm.inverse_dynamics(&fq, &fqd, &fqdd, &mut tau);
        WRIST_JOINTS.map(|j| tau[j])
    }

    /// Mass matrix of the wrist joints (links only) and the rigid bias h(q, qd).
    fn mass_and_bias(&self, q: &[f64; J], qd: &[f64; J]) -> (Matrix3<f64>, [f64; J]) {
        let g = self.rigid(q, &[0.0; J], &[0.0; J]);
        let mut m = Matrix3::zeros();
        for c in 0..J {
            let mut e = [0.0; J];
            e[c] = 1.0;
            let t = self.rigid(q, &[0.0; J], &e);
            for r in 0..J {
                m[(r, c)] = t[r] - g[r];
            }
        }
        (m, self.rigid(q, qd, &[0.0; J]))
    }
}

impl Mechanism<J> for TrueWrist<'_> {
    /// Mass matrix (links + reflected rotors) and rigid bias held over the PWM period.
    fn begin_period(
        &mut self,
        t_s: f64,
        q: &[f64; J],
        qd: &[f64; J],
        reflected: &[f64; J],
    ) -> anyhow::Result<()> {
        let (m_links, h_rigid) = self.mass_and_bias(q, qd);
        let mut mm = m_links;
        for j in 0..J {
            mm[(j, j)] += reflected[j];
        }
        self.m_inv = mm
            .try_inverse()
            .ok_or_else(|| anyhow::anyhow!("singular mass matrix at t = {t_s}"))?;
        self.m_links = m_links;
        self.h_rigid = h_rigid;
        self.friction_energy_j = [0.0; J];
        Ok(())
    }

    /// Friction and ripple every step (`plant_sim::drive::drive_torque_step`).
    fn accelerations(
        &mut self,
        _t_s: f64,
        q: &[f64; J],
        qd: &[f64; J],
        tau: &[f64; J],
        _reflected: &[f64; J],
        dt_s: f64,
    ) -> anyhow::Result<[f64; J]> {
        let transmitted = self.m_links * Vector3::from(self.qdd);
        let mut rhs = Vector3::zeros();
        for j in 0..J {
            let d = plant_sim::drive::drive_torque_step(
                self.drives[j],
                &self.effects,
                &mut self.states[j],
                q[j],
                qd[j],
                0.0,
                transmitted[j] + self.h_rigid[j],
                self.ambient_c,
                dt_s,
            );
            self.friction_energy_j[j] += d.friction_nm * qd[j] * dt_s;
            rhs[j] = tau[j] - self.h_rigid[j] - d.total_nm();
        }
        let a = self.m_inv * rhs;
        self.qdd = [a[0], a[1], a[2]];
        Ok(self.qdd)
    }

    /// The drives' temperature (`plant_sim::drive::thermal_step`).
    fn end_period(&mut self, iq_a: &[f64; J], period_s: f64) {
        if self.effects.thermal {
            for (j, &iq) in iq_a.iter().enumerate() {
                plant_sim::drive::thermal_step(
                    self.drives[j],
                    &mut self.states[j],
                    iq,
                    self.friction_energy_j[j] / period_s,
                    self.ambient_c,
                    period_s,
                );
            }
        }
    }
}

fn reference(traj: &CommandedTrajectory, t: f64) -> [(f64, f64, f64); J] {
    let (mut q, mut qd, mut qdd) = ([0.0; J], [0.0; J], [0.0; J]);
    traj.eval_into(t, &mut q, &mut qd, &mut qdd);
    std::array::from_fn(|k| (q[k], qd[k], qdd[k]))
}

/// Run the wrist with the model and LSTM stages `make(slot)` gives the compensator of
/// each board its configuration block names (`slot`: its index among the image's
/// joints).
pub fn run_wrist_with<M, L>(
    setup: &WristSetup,
    make: impl FnMut(usize) -> anyhow::Result<(M, L)>,
) -> anyhow::Result<[WristJointReport; J]>
where
    M: TorquePredictor<J>,
    L: TorquePredictor<J>,
{
    run_wrist_with_on(setup, make, &mut StateBus::default())
}

/// [`run_wrist_with`] on the state bus `bus` (a recording one keeps the run's frames
/// in the drive's output format).
pub fn run_wrist_with_on<M, L>(
    setup: &WristSetup,
    mut make: impl FnMut(usize) -> anyhow::Result<(M, L)>,
    bus: &mut StateBus,
) -> anyhow::Result<[WristJointReport; J]>
where
    M: TorquePredictor<J>,
    L: TorquePredictor<J>,
{
    let r0 = reference(&setup.trajectory, 0.0);
    let mut joints = Vec::with_capacity(J);
    for (k, r) in r0.iter().enumerate() {
        joints.push(SimulatedJoint::<J, M, L>::start(
            &setup.config_blocks[k],
            &setup.joint_indices,
            &setup.profiles,
            setup.compensator_hz,
            setup.motor(k),
            r.0,
            &mut make,
        )?);
    }
    let mut plant = TrueWrist {
        arm: plant_sim::RobotRigidBody::new(&setup.robot),
        effects: PlantEffects {
            rotor_inertia: false, // in the mass matrix instead
            ..setup.effects
        },
        drives: WRIST_JOINTS.map(|j| &setup.plant.joints[j]),
        states: [DriveState::at_rest(setup.plant.ambient_temperature_c); J],
        ambient_c: setup.plant.ambient_temperature_c,
        m_links: Matrix3::zeros(),
        h_rigid: [0.0; J],
        m_inv: Matrix3::zeros(),
        qdd: [0.0; J],
        friction_energy_j: [0.0; J],
    };
    let runs = run_joints_on(
        &mut joints,
        &mut plant,
        |t| reference(&setup.trajectory, t),
        setup.compensator_hz,
        setup.duration_s.min(setup.trajectory.duration_s()),
        bus,
    )?;
    Ok(std::array::from_fn(|k| WristJointReport {
        joint: WRIST_JOINTS[k] + 1,
        rms_error_rad: runs[k].rms_error_rad,
        max_error_rad: runs[k].max_error_rad,
        rms_iq_a: runs[k].rms_iq_a,
        fault_bits: runs[k].faults.bits(),
        source_ticks: runs[k].source_ticks,
        outside_envelope_share: runs[k].outside_envelope_ticks as f64
            / runs[k].source_ticks.iter().sum::<u64>().max(1) as f64,
        faded_share: runs[k].faded_ticks as f64
            / runs[k].source_ticks.iter().sum::<u64>().max(1) as f64,
        mean_monitor_gain: runs[k].mean_monitor_gain,
        min_monitor_gain: runs[k].min_monitor_gain,
        startup_fault: runs[k].startup.err().map(|f| format!("{f:?}")),
    }))
}

/// Builds the firmware's f32 model of the wrist from an identified model file (JSON
/// from `identify`; its locked joints must be 1-3 at 0) for the robot description `source`.
pub fn identified_wrist_model(
    source: &robot::RobotSource,
    model: &std::path::Path,
    chain: &robot::ChainSelection,
) -> anyhow::Result<RigidBodyModel<J>> {
    let selection = identify::identified::ModelSelection {
        chain: chain.clone(),
        ..Default::default()
    };
    let identify::identified::IdentifiedRobot {
        robot: r,
        standard_parameters: theta,
        ..
    } = identify::identified::load_model_robot(source, Some(model), &selection)?;
    ensure!(
        r.modelled_joints() == WRIST_JOINTS.to_vec(),
        "{}: models joints {:?} (0-based); the wrist SIL needs 3, 4, 5 (identify with --lock 1=0,2=0,3=0)",
        model.display(),
        r.modelled_joints()
    );
    for (i, j) in r.joints.iter().enumerate() {
        if let robot::JointMode::Locked { q_rad } = j.mode {
            ensure!(
                q_rad == 0.0,
                "{}: joint {} locked at {q_rad} rad; the wrist SIL holds it at 0",
                model.display(),
                i + 1
            );
        }
    }
    Ok(robot::dynamics::firmware_model::build_firmware_model::<J>(
        &r, &theta,
    )?)
}

/// Run one feedforward mode. `model` is needed for every mode but `None`, `lstm` for
/// the LSTM modes.
pub fn run_wrist(
    setup: &WristSetup,
    mode: WristFeedforward,
    model: Option<&RigidBodyModel<J>>,
    lstm: Option<&WristLstm>,
) -> anyhow::Result<[WristJointReport; J]> {
    run_wrist_on(setup, mode, model, lstm, &mut StateBus::default())
}

/// [`run_wrist`] on the state bus `bus` (a recording one keeps the run's frames in
/// the drive's output format: `sil --candump`).
pub fn run_wrist_on(
    setup: &WristSetup,
    mode: WristFeedforward,
    model: Option<&RigidBodyModel<J>>,
    lstm: Option<&WristLstm>,
    bus: &mut StateBus,
) -> anyhow::Result<[WristJointReport; J]> {
    let need_model = || model.copied().context("this feedforward needs --model");
    match mode {
        WristFeedforward::None => run_wrist_with_on(setup, |_| Ok((NoPredictor, NoPredictor)), bus),
        WristFeedforward::Model => {
            let m = need_model()?;
            run_wrist_with_on(setup, |_| Ok((m, NoPredictor)), bus)
        }
        WristFeedforward::ModelLstmF32 | WristFeedforward::ModelLstmInt16 => {
            let m = need_model()?;
            let l = lstm.context("this feedforward needs --lstm")?;
            let net = l.network(mode == WristFeedforward::ModelLstmInt16)?;
            let preset = l.preset;
            let layout = "the network does not take its preset's feature layout";
            // The network's training envelope (unbounded where it carries none).
            let envelope: [JointEnvelope; J] = std::array::from_fn(|k| {
                l.model
                    .envelope
                    .get(k)
                    .copied()
                    .unwrap_or(JointEnvelope::UNBOUNDED)
            });
            if preset == FeaturePreset::Drive {
                let mut linear = [[0.0; FRICTION_FEATURES]; J];
                for (row, w) in linear
                    .iter_mut()
                    .zip(l.model.linear.chunks_exact(FRICTION_FEATURES))
                {
                    row.copy_from_slice(w);
                }
                run_wrist_with_on(
                    setup,
                    |_| {
                        let p = LstmPredictor::<_, J, { DRIVE_INPUTS_PER_JOINT * J }>::new(
                            &net, preset,
                        )
                        .context(layout)?
                        .with_linear_stage(linear)
                        .with_envelope(envelope);
                        Ok((m, p))
                    },
                    bus,
                )
            } else {
                run_wrist_with_on(
                    setup,
                    |_| {
                        let p = LstmPredictor::<_, J, { 3 * J }>::new(&net, preset)
                            .context(layout)?
                            .with_envelope(envelope);
                        Ok((m, p))
                    },
                    bus,
                )
            }
        }
    }
}

/// One mode's results.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct ModeReport {
    /// Feedforward.
    pub feedforward: String,
    /// Per joint.
    pub joints: Vec<WristJointReport>,
}

/// `sil --json`: the wrist runs and their setup.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct WristReport {
    /// One line describing the setup.
    pub title: String,
    /// Simulated time [s].
    pub duration_s: f64,
    /// Compensator rate [Hz].
    pub compensator_hz: f64,
    /// Seed of the sensor noise.
    pub seed: u64,
    /// One per feedforward mode.
    pub results: Vec<ModeReport>,
}

/// The Markdown table of a set of runs (with the LSTM rows' change against model only).
pub fn markdown_table(reports: &[ModeReport]) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "| feedforward | joint | RMS error [mrad] | max error [mrad] | RMS iq [A] | vs model: error | vs model: iq | ticks zero/model/LSTM | outside envelope | monitor gain mean / min | faults |"
    );
    let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|---:|---|---:|---:|---|");
    let model = reports.iter().find(|r| r.feedforward == "model");
    for r in reports {
        for (k, j) in r.joints.iter().enumerate() {
            let (de, di) = match (model, r.feedforward.contains("LSTM")) {
                (Some(m), true) => (
                    format!(
                        "{:+.1} %",
                        100.0 * (j.rms_error_rad / m.joints[k].rms_error_rad - 1.0)
                    ),
                    format!(
                        "{:+.1} %",
                        100.0 * (j.rms_iq_a / m.joints[k].rms_iq_a - 1.0)
                    ),
                ),
                _ => (String::new(), String::new()),
            };
            let _ = writeln!(
                s,
                "| {} | {} | {:.4} | {:.4} | {:.4} | {de} | {di} | {}/{}/{} | {:.1} % | {:.3} / {:.3} | {:#06x} |",
                r.feedforward,
                j.joint,
                j.rms_error_rad * 1e3,
                j.max_error_rad * 1e3,
                j.rms_iq_a,
                j.source_ticks[0],
                j.source_ticks[1],
                j.source_ticks[2],
                100.0 * j.outside_envelope_share,
                j.mean_monitor_gain,
                j.min_monitor_gain,
                j.fault_bits
            );
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::joint::config_block;
    use firmware::control::{FaultFlags, JointConfigFault, SubsetModel};
    use firmware::model::default as compiled;

    /// The compiled-in model as an image: its compensated joints and profiles on the
    /// wrist, every board's compensator built from its dynamics and network as the
    /// board builds them.
    fn image_setup(seconds: f64) -> WristSetup {
        let robot = robot::RobotSource::BuiltIn.load().unwrap();
        let traj = plant_sim::trajectory::trajectory_or_seeded(None, 1, 2, J).unwrap();
        let mut s = WristSetup::new(
            robot,
            PlantParameters::default_robot(),
            traj,
            compiled::CONTROL_RATE_HZ,
            3,
        )
        .unwrap();
        s.joint_indices = compiled::JOINT_INDICES;
        s.profiles = compiled::JOINT_PROFILES;
        s.duration_s = seconds;
        s
    }

    fn run_image(s: &WristSetup) -> [WristJointReport; J] {
        let model_joints =
            firmware::model::dynamics_indices(compiled::JOINT_INDICES, compiled::DYNAMICS_JOINTS);
        run_wrist_with(s, |_slot| {
            let model = SubsetModel {
                model: &compiled::DYNAMICS,
                joints: model_joints,
                fixed_q_rad: [0.0; compiled::DYNAMICS_JOINTS],
            };
            let lstm = LstmPredictor::<_, J, { compiled::INPUTS }>::new(
                &compiled::NETWORK,
                compiled::FEATURE_PRESET,
            )
            .context("the compiled-in network takes its preset's layout")?
            .with_linear_stage(compiled::LINEAR_STAGE)
            .with_envelope(compiled::ENVELOPE);
            Ok((model, lstm))
        })
        .unwrap()
    }

    #[test]
    fn the_default_robots_wrist_runs_the_compiled_in_profiles() {
        let robot = robot::RobotSource::BuiltIn.load().unwrap();
        let traj = plant_sim::trajectory::trajectory_or_seeded(None, 1, 2, J).unwrap();
        let s = WristSetup::new(robot, PlantParameters::default_robot(), traj, 100, 3).unwrap();
        assert_eq!(s.joint_indices, compiled::JOINT_INDICES);
        assert_eq!(s.profiles, compiled::JOINT_PROFILES);
        // The simulated motor and gear are the ones the drive is configured for.
        for k in 0..J {
            let m = s.motor(k);
            let p = &s.profiles[k];
            assert_eq!(m.motor(), p.motor);
            assert_eq!(m.gear_ratio, f64::from(p.gear_ratio));
            assert_eq!(m.encoder_offset_rad, f64::from(p.encoder_offset_rad));
        }
    }

    #[test]
    fn one_image_runs_as_joint_4_5_or_6_by_its_configuration_block() {
        let s = image_setup(0.4);
        // Three boards, one image: they differ only in their configuration blocks.
        assert_eq!(
            s.config_blocks,
            [4u8, 5, 6].map(|n| JointConfigBlock {
                joint_number: n,
                bus_key: crate::joint::SIL_BUS_KEY
            }
            .encode())
        );
        let r = run_image(&s);
        let bus =
            FaultFlags::STATE_STALE | FaultFlags::STATE_REJECTED | FaultFlags::STATE_OUT_OF_ORDER;
        for (k, j) in r.iter().enumerate() {
            println!("{j:?}");
            assert_eq!(j.startup_fault, None);
            assert_eq!(j.joint, 4 + k);
            // Every board sent as the joint its block names and heard the others:
            // after the first tick, model + LSTM on every tick.
            assert_eq!(j.source_ticks, [1, 0, 39], "{j:?}");
            assert!(
                !FaultFlags::from_bits(j.fault_bits).intersects(bus),
                "{j:?}"
            );
            assert!(j.rms_error_rad < 2e-3, "{j:?}");
        }
    }

    #[test]
    fn a_refused_block_runs_without_feedforward_and_reports_why() {
        for (block, fault) in [
            ([0xFF; JointConfigBlock::LEN], JointConfigFault::Erased),
            (config_block(2), JointConfigFault::JointNotCompensated(2)),
        ] {
            let mut s = image_setup(0.3);
            s.config_blocks[1] = block;
            let r = run_image(&s);
            for j in &r {
                println!("{j:?}");
            }
            // Joint 5's board: no compensator, the fault in its report, yet its drive
            // (the profile all three joints share) tracks.
            assert_eq!(r[1].startup_fault, Some(format!("{fault:?}")));
            assert_eq!(r[1].source_ticks, [30, 0, 0]);
            assert!(r[1].rms_error_rad < 2e-3, "{:?}", r[1]);
            // It sends no state frames: the others' watchdogs see joint 5 stale and
            // their feedforward falls back to zero, as on the board.
            for k in [0, 2] {
                assert_eq!(r[k].startup_fault, None);
                let f = FaultFlags::from_bits(r[k].fault_bits);
                assert!(f.contains(FaultFlags::STATE_STALE), "{:?}", r[k]);
                assert_eq!(r[k].source_ticks, [30, 0, 0], "{:?}", r[k]);
            }
        }
    }
}
