//! Robot description: a serial chain of revolute joints with per-link inertia,
//! joint limits, drive data and friction, loaded from URDF or from a DH table (TOML).
//!
//! Every joint is represented generically, whatever the source format:
//! body frame `F_i = F_{i-1} * X_i * Rot(axis_i, q_i)`, where `X_i` is the fixed
//! transform [`Joint::origin_rotation`], [`Joint::origin_translation`] (parent body
//! frame to the joint frame at `q = 0`) and `axis_i` is a unit vector in the joint
//! frame. The link's inertial parameters are given in the *link frame*
//! `L_i = F_i * [Joint::link_frame]` (identity for URDF and modified DH; for standard
//! DH the distal DH frame `i`, i.e. `Trans_x(a_i) Rot_x(alpha_i)` after the body frame).
//!
//! API:
//! - [`Robot::load`] picks the reader by extension (`.urdf`/`.xml` or `.toml`);
//!   [`Robot::from_urdf_str`], [`Robot::from_dh_toml_str`] parse text.
//! - [`Robot::load_chain`], [`Robot::from_urdf_str_chain`]: a URDF tree, of which one
//!   chain ([`ChainSelection`]: base and tip link) is modelled; the other branches ride on
//!   it as fixed bodies, and those with moving joints come back as [`FoldedJoint`]s
//!   (the warning to show).
//! - [`Robot::modelled_joints`]: the joints whose torques are modelled; the others are
//!   locked at [`JointMode::Locked`] positions. [`Robot::default_paper_selection`] locks
//!   joints 1-3 and models 4-6 (Zhang et al. 2020).
//! - [`Robot::standard_parameters`], [`Robot::parameter_names`]: the nominal standard
//!   parameter vector (layout: [`ParameterLayout`]).
//!
//! Errors ([`RobotError`]) name the file, the line (where known) and the field.
#![deny(unsafe_code)]
#![warn(missing_docs)]
use firmware::dynamics::{STRIBECK_INV_SPEEDS_S_RAD, STRIBECK_TERMS};
use nalgebra::{Matrix3, Rotation3, Unit, Vector3};
use std::fmt;
use std::path::{Path, PathBuf};

pub mod base;
mod dh;
pub mod dynamics;
mod urdf;

pub use dh::DhConvention;

/// Largest URDF file read [bytes].
pub const MAX_URDF_BYTES: usize = 64 << 20;

/// Largest number of `<link>` elements in a URDF.
pub const MAX_URDF_LINKS: usize = 10_000;

/// Largest number of `<joint>` elements in a URDF.
pub const MAX_URDF_JOINTS: usize = 10_000;

/// Largest number of attributes on one URDF element.
pub const MAX_URDF_ATTRIBUTES: usize = 64;

/// Which chain of a URDF tree is modelled, and where the joints outside it stand.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ChainSelection {
    /// First link of the chain (its frame is the base frame); `None`: the root link.
    pub base_link: Option<String>,
    /// Last link of the chain; `None`: the single link that ends a path of moving joints
    /// below the base (an error lists the candidates when there are several).
    pub tip_link: Option<String>,
    /// Positions [rad, or m for prismatic joints] of moving joints outside the chain, by
    /// joint name; the others stand at 0.
    pub side_joint_positions: Vec<(String, f64)>,
    /// Whether the URDF's `<dynamics damping friction>` enter the nominal model.
    pub urdf_friction: UrdfFriction,
}

/// What the nominal model takes from a URDF joint's `<dynamics damping friction>`.
///
/// The default leaves them out, as Pinocchio's RNEA (and most URDF consumers' inverse
/// dynamics) does: in the makers' descriptions they are simulator damping, not measured
/// friction. [`UrdfFriction::Nominal`] takes `damping` as the viscous coefficient
/// [N·m·s/rad] and `friction` as the Coulomb torque [N·m] of the joint's nominal friction.
/// A DH table's friction values are always taken (they are the description's own).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum UrdfFriction {
    /// Left out: nominal friction 0 (Pinocchio's RNEA).
    #[default]
    LeftOut,
    /// `damping` and `friction` as the nominal viscous and Coulomb friction.
    Nominal,
}

impl ChainSelection {
    /// Whether no chain is selected (the whole description's default chain; the
    /// [`UrdfFriction`] choice is not a chain and a DH table ignores it).
    pub fn is_default(&self) -> bool {
        self.base_link.is_none() && self.tip_link.is_none() && self.side_joint_positions.is_empty()
    }
}

/// A moving joint outside the modelled chain, folded in as part of a fixed body.
#[derive(Debug, Clone, PartialEq)]
pub struct FoldedJoint {
    /// Joint name.
    pub name: String,
    /// URDF joint type (`revolute`, `continuous` or `prismatic`).
    pub joint_type: String,
    /// Position it is held at [rad, or m for prismatic joints].
    pub position: f64,
    /// The chain link whose body carries it, or `None` when it rides on the base (or
    /// above it) and does not load the modelled joints' gravity-free dynamics.
    pub carried_by: Option<String>,
}

impl fmt::Display for FoldedJoint {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let unit = if self.joint_type == "prismatic" {
            "m"
        } else {
            "rad"
        };
        write!(
            f,
            "{} ({}) at {} {unit}, on {}",
            self.name,
            self.joint_type,
            self.position,
            self.carried_by.as_deref().unwrap_or("the base")
        )
    }
}

/// The built-in default robot: a UR5e-class arm with a 2.5 kg tool, as a DH table
/// (`robots/default.toml`), compiled in.
pub const DEFAULT_ROBOT_TOML: &str = include_str!("../../../robots/default.toml");
/// The name the built-in default robot goes by in messages and model files.
pub const DEFAULT_ROBOT_NAME: &str = "robots/default.toml";

/// Where a robot description comes from.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub enum RobotSource {
    /// The built-in default robot ([`DEFAULT_ROBOT_TOML`]).
    #[default]
    BuiltIn,
    /// A URDF (`.urdf`, `.xml`) or DH table (`.toml`) file.
    File(PathBuf),
}

impl From<Option<PathBuf>> for RobotSource {
    fn from(path: Option<PathBuf>) -> Self {
        path.map_or(Self::BuiltIn, Self::File)
    }
}

impl fmt::Display for RobotSource {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::BuiltIn => write!(f, "{DEFAULT_ROBOT_NAME} (built in)"),
            Self::File(p) => write!(f, "{}", p.display()),
        }
    }
}

impl RobotSource {
    /// The path errors and model files name: the file, or [`DEFAULT_ROBOT_NAME`].
    pub fn path(&self) -> &Path {
        match self {
            Self::BuiltIn => Path::new(DEFAULT_ROBOT_NAME),
            Self::File(p) => p,
        }
    }

    /// The description's bytes (a file larger than [`MAX_URDF_BYTES`] is refused).
    pub fn bytes(&self) -> Result<std::borrow::Cow<'static, [u8]>, RobotError> {
        match self {
            Self::BuiltIn => Ok(DEFAULT_ROBOT_TOML.as_bytes().into()),
            Self::File(path) => {
                let file_err = |message: String| RobotError {
                    file: path.clone(),
                    line: None,
                    field: "<file>".into(),
                    message,
                };
                let size = std::fs::metadata(path)
                    .map_err(|e| file_err(format!("cannot read: {e}")))?
                    .len();
                if size > MAX_URDF_BYTES as u64 {
                    return Err(file_err(format!(
                        "{size} bytes: larger than the limit of {MAX_URDF_BYTES} bytes (MAX_URDF_BYTES)"
                    )));
                }
                let bytes =
                    std::fs::read(path).map_err(|e| file_err(format!("cannot read: {e}")))?;
                Ok(bytes.into())
            }
        }
    }

    /// Loads the robot ([`Robot::load`]).
    pub fn load(&self) -> Result<Robot, RobotError> {
        Ok(self.load_chain(&ChainSelection::default())?.robot)
    }

    /// Loads the robot and selects the chain of a URDF tree ([`Robot::load_chain`]).
    pub fn load_chain(&self, selection: &ChainSelection) -> Result<LoadedRobot, RobotError> {
        let bytes = self.bytes()?;
        let text = std::str::from_utf8(&bytes).map_err(|e| RobotError {
            file: self.path().to_path_buf(),
            line: None,
            field: "<file>".into(),
            message: format!("cannot read: not UTF-8 text ({e})"),
        })?;
        Robot::parse_chain(text, self.path(), selection)
    }
}

/// A robot read from a description, with the moving joints folded out of its chain.
#[derive(Debug, Clone, PartialEq)]
pub struct LoadedRobot {
    /// The modelled chain.
    pub robot: Robot,
    /// First and last link of the chain (URDF; `None` for a DH table).
    pub chain_links: Option<(String, String)>,
    /// Moving joints outside the chain, held at fixed positions (empty for a serial
    /// description); callers show them as a warning ([`LoadedRobot::warning`]).
    pub folded: Vec<FoldedJoint>,
}

impl LoadedRobot {
    /// The warning listing the folded joints, if any.
    pub fn warning(&self) -> Option<String> {
        if self.folded.is_empty() {
            return None;
        }
        let list: Vec<String> = self.folded.iter().map(|j| j.to_string()).collect();
        let chain = match &self.chain_links {
            Some((base, tip)) => format!("the chain from \"{base}\" to \"{tip}\""),
            None => "the chain".into(),
        };
        Some(format!(
            "{}: {} moving joint(s) outside {chain} are held fixed (set with --side-joint NAME=Q): {}",
            self.robot.source.display(),
            self.folded.len(),
            list.join("; ")
        ))
    }
}

/// Standard inertial parameters of one link per row block, in this order
/// (inertia about the link frame origin, link axes).
pub const LINK_PARAMETER_NAMES: [&str; 10] =
    ["m", "mx", "my", "mz", "xx", "yy", "zz", "xy", "xz", "yz"];

/// Number of standard inertial parameters per link.
pub const PARAMETERS_PER_LINK: usize = 10;

/// An error in a robot description: file, line (1-based, where known), field, message.
#[derive(Debug, Clone, PartialEq)]
pub struct RobotError {
    /// The file read (or `<string>`).
    pub file: PathBuf,
    /// 1-based line, where the position is known.
    pub line: Option<usize>,
    /// The field (or element) at fault, e.g. `joint[2].mass` or `link "forearm" inertial.mass`.
    pub field: String,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for RobotError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file.display())?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
        }
        write!(f, ": field `{}`: {}", self.field, self.message)
    }
}

impl std::error::Error for RobotError {}

/// Mass, centre of mass and inertia of one link, in its link frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkInertial {
    /// Mass [kg].
    pub mass_kg: f64,
    /// Centre of mass [m], link frame.
    pub com_m: Vector3<f64>,
    /// Inertia [kg*m^2] about the centre of mass, link axes (symmetric).
    pub inertia_com: Matrix3<f64>,
}

impl LinkInertial {
    /// A massless link.
    pub fn zero() -> Self {
        LinkInertial {
            mass_kg: 0.0,
            com_m: Vector3::zeros(),
            inertia_com: Matrix3::zeros(),
        }
    }

    /// Standard parameters `[m, m*cx, m*cy, m*cz, Ixx, Iyy, Izz, Ixy, Ixz, Iyz]`, the
    /// inertia about the link frame origin (parallel-axis theorem).
    pub fn standard_parameters(&self) -> [f64; 10] {
        let m = self.mass_kg;
        let c = self.com_m;
        let io =
            self.inertia_com + m * (c.norm_squared() * Matrix3::identity() - c * c.transpose());
        [
            m,
            m * c.x,
            m * c.y,
            m * c.z,
            io[(0, 0)],
            io[(1, 1)],
            io[(2, 2)],
            io[(0, 1)],
            io[(0, 2)],
            io[(1, 2)],
        ]
    }

    /// Inverse of [`standard_parameters`](Self::standard_parameters) (a massless
    /// link keeps its inertia about the origin as inertia about the COM).
    pub fn from_standard_parameters(p: &[f64; 10]) -> Self {
        let m = p[0];
        let h = Vector3::new(p[1], p[2], p[3]);
        let io = inertia_matrix(&[p[4], p[5], p[6], p[7], p[8], p[9]]);
        if m.abs() < 1e-300 {
            return LinkInertial {
                mass_kg: m,
                com_m: Vector3::zeros(),
                inertia_com: io,
            };
        }
        let c = h / m;
        let ic = io - m * (c.norm_squared() * Matrix3::identity() - c * c.transpose());
        LinkInertial {
            mass_kg: m,
            com_m: c,
            inertia_com: ic,
        }
    }
}

/// The symmetric inertia matrix from `[Ixx, Iyy, Izz, Ixy, Ixz, Iyz]`.
pub fn inertia_matrix(i: &[f64; 6]) -> Matrix3<f64> {
    Matrix3::new(i[0], i[3], i[4], i[3], i[1], i[5], i[4], i[5], i[2])
}

/// Expresses standard parameters given in frame `L` in frame `B`, where `L` is placed in
/// `B` by rotation `r` and translation `p` (`x_B = r * x_L + p`). Linear in `params`.
pub fn transform_standard_parameters(
    params: &[f64; 10],
    r: &Matrix3<f64>,
    p: &Vector3<f64>,
) -> [f64; 10] {
    let m = params[0];
    let h = r * Vector3::new(params[1], params[2], params[3]);
    let il = inertia_matrix(&[
        params[4], params[5], params[6], params[7], params[8], params[9],
    ]);
    let e = Matrix3::identity();
    let ib = r * il * r.transpose() + 2.0 * p.dot(&h) * e - (h * p.transpose() + p * h.transpose())
        + m * (p.norm_squared() * e - p * p.transpose());
    let hb = h + m * p;
    [
        m,
        hb.x,
        hb.y,
        hb.z,
        ib[(0, 0)],
        ib[(1, 1)],
        ib[(2, 2)],
        ib[(0, 1)],
        ib[(0, 2)],
        ib[(1, 2)],
    ]
}

/// Joint limits; `None` where the description gives none.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct JointLimits {
    /// Lower position limit [rad].
    pub q_min_rad: Option<f64>,
    /// Upper position limit [rad].
    pub q_max_rad: Option<f64>,
    /// Speed limit [rad/s].
    pub qd_max_rad_s: Option<f64>,
    /// Acceleration limit [rad/s^2].
    pub qdd_max_rad_s2: Option<f64>,
    /// Torque limit [N*m].
    pub effort_max_nm: Option<f64>,
}

/// Drive data of one joint (joint side), where known.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct JointDrive {
    /// Joint torque per motor current [N*m/A]: Kt x gear ratio x efficiency.
    pub drive_gain_nm_per_a: Option<f64>,
    /// Gear ratio (motor turns per joint turn).
    pub gear_ratio: Option<f64>,
    /// Motor torque constant [N*m/A], motor side.
    pub torque_constant_nm_per_a: Option<f64>,
    /// Rotor inertia reflected to the joint side [kg*m^2] (ratio^2 x rotor inertia).
    pub rotor_inertia_kg_m2: Option<f64>,
}

/// Friction of one joint: `tau_f = viscous * qd + coulomb * sgn(qd) + offset`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct JointFriction {
    /// Viscous coefficient [N*m*s/rad].
    pub viscous_nm_s_rad: f64,
    /// Coulomb level [N*m].
    pub coulomb_nm: f64,
    /// Constant offset [N*m].
    pub offset_nm: f64,
}

/// Whether a joint is modelled (its torque predicted) or locked at a fixed position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum JointMode {
    /// Moves; its torque is modelled.
    Modelled,
    /// Held at this position [rad]; its link moves rigidly with its parent.
    Locked {
        /// Fixed position [rad].
        q_rad: f64,
    },
}

/// One revolute joint and the link it moves.
#[derive(Debug, Clone, PartialEq)]
pub struct Joint {
    /// Joint name.
    pub name: String,
    /// Rotation of the fixed parent-body-to-joint transform `X_i`.
    pub origin_rotation: Matrix3<f64>,
    /// Translation [m] of `X_i` (joint frame origin in the parent body frame).
    pub origin_translation: Vector3<f64>,
    /// Rotation axis (unit), joint frame.
    pub axis: Unit<Vector3<f64>>,
    /// Link frame in the body frame (rotation, translation [m]); `None` = identity.
    pub link_frame: Option<(Matrix3<f64>, Vector3<f64>)>,
    /// Inertial data of the moved link (all links rigidly attached merged), link frame.
    pub inertial: LinkInertial,
    /// Limits.
    pub limits: JointLimits,
    /// Drive data.
    pub drive: JointDrive,
    /// Nominal friction.
    pub friction: JointFriction,
    /// Modelled or locked.
    pub mode: JointMode,
    /// The joint drive's profile from the description (`[joint.profile]` of a DH
    /// table); `None`: not given (see [`Joint::drive_profile`]).
    pub profile: Option<firmware::control::JointProfile>,
}

impl Joint {
    /// The joint drive's profile: the description's, else the board's
    /// (`firmware::control::JointProfile::BOARD`). What the exporter writes into a
    /// model file's `JOINT_PROFILES` and what a closed-loop simulation of this joint's
    /// drive and compensator runs.
    pub fn drive_profile(&self) -> firmware::control::JointProfile {
        self.profile
            .unwrap_or(firmware::control::JointProfile::BOARD)
    }

    /// Standard parameters of this link expressed in the body frame `F_i` (what the
    /// recursive Newton-Euler uses), from parameters `link_params` in the link frame.
    pub fn link_to_body(&self, link_params: &[f64; 10]) -> [f64; 10] {
        match &self.link_frame {
            None => *link_params,
            Some((r, p)) => transform_standard_parameters(link_params, r, p),
        }
    }
}

/// Which non-rigid-body terms the model (and hence the regressor) includes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModelTerms {
    /// Viscous friction column per modelled joint.
    pub viscous_friction: bool,
    /// Coulomb friction column per modelled joint.
    pub coulomb_friction: bool,
    /// Constant torque offset column per modelled joint.
    pub friction_offset: bool,
    /// `Some(eps)`: Coulomb uses `tanh(qd / eps)` instead of `sgn(qd)` [rad/s].
    pub coulomb_smoothing_rad_s: Option<f64>,
    /// Reflected rotor inertia column per modelled joint (`tau = Ia * qdd`).
    pub rotor_inertia: bool,
    /// The extended friction basis per modelled joint (with the offset): velocity-weakening
    /// `tanh(qd / v_k)` at `firmware::dynamics::STRIBECK_SPEEDS_RAD_S` and quadratic drag
    /// `qd*|qd|`.
    pub extended_friction: bool,
}

impl Default for ModelTerms {
    /// The paper's model: viscous and Coulomb friction (hard sign), no offset, no rotor.
    fn default() -> Self {
        ModelTerms {
            viscous_friction: true,
            coulomb_friction: true,
            friction_offset: false,
            coulomb_smoothing_rad_s: None,
            rotor_inertia: false,
            extended_friction: false,
        }
    }
}

impl ModelTerms {
    /// Only the rigid body (no friction, no rotor inertia).
    pub fn rigid_body_only() -> Self {
        ModelTerms {
            viscous_friction: false,
            coulomb_friction: false,
            friction_offset: false,
            coulomb_smoothing_rad_s: None,
            rotor_inertia: false,
            extended_friction: false,
        }
    }

    /// Names of the per-joint extra parameters, in layout order.
    pub fn joint_parameter_kinds(&self) -> Vec<JointParameter> {
        let mut v = Vec::new();
        if self.viscous_friction {
            v.push(JointParameter::Viscous);
        }
        if self.coulomb_friction {
            v.push(JointParameter::Coulomb);
        }
        if self.friction_offset || self.extended_friction {
            v.push(JointParameter::Offset);
        }
        if self.rotor_inertia {
            v.push(JointParameter::RotorInertia);
        }
        if self.extended_friction {
            v.extend((0..STRIBECK_TERMS).map(JointParameter::Stribeck));
            v.push(JointParameter::Quadratic);
        }
        v
    }

    /// The Coulomb sign function used (hard sign or smoothed).
    pub fn coulomb_sign(&self, qd: f64) -> f64 {
        match self.coulomb_smoothing_rad_s {
            Some(eps) if eps > 0.0 => (qd / eps).tanh(),
            _ => {
                if qd > 0.0 {
                    1.0
                } else if qd < 0.0 {
                    -1.0
                } else {
                    0.0
                }
            }
        }
    }
}

/// A per-joint (non-inertial) parameter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointParameter {
    /// Viscous friction [N*m*s/rad] (name `fv<i>`).
    Viscous,
    /// Coulomb friction [N*m] (name `fc<i>`).
    Coulomb,
    /// Offset [N*m] (name `fo<i>`).
    Offset,
    /// Reflected rotor inertia [kg*m^2] (name `Ia<i>`).
    RotorInertia,
    /// Velocity-weakening friction `tanh(qd / v_k)` [N*m] (name `fs<k>_<i>`, k from 1).
    Stribeck(usize),
    /// Quadratic drag `qd*|qd|` [N*m*s^2/rad^2] (name `fq<i>`).
    Quadratic,
}

impl JointParameter {
    /// Name prefix (the 1-based joint number follows).
    pub fn prefix(self) -> String {
        match self {
            JointParameter::Viscous => "fv".into(),
            JointParameter::Coulomb => "fc".into(),
            JointParameter::Offset => "fo".into(),
            JointParameter::RotorInertia => "Ia".into(),
            JointParameter::Stribeck(k) => format!("fs{}_", k + 1),
            JointParameter::Quadratic => "fq".into(),
        }
    }

    /// The regressor column of this term for one joint at `qd` [rad/s], `qdd`
    /// [rad/s^2], with `coulomb_sign` the model's sign function of `qd`.
    pub fn column(self, qd: f64, qdd: f64, coulomb_sign: f64) -> f64 {
        match self {
            JointParameter::Viscous => qd,
            JointParameter::Coulomb => coulomb_sign,
            JointParameter::Offset => 1.0,
            JointParameter::RotorInertia => qdd,
            JointParameter::Stribeck(k) => (qd * f64::from(STRIBECK_INV_SPEEDS_S_RAD[k])).tanh(),
            JointParameter::Quadratic => qd * qd.abs(),
        }
    }
}

/// Layout of the standard parameter vector `theta`:
/// `10 * n_joints` link parameters (all links, joint order, [`LINK_PARAMETER_NAMES`]),
/// then for each modelled joint (in order) its [`ModelTerms::joint_parameter_kinds`].
#[derive(Debug, Clone, PartialEq)]
pub struct ParameterLayout {
    /// Number of links (= joints of the robot).
    pub links: usize,
    /// Indices (into the robot's joints) of the modelled joints.
    pub modelled: Vec<usize>,
    /// The per-joint kinds, in order.
    pub joint_kinds: Vec<JointParameter>,
}

impl ParameterLayout {
    /// Total number of standard parameters.
    pub fn len(&self) -> usize {
        PARAMETERS_PER_LINK * self.links + self.modelled.len() * self.joint_kinds.len()
    }

    /// Whether the layout is empty.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Index of link `link`'s parameter `k` (0..10).
    pub fn link_index(&self, link: usize, k: usize) -> usize {
        PARAMETERS_PER_LINK * link + k
    }

    /// Index of the `kind` parameter of the `m`-th modelled joint, if present.
    pub fn joint_index(&self, m: usize, kind: JointParameter) -> Option<usize> {
        let pos = self.joint_kinds.iter().position(|&k| k == kind)?;
        Some(PARAMETERS_PER_LINK * self.links + m * self.joint_kinds.len() + pos)
    }
}

/// A serial robot arm.
#[derive(Debug, Clone, PartialEq)]
pub struct Robot {
    /// Robot name.
    pub name: String,
    /// Where it was read from.
    pub source: PathBuf,
    /// Gravity [m/s^2] in the base frame (e.g. `[0, 0, -9.81]`).
    pub gravity: Vector3<f64>,
    /// Joints from base to tip.
    pub joints: Vec<Joint>,
    /// Terms modelled besides the rigid body.
    pub terms: ModelTerms,
    /// Per modelled joint (output order), the states identification saw; empty: not
    /// recorded (a nominal model). The firmware model continues its extended friction
    /// terms linearly beyond the recorded speeds.
    pub identified_ranges: Vec<IdentifiedRanges>,
}

/// The `[min, max]` of one modelled joint's state over the identification data.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IdentifiedRanges {
    /// Angle [rad].
    pub q_rad: [f64; 2],
    /// Speed [rad/s].
    pub qd_rad_s: [f64; 2],
    /// Acceleration [rad/s^2].
    pub qdd_rad_s2: [f64; 2],
}

/// Largest |offset| of a joint origin or link frame in a robot description [m].
pub const MAX_ABS_OFFSET_M: f64 = 1e3;
/// Largest |value| of a standard parameter derived from a robot description (mass,
/// first moment, inertia, friction; SI units).
pub const MAX_ABS_STANDARD_PARAMETER: f64 = 1e9;

impl Robot {
    /// Loads a robot: `.urdf` or `.xml` as URDF, `.toml` as a DH table; a URDF tree's
    /// default chain ([`Robot::load_chain`] returns the folded joints as well).
    pub fn load(path: impl AsRef<Path>) -> Result<Robot, RobotError> {
        Ok(Self::load_chain(path, &ChainSelection::default())?.robot)
    }

    /// Loads a robot and selects the chain of a URDF tree (a DH table is one chain and
    /// takes no selection).
    pub fn load_chain(
        path: impl AsRef<Path>,
        selection: &ChainSelection,
    ) -> Result<LoadedRobot, RobotError> {
        RobotSource::File(path.as_ref().to_path_buf()).load_chain(selection)
    }

    /// Parses a description's text: the reader is chosen by `path`'s extension (`.urdf`,
    /// `.xml` or `.toml`), and errors name `path`.
    pub fn parse_chain(
        text: &str,
        path: &Path,
        selection: &ChainSelection,
    ) -> Result<LoadedRobot, RobotError> {
        match path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase())
            .as_deref()
        {
            Some("urdf") | Some("xml") => urdf::parse(text, path, selection).and_then(|l| {
                Ok(LoadedRobot {
                    robot: l.robot.check_derived()?,
                    ..l
                })
            }),
            Some("toml") if selection.is_default() => Ok(LoadedRobot {
                robot: dh::parse(text, path)?.check_derived()?,
                chain_links: None,
                folded: Vec::new(),
            }),
            Some("toml") => Err(RobotError {
                file: path.to_path_buf(),
                line: None,
                field: "<chain>".into(),
                message: "a DH table is a single chain: --base-link, --tip-link and --side-joint apply to URDF files only".into(),
            }),
            _ => Err(RobotError {
                file: path.to_path_buf(),
                line: None,
                field: "<file>".into(),
                message: "unknown extension: expected .urdf, .xml or .toml".into(),
            }),
        }
    }

    /// Parses URDF text (`file` names it in errors).
    pub fn from_urdf_str(text: &str, file: impl AsRef<Path>) -> Result<Robot, RobotError> {
        urdf::parse(text, file.as_ref(), &ChainSelection::default())?
            .robot
            .check_derived()
    }

    /// Parses URDF text and selects one chain of its tree (`file` names it in errors).
    pub fn from_urdf_str_chain(
        text: &str,
        file: impl AsRef<Path>,
        selection: &ChainSelection,
    ) -> Result<LoadedRobot, RobotError> {
        let l = urdf::parse(text, file.as_ref(), selection)?;
        Ok(LoadedRobot {
            robot: l.robot.check_derived()?,
            ..l
        })
    }

    /// Parses a DH table in TOML (`file` names it in errors); schema in the crate README.
    pub fn from_dh_toml_str(text: &str, file: impl AsRef<Path>) -> Result<Robot, RobotError> {
        dh::parse(text, file.as_ref()).and_then(Robot::check_derived)
    }

    /// Checks what the parsers derived, not only what they read: a finite but huge
    /// value (a 1e300 COM offset) gives an infinite inertia once scaled. Every joint
    /// origin and link frame offset within [`MAX_ABS_OFFSET_M`], every standard parameter
    /// within [`MAX_ABS_STANDARD_PARAMETER`]; the error names the joint or parameter.
    fn check_derived(self) -> Result<Robot, RobotError> {
        let fail = |field: String, message: String| RobotError {
            file: self.source.clone(),
            line: None,
            field,
            message,
        };
        artifacts::plausible::count(
            self.joints.len(),
            artifacts::plausible::MAX_JOINTS,
            "joints in the chain, MAX_JOINTS",
        )
        .map_err(|m| fail("joints".into(), m))?;
        for j in &self.joints {
            artifacts::plausible::name(&j.name).map_err(|m| {
                fail(
                    format!("joint {} name", j.name.chars().take(40).collect::<String>()),
                    m,
                )
            })?;
            let offsets = std::iter::once(&j.origin_translation)
                .chain(j.link_frame.as_ref().map(|(_, p)| p))
                .flat_map(|p| p.iter());
            if let Some(v) = offsets
                .copied()
                .find(|v| v.is_nan() || v.abs() > MAX_ABS_OFFSET_M)
            {
                return Err(fail(
                    format!("joint `{}` origin", j.name),
                    format!(
                        "offset {v:e} m is beyond the limit {MAX_ABS_OFFSET_M:e} m (MAX_ABS_OFFSET_M)"
                    ),
                ));
            }
        }
        let theta = self.standard_parameters();
        if let Some((k, v)) = theta
            .iter()
            .enumerate()
            .find(|(_, v)| v.is_nan() || v.abs() > MAX_ABS_STANDARD_PARAMETER)
        {
            let name = self.parameter_names().get(k).cloned().unwrap_or_default();
            return Err(fail(
                format!("standard parameter {name}"),
                format!(
                    "{v:e} (from the masses, centres of mass, inertias and friction) is beyond \
                     the limit {MAX_ABS_STANDARD_PARAMETER:e} (MAX_ABS_STANDARD_PARAMETER, SI units)"
                ),
            ));
        }
        Ok(self)
    }

    /// Number of joints (= links) in the chain.
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    /// Indices of the modelled joints, base to tip.
    pub fn modelled_joints(&self) -> Vec<usize> {
        (0..self.joints.len())
            .filter(|&i| self.joints[i].mode == JointMode::Modelled)
            .collect()
    }

    /// Number of modelled joints (length of `q`, `qd`, `qdd` and `tau` vectors).
    pub fn n_modelled(&self) -> usize {
        self.modelled_joints().len()
    }

    /// The paper's selection: joints 1-3 locked (at their current locked position, 0 rad
    /// if they were modelled), joints 4.. modelled. Returns the changed robot.
    pub fn default_paper_selection(&self) -> Robot {
        let mut r = self.clone();
        for (i, j) in r.joints.iter_mut().enumerate() {
            if i < 3 {
                if j.mode == JointMode::Modelled {
                    j.mode = JointMode::Locked { q_rad: 0.0 };
                }
            } else {
                j.mode = JointMode::Modelled;
            }
        }
        r
    }

    /// Locks joint `i` (0-based) at `q_rad`.
    pub fn lock_joint(&mut self, i: usize, q_rad: f64) {
        self.joints[i].mode = JointMode::Locked { q_rad };
    }

    /// Models every joint.
    pub fn model_all_joints(&mut self) {
        for j in &mut self.joints {
            j.mode = JointMode::Modelled;
        }
    }

    /// Layout of the standard parameter vector.
    pub fn parameter_layout(&self) -> ParameterLayout {
        ParameterLayout {
            links: self.joints.len(),
            modelled: self.modelled_joints(),
            joint_kinds: self.terms.joint_parameter_kinds(),
        }
    }

    /// Number of standard parameters.
    pub fn parameter_count(&self) -> usize {
        self.parameter_layout().len()
    }

    /// Names of the standard parameters, e.g. `m6`, `mx6`, `I5zz`, `fv4` (1-based
    /// joint numbers of the full robot).
    pub fn parameter_names(&self) -> Vec<String> {
        let layout = self.parameter_layout();
        let mut names = Vec::with_capacity(layout.len());
        for l in 0..layout.links {
            let n = l + 1;
            for (k, p) in LINK_PARAMETER_NAMES.iter().enumerate() {
                names.push(if k < 4 {
                    format!("{p}{n}")
                } else {
                    format!("I{n}{p}")
                });
            }
        }
        for &j in &layout.modelled {
            for kind in &layout.joint_kinds {
                names.push(format!("{}{}", kind.prefix(), j + 1));
            }
        }
        names
    }

    /// The nominal standard parameter vector from the description (link frames;
    /// friction from the description, rotor inertia 0 where unknown).
    pub fn standard_parameters(&self) -> nalgebra::DVector<f64> {
        let layout = self.parameter_layout();
        let mut theta = nalgebra::DVector::zeros(layout.len());
        for (l, j) in self.joints.iter().enumerate() {
            let p = j.inertial.standard_parameters();
            for k in 0..PARAMETERS_PER_LINK {
                theta[layout.link_index(l, k)] = p[k];
            }
        }
        for (m, &ji) in layout.modelled.iter().enumerate() {
            let j = &self.joints[ji];
            for &kind in &layout.joint_kinds {
                let v = match kind {
                    JointParameter::Viscous => j.friction.viscous_nm_s_rad,
                    JointParameter::Coulomb => j.friction.coulomb_nm,
                    JointParameter::Offset => j.friction.offset_nm,
                    JointParameter::RotorInertia => j.drive.rotor_inertia_kg_m2.unwrap_or(0.0),
                    JointParameter::Stribeck(_) | JointParameter::Quadratic => 0.0,
                };
                if let Some(idx) = layout.joint_index(m, kind) {
                    theta[idx] = v;
                }
            }
        }
        theta
    }
}

/// Rotation by angle `q` about unit axis `a` (Rodrigues).
pub fn axis_rotation(a: &Unit<Vector3<f64>>, q: f64) -> Matrix3<f64> {
    Rotation3::from_axis_angle(a, q).into_inner()
}

/// Rotation from URDF roll-pitch-yaw: `Rz(yaw) * Ry(pitch) * Rx(roll)`.
pub fn rpy_rotation(rpy: [f64; 3]) -> Matrix3<f64> {
    Rotation3::from_euler_angles(rpy[0], rpy[1], rpy[2]).into_inner()
}
