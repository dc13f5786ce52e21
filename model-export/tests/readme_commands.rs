//! The READMEs' `$ME ...` and `model-export ...` command lines, taken from the READMEs (the
//! rule of `test_support::readme`) and run with `bash` in a temporary directory, `$ME` =
//! this package's binary. Each test lists what it changes from the lines as written: tiny
//! sizes (fewer periods and epochs), placeholders filled with the committed fixtures or
//! with the files the lines before wrote, `[optional]` brackets dropped. The lines on the
//! real UR10e logs or the firmware target run when those are present and print a skip line
//! otherwise; `xtask/readme-commands.toml` names these tests as their runners.

use std::path::{Path, PathBuf};
use test_support::readme::{ReadmeCommand, readme_commands, run_ok, run_shell};
use test_support::workspace_root;

/// The model-export binary, as `$ME`.
fn me() -> (&'static str, String) {
    ("ME", env!("CARGO_BIN_EXE_model-export").to_string())
}

/// `command` with each `(from, to)` replaced; panics when `from` is not in it (a README
/// that changed must change the test too).
fn with(c: &ReadmeCommand, edits: &[(&str, &str)]) -> String {
    let mut s = c.command.clone();
    for (from, to) in edits {
        assert!(
            s.contains(from),
            "{}:{}: `{}` has no `{from}`",
            c.readme,
            c.line,
            c.command
        );
        s = s.replacen(from, to, 1);
    }
    s
}

/// A `model-export ...` synopsis line run through `$ME`, its `[optional]` brackets dropped
/// (the options inside kept).
fn synopsis(command: &str) -> String {
    let s = command.replace(['[', ']'], "");
    match s.strip_prefix("model-export ") {
        Some(rest) => format!("$ME {rest}"),
        None => s,
    }
}

/// Runs an export line: it exits 0, or the do-no-harm gate refuses the tiny network,
/// naming why, and nothing is written to `out`; returns whether it refused. `env` is the
/// same as for the other lines (both outcomes must run with it).
fn export_or_gate_refusal(
    c: &ReadmeCommand,
    command: &str,
    dir: &Path,
    env: &[(&str, String)],
    out: &Path,
) -> bool {
    let o = std::process::Command::new("bash")
        .args(["-c", command])
        .current_dir(dir)
        .envs(env.iter().map(|(k, v)| (*k, v.as_str())))
        .output()
        .unwrap();
    println!("$ {command}\n{}", String::from_utf8_lossy(&o.stdout));
    if o.status.success() {
        assert!(out.is_file(), "{}", out.display());
        return false;
    }
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("worse than the model alone"),
        "{}:{}: `{}` failed without the gate's refusal: {err}",
        c.readme,
        c.line,
        c.command
    );
    assert!(!out.exists(), "{} written after a refusal", out.display());
    println!("the do-no-harm gate refused the tiny network: {err}");
    true
}

fn fixture(path: &str) -> String {
    workspace_root().join(path).display().to_string()
}

/// The sil README's "Reproduce" block (simulate, identify, torque, train, sil on the
/// default robot's wrist), then the compnet README's CLI synopsis and PyTorch import lines
/// on its outputs and the committed PyTorch fixtures. Tiny sizes: 2 and 1 periods instead
/// of 6 and 3, 1 epoch (patience 1) instead of 30, `sil --seconds 2`.
#[test]
fn sil_and_compnet_readme_lines_run_on_the_default_robot() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let env = [me()];
    let sil = readme_commands("docs/design/sil.md", |c| {
        c.starts_with("$ME ") || c.starts_with("mkdir ")
    });
    assert_eq!(sil.len(), 7, "{sil:#?}");
    for c in &sil {
        let cmd = match c.command.split_whitespace().nth(1) {
            Some("simulate") if c.command.contains("--periods 6") => {
                with(c, &[("--periods 6", "--periods 2")])
            }
            Some("simulate") => with(c, &[("--periods 3", "--periods 1")]),
            Some("train") => with(
                c,
                &[("--epochs 30 --patience 10", "--epochs 1 --patience 1")],
            ),
            Some("sil") => format!("{} --seconds 2", c.command),
            _ => c.command.clone(),
        };
        run_ok(c, &cmd, d, &env);
    }
    for out in [
        "wrist_model.json",
        "train_features.csv",
        "sil.json",
        "sil.md",
    ] {
        assert!(d.join(out).is_file(), "{out}");
    }

    // The compnet README's CLI synopsis: run1/run2/test = the block's dataset, 1 epoch;
    // from_pytorch.* and reference.csv = the committed PyTorch fixtures.
    for name in ["run1.csv", "run2.csv", "test.csv"] {
        std::fs::copy(d.join("train_features.csv"), d.join(name)).unwrap();
    }
    let cli = |c: &str| c.starts_with("model-export ") || c.starts_with("$ME ");
    let compnet: Vec<_> = readme_commands("crates/compnet/README.md", cli)
        .into_iter()
        .chain(readme_commands("docs/design/network-interchange.md", cli))
        .collect();
    assert_eq!(compnet.len(), 6, "{compnet:#?}");
    let fx = "crates/compnet/tests/fixtures";
    for c in &compnet {
        let cmd = synopsis(&c.command);
        let cmd = match c.command.split_whitespace().nth(1) {
            Some("train") => cmd.replace("--epochs 200", "--epochs 1"),
            Some("import") if c.command.contains("from_pytorch.safetensors") => cmd
                .replace(
                    "from_pytorch.safetensors",
                    &fixture(&format!("{fx}/torch_lstm.safetensors")),
                )
                .replace(
                    "reference.csv",
                    &fixture(&format!("{fx}/torch_reference.csv")),
                ),
            Some("import") if c.command.contains("from_pytorch.onnx") => cmd
                .replace(
                    "from_pytorch.onnx",
                    &fixture(&format!("{fx}/torch_lstm.onnx")),
                )
                .replace(
                    "reference.csv",
                    &fixture(&format!("{fx}/onnx_reference.csv")),
                ),
            Some("import") => cmd
                .replace(
                    "net.safetensors",
                    &fixture(&format!("{fx}/torch_linear.safetensors")),
                )
                .replace(
                    "torch_outputs.csv",
                    &fixture(&format!("{fx}/torch_linear_reference.csv")),
                ),
            _ => cmd,
        };
        if c.command.starts_with("$ME export") {
            continue;
        }
        run_ok(c, &cmd, d, &env);
    }
    for out in [
        "train.json",
        "loss.svg",
        "eval.json",
        "net-ours.safetensors",
    ] {
        assert!(d.join(out).is_file(), "{out}");
    }
    // The linear-input network's export: net-ours = the block's 1-epoch paper network of
    // joints 4-6 (the PyTorch fixture's network has joints 1 and 2), robot.toml = the
    // default robot, VALIDATION.csv and TRAINING.csv = the block's dataset, /abs/path/ = the temporary
    // directory, host-tests/ from the workspace root.
    let export = compnet
        .iter()
        .find(|c| c.command.starts_with("$ME export"))
        .unwrap();
    let root = workspace_root();
    let cmd = with(
        export,
        &[
            (
                "--network net-ours.safetensors",
                "--network lstm_paper/lstm.safetensors",
            ),
            ("robot.toml", &fixture("robots/default.toml")),
            ("VALIDATION.csv", "train_features.csv"),
            ("TRAINING.csv", "train_features.csv"),
            (
                "host-tests/budgets.toml",
                &root.join("host-tests/budgets.toml").display().to_string(),
            ),
            ("/abs/path/", &format!("{}/", d.display())),
        ],
    );
    export_or_gate_refusal(export, &cmd, d, &env, &d.join("my_model.rs"));
}

/// The UR10e logs' folder, or `None` after the skip line.
fn ur10e() -> Option<PathBuf> {
    test_support::ur10e_dir("the README walkthrough on the UR10e logs")
}

/// The top README's "Your own robot, step by step" lines 1 and 3-7 on the UR10e logs
/// (`$D`): the excitation (300 evaluations, 1 restart, no random baseline instead of the
/// defaults), the identification as written, one dataset per run for four runs
/// (`RUN.csv` = two training runs a, b, the validation run c and the test run d), the
/// paper network trained for 1 epoch, evaluated and exported (`host-tests/` from the
/// workspace root). The export's do-no-harm gate may refuse the 1-epoch network: then the
/// refusal must name it, and the export runs again with `--allow-worse`. With the firmware target, step 8 builds the board with the
/// exported model and runs the budget with it (`$PWD` = the temporary directory).
#[test]
fn own_robot_steps_run_on_the_ur10e_logs() {
    let Some(data) = ur10e() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir_all(d.join("data")).unwrap();
    let env = [me(), ("D", data.display().to_string())];
    let steps = readme_commands("README.md", |c| {
        c.starts_with("$ME ") && c.contains("$D/ur10e.urdf")
            || c.starts_with("$ME train --data data/")
            || c.starts_with("$ME evaluate --network lstm.safetensors --data data/d.csv")
    });
    assert_eq!(steps.len(), 6, "{steps:#?}");
    let runs = [
        ("a", "identification/ur-20_02_12-50sec_12harm.csv"),
        ("b", "identification/ur-20_02_12-40sec_12harm.csv"),
        ("c", "identification/ur-20_02_05-20sec_12harm.csv"),
        ("d", "identification/ur-20_02_19_15harm50sec.csv"),
    ];
    let budgets = workspace_root().join("host-tests/budgets.toml");
    for c in &steps {
        match c.command.split_whitespace().nth(1) {
            Some("excite") => run_ok(
                c,
                &format!("{} --evaluations 300 --restarts 1 --baseline 0", c.command),
                d,
                &env,
            ),
            Some("torque") => {
                for (name, run) in runs {
                    let log = data.join(run);
                    if !log.is_file() {
                        let what = log.display().to_string();
                        test_support::skip("the README walkthrough", &what, true);
                        return;
                    }
                    let cmd = with(
                        c,
                        &[
                            ("--log RUN.csv", &format!("--log {}", log.display())),
                            ("-o data/RUN.csv", &format!("-o data/{name}.csv")),
                        ],
                    );
                    run_ok(c, &cmd, d, &env);
                }
            }
            Some("train") => run_ok(c, &format!("{} --epochs 1", c.command), d, &env),
            Some("export") => {
                let cmd = with(
                    c,
                    &[("host-tests/budgets.toml", &budgets.display().to_string())],
                );
                if export_or_gate_refusal(c, &cmd, d, &env, &d.join("my_model.rs")) {
                    // Step 8 still gets a model: the same export past the gate.
                    run_ok(c, &format!("{cmd} --allow-worse"), d, &env);
                }
            }
            _ => run_ok(c, &c.command, d, &env),
        }
    }
    if d.join("my_model.rs").is_file() && test_support::target_tools_or_skip("step 8") {
        let step8 = readme_commands("README.md", |c| {
            c.starts_with("FIRMWARE_MODEL=$PWD/my_model.rs cargo ")
        });
        assert_eq!(step8.len(), 2, "{step8:#?}");
        for c in &step8 {
            let cmd = with(c, &[("$PWD", &d.display().to_string())]);
            if c.command.ends_with("cargo budget") {
                // Exit 1: the table names the workloads still over (README "Size and cycle
                // budgets").
                let code = run_shell(&cmd, workspace_root(), &[]);
                assert!(
                    code == 0 || code == 1,
                    "{}:{}: exited {code}",
                    c.readme,
                    c.line
                );
            } else {
                run_ok(c, &cmd, workspace_root(), &[]);
            }
        }
    }
}

/// The export-then-build lines (top README's "Compiled-in model", compnet README's
/// linear-input network, top README step 8): a network exported with the README's flags
/// and the board built with it, when the firmware target is installed. The network is a
/// 1-epoch paper network of the default robot's wrist (the sil README's lines, tiny);
/// `trained.safetensors`, `robot.toml`, `validation.csv` and `/abs/path/` are filled with
/// it, the default robot, its training dataset and the temporary directory; `cargo budget` with the model runs in the budget's
/// own test (xtask).
#[test]
fn export_then_board_build_lines_run_with_the_target() {
    if !test_support::target_tools_or_skip("the export-then-build lines") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let env = [me()];
    let tiny = [
        "$ME simulate --seeded-trajectory 1 --joints 4,5,6 --periods 2 --seed 0 -o train_log.csv",
        "$ME identify --log train_log.csv --lock 1=0,2=0,3=0 --layout torque --header yes --torque-cols 20,21,22,23,24,25 -o wrist_model.json",
        "$ME torque --identified wrist_model.json --log train_log.csv --layout torque --header yes --torque-cols 20,21,22,23,24,25 --dataset --trim-rest-rad-s 0 --torque-cutoff-hz 0 -o train_features.csv",
        "$ME train --data train_features.csv --preset paper_relative --joints 4,5,6 --epochs 1 --out trained.safetensors --quiet",
    ];
    for cmd in tiny {
        assert_eq!(run_shell(cmd, d, &env), 0, "{cmd}");
    }
    let root = workspace_root();
    let robot = root.join("robots/default.toml").display().to_string();
    let budgets = root.join("host-tests/budgets.toml").display().to_string();
    let abs = format!("{}/", d.display());
    let top = readme_commands("README.md", |c| {
        c.starts_with("model-export export --network trained.safetensors")
    });
    assert_eq!(top.len(), 1, "{top:#?}");
    let cmd = with(
        &top[0],
        &[
            ("model-export export", "$ME export"),
            (
                "--network trained.safetensors",
                &format!("--network {}", d.join("trained.safetensors").display()),
            ),
            ("robot.toml", &robot),
            (
                "validation.csv",
                &d.join("train_features.csv").display().to_string(),
            ),
            ("host-tests/budgets.toml", &budgets),
            ("/abs/path/", &abs),
            ("/abs/path/", &abs),
        ],
    );
    // From the workspace root: the `&& cargo board-build` needs its aliases. When the
    // gate refuses the 1-epoch network (naming why, writing nothing), the export runs
    // again past it so the build still runs.
    let (export, build) = cmd.split_once(" && ").expect("export && build");
    if export_or_gate_refusal(&top[0], export, root, &env, &d.join("my_model.rs")) {
        run_ok(&top[0], &format!("{export} --allow-worse"), root, &env);
    }
    run_ok(&top[0], build, root, &env);
    let compnet = readme_commands("docs/design/network-interchange.md", |c| {
        c == "FIRMWARE_MODEL=/abs/path/my_model.rs cargo board-build"
    });
    assert_eq!(compnet.len(), 1);
    run_ok(
        &compnet[0],
        &with(&compnet[0], &[("/abs/path/", &abs)]),
        root,
        &[],
    );
}
