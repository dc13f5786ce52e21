//! One joint profile through the exporter: the robot description's `[joint.profile]`
//! tables are what it writes into a model file's `JOINT_PROFILES` (the profiles
//! themselves: `crates/robot/tests/joint_profile.rs`).
use fw_export::{Precision, WeightsIn};
use model_export::cmd::export::ExportArgs;
use std::path::PathBuf;
use test_support::default_robot_toml as default_robot_text;

fn export_args(robot: Option<PathBuf>, out: PathBuf) -> ExportArgs {
    ExportArgs {
        network: None,
        dims: vec![9, 8, 8, 3],
        seed: 1,
        preset: firmware::nn::format::FeaturePreset::Paper,
        joints: vec![4, 5, 6],
        control_rate_hz: 100,
        precision: Precision::Int16,
        robot,
        out,
        budgets: None,
        weights_in: WeightsIn::Flash,
        self_check_steps: 10,
        accuracy_log: None,
        identified: None,
        chain: Default::default(),
        report: None,
        gate_data: Vec::new(),
        allow_worse: false,
        adapt_time_constant_s: None,
        monitor_window_s: None,
        envelope_data: Vec::new(),
        no_envelope: false,
        no_monitor: false,
    }
}

#[test]
fn the_exporter_writes_each_compensated_joints_profile() {
    let dir = tempfile::tempdir().expect("tempdir");
    // Joint 5's gear and joint 4's bus rate differ from the board's.
    let good = default_robot_text();
    let at = good
        .match_indices("gear_ratio = 100.0")
        .nth(1)
        .expect("joint 5")
        .0;
    let text = format!(
        "{}gear_ratio = 160.0{}",
        &good[..at],
        &good[at + "gear_ratio = 100.0".len()..]
    );
    let text = text.replacen("bus_baud = 2000000", "bus_baud = 1000000", 1);
    let robot_path = dir.path().join("robot.toml");
    std::fs::write(&robot_path, &text).expect("write robot");
    let out = dir.path().join("model.rs");
    let a = export_args(Some(robot_path.clone()), out.clone());
    let m = model_export::cmd::export::model(&a).expect("model");
    model_export::cmd::export::export(&m, &a).expect("export");
    let file = std::fs::read_to_string(&out).expect("model file");
    let block: Vec<&str> = file
        .lines()
        .skip_while(|l| !l.starts_with("pub const JOINT_PROFILES"))
        .take_while(|l| *l != "];")
        .collect();
    assert!(block[0].starts_with("pub const JOINT_PROFILES: [firmware::control::JointProfile; 3]"));
    let gears: Vec<&str> = block
        .iter()
        .filter(|l| l.trim_start().starts_with("gear_ratio:"))
        .map(|l| l.trim())
        .collect();
    assert_eq!(gears.len(), 3);
    assert!(gears[0].starts_with("gear_ratio: 100.0,"), "{gears:?}");
    assert!(gears[1].starts_with("gear_ratio: 160.0,"), "{gears:?}");
    assert!(gears[2].starts_with("gear_ratio: 100.0,"), "{gears:?}");
    let bauds: Vec<&str> = block
        .iter()
        .filter(|l| l.contains("bus_baud:"))
        .map(|l| l.trim())
        .collect();
    assert!(bauds[0].ends_with("bus_baud: 1000000,"), "{bauds:?}");
    assert!(bauds[1].ends_with("bus_baud: 2000000,"), "{bauds:?}");
    // Without a robot: the board's profile for every joint, the same lines.
    let out2 = dir.path().join("plain.rs");
    let a = export_args(None, out2.clone());
    model_export::cmd::export::export(&m, &a).expect("export");
    let plain = std::fs::read_to_string(&out2).expect("model file");
    assert_eq!(
        plain
            .matches("gear_ratio: 100.0, gear_efficiency: 1.0")
            .count(),
        3
    );
    // A bad profile: refused before anything is written.
    let bad = text.replacen("velocity_kp = 12.0", "velocity_kp = -12.0", 1);
    std::fs::write(&robot_path, bad).expect("write robot");
    let before = std::fs::read(&out).expect("model file");
    let a = export_args(Some(robot_path), out.clone());
    let err = model_export::cmd::export::export(&m, &a).expect_err("bad profile");
    assert!(
        format!("{err:#}").contains("profile.velocity_kp"),
        "{err:#}"
    );
    assert_eq!(std::fs::read(&out).expect("model file"), before);
}
