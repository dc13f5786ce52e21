//! A network, a dataset or a preset that do not match: `evaluate` names both sides (the
//! network's preset and features, the data's), exits with an error and writes nothing.
use model_export::cli::run_args as cli;
use std::path::Path;

/// A `feedforward` dataset of joints 4 and 5, and a network trained on it for joint 4 (one
/// epoch); returns (dataset, network) paths.
fn trained_feedforward(dir: &Path) -> (String, String) {
    let data = dir.join("data.csv");
    let mut csv = String::from("time_s,q_j4,qd_j4,tau_meas_j4,tau_model_j4,q_j5,qd_j5\n");
    for k in 0..3000 {
        let t = k as f64 * 0.01;
        let (s, c) = t.sin_cos();
        csv += &format!("{t},{s},{c},{},{},{c},{s}\n", 2.0 * s, 1.9 * s);
    }
    std::fs::write(&data, csv).unwrap();
    let (data, net) = (
        data.display().to_string(),
        dir.join("ff.safetensors").display().to_string(),
    );
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
        "--window",
        "20",
        "--embed",
        "4",
        "--hidden",
        "4",
        "--quiet",
        "--out",
        &net,
        "--loss-plot",
        &dir.join("loss.svg").display().to_string(),
    ];
    cli(&args).expect("trains");
    (data, net)
}

/// `evaluate` with `extra` arguments fails with an error containing every `want`, and
/// leaves no report.
fn refused(net: &str, data: &str, extra: &[&str], want: &[&str], dir: &Path) {
    let report = dir.join("report.json");
    let mut args = vec!["evaluate", "--network", net, "--data", data];
    let r = report.display().to_string();
    args.extend_from_slice(extra);
    args.extend_from_slice(&["--report", &r]);
    let e = format!("{:#}", cli(&args).expect_err("a mismatch"));
    for w in want {
        assert!(e.contains(w), "{extra:?}: `{w}` missing from: {e}");
    }
    assert!(!report.exists(), "{extra:?} wrote {}", report.display());
}

#[test]
fn a_preset_that_does_not_match_the_network_names_both() {
    let dir = tempfile::tempdir().unwrap();
    let (data, net) = trained_feedforward(dir.path());
    // The network is a `feedforward` one; the data read as `drive` lacks its columns, and
    // the error names the network's preset and the data's.
    refused(
        &net,
        &data,
        &["--preset", "paper_relative", "--joints", "4"],
        &[
            "ff.safetensors",
            "preset `feedforward`",
            "preset `paper_relative`",
        ],
        dir.path(),
    );
}

#[test]
fn joints_that_do_not_match_the_network_name_both() {
    let dir = tempfile::tempdir().unwrap();
    let (data, net) = trained_feedforward(dir.path());
    refused(
        &net,
        &data,
        &["--preset", "feedforward", "--joints", "5"],
        &["ff.safetensors", "tau_model_j4", "tau_model_j5"],
        dir.path(),
    );
}

#[test]
fn a_dataset_without_the_networks_columns_names_the_file_and_the_column() {
    let dir = tempfile::tempdir().unwrap();
    let (_, net) = trained_feedforward(dir.path());
    let thin = dir.path().join("thin.csv");
    std::fs::write(
        &thin,
        "time_s,q_j4,qd_j4,tau_meas_j4\n0,0,0,0\n0.01,0,0,0\n",
    )
    .unwrap();
    refused(
        &net,
        &thin.display().to_string(),
        &["--preset", "feedforward", "--joints", "4"],
        &["thin.csv", "tau_model_j4"],
        dir.path(),
    );
}
