//! The simulated controller log and its CSV form.
//!
//! Columns (header row; SI units, radians), `j` = 1..dof:
//! - `t_s`, `q{j}_rad`, `qd{j}_rad_s`: what a real controller logs;
//! - `i{j}_a`: measured motor current after the sensing chain (noise, ADC, optional
//!   Kalman filter); `tau{j}_nm`: the same times the drive gain (measured joint torque);
//! - ground truth, never available on a real robot, all prefixed `true_`:
//!   `true_qdd{j}_rad_s2`, `true_i{j}_a` (current before sensing), `true_tau{j}_nm`
//!   (total joint-side motor torque), `true_rigid{j}_nm` (rigid body), `true_friction{j}_nm`,
//!   `true_ripple{j}_nm`, `true_rotor{j}_nm`, `true_temp{j}_c` (thermal node),
//!   `true_bristle{j}_rad` (LuGre state).
use super::drive::{DriveState, DriveTorque};
use anyhow::Context;
use std::io::Write;
use std::path::Path;

/// Column groups of the log, in CSV order: (prefix, suffix).
pub const GROUPS: [(&str, &str); 13] = [
    ("q", "_rad"),
    ("qd", "_rad_s"),
    ("i", "_a"),
    ("tau", "_nm"),
    ("true_qdd", "_rad_s2"),
    ("true_i", "_a"),
    ("true_tau", "_nm"),
    ("true_rigid", "_nm"),
    ("true_friction", "_nm"),
    ("true_ripple", "_nm"),
    ("true_rotor", "_nm"),
    ("true_temp", "_c"),
    ("true_bristle", "_rad"),
];

/// A simulated log: one row per controller sample, `GROUPS.len() * dof + 1` values.
#[derive(Debug, Clone, PartialEq)]
pub struct SimulatedLog {
    /// Number of joints.
    pub dof: usize,
    /// Joint-side torque per ampere of each drive [N*m/A].
    pub drive_gain_nm_a: Vec<f64>,
    /// Rows: `t_s` then the groups of [`GROUPS`], each `dof` wide.
    pub rows: Vec<Vec<f64>>,
}

impl SimulatedLog {
    pub(crate) fn with_capacity(dof: usize, rows: usize, drive_gain_nm_a: Vec<f64>) -> Self {
        SimulatedLog {
            dof,
            drive_gain_nm_a,
            rows: Vec::with_capacity(rows),
        }
    }

    #[allow(clippy::too_many_arguments)]
    pub(crate) fn push(
        &mut self,
        t: f64,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        measured_a: &[f64],
        current_a: &[f64],
        rigid: &[f64],
        parts: &[DriveTorque],
        state: &[DriveState],
    ) {
        let n = self.dof;
        let mut r = Vec::with_capacity(1 + GROUPS.len() * n);
        r.push(t);
        r.extend_from_slice(q);
        r.extend_from_slice(qd);
        r.extend_from_slice(measured_a);
        r.extend(
            measured_a
                .iter()
                .zip(&self.drive_gain_nm_a)
                .map(|(i, g)| i * g),
        );
        r.extend_from_slice(qdd);
        r.extend_from_slice(current_a);
        r.extend(
            current_a
                .iter()
                .zip(&self.drive_gain_nm_a)
                .map(|(i, g)| i * g),
        );
        r.extend_from_slice(rigid);
        r.extend(parts.iter().map(|p| p.friction_nm));
        r.extend(parts.iter().map(|p| p.ripple_nm));
        r.extend(parts.iter().map(|p| p.rotor_nm));
        r.extend(state.iter().map(|s| s.temperature_c));
        r.extend(state.iter().map(|s| s.bristle_rad));
        self.rows.push(r);
    }

    /// The column names, in order.
    pub fn header(&self) -> Vec<String> {
        let mut h = vec!["t_s".to_string()];
        for (p, s) in GROUPS {
            h.extend((1..=self.dof).map(|j| format!("{p}{j}{s}")));
        }
        h
    }

    /// The arguments with which `identify` and `torque` read a log of `dof` joints like a
    /// real robot's: header row, measured torque columns (1-based).
    pub fn reader_args(dof: usize) -> Vec<String> {
        let tau = GROUPS.iter().position(|(p, _)| *p == "tau").unwrap_or(0);
        let cols: Vec<String> = (0..dof).map(|j| (2 + tau * dof + j).to_string()).collect();
        [
            "--layout",
            "torque",
            "--header",
            "yes",
            "--torque-cols",
            &cols.join(","),
        ]
        .map(String::from)
        .to_vec()
    }

    /// Index of a column group (by prefix, e.g. `"tau"`), joint `j` 0-based.
    pub fn column(&self, prefix: &str, j: usize) -> Option<usize> {
        GROUPS
            .iter()
            .position(|(p, _)| *p == prefix)
            .map(|g| 1 + g * self.dof + j)
    }

    /// One column's values over time.
    pub fn series(&self, prefix: &str, j: usize) -> Vec<f64> {
        match self.column(prefix, j) {
            Some(c) => self.rows.iter().map(|r| r[c]).collect(),
            None => Vec::new(),
        }
    }

    /// Writes the CSV bytes (shortest round-trip decimal form of each value, so the file
    /// is a deterministic function of the log).
    pub fn write_csv<W: Write>(&self, mut w: W) -> std::io::Result<()> {
        writeln!(w, "{}", self.header().join(","))?;
        let mut line = String::new();
        for r in &self.rows {
            line.clear();
            for (k, v) in r.iter().enumerate() {
                if k > 0 {
                    line.push(',');
                }
                use std::fmt::Write as _;
                let _ = write!(line, "{v}");
            }
            line.push('\n');
            w.write_all(line.as_bytes())?;
        }
        Ok(())
    }

    /// Writes the CSV to `path` atomically (`model_file::write_atomic`), after checking
    /// that every value is finite (the row is named in the error).
    pub fn save(&self, path: &Path) -> anyhow::Result<()> {
        if let Some(k) = self
            .rows
            .iter()
            .position(|r| r.iter().any(|v| !v.is_finite()))
        {
            artifacts::ensure_finite(
                &format!(
                    "{}: simulated row {} (t = {} s); nothing written",
                    path.display(),
                    k + 1,
                    self.rows[k].first().copied().unwrap_or(f64::NAN)
                ),
                self.rows[k].iter().copied(),
            )?;
        }
        let mut csv = Vec::new();
        self.write_csv(&mut csv)
            .with_context(|| format!("{}: write failed", path.display()))?;
        artifacts::write_atomic(path, &csv)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reader_args_name_the_measured_torque_columns() {
        // t_s, q1..6, qd1..6, i1..6, then tau1..6 (columns 20-25, the README's layout).
        assert_eq!(
            SimulatedLog::reader_args(6),
            [
                "--layout",
                "torque",
                "--header",
                "yes",
                "--torque-cols",
                "20,21,22,23,24,25"
            ]
        );
        assert_eq!(SimulatedLog::reader_args(3)[5], "11,12,13");
    }
}
