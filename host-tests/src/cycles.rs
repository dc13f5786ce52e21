//! Cortex-M4 cycle weights for executed instructions.
//!
//! Every figure comes from the Cortex-M4 Technical Reference Manual, r0p1
//! (ARM DDI 0439B): Table 3-1 "Cortex-M4 instruction set summary" for the integer
//! and DSP instructions, and Table 7-1 "FPU instruction set" for the FPU. `P` is
//! the pipeline refill after a taken branch or a write to the PC, `N` the number of
//! registers (32-bit words) a multiple load/store transfers.
//!
//! What the weighting resolves: conditional branches (B<c>, CBZ/CBNZ, and any
//! conditional instruction that writes the PC) cost `1` when not taken and `1+P`
//! when taken; taken or not is read from the trace (the next executed address).
//!
//! These are zero-wait figures: memory as fast as the tables assume. The STM32G474
//! runs its flash at 170 MHz with 4 wait states (RM0440 §3.3.3) behind the ART
//! accelerator; [`crate::memory`] replays the same instructions on that memory
//! system (and adds the FPU result-dependency stall) for the chip's figure.
//!
//! What the tables' weighting ignores (so the figures are estimates, not measured
//! cycles):
//! - memory: flash wait states, prefetch and caches (modelled in [`crate::memory`]);
//! - the range of `P` (1 to 3 cycles, depending on the target's alignment and
//!   width and on branch speculation): `P` is the fixed [`CycleModel::pipeline_refill`]
//!   (default 1, the table's best case; the budget also gives the chip figure at 3);
//! - load/store pipelining: the TRM lets neighbouring independent LDRs (and an STR
//!   after an LDR) overlap, taking 1 cycle instead of 2, and an STR with an
//!   immediate offset complete in 1; here every LDR/STR/VLDR/VSTR costs the table's
//!   2 (an upper bound);
//! - data-dependent ranges: SDIV/UDIV (2 to 12) count 12; MRS/MSR/CPSID/CPSIE
//!   (1 or 2) count 2; barriers (1+B) count 1;
//! - IT folding: an IT instruction counts 1 cycle (the core can fold it into the
//!   preceding 16-bit instruction); an instruction inside an IT block whose condition
//!   fails counts as if it executed (the trace shows the address, not the flags);
//! - FPU overlap: VDIV/VSQRT (14) count in full although the integer pipeline
//!   continues while they run (the VADD/VMUL result stall is in [`crate::memory`]);
//! - interrupts, exceptions and bus contention (none occur inside the measured ticks).
use anyhow::{Result, bail};

/// One disassembled instruction (from `llvm-objdump -d`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Instr {
    /// Address (Thumb bit clear).
    pub addr: u32,
    /// Encoded size in bytes (2 or 4).
    pub size: u32,
    /// Mnemonic as printed, with width and data-type suffixes (`ldr.w`, `vmla.f32`).
    pub mnemonic: String,
    /// Operands as printed, without the trailing `@` comment.
    pub operands: String,
}

impl Instr {
    /// Address of the next instruction in memory.
    pub fn next_addr(&self) -> u32 {
        self.addr + self.size
    }

    /// Direct branch target (`b`, `bl`, `cbz`, ... print it as `0x1234 <sym>`).
    pub fn direct_target(&self) -> Option<u32> {
        let word = self
            .operands
            .split_whitespace()
            .find(|w| w.starts_with("0x"))?;
        u32::from_str_radix(word.trim_start_matches("0x").trim_end_matches(','), 16).ok()
    }
}

/// How an instruction's cycle count is formed (TRM Table 3-1 / 7-1 columns).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Timing {
    /// A fixed number of cycles.
    Fixed(u32),
    /// A branch: `1+P` taken, `1` not taken (unconditional branches are always taken).
    Branch,
    /// Table branch TBB/TBH: `2+P`.
    TableBranch,
    /// Multiple load/store of core registers: `1+N`, `1+N+P` when the list holds the PC.
    Multiple,
    /// Multiple load/store of FPU registers (VLDM/VSTM/VPUSH/VPOP): `1+N`, N in words.
    FpMultiple,
    /// A single load (LDR family): `2`, `2+P` when it loads the PC.
    Load,
    /// A data-processing instruction: `1`, `1+P` when it writes the PC.
    Alu,
}

/// What kind of control flow an instruction is (for splitting the trace into calls).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Flow {
    /// Falls through (or branches within the call level).
    Plain,
    /// A call (BL, BLX): the callee returns to the next instruction.
    Call,
    /// A return (BX LR, POP/LDM/LDR with the PC from the stack).
    Return,
}

/// The classified instruction: its timing rule and control-flow kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Class {
    /// Cycle rule.
    pub timing: Timing,
    /// Whether the instruction writes the PC (then `P` applies when it executes).
    pub writes_pc: bool,
    /// Whether it carries a condition (then "not taken" costs 1).
    pub conditional: bool,
    /// Call / return / plain.
    pub flow: Flow,
    /// Registers (32-bit words) moved, for [`Timing::Multiple`] and [`Timing::FpMultiple`].
    pub words: u32,
}

/// The cycle model: TRM tables plus the one free parameter, `P`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CycleModel {
    /// Cycles of a pipeline refill `P` (the TRM gives 1 to 3).
    pub pipeline_refill: u32,
}

impl Default for CycleModel {
    fn default() -> Self {
        CycleModel { pipeline_refill: 1 }
    }
}

const CONDITIONS: [&str; 16] = [
    "eq", "ne", "cs", "hs", "cc", "lo", "mi", "pl", "vs", "vc", "hi", "ls", "ge", "lt", "gt", "le",
];

/// Base mnemonic -> timing (Table 3-1 and Table 7-1 rows).
fn base_timing(base: &str) -> Option<Timing> {
    use Timing::*;
    Some(match base {
        // Table 3-1: branches. B, BL, BX, BLX: 1+P; B<c>, CBZ, CBNZ: 1 or 1+P.
        "b" | "bl" | "bx" | "blx" | "cbz" | "cbnz" => Branch,
        // Table 3-1: TBB, TBH: 2+P.
        "tbb" | "tbh" => TableBranch,
        // Table 3-1: load/store multiple, push, pop: 1+N (+P with the PC).
        "ldm" | "ldmia" | "ldmfd" | "ldmdb" | "ldmea" | "stm" | "stmia" | "stmea" | "stmdb"
        | "stmfd" | "push" | "pop" => Multiple,
        // Table 3-1: loads (word, halfword, byte, signed, unprivileged, exclusive): 2.
        "ldr" | "ldrh" | "ldrb" | "ldrsh" | "ldrsb" | "ldrt" | "ldrht" | "ldrbt" | "ldrsht"
        | "ldrsbt" | "ldrex" | "ldrexb" | "ldrexh" => Load,
        // Table 3-1: load/store doubleword: 1+N with N = 2.
        "ldrd" | "strd" => Fixed(3),
        // Table 3-1: stores (word, halfword, byte, unprivileged, exclusive): 2.
        "str" | "strh" | "strb" | "strt" | "strht" | "strbt" | "strex" | "strexb" | "strexh" => {
            Fixed(2)
        }
        // Table 3-1: preload: treated as a load slot without a result.
        "pld" | "pli" => Fixed(2),
        // Table 3-1: divide 2..12 (early termination): worst case.
        "sdiv" | "udiv" => Fixed(12),
        // Table 3-1: multiply, multiply-accumulate, long, 16x16, 32x16, dual 16x16
        // (SMLAD/SMUAD/SMLALD...), most significant word: all 1 cycle on the M4.
        "mul" | "mla" | "mls" | "smull" | "umull" | "smlal" | "umlal" | "umaal" | "smulbb"
        | "smulbt" | "smultb" | "smultt" | "smulwb" | "smulwt" | "smlabb" | "smlabt" | "smlatb"
        | "smlatt" | "smlawb" | "smlawt" | "smlalbb" | "smlalbt" | "smlaltb" | "smlaltt"
        | "smuad" | "smuadx" | "smusd" | "smusdx" | "smlad" | "smladx" | "smlsd" | "smlsdx"
        | "smlald" | "smlaldx" | "smlsld" | "smlsldx" | "smmul" | "smmulr" | "smmla" | "smmlar"
        | "smmls" | "smmlsr" => Fixed(1),
        // Table 3-1: status register access and interrupt masks: 1 or 2 (worst case).
        "mrs" | "msr" | "cpsid" | "cpsie" => Fixed(2),
        // Table 3-1: barriers 1+B (B not modelled), hints 1, breakpoint/SVC/UDF
        // (they end the program or trap; never inside a measured tick).
        "dmb" | "dsb" | "isb" | "nop" | "yield" | "wfi" | "wfe" | "sev" | "bkpt" | "svc"
        | "udf" | "trap" | "clrex" => Fixed(1),
        // Table 3-1: moves, arithmetic, logic, shifts, compares, saturation, bit
        // field, extend, reverse, count leading zeros, parallel add/subtract,
        // packing, SEL, USAD8, saturating arithmetic: 1 (1+P when writing the PC).
        "mov" | "movw" | "movt" | "mvn" | "add" | "addw" | "adc" | "adr" | "sub" | "subw"
        | "sbc" | "rsb" | "and" | "orr" | "orn" | "eor" | "bic" | "lsl" | "lsr" | "asr" | "ror"
        | "rrx" | "cmp" | "cmn" | "tst" | "teq" | "ssat" | "usat" | "ssat16" | "usat16" | "bfi"
        | "bfc" | "ubfx" | "sbfx" | "sxtb" | "sxth" | "uxtb" | "uxth" | "sxtb16" | "uxtb16"
        | "sxtab" | "sxtah" | "uxtab" | "uxtah" | "sxtab16" | "uxtab16" | "rev" | "rev16"
        | "revsh" | "rbit" | "clz" | "sel" | "pkhbt" | "pkhtb" | "usad8" | "usada8" | "qadd"
        | "qsub" | "qdadd" | "qdsub" | "sadd16" | "sadd8" | "ssub16" | "ssub8" | "sasx"
        | "ssax" | "uadd16" | "uadd8" | "usub16" | "usub8" | "uasx" | "usax" | "qadd16"
        | "qadd8" | "qsub16" | "qsub8" | "qasx" | "qsax" | "uqadd16" | "uqadd8" | "uqsub16"
        | "uqsub8" | "uqasx" | "uqsax" | "shadd16" | "shadd8" | "shsub16" | "shsub8" | "shasx"
        | "shsax" | "uhadd16" | "uhadd8" | "uhsub16" | "uhsub8" | "uhasx" | "uhsax" | "neg" => Alu,
        // Table 7-1: VADD, VSUB, VMUL, VNMUL, VABS, VNEG, VCMP(E), VCVT (all forms),
        // VMOV (immediate, register, core<->single), VMRS, VMSR: 1.
        "vadd" | "vsub" | "vmul" | "vnmul" | "vabs" | "vneg" | "vcmp" | "vcmpe" | "vcvt"
        | "vcvtr" | "vcvtb" | "vcvtt" | "vmrs" | "vmsr" => Fixed(1),
        // Table 7-1: VMOV: 1; with two core registers (two singles or a double): 2
        // (decided from the operands in `classify`).
        "vmov" => Fixed(1),
        // Table 7-1: VMLA, VMLS, VNMLA, VNMLS, VFMA, VFMS, VFNMA, VFNMS: 3.
        "vmla" | "vmls" | "vnmla" | "vnmls" | "vfma" | "vfms" | "vfnma" | "vfnms" => Fixed(3),
        // Table 7-1: VDIV, VSQRT: 14.
        "vdiv" | "vsqrt" => Fixed(14),
        // Table 7-1: VLDR, VSTR: 2.
        "vldr" | "vstr" => Fixed(2),
        // Table 7-1: VLDM, VSTM, VPUSH, VPOP: 1+N.
        "vldm" | "vldmia" | "vldmdb" | "vstm" | "vstmia" | "vstmdb" | "vpush" | "vpop" => {
            FpMultiple
        }
        _ => return None,
    })
}

/// Strips width/type suffixes and resolves conditions and the flag-setting `s`:
/// returns (base mnemonic, conditional).
fn normalise(mnemonic: &str) -> Option<(String, bool)> {
    let m = mnemonic.to_ascii_lowercase();
    let head = m.split('.').next().unwrap_or_default();
    // IT, ITT, ITE, ITTE, ... (If-Then): 1 cycle (folding ignored).
    if head.len() >= 2
        && head.len() <= 5
        && head.starts_with("it")
        && head[2..].chars().all(|c| c == 't' || c == 'e')
    {
        return Some(("it".to_string(), false));
    }
    let strip_cond = |s: &str| -> Option<String> {
        let n = s.len();
        (n > 2 && CONDITIONS.contains(&&s[n - 2..])).then(|| s[..n - 2].to_string())
    };
    // The flag-setting `s` exists only on data-processing and multiply instructions.
    let strip_s = |s: &str| -> Option<String> {
        s.strip_suffix('s')
            .filter(|b| matches!(base_timing(b), Some(Timing::Alu | Timing::Fixed(1))))
            .filter(|b| !b.starts_with('v'))
            .map(str::to_string)
    };
    if head == "it" || base_timing(head).is_some() {
        return Some((head.to_string(), false));
    }
    if let Some(b) = strip_s(head).filter(|b| base_timing(b).is_some()) {
        return Some((b, false));
    }
    if let Some(c) = strip_cond(head) {
        if base_timing(&c).is_some() {
            return Some((c, true));
        }
        if let Some(b) = strip_s(&c).filter(|b| base_timing(b).is_some()) {
            return Some((b, true));
        }
    }
    None
}

/// Registers in a `{r4, r5, lr}` list, counted in 32-bit words (`d` registers count 2),
/// and whether the list holds the PC.
fn register_list(operands: &str) -> Option<(u32, bool)> {
    let open = operands.find('{')?;
    let close = operands[open..].find('}')? + open;
    let mut words = 0;
    let mut pc = false;
    for item in operands[open + 1..close]
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
    {
        let (lo, hi) = item.split_once('-').unwrap_or((item, item));
        let num = |r: &str| r.trim()[1..].parse::<u32>().ok();
        let width = if lo.starts_with('d') { 2 } else { 1 };
        let count = match (num(lo), num(hi)) {
            (Some(a), Some(b)) if (lo.starts_with(['d', 's', 'r'])) && b >= a => b - a + 1,
            _ => 1,
        };
        pc |= item == "pc";
        words += width * count;
    }
    Some((words, pc))
}

/// First operand (the destination of most instructions).
fn first_operand(operands: &str) -> &str {
    operands.split(',').next().unwrap_or_default().trim()
}

/// Classifies an instruction; unknown mnemonics are an error naming them, so a new
/// instruction in the firmware shows up as a missing table row, never as a guess.
pub fn classify(instr: &Instr) -> Result<Class> {
    let Some((base, conditional)) = normalise(&instr.mnemonic) else {
        bail!(
            "no Cortex-M4 cycle-table entry for `{} {}` at {:#x}: add it to host-tests/src/cycles.rs",
            instr.mnemonic,
            instr.operands,
            instr.addr
        );
    };
    let ops = instr.operands.as_str();
    if base == "it" {
        return Ok(Class {
            timing: Timing::Fixed(1),
            writes_pc: false,
            conditional: false,
            flow: Flow::Plain,
            words: 0,
        });
    }
    let timing = base_timing(&base).expect("normalise returns only known bases");
    let dest_pc = first_operand(ops) == "pc";
    let (mut words, list_pc) = register_list(ops).unwrap_or((0, false));
    let (writes_pc, flow, timing) = match timing {
        Timing::Branch => {
            let flow = match base.as_str() {
                "bl" | "blx" => Flow::Call,
                "bx" if ops.trim() == "lr" => Flow::Return,
                _ => Flow::Plain,
            };
            (true, flow, timing)
        }
        Timing::TableBranch => (true, Flow::Plain, timing),
        Timing::Multiple => {
            let from_stack = base == "pop" || ops.trim_start().starts_with("sp!");
            let is_load = base == "pop" || base.starts_with("ldm");
            let pc = list_pc && is_load;
            (
                pc,
                if pc && from_stack {
                    Flow::Return
                } else {
                    Flow::Plain
                },
                timing,
            )
        }
        Timing::Load => {
            let from_stack = ops.contains("[sp]") || ops.contains("[sp,");
            (
                dest_pc,
                if dest_pc && from_stack {
                    Flow::Return
                } else {
                    Flow::Plain
                },
                timing,
            )
        }
        Timing::Alu => (dest_pc, Flow::Plain, timing),
        Timing::Fixed(1) if base == "vmov" => {
            // Two core registers with two singles or one double: 2 cycles.
            let cores = ops
                .split(',')
                .map(str::trim)
                .filter(|o| {
                    matches!(*o, "lr" | "ip" | "sp")
                        || (o.starts_with('r') && o[1..].parse::<u8>().is_ok())
                })
                .count();
            (
                false,
                Flow::Plain,
                Timing::Fixed(if cores >= 2 { 2 } else { 1 }),
            )
        }
        Timing::FpMultiple => (false, Flow::Plain, timing),
        Timing::Fixed(_) => (false, Flow::Plain, timing),
    };
    if !matches!(timing, Timing::Multiple | Timing::FpMultiple) {
        words = 0;
    }
    Ok(Class {
        timing,
        writes_pc,
        conditional,
        flow,
        words,
    })
}

impl CycleModel {
    /// Cycles of one execution of `class`; `taken` says whether a PC-writing
    /// instruction actually changed the flow (the next executed address is not the
    /// next one in memory).
    pub fn cycles(&self, class: &Class, taken: bool) -> u32 {
        let p = self.pipeline_refill;
        // A PC-writing instruction that did not change the flow: a branch not taken
        // (1 cycle, Table 3-1 "1 or 1+P"), or a conditional one whose condition failed.
        if class.writes_pc && !taken && (class.conditional || class.timing == Timing::Branch) {
            return 1;
        }
        let refill = if class.writes_pc { p } else { 0 };
        match class.timing {
            Timing::Fixed(c) => c,
            Timing::Branch => 1 + refill,
            Timing::TableBranch => 2 + refill,
            Timing::Multiple | Timing::FpMultiple => 1 + class.words + refill,
            Timing::Load => 2 + refill,
            Timing::Alu => 1 + refill,
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// An instruction at `addr` of `size` bytes (test sequences).
    pub(crate) fn ins(addr: u32, size: u32, m: &str, ops: &str) -> Instr {
        Instr {
            addr,
            size,
            mnemonic: m.into(),
            operands: ops.into(),
        }
    }

    fn cyc(m: &str, ops: &str, taken: bool) -> u32 {
        let c = classify(&ins(0, 4, m, ops)).unwrap();
        CycleModel::default().cycles(&c, taken)
    }

    #[test]
    fn table_3_1_rows() {
        assert_eq!(cyc("smlad", "r0, r1, r2, r0", false), 1);
        assert_eq!(cyc("mla", "r0, r1, r2, r0", false), 1);
        assert_eq!(cyc("muls", "r0, r1, r0", false), 1);
        assert_eq!(cyc("smlal", "r0, r1, r2, r3", false), 1);
        assert_eq!(cyc("ldr.w", "r0, [r1, #4]", false), 2);
        assert_eq!(cyc("ldrsh", "r0, [r1, r2]", false), 2);
        assert_eq!(cyc("str", "r0, [r1]", false), 2);
        assert_eq!(cyc("ldrd", "r0, r1, [r2]", false), 3);
        assert_eq!(cyc("udiv", "r0, r1, r2", false), 12);
        assert_eq!(cyc("push", "{r4, r5, r6, r7, lr}", false), 6);
        assert_eq!(cyc("pop.w", "{r4, r5, r6, r7, r8, pc}", true), 1 + 6 + 1);
        assert_eq!(cyc("pop", "{r4, r5}", false), 3);
        assert_eq!(cyc("bl", "0x1000 <f>", true), 2);
        assert_eq!(cyc("b.w", "0x1000 <f>", true), 2);
        assert_eq!(cyc("bne", "0x1000 <f>", true), 2);
        assert_eq!(cyc("bne", "0x1000 <f>", false), 1);
        assert_eq!(cyc("cbz", "r0, 0x1000 <f>", false), 1);
        assert_eq!(cyc("tbb", "[pc, r0]", true), 3);
        assert_eq!(cyc("bx", "lr", true), 2);
        assert_eq!(cyc("movs", "r0, #0", false), 1);
        assert_eq!(cyc("moveq", "r0, #1", false), 1);
        assert_eq!(cyc("addseq.w", "r0, r0, #1", false), 1);
        assert_eq!(cyc("mov", "pc, r0", true), 2);
        assert_eq!(cyc("ittte", "ne", false), 1);
        assert_eq!(cyc("ldr", "pc, [sp], #4", true), 3);
    }

    #[test]
    fn table_7_1_rows() {
        assert_eq!(cyc("vmla.f32", "s0, s1, s2", false), 3);
        assert_eq!(cyc("vfma.f32", "s0, s1, s2", false), 3);
        assert_eq!(cyc("vmul.f32", "s0, s1, s2", false), 1);
        assert_eq!(cyc("vadd.f32", "s0, s1, s2", false), 1);
        assert_eq!(cyc("vdiv.f32", "s0, s1, s2", false), 14);
        assert_eq!(cyc("vsqrt.f32", "s0, s1", false), 14);
        assert_eq!(cyc("vldr", "s0, [r0, #4]", false), 2);
        assert_eq!(cyc("vstr", "s0, [r0]", false), 2);
        assert_eq!(cyc("vmov", "r0, s0", false), 1);
        assert_eq!(cyc("vmov", "r0, r1, d0", false), 2);
        assert_eq!(cyc("vmov", "s0, s1, r2, r3", false), 2);
        assert_eq!(cyc("vmov.f32", "s0, #1.000000e+00", false), 1);
        assert_eq!(cyc("vpush", "{d8, d9}", false), 5);
        assert_eq!(cyc("vpop", "{s16, s17, s18}", false), 4);
        assert_eq!(cyc("vldmia", "r0!, {s0-s7}", false), 9);
        assert_eq!(cyc("vcvt.s32.f32", "s0, s0", false), 1);
        assert_eq!(cyc("vmrs", "APSR_nzcv, fpscr", false), 1);
    }

    #[test]
    fn flow_kinds() {
        let f = |m: &str, o: &str| classify(&ins(0, 2, m, o)).unwrap().flow;
        assert_eq!(f("bl", "0x10 <x>"), Flow::Call);
        assert_eq!(f("blx", "r4"), Flow::Call);
        assert_eq!(f("bx", "lr"), Flow::Return);
        assert_eq!(f("pop", "{r7, pc}"), Flow::Return);
        assert_eq!(f("ldm.w", "sp!, {r4, r5, pc}"), Flow::Return);
        assert_eq!(f("ldr", "pc, [sp], #4"), Flow::Return);
        assert_eq!(f("b.w", "0x10 <x>"), Flow::Plain);
        assert_eq!(f("pop", "{r4, r5}"), Flow::Plain);
        assert_eq!(f("vmls.f32", "s0, s1, s2"), Flow::Plain);
        assert_eq!(f("bls", "0x10 <x>"), Flow::Plain);
        assert!(classify(&ins(0, 2, "bls", "0x10 <x>")).unwrap().conditional);
        assert!(
            !classify(&ins(0, 2, "vmls.f32", "s0, s1, s2"))
                .unwrap()
                .conditional
        );
    }

    #[test]
    fn unknown_mnemonic_is_an_error_naming_it() {
        let e = classify(&ins(0x40, 4, "vfoo.f32", "s0, s1"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("vfoo.f32") && e.contains("0x40"), "{e}");
    }

    #[test]
    fn refill_parameter_applies_to_taken_branches_only() {
        let m = CycleModel { pipeline_refill: 3 };
        let b = classify(&ins(0, 2, "bne", "0x10 <x>")).unwrap();
        assert_eq!(m.cycles(&b, true), 4);
        assert_eq!(m.cycles(&b, false), 1);
        let add = classify(&ins(0, 2, "adds", "r0, #1")).unwrap();
        assert_eq!(m.cycles(&add, false), 1);
    }
}
