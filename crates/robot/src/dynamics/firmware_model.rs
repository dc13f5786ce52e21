//! Builds the firmware's f32 [`RigidBodyModel<N>`] from a robot and a standard
//! parameter vector (nominal, or the equivalent standard parameters of identified base
//! parameters: [`crate::base::BaseParameters::equivalent_standard`]).
//!
//! Locked joints are folded in: their transforms (at the locked position) go into the
//! next modelled joint's fixed transform, their links' parameters are moved into the
//! frame of the modelled body they ride on and summed. Links before the first modelled
//! joint do not affect the modelled torques and are dropped.
use crate::{
    JointMode, JointParameter, PARAMETERS_PER_LINK, Robot, axis_rotation,
    transform_standard_parameters,
};
use firmware::dynamics::{JointModel, RigidBodyModel};
use nalgebra::{DVector, Matrix3, Vector3};

/// Why a firmware model could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FirmwareModelError {
    /// An identified range whose minimum is above its maximum.
    #[error("joint `{joint}`: identified range [{min}, {max}] is empty")]
    Range {
        /// Joint name.
        joint: String,
        /// Its minimum.
        min: f64,
        /// Its maximum.
        max: f64,
    },
    /// `N` differs from the robot's number of modelled joints.
    #[error("the firmware model has {expected} joints but the robot models {actual}")]
    JointCount {
        /// `N`.
        expected: usize,
        /// Modelled joints of the robot.
        actual: usize,
    },
    /// `theta` has the wrong length.
    #[error("theta has {actual} entries, the robot's layout needs {expected}")]
    ParameterCount {
        /// Layout length.
        expected: usize,
        /// Given length.
        actual: usize,
    },
    /// A value is not finite or does not fit in f32.
    #[error("parameter `{name}` = {value} is not a finite f32")]
    NotFinite {
        /// Parameter name.
        name: String,
        /// Its value.
        value: f64,
    },
}

fn f32_checked(name: &str, v: f64) -> Result<f32, FirmwareModelError> {
    let x = v as f32;
    if x.is_finite() {
        Ok(x)
    } else {
        Err(FirmwareModelError::NotFinite {
            name: name.to_string(),
            value: v,
        })
    }
}

/// The f32 model of the robot's modelled joints with parameters `theta`.
pub fn build_firmware_model<const N: usize>(
    robot: &Robot,
    theta: &DVector<f64>,
) -> Result<RigidBodyModel<N>, FirmwareModelError> {
    let modelled = robot.modelled_joints();
    if modelled.len() != N {
        return Err(FirmwareModelError::JointCount {
            expected: N,
            actual: modelled.len(),
        });
    }
    let layout = robot.parameter_layout();
    if theta.len() != layout.len() {
        return Err(FirmwareModelError::ParameterCount {
            expected: layout.len(),
            actual: theta.len(),
        });
    }
    let names = robot.parameter_names();
    let mut joints = [JointModel::ZERO; N];
    // Fixed transform accumulated since the last modelled body (base at first).
    let mut acc_r = Matrix3::identity();
    let mut acc_p = Vector3::zeros();
    let mut current: Option<usize> = None; // reduced index of the body links ride on
    // Transform from the current modelled body's frame to the frame of link k.
    let mut body_to_link_r = Matrix3::identity();
    let mut body_to_link_p = Vector3::zeros();
    let mut inertial = vec![[0.0f64; 10]; N];
    for (k, j) in robot.joints.iter().enumerate() {
        let mut lp = [0.0; 10];
        lp.copy_from_slice(
            &theta.as_slice()[PARAMETERS_PER_LINK * k..PARAMETERS_PER_LINK * (k + 1)],
        );
        let body = j.link_to_body(&lp);
        match j.mode {
            JointMode::Modelled => {
                let r_idx = current.map_or(0, |c| c + 1);
                let xr = acc_r * j.origin_rotation;
                let xp = acc_p + acc_r * j.origin_translation;
                let jm = &mut joints[r_idx];
                for a in 0..3 {
                    for b in 0..3 {
                        jm.origin_rotation[a][b] = f32_checked(&j.name, xr[(a, b)])?;
                    }
                    jm.origin_translation_m[a] = f32_checked(&j.name, xp[a])?;
                    jm.axis[a] = f32_checked(&j.name, j.axis[a])?;
                }
                acc_r = Matrix3::identity();
                acc_p = Vector3::zeros();
                body_to_link_r = Matrix3::identity();
                body_to_link_p = Vector3::zeros();
                current = Some(r_idx);
                for (t, b) in inertial[r_idx].iter_mut().zip(body.iter()) {
                    *t += b;
                }
            }
            JointMode::Locked { q_rad } => {
                let rot = j.origin_rotation * axis_rotation(&j.axis, q_rad);
                acc_p += acc_r * j.origin_translation;
                acc_r *= rot;
                body_to_link_p += body_to_link_r * j.origin_translation;
                body_to_link_r *= rot;
                if let Some(c) = current {
                    let moved =
                        transform_standard_parameters(&body, &body_to_link_r, &body_to_link_p);
                    for (t, b) in inertial[c].iter_mut().zip(moved.iter()) {
                        *t += b;
                    }
                }
            }
        }
    }
    for (r, &ji) in modelled.iter().enumerate() {
        for (a, v) in inertial[r].iter().enumerate() {
            joints[r].inertial[a] = f32_checked(&names[PARAMETERS_PER_LINK * ji + a], *v)?;
        }
        let term = |kind: JointParameter| -> Result<f32, FirmwareModelError> {
            match layout.joint_index(r, kind) {
                Some(i) => f32_checked(&names[i], theta[i]),
                None => Ok(0.0),
            }
        };
        joints[r].viscous_nm_s_rad = term(JointParameter::Viscous)?;
        joints[r].coulomb_nm = term(JointParameter::Coulomb)?;
        joints[r].offset_nm = term(JointParameter::Offset)?;
        joints[r].rotor_inertia_kg_m2 = term(JointParameter::RotorInertia)?;
        for (k, f) in joints[r].stribeck_nm.iter_mut().enumerate() {
            *f = term(JointParameter::Stribeck(k))?;
        }
        joints[r].quadratic_nm_s2_rad2 = term(JointParameter::Quadratic)?;
        if let Some(g) = robot.identified_ranges.get(r) {
            let name = &robot.joints[ji].name;
            let range = |v: [f64; 2]| -> Result<[f32; 2], FirmwareModelError> {
                let out = [f32_checked(name, v[0])?, f32_checked(name, v[1])?];
                if out[0] <= out[1] {
                    Ok(out)
                } else {
                    Err(FirmwareModelError::Range {
                        joint: name.clone(),
                        min: v[0],
                        max: v[1],
                    })
                }
            };
            joints[r].q_range_rad = range(g.q_rad)?;
            joints[r].qd_range_rad_s = range(g.qd_rad_s)?;
            joints[r].qdd_range_rad_s2 = range(g.qdd_rad_s2)?;
        }
    }
    let g = robot.gravity;
    Ok(RigidBodyModel {
        joints,
        gravity_m_s2: [
            f32_checked("gravity", g.x)?,
            f32_checked("gravity", g.y)?,
            f32_checked("gravity", g.z)?,
        ],
        coulomb_inv_eps_s_rad: match robot.terms.coulomb_smoothing_rad_s {
            Some(eps) if eps > 0.0 => f32_checked("coulomb_smoothing", 1.0 / eps)?,
            _ => 0.0,
        },
    })
}

/// The firmware's f32 model for any supported joint count (1..=7).
#[derive(Clone, Debug)]
pub enum FirmwareModel {
    /// 1 joint.
    J1(RigidBodyModel<1>),
    /// 2 joints.
    J2(RigidBodyModel<2>),
    /// 3 joints.
    J3(RigidBodyModel<3>),
    /// 4 joints.
    J4(RigidBodyModel<4>),
    /// 5 joints.
    J5(RigidBodyModel<5>),
    /// 6 joints.
    J6(RigidBodyModel<6>),
    /// 7 joints.
    J7(RigidBodyModel<7>),
}

fn arr<const N: usize>(v: &[f64]) -> [f32; N] {
    core::array::from_fn(|i| v[i] as f32)
}

impl FirmwareModel {
    /// Builds the f32 model of `robot` with standard parameters `theta`.
    pub fn build(robot: &Robot, theta: &DVector<f64>) -> anyhow::Result<Self> {
        Ok(match robot.n_modelled() {
            1 => Self::J1(build_firmware_model(robot, theta)?),
            2 => Self::J2(build_firmware_model(robot, theta)?),
            3 => Self::J3(build_firmware_model(robot, theta)?),
            4 => Self::J4(build_firmware_model(robot, theta)?),
            5 => Self::J5(build_firmware_model(robot, theta)?),
            6 => Self::J6(build_firmware_model(robot, theta)?),
            7 => Self::J7(build_firmware_model(robot, theta)?),
            n => anyhow::bail!(
                "{}: {n} modelled joints; the firmware model supports 1 to 7",
                robot.source.display()
            ),
        })
    }

    /// Torques [N·m] via `firmware::dynamics::RigidBodyModel::torques` (f32).
    pub fn torques(&self, q: &[f64], qd: &[f64], qdd: &[f64]) -> Vec<f64> {
        fn go<const N: usize>(
            m: &RigidBodyModel<N>,
            q: &[f64],
            qd: &[f64],
            qdd: &[f64],
        ) -> Vec<f64> {
            m.torques(&arr(q), &arr(qd), &arr(qdd))
                .iter()
                .map(|&t| t as f64)
                .collect()
        }
        match self {
            Self::J1(m) => go(m, q, qd, qdd),
            Self::J2(m) => go(m, q, qd, qdd),
            Self::J3(m) => go(m, q, qd, qdd),
            Self::J4(m) => go(m, q, qd, qdd),
            Self::J5(m) => go(m, q, qd, qdd),
            Self::J6(m) => go(m, q, qd, qdd),
            Self::J7(m) => go(m, q, qd, qdd),
        }
    }
}
