//! ROS 2 recordings of `sensor_msgs/msg/JointState` messages: an MCAP file, a sqlite3
//! (`.db3`) file, or a rosbag2 folder (`metadata.yaml` and its storage files, split bags
//! read in the metadata's order).
//!
//! One topic (default [`DEFAULT_TOPIC`]) is read in file order (a `.db3` in timestamp
//! order, as `ros2 bag play` does). Each message's
//! `header.stamp` (or with [`TimeSource::Log`] the time the bag logged it) is its time
//! (relative to the first message's, in exact integer
//! nanoseconds before the conversion to seconds), `position[]` the joint positions [rad],
//! `velocity[]` (if the recording has it) the velocities [rad/s], and `effort[]` the
//! joint torques [N·m], or motor currents [A] when drive gains are given. Joints are
//! matched by name to the robot's joints, in any order; further names in a message (a
//! gripper's fingers) are ignored. Messages are CDR-encoded (little or big endian), as
//! every ROS 2 middleware records them. MCAP chunk, data-section and summary CRCs are
//! verified. Names are first renamed by the joint map ([`BagOptions::joint_map`]).
//! Several publishers on the topic (an arm and a gripper) are told apart by their set of
//! names and merged by joint name onto the time base of the one with most messages
//! (the others interpolated linearly; samples outside their common span dropped); what
//! was merged or dropped is reported in [`RawLog::notes`].
//!
//! Errors name the file, the topic, the message (1-based number on its topic) and the
//! field; a log read from a bag records that number where a CSV log records its line.

use super::{LogError, RawLog, sha256_hex};
use serde::Deserialize;
use sha2::{Digest, Sha256};
use std::borrow::Cow;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// The topic `ros2 bag record` writes `sensor_msgs/msg/JointState` to by default.
pub const DEFAULT_TOPIC: &str = "/joint_states";

/// The message type read.
pub const JOINT_STATE_SCHEMA: &str = "sensor_msgs/msg/JointState";

/// The first bytes of every MCAP file.
pub const MCAP_MAGIC: &[u8] = b"\x89MCAP0\r\n";

/// The first bytes of every SQLite database (a `.db3` bag).
pub const SQLITE_MAGIC: &[u8] = b"SQLite format 3\0";

/// The rosbag2 folder's description of its storage files.
pub const METADATA_FILE: &str = "metadata.yaml";

/// Largest rosbag2 storage file or folder read [bytes] (4 GiB), checked before reading.
pub const MAX_BAG_BYTES: u64 = 4 << 30;

/// Where a message's time comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TimeSource {
    /// `header.stamp`, as the publisher set it.
    #[default]
    Header,
    /// The time the recorder logged the message (MCAP `log_time`, `.db3` `timestamp`):
    /// for drivers whose stamps are zero or repeated.
    Log,
}

/// How to read a ROS 2 recording.
#[derive(Debug, Clone, PartialEq)]
pub struct BagOptions {
    /// The `sensor_msgs/msg/JointState` topic.
    pub topic: String,
    /// Drive gains [N·m/A] per robot joint: `effort[]` is then motor current [A] and the
    /// torque is current × gain; `None`: `effort[]` is joint torque [N·m].
    pub drive_gains_nm_per_a: Option<Vec<f64>>,
    /// Where each message's time comes from.
    pub time_source: TimeSource,
    /// Renames applied to `name[]` before matching: (name in the bag, robot joint name).
    pub joint_map: Vec<(String, String)>,
}

impl Default for BagOptions {
    /// The default topic, header stamps, torque effort and no joint map.
    fn default() -> Self {
        Self {
            topic: DEFAULT_TOPIC.to_string(),
            drive_gains_nm_per_a: None,
            time_source: TimeSource::Header,
            joint_map: Vec::new(),
        }
    }
}

/// Parses a joint map: `bag=robot` pairs separated by commas or new lines (a file's
/// text; blank lines and `#` comments skipped). Errors name the entry.
pub fn parse_joint_map(text: &str) -> Result<Vec<(String, String)>, String> {
    let mut out: Vec<(String, String)> = Vec::new();
    for (i, entry) in text
        .lines()
        .map(|l| l.split('#').next().unwrap_or(""))
        .flat_map(|l| l.split(','))
        .map(str::trim)
        .filter(|e| !e.is_empty())
        .enumerate()
    {
        let (from, to) = entry
            .split_once('=')
            .map(|(a, b)| (a.trim(), b.trim()))
            .filter(|(a, b)| !a.is_empty() && !b.is_empty() && !b.contains('='))
            .ok_or_else(|| {
                format!(
                    "joint map entry {} '{entry}': expected BAG_NAME=ROBOT_NAME",
                    i + 1
                )
            })?;
        if out.iter().any(|(a, _)| a == from) {
            return Err(format!(
                "joint map entry {} '{entry}': '{from}' mapped twice",
                i + 1
            ));
        }
        if out.iter().any(|(_, b)| b == to) {
            return Err(format!(
                "joint map entry {} '{entry}': two names mapped to '{to}'",
                i + 1
            ));
        }
        out.push((from.to_string(), to.to_string()));
    }
    Ok(out)
}

/// True when `path` names an MCAP file: by its extension (`.mcap`), else by its first
/// bytes (an unreadable file is not one; reading it later names the error).
pub fn is_mcap(path: &Path) -> bool {
    has_ext_or_magic(path, "mcap", MCAP_MAGIC)
}

/// True when `path` names a sqlite3 bag: by its extension (`.db3`), else by its first
/// bytes (the SQLite magic).
pub fn is_db3(path: &Path) -> bool {
    has_ext_or_magic(path, "db3", SQLITE_MAGIC)
}

/// True when `path` is a ROS 2 recording: a folder (a rosbag2 folder; reading it names
/// what is missing), an MCAP file or a `.db3` file.
pub fn is_bag(path: &Path) -> bool {
    path.is_dir() || is_mcap(path) || is_db3(path)
}

fn has_ext_or_magic(path: &Path, ext: &str, magic: &[u8]) -> bool {
    if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case(ext))
    {
        return true;
    }
    let mut head = vec![0u8; magic.len()];
    std::fs::File::open(path)
        .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut head))
        .is_ok_and(|()| head == magic)
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

/// One message of the topic, before decoding.
struct BagMessage<'a> {
    /// Index of the storage file it came from (into the list of files).
    file: usize,
    /// The time the recorder logged it [ns].
    log_time_ns: i128,
    /// CDR bytes.
    data: Cow<'a, [u8]>,
}

/// The messages of one topic of a recording, in order, and what else it had.
struct TopicMessages<'a> {
    /// The storage files (errors about a message name its file).
    files: Vec<PathBuf>,
    messages: Vec<BagMessage<'a>>,
    /// Other topics seen.
    other_topics: Vec<String>,
}

impl TopicMessages<'_> {
    fn note_topic(&mut self, t: &str) {
        if !self.other_topics.iter().any(|x| x == t) {
            self.other_topics.push(t.to_string());
        }
    }
}

/// Reads the `JointState` messages of one topic of a recording (a rosbag2 folder, an
/// MCAP file or a `.db3` file) into a log of the robot joints `joint_names` (in the
/// robot's order).
pub fn read_bag(
    path: &Path,
    opts: &BagOptions,
    joint_names: &[String],
) -> Result<RawLog, LogError> {
    if path.is_dir() {
        return read_bag_folder(path, opts, joint_names);
    }
    let bytes = read_limited(path)?;
    if is_db3(path) && !bytes.starts_with(MCAP_MAGIC) {
        parse_db3(path, &bytes, opts, joint_names)
    } else {
        parse_bag(path, &bytes, opts, joint_names)
    }
}

fn read_limited(path: &Path) -> Result<Vec<u8>, LogError> {
    let len = std::fs::metadata(path)
        .map_err(|e| LogError::new(path, None, None, format!("cannot read: {e}")))?
        .len();
    if len > MAX_BAG_BYTES {
        return Err(LogError::new(
            path,
            None,
            None,
            format!("{len} bytes: larger than the {MAX_BAG_BYTES} bytes read"),
        ));
    }
    std::fs::read(path).map_err(|e| LogError::new(path, None, None, format!("cannot read: {e}")))
}

/// [`read_bag`] on an MCAP file's bytes (`path` names it in errors).
pub fn parse_bag(
    path: &Path,
    bytes: &[u8],
    opts: &BagOptions,
    joint_names: &[String],
) -> Result<RawLog, LogError> {
    let mut tm = TopicMessages {
        files: vec![path.to_path_buf()],
        messages: Vec::new(),
        other_topics: Vec::new(),
    };
    mcap_messages(path, bytes, 0, &opts.topic, &mut tm)?;
    assemble(path, sha256_hex(bytes), tm, opts, joint_names)
}

/// [`read_bag`] on a `.db3` file's bytes (`path` names it in errors).
pub fn parse_db3(
    path: &Path,
    bytes: &[u8],
    opts: &BagOptions,
    joint_names: &[String],
) -> Result<RawLog, LogError> {
    let mut tm = TopicMessages {
        files: vec![path.to_path_buf()],
        messages: Vec::new(),
        other_topics: Vec::new(),
    };
    db3_messages(path, bytes, 0, &opts.topic, &mut tm)?;
    assemble(path, sha256_hex(bytes), tm, opts, joint_names)
}

/// Reads a rosbag2 folder: its `metadata.yaml`, then every storage file it lists.
pub fn read_bag_folder(
    dir: &Path,
    opts: &BagOptions,
    joint_names: &[String],
) -> Result<RawLog, LogError> {
    let meta_path = dir.join(METADATA_FILE);
    if !meta_path.is_file() {
        return Err(LogError::new(
            dir,
            None,
            None,
            format!("a folder without {METADATA_FILE}: not a rosbag2 folder"),
        ));
    }
    let meta = read_limited(&meta_path)?;
    let mut total = meta.len() as u64;
    parse_bag_folder(
        dir,
        &meta,
        &mut |rel| {
            let p = dir.join(rel);
            let len = std::fs::metadata(&p)
                .map_err(|e| format!("cannot read: {e}"))?
                .len();
            total = total.saturating_add(len);
            if total > MAX_BAG_BYTES {
                return Err(format!(
                    "the bag's files exceed the {MAX_BAG_BYTES} bytes read"
                ));
            }
            std::fs::read(&p).map_err(|e| format!("cannot read: {e}"))
        },
        opts,
        joint_names,
    )
}

/// The fields of `metadata.yaml` read.
#[derive(Debug, Deserialize)]
struct Metadata {
    rosbag2_bagfile_information: BagInfo,
}

#[derive(Debug, Deserialize)]
struct BagInfo {
    storage_identifier: String,
    relative_file_paths: Vec<String>,
}

/// [`read_bag_folder`] on the text of `metadata.yaml` and a loader of the storage files
/// it lists (by their relative path; an error is the loader's message).
pub fn parse_bag_folder(
    dir: &Path,
    metadata: &[u8],
    load: &mut dyn FnMut(&str) -> Result<Vec<u8>, String>,
    opts: &BagOptions,
    joint_names: &[String],
) -> Result<RawLog, LogError> {
    let meta_path = dir.join(METADATA_FILE);
    let info = serde_yaml_ng::from_slice::<Metadata>(metadata)
        .map_err(|e| {
            let line = e.location().map(|l| l.line() as u64);
            LogError::new(
                &meta_path,
                line,
                None,
                format!("not a rosbag2 metadata file: {e}"),
            )
        })?
        .rosbag2_bagfile_information;
    let field = |f: &str| Some(format!("rosbag2_bagfile_information.{f}"));
    let storage = info.storage_identifier.as_str();
    if storage != "mcap" && storage != "sqlite3" {
        return Err(LogError::new(
            &meta_path,
            None,
            field("storage_identifier"),
            format!("storage '{storage}': only mcap and sqlite3 are read"),
        ));
    }
    if info.relative_file_paths.is_empty() {
        return Err(LogError::new(
            &meta_path,
            None,
            field("relative_file_paths"),
            "no storage files listed",
        ));
    }
    let mut hasher = Sha256::new();
    hasher.update(metadata);
    let mut blobs = Vec::with_capacity(info.relative_file_paths.len().min(1024));
    let mut files = Vec::new();
    for (i, rel) in info.relative_file_paths.iter().enumerate() {
        let rp = Path::new(rel);
        let inside = !rel.is_empty()
            && rp
                .components()
                .all(|c| matches!(c, std::path::Component::Normal(_)));
        if !inside {
            return Err(LogError::new(
                &meta_path,
                None,
                field(&format!("relative_file_paths[{i}]")),
                format!("'{rel}' is not a path inside the bag folder"),
            ));
        }
        if files.iter().any(|f: &PathBuf| f == &dir.join(rp)) {
            return Err(LogError::new(
                &meta_path,
                None,
                field(&format!("relative_file_paths[{i}]")),
                format!("'{rel}' listed twice"),
            ));
        }
        let bytes = load(rel).map_err(|e| LogError::new(&dir.join(rp), None, None, e))?;
        hasher.update(&bytes);
        files.push(dir.join(rp));
        blobs.push(bytes);
    }
    let mut tm = TopicMessages {
        files: files.clone(),
        messages: Vec::new(),
        other_topics: Vec::new(),
    };
    for (i, bytes) in blobs.iter().enumerate() {
        if storage == "mcap" {
            mcap_messages(&files[i], bytes, i, &opts.topic, &mut tm)?;
        } else {
            db3_messages(&files[i], bytes, i, &opts.topic, &mut tm)?;
        }
    }
    let digest = hasher.finalize();
    let sha = digest.iter().map(|b| format!("{b:02x}")).collect();
    assemble(dir, sha, tm, opts, joint_names)
}

/// Checks an MCAP file's chunk, data-section and summary CRCs and its structure,
/// naming the chunk whose CRC fails.
fn verify_mcap(path: &Path, bytes: &[u8]) -> Result<(), LogError> {
    check_uncompressed_chunks(path, bytes)?;
    use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};
    let mut reader = LinearReader::new_with_options(
        LinearReaderOptions::default()
            .with_validate_chunk_crcs(true)
            .with_validate_data_section_crc(true)
            .with_validate_summary_section_crc(true)
            .with_record_length_limit(bytes.len()),
    );
    let mut fed = 0usize;
    while let Some(ev) = reader.next_event() {
        match ev {
            Ok(LinearReadEvent::ReadRequest(need)) => {
                let n = need.min(bytes.len() - fed);
                if n == 0 {
                    return Err(LogError::new(
                        path,
                        None,
                        None,
                        "corrupt or truncated MCAP file: ends inside a record",
                    ));
                }
                reader.insert(n).copy_from_slice(&bytes[fed..fed + n]);
                reader.notify_read(n);
                fed += n;
            }
            Ok(LinearReadEvent::Record { .. }) => {}
            Err(mcap::McapError::BadChunkCrc { saved, calculated }) => {
                let which = chunk_with_crc(bytes, saved)
                    .map(|k| format!("chunk {k}"))
                    .unwrap_or_else(|| "a chunk".into());
                return Err(LogError::new(
                    path,
                    None,
                    Some(which),
                    format!(
                        "corrupt MCAP file: CRC {calculated:08x} of the chunk's records, {saved:08x} recorded"
                    ),
                ));
            }
            Err(e) => {
                return Err(LogError::new(
                    path,
                    None,
                    None,
                    format!("corrupt or truncated MCAP file: {e}"),
                ));
            }
        }
    }
    Ok(())
}

/// Checks that every record inside an uncompressed chunk ends inside the chunk's records
/// (the `mcap` crate's linear reader subtracts each record's length from what remains of
/// the chunk unchecked, and overflows on such a file). Walks the bytes there are: a chunk
/// running past the end of the file is checked up to its last whole record header (the
/// reader streams into it record by record before it meets the end of the file), chunks
/// after the data section's end too (the reader descends into them alike), and everything
/// the walk cannot see (a truncated header, compressed records) is left to the reader,
/// which refuses it.
fn check_uncompressed_chunks(path: &Path, bytes: &[u8]) -> Result<(), LogError> {
    const CHUNK: u8 = 0x06;
    let u64_at = |b: &[u8], at: usize| -> Option<u64> {
        Some(u64::from_le_bytes(
            b.get(at..at.checked_add(8)?)?.try_into().ok()?,
        ))
    };
    let mut at = MCAP_MAGIC.len();
    let mut chunk = 0usize;
    while let (Some(&op), Some(len)) = (bytes.get(at), u64_at(bytes, at + 1)) {
        let start = at + 9;
        // The record's body as far as the file holds it.
        let end = usize::try_from(len)
            .ok()
            .and_then(|l| start.checked_add(l))
            .filter(|&e| e <= bytes.len());
        let body = &bytes[start.min(bytes.len())..end.unwrap_or(bytes.len())];
        if op == CHUNK {
            chunk += 1;
            let bad = |what: String| {
                LogError::new(
                    path,
                    None,
                    Some(format!("chunk {chunk}")),
                    format!("corrupt MCAP file: {what}"),
                )
            };
            let Some(clen) = body
                .get(28..32)
                .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            else {
                return Ok(()); // a truncated header: the reader names it
            };
            let Some(rlen_at) = 32usize.checked_add(clen as usize) else {
                return Ok(());
            };
            let Some(rlen) = u64_at(body, rlen_at) else {
                return Ok(());
            };
            if clen == 0 {
                // The reader reads a record's opcode and length even where they cross
                // the end of the chunk's records (from whatever bytes follow in the
                // file): so are they read here, from the file.
                let records_at = start + rlen_at + 8;
                let mut r = 0u64;
                while r < rlen {
                    if r.saturating_add(9) > rlen {
                        return Err(bad(format!(
                            "a record header at byte {r} of the chunk's {rlen} bytes of records runs past them"
                        )));
                    }
                    let Some(ilen) = usize::try_from(r)
                        .ok()
                        .and_then(|r| records_at.checked_add(r)?.checked_add(1))
                        .and_then(|at| u64_at(bytes, at))
                    else {
                        return Ok(()); // the file ends inside the chunk
                    };
                    let rec_end = r.checked_add(9).and_then(|e| e.checked_add(ilen));
                    if rec_end.is_none_or(|e| e > rlen) {
                        return Err(bad(format!(
                            "a record of {ilen} bytes at byte {r} of the chunk's {rlen} bytes of records runs past them"
                        )));
                    }
                    r = rec_end.unwrap_or(rlen);
                }
            }
        }
        let Some(next) = end else {
            return Ok(()); // a truncated record: the reader names it
        };
        at = next;
    }
    Ok(())
}

/// The 1-based number of the first chunk whose recorded CRC is `crc`.
fn chunk_with_crc(bytes: &[u8], crc: u32) -> Option<usize> {
    let mut k = 0;
    for r in mcap::read::LinearReader::new(bytes).ok()? {
        if let Ok(mcap::records::Record::Chunk { header, .. }) = r {
            k += 1;
            if header.uncompressed_crc == crc {
                return Some(k);
            }
        }
    }
    None
}

/// Appends the messages of `topic` in an MCAP file to `tm`, checking type and encoding.
fn mcap_messages<'a>(
    path: &Path,
    bytes: &'a [u8],
    file: usize,
    topic: &str,
    tm: &mut TopicMessages<'a>,
) -> Result<(), LogError> {
    verify_mcap(path, bytes)?;
    let stream =
        mcap::MessageStream::new_with_options(bytes, mcap::read::Options::ValidateChunkCrcs.into())
            .map_err(|e| LogError::new(path, None, None, format!("not an MCAP file: {e}")))?;
    let mut checked: Vec<u16> = Vec::new();
    for m in stream {
        let m = m.map_err(|e| {
            let after = match tm.messages.len() {
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
        if m.channel.topic != topic {
            tm.note_topic(&m.channel.topic);
            continue;
        }
        if !checked.contains(&m.channel.id) {
            let schema = m.channel.schema.as_ref().map(|s| s.name.as_str());
            check_type(path, topic, schema, &m.channel.message_encoding)?;
            checked.push(m.channel.id);
        }
        tm.messages.push(BagMessage {
            file,
            log_time_ns: i128::from(m.log_time),
            data: m.data,
        });
    }
    Ok(())
}

fn check_type(
    path: &Path,
    topic: &str,
    schema: Option<&str>,
    encoding: &str,
) -> Result<(), LogError> {
    let at = Some(format!("topic {topic}"));
    if schema.is_some_and(|s| s != JOINT_STATE_SCHEMA) {
        return Err(LogError::new(
            path,
            None,
            at,
            format!(
                "message type {}, expected {JOINT_STATE_SCHEMA}",
                schema.unwrap_or_default()
            ),
        ));
    }
    if encoding != "cdr" {
        return Err(LogError::new(
            path,
            None,
            at,
            format!("message encoding '{encoding}', expected 'cdr' (a ROS 2 recording)"),
        ));
    }
    Ok(())
}

/// Appends the messages of `topic` in a `.db3` (rosbag2 sqlite3 storage) to `tm`, in
/// timestamp order.
fn db3_messages(
    path: &Path,
    bytes: &[u8],
    file: usize,
    topic: &str,
    tm: &mut TopicMessages<'_>,
) -> Result<(), LogError> {
    use rusqlite::{Connection, MAIN_DB, OpenFlags};
    let sql = |e: rusqlite::Error| {
        LogError::new(
            path,
            None,
            None,
            format!("not a rosbag2 sqlite3 file (tables topics and messages): {e}"),
        )
    };
    if !bytes.starts_with(SQLITE_MAGIC) {
        return Err(LogError::new(
            path,
            None,
            None,
            "not an SQLite database (a .db3 bag starts with 'SQLite format 3')",
        ));
    }
    if bytes.len() >= i32::MAX as usize {
        return Err(LogError::new(
            path,
            None,
            None,
            "larger than 2 GiB: not read",
        ));
    }
    let mut db = Connection::open_in_memory_with_flags(
        OpenFlags::SQLITE_OPEN_READ_WRITE | OpenFlags::SQLITE_OPEN_NO_MUTEX,
    )
    .map_err(sql)?;
    db.deserialize_read_exact(MAIN_DB, bytes, bytes.len(), true)
        .map_err(sql)?;
    let mut ids = Vec::new();
    {
        let mut st = db
            .prepare("SELECT id, name, type, serialization_format FROM topics ORDER BY id")
            .map_err(sql)?;
        let mut rows = st.query([]).map_err(sql)?;
        while let Some(r) = rows.next().map_err(sql)? {
            let id: i64 = r.get(0).map_err(sql)?;
            let name: String = r.get(1).map_err(sql)?;
            if name != topic {
                tm.note_topic(&name);
                continue;
            }
            let ty: String = r.get(2).map_err(sql)?;
            let enc: String = r.get(3).map_err(sql)?;
            check_type(path, topic, Some(&ty), &enc)?;
            ids.push(id);
        }
    }
    for id in ids {
        let mut st = db
            .prepare(
                "SELECT timestamp, data FROM messages WHERE topic_id = ?1 ORDER BY timestamp, id",
            )
            .map_err(sql)?;
        let mut rows = st.query([id]).map_err(sql)?;
        while let Some(r) = rows.next().map_err(sql)? {
            let t: i64 = r.get(0).map_err(sql)?;
            let data: Vec<u8> = r.get(1).map_err(sql)?;
            tm.messages.push(BagMessage {
                file,
                log_time_ns: i128::from(t),
                data: Cow::Owned(data),
            });
        }
    }
    Ok(())
}

/// The samples of one publisher (one set of names) on the topic.
struct Stream {
    /// Its names, sorted (the key).
    key: Vec<String>,
    /// Names of its first message, in their order (for messages).
    first_names: Vec<String>,
    /// Topic message number of its first message.
    first_k: u64,
    time_ns: Vec<i128>,
    ks: Vec<u64>,
    /// Robot joint indices it carries, and per sample their values.
    joints: Vec<usize>,
    q: Vec<Vec<f64>>,
    qd: Option<Vec<Vec<f64>>>,
    effort: Option<Vec<Vec<f64>>>,
}

/// Decodes, checks and merges the topic's messages into a log.
fn assemble(
    path: &Path,
    sha256: String,
    tm: TopicMessages<'_>,
    opts: &BagOptions,
    joint_names: &[String],
) -> Result<RawLog, LogError> {
    let topic = &opts.topic;
    let n = joint_names.len();
    let err = |file: &Path, msg_no: Option<u64>, field: Option<String>, message: String| {
        let at = match (msg_no, field) {
            (Some(k), Some(f)) => format!("topic {topic}, message {k}, field {f}"),
            (Some(k), None) => format!("topic {topic}, message {k}"),
            (None, Some(f)) => format!("topic {topic}, field {f}"),
            (None, None) => format!("topic {topic}"),
        };
        LogError::new(file, None, Some(at), message)
    };
    if n == 0 {
        return Err(err(
            path,
            None,
            None,
            "the robot has no joints to read".into(),
        ));
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
    if tm.messages.is_empty() {
        let mut topics = tm.other_topics.clone();
        topics.sort();
        return Err(err(
            path,
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
    let robot_index: HashMap<&str, usize> = joint_names
        .iter()
        .enumerate()
        .map(|(j, s)| (s.as_str(), j))
        .collect();
    let rename: HashMap<&str, &str> = opts
        .joint_map
        .iter()
        .map(|(a, b)| (a.as_str(), b.as_str()))
        .collect();
    let mut streams: Vec<Stream> = Vec::new();
    // Cache: the last message's raw names, its stream and the array index of each of the
    // stream's joints.
    let mut last_names: Vec<String> = Vec::new();
    let mut last: Option<(usize, Vec<usize>)> = None;
    for (i, m) in tm.messages.iter().enumerate() {
        let k = i as u64 + 1;
        let file = tm.files[m.file].as_path();
        let js = decode_joint_state(&m.data).map_err(|e| err(file, Some(k), None, e))?;
        let st = &js.header.stamp;
        if st.nanosec >= 1_000_000_000 {
            return Err(err(
                file,
                Some(k),
                Some("header.stamp.nanosec".into()),
                format!("{} is not below 1e9", st.nanosec),
            ));
        }
        let ns = match opts.time_source {
            TimeSource::Header => i128::from(st.sec) * 1_000_000_000 + i128::from(st.nanosec),
            TimeSource::Log => m.log_time_ns,
        };
        for (field, v) in [
            ("position", &js.position),
            ("velocity", &js.velocity),
            ("effort", &js.effort),
        ] {
            let optional = field != "position";
            if !(v.len() == js.name.len() || (optional && v.is_empty())) {
                return Err(err(
                    file,
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
        if last.is_none() || js.name != last_names {
            let mut names: Vec<String> = Vec::with_capacity(js.name.len());
            for (a, nm) in js.name.iter().enumerate() {
                let mapped = rename.get(nm.as_str()).copied().unwrap_or(nm);
                if names.iter().any(|x| x == mapped) {
                    return Err(err(
                        file,
                        Some(k),
                        Some(format!("name[{a}]")),
                        format!("joint '{mapped}' appears twice"),
                    ));
                }
                names.push(mapped.to_string());
            }
            let mut key = names.clone();
            key.sort();
            let s = match streams.iter().position(|s| s.key == key) {
                Some(s) => s,
                None => {
                    let joints: Vec<usize> = names
                        .iter()
                        .filter_map(|x| robot_index.get(x.as_str()).copied())
                        .collect();
                    let mut joints = joints;
                    joints.sort_unstable();
                    streams.push(Stream {
                        key,
                        first_names: names.clone(),
                        first_k: k,
                        time_ns: Vec::new(),
                        ks: Vec::new(),
                        q: vec![Vec::new(); joints.len()],
                        qd: (!js.velocity.is_empty()).then(|| vec![Vec::new(); joints.len()]),
                        effort: (!js.effort.is_empty()).then(|| vec![Vec::new(); joints.len()]),
                        joints,
                    });
                    streams.len() - 1
                }
            };
            let idx = streams[s]
                .joints
                .iter()
                .map(|&j| names.iter().position(|x| *x == joint_names[j]).unwrap_or(0))
                .collect();
            last = Some((s, idx));
            last_names = js.name.clone();
        }
        let Some((s, idx)) = last.as_ref() else {
            continue;
        };
        let stream = &mut streams[*s];
        if let (Some(&p), Some(&pk)) = (stream.time_ns.last(), stream.ks.last())
            && ns <= p
        {
            let (field, hint) = match opts.time_source {
                TimeSource::Header => (
                    "header.stamp",
                    " (header stamps unusable? --time-source log times messages by when the bag logged them)",
                ),
                TimeSource::Log => ("log time", ""),
            };
            return Err(err(
                file,
                Some(k),
                Some(field.into()),
                format!(
                    "{} not strictly increasing: {}.{:09} s after {}.{:09} s in message {pk}{hint}",
                    if opts.time_source == TimeSource::Header {
                        "stamps"
                    } else {
                        "times"
                    },
                    ns.div_euclid(1_000_000_000),
                    ns.rem_euclid(1_000_000_000),
                    p.div_euclid(1_000_000_000),
                    p.rem_euclid(1_000_000_000)
                ),
            ));
        }
        for (field, v, has) in [
            ("velocity", &js.velocity, stream.qd.is_some()),
            ("effort", &js.effort, stream.effort.is_some()),
        ] {
            if v.is_empty() == has {
                return Err(err(
                    file,
                    Some(k),
                    Some(field.into()),
                    format!(
                        "{} here, {} in message {} (its publisher's first)",
                        if has { "empty" } else { "present" },
                        if has { "present" } else { "empty" },
                        stream.first_k
                    ),
                ));
            }
        }
        let value = |field: &str, v: &[f64], a: usize, j: usize| -> Result<f64, LogError> {
            let x = v[a];
            if x.is_finite() {
                Ok(x)
            } else {
                Err(err(
                    file,
                    Some(k),
                    Some(format!("{field}[{a}] ('{}')", joint_names[j])),
                    format!("non-finite value {x}"),
                ))
            }
        };
        for (c, (&j, &a)) in stream.joints.iter().zip(idx.iter()).enumerate() {
            stream.q[c].push(value("position", &js.position, a, j)?);
            if let Some(qd) = stream.qd.as_mut() {
                qd[c].push(value("velocity", &js.velocity, a, j)?);
            }
            if let Some(e) = stream.effort.as_mut() {
                e[c].push(value("effort", &js.effort, a, j)?);
            }
        }
        stream.time_ns.push(ns);
        stream.ks.push(k);
    }

    // Each robot joint from exactly one publisher.
    let mut owner = vec![usize::MAX; n];
    for (s, st) in streams.iter().enumerate() {
        for &j in &st.joints {
            if owner[j] != usize::MAX {
                let o = &streams[owner[j]];
                return Err(err(
                    path,
                    Some(st.first_k),
                    Some("name".into()),
                    format!(
                        "joint '{}' in two sets of names: [{}] (from message {}) and [{}]; a publisher's name[] must not change",
                        joint_names[j],
                        o.first_names.join(", "),
                        o.first_k,
                        st.first_names.join(", ")
                    ),
                ));
            }
            owner[j] = s;
        }
    }
    if let Some(j) = owner.iter().position(|&o| o == usize::MAX) {
        let mut seen: Vec<&str> = streams
            .iter()
            .flat_map(|s| s.first_names.iter().map(String::as_str))
            .collect();
        seen.dedup();
        let hint = if opts.joint_map.is_empty() {
            "; rename them with --joint-map BAG_NAME=ROBOT_NAME,..."
        } else {
            ""
        };
        return Err(err(
            path,
            Some(1),
            Some("name".into()),
            format!(
                "no joint '{}' of the robot (robot joints: {}; message joints: {}{hint})",
                joint_names[j],
                joint_names.join(", "),
                seen.join(", ")
            ),
        ));
    }
    let mut notes = Vec::new();
    let mut used: Vec<usize> = Vec::new();
    for (s, st) in streams.iter().enumerate() {
        if st.joints.is_empty() {
            notes.push(format!(
                "{}: dropped {} messages of {topic} naming no robot joint ([{}], another publisher)",
                path.display(),
                st.time_ns.len(),
                st.first_names.join(", ")
            ));
        } else {
            used.push(s);
        }
    }
    // The time base: the used publisher with most messages (the first on a tie).
    let base = used
        .iter()
        .copied()
        .rev()
        .max_by_key(|&s| streams[s].time_ns.len())
        .unwrap_or(0);
    let b = &streams[base];
    let lo = used
        .iter()
        .map(|&s| streams[s].time_ns[0])
        .max()
        .unwrap_or(0);
    let hi = used
        .iter()
        .map(|&s| *streams[s].time_ns.last().unwrap_or(&0))
        .min()
        .unwrap_or(0);
    let keep: Vec<usize> = (0..b.time_ns.len())
        .filter(|&i| used.len() == 1 || (b.time_ns[i] >= lo && b.time_ns[i] <= hi))
        .collect();
    if keep.is_empty() {
        return Err(err(
            path,
            None,
            Some("name".into()),
            "the publishers of the robot's joints never overlap in time: nothing to merge".into(),
        ));
    }
    let has_qd = used.iter().all(|&s| streams[s].qd.is_some());
    let has_effort = used.iter().all(|&s| streams[s].effort.is_some());
    let t0 = b.time_ns[keep[0]];
    let mut out = RawLog {
        path: path.to_path_buf(),
        sha256,
        // Exact integer nanoseconds since the first kept time, then one rounding.
        time_s: keep
            .iter()
            .map(|&i| (b.time_ns[i] - t0) as f64 / 1e9)
            .collect(),
        q_rad: vec![Vec::new(); n],
        qd_rad_s: has_qd.then(|| vec![Vec::new(); n]),
        qdd_rad_s2: None,
        current_a: (has_effort && opts.drive_gains_nm_per_a.is_some()).then(|| vec![Vec::new(); n]),
        drive_gains_nm_per_a: opts.drive_gains_nm_per_a.clone(),
        torque_nm: has_effort.then(|| vec![Vec::new(); n]),
        lines: keep.iter().map(|&i| b.ks[i]).collect(),
        notes: Vec::new(),
    };
    for &s in &used {
        let st = &streams[s];
        // Values of this publisher at the kept base times: its own samples for the
        // base, linear interpolation between its neighbouring samples otherwise.
        let sample = |series: &[f64]| -> Vec<f64> {
            if s == base {
                return keep.iter().map(|&i| series[i]).collect();
            }
            let mut a = 0usize;
            keep.iter()
                .map(|&i| {
                    let t = b.time_ns[i];
                    while a + 1 < st.time_ns.len() && st.time_ns[a + 1] <= t {
                        a += 1;
                    }
                    let (ta, ya) = (st.time_ns[a], series[a]);
                    if a + 1 >= st.time_ns.len() || t <= ta {
                        return ya;
                    }
                    let (tb, yb) = (st.time_ns[a + 1], series[a + 1]);
                    let w = (t - ta) as f64 / (tb - ta) as f64;
                    ya + w * (yb - ya)
                })
                .collect()
        };
        for (c, &j) in st.joints.iter().enumerate() {
            out.q_rad[j] = sample(&st.q[c]);
            if let (Some(dst), Some(src)) = (out.qd_rad_s.as_mut(), st.qd.as_ref()) {
                dst[j] = sample(&src[c]);
            }
            if let (Some(dst), Some(src)) = (out.torque_nm.as_mut(), st.effort.as_ref()) {
                let e = sample(&src[c]);
                match (&opts.drive_gains_nm_per_a, out.current_a.as_mut()) {
                    (Some(g), Some(cur)) => {
                        dst[j] = e.iter().map(|x| x * g[j]).collect();
                        cur[j] = e;
                    }
                    _ => dst[j] = e,
                }
            }
        }
    }
    if used.len() > 1 {
        let others: Vec<String> = used
            .iter()
            .filter(|&&s| s != base)
            .map(|&s| {
                format!(
                    "[{}] ({} messages)",
                    streams[s].first_names.join(", "),
                    streams[s].time_ns.len()
                )
            })
            .collect();
        notes.push(format!(
            "{}: merged {} publishers of {topic} by joint name: [{}] ({} messages) is the time base, {} interpolated linearly onto it; {} of its samples outside their common time span dropped",
            path.display(),
            used.len(),
            b.first_names.join(", "),
            b.time_ns.len(),
            others.join(", "),
            b.time_ns.len() - keep.len()
        ));
        for (field, has) in [("velocity", has_qd), ("effort", has_effort)] {
            if !has
                && used.iter().any(|&s| {
                    if field == "velocity" {
                        streams[s].qd.is_some()
                    } else {
                        streams[s].effort.is_some()
                    }
                })
            {
                notes.push(format!(
                    "{}: {field}[] dropped: empty in one of the merged publishers",
                    path.display()
                ));
            }
        }
    }
    out.notes = notes;
    Ok(out)
}
