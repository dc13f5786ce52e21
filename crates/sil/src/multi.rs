//! Several joints on one mechanism: one simulated board and motor per joint
//! ([`super::joint`]) and coupled joint-side mechanics ([`CoupledJoints`]); the
//! firmware instances exchange their states as `JointStateMessage` wire frames with
//! one compensator tick of bus latency.

use super::joint::{
    JointRun, Mechanism, SimulatedHardware, SimulatedJoint, config_block_of_index, run_joints,
};
use super::{FeedforwardMode, Trajectory};
use crate::plant::JointPlantConfig;
use firmware::control::{
    FaultFlags, JointConfigBlock, JointProfile, NoPredictor, PredictorInput, TorquePredictor,
};
use nalgebra::{DMatrix, DVector};

/// A test mechanism: constant inertia matrix with coupling, per-joint viscous and
/// Coulomb friction and gravity (tau_g = g_j sin q_j); the motors' rotors are added
/// on the diagonal.
#[derive(Clone, Debug, PartialEq)]
pub struct CoupledJoints<const J: usize> {
    /// Inertia matrix (symmetric, positive definite), kg*m^2.
    pub inertia_kg_m2: [[f64; J]; J],
    /// Viscous friction, N*m*s/rad.
    pub viscous_nm_s_rad: [f64; J],
    /// Coulomb friction, N*m.
    pub coulomb_nm: [f64; J],
    /// tanh smoothing of the Coulomb term, rad/s.
    pub coulomb_smoothing_rad_s: f64,
    /// Gravity amplitude, N*m.
    pub gravity_nm: [f64; J],
}

impl<const J: usize> CoupledJoints<J> {
    fn bias(&self, q: &[f64; J], qd: &[f64; J]) -> [f64; J] {
        let mut h = [0.0; J];
        for j in 0..J {
            h[j] = self.viscous_nm_s_rad[j] * qd[j]
                + self.coulomb_nm[j] * (qd[j] / self.coulomb_smoothing_rad_s).tanh()
                + self.gravity_nm[j] * q[j].sin();
        }
        h
    }
}

impl<const J: usize> Mechanism<J> for CoupledJoints<J> {
    fn accelerations(
        &mut self,
        t_s: f64,
        q: &[f64; J],
        qd: &[f64; J],
        tau: &[f64; J],
        reflected: &[f64; J],
        _dt_s: f64,
    ) -> anyhow::Result<[f64; J]> {
        let h = self.bias(q, qd);
        let mm = DMatrix::<f64>::from_fn(J, J, |r, c| {
            self.inertia_kg_m2[r][c] + if r == c { reflected[r] } else { 0.0 }
        });
        let rhs = DVector::<f64>::from_fn(J, |r, _| tau[r] - h[r]);
        let qdd = mm
            .lu()
            .solve(&rhs)
            .ok_or_else(|| anyhow::anyhow!("singular mass matrix at t = {t_s}"))?;
        Ok(std::array::from_fn(|j| qdd[j]))
    }
}

/// The exact inverse dynamics of a [`CoupledJoints`] mechanism (plus rotors) on every
/// joint's reference, as a firmware `TorquePredictor`: it needs the other joints'
/// states from the bus.
#[derive(Clone, Debug)]
pub struct CoupledInverseDynamics<const J: usize> {
    /// The mechanism.
    pub mechanics: CoupledJoints<J>,
    /// Rotor inertia reflected to the joint, per joint, kg*m^2.
    pub rotor_reflected_kg_m2: [f64; J],
    /// Output scale (1 = exact).
    pub scale: f64,
    /// Ignore the other joints (zero their acceleration): what a drive could do alone.
    pub decoupled: bool,
}

impl<const J: usize> TorquePredictor<J> for CoupledInverseDynamics<J> {
    fn predict_nm(&mut self, input: &PredictorInput<J>) -> [f32; J] {
        let q = input.joints.map(|s| s.q_ref_rad as f64);
        let qd = input.joints.map(|s| s.qd_ref_rad_s as f64);
        let mut qdd = input.joints.map(|s| s.qdd_ref_rad_s2 as f64);
        if self.decoupled {
            for (j, a) in qdd.iter_mut().enumerate() {
                if j != input.own_joint {
                    *a = 0.0;
                }
            }
        }
        let h = self.mechanics.bias(&q, &qd);
        let mut out = [0.0f32; J];
        for i in 0..J {
            let mut t = h[i] + self.rotor_reflected_kg_m2[i] * qdd[i];
            for (j, a) in qdd.iter().enumerate() {
                t += self.mechanics.inertia_kg_m2[i][j] * a;
            }
            out[i] = (self.scale * t) as f32;
        }
        out
    }
    fn reset(&mut self) {}
}

/// Which feedforward each joint gets in a multi-joint run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MultiFeedforward {
    /// As in the single-joint run (`None`, or the coupled inverse dynamics scaled).
    Mode(FeedforwardMode),
    /// Exact inverse dynamics, but each drive ignores the other joints' accelerations.
    Decoupled,
}

/// Everything a multi-joint run needs: the image's joints and profiles, each board's
/// configuration block, the simulated hardware, the mechanism and the references.
#[derive(Clone, Debug)]
pub struct MultiJointSetup<const J: usize> {
    /// The compensated joints of the image (0-based robot joints, `JOINT_INDICES`).
    pub joint_indices: [usize; J],
    /// Their drive profiles (`JOINT_PROFILES`); simulated joint `k` is robot joint
    /// `joint_indices[k]`, its motor and gear those of `profiles[k]`.
    pub profiles: [JointProfile; J],
    /// Each simulated board's configuration block (encoded).
    pub config_blocks: [[u8; JointConfigBlock::LEN]; J],
    /// Per joint: what only the simulation has (the seeds should differ).
    pub hardware: [SimulatedHardware; J],
    /// The mechanism.
    pub mechanics: CoupledJoints<J>,
    /// Compensator rate, Hz.
    pub compensator_hz: u32,
    /// Per-joint reference trajectory.
    pub trajectories: [Trajectory; J],
    /// Simulated time, s.
    pub duration_s: f64,
}

impl<const J: usize> MultiJointSetup<J> {
    /// Simulated joint `k`'s motor, gear and sensors.
    pub fn plant(&self, k: usize) -> JointPlantConfig {
        JointPlantConfig::from_profile(&self.profiles[k], &self.hardware[k])
    }
}

impl MultiJointSetup<3> {
    /// The compiled-in model's three compensated joints (the wrist: the board's wrist
    /// motor and gear per joint), each board configured as its joint, with inertial
    /// coupling between them; the hardware as `SingleJointSetup::wrist_joint`'s.
    pub fn wrist(compensator_hz: u32, seed: u64) -> anyhow::Result<Self> {
        use firmware::model::default as compiled;
        let joint_indices: [usize; 3] = compiled::JOINT_INDICES[..].try_into().map_err(|_| {
            anyhow::anyhow!(
                "the compiled-in model compensates {} joints; the coupled wrist needs 3",
                compiled::JOINT_INDICES.len()
            )
        })?;
        let profiles: [JointProfile; 3] = std::array::from_fn(|k| compiled::JOINT_PROFILES[k]);
        let base = super::SingleJointSetup::wrist_joint(compensator_hz, seed);
        let hardware = std::array::from_fn(|k| SimulatedHardware {
            seed: seed.wrapping_mul(31).wrapping_add(k as u64),
            ..base.hardware
        });
        let mechanics = CoupledJoints {
            inertia_kg_m2: [[0.5, 0.3, 0.15], [0.3, 0.4, 0.2], [0.15, 0.2, 0.3]],
            viscous_nm_s_rad: [3.0, 2.5, 2.0],
            coulomb_nm: [5.0, 4.0, 3.0],
            coulomb_smoothing_rad_s: 0.02,
            gravity_nm: [20.0, 12.0, 5.0],
        };
        let trajectories = [
            Trajectory {
                offset_rad: 0.2,
                fundamental_hz: 0.4,
                amplitudes_rad: vec![0.5, 0.15, 0.05],
            },
            Trajectory {
                offset_rad: -0.3,
                fundamental_hz: 0.3,
                amplitudes_rad: vec![0.6, -0.2, 0.1],
            },
            Trajectory {
                offset_rad: 0.5,
                fundamental_hz: 0.5,
                amplitudes_rad: vec![-0.4, 0.1, 0.08],
            },
        ];
        Ok(Self {
            joint_indices,
            profiles,
            config_blocks: joint_indices.map(config_block_of_index),
            hardware,
            mechanics,
            compensator_hz,
            trajectories,
            duration_s: base.duration_s,
        })
    }
}

/// Per-joint results of a multi-joint run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointReport {
    /// RMS position-tracking error, rad.
    pub rms_error_rad: f64,
    /// RMS true q current, A.
    pub rms_iq_a: f64,
    /// Faults raised by this joint's drive, and by its compensator after its first
    /// tick (which has not heard from the other joints yet).
    pub faults: FaultFlags,
    /// Compensator ticks whose feedforward target was zero (no usable prediction).
    pub zero_feedforward_ticks: u64,
}

/// Run the coupled joints: one simulated board per joint (start-up from its block,
/// firmware `JointDrive` + `Compensator<J>`), states exchanged as wire frames each
/// compensator tick and delivered at the next one, through [`run_joints`].
pub fn run_multi_joint<const J: usize>(
    setup: &MultiJointSetup<J>,
    mode: MultiFeedforward,
) -> anyhow::Result<[JointReport; J]> {
    let plants: [JointPlantConfig; J] = std::array::from_fn(|k| setup.plant(k));
    let reflected: [f64; J] = plants.map(|p| p.reflected_rotor_inertia_kg_m2());
    let (scale, decoupled) = match mode {
        MultiFeedforward::Mode(FeedforwardMode::None) => (0.0, false),
        MultiFeedforward::Mode(FeedforwardMode::InverseDynamics(s)) => (s, false),
        MultiFeedforward::Decoupled => (1.0, true),
    };
    let mut joints = Vec::with_capacity(J);
    for (k, plant) in plants.iter().enumerate() {
        let joint = SimulatedJoint::<J, _, NoPredictor>::start(
            &setup.config_blocks[k],
            &setup.joint_indices,
            &setup.profiles,
            setup.compensator_hz,
            *plant,
            setup.trajectories[k].offset_rad,
            |_| {
                Ok((
                    CoupledInverseDynamics {
                        mechanics: setup.mechanics.clone(),
                        rotor_reflected_kg_m2: reflected,
                        scale,
                        decoupled,
                    },
                    NoPredictor,
                ))
            },
        )?;
        joints.push(match mode {
            MultiFeedforward::Mode(FeedforwardMode::None) => joint.without_adaptation(),
            _ => joint,
        });
    }
    let runs: Vec<JointRun> = run_joints(
        &mut joints,
        &mut setup.mechanics.clone(),
        |t| std::array::from_fn(|k| setup.trajectories[k].at(t)),
        setup.compensator_hz,
        setup.duration_s,
    )?;
    Ok(std::array::from_fn(|k| JointReport {
        rms_error_rad: runs[k].rms_error_rad,
        rms_iq_a: runs[k].rms_iq_a,
        faults: runs[k].faults,
        zero_feedforward_ticks: runs[k].source_ticks[0],
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrist_exchanges_states_and_coupled_feedforward_wins_on_every_joint() {
        let mut setup = MultiJointSetup::wrist(1000, 3).unwrap();
        setup.duration_s = 3.0;
        let none = run_multi_joint(&setup, MultiFeedforward::Mode(FeedforwardMode::None)).unwrap();
        let alone = run_multi_joint(&setup, MultiFeedforward::Decoupled).unwrap();
        let coupled = run_multi_joint(
            &setup,
            MultiFeedforward::Mode(FeedforwardMode::InverseDynamics(1.0)),
        )
        .unwrap();
        for j in 0..3 {
            println!(
                "joint {j}: none {:?}\n   alone {:?}\n   coupled {:?}",
                none[j], alone[j], coupled[j]
            );
            assert!(coupled[j].rms_error_rad < none[j].rms_error_rad / 2.0);
            // The bus delivered every joint's state: no watchdog or rejection.
            let bus = FaultFlags::STATE_STALE
                | FaultFlags::STATE_REJECTED
                | FaultFlags::STATE_OUT_OF_ORDER;
            assert!(
                !coupled[j].faults.intersects(bus),
                "{:?}",
                coupled[j].faults
            );
            assert_eq!(
                coupled[j].zero_feedforward_ticks, 1,
                "only the first tick lacks the others' states"
            );
        }
        // Using the other joints' states (from the bus) beats each drive alone on the
        // wrist as a whole (per joint: clearly on joints 0 and 1, about even on joint 2).
        let ms = |r: &[JointReport; 3]| r.iter().map(|x| x.rms_error_rad.powi(2)).sum::<f64>();
        assert!(
            ms(&coupled) < 0.8 * ms(&alone),
            "{} vs {}",
            ms(&coupled),
            ms(&alone)
        );
    }
}
