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
    observation_matrix, scaled_condition_number,
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

/// Default number of CMA-ES restarts.
pub const DEFAULT_RESTARTS: usize = 4;
/// Default objective evaluations per restart.
pub const DEFAULT_EVALUATIONS_PER_RESTART: usize = 6000;

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
    /// How a decision vector is repaired into the limits (default: per joint).
    #[serde(default)]
    pub repair: Repair,
    /// CMA-ES population size λ, at least 4 (`None`: the crate's default `4 + ⌊3 ln n⌋`).
    #[serde(default)]
    pub population: Option<usize>,
}

/// How a decision vector `x` is mapped into the limits before it is scored.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Repair {
    /// One scale `s ≤ 1` for all joints ([`FourierFamily::search_scale`]): the tightest joint
    /// shrinks every other joint too.
    Global,
    /// One scale `s_j ≤ 1` per joint ([`FourierFamily::search_joint_scales`]): every joint is
    /// shrunk only as far as its own limits require.
    #[default]
    PerJoint,
}

impl Repair {
    /// Every repair, in the order the command line lists them.
    pub const ALL: [Self; 2] = [Self::Global, Self::PerJoint];

    /// The repair's name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::Global => "global",
            Self::PerJoint => "per-joint",
        }
    }
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
            restarts: DEFAULT_RESTARTS,
            evaluations_per_restart: DEFAULT_EVALUATIONS_PER_RESTART,
            step_size: 0.5,
            seed: 1,
            max_seconds_per_restart: None,
            repair: Repair::PerJoint,
            population: None,
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

/// Scores a trajectory at the controller rate: both condition numbers from the SVD of the full
/// `W`, log-determinant and smallest singular value from `WᵀW`.
pub fn final_score<M: ObservationModel + ?Sized>(
    model: &M,
    tr: &ExcitationTrajectory,
    rate_hz: f64,
) -> ExcitationScore {
    let samples = (tr.period_s * rate_hz).round().max(1.0) as usize;
    let mut s = ObservationEvaluator::new(model, samples).score(tr);
    let w = observation_matrix(model, tr, rate_hz);
    s.condition = condition_number(&w);
    s.scaled_condition = scaled_condition_number(&w);
    s
}

/// Per-joint scales of `x` on the search grid for the chosen repair (capped at 1).
fn search_scales(family: &FourierFamily, x: &[f64], repair: Repair) -> Vec<f64> {
    match repair {
        Repair::Global => vec![family.search_scale(x, 1.0); family.joint_count()],
        Repair::PerJoint => family.search_joint_scales(x, 1.0),
    }
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
    let n = family.joint_count();
    let criterion = settings.criterion;
    let mut best: Option<(f64, Vec<f64>, Vec<f64>)> = None;
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
        let mut evaluator =
            ObservationEvaluator::new(model, settings.objective_samples).only_for(criterion);
        let f = |x: &DVector<f64>| {
            count.set(count.get() + 1);
            let scales = search_scales(fam, x.as_slice(), settings.repair);
            if scales.iter().any(|&s| s <= 0.0) {
                return 1e6;
            }
            let penalty = scales.iter().map(|s| (1.0 / s).ln()).sum::<f64>() / n as f64;
            let tr = fam.trajectory_per_joint(x.as_slice(), &scales);
            evaluator.score(&tr).cost(criterion) + PENALTY_WEIGHT * penalty
        };
        let mut options = CMAESOptions::new(mean, settings.step_size)
            .seed(seed)
            .max_function_evals(settings.evaluations_per_restart)
            .tol_fun(1e-9);
        if let Some(lambda) = settings.population {
            options = options.population_size(lambda.max(4));
        }
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
            // Final scales on the dense grid (at most a hair below the search grid's).
            let s = search_scales(&family, &x, settings.repair);
            let s = family.dense_joint_scales(&x, &s);
            best = Some((ind.value, x, s));
        }
    }
    let (_, x, s) =
        best.ok_or_else(|| ExciteError::Invalid("the optimiser returned no point".into()))?;
    let trajectory = family.trajectory_per_joint(&x, &s);
    let margins = family.margins_per_joint(&x, &s);
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

/// How a random baseline trajectory is brought onto the limits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum BaselineScaling {
    /// Every joint scaled onto its own tightest limit (the optimiser's per-joint repair with
    /// no cap): a generous baseline that uses every joint's limits as fully as a design.
    PerJoint,
    /// One scale for all joints, onto the tightest limit of any joint: random coefficients
    /// shrunk (or stretched) uniformly until feasible, the plain random feasible trajectory.
    Common,
}

impl BaselineScaling {
    /// Both, generous first.
    pub const ALL: [BaselineScaling; 2] = [BaselineScaling::PerJoint, BaselineScaling::Common];

    /// Short name (`per-joint`, `common`).
    pub fn name(self) -> &'static str {
        match self {
            BaselineScaling::PerJoint => "per-joint",
            BaselineScaling::Common => "common",
        }
    }

    /// How the population was scaled, in words.
    pub fn describe(self) -> &'static str {
        match self {
            BaselineScaling::PerJoint => "every joint scaled onto its own tightest limit",
            BaselineScaling::Common => "one scale for all joints, onto the tightest limit",
        }
    }
}

/// A random feasible trajectory of the family (the baseline the design must beat): a
/// standard-normal decision vector (the optimiser's parametrisation: rest-to-rest by
/// construction), brought onto the limits by `scaling`.
pub fn random_feasible(
    family: &FourierFamily,
    seed: u64,
    scaling: BaselineScaling,
) -> ExcitationTrajectory {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let x: Vec<f64> = (0..family.dimension())
        .map(|_| StandardNormal.sample(&mut rng))
        .collect();
    let mut s: Vec<f64> = family
        .joint_scales(&x, f64::INFINITY)
        .into_iter()
        .map(|s| if s.is_finite() { s } else { 1.0 })
        .collect();
    if scaling == BaselineScaling::Common {
        let common = s.iter().copied().fold(f64::INFINITY, f64::min);
        s.fill(if common.is_finite() { common } else { 1.0 });
    }
    family.trajectory_per_joint(&x, &s)
}

/// Seed of member `i` of a random baseline population with master seed `seed`.
pub fn baseline_seed(seed: u64, i: usize) -> u64 {
    restart_seed(seed ^ 0xBA5E_BA5E, i)
}

/// Default size of the random baseline population.
pub const DEFAULT_BASELINE_COUNT: usize = 20;

/// Scores of a seeded population of random feasible trajectories ([`random_feasible`] with
/// seeds [`baseline_seed`]`(seed, 0..count)`), each scored at the controller rate like a design.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct RandomBaseline {
    /// Master seed of the population.
    pub seed: u64,
    /// How each member was brought onto the limits.
    pub scaling: BaselineScaling,
    /// Seed of each member.
    pub seeds: Vec<u64>,
    /// Score of each member (same order as `seeds`).
    pub scores: Vec<ExcitationScore>,
}

/// Median and best of one figure over a population.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PopulationStats {
    /// Median (mean of the two middle values for an even count).
    pub median: f64,
    /// Smallest value (the best draw: condition numbers are minimised).
    pub best: f64,
    /// Largest value.
    pub worst: f64,
}

impl PopulationStats {
    /// Statistics of `values` (at least one).
    pub fn of(values: &[f64]) -> Self {
        let mut v = values.to_vec();
        v.sort_by(f64::total_cmp);
        let m = v.len();
        let median = if m % 2 == 1 {
            v[m / 2]
        } else {
            0.5 * (v[m / 2 - 1] + v[m / 2])
        };
        Self {
            median,
            best: v[0],
            worst: v[m - 1],
        }
    }
}

impl RandomBaseline {
    /// Statistics of the unscaled condition number (the paper's).
    pub fn condition(&self) -> PopulationStats {
        PopulationStats::of(&self.scores.iter().map(|s| s.condition).collect::<Vec<_>>())
    }

    /// Statistics of the column-scaled condition number.
    pub fn scaled_condition(&self) -> PopulationStats {
        PopulationStats::of(
            &self
                .scores
                .iter()
                .map(|s| s.scaled_condition)
                .collect::<Vec<_>>(),
        )
    }
}

/// Scores `count` (at least 1) seeded random feasible trajectories of `family` at `rate_hz`.
pub fn random_baseline<M: ObservationModel + ?Sized>(
    model: &M,
    family: &FourierFamily,
    count: usize,
    seed: u64,
    rate_hz: f64,
    scaling: BaselineScaling,
) -> RandomBaseline {
    let seeds: Vec<u64> = (0..count.max(1)).map(|i| baseline_seed(seed, i)).collect();
    let scores = seeds
        .iter()
        .map(|&sd| final_score(model, &random_feasible(family, sd, scaling), rate_hz))
        .collect();
    RandomBaseline {
        seed,
        scaling,
        seeds,
        scores,
    }
}
