//! Pin functions (GPIOA, GPIOB): the encoder's chip select and SPI1, TIM1's six
//! bridge outputs and USART3. The analog inputs (PA0, PA1, PB1) keep their reset
//! state. (`unsafe`: the PAC's raw multi-bit MODER, OSPEEDR and AFR field writes.)
//!
//! | pin | function |
//! |---|---|
//! | PA4 | encoder chip select (output, idle high) |
//! | PA5, PA6, PA7 | SPI1 SCK, MISO, MOSI (AF5) |
//! | PA8, PA9, PA10 | TIM1 CH1..3 (AF6) |
//! | PB13, PB14, PB15 | TIM1 CH1N..3N (AF6) |
//! | PB10, PB11 | USART3 TX, RX (AF7) |
//! | PA0, PA1, PB1 | ADC1 IN1, IN2 (phase currents a, b), IN12 (bus voltage) |

use crate::pac;

/// Clocks GPIOA and GPIOB and sets every pin of the table above.
pub fn init(rcc: &pac::RCC, ga: &pac::GPIOA, gb: &pac::GPIOB) {
    rcc.ahb2enr()
        .modify(|_, w| w.gpioaen().set_bit().gpioben().set_bit());
    // GPIOA: PA4 output (encoder chip select, high), PA5..7 AF5 (SPI1),
    // PA8..10 AF6 (TIM1 CH1..3).
    ga.bsrr().write(|w| w.bs4().set_bit());
    ga.moder().modify(|_, w| unsafe {
        w.moder4()
            .bits(0b01)
            .moder5()
            .bits(0b10)
            .moder6()
            .bits(0b10)
            .moder7()
            .bits(0b10)
            .moder8()
            .bits(0b10)
            .moder9()
            .bits(0b10)
            .moder10()
            .bits(0b10)
    });
    ga.ospeedr().modify(|_, w| unsafe {
        w.ospeedr4()
            .bits(0b10)
            .ospeedr5()
            .bits(0b10)
            .ospeedr7()
            .bits(0b10)
            .ospeedr8()
            .bits(0b10)
            .ospeedr9()
            .bits(0b10)
            .ospeedr10()
            .bits(0b10)
    });
    ga.afrl()
        .modify(|_, w| unsafe { w.afrl5().bits(5).afrl6().bits(5).afrl7().bits(5) });
    ga.afrh()
        .modify(|_, w| unsafe { w.afrh8().bits(6).afrh9().bits(6).afrh10().bits(6) });
    // GPIOB: PB10/PB11 AF7 (USART3), PB13..15 AF6 (TIM1 CH1N..3N); PB1 analog.
    gb.moder().modify(|_, w| unsafe {
        w.moder10()
            .bits(0b10)
            .moder11()
            .bits(0b10)
            .moder13()
            .bits(0b10)
            .moder14()
            .bits(0b10)
            .moder15()
            .bits(0b10)
    });
    gb.ospeedr().modify(|_, w| unsafe {
        w.ospeedr13()
            .bits(0b10)
            .ospeedr14()
            .bits(0b10)
            .ospeedr15()
            .bits(0b10)
    });
    gb.afrh().modify(|_, w| unsafe {
        w.afrh10()
            .bits(7)
            .afrh11()
            .bits(7)
            .afrh13()
            .bits(6)
            .afrh14()
            .bits(6)
            .afrh15()
            .bits(6)
    });
}
