//! The friction-feature least-squares baseline through `model-export evaluate
//! --baseline-data`, and the drive's online adaptation in `evaluate` (the fit itself:
//! `crates/compnet/tests/baseline.rs`).
use compnet::data::FeatureSpec;
use compnet::{LstmModel, io};
use firmware::nn::reference::LstmDims;
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::Command;

#[path = "../../crates/compnet/tests/support/friction_data.rs"]
mod friction_data;
use friction_data::{JOINTS, datasets, write_dataset};

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
        "--network".into(),
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
