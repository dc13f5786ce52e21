//! The robot's base regressor as an [`ObservationModel`], and the robot's limits and joint
//! layout for the excitation design.

use super::ExciteError;
use super::constraints::JointLimits;
use super::objective::ObservationModel;
use super::output::PlaybackLayout;
use robot::base::BaseParameters;
use robot::dynamics::regressor;
use robot::{JointMode, Robot};

/// Seed of the random states the base parameters are computed from (documented in `base`).
pub const BASE_PARAMETER_SEED: u64 = 7;

/// The base-parameter observation model of a robot: rows `Y_base(q, q̇, q̈)` of the modelled
/// joints (locked joints held at their positions), friction columns included as the robot's
/// `[terms]` select them.
#[derive(Debug, Clone)]
pub struct RobotObservation {
    robot: Robot,
    base: BaseParameters,
}

impl RobotObservation {
    /// Computes the base parameters of `robot` (its current modelled/locked selection).
    pub fn new(robot: Robot) -> Result<Self, ExciteError> {
        if robot.n_modelled() == 0 {
            return Err(ExciteError::Invalid(format!(
                "{}: no modelled (moving) joint",
                robot.source.display()
            )));
        }
        let base = BaseParameters::compute(&robot, BASE_PARAMETER_SEED).map_err(|e| {
            ExciteError::Invalid(format!("{}: base parameters: {e}", robot.source.display()))
        })?;
        Ok(Self { robot, base })
    }

    /// The robot.
    pub fn robot(&self) -> &Robot {
        &self.robot
    }

    /// Its base parameters.
    pub fn base(&self) -> &BaseParameters {
        &self.base
    }
}

impl ObservationModel for RobotObservation {
    fn joint_count(&self) -> usize {
        self.robot.n_modelled()
    }
    fn rows_per_sample(&self) -> usize {
        self.robot.n_modelled()
    }
    fn parameter_count(&self) -> usize {
        self.base.count()
    }
    fn rows(&self, q: &[f64], qd: &[f64], qdd: &[f64], out: &mut [f64]) {
        let y = regressor(&self.robot, q, qd, qdd);
        let p = self.base.count();
        for r in 0..y.nrows() {
            for (c, &col) in self.base.independent.iter().enumerate() {
                out[r * p + c] = y[(r, col)];
            }
        }
    }
}

/// Optional overrides of the robot file's limits (applied to every moving joint).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LimitOverrides {
    /// Symmetric position limit |q| ≤ this (rad), intersected with the file's limits.
    pub q_max_rad: Option<f64>,
    /// Velocity limit (rad/s), replaces the file's.
    pub qd_max_rad_s: Option<f64>,
    /// Acceleration limit (rad/s²), replaces the file's.
    pub qdd_max_rad_s2: Option<f64>,
}

impl LimitOverrides {
    /// A slow identification run: 1 rad/s and 3 rad/s² on every joint (where random
    /// trajectories excite inertia poorly against gravity and friction, so the design gains
    /// most; README "Proof and figures").
    pub const IDENTIFICATION: LimitOverrides = LimitOverrides {
        q_max_rad: None,
        qd_max_rad_s: Some(1.0),
        qdd_max_rad_s2: Some(3.0),
    };
}

/// Limits of the robot's modelled joints; an error names the joint and the missing field.
pub fn joint_limits(robot: &Robot, o: &LimitOverrides) -> Result<Vec<JointLimits>, ExciteError> {
    robot
        .modelled_joints()
        .into_iter()
        .map(|i| {
            let j = &robot.joints[i];
            let l = j.limits;
            let missing = |field: &str, flag: &str| {
                ExciteError::Invalid(format!(
                    "{}: joint {} (`{}`): no `{field}` limit; give it in the robot file or pass {flag}",
                    robot.source.display(),
                    i + 1,
                    j.name
                ))
            };
            let (mut lo, mut hi) = match (l.q_min_rad, l.q_max_rad, o.q_max_rad) {
                (Some(a), Some(b), _) => (a, b),
                (_, _, Some(m)) => (-m, m),
                _ => return Err(missing("q_min/q_max", "--q-max")),
            };
            if let Some(m) = o.q_max_rad {
                lo = lo.max(-m);
                hi = hi.min(m);
            }
            let qd = o
                .qd_max_rad_s
                .or(l.qd_max_rad_s)
                .ok_or_else(|| missing("qd_max", "--qd-max"))?;
            let qdd = o
                .qdd_max_rad_s2
                .or(l.qdd_max_rad_s2)
                .ok_or_else(|| missing("qdd_max", "--qdd-max"))?;
            Ok(JointLimits {
                q_min_rad: lo,
                q_max_rad: hi,
                qd_max_rad_s: qd,
                qdd_max_rad_s2: qdd,
            })
        })
        .collect()
}

/// Playback layout of the robot: every joint, modelled ones moving, locked ones at their lock
/// position; `rest_rad` gives the modelled joints' rest pose.
pub fn playback_layout(robot: &Robot, rest_rad: &[f64]) -> PlaybackLayout {
    let mut it = rest_rad.iter();
    PlaybackLayout {
        joint_names: robot.joints.iter().map(|j| j.name.clone()).collect(),
        moving: robot.modelled_joints(),
        fixed_rad: robot
            .joints
            .iter()
            .map(|j| match j.mode {
                JointMode::Modelled => *it.next().unwrap_or(&0.0),
                JointMode::Locked { q_rad } => q_rad,
            })
            .collect(),
    }
}
