//! The f32 network in the kernels' layout: gate rows interleaved by four, run-time
//! sizes ([`F32Net`], `firmware::nn::kernels::F32View`).
use super::*;

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
pub(crate) fn interleave(rows: &[Vec<f64>]) -> Vec<[f32; 4]> {
    let cols = rows.first().map_or(0, Vec::len);
    let mut out = Vec::new();
    for blk in rows.chunks_exact(4) {
        for k in 0..cols {
            out.push(std::array::from_fn(|r| blk[r][k] as f32));
        }
    }
    out
}

pub(crate) fn blocks4(v: &[f64]) -> Vec<[f32; 4]> {
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
