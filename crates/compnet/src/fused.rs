//! A fused LSTM recurrence as a candle custom op with a hand-written backward pass
//! (back-propagation through time), on GEMMs.
//!
//! The op takes the input projections `gx = W_ih·e + b_ih + b_hh` for the whole window,
//! `[B, T, 4H]`, and the recurrent weights `W_hh` `[4H, H]`, starts from the zero state
//! and returns every hidden state `[B, T, H]`. Candle's autograd handles everything
//! around it (input layer, projections, output layer, loss). Gate order i, f, g, o.
//!
//! Forward per step: one `[B,H]×[H,4H]` GEMM plus the cell's element-wise update.
//! Backward recomputes the forward (the op keeps no tape), then per step one
//! `[B,4H]×[4H,H]` GEMM for `dh`, and a single `[4H, B·T]×[B·T, H]` GEMM for `dW_hh`.
use super::gemm::{Op, sgemm};
use candle_core::{CpuStorage, CustomOp2, Layout, Result, Shape, Tensor};

/// The fused LSTM recurrence (see the module docs).
#[derive(Clone, Copy, Debug)]
pub struct FusedLstm;

fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}

/// tanh through one `exp` (libm's `tanhf` goes through `expm1f` and was 30 % of an epoch
/// in a profile); absolute error ~1e-7, saturates to ±1 without NaN.
fn tanh(x: f32) -> f32 {
    2.0 * sigmoid(2.0 * x) - 1.0
}

fn contiguous<'a>(s: &'a CpuStorage, l: &Layout) -> Result<&'a [f32]> {
    let data = s.as_slice::<f32>()?;
    match l.contiguous_offsets() {
        Some((a, b)) => Ok(&data[a..b]),
        None => candle_core::bail!("fused LSTM: non-contiguous input"),
    }
}

/// Forward over a window. Returns hidden states `[B,T,H]`; with `tape`, also the gate
/// activations `[B,T,4H]` and cell states `[B,T,H]` the backward pass needs.
fn forward(
    gx: &[f32],
    w_hh: &[f32],
    b: usize,
    t_len: usize,
    h: usize,
    tape: bool,
) -> (Vec<f32>, Vec<f32>, Vec<f32>) {
    let g4 = 4 * h;
    let mut hs = vec![0.0f32; b * t_len * h];
    let mut acts = if tape {
        vec![0.0f32; b * t_len * g4]
    } else {
        Vec::new()
    };
    let mut cs = if tape {
        vec![0.0f32; b * t_len * h]
    } else {
        Vec::new()
    };
    let mut h_prev = vec![0.0f32; b * h];
    let mut c = vec![0.0f32; b * h];
    let mut gates = vec![0.0f32; b * g4];
    for t in 0..t_len {
        for bi in 0..b {
            gates[bi * g4..][..g4].copy_from_slice(&gx[(bi * t_len + t) * g4..][..g4]);
        }
        sgemm(b, h, g4, 1.0, &h_prev, Op::N, w_hh, Op::T, 1.0, &mut gates);
        for bi in 0..b {
            let gr = &mut gates[bi * g4..][..g4];
            let cr = &mut c[bi * h..][..h];
            let hr = &mut h_prev[bi * h..][..h];
            for j in 0..h {
                let i = sigmoid(gr[j]);
                let f = sigmoid(gr[h + j]);
                let g = tanh(gr[2 * h + j]);
                let o = sigmoid(gr[3 * h + j]);
                cr[j] = f * cr[j] + i * g;
                hr[j] = o * tanh(cr[j]);
                if tape {
                    gr[j] = i;
                    gr[h + j] = f;
                    gr[2 * h + j] = g;
                    gr[3 * h + j] = o;
                }
            }
            hs[(bi * t_len + t) * h..][..h].copy_from_slice(hr);
            if tape {
                acts[(bi * t_len + t) * g4..][..g4].copy_from_slice(gr);
                cs[(bi * t_len + t) * h..][..h].copy_from_slice(cr);
            }
        }
    }
    (hs, acts, cs)
}

/// Back-propagation through time. Returns `(d gx [B,T,4H], d W_hh [4H,H])`.
fn backward(
    gx: &[f32],
    w_hh: &[f32],
    d_hs: &[f32],
    b: usize,
    t_len: usize,
    h: usize,
) -> (Vec<f32>, Vec<f32>) {
    let g4 = 4 * h;
    let (hs, acts, cs) = forward(gx, w_hh, b, t_len, h, true);
    let mut d_gx = vec![0.0f32; b * t_len * g4];
    let mut dh_next = vec![0.0f32; b * h];
    let mut dc_next = vec![0.0f32; b * h];
    let mut d_a = vec![0.0f32; b * g4];
    for t in (0..t_len).rev() {
        for bi in 0..b {
            let at = &acts[(bi * t_len + t) * g4..][..g4];
            let row = (bi * t_len + t) * h;
            for j in 0..h {
                let (i, f, g, o) = (at[j], at[h + j], at[2 * h + j], at[3 * h + j]);
                let c = cs[row + j];
                let c_prev = if t > 0 { cs[row - h + j] } else { 0.0 };
                let tc = tanh(c);
                let dh = d_hs[row + j] + dh_next[bi * h + j];
                let d_o = dh * tc;
                let dc = dc_next[bi * h + j] + dh * o * (1.0 - tc * tc);
                let da = &mut d_a[bi * g4..][..g4];
                da[j] = dc * g * i * (1.0 - i);
                da[h + j] = dc * c_prev * f * (1.0 - f);
                da[2 * h + j] = dc * i * (1.0 - g * g);
                da[3 * h + j] = d_o * o * (1.0 - o);
                dc_next[bi * h + j] = dc * f;
            }
            d_gx[(bi * t_len + t) * g4..][..g4].copy_from_slice(&d_a[bi * g4..][..g4]);
        }
        sgemm(b, g4, h, 1.0, &d_a, Op::N, w_hh, Op::N, 0.0, &mut dh_next);
    }
    // dW_hh = Σ_t dA_tᵀ · h_{t-1}: one GEMM over all (b, t) rows with h shifted by one step.
    let mut h_prev = vec![0.0f32; b * t_len * h];
    for bi in 0..b {
        for t in 1..t_len {
            h_prev[(bi * t_len + t) * h..][..h]
                .copy_from_slice(&hs[(bi * t_len + t - 1) * h..][..h]);
        }
    }
    let mut d_w = vec![0.0f32; g4 * h];
    sgemm(
        g4,
        b * t_len,
        h,
        1.0,
        &d_gx,
        Op::T,
        &h_prev,
        Op::N,
        0.0,
        &mut d_w,
    );
    (d_gx, d_w)
}

fn dims(l_gx: &Layout, l_w: &Layout) -> Result<(usize, usize, usize)> {
    let (b, t_len, g4) = l_gx.shape().dims3()?;
    let (g4w, h) = l_w.shape().dims2()?;
    if g4 != 4 * h || g4w != g4 {
        candle_core::bail!(
            "fused LSTM: gx {:?} and w_hh {:?} do not match",
            l_gx.shape(),
            l_w.shape()
        );
    }
    Ok((b, t_len, h))
}

impl CustomOp2 for FusedLstm {
    fn name(&self) -> &'static str {
        "fused-lstm"
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
    ) -> Result<(CpuStorage, Shape)> {
        let (b, t_len, h) = dims(l1, l2)?;
        let (hs, _, _) = forward(contiguous(s1, l1)?, contiguous(s2, l2)?, b, t_len, h, false);
        Ok((CpuStorage::F32(hs), Shape::from((b, t_len, h))))
    }

    fn bwd(
        &self,
        gx: &Tensor,
        w_hh: &Tensor,
        _res: &Tensor,
        grad: &Tensor,
    ) -> Result<(Option<Tensor>, Option<Tensor>)> {
        let (b, t_len, g4) = gx.dims3()?;
        let h = g4 / 4;
        let gx_v = gx.flatten_all()?.to_vec1::<f32>()?;
        let w_v = w_hh.flatten_all()?.to_vec1::<f32>()?;
        let d_v = grad.flatten_all()?.to_vec1::<f32>()?;
        let (d_gx, d_w) = backward(&gx_v, &w_v, &d_v, b, t_len, h);
        Ok((
            Some(Tensor::from_vec(d_gx, (b, t_len, g4), gx.device())?),
            Some(Tensor::from_vec(d_w, (g4, h), w_hh.device())?),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::{Device, Var};

    /// The same recurrence in candle's own ops (autograd by candle), as the reference.
    fn reference(gx: &Tensor, w_hh: &Tensor) -> Result<Tensor> {
        let (b, t_len, g4) = gx.dims3()?;
        let h = g4 / 4;
        let mut hp = Tensor::zeros((b, h), candle_core::DType::F32, gx.device())?;
        let mut c = hp.clone();
        let mut out = Vec::new();
        for t in 0..t_len {
            let g = (gx.narrow(1, t, 1)?.squeeze(1)? + hp.matmul(&w_hh.t()?)?)?;
            let i = candle_nn::ops::sigmoid(&g.narrow(1, 0, h)?)?;
            let f = candle_nn::ops::sigmoid(&g.narrow(1, h, h)?)?;
            let gg = g.narrow(1, 2 * h, h)?.tanh()?;
            let o = candle_nn::ops::sigmoid(&g.narrow(1, 3 * h, h)?)?;
            c = ((f * &c)? + (i * gg)?)?;
            hp = (o * c.tanh()?)?;
            out.push(hp.unsqueeze(1)?);
        }
        Tensor::cat(&out, 1)
    }

    #[test]
    fn forward_and_gradients_match_candle_autograd() -> Result<()> {
        let dev = Device::Cpu;
        let (b, t_len, h) = (3, 7, 5);
        let gxv: Vec<f32> = (0..b * t_len * 4 * h)
            .map(|i| (i as f32 * 0.731).sin() * 1.5)
            .collect();
        let wv: Vec<f32> = (0..4 * h * h)
            .map(|i| (i as f32 * 0.377).cos() * 0.6)
            .collect();
        let gx = Var::from_tensor(&Tensor::from_vec(gxv, (b, t_len, 4 * h), &dev)?)?;
        let w = Var::from_tensor(&Tensor::from_vec(wv, (4 * h, h), &dev)?)?;
        let weights = Tensor::arange(0f32, (b * t_len * h) as f32, &dev)?
            .reshape((b, t_len, h))?
            .sin()?;
        let ours = gx.as_tensor().apply_op2(w.as_tensor(), FusedLstm)?;
        let theirs = reference(gx.as_tensor(), w.as_tensor())?;
        let diff = (&ours - &theirs)?.abs()?.max_all()?.to_scalar::<f32>()?;
        assert!(diff < 1e-6, "forward differs by {diff}");
        let g1 = (ours * &weights)?.sum_all()?.backward()?;
        let g2 = (theirs * &weights)?.sum_all()?.backward()?;
        for v in [&gx, &w] {
            let a = g1.get(v.as_tensor()).unwrap();
            let r = g2.get(v.as_tensor()).unwrap();
            let d = (a - r)?.abs()?.max_all()?.to_scalar::<f32>()?;
            let scale = r.abs()?.max_all()?.to_scalar::<f32>()?;
            assert!(
                d <= 1e-5 * scale.max(1.0),
                "gradient differs by {d} (scale {scale})"
            );
        }
        Ok(())
    }
}
