//! Excitation criteria of the observation matrix `W` (the stacked base regressor, friction
//! columns included, evaluated along the sampled trajectory).

use super::trajectory::ExcitationTrajectory;
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

/// A model whose torques are linear in a parameter vector: it writes the rows of the
/// observation matrix for one state of the moving joints.
///
/// Implemented by the base regressor of a robot (see `ExcitationModel` in this module's
/// parent for the adapter) and, in tests, by small hand-written models.
pub trait ObservationModel {
    /// Number of moving joints (the trajectory's dimension).
    fn joint_count(&self) -> usize;
    /// Number of rows the model writes per sample (usually the number of moving joints).
    fn rows_per_sample(&self) -> usize;
    /// Number of parameters (columns of the observation matrix).
    fn parameter_count(&self) -> usize;
    /// Writes the `rows_per_sample × parameter_count` rows (row-major) for the moving joints'
    /// positions (rad), velocities (rad/s) and accelerations (rad/s²).
    fn rows(&self, q_rad: &[f64], qd_rad_s: &[f64], qdd_rad_s2: &[f64], out: &mut [f64]);
}

/// Which scalar of the observation matrix the optimiser minimises.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum Criterion {
    /// Condition number `σ_max / σ_min` of `W` (the paper's criterion). Minimised.
    #[default]
    Condition,
    /// D-optimality: `log det(WᵀW / n_samples)`. Maximised (the optimiser minimises its negative).
    LogDet,
}

/// Both criteria of one observation matrix.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ExcitationScore {
    /// Condition number of `W` (∞ when rank-deficient).
    pub condition: f64,
    /// `log det(WᵀW / n_samples)` (−∞ when rank-deficient).
    pub log_det: f64,
    /// Smallest singular value of `W / sqrt(n_samples)`.
    pub sigma_min: f64,
}

impl ExcitationScore {
    /// The value the optimiser minimises for `criterion` (finite: rank deficiency maps to a
    /// large penalty).
    pub fn cost(&self, criterion: Criterion) -> f64 {
        match criterion {
            Criterion::Condition => {
                if self.condition.is_finite() {
                    self.condition.ln()
                } else {
                    1e3
                }
            }
            Criterion::LogDet => {
                if self.log_det.is_finite() {
                    -self.log_det
                } else {
                    1e6
                }
            }
        }
    }
}

/// Reusable evaluator: samples a trajectory at `samples` instants over one period, stacks the
/// model's rows and scores the result.
pub struct ObservationEvaluator<'m, M: ObservationModel + ?Sized> {
    model: &'m M,
    samples: usize,
    rows: Vec<f64>,
    gram: DMatrix<f64>,
    q: Vec<f64>,
    qd: Vec<f64>,
    qdd: Vec<f64>,
}

impl<'m, M: ObservationModel + ?Sized> ObservationEvaluator<'m, M> {
    /// An evaluator over `samples` instants per period (`t_k = k·T/samples`, the period's end
    /// left out since it repeats the start).
    pub fn new(model: &'m M, samples: usize) -> Self {
        let p = model.parameter_count();
        let n = model.joint_count();
        Self {
            model,
            samples: samples.max(1),
            rows: vec![0.0; model.rows_per_sample() * p],
            gram: DMatrix::zeros(p, p),
            q: vec![0.0; n],
            qd: vec![0.0; n],
            qdd: vec![0.0; n],
        }
    }

    /// Scores a trajectory through the eigenvalues of `WᵀW` (fast; accurate while the condition
    /// number stays below ~1e7, which covers every trajectory worth keeping).
    pub fn score(&mut self, tr: &ExcitationTrajectory) -> ExcitationScore {
        let p = self.model.parameter_count();
        let r = self.model.rows_per_sample();
        self.gram.fill(0.0);
        for k in 0..self.samples {
            let t = k as f64 * tr.period_s / self.samples as f64;
            tr.eval_into(t, &mut self.q, &mut self.qd, &mut self.qdd);
            self.model
                .rows(&self.q, &self.qd, &self.qdd, &mut self.rows);
            // Wᵀ W += rowsᵀ rows (upper triangle, mirrored below).
            for row in self.rows.chunks_exact(p).take(r) {
                for (a, &ra) in row.iter().enumerate() {
                    if ra == 0.0 {
                        continue;
                    }
                    for (b, &rb) in row.iter().enumerate().skip(a) {
                        self.gram[(a, b)] += ra * rb;
                    }
                }
            }
        }
        for a in 0..p {
            for b in 0..a {
                self.gram[(a, b)] = self.gram[(b, a)];
            }
        }
        let n = self.samples as f64;
        let eig = self.gram.clone().symmetric_eigenvalues();
        let (mut lmin, mut lmax) = (f64::INFINITY, 0.0f64);
        let mut log_det = 0.0;
        for &l in eig.iter() {
            lmin = lmin.min(l);
            lmax = lmax.max(l);
            log_det += (l / n).ln();
        }
        if lmin.is_nan() || lmin <= lmax * 1e-28 || !lmin.is_finite() {
            return ExcitationScore {
                condition: f64::INFINITY,
                log_det: f64::NEG_INFINITY,
                sigma_min: 0.0,
            };
        }
        ExcitationScore {
            condition: (lmax / lmin).sqrt(),
            log_det,
            sigma_min: (lmin / n).sqrt(),
        }
    }
}

/// The observation matrix `W` of a trajectory sampled at `rate_hz` over one period (period end
/// excluded), for reports and identification.
pub fn observation_matrix<M: ObservationModel + ?Sized>(
    model: &M,
    tr: &ExcitationTrajectory,
    rate_hz: f64,
) -> DMatrix<f64> {
    let samples = (tr.period_s * rate_hz).round().max(1.0) as usize;
    let (p, r, n) = (
        model.parameter_count(),
        model.rows_per_sample(),
        model.joint_count(),
    );
    let mut w = DMatrix::zeros(samples * r, p);
    let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let mut rows = vec![0.0; r * p];
    for k in 0..samples {
        let t = k as f64 * tr.period_s / samples as f64;
        tr.eval_into(t, &mut q, &mut qd, &mut qdd);
        model.rows(&q, &qd, &qdd, &mut rows);
        for i in 0..r {
            for c in 0..p {
                w[(k * r + i, c)] = rows[i * p + c];
            }
        }
    }
    w
}

/// Condition number of a matrix from its singular values (accurate reference for reports).
pub fn condition_number(w: &DMatrix<f64>) -> f64 {
    let sv = w.clone().singular_values();
    let (mn, mx) = (sv.min(), sv.max());
    if mn > 0.0 { mx / mn } else { f64::INFINITY }
}
