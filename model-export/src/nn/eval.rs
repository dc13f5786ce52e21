//! The paper's evaluation, streaming the FIRMWARE f32 step over whole sequences.
use super::data::Sequence;
use super::model::LstmModel;
use anyhow::Result;
use serde::Serialize;

/// Figures for one output (one joint).
#[derive(Clone, Debug, Serialize)]
pub struct TargetEval {
    /// Output name.
    pub name: String,
    /// RMS error of the identified model alone (raw units, e.g. N·m).
    pub rms_before: f64,
    /// RMS error after compensation (the network's prediction).
    pub rms_after: f64,
    /// `100 · (1 - after / before)`.
    pub reduction_pct: f64,
    /// RMS error of the persistence baseline (`paper` preset: τ(t+1) = τ(t)).
    pub rms_persistence: Option<f64>,
}

/// Streams `m` from the zero state over `seq` and compares with the baselines.
pub fn evaluate(m: &LstmModel, seq: &Sequence) -> Result<Vec<TargetEval>> {
    let pred = m.stream(&seq.inputs)?;
    let n = seq.len().max(1) as f64;
    let mut out = Vec::new();
    for k in 0..m.dims.output {
        let (mut b, mut a, mut p, mut p_ok) = (0.0f64, 0.0f64, 0.0f64, true);
        for t in 0..seq.len() {
            let y = seq.targets[t][k] as f64;
            b += (y - seq.model_only[t][k] as f64).powi(2);
            a += (y - pred[t][k] as f64).powi(2);
            match seq.persistence[t][k] {
                Some(v) => p += (y - v as f64).powi(2),
                None => p_ok = false,
            }
        }
        let (rb, ra) = ((b / n).sqrt(), (a / n).sqrt());
        out.push(TargetEval {
            name: m.output_names[k].clone(),
            rms_before: rb,
            rms_after: ra,
            reduction_pct: if rb > 0.0 { 100.0 * (1.0 - ra / rb) } else { 0.0 },
            rms_persistence: (p_ok && !seq.is_empty()).then(|| (p / n).sqrt()),
        });
    }
    Ok(out)
}

/// A Markdown table of the figures.
pub fn markdown(rows: &[TargetEval]) -> String {
    let mut s = String::from("| output | RMS before | RMS after | reduction % | RMS persistence |\n|---|---:|---:|---:|---:|\n");
    for r in rows {
        let p = r.rms_persistence.map_or("-".to_string(), |v| format!("{v:.4}"));
        s += &format!("| {} | {:.4} | {:.4} | {:.1} | {} |\n", r.name, r.rms_before, r.rms_after, r.reduction_pct, p);
    }
    s
}
