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
#[allow(clippy::needless_range_loop)] // three parallel per-step tables indexed alike
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
            reduction_pct: if rb > 0.0 {
                100.0 * (1.0 - ra / rb)
            } else {
                0.0
            },
            rms_persistence: (p_ok && !seq.is_empty()).then(|| (p / n).sqrt()),
        });
    }
    Ok(out)
}

/// A Markdown table of the figures.
pub fn markdown(rows: &[TargetEval]) -> String {
    let mut s = String::from(
        "| output | RMS before | RMS after | reduction % | RMS persistence |\n|---|---:|---:|---:|---:|\n",
    );
    for r in rows {
        let p = r
            .rms_persistence
            .map_or("-".to_string(), |v| format!("{v:.4}"));
        s += &format!(
            "| {} | {:.4} | {:.4} | {:.1} | {} |\n",
            r.name, r.rms_before, r.rms_after, r.reduction_pct, p
        );
    }
    s
}

/// The paper's Table 2 (Zhang et al. 2020), wrist joints 4-6: (joint, RMS before,
/// RMS after [N m], reduction [%]).
pub const PAPER_TABLE2: [(usize, f64, f64, f64); 3] = [
    (4, 3.61, 1.21, 66.5),
    (5, 4.84, 1.02, 78.9),
    (6, 6.10, 2.33, 61.8),
];

/// For the paper's wrist joints (4, 5, 6, in this order): a Markdown table of ours beside
/// the paper's Table 2; `None` for other joints.
pub fn beside_paper_markdown(joints: &[usize], rows: &[TargetEval]) -> Option<String> {
    if joints != [4, 5, 6] || rows.len() != 3 {
        return None;
    }
    let mut s = String::from(
        "| joint | paper before | paper after | paper reduction % | ours before | ours after | ours reduction % | ours persistence |\n|---|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for ((j, pb, pa, pr), r) in PAPER_TABLE2.iter().zip(rows) {
        let p = r
            .rms_persistence
            .map_or("-".to_string(), |v| format!("{v:.4}"));
        s += &format!(
            "| {j} | {pb:.2} | {pa:.2} | {pr:.1} | {:.4} | {:.4} | {:.1} | {p} |\n",
            r.rms_before, r.rms_after, r.reduction_pct
        );
    }
    Some(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(before: f64, after: f64) -> TargetEval {
        TargetEval {
            name: "y".into(),
            rms_before: before,
            rms_after: after,
            reduction_pct: 100.0 * (1.0 - after / before),
            rms_persistence: Some(0.5),
        }
    }

    #[test]
    fn the_paper_table_stands_beside_the_wrist_only() {
        let rows = [row(2.0, 1.0), row(3.0, 1.5), row(4.0, 1.0)];
        let t = beside_paper_markdown(&[4, 5, 6], &rows).expect("wrist");
        assert_eq!(t.lines().count(), 5);
        assert!(t.contains("| 5 | 4.84 | 1.02 | 78.9 | 3.0000 | 1.5000 | 50.0 | 0.5000 |"));
        assert!(beside_paper_markdown(&[1, 2, 3], &rows).is_none());
        assert!(beside_paper_markdown(&[4, 5, 6], &rows[..2]).is_none());
    }
}
