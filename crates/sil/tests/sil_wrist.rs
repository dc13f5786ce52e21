//! The wrist SIL (joints 4-6 on the plant simulator's true drive effects, one firmware
//! drive + compensator per joint, states over the simulated bus): short runs that
//! check the wiring; the full table is `model-export sil` (README, "Wrist SIL").

use compnet::model::LstmModel;
use firmware::control::FaultFlags;
use firmware::nn::reference::LstmDims;
use plant_sim::{CommandedTrajectory, PlantParameters};
use sil::wrist::{WRIST_JOINTS, WristFeedforward, WristLstm, WristSetup, run_wrist};

fn setup(seconds: f64) -> WristSetup {
    let robot = robot::RobotSource::BuiltIn.load().unwrap();
    let traj: CommandedTrajectory =
        plant_sim::trajectory::trajectory_or_seeded(None, 1, 2, 3).unwrap();
    let mut s = WristSetup::new(robot, PlantParameters::default_robot(), traj, 100, 3).unwrap();
    s.duration_s = seconds;
    s
}

/// The nominal model of the wrist (joints 1-3 locked at 0) as the firmware builds it.
fn nominal_model() -> firmware::dynamics::RigidBodyModel<3> {
    let identify::identified::IdentifiedRobot {
        robot,
        standard_parameters: theta,
        ..
    } = identify::identified::load_model_robot(
        &robot::RobotSource::BuiltIn,
        None,
        &identify::identified::ModelSelection {
            locked: vec![(0, 0.0), (1, 0.0), (2, 0.0)],
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(robot.modelled_joints(), WRIST_JOINTS.to_vec());
    robot::dynamics::firmware_model::build_firmware_model::<3>(&robot, &theta).unwrap()
}

/// A paper-preset network of the wrist whose output is always 0 N*m (zero output
/// weights and statistics): the LSTM stage is accepted and its feedforward is zero.
fn zero_output_lstm() -> WristLstm {
    let mut m = LstmModel::init(
        LstmDims {
            input: 9,
            embed: 8,
            hidden: 8,
            output: 3,
        },
        5,
    );
    let spec = compnet::data::FeatureSpec::paper(&[4, 5, 6]);
    m.preset = spec.preset.clone();
    m.output_names = spec.output_names();
    m.input_names = spec.inputs;
    m.w_out.iter_mut().for_each(|w| *w = 0.0);
    m.b_out.iter_mut().for_each(|b| *b = 0.0);
    m.output_mean.iter_mut().for_each(|b| *b = 0.0);
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("zero.safetensors");
    compnet::io::write_model(&m, &p).unwrap();
    WristLstm::load(dir.path()).unwrap()
}

#[test]
fn wrist_tracks_and_every_compensator_hears_the_others() {
    let s = setup(1.5);
    let model = nominal_model();
    let bus = FaultFlags::STATE_STALE | FaultFlags::STATE_REJECTED | FaultFlags::STATE_OUT_OF_ORDER;
    let drive = FaultFlags::SENSOR_INVALID | FaultFlags::OVERCURRENT | FaultFlags::BUS_VOLTAGE;
    let none = run_wrist(&s, WristFeedforward::None, None, None).unwrap();
    let with_model = run_wrist(&s, WristFeedforward::Model, Some(&model), None).unwrap();
    for (a, b) in none.iter().zip(&with_model) {
        println!("none {a:?}\nmodel {b:?}");
        for r in [a, b] {
            assert!(r.rms_error_rad < 2e-3 && r.rms_error_rad > 0.0, "{r:?}");
            assert!(r.rms_iq_a.is_finite() && r.rms_iq_a > 0.0, "{r:?}");
            let f = FaultFlags::from_bits(r.fault_bits);
            assert!(!f.intersects(bus | drive), "{r:?}");
            // Only the first tick (before any frame arrived) has no feedforward.
            assert_eq!(r.source_ticks, [1, 149, 0], "{r:?}");
        }
    }
    // The plant sets the total current; feedforward only changes how it is split
    // between the feedforward and the feedback loops.
    assert!((none[0].rms_iq_a - with_model[0].rms_iq_a).abs() < 0.05 * none[0].rms_iq_a);
}

#[test]
fn lstm_stage_runs_in_both_precisions_through_the_firmware_predictor() {
    let mut s = setup(0.6);
    for p in &mut s.profiles {
        p.max_lstm_correction_nm = 200.0;
    }
    let model = nominal_model();
    let lstm = zero_output_lstm();
    let none = run_wrist(&s, WristFeedforward::None, None, None).unwrap();
    for mode in [
        WristFeedforward::ModelLstmF32,
        WristFeedforward::ModelLstmInt16,
    ] {
        let r = run_wrist(&s, mode, Some(&model), Some(&lstm)).unwrap();
        for (a, b) in none.iter().zip(&r) {
            println!("{mode:?}: {b:?}");
            // Every tick after the first used the LSTM stage, whose output is 0 N*m
            // (after the warm-up blend from the model): the end matches no feedforward.
            assert_eq!(b.source_ticks, [1, 0, 59], "{b:?}");
            assert!(b.rms_error_rad < 2e-3, "{b:?}");
            assert!(a.rms_error_rad < 2e-3);
        }
    }
}
