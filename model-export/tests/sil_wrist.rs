//! The wrist SIL (joints 4-6 on the plant simulator's true drive effects, one firmware
//! drive + compensator per joint, states over the simulated bus): short runs that
//! check the wiring; the full table is `model-export sil` (README, "Wrist SIL").

use compnet::model::LstmModel;
use firmware::control::FaultFlags;
use firmware::nn::reference::LstmDims;
use model_export::cli::run_args as cli;
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
            let f = FaultFlags::from_bits(r.fault_bits as u16);
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

#[test]
fn cli_simulate_identify_sil_writes_markdown_and_json() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_str().unwrap().to_string();
    let (log, model, md, json) = (p("log.csv"), p("m.json"), p("sil.md"), p("sil.json"));
    cli(&[
        "simulate",
        "--seeded-trajectory",
        "1",
        "--joints",
        "4,5,6",
        "-o",
        &log,
    ])
    .unwrap();
    let layout = plant_sim::SimulatedLog::reader_args(6);
    let layout: Vec<&str> = layout.iter().map(String::as_str).collect();
    let mut id = vec![
        "identify",
        "--log",
        &log,
        "--lock",
        "1=0,2=0,3=0",
        "-o",
        &model,
    ];
    id.extend_from_slice(&layout);
    cli(&id).unwrap();
    // The LSTM dataset columns.
    let feat = p("features.csv");
    let mut tq = vec![
        "torque",
        "--model",
        &model,
        "--log",
        &log,
        "--dataset",
        "-o",
        &feat,
    ];
    tq.extend_from_slice(&layout);
    cli(&tq).unwrap();
    let header = std::fs::read_to_string(&feat).unwrap();
    assert!(header.starts_with(
        "time_s,q_j4,q_j5,q_j6,qd_j4,qd_j5,qd_j6,tau_meas_j4,tau_meas_j5,tau_meas_j6,tau_model_j4,tau_model_j5,tau_model_j6,\
         qdd_j4,qdd_j5,qdd_j6,sin_q_j4,sin_q_j5,sin_q_j6,cos_q_j4,cos_q_j5,cos_q_j6,rest_dir_j4,rest_dir_j5,rest_dir_j6,\
         slip_1mrad_j4,slip_1mrad_j5,slip_1mrad_j6,slip_3mrad_j4,slip_3mrad_j5,slip_3mrad_j6,\
         slip_10mrad_j4,slip_10mrad_j5,slip_10mrad_j6,slip_30mrad_j4,slip_30mrad_j5,slip_30mrad_j6\n"
    ));
    cli(&[
        "sil",
        "--model",
        &model,
        "--seconds",
        "0.3",
        "--markdown",
        &md,
        "--json",
        &json,
    ])
    .unwrap();
    let md = std::fs::read_to_string(&md).unwrap();
    assert!(
        md.contains("| feedforward | joint | RMS error [mrad]"),
        "{md}"
    );
    assert_eq!(md.matches("| model | ").count(), 3, "{md}");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let results = v["results"].as_array().unwrap();
    assert_eq!(results.len(), 2, "none and model (no --lstm)");
    for r in results {
        let joints = r["joints"].as_array().unwrap();
        assert_eq!(joints.len(), 3);
        for j in joints {
            assert!(j["rms_error_rad"].as_f64().unwrap() > 0.0);
            assert!(j["rms_iq_a"].as_f64().unwrap() > 0.0);
        }
    }
    // An LSTM needs the model it corrects.
    assert!(cli(&["sil", "--lstm", &p("x.safetensors")]).is_err());
}
