//! Robot logs: reading CSV files and ROS 2 recordings (rosbag2 MCAP, [`rosbag`]) into
//! joint signals, and preprocessing them into
//! identification samples (uniform resampling, zero-phase filtering, derivatives,
//! trimming of rest periods, optional Kalman filtering of the motor current).
//!
//! Column layout defaults (the UR10e preset, [`LogLayout::ur10e`]): no header;
//! column 1 = time [s], 2..7 = q [rad], 8..13 = q̇ [rad/s], 14..19 = motor current [A]
//! (then × drive gain per joint); further columns are ignored.
//!
//! Every error names the file, the 1-based line and the field (column name or
//! 1-based index) it concerns.
#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod preprocess;
pub mod rosbag;
pub mod signal;

use sha2::{Digest, Sha256};
use std::fmt;
use std::path::{Path, PathBuf};

pub use preprocess::{
    MAX_GAP_GRID_STEPS, MAX_GRID_SAMPLES, PreprocessOptions, Samples, preprocess,
};
pub use rosbag::{BagOptions, TimeSource};

/// One column of a log: by header name or by 1-based index.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ColumnRef {
    /// A header name (requires a header row).
    Name(String),
    /// A 1-based column index.
    Index(usize),
}

impl ColumnRef {
    /// Parses `"3"` as an index and anything else as a name.
    pub fn parse(s: &str) -> Self {
        match s.trim().parse::<usize>() {
            Ok(i) => ColumnRef::Index(i),
            Err(_) => ColumnRef::Name(s.trim().to_string()),
        }
    }
}

impl fmt::Display for ColumnRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ColumnRef::Name(n) => write!(f, "column '{n}'"),
            ColumnRef::Index(i) => write!(f, "column {i}"),
        }
    }
}

/// What the effort columns hold.
#[derive(Debug, Clone, PartialEq)]
pub enum Effort {
    /// Joint torques [N·m].
    TorqueNm(Vec<ColumnRef>),
    /// Motor currents [A]; joint torque = current × drive gain [N·m/A] per joint.
    CurrentA {
        /// Current columns, one per joint.
        columns: Vec<ColumnRef>,
        /// Drive gains [N·m/A], one per joint.
        drive_gains_nm_per_a: Vec<f64>,
    },
}

/// Which columns of a log hold which signal.
#[derive(Debug, Clone, PartialEq)]
pub struct LogLayout {
    /// `Some(true)`: first row is a header; `Some(false)`: no header; `None`: detect
    /// (the first row is a header if any of its cells is not a number).
    pub header: Option<bool>,
    /// Time column [s].
    pub time: ColumnRef,
    /// Joint position columns [rad], one per joint.
    pub q: Vec<ColumnRef>,
    /// Joint velocity columns [rad/s] (optional; otherwise differentiated from q).
    pub qd: Option<Vec<ColumnRef>>,
    /// Joint acceleration columns [rad/s²] (optional; otherwise differentiated).
    pub qdd: Option<Vec<ColumnRef>>,
    /// Torque or current columns (optional for state-only files).
    pub effort: Option<Effort>,
    /// Number of data rows to skip after the header (corrupt rows at the start of a log).
    pub skip_rows: usize,
}

/// Drive gains [N·m/A] of the UR10e estimated by the dataset's authors, joints 1..6.
pub const UR10E_DRIVE_GAINS_NM_PER_A: [f64; 6] = [10.0, 10.6956, 8.4566, 9.0029, 9.48, 10.1232];

impl LogLayout {
    /// The UR10e layout of `shared/datasets/ur10e`: no header, time, q1..6, qd1..6,
    /// i1..6 (× [`UR10E_DRIVE_GAINS_NM_PER_A`]); optional further columns ignored.
    pub fn ur10e() -> Self {
        Self::sequential(6, true, true, Some(UR10E_DRIVE_GAINS_NM_PER_A.to_vec()))
    }

    /// Time in column 1, then `n` positions, then (if `with_qd`) `n` velocities, then
    /// (if `with_effort`) `n` efforts: currents if `gains` is given, torques otherwise.
    pub fn sequential(n: usize, with_qd: bool, with_effort: bool, gains: Option<Vec<f64>>) -> Self {
        let idx = |start: usize| (start..start + n).map(ColumnRef::Index).collect::<Vec<_>>();
        let q = idx(2);
        let qd = with_qd.then(|| idx(2 + n));
        let e0 = 2 + n + if with_qd { n } else { 0 };
        let effort = with_effort.then(|| match gains {
            Some(g) => Effort::CurrentA {
                columns: idx(e0),
                drive_gains_nm_per_a: g,
            },
            None => Effort::TorqueNm(idx(e0)),
        });
        Self {
            header: Some(false),
            time: ColumnRef::Index(1),
            q,
            qd,
            qdd: None,
            effort,
            skip_rows: 0,
        }
    }

    /// Number of joints in the log.
    pub fn n_joints(&self) -> usize {
        self.q.len()
    }
}

/// A log read from a CSV file: raw signals per joint, one entry per row.
#[derive(Debug, Clone)]
pub struct RawLog {
    /// The file it came from.
    pub path: PathBuf,
    /// SHA-256 of the file's bytes, lowercase hex.
    pub sha256: String,
    /// Time stamps [s], strictly increasing.
    pub time_s: Vec<f64>,
    /// Positions [rad], `q_rad[joint][sample]`.
    pub q_rad: Vec<Vec<f64>>,
    /// Velocities [rad/s] if logged.
    pub qd_rad_s: Option<Vec<Vec<f64>>>,
    /// Accelerations [rad/s²] if logged.
    pub qdd_rad_s2: Option<Vec<Vec<f64>>>,
    /// Motor currents [A] if the effort columns are currents.
    pub current_a: Option<Vec<Vec<f64>>>,
    /// Drive gains [N·m/A] used when the effort columns are currents.
    pub drive_gains_nm_per_a: Option<Vec<f64>>,
    /// Joint torques [N·m] (currents × drive gains, or logged torques).
    pub torque_nm: Option<Vec<Vec<f64>>>,
    /// 1-based file line of each sample (for error messages after reading; a bag's
    /// message number on its topic).
    pub lines: Vec<u64>,
    /// What reading did beyond the plain case (publishers merged or dropped), one
    /// sentence each naming the file, for the user.
    pub notes: Vec<String>,
}

impl RawLog {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.time_s.len()
    }
    /// True when the log has no samples.
    pub fn is_empty(&self) -> bool {
        self.time_s.is_empty()
    }
}

/// An error reading a log: always names the file, and the line and field when known.
#[derive(Debug, Clone, PartialEq)]
pub struct LogError {
    /// The file.
    pub path: PathBuf,
    /// 1-based line, if the error concerns one.
    pub line: Option<u64>,
    /// The field (column), if the error concerns one.
    pub field: Option<String>,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for LogError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.path.display())?;
        if let Some(l) = self.line {
            write!(f, ", line {l}")?;
        }
        if let Some(c) = &self.field {
            write!(f, ", {c}")?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for LogError {}

impl LogError {
    fn new(
        path: &Path,
        line: Option<u64>,
        field: Option<String>,
        message: impl Into<String>,
    ) -> Self {
        Self {
            path: path.to_path_buf(),
            line,
            field,
            message: message.into(),
        }
    }
}

/// SHA-256 of a file's bytes, lowercase hex.
pub fn sha256_file(path: &Path) -> std::io::Result<String> {
    let bytes = std::fs::read(path)?;
    Ok(sha256_hex(&bytes))
}

/// SHA-256 of bytes, lowercase hex.
pub fn sha256_hex(bytes: &[u8]) -> String {
    let digest = Sha256::digest(bytes);
    digest.iter().map(|b| format!("{b:02x}")).collect()
}

/// Reads a robot log: a ROS 2 recording (a rosbag2 folder, an MCAP or `.db3` file, by
/// extension or content: see [`rosbag::is_bag`]) with `bag`, its joints matched by name to `joint_names` (the
/// robot's joints, in order), or a CSV file with `layout`.
pub fn read_robot_log(
    path: &Path,
    layout: &LogLayout,
    bag: &BagOptions,
    joint_names: &[String],
) -> Result<RawLog, LogError> {
    if rosbag::is_bag(path) {
        rosbag::read_bag(path, bag, joint_names)
    } else {
        if layout.n_joints() != joint_names.len() {
            return Err(LogError::new(
                path,
                None,
                None,
                format!(
                    "the log layout has {} joints but the robot has {} (use --log-joints)",
                    layout.n_joints(),
                    joint_names.len()
                ),
            ));
        }
        read_log(path, layout)
    }
}

/// Reads a CSV log with the given layout. Rejects malformed rows, non-finite cells,
/// non-increasing time and missing columns, naming file, line and field.
pub fn read_log(path: &Path, layout: &LogLayout) -> Result<RawLog, LogError> {
    let bytes = std::fs::read(path)
        .map_err(|e| LogError::new(path, None, None, format!("cannot read: {e}")))?;
    let sha256 = sha256_hex(&bytes);
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .trim(csv::Trim::All)
        .from_reader(bytes.as_slice());
    let mut records = reader.records();

    // First record: header or data.
    let first = match records.next() {
        None => return Err(LogError::new(path, None, None, "empty file: no rows")),
        Some(r) => r.map_err(|e| csv_error(path, e))?,
    };
    let first_is_header = match layout.header {
        Some(h) => h,
        None => first
            .iter()
            .any(|c| !c.is_empty() && c.parse::<f64>().is_err()),
    };
    let header: Option<Vec<String>> =
        first_is_header.then(|| first.iter().map(str::to_string).collect());
    let header_line = first.position().map(|p| p.line()).unwrap_or(1);

    // Resolve column references to 0-based indices; `width` = number of columns.
    let width_hint = header.as_ref().map(|h| h.len()).unwrap_or(first.len());
    let resolve = |c: &ColumnRef, role: &str| -> Result<(usize, String), LogError> {
        match c {
            ColumnRef::Index(0) => Err(LogError::new(
                path,
                None,
                Some(role.to_string()),
                "column indices are 1-based; 0 is not a column",
            )),
            ColumnRef::Index(i) => {
                let label = match &header {
                    Some(h) if *i <= h.len() => format!("column {i} ('{}', {role})", h[i - 1]),
                    _ => format!("column {i} ({role})"),
                };
                Ok((i - 1, label))
            }
            ColumnRef::Name(n) => match &header {
                None => Err(LogError::new(
                    path,
                    Some(header_line),
                    Some(format!("column '{n}' ({role})")),
                    "columns named but the file has no header row (use 1-based indices)",
                )),
                Some(h) => h
                    .iter()
                    .position(|x| x == n)
                    .map(|i| (i, format!("column {} ('{n}', {role})", i + 1)))
                    .ok_or_else(|| {
                        LogError::new(
                            path,
                            Some(header_line),
                            Some(format!("column '{n}' ({role})")),
                            format!("missing column: header has {}", h.join(",")),
                        )
                    }),
            },
        }
    };
    let n = layout.n_joints();
    if n == 0 {
        return Err(LogError::new(
            path,
            None,
            None,
            "layout names no position columns",
        ));
    }
    let group = |cols: &[ColumnRef], role: &str| -> Result<Vec<(usize, String)>, LogError> {
        if cols.len() != n {
            return Err(LogError::new(
                path,
                None,
                Some(role.to_string()),
                format!("{} columns given for {n} joints", cols.len()),
            ));
        }
        cols.iter()
            .enumerate()
            .map(|(j, c)| resolve(c, &format!("{role}{}", j + 1)))
            .collect()
    };
    let time_col = resolve(&layout.time, "time")?;
    let q_cols = group(&layout.q, "q")?;
    let qd_cols = layout.qd.as_ref().map(|c| group(c, "qd")).transpose()?;
    let qdd_cols = layout.qdd.as_ref().map(|c| group(c, "qdd")).transpose()?;
    let (effort_cols, gains, is_current) = match &layout.effort {
        None => (None, None, false),
        Some(Effort::TorqueNm(c)) => (Some(group(c, "tau")?), None, false),
        Some(Effort::CurrentA {
            columns,
            drive_gains_nm_per_a,
        }) => {
            if drive_gains_nm_per_a.len() != n {
                return Err(LogError::new(
                    path,
                    None,
                    Some("drive gains".into()),
                    format!(
                        "{} drive gains given for {n} joints",
                        drive_gains_nm_per_a.len()
                    ),
                ));
            }
            (
                Some(group(columns, "i")?),
                Some(drive_gains_nm_per_a.clone()),
                true,
            )
        }
    };
    let _ = width_hint;

    let mut out = RawLog {
        path: path.to_path_buf(),
        sha256,
        time_s: Vec::new(),
        q_rad: vec![Vec::new(); n],
        qd_rad_s: qd_cols.as_ref().map(|_| vec![Vec::new(); n]),
        qdd_rad_s2: qdd_cols.as_ref().map(|_| vec![Vec::new(); n]),
        current_a: is_current.then(|| vec![Vec::new(); n]),
        drive_gains_nm_per_a: gains.clone(),
        torque_nm: effort_cols.as_ref().map(|_| vec![Vec::new(); n]),
        lines: Vec::new(),
        notes: Vec::new(),
    };

    let mut pending_first = if first_is_header { None } else { Some(first) };
    let mut skipped = 0usize;
    let mut prev_t: Option<(f64, u64)> = None;
    loop {
        let rec = match pending_first.take() {
            Some(r) => r,
            None => match records.next() {
                None => break,
                Some(r) => r.map_err(|e| csv_error(path, e))?,
            },
        };
        let line = rec.position().map(|p| p.line()).unwrap_or(0);
        if rec.iter().all(|c| c.is_empty()) {
            continue; // blank line
        }
        if skipped < layout.skip_rows {
            skipped += 1;
            continue;
        }
        let cell = |(idx, label): &(usize, String)| -> Result<f64, LogError> {
            let s = rec.get(*idx).ok_or_else(|| {
                LogError::new(
                    path,
                    Some(line),
                    Some(label.clone()),
                    format!("missing column: the row has only {} fields", rec.len()),
                )
            })?;
            let v: f64 = s.parse().map_err(|_| {
                LogError::new(
                    path,
                    Some(line),
                    Some(label.clone()),
                    format!("not a number: '{s}'"),
                )
            })?;
            if !v.is_finite() {
                return Err(LogError::new(
                    path,
                    Some(line),
                    Some(label.clone()),
                    format!("non-finite value '{s}'"),
                ));
            }
            Ok(v)
        };
        let t = cell(&time_col)?;
        if let Some((tp, lp)) = prev_t
            && t <= tp
        {
            return Err(LogError::new(
                path,
                Some(line),
                Some(time_col.1.clone()),
                format!("time not strictly increasing: {t} after {tp} on line {lp}"),
            ));
        }
        prev_t = Some((t, line));
        out.time_s.push(t);
        out.lines.push(line);
        for (j, c) in q_cols.iter().enumerate() {
            out.q_rad[j].push(cell(c)?);
        }
        if let (Some(cols), Some(dst)) = (&qd_cols, out.qd_rad_s.as_mut()) {
            for (j, c) in cols.iter().enumerate() {
                dst[j].push(cell(c)?);
            }
        }
        if let (Some(cols), Some(dst)) = (&qdd_cols, out.qdd_rad_s2.as_mut()) {
            for (j, c) in cols.iter().enumerate() {
                dst[j].push(cell(c)?);
            }
        }
        if let (Some(cols), Some(dst)) = (&effort_cols, out.torque_nm.as_mut()) {
            for (j, c) in cols.iter().enumerate() {
                let v = cell(c)?;
                match (&gains, out.current_a.as_mut()) {
                    (Some(g), Some(cur)) => {
                        cur[j].push(v);
                        dst[j].push(v * g[j]);
                    }
                    _ => dst[j].push(v),
                }
            }
        }
    }
    Ok(out)
}

fn csv_error(path: &Path, e: csv::Error) -> LogError {
    let line = e.position().map(|p| p.line());
    LogError::new(path, line, None, format!("malformed CSV: {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    fn write(dir: &tempfile::TempDir, name: &str, text: &str) -> PathBuf {
        let p = dir.path().join(name);
        std::fs::File::create(&p)
            .unwrap()
            .write_all(text.as_bytes())
            .unwrap();
        p
    }

    fn layout2() -> LogLayout {
        LogLayout::sequential(2, false, true, Some(vec![2.0, 3.0]))
    }

    #[test]
    fn reads_headerless_and_scales_current() {
        let d = tempfile::tempdir().unwrap();
        let p = write(&d, "a.csv", "0.0,1,2,0.5,1\n0.01,1.1,2.1,0.25,2\n");
        let log = read_log(&p, &layout2()).unwrap();
        assert_eq!(log.len(), 2);
        assert_eq!(log.q_rad[1], vec![2.0, 2.1]);
        assert_eq!(log.torque_nm.as_ref().unwrap()[0], vec![1.0, 0.5]);
        assert_eq!(log.torque_nm.as_ref().unwrap()[1], vec![3.0, 6.0]);
        assert_eq!(
            log.sha256,
            sha256_hex(b"0.0,1,2,0.5,1\n0.01,1.1,2.1,0.25,2\n")
        );
    }

    #[test]
    fn columns_by_name_with_detected_header() {
        let d = tempfile::tempdir().unwrap();
        let p = write(&d, "h.csv", "t,a,b,ta,tb\n0,1,2,3,4\n1,1,2,3,5\n");
        let layout = LogLayout {
            header: None,
            time: ColumnRef::parse("t"),
            q: vec![ColumnRef::parse("a"), ColumnRef::parse("b")],
            qd: None,
            qdd: None,
            effort: Some(Effort::TorqueNm(vec![
                ColumnRef::parse("ta"),
                ColumnRef::parse("5"),
            ])),
            skip_rows: 0,
        };
        let log = read_log(&p, &layout).unwrap();
        assert_eq!(log.torque_nm.unwrap()[1], vec![4.0, 5.0]);
        assert_eq!(log.lines, vec![2, 3]);
    }

    #[test]
    fn errors_name_file_line_and_field() {
        let d = tempfile::tempdir().unwrap();
        let p = write(&d, "nan.csv", "0,1,2,3,4\n0.1,1,NaN,3,4\n");
        let e = read_log(&p, &layout2()).unwrap_err();
        assert_eq!(e.line, Some(2));
        assert!(
            e.to_string().contains("nan.csv, line 2, column 3 (q2)"),
            "{e}"
        );

        let p = write(&d, "mono.csv", "0,1,2,3,4\n0.2,1,2,3,4\n0.1,1,2,3,4\n");
        let e = read_log(&p, &layout2()).unwrap_err();
        assert!(
            e.to_string().contains("line 3, column 1 (time)") && e.message.contains("increasing"),
            "{e}"
        );

        let p = write(&d, "short.csv", "0,1,2,3,4\n0.2,1,2,3\n");
        let e = read_log(&p, &layout2()).unwrap_err();
        assert!(
            e.to_string().contains("line 2, column 5 (i2)") && e.message.contains("missing"),
            "{e}"
        );

        let p = write(&d, "text.csv", "0,1,2,3,4\n0.2,1,x,3,4\n");
        let e = read_log(&p, &layout2()).unwrap_err();
        assert!(
            e.to_string()
                .contains("line 2, column 3 (q2): not a number: 'x'"),
            "{e}"
        );

        let p = write(&d, "hdr.csv", "t,a\n0,1\n");
        let mut l = layout2();
        l.header = Some(true);
        l.time = ColumnRef::Name("time".into());
        let e = read_log(&p, &l).unwrap_err();
        assert!(
            e.to_string().contains("column 'time' (time)") && e.message.contains("missing column"),
            "{e}"
        );
    }

    #[test]
    fn skip_rows_drops_corrupt_start() {
        let d = tempfile::tempdir().unwrap();
        let p = write(&d, "s.csv", "9e300,1,2,3,4\n0,1,2,3,4\n0.1,1,2,3,4\n");
        assert!(read_log(&p, &layout2()).is_err());
        let mut l = layout2();
        l.skip_rows = 1;
        assert_eq!(read_log(&p, &l).unwrap().len(), 2);
    }
}
