//! Identification on simulated logs of a UR-type 6R arm (torque = regressor x true
//! parameters): exact recovery without noise, estimates within three standard deviations
//! with noise, the firmware's f32 model against the f64 regressor (through the command
//! line: `model-export/tests/identify_command.rs`).
#![allow(clippy::needless_range_loop)]

use identify::identified::{BASE_SEED, predict_log};
use identify::pipeline::{self, LinearModel};
use identify::{IdentifyOptions, Weighting, solve};
use robot::base::BaseParameters;
use robot::dynamics::firmware_model::FirmwareModel;

#[path = "support/arm.rs"]
mod arm;
use arm::{robot_model, simulate, true_beta};

#[test]
fn six_dof_noise_free_recovers_base_parameters_to_1e_6() {
    let m = robot_model();
    assert_eq!(m.base.count(), m.parameter_names().len());
    let logs = [simulate(&m, 4000, 1, None)];
    let beta = true_beta(&m);
    let scale = beta.amax();
    for w in [Weighting::Ordinary, Weighting::PerJointFromOls] {
        let mut ne = pipeline::accumulate(&m, &logs);
        let opt = IdentifyOptions {
            weighting: w.clone(),
            ..Default::default()
        };
        let id = solve(&mut ne, &m.parameter_names(), &opt).unwrap();
        for i in 0..beta.len() {
            let err = (id.values[i] - beta[i]).abs();
            assert!(
                err <= (1e-6 * beta[i].abs()).max(1e-9 * scale),
                "{w:?} {}: {} vs {} ({})",
                m.parameter_names()[i],
                id.values[i],
                beta[i],
                m.expressions()[i]
            );
        }
    }
}

#[test]
fn six_dof_noisy_estimates_lie_within_three_std() {
    let m = robot_model();
    let sigma = [1.0, 1.0, 0.5, 0.2, 0.2, 0.1];
    let logs = [simulate(&m, 20_000, 2, Some(&sigma))];
    let beta = true_beta(&m);
    let mut ne = pipeline::accumulate(&m, &logs);
    let opt = IdentifyOptions {
        weighting: Weighting::PerJointFromOls,
        ..Default::default()
    };
    let id = solve(&mut ne, &m.parameter_names(), &opt).unwrap();
    let mut worst: f64 = 0.0;
    for i in 0..beta.len() {
        let z = (id.values[i] - beta[i]).abs() / id.std[i];
        worst = worst.max(z);
        assert!(
            z < 3.0,
            "{}: {} vs {} std {}",
            m.parameter_names()[i],
            id.values[i],
            beta[i],
            id.std[i]
        );
    }
    for j in 0..6 {
        assert!(
            (id.joint_sigma_nm[j] / sigma[j] - 1.0).abs() < 0.05,
            "{:?}",
            id.joint_sigma_nm
        );
    }
    println!(
        "largest |error| / std over {} base parameters: {worst:.2}",
        beta.len()
    );
}

#[test]
fn firmware_f32_model_matches_f64_regressor_with_identified_parameters() {
    let m = robot_model();
    let s = simulate(&m, 500, 3, None);
    let theta = m.equivalent_standard(&true_beta(&m));
    let fw = FirmwareModel::build(&m.robot, &theta).unwrap();
    let joints = m.modelled_log_joints();
    let p32 = predict_log(&fw, &joints, &s);
    let p64 = pipeline::predict(&m, &true_beta(&m), &s);
    let scale = p64.iter().flatten().fold(0.0f64, |a, v| a.max(v.abs()));
    let diff = pipeline::max_abs_difference(&p32, &p64);
    assert!(
        diff < 1e-4 * scale,
        "max diff {diff} (torque scale {scale})"
    );
    // The base parameters recomputed with the fixed seed are identical.
    let again = BaseParameters::compute(&m.robot, BASE_SEED).unwrap();
    assert_eq!(again.expressions(), m.expressions());
}

// ---- through the binary ----
