//! Physically consistent identification: the pseudo-inertia LMI (Wensing, Kim and
//! Slotine 2017) solved with Clarabel's PSD cones.
//!
//! The least-squares solve ([`crate::solve`]) returns base parameters `β_u` that fit the
//! data; the directions it could not identify keep the prior. Nothing makes the mix a
//! rigid body: a link may need a negative mass or a second moment smaller than its first
//! moment allows, and then poses the data never visited get implausible torques.
//!
//! Here the standard parameters `θ` of every link (mass, first moments, inertia about
//! the link origin) and the per-joint terms (friction, rotor inertia) are the unknowns:
//! - **consistency test**: is there a `θ` with `Kθ = β_u` (the base parameters) whose
//!   every link's 4×4 pseudo-inertia `J = [[½tr(I)·1 − I, h], [hᵀ, m]]` is PSD and whose
//!   viscous, Coulomb and rotor-inertia terms are ≥ 0? If so, `β_u` is kept bit for bit
//!   (`solution = "unconstrained"`).
//! - otherwise, where the data leave directions unidentified, the **LMI fit**: minimise the increase of the weighted residual,
//!   `(Kθ − β_u)ᵀ H (Kθ − β_u)` (`H = Σⱼ YⱼᵀYⱼ/σⱼ²`, the weighted normal matrix: this is the
//!   weighted residual sum minus its least-squares minimum, in units of the noise
//!   variance, as `β_u` minimises it along every identified direction), plus a small pull
//!   [`PULL_WEIGHT`]`·‖(θ − θ₀)/s‖²` to the robot description's nominal values `θ₀` (`s`:
//!   per-parameter scales, [`parameter_scales`]), subject to the same cones. Along the
//!   directions the data identify the pull is negligible; along the others it picks the
//!   consistent body closest to the description (`solution = "lmi"`).
//!
//! The pseudo-inertia is PSD in one frame exactly when it is in any other (a congruence),
//! so the link-frame parameters of the robot description are constrained as they are.
use crate::NormalEquations;
use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettings, DefaultSolver, IPSolver, SolverStatus, SupportedConeT};
use nalgebra::{DMatrix, DVector, Matrix4};
use robot::base::BaseParameters;
use robot::{JointParameter, PARAMETERS_PER_LINK, Robot};
use serde::{Deserialize, Serialize};
use std::fmt;

/// Weight of the pull to the nominal parameters, in units of the weighted residual (the
/// noise variance σ²): moving one parameter by its own scale costs as much as one σ² of
/// residual, what one standard deviation along an identified direction costs. A
/// direction the data pin down costs thousands of σ² per scale, so the pull moves it by
/// a fraction of its standard deviation; a direction the data leave open stays near the
/// description instead of going wherever the cones let it (measured in
/// `tests/consistent.rs`: 1e-2 let weakly excited wrist parameters drift, 100 cost
/// hundreds of σ² of residual).
pub const PULL_WEIGHT: f64 = 1.0;

/// What the consistency step did, as recorded in the model file (`first_stage`).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ConsistencyReport {
    /// `"unconstrained"`: the least-squares parameters were kept (those of a physically
    /// consistent body, or identified along every direction); `"lmi"`: they were no
    /// rigid body and the data left directions open, the LMI fit replaced them.
    pub solution: String,
    /// Clarabel's status of the consistency test (`Solved`: consistent;
    /// `PrimalInfeasible`: no consistent body has these base parameters).
    pub test_status: String,
    /// Clarabel's status of the LMI fit (empty when it was not needed).
    pub fit_status: String,
    /// Wall-clock time of both solves [s]: printed, not written to the model file (the
    /// same inputs give the same file).
    #[serde(skip)]
    pub solve_time_s: f64,
    /// Per link (base to tip), the smallest eigenvalue of the pseudo-inertia of the
    /// standard parameters kept [kg·m²] (≥ 0 up to the solver's tolerance for a
    /// consistent body).
    pub min_pseudo_inertia_eigenvalue_kg_m2: Vec<f64>,
    /// Increase of the weighted residual sum `Σ e²/σ²` over its least-squares minimum
    /// that the LMI fit costs (units of the noise variance; the sum itself is about
    /// samples × joints; 0 when the fit was not run).
    pub residual_increase_sigma2: f64,
}

/// Equal when everything the model file records is equal (the wall-clock time is not
/// recorded, so a file reads back equal to the report it was written from).
impl PartialEq for ConsistencyReport {
    fn eq(&self, other: &Self) -> bool {
        self.solution == other.solution
            && self.test_status == other.test_status
            && self.fit_status == other.fit_status
            && self.min_pseudo_inertia_eigenvalue_kg_m2 == other.min_pseudo_inertia_eigenvalue_kg_m2
            && self.residual_increase_sigma2 == other.residual_increase_sigma2
    }
}

/// The consistent first stage.
#[derive(Debug, Clone, PartialEq)]
pub struct ConsistentFit {
    /// Base parameters (the least-squares ones when they were consistent).
    pub values: Vec<f64>,
    /// Standard parameters with these base parameters (layout of
    /// [`Robot::parameter_layout`]): a consistent body's, unless the test found none and
    /// the least-squares model was kept (then the dependent ones are 0).
    pub standard: Vec<f64>,
    /// What was done.
    pub report: ConsistencyReport,
}

/// Why the consistency step failed.
#[derive(Debug, Clone, PartialEq)]
pub enum ConsistencyError {
    /// The inputs do not fit together (sizes) or are not finite.
    Setup(String),
    /// The solver did not solve the LMI fit.
    Solver {
        /// The step ("consistency test" or "LMI fit").
        stage: &'static str,
        /// Clarabel's status or error.
        status: String,
    },
}

impl fmt::Display for ConsistencyError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ConsistencyError::Setup(why) => write!(f, "physical consistency: {why}"),
            ConsistencyError::Solver { stage, status } => write!(
                f,
                "physical consistency: the convex solver (Clarabel) did not solve the {stage}: {status}"
            ),
        }
    }
}

impl std::error::Error for ConsistencyError {}

/// Indices into the 10 link parameters `[m, hx, hy, hz, Ixx, Iyy, Izz, Ixy, Ixz, Iyz]` and
/// coefficients of each entry of the pseudo-inertia, in Clarabel's PSD-triangle order
/// (upper triangle by columns: 00, 01, 11, 02, 12, 22, 03, 13, 23, 33).
const PSEUDO_INERTIA_TERMS: [&[(usize, f64)]; 10] = [
    &[(4, -0.5), (5, 0.5), (6, 0.5)], // Σxx = (−Ixx + Iyy + Izz)/2
    &[(7, -1.0)],                     // Σxy = −Ixy
    &[(4, 0.5), (5, -0.5), (6, 0.5)], // Σyy
    &[(8, -1.0)],                     // Σxz = −Ixz
    &[(9, -1.0)],                     // Σyz = −Iyz
    &[(4, 0.5), (5, 0.5), (6, -0.5)], // Σzz
    &[(1, 1.0)],                      // hx
    &[(2, 1.0)],                      // hy
    &[(3, 1.0)],                      // hz
    &[(0, 1.0)],                      // m
];
const TRIANGLE: [(usize, usize); 10] = [
    (0, 0),
    (0, 1),
    (1, 1),
    (0, 2),
    (1, 2),
    (2, 2),
    (0, 3),
    (1, 3),
    (2, 3),
    (3, 3),
];

/// The 4×4 pseudo-inertia of link parameters `[m, hx, hy, hz, Ixx, Iyy, Izz, Ixy, Ixz, Iyz]`
/// (inertia about the frame origin).
pub fn pseudo_inertia(p: &[f64]) -> Matrix4<f64> {
    let mut j = Matrix4::zeros();
    for (terms, &(r, c)) in PSEUDO_INERTIA_TERMS.iter().zip(&TRIANGLE) {
        let v: f64 = terms.iter().map(|&(k, w)| w * p[k]).sum();
        j[(r, c)] = v;
        j[(c, r)] = v;
    }
    j
}

/// Smallest eigenvalue of each link's pseudo-inertia in a standard parameter vector
/// `theta` of `robot`'s layout [kg·m²].
pub fn min_pseudo_inertia_eigenvalues(robot: &Robot, theta: &[f64]) -> Vec<f64> {
    let layout = robot.parameter_layout();
    (0..layout.links)
        .map(|l| {
            let i0 = layout.link_index(l, 0);
            pseudo_inertia(&theta[i0..i0 + PARAMETERS_PER_LINK])
                .symmetric_eigenvalues()
                .min()
        })
        .collect()
}

/// Scales of the standard parameters for the pull: per class (mass, first moment,
/// inertia, each per-joint kind) `max(|θ₀ᵢ|, 0.01 · max over the class |θ₀|)`, 1 where a
/// whole class is zero.
pub fn parameter_scales(robot: &Robot, theta0: &[f64]) -> Vec<f64> {
    let layout = robot.parameter_layout();
    let class = |i: usize| -> usize {
        let nl = PARAMETERS_PER_LINK * layout.links;
        if i < nl {
            match i % PARAMETERS_PER_LINK {
                0 => 0,
                1..=3 => 1,
                _ => 2,
            }
        } else {
            3 + (i - nl) % layout.joint_kinds.len().max(1)
        }
    };
    let n_classes = 3 + layout.joint_kinds.len();
    let mut cmax = vec![0.0f64; n_classes];
    for (i, v) in theta0.iter().enumerate() {
        cmax[class(i)] = cmax[class(i)].max(v.abs());
    }
    theta0
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let c = cmax[class(i)];
            if c > 0.0 { v.abs().max(0.01 * c) } else { 1.0 }
        })
        .collect()
}

/// Standard parameters constrained to be ≥ 0: viscous and Coulomb friction, rotor inertia.
fn nonnegative_parameters(robot: &Robot) -> Vec<usize> {
    let layout = robot.parameter_layout();
    let mut v = Vec::new();
    for m in 0..layout.modelled.len() {
        for kind in [
            JointParameter::Viscous,
            JointParameter::Coulomb,
            JointParameter::RotorInertia,
        ] {
            if let Some(i) = layout.joint_index(m, kind) {
                v.push(i);
            }
        }
    }
    v
}

/// A dense matrix as Clarabel's CSC (entries exactly 0 left out; `upper`: upper triangle only).
fn csc(m: &DMatrix<f64>, upper: bool) -> CscMatrix<f64> {
    let mut colptr = vec![0usize];
    let mut rowval = Vec::new();
    let mut nzval = Vec::new();
    for c in 0..m.ncols() {
        let rows = if upper { c + 1 } else { m.nrows() };
        for r in 0..rows {
            let v = m[(r, c)];
            if v != 0.0 {
                rowval.push(r);
                nzval.push(v);
            }
        }
        colptr.push(rowval.len());
    }
    CscMatrix::new(m.nrows(), m.ncols(), colptr, rowval, nzval)
}

/// The cone rows on the scaled unknowns `z = θ / s`: per link a 4×4 PSD triangle (the
/// pseudo-inertia), then one non-negative row per sign-constrained term. Returns
/// `(A, cones)` for Clarabel's `A z + slack = 0`, slack in the cones.
fn cone_rows(robot: &Robot, scales: &[f64]) -> (DMatrix<f64>, Vec<SupportedConeT<f64>>) {
    let layout = robot.parameter_layout();
    let p = scales.len();
    let nonneg = nonnegative_parameters(robot);
    let rows = 10 * layout.links + nonneg.len();
    let mut a = DMatrix::zeros(rows, p);
    let mut cones = Vec::new();
    for l in 0..layout.links {
        let i0 = layout.link_index(l, 0);
        for (e, (terms, &(r, c))) in PSEUDO_INERTIA_TERMS.iter().zip(&TRIANGLE).enumerate() {
            let w = if r == c {
                1.0
            } else {
                std::f64::consts::SQRT_2
            };
            for &(k, coef) in terms.iter() {
                a[(10 * l + e, i0 + k)] = -w * coef * scales[i0 + k];
            }
        }
        cones.push(SupportedConeT::PSDTriangleConeT(4));
    }
    for (n, &i) in nonneg.iter().enumerate() {
        a[(10 * layout.links + n, i)] = -scales[i];
    }
    if !nonneg.is_empty() {
        cones.push(SupportedConeT::NonnegativeConeT(nonneg.len()));
    }
    (a, cones)
}

struct Solved {
    status: SolverStatus,
    x: Vec<f64>,
}

fn run_clarabel(
    p: &DMatrix<f64>,
    q: &[f64],
    a: &DMatrix<f64>,
    b: &[f64],
    cones: &[SupportedConeT<f64>],
    stage: &'static str,
) -> Result<Solved, ConsistencyError> {
    let settings = DefaultSettings {
        verbose: false,
        max_iter: 500,
        ..DefaultSettings::default()
    };
    let (pc, ac) = (csc(p, true), csc(a, false));
    // The solver is a library of ours to call, not to trust with the process: any panic
    // inside it becomes an error naming the step.
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        let mut solver =
            DefaultSolver::new(&pc, q, &ac, b, cones, settings).map_err(|e| format!("{e:?}"))?;
        solver.solve();
        Ok::<_, String>(Solved {
            status: solver.solution.status,
            x: solver.solution.x.clone(),
        })
    }))
    .map_err(|_| ConsistencyError::Solver {
        stage,
        status: "the solver panicked".into(),
    })?
    .map_err(|status| ConsistencyError::Solver { stage, status })
}

/// Makes the least-squares base parameters `beta_u` (identified from `ne` with per-joint
/// noise `sigma_nm`, `dropped_directions` of them left to the prior) physically
/// consistent, see the module documentation. `robot` and `base` are the model the base
/// parameters belong to; `robot`'s own (nominal) parameters are the prior.
///
/// Where the data identify every direction (`dropped_directions == 0`) an inconsistent
/// least-squares model is kept all the same, with the LMI fit's cost reported: there the
/// inconsistency is the data's (a model error the rigid body cannot express), and on the
/// real UR10e runs the LMI fit made the held-out error of joint 2 4 % (viscous-Coulomb)
/// and 11 % (extended friction) worse.
pub fn consistent_fit(
    ne: &mut NormalEquations,
    sigma_nm: &[f64],
    beta_u: &[f64],
    dropped_directions: usize,
    robot: &Robot,
    base: &BaseParameters,
) -> Result<ConsistentFit, ConsistencyError> {
    let t0 = std::time::Instant::now();
    ne.flush();
    let r = base.count();
    let theta0: Vec<f64> = robot.standard_parameters().iter().copied().collect();
    let p = theta0.len();
    if ne.n_params != r || beta_u.len() != r || base.k.ncols() != p {
        return Err(ConsistencyError::Setup(format!(
            "{} base parameters, {} in the normal equations, {} estimates, {} standard parameters for {p}",
            r,
            ne.n_params,
            beta_u.len(),
            base.k.ncols()
        )));
    }
    if sigma_nm.len() != ne.n_joints || sigma_nm.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
        return Err(ConsistencyError::Setup(format!(
            "per-joint noise {sigma_nm:?} for {} joints",
            ne.n_joints
        )));
    }
    if let Some(i) = beta_u.iter().position(|v| !v.is_finite()) {
        return Err(ConsistencyError::Setup(format!(
            "base parameter b{} is {}",
            i + 1,
            beta_u[i]
        )));
    }
    let mut h = DMatrix::<f64>::zeros(r, r);
    for (ata, s) in ne.ata.iter().zip(sigma_nm) {
        h += ata / (s * s);
    }
    let scales = parameter_scales(robot, &theta0);
    let z0 = DVector::from_iterator(p, (0..p).map(|i| theta0[i] / scales[i]));
    // Base parameters of the scaled unknowns: β = M z.
    let mut m = base.k.clone();
    for (c, s) in scales.iter().enumerate() {
        m.column_mut(c).scale_mut(*s);
    }
    let beta_u_v = DVector::from_column_slice(beta_u);
    let (a_cone, cones) = cone_rows(robot, &scales);

    // Consistency test: M z = β_u (rows scaled to unit largest entry), cones, nearest to z0.
    let mut a_eq = DMatrix::zeros(r, p);
    let mut b_eq = vec![0.0; r];
    for i in 0..r {
        let row_max = m.row(i).amax();
        let w = if row_max > 0.0 { 1.0 / row_max } else { 1.0 };
        a_eq.row_mut(i).copy_from(&(m.row(i) * w));
        b_eq[i] = beta_u[i] * w;
    }
    let a_test = stack(&a_eq, &a_cone);
    let b_test: Vec<f64> = b_eq
        .iter()
        .copied()
        .chain(std::iter::repeat_n(0.0, a_cone.nrows()))
        .collect();
    let mut cones_test = vec![SupportedConeT::ZeroConeT(r)];
    cones_test.extend(cones.iter().cloned());
    let q_test: Vec<f64> = z0.iter().map(|v| -v).collect();
    let test = run_clarabel(
        &DMatrix::identity(p, p),
        &q_test,
        &a_test,
        &b_test,
        &cones_test,
        "consistency test",
    )?;
    let test_status = format!("{:?}", test.status);
    if matches!(test.status, SolverStatus::Solved) {
        let theta: Vec<f64> = (0..p).map(|i| test.x[i] * scales[i]).collect();
        return Ok(ConsistentFit {
            values: beta_u.to_vec(),
            report: ConsistencyReport {
                solution: "unconstrained".into(),
                test_status,
                fit_status: String::new(),
                solve_time_s: t0.elapsed().as_secs_f64(),
                min_pseudo_inertia_eigenvalue_kg_m2: min_pseudo_inertia_eigenvalues(robot, &theta),
                residual_increase_sigma2: 0.0,
            },
            standard: theta,
        });
    }

    // LMI fit: min (M z − β_u)ᵀ H (M z − β_u) + ε ‖z − z0‖² over the cones, the
    // objective divided by its largest curvature (the same minimiser, a well-scaled problem).
    let hm = &h * &m;
    let mut p_fit = m.transpose() * &hm;
    p_fit = (&p_fit + p_fit.transpose()) * 0.5;
    for i in 0..p {
        p_fit[(i, i)] += PULL_WEIGHT;
    }
    let q_fit = -(hm.transpose() * &beta_u_v + &z0 * PULL_WEIGHT);
    // The curvature spans the pull (1) to the best-identified direction (1e9 and more):
    // unknowns w = z·√Pᵢᵢ give the solver a unit diagonal (its own equilibration stops
    // at 1e4), so the directions only the pull holds are solved as accurately as the rest.
    let c: Vec<f64> = (0..p).map(|i| 1.0 / p_fit[(i, i)].sqrt()).collect();
    let p_w = DMatrix::from_fn(p, p, |r, k| p_fit[(r, k)] * c[r] * c[k]);
    let q_w: Vec<f64> = (0..p).map(|i| q_fit[i] * c[i]).collect();
    let a_w = DMatrix::from_fn(a_cone.nrows(), p, |r, k| a_cone[(r, k)] * c[k]);
    let mut fit = run_clarabel(
        &p_w,
        &q_w,
        &a_w,
        &vec![0.0; a_cone.nrows()],
        &cones,
        "LMI fit",
    )?;
    fit.x.iter_mut().zip(&c).for_each(|(x, c)| *x *= c);
    let fit_status = format!("{:?}", fit.status);
    if !matches!(
        fit.status,
        SolverStatus::Solved | SolverStatus::AlmostSolved
    ) || fit.x.iter().any(|v| !v.is_finite())
    {
        return Err(ConsistencyError::Solver {
            stage: "LMI fit",
            status: fit_status,
        });
    }
    let theta: Vec<f64> = (0..p).map(|i| fit.x[i] * scales[i]).collect();
    let beta = &base.k * DVector::from_column_slice(&theta);
    let d = &beta - &beta_u_v;
    let residual_increase_sigma2 = (d.transpose() * &h * &d)[(0, 0)];
    if dropped_directions == 0 {
        // The data identify every direction: the least-squares model is kept (see
        // `consistent_fit`); the fit's cost is reported beside it.
        let theta: Vec<f64> = base
            .equivalent_standard(&beta_u_v)
            .iter()
            .copied()
            .collect();
        return Ok(ConsistentFit {
            values: beta_u.to_vec(),
            report: ConsistencyReport {
                solution: "unconstrained".into(),
                test_status,
                fit_status,
                solve_time_s: t0.elapsed().as_secs_f64(),
                min_pseudo_inertia_eigenvalue_kg_m2: min_pseudo_inertia_eigenvalues(robot, &theta),
                residual_increase_sigma2,
            },
            standard: theta,
        });
    }
    Ok(ConsistentFit {
        values: beta.iter().copied().collect(),
        report: ConsistencyReport {
            solution: "lmi".into(),
            test_status,
            fit_status,
            solve_time_s: t0.elapsed().as_secs_f64(),
            min_pseudo_inertia_eigenvalue_kg_m2: min_pseudo_inertia_eigenvalues(robot, &theta),
            residual_increase_sigma2,
        },
        standard: theta,
    })
}

fn stack(a: &DMatrix<f64>, b: &DMatrix<f64>) -> DMatrix<f64> {
    let mut s = DMatrix::zeros(a.nrows() + b.nrows(), a.ncols());
    s.rows_mut(0, a.nrows()).copy_from(a);
    s.rows_mut(a.nrows(), b.nrows()).copy_from(b);
    s
}
