//! Named fault flags of the control loop: a bitflags-like `u32` (bits 0-15 the control loop's first set; bit 16 and up: the do-no-harm layer and the state bus).

/// A set of named faults (one bit each). Each flag says why an output was limited,
/// held or replaced by a safe value.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FaultFlags(u32);

impl FaultFlags {
    /// No fault.
    pub const NONE: Self = Self(0);
    /// A joint-state message was rejected: a non-finite or out-of-range field, a
    /// joint index outside the modelled joints, or (synchronised bus time) a
    /// timestamp already over age when it arrived.
    pub const STATE_REJECTED: Self = Self(1 << 0);
    /// Watchdog: another modelled joint's state is older than the timeout; the
    /// feedforward falls back to zero.
    pub const STATE_STALE: Self = Self(1 << 1);
    /// A joint-state message did not continue its sender's stream (a replayed, older
    /// or far-ahead sequence number: dropped; a new session: the stream restarts);
    /// for `watchdog_ticks` ticks after such a conflict the feedforward is zero and
    /// this flag is set.
    pub const STATE_OUT_OF_ORDER: Self = Self(1 << 2);
    /// This joint's own state was non-finite or out of range; feedforward is zero.
    pub const OWN_STATE_INVALID: Self = Self(1 << 3);
    /// The dynamics model's prediction was non-finite or out of range; feedforward is zero.
    pub const MODEL_INVALID: Self = Self(1 << 4);
    /// The LSTM's prediction was non-finite or out of range; it is reset and the
    /// feedforward falls back to the model only.
    pub const LSTM_INVALID: Self = Self(1 << 5);
    /// The LSTM's correction to the model exceeded the plausible residual; it is reset
    /// and the feedforward falls back to the model only.
    pub const LSTM_IMPLAUSIBLE: Self = Self(1 << 6);
    /// The feedforward's rate limit acted this tick.
    pub const FF_RATE_LIMITED: Self = Self(1 << 7);
    /// The feedforward's magnitude limit acted this tick.
    pub const FF_MAGNITUDE_LIMITED: Self = Self(1 << 8);
    /// The feedforward (or the LSTM's share of it) is blending in after a reset.
    pub const FF_WARMUP: Self = Self(1 << 9);
    /// A sensor reading (phase current, rotor angle, bus voltage) was non-finite or
    /// out of range; the bridge outputs zero voltage and the integrators reset.
    pub const SENSOR_INVALID: Self = Self(1 << 10);
    /// A phase current exceeded the trip level; the bridge outputs zero voltage.
    pub const OVERCURRENT: Self = Self(1 << 11);
    /// The bus voltage is outside the drive's operating range; zero voltage.
    pub const BUS_VOLTAGE: Self = Self(1 << 12);
    /// The q-current reference was clamped to the drive's current limit.
    pub const IQ_CLAMPED: Self = Self(1 << 13);
    /// The dq voltage vector was limited to the bus voltage's circle.
    pub const VOLTAGE_LIMITED: Self = Self(1 << 14);
    /// A trajectory reference or feedforward current was non-finite or out of
    /// range and was replaced (reference held, feedforward zero).
    pub const REFERENCE_INVALID: Self = Self(1 << 15);
    /// The joint's state is outside its training envelope (`crate::envelope`): the
    /// learned share of the feedforward is faded by a weight below 1.
    pub const ENVELOPE_OUTSIDE: Self = Self(1 << 16);
    /// The do-no-harm monitor (`crate::monitor`) holds the compensation's gain below 1:
    /// over its window the measured torque showed the compensation doing harm.
    pub const COMPENSATION_FADED: Self = Self(1 << 17);
    /// A state-bus frame failed its authentication (MAC, or a malformed frame): it
    /// was counted and dropped, never used.
    pub const FRAME_UNAUTHENTICATED: Self = Self(1 << 18);
    /// Another modelled joint's real sender was not heard (no accepted,
    /// authenticated frame) within the watchdog bound; its state is not used and
    /// the feedforward falls back to zero (with `STATE_STALE`).
    pub const SENDER_SILENT: Self = Self(1 << 19);

    /// Every flag with its name, in bit order (new flags take the next bit and an
    /// entry here).
    pub const NAMED: [(Self, &'static str); 20] = [
        (Self::STATE_REJECTED, "STATE_REJECTED"),
        (Self::STATE_STALE, "STATE_STALE"),
        (Self::STATE_OUT_OF_ORDER, "STATE_OUT_OF_ORDER"),
        (Self::OWN_STATE_INVALID, "OWN_STATE_INVALID"),
        (Self::MODEL_INVALID, "MODEL_INVALID"),
        (Self::LSTM_INVALID, "LSTM_INVALID"),
        (Self::LSTM_IMPLAUSIBLE, "LSTM_IMPLAUSIBLE"),
        (Self::FF_RATE_LIMITED, "FF_RATE_LIMITED"),
        (Self::FF_MAGNITUDE_LIMITED, "FF_MAGNITUDE_LIMITED"),
        (Self::FF_WARMUP, "FF_WARMUP"),
        (Self::SENSOR_INVALID, "SENSOR_INVALID"),
        (Self::OVERCURRENT, "OVERCURRENT"),
        (Self::BUS_VOLTAGE, "BUS_VOLTAGE"),
        (Self::IQ_CLAMPED, "IQ_CLAMPED"),
        (Self::VOLTAGE_LIMITED, "VOLTAGE_LIMITED"),
        (Self::REFERENCE_INVALID, "REFERENCE_INVALID"),
        (Self::ENVELOPE_OUTSIDE, "ENVELOPE_OUTSIDE"),
        (Self::COMPENSATION_FADED, "COMPENSATION_FADED"),
        (Self::FRAME_UNAUTHENTICATED, "FRAME_UNAUTHENTICATED"),
        (Self::SENDER_SILENT, "SENDER_SILENT"),
    ];

    /// The raw bits.
    #[inline]
    pub const fn bits(self) -> u32 {
        self.0
    }
    /// Flags from raw bits (every bit is named, so any value is valid).
    #[inline]
    pub const fn from_bits(bits: u32) -> Self {
        Self(bits)
    }
    /// True when no flag is set.
    #[inline]
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }
    /// True when every flag of `other` is set in `self`.
    #[inline]
    pub const fn contains(self, other: Self) -> bool {
        self.0 & other.0 == other.0
    }
    /// True when any flag of `other` is set in `self`.
    #[inline]
    pub const fn intersects(self, other: Self) -> bool {
        self.0 & other.0 != 0
    }
    /// Set the flags of `other`.
    #[inline]
    pub fn insert(&mut self, other: Self) {
        self.0 |= other.0;
    }
    /// Clear the flags of `other`.
    #[inline]
    pub fn remove(&mut self, other: Self) {
        self.0 &= !other.0;
    }
    /// Set the flags of `other` when `cond` holds.
    #[inline]
    pub fn set_if(&mut self, other: Self, cond: bool) {
        if cond {
            self.insert(other);
        }
    }
    /// The union of two sets.
    #[inline]
    pub const fn union(self, other: Self) -> Self {
        Self(self.0 | other.0)
    }
}

impl core::ops::BitOr for FaultFlags {
    type Output = Self;
    fn bitor(self, rhs: Self) -> Self {
        self.union(rhs)
    }
}

impl core::ops::BitOrAssign for FaultFlags {
    fn bitor_assign(&mut self, rhs: Self) {
        self.insert(rhs);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn set_if_and_union() {
        let mut f = FaultFlags::NONE;
        f.set_if(FaultFlags::STATE_STALE, false);
        assert!(f.is_empty());
        f.set_if(FaultFlags::STATE_STALE, true);
        assert_eq!(f, FaultFlags::STATE_STALE);
        let u = FaultFlags::STATE_STALE.union(FaultFlags::STATE_STALE);
        assert_eq!(u, FaultFlags::STATE_STALE);
        assert_eq!(
            f.union(FaultFlags::OVERCURRENT).bits(),
            FaultFlags::STATE_STALE.bits() | FaultFlags::OVERCURRENT.bits()
        );
    }

    #[test]
    fn every_bit_has_one_name() {
        let mut all = 0u32;
        let mut last = 0u32;
        for (flag, _) in FaultFlags::NAMED.iter() {
            // One bit each, in bit order, none named twice.
            assert_eq!(flag.bits().count_ones(), 1);
            assert!(flag.bits() > last);
            last = flag.bits();
            all |= flag.bits();
        }
        // The control loop's sixteen, the do-no-harm layer's two (16, 17) and the
        // state bus's two (18, 19): none skipped.
        assert_eq!(all, (1u32 << FaultFlags::NAMED.len()) - 1);
        let mut f = FaultFlags::NONE;
        f.insert(FaultFlags::STATE_STALE | FaultFlags::OVERCURRENT);
        assert!(f.contains(FaultFlags::STATE_STALE) && !f.contains(FaultFlags::LSTM_INVALID));
        f.remove(FaultFlags::STATE_STALE);
        assert_eq!(f, FaultFlags::OVERCURRENT);
    }
}
