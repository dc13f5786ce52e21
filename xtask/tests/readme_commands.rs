//! Every command the workspace's READMEs show is run by a test or by CI: the commands (by
//! the rule of `test_support::readme`) against the registry `xtask/readme-commands.toml`,
//! which names, for each, the test or the `.ci/run` step that runs it. A command nothing
//! runs fails with its README and line; so does a registry entry that names a test that
//! does not exist or matches no README command. Commands registered as `not run` (each
//! with its reason) are listed on every run: the open work.

use serde::Deserialize;
use std::collections::BTreeSet;
use std::path::Path;
use test_support::readme::{ReadmeCommand, workspace_commands};

/// The registry file, relative to the workspace root.
const REGISTRY: &str = "xtask/readme-commands.toml";

/// The `run_by` of a command nothing runs yet (listed on every run, with its reason).
const NOT_RUN: &str = "not run";

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Registry {
    command: Vec<Entry>,
}

/// One README command and what runs it.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Entry {
    /// The README, relative to the workspace root.
    readme: String,
    /// The command, whitespace folded, as the rule extracts it.
    command: String,
    /// `PATH::TEST` (a `#[test]` function in that file); `ci`: `.ci/run` itself, a line
    /// of it (or the start of one), a `cargo test` that selects tests `.ci/run`'s
    /// `cargo test --workspace` runs, or a `cargo bench` of a bench it runs as a smoke
    /// test; or `not run` (with the reason in `note`).
    run_by: String,
    /// How the runner differs from the command as written (tiny sizes, a placeholder
    /// filled, the alias's expansion), when it does.
    #[serde(default)]
    note: Option<String>,
}

/// The folder of the workspace package named `name` (`NAME/` or `crates/NAME/` holding a
/// `Cargo.toml` with that name).
fn package_dir(root: &Path, name: &str) -> Option<std::path::PathBuf> {
    [root.to_path_buf(), root.join("crates")]
        .iter()
        .filter_map(|d| std::fs::read_dir(d).ok())
        .flatten()
        .flatten()
        .map(|e| e.path())
        .find(|d| {
            // The first `name =` of a manifest is its package's.
            std::fs::read_to_string(d.join("Cargo.toml")).is_ok_and(|t| {
                t.lines().find(|l| l.starts_with("name = "))
                    == Some(format!("name = \"{name}\"").as_str())
            })
        })
}

/// Why a `cargo test ...` command is not among the tests `cargo test --workspace` runs,
/// or `None` when it is: no profile of its own, its package in the workspace, its
/// `--test NAME` target a file of that package's `tests/`.
fn ci_test_problem(root: &Path, command: &str) -> Option<String> {
    let words: Vec<&str> = command.split_whitespace().collect();
    if words.iter().any(|w| *w == "--profile" || *w == "--release") {
        return Some("a profile of its own: not what CI's `cargo test --workspace` runs".into());
    }
    let after = |flag: &str| {
        words
            .iter()
            .position(|w| *w == flag)
            .and_then(|k| words.get(k + 1))
    };
    // No `-p`: the whole workspace's tests.
    let package = after("-p")?;
    let Some(dir) = package_dir(root, package) else {
        return Some(format!("no workspace package `{package}`"));
    };
    match after("--test") {
        Some(test) if !dir.join("tests").join(format!("{test}.rs")).is_file() => Some(format!(
            "package `{package}` has no test target `{test}` ({}/tests/{test}.rs)",
            dir.display()
        )),
        _ => None,
    }
}

/// Why a `cargo bench ... -p PACKAGE --bench NAME` command (after any `VAR=value`
/// settings) is not run by `cargo test --workspace`, or `None` when it is: the package's
/// manifest gives bench `NAME` `test = true`, so `cargo test` runs it as a smoke test
/// (tiny sizes, `test_support::bench`).
fn ci_bench_problem(root: &Path, command: &str) -> Option<String> {
    let words: Vec<&str> = command
        .split_whitespace()
        .skip_while(|w| w.contains('=') && !w.starts_with('-'))
        .collect();
    let after = |flag: &str| {
        words
            .iter()
            .position(|w| *w == flag)
            .and_then(|k| words.get(k + 1))
    };
    let (Some(package), Some(bench)) = (after("-p"), after("--bench")) else {
        return Some("a `cargo bench` without `-p PACKAGE --bench NAME`".into());
    };
    let Some(dir) = package_dir(root, package) else {
        return Some(format!("no workspace package `{package}`"));
    };
    let path = dir.join("Cargo.toml");
    let manifest: toml::Value = match std::fs::read_to_string(&path)
        .map_err(|e| e.to_string())
        .and_then(|t| toml::from_str(&t).map_err(|e| e.to_string()))
    {
        Ok(m) => m,
        Err(e) => return Some(format!("{}: {e}", path.display())),
    };
    let smoke_tested = manifest
        .get("bench")
        .and_then(|b| b.as_array())
        .into_iter()
        .flatten()
        .any(|b| {
            b.get("name").and_then(|n| n.as_str()) == Some(bench)
                && b.get("test").and_then(|t| t.as_bool()) == Some(true)
        });
    (!smoke_tested).then(|| {
        format!("package `{package}` has no bench `{bench}` with `test = true` (cargo test would not run it)")
    })
}

/// Why `run_by` does not name a runner, or `None` when it does.
fn runner_problem(root: &Path, entry: &Entry, ci_lines: &BTreeSet<String>) -> Option<String> {
    if entry.run_by == NOT_RUN {
        return entry
            .note
            .is_none()
            .then(|| "`not run` without a `note` saying why".to_string());
    }
    if entry.run_by == "ci" {
        // `.ci/run` itself; a line of it, or the start of one (CI runs it with more flags);
        // a `cargo test` of tests `.ci/run`'s `cargo test --workspace` runs; a `cargo bench`
        // of a bench that it runs as a smoke test.
        if entry.command == "bash .ci/run"
            || ci_lines
                .iter()
                .any(|l| *l == entry.command || l.starts_with(&format!("{} ", entry.command)))
        {
            return None;
        }
        if entry.command.starts_with("cargo test ") && ci_lines.contains("cargo test --workspace") {
            return ci_test_problem(root, &entry.command);
        }
        if entry.command.contains("cargo bench ") && ci_lines.contains("cargo test --workspace") {
            return ci_bench_problem(root, &entry.command);
        }
        return Some(
            "`ci`, but it is neither .ci/run, a line of it, nor a `cargo test` of the workspace"
                .to_string(),
        );
    }
    let Some((file, test)) = entry.run_by.split_once("::") else {
        return Some(format!(
            "run_by `{}` is neither `ci` nor PATH::TEST",
            entry.run_by
        ));
    };
    let Ok(text) = std::fs::read_to_string(root.join(file)) else {
        return Some(format!("run_by names {file}, which does not exist"));
    };
    let lines: Vec<&str> = text.lines().collect();
    let Some(k) = lines
        .iter()
        .position(|l| l.trim_start().starts_with(&format!("fn {test}(")))
    else {
        return Some(format!("{file} has no `fn {test}(`"));
    };
    let is_test = lines[k.saturating_sub(4)..k]
        .iter()
        .any(|l| l.trim() == "#[test]");
    (!is_test).then(|| format!("{file}: `{test}` is not a #[test]"))
}

#[test]
fn a_bench_counts_as_run_by_ci_only_when_cargo_test_runs_it() {
    let root = test_support::workspace_root();
    for ok in [
        "cargo bench -p model-export --bench urdf",
        "cargo bench -p model-export --bench urdf --profile host",
        "CARGO_PROFILE_BENCH_LTO=false cargo bench -p model-export --bench excite",
    ] {
        assert_eq!(ci_bench_problem(root, ok), None, "{ok}");
    }
    for (bad, why) in [
        (
            "cargo bench -p model-export --bench nothing",
            "no bench `nothing`",
        ),
        (
            "cargo bench -p no-such-crate --bench urdf",
            "no workspace package",
        ),
        (
            "cargo bench -p model-export",
            "without `-p PACKAGE --bench NAME`",
        ),
    ] {
        let problem = ci_bench_problem(root, bad).unwrap_or_default();
        assert!(problem.contains(why), "{bad}: {problem}");
    }
}

#[test]
fn every_readme_command_is_run_by_a_test_or_ci() {
    let root = test_support::workspace_root();
    let commands: Vec<ReadmeCommand> = workspace_commands(root).expect("READMEs read");
    assert!(
        commands.len() > 50,
        "the rule found only {} commands",
        commands.len()
    );
    let text = std::fs::read_to_string(root.join(REGISTRY)).expect("the registry");
    let registry: Registry = toml::from_str(&text).unwrap_or_else(|e| panic!("{REGISTRY}: {e}"));
    let ci_lines: BTreeSet<String> = std::fs::read_to_string(root.join(".ci/run"))
        .expect(".ci/run")
        .lines()
        .map(|l| l.split_whitespace().collect::<Vec<_>>().join(" "))
        .collect();

    let mut problems = Vec::new();
    for c in &commands {
        if !registry
            .command
            .iter()
            .any(|e| e.readme == c.readme && e.command == c.command)
        {
            problems.push(format!(
                "{}:{}: `{}` is run by no test and no CI step (add it to {REGISTRY} with its runner)",
                c.readme, c.line, c.command
            ));
        }
    }
    let mut seen = BTreeSet::new();
    let mut notes = 0;
    for e in &registry.command {
        if !seen.insert((e.readme.as_str(), e.command.as_str())) {
            problems.push(format!(
                "{REGISTRY}: `{}` ({}) is listed twice",
                e.command, e.readme
            ));
        }
        if !commands
            .iter()
            .any(|c| c.readme == e.readme && c.command == e.command)
        {
            problems.push(format!(
                "{REGISTRY}: `{}` is not a command of {} (any more)",
                e.command, e.readme
            ));
        }
        if let Some(p) = runner_problem(root, e, &ci_lines) {
            problems.push(format!("{REGISTRY}: `{}` ({}): {p}", e.command, e.readme));
        }
        notes += usize::from(e.note.is_some());
    }
    let not_run: Vec<&Entry> = registry
        .command
        .iter()
        .filter(|e| e.run_by == NOT_RUN)
        .collect();
    for e in &not_run {
        println!(
            "not run: {}: `{}`: {}",
            e.readme,
            e.command,
            e.note.as_deref().unwrap_or("")
        );
    }
    println!(
        "{} README commands ({} distinct), {} registry entries ({} with a note, {} not run)",
        commands.len(),
        commands
            .iter()
            .map(|c| (&c.readme, &c.command))
            .collect::<BTreeSet<_>>()
            .len(),
        registry.command.len(),
        notes,
        not_run.len()
    );
    assert!(problems.is_empty(), "\n{}", problems.join("\n"));
}
