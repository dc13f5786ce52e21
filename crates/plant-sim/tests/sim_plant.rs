//! The default robot and the plant simulator: what the simulated logs must show.
use excitation::ExcitationTrajectory;
use plant_sim::{
    self, CommandedTrajectory, PlantEffects, PlantParameters, RigidBodyModel, RobotRigidBody,
    SimulationConfig,
};
use rand::{Rng, SeedableRng};
use robot::Robot;
use test_support::robots_dir;

/// default.toml and default.urdf describe the same arm: equal inverse dynamics at random
/// states, and both equal an independent standard-DH Newton-Euler (plant_sim::DhArm) built
/// from the published UR5e numbers.
#[test]
fn toml_and_urdf_give_the_same_dynamics() {
    let toml = RobotRigidBody::new(&Robot::load(robots_dir().join("default.toml")).unwrap());
    let urdf = RobotRigidBody::new(&Robot::load(robots_dir().join("default.urdf")).unwrap());
    let independent = plant_sim::default_arm();
    assert_eq!(toml.dof(), 6);
    assert_eq!(urdf.dof(), 6);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let mut worst: f64 = 0.0;
    for _ in 0..200 {
        let mut draw = |s: f64| -> Vec<f64> { (0..6).map(|_| rng.gen_range(-s..s)).collect() };
        let (q, qd, qdd) = (draw(3.0), draw(3.0), draw(10.0));
        let (mut a, mut b, mut c) = ([0.0; 6], [0.0; 6], [0.0; 6]);
        toml.inverse_dynamics(&q, &qd, &qdd, &mut a);
        urdf.inverse_dynamics(&q, &qd, &qdd, &mut b);
        independent.inverse_dynamics(&q, &qd, &qdd, &mut c);
        let scale = a.iter().map(|x| x.abs()).fold(1.0, f64::max);
        for j in 0..6 {
            worst = worst
                .max((a[j] - b[j]).abs() / scale)
                .max((a[j] - c[j]).abs() / scale);
        }
    }
    assert!(worst < 1e-10, "worst relative difference {worst:e}");
}

/// The plant file and the robot file agree on every number they share.
#[test]
fn plant_file_agrees_with_robot_file() {
    let robot = Robot::load(robots_dir().join("default.toml")).unwrap();
    let plant = PlantParameters::default_robot();
    assert_eq!(
        plant,
        PlantParameters::load(&robots_dir().join("default.plant.toml")).unwrap()
    );
    // The URDF's <dynamics damping friction>, taken as the nominal friction when chosen.
    let urdf = Robot::load_chain(
        robots_dir().join("default.urdf"),
        &robot::ChainSelection {
            urdf_friction: robot::UrdfFriction::Nominal,
            ..robot::ChainSelection::default()
        },
    )
    .unwrap()
    .robot;
    for (j, (rj, pj)) in robot.joints.iter().zip(&plant.joints).enumerate() {
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * a.abs().max(1.0);
        assert!(
            close(rj.drive.gear_ratio.unwrap(), pj.gear_ratio),
            "joint {j} gear"
        );
        assert!(
            close(
                rj.drive.torque_constant_nm_per_a.unwrap(),
                pj.motor_torque_constant_nm_a
            ),
            "joint {j} kt"
        );
        assert!(
            close(rj.drive.drive_gain_nm_per_a.unwrap(), pj.drive_gain_nm_a()),
            "joint {j} gain"
        );
        assert!(
            close(
                rj.drive.rotor_inertia_kg_m2.unwrap(),
                pj.reflected_rotor_inertia_kgm2()
            ),
            "joint {j} rotor"
        );
        assert!(
            close(rj.friction.viscous_nm_s_rad, pj.viscous_nms_rad),
            "joint {j} viscous"
        );
        assert!(
            close(rj.friction.coulomb_nm, pj.coulomb_nm),
            "joint {j} coulomb"
        );
        assert!(
            close(urdf.joints[j].friction.viscous_nm_s_rad, pj.viscous_nms_rad),
            "urdf joint {j} viscous"
        );
        assert!(
            close(urdf.joints[j].friction.coulomb_nm, pj.coulomb_nm),
            "urdf joint {j} coulomb"
        );
    }
}

fn run(seed: u64) -> Vec<u8> {
    let robot = Robot::load(robots_dir().join("default.toml")).unwrap();
    let arm = RobotRigidBody::new(&robot);
    let series = ExcitationTrajectory::seeded_rest_to_rest(
        5,
        &[0.0; 6],
        5,
        10.0,
        plant_sim::trajectory::DEMO_LIMITS,
    );
    let tr = CommandedTrajectory::Fourier { series, periods: 1 };
    let mut cfg = SimulationConfig::new(6, 6);
    cfg.effects = PlantEffects {
        kalman: true,
        ..PlantEffects::all()
    };
    cfg.seed = seed;
    let log = plant_sim::simulate(&arm, &PlantParameters::default_robot(), &tr, &cfg).unwrap();
    let mut bytes = Vec::new();
    log.write_csv(&mut bytes).unwrap();
    bytes
}

/// Same seed, same bytes; another seed, other noise.
#[test]
fn same_seed_same_bytes() {
    let a = run(42);
    let b = run(42);
    assert_eq!(a, b);
    assert_ne!(a, run(43));
}

/// A simulated log reads with the same layout as a real robot's (the UR10e dataset's
/// column order: time, q1..6, qd1..6, i1..6 x drive gain) plus a header row.
#[test]
fn simulated_log_reads_like_a_real_robot_log() {
    let robot = Robot::load(robots_dir().join("default.toml")).unwrap();
    let arm = RobotRigidBody::new(&robot);
    let series = ExcitationTrajectory::seeded_rest_to_rest(
        9,
        &[0.0; 3],
        5,
        10.0,
        plant_sim::trajectory::DEMO_LIMITS,
    );
    let tr = CommandedTrajectory::Fourier { series, periods: 1 };
    let mut cfg = SimulationConfig::new(6, 3);
    cfg.driven_joints = vec![3, 4, 5];
    let plant = PlantParameters::default_robot();
    let log = plant_sim::simulate(&arm, &plant, &tr, &cfg).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sim.csv");
    log.save(&path).unwrap();
    let gains: Vec<f64> = plant.joints.iter().map(|d| d.drive_gain_nm_a()).collect();
    let mut layout = logs::LogLayout::sequential(6, true, true, Some(gains));
    layout.header = Some(true);
    let raw = logs::read_log(&path, &layout).unwrap();
    assert_eq!(raw.time_s.len(), log.rows.len());
    let tau = raw.torque_nm.unwrap();
    let k = 437;
    for (j, (q, t)) in raw.q_rad.iter().zip(&tau).enumerate() {
        assert_eq!(q[k], log.rows[k][log.column("q", j).unwrap()]);
        let logged = log.rows[k][log.column("tau", j).unwrap()];
        assert!((t[k] - logged).abs() <= 1e-12 * logged.abs().max(1.0));
    }
}
