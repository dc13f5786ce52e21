//! `model-export evaluate`: stream the firmware step over whole logs, against the baselines.
use super::train::FeatureArgs;
use anyhow::{Context, Result, bail};
use clap::Args;
use compnet::data::{Sequence, Table};
use compnet::report::{
    AdaptationRef, BaselineRef, EvaluatedRun, EvaluationReport, MonitorRef, PaperRow,
};
use compnet::{adaptation, eval, io, plot};
use firmware::adaptation::AdaptationConfig;
use firmware::monitor::MonitorConfig;
use std::path::{Path, PathBuf};

/// `evaluate` options.
#[derive(Debug, Args)]
pub struct EvaluateArgs {
    /// The network (safetensors, or ONNX exported from PyTorch).
    #[arg(long = "network", alias = "model", value_name = "FILE")]
    pub network: PathBuf,
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
    /// Also run the drive's online friction adaptation after the model alone, the
    /// baseline and the network, with this forgetting time constant [s], at each log's
    /// tick rate (`adapted` columns and report fields).
    #[arg(long)]
    pub adapt_time_constant_s: Option<f32>,
    /// Largest |correction| of the adaptation [N·m].
    #[arg(long, default_value_t = 10.0)]
    pub adapt_max_nm: f32,
    /// Score every figure against the measured torque zero-phase low-passed at this
    /// cut-off [Hz] (4th-order Butterworth), so that sensor noise above it, which no
    /// feedforward can cancel, does not count; the network and the adaptation still see
    /// the torque as logged.
    #[arg(long)]
    pub score_cutoff_hz: Option<f64>,
    /// Also run the drive's do-no-harm monitor after the network (and after the
    /// adaptation, when asked for), comparing it with the model alone over this window
    /// [s] at each log's tick rate (`monitored` report fields).
    #[arg(long)]
    pub monitor_window_s: Option<f32>,
    /// Time the monitor's gain takes to fade from 1 to 0 [s].
    #[arg(long, default_value_t = 0.5)]
    pub monitor_fade_s: f32,
    /// Hysteresis of the monitor's gain, in [0, 1).
    #[arg(long, default_value_t = 0.05)]
    pub monitor_hysteresis: f32,
}

/// Runs `evaluate`.
pub fn run(a: EvaluateArgs) -> Result<()> {
    let spec = a.features.spec()?;
    let model = io::read_model(&a.network)?;
    spec.check_model(&model)
        .with_context(|| format!("{}", a.network.display()))?;
    // The linear baseline, fitted on --baseline-data (before any output).
    let baseline = if a.baseline_data.is_empty() {
        None
    } else {
        let tables: Vec<Table> = a
            .baseline_data
            .iter()
            .map(|p| Table::read(p))
            .collect::<Result<_>>()?;
        Some(compnet::baseline::fit(
            &tables,
            &eval::target_joints(&spec),
        )?)
    };
    let tables: Vec<Table> = a
        .data
        .iter()
        .map(|p| Table::read(p))
        .collect::<Result<_>>()?;
    for (p, t) in a.data.iter().zip(&tables) {
        if t.len() < 2 {
            bail!(
                "{}: {} data rows: a run to evaluate needs at least two (an RMS over fewer says nothing)",
                p.display(),
                t.len()
            );
        }
    }
    // The torque the figures are scored against: as logged, or low-passed.
    let scored_tables: Vec<Table> = match a.score_cutoff_hz {
        Some(fc) => tables
            .iter()
            .map(|t| adaptation::low_passed(t, fc))
            .collect::<Result<_>>()?,
        None => tables.clone(),
    };
    let mut seqs: Vec<Sequence> = tables
        .iter()
        .map(|t| spec.sequence(t))
        .collect::<Result<_>>()?;
    if a.score_cutoff_hz.is_some() {
        for (s, scored) in seqs.iter_mut().zip(&scored_tables) {
            s.targets = spec.sequence(scored)?.targets;
        }
    }
    let adaptation = a.adapt_time_constant_s.map(|t| AdaptationConfig {
        time_constant_s: t,
        max_correction_nm: a.adapt_max_nm,
    });
    if let Some(cfg) = adaptation
        && cfg.forgetting(1.0e3).is_none()
    {
        bail!(
            "--adapt-time-constant-s {} / --adapt-max-nm {}: both must be finite and positive",
            cfg.time_constant_s,
            cfg.max_correction_nm
        );
    }
    let monitor = a.monitor_window_s.map(|w| MonitorConfig {
        window_s: w,
        fade_s: a.monitor_fade_s,
        hysteresis: a.monitor_hysteresis,
    });
    if let Some(cfg) = monitor
        && cfg.per_tick(1.0e3).is_none()
    {
        bail!(
            "--monitor-window-s {} / --monitor-fade-s {} / --monitor-hysteresis {}: the window \
             and the fade must be finite and positive, the hysteresis in [0, 1)",
            cfg.window_s,
            cfg.fade_s,
            cfg.hysteresis
        );
    }
    let mut reports = Vec::new();
    let mut figures = Vec::new();
    for (i, ((p, s), (table, scored))) in a
        .data
        .iter()
        .zip(seqs)
        .zip(tables.iter().zip(&scored_tables))
        .enumerate()
    {
        // The learned share faded outside the training envelope, as the drive fades it.
        let mut pred = model.stream(&s.inputs)?;
        let outside = if model.envelope.is_empty() {
            vec![0.0; model.dims.output]
        } else {
            let weights = compnet::envelope::step_weights(&model.envelope, &spec, table, &s)
                .with_context(|| format!("{}: the training envelope's inputs", p.display()))?;
            compnet::envelope::fade_predictions(&mut pred, &s, &weights);
            compnet::envelope::outside_share(&weights, model.dims.output)
        };
        let rows = eval::evaluate_streamed(&model, &s, &pred)?;
        let base_rms = match &baseline {
            Some(b) => eval::baseline_rms(&spec, scored, s.len(), b)?,
            None => vec![None; rows.len()],
        };
        let adapted = match adaptation {
            Some(cfg) => {
                eval::adapted_rms(&pred, &spec, (table, scored), &s, baseline.as_ref(), cfg)?
            }
            None => vec![None; rows.len()],
        };
        let monitored = match monitor {
            Some(cfg) => eval::monitored_rms(&pred, &spec, (table, scored), &s, adaptation, cfg)?,
            None => vec![None; rows.len()],
        };
        let deployed = match monitor {
            Some(cfg) => eval::deployed_rms(
                &pred,
                &spec,
                (table, scored),
                &s,
                baseline.as_ref(),
                adaptation,
                cfg,
            )?,
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
            .zip(adapted)
            .zip(&outside)
            .zip(monitored)
            .zip(deployed)
            .map(
                |(
                    ((((eval, baseline_rms_nm), adapted), &outside_envelope_share), monitored),
                    deployed,
                )| {
                    eval::ReportRow {
                        eval,
                        samples: s.len(),
                        baseline_rms_nm,
                        adapted,
                        outside_envelope_share,
                        monitored,
                        deployed,
                    }
                },
            )
            .collect();
        artifacts::ensure_finite(
            &format!("{}: evaluation", p.display()),
            rows.iter().flat_map(|r| {
                r.eval
                    .figures()
                    .chain(r.baseline_rms_nm)
                    .chain(r.adapted.iter().flat_map(|a| a.figures()))
                    .chain(r.monitored.iter().flat_map(|m| m.figures()))
                    .chain(r.deployed.iter().flat_map(|d| d.figures()))
            }),
        )?;
        let plain: Vec<eval::TargetEval> = rows.iter().map(|r| r.eval.clone()).collect();
        println!(
            "{} ({} steps, streamed):\n{}",
            p.display(),
            s.len(),
            if baseline.is_some() || adaptation.is_some() {
                eval::markdown_with_baseline(&rows)
            } else {
                eval::markdown(&plain)
            }
        );
        if !model.envelope.is_empty() {
            let shares: Vec<String> = rows
                .iter()
                .map(|r| format!("{} {:.1} %", r.eval.name, 100.0 * r.outside_envelope_share))
                .collect();
            println!(
                "outside the training envelope (learned share faded): {}",
                shares.join(", ")
            );
        }
        if monitor.is_some() {
            let lines: Vec<String> = rows
                .iter()
                .filter_map(|r| {
                    let m = r.monitored?;
                    let adapted = match (m.adapted_compensated_rms_nm, m.adapted_faded_share) {
                        (Some(v), Some(f)) => {
                            format!("; adapted {v:.4} N m, faded {:.1} %", 100.0 * f)
                        }
                        _ => String::new(),
                    };
                    Some(format!(
                        "| {} | {:.4} | {:.1} %{adapted} |",
                        r.eval.name,
                        m.compensated_rms_nm,
                        100.0 * m.faded_share
                    ))
                })
                .collect();
            println!(
                "After the do-no-harm monitor (RMS N m, share of rows faded):\n{}",
                lines.join("\n")
            );
        }
        let paper = spec
            .preset
            .starts_with("paper")
            .then(|| eval::beside_paper_markdown(&a.features.joints, &plain))
            .flatten();
        if let Some(t) = &paper {
            println!("Beside the paper's Table 2 (Zhang et al. 2020, N m):\n{t}");
        }
        // The paper's figures for the same joints, beside ours.
        let paper_table2 = paper.as_ref().map(|_| {
            eval::PAPER_TABLE2
                .iter()
                .map(|&(joint, rms_before, rms_after, reduction_pct)| PaperRow {
                    joint,
                    rms_before,
                    rms_after,
                    reduction_pct,
                })
                .collect()
        });
        reports.push(EvaluatedRun {
            file: p.display().to_string(),
            steps: s.len(),
            outputs: rows,
            paper_table2,
        });
    }
    let report = match &a.report {
        Some(r) => Some((
            r,
            serde_json::to_string_pretty(&EvaluationReport {
                preset: spec.preset.clone(),
                data: reports,
                baseline: baseline.as_ref().map(|b| BaselineRef {
                    data: a
                        .baseline_data
                        .iter()
                        .map(|p| p.display().to_string())
                        .collect(),
                    fit: b.clone(),
                }),
                adaptation: adaptation.map(|c| AdaptationRef {
                    time_constant_s: c.time_constant_s,
                    max_correction_nm: c.max_correction_nm,
                }),
                score_cutoff_hz: a.score_cutoff_hz,
                monitor: monitor.map(|c| MonitorRef {
                    window_s: c.window_s,
                    fade_s: c.fade_s,
                    hysteresis: c.hysteresis,
                }),
            })?,
        )),
        None => None,
    };
    // The figures and the report: all or none, the figures' folder made as `excite
    // --out` makes its own.
    if let (Some(dir), false) = (&a.figures, figures.is_empty()) {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("creating the figures folder {}", dir.display()))?;
    }
    let mut files: Vec<(&Path, &[u8])> = figures
        .iter()
        .map(|(p, svg)| (p.as_path(), svg.as_bytes()))
        .collect();
    if let Some((path, text)) = &report {
        files.push((path.as_path(), text.as_bytes()));
    }
    artifacts::write_atomic_all(&files)
}
