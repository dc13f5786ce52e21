//! The host model: weights in PyTorch's layouts, normalisation, feature names; the
//! candle network used for training; and streaming evaluation through the firmware step.
use super::fused::FusedLstm;
use anyhow::{Result, bail};
use candle_core::{DType, Device, Tensor, Var};
use firmware::envelope::JointEnvelope;
use firmware::features::{self, DRIVE_INPUTS_PER_JOINT, FRICTION_FEATURES};
use firmware::nn::format::InputActivation;
use firmware::nn::reference::{LstmDims, LstmView};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Widest layer (input, embedding, hidden or output) a network may have: 16x the paper's
/// 64, so a mistyped size is an error naming the limit, not a huge allocation.
pub const MAX_LAYER_WIDTH: usize = 1024;

/// Largest |weight|, |bias|, |mean| and standard deviation a network may hold: trained
/// values are a few units, and within this bound no sum of a step can overflow `f32`.
pub const MAX_ABS_NETWORK_VALUE: f32 = 1e6;

/// Smallest input standard deviation (the trainer's floor): a smaller one scales an
/// input to infinity.
pub const MIN_INPUT_STD: f32 = 1e-12;

/// A trained (or imported) compensation network with everything needed to run it.
///
/// Weight layouts are PyTorch's: `nn.Linear.weight` `[out, in]`, `nn.LSTM` `weight_ih_l0`
/// `[4H, E]`, `weight_hh_l0` `[4H, H]`, gate order i, f, g, o; all row-major, flat.
#[derive(Clone, Debug, PartialEq)]
pub struct LstmModel {
    /// Sizes.
    pub dims: LstmDims,
    /// Input feature names (CSV columns), in input order.
    pub input_names: Vec<String>,
    /// Output names, in output order.
    pub output_names: Vec<String>,
    /// Feature preset the model was trained with (`paper`, `feedforward`, `custom`).
    pub preset: String,
    /// Mean of each input feature.
    pub input_mean: Vec<f32>,
    /// Standard deviation of each input feature.
    pub input_std: Vec<f32>,
    /// `input.weight` `[E, I]`.
    pub w_in: Vec<f32>,
    /// `input.bias` `[E]`.
    pub b_in: Vec<f32>,
    /// Activation after the input layer (`tanh` for the networks trained here; a
    /// PyTorch network may have a plain `nn.Linear`).
    pub input_activation: InputActivation,
    /// `lstm.weight_ih_l0` `[4H, E]`.
    pub w_ih: Vec<f32>,
    /// `lstm.weight_hh_l0` `[4H, H]`.
    pub w_hh: Vec<f32>,
    /// `lstm.bias_ih_l0` `[4H]`.
    pub b_ih: Vec<f32>,
    /// `lstm.bias_hh_l0` `[4H]`.
    pub b_hh: Vec<f32>,
    /// `output.weight` `[O, H]`.
    pub w_out: Vec<f32>,
    /// `output.bias` `[O]`.
    pub b_out: Vec<f32>,
    /// Mean of each target.
    pub output_mean: Vec<f32>,
    /// Standard deviation of each target.
    pub output_std: Vec<f32>,
    /// The `drive` preset's linear stage `linear.weight` `[O, 16]`: per output, the
    /// coefficients [N*m per feature unit] of `firmware::features::FRICTION_FEATURE_NAMES`
    /// of that joint's inputs, added to the network's output; empty without one.
    pub linear: Vec<f32>,
    /// Per output (compensated joint), the training envelope recorded over the training
    /// datasets (`firmware::envelope`); empty: none recorded (an imported network).
    pub envelope: Vec<JointEnvelope>,
}

impl LstmModel {
    /// A fresh model with PyTorch's default initialisation, drawn from a seeded ChaCha8:
    /// every weight and bias of a layer with fan-in `n` (the LSTM: `H`) from U(±1/√n).
    /// Normalisation starts as identity.
    pub fn init(dims: LstmDims, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut uniform = |n: usize, fan_in: usize| -> Vec<f32> {
            let k = 1.0 / (fan_in.max(1) as f32).sqrt();
            (0..n).map(|_| rng.gen_range(-k..k)).collect()
        };
        let LstmDims {
            input: i,
            embed: e,
            hidden: h,
            output: o,
        } = dims;
        LstmModel {
            dims,
            input_names: (0..i).map(|k| format!("x{k}")).collect(),
            output_names: (0..o).map(|k| format!("y{k}")).collect(),
            preset: "custom".into(),
            input_mean: vec![0.0; i],
            input_std: vec![1.0; i],
            w_in: uniform(e * i, i),
            b_in: uniform(e, i),
            input_activation: InputActivation::Tanh,
            w_ih: uniform(4 * h * e, h),
            w_hh: uniform(4 * h * h, h),
            b_ih: uniform(4 * h, h),
            b_hh: uniform(4 * h, h),
            w_out: uniform(o * h, h),
            b_out: uniform(o, h),
            output_mean: vec![0.0; o],
            output_std: vec![1.0; o],
            linear: Vec::new(),
            envelope: Vec::new(),
        }
    }

    /// Checks shapes, finiteness and positive standard deviations.
    pub fn validate(&self) -> Result<()> {
        artifacts::plausible::name(&self.preset)
            .map_err(|m| anyhow::anyhow!("metadata `preset`: {m}"))?;
        for (key, names) in [
            ("input_names", &self.input_names),
            ("output_names", &self.output_names),
        ] {
            for (k, n) in names.iter().enumerate() {
                artifacts::plausible::name(n)
                    .map_err(|m| anyhow::anyhow!("metadata `{key}`, name {}: {m}", k + 1))?;
            }
        }
        self.streamer()?;
        for (name, v) in self.tensors() {
            if let Some(k) = v.iter().position(|x| !x.is_finite()) {
                bail!(
                    "tensor `{name}`: element {k} is {} (weights must be finite)",
                    v[k]
                );
            }
        }
        for (name, v) in [
            ("norm.input_std", &self.input_std),
            ("norm.output_std", &self.output_std),
        ] {
            if let Some(k) = v.iter().position(|&x| x <= 0.0) {
                bail!("tensor `{name}`: element {k} is {} (must be > 0)", v[k]);
            }
        }
        for (name, v) in self.tensors() {
            if let Some(k) = v.iter().position(|x| x.abs() > MAX_ABS_NETWORK_VALUE) {
                bail!(
                    "tensor `{name}`: element {k} is {} (|value| must be <= {MAX_ABS_NETWORK_VALUE:e})",
                    v[k]
                );
            }
        }
        if let Some(k) = self.input_std.iter().position(|&x| x < MIN_INPUT_STD) {
            bail!(
                "tensor `norm.input_std`: element {k} is {:e} (must be >= {MIN_INPUT_STD:e})",
                self.input_std[k]
            );
        }
        if !self.linear.is_empty() {
            let o = self.dims.output;
            if self.preset != "drive"
                || self.dims.input != DRIVE_INPUTS_PER_JOINT * o
                || self.linear.len() != FRICTION_FEATURES * o
            {
                bail!(
                    "tensor `linear.weight`: {} values; a linear stage belongs to a `drive` network \
                     of {DRIVE_INPUTS_PER_JOINT} inputs per output and has [{o}, {FRICTION_FEATURES}] \
                     (this one: preset `{}`, {:?})",
                    self.linear.len(),
                    self.preset,
                    self.dims
                );
            }
            if let Some(k) = self.linear.iter().position(|x| !x.is_finite()) {
                bail!("tensor `linear.weight`: element {k} is not finite");
            }
        }
        if !self.envelope.is_empty() && self.envelope.len() != self.dims.output {
            bail!(
                "model has {} joint envelopes for {} outputs",
                self.envelope.len(),
                self.dims.output
            );
        }
        if let Some(k) = self.envelope.iter().position(|e| !e.is_valid()) {
            bail!("joint envelope {k} has an unordered or NaN range");
        }
        if self.input_names.len() != self.dims.input || self.output_names.len() != self.dims.output
        {
            bail!(
                "model has {} input and {} output names for {:?}",
                self.input_names.len(),
                self.output_names.len(),
                self.dims
            );
        }
        Ok(())
    }

    /// Every tensor with its interchange name (see [`super::io`]).
    pub fn tensors(&self) -> [(&'static str, &Vec<f32>); 12] {
        [
            ("input.weight", &self.w_in),
            ("input.bias", &self.b_in),
            ("lstm.weight_ih_l0", &self.w_ih),
            ("lstm.weight_hh_l0", &self.w_hh),
            ("lstm.bias_ih_l0", &self.b_ih),
            ("lstm.bias_hh_l0", &self.b_hh),
            ("output.weight", &self.w_out),
            ("output.bias", &self.b_out),
            ("norm.input_mean", &self.input_mean),
            ("norm.input_std", &self.input_std),
            ("norm.output_mean", &self.output_mean),
            ("norm.output_std", &self.output_std),
        ]
    }

    /// A streaming runner over the FIRMWARE's f32 step.
    pub fn streamer(&self) -> Result<Streamer<'_>> {
        let h = self.dims.hidden;
        let b_gates: Vec<f32> = self
            .b_ih
            .iter()
            .zip(&self.b_hh)
            .map(|(a, b)| a + b)
            .collect();
        let s = Streamer {
            model: self,
            b_gates,
            h: vec![0.0; h],
            c: vec![0.0; h],
            embed: vec![0.0; self.dims.embed],
            h_scratch: vec![0.0; h],
        };
        if let Err(e) = s.view().check() {
            bail!("model tensor {e}");
        }
        Ok(s)
    }

    /// Streams the firmware step over a whole sequence from the zero state
    /// (`inputs`: one row of `I` raw features per step); returns one output row per step.
    pub fn stream(&self, inputs: &[Vec<f32>]) -> Result<Vec<Vec<f32>>> {
        let mut s = self.streamer()?;
        inputs.iter().map(|x| s.step(x)).collect()
    }
}

/// The `drive` preset's linear stage (`LstmModel::linear`, `[O, 16]`; empty: none) on
/// one row of inputs: per output, the correction [N*m] of that joint's inputs, its
/// features clamped to that joint's `envelope` (missing: unbounded), as the firmware
/// computes it.
pub fn linear_stage_nm(linear: &[f32], envelope: &[JointEnvelope], row: &[f32]) -> Vec<f32> {
    let outputs = linear.len() / FRICTION_FEATURES;
    linear
        .chunks_exact(FRICTION_FEATURES)
        .enumerate()
        .map(|(k, w)| {
            let w: [f32; FRICTION_FEATURES] = std::array::from_fn(|c| w[c]);
            let e = envelope.get(k).unwrap_or(&JointEnvelope::UNBOUNDED);
            features::linear_correction_nm(&w, e, &features::joint_drive_inputs(row, outputs, k))
        })
        .collect()
}

/// Runs [`firmware::nn::reference::LstmView::step`] on a host model, keeping the state.
#[derive(Debug)]
pub struct Streamer<'a> {
    model: &'a LstmModel,
    b_gates: Vec<f32>,
    h: Vec<f32>,
    c: Vec<f32>,
    embed: Vec<f32>,
    h_scratch: Vec<f32>,
}

impl Streamer<'_> {
    fn view(&self) -> LstmView<'_> {
        let m = self.model;
        LstmView {
            dims: m.dims,
            input_mean: &m.input_mean,
            input_std: &m.input_std,
            w_in: &m.w_in,
            b_in: &m.b_in,
            input_activation: m.input_activation,
            w_ih: &m.w_ih,
            w_hh: &m.w_hh,
            b_gates: &self.b_gates,
            w_out: &m.w_out,
            b_out: &m.b_out,
            output_mean: &m.output_mean,
            output_std: &m.output_std,
        }
    }

    /// One firmware step.
    pub fn step(&mut self, input: &[f32]) -> Result<Vec<f32>> {
        let mut out = vec![0.0; self.model.dims.output];
        let (mut h, mut c, mut e, mut hs) = (
            std::mem::take(&mut self.h),
            std::mem::take(&mut self.c),
            std::mem::take(&mut self.embed),
            std::mem::take(&mut self.h_scratch),
        );
        let r = self
            .view()
            .step(&mut h, &mut c, &mut e, &mut hs, input, &mut out);
        (self.h, self.c, self.embed, self.h_scratch) = (h, c, e, hs);
        r.map_err(|e| anyhow::anyhow!("firmware LSTM step: {e}"))?;
        for (y, c) in out.iter_mut().zip(linear_stage_nm(
            &self.model.linear,
            &self.model.envelope,
            input,
        )) {
            *y += c;
        }
        Ok(out)
    }

    /// Back to the zero state.
    pub fn reset(&mut self) {
        self.h.fill(0.0);
        self.c.fill(0.0);
    }
}

/// The trainable candle network (variables in PyTorch layouts).
#[derive(Debug)]
pub struct Net {
    /// Sizes.
    pub dims: LstmDims,
    /// Activation after the input layer.
    pub input_activation: InputActivation,
    /// `input.weight`, `input.bias`, `lstm.weight_ih_l0`, `lstm.weight_hh_l0`,
    /// `lstm.bias_ih_l0`, `lstm.bias_hh_l0`, `output.weight`, `output.bias`.
    pub vars: Vec<Var>,
}

impl Net {
    /// Candle variables holding a model's weights.
    pub fn from_model(m: &LstmModel, dev: &Device) -> Result<Self> {
        let LstmDims {
            input: i,
            embed: e,
            hidden: h,
            output: o,
        } = m.dims;
        let t = |v: &Vec<f32>, shape: &[usize]| -> Result<Var> {
            Ok(Var::from_tensor(&Tensor::from_slice(v, shape, dev)?)?)
        };
        let vars = vec![
            t(&m.w_in, &[e, i])?,
            t(&m.b_in, &[e])?,
            t(&m.w_ih, &[4 * h, e])?,
            t(&m.w_hh, &[4 * h, h])?,
            t(&m.b_ih, &[4 * h])?,
            t(&m.b_hh, &[4 * h])?,
            t(&m.w_out, &[o, h])?,
            t(&m.b_out, &[o])?,
        ];
        Ok(Net {
            dims: m.dims,
            input_activation: m.input_activation,
            vars,
        })
    }

    /// Copies the variables back into `m`'s weights.
    pub fn store(&self, m: &mut LstmModel) -> Result<()> {
        let get = |k: usize| -> Result<Vec<f32>> {
            Ok(self.vars[k].as_tensor().flatten_all()?.to_vec1::<f32>()?)
        };
        m.w_in = get(0)?;
        m.b_in = get(1)?;
        m.w_ih = get(2)?;
        m.w_hh = get(3)?;
        m.b_ih = get(4)?;
        m.b_hh = get(5)?;
        m.w_out = get(6)?;
        m.b_out = get(7)?;
        Ok(())
    }

    /// Forward over a batch of NORMALISED windows `[B, T, I]` from the zero state;
    /// returns normalised outputs `[B, T, O]`.
    pub fn forward(&self, x: &Tensor) -> Result<Tensor> {
        let (b, t_len, i) = x.dims3()?;
        let LstmDims {
            embed: e,
            hidden: h,
            output: o,
            ..
        } = self.dims;
        let v = |k: usize| self.vars[k].as_tensor();
        let x2 = x.reshape((b * t_len, i))?;
        let pre = x2.matmul(&v(0).t()?)?.broadcast_add(v(1))?;
        let emb = match self.input_activation {
            InputActivation::Tanh => pre.tanh()?,
            InputActivation::Linear => pre,
        };
        let bias = (v(4) + v(5))?;
        let gx = emb
            .matmul(&v(2).t()?)?
            .broadcast_add(&bias)?
            .reshape((b, t_len, 4 * h))?;
        let hs = gx.apply_op2(v(3), FusedLstm)?;
        let y = hs
            .reshape((b * t_len, h))?
            .matmul(&v(6).t()?)?
            .broadcast_add(v(7))?;
        let _ = e;
        Ok(y.reshape((b, t_len, o))?)
    }
}

/// Normalises raw rows with the model's statistics into a `[1, T, I]` tensor.
#[allow(clippy::needless_range_loop)]
pub fn normalised_sequence(m: &LstmModel, rows: &[Vec<f32>], dev: &Device) -> Result<Tensor> {
    let i = m.dims.input;
    let mut flat = Vec::with_capacity(rows.len() * i);
    for r in rows {
        for k in 0..i {
            flat.push((r[k] - m.input_mean[k]) / m.input_std[k]);
        }
    }
    Ok(Tensor::from_vec(flat, (1, rows.len(), i), dev)?.to_dtype(DType::F32)?)
}
