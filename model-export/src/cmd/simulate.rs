//! Command-line arguments of `model-export simulate` and `model-export plant-report`.
use anyhow::{Context, ensure};
use clap::Args;
use identify::plant_check::{self as report, TorqueSource};
use plant_sim::{PlantEffects, PlantParameters, SimulationConfig};
use robot::RobotSource;
use std::path::PathBuf;

/// Switches for the plant's effects beyond the identification model (all on by default).
#[derive(Debug, Clone, Args)]
pub struct EffectFlags {
    /// Switch every effect off: the plant is exactly the identification model
    /// (rigid body + viscous + Coulomb), current logged exactly.
    #[arg(long)]
    pub ideal: bool,
    /// No Stribeck (velocity-weakening) friction.
    #[arg(long)]
    pub no_stribeck: bool,
    /// No presliding hysteresis (LuGre state); friction becomes a static map.
    #[arg(long)]
    pub no_presliding: bool,
    /// No load-dependent friction.
    #[arg(long)]
    pub no_load_friction: bool,
    /// No reflected rotor inertia.
    #[arg(long)]
    pub no_rotor_inertia: bool,
    /// No thermal drift of viscous friction.
    #[arg(long)]
    pub no_thermal: bool,
    /// No transmission torque ripple.
    #[arg(long)]
    pub no_ripple: bool,
    /// No current noise.
    #[arg(long)]
    pub no_noise: bool,
    /// No ADC quantisation.
    #[arg(long)]
    pub no_quantisation: bool,
    /// Filter the logged current with the paper's Kalman filter.
    #[arg(long)]
    pub kalman: bool,
}

impl EffectFlags {
    /// The effects these flags select.
    pub fn effects(&self) -> PlantEffects {
        let base = if self.ideal {
            PlantEffects::none()
        } else {
            PlantEffects::all()
        };
        PlantEffects {
            stribeck: base.stribeck && !self.no_stribeck,
            presliding: base.presliding && !self.no_presliding,
            load_friction: base.load_friction && !self.no_load_friction,
            rotor_inertia: base.rotor_inertia && !self.no_rotor_inertia,
            thermal: base.thermal && !self.no_thermal,
            ripple: base.ripple && !self.no_ripple,
            current_noise: base.current_noise && !self.no_noise,
            quantisation: base.quantisation && !self.no_quantisation,
            kalman: self.kalman,
        }
    }
}

/// Robot, plant and rates shared by the simulator's commands.
#[derive(Debug, Clone, Args)]
pub struct PlantArgs {
    /// Robot description (DH TOML or URDF); default: the built-in UR5e-class arm.
    #[arg(long)]
    pub robot: Option<PathBuf>,
    /// The modelled chain of a URDF tree.
    #[command(flatten)]
    pub chain: crate::args::robot::ChainArgs,
    /// Plant file (effects beyond the model, TOML); default: the built-in
    /// robots/default.plant.toml.
    #[arg(long)]
    pub plant: Option<PathBuf>,
    /// Controller (log) rate [Hz].
    #[arg(long, default_value_t = 100.0)]
    pub controller_rate_hz: f64,
    /// Internal integration rate [Hz], an integer multiple of the controller rate.
    #[arg(long, default_value_t = 1000.0)]
    pub internal_rate_hz: f64,
    /// Temperature of the drives at the start [degC]: one value for all, or one per
    /// joint (comma separated); default: ambient.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub initial_temperature_c: Vec<f64>,
    /// Effects.
    #[command(flatten)]
    pub effects: EffectFlags,
}

/// `model-export simulate`.
#[derive(Debug, Clone, Args)]
pub struct SimulateArgs {
    /// Plant and robot.
    #[command(flatten)]
    pub plant: PlantArgs,
    /// Commanded trajectory: Fourier coefficients (.json, from `model-export excite`) or a
    /// playback CSV with header t, q1.., qd1.., qdd1.. (any other extension).
    #[arg(long, required_unless_present = "seeded_trajectory")]
    pub trajectory: Option<PathBuf>,
    /// Instead of --trajectory: the built-in seeded rest-to-rest 5-harmonic Fourier
    /// trajectory (10 s period) of this seed over the --joints (`plant-report` trains on
    /// seed 1 and tests on seed 2).
    #[arg(long, conflicts_with = "trajectory")]
    pub seeded_trajectory: Option<u64>,
    /// Robot joints (1-based, comma separated) driven by the trajectory's joints, in
    /// order; default: the excitation file's `layout.moving`, else 1..n. Example for the
    /// paper's wrist: 4,5,6.
    #[arg(long, value_delimiter = ',')]
    pub joints: Vec<usize>,
    /// Joints not driven held at an angle: `J=RAD` with 1-based joint J, comma separated
    /// (e.g. `1=0,2=-1.57`); the others not driven stay at the excitation file's
    /// `layout.fixed_rad`, else zero.
    #[arg(
        long,
        value_name = "J=RAD",
        value_delimiter = ',',
        allow_hyphen_values = true
    )]
    pub lock: Vec<String>,
    /// Old spelling (hidden, warns): the positions of all joints [rad], one per robot joint.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true, hide = true)]
    pub locked_rad: Vec<f64>,
    /// Periods of a Fourier trajectory to run.
    #[arg(long, default_value_t = 1)]
    pub periods: usize,
    /// Seed of the sensing noise.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Output CSV (written atomically).
    #[arg(long = "out", short, alias = "output", value_name = "FILE")]
    pub out: PathBuf,
}

/// `model-export plant-report`.
#[derive(Debug, Clone, Args)]
pub struct PlantReportArgs {
    /// Plant and robot.
    #[command(flatten)]
    pub plant: PlantArgs,
    /// Modelled joints (1-based); the others are locked at zero. Default: the paper's wrist.
    #[arg(long, value_delimiter = ',', default_values_t = [4usize, 5, 6])]
    pub joints: Vec<usize>,
    /// Training (excitation) trajectory; default: a seeded rest-to-rest 5-harmonic
    /// Fourier trajectory (seed 1).
    #[arg(long)]
    pub train: Option<PathBuf>,
    /// Test trajectory; default: a different seeded one (seed 2).
    #[arg(long)]
    pub test: Option<PathBuf>,
    /// Periods of the training trajectory.
    #[arg(long, default_value_t = 6)]
    pub train_periods: usize,
    /// Periods of the test trajectory.
    #[arg(long, default_value_t = 3)]
    pub test_periods: usize,
    /// Seed of the sensing noise (test run uses seed + 1).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Also print the error with each effect alone (what dominates).
    #[arg(long)]
    pub ablation: bool,
}

fn one_based(joints: &[usize], dof: usize) -> anyhow::Result<Vec<usize>> {
    joints
        .iter()
        .map(|&j| {
            ensure!(
                j >= 1 && j <= dof,
                "--joints: joint {j} out of range 1..={dof}"
            );
            Ok(j - 1)
        })
        .collect()
}

fn load_plant(args: &PlantArgs) -> anyhow::Result<PlantParameters> {
    match &args.plant {
        Some(p) => PlantParameters::load(p),
        None => Ok(PlantParameters::default_robot()),
    }
}

fn config(args: &PlantArgs, dof: usize, driven: Vec<usize>, seed: u64) -> SimulationConfig {
    let mut cfg = SimulationConfig::new(dof, driven.len());
    cfg.effects = args.effects.effects();
    cfg.controller_rate_hz = args.controller_rate_hz;
    cfg.internal_rate_hz = args.internal_rate_hz;
    cfg.initial_temperature_c = args.initial_temperature_c.clone();
    cfg.driven_joints = driven;
    cfg.seed = seed;
    cfg
}

/// Runs `simulate`.
pub fn run_simulate(args: &SimulateArgs) -> anyhow::Result<()> {
    let robot = args
        .plant
        .chain
        .load_and_warn(&RobotSource::from(args.plant.robot.clone()))?;
    let arm = plant_sim::RobotRigidBody::new(&robot);
    let dof = robot.dof();
    let plant = load_plant(&args.plant)?;
    ensure!(
        args.trajectory.is_some() || !args.joints.is_empty(),
        "--seeded-trajectory needs --joints"
    );
    let traj = plant_sim::trajectory::trajectory_or_seeded(
        args.trajectory.as_deref(),
        args.periods,
        args.seeded_trajectory.unwrap_or(0),
        args.joints.len(),
    )?;
    let source = args
        .trajectory
        .clone()
        .unwrap_or_else(|| PathBuf::from("seeded trajectory"));
    let layout = plant_sim::trajectory::excitation_layout(&source)
        .filter(|(m, f)| m.len() == traj.joint_count() && f.len() == dof);
    let driven = if let (true, Some((moving, _))) = (args.joints.is_empty(), &layout) {
        moving.clone()
    } else if args.joints.is_empty() {
        ensure!(
            traj.joint_count() <= dof,
            "{}: trajectory has {} joints, robot {dof}",
            source.display(),
            traj.joint_count()
        );
        (0..traj.joint_count()).collect()
    } else {
        one_based(&args.joints, dof)?
    };
    let mut cfg = config(&args.plant, dof, driven, args.seed);
    if !args.locked_rad.is_empty() {
        cfg.locked_position_rad = args.locked_rad.clone();
    } else if let Some((_, fixed)) = layout {
        cfg.locked_position_rad = fixed;
    }
    let locks = crate::args::joints::lock_indices(&args.lock)?;
    if !locks.is_empty() && cfg.locked_position_rad.len() != dof {
        cfg.locked_position_rad = vec![0.0; dof];
    }
    for (index, q_rad) in locks {
        ensure!(
            index < dof,
            "--lock: joint {} of a {dof}-joint robot",
            index + 1
        );
        cfg.locked_position_rad[index] = q_rad;
    }
    let log = plant_sim::simulate(&arm, &plant, &traj, &cfg)
        .with_context(|| format!("{}", source.display()))?;
    log.save(&args.out)?;
    eprintln!(
        "wrote {} ({} samples at {} Hz, {:.1} s)",
        args.out.display(),
        log.rows.len(),
        cfg.controller_rate_hz,
        traj.duration_s()
    );
    Ok(())
}

/// Runs `plant-report`: the per-joint uncompensated RMS table.
pub fn run_plant_report(args: &PlantReportArgs) -> anyhow::Result<()> {
    let robot = args
        .plant
        .chain
        .load_and_warn(&RobotSource::from(args.plant.robot.clone()))?;
    let arm = plant_sim::RobotRigidBody::new(&robot);
    let dof = robot.dof();
    let plant = load_plant(&args.plant)?;
    let joints = one_based(&args.joints, dof)?;
    let train = plant_sim::trajectory::trajectory_or_seeded(
        args.train.as_deref(),
        args.train_periods,
        1,
        joints.len(),
    )?;
    let test = plant_sim::trajectory::trajectory_or_seeded(
        args.test.as_deref(),
        args.test_periods,
        2,
        joints.len(),
    )?;
    let run = |effects: PlantEffects| -> anyhow::Result<Vec<report::JointRms>> {
        let mut cfg = config(&args.plant, dof, joints.clone(), args.seed);
        cfg.effects = effects;
        let a = plant_sim::simulate(&arm, &plant, &train, &cfg).context("training run")?;
        // The test runs after the training run, on the drives as warm as it left them.
        if cfg.effects.thermal {
            cfg.initial_temperature_c = (0..dof)
                .map(|j| a.series("true_temp", j).last().copied().unwrap_or(25.0))
                .collect();
        }
        cfg.seed = args.seed.wrapping_add(1);
        let b = plant_sim::simulate(&arm, &plant, &test, &cfg).context("test run")?;
        report::uncompensated_rms(&robot, &a, &b, &joints, TorqueSource::Measured)
    };
    let effects = args.plant.effects.effects();
    let rms = run(effects)?;
    println!(
        "Uncompensated RMS torque error of the identified rigid-body + viscous + Coulomb model"
    );
    println!(
        "(robot {}, joints {:?} modelled, others locked at 0; train {:.0} s, test {:.0} s; {effects:?})",
        RobotSource::from(args.plant.robot.clone()),
        args.joints,
        train.duration_s(),
        test.duration_s()
    );
    println!();
    println!(
        "| joint | train RMS [N*m] | test RMS [N*m] | test torque RMS [N*m] | paper (uncompensated) [N*m] |"
    );
    println!("|---|---|---|---|---|");
    let paper = [(3, 3.61), (4, 4.84), (5, 6.10)];
    for r in &rms {
        let p = paper
            .iter()
            .find(|(j, _)| *j == r.joint)
            .map(|(_, v)| format!("{v:.2}"))
            .unwrap_or("-".into());
        println!(
            "| {} | {:.3} | {:.3} | {:.3} | {p} |",
            r.joint + 1,
            r.train_nm,
            r.test_nm,
            r.test_signal_nm
        );
    }
    if args.ablation {
        println!();
        println!(
            "Test RMS [N*m] with one effect alone (all others off, exact sensing unless named):"
        );
        println!();
        print!("| effect alone |");
        for j in &joints {
            print!(" joint {} |", j + 1);
        }
        println!();
        println!("|---|{}", "---|".repeat(joints.len()));
        let none = PlantEffects::none();
        let cases = [
            ("none (ideal)", none),
            (
                "stribeck",
                PlantEffects {
                    stribeck: true,
                    ..none
                },
            ),
            (
                "presliding (LuGre)",
                PlantEffects {
                    presliding: true,
                    ..none
                },
            ),
            (
                "stribeck + presliding",
                PlantEffects {
                    stribeck: true,
                    presliding: true,
                    ..none
                },
            ),
            (
                "load friction",
                PlantEffects {
                    load_friction: true,
                    ..none
                },
            ),
            (
                "rotor inertia",
                PlantEffects {
                    rotor_inertia: true,
                    ..none
                },
            ),
            (
                "thermal",
                PlantEffects {
                    thermal: true,
                    ..none
                },
            ),
            (
                "ripple",
                PlantEffects {
                    ripple: true,
                    ..none
                },
            ),
            (
                "noise + quantisation",
                PlantEffects {
                    current_noise: true,
                    quantisation: true,
                    ..none
                },
            ),
        ];
        for (name, fx) in cases {
            let r = run(fx)?;
            print!("| {name} |");
            for x in r {
                print!(" {:.3} |", x.test_nm);
            }
            println!();
        }
    }
    Ok(())
}
