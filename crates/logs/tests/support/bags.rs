//! Writes rosbag2 MCAP files of sensor_msgs/msg/JointState messages for the tests: the
//! default robot's joint names, one message per 10 ms, edited per test. Shared by the log
//! reader's tests and the command line's (`#[path]`-included, one source).
#![allow(dead_code)]

use byteorder::LittleEndian;
use logs::rosbag;
use serde::Serialize;
use std::collections::BTreeMap;
use std::io::Cursor;

/// The default robot's joint names, in order.
pub fn names() -> Vec<String> {
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

#[derive(Serialize, Clone)]
pub struct Time {
    pub sec: i32,
    pub nanosec: u32,
}

#[derive(Serialize, Clone)]
pub struct Header {
    pub stamp: Time,
    pub frame_id: String,
}

#[derive(Serialize, Clone)]
pub struct JointState {
    pub header: Header,
    pub name: Vec<String>,
    pub position: Vec<f64>,
    pub velocity: Vec<f64>,
    pub effort: Vec<f64>,
}

pub fn joint_state(k: usize) -> JointState {
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

pub fn cdr(m: &JointState) -> Vec<u8> {
    let mut v = vec![0, 1, 0, 0];
    v.extend(cdr_encoding::to_vec::<_, LittleEndian>(m).unwrap());
    v
}

/// A bag with the messages `msgs` (raw CDR bytes) on `topic`.
pub fn bag(topic: &str, msgs: &[Vec<u8>]) -> Vec<u8> {
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

pub fn messages(edit: impl Fn(usize, &mut JointState)) -> Vec<Vec<u8>> {
    (0..40)
        .map(|k| {
            let mut m = joint_state(k);
            edit(k, &mut m);
            cdr(&m)
        })
        .collect()
}
