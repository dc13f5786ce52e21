//! TIM1: center-aligned PWM on CH1..3 with complementary outputs CH1N..3N and dead
//! time, MOE as the bridge enable; CH4 (PWM mode 2, CCR4 = ARR - 1) drives TRGO at
//! the counter's peak, where the low-side switches conduct, which starts the ADC's
//! injected conversions. (`unsafe`: the PAC's raw multi-bit field writes: prescaler,
//! auto-reload, compare values, output modes, dead time, master mode.)

use crate::pac;

/// Dead-time generator value (DTG, 170 MHz timer clock): 17 ticks = 100 ns.
const DEAD_TIME_DTG: u8 = 17;

/// TIM1's auto-reload for center-aligned PWM at `pwm_hz` from `timer_clock_hz`.
pub const fn auto_reload(timer_clock_hz: u32, pwm_hz: u32) -> u16 {
    (timer_clock_hz / (2 * pwm_hz)) as u16
}

/// TIM1's three PWM channels and the bridge enable (MOE).
pub struct Pwm {
    tim: pac::TIM1,
    arr: u16,
}

impl Pwm {
    /// Clocks and sets up TIM1 (auto-reload `arr`, duties 0.5, bridge off, counter
    /// stopped until [`Pwm::start`]).
    pub fn init(rcc: &pac::RCC, t: pac::TIM1, arr: u16) -> Self {
        rcc.apb2enr().modify(|_, w| w.tim1en().set_bit());
        // Center-aligned PWM mode 1 on CH1..3 + complementary, CH4 in PWM mode 2 at
        // ARR - 1 as TRGO (the counter's peak).
        t.psc().write(|w| unsafe { w.psc().bits(0) });
        t.arr().write(|w| unsafe { w.arr().bits(arr as u32) });
        t.cr1()
            .modify(|_, w| unsafe { w.cms().bits(0b01) }.arpe().set_bit());
        t.ccmr1_output().modify(|_, w| unsafe {
            w.oc1m()
                .bits(0b110)
                .oc1pe()
                .set_bit()
                .oc2m()
                .bits(0b110)
                .oc2pe()
                .set_bit()
        });
        t.ccmr2_output().modify(|_, w| unsafe {
            w.oc3m()
                .bits(0b110)
                .oc3pe()
                .set_bit()
                .oc4m()
                .bits(0b111)
                .oc4pe()
                .set_bit()
        });
        let half = arr as u32 / 2;
        t.ccr1().write(|w| unsafe { w.ccr().bits(half) });
        t.ccr2().write(|w| unsafe { w.ccr().bits(half) });
        t.ccr3().write(|w| unsafe { w.ccr().bits(half) });
        t.ccr4().write(|w| unsafe { w.ccr().bits(arr as u32 - 1) });
        t.ccer().modify(|_, w| {
            w.cc1e()
                .set_bit()
                .cc1ne()
                .set_bit()
                .cc2e()
                .set_bit()
                .cc2ne()
                .set_bit()
                .cc3e()
                .set_bit()
                .cc3ne()
                .set_bit()
        });
        t.bdtr().modify(|_, w| {
            unsafe { w.dtg().bits(DEAD_TIME_DTG) }
                .ossr()
                .set_bit()
                .ossi()
                .set_bit()
        });
        t.cr2().modify(|_, w| unsafe { w.mms().bits(0b111) });
        t.egr().write(|w| w.ug().set_bit());
        Pwm { tim: t, arr }
    }

    /// Starts the counter (and with it the ADC trigger).
    pub fn start(&mut self) {
        self.tim.cr1().modify(|_, w| w.cen().set_bit());
    }

    /// Write three duties in [0, 1] (preloaded: they apply from the next period) and
    /// switch the bridge on or off.
    #[inline]
    pub fn set_duties(&mut self, duties: [f32; 3], enabled: bool) {
        let arr = self.arr as f32;
        // `as` saturates and maps NaN to 0.
        let c = duties.map(|d| (d * arr) as u32);
        self.tim.ccr1().write(|w| unsafe { w.ccr().bits(c[0]) });
        self.tim.ccr2().write(|w| unsafe { w.ccr().bits(c[1]) });
        self.tim.ccr3().write(|w| unsafe { w.ccr().bits(c[2]) });
        self.tim.bdtr().modify(|_, w| w.moe().bit(enabled));
    }
}
