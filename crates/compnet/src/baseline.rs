//! The friction-feature least-squares baseline: per joint, ordinary least squares (f64)
//! of the measured torque `tau_meas_jN` [N·m] on the identified model's torque and a
//! fixed set of friction, inertia and pose features ([`FEATURE_NAMES`]). It is the linear
//! yardstick a learned compensator has to beat.
//!
//! Columns read per joint N: `tau_meas_jN` (fit only), `tau_model_jN` [N·m], `q_jN`
//! [rad], `qd_jN` [rad/s]; `qdd_jN` [rad/s²] when present, else central differences of
//! `qd_jN` over `time_s` [s]; `rest_dir_jN` (-1/0/+1) and the presliding states
//! `slip_*_jN` when present, else computed here from `q_jN` and `qd_jN`
//! (`firmware::features::MotionMemory`). The features are the drive's own
//! (`firmware::features::friction_features`), which the `drive` preset's linear stage
//! evaluates too.
use super::data::Table;
use anyhow::{Context, Result, bail};
use firmware::features;
use nalgebra::{DMatrix, DVector};

/// Number of features per joint.
pub const N_FEATURES: usize = features::FRICTION_FEATURES;

/// Feature names, in coefficient order (units of each coefficient: N·m per feature unit).
pub const FEATURE_NAMES: [&str; N_FEATURES] = features::FRICTION_FEATURE_NAMES;

/// Singular values below this fraction of the largest (column-scaled design) count as 0:
/// about f32's resolution. The drive evaluates the stage in f32 from f32 inputs (and a
/// dataset stores six decimals), so a direction the features span only to that
/// precision (a model torque that never changes sign makes `|tau_model|` equal to
/// `tau_model`; a model torque that is a combination of the pose and acceleration
/// features) is rounding noise: fitted, it gives opposite coefficients of 1e4 or more
/// that cancel on the training runs only.
const RCOND: f64 = 1e-6;

/// A fitted baseline: per joint, coefficients of [`FEATURE_NAMES`] (N·m per feature unit).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct LinearBaseline {
    /// Robot joint numbers (1-based, as in `tau_meas_jN`), in coefficient order.
    pub joints: Vec<usize>,
    /// Feature names ([`FEATURE_NAMES`]).
    pub feature_names: Vec<String>,
    /// Per joint, one coefficient per feature.
    pub coefficients: Vec<Vec<f64>>,
    /// Per joint, RMS fit residual on the training rows [N·m].
    pub train_rms_nm: Vec<f64>,
    /// Training rows (all tables together).
    pub samples: usize,
}

/// The rest direction (-1/0/+1) and presliding states of a sequence of angles [rad] and
/// velocities [rad/s]: `firmware::features::MotionMemory` over the sequence.
pub fn motion_memory(
    q_rad: &[f32],
    qd_rad_s: &[f32],
) -> Vec<(f32, [f32; features::PRESLIDING_ELEMENTS])> {
    let mut memory = features::MotionMemory::new();
    q_rad
        .iter()
        .zip(qd_rad_s)
        .map(|(&q, &qd)| memory.update(q, qd))
        .collect()
}

/// Central differences of `qd` [rad/s] over `time_s` [s] (one-sided at the ends) [rad/s²].
pub fn central_differences(table: &Table, qd_rad_s: &[f32], qd_name: &str) -> Result<Vec<f64>> {
    let n = qd_rad_s.len();
    if n < 2 {
        return Ok(vec![0.0; n]);
    }
    let t = table.column("time_s")?;
    (0..n)
        .map(|k| {
            let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
            let dt = t[b] as f64 - t[a] as f64;
            if dt.is_finite() && dt > 0.0 {
                Ok((qd_rad_s[b] as f64 - qd_rad_s[a] as f64) / dt)
            } else {
                bail!(
                    "{}: column `time_s` does not increase at row {} (needed for the acceleration \
                     of `{qd_name}`; or give a `qdd` column)",
                    table.path.display(),
                    k + 1
                )
            }
        })
        .collect()
}

/// The feature rows of joint `joint` (1-based) of `table`, [`FEATURE_NAMES`] order.
pub fn features(table: &Table, joint: usize) -> Result<Vec<[f64; N_FEATURES]>> {
    let name = |kind: &str| format!("{kind}_j{joint}");
    let has = |c: &str| table.names.iter().any(|n| n == c);
    let q = table.column(&name("q"))?;
    let qd = table.column(&name("qd"))?;
    let tau_model = table.column(&name("tau_model"))?;
    let stored = |kind: &str| -> Result<Option<Vec<f64>>> {
        let c = name(kind);
        Ok(if has(&c) {
            Some(table.column(&c)?.iter().map(|&v| v as f64).collect())
        } else {
            None
        })
    };
    let qdd = match stored("qdd")? {
        Some(v) => v,
        None => central_differences(table, qd, &name("qd"))?,
    };
    // The stored rest direction and presliding states, else computed here.
    let mut memory = motion_memory(q, qd);
    if let Some(rest) = stored(features::DRIVE_COLUMNS[5])? {
        for (m, r) in memory.iter_mut().zip(rest) {
            m.0 = r as f32;
        }
    }
    for (e, &column) in features::DRIVE_COLUMNS[6..].iter().enumerate() {
        if let Some(slip) = stored(column)? {
            for (m, p) in memory.iter_mut().zip(slip) {
                m.1[e] = p as f32;
            }
        }
    }
    // The drive's own feature function (f32), as the `drive` preset's linear stage (the
    // measured residual is not a friction feature: 0).
    let rows: Vec<[f64; N_FEATURES]> = (0..table.len())
        .map(|k| {
            let x =
                features::drive_inputs(q[k], qd[k], qdd[k] as f32, tau_model[k], memory[k], 0.0);
            features::friction_features(&x).map(f64::from)
        })
        .collect();
    for (k, r) in rows.iter().enumerate() {
        if let Some(f) = r.iter().position(|x| !x.is_finite()) {
            bail!(
                "{}: row {}: joint {joint}: feature `{}` is not finite",
                table.path.display(),
                k + 1,
                FEATURE_NAMES[f]
            );
        }
    }
    Ok(rows)
}

/// Fits the baseline per joint (1-based) on all rows of `tables` (column-scaled SVD).
pub fn fit(tables: &[Table], joints: &[usize]) -> Result<LinearBaseline> {
    if joints.is_empty() {
        bail!("the linear baseline needs at least one joint");
    }
    let mut coefficients = Vec::new();
    let mut train_rms_nm = Vec::new();
    let mut samples = 0;
    for &j in joints {
        let mut x: Vec<[f64; N_FEATURES]> = Vec::new();
        let mut y: Vec<f64> = Vec::new();
        for t in tables {
            let f = features(t, j)?;
            let meas = t.column(&format!("tau_meas_j{j}"))?;
            x.extend(f);
            y.extend(meas.iter().map(|&v| v as f64));
        }
        let n = x.len();
        if n < N_FEATURES {
            bail!(
                "the linear baseline has {N_FEATURES} features per joint but only {n} training \
                 samples ({})",
                tables
                    .iter()
                    .map(|t| t.path.display().to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
        let w = solve(&x, &y).with_context(|| format!("linear baseline, joint {j}"))?;
        let ss: f64 = x
            .iter()
            .zip(&y)
            .map(|(r, y)| (y - dot(&w, r)).powi(2))
            .sum();
        train_rms_nm.push((ss / n as f64).sqrt());
        coefficients.push(w);
        samples = n;
    }
    Ok(LinearBaseline {
        joints: joints.to_vec(),
        feature_names: FEATURE_NAMES.iter().map(|s| s.to_string()).collect(),
        coefficients,
        train_rms_nm,
        samples,
    })
}

/// Least squares `x w ≈ y` through the SVD of the column-scaled design (minimum-norm
/// solution when columns are dependent, e.g. a constant column beside the intercept).
pub(crate) fn solve(x: &[[f64; N_FEATURES]], y: &[f64]) -> Result<Vec<f64>> {
    let n = x.len();
    let scale: Vec<f64> = (0..N_FEATURES)
        .map(|c| {
            let rms = (x.iter().map(|r| r[c] * r[c]).sum::<f64>() / n as f64).sqrt();
            if rms.is_finite() && rms > 0.0 {
                rms
            } else {
                1.0
            }
        })
        .collect();
    let a = DMatrix::from_fn(n, N_FEATURES, |r, c| x[r][c] / scale[c]);
    let b = DVector::from_column_slice(y);
    let svd = a.svd(true, true);
    let smax = svd.singular_values.max();
    let z = svd
        .solve(&b, smax * RCOND)
        .map_err(|e| anyhow::anyhow!("least squares: {e}"))?;
    let w: Vec<f64> = z.iter().zip(&scale).map(|(z, s)| z / s).collect();
    if w.iter().any(|v| !v.is_finite()) {
        bail!("least squares gave non-finite coefficients");
    }
    Ok(w)
}

fn dot(w: &[f64], r: &[f64; N_FEATURES]) -> f64 {
    w.iter().zip(r).map(|(a, b)| a * b).sum()
}

impl LinearBaseline {
    /// Predicted measured torque [N·m] per joint (in [`Self::joints`] order), per row.
    pub fn predict(&self, table: &Table) -> Result<Vec<Vec<f64>>> {
        self.joints
            .iter()
            .zip(&self.coefficients)
            .map(|(&j, w)| Ok(features(table, j)?.iter().map(|r| dot(w, r)).collect()))
            .collect()
    }

    /// The coefficients of joint `joint` (1-based), if fitted.
    pub fn joint_coefficients(&self, joint: usize) -> Option<&[f64]> {
        let k = self.joints.iter().position(|&j| j == joint)?;
        Some(&self.coefficients[k])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn table(names: &[&str], columns: Vec<Vec<f32>>) -> Table {
        Table {
            path: PathBuf::from("mem.csv"),
            names: names.iter().map(|s| s.to_string()).collect(),
            columns,
        }
    }

    #[test]
    fn motion_memory_holds_the_last_motion_and_the_presliding_states() {
        let qd = [0.0, 0.3, 0.001, 0.0, -0.2, -0.004, 0.0, 0.01];
        let q = [0.0, 0.05, 0.05, 0.05, 0.048, 0.048, 0.048, 0.1];
        let m = motion_memory(&q, &qd);
        let rest: Vec<f32> = m.iter().map(|x| x.0).collect();
        assert_eq!(rest, [0.0, 0.0, 1.0, 1.0, 0.0, -1.0, -1.0, 0.0]);
        // 50 mrad forward saturates every element; 2 mrad back sweeps the 1 mrad one
        // from +1 to -1 and the 10 mrad one by 0.2.
        assert_eq!(m[1].1, [1.0; 4]);
        assert!(m[4].1[0] < -0.99 && (m[4].1[2] - 0.8).abs() < 1e-3);
    }

    #[test]
    fn central_differences_use_the_time_column() {
        let t = table(
            &["time_s", "qd_j1"],
            vec![vec![0.0, 0.1, 0.3, 0.4], vec![0.0, 1.0, 3.0, 4.0]],
        );
        let qdd = central_differences(&t, t.column("qd_j1").unwrap(), "qd_j1").unwrap();
        for v in qdd {
            assert!((v - 10.0).abs() < 1e-4, "{v}");
        }
        let bad = table(&["time_s", "qd_j1"], vec![vec![0.0, 0.0], vec![0.0, 1.0]]);
        let e = central_differences(&bad, bad.column("qd_j1").unwrap(), "qd_j1").unwrap_err();
        assert!(e.to_string().contains("mem.csv") && e.to_string().contains("time_s"));
    }

    #[test]
    fn a_constant_column_beside_the_intercept_is_harmless() {
        // rest_dir is constant 1 (collinear with the intercept); tau = 2 + 3 qd.
        let n = 200;
        let qd: Vec<f32> = (0..n).map(|k| (k as f32 * 0.37).sin()).collect();
        let q: Vec<f32> = (0..n).map(|k| k as f32 * 0.01).collect();
        let tau: Vec<f32> = qd.iter().map(|v| 2.0 + 3.0 * v).collect();
        let t = table(
            &[
                "q_j1",
                "qd_j1",
                "qdd_j1",
                "tau_model_j1",
                "rest_dir_j1",
                "tau_meas_j1",
            ],
            vec![q, qd, vec![0.0; n], vec![0.0; n], vec![1.0; n], tau.clone()],
        );
        let b = fit(std::slice::from_ref(&t), &[1]).unwrap();
        let p = b.predict(&t).unwrap();
        for (a, y) in p[0].iter().zip(&tau) {
            assert!((a - *y as f64).abs() < 1e-5, "{a} vs {y}");
        }
    }
}
