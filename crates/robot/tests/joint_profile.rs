//! One joint profile: the robot description's `[joint.profile]` tables are what the
//! board runs and what the committed default model holds; a bad profile field is refused
//! naming the file, line and field (the exporter writing them:
//! `model-export/tests/export_joint_profiles.rs`).
use firmware::control::{BusClock, JointProfile};
use robot::Robot;
use test_support::default_robot_toml as default_robot_text;

/// 1-based line of the `nth` line starting with `needle`.
fn line_of(text: &str, needle: &str, nth: usize) -> usize {
    text.lines()
        .enumerate()
        .filter(|(_, l)| l.trim_start().starts_with(needle))
        .nth(nth)
        .expect("needle")
        .0
        + 1
}

#[test]
fn the_default_robots_wrist_profiles_are_the_boards_and_the_compiled_models() {
    let robot = Robot::from_dh_toml_str(&default_robot_text(), "default.toml").expect("robot");
    for j in &robot.joints[..3] {
        assert_eq!(j.profile, None, "{}", j.name);
        assert_eq!(j.drive_profile(), JointProfile::BOARD);
    }
    // The wrist asks for free-running bus clocks (the generic board's UART has no
    // SYNC); every other field is the board's.
    let uart = JointProfile {
        bus_clock: JointProfile::FREE_RUNNING,
        ..JointProfile::BOARD
    };
    assert_eq!(JointProfile::BOARD.bus_clock, JointProfile::FREE_RUNNING);
    for j in &robot.joints[3..] {
        assert_eq!(j.profile, Some(uart), "{}", j.name);
    }
    // The committed default model holds the default robot's wrist profiles: the board
    // reads the same definition the exporter read (another model, `FIRMWARE_MODEL`, was
    // exported for its own robot).
    if std::env::var_os("FIRMWARE_MODEL").is_some() {
        let what = "the committed default model (FIRMWARE_MODEL names another)";
        test_support::skip("the default model's profiles", what, false);
        return;
    }
    let wrist: Vec<JointProfile> = firmware::model::default::JOINT_INDICES
        .iter()
        .map(|&j| robot.joints[j].drive_profile())
        .collect();
    assert_eq!(wrist, firmware::model::default::JOINT_PROFILES.to_vec());
}

fn expect_profile_error(text: &str, line: usize, field: &str) {
    let e = Robot::from_dh_toml_str(text, "bad.toml").expect_err("must fail");
    let msg = e.to_string();
    println!("{msg}");
    assert_eq!(e.line, Some(line), "{msg}");
    assert_eq!(e.field, field, "{msg}");
    assert!(msg.starts_with("bad.toml"), "{msg}");
}

#[test]
fn a_bad_profile_field_is_refused_naming_file_line_and_field() {
    let good = default_robot_text();
    // Joint 5 (index 4) is the second wrist joint with a profile table.
    for (from, to, field) in [
        ("velocity_kp = 12.0", "velocity_kp = -1.0", "velocity_kp"),
        (
            "phase_inductance_h = 3e-4",
            "phase_inductance_h = nan",
            "phase_inductance_h",
        ),
        ("gear_ratio = 100.0", "gear_ratio = 1e40", "gear_ratio"),
        (
            "gear_efficiency = 1.0",
            "gear_efficiency = 1.2",
            "gear_efficiency",
        ),
        ("bus_max_v = 56.0", "bus_max_v = 30.0", "bus_max_v"),
        ("watchdog_ticks = 3", "watchdog_ticks = 0", "watchdog_ticks"),
    ] {
        // The second occurrence of `from` inside a profile: joint 5's table (the
        // joint's own `gear_ratio = 101.0` does not match these).
        let at = good.match_indices(from).nth(1).map(|(k, _)| k).expect(from);
        let text = format!("{}{}{}", &good[..at], to, &good[at + from.len()..]);
        expect_profile_error(
            &text,
            line_of(&text, to, 0),
            &format!("joint[4].profile.{field}"),
        );
    }
    // Unknown field and wrong type: the toml reader's error, at the line.
    let text = good.replacen("bus_baud = 2000000", "bus_bauds = 2000000", 1);
    let e = Robot::from_dh_toml_str(&text, "bad.toml").expect_err("unknown field");
    assert_eq!(e.line, Some(line_of(&text, "bus_bauds", 0)), "{e}");
    assert!(e.field.contains("bus_bauds"), "{e}");
    let text = good.replacen("pole_pairs = 7", "pole_pairs = 300", 1);
    let e = Robot::from_dh_toml_str(&text, "bad.toml").expect_err("out of u8");
    assert_eq!(e.line, Some(line_of(&text, "pole_pairs = 300", 0)), "{e}");
}

#[test]
fn a_partial_profile_takes_the_boards_values_for_the_rest() {
    let good = default_robot_text();
    let start = good.find("[joint.profile]").expect("profile");
    let end = good[start..].find("\n\n").map(|k| start + k).expect("end");
    let text = format!(
        "{}[joint.profile]\ngear_ratio = 160.0\nbus_clock = \"synchronised\"{}",
        &good[..start],
        &good[end..]
    );
    let robot = Robot::from_dh_toml_str(&text, "partial.toml").expect("robot");
    let p = robot.joints[3].profile.expect("profile");
    assert_eq!(p.gear_ratio, 160.0);
    assert_eq!(p.bus_clock, BusClock::Synchronised);
    assert_eq!(
        JointProfile {
            gear_ratio: JointProfile::BOARD.gear_ratio,
            bus_clock: JointProfile::BOARD.bus_clock,
            ..p
        },
        JointProfile::BOARD
    );
}
