//! The whole training network fused into one kernel on flat buffers: input layer →
//! tanh → LSTM → output layer → RMS loss, its back-propagation through time, global-norm
//! gradient clipping and Adam, with every buffer allocated once.
//!
//! Why not candle's graph: at the paper's size (B = 50, T = 100-150, H = 64) a training
//! step is ~1 GFLOP spread over hundreds of small operations; candle's per-op tensors,
//! allocations and autograd bookkeeping cost more than the arithmetic (measured: 127 ms
//! per batch with the fused LSTM op against PyTorch's 25 ms). Here the work is a few large
//! GEMMs over all `T·B` rows (input layer, input projections, weight gradients, output
//! layer) plus, per step, one `[B,H]×[H,4H]` GEMM forward and one `[B,4H]×[4H,H]`
//! backward, on the `gemm` crate. Candle stays the reference: the tests compare this
//! kernel's loss and gradients with candle's autograd of [`super::Net`], and with finite
//! differences.
//!
//! Rows are time-major (`row = t·B + b`), so one step's rows are contiguous: the recurrent
//! GEMM accumulates straight into the gate buffer, and `dW_hh = Σ_t dA_tᵀ·h_{t−1}` is one
//! GEMM over rows shifted by one step, with no copies.
//!
//! A batch is split into fixed shards (the same split on any thread count, so results are
//! bit-identical with 1 or 2 threads); each shard runs the forward and backward of its
//! windows on its own buffers, and the shard gradients are summed in a fixed order.
use super::gemm::{Op, sgemm};
use super::model::LstmModel;
use firmware::nn::reference::LstmDims;

/// `exp(x)` for f32 in branch-free arithmetic the compiler vectorises (Cephes' `expf`
/// polynomial after range reduction; relative error ~2e-7). Inputs clamp to [−87, 88].
#[inline(always)]
fn exp(x: f32) -> f32 {
    const LOG2E: f32 = std::f32::consts::LOG2_E;
    const ROUND: f32 = 12_582_912.0; // 1.5·2^23: adding it rounds to an integer
    let x = x.clamp(-87.0, 88.0);
    let z = x * LOG2E + ROUND;
    let n = z - ROUND;
    let r = (x - n * 0.693_359_4) - n * -2.121_944_4e-4;
    let mut p = 1.987_569_1e-4f32;
    p = p * r + 1.398_199_9e-3;
    p = p * r + 8.333_452e-3;
    p = p * r + 4.166_579_6e-2;
    p = p * r + 0.166_666_65;
    p = p * r + 0.5;
    let e = p * r * r + r + 1.0;
    // z's low mantissa bits hold n: (n + 127) << 23 is 2^n.
    e * f32::from_bits(z.to_bits().wrapping_add(127) << 23)
}

/// Logistic sigmoid through [`exp`].
#[inline(always)]
pub fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + exp(-x))
}

/// `tanh(x) = 2σ(2x) − 1` through [`exp`]; absolute error ~2e-7, saturates to ±1.
#[inline(always)]
pub fn tanh(x: f32) -> f32 {
    2.0 / (1.0 + exp(-2.0 * x)) - 1.0
}

fn sigmoid_in_place(v: &mut [f32]) {
    for x in v {
        *x = sigmoid(*x);
    }
}

fn tanh_in_place(v: &mut [f32]) {
    for x in v {
        *x = tanh(*x);
    }
}

/// Offsets of the eight parameter tensors in the flat vector, in [`super::Net::vars`]'s
/// order (`input.weight`, `input.bias`, `lstm.weight_ih_l0`, `lstm.weight_hh_l0`,
/// `lstm.bias_ih_l0`, `lstm.bias_hh_l0`, `output.weight`, `output.bias`).
#[derive(Clone, Copy, Debug)]
struct Layout {
    at: [usize; 9],
}

impl Layout {
    fn new(d: LstmDims) -> Self {
        let (i, e, h, o) = (d.input, d.embed, d.hidden, d.output);
        let sizes = [e * i, e, 4 * h * e, 4 * h * h, 4 * h, 4 * h, o * h, o];
        let mut at = [0; 9];
        for k in 0..8 {
            at[k + 1] = at[k] + sizes[k];
        }
        Layout { at }
    }
    fn len(&self) -> usize {
        self.at[8]
    }
    fn get<'a>(&self, p: &'a [f32], k: usize) -> &'a [f32] {
        &p[self.at[k]..self.at[k + 1]]
    }
    fn get_mut<'a>(&self, p: &'a mut [f32], k: usize) -> &'a mut [f32] {
        &mut p[self.at[k]..self.at[k + 1]]
    }
}

const W_IN: usize = 0;
const B_IN: usize = 1;
const W_IH: usize = 2;
const W_HH: usize = 3;
const B_IH: usize = 4;
const B_HH: usize = 5;
const W_OUT: usize = 6;
const B_OUT: usize = 7;

/// Windows per shard: a batch of 50 is two shards of 25.
pub const SHARD: usize = 25;

/// One shard's buffers for `bs` windows of `t_len` steps (time-major rows).
#[derive(Debug, Default)]
struct Shard {
    bs: usize,
    /// Inputs `[T·bs, I]`.
    x: Vec<f32>,
    /// Targets of the loss steps `[W·bs, O]`.
    y_ref: Vec<f32>,
    /// tanh of the input layer `[T·bs, E]`.
    emb: Vec<f32>,
    /// Gate pre-activations, then activations i, f, g, o `[T·bs, 4H]`.
    acts: Vec<f32>,
    /// Cell states `[T·bs, H]`.
    cs: Vec<f32>,
    /// tanh of the cell states `[T·bs, H]`.
    tcs: Vec<f32>,
    /// Hidden states `[T·bs, H]`.
    hs: Vec<f32>,
    /// Outputs of the loss steps, then their gradient `[W·bs, O]`.
    y: Vec<f32>,
    /// Gradient w.r.t. the hidden states `[T·bs, H]`.
    dh: Vec<f32>,
    /// Gradient w.r.t. the gate pre-activations `[T·bs, 4H]`.
    dgx: Vec<f32>,
    /// Gradient w.r.t. the embedding, then its pre-activation `[T·bs, E]`.
    demb: Vec<f32>,
    /// Cell-state gradient carried backwards `[bs, H]`.
    dc: Vec<f32>,
    /// This shard's parameter gradient (flat).
    grad: Vec<f32>,
    /// `H` zeros: the cell state before the first step.
    zeros: Vec<f32>,
    /// Sum of squared errors of the last forward.
    sse: f64,
}

fn resize(v: &mut Vec<f32>, n: usize) {
    v.resize(n, 0.0);
}

/// Shapes shared by the shard passes.
#[derive(Clone, Copy, Debug)]
struct Shape {
    d: LstmDims,
    t_len: usize,
    burn_in: usize,
}

impl Shard {
    fn prepare(&mut self, s: Shape, bs: usize, n_params: usize) {
        let LstmDims {
            input: i,
            embed: e,
            hidden: h,
            output: o,
        } = s.d;
        let rows = s.t_len * bs;
        let loss_rows = (s.t_len - s.burn_in) * bs;
        self.bs = bs;
        resize(&mut self.x, rows * i);
        resize(&mut self.y_ref, loss_rows * o);
        resize(&mut self.emb, rows * e);
        resize(&mut self.acts, rows * 4 * h);
        resize(&mut self.cs, rows * h);
        resize(&mut self.tcs, rows * h);
        resize(&mut self.hs, rows * h);
        resize(&mut self.y, loss_rows * o);
        resize(&mut self.dh, rows * h);
        resize(&mut self.dgx, rows * 4 * h);
        resize(&mut self.demb, rows * e);
        resize(&mut self.dc, bs * h);
        resize(&mut self.grad, n_params);
        resize(&mut self.zeros, h);
    }

    /// Forward over the shard's windows from the zero state; keeps the tape, sets `sse`.
    fn forward(&mut self, s: Shape, lay: &Layout, p: &[f32]) {
        let LstmDims {
            input: i,
            embed: e,
            hidden: h,
            output: o,
        } = s.d;
        let (bs, g4) = (self.bs, 4 * h);
        let rows = s.t_len * bs;
        // Input layer over every row at once: emb = tanh(x·W_inᵀ + b_in).
        let emb = &mut self.emb[..rows * e];
        emb[..e].copy_from_slice(lay.get(p, B_IN));
        affine_rows(emb, e, &self.x, lay.get(p, W_IN), i);
        tanh_in_place(emb);
        // Input projections for every step: acts = emb·W_ihᵀ + b_ih + b_hh.
        let acts = &mut self.acts[..rows * g4];
        let (bi, bh) = (lay.get(p, B_IH), lay.get(p, B_HH));
        for ((a, x), y) in acts[..g4].iter_mut().zip(bi).zip(bh) {
            *a = x + y;
        }
        affine_rows(acts, g4, emb, lay.get(p, W_IH), e);
        // The recurrence.
        let w_hh = lay.get(p, W_HH);
        let blk = bs * h;
        for t in 0..s.t_len {
            let (done_h, now_h) = self.hs.split_at_mut(t * blk);
            let a_t = &mut acts[t * bs * g4..][..bs * g4];
            if t > 0 {
                sgemm(
                    bs,
                    h,
                    g4,
                    1.0,
                    &done_h[(t - 1) * blk..],
                    Op::N,
                    w_hh,
                    Op::T,
                    1.0,
                    a_t,
                );
            }
            let (done_c, now_c) = self.cs.split_at_mut(t * blk);
            let c_prev = if t > 0 {
                Some(&done_c[(t - 1) * blk..])
            } else {
                None
            };
            let c_t = &mut now_c[..blk];
            let tc_t = &mut self.tcs[t * blk..][..blk];
            let h_t = &mut now_h[..blk];
            for b in 0..bs {
                let g = &mut a_t[b * g4..][..g4];
                sigmoid_in_place(&mut g[..2 * h]);
                tanh_in_place(&mut g[2 * h..3 * h]);
                sigmoid_in_place(&mut g[3 * h..]);
                let (ig, rest) = g.split_at(h);
                let (fg, rest) = rest.split_at(h);
                let (gg, og) = rest.split_at(h);
                let c = &mut c_t[b * h..][..h];
                match c_prev {
                    Some(cp) => {
                        for (j, c) in c.iter_mut().enumerate() {
                            *c = fg[j] * cp[b * h + j] + ig[j] * gg[j];
                        }
                    }
                    None => {
                        for (j, c) in c.iter_mut().enumerate() {
                            *c = ig[j] * gg[j];
                        }
                    }
                }
                let tc = &mut tc_t[b * h..][..h];
                for (x, c) in tc.iter_mut().zip(c.iter()) {
                    *x = tanh(*c);
                }
                for ((hv, o), tc) in h_t[b * h..][..h].iter_mut().zip(og).zip(tc.iter()) {
                    *hv = o * tc;
                }
            }
        }
        // Output layer on the loss steps.
        let tail = s.burn_in * blk;
        let loss_rows = (s.t_len - s.burn_in) * bs;
        let y = &mut self.y[..loss_rows * o];
        y[..o].copy_from_slice(lay.get(p, B_OUT));
        affine_rows(y, o, &self.hs[tail..], lay.get(p, W_OUT), h);
        self.sse = y
            .iter()
            .zip(&self.y_ref)
            .map(|(a, b)| ((a - b) as f64).powi(2))
            .sum();
    }

    /// Back-propagation through time of `scale · Σ (y − y_ref)²/2·…`: with `scale` =
    /// `1/(N·loss)` the gradient of the RMS loss. Overwrites `grad`.
    fn backward(&mut self, s: Shape, lay: &Layout, p: &[f32], scale: f32) {
        let LstmDims {
            input: i,
            embed: e,
            hidden: h,
            output: o,
        } = s.d;
        let (bs, g4) = (self.bs, 4 * h);
        let rows = s.t_len * bs;
        let blk = bs * h;
        let loss_rows = (s.t_len - s.burn_in) * bs;
        let tail = s.burn_in * blk;
        let grad = &mut self.grad;
        // dL/dy.
        let dy = &mut self.y[..loss_rows * o];
        for (a, b) in dy.iter_mut().zip(&self.y_ref) {
            *a = (*a - b) * scale;
        }
        // Output layer.
        sgemm(
            o,
            loss_rows,
            h,
            1.0,
            dy,
            Op::T,
            &self.hs[tail..rows * h],
            Op::N,
            0.0,
            lay.get_mut(grad, W_OUT),
        );
        col_sums(dy, o, lay.get_mut(grad, B_OUT));
        let dh = &mut self.dh[..rows * h];
        dh[..tail].fill(0.0);
        sgemm(
            loss_rows,
            o,
            h,
            1.0,
            dy,
            Op::N,
            lay.get(p, W_OUT),
            Op::N,
            0.0,
            &mut dh[tail..],
        );
        // Through time.
        let w_hh = lay.get(p, W_HH);
        let dc = &mut self.dc[..blk];
        dc.fill(0.0);
        let dgx = &mut self.dgx[..rows * g4];
        for t in (0..s.t_len).rev() {
            let a_t = &self.acts[t * bs * g4..][..bs * g4];
            let da_t = &mut dgx[t * bs * g4..][..bs * g4];
            let (dh_done, dh_t) = dh.split_at_mut(t * blk);
            let dh_t = &dh_t[..blk];
            for b in 0..bs {
                let g = &a_t[b * g4..][..g4];
                let da = &mut da_t[b * g4..][..g4];
                let r = t * blk + b * h;
                let tc = &self.tcs[r..][..h];
                let dhb = &dh_t[b * h..][..h];
                let dcb = &mut dc[b * h..][..h];
                let cp = if t > 0 {
                    &self.cs[r - blk..][..h]
                } else {
                    &self.zeros[..h]
                };
                let (dai, rest) = da.split_at_mut(h);
                let (daf, rest) = rest.split_at_mut(h);
                let (dag, dao) = rest.split_at_mut(h);
                for j in 0..h {
                    let (ig, fg, gg, og) = (g[j], g[h + j], g[2 * h + j], g[3 * h + j]);
                    let d_o = dhb[j] * tc[j];
                    let dcj = dcb[j] + dhb[j] * og * (1.0 - tc[j] * tc[j]);
                    dai[j] = dcj * gg * ig * (1.0 - ig);
                    daf[j] = dcj * cp[j] * fg * (1.0 - fg);
                    dag[j] = dcj * ig * (1.0 - gg * gg);
                    dao[j] = d_o * og * (1.0 - og);
                    dcb[j] = dcj * fg;
                }
            }
            if t > 0 {
                sgemm(
                    bs,
                    g4,
                    h,
                    1.0,
                    da_t,
                    Op::N,
                    w_hh,
                    Op::N,
                    1.0,
                    &mut dh_done[(t - 1) * blk..],
                );
            }
        }
        // Weight gradients over all rows at once.
        sgemm(
            g4,
            (s.t_len - 1) * bs,
            h,
            1.0,
            &dgx[bs * g4..],
            Op::T,
            &self.hs[..(rows - bs) * h],
            Op::N,
            0.0,
            lay.get_mut(grad, W_HH),
        );
        col_sums(dgx, g4, lay.get_mut(grad, B_IH));
        let (lo, hi) = grad.split_at_mut(lay.at[B_HH]);
        hi[..g4].copy_from_slice(&lo[lay.at[B_IH]..][..g4]);
        let emb = &self.emb[..rows * e];
        sgemm(
            g4,
            rows,
            e,
            1.0,
            dgx,
            Op::T,
            emb,
            Op::N,
            0.0,
            lay.get_mut(grad, W_IH),
        );
        let demb = &mut self.demb[..rows * e];
        sgemm(
            rows,
            g4,
            e,
            1.0,
            dgx,
            Op::N,
            lay.get(p, W_IH),
            Op::N,
            0.0,
            demb,
        );
        for (d, v) in demb.iter_mut().zip(emb) {
            *d *= 1.0 - v * v;
        }
        sgemm(
            e,
            rows,
            i,
            1.0,
            demb,
            Op::T,
            &self.x[..rows * i],
            Op::N,
            0.0,
            lay.get_mut(grad, W_IN),
        );
        col_sums(demb, e, lay.get_mut(grad, B_IN));
    }
}

/// A dense layer over many rows: `out[r] = bias + x[r]·wᵀ` for every row of `out`
/// (`n` columns), where `bias` is what `out`'s first row holds on entry, `x` is
/// `rows × k` and `w` is `n × k` (PyTorch's layout).
fn affine_rows(out: &mut [f32], n: usize, x: &[f32], w: &[f32], k: usize) {
    let (first, rest) = out.split_at_mut(n);
    for r in rest.chunks_exact_mut(n) {
        r.copy_from_slice(first);
    }
    sgemm(out.len() / n, k, n, 1.0, x, Op::N, w, Op::T, 1.0, out);
}

/// `out[j] = Σ_r m[r][j]` for a row-major matrix with `n` columns.
fn col_sums(m: &[f32], n: usize, out: &mut [f32]) {
    out.fill(0.0);
    for r in m.chunks_exact(n) {
        for (o, v) in out.iter_mut().zip(r) {
            *o += v;
        }
    }
}

/// Adam's hyper-parameters (candle's `ParamsAdamW` defaults with weight decay 0).
#[derive(Clone, Copy, Debug)]
pub struct Adam {
    /// Learning rate.
    pub lr: f64,
    /// First-moment decay.
    pub beta1: f64,
    /// Second-moment decay.
    pub beta2: f64,
    /// Denominator offset.
    pub eps: f64,
}

impl Adam {
    /// Adam with candle's defaults and learning rate `lr`.
    pub fn new(lr: f64) -> Self {
        Adam {
            lr,
            beta1: 0.9,
            beta2: 0.999,
            eps: 1e-8,
        }
    }
}

/// The trainable network on flat buffers (see the module docs).
#[derive(Debug)]
pub struct FusedNet {
    /// Sizes.
    pub dims: LstmDims,
    lay: Layout,
    /// All parameters, flat, in [`super::Net::vars`]'s order and PyTorch layouts.
    params: Vec<f32>,
    grad: Vec<f32>,
    m1: Vec<f32>,
    m2: Vec<f32>,
    step_t: i32,
    shards: Vec<Shard>,
    threads: usize,
}

/// Normalised windows for [`FusedNet`]: inputs `[n, burn_in + window, I]` and targets of
/// the loss steps `[n, window, O]`, each window contiguous.
#[derive(Clone, Copy, Debug)]
pub struct WindowSet<'a> {
    /// Inputs.
    pub x: &'a [f32],
    /// Targets.
    pub y: &'a [f32],
    /// Steps per window (burn-in included).
    pub len: usize,
    /// Steps at the start of each window outside the loss.
    pub burn_in: usize,
}

impl FusedNet {
    /// The network with `m`'s weights; `threads` (≥ 1) run the shards of a batch.
    pub fn from_model(m: &LstmModel, threads: usize) -> Self {
        let lay = Layout::new(m.dims);
        let mut params = Vec::with_capacity(lay.len());
        for v in [
            &m.w_in, &m.b_in, &m.w_ih, &m.w_hh, &m.b_ih, &m.b_hh, &m.w_out, &m.b_out,
        ] {
            params.extend_from_slice(v);
        }
        assert_eq!(
            params.len(),
            lay.len(),
            "model tensors do not match its dims"
        );
        FusedNet {
            dims: m.dims,
            lay,
            grad: vec![0.0; lay.len()],
            m1: vec![0.0; lay.len()],
            m2: vec![0.0; lay.len()],
            params,
            step_t: 0,
            shards: Vec::new(),
            threads: threads.max(1),
        }
    }

    /// Copies the weights into `m`.
    pub fn store(&self, m: &mut LstmModel) {
        let p = &self.params;
        let g = |k| self.lay.get(p, k).to_vec();
        m.w_in = g(W_IN);
        m.b_in = g(B_IN);
        m.w_ih = g(W_IH);
        m.w_hh = g(W_HH);
        m.b_ih = g(B_IH);
        m.b_hh = g(B_HH);
        m.w_out = g(W_OUT);
        m.b_out = g(B_OUT);
    }

    /// The flat gradient of the last [`FusedNet::loss_and_grad`] (tensor order as in
    /// [`super::Net::vars`]).
    pub fn grad(&self) -> Vec<Vec<f32>> {
        (0..8)
            .map(|k| self.lay.get(&self.grad, k).to_vec())
            .collect()
    }

    fn shape(&self, w: &WindowSet) -> Shape {
        Shape {
            d: self.dims,
            t_len: w.len,
            burn_in: w.burn_in,
        }
    }

    /// Gathers windows `idx` into the shards (time-major) and runs their forwards;
    /// returns the total squared error and the count of loss elements.
    fn forward(&mut self, w: &WindowSet, idx: &[usize]) -> (f64, usize) {
        let s = self.shape(w);
        let (i, o) = (self.dims.input, self.dims.output);
        let wl = w.len - w.burn_in;
        let n_shards = idx.len().div_ceil(SHARD);
        if self.shards.len() < n_shards {
            self.shards.resize_with(n_shards, Shard::default);
        }
        let n_params = self.lay.len();
        for (sh, ids) in self.shards.iter_mut().zip(idx.chunks(SHARD)) {
            let bs = ids.len();
            sh.prepare(s, bs, n_params);
            for (b, &k) in ids.iter().enumerate() {
                let xw = &w.x[k * w.len * i..][..w.len * i];
                for t in 0..w.len {
                    sh.x[(t * bs + b) * i..][..i].copy_from_slice(&xw[t * i..][..i]);
                }
                let yw = &w.y[k * wl * o..][..wl * o];
                for t in 0..wl {
                    sh.y_ref[(t * bs + b) * o..][..o].copy_from_slice(&yw[t * o..][..o]);
                }
            }
        }
        let (lay, p) = (self.lay, &self.params);
        let active = &mut self.shards[..n_shards];
        run_shards(active, self.threads, |sh| sh.forward(s, &lay, p));
        let sse = active.iter().map(|sh| sh.sse).sum();
        (sse, idx.len() * wl * o)
    }

    /// RMS loss of the windows `idx` (normalised units), forward only.
    pub fn loss(&mut self, w: &WindowSet, idx: &[usize]) -> f64 {
        let (sse, n) = self.forward(w, idx);
        (sse / n.max(1) as f64).sqrt()
    }

    /// RMS loss of windows `idx` and its gradient (kept for [`FusedNet::grad`] and
    /// [`FusedNet::step`]).
    pub fn loss_and_grad(&mut self, w: &WindowSet, idx: &[usize]) -> f64 {
        let (sse, n) = self.forward(w, idx);
        let loss = (sse / n.max(1) as f64).sqrt();
        let scale = if loss > 0.0 {
            (1.0 / (n as f64 * loss)) as f32
        } else {
            0.0
        };
        let s = self.shape(w);
        let n_shards = idx.len().div_ceil(SHARD);
        let (lay, p) = (self.lay, &self.params);
        let active = &mut self.shards[..n_shards];
        run_shards(active, self.threads, |sh| sh.backward(s, &lay, p, scale));
        self.grad.copy_from_slice(&active[0].grad);
        for sh in &active[1..] {
            for (g, x) in self.grad.iter_mut().zip(&sh.grad) {
                *g += x;
            }
        }
        loss
    }

    /// Clips the gradient to global norm `clip` (0: off) and takes one Adam step
    /// (candle's AdamW arithmetic, weight decay 0).
    pub fn step(&mut self, adam: &Adam, clip: f64) {
        if clip > 0.0 {
            let norm = self.grad.iter().map(|g| (g * g) as f64).sum::<f64>().sqrt();
            if norm > clip {
                let k = (clip / norm) as f32;
                self.grad.iter_mut().for_each(|g| *g *= k);
            }
        }
        self.step_t += 1;
        let (b1, b2) = (adam.beta1 as f32, adam.beta2 as f32);
        let scale_m = (1.0 / (1.0 - adam.beta1.powi(self.step_t))) as f32;
        let scale_v = (1.0 / (1.0 - adam.beta2.powi(self.step_t))) as f32;
        let (lr, eps) = (adam.lr as f32, adam.eps as f32);
        for (((p, g), m), v) in self
            .params
            .iter_mut()
            .zip(&self.grad)
            .zip(&mut self.m1)
            .zip(&mut self.m2)
        {
            *m = *m * b1 + g * (1.0 - b1);
            *v = *v * b2 + g * g * (1.0 - b2);
            *p -= (*m * scale_m) / ((*v * scale_v).sqrt() + eps) * lr;
        }
    }
}

/// Runs `f` on every shard, on up to `threads` threads (each shard is independent).
fn run_shards(shards: &mut [Shard], threads: usize, f: impl Fn(&mut Shard) + Sync) {
    if threads <= 1 || shards.len() <= 1 {
        shards.iter_mut().for_each(&f);
        return;
    }
    let per = shards.len().div_ceil(threads);
    std::thread::scope(|sc| {
        let mut chunks = shards.chunks_mut(per);
        let first = chunks.next();
        for c in chunks {
            let f = &f;
            sc.spawn(move || c.iter_mut().for_each(f));
        }
        if let Some(c) = first {
            c.iter_mut().for_each(&f);
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Net;
    use candle_core::{Device, Tensor};

    /// A small model, 30 windows (two shards: 25 + 5) of 4 + 7 steps.
    fn setup() -> (LstmModel, Vec<f32>, Vec<f32>, usize, usize) {
        let dims = LstmDims {
            input: 3,
            embed: 5,
            hidden: 4,
            output: 2,
        };
        let m = LstmModel::init(dims, 7);
        let (n, len, burn) = (30, 11, 4);
        let x: Vec<f32> = (0..n * len * 3)
            .map(|k| (k as f32 * 0.37).sin() * 1.3)
            .collect();
        let y: Vec<f32> = (0..n * (len - burn) * 2)
            .map(|k| (k as f32 * 0.21).cos())
            .collect();
        (m, x, y, len, burn)
    }

    /// Loss and gradients against candle's autograd of [`Net`] (candle ops around the
    /// `FusedLstm` op, itself checked against candle's autograd of plain ops).
    #[test]
    fn loss_and_gradients_match_candle_autograd() -> anyhow::Result<()> {
        let (m, x, y, len, burn) = setup();
        let n = 30;
        let idx: Vec<usize> = (0..n).rev().collect();
        let set = WindowSet {
            x: &x,
            y: &y,
            len,
            burn_in: burn,
        };
        let mut f = FusedNet::from_model(&m, 1);
        let loss = f.loss_and_grad(&set, &idx);
        let ours = f.grad();

        let dev = Device::Cpu;
        let net = Net::from_model(&m, &dev)?;
        let xs: Vec<f32> = idx
            .iter()
            .flat_map(|&k| x[k * len * 3..][..len * 3].to_vec())
            .collect();
        let ys: Vec<f32> = idx
            .iter()
            .flat_map(|&k| y[k * (len - burn) * 2..][..(len - burn) * 2].to_vec())
            .collect();
        let xt = Tensor::from_vec(xs, (n, len, 3), &dev)?;
        let yt = Tensor::from_vec(ys, (n, len - burn, 2), &dev)?;
        let pred = net.forward(&xt)?.narrow(1, burn, len - burn)?;
        let l = (pred - yt)?.sqr()?.mean_all()?.sqrt()?;
        let want = l.to_scalar::<f32>()? as f64;
        assert!((loss - want).abs() < 1e-6 * want, "loss {loss} vs {want}");
        let grads = l.backward()?;
        for (k, v) in net.vars.iter().enumerate() {
            let g = grads
                .get(v.as_tensor())
                .unwrap()
                .flatten_all()?
                .to_vec1::<f32>()?;
            let scale = g.iter().fold(1e-3f32, |a, b| a.max(b.abs()));
            for (a, b) in ours[k].iter().zip(&g) {
                assert!(
                    (a - b).abs() <= 1e-5 * scale,
                    "tensor {k}: {a} vs candle {b} (scale {scale})"
                );
            }
        }
        // Two threads: the same shards, the same bits.
        let mut f2 = FusedNet::from_model(&m, 2);
        assert_eq!(f2.loss_and_grad(&set, &idx), loss);
        assert_eq!(f2.grad(), ours);
        Ok(())
    }

    /// Central finite differences of the loss against the backward pass, on every
    /// parameter tensor (the largest-gradient elements of each).
    #[test]
    fn gradients_match_finite_differences() {
        let (m, x, y, len, burn) = setup();
        let idx: Vec<usize> = (0..30).collect();
        let set = WindowSet {
            x: &x,
            y: &y,
            len,
            burn_in: burn,
        };
        let mut f = FusedNet::from_model(&m, 1);
        f.loss_and_grad(&set, &idx);
        let grad = f.grad();
        let lay = f.lay;
        for (k, g) in grad.iter().enumerate() {
            let mut order: Vec<usize> = (0..g.len()).collect();
            order.sort_by(|a, b| g[*b].abs().total_cmp(&g[*a].abs()));
            for &j in order.iter().take(3) {
                let at = lay.at[k] + j;
                let p0 = f.params[at];
                let h = 1e-2f32;
                f.params[at] = p0 + h;
                let lp = f.loss(&set, &idx);
                f.params[at] = p0 - h;
                let lm = f.loss(&set, &idx);
                f.params[at] = p0;
                let fd = (lp - lm) / (2.0 * h as f64);
                let err = (fd - g[j] as f64).abs();
                assert!(
                    err <= 2e-2 * fd.abs().max(1e-2),
                    "tensor {k} element {j}: backward {} vs finite difference {fd}",
                    g[j]
                );
            }
        }
    }

    /// One Adam step equals candle's AdamW (weight decay 0) on the same gradient.
    #[test]
    fn adam_step_matches_candle_adamw() -> anyhow::Result<()> {
        use candle_nn::{AdamW, Optimizer, ParamsAdamW};
        let (m, x, y, len, burn) = setup();
        let idx: Vec<usize> = (0..30).collect();
        let set = WindowSet {
            x: &x,
            y: &y,
            len,
            burn_in: burn,
        };
        let mut f = FusedNet::from_model(&m, 1);
        let dev = Device::Cpu;
        let net = Net::from_model(&m, &dev)?;
        let mut opt = AdamW::new(
            net.vars.clone(),
            ParamsAdamW {
                lr: 0.01,
                weight_decay: 0.0,
                ..Default::default()
            },
        )?;
        for _ in 0..3 {
            f.loss_and_grad(&set, &idx);
            let g = f.grad();
            // (GradStore has no public constructor: take one from a backward, overwrite it.)
            let mut store = net.vars[0].as_tensor().sum_all()?.backward()?;
            for (v, gk) in net.vars.iter().zip(&g) {
                store.insert(v.as_tensor(), Tensor::from_slice(gk, v.shape(), &dev)?);
            }
            opt.step(&store)?;
            f.step(&Adam::new(0.01), 0.0);
            let mut mine = m.clone();
            f.store(&mut mine);
            let mut theirs = m.clone();
            net.store(&mut theirs)?;
            for ((a, b), name) in mine
                .tensors()
                .iter()
                .zip(theirs.tensors().iter())
                .map(|(a, b)| (a.1, b.1))
                .zip(mine.tensors().map(|t| t.0))
            {
                for (p, q) in a.iter().zip(b) {
                    assert!(
                        (p - q).abs() <= 1e-6 * p.abs().max(1.0),
                        "{name}: {p} vs {q}"
                    );
                }
            }
        }
        Ok(())
    }

    #[test]
    fn fast_activations_match_std() {
        let mut worst = (0.0f32, 0.0f32, 0.0f32);
        for k in -40_000..=40_000 {
            let x = k as f32 * 1e-3;
            worst.0 = worst.0.max(((exp(x) - x.exp()) / x.exp()).abs());
            worst.1 = worst.1.max((sigmoid(x) - 1.0 / (1.0 + (-x).exp())).abs());
            worst.2 = worst.2.max((tanh(x) - x.tanh()).abs());
        }
        assert!(
            worst.0 < 5e-7 && worst.1 < 2e-7 && worst.2 < 5e-7,
            "{worst:?}"
        );
        assert_eq!(tanh(100.0), 1.0);
        assert_eq!(tanh(-100.0), -1.0);
        assert!(sigmoid(-200.0) >= 0.0 && sigmoid(200.0) == 1.0);
        assert!(exp(f32::NAN).is_nan());
    }
}
