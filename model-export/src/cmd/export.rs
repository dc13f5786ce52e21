//! `model-export export`: quantise a network and write the firmware model file.
use crate::args::choice::named;
use anyhow::{Context, Result, bail};
use compnet::model::LstmModel;
use firmware::nn::format::FeaturePreset;
use firmware::nn::reference::LstmDims;
use fw_export::*;
use robot::RobotSource;
use robot::dynamics::firmware_model::FirmwareModel;
use std::path::{Path, PathBuf};

/// `model-export export`.
#[derive(Debug, clap::Args)]
pub struct ExportArgs {
    /// Network to export (safetensors written by `train` / `import`, or ONNX exported
    /// from PyTorch). Without it, a seeded PyTorch-style initialisation of the size
    /// `--dims` (for benchmarks and the committed default until a trained network
    /// replaces it).
    #[arg(long = "network", alias = "model", value_name = "FILE")]
    pub network: Option<PathBuf>,
    /// Sizes `I,E,H,O` of the seeded network (without `--network`).
    #[arg(long, value_delimiter = ',', default_value = "9,64,64,3")]
    pub dims: Vec<usize>,
    /// Seed of the seeded network.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Feature preset of the seeded network (one of the firmware's presets).
    #[arg(long, value_parser = named::<FeaturePreset>(), default_value = "paper")]
    pub preset: FeaturePreset,
    /// Compensated joints, numbered from 1 like every other command's `--joints`
    /// (the generated file's `JOINT_INDICES` are their 0-based indices).
    #[arg(long, value_delimiter = ',', default_value = "4,5,6")]
    pub joints: Vec<usize>,
    /// Control rate [Hz].
    #[arg(long, default_value_t = 100)]
    pub control_rate_hz: u32,
    /// Precision.
    #[arg(long, value_parser = named::<Precision>(), default_value = "int16")]
    pub precision: Precision,
    /// Robot description (DH TOML or URDF) whose nominal rigid-body model is
    /// exported with the network.
    #[arg(long)]
    pub robot: Option<PathBuf>,
    /// Identified model (JSON from `identify`) of `--robot` (default: the built-in default
    /// robot): its parameters and joint selection are exported with the network.
    #[arg(long)]
    pub identified: Option<PathBuf>,
    /// The modelled chain of a URDF tree (`--robot` without `--identified`; an
    /// identified model brings its own).
    #[command(flatten)]
    pub chain: crate::args::robot::ChainArgs,
    /// Output Rust file (written to a temporary file, then renamed).
    #[arg(long)]
    pub out: PathBuf,
    /// Flash budget file (`host-tests/budgets.toml`): the network must fit the
    /// board binary's flash limit.
    #[arg(long)]
    pub budgets: Option<PathBuf>,
    /// Where the model's arrays (network, linear stage, rigid-body model) live on
    /// the target: `auto` puts them in SRAM (copied from flash at reset, zero wait
    /// states) when they fit the SRAM budget of `--budgets` (the board's RAM in its
    /// `memory.x` and budget, less the stack reserve and the firmware's own RAM), in
    /// flash otherwise.
    #[arg(long, value_parser = named::<WeightsIn>(), default_value = "auto")]
    pub weights_in: WeightsIn,
    /// Steps of golden input in the self-check digest.
    #[arg(long, default_value_t = 1000)]
    pub self_check_steps: usize,
    /// CSV log (columns of the model's `paper` / `feedforward` preset for
    /// `--joints`, as `model-export torque --dataset` writes them): print per output,
    /// for every precision streamed over it, the RMS
    /// against the f32 firmware step and the compensated RMS against the targets
    /// beside f32's.
    #[arg(long)]
    pub accuracy_log: Option<PathBuf>,
    /// With `--accuracy-log`: also write the accuracy rows as JSON here.
    #[arg(
        long = "report",
        alias = "accuracy-json",
        requires = "accuracy_log",
        value_name = "FILE"
    )]
    pub report: Option<PathBuf>,
    /// Do-no-harm gate: validation runs (compensation datasets, whole runs the
    /// network never trained on; repeat or comma-separate). A trained network is
    /// refused when, on any of them, it is worse than the model alone on any
    /// compensated joint. Required with `--network` unless `--allow-worse`.
    #[arg(long = "gate-data", value_name = "CSV", value_delimiter = ',')]
    pub gate_data: Vec<PathBuf>,
    /// Export even when the gate finds the network worse than the model alone (or
    /// without `--gate-data`); the generated file then carries a warning.
    #[arg(long)]
    pub allow_worse: bool,
    /// Every compensated joint's friction adaptation with this forgetting time constant
    /// [s] instead of its profile's (0: off; limit as in the profile).
    #[arg(long)]
    pub adapt_time_constant_s: Option<f32>,
    /// Every compensated joint's do-no-harm monitor with this window [s] instead of its
    /// profile's (0: off; fade and hysteresis as in the profile).
    #[arg(long)]
    pub monitor_window_s: Option<f32>,
    /// Training datasets (CSV written by `torque --dataset`, whole runs) from which to
    /// record the training envelope of `--joints` (`firmware::envelope`), for a network
    /// that carries none (imported from PyTorch) or to replace the one it carries.
    #[arg(long = "envelope-data", value_name = "CSV", value_delimiter = ',')]
    pub envelope_data: Vec<PathBuf>,
    /// Export a network from `--model` that carries no envelope without one: its learned
    /// stages are then never faded (test fixtures; a seeded network never has one).
    #[arg(long, conflicts_with = "envelope_data")]
    pub no_envelope: bool,
    /// A `drive` network's profiles keep the do-no-harm monitor off where the robot
    /// description leaves it off (by default the exporter turns it on there with
    /// `JointProfile::DRIVE_MONITOR`).
    #[arg(long)]
    pub no_monitor: bool,
}

/// The training envelope of the network to export: recorded from `--envelope-data`
/// when given, else the one `m` carries; a network from `--model` without one is
/// refused unless `--no-envelope`.
fn envelope(m: &mut LstmModel, a: &ExportArgs) -> Result<()> {
    if !a.envelope_data.is_empty() {
        let tables: Vec<compnet::data::Table> = a
            .envelope_data
            .iter()
            .map(|p| compnet::data::Table::read(p))
            .collect::<Result<_>>()?;
        if a.joints.len() != m.dims.output {
            bail!(
                "--envelope-data: --joints names {} joints, the network has {} outputs",
                a.joints.len(),
                m.dims.output
            );
        }
        m.envelope = compnet::envelope::record(&tables, &a.joints)
            .context("--envelope-data: recording the training envelope")?;
        return Ok(());
    }
    if a.network.is_some() && m.envelope.is_empty() && !a.no_envelope {
        bail!(
            "the network carries no training envelope (imported, or trained before envelopes \
             were recorded): name its training datasets with --envelope-data FILES (whole \
             runs), or export it without one with --no-envelope (its learned stages are then \
             never faded outside the conditions they were trained on)"
        );
    }
    Ok(())
}

/// The gate's motion threshold: each compensated joint must move faster than this in
/// the gate data, rad/s ...
pub const GATE_MOVING_RAD_S: f64 = 0.05;
/// ... for at least this long over all gate runs together, s: a gate run that barely
/// moves a joint cannot show whether the network harms it.
pub const GATE_MIN_MOVING_S: f64 = 1.0;

/// Refuses gate data that cannot judge a network: a file without at least two data rows
/// (empty, header only, one row) is an error naming it; per compensated joint (`qd_jN`),
/// less than [`GATE_MIN_MOVING_S`] of motion faster than [`GATE_MOVING_RAD_S`] over all
/// runs (each row counts as its run's median time step) is an error naming the joint.
fn check_gate_data(a: &ExportArgs) -> Result<Vec<compnet::data::Table>> {
    let mut tables = Vec::new();
    for path in &a.gate_data {
        let table = compnet::data::Table::read(path)
            .with_context(|| format!("--gate-data {}", path.display()))?;
        if table.len() < 2 {
            bail!(
                "--gate-data {}: {} data rows; the do-no-harm gate needs whole runs (at \
                 least two rows, and motion on every compensated joint)",
                path.display(),
                table.len()
            );
        }
        tables.push(table);
    }
    eprintln!(
        "gate motion threshold: at least {GATE_MIN_MOVING_S} s faster than \
         {GATE_MOVING_RAD_S} rad/s per compensated joint"
    );
    for &joint in &a.joints {
        let mut moving_s = 0.0f64;
        for table in &tables {
            let qd = table
                .column(&format!("qd_j{joint}"))
                .with_context(|| format!("--gate-data {}", table.path.display()))?;
            let t = table.column("time_s").ok();
            let dt = t
                .map(|t| {
                    let t: Vec<f64> = t.iter().map(|&v| f64::from(v)).collect();
                    logs::signal::median_step(&t)
                })
                .filter(|dt| dt.is_finite() && *dt > 0.0)
                .with_context(|| {
                    format!(
                        "--gate-data {}: column `time_s` missing or not increasing",
                        table.path.display()
                    )
                })?;
            let rows = qd
                .iter()
                .filter(|v| f64::from(v.abs()) > GATE_MOVING_RAD_S)
                .count();
            moving_s += rows as f64 * dt;
        }
        eprintln!("gate data: joint {joint} moves {moving_s:.2} s");
        if moving_s < GATE_MIN_MOVING_S {
            bail!(
                "--gate-data: joint {joint} moves faster than {GATE_MOVING_RAD_S} rad/s for \
                 {moving_s:.2} s over all gate runs, less than the {GATE_MIN_MOVING_S} s the \
                 do-no-harm gate needs to judge the network on it"
            );
        }
    }
    Ok(tables)
}

/// Per validation run (1-based, `--gate-data` order) and compensated joint: the model
/// alone's and the compensated RMS [N*m] (f32 firmware step), for the do-no-harm gate,
/// and the linear friction baseline's fitted on the gate data itself (the best a linear
/// friction correction could do there; `None` where it cannot be fitted), for the report.
type GateRow = (usize, usize, f64, f64, Option<f64>);

fn gate(m: &LstmModel, a: &ExportArgs) -> Result<Vec<GateRow>> {
    let spec = compnet::data::FeatureSpec::for_preset(&m.preset, &a.joints).with_context(|| {
        format!(
            "--gate-data needs a `paper`, `feedforward` or `drive` network (this one: `{}`)",
            m.preset
        )
    })?;
    spec.check_model(m)?;
    let tables = check_gate_data(a)?;
    let baseline = match compnet::baseline::fit(&tables, &a.joints) {
        Ok(b) => Some(b),
        Err(e) => {
            eprintln!("note: no linear baseline on the gate data: {e:#}");
            None
        }
    };
    let mut rows = Vec::new();
    for (run, (path, table)) in a.gate_data.iter().zip(&tables).enumerate() {
        let seq = spec
            .sequence(table)
            .with_context(|| format!("{}", path.display()))?;
        let base = match &baseline {
            Some(b) => compnet::eval::baseline_rms(&spec, table, seq.len(), b)?,
            None => Vec::new(),
        };
        for (k, (e, &joint)) in compnet::eval::evaluate(m, &seq)?
            .iter()
            .zip(&a.joints)
            .enumerate()
        {
            let b = base.get(k).copied().flatten();
            rows.push((run + 1, joint, e.rms_before, e.rms_after, b));
        }
    }
    Ok(rows)
}

/// The 0-based indices of `--joints` (joint numbers start at 1).
fn joint_indices(a: &ExportArgs) -> Result<Vec<usize>> {
    a.joints
        .iter()
        .map(|&j| match j {
            0 => bail!("--joints: joint numbers start at 1 (got 0)"),
            j => Ok(j - 1),
        })
        .collect()
}

/// The drive profiles of `robot`'s joints `joints` (0-based), noting on stderr each joint
/// whose description gives none (it gets the board's).
fn joint_profiles(
    robot: &robot::Robot,
    joints: &[usize],
) -> Result<Vec<firmware::control::JointProfile>> {
    joints
        .iter()
        .map(|&j| {
            let Some(joint) = robot.joints.get(j) else {
                bail!(
                    "--joints {}: {} has {} joints",
                    j + 1,
                    robot.source.display(),
                    robot.joints.len()
                );
            };
            if joint.profile.is_none() {
                eprintln!(
                    "note: joint {} ({}) of {} has no [joint.profile]: the board's default profile",
                    j + 1,
                    joint.name,
                    robot.source.display()
                );
            }
            Ok(joint.drive_profile())
        })
        .collect()
}

/// The deployed drive compensator runs its do-no-harm monitor: for a `drive` network,
/// every profile whose monitor is off (window 0, the robot description's default) gets
/// [`firmware::control::JointProfile::DRIVE_MONITOR`], unless `no_monitor`; a window the
/// description gives is kept. Other presets' profiles are unchanged.
fn with_drive_monitor(
    mut profiles: Vec<firmware::control::JointProfile>,
    preset: &str,
    no_monitor: bool,
) -> Vec<firmware::control::JointProfile> {
    if preset == "drive" && !no_monitor {
        for p in profiles.iter_mut().filter(|p| p.monitor.window_s == 0.0) {
            p.monitor = firmware::control::JointProfile::DRIVE_MONITOR;
        }
    }
    profiles
}

/// Builds the model to export.
pub fn model(a: &ExportArgs) -> Result<LstmModel> {
    let mut m = seeded_or_read(a)?;
    envelope(&mut m, a)?;
    Ok(m)
}

/// The network of `--network`, or the seeded one.
fn seeded_or_read(a: &ExportArgs) -> Result<LstmModel> {
    match &a.network {
        Some(p) => compnet::io::read_model(p),
        None => {
            let [i, e, h, o] = a.dims[..] else {
                bail!("--dims needs 4 sizes I,E,H,O, got {:?}", a.dims);
            };
            let max = compnet::model::MAX_LAYER_WIDTH;
            if let Some(&bad) = a.dims.iter().find(|&&d| d == 0 || d > max) {
                bail!(
                    "--dims {:?}: each size must be in 1..={max} (MAX_LAYER_WIDTH), got {bad}",
                    a.dims
                );
            }
            let mut m = LstmModel::init(
                LstmDims {
                    input: i,
                    embed: e,
                    hidden: h,
                    output: o,
                },
                a.seed,
            );
            m.preset = a.preset.name().into();
            // Feature names of the preset for the joint numbers (checked here), when
            // the sizes fit it.
            joint_indices(a)?;
            let spec = compnet::data::FeatureSpec::for_preset(a.preset.name(), &a.joints);
            if let Some(spec) = spec.filter(|s| s.inputs.len() == i && s.targets.len() == o) {
                m.output_names = spec.output_names();
                m.input_names = spec.inputs;
            }
            Ok(m)
        }
    }
}

/// Exports `m` to `a.out`; returns the exported network and where its arrays live.
pub fn export(m: &LstmModel, a: &ExportArgs) -> Result<(Exported, PlacementChoice)> {
    let (net, placement, text) = render_export(m, a)?;
    compnet::write_atomic(&a.out, text.as_bytes())?;
    Ok((net, placement))
}

/// The exported network, where its arrays live, and the text of the Rust file
/// [`export`] writes to `a.out` (after every check: the do-no-harm gate, the flash
/// and SRAM budgets).
pub fn render_export(m: &LstmModel, a: &ExportArgs) -> Result<(Exported, PlacementChoice, String)> {
    let increment = m
        .output_names
        .iter()
        .find(|n| compnet::data::is_increment_name(n));
    if let Some(name) = increment {
        bail!(
            "the model predicts the next-step torque as an increment over the measured \
             torque (output `{name}`, `train --paper-output increment`): fed forward, it \
             closes a unit-gain loop on the applied torque (docs/studies/sil-paper-network.md); export \
             a network trained with `--preset paper_relative` or `paper`, or the `drive` \
             preset"
        );
    }
    let warning = match a.network {
        Some(_) => do_no_harm(m, a)?,
        None => String::new(),
    };
    let net = Exported::new(m, a.precision).with_context(|| {
        format!(
            "exporting {}",
            a.network
                .as_ref()
                .map_or("the seeded network".into(), |p| p.display().to_string())
        )
    })?;
    if let Some(b) = &a.budgets {
        let budget = flash_budget(b)?;
        let bytes = net.flash_bytes();
        if bytes as u64 > budget {
            return Err(ExportError::TooLarge {
                bytes,
                budget,
                source_file: b.display().to_string(),
            }
            .into());
        }
    }
    let joints = joint_indices(a)?;
    let (dynamics, profiles) = match (&a.robot, &a.identified) {
        (p, Some(identified)) => {
            if !a.chain.selection()?.is_default() {
                anyhow::bail!(
                    "--base-link, --tip-link and --side-joint do not apply with --identified: the model file records its chain"
                );
            }
            let id =
                identify::identified::load_identified(&RobotSource::from(p.clone()), identified)?;
            if let Some(w) = &id.warning {
                eprintln!("warning: {w}");
            }
            let profiles = joint_profiles(&id.robot, &joints)?;
            (
                Some(FirmwareModel::build(&id.robot, &id.standard_parameters)?),
                profiles,
            )
        }
        (Some(p), None) => {
            let robot = a
                .chain
                .load_and_warn(&RobotSource::File(p.clone()))
                .with_context(|| format!("reading robot {}", p.display()))?;
            let profiles = joint_profiles(&robot, &joints)?;
            (
                Some(FirmwareModel::build(&robot, &robot.standard_parameters())?),
                profiles,
            )
        }
        (None, None) => (
            None,
            vec![firmware::control::JointProfile::BOARD; joints.len()],
        ),
    };
    let mut profiles = with_drive_monitor(profiles, &m.preset, a.no_monitor);
    for p in &mut profiles {
        if let Some(t) = a.adapt_time_constant_s {
            p.adaptation.time_constant_s = t;
        }
        if let Some(w) = a.monitor_window_s {
            p.monitor.window_s = w;
        }
        if let Some(field) = p.invalid_field() {
            anyhow::bail!(
                "--adapt-time-constant-s / --monitor-window-s: {field} out of range (finite, not negative)"
            );
        }
    }
    let sram = a.budgets.as_deref().map(sram_budget).transpose()?;
    let bytes = ModelBytes {
        network: net.flash_bytes(),
        dynamics: dynamics.as_ref().map_or(0, dynamics_bytes),
        linear_stage: m.dims.output * firmware::features::FRICTION_FEATURES * 4,
        act_tables: net.act_tables_bytes(),
        gate_block: net.gate_blocks().0,
        gate_blocks: net.gate_blocks().1,
    };
    let placement = choose_placement(a.weights_in, bytes, sram.map(|b| b.model_bytes()))?;
    let meta = ExportMeta {
        preset: m.preset.clone(),
        joints,
        control_rate_hz: a.control_rate_hz,
        self_check_steps: a.self_check_steps,
        placement,
        profiles,
    };
    let mut text = render(m, &net, &meta, dynamics.as_ref());
    if !warning.is_empty() {
        eprintln!("warning: exported anyway (--allow-worse):\n{warning}");
        let commented: String = warning.lines().map(|l| format!("// {l}\n")).collect();
        text = format!(
            "// WARNING: exported with --allow-worse; the do-no-harm gate did not pass:\n{commented}{text}"
        );
    }
    Ok((net, placement, text))
}

/// The do-no-harm gate of a trained network: an error listing the per-joint figures
/// when it is worse than the model alone on any validation run and joint (or has no
/// validation runs); with `--allow-worse`, that listing as a warning instead (empty
/// when the gate passes). The listing names the validation runs by number only.
fn do_no_harm(m: &LstmModel, a: &ExportArgs) -> Result<String> {
    if a.gate_data.is_empty() {
        if a.allow_worse {
            return Ok(
                "no --gate-data: the network was not checked against the model alone".into(),
            );
        }
        bail!(
            "exporting a trained network needs --gate-data VALIDATION.csv (whole runs it \
             never trained on) for the do-no-harm gate, or --allow-worse"
        );
    }
    let rows = gate(m, a)?;
    // Runs by number (their paths go to stderr only: input never enters the file).
    for (k, path) in a.gate_data.iter().enumerate() {
        eprintln!("gate run {}: {}", k + 1, path.display());
    }
    let mut table = String::from(
        "run | joint | model alone RMS N*m | compensated RMS N*m | linear baseline RMS N*m\n",
    );
    let mut worse = false;
    for (run, joint, before, after, baseline) in &rows {
        worse |= after.is_nan() || before.is_nan() || after > before;
        let b = baseline.map_or("-".to_string(), |b| format!("{b:.4}"));
        table += &format!("{run} | {joint} | {before:.4} | {after:.4} | {b}\n");
    }
    eprint!("do-no-harm gate:\n{table}");
    match (worse, a.allow_worse) {
        (false, _) => Ok(String::new()),
        (true, true) => Ok(table),
        (true, false) => bail!(
            "the network is worse than the model alone on a validation run (do-no-harm \
             gate; --allow-worse overrides):\n{table}"
        ),
    }
}

/// Runs the subcommand: the Rust file and the accuracy JSON are written all or none,
/// after the accuracy log was read and evaluated.
pub fn run(a: ExportArgs) -> Result<()> {
    artifacts::plausible::positive(f64::from(a.control_rate_hz))
        .map_err(|m| anyhow::anyhow!("--control-rate-hz {m}"))?;
    let m = model(&a)?;
    let (net, placement, text) = render_export(&m, &a)?;
    let mut accuracy_json = None;
    if let Some(log) = &a.accuracy_log {
        let table = compnet::data::Table::read(log)?;
        let spec = compnet::data::FeatureSpec::for_preset(&m.preset, &a.joints)
            .with_context(|| {
                format!(
                    "--accuracy-log needs a `paper`, `feedforward` or `drive` model (this one: `{}`)",
                    m.preset
                )
            })?;
        spec.check_model(&m)
            .with_context(|| format!("{}", log.display()))?;
        let seq = spec
            .sequence(&table)
            .with_context(|| format!("{}", log.display()))?;
        let rows = accuracy(&m, &seq.inputs, Some(&seq.targets))?;
        artifacts::ensure_finite(
            &format!("{}: accuracy", log.display()),
            rows.iter().flat_map(|r| {
                [r.rms_vs_f32]
                    .into_iter()
                    .chain(r.compensated_rms)
                    .chain(r.f32_compensated_rms)
            }),
        )?;
        println!(
            "Accuracy on {} ({} steps, streamed from the zero state):\n",
            log.display(),
            seq.len()
        );
        print!("{}", accuracy_markdown(&rows));
        if let Some(path) = &a.report {
            accuracy_json = Some((path, serde_json::to_string_pretty(&rows)?));
        }
    }
    // The Rust file (a source file, 0644 like every staged output) and the accuracy
    // JSON: all or none.
    let mut files: Vec<(&Path, &[u8])> = vec![(&a.out, text.as_bytes())];
    if let Some((path, json)) = &accuracy_json {
        files.push((path.as_path(), json.as_bytes()));
    }
    artifacts::write_atomic_all(&files)?;
    println!(
        "wrote {} ({}, {} bytes of network arrays)",
        a.out.display(),
        a.precision.name(),
        net.flash_bytes()
    );
    println!("placement: {}", placement.describe());
    Ok(())
}
