//! The STM32G474's memory system on top of the Cortex-M4 cycle tables: flash wait
//! states behind the ART accelerator (prefetch, instruction and data caches), SRAM,
//! CCM SRAM, and the FPU result-dependency stall.
//!
//! [`crate::cycles::CycleModel`] gives each instruction's zero-wait cost. This
//! model replays the same instructions on a clock and adds the cycles the core
//! waits for the memory that holds its code and data ([`ChipState::step`]).
//!
//! Figures (RM0440 rev 8, §3.3.3-3.3.5 "Read access latency", "Instruction
//! prefetch", "Instruction cache memory", "Data cache memory"; Cortex-M4 TRM):
//! - flash at 170 MHz (range 1 boost) needs LATENCY = 4 wait states: one flash read
//!   takes 1 + 4 = 5 HCLK cycles and returns 128 bits in single-bank mode (DBANK = 0,
//!   how the board is provisioned) or 64 bits in dual-bank mode (DBANK = 1, the
//!   factory setting) ([`FlashTiming::read_bytes`]);
//! - prefetch (PRFTEN, instruction bus only): while the core uses one line the
//!   next sequential line is read;
//! - instruction cache (ICEN): 32 lines of 4 x 64 bits (1 KiB); a line read on a
//!   miss (not in the current line, the prefetched line or the cache) is copied
//!   into it, the least recently used one is replaced; lines that arrive through
//!   the prefetch are not copied;
//! - data cache (DCEN): 8 lines of 4 x 64 bits (256 B) for data (literal pools,
//!   constant tables, weights) read from flash over the data bus, least recently
//!   used replaced;
//! - SRAM1/2 and CCM SRAM run at the core clock (zero wait states, data and code;
//!   CCM SRAM is on the instruction bus at 0x1000_0000);
//! - FPU (Cortex-M4 TRM, chapter 7; GCC's cortex-m4-fpu model gives VADD/VMUL a
//!   latency of 2): a VADD/VSUB/VMUL/VNMUL whose result the next FPU
//!   data-processing instruction reads stalls that instruction one cycle.
//!
//! Modelling choices (so the figures stay estimates): a cache "line" of 4 x 64
//! bits is read as a set of four flash reads (4-way set associative, sets chosen by
//! the flash read's address, LRU within the set); the flash serves one read at a time
//! in request order (an in-flight prefetch delays a data read that follows it); a
//! load's data phase is one cycle after it issues and the k-th word of a multiple
//! load k cycles later; every measured tick starts with empty caches and an idle
//! flash (what a control tick finds after the rest of the firmware ran); bus
//! contention between SRAM code fetches and data (S-bus) is not modelled.
use crate::cycles::Instr;

/// Where an address lives on the STM32G474.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Region {
    /// Main flash (0x0800_0000), through the ART accelerator.
    Flash,
    /// SRAM1 + SRAM2 (0x2000_0000), zero wait states.
    Sram,
    /// CCM SRAM (0x1000_0000 on the instruction bus, 0x2001_8000 on the data bus),
    /// zero wait states.
    CcmSram,
    /// Peripherals and anything else: no memory stall modelled.
    Other,
}

/// Maps the addresses of the traced image to the STM32G474 region where the board
/// places the same bytes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MemoryMap {
    /// `[start, end)` ranges of the traced image and the board region they stand for.
    pub ranges: Vec<(u32, u32, Region)>,
}

impl MemoryMap {
    /// The QEMU mps2-an386 image (`firmware/qemu/memory.x`) as the board places it
    /// (`board/memory.x`): the image's FLASH region (0x0000_0000, 4 MiB: vector
    /// table, `.text`, `.rodata`) is the board's flash at 0x0800_0000, its CCMRAM
    /// region (0x203E_0000, 128 KiB: `.ccmram_text` and `.ccmram_data`) the board's
    /// CCM SRAM (code on the instruction bus at 0x1000_0000, data zero-wait on the
    /// data bus), the rest of its RAM (0x2000_0000: `.data`, `.bss`, stack) the
    /// board's SRAM at 0x2000_0000.
    pub fn qemu_image_on_g474() -> MemoryMap {
        MemoryMap {
            ranges: vec![
                (0x0000_0000, 0x0040_0000, Region::Flash),
                (0x203E_0000, 0x2040_0000, Region::CcmSram),
                (0x2000_0000, 0x203E_0000, Region::Sram),
            ],
        }
    }

    /// The board's own addresses (`board/memory.x`): flash, CCM SRAM on both buses,
    /// SRAM1/2.
    pub fn g474() -> MemoryMap {
        MemoryMap {
            ranges: vec![
                (0x0800_0000, 0x0808_0000, Region::Flash),
                (0x1000_0000, 0x1000_8000, Region::CcmSram),
                (0x2001_8000, 0x2002_0000, Region::CcmSram),
                (0x2000_0000, 0x2001_8000, Region::Sram),
            ],
        }
    }

    /// The region of `addr`.
    pub fn region(&self, addr: u32) -> Region {
        self.ranges
            .iter()
            .find(|(s, e, _)| (*s..*e).contains(&addr))
            .map_or(Region::Other, |r| r.2)
    }
}

/// Flash interface settings (`FLASH_ACR` and the DBANK option bit).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FlashTiming {
    /// Wait states (`FLASH_ACR.LATENCY`): a read takes `1 + wait_states` cycles.
    pub wait_states: u32,
    /// Bytes one flash read returns: 8 (dual bank) or 16 (single bank).
    pub read_bytes: u32,
    /// Instruction prefetch (`PRFTEN`).
    pub prefetch: bool,
    /// Instruction cache size in bytes (`ICEN`; 0 = off).
    pub icache_bytes: u32,
    /// Data cache size in bytes (`DCEN`; 0 = off).
    pub dcache_bytes: u32,
}

impl FlashTiming {
    /// The board (`board/src/clock.rs`, `board/memory.x`): 170 MHz, LATENCY = 4,
    /// PRFTEN, ICEN, DCEN, single bank (DBANK = 0: 128-bit reads).
    pub const G474_170_MHZ: FlashTiming = FlashTiming {
        read_bytes: 16,
        ..Self::G474_170_MHZ_DUAL_BANK
    };

    /// The same in the factory dual-bank mode (DBANK = 1: 64-bit reads).
    pub const G474_170_MHZ_DUAL_BANK: FlashTiming = FlashTiming {
        wait_states: 4,
        read_bytes: 8,
        prefetch: true,
        icache_bytes: 1024,
        dcache_bytes: 256,
    };

    /// Zero wait states, nothing else: flash as fast as the tables assume.
    pub const ZERO_WAIT: FlashTiming = FlashTiming {
        wait_states: 0,
        read_bytes: 8,
        prefetch: false,
        icache_bytes: 0,
        dcache_bytes: 0,
    };
}

/// The memory system the instructions run on.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ChipModel {
    /// Flash settings.
    pub flash: FlashTiming,
    /// Address -> region.
    pub map: MemoryMap,
    /// Whether the FPU result-dependency stall is counted.
    pub fpu_result_stall: bool,
}

impl ChipModel {
    /// The board at 170 MHz running the QEMU image's placement.
    pub fn g474_for_qemu_image() -> ChipModel {
        ChipModel {
            flash: FlashTiming::G474_170_MHZ,
            map: MemoryMap::qemu_image_on_g474(),
            fpu_result_stall: true,
        }
    }
}

/// One data access of an instruction (from the trace).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Access {
    /// Address.
    pub addr: u32,
    /// Bytes (1, 2, 4 or 8).
    pub bytes: u8,
    /// Store (true) or load.
    pub store: bool,
}

/// A cache of flash reads: `ways`-way set associative, the least recently used way
/// of a set replaced.
#[derive(Clone, Debug, Default)]
struct Lru {
    /// Per set, the line numbers held, most recently used last.
    sets: Vec<Vec<u32>>,
    ways: usize,
}

impl Lru {
    /// A cache of `entries` flash reads in sets of `ways` (no cache when 0).
    fn new(entries: usize, ways: usize) -> Lru {
        let ways = ways.clamp(1, entries.max(1));
        Lru {
            sets: vec![Vec::with_capacity(ways); entries / ways],
            ways,
        }
    }

    fn set(&mut self, line: u32) -> Option<&mut Vec<u32>> {
        let n = self.sets.len();
        (n > 0).then(|| &mut self.sets[line as usize % n])
    }

    /// Whether `line` is held; a hit makes it the most recently used of its set.
    fn hit(&mut self, line: u32) -> bool {
        let Some(set) = self.set(line) else {
            return false;
        };
        match set.iter().position(|&l| l == line) {
            Some(i) => {
                let l = set.remove(i);
                set.push(l);
                true
            }
            None => false,
        }
    }

    fn contains(&self, line: u32) -> bool {
        let n = self.sets.len();
        n > 0 && self.sets[line as usize % n].contains(&line)
    }

    fn insert(&mut self, line: u32) {
        let ways = self.ways;
        if self.hit(line) {
            return;
        }
        let Some(set) = self.set(line) else {
            return;
        };
        if set.len() == ways {
            set.remove(0);
        }
        set.push(line);
    }
}

/// What a replay costs beyond the zero-wait tables, by cause.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stalls {
    /// Cycles waiting for instruction fetches from flash.
    pub fetch: u64,
    /// Cycles waiting for data reads from flash.
    pub data: u64,
    /// FPU result-dependency stalls.
    pub fpu: u64,
}

/// The state of the memory system while a trace is replayed.
#[derive(Clone, Debug)]
pub struct ChipState {
    /// Core clock: the cycle the next instruction issues.
    now: u64,
    /// Cycle the flash finishes its current read.
    flash_free: u64,
    /// The flash line the core is executing from.
    current_line: Option<u32>,
    /// The prefetched line and the cycle it arrives.
    prefetched: Option<(u32, u64)>,
    icache: Lru,
    dcache: Lru,
    /// Destination register of the previous instruction when it was a VADD, VSUB,
    /// VMUL or VNMUL.
    fp_result: Option<String>,
    /// Stalls so far.
    pub stalls: Stalls,
}

/// Ways per set of both caches: RM0440 describes them as lines of "4 x 64 bits"
/// (32 such lines = 1 KiB of instructions, 8 = 256 B of data), read here as four
/// flash reads per set.
const CACHE_WAYS: usize = 4;

/// FPU data-processing instructions (they read their source registers at issue).
const FP_DATA: [&str; 19] = [
    "vadd", "vsub", "vmul", "vnmul", "vmla", "vmls", "vnmla", "vnmls", "vfma", "vfms", "vfnma",
    "vfnms", "vabs", "vneg", "vcmp", "vcmpe", "vcvt", "vdiv", "vsqrt",
];

impl ChipState {
    /// An idle chip with empty caches.
    pub fn new(model: &ChipModel) -> ChipState {
        let lines = |bytes: u32| (bytes / model.flash.read_bytes.max(1)) as usize;
        ChipState {
            now: 0,
            flash_free: 0,
            current_line: None,
            prefetched: None,
            icache: Lru::new(lines(model.flash.icache_bytes), CACHE_WAYS),
            dcache: Lru::new(lines(model.flash.dcache_bytes), CACHE_WAYS),
            fp_result: None,
            stalls: Stalls::default(),
        }
    }

    /// Starts a flash read at or after `at`; returns the cycle the data is there
    /// (`wait_states` after the read starts: the zero-wait tables already count
    /// the read's first cycle). The flash is busy for `1 + wait_states` cycles; at
    /// zero wait states a read is what the tables count and never delays another.
    fn flash_read(&mut self, model: &ChipModel, at: u64) -> u64 {
        let ws = u64::from(model.flash.wait_states);
        let start = at.max(self.flash_free);
        self.flash_free = if ws == 0 { start } else { start + 1 + ws };
        start + ws
    }

    /// Issues the prefetch of the line after `line` when the prefetcher is on and
    /// that line is neither cached nor already prefetched.
    fn prefetch_after(&mut self, model: &ChipModel, line: u32) {
        let next = line.wrapping_add(1);
        if !model.flash.prefetch
            || self.icache.contains(next)
            || self.prefetched.is_some_and(|(l, _)| l == next)
        {
            return;
        }
        let ready = self.flash_read(model, self.now);
        self.prefetched = Some((next, ready));
    }

    /// Cycles the fetch of flash line `line` makes the core wait.
    fn fetch_line(&mut self, model: &ChipModel, line: u32) -> u64 {
        if self.current_line == Some(line) {
            return 0;
        }
        let wait = if self.icache.hit(line) {
            0
        } else if let Some((l, ready)) = self.prefetched.filter(|(l, _)| *l == line) {
            self.prefetched = None;
            let _ = l;
            ready.saturating_sub(self.now)
        } else {
            let ready = self.flash_read(model, self.now);
            self.icache.insert(line);
            ready - self.now
        };
        self.now += wait;
        self.current_line = Some(line);
        self.prefetch_after(model, line);
        wait
    }

    /// Replays one executed instruction that costs `table_cycles` at zero wait
    /// states, with its data accesses, and returns its cycles on the chip.
    pub fn step(
        &mut self,
        model: &ChipModel,
        instr: &Instr,
        table_cycles: u32,
        accesses: &[Access],
    ) -> u64 {
        let issue = self.now;
        // Instruction fetch: every flash line the encoding touches.
        if model.map.region(instr.addr) == Region::Flash {
            let rb = model.flash.read_bytes.max(1);
            let first = instr.addr / rb;
            let last = (instr.addr + instr.size.max(1) - 1) / rb;
            for line in first..=last {
                let w = self.fetch_line(model, line);
                self.stalls.fetch += w;
            }
        } else {
            // Code outside flash: the flash line buffer no longer feeds the core.
            self.current_line = None;
        }
        // FPU result dependency on the previous instruction.
        let (base, dest, sources) = fp_operands(instr);
        if model.fpu_result_stall
            && let Some(prev) = &self.fp_result
            && FP_DATA.contains(&base.as_str())
            && sources.iter().any(|s| s == prev)
        {
            self.now += 1;
            self.stalls.fpu += 1;
        }
        self.fp_result = matches!(base.as_str(), "vadd" | "vsub" | "vmul" | "vnmul")
            .then_some(dest)
            .flatten();
        // Data reads from flash, through the data cache.
        let rb = model.flash.read_bytes.max(1);
        for (k, a) in accesses.iter().enumerate() {
            if a.store || model.map.region(a.addr) != Region::Flash {
                continue;
            }
            let last = a.addr.saturating_add(u32::from(a.bytes.max(1)) - 1) / rb;
            for line in a.addr / rb..=last {
                if self.dcache.hit(line) {
                    continue;
                }
                let at = self.now + 1 + k as u64;
                let ready = self.flash_read(model, at);
                self.dcache.insert(line);
                let wait = ready - at;
                self.now += wait;
                self.stalls.data += wait;
            }
        }
        self.now += u64::from(table_cycles);
        self.now - issue
    }
}

/// Base mnemonic (lower case, no `.f32`-style suffix), destination register and the
/// registers the instruction reads, for FPU instructions (others: no registers).
fn fp_operands(instr: &Instr) -> (String, Option<String>, Vec<String>) {
    let m = instr.mnemonic.to_ascii_lowercase();
    let base = m.split('.').next().unwrap_or_default().to_string();
    if !base.starts_with('v') {
        return (base, None, Vec::new());
    }
    let regs: Vec<String> = instr
        .operands
        .split(',')
        .map(|o| o.trim().to_string())
        .filter(|o| o.starts_with('s') && o[1..].parse::<u8>().is_ok())
        .collect();
    let dest = regs.first().cloned();
    // The multiply-accumulate family also reads its destination.
    let accumulates = matches!(
        base.as_str(),
        "vmla" | "vmls" | "vnmla" | "vnmls" | "vfma" | "vfms" | "vfnma" | "vfnms"
    );
    let compares = matches!(base.as_str(), "vcmp" | "vcmpe");
    let sources = if accumulates || compares {
        regs.clone()
    } else {
        regs.iter().skip(1).cloned().collect()
    };
    (base, dest, sources)
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::cycles::tests::ins;

    /// Replays `code` (each with its zero-wait cycles and accesses) and returns the
    /// cycles on the chip.
    fn replay(model: &ChipModel, code: &[(Instr, u32, Vec<Access>)]) -> (u64, Stalls) {
        let mut s = ChipState::new(model);
        let total = code.iter().map(|(i, c, a)| s.step(model, i, *c, a)).sum();
        (total, s.stalls)
    }

    fn flash_only(flash: FlashTiming) -> ChipModel {
        ChipModel {
            flash,
            map: MemoryMap::qemu_image_on_g474(),
            fpu_result_stall: false,
        }
    }

    /// `n` 32-bit one-cycle instructions from `start`.
    fn straight(start: u32, n: u32) -> Vec<(Instr, u32, Vec<Access>)> {
        (0..n)
            .map(|k| (ins(start + 4 * k, 4, "add.w", "r0, r0, #1"), 1, vec![]))
            .collect()
    }

    fn load(addr: u32, from: u32) -> (Instr, u32, Vec<Access>) {
        (
            ins(addr, 2, "ldr", "r0, [r1]"),
            2,
            vec![Access {
                addr: from,
                bytes: 4,
                store: false,
            }],
        )
    }

    #[test]
    fn zero_wait_flash_adds_nothing() {
        let m = flash_only(FlashTiming::ZERO_WAIT);
        let mut code = straight(0x100, 16);
        code.push(load(0x140, 0x8000));
        assert_eq!(replay(&m, &code).0, 16 + 2);
    }

    #[test]
    fn wait_states_without_prefetch_cost_each_line() {
        // 16 x 4-byte instructions = 8 lines of 8 bytes, each a 4-cycle wait.
        let m = flash_only(FlashTiming {
            wait_states: 4,
            ..FlashTiming::ZERO_WAIT
        });
        let (c, st) = replay(&m, &straight(0x100, 16));
        assert_eq!(st.fetch, 8 * 4);
        assert_eq!(c, 16 + 8 * 4);
        // 128-bit reads: 4 lines.
        let m = flash_only(FlashTiming {
            wait_states: 4,
            read_bytes: 16,
            ..FlashTiming::ZERO_WAIT
        });
        assert_eq!(replay(&m, &straight(0x100, 16)).0, 16 + 4 * 4);
    }

    #[test]
    fn prefetch_streams_one_line_per_flash_read() {
        // With prefetch the flash delivers 8 bytes every 1 + 4 = 5 cycles: the
        // first line waits 4, every later line of two 1-cycle instructions waits 3
        // (5 cycles per line).
        let m = flash_only(FlashTiming {
            wait_states: 4,
            prefetch: true,
            ..FlashTiming::ZERO_WAIT
        });
        let (c, st) = replay(&m, &straight(0x100, 16));
        assert_eq!(st.fetch, 4 + 7 * 3);
        assert_eq!(c, 16 + 4 + 7 * 3);
        // Slow instructions hide the flash: four 16-bit 3-cycle instructions per
        // line take 12 cycles, more than the 5 of the next line's read.
        let slow: Vec<_> = (0..16)
            .map(|k| (ins(0x100 + 2 * k, 2, "vmla.f32", "s0, s1, s2"), 3, vec![]))
            .collect();
        let (c, st) = replay(&m, &slow);
        assert_eq!(st.fetch, 4, "only the first line waits");
        assert_eq!(c, 4 + 16 * 3);
    }

    #[test]
    fn instruction_cache_holds_branch_targets_lru() {
        // A loop of one line (two instructions), 10 iterations: the first fetch
        // misses (4), then every iteration re-enters the cached line.
        let m = flash_only(FlashTiming {
            wait_states: 4,
            icache_bytes: 1024,
            ..FlashTiming::ZERO_WAIT
        });
        let mut code = Vec::new();
        for _ in 0..10 {
            code.push((ins(0x100, 4, "add.w", "r0, r0, #1"), 1, vec![]));
            code.push((ins(0x104, 4, "b.w", "0x100"), 2, vec![]));
            // Leave the line: an instruction in SRAM between iterations.
            code.push((ins(0x2000_0000, 2, "nop", ""), 1, vec![]));
        }
        let (c, st) = replay(&m, &code);
        assert_eq!(st.fetch, 4);
        assert_eq!(c, 4 + 10 * 4);
        // Without the cache every iteration misses.
        let m = flash_only(FlashTiming {
            wait_states: 4,
            ..FlashTiming::ZERO_WAIT
        });
        assert_eq!(replay(&m, &code).1.fetch, 10 * 4);
        // Five lines of one set (stride 32 reads = 256 B) visited round-robin
        // overflow its four ways (LRU): every visit misses; four lines fit.
        let m = flash_only(FlashTiming {
            wait_states: 4,
            icache_bytes: 1024,
            ..FlashTiming::ZERO_WAIT
        });
        let visits = |lines: u32| -> Vec<(Instr, u32, Vec<Access>)> {
            (0..3 * lines)
                .map(|k| {
                    (
                        ins(0x1000 + 256 * (k % lines), 4, "add.w", "r0, r0, #1"),
                        1,
                        vec![],
                    )
                })
                .collect()
        };
        assert_eq!(replay(&m, &visits(5)).1.fetch, 3 * 5 * 4);
        assert_eq!(replay(&m, &visits(4)).1.fetch, 4 * 4);
        // 128 lines of consecutive code fit (32 sets x 4 ways).
        let mut code = straight(0x1000, 256);
        code.extend(straight(0x1000, 256));
        assert_eq!(replay(&m, &code).1.fetch, 128 * 4);
    }

    #[test]
    fn data_reads_from_flash_wait_unless_cached() {
        // Code in SRAM; loads from flash: the first read of a line waits 4 cycles,
        // the second word of the same 8-byte line is a data-cache hit.
        let m = flash_only(FlashTiming {
            wait_states: 4,
            dcache_bytes: 256,
            ..FlashTiming::ZERO_WAIT
        });
        let code = vec![
            load(0x2000_0000, 0x8000),
            load(0x2000_0002, 0x8004),
            load(0x2000_0004, 0x8008),
        ];
        let (c, st) = replay(&m, &code);
        assert_eq!(st.data, 8);
        assert_eq!(c, 3 * 2 + 8);
        // Five lines of one of the 8 sets (stride 64 B) round-robin overflow its
        // four ways: every read misses; four fit.
        let reads = |lines: u32| -> Vec<(Instr, u32, Vec<Access>)> {
            (0..3 * lines)
                .map(|k| load(0x2000_0000 + 2 * k, 0x8000 + 64 * (k % lines)))
                .collect()
        };
        assert_eq!(replay(&m, &reads(5)).1.data, 3 * 5 * 4);
        assert_eq!(replay(&m, &reads(4)).1.data, 4 * 4);
        // An 8-byte load across two lines reads both: the first waits 4, the second
        // waits for the flash to finish the first (5).
        let across = vec![(
            ins(0x2000_0000, 4, "ldrd", "r0, r1, [r2]"),
            3,
            vec![Access {
                addr: 0x9004,
                bytes: 8,
                store: false,
            }],
        )];
        assert_eq!(replay(&m, &across).1.data, 4 + 5);
        // Loads from SRAM and CCM SRAM never wait.
        let code = vec![
            load(0x2000_0000, 0x2000_1000),
            load(0x2000_0002, 0x203F_8000),
        ];
        assert_eq!(replay(&m, &code).0, 4);
    }

    #[test]
    fn a_data_read_waits_for_the_prefetch_in_flight() {
        // Flash code with prefetch, then a load from flash right after the first
        // line arrives: the prefetch of the next line holds the flash for 5 cycles.
        let m = flash_only(FlashTiming {
            wait_states: 4,
            prefetch: true,
            ..FlashTiming::ZERO_WAIT
        });
        let code = vec![load(0x100, 0x8000)];
        // The fetch waits 4 (flash busy until 5), the prefetch holds the flash from
        // 5 to 10; the data phase at 5 starts its read at 10, ready at 14: waits 9.
        let (c, st) = replay(&m, &code);
        assert_eq!((st.fetch, st.data), (4, 9));
        assert_eq!(c, 4 + 9 + 2);
    }

    #[test]
    fn fpu_result_dependency_stalls_one_cycle() {
        let m = ChipModel {
            flash: FlashTiming::ZERO_WAIT,
            map: MemoryMap::qemu_image_on_g474(),
            fpu_result_stall: true,
        };
        let dep = vec![
            (ins(0x100, 4, "vmul.f32", "s0, s1, s2"), 1, vec![]),
            (ins(0x104, 4, "vadd.f32", "s3, s3, s0"), 1, vec![]),
        ];
        assert_eq!(
            replay(&m, &dep),
            (
                3,
                Stalls {
                    fpu: 1,
                    ..Stalls::default()
                }
            )
        );
        let indep = vec![
            (ins(0x100, 4, "vmul.f32", "s0, s1, s2"), 1, vec![]),
            (ins(0x104, 4, "vadd.f32", "s3, s3, s4"), 1, vec![]),
        ];
        assert_eq!(replay(&m, &indep).0, 2);
        // One instruction between them: no stall.
        let apart = vec![
            (ins(0x100, 4, "vmul.f32", "s0, s1, s2"), 1, vec![]),
            (ins(0x104, 4, "vmul.f32", "s5, s1, s2"), 1, vec![]),
            (ins(0x108, 4, "vadd.f32", "s3, s3, s0"), 1, vec![]),
        ];
        assert_eq!(replay(&m, &apart).0, 3);
        // A VMLA reads its accumulator: dependent.
        let acc = vec![
            (ins(0x100, 4, "vadd.f32", "s0, s1, s2"), 1, vec![]),
            (ins(0x104, 4, "vmla.f32", "s0, s1, s2"), 3, vec![]),
        ];
        assert_eq!(replay(&m, &acc).0, 5);
        let off = ChipModel {
            fpu_result_stall: false,
            ..m
        };
        assert_eq!(replay(&off, &dep).0, 2);
    }

    #[test]
    fn code_in_sram_and_ccm_sram_never_waits() {
        let m = ChipModel::g474_for_qemu_image();
        assert_eq!(replay(&m, &straight(0x203F_8000, 16)).0, 16);
        assert_eq!(replay(&m, &straight(0x2000_0000, 16)).0, 16);
        // From flash (single bank, the board's): 16 bytes (4 instructions) per read
        // every 5 cycles, the first line waits 4, each later one 1.
        assert_eq!(replay(&m, &straight(0x0000_0100, 16)).0, 16 + 4 + 3);
        // Dual bank (the factory setting): 8 bytes per read, 4 + 7 x 3.
        let dual = ChipModel {
            flash: FlashTiming::G474_170_MHZ_DUAL_BANK,
            ..m
        };
        assert_eq!(replay(&dual, &straight(0x0000_0100, 16)).0, 16 + 4 + 7 * 3);
    }

    #[test]
    fn the_qemu_image_maps_to_the_boards_regions() {
        let q = MemoryMap::qemu_image_on_g474();
        assert_eq!(q.region(0x0000_1234), Region::Flash);
        assert_eq!(q.region(0x2000_0100), Region::Sram);
        assert_eq!(q.region(0x203F_8100), Region::CcmSram);
        assert_eq!(q.region(0x203E_0000), Region::CcmSram);
        assert_eq!(q.region(0x203D_FFFC), Region::Sram);
        assert_eq!(q.region(0x4000_0000), Region::Other);
        let b = MemoryMap::g474();
        assert_eq!(b.region(0x0800_0000), Region::Flash);
        assert_eq!(b.region(0x2001_8000), Region::CcmSram);
        assert_eq!(b.region(0x2001_7ffc), Region::Sram);
    }
}
