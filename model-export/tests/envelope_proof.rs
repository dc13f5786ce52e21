//! The training envelope's proof on one joint: a `drive` compensator trained on slow
//! motion of a simulated joint (the plant simulator's drive of the default robot's joint
//! 5: Stribeck, LuGre presliding, load-dependent friction, ripple, reflected rotor inertia,
//! under a pendulum load) runs, as the firmware's `Compensator` on the host, on the same
//! motion three times faster. Its output never leaves the model torque plus or minus the
//! profile's `max_lstm_correction_nm`, and its RMS error against the true torque is within
//! 2 % of the identified model's. The network is tiny and trained for a few epochs: the
//! envelope is what is tested. (The same kernels run bit-identically on QEMU: the test
//! kit's `envelope` suite, `host-tests`.)
use compnet::io;
use firmware::control::{
    Compensator, FaultFlags, JointProfile, JointState, LstmPredictor, PredictorInput,
    TorquePredictor,
};
use firmware::envelope::JointEnvelope;
use firmware::features::{self, DRIVE_COLUMNS, DRIVE_INPUTS_PER_JOINT, MotionMemory};
use firmware::math;
use firmware::nn::format::FeaturePreset;
use model_export::cli::run_args as cli;
use plant_sim::PlantEffects;
use plant_sim::drive::{DriveState, drive_torque_step};
use std::path::{Path, PathBuf};

/// Compensator rate [Hz] and the plant's internal steps per tick.
const RATE_HZ: u32 = 100;
const SUBSTEPS: usize = 10;
/// The pendulum: inertia [kg m^2] and gravity amplitude [N m].
const INERTIA_KG_M2: f32 = 0.4;
const GRAVITY_NM: f32 = 12.0;
/// What identification found of the drive's friction: viscous [N m s/rad], Coulomb [N m].
const VISCOUS_NM_S_RAD: f32 = 2.0;
const COULOMB_NM: f32 = 1.5;

/// The identified model (rigid body, viscous and Coulomb friction), in f32 as the drive
/// evaluates it: its model stage and the datasets' `tau_model_j1`.
fn model_nm(q: f32, qd: f32, qdd: f32) -> f32 {
    INERTIA_KG_M2 * qdd
        + GRAVITY_NM * math::sin(q)
        + VISCOUS_NM_S_RAD * qd
        + COULOMB_NM * math::tanh(qd / 0.02)
}

struct Model;
impl TorquePredictor<1> for Model {
    fn predict_nm(&mut self, input: &PredictorInput<1>) -> [f32; 1] {
        let s = input.joints[0];
        [model_nm(s.q_ref_rad, s.qd_ref_rad_s, s.qdd_ref_rad_s2)]
    }
    fn reset(&mut self) {}
}

/// One tick of a motion: angle, velocity, acceleration, true torque.
#[derive(Clone, Copy)]
struct Tick {
    q: f64,
    qd: f64,
    qdd: f64,
    tau_true: f64,
}

/// `q(t) = a1 sin(s w1 t + p) + a2 sin(s w2 t)` for `seconds`, `s` the speed factor, and
/// the torque the true joint needs along it (stepped `SUBSTEPS` times per tick).
fn motion(speed: f64, phase: f64, seconds: f64) -> Vec<Tick> {
    let drive = plant_sim::PlantParameters::default_robot().joints[4].clone();
    let effects = PlantEffects::all();
    let mut state = DriveState::at_rest(25.0);
    let (a1, w1, a2, w2) = (0.7, 0.45 * speed, 0.25, 1.1 * speed);
    let at = |t: f64| {
        let (x1, x2) = (w1 * t + phase, w2 * t);
        (
            a1 * x1.sin() + a2 * x2.sin(),
            a1 * w1 * x1.cos() + a2 * w2 * x2.cos(),
            -a1 * w1 * w1 * x1.sin() - a2 * w2 * w2 * x2.sin(),
        )
    };
    let dt = 1.0 / (f64::from(RATE_HZ) * SUBSTEPS as f64);
    let ticks = (seconds * f64::from(RATE_HZ)) as usize;
    let mut out = Vec::with_capacity(ticks);
    for k in 0..ticks {
        let mut tau = 0.0;
        for s in 0..SUBSTEPS {
            let t = (k * SUBSTEPS + s) as f64 * dt;
            let (q, qd, qdd) = at(t);
            let rigid = f64::from(INERTIA_KG_M2) * qdd + f64::from(GRAVITY_NM) * q.sin();
            let d = drive_torque_step(&drive, &effects, &mut state, q, qd, qdd, rigid, 25.0, dt);
            tau = rigid + d.total_nm();
        }
        let (q, qd, qdd) = at(k as f64 / f64::from(RATE_HZ));
        out.push(Tick {
            q,
            qd,
            qdd,
            tau_true: tau,
        });
    }
    out
}

/// A `drive` dataset of joint 1 from a motion.
fn dataset(path: &Path, ticks: &[Tick]) {
    let mut csv = String::from("time_s,q_j1,qd_j1,qdd_j1,tau_meas_j1,tau_model_j1");
    for c in [0, 1, 5, 6, 7, 8, 9] {
        csv += &format!(",{}_j1", DRIVE_COLUMNS[c]);
    }
    csv += "\n";
    let mut memory = MotionMemory::new();
    for (k, t) in ticks.iter().enumerate() {
        let (q, qd, qdd) = (t.q as f32, t.qd as f32, t.qdd as f32);
        let model = model_nm(q, qd, qdd);
        let x = features::drive_inputs(q, qd, qdd, model, memory.update(q, qd), 0.0);
        csv += &format!(
            "{},{q},{qd},{qdd},{},{model}",
            k as f64 / f64::from(RATE_HZ),
            t.tau_true
        );
        for c in [0, 1, 5, 6, 7, 8, 9] {
            csv += &format!(",{}", x[c]);
        }
        csv += "\n";
    }
    std::fs::write(path, csv).unwrap();
}

fn path(p: &Path) -> String {
    p.display().to_string()
}

/// Runs the compensator over `ticks` (the torque measured since the last tick is the
/// previous tick's true torque); returns per tick (output, model torque, true torque,
/// flags).
fn run(
    net: &sil::wrist::HostNetwork,
    linear: [[f32; features::FRICTION_FEATURES]; 1],
    envelope: JointEnvelope,
    profile: &JointProfile,
    ticks: &[Tick],
) -> Vec<(f32, f32, f64, FaultFlags)> {
    let lstm = LstmPredictor::<_, 1, DRIVE_INPUTS_PER_JOINT>::new(net, FeaturePreset::Drive)
        .unwrap()
        .with_linear_stage(linear)
        .with_envelope([envelope]);
    let mut c = Compensator::new(profile.compensator_config(RATE_HZ, 0), Model, lstm).unwrap();
    let mut previous = ticks[0].tau_true as f32;
    ticks
        .iter()
        .enumerate()
        .map(|(k, t)| {
            let own = JointState {
                q_ref_rad: t.q as f32,
                qd_ref_rad_s: t.qd as f32,
                qdd_ref_rad_s2: t.qdd as f32,
                tau_meas_nm: previous,
                ..Default::default()
            };
            previous = t.tau_true as f32;
            let o = c.tick(&own, k as u32 * (1_000_000 / RATE_HZ));
            let m = model_nm(own.q_ref_rad, own.qd_ref_rad_s, own.qdd_ref_rad_s2);
            (o.torque_nm, m, t.tau_true, o.faults)
        })
        .collect()
}

fn rms(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
    (s / n.max(1) as f64).sqrt()
}

#[test]
fn trained_slow_run_three_times_faster_the_compensator_stays_with_the_model() {
    let dir = tempfile::tempdir().unwrap();
    let (net_path, runs) = train_on_slow_runs(dir.path(), |p, k| {
        dataset(p, &motion(1.0, 0.9 * k as f64, 20.0))
    });
    let model = io::read_model(&net_path).unwrap();
    assert_eq!(model.envelope.len(), 1, "the training recorded an envelope");
    let envelope = model.envelope[0];
    let net = sil::wrist::HostNetwork::F32(fw_export::F32Net::arrange(&model).unwrap());
    let linear = [std::array::from_fn(|c| model.linear[c])];
    let profile = JointProfile::BOARD;
    let warmup = usize::from(profile.warmup_ticks);

    // Inside the envelope (a slow run it validated on) the learned stages act.
    let slow = motion(1.0, 0.9 * 2.0, 20.0);
    let inside = run(&net, linear, envelope, &profile, &slow);
    let outside_ticks = |r: &[(f32, f32, f64, FaultFlags)]| {
        r.iter()
            .filter(|x| x.3.contains(FaultFlags::ENVELOPE_OUTSIDE))
            .count()
    };
    let (rms_model_slow, rms_comp_slow) = (
        rms(inside[warmup..].iter().map(|x| f64::from(x.1) - x.2)),
        rms(inside[warmup..].iter().map(|x| f64::from(x.0) - x.2)),
    );
    println!(
        "slow (trained) run: model {rms_model_slow:.4} N m RMS, compensator {rms_comp_slow:.4} N m, \
         {} of {} ticks outside the envelope",
        outside_ticks(&inside),
        inside.len()
    );

    // Three times faster: outside the envelope most of the time.
    let fast = motion(3.0, 0.3, 20.0);
    let faded = run(&net, linear, envelope, &profile, &fast);
    let unbounded = run(&net, linear, JointEnvelope::UNBOUNDED, &profile, &fast);
    let after = &faded[warmup..];
    let rms_model = rms(after.iter().map(|x| f64::from(x.1) - x.2));
    let rms_comp = rms(after.iter().map(|x| f64::from(x.0) - x.2));
    let rms_unbounded = rms(unbounded[warmup..].iter().map(|x| f64::from(x.0) - x.2));
    let worst = after
        .iter()
        .map(|x| (x.0 - x.1).abs())
        .fold(0.0f32, f32::max);
    println!(
        "3x faster: model {rms_model:.4} N m RMS, compensator with the envelope {rms_comp:.4} N m \
         ({:.4} x), without it {rms_unbounded:.4} N m; largest |output - model| {worst:.4} N m \
         (bound {} N m); {} of {} ticks outside the envelope",
        rms_comp / rms_model,
        profile.max_lstm_correction_nm,
        outside_ticks(&faded),
        faded.len()
    );
    assert!(outside_ticks(&faded) > faded.len() / 2);
    assert!(
        worst <= profile.max_lstm_correction_nm,
        "output left the model by {worst} N m"
    );
    assert!(
        rms_comp <= 1.02 * rms_model,
        "compensator {rms_comp} N m RMS vs model {rms_model} N m RMS"
    );

    // `evaluate` fades as the drive does and reports the share outside the envelope.
    let fast_csv = dir.path().join("fast.csv");
    dataset(&fast_csv, &fast);
    let report = dir.path().join("eval.json");
    cli(&[
        "evaluate",
        "--network",
        &path(&net_path),
        "--data",
        &path(&fast_csv),
        "--preset",
        "drive",
        "--joints",
        "1",
        "--report",
        &path(&report),
    ])
    .expect("evaluates");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let row = &json["data"][0]["outputs"][0];
    let share = row["outside_envelope_share"].as_f64().unwrap();
    let (before, after) = (
        row["rms_before"].as_f64().unwrap(),
        row["rms_after"].as_f64().unwrap(),
    );
    println!("evaluate on the fast run: {share:.4} outside, RMS {before:.4} -> {after:.4} N m");
    assert!(share > 0.5 && share < 1.0, "{share}");
    assert!(after <= 1.02 * before, "{after} vs {before}");

    // A network without an envelope: `export` refuses it and writes nothing, unless its
    // training data is named; then it records the same envelope `train` recorded.
    let mut bare = model.clone();
    bare.envelope.clear();
    let bare_path = dir.path().join("bare.safetensors");
    io::write_model(&bare, &bare_path).unwrap();
    let out = dir.path().join("model.rs");
    let export = |extra: &[&str]| {
        let mut args = vec![
            "export",
            "--network",
            bare_path.to_str().unwrap(),
            "--joints",
            "1",
            "--precision",
            "f32",
            "--allow-worse",
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        cli(&args)
    };
    let err = export(&[]).unwrap_err();
    assert!(format!("{err:#}").contains("--envelope-data") && !out.exists());
    let training = format!("{},{}", path(&runs[0]), path(&runs[1]));
    export(&["--envelope-data", &training]).expect("exports");
    let text = std::fs::read_to_string(&out).unwrap();
    let q = envelope.q_rad;
    assert!(
        text.contains(&format!(
            "q_rad: firmware::envelope::Range::new({:?}, {:?})",
            q.lo, q.hi
        )),
        "{}",
        &text[..text.len().min(3000)]
    );
    assert!(!text.contains("JointEnvelope::UNBOUNDED"));
}

/// A `drive` dataset of joint 1 along the test kit's proof motion at `speed`
/// (`test_kit::proof`: the true torque and the model torque the QEMU image computes).
fn proof_dataset(path: &Path, speed: f32, phase_rad: f32, ticks: usize) {
    use test_kit::proof;
    let mut csv = String::from("time_s,q_j1,qd_j1,qdd_j1,tau_meas_j1,tau_model_j1");
    for c in [0, 1, 5, 6, 7, 8, 9] {
        csv += &format!(",{}_j1", DRIVE_COLUMNS[c]);
    }
    csv += "\n";
    let mut memory = MotionMemory::new();
    for k in 0..ticks {
        let (q, qd, qdd) = proof::motion(speed, phase_rad, k);
        let model = proof::model_torque_nm(q, qd, qdd);
        let x = features::drive_inputs(q, qd, qdd, model, memory.update(q, qd), 0.0);
        csv += &format!(
            "{},{q},{qd},{qdd},{},{model}",
            k as f64 / f64::from(proof::RATE_HZ),
            proof::true_torque_nm(q, qd, qdd)
        );
        for c in [0, 1, 5, 6, 7, 8, 9] {
            csv += &format!(",{}", x[c]);
        }
        csv += "\n";
    }
    std::fs::write(path, csv).unwrap();
}

/// The same proof on the target: a `drive` compensator trained on the test kit's slow
/// proof motion is exported, compiled into the QEMU image as its model
/// (`FIRMWARE_MODEL`), and run there (`test_kit::proof::stream`, the image's `proof`
/// suite) on the motion three times faster. Its outputs and flags are bit-identical to
/// the host's, never leave the model torque plus or minus the profile's
/// `max_lstm_correction_nm`, and their RMS error against the true torque is within 2 %
/// of the model's.
#[test]
fn trained_model_on_qemu_three_times_faster_matches_the_host_and_stays_with_the_model() {
    use host_tests::compare::{Record, compare};
    use host_tests::{golden, qemu, target};
    use test_kit::proof;
    if !test_support::target_tools_or_skip("the envelope proof on QEMU") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (net_path, _) = train_on_slow_runs(dir.path(), |p, k| {
        proof_dataset(p, 1.0, 0.9 * k as f32, 2_000)
    });
    let model_rs = dir.path().join("proof_model.rs");
    cli(&[
        "export",
        "--network",
        &path(&net_path),
        "--joints",
        "1",
        "--precision",
        "f32",
        "--allow-worse",
        "--out",
        &path(&model_rs),
    ])
    .expect("exports");

    // The host: the same stream through the run-time view of the same f32 network.
    let model = io::read_model(&net_path).unwrap();
    let net = sil::wrist::HostNetwork::F32(fw_export::F32Net::arrange(&model).unwrap());
    let linear = [std::array::from_fn(|c| model.linear[c])];
    let profile = JointProfile::BOARD;
    let mut host_ticks = Vec::new();
    proof::stream::<1, DRIVE_INPUTS_PER_JOINT, _>(
        &net,
        FeaturePreset::Drive,
        linear,
        [model.envelope[0]],
        &profile,
        proof::FAST_SPEED,
        proof::FAST_PHASE_RAD,
        proof::FAST_TICKS,
        |_, t| host_ticks.push(t),
    );
    assert_eq!(host_ticks.len(), proof::FAST_TICKS);
    let host_records: Vec<Record> = host_ticks
        .iter()
        .enumerate()
        .flat_map(|(k, t)| {
            [
                Record::new("py", k, k as u32, t.output_nm.to_bits()),
                Record::new("pf", k, k as u32, t.faults),
            ]
        })
        .collect();

    // The target: the QEMU image with the exported file as its model.
    let t0 = std::time::Instant::now();
    let elf = target::build_with_model(target::FirmwareBin::Qemu, &model_rs)
        .unwrap_or_else(|e| panic!("{e:#}"));
    let report = qemu::run(&elf).unwrap_or_else(|e| panic!("{e:#}"));
    let suites = golden::parse_report(&report).unwrap_or_else(|e| panic!("{e:#}"));
    let suite = suites
        .iter()
        .find(|s| s.name == "proof")
        .expect("the image's proof suite");
    let n = compare(&suite.records, &host_records)
        .unwrap_or_else(|m| panic!("proof: first mismatch between QEMU and the host: {m}"));
    println!(
        "QEMU image with the trained model (built and run in {:.1} s): {n} results bit-identical to the host",
        t0.elapsed().as_secs_f64()
    );

    // Read on the target's own outputs.
    let target_out: Vec<f32> = suite
        .records
        .iter()
        .filter(|r| r.function == "py")
        .map(|r| f32::from_bits(r.output_bits))
        .collect();
    assert_eq!(target_out.len(), host_ticks.len());
    let warmup = usize::from(profile.warmup_ticks);
    let after = || target_out.iter().zip(&host_ticks).skip(warmup);
    let worst = after()
        .map(|(y, t)| (y - t.model_nm).abs())
        .fold(0.0f32, f32::max);
    let rms_model = rms(after().map(|(_, t)| f64::from(t.model_nm - t.true_nm)));
    let rms_comp = rms(after().map(|(y, t)| f64::from(y - t.true_nm)));
    let outside = host_ticks
        .iter()
        .filter(|t| FaultFlags::from_bits(t.faults).contains(FaultFlags::ENVELOPE_OUTSIDE))
        .count();
    println!(
        "QEMU, 3x faster: model {rms_model:.4} N m RMS, compensator {rms_comp:.4} N m ({:.4} x); \
         largest |output - model| {worst:.4} N m (bound {} N m); {outside} of {} ticks outside the envelope",
        rms_comp / rms_model,
        profile.max_lstm_correction_nm,
        host_ticks.len()
    );
    assert!(outside > host_ticks.len() / 2, "{outside} ticks outside");
    assert!(
        worst <= profile.max_lstm_correction_nm,
        "output left the model by {worst} N m"
    );
    assert!(
        rms_comp <= 1.02 * rms_model,
        "compensator {rms_comp} N m RMS vs model {rms_model} N m RMS"
    );
}

/// Trains the single joint's drive network on three slow runs written by `write` (run
/// `k` to path), two for training and one for validation, seeded; the network's path
/// and the runs'.
fn train_on_slow_runs(dir: &Path, write: impl Fn(&Path, usize)) -> (PathBuf, Vec<PathBuf>) {
    let runs: Vec<PathBuf> = (0..3)
        .map(|k| {
            let p = dir.join(format!("slow{k}.csv"));
            write(&p, k);
            p
        })
        .collect();
    let net_path = dir.join("drive.safetensors");
    cli(&[
        "train",
        "--data",
        &format!("{},{}", path(&runs[0]), path(&runs[1])),
        "--validation-data",
        &path(&runs[2]),
        "--preset",
        "drive",
        "--joints",
        "1",
        "--epochs",
        "3",
        "--window",
        "50",
        "--burn-in",
        "10",
        "--embed",
        "4",
        "--hidden",
        "4",
        "--lr",
        "0.01",
        "--seed",
        "3",
        "--quiet",
        "--out",
        &path(&net_path),
        "--loss-plot",
        &path(&dir.join("loss.svg")),
    ])
    .expect("trains");
    (net_path, runs)
}
