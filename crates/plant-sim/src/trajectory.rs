//! Commanded trajectories the simulated robot follows: the excitation designer's Fourier
//! coefficients (JSON) or a playback CSV (`t`, then `q`, `qd`, `qdd` of each joint).
use anyhow::{Context, bail, ensure};
use excitation::trajectory::ExcitationTrajectory;
use std::path::Path;

/// A trajectory given as samples; evaluated between samples by quintic Hermite
/// interpolation of (q, qd, qdd), which reproduces all three at the samples.
#[derive(Debug, Clone, PartialEq)]
pub struct PlaybackTrajectory {
    /// Sample times [s], strictly increasing, first = 0 after loading.
    pub t_s: Vec<f64>,
    /// Positions per sample [rad].
    pub q_rad: Vec<Vec<f64>>,
    /// Velocities per sample [rad/s].
    pub qd_rad_s: Vec<Vec<f64>>,
    /// Accelerations per sample [rad/s^2].
    pub qdd_rad_s2: Vec<Vec<f64>>,
}

pub use excitation::trajectory::{
    MAX_HARMONICS, MAX_TRAJECTORY_Q_RAD, MAX_TRAJECTORY_QD_RAD_S, MAX_TRAJECTORY_QDD_RAD_S2,
};

/// The motion the robot is commanded to follow, for the joints it drives.
#[derive(Debug, Clone, PartialEq)]
pub enum CommandedTrajectory {
    /// Fourier series, repeated for a number of periods.
    Fourier {
        /// The coefficients.
        series: ExcitationTrajectory,
        /// How many periods to run.
        periods: usize,
    },
    /// Sampled playback.
    Playback(PlaybackTrajectory),
}

impl PlaybackTrajectory {
    /// Evaluates at `t_s` (clamped to the sampled span).
    pub fn eval_into(&self, t_s: f64, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) {
        let n = self.t_s.len();
        let t = t_s.clamp(self.t_s[0], self.t_s[n - 1]);
        // Last sample index with t_s[i] <= t.
        let i = match self.t_s.binary_search_by(|x| x.total_cmp(&t)) {
            Ok(i) => i.min(n - 2),
            Err(i) => i.saturating_sub(1).min(n - 2),
        };
        let h = self.t_s[i + 1] - self.t_s[i];
        let s = (t - self.t_s[i]) / h;
        let (s2, s3) = (s * s, s * s * s);
        let (s4, s5) = (s3 * s, s3 * s * s);
        // Quintic Hermite basis and its derivatives in s.
        let b = [
            1.0 - 10.0 * s3 + 15.0 * s4 - 6.0 * s5,
            s - 6.0 * s3 + 8.0 * s4 - 3.0 * s5,
            0.5 * s2 - 1.5 * s3 + 1.5 * s4 - 0.5 * s5,
            0.5 * s3 - s4 + 0.5 * s5,
            -4.0 * s3 + 7.0 * s4 - 3.0 * s5,
            10.0 * s3 - 15.0 * s4 + 6.0 * s5,
        ];
        let db = [
            -30.0 * s2 + 60.0 * s3 - 30.0 * s4,
            1.0 - 18.0 * s2 + 32.0 * s3 - 15.0 * s4,
            s - 4.5 * s2 + 6.0 * s3 - 2.5 * s4,
            1.5 * s2 - 4.0 * s3 + 2.5 * s4,
            -12.0 * s2 + 28.0 * s3 - 15.0 * s4,
            30.0 * s2 - 60.0 * s3 + 30.0 * s4,
        ];
        let ddb = [
            -60.0 * s + 180.0 * s2 - 120.0 * s3,
            -36.0 * s + 96.0 * s2 - 60.0 * s3,
            1.0 - 9.0 * s + 18.0 * s2 - 10.0 * s3,
            3.0 * s - 12.0 * s2 + 10.0 * s3,
            -24.0 * s + 84.0 * s2 - 60.0 * s3,
            60.0 * s - 180.0 * s2 + 120.0 * s3,
        ];
        for j in 0..q.len() {
            let c = [
                self.q_rad[i][j],
                h * self.qd_rad_s[i][j],
                h * h * self.qdd_rad_s2[i][j],
                h * h * self.qdd_rad_s2[i + 1][j],
                h * self.qd_rad_s[i + 1][j],
                self.q_rad[i + 1][j],
            ];
            let dot = |w: &[f64; 6]| w.iter().zip(&c).map(|(a, b)| a * b).sum::<f64>();
            q[j] = dot(&b);
            qd[j] = dot(&db) / h;
            qdd[j] = dot(&ddb) / (h * h);
        }
    }

    /// Reads a playback CSV with a header: a time column (`t`, `t_s` or `time`) and for
    /// each joint j = 1.. columns `q{j}`, `qd{j}`, `qdd{j}` (a unit suffix such as `_rad`
    /// is allowed). Errors name the file, line and field.
    pub fn from_csv(path: &Path) -> anyhow::Result<Self> {
        let name = path.display();
        let mut rdr = csv::ReaderBuilder::new()
            .has_headers(true)
            .trim(csv::Trim::All)
            .from_path(path)
            .with_context(|| format!("{name}: cannot open"))?;
        let headers = rdr
            .headers()
            .with_context(|| format!("{name}: line 1: cannot read the header"))?
            .clone();
        let base = |h: &str| -> String {
            let h = h.to_ascii_lowercase();
            match h.find(['_', '[', ' ']) {
                Some(i)
                    if h[..i].chars().last().is_some_and(|c| c.is_ascii_digit())
                        || h.starts_with("t") =>
                {
                    h[..i].to_string()
                }
                _ => h,
            }
        };
        let names: Vec<String> = headers.iter().map(base).collect();
        let find = |want: &str| names.iter().position(|n| n == want);
        let t_col = find("t")
            .or_else(|| find("time"))
            .with_context(|| format!("{name}: line 1: no time column (t, t_s or time)"))?;
        let mut cols = Vec::new();
        for j in 1.. {
            match (
                find(&format!("q{j}")),
                find(&format!("qd{j}")),
                find(&format!("qdd{j}")),
            ) {
                (Some(a), Some(b), Some(c)) => cols.push((a, b, c)),
                (None, None, None) => break,
                _ => bail!("{name}: line 1: joint {j} needs all of q{j}, qd{j}, qdd{j}"),
            }
        }
        ensure!(
            !cols.is_empty(),
            "{name}: line 1: no joint columns (q1, qd1, qdd1, ...)"
        );
        let mut tr = PlaybackTrajectory {
            t_s: vec![],
            q_rad: vec![],
            qd_rad_s: vec![],
            qdd_rad_s2: vec![],
        };
        for (k, rec) in rdr.records().enumerate() {
            let line = k + 2;
            let rec = rec.with_context(|| format!("{name}: line {line}: malformed record"))?;
            let cell = |i: usize| -> anyhow::Result<f64> {
                let field = &headers[i];
                let s = rec
                    .get(i)
                    .with_context(|| format!("{name}: line {line}: field {field}: missing"))?;
                let v: f64 = s.parse().with_context(|| {
                    format!("{name}: line {line}: field {field}: not a number: {s:?}")
                })?;
                ensure!(
                    v.is_finite(),
                    "{name}: line {line}: field {field}: not finite"
                );
                Ok(v)
            };
            let t = cell(t_col)?;
            if let Some(&prev) = tr.t_s.last() {
                ensure!(
                    t > prev,
                    "{name}: line {line}: field {}: time {t} not after {prev}",
                    &headers[t_col]
                );
            }
            tr.t_s.push(t);
            let mut row = [vec![], vec![], vec![]];
            for &(a, b, c) in &cols {
                row[0].push(cell(a)?);
                row[1].push(cell(b)?);
                row[2].push(cell(c)?);
            }
            let [q, qd, qdd] = row;
            tr.q_rad.push(q);
            tr.qd_rad_s.push(qd);
            tr.qdd_rad_s2.push(qdd);
        }
        ensure!(
            tr.t_s.len() >= 2,
            "{name}: needs at least 2 samples, has {}",
            tr.t_s.len()
        );
        let t0 = tr.t_s[0];
        tr.t_s.iter_mut().for_each(|t| *t -= t0);
        Ok(tr)
    }
}

impl CommandedTrajectory {
    /// Number of joints the trajectory drives.
    pub fn joint_count(&self) -> usize {
        match self {
            Self::Fourier { series, .. } => series.joints.len(),
            Self::Playback(p) => p.q_rad[0].len(),
        }
    }

    /// Duration [s].
    pub fn duration_s(&self) -> f64 {
        match self {
            Self::Fourier { series, periods } => series.period_s * *periods as f64,
            Self::Playback(p) => *p.t_s.last().unwrap_or(&0.0),
        }
    }

    /// Evaluates the driven joints at `t_s`.
    pub fn eval_into(&self, t_s: f64, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) {
        match self {
            Self::Fourier { series, .. } => series.eval_into(t_s, q, qd, qdd),
            Self::Playback(p) => p.eval_into(t_s, q, qd, qdd),
        }
    }

    /// Loads a `.json` (Fourier coefficients: an object with `period_s`, `harmonics` and
    /// `joints`, at the top level or nested one level under any key, e.g. the excitation
    /// designer's output) or any other file as a playback CSV.
    pub fn load(path: &Path, periods: usize) -> anyhow::Result<Self> {
        let name = path.display();
        let is_json = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("json"));
        if !is_json {
            return Ok(Self::Playback(PlaybackTrajectory::from_csv(path)?));
        }
        ensure!(periods >= 1, "periods must be >= 1");
        let text = std::fs::read_to_string(path).with_context(|| format!("{name}: cannot read"))?;
        let value: serde_json::Value =
            serde_json::from_str(&text).with_context(|| format!("{name}: not valid JSON"))?;
        let series = find_fourier(&value).with_context(|| {
            format!("{name}: no Fourier trajectory (an object with period_s, harmonics, joints[q0_rad, a_rad, b_rad])")
        })?;
        series.validate().with_context(|| format!("{name}"))?;
        Ok(Self::Fourier { series, periods })
    }
}

/// The joint layout an excitation file (`model-export excite`) records, if any:
/// `layout.moving` (0-based robot joints, trajectory order) and `layout.fixed_rad`
/// (position of every robot joint when not moving).
pub fn excitation_layout(path: &Path) -> Option<(Vec<usize>, Vec<f64>)> {
    if !path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"))
    {
        return None;
    }
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(path).ok()?).ok()?;
    let layout = v.get("layout")?;
    let moving: Vec<usize> = serde_json::from_value(layout.get("moving")?.clone()).ok()?;
    let fixed: Vec<f64> = serde_json::from_value(layout.get("fixed_rad")?.clone()).ok()?;
    Some((moving, fixed))
}

fn find_fourier(v: &serde_json::Value) -> Option<ExcitationTrajectory> {
    if let Ok(f) = serde_json::from_value::<ExcitationTrajectory>(v.clone()) {
        return Some(f);
    }
    v.as_object()?
        .values()
        .find_map(|inner| serde_json::from_value::<ExcitationTrajectory>(inner.clone()).ok())
}

/// The trajectory file `path` (`periods` periods of a Fourier file), or the built-in
/// seeded rest-to-rest trajectory of `seed` over `n` joints.
pub fn trajectory_or_seeded(
    path: Option<&std::path::Path>,
    periods: usize,
    seed: u64,
    n: usize,
) -> anyhow::Result<CommandedTrajectory> {
    match path {
        Some(p) => CommandedTrajectory::load(p, periods),
        None => Ok(CommandedTrajectory::Fourier {
            series: ExcitationTrajectory::seeded_rest_to_rest(
                seed,
                &vec![0.0; n],
                5,
                10.0,
                DEMO_LIMITS,
            ),
            periods,
        }),
    }
}

/// Limits of the built-in demo trajectories: (|q - rest| [rad], |qd| [rad/s], |qdd| [rad/s^2]).
pub const DEMO_LIMITS: (f64, f64, f64) = (2.5, 2.5, 10.0);

#[cfg(test)]
mod tests {
    use super::*;
    use excitation::trajectory::JointFourier;

    fn series() -> ExcitationTrajectory {
        ExcitationTrajectory {
            period_s: 4.0,
            harmonics: 2,
            joints: vec![
                JointFourier {
                    q0_rad: 0.1,
                    a_rad: vec![0.2, -0.1],
                    b_rad: vec![0.05, 0.3],
                },
                JointFourier {
                    q0_rad: -0.2,
                    a_rad: vec![0.0, 0.4],
                    b_rad: vec![-0.1, 0.0],
                },
            ],
        }
    }

    #[test]
    fn playback_interpolation_tracks_the_fourier_series() {
        let f = series();
        let mut pb = PlaybackTrajectory {
            t_s: vec![],
            q_rad: vec![],
            qd_rad_s: vec![],
            qdd_rad_s2: vec![],
        };
        for k in 0..=400 {
            let t = k as f64 * 0.01;
            let (mut q, mut qd, mut qdd) = (vec![0.0; 2], vec![0.0; 2], vec![0.0; 2]);
            f.eval_into(t, &mut q, &mut qd, &mut qdd);
            pb.t_s.push(t);
            pb.q_rad.push(q);
            pb.qd_rad_s.push(qd);
            pb.qdd_rad_s2.push(qdd);
        }
        let mut worst = [0.0f64; 3];
        for k in 0..3999 {
            let t = k as f64 * 0.001 + 0.0003;
            let (mut a, mut b) = (
                [vec![0.0; 2], vec![0.0; 2], vec![0.0; 2]],
                [vec![0.0; 2], vec![0.0; 2], vec![0.0; 2]],
            );
            let [q, qd, qdd] = &mut a;
            f.eval_into(t, q, qd, qdd);
            let [q2, qd2, qdd2] = &mut b;
            pb.eval_into(t, q2, qd2, qdd2);
            for d in 0..3 {
                for j in 0..2 {
                    worst[d] = worst[d].max((a[d][j] - b[d][j]).abs());
                }
            }
        }
        assert!(
            worst[0] < 1e-9 && worst[1] < 1e-7 && worst[2] < 1e-4,
            "{worst:?}"
        );
    }

    #[test]
    fn fourier_json_is_found_nested() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.json");
        let wrapped = serde_json::json!({ "version": 1, "trajectory": series() });
        std::fs::write(&p, wrapped.to_string()).unwrap();
        let tr = CommandedTrajectory::load(&p, 2).unwrap();
        assert_eq!(tr.joint_count(), 2);
        assert_eq!(tr.duration_s(), 8.0);
    }

    #[test]
    fn playback_csv_errors_name_line_and_field() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.csv");
        std::fs::write(&p, "t,q1,qd1,qdd1\n0,0,0,0\n0.01,0.1,nan?,0\n").unwrap();
        let e = format!("{:#}", PlaybackTrajectory::from_csv(&p).unwrap_err());
        assert!(e.contains("line 3") && e.contains("qd1"), "{e}");
        std::fs::write(&p, "t,q1,qd1,qdd1\n0,0,0,0\n0,0.1,0,0\n").unwrap();
        let e = format!("{:#}", PlaybackTrajectory::from_csv(&p).unwrap_err());
        assert!(e.contains("line 3") && e.contains("not after"), "{e}");
    }
}
