//! Identification on simulated data from a planar 2R arm written out by hand (base
//! parameters ZZ1R, ZZ2, MX2, MY2, MX1R, MY1 and viscous/Coulomb friction per joint).

#![allow(clippy::needless_range_loop)]

use super::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

const L1: f64 = 0.6;
const G: f64 = 9.81;

fn names() -> Vec<String> {
    [
        "ZZ1R", "ZZ2", "MX2", "MY2", "MX1R", "MY1", "fv1", "fc1", "fv2", "fc2",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect()
}

/// 2 × 10 row-major regressor of a vertical planar 2R arm.
fn regressor(q: [f64; 2], qd: [f64; 2], qdd: [f64; 2]) -> [f64; 20] {
    let (s2, c2) = q[1].sin_cos();
    let (s1, c1) = q[0].sin_cos();
    let (s12, c12) = (q[0] + q[1]).sin_cos();
    let mut y = [0.0; 20];
    // joint 1
    y[0] = qdd[0];
    y[1] = qdd[0] + qdd[1];
    y[2] = L1 * (2.0 * c2 * qdd[0] + c2 * qdd[1] - s2 * (2.0 * qd[0] * qd[1] + qd[1] * qd[1]))
        + G * c12;
    y[3] = L1 * (-2.0 * s2 * qdd[0] - s2 * qdd[1] - c2 * (2.0 * qd[0] * qd[1] + qd[1] * qd[1]))
        - G * s12;
    y[4] = G * c1;
    y[5] = -G * s1;
    y[6] = qd[0];
    y[7] = qd[0].signum();
    // joint 2
    y[11] = qdd[0] + qdd[1];
    y[12] = L1 * (c2 * qdd[0] + s2 * qd[0] * qd[0]) + G * c12;
    y[13] = L1 * (-s2 * qdd[0] + c2 * qd[0] * qd[0]) - G * s12;
    y[18] = qd[1];
    y[19] = qd[1].signum();
    y
}

const THETA: [f64; 10] = [1.7, 0.45, 0.9, -0.07, 3.2, 0.15, 2.5, 4.0, 1.1, 2.2];

/// Random Fourier trajectory samples.
fn states(n: usize, seed: u64) -> Vec<([f64; 2], [f64; 2], [f64; 2])> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let w = 2.0 * std::f64::consts::PI / 10.0;
    let coef: Vec<[(f64, f64); 5]> = (0..2)
        .map(|_| core::array::from_fn(|_| (rng.gen_range(-0.3..0.3), rng.gen_range(-0.3..0.3))))
        .collect();
    (0..n)
        .map(|k| {
            let t = k as f64 * 0.01;
            let mut s = ([0.0; 2], [0.0; 2], [0.0; 2]);
            for j in 0..2 {
                for (h, (a, b)) in coef[j].iter().enumerate() {
                    let wl = w * (h + 1) as f64;
                    let (sn, cs) = (wl * t).sin_cos();
                    s.0[j] += a / wl * sn - b / wl * cs;
                    s.1[j] += a * cs + b * sn;
                    s.2[j] += -a * wl * sn + b * wl * cs;
                }
            }
            s
        })
        .collect()
}

fn torque(y: &[f64; 20]) -> [f64; 2] {
    let mut t = [0.0; 2];
    for j in 0..2 {
        t[j] = (0..10).map(|p| y[j * 10 + p] * THETA[p]).sum();
    }
    t
}

#[test]
fn noise_free_data_recover_parameters_to_1e_6() {
    let mut ne = NormalEquations::new(2, 10);
    for (q, qd, qdd) in states(3000, 7) {
        let y = regressor(q, qd, qdd);
        ne.add_sample(&y, &torque(&y));
    }
    for weighting in [Weighting::Ordinary, Weighting::PerJointFromOls] {
        let opt = IdentifyOptions {
            weighting,
            ..Default::default()
        };
        let id = solve(&mut ne.clone(), &names(), &opt).unwrap();
        for (i, (x, t)) in id.values.iter().zip(THETA).enumerate() {
            assert!(((x - t) / t).abs() < 1e-6, "{}: {x} vs {t}", names()[i]);
        }
        assert!(id.rms_nm.iter().all(|r| *r < 1e-6), "{:?}", id.rms_nm);
        assert!(id.condition_number.is_finite() && id.condition_number_scaled >= 1.0);
        assert_eq!(id.samples, 3000);
    }
}

#[test]
fn noisy_data_estimates_within_three_std_and_wls_finds_noise_levels() {
    let sigma = [0.5, 0.1];
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let noise: Vec<Normal<f64>> = sigma
        .iter()
        .map(|s| Normal::new(0.0, *s).unwrap())
        .collect();
    let mut ne = NormalEquations::new(2, 10);
    for (q, qd, qdd) in states(20_000, 3) {
        let y = regressor(q, qd, qdd);
        let t = torque(&y);
        let tn = [
            t[0] + noise[0].sample(&mut rng),
            t[1] + noise[1].sample(&mut rng),
        ];
        ne.add_sample(&y, &tn);
    }
    let opt = IdentifyOptions {
        weighting: Weighting::PerJointFromOls,
        ..Default::default()
    };
    let id = solve(&mut ne.clone(), &names(), &opt).unwrap();
    for i in 0..10 {
        let err = (id.values[i] - THETA[i]).abs();
        assert!(
            err < 3.0 * id.std[i],
            "{}: err {err} std {}",
            names()[i],
            id.std[i]
        );
        assert!(id.std[i] > 0.0 && id.relative_std_pct[i] < 20.0);
    }
    for j in 0..2 {
        assert!(
            (id.joint_sigma_nm[j] / sigma[j] - 1.0).abs() < 0.05,
            "{:?}",
            id.joint_sigma_nm
        );
        assert!((id.rms_nm[j] / sigma[j] - 1.0).abs() < 0.05);
    }
    // OLS gives the same estimates within the (larger) OLS uncertainty.
    let ols = solve(&mut ne, &names(), &IdentifyOptions::default()).unwrap();
    for i in 0..10 {
        assert!((ols.values[i] - THETA[i]).abs() < 3.0 * ols.std[i]);
    }
}

#[test]
fn zero_and_dependent_columns_are_dropped_and_named() {
    // A zero column (fv1) keeps the prior's value; everything else is recovered.
    let mut ne = NormalEquations::new(2, 10);
    for (q, qd, qdd) in states(500, 5) {
        let mut y = regressor(q, qd, qdd);
        y[6] = 0.0; // fv1 column zero
        ne.add_sample(&y, &torque(&y));
    }
    let mut prior = vec![0.0; 10];
    prior[6] = 0.25;
    let opt = IdentifyOptions {
        prior: Some(prior.clone()),
        ..Default::default()
    };
    let id = solve(&mut ne, &names(), &opt).unwrap();
    assert_eq!(id.dropped.len(), 1, "{:?}", id.dropped);
    let d = &id.dropped[0];
    assert_eq!(d.parameters.len(), 1, "{d}");
    assert!(
        d.parameters[0].0 == "fv1" && d.parameters[0].1.abs() > 0.999,
        "{d}"
    );
    assert!(d.relative_singular_value < 1e-6, "{d}");
    assert!((id.values[6] - 0.25).abs() < 1e-9, "{}", id.values[6]);
    for i in (0..10).filter(|&i| i != 6) {
        assert!(
            (id.values[i] - THETA[i]).abs() < 1e-6 * (1.0 + THETA[i].abs()),
            "{i}"
        );
    }

    // Two columns proportional (fc2 = 2·ZZ2 on every row): their difference is dropped,
    // named by both, and the sum the data holds is kept: the torques are reproduced.
    let mut ne = NormalEquations::new(2, 10);
    for (q, qd, qdd) in states(500, 5) {
        let mut y = regressor(q, qd, qdd);
        y[9] = 2.0 * y[1]; // a column proportional to ZZ2's
        y[19] = 2.0 * y[11];
        ne.add_sample(&y, &torque(&y));
    }
    let id = solve(&mut ne, &names(), &IdentifyOptions::default()).unwrap();
    assert_eq!(id.dropped.len(), 1, "{:?}", id.dropped);
    let named: Vec<&str> = id.dropped[0]
        .parameters
        .iter()
        .map(|(n, _)| n.as_str())
        .collect();
    assert_eq!(named.len(), 2, "{}", id.dropped[0]);
    assert!(
        named.contains(&"ZZ2") && named.contains(&"fc2"),
        "{}",
        id.dropped[0]
    );
    let kept = |v: &[f64]| v[1] + 2.0 * v[9];
    assert!(
        (kept(&id.values) - kept(&THETA)).abs() < 1e-6,
        "{:?}",
        id.values
    );
    assert!(id.rms_nm.iter().all(|r| *r < 1e-6), "{:?}", id.rms_nm);
    assert!(id.condition_number_scaled.is_finite() && id.condition_number.is_finite());
}

#[test]
fn too_few_samples_and_rel_std_limit() {
    let mut ne = NormalEquations::new(2, 10);
    for (q, qd, qdd) in states(4, 5) {
        let y = regressor(q, qd, qdd);
        ne.add_sample(&y, &torque(&y));
    }
    assert!(matches!(
        solve(&mut ne, &names(), &IdentifyOptions::default()),
        Err(IdentifyError::TooFewSamples {
            rows: 8,
            params: 10
        })
    ));
    // Weak excitation of MY1 (tiny parameter) with noise: flagged by the limit.
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let n = Normal::new(0.0, 1.0).unwrap();
    let mut ne = NormalEquations::new(2, 10);
    for (q, qd, qdd) in states(300, 9) {
        let y = regressor(q, qd, qdd);
        let t = torque(&y);
        ne.add_sample(&y, &[t[0] + n.sample(&mut rng), t[1] + n.sample(&mut rng)]);
    }
    let opt = IdentifyOptions {
        max_relative_std_pct: Some(10.0),
        ..Default::default()
    };
    let e = solve(&mut ne, &names(), &opt).unwrap_err();
    assert!(
        matches!(e, IdentifyError::PoorlyIdentified(_)) && e.to_string().contains("MY2"),
        "{e}"
    );
}

#[test]
fn merge_equals_single_accumulation() {
    let st = states(1000, 1);
    let mut a = NormalEquations::new(2, 10);
    let mut b = NormalEquations::new(2, 10);
    let mut c = NormalEquations::new(2, 10);
    for (k, (q, qd, qdd)) in st.iter().enumerate() {
        let y = regressor(*q, *qd, *qdd);
        let t = torque(&y);
        a.add_sample(&y, &t);
        if k < 333 {
            b.add_sample(&y, &t)
        } else {
            c.add_sample(&y, &t)
        }
    }
    b.merge(c);
    let x = solve(&mut a, &names(), &IdentifyOptions::default()).unwrap();
    let y = solve(&mut b, &names(), &IdentifyOptions::default()).unwrap();
    for i in 0..10 {
        assert!((x.values[i] - y.values[i]).abs() < 1e-9 * x.values[i].abs());
    }
}
