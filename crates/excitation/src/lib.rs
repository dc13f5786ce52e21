//! Excitation trajectory design: optimised finite Fourier series under joint limits.
//!
//! - [`trajectory`]: the family `q_i(t) = q_i0 + Σ_k a_ik sin(kω_f t) + b_ik cos(kω_f t)`.
//! - [`constraints`]: rest and point equality constraints by construction (null-space
//!   parameterisation), limits on a dense grid, scaling into feasibility, margins.
//! - [`objective`]: condition number (the paper) or log-determinant of the observation matrix.
//! - [`optimise`]: seeded multi-start CMA-ES.
//! - [`output`]: coefficient JSON, playback CSV, SVG plots.
#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod constraints;
pub mod objective;
pub mod optimise;
pub mod output;
pub mod robot_model;
pub mod trajectory;

pub use constraints::{ConstraintMargin, FourierFamily, JointLimits, LimitKind, PointConstraint};
pub use objective::{Criterion, ExcitationScore, ObservationModel};
pub use optimise::{
    BaselineScaling, ExcitationDesign, ExcitationSettings, PopulationStats, RandomBaseline, Repair,
    design, random_baseline, random_feasible,
};
pub use trajectory::{Derivative, ExcitationTrajectory, JointFourier};

/// Errors of the excitation design.
#[derive(Debug, thiserror::Error)]
pub enum ExciteError {
    /// The problem is well formed but has no admissible solution.
    #[error("infeasible: {0}")]
    Infeasible(String),
    /// Bad input (settings, limits, constraints, files).
    #[error("invalid input: {0}")]
    Invalid(String),
    /// Reading or writing a file failed.
    #[error("i/o: {0}")]
    Io(String),
}

/// Small linear-in-parameters models for tests and examples that do not need a robot.
pub mod toy {
    use super::ObservationModel;

    /// Independent pendulum-like joints: `τ_i = I_i q̈_i + m_i g l_i sin q_i + Fv_i q̇_i +
    /// Fc_i tanh(q̇_i / 0.01) + coupling_i q̈_{i+1}` (coupling to the next joint), linear in
    /// 5 parameters per joint (the last joint has 4). Good enough to exercise the optimiser.
    #[derive(Debug, Clone)]
    pub struct PendulumChain {
        /// Number of joints.
        pub joints: usize,
    }

    impl ObservationModel for PendulumChain {
        fn joint_count(&self) -> usize {
            self.joints
        }
        fn rows_per_sample(&self) -> usize {
            self.joints
        }
        fn parameter_count(&self) -> usize {
            5 * self.joints - 1
        }
        fn rows(&self, q: &[f64], qd: &[f64], qdd: &[f64], out: &mut [f64]) {
            let p = self.parameter_count();
            out.fill(0.0);
            for i in 0..self.joints {
                let r = &mut out[i * p..(i + 1) * p];
                let c = 5 * i;
                r[c] = qdd[i];
                r[c + 1] = 9.81 * q[i].sin();
                r[c + 2] = qd[i];
                r[c + 3] = (qd[i] / 0.01).tanh();
                if i + 1 < self.joints {
                    r[c + 4] = qdd[i + 1] * (q[i] - q[i + 1]).cos();
                }
            }
        }
    }
}
