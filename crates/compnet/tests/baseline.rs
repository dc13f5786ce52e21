//! The friction-feature least-squares baseline: coefficient recovery on synthetic
//! datasets (with and without the `qdd`, `rest_dir` and presliding columns) and bad input
//! (the `evaluate --baseline-data` wiring: `model-export/tests/evaluate_baseline_data.rs`).
use compnet::baseline::{self, FEATURE_NAMES, N_FEATURES};
use compnet::data::Table;
use std::path::PathBuf;

#[path = "support/friction_data.rs"]
mod friction_data;
use friction_data::{JOINTS, datasets, truth};

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
