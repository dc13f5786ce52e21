//! The true plant: a robot arm whose behaviour includes what the identification model
//! (rigid body + viscous + Coulomb friction) misses, logged like a real controller logs.
//!
//! Approach (justified in crates/plant-sim/README.md, "Plant simulator"): the arm follows the
//! commanded trajectory (a stiff position loop), and the motor current is the inverse
//! dynamics of the true plant along it, stepped at an internal rate (default 1 kHz) that
//! integrates the memory effects (LuGre bristles, thermal node), then sampled, corrupted
//! and optionally filtered at the controller rate (default 100 Hz).
#![deny(unsafe_code)]
#![warn(missing_docs)]
pub mod drive;
pub mod log;
pub mod params;
pub mod rigid;
pub mod sensor;
pub mod trajectory;

use anyhow::ensure;
use rand::SeedableRng;

pub use drive::{DriveState, DriveTorque};
pub use log::SimulatedLog;
pub use params::{JointDrive, PlantParameters, RippleHarmonic, SensorParameters};
pub use rigid::{DhArm, DhLink, RigidBodyModel};
pub use trajectory::{CommandedTrajectory, PlaybackTrajectory};

/// Which effects beyond the identification model the plant includes (each switchable).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PlantEffects {
    /// Stribeck (velocity-weakening) friction: static level above Coulomb at low speed.
    pub stribeck: bool,
    /// Presliding hysteresis with memory (LuGre bristle state).
    pub presliding: bool,
    /// Coulomb level grows with the torque transmitted through the gear.
    pub load_friction: bool,
    /// Rotor inertia reflected through the gear (`N^2 J_r qdd`).
    pub rotor_inertia: bool,
    /// Viscous friction drifts with the temperature of an I^2 R-heated thermal node.
    pub thermal: bool,
    /// Position-periodic transmission torque ripple.
    pub ripple: bool,
    /// White noise on each current sample.
    pub current_noise: bool,
    /// ADC quantisation of each current sample.
    pub quantisation: bool,
    /// The paper's Kalman filter on the logged current.
    pub kalman: bool,
}

impl PlantEffects {
    /// Every physical and sensing effect on; the Kalman filter off (an option of the log chain).
    pub const fn all() -> Self {
        PlantEffects {
            stribeck: true,
            presliding: true,
            load_friction: true,
            rotor_inertia: true,
            thermal: true,
            ripple: true,
            current_noise: true,
            quantisation: true,
            kalman: false,
        }
    }

    /// Nothing beyond the identification model: rigid body + viscous + Coulomb (`sgn`),
    /// exact current samples.
    pub const fn none() -> Self {
        PlantEffects {
            stribeck: false,
            presliding: false,
            load_friction: false,
            rotor_inertia: false,
            thermal: false,
            ripple: false,
            current_noise: false,
            quantisation: false,
            kalman: false,
        }
    }
}

impl Default for PlantEffects {
    fn default() -> Self {
        Self::all()
    }
}

/// How to run one simulation.
#[derive(Debug, Clone, PartialEq)]
pub struct SimulationConfig {
    /// Effects of the true plant.
    pub effects: PlantEffects,
    /// Rate of the logged samples (the controller) [Hz].
    pub controller_rate_hz: f64,
    /// Internal integration rate [Hz]; an integer multiple of the controller rate.
    pub internal_rate_hz: f64,
    /// Seed of every random process (noise).
    pub seed: u64,
    /// Robot joint (0-based) driven by each trajectory joint, in trajectory order.
    pub driven_joints: Vec<usize>,
    /// Position of every robot joint not driven by the trajectory [rad] (length = dof).
    pub locked_position_rad: Vec<f64>,
    /// Temperature of each drive at t = 0 [degC] (one value: all drives); empty: ambient.
    pub initial_temperature_c: Vec<f64>,
}

impl SimulationConfig {
    /// Defaults: all effects, 100 Hz log, 1 kHz internal, seed 0, the trajectory drives
    /// joints `0..n` and the rest are locked at zero.
    pub fn new(dof: usize, trajectory_joints: usize) -> Self {
        SimulationConfig {
            effects: PlantEffects::all(),
            controller_rate_hz: 100.0,
            internal_rate_hz: 1000.0,
            seed: 0,
            driven_joints: (0..trajectory_joints.min(dof)).collect(),
            locked_position_rad: vec![0.0; dof],
            initial_temperature_c: Vec::new(),
        }
    }
}

/// Simulates the arm along `trajectory` and returns the controller's log.
pub fn simulate<R: RigidBodyModel + ?Sized>(
    arm: &R,
    plant: &PlantParameters,
    trajectory: &CommandedTrajectory,
    cfg: &SimulationConfig,
) -> anyhow::Result<SimulatedLog> {
    let dof = arm.dof();
    plant.validate()?;
    ensure!(
        plant.joints.len() == dof,
        "plant has {} drives, robot has {dof} joints",
        plant.joints.len()
    );
    ensure!(
        cfg.driven_joints.len() == trajectory.joint_count(),
        "trajectory drives {} joints, {} robot joints given",
        trajectory.joint_count(),
        cfg.driven_joints.len()
    );
    for (k, &j) in cfg.driven_joints.iter().enumerate() {
        ensure!(
            j < dof,
            "driven joint {} out of range (robot has {dof})",
            j + 1
        );
        ensure!(
            !cfg.driven_joints[..k].contains(&j),
            "joint {} driven twice",
            j + 1
        );
    }
    ensure!(
        cfg.locked_position_rad.len() == dof,
        "locked positions: {} given, need {dof}",
        cfg.locked_position_rad.len()
    );
    ensure!(
        cfg.controller_rate_hz > 0.0 && cfg.internal_rate_hz > 0.0,
        "rates must be > 0"
    );
    let ratio = cfg.internal_rate_hz / cfg.controller_rate_hz;
    let every = ratio.round() as usize;
    ensure!(
        every >= 1 && (ratio - every as f64).abs() < 1e-9,
        "internal rate {} Hz must be an integer multiple of the controller rate {} Hz",
        cfg.internal_rate_hz,
        cfg.controller_rate_hz
    );
    let duration = trajectory.duration_s();
    ensure!(
        duration.is_finite() && duration > 0.0,
        "trajectory has no duration"
    );
    // The log's rows are kept in memory: a bounded count (`--periods 1e9`, a period of
    // 1e308 s) is an error naming the limit, not an allocation failure.
    ensure!(
        duration * cfg.controller_rate_hz <= logs::MAX_GRID_SAMPLES as f64,
        "{duration} s at {} Hz is more than {} logged samples: shorten the trajectory or \
         its periods",
        cfg.controller_rate_hz,
        logs::MAX_GRID_SAMPLES
    );
    let h = 1.0 / cfg.internal_rate_hz;
    let steps = (duration * cfg.internal_rate_hz + 1e-6).floor() as usize;
    let fx = cfg.effects;

    let ambient = plant.ambient_temperature_c;
    let t0 = &cfg.initial_temperature_c;
    ensure!(
        t0.len() <= 1 || t0.len() == dof,
        "initial temperatures: {} given, need 1 or {dof}",
        t0.len()
    );
    ensure!(
        t0.iter().all(|t| t.is_finite()),
        "initial temperatures must be finite"
    );
    let mut state: Vec<DriveState> = (0..dof)
        .map(|j| {
            DriveState::at_rest(if t0.is_empty() {
                ambient
            } else {
                t0[j.min(t0.len() - 1)]
            })
        })
        .collect();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(cfg.seed);
    let s = &plant.sensor;
    let mut kalman =
        vec![sensor::CurrentKalman::new(s.kalman_process_var_a2, s.kalman_measurement_var_a2); dof];
    let gains: Vec<f64> = plant
        .joints
        .iter()
        .map(JointDrive::drive_gain_nm_a)
        .collect();

    let nt = trajectory.joint_count();
    let (mut tq, mut tqd, mut tqdd) = (vec![0.0; nt], vec![0.0; nt], vec![0.0; nt]);
    let mut q = cfg.locked_position_rad.clone();
    let mut qd = vec![0.0; dof];
    let mut qdd = vec![0.0; dof];
    let mut rigid = vec![0.0; dof];
    let mut log = SimulatedLog::with_capacity(dof, steps / every + 1, gains.clone());
    let mut parts = vec![DriveTorque::default(); dof];
    let mut current = vec![0.0; dof];
    let mut measured = vec![0.0; dof];
    for step in 0..=steps {
        let t = step as f64 * h;
        trajectory.eval_into(t, &mut tq, &mut tqd, &mut tqdd);
        for (k, &j) in cfg.driven_joints.iter().enumerate() {
            q[j] = tq[k];
            qd[j] = tqd[k];
            qdd[j] = tqdd[k];
        }
        arm.inverse_dynamics(&q, &qd, &qdd, &mut rigid);
        let dt = if step == 0 { 0.0 } else { h };
        for j in 0..dof {
            parts[j] = drive::drive_torque_step(
                &plant.joints[j],
                &fx,
                &mut state[j],
                q[j],
                qd[j],
                qdd[j],
                rigid[j],
                ambient,
                dt,
            );
            let p = parts[j];
            current[j] = (rigid[j] + p.friction_nm + p.ripple_nm + p.rotor_nm) / gains[j];
        }
        if step % every == 0 {
            for j in 0..dof {
                let mut i = current[j];
                if fx.current_noise {
                    i = sensor::add_noise(&mut rng, i, s.current_noise_a);
                }
                if fx.quantisation {
                    i = sensor::quantise(i, plant.joints[j].adc_full_scale_a, s.adc_bits);
                }
                if fx.kalman {
                    i = kalman[j].update(i);
                }
                measured[j] = i;
            }
            log.push(
                t, &q, &qd, &qdd, &measured, &current, &rigid, &parts, &state,
            );
        }
        if fx.thermal {
            for j in 0..dof {
                let friction_power = parts[j].friction_nm * qd[j];
                drive::thermal_step(
                    &plant.joints[j],
                    &mut state[j],
                    current[j],
                    friction_power,
                    ambient,
                    h,
                );
            }
        }
    }
    Ok(log)
}

/// The built-in default robot's rigid body (UR5e published DH, masses, centres of mass
/// and inertia tensors) carrying the default 2.5 kg tool; see crates/robot/README.md, "The default robot".
pub fn default_arm() -> DhArm {
    use std::f64::consts::FRAC_PI_2;
    let d = [0.1625, 0.0, 0.0, 0.1333, 0.0997, 0.0996];
    let a = [0.0, -0.425, -0.3922, 0.0, 0.0, 0.0];
    let alpha = [FRAC_PI_2, 0.0, 0.0, FRAC_PI_2, -FRAC_PI_2, 0.0];
    let mut mass = [3.761, 8.058, 2.846, 1.37, 1.3, 0.365];
    let mut com = [
        [0.0, -0.02561, 0.00193],
        [0.2125, 0.0, 0.11336],
        [0.15, 0.0, 0.0265],
        [0.0, -0.0018, 0.01634],
        [0.0, 0.0018, 0.01634],
        [0.0, 0.0, -0.001159],
    ];
    // [ixx, iyy, izz, ixy, ixz, iyz] about the centre of mass, DH frame axes.
    let mut inertia = [
        [
            0.0070021,
            0.00648091,
            0.00657286,
            0.00000073,
            -0.00001053,
            0.00049994,
        ],
        [
            0.01505885,
            0.33388086,
            0.33247207,
            -0.000054,
            0.00000563,
            -0.00000181,
        ],
        [
            0.00399632,
            0.07879254,
            0.0784851,
            -0.00001365,
            0.00137272,
            -0.0000066,
        ],
        [
            0.00165491,
            0.00135962,
            0.00126279,
            -0.00000282,
            -0.00000438,
            0.00010157,
        ],
        [
            0.00135617,
            0.00127827,
            0.00096614,
            -0.00000274,
            0.00000444,
            -0.00005048,
        ],
        [
            0.00018694,
            0.00018908,
            0.00025756,
            0.00000006,
            -0.00000017,
            -0.00000092,
        ],
    ];
    // The default tool (default.urdf's `tool` link): 2.5 kg, centre of mass
    // [0, 0.03, 0.07] m in the flange frame (DH frame 6), inertia diag(0.006, 0.006,
    // 0.003) kg m^2 about it, rigidly added to the last link.
    (mass[5], com[5], inertia[5]) = combine_rigid_bodies(
        (mass[5], com[5], inertia[5]),
        (2.5, [0.0, 0.03, 0.07], [0.006, 0.006, 0.003, 0.0, 0.0, 0.0]),
    );
    DhArm {
        links: (0..6)
            .map(|i| DhLink {
                d_m: d[i],
                a_m: a[i],
                alpha_rad: alpha[i],
                theta_offset_rad: 0.0,
                mass_kg: mass[i],
                com_m: com[i],
                inertia_com_kgm2: inertia[i],
            })
            .collect(),
    }
}

/// A rigid body as (mass [kg], centre of mass [m], inertia about the centre of mass
/// [ixx, iyy, izz, ixy, ixz, iyz] [kg m^2]), all in one frame.
type MassProperties = (f64, [f64; 3], [f64; 6]);

/// Two rigid bodies fixed together: masses and first moments add, and each inertia
/// moves to the common centre of mass by the parallel-axis theorem.
fn combine_rigid_bodies(a: MassProperties, b: MassProperties) -> MassProperties {
    use nalgebra::{Matrix3, Vector3};
    let m = a.0 + b.0;
    let c = (Vector3::from(a.1) * a.0 + Vector3::from(b.1) * b.0) / m;
    let about_c = |(mi, ci, i): MassProperties| {
        let t = Matrix3::new(i[0], i[3], i[4], i[3], i[1], i[5], i[4], i[5], i[2]);
        let d = Vector3::from(ci) - c;
        t + (Matrix3::identity() * d.dot(&d) - d * d.transpose()) * mi
    };
    let t = about_c(a) + about_c(b);
    (
        m,
        c.into(),
        [
            t[(0, 0)],
            t[(1, 1)],
            t[(2, 2)],
            t[(0, 1)],
            t[(0, 2)],
            t[(1, 2)],
        ],
    )
}

/// A robot description ([`robot::Robot`], from DH TOML or URDF) as the plant's
/// rigid body: every joint moves, no friction or rotor terms (the plant adds its own),
/// evaluated with the robot module's recursive Newton-Euler ([`robot::dynamics::rnea`]).
#[derive(Debug, Clone)]
pub struct RobotRigidBody {
    /// The robot, all joints modelled, rigid-body terms only.
    pub robot: robot::Robot,
    theta: nalgebra::DVector<f64>,
}

impl RobotRigidBody {
    /// Wraps a robot description (its joint selection and model terms are ignored).
    pub fn new(robot: &robot::Robot) -> Self {
        let mut robot = robot.clone();
        robot.model_all_joints();
        robot.terms = robot::ModelTerms::rigid_body_only();
        let theta = robot.standard_parameters();
        RobotRigidBody { robot, theta }
    }
}

impl RigidBodyModel for RobotRigidBody {
    fn dof(&self) -> usize {
        self.robot.dof()
    }

    fn inverse_dynamics(&self, q: &[f64], qd: &[f64], qdd: &[f64], tau_nm: &mut [f64]) {
        let t = robot::dynamics::rnea(&self.robot, &self.theta, q, qd, qdd, &self.robot.gravity);
        tau_nm.copy_from_slice(t.as_slice());
    }
}
