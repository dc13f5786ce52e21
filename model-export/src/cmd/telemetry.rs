//! `model-export telemetry`: what the drives did on the robot, from a `candump -l`
//! log of their CAN-FD state bus, as a log in the project's format (the `torque`
//! layout with a header), which `identify` and `torque --dataset` read, and so
//! `train` and `evaluate`.
//!
//! Every state frame is authenticated with the robot's bus key (the provisioning
//! key file) before it is used: a frame that fails (forged, altered, corrupted, cut
//! short) is counted and dropped, as on the drives. Times are the frames' own bus
//! times (authenticated), not candump's receive stamps; a frame not newer than its
//! joint's previous one (a replay, a duplicate) is counted and dropped.
use anyhow::{Context, Result, bail, ensure};
use clap::Args;
use firmware::control::FaultFlags;
use firmware::control::canfd::{
    CanFdFrame, FrameAuth, FrameError, MAX_JOINTS, STATE_ID_BASE, SYNC_ID, StateFrame, SyncFrame,
};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// `telemetry` options.
#[derive(Debug, Args)]
pub struct TelemetryArgs {
    /// The CAN-FD bus recording: a `candump -l` log (`(seconds) IFACE ID##F HEX`
    /// lines; classic `ID#HEX` frames are read too, and are no state frames).
    #[arg(long = "log", value_name = "FILE")]
    pub log: PathBuf,
    /// The robot's state-bus key: the key file given to `provision` (32 hex digits).
    #[arg(long)]
    pub key_file: PathBuf,
    /// The robot joint of each bus joint index, 1-based, in bus order (the compiled-in
    /// model's compensated joints; default: the default model's, 4,5,6).
    #[arg(long, value_delimiter = ',')]
    pub joints: Vec<usize>,
    /// Joints in the written log (the robot's joint count; the columns of the joints
    /// not on the bus hold their `--lock` angle, else 0 rad, as the drive's model does).
    #[arg(long, default_value_t = 6)]
    pub log_joints: usize,
    /// Joints not on the bus, held at an angle: J=RAD,... (1-based).
    #[arg(long, value_delimiter = ',')]
    pub lock: Vec<String>,
    /// The log to write (CSV): `t_s`, `q{j}_rad`, `qd{j}_rad_s`, `tau{j}_nm` for
    /// every joint, then per bus joint `ff{j}_nm` (its feedforward) and `faults{j}`
    /// (its compensator's fault flags).
    #[arg(long, short = 'o')]
    pub out: PathBuf,
}

/// One line of a `candump -l` log: the frame, or `None` for a line that is no data
/// frame of interest (an error frame, a remote frame). Errors name the field.
pub fn parse_candump_line(line: &str) -> Result<Option<CanFdFrame>> {
    let mut fields = line.split_whitespace();
    let stamp = fields.next().context("the receive time: missing")?;
    let ok_stamp = stamp.len() > 2
        && stamp.starts_with('(')
        && stamp.ends_with(')')
        && stamp[1..stamp.len() - 1]
            .parse::<f64>()
            .is_ok_and(f64::is_finite);
    ensure!(
        ok_stamp,
        "the receive time: `{stamp}` is not `(seconds.micros)`"
    );
    let _interface = fields.next().context("the interface: missing")?;
    let frame = fields.next().context("the frame: missing")?;
    ensure!(
        fields.next().is_none(),
        "after the frame: unexpected text (a `candump -l` line has three fields)"
    );
    let (id_hex, rest) = frame
        .split_once('#')
        .with_context(|| format!("the frame: `{frame}` has no `#`"))?;
    ensure!(
        !id_hex.is_empty() && id_hex.len() <= 8 && id_hex.chars().all(|c| c.is_ascii_hexdigit()),
        "the identifier: `{id_hex}` is not 1 to 8 hex digits"
    );
    let id = u32::from_str_radix(id_hex, 16).context("the identifier")?;
    if id & 0x2000_0000 != 0 {
        // SocketCAN's error-frame flag.
        return Ok(None);
    }
    let data = if let Some(fd) = rest.strip_prefix('#') {
        let mut chars = fd.chars();
        let flags = chars.next().context("the CAN-FD flags: missing")?;
        ensure!(
            flags.is_ascii_hexdigit(),
            "the CAN-FD flags: `{flags}` is not a hex digit"
        );
        chars.as_str()
    } else if rest.starts_with('R') || rest.starts_with('r') {
        return Ok(None);
    } else {
        rest
    };
    // Classic frames may separate bytes with dots.
    let hex: String = data.chars().filter(|&c| c != '.').collect();
    ensure!(
        hex.len().is_multiple_of(2)
            && hex.len() <= 128
            && hex.chars().all(|c| c.is_ascii_hexdigit()),
        "the data: `{data}` is not whole hex bytes (at most 64)"
    );
    let bytes: Vec<u8> = (0..hex.len() / 2)
        .map(|i| u8::from_str_radix(&hex[2 * i..2 * i + 2], 16))
        .collect::<std::result::Result<_, _>>()
        .context("the data")?;
    // An extended identifier (more than 3 digits, as candump writes them) is no
    // frame of the state bus.
    let id = if id_hex.len() > 3 || id > 0x7FF {
        0xFFFF
    } else {
        id as u16
    };
    Ok(CanFdFrame::new(id, &bytes))
}

/// One bus joint's accepted state frames: (bus time us, unwrapped, from the log's
/// first accepted frame), the frame.
type Track = Vec<(i64, StateFrame)>;

/// What a bus recording held.
#[derive(Debug, Default)]
pub struct BusRecording {
    /// Per bus joint index, its accepted frames in time order.
    pub tracks: Vec<Track>,
    /// State and SYNC frames that failed authentication (or their length).
    pub unauthenticated: usize,
    /// State frames not newer than their joint's previous (replays, duplicates).
    pub not_newer: usize,
    /// Authentic SYNC frames.
    pub syncs: usize,
    /// Frames of other identifiers (other traffic), and error or remote frames.
    pub other: usize,
}

/// Reads a `candump -l` log's text (`path` names it in errors) with the bus key.
pub fn read_bus(path: &Path, text: &str, auth: &FrameAuth) -> Result<BusRecording> {
    let mut rec = BusRecording::default();
    let mut base: Option<u32> = None;
    // Per joint: the latest accepted frame's unwrapped bus time and raw bus time.
    let mut last: Vec<Option<(i64, u32)>> = Vec::new();
    for (n, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let frame =
            parse_candump_line(line).with_context(|| format!("{}:{}", path.display(), n + 1))?;
        let Some(frame) = frame else {
            rec.other += 1;
            continue;
        };
        if frame.id == SYNC_ID {
            match SyncFrame::decode(auth, &frame) {
                Ok(_) => rec.syncs += 1,
                Err(_) => rec.unauthenticated += 1,
            }
            continue;
        }
        let joint = usize::from(frame.id.wrapping_sub(STATE_ID_BASE));
        if joint >= MAX_JOINTS {
            rec.other += 1;
            continue;
        }
        let f = match StateFrame::decode(auth, &frame) {
            Ok(f) => f,
            Err(FrameError::UnknownId) => {
                rec.other += 1;
                continue;
            }
            Err(_) => {
                rec.unauthenticated += 1;
                continue;
            }
        };
        let bus_us = f.message.timestamp_us;
        let b = *base.get_or_insert(bus_us);
        if last.len() <= joint {
            last.resize(joint + 1, None);
            rec.tracks.resize_with(joint + 1, Vec::new);
        }
        let t = match last[joint] {
            Some((t_prev, raw_prev)) => t_prev + i64::from(bus_us.wrapping_sub(raw_prev) as i32),
            None => i64::from(bus_us.wrapping_sub(b) as i32),
        };
        if let Some((t_prev, _)) = last[joint]
            && t <= t_prev
        {
            rec.not_newer += 1;
            continue;
        }
        last[joint] = Some((t, bus_us));
        rec.tracks[joint].push((t, f));
    }
    Ok(rec)
}

/// The log's rows: at every accepted frame time of the bus joint with the most
/// frames, each bus joint's frame of that tick (its latest within half a median
/// step); a tick where some joint has none (lost, dropped as unauthentic) is left out
/// (counted): a row never mixes ticks.
fn rows(tracks: &[Track]) -> (Vec<(i64, Vec<StateFrame>)>, usize) {
    let Some(reference) = (0..tracks.len()).max_by_key(|&k| (tracks[k].len(), usize::MAX - k))
    else {
        return (Vec::new(), 0);
    };
    let times: Vec<i64> = tracks[reference].iter().map(|(t, _)| *t).collect();
    let mut steps: Vec<i64> = times.windows(2).map(|w| w[1] - w[0]).collect();
    steps.sort_unstable();
    let step = steps.get(steps.len() / 2).copied().unwrap_or(1).max(1);
    let mut cursor = vec![0usize; tracks.len()];
    let mut out = Vec::with_capacity(times.len());
    let mut gaps = 0;
    for &t in &times {
        let mut row = Vec::with_capacity(tracks.len());
        let mut complete = true;
        for (k, track) in tracks.iter().enumerate() {
            while cursor[k] < track.len() && track[cursor[k]].0 <= t + step / 2 {
                cursor[k] += 1;
            }
            match cursor[k].checked_sub(1).map(|i| &track[i]) {
                Some((tk, f)) if t - tk <= step / 2 => row.push(*f),
                _ => complete = false,
            }
        }
        if complete {
            out.push((t, row));
        } else {
            gaps += 1;
        }
    }
    (out, gaps)
}

/// Runs `telemetry`.
pub fn run(a: &TelemetryArgs) -> Result<()> {
    let key_text = std::fs::read_to_string(&a.key_file)
        .with_context(|| format!("reading {}", a.key_file.display()))?;
    let key = super::provision::parse_key(&a.key_file, &key_text)?;
    let joints: Vec<usize> = if a.joints.is_empty() {
        firmware::model::default::JOINT_INDICES
            .iter()
            .map(|j| j + 1)
            .collect()
    } else {
        a.joints.clone()
    };
    ensure!(
        a.log_joints >= 1 && a.log_joints <= MAX_JOINTS,
        "--log-joints {}: 1 to {MAX_JOINTS}",
        a.log_joints
    );
    for (k, &j) in joints.iter().enumerate() {
        ensure!(
            (1..=a.log_joints).contains(&j),
            "--joints: joint {j} is not one of the log's {} joints (--log-joints)",
            a.log_joints
        );
        ensure!(
            !joints[..k].contains(&j),
            "--joints: joint {j} is given twice"
        );
    }
    let mut held = vec![0.0f64; a.log_joints];
    for (index, q_rad) in super::super::args::joints::lock_indices(&a.lock)? {
        ensure!(
            index < a.log_joints,
            "--lock: joint {} is not one of the log's {} joints",
            index + 1,
            a.log_joints
        );
        ensure!(
            !joints.contains(&(index + 1)),
            "--lock: joint {} is on the bus (--joints)",
            index + 1
        );
        held[index] = q_rad;
    }
    let bytes = std::fs::read(&a.log).with_context(|| format!("reading {}", a.log.display()))?;
    let text = String::from_utf8(bytes)
        .map_err(|e| anyhow::anyhow!("{}: not UTF-8 text: {e}", a.log.display()))?;
    let rec = read_bus(&a.log, &text, &FrameAuth::new(&key))?;
    if rec.tracks.len() > joints.len() {
        bail!(
            "{}: authentic state frames of bus joint index {} but --joints names {} joints ({:?})",
            a.log.display(),
            rec.tracks.len() - 1,
            joints.len(),
            joints
        );
    }
    for (k, &j) in joints.iter().enumerate() {
        if rec.tracks.get(k).is_none_or(Vec::is_empty) {
            bail!(
                "{}: no authentic state frame of joint {j} (bus joint index {k}); {} failed authentication (is --key-file the robot's?)",
                a.log.display(),
                rec.unauthenticated
            );
        }
    }
    let (rows, gaps) = rows(&rec.tracks);
    ensure!(
        rows.len() >= 2,
        "{}: fewer than two ticks heard from every joint",
        a.log.display()
    );
    let n = a.log_joints;
    let mut csv = String::from("t_s");
    for (prefix, suffix) in [("q", "_rad"), ("qd", "_rad_s"), ("tau", "_nm")] {
        for j in 1..=n {
            let _ = write!(csv, ",{prefix}{j}{suffix}");
        }
    }
    for &j in &joints {
        let _ = write!(csv, ",ff{j}_nm");
    }
    for &j in &joints {
        let _ = write!(csv, ",faults{j}");
    }
    csv.push('\n');
    let mut faults = vec![FaultFlags::NONE; joints.len()];
    let mut written = 0usize;
    let mut not_finite = 0usize;
    let t0 = rows.first().map_or(0, |r| r.0);
    for (t, row) in &rows {
        let mut q = held.clone();
        let (mut qd, mut tau) = (vec![0.0f64; n], vec![0.0f64; n]);
        for (k, f) in row.iter().enumerate() {
            let i = joints[k] - 1;
            let s = &f.message.state;
            q[i] = f64::from(s.q_meas_rad);
            qd[i] = f64::from(s.qd_meas_rad_s);
            tau[i] = f64::from(s.tau_meas_nm);
        }
        let ff: Vec<f64> = row.iter().map(|f| f64::from(f.feedforward_nm)).collect();
        // A drive with a failed sensor sends a non-finite state (authentic): the row
        // is left out, counted; the readers refuse non-finite cells.
        if q.iter()
            .chain(&qd)
            .chain(&tau)
            .chain(&ff)
            .any(|v| !v.is_finite())
        {
            not_finite += 1;
            continue;
        }
        let _ = write!(csv, "{:.6}", (t - t0) as f64 * 1e-6);
        for v in q.iter().chain(&qd).chain(&tau).chain(&ff) {
            let _ = write!(csv, ",{v}");
        }
        for (k, f) in row.iter().enumerate() {
            faults[k] |= f.faults;
            let _ = write!(csv, ",{}", f.faults.bits());
        }
        csv.push('\n');
        written += 1;
    }
    ensure!(
        written >= 2,
        "{}: fewer than two ticks with a finite state from every joint",
        a.log.display()
    );
    artifacts::write_atomic(&a.out, csv.as_bytes())?;
    println!(
        "{}: {written} ticks of joints {:?} ({} SYNC; {} state frames failed authentication, {} not newer than their joint's last, {} other frames; {gaps} ticks without every joint and {not_finite} with a non-finite state left out)",
        a.out.display(),
        joints,
        rec.syncs,
        rec.unauthenticated,
        rec.not_newer,
        rec.other
    );
    for (k, &j) in joints.iter().enumerate() {
        println!(
            "  joint {j}: {} frames, compensator faults seen {:#010x}",
            rec.tracks[k].len(),
            faults[k].bits()
        );
    }
    println!(
        "read it with: --layout torque --header yes --log-joints {n} (the `ff` and `faults` columns follow)"
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn candump_lines_parse_and_bad_fields_are_named() {
        let f = parse_candump_line("(1700000000.123456) can0 105##1AABB")
            .unwrap()
            .unwrap();
        assert_eq!((f.id, f.payload()), (0x105, &[0xAA, 0xBB][..]));
        let c = parse_candump_line("(0.5) vcan0 123#DEAD.BEEF")
            .unwrap()
            .unwrap();
        assert_eq!((c.id, c.len), (0x123, 4));
        assert!(parse_candump_line("(0.5) can0 123#R").unwrap().is_none());
        assert!(
            parse_candump_line("(0.5) can0 20000080#0000000000000000")
                .unwrap()
                .is_none()
        );
        // An extended identifier is no state-bus frame.
        let x = parse_candump_line("(0.5) can0 00000105#00")
            .unwrap()
            .unwrap();
        assert_eq!(x.id, 0xFFFF);
        for (bad, field) in [
            ("", "receive time"),
            ("0.5 can0 105##1AA", "receive time"),
            ("(x) can0 105##1AA", "receive time"),
            ("(0.5) can0", "frame"),
            ("(0.5) can0 105", "frame"),
            ("(0.5) can0 1G5##1AA", "identifier"),
            ("(0.5) can0 105##", "flags"),
            ("(0.5) can0 105##1AAB", "data"),
            ("(0.5) can0 105##1ZZ", "data"),
            ("(0.5) can0 105##1AA extra", "unexpected"),
        ] {
            let e = parse_candump_line(bad).unwrap_err().to_string();
            assert!(e.contains(field), "{bad}: {e}");
        }
        let long = format!("(0.5) can0 105##1{}", "00".repeat(65));
        assert!(parse_candump_line(&long).is_err());
    }
}
