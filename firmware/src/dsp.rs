//! Cortex-M4 DSP kernels: the firmware's only inline assembly.
//!
//! rustc 1.95 never emits SMLAD for a plain int16 dot product (about 3.6 instructions
//! per MAC), nor VLDM for an f32 one; these kernels issue them explicitly over 4
//! interleaved weight rows. The layer kernels ([`matvec4_i16`], [`matvec4_i8`],
//! [`matvec4_f32`]) run every 4-row block of a layer in one call: 1.34 estimated cycles
//! per MAC in the int16 loop (LDRD + 2 LDM + 8 SMLAD per quad, 8 quads per iteration),
//! about 1.6 in the int8 loop (LDM + 2 LDR + 8 SXTB16 + 8 SMLAD per quad, 2 quads per
//! iteration), 3.25 in the f32 loop (two blocks at a time: VLDM of 8 inputs and 4 x 16
//! weights, in-place VMUL + VADD, 8 columns per iteration); the single-block kernels
//! ([`dot4_i16`], [`dot4_i8`],
//! [`dot4_f32`])
//! serve the small layers. [`lstm_small_i16`] runs a small int16 network's input
//! layer, gates and cell updates in one unrolled block with `[e; h]` held in FPU
//! registers (its portable twin is `nn::kernels::QuantView::step`). VMLA/VFMA are not used: the separate rounding of VMUL + VADD
//! keeps the bits of the plain Rust sum (and the M4 takes 3 cycles for VMLA against 2
//! for VMUL + VADD only when the VADD does not read the VMUL's result in the next
//! instruction: the FPU's one-cycle result stall, which the f32 kernels avoid by
//! placing each VADD two instructions after the VMUL it reads). Every kernel has a portable twin in plain Rust with the same wrapping
//! (integer) or rounding (f32) semantics; the host (and any target without the DSP
//! extension) runs the twin, the Cortex-M4 the assembly, the twin tests here check
//! the kernels against their definitions, and the QEMU golden suites (`host-tests`)
//! prove both give the same bits.
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

/// A whole int16 layer: for every 4-row block `b`, `acc[b] = dot4_i16(bias[b],
/// w[b * Q..(b + 1) * Q], x)` with `Q = x.len()` quads;
/// `min(acc.len(), bias.len(), w.len() / Q)` blocks (with `Q == 0`, `acc[b] =
/// bias[b]`). One call per layer keeps the per-block overhead inside the assembly
/// (about 35 estimated cycles per block) and the inner loop at 8 quads (128 MACs)
/// per iteration with LDRD for the inputs and LDM for the weights.
#[inline(always)]
pub fn matvec4_i16(acc: &mut [[i32; 4]], bias: &[[i32; 4]], w: &[[[u32; 4]; 2]], x: &[[u32; 2]]) {
    let q = x.len();
    let blocks = layer_blocks(acc, bias, w.len(), q);
    if blocks == 0 {
        return;
    }
    #[cfg(fw_dsp_asm)]
    {
        // SAFETY: blocks > 0 blocks of q > 0 quads of `w`, q quads of `x`, blocks
        // biases and accumulators, all in bounds by the computation above.
        unsafe {
            asm::matvec4_i16(
                acc.as_mut_ptr(),
                bias.as_ptr(),
                w.as_ptr(),
                x.as_ptr(),
                q,
                blocks,
            )
        }
    }
    #[cfg(not(fw_dsp_asm))]
    {
        portable::matvec4_i16(&mut acc[..blocks], bias, w, x)
    }
}

/// The 4-row blocks a layer kernel computes: `min(acc.len(), bias.len(), weights / q)`
/// for `q > 0` quads per block; with `q == 0`, `acc[b] = bias[b]` here and 0 blocks.
#[inline(always)]
fn layer_blocks(acc: &mut [[i32; 4]], bias: &[[i32; 4]], weights: usize, q: usize) -> usize {
    if q == 0 {
        for (a, b) in acc.iter_mut().zip(bias) {
            *a = *b;
        }
        return 0;
    }
    acc.len().min(bias.len()).min(weights / q)
}

/// A whole int8-weight layer: for every 4-row block `b`, `acc[b] = dot4_i8(bias[b],
/// w[b * Q..(b + 1) * Q], x)` with `Q = x.len()` quads; `min(acc.len(), bias.len(),
/// w.len() / Q)` blocks (with `Q == 0`, `acc[b] = bias[b]`). One call per layer keeps
/// the block loop and the accumulators inside the assembly: per quad one LDM of the 4
/// rows' weight words, two LDR of the input pairs, 8 SXTB16 and 8 SMLAD (25 estimated
/// cycles per 16 MACs), two quads per iteration.
#[inline(always)]
pub fn matvec4_i8(acc: &mut [[i32; 4]], bias: &[[i32; 4]], w: &[[u32; 4]], x: &[[u32; 2]]) {
    let q = x.len();
    let blocks = layer_blocks(acc, bias, w.len(), q);
    if blocks == 0 {
        return;
    }
    #[cfg(fw_dsp_asm)]
    {
        // SAFETY: blocks > 0 blocks of q > 0 quads of `w`, q quads of `x`, blocks
        // biases and accumulators, all in bounds by the computation above.
        unsafe {
            asm::matvec4_i8(
                acc.as_mut_ptr(),
                bias.as_ptr(),
                w.as_ptr(),
                x.as_ptr(),
                q,
                blocks,
            )
        }
    }
    #[cfg(not(fw_dsp_asm))]
    {
        portable::matvec4_i8(&mut acc[..blocks], bias, w, x)
    }
}

/// A whole f32 layer: for every 4-row block `b`, `out[b] = dot4_f32([0.0; 4],
/// w[b * N..(b + 1) * N], x)` with `N = x.len()` columns (each row summed left to
/// right from +0.0, separate multiply and add: the bits of [`dot4_f32`]);
/// `min(out.len(), w.len() / N)` blocks (all of `out` is zero when `N == 0`).
/// On the Cortex-M4F: two blocks (8 rows) at a time, 8 columns per iteration (VLDM
/// of 8 inputs, four VLDM of 16 weights, in-place VMUL + VADD), the FPU registers
/// saved once per layer.
#[inline(always)]
pub fn matvec4_f32(out: &mut [[f32; 4]], w: &[[f32; 4]], x: &[f32]) {
    matvec4_f32_parts(out, [w, &[], &[]], x);
}

/// [`matvec4_f32`] over a layer whose blocks are stored in up to three parts (e.g.
/// the first in SRAM, the next in CCM SRAM, the rest in flash): `out[b]` from the
/// blocks of `parts[0]`, then of `parts[1]`, then of `parts[2]`, the same bits as one
/// layer; each part contributes `len / N` blocks, as many as `out` still takes. One
/// assembly block for all parts (switching parts costs a few cycles per layer, not
/// per block); a part's blocks run two at a time, an odd last one alone.
#[inline(always)]
pub fn matvec4_f32_parts(out: &mut [[f32; 4]], parts: [&[[f32; 4]]; 3], x: &[f32]) {
    let n = x.len();
    if n == 0 {
        out.fill([0.0; 4]);
        return;
    }
    let mut left = out.len();
    let blocks = parts.map(|p| {
        let b = left.min(p.len() / n);
        left -= b;
        b
    });
    #[cfg(fw_dsp_asm)]
    {
        let table: [[usize; 2]; 3] =
            core::array::from_fn(|i| [parts[i].as_ptr() as usize, blocks[i]]);
        if blocks.iter().all(|&b| b == 0) {
            return;
        }
        // SAFETY: 3 table entries, each with blocks[i] blocks of n > 0 columns of
        // parts[i] (in bounds by the computation above), n values of `x`, and the
        // sum of the blocks <= out.len() outputs.
        unsafe { asm::matvec4_f32(out.as_mut_ptr(), table.as_ptr(), 3, x.as_ptr(), n) }
    }
    #[cfg(not(fw_dsp_asm))]
    {
        let mut rest = &mut out[..];
        for (p, b) in parts.iter().zip(blocks) {
            let (now, later) = rest.split_at_mut(b);
            portable::matvec4_f32(now, p, x);
            rest = later;
        }
    }
}

/// The cell updates of an f32 LSTM layer: for each cell `j`, the gates `x = acc[j] +
/// bias[j]` (rows i, f, g, o) through [`math::lstm_gates_fast`], then `c[j] = f c[j] +
/// i g` and `h[j] = o` (the caller multiplies `h` by `tanh(c)`), over `min(acc.len(),
/// bias.len(), c.len(), h.len())` cells. On the Cortex-M4F one assembly loop computes
/// each cell's four exponentials side by side, one operation across the four lanes at
/// a time (the same operations in the same order per lane, so the same bits; no
/// instruction reads the VADD/VMUL right before it), the FPU registers saved once.
///
/// [`math::lstm_gates_fast`]: crate::math::lstm_gates_fast
#[inline(always)]
pub fn lstm_cells_f32(acc: &[[f32; 4]], bias: &[[f32; 4]], c: &mut [f32], h: &mut [f32]) {
    let n = acc.len().min(bias.len()).min(c.len()).min(h.len());
    if n == 0 {
        return;
    }
    #[cfg(fw_dsp_asm)]
    {
        // SAFETY: n > 0 cells of each of the four slices, in bounds by the computation
        // above; the constants' table has the 12 values the kernel reads.
        unsafe {
            asm::lstm_cells_f32(
                acc.as_ptr(),
                bias.as_ptr(),
                c.as_mut_ptr(),
                h.as_mut_ptr(),
                n,
                &crate::math::LSTM_CELL_CONSTANTS,
            )
        }
    }
    #[cfg(not(fw_dsp_asm))]
    {
        portable::lstm_cells_f32(acc, bias, c, h)
    }
}

/// `x[j] = math::tanh_fast4(x[j] + bias[j])` for `min(x.len(), bias.len())` blocks (an
/// f32 input layer's bias and tanh). On the Cortex-M4F one assembly loop, four lanes
/// side by side as in [`lstm_cells_f32`] (the same bits).
#[inline(always)]
pub fn tanh4_bias_f32(x: &mut [[f32; 4]], bias: &[[f32; 4]]) {
    let n = x.len().min(bias.len());
    if n == 0 {
        return;
    }
    #[cfg(fw_dsp_asm)]
    {
        // SAFETY: n > 0 blocks of both slices, in bounds by the computation above; the
        // constants' table has the 11 values after its first that the kernel reads.
        unsafe {
            asm::tanh4_bias_f32(
                x.as_mut_ptr(),
                bias.as_ptr(),
                n,
                crate::math::LSTM_CELL_CONSTANTS[1..].as_ptr(),
            )
        }
    }
    #[cfg(not(fw_dsp_asm))]
    {
        portable::tanh4_bias_f32(x, bias)
    }
}

/// `h[j][r] *= math::tanh_fast(c[j][r])` for `min(h.len(), c.len())` blocks (an LSTM
/// layer's `h = o tanh(c)`), lane for lane `math::tanh_fast4`. On the Cortex-M4F one
/// assembly loop, four lanes side by side as in [`lstm_cells_f32`] (the same bits).
#[inline(always)]
pub fn mul_tanh4_f32(h: &mut [[f32; 4]], c: &[[f32; 4]]) {
    let n = h.len().min(c.len());
    if n == 0 {
        return;
    }
    #[cfg(fw_dsp_asm)]
    {
        // SAFETY: n > 0 blocks of both slices, in bounds by the computation above; the
        // constants' table has the 11 values after its first that the kernel reads.
        unsafe {
            asm::mul_tanh4_f32(
                h.as_mut_ptr(),
                c.as_ptr(),
                n,
                crate::math::LSTM_CELL_CONSTANTS[1..].as_ptr(),
            )
        }
    }
    #[cfg(not(fw_dsp_asm))]
    {
        portable::mul_tanh4_f32(h, c)
    }
}

/// Whether this build runs the assembly kernels (`cfg(fw_dsp_asm)`), else their portable
/// twins.
pub const ASM: bool = cfg!(fw_dsp_asm);

/// Largest `[e; h]` (quads) of [`lstm_small_i16`]: 16 words, held in s0-s15.
pub const SMALL_MAX_Z_QUADS: usize = 8;
/// Largest input (quads) of [`lstm_small_i16`]: 4 words, held in s20-s23.
pub const SMALL_MAX_INPUT_QUADS: usize = 2;

/// One step of a small int16 network except the input quantisation and the f32
/// de-normalisation (everything of `nn::kernels::QuantView::step` in between, with the same
/// bits) in one assembly block, on the Cortex-M4: `xq` the quantised input,
/// `in_w`/`in_bias`/`gate_w`/`gate_bias`/`out_w` the network's arrays (`EB * IQ`,
/// `H * ZQ` and `HQ` quads), `state` advanced in place (the new `h` in `state.z[EB..]`,
/// the new `c`; the `e` part of `z` and `acc` are not written). Returns the output
/// rows' accumulators (rows `O..4` zero), or `None` (nothing written) when the sizes
/// are beyond [`SMALL_MAX_Z_QUADS`] / [`SMALL_MAX_INPUT_QUADS`] / 4 outputs or a slice
/// is short, and always on targets without the DSP extension.
///
/// Per cell (block `j` of rows `i, f, g, o`): the bias by one LDM, then per quad of
/// `[e; h]` one LDM of its 8 weight words and 8 SMLAD, the input words moved from
/// s0-s15 by VMOV (about 1.19 estimated cycles per MAC), then the cell update of
/// `nn::kernels::cell_update` (4 SSAT + LDRSH activations, the int16 `c` by LDRSH, SMLABB,
/// SMULBB, ADD, SSAT, STRH, the tanh of `c`, the new `h` stored as one halfword),
/// 22 instructions. Unrolled over
/// cells and quads by the assembler (`.irp`, `.if` on the const sizes), with the
/// index shifts of `F` as immediates. The output rows read their weight words by
/// immediate offsets (no work for the padding rows).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub fn lstm_small_i16<
    F: crate::nn::format::QuantFormat,
    const IQ: usize,
    const EB: usize,
    const H: usize,
    const ZQ: usize,
    const O: usize,
>(
    xq: &[[u32; 2]; IQ],
    in_w: &[[[u32; 4]; 2]],
    in_bias: &[[i32; 4]; EB],
    gate_w: &[[[u32; 4]; 2]],
    gate_bias: &[[i32; 4]; H],
    out_w: &[[[u32; 4]; 2]],
    state: &mut crate::nn::format::QuantState<ZQ, H>,
) -> Option<[i32; 4]> {
    let fits = IQ >= 1
        && IQ <= SMALL_MAX_INPUT_QUADS
        && ZQ <= SMALL_MAX_Z_QUADS
        && ZQ == EB + H / 4
        && H.is_multiple_of(4)
        && O <= 4
        && in_w.len() >= EB * IQ
        && gate_w.len() >= H * ZQ
        && out_w.len() >= H / 4;
    if !fits {
        return None;
    }
    #[cfg(fw_dsp_asm)]
    {
        use crate::nn::act::{SIGMOID, TABLE_LEN, TANH};
        let mid = |f: usize| {
            F::ACT_TABLES.get(f).map_or(core::ptr::null(), |t| {
                t.as_ptr().wrapping_add(TABLE_LEN / 2)
            }) as usize
        };
        let args: [usize; 9] = [
            xq.as_ptr() as usize,
            in_w.as_ptr() as usize,
            in_bias.as_ptr() as usize,
            gate_w.as_ptr() as usize,
            gate_bias.as_ptr() as usize,
            state as *mut crate::nn::format::QuantState<ZQ, H> as usize,
            mid(SIGMOID),
            mid(TANH),
            out_w.as_ptr() as usize,
        ];
        // SAFETY: sizes checked above: the block reads 2 * IQ words of `xq`, EB * IQ
        // quads of `in_w`, EB biases, H * ZQ quads of `gate_w`, H biases, the first
        // O rows of H / 4 quads of `out_w`, both activation tables within their 8192
        // entries (indices saturate to -4096..=4095 around the middle), reads the h
        // words and reads and writes the c and h halfwords of `state`
        // (`repr(C)`: z at 0, c at 8 * ZQ); it writes only the declared registers,
        // r6/r7 (saved and restored on the stack) and the flags.
        Some(unsafe { asm::lstm_small_i16::<F, IQ, EB, H, ZQ, O>(&args) })
    }
    #[cfg(not(fw_dsp_asm))]
    {
        let _ = (xq, in_bias, gate_bias, state);
        None
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

    /// Portable [`super::matvec4_i16`].
    #[inline(always)]
    pub fn matvec4_i16(
        acc: &mut [[i32; 4]],
        bias: &[[i32; 4]],
        w: &[[[u32; 4]; 2]],
        x: &[[u32; 2]],
    ) {
        if x.is_empty() {
            for (a, b) in acc.iter_mut().zip(bias) {
                *a = *b;
            }
            return;
        }
        for ((a, b), wb) in acc.iter_mut().zip(bias).zip(w.chunks_exact(x.len())) {
            *a = dot4_i16(*b, wb, x);
        }
    }

    /// Portable [`super::matvec4_i8`].
    #[inline(always)]
    pub fn matvec4_i8(acc: &mut [[i32; 4]], bias: &[[i32; 4]], w: &[[u32; 4]], x: &[[u32; 2]]) {
        if x.is_empty() {
            for (a, b) in acc.iter_mut().zip(bias) {
                *a = *b;
            }
            return;
        }
        for ((a, b), wb) in acc.iter_mut().zip(bias).zip(w.chunks_exact(x.len())) {
            *a = dot4_i8(*b, wb, x);
        }
    }

    /// Portable [`super::matvec4_f32`].
    #[inline(always)]
    pub fn matvec4_f32(out: &mut [[f32; 4]], w: &[[f32; 4]], x: &[f32]) {
        if x.is_empty() {
            out.fill([0.0; 4]);
            return;
        }
        for (o, wb) in out.iter_mut().zip(w.chunks_exact(x.len())) {
            *o = dot4_f32([0.0; 4], wb, x);
        }
    }

    /// Portable [`super::lstm_cells_f32`].
    #[inline(always)]
    pub fn lstm_cells_f32(acc: &[[f32; 4]], bias: &[[f32; 4]], c: &mut [f32], h: &mut [f32]) {
        let cells = acc.iter().zip(bias).zip(c.iter_mut()).zip(h.iter_mut());
        for (((a, b), cj), hj) in cells {
            let [i, f, g, o] =
                crate::math::lstm_gates_fast([a[0] + b[0], a[1] + b[1], a[2] + b[2], a[3] + b[3]]);
            *cj = f * *cj + i * g;
            *hj = o;
        }
    }

    /// Portable [`super::tanh4_bias_f32`].
    #[inline(always)]
    pub fn tanh4_bias_f32(x: &mut [[f32; 4]], bias: &[[f32; 4]]) {
        for (e, b) in x.iter_mut().zip(bias) {
            *e = crate::math::tanh_fast4([e[0] + b[0], e[1] + b[1], e[2] + b[2], e[3] + b[3]]);
        }
    }

    /// Portable [`super::mul_tanh4_f32`].
    #[inline(always)]
    pub fn mul_tanh4_f32(h: &mut [[f32; 4]], c: &[[f32; 4]]) {
        for (hs, cs) in h.iter_mut().zip(c) {
            let t = crate::math::tanh_fast4(*cs);
            for (h, t) in hs.iter_mut().zip(t) {
                *h *= t;
            }
        }
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
                "vmul.f32 s31, s23, s20\n",
                "vadd.f32 s16, s16, s30\n",
                "vadd.f32 s17, s17, s31\n",
                "vmul.f32 s30, s24, s20\n",
                "vmul.f32 s31, s25, s20\n",
                "vadd.f32 s18, s18, s30\n",
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
                "vmul.f32 s31, s23, s20",
                "vadd.f32 s16, s16, s30",
                "vadd.f32 s17, s17, s31",
                "vmul.f32 s30, s24, s20",
                "vmul.f32 s31, s25, s20",
                "vadd.f32 s18, s18, s30",
                "vadd.f32 s19, s19, s31",
                "vmul.f32 s30, s26, s21",
                "vmul.f32 s31, s27, s21",
                "vadd.f32 s16, s16, s30",
                "vadd.f32 s17, s17, s31",
                "vmul.f32 s30, s28, s21",
                "vmul.f32 s31, s29, s21",
                "vadd.f32 s18, s18, s30",
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

    /// One quad of the layer kernel: LDRD of the input pair, two LDM of 4 weights,
    /// accumulators in r0-r3.
    macro_rules! quad_i16_d {
        () => {
            concat!(
                "ldrd {x0}, {x1}, [{xp}], #8\n",
                "ldm {wp}!, {{r4, r5, r8, r9}}\n",
                "smlad r0, r4, {x0}, r0\n",
                "smlad r1, r5, {x0}, r1\n",
                "smlad r2, r8, {x0}, r2\n",
                "smlad r3, r9, {x0}, r3\n",
                "ldm {wp}!, {{r4, r5, r8, r9}}\n",
                "smlad r0, r4, {x1}, r0\n",
                "smlad r1, r5, {x1}, r1\n",
                "smlad r2, r8, {x1}, r2\n",
                "smlad r3, r9, {x1}, r3\n",
            )
        };
    }

    /// The int16 layer: per block, accumulators (r0-r3) from `bias` by one LDM,
    /// `q / 8` iterations of 8 quads, then `q % 8` single quads, accumulators to `acc`
    /// by one STM. The loop-invariant values (x base, q, blocks left, bias and
    /// accumulator pointers) live in 24 bytes of stack that the block reserves and
    /// frees itself, so 13 registers carry the inner loop.
    ///
    /// # Safety
    /// `acc` (written) and `bias` valid for `blocks > 0` blocks, `w` for `blocks * q`
    /// quads, `x` for `q > 0` quads.
    #[inline(always)]
    pub unsafe fn matvec4_i16(
        acc: *mut [i32; 4],
        bias: *const [i32; 4],
        w: *const [[u32; 4]; 2],
        x: *const [u32; 2],
        q: usize,
        blocks: usize,
    ) {
        // SAFETY (caller: pointers valid as documented): per block the loops read q
        // quads of `x` and of `w` (w advances block after block), one `[i32; 4]` of
        // `bias` and write one of `acc`; sp is restored; only declared registers and
        // the flags are written.
        unsafe {
            asm!(
                "sub sp, sp, #24",
                "strd r0, r1, [sp]",
                "strd r2, r3, [sp, #8]",
                "str {x0}, [sp, #16]",
                "2:",
                "ldr {x0}, [sp, #16]",
                "ldm {x0}!, {{r0, r1, r2, r3}}",
                "str {x0}, [sp, #16]",
                "ldrd {xp}, {n}, [sp]",
                "subs {n}, {n}, #8",
                "blo 4f",
                "3:",
                quad_i16_d!(),
                quad_i16_d!(),
                quad_i16_d!(),
                quad_i16_d!(),
                quad_i16_d!(),
                quad_i16_d!(),
                quad_i16_d!(),
                quad_i16_d!(),
                "subs {n}, {n}, #8",
                "bhs 3b",
                "4:",
                "adds {n}, {n}, #8",
                "beq 6f",
                "5:",
                quad_i16_d!(),
                "subs {n}, {n}, #1",
                "bne 5b",
                "6:",
                "ldr {x0}, [sp, #12]",
                "stm {x0}!, {{r0, r1, r2, r3}}",
                "ldr {x1}, [sp, #8]",
                "str {x0}, [sp, #12]",
                "subs {x1}, {x1}, #1",
                "str {x1}, [sp, #8]",
                "bne 2b",
                "add sp, sp, #24",
                inout("r0") x => _,
                inout("r1") q => _,
                inout("r2") blocks => _,
                inout("r3") acc => _,
                x0 = inout(reg) bias => _,
                x1 = out(reg) _,
                xp = out(reg) _,
                n = out(reg) _,
                wp = inout(reg) w => _,
                out("r4") _,
                out("r5") _,
                out("r8") _,
                out("r9") _,
            );
        }
    }

    /// One quad of the int8 layer kernel: the 4 rows' weight words by one LDM (r4, r5,
    /// r8, r9: rows 0..4), the input pairs by LDR; the low byte pairs through a
    /// temporary, the high ones rotated in place. Accumulators in r0-r3.
    macro_rules! quad_i8 {
        () => {
            concat!(
                "ldr {x}, [{xp}], #4\n",
                "ldm {wp}!, {{r4, r5, r8, r9}}\n",
                "sxtb16 {t}, r4\n",
                "smlad r0, {t}, {x}, r0\n",
                "sxtb16 {t}, r5\n",
                "smlad r1, {t}, {x}, r1\n",
                "sxtb16 {t}, r8\n",
                "smlad r2, {t}, {x}, r2\n",
                "sxtb16 {t}, r9\n",
                "smlad r3, {t}, {x}, r3\n",
                "ldr {x}, [{xp}], #4\n",
                "sxtb16 r4, r4, ror #8\n",
                "smlad r0, r4, {x}, r0\n",
                "sxtb16 r5, r5, ror #8\n",
                "smlad r1, r5, {x}, r1\n",
                "sxtb16 r8, r8, ror #8\n",
                "smlad r2, r8, {x}, r2\n",
                "sxtb16 r9, r9, ror #8\n",
                "smlad r3, r9, {x}, r3\n",
            )
        };
    }

    /// The int8 layer: per block, accumulators (r0-r3) from `bias` by one LDM, `q / 2`
    /// iterations of 2 quads, then one more quad when `q` is odd, accumulators to `acc`
    /// by one STM. The loop-invariant values (x base, q, blocks left, accumulator and
    /// bias pointers) live in 24 bytes of stack that the block reserves and frees
    /// itself.
    ///
    /// # Safety
    /// `acc` (written) and `bias` valid for `blocks > 0` blocks, `w` for `blocks * q`
    /// quads, `x` for `q > 0` quads.
    #[inline(always)]
    pub unsafe fn matvec4_i8(
        acc: *mut [i32; 4],
        bias: *const [i32; 4],
        w: *const [u32; 4],
        x: *const [u32; 2],
        q: usize,
        blocks: usize,
    ) {
        // SAFETY (caller: pointers valid as documented): per block the loops read q
        // quads of `x` and of `w` (w advances block after block), one `[i32; 4]` of
        // `bias` and write one of `acc`; sp is restored; only declared registers and
        // the flags are written.
        unsafe {
            asm!(
                "sub sp, sp, #24",
                "strd r0, r1, [sp]",
                "strd r2, r3, [sp, #8]",
                "str {t}, [sp, #16]",
                "2:",
                "ldr {t}, [sp, #16]",
                "ldm {t}!, {{r0, r1, r2, r3}}",
                "str {t}, [sp, #16]",
                "ldrd {xp}, {n}, [sp]",
                "lsrs {n}, {n}, #1",
                "beq 4f",
                "3:",
                quad_i8!(),
                quad_i8!(),
                "subs {n}, {n}, #1",
                "bne 3b",
                "4:",
                "ldr {n}, [sp, #4]",
                "lsls {n}, {n}, #31",
                "beq 5f",
                quad_i8!(),
                "5:",
                "ldr {t}, [sp, #12]",
                "stm {t}!, {{r0, r1, r2, r3}}",
                "str {t}, [sp, #12]",
                "ldr {t}, [sp, #8]",
                "subs {t}, {t}, #1",
                "str {t}, [sp, #8]",
                "bne 2b",
                "add sp, sp, #24",
                inout("r0") x => _,
                inout("r1") q => _,
                inout("r2") blocks => _,
                inout("r3") acc => _,
                t = inout(reg) bias => _,
                wp = inout(reg) w => _,
                x = out(reg) _,
                xp = out(reg) _,
                n = out(reg) _,
                out("r4") _,
                out("r5") _,
                out("r8") _,
                out("r9") _,
            );
        }
    }

    /// Sixteen products of the f32 layer kernel, in place: weights s16-s31 (4 columns
    /// of one 4-row block, `s16 + 4 j + r` = column `j`, row `r`), inputs `$x0..$x3`,
    /// accumulators `$a0..$a3` (rows 0-3). Each VMUL overwrites its weight with the
    /// product; each VADD comes two instructions after the VMUL it reads (the FPU's
    /// one-cycle result stall falls on the instruction right after a VMUL), and each
    /// accumulator adds its products in column order.
    macro_rules! products16_f32 {
        ($x0:literal, $x1:literal, $x2:literal, $x3:literal, $a0:literal, $a1:literal, $a2:literal, $a3:literal) => {
            concat!(
                "vmul.f32 s16, s16, ",
                $x0,
                "\n",
                "vmul.f32 s17, s17, ",
                $x0,
                "\n",
                "vadd.f32 ",
                $a0,
                ", ",
                $a0,
                ", s16\n",
                "vmul.f32 s18, s18, ",
                $x0,
                "\n",
                "vadd.f32 ",
                $a1,
                ", ",
                $a1,
                ", s17\n",
                "vmul.f32 s19, s19, ",
                $x0,
                "\n",
                "vadd.f32 ",
                $a2,
                ", ",
                $a2,
                ", s18\n",
                "vmul.f32 s20, s20, ",
                $x1,
                "\n",
                "vadd.f32 ",
                $a3,
                ", ",
                $a3,
                ", s19\n",
                "vmul.f32 s21, s21, ",
                $x1,
                "\n",
                "vadd.f32 ",
                $a0,
                ", ",
                $a0,
                ", s20\n",
                "vmul.f32 s22, s22, ",
                $x1,
                "\n",
                "vadd.f32 ",
                $a1,
                ", ",
                $a1,
                ", s21\n",
                "vmul.f32 s23, s23, ",
                $x1,
                "\n",
                "vadd.f32 ",
                $a2,
                ", ",
                $a2,
                ", s22\n",
                "vmul.f32 s24, s24, ",
                $x2,
                "\n",
                "vadd.f32 ",
                $a3,
                ", ",
                $a3,
                ", s23\n",
                "vmul.f32 s25, s25, ",
                $x2,
                "\n",
                "vadd.f32 ",
                $a0,
                ", ",
                $a0,
                ", s24\n",
                "vmul.f32 s26, s26, ",
                $x2,
                "\n",
                "vadd.f32 ",
                $a1,
                ", ",
                $a1,
                ", s25\n",
                "vmul.f32 s27, s27, ",
                $x2,
                "\n",
                "vadd.f32 ",
                $a2,
                ", ",
                $a2,
                ", s26\n",
                "vmul.f32 s28, s28, ",
                $x3,
                "\n",
                "vadd.f32 ",
                $a3,
                ", ",
                $a3,
                ", s27\n",
                "vmul.f32 s29, s29, ",
                $x3,
                "\n",
                "vadd.f32 ",
                $a0,
                ", ",
                $a0,
                ", s28\n",
                "vmul.f32 s30, s30, ",
                $x3,
                "\n",
                "vadd.f32 ",
                $a1,
                ", ",
                $a1,
                ", s29\n",
                "vmul.f32 s31, s31, ",
                $x3,
                "\n",
                "vadd.f32 ",
                $a2,
                ", ",
                $a2,
                ", s30\n",
                "vadd.f32 ",
                $a3,
                ", ",
                $a3,
                ", s31\n",
            )
        };
    }

    /// One column of the f32 layer kernel for a pair of blocks: input s8, weights
    /// s16-s19 (first block) and s20-s23 (second), accumulators s0-s3 and s4-s7;
    /// VMUL in place, each VADD two instructions after the VMUL it reads.
    macro_rules! column8_f32 {
        () => {
            concat!(
                "vmul.f32 s16, s16, s8\n",
                "vmul.f32 s17, s17, s8\n",
                "vadd.f32 s0, s0, s16\n",
                "vmul.f32 s18, s18, s8\n",
                "vadd.f32 s1, s1, s17\n",
                "vmul.f32 s19, s19, s8\n",
                "vadd.f32 s2, s2, s18\n",
                "vmul.f32 s20, s20, s8\n",
                "vadd.f32 s3, s3, s19\n",
                "vmul.f32 s21, s21, s8\n",
                "vadd.f32 s4, s4, s20\n",
                "vmul.f32 s22, s22, s8\n",
                "vadd.f32 s5, s5, s21\n",
                "vmul.f32 s23, s23, s8\n",
                "vadd.f32 s6, s6, s22\n",
                "vadd.f32 s7, s7, s23\n",
            )
        };
    }

    /// One column of the f32 layer kernel for a single block: input s8, weights
    /// s16-s19, accumulators s0-s3; VMUL in place, each VADD two instructions after
    /// the VMUL it reads.
    macro_rules! column4_f32 {
        () => {
            concat!(
                "vmul.f32 s16, s16, s8\n",
                "vmul.f32 s17, s17, s8\n",
                "vadd.f32 s0, s0, s16\n",
                "vmul.f32 s18, s18, s8\n",
                "vadd.f32 s1, s1, s17\n",
                "vmul.f32 s19, s19, s8\n",
                "vadd.f32 s2, s2, s18\n",
                "vadd.f32 s3, s3, s19\n",
            )
        };
    }

    /// The f32 layer: the blocks of each part, two at a time (8 rows sharing every
    /// input load: accumulators s0-s7 from +0.0), `n / 8` iterations of 8 columns
    /// (VLDM of 8 inputs into s8-s15, then per block and 4 columns one VLDM of 16
    /// weights into s16-s31 and 16 in-place VMUL + 16 VADD), then `n % 8` single
    /// columns; VSTM of s0-s7. A part's odd last block runs alone (the same loops
    /// over one block, accumulators s0-s3). `parts` holds `nparts` entries
    /// `[weights address, blocks]`, run in order. All 32 FPU registers are saved and
    /// restored inside the block (VPUSH/VPOP of d0-d15, once per layer).
    ///
    /// # Safety
    /// `parts` valid for `nparts > 0` entries, each weight address valid for its
    /// `blocks * n` columns; `out` valid for the sum of the blocks (written); `x` for
    /// `n > 0` values.
    ///
    /// One copy for every f32 layer of the image (not inlined: it is the biggest
    /// kernel, and on the board it runs from CCM SRAM, whose bytes the exporter also
    /// gives to model data).
    #[inline(never)]
    #[cfg_attr(target_os = "none", unsafe(link_section = ".ccmram_text"))]
    pub unsafe fn matvec4_f32(
        out: *mut [f32; 4],
        parts: *const [usize; 2],
        nparts: usize,
        x: *const f32,
        n: usize,
    ) {
        // SAFETY (caller: pointers valid as documented): per block pair the loops read
        // n values of `x` and n columns of each of the two blocks (the second pointer
        // starts n columns after the first) and write two `[f32; 4]` of `out`; an odd
        // last block reads its own n columns and writes one; every FPU register is
        // pushed before and popped after; sp is restored; only declared core registers
        // and the flags change.
        unsafe {
            asm!(
                "vpush {{d0-d15}}",
                // Next part: its weights and block count.
                "1:",
                "ldr {wp}, [{tbl}], #4",
                "ldr {nb}, [{tbl}], #4",
                "cmp {nb}, #0",
                "beq 7f",
                // Next pair of blocks (the odd last one: 10f).
                "2:",
                "movs {k}, #0",
                "vmov s0, s1, {k}, {k}",
                "vmov s2, s3, {k}, {k}",
                "mov {xp}, {xb}",
                "cmp {nb}, #1",
                "beq 10f",
                "vmov s4, s5, {k}, {k}",
                "vmov s6, s7, {k}, {k}",
                "add {wq}, {wp}, {n}, lsl #4",
                "lsrs {k}, {n}, #3",
                "beq 4f",
                "3:",
                "vldmia {xp}!, {{s8-s15}}",
                "vldmia {wp}!, {{s16-s31}}",
                products16_f32!("s8", "s9", "s10", "s11", "s0", "s1", "s2", "s3"),
                "vldmia {wq}!, {{s16-s31}}",
                products16_f32!("s8", "s9", "s10", "s11", "s4", "s5", "s6", "s7"),
                "vldmia {wp}!, {{s16-s31}}",
                products16_f32!("s12", "s13", "s14", "s15", "s0", "s1", "s2", "s3"),
                "vldmia {wq}!, {{s16-s31}}",
                products16_f32!("s12", "s13", "s14", "s15", "s4", "s5", "s6", "s7"),
                "subs {k}, {k}, #1",
                "bne 3b",
                "4:",
                "ands {k}, {n}, #7",
                "beq 6f",
                "5:",
                "vldmia {xp}!, {{s8}}",
                "vldmia {wp}!, {{s16-s19}}",
                "vldmia {wq}!, {{s20-s23}}",
                column8_f32!(),
                "subs {k}, {k}, #1",
                "bne 5b",
                "6:",
                "mov {wp}, {wq}",
                "vstmia {op}!, {{s0-s7}}",
                "subs {nb}, {nb}, #2",
                "bne 2b",
                "7:",
                "subs {np}, {np}, #1",
                "bne 1b",
                "b 9f",
                // A part's odd last block alone.
                "10:",
                "lsrs {k}, {n}, #3",
                "beq 12f",
                "11:",
                "vldmia {xp}!, {{s8-s15}}",
                "vldmia {wp}!, {{s16-s31}}",
                products16_f32!("s8", "s9", "s10", "s11", "s0", "s1", "s2", "s3"),
                "vldmia {wp}!, {{s16-s31}}",
                products16_f32!("s12", "s13", "s14", "s15", "s0", "s1", "s2", "s3"),
                "subs {k}, {k}, #1",
                "bne 11b",
                "12:",
                "ands {k}, {n}, #7",
                "beq 14f",
                "13:",
                "vldmia {xp}!, {{s8}}",
                "vldmia {wp}!, {{s16-s19}}",
                column4_f32!(),
                "subs {k}, {k}, #1",
                "bne 13b",
                "14:",
                "vstmia {op}!, {{s0-s3}}",
                "subs {np}, {np}, #1",
                "bne 1b",
                "9:",
                "vpop {{d0-d15}}",
                op = inout(reg) out => _,
                tbl = inout(reg) parts => _,
                np = inout(reg) nparts => _,
                xb = in(reg) x,
                n = in(reg) n,
                wp = out(reg) _,
                wq = out(reg) _,
                nb = out(reg) _,
                xp = out(reg) _,
                k = out(reg) _,
            );
        }
    }

    /// The cell loop of [`super::lstm_cells_f32`]. Registers: s0-s3 the gate sums `x`,
    /// s4-s7 `y = -|x|` (lane 2: `-2 min(|x|, 9)`), then `r`, then the activations;
    /// s8-s11 `u`, `k`, the scale; s12-s15 `hi`, `z`, the denominators; s16-s19 the
    /// polynomial and `e`; s20-s31 the constants (`consts`: -87, -log2 e, 0.5,
    /// ln 2 high and low parts, P0-P4, 1, 9). Each step runs across the four lanes.
    ///
    /// # Safety
    /// `acc`, `bias` valid for `n > 0` blocks, `c` and `h` for `n` values (written).
    #[inline(always)]
    pub unsafe fn lstm_cells_f32(
        acc: *const [f32; 4],
        bias: *const [f32; 4],
        c: *mut f32,
        h: *mut f32,
        n: usize,
        consts: &[f32; 12],
    ) {
        // SAFETY (caller: pointers valid as documented): per cell the loop reads one
        // block of `acc` and `bias` and one value of `c`, and writes one value of `c`
        // and of `h`; every FPU register is pushed before and popped after; sp is
        // restored; only declared core registers and the flags change.
        unsafe {
            asm!(
                "vpush {{d0-d15}}",
                "vldmia {consts}, {{s20-s31}}",
                "1:",
                "vldmia {acc}!, {{s4-s7}}",
                "vldmia {bias}!, {{s8-s11}}",
                "vadd.f32 s0, s4, s8",
                "vadd.f32 s1, s5, s9",
                "vadd.f32 s2, s6, s10",
                "vadd.f32 s3, s7, s11",
                "vabs.f32 s4, s0",
                "vabs.f32 s5, s1",
                "vabs.f32 s6, s2",
                "vabs.f32 s7, s3",
                "vcmp.f32 s6, s31",
                "vmrs APSR_nzcv, fpscr",
                "it gt",
                "vmovgt.f32 s6, s31",
                "vmov.f32 s10, #-2.0",
                "vneg.f32 s4, s4",
                "vneg.f32 s5, s5",
                "vmul.f32 s6, s10, s6",
                "vneg.f32 s7, s7",
                "vcmp.f32 s4, s20",
                "vmrs APSR_nzcv, fpscr",
                "it mi",
                "vmovmi.f32 s4, s20",
                "vcmp.f32 s5, s20",
                "vmrs APSR_nzcv, fpscr",
                "it mi",
                "vmovmi.f32 s5, s20",
                "vcmp.f32 s6, s20",
                "vmrs APSR_nzcv, fpscr",
                "it mi",
                "vmovmi.f32 s6, s20",
                "vcmp.f32 s7, s20",
                "vmrs APSR_nzcv, fpscr",
                "it mi",
                "vmovmi.f32 s7, s20",
                "vmul.f32 s8, s4, s21",
                "vmul.f32 s9, s5, s21",
                "vmul.f32 s10, s6, s21",
                "vmul.f32 s11, s7, s21",
                "vadd.f32 s8, s8, s22",
                "vadd.f32 s9, s9, s22",
                "vadd.f32 s10, s10, s22",
                "vadd.f32 s11, s11, s22",
                "vcvt.s32.f32 s8, s8",
                "vcvt.s32.f32 s9, s9",
                "vcvt.s32.f32 s10, s10",
                "vcvt.s32.f32 s11, s11",
                "vmov {k0}, s8",
                "vmov {k1}, s9",
                "vmov {k2}, s10",
                "vmov {k3}, s11",
                "vcvt.f32.s32 s8, s8",
                "vcvt.f32.s32 s9, s9",
                "vcvt.f32.s32 s10, s10",
                "vcvt.f32.s32 s11, s11",
                "vmul.f32 s12, s8, s23",
                "vmul.f32 s13, s9, s23",
                "vmul.f32 s14, s10, s23",
                "vmul.f32 s15, s11, s23",
                "vmul.f32 s8, s8, s24",
                "vmul.f32 s9, s9, s24",
                "vmul.f32 s10, s10, s24",
                "vmul.f32 s11, s11, s24",
                "vadd.f32 s4, s4, s12",
                "vadd.f32 s5, s5, s13",
                "vadd.f32 s6, s6, s14",
                "vadd.f32 s7, s7, s15",
                "vadd.f32 s4, s4, s8",
                "vadd.f32 s5, s5, s9",
                "vadd.f32 s6, s6, s10",
                "vadd.f32 s7, s7, s11",
                "vmul.f32 s12, s4, s4",
                "vmul.f32 s13, s5, s5",
                "vmul.f32 s14, s6, s6",
                "vmul.f32 s15, s7, s7",
                "vmul.f32 s16, s25, s4",
                "vmul.f32 s17, s25, s5",
                "vmul.f32 s18, s25, s6",
                "vmul.f32 s19, s25, s7",
                "vadd.f32 s16, s16, s26",
                "vadd.f32 s17, s17, s26",
                "vadd.f32 s18, s18, s26",
                "vadd.f32 s19, s19, s26",
                "vmul.f32 s16, s16, s4",
                "vmul.f32 s17, s17, s5",
                "vmul.f32 s18, s18, s6",
                "vmul.f32 s19, s19, s7",
                "vadd.f32 s16, s16, s27",
                "vadd.f32 s17, s17, s27",
                "vadd.f32 s18, s18, s27",
                "vadd.f32 s19, s19, s27",
                "vmul.f32 s16, s16, s4",
                "vmul.f32 s17, s17, s5",
                "vmul.f32 s18, s18, s6",
                "vmul.f32 s19, s19, s7",
                "vadd.f32 s16, s16, s28",
                "vadd.f32 s17, s17, s28",
                "vadd.f32 s18, s18, s28",
                "vadd.f32 s19, s19, s28",
                "vmul.f32 s16, s16, s4",
                "vmul.f32 s17, s17, s5",
                "vmul.f32 s18, s18, s6",
                "vmul.f32 s19, s19, s7",
                "vadd.f32 s16, s16, s29",
                "vadd.f32 s17, s17, s29",
                "vadd.f32 s18, s18, s29",
                "vadd.f32 s19, s19, s29",
                "vmul.f32 s16, s16, s4",
                "vmul.f32 s17, s17, s5",
                "vmul.f32 s18, s18, s6",
                "vmul.f32 s19, s19, s7",
                "vadd.f32 s16, s16, s22",
                "vadd.f32 s17, s17, s22",
                "vadd.f32 s18, s18, s22",
                "vadd.f32 s19, s19, s22",
                "vmul.f32 s16, s16, s12",
                "vmul.f32 s17, s17, s13",
                "vmul.f32 s18, s18, s14",
                "vmul.f32 s19, s19, s15",
                "vadd.f32 s16, s16, s4",
                "vadd.f32 s17, s17, s5",
                "vadd.f32 s18, s18, s6",
                "vadd.f32 s19, s19, s7",
                "vadd.f32 s16, s16, s30",
                "vadd.f32 s17, s17, s30",
                "vadd.f32 s18, s18, s30",
                "vadd.f32 s19, s19, s30",
                "sub {k0}, {e127}, {k0}, lsl #23",
                "sub {k1}, {e127}, {k1}, lsl #23",
                "sub {k2}, {e127}, {k2}, lsl #23",
                "sub {k3}, {e127}, {k3}, lsl #23",
                "vmov s8, {k0}",
                "vmov s9, {k1}",
                "vmov s10, {k2}",
                "vmov s11, {k3}",
                "vmul.f32 s16, s16, s8",
                "vmul.f32 s17, s17, s9",
                "vmul.f32 s18, s18, s10",
                "vmul.f32 s19, s19, s11",
                "vadd.f32 s12, s30, s16",
                "vadd.f32 s13, s30, s17",
                "vadd.f32 s14, s30, s18",
                "vadd.f32 s15, s30, s19",
                "vsub.f32 s6, s30, s18",
                "vcmp.f32 s0, #0",
                "vmrs APSR_nzcv, fpscr",
                "ite ge",
                "vmovge.f32 s4, s30",
                "vmovlt.f32 s4, s16",
                "vcmp.f32 s1, #0",
                "vmrs APSR_nzcv, fpscr",
                "ite ge",
                "vmovge.f32 s5, s30",
                "vmovlt.f32 s5, s17",
                "vcmp.f32 s3, #0",
                "vmrs APSR_nzcv, fpscr",
                "ite ge",
                "vmovge.f32 s7, s30",
                "vmovlt.f32 s7, s19",
                "vdiv.f32 s4, s4, s12",
                "vdiv.f32 s5, s5, s13",
                "vdiv.f32 s6, s6, s14",
                "vdiv.f32 s7, s7, s15",
                "vcmp.f32 s2, #0",
                "vmrs APSR_nzcv, fpscr",
                "it mi",
                "vnegmi.f32 s6, s6",
                "vldr s8, [{c}]",
                "vmul.f32 s9, s5, s8",
                "vmul.f32 s10, s4, s6",
                "vstmia {h}!, {{s7}}",
                "vadd.f32 s8, s9, s10",
                "vstmia {c}!, {{s8}}",
                "subs {n}, {n}, #1",
                "bne 1b",
                "vpop {{d0-d15}}",
                acc = inout(reg) acc => _,
                bias = inout(reg) bias => _,
                c = inout(reg) c => _,
                h = inout(reg) h => _,
                n = inout(reg) n => _,
                consts = in(reg) consts,
                e127 = in(reg) 0x3f80_0000u32,
                k0 = out(reg) _,
                k1 = out(reg) _,
                k2 = out(reg) _,
                k3 = out(reg) _,
            );
        }
    }

    /// The tanh steps shared by [`tanh4_bias_f32`] and [`mul_tanh4_f32`]: tanh of s0-s3
    /// (lane for lane `math::tanh_fast4`) into s4-s7, with the constants in s20-s31 and
    /// the operands `k0`-`k3` and `e127` of the calling block.
    macro_rules! tanh4_s0_s3 {
        () => {
            concat!(
                "vabs.f32 s4, s0\n",
                "vabs.f32 s5, s1\n",
                "vabs.f32 s6, s2\n",
                "vabs.f32 s7, s3\n",
                "vcmp.f32 s4, s30\n",
                "vmrs APSR_nzcv, fpscr\n",
                "it gt\n",
                "vmovgt.f32 s4, s30\n",
                "vcmp.f32 s5, s30\n",
                "vmrs APSR_nzcv, fpscr\n",
                "it gt\n",
                "vmovgt.f32 s5, s30\n",
                "vcmp.f32 s6, s30\n",
                "vmrs APSR_nzcv, fpscr\n",
                "it gt\n",
                "vmovgt.f32 s6, s30\n",
                "vcmp.f32 s7, s30\n",
                "vmrs APSR_nzcv, fpscr\n",
                "it gt\n",
                "vmovgt.f32 s7, s30\n",
                "vmul.f32 s4, s31, s4\n",
                "vmul.f32 s5, s31, s5\n",
                "vmul.f32 s6, s31, s6\n",
                "vmul.f32 s7, s31, s7\n",
                "vmul.f32 s8, s4, s20\n",
                "vmul.f32 s9, s5, s20\n",
                "vmul.f32 s10, s6, s20\n",
                "vmul.f32 s11, s7, s20\n",
                "vadd.f32 s8, s8, s21\n",
                "vadd.f32 s9, s9, s21\n",
                "vadd.f32 s10, s10, s21\n",
                "vadd.f32 s11, s11, s21\n",
                "vcvt.s32.f32 s8, s8\n",
                "vcvt.s32.f32 s9, s9\n",
                "vcvt.s32.f32 s10, s10\n",
                "vcvt.s32.f32 s11, s11\n",
                "vmov {k0}, s8\n",
                "vmov {k1}, s9\n",
                "vmov {k2}, s10\n",
                "vmov {k3}, s11\n",
                "vcvt.f32.s32 s8, s8\n",
                "vcvt.f32.s32 s9, s9\n",
                "vcvt.f32.s32 s10, s10\n",
                "vcvt.f32.s32 s11, s11\n",
                "vmul.f32 s12, s8, s22\n",
                "vmul.f32 s13, s9, s22\n",
                "vmul.f32 s14, s10, s22\n",
                "vmul.f32 s15, s11, s22\n",
                "vmul.f32 s8, s8, s23\n",
                "vmul.f32 s9, s9, s23\n",
                "vmul.f32 s10, s10, s23\n",
                "vmul.f32 s11, s11, s23\n",
                "vadd.f32 s4, s4, s12\n",
                "vadd.f32 s5, s5, s13\n",
                "vadd.f32 s6, s6, s14\n",
                "vadd.f32 s7, s7, s15\n",
                "vadd.f32 s4, s4, s8\n",
                "vadd.f32 s5, s5, s9\n",
                "vadd.f32 s6, s6, s10\n",
                "vadd.f32 s7, s7, s11\n",
                "vmul.f32 s12, s4, s4\n",
                "vmul.f32 s13, s5, s5\n",
                "vmul.f32 s14, s6, s6\n",
                "vmul.f32 s15, s7, s7\n",
                "vmul.f32 s16, s24, s4\n",
                "vmul.f32 s17, s24, s5\n",
                "vmul.f32 s18, s24, s6\n",
                "vmul.f32 s19, s24, s7\n",
                "vadd.f32 s16, s16, s25\n",
                "vadd.f32 s17, s17, s25\n",
                "vadd.f32 s18, s18, s25\n",
                "vadd.f32 s19, s19, s25\n",
                "vmul.f32 s16, s16, s4\n",
                "vmul.f32 s17, s17, s5\n",
                "vmul.f32 s18, s18, s6\n",
                "vmul.f32 s19, s19, s7\n",
                "vadd.f32 s16, s16, s26\n",
                "vadd.f32 s17, s17, s26\n",
                "vadd.f32 s18, s18, s26\n",
                "vadd.f32 s19, s19, s26\n",
                "vmul.f32 s16, s16, s4\n",
                "vmul.f32 s17, s17, s5\n",
                "vmul.f32 s18, s18, s6\n",
                "vmul.f32 s19, s19, s7\n",
                "vadd.f32 s16, s16, s27\n",
                "vadd.f32 s17, s17, s27\n",
                "vadd.f32 s18, s18, s27\n",
                "vadd.f32 s19, s19, s27\n",
                "vmul.f32 s16, s16, s4\n",
                "vmul.f32 s17, s17, s5\n",
                "vmul.f32 s18, s18, s6\n",
                "vmul.f32 s19, s19, s7\n",
                "vadd.f32 s16, s16, s28\n",
                "vadd.f32 s17, s17, s28\n",
                "vadd.f32 s18, s18, s28\n",
                "vadd.f32 s19, s19, s28\n",
                "vmul.f32 s16, s16, s4\n",
                "vmul.f32 s17, s17, s5\n",
                "vmul.f32 s18, s18, s6\n",
                "vmul.f32 s19, s19, s7\n",
                "vadd.f32 s16, s16, s21\n",
                "vadd.f32 s17, s17, s21\n",
                "vadd.f32 s18, s18, s21\n",
                "vadd.f32 s19, s19, s21\n",
                "vmul.f32 s16, s16, s12\n",
                "vmul.f32 s17, s17, s13\n",
                "vmul.f32 s18, s18, s14\n",
                "vmul.f32 s19, s19, s15\n",
                "vadd.f32 s16, s16, s4\n",
                "vadd.f32 s17, s17, s5\n",
                "vadd.f32 s18, s18, s6\n",
                "vadd.f32 s19, s19, s7\n",
                "vadd.f32 s16, s16, s29\n",
                "vadd.f32 s17, s17, s29\n",
                "vadd.f32 s18, s18, s29\n",
                "vadd.f32 s19, s19, s29\n",
                "sub {k0}, {e127}, {k0}, lsl #23\n",
                "sub {k1}, {e127}, {k1}, lsl #23\n",
                "sub {k2}, {e127}, {k2}, lsl #23\n",
                "sub {k3}, {e127}, {k3}, lsl #23\n",
                "vmov s8, {k0}\n",
                "vmov s9, {k1}\n",
                "vmov s10, {k2}\n",
                "vmov s11, {k3}\n",
                "vmul.f32 s16, s16, s8\n",
                "vmul.f32 s17, s17, s9\n",
                "vmul.f32 s18, s18, s10\n",
                "vmul.f32 s19, s19, s11\n",
                "vsub.f32 s4, s29, s16\n",
                "vsub.f32 s5, s29, s17\n",
                "vsub.f32 s6, s29, s18\n",
                "vsub.f32 s7, s29, s19\n",
                "vadd.f32 s12, s29, s16\n",
                "vadd.f32 s13, s29, s17\n",
                "vadd.f32 s14, s29, s18\n",
                "vadd.f32 s15, s29, s19\n",
                "vdiv.f32 s4, s4, s12\n",
                "vdiv.f32 s5, s5, s13\n",
                "vdiv.f32 s6, s6, s14\n",
                "vdiv.f32 s7, s7, s15\n",
                "vcmp.f32 s0, #0\n",
                "vmrs APSR_nzcv, fpscr\n",
                "it mi\n",
                "vnegmi.f32 s4, s4\n",
                "vcmp.f32 s1, #0\n",
                "vmrs APSR_nzcv, fpscr\n",
                "it mi\n",
                "vnegmi.f32 s5, s5\n",
                "vcmp.f32 s2, #0\n",
                "vmrs APSR_nzcv, fpscr\n",
                "it mi\n",
                "vnegmi.f32 s6, s6\n",
                "vcmp.f32 s3, #0\n",
                "vmrs APSR_nzcv, fpscr\n",
                "it mi\n",
                "vnegmi.f32 s7, s7\n",
            )
        };
    }

    /// The loop of [`super::tanh4_bias_f32`]: per block `x + bias` into s0-s3, then
    /// [`super::mul_tanh4_f32`]'s tanh steps. `consts`: -log2 e, 0.5, ln 2 high and low
    /// parts, P0-P4, 1, 9.
    ///
    /// # Safety
    /// `x` valid for `n > 0` blocks (read and written), `bias` for `n` blocks, `consts`
    /// for 11 values.
    #[inline(always)]
    pub unsafe fn tanh4_bias_f32(
        x: *mut [f32; 4],
        bias: *const [f32; 4],
        n: usize,
        consts: *const f32,
    ) {
        // SAFETY (caller: pointers valid as documented): per block the loop reads one
        // block of `x` and of `bias` and writes that block of `x`; every FPU register
        // is pushed before and popped after; sp is restored; only declared core
        // registers and the flags change.
        unsafe {
            asm!(
                "vpush {{d0-d15}}",
                "vldmia {consts}, {{s20-s30}}",
                "vmov.f32 s31, #-2.0",
                "1:",
                "vldmia {x}, {{s0-s3}}",
                "vldmia {b}!, {{s4-s7}}",
                "vadd.f32 s0, s0, s4",
                "vadd.f32 s1, s1, s5",
                "vadd.f32 s2, s2, s6",
                "vadd.f32 s3, s3, s7",
                tanh4_s0_s3!(),
                "vstmia {x}!, {{s4-s7}}",
                "subs {n}, {n}, #1",
                "bne 1b",
                "vpop {{d0-d15}}",
                x = inout(reg) x => _,
                b = inout(reg) bias => _,
                n = inout(reg) n => _,
                consts = in(reg) consts,
                e127 = in(reg) 0x3f80_0000u32,
                k0 = out(reg) _,
                k1 = out(reg) _,
                k2 = out(reg) _,
                k3 = out(reg) _,
            );
        }
    }

    /// The loop of [`super::mul_tanh4_f32`]. Registers: s0-s3 `c`, s4-s7 `-2 min(|c|,
    /// 9)`, then `r`, then `tanh`; s8-s11 `u`, `k`, the scale, then `h`; s12-s15 `hi`,
    /// `z`, the denominators; s16-s19 the polynomial and `e`; s20-s30 the constants
    /// (`consts`: -log2 e, 0.5, ln 2 high and low parts, P0-P4, 1, 9), s31 -2. The
    /// exponential's clamp at -87 is left out: its argument is at least -18 (or NaN).
    ///
    /// # Safety
    /// `h` valid for `n > 0` blocks (read and written), `c` for `n` blocks, `consts` for
    /// 11 values.
    #[inline(always)]
    pub unsafe fn mul_tanh4_f32(
        h: *mut [f32; 4],
        c: *const [f32; 4],
        n: usize,
        consts: *const f32,
    ) {
        // SAFETY (caller: pointers valid as documented): per block the loop reads one
        // block of `c` and of `h` and writes that block of `h`; every FPU register is
        // pushed before and popped after; sp is restored; only declared core registers
        // and the flags change.
        unsafe {
            asm!(
                "vpush {{d0-d15}}",
                "vldmia {consts}, {{s20-s30}}",
                "vmov.f32 s31, #-2.0",
                "1:",
                "vldmia {c}!, {{s0-s3}}",
                tanh4_s0_s3!(),
                "vldmia {h}, {{s8-s11}}",
                "vmul.f32 s8, s8, s4",
                "vmul.f32 s9, s9, s5",
                "vmul.f32 s10, s10, s6",
                "vmul.f32 s11, s11, s7",
                "vstmia {h}!, {{s8-s11}}",
                "subs {n}, {n}, #1",
                "bne 1b",
                "vpop {{d0-d15}}",
                h = inout(reg) h => _,
                c = inout(reg) c => _,
                n = inout(reg) n => _,
                consts = in(reg) consts,
                e127 = in(reg) 0x3f80_0000u32,
                k0 = out(reg) _,
                k1 = out(reg) _,
                k2 = out(reg) _,
                k3 = out(reg) _,
            );
        }
    }

    /// One quad of a 4-row block of [`lstm_small_i16`] (input words in `$sa`, `$sb`):
    /// one LDM of its 8 weight words from lr, 8 SMLAD into r0-r3.
    macro_rules! small_quad_macs {
        ($sa:literal, $sb:literal) => {
            concat!(
                "ldm lr!, {{r4, r5, r6, r7, r8, r9, r10, r11}}\n",
                "vmov r12, ",
                $sa,
                "\n",
                "smlad r0, r4, r12, r0\n",
                "smlad r1, r5, r12, r1\n",
                "smlad r2, r6, r12, r2\n",
                "smlad r3, r7, r12, r3\n",
                "vmov r12, ",
                $sb,
                "\n",
                "smlad r0, r8, r12, r0\n",
                "smlad r1, r9, r12, r1\n",
                "smlad r2, r10, r12, r2\n",
                "smlad r3, r11, r12, r3\n",
            )
        };
    }

    /// `$m!(k, s2k, s2k+1)` for the 8 quads of `[e; h]` in s0-s15, as one string.
    macro_rules! for_z_quads {
        ($m:ident) => {
            concat!(
                $m!("0", "s0", "s1"),
                $m!("1", "s2", "s3"),
                $m!("2", "s4", "s5"),
                $m!("3", "s6", "s7"),
                $m!("4", "s8", "s9"),
                $m!("5", "s10", "s11"),
                $m!("6", "s12", "s13"),
                $m!("7", "s14", "s15"),
            )
        };
    }

    /// One input-layer block `b` of [`lstm_small_i16`]: bias, IQ quads, 4 tanh (or,
    /// for a linear input layer, 4 `SSAT #16` of the shifted sums), the packed e pair
    /// into `$s0, $s1`.
    macro_rules! small_in_block {
        ($b:literal, $s0:literal, $s1:literal) => {
            concat!(
                ".if {eb} > ",
                $b,
                "\n",
                "vmov r12, s19\n",
                "ldm r12!, {{r0, r1, r2, r3}}\n",
                "vmov s19, r12\n",
                small_quad_macs!("s20", "s21"),
                ".if {iq} > 1\n",
                small_quad_macs!("s22", "s23"),
                ".endif\n",
                ".if {lin}\n",
                "ssat r0, #16, r0, asr #{si}\n",
                "ssat r1, #16, r1, asr #{si}\n",
                "ssat r2, #16, r2, asr #{si}\n",
                "ssat r3, #16, r3, asr #{si}\n",
                ".else\n",
                "vmov r4, s17\n",
                "ssat r0, #13, r0, asr #{si}\n",
                "ssat r1, #13, r1, asr #{si}\n",
                "ssat r2, #13, r2, asr #{si}\n",
                "ssat r3, #13, r3, asr #{si}\n",
                "ldrsh r0, [r4, r0, lsl #1]\n",
                "ldrsh r1, [r4, r1, lsl #1]\n",
                "ldrsh r2, [r4, r2, lsl #1]\n",
                "ldrsh r3, [r4, r3, lsl #1]\n",
                ".endif\n",
                "pkhbt r0, r0, r1, lsl #16\n",
                "pkhbt r2, r2, r3, lsl #16\n",
                "vmov ",
                $s0,
                ", ",
                $s1,
                ", r0, r2\n",
                ".endif\n",
            )
        };
    }

    /// One quad `p` of `[e; h]` (words in `$sa`, `$sb`) of a gate block of
    /// [`lstm_small_i16`].
    macro_rules! small_gate_quad {
        ($p:literal, $sa:literal, $sb:literal) => {
            concat!(
                ".if {zq} > ",
                $p,
                "\n",
                small_quad_macs!($sa, $sb),
                ".endif\n"
            )
        };
    }

    /// One quad `q` of the output rows `r < O` of [`lstm_small_i16`]: the two h words
    /// by LDRD from the state (r6), each row's two weight words by LDR (lr + offset).
    macro_rules! small_out_row {
        ($r:literal, $acc:literal) => {
            concat!(
                ".if {o} > ",
                $r,
                "\n",
                "ldr r8, [lr, #(32 * \\q + 4 * ",
                $r,
                ")]\n",
                "smlad ",
                $acc,
                ", r8, r4, ",
                $acc,
                "\n",
                "ldr r9, [lr, #(32 * \\q + 16 + 4 * ",
                $r,
                ")]\n",
                "smlad ",
                $acc,
                ", r9, r5, ",
                $acc,
                "\n",
                ".endif\n",
            )
        };
    }

    /// The fused small int16 network step, see [`super::lstm_small_i16`]. `args` =
    /// `[xq, in_w, in_bias, gate_w, gate_bias, state, sigmoid mid, tanh mid, out_w]`.
    /// Registers: accumulators r0-r3, weights r4-r11, the input word r12, the weight
    /// pointer lr; s0-s15 `[e; h]`, s16/s17 the table middles, s18 the state, s19/s25
    /// the bias pointers, s20-s23 the input words, s24 the gate weights, s26 the
    /// output weights. Returns the output accumulators.
    ///
    /// # Safety
    /// `args` as documented, each pointer valid for what the wrapper's SAFETY note lists.
    #[inline(always)]
    pub unsafe fn lstm_small_i16<
        F: crate::nn::format::QuantFormat,
        const IQ: usize,
        const EB: usize,
        const H: usize,
        const ZQ: usize,
        const O: usize,
    >(
        args: &[usize; 9],
    ) -> [i32; 4] {
        let (a0, a1, a2, a3): (i32, i32, i32, i32);
        // SAFETY (caller: pointers valid as documented): see the wrapper.
        unsafe {
            asm!(
                "push {{r6, r7}}",
                "ldr r1, [r0, #32]",
                "vmov s26, r1",
                "ldm r0, {{r1, r2, r3, r4, r5, r6, r8, r9}}",
                "vmov s16, s17, r8, r9",
                "vmov s18, s19, r6, r3",
                "vmov s24, s25, r4, r5",
                "vldmia r1, {{s20-s{xl}}}",
                "add r1, r6, #{h_base}",
                "vldmia r1, {{s{h0}-s{h1}}}",
                "mov lr, r2",
                for_z_quads!(small_in_block),
                "vmov lr, s24",
                ".irp j, 0,1,2,3,4,5,6,7,8,9,10,11,12,13,14,15,16,17,18,19,20,21,22,23,24,25,26,27,28,29,30,31",
                ".if \\j < {h}",
                "vmov r12, s25",
                "ldm r12!, {{r0, r1, r2, r3}}",
                "vmov s25, r12",
                for_z_quads!(small_gate_quad),
                "vmov r4, r5, s16, s17",
                "vmov r6, s18",
                "ssat r0, #13, r0, asr #{s0}",
                "ssat r1, #13, r1, asr #{s1}",
                "ssat r2, #13, r2, asr #{s2}",
                "ssat r3, #13, r3, asr #{s3}",
                "ldrsh r0, [r4, r0, lsl #1]",
                "ldrsh r1, [r4, r1, lsl #1]",
                "ldrsh r2, [r5, r2, lsl #1]",
                "ldrsh r3, [r4, r3, lsl #1]",
                "ldrsh r8, [r6, #({c_off} + 2 * \\j)]",
                "mov r10, #{cr}",
                "smulbb r0, r0, r2",
                "smlabb r9, r8, r1, r10",
                "add r9, r9, r0, asr #{cig}",
                "ssat r8, #16, r9, asr #{cf}",
                "strh r8, [r6, #({c_off} + 2 * \\j)]",
                "ssat r9, #13, r8, asr #{ct}",
                "ldrsh r9, [r5, r9, lsl #1]",
                "smulbb r3, r3, r9",
                "asr r3, r3, #15",
                "strh r3, [r6, #({h_base} + 2 * \\j)]",
                ".endif",
                ".endr",
                "vmov r6, s18",
                "vmov lr, s26",
                "movs r0, #0",
                "movs r1, #0",
                "movs r2, #0",
                "movs r3, #0",
                ".irp q, 0,1,2,3,4,5,6,7",
                ".if \\q < {hq}",
                "ldrd r4, r5, [r6, #({h_base} + 8 * \\q)]",
                small_out_row!("0", "r0"),
                small_out_row!("1", "r1"),
                small_out_row!("2", "r2"),
                small_out_row!("3", "r3"),
                ".endif",
                ".endr",
                "pop {{r6, r7}}",
                eb = const EB,
                iq = const IQ,
                zq = const ZQ,
                h = const H,
                hq = const H / 4,
                o = const O,
                xl = const 20 + 2 * IQ - 1,
                h_base = const 8 * EB,
                h0 = const 2 * EB,
                h1 = const 2 * ZQ - 1,
                c_off = const 8 * ZQ,
                si = const F::INPUT_SHIFT,
                lin = const F::INPUT_ACTIVATION.is_linear() as u32,
                s0 = const F::GATE_SHIFTS[0],
                s1 = const F::GATE_SHIFTS[1],
                s2 = const F::GATE_SHIFTS[2],
                s3 = const F::GATE_SHIFTS[3],
                ct = const crate::nn::format::CELL_TANH_SHIFT,
                cr = const crate::nn::format::CELL_ROUND,
                cig = const crate::nn::format::CELL_IG_SHIFT,
                cf = const crate::nn::format::ACT_FRAC_BITS,
                inout("r0") args.as_ptr() => a0,
                out("r1") a1,
                out("r2") a2,
                out("r3") a3,
                out("r4") _,
                out("r5") _,
                out("r8") _,
                out("r9") _,
                out("r10") _,
                out("r11") _,
                out("r12") _,
                out("lr") _,
                out("s0") _, out("s1") _, out("s2") _, out("s3") _,
                out("s4") _, out("s5") _, out("s6") _, out("s7") _,
                out("s8") _, out("s9") _, out("s10") _, out("s11") _,
                out("s12") _, out("s13") _, out("s14") _, out("s15") _,
                out("s16") _, out("s17") _, out("s18") _, out("s19") _,
                out("s20") _, out("s21") _, out("s22") _, out("s23") _,
                out("s24") _, out("s25") _, out("s26") _,
            );
        }
        [a0, a1, a2, a3]
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

    /// Test data: a 32-bit integer hash of `seed` (lowbias32).
    fn word(seed: u32) -> u32 {
        let mut x = seed;
        x ^= x >> 16;
        x = x.wrapping_mul(0x7feb_352d);
        x ^= x >> 15;
        x = x.wrapping_mul(0x846c_a68b);
        x ^ (x >> 16)
    }

    /// A test value in [0, 1) from a hash.
    fn unit(h: u32) -> f32 {
        (h >> 8) as f32 * (1.0 / 16_777_216.0)
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
            core::array::from_fn(|r| unit(word((k * 4 + r) as u32)) - 0.5)
        });
        let x: [f32; 5] = core::array::from_fn(|k| 3.0 * unit(word(300 + k as u32)) - 1.5);
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
    fn layer_kernels_equal_their_blockwise_dots() {
        // 3 blocks of 7 quads (28 columns): the 4-quad loop and the single-quad tail.
        const Q: usize = 7;
        let w: [[[u32; 4]; 2]; 3 * Q] = core::array::from_fn(|q| {
            core::array::from_fn(|p| core::array::from_fn(|r| word(5 + (q * 8 + p * 4 + r) as u32)))
        });
        let x: [[u32; 2]; Q] =
            core::array::from_fn(|q| core::array::from_fn(|p| word(700 + (2 * q + p) as u32)));
        let bias = [[1, 2, 3, 4], [-5, 6, -7, 8], [0; 4]];
        let want: [[i32; 4]; 3] =
            core::array::from_fn(|b| dot4_i16(bias[b], &w[b * Q..(b + 1) * Q], &x));
        let mut acc = [[7; 4]; 3];
        matvec4_i16(&mut acc, &bias, &w, &x);
        assert_eq!(acc, want);
        // 2 blocks of 19 quads: two 8-quad iterations and 3 single quads.
        let w19: [[[u32; 4]; 2]; 38] = core::array::from_fn(|q| {
            core::array::from_fn(|p| {
                core::array::from_fn(|r| word(3000 + (q * 8 + p * 4 + r) as u32))
            })
        });
        let x19: [[u32; 2]; 19] =
            core::array::from_fn(|q| core::array::from_fn(|p| word(4000 + (2 * q + p) as u32)));
        let mut acc2 = [[0; 4]; 2];
        matvec4_i16(&mut acc2, &bias[..2], &w19, &x19);
        for b in 0..2 {
            assert_eq!(acc2[b], dot4_i16(bias[b], &w19[b * 19..(b + 1) * 19], &x19));
        }
        let mut copy = [[0; 4]; 2];
        matvec4_i16(&mut copy, &bias[..2], &w19, &[]);
        assert_eq!(copy, [bias[0], bias[1]]);
        // int8: 3 blocks of 7 quads (three 2-quad iterations and the odd quad), 2 of 19.
        let w8: [[u32; 4]; 3 * Q] = core::array::from_fn(|q| w[q][0]);
        let mut acc8 = [[7; 4]; 3];
        matvec4_i8(&mut acc8, &bias, &w8, &x);
        for b in 0..3 {
            assert_eq!(
                acc8[b],
                dot4_i8(bias[b], &w8[b * Q..(b + 1) * Q], &x),
                "block {b}"
            );
        }
        let w8_19: [[u32; 4]; 38] = core::array::from_fn(|q| w19[q][1]);
        let mut acc8 = [[0; 4]; 2];
        matvec4_i8(&mut acc8, &bias[..2], &w8_19, &x19);
        for b in 0..2 {
            assert_eq!(
                acc8[b],
                dot4_i8(bias[b], &w8_19[b * 19..(b + 1) * 19], &x19)
            );
        }
        let mut copy8 = [[0; 4]; 2];
        matvec4_i8(&mut copy8, &bias[..2], &w8_19, &[]);
        assert_eq!(copy8, [bias[0], bias[1]]);
        // f32: 2 blocks of 11 columns (one 8-column iteration and 3 single columns).
        const N: usize = 11;
        let wf: [[f32; 4]; 2 * N] = core::array::from_fn(|k| {
            core::array::from_fn(|r| unit(word(900 + (k * 4 + r) as u32)) - 0.5)
        });
        let xf: [f32; N] = core::array::from_fn(|k| 4.0 * unit(word(1200 + k as u32)) - 2.0);
        let mut out = [[9.0f32; 4]; 2];
        matvec4_f32(&mut out, &wf, &xf);
        for b in 0..2 {
            let want = dot4_f32([0.0; 4], &wf[b * N..(b + 1) * N], &xf);
            assert_eq!(
                out[b].map(f32::to_bits),
                want.map(f32::to_bits),
                "block {b}"
            );
        }
        // The same layer from three parts: the same bits, whichever split.
        for first in 0..=2 {
            for second in first..=2 {
                let mut parts = [[9.0f32; 4]; 2];
                let (head, rest) = wf.split_at(first * N);
                let (middle, tail) = rest.split_at((second - first) * N);
                matvec4_f32_parts(&mut parts, [head, middle, tail], &xf);
                assert_eq!(
                    parts.map(|b| b.map(f32::to_bits)),
                    out.map(|b| b.map(f32::to_bits)),
                    "split after {first} and {second} blocks"
                );
            }
        }
        let mut none = [[1.0f32; 4]; 1];
        matvec4_f32(&mut none, &wf, &[]);
        assert_eq!(none, [[0.0; 4]]);
    }

    #[test]
    fn lstm_cells_f32_is_the_gates_and_the_cell_update() {
        // Gate sums over the activations' whole range, NaN and the clamps included.
        let sums = [
            -100.0f32,
            -9.5,
            -1.25,
            -0.0,
            0.0,
            3e-8,
            0.7,
            9.0,
            20.0,
            120.0,
            f32::NAN,
        ];
        let acc: [[f32; 4]; 11] =
            core::array::from_fn(|j| core::array::from_fn(|r| sums[(j + 3 * r) % sums.len()]));
        let bias: [[f32; 4]; 11] = core::array::from_fn(|j| {
            core::array::from_fn(|r| unit(word((4 * j + r) as u32)) - 0.5)
        });
        let c0: [f32; 11] = core::array::from_fn(|j| 4.0 * unit(word(50 + j as u32)) - 2.0);
        let mut c = c0;
        let mut h = [7.0f32; 11];
        lstm_cells_f32(&acc, &bias, &mut c, &mut h);
        for j in 0..11 {
            let x: [f32; 4] = core::array::from_fn(|r| acc[j][r] + bias[j][r]);
            let (i, f, g, o) = (
                crate::math::sigmoid_fast(x[0]),
                crate::math::sigmoid_fast(x[1]),
                crate::math::tanh_fast(x[2]),
                crate::math::sigmoid_fast(x[3]),
            );
            assert_eq!(c[j].to_bits(), (f * c0[j] + i * g).to_bits(), "cell {j}");
            assert_eq!(h[j].to_bits(), o.to_bits(), "cell {j}");
        }
        // Only min(len) cells are touched.
        let mut c2 = [1.0f32; 3];
        let mut h2 = [2.0f32; 3];
        lstm_cells_f32(&acc[..2], &bias, &mut c2, &mut h2);
        assert_eq!((c2[2], h2[2]), (1.0, 2.0));
    }

    #[test]
    fn the_tanh_layers_are_tanh_fast_lane_for_lane() {
        let v = [
            -30.0f32,
            -9.5,
            -1.0,
            -0.0,
            0.0,
            1e-6,
            0.3,
            8.9,
            12.0,
            f32::INFINITY,
            f32::NAN,
        ];
        let x: [[f32; 4]; 7] =
            core::array::from_fn(|j| core::array::from_fn(|r| v[(3 * j + r) % v.len()]));
        let b: [[f32; 4]; 7] = core::array::from_fn(|j| {
            core::array::from_fn(|r| unit(word((9 * j + r) as u32)) - 0.5)
        });
        let mut t = x;
        tanh4_bias_f32(&mut t, &b);
        let mut m = b;
        mul_tanh4_f32(&mut m, &x);
        for j in 0..7 {
            for r in 0..4 {
                let want_t = crate::math::tanh_fast(x[j][r] + b[j][r]);
                assert_eq!(
                    t[j][r].to_bits(),
                    want_t.to_bits(),
                    "tanh block {j} lane {r}"
                );
                let want_m = b[j][r] * crate::math::tanh_fast(x[j][r]);
                assert_eq!(
                    m[j][r].to_bits(),
                    want_m.to_bits(),
                    "mul block {j} lane {r}"
                );
            }
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
