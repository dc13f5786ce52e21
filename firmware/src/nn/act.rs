//! Fixed-point activations: the logistic sigmoid and tanh of an integer accumulator by
//! direct lookup in an 8192-entry table over [-8, 8) (step 1/512; each entry holds the
//! value at its interval's midpoint, Q0.15). Integer only, no division, no branch:
//! identical on host and target, and two Cortex-M4 instructions per activation in the
//! kernels: `SSAT` of the index, with the accumulator's power-of-two scale folded into
//! its shift, and `LDRSH` (see [`lookup`]).
//!
//! Why direct lookup rather than interpolation: interpolating costs two more
//! instructions per activation (the fraction bits and their multiply), about 200
//! estimated cycles per step of the per-joint network's 96 activations, a sixth of what
//! its cycle goal leaves beside the multiply-accumulates. The finer table keeps the
//! worst-case error within 33 LSB of Q0.15 for tanh and 12 for the sigmoid (11 of them
//! its saturation beyond +-8, as before; the `*_error_bound` tests; an interpolated
//! 1025-entry table had 4), and the exporter's accuracy report measures what that costs
//! on the compensated torque.
//!
//! The tables are written by `build.rs` with `libm` (the same bits on every build
//! machine) and checked against the f64 formula by `tables_match_f64`. Both end flat
//! (sigmoid 11 and 32757, tanh -32767 and 32767), so a saturated index gives the end
//! value.
//!
//! Placement: the values are defined once ([`ACT_TABLE_VALUES`]) and held by two
//! statics, [`ACT_TABLES_FLASH`] (`.rodata`) and [`ACT_TABLES_SRAM`] (the SRAM input
//! section of the exporter's model arrays, copied from flash at reset). A compiled-in
//! network reads the one its model file names (`QuantFormat::ACT_TABLES`, chosen by the
//! exporter from the model's size against the board's SRAM budget); the linker keeps
//! only the statics something refers to, so a board image holds one copy (32 KiB).

include!(concat!(env!("OUT_DIR"), "/act_tables.rs"));

/// Both tables, `[sigmoid, tanh]` (rows [`SIGMOID`], [`TANH`]), Q0.15.
pub type ActTables = [[i16; TABLE_LEN]; 2];

/// The tables in flash (`.rodata`): read through the flash interface and its data cache.
pub static ACT_TABLES_FLASH: ActTables = ACT_TABLE_VALUES;

/// The tables in SRAM (`.data`, copied from flash at reset): zero wait states. The
/// attribute line is the one the exporter writes before a model's arrays placed in SRAM.
#[cfg_attr(
    target_os = "none",
    allow(unsafe_code),
    unsafe(link_section = ".data.model_arrays")
)]
pub static ACT_TABLES_SRAM: ActTables = ACT_TABLE_VALUES;

/// Bytes of one copy of the tables (what placing them in SRAM costs).
pub const ACT_TABLES_BYTES: usize = core::mem::size_of::<ActTables>();

/// Entries per table.
pub const TABLE_LEN: usize = 8192;
/// Index bits: the index saturates to `-4096..=4095` (`SSAT #13`).
pub const INDEX_BITS: u32 = 13;
/// Fraction bits of the table's grid (step `2^-9`).
pub const GRID_FRAC_BITS: u32 = 9;
/// Row of the sigmoid in [`ActTables`].
pub const SIGMOID: usize = 0;
/// Row of tanh in [`ActTables`].
pub const TANH: usize = 1;

const HALF: i32 = (TABLE_LEN / 2) as i32;

/// Whether `shift` is a valid index shift (`1..=31`: what `SSAT ..., ASR #shift` encodes).
pub const fn shift_fits(shift: u32) -> bool {
    shift >= 1 && shift <= 31
}

/// The table index of `acc * 2^-(shift + 9)`: `sat13(acc >> shift)`, `-4096..=4095`.
#[inline(always)]
pub fn index(acc: i32, shift: u32) -> i32 {
    (acc >> (shift & 31)).clamp(-HALF, HALF - 1)
}

/// `f(acc * 2^-(shift + 9))`, Q0.15, for the function in row `f` of `tables`
/// ([`SIGMOID`] or [`TANH`]); `shift` is `E - 9` for an accumulator with `E` fraction bits.
#[inline(always)]
pub fn lookup(tables: &ActTables, f: usize, acc: i32, shift: u32) -> i16 {
    let k = (index(acc, shift) + HALF) as usize;
    tables.get(f).and_then(|t| t.get(k)).copied().unwrap_or(0)
}

/// Logistic sigmoid of `acc * 2^-(shift + 9)`, Q0.15, from `tables`.
#[inline(always)]
pub fn sigmoid_q15(tables: &ActTables, acc: i32, shift: u32) -> i16 {
    lookup(tables, SIGMOID, acc, shift)
}

/// tanh of `acc * 2^-(shift + 9)`, Q0.15, from `tables`.
#[inline(always)]
pub fn tanh_q15(tables: &ActTables, acc: i32, shift: u32) -> i16 {
    lookup(tables, TANH, acc, shift)
}

/// The identity of an accumulator, requantised: `sat16(acc >> shift)` (one `SSAT #16`
/// with the shift; the linear input layer's `e`, rounded to nearest by the half-step the
/// exporter adds to its bias).
#[inline(always)]
pub fn linear_i16(acc: i32, shift: u32) -> i16 {
    (acc >> (shift & 31)).clamp(i16::MIN as i32, i16::MAX as i32) as i16
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linear_requantisation_is_a_saturating_floor_shift() {
        for (acc, shift, want) in [
            (0x1234_5678, 8, i16::MAX),
            (-0x1234_5678, 8, i16::MIN),
            (0x0012_3456, 8, 0x1234),
            (-0x0012_3456, 8, -0x1235),
            (-1, 3, -1),
            (7, 3, 0),
            (i32::MAX, 31, 0),
            (i32::MIN, 31, -1),
        ] {
            assert_eq!(linear_i16(acc, shift), want, "{acc:#x} >> {shift}");
        }
    }

    fn sigmoid(x: f64) -> f64 {
        1.0 / (1.0 + (-x).exp())
    }

    const T: &ActTables = &ACT_TABLES_FLASH;

    #[test]
    fn both_placements_hold_the_same_values() {
        assert_eq!(ACT_TABLES_FLASH, ACT_TABLE_VALUES);
        assert_eq!(ACT_TABLES_SRAM, ACT_TABLE_VALUES);
        assert!(!core::ptr::eq(&ACT_TABLES_FLASH, &ACT_TABLES_SRAM));
        assert_eq!(ACT_TABLES_BYTES, 32_768);
    }

    #[test]
    fn tables_match_f64() {
        let rows = T[SIGMOID].iter().zip(&T[TANH]);
        for (k, (&sig, &tanh)) in rows.enumerate() {
            let x = (k as f64 - 4096.0 + 0.5) / 512.0;
            let s = ((sigmoid(x) * 32768.0).round() as i32).clamp(0, 32767);
            let t = ((x.tanh() * 32768.0).round() as i32).clamp(-32767, 32767);
            assert_eq!(sig as i32, s, "sigmoid {k}");
            assert_eq!(tanh as i32, t, "tanh {k}");
        }
    }

    /// Worst |error| in Q0.15 LSB over a dense sweep of [-12, 12] at Q3.12 (shift 3).
    fn max_err_lsb(f: usize, g: fn(f64) -> f64) -> f64 {
        (-12 * 4096..12 * 4096)
            .map(|a: i32| (lookup(T, f, a, 3) as f64 - g(a as f64 / 4096.0) * 32768.0).abs())
            .fold(0.0, f64::max)
    }

    #[test]
    fn tanh_error_bound() {
        let e = max_err_lsb(TANH, f64::tanh);
        assert!(e < 33.0, "tanh max error {e} LSB");
        assert_eq!(tanh_q15(T, i32::MAX, 1), 32767);
        assert_eq!(tanh_q15(T, i32::MIN, 1), -32767);
        // Odd: the midpoint grid is symmetric about zero.
        assert_eq!(tanh_q15(T, -1, 0), -tanh_q15(T, 0, 0));
    }

    #[test]
    fn sigmoid_error_bound() {
        let e = max_err_lsb(SIGMOID, sigmoid);
        assert!(e < 12.0, "sigmoid max error {e} LSB");
        assert_eq!(sigmoid_q15(T, i32::MIN, 1), 11);
        assert_eq!(sigmoid_q15(T, i32::MAX, 1), 32757);
        assert_eq!(
            sigmoid_q15(T, -1, 0) as i32 + sigmoid_q15(T, 0, 0) as i32,
            32768
        );
    }

    #[test]
    fn the_shift_sets_the_scale() {
        // 1.5 with 12 fraction bits (shift 3) and with 25 (shift 16): the same entry.
        assert_eq!(index(6144, 3), 768);
        assert_eq!(index(6144 << 13, 16), 768);
        assert_eq!(index(i32::MAX, 1), 4095);
        assert_eq!(index(i32::MIN, 1), -4096);
    }
}
