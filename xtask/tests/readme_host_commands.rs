//! The READMEs' host commands that run the model-export binary or its examples
//! (`cargo run ... -p model-export ...`), the PyTorch reference epoch and a build-time
//! measurement, taken from the READMEs and run with `bash` from
//! the workspace root in the dev profile that `cargo test` has already built: `--release`
//! and `--profile host` are dropped (they only choose the build profile, and a cold
//! release build of model-export takes minutes), `[optional]` brackets dropped with their
//! options kept, placeholders filled (each test says which).
//! `xtask/readme-commands.toml` names these tests as their runners.

use test_support::readme::{ReadmeCommand, readme_command, run_ok};
use test_support::workspace_root;

/// `c` in the dev profile: `--release` and `--profile host` dropped, brackets dropped.
fn dev_profile(c: &ReadmeCommand) -> String {
    c.command
        .replace(" --release", "")
        .replace(" --profile host", "")
        .replace(['[', ']'], "")
}

/// `model-export sil` (sil and firmware READMEs, 2 s of simulated time instead of the
/// 30 s default) and `plant-report --ablation` (docs/studies/plant-residual.md) through `cargo run`.
#[test]
fn cargo_run_model_export_lines_run() {
    let root = workspace_root();
    let c = readme_command(
        "docs/design/sil.md",
        "cargo run --release -p model-export -- sil [--seconds 5] [--seed 7]",
    );
    run_ok(
        &c,
        &dev_profile(&c).replace("--seconds 5", "--seconds 2"),
        root,
        &[],
    );
    let c = readme_command(
        "firmware/README.md",
        "cargo run --release -p model-export -- sil",
    );
    run_ok(&c, &format!("{} --seconds 2", dev_profile(&c)), root, &[]);
    let c = readme_command(
        "docs/studies/plant-residual.md",
        "cargo run --release -p model-export -- plant-report --ablation",
    );
    run_ok(&c, &dev_profile(&c), root, &[]);
}

/// The model-export examples (robot, compnet and excitation READMEs): base parameters of
/// the default robot (`ROBOT` = `robots/default.toml`), the SGEMM shapes, the excitation
/// probe's `floors` (tiny: 1 restart of 60 evaluations instead of 4 of 6 000).
#[test]
fn model_export_examples_run() {
    let root = workspace_root();
    let c = readme_command(
        "docs/design/robot-dynamics.md",
        "cargo run -p model-export --example base_parameters -- ROBOT [--rigid] [--paper]",
    );
    run_ok(
        &c,
        &dev_profile(&c).replace("ROBOT", "robots/default.toml"),
        root,
        &[],
    );
    let c = readme_command(
        "docs/studies/training-benchmark.md",
        "cargo run --release -p model-export --example gemm_shapes",
    );
    run_ok(&c, &dev_profile(&c), root, &[]);
    let c = readme_command(
        "docs/studies/excitation-vs-random.md",
        "cargo run --profile host -p model-export --example excite_probe -- floors",
    );
    run_ok(&c, &format!("{} 1 60", dev_profile(&c)), root, &[]);
}

/// The compnet README's PyTorch reference epoch (the `lstm_epoch` benchmark's other
/// half), tiny (2 000 steps, H = 16, 1 epoch), where `python3` imports torch; otherwise
/// one skip line.
#[test]
fn bench_torch_script_runs_where_torch_is_installed() {
    if !test_support::available("the PyTorch reference epoch", &[test_support::Need::Torch]) {
        return;
    }
    let c = readme_command(
        "docs/studies/training-benchmark.md",
        "python3 scripts/bench_torch.py --burn-in 0 --threads 1",
    );
    run_ok(
        &c,
        &format!("{} --steps 2000 --hidden 16 --epochs 1", c.command),
        workspace_root(),
        &[],
    );
}

/// The compnet README's build-time measurement of the ONNX reader's crates, in a
/// temporary `CARGO_TARGET_DIR` (the from-scratch build the line measures, leaving the
/// workspace's own build alone): it builds and writes cargo's timing report.
#[test]
fn onnx_protobuf_build_timing_line_runs() {
    let c = readme_command(
        "crates/compnet/README.md",
        "cargo clean -p onnx-protobuf -p protobuf -p protobuf-support && cargo build -p onnx-protobuf --timings",
    );
    let target = tempfile::tempdir().unwrap();
    let env = [("CARGO_TARGET_DIR", target.path().display().to_string())];
    run_ok(&c, &c.command, workspace_root(), &env);
    assert!(
        target
            .path()
            .join("cargo-timings/cargo-timing.html")
            .is_file(),
        "no timing report in {}",
        target.path().display()
    );
}
