//! Joint states exchanged between the joint MCUs (as over EtherCAT) and their wire
//! format.

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
    /// Sequence number, incremented (wrapping) per message by the sender.
    pub sequence: u16,
    /// Sender's time of the state, microseconds (bus-synchronised clock, wrapping).
    pub timestamp_us: u32,
    /// The state.
    pub state: JointState,
}

/// Start-of-frame marker of the wire format.
pub const FRAME_SYNC: [u8; 2] = [0xA5, 0x5A];

impl JointStateMessage {
    /// Length of an encoded frame: sync (2), joint (1), sequence (2), timestamp (4),
    /// six f32 (24), CRC-16 (2); little-endian.
    pub const WIRE_LEN: usize = 35;

    /// Encode into a frame (CRC-16/CCITT-FALSE over everything after the sync).
    pub fn encode(&self) -> [u8; Self::WIRE_LEN] {
        let mut b = [0u8; Self::WIRE_LEN];
        b[0] = FRAME_SYNC[0];
        b[1] = FRAME_SYNC[1];
        b[2] = self.joint;
        b[3..5].copy_from_slice(&self.sequence.to_le_bytes());
        b[5..9].copy_from_slice(&self.timestamp_us.to_le_bytes());
        let fields = self.state.to_array();
        let mut k = 9;
        for f in fields {
            b[k..k + 4].copy_from_slice(&f.to_le_bytes());
            k += 4;
        }
        let crc = crc16(&b[2..33]);
        b[33..35].copy_from_slice(&crc.to_le_bytes());
        b
    }

    /// Decode a frame; `None` when the sync or CRC is wrong. (Field values are not
    /// checked here: the compensator checks them against its limits.)
    pub fn decode(b: &[u8; Self::WIRE_LEN]) -> Option<Self> {
        if b[0] != FRAME_SYNC[0] || b[1] != FRAME_SYNC[1] {
            return None;
        }
        if crc16(&b[2..33]) != u16::from_le_bytes([b[33], b[34]]) {
            return None;
        }
        let mut fields = [0.0f32; 6];
        for (i, f) in fields.iter_mut().enumerate() {
            let k = 9 + 4 * i;
            *f = f32::from_le_bytes([b[k], b[k + 1], b[k + 2], b[k + 3]]);
        }
        Some(Self {
            joint: b[2],
            sequence: u16::from_le_bytes([b[3], b[4]]),
            timestamp_us: u32::from_le_bytes([b[5], b[6], b[7], b[8]]),
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

/// Reassembles frames from a byte stream (UART) in fixed time per byte.
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

    /// Feed one byte; returns a message when it completes a valid frame. A bad frame
    /// is dropped and the receiver re-synchronises on the next sync marker.
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
        self.len = 0;
        JointStateMessage::decode(&self.buf)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_round_trip_and_resync() {
        let m = JointStateMessage {
            joint: 2,
            sequence: 65535,
            timestamp_us: 123_456_789,
            state: JointState::from_array([1.0, -2.0, 3.5, f32::NAN, 1e30, -0.25]),
        };
        let frame = m.encode();
        let d = JointStateMessage::decode(&frame).unwrap();
        assert_eq!(
            d.state.to_array().map(f32::to_bits),
            m.state.to_array().map(f32::to_bits)
        );
        assert_eq!(
            (d.joint, d.sequence, d.timestamp_us),
            (2, 65535, 123_456_789)
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
}
