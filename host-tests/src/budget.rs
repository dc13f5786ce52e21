//! Size and cycle budgets: measure the firmware (ELF sizes, QEMU trace weighted by
//! the Cortex-M4 cycle tables), compare with `host-tests/budgets.toml`, and print
//! the table (Markdown or JSON).
//!
//! Cycle figures here are estimates from the QEMU instruction trace weighted by the
//! Cortex-M4 TRM cycle tables (see [`crate::cycles`]); only DWT CYCCNT on the board
//! measures cycles.
use crate::cycles::CycleModel;
use crate::elf::{self, SizeReport};
use crate::memory::ChipModel;
use crate::target::{self, FirmwareBin};
use crate::{disasm, qemu, trace};
use anyhow::{Result, bail};
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The checked-in budget file.
pub fn default_budget_file() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("budgets.toml")
}

/// The budget file's schema, shared with the exporter (`crates/budgets`).
pub use budgets::{BinaryBudget, Budgets, Mcu};

/// Measured size of one binary.
#[derive(Clone, Debug, Serialize)]
pub struct BinarySize {
    /// Cargo binary name.
    pub name: String,
    /// ELF path.
    pub elf: PathBuf,
    /// Sections and biggest symbols.
    pub size: SizeReport,
}

/// Per-function share of a workload's tick (self cost, mean per tick).
#[derive(Clone, Debug, Serialize)]
pub struct FunctionCost {
    /// Demangled function name.
    pub name: String,
    /// Instructions per tick.
    pub instructions: f64,
    /// Estimated cycles per tick.
    pub cycles: f64,
    /// Estimated cycles per tick on the STM32G474.
    pub cycles_g474: f64,
}

/// Measured cost of one workload's tick.
#[derive(Clone, Debug, Serialize)]
pub struct WorkloadCost {
    /// Workload name.
    pub name: String,
    /// The measured tick function.
    pub function: String,
    /// Ticks traced.
    pub ticks: usize,
    /// Multiply-accumulates per tick.
    pub macs: u32,
    /// Traced instructions per tick: mean.
    pub instructions_mean: f64,
    /// Estimated cycles per tick: min, mean, max.
    pub cycles_min: u64,
    /// Mean estimated cycles per tick.
    pub cycles_mean: f64,
    /// Most estimated cycles of one tick.
    pub cycles_max: u64,
    /// Estimated cycles per tick on the STM32G474 at 170 MHz (flash wait states,
    /// ART prefetch and caches, FPU stall; [`crate::memory`]): fewest.
    pub cycles_min_g474: u64,
    /// Mean estimated cycles per tick on the STM32G474.
    pub cycles_mean_g474: f64,
    /// Most estimated cycles of one tick on the STM32G474 (the figure the budget
    /// limit applies to).
    pub cycles_max_g474: u64,
    /// The same with the pipeline refill at the top of its range
    /// ([`Measurement::pipeline_refill_high`]).
    pub cycles_max_g474_refill_high: u64,
    /// Of the worst STM32G474 tick: cycles waiting for instruction fetches from flash.
    pub stall_fetch: u64,
    /// Of the worst STM32G474 tick: cycles waiting for data reads from flash.
    pub stall_data: u64,
    /// Of the worst STM32G474 tick: FPU result-dependency stalls.
    pub stall_fpu: u64,
    /// Instructions per tick from SysTick under `-icount shift=0` (±8 with 10 ticks).
    pub icount_instructions: u64,
    /// Deepest stack use of a tick in bytes, measured in QEMU by stack painting
    /// (64 means "64 or less").
    pub stack_bytes: u64,
    /// Per function (self cost), most cycles first.
    pub functions: Vec<FunctionCost>,
    /// Per instruction of the worst STM32G474 tick, in address order (`--per-instruction`).
    #[serde(skip)]
    pub instructions: Vec<InstructionCost>,
}

/// One instruction's share of a tick: how often it ran and what it cost.
#[derive(Clone, Debug)]
pub struct InstructionCost {
    /// Address (Thumb bit clear).
    pub addr: u32,
    /// The disassembled instruction.
    pub text: String,
    /// The function it belongs to.
    pub function: String,
    /// Executions and estimated cycles (zero wait, G474) in the tick.
    pub cost: trace::Cost,
}

/// Everything measured, before budgets are applied.
#[derive(Clone, Debug, Serialize)]
pub struct Measurement {
    /// `opt-level` override used for the builds (None: the checked-in profile).
    pub opt_level: Option<String>,
    /// Pipeline refill `P` used by the cycle model.
    pub pipeline_refill: u32,
    /// Top of the refill range the STM32G474 figure is also given for.
    pub pipeline_refill_high: u32,
    /// The STM32G474 memory model's flash settings: wait states.
    pub flash_wait_states: u32,
    /// Bytes per flash read (8: dual bank, 16: single bank).
    pub flash_read_bytes: u32,
    /// Sizes per binary.
    pub binaries: Vec<BinarySize>,
    /// Cycle estimates per workload.
    pub workloads: Vec<WorkloadCost>,
    /// True when an indirect branch forced the trace to cover the whole `.text`.
    pub traced_whole_text: bool,
}

/// What to measure.
#[derive(Clone, Debug)]
pub struct Options {
    /// Binaries to size.
    pub binaries: Vec<FirmwareBin>,
    /// `opt-level` override.
    pub opt_level: Option<String>,
    /// Cycle model.
    pub model: CycleModel,
    /// Memory model of the STM32G474 for the QEMU image's placement.
    pub chip: ChipModel,
    /// Biggest symbols to list per binary.
    pub top_symbols: usize,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            binaries: vec![
                FirmwareBin::Board,
                FirmwareBin::BoardMoteus,
                FirmwareBin::Qemu,
                FirmwareBin::QemuBench,
            ],
            opt_level: None,
            model: CycleModel::default(),
            chip: ChipModel::g474_for_qemu_image(),
            top_symbols: 10,
        }
    }
}

/// Builds the binaries, sizes them, and estimates each workload's cycles.
pub fn measure(opts: &Options) -> Result<Measurement> {
    let level = opts.opt_level.as_deref();
    let mut binaries = Vec::new();
    for &bin in &opts.binaries {
        let elf = target::build_with(bin, level)?;
        let size = elf::size_report(&elf, opts.top_symbols)?;
        binaries.push(BinarySize {
            name: bin.name().to_string(),
            elf,
            size,
        });
    }
    let bench_elf = target::build_with(FirmwareBin::QemuBench, level)?;
    let (workloads, traced_whole_text) = estimate_workloads(&bench_elf, &opts.model, &opts.chip)?;
    Ok(Measurement {
        opt_level: opts.opt_level.clone(),
        pipeline_refill: opts.model.pipeline_refill,
        pipeline_refill_high: refill_high(&opts.model),
        flash_wait_states: opts.chip.flash.wait_states,
        flash_read_bytes: opts.chip.flash.read_bytes,
        binaries,
        workloads,
        traced_whole_text,
    })
}

/// Top of the pipeline refill range (TRM: `P` is 1 to 3).
fn refill_high(model: &CycleModel) -> u32 {
    model.pipeline_refill.max(3)
}

/// Runs the bench binary (icount run, then traced run) and costs every workload,
/// at zero wait states and on the STM32G474 (`chip`).
pub fn estimate_workloads(
    elf: &Path,
    model: &CycleModel,
    chip: &ChipModel,
) -> Result<(Vec<WorkloadCost>, bool)> {
    let bench = trace::parse_bench(&qemu::run(elf)?)?;
    let code = disasm::disassemble(elf)?;
    let fns = elf::functions(elf)?;
    let entries: Vec<u32> = bench.workloads.iter().map(|w| w.tick_addr).collect();
    let (reach, indirect) = trace::reachable(&code, &fns, &entries)?;
    let ranges = if indirect {
        // An indirect branch could go anywhere: trace all code.
        let lo = fns.first().map_or(0, |f| f.start);
        let hi = fns.iter().map(|f| f.end).max().unwrap_or(lo);
        vec![(lo, hi)]
    } else {
        trace::trace_ranges(&reach)
    };
    let (traced, out) = trace::run_trace(elf, &ranges)?;
    let traced_bench = trace::parse_bench(&out)?;
    if traced_bench
        .workloads
        .iter()
        .map(|w| w.tick_addr)
        .ne(entries.iter().copied())
    {
        bail!("the traced run reported other tick addresses than the icount run");
    }
    let ticks = trace::split_ticks(&traced, &code, &fns, &entries, model, chip)?;
    let high = CycleModel {
        pipeline_refill: refill_high(model),
    };
    let ticks_high = trace::split_ticks(&traced, &code, &fns, &entries, &high, chip)?;
    let mut out = Vec::new();
    for w in &bench.workloads {
        let mine: Vec<&trace::TickTrace> =
            ticks.iter().filter(|t| t.entry == w.tick_addr).collect();
        if mine.len() != bench.ticks as usize {
            bail!(
                "workload `{}`: traced {} ticks, the bench binary ran {}",
                w.name,
                mine.len(),
                bench.ticks
            );
        }
        let n = mine.len() as f64;
        let mut per_fn: BTreeMap<&str, (u64, u64, u64)> = BTreeMap::new();
        for t in &mine {
            for (name, c) in &t.per_function {
                let e = per_fn.entry(name).or_default();
                e.0 += c.instructions;
                e.1 += c.cycles;
                e.2 += c.chip_cycles;
            }
        }
        let mut functions: Vec<FunctionCost> = per_fn
            .into_iter()
            .map(|(name, (i, c, g))| FunctionCost {
                name: name.to_string(),
                instructions: i as f64 / n,
                cycles: c as f64 / n,
                cycles_g474: g as f64 / n,
            })
            .collect();
        functions.sort_by(|a, b| b.cycles_g474.total_cmp(&a.cycles_g474));
        let chip = |t: &&trace::TickTrace| t.total.chip_cycles;
        let worst = mine
            .iter()
            .max_by_key(|t| chip(t))
            .expect("ticks were traced");
        let high_max = ticks_high
            .iter()
            .filter(|t| t.entry == w.tick_addr)
            .map(|t| t.total.chip_cycles)
            .max()
            .unwrap_or(0);
        out.push(WorkloadCost {
            name: w.name.clone(),
            function: elf::function_at(&fns, w.tick_addr)
                .map_or_else(String::new, |f| f.name.clone()),
            ticks: mine.len(),
            macs: w.macs,
            instructions_mean: mine.iter().map(|t| t.total.instructions).sum::<u64>() as f64 / n,
            cycles_min: mine.iter().map(|t| t.total.cycles).min().unwrap_or(0),
            cycles_mean: mine.iter().map(|t| t.total.cycles).sum::<u64>() as f64 / n,
            cycles_max: mine.iter().map(|t| t.total.cycles).max().unwrap_or(0),
            cycles_min_g474: mine.iter().map(chip).min().unwrap_or(0),
            cycles_mean_g474: mine.iter().map(chip).sum::<u64>() as f64 / n,
            cycles_max_g474: worst.total.chip_cycles,
            cycles_max_g474_refill_high: high_max,
            stall_fetch: worst.stalls.fetch,
            stall_data: worst.stalls.data,
            stall_fpu: worst.stalls.fpu,
            icount_instructions: w.icount_instructions_per_tick(bench.ticks),
            stack_bytes: w.stack_bytes,
            functions,
            instructions: worst
                .per_address
                .iter()
                .map(|(&addr, &cost)| InstructionCost {
                    addr,
                    text: code
                        .at(addr)
                        .map_or_else(String::new, |i| format!("{} {}", i.mnemonic, i.operands)),
                    function: elf::function_at(&fns, addr)
                        .map_or_else(String::new, |f| f.name.clone()),
                    cost,
                })
                .collect(),
        });
    }
    Ok((out, indirect))
}

/// A budget exceeded.
#[derive(Clone, Debug, Serialize, PartialEq, Eq)]
pub struct Violation {
    /// What overran: `binary board: flash`, `workload dot64 (<...>::tick): cycles`.
    pub what: String,
    /// The measured figure.
    pub measured: u64,
    /// The limit.
    pub limit: u64,
}

impl std::fmt::Display for Violation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let over = self.measured.saturating_sub(self.limit);
        write!(
            f,
            "{}: {} > limit {} (overrun {} = {:.1} %)",
            self.what,
            self.measured,
            self.limit,
            over,
            100.0 * over as f64 / self.limit.max(1) as f64
        )
    }
}

/// The measurement with its budgets.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// The budgets applied.
    pub budgets: Budgets,
    /// What was measured.
    pub measurement: Measurement,
    /// Every budget exceeded (empty: all within budget).
    pub violations: Vec<Violation>,
}

/// Compares a measurement with the budgets. A binary or workload missing from the
/// budget file is a violation for binaries (no silent pass) and gets one whole tick
/// at the control rate for workloads.
pub fn check(m: &Measurement, b: &Budgets) -> Vec<Violation> {
    let mut v = Vec::new();
    for bin in &m.binaries {
        let Some(lim) = b.binary.get(&bin.name) else {
            v.push(Violation {
                what: format!("binary {}: no budget in the budget file", bin.name),
                measured: bin.size.flash_bytes,
                limit: 0,
            });
            continue;
        };
        let ram = bin.size.static_ram_bytes + lim.stack_reserve_bytes;
        if bin.size.flash_bytes > lim.flash_bytes {
            v.push(Violation {
                what: format!("binary {}: flash bytes", bin.name),
                measured: bin.size.flash_bytes,
                limit: lim.flash_bytes,
            });
        }
        if ram > lim.ram_bytes {
            v.push(Violation {
                what: format!("binary {}: RAM bytes (static + stack reserve)", bin.name),
                measured: ram,
                limit: lim.ram_bytes,
            });
        }
    }
    let reserve = b
        .binary
        .values()
        .map(|l| l.stack_reserve_bytes)
        .min()
        .unwrap_or(0);
    for w in &m.workloads {
        if w.stack_bytes > reserve {
            v.push(Violation {
                what: format!(
                    "workload {} ({}): stack bytes of a tick vs the smallest stack reserve",
                    w.name, w.function
                ),
                measured: w.stack_bytes,
                limit: reserve,
            });
        }
        let limit = b.cycle_limit(&w.name);
        if w.cycles_max_g474 > limit {
            v.push(Violation {
                what: format!(
                    "workload {} ({}): estimated STM32G474 cycles per tick",
                    w.name, w.function
                ),
                measured: w.cycles_max_g474,
                limit,
            });
        }
    }
    v
}

/// Applies the budgets.
pub fn report(m: Measurement, b: Budgets) -> Report {
    let violations = check(&m, &b);
    Report {
        budgets: b,
        measurement: m,
        violations,
    }
}

fn kib(bytes: u64) -> String {
    if bytes < 1024 {
        format!("{bytes} B")
    } else {
        format!("{bytes} B ({:.1} KiB)", bytes as f64 / 1024.0)
    }
}

impl Report {
    /// The whole table as Markdown.
    pub fn markdown(&self) -> String {
        let m = &self.measurement;
        let b = &self.budgets;
        let mut s = String::new();
        let profile = m
            .opt_level
            .as_deref()
            .map_or("checked-in release profile".to_string(), |l| {
                format!("release profile with opt-level = {l}")
            });
        let _ = writeln!(s, "## Size ({}, {profile})\n", b.mcu.name);
        let _ = writeln!(
            s,
            "| binary | flash | flash limit | flash % | static RAM | stack reserve | RAM | RAM limit | RAM % |"
        );
        let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|---:|---:|---:|");
        for bin in &m.binaries {
            let lim = b.binary.get(&bin.name);
            let (fl, rl, st) = lim.map_or((0, 0, 0), |l| {
                (l.flash_bytes, l.ram_bytes, l.stack_reserve_bytes)
            });
            let ram = bin.size.static_ram_bytes + st;
            let pct = |a: u64, l: u64| {
                if l == 0 {
                    "no budget".to_string()
                } else {
                    format!("{:.1} %", 100.0 * a as f64 / l as f64)
                }
            };
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                bin.name,
                kib(bin.size.flash_bytes),
                kib(fl),
                pct(bin.size.flash_bytes, fl),
                kib(bin.size.static_ram_bytes),
                kib(st),
                kib(ram),
                kib(rl),
                pct(ram, rl)
            );
        }
        for bin in &m.binaries {
            let _ = writeln!(s, "\n### {}: sections and biggest symbols\n", bin.name);
            let _ = writeln!(s, "| section | address | bytes | flash | RAM |");
            let _ = writeln!(s, "|---|---:|---:|---:|---:|");
            for sec in &bin.size.sections {
                let _ = writeln!(
                    s,
                    "| `{}` | {:#010x} | {} | {} | {} |",
                    sec.name, sec.addr, sec.size, sec.flash_bytes, sec.ram_bytes
                );
            }
            let _ = writeln!(s, "\n| symbol | section | bytes |");
            let _ = writeln!(s, "|---|---|---:|");
            for sym in &bin.size.biggest_symbols {
                let _ = writeln!(s, "| `{}` | `{}` | {} |", sym.name, sym.section, sym.size);
            }
        }
        let _ = writeln!(
            s,
            "\n## Cycles per control tick (estimated, not measured: QEMU trace x Cortex-M4 TRM \
             tables 3-1/7-1, P = {p}; zero wait states, and on the {mcu} at {mhz} MHz: flash with \
             {ws} wait states, {bits}-bit reads, ART prefetch, 1 KiB instruction and 256 B data \
             cache, SRAM/CCM SRAM zero-wait, FPU result stall)\n",
            p = m.pipeline_refill,
            mcu = b.mcu.name,
            mhz = b.mcu.clock_hz / 1_000_000,
            ws = m.flash_wait_states,
            bits = 8 * m.flash_read_bytes,
        );
        let rates: Vec<String> = b
            .mcu
            .control_rates_hz
            .iter()
            .map(|r| format!("% of tick @ {}", rate_name(*r)))
            .collect();
        let _ = writeln!(
            s,
            "| workload | ticks | instr/tick (trace) | instr/tick (icount) | zero-wait mean | zero-wait max | G474 min | G474 mean | G474 max | G474 max, P = {} | fetch / data / FPU stall | G474 cycles/MAC | {} | limit (G474 max) | status | stack |",
            m.pipeline_refill_high,
            rates.join(" | ")
        );
        let _ = writeln!(
            s,
            "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|{}---:|---|---:|",
            "---:|".repeat(rates.len())
        );
        let shares_of = |cycles: f64| -> Vec<String> {
            b.mcu
                .control_rates_hz
                .iter()
                .map(|&r| format!("{:.3} %", 100.0 * cycles * r as f64 / b.mcu.clock_hz as f64))
                .collect()
        };
        for w in &m.workloads {
            let limit = b.cycle_limit(&w.name);
            let per_mac = if w.macs == 0 {
                "-".to_string()
            } else {
                format!("{:.2}", w.cycles_mean_g474 / f64::from(w.macs))
            };
            let status = if w.cycles_max_g474 > limit {
                format!("OVER by {}", w.cycles_max_g474 - limit)
            } else {
                "ok".to_string()
            };
            let stack = if w.stack_bytes <= 64 {
                "≤ 64 B".to_string()
            } else {
                format!("{} B", w.stack_bytes)
            };
            let _ = writeln!(
                s,
                "| {} | {} | {:.0} | {} | {:.0} | {} | {} | {:.0} | {} | {} | {} / {} / {} | {} | {} | {} | {} | {} |",
                w.name,
                w.ticks,
                w.instructions_mean,
                w.icount_instructions,
                w.cycles_mean,
                w.cycles_max,
                w.cycles_min_g474,
                w.cycles_mean_g474,
                w.cycles_max_g474,
                w.cycles_max_g474_refill_high,
                w.stall_fetch,
                w.stall_data,
                w.stall_fpu,
                per_mac,
                shares_of(w.cycles_max_g474 as f64).join(" | "),
                limit,
                status,
                stack
            );
        }
        // The board binary runs every registered workload in one tick.
        let sum = |f: fn(&WorkloadCost) -> f64| m.workloads.iter().map(f).sum::<f64>();
        let _ = writeln!(
            s,
            "| all workloads (one board tick) | | {:.0} | {:.0} | {:.0} | {:.0} | {:.0} | {:.0} | {:.0} | {:.0} | {:.0} / {:.0} / {:.0} | - | {} | - | - | - |",
            sum(|w| w.instructions_mean),
            sum(|w| w.icount_instructions as f64),
            sum(|w| w.cycles_mean),
            sum(|w| w.cycles_max as f64),
            sum(|w| w.cycles_min_g474 as f64),
            sum(|w| w.cycles_mean_g474),
            sum(|w| w.cycles_max_g474 as f64),
            sum(|w| w.cycles_max_g474_refill_high as f64),
            sum(|w| w.stall_fetch as f64),
            sum(|w| w.stall_data as f64),
            sum(|w| w.stall_fpu as f64),
            shares_of(sum(|w| w.cycles_max_g474 as f64)).join(" | ")
        );
        let _ = writeln!(
            s,
            "\nThe limits apply to the G474 max (worst traced tick, each tick from empty caches). \
             Shares use it at {} MHz. Stalls: cycles of the worst G474 tick spent waiting for \
             instruction fetches and data reads from flash, and FPU result stalls. icount: \
             SysTick under `-icount shift=0` (40 instructions per count; the measuring loop \
             subtracted). stack: deepest stack use of a tick in QEMU (painted stack), checked \
             against the stack reserve. Placement: the QEMU image's code and constants \
             (0x0000_0000) are the board's flash (0x0800_0000), its RAM (0x2000_0000) the \
             board's SRAM.",
            b.mcu.clock_hz / 1_000_000
        );
        if m.traced_whole_text {
            let _ = writeln!(
                s,
                "\nAn indirect branch was reachable: the whole `.text` was traced."
            );
        }
        for w in &m.workloads {
            let _ = writeln!(s, "\n### {}: per function (self, mean per tick)\n", w.name);
            let _ = writeln!(
                s,
                "| function | instructions | est. cycles, zero wait | est. cycles, G474 |"
            );
            let _ = writeln!(s, "|---|---:|---:|---:|");
            for f in &w.functions {
                let _ = writeln!(
                    s,
                    "| `{}` | {:.1} | {:.1} | {:.1} |",
                    f.name, f.instructions, f.cycles, f.cycles_g474
                );
            }
        }
        let _ = writeln!(s, "\n## Budget check\n");
        if self.violations.is_empty() {
            let _ = writeln!(s, "All within budget.");
        }
        for v in &self.violations {
            let _ = writeln!(s, "- OVER BUDGET {v}");
        }
        s
    }

    /// The whole report as JSON.
    pub fn json(&self) -> Result<String> {
        Ok(serde_json::to_string_pretty(self)?)
    }
}

fn rate_name(hz: u64) -> String {
    if hz >= 1000 && hz.is_multiple_of(1000) {
        format!("{} kHz", hz / 1000)
    } else {
        format!("{hz} Hz")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::elf::SizeReport;

    fn budgets() -> Budgets {
        Budgets::load(&default_budget_file()).unwrap()
    }

    fn measurement(flash: u64, ram: u64, cycles: u64) -> Measurement {
        Measurement {
            opt_level: None,
            pipeline_refill: 1,
            pipeline_refill_high: 3,
            flash_wait_states: 4,
            flash_read_bytes: 8,
            binaries: vec![BinarySize {
                name: "board".into(),
                elf: PathBuf::from("board"),
                size: SizeReport {
                    sections: vec![],
                    flash_bytes: flash,
                    static_ram_bytes: ram,
                    biggest_symbols: vec![],
                },
            }],
            workloads: vec![WorkloadCost {
                name: "dot64".into(),
                function: "<test_kit::bench::Dot64 as test_kit::bench::Workload>::tick".into(),
                ticks: 1,
                macs: 64,
                instructions_mean: 1.0,
                cycles_min: cycles,
                cycles_mean: cycles as f64,
                cycles_max: cycles / 2,
                cycles_min_g474: cycles,
                cycles_mean_g474: cycles as f64,
                cycles_max_g474: cycles,
                cycles_max_g474_refill_high: cycles + 1,
                stall_fetch: cycles / 4,
                stall_data: 0,
                stall_fpu: 0,
                icount_instructions: 1,
                stack_bytes: 64,
                functions: vec![],
                instructions: vec![],
            }],
            traced_whole_text: false,
        }
    }

    #[test]
    fn budget_file_has_the_stm32g474_defaults() {
        let b = budgets();
        assert_eq!(b.mcu.clock_hz, 170_000_000);
        // 508 KiB: the last 4 KiB page (single bank) holds the per-board configuration
        // block.
        assert_eq!(b.binary["board"].flash_bytes, 508 * 1024);
        assert_eq!(b.binary["board"].ram_bytes, 96 * 1024);
        assert_eq!(
            b.cycle_limit("no-such-workload"),
            170_000_000 / b.mcu.control_rate_hz
        );
    }

    #[test]
    fn within_budget_passes_and_each_overrun_is_named() {
        let b = budgets();
        let board = b.binary["board"];
        let dot = b.cycle_limit("dot64");
        assert!(check(&measurement(1000, 1000, dot), &b).is_empty());
        let v = check(
            &measurement(board.flash_bytes + 1, board.ram_bytes, dot + 7),
            &b,
        );
        assert_eq!(v.len(), 3, "{v:?}");
        assert!(
            v[0].to_string().starts_with("binary board: flash bytes"),
            "{}",
            v[0]
        );
        assert!(v[1].what.contains("RAM"));
        assert_eq!(v[1].measured, board.ram_bytes + board.stack_reserve_bytes);
        let s = v[2].to_string();
        assert!(
            s.contains("dot64") && s.contains("Dot64") && s.contains("overrun 7"),
            "{s}"
        );
    }

    #[test]
    fn markdown_tables_are_rectangular() {
        let r = report(measurement(1000, 100, 400), budgets());
        let text = r.markdown();
        let mut header_cells = None;
        for line in text.lines() {
            if !line.starts_with('|') {
                header_cells = None;
                continue;
            }
            let cells = line.matches('|').count();
            match header_cells {
                None => header_cells = Some(cells),
                Some(n) => assert_eq!(cells, n, "row {line:?}"),
            }
        }
        assert!(text.contains("| dot64 | 1 |"), "{text}");
        assert!(r.json().unwrap().contains("\"violations\": []"));
    }

    #[test]
    fn a_binary_without_budget_is_a_violation() {
        let mut m = measurement(1, 1, 1);
        m.binaries[0].name = "unknown-bin".into();
        let v = check(&m, &budgets());
        assert_eq!(v.len(), 1);
        assert!(v[0].what.contains("unknown-bin"));
    }
}
