//! ROS 2 recordings as other tools write them (scripts/make_ros2_fixtures.py), through
//! the command line: a `.db3` bag of the default robot, a split rosbag2 folder with the
//! UR driver's joint names (`--joint-map`), the arm from two publishers and a bag with
//! zero header stamps (`--time-source log`) each identify to the same model as the CSV
//! twin, to the last digit; refusals exit non-zero, name the file and write nothing.
use model_export::cli::run_args as cli;
use std::path::PathBuf;

fn fixture(name: &str) -> String {
    test_support::workspace_root()
        .join("crates/logs/tests/fixtures")
        .join(name)
        .display()
        .to_string()
}

fn robot() -> String {
    test_support::robots_dir()
        .join("default.toml")
        .display()
        .to_string()
}

const UR_MAP: &str = "shoulder_pan_joint=shoulder_pan,shoulder_lift_joint=shoulder_lift,elbow_joint=elbow,wrist_1_joint=wrist_1,wrist_2_joint=wrist_2,wrist_3_joint=wrist_3";

/// The model file with the log's path and hash replaced (they name the input).
fn stripped(path: &PathBuf, log: &str) -> serde_json::Value {
    let text = std::fs::read_to_string(path).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    for l in v["identification_logs"].as_array_mut().unwrap() {
        assert_eq!(l["path"], log);
        l["path"] = "LOG".into();
        l["sha256"] = "HASH".into();
    }
    // The error figures are labelled by the log's path.
    serde_json::from_str(&v.to_string().replace(log, "LOG")).unwrap()
}

#[test]
fn every_storage_identifies_like_the_csv() {
    let dir = tempfile::tempdir().unwrap();
    let r = robot();
    let identify = |log: &str, extra: &[&str], out: &str| -> serde_json::Value {
        let o = dir.path().join(out);
        let mut args = vec![
            "identify",
            "--robot",
            &r,
            "--lock",
            "1=0,2=0,3=0",
            "--log",
            log,
        ];
        args.extend(extra);
        let os = o.display().to_string();
        args.extend(["-o", &os]);
        cli(&args).unwrap();
        stripped(&o, log)
    };
    let csv = fixture("joint_states.csv");
    let reference = identify(&csv, &["--layout", "torque", "--header", "yes"], "csv.json");
    for (log, extra) in [
        (fixture("default.db3"), vec![]),
        (fixture("ur_split"), vec!["--joint-map", UR_MAP]),
        (fixture("two_publishers.mcap"), vec![]),
        (fixture("zero_stamps.mcap"), vec!["--time-source", "log"]),
    ] {
        let m = identify(&log, &extra, "bag.json");
        assert_eq!(m, reference, "{log}: model differs from the CSV's");
    }
}

/// Through the binary: exit status non-zero, the message on stderr naming the file,
/// no output written.
#[test]
fn refusals_exit_nonzero_name_the_file_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A copy of the fixture with one byte flipped inside its first chunk's records.
    let mut b = std::fs::read(fixture("joint_states.mcap")).unwrap();
    b[110 + 1000] ^= 0x01;
    let flipped = d.join("flipped.mcap");
    std::fs::write(&flipped, &b).unwrap();
    let flipped = flipped.display().to_string();
    // A bag with velocity[] empty.
    #[path = "../../crates/logs/tests/support/bags.rs"]
    mod bags;
    let noqd = d.join("noqd.mcap");
    std::fs::write(
        &noqd,
        bags::bag("/joint_states", &bags::messages(|_, m| m.velocity.clear())),
    )
    .unwrap();
    let noqd = noqd.display().to_string();
    let map_file = d.join("map.txt");
    std::fs::write(
        &map_file,
        "shoulder_pan_joint=shoulder_pan\nshoulder_pan_joint=elbow\n",
    )
    .unwrap();
    let map_file = map_file.display().to_string();
    let cases: Vec<(Vec<String>, &str)> = vec![
        (
            vec![fixture("zero_stamps.mcap")],
            "zero_stamps.mcap, topic /joint_states, message 2, field header.stamp: stamps not strictly increasing",
        ),
        (
            vec![flipped],
            "flipped.mcap, chunk 1: corrupt MCAP file: CRC",
        ),
        (
            vec![fixture("ur_split")],
            "ur_split, topic /joint_states, message 1, field name: no joint 'shoulder_pan'",
        ),
        (
            vec![noqd, "--use-logged-qd".into()],
            "noqd.mcap, velocity: logged velocities asked for (--use-logged-qd)",
        ),
        (
            vec![fixture("ur_split"), "--joint-map".into(), map_file],
            "map.txt: joint map entry 2 'shoulder_pan_joint=elbow': 'shoulder_pan_joint' mapped twice",
        ),
    ];
    let model = d.join("model.json");
    for (args, want) in cases {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_model-export"))
            .args([
                "identify",
                "--robot",
                &robot(),
                "--lock",
                "1=0,2=0,3=0",
                "--log",
            ])
            .args(&args)
            .arg("-o")
            .arg(&model)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?}");
        assert!(err.contains(want), "{args:?}: {err}");
        if want.contains("zero_stamps") {
            assert!(err.contains("--time-source log"), "{err}");
        }
        assert!(!model.exists(), "{args:?} wrote the model");
    }
}
