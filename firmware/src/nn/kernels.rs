//! Quantised LSTM kernels: the streaming step of the compensation network
//! (`input layer (tanh or linear) -> LSTM -> output layer`, the architecture of
//! `crate::nn::reference`)
//! in three precisions, with weights pre-arranged by the exporter
//! (`model-export export`) for the Cortex-M4:
//!
//! | precision | weights | activations | accumulator | kernel |
//! |---|---|---|---|---|
//! | [`F32Lstm`] | f32 | f32 | f32, sequential per row | `dsp::matvec4_f32` (input layer), `dsp::matvec4_f32_parts` (gates, [`F32GateRows`]), `math::sigmoid_fast` / `tanh_fast` |
//! | [`QuantLstm`] with [`I16Weights`] | int16, per-gate power-of-two scale | int16 | i32 (SMLAD) | `dsp::lstm_small_i16` (`[e; h]` of at most 16 words), else `dsp::matvec4_i16` |
//! | [`QuantLstm`] with [`I8Weights`] | int8, per-gate power-of-two scale | int16 | i32 (SXTB16 + SMLAD) | `dsp::matvec4_i8` (gates), `dsp::dot4_i8` |
//!
//! # Integer scheme (in the spirit of CMSIS-NN's q15 kernels and TFLM's int16x8 LSTM)
//!
//! Q formats (`Qm.n`: m integer bits, n fraction bits, sign bit not counted):
//!
//! | quantity | format | range |
//! |---|---|---|
//! | normalised input `x_n = (x - mean) / std` | Q3.12 | +-8 |
//! | input-layer output `e = tanh(.)` | Q0.15 | +-1 |
//! | input-layer output `e` of a linear input layer | `Q(15-F).F`, `F` per network | `+-2^(15-F)` |
//! | hidden state `h` | Q0.15 | +-1 |
//! | gates `i, f, o` (sigmoid) and `g` (tanh) | Q0.15 | 0..1, +-1 |
//! | cell state `c` (i16, power-of-two scale 2^-11) | Q4.11 | +-16 |
//! | input-layer weights | `2^-P_in` per layer | |
//! | gate weights | `2^-P_g` per gate (`i`, `f`, `g`, `o`: the rows of one gate share it, as TFLM's per-tensor gate scales) | |
//! | output weights | f32 scale per row | |
//!
//! Power-of-two scales make requantisation free: an accumulator with `E` fraction bits
//! (`E = P_in + 12` for the input layer, `P_g + 15` for gate `g`) indexes the activation
//! table directly as `sat13(acc >> (E - 9))` (`act::index`, one `SSAT` with a shift), so
//! no multiplier and no rounding shift stand between the multiply-accumulates and the
//! activation. The exporter picks each exponent as the largest for which every weight
//! fits the format (32767 or 127) and no accumulator can overflow for any input
//! (`sum_k |w_q[r][k]| * 32768 + |b_q[r]| < 2^31` on every row), and refuses a model
//! whose index shift would leave `1..=31`.
//!
//! A linear input layer ([`InputActivation::Linear`]) stores `e` as
//! `sat16(acc >> (P_in + 12 - F))`: `F` fraction bits, chosen by the exporter as the
//! most for which the largest `|e|` any Q3.12 input can give fits int16; the shift
//! replaces the tanh index shift ([`QuantFormat::INPUT_SHIFT`]), the half-step that rounds
//! it to nearest is folded into the input bias, and the gate weights of the `e` columns
//! carry the factor `2^(15 - F)` so that every column of `[e; h]` accumulates on the
//! gate's one scale. The bias is folded into the accumulator's
//! scale (`b_q = round(b * 2^E)`), the input normalisation into a per-feature multiplier
//! (`x_q = round((x - mean) * 2^12 / std)`, the only f32 arithmetic besides the output),
//! the LSTM's two PyTorch biases into one. With `i, f, g, o` in Q0.15:
//!
//! ```text
//! c' = sat16((c * f + 2^14 + ((i * g) >> 4)) >> 15)  // SMLABB, SMULBB, ADD ASR, SSAT: Q4.11, rounded
//! h' = (o * tanh(c')) >> 15                         // tanh index sat13(c' >> 2); SMULBB, ASR
//! ```
//!
//! The output row is `y = acc * scale_o + offset_o` in f32 (`scale_o` holds `s_o * 2^-15 *
//! output_std`, `offset_o` the bias and the output mean). Activations: [`act`] (direct
//! lookup in an 8192-entry table, no division).
//!
//! # Layout
//!
//! Rows come in blocks of 4, columns in quads of 4 (padded with zero weights and
//! zero inputs by the exporter). The LSTM's gate rows are grouped by cell: block `j`
//! holds the rows `i_j, f_j, g_j, o_j`, so one 4-row pass gives all gates of cell `j`.
//! The LSTM's input is the packed vector `z = [e; h]` (input layer output, then the
//! hidden state) and one weight matrix `[W_ih | W_hh]`.
//! Packed int16 activations are `[[u32; 2]; Q]`: quad `q`, word `0` = columns
//! `4q, 4q+1`, word `1` = `4q+2, 4q+3` (`dsp::pack`).
//!
//! Shapes are const generics; [`QuantLstm::SHAPE`] and [`F32Lstm::SHAPE`] are
//! compile-time assertions (a model whose sizes do not fit together does not compile).
//! All arithmetic is defined by shape-erased kernels ([`QuantView::step`],
//! [`F32View::step`]) that the fixed-size networks call on their own arrays without
//! copying; the exporter, whose sizes are only known at run time, runs exactly this
//! code on its own vectors. On the Cortex-M4, a small int16 network (`[e; h]` in at
//! most 8 quads, at most 8 inputs) runs instead the fused assembly kernel
//! `dsp::lstm_small_i16`, which computes the same bits (the QEMU golden suites prove it).

use crate::dsp;
use crate::math;
use crate::nn::act;
use crate::nn::format::{
    ACT_FRAC_BITS, CELL_IG_SHIFT, CELL_ROUND, CELL_TANH_SHIFT, I8Weights, I16Weights,
    InputActivation, QuantFormat, QuantState, WeightFormat,
};

impl WeightFormat for I16Weights {
    type Quad = [[u32; 4]; 2];
    const NAME: &'static str = "int16";
    const MAX_WEIGHT: i32 = 32767;
    const INT16_PAIRS: bool = true;
    #[inline(always)]
    fn dot4(acc: [i32; 4], w: &[Self::Quad], x: &[[u32; 2]]) -> [i32; 4] {
        dsp::dot4_i16(acc, w, x)
    }
    #[inline(always)]
    fn matvec4(acc: &mut [[i32; 4]], bias: &[[i32; 4]], w: &[Self::Quad], x: &[[u32; 2]]) {
        dsp::matvec4_i16(acc, bias, w, x)
    }
    fn pack(w: [[i32; 4]; 4]) -> Self::Quad {
        let p = |r: usize, k: usize| dsp::pack(w[r][k] as i16, w[r][k + 1] as i16);
        [
            [p(0, 0), p(1, 0), p(2, 0), p(3, 0)],
            [p(0, 2), p(1, 2), p(2, 2), p(3, 2)],
        ]
    }
    fn int16_pairs(q: &[Self::Quad]) -> Option<&[[[u32; 4]; 2]]> {
        Some(q)
    }
}

impl WeightFormat for I8Weights {
    type Quad = [u32; 4];
    const NAME: &'static str = "int8";
    const MAX_WEIGHT: i32 = 127;
    #[inline(always)]
    fn dot4(acc: [i32; 4], w: &[Self::Quad], x: &[[u32; 2]]) -> [i32; 4] {
        dsp::dot4_i8(acc, w, x)
    }
    #[inline(always)]
    fn matvec4(acc: &mut [[i32; 4]], bias: &[[i32; 4]], w: &[Self::Quad], x: &[[u32; 2]]) {
        dsp::matvec4_i8(acc, bias, w, x)
    }
    fn pack(w: [[i32; 4]; 4]) -> Self::Quad {
        w.map(|row| dsp::pack_i8(row.map(|v| v as i8)))
    }
}

/// Rounds half away from zero and saturates to int16 (NaN gives 0).
#[inline(always)]
pub fn quantise_i16(v: f32) -> i16 {
    let r = if v >= 0.0 { v + 0.5 } else { v - 0.5 };
    // `r as i16` (saturating, NaN -> 0) in two steps the M4F does in one VCVT and
    // one SSAT: the i32 conversion saturates and maps NaN to 0 too.
    (r as i32).clamp(i16::MIN as i32, i16::MAX as i32) as i16
}

/// Writes element `k` (0..4) of a packed quad.
#[inline(always)]
fn put(q: &mut [u32; 2], k: usize, v: i16) {
    let word = &mut q[(k >> 1) & 1];
    if k & 1 == 0 {
        *word = (*word & 0xffff_0000) | (v as u16 as u32);
    } else {
        *word = (*word & 0x0000_ffff) | ((v as u16 as u32) << 16);
    }
}

/// Sizes of an integer network (all in elements, blocks of 4 rows, quads of 4 columns).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct QuantDims {
    /// Inputs `I`.
    pub input: usize,
    /// Input quads `IQ = ceil(I / 4)`.
    pub input_quads: usize,
    /// Input-layer blocks `EB` (`E = 4 * EB`).
    pub embed_blocks: usize,
    /// Cells `H` (a multiple of 4; `HQ = H / 4`).
    pub hidden: usize,
    /// Outputs `O`.
    pub output: usize,
    /// Output blocks `OB = ceil(O / 4)`.
    pub output_blocks: usize,
}

impl QuantDims {
    /// Quads of `[e; h]`.
    pub const fn z_quads(&self) -> usize {
        self.embed_blocks + self.hidden / 4
    }
}

/// An integer network of run-time sizes borrowing flat arrays in the kernel layout.
#[derive(Clone, Copy, Debug)]
pub struct QuantView<'a, F: WeightFormat> {
    /// Sizes.
    pub dims: QuantDims,
    /// `[I]` input mean.
    pub input_mean: &'a [f32],
    /// `[I]` `2^12 / std`.
    pub input_scale: &'a [f32],
    /// `[EB * IQ]` input layer.
    pub in_w: &'a [F::Quad],
    /// `[EB]` input layer bias (accumulator scale).
    pub in_bias: &'a [[i32; 4]],
    /// Activation after the input layer ([`QuantFormat::INPUT_ACTIVATION`]).
    pub in_activation: InputActivation,
    /// Shift of the input layer's accumulators ([`QuantFormat::INPUT_SHIFT`]).
    pub in_shift: u32,
    /// `[H * ZQ]` gates.
    pub gate_w: &'a [F::Quad],
    /// `[H]` gate bias.
    pub gate_bias: &'a [[i32; 4]],
    /// Activation-index shifts of the gates ([`QuantFormat::GATE_SHIFTS`]).
    pub gate_shift: [u32; 4],
    /// The activation tables ([`QuantFormat::ACT_TABLES`]).
    pub act_tables: &'a act::ActTables,
    /// `[OB * HQ]` output layer.
    pub out_w: &'a [F::Quad],
    /// `[OB]` output scale.
    pub out_scale: &'a [[f32; 4]],
    /// `[OB]` output offset.
    pub out_offset: &'a [[f32; 4]],
}

impl<F: WeightFormat> QuantView<'_, F> {
    /// Whether every array has the length `dims` asks for and every shift is in
    /// `1..=31` (`None`), or the first that does not (its name).
    pub fn check(&self) -> Option<&'static str> {
        let d = self.dims;
        let zq = d.z_quads();
        let lens: [(&'static str, usize, usize); 9] = [
            ("input_mean", d.input, self.input_mean.len()),
            ("input_scale", d.input, self.input_scale.len()),
            ("in_w", d.embed_blocks * d.input_quads, self.in_w.len()),
            ("in_bias", d.embed_blocks, self.in_bias.len()),
            ("gate_w", d.hidden * zq, self.gate_w.len()),
            ("gate_bias", d.hidden, self.gate_bias.len()),
            ("out_w", d.output_blocks * (d.hidden / 4), self.out_w.len()),
            ("out_scale", d.output_blocks, self.out_scale.len()),
            ("out_offset", d.output_blocks, self.out_offset.len()),
        ];
        let shape_ok = d.hidden.is_multiple_of(4)
            && d.input_quads * 4 >= d.input
            && d.output_blocks * 4 >= d.output;
        if !shape_ok {
            return Some("dims");
        }
        if !act::shift_fits(self.in_shift) {
            return Some("in_shift");
        }
        if !self.gate_shift.iter().all(|&s| act::shift_fits(s)) {
            return Some("gate_shift");
        }
        lens.iter().find(|(_, e, a)| e != a).map(|(n, _, _)| *n)
    }

    /// Input quantisation (f32, the only float arithmetic before the output): `input`
    /// (`I`) into the packed Q3.12 quads `xq` (`IQ`, padding zero).
    #[inline(always)]
    pub fn quantise_input(&self, xq: &mut [[u32; 2]], input: &[f32]) {
        for q in xq.iter_mut() {
            *q = [0, 0];
        }
        for (k, ((x, m), s)) in input
            .iter()
            .zip(self.input_mean)
            .zip(self.input_scale)
            .enumerate()
        {
            if let Some(q) = xq.get_mut(k >> 2) {
                put(q, k & 3, quantise_i16((x - m) * s));
            }
        }
    }

    /// The output layer over the packed hidden state `h` (`HQ` quads), with the f32
    /// de-normalisation, into `out` (`O`).
    #[inline(always)]
    pub fn output(&self, h: &[[u32; 2]], out: &mut [f32]) {
        let hq = (self.dims.hidden / 4).max(1);
        let blocks = self.out_w.chunks_exact(hq).zip(out.chunks_mut(4));
        for (b, (w, rows)) in blocks.enumerate() {
            self.denormalise(b, F::dot4([0; 4], w, h), rows);
        }
    }

    /// Output block `b` from its row accumulators: `y = acc * scale + offset` (f32)
    /// into `rows` (at most 4; padding rows are not written).
    #[inline(always)]
    pub fn denormalise(&self, b: usize, acc: [i32; 4], rows: &mut [f32]) {
        if let (Some(s), Some(off)) = (self.out_scale.get(b), self.out_offset.get(b)) {
            for ((y, a), (s, off)) in rows.iter_mut().zip(acc).zip(s.iter().zip(off)) {
                *y = a as f32 * s + off;
            }
        }
    }

    /// The kernel: one step. `z` (`ZQ` quads) and `c` (`H`) are the state, `xq`
    /// (`IQ` quads), `h_new` (`HQ` quads) and `acc` (`H` blocks) scratch, `input`
    /// (`I`) and `out` (`O`). Lengths are trusted (a mismatch gives a wrong result,
    /// never a panic).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn step(
        &self,
        z: &mut [[u32; 2]],
        c: &mut [i16],
        xq: &mut [[u32; 2]],
        h_new: &mut [[u32; 2]],
        acc: &mut [[i32; 4]],
        input: &[f32],
        out: &mut [f32],
    ) {
        let d = self.dims;
        let iq = d.input_quads.max(1);
        self.quantise_input(xq, input);
        // Input layer: e = tanh(acc), Q0.15, or the linear layer's requantised acc,
        // into the e part of z.
        let blocks = self.in_w.chunks_exact(iq).zip(self.in_bias);
        let linear = self.in_activation.is_linear();
        for ((w, b), zq_e) in blocks.zip(z.iter_mut()) {
            let e = F::dot4(*b, w, xq).map(|a| {
                if linear {
                    act::linear_i16(a, self.in_shift)
                } else {
                    act::tanh_q15(self.act_tables, a, self.in_shift)
                }
            });
            *zq_e = [dsp::pack(e[0], e[1]), dsp::pack(e[2], e[3])];
        }
        // LSTM gates: one 4-row block per cell (i, f, g, o), the whole layer in one
        // kernel call from the biases.
        F::matvec4(acc, self.gate_bias, self.gate_w, z);
        // Cell updates, two cells (one packed word of h) at a time.
        let cells = acc
            .chunks_exact(2)
            .zip(c.chunks_exact_mut(2))
            .zip(h_new.as_flattened_mut());
        for ((a2, c2), hw) in cells {
            let h0 = cell_update(self.act_tables, &a2[0], &self.gate_shift, &mut c2[0]);
            let h1 = cell_update(self.act_tables, &a2[1], &self.gate_shift, &mut c2[1]);
            *hw = dsp::pack(h0, h1);
        }
        if let Some(hz) = z.get_mut(d.embed_blocks..) {
            for (dst, src) in hz.iter_mut().zip(h_new.iter()) {
                *dst = *src;
            }
        }
        self.output(h_new, out);
    }
}

/// One LSTM cell from its four gate accumulators (i, f, g, o), their index shifts and
/// the activation tables: updates the int16 Q4.11 cell state `c` (rounded, saturating) and returns
/// the Q0.15 hidden value (the instruction sequence of `dsp::lstm_small_i16`'s cell,
/// see the module docs). No intermediate can overflow: `|c * f| <= 2^30`,
/// `|i * g| >> 4 <= 2^26`.
#[inline(always)]
pub fn cell_update(tables: &act::ActTables, acc: &[i32; 4], shift: &[u32; 4], c: &mut i16) -> i16 {
    let i = act::sigmoid_q15(tables, acc[0], shift[0]) as i32;
    let f = act::sigmoid_q15(tables, acc[1], shift[1]) as i32;
    let g = act::tanh_q15(tables, acc[2], shift[2]) as i32;
    let o = act::sigmoid_q15(tables, acc[3], shift[3]) as i32;
    // SMLABB (c * f + round), SMULBB (i * g), ADD with ASR, SSAT #16 with ASR #15.
    let sum = *c as i32 * f + CELL_ROUND + ((i * g) >> CELL_IG_SHIFT);
    let cn = (sum >> ACT_FRAC_BITS).clamp(i16::MIN as i32, i16::MAX as i32) as i16;
    *c = cn;
    let tc = act::tanh_q15(tables, cn as i32, CELL_TANH_SHIFT) as i32;
    ((o * tc) >> 15) as i16
}

/// An integer LSTM network of fixed sizes in format `F` ([`QuantFormat`]: weights and
/// index shifts): `I` inputs (padded to `4 * IQ` columns), input layer of `E = 4 * EB`
/// rows, `H = 4 * HQ` cells (gate matrix over `ZQ = EB + HQ` quads of `[e; h]`), `O`
/// outputs (padded to `4 * OB` rows).
#[derive(Clone, Copy, Debug)]
pub struct QuantLstm<
    F: QuantFormat,
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
    /// Input layer weights `[block][quad]`.
    pub in_w: [[<F::Weights as WeightFormat>::Quad; IQ]; EB],
    /// Input layer bias (accumulator scale).
    pub in_bias: [[i32; 4]; EB],
    /// Gate weights over `[e; h]`; block `j` = rows `i_j, f_j, g_j, o_j`.
    pub gate_w: [[<F::Weights as WeightFormat>::Quad; ZQ]; H],
    /// Gate bias (accumulator scale).
    pub gate_bias: [[i32; 4]; H],
    /// Output weights (rows beyond `O` zero).
    pub out_w: [[<F::Weights as WeightFormat>::Quad; HQ]; OB],
    /// f32 scale per output row (row scale x 2^-15 x output std).
    pub out_scale: [[f32; 4]; OB],
    /// f32 offset per output row (bias x output std + output mean).
    pub out_offset: [[f32; 4]; OB],
}

impl<
    F: QuantFormat,
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
        assert!(
            act::shift_fits(F::INPUT_SHIFT),
            "input index shift out of 1..=31"
        );
        let s = F::GATE_SHIFTS;
        assert!(
            act::shift_fits(s[0])
                && act::shift_fits(s[1])
                && act::shift_fits(s[2])
                && act::shift_fits(s[3]),
            "gate index shift out of 1..=31"
        );
    };
    /// Activation after the input layer (the format's).
    pub const INPUT_ACTIVATION: InputActivation = F::INPUT_ACTIVATION;
    /// Sizes.
    pub const DIMS: QuantDims = QuantDims {
        input: I,
        input_quads: IQ,
        embed_blocks: EB,
        hidden: H,
        output: O,
        output_blocks: OB,
    };
    /// Multiply-accumulates per step (without padding).
    pub const MACS: u32 = (4 * EB * I + 4 * H * (4 * EB + H) + O * H) as u32;
    /// Whether the step runs the fused kernel `dsp::lstm_small_i16`: on a target with the
    /// DSP extension, int16 weights, `[e; h]` in at most 8 quads, at most 2 input quads,
    /// at most 4 outputs.
    pub const FUSED: bool = dsp::ASM
        && <F::Weights as WeightFormat>::INT16_PAIRS
        && ZQ <= dsp::SMALL_MAX_Z_QUADS
        && IQ <= dsp::SMALL_MAX_INPUT_QUADS
        && OB == 1;

    /// The network as a shape-erased view of its own arrays (no copy).
    pub fn view(&self) -> QuantView<'_, F::Weights> {
        QuantView {
            dims: Self::DIMS,
            input_mean: &self.input_mean,
            input_scale: &self.input_scale,
            in_w: self.in_w.as_flattened(),
            in_bias: &self.in_bias,
            in_activation: F::INPUT_ACTIVATION,
            in_shift: F::INPUT_SHIFT,
            gate_w: self.gate_w.as_flattened(),
            gate_bias: &self.gate_bias,
            gate_shift: F::GATE_SHIFTS,
            act_tables: F::ACT_TABLES,
            out_w: self.out_w.as_flattened(),
            out_scale: &self.out_scale,
            out_offset: &self.out_offset,
        }
    }

    /// One control tick: advances `state` by the raw (unnormalised) `input` and
    /// returns the de-normalised outputs. On the target it runs from CCM SRAM
    /// (`.ccmram_text`, copied there at start-up).
    #[inline(never)]
    #[cfg_attr(target_os = "none", unsafe(link_section = ".ccmram_text"))]
    pub fn step(&self, state: &mut QuantState<ZQ, H>, input: &[f32; I]) -> [f32; O] {
        let () = Self::SHAPE;
        let mut xq = [[0u32; 2]; IQ];
        let mut out = [0.0f32; O];
        if Self::FUSED {
            let v = self.view();
            let pairs = <F::Weights as WeightFormat>::int16_pairs;
            if let (Some(in_w), Some(gate_w), Some(out_w)) =
                (pairs(v.in_w), pairs(v.gate_w), pairs(v.out_w))
            {
                v.quantise_input(&mut xq, input);
                let acc = dsp::lstm_small_i16::<F, IQ, EB, H, ZQ, O>(
                    &xq,
                    in_w,
                    &self.in_bias,
                    gate_w,
                    &self.gate_bias,
                    out_w,
                    state,
                );
                if let Some(a) = acc {
                    v.denormalise(0, a, &mut out);
                    return out;
                }
            }
        }
        let mut h_new = [[0u32; 2]; HQ];
        self.view().step(
            &mut state.z,
            &mut state.c,
            &mut xq,
            &mut h_new,
            &mut state.acc,
            input,
            &mut out,
        );
        out
    }
}

/// Sizes of an f32 network.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct F32Dims {
    /// Inputs `I`.
    pub input: usize,
    /// Input-layer blocks `EB` (`E = 4 * EB`).
    pub embed_blocks: usize,
    /// Cells `H`.
    pub hidden: usize,
    /// Outputs `O`.
    pub output: usize,
    /// Output blocks `OB = ceil(O / 4)`.
    pub output_blocks: usize,
}

/// An f32 network of run-time sizes borrowing flat arrays in the kernel layout.
#[derive(Clone, Copy, Debug)]
pub struct F32View<'a> {
    /// Sizes.
    pub dims: F32Dims,
    /// `[I]`
    pub input_mean: &'a [f32],
    /// `[I]`
    pub input_inv_std: &'a [f32],
    /// `[EB * I]` blocks of 4 rows, column-interleaved.
    pub w_in: &'a [[f32; 4]],
    /// `[EB]`
    pub b_in: &'a [[f32; 4]],
    /// Activation after the input layer.
    pub input_activation: InputActivation,
    /// The first blocks of the gate matrix (`[HS * Z]`, `Z = E + H`): with
    /// [`Self::w_gates_middle`] and [`Self::w_gates_tail`] the `[H * Z]` gate matrix
    /// ([`F32GateRows`]).
    pub w_gates: &'a [[f32; 4]],
    /// The next `HM` blocks of the gate matrix (`[HM * Z]`).
    pub w_gates_middle: &'a [[f32; 4]],
    /// The other `H - HS - HM` blocks of the gate matrix (`[(H - HS - HM) * Z]`).
    pub w_gates_tail: &'a [[f32; 4]],
    /// `[H]`
    pub b_gates: &'a [[f32; 4]],
    /// `[OB * H]`
    pub w_out: &'a [[f32; 4]],
    /// `[OB]`
    pub b_out: &'a [[f32; 4]],
    /// `[OB]`
    pub output_std: &'a [[f32; 4]],
    /// `[OB]`
    pub output_mean: &'a [[f32; 4]],
}

/// Four rows at once, each summed left to right (`dsp::dot4_f32`).
#[inline(always)]
fn dot4_f32(acc: [f32; 4], w: &[[f32; 4]], x: &[f32]) -> [f32; 4] {
    dsp::dot4_f32(acc, w, x)
}

impl F32View<'_> {
    /// Whether every array has the length `dims` asks for (`None`) or the first that
    /// does not.
    pub fn check(&self) -> Option<&'static str> {
        let d = self.dims;
        let z = 4 * d.embed_blocks + d.hidden;
        let lens: [(&'static str, usize, usize); 10] = [
            ("input_mean", d.input, self.input_mean.len()),
            ("input_inv_std", d.input, self.input_inv_std.len()),
            ("w_in", d.embed_blocks * d.input, self.w_in.len()),
            ("b_in", d.embed_blocks, self.b_in.len()),
            (
                "w_gates",
                d.hidden * z,
                self.w_gates.len() + self.w_gates_middle.len() + self.w_gates_tail.len(),
            ),
            ("b_gates", d.hidden, self.b_gates.len()),
            ("w_out", d.output_blocks * d.hidden, self.w_out.len()),
            ("b_out", d.output_blocks, self.b_out.len()),
            ("output_std", d.output_blocks, self.output_std.len()),
            ("output_mean", d.output_blocks, self.output_mean.len()),
        ];
        if d.output_blocks * 4 < d.output {
            return Some("dims");
        }
        lens.iter().find(|(_, e, a)| e != a).map(|(n, _, _)| *n)
    }

    /// The kernel: one step. `z` (`E + H`) and `c` (`H`) are the state, `xn` (`I`)
    /// and `acc` (`H` blocks) scratch. Lengths are trusted (never a panic).
    #[inline(always)]
    pub fn step(
        &self,
        z: &mut [f32],
        c: &mut [f32],
        xn: &mut [f32],
        acc: &mut [[f32; 4]],
        input: &[f32],
        out: &mut [f32],
    ) {
        let d = self.dims;
        let e_len = 4 * d.embed_blocks;
        for (((n, x), m), s) in xn
            .iter_mut()
            .zip(input)
            .zip(self.input_mean)
            .zip(self.input_inv_std)
        {
            *n = (x - m) * s;
        }
        let xn: &[f32] = xn;
        // Input layer: one kernel call into the e part of z, then the bias and tanh
        // (or nothing more: a linear input layer) in place.
        let (z4, _) = z.as_chunks_mut::<4>();
        let e4 = z4.get_mut(..d.embed_blocks).unwrap_or_default();
        dsp::matvec4_f32(e4, self.w_in, xn);
        if self.input_activation.is_linear() {
            for (e, b) in e4.iter_mut().zip(self.b_in) {
                *e = [e[0] + b[0], e[1] + b[1], e[2] + b[2], e[3] + b[3]];
            }
        } else {
            dsp::tanh4_bias_f32(e4, self.b_in);
        }
        // LSTM gates: the whole layer in one kernel call per part of the gate matrix
        // (each block only reads its own rows), then the cells.
        let z_in: &[f32] = z;
        dsp::matvec4_f32_parts(
            acc,
            [self.w_gates, self.w_gates_middle, self.w_gates_tail],
            z_in.get(..e_len + d.hidden).unwrap_or(z_in),
        );
        let acc: &[[f32; 4]] = acc;
        // The gate layer has read h: the cells write the new h in its place in z. First
        // each cell's gates and new c (h holds o for now), then h = o tanh(c) four
        // cells at a time (the same bits as one at a time).
        let h_new = z.get_mut(e_len..).unwrap_or_default();
        dsp::lstm_cells_f32(acc, self.b_gates, c, h_new);
        let (c4, c_rest) = c.as_chunks::<4>();
        let (h4, h_rest) = h_new.as_chunks_mut::<4>();
        dsp::mul_tanh4_f32(h4, c4);
        for (cj, hn) in c_rest.iter().zip(h_rest.iter_mut()) {
            *hn *= math::tanh_fast(*cj);
        }
        let h_new: &[f32] = h_new;
        let mut ys = out.iter_mut();
        let outs = self
            .w_out
            .chunks_exact(d.hidden.max(1))
            .zip(self.b_out)
            .zip(self.output_std)
            .zip(self.output_mean);
        for (((w, b), s), m) in outs {
            let acc = dot4_f32([0.0; 4], w, h_new);
            for r in 0..4 {
                if let Some(y) = ys.next() {
                    *y = (acc[r] + b[r]) * s[r] + m[r];
                }
            }
        }
    }
}

/// The input layer's activation as a type, so that a compiled-in f32 network carries
/// it in its type ([`TanhInput`], [`LinearInput`]).
pub trait InputLayer: Copy + core::fmt::Debug {
    /// The activation.
    const ACTIVATION: InputActivation;
}

/// A `tanh` input layer ([`InputActivation::Tanh`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TanhInput;

impl InputLayer for TanhInput {
    const ACTIVATION: InputActivation = InputActivation::Tanh;
}

/// A linear input layer ([`InputActivation::Linear`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LinearInput;

impl InputLayer for LinearInput {
    const ACTIVATION: InputActivation = InputActivation::Linear;
}

/// The gate matrix of a compiled-in f32 network, `H` blocks over `Z` columns (block
/// `j` = rows `i_j, f_j, g_j, o_j`, column-interleaved), as three statics so that the
/// exporter can place them apart: when the whole matrix does not fit the board's SRAM
/// budget, the first blocks (`head`) in SRAM, the next (`middle`) in CCM SRAM and the
/// rest (`tail`) in flash (unused parts are empty). The generated file asserts at
/// compile time that together they hold `H` blocks.
#[derive(Clone, Copy, Debug)]
pub struct F32GateRows<const Z: usize> {
    /// Blocks `0..HS`.
    pub head: &'static [[[f32; 4]; Z]],
    /// Blocks `HS..HS + HM`.
    pub middle: &'static [[[f32; 4]; Z]],
    /// Blocks `HS + HM..H`.
    pub tail: &'static [[[f32; 4]; Z]],
}

/// The f32 network of fixed sizes in the exporter's layout: `I` inputs, input layer
/// of `E = 4 * EB` rows with the activation `A` ([`InputLayer`]), `H` cells over
/// `Z = E + H` columns (`[e; h]`), `O` outputs in `OB` blocks. Each block stores its 4 rows column-interleaved (`[k][row]`);
/// every row sums left to right in f32 as in `crate::nn::reference`; sigmoid and tanh are
/// the f32-only `math::sigmoid_fast` / `math::tanh_fast` (within 2e-7 of libm's, so
/// the step tracks `crate::nn::reference` to about 1e-7, not bit for bit).
#[derive(Clone, Copy, Debug)]
pub struct F32Lstm<
    const I: usize,
    const E: usize,
    const EB: usize,
    const H: usize,
    const Z: usize,
    const O: usize,
    const OB: usize,
    A: InputLayer,
> {
    /// Input normalisation: per-feature mean.
    pub input_mean: [f32; I],
    /// Input normalisation: `1 / std` per feature.
    pub input_inv_std: [f32; I],
    /// Input layer weights, 4-row blocks `[block][k][row]`.
    pub w_in: [[[f32; 4]; I]; EB],
    /// Input layer bias.
    pub b_in: [[f32; 4]; EB],
    /// Activation after the input layer.
    pub input_layer: A,
    /// Gate weights over `[e; h]`, block `j` = rows `i_j, f_j, g_j, o_j`, in two
    /// statics ([`F32GateRows`]).
    pub w_gates: F32GateRows<Z>,
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

/// The recurrent state of the f32 network: `[e; h]` (the `h` part is the state),
/// `c`, and the gate sums as scratch (kept here so that a step need not clear
/// `16 * H` bytes of stack; every step overwrites them before reading).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct F32State<const Z: usize, const H: usize> {
    /// `[e; h]`.
    pub z: [f32; Z],
    /// Cell state.
    pub c: [f32; H],
    /// Scratch: the last step's gate sums (no meaning between steps).
    pub acc: [[f32; 4]; H],
}

impl<const Z: usize, const H: usize> F32State<Z, H> {
    /// The zero state.
    pub const fn new() -> Self {
        F32State {
            z: [0.0; Z],
            c: [0.0; H],
            acc: [[0.0; 4]; H],
        }
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

impl<
    const I: usize,
    const E: usize,
    const EB: usize,
    const H: usize,
    const Z: usize,
    const O: usize,
    const OB: usize,
    A: InputLayer,
> F32Lstm<I, E, EB, H, Z, O, OB, A>
{
    /// Activation after the input layer.
    pub const INPUT_ACTIVATION: InputActivation = A::ACTIVATION;
    /// Compile-time shape check, evaluated by every [`Self::step`] instantiation.
    pub const SHAPE: () = {
        assert!(I > 0 && O > 0 && E > 0 && H > 0, "empty network");
        assert!(E == 4 * EB, "E must be 4 * EB");
        assert!(Z == E + H, "Z must be E + H");
        assert!(4 * OB >= O && 4 * OB < O + 4, "OB must be ceil(O / 4)");
    };
    /// Sizes.
    pub const DIMS: F32Dims = F32Dims {
        input: I,
        embed_blocks: EB,
        hidden: H,
        output: O,
        output_blocks: OB,
    };
    /// Multiply-accumulates per step.
    pub const MACS: u32 = (E * I + 4 * H * Z + O * H) as u32;

    /// The network as a shape-erased view of its own arrays (no copy).
    pub fn view(&self) -> F32View<'_> {
        F32View {
            dims: Self::DIMS,
            input_mean: &self.input_mean,
            input_inv_std: &self.input_inv_std,
            w_in: self.w_in.as_flattened(),
            b_in: &self.b_in,
            input_activation: A::ACTIVATION,
            w_gates: self.w_gates.head.as_flattened(),
            w_gates_middle: self.w_gates.middle.as_flattened(),
            w_gates_tail: self.w_gates.tail.as_flattened(),
            b_gates: &self.b_gates,
            w_out: self.w_out.as_flattened(),
            b_out: &self.b_out,
            output_std: &self.output_std,
            output_mean: &self.output_mean,
        }
    }

    /// One control tick: advances `state` by the raw `input`, returns the outputs.
    /// On the target it runs from CCM SRAM (`.ccmram_text`).
    #[inline(never)]
    #[cfg_attr(target_os = "none", unsafe(link_section = ".ccmram_text"))]
    pub fn step(&self, state: &mut F32State<Z, H>, input: &[f32; I]) -> [f32; O] {
        let () = Self::SHAPE;
        let mut xn = [0.0f32; I];
        let mut out = [0.0f32; O];
        self.view().step(
            &mut state.z,
            &mut state.c,
            &mut xn,
            &mut state.acc,
            input,
            &mut out,
        );
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Gate accumulators with index shift 1: value `acc / 1024`.
    const SHIFTS: [u32; 4] = [1; 4];
    /// The tables (either placement holds the same values).
    const T: &act::ActTables = &act::ACT_TABLES_FLASH;

    #[test]
    fn cell_update_rounds_to_nearest_q4_11() {
        let accs = [-9000, -2048, -300, 0, 77, 1500, 4096, 9000];
        let cells = [i16::MIN, -20000, -2048, -1, 0, 1, 777, 16384, i16::MAX];
        for &a in &accs {
            for &b in &accs {
                for &c0 in &cells {
                    let acc = [a, b, -a / 2, b / 3];
                    let i = act::sigmoid_q15(T, acc[0], 1) as f64;
                    let f = act::sigmoid_q15(T, acc[1], 1) as f64;
                    let g = act::tanh_q15(T, acc[2], 1) as f64;
                    // c' in Q4.11 units, exact: c f / 2^15 + i g / 2^19.
                    let exact = c0 as f64 * f / 32768.0 + i * g / 524288.0;
                    let mut c = c0;
                    cell_update(T, &acc, &SHIFTS, &mut c);
                    let want = exact.clamp(i16::MIN as f64, i16::MAX as f64);
                    assert!(
                        (c as f64 - want).abs() <= 0.5 + 1.0 / 32768.0,
                        "c {c0}, acc {acc:?}: {c} vs {exact}"
                    );
                }
            }
        }
    }

    #[test]
    fn cell_state_saturates_at_the_q4_11_range() {
        // i, f, o ~ 1 and g ~ +-1 push c past +-16.
        for (g_acc, end) in [(9000, i16::MAX), (-9000, i16::MIN)] {
            let mut c = end;
            let h = cell_update(T, &[9000, 9000, g_acc, 9000], &SHIFTS, &mut c);
            assert_eq!(c, end);
            let o_tanh = act::sigmoid_q15(T, 9000, 1) as i32
                * act::tanh_q15(T, end as i32, CELL_TANH_SHIFT) as i32;
            assert_eq!(h as i32, o_tanh >> 15);
        }
    }
}
