//! Hostile command lines: an output that is one of the inputs is refused before anything
//! is read or written (the input stays as it was), and training sizes of 0 are errors,
//! not panics.
use clap::Parser;
use model_export::cli::{Cli, run};
use std::path::Path;

/// A small `feedforward` dataset of joint 4 in `dir`; returns its path.
fn feedforward_data(dir: &Path) -> std::path::PathBuf {
    let data = dir.join("data.csv");
    let mut csv = String::from("time_s,q_j4,qd_j4,tau_meas_j4,tau_model_j4\n");
    for k in 0..400 {
        let t = k as f64 * 0.01;
        let (s, c) = t.sin_cos();
        csv += &format!("{t},{s},{c},{},{}\n", 2.0 * s, 1.9 * s);
    }
    std::fs::write(&data, csv).unwrap();
    data
}

/// `train` of one epoch on [`feedforward_data`] in `dir`: the arguments, and the model and
/// loss-plot paths they name.
fn train_args(dir: &Path) -> (Vec<String>, std::path::PathBuf, std::path::PathBuf) {
    let (out, plot) = (dir.join("m.safetensors"), dir.join("loss.svg"));
    let data = feedforward_data(dir);
    let args = [
        "train",
        "--data",
        &data.display().to_string(),
        "--preset",
        "feedforward",
        "--joints",
        "4",
        "--epochs",
        "1",
        "--quiet",
        "--out",
        &out.display().to_string(),
        "--loss-plot",
        &plot.display().to_string(),
    ]
    .map(String::from)
    .to_vec();
    (args, out, plot)
}

fn cli(args: &[&str]) -> anyhow::Result<()> {
    let mut v = vec!["model-export"];
    v.extend_from_slice(args);
    run(Cli::try_parse_from(v)?)
}

fn robot() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("robots/default.toml")
        .display()
        .to_string()
}

/// A file with known bytes; returns its path.
fn file(dir: &Path, name: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, format!("contents of {name}\n")).unwrap();
    p.display().to_string()
}

fn refused(args: &[&str], victim: &str) {
    let before = std::fs::read(victim).unwrap();
    let e = format!("{:#}", cli(args).expect_err("an output equal to an input"));
    assert!(e.contains("refusing to replace an input"), "{args:?}: {e}");
    assert_eq!(
        std::fs::read(victim).unwrap(),
        before,
        "{args:?} changed {victim}"
    );
}

#[test]
fn an_output_that_is_an_input_is_refused_and_the_input_kept() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let log = file(d, "run.csv");
    let data = file(d, "data.csv");
    let model = file(d, "model.safetensors");
    let r = robot();
    refused(
        &["identify", "--robot", &r, "--log", &log, "-o", &log],
        &log,
    );
    refused(&["torque", "--robot", &r, "--log", &log, "-o", &log], &log);
    // The same file through another spelling of its path.
    let other = format!("{}/./data.csv", d.display());
    refused(&["train", "--data", &data, "--out", &other], &data);
    refused(
        &[
            "train",
            "--data",
            &data,
            "--loss-plot",
            &data,
            "--out",
            &model,
        ],
        &data,
    );
    refused(
        &[
            "evaluate", "--model", &model, "--data", &data, "--report", &model,
        ],
        &model,
    );
    refused(&["export", "--model", &model, "--out", &model], &model);
}

#[test]
fn two_outputs_that_are_one_file_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let data = file(d, "data.csv");
    let out = file(d, "out.bin");
    let e = format!(
        "{:#}",
        cli(&["train", "--data", &data, "--out", &out, "--loss-plot", &out]).unwrap_err()
    );
    assert!(e.contains("are the same file"), "{e}");
}

#[test]
fn training_sizes_of_zero_are_errors_naming_the_option() {
    let dir = tempfile::tempdir().unwrap();
    let (base, out, plot) = train_args(dir.path());
    for (flag, value) in [
        ("--hidden", "0"),
        ("--embed", "0"),
        ("--window", "0"),
        ("--batch", "0"),
    ] {
        let mut args: Vec<&str> = base.iter().map(String::as_str).collect();
        args.extend([flag, value]);
        let e = format!("{:#}", cli(&args).expect_err(flag));
        assert!(
            e.contains(&format!("{flag} must be at least 1")),
            "{flag}: {e}"
        );
        assert!(!out.exists() && !plot.exists());
    }
}

/// A six-joint log in the `torque` layout (time, q, qd, tau), row `k` giving `(t, q)`;
/// runs `torque` on it and returns the error and whether an output was written.
fn torque_on_log(name: &str, row: impl Fn(usize) -> (f64, f64)) -> (String, bool) {
    let dir = tempfile::tempdir().unwrap();
    let mut csv = String::new();
    for k in 0..300 {
        let (t, q) = row(k);
        let cells: Vec<String> = std::iter::once(t)
            .chain([q; 6])
            .chain([0.1 * t.cos(); 6])
            .chain([1.0; 6])
            .map(|v| v.to_string())
            .collect();
        csv += &cells.join(",");
        csv.push('\n');
    }
    let log = dir.path().join(name);
    std::fs::write(&log, csv).unwrap();
    let out = dir.path().join("tau.csv");
    let (r, l, o) = (
        robot(),
        log.display().to_string(),
        out.display().to_string(),
    );
    let e = cli(&[
        "torque", "--robot", &r, "--layout", "torque", "--log", &l, "-o", &o,
    ])
    .expect_err("a hostile log");
    (format!("{e:#}"), out.exists())
}

#[test]
fn a_huge_finite_log_value_is_an_error_not_nan_rows() {
    // One position cell at 1e300.
    let (e, wrote) = torque_on_log("log.csv", |k| {
        let t = k as f64 * 0.01;
        (t, if k == 150 { 1e300 } else { 0.1 * t.sin() })
    });
    assert!(
        e.contains("log.csv") && e.contains("model torque of joint"),
        "{e}"
    );
    assert!(!wrote);
}

#[test]
fn a_time_jump_in_one_row_is_an_error_not_a_huge_grid() {
    // One row 1e7 s later (a clock jump): 1e9 samples at 100 Hz.
    let (e, wrote) = torque_on_log("jump.csv", |k| {
        let t = k as f64 * 0.01 + if k >= 200 { 1e7 } else { 0.0 };
        (t, 0.1 * t.sin())
    });
    assert!(
        e.contains("jump.csv") && e.contains("largest time step"),
        "{e}"
    );
    assert!(!wrote);
}

#[test]
fn joint_limits_above_pi_do_not_panic_the_base_parameters() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("robots/planar_2r.toml"),
    )
    .unwrap()
    // Both joints' limits above pi: no range inside ±pi to sample.
    .replacen("q_min = -3.0\nq_max = 3.0", "q_min = 3.3\nq_max = 3.6", 1)
    .replacen("q_min = -2.6\nq_max = 2.6", "q_min = 3.5\nq_max = 4.0", 1);
    assert!(text.contains("q_min = 3.3") && text.contains("q_min = 3.5"));
    let path = dir.path().join("r.toml");
    std::fs::write(&path, text).unwrap();
    let robot = model_export::robot::Robot::load(&path).unwrap();
    let base = model_export::base::BaseParameters::compute(&robot, 1);
    assert!(base.is_ok(), "{:?}", base.err());
}

#[test]
fn a_simulation_longer_than_the_log_limit_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("log.csv").display().to_string();
    let args = [
        "simulate",
        "--seeded-trajectory",
        "1",
        "--joints",
        "4,5,6",
        "--periods",
        "1000000000",
        "-o",
        &out,
    ];
    let e = format!("{:#}", cli(&args).expect_err("1e9 periods"));
    assert!(e.contains("logged samples"), "{e}");
    assert!(!Path::new(&out).exists());
}

#[test]
fn train_writes_its_model_plot_and_report_all_or_none() {
    let dir = tempfile::tempdir().unwrap();
    let (base, out, plot) = train_args(dir.path());
    let small = [
        "--embed",
        "4",
        "--hidden",
        "4",
        "--window",
        "20",
        "--burn-in",
        "5",
    ];
    let run = |report: &Path| {
        let report = report.display().to_string();
        let mut args: Vec<&str> = base.iter().map(String::as_str).collect();
        args.extend(small);
        args.extend(["--report", report.as_str()]);
        cli(&args)
    };
    // The report cannot be written (its folder does not exist): nothing is.
    assert!(run(&dir.path().join("missing/report.json")).is_err());
    assert!(!out.exists() && !plot.exists(), "a partial output");
    let report = dir.path().join("report.json");
    run(&report).expect("trains");
    assert!(out.exists() && plot.exists() && report.exists());
}
