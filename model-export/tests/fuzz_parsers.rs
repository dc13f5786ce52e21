//! The fuzz targets of `fuzz/` as bounded property tests on stable: every parser on its
//! seed corpus (`fuzz/corpus/<target>/`, the hostile cases among them) and on seeded
//! mutants of it, 10 000 cases per target by default. No case may panic or take longer
//! than `fuzz::HANG_AFTER`; a rejected network leaves `import`'s existing output as it was.
//!
//! A longer run: `FUZZ_CASES=1000000 cargo test --release -p model-export --test
//! fuzz_parsers -- --nocapture` (`FUZZ_SEED` picks another mutation sequence).
use model_export::fuzz::{self, FuzzReport};
use std::path::{Path, PathBuf};

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

/// Runs `target` on its corpus and mutants; prints the figures and asserts no panic
/// and no hang.
fn check(name: &str, target: impl FnMut(&[u8])) -> FuzzReport {
    let seeds = corpus(name);
    let r = fuzz::run_bounded(name, &seeds, cases(), seed(), target);
    println!(
        "fuzz {name}: {} cases ({} seeds), {} panics, {} hangs (> {:?}), slowest {:.3} s",
        r.cases,
        seeds.len(),
        r.panics,
        r.hangs,
        fuzz::HANG_AFTER,
        r.slowest_s
    );
    assert_eq!(
        (r.panics, r.hangs),
        (0, 0),
        "{name}: first panicking input: {:?}",
        r.first_panic.as_ref().map(|d| String::from_utf8_lossy(d))
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

/// `import --torch IN --out OUT` on one input: an error leaves the existing OUT as it
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
        "--torch",
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
