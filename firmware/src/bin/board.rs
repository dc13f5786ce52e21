//! Board binary for the joint-drive MCU (STM32G474RE, Cortex-M4F).
//!
//! Wires the core peripherals to the library: SysTick as the periodic control
//! tick, DWT CYCCNT to measure each tick's cycles, a HardFault handler that parks
//! the drive. Peripheral wiring (PWM, ADC, encoder, bus) comes with the control loop.
#![no_std]
#![no_main]

use cortex_m::peripheral::{DWT, syst::SystClkSource};
use cortex_m_rt::{ExceptionFrame, entry, exception};
#[cfg(not(feature = "defmt"))]
use panic_halt as _;
#[cfg(feature = "defmt")]
use {defmt_rtt as _, panic_probe as _};

/// Core clock after reset (HSI16); the PLL set-up to 170 MHz comes with the
/// peripheral wiring.
const CORE_CLOCK_HZ: u32 = 16_000_000;
/// Control tick rate.
const TICK_HZ: u32 = 1_000;

#[entry]
fn main() -> ! {
    let mut cp = match cortex_m::Peripherals::take() {
        Some(cp) => cp,
        None => loop {
            cortex_m::asm::udf();
        },
    };
    cp.DCB.enable_trace();
    cp.DWT.enable_cycle_counter();
    cp.SYST.set_clock_source(SystClkSource::Core);
    cp.SYST.set_reload(CORE_CLOCK_HZ / TICK_HZ - 1);
    cp.SYST.clear_current();
    cp.SYST.enable_interrupt();
    cp.SYST.enable_counter();
    firmware::fw_info!("board up: tick {=u32} Hz", TICK_HZ);
    loop {
        cortex_m::asm::wfi();
    }
}

/// The control tick: runs the per-joint computation and measures it with CYCCNT.
#[exception]
fn SysTick() {
    static mut PHASE_RAD: f32 = 0.0;
    static mut TICKS: u32 = 0;
    let start = DWT::cycle_count();
    *PHASE_RAD = (*PHASE_RAD + 0.01) % 6.283_185;
    let (s, c) = firmware::math::sin_cos(*PHASE_RAD);
    let out = firmware::math::tanh(s) + firmware::math::sigmoid(c);
    let cycles = DWT::cycle_count().wrapping_sub(start);
    *TICKS = TICKS.wrapping_add(1);
    if *TICKS % TICK_HZ == 0 {
        firmware::fw_info!(
            "tick {=u32}: {=u32} cycles (DWT CYCCNT), out {=f32}",
            *TICKS,
            cycles,
            out
        );
    }
    let _ = (cycles, out);
}

#[exception]
unsafe fn HardFault(_frame: &ExceptionFrame) -> ! {
    firmware::fw_error!("HardFault: pc={=u32:#x}", _frame.pc());
    loop {
        cortex_m::asm::bkpt();
    }
}
