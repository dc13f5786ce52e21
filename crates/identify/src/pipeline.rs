//! Identification over preprocessed logs: folding the regressor rows of every sample
//! into [`NormalEquations`] block by block, and evaluating predictions per joint.

use super::{ErrorAccumulator, JointErrors, NormalEquations};
use logs::Samples;
use nalgebra::{DMatrix, DVector};

/// Samples per regressor block (states evaluated together, then folded in).
pub const STATE_BLOCK: usize = 256;

/// A joint-torque model linear in its parameters, `τ = Y(q, q̇, q̈) θ`, over the
/// modelled joints of a robot whose logs hold `log_joints` joints.
pub trait LinearModel {
    /// Indices (0-based, into the log's joints) of the modelled joints, in output order.
    fn modelled_log_joints(&self) -> Vec<usize>;
    /// Parameter names, in column order.
    fn parameter_names(&self) -> Vec<String>;
    /// The regressor of `states.len()` samples, sample-major: rows
    /// `k·n .. (k+1)·n` belong to sample `k` (`n` = modelled joints). Each state holds
    /// the modelled joints' `(q, q̇, q̈)`.
    fn regressor_block(&self, states: &[(Vec<f64>, Vec<f64>, Vec<f64>)]) -> DMatrix<f64>;
}

/// Modelled-joint states of samples `k0..k1` of a log.
pub fn states(
    s: &Samples,
    joints: &[usize],
    k0: usize,
    k1: usize,
) -> Vec<(Vec<f64>, Vec<f64>, Vec<f64>)> {
    (k0..k1)
        .map(|k| {
            (
                joints.iter().map(|&j| s.q_rad[j][k]).collect(),
                joints.iter().map(|&j| s.qd_rad_s[j][k]).collect(),
                joints.iter().map(|&j| s.qdd_rad_s2[j][k]).collect(),
            )
        })
        .collect()
}

/// Folds every sample of `logs` (which must have torques) into normal equations.
pub fn accumulate(model: &dyn LinearModel, logs: &[Samples]) -> NormalEquations {
    let joints = model.modelled_log_joints();
    let n = joints.len();
    let p = model.parameter_names().len();
    let mut ne = NormalEquations::new(n, p);
    let mut row = vec![0.0; n * p];
    let mut tau = vec![0.0; n];
    for s in logs {
        let Some(torque) = &s.torque_nm else { continue };
        let mut k0 = 0;
        while k0 < s.len() {
            let k1 = (k0 + STATE_BLOCK).min(s.len());
            let y = model.regressor_block(&states(s, &joints, k0, k1));
            for k in 0..k1 - k0 {
                for r in 0..n {
                    for c in 0..p {
                        row[r * p + c] = y[(k * n + r, c)];
                    }
                    tau[r] = torque[joints[r]][k0 + k];
                }
                ne.add_sample(&row, &tau);
            }
            k0 = k1;
        }
    }
    ne
}

/// Predicted torques `Y θ` (f64 path) for every sample: `out[joint][sample]`.
pub fn predict(model: &dyn LinearModel, theta: &DVector<f64>, s: &Samples) -> Vec<Vec<f64>> {
    let joints = model.modelled_log_joints();
    let n = joints.len();
    let mut out: Vec<Vec<f64>> = (0..n).map(|_| Vec::with_capacity(s.len())).collect();
    let mut k0 = 0;
    while k0 < s.len() {
        let k1 = (k0 + STATE_BLOCK).min(s.len());
        let tau = model.regressor_block(&states(s, &joints, k0, k1)) * theta;
        for k in 0..k1 - k0 {
            for r in 0..n {
                out[r].push(tau[k * n + r]);
            }
        }
        k0 = k1;
    }
    out
}

/// Per-joint errors of predictions `pred[joint][sample]` against a log's torques.
pub fn errors(pred: &[Vec<f64>], joints: &[usize], s: &Samples) -> Option<ErrorAccumulator> {
    let torque = s.torque_nm.as_ref()?;
    let mut acc = ErrorAccumulator::new(joints.len());
    let mut p = vec![0.0; joints.len()];
    let mut m = vec![0.0; joints.len()];
    for k in 0..s.len() {
        for (r, &j) in joints.iter().enumerate() {
            p[r] = pred[r][k];
            m[r] = torque[j][k];
        }
        acc.add(&p, &m);
    }
    Some(acc)
}

/// Largest |a − b| over all joints and samples.
pub fn max_abs_difference(a: &[Vec<f64>], b: &[Vec<f64>]) -> f64 {
    a.iter()
        .zip(b)
        .flat_map(|(x, y)| x.iter().zip(y).map(|(u, v)| (u - v).abs()))
        .fold(0.0, f64::max)
}

/// Errors of a set of logs merged into one figure per joint.
pub fn merged_errors(items: &[ErrorAccumulator], n: usize) -> JointErrors {
    let mut acc = ErrorAccumulator::new(n);
    for a in items {
        acc.merge(a);
    }
    acc.finish()
}
