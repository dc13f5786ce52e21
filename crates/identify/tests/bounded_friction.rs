//! One joint's friction identified on slow motion and evaluated on faster motion: the
//! first stage's extended friction is continued linearly beyond the identified speeds
//! (bounded error, where the plain basis extrapolated its quadratic drag), and a very
//! slow run with the extended basis identifies, naming what it cannot identify.

use identify::identified::{ModelSelection, RobotBaseModel, load_robot, predict_log};
use identify::pipeline::{self, LinearModel};
use identify::{IdentifyOptions, Weighting, solve};
use logs::Samples;
use nalgebra::DVector;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use robot::dynamics::firmware_model::FirmwareModel;
use robot::{IdentifiedRanges, RobotSource};
use std::path::PathBuf;

/// The wrist joint (6) of the test arm, the others locked at 0, with the extended
/// friction basis and a smoothed Coulomb sign.
fn wrist_model() -> RobotBaseModel {
    let path = test_support::workspace_root().join("crates/identify/tests/data/ur_type_6r.toml");
    let sel = ModelSelection {
        locked: (0..5).map(|i| (i, 0.0)).collect(),
        extended_friction: true,
        coulomb_smoothing_rad_s: Some(0.02),
        ..Default::default()
    };
    RobotBaseModel::new(load_robot(&RobotSource::File(path), &sel).unwrap().robot).unwrap()
}

/// The "true" friction of the joint [N·m] (not in the model's basis): Coulomb with a
/// Stribeck peak at low speed and viscous drag.
fn true_friction_nm(qd: f64) -> f64 {
    let (fc, fs, vs, fv) = (0.3, 0.45, 0.1, 0.25);
    (fc + (fs - fc) * (-(qd / vs).powi(2)).exp()) * (qd / 0.01).tanh() + fv * qd
}

/// A sinusoidal motion of joint 6 reaching `peak_rad_s`, 3000 samples at 100 Hz; the
/// torque is the rigid body (nominal) plus the true friction plus seeded noise.
fn run(m: &RobotBaseModel, peak_rad_s: f64, seed: u64) -> Samples {
    let n = 3000;
    let w = 2.0 * std::f64::consts::PI / 6.0;
    let t: Vec<f64> = (0..n).map(|k| k as f64 * 0.01).collect();
    let mut s = Samples {
        path: PathBuf::from(format!("sim_{peak_rad_s}")),
        sha256: String::new(),
        time_s: t.clone(),
        q_rad: vec![vec![0.0; n]; 6],
        qd_rad_s: vec![vec![0.0; n]; 6],
        qdd_rad_s2: vec![vec![0.0; n]; 6],
        torque_nm: None,
    };
    for (k, tk) in t.iter().enumerate() {
        s.q_rad[5][k] = peak_rad_s / w * (w * tk).sin();
        s.qd_rad_s[5][k] = peak_rad_s * (w * tk).cos();
        s.qdd_rad_s2[5][k] = -peak_rad_s * w * (w * tk).sin();
    }
    let beta = m.base.beta(&m.robot.standard_parameters());
    let rigid = pipeline::predict(m, &rigid_only(m, &beta), &s);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 0.02).unwrap();
    let mut tau = vec![vec![0.0; n]; 6];
    for k in 0..n {
        tau[5][k] = rigid[0][k] + true_friction_nm(s.qd_rad_s[5][k]) + noise.sample(&mut rng);
    }
    s.torque_nm = Some(tau);
    s
}

/// `beta` with its friction parameters zeroed (the rigid body alone).
fn rigid_only(m: &RobotBaseModel, beta: &DVector<f64>) -> DVector<f64> {
    let mut b = beta.clone();
    for (i, e) in m.expressions().iter().enumerate() {
        let def = e.split_once(" = ").map_or("", |(_, d)| d.trim());
        if def.starts_with('f') {
            b[i] = 0.0;
        }
    }
    b
}

fn ranges(logs: &[Samples]) -> IdentifiedRanges {
    let span = |f: &dyn Fn(&Samples) -> &Vec<f64>| {
        let v = logs.iter().flat_map(|s| f(s).iter().copied());
        let lo = v.clone().fold(f64::INFINITY, f64::min);
        [lo, v.fold(f64::NEG_INFINITY, f64::max)]
    };
    IdentifiedRanges {
        q_rad: span(&|s| &s.q_rad[5]),
        qd_rad_s: span(&|s| &s.qd_rad_s[5]),
        qdd_rad_s2: span(&|s| &s.qdd_rad_s2[5]),
    }
}

fn identify(m: &RobotBaseModel, logs: &[Samples]) -> identify::Identification {
    let mut ne = pipeline::accumulate(m, logs);
    let opt = IdentifyOptions {
        weighting: Weighting::PerJointFromOls,
        prior: Some(
            m.base
                .beta(&m.robot.standard_parameters())
                .iter()
                .copied()
                .collect(),
        ),
        ..Default::default()
    };
    solve(&mut ne, &m.expressions(), &opt).expect("identifies")
}

/// RMS of the firmware model's torque against the noise-free truth on `s`.
fn rms_vs_truth(m: &RobotBaseModel, fw: &FirmwareModel, s: &Samples) -> f64 {
    let pred = predict_log(fw, &m.modelled_log_joints(), s);
    let beta = m.base.beta(&m.robot.standard_parameters());
    let rigid = pipeline::predict(m, &rigid_only(m, &beta), s);
    let se: f64 = (0..s.len())
        .map(|k| {
            let truth = rigid[0][k] + true_friction_nm(s.qd_rad_s[5][k]);
            (pred[0][k] - truth).powi(2)
        })
        .sum();
    (se / s.len() as f64).sqrt()
}

#[test]
fn friction_identified_slow_stays_bounded_on_faster_motion() {
    let mut m = wrist_model();
    let train = [run(&m, 0.15, 1), run(&m, 0.4, 2)];
    let test = run(&m, 1.5, 3);
    let id = identify(&m, &train);
    let theta = m.equivalent_standard(&DVector::from_vec(id.values.clone()));
    // The old first stage: the extended basis evaluated at any speed.
    let plain = FirmwareModel::build(&m.robot, &theta).unwrap();
    m.robot.identified_ranges = vec![ranges(&train)];
    let bounded = FirmwareModel::build(&m.robot, &theta).unwrap();
    let inside = rms_vs_truth(&m, &bounded, &train[1]);
    let inside_plain = rms_vs_truth(&m, &plain, &train[1]);
    let e_plain = rms_vs_truth(&m, &plain, &test);
    let e_bounded = rms_vs_truth(&m, &bounded, &test);
    let truth_rms = {
        let v: f64 = test.qd_rad_s[5]
            .iter()
            .map(|&v| true_friction_nm(v).powi(2))
            .sum();
        (v / test.len() as f64).sqrt()
    };
    let msg = format!(
        "RMS vs truth at 1.5 rad/s (identified up to 0.4): bounded {e_bounded:.4} N·m, \
         plain extrapolation {e_plain:.4} N·m; friction RMS {truth_rms:.4} N·m; inside the \
         range {inside:.4} (plain {inside_plain:.4}); dropped {:?}",
        id.dropped.iter().map(|d| d.to_string()).collect::<Vec<_>>()
    );
    println!("{msg}");
    // Inside the identified speeds, the same torque bit for bit.
    assert_eq!(inside, inside_plain, "{msg}");
    // Beyond them, bounded: a fraction of the friction torque itself, and well below
    // the plain basis' extrapolation.
    assert!(e_bounded < 0.25 * truth_rms, "{msg}");
    assert!(e_bounded < 0.5 * e_plain, "{msg}");
}

#[test]
fn a_very_slow_run_identifies_and_names_what_it_cannot() {
    let m = wrist_model();
    let slow = run(&m, 0.03, 4);
    let id = identify(&m, std::slice::from_ref(&slow));
    let names: Vec<String> = id
        .dropped
        .iter()
        .flat_map(|d| d.parameters.iter().map(|(n, _)| n.clone()))
        .collect();
    println!(
        "dropped: {:?}; rms {:?} N·m",
        id.dropped.iter().map(|d| d.to_string()).collect::<Vec<_>>(),
        id.rms_nm
    );
    assert!(!id.dropped.is_empty());
    // The drag terms of speeds the run never reached are among the dropped.
    assert!(
        names
            .iter()
            .any(|n| n.contains("fq6") || n.contains("fs3_6")),
        "{names:?}"
    );
    // What the data holds is fitted: the residual is at the noise level.
    assert!(id.rms_nm[0] < 0.05, "{:?}", id.rms_nm);
}
