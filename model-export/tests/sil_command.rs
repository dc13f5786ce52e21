//! The wrist SIL through the command line: simulate, identify and `sil` write the Markdown
//! and JSON reports (the simulation's own checks: `crates/sil/tests/sil_wrist.rs`).

use model_export::cli::run_args as cli;

#[test]
fn cli_simulate_identify_sil_writes_markdown_and_json() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_str().unwrap().to_string();
    let (log, model, md, json) = (p("log.csv"), p("m.json"), p("sil.md"), p("sil.json"));
    cli(&[
        "simulate",
        "--seeded-trajectory",
        "1",
        "--joints",
        "4,5,6",
        "-o",
        &log,
    ])
    .unwrap();
    let layout = plant_sim::SimulatedLog::reader_args(6);
    let layout: Vec<&str> = layout.iter().map(String::as_str).collect();
    let mut id = vec![
        "identify",
        "--log",
        &log,
        "--lock",
        "1=0,2=0,3=0",
        "-o",
        &model,
    ];
    id.extend_from_slice(&layout);
    cli(&id).unwrap();
    // The LSTM dataset columns.
    let feat = p("features.csv");
    let mut tq = vec![
        "torque",
        "--identified",
        &model,
        "--log",
        &log,
        "--dataset",
        "-o",
        &feat,
    ];
    tq.extend_from_slice(&layout);
    cli(&tq).unwrap();
    let header = std::fs::read_to_string(&feat).unwrap();
    assert!(header.starts_with(
        "time_s,q_j4,q_j5,q_j6,qd_j4,qd_j5,qd_j6,tau_meas_j4,tau_meas_j5,tau_meas_j6,tau_model_j4,tau_model_j5,tau_model_j6,\
         qdd_j4,qdd_j5,qdd_j6,sin_q_j4,sin_q_j5,sin_q_j6,cos_q_j4,cos_q_j5,cos_q_j6,rest_dir_j4,rest_dir_j5,rest_dir_j6,\
         slip_1mrad_j4,slip_1mrad_j5,slip_1mrad_j6,slip_3mrad_j4,slip_3mrad_j5,slip_3mrad_j6,\
         slip_10mrad_j4,slip_10mrad_j5,slip_10mrad_j6,slip_30mrad_j4,slip_30mrad_j5,slip_30mrad_j6\n"
    ));
    cli(&[
        "sil",
        "--identified",
        &model,
        "--seconds",
        "0.3",
        "--report-md",
        &md,
        "--report",
        &json,
    ])
    .unwrap();
    let md = std::fs::read_to_string(&md).unwrap();
    assert!(
        md.contains("| feedforward | joint | RMS error [mrad]"),
        "{md}"
    );
    assert_eq!(md.matches("| model | ").count(), 3, "{md}");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let results = v["results"].as_array().unwrap();
    assert_eq!(results.len(), 2, "none and model (no --lstm)");
    for r in results {
        let joints = r["joints"].as_array().unwrap();
        assert_eq!(joints.len(), 3);
        for j in joints {
            assert!(j["rms_error_rad"].as_f64().unwrap() > 0.0);
            assert!(j["rms_iq_a"].as_f64().unwrap() > 0.0);
        }
    }
    // An LSTM needs the model it corrects.
    assert!(cli(&["sil", "--network", &p("x.safetensors")]).is_err());
}
