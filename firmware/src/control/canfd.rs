//! The state bus over CAN-FD: authenticated state frames, the SYNC frame that gives
//! every node one bus time, and the bus's load and worst-case latency.
//!
//! # Frames
//!
//! Standard (11-bit) identifiers; a lower identifier wins arbitration:
//!
//! | id | frame | payload (little-endian) |
//! |---|---|---|
//! | [`SYNC_ID`] `0x080` | SYNC, from the bus-time master (robot controller or one elected drive) | session u16, counter u16, bus time u32 (us), MAC 8 bytes: 16 bytes |
//! | [`STATE_ID_BASE`] `0x100` + joint index | one joint's state, broadcast every compensator tick | session u16, sequence u16, bus time u32 (us), six f32 ([`JointState::to_array`] order), fault flags u32, feedforward f32 (N*m), MAC 8 bytes: 48 bytes |
//!
//! The joint index is the identifier's, so a node hears every joint and knows the
//! claimed sender before it reads the payload.
//!
//! # Authentication
//!
//! Every frame ends in a truncated AES-128-CMAC (RustCrypto `cmac` + `aes`, 64 of
//! 128 bits) over the identifier, the length and the payload before the MAC, keyed
//! by the robot's 16-byte bus key (written per robot by `model-export provision`
//! into each drive's configuration block). The MAC covers the freshness fields
//! (session, sequence or counter, bus time), so a node without the key can neither
//! forge a frame nor alter one; a frame that fails is dropped and counted
//! ([`super::Compensator::reject_frame`], `FRAME_UNAUTHENTICATED`). A replayed
//! frame carries a valid MAC: it is caught by its freshness (the sequence window
//! and the age against the SYNC bus time). Every node of one robot holds the same
//! key: a compromised node that holds it can speak for any joint.
//!
//! # Bus time
//!
//! The master sends SYNC every compensator tick with its bus time; [`BusTime`]
//! follows it (the offset of the local microsecond clock is set at every accepted
//! SYNC), so a state frame's age is the local bus time minus its bus time, known
//! from the frame's authenticated timestamp and not learned from the frame. A SYNC
//! is accepted when it continues the master's stream (same session, counter one to
//! [`super::SEQUENCE_WINDOW`] ahead) and moves the bus time by no more than
//! [`BusTimeConfig::max_step_us`]; a replayed or forged one is a conflict, counted
//! and ignored. Without an accepted SYNC for [`BusTimeConfig::timeout_us`] the node
//! has no bus time and its compensator treats every other joint as stale
//! (feedforward zero) until the next SYNC, which it then takes whatever its session.

use aes::Aes128;
use cmac::Cmac;
use cmac::digest::{KeyInit, Mac};

use super::compensator::{Compensator, CompensatorOutput, TorquePredictor};
use super::faults::FaultFlags;
use super::message::{JointState, JointStateMessage, SEQUENCE_WINDOW};

/// Identifier of the SYNC frame (CANopen's SYNC identifier).
pub const SYNC_ID: u16 = 0x080;
/// Identifier of joint index 0's state frame; joint index `j` sends `STATE_ID_BASE + j`.
pub const STATE_ID_BASE: u16 = 0x100;
/// Joint indices a state identifier can carry (0x100..0x13F).
pub const MAX_JOINTS: usize = 64;
/// Length of the truncated MAC at the end of every frame, bytes.
pub const MAC_LEN: usize = 8;
/// Payload length of a state frame, bytes (a CAN-FD DLC of 14).
pub const STATE_LEN: usize = 48;
/// Payload length of a SYNC frame, bytes (a CAN-FD DLC of 10).
pub const SYNC_LEN: usize = 16;

/// One CAN-FD frame as the controller hands it over: a standard identifier and up
/// to 64 payload bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CanFdFrame {
    /// Standard (11-bit) identifier.
    pub id: u16,
    /// Payload length, bytes (a valid CAN-FD length: 0..=8, 12, 16, 20, 24, 32, 48, 64).
    pub len: u8,
    /// Payload (the first `len` bytes are the frame's).
    pub data: [u8; 64],
}

impl CanFdFrame {
    /// A frame from an identifier and a payload (`None` for more than 64 bytes).
    pub fn new(id: u16, payload: &[u8]) -> Option<Self> {
        let mut data = [0u8; 64];
        data.get_mut(..payload.len())?.copy_from_slice(payload);
        Some(Self {
            id,
            len: payload.len() as u8,
            data,
        })
    }

    /// The payload's bytes (at most 64, whatever `len` says).
    pub fn payload(&self) -> &[u8] {
        let n = usize::from(self.len).min(self.data.len());
        &self.data[..n]
    }
}

/// Why a received frame was not taken.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrameError {
    /// The identifier is neither SYNC nor a state frame of a joint of the bus.
    UnknownId,
    /// The length is not the frame's.
    WrongLength,
    /// The MAC does not match: forged, altered or corrupted.
    Unauthenticated,
}

/// The robot's bus key, ready to compute and check MACs (AES-128-CMAC).
#[derive(Clone)]
pub struct FrameAuth {
    cmac: Cmac<Aes128>,
}

impl FrameAuth {
    /// The authenticator of a 16-byte key.
    pub fn new(key: &[u8; 16]) -> Self {
        Self {
            cmac: <Cmac<Aes128> as KeyInit>::new(&(*key).into()),
        }
    }

    fn mac_of(&self, id: u16, body: &[u8]) -> Cmac<Aes128> {
        let mut m = self.cmac.clone();
        let [lo, hi] = id.to_le_bytes();
        // The identifier and the length are authenticated with the payload.
        m.update(&[lo, hi, body.len() as u8, 0xFD]);
        m.update(body);
        m
    }

    /// The truncated MAC (the first [`MAC_LEN`] bytes of the CMAC) of `body` sent
    /// under `id`.
    pub fn tag(&self, id: u16, body: &[u8]) -> [u8; MAC_LEN] {
        let full = self.mac_of(id, body).finalize().into_bytes();
        let mut t = [0u8; MAC_LEN];
        t.copy_from_slice(&full[..MAC_LEN]);
        t
    }

    /// True when `tag` is the truncated MAC of `body` under `id` (constant time).
    pub fn verify(&self, id: u16, body: &[u8], tag: &[u8]) -> bool {
        tag.len() == MAC_LEN && self.mac_of(id, body).verify_truncated_left(tag).is_ok()
    }

    /// Seal a payload in place: its last [`MAC_LEN`] bytes become the MAC of the rest.
    fn seal(&self, id: u16, payload: &mut [u8]) {
        let n = payload.len().saturating_sub(MAC_LEN);
        let (body, tag) = payload.split_at_mut(n);
        let t = self.tag(id, body);
        tag.copy_from_slice(&t[..tag.len().min(MAC_LEN)]);
    }

    /// Check a payload sealed by [`FrameAuth::seal`].
    fn open(&self, id: u16, payload: &[u8]) -> bool {
        let n = payload.len().saturating_sub(MAC_LEN);
        let (body, tag) = payload.split_at(n);
        self.verify(id, body, tag)
    }
}

fn le_u16(b: &[u8], at: usize) -> u16 {
    let mut x = [0u8; 2];
    if let Some(s) = b.get(at..at + 2) {
        x.copy_from_slice(s);
    }
    u16::from_le_bytes(x)
}

fn le_u32(b: &[u8], at: usize) -> u32 {
    let mut x = [0u8; 4];
    if let Some(s) = b.get(at..at + 4) {
        x.copy_from_slice(s);
    }
    u32::from_le_bytes(x)
}

/// One joint's state frame: the state message, the sender's compensator flags and
/// feedforward (telemetry for the host; the receiving compensators use the message).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StateFrame {
    /// The joint state with its freshness (`timestamp_us` is bus time).
    pub message: JointStateMessage,
    /// The sender's fault flags of its latest compensator tick.
    pub faults: FaultFlags,
    /// The sender's latest torque feedforward, N*m (joint side).
    pub feedforward_nm: f32,
}

impl StateFrame {
    /// The sealed CAN-FD frame (`None` for a joint index beyond [`MAX_JOINTS`]).
    pub fn encode(&self, auth: &FrameAuth) -> Option<CanFdFrame> {
        let m = &self.message;
        if usize::from(m.joint) >= MAX_JOINTS {
            return None;
        }
        let id = STATE_ID_BASE + u16::from(m.joint);
        let mut p = [0u8; STATE_LEN];
        p[0..2].copy_from_slice(&m.session.to_le_bytes());
        p[2..4].copy_from_slice(&m.sequence.to_le_bytes());
        p[4..8].copy_from_slice(&m.timestamp_us.to_le_bytes());
        for (k, f) in m.state.to_array().iter().enumerate() {
            p[8 + 4 * k..12 + 4 * k].copy_from_slice(&f.to_le_bytes());
        }
        p[32..36].copy_from_slice(&self.faults.bits().to_le_bytes());
        p[36..40].copy_from_slice(&self.feedforward_nm.to_le_bytes());
        auth.seal(id, &mut p);
        CanFdFrame::new(id, &p)
    }

    /// The state frame of a received frame, authenticated (field values are not
    /// checked here: the compensator checks them against its limits).
    pub fn decode(auth: &FrameAuth, frame: &CanFdFrame) -> Result<Self, FrameError> {
        let joint = frame.id.wrapping_sub(STATE_ID_BASE);
        if usize::from(joint) >= MAX_JOINTS {
            return Err(FrameError::UnknownId);
        }
        let p = frame.payload();
        if p.len() != STATE_LEN {
            return Err(FrameError::WrongLength);
        }
        if !auth.open(frame.id, p) {
            return Err(FrameError::Unauthenticated);
        }
        let mut fields = [0.0f32; 6];
        for (k, f) in fields.iter_mut().enumerate() {
            *f = f32::from_bits(le_u32(p, 8 + 4 * k));
        }
        Ok(Self {
            message: JointStateMessage {
                joint: joint as u8,
                session: le_u16(p, 0),
                sequence: le_u16(p, 2),
                timestamp_us: le_u32(p, 4),
                state: JointState::from_array(fields),
            },
            faults: FaultFlags::from_bits(le_u32(p, 32)),
            feedforward_nm: f32::from_bits(le_u32(p, 36)),
        })
    }
}

/// The SYNC frame: the master's bus time.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SyncFrame {
    /// The master's session (chosen anew at every start).
    pub session: u16,
    /// Counter, incremented (wrapping) per SYNC.
    pub counter: u16,
    /// The bus time, microseconds (wrapping).
    pub bus_time_us: u32,
}

impl SyncFrame {
    /// The sealed CAN-FD frame.
    pub fn encode(&self, auth: &FrameAuth) -> CanFdFrame {
        let mut p = [0u8; SYNC_LEN];
        p[0..2].copy_from_slice(&self.session.to_le_bytes());
        p[2..4].copy_from_slice(&self.counter.to_le_bytes());
        p[4..8].copy_from_slice(&self.bus_time_us.to_le_bytes());
        auth.seal(SYNC_ID, &mut p);
        let mut data = [0u8; 64];
        data[..SYNC_LEN].copy_from_slice(&p);
        CanFdFrame {
            id: SYNC_ID,
            len: SYNC_LEN as u8,
            data,
        }
    }

    /// The SYNC of a received frame, authenticated.
    pub fn decode(auth: &FrameAuth, frame: &CanFdFrame) -> Result<Self, FrameError> {
        if frame.id != SYNC_ID {
            return Err(FrameError::UnknownId);
        }
        let p = frame.payload();
        if p.len() != SYNC_LEN {
            return Err(FrameError::WrongLength);
        }
        if !auth.open(SYNC_ID, p) {
            return Err(FrameError::Unauthenticated);
        }
        Ok(Self {
            session: le_u16(p, 0),
            counter: le_u16(p, 2),
            bus_time_us: le_u32(p, 4),
        })
    }
}

/// How a node follows the bus time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BusTimeConfig {
    /// Largest change of the bus-time offset one SYNC may make, microseconds (the
    /// SYNC's delivery jitter plus the clocks' drift over the SYNC period).
    pub max_step_us: u32,
    /// Without an accepted SYNC for this long the node has no bus time, microseconds.
    pub timeout_us: u32,
}

impl BusTimeConfig {
    /// SYNC every compensator tick of `tick_period_us`: a step of at most a quarter
    /// tick, bus time lost after three ticks without SYNC.
    pub const fn every_tick(tick_period_us: u32) -> Self {
        Self {
            max_step_us: tick_period_us / 4,
            timeout_us: 3 * tick_period_us,
        }
    }
}

/// The bus time a node follows: its local microsecond clock plus the offset the
/// latest accepted SYNC set.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BusTime {
    config: BusTimeConfig,
    offset_us: u32,
    last_sync_local_us: u32,
    session: u16,
    counter: u16,
    synced: bool,
    conflicts: u32,
}

impl BusTime {
    /// A follower that has not heard SYNC yet.
    pub const fn new(config: BusTimeConfig) -> Self {
        Self {
            config,
            offset_us: 0,
            last_sync_local_us: 0,
            session: 0,
            counter: 0,
            synced: false,
            conflicts: 0,
        }
    }

    fn live(&self, local_us: u32) -> bool {
        self.synced && local_us.wrapping_sub(self.last_sync_local_us) <= self.config.timeout_us
    }

    /// Take an authenticated SYNC received at local time `local_us`; false (and
    /// counted) when it does not continue the master's stream: another session,
    /// a counter outside the window, or a bus-time step beyond `max_step_us`.
    pub fn on_sync(&mut self, sync: &SyncFrame, local_us: u32) -> bool {
        let offset = sync.bus_time_us.wrapping_sub(local_us);
        if self.live(local_us) {
            let step = sync.counter.wrapping_sub(self.counter);
            let drift = offset.wrapping_sub(self.offset_us) as i32;
            let continues = sync.session == self.session
                && (1..=SEQUENCE_WINDOW).contains(&step)
                && drift.unsigned_abs() <= self.config.max_step_us;
            if !continues {
                self.conflicts = self.conflicts.saturating_add(1);
                return false;
            }
        }
        self.offset_us = offset;
        self.last_sync_local_us = local_us;
        self.session = sync.session;
        self.counter = sync.counter;
        self.synced = true;
        true
    }

    /// The bus time at local time `local_us`, or `None` without a live SYNC.
    pub fn now_us(&self, local_us: u32) -> Option<u32> {
        self.live(local_us)
            .then(|| local_us.wrapping_add(self.offset_us))
    }

    /// SYNC frames refused since start (saturating).
    pub fn conflicts(&self) -> u32 {
        self.conflicts
    }
}

/// Where a node's bus time comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BusTimeSource {
    /// The SYNC master's (the default: a frame's age is bounded).
    Sync(BusTime),
    /// The node's own free-running clock; senders' clock offsets are learned by the
    /// compensator (`BusClock::FreeRunning`; see the board README for what it
    /// cannot catch). SYNC frames are ignored.
    FreeRunning,
}

/// One node's end of the CAN-FD state bus: the key, the bus time, and the
/// dispatch of received frames to the compensator.
#[derive(Clone)]
pub struct BusNode {
    auth: FrameAuth,
    time: BusTimeSource,
}

impl BusNode {
    /// A node with the robot's bus key and its bus-time source.
    pub fn new(key: &[u8; 16], time: BusTimeSource) -> Self {
        Self {
            auth: FrameAuth::new(key),
            time,
        }
    }

    /// The authenticator (to seal this node's own frames).
    pub fn auth(&self) -> &FrameAuth {
        &self.auth
    }

    /// The bus time at local time `local_us` (`None` without a live SYNC).
    pub fn now_us(&self, local_us: u32) -> Option<u32> {
        match &self.time {
            BusTimeSource::Sync(t) => t.now_us(local_us),
            BusTimeSource::FreeRunning => Some(local_us),
        }
    }

    /// The SYNC follower, if this node follows SYNC.
    pub fn bus_time(&self) -> Option<&BusTime> {
        match &self.time {
            BusTimeSource::Sync(t) => Some(t),
            BusTimeSource::FreeRunning => None,
        }
    }

    /// Take a received frame at local time `local_us`: SYNC to the bus time, a
    /// state frame to the compensator; a frame of the bus's identifiers that fails
    /// its length or MAC is counted by the compensator and dropped
    /// (`FRAME_UNAUTHENTICATED`); other identifiers are other traffic, ignored.
    pub fn receive<const J: usize, M: TorquePredictor<J>, L: TorquePredictor<J>>(
        &mut self,
        frame: &CanFdFrame,
        local_us: u32,
        compensator: &mut Compensator<J, M, L>,
    ) -> FaultFlags {
        if frame.id == SYNC_ID {
            return match SyncFrame::decode(&self.auth, frame) {
                Ok(s) => {
                    if let BusTimeSource::Sync(t) = &mut self.time {
                        t.on_sync(&s, local_us);
                    }
                    FaultFlags::NONE
                }
                Err(_) => compensator.reject_frame(),
            };
        }
        match StateFrame::decode(&self.auth, frame) {
            Ok(f) => compensator.receive_at(&f.message, self.now_us(local_us)),
            Err(FrameError::UnknownId) => FaultFlags::NONE,
            Err(_) => compensator.reject_frame(),
        }
    }

    /// One compensator tick at local time `local_us`, against the bus time.
    pub fn tick<const J: usize, M: TorquePredictor<J>, L: TorquePredictor<J>>(
        &self,
        compensator: &mut Compensator<J, M, L>,
        own: &JointState,
        local_us: u32,
    ) -> CompensatorOutput {
        match self.now_us(local_us) {
            Some(t) => compensator.tick(own, t),
            None => compensator.tick_without_bus_time(own),
        }
    }
}

/// CAN-FD bit rates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BitRates {
    /// Arbitration (nominal) bit rate, bit/s.
    pub nominal_bit_s: f32,
    /// Data-phase bit rate with bit-rate switching, bit/s.
    pub data_bit_s: f32,
}

impl BitRates {
    /// 1 Mbit/s arbitration, 5 Mbit/s data (the rates moteus drives use).
    pub const MOTEUS: Self = Self {
        nominal_bit_s: 1.0e6,
        data_bit_s: 5.0e6,
    };
}

/// Worst-case bit counts of a CAN-FD frame with a standard identifier and bit-rate
/// switching: (bits at the nominal rate, bits at the data rate). Nominal: SOF,
/// identifier, RRS, IDE, FDF, res, BRS (17, dynamic stuffing at most one per four
/// after the first: 21) and CRC delimiter, ACK, ACK delimiter, EOF and intermission
/// (13). Data: ESI, DLC and the payload with worst-case dynamic stuffing (one per
/// four bits, rounded up), then the
/// stuff count (4) and CRC (17 up to 16 bytes, else 21) with a fixed stuff bit
/// every four bits and before the stuff count.
pub const fn frame_bits(payload_len: u32) -> (u32, u32) {
    let arbitration = 17 + (17 - 1) / 4;
    let tail = 13;
    let dynamic = 1 + 4 + 8 * payload_len;
    let crc: u32 = if payload_len <= 16 { 17 } else { 21 };
    let fixed_stuff = (4 + crc).div_ceil(4);
    let data = dynamic + dynamic.div_ceil(4) + 4 + crc + fixed_stuff;
    (arbitration + tail, data)
}

/// Worst-case time on the bus of one frame of `payload_len` bytes, seconds.
pub fn frame_time_s(payload_len: u32, rates: BitRates) -> f32 {
    let (n, d) = frame_bits(payload_len);
    n as f32 / rates.nominal_bit_s + d as f32 / rates.data_bit_s
}

/// The bus's load and worst-case latency with `joints` drives each sending one state
/// frame and the master one SYNC per tick of `tick_hz`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BusBudget {
    /// Share of the bus time the frames take, worst case (1 = saturated).
    pub load: f32,
    /// Worst-case time from a state frame's queueing to its end of reception, for
    /// the lowest-priority joint, microseconds: one frame already on the bus
    /// (non-preemptive), SYNC and every higher-priority state frame, then its own.
    pub worst_latency_us: f32,
    /// The compensator tick period, microseconds.
    pub tick_period_us: f32,
}

impl BusBudget {
    /// The budget of `joints` state frames and one SYNC per tick of `tick_hz`.
    pub fn of(joints: u32, tick_hz: f32, rates: BitRates) -> Self {
        let state = frame_time_s(STATE_LEN as u32, rates);
        let sync = frame_time_s(SYNC_LEN as u32, rates);
        let per_tick = joints as f32 * state + sync;
        let longest = if state > sync { state } else { sync };
        Self {
            load: per_tick * tick_hz,
            worst_latency_us: (longest + per_tick) * 1e6,
            tick_period_us: 1e6 / tick_hz,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const KEY: [u8; 16] = *b"robot-bus-key-01";

    #[test]
    fn cmac_matches_rfc4493() {
        // RFC 4493 example 2 (AES-128, 16-byte message), over the raw CMAC.
        let key = [
            0x2b, 0x7e, 0x15, 0x16, 0x28, 0xae, 0xd2, 0xa6, 0xab, 0xf7, 0x15, 0x88, 0x09, 0xcf,
            0x4f, 0x3c,
        ];
        let msg = [
            0x6b, 0xc1, 0xbe, 0xe2, 0x2e, 0x40, 0x9f, 0x96, 0xe9, 0x3d, 0x7e, 0x11, 0x73, 0x93,
            0x17, 0x2a,
        ];
        let mut m = <Cmac<Aes128> as KeyInit>::new(&key.into());
        m.update(&msg);
        let want = [
            0x07, 0x0a, 0x16, 0xb4, 0x6b, 0x4d, 0x41, 0x44, 0xf7, 0x9b, 0xdd, 0x9d, 0xd0, 0x4a,
            0x28, 0x7c,
        ];
        assert_eq!(m.finalize().into_bytes().as_slice(), &want);
    }

    #[test]
    fn state_and_sync_frames_round_trip_and_refuse_any_bit_flip() {
        let auth = FrameAuth::new(&KEY);
        let f = StateFrame {
            message: JointStateMessage {
                joint: 5,
                session: 0xBEEF,
                sequence: 65535,
                timestamp_us: 123_456_789,
                state: JointState::from_array([1.0, -2.0, 3.5, f32::NAN, 1e30, -0.25]),
            },
            faults: FaultFlags::SENDER_SILENT | FaultFlags::FF_WARMUP,
            feedforward_nm: -12.5,
        };
        let frame = f.encode(&auth).unwrap();
        assert_eq!((frame.id, frame.len), (0x105, 48));
        let d = StateFrame::decode(&auth, &frame).unwrap();
        assert_eq!(
            d.message.state.to_array().map(f32::to_bits),
            f.message.state.to_array().map(f32::to_bits)
        );
        assert_eq!(
            (d.message.joint, d.message.session, d.message.sequence),
            (5, 0xBEEF, 65535)
        );
        assert_eq!(d.message.timestamp_us, 123_456_789);
        assert_eq!((d.faults, d.feedforward_nm), (f.faults, -12.5));
        for bit in 0..STATE_LEN * 8 {
            let mut bad = frame;
            bad.data[bit / 8] ^= 1 << (bit % 8);
            assert_eq!(
                StateFrame::decode(&auth, &bad),
                Err(FrameError::Unauthenticated),
                "bit {bit}"
            );
        }
        // Another joint's identifier, another length, another key.
        let mut moved = frame;
        moved.id = 0x104;
        assert_eq!(
            StateFrame::decode(&auth, &moved),
            Err(FrameError::Unauthenticated)
        );
        let mut short = frame;
        short.len = 32;
        assert_eq!(
            StateFrame::decode(&auth, &short),
            Err(FrameError::WrongLength)
        );
        let other = FrameAuth::new(b"robot-bus-key-02");
        assert_eq!(
            StateFrame::decode(&other, &frame),
            Err(FrameError::Unauthenticated)
        );
        let mut far = f;
        far.message.joint = MAX_JOINTS as u8;
        assert!(far.encode(&auth).is_none());

        let s = SyncFrame {
            session: 7,
            counter: 9,
            bus_time_us: 0xFFFF_FFF0,
        };
        let sf = s.encode(&auth);
        assert_eq!(SyncFrame::decode(&auth, &sf), Ok(s));
        let mut bad = sf;
        bad.data[5] ^= 0x10;
        assert_eq!(
            SyncFrame::decode(&auth, &bad),
            Err(FrameError::Unauthenticated)
        );
    }

    #[test]
    fn bus_time_follows_sync_and_refuses_jumps() {
        let mut t = BusTime::new(BusTimeConfig::every_tick(1000));
        assert_eq!(t.now_us(5), None);
        let sync = |counter: u16, bus: u32| SyncFrame {
            session: 1,
            counter,
            bus_time_us: bus,
        };
        assert!(t.on_sync(&sync(1, 1_000_000), 50));
        assert_eq!(t.now_us(550), Some(1_000_500));
        // A drift of 100 us is followed.
        assert!(t.on_sync(&sync(2, 1_001_100), 1050));
        assert_eq!(t.now_us(1050), Some(1_001_100));
        // A replayed SYNC (old counter, old time) and a jump are refused.
        assert!(!t.on_sync(&sync(1, 1_000_000), 2050));
        assert!(!t.on_sync(&sync(3, 1_900_000), 2050));
        // Another master session while the stream is live: refused.
        let other = SyncFrame {
            session: 2,
            counter: 3,
            bus_time_us: 1_002_100,
        };
        assert!(!t.on_sync(&other, 2050));
        assert_eq!(t.conflicts(), 3);
        // Silence beyond the timeout: no bus time; the next SYNC is taken.
        assert_eq!(t.now_us(1050 + 3001), None);
        assert!(t.on_sync(&other, 1050 + 3001));
        assert_eq!(t.now_us(1050 + 3001), Some(1_002_100));
    }

    #[test]
    fn frame_bits_match_hand_counts() {
        // 8 bytes: data phase 1 + 4 + 64 = 69, stuffing ceil(69 / 4) = 18, stuff
        // count 4, CRC-17, 6 fixed stuff bits: 114; nominal 21 + 13 = 34.
        assert_eq!(frame_bits(8), (34, 114));
        // 48 bytes: 389 + 98 + 4 + 21 + 7 = 519.
        assert_eq!(frame_bits(48), (34, 519));
        // Six joints at 100 Hz: 6 * (34 + 519 / 5) us + SYNC (34 + 194 / 5) us.
        let b = BusBudget::of(6, 100.0, BitRates::MOTEUS);
        let per_tick_us = 6.0 * (34.0 + 103.8) + 34.0 + 38.8;
        assert!((b.load - per_tick_us * 100.0 / 1e6).abs() < 1e-5, "{b:?}");
        assert!(
            (b.worst_latency_us - (137.8 + per_tick_us)).abs() < 1e-2,
            "{b:?}"
        );
    }
}
