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
    /// Identify a robot's base parameters (rigid body + friction) from logs by least
    /// squares; write the model JSON and print per-joint RMS errors.
    ///
    /// Example (UR10e data): model-export identify --robot ur10e.urdf --log a.csv
    /// --log b.csv --validate c.csv -o ur10e-model.json
    Identify(Box<crate::identify::commands::IdentifyArgs>),
    /// Predict joint torques for a log or a CSV of states with the robot's nominal
    /// parameters or an identified model (firmware f32 model); write them as CSV.
    Torque(Box<crate::identify::commands::TorqueArgs>),
    /// Simulate the true plant along a commanded trajectory and write the controller's log (CSV).
    Simulate(crate::sim::cli::SimulateArgs),
    /// Identify rigid body + friction on simulated logs and print the per-joint uncompensated RMS table.
    PlantReport(crate::sim::cli::PlantReportArgs),
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
        Command::Identify(a) => crate::identify::commands::identify(&a),
        Command::Torque(a) => crate::identify::commands::torque(&a),
        Command::Simulate(args) => crate::sim::cli::run_simulate(&args),
        Command::PlantReport(args) => crate::sim::cli::run_plant_report(&args),
    }
}
