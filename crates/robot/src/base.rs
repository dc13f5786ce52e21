//! Base (minimal) parameters, computed numerically.
//!
//! Method: stack the regressors of `samples` random states (seeded ChaCha8; positions
//! uniform in the joint limits or [-pi, pi], speeds and accelerations uniform in
//! +-limit or +-2 rad/s, +-5 rad/s^2), scale every column to unit norm, and run a
//! Householder QR with column pivoting twice:
//! 1. largest-residual pivoting (Businger-Golub): the numerical rank `r`;
//! 2. priority pivoting: at each step the *first* remaining column (standard parameter
//!    order) whose residual norm exceeds the tolerance. This picks the `r` independent
//!    columns in natural order (so links near the base absorb the parameters of links
//!    further out, e.g. `b = I1zz + 0.18*m2`), and its count must equal `r`.
//!
//! Rank tolerance: a unit-norm column is dependent when its residual after projecting
//! out the chosen columns is below [`RANK_TOLERANCE`] (1e-8); columns whose norm is below
//! [`ZERO_COLUMN_TOLERANCE`] x the largest column norm have no effect on the torques.
//! The gap between [`BaseParameters::smallest_kept_residual`] and
//! [`BaseParameters::largest_dropped_residual`] shows how clear the decision was.
//!
//! Then `Y_dep = Y_indep * B` (least squares, entries below 1e-10 set to zero, checked on
//! a second independent batch of states), the base parameters are
//! `beta = K theta` with `K = [I  B] (permuted)`, and `Y theta = Y_indep beta`.
//!
//! API: [`BaseParameters::compute`], [`count`](BaseParameters::count),
//! [`project`](BaseParameters::project) (`Y_std -> Y_base`), [`beta`](BaseParameters::beta),
//! [`equivalent_standard`](BaseParameters::equivalent_standard), [`expressions`](BaseParameters::expressions).
use crate::Robot;
use crate::dynamics::stack_regressors;
use nalgebra::{DMatrix, DVector};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Relative residual below which a unit-norm regressor column is dependent.
pub const RANK_TOLERANCE: f64 = 1e-8;
/// Column norm (relative to the largest) below which a column is treated as zero.
pub const ZERO_COLUMN_TOLERANCE: f64 = 1e-10;
/// Grouping coefficients below this magnitude are set to exactly zero.
pub const COEFFICIENT_CUTOFF: f64 = 1e-10;

/// Why base parameters could not be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BaseError {
    /// The robot models no joint.
    #[error("the robot has no modelled joint")]
    NoModelledJoints,
    /// The two pivoting rules disagree on the rank: the decision is not numerically clear.
    #[error(
        "rank is ambiguous: largest-residual pivoting gives {max_norm}, ordered pivoting {ordered}"
    )]
    AmbiguousRank {
        /// Rank from largest-residual pivoting.
        max_norm: usize,
        /// Rank from priority (ordered) pivoting.
        ordered: usize,
    },
    /// The grouping relations do not hold on fresh states.
    #[error("grouping relations fail on fresh states (relative residual {0:e})")]
    Unreliable(f64),
}

/// The base parameters of a robot model.
#[derive(Debug, Clone, PartialEq)]
pub struct BaseParameters {
    /// Names of the standard parameters (layout order).
    pub standard_names: Vec<String>,
    /// Standard parameter kept for each base parameter (increasing).
    pub independent: Vec<usize>,
    /// Standard parameters that are absorbed (or have no effect).
    pub dependent: Vec<usize>,
    /// `beta = K * theta`, `count x p`.
    pub k: DMatrix<f64>,
    /// Seed of the random states.
    pub seed: u64,
    /// Number of random states stacked.
    pub samples: usize,
    /// Smallest relative residual among the kept columns.
    pub smallest_kept_residual: f64,
    /// Largest relative residual among the dropped (non-zero) columns.
    pub largest_dropped_residual: f64,
    /// Largest relative violation of `Y_dep = Y_indep B` on a second batch of states.
    pub relation_residual: f64,
}

/// Random states for identifiability analysis.
pub fn random_states(
    robot: &Robot,
    samples: usize,
    seed: u64,
) -> Vec<(Vec<f64>, Vec<f64>, Vec<f64>)> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let modelled = robot.modelled_joints();
    (0..samples)
        .map(|_| {
            let mut q = Vec::with_capacity(modelled.len());
            let mut qd = Vec::with_capacity(modelled.len());
            let mut qdd = Vec::with_capacity(modelled.len());
            for &i in &modelled {
                let l = &robot.joints[i].limits;
                let lo = l
                    .q_min_rad
                    .unwrap_or(-std::f64::consts::PI)
                    .max(-std::f64::consts::PI);
                let hi = l
                    .q_max_rad
                    .unwrap_or(std::f64::consts::PI)
                    .min(std::f64::consts::PI);
                // Limits that leave no range inside ±π (both above π, or equal) sample
                // their own range, or the one position they allow.
                let (lo, hi) = if lo < hi {
                    (lo, hi)
                } else {
                    let (a, b) = (l.q_min_rad.unwrap_or(lo), l.q_max_rad.unwrap_or(hi));
                    (a.min(b), a.max(b))
                };
                let symmetric = |rng: &mut ChaCha8Rng, m: f64| {
                    if m > 0.0 { rng.gen_range(-m..m) } else { 0.0 }
                };
                q.push(if lo < hi { rng.gen_range(lo..hi) } else { lo });
                qd.push(symmetric(&mut rng, l.qd_max_rad_s.unwrap_or(2.0)));
                qdd.push(symmetric(&mut rng, l.qdd_max_rad_s2.unwrap_or(5.0)));
            }
            (q, qd, qdd)
        })
        .collect()
}

/// Householder QR with column pivoting on `a` (columns already scaled). `ordered`:
/// pick the first remaining column (by original index) above `tol`; otherwise the
/// largest residual. Returns (chosen original indices in pivot order, their residuals,
/// the largest residual left among the rest).
fn pivoted_qr(
    mut a: DMatrix<f64>,
    candidates: &[usize],
    tol: f64,
    ordered: bool,
) -> (Vec<usize>, Vec<f64>, f64) {
    let m = a.nrows();
    let mut rest: Vec<usize> = candidates.to_vec();
    let mut chosen = Vec::new();
    let mut residuals = Vec::new();
    let mut row = 0;
    loop {
        if row >= m || rest.is_empty() {
            break;
        }
        let res = |c: usize, a: &DMatrix<f64>| a.view((row, c), (m - row, 1)).norm();
        let pick = if ordered {
            rest.iter().position(|&c| res(c, &a) > tol)
        } else {
            let (best, val) = rest
                .iter()
                .enumerate()
                .map(|(i, &c)| (i, res(c, &a)))
                .fold((0, -1.0), |acc, x| if x.1 > acc.1 { x } else { acc });
            (val > tol).then_some(best)
        };
        let Some(pos) = pick else { break };
        let c = rest.remove(pos);
        // Householder reflector zeroing column c below `row`.
        let x = a.view((row, c), (m - row, 1)).clone_owned();
        let alpha = -x[0].signum() * x.norm();
        let mut v = x;
        v[0] -= alpha;
        let vn = v.norm();
        residuals.push(alpha.abs());
        chosen.push(c);
        if vn > 0.0 {
            v /= vn;
            for &cc in rest.iter() {
                let mut col = a.view_mut((row, cc), (m - row, 1));
                let d = v.dot(&col);
                col -= &v * (2.0 * d);
            }
        }
        row += 1;
    }
    let left = rest
        .iter()
        .map(|&c| a.view((row.min(m), c), (m - row.min(m), 1)).norm())
        .fold(0.0, f64::max);
    (chosen, residuals, left)
}

/// Rounds to 10 significant digits and cuts tiny values to zero.
fn clean(c: f64) -> f64 {
    if c.abs() < COEFFICIENT_CUTOFF {
        return 0.0;
    }
    format!("{c:.9e}").parse().unwrap_or(c)
}

impl BaseParameters {
    /// Computes the base parameters of `robot`'s model (its modelled joints and terms)
    /// from random states drawn with `seed`.
    pub fn compute(robot: &Robot, seed: u64) -> Result<BaseParameters, BaseError> {
        let n = robot.n_modelled();
        if n == 0 {
            return Err(BaseError::NoModelledJoints);
        }
        let p = robot.parameter_count();
        let samples = (10 * p).div_ceil(n).max(100);
        let states = random_states(robot, samples, seed);
        let y = stack_regressors(
            robot,
            states
                .iter()
                .map(|(a, b, c)| (a.as_slice(), b.as_slice(), c.as_slice())),
        );
        let norms: Vec<f64> = (0..p).map(|c| y.column(c).norm()).collect();
        let max_norm = norms.iter().cloned().fold(0.0, f64::max);
        let nonzero: Vec<usize> = (0..p)
            .filter(|&c| norms[c] > ZERO_COLUMN_TOLERANCE * max_norm)
            .collect();
        let mut scaled = y.clone();
        for &c in &nonzero {
            scaled.column_mut(c).scale_mut(1.0 / norms[c]);
        }
        let (by_norm, _, _) = pivoted_qr(scaled.clone(), &nonzero, RANK_TOLERANCE, false);
        let (chosen, residuals, left) = pivoted_qr(scaled, &nonzero, RANK_TOLERANCE, true);
        if by_norm.len() != chosen.len() {
            return Err(BaseError::AmbiguousRank {
                max_norm: by_norm.len(),
                ordered: chosen.len(),
            });
        }
        let mut independent = chosen.clone();
        independent.sort_unstable();
        let dependent: Vec<usize> = (0..p).filter(|c| !independent.contains(c)).collect();
        let r = independent.len();
        let yb = y.select_columns(&independent);
        let yd = y.select_columns(&dependent);
        let b = if dependent.is_empty() {
            DMatrix::zeros(r, 0)
        } else {
            yb.clone()
                .svd(true, true)
                .solve(&yd, 1e-14)
                .unwrap_or_else(|_| DMatrix::zeros(r, dependent.len()))
        };
        let b = b.map(clean);
        let mut k = DMatrix::zeros(r, p);
        for (i, &c) in independent.iter().enumerate() {
            k[(i, c)] = 1.0;
        }
        for (j, &c) in dependent.iter().enumerate() {
            for i in 0..r {
                k[(i, c)] = b[(i, j)];
            }
        }
        // Check Y = Y_indep K on fresh states.
        let fresh = random_states(robot, samples, seed ^ 0x9e37_79b9_7f4a_7c15);
        let y2 = stack_regressors(
            robot,
            fresh
                .iter()
                .map(|(a, b, c)| (a.as_slice(), b.as_slice(), c.as_slice())),
        );
        let recon = y2.select_columns(&independent) * &k;
        let mut relation_residual = 0.0f64;
        for c in 0..p {
            let scale = y2
                .column(c)
                .norm()
                .max(ZERO_COLUMN_TOLERANCE * max_norm)
                .max(1e-300);
            relation_residual =
                relation_residual.max((y2.column(c) - recon.column(c)).norm() / scale);
        }
        if relation_residual > 1e-6 {
            return Err(BaseError::Unreliable(relation_residual));
        }
        Ok(BaseParameters {
            standard_names: robot.parameter_names(),
            independent,
            dependent,
            k,
            seed,
            samples,
            smallest_kept_residual: residuals.iter().cloned().fold(f64::INFINITY, f64::min),
            largest_dropped_residual: left,
            relation_residual,
        })
    }

    /// Number of base parameters.
    pub fn count(&self) -> usize {
        self.independent.len()
    }

    /// Names `b1 .. br`.
    pub fn names(&self) -> Vec<String> {
        (1..=self.count()).map(|i| format!("b{i}")).collect()
    }

    /// The base regressor: the independent columns of a standard regressor
    /// (any number of rows).
    pub fn project(&self, y_std: &DMatrix<f64>) -> DMatrix<f64> {
        y_std.select_columns(&self.independent)
    }

    /// Base parameters of a standard parameter vector: `beta = K theta`.
    pub fn beta(&self, theta: &DVector<f64>) -> DVector<f64> {
        &self.k * theta
    }

    /// A standard parameter vector reproducing `beta`: the independent parameters take
    /// `beta`, the dependent ones zero, so `Y theta_eq = Y_base beta` for every state.
    pub fn equivalent_standard(&self, beta: &DVector<f64>) -> DVector<f64> {
        let mut theta = DVector::zeros(self.k.ncols());
        for (i, &c) in self.independent.iter().enumerate() {
            theta[c] = beta[i];
        }
        theta
    }

    /// Grouping coefficients of base parameter `i`: (standard index, coefficient),
    /// the kept parameter first.
    pub fn terms(&self, i: usize) -> Vec<(usize, f64)> {
        let mut v = vec![(self.independent[i], 1.0)];
        for &c in &self.dependent {
            let x = self.k[(i, c)];
            if x != 0.0 {
                v.push((c, x));
            }
        }
        v
    }

    /// Readable definitions, e.g. `b3 = I1zz + 0.180625*m2 + 0.425*mx2`.
    pub fn expressions(&self) -> Vec<String> {
        (0..self.count())
            .map(|i| {
                let mut s = format!("b{} = ", i + 1);
                for (n, (c, x)) in self.terms(i).into_iter().enumerate() {
                    let name = &self.standard_names[c];
                    if n == 0 {
                        s.push_str(name);
                    } else if x == 1.0 {
                        s.push_str(&format!(" + {name}"));
                    } else if x == -1.0 {
                        s.push_str(&format!(" - {name}"));
                    } else if x < 0.0 {
                        s.push_str(&format!(" - {}*{name}", -x));
                    } else {
                        s.push_str(&format!(" + {x}*{name}"));
                    }
                }
                s
            })
            .collect()
    }
}
