//! What the identification model leaves unexplained in the simulated plant: identify
//! the base parameters of rigid body + viscous + Coulomb friction by ordinary least
//! squares on a training log (the robot module's regressor, [`BaseParameters`] and
//! [`crate::solve`]), then the per-joint RMS of `measured - model` on the training and
//! a test log (the paper's "uncompensated" error, Table 2).
use crate::{IdentifyOptions, NormalEquations};
use anyhow::{Context, ensure};
use nalgebra::DVector;
use plant_sim::SimulatedLog;
use robot::base::BaseParameters;
use robot::{JointMode, ModelTerms, Robot};

/// One joint's uncompensated RMS error [N*m].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointRms {
    /// Robot joint, 0-based.
    pub joint: usize,
    /// RMS of measured - model on the training log.
    pub train_nm: f64,
    /// RMS of measured - model on the test log.
    pub test_nm: f64,
    /// RMS of the measured torque itself on the test log (signal size).
    pub test_signal_nm: f64,
}

/// Which torque column of the log to fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TorqueSource {
    /// `tau{j}_nm`: the measured (logged) torque.
    Measured,
    /// `true_tau{j}_nm`: the plant's torque before sensing.
    True,
}

/// The robot as the identification sees it: `joints` modelled with the paper's terms
/// (viscous + Coulomb), every other joint locked where the log holds it (its first sample).
pub fn identification_robot(robot: &Robot, log: &SimulatedLog, joints: &[usize]) -> Robot {
    let mut r = robot.clone();
    r.terms = ModelTerms::default();
    let q0 = log
        .rows
        .first()
        .map(|row| row[1..1 + log.dof].to_vec())
        .unwrap_or_else(|| vec![0.0; log.dof]);
    for (i, j) in r.joints.iter_mut().enumerate() {
        j.mode = if joints.contains(&i) {
            JointMode::Modelled
        } else {
            JointMode::Locked { q_rad: q0[i] }
        };
    }
    r
}

/// The identification of one log: base parameters and the fitted values.
#[derive(Debug, Clone)]
pub struct LogIdentification {
    /// The identified robot (joint selection and terms).
    pub robot: Robot,
    /// Its base parameters.
    pub base: BaseParameters,
    /// The least-squares result (values are the base parameters `beta`).
    pub result: crate::Identification,
}

fn state(log: &SimulatedLog, row: &[f64], joints: &[usize]) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let pick = |prefix: &str| -> Vec<f64> {
        joints
            .iter()
            .map(|&j| row[log.column(prefix, j).unwrap_or(0)])
            .collect()
    };
    (pick("q"), pick("qd"), pick("true_qdd"))
}

fn torque_prefix(source: TorqueSource) -> &'static str {
    match source {
        TorqueSource::Measured => "tau",
        TorqueSource::True => "true_tau",
    }
}

/// Identifies rigid body + viscous + Coulomb base parameters of `joints` (0-based) from
/// a simulated log, using its ground-truth accelerations (`true_qdd`) so the result
/// isolates the plant's unmodelled effects from differentiation error.
pub fn identify_log(
    robot: &Robot,
    log: &SimulatedLog,
    joints: &[usize],
    source: TorqueSource,
) -> anyhow::Result<LogIdentification> {
    ensure!(!joints.is_empty(), "no joints to identify");
    let robot = identification_robot(robot, log, joints);
    let base =
        BaseParameters::compute(&robot, 0).map_err(|e| anyhow::anyhow!("base parameters: {e}"))?;
    let mut ne = NormalEquations::new(joints.len(), base.count());
    let prefix = torque_prefix(source);
    for row in &log.rows {
        let (q, qd, qdd) = state(log, row, joints);
        let y = base.project(&robot::dynamics::regressor(&robot, &q, &qd, &qdd));
        let tau: Vec<f64> = joints
            .iter()
            .map(|&j| row[log.column(prefix, j).unwrap_or(0)])
            .collect();
        ne.add_sample_matrix(&y, &tau);
    }
    let result = crate::solve(&mut ne, &base.names(), &IdentifyOptions::default())
        .context("identification")?;
    Ok(LogIdentification {
        robot,
        base,
        result,
    })
}

/// Per-joint RMS of `measured - model` over a log, and RMS of the measured torque.
pub fn residual_rms(
    id: &LogIdentification,
    log: &SimulatedLog,
    joints: &[usize],
    source: TorqueSource,
) -> Vec<(f64, f64)> {
    let beta = DVector::from_column_slice(&id.result.values);
    let prefix = torque_prefix(source);
    let mut e2 = vec![0.0; joints.len()];
    let mut s2 = vec![0.0; joints.len()];
    for row in &log.rows {
        let (q, qd, qdd) = state(log, row, joints);
        let pred = id
            .base
            .project(&robot::dynamics::regressor(&id.robot, &q, &qd, &qdd))
            * &beta;
        for (m, &j) in joints.iter().enumerate() {
            let y = row[log.column(prefix, j).unwrap_or(0)];
            e2[m] += (y - pred[m]).powi(2);
            s2[m] += y * y;
        }
    }
    let n = log.rows.len().max(1) as f64;
    e2.iter()
        .zip(&s2)
        .map(|(e, s)| ((e / n).sqrt(), (s / n).sqrt()))
        .collect()
}

/// Identifies on `train`, evaluates on `train` and `test`: per-joint uncompensated RMS.
pub fn uncompensated_rms(
    robot: &Robot,
    train: &SimulatedLog,
    test: &SimulatedLog,
    joints: &[usize],
    source: TorqueSource,
) -> anyhow::Result<Vec<JointRms>> {
    let id = identify_log(robot, train, joints, source)?;
    let tr = residual_rms(&id, train, joints, source);
    let te = residual_rms(&id, test, joints, source);
    Ok(joints
        .iter()
        .enumerate()
        .map(|(m, &j)| JointRms {
            joint: j,
            train_nm: tr[m].0,
            test_nm: te[m].0,
            test_signal_nm: te[m].1,
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use excitation::ExcitationTrajectory;
    use plant_sim::{CommandedTrajectory, PlantEffects, PlantParameters, SimulationConfig};

    fn robot() -> Robot {
        robot::RobotSource::BuiltIn.load().unwrap()
    }

    fn wrist_log(effects: PlantEffects, seed: u64, periods: usize) -> SimulatedLog {
        let arm = plant_sim::RobotRigidBody::new(&robot());
        let plant = PlantParameters::default_robot();
        let series = ExcitationTrajectory::seeded_rest_to_rest(
            seed,
            &[0.0; 3],
            5,
            10.0,
            plant_sim::trajectory::DEMO_LIMITS,
        );
        let tr = CommandedTrajectory::Fourier { series, periods };
        let mut cfg = SimulationConfig::new(6, 3);
        cfg.driven_joints = vec![3, 4, 5];
        cfg.effects = effects;
        cfg.seed = seed;
        plant_sim::simulate(&arm, &plant, &tr, &cfg).unwrap()
    }

    /// With every unmodelled effect off, identifying the default robot
    /// from its own simulated log recovers its true base parameters.
    #[test]
    fn ideal_plant_identification_recovers_true_base_parameters() {
        let robot = robot();
        let log = wrist_log(PlantEffects::none(), 1, 2);
        let joints = [3, 4, 5];
        let id = identify_log(&robot, &log, &joints, TorqueSource::Measured).unwrap();
        // True standard parameters of the identified model: the robot file's inertia and
        // the plant's viscous and Coulomb friction (the plant file must agree with it).
        let truth = id.base.beta(&id.robot.standard_parameters());
        let mut worst: f64 = 0.0;
        for (b, t) in id.result.values.iter().zip(truth.iter()) {
            worst = worst.max((b - t).abs() / t.abs().max(1e-3));
        }
        assert!(
            worst < 1e-6,
            "worst relative error {worst:e}: {:?} vs {:?}",
            id.result.values,
            truth
        );
        let test = wrist_log(PlantEffects::none(), 2, 1);
        for (e, _) in residual_rms(&id, &test, &joints, TorqueSource::Measured) {
            assert!(e < 1e-6, "test residual {e}");
        }
    }

    #[test]
    fn unmodelled_effects_leave_an_error() {
        let r = uncompensated_rms(
            &robot(),
            &wrist_log(PlantEffects::all(), 1, 2),
            &wrist_log(PlantEffects::all(), 2, 1),
            &[3, 4, 5],
            TorqueSource::Measured,
        )
        .unwrap();
        for x in r {
            assert!(x.train_nm > 0.1 && x.test_nm > 0.1, "{x:?}");
        }
    }
}
