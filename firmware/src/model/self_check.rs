//! The self-check contract between the exporter and every build of a model file: the
//! golden input stream (integer hashing and exact f32 arithmetic, no libm: the same bits
//! on host and target) and the FNV-1a digest of the outputs. `model-export export`
//! streams the network over [`input`] for `SELF_CHECK_STEPS` steps and writes the
//! [`Digest`] as `SELF_CHECK_FNV`; the test kit streams the compiled model the same way
//! and compares (and the QEMU suites use the same stream).

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

/// A 32-bit integer hash (lowbias32), the generator behind the golden inputs.
pub const fn hash(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

/// Maps a hash to [0, 1) with 24 bits of resolution (exact in f32).
pub fn unit(h: u32) -> f32 {
    (h >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// FNV-1a over output bits (each f32's bits, little-endian), the digest the exporter
/// writes as `SELF_CHECK_FNV`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_digest_is_fnv_1a_over_the_output_bytes() {
        // FNV-1a 64 of the empty input is its offset basis; of the bytes of 1.0f32
        // (00 00 80 3f) the reference value below (computed byte by byte).
        assert_eq!(Digest::default().0, 0xcbf2_9ce4_8422_2325);
        let mut d = Digest::default();
        d.add(&[1.0]);
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        for b in [0x00u8, 0x00, 0x80, 0x3f] {
            h = (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3);
        }
        assert_eq!(d.0, h);
        assert_ne!(d, Digest::default());
    }

    #[test]
    fn the_inputs_are_bounded_and_deterministic() {
        for t in 0..2_000 {
            let x: [f32; 9] = inputs(t);
            assert_eq!(x, inputs::<9>(t));
            assert!(
                x.iter().all(|v| v.is_finite() && v.abs() <= 4.0),
                "{t}: {x:?}"
            );
        }
    }
}
