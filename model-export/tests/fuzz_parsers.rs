//! The fuzz targets of `fuzz/` as bounded property tests on stable: every parser on its
//! seed corpus (`fuzz/corpus/<target>/`, the hostile cases among them) and on seeded
//! mutants of it, 10 000 cases per target by default. No case may panic or take longer
//! than `fuzz::HANG_AFTER`; a rejected network leaves `import`'s existing output as it was.
//!
//! A longer run: `FUZZ_CASES=1000000 TMPDIR=/dev/shm cargo test --release -p
//! model-export --test fuzz_parsers -- --nocapture` (`FUZZ_SEED` picks another mutation
//! sequence; the file targets rewrite one scratch file per case, which ext4 flushes on
//! close, so a tmpfs scratch folder runs them several times faster). A case that has
//! not returned after `WATCHDOG_AFTER` ends the run with its input saved.
use model_export::fuzz::{self, FuzzReport};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

fn cases() -> u64 {
    std::env::var("FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10_000)
}

fn seed() -> u64 {
    std::env::var("FUZZ_SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(0x5eed_f022)
}

fn corpus(target: &str) -> Vec<Vec<u8>> {
    let dir: PathBuf = [env!("CARGO_MANIFEST_DIR"), "..", "fuzz", "corpus", target]
        .iter()
        .collect();
    fuzz::read_corpus(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
}

/// A case still running after this long never returns in time: the watchdog writes it
/// to a file, names the case and ends the test process with a failure (a case that
/// returns after more than `fuzz::HANG_AFTER` is counted as a hang by `run_bounded`).
const WATCHDOG_AFTER: Duration = Duration::from_secs(60);

/// The case in progress, watched by [`watchdog`].
struct CaseInProgress {
    index: u64,
    started: Option<Instant>,
    input: Vec<u8>,
}

/// Polls `current` until `done`; a case older than [`WATCHDOG_AFTER`] is a hang that
/// would block the run for ever: its input goes to a file in the temp folder, the
/// target, case and seed are printed, and the process exits with status 101.
fn watchdog(name: String, current: Arc<Mutex<CaseInProgress>>, done: Arc<AtomicBool>) {
    while !done.load(Ordering::Relaxed) {
        std::thread::sleep(Duration::from_millis(200));
        let c = current.lock().unwrap_or_else(|e| e.into_inner());
        if c.started.is_some_and(|t| t.elapsed() > WATCHDOG_AFTER) {
            let path = std::env::temp_dir().join(format!("fuzz-hang-{name}-{}.bin", c.index));
            let saved = std::fs::write(&path, &c.input).map(|_| path.display().to_string());
            eprintln!(
                "fuzz {name}: case {} (seed {}) still running after {WATCHDOG_AFTER:?}: a hang; input: {saved:?}",
                c.index,
                seed()
            );
            std::process::exit(101);
        }
    }
}

/// Runs `target` on its corpus and mutants under [`watchdog`]; prints the figures and
/// asserts no panic and no hang.
fn check(name: &str, mut target: impl FnMut(&[u8])) -> FuzzReport {
    let seeds = corpus(name);
    let current = Arc::new(Mutex::new(CaseInProgress {
        index: 0,
        started: None,
        input: Vec::new(),
    }));
    let done = Arc::new(AtomicBool::new(false));
    let dog = {
        let (name, current, done) = (name.to_string(), current.clone(), done.clone());
        std::thread::spawn(move || watchdog(name, current, done))
    };
    let wall = Instant::now();
    let mut index = 0;
    let mut slowest = (Duration::ZERO, 0, Vec::new());
    let r = fuzz::run_bounded(name, &seeds, cases(), seed(), |d| {
        {
            let mut c = current.lock().unwrap_or_else(|e| e.into_inner());
            (c.index, c.started) = (index, Some(Instant::now()));
            c.input.clear();
            c.input.extend_from_slice(d);
        }
        index += 1;
        // A panic skips the lines below; the next case restarts the clock.
        let start = Instant::now();
        target(d);
        let took = start.elapsed();
        if took > slowest.0 {
            slowest = (took, index - 1, d.to_vec());
        }
        current.lock().unwrap_or_else(|e| e.into_inner()).started = None;
    });
    let wall_s = wall.elapsed().as_secs_f64();
    done.store(true, Ordering::Relaxed);
    dog.join().unwrap();
    println!(
        "fuzz {name}: {} cases ({} seeds), seed {}, {} panics, {} hangs (> {:?}), slowest {:.3} s, wall {:.1} s",
        r.cases,
        seeds.len(),
        seed(),
        r.panics,
        r.hangs,
        fuzz::HANG_AFTER,
        r.slowest_s,
        wall_s
    );
    let slow_input = (r.hangs > 0).then(|| {
        let path = std::env::temp_dir().join(format!("fuzz-slowest-{name}-{}.bin", slowest.1));
        std::fs::write(&path, &slowest.2).map(|_| path.display().to_string())
    });
    assert_eq!(
        (r.panics, r.hangs),
        (0, 0),
        "{name}: first panicking input: {:?}; slowest case {} ({:?}), input: {slow_input:?}",
        r.first_panic.as_ref().map(|d| String::from_utf8_lossy(d)),
        slowest.1,
        slowest.0
    );
    assert!(r.cases >= cases().max(seeds.len() as u64));
    r
}

#[test]
fn fuzz_dh_toml() {
    check("dh_toml", fuzz::dh_toml_target);
}

#[test]
fn fuzz_urdf() {
    check("urdf", fuzz::urdf_target);
}

#[test]
fn fuzz_log_csv() {
    let dir = tempfile::tempdir().unwrap();
    check("log_csv", |d| fuzz::log_csv_target(dir.path(), d));
}

#[test]
fn fuzz_model_json() {
    let dir = tempfile::tempdir().unwrap();
    check("model_json", |d| fuzz::model_json_target(dir.path(), d));
}

#[test]
fn fuzz_excitation_json() {
    let dir = tempfile::tempdir().unwrap();
    check("excitation_json", |d| {
        fuzz::excitation_json_target(dir.path(), d)
    });
}

#[test]
fn fuzz_budget_toml() {
    let dir = tempfile::tempdir().unwrap();
    check("budget_toml", |d| {
        fuzz::budget_toml_target(dir.path(), d);
        // The budget tool's own reader of the same file.
        let _ = host_tests::budget::Budgets::load(&dir.path().join("budgets.toml"));
    });
}

#[test]
fn fuzz_wire_frame() {
    check("wire_frame", fuzz::wire_frame_target);
}

/// `import --network IN --out OUT` on one input: an error leaves the existing OUT as it
/// was; a success is restored for the next case.
fn import_keeps_output_on_error(dir: &Path, data: &[u8]) {
    use clap::Parser;
    let (input, out) = (dir.join("in.safetensors"), dir.join("out.safetensors"));
    std::fs::write(&input, data).unwrap();
    const KEPT: &[u8] = b"the previous output\n";
    std::fs::write(&out, KEPT).unwrap();
    let args = [
        "model-export",
        "import",
        "--network",
        input.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--input-activation",
        "tanh",
    ];
    let cli = model_export::cli::Cli::try_parse_from(args).unwrap();
    if model_export::cli::run(cli).is_err() {
        assert_eq!(
            std::fs::read(&out).unwrap(),
            KEPT,
            "a rejected input changed the output"
        );
    }
}

#[test]
fn fuzz_safetensors() {
    let dir = tempfile::tempdir().unwrap();
    check("safetensors", |d| {
        fuzz::safetensors_target(d);
        import_keeps_output_on_error(dir.path(), d);
    });
}

/// The ONNX reader on each exporter variant's corpus (`fuzz/corpus/onnx_*`, written by
/// scripts/make_onnx_fixture.py): parse, and stream a network that parses.
fn fuzz_onnx(variant: &str) {
    check(&format!("onnx_{variant}"), fuzz::onnx_target);
}

#[test]
fn fuzz_onnx_torchscript() {
    fuzz_onnx("torchscript");
}

#[test]
fn fuzz_onnx_time_first() {
    fuzz_onnx("time_first");
}

#[test]
fn fuzz_onnx_dynamo() {
    fuzz_onnx("dynamo");
}

#[test]
fn fuzz_onnx_dynamo_batch_first() {
    fuzz_onnx("dynamo_batch_first");
}

/// Found by the long run: a network whose weights reach 3e38 or whose input standard
/// deviation is subnormal parsed, and its outputs overflowed to infinity or NaN.
#[test]
fn a_network_with_huge_weights_or_a_subnormal_std_is_refused() {
    use compnet::io::parse_model;
    let seeds: PathBuf = [
        env!("CARGO_MANIFEST_DIR"),
        "..",
        "fuzz",
        "corpus",
        "safetensors",
    ]
    .iter()
    .collect();
    for (file, tensor) in [
        (
            "shifted_weights_subnormal_std.safetensors",
            "lstm.weight_ih_l0",
        ),
        ("shifted_weights_3e38.safetensors", "input.weight"),
    ] {
        let bytes = std::fs::read(seeds.join(file)).unwrap();
        let e = parse_model(&bytes).unwrap_err().to_string();
        assert!(
            e.contains(tensor) && e.contains("must be <="),
            "{file}: {e}"
        );
    }
    // One value at a time, on the fixture that parses.
    let good = parse_model(&std::fs::read(seeds.join("torch_lstm.safetensors")).unwrap()).unwrap();
    let mut m = good.clone();
    m.input_std[2] = 2.3e-41;
    let e = m.validate().unwrap_err().to_string();
    assert!(
        e.contains("norm.input_std") && e.contains("element 2"),
        "{e}"
    );
    let mut m = good.clone();
    m.w_ih[7] = -3e38;
    let e = m.validate().unwrap_err().to_string();
    assert!(
        e.contains("lstm.weight_ih_l0") && e.contains("element 7"),
        "{e}"
    );
    let mut m = good.clone();
    m.output_mean[1] = 1e7;
    assert!(m.validate().is_err());
    // Values at the bounds still parse, and a shrunk output (tiny std) is a network.
    let mut m = good;
    m.w_ih[7] = compnet::model::MAX_ABS_NETWORK_VALUE;
    m.input_std[2] = compnet::model::MIN_INPUT_STD;
    m.output_std[0] = f32::MIN_POSITIVE;
    m.validate().unwrap();
}

#[test]
fn fuzz_rosbag2_folder() {
    check("rosbag2_folder", fuzz::rosbag2_folder_target);
}

#[test]
fn fuzz_db3() {
    check("db3", fuzz::db3_target);
}
