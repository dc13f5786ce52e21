//! The firmware's predictor stages on the fixture models: the LSTM stage's feature
//! layouts on the per-joint bench network, the subset model on the paper bench
//! model's 6-joint dynamics.
use firmware::control::{JointState, LstmPredictor, PredictorInput, SubsetModel, TorquePredictor};
use firmware::nn::format::FeaturePreset;
use test_kit::fixtures::{bench_joint_int16 as net1, bench_paper_int16 as dm};

fn input1(q: f32, qd: f32, tau_meas: f32, model: f32) -> PredictorInput<1> {
    PredictorInput {
        joints: [JointState {
            q_ref_rad: q,
            qd_ref_rad_s: qd,
            tau_meas_nm: tau_meas,
            ..Default::default()
        }],
        own_joint: 0,
        model_nm: [model],
    }
}

#[test]
fn paper_stage_pairs_the_previous_model_torque_with_the_new_measurement() {
    let mut p = LstmPredictor::<_, 1, 3>::new(&net1::NETWORK, FeaturePreset::Paper).unwrap();
    let mut st = net1::State::new();
    // First tick after a reset: no previous tick, this tick's values.
    let y = p.predict_nm(&input1(0.3, 1.0, 2.0, 1.5));
    assert_eq!(y, net1::NETWORK.step(&mut st, &[1.5, 2.0, 0.3]));
    // Then: previous model torque and position, this tick's measured torque.
    let y = p.predict_nm(&input1(0.4, 1.0, 2.5, 1.7));
    assert_eq!(y, net1::NETWORK.step(&mut st, &[1.5, 2.5, 0.3]));
    let y = p.predict_nm(&input1(0.5, 1.0, 2.6, 1.9));
    assert_eq!(y, net1::NETWORK.step(&mut st, &[1.7, 2.6, 0.4]));
    // Reset forgets both the recurrent state and the previous tick.
    p.reset();
    let mut st = net1::State::new();
    let y = p.predict_nm(&input1(0.6, 1.0, 2.7, 2.0));
    assert_eq!(y, net1::NETWORK.step(&mut st, &[2.0, 2.7, 0.6]));
}

#[test]
fn feedforward_stage_adds_the_residual_to_the_model() {
    let mut p = LstmPredictor::<_, 1, 3>::new(&net1::NETWORK, FeaturePreset::Feedforward).unwrap();
    let mut st = net1::State::new();
    for k in 0..5 {
        let (q, qd, m) = (0.1 * k as f32, 0.5, 3.0 + k as f32);
        let y = p.predict_nm(&input1(q, qd, 9.0, m));
        let r = net1::NETWORK.step(&mut st, &[m, q, qd]);
        assert_eq!(y, [m + r[0]]);
    }
    assert!(LstmPredictor::<_, 1, 3>::new(&net1::NETWORK, FeaturePreset::Custom).is_none());
}

#[test]
fn subset_model_is_the_full_model_with_the_other_joints_at_rest() {
    let mut sub = SubsetModel {
        model: &dm::DYNAMICS,
        joints: [3, 4, 5],
        fixed_q_rad: [0.0; 6],
    };
    let s = |q: f32, qd: f32, qdd: f32| JointState {
        q_ref_rad: q,
        qd_ref_rad_s: qd,
        qdd_ref_rad_s2: qdd,
        ..Default::default()
    };
    let input = PredictorInput {
        joints: [s(0.3, 0.5, 2.0), s(-0.7, -1.0, 1.0), s(1.1, 0.2, -3.0)],
        own_joint: 1,
        model_nm: [0.0; 3],
    };
    let y = sub.predict_nm(&input);
    let full = dm::DYNAMICS.torques(
        &[0.0, 0.0, 0.0, 0.3, -0.7, 1.1],
        &[0.0, 0.0, 0.0, 0.5, -1.0, 0.2],
        &[0.0, 0.0, 0.0, 2.0, 1.0, -3.0],
    );
    assert_eq!(y, [full[3], full[4], full[5]]);
    assert!(y.iter().all(|t| t.is_finite() && *t != 0.0));
    // A wrong index gives NaN (rejected by the compensator), never a panic.
    sub.joints = [3, 4, 9];
    assert!(sub.predict_nm(&input)[2].is_nan());
}
