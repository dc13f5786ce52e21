//! The robot an identification works on, and the identified model read back: the robot
//! with its joint selection and model terms, its base parameters, and the standard
//! parameters an identified model file maps back to.

use crate::model_file::ModelFile;
use crate::pipeline::{self, LinearModel};
use anyhow::{Context, bail};
use logs::Samples;
use nalgebra::{DMatrix, DVector};
use robot::base::BaseParameters;
use robot::dynamics::firmware_model::FirmwareModel;
use robot::{ChainSelection, LoadedRobot, Robot, RobotSource};
use std::path::Path;

/// Seed of the random states from which base parameters are computed (fixed, so a
/// model file's base parameters can be recomputed and checked).
pub const BASE_SEED: u64 = 2020;

/// Largest |value| of an identified base parameter a model file may hold (SI units: a
/// tonne, 1e6 kg m^2 or N m s/rad): an identified cobot's are below 1e3.
pub const MAX_ABS_BASE_PARAMETER: f64 = 1e6;

/// Which joints are modelled and which terms are added to the robot file's model.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ModelSelection {
    /// Joints locked at a position: (0-based joint, position [rad]); when any is given, the
    /// others are modelled (otherwise the robot file's own selection applies).
    pub locked: Vec<(usize, f64)>,
    /// A constant torque offset per joint.
    pub friction_offset: bool,
    /// Coulomb sign smoothed as tanh(q̇ / ε) with this ε [rad/s].
    pub coulomb_smoothing_rad_s: Option<f64>,
    /// The extended friction basis (offset, velocity-weakening terms, quadratic drag).
    pub extended_friction: bool,
    /// The modelled chain of a URDF tree.
    pub chain: ChainSelection,
}

/// Loads the robot's chain and applies the joint selection and model terms. The loaded
/// robot's [`LoadedRobot::warning`] names the moving joints folded out of the chain.
pub fn load_robot(source: &RobotSource, m: &ModelSelection) -> anyhow::Result<LoadedRobot> {
    let mut loaded = source.load_chain(&m.chain)?;
    let robot = &mut loaded.robot;
    if !m.locked.is_empty() {
        robot.model_all_joints();
    }
    for &(i, q) in &m.locked {
        if i >= robot.dof() || !q.is_finite() {
            bail!(
                "locked joint {} at {q}: the joint must be 1..={} and the position finite",
                i + 1,
                robot.dof()
            );
        }
        robot.lock_joint(i, q);
    }
    robot.terms.friction_offset |= m.friction_offset;
    robot.terms.extended_friction |= m.extended_friction;
    if let Some(eps) = m.coulomb_smoothing_rad_s {
        robot.terms.coulomb_smoothing_rad_s = Some(eps);
    }
    if robot.n_modelled() == 0 {
        bail!("{source}: every joint is locked; nothing to model");
    }
    Ok(loaded)
}

/// A robot with its base parameters: the [`LinearModel`] identified from logs.
pub struct RobotBaseModel {
    /// The robot (joint selection and model terms applied).
    pub robot: Robot,
    /// Its base parameters.
    pub base: BaseParameters,
}

impl RobotBaseModel {
    /// Computes the base parameters of `robot`.
    pub fn new(robot: Robot) -> anyhow::Result<Self> {
        let base = BaseParameters::compute(&robot, BASE_SEED)
            .with_context(|| format!("{}: base parameters", robot.source.display()))?;
        Ok(Self { robot, base })
    }

    /// Standard parameters equivalent to base parameter values `beta`.
    pub fn equivalent_standard(&self, beta: &DVector<f64>) -> DVector<f64> {
        self.base.equivalent_standard(beta)
    }

    /// Readable definition of each base parameter.
    pub fn expressions(&self) -> Vec<String> {
        self.base.expressions()
    }
}

impl LinearModel for RobotBaseModel {
    fn modelled_log_joints(&self) -> Vec<usize> {
        self.robot.modelled_joints()
    }

    fn parameter_names(&self) -> Vec<String> {
        self.base.names()
    }

    fn regressor_block(&self, states: &[(Vec<f64>, Vec<f64>, Vec<f64>)]) -> DMatrix<f64> {
        let y = robot::dynamics::stack_regressors(
            &self.robot,
            states
                .iter()
                .map(|(q, qd, qdd)| (q.as_slice(), qd.as_slice(), qdd.as_slice())),
        );
        self.base.project(&y)
    }
}

/// The firmware f32 model's torques for every sample of a log: `out[joint][sample]`.
pub fn predict_log(model: &FirmwareModel, joints: &[usize], s: &Samples) -> Vec<Vec<f64>> {
    let mut out: Vec<Vec<f64>> = joints.iter().map(|_| Vec::with_capacity(s.len())).collect();
    for (q, qd, qdd) in pipeline::states(s, joints, 0, s.len()) {
        for (r, t) in model.torques(&q, &qd, &qdd).into_iter().enumerate() {
            out[r].push(t);
        }
    }
    out
}

/// An identified model read back: the robot as identified and its standard parameters.
pub struct IdentifiedRobot {
    /// The robot with the model file's chain, joint selection and terms.
    pub robot: Robot,
    /// Standard parameters equivalent to the identified base parameters.
    pub standard_parameters: DVector<f64>,
    /// The warning naming moving joints folded out of the chain, if any.
    pub warning: Option<String>,
}

/// The robot and its standard parameters from an identified model file (JSON from
/// `identify`): checks that the robot description is the one identified (SHA-256),
/// applies the model's joint selection and terms, and maps the base parameters back.
pub fn load_identified(source: &RobotSource, mp: &Path) -> anyhow::Result<IdentifiedRobot> {
    let file = ModelFile::read(mp)?;
    let hash = logs::sha256_hex(&source.bytes()?);
    if hash != file.robot.sha256 {
        bail!(
            "{source}: robot file differs from the one the model was identified for ({}, sha256 {})",
            file.robot.source_path,
            file.robot.sha256
        );
    }
    // Chain, joint selection and model terms come from the model file.
    let loaded = source.load_chain(&file.robot.chain.selection())?;
    let warning = loaded.warning();
    let mut robot = loaded.robot;
    robot.model_all_joints();
    let t = &file.model_terms;
    robot.terms.viscous_friction = t.viscous_friction;
    robot.terms.coulomb_friction = t.coulomb_friction;
    robot.terms.friction_offset = t.friction_offset;
    robot.terms.coulomb_smoothing_rad_s = t.coulomb_smoothing_rad_s;
    robot.terms.rotor_inertia = t.rotor_inertia;
    robot.terms.extended_friction = t.extended_friction;
    if file.base_seed != BASE_SEED {
        bail!(
            "{}, field base_seed: {} (this build computes base parameters with seed {BASE_SEED})",
            mp.display(),
            file.base_seed
        );
    }
    for l in &file.locked_joints {
        let i = robot
            .joints
            .iter()
            .position(|x| x.name == l.name)
            .with_context(|| {
                format!(
                    "{}, field locked_joints: no joint '{}' in the robot",
                    mp.display(),
                    l.name
                )
            })?;
        robot.lock_joint(i, l.position_rad);
    }
    let model = RobotBaseModel::new(robot)?;
    let names = model.parameter_names();
    let expr = model.expressions();
    if names.len() != file.base_parameters.len()
        || file
            .base_parameters
            .iter()
            .zip(names.iter().zip(&expr))
            .any(|(b, (n, e))| &b.name != n || &b.expression != e)
    {
        bail!(
            "{}, field base_parameters: they do not match the base parameters of {source} with this joint selection and model terms (--friction-offset, --coulomb-smoothing-rad-s)",
            mp.display(),
        );
    }
    // A finite but huge value (3e38 fits an f32) overflows the torques it scales.
    if let Some((k, b)) = file
        .base_parameters
        .iter()
        .enumerate()
        .find(|(_, b)| b.value.is_nan() || b.value.abs() > MAX_ABS_BASE_PARAMETER)
    {
        bail!(
            "{}, field base_parameters[{k}].value ({}): {} is beyond the limit {MAX_ABS_BASE_PARAMETER:e} (MAX_ABS_BASE_PARAMETER, SI units)",
            mp.display(),
            b.name,
            b.value
        );
    }
    let beta = DVector::from_iterator(names.len(), file.base_parameters.iter().map(|b| b.value));
    let standard_parameters = model.equivalent_standard(&beta);
    let mut robot = model.robot;
    robot.identified_ranges = identified_ranges(&file, &robot, mp)?;
    Ok(IdentifiedRobot {
        robot,
        standard_parameters,
        warning,
    })
}

/// The model file's identification ranges in the robot's modelled-joint order (empty
/// when the file records none); each must name a modelled joint, in order, with finite
/// `min <= max`.
fn identified_ranges(
    file: &ModelFile,
    robot: &Robot,
    mp: &Path,
) -> anyhow::Result<Vec<robot::IdentifiedRanges>> {
    if file.identification_ranges.is_empty() {
        return Ok(Vec::new());
    }
    let modelled = robot.modelled_joints();
    if file.identification_ranges.len() != modelled.len() {
        bail!(
            "{}, field identification_ranges: {} entries for {} modelled joints",
            mp.display(),
            file.identification_ranges.len(),
            modelled.len()
        );
    }
    let mut out = Vec::with_capacity(modelled.len());
    for (k, (r, &j)) in file.identification_ranges.iter().zip(&modelled).enumerate() {
        if r.joint != robot.joints[j].name {
            bail!(
                "{}, field identification_ranges[{k}].joint: '{}', expected '{}'",
                mp.display(),
                r.joint,
                robot.joints[j].name
            );
        }
        for (field, v) in [
            ("q_rad", r.q_rad),
            ("qd_rad_s", r.qd_rad_s),
            ("qdd_rad_s2", r.qdd_rad_s2),
        ] {
            if !(v[0].is_finite() && v[1].is_finite() && v[0] <= v[1])
                || v[0].abs() > f32::MAX as f64
                || v[1].abs() > f32::MAX as f64
            {
                bail!(
                    "{}, field identification_ranges[{k}].{field}: [{}, {}] is not a finite range (min <= max)",
                    mp.display(),
                    v[0],
                    v[1]
                );
            }
        }
        out.push(r.to_robot());
    }
    Ok(out)
}

/// The robot and standard parameters of an identified model ([`load_identified`]), or,
/// without a model, the robot's nominal parameters with the selection `m`.
pub fn load_model_robot(
    source: &RobotSource,
    model: Option<&Path>,
    m: &ModelSelection,
) -> anyhow::Result<IdentifiedRobot> {
    match model {
        None => {
            let loaded = load_robot(source, m)?;
            let warning = loaded.warning();
            let standard_parameters = loaded.robot.standard_parameters();
            Ok(IdentifiedRobot {
                robot: loaded.robot,
                standard_parameters,
                warning,
            })
        }
        Some(mp) => {
            let recorded = ModelFile::read(mp)?.robot.chain.selection();
            if !m.chain.is_default() && m.chain != recorded {
                bail!(
                    "{}: the model was identified on another chain ({:?}); leave out --base-link, --tip-link and --side-joint to use the model's",
                    mp.display(),
                    recorded
                );
            }
            load_identified(source, mp)
        }
    }
}
