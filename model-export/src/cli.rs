//! Command-line interface: one subcommand per pipeline stage.
use clap::{Parser, Subcommand};

/// `model-export`: identify a robot's dynamics, learn what the model misses, and
/// export both as fixed-size arrays for the joint-drive firmware.
#[derive(Debug, Parser)]
#[command(name = "model-export", version, about)]
pub struct Cli {
    /// The stage to run.
    #[command(subcommand)]
    pub command: Command,
}

/// Pipeline stages.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Print the firmware's math primitives over a range (a smoke test of the shared numerics).
    Primitives {
        /// Number of points in [-4, 4].
        #[arg(long, default_value_t = 9)]
        points: usize,
    },
    /// Software in the loop: the firmware's control loop drives a simulated joint
    /// (motor, gear, load, sensors); prints tracking error and current per feedforward.
    Sil {
        /// Simulated seconds per run.
        #[arg(long, default_value_t = 5.0)]
        seconds: f64,
        /// Sensor-noise seed.
        #[arg(long, default_value_t = 7)]
        seed: u64,
    },
    /// Identify a robot's base parameters (rigid body + friction) from logs by least
    /// squares; write the model JSON and print per-joint RMS errors.
    ///
    /// Example (UR10e data): model-export identify --robot ur10e.urdf --log a.csv
    /// --log b.csv --validate c.csv -o ur10e-model.json
    Identify(Box<crate::identify::commands::IdentifyArgs>),
    /// Predict joint torques for a log or a CSV of states with the robot's nominal
    /// parameters or an identified model (firmware f32 model); write them as CSV.
    Torque(Box<crate::identify::commands::TorqueArgs>),
}

/// Runs one parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Primitives { points } => {
            println!("{:>10} {:>12} {:>12} {:>12}", "x", "exp", "tanh", "sigmoid");
            for i in 0..points {
                let x = -4.0 + 8.0 * i as f32 / (points.max(2) - 1) as f32;
                println!(
                    "{:>10.4} {:>12.6} {:>12.6} {:>12.6}",
                    x,
                    firmware::math::exp(x),
                    firmware::math::tanh(x),
                    firmware::math::sigmoid(x)
                );
            }
            Ok(())
        }
        Command::Sil { seconds, seed } => run_sil(seconds, seed),
        Command::Identify(a) => crate::identify::commands::identify(&a),
        Command::Torque(a) => crate::identify::commands::torque(&a),
    }
}

fn run_sil(seconds: f64, seed: u64) -> anyhow::Result<()> {
    use crate::sil::{FeedforwardMode, SingleJointSetup, run_single_joint};
    anyhow::ensure!(
        seconds.is_finite() && seconds > 0.0 && seconds <= 600.0,
        "--seconds must be in (0, 600]"
    );
    println!(
        "single joint (wrist-sized, gear 100, 20 kHz PWM, outer loops 5 kHz), {seconds} s, seed {seed}"
    );
    println!(
        "{:<28} {:>9} {:>16} {:>16} {:>12} {:>16}",
        "feedforward", "comp. Hz", "RMS error mrad", "max error mrad", "RMS iq A", "RMS feedback A"
    );
    let modes = [
        ("none", FeedforwardMode::None),
        (
            "inverse dynamics x0.8",
            FeedforwardMode::InverseDynamics(0.8),
        ),
        (
            "perfect inverse dynamics",
            FeedforwardMode::InverseDynamics(1.0),
        ),
    ];
    for hz in [100.0, 1000.0] {
        for (name, mode) in modes {
            let mut setup = SingleJointSetup::wrist_joint(hz, seed);
            setup.duration_s = seconds;
            let r = run_single_joint(&setup, mode)?;
            println!(
                "{:<28} {:>9} {:>16.4} {:>16.4} {:>12.3} {:>16.3}",
                name,
                hz,
                r.rms_error_rad * 1e3,
                r.max_error_rad * 1e3,
                r.rms_iq_a,
                r.rms_feedback_current_a
            );
        }
    }
    println!();
    println!(
        "wrist: 3 coupled joints, one firmware drive + compensator (1 kHz) per joint, states exchanged as wire frames with one tick of latency, {seconds} s"
    );
    println!(
        "{:<34} {:>6} {:>16} {:>12}",
        "feedforward", "joint", "RMS error mrad", "RMS iq A"
    );
    use crate::sil::multi::{MultiFeedforward, MultiJointSetup, run_multi_joint};
    let mut setup = MultiJointSetup::wrist(1000.0, seed);
    setup.duration_s = seconds;
    for (name, mode) in [
        ("none", MultiFeedforward::Mode(FeedforwardMode::None)),
        (
            "inverse dynamics, own joint only",
            MultiFeedforward::Decoupled,
        ),
        (
            "inverse dynamics, all joints (bus)",
            MultiFeedforward::Mode(FeedforwardMode::InverseDynamics(1.0)),
        ),
    ] {
        let r = run_multi_joint(&setup, mode)?;
        for (j, jr) in r.iter().enumerate() {
            println!(
                "{:<34} {:>6} {:>16.4} {:>12.3}",
                name,
                j,
                jr.rms_error_rad * 1e3,
                jr.rms_iq_a
            );
        }
    }
    Ok(())
}
