//! `model-export excite`: design an optimised excitation trajectory for a robot.

use crate::args::choice::named;
use anyhow::{Context, bail};
use excitation::constraints::{FourierFamily, PointConstraint, tightest};
use excitation::objective::Criterion;
use excitation::optimise::{
    BaselineScaling, DEFAULT_BASELINE_COUNT, DEFAULT_EVALUATIONS_PER_RESTART, DEFAULT_RESTARTS,
    ExcitationDesign, ExcitationSettings, RandomBaseline, Repair, design, random_baseline,
};
use excitation::output::{ExcitationFile, OutputPaths, write_outputs};
use excitation::robot_model::{LimitOverrides, RobotObservation, joint_limits, playback_layout};
use excitation::trajectory::Derivative;
use robot::{Robot, RobotSource};
use std::path::PathBuf;

/// Arguments of `model-export excite`.
#[derive(Debug, Clone, clap::Args)]
pub struct ExciteArgs {
    /// Robot description (DH TOML or URDF).
    #[arg(long)]
    pub robot: Option<PathBuf>,
    /// The modelled chain of a URDF tree.
    #[command(flatten)]
    pub chain: crate::args::robot::ChainArgs,
    /// Moving joints: `file` (the robot file's selection), `wrist` (the paper: joints 1-3
    /// locked at zero, 4.. moving), `all`, or a 1-based list such as `4,5,6` (others locked at
    /// zero).
    #[arg(long, default_value = "file")]
    pub joints: String,
    /// Number of harmonics N.
    #[arg(long, default_value_t = 5)]
    pub harmonics: usize,
    /// Period T in s (ω_f = 2π/T); the trajectory lasts one period.
    #[arg(long, default_value_t = 10.0)]
    pub period: f64,
    /// Controller (playback CSV) rate in Hz.
    #[arg(long, default_value_t = 100.0)]
    pub rate: f64,
    /// Limit-check grid rate as a multiple of the controller rate (at least 10).
    #[arg(long, default_value_t = 10)]
    pub check_factor: usize,
    /// Criterion: the condition number (the paper) or the D-optimal log-determinant.
    #[arg(long, value_parser = named::<Criterion>(), default_value = "condition")]
    pub criterion: Criterion,
    /// Independent seeded CMA-ES runs.
    #[arg(long, default_value_t = DEFAULT_RESTARTS)]
    pub restarts: usize,
    /// Objective evaluations per run.
    #[arg(long, default_value_t = DEFAULT_EVALUATIONS_PER_RESTART)]
    pub evaluations: usize,
    /// CMA-ES population size λ (default: the crate's 4 + 3 ln n).
    #[arg(long)]
    pub population: Option<usize>,
    /// How a candidate is scaled into the limits: one scale per joint or one for all joints.
    #[arg(long, value_parser = named::<Repair>(), default_value = "per-joint")]
    pub repair: Repair,
    /// Size of the random baselines: this many seeded random feasible trajectories of the
    /// same family, once with every joint scaled onto its own tightest limit and once with one
    /// scale for all joints, each compared with the design in a printed table (median and
    /// best); 0 skips them. Seeds derive from --seed.
    #[arg(long, default_value_t = DEFAULT_BASELINE_COUNT)]
    pub baseline: usize,
    /// Samples per period when scoring a candidate during the search.
    #[arg(long, default_value_t = 200)]
    pub samples: usize,
    /// Master seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Rest pose of the moving joints in rad, comma-separated (default: all zero).
    #[arg(long, value_delimiter = ',')]
    pub rest: Option<Vec<f64>>,
    /// Extra constraint q_i(t) = 0 on every moving joint at this time in s (repeatable; the
    /// paper's test trajectory uses 3.8).
    #[arg(long)]
    pub zero_at: Vec<f64>,
    /// Symmetric position limit in rad (intersected with the robot file's).
    #[arg(long)]
    pub q_max: Option<f64>,
    /// Velocity limit in rad/s (replaces the robot file's).
    #[arg(long)]
    pub qd_max: Option<f64>,
    /// Acceleration limit in rad/s² (replaces the robot file's).
    #[arg(long)]
    pub qdd_max: Option<f64>,
    /// Output folder.
    #[arg(
        long = "out",
        short,
        alias = "out-dir",
        default_value = ".",
        value_name = "DIR"
    )]
    pub out: PathBuf,
    /// Base name of the outputs: `<name>.json`, `<name>.csv`, `<name>.svg`.
    #[arg(long, default_value = "excitation")]
    pub name: String,
    /// Do not write the SVG plot.
    #[arg(long)]
    pub no_plot: bool,
}

fn select_joints(robot: &mut Robot, spec: &str) -> anyhow::Result<()> {
    match spec {
        "file" => {}
        "wrist" => *robot = robot.default_paper_selection(),
        "all" => robot.model_all_joints(),
        list => {
            let picked: Vec<usize> = list
                .split(',')
                .map(|s| s.trim().parse::<usize>())
                .collect::<Result<_, _>>()
                .with_context(|| {
                    format!("--joints `{list}`: expected file, wrist, all or a list like 4,5,6")
                })?;
            for &p in &picked {
                if p == 0 || p > robot.dof() {
                    bail!(
                        "--joints: joint {p} does not exist (the robot has {} joints)",
                        robot.dof()
                    );
                }
            }
            for i in 0..robot.dof() {
                if picked.contains(&(i + 1)) {
                    robot.joints[i].mode = robot::JointMode::Modelled;
                } else {
                    robot.lock_joint(i, 0.0);
                }
            }
        }
    }
    Ok(())
}

/// Runs `model-export excite`.
pub fn run(a: &ExciteArgs) -> anyhow::Result<()> {
    if a.check_factor < 10 {
        bail!("--check-factor {}: must be at least 10", a.check_factor);
    }
    if !(a.rate.is_finite() && a.rate > 0.0) {
        bail!("--rate {}: must be positive", a.rate);
    }
    let mut robot = a.chain.load_and_warn(&RobotSource::from(a.robot.clone()))?;
    select_joints(&mut robot, &a.joints)?;
    let model = RobotObservation::new(robot)?;
    let robot = model.robot();
    let overrides = LimitOverrides {
        q_max_rad: a.q_max,
        qd_max_rad_s: a.qd_max,
        qdd_max_rad_s2: a.qdd_max,
    };
    let limits = joint_limits(robot, &overrides)?;
    let n = limits.len();
    let rest = a.rest.clone().unwrap_or_else(|| vec![0.0; n]);
    if rest.len() != n {
        bail!("--rest: {} values for {n} moving joints", rest.len());
    }
    let extra: Vec<PointConstraint> = a
        .zero_at
        .iter()
        .flat_map(|&t| {
            (0..n).map(move |j| PointConstraint {
                joint: j,
                t_s: t,
                derivative: Derivative::Position,
                value: 0.0,
            })
        })
        .collect();
    let settings = ExcitationSettings {
        harmonics: a.harmonics,
        period_s: a.period,
        rate_hz: a.rate,
        check_factor: a.check_factor,
        objective_samples: a.samples,
        criterion: a.criterion,
        restarts: a.restarts,
        evaluations_per_restart: a.evaluations,
        seed: a.seed,
        repair: a.repair,
        population: a.population,
        ..ExcitationSettings::default()
    };
    let legend = robot
        .modelled_joints()
        .iter()
        .enumerate()
        .map(|(m, &i)| format!("#{m} = joint {} ({})", i + 1, robot.joints[i].name))
        .collect::<Vec<_>>()
        .join(", ");
    let legend = format!("moving joints {legend}");
    let family = FourierFamily::new(
        a.period,
        a.harmonics,
        &rest,
        &limits,
        &extra,
        a.rate * a.check_factor as f64,
    )
    .with_context(|| legend.clone())?;
    println!(
        "robot {} ({}), {}; {} base parameters; {} free coefficients; limit grid {} points",
        robot.name,
        RobotSource::from(a.robot.clone()),
        legend,
        model.base().count(),
        family.dimension(),
        family.grid_points()
    );
    let d = design(&model, family.clone(), &settings).with_context(|| legend.clone())?;
    // Random members shrink toward the particular solution: only meaningful when it is feasible
    // (always, unless point constraints move it outside the limits).
    let particular_feasible = family.particular_margins().iter().all(|m| m.margin >= 0.0);
    if a.baseline > 0 && !particular_feasible {
        println!(
            "random baseline skipped: the point constraints' particular solution breaks a limit"
        );
    }
    let baselines: Vec<RandomBaseline> = if a.baseline > 0 && particular_feasible {
        BaselineScaling::ALL
            .iter()
            .map(|&sc| random_baseline(&model, &family, a.baseline, a.seed, a.rate, sc))
            .collect()
    } else {
        Vec::new()
    };
    // The JSON's `random_condition`: the generous (per-joint) population's median.
    let random_cond = baselines.first().map(|b| b.condition().median);
    println!(
        "{:>3} {:>20} {:>12} {:>8}  stopped",
        "run", "seed", "best_cost", "evals"
    );
    for (i, r) in d.restarts.iter().enumerate() {
        println!(
            "{:>3} {:>20} {:>12.5} {:>8}  {}",
            i, r.seed, r.best_cost, r.evaluations, r.stopped_because
        );
    }
    println!(
        "best: condition number {:.3}, log det(W'W/n) {:.3}; {} evaluations in {:.1} s",
        d.score.condition, d.score.log_det, d.evaluations, d.seconds
    );
    if !baselines.is_empty() {
        print_comparison(&d, &baselines);
    }
    println!(
        "{:>5} {:<30} {:>12} {:>12} {:>12} {:>8}",
        "joint", "limit", "limit", "extreme", "margin", "use"
    );
    for m in &d.margins {
        println!(
            "{:>5} {:<30} {:>12.4} {:>12.4} {:>12.4} {:>7.1}%",
            robot.modelled_joints()[m.joint] + 1,
            m.kind.describe(),
            m.limit,
            m.extreme,
            m.margin,
            100.0 * m.utilisation
        );
    }
    if let Some(t) = tightest(&d.margins) {
        println!(
            "tightest: joint {} {} at {:.1}%",
            robot.modelled_joints()[t.joint] + 1,
            t.kind.describe(),
            100.0 * t.utilisation
        );
    }
    let layout = playback_layout(robot, &rest);
    let file = ExcitationFile::new(&robot.name, layout, &limits, &extra, &d, random_cond);
    std::fs::create_dir_all(&a.out).with_context(|| format!("{}", a.out.display()))?;
    let paths = OutputPaths {
        json: a.out.join(format!("{}.json", a.name)),
        csv: a.out.join(format!("{}.csv", a.name)),
        plot: (!a.no_plot).then(|| a.out.join(format!("{}.svg", a.name))),
    };
    let labels: Vec<String> = robot
        .modelled_joints()
        .iter()
        .map(|&i| format!("joint {}", i + 1))
        .collect();
    write_outputs(&file, &labels, &paths)?;
    println!("wrote {}, {}", paths.json.display(), paths.csv.display());
    if let Some(p) = &paths.plot {
        println!("wrote {}", p.display());
    }
    Ok(())
}

/// Prints the design against the random baseline populations: both condition numbers, each
/// population's median and best, and the factors.
pub fn print_comparison(d: &ExcitationDesign, baselines: &[RandomBaseline]) {
    for b in baselines {
        println!(
            "optimised vs {} random feasible trajectories of the same family (seeds from {}; {}), \
             scored at {} Hz:",
            b.scores.len(),
            b.seed,
            b.scaling.describe(),
            d.settings.rate_hz
        );
        println!(
            "{:<24} {:>10} {:>13} {:>11} {:>10} {:>10}",
            "criterion", "optimised", "random_median", "random_best", "x_median", "x_best"
        );
        for (label, opt, stats) in [
            ("cond(W) (paper)", d.score.condition, b.condition()),
            (
                "cond(W, unit columns)",
                d.score.scaled_condition,
                b.scaled_condition(),
            ),
        ] {
            println!(
                "{:<24} {:>10.2} {:>13.2} {:>11.2} {:>10.2} {:>10.2}",
                label,
                opt,
                stats.median,
                stats.best,
                stats.median / opt,
                stats.best / opt
            );
        }
    }
    println!(
        "optimised criterion: {:?}; the factor against the best random draw is printed as measured",
        d.settings.criterion
    );
}
