//! The f32 LSTM compensation network: a stateful, streaming step.
//!
//! Architecture (Zhang et al. 2020, Fig. 9), one control tick per call:
//!
//! ```text
//! x_n = (x - input_mean) / input_std                      normalisation (part of the model)
//! e   = act(W_in x_n + b_in)                              fully connected input layer
//! i   = σ(W_ii e + W_hi h + b_i)                          LSTM, PyTorch gate order i, f, g, o
//! f   = σ(W_if e + W_hf h + b_f)
//! g   = tanh(W_ig e + W_hg h + b_g)
//! o   = σ(W_io e + W_ho h + b_o)
//! c'  = f ⊙ c + i ⊙ g,   h' = o ⊙ tanh(c')
//! y   = (W_out h' + b_out) ⊙ output_std + output_mean     fully connected output, de-normalised
//! ```
//!
//! **Input-layer activation `act`: [`InputActivation`], `tanh` or linear (identity).**
//! The paper does not name one. The networks trained here use `tanh`: it adds a
//! nonlinearity and bounds the LSTM's input to (-1, 1), a fixed Q format for the integer
//! kernels. A linear input layer (a plain PyTorch `nn.Linear`, the most common form) is
//! run as it is; the integer kernels then give `e` a power-of-two format wide enough for
//! its range (see `crate::nn::kernels`). Each model names its activation.
//!
//! The LSTM bias `b` is PyTorch's `bias_ih + bias_hh`, summed once by the exporter.
//!
//! Layout: every weight matrix is row-major `[out][in]` as in PyTorch, and the four gates
//! are stacked gate-major, so `w_ih` flattened is exactly PyTorch's `weight_ih_l0` `[4H, E]`.
//!
//! [`Lstm`] fixes the sizes through const generics (stable Rust cannot compute `4 * H` in a
//! type, so the gates are a separate array dimension). All arithmetic lives in one
//! shape-erased kernel, [`LstmView::step`], that [`Lstm::step`] calls on its own arrays
//! flattened without copying: the host evaluation (whose sizes are only known at run time)
//! runs exactly this code, so host and target compute the same bits.
//!
//! The step is pure: it neither checks inputs for being finite nor saturates its outputs;
//! the control loop does that around it.

use crate::math;
use crate::nn::format::InputActivation;

/// Sizes of a network: inputs, input-layer width, LSTM cells, outputs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LstmDims {
    /// Number of input features `I`.
    pub input: usize,
    /// Width of the fully connected input layer `E`.
    pub embed: usize,
    /// Number of LSTM cells `H`.
    pub hidden: usize,
    /// Number of outputs `O`.
    pub output: usize,
}

/// Why a set of slices does not form a network of the stated sizes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShapeError {
    /// Which array (PyTorch-style name).
    pub field: &'static str,
    /// Its expected length.
    pub expected: usize,
    /// Its actual length.
    pub actual: usize,
}

impl core::fmt::Display for ShapeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "{}: expected {} values, got {}",
            self.field, self.expected, self.actual
        )
    }
}

/// A network of fixed sizes: `I` inputs, input layer of `E`, `H` LSTM cells, `O` outputs.
#[derive(Clone, Debug, PartialEq)]
pub struct Lstm<const I: usize, const E: usize, const H: usize, const O: usize> {
    /// Input normalisation: mean of each feature.
    pub input_mean: [f32; I],
    /// Input normalisation: standard deviation of each feature (non-zero).
    pub input_std: [f32; I],
    /// Input layer weights `[E][I]`.
    pub w_in: [[f32; I]; E],
    /// Input layer bias.
    pub b_in: [f32; E],
    /// Activation after the input layer.
    pub input_activation: InputActivation,
    /// LSTM input weights per gate (i, f, g, o): `[4][H][E]`.
    pub w_ih: [[[f32; E]; H]; 4],
    /// LSTM recurrent weights per gate (i, f, g, o): `[4][H][H]`.
    pub w_hh: [[[f32; H]; H]; 4],
    /// LSTM bias per gate, `bias_ih + bias_hh`: `[4][H]`.
    pub b_gates: [[f32; H]; 4],
    /// Output layer weights `[O][H]`.
    pub w_out: [[f32; H]; O],
    /// Output layer bias.
    pub b_out: [f32; O],
    /// Output de-normalisation: mean of each target.
    pub output_mean: [f32; O],
    /// Output de-normalisation: standard deviation of each target.
    pub output_std: [f32; O],
}

/// The recurrent state of a network with `H` cells: hidden `h` and cell `c`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LstmState<const H: usize> {
    /// Hidden state `h`.
    pub h: [f32; H],
    /// Cell state `c`.
    pub c: [f32; H],
}

impl<const H: usize> LstmState<H> {
    /// The zero state a sequence starts from.
    pub const fn new() -> Self {
        LstmState {
            h: [0.0; H],
            c: [0.0; H],
        }
    }

    /// Forgets the past: back to the zero state.
    pub fn reset(&mut self) {
        *self = Self::new();
    }
}

impl<const H: usize> Default for LstmState<H> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const I: usize, const E: usize, const H: usize, const O: usize> Lstm<I, E, H, O> {
    /// Sizes of this network.
    pub const DIMS: LstmDims = LstmDims {
        input: I,
        embed: E,
        hidden: H,
        output: O,
    };

    /// The network as a shape-erased view of its own arrays (no copy).
    pub fn view(&self) -> LstmView<'_> {
        LstmView {
            dims: Self::DIMS,
            input_mean: &self.input_mean,
            input_std: &self.input_std,
            w_in: self.w_in.as_flattened(),
            b_in: &self.b_in,
            input_activation: self.input_activation,
            w_ih: self.w_ih.as_flattened().as_flattened(),
            w_hh: self.w_hh.as_flattened().as_flattened(),
            b_gates: self.b_gates.as_flattened(),
            w_out: self.w_out.as_flattened(),
            b_out: &self.b_out,
            output_mean: &self.output_mean,
            output_std: &self.output_std,
        }
    }

    /// One control tick: advances `state` by `input` and returns the de-normalised output.
    pub fn step(&self, state: &mut LstmState<H>, input: &[f32; I]) -> [f32; O] {
        let mut embed = [0.0f32; E];
        let mut h_new = [0.0f32; H];
        let mut out = [0.0f32; O];
        self.view().step_unchecked(
            &mut state.h,
            &mut state.c,
            &mut embed,
            &mut h_new,
            input,
            &mut out,
        );
        out
    }
}

/// A network of run-time sizes borrowing flat, row-major arrays (PyTorch layouts).
#[derive(Clone, Copy, Debug)]
pub struct LstmView<'a> {
    /// Sizes.
    pub dims: LstmDims,
    /// `[I]`
    pub input_mean: &'a [f32],
    /// `[I]`
    pub input_std: &'a [f32],
    /// `[E * I]`
    pub w_in: &'a [f32],
    /// `[E]`
    pub b_in: &'a [f32],
    /// Activation after the input layer.
    pub input_activation: InputActivation,
    /// `[4H * E]`
    pub w_ih: &'a [f32],
    /// `[4H * H]`
    pub w_hh: &'a [f32],
    /// `[4H]`
    pub b_gates: &'a [f32],
    /// `[O * H]`
    pub w_out: &'a [f32],
    /// `[O]`
    pub b_out: &'a [f32],
    /// `[O]`
    pub output_mean: &'a [f32],
    /// `[O]`
    pub output_std: &'a [f32],
}

impl<'a> LstmView<'a> {
    /// Checks that every array has the length `dims` asks for.
    pub fn check(&self) -> Result<(), ShapeError> {
        let LstmDims {
            input: i,
            embed: e,
            hidden: h,
            output: o,
        } = self.dims;
        let fields: [(&'static str, usize, usize); 11] = [
            ("input_mean", i, self.input_mean.len()),
            ("input_std", i, self.input_std.len()),
            ("input.weight", e * i, self.w_in.len()),
            ("input.bias", e, self.b_in.len()),
            ("lstm.weight_ih_l0", 4 * h * e, self.w_ih.len()),
            ("lstm.weight_hh_l0", 4 * h * h, self.w_hh.len()),
            ("lstm.bias", 4 * h, self.b_gates.len()),
            ("output.weight", o * h, self.w_out.len()),
            ("output.bias", o, self.b_out.len()),
            ("output_mean", o, self.output_mean.len()),
            ("output_std", o, self.output_std.len()),
        ];
        for (field, expected, actual) in fields {
            if expected != actual {
                return Err(ShapeError {
                    field,
                    expected,
                    actual,
                });
            }
        }
        Ok(())
    }

    /// One step with caller-provided state and scratch; every slice must have the
    /// length `dims` gives (`h`, `c`, `h_scratch`: `H`; `embed_scratch`: `E`;
    /// `input`: `I`; `out`: `O`), otherwise a [`ShapeError`] and nothing is changed.
    pub fn step(
        &self,
        h: &mut [f32],
        c: &mut [f32],
        embed_scratch: &mut [f32],
        h_scratch: &mut [f32],
        input: &[f32],
        out: &mut [f32],
    ) -> Result<(), ShapeError> {
        self.check()?;
        let d = self.dims;
        let lens: [(&'static str, usize, usize); 6] = [
            ("h", d.hidden, h.len()),
            ("c", d.hidden, c.len()),
            ("h_scratch", d.hidden, h_scratch.len()),
            ("embed_scratch", d.embed, embed_scratch.len()),
            ("input", d.input, input.len()),
            ("out", d.output, out.len()),
        ];
        for (field, expected, actual) in lens {
            if expected != actual {
                return Err(ShapeError {
                    field,
                    expected,
                    actual,
                });
            }
        }
        self.step_unchecked(h, c, embed_scratch, h_scratch, input, out);
        Ok(())
    }

    /// The kernel. Lengths are trusted (a mismatch gives a wrong result, never a panic:
    /// all loops are zipped iterators).
    fn step_unchecked(
        &self,
        h: &mut [f32],
        c: &mut [f32],
        embed: &mut [f32],
        h_new: &mut [f32],
        input: &[f32],
        out: &mut [f32],
    ) {
        let d = self.dims;
        // Input layer on the normalised input; normalisation fused into the row loop.
        for ((e, row), b) in embed
            .iter_mut()
            .zip(self.w_in.chunks_exact(d.input.max(1)))
            .zip(self.b_in)
        {
            let mut acc = 0.0f32;
            for (((w, x), m), s) in row
                .iter()
                .zip(input)
                .zip(self.input_mean)
                .zip(self.input_std)
            {
                acc += w * ((x - m) / s);
            }
            *e = self.input_activation.apply(acc + b);
        }
        // LSTM cell: per cell j, the four gate rows j, H + j, 2H + j, 3H + j.
        let gate_ih = |g: usize, j: usize| &self.w_ih[(g * d.hidden + j) * d.embed..][..d.embed];
        let gate_hh = |g: usize, j: usize| &self.w_hh[(g * d.hidden + j) * d.hidden..][..d.hidden];
        for (j, (hn, cj)) in h_new.iter_mut().zip(c.iter_mut()).enumerate() {
            let mut pre = [0.0f32; 4];
            for (g, p) in pre.iter_mut().enumerate() {
                *p = self.b_gates[g * d.hidden + j]
                    + dot(gate_ih(g, j), embed)
                    + dot(gate_hh(g, j), h);
            }
            let i = math::sigmoid(pre[0]);
            let f = math::sigmoid(pre[1]);
            let g = math::tanh(pre[2]);
            let o = math::sigmoid(pre[3]);
            *cj = f * *cj + i * g;
            *hn = o * math::tanh(*cj);
        }
        h.copy_from_slice(h_new);
        // Output layer, de-normalised.
        let rows = self.w_out.chunks_exact(d.hidden.max(1));
        for ((((y, row), b), m), s) in out
            .iter_mut()
            .zip(rows)
            .zip(self.b_out)
            .zip(self.output_mean)
            .zip(self.output_std)
        {
            *y = (dot(row, h) + b) * s + m;
        }
    }
}

/// Dot product of two equally long slices, summed left to right (the order of
/// [`math::dot`], so a fixed-size caller gets the same bits).
#[inline]
fn dot(a: &[f32], b: &[f32]) -> f32 {
    let mut acc = 0.0f32;
    for (x, y) in a.iter().zip(b) {
        acc += x * y;
    }
    acc
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_a_hand_computed_single_cell() {
        for activation in [InputActivation::Tanh, InputActivation::Linear] {
            single_cell(activation);
        }
    }

    fn single_cell(activation: InputActivation) {
        // I = E = H = O = 1: every formula written out by hand.
        let net = Lstm::<1, 1, 1, 1> {
            input_mean: [1.0],
            input_std: [2.0],
            w_in: [[0.5]],
            b_in: [0.1],
            input_activation: activation,
            w_ih: [[[0.3]], [[-0.2]], [[0.7]], [[0.4]]],
            w_hh: [[[0.1]], [[0.2]], [[-0.3]], [[0.5]]],
            b_gates: [[0.05], [0.6], [-0.1], [0.0]],
            w_out: [[1.5]],
            b_out: [-0.2],
            output_mean: [3.0],
            output_std: [0.5],
        };
        let mut st = LstmState::new();
        let (mut h, mut c) = (0.0f64, 0.0f64);
        let sig = |x: f64| 1.0 / (1.0 + (-x).exp());
        for t in 0..20 {
            let x = (t as f32 * 0.37).sin() * 3.0;
            let y = net.step(&mut st, &[x])[0];
            let pre = 0.5 * ((x as f64 - 1.0) / 2.0) + 0.1;
            let e = match activation {
                InputActivation::Tanh => pre.tanh(),
                InputActivation::Linear => pre,
            };
            let i = sig(0.05 + 0.3 * e + 0.1 * h);
            let f = sig(0.6 - 0.2 * e + 0.2 * h);
            let g = (-0.1 + 0.7 * e - 0.3 * h).tanh();
            let o = sig(0.4 * e + 0.5 * h);
            c = f * c + i * g;
            h = o * c.tanh();
            let want = (1.5 * h - 0.2) * 0.5 + 3.0;
            assert!(
                (y as f64 - want).abs() < 1e-6,
                "{activation:?} t {t}: {y} vs {want}"
            );
        }
    }
}
