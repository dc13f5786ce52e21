//! Which joint this board drives, decided at start-up from its configuration block,
//! so that one firmware image serves every compensated joint of a robot.
//!
//! The block lives in its own flash page (the board's `memory.x` reserves the last
//! 2 KiB, `BOARD_CONFIG`, in the last 4 KiB page of the single-bank flash, which the
//! firmware image never covers, so flashing a new image keeps it). Layout ([`JointConfigBlock::LEN`] = 32 bytes, little-endian;
//! `model-export provision` writes it):
//!
//! | bytes | field |
//! |---|---|
//! | 0..4 | magic `b"JCFG"` |
//! | 4 | layout version ([`JointConfigBlock::VERSION`], 2) |
//! | 5 | robot joint number, counted from 1 (as `model-export --joints`) |
//! | 6..8 | reserved, zero |
//! | 8..24 | the robot's state-bus key (AES-128, [`super::canfd`]); all-zero and all-0xFF keys are refused |
//! | 24..30 | reserved, zero |
//! | 30..32 | CRC-16/CCITT-FALSE of bytes 0..30 (`message::crc16`) |
//!
//! [`select_joint`] turns the block into this board's slot among the compiled-in
//! model's compensated joints, or refuses: erased flash, a wrong magic, version or
//! CRC, a joint the model does not compensate, or an unusable profile. On a refusal
//! the board runs without feedforward, sends no state frames and reports the fault
//! ([`StartupPlan`]); it never runs as a joint it was not configured for.

use super::compensator::CompensatorConfig;
use super::drive::DriveConfig;
use super::message::crc16;
use super::profile::JointProfile;
use crate::adaptation::AdaptationConfig;
use crate::monitor::MonitorConfig;

/// The per-board configuration block: which robot joint this board drives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct JointConfigBlock {
    /// The robot joint this board drives, counted from 1.
    pub joint_number: u8,
    /// The robot's state-bus key (the same on every drive of one robot).
    pub bus_key: [u8; 16],
}

/// Why the configuration block was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum JointConfigFault {
    /// Every byte reads 0xFF: the page was never written.
    Erased,
    /// The first four bytes are not the magic.
    BadMagic,
    /// A layout version this firmware does not read.
    UnsupportedVersion(u8),
    /// The CRC does not match the bytes.
    BadCrc,
    /// Reserved bytes are not zero (a newer layout this firmware does not read).
    ReservedNotZero,
    /// The bus key is all zero or all 0xFF (never provisioned).
    NoBusKey,
    /// The block names a joint (counted from 1) the compiled-in model does not
    /// compensate (or joint 0).
    JointNotCompensated(u8),
    /// The compiled-in profile of that joint has an unusable field.
    InvalidProfile(&'static str),
}

impl JointConfigBlock {
    /// Bytes of the block.
    pub const LEN: usize = 32;
    /// The magic at bytes 0..4.
    pub const MAGIC: [u8; 4] = *b"JCFG";
    /// The layout version this firmware writes and reads.
    pub const VERSION: u8 = 2;
    /// Offset of the bus key.
    const KEY_AT: usize = 8;
    /// Offset of the CRC.
    const CRC_AT: usize = Self::LEN - 2;

    /// The block's bytes, as they go into the configuration page.
    pub fn encode(&self) -> [u8; Self::LEN] {
        let mut b = [0u8; Self::LEN];
        b[..4].copy_from_slice(&Self::MAGIC);
        b[4] = Self::VERSION;
        b[5] = self.joint_number;
        b[Self::KEY_AT..Self::KEY_AT + 16].copy_from_slice(&self.bus_key);
        let crc = crc16(&b[..Self::CRC_AT]);
        b[Self::CRC_AT..].copy_from_slice(&crc.to_le_bytes());
        b
    }

    /// Reads a block, checking erasure, magic, version, CRC, the reserved bytes and
    /// the key in that order (the joint number is checked against the model by
    /// [`select_joint`]).
    pub fn decode(b: &[u8; Self::LEN]) -> Result<Self, JointConfigFault> {
        if b.iter().all(|&x| x == 0xFF) {
            return Err(JointConfigFault::Erased);
        }
        if b[..4] != Self::MAGIC {
            return Err(JointConfigFault::BadMagic);
        }
        if b[4] != Self::VERSION {
            return Err(JointConfigFault::UnsupportedVersion(b[4]));
        }
        let crc = u16::from_le_bytes([b[Self::CRC_AT], b[Self::CRC_AT + 1]]);
        if crc16(&b[..Self::CRC_AT]) != crc {
            return Err(JointConfigFault::BadCrc);
        }
        let reserved = b[6..Self::KEY_AT]
            .iter()
            .chain(&b[Self::KEY_AT + 16..Self::CRC_AT]);
        if reserved.into_iter().any(|&x| x != 0) {
            return Err(JointConfigFault::ReservedNotZero);
        }
        let mut bus_key = [0u8; 16];
        bus_key.copy_from_slice(&b[Self::KEY_AT..Self::KEY_AT + 16]);
        if bus_key.iter().all(|&x| x == 0) || bus_key.iter().all(|&x| x == 0xFF) {
            return Err(JointConfigFault::NoBusKey);
        }
        Ok(Self {
            joint_number: b[5],
            bus_key,
        })
    }
}

/// The joint a board was configured for, among the compiled-in model's joints.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct JointSlot {
    /// Index among the model's compensated joints (`JOINT_INDICES`, `JOINT_PROFILES`,
    /// `CompensatorConfig::own_joint`, the state bus's joint index).
    pub slot: usize,
    /// The robot joint, counted from 1.
    pub joint_number: u8,
    /// The robot's state-bus key from the block.
    pub bus_key: [u8; 16],
}

/// This board's slot from its configuration block `block` and the compiled-in
/// model's compensated joints (`joint_indices`, 0-based robot joints) and profiles.
pub fn select_joint<const J: usize>(
    block: &[u8; JointConfigBlock::LEN],
    joint_indices: &[usize; J],
    profiles: &[JointProfile; J],
) -> Result<JointSlot, JointConfigFault> {
    let c = JointConfigBlock::decode(block)?;
    let wanted = (c.joint_number as usize).checked_sub(1);
    let slot = joint_indices
        .iter()
        .position(|&j| Some(j) == wanted)
        .ok_or(JointConfigFault::JointNotCompensated(c.joint_number))?;
    match profiles.get(slot).map(JointProfile::invalid_field) {
        Some(None) => Ok(JointSlot {
            slot,
            joint_number: c.joint_number,
            bus_key: c.bus_key,
        }),
        Some(Some(field)) => Err(JointConfigFault::InvalidProfile(field)),
        None => Err(JointConfigFault::JointNotCompensated(c.joint_number)),
    }
}

/// What the board runs after start-up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StartupPlan {
    /// The configured joint, or why there is none.
    pub joint: Result<JointSlot, JointConfigFault>,
    /// The drive's configuration: the joint's profile; on a refusal, the profile all
    /// compensated joints share if their drive settings agree, else `None` (the
    /// bridge stays off).
    pub drive: Option<DriveConfig>,
    /// The compensator's configuration; `None` on a refusal (no feedforward, no state
    /// frames).
    pub compensator: Option<CompensatorConfig>,
    /// The compensator's friction adaptation (`Compensator::with_adaptation`); off on
    /// a refusal.
    pub adaptation: AdaptationConfig,
    /// The compensator's do-no-harm monitor (`Compensator::with_monitor`); off on a
    /// refusal.
    pub monitor: MonitorConfig,
}

/// The start-up decision: [`select_joint`], then the drive and compensator
/// configurations of that joint's profile at PWM rate `pwm_hz` and compensator rate
/// `rate_hz`.
pub fn plan_startup<const J: usize>(
    block: &[u8; JointConfigBlock::LEN],
    joint_indices: &[usize; J],
    profiles: &[JointProfile; J],
    pwm_hz: f32,
    rate_hz: u32,
) -> StartupPlan {
    match select_joint(block, joint_indices, profiles) {
        Ok(j) => {
            let p = profiles.get(j.slot);
            StartupPlan {
                joint: Ok(j),
                drive: p.map(|p| p.drive_config(pwm_hz)),
                compensator: p.map(|p| p.compensator_config(rate_hz, j.slot)),
                adaptation: p.map_or(AdaptationConfig::OFF, |p| p.adaptation),
                monitor: p.map_or(MonitorConfig::OFF, |p| p.monitor),
            }
        }
        Err(fault) => {
            let first = profiles.first().filter(|p| p.invalid_field().is_none());
            let shared = first
                .map(|p| p.drive_config(pwm_hz))
                .filter(|d| profiles.iter().all(|p| p.drive_config(pwm_hz) == *d));
            StartupPlan {
                joint: Err(fault),
                drive: shared,
                compensator: None,
                adaptation: AdaptationConfig::OFF,
                monitor: MonitorConfig::OFF,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const WRIST: [usize; 3] = [3, 4, 5];
    const PROFILES: [JointProfile; 3] = [JointProfile::BOARD; 3];

    const KEY: [u8; 16] = *b"0123456789abcdef";

    fn block(joint: u8) -> [u8; JointConfigBlock::LEN] {
        JointConfigBlock {
            joint_number: joint,
            bus_key: KEY,
        }
        .encode()
    }

    #[test]
    fn the_block_has_its_documented_layout() {
        let b = block(5);
        assert_eq!(&b[..4], b"JCFG");
        assert_eq!(b[4], 2);
        assert_eq!(b[5], 5);
        assert!(b[6..8].iter().all(|&x| x == 0));
        assert_eq!(b[8..24], KEY);
        assert!(b[24..30].iter().all(|&x| x == 0));
        assert_eq!(u16::from_le_bytes([b[30], b[31]]), crc16(&b[..30]));
        assert_eq!(
            JointConfigBlock::decode(&b),
            Ok(JointConfigBlock {
                joint_number: 5,
                bus_key: KEY
            })
        );
    }

    #[test]
    fn a_valid_block_selects_its_joints_slot() {
        for (number, slot) in [(4u8, 0usize), (5, 1), (6, 2)] {
            assert_eq!(
                select_joint(&block(number), &WRIST, &PROFILES),
                Ok(JointSlot {
                    slot,
                    joint_number: number,
                    bus_key: KEY,
                })
            );
        }
    }

    #[test]
    fn bad_blocks_are_refused() {
        assert_eq!(
            select_joint(&[0xFF; JointConfigBlock::LEN], &WRIST, &PROFILES),
            Err(JointConfigFault::Erased)
        );
        assert_eq!(
            select_joint(&[0; JointConfigBlock::LEN], &WRIST, &PROFILES),
            Err(JointConfigFault::BadMagic)
        );
        // Every single-bit flip of a valid block is refused (none selects a joint).
        let good = block(5);
        for byte in 0..JointConfigBlock::LEN {
            for bit in 0..8 {
                let mut b = good;
                b[byte] ^= 1 << bit;
                let r = select_joint(&b, &WRIST, &PROFILES);
                assert!(r.is_err(), "flip of byte {byte} bit {bit}: {r:?}");
                if byte >= 5 {
                    assert_eq!(r, Err(JointConfigFault::BadCrc), "byte {byte} bit {bit}");
                }
            }
        }
        // The first layout (no key), with its own CRC: refused by version.
        let mut b = good;
        b[4] = 1;
        let crc = crc16(&b[..30]).to_le_bytes();
        b[30..].copy_from_slice(&crc);
        assert_eq!(
            select_joint(&b, &WRIST, &PROFILES),
            Err(JointConfigFault::UnsupportedVersion(1))
        );
        // Reserved bytes set, with a matching CRC: a layout this firmware does not read.
        for at in [6, 7, 24, 29] {
            let mut b = good;
            b[at] = 1;
            let crc = crc16(&b[..30]).to_le_bytes();
            b[30..].copy_from_slice(&crc);
            assert_eq!(
                select_joint(&b, &WRIST, &PROFILES),
                Err(JointConfigFault::ReservedNotZero),
                "byte {at}"
            );
        }
        // An unprovisioned key.
        for key in [[0u8; 16], [0xFF; 16]] {
            let b = JointConfigBlock {
                joint_number: 5,
                bus_key: key,
            }
            .encode();
            assert_eq!(
                select_joint(&b, &WRIST, &PROFILES),
                Err(JointConfigFault::NoBusKey)
            );
        }
        // Joints the model does not compensate, and joint 0.
        for n in [0u8, 1, 3, 7, 255] {
            assert_eq!(
                select_joint(&block(n), &WRIST, &PROFILES),
                Err(JointConfigFault::JointNotCompensated(n))
            );
        }
        let mut bad = PROFILES;
        bad[2].bus_max_v = f32::NAN;
        assert_eq!(
            select_joint(&block(6), &WRIST, &bad),
            Err(JointConfigFault::InvalidProfile("bus_max_v"))
        );
        assert!(select_joint(&block(5), &WRIST, &bad).is_ok());
    }

    #[test]
    fn a_refusal_runs_no_feedforward_and_drives_only_with_a_shared_profile() {
        let plan = plan_startup(
            &[0xFF; JointConfigBlock::LEN],
            &WRIST,
            &PROFILES,
            20_000.0,
            100,
        );
        assert_eq!(plan.joint, Err(JointConfigFault::Erased));
        assert_eq!(plan.compensator, None);
        assert_eq!(plan.adaptation, AdaptationConfig::OFF);
        assert_eq!(plan.drive, Some(JointProfile::BOARD.drive_config(20_000.0)));
        // Joints with different drives: no drive the board could be sure of.
        let mut mixed = PROFILES;
        mixed[1].gear_ratio = 160.0;
        let plan = plan_startup(&block(2), &WRIST, &mixed, 20_000.0, 100);
        assert_eq!(plan.joint, Err(JointConfigFault::JointNotCompensated(2)));
        assert_eq!(plan.drive, None);
        assert_eq!(plan.compensator, None);
        // Configured: that joint's own drive.
        mixed[1].adaptation.time_constant_s = 5.0;
        let plan = plan_startup(&block(5), &WRIST, &mixed, 20_000.0, 100);
        assert_eq!(plan.drive.map(|d| d.gear_ratio), Some(160.0));
        assert_eq!(plan.compensator.map(|c| c.own_joint), Some(1));
        assert_eq!(plan.adaptation, mixed[1].adaptation);
    }
}
