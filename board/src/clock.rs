//! The STM32G474's 170 MHz core clock with the flash set for it: shared by the
//! board and board-bench binaries, so that the bench times what the board runs.
//! (`unsafe`: the raw multi-bit `FLASH_ACR`, `PLLCFGR` and `CFGR` field writes the PAC
//! marks unsafe, each with its value from the reference manual.)

use crate::{pac, spin_until};

/// Core clock after [`boost_170_mhz`], in Hz.
pub const CORE_CLOCK_HZ: u32 = 170_000_000;

/// Flash wait states at 170 MHz in range-1 boost mode (RM0440 §3.3.3).
pub const FLASH_WAIT_STATES: u8 = 4;

/// Whether the flash is in single-bank mode (option bit DBANK = 0): 128-bit reads and
/// 4 KiB pages, the organisation the cycle budget assumes (`host-tests`: a weight read
/// from flash costs half the wait of the factory dual-bank mode's 64-bit reads). An
/// option byte, set when the board is provisioned (board README), not by the firmware:
/// changing it reorganises the flash, which must then be erased and written again.
pub fn flash_single_bank(flash: &pac::FLASH) -> bool {
    flash.optr().read().dbank().bit_is_clear()
}

/// Boost mode, flash at [`FLASH_WAIT_STATES`] with prefetch, instruction and data
/// caches on, then HSI16 / 4 x 85 / 2 = 170 MHz through the PLL (switched through
/// AHB / 2, the reference manual's boost-mode sequence). Whether every step
/// reported ready.
pub fn boost_170_mhz(rcc: &pac::RCC, pwr: &pac::PWR, flash: &pac::FLASH) -> bool {
    rcc.apb1enr1().modify(|_, w| w.pwren().set_bit());
    pwr.cr5().modify(|_, w| w.r1mode().clear_bit());
    flash.acr().modify(|_, w| {
        unsafe { w.latency().bits(FLASH_WAIT_STATES) }
            .prften()
            .set_bit()
            .icen()
            .set_bit()
            .dcen()
            .set_bit()
    });
    let mut ready = spin_until(|| flash.acr().read().latency().bits() == FLASH_WAIT_STATES);
    rcc.pllcfgr().write(|w| {
        unsafe {
            w.pllsrc()
                .bits(0b10)
                .pllm()
                .bits(3)
                .plln()
                .bits(85)
                .pllr()
                .bits(0)
        }
        .pllren()
        .set_bit()
    });
    rcc.cr().modify(|_, w| w.pllon().set_bit());
    ready &= spin_until(|| rcc.cr().read().pllrdy().bit_is_set());
    rcc.cfgr().modify(|_, w| unsafe { w.hpre().bits(0b1000) });
    rcc.cfgr().modify(|_, w| unsafe { w.sw().bits(0b11) });
    ready &= spin_until(|| rcc.cfgr().read().sws().bits() == 0b11);
    cortex_m::asm::delay(200);
    rcc.cfgr().modify(|_, w| unsafe { w.hpre().bits(0) });
    ready
}
