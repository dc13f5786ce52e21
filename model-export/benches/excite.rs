//! Excitation design benchmark: `cargo bench -p model-export --bench excite`.
//!
//! Designs the paper's wrist trajectory (3 joints, 5 harmonics) and a 6-joint trajectory with
//! the default settings, and prints a table: evaluations, wall time, and for both the paper's
//! condition number `cond(W)` and the unit-column one, the optimised value against the median
//! and best of the default random baseline (20 seeded random feasible trajectories of the same
//! family), once with every joint scaled onto its own tightest limit (`per-joint`, generous)
//! and once with one scale for all joints (`common`); each at the robot's own limits and at
//! identification limits (1 rad/s, 3 rad/s² on every joint). Targets: 3 joints < 60 s,
//! 6 joints < 5 min.
//!
//! `cargo test` runs it as a smoke test: one restart of 40 evaluations, 3 random draws.
//!
//! Robot: `robots/default.toml` if present, else the UR10e URDF under
//! `$DATASETS_DIR` (default `../shared/datasets`), with 8 rad/s² acceleration limits.

use excitation::optimise::DEFAULT_BASELINE_COUNT;
use excitation::robot_model::{LimitOverrides, RobotObservation, joint_limits};
use excitation::{BaselineScaling, ExcitationSettings, FourierFamily, design, random_baseline};
use robot::Robot;
use std::path::PathBuf;
use test_support::bench::BenchRun;

fn robot() -> Option<(Robot, LimitOverrides)> {
    let manifest = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let default = manifest.join("../robots/default.toml");
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
    let run = BenchRun::from_args();
    let Some((robot, overrides)) = robot() else {
        let what = "robots/default.toml or $DATASETS_DIR/ur10e/ur10e.urdf";
        test_support::skip("the excitation benchmark", what, true);
        return;
    };
    println!("robot: {}", robot.source.display());
    println!(
        "{:<10} {:<8} {:>6} {:>4} {:>6} {:>7} {:>7} {:<10} {:<10} {:>9} {:>9} {:>9} {:>7} {:>7}",
        "case",
        "limits",
        "joints",
        "dim",
        "params",
        "evals",
        "time_s",
        "criterion",
        "baseline",
        "optimised",
        "rnd_med",
        "rnd_best",
        "x_med",
        "x_best"
    );
    let mut six = robot.clone();
    six.model_all_joints();
    let cases = [
        ("wrist 4-6", robot.default_paper_selection()),
        ("all 6", six),
    ];
    for ((label, r), (limit_label, o)) in cases.iter().flat_map(|c| {
        [
            (c, ("robot", &overrides)),
            (c, ("1, 3", &LimitOverrides::IDENTIFICATION)),
        ]
    }) {
        let model = RobotObservation::new(r.clone()).expect("base parameters");
        let limits = joint_limits(model.robot(), o).expect("limits");
        let rest = vec![0.0; limits.len()];
        let defaults = ExcitationSettings::default();
        let settings = ExcitationSettings {
            restarts: run.size(defaults.restarts, 1),
            evaluations_per_restart: run.size(defaults.evaluations_per_restart, 40),
            ..defaults
        };
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
        for scaling in BaselineScaling::ALL {
            let random = random_baseline(
                &model,
                &family,
                run.size(DEFAULT_BASELINE_COUNT, 3),
                settings.seed,
                settings.rate_hz,
                scaling,
            );
            for (name, opt, stats) in [
                ("cond(W)", d.score.condition, random.condition()),
                (
                    "unit-cols",
                    d.score.scaled_condition,
                    random.scaled_condition(),
                ),
            ] {
                println!(
                    "{:<10} {:<8} {:>6} {:>4} {:>6} {:>7} {:>7.1} {:<10} {:<10} {:>9.2} {:>9.2} {:>9.2} {:>7.2} {:>7.2}",
                    label,
                    limit_label,
                    limits.len(),
                    family.dimension(),
                    model.base().count(),
                    d.evaluations,
                    d.seconds,
                    name,
                    scaling.name(),
                    opt,
                    stats.median,
                    stats.best,
                    stats.median / opt,
                    stats.best / opt
                );
            }
        }
    }
}
