//! The friction-feature least-squares baseline: coefficient recovery on synthetic
//! datasets (with and without the `qdd`, `rest_dir` and presliding columns), bad input, and the
//! `evaluate --baseline-data` wiring.
use compnet::baseline::{self, FEATURE_NAMES, N_FEATURES};
use compnet::data::{FeatureSpec, Table};
use compnet::{LstmModel, io};
use firmware::nn::reference::LstmDims;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::Command;

const JOINTS: [usize; 2] = [1, 3];

/// Per joint: the extra torque over `tau_model` [N·m per feature unit], FEATURE_NAMES
/// order (the `tau_model` entry is a gain error: the fitted coefficient is 1 + it).
fn truth(joint: usize) -> [f64; N_FEATURES] {
    let s = joint as f64;
    [
        0.3 * s,
        0.05 * s,
        1.2,
        -0.4 * s,
        0.8,
        0.25,
        2.0 / s,
        -0.3,
        0.15 * s,
        0.02 * s,
        1.5,
        -0.7 * s,
        0.35,
        0.2,
        0.6 / s,
        0.04 * s,
        -0.03 * s,
        0.05,
        0.1 / s,
        0.9,
        -0.5 * s,
        0.3,
        -0.2,
        0.02 * s,
        -0.04,
        0.06 / s,
        0.015 * s,
    ]
}

/// Presliding (Maxwell-slip) states over a sequence of angles [rad], written out from
/// their definition: spans of 1, 3, 10 and 30 mrad, saturating at +-1.
fn presliding(q: &[f32]) -> Vec<[f64; 4]> {
    let spans = [0.001, 0.003, 0.01, 0.03];
    let mut s = [0.0f64; 4];
    let mut last = q[0] as f64;
    q.iter()
        .map(|&x| {
            let dq = x as f64 - last;
            last = x as f64;
            for (e, span) in s.iter_mut().zip(spans) {
                *e = (*e + dq / span).clamp(-1.0, 1.0);
            }
            s
        })
        .collect()
}

/// The features of one row, computed independently of the crate (f32 inputs, f64 math).
fn row_features(
    q: f32,
    qd: f32,
    qdd: f64,
    tau_model: f32,
    (rest, slip): (f64, [f64; 4]),
) -> [f64; N_FEATURES] {
    let (q, v, m) = (q as f64, qd as f64, tau_model as f64);
    let sgn = if v > 0.0 {
        1.0
    } else if v < 0.0 {
        -1.0
    } else {
        0.0
    };
    [
        1.0,
        m,
        (v / 0.01).tanh(),
        (v / 0.05).tanh(),
        (v / 0.2).tanh(),
        (v / 1.0).tanh(),
        v,
        v * v.abs(),
        v.abs().sqrt() * sgn,
        qdd,
        q.sin(),
        q.cos(),
        (2.0 * q).sin(),
        (2.0 * q).cos(),
        rest,
        m.abs() * (v / 0.05).tanh(),
        m * (v / 0.05).tanh(),
        m.abs() * (v / 0.2).tanh(),
        m.abs(),
        slip[0],
        slip[1],
        slip[2],
        slip[3],
        m.abs() * slip[0],
        m.abs() * slip[1],
        m.abs() * slip[2],
        m.abs() * slip[3],
    ]
}

/// Writes a synthetic dataset of `n` rows: random states (speeds over four decades, a
/// fifth of the rows at rest), `tau_meas = tau_model + truth · features + noise`. With
/// `full`, the `qdd`, `rest_dir` and presliding columns are written (random); without,
/// the baseline must compute them (central differences over `time_s`, the last motion's
/// direction, the presliding states of the angles).
fn write_dataset(path: &Path, n: usize, seed: u64, full: bool, noise_nm: f64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, noise_nm.max(1e-300)).unwrap();
    let time: Vec<f32> = (0..n).map(|k| 10.0 + k as f32 * 0.01).collect();
    let mut names = vec!["time_s".to_string()];
    let mut cols: Vec<Vec<f32>> = vec![time.clone()];
    let mut meas = Vec::new();
    let mut per_joint = Vec::new();
    for &j in &JOINTS {
        let q: Vec<f32> = (0..n).map(|_| rng.gen_range(-3.0f32..3.0)).collect();
        let qd: Vec<f32> = (0..n)
            .map(|_| {
                if rng.gen_bool(0.2) {
                    rng.gen_range(-0.004f32..0.004)
                } else {
                    let mag = 10f32.powf(rng.gen_range(-3.0f32..0.6));
                    if rng.gen_bool(0.5) { mag } else { -mag }
                }
            })
            .collect();
        let qdd_col: Vec<f32> = (0..n).map(|_| rng.gen_range(-4.0f32..4.0)).collect();
        let rest_col: Vec<f32> = (0..n).map(|_| rng.gen_range(-1i32..=1) as f32).collect();
        let model: Vec<f32> = (0..n).map(|_| rng.gen_range(-3.0f32..3.0)).collect();
        let slip_cols: Vec<Vec<f32>> = (0..4)
            .map(|_| (0..n).map(|_| rng.gen_range(-1.0f32..1.0)).collect())
            .collect();
        // What the baseline sees without the columns.
        let qdd: Vec<f64> = if full {
            qdd_col.iter().map(|&v| v as f64).collect()
        } else {
            (0..n)
                .map(|k| {
                    let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
                    (qd[b] as f64 - qd[a] as f64) / (time[b] as f64 - time[a] as f64)
                })
                .collect()
        };
        let rest: Vec<f64> = if full {
            rest_col.iter().map(|&v| v as f64).collect()
        } else {
            let mut last = 0.0;
            qd.iter()
                .map(|&v| {
                    if v.abs() > 0.005 {
                        last = v.signum() as f64;
                        0.0
                    } else {
                        last
                    }
                })
                .collect()
        };
        let slip: Vec<[f64; 4]> = if full {
            (0..n)
                .map(|k| std::array::from_fn(|e| slip_cols[e][k] as f64))
                .collect()
        } else {
            presliding(&q)
        };
        let c = truth(j);
        let tau: Vec<f32> = (0..n)
            .map(|k| {
                let f = row_features(q[k], qd[k], qdd[k], model[k], (rest[k], slip[k]));
                let extra: f64 = c.iter().zip(&f).map(|(a, b)| a * b).sum();
                let e = if noise_nm > 0.0 {
                    noise.sample(&mut rng)
                } else {
                    0.0
                };
                (model[k] as f64 + extra + e) as f32
            })
            .collect();
        meas.push((format!("tau_meas_j{j}"), tau));
        per_joint.push((j, q, qd, model, qdd_col, rest_col, slip_cols));
    }
    for (j, q, qd, model, qdd_col, rest_col, slip_cols) in per_joint {
        names.extend(["q", "qd", "tau_model"].map(|k| format!("{k}_j{j}")));
        cols.extend([q.clone(), qd, model]);
        if full {
            names.extend(["qdd", "sin_q", "cos_q", "rest_dir"].map(|k| format!("{k}_j{j}")));
            cols.extend([
                qdd_col,
                q.iter().map(|v| v.sin()).collect(),
                q.iter().map(|v| v.cos()).collect(),
                rest_col,
            ]);
            names.extend(
                ["slip_1mrad", "slip_3mrad", "slip_10mrad", "slip_30mrad"]
                    .map(|k| format!("{k}_j{j}")),
            );
            cols.extend(slip_cols);
        }
    }
    for (name, tau) in meas {
        names.push(name);
        cols.push(tau);
    }
    let mut s = names.join(",");
    s.push('\n');
    for k in 0..n {
        let row: Vec<String> = cols.iter().map(|c| format!("{}", c[k])).collect();
        s += &row.join(",");
        s.push('\n');
    }
    std::fs::write(path, s).unwrap();
}

fn datasets(dir: &Path, noise_nm: f64) -> Vec<PathBuf> {
    let a = dir.join("run_a.csv");
    let b = dir.join("run_b.csv");
    write_dataset(&a, 4000, 11, true, noise_nm);
    write_dataset(&b, 3000, 12, false, noise_nm);
    vec![a, b]
}

fn read(paths: &[PathBuf]) -> Vec<Table> {
    paths.iter().map(|p| Table::read(p).unwrap()).collect()
}

#[test]
fn the_fit_recovers_the_coefficients() {
    let dir = tempfile::tempdir().unwrap();
    let tables = read(&datasets(dir.path(), 0.0));
    let fit = baseline::fit(&tables, &JOINTS).unwrap();
    assert_eq!(fit.joints, JOINTS);
    assert_eq!(fit.feature_names, FEATURE_NAMES);
    assert_eq!(fit.samples, 7000);
    let mut worst = 0.0f64;
    for &j in &JOINTS {
        let mut want = truth(j);
        want[1] += 1.0;
        let got = fit.joint_coefficients(j).unwrap();
        for (f, (g, w)) in got.iter().zip(&want).enumerate() {
            assert!(
                (g - w).abs() < 1e-6,
                "joint {j}, {}: {g} vs {w}",
                FEATURE_NAMES[f]
            );
            worst = worst.max((g - w).abs());
        }
    }
    eprintln!("noise-free: largest coefficient error {worst:.2e}");
    // The prediction reproduces the measured torque on both tables (f32 rounding only).
    for t in &tables {
        let p = fit.predict(t).unwrap();
        for (k, &j) in JOINTS.iter().enumerate() {
            let y = t.column(&format!("tau_meas_j{j}")).unwrap();
            for (a, b) in p[k].iter().zip(y) {
                assert!((a - *b as f64).abs() < 1e-4 * (1.0 + b.abs() as f64));
            }
        }
    }
}

#[test]
fn with_noise_the_fit_is_close_and_its_residual_is_the_noise() {
    let dir = tempfile::tempdir().unwrap();
    let sigma = 0.05;
    let tables = read(&datasets(dir.path(), sigma));
    let fit = baseline::fit(&tables, &JOINTS).unwrap();
    let clean_dir = tempfile::tempdir().unwrap();
    let clean = read(&datasets(clean_dir.path(), 0.0));
    for (k, &j) in JOINTS.iter().enumerate() {
        let r = fit.train_rms_nm[k];
        assert!((r / sigma - 1.0).abs() < 0.1, "joint {j}: residual {r}");
        // The fitted function is within a fraction of the noise of the true one.
        let mut ss = 0.0;
        let mut n = 0;
        for t in &clean {
            let p = fit.predict(t).unwrap();
            let y = t.column(&format!("tau_meas_j{j}")).unwrap();
            for (a, b) in p[k].iter().zip(y) {
                ss += (a - *b as f64).powi(2);
                n += 1;
            }
        }
        let e = (ss / n as f64).sqrt();
        assert!(e < 0.25 * sigma, "joint {j}: function error {e}");
        let got = fit.joint_coefficients(j).unwrap();
        // Well-determined coefficients: the model gain and the pose terms.
        for f in [1, 10, 11, 12, 13] {
            let w = truth(j)[f] + if f == 1 { 1.0 } else { 0.0 };
            assert!(
                (got[f] - w).abs() < 0.02,
                "joint {j}, {}: {} vs {w}",
                FEATURE_NAMES[f],
                got[f]
            );
        }
    }
}

#[test]
fn a_missing_column_names_the_file_and_the_column() {
    let dir = tempfile::tempdir().unwrap();
    let paths = datasets(dir.path(), 0.0);
    let t = Table::read(&paths[0]).unwrap();
    // Drop `tau_model_j3` from the first file.
    let k = t.names.iter().position(|n| n == "tau_model_j3").unwrap();
    let mut cut = t.clone();
    cut.names.remove(k);
    cut.columns.remove(k);
    let e = format!(
        "{:#}",
        baseline::fit(&[read(&paths[1..])[0].clone(), cut.clone()], &JOINTS).unwrap_err()
    );
    assert!(
        e.contains("run_a.csv") && e.contains("`tau_model_j3`"),
        "{e}"
    );
    // Predicting on it fails the same way.
    let fit = baseline::fit(&read(&paths), &JOINTS).unwrap();
    let e = format!("{:#}", fit.predict(&cut).unwrap_err());
    assert!(
        e.contains("run_a.csv") && e.contains("`tau_model_j3`"),
        "{e}"
    );
    // Without `qdd_j1`, `time_s` is needed.
    let mut no_time = t.clone();
    for name in ["qdd_j1", "time_s"] {
        let k = no_time.names.iter().position(|n| n == name).unwrap();
        no_time.names.remove(k);
        no_time.columns.remove(k);
    }
    let e = format!("{:#}", fit.predict(&no_time).unwrap_err());
    assert!(e.contains("run_a.csv") && e.contains("`time_s`"), "{e}");
    // Fewer rows than features.
    let mut short = t.clone();
    for c in &mut short.columns {
        c.truncate(N_FEATURES - 1);
    }
    let e = format!("{:#}", baseline::fit(&[short], &JOINTS).unwrap_err());
    let want = format!("{} training samples", N_FEATURES - 1);
    assert!(e.contains(&want), "{e}");
}

/// A feedforward model for joints 1 and 3 (untrained: only the baseline column matters).
fn feedforward_model(path: &Path) {
    let spec = FeatureSpec::feedforward(&JOINTS);
    let mut m = LstmModel::init(
        LstmDims {
            input: spec.inputs.len(),
            embed: 8,
            hidden: 8,
            output: JOINTS.len(),
        },
        3,
    );
    m.input_names = spec.inputs.clone();
    m.output_names = spec.output_names();
    m.preset = spec.preset.clone();
    io::write_model(&m, path).unwrap();
}

/// Two training datasets, a feedforward network and a test dataset of `test_rows` rows
/// in `dir`.
fn evaluation_files(dir: &Path, test_rows: usize) -> (Vec<PathBuf>, PathBuf, PathBuf) {
    let paths = datasets(dir, 0.05);
    let model = dir.join("ff.safetensors");
    feedforward_model(&model);
    let test = dir.join("test.csv");
    write_dataset(&test, test_rows, 99, true, 0.05);
    (paths, model, test)
}

/// Writes `from` to `to` with column `column`'s field of each line (1-based, the
/// header is line 0) replaced by `edit(line, field)`.
fn edit_column(from: &Path, to: &Path, column: &str, edit: impl Fn(usize, &str) -> String) {
    let text = std::fs::read_to_string(from).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let k = lines[0].split(',').position(|n| n == column).unwrap();
    for (row, l) in lines.iter_mut().enumerate().skip(1) {
        let mut f: Vec<String> = l.split(',').map(String::from).collect();
        f[k] = edit(row, &f[k]);
        *l = f.join(",");
    }
    std::fs::write(to, lines.join("\n") + "\n").unwrap();
}

/// `evaluate` of the feedforward network `model` on joints 1 and 3 of `test`, report to
/// `report`.
fn evaluation_args(model: &Path, test: &Path, report: &Path) -> Vec<OsString> {
    vec![
        "--model".into(),
        model.into(),
        "--data".into(),
        test.into(),
        "--preset".into(),
        "feedforward".into(),
        "--joints".into(),
        "1,3".into(),
        "--report".into(),
        report.into(),
    ]
}

fn evaluate(args: &[OsString]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_model-export"))
        .arg("evaluate")
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn evaluate_reports_the_baseline_and_refuses_bad_baseline_data() {
    let dir = tempfile::tempdir().unwrap();
    let (paths, model, test) = evaluation_files(dir.path(), 400);
    let report = dir.path().join("eval.json");
    let base = format!("{},{}", paths[0].display(), paths[1].display());
    let common = |report: &Path| evaluation_args(&model, &test, report);

    // Without the flag: no baseline column, nulls in the report.
    let plain = dir.path().join("plain.json");
    let args = common(&plain);
    let out = evaluate(&args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(!String::from_utf8_lossy(&out.stdout).contains("baseline"));
    let j: serde_json::Value = serde_json::from_slice(&std::fs::read(&plain).unwrap()).unwrap();
    let o = &j["data"][0]["outputs"];
    assert!(o[0]["baseline_rms_nm"].is_null() && o[0]["samples"] == 400);

    // With it: the baseline column, its RMS about the noise, the other figures unchanged.
    let mut args = common(&report);
    args.extend(["--baseline-data".into(), base.clone().into()]);
    let out = evaluate(&args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("| RMS baseline |"), "{stdout}");
    let j2: serde_json::Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    for k in 0..JOINTS.len() {
        let (a, b) = (&j["data"][0]["outputs"][k], &j2["data"][0]["outputs"][k]);
        for key in ["rms_before", "rms_after", "reduction_pct"] {
            assert_eq!(a[key], b[key], "{key}");
        }
        let r = b["baseline_rms_nm"].as_f64().unwrap();
        assert!((0.04..0.07).contains(&r), "baseline RMS {r}");
        assert_eq!(b["samples"], 400);
    }
    assert_eq!(j2["baseline"]["fit"]["samples"], 7000);

    // A baseline dataset without `qd_j3`: non-zero exit, file and column named, no report.
    let bad = dir.path().join("bad_base.csv");
    let text = std::fs::read_to_string(&paths[0]).unwrap();
    let header = text.lines().next().unwrap();
    let k = header.split(',').position(|n| n == "qd_j3").unwrap();
    let cut: String = text
        .lines()
        .map(|l| {
            let mut f: Vec<&str> = l.split(',').collect();
            f.remove(k);
            f.join(",") + "\n"
        })
        .collect();
    std::fs::write(&bad, cut).unwrap();
    // A non-finite value in the other.
    let nan = dir.path().join("nan_base.csv");
    edit_column(&paths[1], &nan, "tau_meas_j1", |row, v| {
        if row == 5 { "NaN".into() } else { v.into() }
    });
    for (file, column, other) in [(&bad, "qd_j3", &paths[1]), (&nan, "tau_meas_j1", &paths[0])] {
        let rep = dir.path().join("refused.json");
        let mut args = common(&rep);
        args.extend([
            "--baseline-data".into(),
            format!("{},{}", other.display(), file.display()).into(),
        ]);
        let out = evaluate(&args);
        assert!(!out.status.success());
        let err = String::from_utf8_lossy(&out.stderr);
        let name = file.file_name().unwrap().to_string_lossy();
        assert!(
            err.contains(&*name) && err.contains(&format!("`{column}`")),
            "{err}"
        );
        assert!(!rep.exists());
    }
}

#[test]
fn evaluate_runs_the_drive_adaptation_and_scores_against_the_low_passed_torque() {
    let dir = tempfile::tempdir().unwrap();
    // A test run whose joint 1 carries a 2 N·m offset no training run has (friction
    // drift): the baseline misses it, the adaptation learns it from the measured torque.
    let (paths, model, test) = evaluation_files(dir.path(), 2000);
    edit_column(&test, &test, "tau_meas_j1", |_, v| {
        (v.parse::<f32>().unwrap() + 2.0).to_string()
    });
    let base = format!("{},{}", paths[0].display(), paths[1].display());
    let run = |report: &Path, extra: &[&str]| {
        let mut args = evaluation_args(&model, &test, report);
        args.extend(["--baseline-data".into(), base.clone().into()]);
        args.extend(extra.iter().map(OsString::from));
        evaluate(&args)
    };
    let report = dir.path().join("adapted.json");
    let out = run(&report, &["--adapt-time-constant-s", "0.5"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("adapted: baseline"));
    let j: serde_json::Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    assert_eq!(j["adaptation"]["time_constant_s"], 0.5);
    assert!(j["score_cutoff_hz"].is_null());
    let o = &j["data"][0]["outputs"];
    let (static_nm, adapted_nm) = (
        o[0]["baseline_rms_nm"].as_f64().unwrap(),
        o[0]["adapted"]["baseline_rms_nm"].as_f64().unwrap(),
    );
    assert!(
        static_nm > 1.9 && adapted_nm < 0.5,
        "{static_nm} -> {adapted_nm}"
    );
    // Joint 3 has no drift: the adaptation costs little there.
    let (s3, a3) = (
        o[1]["baseline_rms_nm"].as_f64().unwrap(),
        o[1]["adapted"]["baseline_rms_nm"].as_f64().unwrap(),
    );
    assert!(a3 < 1.5 * s3, "{s3} -> {a3}");

    // Scored against the torque low-passed at 5 Hz: the white sensor noise drops out.
    let low = dir.path().join("low.json");
    let out = run(&low, &["--score-cutoff-hz", "5"]);
    assert!(out.status.success());
    let l: serde_json::Value = serde_json::from_slice(&std::fs::read(&low).unwrap()).unwrap();
    assert_eq!(l["score_cutoff_hz"], 5.0);
    let raw = o[1]["rms_before"].as_f64().unwrap();
    let filtered = l["data"][0]["outputs"][1]["rms_before"].as_f64().unwrap();
    assert!(filtered < raw, "{raw} -> {filtered}");

    // A cut-off at or above Nyquist (50 Hz here), a zero time constant: refused, the
    // file named, nothing written.
    for (extra, words) in [
        (&["--score-cutoff-hz", "60"][..], ["test.csv", "Nyquist"]),
        (
            &["--adapt-time-constant-s", "0"][..],
            ["--adapt-time-constant-s", "positive"],
        ),
    ] {
        let refused = dir.path().join("refused.json");
        let out = run(&refused, extra);
        assert!(!out.status.success());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(words.iter().all(|w| err.contains(w)), "{err}");
        assert!(!refused.exists());
    }
}
