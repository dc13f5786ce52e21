//! The predictor adapters against what they are specified to be: the rigid-body model
//! as a predictor is the model's torques on each joint's *reference* (the measured
//! fields play no part), and an f32 or quantised network behind `TorqueNetwork`
//! starts from the zero state and steps exactly as the network itself does.

use firmware::control::{
    JointState, LstmPredictor, PredictorInput, TorqueNetwork, TorquePredictor,
};
use firmware::nn::format::FeaturePreset;
use firmware::nn::kernels::F32State;
use test_kit::fixtures::{bench_paper_f32 as f32_model, bench_paper_int16 as i16_model};

/// Six joints in motion: reference and measured fields all different.
fn moving_input(k: usize) -> PredictorInput<6> {
    let t = k as f32 * 0.01;
    let joints: [JointState; 6] = core::array::from_fn(|j| {
        let p = 0.3 * j as f32 + t;
        JointState {
            q_ref_rad: 0.8 * p.sin(),
            qd_ref_rad_s: 1.2 * p.cos(),
            qdd_ref_rad_s2: -2.0 * p.sin(),
            q_meas_rad: -0.5 + 0.1 * j as f32,
            qd_meas_rad_s: 0.7,
            tau_meas_nm: 4.0 - j as f32,
        }
    });
    PredictorInput {
        joints,
        own_joint: 4,
        model_nm: [0.0; 6],
    }
}

#[test]
fn the_rigid_body_model_predicts_its_torques_on_the_references() {
    let mut model = f32_model::DYNAMICS;
    for k in 0..20 {
        let input = moving_input(k);
        let want = f32_model::DYNAMICS.torques(
            &input.joints.map(|s| s.q_ref_rad),
            &input.joints.map(|s| s.qd_ref_rad_s),
            &input.joints.map(|s| s.qdd_ref_rad_s2),
        );
        assert!(want.iter().all(|t| t.is_finite()));
        // Not a constant: joints with other loads have other torques.
        assert!(want.iter().any(|t| t.abs() > 1.0), "{want:?}");
        assert_eq!(model.predict_nm(&input), want, "tick {k}");
        // The measured fields are not read.
        let mut other = input;
        for s in &mut other.joints {
            (s.q_meas_rad, s.qd_meas_rad_s, s.tau_meas_nm) = (2.0, -3.0, 50.0);
        }
        assert_eq!(model.predict_nm(&other), want, "tick {k}");
    }
}

/// A paper-preset input of 9 features (3 joints) that changes every step.
fn paper_features(k: usize) -> [f32; 9] {
    core::array::from_fn(|i| ((k * 9 + i) as f32 * 0.37).sin() * 5.0)
}

#[test]
fn an_f32_network_steps_behind_the_adapter_as_it_does_alone() {
    let net = &f32_model::NETWORK;
    let mut alone = f32_model::State::new();
    let mut adapted = TorqueNetwork::<9, 3>::zero_state(net);
    assert_eq!(adapted, F32State::new());
    let mut outputs = Vec::new();
    for k in 0..10 {
        let x = paper_features(k);
        let want = net.step(&mut alone, &x);
        let got = TorqueNetwork::<9, 3>::step(net, &mut adapted, &x);
        assert_eq!(got.map(f32::to_bits), want.map(f32::to_bits), "step {k}");
        assert_eq!(adapted, alone);
        outputs.push(got);
    }
    // The outputs depend on the input: no two steps alike, none a constant 0 or +-1.
    for (k, y) in outputs.iter().enumerate() {
        assert!(
            y.iter()
                .all(|v| v.is_finite() && v.abs() != 1.0 && *v != 0.0),
            "{y:?}"
        );
        assert!(outputs[..k].iter().all(|o| o != y), "step {k} repeats");
    }
}

#[test]
fn the_lstm_stage_runs_an_f32_network_from_the_zero_state_after_a_reset() {
    // Paper preset: the stage feeds (previous model torque, measured torque, previous
    // position) per joint, all joints of one kind together.
    let mut stage =
        LstmPredictor::<_, 3, 9>::new(&f32_model::NETWORK, FeaturePreset::Paper).unwrap();
    let input = |k: usize| {
        let f = paper_features(k);
        let joints: [JointState; 3] = core::array::from_fn(|j| JointState {
            q_ref_rad: f[6 + j],
            tau_meas_nm: f[3 + j],
            ..Default::default()
        });
        PredictorInput {
            joints,
            own_joint: 0,
            model_nm: [f[0], f[1], f[2]],
        }
    };
    for _ in 0..2 {
        let mut state = f32_model::State::new();
        let mut previous: Option<([f32; 3], [f32; 3])> = None;
        for k in 0..6 {
            let f = paper_features(k);
            let (model, q) = previous.unwrap_or(([f[0], f[1], f[2]], [f[6], f[7], f[8]]));
            let x = [
                model[0], model[1], model[2], f[3], f[4], f[5], q[0], q[1], q[2],
            ];
            let want = f32_model::NETWORK.step(&mut state, &x);
            assert_eq!(stage.predict_nm(&input(k)), want, "tick {k}");
            previous = Some(([f[0], f[1], f[2]], [f[6], f[7], f[8]]));
        }
        // After a reset the same ticks give the same torques (zero state, no previous).
        stage.reset();
    }
}

#[test]
fn a_quantised_network_starts_from_the_zero_state() {
    let net = &i16_model::NETWORK;
    let zero = TorqueNetwork::<9, 3>::zero_state(net);
    assert_eq!(zero, i16_model::State::new());
    assert!(zero.z.iter().flatten().all(|&v| v == 0) && zero.c.iter().all(|&v| v == 0));
}

/// A network that keeps the last input it was given and outputs zeros.
struct Recorder<const I: usize, const O: usize>(core::cell::Cell<[f32; I]>);

impl<const I: usize, const O: usize> TorqueNetwork<I, O> for Recorder<I, O> {
    type State = ();
    fn zero_state(&self) {}
    fn step(&self, _: &mut (), x: &[f32; I]) -> [f32; O] {
        self.0.set(*x);
        [0.0; O]
    }
}

#[test]
fn the_drive_stage_lays_out_two_joints_one_kind_after_the_other() {
    // The drive layout: feature `kind` of joint `j` is input `kind * J + j`, and a
    // joint's features are those the one-joint stage computes from that joint alone.
    const K: usize = firmware::features::DRIVE_INPUTS_PER_JOINT;
    let two = Recorder::<{ 2 * K }, 2>(core::cell::Cell::new([0.0; 2 * K]));
    let ones = [0, 1].map(|_| Recorder::<K, 1>(core::cell::Cell::new([0.0; K])));
    let mut stage2 = LstmPredictor::<_, 2, { 2 * K }>::new(&two, FeaturePreset::Drive).unwrap();
    let mut stage1 = [&ones[0], &ones[1]]
        .map(|n| LstmPredictor::<_, 1, K>::new(n, FeaturePreset::Drive).unwrap());
    let mut differing = 0;
    for k in 0..40 {
        let t = k as f32 * 0.05;
        let joint = |j: usize| JointState {
            q_ref_rad: (1.0 + j as f32) * (t + 0.4 * j as f32).sin(),
            qd_ref_rad_s: (2.0 - j as f32) * (t + 0.4 * j as f32).cos(),
            qdd_ref_rad_s2: 0.5 + j as f32,
            ..Default::default()
        };
        let model = [3.0 + t, -7.0 * t];
        stage2.predict_nm(&PredictorInput {
            joints: [joint(0), joint(1)],
            own_joint: 0,
            model_nm: model,
        });
        let x2 = two.0.get();
        for j in 0..2 {
            stage1[j].predict_nm(&PredictorInput {
                joints: [joint(j)],
                own_joint: 0,
                model_nm: [model[j]],
            });
        }
        let x1 = ones.each_ref().map(|n| n.0.get());
        for kind in 0..K {
            for j in 0..2 {
                assert_eq!(
                    x2[kind * 2 + j],
                    x1[j][kind],
                    "tick {k}, kind {kind}, joint {j}"
                );
            }
            differing += usize::from(x1[0][kind] != x1[1][kind]);
        }
    }
    // The two joints' features differ, so a swapped layout would be seen.
    assert!(differing > 40 * K / 2, "{differing}");
}
