//! Identification benchmark: a UR-type 6R arm (48 base parameters with viscous and
//! Coulomb friction), 100 000 simulated samples (600 000 equations; the identification
//! tests' arm and seeded excitation, 0.5 N·m noise).
//!
//! Run: `cargo bench -p model-export --bench identify`. Prints wall-clock times of
//! the stages (best of 3 runs) on this machine; target: whole identification < 1 s.
//! `cargo test` runs it as a smoke test on 5 000 samples.

use identify::pipeline::{self, LinearModel};
use identify::{IdentifyOptions, Weighting, solve};
use std::time::Instant;
use test_support::bench::BenchRun;

// The identification tests' arm and its simulated logs (one source).
#[path = "../../crates/identify/tests/support/arm.rs"]
mod arm;

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
    let m = arm::robot_model();
    let names = m.parameter_names();
    let logs = [arm::simulate(&m, samples, 42, Some(&[0.5; 6]))];
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
