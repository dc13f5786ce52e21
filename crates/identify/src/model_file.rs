//! The identified model as a versioned JSON file that later stages consume.
//!
//! Schema version [`MODEL_SCHEMA_VERSION`]. Written with [`artifacts::write_atomic`]: a
//! failure never leaves a partial file.

use artifacts::write_atomic;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Schema version written into every model file; bump on incompatible changes.
pub const MODEL_SCHEMA_VERSION: u32 = 1;

/// The robot description the model was identified for.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RobotRef {
    /// Robot name (from the URDF or DH file).
    pub name: String,
    /// Path of the description file as given.
    pub source_path: String,
    /// SHA-256 of the description file.
    pub sha256: String,
    /// The modelled chain of a URDF tree (absent: the description's default chain).
    #[serde(default, skip_serializing_if = "ChainRef::is_default")]
    pub chain: ChainRef,
}

/// The chain of a URDF tree a model was identified on (`--base-link`, `--tip-link`,
/// `--side-joint`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ChainRef {
    /// Base link; `None`: the root.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base_link: Option<String>,
    /// Tip link; `None`: the single end of the moving joints.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tip_link: Option<String>,
    /// Positions of moving joints outside the chain [rad or m].
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub side_joints: Vec<LockedJoint>,
}

impl ChainRef {
    /// Whether this is the description's default chain.
    pub fn is_default(&self) -> bool {
        *self == ChainRef::default()
    }

    /// The same chain as a robot loader's selection.
    pub fn selection(&self) -> robot::ChainSelection {
        robot::ChainSelection {
            base_link: self.base_link.clone(),
            tip_link: self.tip_link.clone(),
            side_joint_positions: self
                .side_joints
                .iter()
                .map(|j| (j.name.clone(), j.position_rad))
                .collect(),
            ..robot::ChainSelection::default()
        }
    }

    /// The record of a loader's selection.
    pub fn from_selection(s: &robot::ChainSelection) -> Self {
        ChainRef {
            base_link: s.base_link.clone(),
            tip_link: s.tip_link.clone(),
            side_joints: s
                .side_joint_positions
                .iter()
                .map(|(name, q)| LockedJoint {
                    name: name.clone(),
                    position_rad: *q,
                })
                .collect(),
        }
    }
}

/// A joint held at a fixed position during identification.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LockedJoint {
    /// Joint name.
    pub name: String,
    /// Position [rad].
    pub position_rad: f64,
}

/// One identified base parameter.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BaseParameter {
    /// Short name.
    pub name: String,
    /// The combination of standard parameters it stands for.
    pub expression: String,
    /// Estimate (SI units).
    pub value: f64,
    /// Standard deviation of the estimate.
    pub std: f64,
    /// Relative standard deviation [%].
    pub relative_std_pct: f64,
}

/// Friction of one modelled joint.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointFriction {
    /// Joint name.
    pub joint: String,
    /// Viscous coefficient [N·m·s/rad], if modelled.
    pub viscous_nm_s_rad: Option<f64>,
    /// Coulomb coefficient [N·m], if modelled.
    pub coulomb_nm: Option<f64>,
    /// Constant offset [N·m], if modelled.
    pub offset_nm: Option<f64>,
}

/// The non-rigid-body terms of the model (the regressor's extra columns).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelTermsRef {
    /// Viscous friction per joint.
    pub viscous_friction: bool,
    /// Coulomb friction per joint.
    pub coulomb_friction: bool,
    /// Constant offset per joint.
    pub friction_offset: bool,
    /// Coulomb sign smoothed as tanh(q̇ / eps) [rad/s]; `None` = hard sign.
    pub coulomb_smoothing_rad_s: Option<f64>,
    /// Reflected rotor inertia per joint.
    pub rotor_inertia: bool,
    /// The extended friction basis per joint (offset, velocity-weakening and quadratic
    /// terms); absent in older files (false).
    #[serde(default)]
    pub extended_friction: bool,
}

/// A log used for identification or validation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LogRef {
    /// Path as given.
    pub path: String,
    /// SHA-256 of the file.
    pub sha256: String,
    /// Samples after preprocessing.
    pub samples: usize,
}

/// Per-joint error figures on a data set.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ErrorReport {
    /// What data: "identification" or a validation log path.
    pub data: String,
    /// Per-joint RMS [N·m] (firmware f32 model).
    pub rms_nm: Vec<f64>,
    /// Per-joint normalised RMS [%].
    pub nrms_pct: Vec<f64>,
    /// Samples.
    pub samples: usize,
}

/// The identified model file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelFile {
    /// [`MODEL_SCHEMA_VERSION`].
    pub schema_version: u32,
    /// The robot description.
    pub robot: RobotRef,
    /// Names of the modelled joints, in output order.
    pub modelled_joints: Vec<String>,
    /// Locked joints and their positions.
    pub locked_joints: Vec<LockedJoint>,
    /// Model terms besides the rigid body.
    pub model_terms: ModelTermsRef,
    /// Seed of the random states the base parameters were computed from.
    pub base_seed: u64,
    /// Drive gains [N·m/A] of all joints of the log (current → torque).
    pub drive_gains_nm_per_a: Vec<f64>,
    /// Base parameters (including friction parameters), in regressor column order.
    pub base_parameters: Vec<BaseParameter>,
    /// Friction per modelled joint (the friction entries of `base_parameters`).
    pub friction: Vec<JointFriction>,
    /// Condition number of the observation matrix (and after column scaling).
    pub condition_number: f64,
    /// Condition number after scaling columns to unit norm.
    pub condition_number_scaled: f64,
    /// Weighting used ("ordinary" or "weighted") and per-joint σ [N·m].
    pub weighting: String,
    /// Per-joint noise std used as weights [N·m].
    pub joint_sigma_nm: Vec<f64>,
    /// Logs used for identification.
    pub identification_logs: Vec<LogRef>,
    /// Logs used for validation.
    pub validation_logs: Vec<LogRef>,
    /// Error figures.
    pub errors: Vec<ErrorReport>,
    /// Preprocessing settings, as JSON.
    pub preprocessing: serde_json::Value,
    /// The parameter combinations the identification data could not identify: they
    /// keep the prior's values ([`ModelFile::prior`]); absent in older files.
    #[serde(default)]
    pub dropped_directions: Vec<crate::DroppedDirection>,
    /// What the dropped directions keep (e.g. the robot description's nominal
    /// parameters); absent in older files.
    #[serde(default)]
    pub prior: String,
    /// Per modelled joint, the states the identification data covered; absent in older
    /// files (then nothing is bounded by them).
    #[serde(default)]
    pub identification_ranges: Vec<JointRanges>,
    /// Which first stage was kept: the least-squares one when a physically consistent
    /// body has its base parameters, else the pseudo-inertia LMI's, with the solver's
    /// status and time; absent in older files.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub first_stage: Option<crate::consistent::ConsistencyReport>,
}

/// The `[min, max]` of one modelled joint's state over the identification data.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointRanges {
    /// Joint name.
    pub joint: String,
    /// Angle [rad].
    pub q_rad: [f64; 2],
    /// Speed [rad/s].
    pub qd_rad_s: [f64; 2],
    /// Acceleration [rad/s²].
    pub qdd_rad_s2: [f64; 2],
}

impl JointRanges {
    /// The robot crate's form.
    pub fn to_robot(&self) -> robot::IdentifiedRanges {
        robot::IdentifiedRanges {
            q_rad: self.q_rad,
            qd_rad_s: self.qd_rad_s,
            qdd_rad_s2: self.qdd_rad_s2,
        }
    }
}

impl ModelFile {
    /// Reads and checks the schema version.
    pub fn read(path: &Path) -> anyhow::Result<Self> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| anyhow::anyhow!("{}: cannot read: {e}", path.display()))?;
        let v: serde_json::Value = serde_json::from_str(&text).map_err(|e| {
            anyhow::anyhow!(
                "{}, line {}, column {}: malformed JSON: {e}",
                path.display(),
                e.line(),
                e.column()
            )
        })?;
        let ver = v.get("schema_version").and_then(|s| s.as_u64());
        if ver != Some(MODEL_SCHEMA_VERSION as u64) {
            anyhow::bail!(
                "{}, field schema_version: expected {MODEL_SCHEMA_VERSION}, found {:?}",
                path.display(),
                ver
            );
        }
        let m: Self = serde_json::from_value(v)
            .map_err(|e| anyhow::anyhow!("{}: invalid model file: {e}", path.display()))?;
        m.check_plausible()
            .map_err(|e| anyhow::anyhow!("{}, {e}", path.display()))?;
        Ok(m)
    }

    /// The plausibility layer on what a model file says (beyond its schema): the Coulomb
    /// smoothing width above zero, names without control characters.
    fn check_plausible(&self) -> anyhow::Result<()> {
        use artifacts::plausible;
        if let Some(eps) = self.model_terms.coulomb_smoothing_rad_s {
            plausible::positive(eps)
                .map_err(|m| anyhow::anyhow!("field model_terms.coulomb_smoothing_rad_s: {m}"))?;
        }
        let names = self
            .modelled_joints
            .iter()
            .chain(self.locked_joints.iter().map(|l| &l.name));
        for (k, j) in names.enumerate() {
            plausible::name(j).map_err(|m| anyhow::anyhow!("joint name {}: {m}", k + 1))?;
        }
        Ok(())
    }

    /// Writes atomically (temp file + rename), only a file that reads back to this very
    /// model: a NaN or infinite number (which JSON would write as `null`) is refused,
    /// naming the fields written as `null`, and nothing is written.
    pub fn write(&self, path: &Path) -> anyhow::Result<()> {
        let v = serde_json::to_value(self)?;
        let back: Option<Self> = serde_json::from_value(v.clone()).ok();
        if back.as_ref() != Some(self) {
            let mut nulls = Vec::new();
            null_fields(&v, String::new(), &mut nulls);
            anyhow::bail!(
                "{}: refusing to write a model with a number that is not finite (written as \
                 null, it would not read back): fields {}",
                path.display(),
                nulls.join(", ")
            );
        }
        let mut text = serde_json::to_string_pretty(&v)?;
        text.push('\n');
        write_atomic(path, text.as_bytes())
    }
}

/// The paths of the `null` values in `v` (at most 8 listed).
fn null_fields(v: &serde_json::Value, at: String, out: &mut Vec<String>) {
    match v {
        serde_json::Value::Null if out.len() < 8 => out.push(at),
        serde_json::Value::Array(a) => {
            for (k, x) in a.iter().enumerate() {
                null_fields(x, format!("{at}[{k}]"), out);
            }
        }
        serde_json::Value::Object(o) => {
            for (k, x) in o {
                let p = if at.is_empty() {
                    k.clone()
                } else {
                    format!("{at}.{k}")
                };
                null_fields(x, p, out);
            }
        }
        _ => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> ModelFile {
        ModelFile {
            schema_version: MODEL_SCHEMA_VERSION,
            robot: RobotRef {
                name: "r".into(),
                source_path: "r.urdf".into(),
                sha256: "00".into(),
                chain: ChainRef::default(),
            },
            modelled_joints: vec!["j1".into()],
            locked_joints: vec![],
            model_terms: ModelTermsRef {
                viscous_friction: true,
                coulomb_friction: true,
                friction_offset: false,
                coulomb_smoothing_rad_s: Some(0.02),
                rotor_inertia: false,
                extended_friction: false,
            },
            base_seed: 1,
            drive_gains_nm_per_a: vec![1.0],
            base_parameters: vec![BaseParameter {
                name: "a".into(),
                expression: "ZZ1".into(),
                value: 1.5,
                std: 0.1,
                relative_std_pct: 6.7,
            }],
            friction: vec![],
            condition_number: 10.0,
            condition_number_scaled: 2.0,
            weighting: "ordinary".into(),
            joint_sigma_nm: vec![1.0],
            identification_logs: vec![],
            validation_logs: vec![],
            errors: vec![],
            preprocessing: serde_json::Value::Null,
            dropped_directions: vec![crate::DroppedDirection {
                relative_singular_value: 1e-9,
                parameters: vec![("b2 = fq1".into(), 0.8), ("b1 = fv1".into(), -0.6)],
            }],
            prior: "nominal".into(),
            identification_ranges: vec![JointRanges {
                joint: "j1".into(),
                q_rad: [-1.0, 2.0],
                qd_rad_s: [-0.5, 0.5],
                qdd_rad_s2: [-3.0, 3.0],
            }],
            first_stage: Some(crate::consistent::ConsistencyReport {
                solution: "lmi".into(),
                test_status: "PrimalInfeasible".into(),
                fit_status: "Solved".into(),
                solve_time_s: 0.0,
                min_pseudo_inertia_eigenvalue_kg_m2: vec![1e-8, 0.01],
                residual_increase_sigma2: 8.5,
            }),
        }
    }

    #[test]
    fn round_trip_and_version_check() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("m.json");
        let m = sample();
        m.write(&p).unwrap();
        assert_eq!(ModelFile::read(&p).unwrap(), m);
        std::fs::write(&p, "{\"schema_version\": 99}").unwrap();
        assert!(
            ModelFile::read(&p)
                .unwrap_err()
                .to_string()
                .contains("schema_version")
        );
        // Writing into a missing directory fails and leaves nothing behind.
        let bad = d.path().join("missing/m.json");
        assert!(m.write(&bad).is_err());
        assert!(!bad.exists());
        assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 1);
    }

    #[test]
    fn a_non_finite_number_is_never_written_and_a_non_positive_smoothing_never_read() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("m.json");
        std::fs::write(&p, "the previous model\n").unwrap();
        let mut m = sample();
        m.condition_number = f64::NAN;
        m.friction = vec![JointFriction {
            joint: "j1".into(),
            viscous_nm_s_rad: Some(f64::INFINITY),
            coulomb_nm: Some(1.0),
            offset_nm: None,
        }];
        let e = m.write(&p).unwrap_err().to_string();
        assert!(
            e.contains("m.json")
                && e.contains("not finite")
                && e.contains("condition_number")
                && e.contains("friction[0].viscous_nm_s_rad"),
            "{e}"
        );
        assert_eq!(std::fs::read(&p).unwrap(), b"the previous model\n");
        for eps in [-1.0, 0.0] {
            let mut m = sample();
            m.model_terms.coulomb_smoothing_rad_s = Some(eps);
            // Written by hand (or by an older tool): refused when read.
            std::fs::write(&p, serde_json::to_string(&m).unwrap()).unwrap();
            let e = ModelFile::read(&p).unwrap_err().to_string();
            assert!(
                e.contains("m.json") && e.contains("coulomb_smoothing_rad_s"),
                "{e}"
            );
        }
        let mut m = sample();
        m.modelled_joints = vec!["j1\nj2".into()];
        std::fs::write(&p, serde_json::to_string(&m).unwrap()).unwrap();
        let e = ModelFile::read(&p).unwrap_err().to_string();
        assert!(e.contains("control character"), "{e}");
    }
}
