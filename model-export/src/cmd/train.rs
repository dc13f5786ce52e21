//! `model-export train`: fit the compensation network on logs.
use crate::args::choice::named;
use anyhow::{Context, Result, bail};
use clap::Args;
use compnet::data::{FeatureSpec, Sequence, Table};
use compnet::report::{AdaptationRef, TrainReport, TrainTestBlock};
use compnet::{adaptation, eval, io, plot, train};
use firmware::adaptation::AdaptationConfig;
use firmware::nn::format::FeaturePreset;
use std::path::{Path, PathBuf};

/// Which columns the network reads and predicts.
#[derive(Debug, Args)]
pub struct FeatureArgs {
    /// Feature preset, one of the firmware's: `paper` (the paper's form: tau_model,
    /// tau_meas, q of each joint -> next-step tau_meas), `paper_relative` (the same inputs
    /// with the measured residual -> the residual over the model's next-step torque: a
    /// network that knows nothing returns the model), `feedforward` (tau_model, q, qd ->
    /// tau_meas - tau_model), `drive` (what the drive knows before the tick and the
    /// residual it measured over the previous tick -> tau_meas - tau_model) or `custom`
    /// (--inputs/--targets).
    #[arg(long, value_parser = named::<FeaturePreset>(), default_value = "paper_relative")]
    pub preset: FeaturePreset,
    /// Joints for the presets (1-based robot joint numbers; columns `q_j4`, `qd_j4`,
    /// `tau_meas_j4`, `tau_model_j4`, ...).
    #[arg(long, value_delimiter = ',', default_value = "4,5,6")]
    pub joints: Vec<usize>,
    /// `custom`: input columns.
    #[arg(long, value_delimiter = ',')]
    pub inputs: Vec<String>,
    /// `custom`: target columns, each `col` or `col-col` (a difference).
    #[arg(long, value_delimiter = ',')]
    pub targets: Vec<String>,
    /// `custom`: steps ahead the targets are taken.
    #[arg(long, default_value_t = 0)]
    pub shift: usize,
    /// Old spelling of the paper forms (hidden, warns): `next` is `--preset paper`,
    /// `relative` is `--preset paper_relative`, `increment` (the measured torque now plus
    /// the output: beats persistence in open loop, but fed forward it closes a unit-gain
    /// loop on the applied torque) is a study form with no firmware preset.
    #[arg(long, value_enum, hide = true)]
    pub paper_output: Option<PaperOutput>,
}

/// The old `--paper-output` values.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum PaperOutput {
    /// The next-step torque itself (`--preset paper`).
    Next,
    /// The increment over the measured torque now (a study form, not exportable).
    Increment,
    /// The residual over the model's torque at the next step (`--preset paper_relative`).
    Relative,
}

impl FeatureArgs {
    /// The feature specification these options choose.
    pub fn spec(&self) -> Result<FeatureSpec> {
        let paper = matches!(
            self.preset,
            FeaturePreset::Paper | FeaturePreset::PaperRelative
        );
        let preset = match self.paper_output {
            Some(PaperOutput::Increment) if paper => {
                return Ok(FeatureSpec::paper_increment(&self.joints));
            }
            Some(PaperOutput::Next) if paper => FeaturePreset::Paper,
            Some(PaperOutput::Relative) if paper => FeaturePreset::PaperRelative,
            Some(_) | None => self.preset,
        };
        match preset {
            FeaturePreset::Custom => FeatureSpec::custom(&self.inputs, &self.targets, self.shift),
            other => FeatureSpec::for_preset(other.name(), &self.joints)
                .with_context(|| format!("preset `{}` has no feature layout", other.name())),
        }
    }
}

/// `train` options.
#[derive(Debug, Args)]
pub struct TrainArgs {
    /// CSV logs (repeat or comma-separate); windows never cross files.
    #[arg(long, required = true, value_delimiter = ',')]
    pub data: Vec<PathBuf>,
    /// Validation logs, used whole (early stopping and learning-rate choice on runs the
    /// network never trains on); without them, the `--val-fraction` block of each
    /// training log validates.
    #[arg(long, value_delimiter = ',')]
    pub validation_data: Vec<PathBuf>,
    /// Features.
    #[command(flatten)]
    pub features: FeatureArgs,
    /// Output model (safetensors, PyTorch names).
    #[arg(long, default_value = "lstm.safetensors")]
    pub out: PathBuf,
    /// Loss curve (SVG).
    #[arg(long, default_value = "loss.svg")]
    pub loss_plot: PathBuf,
    /// Report (JSON) with the per-output figures on the test blocks.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Input-layer width.
    #[arg(long, default_value_t = 64)]
    pub embed: usize,
    /// LSTM cells.
    #[arg(long, default_value_t = 64)]
    pub hidden: usize,
    /// Window length (steps in the loss).
    #[arg(long, default_value_t = 100)]
    pub window: usize,
    /// Burn-in steps before each window (seen, not in the loss).
    #[arg(long, default_value_t = 50)]
    pub burn_in: usize,
    /// Windows per batch.
    #[arg(long, default_value_t = 50)]
    pub batch: usize,
    /// Learning rate (the paper: 0.05); default: chosen by validation among 0.05, 0.01, 0.003, 0.001.
    #[arg(long)]
    pub lr: Option<f64>,
    /// Maximum epochs.
    #[arg(long, default_value_t = 200)]
    pub epochs: usize,
    /// Early stopping patience (epochs).
    #[arg(long, default_value_t = 20)]
    pub patience: usize,
    /// Gradient-norm clip (0: off).
    #[arg(long, default_value_t = 1.0)]
    pub clip: f64,
    /// Validation fraction of each file.
    #[arg(long, default_value_t = 0.15)]
    pub val_fraction: f64,
    /// Test fraction of each file (its end).
    #[arg(long, default_value_t = 0.15)]
    pub test_fraction: f64,
    /// Random seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// With `--validation-data`, the do-no-harm output gains of a residual network are
    /// judged on every held-out run: the training runs are dealt into this many folds
    /// (run i into fold i mod N), a network trained on the other folds predicts each
    /// fold, and the gains fit those predictions together with the validation runs'
    /// (0: on the validation runs alone; the UR10e study uses 4 for the `drive` preset).
    #[arg(long, default_value_t = 0)]
    pub gain_folds: usize,
    /// `drive` preset: the network learns what the drive's online friction adaptation
    /// (this forgetting time constant [s], at each dataset's tick rate, within
    /// `--adapt-max-nm`) leaves after the linear stage, as the drive runs it.
    #[arg(long)]
    pub adapt_time_constant_s: Option<f32>,
    /// Largest |correction| of that adaptation [N·m].
    #[arg(long, default_value_t = 10.0)]
    pub adapt_max_nm: f32,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// Each dataset's sequence, with its tick rate [Hz] (from `time_s`) if `rates`, else 0.
fn load(paths: &[PathBuf], spec: &FeatureSpec, rates: bool) -> Result<Vec<(Sequence, f32)>> {
    paths
        .iter()
        .map(|p| {
            let t = Table::read(p)?;
            let hz = if rates {
                adaptation::tick_hz(&t)? as f32
            } else {
                0.0
            };
            Ok((spec.sequence(&t)?, hz))
        })
        .collect()
}

/// Runs `train`.
pub fn run(a: TrainArgs) -> Result<()> {
    let spec = a.features.spec()?;
    let cfg = train::TrainConfig {
        embed: a.embed,
        hidden: a.hidden,
        window: a.window,
        burn_in: a.burn_in,
        batch: a.batch,
        lr: a.lr,
        epochs: a.epochs,
        patience: a.patience,
        clip_norm: a.clip,
        val_fraction: a.val_fraction,
        test_fraction: a.test_fraction,
        seed: a.seed,
        progress: !a.quiet,
        ..Default::default()
    };
    let mut tr = Vec::new();
    let mut va = Vec::new();
    let mut te = Vec::new();
    let held_out = !a.validation_data.is_empty();
    let (mut tr_hz, mut va_hz) = (Vec::new(), Vec::new());
    let rates = a.adapt_time_constant_s.is_some();
    for (s, hz) in load(&a.data, &spec, rates)? {
        let val_fraction = if held_out { 0.0 } else { cfg.val_fraction };
        let (x, y, z) = s.split(val_fraction, cfg.test_fraction)?;
        tr.push(x);
        tr_hz.push(hz);
        if !held_out {
            va.push(y);
            va_hz.push(hz);
        }
        te.push(z);
    }
    for (s, hz) in load(&a.validation_data, &spec, rates)? {
        va.push(s);
        va_hz.push(hz);
    }
    let adapt = match a.adapt_time_constant_s {
        Some(t) if spec.preset != "drive" => {
            bail!(
                "--adapt-time-constant-s {t}: only for the `drive` preset (here `{}`)",
                spec.preset
            )
        }
        Some(t) => {
            let c = AdaptationConfig {
                time_constant_s: t,
                max_correction_nm: a.adapt_max_nm,
            };
            if c.forgetting(1.0e3).is_none() {
                bail!(
                    "--adapt-time-constant-s {t} / --adapt-max-nm {}: both must be finite and positive",
                    a.adapt_max_nm
                );
            }
            Some(c)
        }
        None => None,
    };
    // The `drive` preset's linear stage first (least squares on the training steps); the
    // network then learns what it leaves. The test blocks keep the whole targets. With
    // held-out validation runs, the linear stage is fitted on the whole training runs,
    // the samples the built-in linear baseline is fitted on: it is that baseline, and
    // the network's part is all that the compensator adds to it. With the drive's
    // adaptation (`--adapt-time-constant-s`) it is fitted jointly with the adaptation,
    // and the network learns what both leave.
    let linear = if spec.preset == "drive" {
        let fit_on: Vec<Sequence> = if held_out {
            tr.iter().chain(&te).cloned().collect()
        } else {
            tr.clone()
        };
        let w = match adapt {
            // With the drive's adaptation: fitted jointly with it (the training blocks
            // and the test blocks come from the same files, at the same rates).
            Some(c) => {
                let rates = if held_out {
                    [tr_hz.as_slice(), tr_hz.as_slice()].concat()
                } else {
                    tr_hz.clone()
                };
                adaptation::fit_linear_stage_under_adaptation(
                    &fit_on,
                    &rates,
                    spec.targets.len(),
                    c,
                )?
            }
            None => train::fit_linear_stage(&fit_on, spec.targets.len())?,
        };
        train::subtract_linear_stage(&w, &mut tr);
        train::subtract_linear_stage(&w, &mut va);
        if let Some(c) = adapt {
            for (s, &hz) in tr.iter_mut().zip(&tr_hz).chain(va.iter_mut().zip(&va_hz)) {
                adaptation::subtract_from_drive_targets(s, spec.targets.len(), c, hz);
            }
        }
        w
    } else {
        Vec::new()
    };
    let all_train = Sequence {
        inputs: tr.iter().flat_map(|s| s.inputs.clone()).collect(),
        targets: tr.iter().flat_map(|s| s.targets.clone()).collect(),
        ..Default::default()
    };
    let init = train::new_model(
        &all_train,
        spec.inputs.clone(),
        spec.output_names(),
        &spec.preset,
        &cfg,
    )?;
    let val: Vec<&Sequence> = va.iter().collect();
    let train_runs: Vec<&Sequence> = tr.iter().collect();
    let (mut model, hist) = train::train(&init, &train_runs, &val, &cfg)?;
    // Only on whole held-out runs: a block of the training runs would not tell.
    let gains = if held_out && a.gain_folds > 0 {
        let g = train::cross_validated_gains(
            &init,
            &model,
            &train_runs,
            &val,
            &cfg,
            hist.lr,
            a.gain_folds,
        )?;
        train::apply_output_gains(&mut model, &g);
        g
    } else if held_out {
        train::shrink_residual_outputs(&mut model, &val)?
    } else {
        vec![1.0; model.dims.output]
    };
    if gains.iter().any(|&g| g != 1.0) {
        println!("output gains on the held-out runs (do-no-harm shrinkage): {gains:?}");
    }
    model.linear = linear;
    // The training envelope of each compensated joint, over the whole training runs
    // (not only their training blocks): what the drive fades the learned stages outside.
    let joints: Option<Vec<usize>> = (0..spec.targets.len())
        .map(|k| eval::target_joint(&spec, k))
        .collect();
    if let Some(joints) = joints {
        let tables: Vec<Table> = a
            .data
            .iter()
            .map(|p| Table::read(p))
            .collect::<Result<_>>()?;
        model.envelope = compnet::envelope::record(&tables, &joints)
            .context("recording the training envelope")?;
        for (j, e) in joints.iter().zip(&model.envelope) {
            let qd = e.drive[2];
            println!(
                "envelope joint {j}: q [{:.3}, {:.3}] rad, qd [{:.3}, {:.3}] rad/s, {} of {} (q, qd) cells covered",
                e.q_rad.lo,
                e.q_rad.hi,
                qd.lo,
                qd.hi,
                e.covered_cells(),
                firmware::envelope::COVERAGE_CELLS_Q * firmware::envelope::COVERAGE_CELLS_QD
            );
        }
    }
    let model_bytes = io::model_bytes(&model)?;
    let loss_svg = plot::loss_curve_svg(&hist)?;
    println!(
        "learning rate {} (trials: {:?}); best epoch {} of {}",
        hist.lr,
        hist.lr_trials,
        hist.best_epoch + 1,
        hist.train.len()
    );
    let mut reports = Vec::new();
    for (p, t) in a.data.iter().zip(&te) {
        let rows = eval::evaluate(&model, t)?;
        println!(
            "\n{} (test block, {} steps, streamed):\n{}",
            p.display(),
            t.len(),
            eval::markdown(&rows)
        );
        reports.push(TrainTestBlock {
            file: p.display().to_string(),
            steps: t.len(),
            outputs: rows,
        });
    }
    let report = match &a.report {
        Some(_) => {
            let report = TrainReport {
                preset: spec.preset.clone(),
                lr: hist.lr,
                lr_trials: hist.lr_trials.clone(),
                epochs: hist.train.len(),
                best_epoch: hist.best_epoch + 1,
                output_gains: gains.iter().map(|&g| f64::from(g)).collect(),
                adaptation: adapt.map(|c| AdaptationRef {
                    time_constant_s: c.time_constant_s,
                    max_correction_nm: c.max_correction_nm,
                }),
                train_loss: hist.train.clone(),
                val_loss: hist.val.clone(),
                test: reports,
            };
            Some(serde_json::to_string_pretty(&report)?)
        }
        None => None,
    };
    // The model, the plot and the report: all three or none.
    let mut files: Vec<(&Path, &[u8])> =
        vec![(&a.out, &model_bytes), (&a.loss_plot, loss_svg.as_bytes())];
    if let (Some(path), Some(text)) = (&a.report, &report) {
        files.push((path, text.as_bytes()));
    }
    artifacts::write_atomic_all(&files)?;
    println!("wrote {} and {}", a.out.display(), a.loss_plot.display());
    Ok(())
}
