//! The READMEs' cargo, script and tool commands that need more than the host: the
//! firmware target and `qemu-system-arm` (board and QEMU builds, the budget, the demo),
//! the real UR10e logs (the study scripts), embassy's crates (hal-compare), a nightly
//! toolchain with cargo-fuzz, a debug probe. Each runs its README's lines as written
//! (taken from the README by the rule of `test_support::readme`), from the folder the
//! README says, when what it needs is present, and prints a skip line otherwise; each
//! test lists what it changes (tiny sizes, placeholders filled).
//! `xtask/readme-commands.toml` names these tests as their runners.

use std::path::{Path, PathBuf};
use test_support::readme::{ReadmeCommand, readme_command, readme_commands, run_ok, run_shell};
use test_support::{Need, available, has_program, skip, target_tools_or_skip, workspace_root};

/// `c` as written, from the workspace root.
fn run_at_root(c: &ReadmeCommand) {
    run_ok(c, &c.command, workspace_root(), &[]);
}

/// A budget command as written: exit 0 (within budget) or 1 (the table names the
/// workloads still over, README "Size and cycle budgets"), the table or JSON printed.
fn run_budget(c: &ReadmeCommand, command: &str, env: &[(&str, String)]) {
    let code = run_shell(command, workspace_root(), env);
    assert!(
        code == 0 || code == 1,
        "{}:{}: `{}` exited {code}",
        c.readme,
        c.line,
        c.command
    );
}

/// The firmware target's cargo aliases and builds (top, board and host-tests READMEs),
/// as written from the workspace root. `LEVEL` is filled with 2; `FIRMWARE_MODEL=…` and
/// `--json-file …` with the committed default model and a temporary file.
#[test]
fn firmware_target_commands_run_as_written() {
    if !target_tools_or_skip("the firmware target's commands") {
        return;
    }
    for (readme, command) in [
        ("README.md", "cargo board-build"),
        ("README.md", "cargo qemu-build"),
        ("README.md", "cargo qemu-run"),
        (
            "board/README.md",
            "cargo build --release --target thumbv7em-none-eabihf -p board --bin board --features defmt",
        ),
        (
            "board/README.md",
            "cargo build --release --target thumbv7em-none-eabihf -p board --bin board-moteus --features defmt",
        ),
    ] {
        run_at_root(&readme_command(readme, command));
    }
    let dir = tempfile::tempdir().unwrap();
    for (readme, command) in [
        ("README.md", "cargo budget"),
        ("README.md", "cargo run -p host-tests --bin budget"),
        (
            "host-tests/README.md",
            "cargo run -p host-tests --bin budget -- --json",
        ),
    ] {
        let c = readme_command(readme, command);
        run_budget(&c, &c.command, &[]);
    }
    let c = readme_command(
        "README.md",
        "cargo run -p host-tests --bin budget -- --opt-level LEVEL --json",
    );
    run_budget(&c, &c.command.replace("LEVEL", "2"), &[]);
    let model = workspace_root().join("firmware/src/model/default_model.rs");
    let json = dir.path().join("budget.json");
    let c = readme_command(
        "host-tests/README.md",
        "FIRMWARE_MODEL=… cargo run --quiet --target-dir target/demo -p host-tests --bin budget -- --json-file …",
    );
    let command = c
        .command
        .replacen('…', &model.display().to_string(), 1)
        .replacen('…', &json.display().to_string(), 1);
    run_budget(&c, &command, &[]);
    let text = std::fs::read_to_string(&json).expect("the budget JSON file");
    assert!(text.contains("cycles_max_g474"), "{text}");
}

/// The demo (top and xtask READMEs) through the xtask binary: `cargo xtask demo` in its
/// fast variant (`--fast`, report in a temporary folder), with the board build and the
/// budget run, so with the firmware target only. `--install` is left out: it overwrites
/// the committed default model.
#[test]
fn xtask_demo_runs_with_the_firmware_stages() {
    if !target_tools_or_skip("`cargo xtask demo`") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("report");
    let c = readme_command("README.md", "cargo xtask demo");
    let command = format!(
        "{} demo --fast --out {}",
        env!("CARGO_BIN_EXE_xtask"),
        out.display()
    );
    run_ok(&c, &command, workspace_root(), &[]);
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(report.contains("fast (CI) variant"), "{report}");
    assert!(out.join("firmware/budget.md").is_file());
}

/// Whether a debug probe is attached (`probe-rs list` names one); prints the skip line
/// otherwise.
fn probe_or_skip() -> bool {
    if !has_program("probe-rs") {
        let what = "probe-rs (`cargo install probe-rs-tools`) and a debug probe";
        skip("the board commands", what, false);
        return false;
    }
    let out = std::process::Command::new("probe-rs").arg("list").output();
    let listed = out
        .map(|o| String::from_utf8_lossy(&o.stdout).contains('['))
        .unwrap_or(false);
    if !listed {
        skip(
            "the board commands",
            "a debug probe (probe-rs lists none)",
            false,
        );
    }
    listed
}

/// The commands that flash and run the board (top, board, host-tests and test-kit
/// READMEs), on an attached probe and board: the joint 5 configuration block, then the
/// bench and drive binaries, each for 60 s (they log until stopped).
#[test]
fn board_commands_run_on_a_probe() {
    if !target_tools_or_skip("the board commands") || !probe_or_skip() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    // The provisioning lines (a fresh key, the block for joint 5, the probe-rs write),
    // `$ME` the model-export binary of this workspace.
    let me = format!(
        "cargo run -q --profile host --manifest-path {} -p model-export --",
        workspace_root().join("Cargo.toml").display()
    );
    for c in readme_commands("board/README.md", |c| {
        c.starts_with("od ") || c.starts_with("$ME provision ") || c.starts_with("probe-rs ")
    }) {
        run_ok(&c, &c.command.replace("$ME", &me), dir.path(), &[]);
    }
    for command in ["cargo board-bench-run", "cargo board-run"] {
        let c = readme_command("README.md", command);
        let code = run_shell(&format!("timeout 60 {command}"), workspace_root(), &[]);
        // 124: stopped by the timeout while logging, as it runs until stopped.
        assert!(
            code == 124 || code == 0,
            "{}:{}: {command} exited {code}",
            c.readme,
            c.line
        );
    }
}

/// The UR10e logs' folder (`$DATASETS_DIR/ur10e`), or `None` after the skip line.
fn ur10e() -> Option<PathBuf> {
    test_support::ur10e_dir("the real-data study scripts")
}

/// The real-data study scripts (top and compnet READMEs) on the UR10e logs, tiny: the
/// compensation study on joint 6 only, the drive network only, 1 epoch (`JOINTS=6 NETS=drive
/// EPOCHS=1`), the LSTM tables' script for 1 epoch (`EPOCHS=1`); `$D` is the logs' folder,
/// `OUT_DIR` a temporary one. The compnet README's two other spellings of the study
/// (`DATASET_DIR OUT_DIR`, `../shared/datasets/ur10e /tmp/study13`) are this line with
/// other placeholders.
#[test]
fn study_scripts_run_on_the_ur10e_logs() {
    let Some(data) = ur10e() else {
        return;
    };
    let datasets = data
        .parent()
        .expect("the datasets folder")
        .display()
        .to_string();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("study");
    let tiny = [
        ("JOINTS", "6".to_string()),
        ("EPOCHS", "1".to_string()),
        ("NETS", "drive".to_string()),
        ("D", data.display().to_string()),
        ("DATASETS_DIR", datasets),
    ];
    let c = readme_command("README.md", "bash scripts/ur10e_compensation.sh $D OUT_DIR");
    run_ok(
        &c,
        &c.command.replace("OUT_DIR", &out.display().to_string()),
        workspace_root(),
        &tiny,
    );
    let summary = std::fs::read_to_string(out.join("summary.json")).expect("summary.json");
    assert!(summary.contains("drive"), "{summary}");
    let c = readme_command(
        "docs/studies/ur10e-compensation.md",
        "bash scripts/ur10e_lstm.sh OUT_DIR",
    );
    let lstm = dir.path().join("lstm");
    run_ok(
        &c,
        &c.command.replace("OUT_DIR", &lstm.display().to_string()),
        workspace_root(),
        &tiny,
    );
    assert!(lstm.join("model.json").is_file());
}

/// Whether embassy's crates for hal-compare can be had (from the local cache or the
/// network); prints the skip line otherwise.
fn hal_compare_crates_or_skip(dir: &Path) -> bool {
    let ok = std::process::Command::new(env!("CARGO"))
        .args(["fetch", "--quiet"])
        .current_dir(dir)
        .status()
        .is_ok_and(|s| s.success());
    if !ok {
        let what = "embassy-stm32's crates (neither cached nor downloadable)";
        skip("hal-compare", what, false);
    }
    ok
}

/// The board/hal-compare README's build and measurement lines, from its folder, and the
/// board's counterpart from the workspace root; with the firmware target, embassy's crates
/// (cached or downloadable), python3 and llvm-size. The clean-build timing lines (their
/// own target folders) are left to the README: a full embassy build each.
#[test]
fn hal_compare_builds_and_measures() {
    let here = workspace_root().join("board/hal-compare");
    if !target_tools_or_skip("hal-compare") || !hal_compare_crates_or_skip(&here) {
        return;
    }
    let tools = [
        Need::Program {
            name: "python3",
            ci: false,
        },
        Need::Program {
            name: "llvm-size",
            ci: true,
        },
    ];
    if !available("hal-compare's measurement", &tools) {
        return;
    }
    let lines = readme_commands("board/hal-compare/README.md", |c| {
        c == "cargo build --release" || c.starts_with("python3 ") || c.starts_with("llvm-size ")
    });
    assert_eq!(lines.len(), 3, "{lines:#?}");
    for c in &lines {
        run_ok(c, &c.command, &here, &[]);
    }
    let board = readme_command("board/hal-compare/README.md", "cargo board-build");
    run_at_root(&board);
    run_ok(
        &board,
        "python3 board/hal-compare/isr_path.py target/thumbv7em-none-eabihf/release/board",
        workspace_root(),
        &[],
    );
}

/// The fuzzing README line, 20 s of the `log_csv` target, with a nightly toolchain and
/// cargo-fuzz.
#[test]
fn cargo_fuzz_runs_with_nightly() {
    let ok = std::process::Command::new("cargo")
        .args(["+nightly", "fuzz", "--version"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok {
        skip(
            "the fuzzing README line",
            "a nightly toolchain and cargo-fuzz",
            false,
        );
        return;
    }
    let c = readme_command("model-export/README.md", "cargo +nightly fuzz run log_csv");
    run_ok(
        &c,
        &format!("{} -- -max_total_time=20", c.command),
        workspace_root(),
        &[],
    );
}
