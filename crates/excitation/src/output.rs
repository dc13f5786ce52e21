//! Output files of an excitation design: coefficients (JSON), playback CSV, and plots (SVG).
//!
//! Every file is first written to a temporary file in its destination directory and renamed
//! into place only after all of them were written, so a failure leaves no partial output.

use super::ExciteError;
use super::constraints::{ConstraintMargin, JointLimits, PointConstraint};
use super::objective::{Criterion, ExcitationScore};
use super::optimise::{ExcitationDesign, RestartReport};
use super::trajectory::{ExcitationTrajectory, SampledTrajectory};
use plotters::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Format tag of the coefficient file.
pub const FORMAT: &str = "excitation-trajectory";
/// Version of the coefficient file format.
pub const FORMAT_VERSION: u32 = 1;

/// How the moving joints sit among all the robot's joints (locked joints stay at a fixed
/// position during playback).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlaybackLayout {
    /// Names of all the robot's joints, in chain order.
    pub joint_names: Vec<String>,
    /// Indices (0-based, into `joint_names`) of the moving joints, in trajectory order.
    pub moving: Vec<usize>,
    /// Position of every joint when not moving (locked position or rest pose), rad.
    pub fixed_rad: Vec<f64>,
}

impl PlaybackLayout {
    /// All joints move; rest pose as given.
    pub fn all_moving(rest_rad: &[f64]) -> Self {
        Self {
            joint_names: (1..=rest_rad.len()).map(|i| format!("joint{i}")).collect(),
            moving: (0..rest_rad.len()).collect(),
            fixed_rad: rest_rad.to_vec(),
        }
    }
}

/// The coefficient file (`excitation.json`): everything needed to replay and to audit a design.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ExcitationFile {
    /// Always [`FORMAT`].
    pub format: String,
    /// Always [`FORMAT_VERSION`].
    pub version: u32,
    /// Robot description the design was made for.
    pub robot: String,
    /// Joint layout.
    pub layout: PlaybackLayout,
    /// Limits of the moving joints.
    pub limits: Vec<JointLimits>,
    /// Extra point constraints.
    pub point_constraints: Vec<PointConstraint>,
    /// Fundamental angular frequency ω_f in rad/s (= 2π / period).
    pub omega_rad_s: f64,
    /// Coefficients of the moving joints (period, harmonics, q0/a/b per joint).
    pub trajectory: ExcitationTrajectory,
    /// Criterion optimised.
    pub criterion: Criterion,
    /// Score at the controller rate.
    pub score: ExcitationScore,
    /// Median unscaled condition number of the random baseline population (seeded random
    /// feasible trajectories of the same family, see `optimise::random_baseline`), if computed.
    pub random_condition: Option<f64>,
    /// Margins to every limit on the dense grid.
    pub margins: Vec<ConstraintMargin>,
    /// Total objective evaluations.
    pub evaluations: usize,
    /// Per-restart outcomes.
    pub restarts: Vec<RestartReport>,
    /// Controller rate of the playback CSV, Hz.
    pub rate_hz: f64,
    /// Master seed.
    pub seed: u64,
}

impl ExcitationFile {
    /// Builds the file contents from a design.
    pub fn new(
        robot: &str,
        layout: PlaybackLayout,
        limits: &[JointLimits],
        point_constraints: &[PointConstraint],
        design: &ExcitationDesign,
        random_condition: Option<f64>,
    ) -> Self {
        Self {
            format: FORMAT.into(),
            version: FORMAT_VERSION,
            robot: robot.into(),
            layout,
            limits: limits.to_vec(),
            point_constraints: point_constraints.to_vec(),
            omega_rad_s: design.trajectory.omega_rad_s(),
            trajectory: design.trajectory.clone(),
            criterion: design.settings.criterion,
            score: design.score,
            random_condition,
            margins: design.margins.clone(),
            evaluations: design.evaluations,
            restarts: design.restarts.clone(),
            rate_hz: design.settings.rate_hz,
            seed: design.settings.seed,
        }
    }

    /// Reads and checks a coefficient file.
    pub fn read(path: &Path) -> Result<Self, ExciteError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| ExciteError::Io(format!("{}: {e}", path.display())))?;
        let f: Self = serde_json::from_str(&text).map_err(|e| {
            ExciteError::Invalid(format!(
                "{}: line {}, column {}: {e}",
                path.display(),
                e.line(),
                e.column()
            ))
        })?;
        if f.format != FORMAT || f.version != FORMAT_VERSION {
            return Err(ExciteError::Invalid(format!(
                "{}: field `format`/`version`: expected {FORMAT} v{FORMAT_VERSION}, found {} v{}",
                path.display(),
                f.format,
                f.version
            )));
        }
        Ok(f)
    }
}

/// The full-robot playback samples: every joint, moving or locked.
pub fn playback(layout: &PlaybackLayout, sampled: &SampledTrajectory) -> Vec<Vec<f64>> {
    let n = layout.joint_names.len();
    sampled
        .t_s
        .iter()
        .enumerate()
        .map(|(k, t)| {
            let mut row = Vec::with_capacity(1 + 3 * n);
            row.push(*t);
            let mut q = layout.fixed_rad.clone();
            let mut qd = vec![0.0; n];
            let mut qdd = vec![0.0; n];
            for (m, &j) in layout.moving.iter().enumerate() {
                q[j] = sampled.q_rad[k][m];
                qd[j] = sampled.qd_rad_s[k][m];
                qdd[j] = sampled.qdd_rad_s2[k][m];
            }
            row.extend(q);
            row.extend(qd);
            row.extend(qdd);
            row
        })
        .collect()
}

/// Header of the playback CSV: `t_s`, then `q<i>_rad`, `qd<i>_rad_s`, `qdd<i>_rad_s2` for every
/// robot joint `i = 1..n` (1-based, chain order), grouped by quantity.
pub fn playback_header(joints: usize) -> Vec<String> {
    let mut h = vec!["t_s".to_string()];
    h.extend((1..=joints).map(|i| format!("q{i}_rad")));
    h.extend((1..=joints).map(|i| format!("qd{i}_rad_s")));
    h.extend((1..=joints).map(|i| format!("qdd{i}_rad_s2")));
    h
}

fn playback_csv(
    layout: &PlaybackLayout,
    sampled: &SampledTrajectory,
) -> Result<Vec<u8>, ExciteError> {
    let mut w = csv::Writer::from_writer(Vec::new());
    let io = |e: csv::Error| ExciteError::Io(e.to_string());
    w.write_record(playback_header(layout.joint_names.len()))
        .map_err(io)?;
    for row in playback(layout, sampled) {
        w.write_record(row.iter().map(|v| format!("{v:e}")))
            .map_err(io)?;
    }
    w.into_inner().map_err(|e| ExciteError::Io(e.to_string()))
}

/// SVG plot of position, velocity and acceleration of every moving joint over the samples
/// (three stacked panels, like Figures 3 and 4 of Zhang et al. 2020).
pub fn plot_svg(
    sampled: &SampledTrajectory,
    joint_labels: &[String],
    limits: &[JointLimits],
    title: &str,
) -> Result<String, ExciteError> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (900, 960)).into_drawing_area();
        let err = |e: &dyn std::fmt::Display| ExciteError::Io(format!("plot: {e}"));
        root.fill(&WHITE).map_err(|e| err(&e))?;
        let root = root
            .titled(title, ("sans-serif", 22))
            .map_err(|e| err(&e))?;
        let panels = root.split_evenly((3, 1));
        let t_end = *sampled.t_s.last().unwrap_or(&1.0);
        // Velocity and acceleration panels also show each joint's limits (dashed).
        type LimitOf = fn(&JointLimits) -> Option<f64>;
        let series: [(&str, &Vec<Vec<f64>>, LimitOf); 3] = [
            ("position (rad)", &sampled.q_rad, |_| None),
            ("velocity (rad/s)", &sampled.qd_rad_s, |l| {
                Some(l.qd_max_rad_s)
            }),
            ("acceleration (rad/s^2)", &sampled.qdd_rad_s2, |l| {
                Some(l.qdd_max_rad_s2)
            }),
        ];
        for (panel, (label, data, limit_of)) in panels.iter().zip(series.iter()) {
            let data_max = data
                .iter()
                .flat_map(|r| r.iter())
                .fold(1e-6f64, |m, v| m.max(v.abs()));
            let limit_max = limits.iter().filter_map(limit_of).fold(0.0f64, f64::max);
            let ymax = data_max.max(limit_max) * 1.1;
            let mut chart = ChartBuilder::on(panel)
                .margin(10)
                .x_label_area_size(35)
                .y_label_area_size(60)
                .build_cartesian_2d(0.0..t_end, -ymax..ymax)
                .map_err(|e| err(&e))?;
            chart
                .configure_mesh()
                .x_desc("t (s)")
                .y_desc(*label)
                .draw()
                .map_err(|e| err(&e))?;
            for (j, name) in joint_labels.iter().enumerate() {
                let color = Palette99::pick(j).to_rgba();
                chart
                    .draw_series(LineSeries::new(
                        sampled.t_s.iter().zip(data.iter()).map(|(t, r)| (*t, r[j])),
                        color.stroke_width(2),
                    ))
                    .map_err(|e| err(&e))?
                    .label(name.as_str())
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                    });
                if let Some(lim) = limits.get(j).and_then(limit_of) {
                    for sign in [-1.0, 1.0] {
                        let dashes = (0..40).map(|i| {
                            let t0 = t_end * i as f64 / 40.0;
                            PathElement::new(
                                vec![(t0, sign * lim), (t0 + 0.5 * t_end / 40.0, sign * lim)],
                                color.stroke_width(1),
                            )
                        });
                        chart.draw_series(dashes).map_err(|e| err(&e))?;
                    }
                }
            }
            chart
                .configure_series_labels()
                .border_style(BLACK)
                .background_style(WHITE.mix(0.8))
                .draw()
                .map_err(|e| err(&e))?;
        }
        root.present().map_err(|e| err(&e))?;
    }
    Ok(svg)
}

/// Paths of the files an `excite` run writes.
#[derive(Debug, Clone)]
pub struct OutputPaths {
    /// Coefficients and report (JSON).
    pub json: PathBuf,
    /// Playback samples (CSV).
    pub csv: PathBuf,
    /// Plot (SVG), if wanted.
    pub plot: Option<PathBuf>,
}

/// Writes the coefficient file, the playback CSV at the controller rate and the plot, all or
/// nothing (`model_file::write_atomic_all`), after checking that every sample is finite.
pub fn write_outputs(
    file: &ExcitationFile,
    joint_labels: &[String],
    paths: &OutputPaths,
) -> Result<(), ExciteError> {
    let sampled = file.trajectory.sample(file.rate_hz, 1);
    artifacts::ensure_finite(
        "the excitation trajectory's samples",
        sampled
            .q_rad
            .iter()
            .chain(&sampled.qd_rad_s)
            .chain(&sampled.qdd_rad_s2)
            .flatten()
            .copied(),
    )
    .map_err(|e| ExciteError::Invalid(format!("{e:#}")))?;
    let json = serde_json::to_vec_pretty(file).map_err(|e| ExciteError::Io(e.to_string()))?;
    let csv = playback_csv(&file.layout, &sampled)?;
    let mut files: Vec<(&Path, &[u8])> =
        vec![(paths.json.as_path(), &json), (paths.csv.as_path(), &csv)];
    let svg;
    if let Some(plot) = &paths.plot {
        let title = format!(
            "Excitation trajectory ({}, cond = {:.1})",
            file.robot, file.score.condition
        );
        svg = plot_svg(&sampled, joint_labels, &file.limits, &title)?;
        files.push((plot.as_path(), svg.as_bytes()));
    }
    artifacts::write_atomic_all(&files).map_err(|e| ExciteError::Io(format!("{e:#}")))
}
