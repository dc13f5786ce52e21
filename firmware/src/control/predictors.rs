//! Simple predictors that plug into the [`TorquePredictor`] trait: a decoupled
//! per-joint model (inertia, viscous and Coulomb friction, gravity on a lever).
//! The identified multi-joint dynamics model (`crate::dynamics`) and the LSTM
//! (`crate::lstm`) implement the same trait.

use super::compensator::{PredictorInput, TorquePredictor};
use crate::math;

/// tau_j = I_j qdd_j + D_j qd_j + mu_j tanh(qd_j / v_j) + g_j sin(q_j + phi_j) on each
/// joint's reference, ignoring the coupling between joints.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DecoupledJointModel<const J: usize> {
    /// Joint-side inertia (load + rotor * ratio^2), kg*m^2.
    pub inertia_kg_m2: [f32; J],
    /// Viscous friction, N*m*s/rad.
    pub viscous_nm_s_rad: [f32; J],
    /// Coulomb friction, N*m.
    pub coulomb_nm: [f32; J],
    /// Velocity over which the Coulomb term changes sign, rad/s (> 0).
    pub coulomb_smoothing_rad_s: [f32; J],
    /// Gravity torque amplitude, N*m.
    pub gravity_nm: [f32; J],
    /// Gravity phase, rad.
    pub gravity_phase_rad: [f32; J],
}

impl<const J: usize> TorquePredictor<J> for DecoupledJointModel<J> {
    fn predict_nm(&mut self, input: &PredictorInput<J>) -> [f32; J] {
        let mut out = [0.0f32; J];
        for (j, (o, s)) in out.iter_mut().zip(input.joints.iter()).enumerate() {
            let smooth = self.coulomb_smoothing_rad_s[j].max(1e-6);
            *o = self.inertia_kg_m2[j] * s.qdd_ref_rad_s2
                + self.viscous_nm_s_rad[j] * s.qd_ref_rad_s
                + self.coulomb_nm[j] * math::tanh(s.qd_ref_rad_s / smooth)
                + self.gravity_nm[j] * math::sin(s.q_ref_rad + self.gravity_phase_rad[j]);
        }
        out
    }
    fn reset(&mut self) {}
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::JointState;

    #[test]
    fn decoupled_model_terms() {
        let mut m = DecoupledJointModel::<2> {
            inertia_kg_m2: [2.0, 0.0],
            viscous_nm_s_rad: [3.0, 0.0],
            coulomb_nm: [5.0, 1.0],
            coulomb_smoothing_rad_s: [1e-3, 0.0],
            gravity_nm: [10.0, 0.0],
            gravity_phase_rad: [0.0, 0.0],
        };
        let s = JointState {
            q_ref_rad: core::f32::consts::FRAC_PI_2,
            qd_ref_rad_s: 1.0,
            qdd_ref_rad_s2: 4.0,
            ..Default::default()
        };
        let out = m.predict_nm(&PredictorInput {
            joints: [s, JointState::default()],
            own_joint: 0,
            model_nm: [0.0; 2],
        });
        assert!((out[0] - (8.0 + 3.0 + 5.0 + 10.0)).abs() < 1e-4, "{out:?}");
        assert_eq!(out[1], 0.0);
    }
}
