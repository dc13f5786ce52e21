//! Quantise a compensation network into the firmware's kernel layout
//! (`firmware::nn::kernels`, Q formats documented there) and write it, with the
//! normalisation, feature preset, joints, control rate and optionally the dynamics
//! model, as ONE Rust source file of fixed-size `static`/`const` arrays that the
//! firmware compiles in (`model-export export`).
//!
//! The host evaluation of an exported network runs the firmware's own shape-erased
//! kernels (`QuantView::step`, `F32View::step`) on the exporter's vectors, so the
//! predictions written into the file (`SELF_CHECK_*`) are what the target computes.
#![deny(unsafe_code)]
#![warn(missing_docs)]
pub mod envelope;

use anyhow::{Context, Result, bail};
use compnet::model::LstmModel;
use firmware::dynamics::RigidBodyModel;
use firmware::model::self_check;
use firmware::nn::act;
use firmware::nn::format::{
    ACT_FRAC_BITS, FeaturePreset, I8Weights, I16Weights, INPUT_FRAC_BITS, InputActivation,
    WeightFormat,
};
use firmware::nn::kernels::{F32Dims, F32View, QuantDims, QuantView};
use robot::dynamics::firmware_model::FirmwareModel;
use sha2::{Digest, Sha256};
use std::fmt::Write as _;

/// Version of the generated file's layout and numerics: the firmware's.
pub const SCHEMA_VERSION: u32 = firmware::model::SCHEMA_VERSION;

/// Numeric precision of an exported network.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Precision {
    /// f32 weights and activations.
    F32,
    /// int16 weights, int16 activations.
    Int16,
    /// int8 weights, int16 activations.
    Int8,
}

impl Precision {
    /// All precisions, in report order.
    pub const ALL: [Precision; 3] = [Precision::F32, Precision::Int16, Precision::Int8];
    /// Name in reports and generated files.
    pub fn name(self) -> &'static str {
        match self {
            Precision::F32 => "f32",
            Precision::Int16 => "int16",
            Precision::Int8 => "int8",
        }
    }
}

/// Why a network cannot be exported.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// A weight or normalisation value is NaN or infinite.
    #[error("tensor `{tensor}` element {index} is {value}: weights must be finite")]
    NotFinite {
        /// Tensor name (interchange name).
        tensor: &'static str,
        /// Flat index.
        index: usize,
        /// The value.
        value: f32,
    },
    /// No power-of-two weight scale fits a layer (or gate) into the Q format.
    #[error(
        "layer `{layer}`: weights up to {max_abs:e} (bias up to {max_bias:e}) overflow the Q \
         format: no power-of-two scale 2^-P with P >= {p_min} keeps every weight within the \
         format and every accumulator below 2^31 (a smaller P would put the activation \
         index shift outside 1..=31); the weights are too large"
    )]
    ScaleOverflow {
        /// Layer name (`input`, `lstm gate i`, ...).
        layer: &'static str,
        /// Largest weight magnitude.
        max_abs: f64,
        /// Largest bias magnitude.
        max_bias: f64,
        /// Smallest exponent the index shift allows.
        p_min: i32,
    },
    /// A linear input layer's outputs have no int16 format the kernel can shift to.
    #[error(
        "layer `input` (linear): its outputs reach {bound:e} for inputs within the Q3.12 \
         range (+-8 after normalisation), and no int16 format of them has a requantisation \
         shift in 1..=31 that keeps the accumulator below 2^31; the weights are too large"
    )]
    LinearInputRange {
        /// Largest `|e|` the layer can give.
        bound: f64,
    },
    /// A standard deviation is not positive.
    #[error("tensor `{tensor}` element {index} is {value}: standard deviations must be > 0")]
    BadStd {
        /// Tensor name.
        tensor: &'static str,
        /// Index.
        index: usize,
        /// Value.
        value: f32,
    },
    /// The model does not fit the flash budget.
    #[error(
        "the exported network needs {bytes} bytes of flash, over the budget of {budget} bytes \
         ({source_file})"
    )]
    TooLarge {
        /// Bytes of weights.
        bytes: usize,
        /// Budget.
        budget: u64,
        /// Where the budget comes from.
        source_file: String,
    },
}

fn check_finite(m: &LstmModel) -> Result<(), ExportError> {
    for (tensor, v) in m.tensors() {
        if let Some(index) = v.iter().position(|x| !x.is_finite()) {
            return Err(ExportError::NotFinite {
                tensor,
                index,
                value: v[index],
            });
        }
    }
    for (tensor, v) in [
        ("norm.input_std", &m.input_std),
        ("norm.output_std", &m.output_std),
    ] {
        if let Some(index) = v.iter().position(|&x| x <= 0.0) {
            return Err(ExportError::BadStd {
                tensor,
                index,
                value: v[index],
            });
        }
    }
    Ok(())
}

fn pad4(n: usize) -> usize {
    n.div_ceil(4) * 4
}

/// The network's rows in kernel order with padding: returns `(rows, bias)` for each
/// layer, as f64. Gate block `j` = rows `i_j, f_j, g_j, o_j`, columns `[e (Ep); h (Hp)]`.
struct Layers {
    e_pad: usize,
    h_pad: usize,
    input: (Vec<Vec<f64>>, Vec<f64>),
    gates: (Vec<Vec<f64>>, Vec<f64>),
    output: (Vec<Vec<f64>>, Vec<f64>),
}

fn layers(m: &LstmModel, in_cols: usize) -> Layers {
    let d = m.dims;
    let (i, e, h, o) = (d.input, d.embed, d.hidden, d.output);
    let (ep, hp) = (pad4(e), pad4(h));
    let mut input = (vec![vec![0.0; in_cols]; ep], vec![0.0; ep]);
    for r in 0..e {
        for k in 0..i {
            input.0[r][k] = m.w_in[r * i + k] as f64;
        }
        input.1[r] = m.b_in[r] as f64;
    }
    let mut gates = (vec![vec![0.0; ep + hp]; 4 * hp], vec![0.0; 4 * hp]);
    for j in 0..h {
        for g in 0..4 {
            let src = g * h + j;
            let row = &mut gates.0[4 * j + g];
            for (dst, w) in row.iter_mut().zip(&m.w_ih[src * e..(src + 1) * e]) {
                *dst = *w as f64;
            }
            for (dst, w) in row[ep..].iter_mut().zip(&m.w_hh[src * h..(src + 1) * h]) {
                *dst = *w as f64;
            }
            // The LSTM's two biases summed in f32, as the f32 firmware step does.
            gates.1[4 * j + g] = (m.b_ih[src] + m.b_hh[src]) as f64;
        }
    }
    let mut output = (vec![vec![0.0; hp]; pad4(o)], vec![0.0; pad4(o)]);
    for r in 0..o {
        for k in 0..h {
            output.0[r][k] = m.w_out[r * h + k] as f64;
        }
        output.1[r] = m.b_out[r] as f64;
    }
    Layers {
        e_pad: ep,
        h_pad: hp,
        input,
        gates,
        output,
    }
}

/// An integer network in the kernel layout, with run-time sizes.
#[derive(Clone, Debug)]
pub struct QuantNet<F: WeightFormat> {
    /// Sizes.
    pub dims: QuantDims,
    /// `[I]`
    pub input_mean: Vec<f32>,
    /// `[I]`
    pub input_scale: Vec<f32>,
    /// Input layer.
    pub in_w: Vec<F::Quad>,
    /// Input bias.
    pub in_bias: Vec<[i32; 4]>,
    /// Activation after the input layer.
    pub in_activation: InputActivation,
    /// Shift of the input layer's accumulators (tanh index or linear requantisation).
    pub in_shift: u32,
    /// Gates.
    pub gate_w: Vec<F::Quad>,
    /// Gate bias.
    pub gate_bias: Vec<[i32; 4]>,
    /// Activation-index shifts of the gates `i, f, g, o`.
    pub gate_shift: [u32; 4],
    /// Output layer.
    pub out_w: Vec<F::Quad>,
    /// Output scale.
    pub out_scale: Vec<[f32; 4]>,
    /// Output offset.
    pub out_offset: Vec<[f32; 4]>,
}

const ACC_LIMIT: f64 = 2_147_483_647.0;

/// Largest `sum_k |w_q[k]| * 32768 + |b_q|` of `rows` at exponent `p` (weights
/// `round(w 2^p)`, bias `round(b 2^(p + x_frac))`), or `None` when a weight leaves
/// `+-max_w`.
fn worst_accumulator(rows: &[(&[f64], f64)], p: i32, x_frac: u32, max_w: i32) -> Option<f64> {
    let mut worst = 0.0f64;
    for (w, b) in rows {
        let mut sum = (b * 2f64.powi(p + x_frac as i32)).round().abs();
        for x in w.iter() {
            let q = (x * 2f64.powi(p)).round();
            if q.abs() > max_w as f64 {
                return None;
            }
            sum += q.abs() * 32768.0;
        }
        worst = worst.max(sum);
    }
    Some(worst)
}

/// The power-of-two exponent `P` of a group of rows sharing one scale (`w ~ w_q 2^-P`):
/// the largest for which every weight fits `+-max_w` and no accumulator can reach 2^31
/// for any input, with the activation-index shift `P + x_frac - 9` in `1..=31`.
fn group_exponent(
    layer: &'static str,
    rows: &[(&[f64], f64)],
    x_frac: u32,
    max_w: i32,
) -> Result<i32, ExportError> {
    let grid = act::GRID_FRAC_BITS as i32;
    let (p_min, p_max) = (1 + grid - x_frac as i32, 31 + grid - x_frac as i32);
    (p_min..=p_max)
        .rev()
        .find(|&p| worst_accumulator(rows, p, x_frac, max_w).is_some_and(|a| a < ACC_LIMIT))
        .ok_or_else(|| {
            let fold = |f: fn(&(&[f64], f64)) -> f64| rows.iter().map(f).fold(0.0, f64::max);
            ExportError::ScaleOverflow {
                layer,
                max_abs: fold(|(w, _)| w.iter().fold(0.0f64, |a, x| a.max(x.abs()))),
                max_bias: fold(|(_, b)| b.abs()),
                p_min,
            }
        })
}

/// Quantises a dense layer (blocks of 4 rows, quads of 4 columns) with exponent
/// `exp[r % 4]` for row `r`: the quads and the biases in accumulator scale.
fn quant_layer<F: WeightFormat>(
    rows: &[Vec<f64>],
    bias: &[f64],
    x_frac: u32,
    exp: [i32; 4],
) -> (Vec<F::Quad>, Vec<[i32; 4]>) {
    let cols = pad4(rows.first().map_or(0, Vec::len));
    let q = |r: usize, k: usize| {
        let x = rows[r].get(k).copied().unwrap_or(0.0);
        (x * 2f64.powi(exp[r % 4])).round() as i32
    };
    let mut w = Vec::new();
    let mut bias4 = Vec::new();
    for blk in 0..rows.len() / 4 {
        for c in 0..cols / 4 {
            w.push(F::pack(std::array::from_fn(|r| {
                std::array::from_fn(|k| q(4 * blk + r, 4 * c + k))
            })));
        }
        bias4.push(std::array::from_fn(|r| {
            let row = 4 * blk + r;
            (bias[row] * 2f64.powi(exp[r] + x_frac as i32)).round() as i32
        }));
    }
    (w, bias4)
}

/// Largest `|e|` a linear input layer can give for any Q3.12 input (`|x_n| <= 8`):
/// `max_r sum_k |w_rk| * 8 + |b_r|`.
fn linear_embed_bound(rows: &[(&[f64], f64)]) -> f64 {
    let x_max = 32768.0 / f64::from(1u32 << INPUT_FRAC_BITS);
    rows.iter()
        .map(|(w, b)| w.iter().map(|x| x.abs()).sum::<f64>() * x_max + b.abs())
        .fold(0.0, f64::max)
}

/// Fraction bits `F` of a linear input layer's `e` (int16, `Q(15-F).F`): the most for
/// which [`linear_embed_bound`] fits, at most 15.
fn linear_embed_frac_bits(rows: &[(&[f64], f64)]) -> i32 {
    let bound = linear_embed_bound(rows);
    let mut f = ACT_FRAC_BITS as i32;
    while f > -16 && bound * 2f64.powi(f) >= 32767.0 {
        f -= 1;
    }
    f
}

/// Index shift of an accumulator with `p + x_frac` fraction bits.
fn index_shift(p: i32, x_frac: u32) -> u32 {
    (p + x_frac as i32 - act::GRID_FRAC_BITS as i32) as u32
}

/// Quantises one output row with its own scale (f32 multiplier at the output):
/// returns the integer weights and the scale `s` (`w ~ s * w_q`), enlarged where needed
/// so that `sum |w_q| * 32768 < 2^31`.
fn quantise_output_row(w: &[f64], max_w: i32) -> (Vec<i32>, f64) {
    let maxabs = w.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    if maxabs == 0.0 {
        return (vec![0; w.len()], 0.0);
    }
    let mut s = maxabs / max_w as f64;
    loop {
        let wq: Vec<i32> = w
            .iter()
            .map(|x| ((x / s).round() as i32).clamp(-max_w, max_w))
            .collect();
        let bound = wq.iter().map(|q| q.unsigned_abs() as f64).sum::<f64>() * 32768.0;
        if bound < ACC_LIMIT {
            return (wq, s);
        }
        s *= bound / (ACC_LIMIT - 65536.0) * 1.0001;
    }
}

/// Gate names in block order, for errors.
const GATE_LAYERS: [&str; 4] = ["lstm gate i", "lstm gate f", "lstm gate g", "lstm gate o"];

impl<F: WeightFormat> QuantNet<F> {
    /// Quantises `m` (see `firmware::nn::kernels` for the scheme).
    pub fn quantise(m: &LstmModel) -> Result<Self, ExportError> {
        check_finite(m)?;
        let d = m.dims;
        let ip = pad4(d.input);
        let mut l = layers(m, ip);
        let (x_in, x_z) = (INPUT_FRAC_BITS, ACT_FRAC_BITS);
        let in_rows: Vec<(&[f64], f64)> = l
            .input
            .0
            .iter()
            .zip(&l.input.1)
            .map(|(w, b)| (w.as_slice(), *b))
            .collect();
        let p_in = group_exponent("input", &in_rows, x_in, F::MAX_WEIGHT)?;
        // A linear input layer: e in F fraction bits, the shift to it, and the factor
        // 2^(15 - F) on the gate weights of the e columns (module docs of firmware::nn::kernels).
        let (in_shift, e_frac) = match m.input_activation {
            InputActivation::Tanh => (index_shift(p_in, x_in), ACT_FRAC_BITS as i32),
            InputActivation::Linear => {
                let e_frac = linear_embed_frac_bits(&in_rows);
                let shift = p_in + x_in as i32 - e_frac;
                if !(1..=31).contains(&shift) {
                    return Err(ExportError::LinearInputRange {
                        bound: linear_embed_bound(&in_rows),
                    });
                }
                (shift as u32, e_frac)
            }
        };
        let e_gain = 2f64.powi(ACT_FRAC_BITS as i32 - e_frac);
        if e_gain != 1.0 {
            for row in l.gates.0.iter_mut() {
                for w in row[..l.e_pad].iter_mut() {
                    *w *= e_gain;
                }
            }
        }
        let mut p_gate = [0i32; 4];
        for (g, p) in p_gate.iter_mut().enumerate() {
            let rows: Vec<(&[f64], f64)> = (g..l.gates.0.len())
                .step_by(4)
                .map(|r| (l.gates.0[r].as_slice(), l.gates.1[r]))
                .collect();
            *p = group_exponent(GATE_LAYERS[g], &rows, x_z, F::MAX_WEIGHT)?;
        }
        let (in_w, mut in_bias) = quant_layer::<F>(&l.input.0, &l.input.1, x_in, [p_in; 4]);
        if m.input_activation == InputActivation::Linear {
            // Round to nearest: the half step of the shift in the bias (the kernel's
            // arithmetic shift floors).
            let half = 1i64 << (in_shift - 1);
            let worst = worst_accumulator(&in_rows, p_in, x_in, F::MAX_WEIGHT).unwrap_or(ACC_LIMIT);
            if worst + half as f64 >= ACC_LIMIT {
                return Err(ExportError::LinearInputRange {
                    bound: linear_embed_bound(&in_rows),
                });
            }
            for b in in_bias.iter_mut().flatten() {
                *b = (*b as i64 + half) as i32;
            }
        }
        let (gate_w, gate_bias) = quant_layer::<F>(&l.gates.0, &l.gates.1, x_z, p_gate);
        // Output layer: no integer bias; y = acc * s * 2^-15 * std + (b * std + mean).
        let mut out_w = Vec::new();
        let mut out_scale = Vec::new();
        let mut out_offset = Vec::new();
        let hp = l.h_pad;
        let ob = pad4(d.output) / 4;
        let mut rows_q = Vec::new();
        let mut sc = Vec::new();
        let mut off = Vec::new();
        for (r, row) in l.output.0.iter().enumerate() {
            let (mut q, s) = quantise_output_row(row, F::MAX_WEIGHT);
            q.resize(hp, 0);
            rows_q.push(q);
            if r < d.output {
                let std = m.output_std[r];
                sc.push((s * 2f64.powi(-15)) as f32 * std);
                off.push(m.b_out[r] * std + m.output_mean[r]);
            } else {
                sc.push(0.0);
                off.push(0.0);
            }
        }
        for blk in 0..ob {
            for q in 0..hp / 4 {
                let mm: [[i32; 4]; 4] = std::array::from_fn(|r| {
                    std::array::from_fn(|k| rows_q[4 * blk + r][4 * q + k])
                });
                out_w.push(F::pack(mm));
            }
            out_scale.push(std::array::from_fn(|r| sc[4 * blk + r]));
            out_offset.push(std::array::from_fn(|r| off[4 * blk + r]));
        }
        let net = QuantNet {
            dims: QuantDims {
                input: d.input,
                input_quads: ip / 4,
                embed_blocks: l.e_pad / 4,
                hidden: hp,
                output: d.output,
                output_blocks: ob,
            },
            input_mean: m.input_mean.clone(),
            input_scale: m.input_std.iter().map(|s| 4096.0 / s).collect(),
            in_w,
            in_bias,
            in_activation: m.input_activation,
            in_shift,
            gate_w,
            gate_bias,
            gate_shift: p_gate.map(|p| index_shift(p, x_z)),
            out_w,
            out_scale,
            out_offset,
        };
        debug_assert_eq!(net.view().check(), None);
        Ok(net)
    }

    /// The firmware view of this network.
    pub fn view(&self) -> QuantView<'_, F> {
        QuantView {
            dims: self.dims,
            input_mean: &self.input_mean,
            input_scale: &self.input_scale,
            in_w: &self.in_w,
            in_bias: &self.in_bias,
            in_activation: self.in_activation,
            in_shift: self.in_shift,
            gate_w: &self.gate_w,
            gate_bias: &self.gate_bias,
            gate_shift: self.gate_shift,
            // The host has one memory: either static holds the same values.
            act_tables: &act::ACT_TABLES_FLASH,
            out_w: &self.out_w,
            out_scale: &self.out_scale,
            out_offset: &self.out_offset,
        }
    }

    /// Streams the firmware kernel from the zero state over `inputs`.
    pub fn stream(&self, inputs: &[Vec<f32>]) -> Vec<Vec<f32>> {
        let d = self.dims;
        let v = self.view();
        let mut z = vec![[0u32; 2]; d.z_quads()];
        let mut c = vec![0i16; d.hidden];
        let mut xq = vec![[0u32; 2]; d.input_quads];
        let mut hn = vec![[0u32; 2]; d.hidden / 4];
        let mut acc = vec![[0i32; 4]; d.hidden];
        inputs
            .iter()
            .map(|x| {
                let mut y = vec![0.0f32; d.output];
                v.step(&mut z, &mut c, &mut xq, &mut hn, &mut acc, x, &mut y);
                y
            })
            .collect()
    }

    /// Bytes of flash the arrays take.
    pub fn flash_bytes(&self) -> usize {
        let q = std::mem::size_of::<F::Quad>();
        (self.in_w.len() + self.gate_w.len() + self.out_w.len()) * q
            + (self.in_bias.len() + self.gate_bias.len()) * 16
            + (self.out_scale.len() + self.out_offset.len()) * 16
            + self.input_mean.len() * 8
    }
}

/// The f32 network in the kernel layout, with run-time sizes.
#[derive(Clone, Debug)]
pub struct F32Net {
    /// Sizes.
    pub dims: F32Dims,
    /// `[I]`
    pub input_mean: Vec<f32>,
    /// `[I]`
    pub input_inv_std: Vec<f32>,
    /// Input layer.
    pub w_in: Vec<[f32; 4]>,
    /// Input bias.
    pub b_in: Vec<[f32; 4]>,
    /// Activation after the input layer.
    pub input_activation: InputActivation,
    /// Gates.
    pub w_gates: Vec<[f32; 4]>,
    /// Gate bias.
    pub b_gates: Vec<[f32; 4]>,
    /// Output layer.
    pub w_out: Vec<[f32; 4]>,
    /// Output bias.
    pub b_out: Vec<[f32; 4]>,
    /// Output std.
    pub output_std: Vec<[f32; 4]>,
    /// Output mean.
    pub output_mean: Vec<[f32; 4]>,
}

#[allow(clippy::needless_range_loop)] // k indexes the columns of 4 rows at once
fn interleave(rows: &[Vec<f64>]) -> Vec<[f32; 4]> {
    let cols = rows.first().map_or(0, Vec::len);
    let mut out = Vec::new();
    for blk in rows.chunks_exact(4) {
        for k in 0..cols {
            out.push(std::array::from_fn(|r| blk[r][k] as f32));
        }
    }
    out
}

fn blocks4(v: &[f64]) -> Vec<[f32; 4]> {
    v.chunks_exact(4)
        .map(|c| std::array::from_fn(|r| c[r] as f32))
        .collect()
}

impl F32Net {
    /// Rearranges `m` into the kernel layout (no rounding: every value is the f32 of
    /// the model; the gate bias is `bias_ih + bias_hh` in f32).
    pub fn arrange(m: &LstmModel) -> Result<Self, ExportError> {
        check_finite(m)?;
        let d = m.dims;
        let l = layers(m, d.input);
        let o = pad4(d.output);
        let mut std = vec![0.0f64; o];
        let mut mean = vec![0.0f64; o];
        for r in 0..d.output {
            std[r] = m.output_std[r] as f64;
            mean[r] = m.output_mean[r] as f64;
        }
        let net = F32Net {
            dims: F32Dims {
                input: d.input,
                embed_blocks: l.e_pad / 4,
                hidden: l.h_pad,
                output: d.output,
                output_blocks: o / 4,
            },
            input_mean: m.input_mean.clone(),
            input_inv_std: m.input_std.iter().map(|s| 1.0 / s).collect(),
            w_in: interleave(&l.input.0),
            b_in: blocks4(&l.input.1),
            input_activation: m.input_activation,
            w_gates: interleave(&l.gates.0),
            b_gates: blocks4(&l.gates.1),
            w_out: interleave(&l.output.0),
            b_out: blocks4(&l.output.1),
            output_std: blocks4(&std),
            output_mean: blocks4(&mean),
        };
        debug_assert_eq!(net.view().check(), None);
        Ok(net)
    }

    /// The firmware view.
    pub fn view(&self) -> F32View<'_> {
        F32View {
            dims: self.dims,
            input_mean: &self.input_mean,
            input_inv_std: &self.input_inv_std,
            w_in: &self.w_in,
            b_in: &self.b_in,
            input_activation: self.input_activation,
            w_gates: &self.w_gates,
            w_gates_middle: &[],
            w_gates_tail: &[],
            b_gates: &self.b_gates,
            w_out: &self.w_out,
            b_out: &self.b_out,
            output_std: &self.output_std,
            output_mean: &self.output_mean,
        }
    }

    /// Streams the firmware kernel from the zero state over `inputs`.
    pub fn stream(&self, inputs: &[Vec<f32>]) -> Vec<Vec<f32>> {
        let d = self.dims;
        let v = self.view();
        let e = 4 * d.embed_blocks;
        let mut z = vec![0.0f32; e + d.hidden];
        let mut c = vec![0.0f32; d.hidden];
        let mut xn = vec![0.0f32; d.input];
        let mut acc = vec![[0.0f32; 4]; d.hidden];
        inputs
            .iter()
            .map(|x| {
                let mut y = vec![0.0f32; d.output];
                v.step(&mut z, &mut c, &mut xn, &mut acc, x, &mut y);
                y
            })
            .collect()
    }

    /// Bytes of flash the arrays take.
    pub fn flash_bytes(&self) -> usize {
        (self.w_in.len()
            + self.b_in.len()
            + self.w_gates.len()
            + self.b_gates.len()
            + self.w_out.len()
            + 3 * self.b_out.len())
            * 16
            + self.input_mean.len() * 8
    }
}

/// An exported network in one of the precisions.
#[derive(Clone, Debug)]
pub enum Exported {
    /// f32.
    F32(F32Net),
    /// int16 weights.
    Int16(QuantNet<I16Weights>),
    /// int8 weights.
    Int8(QuantNet<I8Weights>),
}

impl Exported {
    /// Quantises / arranges `m` for `p`.
    pub fn new(m: &LstmModel, p: Precision) -> Result<Self, ExportError> {
        Ok(match p {
            Precision::F32 => Exported::F32(F32Net::arrange(m)?),
            Precision::Int16 => Exported::Int16(QuantNet::quantise(m)?),
            Precision::Int8 => Exported::Int8(QuantNet::quantise(m)?),
        })
    }

    /// Streams the firmware kernel from the zero state.
    pub fn stream(&self, inputs: &[Vec<f32>]) -> Vec<Vec<f32>> {
        match self {
            Exported::F32(n) => n.stream(inputs),
            Exported::Int16(n) => n.stream(inputs),
            Exported::Int8(n) => n.stream(inputs),
        }
    }

    /// Activation after the network's input layer.
    pub fn input_activation(&self) -> InputActivation {
        match self {
            Exported::F32(n) => n.input_activation,
            Exported::Int16(n) => n.in_activation,
            Exported::Int8(n) => n.in_activation,
        }
    }

    /// Bytes of one block of the gate matrix and the number of blocks, when the network
    /// can place the first blocks apart from the rest (f32: `F32GateRows`), else `(0, 0)`.
    pub fn gate_blocks(&self) -> (usize, usize) {
        match self {
            Exported::F32(n) => {
                let z = 4 * n.dims.embed_blocks + n.dims.hidden;
                (z * 16, n.dims.hidden)
            }
            Exported::Int16(_) | Exported::Int8(_) => (0, 0),
        }
    }

    /// Bytes of the activation tables the network reads (`firmware::nn::act`, 32 KiB for
    /// the integer networks; 0 for f32, whose activations are computed).
    pub fn act_tables_bytes(&self) -> usize {
        match self {
            Exported::F32(_) => 0,
            Exported::Int16(_) | Exported::Int8(_) => act::ACT_TABLES_BYTES,
        }
    }

    /// Bytes of flash the network's arrays take.
    pub fn flash_bytes(&self) -> usize {
        match self {
            Exported::F32(n) => n.flash_bytes(),
            Exported::Int16(n) => n.flash_bytes(),
            Exported::Int8(n) => n.flash_bytes(),
        }
    }
}

/// FNV-1a over the bits of every output of every step (the self-check digest).
/// (`firmware::model::self_check::Digest`).
pub fn output_digest(outputs: &[Vec<f32>]) -> u64 {
    let mut d = self_check::Digest::default();
    for row in outputs {
        d.add(row);
    }
    d.0
}

/// What goes into the generated file besides the network.
#[derive(Clone, Debug)]
pub struct ExportMeta {
    /// Feature preset (`paper`, `feedforward`, `custom`).
    pub preset: String,
    /// Indices of the compensated joints (0-based).
    pub joints: Vec<usize>,
    /// Control rate [Hz].
    pub control_rate_hz: u32,
    /// Steps of golden input for the self-check (`firmware::model::self_check::input`).
    pub self_check_steps: usize,
    /// Where the model's arrays live on the target, and why.
    pub placement: PlacementChoice,
    /// Drive profile of each compensated joint, in `joints` order (the robot
    /// description's, `JointProfile::BOARD` where it gives none).
    pub profiles: Vec<firmware::control::JointProfile>,
}

/// The `link_section` attribute of the model's arrays placed in SRAM: an input section
/// of cortex-m-rt's `.data` (run address in RAM, load image in flash, copied by its
/// reset handler before `main`, so the static holds its value whenever Rust code reads
/// it; `unsafe_code` is allowed for this one attribute of the static). Host builds
/// ignore it.
pub const SRAM_SECTION_ATTRIBUTE: &str = "#[cfg_attr(target_os = \"none\", allow(unsafe_code), \
     unsafe(link_section = \".data.model_arrays\"))]";

/// The `link_section` attribute of the gate blocks placed in CCM SRAM: an input section
/// of `.ccmram_data` (both `memory.x` files: run address in CCM SRAM, load image in
/// flash, copied at start-up by `ccm::copy_code` before `main` reads it; the linker
/// fails when code and data outgrow CCM SRAM). Host builds ignore it.
pub const CCM_SECTION_ATTRIBUTE: &str = "#[cfg_attr(target_os = \"none\", allow(unsafe_code), \
     unsafe(link_section = \".ccmram_data.model_arrays\"))]";

/// Where the exporter puts the model's arrays (network, linear stage, rigid-body model).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Placement {
    /// Flash (`.rodata`), read over the flash interface every tick.
    Flash,
    /// SRAM (`.data`, copied from flash at reset): zero wait states.
    Sram,
}

/// Where `export --weights-in` puts the model's arrays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WeightsIn {
    /// Flash.
    Flash,
    /// SRAM (an error when a budget file is given and they do not fit its SRAM budget).
    Sram,
    /// SRAM when they fit the budget file's SRAM budget, flash otherwise (and without a
    /// budget file).
    Auto,
}

impl WeightsIn {
    /// Every choice, in the order the command line lists them.
    pub const ALL: [Self; 3] = [Self::Flash, Self::Sram, Self::Auto];

    /// The choice's name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::Flash => "flash",
            Self::Sram => "sram",
            Self::Auto => "auto",
        }
    }
}

/// Reads the board's flash limit from a budget file (`budgets::Budgets`, the budget
/// tool's schema).
pub fn flash_budget(path: &std::path::Path) -> anyhow::Result<u64> {
    let b = budgets::Budgets::read(path)?;
    let flash = b.board(path)?.flash_bytes;
    if flash == 0 {
        bail!(
            "{}: field `binary.board.flash_bytes` = 0: must be a positive byte count",
            path.display()
        );
    }
    Ok(flash)
}

/// Reads the board's SRAM budget for a model's arrays from a budget file and the
/// linker memory layout it names (`mcu.memory_layout`, relative to the budget file).
pub fn sram_budget(path: &std::path::Path) -> anyhow::Result<SramBudget> {
    let b = budgets::Budgets::read(path)?;
    let board = b.board(path)?;
    let layout = b
        .mcu
        .memory_layout
        .as_deref()
        .with_context(|| format!("{}: field `mcu.memory_layout` missing", path.display()))?;
    let layout = path
        .parent()
        .unwrap_or(std::path::Path::new("."))
        .join(layout);
    let layout_text = std::fs::read_to_string(&layout).with_context(|| {
        format!(
            "reading {} (`mcu.memory_layout` of {})",
            layout.display(),
            path.display()
        )
    })?;
    let layout_ram_bytes =
        layout_ram_bytes(&layout_text).map_err(|e| anyhow::anyhow!("{}: {e}", layout.display()))?;
    let ram_limit_bytes = board.ram_bytes;
    let stack_reserve_bytes = board.stack_reserve_bytes;
    let firmware_ram_bytes = board.firmware_ram_bytes.with_context(|| {
        format!(
            "{}: field `binary.board.firmware_ram_bytes` missing",
            path.display()
        )
    })?;
    // CCM SRAM for model data: optional (a layout without the region, or a budget file
    // without the code reserve, places nothing there).
    let ccm_code_reserve_bytes = board.ccm_code_reserve_bytes;
    let layout_ccm_bytes = layout_region_bytes(&layout_text, "CCMRAM")
        .map_err(|e| anyhow::anyhow!("{}: {e}", layout.display()))?
        .unwrap_or(0);
    Ok(SramBudget {
        layout_ram_bytes,
        ram_limit_bytes,
        stack_reserve_bytes,
        firmware_ram_bytes,
        layout_ccm_bytes,
        ccm_code_reserve_bytes,
    })
}

/// Chooses where each of the model's arrays lives, and the activation tables its
/// network reads. `auto` fills the SRAM budget in the order of what a tick reads most:
/// the network, then the rigid-body model, then the linear stage; each goes to SRAM
/// when it fits what is left, to flash otherwise. The activation tables (an integer
/// network's; an f32 network reads none) go to SRAM when they fit what the arrays
/// left, with `auto` and with `sram` (which puts the arrays in SRAM or fails), to
/// flash otherwise; with `flash` everything stays in flash, and without a budget
/// `sram` puts the tables in SRAM too.
pub fn choose_placement(
    want: WeightsIn,
    bytes: ModelBytes,
    budget: Option<ModelBudget>,
) -> Result<PlacementChoice> {
    let sram_budget_bytes = budget.map(|b| b.sram_bytes);
    let total = bytes.network + bytes.dynamics + bytes.linear_stage;
    let all = |p| [p; 3];
    let [network, dynamics, linear_stage] = match (want, sram_budget_bytes) {
        (WeightsIn::Flash, _) | (WeightsIn::Auto, None) => all(Placement::Flash),
        (WeightsIn::Sram, None) => all(Placement::Sram),
        (WeightsIn::Sram, Some(b)) if total as u64 <= b => all(Placement::Sram),
        (WeightsIn::Sram, Some(b)) => bail!(
            "--weights-in sram: the model's arrays need {total} bytes, over the SRAM budget \
             of {b} bytes (the board's RAM less the stack reserve and the firmware's own RAM)"
        ),
        (WeightsIn::Auto, Some(b)) => {
            let mut left = b;
            [bytes.network, bytes.dynamics, bytes.linear_stage].map(|n| {
                if n as u64 <= left {
                    left -= n as u64;
                    Placement::Sram
                } else {
                    Placement::Flash
                }
            })
        }
    };
    let arrays_in_sram = [
        (network, bytes.network),
        (dynamics, bytes.dynamics),
        (linear_stage, bytes.linear_stage),
    ]
    .iter()
    .filter(|(p, _)| *p == Placement::Sram)
    .map(|(_, n)| *n as u64)
    .sum::<u64>();
    // A network too big for SRAM: the first blocks of its gate matrix fill what is left,
    // the next ones the CCM SRAM budget.
    let whole_blocks =
        |left: u64, at_most: usize| ((left / bytes.gate_block.max(1) as u64) as usize).min(at_most);
    let (gate_blocks_in_sram, gate_blocks_in_ccm) = match (want, budget, network) {
        (WeightsIn::Auto, Some(b), Placement::Flash) if bytes.gate_block > 0 => {
            let sram = whole_blocks(
                b.sram_bytes.saturating_sub(arrays_in_sram),
                bytes.gate_blocks,
            );
            let ccm = whole_blocks(b.ccm_bytes, bytes.gate_blocks - sram);
            (sram, ccm)
        }
        _ => (0, 0),
    };
    let in_sram = arrays_in_sram + (gate_blocks_in_sram * bytes.gate_block) as u64;
    let act_tables = (bytes.act_tables > 0).then(|| match (want, sram_budget_bytes) {
        (WeightsIn::Flash, _) | (WeightsIn::Auto, None) => Placement::Flash,
        (WeightsIn::Sram, None) => Placement::Sram,
        (WeightsIn::Sram | WeightsIn::Auto, Some(b)) => {
            if in_sram + bytes.act_tables as u64 <= b {
                Placement::Sram
            } else {
                Placement::Flash
            }
        }
    });
    Ok(PlacementChoice {
        network,
        dynamics,
        linear_stage,
        act_tables,
        gate_blocks_in_sram,
        gate_blocks_in_ccm,
        bytes,
        sram_budget_bytes,
        ccm_budget_bytes: budget.map(|b| b.ccm_bytes),
    })
}

/// Bytes of each of the model's arrays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ModelBytes {
    /// `NETWORK`.
    pub network: usize,
    /// `DYNAMICS` (0 without a rigid-body model).
    pub dynamics: usize,
    /// `LINEAR_STAGE`.
    pub linear_stage: usize,
    /// The activation tables the network reads (`firmware::nn::act`; 0 when it reads
    /// none).
    pub act_tables: usize,
    /// Bytes of one block of the gate matrix when the network can place the first
    /// blocks of its gate matrix in SRAM apart from the rest (`F32GateRows`, f32
    /// networks), else 0.
    pub gate_block: usize,
    /// Blocks of the gate matrix (`H`).
    pub gate_blocks: usize,
}

/// Where each of the model's arrays lives, and the budget the choice was weighed against.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PlacementChoice {
    /// `NETWORK`.
    pub network: Placement,
    /// `DYNAMICS`.
    pub dynamics: Placement,
    /// `LINEAR_STAGE`.
    pub linear_stage: Placement,
    /// The activation tables (`Format::ACT_TABLES`); `None` when the network reads none.
    pub act_tables: Option<Placement>,
    /// With the network in flash: the first blocks of its gate matrix placed in SRAM
    /// (`GATES_HEAD`; 0 for none, always 0 for an integer network).
    pub gate_blocks_in_sram: usize,
    /// With the network in flash: the blocks after those placed in CCM SRAM
    /// (`GATES_MIDDLE`; 0 for none).
    pub gate_blocks_in_ccm: usize,
    /// Their sizes.
    pub bytes: ModelBytes,
    /// The SRAM budget for the model's arrays [bytes], when a budget file was given.
    pub sram_budget_bytes: Option<u64>,
    /// The CCM SRAM budget for model data [bytes], when a budget file was given.
    pub ccm_budget_bytes: Option<u64>,
}

impl PlacementChoice {
    /// One line describing the choice (the generated file's header and `export`'s output).
    pub fn describe(&self) -> String {
        let at = |p: Placement| match p {
            Placement::Sram => "SRAM",
            Placement::Flash => "flash",
        };
        // The CCM SRAM budget is named where the choice used it.
        let budget = match (self.sram_budget_bytes, self.ccm_budget_bytes) {
            (Some(b), Some(c)) if self.gate_blocks_in_ccm > 0 => {
                format!("SRAM budget for the model {b} bytes, CCM SRAM budget {c} bytes")
            }
            (Some(b), _) => format!("SRAM budget for the model {b} bytes"),
            (None, _) => "no budget file".to_string(),
        };
        let tables = match self.act_tables {
            Some(p) => format!(
                "activation tables {} bytes in {}",
                self.bytes.act_tables,
                at(p)
            ),
            None => "no activation tables (f32)".to_string(),
        };
        let split = match (self.gate_blocks_in_sram, self.gate_blocks_in_ccm) {
            (0, 0) => String::new(),
            (k, 0) => format!(
                " (its gate matrix's first {k} of {} blocks, {} bytes, in SRAM)",
                self.bytes.gate_blocks,
                k * self.bytes.gate_block
            ),
            (k, m) => format!(
                " (its gate matrix's first {k} of {} blocks, {} bytes, in SRAM, the next {m}, \
                 {} bytes, in CCM SRAM)",
                self.bytes.gate_blocks,
                k * self.bytes.gate_block,
                m * self.bytes.gate_block
            ),
        };
        format!(
            "network {} bytes in {}{split}, rigid-body model {} bytes in {}, linear stage {} bytes in {}, \
             {tables} (SRAM: .data, copied from flash at reset; flash: .rodata); {budget}",
            self.bytes.network,
            at(self.network),
            self.bytes.dynamics,
            at(self.dynamics),
            self.bytes.linear_stage,
            at(self.linear_stage),
        )
    }
}

/// The board's SRAM budget for a model's arrays, from the budget file and the linker
/// memory layout it names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SramBudget {
    /// Length of the `RAM` region in the memory layout (`memory.x`) [bytes].
    pub layout_ram_bytes: u64,
    /// The board binary's RAM limit (`binary.board.ram_bytes`) [bytes].
    pub ram_limit_bytes: u64,
    /// The board's stack reserve (`binary.board.stack_reserve_bytes`) [bytes].
    pub stack_reserve_bytes: u64,
    /// RAM of the board firmware's own static data and buffers
    /// (`binary.board.firmware_ram_bytes`) [bytes].
    pub firmware_ram_bytes: u64,
    /// Length of the `CCMRAM` region in the memory layout [bytes] (0 without one).
    pub layout_ccm_bytes: u64,
    /// CCM SRAM kept for the per-tick code (`binary.board.ccm_code_reserve_bytes`)
    /// [bytes]; without the field no model data goes to CCM SRAM.
    pub ccm_code_reserve_bytes: Option<u64>,
}

/// What the board leaves for a model's arrays: SRAM and CCM SRAM [bytes].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ModelBudget {
    /// SRAM (`.data`).
    pub sram_bytes: u64,
    /// CCM SRAM beside the per-tick code (`.ccmram_data`).
    pub ccm_bytes: u64,
}

impl SramBudget {
    /// Bytes left for the model's arrays: in SRAM the smaller of the two RAM sizes,
    /// less the stack reserve and the firmware's own static RAM; in CCM SRAM the
    /// region's length less the code reserve (0 without either).
    pub fn model_bytes(&self) -> ModelBudget {
        ModelBudget {
            sram_bytes: self
                .layout_ram_bytes
                .min(self.ram_limit_bytes)
                .saturating_sub(self.stack_reserve_bytes)
                .saturating_sub(self.firmware_ram_bytes),
            ccm_bytes: self
                .ccm_code_reserve_bytes
                .map_or(0, |r| self.layout_ccm_bytes.saturating_sub(r)),
        }
    }
}

/// Length in bytes of the `RAM` region of a linker memory layout (`memory.x`):
/// `RAM : ORIGIN = ..., LENGTH = 96K` (decimal or `0x` hex, optional `K` or `M`).
/// Errors name the line.
pub fn layout_ram_bytes(text: &str) -> Result<u64, String> {
    layout_region_bytes(text, "RAM")?.ok_or_else(|| "no RAM region".into())
}

/// Length in bytes of the region `name` of a linker memory layout (`memory.x`), `None`
/// when the layout has no such region. Errors name the line.
pub fn layout_region_bytes(text: &str, name: &str) -> Result<Option<u64>, String> {
    for (k, line) in text.lines().enumerate() {
        let code = line.split("/*").next().unwrap_or("");
        let Some((region, rest)) = code.split_once(':') else {
            continue;
        };
        if region.trim() != name {
            continue;
        }
        let length = rest
            .split(',')
            .filter_map(|f| f.split_once('='))
            .find(|(key, _)| key.trim() == "LENGTH")
            .map(|(_, v)| v.trim())
            .ok_or_else(|| format!("line {}: region {name} has no LENGTH", k + 1))?;
        return parse_layout_size(length).map(Some).ok_or_else(|| {
            format!(
                "line {}: field LENGTH of region {name} is not a size",
                k + 1
            )
        });
    }
    Ok(None)
}

fn parse_layout_size(v: &str) -> Option<u64> {
    let (digits, unit) = match v.as_bytes().last()? {
        b'K' | b'k' => (&v[..v.len() - 1], 1024),
        b'M' | b'm' => (&v[..v.len() - 1], 1024 * 1024),
        _ => (v, 1),
    };
    let n = match digits
        .strip_prefix("0x")
        .or_else(|| digits.strip_prefix("0X"))
    {
        Some(hex) => u64::from_str_radix(&hex.replace('_', ""), 16).ok()?,
        None => digits.replace('_', "").parse::<u64>().ok()?,
    };
    n.checked_mul(unit)
}

fn f32_lit(x: f32) -> String {
    let s = format!("{x:?}");
    if s.contains('.') || s.contains('e') || s.contains("inf") || s.contains("NaN") {
        s
    } else {
        format!("{s}.0")
    }
}

fn list<T>(v: &[T], f: impl Fn(&T) -> String) -> String {
    let items: Vec<String> = v.iter().map(f).collect();
    format!("[{}]", items.join(", "))
}

fn quads_i16(q: &[[u32; 4]; 2]) -> String {
    format!(
        "[{}, {}]",
        list(&q[0], |w| format!("{w:#010x}")),
        list(&q[1], |w| format!("{w:#010x}"))
    )
}

fn quads_i8(q: &[u32; 4]) -> String {
    list(q, |w| format!("{w:#010x}"))
}

fn nested<T: Copy>(flat: &[T], per: usize, f: impl Fn(&T) -> String) -> String {
    if flat.is_empty() {
        return "[]".into();
    }
    let chunks: Vec<String> = flat.chunks(per.max(1)).map(|c| list(c, &f)).collect();
    format!("[\n    {}\n]", chunks.join(",\n    "))
}

fn write_quant<F: WeightFormat>(
    s: &mut String,
    section: &str,
    tables: Placement,
    n: &QuantNet<F>,
    fmt: &str,
    quad: impl Fn(&F::Quad) -> String,
) {
    let d = n.dims;
    let (i, iq, eb, h, hq, zq, o, ob) = (
        d.input,
        d.input_quads,
        d.embed_blocks,
        d.hidden,
        d.hidden / 4,
        d.z_quads(),
        d.output,
        d.output_blocks,
    );
    let _ = writeln!(
        s,
        "/// The network's integer format: `{}` weights, the input activation, the \
         activation-index shifts of its power-of-two scales and the activation tables' \
         placement.",
        F::NAME
    );
    let _ = writeln!(s, "pub struct Format;");
    let _ = writeln!(s, "impl QuantFormat for Format {{");
    let _ = writeln!(s, "    type Weights = {fmt};");
    let _ = writeln!(
        s,
        "    const INPUT_ACTIVATION: InputActivation = InputActivation::{};",
        activation_variant(n.in_activation)
    );
    let _ = writeln!(s, "    const INPUT_SHIFT: u32 = {};", n.in_shift);
    let _ = writeln!(
        s,
        "    const GATE_SHIFTS: [u32; 4] = {};",
        list(&n.gate_shift, |x| x.to_string())
    );
    // A closed set of paths (never input text).
    let tables = match tables {
        Placement::Sram => "ACT_TABLES_SRAM",
        Placement::Flash => "ACT_TABLES_FLASH",
    };
    let _ = writeln!(
        s,
        "    const ACT_TABLES: &'static firmware::nn::act::ActTables = &firmware::nn::act::{tables};"
    );
    let _ = writeln!(s, "}}");
    let _ = writeln!(s, "/// The network's type: sizes from the exporter.");
    let _ = writeln!(
        s,
        "pub type Network = QuantLstm<Format, {i}, {iq}, {eb}, {h}, {hq}, {zq}, {o}, {ob}>;"
    );
    let _ = writeln!(s, "/// The network's recurrent state.");
    let _ = writeln!(s, "pub type State = QuantState<{zq}, {h}>;");
    let _ = writeln!(s, "/// The network.");
    let _ = write!(s, "{section}");
    let _ = writeln!(s, "pub static NETWORK: Network = QuantLstm {{");
    let _ = writeln!(
        s,
        "    input_mean: {},",
        list(&n.input_mean, |x| f32_lit(*x))
    );
    let _ = writeln!(
        s,
        "    input_scale: {},",
        list(&n.input_scale, |x| f32_lit(*x))
    );
    let _ = writeln!(s, "    in_w: {},", nested(&n.in_w, iq, &quad));
    let _ = writeln!(
        s,
        "    in_bias: {},",
        list(&n.in_bias, |b| list(b, |x| x.to_string()))
    );
    let _ = writeln!(s, "    gate_w: {},", nested(&n.gate_w, zq, &quad));
    let _ = writeln!(
        s,
        "    gate_bias: {},",
        list(&n.gate_bias, |b| list(b, |x| x.to_string()))
    );
    let _ = writeln!(s, "    out_w: {},", nested(&n.out_w, hq, &quad));
    let _ = writeln!(
        s,
        "    out_scale: {},",
        list(&n.out_scale, |b| list(b, |x| f32_lit(*x)))
    );
    let _ = writeln!(
        s,
        "    out_offset: {},",
        list(&n.out_offset, |b| list(b, |x| f32_lit(*x)))
    );
    let _ = writeln!(s, "}};");
}

/// The `InputActivation` variant's name in a generated file (a closed set, never text
/// from the input).
fn activation_variant(a: InputActivation) -> &'static str {
    match a {
        InputActivation::Tanh => "Tanh",
        InputActivation::Linear => "Linear",
    }
}

/// The `firmware::nn::kernels::InputLayer` type of an activation.
fn input_layer_type(a: InputActivation) -> &'static str {
    match a {
        InputActivation::Tanh => "TanhInput",
        InputActivation::Linear => "LinearInput",
    }
}

/// `head_blocks`: how many blocks of the gate matrix go to `GATES_HEAD` (placed by
/// `head_section`); the rest go to `GATES_TAIL`, placed with the network (`section`).
fn write_f32(s: &mut String, section: &str, head_section: &str, split: [usize; 2], n: &F32Net) {
    let d = n.dims;
    let (i, eb, h, o, ob) = (d.input, d.embed_blocks, d.hidden, d.output, d.output_blocks);
    let e = 4 * eb;
    let z = e + h;
    let v4 = |b: &[f32; 4]| list(b, |x| f32_lit(*x));
    let layer = input_layer_type(n.input_activation);
    let _ = writeln!(
        s,
        "/// The network's type: f32, sizes and input activation from the exporter."
    );
    let _ = writeln!(
        s,
        "pub type Network = F32Lstm<{i}, {e}, {eb}, {h}, {z}, {o}, {ob}, {layer}>;"
    );
    let _ = writeln!(s, "/// The network's recurrent state.");
    let _ = writeln!(s, "pub type State = F32State<{z}, {h}>;");
    let head_blocks = split[0].min(h);
    let middle_blocks = split[1].min(h - head_blocks);
    let (head, rest) = n.w_gates.split_at((head_blocks * z).min(n.w_gates.len()));
    let (middle, tail) = rest.split_at((middle_blocks * z).min(rest.len()));
    let _ = writeln!(
        s,
        "/// The gate matrix's first {head_blocks} blocks ({} bytes; `F32GateRows`).",
        head.len() * 16
    );
    let head_section = if head.is_empty() { "" } else { head_section };
    let _ = write!(s, "{head_section}");
    let _ = writeln!(
        s,
        "pub static GATES_HEAD: [[[f32; 4]; {z}]; {head_blocks}] = {};",
        nested(head, z, v4)
    );
    let _ = writeln!(
        s,
        "/// The gate matrix's next {middle_blocks} blocks ({} bytes).",
        middle.len() * 16
    );
    // An empty part needs no placement.
    if !middle.is_empty() {
        let _ = writeln!(s, "{CCM_SECTION_ATTRIBUTE}");
    }
    let _ = writeln!(
        s,
        "pub static GATES_MIDDLE: [[[f32; 4]; {z}]; {middle_blocks}] = {};",
        nested(middle, z, v4)
    );
    let tail_blocks = h - head_blocks - middle_blocks;
    let _ = writeln!(
        s,
        "/// The gate matrix's other {tail_blocks} blocks ({} bytes).",
        tail.len() * 16
    );
    let tail_section = if tail.is_empty() { "" } else { section };
    let _ = write!(s, "{tail_section}");
    let _ = writeln!(
        s,
        "pub static GATES_TAIL: [[[f32; 4]; {z}]; {tail_blocks}] = {};",
        nested(tail, z, v4)
    );
    let _ = writeln!(
        s,
        "const _: () = assert!(GATES_HEAD.len() + GATES_MIDDLE.len() + GATES_TAIL.len() == {h}, \"the gate matrix has H blocks\");"
    );
    let _ = writeln!(s, "/// The network.");
    let _ = write!(s, "{section}");
    let _ = writeln!(s, "pub static NETWORK: Network = F32Lstm {{");
    let _ = writeln!(
        s,
        "    input_mean: {},",
        list(&n.input_mean, |x| f32_lit(*x))
    );
    let _ = writeln!(
        s,
        "    input_inv_std: {},",
        list(&n.input_inv_std, |x| f32_lit(*x))
    );
    let _ = writeln!(s, "    w_in: {},", nested(&n.w_in, i, v4));
    let _ = writeln!(s, "    b_in: {},", list(&n.b_in, v4));
    let _ = writeln!(s, "    input_layer: {layer},");
    let _ = writeln!(
        s,
        "    w_gates: F32GateRows {{ head: &GATES_HEAD, middle: &GATES_MIDDLE, tail: &GATES_TAIL }},"
    );
    let _ = writeln!(s, "    b_gates: {},", list(&n.b_gates, v4));
    let _ = writeln!(s, "    w_out: {},", nested(&n.w_out, h, v4));
    let _ = writeln!(s, "    b_out: {},", list(&n.b_out, v4));
    let _ = writeln!(s, "    output_std: {},", list(&n.output_std, v4));
    let _ = writeln!(s, "    output_mean: {},", list(&n.output_mean, v4));
    let _ = writeln!(s, "}};");
}

fn write_dynamics<const N: usize>(s: &mut String, section: &str, m: &RigidBodyModel<N>) {
    let v3 = |v: &[f32; 3]| list(v, |x| f32_lit(*x));
    let _ = writeln!(s, "/// Number of joints of the rigid-body model.");
    let _ = writeln!(s, "pub const DYNAMICS_JOINTS: usize = {N};");
    let _ = writeln!(s, "/// The identified (or nominal) rigid-body model, f32.");
    let _ = write!(s, "{section}");
    let _ = writeln!(
        s,
        "pub static DYNAMICS: RigidBodyModel<{N}> = RigidBodyModel {{"
    );
    let _ = writeln!(s, "    joints: [");
    for j in &m.joints {
        let _ = writeln!(s, "        JointModel {{");
        let _ = writeln!(
            s,
            "            origin_rotation: {},",
            list(&j.origin_rotation, v3)
        );
        let _ = writeln!(
            s,
            "            origin_translation_m: {},",
            v3(&j.origin_translation_m)
        );
        let _ = writeln!(s, "            axis: {},", v3(&j.axis));
        let _ = writeln!(
            s,
            "            inertial: {},",
            list(&j.inertial, |x| f32_lit(*x))
        );
        let _ = writeln!(
            s,
            "            viscous_nm_s_rad: {},",
            f32_lit(j.viscous_nm_s_rad)
        );
        let _ = writeln!(s, "            coulomb_nm: {},", f32_lit(j.coulomb_nm));
        let _ = writeln!(s, "            offset_nm: {},", f32_lit(j.offset_nm));
        let _ = writeln!(
            s,
            "            rotor_inertia_kg_m2: {},",
            f32_lit(j.rotor_inertia_kg_m2)
        );
        let f = |x: &f32| f32_lit(*x);
        let _ = writeln!(s, "            stribeck_nm: {},", list(&j.stribeck_nm, f));
        let _ = writeln!(
            s,
            "            quadratic_nm_s2_rad2: {},",
            f32_lit(j.quadratic_nm_s2_rad2)
        );
        let _ = writeln!(s, "            q_range_rad: {},", list(&j.q_range_rad, f));
        let _ = writeln!(
            s,
            "            qd_range_rad_s: {},",
            list(&j.qd_range_rad_s, f)
        );
        let _ = writeln!(
            s,
            "            qdd_range_rad_s2: {},",
            list(&j.qdd_range_rad_s2, f)
        );
        let _ = writeln!(s, "        }},");
    }
    let _ = writeln!(s, "    ],");
    let _ = writeln!(s, "    gravity_m_s2: {},", v3(&m.gravity_m_s2));
    let _ = writeln!(
        s,
        "    coulomb_inv_eps_s_rad: {},",
        f32_lit(m.coulomb_inv_eps_s_rad)
    );
    let _ = writeln!(s, "}};");
}

/// Bytes of the `DYNAMICS` static of a model of any joint count.
pub fn dynamics_bytes(d: &FirmwareModel) -> usize {
    match d {
        FirmwareModel::J1(m) => std::mem::size_of_val(m),
        FirmwareModel::J2(m) => std::mem::size_of_val(m),
        FirmwareModel::J3(m) => std::mem::size_of_val(m),
        FirmwareModel::J4(m) => std::mem::size_of_val(m),
        FirmwareModel::J5(m) => std::mem::size_of_val(m),
        FirmwareModel::J6(m) => std::mem::size_of_val(m),
        FirmwareModel::J7(m) => std::mem::size_of_val(m),
    }
}

/// Writes the `DYNAMICS` items of the generated file for a model of any joint count.
fn write_any_dynamics(s: &mut String, section: &str, d: &FirmwareModel) {
    match d {
        FirmwareModel::J1(m) => write_dynamics(s, section, m),
        FirmwareModel::J2(m) => write_dynamics(s, section, m),
        FirmwareModel::J3(m) => write_dynamics(s, section, m),
        FirmwareModel::J4(m) => write_dynamics(s, section, m),
        FirmwareModel::J5(m) => write_dynamics(s, section, m),
        FirmwareModel::J6(m) => write_dynamics(s, section, m),
        FirmwareModel::J7(m) => write_dynamics(s, section, m),
    }
}

/// The golden inputs of the self-check: `firmware::model::self_check::input`.
pub fn golden_inputs(n_inputs: usize, steps: usize) -> Vec<Vec<f32>> {
    (0..steps)
        .map(|t| (0..n_inputs).map(|k| self_check::input(t, k)).collect())
        .collect()
}

/// Writes `JOINT_PROFILES`: one `JointProfile` literal per compensated joint (numbers
/// only, each f32 written so that it reads back to the same bits).
fn write_profiles(s: &mut String, profiles: &[firmware::control::JointProfile]) {
    use firmware::control::BusClock;
    let _ = writeln!(
        s,
        "/// Drive profile of each compensated joint, in `JOINT_INDICES` order: motor, gear,\n\
         /// limits, gains and bus settings (`control::JointProfile`)."
    );
    let _ = writeln!(
        s,
        "pub const JOINT_PROFILES: [firmware::control::JointProfile; {}] = [",
        profiles.len()
    );
    for p in profiles {
        let m = &p.motor;
        let c = &p.cascade;
        let l = &p.state_limits;
        let bus_clock = match p.bus_clock {
            BusClock::Synchronised => "firmware::control::BusClock::Synchronised".to_string(),
            BusClock::FreeRunning { max_rate_error_ppm } => format!(
                "firmware::control::BusClock::FreeRunning {{ max_rate_error_ppm: {max_rate_error_ppm} }}"
            ),
        };
        let _ = writeln!(s, "    firmware::control::JointProfile {{");
        let _ = writeln!(
            s,
            "        motor: firmware::control::MotorParameters {{ pole_pairs: {}, phase_resistance_ohm: {}, phase_inductance_h: {}, flux_linkage_wb: {} }},",
            m.pole_pairs,
            f32_lit(m.phase_resistance_ohm),
            f32_lit(m.phase_inductance_h),
            f32_lit(m.flux_linkage_wb)
        );
        let _ = writeln!(
            s,
            "        gear_ratio: {}, gear_efficiency: {}, encoder_offset_rad: {},",
            f32_lit(p.gear_ratio),
            f32_lit(p.gear_efficiency),
            f32_lit(p.encoder_offset_rad)
        );
        let _ = writeln!(
            s,
            "        cascade: firmware::control::CascadeConfig {{ rate_hz: {}, position_kp: {}, position_ki: {}, position_kd: {}, max_velocity_rad_s: {}, velocity_kp: {}, velocity_ki: {}, velocity_kd: {}, max_current_a: {}, velocity_filter_alpha: {} }},",
            f32_lit(c.rate_hz),
            f32_lit(c.position_kp),
            f32_lit(c.position_ki),
            f32_lit(c.position_kd),
            f32_lit(c.max_velocity_rad_s),
            f32_lit(c.velocity_kp),
            f32_lit(c.velocity_ki),
            f32_lit(c.velocity_kd),
            f32_lit(c.max_current_a),
            f32_lit(c.velocity_filter_alpha)
        );
        let _ = writeln!(
            s,
            "        max_current_a: {}, overcurrent_trip_a: {}, bus_min_v: {}, bus_max_v: {}, max_abs_q_ref_rad: {},",
            f32_lit(p.max_current_a),
            f32_lit(p.overcurrent_trip_a),
            f32_lit(p.bus_min_v),
            f32_lit(p.bus_max_v),
            f32_lit(p.max_abs_q_ref_rad)
        );
        let _ = writeln!(
            s,
            "        state_limits: firmware::control::StateLimits {{ max_abs_q_rad: {}, max_abs_qd_rad_s: {}, max_abs_qdd_rad_s2: {}, max_abs_tau_nm: {} }},",
            f32_lit(l.max_abs_q_rad),
            f32_lit(l.max_abs_qd_rad_s),
            f32_lit(l.max_abs_qdd_rad_s2),
            f32_lit(l.max_abs_tau_nm)
        );
        let _ = writeln!(
            s,
            "        watchdog_ticks: {}, max_message_age_ticks: {}, bus_clock: {bus_clock},",
            p.watchdog_ticks, p.max_message_age_ticks
        );
        let _ = writeln!(
            s,
            "        max_torque_nm: {}, max_torque_rate_nm_s: {}, max_lstm_correction_nm: {}, warmup_ticks: {}, lstm_retry_ticks: {},",
            f32_lit(p.max_torque_nm),
            f32_lit(p.max_torque_rate_nm_s),
            f32_lit(p.max_lstm_correction_nm),
            p.warmup_ticks,
            p.lstm_retry_ticks
        );
        let _ = writeln!(
            s,
            "        feedforward_max_current_a: {}, bus_baud: {},",
            f32_lit(p.feedforward_max_current_a),
            p.bus_baud
        );
        let _ = writeln!(
            s,
            "        adaptation: firmware::adaptation::AdaptationConfig {{ time_constant_s: {}, max_correction_nm: {} }},",
            f32_lit(p.adaptation.time_constant_s),
            f32_lit(p.adaptation.max_correction_nm)
        );
        let _ = writeln!(
            s,
            "        monitor: firmware::monitor::MonitorConfig {{ window_s: {}, fade_s: {}, hysteresis: {} }},",
            f32_lit(p.monitor.window_s),
            f32_lit(p.monitor.fade_s),
            f32_lit(p.monitor.hysteresis)
        );
        let _ = writeln!(s, "    }},");
    }
    let _ = writeln!(s, "];");
}

/// Renders the whole generated file.
pub fn render(
    m: &LstmModel,
    net: &Exported,
    meta: &ExportMeta,
    dynamics: Option<&FirmwareModel>,
) -> String {
    let mut body = String::new();
    // The attribute line placing a static in SRAM (a closed set, never input text).
    let attribute = |p: Placement| match p {
        Placement::Sram => format!("{SRAM_SECTION_ATTRIBUTE}\n"),
        Placement::Flash => String::new(),
    };
    let (network_section, dynamics_section, section) = (
        attribute(meta.placement.network),
        attribute(meta.placement.dynamics),
        attribute(meta.placement.linear_stage),
    );
    let section = section.as_str();
    let tables = meta.placement.act_tables.unwrap_or(Placement::Flash);
    // The variant of a known preset name; anything else is `Custom` (never input text).
    let preset = format!(
        "{:?}",
        FeaturePreset::from_name(&meta.preset).unwrap_or(FeaturePreset::Custom)
    );
    let s = &mut body;
    let _ = writeln!(
        s,
        "/// Layout version of this file (`fw_export::SCHEMA_VERSION`)."
    );
    let _ = writeln!(s, "pub const SCHEMA_VERSION: u32 = {SCHEMA_VERSION};");
    let prec = match net {
        Exported::F32(_) => "F32",
        Exported::Int16(_) => "Int16",
        Exported::Int8(_) => "Int8",
    };
    let _ = writeln!(s, "/// Numeric precision of the network.");
    let _ = writeln!(s, "pub const PRECISION: Precision = Precision::{prec};");
    let _ = writeln!(s, "/// Activation after the network's input layer.");
    let _ = writeln!(
        s,
        "pub const INPUT_ACTIVATION: InputActivation = InputActivation::{};",
        activation_variant(net.input_activation())
    );
    let _ = writeln!(s, "/// Feature preset the network was trained with.");
    let _ = writeln!(
        s,
        "pub const FEATURE_PRESET: FeaturePreset = FeaturePreset::{preset};"
    );
    let _ = writeln!(s, "/// Number of inputs.");
    let _ = writeln!(s, "pub const INPUTS: usize = {};", m.dims.input);
    let _ = writeln!(s, "/// Number of outputs.");
    let _ = writeln!(s, "pub const OUTPUTS: usize = {};", m.dims.output);
    let _ = writeln!(
        s,
        "/// The `drive` preset's linear stage: per output, coefficients [N*m per unit] of\n\
         /// `features::FRICTION_FEATURE_NAMES` (zero for other presets)."
    );
    let f = firmware::features::FRICTION_FEATURES;
    // Without a linear stage the file does not depend on the number of features.
    let stage = if m.linear.iter().all(|&x| x == 0.0) {
        "[[0.0; firmware::features::FRICTION_FEATURES]; OUTPUTS]".to_string()
    } else {
        let rows: Vec<Vec<f32>> = (0..m.dims.output)
            .map(|k| {
                m.linear
                    .get(k * f..(k + 1) * f)
                    .map_or_else(|| vec![0.0; f], <[f32]>::to_vec)
            })
            .collect();
        list(&rows, |r| list(r, |x| f32_lit(*x)))
    };
    let _ = write!(s, "{section}");
    let _ = writeln!(
        s,
        "pub static LINEAR_STAGE: [[f32; firmware::features::FRICTION_FEATURES]; OUTPUTS] = {stage};"
    );
    let _ = writeln!(s, "/// Input feature names, in input order.");
    let _ = writeln!(
        s,
        "pub const INPUT_NAMES: [&str; {}] = {};",
        m.dims.input,
        list(&m.input_names, |n| format!("{n:?}"))
    );
    let _ = writeln!(s, "/// Output names, in output order.");
    let _ = writeln!(
        s,
        "pub const OUTPUT_NAMES: [&str; {}] = {};",
        m.dims.output,
        list(&m.output_names, |n| format!("{n:?}"))
    );
    let _ = writeln!(s, "/// Indices (0-based) of the compensated joints.");
    let _ = writeln!(
        s,
        "pub const JOINT_INDICES: [usize; {}] = {};",
        meta.joints.len(),
        list(&meta.joints, |j| j.to_string())
    );
    let _ = writeln!(
        s,
        "/// Control (compensator) rate the network was trained for [Hz]."
    );
    let _ = writeln!(
        s,
        "pub const CONTROL_RATE_HZ: u32 = {};",
        meta.control_rate_hz
    );
    write_profiles(s, &meta.profiles);
    envelope::write_envelope(s, m);
    match net {
        Exported::F32(n) => {
            // The whole gate matrix goes with the network, or its first blocks to SRAM
            // and the next to CCM SRAM.
            let (head_section, split) = match meta.placement.network {
                Placement::Sram => (network_section.clone(), [n.dims.hidden, 0]),
                Placement::Flash => (
                    attribute(Placement::Sram),
                    [
                        meta.placement.gate_blocks_in_sram,
                        meta.placement.gate_blocks_in_ccm,
                    ],
                ),
            };
            write_f32(s, &network_section, &head_section, split, n)
        }
        Exported::Int16(n) => write_quant(s, &network_section, tables, n, "I16Weights", quads_i16),
        Exported::Int8(n) => write_quant(s, &network_section, tables, n, "I8Weights", quads_i8),
    }
    if let Some(d) = dynamics {
        write_any_dynamics(s, &dynamics_section, d);
    } else {
        let _ = writeln!(
            s,
            "/// Number of joints of the rigid-body model (0: none exported)."
        );
        let _ = writeln!(s, "pub const DYNAMICS_JOINTS: usize = 0;");
    }
    let outs = net.stream(&golden_inputs(m.dims.input, meta.self_check_steps));
    let _ = writeln!(
        s,
        "/// Self-check: streaming steps of `test_kit::golden::network::input` from the zero state."
    );
    let _ = writeln!(
        s,
        "pub const SELF_CHECK_STEPS: usize = {};",
        meta.self_check_steps
    );
    let _ = writeln!(
        s,
        "/// Self-check: FNV-1a of the output bits of those steps, computed by the exporter."
    );
    let _ = writeln!(
        s,
        "pub const SELF_CHECK_FNV: u64 = {:#018x};",
        output_digest(&outs)
    );
    let hash = Sha256::digest(body.as_bytes());
    let hash64 = u64::from_be_bytes(hash[..8].try_into().unwrap_or([0; 8]));
    let mut out = String::new();
    let _ = writeln!(
        out,
        "// Generated by `model-export export` (schema {SCHEMA_VERSION}); do not edit."
    );
    let _ = writeln!(
        out,
        "// Network {}x{}x{}x{} ({}), preset {}, joints {:?}, {} Hz.",
        m.dims.input,
        m.dims.embed,
        m.dims.hidden,
        m.dims.output,
        prec,
        // The closed set's name, never the model file's text.
        preset,
        meta.joints,
        meta.control_rate_hz
    );
    let _ = writeln!(out, "// Placement: {}.", meta.placement.describe());
    let _ = writeln!(out, "#[allow(unused_imports)]");
    let _ = writeln!(
        out,
        "use firmware::dynamics::{{JointModel, RigidBodyModel}};"
    );
    let _ = writeln!(out, "#[allow(unused_imports)]");
    let _ = writeln!(
        out,
        "use firmware::nn::format::{{FeaturePreset, I8Weights, I16Weights, InputActivation, Precision, QuantFormat, QuantState}};"
    );
    let _ = writeln!(out, "#[allow(unused_imports)]");
    let _ = writeln!(
        out,
        "use firmware::nn::kernels::{{F32GateRows, F32Lstm, F32State, LinearInput, QuantLstm, TanhInput}};"
    );
    let _ = writeln!(
        out,
        "/// SHA-256 (first 8 bytes) of everything below this line."
    );
    let _ = writeln!(out, "pub const CONTENT_HASH: u64 = {hash64:#018x};");
    out.push_str(&body);
    out
}

/// One precision's accuracy on one output.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct AccuracyRow {
    /// Precision name (`f32`, `int16`, `int8`).
    pub precision: String,
    /// Output name.
    pub output: String,
    /// RMS of the precision's streamed output against the f32 firmware step.
    pub rms_vs_f32: f64,
    /// RMS error against the targets ("compensated RMS"), with targets.
    pub compensated_rms: Option<f64>,
    /// f32's compensated RMS, with targets.
    pub f32_compensated_rms: Option<f64>,
}

/// Per-output RMS of each precision's streamed output against the f32 firmware step
/// (`nn::model::LstmModel::stream`), and, with `targets`, each one's RMS error against
/// the targets ("compensated RMS") beside f32's.
pub fn accuracy(
    m: &LstmModel,
    inputs: &[Vec<f32>],
    targets: Option<&[Vec<f32>]>,
) -> Result<Vec<AccuracyRow>> {
    let reference = m.stream(inputs)?;
    let rms = |a: &[Vec<f32>], b: &[Vec<f32>], j: usize| -> f64 {
        let s: f64 = a
            .iter()
            .zip(b)
            .map(|(x, y)| ((x[j] - y[j]) as f64).powi(2))
            .sum();
        (s / a.len().max(1) as f64).sqrt()
    };
    let mut rows = Vec::new();
    for p in Precision::ALL {
        let y = Exported::new(m, p)?.stream(inputs);
        for j in 0..m.dims.output {
            rows.push(AccuracyRow {
                precision: p.name().to_string(),
                output: m.output_names[j].clone(),
                rms_vs_f32: rms(&y, &reference, j),
                compensated_rms: targets.map(|t| rms(&y, t, j)),
                f32_compensated_rms: targets.map(|t| rms(&reference, t, j)),
            });
        }
    }
    Ok(rows)
}

/// [`accuracy`] as a Markdown table (ratio = compensated RMS / f32's).
pub fn accuracy_markdown(rows: &[AccuracyRow]) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "| precision | output | RMS vs f32 step | compensated RMS | f32 compensated RMS | ratio |"
    );
    let _ = writeln!(out, "|---|---|---:|---:|---:|---:|");
    for r in rows {
        let (c, f, ratio) = match (r.compensated_rms, r.f32_compensated_rms) {
            (Some(c), Some(f)) => (
                format!("{c:.5}"),
                format!("{f:.5}"),
                format!("{:.4}", c / f),
            ),
            _ => ("-".into(), "-".into(), "-".into()),
        };
        let _ = writeln!(
            out,
            "| {} | {} | {:.3e} | {c} | {f} | {ratio} |",
            r.precision, r.output, r.rms_vs_f32
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use firmware::nn::reference::LstmDims;

    /// The paper int16 network's sizes (68 968 B), and the board's model budget.
    const PAPER_INT16: ModelBytes = ModelBytes {
        network: 68_968,
        dynamics: 808,
        linear_stage: 324,
        act_tables: act::ACT_TABLES_BYTES,
        gate_block: 0,
        gate_blocks: 0,
    };
    const BUDGET: Option<ModelBudget> = Some(ModelBudget {
        sram_bytes: 73_728,
        ccm_bytes: 0,
    });

    fn tables(
        want: WeightsIn,
        bytes: ModelBytes,
        budget: Option<ModelBudget>,
    ) -> Option<Placement> {
        choose_placement(want, bytes, budget)
            .expect("placement")
            .act_tables
    }

    #[test]
    fn the_tables_go_to_sram_only_when_they_fit_beside_the_arrays() {
        // 68 968 + 808 + 324 + 32 768 > 73 728: the tables stay in flash.
        assert_eq!(
            tables(WeightsIn::Auto, PAPER_INT16, BUDGET),
            Some(Placement::Flash)
        );
        // The per-joint network (4 728 B): everything fits.
        let joint = ModelBytes {
            network: 4_728,
            dynamics: 0,
            linear_stage: 108,
            ..PAPER_INT16
        };
        let p = choose_placement(WeightsIn::Auto, joint, BUDGET).expect("placement");
        assert_eq!(
            (p.network, p.linear_stage, p.act_tables),
            (Placement::Sram, Placement::Sram, Some(Placement::Sram))
        );
        assert!(
            p.describe()
                .contains("activation tables 32768 bytes in SRAM")
        );
        // Exactly at the budget fits; one byte over does not.
        let exact = ModelBytes {
            network: 73_728 - 32_768,
            dynamics: 0,
            linear_stage: 0,
            ..PAPER_INT16
        };
        assert_eq!(
            tables(WeightsIn::Auto, exact, BUDGET),
            Some(Placement::Sram)
        );
        let over = ModelBytes {
            network: exact.network + 1,
            ..exact
        };
        assert_eq!(
            tables(WeightsIn::Auto, over, BUDGET),
            Some(Placement::Flash)
        );
        // A network too big for SRAM leaves the room to the tables.
        let f32_sized = ModelBytes {
            network: 135_800,
            ..joint
        };
        let p = choose_placement(WeightsIn::Auto, f32_sized, BUDGET).expect("placement");
        assert_eq!(
            (p.network, p.act_tables),
            (Placement::Flash, Some(Placement::Sram))
        );
    }

    #[test]
    fn an_f32_network_too_big_for_sram_puts_its_first_gate_blocks_there() {
        // The paper f32 network: 135 800 B, 64 gate blocks of 128 columns (2 048 B).
        let paper_f32 = ModelBytes {
            network: 135_800,
            dynamics: 808,
            linear_stage: 324,
            act_tables: 0,
            gate_block: 2_048,
            gate_blocks: 64,
        };
        let p = choose_placement(WeightsIn::Auto, paper_f32, BUDGET).expect("placement");
        // (73 728 - 808 - 324) / 2 048 = 35 blocks.
        assert_eq!(
            (p.network, p.dynamics, p.linear_stage, p.gate_blocks_in_sram),
            (Placement::Flash, Placement::Sram, Placement::Sram, 35)
        );
        assert_eq!(p.gate_blocks_in_ccm, 0);
        assert!(
            p.describe()
                .contains("(its gate matrix's first 35 of 64 blocks, 71680 bytes, in SRAM)"),
            "{}",
            p.describe()
        );
        // With CCM SRAM beside the code: the next blocks go there (24 576 / 2 048 = 12;
        // up to 26 623 B still 12: whole blocks).
        for ccm_bytes in [24_576, 25_000, 26_623] {
            let budget = Some(ModelBudget {
                sram_bytes: 73_728,
                ccm_bytes,
            });
            let p = choose_placement(WeightsIn::Auto, paper_f32, budget).expect("placement");
            assert_eq!((p.gate_blocks_in_sram, p.gate_blocks_in_ccm), (35, 12));
            assert!(
                p.describe()
                    .contains("71680 bytes, in SRAM, the next 12, 24576 bytes, in CCM SRAM)"),
                "{}",
                p.describe()
            );
        }
        // Never more blocks than the matrix has.
        let huge = Some(ModelBudget {
            sram_bytes: 73_728,
            ccm_bytes: 1 << 20,
        });
        let p = choose_placement(WeightsIn::Auto, paper_f32, huge).expect("placement");
        assert_eq!((p.gate_blocks_in_sram, p.gate_blocks_in_ccm), (35, 29));
        for (want, budget) in [(WeightsIn::Flash, BUDGET), (WeightsIn::Auto, None)] {
            let p = choose_placement(want, paper_f32, budget).expect("placement");
            assert_eq!((p.gate_blocks_in_sram, p.gate_blocks_in_ccm), (0, 0));
        }
        // A network that fits keeps its gate matrix whole (with the network).
        let small = ModelBytes {
            network: 3_192,
            ..paper_f32
        };
        let p = choose_placement(WeightsIn::Auto, small, BUDGET).expect("placement");
        assert_eq!((p.network, p.gate_blocks_in_sram), (Placement::Sram, 0));
    }

    #[test]
    fn the_ccm_budget_is_the_ccmram_region_less_the_code_reserve() {
        let layout = "MEMORY\n{\n  RAM : ORIGIN = 0x20000000, LENGTH = 96K\n  \
                      CCMRAM : ORIGIN = 0x10000000, LENGTH = 32K /* CCMRAM: LENGTH = 1 */\n}\n";
        assert_eq!(layout_region_bytes(layout, "CCMRAM"), Ok(Some(32 * 1024)));
        assert_eq!(layout_region_bytes(layout, "FLASH"), Ok(None));
        assert!(
            layout_region_bytes("CCMRAM : ORIGIN = 0, LENGTH = x", "CCMRAM")
                .is_err_and(|e| e.contains("line 1") && e.contains("CCMRAM"))
        );
        let mut b = SramBudget {
            layout_ram_bytes: 96 * 1024,
            ram_limit_bytes: 98_304,
            stack_reserve_bytes: 16_384,
            firmware_ram_bytes: 8_192,
            layout_ccm_bytes: 32 * 1024,
            ccm_code_reserve_bytes: Some(8_192),
        };
        assert_eq!(
            b.model_bytes(),
            ModelBudget {
                sram_bytes: 73_728,
                ccm_bytes: 24_576
            }
        );
        // Without the reserve in the budget file, nothing goes to CCM SRAM.
        b.ccm_code_reserve_bytes = None;
        assert_eq!(b.model_bytes().ccm_bytes, 0);
        // The board's own budget file and memory layout.
        let file =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../host-tests/budgets.toml");
        let board = sram_budget(&file).expect("budget file");
        assert_eq!(board.layout_ccm_bytes, 32 * 1024);
        assert!(board.model_bytes().ccm_bytes > 0);
    }

    #[test]
    fn the_generated_f32_network_splits_its_gate_matrix_between_three_statics() {
        let m = LstmModel::init(
            LstmDims {
                input: 3,
                embed: 4,
                hidden: 8,
                output: 1,
            },
            5,
        );
        let net = F32Net::arrange(&m).expect("arranges");
        let sram = format!("{SRAM_SECTION_ATTRIBUTE}\n");
        let ccm = format!("{CCM_SECTION_ATTRIBUTE}\n");
        let mut s = String::new();
        write_f32(&mut s, "", &sram, [3, 2], &net);
        assert!(s.contains(&format!(
            "{sram}pub static GATES_HEAD: [[[f32; 4]; 12]; 3] = "
        )));
        assert!(s.contains(&format!(
            "{ccm}pub static GATES_MIDDLE: [[[f32; 4]; 12]; 2] = "
        )));
        assert!(s.contains("\npub static GATES_TAIL: [[[f32; 4]; 12]; 3] = "));
        assert!(!s.contains(&format!("{sram}pub static GATES_TAIL")));
        assert!(s.contains(
            "w_gates: F32GateRows { head: &GATES_HEAD, middle: &GATES_MIDDLE, tail: &GATES_TAIL },"
        ));
        // Nothing in SRAM or CCM SRAM: no attribute for the empty parts.
        let mut s = String::new();
        write_f32(&mut s, "", "", [0, 0], &net);
        assert!(s.contains("pub static GATES_HEAD: [[[f32; 4]; 12]; 0] = [];"));
        assert!(s.contains("pub static GATES_MIDDLE: [[[f32; 4]; 12]; 0] = [];"));
        assert!(!s.contains("link_section"));
        assert_eq!(Exported::F32(net).gate_blocks(), (12 * 16, 8));
    }

    #[test]
    fn forced_and_unbudgeted_choices_place_the_tables_with_the_arrays() {
        let joint = ModelBytes {
            network: 4_728,
            dynamics: 0,
            linear_stage: 108,
            ..PAPER_INT16
        };
        assert_eq!(
            tables(WeightsIn::Flash, joint, BUDGET),
            Some(Placement::Flash)
        );
        assert_eq!(tables(WeightsIn::Auto, joint, None), Some(Placement::Flash));
        assert_eq!(tables(WeightsIn::Sram, joint, None), Some(Placement::Sram));
        assert_eq!(
            tables(WeightsIn::Sram, joint, BUDGET),
            Some(Placement::Sram)
        );
        // `sram` keeps the arrays in SRAM and the tables where they fit.
        assert_eq!(
            tables(WeightsIn::Sram, PAPER_INT16, BUDGET),
            Some(Placement::Flash)
        );
        // An f32 network reads no tables.
        let f32_net = ModelBytes {
            act_tables: 0,
            ..joint
        };
        let p = choose_placement(WeightsIn::Auto, f32_net, BUDGET).expect("placement");
        assert_eq!(p.act_tables, None);
        assert!(p.describe().contains("no activation tables (f32)"));
    }

    #[test]
    fn the_generated_format_names_the_chosen_tables() {
        let m = LstmModel::init(
            LstmDims {
                input: 3,
                embed: 4,
                hidden: 4,
                output: 1,
            },
            5,
        );
        let net = QuantNet::<I16Weights>::quantise(&m).expect("quantises");
        for (p, name) in [
            (Placement::Sram, "&firmware::nn::act::ACT_TABLES_SRAM;"),
            (Placement::Flash, "&firmware::nn::act::ACT_TABLES_FLASH;"),
        ] {
            let mut s = String::new();
            write_quant(&mut s, "", p, &net, "I16Weights", quads_i16);
            let line = s
                .lines()
                .find(|l| l.contains("const ACT_TABLES"))
                .expect("the format names its tables");
            assert!(line.ends_with(name), "{line}");
        }
        assert_eq!(Exported::Int16(net).act_tables_bytes(), 32_768);
    }
}
