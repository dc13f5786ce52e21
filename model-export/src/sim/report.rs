//! What the identification model leaves unexplained in the simulated plant: identify
//! rigid body + viscous + Coulomb friction by least squares on a training log, then the
//! per-joint RMS of `measured - model` on the training and a test log (the paper's
//! "uncompensated" error, Table 2).
//!
//! The least-squares fit uses the full standard-parameter regressor (10 per link plus
//! viscous and Coulomb columns per modelled joint) solved with a rank-revealing SVD, so
//! its predictions equal those of the base-parameter identification (same column space).
use super::SimulatedLog;
use super::rigid::DhArm;
use anyhow::ensure;
use nalgebra::{DMatrix, DVector};

/// One joint's uncompensated RMS error [N*m].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointRms {
    /// Robot joint, 0-based.
    pub joint: usize,
    /// RMS of measured - model on the training log.
    pub train_nm: f64,
    /// RMS of measured - model on the test log.
    pub test_nm: f64,
    /// RMS of the measured torque itself on the test log (signal size).
    pub test_signal_nm: f64,
}

/// Which column of the log to fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TorqueSource {
    /// `tau{j}_nm`: the measured (logged) torque.
    Measured,
    /// `true_tau{j}_nm`: the plant's torque before sensing.
    True,
}

/// Regressor rows of `joints` at one state (`cols`: 10 per link from link `first` on,
/// then viscous and Coulomb per joint).
fn regressor_rows(
    arm: &DhArm,
    joints: &[usize],
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    out: &mut DMatrix<f64>,
    row0: usize,
) {
    let dof = arm.links.len();
    let first = joints.iter().copied().min().unwrap_or(0);
    let mut e = vec![0.0; 10 * dof];
    let mut tau = vec![0.0; dof];
    let mut col = 0;
    for k in 10 * first..10 * dof {
        e[k] = 1.0;
        arm.inverse_dynamics_with(&e, q, qd, qdd, &mut tau);
        e[k] = 0.0;
        for (m, &j) in joints.iter().enumerate() {
            out[(row0 + m, col)] = tau[j];
        }
        col += 1;
    }
    for (m, &j) in joints.iter().enumerate() {
        out[(row0 + m, col + 2 * m)] = qd[j];
        out[(row0 + m, col + 2 * m + 1)] = super::drive::sign(qd[j]);
    }
}

fn observation(
    arm: &DhArm,
    log: &SimulatedLog,
    joints: &[usize],
    source: TorqueSource,
) -> (DMatrix<f64>, DVector<f64>) {
    let dof = log.dof;
    let first = joints.iter().copied().min().unwrap_or(0);
    let cols = 10 * (dof - first) + 2 * joints.len();
    let n = log.rows.len();
    let mut w = DMatrix::zeros(n * joints.len(), cols);
    let mut y = DVector::zeros(n * joints.len());
    let tau = match source {
        TorqueSource::Measured => "tau",
        TorqueSource::True => "true_tau",
    };
    let qc = log.column("q", 0).unwrap_or(1);
    let qdc = log.column("qd", 0).unwrap_or(1);
    let qddc = log.column("true_qdd", 0).unwrap_or(1);
    for (k, r) in log.rows.iter().enumerate() {
        regressor_rows(
            arm,
            joints,
            &r[qc..qc + dof],
            &r[qdc..qdc + dof],
            &r[qddc..qddc + dof],
            &mut w,
            k * joints.len(),
        );
        for (m, &j) in joints.iter().enumerate() {
            y[k * joints.len() + m] = r[log.column(tau, j).unwrap_or(0)];
        }
    }
    (w, y)
}

/// Identifies on `train`, evaluates on `train` and `test`: per-joint uncompensated RMS.
/// Uses the logged accelerations' ground truth (`true_qdd`), so the figure isolates the
/// plant's unmodelled effects from differentiation error.
pub fn uncompensated_rms(
    arm: &DhArm,
    train: &SimulatedLog,
    test: &SimulatedLog,
    joints: &[usize],
    source: TorqueSource,
) -> anyhow::Result<Vec<JointRms>> {
    ensure!(!joints.is_empty(), "no joints to evaluate");
    ensure!(
        train.rows.len() > 10 && test.rows.len() > 10,
        "logs too short"
    );
    let (w, y) = observation(arm, train, joints, source);
    // Column scaling, then an SVD solve with a relative rank tolerance.
    let scale: Vec<f64> = (0..w.ncols())
        .map(|c| w.column(c).norm().max(1e-300))
        .collect();
    let mut ws = w.clone();
    for (c, s) in scale.iter().enumerate() {
        ws.column_mut(c).scale_mut(1.0 / s);
    }
    let svd = ws.svd(true, true);
    let tol = 1e-9 * svd.singular_values.max();
    let theta_s = svd
        .solve(&y, tol)
        .map_err(|e| anyhow::anyhow!("least squares failed: {e}"))?;
    let rms = |w: &DMatrix<f64>, y: &DVector<f64>| -> Vec<(f64, f64)> {
        let pred = w * DVector::from_iterator(
            theta_s.len(),
            theta_s.iter().zip(&scale).map(|(t, s)| t / s),
        );
        let nj = joints.len();
        (0..nj)
            .map(|m| {
                let rows = y.len() / nj;
                let (mut e2, mut s2) = (0.0, 0.0);
                for k in 0..rows {
                    let i = k * nj + m;
                    e2 += (y[i] - pred[i]).powi(2);
                    s2 += y[i] * y[i];
                }
                ((e2 / rows as f64).sqrt(), (s2 / rows as f64).sqrt())
            })
            .collect()
    };
    let tr = rms(&w, &y);
    let (wt, yt) = observation(arm, test, joints, source);
    let te = rms(&wt, &yt);
    Ok(joints
        .iter()
        .enumerate()
        .map(|(m, &j)| JointRms {
            joint: j,
            train_nm: tr[m].0,
            test_nm: te[m].0,
            test_signal_nm: te[m].1,
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::{
        self, CommandedTrajectory, FourierTrajectory, PlantEffects, PlantParameters,
        SimulationConfig,
    };

    fn wrist_logs(effects: PlantEffects) -> (SimulatedLog, SimulatedLog) {
        let arm = sim::default_arm();
        let plant = PlantParameters::default_robot();
        let lim = (1.2, 1.5, 5.0);
        let run = |seed: u64, periods| {
            let series = FourierTrajectory::seeded_rest_to_rest(seed, &[0.0; 3], 5, 10.0, lim);
            let tr = CommandedTrajectory::Fourier { series, periods };
            let mut cfg = SimulationConfig::new(6, 3);
            cfg.driven_joints = vec![3, 4, 5];
            cfg.effects = effects;
            cfg.seed = seed;
            sim::simulate(&arm, &plant, &tr, &cfg).unwrap()
        };
        (run(1, 2), run(2, 1))
    }

    #[test]
    fn ideal_plant_is_explained_exactly() {
        let (train, test) = wrist_logs(PlantEffects::none());
        let rms = uncompensated_rms(
            &sim::default_arm(),
            &train,
            &test,
            &[3, 4, 5],
            TorqueSource::Measured,
        )
        .unwrap();
        for r in rms {
            assert!(r.train_nm < 1e-8 && r.test_nm < 1e-8, "{r:?}");
        }
    }

    #[test]
    fn unmodelled_effects_leave_an_error() {
        let (train, test) = wrist_logs(PlantEffects::all());
        let rms = uncompensated_rms(
            &sim::default_arm(),
            &train,
            &test,
            &[3, 4, 5],
            TorqueSource::Measured,
        )
        .unwrap();
        for r in rms {
            assert!(r.train_nm > 0.1 && r.test_nm > 0.1, "{r:?}");
        }
    }
}
