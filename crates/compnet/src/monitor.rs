//! The drive's do-no-harm monitor ([`firmware::monitor`]) streamed over a log, after a
//! prediction, as the drive runs it: per row `r`, the monitor scores the model alone and
//! the prediction of row `r-1` against the torque measured at row `r-1` (what the drive
//! has measured before its tick), then scales what row `r`'s prediction adds to the
//! model by its gain. The same firmware function, the same f32 bits.
//! Columns read per joint N: `tau_meas_jN` [N·m] and `time_s` [s] (the tick rate).
use super::adaptation;
use super::data::Table;
use anyhow::{Result, bail};
use firmware::monitor::{DoNoHarmMonitor, MonitorConfig};

/// A prediction after the monitor: the torque fed forward per row [N·m] and the gain.
#[derive(Clone, Debug, PartialEq)]
pub struct Monitored {
    /// `base + gain (full - base)` per row [N·m] (NaN where a candidate is NaN).
    pub torque_nm: Vec<f64>,
    /// The monitor's gain per row, in [0, 1].
    pub gain: Vec<f32>,
}

impl Monitored {
    /// Share of the rows of `rows` whose gain is below 1 (`COMPENSATION_FADED`).
    pub fn faded_share(&self, rows: std::ops::Range<usize>) -> f64 {
        let n = rows.len();
        let faded = self.gain[rows].iter().filter(|&&g| g < 1.0).count();
        if n > 0 { faded as f64 / n as f64 } else { 0.0 }
    }
}

/// `full_nm` (the model plus the compensation, per row of `table`, joint `joint`,
/// 1-based) after the monitor `config` that compares it with `base_nm` (the model
/// alone), at the table's tick rate.
pub fn monitor(
    table: &Table,
    joint: usize,
    base_nm: &[f64],
    full_nm: &[f64],
    config: MonitorConfig,
) -> Result<Monitored> {
    let measured = table.column(&format!("tau_meas_j{joint}"))?;
    if base_nm.len() != measured.len() || full_nm.len() != measured.len() {
        bail!(
            "{}: {} model and {} compensated predictions for {} rows",
            table.path.display(),
            base_nm.len(),
            full_nm.len(),
            measured.len()
        );
    }
    let mut m = DoNoHarmMonitor::new(config, adaptation::tick_hz(table)? as f32);
    let mut out = Monitored {
        torque_nm: Vec::with_capacity(measured.len()),
        gain: Vec::with_capacity(measured.len()),
    };
    for (r, (&base, &full)) in base_nm.iter().zip(full_nm).enumerate() {
        let before = r.checked_sub(1).map_or(f32::NAN, |p| measured[p]);
        let y = m.step(base as f32, full as f32, before);
        // The same blend in f64 where a candidate is NaN (rows outside a sequence).
        out.torque_nm.push(if y.is_finite() {
            f64::from(y)
        } else {
            base + f64::from(m.gain()) * (full - base)
        });
        out.gain.push(m.gain());
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn table(meas: Vec<f32>) -> Table {
        let t: Vec<f32> = (0..meas.len()).map(|k| k as f32 * 0.01).collect();
        Table {
            path: PathBuf::from("m.csv"),
            names: ["time_s", "tau_meas_j2"].map(String::from).to_vec(),
            columns: vec![t, meas],
        }
    }

    const ON: MonitorConfig = MonitorConfig {
        window_s: 1.0,
        fade_s: 0.5,
        hysteresis: 0.05,
    };

    #[test]
    fn a_harmful_compensation_is_faded_to_the_model_and_a_good_one_kept() {
        let n = 3000;
        let base: Vec<f64> = (0..n).map(|k| 10.0 * (k as f64 * 0.01).sin()).collect();
        // The joint needs 1 N·m more than the model.
        let t = table(base.iter().map(|b| (b + 1.0) as f32).collect());
        let good: Vec<f64> = base.iter().map(|b| b + 1.0).collect();
        let bad: Vec<f64> = base.iter().map(|b| b - 2.0).collect();
        let rms = |p: &[f64]| adaptation::rms_nm(&t.columns[1], p, 0..n).unwrap();
        let kept = monitor(&t, 2, &base, &good, ON).unwrap();
        assert!(rms(&kept.torque_nm) < 1e-3, "{}", rms(&kept.torque_nm));
        assert_eq!(kept.faded_share(0..n), 0.0);
        let faded = monitor(&t, 2, &base, &bad, ON).unwrap();
        // The model alone is 1 N·m off, the bad compensation 3; faded within the
        // first second and a half, the whole run is close to the model.
        assert!(
            rms(&faded.torque_nm) < 1.2 * rms(&base),
            "{}",
            rms(&faded.torque_nm)
        );
        assert!(faded.faded_share(0..n) > 0.9);
        assert_eq!(*faded.gain.last().unwrap(), 0.0);
        // Lengths that do not match the table are an error naming it.
        let e = monitor(&t, 2, &base[1..], &good, ON).unwrap_err();
        assert!(format!("{e}").contains("m.csv"), "{e}");
    }
}
