//! Quantised LSTM kernels: the streaming step of the compensation network
//! (`input layer (tanh) -> LSTM -> output layer`, the architecture of `crate::lstm`)
//! in three precisions, with weights pre-arranged by the exporter
//! (`model-export export`) for the Cortex-M4:
//!
//! | precision | weights | activations | accumulator | kernel |
//! |---|---|---|---|---|
//! | [`F32Lstm`] | f32 | f32 | f32, sequential per row | 4 rows per pass, libm sigmoid/tanh |
//! | [`QuantLstm<I16Weights>`] | int16, per-row scale | int16 | i32 (SMLAD), i64 requantisation | `dsp::dot4_i16` |
//! | [`QuantLstm<I8Weights>`] | int8, per-row scale | int16 | i32 (SXTB16 + SMLAD), i64 requantisation | `dsp::dot4_i8` |
//!
//! # Integer scheme (in the spirit of CMSIS-NN / TFLM int16x8 LSTM)
//!
//! Q formats (`Qm.n`: m integer bits, n fraction bits, sign bit not counted):
//!
//! | quantity | format | range |
//! |---|---|---|
//! | normalised input `x_n = (x - mean) / std` | Q3.12 | +-8 |
//! | input-layer output `e = tanh(.)` | Q0.15 | +-1 |
//! | hidden state `h` | Q0.15 | +-1 |
//! | gate pre-activations (input layer too) | Q3.12 | +-8 (sigmoid/tanh saturate beyond) |
//! | gates `i, f, o` (sigmoid) and `g` (tanh) | Q0.15 | 0..1, +-1 |
//! | cell state `c` | Q4.11 (power-of-two scale 2^-11) | +-16 |
//!
//! Every weight row `r` has its own scale `s_r` (`w ~ s_r * w_q`): `max|w| / 32767`
//! (int16) or `/ 127` (int8), enlarged by the exporter where needed so that the worst
//! case `sum_k |w_q[r][k]| * 32768 + |b_q[r]| < 2^31`: no accumulator can overflow
//! for any input (int8 rows of up to 511 columns always fit). The bias is folded into
//! the accumulator's scale (`b_q = round(b / (s_r * 2^-n_x))`), the input
//! normalisation into a per-feature multiplier (`x_q = round((x - mean) * 2^12 / std)`,
//! the only f32 arithmetic besides the output), the LSTM's two PyTorch biases into one.
//! A row's accumulator goes to the Q3.12 pre-activation by a fixed-point multiplier:
//! `pre = sat16((acc * m_r + 2^(s-1)) >> s)` in i64, `m_r` in `[2^30, 2^31)`.
//! The cell update is `c' = sat16(round(f*c >> 15) + round(i*g >> 19))`, `h' =
//! round(o * tanh(sat16(2c')) >> 15)`. The output row is `y = acc * scale_o + offset_o`
//! in f32 (`scale_o` holds `s_o * 2^-15 * output_std`, `offset_o` the bias and the
//! output mean). Activations: [`act`] (table + interpolation, no division).
//!
//! # Layout
//!
//! Rows come in blocks of 4, columns in quads of 4 (padded with zero weights and
//! zero inputs by the exporter). The LSTM's gate rows are grouped by cell: block `j`
//! holds the rows `i_j, f_j, g_j, o_j`, so one 4-row pass gives all gates of cell `j`.
//! The LSTM's input is the packed vector `z = [e; h]` (input layer output, then the
//! hidden state) and one weight matrix `[W_ih | W_hh]` with one scale per row.
//! Packed int16 activations are `[[u32; 2]; Q]`: quad `q`, word `0` = columns
//! `4q, 4q+1`, word `1` = `4q+2, 4q+3` (`dsp::pack`).
//!
//! Shapes are const generics; [`QuantLstm::SHAPE`] and [`F32Lstm::SHAPE`] are
//! compile-time assertions (a model whose sizes do not fit together does not compile).

pub mod act;

use crate::dsp;
use crate::math;

/// Fraction bits of the normalised input (Q3.12).
pub const INPUT_FRAC_BITS: u32 = 12;
/// Fraction bits of gate and layer pre-activations (Q3.12).
pub const PRE_FRAC_BITS: u32 = 12;
/// Fraction bits of `e`, `h` and the gates (Q0.15).
pub const ACT_FRAC_BITS: u32 = 15;
/// Fraction bits of the cell state (Q4.11).
pub const CELL_FRAC_BITS: u32 = 11;

/// A weight storage format of the integer kernels: how one block of 4 rows over `Q`
/// column quads is stored and multiplied.
pub trait WeightFormat {
    /// One block of 4 rows over `Q` column quads.
    type Block<const Q: usize>: Copy + core::fmt::Debug;
    /// Name used in reports (`int16`, `int8`).
    const NAME: &'static str;
    /// Largest weight magnitude of the format.
    const MAX_WEIGHT: i32;
    /// `acc[r] + sum_k w[r][k] * x[k]` for the 4 rows of the block.
    fn dot4<const Q: usize>(acc: [i32; 4], w: &Self::Block<Q>, x: &[[u32; 2]; Q]) -> [i32; 4];
}

/// int16 weights: per quad, the two packed pairs of the 4 rows (`[pair][row]`).
#[derive(Clone, Copy, Debug)]
pub struct I16Weights;

impl WeightFormat for I16Weights {
    type Block<const Q: usize> = [[[u32; 4]; 2]; Q];
    const NAME: &'static str = "int16";
    const MAX_WEIGHT: i32 = 32767;
    #[inline(always)]
    fn dot4<const Q: usize>(acc: [i32; 4], w: &Self::Block<Q>, x: &[[u32; 2]; Q]) -> [i32; 4] {
        dsp::dot4_i16(acc, w, x)
    }
}

/// int8 weights: per quad, one word of four int8 weights per row (`dsp::pack_i8`).
#[derive(Clone, Copy, Debug)]
pub struct I8Weights;

impl WeightFormat for I8Weights {
    type Block<const Q: usize> = [[u32; 4]; Q];
    const NAME: &'static str = "int8";
    const MAX_WEIGHT: i32 = 127;
    #[inline(always)]
    fn dot4<const Q: usize>(acc: [i32; 4], w: &Self::Block<Q>, x: &[[u32; 2]; Q]) -> [i32; 4] {
        dsp::dot4_i8(acc, w, x)
    }
}

/// Fixed-point requantisation of one row: multiplier in `[2^30, 2^31)`, right shift.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Requant {
    /// Multiplier (Q31 mantissa).
    pub mult: i32,
    /// Right shift, `1..=62`.
    pub shift: u8,
}

impl Requant {
    /// `sat16((acc * mult + 2^(shift-1)) >> shift)`.
    #[inline(always)]
    pub fn apply(self, acc: i32) -> i16 {
        let s = (self.shift & 63) as u32;
        let p = (acc as i64) * (self.mult as i64) + ((1i64 << s) >> 1);
        sat16_i64(p >> s)
    }
}

#[inline(always)]
fn sat16_i64(v: i64) -> i16 {
    if v > i16::MAX as i64 {
        i16::MAX
    } else if v < i16::MIN as i64 {
        i16::MIN
    } else {
        v as i16
    }
}

#[inline(always)]
fn sat16(v: i32) -> i16 {
    if v > i16::MAX as i32 {
        i16::MAX
    } else if v < i16::MIN as i32 {
        i16::MIN
    } else {
        v as i16
    }
}

/// A dense layer of `4 * B` rows over `4 * Q` columns in format `F`, with per-row
/// requantisation to Q3.12 and the bias in accumulator scale.
#[derive(Clone, Copy, Debug)]
pub struct QuantDense<F: WeightFormat, const B: usize, const Q: usize> {
    /// Weights, block by block.
    pub w: [F::Block<Q>; B],
    /// Bias per row, in the row's accumulator scale.
    pub bias: [[i32; 4]; B],
    /// Requantisation per row to the Q3.12 pre-activation.
    pub requant: [[Requant; 4]; B],
}

/// Output layer of the integer networks: `y = acc * scale + offset` per output.
#[derive(Clone, Copy, Debug)]
pub struct QuantOutput<F: WeightFormat, const OB: usize, const HQ: usize> {
    /// Weights, block by block (rows beyond the outputs are zero).
    pub w: [F::Block<HQ>; OB],
    /// f32 scale per row (row scale x 2^-15 x output std).
    pub scale: [[f32; 4]; OB],
    /// f32 offset per row (bias x output std + output mean).
    pub offset: [[f32; 4]; OB],
}

/// An integer LSTM network: `I` inputs (padded to `4 * IQ` columns), input layer of
/// `E = 4 * EB` rows, `H = 4 * HQ` cells (gate matrix over `ZQ = EB + HQ` quads of
/// `[e; h]`), `O` outputs (padded to `4 * OB` rows).
#[derive(Clone, Copy, Debug)]
pub struct QuantLstm<
    F: WeightFormat,
    const I: usize,
    const IQ: usize,
    const EB: usize,
    const H: usize,
    const HQ: usize,
    const ZQ: usize,
    const O: usize,
    const OB: usize,
> {
    /// Input normalisation: per-feature mean (f32).
    pub input_mean: [f32; I],
    /// Input quantisation: `2^12 / std` per feature.
    pub input_scale: [f32; I],
    /// Input layer (`E` rows over the padded inputs).
    pub input: QuantDense<F, EB, IQ>,
    /// LSTM gates: block `j` = rows `i_j, f_j, g_j, o_j` over `[e; h]`.
    pub gates: QuantDense<F, H, ZQ>,
    /// Output layer.
    pub output: QuantOutput<F, OB, HQ>,
}

/// The recurrent state of an integer network: the packed `[e; h]` vector (the `h`
/// part is the state, the `e` part scratch) and the Q4.11 cell state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct QuantState<const ZQ: usize, const H: usize> {
    /// Packed `[e; h]`, Q0.15.
    pub z: [[u32; 2]; ZQ],
    /// Cell state, Q4.11.
    pub c: [i16; H],
}

impl<const ZQ: usize, const H: usize> QuantState<ZQ, H> {
    /// The zero state a sequence starts from.
    pub const fn new() -> Self {
        QuantState { z: [[0; 2]; ZQ], c: [0; H] }
    }

    /// Forgets the past: back to the zero state.
    pub fn reset(&mut self) {
        *self = Self::new();
    }
}

impl<const ZQ: usize, const H: usize> Default for QuantState<ZQ, H> {
    fn default() -> Self {
        Self::new()
    }
}

/// Rounds half away from zero and saturates to int16 (NaN gives 0).
#[inline(always)]
pub fn quantise_i16(v: f32) -> i16 {
    let r = if v >= 0.0 { v + 0.5 } else { v - 0.5 };
    r as i16
}

/// Writes value `j` of a packed vector.
#[inline(always)]
fn put(q: &mut [u32; 2], k: usize, v: i16) {
    let word = &mut q[(k >> 1) & 1];
    if k & 1 == 0 {
        *word = (*word & 0xffff_0000) | (v as u16 as u32);
    } else {
        *word = (*word & 0x0000_ffff) | ((v as u16 as u32) << 16);
    }
}

impl<
    F: WeightFormat,
    const I: usize,
    const IQ: usize,
    const EB: usize,
    const H: usize,
    const HQ: usize,
    const ZQ: usize,
    const O: usize,
    const OB: usize,
> QuantLstm<F, I, IQ, EB, H, HQ, ZQ, O, OB>
{
    /// Compile-time shape check, evaluated by every [`Self::step`] instantiation.
    pub const SHAPE: () = {
        assert!(I > 0 && O > 0 && EB > 0 && H > 0, "empty network");
        assert!(4 * IQ >= I && 4 * IQ < I + 4, "IQ must be ceil(I / 4)");
        assert!(4 * HQ == H, "H must be 4 * HQ");
        assert!(ZQ == EB + HQ, "ZQ must be EB + HQ ([e; h])");
        assert!(4 * OB >= O && 4 * OB < O + 4, "OB must be ceil(O / 4)");
    };
    /// Multiply-accumulates per step.
    pub const MACS: u32 = (4 * EB * I + 4 * H * (4 * EB + H) + O * H) as u32;

    /// One control tick: advances `state` by the raw (unnormalised) `input` and
    /// returns the de-normalised outputs.
    #[inline(never)]
    pub fn step(&self, state: &mut QuantState<ZQ, H>, input: &[f32; I]) -> [f32; O] {
        let () = Self::SHAPE;
        // Input quantisation (f32, the only float arithmetic before the output).
        let mut xq = [[0u32; 2]; IQ];
        for (k, ((x, m), s)) in input.iter().zip(&self.input_mean).zip(&self.input_scale).enumerate() {
            if let Some(q) = xq.get_mut(k >> 2) {
                put(q, k & 3, quantise_i16((x - m) * s));
            }
        }
        // Input layer: e = tanh(pre), Q0.15, into the e part of z.
        for ((w, (b, rq)), zq) in self.input.w.iter().zip(self.input.bias.iter().zip(&self.input.requant)).zip(state.z.iter_mut()) {
            let acc = F::dot4(*b, w, &xq);
            let e = [0, 1, 2, 3].map(|r| act::tanh_q15(rq[r].apply(acc[r])));
            *zq = [dsp::pack(e[0], e[1]), dsp::pack(e[2], e[3])];
        }
        // LSTM: one block per cell, gates i, f, g, o.
        let mut h_new = [[0u32; 2]; HQ];
        for (j, ((w, (b, rq)), c)) in
            self.gates.w.iter().zip(self.gates.bias.iter().zip(&self.gates.requant)).zip(state.c.iter_mut()).enumerate()
        {
            let acc = F::dot4(*b, w, &state.z);
            let i = act::sigmoid_q15(rq[0].apply(acc[0])) as i32;
            let f = act::sigmoid_q15(rq[1].apply(acc[1])) as i32;
            let g = act::tanh_q15(rq[2].apply(acc[2])) as i32;
            let o = act::sigmoid_q15(rq[3].apply(acc[3])) as i32;
            let fc = (f * (*c as i32) + (1 << 14)) >> 15;
            let ig = (i * g + (1 << 18)) >> 19;
            *c = sat16(fc + ig);
            let tc = act::tanh_q15(sat16(2 * (*c as i32))) as i32;
            let h = ((o * tc + (1 << 14)) >> 15) as i16;
            if let Some(q) = h_new.get_mut(j >> 2) {
                put(q, j & 3, h);
            }
        }
        if let Some(hz) = state.z.get_mut(EB..) {
            for (d, s) in hz.iter_mut().zip(&h_new) {
                *d = *s;
            }
        }
        // Output layer, f32 de-normalisation.
        let mut out = [0.0f32; O];
        let mut rows = out.iter_mut();
        for ((w, s), off) in self.output.w.iter().zip(&self.output.scale).zip(&self.output.offset) {
            let acc = F::dot4([0; 4], w, &h_new);
            for r in 0..4 {
                if let Some(y) = rows.next() {
                    *y = acc[r] as f32 * s[r] + off[r];
                }
            }
        }
        out
    }
}

/// The f32 network in the exporter's layout: `I` inputs, input layer of `E = 4 * EB`
/// rows, `H` cells over `Z = E + H` columns (`[e; h]`), `O` outputs in `OB` blocks.
/// Each block stores its 4 rows column-interleaved (`[k][row]`); every row sums
/// left to right in f32, sigmoid and tanh are `math::sigmoid` / `math::tanh` (libm),
/// the arithmetic of `crate::lstm`.
#[derive(Clone, Copy, Debug)]
pub struct F32Lstm<
    const I: usize,
    const E: usize,
    const EB: usize,
    const H: usize,
    const Z: usize,
    const O: usize,
    const OB: usize,
> {
    /// Input normalisation: per-feature mean.
    pub input_mean: [f32; I],
    /// Input normalisation: `1 / std` per feature.
    pub input_inv_std: [f32; I],
    /// Input layer weights, 4-row blocks `[block][k][row]`.
    pub w_in: [[[f32; 4]; I]; EB],
    /// Input layer bias.
    pub b_in: [[f32; 4]; EB],
    /// Gate weights over `[e; h]`, block `j` = rows `i_j, f_j, g_j, o_j`.
    pub w_gates: [[[f32; 4]; Z]; H],
    /// Gate bias (`bias_ih + bias_hh`).
    pub b_gates: [[f32; 4]; H],
    /// Output weights (rows beyond `O` zero).
    pub w_out: [[[f32; 4]; H]; OB],
    /// Output bias.
    pub b_out: [[f32; 4]; OB],
    /// Output de-normalisation: std per row.
    pub output_std: [[f32; 4]; OB],
    /// Output de-normalisation: mean per row.
    pub output_mean: [[f32; 4]; OB],
}

/// The recurrent state of the f32 network: `[e; h]` (the `h` part is the state) and `c`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct F32State<const Z: usize, const H: usize> {
    /// `[e; h]`.
    pub z: [f32; Z],
    /// Cell state.
    pub c: [f32; H],
}

impl<const Z: usize, const H: usize> F32State<Z, H> {
    /// The zero state.
    pub const fn new() -> Self {
        F32State { z: [0.0; Z], c: [0.0; H] }
    }
    /// Back to the zero state.
    pub fn reset(&mut self) {
        *self = Self::new();
    }
}

impl<const Z: usize, const H: usize> Default for F32State<Z, H> {
    fn default() -> Self {
        Self::new()
    }
}

/// Four rows at once, each summed left to right: `acc[r] + sum_k w[k][r] * x[k]`.
#[inline(always)]
fn dot4_f32<const K: usize>(mut acc: [f32; 4], w: &[[f32; 4]; K], x: &[f32; K]) -> [f32; 4] {
    for (wk, xk) in w.iter().zip(x.iter()) {
        acc[0] += wk[0] * xk;
        acc[1] += wk[1] * xk;
        acc[2] += wk[2] * xk;
        acc[3] += wk[3] * xk;
    }
    acc
}

impl<const I: usize, const E: usize, const EB: usize, const H: usize, const Z: usize, const O: usize, const OB: usize>
    F32Lstm<I, E, EB, H, Z, O, OB>
{
    /// Compile-time shape check, evaluated by every [`Self::step`] instantiation.
    pub const SHAPE: () = {
        assert!(I > 0 && O > 0 && E > 0 && H > 0, "empty network");
        assert!(E == 4 * EB, "E must be 4 * EB");
        assert!(Z == E + H, "Z must be E + H");
        assert!(4 * OB >= O && 4 * OB < O + 4, "OB must be ceil(O / 4)");
    };
    /// Multiply-accumulates per step.
    pub const MACS: u32 = (E * I + 4 * H * Z + O * H) as u32;

    /// One control tick: advances `state` by the raw `input`, returns the outputs.
    #[inline(never)]
    pub fn step(&self, state: &mut F32State<Z, H>, input: &[f32; I]) -> [f32; O] {
        let () = Self::SHAPE;
        let mut xn = [0.0f32; I];
        for (((n, x), m), s) in xn.iter_mut().zip(input).zip(&self.input_mean).zip(&self.input_inv_std) {
            *n = (x - m) * s;
        }
        for ((w, b), e4) in self.w_in.iter().zip(&self.b_in).zip(state.z.chunks_exact_mut(4)) {
            let acc = dot4_f32([0.0; 4], w, &xn);
            for ((e, a), bb) in e4.iter_mut().zip(acc).zip(b) {
                *e = math::tanh(a + bb);
            }
        }
        let mut h_new = [0.0f32; H];
        for (((w, b), c), hn) in self.w_gates.iter().zip(&self.b_gates).zip(state.c.iter_mut()).zip(h_new.iter_mut()) {
            let acc = dot4_f32([0.0; 4], w, &state.z);
            let i = math::sigmoid(acc[0] + b[0]);
            let f = math::sigmoid(acc[1] + b[1]);
            let g = math::tanh(acc[2] + b[2]);
            let o = math::sigmoid(acc[3] + b[3]);
            *c = f * *c + i * g;
            *hn = o * math::tanh(*c);
        }
        if let Some(hz) = state.z.get_mut(E..) {
            for (d, s) in hz.iter_mut().zip(&h_new) {
                *d = *s;
            }
        }
        let mut out = [0.0f32; O];
        let mut rows = out.iter_mut();
        for (((w, b), s), m) in self.w_out.iter().zip(&self.b_out).zip(&self.output_std).zip(&self.output_mean) {
            let acc = dot4_f32([0.0; 4], w, &h_new);
            for r in 0..4 {
                if let Some(y) = rows.next() {
                    *y = (acc[r] + b[r]) * s[r] + m[r];
                }
            }
        }
        out
    }
}
