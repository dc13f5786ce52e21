//! Synthetic friction-feature datasets with known coefficients for the baseline's tests
//! (with and without the `qdd`, `rest_dir` and presliding columns, seeded noise), shared by
//! the library's tests and the command line's (`#[path]`-included, one source).
#![allow(dead_code)]

use compnet::baseline::N_FEATURES;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use std::path::{Path, PathBuf};

/// The joints the synthetic datasets hold (1-based).
pub const JOINTS: [usize; 2] = [1, 3];

/// Per joint: the extra torque over `tau_model` [N·m per feature unit], FEATURE_NAMES
/// order (the `tau_model` entry is a gain error: the fitted coefficient is 1 + it).
pub fn truth(joint: usize) -> [f64; N_FEATURES] {
    let s = joint as f64;
    [
        0.3 * s,
        0.05 * s,
        1.2,
        -0.4 * s,
        0.8,
        0.25,
        2.0 / s,
        -0.3,
        0.15 * s,
        0.02 * s,
        1.5,
        -0.7 * s,
        0.35,
        0.2,
        0.6 / s,
        0.04 * s,
        -0.03 * s,
        0.05,
        0.1 / s,
        0.9,
        -0.5 * s,
        0.3,
        -0.2,
        0.02 * s,
        -0.04,
        0.06 / s,
        0.015 * s,
    ]
}

/// Presliding (Maxwell-slip) states over a sequence of angles [rad], written out from
/// their definition: spans of 1, 3, 10 and 30 mrad, saturating at +-1.
pub fn presliding(q: &[f32]) -> Vec<[f64; 4]> {
    let spans = [0.001, 0.003, 0.01, 0.03];
    let mut s = [0.0f64; 4];
    let mut last = q[0] as f64;
    q.iter()
        .map(|&x| {
            let dq = x as f64 - last;
            last = x as f64;
            for (e, span) in s.iter_mut().zip(spans) {
                *e = (*e + dq / span).clamp(-1.0, 1.0);
            }
            s
        })
        .collect()
}

/// The features of one row, computed independently of the crate (f32 inputs, f64 math).
pub fn row_features(
    q: f32,
    qd: f32,
    qdd: f64,
    tau_model: f32,
    (rest, slip): (f64, [f64; 4]),
) -> [f64; N_FEATURES] {
    let (q, v, m) = (q as f64, qd as f64, tau_model as f64);
    let sgn = if v > 0.0 {
        1.0
    } else if v < 0.0 {
        -1.0
    } else {
        0.0
    };
    [
        1.0,
        m,
        (v / 0.01).tanh(),
        (v / 0.05).tanh(),
        (v / 0.2).tanh(),
        (v / 1.0).tanh(),
        v,
        v * v.abs(),
        v.abs().sqrt() * sgn,
        qdd,
        q.sin(),
        q.cos(),
        (2.0 * q).sin(),
        (2.0 * q).cos(),
        rest,
        m.abs() * (v / 0.05).tanh(),
        m * (v / 0.05).tanh(),
        m.abs() * (v / 0.2).tanh(),
        m.abs(),
        slip[0],
        slip[1],
        slip[2],
        slip[3],
        m.abs() * slip[0],
        m.abs() * slip[1],
        m.abs() * slip[2],
        m.abs() * slip[3],
    ]
}

/// Writes a synthetic dataset of `n` rows: random states (speeds over four decades, a
/// fifth of the rows at rest), `tau_meas = tau_model + truth · features + noise`. With
/// `full`, the `qdd`, `rest_dir` and presliding columns are written (random); without,
/// the baseline must compute them (central differences over `time_s`, the last motion's
/// direction, the presliding states of the angles).
pub fn write_dataset(path: &Path, n: usize, seed: u64, full: bool, noise_nm: f64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, noise_nm.max(1e-300)).unwrap();
    let time: Vec<f32> = (0..n).map(|k| 10.0 + k as f32 * 0.01).collect();
    let mut names = vec!["time_s".to_string()];
    let mut cols: Vec<Vec<f32>> = vec![time.clone()];
    let mut meas = Vec::new();
    let mut per_joint = Vec::new();
    for &j in &JOINTS {
        let q: Vec<f32> = (0..n).map(|_| rng.gen_range(-3.0f32..3.0)).collect();
        let qd: Vec<f32> = (0..n)
            .map(|_| {
                if rng.gen_bool(0.2) {
                    rng.gen_range(-0.004f32..0.004)
                } else {
                    let mag = 10f32.powf(rng.gen_range(-3.0f32..0.6));
                    if rng.gen_bool(0.5) { mag } else { -mag }
                }
            })
            .collect();
        let qdd_col: Vec<f32> = (0..n).map(|_| rng.gen_range(-4.0f32..4.0)).collect();
        let rest_col: Vec<f32> = (0..n).map(|_| rng.gen_range(-1i32..=1) as f32).collect();
        let model: Vec<f32> = (0..n).map(|_| rng.gen_range(-3.0f32..3.0)).collect();
        let slip_cols: Vec<Vec<f32>> = (0..4)
            .map(|_| (0..n).map(|_| rng.gen_range(-1.0f32..1.0)).collect())
            .collect();
        // What the baseline sees without the columns.
        let qdd: Vec<f64> = if full {
            qdd_col.iter().map(|&v| v as f64).collect()
        } else {
            (0..n)
                .map(|k| {
                    let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
                    (qd[b] as f64 - qd[a] as f64) / (time[b] as f64 - time[a] as f64)
                })
                .collect()
        };
        let rest: Vec<f64> = if full {
            rest_col.iter().map(|&v| v as f64).collect()
        } else {
            let mut last = 0.0;
            qd.iter()
                .map(|&v| {
                    if v.abs() > 0.005 {
                        last = v.signum() as f64;
                        0.0
                    } else {
                        last
                    }
                })
                .collect()
        };
        let slip: Vec<[f64; 4]> = if full {
            (0..n)
                .map(|k| std::array::from_fn(|e| slip_cols[e][k] as f64))
                .collect()
        } else {
            presliding(&q)
        };
        let c = truth(j);
        let tau: Vec<f32> = (0..n)
            .map(|k| {
                let f = row_features(q[k], qd[k], qdd[k], model[k], (rest[k], slip[k]));
                let extra: f64 = c.iter().zip(&f).map(|(a, b)| a * b).sum();
                let e = if noise_nm > 0.0 {
                    noise.sample(&mut rng)
                } else {
                    0.0
                };
                (model[k] as f64 + extra + e) as f32
            })
            .collect();
        meas.push((format!("tau_meas_j{j}"), tau));
        per_joint.push((j, q, qd, model, qdd_col, rest_col, slip_cols));
    }
    for (j, q, qd, model, qdd_col, rest_col, slip_cols) in per_joint {
        names.extend(["q", "qd", "tau_model"].map(|k| format!("{k}_j{j}")));
        cols.extend([q.clone(), qd, model]);
        if full {
            names.extend(["qdd", "sin_q", "cos_q", "rest_dir"].map(|k| format!("{k}_j{j}")));
            cols.extend([
                qdd_col,
                q.iter().map(|v| v.sin()).collect(),
                q.iter().map(|v| v.cos()).collect(),
                rest_col,
            ]);
            names.extend(
                ["slip_1mrad", "slip_3mrad", "slip_10mrad", "slip_30mrad"]
                    .map(|k| format!("{k}_j{j}")),
            );
            cols.extend(slip_cols);
        }
    }
    for (name, tau) in meas {
        names.push(name);
        cols.push(tau);
    }
    let mut s = names.join(",");
    s.push('\n');
    for k in 0..n {
        let row: Vec<String> = cols.iter().map(|c| format!("{}", c[k])).collect();
        s += &row.join(",");
        s.push('\n');
    }
    std::fs::write(path, s).unwrap();
}

pub fn datasets(dir: &Path, noise_nm: f64) -> Vec<PathBuf> {
    let a = dir.join("run_a.csv");
    let b = dir.join("run_b.csv");
    write_dataset(&a, 4000, 11, true, noise_nm);
    write_dataset(&b, 3000, 12, false, noise_nm);
    vec![a, b]
}
