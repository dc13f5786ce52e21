//! The excitation tests' robot and small design, shared by the design's tests, the
//! identification along it and the command line's (`#[path]`-included, one source).
#![allow(dead_code)]

use excitation::robot_model::{LimitOverrides, RobotObservation, joint_limits};
use excitation::{ExcitationDesign, ExcitationSettings, FourierFamily, JointLimits, design};
use robot::Robot;

/// The test robot: `robots/default.toml` when present, else the UR10e URDF under the
/// datasets directory (printing a skip line and giving `None` when neither exists).
pub fn test_robot() -> Option<(Robot, LimitOverrides)> {
    let default = test_support::robots_dir().join("default.toml");
    if default.exists() {
        return Some((
            Robot::load(&default).expect("default robot loads"),
            LimitOverrides::default(),
        ));
    }
    let datasets = test_support::datasets_dir()
        .unwrap_or_else(|| test_support::workspace_root().join("../shared/datasets"));
    let urdf = datasets.join("ur10e/ur10e.urdf");
    if urdf.exists() {
        // The URDF gives no acceleration limits: use 8 rad/s² (the default robot's estimate).
        let o = LimitOverrides {
            qdd_max_rad_s2: Some(8.0),
            ..LimitOverrides::default()
        };
        return Some((Robot::load(&urdf).expect("UR10e URDF loads"), o));
    }
    let what = format!("robots/default.toml or {}", urdf.display());
    test_support::skip("the excitation tests", &what, true);
    None
}

/// Every limit on a 2 kHz grid (20x the controller rate, twice the design's grid) and rest at
/// both ends (q = 0, zero velocity and acceleration) within 1e-9.
pub fn assert_admissible(tr: &excitation::ExcitationTrajectory, lim: &[JointLimits]) {
    let dense = tr.sample(2000.0, 1);
    let mut worst: f64 = 0.0;
    for k in 0..dense.t_s.len() {
        for (j, l) in lim.iter().enumerate() {
            let q = dense.q_rad[k][j];
            assert!(
                q <= l.q_max_rad + 1e-9 && q >= l.q_min_rad - 1e-9,
                "q{j} = {q}"
            );
            let v = dense.qd_rad_s[k][j].abs() / l.qd_max_rad_s;
            let a = dense.qdd_rad_s2[k][j].abs() / l.qdd_max_rad_s2;
            worst = worst.max(v).max(a);
        }
    }
    assert!(worst <= 1.0 + 1e-6, "limit utilisation {worst}");
    for t in [0.0, tr.period_s] {
        let p = tr.eval(t);
        for j in 0..lim.len() {
            assert!(p.q_rad[j].abs() < 1e-9, "q{j}({t}) = {}", p.q_rad[j]);
            assert!(p.qd_rad_s[j].abs() < 1e-9, "qd{j}({t}) = {}", p.qd_rad_s[j]);
            assert!(p.qdd_rad_s2[j].abs() < 1e-9, "qdd{j}({t})");
        }
    }
}

/// The tests' small design (1 run × 1500 evaluations, 100 scoring samples, rest at zero)
/// under `overrides`, checked admissible: its limits, family and design.
pub fn small_design(
    model: &RobotObservation,
    overrides: &LimitOverrides,
) -> (Vec<JointLimits>, FourierFamily, ExcitationDesign) {
    let limits: Vec<JointLimits> = joint_limits(model.robot(), overrides).unwrap();
    let rest = vec![0.0; limits.len()];
    let settings = ExcitationSettings {
        restarts: 1,
        evaluations_per_restart: 1500,
        objective_samples: 100,
        ..ExcitationSettings::default()
    };
    let family = FourierFamily::new(10.0, 5, &rest, &limits, &[], 1000.0).unwrap();
    let d = design(model, family.clone(), &settings).unwrap();
    assert!(
        d.margins.iter().all(|m| m.margin >= -1e-9),
        "{:?}",
        d.margins
    );
    assert_admissible(&d.trajectory, &limits);
    (limits, family, d)
}
