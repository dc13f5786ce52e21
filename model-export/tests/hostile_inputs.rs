//! The plausibility layer through the command line: files made by hand that no physical
//! robot, run or network has, each refused with a message naming the file and the field,
//! an error (never a panic or a hang) and nothing written; outputs that would replace an
//! input refused for every command that writes; and ONNX networks from current PyTorch
//! taken where the README says they are.
use model_export::cli::run_args as cli;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn s(p: &Path) -> String {
    p.display().to_string()
}

/// Runs `args`, expects an error containing every one of `expect`, within `limit`.
fn refused(args: &[&str], expect: &[&str]) -> String {
    let start = Instant::now();
    let e = format!("{:#}", cli(args).expect_err("refused"));
    assert!(
        start.elapsed() < Duration::from_secs(20),
        "{args:?} took {:?}",
        start.elapsed()
    );
    for x in expect {
        assert!(e.contains(x), "{args:?}: expected {x:?} in: {e}");
    }
    e
}

/// A two-joint URDF; `joint2` and `link2` take the given limit and inertia attributes.
fn urdf(limits: &str, inertia: &str, name2: &str) -> String {
    format!(
        r#"<?xml version="1.0"?>
<robot name="two">
  <link name="base"/>
  <link name="link1">
    <inertial><origin xyz="0 0 0.1"/><mass value="2"/>
      <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <link name="link2">
    <inertial><origin xyz="0.2 0 0"/><mass value="1"/>
      <inertia {inertia} ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <joint name="joint1" type="revolute">
    <parent link="base"/><child link="link1"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="100" velocity="3"/>
  </joint>
  <joint name="{name2}" type="revolute">
    <parent link="link1"/><child link="link2"/><origin xyz="0 0 0.3"/><axis xyz="0 1 0"/>
    <limit {limits} effort="100" velocity="3"/>
  </joint>
</robot>
"#
    )
}

const GOOD_LIMITS: &str = r#"lower="-2" upper="2""#;
const GOOD_INERTIA: &str = r#"ixx="0.002" iyy="0.003" izz="0.004""#;

/// `excite` on `robot` (written to `dir/name`): refused with `expect`, the out-dir empty.
fn excite_refused(dir: &Path, name: &str, robot: &str, expect: &[&str]) {
    let path = dir.join(name);
    std::fs::write(&path, robot).unwrap();
    let out = dir.join(format!("exc-{name}"));
    refused(
        &[
            "excite",
            "--robot",
            &s(&path),
            "--joints",
            "all",
            "--qdd-max",
            "5",
            "--period",
            "2",
            "--harmonics",
            "2",
            "--restarts",
            "1",
            "--evaluations",
            "10",
            "--baseline",
            "0",
            "--out",
            &s(&out),
            "--name",
            "e",
        ],
        &[&[name][..], expect].concat(),
    );
    assert!(
        !out.exists() || std::fs::read_dir(&out).unwrap().next().is_none(),
        "{name}: excite wrote into {}",
        out.display()
    );
}

#[test]
fn urdf_limits_inertias_and_names_no_body_has_are_refused_naming_file_line_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // The good robot loads (the test can fail).
    let good = d.join("good.urdf");
    std::fs::write(&good, urdf(GOOD_LIMITS, GOOD_INERTIA, "joint2")).unwrap();
    robot::RobotSource::from(Some(good.clone()))
        .load()
        .expect("the good URDF loads");
    excite_refused(
        d,
        "equal_limits.urdf",
        &urdf(r#"lower="1" upper="1""#, GOOD_INERTIA, "joint2"),
        &[
            "equal_limits.urdf:16:",
            "joint2",
            "limit",
            "ordered and distinct",
        ],
    );
    excite_refused(
        d,
        "triangle.urdf",
        &urdf(
            GOOD_LIMITS,
            r#"ixx="0.001" iyy="0.001" izz="0.005""#,
            "joint2",
        ),
        &[
            "triangle.urdf:8:",
            "link2",
            "inertia",
            "triangle inequality",
        ],
    );
    let long = "j".repeat(200_000);
    excite_refused(
        d,
        "long_name.urdf",
        &urdf(GOOD_LIMITS, GOOD_INERTIA, &long),
        &["MAX_NAME_BYTES"],
    );
}

/// A DH TOML of `n` copies of the default robot's first joint, with `inertia`.
fn dh(n: usize, inertia: &str) -> String {
    let mut t = String::from("name = \"many\"\nconvention = \"standard\"\n");
    for k in 0..n {
        t += &format!(
            "\n[[joint]]\nname = \"j{k}\"\na = 0.1\nalpha = 1.5707963267948966\nd = 0.1\nmass = 3.0\ncom = [0.0, 0.0, 0.0]\ninertia = {inertia}\nq_min = -3.0\nq_max = 3.0\n"
        );
    }
    t
}

#[test]
fn dh_robots_with_impossible_inertia_or_a_thousand_joints_are_refused_quickly() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let ok = "[0.01, 0.01, 0.01, 0.0, 0.0, 0.0]";
    let good = d.join("good.toml");
    std::fs::write(&good, dh(2, ok)).unwrap();
    robot::RobotSource::from(Some(good))
        .load()
        .expect("the good TOML loads");
    excite_refused(
        d,
        "triangle.toml",
        &dh(2, "[0.01, 0.01, 0.05, 0.0, 0.0, 0.0]"),
        &["inertia", "triangle inequality"],
    );
    excite_refused(
        d,
        "thousand.toml",
        &dh(1000, ok),
        &["1000 is not in 1..=64", "MAX_JOINTS"],
    );
}

#[test]
fn every_output_equal_to_an_input_is_refused_and_the_input_kept() {
    let dir = tempfile::tempdir().unwrap();
    let trajectory = dir.path().join("trajectory.json");
    std::fs::write(&trajectory, "the trajectory\n").unwrap();
    let t = s(&trajectory);
    for args in [
        vec!["simulate", "--trajectory", &t, "-o", &t],
        vec!["sil", "--trajectory", &t, "--report", &t],
        vec!["sil", "--trajectory", &t, "--report-md", &t],
    ] {
        refused(&args, &["refusing to replace an input"]);
        assert_eq!(std::fs::read(&trajectory).unwrap(), b"the trajectory\n");
    }
}

#[test]
fn rates_and_durations_out_of_range_are_refused_before_running() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("m.rs");
    refused(
        &["export", "--control-rate-hz", "0", "--out", &s(&out)],
        &["--control-rate-hz", "above zero"],
    );
    assert!(!out.exists());
    for seconds in ["1e308", "1e9", "inf", "NaN"] {
        refused(&["sil", "--seconds", seconds], &["--seconds"]);
    }
}

fn fixture(name: &str) -> PathBuf {
    workspace().join("crates/compnet/tests/fixtures").join(name)
}

#[test]
fn an_empty_reference_and_a_newline_in_a_preset_are_refused_and_nothing_written() {
    use onnx_protobuf::{Message, ModelProto};
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = d.join("m.safetensors");
    let empty = d.join("empty.csv");
    std::fs::write(&empty, "t,x0,x1,x2,x3,x4,y0,y1\n").unwrap();
    let net = fixture("torch_lstm_dynamo.onnx");
    refused(
        &[
            "import",
            "--network",
            &s(&net),
            "--reference",
            &s(&empty),
            "--out",
            &s(&out),
        ],
        &["empty.csv", "no rows"],
    );
    assert!(!out.exists());
    let mut m = ModelProto::parse_from_bytes(&std::fs::read(&net).unwrap()).unwrap();
    for p in &mut m.metadata_props {
        if p.key == "preset" {
            p.value = "paper\ncustom".into();
        }
    }
    let bad = d.join("newline.onnx");
    std::fs::write(&bad, m.write_to_bytes().unwrap()).unwrap();
    refused(
        &["import", "--network", &s(&bad), "--out", &s(&out)],
        &["newline.onnx", "preset", "control character"],
    );
    assert!(!out.exists());
}

#[test]
fn the_network_option_takes_an_onnx_file_from_the_default_exporter() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("m.rs");
    let net = fixture("torch_lstm_dynamo.onnx");
    cli(&[
        "export",
        "--network",
        &s(&net),
        "--joints",
        "1,2",
        "--precision",
        "f32",
        "--allow-worse",
        // An imported network carries no training envelope: the user opts out of it
        // by name (or names the training datasets with --envelope-data).
        "--no-envelope",
        "--out",
        &s(&out),
    ])
    .expect("export of the dynamo ONNX network");
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(
        text.contains("CONTENT_HASH"),
        "{}",
        &text[..200.min(text.len())]
    );
}

#[test]
fn evaluate_refuses_a_run_of_fewer_than_two_rows() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let net = fixture("torch_lstm.onnx");
    for (name, rows) in [("header_only.csv", 0), ("one_row.csv", 1)] {
        let mut csv = String::from("x0,x1,x2,x3,x4,y0,y1\n");
        for _ in 0..rows {
            csv += "0.1,0.2,0.3,0.4,0.5,1.0,2.0\n";
        }
        let p = d.join(name);
        std::fs::write(&p, csv).unwrap();
        let report = d.join("r.json");
        refused(
            &[
                "evaluate",
                "--network",
                &s(&net),
                "--data",
                &s(&p),
                "--preset",
                "custom",
                "--inputs",
                "x0,x1,x2,x3,x4",
                "--targets",
                "y0,y1",
                "--report",
                &s(&report),
            ],
            &[name, "at least two"],
        );
        assert!(!report.exists());
    }
}

#[test]
fn logged_angles_thousands_of_turns_beyond_the_limits_are_refused_at_their_line() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("turns.csv");
    // Layout `torque`: time, q1..q6, qd1..qd6, tau1..tau6; line 201 (no header) holds a
    // joint-1 angle 2000 turns out.
    let mut csv = String::new();
    for k in 0..400 {
        let t = k as f64 * 0.01;
        let q1 = if k == 200 {
            2000.0 * std::f64::consts::TAU
        } else {
            0.5 * t.sin()
        };
        let mut row = vec![t, q1];
        row.extend((1..6).map(|j| 0.3 * (t + j as f64).sin()));
        row.extend((0..6).map(|j| 0.3 * (t + j as f64).cos()));
        row.extend((0..6).map(|j| (t * j as f64).sin()));
        csv += &row
            .iter()
            .map(|v| v.to_string())
            .collect::<Vec<_>>()
            .join(",");
        csv.push('\n');
    }
    std::fs::write(&log, csv).unwrap();
    let out = dir.path().join("m.json");
    let robot = workspace().join("robots/default.toml");
    refused(
        &[
            "identify",
            "--robot",
            &s(&robot),
            "--layout",
            "torque",
            "--log",
            &s(&log),
            "-o",
            &s(&out),
        ],
        &["turns.csv, line 201, joint 1", "beyond the robot's limits"],
    );
    assert!(!out.exists());
}
