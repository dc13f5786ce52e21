//! The do-no-harm proof on the real UR10e logs, a fast representative subset of the
//! study (`scripts/ur10e_compensation.sh`, `proof.md`): the first stage identified on
//! three runs without payload, the drive compensator of joint 6 (a small network, a few
//! epochs, seeded) trained on them, then run as deployed (envelope and the monitor of
//! `JointProfile::DRIVE_MONITOR`; with and without the online adaptation) on one run of
//! each regime: a held-out run trimmed of its rest (`heldout`), the same run whole and a
//! static pose (`held`), a payload run (`payload`). On all rows, moving rows and held
//! rows it is never worse than the model alone by more than 2 % RMS, and where it moves
//! not worse than the adapted linear baseline by more than 2 %, adapted. Skips with one
//! line when the data is absent.
use compnet::report::EvaluationReport;
use firmware::control::JointProfile;
use model_export::cli::run_args as cli;
use std::path::Path;

const BAR: f64 = 1.02;

fn s(p: &Path) -> String {
    p.display().to_string()
}

#[test]
fn the_deployed_drive_compensator_does_no_harm_on_the_ur10e_logs() {
    let Some(d) =
        test_support::ur10e_dir("the_deployed_drive_compensator_does_no_harm_on_the_ur10e_logs")
    else {
        return;
    };
    let id = d.join("identification");
    let run = |name: &str| id.join(format!("ur-{name}.csv"));
    let tmp = tempfile::tempdir().unwrap();
    let out = |name: &str| tmp.path().join(name);
    let urdf = s(&d.join("ur10e.urdf"));
    let train = [
        "20_02_12-50sec_12harm",
        "20_02_12-40sec_12harm",
        "20_02_19_14harm50sec",
    ];
    let mut args = vec!["identify", "--robot", &urdf, "--layout", "ur10e"];
    let logs: Vec<String> = train.iter().map(|r| s(&run(r))).collect();
    for l in &logs {
        args.extend(["--log", l]);
    }
    let model = s(&out("model.json"));
    args.extend([
        "--coulomb-smoothing-rad-s",
        "0.02",
        "--friction",
        "extended",
        "-o",
        &model,
    ]);
    cli(&args).unwrap();
    let dataset = |log: &Path, name: &str, trim: &str| {
        let o = s(&out(&format!("{name}.csv")));
        cli(&[
            "torque",
            "--robot",
            &urdf,
            "--identified",
            &model,
            "--layout",
            "ur10e",
            "--log",
            &s(log),
            "--dataset",
            "--trim-rest-rad-s",
            trim,
            "--torque-cutoff-hz",
            "0",
            "-o",
            &o,
        ])
        .unwrap();
        o
    };
    let train_data: Vec<String> = train.iter().map(|r| dataset(&run(r), r, "0")).collect();
    let train_list = train_data.join(",");
    let val = dataset(&run("20_02_05-20sec_12harm"), "val", "0");
    let network = s(&out("drive_j6.safetensors"));
    let loss = s(&out("loss.svg"));
    cli(&[
        "train",
        "--data",
        &train_list,
        "--validation-data",
        &val,
        "--preset",
        "drive",
        "--joints",
        "6",
        "--embed",
        "8",
        "--hidden",
        "8",
        "--epochs",
        "4",
        "--lr",
        "0.003",
        "--seed",
        "1",
        "--quiet",
        "--adapt-time-constant-s",
        "2",
        "--adapt-max-nm",
        "10",
        "--out",
        &network,
        "--loss-plot",
        &loss,
    ])
    .unwrap();
    let m = JointProfile::DRIVE_MONITOR;
    let (window, fade, hysteresis) = (
        m.window_s.to_string(),
        m.fade_s.to_string(),
        m.hysteresis.to_string(),
    );
    let cases = [
        (
            "heldout",
            dataset(&run("20_02_19_15harm50sec"), "test", "0.01"),
        ),
        (
            "held",
            dataset(&run("20_02_19_15harm50sec"), "test_whole", "0"),
        ),
        (
            "held",
            dataset(&d.join("validation/ur-20_01_17-p2.csv"), "pose", "0.01"),
        ),
        (
            "payload",
            dataset(&run("20_02_19_14harm50secLoad"), "payload", "0.01"),
        ),
    ];
    let mut failures = Vec::new();
    for (regime, data) in &cases {
        let report = s(&out("eval.json"));
        cli(&[
            "evaluate",
            "--network",
            &network,
            "--data",
            data,
            "--preset",
            "drive",
            "--joints",
            "6",
            "--baseline-data",
            &train_list,
            "--adapt-time-constant-s",
            "2",
            "--adapt-max-nm",
            "10",
            "--monitor-window-s",
            &window,
            "--monitor-fade-s",
            &fade,
            "--monitor-hysteresis",
            &hysteresis,
            "--report",
            &report,
        ])
        .unwrap();
        let r: EvaluationReport =
            serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
        let d = r.data[0].outputs[0].deployed.expect("deployed figures");
        for (rows, f) in [("all", Some(d.all)), ("moving", d.moving), ("held", d.held)] {
            let Some(f) = f else { continue };
            let adapted = f.adapted_deployed_rms_nm.unwrap();
            let mut checks = vec![
                ("deployed / model", f.deployed_rms_nm / f.model_rms_nm),
                ("adapted / model", adapted / f.model_rms_nm),
            ];
            if rows == "moving" {
                checks.push((
                    "adapted / adapted baseline",
                    adapted / f.adapted_baseline_rms_nm.unwrap(),
                ));
            }
            for (what, ratio) in checks {
                println!(
                    "{regime} {data} {rows} ({} rows): {what} {ratio:.3}",
                    f.rows
                );
                if ratio > BAR {
                    failures.push(format!("{regime} {data} {rows}: {what} {ratio:.3}"));
                }
            }
        }
    }
    assert!(failures.is_empty(), "above the {BAR} bar: {failures:#?}");
}
