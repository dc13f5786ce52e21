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

/// A wrapping microsecond clock from DWT CYCCNT: read it at least once per
/// CYCCNT period (25 s at 170 MHz; the compensator tick reads it every tick).
pub struct MicrosClock {
    cycles_per_us: u32,
    last_cycles: u32,
    spare_cycles: u32,
    now_us: u32,
}

impl MicrosClock {
    /// A clock at zero now, counting `core_clock_hz` cycles per second.
    pub fn new(core_clock_hz: u32) -> Self {
        Self {
            cycles_per_us: (core_clock_hz / 1_000_000).max(1),
            last_cycles: cycles(),
            spare_cycles: 0,
            now_us: 0,
        }
    }

    /// Microseconds since [`MicrosClock::new`] (wrapping).
    pub fn now_us(&mut self) -> u32 {
        let c = cycles();
        let elapsed = c
            .wrapping_sub(self.last_cycles)
            .saturating_add(self.spare_cycles);
        self.last_cycles = c;
        self.now_us = self.now_us.wrapping_add(elapsed / self.cycles_per_us);
        self.spare_cycles = elapsed % self.cycles_per_us;
        self.now_us
    }

    /// The local time of an earlier cycle count `at_cycles` (taken less than one
    /// CYCCNT period ago), microseconds.
    pub fn at(&mut self, at_cycles: u32) -> u32 {
        let now = self.now_us();
        let ago = self.last_cycles.wrapping_sub(at_cycles) / self.cycles_per_us;
        now.wrapping_sub(ago)
    }
}
