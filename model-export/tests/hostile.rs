//! Hostile command lines: an output that is one of the inputs is refused before anything
//! is read or written (the input stays as it was), and training sizes of 0 are errors,
//! not panics.
use clap::Parser;
use model_export::cli::{Cli, run};
use std::path::Path;

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
    let d = dir.path();
    let data = d.join("data.csv");
    let mut csv = String::from("time_s,q_j4,qd_j4,tau_meas_j4,tau_model_j4\n");
    for k in 0..400 {
        let t = k as f64 * 0.01;
        csv += &format!(
            "{t},{},{},{},{}\n",
            t.sin(),
            t.cos(),
            2.0 * t.sin(),
            1.9 * t.sin()
        );
    }
    std::fs::write(&data, csv).unwrap();
    let data = data.display().to_string();
    let out = d.join("m.safetensors").display().to_string();
    let plot = d.join("loss.svg").display().to_string();
    for (flag, value) in [
        ("--hidden", "0"),
        ("--embed", "0"),
        ("--window", "0"),
        ("--batch", "0"),
    ] {
        let args = [
            "train",
            "--data",
            &data,
            "--preset",
            "feedforward",
            "--joints",
            "4",
            "--epochs",
            "1",
            "--quiet",
            "--out",
            &out,
            "--loss-plot",
            &plot,
            flag,
            value,
        ];
        let e = format!("{:#}", cli(&args).expect_err(flag));
        assert!(
            e.contains(&format!("{flag} must be at least 1")),
            "{flag}: {e}"
        );
        assert!(!Path::new(&out).exists() && !Path::new(&plot).exists());
    }
}

#[test]
fn a_huge_finite_log_value_is_an_error_not_nan_rows() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A log in the `torque` layout of six joints (time, q, qd, tau) with one cell at 1e300.
    let mut csv = String::new();
    for k in 0..300 {
        let t = k as f64 * 0.01;
        let q = if k == 150 { 1e300 } else { 0.1 * t.sin() };
        let row: Vec<String> = std::iter::once(t)
            .chain([q; 6])
            .chain([0.1 * t.cos(); 6])
            .chain([1.0; 6])
            .map(|v| v.to_string())
            .collect();
        csv += &row.join(",");
        csv.push('\n');
    }
    let log = d.join("log.csv");
    std::fs::write(&log, csv).unwrap();
    let out = d.join("tau.csv");
    let (r, l, o) = (
        robot(),
        log.display().to_string(),
        out.display().to_string(),
    );
    let e = cli(&[
        "torque", "--robot", &r, "--layout", "torque", "--log", &l, "-o", &o,
    ]);
    let e = format!("{:#}", e.expect_err("a 1e300 position"));
    assert!(
        e.contains("log.csv") && e.contains("model torque of joint"),
        "{e}"
    );
    assert!(!out.exists(), "wrote {}", out.display());
}

#[test]
fn a_time_jump_in_one_row_is_an_error_not_a_huge_grid() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut csv = String::new();
    for k in 0..300 {
        // One row 1e7 s later (a clock jump): 1e9 samples at 100 Hz.
        let t = k as f64 * 0.01 + if k >= 200 { 1e7 } else { 0.0 };
        let row: Vec<String> = std::iter::once(t)
            .chain([0.1 * t.sin(); 6])
            .chain([0.0; 6])
            .chain([1.0; 6])
            .map(|v| v.to_string())
            .collect();
        csv += &row.join(",");
        csv.push('\n');
    }
    let log = d.join("jump.csv");
    std::fs::write(&log, csv).unwrap();
    let out = d.join("tau.csv");
    let (r, l, o) = (
        robot(),
        log.display().to_string(),
        out.display().to_string(),
    );
    let e = cli(&[
        "torque", "--robot", &r, "--layout", "torque", "--log", &l, "-o", &o,
    ]);
    let e = format!("{:#}", e.expect_err("a 1e7 s time jump"));
    assert!(
        e.contains("jump.csv") && e.contains("largest time step"),
        "{e}"
    );
    assert!(!out.exists());
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
    let d = dir.path();
    let data = d.join("data.csv");
    let mut csv = String::from("time_s,q_j4,qd_j4,tau_meas_j4,tau_model_j4\n");
    for k in 0..400 {
        let t = k as f64 * 0.01;
        csv += &format!(
            "{t},{},{},{},{}\n",
            t.sin(),
            t.cos(),
            2.0 * t.sin(),
            1.9 * t.sin()
        );
    }
    std::fs::write(&data, csv).unwrap();
    let (data, out, plot) = (
        data.display().to_string(),
        d.join("m.safetensors").display().to_string(),
        d.join("loss.svg").display().to_string(),
    );
    // The report cannot be written (its folder does not exist): nothing is.
    let report = d.join("missing/report.json").display().to_string();
    let args = [
        "train",
        "--data",
        &data,
        "--preset",
        "feedforward",
        "--joints",
        "4",
        "--epochs",
        "1",
        "--embed",
        "4",
        "--hidden",
        "4",
        "--window",
        "20",
        "--burn-in",
        "5",
        "--quiet",
        "--out",
        &out,
        "--loss-plot",
        &plot,
        "--report",
        &report,
    ];
    assert!(cli(&args).is_err());
    assert!(
        !Path::new(&out).exists() && !Path::new(&plot).exists(),
        "a partial output"
    );
    let report = d.join("report.json").display().to_string();
    let mut args = args.to_vec();
    *args.last_mut().unwrap() = &report;
    cli(&args).expect("trains");
    assert!(Path::new(&out).exists() && Path::new(&plot).exists() && Path::new(&report).exists());
}
