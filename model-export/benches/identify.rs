//! Identification benchmark: a UR-type 6R arm (48 base parameters with viscous and
//! Coulomb friction), 100 000 simulated samples (600 000 equations).
//!
//! Run: `cargo bench -p model-export --bench identify`. Prints wall-clock times of
//! the stages (best of 3 runs) on this machine; target: whole identification < 1 s.
//! `cargo test` runs it as a smoke test on 5 000 samples.

use identify::identified::{ModelSelection, RobotBaseModel, load_robot};
use identify::pipeline::{self, LinearModel};
use identify::{IdentifyOptions, Weighting, solve};
use logs::Samples;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use robot::RobotSource;
use std::path::PathBuf;
use std::time::Instant;
use test_support::bench::BenchRun;

const ROBOT: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../crates/identify/tests/data/ur_type_6r.toml"
);

fn simulate(m: &RobotBaseModel, n: usize) -> Samples {
    let mut rng = ChaCha8Rng::seed_from_u64(42);
    let w = 2.0 * std::f64::consts::PI / 20.0;
    let mut s = Samples {
        path: PathBuf::from("bench"),
        sha256: String::new(),
        time_s: (0..n).map(|k| k as f64 * 0.01).collect(),
        q_rad: (0..6).map(|_| Vec::with_capacity(n)).collect(),
        qd_rad_s: (0..6).map(|_| Vec::with_capacity(n)).collect(),
        qdd_rad_s2: (0..6).map(|_| Vec::with_capacity(n)).collect(),
        torque_nm: None,
    };
    for j in 0..6 {
        let c: Vec<(f64, f64)> = (0..5)
            .map(|_| (rng.gen_range(-0.5..0.5), rng.gen_range(-0.5..0.5)))
            .collect();
        for k in 0..n {
            let t = s.time_s[k];
            let (mut q, mut qd, mut qdd) = (0.0, 0.0, 0.0);
            for (h, (a, b)) in c.iter().enumerate() {
                let wl = w * (h + 1) as f64;
                let (sn, cs) = (wl * t).sin_cos();
                q += a / wl * sn - b / wl * cs;
                qd += a * cs + b * sn;
                qdd += -a * wl * sn + b * wl * cs;
            }
            s.q_rad[j].push(q);
            s.qd_rad_s[j].push(qd);
            s.qdd_rad_s2[j].push(qdd);
        }
    }
    let beta = m.base.beta(&m.robot.standard_parameters());
    let mut tau = pipeline::predict(m, &beta, &s);
    let noise = Normal::new(0.0, 0.5).unwrap();
    tau.iter_mut()
        .flatten()
        .for_each(|v| *v += noise.sample(&mut rng));
    s.torque_nm = Some(tau);
    s
}

fn best<T>(mut f: impl FnMut() -> T) -> (f64, T) {
    let mut out = None;
    let mut t_best = f64::INFINITY;
    for _ in 0..3 {
        let t0 = Instant::now();
        let r = f();
        t_best = t_best.min(t0.elapsed().as_secs_f64());
        out = Some(r);
    }
    (t_best, out.unwrap())
}

fn main() {
    let samples = BenchRun::from_args().size(100_000, 5_000);
    let source = RobotSource::File(ROBOT.into());
    let m = RobotBaseModel::new(
        load_robot(&source, &ModelSelection::default())
            .unwrap()
            .robot,
    )
    .unwrap();
    let names = m.parameter_names();
    let logs = [simulate(&m, samples)];
    let s = &logs[0];
    let j = m.modelled_log_joints();

    let (t_reg, _) = best(|| {
        let mut acc = 0.0;
        let mut k0 = 0;
        while k0 < s.len() {
            let k1 = (k0 + pipeline::STATE_BLOCK).min(s.len());
            acc += m.regressor_block(&pipeline::states(s, &j, k0, k1))[(0, 0)];
            k0 = k1;
        }
        acc
    });
    let (t_acc, ne) = best(|| pipeline::accumulate(&m, &logs));
    let (t_ols, _) = best(|| solve(&mut ne.clone(), &names, &IdentifyOptions::default()).unwrap());
    let wls = IdentifyOptions {
        weighting: Weighting::PerJointFromOls,
        ..Default::default()
    };
    let (t_wls, id) = best(|| solve(&mut ne.clone(), &names, &wls).unwrap());

    println!(
        "identification benchmark: UR-type 6R, {} base parameters, {samples} samples ({} equations)",
        names.len(),
        6 * samples
    );
    println!("wall-clock, best of 3, this machine");
    println!("{:<58} {:>10}", "stage", "time [s]");
    println!(
        "{:<58} {:>10.3}",
        "regressor only (f64 RNEA-based, blocks of 256 states)", t_reg
    );
    println!(
        "{:<58} {:>10.3}",
        "regressor + normal equations (blocked gemm)", t_acc
    );
    println!(
        "{:<58} {:>10.4}",
        "solve OLS (equilibrate, eigen, Cholesky, std)", t_ols
    );
    println!(
        "{:<58} {:>10.4}",
        "solve WLS (OLS pass + weighted pass)", t_wls
    );
    println!(
        "{:<58} {:>10.3}",
        "total identification (accumulate + WLS)",
        t_acc + t_wls
    );
    println!("(normal-equation folding alone ≈ {:.3} s)", t_acc - t_reg);
    println!(
        "condition number {:.3e}, scaled {:.3e}; per-joint sigma {:?}",
        id.condition_number, id.condition_number_scaled, id.joint_sigma_nm
    );
}
