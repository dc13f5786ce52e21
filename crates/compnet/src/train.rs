//! Training: seeded initialisation, windows of a contiguous training block with a burn-in
//! prefix, Adam, RMS loss, gradient clipping, early stopping, on the fused network kernel
//! of [`super::fused_net`] (checked against candle's autograd in its tests).
//!
//! **Streaming robustness.** Each training window starts from the zero state, but a drive
//! runs one unbroken stream. Every window is therefore preceded by `burn_in` steps that
//! the network sees but the loss ignores, so it learns to predict from a state that has
//! forgotten its zero start; evaluation streams the firmware step over whole sequences.
use super::data::{Sequence, mean_std};
use super::fused_net::{Adam, FusedNet, WindowSet};
use super::model::LstmModel;
use anyhow::{Result, bail};
use firmware::nn::format::InputActivation;
use firmware::nn::reference::LstmDims;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Learning rates tried when none is given (the paper's 0.05 first); the one with the
/// lowest validation loss after [`TrainConfig::lr_trial_epochs`] wins.
pub const LR_CANDIDATES: [f64; 4] = [0.05, 0.01, 0.003, 0.001];

/// Training options; the defaults are the paper's Table 1 where it gives one.
#[derive(Clone, Debug)]
pub struct TrainConfig {
    /// Input-layer width (paper: 64 per the quantisation issue's 9 → 64 → 64 → 3).
    pub embed: usize,
    /// LSTM cells (paper: 64).
    pub hidden: usize,
    /// Steps per window that enter the loss (paper: 100).
    pub window: usize,
    /// Steps before each window that the network sees but the loss ignores.
    pub burn_in: usize,
    /// Windows per batch (paper: 50).
    pub batch: usize,
    /// Learning rate; `None`: chosen by validation among [`LR_CANDIDATES`].
    pub lr: Option<f64>,
    /// Epochs per candidate when choosing the learning rate.
    pub lr_trial_epochs: usize,
    /// Maximum epochs.
    pub epochs: usize,
    /// Early stopping: epochs without a better validation loss before stopping.
    pub patience: usize,
    /// Global gradient-norm clip (0: off).
    pub clip_norm: f64,
    /// Validation block fraction (the block after training).
    pub val_fraction: f64,
    /// Test block fraction (the last block).
    pub test_fraction: f64,
    /// Seed of the initialisation, window phases and order.
    pub seed: u64,
    /// Show a progress bar.
    pub progress: bool,
    /// Threads for the shards of a batch (results do not depend on it: the shards are
    /// fixed, see [`super::fused_net`]).
    pub threads: usize,
}

impl TrainConfig {
    /// Sizes and counts that training needs to be at least 1, a finite positive learning
    /// rate and a finite clipping norm (0: off); the error names the option.
    pub fn check(&self) -> Result<()> {
        for (name, v) in [
            ("embed", self.embed),
            ("hidden", self.hidden),
            ("window", self.window),
            ("batch", self.batch),
            ("epochs", self.epochs),
        ] {
            if v == 0 {
                bail!("--{name} must be at least 1");
            }
        }
        for (name, v) in [("embed", self.embed), ("hidden", self.hidden)] {
            if v > super::model::MAX_LAYER_WIDTH {
                bail!(
                    "--{name} {v}: at most {} (MAX_LAYER_WIDTH)",
                    super::model::MAX_LAYER_WIDTH
                );
            }
        }
        if let Some(lr) = self.lr.filter(|lr| !(lr.is_finite() && *lr > 0.0)) {
            bail!("--lr must be a finite number above 0 (got {lr})");
        }
        if !(self.clip_norm.is_finite() && self.clip_norm >= 0.0) {
            bail!(
                "--clip must be a finite number, 0 or above (got {})",
                self.clip_norm
            );
        }
        Ok(())
    }
}

impl Default for TrainConfig {
    fn default() -> Self {
        TrainConfig {
            embed: 64,
            hidden: 64,
            window: 100,
            burn_in: 50,
            batch: 50,
            lr: None,
            lr_trial_epochs: 5,
            epochs: 200,
            patience: 20,
            clip_norm: 1.0,
            val_fraction: 0.15,
            test_fraction: 0.15,
            seed: 1,
            progress: true,
            threads: 1,
        }
    }
}

/// Per-epoch losses (RMS in normalised units).
#[derive(Clone, Debug, Default)]
pub struct History {
    /// Mean training loss per epoch.
    pub train: Vec<f64>,
    /// Validation loss per epoch.
    pub val: Vec<f64>,
    /// Epoch (0-based) of the kept weights.
    pub best_epoch: usize,
    /// Learning rate used.
    pub lr: f64,
    /// Validation loss of each learning-rate candidate tried, if any.
    pub lr_trials: Vec<(f64, f64)>,
}

/// Normalised windows `[n, burn_in + window, I]` and targets `[n, window, O]`.
struct Windows {
    x: Vec<f32>,
    y: Vec<f32>,
    count: usize,
}

fn windows(m: &LstmModel, seqs: &[&Sequence], cfg: &TrainConfig, phase: usize) -> Windows {
    let (i, o) = (m.dims.input, m.dims.output);
    let len = cfg.burn_in + cfg.window;
    let mut w = Windows {
        x: Vec::new(),
        y: Vec::new(),
        count: 0,
    };
    for s in seqs {
        let mut start = phase;
        while start + len <= s.len() {
            for t in start..start + len {
                for k in 0..i {
                    w.x.push((s.inputs[t][k] - m.input_mean[k]) / m.input_std[k]);
                }
            }
            for t in start + cfg.burn_in..start + len {
                for k in 0..o {
                    w.y.push((s.targets[t][k] - m.output_mean[k]) / m.output_std[k]);
                }
            }
            w.count += 1;
            start += cfg.window;
        }
    }
    w
}

impl Windows {
    fn set(&self, cfg: &TrainConfig) -> WindowSet<'_> {
        WindowSet {
            x: &self.x,
            y: &self.y,
            len: cfg.burn_in + cfg.window,
            burn_in: cfg.burn_in,
        }
    }
}

fn eval_loss(net: &mut FusedNet, w: &Windows, cfg: &TrainConfig) -> f64 {
    let idx: Vec<usize> = (0..w.count).collect();
    let set = w.set(cfg);
    let mut sq = 0.0;
    for chunk in idx.chunks(cfg.batch.max(1)) {
        let l = net.loss(&set, chunk);
        sq += l * l * chunk.len() as f64;
    }
    (sq / w.count.max(1) as f64).sqrt()
}

/// One epoch over shuffled windows; returns the mean training loss.
fn epoch(
    net: &mut FusedNet,
    adam: &Adam,
    w: &Windows,
    cfg: &TrainConfig,
    rng: &mut ChaCha8Rng,
) -> f64 {
    let mut idx: Vec<usize> = (0..w.count).collect();
    idx.shuffle(rng);
    let set = w.set(cfg);
    let mut total = 0.0;
    let mut n = 0;
    for chunk in idx.chunks(cfg.batch.max(1)) {
        total += net.loss_and_grad(&set, chunk);
        net.step(adam, cfg.clip_norm);
        n += 1;
    }
    total / n.max(1) as f64
}

/// A fresh model for `train` with normalisation from the training block only.
pub fn new_model(
    train: &Sequence,
    input_names: Vec<String>,
    output_names: Vec<String>,
    preset: &str,
    cfg: &TrainConfig,
) -> Result<LstmModel> {
    if train.is_empty() {
        bail!("the training block is empty");
    }
    cfg.check()?;
    let dims = LstmDims {
        input: train.inputs[0].len(),
        embed: cfg.embed,
        hidden: cfg.hidden,
        output: train.targets[0].len(),
    };
    let mut m = LstmModel::init(dims, cfg.seed);
    (m.input_mean, m.input_std) = mean_std(&train.inputs);
    (m.output_mean, m.output_std) = mean_std(&train.targets);
    m.input_names = input_names;
    m.output_names = output_names;
    m.preset = preset.to_string();
    Ok(m)
}

/// The training kernel (`FusedNet`) runs a tanh input layer: a linear one is refused
/// rather than trained as another network.
fn tanh_input_layer(init: &LstmModel) -> Result<()> {
    if init.input_activation != InputActivation::Tanh {
        bail!(
            "training runs a tanh input layer; this network's input layer is {} \
             (import it and export it as it is instead)",
            init.input_activation.name()
        );
    }
    Ok(())
}

fn run(
    init: &LstmModel,
    train: &[&Sequence],
    val: &[&Sequence],
    cfg: &TrainConfig,
    lr: f64,
    epochs: usize,
    show: bool,
) -> Result<(LstmModel, History)> {
    tanh_input_layer(init)?;
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed ^ 0x5eed);
    let mut net = FusedNet::from_model(init, cfg.threads);
    let adam = Adam::new(lr);
    let val_w = windows(init, val, cfg, 0);
    if val_w.count == 0 {
        bail!(
            "the validation block is shorter than one window ({} steps)",
            cfg.burn_in + cfg.window
        );
    }
    let bar = if show {
        indicatif::ProgressBar::new(epochs as u64)
    } else {
        indicatif::ProgressBar::hidden()
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template("epoch {pos}/{len} [{bar:30}] {msg} ETA {eta}")
            .map_err(|e| anyhow::anyhow!("{e}"))?
            .progress_chars("=> "),
    );
    let mut hist = History {
        lr,
        ..Default::default()
    };
    let mut best = (f64::INFINITY, init.clone());
    for ep in 0..epochs {
        let phase = rng.gen_range(0..cfg.window.max(1));
        let w = windows(init, train, cfg, phase);
        if w.count == 0 {
            bail!(
                "the training block is shorter than one window ({} steps)",
                cfg.burn_in + cfg.window
            );
        }
        let tl = epoch(&mut net, &adam, &w, cfg, &mut rng);
        let vl = eval_loss(&mut net, &val_w, cfg);
        hist.train.push(tl);
        hist.val.push(vl);
        if vl < best.0 {
            best.0 = vl;
            net.store(&mut best.1);
            hist.best_epoch = ep;
        }
        bar.set_message(format!(
            "train {tl:.4} val {vl:.4} best {:.4}@{}",
            best.0,
            hist.best_epoch + 1
        ));
        bar.inc(1);
        if !tl.is_finite() {
            break;
        }
        if ep - hist.best_epoch >= cfg.patience.max(1) {
            break;
        }
    }
    bar.finish();
    if !best.0.is_finite() {
        bail!("training diverged (no finite validation loss) at learning rate {lr}");
    }
    Ok((best.1, hist))
}

/// Trains `init` (from [`new_model`]) on the training sequences with early stopping on
/// the validation sequences; returns the best model and the loss history.
pub fn train(
    init: &LstmModel,
    train: &[&Sequence],
    val: &[&Sequence],
    cfg: &TrainConfig,
) -> Result<(LstmModel, History)> {
    cfg.check()?;
    let (lr, trials) = match cfg.lr {
        Some(lr) => (lr, Vec::new()),
        None => {
            let mut trials = Vec::new();
            for lr in LR_CANDIDATES {
                let v = match run(init, train, val, cfg, lr, cfg.lr_trial_epochs.max(1), false) {
                    Ok((_, h)) => h.val.iter().cloned().fold(f64::INFINITY, f64::min),
                    Err(_) => f64::INFINITY,
                };
                if cfg.progress {
                    eprintln!(
                        "learning rate {lr}: validation RMS {v:.4} after {} epochs",
                        cfg.lr_trial_epochs
                    );
                }
                trials.push((lr, v));
            }
            let best = trials
                .iter()
                .cloned()
                .fold((LR_CANDIDATES[0], f64::INFINITY), |a, b| {
                    if b.1 < a.1 { b } else { a }
                });
            (best.0, trials)
        }
    };
    let (m, mut h) = run(init, train, val, cfg, lr, cfg.epochs, cfg.progress)?;
    h.lr_trials = trials;
    Ok((m, h))
}

/// The `drive` preset's linear stage: per output, least squares (f64, column-scaled
/// SVD) of the target on `firmware::features::friction_features` of that joint's inputs
/// over every training step; `[O, 16]` row-major, as `LstmModel::linear` holds it.
pub fn fit_linear_stage(train: &[Sequence], outputs: usize) -> Result<Vec<f32>> {
    let mut w = Vec::with_capacity(outputs * firmware::features::FRICTION_FEATURES);
    for k in 0..outputs {
        let mut x = Vec::new();
        let mut y = Vec::new();
        for s in train {
            for (row, t) in s.inputs.iter().zip(&s.targets) {
                let inputs = firmware::features::joint_drive_inputs(row, outputs, k);
                let f = firmware::features::friction_features(&inputs);
                x.push(f.map(f64::from));
                y.push(f64::from(t[k]));
            }
        }
        w.extend(super::baseline::solve(&x, &y)?.iter().map(|&c| c as f32));
    }
    Ok(w)
}

/// Subtracts the linear stage `w` (from [`fit_linear_stage`]) from every target, so the
/// network learns what the linear stage leaves.
pub fn subtract_linear_stage(w: &[f32], seqs: &mut [Sequence]) {
    for s in seqs {
        for (row, t) in s.inputs.iter().zip(s.targets.iter_mut()) {
            for (y, c) in t.iter_mut().zip(super::model::linear_stage_nm(w, &[], row)) {
                *y -= c;
            }
        }
    }
}

/// Do-no-harm shrinkage of a residual network (targets whose model-only prediction is
/// 0: `feedforward`, `drive`): per output the gain `a` in [0, 1] that minimises the
/// squared error of `a * prediction` on the validation sequences (streamed as the
/// firmware runs them), folded into the output de-normalisation, so a network that
/// does not help on held-out runs fades towards the model alone. Returns the gains
/// (1 for outputs that are not residuals).
pub fn shrink_residual_outputs(m: &mut LstmModel, val: &[&Sequence]) -> Result<Vec<f32>> {
    let mut fit = GainFit::new(m.dims.output);
    fit.add(m, val)?;
    let gains = fit.gains();
    apply_output_gains(m, &gains);
    Ok(gains)
}

/// Scales output `k` of `m` by `gains[k]` (folded into the output de-normalisation).
pub fn apply_output_gains(m: &mut LstmModel, gains: &[f32]) {
    for (k, g) in gains.iter().enumerate().take(m.dims.output) {
        m.output_mean[k] *= g;
        m.output_std[k] = (m.output_std[k] * g).max(f32::MIN_POSITIVE);
    }
}

/// Sums for the least-squares output gains of a residual network over sequences it did
/// not train on: per output, `sum(target * prediction)` and `sum(prediction^2)`.
#[derive(Clone, Debug)]
pub struct GainFit {
    target_times_prediction: Vec<f64>,
    prediction_squared: Vec<f64>,
    residual: Vec<bool>,
    sequences: usize,
}

impl GainFit {
    /// No sequences yet, `outputs` outputs.
    pub fn new(outputs: usize) -> Self {
        GainFit {
            target_times_prediction: vec![0.0; outputs],
            prediction_squared: vec![0.0; outputs],
            residual: vec![true; outputs],
            sequences: 0,
        }
    }

    /// Streams `m` over each sequence (as the firmware runs it) and adds its
    /// predictions and targets.
    pub fn add(&mut self, m: &LstmModel, seqs: &[&Sequence]) -> Result<()> {
        for seq in seqs {
            let pred = m.stream(&seq.inputs)?;
            for (t, p) in pred.iter().enumerate() {
                for (k, &pk) in p.iter().enumerate().take(self.residual.len()) {
                    self.residual[k] &= seq.model_only[t][k] == 0.0;
                    self.target_times_prediction[k] += f64::from(seq.targets[t][k]) * f64::from(pk);
                    self.prediction_squared[k] += f64::from(pk).powi(2);
                }
            }
            self.sequences += 1;
        }
        Ok(())
    }

    /// Per output, the gain in [0, 1] that minimises the squared error of
    /// `gain * prediction` over the sequences added; 1 for an output that is not a
    /// residual, an output never predicted, or when no sequence was added.
    pub fn gains(&self) -> Vec<f32> {
        (0..self.residual.len())
            .map(|k| {
                let pp = self.prediction_squared[k];
                if self.residual[k] && self.sequences > 0 && pp > 0.0 {
                    (self.target_times_prediction[k] / pp).clamp(0.0, 1.0) as f32
                } else {
                    1.0
                }
            })
            .collect()
    }
}

/// Do-no-harm gains judged on every held-out run, not on the validation runs alone: the
/// training runs are dealt into `folds` folds (run `i` into fold `i % folds`); for each
/// fold a network trained from `init` as [`train`] trains (learning rate `lr`, early
/// stopping on `val`) on the other folds' runs predicts that fold's runs, and `trained`
/// (the network trained on every training run) predicts the validation runs. The gains
/// ([`GainFit::gains`]) are fitted on all these predictions together, so a network whose
/// help does not carry over from run to run fades towards its linear stage.
pub fn cross_validated_gains(
    init: &LstmModel,
    trained: &LstmModel,
    train_runs: &[&Sequence],
    val: &[&Sequence],
    cfg: &TrainConfig,
    lr: f64,
    folds: usize,
) -> Result<Vec<f32>> {
    let mut fit = GainFit::new(trained.dims.output);
    fit.add(trained, val)?;
    if !fit.residual.iter().any(|&r| r) {
        return Ok(fit.gains());
    }
    let folds = folds.min(train_runs.len());
    for k in 0..folds {
        let (mut held, mut rest) = (Vec::new(), Vec::new());
        for (i, &s) in train_runs.iter().enumerate() {
            if i % folds == k {
                held.push(s);
            } else {
                rest.push(s);
            }
        }
        if rest.is_empty() || held.is_empty() {
            continue;
        }
        let (m, _) = run(init, &rest, val, cfg, lr, cfg.epochs, false)?;
        fit.add(&m, &held)?;
    }
    Ok(fit.gains())
}

/// CPU seconds (user + system) this process has used, from `/proc/self/stat` (10 ms
/// ticks), or `None` where that file is missing. Benchmarks on a loaded machine report it
/// beside the wall clock.
pub fn process_cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the parenthesised command name: state is field 3, utime 14, stime 15.
    let rest = &stat[stat.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks: f64 = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}

/// Wall-clock and process CPU seconds (see [`process_cpu_seconds`]; NaN if unknown) of
/// each of `epochs` training epochs (no validation) over `train`, for the benchmark: the
/// same windows, batches, loss, clipping and optimiser as [`train`].
pub fn time_epochs(
    init: &LstmModel,
    train: &[&Sequence],
    cfg: &TrainConfig,
    lr: f64,
    epochs: usize,
) -> Result<(usize, Vec<(f64, f64)>)> {
    tanh_input_layer(init)?;
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    let mut net = FusedNet::from_model(init, cfg.threads);
    let adam = Adam::new(lr);
    let w = windows(init, train, cfg, 0);
    let mut times = Vec::new();
    for _ in 0..epochs {
        let t0 = std::time::Instant::now();
        let c0 = process_cpu_seconds();
        epoch(&mut net, &adam, &w, cfg, &mut rng);
        let cpu = match (c0, process_cpu_seconds()) {
            (Some(a), Some(b)) => b - a,
            _ => f64::NAN,
        };
        times.push((t0.elapsed().as_secs_f64(), cpu));
    }
    Ok((w.count, times))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sequence whose targets are `scale` times what `m` predicts on it (`model_only`
    /// 0: a residual, or 1: not one).
    fn scaled_sequence(m: &LstmModel, scale: f32, model_only: f32) -> Sequence {
        let inputs: Vec<Vec<f32>> = (0..200)
            .map(|t| vec![(t as f32 * 0.1).sin(), (t as f32 * 0.03).cos()])
            .collect();
        let pred = m.stream(&inputs).unwrap();
        Sequence {
            targets: pred.iter().map(|p| vec![scale * p[0]]).collect(),
            model_only: vec![vec![model_only]; inputs.len()],
            inputs,
            ..Default::default()
        }
    }

    #[test]
    fn gains_are_the_clamped_least_squares_scale_over_every_sequence_added() {
        let dims = LstmDims {
            input: 2,
            embed: 4,
            hidden: 4,
            output: 1,
        };
        let m = LstmModel::init(dims, 3);
        let gain = |seqs: &[Sequence]| {
            let mut fit = GainFit::new(1);
            for s in seqs {
                fit.add(&m, &[s]).unwrap();
            }
            fit.gains()[0]
        };
        assert!((gain(&[scaled_sequence(&m, 0.5, 0.0)]) - 0.5).abs() < 1e-6);
        // Pooled over runs: one where the network helps fully, one where it is wrong.
        let pooled = gain(&[
            scaled_sequence(&m, 1.0, 0.0),
            scaled_sequence(&m, -1.0, 0.0),
        ]);
        assert_eq!(pooled, 0.0);
        assert_eq!(gain(&[scaled_sequence(&m, 3.0, 0.0)]), 1.0);
        // Not a residual, or nothing added: left as it is.
        assert_eq!(gain(&[scaled_sequence(&m, 0.5, 1.0)]), 1.0);
        assert_eq!(gain(&[]), 1.0);
    }
}
