//! The identified model as a versioned JSON file that later stages consume.
//!
//! Schema version [`MODEL_SCHEMA_VERSION`]. Files are written atomically: to a
//! temporary file in the destination directory, flushed, then renamed over the
//! destination, so a failure never leaves a partial file.

use serde::{Deserialize, Serialize};
use std::io::Write;
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
    pub fn selection(&self) -> crate::robot::ChainSelection {
        crate::robot::ChainSelection {
            base_link: self.base_link.clone(),
            tip_link: self.tip_link.clone(),
            side_joint_positions: self
                .side_joints
                .iter()
                .map(|j| (j.name.clone(), j.position_rad))
                .collect(),
        }
    }

    /// The record of a loader's selection.
    pub fn from_selection(s: &crate::robot::ChainSelection) -> Self {
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
        serde_json::from_value(v)
            .map_err(|e| anyhow::anyhow!("{}: invalid model file: {e}", path.display()))
    }

    /// Writes atomically (temp file + rename).
    pub fn write(&self, path: &Path) -> anyhow::Result<()> {
        let mut text = serde_json::to_string_pretty(self)?;
        text.push('\n');
        write_atomic(path, text.as_bytes())
    }
}

/// Refuses a command line whose outputs would replace one of its inputs or each other
/// (`identify --log run.csv -o run.csv` would destroy the log): an output that exists is
/// compared with every existing input by canonical path. Names both paths.
pub fn refuse_outputs_that_are_inputs(inputs: &[&Path], outputs: &[&Path]) -> anyhow::Result<()> {
    let canonical = |p: &Path| std::fs::canonicalize(p).ok();
    for (k, out) in outputs.iter().enumerate() {
        let Some(o) = canonical(out) else { continue };
        for input in inputs {
            if canonical(input).as_ref() == Some(&o) {
                anyhow::bail!(
                    "output {} is the input {}: refusing to replace an input",
                    out.display(),
                    input.display()
                );
            }
        }
        for other in &outputs[..k] {
            if canonical(other).as_ref() == Some(&o) {
                anyhow::bail!(
                    "outputs {} and {} are the same file",
                    other.display(),
                    out.display()
                );
            }
        }
    }
    Ok(())
}

/// An error naming `what` and the first value when any of `values` is NaN or infinite:
/// every number a command writes passes this check first (JSON would write NaN as
/// `null`, CSV as `NaN`).
pub fn ensure_finite(what: &str, values: impl IntoIterator<Item = f64>) -> anyhow::Result<()> {
    match values.into_iter().enumerate().find(|(_, v)| !v.is_finite()) {
        Some((k, v)) => anyhow::bail!("{what}: value {} is {v}, not a finite number", k + 1),
        None => Ok(()),
    }
}

/// Writes several outputs all or none: every one is staged in a temporary file beside its
/// destination (non-regular destinations refused, as in [`write_atomic`]), written and
/// fsynced before any is renamed into place, so a failure while preparing them leaves
/// every output as it was; after the renames each destination folder is fsynced, so the
/// new names survive a power cut. Files get the usual `0666` less the process umask.
pub fn write_atomic_all(files: &[(&Path, &[u8])]) -> anyhow::Result<()> {
    let mut staged = Vec::with_capacity(files.len());
    for (path, bytes) in files {
        staged.push((path, stage(path, bytes)?));
    }
    let mut dirs: Vec<&Path> = Vec::new();
    for (path, tmp) in staged {
        tmp.persist(path).map_err(|e| {
            anyhow::anyhow!("{}: cannot rename into place: {}", path.display(), e.error)
        })?;
        let dir = parent_dir(path);
        if !dirs.contains(&dir) {
            dirs.push(dir);
        }
    }
    for dir in dirs {
        sync_dir(dir)?;
    }
    Ok(())
}

/// Writes `bytes` to `path` via a temporary file in the same directory and a rename:
/// either the whole new content is there, or the old state is untouched.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    write_atomic_all(&[(path, bytes)])
}

/// The folder `path` is in (`.` for a bare file name).
fn parent_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// Makes the renames in `dir` durable (a no-op where folders cannot be opened).
fn sync_dir(dir: &Path) -> anyhow::Result<()> {
    #[cfg(unix)]
    std::fs::File::open(dir)
        .and_then(|d| d.sync_all())
        .map_err(|e| anyhow::anyhow!("{}: cannot sync the folder: {e}", dir.display()))?;
    #[cfg(not(unix))]
    let _ = dir;
    Ok(())
}

/// `bytes` in a synced temporary file beside `path` (mode `0666` less the umask, like any
/// file the user creates), ready to be renamed onto it.
fn stage(path: &Path, bytes: &[u8]) -> anyhow::Result<tempfile::NamedTempFile> {
    // Renaming over a device, a directory or a pipe would replace it (`-o /dev/null`
    // once replaced the system's null device with a file): only regular files.
    if let Ok(meta) = std::fs::metadata(path)
        && !meta.is_file()
    {
        anyhow::bail!(
            "{}: exists and is not a regular file; refusing to replace it",
            path.display()
        );
    }
    let dir = parent_dir(path);
    let mut builder = tempfile::Builder::new();
    // The temporary file would be created 0600; asking for 0666 lets the umask decide.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    let mut tmp = builder.tempfile_in(dir).map_err(|e| {
        anyhow::anyhow!(
            "{}: cannot create a temporary file in {}: {e}",
            path.display(),
            dir.display()
        )
    })?;
    tmp.write_all(bytes)
        .and_then(|_| tmp.as_file().sync_all())
        .map_err(|e| anyhow::anyhow!("{}: write failed: {e}", path.display()))?;
    Ok(tmp)
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
}
