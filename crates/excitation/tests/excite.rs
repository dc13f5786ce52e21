//! Excitation design on a small hand-written model (no robot needed): limits on a dense grid,
//! exact start and end conditions, improvement over random feasible trajectories, infeasibility
//! errors, output files.

use excitation::constraints::tightest;
use excitation::objective::condition_number;
use excitation::objective::observation_matrix;
use excitation::output::{ExcitationFile, OutputPaths, PlaybackLayout, write_outputs};
use excitation::toy::PendulumChain;
use excitation::{
    BaselineScaling, Derivative, ExcitationSettings, ExcitationTrajectory, FourierFamily,
    JointLimits, PointConstraint, design, random_feasible,
};

fn limits(n: usize) -> Vec<JointLimits> {
    vec![JointLimits::symmetric(2.5, 1.2, 3.0); n]
}

fn quick_settings() -> ExcitationSettings {
    ExcitationSettings {
        restarts: 2,
        evaluations_per_restart: 1500,
        objective_samples: 100,
        ..ExcitationSettings::default()
    }
}

/// Checks every limit on a grid 20× finer than the controller rate (twice the design's grid),
/// and the rest conditions at both ends to 1e-9.
fn assert_admissible(tr: &ExcitationTrajectory, rest: &[f64], lim: &[JointLimits]) {
    let dense = tr.sample(100.0 * 20.0, 1);
    for k in 0..dense.t_s.len() {
        for (j, l) in lim.iter().enumerate() {
            let (q, qd, qdd) = (
                dense.q_rad[k][j],
                dense.qd_rad_s[k][j],
                dense.qdd_rad_s2[k][j],
            );
            let tol = 1e-6;
            assert!(
                q <= l.q_max_rad + tol && q >= l.q_min_rad - tol,
                "q{j}({}) = {q}",
                dense.t_s[k]
            );
            assert!(
                qd.abs() <= l.qd_max_rad_s * (1.0 + tol),
                "qd{j}({}) = {qd}",
                dense.t_s[k]
            );
            assert!(
                qdd.abs() <= l.qdd_max_rad_s2 * (1.0 + tol),
                "qdd{j}({}) = {qdd}",
                dense.t_s[k]
            );
        }
    }
    for t in [0.0, tr.period_s] {
        let p = tr.eval(t);
        for (j, r) in rest.iter().enumerate() {
            assert!((p.q_rad[j] - r).abs() < 1e-9, "q{j}({t}) = {}", p.q_rad[j]);
            assert!(p.qd_rad_s[j].abs() < 1e-9, "qd{j}({t}) = {}", p.qd_rad_s[j]);
            assert!(
                p.qdd_rad_s2[j].abs() < 1e-9,
                "qdd{j}({t}) = {}",
                p.qdd_rad_s2[j]
            );
        }
    }
}

#[test]
fn optimised_design_is_admissible_and_beats_random_trajectories() {
    let model = PendulumChain { joints: 3 };
    let rest = [0.0, 0.3, -0.2];
    let lim = limits(3);
    let settings = quick_settings();
    let family = FourierFamily::new(settings.period_s, 5, &rest, &lim, &[], 1000.0).unwrap();
    let d = design(&model, family.clone(), &settings).unwrap();
    assert_admissible(&d.trajectory, &rest, &lim);
    assert!(
        d.margins.iter().all(|m| m.margin >= -1e-12),
        "{:?}",
        d.margins
    );
    assert_eq!(d.margins.len(), 12);
    assert!(d.evaluations >= 2 * 100, "evaluations {}", d.evaluations);
    // Baseline: the median of several random feasible trajectories.
    let mut random: Vec<f64> = (0..5)
        .map(|s| {
            let tr = random_feasible(&family, 100 + s, BaselineScaling::PerJoint);
            assert_admissible(&tr, &rest, &lim);
            condition_number(&observation_matrix(&model, &tr, 100.0))
        })
        .collect();
    random.sort_by(f64::total_cmp);
    println!(
        "toy 3-joint: optimised cond {:.2}, random feasible cond (median of 5) {:.2}",
        d.score.condition, random[2]
    );
    assert!(
        d.score.condition < random[0],
        "worse than the best random trajectory"
    );
    assert!(
        d.score.condition * 2.0 < random[2],
        "not 2x better than the median"
    );
}

#[test]
fn same_seed_gives_the_same_design() {
    let model = PendulumChain { joints: 2 };
    let lim = limits(2);
    let settings = ExcitationSettings {
        restarts: 1,
        evaluations_per_restart: 300,
        ..quick_settings()
    };
    let fam = FourierFamily::new(10.0, 5, &[0.0, 0.0], &lim, &[], 1000.0).unwrap();
    let a = design(&model, fam.clone(), &settings).unwrap();
    let b = design(&model, fam, &settings).unwrap();
    assert_eq!(a.trajectory, b.trajectory);
}

#[test]
fn point_constraint_holds_on_the_test_trajectory() {
    // The paper's test trajectory: q_i(3.8 s) = 0 on every moving joint, here with a rest pose
    // away from zero so the particular solution is not constant.
    let model = PendulumChain { joints: 2 };
    let rest = [0.2, -0.1];
    let lim = limits(2);
    let extra: Vec<PointConstraint> = (0..2)
        .map(|j| PointConstraint {
            joint: j,
            t_s: 3.8,
            derivative: Derivative::Position,
            value: 0.0,
        })
        .collect();
    let fam = FourierFamily::new(10.0, 5, &rest, &lim, &extra, 1000.0).unwrap();
    let d = design(&model, fam, &quick_settings()).unwrap();
    assert_admissible(&d.trajectory, &rest, &lim);
    let p = d.trajectory.eval(3.8);
    assert!(p.q_rad.iter().all(|q| q.abs() < 1e-9), "{:?}", p.q_rad);
}

#[test]
fn infeasible_problem_names_the_tightest_constraint() {
    // Rest at 0 and q(5 s) = 2 rad within 1 s... of period 10 s with a 0.05 rad/s velocity
    // limit: impossible; the velocity limit of joint 0 must be named.
    let model = PendulumChain { joints: 1 };
    let lim = [JointLimits::symmetric(3.0, 0.05, 10.0)];
    let extra = [PointConstraint {
        joint: 0,
        t_s: 5.0,
        derivative: Derivative::Position,
        value: 2.0,
    }];
    let fam = FourierFamily::new(10.0, 3, &[0.0], &lim, &extra, 1000.0).unwrap();
    let settings = ExcitationSettings {
        restarts: 2,
        evaluations_per_restart: 800,
        ..quick_settings()
    };
    let err = design(&model, fam, &settings).unwrap_err().to_string();
    println!("{err}");
    assert!(err.contains("moving joint #0 velocity limit"), "{err}");
}

#[test]
fn outputs_are_written_and_read_back() {
    let model = PendulumChain { joints: 2 };
    let lim = limits(2);
    let settings = ExcitationSettings {
        restarts: 1,
        evaluations_per_restart: 200,
        ..quick_settings()
    };
    let fam = FourierFamily::new(10.0, 5, &[0.0, 0.0], &lim, &[], 1000.0).unwrap();
    let d = design(&model, fam, &settings).unwrap();
    let layout = PlaybackLayout {
        joint_names: vec!["a".into(), "b".into(), "c".into()],
        moving: vec![0, 2],
        fixed_rad: vec![0.0, 0.7, 0.0],
    };
    let file = ExcitationFile::new("toy", layout, &lim, &[], &d, None);
    let dir = tempfile::tempdir().unwrap();
    let paths = OutputPaths {
        json: dir.path().join("e.json"),
        csv: dir.path().join("e.csv"),
        plot: Some(dir.path().join("e.svg")),
    };
    write_outputs(&file, &["a".into(), "c".into()], &paths).unwrap();
    let back = ExcitationFile::read(&paths.json).unwrap();
    assert_eq!(back.trajectory, d.trajectory);
    let mut rd = csv::Reader::from_path(&paths.csv).unwrap();
    let header: Vec<String> = rd.headers().unwrap().iter().map(String::from).collect();
    assert_eq!(header.len(), 1 + 9);
    assert_eq!(header[0], "t_s");
    assert_eq!(header[2], "q2_rad");
    let rows: Vec<csv::StringRecord> = rd.records().map(|r| r.unwrap()).collect();
    assert_eq!(rows.len(), 1001);
    let mid: Vec<f64> = rows[437].iter().map(|v| v.parse().unwrap()).collect();
    let p = d.trajectory.eval(mid[0]);
    assert!((mid[1] - p.q_rad[0]).abs() < 1e-10 && (mid[3] - p.q_rad[1]).abs() < 1e-10);
    assert_eq!(mid[2], 0.7);
    assert!((mid[4 + 2] - p.qd_rad_s[1]).abs() < 1e-10);
    assert!((mid[7] - p.qdd_rad_s2[0]).abs() < 1e-10);
    let svg = std::fs::read_to_string(paths.plot.as_ref().unwrap()).unwrap();
    assert!(svg.contains("<svg") && svg.contains("velocity"));
    // No temporary files left behind.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 3);
    let _ = tightest(&d.margins).unwrap();
}
