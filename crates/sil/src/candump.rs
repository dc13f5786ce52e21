//! The SIL's run in the drive's output format: the CAN-FD frames its boards would
//! send (`firmware::control::canfd`: SYNC and every joint's authenticated state frame
//! with its compensator flags and feedforward), as a `candump -l` log, the format
//! `model-export telemetry --log` reads from a real bus.

use firmware::control::canfd::{CanFdFrame, FrameAuth, StateFrame, SyncFrame};
use firmware::control::{FaultFlags, JointState, JointStateMessage};
use std::fmt::Write;

/// Interface name written in each line (`candump -l` writes the bus's).
pub const INTERFACE: &str = "can0";

/// One frame as a `candump -l` line: `(seconds.micros) can0 ID##F DATA` (CAN-FD,
/// flags `1` = bit-rate switch), `receive_s` the receive time, seconds.
pub fn line(receive_s: f64, frame: &CanFdFrame) -> String {
    let mut s = format!(
        "({:.6}) {INTERFACE} {:03X}##1",
        receive_s.max(0.0),
        frame.id
    );
    for b in frame.payload() {
        let _ = write!(s, "{b:02X}");
    }
    s
}

/// The frames a run's boards send, sealed with the robot's bus key, as `candump -l`
/// text: one SYNC per compensator tick (the bus time master's, before the tick's
/// state frames), then each board's state frame.
pub struct CandumpRecorder {
    auth: FrameAuth,
    session: u16,
    sync_counter: u16,
    sequences: Vec<u16>,
    last_sync_us: Option<u32>,
    text: String,
}

impl CandumpRecorder {
    /// A recorder sealing with `key`, the drives' session `session` (a drive draws
    /// one at every start; the recording's is given, for determinism).
    pub fn new(key: &[u8; 16], session: u16) -> Self {
        Self {
            auth: FrameAuth::new(key),
            session,
            sync_counter: 0,
            sequences: Vec::new(),
            last_sync_us: None,
            text: String::new(),
        }
    }

    fn push(&mut self, bus_us: u32, frame: &CanFdFrame) {
        self.text.push_str(&line(f64::from(bus_us) * 1e-6, frame));
        self.text.push('\n');
    }

    /// Record joint index `joint`'s state frame sent at bus time `bus_us` with its
    /// compensator's `faults` and feedforward `feedforward_nm` (a SYNC first when
    /// this is the tick's first frame).
    pub fn record(
        &mut self,
        joint: usize,
        bus_us: u32,
        state: JointState,
        faults: FaultFlags,
        feedforward_nm: f32,
    ) {
        if self.last_sync_us != Some(bus_us) {
            self.last_sync_us = Some(bus_us);
            self.sync_counter = self.sync_counter.wrapping_add(1);
            let sync = SyncFrame {
                session: self.session,
                counter: self.sync_counter,
                bus_time_us: bus_us,
            }
            .encode(&self.auth);
            self.push(bus_us, &sync);
        }
        if self.sequences.len() <= joint {
            self.sequences.resize(joint + 1, 0);
        }
        self.sequences[joint] = self.sequences[joint].wrapping_add(1);
        let frame = StateFrame {
            message: JointStateMessage {
                joint: joint as u8,
                session: self.session,
                sequence: self.sequences[joint],
                timestamp_us: bus_us,
                state,
            },
            faults,
            feedforward_nm,
        }
        .encode(&self.auth);
        if let Some(f) = frame {
            self.push(bus_us, &f);
        }
    }

    /// The log so far.
    pub fn text(&self) -> &str {
        &self.text
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_are_candump_fd_lines_that_authenticate() {
        let key = *b"sil-telemetry-01";
        let mut r = CandumpRecorder::new(&key, 0x1234);
        let s = JointState::from_array([0.5, 0.0, 0.0, 0.25, -1.0, 3.5]);
        r.record(0, 10_000, s, FaultFlags::NONE, 1.5);
        r.record(1, 10_000, s, FaultFlags::FF_WARMUP, -2.0);
        r.record(0, 20_000, s, FaultFlags::NONE, 1.0);
        let lines: Vec<&str> = r.text().lines().collect();
        assert_eq!(lines.len(), 5, "{}", r.text());
        assert!(
            lines[0].starts_with("(0.010000) can0 080##1"),
            "{}",
            lines[0]
        );
        assert!(
            lines[1].starts_with("(0.010000) can0 100##1"),
            "{}",
            lines[1]
        );
        assert!(
            lines[2].starts_with("(0.010000) can0 101##1"),
            "{}",
            lines[2]
        );
        assert!(
            lines[3].starts_with("(0.020000) can0 080##1"),
            "{}",
            lines[3]
        );
        // 16-byte SYNC and 48-byte state payloads, hex.
        assert_eq!(lines[0].split("##1").nth(1).map(str::len), Some(32));
        assert_eq!(lines[1].split("##1").nth(1).map(str::len), Some(96));
        // The state frame decodes with the key, not without it.
        let hex = lines[2].split("##1").nth(1).unwrap_or("");
        let bytes: Vec<u8> = (0..hex.len() / 2)
            .map(|i| u8::from_str_radix(&hex[2 * i..2 * i + 2], 16).unwrap_or(0))
            .collect();
        let frame = CanFdFrame::new(0x101, &bytes).unwrap();
        let d = StateFrame::decode(&FrameAuth::new(&key), &frame).unwrap();
        assert_eq!(
            (d.message.joint, d.message.sequence, d.feedforward_nm),
            (1, 1, -2.0)
        );
        assert_eq!(d.faults, FaultFlags::FF_WARMUP);
        assert!(StateFrame::decode(&FrameAuth::new(b"another-key-0000"), &frame).is_err());
    }
}
