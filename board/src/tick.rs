//! SysTick as the periodic control tick, and DWT CYCCNT, which measures each tick's
//! cycles on the hardware.

use cortex_m::peripheral::{DCB, DWT, SYST, syst::SystClkSource};

/// Starts DWT CYCCNT (the cycle counter the binaries' reports read).
pub fn enable_cycle_counter(dcb: &mut DCB, dwt: &mut DWT) {
    dcb.enable_trace();
    dwt.enable_cycle_counter();
}

/// The cycle counter now.
#[inline]
pub fn cycles() -> u32 {
    DWT::cycle_count()
}

/// Starts SysTick from the core clock `core_clock_hz` with its interrupt at
/// `tick_hz` (a zero rate leaves it stopped).
pub fn start_systick(syst: &mut SYST, core_clock_hz: u32, tick_hz: u32) {
    let Some(reload) = core_clock_hz.checked_div(tick_hz) else {
        return;
    };
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(reload.saturating_sub(1));
    syst.clear_current();
    syst.enable_interrupt();
    syst.enable_counter();
}
