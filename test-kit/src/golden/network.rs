//! Golden inputs of the quantised networks' self-check and of the QEMU suites: a
//! deterministic stream of raw features from integer hashing and exact f32
//! arithmetic (no libm), the same on host and target.
use super::{hash, unit};

/// Streaming steps of the bit-exact suites (host vs QEMU).
pub const STEPS: usize = 10_000;

/// Feature `k` at step `t`: a triangle wave of period depending on `k` (amplitude 3)
/// plus hashed noise in [-1, 1), so the state sees structure and saturation.
pub fn input(t: usize, k: usize) -> f32 {
    let period = 97 + 31 * k as u32;
    let phase = (t as u32 % period) as f32 / period as f32;
    let tri = 4.0 * if phase < 0.5 { phase } else { 1.0 - phase } - 1.0;
    3.0 * tri + 2.0 * unit(hash((t as u32).wrapping_mul(16) ^ k as u32 ^ 0x51a7_0000)) - 1.0
}

/// The golden input vector at step `t`.
pub fn inputs<const I: usize>(t: usize) -> [f32; I] {
    core::array::from_fn(|k| input(t, k))
}

/// FNV-1a over output bits, the digest the exporter writes as `SELF_CHECK_FNV`.
#[derive(Clone, Copy, Debug)]
pub struct Digest(pub u64);

impl Default for Digest {
    fn default() -> Self {
        Digest(0xcbf2_9ce4_8422_2325)
    }
}

impl Digest {
    /// Adds one step's outputs.
    pub fn add(&mut self, ys: &[f32]) {
        for y in ys {
            for b in y.to_bits().to_le_bytes() {
                self.0 ^= b as u64;
                self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
            }
        }
    }
}
