//! Fuzz targets of every parser that reads outside input, and the seeded mutation loop
//! that runs them as bounded property tests on stable Rust.
//!
//! Each `*_target` function feeds one arbitrary input to one parser through its public
//! entry point and panics only when a property fails (a parsed value that is not finite,
//! a frame that does not round-trip); a parser's own error is the expected outcome of most
//! inputs. The `fuzz/` cargo-fuzz crate calls the same functions, and
//! `tests/fuzz_parsers.rs` runs them through [`run_bounded`] over the seed corpus in
//! `fuzz/corpus/<target>/` (the hostile cases among the seeds).
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::Path;
use std::time::{Duration, Instant};

/// Largest input the mutator produces [bytes] (cargo-fuzz's default `-max_len` is 4096;
/// the seeds are a few KiB).
pub const MAX_INPUT_BYTES: usize = 64 * 1024;

/// A case slower than this counts as a hang in [`FuzzReport::hangs`].
pub const HANG_AFTER: Duration = Duration::from_secs(5);

/// Numbers that broke or nearly broke a parser: overflow after scaling, `f32` edge,
/// huge counts, signed zero, non-finite spellings.
const HOSTILE_NUMBERS: &[&str] = &[
    "1e308",
    "-1e308",
    "1e300",
    "3e38",
    "3.5e38",
    "3e307",
    "0",
    "-0",
    "-1",
    "1e-320",
    "NaN",
    "inf",
    "-inf",
    "1e9",
    "1e12",
    "4294967296",
    "18446744073709551616",
    "9223372036854775807",
    "65535",
];

/// Structural tokens of the text formats (CSV, TOML, JSON, XML).
const TOKENS: &[&str] = &[
    "\n", ",", "\"", "[", "]", "{", "}", "=", ":", "<", ">", "/>", "-", ".", "e", "\r\n", "#",
    "\0", "\u{feff}",
];

/// The outcome of a bounded run of one target.
#[derive(Clone, Debug, PartialEq)]
pub struct FuzzReport {
    /// Target name.
    pub target: String,
    /// Cases run (the seeds themselves first, then mutants).
    pub cases: u64,
    /// Cases that panicked.
    pub panics: u64,
    /// Cases slower than [`HANG_AFTER`].
    pub hangs: u64,
    /// The slowest case [s].
    pub slowest_s: f64,
    /// The first panicking input, for a regression seed.
    pub first_panic: Option<Vec<u8>>,
}

/// One mutant of a corpus entry: 1 to 4 stacked edits (bit flips, byte sets, inserted
/// and deleted ranges, duplicated ranges, a number replaced by a hostile one, a splice
/// with another entry, a truncation, a structural token), at most [`MAX_INPUT_BYTES`].
pub fn mutate(rng: &mut ChaCha8Rng, corpus: &[Vec<u8>]) -> Vec<u8> {
    let mut d = corpus[rng.gen_range(0..corpus.len())].clone();
    for _ in 0..rng.gen_range(1..=4) {
        let len = d.len();
        let at = if len == 0 { 0 } else { rng.gen_range(0..len) };
        match rng.gen_range(0..10) {
            0 if len > 0 => d[at] ^= 1 << rng.gen_range(0..8),
            1 if len > 0 => d[at] = rng.r#gen(),
            2 => {
                let n = rng.gen_range(1..=8);
                for _ in 0..n {
                    d.insert(at, rng.r#gen());
                }
            }
            3 if len > 0 => {
                let end = (at + rng.gen_range(1..=16)).min(len);
                d.drain(at..end);
            }
            4 if len > 0 => {
                let end = (at + rng.gen_range(1..=256)).min(len);
                let copy = d[at..end].to_vec();
                let to = rng.gen_range(0..=len);
                d.splice(to..to, copy);
            }
            5 | 6 => replace_number(rng, &mut d),
            7 => {
                let other = &corpus[rng.gen_range(0..corpus.len())];
                let from = if other.is_empty() {
                    0
                } else {
                    rng.gen_range(0..other.len())
                };
                d.truncate(at);
                d.extend_from_slice(&other[from..]);
            }
            8 if len > 0 => d.truncate(at),
            _ => {
                let t = TOKENS[rng.gen_range(0..TOKENS.len())].as_bytes();
                d.splice(at..at, t.iter().copied());
            }
        }
    }
    d.truncate(MAX_INPUT_BYTES);
    d
}

/// Replaces one decimal number of `d` (digits with sign, point and exponent) by a
/// hostile one; inserts one when `d` has none.
fn replace_number(rng: &mut ChaCha8Rng, d: &mut Vec<u8>) {
    let is_num = |b: u8| b.is_ascii_digit() || matches!(b, b'.' | b'e' | b'E' | b'-' | b'+');
    let starts: Vec<usize> = (0..d.len())
        .filter(|&i| d[i].is_ascii_digit() && (i == 0 || !is_num(d[i - 1])))
        .collect();
    let new = HOSTILE_NUMBERS[rng.gen_range(0..HOSTILE_NUMBERS.len())].as_bytes();
    if starts.is_empty() {
        let at = rng.gen_range(0..=d.len());
        d.splice(at..at, new.iter().copied());
        return;
    }
    let mut s = starts[rng.gen_range(0..starts.len())];
    if s > 0 && d[s - 1] == b'-' {
        s -= 1;
    }
    let mut e = s + 1;
    while e < d.len() && is_num(d[e]) {
        e += 1;
    }
    d.splice(s..e, new.iter().copied());
}

/// Runs `target` on every seed and then on mutants until `cases` inputs ran, from
/// `seed`; catches and counts panics, times every case.
pub fn run_bounded(
    name: &str,
    corpus: &[Vec<u8>],
    cases: u64,
    seed: u64,
    mut target: impl FnMut(&[u8]),
) -> FuzzReport {
    assert!(!corpus.is_empty(), "{name}: empty seed corpus");
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut report = FuzzReport {
        target: name.to_string(),
        cases: 0,
        panics: 0,
        hangs: 0,
        slowest_s: 0.0,
        first_panic: None,
    };
    for k in 0..cases {
        let input = match corpus.get(k as usize) {
            Some(s) => s.clone(),
            None => mutate(&mut rng, corpus),
        };
        let start = Instant::now();
        let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| target(&input)));
        let took = start.elapsed();
        report.cases += 1;
        report.slowest_s = report.slowest_s.max(took.as_secs_f64());
        if took > HANG_AFTER {
            report.hangs += 1;
        }
        if r.is_err() {
            report.panics += 1;
            report.first_panic.get_or_insert(input);
        }
    }
    report
}

/// Reads the seed corpus folder `dir` (every file, sorted by name).
pub fn read_corpus(dir: &Path) -> std::io::Result<Vec<Vec<u8>>> {
    let mut paths: Vec<_> = std::fs::read_dir(dir)?
        .map(|e| e.map(|e| e.path()))
        .collect::<Result<_, _>>()?;
    paths.sort();
    paths.iter().map(std::fs::read).collect()
}

/// DH table in TOML: parse; a robot that parses has finite standard parameters.
pub fn dh_toml_target(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    if let Ok(robot) = robot::Robot::from_dh_toml_str(&text, "fuzz.toml") {
        check_robot(&robot);
    }
}

/// URDF: parse through the public entry point; a robot that parses has finite standard
/// parameters.
pub fn urdf_target(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    if let Ok(robot) = robot::Robot::from_urdf_str(&text, "fuzz.urdf") {
        check_robot(&robot);
    }
}

fn check_robot(robot: &robot::Robot) {
    let p = robot.standard_parameters();
    assert!(
        p.iter().all(|x| x.is_finite()),
        "a parsed robot with a non-finite parameter"
    );
}

/// Log CSV (`dir/log.csv`, two joints: time, q, qd, torque): read and preprocess as for
/// identification, and read as a training table; whatever is accepted is finite.
pub fn log_csv_target(dir: &Path, data: &[u8]) {
    let path = dir.join("log.csv");
    std::fs::write(&path, data).expect("fuzz scratch folder");
    let layout = logs::LogLayout::sequential(2, true, true, None);
    if let Ok(raw) = logs::read_log(&path, &layout)
        && let Ok(s) = logs::preprocess(&raw, &logs::PreprocessOptions::default())
    {
        for j in 0..s.n_joints() {
            let (mut q, mut qd, mut qdd) = ([0.0; 2], [0.0; 2], [0.0; 2]);
            for k in 0..s.len() {
                s.state(k, &mut q, &mut qd, &mut qdd);
                assert!(
                    q[j].is_finite() && qd[j].is_finite() && qdd[j].is_finite(),
                    "a preprocessed sample that is not finite"
                );
            }
        }
    }
    if let Ok(t) = compnet::data::Table::read(&path) {
        assert!(
            t.columns.iter().flatten().all(|v| v.is_finite()),
            "a non-finite table cell"
        );
    }
}

/// Identified model JSON (`dir/model.json`): read and check.
pub fn model_json_target(dir: &Path, data: &[u8]) {
    let path = dir.join("model.json");
    std::fs::write(&path, data).expect("fuzz scratch folder");
    let _ = identify::model_file::ModelFile::read(&path);
}

/// Network safetensors: parse; a model that parses streams finite outputs on a few
/// steps of bounded inputs.
pub fn safetensors_target(data: &[u8]) {
    if let Ok(m) = compnet::io::parse_model(data) {
        let inputs: Vec<Vec<f32>> = (0..3)
            .map(|k| (0..m.dims.input).map(|i| (k + i) as f32 * 0.1).collect())
            .collect();
        if let Ok(out) = m.stream(&inputs) {
            assert!(
                out.iter().flatten().all(|v| v.is_finite()),
                "a parsed network with non-finite outputs"
            );
        }
    }
}

/// Network ONNX (any exporter's variant): parse; a model that parses streams finite
/// outputs on a few steps of bounded inputs.
pub fn onnx_target(data: &[u8]) {
    if let Ok(m) = compnet::onnx::parse_onnx_model(data) {
        let inputs: Vec<Vec<f32>> = (0..3)
            .map(|k| (0..m.dims.input).map(|i| (k + i) as f32 * 0.1).collect())
            .collect();
        if let Ok(out) = m.stream(&inputs) {
            assert!(
                out.iter().flatten().all(|v| v.is_finite()),
                "a parsed ONNX network with non-finite outputs"
            );
        }
    }
}

/// Excitation JSON (`dir/exc.json`): load as a commanded trajectory (one period) and as
/// an excitation file; a trajectory that loads is finite over its whole period.
pub fn excitation_json_target(dir: &Path, data: &[u8]) {
    let path = dir.join("exc.json");
    std::fs::write(&path, data).expect("fuzz scratch folder");
    if let Ok(t) = plant_sim::trajectory::CommandedTrajectory::load(&path, 1) {
        let n = t.joint_count();
        let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let d = t.duration_s();
        assert!(d.is_finite() && d > 0.0, "a loaded trajectory of {d} s");
        for k in 0..=16 {
            t.eval_into(d / 16.0 * k as f64, &mut q, &mut qd, &mut qdd);
            assert!(
                q.iter().chain(&qd).chain(&qdd).all(|v| v.is_finite()),
                "a loaded trajectory with a non-finite point"
            );
        }
    }
    let _ = excitation::output::ExcitationFile::read(&path);
}

/// Flash budget TOML as `export --budgets` reads it (`dir/budgets.toml`).
pub fn budget_toml_target(dir: &Path, data: &[u8]) {
    let path = dir.join("budgets.toml");
    std::fs::write(&path, data).expect("fuzz scratch folder");
    let _ = fw_export::flash_budget(&path);
}

/// State-bus wire frames: the bytes through the firmware's frame receiver; every
/// message it yields encodes back to a frame that decodes to the same bits.
pub fn wire_frame_target(data: &[u8]) {
    use firmware::control::{FrameReceiver, JointStateMessage};
    let mut rx = FrameReceiver::new();
    for &b in data {
        if let Some(m) = rx.push(b) {
            let again = JointStateMessage::decode(&m.encode()).expect("a re-encoded frame");
            assert_eq!(
                (
                    again.joint,
                    again.session,
                    again.sequence,
                    again.timestamp_us
                ),
                (m.joint, m.session, m.sequence, m.timestamp_us)
            );
            let (a, b) = (again.state.to_array(), m.state.to_array());
            assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
        }
    }
    for w in data.windows(JointStateMessage::WIRE_LEN) {
        let _ = JointStateMessage::decode(w.try_into().expect("window length"));
    }
}

/// The joints the ROS 2 targets read (the default robot's, the UR driver's names mapped).
fn bag_joint_names() -> Vec<String> {
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

/// Bag options of the ROS 2 targets: the UR driver's names mapped to the robot's.
fn bag_options(time_source: logs::TimeSource) -> logs::BagOptions {
    logs::BagOptions {
        time_source,
        joint_map: bag_joint_names()
            .into_iter()
            .map(|n| (format!("{n}_joint"), n))
            .collect(),
        ..logs::BagOptions::default()
    }
}

/// What every accepted bag satisfies: one sample per message kept, time starting at 0
/// and strictly increasing, every value finite, every array one entry per sample.
fn check_bag_log(raw: &logs::RawLog) {
    let n = raw.len();
    assert!(
        n > 0 && raw.time_s[0] == 0.0,
        "a log not starting at time 0"
    );
    assert!(
        raw.time_s.windows(2).all(|w| w[1] > w[0]),
        "time not strictly increasing"
    );
    assert_eq!(raw.lines.len(), n);
    let series = raw
        .q_rad
        .iter()
        .chain(raw.qd_rad_s.iter().flatten())
        .chain(raw.torque_nm.iter().flatten());
    for s in series {
        assert_eq!(s.len(), n, "a joint series of another length");
        assert!(s.iter().all(|v| v.is_finite()), "a non-finite value");
    }
}

/// Splits `data` into u32-LE-length-prefixed parts (a short or overlong prefix ends the
/// list: the rest is the last part).
fn framed_parts(mut data: &[u8]) -> Vec<Vec<u8>> {
    let mut parts = Vec::new();
    while data.len() >= 4 {
        let len = u32::from_le_bytes([data[0], data[1], data[2], data[3]]) as usize;
        let body = &data[4..];
        let take = len.min(body.len());
        parts.push(body[..take].to_vec());
        data = &body[take..];
    }
    parts
}

/// rosbag2 folder: `data` is `metadata.yaml` then the storage files, each prefixed by its
/// u32 LE length; the files are served in the order the metadata asks for them. Read
/// with header stamps and with log time; whatever is accepted passes [`check_bag_log`].
pub fn rosbag2_folder_target(data: &[u8]) {
    let parts = framed_parts(data);
    let Some((meta, files)) = parts.split_first() else {
        return;
    };
    for ts in [logs::TimeSource::Header, logs::TimeSource::Log] {
        let mut next = 0usize;
        let mut load = |_: &str| -> Result<Vec<u8>, String> {
            next += 1;
            files
                .get(next - 1)
                .cloned()
                .ok_or_else(|| "no such file".to_string())
        };
        if let Ok(raw) = logs::rosbag::parse_bag_folder(
            Path::new("bag"),
            meta,
            &mut load,
            &bag_options(ts),
            &bag_joint_names(),
        ) {
            check_bag_log(&raw);
        }
    }
}

/// `.db3` (rosbag2 sqlite3 storage) bytes: read with header stamps and with log time;
/// whatever is accepted passes [`check_bag_log`].
pub fn db3_target(data: &[u8]) {
    for ts in [logs::TimeSource::Header, logs::TimeSource::Log] {
        if let Ok(raw) = logs::rosbag::parse_db3(
            Path::new("bag.db3"),
            data,
            &bag_options(ts),
            &bag_joint_names(),
        ) {
            check_bag_log(&raw);
        }
    }
}
