//! Constraints on an excitation trajectory and the constrained trajectory family.
//!
//! Equality constraints (rest pose with zero velocity and acceleration at `t = 0`, hence at
//! `t = T` by periodicity, plus optional point constraints such as `q_i(3.8 s) = 0`) are linear
//! in each joint's coefficients `c = [q0, a_1..a_N, b_1..b_N]`. They are enforced **by
//! construction**: `c = c_p + Z·x`, where `c_p` solves the equality system (the rest pose itself
//! when it satisfies every constraint, otherwise the minimum-norm correction of it) and the
//! columns of `Z` span the null space of the system. Every `x` is then an admissible trajectory,
//! and the optimiser works on `x` alone.
//!
//! Inequality constraints (`q_min ≤ q ≤ q_max`, `|q̇| ≤ q̇_max`, `|q̈| ≤ q̈_max`) are checked on a
//! dense uniform grid over the period. The trajectory `c_p + s·Z·x` is affine in the scale `s`,
//! so the largest `s ∈ [0, 1]` that keeps every grid point within its limits has a closed form:
//! a candidate that leaves the limits is shrunk toward `c_p` ("scaling into feasibility").

use super::ExciteError;
use super::trajectory::{Derivative, ExcitationTrajectory, JointFourier, basis, sample_count};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};
use std::f64::consts::TAU;

/// Limits of one moving joint.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct JointLimits {
    /// Lower position limit in rad.
    pub q_min_rad: f64,
    /// Upper position limit in rad.
    pub q_max_rad: f64,
    /// Velocity limit (symmetric) in rad/s.
    pub qd_max_rad_s: f64,
    /// Acceleration limit (symmetric) in rad/s².
    pub qdd_max_rad_s2: f64,
}

impl JointLimits {
    /// Symmetric limits `|q| ≤ q_max`, `|q̇| ≤ qd_max`, `|q̈| ≤ qdd_max`.
    pub fn symmetric(q_max_rad: f64, qd_max_rad_s: f64, qdd_max_rad_s2: f64) -> Self {
        Self {
            q_min_rad: -q_max_rad,
            q_max_rad,
            qd_max_rad_s,
            qdd_max_rad_s2,
        }
    }

    fn half_range(&self) -> f64 {
        0.5 * (self.q_max_rad - self.q_min_rad)
    }
}

/// An extra equality constraint on one joint at one instant, e.g. the paper's test trajectory
/// `q_i(3.8 s) = 0`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PointConstraint {
    /// Index of the moving joint (trajectory order, 0-based).
    pub joint: usize,
    /// Time in s within the period.
    pub t_s: f64,
    /// Which derivative is constrained.
    pub derivative: Derivative,
    /// Required value (rad, rad/s or rad/s²).
    pub value: f64,
}

/// The kind of an inequality constraint.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LimitKind {
    /// `q ≤ q_max`.
    PositionUpper,
    /// `q ≥ q_min`.
    PositionLower,
    /// `|q̇| ≤ q̇_max`.
    Velocity,
    /// `|q̈| ≤ q̈_max`.
    Acceleration,
}

impl LimitKind {
    /// All kinds, in report order.
    pub const ALL: [LimitKind; 4] = [
        LimitKind::PositionLower,
        LimitKind::PositionUpper,
        LimitKind::Velocity,
        LimitKind::Acceleration,
    ];

    /// Short human-readable name with the unit.
    pub fn describe(self) -> &'static str {
        match self {
            LimitKind::PositionUpper => "upper position limit (rad)",
            LimitKind::PositionLower => "lower position limit (rad)",
            LimitKind::Velocity => "velocity limit (rad/s)",
            LimitKind::Acceleration => "acceleration limit (rad/s^2)",
        }
    }
}

/// How close a trajectory comes to one limit of one joint over the dense grid.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ConstraintMargin {
    /// Moving-joint index (trajectory order).
    pub joint: usize,
    /// Which limit.
    pub kind: LimitKind,
    /// The limit (for lower position limits, the lower bound itself).
    pub limit: f64,
    /// The extreme value reached (max of q, min of q, max |q̇|, max |q̈|).
    pub extreme: f64,
    /// Distance to the limit in the limit's unit; negative when violated.
    pub margin: f64,
    /// Utilisation: 1 at the limit, < 1 inside; for position limits measured relative to
    /// half the position range beyond the limit (`1 + excess / half_range`).
    pub utilisation: f64,
}

/// Per-joint constrained coefficient space `c = c_p + scale·Z·x`.
#[derive(Debug, Clone)]
struct JointSpace {
    particular: DVector<f64>,
    null: DMatrix<f64>,
    /// Natural amplitude (rad) of one unit of `x` for this joint.
    amplitude_rad: f64,
}

/// Grid images of the particular solution and of the null-space basis of one joint.
#[derive(Debug, Clone)]
struct JointGrid {
    base: [DVector<f64>; 3],
    dirs: [DMatrix<f64>; 3],
}

/// A uniform grid over one period (both ends included): basis matrices and per-joint images.
#[derive(Debug, Clone)]
struct Grid {
    basis: [DMatrix<f64>; 3],
    joints: Vec<JointGrid>,
}

impl Grid {
    fn new(points: usize, period_s: f64, harmonics: usize, spaces: &[JointSpace]) -> Self {
        let width = 1 + 2 * harmonics;
        let omega = TAU / period_s;
        let dt = period_s / (points - 1) as f64;
        let mut g = [
            DMatrix::zeros(points, width),
            DMatrix::zeros(points, width),
            DMatrix::zeros(points, width),
        ];
        let mut row = vec![0.0; width];
        for i in 0..points {
            let t = i as f64 * dt;
            for (d, m) in [
                Derivative::Position,
                Derivative::Velocity,
                Derivative::Acceleration,
            ]
            .into_iter()
            .zip(g.iter_mut())
            {
                basis(d, harmonics, omega, t, &mut row);
                for (c, v) in row.iter().enumerate() {
                    m[(i, c)] = *v;
                }
            }
        }
        let joints = spaces
            .iter()
            .map(|s| JointGrid {
                base: [
                    &g[0] * &s.particular,
                    &g[1] * &s.particular,
                    &g[2] * &s.particular,
                ],
                dirs: [&g[0] * &s.null, &g[1] * &s.null, &g[2] * &s.null],
            })
            .collect();
        Self { basis: g, joints }
    }

    fn update_base(&mut self, spaces: &[JointSpace]) {
        for (jg, s) in self.joints.iter_mut().zip(spaces) {
            jg.base = [
                &self.basis[0] * &s.particular,
                &self.basis[1] * &s.particular,
                &self.basis[2] * &s.particular,
            ];
        }
    }
}

/// Points per period of the grid the optimiser checks limits on during the search (the final
/// trajectory is then scaled on the dense grid). With at most `N` harmonics this grid has
/// `SEARCH_GRID_POINTS / N` points per period of the highest harmonic: for N = 5, 100, which
/// misses a peak by at most `1 − cos(π/100) ≈ 5e-4` relative.
pub const SEARCH_GRID_POINTS: usize = 501;

/// The constrained Fourier family: every decision vector `x` maps to a trajectory that meets the
/// rest and point constraints exactly; [`FourierFamily::feasible_scale`] maps it into the limits.
#[derive(Debug, Clone)]
pub struct FourierFamily {
    period_s: f64,
    harmonics: usize,
    rest_rad: Vec<f64>,
    limits: Vec<JointLimits>,
    spaces: Vec<JointSpace>,
    offsets: Vec<usize>,
    grid: Grid,
    search_grid: Grid,
    grid_points: usize,
}

/// Values of one joint's q, q̇ and q̈ on the dense grid.
type GridValues = [DVector<f64>; 3];

impl FourierFamily {
    /// Builds the family for the given rest pose (one value per moving joint), limits and extra
    /// point constraints, with the limit-check grid at `check_rate_hz` (at least 10× the
    /// controller rate).
    pub fn new(
        period_s: f64,
        harmonics: usize,
        rest_rad: &[f64],
        limits: &[JointLimits],
        extra: &[PointConstraint],
        check_rate_hz: f64,
    ) -> Result<Self, ExciteError> {
        let n = rest_rad.len();
        if n == 0 {
            return Err(ExciteError::Invalid("no moving joints".into()));
        }
        if limits.len() != n {
            return Err(ExciteError::Invalid(format!(
                "{} joint limits given for {} moving joints",
                limits.len(),
                n
            )));
        }
        if !(period_s.is_finite() && period_s > 0.0) || harmonics == 0 {
            return Err(ExciteError::Invalid(format!(
                "period {period_s} s and {harmonics} harmonics: need a positive period and at least one harmonic"
            )));
        }
        for (j, l) in limits.iter().enumerate() {
            let ok = [l.q_min_rad, l.q_max_rad, l.qd_max_rad_s, l.qdd_max_rad_s2]
                .iter()
                .all(|v| v.is_finite())
                && l.q_max_rad > l.q_min_rad
                && l.qd_max_rad_s > 0.0
                && l.qdd_max_rad_s2 > 0.0;
            if !ok {
                return Err(ExciteError::Invalid(format!(
                    "moving joint #{j}: invalid limits {l:?}"
                )));
            }
            if !(rest_rad[j] >= l.q_min_rad && rest_rad[j] <= l.q_max_rad) {
                return Err(ExciteError::Infeasible(format!(
                    "moving joint #{j}: rest pose {} rad lies outside the position limits [{}, {}] rad",
                    rest_rad[j], l.q_min_rad, l.q_max_rad
                )));
            }
        }
        for pc in extra {
            if pc.joint >= n || !pc.t_s.is_finite() || !pc.value.is_finite() {
                return Err(ExciteError::Invalid(format!(
                    "invalid point constraint {pc:?}"
                )));
            }
        }
        let omega = TAU / period_s;
        let width = 1 + 2 * harmonics;
        let mut spaces = Vec::with_capacity(n);
        for j in 0..n {
            let mut rows: Vec<(Vec<f64>, f64, String)> = Vec::new();
            for (d, v, name) in [
                (Derivative::Position, rest_rad[j], "q(0) = rest pose"),
                (Derivative::Velocity, 0.0, "qd(0) = 0"),
                (Derivative::Acceleration, 0.0, "qdd(0) = 0"),
            ] {
                let mut r = vec![0.0; width];
                basis(d, harmonics, omega, 0.0, &mut r);
                rows.push((r, v, name.to_string()));
            }
            for pc in extra.iter().filter(|pc| pc.joint == j) {
                let mut r = vec![0.0; width];
                basis(pc.derivative, harmonics, omega, pc.t_s, &mut r);
                let name = format!("{:?}({} s) = {}", pc.derivative, pc.t_s, pc.value);
                rows.push((r, pc.value, name));
            }
            spaces.push(solve_joint_space(
                j,
                &rows,
                rest_rad[j],
                width,
                harmonics,
                omega,
                &limits[j],
            )?);
        }
        let mut offsets = Vec::with_capacity(n + 1);
        let mut acc = 0;
        for s in &spaces {
            offsets.push(acc);
            acc += s.null.ncols();
        }
        offsets.push(acc);

        // Dense grid over one period, both ends included; a coarser one for the search.
        let grid_points = sample_count(period_s, check_rate_hz);
        let grid = Grid::new(grid_points, period_s, harmonics, &spaces);
        let search_points = SEARCH_GRID_POINTS.max(40 * harmonics + 1).min(grid_points);
        let search_grid = Grid::new(search_points, period_s, harmonics, &spaces);
        Ok(Self {
            period_s,
            harmonics,
            rest_rad: rest_rad.to_vec(),
            limits: limits.to_vec(),
            spaces,
            offsets,
            grid,
            search_grid,
            grid_points,
        })
    }

    /// Number of free coefficients (the optimiser's dimension).
    pub fn dimension(&self) -> usize {
        *self.offsets.last().unwrap_or(&0)
    }

    /// Number of moving joints.
    pub fn joint_count(&self) -> usize {
        self.spaces.len()
    }

    /// Period in s.
    pub fn period_s(&self) -> f64 {
        self.period_s
    }

    /// Number of harmonics.
    pub fn harmonics(&self) -> usize {
        self.harmonics
    }

    /// Rest pose of the moving joints in rad.
    pub fn rest_rad(&self) -> &[f64] {
        &self.rest_rad
    }

    /// Limits of the moving joints.
    pub fn limits(&self) -> &[JointLimits] {
        &self.limits
    }

    /// Number of points of the limit-check grid over one period (both ends included).
    pub fn grid_points(&self) -> usize {
        self.grid_points
    }

    /// The trajectory `c_p + scale·Z·x`.
    pub fn trajectory(&self, x: &[f64], scale: f64) -> ExcitationTrajectory {
        self.trajectory_per_joint(x, &vec![scale; self.joint_count()])
    }

    /// The particular part `c_p` and direction part `Z·x` of joint `j` on the dense grid.
    fn grid_parts<'g>(&self, grid: &'g Grid, x: &[f64], j: usize) -> (&'g GridValues, GridValues) {
        let s = &self.spaces[j];
        let xj =
            DVector::from_column_slice(&x[self.offsets[j]..self.offsets[j + 1]]) * s.amplitude_rad;
        let gr = &grid.joints[j];
        let dirs = [&gr.dirs[0] * &xj, &gr.dirs[1] * &xj, &gr.dirs[2] * &xj];
        (&gr.base, dirs)
    }

    /// The largest `s ∈ [0, cap]` such that `c_p + s·Z·x` stays within every limit on the dense
    /// grid. Requires the particular solution itself to be feasible (see
    /// [`FourierFamily::particular_margins`]); returns 0 otherwise.
    pub fn feasible_scale(&self, x: &[f64], cap: f64) -> f64 {
        self.scale_on(&self.grid, x, cap)
    }

    /// [`FourierFamily::feasible_scale`] on the coarser search grid ([`SEARCH_GRID_POINTS`]); the
    /// optimiser uses it and rescales its result on the dense grid.
    pub fn search_scale(&self, x: &[f64], cap: f64) -> f64 {
        self.scale_on(&self.search_grid, x, cap)
    }

    fn scale_on(&self, grid: &Grid, x: &[f64], cap: f64) -> f64 {
        (0..self.joint_count()).fold(cap, |s, j| self.joint_scale_on(grid, x, j, s))
    }

    /// The largest scale `≤ cap` of joint `j`'s part `Z_j·x_j` alone that keeps joint `j` within
    /// its limits on `grid` (0 when its particular solution breaks a limit).
    fn joint_scale_on(&self, grid: &Grid, x: &[f64], j: usize, cap: f64) -> f64 {
        let mut s_max: f64 = cap;
        let l = &self.limits[j];
        let (base, dir) = self.grid_parts(grid, x, j);
        let bounds = [
            (l.q_min_rad, l.q_max_rad),
            (-l.qd_max_rad_s, l.qd_max_rad_s),
            (-l.qdd_max_rad_s2, l.qdd_max_rad_s2),
        ];
        for ((b, d), (lo, hi)) in base.iter().zip(dir.iter()).zip(bounds) {
            for (p, v) in b.iter().zip(d.iter()) {
                if *p > hi || *p < lo {
                    return 0.0;
                }
                if *v > 0.0 {
                    s_max = s_max.min((hi - p) / v);
                } else if *v < 0.0 {
                    s_max = s_max.min((lo - p) / v);
                }
            }
        }
        s_max.max(0.0)
    }

    /// Per-joint repair into the limits: for every joint `j` the largest `s_j ≤ cap` such that
    /// `c_p,j + s_j·Z_j·x_j` stays within joint `j`'s limits on the dense grid. The limits are
    /// per joint and each joint's coefficients only move that joint, so the joints can be
    /// scaled independently (unlike [`FourierFamily::feasible_scale`], where the tightest joint
    /// shrinks every other joint too).
    pub fn joint_scales(&self, x: &[f64], cap: f64) -> Vec<f64> {
        (0..self.joint_count())
            .map(|j| self.joint_scale_on(&self.grid, x, j, cap))
            .collect()
    }

    /// [`FourierFamily::joint_scales`] on the coarser search grid.
    pub fn search_joint_scales(&self, x: &[f64], cap: f64) -> Vec<f64> {
        (0..self.joint_count())
            .map(|j| self.joint_scale_on(&self.search_grid, x, j, cap))
            .collect()
    }

    /// Per-joint scales of `x` rescaled onto the dense grid: each `scales[j]` lowered (never
    /// raised) so that joint `j` stays within its limits on the dense grid.
    pub fn dense_joint_scales(&self, x: &[f64], scales: &[f64]) -> Vec<f64> {
        (0..self.joint_count())
            .map(|j| self.joint_scale_on(&self.grid, x, j, scales[j]))
            .collect()
    }

    /// The trajectory `c_p,j + scales[j]·Z_j·x_j` per joint.
    pub fn trajectory_per_joint(&self, x: &[f64], scales: &[f64]) -> ExcitationTrajectory {
        let joints = self
            .spaces
            .iter()
            .enumerate()
            .map(|(j, s)| {
                let xj = DVector::from_column_slice(&x[self.offsets[j]..self.offsets[j + 1]]);
                let c = &s.particular + (&s.null * xj) * (scales[j] * s.amplitude_rad);
                JointFourier::from_packed(c.as_slice())
            })
            .collect();
        ExcitationTrajectory {
            period_s: self.period_s,
            harmonics: self.harmonics,
            joints,
        }
    }

    /// Margins of the trajectory `c_p,j + scales[j]·Z_j·x_j` to every limit on the dense grid.
    pub fn margins_per_joint(&self, x: &[f64], scales: &[f64]) -> Vec<ConstraintMargin> {
        let mut out = Vec::with_capacity(4 * self.joint_count());
        for (j, &scale) in scales.iter().enumerate().take(self.joint_count()) {
            let l = self.limits[j];
            let (base, dir) = self.grid_parts(&self.grid, x, j);
            let vals: Vec<DVector<f64>> = (0..3).map(|k| &base[k] + &dir[k] * scale).collect();
            out.extend(margins_of(j, &l, &vals[0], &vals[1], &vals[2]));
        }
        out
    }

    /// Margins of the trajectory `c_p + scale·Z·x` to every limit on the dense grid.
    pub fn margins(&self, x: &[f64], scale: f64) -> Vec<ConstraintMargin> {
        self.margins_per_joint(x, &vec![scale; self.joint_count()])
    }

    /// Margins of the particular solution `c_p` alone (the rest pose when it satisfies the point
    /// constraints).
    pub fn particular_margins(&self) -> Vec<ConstraintMargin> {
        self.margins(&vec![0.0; self.dimension()], 0.0)
    }

    /// Replaces the particular solution by `c_p + scale·Z·x` (used after a feasibility search
    /// found a feasible point when `c_p` itself is not).
    pub fn recentre(&mut self, x: &[f64], scale: f64) {
        for j in 0..self.joint_count() {
            let s = &mut self.spaces[j];
            let xj = DVector::from_column_slice(&x[self.offsets[j]..self.offsets[j + 1]]);
            s.particular += (&s.null * xj) * (scale * s.amplitude_rad);
        }
        self.grid.update_base(&self.spaces);
        self.search_grid.update_base(&self.spaces);
    }
}

/// Margins of one joint's dense-grid values to its limits.
pub fn margins_of(
    joint: usize,
    l: &JointLimits,
    q: &DVector<f64>,
    qd: &DVector<f64>,
    qdd: &DVector<f64>,
) -> [ConstraintMargin; 4] {
    let qmax = q.max();
    let qmin = q.min();
    let vmax = qd.amax();
    let amax = qdd.amax();
    let h = l.half_range();
    [
        ConstraintMargin {
            joint,
            kind: LimitKind::PositionLower,
            limit: l.q_min_rad,
            extreme: qmin,
            margin: qmin - l.q_min_rad,
            utilisation: 1.0 + (l.q_min_rad - qmin) / h,
        },
        ConstraintMargin {
            joint,
            kind: LimitKind::PositionUpper,
            limit: l.q_max_rad,
            extreme: qmax,
            margin: l.q_max_rad - qmax,
            utilisation: 1.0 + (qmax - l.q_max_rad) / h,
        },
        ConstraintMargin {
            joint,
            kind: LimitKind::Velocity,
            limit: l.qd_max_rad_s,
            extreme: vmax,
            margin: l.qd_max_rad_s - vmax,
            utilisation: vmax / l.qd_max_rad_s,
        },
        ConstraintMargin {
            joint,
            kind: LimitKind::Acceleration,
            limit: l.qdd_max_rad_s2,
            extreme: amax,
            margin: l.qdd_max_rad_s2 - amax,
            utilisation: amax / l.qdd_max_rad_s2,
        },
    ]
}

/// The margin with the highest utilisation (the tightest constraint).
pub fn tightest(margins: &[ConstraintMargin]) -> Option<ConstraintMargin> {
    margins
        .iter()
        .copied()
        .max_by(|a, b| a.utilisation.total_cmp(&b.utilisation))
}

/// Solves one joint's equality system: particular solution closest to the rest pose and an
/// orthonormal null-space basis.
fn solve_joint_space(
    joint: usize,
    rows: &[(Vec<f64>, f64, String)],
    rest: f64,
    width: usize,
    harmonics: usize,
    omega: f64,
    limits: &JointLimits,
) -> Result<JointSpace, ExciteError> {
    let m = rows.len();
    if m >= width {
        return Err(ExciteError::Infeasible(format!(
            "moving joint #{joint}: {m} equality constraints leave no free coefficient out of {width}; \
             use more harmonics or fewer point constraints"
        )));
    }
    // Add the rows one at a time so an inconsistency is blamed on the first row that causes it.
    let mut c_rest = DVector::zeros(width);
    c_rest[0] = rest;
    let mut solved = None;
    for used in 1..=m {
        let (particular, null_cols, resid) = solve_rows(&rows[..used], &c_rest, width);
        if resid > 1e-9 {
            let earlier: Vec<&str> = rows[..used - 1].iter().map(|r| r.2.as_str()).collect();
            return Err(ExciteError::Infeasible(format!(
                "moving joint #{joint}: equality constraints are inconsistent: `{}` cannot hold together \
                 with {} (residual {resid:.3e})",
                rows[used - 1].2,
                earlier.join(", ")
            )));
        }
        solved = Some((particular, null_cols));
    }
    let (particular, null_cols) = solved.expect("at least the start conditions");
    if null_cols.is_empty() {
        return Err(ExciteError::Infeasible(format!(
            "moving joint #{joint}: the equality constraints fix every coefficient; nothing left to optimise"
        )));
    }
    let null = DMatrix::from_columns(&null_cols);
    let nw = harmonics as f64 * omega;
    let amplitude_rad = 0.5
        * limits
            .half_range()
            .min(limits.qd_max_rad_s / nw)
            .min(limits.qdd_max_rad_s2 / (nw * nw));
    Ok(JointSpace {
        particular,
        null,
        amplitude_rad,
    })
}

/// Minimum-norm correction of `c_rest` that satisfies `rows` (row-normalised, padded to square
/// so the SVD yields a full right basis), the null-space basis, and the largest residual.
fn solve_rows(
    rows: &[(Vec<f64>, f64, String)],
    c_rest: &DVector<f64>,
    width: usize,
) -> (DVector<f64>, Vec<DVector<f64>>, f64) {
    let mut e = DMatrix::zeros(width, width);
    let mut r = DVector::zeros(width);
    for (i, (row, v, _)) in rows.iter().enumerate() {
        let norm = row.iter().map(|x| x * x).sum::<f64>().sqrt();
        for (c, x) in row.iter().enumerate() {
            e[(i, c)] = x / norm;
        }
        r[i] = v / norm;
    }
    let svd = e.clone().svd(true, true);
    let (u, vt) = (
        svd.u.as_ref().expect("requested"),
        svd.v_t.as_ref().expect("requested"),
    );
    let tol = 1e-10 * svd.singular_values.max().max(1.0);
    // c_p = c_rest + E⁺ (r − E c_rest)
    let rhs = &r - &e * c_rest;
    let mut particular = c_rest.clone();
    let mut null_cols = Vec::new();
    for (k, &sv) in svd.singular_values.iter().enumerate() {
        if sv > tol {
            particular += vt.row(k).transpose() * (u.column(k).dot(&rhs) / sv);
        } else {
            null_cols.push(vt.row(k).transpose());
        }
    }
    let resid = (&e * &particular - &r).amax();
    (particular, null_cols, resid)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn family(extra: &[PointConstraint]) -> FourierFamily {
        let limits = vec![JointLimits::symmetric(2.0, 1.5, 4.0); 2];
        FourierFamily::new(10.0, 5, &[0.3, -0.2], &limits, extra, 1000.0).unwrap()
    }

    #[test]
    fn every_decision_vector_meets_rest_conditions_exactly() {
        let zero_at = [PointConstraint {
            joint: 1,
            t_s: 3.8,
            derivative: Derivative::Position,
            value: 0.0,
        }];
        let fam = family(&zero_at);
        assert_eq!(fam.dimension(), 8 + 7);
        let x: Vec<f64> = (0..fam.dimension())
            .map(|i| ((i * 7919) % 13) as f64 / 6.0 - 1.0)
            .collect();
        let tr = fam.trajectory(&x, 0.7);
        for t in [0.0, 10.0] {
            let p = tr.eval(t);
            assert!((p.q_rad[0] - 0.3).abs() < 1e-9 && (p.q_rad[1] + 0.2).abs() < 1e-9);
            for j in 0..2 {
                assert!(p.qd_rad_s[j].abs() < 1e-9 && p.qdd_rad_s2[j].abs() < 1e-9);
            }
        }
        assert!(tr.eval(3.8).q_rad[1].abs() < 1e-9);
    }

    #[test]
    fn feasible_scale_lands_on_the_tightest_limit() {
        let fam = family(&[]);
        let x = vec![3.0; fam.dimension()];
        let s = fam.feasible_scale(&x, 1.0);
        assert!(s > 0.0 && s < 1.0, "scale {s}");
        let m = fam.margins(&x, s);
        let t = tightest(&m).unwrap();
        assert!((t.utilisation - 1.0).abs() < 1e-9, "{t:?}");
        assert!(m.iter().all(|m| m.margin >= -1e-12));
    }

    #[test]
    fn inconsistent_constraints_are_named() {
        let limits = vec![JointLimits::symmetric(2.0, 1.5, 4.0)];
        let bad = [PointConstraint {
            joint: 0,
            t_s: 10.0,
            derivative: Derivative::Position,
            value: 1.0,
        }];
        let err = FourierFamily::new(10.0, 5, &[0.0], &limits, &bad, 1000.0).unwrap_err();
        assert!(err.to_string().contains("Position(10 s) = 1"), "{err}");
        let out = FourierFamily::new(10.0, 5, &[3.0], &limits, &[], 1000.0).unwrap_err();
        assert!(
            out.to_string().contains("outside the position limits"),
            "{out}"
        );
    }
}
