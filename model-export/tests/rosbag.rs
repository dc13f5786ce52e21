//! ROS 2 recordings (rosbag2 MCAP of sensor_msgs/msg/JointState): the committed fixture
//! (scripts/make_mcap_fixture.py, a simulated run of the default robot) reads, identifies
//! and evaluates exactly like the same samples as CSV, and hostile bags are refused with
//! the file, topic and field named, nothing written.
use byteorder::LittleEndian;
use logs::{BagOptions, LogLayout, read_log, read_robot_log, rosbag};
use model_export::cli::run_args as cli;
use serde::Serialize;
use std::collections::BTreeMap;
use std::io::Cursor;
use std::path::{Path, PathBuf};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

fn robot() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../robots/default.toml")
        .display()
        .to_string()
}

/// The default robot's joint names, in order.
fn names() -> Vec<String> {
    [
        "shoulder_pan",
        "shoulder_lift",
        "elbow",
        "wrist_1",
        "wrist_2",
        "wrist_3",
    ]
    .map(String::from)
    .to_vec()
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
    let mut id_bag = vec!["identify", "--robot", &r, "--log", &bag, "--validate", &bag];
    id_bag.extend(lock);
    let (m_bag, m_csv) = (p("bag.json"), p("csv.json"));
    id_bag.extend(["-o", &m_bag]);
    cli(&id_bag).unwrap();
    let mut id_csv = vec!["identify", "--robot", &r, "--log", &csv, "--validate", &csv];
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
    let mut tq = vec!["torque", "--robot", &r, "--model", &m_bag, "--log", &bag];
    tq.extend(keep);
    tq.extend(["-o", &d_bag]);
    cli(&tq).unwrap();
    let mut tq = vec!["torque", "--robot", &r, "--model", &m_csv, "--log", &csv];
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

#[derive(Serialize, Clone)]
struct Time {
    sec: i32,
    nanosec: u32,
}

#[derive(Serialize, Clone)]
struct Header {
    stamp: Time,
    frame_id: String,
}

#[derive(Serialize, Clone)]
struct JointState {
    header: Header,
    name: Vec<String>,
    position: Vec<f64>,
    velocity: Vec<f64>,
    effort: Vec<f64>,
}

fn joint_state(k: usize) -> JointState {
    let t_ns = 1_000_000_000u64 + 10_000_000 * k as u64;
    JointState {
        header: Header {
            stamp: Time {
                sec: (t_ns / 1_000_000_000) as i32,
                nanosec: (t_ns % 1_000_000_000) as u32,
            },
            frame_id: String::new(),
        },
        name: names(),
        position: (0..6).map(|j| 0.1 * j as f64 + 0.01 * k as f64).collect(),
        velocity: vec![1.0; 6],
        effort: vec![2.0; 6],
    }
}

fn cdr(m: &JointState) -> Vec<u8> {
    let mut v = vec![0, 1, 0, 0];
    v.extend(cdr_encoding::to_vec::<_, LittleEndian>(m).unwrap());
    v
}

/// A bag with the messages `msgs` (raw CDR bytes) on `topic`.
fn bag(topic: &str, msgs: &[Vec<u8>]) -> Vec<u8> {
    let mut w = mcap::Writer::new(Cursor::new(Vec::new())).unwrap();
    let s = w
        .add_schema(rosbag::JOINT_STATE_SCHEMA, "ros2msg", b"")
        .unwrap();
    let c = w.add_channel(s, topic, "cdr", &BTreeMap::new()).unwrap();
    for (k, m) in msgs.iter().enumerate() {
        let header = mcap::records::MessageHeader {
            channel_id: c,
            sequence: k as u32,
            log_time: k as u64,
            publish_time: k as u64,
        };
        w.write_to_known_channel(&header, m).unwrap();
    }
    w.finish().unwrap();
    w.into_inner().into_inner()
}

fn messages(edit: impl Fn(usize, &mut JointState)) -> Vec<Vec<u8>> {
    (0..40)
        .map(|k| {
            let mut m = joint_state(k);
            edit(k, &mut m);
            cdr(&m)
        })
        .collect()
}

/// The error of reading `bytes` as a bag (in `dir`) on `topic`, as text.
fn bag_error(dir: &Path, name: &str, bytes: &[u8], topic: &str) -> String {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    let opts = BagOptions {
        topic: topic.into(),
        drive_gains_nm_per_a: None,
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
    // Flipped bytes inside a zstd chunk: caught by the chunk's CRC, or earlier by a
    // message that no longer decodes to a valid JointState, whichever comes first.
    let e = bag_error(d, "flipped.mcap", &flipped, "/joint_states");
    assert!(
        e.contains("flipped.mcap: corrupt or truncated MCAP file")
            || e.contains("flipped.mcap, topic /joint_states, message "),
        "{e}"
    );
    println!("flipped bytes: {e}");
    let e = bag_error(d, "empty.mcap", b"", "/joint_states");
    assert!(
        e.contains("empty.mcap: not an MCAP file") || e.contains("empty.mcap: corrupt"),
        "{e}"
    );
}

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
