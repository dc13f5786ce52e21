//! Seeded multi-start CMA-ES over the constrained Fourier family.
//!
//! Each decision vector `x` is first mapped into the limits by [`FourierFamily::feasible_scale`]
//! (shrinking toward the particular solution, normally the rest pose), so every evaluated
//! trajectory is feasible and the optimiser is unconstrained. A small penalty
//! `PENALTY_WEIGHT · ln(1/s)` on the shrink factor `s` keeps the search near the feasible
//! boundary instead of drifting along rays where the scaled trajectory no longer changes.
//!
//! When the particular solution itself breaks a limit (possible only with extra point
//! constraints), a first CMA-ES phase minimises the largest limit utilisation; if that stays
//! above 1 the problem has no feasible solution and the error names the tightest constraint.

use super::ExciteError;
use super::constraints::{ConstraintMargin, FourierFamily, tightest};
use super::objective::{
    Criterion, ExcitationScore, ObservationEvaluator, ObservationModel, condition_number,
    observation_matrix,
};
use super::trajectory::{
    DEFAULT_HARMONICS, DEFAULT_PERIOD_S, DEFAULT_RATE_HZ, ExcitationTrajectory,
};
use cmaes::{CMAESOptions, DVector, TerminationReason};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};
use std::cell::Cell;
use std::time::{Duration, Instant};

/// Weight of the shrink penalty `ln(1/s)` added to the cost (cost is `ln cond` or `−log det`).
pub const PENALTY_WEIGHT: f64 = 0.05;

/// Settings of an excitation design.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ExcitationSettings {
    /// Number of harmonics `N` (paper: 5).
    pub harmonics: usize,
    /// Period `T` in s (`ω_f = 2π/T`; paper: 10 s trajectories).
    pub period_s: f64,
    /// Controller (playback) rate in Hz.
    pub rate_hz: f64,
    /// Limit-check grid rate as a multiple of the controller rate (≥ 10).
    pub check_factor: usize,
    /// Samples per period used to score a candidate during the search (the final score uses the
    /// controller rate).
    pub objective_samples: usize,
    /// Criterion minimised.
    pub criterion: Criterion,
    /// Number of independent CMA-ES runs (restarts), each from its own seeded start.
    pub restarts: usize,
    /// Objective evaluations allowed per restart.
    pub evaluations_per_restart: usize,
    /// Initial CMA-ES step size in normalised coefficient units.
    pub step_size: f64,
    /// Master seed: restart `r` uses a seed derived from it.
    pub seed: u64,
    /// Optional wall-clock limit per restart.
    pub max_seconds_per_restart: Option<f64>,
}

impl Default for ExcitationSettings {
    fn default() -> Self {
        Self {
            harmonics: DEFAULT_HARMONICS,
            period_s: DEFAULT_PERIOD_S,
            rate_hz: DEFAULT_RATE_HZ,
            check_factor: 10,
            objective_samples: 200,
            criterion: Criterion::Condition,
            restarts: 4,
            evaluations_per_restart: 6000,
            step_size: 0.5,
            seed: 1,
            max_seconds_per_restart: None,
        }
    }
}

/// Outcome of one CMA-ES run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RestartReport {
    /// Seed of the run.
    pub seed: u64,
    /// Best cost reached (`ln cond + penalty` or `−log det + penalty`).
    pub best_cost: f64,
    /// Objective evaluations used.
    pub evaluations: usize,
    /// Why CMA-ES stopped.
    pub stopped_because: String,
}

/// The result of an excitation design.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ExcitationDesign {
    /// The optimised trajectory (coefficients).
    pub trajectory: ExcitationTrajectory,
    /// Score of the observation matrix at the controller rate (condition number from the SVD).
    pub score: ExcitationScore,
    /// Margin to every limit on the dense grid.
    pub margins: Vec<ConstraintMargin>,
    /// Total objective evaluations (all phases, all restarts).
    pub evaluations: usize,
    /// One report per restart.
    pub restarts: Vec<RestartReport>,
    /// Wall-clock time of the search in s.
    pub seconds: f64,
    /// Settings used.
    pub settings: ExcitationSettings,
}

/// Derives restart `r`'s seed from the master seed.
fn restart_seed(seed: u64, r: usize) -> u64 {
    seed.wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(r as u64 + 1)
        .rotate_left(17)
}

fn reason_text(reasons: &[TerminationReason]) -> String {
    reasons
        .iter()
        .map(|r| format!("{r:?}"))
        .collect::<Vec<_>>()
        .join(",")
}

/// Scores a trajectory at the controller rate: condition number from the SVD of the full `W`,
/// log-determinant and smallest singular value from `WᵀW`.
pub fn final_score<M: ObservationModel + ?Sized>(
    model: &M,
    tr: &ExcitationTrajectory,
    rate_hz: f64,
) -> ExcitationScore {
    let samples = (tr.period_s * rate_hz).round().max(1.0) as usize;
    let mut s = ObservationEvaluator::new(model, samples).score(tr);
    s.condition = condition_number(&observation_matrix(model, tr, rate_hz));
    s
}

/// Finds a feasible particular solution when the given one breaks a limit (phase 1).
fn ensure_feasible_start(
    family: &mut FourierFamily,
    settings: &ExcitationSettings,
    evaluations: &mut usize,
) -> Result<(), ExciteError> {
    let start = family.particular_margins();
    let worst = tightest(&start).expect("at least one joint");
    if worst.utilisation <= 1.0 {
        return Ok(());
    }
    let dim = family.dimension();
    let count = Cell::new(0usize);
    let fam = &*family;
    let f = |x: &DVector<f64>| {
        count.set(count.get() + 1);
        tightest(&fam.margins(x.as_slice(), 1.0)).map_or(f64::INFINITY, |m| m.utilisation)
    };
    let mut best: Option<(f64, Vec<f64>)> = None;
    for r in 0..settings.restarts.max(1) {
        let seed = restart_seed(settings.seed ^ 0xFEA5_1B1E, r);
        let mut cm = CMAESOptions::new(vec![0.0; dim], settings.step_size)
            .seed(seed)
            .max_function_evals(settings.evaluations_per_restart)
            .fun_target(0.99)
            .build(f)
            .map_err(|e| ExciteError::Invalid(format!("CMA-ES options: {e:?}")))?;
        let res = cm.run();
        if let Some(ind) = res.overall_best
            && best.as_ref().is_none_or(|b| ind.value < b.0)
        {
            best = Some((ind.value, ind.point.as_slice().to_vec()));
        }
        if best.as_ref().is_some_and(|b| b.0 <= 1.0) {
            break;
        }
    }
    *evaluations += count.get();
    let (value, x) =
        best.ok_or_else(|| ExciteError::Invalid("feasibility search failed".into()))?;
    if value > 1.0 {
        let t = tightest(&family.margins(&x, 1.0)).expect("at least one joint");
        return Err(ExciteError::Infeasible(format!(
            "no trajectory meets every limit; the tightest constraint is moving joint #{} {}: \
             best reached {:.4} against the limit {:.4} (utilisation {:.3})",
            t.joint,
            t.kind.describe(),
            t.extreme,
            t.limit,
            t.utilisation
        )));
    }
    family.recentre(&x, 1.0);
    Ok(())
}

/// Designs an optimised excitation trajectory for `model` over `family`.
pub fn design<M: ObservationModel + ?Sized>(
    model: &M,
    mut family: FourierFamily,
    settings: &ExcitationSettings,
) -> Result<ExcitationDesign, ExciteError> {
    if model.joint_count() != family.joint_count() {
        return Err(ExciteError::Invalid(format!(
            "the model moves {} joints but the trajectory family has {}",
            model.joint_count(),
            family.joint_count()
        )));
    }
    let started = Instant::now();
    let mut evaluations = 0usize;
    ensure_feasible_start(&mut family, settings, &mut evaluations)?;
    let dim = family.dimension();
    let criterion = settings.criterion;
    let mut best: Option<(f64, Vec<f64>, f64)> = None;
    let mut restarts = Vec::new();
    for r in 0..settings.restarts.max(1) {
        let seed = restart_seed(settings.seed, r);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mean: Vec<f64> = (0..dim)
            .map(|_| {
                let z: f64 = StandardNormal.sample(&mut rng);
                z
            })
            .collect();
        let count = Cell::new(0usize);
        let fam = &family;
        let mut evaluator = ObservationEvaluator::new(model, settings.objective_samples);
        let f = |x: &DVector<f64>| {
            count.set(count.get() + 1);
            let s = fam.search_scale(x.as_slice(), 1.0);
            if s <= 0.0 {
                return 1e6;
            }
            let tr = fam.trajectory(x.as_slice(), s);
            evaluator.score(&tr).cost(criterion) + PENALTY_WEIGHT * (1.0 / s).ln()
        };
        let mut options = CMAESOptions::new(mean, settings.step_size)
            .seed(seed)
            .max_function_evals(settings.evaluations_per_restart)
            .tol_fun(1e-9);
        if let Some(secs) = settings.max_seconds_per_restart {
            options = options.max_time(Duration::from_secs_f64(secs));
        }
        let mut cm = options
            .build(f)
            .map_err(|e| ExciteError::Invalid(format!("CMA-ES options: {e:?}")))?;
        let res = cm.run();
        drop(cm);
        evaluations += count.get();
        let Some(ind) = res.overall_best else {
            continue;
        };
        restarts.push(RestartReport {
            seed,
            best_cost: ind.value,
            evaluations: count.get(),
            stopped_because: reason_text(&res.reasons),
        });
        if best.as_ref().is_none_or(|b| ind.value < b.0) {
            let x = ind.point.as_slice().to_vec();
            // Final scale on the dense grid (at most a hair below the search grid's).
            let s = family.feasible_scale(&x, family.search_scale(&x, 1.0));
            best = Some((ind.value, x, s));
        }
    }
    let (_, x, s) =
        best.ok_or_else(|| ExciteError::Invalid("the optimiser returned no point".into()))?;
    let trajectory = family.trajectory(&x, s);
    let margins = family.margins(&x, s);
    let score = final_score(model, &trajectory, settings.rate_hz);
    if !score.condition.is_finite() {
        let t = tightest(&margins).expect("at least one joint");
        return Err(ExciteError::Infeasible(format!(
            "no feasible trajectory excites every parameter (observation matrix rank-deficient); \
             the tightest constraint is moving joint #{} {} (utilisation {:.3})",
            t.joint,
            t.kind.describe(),
            t.utilisation
        )));
    }
    Ok(ExcitationDesign {
        trajectory,
        score,
        margins,
        evaluations,
        restarts,
        seconds: started.elapsed().as_secs_f64(),
        settings: settings.clone(),
    })
}

/// A random feasible trajectory of the family (the baseline the design must beat): standard
/// normal decision vector, scaled so that its tightest limit is just reached.
pub fn random_feasible(family: &FourierFamily, seed: u64) -> ExcitationTrajectory {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let x: Vec<f64> = (0..family.dimension())
        .map(|_| StandardNormal.sample(&mut rng))
        .collect();
    let s = family.feasible_scale(&x, f64::INFINITY);
    family.trajectory(&x, if s.is_finite() { s } else { 1.0 })
}
