//! The identification tests' arm and its simulated logs (torque = regressor x true
//! parameters along a seeded Fourier excitation), shared by the library's tests and the
//! command line's (`#[path]`-included, one source).
#![allow(dead_code)]

use identify::identified::{ModelSelection, RobotBaseModel, load_robot};
use identify::pipeline;
use logs::Samples;
use nalgebra::DVector;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use robot::RobotSource;
use std::path::PathBuf;
use std::sync::LazyLock;

/// The test arm's description (a UR-type 6R in DH TOML), as a path.
pub static ROBOT: LazyLock<String> = LazyLock::new(|| {
    test_support::workspace_root()
        .join("crates/identify/tests/data/ur_type_6r.toml")
        .display()
        .to_string()
});

pub fn robot_model() -> RobotBaseModel {
    RobotBaseModel::new(
        load_robot(
            &RobotSource::File(ROBOT.as_str().into()),
            &ModelSelection::default(),
        )
        .unwrap()
        .robot,
    )
    .unwrap()
}

/// A Fourier excitation (5 harmonics, 10 s period) sampled at `t`.
pub fn fourier_states(t: &[f64], seed: u64) -> Samples {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let w = 2.0 * std::f64::consts::PI / 10.0;
    let n = 6;
    let mut s = Samples {
        path: PathBuf::from("sim"),
        sha256: String::new(),
        time_s: t.to_vec(),
        q_rad: vec![Vec::new(); n],
        qd_rad_s: vec![Vec::new(); n],
        qdd_rad_s2: vec![Vec::new(); n],
        torque_nm: None,
    };
    for j in 0..n {
        let q0: f64 = rng.gen_range(-1.0..1.0);
        let c: Vec<(f64, f64)> = (0..5)
            .map(|_| (rng.gen_range(-0.5..0.5), rng.gen_range(-0.5..0.5)))
            .collect();
        for &tk in t {
            let (mut q, mut qd, mut qdd) = (q0, 0.0, 0.0);
            for (h, (a, b)) in c.iter().enumerate() {
                let wl = w * (h + 1) as f64;
                let (sn, cs) = (wl * tk).sin_cos();
                q += a / wl * sn - b / wl * cs;
                qd += a * cs + b * sn;
                qdd += -a * wl * sn + b * wl * cs;
            }
            s.q_rad[j].push(q);
            s.qd_rad_s[j].push(qd);
            s.qdd_rad_s2[j].push(qdd);
        }
    }
    s
}

// Noise-free recovery: every base parameter to 1e-6 relative; parameters whose true
// value is exactly 0 (no relative error exists) to 1e-9 of the largest parameter.

/// True base parameters: those of the robot's nominal standard parameters.
pub fn true_beta(m: &RobotBaseModel) -> DVector<f64> {
    m.base.beta(&m.robot.standard_parameters())
}

pub fn simulate(
    m: &RobotBaseModel,
    samples: usize,
    seed: u64,
    noise_nm: Option<&[f64]>,
) -> Samples {
    let t: Vec<f64> = (0..samples).map(|k| k as f64 * 0.01).collect();
    let mut s = fourier_states(&t, seed);
    let mut tau = pipeline::predict(m, &true_beta(m), &s);
    if let Some(sig) = noise_nm {
        let mut rng = ChaCha8Rng::seed_from_u64(seed + 1);
        for (j, col) in tau.iter_mut().enumerate() {
            let d = Normal::new(0.0, sig[j]).unwrap();
            col.iter_mut().for_each(|v| *v += d.sample(&mut rng));
        }
    }
    s.torque_nm = Some(tau);
    s
}
