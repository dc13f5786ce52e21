//! Each precision's accuracy against the f32 network, as a table.
use super::*;

/// One precision's accuracy on one output.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct AccuracyRow {
    /// Precision name (`f32`, `int16`, `int8`).
    pub precision: String,
    /// Output name.
    pub output: String,
    /// RMS of the precision's streamed output against the f32 firmware step.
    pub rms_vs_f32: f64,
    /// RMS error against the targets ("compensated RMS"), with targets.
    pub compensated_rms: Option<f64>,
    /// f32's compensated RMS, with targets.
    pub f32_compensated_rms: Option<f64>,
}

/// Per-output RMS of each precision's streamed output against the f32 firmware step
/// (`nn::model::LstmModel::stream`), and, with `targets`, each one's RMS error against
/// the targets ("compensated RMS") beside f32's.
pub fn accuracy(
    m: &LstmModel,
    inputs: &[Vec<f32>],
    targets: Option<&[Vec<f32>]>,
) -> Result<Vec<AccuracyRow>> {
    let reference = m.stream(inputs)?;
    let rms = |a: &[Vec<f32>], b: &[Vec<f32>], j: usize| -> f64 {
        let s: f64 = a
            .iter()
            .zip(b)
            .map(|(x, y)| ((x[j] - y[j]) as f64).powi(2))
            .sum();
        (s / a.len().max(1) as f64).sqrt()
    };
    let mut rows = Vec::new();
    for p in Precision::ALL {
        let y = Exported::new(m, p)?.stream(inputs);
        for j in 0..m.dims.output {
            rows.push(AccuracyRow {
                precision: p.name().to_string(),
                output: m.output_names[j].clone(),
                rms_vs_f32: rms(&y, &reference, j),
                compensated_rms: targets.map(|t| rms(&y, t, j)),
                f32_compensated_rms: targets.map(|t| rms(&reference, t, j)),
            });
        }
    }
    Ok(rows)
}

/// [`accuracy`] as a Markdown table (ratio = compensated RMS / f32's).
pub fn accuracy_markdown(rows: &[AccuracyRow]) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "| precision | output | RMS vs f32 step | compensated RMS | f32 compensated RMS | ratio |"
    );
    let _ = writeln!(out, "|---|---|---:|---:|---:|---:|");
    for r in rows {
        let (c, f, ratio) = match (r.compensated_rms, r.f32_compensated_rms) {
            (Some(c), Some(f)) => (
                format!("{c:.5}"),
                format!("{f:.5}"),
                format!("{:.4}", c / f),
            ),
            _ => ("-".into(), "-".into(), "-".into()),
        };
        let _ = writeln!(
            out,
            "| {} | {} | {:.3e} | {c} | {f} | {ratio} |",
            r.precision, r.output, r.rms_vs_f32
        );
    }
    out
}
