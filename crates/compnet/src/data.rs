//! Compensation datasets: CSV logs, feature presets, contiguous splits, normalisation
//! and training windows.
//!
//! **Columns.** A log is a CSV file with a header row, one row per control tick, every
//! field a number. Presets select columns by name, for joint `j`:
//! `q_j{j}` position (rad), `qd_j{j}` velocity (rad/s), `tau_meas_j{j}` measured torque
//! (N·m), `tau_model_j{j}` the identified model's torque (N·m).
//! - `paper`: inputs `tau_model_j*`, `tau_meas_j*`, `q_j*` (all joints of one kind, then
//!   the next kind) → target `tau_meas_j*` one step ahead; model-only prediction
//!   `tau_model_j*` at that step; persistence baseline `tau_meas_j*` now.
//! - `paper_relative` (`--preset paper_relative`): the same with the measured residual
//!   `tau_meas_j*-tau_model_j*` in place of `tau_meas_j*` → target the residual
//!   `tau_meas_j* - tau_model_j*` one step ahead ([`FeatureSpec::paper_relative`]): the
//!   model's torque at t+1 is added back, so a network that knows nothing returns the
//!   model, and its inputs keep the scale of the residual, not of the joint's torque.
//! - `paper --paper-output increment` ([`FeatureSpec::paper_increment`]): the `paper`
//!   inputs, the next-step torque as the measured torque now plus the network's
//!   increment (a residual connection). It beats persistence in open loop but, fed
//!   forward, closes a unit-gain loop on the applied torque that destabilised the
//!   closed-loop simulation (measured, docs/studies/sil-paper-network.md), so the exporter refuses it.
//! - `feedforward`: inputs `tau_model_j*`, `q_j*`, `qd_j*` → target the residual
//!   `tau_meas_j* - tau_model_j*` at the same step; model-only prediction 0.
//! - `drive`: what the drive knows before the tick, per joint (`firmware::features`):
//!   `sin_q_j*`, `cos_q_j*`, `qd_j*`, `qdd_j*`, `tau_model_j*` (the first stage),
//!   `rest_dir_j*`, the presliding states `slip_*_j*`, and the residual measured over the
//!   previous tick `tau_resid_prev_j*` (derived from the previous row when a dataset does
//!   not store it, [`Table::input_column`]) → target the residual
//!   `tau_meas_j* - tau_model_j*` at the same step; model-only prediction 0. Angles enter
//!   as sine and cosine, so poses outside the training range stay in distribution.
//! - `custom`: `--inputs a,b,c --targets y1,y2-z2 --shift k`: a target is a column or a
//!   difference `col-col`, taken `k` steps ahead; model-only prediction 0.
use anyhow::{Context, Result, bail};
use firmware::features;
use firmware::nn::format::FeaturePreset;
use std::path::{Path, PathBuf};

/// A CSV log: named columns of equal length.
#[derive(Clone, Debug)]
pub struct Table {
    /// Where it was read from.
    pub path: PathBuf,
    /// Column names.
    pub names: Vec<String>,
    /// Column values.
    pub columns: Vec<Vec<f32>>,
}

impl Table {
    /// Reads a CSV file with a header; any unparsable or non-finite field is an error
    /// naming the file, line and column.
    pub fn read(path: &Path) -> Result<Table> {
        let mut rdr = csv::ReaderBuilder::new()
            .trim(csv::Trim::All)
            .from_path(path)
            .with_context(|| format!("opening {}", path.display()))?;
        let names: Vec<String> = rdr
            .headers()
            .with_context(|| format!("{}: header", path.display()))?
            .iter()
            .map(String::from)
            .collect();
        let mut columns = vec![Vec::new(); names.len()];
        for (n, rec) in rdr.records().enumerate() {
            let line = n + 2;
            let rec = rec.with_context(|| format!("{}:{line}", path.display()))?;
            if rec.len() != names.len() {
                bail!(
                    "{}:{line}: {} fields, the header has {}",
                    path.display(),
                    rec.len(),
                    names.len()
                );
            }
            for (k, field) in rec.iter().enumerate() {
                let v: f32 = field
                    .parse()
                    .ok()
                    .filter(|v: &f32| v.is_finite())
                    .with_context(|| {
                        format!(
                            "{}:{line}: column `{}`: `{field}` is not a finite number",
                            path.display(),
                            names[k]
                        )
                    })?;
                columns[k].push(v);
            }
        }
        Ok(Table {
            path: path.to_path_buf(),
            names,
            columns,
        })
    }

    /// A column by name, or an error naming the file and what exists.
    pub fn column(&self, name: &str) -> Result<&[f32]> {
        match self.names.iter().position(|n| n == name) {
            Some(k) => Ok(&self.columns[k]),
            None => bail!(
                "{}: no column `{name}` (columns: {})",
                self.path.display(),
                self.names.join(", ")
            ),
        }
    }

    /// A column by name; when the table has no such column, two derived inputs (in f32,
    /// as the firmware computes them): for a name `a-b` the difference of two columns
    /// (the `paper_relative` preset's measured residual `tau_meas_j1-tau_model_j1`), and
    /// for `tau_resid_prev_j<N>` ([`features::MEASURED_RESIDUAL_COLUMN`], the `drive`
    /// preset's) the residual `tau_meas_j<N> - tau_model_j<N>` of the previous row (the
    /// first row's own).
    pub fn input_column(&self, name: &str) -> Result<std::borrow::Cow<'_, [f32]>> {
        if self.names.iter().any(|n| n == name) {
            return self.column(name).map(Into::into);
        }
        let difference = |a: &str, b: &str| -> Result<Vec<f32>> {
            let (a, b) = (self.column(a)?, self.column(b)?);
            Ok(a.iter().zip(b).map(|(a, b)| a - b).collect())
        };
        let lagged = name
            .strip_prefix(features::MEASURED_RESIDUAL_COLUMN)
            .and_then(|j| j.strip_prefix("_j"));
        if let Some(j) = lagged {
            let r = difference(&format!("tau_meas_j{j}"), &format!("tau_model_j{j}"))?;
            let previous = r.first().into_iter().chain(&r).take(r.len());
            return Ok(previous.copied().collect::<Vec<_>>().into());
        }
        match name.split_once('-') {
            Some((a, b)) => Ok(difference(a, b)?.into()),
            None => self.column(name).map(Into::into),
        }
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.columns.first().map_or(0, Vec::len)
    }

    /// True without rows.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// One output of the network.
#[derive(Clone, Debug, PartialEq)]
pub struct TargetSpec {
    /// Column whose value is predicted.
    pub column: String,
    /// Column subtracted from it (residual targets).
    pub minus: Option<String>,
    /// Subtract `minus` at the input step `t` (an increment over a known input) instead
    /// of at `t + shift`.
    pub minus_now: bool,
    /// Steps ahead (`paper`: 1).
    pub shift: usize,
    /// Column that is the identified model's prediction of the target (same step);
    /// `None`: the model-only prediction is 0 (a residual).
    pub model_only: Option<String>,
}

impl TargetSpec {
    /// Display name (`col`, `col-minus`, with `@+k` when shifted; `col@+k-minus@0` for an
    /// increment over the input step).
    pub fn name(&self) -> String {
        if let (true, Some(m)) = (self.minus_now, &self.minus) {
            return format!("{}@+{}-{m}@0", self.column, self.shift);
        }
        let base = match &self.minus {
            Some(m) => format!("{}-{m}", self.column),
            None => self.column.clone(),
        };
        if self.shift > 0 {
            format!("{base}@+{}", self.shift)
        } else {
            base
        }
    }
}

/// Whether an output name is a future torque as an increment over the measured torque
/// now (`col@+k-minus@0`, `paper --paper-output increment`): it closes a unit-gain loop
/// on the applied torque when fed forward.
pub fn is_increment_name(name: &str) -> bool {
    name.contains("@+") && name.ends_with("@0")
}

/// Which columns go in and what comes out.
#[derive(Clone, Debug, PartialEq)]
pub struct FeatureSpec {
    /// `paper`, `feedforward` or `custom`.
    pub preset: String,
    /// Input columns, in input order.
    pub inputs: Vec<String>,
    /// Targets, in output order.
    pub targets: Vec<TargetSpec>,
}

impl FeatureSpec {
    /// The `paper` preset for `joints` (see module docs).
    pub fn paper(joints: &[usize]) -> Self {
        let mut inputs = Vec::new();
        for kind in ["tau_model", "tau_meas", "q"] {
            inputs.extend(joints.iter().map(|j| format!("{kind}_j{j}")));
        }
        let targets = joints
            .iter()
            .map(|j| TargetSpec {
                column: format!("tau_meas_j{j}"),
                minus: None,
                minus_now: false,
                shift: 1,
                model_only: Some(format!("tau_model_j{j}")),
            })
            .collect();
        FeatureSpec {
            preset: "paper".into(),
            inputs,
            targets,
        }
    }

    /// The `paper` preset's open-loop variant: the same inputs, the next-step torque
    /// predicted as the measured torque now plus the network's increment (a residual
    /// connection). It beats persistence in open loop but is not for feedforward (module
    /// docs), so the exporter refuses it.
    pub fn paper_increment(joints: &[usize]) -> Self {
        let mut spec = Self::paper(joints);
        for t in &mut spec.targets {
            t.minus = Some(t.column.clone());
            t.minus_now = true;
        }
        spec
    }

    /// The `paper` preset relative to the model (`paper_relative`): the measured residual
    /// `tau_meas - tau_model` in place of the measured torque, the next-step torque
    /// predicted as the model's torque at that step plus the network's residual (module
    /// docs): a network that knows nothing returns the model.
    pub fn paper_relative(joints: &[usize]) -> Self {
        let mut spec = Self::paper(joints);
        spec.preset = FeaturePreset::PaperRelative.name().into();
        for (input, j) in spec.inputs[joints.len()..2 * joints.len()]
            .iter_mut()
            .zip(joints)
        {
            *input = format!("tau_meas_j{j}-tau_model_j{j}");
        }
        for t in &mut spec.targets {
            t.minus.clone_from(&t.model_only);
        }
        spec
    }

    /// The `feedforward` preset for `joints` (see module docs).
    pub fn feedforward(joints: &[usize]) -> Self {
        Self::residual("feedforward", &["tau_model", "q", "qd"], joints)
    }

    /// The `drive` preset for `joints` (see module docs).
    pub fn drive(joints: &[usize]) -> Self {
        Self::residual("drive", &features::DRIVE_COLUMNS, joints)
    }

    /// The spec of a named preset (`paper`, `feedforward`, `drive`) for `joints`; `None`
    /// for `custom` and unknown names.
    pub fn for_preset(preset: &str, joints: &[usize]) -> Option<Self> {
        match preset {
            "paper" => Some(Self::paper(joints)),
            "paper_relative" => Some(Self::paper_relative(joints)),
            "feedforward" => Some(Self::feedforward(joints)),
            "drive" => Some(Self::drive(joints)),
            _ => None,
        }
    }

    /// A preset whose inputs are `kinds` (all joints of one kind, then the next) and whose
    /// targets are the residuals over the model torque at the same step.
    fn residual(preset: &str, kinds: &[&str], joints: &[usize]) -> Self {
        let mut inputs = Vec::new();
        for kind in kinds {
            inputs.extend(joints.iter().map(|j| format!("{kind}_j{j}")));
        }
        let targets = joints
            .iter()
            .map(|j| TargetSpec {
                column: format!("tau_meas_j{j}"),
                minus: Some(format!("tau_model_j{j}")),
                minus_now: false,
                shift: 0,
                model_only: None,
            })
            .collect();
        FeatureSpec {
            preset: preset.into(),
            inputs,
            targets,
        }
    }

    /// A `custom` spec: targets are `col` or `col-col`, all `shift` steps ahead.
    pub fn custom(inputs: &[String], targets: &[String], shift: usize) -> Result<Self> {
        if inputs.is_empty() || targets.is_empty() {
            bail!("a custom feature spec needs at least one input and one target column");
        }
        let targets = targets
            .iter()
            .map(|t| {
                let (column, minus) = match t.split_once('-') {
                    Some((a, b)) => (a.to_string(), Some(b.to_string())),
                    None => (t.clone(), None),
                };
                TargetSpec {
                    column,
                    minus,
                    minus_now: false,
                    shift,
                    model_only: None,
                }
            })
            .collect();
        Ok(FeatureSpec {
            preset: "custom".into(),
            inputs: inputs.to_vec(),
            targets,
        })
    }

    /// Output names as stored in the model.
    pub fn output_names(&self) -> Vec<String> {
        self.targets.iter().map(TargetSpec::name).collect()
    }

    /// Checks a model was trained for this spec (same preset, inputs and outputs).
    pub fn check_model(&self, m: &super::LstmModel) -> Result<()> {
        if m.input_names != self.inputs || m.output_names != self.output_names() {
            bail!(
                "the model's features (preset `{}`: inputs [{}] -> outputs [{}]) do not match the data's \
                 (preset `{}`: inputs [{}] -> outputs [{}])",
                m.preset,
                m.input_names.join(", "),
                m.output_names.join(", "),
                self.preset,
                self.inputs.join(", "),
                self.output_names().join(", ")
            );
        }
        Ok(())
    }

    /// Extracts the aligned sequence from a table: row `t` holds the inputs at `t` and
    /// the targets at `t + shift`; rows without a target are dropped.
    pub fn sequence(&self, table: &Table) -> Result<Sequence> {
        let max_shift = self.targets.iter().map(|t| t.shift).max().unwrap_or(0);
        let n = table.len().saturating_sub(max_shift);
        let ins: Vec<_> = self
            .inputs
            .iter()
            .map(|c| table.input_column(c))
            .collect::<Result<_>>()?;
        let mut tcols = Vec::new();
        for t in &self.targets {
            let a = table.column(&t.column)?;
            let b = t.minus.as_deref().map(|m| table.column(m)).transpose()?;
            let mo = t
                .model_only
                .as_deref()
                .map(|m| table.column(m))
                .transpose()?;
            tcols.push((t, a, b, mo));
        }
        let mut s = Sequence::default();
        for row in 0..n {
            s.inputs.push(ins.iter().map(|c| c[row]).collect());
            let mut y = Vec::new();
            let mut mo_row = Vec::new();
            let mut pers = Vec::new();
            let mut offset = Vec::new();
            for (spec, a, b, mo) in &tcols {
                let k = row + spec.shift;
                let base = b.map_or(0.0, |b| if spec.minus_now { b[row] } else { b[k] });
                y.push(a[k] - base);
                // The model's prediction of the target (0 for a residual without one).
                mo_row.push(mo.map_or(0.0, |m| m[k] - base));
                // Persistence: the target's column now, in the target's terms (defined
                // for a shifted target that the model predicts).
                let persistent = spec.shift > 0 && spec.model_only.is_some();
                pers.push(persistent.then(|| a[row] - base));
                offset.push(base);
            }
            s.targets.push(y);
            s.model_only.push(mo_row);
            s.persistence.push(pers);
            s.offset.push(offset);
        }
        Ok(s)
    }
}

/// An aligned sequence of inputs and targets (raw units).
#[derive(Clone, Debug, Default)]
pub struct Sequence {
    /// Inputs per step.
    pub inputs: Vec<Vec<f32>>,
    /// Targets per step.
    pub targets: Vec<Vec<f32>>,
    /// The identified model's prediction of each target (0 for residuals).
    pub model_only: Vec<Vec<f32>>,
    /// Persistence prediction (the target's column now) where it is defined.
    pub persistence: Vec<Vec<Option<f32>>>,
    /// What was subtracted from each target's column (an increment's base, a residual's
    /// model torque; 0 otherwise): the column's value is `target + offset`.
    pub offset: Vec<Vec<f32>>,
}

impl Sequence {
    /// Number of steps.
    pub fn len(&self) -> usize {
        self.inputs.len()
    }

    /// True without steps.
    pub fn is_empty(&self) -> bool {
        self.inputs.is_empty()
    }

    /// Steps `range` as a new sequence.
    pub fn slice(&self, range: std::ops::Range<usize>) -> Sequence {
        Sequence {
            inputs: self.inputs[range.clone()].to_vec(),
            targets: self.targets[range.clone()].to_vec(),
            model_only: self.model_only[range.clone()].to_vec(),
            persistence: self.persistence[range.clone()].to_vec(),
            offset: self.offset[range].to_vec(),
        }
    }

    /// Contiguous train / validation / test blocks, in time order, never shuffled.
    pub fn split(
        &self,
        val_fraction: f64,
        test_fraction: f64,
    ) -> Result<(Sequence, Sequence, Sequence)> {
        if !(0.0..1.0).contains(&val_fraction)
            || !(0.0..1.0).contains(&test_fraction)
            || val_fraction + test_fraction >= 1.0
        {
            bail!(
                "validation ({val_fraction}) and test ({test_fraction}) fractions must be in [0, 1) and sum below 1"
            );
        }
        let n = self.len();
        let n_test = (n as f64 * test_fraction).round() as usize;
        let n_val = (n as f64 * val_fraction).round() as usize;
        let n_train = n - n_test - n_val;
        Ok((
            self.slice(0..n_train),
            self.slice(n_train..n_train + n_val),
            self.slice(n_train + n_val..n),
        ))
    }
}

/// Mean and standard deviation per column of `rows` (std floored at 1e-6 of the
/// column's magnitude scale, and at 1e-12, so constant columns stay finite).
pub fn mean_std(rows: &[Vec<f32>]) -> (Vec<f32>, Vec<f32>) {
    let d = rows.first().map_or(0, Vec::len);
    let n = rows.len().max(1) as f64;
    let mut mean = vec![0.0f64; d];
    for r in rows {
        for k in 0..d {
            mean[k] += r[k] as f64 / n;
        }
    }
    let mut var = vec![0.0f64; d];
    for r in rows {
        for k in 0..d {
            var[k] += (r[k] as f64 - mean[k]).powi(2) / n;
        }
    }
    let std = var
        .iter()
        .zip(&mean)
        .map(|(v, m)| v.sqrt().max(1e-6 * m.abs()).max(1e-12) as f32)
        .collect();
    (mean.into_iter().map(|m| m as f32).collect(), std)
}
