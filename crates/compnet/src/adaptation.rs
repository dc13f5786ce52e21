//! The drive's online friction adaptation ([`firmware::adaptation`]) streamed over a
//! log, after any prediction (the model alone, the linear baseline, a network), and
//! the scoring of predictions against the measured torque, as logged or low-passed.
//!
//! Per row `r` of a table, the adaptation learns from the torque measured at row `r-1`
//! (what the drive has measured before its tick) against its prediction for that row,
//! then corrects the prediction for row `r`: no sample is used before its time.
//! Columns read per joint N: `tau_meas_jN` [N·m], `time_s` [s] (the tick rate), and
//! what [`baseline::features`] reads (`qd_jN`, `rest_dir_jN`, ...).
use super::baseline;
use super::data::{Sequence, Table};
use super::train;
use anyhow::{Result, bail};
use firmware::adaptation::{self, ADAPTED_FEATURES, AdaptationConfig, FrictionAdaptation};
use firmware::features;

/// The tick rate of a table [Hz]: one over the median step of `time_s`.
pub fn tick_hz(table: &Table) -> Result<f64> {
    let t: Vec<f64> = table.column("time_s")?.iter().map(|&v| v as f64).collect();
    let dt = logs::signal::median_step(&t);
    if !(dt.is_finite() && dt > 0.0) {
        bail!(
            "{}: column `time_s` does not increase (the adaptation needs the tick rate)",
            table.path.display()
        );
    }
    Ok(1.0 / dt)
}

/// `predicted_nm` (one value per row of `table`, joint `joint`, 1-based) corrected by
/// the adaptation, as the drive would run it at the table's tick rate.
pub fn adapt(
    table: &Table,
    joint: usize,
    predicted_nm: &[f64],
    config: AdaptationConfig,
) -> Result<Vec<f64>> {
    let features = baseline::features(table, joint)?;
    let measured = table.column(&format!("tau_meas_j{joint}"))?;
    if predicted_nm.len() != features.len() {
        bail!(
            "{}: {} predictions for {} rows",
            table.path.display(),
            predicted_nm.len(),
            features.len()
        );
    }
    let mut a = FrictionAdaptation::new(config, tick_hz(table)? as f32);
    Ok(features
        .iter()
        .zip(predicted_nm)
        .enumerate()
        .map(|(r, (f, &base))| {
            let x = ADAPTED_FEATURES.map(|i| f[i] as f32);
            let before = r.checked_sub(1).map_or(f32::NAN, |p| measured[p]);
            base + f64::from(a.step(x, base as f32, before))
        })
        .collect())
}

/// What the adaptation `config` at `tick_hz` corrects in each row of a `drive` sequence
/// whose targets are the residuals over the model and the linear stage (one output per
/// joint, `outputs` joints), streamed causally from the start of the sequence: per row,
/// per output [N·m].
pub fn drive_corrections(
    seq: &Sequence,
    outputs: usize,
    config: AdaptationConfig,
    tick_hz: f32,
) -> Vec<Vec<f32>> {
    let mut out = vec![vec![0.0f32; outputs]; seq.len()];
    for k in 0..outputs {
        let mut a = FrictionAdaptation::new(config, tick_hz);
        let mut residual_before = f32::NAN;
        for ((row, t), c) in seq.inputs.iter().zip(&seq.targets).zip(out.iter_mut()) {
            let x = features::joint_drive_inputs(row, outputs, k);
            // In residual terms the prediction is 0 and the measurement the residual.
            c[k] = a.step(adaptation::regressors(x[2], x[5]), 0.0, residual_before);
            residual_before = t[k];
        }
    }
    out
}

/// Takes [`drive_corrections`] out of the targets of `seq`: the network then learns what
/// the drive's adaptation leaves, as it will run after it.
pub fn subtract_from_drive_targets(
    seq: &mut Sequence,
    outputs: usize,
    config: AdaptationConfig,
    tick_hz: f32,
) {
    let corrections = drive_corrections(seq, outputs, config, tick_hz);
    subtract(&mut seq.targets, &corrections);
}

fn subtract(targets: &mut [Vec<f32>], corrections: &[Vec<f32>]) {
    for (t, c) in targets.iter_mut().zip(corrections) {
        for (t, c) in t.iter_mut().zip(c) {
            *t -= c;
        }
    }
}

/// The `drive` preset's linear stage fitted jointly with the adaptation `config`: the
/// least-squares fit ([`train::fit_linear_stage`]) on `runs`, then once more on their
/// targets less what the adaptation corrects over the first fit's residual (run `i` at
/// tick rate `rates_hz[i]`). Friction that drifts from run to run then moves the
/// adapted levels, not the static coefficients.
pub fn fit_linear_stage_under_adaptation(
    runs: &[Sequence],
    rates_hz: &[f32],
    outputs: usize,
    config: AdaptationConfig,
) -> Result<Vec<f32>> {
    if runs.len() != rates_hz.len() {
        bail!("{} runs but {} tick rates", runs.len(), rates_hz.len());
    }
    let first = train::fit_linear_stage(runs, outputs)?;
    let without_drift: Vec<Sequence> = runs
        .iter()
        .zip(rates_hz)
        .map(|(s, &hz)| {
            let mut residual = s.clone();
            train::subtract_linear_stage(&first, std::slice::from_mut(&mut residual));
            let corrections = drive_corrections(&residual, outputs, config, hz);
            let mut out = s.clone();
            subtract(&mut out.targets, &corrections);
            out
        })
        .collect();
    train::fit_linear_stage(&without_drift, outputs)
}

/// `table` with every measured torque column (`tau_meas_j*`) zero-phase low-passed at
/// `cutoff_hz` (4th-order Butterworth, forward and backward): the torque the figures are
/// scored against when sensor noise, which no feedforward can cancel, should not count.
pub fn low_passed(table: &Table, cutoff_hz: f64) -> Result<Table> {
    let fs = tick_hz(table)?;
    let Some(filter) = logs::signal::ButterworthLowPass::new(4, cutoff_hz, fs) else {
        bail!(
            "{}: scoring cut-off {cutoff_hz} Hz is not below the Nyquist frequency ({} Hz)",
            table.path.display(),
            fs / 2.0
        );
    };
    let mut out = table.clone();
    for (name, column) in out.names.iter().zip(out.columns.iter_mut()) {
        if name.starts_with("tau_meas_j") {
            let raw: Vec<f64> = column.iter().map(|&v| v as f64).collect();
            let pad = (3.0 * fs / cutoff_hz) as usize;
            *column = filter
                .filtfilt(&raw, pad)
                .iter()
                .map(|&v| v as f32)
                .collect();
        }
    }
    Ok(out)
}

/// RMS [N·m] of `measured - predicted` over rows `rows` (`None` when empty).
pub fn rms_nm(measured: &[f32], predicted: &[f64], rows: std::ops::Range<usize>) -> Option<f64> {
    let n = rows.len();
    let ss: f64 = rows
        .map(|r| (measured[r] as f64 - predicted[r]).powi(2))
        .sum();
    (n > 0).then(|| (ss / n as f64).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    /// A joint whose measured torque is the model's plus a Coulomb level of 2 N·m and an
    /// offset of 1 N·m that the model does not know.
    fn drifted(n: usize) -> Table {
        let t: Vec<f32> = (0..n).map(|k| k as f32 * 0.01).collect();
        let qd: Vec<f32> = t.iter().map(|t| 0.4 * (0.7 * t).sin()).collect();
        let q: Vec<f32> = t
            .iter()
            .map(|t| 0.4 / 0.7 * (1.0 - (0.7 * t).cos()))
            .collect();
        let model: Vec<f32> = q.iter().map(|q| 10.0 * q.sin()).collect();
        let meas: Vec<f32> = (0..n)
            .map(|k| model[k] + 1.0 + 2.0 * (qd[k] / 0.05).tanh())
            .collect();
        Table {
            path: PathBuf::from("drift.csv"),
            names: ["time_s", "q_j1", "qd_j1", "tau_model_j1", "tau_meas_j1"]
                .map(String::from)
                .to_vec(),
            columns: vec![t, q, qd, model, meas],
        }
    }

    #[test]
    fn the_adaptation_learns_what_the_model_misses_without_looking_ahead() {
        let table = drifted(4000);
        let model: Vec<f64> = table.columns[3].iter().map(|&v| v as f64).collect();
        let cfg = AdaptationConfig {
            time_constant_s: 2.0,
            max_correction_nm: 5.0,
        };
        let adapted = adapt(&table, 1, &model, cfg).unwrap();
        let y = table.columns[4].clone();
        let before = rms_nm(&y, &model, 2000..4000).unwrap();
        let after = rms_nm(&y, &adapted, 2000..4000).unwrap();
        assert!(before > 1.5 && after < 0.1 * before, "{before} -> {after}");
        // Row 0 has nothing measured before it: no correction yet.
        assert_eq!(adapted[0], model[0]);
        // Changing a measured torque changes only the rows after it.
        let mut later = table.clone();
        later.columns[4][3000] += 50.0;
        let moved = adapt(&later, 1, &model, cfg).unwrap();
        assert_eq!(moved[..=3000], adapted[..=3000]);
        assert_ne!(moved[3001], adapted[3001]);
    }

    #[test]
    fn the_drive_targets_lose_what_the_adaptation_corrects() {
        // One joint's drive rows (qd at index 2, rest direction at 5), a residual of
        // 1.5 N·m offset: after subtraction the target is what the adaptation leaves.
        let n = 3000;
        let mut seq = Sequence {
            inputs: (0..n)
                .map(|k| {
                    let mut row = vec![0.0f32; features::DRIVE_INPUTS_PER_JOINT];
                    row[2] = 0.3 * (k as f32 * 0.01).sin();
                    row
                })
                .collect(),
            targets: vec![vec![1.5f32]; n],
            ..Default::default()
        };
        let cfg = AdaptationConfig {
            time_constant_s: 1.0,
            max_correction_nm: 5.0,
        };
        subtract_from_drive_targets(&mut seq, 1, cfg, 100.0);
        // Nothing measured before the first row: it keeps its whole target.
        assert_eq!(seq.targets[0][0], 1.5);
        assert!(
            seq.targets[n - 1][0].abs() < 1e-3,
            "{}",
            seq.targets[n - 1][0]
        );
    }

    #[test]
    fn the_scoring_filter_keeps_slow_torque_and_drops_fast_noise() {
        let mut table = drifted(2000);
        let clean: Vec<f64> = table.columns[4].iter().map(|&v| v as f64).collect();
        for (k, v) in table.columns[4].iter_mut().enumerate() {
            *v += if k % 2 == 0 { 0.5 } else { -0.5 };
        }
        let low = low_passed(&table, 5.0).unwrap();
        assert!((rms_nm(&table.columns[4], &clean, 100..1900).unwrap() - 0.5).abs() < 1e-3);
        assert!(rms_nm(&low.columns[4], &clean, 100..1900).unwrap() < 0.05);
        // Only the measured torque is filtered.
        assert_eq!(low.columns[..4], table.columns[..4]);
        let e = low_passed(&table, 60.0).unwrap_err().to_string();
        assert!(e.contains("drift.csv") && e.contains("Nyquist"), "{e}");
    }
}
