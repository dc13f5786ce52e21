//! ROS 2 recordings (rosbag2 MCAP of sensor_msgs/msg/JointState): the committed fixture
//! (scripts/make_mcap_fixture.py, a simulated run of the default robot) reads exactly like
//! the same samples as CSV, and hostile bags are refused with the file, topic and field
//! named.
use logs::{BagOptions, LogLayout, read_log, read_robot_log, rosbag};
use std::path::{Path, PathBuf};

#[path = "support/bags.rs"]
mod bags;
use bags::{bag, messages, names};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

/// The CSV twin's layout: header, time, q1..6, qd1..6, tau1..6.
fn csv_layout() -> LogLayout {
    let mut l = LogLayout::sequential(6, true, true, None);
    l.header = Some(true);
    l
}

#[test]
fn the_bag_reads_the_same_samples_as_its_csv() {
    let bag = rosbag::read_bag(
        &fixture("joint_states.mcap"),
        &BagOptions::default(),
        &names(),
    )
    .unwrap();
    let csv = read_log(&fixture("joint_states.csv"), &csv_layout()).unwrap();
    assert!(bag.len() >= 1000, "{} messages", bag.len());
    assert_eq!(bag.time_s, csv.time_s);
    assert_eq!(bag.q_rad, csv.q_rad);
    assert_eq!(bag.qd_rad_s, csv.qd_rad_s);
    assert_eq!(bag.torque_nm, csv.torque_nm);
    assert!(bag.current_a.is_none());
    // Chosen by content as well as by extension.
    let dir = tempfile::tempdir().unwrap();
    let renamed = dir.path().join("recording.db");
    std::fs::copy(fixture("joint_states.mcap"), &renamed).unwrap();
    assert!(rosbag::is_mcap(&renamed) && !rosbag::is_mcap(&fixture("joint_states.csv")));
    let by_content = read_robot_log(
        &renamed,
        &LogLayout::ur10e(),
        &BagOptions::default(),
        &names(),
    )
    .unwrap();
    assert_eq!(by_content.q_rad, bag.q_rad);
    // The stamps jitter around the 10 ms period.
    let steps: Vec<f64> = bag.time_s.windows(2).map(|w| w[1] - w[0]).collect();
    let (lo, hi) = steps
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), &d| (a.min(d), b.max(d)));
    assert!(lo < 0.0097 && hi > 0.0103 && lo > 0.0, "steps {lo}..{hi}");
    // Effort as current: torque = current x gain.
    let gains = vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
    let cur = rosbag::read_bag(
        &fixture("joint_states.mcap"),
        &BagOptions {
            drive_gains_nm_per_a: Some(gains.clone()),
            ..BagOptions::default()
        },
        &names(),
    )
    .unwrap();
    let (i, tau) = (cur.current_a.unwrap(), cur.torque_nm.unwrap());
    for j in 0..6 {
        assert_eq!(i[j], csv.torque_nm.as_ref().unwrap()[j]);
        assert_eq!(tau[j][7], i[j][7] * gains[j]);
    }
}

/// The error of reading `bytes` as a bag (in `dir`) on `topic`, as text.
fn bag_error(dir: &Path, name: &str, bytes: &[u8], topic: &str) -> String {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    let opts = BagOptions {
        topic: topic.into(),
        ..BagOptions::default()
    };
    match rosbag::read_bag(&path, &opts, &names()) {
        Ok(l) => panic!("{name}: read {} samples", l.len()),
        Err(e) => e.to_string(),
    }
}

#[test]
fn hostile_bags_are_refused_naming_file_topic_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let good = bag("/joint_states", &messages(|_, _| {}));

    let e = bag_error(d, "other.mcap", &good, "/arm/joint_states");
    assert!(
        e.contains("other.mcap, topic /arm/joint_states: no messages")
            && e.contains("topics /joint_states"),
        "{e}"
    );

    let renamed = bag(
        "/joint_states",
        &messages(|_, m| m.name[3] = "wrist_1_joint".into()),
    );
    let e = bag_error(d, "names.mcap", &renamed, "/joint_states");
    assert!(
        e.contains("names.mcap, topic /joint_states, message 1, field name: no joint 'wrist_1'"),
        "{e}"
    );

    let unordered = bag(
        "/joint_states",
        &messages(|k, m| {
            if k == 20 {
                m.header.stamp.nanosec -= 20_000_000;
            }
        }),
    );
    let e = bag_error(d, "order.mcap", &unordered, "/joint_states");
    assert!(
        e.contains("order.mcap, topic /joint_states, message 21, field header.stamp: stamps not strictly increasing"),
        "{e}"
    );

    let short = bag("/joint_states", &messages(|_, m| m.position.truncate(5)));
    let e = bag_error(d, "short.mcap", &short, "/joint_states");
    assert!(
        e.contains("message 1, field position: 5 values for 6 names"),
        "{e}"
    );

    let nan = bag(
        "/joint_states",
        &messages(|k, m| {
            if k == 3 {
                m.effort[2] = f64::NAN;
            }
        }),
    );
    let e = bag_error(d, "nan.mcap", &nan, "/joint_states");
    assert!(
        e.contains("message 4, field effort[2] ('elbow'): non-finite"),
        "{e}"
    );

    let mut garbage = messages(|_, _| {});
    garbage[5].truncate(30);
    let e = bag_error(
        d,
        "cdr.mcap",
        &bag("/joint_states", &garbage),
        "/joint_states",
    );
    assert!(
        e.contains("topic /joint_states, message 6: not a CDR-encoded sensor_msgs/msg/JointState"),
        "{e}"
    );

    // The committed fixture, truncated and corrupted.
    let fixture_bytes = std::fs::read(fixture("joint_states.mcap")).unwrap();
    let e = bag_error(
        d,
        "truncated.mcap",
        &fixture_bytes[..fixture_bytes.len() / 2],
        "/joint_states",
    );
    assert!(
        e.contains("truncated.mcap: corrupt or truncated MCAP file"),
        "{e}"
    );
    let mut flipped = fixture_bytes.clone();
    let mid = flipped.len() / 3;
    for b in &mut flipped[mid..mid + 64] {
        *b ^= 0x5a;
    }
    // Flipped bytes inside a zstd chunk: caught before any message is read, by the
    // chunk's CRC (or by the decompressor when the flip breaks the zstd frame).
    let e = bag_error(d, "flipped.mcap", &flipped, "/joint_states");
    assert!(
        e.contains("flipped.mcap, chunk 1: corrupt MCAP file: CRC")
            || e.contains("flipped.mcap: corrupt or truncated MCAP file"),
        "{e}"
    );
    println!("flipped bytes: {e}");
    let e = bag_error(d, "empty.mcap", b"", "/joint_states");
    assert!(
        e.contains("empty.mcap: not an MCAP file") || e.contains("empty.mcap: corrupt"),
        "{e}"
    );
}

/// A cell near the largest f64 overflows only after filtering and differentiation; the
/// zero-phase filter spreads the overflow over its window, yet the error names the line
/// of the cell itself (line 201), with or without a header line.
#[test]
fn an_overflow_is_reported_at_the_line_of_its_cell() {
    let dir = tempfile::tempdir().unwrap();
    for (value, header) in [(1.7e308, true), (-1.7e308, false)] {
        let mut text = String::new();
        if header {
            text.push_str("time,q1,tau1\n");
        }
        let first = if header { 2 } else { 1 };
        for k in 0..600 {
            let t = k as f64 * 0.002;
            let mut cells = [t, (3.0 * t).sin(), (2.0 * t).cos()];
            if k + first == 201 {
                cells[1] = value;
            }
            text.push_str(&format!("{},{},{}\n", cells[0], cells[1], cells[2]));
        }
        let p = dir.path().join("big.csv");
        std::fs::write(&p, text).unwrap();
        let mut layout = logs::LogLayout::sequential(1, false, true, None);
        layout.header = Some(header);
        let raw = logs::read_log(&p, &layout).unwrap();
        let opts = logs::PreprocessOptions {
            trim_rest_rad_s: None,
            ..logs::PreprocessOptions::default()
        };
        let Err(e) = logs::preprocess(&raw, &opts) else {
            panic!("value {value}, header {header}: accepted");
        };
        assert_eq!(e.line, Some(201), "value {value}, header {header}: {e}");
        assert!(e.to_string().contains("big.csv, line 201"), "{e}");
    }
}
