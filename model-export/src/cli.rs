//! Command-line interface: one subcommand per pipeline stage.
use crate::cmd::{self, evaluate::EvaluateArgs, import::ImportArgs, train::TrainArgs};
use clap::{Parser, Subcommand};
use std::path::{Path, PathBuf};

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
    /// Software in the loop: the firmware's drives and compensators on the paper's wrist
    /// (joints 4-6 on the plant simulator's true dynamics, friction and ripple); prints
    /// per joint RMS tracking error and RMS q current for no feedforward, the identified
    /// model (--identified), and model + LSTM f32 / int16 (--network). Without --identified: the
    /// single-joint and coupled-load demos.
    Sil {
        /// Wrist options (`--identified` selects the wrist; without it the demos run).
        #[command(flatten)]
        wrist: Box<crate::cmd::sil::SilArgs>,
    },
    /// Identify a robot's base parameters (rigid body + friction) from logs by least
    /// squares; write the model JSON and print per-joint RMS errors.
    ///
    /// Example (UR10e data): model-export identify --robot ur10e.urdf --log a.csv
    /// --log b.csv --validation-log c.csv -o ur10e-model.json
    Identify(Box<crate::cmd::identify::IdentifyArgs>),
    /// Predict joint torques for a log or a CSV of states with the robot's nominal
    /// parameters or an identified model (firmware f32 model); write them as CSV.
    Torque(Box<crate::cmd::identify::TorqueArgs>),
    /// Train the LSTM compensation network on CSV logs (each file split into contiguous
    /// train / validation / test blocks), evaluate it by streaming the firmware step over
    /// each test block, write the model (safetensors), the loss curve and a report.
    Train(TrainArgs),
    /// Evaluate a model by streaming the firmware f32 step over whole CSV logs: per output
    /// RMS before (identified model only) and after compensation, reduction, persistence.
    Evaluate(EvaluateArgs),
    /// Import a model saved from PyTorch (safetensors with PyTorch names, or ONNX from
    /// `torch.onnx.export`; see the README), validate it and write it in our format;
    /// optionally check it against a reference.
    Import(ImportArgs),
    /// Design an optimised Fourier excitation trajectory (coefficients JSON, playback CSV, plot).
    Excite(Box<crate::cmd::excite::ExciteArgs>),
    /// Simulate the true plant along a commanded trajectory and write the controller's log (CSV).
    Simulate(crate::cmd::simulate::SimulateArgs),
    /// Identify rigid body + friction on simulated logs and print the per-joint uncompensated RMS table.
    PlantReport(crate::cmd::simulate::PlantReportArgs),
    /// The main job: the whole pipeline on the built-in default robot (the paper's wrist
    /// setup), every stage as its own subcommand, into one report folder (Markdown + JSON).
    Demo(crate::cmd::demo::DemoArgs),
    /// Quantise a model (f32 / int16 / int8) and write ONE Rust source file of fixed-size
    /// arrays in the firmware kernels' layout (with normalisation, feature preset,
    /// joints, control rate, dynamics, schema version, content hash and a self-check
    /// digest); optionally report accuracy per precision on a CSV log.
    Export(crate::cmd::export::ExportArgs),
    /// Write a drive's configuration block (joint number, the robot's state-bus key)
    /// as a `.bin` and print the `probe-rs download` line that flashes it.
    Provision(crate::cmd::provision::ProvisionArgs),
    /// Read the drives' telemetry (state frames, compensator flags) from a `candump -l`
    /// log of the CAN-FD state bus into a log (CSV) that `torque`, `train` and `evaluate` read.
    Telemetry(crate::cmd::telemetry::TelemetryArgs),
}

/// The files a command reads and the files it writes (for
/// [`artifacts::refuse_outputs_that_are_inputs`]).
fn files(command: &Command) -> (Vec<&Path>, Vec<&Path>) {
    fn all(v: &[PathBuf]) -> impl Iterator<Item = &Path> {
        v.iter().map(PathBuf::as_path)
    }
    match command {
        Command::Identify(a) => (
            a.robot
                .as_deref()
                .into_iter()
                .chain(all(&a.logs))
                .chain(all(&a.validation))
                .collect(),
            vec![&a.out],
        ),
        Command::Torque(a) => (
            [a.robot.as_ref(), a.identified.as_ref(), Some(&a.log)]
                .into_iter()
                .flatten()
                .map(PathBuf::as_path)
                .collect(),
            vec![&a.out],
        ),
        Command::Train(a) => (
            all(&a.data).chain(all(&a.validation_data)).collect(),
            [Some(&a.out), Some(&a.loss_plot), a.report.as_ref()]
                .into_iter()
                .flatten()
                .map(PathBuf::as_path)
                .collect(),
        ),
        Command::Evaluate(a) => (
            std::iter::once(a.network.as_path())
                .chain(all(&a.data))
                .chain(all(&a.baseline_data))
                .collect(),
            a.report.iter().map(PathBuf::as_path).collect(),
        ),
        Command::Import(a) => (
            std::iter::once(a.network.as_path())
                .chain(a.reference.as_deref())
                .collect(),
            vec![&a.out],
        ),
        Command::Export(a) => (
            [
                &a.network,
                &a.robot,
                &a.identified,
                &a.accuracy_log,
                &a.budgets,
            ]
            .into_iter()
            .flatten()
            .map(PathBuf::as_path)
            .chain(all(&a.gate_data))
            .collect(),
            std::iter::once(a.out.as_path())
                .chain(a.report.as_deref())
                .collect(),
        ),
        Command::Simulate(a) => (
            [&a.plant.robot, &a.plant.plant, &a.trajectory]
                .into_iter()
                .flatten()
                .map(PathBuf::as_path)
                .collect(),
            vec![&a.out],
        ),
        Command::Sil { wrist: a } => (
            [
                &a.identified,
                &a.network,
                &a.robot,
                &a.plant,
                &a.trajectory,
                &a.key_file,
            ]
            .into_iter()
            .flatten()
            .map(PathBuf::as_path)
            .collect(),
            [&a.report, &a.report_md, &a.candump]
                .into_iter()
                .flatten()
                .map(PathBuf::as_path)
                .collect(),
        ),
        Command::Provision(a) => (vec![&a.key_file], vec![&a.out]),
        Command::Telemetry(a) => (vec![&a.log, &a.key_file], vec![&a.out]),
        _ => (Vec::new(), Vec::new()),
    }
}

/// The files `excite` writes (they are derived from `--out` and `--name`).
fn excite_outputs(a: &crate::cmd::excite::ExciteArgs) -> Vec<PathBuf> {
    ["json", "csv", "svg"]
        .iter()
        .map(|ext| a.out.join(format!("{}.{ext}", a.name)))
        .collect()
}

/// Parses a whole command line (program name first), printing a warning on standard
/// error for each old spelling of a renamed flag ([`crate::args::renamed`]).
pub fn parse_from<I, T>(line: I) -> Result<Cli, clap::Error>
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    let line: Vec<std::ffi::OsString> = line.into_iter().map(Into::into).collect();
    let text: Vec<String> = line
        .iter()
        .skip(1)
        .map(|a| a.to_string_lossy().into_owned())
        .collect();
    for warning in crate::args::renamed::warnings(&text) {
        eprintln!("{warning}");
    }
    Cli::try_parse_from(line)
}

/// Parses the arguments after `model-export` and runs them, as the binary does with its
/// command line.
pub fn run_args(args: &[&str]) -> anyhow::Result<()> {
    let line = std::iter::once("model-export").chain(args.iter().copied());
    run(parse_from(line)?)
}

/// Runs one parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    let (inputs, outputs) = files(&cli.command);
    artifacts::refuse_outputs_that_are_inputs(&inputs, &outputs)?;
    if let Command::Excite(a) = &cli.command {
        let outs = excite_outputs(a);
        let outs: Vec<&Path> = outs.iter().map(PathBuf::as_path).collect();
        artifacts::refuse_outputs_that_are_inputs(
            &a.robot.as_deref().into_iter().collect::<Vec<_>>(),
            &outs,
        )?;
    }
    match cli.command {
        Command::Excite(args) => crate::cmd::excite::run(&args),
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
        Command::Sil { wrist } => {
            if wrist.identified.is_some() {
                crate::cmd::sil::run(&wrist)
            } else if wrist.candump.is_some() {
                anyhow::bail!("--candump is for the wrist SIL: give --identified too")
            } else if wrist.adapt_time_constant_s.is_some() || wrist.monitor_window_s.is_some() {
                anyhow::bail!(
                    "--adapt-time-constant-s and --monitor-window-s are for the wrist SIL: give --identified too"
                )
            } else {
                run_sil(wrist.seconds.unwrap_or(5.0), wrist.seed)
            }
        }
        Command::Identify(a) => crate::cmd::identify::identify(&a),
        Command::Torque(a) => crate::cmd::identify::torque(&a),
        Command::Train(a) => cmd::train::run(a),
        Command::Evaluate(a) => cmd::evaluate::run(a),
        Command::Import(a) => cmd::import::run(a),
        Command::Simulate(args) => crate::cmd::simulate::run_simulate(&args),
        Command::PlantReport(args) => crate::cmd::simulate::run_plant_report(&args),
        Command::Export(a) => crate::cmd::export::run(a),
        Command::Provision(a) => crate::cmd::provision::run(&a),
        Command::Telemetry(a) => crate::cmd::telemetry::run(&a),
        Command::Demo(a) => crate::cmd::demo::demo(&a, &mut crate::cmd::demo::WithoutCargo),
    }
}

fn run_sil(seconds: f64, seed: u64) -> anyhow::Result<()> {
    use sil::{FeedforwardMode, SingleJointSetup, run_single_joint};
    anyhow::ensure!(
        seconds.is_finite() && seconds > 0.0 && seconds <= 600.0,
        "--seconds must be in (0, 600]"
    );
    println!(
        "single joint (the compiled-in model's joint 4: its drive profile, configured by its block; 20 kHz PWM), {seconds} s, seed {seed}"
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
    for hz in [100, 1000] {
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
    use sil::multi::{MultiFeedforward, MultiJointSetup, run_multi_joint};
    let mut setup = MultiJointSetup::wrist(1000, seed)?;
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
