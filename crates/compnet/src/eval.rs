//! The paper's evaluation, streaming the FIRMWARE f32 step over whole sequences.
use super::adaptation;
use super::baseline::LinearBaseline;
use super::data::{FeatureSpec, Sequence, Table};
use super::model::LstmModel;
use anyhow::{Result, bail};
use firmware::adaptation::AdaptationConfig;
use firmware::monitor::MonitorConfig;
use serde::{Deserialize, Serialize};

/// Figures for one output (one joint).
#[derive(Clone, Debug, Serialize, Deserialize)]
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

impl TargetEval {
    /// Every number of the row (checked finite before a report is written).
    pub fn figures(&self) -> impl Iterator<Item = f64> + '_ {
        [self.rms_before, self.rms_after, self.reduction_pct]
            .into_iter()
            .chain(self.rms_persistence)
    }
}

/// Streams `m` from the zero state over `seq` and compares with the baselines.
pub fn evaluate(m: &LstmModel, seq: &Sequence) -> Result<Vec<TargetEval>> {
    evaluate_streamed(m, seq, &m.stream(&seq.inputs)?)
}

/// [`evaluate`] with `m`'s predictions `pred` over `seq` already streamed.
#[allow(clippy::needless_range_loop)] // three parallel per-step tables indexed alike
pub fn evaluate_streamed(
    m: &LstmModel,
    seq: &Sequence,
    pred: &[Vec<f32>],
) -> Result<Vec<TargetEval>> {
    if pred.len() != seq.len() {
        bail!("{} predictions for {} steps", pred.len(), seq.len());
    }
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

/// One output's figures in the `evaluate` report: [`TargetEval`] plus rows and baseline.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ReportRow {
    /// The network's figures.
    #[serde(flatten)]
    pub eval: TargetEval,
    /// Rows evaluated (target steps).
    pub samples: usize,
    /// RMS [N·m] of `tau_meas - baseline` on the same rows (`None`: no baseline given, or
    /// the output is not a joint's measured torque).
    pub baseline_rms_nm: Option<f64>,
    /// The same predictions followed by the drive's online friction adaptation (`None`:
    /// not asked for, or the output is not a joint's measured torque).
    #[serde(default)]
    pub adapted: Option<AdaptedRms>,
    /// Share of the rows outside the network's training envelope, where the drive fades
    /// its learned share (`firmware::envelope`; 0 for a network without one).
    #[serde(default)]
    pub outside_envelope_share: f64,
    /// The network's prediction followed by the drive's do-no-harm monitor (`None`: not
    /// asked for, or the output is not a joint's measured torque).
    #[serde(default)]
    pub monitored: Option<MonitoredRms>,
    /// The deployed compensator (envelope, adaptation when asked for, monitor) beside the
    /// model alone and the linear baseline, on all rows and apart on the rows where the
    /// joint moves and where it is held (`None`: no monitor asked for, or the output is
    /// not a joint's measured torque).
    #[serde(default)]
    pub deployed: Option<DeployedRms>,
}

/// A joint is held on a row where its |velocity| is below this [rad/s] (the study's
/// `moving_samples` threshold and `torque --trim-rest-rad-s` of its test runs).
pub const HELD_BELOW_RAD_S: f32 = 0.01;

/// RMS [N·m] of the deployed compensator and of what it is read against, on one set of
/// rows.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RowsRms {
    /// Rows scored.
    pub rows: usize,
    /// The identified model alone (what every fade falls back to).
    pub model_rms_nm: f64,
    /// The linear baseline (`None`: no baseline given).
    pub baseline_rms_nm: Option<f64>,
    /// The linear baseline followed by the online adaptation (`None`: no baseline or no
    /// adaptation).
    pub adapted_baseline_rms_nm: Option<f64>,
    /// The compensator as the drive runs it without the adaptation: network (faded
    /// outside its envelope), then the monitor.
    pub deployed_rms_nm: f64,
    /// The same with the adaptation between the network and the monitor (`None`: no
    /// adaptation asked for).
    pub adapted_deployed_rms_nm: Option<f64>,
}

impl RowsRms {
    /// Every number (checked finite before a report is written).
    pub fn figures(&self) -> impl Iterator<Item = f64> + '_ {
        [self.model_rms_nm, self.deployed_rms_nm]
            .into_iter()
            .chain(self.baseline_rms_nm)
            .chain(self.adapted_baseline_rms_nm)
            .chain(self.adapted_deployed_rms_nm)
    }
}

/// [`RowsRms`] on all rows, on the rows where the joint moves and where it is held
/// (`None`: no such row).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct DeployedRms {
    /// Every scored row.
    pub all: RowsRms,
    /// Rows with |qd| at or above [`HELD_BELOW_RAD_S`].
    pub moving: Option<RowsRms>,
    /// Rows with |qd| below it.
    pub held: Option<RowsRms>,
}

impl DeployedRms {
    /// Every number (checked finite before a report is written).
    pub fn figures(&self) -> impl Iterator<Item = f64> + '_ {
        self.all
            .figures()
            .chain(self.moving.iter().flat_map(|r| r.figures()))
            .chain(self.held.iter().flat_map(|r| r.figures()))
    }
}

/// Per output of `spec`: the deployed compensator's figures ([`DeployedRms`]): the
/// network's predictions `pred` (already faded outside the envelope) followed by the
/// adaptation (when given) and the monitor `config` against the model alone, as the
/// drive chains them, learning from `table`'s measured torque, scored against
/// `scored`'s, beside the model alone and the linear baseline (static and adapted);
/// `None` for outputs that are not a joint's measured torque.
pub fn deployed_rms(
    pred: &[Vec<f32>],
    spec: &FeatureSpec,
    (table, scored): (&Table, &Table),
    seq: &Sequence,
    baseline: Option<&LinearBaseline>,
    adaptation_config: Option<AdaptationConfig>,
    config: MonitorConfig,
) -> Result<Vec<Option<DeployedRms>>> {
    if pred.len() != seq.len() {
        bail!("{} predictions for {} steps", pred.len(), seq.len());
    }
    let baseline_pred = baseline.map(|b| b.predict(table)).transpose()?;
    let rows = table.len();
    let mut out = Vec::new();
    for (k, t) in spec.targets.iter().enumerate() {
        let Some(j) = target_joint(spec, k) else {
            out.push(None);
            continue;
        };
        check_span(table, seq.len(), t.shift)?;
        let per_row = |value: &dyn Fn(usize) -> f64| absolute_per_row(rows, seq, k, t.shift, value);
        let measured = scored.column(&format!("tau_meas_j{j}"))?;
        let qd = table.column(&format!("qd_j{j}"))?;
        let base = per_row(&|r| seq.model_only[r][k] as f64);
        let full = per_row(&|r| pred[r][k] as f64);
        let deployed = crate::monitor::monitor(table, j, &base, &full, config)?.torque_nm;
        let adapted_deployed = match adaptation_config {
            Some(cfg) => Some(
                crate::monitor::monitor(
                    table,
                    j,
                    &base,
                    &adaptation::adapt(table, j, &full, cfg)?,
                    config,
                )?
                .torque_nm,
            ),
            None => None,
        };
        let base_line = match (&baseline_pred, baseline) {
            (Some(p), Some(b)) => b.joints.iter().position(|&x| x == j).map(|i| p[i].clone()),
            _ => None,
        };
        let adapted_base_line = match (&base_line, adaptation_config) {
            (Some(p), Some(cfg)) => Some(adaptation::adapt(table, j, p, cfg)?),
            _ => None,
        };
        let span = t.shift..t.shift + seq.len();
        let figures = |keep: &dyn Fn(usize) -> bool| -> Option<RowsRms> {
            let picked: Vec<usize> = span.clone().filter(|&r| keep(r)).collect();
            let rms = |p: &[f64]| {
                let ss: f64 = picked
                    .iter()
                    .map(|&r| (measured[r] as f64 - p[r]).powi(2))
                    .sum();
                (ss / picked.len() as f64).sqrt()
            };
            (!picked.is_empty()).then(|| RowsRms {
                rows: picked.len(),
                model_rms_nm: rms(&base),
                baseline_rms_nm: base_line.as_deref().map(rms),
                adapted_baseline_rms_nm: adapted_base_line.as_deref().map(rms),
                deployed_rms_nm: rms(&deployed),
                adapted_deployed_rms_nm: adapted_deployed.as_deref().map(rms),
            })
        };
        let Some(all) = figures(&|_| true) else {
            out.push(None);
            continue;
        };
        out.push(Some(DeployedRms {
            all,
            moving: figures(&|r| qd[r].abs() >= HELD_BELOW_RAD_S),
            held: figures(&|r| qd[r].abs() < HELD_BELOW_RAD_S),
        }));
    }
    Ok(out)
}

/// RMS [N·m] of the network's prediction after the do-no-harm monitor
/// ([`crate::monitor`]), which compares it with the identified model alone, on the same
/// rows and against the same torque.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct MonitoredRms {
    /// The network's prediction, monitored.
    pub compensated_rms_nm: f64,
    /// Share of the rows where the monitor's gain was below 1.
    pub faded_share: f64,
    /// The network's prediction followed by the adaptation, then monitored (`None`: no
    /// adaptation asked for).
    pub adapted_compensated_rms_nm: Option<f64>,
    /// Share of the rows where the adapted prediction's gain was below 1.
    pub adapted_faded_share: Option<f64>,
}

impl MonitoredRms {
    /// Every number (checked finite before a report is written).
    pub fn figures(&self) -> impl Iterator<Item = f64> + '_ {
        [self.compensated_rms_nm, self.faded_share]
            .into_iter()
            .chain(self.adapted_compensated_rms_nm)
            .chain(self.adapted_faded_share)
    }
}

/// Per output of `spec`: the network's predictions `pred` over `seq` followed by the
/// do-no-harm monitor `config` against the model alone (and, with `adaptation`, the
/// same after the adaptation, as the drive chains them), learning from `table`'s
/// measured torque and scored against `scored`'s; `None` for outputs that are not a
/// joint's measured torque.
pub fn monitored_rms(
    pred: &[Vec<f32>],
    spec: &FeatureSpec,
    (table, scored): (&Table, &Table),
    seq: &Sequence,
    adaptation_config: Option<AdaptationConfig>,
    config: MonitorConfig,
) -> Result<Vec<Option<MonitoredRms>>> {
    if pred.len() != seq.len() {
        bail!("{} predictions for {} steps", pred.len(), seq.len());
    }
    let rows = table.len();
    let mut out = Vec::new();
    for (k, t) in spec.targets.iter().enumerate() {
        let Some(j) = target_joint(spec, k) else {
            out.push(None);
            continue;
        };
        check_span(table, seq.len(), t.shift)?;
        let per_row = |value: &dyn Fn(usize) -> f64| absolute_per_row(rows, seq, k, t.shift, value);
        let scored = scored.column(&format!("tau_meas_j{j}"))?;
        let span = t.shift..t.shift + seq.len();
        let base = per_row(&|r| seq.model_only[r][k] as f64);
        let full = per_row(&|r| pred[r][k] as f64);
        let run = |full: &[f64]| -> Result<(f64, f64)> {
            let m = crate::monitor::monitor(table, j, &base, full, config)?;
            Ok((
                adaptation::rms_nm(scored, &m.torque_nm, span.clone()).unwrap_or(0.0),
                m.faded_share(span.clone()),
            ))
        };
        let (compensated_rms_nm, faded_share) = run(&full)?;
        let adapted = match adaptation_config {
            Some(cfg) => Some(run(&adaptation::adapt(table, j, &full, cfg)?)?),
            None => None,
        };
        out.push(Some(MonitoredRms {
            compensated_rms_nm,
            faded_share,
            adapted_compensated_rms_nm: adapted.map(|a| a.0),
            adapted_faded_share: adapted.map(|a| a.1),
        }));
    }
    Ok(out)
}

/// RMS [N·m] of each prediction followed by the online friction adaptation
/// ([`crate::adaptation`]), on the same rows and against the same torque.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct AdaptedRms {
    /// The identified model alone, adapted.
    pub model_rms_nm: f64,
    /// The linear baseline, adapted (`None`: no baseline given).
    pub baseline_rms_nm: Option<f64>,
    /// The network's prediction, adapted.
    pub compensated_rms_nm: f64,
}

impl AdaptedRms {
    /// Every number (checked finite before a report is written).
    pub fn figures(&self) -> impl Iterator<Item = f64> + '_ {
        [self.model_rms_nm, self.compensated_rms_nm]
            .into_iter()
            .chain(self.baseline_rms_nm)
    }
}

/// Per output of `spec`: the model alone, the baseline and the network's predictions
/// `pred` over `seq` (as [`evaluate_streamed`] takes them), each followed by the online
/// adaptation `config` over `table` (which learns from the measured torque as logged),
/// scored on the sequence's rows against `scored`'s `tau_meas` (the same table, or
/// [`adaptation::low_passed`]); `None` for outputs that are not a joint's measured torque.
pub fn adapted_rms(
    pred: &[Vec<f32>],
    spec: &FeatureSpec,
    (table, scored): (&Table, &Table),
    seq: &Sequence,
    baseline: Option<&LinearBaseline>,
    config: AdaptationConfig,
) -> Result<Vec<Option<AdaptedRms>>> {
    if pred.len() != seq.len() {
        bail!("{} predictions for {} steps", pred.len(), seq.len());
    }
    let baseline_pred = baseline.map(|b| b.predict(table)).transpose()?;
    let rows = table.len();
    let mut out = Vec::new();
    for (k, t) in spec.targets.iter().enumerate() {
        let Some(j) = target_joint(spec, k) else {
            out.push(None);
            continue;
        };
        check_span(table, seq.len(), t.shift)?;
        let per_row = |value: &dyn Fn(usize) -> f64| absolute_per_row(rows, seq, k, t.shift, value);
        let scored = scored.column(&format!("tau_meas_j{j}"))?;
        let span = t.shift..t.shift + seq.len();
        let rms = |p: Vec<f64>| -> Result<f64> {
            let a = adaptation::adapt(table, j, &p, config)?;
            Ok(adaptation::rms_nm(scored, &a, span.clone()).unwrap_or(0.0))
        };
        let baseline_rms_nm = match (&baseline_pred, baseline) {
            (Some(p), Some(b)) => match b.joints.iter().position(|&x| x == j) {
                Some(i) => Some(rms(p[i].clone())?),
                None => None,
            },
            _ => None,
        };
        out.push(Some(AdaptedRms {
            model_rms_nm: rms(per_row(&|r| seq.model_only[r][k] as f64))?,
            baseline_rms_nm,
            compensated_rms_nm: rms(per_row(&|r| pred[r][k] as f64))?,
        }));
    }
    Ok(out)
}

/// The robot joint (1-based) whose measured torque `tau_meas_jN` an output predicts.
pub fn target_joint(spec: &FeatureSpec, output: usize) -> Option<usize> {
    spec.targets
        .get(output)?
        .column
        .strip_prefix("tau_meas_j")?
        .parse()
        .ok()
}

/// Joints (1-based, first-seen order) whose measured torque some output of `spec` predicts.
pub fn target_joints(spec: &FeatureSpec) -> Vec<usize> {
    let mut js = Vec::new();
    for k in 0..spec.targets.len() {
        if let Some(j) = target_joint(spec, k).filter(|j| !js.contains(j)) {
            js.push(j);
        }
    }
    js
}

/// Per output of `spec`: RMS [N·m] of `tau_meas - baseline` over the `steps` rows of the
/// sequence `spec` extracts from `table` (row `t` is compared at the target's step
/// `t + shift`); `None` for outputs that are not a fitted joint's measured torque.
pub fn baseline_rms(
    spec: &FeatureSpec,
    table: &Table,
    steps: usize,
    baseline: &LinearBaseline,
) -> Result<Vec<Option<f64>>> {
    let pred = baseline.predict(table)?;
    let mut out = Vec::new();
    for (k, t) in spec.targets.iter().enumerate() {
        let Some(b) = target_joint(spec, k)
            .and_then(|j| baseline.joints.iter().position(|&x| x == j))
            .map(|i| &pred[i])
        else {
            out.push(None);
            continue;
        };
        check_span(table, steps, t.shift)?;
        let y = table.column(&t.column)?;
        let ss: f64 = (0..steps)
            .map(|r| (y[r + t.shift] as f64 - b[r + t.shift]).powi(2))
            .sum();
        out.push((steps > 0).then(|| (ss / steps as f64).sqrt()));
    }
    Ok(out)
}

/// A Markdown table of the figures with the linear baseline's RMS [N·m] beside them, and
/// the adapted figures when the rows have them.
pub fn markdown_with_baseline(rows: &[ReportRow]) -> String {
    let adapted = rows.iter().any(|r| r.adapted.is_some());
    let mut s = String::from(
        "| output | RMS before | RMS after | reduction % | RMS persistence | RMS baseline |",
    );
    if adapted {
        s += " adapted: model | adapted: baseline | adapted: network |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|\n";
    } else {
        s += "\n|---|---:|---:|---:|---:|---:|\n";
    }
    let cell = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.4}"));
    for r in rows {
        let e = &r.eval;
        s += &format!(
            "| {} | {:.4} | {:.4} | {:.1} | {} | {} |",
            e.name,
            e.rms_before,
            e.rms_after,
            e.reduction_pct,
            cell(e.rms_persistence),
            cell(r.baseline_rms_nm)
        );
        if adapted {
            let a = r.adapted.as_ref();
            s += &format!(
                " {} | {} | {} |",
                cell(a.map(|a| a.model_rms_nm)),
                cell(a.and_then(|a| a.baseline_rms_nm)),
                cell(a.map(|a| a.compensated_rms_nm))
            );
        }
        s += "\n";
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

/// Refuses `steps` steps shifted by `shift` that run past the table's rows.
fn check_span(table: &Table, steps: usize, shift: usize) -> Result<()> {
    if steps + shift > table.len() {
        bail!(
            "{}: {steps} steps shifted by {shift} exceed the table's {} rows",
            table.path.display(),
            table.len()
        );
    }
    Ok(())
}

/// Output `k`'s absolute torque per table row (`value` of each step plus the step's
/// offset, at its row `step + shift`; NaN where the sequence has none).
fn absolute_per_row(
    rows: usize,
    seq: &Sequence,
    k: usize,
    shift: usize,
    value: &dyn Fn(usize) -> f64,
) -> Vec<f64> {
    let mut v = vec![f64::NAN; rows];
    for r in 0..seq.len() {
        v[r + shift] = value(r) + seq.offset[r][k] as f64;
    }
    v
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
    fn the_baseline_is_compared_at_the_targets_step() {
        // A baseline equal to the model torque has the model-only RMS in every preset.
        let n = 50;
        let col = |f: &dyn Fn(usize) -> f32| (0..n).map(f).collect::<Vec<f32>>();
        let table = Table {
            path: "mem.csv".into(),
            names: [
                "q_j2",
                "qd_j2",
                "qdd_j2",
                "rest_dir_j2",
                "tau_meas_j2",
                "tau_model_j2",
            ]
            .map(String::from)
            .to_vec(),
            columns: vec![
                col(&|k| k as f32 * 0.1),
                col(&|k| (k as f32 * 0.3).sin()),
                col(&|_| 0.0),
                col(&|_| 0.0),
                col(&|k| (k * k % 7) as f32),
                col(&|k| (k % 5) as f32),
            ],
        };
        let mut coefficients = vec![vec![0.0; crate::baseline::N_FEATURES]];
        coefficients[0][1] = 1.0;
        let b = LinearBaseline {
            joints: vec![2],
            feature_names: vec![],
            coefficients,
            train_rms_nm: vec![0.0],
            samples: 0,
        };
        for spec in [FeatureSpec::paper(&[2]), FeatureSpec::feedforward(&[2])] {
            let seq = spec.sequence(&table).unwrap();
            let m = LstmModel::init(
                firmware::nn::reference::LstmDims {
                    input: spec.inputs.len(),
                    embed: 4,
                    hidden: 4,
                    output: 1,
                },
                1,
            );
            let before = evaluate(&m, &seq).unwrap()[0].rms_before;
            let got = baseline_rms(&spec, &table, seq.len(), &b).unwrap()[0].unwrap();
            assert!(
                (got - before).abs() < 1e-9,
                "{}: {got} vs {before}",
                spec.preset
            );
        }
        let custom = FeatureSpec::custom(&["q_j2".into()], &["qd_j2".into()], 0).unwrap();
        assert_eq!(target_joints(&custom), Vec::<usize>::new());
        assert_eq!(baseline_rms(&custom, &table, n, &b).unwrap(), vec![None]);
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
