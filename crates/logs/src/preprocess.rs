//! From a [`RawLog`] to identification samples: optional Kalman filtering of the
//! current, resampling onto a uniform time grid (by linear interpolation on the
//! logged time stamps, which jitter), zero-phase Butterworth low-pass of positions
//! and torques, velocities and accelerations by central differences, and trimming
//! of the rest periods at the start and end.

use super::signal::{
    ButterworthLowPass, derivative, interpolate, kalman_current, median_step, uniform_grid,
};
use super::{LogError, RawLog};
use std::path::PathBuf;

/// Preprocessing settings. Defaults suit ~100 Hz logs of slow excitation trajectories.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PreprocessOptions {
    /// Uniform resampling rate [Hz]; `None`: 1 / (median spacing of the time stamps).
    pub resample_hz: Option<f64>,
    /// Butterworth order (even) of the zero-phase low-pass.
    pub filter_order: usize,
    /// Cut-off [Hz] for positions (and logged velocities); `None`: no filtering.
    pub q_cutoff_hz: Option<f64>,
    /// Cut-off [Hz] for torques; `None`: no filtering.
    pub torque_cutoff_hz: Option<f64>,
    /// Use the logged velocities instead of differentiating positions.
    pub use_logged_qd: bool,
    /// Trim leading/trailing samples where every |q̇| is below this [rad/s] (a log that
    /// never moves, e.g. a static pose, is kept whole).
    pub trim_rest_rad_s: Option<f64>,
    /// Scalar Kalman filter on the motor current: (process variance, measurement
    /// variance) [A²]; applied before the drive gain.
    pub kalman_current: Option<(f64, f64)>,
    /// Minimum samples after preprocessing.
    pub min_samples: usize,
}

impl Default for PreprocessOptions {
    fn default() -> Self {
        Self {
            resample_hz: None,
            filter_order: 4,
            q_cutoff_hz: Some(5.0),
            torque_cutoff_hz: Some(5.0),
            use_logged_qd: false,
            trim_rest_rad_s: Some(0.01),
            kalman_current: None,
            min_samples: 20,
        }
    }
}

/// Most samples a log's uniform grid may have (10 M: 28 h at 100 Hz, 2.8 h at 1 kHz).
pub const MAX_GRID_SAMPLES: usize = 10_000_000;

/// Longest time step between two log rows, in steps of the uniform grid (10 s at
/// 100 Hz): a longer gap would be filled by interpolation, not by measurement.
pub const MAX_GAP_GRID_STEPS: usize = 1000;

/// Preprocessed samples on a uniform grid: `x[joint][sample]`.
#[derive(Debug, Clone)]
pub struct Samples {
    /// Source file.
    pub path: PathBuf,
    /// SHA-256 of the source file.
    pub sha256: String,
    /// Time [s].
    pub time_s: Vec<f64>,
    /// Positions [rad].
    pub q_rad: Vec<Vec<f64>>,
    /// Velocities [rad/s].
    pub qd_rad_s: Vec<Vec<f64>>,
    /// Accelerations [rad/s²].
    pub qdd_rad_s2: Vec<Vec<f64>>,
    /// Joint torques [N·m], if the log has effort columns.
    pub torque_nm: Option<Vec<Vec<f64>>>,
}

impl Samples {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.time_s.len()
    }
    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.time_s.is_empty()
    }
    /// Number of joints.
    pub fn n_joints(&self) -> usize {
        self.q_rad.len()
    }
    /// The state of sample `k` into the given buffers.
    pub fn state(&self, k: usize, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) {
        for j in 0..self.n_joints() {
            q[j] = self.q_rad[j][k];
            qd[j] = self.qd_rad_s[j][k];
            qdd[j] = self.qdd_rad_s2[j][k];
        }
    }
}

/// Runs the preprocessing chain on one log.
pub fn preprocess(raw: &RawLog, opt: &PreprocessOptions) -> Result<Samples, LogError> {
    let err = |line: Option<u64>, field: Option<&str>, msg: String| LogError {
        path: raw.path.clone(),
        line,
        field: field.map(str::to_string),
        message: msg,
    };
    if opt.use_logged_qd && raw.qd_rad_s.is_none() {
        return Err(err(
            None,
            Some("velocity"),
            "logged velocities asked for (--use-logged-qd) but the log has none (a bag's velocity[] empty, a CSV without velocity columns)".into(),
        ));
    }
    let need = opt.min_samples.max(3);
    if raw.len() < need {
        return Err(err(
            raw.lines.last().copied(),
            Some("time"),
            format!(
                "too few samples: {} rows, at least {need} needed",
                raw.len()
            ),
        ));
    }
    let t = &raw.time_s;
    let dt = match opt.resample_hz {
        Some(hz) if hz > 0.0 && hz.is_finite() => 1.0 / hz,
        Some(hz) => {
            return Err(err(
                None,
                Some("resample rate"),
                format!("invalid resample rate {hz} Hz"),
            ));
        }
        None => median_step(t),
    };
    let fs = 1.0 / dt;
    // A time jump in one row (or a huge resample rate) would ask for a grid of billions
    // of samples: bounded, the error names the largest jump.
    let span = t[t.len() - 1] - t[0];
    if span.is_nan() || span / dt > MAX_GRID_SAMPLES as f64 {
        let (k, jump) = t
            .windows(2)
            .map(|w| w[1] - w[0])
            .enumerate()
            .fold((0, 0.0f64), |m, (k, d)| if d > m.1 { (k, d) } else { m });
        return Err(err(
            None,
            Some("time"),
            format!(
                "{span} s at {fs} Hz needs more than {MAX_GRID_SAMPLES} samples on the uniform \
                 grid (largest time step: {jump} s, after t = {} s, sample {})",
                t[k],
                k + 1
            ),
        ));
    }
    if let Some(k) = t
        .windows(2)
        .position(|w| w[1] - w[0] > MAX_GAP_GRID_STEPS as f64 * dt)
    {
        return Err(err(
            raw.lines.get(k + 1).copied(),
            Some("time"),
            format!(
                "a gap of {} s after t = {} s (sample {}) is longer than {MAX_GAP_GRID_STEPS} \
                 grid steps of {dt} s: the log would be filled by interpolation",
                t[k + 1] - t[k],
                t[k],
                k + 1
            ),
        ));
    }
    let grid = uniform_grid(t[0], t[t.len() - 1], dt);
    let pad = |fc: f64| ((3.0 * fs / fc).ceil() as usize).max(3 * opt.filter_order);
    let lowpass = |fc: Option<f64>,
                   what: &str|
     -> Result<Option<(ButterworthLowPass, usize)>, LogError> {
        fc.map(|fc| {
            ButterworthLowPass::new(opt.filter_order, fc, fs).map(|f| (f, pad(fc))).ok_or_else(|| {
                err(
                    None,
                    Some(what),
                    format!(
                        "cannot design order-{} low-pass at {fc} Hz for {fs:.1} Hz sampling (order must be even, cut-off below Nyquist)",
                        opt.filter_order
                    ),
                )
            })
        })
        .transpose()
    };
    let q_filter = lowpass(opt.q_cutoff_hz, "q cut-off")?;
    let tau_filter = lowpass(opt.torque_cutoff_hz, "torque cut-off")?;
    let smooth = |y: &[f64], f: &Option<(ButterworthLowPass, usize)>| {
        let r = interpolate(t, y, &grid);
        match f {
            Some((f, pad)) => f.filtfilt(&r, *pad),
            None => r,
        }
    };

    let q: Vec<Vec<f64>> = raw.q_rad.iter().map(|y| smooth(y, &q_filter)).collect();
    let qd: Vec<Vec<f64>> = match (&raw.qd_rad_s, opt.use_logged_qd) {
        (Some(v), true) => v.iter().map(|y| smooth(y, &q_filter)).collect(),
        _ => q.iter().map(|y| derivative(&grid, y)).collect(),
    };
    let qdd: Vec<Vec<f64>> = match &raw.qdd_rad_s2 {
        Some(a) => a.iter().map(|y| smooth(y, &q_filter)).collect(),
        None => qd.iter().map(|y| derivative(&grid, y)).collect(),
    };
    let torque = raw.torque_nm.as_ref().map(|tau| {
        tau.iter()
            .enumerate()
            .map(|(j, y)| {
                let y = match (
                    opt.kalman_current,
                    &raw.current_a,
                    &raw.drive_gains_nm_per_a,
                ) {
                    (Some((pv, mv)), Some(cur), Some(g)) => kalman_current(&cur[j], pv, mv)
                        .iter()
                        .map(|i| i * g[j])
                        .collect(),
                    (Some((pv, mv)), _, _) => kalman_current(y, pv, mv),
                    _ => y.clone(),
                };
                smooth(&y, &tau_filter)
            })
            .collect::<Vec<_>>()
    });

    // Finite but huge cells (1e300) overflow in the filter or the derivatives: what is
    // derived is checked, not only what was read. The zero-phase filter spreads a
    // non-finite value over its whole window, so the error names the line of the cell
    // that overflowed: the read value of largest magnitude among the joint's series the
    // derived one comes from (the first of them, if several).
    let groups = [("q", Some(&q)), ("qd", Some(&qd)), ("qdd", Some(&qdd))];
    for (name, values) in groups.into_iter().chain([("torque", torque.as_ref())]) {
        for (j, v) in values.into_iter().flatten().enumerate() {
            if let Some(k) = v.iter().position(|x| !x.is_finite()) {
                let sources: Vec<&Vec<f64>> = if name == "torque" {
                    [&raw.torque_nm, &raw.current_a]
                        .into_iter()
                        .flatten()
                        .filter_map(|s| s.get(j))
                        .collect()
                } else {
                    std::iter::once(raw.q_rad.get(j))
                        .chain(
                            [&raw.qd_rad_s, &raw.qdd_rad_s2]
                                .map(|s| s.as_ref().and_then(|s| s.get(j))),
                        )
                        .flatten()
                        .collect()
                };
                let culprit = sources
                    .iter()
                    .flat_map(|s| s.iter().enumerate())
                    .fold(None, |best: Option<(usize, f64)>, (r, &x)| match best {
                        Some((br, bx)) if bx > x.abs() || (bx == x.abs() && br <= r) => best,
                        _ => Some((r, x.abs())),
                    })
                    .map(|(r, _)| r);
                let row = culprit
                    .unwrap_or_else(|| t.partition_point(|&x| x <= grid[k]).saturating_sub(1));
                return Err(err(
                    raw.lines.get(row).copied(),
                    Some(format!("{name} of joint {}", j + 1).as_str()),
                    format!(
                        "not finite after resampling, filtering and differentiation at t = {} s \
                         (the largest value read, on this line, is too large)",
                        grid[k]
                    ),
                ));
            }
        }
    }

    // Trim rest periods at both ends.
    let n = grid.len();
    let (mut lo, mut hi) = (0usize, n);
    if let Some(thr) = opt.trim_rest_rad_s {
        let moving = |k: usize| qd.iter().any(|v| v[k].abs() >= thr);
        while lo < n && !moving(lo) {
            lo += 1;
        }
        while hi > lo && !moving(hi - 1) {
            hi -= 1;
        }
        if lo == hi {
            // A log that never moves (a static pose) is kept whole.
            (lo, hi) = (0, n);
        }
    }
    if hi - lo < need {
        return Err(err(
            raw.lines.last().copied(),
            Some("time"),
            format!(
                "too few samples: {} after resampling and trimming rest periods (|qd| < {:?} rad/s), at least {need} needed",
                hi - lo,
                opt.trim_rest_rad_s
            ),
        ));
    }
    let cut = |v: Vec<Vec<f64>>| {
        v.into_iter()
            .map(|x| x[lo..hi].to_vec())
            .collect::<Vec<_>>()
    };
    Ok(Samples {
        path: raw.path.clone(),
        sha256: raw.sha256.clone(),
        time_s: grid[lo..hi].to_vec(),
        q_rad: cut(q),
        qd_rad_s: cut(qd),
        qdd_rad_s2: cut(qdd),
        torque_nm: torque.map(cut),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn sine_log(jitter: bool) -> RawLog {
        // q = sin(2π·0.5·t) sampled with jittered steps; rest for 1 s at both ends.
        let mut t = vec![0.0];
        let mut k = 0u64;
        while *t.last().unwrap() < 8.0 {
            k += 1;
            let step = if jitter {
                [0.010, 0.002, 0.016, 0.012][k as usize % 4]
            } else {
                0.01
            };
            t.push(t.last().unwrap() + step);
        }
        let q: Vec<f64> = t
            .iter()
            .map(|&t| {
                if (1.0..7.0).contains(&t) {
                    (PI * (t - 1.0)).sin()
                } else {
                    0.0
                }
            })
            .collect();
        RawLog {
            path: "sim.csv".into(),
            sha256: String::new(),
            lines: (1..=t.len() as u64).collect(),
            notes: Vec::new(),
            q_rad: vec![q.clone()],
            qd_rad_s: None,
            qdd_rad_s2: None,
            current_a: None,
            drive_gains_nm_per_a: None,
            torque_nm: Some(vec![q.iter().map(|v| 2.0 * v).collect()]),
            time_s: t,
        }
    }

    #[test]
    fn derivatives_from_jittered_time_and_trim() {
        let raw = sine_log(true);
        let opt = PreprocessOptions {
            resample_hz: Some(100.0),
            q_cutoff_hz: Some(8.0),
            ..Default::default()
        };
        let s = preprocess(&raw, &opt).unwrap();
        // Trimmed to the moving part (plus the filter's short spread).
        assert!(s.time_s[0] > 0.7 && s.time_s[0] < 1.05, "{}", s.time_s[0]);
        assert!(*s.time_s.last().unwrap() < 7.3);
        // Away from the kinks, qd ≈ π cos(π(t-1)), qdd ≈ -π² sin(π(t-1)).
        for k in 0..s.len() {
            let tt = s.time_s[k];
            if (2.0..6.0).contains(&tt) {
                let ph = PI * (tt - 1.0);
                assert!(
                    (s.qd_rad_s[0][k] - PI * ph.cos()).abs() < 0.01,
                    "qd at {tt}"
                );
                assert!(
                    (s.qdd_rad_s2[0][k] + PI * PI * ph.sin()).abs() < 0.1,
                    "qdd at {tt}"
                );
            }
        }
    }

    #[test]
    fn static_log_is_kept_whole() {
        let mut raw = sine_log(false);
        for v in raw.q_rad[0].iter_mut() {
            *v = 0.3;
        }
        let s = preprocess(&raw, &PreprocessOptions::default()).unwrap();
        assert!(s.len() > 790, "{}", s.len());
        assert!(s.qd_rad_s[0].iter().all(|v| v.abs() < 1e-12));
    }

    #[test]
    fn too_few_samples_is_an_error_naming_file_and_line() {
        let mut raw = sine_log(false);
        raw.time_s.truncate(5);
        raw.lines.truncate(5);
        let e = preprocess(&raw, &PreprocessOptions::default()).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("sim.csv, line 5, time: too few samples"),
            "{e}"
        );
    }
}
