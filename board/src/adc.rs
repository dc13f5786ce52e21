//! ADC1: three injected conversions triggered by TIM1 TRGO (phase currents a, b on
//! IN1, IN2; bus voltage on IN12), the end-of-sequence interrupt (`ADC1_2`) being the
//! PWM-rate control interrupt; the scales of the board's shunt amplifiers and bus
//! divider. (`unsafe`: the PAC's raw multi-bit field writes: clock mode, sample
//! times, the injected sequence.)

use crate::{pac, spin_until};

/// Phase-current scale of the board's shunt amplifiers, A per ADC count.
pub const AMPS_PER_COUNT: f32 = 0.016_1;
/// Phase-current zero (mid-scale), ADC counts.
pub const CURRENT_ZERO_COUNTS: f32 = 2048.0;
/// Bus-voltage divider, V per ADC count.
pub const VOLTS_PER_COUNT: f32 = 0.019_3;

/// ADC1's injected channels.
pub struct Adc {
    adc: pac::ADC1,
}

impl Adc {
    /// Clocks ADC1 and ADC2's common block (synchronous clock HCLK/4), powers the
    /// regulator, calibrates, enables ADC1 and sets the injected sequence on TIM1
    /// TRGO's rising edge with the end-of-sequence interrupt.
    pub fn init(rcc: &pac::RCC, common: &pac::ADC12_COMMON, a: pac::ADC1) -> Self {
        rcc.ahb2enr().modify(|_, w| w.adc12en().set_bit());
        common.ccr().modify(|_, w| unsafe { w.ckmode().bits(0b11) });
        a.cr().modify(|_, w| w.deeppwd().clear_bit());
        a.cr().modify(|_, w| w.advregen().set_bit());
        cortex_m::asm::delay(170 * 25);
        a.cr()
            .modify(|_, w| w.adcaldif().clear_bit().adcal().set_bit());
        spin_until(|| a.cr().read().adcal().bit_is_clear());
        cortex_m::asm::delay(100);
        a.isr().write(|w| w.adrdy().clear_bit_by_one());
        a.cr().modify(|_, w| w.aden().set_bit());
        spin_until(|| a.isr().read().adrdy().bit_is_set());
        a.smpr1()
            .modify(|_, w| unsafe { w.smp1().bits(0b010).smp2().bits(0b010) });
        a.smpr2().modify(|_, w| unsafe { w.smp12().bits(0b010) });
        a.jsqr().write(|w| unsafe {
            w.jl()
                .bits(2)
                .jextsel()
                .bits(0)
                .jexten()
                .bits(0b01)
                .jsq1()
                .bits(1)
                .jsq2()
                .bits(2)
                .jsq3()
                .bits(12)
        });
        a.ier().modify(|_, w| w.jeosie().set_bit());
        Adc { adc: a }
    }

    /// Arms the injected conversions (they start on the next TIM1 trigger).
    pub fn start(&mut self) {
        self.adc.cr().modify(|_, w| w.jadstart().set_bit());
    }

    /// The three injected results (phase a, phase b, bus), and clear the flag.
    #[inline]
    pub fn read_injected_and_clear(&mut self) -> [u16; 3] {
        let r = [
            self.adc.jdr1().read().jdata().bits(),
            self.adc.jdr2().read().jdata().bits(),
            self.adc.jdr3().read().jdata().bits(),
        ];
        self.adc.isr().write(|w| w.jeos().clear_bit_by_one());
        r
    }
}
