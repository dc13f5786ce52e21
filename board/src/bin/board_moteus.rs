//! Bring-up image for mjbots moteus r4.11 (`cargo board-build` builds it beside
//! `board`): the pin map `board::boards::moteus_r4_11`, the 170 MHz clock, the
//! DRV8353 gate driver's safe start-up over SPI1 (chip select PC4: enable, write and
//! read back every control register, read both status registers), then ENABLE low
//! again, and the on-board AS5047P read over the same SPI1 (chip select PB11) once a
//! second, reported over defmt. The bridge is never switched: the PWM timer (TIM5),
//! the three-ADC current sampling and the CAN-FD state bus of this board are not
//! wired yet (board README, "moteus r4.11"), so this image proves the pin map, the
//! gate driver and the encoder on the hardware, and nothing drives the motor.
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]
#![deny(unsafe_code)]

/// Built for the host: nothing to run.
#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("board-moteus runs on the moteus r4.11 only: `cargo board-build`");
    std::process::exit(2);
}

#[cfg(target_os = "none")]
mod app {
    use board::boards::moteus_r4_11::{BOARD, GATE_DRIVER};
    use board::encoder_spi::EncoderSpi;
    use board::pac;
    use board::pins::{self, Output};
    use board::{ccm, clock};
    use cortex_m_rt::{ExceptionFrame, entry, exception};
    use firmware::drivers::as5047p::As5047p;
    use firmware::drivers::drv83x3::{Drv83x3, Variant};
    #[cfg(not(feature = "defmt"))]
    use panic_halt as _;
    #[cfg(feature = "defmt")]
    use {defmt_rtt as _, panic_probe as _};

    /// The role's pin, or a HardFault at start-up (the map is checked on the host,
    /// `board/tests/pin_map.rs`, so this never happens with the committed map).
    fn pin(role: &str) -> board::boards::PinId {
        match BOARD.by_role(role) {
            Some(a) => a.pin,
            None => cortex_m::asm::udf(),
        }
    }

    #[entry]
    fn main() -> ! {
        ccm::copy_code();
        let Some(dp) = pac::Peripherals::take() else {
            cortex_m::asm::udf();
        };
        if !clock::boost_170_mhz(&dp.RCC, &dp.PWR, &dp.FLASH) {
            firmware::fw_warn!("the 170 MHz clock set-up timed out");
        }
        // Every pin of the map; the gate driver's ENABLE and HIZ start low.
        pins::init(&dp.RCC, &BOARD);
        let enable = Output(pin("gate driver enable"));
        let _fault_line = pin("gate driver nFAULT");

        let spi = EncoderSpi::init(&dp.RCC, dp.SPI1, pin("gate driver chip select"));
        let mut drv = Drv83x3::new(spi, enable, Variant::Drv8353);
        // t_WAKE of the DRV8353 is at most 1 ms; wait 2 ms.
        let started = drv.start_up(&GATE_DRIVER, || {
            cortex_m::asm::delay(2 * clock::CORE_CLOCK_HZ / 1000)
        });
        if let Ok(_f) = started {
            firmware::fw_info!(
                "gate driver up: configuration read back, status {=u16:#x} {=u16:#x}, nFAULT {=bool}",
                _f.status1,
                _f.status2,
                pins::read(_fault_line)
            );
        } else {
            firmware::fw_error!(
                "gate driver start-up refused (no answer, a register read back wrong, or a fault): ENABLE low"
            );
        }
        // Bridge off: nothing in this image switches the gates.
        let _ = drv.disable();
        let (spi, _) = drv.release();

        let spi = EncoderSpi::init(&dp.RCC, spi.release(), pin("encoder chip select"));
        let mut encoder = As5047p::new(spi);
        loop {
            if let Ok(_counts) = encoder.read_angle_counts() {
                firmware::fw_info!("encoder {=u16} counts", _counts);
            } else {
                firmware::fw_error!("encoder read failed");
            }
            cortex_m::asm::delay(clock::CORE_CLOCK_HZ);
        }
    }

    /// A HardFault stops here (halts the core; a debugger shows where). ENABLE is
    /// low then unless the fault hit between `start_up` and `disable`; the PWM inputs
    /// stay low (TIM5 is never started), so no gate is switched either way.
    #[allow(unsafe_code)] // cortex-m-rt requires the handler to be `unsafe fn`
    #[exception]
    unsafe fn HardFault(_frame: &ExceptionFrame) -> ! {
        loop {
            cortex_m::asm::bkpt();
        }
    }
}
