//! ROS 2 recordings: rosbag2 MCAP files of `sensor_msgs/msg/JointState` messages.
//!
//! One topic (default [`DEFAULT_TOPIC`]) is read in file order. Each message's
//! `header.stamp` is its time (relative to the first message's stamp, in exact integer
//! nanoseconds before the conversion to seconds), `position[]` the joint positions [rad],
//! `velocity[]` (if the recording has it) the velocities [rad/s], and `effort[]` the
//! joint torques [N·m], or motor currents [A] when drive gains are given. Joints are
//! matched by name to the robot's joints, in any order; further names in a message (a
//! gripper's fingers) are ignored. Messages are CDR-encoded (little or big endian), as
//! every ROS 2 middleware records them.
//!
//! Errors name the file, the topic, the message (1-based number on its topic) and the
//! field; a log read from a bag records that number where a CSV log records its line.

use super::{LogError, RawLog, sha256_hex};
use serde::Deserialize;
use std::collections::HashMap;
use std::path::Path;

/// The topic `ros2 bag record` writes `sensor_msgs/msg/JointState` to by default.
pub const DEFAULT_TOPIC: &str = "/joint_states";

/// The message type read.
pub const JOINT_STATE_SCHEMA: &str = "sensor_msgs/msg/JointState";

/// The first bytes of every MCAP file.
pub const MCAP_MAGIC: &[u8] = b"\x89MCAP0\r\n";

/// How to read a ROS 2 recording.
#[derive(Debug, Clone, PartialEq)]
pub struct BagOptions {
    /// The `sensor_msgs/msg/JointState` topic.
    pub topic: String,
    /// Drive gains [N·m/A] per robot joint: `effort[]` is then motor current [A] and the
    /// torque is current × gain; `None`: `effort[]` is joint torque [N·m].
    pub drive_gains_nm_per_a: Option<Vec<f64>>,
}

impl Default for BagOptions {
    fn default() -> Self {
        Self {
            topic: DEFAULT_TOPIC.to_string(),
            drive_gains_nm_per_a: None,
        }
    }
}

/// True when `path` names an MCAP file: by its extension (`.mcap`), else by its first
/// bytes (an unreadable file is not one; reading it later names the error).
pub fn is_mcap(path: &Path) -> bool {
    if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("mcap"))
    {
        return true;
    }
    let mut head = [0u8; 8];
    std::fs::File::open(path)
        .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut head))
        .is_ok_and(|()| head == MCAP_MAGIC)
}

/// `builtin_interfaces/msg/Time`.
#[derive(Debug, Deserialize)]
struct Time {
    sec: i32,
    nanosec: u32,
}

/// `std_msgs/msg/Header`.
#[derive(Debug, Deserialize)]
struct Header {
    stamp: Time,
    #[allow(dead_code)] // decoded to reach the fields after it
    frame_id: String,
}

/// `sensor_msgs/msg/JointState`.
#[derive(Debug, Deserialize)]
struct JointState {
    header: Header,
    name: Vec<String>,
    position: Vec<f64>,
    velocity: Vec<f64>,
    effort: Vec<f64>,
}

/// Decodes one CDR-encoded `JointState` (4-byte encapsulation header, then the message
/// aligned relative to its end).
fn decode_joint_state(data: &[u8]) -> Result<JointState, String> {
    use cdr_encoding::from_bytes;
    let (head, body) = data.split_at_checked(4).ok_or_else(|| {
        format!(
            "{} bytes: shorter than the CDR encapsulation header",
            data.len()
        )
    })?;
    let decoded = match [head[0], head[1]] {
        [0, 0] => from_bytes::<JointState, byteorder::BigEndian>(body),
        [0, 1] => from_bytes::<JointState, byteorder::LittleEndian>(body),
        other => {
            return Err(format!(
                "encapsulation {other:02x?} is not plain CDR (00 00 or 00 01)"
            ));
        }
    };
    decoded
        .map(|(m, _)| m)
        .map_err(|e| format!("not a CDR-encoded {JOINT_STATE_SCHEMA}: {e}"))
}

/// Reads the `JointState` messages of one topic of a rosbag2 MCAP file into a log of the
/// robot joints `joint_names` (in the robot's order).
pub fn read_bag(
    path: &Path,
    opts: &BagOptions,
    joint_names: &[String],
) -> Result<RawLog, LogError> {
    let bytes = std::fs::read(path)
        .map_err(|e| LogError::new(path, None, None, format!("cannot read: {e}")))?;
    parse_bag(path, &bytes, opts, joint_names)
}

/// [`read_bag`] on the file's bytes (`path` names it in errors).
pub fn parse_bag(
    path: &Path,
    bytes: &[u8],
    opts: &BagOptions,
    joint_names: &[String],
) -> Result<RawLog, LogError> {
    let topic = &opts.topic;
    let n = joint_names.len();
    let err = |msg_no: Option<u64>, field: Option<String>, message: String| {
        let at = match (msg_no, field) {
            (Some(k), Some(f)) => format!("topic {topic}, message {k}, field {f}"),
            (Some(k), None) => format!("topic {topic}, message {k}"),
            (None, Some(f)) => format!("topic {topic}, field {f}"),
            (None, None) => format!("topic {topic}"),
        };
        LogError::new(path, None, Some(at), message)
    };
    if n == 0 {
        return Err(err(None, None, "the robot has no joints to read".into()));
    }
    if let Some(g) = &opts.drive_gains_nm_per_a
        && g.len() != n
    {
        return Err(LogError::new(
            path,
            None,
            Some("drive gains".into()),
            format!("{} drive gains given for {n} robot joints", g.len()),
        ));
    }
    let stream = mcap::MessageStream::new(bytes)
        .map_err(|e| LogError::new(path, None, None, format!("not an MCAP file: {e}")))?;

    let mut out = RawLog {
        path: path.to_path_buf(),
        sha256: sha256_hex(bytes),
        time_s: Vec::new(),
        q_rad: vec![Vec::new(); n],
        qd_rad_s: None,
        qdd_rad_s2: None,
        current_a: None,
        drive_gains_nm_per_a: opts.drive_gains_nm_per_a.clone(),
        torque_nm: None,
        lines: Vec::new(),
    };
    let mut topics: Vec<String> = Vec::new();
    let mut first_ns: Option<i128> = None;
    let mut prev_ns: Option<(i128, u64)> = None;
    // Index of each robot joint in the message's arrays; recomputed when name[] changes.
    let mut names_seen: Vec<String> = Vec::new();
    let mut index: Vec<usize> = Vec::new();
    let mut count = 0u64;
    for m in stream {
        let m = m.map_err(|e| {
            let after = match count {
                0 => String::new(),
                k => format!(" (after message {k} of {topic})"),
            };
            LogError::new(
                path,
                None,
                None,
                format!("corrupt or truncated MCAP file{after}: {e}"),
            )
        })?;
        if m.channel.topic != *topic {
            if !topics.contains(&m.channel.topic) {
                topics.push(m.channel.topic.clone());
            }
            continue;
        }
        count += 1;
        let k = count;
        if count == 1 {
            let schema = m.channel.schema.as_ref().map(|s| s.name.as_str());
            if schema.is_some_and(|s| s != JOINT_STATE_SCHEMA) {
                return Err(err(
                    None,
                    None,
                    format!(
                        "message type {}, expected {JOINT_STATE_SCHEMA}",
                        schema.unwrap_or_default()
                    ),
                ));
            }
            if m.channel.message_encoding != "cdr" {
                return Err(err(
                    None,
                    None,
                    format!(
                        "message encoding '{}', expected 'cdr' (a ROS 2 recording)",
                        m.channel.message_encoding
                    ),
                ));
            }
        }
        let js = decode_joint_state(&m.data).map_err(|e| err(Some(k), None, e))?;

        // Time: header.stamp, strictly increasing.
        let st = &js.header.stamp;
        if st.nanosec >= 1_000_000_000 {
            return Err(err(
                Some(k),
                Some("header.stamp.nanosec".into()),
                format!("{} is not below 1e9", st.nanosec),
            ));
        }
        let ns = i128::from(st.sec) * 1_000_000_000 + i128::from(st.nanosec);
        if let Some((p, pk)) = prev_ns
            && ns <= p
        {
            return Err(err(
                Some(k),
                Some("header.stamp".into()),
                format!(
                    "stamps not strictly increasing: {}.{:09} s after {}.{:09} s in message {pk}",
                    st.sec,
                    st.nanosec,
                    p.div_euclid(1_000_000_000),
                    p.rem_euclid(1_000_000_000)
                ),
            ));
        }
        prev_ns = Some((ns, k));
        let t0 = *first_ns.get_or_insert(ns);
        // Exact integer nanoseconds since the first stamp, then one rounding.
        out.time_s.push((ns - t0) as f64 / 1e9);
        out.lines.push(k);

        // Joint names.
        if js.name != names_seen {
            let mut pos: HashMap<&str, usize> = HashMap::with_capacity(js.name.len());
            for (i, nm) in js.name.iter().enumerate() {
                if pos.insert(nm.as_str(), i).is_some() {
                    return Err(err(
                        Some(k),
                        Some(format!("name[{i}]")),
                        format!("joint '{nm}' appears twice"),
                    ));
                }
            }
            index = joint_names
                .iter()
                .map(|jn| {
                    pos.get(jn.as_str()).copied().ok_or_else(|| {
                        err(
                            Some(k),
                            Some("name".into()),
                            format!(
                                "no joint '{jn}' of the robot (robot joints: {}; message joints: {})",
                                joint_names.join(", "),
                                js.name.join(", ")
                            ),
                        )
                    })
                })
                .collect::<Result<_, _>>()?;
            names_seen = js.name.clone();
        }

        // Arrays: position always, velocity and effort as in the first message.
        let arrays: [(&str, &Vec<f64>); 3] = [
            ("position", &js.position),
            ("velocity", &js.velocity),
            ("effort", &js.effort),
        ];
        for (field, v) in arrays {
            let optional = field != "position";
            if !(v.len() == js.name.len() || (optional && v.is_empty())) {
                return Err(err(
                    Some(k),
                    Some(field.into()),
                    format!(
                        "{} values for {} names{}",
                        v.len(),
                        js.name.len(),
                        if optional { " (and not empty)" } else { "" }
                    ),
                ));
            }
        }
        if k == 1 {
            if !js.velocity.is_empty() {
                out.qd_rad_s = Some(vec![Vec::new(); n]);
            }
            if !js.effort.is_empty() {
                out.torque_nm = Some(vec![Vec::new(); n]);
                if opts.drive_gains_nm_per_a.is_some() {
                    out.current_a = Some(vec![Vec::new(); n]);
                }
            }
        } else {
            for (field, v, has) in [
                ("velocity", &js.velocity, out.qd_rad_s.is_some()),
                ("effort", &js.effort, out.torque_nm.is_some()),
            ] {
                if v.is_empty() == has {
                    return Err(err(
                        Some(k),
                        Some(field.into()),
                        format!(
                            "{} here, {} in message 1",
                            if has { "empty" } else { "present" },
                            if has { "present" } else { "empty" }
                        ),
                    ));
                }
            }
        }
        let value = |field: &str, v: &[f64], j: usize| -> Result<f64, LogError> {
            let i = index[j];
            let x = v[i];
            if x.is_finite() {
                Ok(x)
            } else {
                Err(err(
                    Some(k),
                    Some(format!("{field}[{i}] ('{}')", joint_names[j])),
                    format!("non-finite value {x}"),
                ))
            }
        };
        for j in 0..n {
            out.q_rad[j].push(value("position", &js.position, j)?);
            if let Some(qd) = out.qd_rad_s.as_mut() {
                qd[j].push(value("velocity", &js.velocity, j)?);
            }
            if let Some(tau) = out.torque_nm.as_mut() {
                let e = value("effort", &js.effort, j)?;
                match (&opts.drive_gains_nm_per_a, out.current_a.as_mut()) {
                    (Some(g), Some(cur)) => {
                        cur[j].push(e);
                        tau[j].push(e * g[j]);
                    }
                    _ => tau[j].push(e),
                }
            }
        }
    }
    if count == 0 {
        topics.sort();
        return Err(err(
            None,
            None,
            format!(
                "no messages on this topic (the bag has {}; choose one with --topic)",
                if topics.is_empty() {
                    "no messages".to_string()
                } else {
                    format!("topics {}", topics.join(", "))
                }
            ),
        ));
    }
    Ok(out)
}
