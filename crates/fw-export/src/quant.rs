//! Quantisation of the network into the integer kernels' layout: per-layer Q formats
//! chosen so no accumulator can overflow, gate rows grouped by four, the output
//! layer's per-row scales ([`QuantNet`], `firmware::nn::kernels::QuantView`).
use super::*;

pub(crate) fn check_finite(m: &LstmModel) -> Result<(), ExportError> {
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

pub(crate) fn pad4(n: usize) -> usize {
    n.div_ceil(4) * 4
}

/// The network's rows in kernel order with padding: returns `(rows, bias)` for each
/// layer, as f64. Gate block `j` = rows `i_j, f_j, g_j, o_j`, columns `[e (Ep); h (Hp)]`.
pub(crate) struct Layers {
    pub(crate) e_pad: usize,
    pub(crate) h_pad: usize,
    pub(crate) input: (Vec<Vec<f64>>, Vec<f64>),
    pub(crate) gates: (Vec<Vec<f64>>, Vec<f64>),
    pub(crate) output: (Vec<Vec<f64>>, Vec<f64>),
}

pub(crate) fn layers(m: &LstmModel, in_cols: usize) -> Layers {
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

pub(crate) const ACC_LIMIT: f64 = 2_147_483_647.0;

/// Largest `sum_k |w_q[k]| * 32768 + |b_q|` of `rows` at exponent `p` (weights
/// `round(w 2^p)`, bias `round(b 2^(p + x_frac))`), or `None` when a weight leaves
/// `+-max_w`.
pub(crate) fn worst_accumulator(
    rows: &[(&[f64], f64)],
    p: i32,
    x_frac: u32,
    max_w: i32,
) -> Option<f64> {
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
pub(crate) fn group_exponent(
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
pub(crate) fn quant_layer<F: WeightFormat>(
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
pub(crate) fn linear_embed_bound(rows: &[(&[f64], f64)]) -> f64 {
    let x_max = 32768.0 / f64::from(1u32 << INPUT_FRAC_BITS);
    rows.iter()
        .map(|(w, b)| w.iter().map(|x| x.abs()).sum::<f64>() * x_max + b.abs())
        .fold(0.0, f64::max)
}

/// Fraction bits `F` of a linear input layer's `e` (int16, `Q(15-F).F`): the most for
/// which [`linear_embed_bound`] fits, at most 15.
pub(crate) fn linear_embed_frac_bits(rows: &[(&[f64], f64)]) -> i32 {
    let bound = linear_embed_bound(rows);
    let mut f = ACT_FRAC_BITS as i32;
    while f > -16 && bound * 2f64.powi(f) >= 32767.0 {
        f -= 1;
    }
    f
}

/// Index shift of an accumulator with `p + x_frac` fraction bits.
pub(crate) fn index_shift(p: i32, x_frac: u32) -> u32 {
    (p + x_frac as i32 - act::GRID_FRAC_BITS as i32) as u32
}

/// Quantises one output row with its own scale (f32 multiplier at the output):
/// returns the integer weights and the scale `s` (`w ~ s * w_q`), enlarged where needed
/// so that `sum |w_q| * 32768 < 2^31`.
pub(crate) fn quantise_output_row(w: &[f64], max_w: i32) -> (Vec<i32>, f64) {
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
pub(crate) const GATE_LAYERS: [&str; 4] =
    ["lstm gate i", "lstm gate f", "lstm gate g", "lstm gate o"];

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
