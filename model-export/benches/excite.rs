//! Excitation design benchmark: `cargo bench -p model-export --bench excite`.
//!
//! Designs the paper's wrist trajectory (3 joints, 5 harmonics) and a 6-joint trajectory with
//! the default settings, and prints a table: evaluations, wall time, optimised condition number
//! and the median condition number of 5 random feasible trajectories of the same family
//! (scaled onto their tightest limit). Targets: 3 joints < 60 s, 6 joints < 5 min.
//!
//! Robot: `model-export/robots/default.toml` if present, else the UR10e URDF under
//! `$DATASETS_DIR` (default `../shared/datasets`), with 8 rad/s² acceleration limits.

use model_export::excite::objective::{condition_number, observation_matrix};
use model_export::excite::robot_model::{LimitOverrides, RobotObservation, joint_limits};
use model_export::excite::{ExcitationSettings, FourierFamily, design, random_feasible};
use model_export::robot::Robot;
use std::path::PathBuf;

fn robot() -> Option<(Robot, LimitOverrides)> {
    let manifest = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let default = manifest.join("robots/default.toml");
    if default.exists() {
        return Some((Robot::load(&default).ok()?, LimitOverrides::default()));
    }
    let datasets = std::env::var_os("DATASETS_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| manifest.join("../../shared/datasets"));
    let urdf = datasets.join("ur10e/ur10e.urdf");
    let o = LimitOverrides {
        qdd_max_rad_s2: Some(8.0),
        ..LimitOverrides::default()
    };
    Robot::load(&urdf).ok().map(|r| (r, o))
}

fn main() {
    let Some((robot, overrides)) = robot() else {
        println!(
            "skipped: no robot description (robots/default.toml or $DATASETS_DIR/ur10e/ur10e.urdf)"
        );
        return;
    };
    println!("robot: {}", robot.source.display());
    println!(
        "{:<12} {:>6} {:>5} {:>8} {:>10} {:>10} {:>12} {:>10} {:>8}",
        "case", "joints", "dim", "params", "evals", "time_s", "cond_random", "cond_opt", "factor"
    );
    let mut six = robot.clone();
    six.model_all_joints();
    for (label, r) in [
        ("wrist 4-6", robot.default_paper_selection()),
        ("all 6", six),
    ] {
        let model = RobotObservation::new(r).expect("base parameters");
        let limits = joint_limits(model.robot(), &overrides).expect("limits");
        let rest = vec![0.0; limits.len()];
        let settings = ExcitationSettings::default();
        let family = FourierFamily::new(
            settings.period_s,
            settings.harmonics,
            &rest,
            &limits,
            &[],
            settings.rate_hz * settings.check_factor as f64,
        )
        .expect("family");
        let d = design(&model, family.clone(), &settings).expect("design");
        let mut random: Vec<f64> = (0..5)
            .map(|s| {
                condition_number(&observation_matrix(
                    &model,
                    &random_feasible(&family, 50 + s),
                    settings.rate_hz,
                ))
            })
            .collect();
        random.sort_by(f64::total_cmp);
        println!(
            "{:<12} {:>6} {:>5} {:>8} {:>10} {:>10.1} {:>12.1} {:>10.2} {:>8.1}",
            label,
            limits.len(),
            family.dimension(),
            model.base().count(),
            d.evaluations,
            d.seconds,
            random[2],
            d.score.condition,
            random[2] / d.score.condition
        );
    }
}
