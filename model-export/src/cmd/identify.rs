//! The `identify` and `torque` subcommands.

use crate::args::logs::{LayoutArgs, PreprocessArgs};
use anyhow::{Context, bail};
use artifacts::write_atomic;
use clap::{Args, ValueEnum};
use firmware::features;
use identify::identified::{
    BASE_SEED, ModelSelection, RobotBaseModel, load_model_robot, load_robot, predict_log,
};
use identify::model_file::{
    BaseParameter, ErrorReport, JointFriction, JointRanges, LockedJoint, LogRef,
    MODEL_SCHEMA_VERSION, ModelFile, ModelTermsRef, RobotRef,
};
use identify::pipeline::{self, LinearModel};
use identify::{IdentifyOptions, Weighting};
use logs::{BagOptions, LogLayout, PreprocessOptions, Samples, preprocess, read_robot_log};
use nalgebra::DVector;
use robot::RobotSource;
use robot::dynamics::firmware_model::FirmwareModel;
use robot::{JointMode, Robot};
use std::path::{Path, PathBuf};

/// Joint selection options.
#[derive(Debug, Clone, Args)]
pub struct JointArgs {
    /// Lock joints at fixed positions: `J=Q` with 1-based joint J and Q in rad,
    /// comma separated (e.g. `1=0,2=-1.57,3=0`); the other joints are modelled.
    /// Without --lock, the robot file's selection applies (DH `locked_at`; URDF: all
    /// joints modelled).
    #[arg(
        long,
        value_name = "J=RAD",
        value_delimiter = ',',
        allow_hyphen_values = true
    )]
    pub lock: Vec<String>,
    /// Model a constant torque offset per joint as well.
    #[arg(long)]
    pub friction_offset: bool,
    /// Smooth the Coulomb sign as tanh(qd / EPS) [rad/s] instead of a hard sign.
    #[arg(long, value_name = "EPS")]
    pub coulomb_smoothing_rad_s: Option<f64>,
    /// Friction model: `viscous-coulomb` (the paper's terms, as the robot file's say) or
    /// `extended` (adds per joint a torque offset, velocity-weakening tanh(qd/v) terms at
    /// 0.05, 0.2 and 1 rad/s and quadratic drag qd|qd|; all linear in their coefficients
    /// and evaluated by the firmware).
    #[arg(long = "friction", alias = "friction-model", value_enum, default_value_t = FrictionModel::ViscousCoulomb)]
    pub friction_model: FrictionModel,
    /// The modelled chain of a URDF tree.
    #[command(flatten)]
    pub chain: crate::args::robot::ChainArgs,
}

impl JointArgs {
    /// The library's joint selection and model terms these options describe (`--lock J=Q`
    /// parsed: 1-based joint, position in rad).
    pub fn selection(&self) -> anyhow::Result<ModelSelection> {
        let locked = crate::args::joints::lock_indices(&self.lock)?;
        Ok(ModelSelection {
            locked,
            friction_offset: self.friction_offset,
            coulomb_smoothing_rad_s: self.coulomb_smoothing_rad_s,
            extended_friction: self.friction_model == FrictionModel::Extended,
            chain: self.chain.selection()?,
        })
    }
}

/// Friction basis of the identified model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum FrictionModel {
    /// Viscous + Coulomb friction, the paper's terms (plus what the robot file selects).
    /// Old value name (warns): `paper`.
    #[value(alias = "paper")]
    ViscousCoulomb,
    /// The paper's terms plus offset, velocity-weakening and quadratic terms.
    Extended,
}

/// Row weighting choice.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum WeightingArg {
    /// Ordinary least squares.
    Ols,
    /// Weighted least squares, per-joint weights 1/σⱼ² from an OLS first pass.
    Wls,
}

/// `model-export identify`.
#[derive(Debug, Clone, Args)]
pub struct IdentifyArgs {
    /// Robot description: URDF (.urdf) or DH table (.toml); default: the built-in
    /// default robot (robots/default.toml).
    #[arg(long)]
    pub robot: Option<PathBuf>,
    /// Identification logs (CSV, or ROS 2 recordings: rosbag2 .mcap), one or more.
    #[arg(long = "log", required = true, value_name = "LOG")]
    pub logs: Vec<PathBuf>,
    /// Validation logs (CSV or .mcap): predicted with the identified model, not used to fit.
    #[arg(long = "validation-log", alias = "validate", value_name = "LOG")]
    pub validation: Vec<PathBuf>,
    /// Output model file (JSON), written atomically.
    #[arg(long = "out", short, alias = "output", value_name = "FILE")]
    pub out: PathBuf,
    /// Row weighting.
    #[arg(long, value_enum, default_value_t = WeightingArg::Wls)]
    pub weighting: WeightingArg,
    /// Fail if any base parameter's relative standard deviation exceeds this [%].
    #[arg(long, value_name = "PCT")]
    pub max_rel_std_pct: Option<f64>,
    /// Print every base parameter with its standard deviation.
    #[arg(long)]
    pub print_parameters: bool,
    /// Joint selection.
    #[command(flatten)]
    pub joints: JointArgs,
    /// Log columns.
    #[command(flatten)]
    pub layout: LayoutArgs,
    /// Preprocessing.
    #[command(flatten)]
    pub pre: PreprocessArgs,
}

/// `model-export torque`.
#[derive(Debug, Clone, Args)]
pub struct TorqueArgs {
    /// Robot description: URDF (.urdf) or DH table (.toml); default: the built-in
    /// default robot (robots/default.toml).
    #[arg(long)]
    pub robot: Option<PathBuf>,
    /// Identified model (JSON from `identify`); without it the robot's nominal
    /// parameters (and its friction, if any) are used.
    #[arg(long = "identified", alias = "model", value_name = "FILE")]
    pub identified: Option<PathBuf>,
    /// Input: a log (CSV, or a ROS 2 recording: rosbag2 .mcap) or a CSV of states (see
    /// --layout states).
    #[arg(long = "log", value_name = "LOG")]
    pub log: PathBuf,
    /// Output CSV: time, tau_model per modelled joint [N·m] (firmware f32 model), and
    /// the measured torque per modelled joint when the input has effort columns.
    #[arg(long = "out", short, alias = "output", value_name = "FILE")]
    pub out: PathBuf,
    /// Joint selection and model terms (ignored with --identified: the model file's are used).
    #[command(flatten)]
    pub joints: JointArgs,
    /// Log columns.
    #[command(flatten)]
    pub layout: LayoutArgs,
    /// Preprocessing.
    #[command(flatten)]
    pub pre: PreprocessArgs,
    /// Write the LSTM compensation dataset instead (`model-export train` reads it):
    /// `time_s`, then per modelled joint N (1-based robot joint number) `q_jN` [rad],
    /// `qd_jN` [rad/s], `tau_meas_jN` and `tau_model_jN` [N·m], `qdd_jN` [rad/s²], and
    /// the drive's own features `sin_q_jN`, `cos_q_jN`, `rest_dir_jN`. Use it with
    /// `--trim-rest-rad-s 0 --torque-cutoff-hz 0` to keep every sample as the drive logged it.
    #[arg(long)]
    pub dataset: bool,
}

/// Names of the robot's joints, in order (ROS 2 recordings are matched by them).
fn joint_names(robot: &Robot) -> Vec<String> {
    robot.joints.iter().map(|j| j.name.clone()).collect()
}

/// Drive gains [N·m/A] a log's effort was read with; `None`: its effort is torque.
type DriveGains = Option<Vec<f64>>;

/// Reads and preprocesses logs; also returns the drive gains each was read with.
fn load_logs(
    paths: &[PathBuf],
    layout: &LogLayout,
    bag: &BagOptions,
    pre: &PreprocessOptions,
    robot: &Robot,
) -> anyhow::Result<(Vec<Samples>, Vec<DriveGains>)> {
    let names = joint_names(robot);
    let mut gains = Vec::with_capacity(paths.len());
    let samples = paths
        .iter()
        .map(|p| {
            let raw = read_robot_log(p, layout, bag, &names)?;
            for note in &raw.notes {
                eprintln!("note: {note}");
            }
            angles_within_limits(&raw, robot)?;
            gains.push(raw.drive_gains_nm_per_a.clone());
            Ok(preprocess(&raw, pre)?)
        })
        .collect::<anyhow::Result<_>>()?;
    Ok((samples, gains))
}

/// How far beyond a joint's limits a logged angle may lie [rad] (one turn: encoder
/// wrap-around and calibration offsets pass; a log of another robot, or a column of
/// another unit, does not).
const ANGLE_MARGIN_RAD: f64 = std::f64::consts::TAU;

/// The plausibility layer on a log against its robot: every logged angle within
/// [`ANGLE_MARGIN_RAD`] of its joint's limits; the error names the file, the line, the
/// joint and the limits.
fn angles_within_limits(raw: &logs::RawLog, robot: &Robot) -> anyhow::Result<()> {
    for (j, (q, joint)) in raw.q_rad.iter().zip(&robot.joints).enumerate() {
        let (Some(lo), Some(hi)) = (joint.limits.q_min_rad, joint.limits.q_max_rad) else {
            continue;
        };
        if let Some(k) = q
            .iter()
            .position(|&v| v < lo - ANGLE_MARGIN_RAD || v > hi + ANGLE_MARGIN_RAD)
        {
            let line = raw
                .lines
                .get(k)
                .map_or(String::new(), |l| format!(", line {l}"));
            anyhow::bail!(
                "{}{line}, joint {} ({}) angle: {} rad is more than one turn beyond the \
                 robot's limits [{lo}, {hi}] rad (a log of another robot, or not in radians?)",
                raw.path.display(),
                j + 1,
                joint.name,
                q[k]
            );
        }
    }
    Ok(())
}

fn log_refs(logs: &[Samples]) -> Vec<LogRef> {
    logs.iter()
        .map(|s| LogRef {
            path: s.path.display().to_string(),
            sha256: s.sha256.clone(),
            samples: s.len(),
        })
        .collect()
}

/// Prints a per-joint table.
fn print_table(title: &str, joint_names: &[String], rows: &[(String, Vec<f64>, Vec<f64>, usize)]) {
    let lw = rows
        .iter()
        .map(|r| r.0.len())
        .chain([18])
        .max()
        .unwrap_or(18);
    let w: Vec<usize> = joint_names.iter().map(|n| n.len().max(9)).collect();
    println!("{title}");
    print!("{:<lw$} {:>7}", "data", "samples");
    for (n, w) in joint_names.iter().zip(&w) {
        print!(" {n:>w$}");
    }
    println!();
    for (name, rms, nrms, samples) in rows {
        print!("{name:<lw$} {samples:>7}");
        for (r, w) in rms.iter().zip(&w) {
            print!(" {r:>w$.3}");
        }
        println!();
        print!("{:<lw$} {:>7}", "  (normalised, %)", "");
        for (r, w) in nrms.iter().zip(&w) {
            let cell = format!("{r:.1}%");
            print!(" {cell:>w$}");
        }
        println!();
    }
}

fn file_label(p: &Path) -> String {
    p.file_name()
        .map(|f| f.to_string_lossy().into_owned())
        .unwrap_or_else(|| p.display().to_string())
}

/// What the directions the data cannot identify keep.
const PRIOR: &str = "nominal parameters of the robot description";

/// Per modelled joint, the `[min, max]` of q, q̇, q̈ over the preprocessed logs
/// (`[0, 0]` for a log set without samples).
fn identification_ranges(logs: &[Samples], joints: &[usize], robot: &Robot) -> Vec<JointRanges> {
    let span = |series: &mut dyn Iterator<Item = f64>| {
        let (lo, hi) = series
            .filter(|x| x.is_finite())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
                (lo.min(x), hi.max(x))
            });
        if lo <= hi { [lo, hi] } else { [0.0, 0.0] }
    };
    joints
        .iter()
        .map(|&j| JointRanges {
            joint: robot.joints[j].name.clone(),
            q_rad: span(&mut logs.iter().flat_map(|s| s.q_rad[j].iter().copied())),
            qd_rad_s: span(&mut logs.iter().flat_map(|s| s.qd_rad_s[j].iter().copied())),
            qdd_rad_s2: span(&mut logs.iter().flat_map(|s| s.qdd_rad_s2[j].iter().copied())),
        })
        .collect()
}

/// Runs `identify`.
pub fn identify(a: &IdentifyArgs) -> anyhow::Result<()> {
    let source = RobotSource::from(a.robot.clone());
    let robot = crate::args::robot::warn(load_robot(&source, &a.joints.selection()?)?);
    let robot_hash = logs::sha256_hex(&source.bytes()?);
    let layout = a.layout.layout()?;
    let pre = a.pre.options()?;
    let bag = a.layout.bag_options()?;
    let (id_logs, id_gains) = load_logs(&a.logs, &layout, &bag, &pre, &robot)?;
    let (val_logs, _) = load_logs(&a.validation, &layout, &bag, &pre, &robot)?;
    // The model file records one set of drive gains: the identification logs' effort
    // must all be torque or all current with the same gains.
    if let Some(k) = id_gains.iter().position(|g| *g != id_gains[0]) {
        bail!(
            "{} and {} are read with different drive gains ({:?} and {:?}; none = torque): \
             identify on logs of one kind",
            a.logs[0].display(),
            a.logs[k].display(),
            id_gains[0],
            id_gains[k]
        );
    }
    for s in id_logs.iter() {
        if s.torque_nm.is_none() {
            bail!(
                "{}: no torque or current columns; cannot identify from it",
                s.path.display()
            );
        }
    }
    let mut model = RobotBaseModel::new(robot)?;
    let names = model.parameter_names();
    let joints = model.modelled_log_joints();
    // The states identification saw: recorded in the file, and the firmware model
    // continues its extended friction linearly beyond the speeds.
    let ranges = identification_ranges(&id_logs, &joints, &model.robot);
    model.robot.identified_ranges = ranges.iter().map(|r| r.to_robot()).collect();
    // Directions the data cannot identify keep the robot description's nominal values.
    let prior = model.base.beta(&model.robot.standard_parameters());
    let joint_names: Vec<String> = joints
        .iter()
        .map(|&j| model.robot.joints[j].name.clone())
        .collect();

    let t0 = std::time::Instant::now();
    let mut ne = pipeline::accumulate(&model, &id_logs);
    let opt = IdentifyOptions {
        weighting: match a.weighting {
            WeightingArg::Ols => Weighting::Ordinary,
            WeightingArg::Wls => Weighting::PerJointFromOls,
        },
        max_relative_std_pct: a.max_rel_std_pct,
        prior: Some(prior.iter().copied().collect()),
        ..Default::default()
    };
    // Errors name base parameters by their definitions ("b36 = fv6").
    let labels = model.expressions();
    let id = identify::solve(&mut ne, &labels, &opt)
        .with_context(|| format!("identification from {} log(s) failed", id_logs.len()))?;
    let elapsed = t0.elapsed();
    // The first stage stays a physically consistent body: the least-squares parameters
    // when one has them, else the pseudo-inertia LMI's.
    let first_stage = identify::consistent::consistent_fit(
        &mut ne,
        &id.joint_sigma_nm,
        &id.values,
        id.dropped.len(),
        &model.robot,
        &model.base,
    )
    .with_context(|| {
        let logs: Vec<String> = a.logs.iter().map(|p| p.display().to_string()).collect();
        format!(
            "identification from {}: not writing {}",
            logs.join(", "),
            a.out.display()
        )
    })?;
    let beta = DVector::from_vec(first_stage.values.clone());
    let theta = model.equivalent_standard(&beta);
    let fw = FirmwareModel::build(&model.robot, &theta)?;

    // Reports with the firmware's f32 model, cross-checked against Y·β in f64.
    let mut reports = Vec::new();
    let mut table = Vec::new();
    let mut max_diff: f64 = 0.0;
    let mut max_tau: f64 = 0.0;
    let mut all_id = Vec::new();
    for (set, logs) in [("identification", &id_logs), ("validation", &val_logs)] {
        let mut accs = Vec::new();
        for s in logs.iter() {
            let p32 = predict_log(&fw, &joints, s);
            let p64 = pipeline::predict(&model, &beta, s);
            // Cross-checked on the identification logs: inside their recorded ranges
            // the firmware's continuation of the extended friction is an exact `+ 0`;
            // on faster validation logs it departs from the plain f64 basis on purpose.
            if set == "identification" {
                max_diff = max_diff.max(pipeline::max_abs_difference(&p32, &p64));
                max_tau = max_tau.max(p64.iter().flatten().fold(0.0, |m, v| m.max(v.abs())));
            }
            if let Some(acc) = pipeline::errors(&p32, &joints, s) {
                let e = acc.finish();
                table.push((
                    format!("{set}: {}", file_label(&s.path)),
                    e.rms_nm.clone(),
                    e.nrms_pct.clone(),
                    e.samples,
                ));
                reports.push(ErrorReport {
                    data: format!("{set}: {}", s.path.display()),
                    rms_nm: e.rms_nm,
                    nrms_pct: e.nrms_pct,
                    samples: e.samples,
                });
                accs.push(acc);
            }
        }
        if !accs.is_empty() {
            let e = pipeline::merged_errors(&accs, joints.len());
            table.push((
                format!("{set}: all"),
                e.rms_nm.clone(),
                e.nrms_pct.clone(),
                e.samples,
            ));
            reports.push(ErrorReport {
                data: format!("{set}: all"),
                rms_nm: e.rms_nm,
                nrms_pct: e.nrms_pct,
                samples: e.samples,
            });
        }
        if set == "identification" {
            all_id = accs;
        }
    }
    let _ = all_id;
    // f32 evaluation vs f64: the f32 model must agree to single-precision accuracy.
    let tol = 1e-3 * max_tau.max(1.0);
    if max_diff.is_nan() || max_diff > tol {
        bail!(
            "firmware f32 model and f64 regressor disagree by {max_diff:.3e} N·m (limit {tol:.3e}); not writing {}",
            a.out.display()
        );
    }

    let expressions = model.expressions();
    let base_parameters: Vec<BaseParameter> = (0..names.len())
        .map(|i| BaseParameter {
            name: names[i].clone(),
            expression: expressions[i].clone(),
            value: first_stage.values[i],
            std: id.std[i],
            relative_std_pct: id.relative_std_pct[i],
        })
        .collect();
    let friction = joints
        .iter()
        .map(|&j| {
            let find = |prefix: &str| {
                let std_name = format!("{prefix}{}", j + 1);
                base_parameters
                    .iter()
                    .find(|b| {
                        b.expression.split_once(" = ").map(|(_, d)| d.trim())
                            == Some(std_name.as_str())
                    })
                    .map(|b| b.value)
            };
            JointFriction {
                joint: model.robot.joints[j].name.clone(),
                viscous_nm_s_rad: find("fv"),
                coulomb_nm: find("fc"),
                offset_nm: find("fo"),
            }
        })
        .collect();
    let locked_joints = model
        .robot
        .joints
        .iter()
        .filter_map(|j| match j.mode {
            JointMode::Locked { q_rad } => Some(LockedJoint {
                name: j.name.clone(),
                position_rad: q_rad,
            }),
            JointMode::Modelled => None,
        })
        .collect();
    let drive_gains_nm_per_a = id_gains.first().cloned().flatten().unwrap_or_default();
    let file = ModelFile {
        schema_version: MODEL_SCHEMA_VERSION,
        robot: RobotRef {
            name: model.robot.name.clone(),
            source_path: source.path().display().to_string(),
            sha256: robot_hash,
            chain: identify::model_file::ChainRef::from_selection(&a.joints.chain.selection()?),
        },
        modelled_joints: joint_names.clone(),
        locked_joints,
        model_terms: ModelTermsRef {
            viscous_friction: model.robot.terms.viscous_friction,
            coulomb_friction: model.robot.terms.coulomb_friction,
            friction_offset: model.robot.terms.friction_offset,
            coulomb_smoothing_rad_s: model.robot.terms.coulomb_smoothing_rad_s,
            rotor_inertia: model.robot.terms.rotor_inertia,
            extended_friction: model.robot.terms.extended_friction,
        },
        base_seed: BASE_SEED,
        drive_gains_nm_per_a,
        base_parameters,
        friction,
        condition_number: id.condition_number,
        condition_number_scaled: id.condition_number_scaled,
        weighting: match a.weighting {
            WeightingArg::Ols => "ordinary".into(),
            WeightingArg::Wls => "weighted (per-joint sigma from OLS residuals)".into(),
        },
        joint_sigma_nm: id.joint_sigma_nm.clone(),
        identification_logs: log_refs(&id_logs),
        validation_logs: log_refs(&val_logs),
        errors: reports,
        preprocessing: serde_json::to_value(&pre)?,
        dropped_directions: id.dropped.clone(),
        prior: PRIOR.into(),
        identification_ranges: ranges,
        first_stage: Some(first_stage.report.clone()),
    };

    if a.print_parameters {
        println!(
            "{:<8} {:>14} {:>12} {:>9}  definition",
            "name", "value", "std", "rel std"
        );
        for b in &file.base_parameters {
            println!(
                "{:<8} {:>14.6} {:>12.4e} {:>8.2}%  {}",
                b.name, b.value, b.std, b.relative_std_pct, b.expression
            );
        }
    }
    println!(
        "identified {} base parameters from {} samples of {} log(s) in {:.3} s; condition number {:.4e} (column-scaled {:.4e})",
        names.len(),
        id.samples,
        id_logs.len(),
        elapsed.as_secs_f64(),
        id.condition_number,
        id.condition_number_scaled
    );
    if !id.dropped.is_empty() {
        println!(
            "the data cannot identify {} direction(s); they keep the {PRIOR}:",
            id.dropped.len()
        );
        for d in &id.dropped {
            println!("  dropped {d}");
        }
    }
    let fs = &first_stage.report;
    let min_eig = fs
        .min_pseudo_inertia_eigenvalue_kg_m2
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min);
    if fs.solution == "unconstrained" && fs.fit_status.is_empty() {
        println!(
            "first stage: the least-squares parameters are a physically consistent body (consistency test {}, {:.3} s); kept",
            fs.test_status, fs.solve_time_s
        );
    } else if fs.solution == "unconstrained" {
        println!(
            "first stage: no physically consistent body has the least-squares parameters (consistency test {}), \
             but the data identify every direction: kept (the pseudo-inertia LMI fit, {} in {:.3} s, would cost +{:.3} sigma²)",
            fs.test_status, fs.fit_status, fs.solve_time_s, fs.residual_increase_sigma2
        );
    } else {
        println!(
            "first stage: no physically consistent body has the least-squares parameters (consistency test {}); \
             pseudo-inertia LMI fit {} in {:.3} s, weighted residual +{:.3} sigma², smallest pseudo-inertia eigenvalue {min_eig:.3e} kg·m²",
            fs.test_status, fs.fit_status, fs.solve_time_s, fs.residual_increase_sigma2
        );
    }
    print!("per-joint noise sigma [N·m]:");
    for s in &id.joint_sigma_nm {
        print!(" {s:.4}");
    }
    println!();
    print_table(
        "per-joint RMS torque error [N·m] (firmware f32 model)",
        &joint_names,
        &table,
    );
    println!("f32 firmware model vs f64 regressor: max |difference| {max_diff:.3e} N·m");
    file.write(&a.out)?;
    println!("wrote {}", a.out.display());
    Ok(())
}

/// Runs `torque`.
pub fn torque(a: &TorqueArgs) -> anyhow::Result<()> {
    let layout = a.layout.layout()?;
    let pre = a.pre.options()?;
    let source = RobotSource::from(a.robot.clone());
    let identified = load_model_robot(&source, a.identified.as_deref(), &a.joints.selection()?)?;
    if let Some(w) = &identified.warning {
        eprintln!("warning: {w}");
    }
    let (robot, theta) = (identified.robot, identified.standard_parameters);
    let fw = FirmwareModel::build(&robot, &theta)?;
    let joints = robot.modelled_joints();
    let raw = read_robot_log(
        &a.log,
        &layout,
        &a.layout.bag_options()?,
        &joint_names(&robot),
    )?;
    for note in &raw.notes {
        eprintln!("note: {note}");
    }
    if raw.q_rad.len() != robot.dof() {
        bail!(
            "{}: the log has {} joints but the robot has {}",
            a.log.display(),
            raw.q_rad.len(),
            robot.dof()
        );
    }
    let s = preprocess(&raw, &pre)?;
    let pred = predict_log(&fw, &joints, &s);
    // Finite inputs can still give non-finite torques (a huge position or velocity):
    // nothing non-finite is written.
    for (p, &j) in pred.iter().zip(&joints) {
        if let Some(k) = p.iter().position(|x| !x.is_finite()) {
            bail!(
                "{}: at t = {} s the model torque of joint {} is not finite (state q = {}, qd = {}, qdd = {}); nothing written",
                a.log.display(),
                s.time_s[k],
                j + 1,
                s.q_rad[j][k],
                s.qd_rad_s[j][k],
                s.qdd_rad_s2[j][k]
            );
        }
    }
    let out = if a.dataset {
        compensation_dataset_csv(&a.log, &joints, &s, &pred)?
    } else {
        named_torque_csv(&robot, &joints, &s, &pred)
    };
    write_atomic(&a.out, out.as_bytes())?;
    if let Some(acc) = pipeline::errors(&pred, &joints, &s) {
        let e = acc.finish();
        let names: Vec<String> = joints
            .iter()
            .map(|&j| robot.joints[j].name.clone())
            .collect();
        print_table(
            "per-joint RMS torque error [N·m] (firmware f32 model)",
            &names,
            &[(file_label(&a.log), e.rms_nm, e.nrms_pct, e.samples)],
        );
    }
    println!("wrote {} ({} samples)", a.out.display(), s.len());
    Ok(())
}

/// `torque`'s default output: time, then the model and measured torque per modelled joint.
fn named_torque_csv(robot: &Robot, joints: &[usize], s: &Samples, pred: &[Vec<f64>]) -> String {
    let mut out = String::new();
    out.push_str("time_s");
    for &j in joints {
        out.push_str(&format!(",tau_model_{}_nm", robot.joints[j].name));
    }
    if s.torque_nm.is_some() {
        for &j in joints {
            out.push_str(&format!(",tau_measured_{}_nm", robot.joints[j].name));
        }
    }
    out.push('\n');
    for k in 0..s.len() {
        out.push_str(&format!("{:.6}", s.time_s[k]));
        for p in pred {
            out.push_str(&format!(",{:.6}", p[k]));
        }
        if let Some(t) = &s.torque_nm {
            for &j in joints {
                out.push_str(&format!(",{:.6}", t[j][k]));
            }
        }
        out.push('\n');
    }
    out
}

/// The `drive` inputs (`firmware::features::DRIVE_COLUMNS` indices) that a compensation
/// dataset stores beside q, qd, qdd and the torques: sin q, cos q, the rest direction and
/// the presliding states.
const DERIVED_COLUMNS: [usize; 7] = [0, 1, 5, 6, 7, 8, 9];

/// `torque --dataset`: the compensation dataset (`nn::data` column names).
fn compensation_dataset_csv(
    log: &Path,
    joints: &[usize],
    s: &Samples,
    pred: &[Vec<f64>],
) -> anyhow::Result<String> {
    let Some(tau) = &s.torque_nm else {
        bail!(
            "{}: no torque or current columns; a compensation dataset needs the measured torque",
            log.display()
        );
    };
    let mut out = String::from("time_s");
    for kind in ["q", "qd", "tau_meas", "tau_model", "qdd"]
        .into_iter()
        .chain(DERIVED_COLUMNS.map(|c| features::DRIVE_COLUMNS[c]))
    {
        for &j in joints {
            out.push_str(&format!(",{kind}_j{}", j + 1));
        }
    }
    out.push('\n');
    // The drive's own feature functions, on the values as the dataset stores them.
    let stored = |x: f64| format!("{x:.6}").parse::<f32>().unwrap_or(f32::NAN);
    let mut motion = vec![features::MotionMemory::new(); joints.len()];
    for k in 0..s.len() {
        out.push_str(&format!("{:.6}", s.time_s[k]));
        for series in [&s.q_rad, &s.qd_rad_s, tau] {
            for &j in joints {
                out.push_str(&format!(",{:.6}", series[j][k]));
            }
        }
        for p in pred {
            out.push_str(&format!(",{:.6}", p[k]));
        }
        for &j in joints {
            out.push_str(&format!(",{:.6}", s.qdd_rad_s2[j][k]));
        }
        let derived: Vec<[f32; features::DRIVE_INPUTS_PER_JOINT]> = joints
            .iter()
            .zip(motion.iter_mut())
            .map(|(&j, m)| {
                let (q, qd) = (stored(s.q_rad[j][k]), stored(s.qd_rad_s[j][k]));
                features::drive_inputs(q, qd, 0.0, 0.0, m.update(q, qd), 0.0)
            })
            .collect();
        for col in DERIVED_COLUMNS {
            for x in &derived {
                out.push_str(&format!(",{}", x[col]));
            }
        }
        out.push('\n');
    }
    Ok(out)
}
