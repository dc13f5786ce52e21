//! Command-line options that describe a log's columns and its preprocessing
//! (shared by `identify` and `torque`).

use clap::{Args, ValueEnum};
use logs::{
    BagOptions, ColumnRef, Effort, LogLayout, PreprocessOptions, TimeSource,
    UR10E_DRIVE_GAINS_NM_PER_A, rosbag,
};

/// Starting point for the column layout.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum LayoutPreset {
    /// No header; time, q1..qN, qd1..qN, current i1..iN (× drive gains); further columns
    /// ignored. With the UR10e's 6 joints and its drive gains: the layout of
    /// shared/datasets/ur10e.
    Ur10e,
    /// No header; time, q1..qN, qd1..qN, torque tau1..tauN [N·m].
    Torque,
    /// No header; time, q1..qN (a CSV of states; velocities and accelerations are
    /// differentiated).
    States,
}

/// Header handling.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum HeaderMode {
    /// A header if any cell of the first row is not a number.
    Auto,
    /// The first row is a header.
    Yes,
    /// No header row.
    No,
}

/// Log column layout options. Columns are 1-based indices or header names; lists are
/// comma separated, one entry per joint of the log. A ROS 2 recording (a rosbag2
/// folder, `.mcap` or `.db3`) needs none of them: its joints are matched by name
/// (`--topic`, `--joint-map`, `--time-source`, and `--torque-constants` when its effort is
/// motor current).
#[derive(Debug, Clone, Args)]
pub struct LayoutArgs {
    /// Column layout preset; the column options below override its columns.
    #[arg(long, value_enum, default_value_t = LayoutPreset::Ur10e)]
    pub layout: LayoutPreset,
    /// Number of joints in the log (preset columns follow from it).
    #[arg(long, default_value_t = 6)]
    pub log_joints: usize,
    /// Header row: auto-detected, present or absent (presets: absent).
    #[arg(long, value_enum)]
    pub header: Option<HeaderMode>,
    /// Time column [s] (default 1).
    #[arg(long, value_name = "COL")]
    pub time_col: Option<String>,
    /// Position columns [rad] (default 2..N+1).
    #[arg(long, value_name = "COLS", value_delimiter = ',')]
    pub q_cols: Option<Vec<String>>,
    /// Velocity columns [rad/s] (default N+2..2N+1 in the ur10e/torque presets).
    #[arg(long, value_name = "COLS", value_delimiter = ',')]
    pub qd_cols: Option<Vec<String>>,
    /// Acceleration columns [rad/s²] (default: none, differentiated).
    #[arg(long, value_name = "COLS", value_delimiter = ',')]
    pub qdd_cols: Option<Vec<String>>,
    /// Joint torque columns [N·m] (replaces the preset's effort columns).
    #[arg(
        long,
        value_name = "COLS",
        value_delimiter = ',',
        conflicts_with = "current_cols"
    )]
    pub torque_cols: Option<Vec<String>>,
    /// Motor current columns [A] (torque = current × torque constant).
    #[arg(long, value_name = "COLS", value_delimiter = ',')]
    pub current_cols: Option<Vec<String>>,
    /// Torque constants [N·m/A, joint side] per joint for current columns (default: the
    /// UR10e's 10.0,10.6956,8.4566,9.0029,9.48,10.1232 for 6 joints).
    #[arg(
        long = "torque-constants",
        alias = "drive-gains",
        value_name = "NM_PER_A",
        value_delimiter = ','
    )]
    pub drive_gains: Option<Vec<f64>>,
    /// Data rows to skip at the start of each log (after any header), e.g. corrupt rows.
    #[arg(long, default_value_t = 0)]
    pub skip_rows: usize,
    /// ROS 2 recordings (rosbag2 MCAP): the sensor_msgs/msg/JointState topic. Its
    /// effort[] is joint torque [N·m], or motor current [A] when --torque-constants is given.
    #[arg(long, default_value = rosbag::DEFAULT_TOPIC)]
    pub topic: String,
    /// ROS 2 recordings: names in the bag renamed to the robot's joint names, as
    /// `BAG=ROBOT,...` or a file of such pairs (one or more a line, `#` comments).
    #[arg(long, value_name = "FILE|A=B,...")]
    pub joint_map: Option<String>,
    /// ROS 2 recordings: each message's time, from its header stamp or from when the
    /// bag logged it (for drivers whose stamps are zero or repeated).
    #[arg(long, value_enum, default_value_t = TimeSourceArg::Header)]
    pub time_source: TimeSourceArg,
}

/// Where a ROS 2 message's time comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum TimeSourceArg {
    /// header.stamp.
    Header,
    /// The bag's log time (MCAP log_time, .db3 timestamp).
    Log,
}

impl LayoutArgs {
    /// Builds the layout.
    pub fn layout(&self) -> anyhow::Result<LogLayout> {
        let n = self.log_joints;
        let default_gains = || {
            if n == 6 {
                Ok(UR10E_DRIVE_GAINS_NM_PER_A.to_vec())
            } else {
                Err(anyhow::anyhow!(
                    "--torque-constants is required for current columns with {n} joints"
                ))
            }
        };
        let mut l = match self.layout {
            LayoutPreset::Ur10e => LogLayout::sequential(
                n,
                true,
                true,
                Some(self.drive_gains.clone().map_or_else(default_gains, Ok)?),
            ),
            LayoutPreset::Torque => LogLayout::sequential(n, true, true, None),
            LayoutPreset::States => LogLayout::sequential(n, false, false, None),
        };
        let cols = |v: &Vec<String>| v.iter().map(|s| ColumnRef::parse(s)).collect::<Vec<_>>();
        if let Some(h) = self.header {
            l.header = match h {
                HeaderMode::Auto => None,
                HeaderMode::Yes => Some(true),
                HeaderMode::No => Some(false),
            };
        }
        if let Some(t) = &self.time_col {
            l.time = ColumnRef::parse(t);
        }
        if let Some(q) = &self.q_cols {
            l.q = cols(q);
        }
        if let Some(qd) = &self.qd_cols {
            l.qd = Some(cols(qd));
        }
        if let Some(qdd) = &self.qdd_cols {
            l.qdd = Some(cols(qdd));
        }
        if let Some(t) = &self.torque_cols {
            l.effort = Some(Effort::TorqueNm(cols(t)));
        }
        if let Some(c) = &self.current_cols {
            l.effort = Some(Effort::CurrentA {
                columns: cols(c),
                drive_gains_nm_per_a: self.drive_gains.clone().map_or_else(default_gains, Ok)?,
            });
        } else if let (
            Some(g),
            Some(Effort::CurrentA {
                drive_gains_nm_per_a,
                ..
            }),
        ) = (&self.drive_gains, l.effort.as_mut())
        {
            *drive_gains_nm_per_a = g.clone();
        }
        l.skip_rows = self.skip_rows;
        Ok(l)
    }
}

impl LayoutArgs {
    /// How to read ROS 2 recordings: the topic, and the drive gains only when given
    /// explicitly (a recording's effort is torque unless the user says it is current).
    pub fn bag_options(&self) -> anyhow::Result<BagOptions> {
        let joint_map = match &self.joint_map {
            None => Vec::new(),
            Some(m) if !m.contains('=') || std::path::Path::new(m).is_file() => {
                let text = std::fs::read_to_string(m)
                    .map_err(|e| anyhow::anyhow!("--joint-map {m}: cannot read: {e}"))?;
                rosbag::parse_joint_map(&text).map_err(|e| anyhow::anyhow!("{m}: {e}"))?
            }
            Some(m) => {
                rosbag::parse_joint_map(m).map_err(|e| anyhow::anyhow!("--joint-map: {e}"))?
            }
        };
        Ok(BagOptions {
            topic: self.topic.clone(),
            drive_gains_nm_per_a: self.drive_gains.clone(),
            time_source: match self.time_source {
                TimeSourceArg::Header => TimeSource::Header,
                TimeSourceArg::Log => TimeSource::Log,
            },
            joint_map,
        })
    }
}

/// Preprocessing options.
#[derive(Debug, Clone, Args)]
pub struct PreprocessArgs {
    /// Resample onto a uniform grid at this rate [Hz] (default: 1 / median time step).
    #[arg(long, value_name = "HZ")]
    pub resample_hz: Option<f64>,
    /// Order of the zero-phase Butterworth low-pass (even).
    #[arg(long, default_value_t = 4)]
    pub filter_order: usize,
    /// Low-pass cut-off for positions [Hz]; 0 = no filtering.
    #[arg(long, default_value_t = 5.0, value_name = "HZ")]
    pub q_cutoff_hz: f64,
    /// Low-pass cut-off for torques/currents [Hz]; 0 = no filtering.
    #[arg(long, default_value_t = 5.0, value_name = "HZ")]
    pub torque_cutoff_hz: f64,
    /// Use the logged velocities (filtered) instead of differentiating positions.
    #[arg(long)]
    pub use_logged_qd: bool,
    /// Trim leading and trailing samples where every |qd| is below this [rad/s]; 0 = keep.
    /// A log that never moves (static pose) is kept whole.
    #[arg(long, default_value_t = 0.01, value_name = "RAD_S")]
    pub trim_rest_rad_s: f64,
    /// Kalman-filter the motor current (random-walk model): process and measurement
    /// variance [A²], e.g. `1e-4,1e-2`.
    #[arg(long, value_name = "Q,R", value_delimiter = ',')]
    pub kalman_current: Option<Vec<f64>>,
    /// Minimum samples per log after preprocessing.
    #[arg(long, default_value_t = 20)]
    pub min_samples: usize,
}

impl PreprocessArgs {
    /// The options.
    pub fn options(&self) -> anyhow::Result<PreprocessOptions> {
        let pos = |x: f64| (x > 0.0).then_some(x);
        if let Some(k) = &self.kalman_current
            && (k.len() != 2 || !k.iter().all(|v| v.is_finite() && *v > 0.0))
        {
            anyhow::bail!("--kalman-current {k:?}: expected two positive variances Q,R [A²]");
        }
        Ok(PreprocessOptions {
            resample_hz: self.resample_hz,
            filter_order: self.filter_order,
            q_cutoff_hz: pos(self.q_cutoff_hz),
            torque_cutoff_hz: pos(self.torque_cutoff_hz),
            use_logged_qd: self.use_logged_qd,
            trim_rest_rad_s: pos(self.trim_rest_rad_s),
            kalman_current: self.kalman_current.as_ref().map(|v| (v[0], v[1])),
            min_samples: self.min_samples,
        })
    }
}
