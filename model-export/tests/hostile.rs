//! Hostile command lines: an output that is one of the inputs is refused before anything
//! is read or written (the input stays as it was), and training sizes of 0 are errors,
//! not panics.
use model_export::cli::run_args as cli;
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

fn robot() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../robots/default.toml")
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
            "evaluate",
            "--network",
            &model,
            "--data",
            &data,
            "--report",
            &model,
        ],
        &model,
    );
    refused(&["export", "--network", &model, "--out", &model], &model);
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
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots/planar_2r.toml"),
    )
    .unwrap()
    // Both joints' limits above pi: no range inside ±pi to sample.
    .replacen("q_min = -3.0\nq_max = 3.0", "q_min = 3.3\nq_max = 3.6", 1)
    .replacen("q_min = -2.6\nq_max = 2.6", "q_min = 3.5\nq_max = 4.0", 1);
    assert!(text.contains("q_min = 3.3") && text.contains("q_min = 3.5"));
    let path = dir.path().join("r.toml");
    std::fs::write(&path, text).unwrap();
    let robot = robot::Robot::load(&path).unwrap();
    let base = robot::base::BaseParameters::compute(&robot, 1);
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

/// A Fourier trajectory file (two joints, two harmonics) in `dir` with `period_s` and the
/// last sine coefficient of joint 1 set to `coefficient`.
fn fourier_file(dir: &Path, period_s: &str, coefficient: &str) -> String {
    let p = dir.join("exc.json");
    std::fs::write(
        &p,
        format!(
            r#"{{"period_s": {period_s}, "harmonics": 2, "joints": [
  {{"q0_rad": 0.1, "a_rad": [0.2, {coefficient}], "b_rad": [0.05, 0.3]}},
  {{"q0_rad": -0.2, "a_rad": [0.0, 0.4], "b_rad": [-0.1, 0.0]}}]}}"#
        ),
    )
    .unwrap();
    p.display().to_string()
}

/// `simulate` of the Fourier file `exc` on joints 4 and 5: the error, and whether the
/// log was written.
fn simulate_fourier(dir: &Path, exc: &str) -> (String, bool) {
    let out = dir.join("log.csv");
    let o = out.display().to_string();
    let e = cli(&["simulate", "--trajectory", exc, "--joints", "4,5", "-o", &o])
        .expect_err("a hostile trajectory");
    (format!("{e:#}"), out.exists())
}

#[test]
fn a_fourier_period_of_1e308_is_an_error_naming_the_file_and_limit() {
    let dir = tempfile::tempdir().unwrap();
    let exc = fourier_file(dir.path(), "1e308", "-0.1");
    let (e, wrote) = simulate_fourier(dir.path(), &exc);
    assert!(
        e.contains("exc.json") && e.contains("logged samples"),
        "{e}"
    );
    assert!(!wrote);
}

#[test]
fn an_excitation_coefficient_of_3e307_is_an_error_not_nan_rows() {
    // Finite, but w^2 * 3e307 overflows the acceleration.
    let dir = tempfile::tempdir().unwrap();
    let exc = fourier_file(dir.path(), "4.0", "3e307");
    let (e, wrote) = simulate_fourier(dir.path(), &exc);
    assert!(
        e.contains("exc.json") && e.contains("joint 1") && e.contains("above the limit"),
        "{e}"
    );
    assert!(!wrote);
}

#[test]
fn huge_network_sizes_are_errors_naming_the_limit() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("m.rs");
    let o = out.display().to_string();
    let e = format!(
        "{:#}",
        cli(&["export", "--dims", "9,1000000000,64,3", "--out", &o]).expect_err("huge --dims")
    );
    assert!(e.contains("MAX_LAYER_WIDTH"), "{e}");
    assert!(!out.exists());
    let (base, model, plot) = train_args(dir.path());
    for flag in ["--hidden", "--embed"] {
        let mut args: Vec<&str> = base.iter().map(String::as_str).collect();
        args.extend([flag, "1000000000"]);
        let e = format!("{:#}", cli(&args).expect_err(flag));
        assert!(e.contains(flag) && e.contains("MAX_LAYER_WIDTH"), "{e}");
        assert!(!model.exists() && !plot.exists());
    }
}

#[test]
fn sil_seconds_of_1e308_is_an_error_naming_the_range() {
    let e = format!(
        "{:#}",
        cli(&["sil", "--seconds", "1e308"]).expect_err("1e308 s")
    );
    assert!(e.contains("--seconds must be in (0, 600]"), "{e}");
}

#[test]
fn sil_adaptation_without_a_wrist_model_is_an_error() {
    let e = format!(
        "{:#}",
        cli(&["sil", "--adapt-time-constant-s", "2"]).expect_err("no --identified")
    );
    assert!(
        e.contains("--adapt-time-constant-s") && e.contains("--identified"),
        "{e}"
    );
}

#[test]
fn a_resample_rate_of_1e12_is_an_error_naming_the_limit() {
    let dir = tempfile::tempdir().unwrap();
    let mut csv = String::new();
    for k in 0..300 {
        let t = k as f64 * 0.01;
        let cells: Vec<String> = std::iter::once(t)
            .chain([0.1 * t.sin(); 6])
            .chain([0.1 * t.cos(); 6])
            .chain([1.0; 6])
            .map(|v| v.to_string())
            .collect();
        csv += &cells.join(",");
        csv.push('\n');
    }
    let log = dir.path().join("run.csv");
    std::fs::write(&log, csv).unwrap();
    let out = dir.path().join("tau.csv");
    let (r, l, o) = (
        robot(),
        log.display().to_string(),
        out.display().to_string(),
    );
    let e = format!(
        "{:#}",
        cli(&[
            "torque",
            "--robot",
            &r,
            "--layout",
            "torque",
            "--log",
            &l,
            "--resample-hz",
            "1e12",
            "-o",
            &o,
        ])
        .expect_err("1e12 Hz")
    );
    assert!(
        e.contains("run.csv") && e.contains("samples on the uniform grid"),
        "{e}"
    );
    assert!(!out.exists());
}

#[test]
fn joint_limits_that_are_equal_are_an_error_naming_line_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots/planar_2r.toml"),
    )
    .unwrap()
    // Joint 1 with lower = upper: an empty range (base-parameter sampling once panicked).
    .replacen("q_min = -3.0\nq_max = 3.0", "q_min = 1.0\nq_max = 1.0", 1);
    assert!(text.contains("q_min = 1.0\nq_max = 1.0"));
    let path = dir.path().join("r.toml");
    std::fs::write(&path, text).unwrap();
    let e = robot::Robot::load(&path).expect_err("lower = upper");
    assert_eq!(
        (e.line, e.field.as_str()),
        (Some(23), "joint[0].q_max"),
        "{e}"
    );
}

/// An identified model of the default robot's wrist from one simulated period in `dir`:
/// the log and the model file, and the arguments that read the log.
fn identified_wrist(dir: &Path) -> (String, String, Vec<String>) {
    let d = |name: &str| dir.join(name).display().to_string();
    let (r, log, model) = (robot(), d("log.csv"), d("model.json"));
    cli(&[
        "simulate",
        "--seeded-trajectory",
        "1",
        "--joints",
        "4,5,6",
        "--periods",
        "1",
        "-o",
        &log,
    ])
    .unwrap();
    let reader = plant_sim::log::SimulatedLog::reader_args(6);
    let mut args = vec![
        "identify",
        "--robot",
        &r,
        "--log",
        &log,
        "--lock",
        "1=0,2=0,3=0",
        "-o",
        &model,
    ];
    args.extend(reader.iter().map(String::as_str));
    cli(&args).unwrap();
    (log, model, reader)
}

#[test]
fn a_3e38_base_parameter_is_an_error_naming_the_field_and_limit() {
    let dir = tempfile::tempdir().unwrap();
    let (log, model, reader) = identified_wrist(dir.path());
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    // Finite, and even an f32; the torques it scales are not.
    v["base_parameters"][0]["value"] = serde_json::json!(3e38);
    std::fs::write(&model, v.to_string()).unwrap();
    let d = |name: &str| dir.path().join(name).display().to_string();
    let (r, tau, code) = (robot(), d("tau.csv"), d("m.rs"));
    let mut torque = vec![
        "torque",
        "--robot",
        &r,
        "--identified",
        &model,
        "--log",
        &log,
    ];
    torque.extend(reader.iter().map(String::as_str));
    torque.extend(["-o", &tau]);
    let export = [
        "export",
        "--robot",
        &r,
        "--identified",
        &model,
        "--out",
        &code,
    ];
    for args in [&torque[..], &export[..]] {
        let e = format!("{:#}", cli(args).expect_err("a 3e38 base parameter"));
        assert!(
            e.contains("model.json")
                && e.contains("base_parameters[0].value")
                && e.contains("MAX_ABS_BASE_PARAMETER"),
            "{args:?}: {e}"
        );
    }
    assert!(!Path::new(&tau).exists() && !Path::new(&code).exists());
}

/// Existing files at `paths` with known bytes; returns a check that they are unchanged.
fn keep(paths: &[&Path]) -> impl Fn() + use<> {
    for p in paths {
        std::fs::write(p, format!("previous {}\n", p.display())).unwrap();
    }
    let paths: Vec<std::path::PathBuf> = paths.iter().map(|p| p.to_path_buf()).collect();
    move || {
        for p in &paths {
            assert_eq!(
                std::fs::read_to_string(p).unwrap(),
                format!("previous {}\n", p.display()),
                "a failed run changed {}",
                p.display()
            );
        }
    }
}

/// Runs `args(bad)`, which must fail with an error containing `expect` and leave the
/// outputs as they were (`unchanged`), then `args(ok)`, which must succeed.
fn refused_then_written<const N: usize>(
    args: impl Fn(&str) -> [String; N],
    (bad, expect): (&str, &str),
    unchanged: impl Fn(),
    ok: &str,
) {
    let e = format!(
        "{:#}",
        cli(&args(bad).each_ref().map(String::as_str)).unwrap_err()
    );
    assert!(e.contains(expect), "{e}");
    unchanged();
    cli(&args(ok).each_ref().map(String::as_str)).unwrap();
}

/// A one-epoch feedforward network of joint 4 trained on [`feedforward_data`] in `dir`.
fn small_network(dir: &Path) -> (String, String) {
    let (base, out, _) = train_args(dir);
    let mut args: Vec<&str> = base.iter().map(String::as_str).collect();
    args.extend([
        "--embed",
        "4",
        "--hidden",
        "4",
        "--window",
        "20",
        "--burn-in",
        "5",
    ]);
    cli(&args).unwrap();
    (
        out.display().to_string(),
        dir.join("data.csv").display().to_string(),
    )
}

#[test]
fn evaluate_writes_its_figures_and_report_all_or_none() {
    let dir = tempfile::tempdir().unwrap();
    let (model, data) = small_network(dir.path());
    let figs = dir.path().join("figs");
    std::fs::create_dir(&figs).unwrap();
    let (before, after) = (figs.join("fig12_before.svg"), figs.join("fig13_after.svg"));
    let unchanged = keep(&[&before, &after]);
    // The report, written last, cannot be written (a folder is in its place).
    let report = dir.path().join("report.json");
    std::fs::create_dir(&report).unwrap();
    let (f, r) = (figs.display().to_string(), report.display().to_string());
    let args = |r: &str| {
        [
            "evaluate",
            "--network",
            &model,
            "--data",
            &data,
            "--preset",
            "feedforward",
            "--joints",
            "4",
            "--figures",
            &f,
            "--report",
            r,
        ]
        .map(str::to_string)
    };
    let report = dir.path().join("ok.json").display().to_string();
    refused_then_written(args, (&r, "not a regular file"), unchanged, &report);
    assert!(std::fs::read_to_string(&after).unwrap().contains("<svg"));
    assert!(
        std::fs::read_to_string(&report)
            .unwrap()
            .contains("rms_after")
    );
}

#[test]
fn export_writes_its_source_and_accuracy_all_or_none() {
    let dir = tempfile::tempdir().unwrap();
    let (model, data) = small_network(dir.path());
    let (out, json) = (dir.path().join("m.rs"), dir.path().join("acc.json"));
    let unchanged = keep(&[&out, &json]);
    let (o, j) = (out.display().to_string(), json.display().to_string());
    let args = |log: &str| {
        [
            "export",
            "--network",
            &model,
            "--preset",
            "feedforward",
            "--joints",
            "4",
            "--allow-worse",
            "--out",
            &o,
            "--accuracy-log",
            log,
            "--report",
            &j,
        ]
        .map(str::to_string)
    };
    // The accuracy log, read after the network is quantised, is broken.
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, "time_s,q_j4\n0,x\n").unwrap();
    let b = bad.display().to_string();
    refused_then_written(args, (&b, "bad.csv"), unchanged, &data);
    assert!(std::fs::read_to_string(&out).unwrap().contains("SCHEMA"));
    assert!(
        std::fs::read_to_string(&json)
            .unwrap()
            .contains("rms_vs_f32")
    );
}

#[test]
fn excite_writes_its_coefficients_playback_and_plot_all_or_none() {
    let dir = tempfile::tempdir().unwrap();
    let (json, csv) = (dir.path().join("e.json"), dir.path().join("e.csv"));
    let unchanged = keep(&[&json, &csv]);
    // The plot, staged last, cannot be written (a folder is in its place).
    std::fs::create_dir(dir.path().join("e.svg")).unwrap();
    let r = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../robots/planar_2r.toml")
        .display()
        .to_string();
    let d = dir.path().display().to_string();
    let args = [
        "excite",
        "--robot",
        &r,
        "--joints",
        "all",
        "--harmonics",
        "2",
        "--restarts",
        "1",
        "--evaluations",
        "40",
        "--baseline",
        "0",
        "--samples",
        "50",
        "--out",
        &d,
        "--name",
        "e",
    ];
    let e = format!("{:#}", cli(&args).unwrap_err());
    assert!(
        e.contains("e.svg") && e.contains("not a regular file"),
        "{e}"
    );
    unchanged();
    std::fs::remove_dir(dir.path().join("e.svg")).unwrap();
    cli(&args).unwrap();
    assert!(std::fs::read_to_string(&csv).unwrap().lines().count() > 100);
    assert!(dir.path().join("e.svg").is_file());
}

#[test]
fn sil_writes_its_markdown_and_json_all_or_none() {
    let dir = tempfile::tempdir().unwrap();
    let (_, model, _) = identified_wrist(dir.path());
    let (md, json) = (dir.path().join("sil.md"), dir.path().join("sil.json"));
    let unchanged = keep(&[&md]);
    std::fs::create_dir(&json).unwrap();
    let (r, m, j) = (
        robot(),
        md.display().to_string(),
        json.display().to_string(),
    );
    let args = |j: &str| {
        [
            "sil",
            "--robot",
            &r,
            "--identified",
            &model,
            "--seconds",
            "0.05",
            "--report-md",
            &m,
            "--report",
            j,
        ]
        .map(str::to_string)
    };
    let ok = dir.path().join("ok.json").display().to_string();
    refused_then_written(args, (&j, "not a regular file"), unchanged, &ok);
    assert!(
        std::fs::read_to_string(&md)
            .unwrap()
            .contains("| feedforward |")
    );
    assert!(
        std::fs::read_to_string(&ok)
            .unwrap()
            .contains("rms_error_rad")
    );
}

#[cfg(unix)]
#[test]
fn outputs_honour_the_umask_of_the_process() {
    // `import` under umask 027: its output is 0666 less the umask, 0640.
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.safetensors");
    let torch =
        test_support::workspace_root().join("crates/compnet/tests/fixtures/torch_lstm.safetensors");
    let st = std::process::Command::new("sh")
        .args([
            "-c",
            "umask 027 && exec \"$0\" import --network \"$1\" --out \"$2\"",
        ])
        .arg(env!("CARGO_BIN_EXE_model-export"))
        .arg(&torch)
        .arg(&out)
        .status()
        .unwrap();
    assert!(st.success());
    let mode = std::fs::metadata(&out).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o640, "{mode:o}");
}

#[test]
fn a_long_gap_between_two_log_rows_is_an_error_not_an_interpolated_log() {
    // Found by the long fuzz run: one row 65535 s later was interpolated into 6.5 M
    // grid samples (seconds of work, 0.5 GB). Here one row 100 s later: 10 000 steps.
    let (e, wrote) = torque_on_log("gap.csv", |k| {
        let t = k as f64 * 0.01 + if k >= 200 { 100.0 } else { 0.0 };
        (t, 0.1 * t.sin())
    });
    assert!(
        e.contains("gap.csv") && e.contains("a gap of") && e.contains("sample 200"),
        "{e}"
    );
    assert!(!wrote);
}
