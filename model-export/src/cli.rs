//! Command-line interface: one subcommand per pipeline stage.
use crate::nn::data::{FeatureSpec, Sequence, Table};
use crate::nn::{eval, io, plot, train};
use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};
use std::path::{Path, PathBuf};

/// `model-export`: identify a robot's dynamics, learn what the model misses, and
/// export both as fixed-size arrays for the joint-drive firmware.
#[derive(Debug, Parser)]
#[command(name = "model-export", version, about)]
pub struct Cli {
    /// The stage to run.
    #[command(subcommand)]
    pub command: Command,
}

/// Pipeline stages.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Print the firmware's math primitives over a range (a smoke test of the shared numerics).
    Primitives {
        /// Number of points in [-4, 4].
        #[arg(long, default_value_t = 9)]
        points: usize,
    },
    /// Software in the loop: the firmware's drives and compensators on the paper's wrist
    /// (joints 4-6 on the plant simulator's true dynamics, friction and ripple); prints
    /// per joint RMS tracking error and RMS q current for no feedforward, the identified
    /// model (--model), and model + LSTM f32 / int16 (--lstm). Without --model: the
    /// single-joint and coupled-load demos.
    Sil {
        /// Wrist options (`--model` selects the wrist; without it the demos run).
        #[command(flatten)]
        wrist: Box<crate::sil::wrist::SilArgs>,
    },
    /// Identify a robot's base parameters (rigid body + friction) from logs by least
    /// squares; write the model JSON and print per-joint RMS errors.
    ///
    /// Example (UR10e data): model-export identify --robot ur10e.urdf --log a.csv
    /// --log b.csv --validate c.csv -o ur10e-model.json
    Identify(Box<crate::identify::commands::IdentifyArgs>),
    /// Predict joint torques for a log or a CSV of states with the robot's nominal
    /// parameters or an identified model (firmware f32 model); write them as CSV.
    Torque(Box<crate::identify::commands::TorqueArgs>),
    /// Train the LSTM compensation network on CSV logs (each file split into contiguous
    /// train / validation / test blocks), evaluate it by streaming the firmware step over
    /// each test block, write the model (safetensors), the loss curve and a report.
    Train(TrainArgs),
    /// Evaluate a model by streaming the firmware f32 step over whole CSV logs: per output
    /// RMS before (identified model only) and after compensation, reduction, persistence.
    Evaluate(EvaluateArgs),
    /// Import a model saved from PyTorch (safetensors with PyTorch names, or ONNX from
    /// `torch.onnx.export`; see the README), validate it and write it in our format;
    /// optionally check it against a reference.
    Import(ImportArgs),
    /// Design an optimised Fourier excitation trajectory (coefficients JSON, playback CSV, plot).
    Excite(Box<crate::excite::cli::ExciteArgs>),
    /// Simulate the true plant along a commanded trajectory and write the controller's log (CSV).
    Simulate(crate::sim::cli::SimulateArgs),
    /// Identify rigid body + friction on simulated logs and print the per-joint uncompensated RMS table.
    PlantReport(crate::sim::cli::PlantReportArgs),
    /// The main job: the whole pipeline on the built-in default robot (the paper's wrist
    /// setup), every stage as its own subcommand, into one report folder (Markdown + JSON).
    Demo(crate::demo::DemoArgs),
    /// Quantise a model (f32 / int16 / int8) and write ONE Rust source file of fixed-size
    /// arrays in the firmware kernels' layout (with normalisation, feature preset,
    /// joints, control rate, dynamics, schema version, content hash and a self-check
    /// digest); optionally report accuracy per precision on a CSV log.
    Export(crate::export::cli::ExportArgs),
}

/// Which columns the network reads and predicts.
#[derive(Debug, Args)]
pub struct FeatureArgs {
    /// Feature preset: `paper` (tau_model, tau_meas, q of each joint -> next-step tau_meas),
    /// `feedforward` (tau_model, q, qd -> tau_meas - tau_model) or `custom` (--inputs/--targets).
    #[arg(long, default_value = "paper")]
    pub preset: String,
    /// Joints for the presets (columns `q_j4`, `qd_j4`, `tau_meas_j4`, `tau_model_j4`, ...).
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
    /// `paper`: how the network's output gives the next-step torque: `next` (the torque
    /// itself, the paper's form and the one a drive can feed forward) or `increment`
    /// (the measured torque now plus the output: beats persistence in open loop, but fed
    /// forward it closes a unit-gain loop on the applied torque; not exportable).
    #[arg(long, value_enum, default_value_t = PaperOutput::Next)]
    pub paper_output: PaperOutput,
}

/// How a `paper` network's output gives the next-step torque.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum PaperOutput {
    /// The next-step torque itself.
    Next,
    /// The increment over the measured torque now.
    Increment,
    /// The residual over the model's torque at the next step.
    Relative,
}

impl FeatureArgs {
    fn spec(&self) -> Result<FeatureSpec> {
        match self.preset.as_str() {
            "paper" if self.paper_output == PaperOutput::Increment => {
                Ok(FeatureSpec::paper_increment(&self.joints))
            }
            "paper" if self.paper_output == PaperOutput::Relative => {
                Ok(FeatureSpec::paper_relative(&self.joints))
            }
            "custom" => FeatureSpec::custom(&self.inputs, &self.targets, self.shift),
            other => FeatureSpec::for_preset(other, &self.joints).with_context(|| {
                format!("unknown preset `{other}` (paper, feedforward, drive, custom)")
            }),
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
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// `evaluate` options.
#[derive(Debug, Args)]
pub struct EvaluateArgs {
    /// Model (safetensors).
    #[arg(long)]
    pub model: PathBuf,
    /// CSV logs, each streamed whole from the zero state.
    #[arg(long, required = true, value_delimiter = ',')]
    pub data: Vec<PathBuf>,
    /// Features (must match the model's).
    #[command(flatten)]
    pub features: FeatureArgs,
    /// Report (JSON).
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Folder for the paper's Figures 12 and 13 (measured, predicted and error torque
    /// before and after compensation) of the first log.
    #[arg(long)]
    pub figures: Option<PathBuf>,
    /// Training datasets (CSV, comma separated) for the friction-feature least-squares
    /// baseline (`nn::baseline`): adds its RMS [N·m] per output (`baseline` column,
    /// `baseline_rms_nm`).
    #[arg(long, value_delimiter = ',')]
    pub baseline_data: Vec<PathBuf>,
}

/// `import` options.
#[derive(Debug, Args)]
pub struct ImportArgs {
    /// Safetensors written from PyTorch, or an ONNX model (`.onnx`) exported from it.
    #[arg(long)]
    pub torch: PathBuf,
    /// Our model file to write.
    #[arg(long)]
    pub out: PathBuf,
    /// Reference CSV (columns `x0..`, `y0..`: raw inputs and PyTorch's outputs per step);
    /// the firmware step must match it to `--tolerance` relative.
    #[arg(long)]
    pub reference: Option<PathBuf>,
    /// Relative tolerance for `--reference` (of the outputs' RMS).
    #[arg(long, default_value_t = 1e-5)]
    pub tolerance: f64,
    /// The activation after the input layer, for files without `input_activation`
    /// metadata (`tanh`, or `linear` for a plain `nn.Linear`); it must agree with the
    /// metadata where there is some.
    #[arg(long, value_parser = ["tanh", "linear"])]
    pub input_activation: Option<String>,
}

fn load(paths: &[PathBuf], spec: &FeatureSpec) -> Result<Vec<Sequence>> {
    paths
        .iter()
        .map(|p| spec.sequence(&Table::read(p)?))
        .collect()
}

fn train_cmd(a: TrainArgs) -> Result<()> {
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
    for s in load(&a.data, &spec)? {
        let val_fraction = if held_out { 0.0 } else { cfg.val_fraction };
        let (x, y, z) = s.split(val_fraction, cfg.test_fraction)?;
        tr.push(x);
        if !held_out {
            va.push(y);
        }
        te.push(z);
    }
    va.extend(load(&a.validation_data, &spec)?);
    // The `drive` preset's linear stage first (least squares on the training steps); the
    // network then learns what it leaves. The test blocks keep the whole targets. With
    // held-out validation runs, the linear stage is fitted on the whole training runs,
    // the samples the built-in linear baseline is fitted on: it is that baseline, and
    // the network's part is all that the compensator adds to it.
    let linear = if spec.preset == "drive" {
        let fit_on: Vec<Sequence> = if held_out {
            tr.iter().chain(&te).cloned().collect()
        } else {
            tr.clone()
        };
        let w = train::fit_linear_stage(&fit_on, spec.targets.len())?;
        train::subtract_linear_stage(&w, &mut tr);
        train::subtract_linear_stage(&w, &mut va);
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
        reports.push(
            serde_json::json!({"file": p.display().to_string(), "steps": t.len(), "outputs": rows}),
        );
    }
    let report = match &a.report {
        Some(_) => {
            let j = serde_json::json!({"preset": spec.preset, "lr": hist.lr, "lr_trials": hist.lr_trials,
                "epochs": hist.train.len(), "best_epoch": hist.best_epoch + 1, "output_gains": gains, "train_loss": hist.train, "val_loss": hist.val, "test": reports});
            Some(serde_json::to_string_pretty(&j)?)
        }
        None => None,
    };
    // The model, the plot and the report: all three or none.
    let mut files: Vec<(&Path, &[u8])> =
        vec![(&a.out, &model_bytes), (&a.loss_plot, loss_svg.as_bytes())];
    if let (Some(path), Some(text)) = (&a.report, &report) {
        files.push((path, text.as_bytes()));
    }
    crate::model_file::write_atomic_all(&files)?;
    println!("wrote {} and {}", a.out.display(), a.loss_plot.display());
    Ok(())
}

fn evaluate_cmd(a: EvaluateArgs) -> Result<()> {
    let spec = a.features.spec()?;
    let model = io::read_model(&a.model)?;
    spec.check_model(&model)
        .with_context(|| format!("{}", a.model.display()))?;
    // The linear baseline, fitted on --baseline-data (before any output).
    let baseline = if a.baseline_data.is_empty() {
        None
    } else {
        let tables: Vec<Table> = a
            .baseline_data
            .iter()
            .map(|p| Table::read(p))
            .collect::<Result<_>>()?;
        Some(crate::nn::baseline::fit(
            &tables,
            &eval::target_joints(&spec),
        )?)
    };
    let tables: Vec<Table> = a
        .data
        .iter()
        .map(|p| Table::read(p))
        .collect::<Result<_>>()?;
    let seqs: Vec<Sequence> = tables
        .iter()
        .map(|t| spec.sequence(t))
        .collect::<Result<_>>()?;
    let mut reports = Vec::new();
    let mut figures = Vec::new();
    for (i, ((p, s), table)) in a.data.iter().zip(seqs).zip(&tables).enumerate() {
        let rows = eval::evaluate(&model, &s)?;
        let base_rms = match &baseline {
            Some(b) => eval::baseline_rms(&spec, table, s.len(), b)?,
            None => vec![None; rows.len()],
        };
        if let (0, Some(dir)) = (i, &a.figures) {
            for (name, svg) in plot::compensation_figures(&model, &s)? {
                figures.push((dir.join(name), svg));
            }
        }
        let rows: Vec<eval::ReportRow> = rows
            .into_iter()
            .zip(base_rms)
            .map(|(eval, baseline_rms_nm)| eval::ReportRow {
                eval,
                samples: s.len(),
                baseline_rms_nm,
            })
            .collect();
        crate::model_file::ensure_finite(
            &format!("{}: evaluation", p.display()),
            rows.iter()
                .flat_map(|r| r.eval.figures().chain(r.baseline_rms_nm)),
        )?;
        let plain: Vec<eval::TargetEval> = rows.iter().map(|r| r.eval.clone()).collect();
        println!(
            "{} ({} steps, streamed):\n{}",
            p.display(),
            s.len(),
            if baseline.is_some() {
                eval::markdown_with_baseline(&rows)
            } else {
                eval::markdown(&plain)
            }
        );
        let paper = (spec.preset == "paper")
            .then(|| eval::beside_paper_markdown(&a.features.joints, &plain))
            .flatten();
        if let Some(t) = &paper {
            println!("Beside the paper's Table 2 (Zhang et al. 2020, N m):\n{t}");
        }
        // The paper's figures for the same joints, beside ours.
        let paper_rows: Option<Vec<serde_json::Value>> = paper.as_ref().map(|_| {
            eval::PAPER_TABLE2
                .iter()
                .map(|(j, b, a, r)| {
                    serde_json::json!({"joint": j, "rms_before": b, "rms_after": a, "reduction_pct": r})
                })
                .collect()
        });
        reports.push(
            serde_json::json!({"file": p.display().to_string(), "steps": s.len(),
            "outputs": rows, "paper_table2": paper_rows}),
        );
    }
    let report = match &a.report {
        Some(r) => Some((
            r,
            serde_json::to_string_pretty(
                &serde_json::json!({"preset": spec.preset, "data": reports,
                    "baseline": baseline.as_ref().map(|b| serde_json::json!({
                        "data": a.baseline_data.iter().map(|p| p.display().to_string()).collect::<Vec<_>>(),
                        "fit": b}))}),
            )?,
        )),
        None => None,
    };
    // The figures and the report: all or none.
    let mut files: Vec<(&Path, &[u8])> = figures
        .iter()
        .map(|(p, svg)| (p.as_path(), svg.as_bytes()))
        .collect();
    if let Some((path, text)) = &report {
        files.push((path.as_path(), text.as_bytes()));
    }
    crate::model_file::write_atomic_all(&files)
}

/// Compares a model's streamed firmware output with a reference CSV (`x*` inputs,
/// `y*` outputs); returns the largest error relative to the reference outputs' RMS.
pub fn check_reference(model: &crate::nn::LstmModel, reference: &std::path::Path) -> Result<f64> {
    let t = Table::read(reference)?;
    let xs: Vec<&[f32]> = (0..model.dims.input)
        .map(|k| t.column(&format!("x{k}")))
        .collect::<Result<_>>()?;
    let ys: Vec<&[f32]> = (0..model.dims.output)
        .map(|k| t.column(&format!("y{k}")))
        .collect::<Result<_>>()?;
    let inputs: Vec<Vec<f32>> = (0..t.len())
        .map(|r| xs.iter().map(|c| c[r]).collect())
        .collect();
    let out = model.stream(&inputs)?;
    let mut worst = 0.0f64;
    for (k, y) in ys.iter().enumerate() {
        let rms = (y.iter().map(|v| (*v as f64).powi(2)).sum::<f64>() / y.len().max(1) as f64)
            .sqrt()
            .max(1e-12);
        for (r, v) in y.iter().enumerate() {
            worst = worst.max((out[r][k] as f64 - *v as f64).abs() / rms);
        }
    }
    Ok(worst)
}

fn import_cmd(a: ImportArgs) -> Result<()> {
    let model = if crate::nn::onnx::is_onnx(&a.torch) {
        // The graph says which activation follows the input layer.
        if let Some(act) = &a.input_activation {
            bail!(
                "{}: --input-activation {act} is for safetensors files; an ONNX graph names its own",
                a.torch.display()
            );
        }
        crate::nn::onnx::read_onnx_model(&a.torch)?
    } else {
        io::read_model_with(&a.torch, a.input_activation.as_deref())?
    };
    println!(
        "{}: {:?}, preset `{}`",
        a.torch.display(),
        model.dims,
        model.preset
    );
    if let Some(r) = &a.reference {
        let err = check_reference(&model, r)?;
        println!(
            "firmware f32 step vs {}: max error {err:.3e} of the output RMS",
            r.display()
        );
        if err > a.tolerance {
            bail!(
                "{}: the imported model differs from the reference by {err:.3e} > {}",
                r.display(),
                a.tolerance
            );
        }
    }
    io::write_model(&model, &a.out)?;
    println!("wrote {}", a.out.display());
    Ok(())
}

/// The files a command reads and the files it writes (for
/// [`crate::model_file::refuse_outputs_that_are_inputs`]).
fn files(command: &Command) -> (Vec<&Path>, Vec<&Path>) {
    fn all(v: &[PathBuf]) -> impl Iterator<Item = &Path> {
        v.iter().map(PathBuf::as_path)
    }
    match command {
        Command::Identify(a) => (
            std::iter::once(a.robot.as_path())
                .chain(all(&a.logs))
                .chain(all(&a.validation))
                .collect(),
            vec![&a.output],
        ),
        Command::Torque(a) => (
            [Some(&a.robot), a.model.as_ref(), Some(&a.log)]
                .into_iter()
                .flatten()
                .map(PathBuf::as_path)
                .collect(),
            vec![&a.output],
        ),
        Command::Train(a) => (
            all(&a.data).chain(all(&a.validation_data)).collect(),
            [Some(&a.out), Some(&a.loss_plot), a.report.as_ref()]
                .into_iter()
                .flatten()
                .map(PathBuf::as_path)
                .collect(),
        ),
        Command::Evaluate(a) => (
            std::iter::once(a.model.as_path())
                .chain(all(&a.data))
                .chain(all(&a.baseline_data))
                .collect(),
            a.report.iter().map(PathBuf::as_path).collect(),
        ),
        Command::Import(a) => (
            std::iter::once(a.torch.as_path())
                .chain(a.reference.as_deref())
                .collect(),
            vec![&a.out],
        ),
        Command::Export(a) => (
            [
                &a.model,
                &a.robot,
                &a.identified,
                &a.accuracy_log,
                &a.budgets,
            ]
            .into_iter()
            .flatten()
            .map(PathBuf::as_path)
            .chain(all(&a.gate_data))
            .collect(),
            std::iter::once(a.out.as_path())
                .chain(a.accuracy_json.as_deref())
                .collect(),
        ),
        _ => (Vec::new(), Vec::new()),
    }
}

/// Parses the arguments after `model-export` and runs them, as the binary does with its
/// command line.
pub fn run_args(args: &[&str]) -> anyhow::Result<()> {
    let line = std::iter::once("model-export").chain(args.iter().copied());
    run(Cli::try_parse_from(line)?)
}

/// Runs one parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    let (inputs, outputs) = files(&cli.command);
    crate::model_file::refuse_outputs_that_are_inputs(&inputs, &outputs)?;
    match cli.command {
        Command::Excite(args) => crate::excite::cli::run(&args),
        Command::Primitives { points } => {
            println!("{:>10} {:>12} {:>12} {:>12}", "x", "exp", "tanh", "sigmoid");
            for i in 0..points {
                let x = -4.0 + 8.0 * i as f32 / (points.max(2) - 1) as f32;
                println!(
                    "{:>10.4} {:>12.6} {:>12.6} {:>12.6}",
                    x,
                    firmware::math::exp(x),
                    firmware::math::tanh(x),
                    firmware::math::sigmoid(x)
                );
            }
            Ok(())
        }
        Command::Sil { wrist } => {
            if wrist.model.is_some() {
                crate::sil::wrist::run_sil_cli(&wrist)
            } else {
                run_sil(wrist.seconds.unwrap_or(5.0), wrist.seed)
            }
        }
        Command::Identify(a) => crate::identify::commands::identify(&a),
        Command::Torque(a) => crate::identify::commands::torque(&a),
        Command::Train(a) => train_cmd(a),
        Command::Evaluate(a) => evaluate_cmd(a),
        Command::Import(a) => import_cmd(a),
        Command::Simulate(args) => crate::sim::cli::run_simulate(&args),
        Command::PlantReport(args) => crate::sim::cli::run_plant_report(&args),
        Command::Export(a) => crate::export::cli::run(a),
        Command::Demo(a) => crate::demo::demo(&a),
    }
}

fn run_sil(seconds: f64, seed: u64) -> anyhow::Result<()> {
    use crate::sil::{FeedforwardMode, SingleJointSetup, run_single_joint};
    anyhow::ensure!(
        seconds.is_finite() && seconds > 0.0 && seconds <= 600.0,
        "--seconds must be in (0, 600]"
    );
    println!(
        "single joint (wrist-sized, gear 100, 20 kHz PWM, outer loops 5 kHz), {seconds} s, seed {seed}"
    );
    println!(
        "{:<28} {:>9} {:>16} {:>16} {:>12} {:>16}",
        "feedforward", "comp. Hz", "RMS error mrad", "max error mrad", "RMS iq A", "RMS feedback A"
    );
    let modes = [
        ("none", FeedforwardMode::None),
        (
            "inverse dynamics x0.8",
            FeedforwardMode::InverseDynamics(0.8),
        ),
        (
            "perfect inverse dynamics",
            FeedforwardMode::InverseDynamics(1.0),
        ),
    ];
    for hz in [100.0, 1000.0] {
        for (name, mode) in modes {
            let mut setup = SingleJointSetup::wrist_joint(hz, seed);
            setup.duration_s = seconds;
            let r = run_single_joint(&setup, mode)?;
            println!(
                "{:<28} {:>9} {:>16.4} {:>16.4} {:>12.3} {:>16.3}",
                name,
                hz,
                r.rms_error_rad * 1e3,
                r.max_error_rad * 1e3,
                r.rms_iq_a,
                r.rms_feedback_current_a
            );
        }
    }
    println!();
    println!(
        "wrist: 3 coupled joints, one firmware drive + compensator (1 kHz) per joint, states exchanged as wire frames with one tick of latency, {seconds} s"
    );
    println!(
        "{:<34} {:>6} {:>16} {:>12}",
        "feedforward", "joint", "RMS error mrad", "RMS iq A"
    );
    use crate::sil::multi::{MultiFeedforward, MultiJointSetup, run_multi_joint};
    let mut setup = MultiJointSetup::wrist(1000.0, seed);
    setup.duration_s = seconds;
    for (name, mode) in [
        ("none", MultiFeedforward::Mode(FeedforwardMode::None)),
        (
            "inverse dynamics, own joint only",
            MultiFeedforward::Decoupled,
        ),
        (
            "inverse dynamics, all joints (bus)",
            MultiFeedforward::Mode(FeedforwardMode::InverseDynamics(1.0)),
        ),
    ] {
        let r = run_multi_joint(&setup, mode)?;
        for (j, jr) in r.iter().enumerate() {
            println!(
                "{:<34} {:>6} {:>16.4} {:>12.3}",
                name,
                j,
                jr.rms_error_rad * 1e3,
                jr.rms_iq_a
            );
        }
    }
    Ok(())
}
