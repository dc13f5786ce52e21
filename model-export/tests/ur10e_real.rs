//! Real data: identify the UR10e from five Fourier runs of `ur10e/identification`,
//! predict five held-out runs and the five static poses of `ur10e/validation`.
//!
//! Data: `$DATASETS_DIR/ur10e` (default `<workspace>/../shared/datasets/ur10e`). Where
//! it is absent the test prints a skip line and passes.

use identify::model_file::ModelFile;
use std::process::Command;

/// Identification runs (no payload) and held-out runs (no payload).
const IDENTIFY: [&str; 5] = [
    "ur-20_02_12-50sec_12harm.csv",
    "ur-20_02_12-40sec_12harm.csv",
    "ur-20_02_19_14harm50sec.csv",
    "ur-20_02_06-20sec_10harm.csv",
    "ur-20_02_06-20sec_5harm.csv",
];
const HELD_OUT: [&str; 5] = [
    "ur-20_02_19_15harm50sec.csv",
    "ur-20_02_10-30sec_12harm.csv",
    "ur-20_02_05-20sec_12harm.csv",
    "ur-20_02_05-20sec_8harm.csv",
    "ur-20_02_10-20sec_7harm.csv",
];

#[test]
fn ur10e_identification_predicts_held_out_runs() {
    let Some(ur) = test_support::ur10e_dir("the UR10e command-line runs") else {
        return;
    };
    let out_dir = tempfile::tempdir().unwrap();
    let model = out_dir.path().join("ur10e-model.json");
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_model-export"));
    cmd.arg("identify")
        .arg("--robot")
        .arg(ur.join("ur10e.urdf"));
    for f in IDENTIFY {
        cmd.arg("--log").arg(ur.join("identification").join(f));
    }
    for f in HELD_OUT {
        cmd.arg("--validation-log")
            .arg(ur.join("identification").join(f));
    }
    for p in 1..=5 {
        cmd.arg("--validation-log")
            .arg(ur.join(format!("validation/ur-20_01_17-p{p}.csv")));
    }
    cmd.args(["--coulomb-smoothing-rad-s", "0.02", "-o"])
        .arg(&model);
    let out = cmd.output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    println!("{stdout}");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );

    let file = ModelFile::read(&model).unwrap();
    assert_eq!(
        file.base_parameters.len(),
        48,
        "36 rigid-body + 12 friction base parameters"
    );
    assert_eq!(file.identification_logs.len(), 5);
    assert_eq!(file.validation_logs.len(), 10);
    assert!(
        file.identification_logs
            .iter()
            .all(|l| l.sha256.len() == 64)
    );
    let get = |name: &str| file.errors.iter().find(|e| e.data == name).unwrap();
    let fit = get("identification: all");
    // Held-out dynamic runs: errors stay close to the fit's (no over-fitting), and far
    // below the torque scale (normalised RMS).
    for f in HELD_OUT {
        let e = file.errors.iter().find(|e| e.data.ends_with(f)).unwrap();
        for j in 0..6 {
            assert!(
                e.rms_nm[j] < 2.0 * fit.rms_nm[j],
                "{f} joint {}: {} vs fit {}",
                j + 1,
                e.rms_nm[j],
                fit.rms_nm[j]
            );
        }
        assert!(
            e.nrms_pct[1] < 10.0 && e.nrms_pct[2] < 15.0,
            "{f}: {:?}",
            e.nrms_pct
        );
    }
    // Gravity-loaded joints 2 and 3 at the static poses: a few N·m of torques of
    // tens of N·m.
    for p in 1..=5 {
        let e = file
            .errors
            .iter()
            .find(|e| e.data.ends_with(&format!("p{p}.csv")))
            .unwrap();
        assert!(
            e.rms_nm[1] < 8.0 && e.rms_nm[2] < 4.0,
            "p{p}: {:?}",
            e.rms_nm
        );
    }
}

/// The drive-side compensator of one joint (the first stage, its linear stage and a
/// per-joint LSTM that also reads the residual measured over the previous tick), trained
/// on the identification runs and judged on a whole held-out run: better than the
/// friction-feature least-squares baseline fitted on the same runs, and than the first
/// stage alone.
#[test]
fn ur10e_drive_compensator_beats_the_linear_baseline_on_a_held_out_run() {
    let Some(ur) = test_support::ur10e_dir("the UR10e command-line runs") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let me = |args: &[&std::ffi::OsStr]| {
        let out = Command::new(env!("CARGO_BIN_EXE_model-export"))
            .args(args)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    let os = |s: &str| std::ffi::OsString::from(s);
    let run = |f: &str| ur.join("identification").join(f);
    let model = dir.path().join("model.json");
    let mut args = vec![os("identify"), os("--robot"), ur.join("ur10e.urdf").into()];
    for f in IDENTIFY {
        args.extend([os("--log"), run(f).into()]);
    }
    args.extend(
        [
            "--coulomb-smoothing-rad-s",
            "0.02",
            "--friction",
            "extended",
            "-o",
        ]
        .map(os),
    );
    args.push(model.clone().into());
    me(&args.iter().map(|a| a.as_os_str()).collect::<Vec<_>>());
    // Datasets: training and validation runs whole, the test run with its rest trimmed.
    let dataset = |f: &str, trim: &str| {
        let out = dir.path().join(f);
        let a: Vec<std::ffi::OsString> = vec![
            os("torque"),
            os("--robot"),
            ur.join("ur10e.urdf").into(),
            os("--identified"),
            model.clone().into(),
            os("--layout"),
            os("ur10e"),
            os("--log"),
            run(f).into(),
            os("--dataset"),
            os("--trim-rest-rad-s"),
            os(trim),
            os("--torque-cutoff-hz"),
            os("0"),
            os("-o"),
            out.clone().into(),
        ];
        me(&a.iter().map(|a| a.as_os_str()).collect::<Vec<_>>());
        out.display().to_string()
    };
    let train: Vec<String> = IDENTIFY.iter().map(|f| dataset(f, "0")).collect();
    let train = train.join(",");
    let val = dataset(HELD_OUT[2], "0");
    let test = dataset(HELD_OUT[0], "0.01");
    let (net, report) = (
        dir.path().join("drive.safetensors"),
        dir.path().join("eval.json"),
    );
    let joint = "3";
    let net_s = net.display().to_string();
    let report_s = report.display().to_string();
    let train_args = [
        "train",
        "--data",
        &train,
        "--validation-data",
        &val,
        "--preset",
        "drive",
        "--joints",
        joint,
        "--embed",
        "16",
        "--hidden",
        "16",
        "--epochs",
        "20",
        "--lr",
        "0.003",
        "--seed",
        "1",
        "--quiet",
        "--out",
        &net_s,
    ];
    me(&train_args
        .map(os)
        .iter()
        .map(|a| a.as_os_str())
        .collect::<Vec<_>>());
    let eval_args = [
        "evaluate",
        "--network",
        &net_s,
        "--data",
        &test,
        "--preset",
        "drive",
        "--joints",
        joint,
        "--baseline-data",
        &train,
        "--report",
        &report_s,
    ];
    me(&eval_args
        .map(os)
        .iter()
        .map(|a| a.as_os_str())
        .collect::<Vec<_>>());
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let o = &r["data"][0]["outputs"][0];
    let (first_stage, baseline, drive) = (
        o["rms_before"].as_f64().unwrap(),
        o["baseline_rms_nm"].as_f64().unwrap(),
        o["rms_after"].as_f64().unwrap(),
    );
    println!(
        "joint {joint}, {}: first stage {first_stage:.3}, linear baseline {baseline:.3}, drive {drive:.3} N m",
        HELD_OUT[0]
    );
    assert!(drive < baseline && drive < first_stage, "{o}");
}
