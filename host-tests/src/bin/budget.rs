//! Size and cycle budget table of the firmware: builds the target binaries, sizes
//! them, estimates each workload's Cortex-M4 cycles from a QEMU instruction trace
//! weighted by the TRM cycle tables and by the STM32G474's flash, caches and FPU
//! stall, and compares the STM32G474 figure with `host-tests/budgets.toml`.
//!
//! `cargo run -p host-tests --bin budget [-- --json] [--budgets FILE]
//! [--opt-level 2|3|s|z] [--pipeline-refill P] [--wait-states N] [--dual-bank]
//! [--no-fpu-stall] [--per-instruction WORKLOAD]`; exits 1 when a budget is exceeded.
//! `--per-instruction WORKLOAD` prints that workload's worst STM32G474 tick per
//! instruction (tab-separated) instead of the table.
use anyhow::{Context, Result, bail};
use host_tests::budget::{self, Budgets, Options};
use std::path::PathBuf;

fn main() -> std::process::ExitCode {
    match run() {
        Ok(true) => std::process::ExitCode::SUCCESS,
        Ok(false) => std::process::ExitCode::FAILURE,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::from(2)
        }
    }
}

fn run() -> Result<bool> {
    let mut json = false;
    let mut json_file = None;
    let mut per_instruction = None;
    let mut file = budget::default_budget_file();
    let mut opts = Options::default();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || args.next().with_context(|| format!("{a} needs a value"));
        match a.as_str() {
            "--json" => json = true,
            "--json-file" => json_file = Some(PathBuf::from(value()?)),
            "--budgets" => file = PathBuf::from(value()?),
            "--opt-level" => opts.opt_level = Some(value()?),
            "--pipeline-refill" => opts.model.pipeline_refill = value()?.parse()?,
            "--wait-states" => opts.chip.flash.wait_states = value()?.parse()?,
            "--dual-bank" => opts.chip.flash.read_bytes = 8,
            "--no-fpu-stall" => opts.chip.fpu_result_stall = false,
            "--per-instruction" => per_instruction = Some(value()?),
            "-h" | "--help" => {
                println!(
                    "usage: budget [--json] [--json-file FILE] [--budgets FILE] [--opt-level 2|3|s|z] \
                     [--pipeline-refill P] [--wait-states N] [--dual-bank] [--no-fpu-stall] \
                     [--per-instruction WORKLOAD]"
                );
                return Ok(true);
            }
            other => bail!("unknown argument `{other}` (try --help)"),
        }
    }
    let budgets = Budgets::load(&file)?;
    let report = budget::report(budget::measure(&opts)?, budgets);
    if let Some(path) = &json_file {
        std::fs::write(path, report.json()?)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    if let Some(name) = &per_instruction {
        let w = report
            .measurement
            .workloads
            .iter()
            .find(|w| &w.name == name)
            .with_context(|| format!("--per-instruction: no workload `{name}`"))?;
        print_instructions(w);
    } else if json {
        println!("{}", report.json()?);
    } else {
        print!("{}", report.markdown());
    }
    for v in &report.violations {
        eprintln!("over budget: {v}");
    }
    Ok(report.violations.is_empty())
}

/// The worst STM32G474 tick of `w`, per instruction in address order: executions,
/// estimated cycles at zero wait and on the G474, and the difference (stalls).
fn print_instructions(w: &budget::WorkloadCost) {
    println!(
        "# {}: worst STM32G474 tick per instruction (estimated cycles)",
        w.name
    );
    println!("address\texecuted\tzero-wait\tG474\tstall\tinstruction\tfunction");
    for i in &w.instructions {
        println!(
            "{:#010x}\t{}\t{}\t{}\t{}\t{}\t{}",
            i.addr,
            i.cost.instructions,
            i.cost.cycles,
            i.cost.chip_cycles,
            i.cost.chip_cycles - i.cost.cycles,
            i.text,
            i.function
        );
    }
}
