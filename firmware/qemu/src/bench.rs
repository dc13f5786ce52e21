//! QEMU bench binary (mps2-an386, Cortex-M4F): runs every registered workload
//! (`test_kit::bench::visit_all`) `TICKS` times and prints, over semihosting, the
//! address of its tick function and the SysTick count around the ticks.
//!
//! `host-tests` (`cargo run -p host-tests --bin budget`) runs it twice: under
//! `-icount shift=0`, where SysTick (core clock, 25 MHz on mps2-an386) advances
//! once per 40 instructions, giving a deterministic instruction count; and with an
//! instruction trace restricted (`-dfilter`) to the tick functions and their
//! callees, which it weights with the Cortex-M4 cycle tables.
//!
//! It also measures each tick's stack depth by painting the stack below the
//! measuring loop and finding the deepest word the ticks overwrote.
//!
//! Output: `@bench TICKS`, then per workload
//! `@workload NAME TICK_ADDR MACS SYSTICK_DELTA BASELINE_DELTA OUTPUT_BITS STACK_BYTES`,
//! `@pass`.
#![no_std]
#![no_main]

use core::fmt::Write;
use core::hint::black_box;
use cortex_m::peripheral::{SYST, syst::SystClkSource};
use cortex_m_rt::entry;
use cortex_m_semihosting::hio;
use test_kit::bench::{Visitor, Workload, visit_all};

mod exit;
/// The start-up copy of the CCM SRAM code, as on the board.
use board_ccm as ccm;
use exit::{fail, pass};

/// Ticks per workload (each traced; keep the trace short).
const TICKS: u32 = 10;
/// SysTick reload: the 24-bit maximum (one wrap is 671 M instructions).
const RELOAD: u32 = 0x00ff_ffff;

/// The driver's empty tick: what the measuring loop costs without a workload.
#[inline(never)]
fn baseline<W>(_: &mut W) {}

/// Runs `tick` `TICKS` times and returns the SysTick ticks elapsed and the
/// deepest stack use of the ticks in bytes (from the stack pointer at the call).
#[inline(never)]
fn time<W>(syst: &mut SYST, w: &mut W, tick: fn(&mut W)) -> (u32, u32) {
    let sp = cortex_m::register::msp::read();
    stack::paint(sp);
    syst.clear_current();
    let start = SYST::get_current();
    for _ in 0..TICKS {
        tick(w);
    }
    let end = SYST::get_current();
    (start.wrapping_sub(end) & RELOAD, stack::depth(sp))
}

/// Stack painting: the only unsafe code of the bench binary.
#[allow(unsafe_code)]
mod stack {
    /// Bytes below the caller's stack pointer that are painted and scanned.
    pub const SPAN: u32 = 32 * 1024;
    /// Bytes right below the stack pointer left unpainted: `paint`'s own frame.
    pub const GAP: u32 = 64;
    const PAINT: u32 = 0x5AA5_C33C;

    /// Fills `[sp - SPAN, sp - GAP)` with the paint pattern.
    #[inline(never)]
    pub fn paint(sp: u32) {
        let mut a = (sp - SPAN) & !3;
        while a < sp - GAP {
            // SAFETY: the words lie in the 4 MiB RAM of mps2-an386 below the live
            // stack frames (`GAP` covers this function's own frame), so no live
            // data is overwritten.
            unsafe { core::ptr::write_volatile(a as *mut u32, PAINT) };
            a += 4;
        }
    }

    /// Bytes between `sp` and the deepest overwritten word (at least `GAP`: a
    /// shallower use cannot be seen).
    pub fn depth(sp: u32) -> u32 {
        let mut a = (sp - SPAN) & !3;
        while a < sp - GAP {
            // SAFETY: reads of the same RAM words `paint` wrote.
            if unsafe { core::ptr::read_volatile(a as *const u32) } != PAINT {
                return sp - a;
            }
            a += 4;
        }
        GAP
    }
}

struct Driver {
    host: hio::HostStream,
    syst: SYST,
}

impl Visitor for Driver {
    fn visit<W: Workload>(&mut self) {
        let mut w = W::new();
        let tick: fn(&mut W) = black_box(W::tick as fn(&mut W));
        let empty: fn(&mut W) = black_box(baseline::<W> as fn(&mut W));
        let (base, _) = time(&mut self.syst, &mut w, empty);
        let (delta, stack_bytes) = time(&mut self.syst, &mut w, tick);
        if writeln!(
            self.host,
            "@workload {} {:#010x} {} {} {} {:08x} {}",
            W::NAME,
            tick as usize,
            W::MACS,
            delta,
            base,
            w.output().to_bits(),
            stack_bytes
        )
        .is_err()
        {
            fail();
        }
    }
}

#[entry]
fn main() -> ! {
    ccm::copy_code();
    let Some(cp) = cortex_m::Peripherals::take() else {
        fail()
    };
    let mut syst = cp.SYST;
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(RELOAD);
    syst.clear_current();
    syst.enable_counter();
    let Ok(mut host) = hio::hstdout() else { fail() };
    if writeln!(host, "@bench {TICKS}").is_err() {
        fail();
    }
    let mut d = Driver { host, syst };
    visit_all(&mut d);
    if writeln!(d.host, "@pass").is_err() {
        fail();
    }
    pass()
}
