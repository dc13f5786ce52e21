//! ROS 2 recordings as other tools write them (scripts/make_ros2_fixtures.py: the
//! `rosbags`, `mcap` and `mcap-ros2-support` packages), each carrying the samples of the
//! CSV twin `joint_states.csv`: a `.db3` (sqlite3 storage), a rosbag2 folder split in two
//! MCAP files with the UR driver's joint names, the arm from two publishers beside a
//! gripper, and zero header stamps. Each reads back to the CSV's samples bit for bit;
//! corrupt or incomplete ones are refused naming the file and what is wrong.
use logs::{BagOptions, LogLayout, PreprocessOptions, TimeSource, preprocess, read_log, rosbag};
use std::path::{Path, PathBuf};

#[path = "support/bags.rs"]
mod bags;
use bags::{bag, messages, names};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

fn csv() -> logs::RawLog {
    let mut l = LogLayout::sequential(6, true, true, None);
    l.header = Some(true);
    read_log(&fixture("joint_states.csv"), &l).unwrap()
}

fn assert_same_samples(bag: &logs::RawLog) {
    let csv = csv();
    assert_eq!(bag.len(), csv.len());
    assert_eq!(bag.time_s, csv.time_s);
    assert_eq!(bag.q_rad, csv.q_rad);
    assert_eq!(bag.qd_rad_s, csv.qd_rad_s);
    assert_eq!(bag.torque_nm, csv.torque_nm);
}

fn ur_map() -> Vec<(String, String)> {
    names()
        .into_iter()
        .map(|n| (format!("{n}_joint"), n))
        .collect()
}

fn read(path: &Path, opts: &BagOptions) -> Result<logs::RawLog, String> {
    logs::read_robot_log(path, &LogLayout::ur10e(), opts, &names()).map_err(|e| e.to_string())
}

#[test]
fn a_db3_bag_reads_the_same_samples_as_its_csv() {
    let path = fixture("default.db3");
    assert!(rosbag::is_db3(&path) && rosbag::is_bag(&path));
    let log = read(&path, &BagOptions::default()).unwrap();
    assert_same_samples(&log);
    assert!(log.notes.is_empty(), "{:?}", log.notes);
}

#[test]
fn a_split_rosbag2_folder_with_ur_names_reads_through_a_joint_map() {
    let dir = fixture("ur_split");
    let e = read(&dir, &BagOptions::default()).unwrap_err();
    assert!(
        e.contains("ur_split, topic /joint_states, message 1, field name: no joint 'shoulder_pan'")
            && e.contains("shoulder_pan_joint")
            && e.contains("--joint-map"),
        "{e}"
    );
    let text = "# UR ROS 2 driver names\nshoulder_pan_joint=shoulder_pan, shoulder_lift_joint=shoulder_lift\nelbow_joint=elbow,wrist_1_joint=wrist_1\nwrist_2_joint=wrist_2,wrist_3_joint=wrist_3\n";
    let map = rosbag::parse_joint_map(text).unwrap();
    assert_eq!(map, ur_map());
    let opts = BagOptions {
        joint_map: map,
        ..BagOptions::default()
    };
    let log = read(&dir, &opts).unwrap();
    assert_same_samples(&log);
    // The folder's hash covers its metadata and both files.
    assert_eq!(log.sha256.len(), 64);
    for bad in ["a", "a=b=c", "a=b,a=c", "a=c,b=c", "=b"] {
        assert!(rosbag::parse_joint_map(bad).is_err(), "{bad}");
    }
}

/// A copy of the split folder in a scratch folder, `edit`ed, read with the UR map.
fn edited_folder(edit: impl Fn(&Path)) -> (tempfile::TempDir, String) {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path().join("bag");
    std::fs::create_dir(&d).unwrap();
    for f in ["metadata.yaml", "ur_split_0.mcap", "ur_split_1.mcap"] {
        std::fs::copy(fixture("ur_split").join(f), d.join(f)).unwrap();
    }
    edit(&d);
    let opts = BagOptions {
        joint_map: ur_map(),
        ..BagOptions::default()
    };
    let e = match read(&d, &opts) {
        Ok(l) => panic!("read {} samples", l.len()),
        Err(e) => e,
    };
    (tmp, e)
}

#[test]
fn broken_rosbag2_folders_are_refused_naming_the_file() {
    let meta = |d: &Path, from: &str, to: &str| {
        let p = d.join("metadata.yaml");
        let t = std::fs::read_to_string(&p).unwrap();
        assert!(t.contains(from), "{from}");
        std::fs::write(&p, t.replace(from, to)).unwrap();
    };
    let (_t, e) = edited_folder(|d| std::fs::remove_file(d.join("metadata.yaml")).unwrap());
    assert!(e.contains("bag: a folder without metadata.yaml"), "{e}");
    let (_t, e) = edited_folder(|d| std::fs::remove_file(d.join("ur_split_1.mcap")).unwrap());
    assert!(e.contains("bag/ur_split_1.mcap: cannot read"), "{e}");
    let (_t, e) = edited_folder(|d| meta(d, "- ur_split_1.mcap", "- ../ur_split_1.mcap"));
    assert!(
        e.contains("metadata.yaml, rosbag2_bagfile_information.relative_file_paths[1]: '../ur_split_1.mcap' is not a path inside"),
        "{e}"
    );
    let (_t, e) = edited_folder(|d| {
        meta(
            d,
            "storage_identifier: mcap",
            "storage_identifier: cassette",
        )
    });
    assert!(e.contains("storage 'cassette'"), "{e}");
    let (_t, e) = edited_folder(|d| meta(d, "relative_file_paths:", "relative_file_pathz:"));
    assert!(
        e.contains("metadata.yaml") && e.contains("not a rosbag2 metadata file"),
        "{e}"
    );
    // The parts in the wrong order: time goes back at the second file's first message.
    let (_t, e) = edited_folder(|d| {
        meta(
            d,
            "- ur_split_0.mcap\n  - ur_split_1.mcap",
            "- ur_split_1.mcap\n  - ur_split_0.mcap",
        )
    });
    assert!(
        e.contains("bag/ur_split_0.mcap, topic /joint_states, message 502, field header.stamp: stamps not strictly increasing"),
        "{e}"
    );
    // The second part cut short (rosbags writes no CRCs to check: the structure tells).
    let (_t, e) = edited_folder(|d| {
        let p = d.join("ur_split_1.mcap");
        let b = std::fs::read(&p).unwrap();
        std::fs::write(&p, &b[..b.len() - 100]).unwrap();
    });
    assert!(
        e.contains("bag/ur_split_1.mcap: corrupt or truncated MCAP file"),
        "{e}"
    );
}

/// The offset of the first chunk record's body in an MCAP file.
fn first_chunk_body(b: &[u8]) -> usize {
    let mut at = 8;
    loop {
        let op = b[at];
        let len = u64::from_le_bytes(b[at + 1..at + 9].try_into().unwrap()) as usize;
        if op == 0x06 {
            return at + 9;
        }
        at += 9 + len;
    }
}

#[test]
fn a_flipped_byte_in_a_chunk_is_refused_or_changes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    for name in [
        "joint_states.mcap",
        "two_publishers.mcap",
        "zero_stamps.mcap",
    ] {
        let b = std::fs::read(fixture(name)).unwrap();
        let opts = BagOptions {
            time_source: if name == "zero_stamps.mcap" {
                TimeSource::Log
            } else {
                TimeSource::Header
            },
            ..BagOptions::default()
        };
        let p = dir.path().join(name);
        let good = read(&fixture(name), &opts).unwrap();
        let body = first_chunk_body(&b);
        // The chunk's records (after its start and end times, sizes, CRC and compression
        // name, which index the chunk and are not read as data).
        let clen = u32::from_le_bytes(b[body + 28..body + 32].try_into().unwrap()) as usize;
        let rec = body + 32 + clen + 8;
        let len = u64::from_le_bytes(b[rec - 8..rec].try_into().unwrap()) as usize;
        // Every 97th byte of the first chunk's records, each flipped alone: refused, or
        // (when the compressed stream decodes to the same records) read unchanged.
        let (mut refused, mut same) = (0, 0);
        for at in (rec..rec + len).step_by(97) {
            let mut c = b.clone();
            c[at] ^= 0x10;
            std::fs::write(&p, &c).unwrap();
            match read(&p, &opts) {
                Ok(l) => {
                    assert!(
                        l.time_s == good.time_s
                            && l.q_rad == good.q_rad
                            && l.torque_nm == good.torque_nm,
                        "{name}: byte {at} flipped, read with other values"
                    );
                    same += 1;
                }
                Err(e) => {
                    assert!(e.contains(name) && e.contains("MCAP"), "{e}");
                    refused += 1;
                }
            }
        }
        println!("{name}: {refused} flips refused, {same} decoded to the same records");
        assert!(refused > 10 * same, "{refused} refused, {same} unchanged");
    }
}

#[test]
fn two_publishers_are_merged_by_joint_name_and_the_gripper_dropped() {
    let log = read(&fixture("two_publishers.mcap"), &BagOptions::default()).unwrap();
    assert_same_samples(&log);
    let notes = log.notes.join("\n");
    assert!(
        notes.contains(
            "dropped 500 messages of /joint_states naming no robot joint ([gripper_finger_joint]"
        ) && notes.contains("merged 2 publishers of /joint_states by joint name")
            && notes.contains("0 of its samples outside their common time span dropped"),
        "{notes}"
    );
}

#[test]
fn publishers_at_other_times_are_interpolated_onto_the_time_base() {
    let dir = tempfile::tempdir().unwrap();
    // Joints 1-3 every 10 ms; joints 4-6 every 20 ms, 5 ms later, as another publisher.
    let mut msgs = Vec::new();
    for k in 0..40usize {
        let mut a = bags::joint_state(k);
        a.name.truncate(3);
        a.position.truncate(3);
        a.velocity.truncate(3);
        a.effort.truncate(3);
        msgs.push(bags::cdr(&a));
        if k % 2 == 0 {
            let mut b = bags::joint_state(k);
            b.header.stamp.nanosec += 5_000_000;
            b.name.drain(..3);
            b.position = (3..6)
                .map(|j| 0.1 * j as f64 + 0.01 * k as f64 + 0.005)
                .collect();
            b.velocity.drain(..3);
            b.effort.drain(..3);
            msgs.push(bags::cdr(&b));
        }
    }
    let p = dir.path().join("merge.mcap");
    std::fs::write(&p, bag("/joint_states", &msgs)).unwrap();
    let log = read(&p, &BagOptions::default()).unwrap();
    // Base: the 40 messages of joints 1-3; kept from the first (5 ms) to the last (395 ms)
    // sample of the other: messages 2..=39 of the base.
    assert_eq!(log.len(), 38, "{:?}", log.notes);
    for (i, t) in log.time_s.iter().enumerate() {
        assert!((t - 0.01 * i as f64).abs() < 1e-12);
        // Joint 4 moves 0.01 rad per 10 ms: interpolated exactly (up to rounding).
        let k = i + 1;
        assert!(
            (log.q_rad[3][i] - (0.3 + 0.01 * k as f64)).abs() < 1e-12,
            "{i}"
        );
        assert_eq!(log.q_rad[0][i], 0.01 * k as f64);
    }
    assert!(
        log.notes[0].contains("2 of its samples outside their common time span dropped"),
        "{:?}",
        log.notes
    );
    // The same joint from two publishers is ambiguous.
    let twice = [bags::cdr(&bags::joint_state(0)), {
        let mut m = bags::joint_state(1);
        m.name.truncate(3);
        m.position.truncate(3);
        m.velocity.truncate(3);
        m.effort.truncate(3);
        bags::cdr(&m)
    }];
    std::fs::write(&p, bag("/joint_states", &twice)).unwrap();
    let e = read(&p, &BagOptions::default()).unwrap_err();
    assert!(
        e.contains("message 2, field name: joint 'shoulder_pan' in two sets of names"),
        "{e}"
    );
}

#[test]
fn zero_stamps_need_the_log_time() {
    let p = fixture("zero_stamps.mcap");
    let e = read(&p, &BagOptions::default()).unwrap_err();
    assert!(
        e.contains("zero_stamps.mcap, topic /joint_states, message 2, field header.stamp: stamps not strictly increasing: 0.000000000 s after 0.000000000 s in message 1")
            && e.contains("--time-source log"),
        "{e}"
    );
    let opts = BagOptions {
        time_source: TimeSource::Log,
        ..BagOptions::default()
    };
    assert_same_samples(&read(&p, &opts).unwrap());
}

#[test]
fn logged_velocities_asked_of_a_bag_without_them_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("noqd.mcap");
    std::fs::write(
        &p,
        bag("/joint_states", &messages(|_, m| m.velocity.clear())),
    )
    .unwrap();
    let raw = read(&p, &BagOptions::default()).unwrap();
    assert!(raw.qd_rad_s.is_none());
    let pre = PreprocessOptions {
        use_logged_qd: true,
        trim_rest_rad_s: None,
        ..PreprocessOptions::default()
    };
    let e = preprocess(&raw, &pre).unwrap_err().to_string();
    assert!(e.contains("noqd.mcap, velocity: logged velocities asked for (--use-logged-qd) but the log has none"), "{e}");
    assert!(
        preprocess(
            &raw,
            &PreprocessOptions {
                use_logged_qd: false,
                ..pre
            }
        )
        .is_ok()
    );
}

/// The `(offset, length)` of every record inside the first chunk of an uncompressed MCAP
/// file, the offset of the chunk's outer length and of its records' length.
fn first_chunk_records(b: &[u8]) -> (Vec<(usize, usize)>, usize, usize) {
    let body = first_chunk_body(b);
    let clen = u32::from_le_bytes(b[body + 28..body + 32].try_into().unwrap()) as usize;
    assert_eq!(clen, 0, "an uncompressed chunk");
    let rlen_at = body + 32;
    let rlen = u64::from_le_bytes(b[rlen_at..rlen_at + 8].try_into().unwrap()) as usize;
    let (mut at, end, mut recs) = (rlen_at + 8, rlen_at + 8 + rlen, Vec::new());
    while at < end {
        let len = u64::from_le_bytes(b[at + 1..at + 9].try_into().unwrap()) as usize;
        recs.push((at, len));
        at += 9 + len;
    }
    assert_eq!(at, end);
    (recs, body - 8, rlen_at)
}

/// The `mcap` crate's linear reader subtracts each record's length from what remains of
/// its uncompressed chunk without checking it fits: a record running past its chunk's
/// records overflows that subtraction (a panic in a debug build, a wrapped count in a
/// release one). Such files are refused before the bytes reach it, also when the chunk
/// itself runs past the end of the file (the case the fuzz target found: the check then
/// stopped at the truncated chunk) and when the chunk sits after the data section's end
/// (the check stopped there; the fuzz target's second find), and one byte more or less in
/// a record's length is refused wherever the record sits in the chunk.
#[test]
fn a_record_overrunning_its_uncompressed_chunk_is_refused_not_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let name = "ur_split_0.mcap";
    let b = std::fs::read(fixture("ur_split").join(name)).unwrap();
    let (recs, outer_at, _) = first_chunk_records(&b);
    let p = dir.path().join(name);
    let set_u64 = |c: &mut [u8], at: usize, v: usize| {
        c[at..at + 8].copy_from_slice(&(v as u64).to_le_bytes());
    };
    let outer = u64::from_le_bytes(b[outer_at..outer_at + 8].try_into().unwrap()) as usize;
    let chunk_end = outer_at + 8 + outer;
    let mut cases = Vec::new();
    for (k, &(at, len)) in [recs[0], recs[recs.len() / 2], recs[recs.len() - 1]]
        .iter()
        .enumerate()
    {
        for delta in [1usize, 9, 1000] {
            // The record runs `delta` bytes past its chunk's records, in a whole chunk ...
            let mut c = b.clone();
            set_u64(&mut c, at + 1, len + delta + (chunk_end - at - 9 - len));
            cases.push((format!("record {k} +{delta}, whole chunk"), c.clone()));
            // ... and in a chunk declared to end past the end of the file (padding after
            // its records within the reader's length limit).
            set_u64(&mut c, outer_at, outer + (b.len() - chunk_end) + delta);
            cases.push((format!("record {k} +{delta}, chunk past the end"), c));
        }
        // One byte short: the next record starts inside this one.
        let mut c = b.clone();
        set_u64(&mut c, at + 1, len.saturating_sub(1));
        cases.push((format!("record {k} -1"), c));
    }
    // A chunk after the data section's end (the reader reads records there alike): the
    // first chunk, its first record overrunning, copied in after the DataEnd record.
    let mut at = 8;
    let data_end = loop {
        let len = u64::from_le_bytes(b[at + 1..at + 9].try_into().unwrap()) as usize;
        if b[at] == 0x0F {
            break at + 9 + len;
        }
        at += 9 + len;
    };
    let mut bad_chunk = b[outer_at - 1..chunk_end].to_vec();
    let first_at = recs[0].0;
    let rel = first_at - (outer_at - 1) + 1;
    bad_chunk[rel..rel + 8].copy_from_slice(&((chunk_end - first_at - 9 + 1) as u64).to_le_bytes());
    let mut c = b[..data_end].to_vec();
    c.extend_from_slice(&bad_chunk);
    c.extend_from_slice(&b[data_end..]);
    cases.push(("a chunk after the data end".into(), c));
    for (what, c) in &cases {
        std::fs::write(&p, c).unwrap();
        let r = std::panic::catch_unwind(|| read(&p, &BagOptions::default()));
        let e = match r {
            Err(_) => panic!("{what}: the reader panicked"),
            Ok(Ok(l)) => panic!("{what}: read {} samples", l.len()),
            Ok(Err(e)) => e,
        };
        assert!(e.contains(name) && e.contains("MCAP"), "{what}: {e}");
    }
}
