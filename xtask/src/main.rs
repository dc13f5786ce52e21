//! `cargo xtask`: the project's orchestration that needs cargo itself (the usual Rust
//! pattern). `cargo xtask demo` is the README's main job: every host stage of the pipeline
//! through `model-export`, then the board firmware built with the exported model and the
//! size and cycle budget run, into one report folder.
use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use model_export::cmd::demo::{DemoArgs, FirmwareStages, Pipeline, demo, stage_spinner};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// Project tasks.
#[derive(Debug, Parser)]
#[command(name = "cargo xtask")]
struct Xtask {
    #[command(subcommand)]
    task: Task,
}

#[derive(Debug, Subcommand)]
enum Task {
    /// The end-to-end demo on the built-in default robot (the README's main job).
    Demo {
        #[command(flatten)]
        demo: DemoArgs,
        /// Also copy the exported model to `firmware/src/model/default_model.rs`, the
        /// committed default the firmware builds with.
        #[arg(long)]
        install: bool,
    },
}

/// The workspace root: the xtask's own crate sits in it.
fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from("."))
}

/// The board build and the budget run, as cargo commands in the workspace.
struct CargoFirmware {
    root: PathBuf,
}

impl CargoFirmware {
    /// Runs `cargo ARGS` with `FIRMWARE_MODEL=model` and records it in `pl`; with
    /// `over_budget_ok`, exit code 1 (the budget tool's "over budget": its table names each
    /// overrun) is recorded as a finding of the stage, not a failure.
    fn cargo(
        &self,
        pl: &mut Pipeline,
        stage: &str,
        args: &[&str],
        model: &Path,
        over_budget_ok: bool,
    ) -> Result<String> {
        let command = format!(
            "FIRMWARE_MODEL={} cargo {}",
            model.display(),
            args.join(" ")
        );
        println!("\n==> [{stage}] {command}");
        let t0 = Instant::now();
        let spinner = stage_spinner(stage);
        let out = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()))
            .current_dir(&self.root)
            .args(args)
            .env("FIRMWARE_MODEL", model)
            .stderr(std::process::Stdio::inherit())
            .output()
            .with_context(|| format!("stage {stage}: running cargo"));
        spinner.finish_and_clear();
        let over_budget = over_budget_ok
            && out
                .as_ref()
                .is_ok_and(|o| o.status.code() == Some(1) && !o.stdout.is_empty());
        let result = match out {
            Ok(o) if o.status.success() || over_budget => {
                Ok(String::from_utf8_lossy(&o.stdout).into_owned())
            }
            Ok(o) => Err(anyhow::anyhow!(
                "stage {stage}: cargo {} failed ({}):\n{}",
                args.join(" "),
                o.status,
                String::from_utf8_lossy(&o.stdout)
            )),
            Err(e) => Err(e),
        };
        pl.record(
            stage,
            command,
            t0,
            result.as_ref().map(|_| ()).map_err(|e| format!("{e:#}")),
        )?;
        if over_budget {
            pl.set_last_status("over budget (see the budget table)");
            println!("    [{stage}] over budget: the budget table names each overrun");
        }
        result
    }
}

impl FirmwareStages for CargoFirmware {
    fn run(&mut self, pl: &mut Pipeline, model: &Path, out: &Path) -> Result<Option<String>> {
        let model = std::fs::canonicalize(model)
            .with_context(|| format!("resolving {}", model.display()))?;
        self.cargo(
            pl,
            "firmware build",
            &[
                "build",
                "--release",
                "--target",
                "thumbv7em-none-eabihf",
                "-p",
                "board",
                "--bin",
                "board",
                "--target-dir",
                "target/demo",
            ],
            &model,
            false,
        )?;
        let json_file = std::path::absolute(out.join("firmware").join("budget.json"))
            .context("resolving the report folder")?;
        let json_arg = json_file.display().to_string();
        let markdown = self.cargo(
            pl,
            "budget",
            &[
                "run",
                "--quiet",
                "--target-dir",
                "target/demo",
                "-p",
                "host-tests",
                "--bin",
                "budget",
                "--",
                "--json-file",
                &json_arg,
            ],
            &model,
            true,
        )?;
        artifacts::write_atomic(&out.join("firmware").join("budget.md"), markdown.as_bytes())?;
        Ok(Some(markdown))
    }
}

fn main() -> std::process::ExitCode {
    let run = || -> Result<()> {
        match Xtask::parse().task {
            Task::Demo {
                demo: mut args,
                install,
            } => {
                let root = workspace_root();
                args.budgets
                    .get_or_insert_with(|| root.join("host-tests/budgets.toml"));
                demo(&args, &mut CargoFirmware { root: root.clone() })?;
                if install {
                    let src = args.out.join("firmware").join("model.rs");
                    let dst = root.join("firmware/src/model/default_model.rs");
                    std::fs::copy(&src, &dst).with_context(|| {
                        format!("copying {} to {}", src.display(), dst.display())
                    })?;
                    println!("installed {} as {}", src.display(), dst.display());
                }
                Ok(())
            }
        }
    };
    match run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
