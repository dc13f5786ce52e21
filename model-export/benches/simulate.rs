//! Benchmark: simulate 60 s of the default 6-DoF arm at a 1 kHz internal rate (the
//! simulator's target: under 2 s). Prints a table; run with `cargo bench -p model-export --bench simulate`
//! (`cargo test` runs it as a smoke test: one 10 s period, once).
use excitation::{ExcitationTrajectory, JointFourier};
use plant_sim::{self, CommandedTrajectory, PlantEffects, PlantParameters, SimulationConfig};
use std::time::Instant;
use test_support::bench::BenchRun;

fn main() {
    let run = BenchRun::from_args();
    let robot = robot::Robot::load(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../robots/default.toml"
    ))
    .expect("default robot");
    let arm = plant_sim::RobotRigidBody::new(&robot);
    let plant = PlantParameters::default_robot();
    let series = ExcitationTrajectory {
        period_s: 10.0,
        harmonics: 5,
        joints: (0..6)
            .map(|j| JointFourier {
                q0_rad: 0.1 * j as f64,
                a_rad: (1..=5)
                    .map(|k| 0.3 / k as f64 * (1.0 + 0.1 * j as f64))
                    .collect(),
                b_rad: (1..=5).map(|k| 0.2 / (k * k) as f64).collect(),
            })
            .collect(),
    };
    let traj = CommandedTrajectory::Fourier {
        series,
        periods: run.size(6, 1),
    };
    let repeats = run.size(5, 1);
    println!(
        "{:<28} {:>10} {:>12} {:>12}",
        "case", "sim [s]", "wall [s]", "x realtime"
    );
    for (name, effects) in [
        ("all effects", PlantEffects::all()),
        ("ideal (no effects)", PlantEffects::none()),
    ] {
        let mut cfg = SimulationConfig::new(6, 6);
        cfg.effects = effects;
        let mut best = f64::INFINITY;
        let mut rows = 0;
        for _ in 0..repeats {
            let t0 = Instant::now();
            let log = plant_sim::simulate(&arm, &plant, &traj, &cfg).expect("simulate");
            best = best.min(t0.elapsed().as_secs_f64());
            rows = log.rows.len();
        }
        println!(
            "{:<28} {:>10.1} {:>12.4} {:>12.0}   ({rows} log rows, {} internal steps, best of {repeats})",
            name,
            traj.duration_s(),
            best,
            traj.duration_s() / best,
            (traj.duration_s() * cfg.internal_rate_hz).round() as u64 + 1
        );
    }
}
