//! The JSON reports of `train` and `evaluate`: one type each, written by the command line
//! and read back with the same type (the demo's report is built from them), so a renamed
//! field is a compile error, not a missing number.
use crate::baseline::LinearBaseline;
use crate::eval::{ReportRow, TargetEval};
use serde::{Deserialize, Serialize};

/// One held-out block's figures in a training report.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TrainTestBlock {
    /// The dataset the block was cut from.
    pub file: String,
    /// Steps streamed.
    pub steps: usize,
    /// Per output.
    pub outputs: Vec<TargetEval>,
}

/// `train --report`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TrainReport {
    /// Feature preset.
    pub preset: String,
    /// Learning rate used.
    pub lr: f64,
    /// (learning rate, validation loss) of each candidate tried.
    pub lr_trials: Vec<(f64, f64)>,
    /// Epochs run.
    pub epochs: usize,
    /// Epoch of the kept weights, 1-based.
    pub best_epoch: usize,
    /// Per output, the do-no-harm gain applied on the validation runs (1: none).
    pub output_gains: Vec<f64>,
    /// The drive adaptation whose leftover the network learned (`drive` preset).
    #[serde(default)]
    pub adaptation: Option<AdaptationRef>,
    /// Mean training loss per epoch.
    pub train_loss: Vec<f64>,
    /// Validation loss per epoch.
    pub val_loss: Vec<f64>,
    /// The held-out test blocks.
    pub test: Vec<TrainTestBlock>,
}

/// One of the paper's Table 2 rows, beside ours.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PaperRow {
    /// Joint (1-based).
    pub joint: usize,
    /// The paper's RMS before compensation [N·m].
    pub rms_before: f64,
    /// The paper's RMS after compensation [N·m].
    pub rms_after: f64,
    /// The paper's reduction [%].
    pub reduction_pct: f64,
}

/// One evaluated run.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct EvaluatedRun {
    /// The dataset.
    pub file: String,
    /// Steps streamed.
    pub steps: usize,
    /// Per output.
    pub outputs: Vec<ReportRow>,
    /// The paper's Table 2 for the same joints (`paper` preset on joints 4-6).
    pub paper_table2: Option<Vec<PaperRow>>,
}

/// The linear baseline an evaluation was read against.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct BaselineRef {
    /// The datasets it was fitted on.
    pub data: Vec<String>,
    /// The fit.
    pub fit: LinearBaseline,
}

/// `evaluate --report`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct EvaluationReport {
    /// Feature preset.
    pub preset: String,
    /// Per run.
    pub data: Vec<EvaluatedRun>,
    /// The linear baseline, when one was fitted.
    pub baseline: Option<BaselineRef>,
    /// The online friction adaptation the `adapted` figures ran, when asked for.
    #[serde(default)]
    pub adaptation: Option<AdaptationRef>,
    /// The cut-off [Hz] of the low-pass the measured torque was scored through
    /// (`None`: as logged).
    #[serde(default)]
    pub score_cutoff_hz: Option<f64>,
    /// The do-no-harm monitor the `monitored` figures ran, when asked for.
    #[serde(default)]
    pub monitor: Option<MonitorRef>,
}

/// The do-no-harm monitor's settings in a report (`firmware::monitor::MonitorConfig`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct MonitorRef {
    /// Window (time constant of the scores) [s].
    pub window_s: f32,
    /// Time of a full fade of the gain [s].
    pub fade_s: f32,
    /// Hysteresis of the gain.
    pub hysteresis: f32,
}

/// The online friction adaptation's settings in a report.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct AdaptationRef {
    /// Forgetting time constant [s].
    pub time_constant_s: f32,
    /// Largest |correction| [N·m].
    pub max_correction_nm: f32,
}
