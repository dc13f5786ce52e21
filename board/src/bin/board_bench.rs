//! Bench binary for the joint-drive MCU (STM32G474RE, Cortex-M4F).
//!
//! SysTick as the periodic tick, DWT CYCCNT to measure each tick's cycles, a
//! HardFault handler that parks the core. No drive peripherals are touched.
//!
//! Each tick runs the selected registered workloads
//! (`test_kit::bench::visit_all`, the same ones the QEMU cycle estimator traces),
//! times each with DWT CYCCNT, and once per second reports per workload and for the
//! whole tick the min / max / mean cycles over defmt. These are
//! measured cycles (`cargo board-bench-run`), the hardware counterpart of `cargo run -p host-tests --bin budget`.
//!
//! Which workloads: the names in `BENCH_WORKLOADS` when the binary is built
//! (comma-separated, e.g. `BENCH_WORKLOADS=lstm_paper_int16 cargo board-bench-run`), else
//! every workload but the three paper-size networks and the PWM tick (its FOC and cascade
//! code in CCM SRAM does not fit beside the others'). Each workload's model is placed as
//! its own board image would place it (its arrays in SRAM where they fit the board's
//! budget), so the paper networks do not fit beside the others: time them one image each.
//! A workload left out is not linked.
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]

/// Built for the host: nothing to run.
#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("board-bench runs on the STM32G474 only: `cargo board-bench-run`");
    std::process::exit(2);
}

#[cfg(target_os = "none")]
mod app {
    use board::{ccm, clock};
    use cortex_m::peripheral::{DWT, syst::SystClkSource};
    use cortex_m_rt::{ExceptionFrame, entry, exception};
    use firmware::log::TickStats;
    use test_kit::bench::{Visitor, Workload, visit_all};
    // The device crate supplies the interrupt vector table.
    use board::pac;
    #[cfg(not(feature = "defmt"))]
    use panic_halt as _;
    #[cfg(feature = "defmt")]
    use {defmt_rtt as _, panic_probe as _};

    /// Core clock: the board's 170 MHz, with its flash wait states, prefetch and caches
    /// (`clock::boost_170_mhz`, as in the board binary).
    const CORE_CLOCK_HZ: u32 = clock::CORE_CLOCK_HZ;
    /// Control tick rate: 100 Hz (the paper's data rate) leaves 1 700 000 cycles per
    /// tick, room for every registered workload.
    const TICK_HZ: u32 = 100;
    /// Most workloads the statistics have room for.
    const MAX_WORKLOADS: usize = 16;
    /// The workloads timed without `BENCH_WORKLOADS`: all but these (each paper-size
    /// network, and the PWM tick, whose FOC and cascade code in CCM SRAM does not fit
    /// beside every other workload's: each is timed in an image of its own).
    const LEFT_OUT_BY_DEFAULT: [&str; 4] = [
        "lstm_paper_f32",
        "lstm_paper_int16",
        "lstm_paper_int8",
        "drive_pwm_tick",
    ];

    /// `a == b`, at compile time.
    const fn same(a: &[u8], b: &[u8]) -> bool {
        if a.len() != b.len() {
            return false;
        }
        let mut k = 0;
        while k < a.len() {
            if a[k] != b[k] {
                return false;
            }
            k += 1;
        }
        true
    }

    /// Whether workload `name` is timed (module docs), at compile time.
    const fn selected(name: &str) -> bool {
        let name = name.as_bytes();
        match option_env!("BENCH_WORKLOADS") {
            Some(list) => {
                let list = list.as_bytes();
                let (mut start, mut k) = (0, 0);
                while k <= list.len() {
                    if k == list.len() || list[k] == b',' {
                        let (_, rest) = list.split_at(start);
                        let (item, _) = rest.split_at(k - start);
                        if same(item, name) {
                            return true;
                        }
                        start = k + 1;
                    }
                    k += 1;
                }
                false
            }
            None => {
                let mut k = 0;
                while k < LEFT_OUT_BY_DEFAULT.len() {
                    if same(LEFT_OUT_BY_DEFAULT[k].as_bytes(), name) {
                        return false;
                    }
                    k += 1;
                }
                true
            }
        }
    }

    #[entry]
    fn main() -> ! {
        ccm::copy_code();
        let (Some(mut cp), Some(dp)) = (cortex_m::Peripherals::take(), pac::Peripherals::take())
        else {
            cortex_m::asm::udf()
        };
        if !clock::boost_170_mhz(&dp.RCC, &dp.PWR, &dp.FLASH) {
            firmware::fw_warn!("the 170 MHz clock set-up timed out: cycles are not the board's");
        }
        if !clock::flash_single_bank(&dp.FLASH) {
            firmware::fw_warn!(
                "flash in dual-bank mode (DBANK = 1): cycles are not the budget's (single-bank) flash"
            );
        }
        cp.DCB.enable_trace();
        cp.DWT.enable_cycle_counter();
        cp.SYST.set_clock_source(SystClkSource::Core);
        cp.SYST.set_reload(CORE_CLOCK_HZ / TICK_HZ - 1);
        cp.SYST.clear_current();
        cp.SYST.enable_interrupt();
        cp.SYST.enable_counter();
        firmware::fw_info!(
            "board up: tick {=u32} Hz, core {=u32} Hz, flash {=u8} wait states, prefetch and caches on, {=usize} workloads",
            TICK_HZ,
            CORE_CLOCK_HZ,
            clock::FLASH_WAIT_STATES,
            test_kit::bench::workload_count()
        );
        loop {
            cortex_m::asm::wfi();
        }
    }

    /// Runs each workload's tick once and records its DWT CYCCNT cycles.
    struct Measure<'a> {
        stats: &'a mut [TickStats; MAX_WORKLOADS],
        next: usize,
        sink: u32,
    }

    impl Visitor for Measure<'_> {
        fn visit<W: Workload>(&mut self) {
            if !const { selected(W::NAME) } {
                return;
            }
            let mut w = W::new();
            let start = DWT::cycle_count();
            w.tick();
            let cycles = DWT::cycle_count().wrapping_sub(start);
            if let Some(s) = self.stats.get_mut(self.next) {
                s.record(cycles);
            }
            self.next += 1;
            self.sink ^= w.output().to_bits();
        }
    }

    /// Reports each workload's window and starts a new one.
    struct Report<'a> {
        stats: &'a mut [TickStats; MAX_WORKLOADS],
        next: usize,
    }

    impl Visitor for Report<'_> {
        fn visit<W: Workload>(&mut self) {
            if !const { selected(W::NAME) } {
                return;
            }
            if let Some(s) = self.stats.get_mut(self.next) {
                let s = s.take();
                firmware::fw_info!(
                    "{=str}: min {=u32} max {=u32} mean {=u32} cycles over {=u32} ticks (DWT CYCCNT)",
                    W::NAME,
                    s.min_cycles,
                    s.max_cycles,
                    s.mean_cycles(),
                    s.ticks
                );
                let _ = s;
            }
            self.next += 1;
        }
    }

    /// The control tick: runs the workloads and measures them with CYCCNT.
    #[exception]
    fn SysTick() {
        static mut STATS: [TickStats; MAX_WORKLOADS] = [TickStats::new(); MAX_WORKLOADS];
        static mut WHOLE: TickStats = TickStats::new();
        static mut TICKS: u32 = 0;
        static mut SINK: u32 = 0;
        let start = DWT::cycle_count();
        let mut m = Measure {
            stats: STATS,
            next: 0,
            sink: 0,
        };
        visit_all(&mut m);
        *SINK ^= m.sink;
        WHOLE.record(DWT::cycle_count().wrapping_sub(start));
        *TICKS = TICKS.wrapping_add(1);
        if TICKS.is_multiple_of(TICK_HZ) {
            visit_all(&mut Report {
                stats: STATS,
                next: 0,
            });
            let w = WHOLE.take();
            firmware::fw_info!(
                "whole tick: min {=u32} max {=u32} mean {=u32} cycles over {=u32} ticks (DWT CYCCNT), out {=u32:#x}",
                w.min_cycles,
                w.max_cycles,
                w.mean_cycles(),
                w.ticks,
                *SINK
            );
            let _ = w;
        }
    }

    #[exception]
    unsafe fn HardFault(_frame: &ExceptionFrame) -> ! {
        firmware::fw_error!("HardFault: pc={=u32:#x}", _frame.pc());
        loop {
            cortex_m::asm::bkpt();
        }
    }
}
