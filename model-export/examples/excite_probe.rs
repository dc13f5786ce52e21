//! Probe of the excitation design: column norms, singular vectors, several criteria and the
//! identification standard deviations along optimised and random feasible trajectories.
//!
//! Analysis only (no library change): why the wrist's optimised/random factor is small.
//!
//! `cargo run --profile host -p model-export --example excite_probe -- [wrist|all] [restarts]
//!  [evaluations] [criteria...]` (criteria: condition, scaled, logdet; default all three) designs
//! with each criterion and prints, against the CLI's two random baselines (20 seeded draws,
//! master seed 1): cond(W), unit-column cond, max/min column-norm ratio, exp(Δ logdet / p)
//! (the "logdet" row's factor), per-parameter identification standard deviations (0.5 N·m
//! noise, 3 periods at 100 Hz, OLS: σ·sqrt(diag((WᵀW)⁻¹))) and their random/optimised ratios,
//! and variance inflation factors `sqrt((WᵀW)⁻¹_ii (WᵀW)_ii)` (1 = orthogonal column).
//!
//! `... --example excite_probe -- friction [restarts] [evaluations]`: the smallest unit-column
//! condition number of one wrist joint's friction block `[q̇, sign q̇]` over the family (a lower
//! bound for the full unit-column condition number of any member). `... -- floors [restarts]
//! [evaluations]`: the smallest condition numbers found for the wrist's friction and
//! gravity + friction column subsets (lower bounds for the full `W` of the same trajectory).

use excitation::objective::observation_matrix;
use excitation::optimise::baseline_seed;
use excitation::robot_model::{LimitOverrides, RobotObservation, joint_limits};
use excitation::{
    BaselineScaling, Criterion, ExcitationSettings, ExcitationTrajectory, FourierFamily,
    ObservationModel, design, random_feasible,
};
use nalgebra::DMatrix;
use robot::Robot;

/// A printed metric: name, getter, and whether its factor is random / optimised (else
/// exp((optimised − random) / p), for the log-determinant).
type Row = (&'static str, fn(&Metrics) -> f64, bool);

#[derive(Clone, Debug)]
struct Metrics {
    cond: f64,
    scaled: f64,
    logdet: f64,
    colratio: f64,
    /// std of each base parameter (0.5 N·m noise, 3 periods at 100 Hz, OLS)
    std: Vec<f64>,
    /// variance inflation sqrt(inv(G)_ii G_ii) per parameter
    vif: Vec<f64>,
}

fn cond(w: &DMatrix<f64>) -> f64 {
    let s = w.clone().singular_values();
    s.max() / s.min()
}

fn metrics(model: &RobotObservation, tr: &ExcitationTrajectory) -> Metrics {
    let w = observation_matrix(model, tr, 100.0);
    let n = w.nrows() as f64 / model.joint_count() as f64;
    let p = w.ncols();
    let norms: Vec<f64> = w.column_iter().map(|c| c.norm()).collect();
    let mut ws = w.clone();
    for (mut c, n) in ws.column_iter_mut().zip(&norms) {
        c.scale_mut(1.0 / n);
    }
    let g = w.transpose() * &w;
    let logdet = g
        .clone()
        .symmetric_eigenvalues()
        .iter()
        .map(|l| (l / n).ln())
        .sum();
    let inv = (g * 3.0).try_inverse().unwrap();
    let std = (0..p).map(|i| 0.5 * inv[(i, i)].sqrt()).collect();
    let vif = (0..p)
        .map(|i| (inv[(i, i)] * 3.0).sqrt() * norms[i])
        .collect();
    let mx = norms.iter().copied().fold(0.0, f64::max);
    let mn = norms.iter().copied().fold(f64::INFINITY, f64::min);
    Metrics {
        cond: cond(&w),
        scaled: cond(&ws),
        logdet,
        colratio: mx / mn,
        std,
        vif,
    }
}

fn describe(model: &RobotObservation, names: &[String], tr: &ExcitationTrajectory, label: &str) {
    let w = observation_matrix(model, tr, 100.0);
    let n = w.nrows() as f64;
    let svd = w.clone().svd(false, true);
    let vt = svd.v_t.unwrap();
    let sv = &svd.singular_values;
    let (imax, imin) = (sv.imax(), sv.imin());
    println!(
        "--- {label}: cond {:.2}; sigma rms max {:.3} min {:.3}",
        sv[imax] / sv[imin],
        sv[imax] / n.sqrt(),
        sv[imin] / n.sqrt()
    );
    let mut s = String::new();
    for (j, c) in w.column_iter().enumerate() {
        s += &format!(" {}={:.3}", names[j], c.norm() / n.sqrt());
    }
    println!("  column rms per row:{s}");
    for (tag, i) in [("v_max", imax), ("v_min", imin)] {
        let mut comp: Vec<(usize, f64)> = vt.row(i).iter().copied().enumerate().collect();
        comp.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
        let txt: Vec<String> = comp
            .iter()
            .take(5)
            .map(|(j, v)| format!("{}:{:+.2}", names[*j], v))
            .collect();
        println!("  {tag}: {}", txt.join(" "));
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let m = v.len();
    if m % 2 == 1 {
        v[m / 2]
    } else {
        0.5 * (v[m / 2 - 1] + v[m / 2])
    }
}

/// One joint's friction columns only: `[q̇, sign(q̇)]` (viscous, Coulomb).
struct Friction;
impl ObservationModel for Friction {
    fn joint_count(&self) -> usize {
        1
    }
    fn rows_per_sample(&self) -> usize {
        1
    }
    fn parameter_count(&self) -> usize {
        2
    }
    fn rows(&self, _q: &[f64], qd: &[f64], _qdd: &[f64], out: &mut [f64]) {
        out[0] = qd[0];
        out[1] = if qd[0] > 0.0 {
            1.0
        } else if qd[0] < 0.0 {
            -1.0
        } else {
            0.0
        };
    }
}

/// A subset of the columns of the wrist's observation matrix: the smallest condition number of
/// a column subset over the family is a lower bound for the full matrix's (cond(W) ≥ cond(W_S)
/// for any column subset S, unscaled and with unit columns).
struct Subset<'a> {
    inner: &'a RobotObservation,
    cols: Vec<usize>,
    buf: std::cell::RefCell<Vec<f64>>,
}
impl ObservationModel for Subset<'_> {
    fn joint_count(&self) -> usize {
        self.inner.joint_count()
    }
    fn rows_per_sample(&self) -> usize {
        self.inner.rows_per_sample()
    }
    fn parameter_count(&self) -> usize {
        self.cols.len()
    }
    fn rows(&self, q: &[f64], qd: &[f64], qdd: &[f64], out: &mut [f64]) {
        let p = self.inner.parameter_count();
        let mut b = self.buf.borrow_mut();
        b.resize(self.rows_per_sample() * p, 0.0);
        self.inner.rows(q, qd, qdd, &mut b);
        let k = self.cols.len();
        for r in 0..self.rows_per_sample() {
            for (c, &col) in self.cols.iter().enumerate() {
                out[r * k + c] = b[r * p + col];
            }
        }
    }
}

fn subset_floors(restarts: usize, evals: usize) {
    use excitation::optimise::final_score;
    let model = RobotObservation::new(default_robot().default_paper_selection()).unwrap();
    let base = model.base();
    let names: Vec<String> = base
        .independent
        .iter()
        .map(|&i| base.standard_names[i].clone())
        .collect();
    let limits = joint_limits(model.robot(), &LimitOverrides::default()).unwrap();
    let family = FourierFamily::new(10.0, 5, &[0.0; 3], &limits, &[], 1000.0).unwrap();
    let pick = |want: &[&str]| -> Vec<usize> {
        want.iter()
            .map(|w| names.iter().position(|n| n == w).expect("name"))
            .collect()
    };
    let friction = ["fv4", "fc4", "fv5", "fc5", "fv6", "fc6"];
    let gravity = ["mx4", "mz4", "mx5", "mz5", "mx6", "my6"];
    let both: Vec<&str> = gravity.iter().chain(friction.iter()).copied().collect();
    for (label, cols) in [
        ("friction (6 columns)", pick(&friction)),
        ("gravity + friction (12 columns)", pick(&both)),
    ] {
        let sub = Subset {
            inner: &model,
            cols,
            buf: Default::default(),
        };
        for crit in [Criterion::Condition, Criterion::ScaledCondition] {
            let settings = ExcitationSettings {
                restarts,
                evaluations_per_restart: evals,
                criterion: crit,
                ..ExcitationSettings::default()
            };
            let d = design(&sub, family.clone(), &settings).unwrap();
            let rnd: Vec<f64> = (0..20)
                .map(|i| {
                    let s = final_score(
                        &sub,
                        &random_feasible(&family, baseline_seed(1, i), BaselineScaling::PerJoint),
                        100.0,
                    );
                    if crit == Criterion::Condition {
                        s.condition
                    } else {
                        s.scaled_condition
                    }
                })
                .collect();
            let v = if crit == Criterion::Condition {
                d.score.condition
            } else {
                d.score.scaled_condition
            };
            println!(
                "subset {label}, {crit:?}: smallest found {v:.3} (lower bound for the full W); random per-joint median of the subset {:.3}",
                median(rnd)
            );
        }
    }
}

fn friction_floor(lim: excitation::JointLimits, restarts: usize, evals: usize) {
    use excitation::optimise::final_score;
    let family = FourierFamily::new(10.0, 5, &[0.0], &[lim], &[], 1000.0).unwrap();
    let settings = ExcitationSettings {
        restarts,
        evaluations_per_restart: evals,
        criterion: Criterion::ScaledCondition,
        ..ExcitationSettings::default()
    };
    let d = design(&Friction, family.clone(), &settings).unwrap();
    let rnd: Vec<f64> = (0..20)
        .map(|i| {
            final_score(
                &Friction,
                &random_feasible(&family, baseline_seed(1, i), BaselineScaling::PerJoint),
                100.0,
            )
            .scaled_condition
        })
        .collect();
    let rho = |c: f64| (c * c - 1.0) / (c * c + 1.0);
    println!(
        "friction block [qd, sign qd] of one joint {lim:?}: unit-column cond min found {:.3} (corr {:.3}, VIF {:.3}); random median {:.3} (corr {:.3})",
        d.score.scaled_condition,
        rho(d.score.scaled_condition),
        1.0 / (1.0 - rho(d.score.scaled_condition).powi(2)).sqrt(),
        median(rnd.clone()),
        rho(median(rnd))
    );
}

/// The built-in default robot (`robots/default.toml`).
fn default_robot() -> Robot {
    Robot::load(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../robots/default.toml"
    )))
    .unwrap()
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.first().map(String::as_str) == Some("friction") {
        let r: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(4);
        let e: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(6000);
        friction_floor(
            excitation::JointLimits::symmetric(std::f64::consts::TAU, std::f64::consts::PI, 12.0),
            r,
            e,
        );
        return;
    }
    if args.first().map(String::as_str) == Some("floors") {
        let r: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(4);
        let e: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(6000);
        subset_floors(r, e);
        return;
    }
    let which = args.first().map(String::as_str).unwrap_or("wrist");
    let restarts: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(4);
    let evals: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(6000);
    let crits: Vec<String> = if args.len() > 3 {
        args[3..].to_vec()
    } else {
        vec!["condition".into(), "scaled".into(), "logdet".into()]
    };
    let robot = default_robot();
    let robot = if which == "all" {
        let mut r = robot;
        r.model_all_joints();
        r
    } else {
        robot.default_paper_selection()
    };
    let model = RobotObservation::new(robot).unwrap();
    let base = model.base();
    let names: Vec<String> = base
        .independent
        .iter()
        .map(|&i| base.standard_names[i].clone())
        .collect();
    let beta = base.beta(&model.robot().standard_parameters());
    let limits = joint_limits(model.robot(), &LimitOverrides::default()).unwrap();
    println!("limits {limits:?}");
    for (i, nm) in names.iter().enumerate() {
        println!("  b{:<2} {:<14} beta {:+.5}", i + 1, nm, beta[i]);
    }
    let family =
        FourierFamily::new(10.0, 5, &vec![0.0; limits.len()], &limits, &[], 1000.0).unwrap();
    let small: Vec<String> = names
        .iter()
        .zip(beta.iter())
        .filter(|(_, b)| b.abs() < 1e-4)
        .map(|(n, b)| format!("{n}={b:.1e}"))
        .collect();
    println!(
        "nominal base parameters below 1e-4 ({}): {} -> W·diag|beta| singular or dominated by them (relative-precision criterion not usable)",
        small.len(),
        small.join(" ")
    );

    // Random baselines (the CLI's seeds, master seed 1).
    let count = 20;
    let mut pops = Vec::new();
    for sc in BaselineScaling::ALL {
        let trs: Vec<ExcitationTrajectory> = (0..count)
            .map(|i| random_feasible(&family, baseline_seed(1, i), sc))
            .collect();
        let ms: Vec<Metrics> = trs.iter().map(|t| metrics(&model, t)).collect();
        describe(&model, &names, &trs[0], &format!("random {} #0", sc.name()));
        pops.push((sc, ms));
    }
    for c in &crits {
        let crit = match c.as_str() {
            "condition" => Criterion::Condition,
            "scaled" => Criterion::ScaledCondition,
            "logdet" => Criterion::LogDet,
            other => panic!("criterion {other}: condition, scaled or logdet"),
        };
        let settings = ExcitationSettings {
            restarts,
            evaluations_per_restart: evals,
            criterion: crit,
            ..ExcitationSettings::default()
        };
        let d = design(&model, family.clone(), &settings).unwrap();
        let costs: Vec<String> = d
            .restarts
            .iter()
            .map(|r| format!("{:.4}", r.best_cost))
            .collect();
        let m = metrics(&model, &d.trajectory);
        println!(
            "\n=== optimised for {c} ({restarts}x{evals}, {:.1} s; restart costs {})",
            d.seconds,
            costs.join(" ")
        );
        describe(&model, &names, &d.trajectory, &format!("optimised {c}"));
        let util: Vec<String> = d
            .margins
            .iter()
            .map(|m| format!("{:.2}", m.utilisation))
            .collect();
        println!("  utilisation (q-,q+,qd,qdd per joint): {}", util.join(" "));
        println!(
            "  {:<10} {:>9} | {:>9} {:>6} | {:>9} {:>6}",
            "metric", "optimised", "rnd_perj", "x", "rnd_comm", "x"
        );
        let rows: [Row; 4] = [
            ("cond(W)", |m| m.cond, true),
            ("unit-col", |m| m.scaled, true),
            ("colratio", |m| m.colratio, true),
            ("logdet", |m| m.logdet, false),
        ];
        for (name, f, ratio) in rows {
            let o = f(&m);
            let mut line = format!("  {name:<10} {o:>9.3} |");
            for (_, ms) in &pops {
                let med = median(ms.iter().map(f).collect());
                let x = if ratio {
                    med / o
                } else {
                    ((o - med) / m.std.len() as f64).exp()
                };
                line += &format!(" {med:>9.3} {x:>6.2} |");
            }
            println!("{line}");
        }
        // Standard deviations: ratio random/optimised per parameter (median over population).
        for (sc, ms) in &pops {
            let p = m.std.len();
            let per: Vec<f64> = (0..p)
                .map(|i| median(ms.iter().map(|r| r.std[i] / m.std[i]).collect()))
                .collect();
            let trace = |s: &[f64]| s.iter().map(|x| x * x).sum::<f64>();
            let maxstd = |s: &[f64]| s.iter().copied().fold(0.0, f64::max);
            let med_trace = median(ms.iter().map(|r| trace(&r.std)).collect());
            let med_max = median(ms.iter().map(|r| maxstd(&r.std)).collect());
            let txt: Vec<String> = per
                .iter()
                .enumerate()
                .map(|(i, r)| format!("{}:{:.2}", names[i], r))
                .collect();
            println!(
                "  std ratio random({})/optimised per parameter: {}",
                sc.name(),
                txt.join(" ")
            );
            println!(
                "    median ratio {:.2}, min {:.2}, max {:.2}; sqrt(trace) ratio {:.2}; max-std ratio {:.2}; geo-mean ratio {:.2}",
                median(per.clone()),
                per.iter().copied().fold(f64::INFINITY, f64::min),
                per.iter().copied().fold(0.0, f64::max),
                (med_trace / trace(&m.std)).sqrt(),
                med_max / maxstd(&m.std),
                (per.iter().map(|r| r.ln()).sum::<f64>() / p as f64).exp()
            );
        }
        let vtxt: Vec<String> = (0..m.std.len())
            .map(|i| {
                format!(
                    "{}:{:.2}/{:.2}/{:.2}",
                    names[i],
                    m.vif[i],
                    median(pops[0].1.iter().map(|r| r.vif[i]).collect()),
                    median(pops[1].1.iter().map(|r| r.vif[i]).collect())
                )
            })
            .collect();
        println!(
            "  VIF optimised/random-perj-median/random-common-median: {}",
            vtxt.join(" ")
        );
        let fc_floor = 0.5 / (3000.0f64).sqrt();
        println!(
            "  Coulomb std floor (any trajectory, 0.5 N*m, 3000 samples): {:.5} N*m",
            fc_floor
        );
        let rel: Vec<String> = (0..m.std.len())
            .map(|i| format!("{}:{:.2}%", names[i], 100.0 * m.std[i] / beta[i].abs()))
            .collect();
        println!("  relative std optimised: {}", rel.join(" "));
    }
}
