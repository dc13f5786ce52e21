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
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Criterion {
    /// Condition number `σ_max / σ_min` of the unscaled `W` (the paper's criterion). Minimised.
    /// Depends on the parameters' units: a column in N·m per (kg·m) (gravity, ~g) against one
    /// in N·m per N·m (Coulomb friction, ~1) puts a floor of roughly `g` under it whatever the
    /// trajectory.
    #[default]
    Condition,
    /// Condition number of `W` with every column scaled to unit norm (`W D⁻¹`, `D` the column
    /// norms): independent of the parameters' units and within `√p` of the best diagonal
    /// scaling (van der Sluis). Minimised.
    ScaledCondition,
    /// D-optimality: `log det(WᵀW / n_samples)`. Maximised (the optimiser minimises its negative).
    LogDet,
}

impl Criterion {
    /// Every criterion, in the order the command line lists them.
    pub const ALL: [Self; 3] = [Self::Condition, Self::ScaledCondition, Self::LogDet];

    /// The criterion's name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::Condition => "condition",
            Self::ScaledCondition => "scaled-condition",
            Self::LogDet => "log-det",
        }
    }
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
    /// Condition number of `W` with unit-norm columns (∞ when rank-deficient).
    #[serde(default = "infinite")]
    pub scaled_condition: f64,
}

fn infinite() -> f64 {
    f64::INFINITY
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
            Criterion::ScaledCondition => {
                if self.scaled_condition.is_finite() {
                    self.scaled_condition.ln()
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
    scaled: DMatrix<f64>,
    want_plain: bool,
    want_scaled: bool,
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
            scaled: DMatrix::zeros(p, p),
            want_plain: true,
            want_scaled: true,
            q: vec![0.0; n],
            qd: vec![0.0; n],
            qdd: vec![0.0; n],
        }
    }

    /// Computes only what `criterion` needs (the other fields of the score stay at their
    /// rank-deficient values); by default both condition numbers and the log-det are computed.
    pub fn only_for(mut self, criterion: Criterion) -> Self {
        self.want_plain = criterion != Criterion::ScaledCondition;
        self.want_scaled = criterion == Criterion::ScaledCondition;
        self
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
        let mut out = ExcitationScore {
            condition: f64::INFINITY,
            log_det: f64::NEG_INFINITY,
            sigma_min: 0.0,
            scaled_condition: f64::INFINITY,
        };
        if self.want_plain {
            let eig = self.gram.clone().symmetric_eigenvalues();
            let (lmin, lmax) = extremes(eig.as_slice());
            if lmin > lmax * 1e-28 {
                out.condition = (lmax / lmin).sqrt();
                out.log_det = eig.iter().map(|l| (l / n).ln()).sum();
                out.sigma_min = (lmin / n).sqrt();
            }
        }
        if self.want_scaled {
            // D⁻¹ WᵀW D⁻¹ with D = column norms: the Gram matrix of the unit-norm columns.
            let d: Vec<f64> = (0..p).map(|a| self.gram[(a, a)].sqrt()).collect();
            if d.iter().all(|&x| x > 0.0 && x.is_finite()) {
                for a in 0..p {
                    for b in 0..p {
                        self.scaled[(a, b)] = self.gram[(a, b)] / (d[a] * d[b]);
                    }
                }
                let eig = self.scaled.clone().symmetric_eigenvalues();
                let (lmin, lmax) = extremes(eig.as_slice());
                if lmin > lmax * 1e-28 {
                    out.scaled_condition = (lmax / lmin).sqrt();
                }
            }
        }
        out
    }
}

/// Smallest and largest of a set of eigenvalues (NaN maps to a rank-deficient result).
fn extremes(eig: &[f64]) -> (f64, f64) {
    let (mut lmin, mut lmax) = (f64::INFINITY, 0.0f64);
    for &l in eig {
        if l.is_nan() {
            return (0.0, 1.0);
        }
        lmin = lmin.min(l);
        lmax = lmax.max(l);
    }
    if !lmin.is_finite() {
        (0.0, 1.0)
    } else {
        (lmin, lmax)
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

/// Condition number of a matrix after scaling every column to unit norm (see
/// [`Criterion::ScaledCondition`]), from its singular values.
pub fn scaled_condition_number(w: &DMatrix<f64>) -> f64 {
    let mut w = w.clone();
    for mut c in w.column_iter_mut() {
        let n = c.norm();
        if n == 0.0 || !n.is_finite() {
            return f64::INFINITY;
        }
        c /= n;
    }
    condition_number(&w)
}
