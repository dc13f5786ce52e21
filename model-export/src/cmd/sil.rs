//! `model-export sil`: the closed loop on the wrist, or the single-joint demos.
use anyhow::{bail, ensure};
use plant_sim::PlantParameters;
use robot::RobotSource;
use sil::wrist::{
    J, ModeReport, WristFeedforward, WristJointReport, WristLstm, WristReport, WristSetup,
    identified_wrist_model, markdown_table, run_wrist_on,
};

/// `model-export sil` options.
#[derive(Debug, Clone, clap::Args)]
pub struct SilArgs {
    /// Identified model (JSON from `identify`, joints 1-3 locked at 0): the model
    /// feedforward. Without it: the single-joint and coupled-load demos.
    #[arg(long = "identified", alias = "model", value_name = "FILE")]
    pub identified: Option<std::path::PathBuf>,
    /// Trained network (safetensors from `train`, or its directory), preset `paper`,
    /// `paper_relative` or `feedforward` on joints 4,5,6: the model + LSTM rows (f32 and
    /// int16).
    #[arg(
        long = "network",
        alias = "lstm",
        requires = "identified",
        value_name = "FILE"
    )]
    pub network: Option<std::path::PathBuf>,
    /// Robot description (must be the one the model was identified for).
    #[arg(long)]
    pub robot: Option<std::path::PathBuf>,
    /// The modelled chain of a URDF tree.
    #[command(flatten)]
    pub chain: crate::args::robot::ChainArgs,
    /// Plant file (true friction, ripple, ...); default: robots/default.plant.toml.
    #[arg(long)]
    pub plant: Option<std::path::PathBuf>,
    /// Reference of joints 4-6: a Fourier JSON (`excite`) or playback CSV; default the
    /// built-in seeded trajectory (`--seeded-trajectory`).
    #[arg(long)]
    pub trajectory: Option<std::path::PathBuf>,
    /// Seed of the built-in trajectory (2: `plant-report`'s test trajectory).
    #[arg(long, default_value_t = 2)]
    pub seeded_trajectory: u64,
    /// Periods of a Fourier trajectory.
    #[arg(long, default_value_t = 3)]
    pub periods: usize,
    /// Simulated seconds (default: the whole trajectory).
    #[arg(long)]
    pub seconds: Option<f64>,
    /// Compensator rate [Hz] (the LSTM's training rate: 100).
    #[arg(long, default_value_t = 100, value_parser = clap::value_parser!(u32).range(1..=20_000))]
    pub compensator_hz: u32,
    /// Sensor-noise seed.
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
    /// Wrist SIL: every board's friction adaptation with this forgetting time constant
    /// [s] instead of its joint profile's (0: off).
    #[arg(long)]
    pub adapt_time_constant_s: Option<f32>,
    /// Wrist SIL: every board's do-no-harm monitor with this window [s] instead of its
    /// joint profile's (0: off), with `--monitor-fade-s` and `--monitor-hysteresis`.
    #[arg(long)]
    pub monitor_window_s: Option<f32>,
    /// Time the monitor's gain takes to fade from 1 to 0 [s] (with `--monitor-window-s`).
    #[arg(long, default_value_t = 0.5, requires = "monitor_window_s")]
    pub monitor_fade_s: f32,
    /// Hysteresis of the monitor's gain, in [0, 1) (with `--monitor-window-s`).
    #[arg(long, default_value_t = 0.05, requires = "monitor_window_s")]
    pub monitor_hysteresis: f32,
    /// Also write the table as JSON (atomically).
    #[arg(long = "report", alias = "json", value_name = "FILE")]
    pub report: Option<std::path::PathBuf>,
    /// Also write the table as Markdown (atomically).
    #[arg(long = "report-md", alias = "markdown", value_name = "FILE")]
    pub report_md: Option<std::path::PathBuf>,
    /// Wrist SIL: also write the last feedforward's run in the drive's output format,
    /// a `candump -l` log of the CAN-FD frames its boards send (SYNC, state frames with
    /// compensator flags and feedforward), sealed with `--key-file`'s key; `telemetry`
    /// reads it.
    #[arg(long, value_name = "FILE", requires = "key_file")]
    pub candump: Option<std::path::PathBuf>,
    /// The robot's state-bus key for `--candump` (the key file `provision` takes).
    #[arg(long, value_name = "FILE", requires = "candump")]
    pub key_file: Option<std::path::PathBuf>,
}

/// Runs `model-export sil` on the wrist.
pub fn run(a: &SilArgs) -> anyhow::Result<()> {
    let Some(model_path) = &a.identified else {
        bail!("internal: the wrist SIL needs --identified");
    };
    let source = RobotSource::from(a.robot.clone());
    let robot = a.chain.load_and_warn(&source)?;
    let plant = match &a.plant {
        Some(p) => PlantParameters::load(p)?,
        None => PlantParameters::default_robot(),
    };
    let traj = plant_sim::trajectory::trajectory_or_seeded(
        a.trajectory.as_deref(),
        a.periods,
        a.seeded_trajectory,
        J,
    )?;
    let mut setup = WristSetup::new(robot, plant, traj, a.compensator_hz, a.seed)?;
    if let Some(t) = a.adapt_time_constant_s {
        ensure!(
            t.is_finite() && t >= 0.0,
            "--adapt-time-constant-s must be finite and >= 0 (0: off), not {t}"
        );
        for p in &mut setup.profiles {
            p.adaptation.time_constant_s = t;
        }
    }
    if let Some(w) = a.monitor_window_s {
        let monitor = firmware::monitor::MonitorConfig {
            window_s: w,
            fade_s: a.monitor_fade_s,
            hysteresis: a.monitor_hysteresis,
        };
        ensure!(
            w == 0.0 || monitor.per_tick(a.compensator_hz as f32).is_some(),
            "--monitor-window-s {w} / --monitor-fade-s {} / --monitor-hysteresis {}: the window \
             (at least two compensator ticks) and the fade (at least one) must be finite and \
             positive, the hysteresis in [0, 1); 0 turns the monitor off",
            a.monitor_fade_s,
            a.monitor_hysteresis
        );
        for p in &mut setup.profiles {
            p.monitor = monitor;
        }
    }
    if let Some(s) = a.seconds {
        artifacts::plausible::duration_s(s).map_err(|m| anyhow::anyhow!("--seconds {m}"))?;
        setup.duration_s = s.min(setup.duration_s);
    }
    let model = identified_wrist_model(&source, model_path, &a.chain.selection()?)?;
    let lstm = a.network.as_deref().map(WristLstm::load).transpose()?;
    let modes: Vec<WristFeedforward> = WristFeedforward::ALL
        .into_iter()
        .filter(|m| {
            lstm.is_some()
                || !matches!(
                    m,
                    WristFeedforward::ModelLstmF32 | WristFeedforward::ModelLstmInt16
                )
        })
        .collect();
    let key = match &a.key_file {
        Some(p) => {
            let text = std::fs::read_to_string(p)
                .map_err(|e| anyhow::anyhow!("reading {}: {e}", p.display()))?;
            Some(super::provision::parse_key(p, &text)?)
        }
        None => None,
    };
    let last = modes.last().copied();
    let mut candump = None;
    // The runs are independent: one thread each; the last one on a recording bus
    // with --candump.
    let results: Vec<anyhow::Result<[WristJointReport; J]>> = std::thread::scope(|sc| {
        let hs: Vec<_> = modes
            .iter()
            .map(|&m| {
                let (setup, model, lstm) = (&setup, &model, lstm.as_ref());
                let record = key.filter(|_| Some(m) == last);
                let seed = a.seed;
                sc.spawn(move || {
                    let mut bus = match record {
                        Some(k) => sil::StateBus::recording(sil::candump::CandumpRecorder::new(
                            &k,
                            (seed as u16) ^ 0x5E55,
                        )),
                        None => sil::StateBus::default(),
                    };
                    let r = run_wrist_on(setup, m, Some(model), lstm, &mut bus);
                    r.map(|r| (r, bus.recorder().map(|c| c.text().to_string())))
                })
            })
            .collect();
        hs.into_iter()
            .map(|h| {
                let (r, text) = h
                    .join()
                    .unwrap_or_else(|_| Err(anyhow::anyhow!("SIL thread panicked")))?;
                if text.is_some() {
                    candump = text;
                }
                Ok(r)
            })
            .collect()
    });
    let mut reports = Vec::new();
    for (m, r) in modes.iter().zip(results) {
        reports.push(ModeReport {
            feedforward: m.name().to_string(),
            joints: r?.to_vec(),
        });
    }
    let title = format!(
        "wrist SIL: joints 4-6 of {} (1-3 locked at 0; drives, compensators and motors from its joint profiles, boards configured as joints 4, 5, 6), true plant {:?}; {:.1} s at {} Hz PWM, outer loops {} Hz, compensator {} Hz, bus latency 1 tick, seed {}; friction adaptation time constant {} s, do-no-harm monitor window {} s (0: off); model {}{}",
        source,
        setup.effects,
        setup.duration_s,
        setup.hardware[0].pwm_hz,
        setup.profiles[0].cascade.rate_hz,
        a.compensator_hz,
        a.seed,
        setup.profiles[0].adaptation.time_constant_s,
        setup.profiles[0].monitor.window_s,
        model_path.display(),
        a.network
            .as_ref()
            .map(|p| format!(
                ", LSTM {} (preset {:?})",
                p.display(),
                lstm.as_ref().map(|l| l.preset)
            ))
            .unwrap_or_default()
    );
    artifacts::ensure_finite(
        "the wrist SIL results",
        reports
            .iter()
            .flat_map(|r| &r.joints)
            .flat_map(|j| [j.rms_error_rad, j.max_error_rad, j.rms_iq_a]),
    )?;
    let md = format!("{title}\n\n{}", markdown_table(&reports));
    print!("{md}");
    let json = match &a.report {
        Some(_) => Some(serde_json::to_string_pretty(&WristReport {
            title: title.clone(),
            duration_s: setup.duration_s,
            compensator_hz: f64::from(a.compensator_hz),
            seed: a.seed,
            results: reports.clone(),
        })?),
        None => None,
    };
    // The Markdown and the JSON table: both or neither.
    if let (Some(p), Some(m)) = (&a.candump, last) {
        println!(
            "{}: the {} run's CAN-FD frames (candump -l)",
            p.display(),
            m.name()
        );
    }
    let files: Vec<(&std::path::Path, &[u8])> = [
        a.report_md.as_deref().map(|p| (p, md.as_bytes())),
        a.report.as_deref().zip(json.as_deref().map(str::as_bytes)),
        a.candump
            .as_deref()
            .zip(candump.as_deref().map(str::as_bytes)),
    ]
    .into_iter()
    .flatten()
    .collect();
    artifacts::write_atomic_all(&files)
}
