//! Cortex-M4 DSP kernels: the firmware's only inline assembly.
//!
//! rustc 1.95 never emits SMLAD for a plain int16 dot product (about 3.6 instructions
//! per MAC); these kernels issue it explicitly over 4 interleaved weight rows
//! (about 1.4 estimated cycles per MAC). Every kernel has a portable twin in plain
//! Rust with the same wrapping semantics; the host (and any target without the DSP
//! extension) runs the twin, the Cortex-M4 the assembly, and the QEMU golden suites
//! (`host-tests`) prove both give the same bits.
//!
//! The assembly is selected by `cfg(fw_dsp_asm)`, which `firmware/build.rs` sets for
//! `thumbv7em-*` and `thumbv8m.main-*` targets (stable Rust does not expose
//! `target_feature = "dsp"` in `cfg`).
//!
//! Packing: an int16 pair is one `u32` word, element `k` in the low half, `k+1` in the
//! high half (little-endian, the order SMLAD multiplies in). An int8 word holds four
//! weights of one row for the columns `k..k+4` in the byte order `[w_k, w_k+2, w_k+1,
//! w_k+3]`, so that `SXTB16 w` gives the int16 pair `(w_k, w_k+1)` and `SXTB16 w, ROR #8`
//! the pair `(w_k+2, w_k+3)`.
#![allow(unsafe_code)]

/// Packs two int16 values into one word: `lo` in bits 0..16, `hi` in bits 16..32.
#[inline(always)]
pub const fn pack(lo: i16, hi: i16) -> u32 {
    (lo as u16 as u32) | ((hi as u16 as u32) << 16)
}

/// The two int16 values of a packed word, `(lo, hi)`.
#[inline(always)]
pub const fn unpack(w: u32) -> (i16, i16) {
    (w as u16 as i16, (w >> 16) as u16 as i16)
}

/// Packs four int8 weights of columns `k..k+4` in the `SXTB16` order.
#[inline(always)]
pub const fn pack_i8(w: [i8; 4]) -> u32 {
    u32::from_le_bytes([w[0] as u8, w[2] as u8, w[1] as u8, w[3] as u8])
}

/// SMLAD: `acc + lo(a)*lo(b) + hi(a)*hi(b)`, wrapping modulo 2^32 like the instruction.
#[inline(always)]
pub const fn smlad(acc: i32, a: u32, b: u32) -> i32 {
    let (a0, a1) = unpack(a);
    let (b0, b1) = unpack(b);
    acc.wrapping_add((a0 as i32) * (b0 as i32))
        .wrapping_add((a1 as i32) * (b1 as i32))
}

/// SXTB16: bytes 0 and 2 sign-extended into the low and high halves.
#[inline(always)]
pub const fn sxtb16(w: u32) -> u32 {
    let b = w.to_le_bytes();
    pack(b[0] as i8 as i16, b[2] as i8 as i16)
}

/// Four-row int16 dot products: `acc[r] + sum_p SMLAD(w[p][r], x[p])`.
///
/// `w[q][p]` holds the packed pair `p` (0: columns `4q, 4q+1`; 1: `4q+2, 4q+3`) of
/// rows 0..4 (the exporter's interleaved layout), `x[q][p]` the same pair of the input
/// vector; `min(w.len(), x.len())` quads are summed. The caller guarantees the sums
/// fit in `i32` (the exporter proves it for every row); otherwise both versions wrap
/// identically.
#[inline(always)]
pub fn dot4_i16(acc: [i32; 4], w: &[[[u32; 4]; 2]], x: &[[u32; 2]]) -> [i32; 4] {
    let n = w.len().min(x.len());
    if n == 0 {
        return acc;
    }
    #[cfg(fw_dsp_asm)]
    {
        // SAFETY: 0 < n <= w.len(), x.len().
        unsafe { asm::dot4_i16(acc, w.as_ptr(), x.as_ptr(), n) }
    }
    #[cfg(not(fw_dsp_asm))]
    {
        portable::dot4_i16(acc, w, x)
    }
}

/// Four-row int8-weight x int16-activation dot products: `acc[r] + sum_q` of the four
/// products of `w[q][r]` (four int8 weights, `SXTB16` order) with `x[q]` (two packed
/// int16 pairs); `min(w.len(), x.len())` quads are summed.
#[inline(always)]
pub fn dot4_i8(acc: [i32; 4], w: &[[u32; 4]], x: &[[u32; 2]]) -> [i32; 4] {
    let n = w.len().min(x.len());
    if n == 0 {
        return acc;
    }
    #[cfg(fw_dsp_asm)]
    {
        // SAFETY: 0 < n <= w.len(), x.len().
        unsafe { asm::dot4_i8(acc, w.as_ptr(), x.as_ptr(), n) }
    }
    #[cfg(not(fw_dsp_asm))]
    {
        portable::dot4_i8(acc, w, x)
    }
}

/// Four-row f32 dot products, each row summed left to right with a separate multiply
/// and add (IEEE single, round to nearest; the bits of the portable twin):
/// `acc[r] + w[0][r]*x[0] + w[1][r]*x[1] + ...` over `min(w.len(), x.len())` columns.
/// `w[k]` holds column `k` of the 4 rows. On the Cortex-M4F: VLDM + VMUL + VADD
/// (rustc emits VLDR per value); the FPU registers it uses are saved and restored
/// inside the assembly (stable Rust rejects the `sreg` operand class here).
#[inline(always)]
pub fn dot4_f32(acc: [f32; 4], w: &[[f32; 4]], x: &[f32]) -> [f32; 4] {
    let n = w.len().min(x.len());
    if n == 0 {
        return acc;
    }
    #[cfg(fw_dsp_asm)]
    {
        // SAFETY: 0 < n <= w.len(), x.len().
        unsafe { asm::dot4_f32(acc, w.as_ptr(), x.as_ptr(), n) }
    }
    #[cfg(not(fw_dsp_asm))]
    {
        portable::dot4_f32(acc, w, x)
    }
}

/// The portable twins (always compiled, so the host tests them and the target can
/// compare).
pub mod portable {
    use super::{smlad, sxtb16};

    /// Portable [`super::dot4_i16`].
    #[inline(always)]
    pub fn dot4_i16(mut acc: [i32; 4], w: &[[[u32; 4]; 2]], x: &[[u32; 2]]) -> [i32; 4] {
        for (wq, xq) in w.iter().zip(x.iter()) {
            for (wp, &xp) in wq.iter().zip(xq.iter()) {
                for (a, &wr) in acc.iter_mut().zip(wp.iter()) {
                    *a = smlad(*a, wr, xp);
                }
            }
        }
        acc
    }

    /// Portable [`super::dot4_f32`].
    #[inline(always)]
    pub fn dot4_f32(mut acc: [f32; 4], w: &[[f32; 4]], x: &[f32]) -> [f32; 4] {
        for (wk, xk) in w.iter().zip(x.iter()) {
            acc[0] += wk[0] * xk;
            acc[1] += wk[1] * xk;
            acc[2] += wk[2] * xk;
            acc[3] += wk[3] * xk;
        }
        acc
    }

    /// Portable [`super::dot4_i8`].
    #[inline(always)]
    pub fn dot4_i8(mut acc: [i32; 4], w: &[[u32; 4]], x: &[[u32; 2]]) -> [i32; 4] {
        for (wq, xq) in w.iter().zip(x.iter()) {
            for (a, &wr) in acc.iter_mut().zip(wq.iter()) {
                *a = smlad(*a, sxtb16(wr), xq[0]);
                *a = smlad(*a, sxtb16(wr.rotate_right(8)), xq[1]);
            }
        }
        acc
    }
}

#[cfg(fw_dsp_asm)]
mod asm {
    use core::arch::asm;

    /// One quad (two pairs) of SMLAD over 4 interleaved rows, as asm text.
    macro_rules! quad_i16 {
        () => {
            concat!(
                "ldr {x}, [{xp}], #4\n",
                "ldm {wp}!, {{r4, r5, r8, r9}}\n",
                "smlad {a0}, r4, {x}, {a0}\n",
                "smlad {a1}, r5, {x}, {a1}\n",
                "smlad {a2}, r8, {x}, {a2}\n",
                "smlad {a3}, r9, {x}, {a3}\n",
                "ldr {x}, [{xp}], #4\n",
                "ldm {wp}!, {{r4, r5, r8, r9}}\n",
                "smlad {a0}, r4, {x}, {a0}\n",
                "smlad {a1}, r5, {x}, {a1}\n",
                "smlad {a2}, r8, {x}, {a2}\n",
                "smlad {a3}, r9, {x}, {a3}\n",
            )
        };
    }

    /// SMLAD over 4 interleaved rows: two quads per loop iteration, then one more
    /// when `n` is odd. Registers are pinned: LDM fills its list in ascending
    /// register order, so the weight registers r4, r5, r8, r9 receive rows 0..4.
    ///
    /// # Safety
    /// `w` and `x` must be valid for `n > 0` quads.
    #[inline(always)]
    pub unsafe fn dot4_i16(
        acc: [i32; 4],
        w: *const [[u32; 4]; 2],
        x: *const [u32; 2],
        n: usize,
    ) -> [i32; 4] {
        let [mut a0, mut a1, mut a2, mut a3] = acc;
        // SAFETY (caller: w, x valid for n quads): the loops read exactly 2 * n words
        // of `x` and 8 * n words of `w` (n / 2 iterations of 2 quads, then n % 2
        // quads); they write only the declared registers and the flags.
        unsafe {
            asm!(
                "lsrs {n2}, {n}, #1",
                "beq 3f",
                "2:",
                quad_i16!(),
                quad_i16!(),
                "subs {n2}, {n2}, #1",
                "bne 2b",
                "3:",
                "lsls {n}, {n}, #31",
                "beq 4f",
                quad_i16!(),
                "4:",
                a0 = inout(reg) a0,
                a1 = inout(reg) a1,
                a2 = inout(reg) a2,
                a3 = inout(reg) a3,
                x = out(reg) _,
                xp = inout(reg) x => _,
                wp = inout(reg) w => _,
                n = inout(reg) n => _,
                n2 = out(reg) _,
                out("r4") _,
                out("r5") _,
                out("r8") _,
                out("r9") _,
                options(nostack, readonly),
            );
        }
        [a0, a1, a2, a3]
    }

    /// One column of the f32 kernel: x in s20, weights s22-s25, temporaries s30/s31.
    macro_rules! col_f32 {
        () => {
            concat!(
                "vldmia {xp}!, {{s20}}\n",
                "vldmia {wp}!, {{s22-s25}}\n",
                "vmul.f32 s30, s22, s20\n",
                "vadd.f32 s16, s16, s30\n",
                "vmul.f32 s31, s23, s20\n",
                "vadd.f32 s17, s17, s31\n",
                "vmul.f32 s30, s24, s20\n",
                "vadd.f32 s18, s18, s30\n",
                "vmul.f32 s31, s25, s20\n",
                "vadd.f32 s19, s19, s31\n",
            )
        };
    }

    /// f32 over 4 interleaved rows: two columns per loop iteration (one VLDM of 2
    /// inputs, one of 8 weights), then one more when `n` is odd. Uses s16-s31, saved
    /// and restored with VPUSH/VPOP inside the block.
    ///
    /// # Safety
    /// `w` and `x` must be valid for `n > 0` columns.
    #[inline(always)]
    pub unsafe fn dot4_f32(acc: [f32; 4], w: *const [f32; 4], x: *const f32, n: usize) -> [f32; 4] {
        let mut a = acc;
        // SAFETY (caller: w, x valid for n columns): reads n floats of `x`, 4 * n of
        // `w`, reads and writes the 4 floats of `a`; every FPU register it writes is
        // pushed before and popped after, so the compiler's registers are untouched.
        unsafe {
            asm!(
                "vpush {{s16-s31}}",
                "vldmia {ap}, {{s16-s19}}",
                "lsrs {n2}, {n}, #1",
                "beq 3f",
                "2:",
                "vldmia {xp}!, {{s20-s21}}",
                "vldmia {wp}!, {{s22-s29}}",
                "vmul.f32 s30, s22, s20",
                "vadd.f32 s16, s16, s30",
                "vmul.f32 s31, s23, s20",
                "vadd.f32 s17, s17, s31",
                "vmul.f32 s30, s24, s20",
                "vadd.f32 s18, s18, s30",
                "vmul.f32 s31, s25, s20",
                "vadd.f32 s19, s19, s31",
                "vmul.f32 s30, s26, s21",
                "vadd.f32 s16, s16, s30",
                "vmul.f32 s31, s27, s21",
                "vadd.f32 s17, s17, s31",
                "vmul.f32 s30, s28, s21",
                "vadd.f32 s18, s18, s30",
                "vmul.f32 s31, s29, s21",
                "vadd.f32 s19, s19, s31",
                "subs {n2}, {n2}, #1",
                "bne 2b",
                "3:",
                "lsls {n}, {n}, #31",
                "beq 4f",
                col_f32!(),
                "4:",
                "vstmia {ap}, {{s16-s19}}",
                "vpop {{s16-s31}}",
                ap = in(reg) a.as_mut_ptr(),
                xp = inout(reg) x => _,
                wp = inout(reg) w => _,
                n = inout(reg) n => _,
                n2 = out(reg) _,
            );
        }
        a
    }

    /// SXTB16 + SMLAD over 4 interleaved rows, four columns per loop iteration.
    #[inline(always)]
    ///
    /// # Safety
    /// `w` and `x` must be valid for `n > 0` quads.
    pub unsafe fn dot4_i8(
        acc: [i32; 4],
        w: *const [u32; 4],
        x: *const [u32; 2],
        n: usize,
    ) -> [i32; 4] {
        let [mut a0, mut a1, mut a2, mut a3] = acc;
        // SAFETY (caller: w, x valid for n quads): the loop reads exactly 2 * n words of `x` and 4 * n words of `w`
        // (n iterations, 0 < n <= both slices' lengths by the caller); it writes
        // only the declared registers and the flags.
        unsafe {
            asm!(
                "2:",
                "ldrd {x0}, {x1}, [{xp}], #8",
                "ldr {w}, [{wp}], #4",
                "sxtb16 {t}, {w}",
                "smlad {a0}, {t}, {x0}, {a0}",
                "sxtb16 {t}, {w}, ror #8",
                "smlad {a0}, {t}, {x1}, {a0}",
                "ldr {w}, [{wp}], #4",
                "sxtb16 {t}, {w}",
                "smlad {a1}, {t}, {x0}, {a1}",
                "sxtb16 {t}, {w}, ror #8",
                "smlad {a1}, {t}, {x1}, {a1}",
                "ldr {w}, [{wp}], #4",
                "sxtb16 {t}, {w}",
                "smlad {a2}, {t}, {x0}, {a2}",
                "sxtb16 {t}, {w}, ror #8",
                "smlad {a2}, {t}, {x1}, {a2}",
                "ldr {w}, [{wp}], #4",
                "sxtb16 {t}, {w}",
                "smlad {a3}, {t}, {x0}, {a3}",
                "sxtb16 {t}, {w}, ror #8",
                "smlad {a3}, {t}, {x1}, {a3}",
                "subs {n}, {n}, #1",
                "bne 2b",
                a0 = inout(reg) a0,
                a1 = inout(reg) a1,
                a2 = inout(reg) a2,
                a3 = inout(reg) a3,
                x0 = out(reg) _,
                x1 = out(reg) _,
                w = out(reg) _,
                t = out(reg) _,
                xp = inout(reg) x => _,
                wp = inout(reg) w => _,
                n = inout(reg) n => _,
                options(nostack, readonly),
            );
        }
        [a0, a1, a2, a3]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::golden::hash;

    fn word(seed: u32) -> u32 {
        hash(seed)
    }

    #[test]
    fn smlad_and_sxtb16_match_their_definitions() {
        assert_eq!(smlad(5, pack(3, -4), pack(-7, 2)), 5 - 21 - 8);
        // Both products 2^30: the sum wraps exactly like the instruction.
        assert_eq!(
            smlad(0, pack(i16::MIN, i16::MIN), pack(i16::MIN, i16::MIN)),
            i32::MIN
        );
        assert_eq!(sxtb16(pack_i8([-1, 2, -128, 127])), pack(-1, 2));
        assert_eq!(
            sxtb16(pack_i8([-1, 2, -128, 127]).rotate_right(8)),
            pack(-128, 127)
        );
        assert_eq!(unpack(pack(-32768, 32767)), (-32768, 32767));
    }

    #[test]
    fn dot4_i16_equals_the_scalar_sum() {
        const Q: usize = 3;
        let w: [[[u32; 4]; 2]; Q] = core::array::from_fn(|q| {
            core::array::from_fn(|p| core::array::from_fn(|r| word((q * 8 + p * 4 + r) as u32)))
        });
        let x: [[u32; 2]; Q] =
            core::array::from_fn(|q| core::array::from_fn(|p| word(1000 + (2 * q + p) as u32)));
        let got = dot4_i16([1, -2, 3, -4], &w, &x);
        for r in 0..4 {
            let mut s: i64 = [1, -2, 3, -4][r];
            for q in 0..Q {
                for p in 0..2 {
                    let (w0, w1) = unpack(w[q][p][r]);
                    let (x0, x1) = unpack(x[q][p]);
                    s += w0 as i64 * x0 as i64 + w1 as i64 * x1 as i64;
                }
            }
            assert_eq!(got[r], s as i32, "row {r} (wrapping)");
        }
    }

    #[test]
    fn dot4_i8_equals_the_scalar_sum() {
        const Q: usize = 5;
        let wi: [[[i8; 4]; 4]; Q] = core::array::from_fn(|q| {
            core::array::from_fn(|r| {
                core::array::from_fn(|k| word((q * 16 + r * 4 + k) as u32) as i8)
            })
        });
        let xi: [[i16; 4]; Q] = core::array::from_fn(|q| {
            core::array::from_fn(|k| word(5000 + (q * 4 + k) as u32) as i16)
        });
        let w: [[u32; 4]; Q] =
            core::array::from_fn(|q| core::array::from_fn(|r| pack_i8(wi[q][r])));
        let x: [[u32; 2]; Q] =
            core::array::from_fn(|q| [pack(xi[q][0], xi[q][1]), pack(xi[q][2], xi[q][3])]);
        let got = dot4_i8([7, 0, -7, 100], &w, &x);
        for r in 0..4 {
            let mut s: i32 = [7, 0, -7, 100][r];
            for q in 0..Q {
                for k in 0..4 {
                    s += wi[q][r][k] as i32 * xi[q][k] as i32;
                }
            }
            assert_eq!(got[r], s, "row {r}");
        }
    }

    #[test]
    fn dot4_f32_sums_each_row_left_to_right() {
        let w: [[f32; 4]; 5] = core::array::from_fn(|k| {
            core::array::from_fn(|r| crate::golden::unit(word((k * 4 + r) as u32)) - 0.5)
        });
        let x: [f32; 5] =
            core::array::from_fn(|k| 3.0 * crate::golden::unit(word(300 + k as u32)) - 1.5);
        let got = dot4_f32([0.25, 0.0, -1.0, 2.0], &w, &x);
        for r in 0..4 {
            let mut s = [0.25f32, 0.0, -1.0, 2.0][r];
            for k in 0..5 {
                s += w[k][r] * x[k];
            }
            assert_eq!(got[r].to_bits(), s.to_bits(), "row {r}");
        }
    }

    #[test]
    fn dispatching_and_portable_versions_agree() {
        const Q: usize = 4;
        let w: [[[u32; 4]; 2]; Q] = core::array::from_fn(|q| {
            core::array::from_fn(|p| {
                core::array::from_fn(|r| word(77 + (q * 8 + p * 4 + r) as u32))
            })
        });
        let x: [[u32; 2]; Q] =
            core::array::from_fn(|q| core::array::from_fn(|p| word(99 + (2 * q + p) as u32)));
        assert_eq!(dot4_i16([0; 4], &w, &x), portable::dot4_i16([0; 4], &w, &x));
        let w8: [[u32; 4]; Q] = core::array::from_fn(|q| w[q][0]);
        assert_eq!(dot4_i8([0; 4], &w8, &x), portable::dot4_i8([0; 4], &w8, &x));
    }
}
