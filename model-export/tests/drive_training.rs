//! `train --preset drive` with held-out validation runs: the linear stage is the built-in
//! linear baseline (fitted on the whole training runs), and the network's do-no-harm gain
//! judged on held-out runs (`--gain-folds`) fades a network that cannot help.
use compnet::{baseline, data::Table, io};
use firmware::features::{self, DRIVE_COLUMNS, MotionMemory};
use model_export::cli::run_args as cli;
use std::path::{Path, PathBuf};

/// A `drive` dataset of joint 1: a sine of `amplitude_rad` at `rate_rad_s` from phase
/// `phase_rad`, measured torque = model torque + viscous and Coulomb friction + white
/// noise (seeded), which no network can predict.
fn drive_run(path: &Path, amplitude_rad: f64, rate_rad_s: f64, phase_rad: f64, seed: u64) {
    let mut head = String::from("time_s,q_j1,qd_j1,tau_meas_j1,tau_model_j1,qdd_j1");
    for c in [0, 1, 5, 6, 7, 8, 9] {
        head += &format!(",{}_j1", DRIVE_COLUMNS[c]);
    }
    let mut csv = head + "\n";
    let mut state = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
    let mut noise = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let mut memory = MotionMemory::new();
    for k in 0..1500 {
        let t = k as f64 * 0.01;
        let q = amplitude_rad * (rate_rad_s * t + phase_rad).sin();
        let qd = amplitude_rad * rate_rad_s * (rate_rad_s * t + phase_rad).cos();
        let qdd = -rate_rad_s * rate_rad_s * q;
        let model = 3.0 * q.cos() + 0.5 * qdd;
        let meas = model + 0.4 * (qd / 0.05).tanh() + 0.8 * qd + 2.0 * noise();
        let x = features::drive_inputs(
            q as f32,
            qd as f32,
            0.0,
            0.0,
            memory.update(q as f32, qd as f32),
            0.0,
        );
        csv += &format!("{t},{q},{qd},{meas},{model},{qdd}");
        for c in [0, 1, 5, 6, 7, 8, 9] {
            csv += &format!(",{}", x[c]);
        }
        csv += "\n";
    }
    std::fs::write(path, csv).unwrap();
}

/// `n` drive datasets of joint 1 in `dir`: the same amplitude and rate from other phases,
/// with fresh noise. (Runs of growing amplitude would make each held-out run an
/// extrapolation of the linear stage, whose error the measured residual input predicts:
/// the network could then help.)
fn drive_runs(dir: &Path, n: usize) -> Vec<PathBuf> {
    (0..n)
        .map(|k| {
            let r = dir.join(format!("run{k}.csv"));
            drive_run(&r, 0.8, 1.5, 0.7 * k as f64, k as u64 + 1);
            r
        })
        .collect()
}

fn path(p: &Path) -> String {
    p.display().to_string()
}

#[test]
fn the_linear_stage_is_the_baseline_and_a_network_that_cannot_help_fades() {
    let dir = tempfile::tempdir().unwrap();
    let runs = drive_runs(dir.path(), 4);
    let (train, val) = (&runs[..3], &runs[3]);
    let train_list = train.iter().map(|p| path(p)).collect::<Vec<_>>().join(",");
    let (net, report) = (
        dir.path().join("drive.safetensors"),
        dir.path().join("train.json"),
    );
    cli(&[
        "train",
        "--data",
        &train_list,
        "--validation-data",
        &path(val),
        "--preset",
        "drive",
        "--joints",
        "1",
        "--epochs",
        "3",
        "--window",
        "50",
        "--burn-in",
        "10",
        "--embed",
        "4",
        "--hidden",
        "4",
        "--lr",
        "0.01",
        "--gain-folds",
        "3",
        "--quiet",
        "--out",
        &path(&net),
        "--loss-plot",
        &path(&dir.path().join("loss.svg")),
        "--report",
        &path(&report),
    ])
    .expect("trains");
    // The linear stage and the baseline are fitted on the same samples: they predict the
    // same torque.
    let model = io::read_model(&net).unwrap();
    let tables: Vec<Table> = train.iter().map(|p| Table::read(p).unwrap()).collect();
    let fit = baseline::fit(&tables, &[1]).unwrap();
    assert_eq!(model.linear.len(), fit.coefficients[0].len());
    // (Their fitted values on the training rows: unique even where features are collinear.)
    let rows: Vec<_> = tables
        .iter()
        .flat_map(|t| baseline::features(t, 1).unwrap())
        .collect();
    let dot = |w: &[f64], f: &[f64]| w.iter().zip(f).map(|(a, b)| a * b).sum::<f64>();
    let linear: Vec<f64> = model.linear.iter().map(|&w| f64::from(w)).collect();
    let diff = rows
        .iter()
        // The baseline fits the measured torque, the linear stage what the model leaves
        // (feature 1 is the model torque).
        .map(|f| (f[1] + dot(&linear, f) - dot(&fit.coefficients[0], f)).powi(2))
        .sum::<f64>()
        / rows.len() as f64;
    assert!(
        diff.sqrt() < 5e-3,
        "linear stage and baseline differ by {} N·m RMS",
        diff.sqrt()
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let gain = report["output_gains"][0].as_f64().unwrap();
    assert!(
        (0.0..0.5).contains(&gain),
        "gain {gain} on a residual of pure noise"
    );
}

#[test]
fn training_on_what_the_drive_adaptation_leaves_is_recorded_and_only_for_the_drive_preset() {
    let dir = tempfile::tempdir().unwrap();
    let runs = drive_runs(dir.path(), 3);
    let (net, report) = (
        dir.path().join("drive.safetensors"),
        dir.path().join("train.json"),
    );
    let args = |preset: &'static str, tau: &'static str| -> Vec<String> {
        [
            "train",
            "--data",
            &format!("{},{}", path(&runs[0]), path(&runs[1])),
            "--validation-data",
            &path(&runs[2]),
            "--preset",
            preset,
            "--joints",
            "1",
            "--epochs",
            "2",
            "--window",
            "50",
            "--burn-in",
            "10",
            "--embed",
            "4",
            "--hidden",
            "4",
            "--adapt-time-constant-s",
            tau,
            "--quiet",
            "--out",
            &path(&net),
            "--loss-plot",
            &path(&dir.path().join("loss.svg")),
            "--report",
            &path(&report),
        ]
        .map(String::from)
        .to_vec()
    };
    let run = |a: Vec<String>| cli(&a.iter().map(String::as_str).collect::<Vec<_>>());
    run(args("drive", "0.5")).expect("trains");
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(r["adaptation"]["time_constant_s"], 0.5);
    assert_eq!(r["adaptation"]["max_correction_nm"], 10.0);
    // Only the `drive` preset runs on the drive's adaptation; a zero time constant is no
    // adaptation. Both refused, nothing written.
    std::fs::remove_file(&net).unwrap();
    for (a, words) in [
        (
            args("feedforward", "0.5"),
            ["only for the `drive` preset", "feedforward"],
        ),
        (
            args("drive", "0"),
            ["--adapt-time-constant-s 0", "positive"],
        ),
    ] {
        let e = format!("{:#}", run(a).unwrap_err());
        assert!(words.iter().all(|w| e.contains(w)), "{e}");
        assert!(!net.exists());
    }
}
