//! The training envelope on the host: recorded per compensated joint over the training
//! datasets (whole runs), carried in the network file's metadata (`envelope`, JSON), and
//! applied to streamed predictions as the firmware applies it
//! (`firmware::envelope`: the learned share faded by the envelope weight).
//!
//! Columns read per joint N: `q_jN` [rad], `qd_jN` [rad/s], `tau_model_jN` and
//! `tau_meas_jN` [N·m]; `qdd_jN` [rad/s²] when present, else central differences of
//! `qd_jN` over `time_s`. The rest direction and presliding states are computed from
//! `q_jN` and `qd_jN` (`firmware::features::MotionMemory`, as the drive computes them),
//! and the measured residual is the previous row's `tau_meas_jN - tau_model_jN`.
use super::baseline::{central_differences, motion_memory};
use super::data::{FeatureSpec, Sequence, Table};
use anyhow::{Result, bail};
use firmware::envelope::{
    COVERAGE_CELLS_Q, COVERAGE_CELLS_QD, COVERAGE_MIN_SAMPLES, JointEnvelope, Range, fade_nm,
};
use firmware::features::{self, DRIVE_INPUTS_PER_JOINT, FRICTION_FEATURES};
use serde::{Deserialize, Serialize};

/// The safetensors metadata key of the envelope.
pub const METADATA_KEY: &str = "envelope";

/// One row of a joint as the drive sees it: the angle [rad] and its `drive` inputs.
pub type JointRow = (f32, [f32; DRIVE_INPUTS_PER_JOINT]);

/// The drive's view of joint `joint` (1-based) in every row of `table`.
pub fn joint_rows(table: &Table, joint: usize) -> Result<Vec<JointRow>> {
    let name = |kind: &str| format!("{kind}_j{joint}");
    let q = table.column(&name("q"))?;
    let qd = table.column(&name("qd"))?;
    let tau_model = table.column(&name("tau_model"))?;
    let qdd: Vec<f32> = if table.names.iter().any(|n| *n == name("qdd")) {
        table.column(&name("qdd"))?.to_vec()
    } else {
        central_differences(table, qd, &name("qd"))?
            .iter()
            .map(|&v| v as f32)
            .collect()
    };
    let residual = table.input_column(&name(features::MEASURED_RESIDUAL_COLUMN))?;
    let memory = motion_memory(q, qd);
    Ok((0..table.len())
        .map(|k| {
            let x =
                features::drive_inputs(q[k], qd[k], qdd[k], tau_model[k], memory[k], residual[k]);
            (q[k], x)
        })
        .collect())
}

/// The envelope weight of a drive row (`JointEnvelope::weight` of its angle, velocity,
/// acceleration, model torque and measured residual).
pub fn row_weight(e: &JointEnvelope, (q, x): &JointRow) -> f32 {
    e.weight(*q, x[2], x[3], x[4], x[10])
}

/// Records one joint's envelope from its rows over whole runs: the range of the angle,
/// of every `drive` input and of every friction feature, and the coverage cells that
/// held at least [`COVERAGE_MIN_SAMPLES`] rows. An error when there is no row or a
/// value is not finite.
pub fn record_joint(runs: &[Vec<JointRow>]) -> Result<JointEnvelope> {
    let rows = || runs.iter().flatten();
    if rows().next().is_none() {
        bail!("no rows to record a training envelope from");
    }
    let empty = Range::new(f32::INFINITY, f32::NEG_INFINITY);
    let widen = |r: &mut Range, v: f32| {
        r.lo = r.lo.min(v);
        r.hi = r.hi.max(v);
    };
    let mut e = JointEnvelope {
        q_rad: empty,
        drive: [empty; DRIVE_INPUTS_PER_JOINT],
        friction: [empty; FRICTION_FEATURES],
        coverage: 0,
    };
    for (q, x) in rows() {
        let f = features::friction_features(x);
        if !q.is_finite() || x.iter().chain(&f).any(|v| !v.is_finite()) {
            bail!("a training row holds a non-finite value (q {q}, inputs {x:?})");
        }
        widen(&mut e.q_rad, *q);
        for (r, &v) in e.drive.iter_mut().zip(x) {
            widen(r, v);
        }
        for (r, &v) in e.friction.iter_mut().zip(&f) {
            widen(r, v);
        }
    }
    let mut counts = [0usize; COVERAGE_CELLS_Q * COVERAGE_CELLS_QD];
    for (q, x) in rows() {
        if let Some(c) = e.cell(*q, x[2]) {
            counts[c] += 1;
        }
    }
    for (c, &n) in counts.iter().enumerate() {
        if n >= COVERAGE_MIN_SAMPLES {
            e.coverage |= 1 << c;
        }
    }
    Ok(e)
}

/// The envelope of each joint of `joints` (1-based, output order) over whole `tables`.
pub fn record(tables: &[Table], joints: &[usize]) -> Result<Vec<JointEnvelope>> {
    joints
        .iter()
        .map(|&j| {
            let runs: Vec<Vec<JointRow>> = tables
                .iter()
                .map(|t| joint_rows(t, j))
                .collect::<Result<_>>()?;
            record_joint(&runs).map_err(|e| anyhow::anyhow!("joint {j}: {e}"))
        })
        .collect()
}

/// One joint's envelope as stored in the metadata (finite ranges `[lo, hi]`).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct StoredEnvelope {
    /// Range of the angle [rad].
    pub q_rad: [f32; 2],
    /// Ranges of the `drive` inputs, `firmware::features::DRIVE_COLUMNS` order.
    pub drive: Vec<[f32; 2]>,
    /// Ranges of the friction features, `firmware::features::FRICTION_FEATURE_NAMES` order.
    pub friction: Vec<[f32; 2]>,
    /// Covered cells of the (q, qd) grid (`firmware::envelope` module docs).
    pub coverage: u64,
}

/// The metadata text of a model's envelopes (one per output).
pub fn to_metadata(envelope: &[JointEnvelope]) -> Result<String> {
    let pair = |r: &Range| [r.lo, r.hi];
    let stored: Vec<StoredEnvelope> = envelope
        .iter()
        .map(|e| StoredEnvelope {
            q_rad: pair(&e.q_rad),
            drive: e.drive.iter().map(pair).collect(),
            friction: e.friction.iter().map(pair).collect(),
            coverage: e.coverage,
        })
        .collect();
    Ok(serde_json::to_string(&stored)?)
}

/// Parses the metadata text of `outputs` envelopes; an error names what is wrong.
pub fn from_metadata(text: &str, outputs: usize) -> Result<Vec<JointEnvelope>> {
    let stored: Vec<StoredEnvelope> = serde_json::from_str(text)
        .map_err(|e| anyhow::anyhow!("metadata `{METADATA_KEY}`: {e}"))?;
    if stored.len() != outputs {
        bail!(
            "metadata `{METADATA_KEY}`: {} joints for {outputs} outputs",
            stored.len()
        );
    }
    stored
        .iter()
        .enumerate()
        .map(|(k, s)| {
            let range = |what: &str, [lo, hi]: [f32; 2]| -> Result<Range> {
                if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
                    bail!("metadata `{METADATA_KEY}`: joint {k}: range {what} [{lo}, {hi}] is not finite and ordered");
                }
                Ok(Range::new(lo, hi))
            };
            let ranges = |what: &str, v: &[[f32; 2]], n: usize| -> Result<Vec<Range>> {
                if v.len() != n {
                    bail!("metadata `{METADATA_KEY}`: joint {k}: {} {what} ranges, expected {n}", v.len());
                }
                v.iter()
                    .enumerate()
                    .map(|(i, &p)| range(&format!("{what} {i}"), p))
                    .collect()
            };
            let drive = ranges("drive", &s.drive, DRIVE_INPUTS_PER_JOINT)?;
            let friction = ranges("friction", &s.friction, FRICTION_FEATURES)?;
            Ok(JointEnvelope {
                q_rad: range("q", s.q_rad)?,
                drive: std::array::from_fn(|i| drive[i]),
                friction: std::array::from_fn(|i| friction[i]),
                coverage: s.coverage,
            })
        })
        .collect()
}

/// Per step of `seq` (from `table`, joints of `spec`'s outputs) and output, the envelope
/// weight the drive computes at the tick the target stands for (row `t + shift`).
pub fn step_weights(
    envelope: &[JointEnvelope],
    spec: &FeatureSpec,
    table: &Table,
    seq: &Sequence,
) -> Result<Vec<Vec<f32>>> {
    let mut per_output = Vec::new();
    for (k, target) in spec.targets.iter().enumerate() {
        let e = envelope.get(k).unwrap_or(&JointEnvelope::UNBOUNDED);
        let Some(joint) = super::eval::target_joint(spec, k) else {
            per_output.push(vec![1.0; seq.len()]);
            continue;
        };
        let rows = joint_rows(table, joint)?;
        per_output.push(
            (0..seq.len())
                .map(|t| rows.get(t + target.shift).map_or(1.0, |r| row_weight(e, r)))
                .collect::<Vec<f32>>(),
        );
    }
    Ok((0..seq.len())
        .map(|t| per_output.iter().map(|w| w[t]).collect())
        .collect())
}

/// Fades streamed predictions (target terms) by the step weights as the firmware does:
/// `model_only + w * (prediction - model_only)` where `w < 1`.
pub fn fade_predictions(pred: &mut [Vec<f32>], seq: &Sequence, weights: &[Vec<f32>]) {
    for ((p, m), w) in pred.iter_mut().zip(&seq.model_only).zip(weights) {
        for ((y, &mo), &wk) in p.iter_mut().zip(m).zip(w) {
            *y = fade_nm(wk, mo, *y);
        }
    }
}

/// Per output, the share of steps whose weight is below 1 (outside the envelope).
pub fn outside_share(weights: &[Vec<f32>], outputs: usize) -> Vec<f64> {
    let n = weights.len().max(1) as f64;
    (0..outputs)
        .map(|k| {
            weights
                .iter()
                .filter(|w| w.get(k).is_some_and(|&v| v < 1.0))
                .count() as f64
                / n
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(q: f32, qd: f32) -> JointRow {
        let x = features::drive_inputs(q, qd, 0.0, 1.0, (0.0, [0.0; 4]), 0.0);
        (q, x)
    }

    #[test]
    fn records_ranges_and_coverage_and_round_trips_through_metadata() {
        // The first half of the angle range at every speed, the second at one speed.
        let run: Vec<JointRow> = (0..4000)
            .map(|k| {
                let q = -1.0 + k as f32 * 0.0005;
                let sweep = 0.5 * ((k % 40) as f32 / 40.0 - 0.5);
                row(q, if k < 2000 { sweep } else { -0.25 })
            })
            .collect();
        let e = record_joint(std::slice::from_ref(&run)).unwrap();
        assert_eq!(e.q_rad, Range::new(-1.0, -1.0 + 3999.0 * 0.0005));
        assert_eq!(e.drive[2].lo, -0.25);
        assert!(e.friction[7].hi > 0.0 && e.friction[0] == Range::new(1.0, 1.0));
        // 4 angle cells x 8 speed cells, then 4 x the lowest speed cell.
        assert_eq!(e.covered_cells(), 4 * 8 + 4);
        assert!(e.covered(-0.9, 0.2) && !e.covered(0.9, 0.2) && e.covered(0.9, -0.25));
        assert!(run.iter().all(|r| row_weight(&e, r) == 1.0));
        assert_eq!(row_weight(&e, &row(0.0, 3.0)), 0.0);
        let text = to_metadata(&[e]).unwrap();
        assert_eq!(from_metadata(&text, 1).unwrap(), vec![e]);
        assert!(from_metadata(&text, 2).is_err());
        assert!(from_metadata("[{}]", 1).is_err());
        let bad = text.replacen("\"q_rad\":[-1.0", "\"q_rad\":[9.0", 1);
        assert!(from_metadata(&bad, 1).is_err(), "{bad}");
        assert!(record_joint(&[]).is_err());
    }
}
