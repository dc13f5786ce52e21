//! The README's main job in its fast (CI) variant: `model-export demo --fast` runs every
//! stage on the built-in default robot and writes the report folder; the figures in the
//! report are what the recorded stage commands print when run again one by one.
//! (The firmware build and budget stages run in `host-tests`' budget tests and in the
//! full demo; here `--no-firmware` keeps the test to the host pipeline.)
use clap::Parser;
use model_export::cli::{Cli, run};
use serde_json::Value;
use std::path::Path;

fn read_json(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
fn fast_demo_writes_the_report_and_its_figures_match_the_stage_commands() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("report");
    let out_s = out.to_str().unwrap().to_string();
    let cli = Cli::try_parse_from([
        "model-export",
        "demo",
        "--fast",
        "--no-firmware",
        "--out",
        &out_s,
    ])
    .unwrap();
    run(cli).expect("demo --fast");

    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(
        md.contains("fast (CI) variant"),
        "the report names its variant"
    );
    for section in [
        "Figures 3 and 4",
        "Table 2",
        "Closed loop",
        "Quantised networks",
        "Stages",
    ] {
        assert!(md.contains(section), "report.md lacks `{section}`");
    }
    for figure in [
        "excite/train.svg",
        "excite/test.svg",
        "figures/fig10_loss.svg",
        "figures/fig12_before.svg",
        "figures/fig13_after.svg",
    ] {
        assert!(md.contains(figure), "report.md does not show {figure}");
        let svg = std::fs::read_to_string(out.join(figure)).unwrap();
        assert!(
            svg.starts_with("<svg") || svg.starts_with("<?xml"),
            "{figure}"
        );
    }
    let report = read_json(&out.join("report.json"));
    assert_eq!(report["variant"], "fast (CI)");
    let table2 = report["table2"].as_array().unwrap();
    assert_eq!(table2.len(), 3);
    for row in table2 {
        for form in ["ours", "ours_relative", "ours_increment"] {
            for k in ["uncompensated_nm", "compensated_nm", "persistence_nm"] {
                let v = row[form][k].as_f64().unwrap();
                assert!(v.is_finite() && v > 0.0, "{row}");
            }
        }
        // The forms are judged on the same targets (the relative and increment forms' are
        // differences taken in f32: equal to rounding).
        let p = |form: &str| row[form]["persistence_nm"].as_f64().unwrap();
        for form in ["ours_relative", "ours_increment"] {
            assert!((p("ours") - p(form)).abs() <= 1e-6 * p("ours"), "{row}");
        }
    }
    // The drive-side compensator: evaluated open loop with baseline, adaptation and
    // monitor, and run in the closed loop with envelope, adaptation and monitor on.
    assert!(md.contains("The drive-side compensator"));
    let drive = &report["drive_compensator"];
    assert_eq!(drive["settings"]["monitor_window_s"], 2.0);
    let rows = drive["open_loop"].as_array().unwrap();
    assert_eq!(rows.len(), 3);
    for row in rows {
        for k in [
            "model_nm",
            "baseline_nm",
            "compensator_nm",
            "adapted_compensator_nm",
            "monitored_nm",
        ] {
            let v = row[k].as_f64().unwrap();
            assert!(v.is_finite() && v > 0.0, "{k}: {row}");
        }
        let share = row["outside_envelope_share"].as_f64().unwrap();
        assert!((0.0..=1.0).contains(&share), "{row}");
    }
    let closed = &report["closed_loop"];
    assert!(
        closed["title"]
            .as_str()
            .unwrap()
            .contains("do-no-harm monitor window 2 s"),
        "{closed}"
    );
    let lstm_rows: Vec<&Value> = closed["results"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|r| r["feedforward"].as_str().unwrap().contains("LSTM"))
        .collect();
    assert_eq!(lstm_rows.len(), 2);
    for r in lstm_rows {
        for j in r["joints"].as_array().unwrap() {
            let share = j["outside_envelope_share"].as_f64().unwrap();
            let (mean, min) = (
                j["mean_monitor_gain"].as_f64().unwrap(),
                j["min_monitor_gain"].as_f64().unwrap(),
            );
            assert!((0.0..=1.0).contains(&share), "{j}");
            assert!(
                (0.0..=1.0).contains(&min) && min <= mean && mean <= 1.0,
                "{j}"
            );
        }
    }
    assert!(
        report["stages"]
            .as_array()
            .unwrap()
            .iter()
            .all(|s| s["status"] == "ok")
    );

    // Run the recorded `evaluate` commands again, by themselves, with their reports
    // elsewhere: the same figures as the report's Table 2.
    for (stage_name, form) in [
        ("evaluate paper", "ours"),
        ("evaluate paper_relative", "ours_relative"),
        ("evaluate paper_increment", "ours_increment"),
    ] {
        let stage = report["stages"]
            .as_array()
            .unwrap()
            .iter()
            .find(|s| s["stage"] == stage_name)
            .expect("an evaluate stage");
        let again = dir.path().join("evaluate_again.json");
        let mut args: Vec<String> = stage["command"]
            .as_str()
            .unwrap()
            .split_whitespace()
            .map(str::to_string)
            .collect();
        let r = args.iter().position(|a| a == "--report").unwrap();
        args[r + 1] = again.to_str().unwrap().to_string();
        if let Some(f) = args.iter().position(|a| a == "--figures") {
            args.drain(f..f + 2);
        }
        run(Cli::try_parse_from(&args).unwrap()).expect("the recorded evaluate command");
        let rows = read_json(&again)["data"][0]["outputs"].clone();
        for (k, row) in table2.iter().enumerate() {
            assert_eq!(row[form]["uncompensated_nm"], rows[k]["rms_before"]);
            assert_eq!(row[form]["compensated_nm"], rows[k]["rms_after"]);
        }
    }
}
