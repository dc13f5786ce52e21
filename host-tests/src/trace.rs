//! Cycle estimate without hardware: the QEMU bench binary's instruction trace,
//! joined with the disassembly and weighted by the Cortex-M4 cycle tables
//! ([`crate::cycles`]) and by the STM32G474's memory system ([`crate::memory`]).
//!
//! Two runs of the bench binary (`firmware/qemu/src/bench.rs`):
//! 1. under `-icount shift=0` (one instruction = 1 ns of virtual time): it prints each
//!    workload's tick address and the SysTick ticks around its `TICKS` calls. SysTick
//!    runs on the 25 MHz core clock of mps2-an386, so it advances once per 40
//!    instructions: `instructions = 40 x SysTick ticks` (each reading exact to one count).
//! 2. with the TCG plugin `host-tests/qemu-plugin/memtrace.c` (no `-icount`, which
//!    re-executes some instructions): the executed addresses of the tick functions and
//!    every function they reach, and every data access of those instructions
//!    (address, size, load or store), in execution order.
//!
//! The trace is split into calls of each tick function by following calls and
//! returns (tail calls stay at the same level), and each instruction is weighted by
//! [`CycleModel`] (branches costed taken or not from the next executed address) and
//! replayed on [`ChipModel`] for the chip's figure.
use crate::cycles::{CycleModel, Flow, Timing, classify};
use crate::disasm::Code;
use crate::elf::{Function, function_at};
use crate::memory::{Access, ChipModel, ChipState, Stalls};
use crate::qemu;
use anyhow::{Context, Result, bail};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;

/// Instructions per SysTick count under `-icount shift=0` on mps2-an386 (25 MHz core
/// clock: 40 ns per count, one instruction per ns).
pub const INSTRUCTIONS_PER_SYSTICK: u64 = 40;

/// What the bench binary printed for one workload.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BenchLine {
    /// Workload name (`test_kit::bench::Workload::NAME`).
    pub name: String,
    /// Address of its tick function (Thumb bit clear).
    pub tick_addr: u32,
    /// Multiply-accumulates per tick.
    pub macs: u32,
    /// SysTick counts over the ticks.
    pub systick: u64,
    /// SysTick counts of the same loop calling an empty function.
    pub baseline_systick: u64,
    /// Deepest stack use of the ticks in bytes, below the caller's stack pointer
    /// (painted stack; 64 means "64 or less").
    pub stack_bytes: u64,
}

/// The bench binary's report.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BenchReport {
    /// Ticks run per workload.
    pub ticks: u32,
    /// One line per workload, in registration order.
    pub workloads: Vec<BenchLine>,
}

impl BenchLine {
    /// Instructions of one tick under `-icount shift=0` (the measuring loop's own
    /// cost subtracted), rounded to the nearest instruction.
    pub fn icount_instructions_per_tick(&self, ticks: u32) -> u64 {
        let net = self.systick.saturating_sub(self.baseline_systick) * INSTRUCTIONS_PER_SYSTICK;
        (net + u64::from(ticks) / 2) / u64::from(ticks.max(1))
    }
}

/// Parses `@bench TICKS`, `@workload NAME ADDR MACS SYSTICK BASELINE OUT STACK`, `@pass`.
pub fn parse_bench(text: &str) -> Result<BenchReport> {
    let mut ticks = None;
    let mut workloads = Vec::new();
    let mut passed = false;
    for (n, line) in text.lines().enumerate() {
        let w: Vec<&str> = line.split_whitespace().collect();
        let bad = || format!("bench report line {}: cannot read {line:?}", n + 1);
        match w.first().copied() {
            Some("@bench") => {
                ticks = Some(w.get(1).and_then(|t| t.parse().ok()).with_context(bad)?)
            }
            Some("@workload") if w.len() == 8 => {
                let hex = |s: &str| u32::from_str_radix(s.trim_start_matches("0x"), 16);
                workloads.push(BenchLine {
                    name: w[1].to_string(),
                    tick_addr: hex(w[2]).with_context(bad)? & !1,
                    macs: w[3].parse().with_context(bad)?,
                    systick: w[4].parse().with_context(bad)?,
                    baseline_systick: w[5].parse().with_context(bad)?,
                    stack_bytes: w[7].parse().with_context(bad)?,
                });
            }
            Some("@pass") => passed = true,
            Some(s) if s.starts_with('@') => bail!("{}", bad()),
            _ => {}
        }
    }
    let Some(ticks) = ticks else {
        bail!("the bench report has no `@bench` line: {text:?}")
    };
    if !passed {
        bail!("the bench binary did not reach `@pass`: {text:?}");
    }
    Ok(BenchReport { ticks, workloads })
}

/// Cost of one function inside a tick (its own instructions, callees excluded).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Cost {
    /// Instructions executed.
    pub instructions: u64,
    /// Estimated cycles at zero wait states (the TRM tables alone).
    pub cycles: u64,
    /// Estimated cycles on the chip ([`ChipModel`]: wait states, caches, FPU stall).
    pub chip_cycles: u64,
}

/// One traced call of a tick function.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct TickTrace {
    /// Entry address of the tick function.
    pub entry: u32,
    /// Whole tick: instructions and estimated cycles, callees included.
    pub total: Cost,
    /// Where the chip model's extra cycles came from.
    pub stalls: Stalls,
    /// Per function (self cost), by demangled name.
    pub per_function: BTreeMap<String, Cost>,
    /// Per executed address (all executions of it in this call).
    pub per_address: BTreeMap<u32, Cost>,
}

/// The executed instructions in order, each with its data accesses.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Trace {
    /// Executed addresses (Thumb bit clear).
    pub pcs: Vec<u32>,
    /// `accesses[starts[i]..starts[i + 1]]` are the accesses of `pcs[i]`
    /// (`starts.len() == pcs.len() + 1`).
    starts: Vec<usize>,
    /// Data accesses of all instructions, in order.
    accesses: Vec<Access>,
}

impl Trace {
    /// A trace without data accesses.
    pub fn from_pcs(pcs: Vec<u32>) -> Trace {
        let starts = vec![0; pcs.len() + 1];
        Trace {
            pcs,
            starts,
            accesses: Vec::new(),
        }
    }

    /// The data accesses of the `i`-th executed instruction.
    pub fn accesses_of(&self, i: usize) -> &[Access] {
        &self.accesses[self.starts[i]..self.starts[i + 1]]
    }

    /// Number of data accesses in the trace.
    pub fn access_count(&self) -> usize {
        self.accesses.len()
    }

    /// Reads the trace plugin's records (`qemu-plugin/memtrace.c`): pairs of
    /// little-endian words, `(0, pc)` per instruction, `(1 | shift << 8, addr)` per
    /// load and `(2 | shift << 8, addr)` per store of `1 << shift` bytes.
    pub fn from_records(bytes: &[u8]) -> Result<Trace> {
        if !bytes.len().is_multiple_of(8) {
            bail!(
                "trace record file of {} bytes is not whole 8-byte records",
                bytes.len()
            );
        }
        let mut t = Trace::default();
        for (n, rec) in bytes.chunks_exact(8).enumerate() {
            let kind = u32::from_le_bytes([rec[0], rec[1], rec[2], rec[3]]);
            let addr = u32::from_le_bytes([rec[4], rec[5], rec[6], rec[7]]);
            match kind & 0xff {
                0 => {
                    t.starts.push(t.accesses.len());
                    t.pcs.push(addr & !1);
                }
                k @ (1 | 2) if !t.pcs.is_empty() && (kind >> 8) <= 3 => {
                    t.accesses.push(Access {
                        addr,
                        bytes: 1 << (kind >> 8),
                        store: k == 2,
                    });
                }
                _ => bail!("trace record {n}: cannot read kind {kind:#x} at {addr:#x}"),
            }
        }
        t.starts.push(t.accesses.len());
        Ok(t)
    }
}

/// Splits an executed-address trace into calls of the `entries` and costs each
/// with the zero-wait tables (`model`) and on the chip (`chip`, from an idle chip
/// with empty caches at each call).
///
/// A call starts when the trace reaches an entry address outside any call and ends
/// at the return that matches it (calls and returns are counted; a tail call stays
/// at the same level). Addresses outside any call are ignored.
pub fn split_ticks(
    trace: &Trace,
    code: &Code,
    fns: &[Function],
    entries: &[u32],
    model: &CycleModel,
    chip: &ChipModel,
) -> Result<Vec<TickTrace>> {
    let pcs = &trace.pcs;
    let mut ticks = Vec::new();
    let mut current: Option<(TickTrace, u32, ChipState)> = None;
    for (i, &pc) in pcs.iter().enumerate() {
        if current.is_none() {
            if !entries.contains(&pc) {
                continue;
            }
            current = Some((
                TickTrace {
                    entry: pc,
                    ..TickTrace::default()
                },
                0,
                ChipState::new(chip),
            ));
        } else if entries.contains(&pc) && current.as_ref().is_some_and(|(t, _, _)| t.entry == pc) {
            bail!(
                "the trace re-entered the tick at {pc:#x} before it returned: a callee is \
                 missing from the trace (an indirect call?) or the tick recurses"
            );
        }
        let Some(instr) = code.at(pc) else {
            bail!("traced address {pc:#x} is not an instruction in the disassembly");
        };
        let class = classify(instr)?;
        let taken = pcs.get(i + 1).is_none_or(|&next| next != instr.next_addr());
        let table = model.cycles(&class, taken);
        let cycles = u64::from(table);
        let (tick, depth, state) = current.as_mut().expect("inside a tick");
        let chip_cycles = state.step(chip, instr, table, trace.accesses_of(i));
        tick.total.instructions += 1;
        tick.total.cycles += cycles;
        tick.total.chip_cycles += chip_cycles;
        tick.stalls = state.stalls;
        let name = function_at(fns, pc).map_or("?", |f| f.name.as_str());
        let c = tick.per_function.entry(name.to_string()).or_default();
        c.instructions += 1;
        c.cycles += cycles;
        c.chip_cycles += chip_cycles;
        let a = tick.per_address.entry(pc).or_default();
        a.instructions += 1;
        a.cycles += cycles;
        a.chip_cycles += chip_cycles;
        match class.flow {
            Flow::Call if taken => *depth += 1,
            Flow::Return if taken => {
                if *depth == 0 {
                    ticks.push(current.take().expect("inside a tick").0);
                } else {
                    *depth -= 1;
                }
            }
            _ => {}
        }
    }
    if let Some((t, _, _)) = current {
        bail!(
            "the trace ended inside the tick at {:#x} (the run was cut short?)",
            t.entry
        );
    }
    Ok(ticks)
}

/// Whether an instruction transfers control to an address the disassembly cannot
/// tell (register branch or call, PC loaded from memory other than the stack).
fn is_indirect(code_instr: &crate::cycles::Instr) -> Result<bool> {
    let class = classify(code_instr)?;
    if !class.writes_pc || class.flow == Flow::Return {
        return Ok(false);
    }
    Ok(match class.timing {
        Timing::Branch => code_instr.direct_target().is_none(),
        Timing::TableBranch => false,
        _ => true,
    })
}

/// The functions reachable from `entries` through direct calls and branches, and
/// whether any of them transfers control indirectly.
pub fn reachable(code: &Code, fns: &[Function], entries: &[u32]) -> Result<(Vec<Function>, bool)> {
    let mut seen = BTreeSet::new();
    let mut todo: Vec<u32> = entries.to_vec();
    let mut indirect = false;
    let mut out = Vec::new();
    while let Some(addr) = todo.pop() {
        let Some(f) = function_at(fns, addr) else {
            bail!("no function symbol holds address {addr:#x}");
        };
        if !seen.insert(f.start) {
            continue;
        }
        for instr in code.range(f.start, f.end) {
            indirect |= is_indirect(instr)?;
            if let Some(t) = instr
                .direct_target()
                .filter(|_| classify(instr).is_ok_and(|c| c.timing == Timing::Branch))
                && !(f.start..f.end).contains(&t)
            {
                todo.push(t);
            }
        }
        out.push(f.clone());
    }
    out.sort_by_key(|f| f.start);
    Ok((out, indirect))
}

/// Address ranges `[start, end)` covering `fns`, merged where adjacent.
pub fn trace_ranges(fns: &[Function]) -> Vec<(u32, u32)> {
    let mut ranges: Vec<(u32, u32)> = Vec::new();
    for f in fns {
        match ranges.last_mut() {
            Some(last) if last.1 >= f.start => last.1 = last.1.max(f.end),
            _ => ranges.push((f.start, f.end)),
        }
    }
    ranges
}

/// The traced ranges as text (`0x2000+0xa,0x2010+0x2`: start + length).
pub fn dfilter(fns: &[Function]) -> String {
    trace_ranges(fns)
        .iter()
        .map(|(s, e)| format!("{s:#x}+{:#x}", e - s))
        .collect::<Vec<_>>()
        .join(",")
}

/// Source of the QEMU trace plugin.
const PLUGIN_SOURCE: &str = include_str!("../qemu-plugin/memtrace.c");

/// Builds the QEMU trace plugin (`host-tests/qemu-plugin/memtrace.c`) with the
/// host C compiler (`$CC`, default `cc`) into `target/qemu-plugin/`, once per
/// version of its source, and returns the shared object's path.
pub fn plugin() -> Result<PathBuf> {
    let hash = PLUGIN_SOURCE
        .bytes()
        .fold(0xcbf2_9ce4_8422_2325_u64, |h, b| {
            (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
        });
    let dir = crate::target::workspace_root()
        .join("target")
        .join("qemu-plugin");
    let so = dir.join(format!("memtrace-{hash:016x}.so"));
    if so.exists() {
        return Ok(so);
    }
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let src = dir.join(format!("memtrace-{hash:016x}.c"));
    std::fs::write(&src, PLUGIN_SOURCE).with_context(|| format!("writing {}", src.display()))?;
    // Built beside its final name, then renamed: parallel runs never load half a file.
    let tmp = dir.join(format!("memtrace-{hash:016x}.{}.tmp", std::process::id()));
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".to_string());
    let out = Command::new(&cc)
        .args(["-O2", "-shared", "-fPIC", "-fvisibility=hidden", "-o"])
        .arg(&tmp)
        .arg(&src)
        .output()
        .with_context(|| {
            format!("starting the C compiler `{cc}` for the QEMU trace plugin (Debian: gcc)")
        })?;
    if !out.status.success() {
        bail!(
            "building the QEMU trace plugin with `{cc}` failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    std::fs::rename(&tmp, &so).with_context(|| format!("renaming to {}", so.display()))?;
    Ok(so)
}

/// Runs `elf` under QEMU with the trace plugin recording the instructions inside
/// `ranges` and their data accesses; returns the trace and the program's
/// semihosting output.
pub fn run_trace(elf: &Path, ranges: &[(u32, u32)]) -> Result<(Trace, String)> {
    qemu::require_qemu()?;
    let plugin = plugin()?;
    static RUNS: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
    let run = RUNS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("fw-trace-{}-{run}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let records = dir.join("trace.bin");
    let range_file = dir.join("ranges.txt");
    let text: String = ranges
        .iter()
        .map(|(s, e)| format!("{s:x} {e:x}\n"))
        .collect();
    std::fs::write(&range_file, text)?;
    let mut arg = std::ffi::OsString::from(plugin);
    arg.push(",out=");
    arg.push(&records);
    arg.push(",ranges=");
    arg.push(&range_file);
    // Without `-icount`, which makes QEMU re-execute (and report again) some
    // instructions.
    let out = Command::new(qemu::QEMU)
        .args([
            "-M",
            "mps2-an386",
            "-nographic",
            "-semihosting-config",
            "enable=on,target=native",
            "-no-reboot",
            "-plugin",
        ])
        .arg(arg)
        .arg("-kernel")
        .arg(elf)
        .output()
        .with_context(|| format!("starting {}", qemu::QEMU))?;
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    if !out.status.success() {
        let _ = std::fs::remove_dir_all(&dir);
        bail!(
            "traced run of {} failed ({}): {stdout} {}",
            elf.display(),
            out.status,
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let bytes =
        std::fs::read(&records).with_context(|| format!("reading {}", records.display()))?;
    let _ = std::fs::remove_dir_all(&dir);
    Ok((Trace::from_records(&bytes)?, stdout))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::disasm::parse_objdump;

    /// Memory as fast as the tables assume: the chip figure equals the table figure.
    fn flat() -> ChipModel {
        ChipModel {
            flash: crate::memory::FlashTiming::ZERO_WAIT,
            map: crate::memory::MemoryMap::qemu_image_on_g474(),
            fpu_result_stall: false,
        }
    }

    /// Walks a straight-line loop body `iterations` times: the addresses QEMU would
    /// log for `entry: prologue; loop: body; subs; bne loop; epilogue; bx lr`.
    fn walk_loop(code: &Code, entry: u32, iterations: u32) -> Vec<u32> {
        let mut pcs = Vec::new();
        let mut pc = entry;
        let mut left = iterations;
        loop {
            let i = code.at(pc).expect("address in snippet");
            pcs.push(pc);
            if i.mnemonic == "bx" {
                return pcs;
            }
            pc = match (i.mnemonic.as_str(), i.direct_target()) {
                ("bne" | "bne.w", Some(t)) => {
                    left -= 1;
                    if left > 0 { t } else { i.next_addr() }
                }
                _ => i.next_addr(),
            };
        }
    }

    /// A loop of `k` copies of `body` per iteration, in llvm-objdump format.
    fn loop_snippet(body: &str, body_size: u32, k: u32) -> (String, u32) {
        let mut s = String::from("00001000 <f>:\n    1000: 00 20        \tmovs\tr3, #16\n");
        let mut a = 0x1002;
        let head = a;
        for _ in 0..k {
            let bytes = if body_size == 4 {
                "00 00 00 00"
            } else {
                "00 00      "
            };
            s += &format!("    {a:x}: {bytes}  \t{body}\n");
            a += body_size;
        }
        s += &format!("    {a:x}: 01 3b        \tsubs\tr3, #1\n");
        a += 2;
        s += &format!("    {a:x}: fe d1        \tbne\t{head:#x} <f+0x2>\n");
        a += 2;
        s += &format!("    {a:x}: 70 47        \tbx\tlr\n");
        (s, a + 2)
    }

    fn estimate_loop(body: &str, size: u32, k: u32, n: u32) -> TickTrace {
        let (text, end) = loop_snippet(body, size, k);
        let code = parse_objdump(&text).unwrap();
        let fns = vec![Function {
            name: "f".into(),
            start: 0x1000,
            end,
        }];
        let trace = Trace::from_pcs(walk_loop(&code, 0x1000, n));
        let ticks = split_ticks(
            &trace,
            &code,
            &fns,
            &[0x1000],
            &CycleModel::default(),
            &flat(),
        )
        .unwrap();
        assert_eq!(ticks.len(), 1);
        ticks.into_iter().next().unwrap()
    }

    /// Loop of N iterations with k copies of an instruction costing `c`:
    /// movs (1) + N*(k*c + subs 1) + (N-1) taken bne (1+P) + 1 not-taken bne + bx lr (1+P).
    fn predicted(k: u32, c: u64, n: u64) -> u64 {
        let p = 1;
        1 + n * (u64::from(k) * c + 1) + (n - 1) * (1 + p) + 1 + (1 + p)
    }

    #[test]
    fn smlad_loop_costs_one_cycle_per_smlad() {
        let t = estimate_loop("smlad\tr0, r1, r2, r0", 4, 8, 16);
        assert_eq!(t.total.cycles, predicted(8, 1, 16));
        assert_eq!(t.total.instructions, 1 + 16 * 10 + 1);
    }

    #[test]
    fn vmla_loop_costs_three_cycles_per_vmla() {
        let t = estimate_loop("vmla.f32\ts0, s2, s4", 4, 4, 16);
        assert_eq!(t.total.cycles, predicted(4, 3, 16));
    }

    #[test]
    fn ldr_loop_costs_two_cycles_per_ldr() {
        let t = estimate_loop("ldr\tr0, [r1, #4]", 2, 6, 10);
        assert_eq!(t.total.cycles, predicted(6, 2, 10));
    }

    /// Assembles `k` copies of `body` in a loop of `n` iterations with llvm-mc (LLVM's
    /// own Cortex-M4 assembler), disassembles the object with llvm-objdump as the
    /// estimator does for the firmware, walks the loop and estimates it.
    fn assembled_loop(body: &str, k: u32, n: u32) -> TickTrace {
        let dir = std::env::temp_dir().join(format!(
            "fw-asm-{}-{}",
            std::process::id(),
            body.len() * 100 + k as usize
        ));
        std::fs::create_dir_all(&dir).unwrap();
        let src = dir.join("loop.s");
        let obj = dir.join("loop.o");
        let mut asm = String::from(
            ".syntax unified\n.thumb\n.text\n.globl f\n.type f,%function\n.thumb_func\nf:\n  movs r3, #16\n1:\n",
        );
        for _ in 0..k {
            asm += &format!("  {body}\n");
        }
        asm += "  subs r3, #1\n  bne 1b\n  bx lr\n.size f, .-f\n";
        std::fs::write(&src, asm).unwrap();
        let st = Command::new("llvm-mc")
            .args([
                "-triple=thumbv7em-none-eabihf",
                "-mcpu=cortex-m4",
                "-filetype=obj",
                "-o",
            ])
            .arg(&obj)
            .arg(&src)
            .status()
            .expect("llvm-mc (Debian package `llvm`; `bash .ci/run` installs it)");
        assert!(st.success());
        let code = crate::disasm::disassemble(&obj).unwrap();
        let _ = std::fs::remove_dir_all(&dir);
        let end = code.instrs.values().last().unwrap().next_addr();
        assert_eq!(code.instrs.len() as u32, k + 4, "{code:?}");
        let fns = vec![Function {
            name: "f".into(),
            start: 0,
            end,
        }];
        let trace = Trace::from_pcs(walk_loop(&code, 0, n));
        let ticks =
            split_ticks(&trace, &code, &fns, &[0], &CycleModel::default(), &flat()).unwrap();
        assert_eq!(ticks.len(), 1);
        ticks.into_iter().next().unwrap()
    }

    #[test]
    fn assembled_smlad_vmla_ldr_loops_cost_what_the_tables_say() {
        use test_support::{Need, available};
        let llvm = [
            Need::Program {
                name: "llvm-mc",
                ci: true,
            },
            Need::Program {
                name: "llvm-objdump",
                ci: true,
            },
        ];
        if !available("the assembled-loop cycle check", &llvm) {
            return;
        }
        let t = assembled_loop("smlad r0, r1, r2, r0", 8, 16);
        assert_eq!(t.total.cycles, predicted(8, 1, 16));
        let t = assembled_loop("vmla.f32 s0, s2, s4", 5, 12);
        assert_eq!(t.total.cycles, predicted(5, 3, 12));
        let t = assembled_loop("ldr r0, [r1, #4]", 6, 10);
        assert_eq!(t.total.cycles, predicted(6, 2, 10));
        let t = assembled_loop("vdiv.f32 s0, s2, s4", 2, 3);
        assert_eq!(t.total.cycles, predicted(2, 14, 3));
    }

    #[test]
    fn calls_and_tail_calls_are_followed_to_the_matching_return() {
        // tick: push; bl g; b.w h (tail call)   g: bx lr   h: pop {r7, pc}
        let text = "
00002000 <tick>:
    2000: 80 b5        \tpush\t{r7, lr}
    2002: 00 f0 00 f8  \tbl\t0x2010 <g>
    2006: 00 f0 00 b8  \tb.w\t0x2020 <h>
00002010 <g>:
    2010: 70 47        \tbx\tlr
00002020 <h>:
    2020: 80 bd        \tpop\t{r7, pc}
";
        let code = parse_objdump(text).unwrap();
        let f = |n: &str, s, e| Function {
            name: n.into(),
            start: s,
            end: e,
        };
        let fns = vec![
            f("tick", 0x2000, 0x200a),
            f("g", 0x2010, 0x2012),
            f("h", 0x2020, 0x2022),
        ];
        let (reach, indirect) = reachable(&code, &fns, &[0x2000]).unwrap();
        assert_eq!(reach.len(), 3);
        assert!(!indirect);
        assert_eq!(dfilter(&reach), "0x2000+0xa,0x2010+0x2,0x2020+0x2");
        // Two ticks, with an unrelated address between them (ignored).
        let one = [0x2000, 0x2002, 0x2010, 0x2006, 0x2020];
        let mut trace = one.to_vec();
        trace.push(0x2010);
        trace.extend(one);
        let trace = Trace::from_pcs(trace);
        let ticks = split_ticks(
            &trace,
            &code,
            &fns,
            &[0x2000],
            &CycleModel::default(),
            &flat(),
        )
        .unwrap();
        assert_eq!(ticks.len(), 2);
        // push 3 + bl 2 + bx lr 2 + b.w 2 + pop {r7,pc} 1+2+1 = 13
        assert_eq!(
            ticks[0].total,
            Cost {
                instructions: 5,
                cycles: 13,
                chip_cycles: 13
            }
        );
        assert_eq!(
            ticks[0].per_function["g"],
            Cost {
                instructions: 1,
                cycles: 2,
                chip_cycles: 2
            }
        );
        // A trace cut inside the tick is an error, not a short tick.
        let cut = Trace::from_pcs(one[..3].to_vec());
        assert!(
            split_ticks(
                &cut,
                &code,
                &fns,
                &[0x2000],
                &CycleModel::default(),
                &flat()
            )
            .is_err()
        );
    }

    #[test]
    fn reads_trace_records_and_bench_report() {
        let word = |w: u32| w.to_le_bytes();
        let mut rec = Vec::new();
        for (k, a) in [
            (0, 0x1905),
            (0x201, 0x2000_0010),
            (0x102, 0x2000_0020),
            (0, 0x1906),
        ] {
            rec.extend(word(k));
            rec.extend(word(a));
        }
        let t = Trace::from_records(&rec).unwrap();
        assert_eq!(t.pcs, vec![0x1904, 0x1906]);
        assert_eq!(
            t.accesses_of(0),
            &[
                Access {
                    addr: 0x2000_0010,
                    bytes: 4,
                    store: false
                },
                Access {
                    addr: 0x2000_0020,
                    bytes: 2,
                    store: true
                }
            ]
        );
        assert!(t.accesses_of(1).is_empty());
        assert!(Trace::from_records(&rec[..12]).is_err());
        assert!(Trace::from_records(&[7, 0, 0, 0, 0, 0, 0, 0]).is_err());
        let rep = "@bench 10\n@workload dot64 0x00001905 64 71 1 41d5380f 64\n@pass\n";
        let b = parse_bench(rep).unwrap();
        assert_eq!(b.ticks, 10);
        assert_eq!(b.workloads[0].tick_addr, 0x1904);
        assert_eq!(b.workloads[0].icount_instructions_per_tick(10), 280);
        assert_eq!(b.workloads[0].stack_bytes, 64);
        assert!(parse_bench("@bench 10\n").is_err());
    }
}
