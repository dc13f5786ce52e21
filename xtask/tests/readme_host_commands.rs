//! The READMEs' host cargo commands that run the model-export binary or its examples
//! (`cargo run ... -p model-export ...`), taken from the READMEs and run with `bash` from
//! the workspace root in the dev profile that `cargo test` has already built: `--release`
//! and `--profile host` are dropped (they only choose the build profile, and a cold
//! release build of model-export takes minutes), `[optional]` brackets dropped with their
//! options kept, placeholders filled (each test says which).
//! `xtask/readme-commands.toml` names these tests as their runners.

use test_support::readme::{ReadmeCommand, readme_commands, run_ok};
use test_support::workspace_root;

/// `c` in the dev profile: `--release` and `--profile host` dropped, brackets dropped.
fn dev_profile(c: &ReadmeCommand) -> String {
    c.command
        .replace(" --release", "")
        .replace(" --profile host", "")
        .replace(['[', ']'], "")
}

/// The one command of `readme` equal to `command`.
fn the(readme: &str, command: &str) -> ReadmeCommand {
    let found = readme_commands(readme, |c| c == command);
    assert!(!found.is_empty(), "{readme}: no `{command}`");
    found[0].clone()
}

/// `model-export sil` (sil and firmware READMEs, 2 s of simulated time instead of the
/// 30 s default) and `plant-report --ablation` (plant-sim README) through `cargo run`.
#[test]
fn cargo_run_model_export_lines_run() {
    let root = workspace_root();
    let c = the(
        "crates/sil/README.md",
        "cargo run --release -p model-export -- sil [--seconds 5] [--seed 7]",
    );
    run_ok(
        &c,
        &dev_profile(&c).replace("--seconds 5", "--seconds 2"),
        root,
        &[],
    );
    let c = the(
        "firmware/README.md",
        "cargo run --release -p model-export -- sil",
    );
    run_ok(&c, &format!("{} --seconds 2", dev_profile(&c)), root, &[]);
    let c = the(
        "crates/plant-sim/README.md",
        "cargo run --release -p model-export -- plant-report --ablation",
    );
    run_ok(&c, &dev_profile(&c), root, &[]);
}

/// The model-export examples (robot and compnet READMEs): base parameters of the default
/// robot (`ROBOT` = `robots/default.toml`), the SGEMM shapes. (The excitation probe's
/// `floors` takes 132 s in the dev profile: not run here, see the registry.)
#[test]
fn model_export_examples_run() {
    let root = workspace_root();
    let c = the(
        "crates/robot/README.md",
        "cargo run -p model-export --example base_parameters -- ROBOT [--rigid] [--paper]",
    );
    run_ok(
        &c,
        &dev_profile(&c).replace("ROBOT", "robots/default.toml"),
        root,
        &[],
    );
    let c = the(
        "crates/compnet/README.md",
        "cargo run --release -p model-export --example gemm_shapes",
    );
    run_ok(&c, &dev_profile(&c), root, &[]);
}
