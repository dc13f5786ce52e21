//! The paper's wrist in the loop: joints 4-6 of the default robot moving, 1-3 locked at
//! 0. The true plant is the issue-4 plant simulator's: the arm's coupled rigid-body
//! dynamics (forward, through its inverse dynamics) plus, per joint, the drive's true
//! friction (Stribeck, LuGre presliding, load-dependent, thermal drift) and ripple
//! through [`plant_sim::drive::drive_torque_step`] (the same function the simulator
//! steps), the reflected rotor inertia in the mass matrix; per joint a motor (R, L,
//! back-EMF, Kt, gear) driven through PWM duties, a quantised encoder and noisy,
//! quantised current sensing ([`super::plant`]). One firmware `JointDrive` +
//! `Compensator<3, _, _>` per joint; each compensator receives the other joints'
//! states as `JointStateMessage` wire frames one compensator tick late.
//!
//! Feedforward ([`WristFeedforward`]): none, the identified model (the firmware's f32
//! `RigidBodyModel` built by `dynamics::firmware_model`), or model + LSTM in f32 or
//! int16 (the firmware kernels through `firmware::control::LstmPredictor`, networks
//! arranged/quantised at run time by `fw_export`).

use super::plant::{
    JointPlantConfig, motor_electrical_step, noise, phase_voltages, q_current_a, sense_joint,
};
use anyhow::{Context, bail, ensure};
use compnet::data::FeatureSpec;
use compnet::model::LstmModel;
use firmware::control::{
    BusClock, CascadeConfig, Compensator, CompensatorConfig, CurrentLoopConfig, DriveConfig,
    DriveOutput, FaultFlags, FeedforwardSource, JointDrive, JointReference, JointState,
    LstmPredictor, NoPredictor, SensorSample, StateLimits, TorqueNetwork, TorquePredictor,
};
use firmware::dynamics::RigidBodyModel;
use firmware::features::{DRIVE_INPUTS_PER_JOINT, FRICTION_FEATURES};
use firmware::nn::format::{FeaturePreset, I16Weights};
use fw_export::{F32Net, QuantNet};
use nalgebra::Matrix3;
use plant_sim::{CommandedTrajectory, DriveState, PlantEffects, PlantParameters};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::Normal;

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
    /// f32: `z`, `c`, normalised input, new `h`, gate accumulators.
    F32(Vec<f32>, Vec<f32>, Vec<f32>, Vec<f32>, Vec<[f32; 4]>),
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
                    vec![0.0; d.hidden],
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
            (HostNetwork::F32(n), HostState::F32(z, c, xn, hn, acc))
                if n.dims.input == I && n.dims.output == O =>
            {
                n.view().step(z, c, xn, hn, acc, input, &mut y);
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
        let preset = match model.preset.as_str() {
            "paper" => FeaturePreset::Paper,
            "feedforward" => FeaturePreset::Feedforward,
            "drive" => FeaturePreset::Drive,
            other => bail!(
                "{}: preset `{other}`; the SIL runs `paper`, `feedforward` or `drive` networks",
                file.display()
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

/// Everything a wrist run needs.
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
    /// Per-joint motor, gear and sensors.
    pub motors: [JointPlantConfig; J],
    /// Per-joint firmware drive.
    pub drives: [DriveConfig; J],
    /// Compensator configuration (`own_joint` set per joint).
    pub compensator: CompensatorConfig,
}

impl WristSetup {
    /// The default wrist: motors from the plant file (Kt, gear, rotor inertia, winding
    /// resistance, current ADC), 7 pole pairs and 0.5 mH (estimates), 48 V, 20 kHz PWM,
    /// 14-bit encoder, outer loops at 5 kHz, compensator at `compensator_hz`.
    pub fn new(
        robot: robot::Robot,
        plant: PlantParameters,
        trajectory: CommandedTrajectory,
        compensator_hz: f64,
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
        let pole_pairs = 7u8;
        let motors: [JointPlantConfig; J] = std::array::from_fn(|k| {
            let d = &plant.joints[WRIST_JOINTS[k]];
            JointPlantConfig {
                pole_pairs,
                phase_resistance_ohm: d.winding_resistance_ohm,
                phase_inductance_h: 5e-4,
                flux_linkage_wb: d.motor_torque_constant_nm_a / (1.5 * pole_pairs as f64),
                rotor_inertia_kg_m2: d.rotor_inertia_kgm2,
                gear_ratio: d.gear_ratio,
                gear_efficiency: 1.0,
                bus_v: 48.0,
                pwm_hz: 20_000.0,
                substeps: 10,
                encoder_bits: 14,
                encoder_offset_rad: 0.05,
                current_noise_a: plant.sensor.current_noise_a,
                current_lsb_a: 2.0 * d.adc_full_scale_a / (1u64 << plant.sensor.adc_bits) as f64,
                bus_noise_v: 0.1,
                seed: seed.wrapping_mul(31).wrapping_add(k as u64),
            }
        });
        let drives: [DriveConfig; J] = std::array::from_fn(|k| {
            let m = &motors[k];
            DriveConfig {
                current: CurrentLoopConfig::tuned(m.motor(), m.pwm_hz as f32),
                cascade: CascadeConfig {
                    rate_hz: 5000.0,
                    position_kp: 40.0,
                    position_ki: 0.0,
                    position_kd: 0.0,
                    max_velocity_rad_s: 4.0,
                    velocity_kp: 3.5,
                    velocity_ki: 120.0,
                    velocity_kd: 0.0,
                    max_current_a: 8.0,
                    velocity_filter_alpha: 0.3,
                },
                gear_ratio: m.gear_ratio as f32,
                encoder_offset_rad: m.encoder_offset_rad as f32,
                max_current_a: 8.0,
                overcurrent_trip_a: 9.5,
                bus_min_v: 36.0,
                bus_max_v: 56.0,
                max_abs_q_ref_rad: 6.3,
            }
        });
        let gain = plant.joints[WRIST_JOINTS[0]].drive_gain_nm_a();
        ensure!(
            WRIST_JOINTS
                .iter()
                .all(|&j| (plant.joints[j].drive_gain_nm_a() - gain).abs() < 1e-9),
            "the wrist drives need one drive gain (the compensator's)"
        );
        let compensator = CompensatorConfig {
            rate_hz: compensator_hz as f32,
            own_joint: 0,
            state_limits: StateLimits {
                max_abs_q_rad: 6.3,
                max_abs_qd_rad_s: 5.0,
                max_abs_qdd_rad_s2: 100.0,
                max_abs_tau_nm: 300.0,
            },
            watchdog_ticks: 3,
            max_message_age_us: (3.5e6 / compensator_hz) as u32,
            bus_clock: BusClock::Synchronised,
            max_torque_nm: 50.0,
            max_torque_rate_nm_s: 2_000.0,
            max_lstm_correction_nm: 10.0,
            warmup_ticks: 10,
            lstm_retry_ticks: 50,
            drive_gain_nm_per_a: gain as f32,
            max_current_a: 8.0,
        };
        let duration_s = trajectory.duration_s();
        Ok(Self {
            robot,
            plant,
            effects: PlantEffects::all(),
            trajectory,
            duration_s,
            motors,
            drives,
            compensator,
        })
    }
}

/// Per-joint results of a wrist run.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
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
    /// Compensator ticks by feedforward source: zero, model, model + LSTM.
    pub source_ticks: [u64; 3],
}

/// The true wrist: arm rigid body (f64 Newton-Euler of the robot file) and drives.
struct TrueWrist {
    arm: plant_sim::RobotRigidBody,
    effects: PlantEffects,
    states: [DriveState; J],
}

impl TrueWrist {
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

struct Motor {
    i_abc_a: [f64; 3],
    rng: ChaCha8Rng,
    current_noise: Normal<f64>,
    bus_noise: Normal<f64>,
}

fn reference(traj: &CommandedTrajectory, t: f64) -> [(f64, f64, f64); J] {
    let (mut q, mut qd, mut qdd) = ([0.0; J], [0.0; J], [0.0; J]);
    traj.eval_into(t, &mut q, &mut qd, &mut qdd);
    std::array::from_fn(|k| (q[k], qd[k], qdd[k]))
}

/// Run the wrist with the model and LSTM stages `make(joint)` gives each compensator.
pub fn run_wrist_with<M, L>(
    setup: &WristSetup,
    mut make: impl FnMut(usize) -> anyhow::Result<(M, L)>,
) -> anyhow::Result<[WristJointReport; J]>
where
    M: TorquePredictor<J>,
    L: TorquePredictor<J>,
{
    let pwm_hz = setup.motors[0].pwm_hz;
    ensure!(
        setup
            .motors
            .iter()
            .all(|m| m.pwm_hz == pwm_hz && m.substeps >= 1),
        "all joints need one PWM rate"
    );
    let mut comps = Vec::with_capacity(J);
    for j in 0..J {
        let (m, l) = make(j)?;
        let cfg = CompensatorConfig {
            own_joint: j,
            ..setup.compensator
        };
        comps.push(
            Compensator::<J, M, L>::new(cfg, m, l)
                .map_err(|e| anyhow::anyhow!("compensator of joint {j}: {e:?}"))?,
        );
    }
    let mut plant = TrueWrist {
        arm: plant_sim::RobotRigidBody::new(&setup.robot),
        effects: PlantEffects {
            rotor_inertia: false, // in the mass matrix instead
            ..setup.effects
        },
        states: [DriveState::at_rest(setup.plant.ambient_temperature_c); J],
    };
    let drive_params: [&plant_sim::JointDrive; J] = WRIST_JOINTS.map(|j| &setup.plant.joints[j]);
    let ambient = setup.plant.ambient_temperature_c;
    let reflected: [f64; J] = std::array::from_fn(|k| {
        setup.motors[k].rotor_inertia_kg_m2 * setup.motors[k].gear_ratio.powi(2)
    });
    let mut drives: Vec<JointDrive> = setup.drives.iter().map(|d| JointDrive::new(*d)).collect();
    let mut motors: Vec<Motor> = setup
        .motors
        .iter()
        .map(|p| Motor {
            i_abc_a: [0.0; 3],
            rng: ChaCha8Rng::seed_from_u64(p.seed),
            current_noise: noise(p.current_noise_a),
            bus_noise: noise(p.bus_noise_v),
        })
        .collect();
    let r0 = reference(&setup.trajectory, 0.0);
    let mut q: [f64; J] = r0.map(|r| r.0);
    let mut qd: [f64; J] = r0.map(|r| r.1);
    let mut qdd = [0.0f64; J];
    for (d, q0) in drives.iter_mut().zip(q.iter()) {
        d.set_position_origin(*q0 as f32);
    }
    let comp_every = (pwm_hz / setup.compensator.rate_hz as f64).round().max(1.0) as u64;
    let period_s = comp_every as f64 / pwm_hz;
    let n = (setup.duration_s.min(setup.trajectory.duration_s()) * pwm_hz).floor() as u64;
    let substeps = setup.motors[0].substeps;
    let dt = 1.0 / (pwm_hz * substeps as f64);
    let gain = setup.compensator.drive_gain_nm_per_a;
    let mut duties = [[0.5f64; 3]; J];
    let mut last_out = [DriveOutput::default(); J];
    let mut iq_sum = [0.0f64; J];
    let mut iq_count = 0u32;
    let mut bus = super::StateBus::default();
    let (mut se, mut max_e, mut siq) = ([0.0f64; J], [0.0f64; J], [0.0f64; J]);
    let mut faults = [FaultFlags::NONE; J];
    let mut sources = [[0u64; 3]; J];
    let state_at = |t_mid: f64, out: &DriveOutput, tau_meas: f32, k: usize| {
        let r = reference(&setup.trajectory, t_mid)[k];
        JointState {
            q_ref_rad: r.0 as f32,
            qd_ref_rad_s: r.1 as f32,
            qdd_ref_rad_s2: r.2 as f32,
            q_meas_rad: out.q_rad,
            qd_meas_rad_s: out.qd_rad_s,
            tau_meas_nm: tau_meas,
        }
    };
    for k in 0..n {
        let t_tick = k as f64 / pwm_hz;
        if k % comp_every == 0 {
            bus.deliver(&mut comps)?;
            // The feedforward is held for one period: it is computed for the period's
            // middle (the reference is known ahead).
            let t_mid = t_tick + 0.5 * period_s;
            for j in 0..J {
                // Measured torque: drive gain x the mean measured q current over the
                // last period.
                let tau_meas = if iq_count > 0 {
                    (iq_sum[j] / iq_count as f64) as f32 * gain
                } else {
                    0.0
                };
                let own = state_at(t_mid, &last_out[j], tau_meas, j);
                let o = comps[j].tick(&own, (t_tick * 1e6) as u32);
                drives[j].set_feedforward_current(o.current_a);
                if k > 0 {
                    faults[j] |= o.faults;
                }
                sources[j][match o.source {
                    FeedforwardSource::Zero => 0,
                    FeedforwardSource::Model => 1,
                    FeedforwardSource::ModelLstm => 2,
                }] += 1;
                // The frame carries the references for the receivers' next tick and
                // this tick's measurements.
                bus.send(
                    j,
                    (t_tick * 1e6) as u32,
                    state_at(t_mid + period_s, &last_out[j], tau_meas, j),
                );
            }
            iq_sum = [0.0; J];
            iq_count = 0;
        }
        let r = reference(&setup.trajectory, t_tick);
        for j in 0..J {
            let c = &setup.motors[j];
            drives[j].set_reference(&JointReference {
                q_rad: r[j].0 as f32,
                qd_rad_s: r[j].1 as f32,
                qdd_rad_s2: r[j].2 as f32,
            });
            let m = &mut motors[j];
            let s = sense_joint(
                c,
                m.i_abc_a,
                q[j] * c.gear_ratio,
                &mut m.rng,
                &m.current_noise,
                &m.bus_noise,
            );
            last_out[j] = drives[j].pwm_tick(&SensorSample {
                phase_current_a: [s.phase_current_a[0] as f32, s.phase_current_a[1] as f32],
                motor_angle_rad: s.motor_angle_rad as f32,
                bus_v: s.bus_v as f32,
            });
            faults[j] |= last_out[j].faults;
            iq_sum[j] += last_out[j].iq_meas_a as f64;
        }
        iq_count += 1;
        // Mechanics: mass matrix (links + reflected rotors) and rigid bias held over the
        // PWM period; motors, friction and ripple every substep.
        let (m_links, h_rigid) = plant.mass_and_bias(&q, &qd);
        let mut mm = m_links;
        for j in 0..J {
            mm[(j, j)] += reflected[j];
        }
        let m_inv = mm
            .try_inverse()
            .ok_or_else(|| anyhow::anyhow!("singular mass matrix at t = {t_tick}"))?;
        let v: [[f64; 3]; J] = std::array::from_fn(|j| phase_voltages(&setup.motors[j], duties[j]));
        let mut friction_power = [0.0f64; J];
        for _ in 0..substeps {
            let transmitted = m_links * nalgebra::Vector3::from(qdd);
            let mut rhs = nalgebra::Vector3::zeros();
            for j in 0..J {
                let c = &setup.motors[j];
                let th = c.pole_pairs as f64 * (q[j] * c.gear_ratio - c.encoder_offset_rad);
                motor_electrical_step(
                    c,
                    &mut motors[j].i_abc_a,
                    v[j],
                    th,
                    qd[j] * c.gear_ratio,
                    dt,
                );
                let t_motor = 1.5
                    * c.pole_pairs as f64
                    * c.flux_linkage_wb
                    * q_current_a(motors[j].i_abc_a, th);
                let d = plant_sim::drive::drive_torque_step(
                    drive_params[j],
                    &plant.effects,
                    &mut plant.states[j],
                    q[j],
                    qd[j],
                    0.0,
                    transmitted[j] + h_rigid[j],
                    ambient,
                    dt,
                );
                friction_power[j] += d.friction_nm * qd[j] / substeps as f64;
                rhs[j] = t_motor * c.gear_ratio * c.gear_efficiency - h_rigid[j] - d.total_nm();
            }
            let a = m_inv * rhs;
            for j in 0..J {
                qdd[j] = a[j];
                qd[j] += qdd[j] * dt;
                q[j] += qd[j] * dt;
            }
        }
        let t_end = (k + 1) as f64 / pwm_hz;
        let r_end = reference(&setup.trajectory, t_end);
        for j in 0..J {
            duties[j] = last_out[j].duties.map(f64::from);
            let c = &setup.motors[j];
            let th = c.pole_pairs as f64 * (q[j] * c.gear_ratio - c.encoder_offset_rad);
            let iq = q_current_a(motors[j].i_abc_a, th);
            if plant.effects.thermal {
                plant_sim::drive::thermal_step(
                    drive_params[j],
                    &mut plant.states[j],
                    iq,
                    friction_power[j],
                    ambient,
                    1.0 / pwm_hz,
                );
            }
            let e = r_end[j].0 - q[j];
            se[j] += e * e;
            max_e[j] = max_e[j].max(e.abs());
            siq[j] += iq * iq;
        }
    }
    let nf = n.max(1) as f64;
    Ok(std::array::from_fn(|j| WristJointReport {
        joint: WRIST_JOINTS[j] + 1,
        rms_error_rad: (se[j] / nf).sqrt(),
        max_error_rad: max_e[j],
        rms_iq_a: (siq[j] / nf).sqrt(),
        fault_bits: faults[j].bits() as u32,
        source_ticks: sources[j],
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
    let need_model = || model.copied().context("this feedforward needs --model");
    match mode {
        WristFeedforward::None => run_wrist_with(setup, |_| Ok((NoPredictor, NoPredictor))),
        WristFeedforward::Model => {
            let m = need_model()?;
            run_wrist_with(setup, |_| Ok((m, NoPredictor)))
        }
        WristFeedforward::ModelLstmF32 | WristFeedforward::ModelLstmInt16 => {
            let m = need_model()?;
            let l = lstm.context("this feedforward needs --lstm")?;
            let net = l.network(mode == WristFeedforward::ModelLstmInt16)?;
            let preset = l.preset;
            let layout = "the network does not take its preset's feature layout";
            if preset == FeaturePreset::Drive {
                let mut linear = [[0.0; FRICTION_FEATURES]; J];
                for (row, w) in linear
                    .iter_mut()
                    .zip(l.model.linear.chunks_exact(FRICTION_FEATURES))
                {
                    row.copy_from_slice(w);
                }
                run_wrist_with(setup, |_| {
                    let p =
                        LstmPredictor::<_, J, { DRIVE_INPUTS_PER_JOINT * J }>::new(&net, preset)
                            .context(layout)?
                            .with_linear_stage(linear);
                    Ok((m, p))
                })
            } else {
                run_wrist_with(setup, |_| {
                    let p = LstmPredictor::<_, J, { 3 * J }>::new(&net, preset).context(layout)?;
                    Ok((m, p))
                })
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
        "| feedforward | joint | RMS error [mrad] | max error [mrad] | RMS iq [A] | vs model: error | vs model: iq | ticks zero/model/LSTM | faults |"
    );
    let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|---:|---|---|");
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
                "| {} | {} | {:.4} | {:.4} | {:.4} | {de} | {di} | {}/{}/{} | {:#06x} |",
                r.feedforward,
                j.joint,
                j.rms_error_rad * 1e3,
                j.max_error_rad * 1e3,
                j.rms_iq_a,
                j.source_ticks[0],
                j.source_ticks[1],
                j.source_ticks[2],
                j.fault_bits
            );
        }
    }
    s
}
