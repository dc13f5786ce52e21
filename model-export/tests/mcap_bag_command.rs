//! ROS 2 recordings through the command line: the committed fixture identifies and
//! evaluates exactly like the same samples as CSV, and a hostile bag is refused with the
//! file, topic and field named, nothing written (the reader itself:
//! `crates/logs/tests/rosbag.rs`).
use model_export::cli::run_args as cli;
use std::path::PathBuf;

#[path = "../../crates/logs/tests/support/bags.rs"]
mod bags;
use bags::{bag, messages};

fn fixture(name: &str) -> PathBuf {
    test_support::workspace_root()
        .join("crates/logs/tests/fixtures")
        .join(name)
}

fn robot() -> String {
    test_support::robots_dir()
        .join("default.toml")
        .display()
        .to_string()
}

/// Identification and model torque from the bag and from its CSV twin: the same model
/// file (but for the log's path and hash), the same figures, the same dataset bytes.
#[test]
fn the_bag_identifies_and_evaluates_like_its_csv() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).display().to_string();
    let (bag, csv) = (
        fixture("joint_states.mcap").display().to_string(),
        fixture("joint_states.csv").display().to_string(),
    );
    let r = robot();
    let lock = ["--lock", "1=0,2=0,3=0"];
    let csv_cols = ["--layout", "torque", "--header", "yes"];
    let mut id_bag = vec![
        "identify",
        "--robot",
        &r,
        "--log",
        &bag,
        "--validation-log",
        &bag,
    ];
    id_bag.extend(lock);
    let (m_bag, m_csv) = (p("bag.json"), p("csv.json"));
    id_bag.extend(["-o", &m_bag]);
    cli(&id_bag).unwrap();
    let mut id_csv = vec![
        "identify",
        "--robot",
        &r,
        "--log",
        &csv,
        "--validation-log",
        &csv,
    ];
    id_csv.extend(lock);
    id_csv.extend(csv_cols);
    id_csv.extend(["-o", &m_csv]);
    cli(&id_csv).unwrap();
    let strip = |path: &str, log: &str| {
        let text = std::fs::read_to_string(path).unwrap();
        let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
        for key in ["identification_logs", "validation_logs"] {
            for l in v[key].as_array_mut().unwrap() {
                assert_eq!(l["path"], log);
                l["path"] = "LOG".into();
                l["sha256"] = "HASH".into();
            }
        }
        // Validation figures are labelled by the log's path.
        serde_json::from_str::<serde_json::Value>(&v.to_string().replace(log, "LOG")).unwrap()
    };
    let (a, b) = (strip(&m_bag, &bag), strip(&m_csv, &csv));
    assert!(
        a["validation_logs"][0]["samples"].as_u64().unwrap() > 900,
        "{a}"
    );
    assert_eq!(a, b, "model files differ");

    // Model torque (the LSTM dataset) from each log with its identified model.
    let (d_bag, d_csv) = (p("bag.csv"), p("csv.csv"));
    let keep = [
        "--dataset",
        "--trim-rest-rad-s",
        "0",
        "--torque-cutoff-hz",
        "0",
    ];
    let mut tq = vec![
        "torque",
        "--robot",
        &r,
        "--identified",
        &m_bag,
        "--log",
        &bag,
    ];
    tq.extend(keep);
    tq.extend(["-o", &d_bag]);
    cli(&tq).unwrap();
    let mut tq = vec![
        "torque",
        "--robot",
        &r,
        "--identified",
        &m_csv,
        "--log",
        &csv,
    ];
    tq.extend(keep);
    tq.extend(csv_cols);
    tq.extend(["-o", &d_csv]);
    cli(&tq).unwrap();
    let (x, y) = (
        std::fs::read_to_string(&d_bag).unwrap(),
        std::fs::read_to_string(&d_csv).unwrap(),
    );
    assert!(x.lines().count() > 1000);
    assert_eq!(x, y, "datasets differ");
}

// ---- hostile bags ----

/// Through the binary: exit status non-zero, the message on stderr, no output written.
#[test]
fn the_cli_refuses_a_hostile_bag_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let unordered = bag(
        "/joint_states",
        &messages(|k, m| {
            if k == 30 {
                m.header.stamp.sec -= 1;
            }
        }),
    );
    let log = d.join("run.mcap");
    std::fs::write(&log, unordered).unwrap();
    let (model, data) = (d.join("model.json"), d.join("data.csv"));
    for args in [
        vec!["identify", "--robot", &robot(), "--log"],
        vec!["torque", "--robot", &robot(), "--log"],
    ] {
        let out = if args[0] == "identify" { &model } else { &data };
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_model-export"))
            .args(&args)
            .arg(&log)
            .arg("-o")
            .arg(out)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?}");
        assert!(
            err.contains("run.mcap, topic /joint_states, message 31, field header.stamp"),
            "{args:?}: {err}"
        );
        assert!(!out.exists(), "{args:?} wrote {}", out.display());
    }
}
