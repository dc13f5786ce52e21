//! Joint states exchanged between the joint MCUs (as over EtherCAT) and their wire
//! format.
//!
//! # Threat model of the state bus
//!
//! Frames carry no authentication: any device on the bus (a faulty node, a
//! misconfigured second sender, a malicious one) can forge any frame, including a
//! valid CRC, any joint index, session, sequence number and timestamp, and the
//! receiver cannot tell it from the real sender's. What the receiver bounds:
//!
//! - **What a forged state can do to the feedforward.** A state is used only when
//!   every field is finite and within [`StateLimits`]; the prediction made from it
//!   must be within `max_abs_tau_nm`; the feedforward is then clamped to
//!   `max_torque_nm` (and `max_current_a`) and changes by at most
//!   `max_torque_rate_nm_s`. A forger who also silences the real sender (so that no
//!   sequence conflict is seen) can therefore move the feedforward anywhere within
//!   +-`max_torque_nm` at the rate limit, and the source still reads `Model` or
//!   `ModelLstm`: without authentication this case cannot be detected. The
//!   position and velocity loops stay in charge of the motion.
//! - **Two senders for one joint are detected.** A frame whose sequence number does
//!   not continue its stream (a replay, an older number, a jump of more than
//!   [`SEQUENCE_WINDOW`]) is dropped, and a session change on a live stream
//!   restarts it; either is a conflict (`STATE_OUT_OF_ORDER`), and for
//!   `watchdog_ticks` ticks after the last conflict the feedforward is zero. A
//!   spoofer interleaving its frames with the real sender's therefore holds the
//!   feedforward at zero (a denial of the feedforward, flagged every tick) instead
//!   of steering it.
//! - **How long one forged frame can silence the real sender.** Within a live
//!   stream only a forward step of 1..=[`SEQUENCE_WINDOW`] is accepted; a stream
//!   with no accepted frame for more than `watchdog_ticks` ticks is stale and the
//!   next valid frame resynchronises it, whatever its session and sequence number.
//!   One forged frame can thus keep the real sender's frames out for at most
//!   `watchdog_ticks + 1` compensator ticks, and the feedforward is zero for at
//!   most `2 * watchdog_ticks + 1` ticks before it warms up again (at 1 kHz with
//!   `watchdog_ticks = 3`: 7 ms).
//! - **Reboots.** A sender picks a new [`JointStateMessage::session`] at every
//!   start; a session change resynchronises the stream at once (flagged as a
//!   conflict, so the feedforward pauses for `watchdog_ticks` ticks). A sender that
//!   happens to restart with its old session is picked up once the old stream is
//!   stale.
//! - **Delays and replays of old frames** are caught by the sender timestamp
//!   (`max_message_age_us`, against a synchronised bus clock, or against each
//!   sender's clock offset learned at resynchronisation and followed at no more
//!   than the clocks' rate tolerance): a stream whose timestamp is off is stale and
//!   must resynchronise. A delay added slower than the rate tolerance is not seen.
//! - **Framing.** A field that happens to contain the sync marker cannot lock the
//!   [`FrameReceiver`] out: after every bad window it rescans the bytes it holds for
//!   the next marker.
//!
//! The fault flags report what was seen: `STATE_REJECTED` (bad field or joint
//! index), `STATE_OUT_OF_ORDER` (a sequence or session conflict, set on every tick
//! the feedforward is held at zero because of one), `STATE_STALE` (silence or a
//! timestamp out of bounds).

/// What one joint tells the others each compensator tick (joint side, SI units).
///
/// The reference is the trajectory point the joint follows (what a feedforward
/// needs before the motion happens); the measured values are what the `paper`
/// feature preset feeds the LSTM.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct JointState {
    /// Reference position, rad.
    pub q_ref_rad: f32,
    /// Reference velocity, rad/s.
    pub qd_ref_rad_s: f32,
    /// Reference acceleration, rad/s^2.
    pub qdd_ref_rad_s2: f32,
    /// Measured position, rad.
    pub q_meas_rad: f32,
    /// Measured velocity, rad/s.
    pub qd_meas_rad_s: f32,
    /// Measured torque (from the q current), N*m.
    pub tau_meas_nm: f32,
}

impl JointState {
    /// The six fields in wire order.
    pub fn to_array(&self) -> [f32; 6] {
        [
            self.q_ref_rad,
            self.qd_ref_rad_s,
            self.qdd_ref_rad_s2,
            self.q_meas_rad,
            self.qd_meas_rad_s,
            self.tau_meas_nm,
        ]
    }

    /// A state from six fields in wire order.
    pub fn from_array(a: [f32; 6]) -> Self {
        Self {
            q_ref_rad: a[0],
            qd_ref_rad_s: a[1],
            qdd_ref_rad_s2: a[2],
            q_meas_rad: a[3],
            qd_meas_rad_s: a[4],
            tau_meas_nm: a[5],
        }
    }
}

/// Bounds a joint state must respect to be used (each an absolute value).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StateLimits {
    /// Largest |position|, rad.
    pub max_abs_q_rad: f32,
    /// Largest |velocity|, rad/s.
    pub max_abs_qd_rad_s: f32,
    /// Largest |acceleration|, rad/s^2.
    pub max_abs_qdd_rad_s2: f32,
    /// Largest |torque|, N*m.
    pub max_abs_tau_nm: f32,
}

impl StateLimits {
    /// True when every field is finite and within its bound (NaN fails).
    pub fn accepts(&self, s: &JointState) -> bool {
        let within = |x: f32, m: f32| x.abs() <= m; // false for NaN and +-inf > m
        within(s.q_ref_rad, self.max_abs_q_rad)
            & within(s.qd_ref_rad_s, self.max_abs_qd_rad_s)
            & within(s.qdd_ref_rad_s2, self.max_abs_qdd_rad_s2)
            & within(s.q_meas_rad, self.max_abs_q_rad)
            & within(s.qd_meas_rad_s, self.max_abs_qd_rad_s)
            & within(s.tau_meas_nm, self.max_abs_tau_nm)
    }
}

/// One joint's state as sent on the state bus.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct JointStateMessage {
    /// Index of the sending joint among the modelled joints (0-based).
    pub joint: u8,
    /// The sender's session: a value chosen anew at every start (a boot counter or a
    /// random number), so that a receiver resynchronises after a reboot.
    pub session: u16,
    /// Sequence number, incremented (wrapping) per message by the sender.
    pub sequence: u16,
    /// Sender's time of the state, microseconds (bus-synchronised clock, wrapping).
    pub timestamp_us: u32,
    /// The state.
    pub state: JointState,
}

/// Start-of-frame marker of the wire format.
pub const FRAME_SYNC: [u8; 2] = [0xA5, 0x5A];

/// Largest forward step of the sequence number accepted within a live stream
/// (frames lost in between); a larger jump is a conflict.
pub const SEQUENCE_WINDOW: u16 = 64;

impl JointStateMessage {
    /// Length of an encoded frame: sync (2), joint (1), session (2), sequence (2),
    /// timestamp (4), six f32 (24), CRC-16 (2); little-endian.
    pub const WIRE_LEN: usize = 37;
    /// Offset of the six f32 fields in a frame.
    const FIELDS_AT: usize = 11;
    /// Offset of the CRC in a frame.
    const CRC_AT: usize = Self::WIRE_LEN - 2;

    /// Encode into a frame (CRC-16/CCITT-FALSE over everything after the sync).
    pub fn encode(&self) -> [u8; Self::WIRE_LEN] {
        let mut b = [0u8; Self::WIRE_LEN];
        b[0] = FRAME_SYNC[0];
        b[1] = FRAME_SYNC[1];
        b[2] = self.joint;
        b[3..5].copy_from_slice(&self.session.to_le_bytes());
        b[5..7].copy_from_slice(&self.sequence.to_le_bytes());
        b[7..11].copy_from_slice(&self.timestamp_us.to_le_bytes());
        let fields = self.state.to_array();
        let mut k = Self::FIELDS_AT;
        for f in fields {
            b[k..k + 4].copy_from_slice(&f.to_le_bytes());
            k += 4;
        }
        let crc = crc16(&b[2..Self::CRC_AT]);
        b[Self::CRC_AT..].copy_from_slice(&crc.to_le_bytes());
        b
    }

    /// Decode a frame; `None` when the sync or CRC is wrong. (Field values are not
    /// checked here: the compensator checks them against its limits.)
    pub fn decode(b: &[u8; Self::WIRE_LEN]) -> Option<Self> {
        if b[0] != FRAME_SYNC[0] || b[1] != FRAME_SYNC[1] {
            return None;
        }
        let crc = u16::from_le_bytes([b[Self::CRC_AT], b[Self::CRC_AT + 1]]);
        if crc16(&b[2..Self::CRC_AT]) != crc {
            return None;
        }
        let mut fields = [0.0f32; 6];
        for (i, f) in fields.iter_mut().enumerate() {
            let k = Self::FIELDS_AT + 4 * i;
            *f = f32::from_le_bytes([b[k], b[k + 1], b[k + 2], b[k + 3]]);
        }
        Some(Self {
            joint: b[2],
            session: u16::from_le_bytes([b[3], b[4]]),
            sequence: u16::from_le_bytes([b[5], b[6]]),
            timestamp_us: u32::from_le_bytes([b[7], b[8], b[9], b[10]]),
            state: JointState::from_array(fields),
        })
    }
}

/// CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF), bitwise: 8 steps per byte.
pub fn crc16(bytes: &[u8]) -> u16 {
    let mut crc = 0xFFFFu16;
    for &byte in bytes {
        crc ^= (byte as u16) << 8;
        for _ in 0..8 {
            crc = if crc & 0x8000 != 0 {
                (crc << 1) ^ 0x1021
            } else {
                crc << 1
            };
        }
    }
    crc
}

/// Reassembles frames from a byte stream (UART) in bounded time per byte (at most
/// one frame's CRC and one scan and shift of the buffer).
#[derive(Clone, Debug)]
pub struct FrameReceiver {
    buf: [u8; JointStateMessage::WIRE_LEN],
    len: usize,
}

impl Default for FrameReceiver {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameReceiver {
    /// An empty receiver.
    pub const fn new() -> Self {
        Self {
            buf: [0; JointStateMessage::WIRE_LEN],
            len: 0,
        }
    }

    /// Feed one byte; returns a message when it completes a valid frame. After a bad
    /// window (a false sync marker inside a field, a truncated or corrupt frame) the
    /// receiver rescans the bytes it holds after the window's start for the next
    /// sync marker, so a real frame starting inside the bad window is not lost.
    pub fn push(&mut self, byte: u8) -> Option<JointStateMessage> {
        match self.len {
            0 if byte != FRAME_SYNC[0] => return None,
            1 if byte != FRAME_SYNC[1] => {
                self.len = usize::from(byte == FRAME_SYNC[0]);
                return None;
            }
            _ => {}
        }
        if let Some(slot) = self.buf.get_mut(self.len) {
            *slot = byte;
        }
        self.len += 1;
        if self.len < JointStateMessage::WIRE_LEN {
            return None;
        }
        let msg = JointStateMessage::decode(&self.buf);
        if msg.is_some() {
            self.len = 0;
        } else {
            self.rescan();
        }
        msg
    }

    /// Drop the window's first byte and everything before the next sync marker (or
    /// a lone first sync byte at the end) in the held bytes: one pass over the
    /// buffer. The rest is kept as a partial frame (shorter than a frame, so it
    /// needs more bytes before it is checked).
    fn rescan(&mut self) {
        const N: usize = JointStateMessage::WIRE_LEN;
        let marker = self.buf.windows(2).skip(1).position(|w| *w == FRAME_SYNC);
        let start = match marker {
            Some(p) => p + 1,
            None if self.buf[N - 1] == FRAME_SYNC[0] => N - 1,
            None => N,
        };
        for k in 0..N {
            self.buf[k] = self.buf.get(k + start).copied().unwrap_or(0);
        }
        self.len = N.saturating_sub(start);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_round_trip_and_resync() {
        let m = JointStateMessage {
            joint: 2,
            session: 0xBEEF,
            sequence: 65535,
            timestamp_us: 123_456_789,
            state: JointState::from_array([1.0, -2.0, 3.5, f32::NAN, 1e30, -0.25]),
        };
        let frame = m.encode();
        let d = JointStateMessage::decode(&frame).unwrap();
        // Field by field, not through to_array (which encode itself uses).
        let fields = |s: &JointState| {
            [
                s.q_ref_rad,
                s.qd_ref_rad_s,
                s.qdd_ref_rad_s2,
                s.q_meas_rad,
                s.qd_meas_rad_s,
                s.tau_meas_nm,
            ]
            .map(f32::to_bits)
        };
        assert_eq!(
            fields(&d.state),
            [1.0, -2.0, 3.5, f32::NAN, 1e30, -0.25].map(f32::to_bits)
        );
        assert_eq!(fields(&d.state), fields(&m.state));
        // Either sync byte wrong (the CRC does not cover them): no message.
        for k in 0..2 {
            let mut unsynced = frame;
            unsynced[k] ^= 0xFF;
            assert!(JointStateMessage::decode(&unsynced).is_none());
        }
        assert_eq!(
            (d.joint, d.session, d.sequence, d.timestamp_us),
            (2, 0xBEEF, 65535, 123_456_789)
        );
        let mut bad = frame;
        bad[12] ^= 1;
        assert!(JointStateMessage::decode(&bad).is_none());
        // crc16 check value of CCITT-FALSE.
        assert_eq!(crc16(b"123456789"), 0x29B1);
        let mut rx = FrameReceiver::new();
        let mut got = 0;
        for &b in [0x00, 0xA5, 0x11]
            .iter()
            .chain(bad.iter())
            .chain(frame.iter())
            .chain(frame.iter())
        {
            if rx.push(b).is_some() {
                got += 1;
            }
        }
        assert_eq!(got, 2);
    }

    #[test]
    fn accepts_checks_every_field_against_its_bound() {
        let limits = StateLimits {
            max_abs_q_rad: 1.0,
            max_abs_qd_rad_s: 2.0,
            max_abs_qdd_rad_s2: 3.0,
            max_abs_tau_nm: 4.0,
        };
        let bounds = [1.0, 2.0, 3.0, 1.0, 2.0, 4.0];
        assert!(limits.accepts(&JointState::from_array(bounds)));
        assert!(limits.accepts(&JointState::from_array(bounds.map(|b: f32| -b))));
        for field in 0..6 {
            for bad in [
                bounds[field].next_up(),
                -bounds[field].next_up(),
                f32::NAN,
                f32::INFINITY,
                f32::NEG_INFINITY,
            ] {
                let mut a = [0.0; 6];
                a[field] = bad;
                assert!(
                    !limits.accepts(&JointState::from_array(a)),
                    "field {field} = {bad}"
                );
            }
        }
    }

    /// Frames whose reference position's bytes hold the sync marker.
    fn frames_with_a_false_marker(n: u16) -> std::vec::Vec<u8> {
        let q = f32::from_le_bytes([0x00, 0xA5, 0x5A, 0x3F]); // 0.85...
        (0..n)
            .flat_map(|i| {
                JointStateMessage {
                    joint: 1,
                    session: 3,
                    sequence: i,
                    timestamp_us: 1000 * u32::from(i),
                    state: JointState::from_array([q, 0.0, 0.0, 0.0, 0.0, 0.0]),
                }
                .encode()
            })
            .collect()
    }

    #[test]
    fn a_false_sync_marker_in_a_field_does_not_lock_the_receiver() {
        let bytes = frames_with_a_false_marker(20);
        // Joining the stream at any byte of the first frame: every later frame is
        // decoded.
        for start in 0..JointStateMessage::WIRE_LEN {
            let mut rx = FrameReceiver::new();
            let got: std::vec::Vec<u16> = bytes[start..]
                .iter()
                .filter_map(|&b| rx.push(b))
                .map(|m| m.sequence)
                .collect();
            let first = u16::from(start > 0);
            assert_eq!(
                got,
                (first..20).collect::<std::vec::Vec<_>>(),
                "start {start}"
            );
        }
    }

    #[test]
    fn the_receiver_rescans_after_a_bad_window() {
        let good = frames_with_a_false_marker(3);
        let n = JointStateMessage::WIRE_LEN;
        // A frame cut short (the sender reset mid-frame), a corrupted frame, then
        // good frames: each good frame starts inside the bad window before it.
        for cut in [2, 10, n - 3] {
            let mut bytes = good[..cut].to_vec();
            let mut corrupt = good[n..2 * n].to_vec();
            corrupt[20] ^= 0x40;
            bytes.extend_from_slice(&corrupt[..n - 1]);
            bytes.extend_from_slice(&good);
            let mut rx = FrameReceiver::new();
            let got: std::vec::Vec<u16> = bytes
                .iter()
                .filter_map(|&b| rx.push(b))
                .map(|m| m.sequence)
                .collect();
            assert_eq!(got, [0, 1, 2], "cut at {cut}");
        }
    }
}
