//! The AS5047P's bus on embassy-stm32: its blocking SPI1 (`SpiBus`) and the chip
//! select as an `Output`, an embedded-hal 1.0 `SpiDevice` of the board's timing
//! (`board/src/encoder_spi.rs`: >= 350 ns chip select low before the first clock and
//! high after the last).

use embassy_stm32::gpio::Output;
use embassy_stm32::mode::Blocking;
use embassy_stm32::spi::{self, Spi, mode::Master};
use embedded_hal::spi::{ErrorType, Operation, SpiBus, SpiDevice};

/// SPI1 and the encoder's chip select.
pub struct EncoderSpi {
    bus: Spi<'static, Blocking, Master>,
    chip_select: Output<'static>,
}

impl EncoderSpi {
    /// The device on a configured bus and a chip-select pin set high.
    pub fn new(bus: Spi<'static, Blocking, Master>, chip_select: Output<'static>) -> Self {
        Self { bus, chip_select }
    }

    #[inline]
    fn run(&mut self, op: &mut Operation<'_, u8>) -> Result<(), spi::Error> {
        match op {
            Operation::Read(buf) => self.bus.read(buf),
            Operation::Write(buf) => self.bus.write(buf),
            Operation::Transfer(read, write) => self.bus.transfer(read, write),
            Operation::TransferInPlace(buf) => self.bus.transfer_in_place(buf),
            Operation::DelayNs(ns) => {
                cortex_m::asm::delay(ns.saturating_mul(17) / 100 + 1);
                Ok(())
            }
        }
    }
}

impl ErrorType for EncoderSpi {
    type Error = spi::Error;
}

impl SpiDevice for EncoderSpi {
    #[inline]
    fn transaction(&mut self, operations: &mut [Operation<'_, u8>]) -> Result<(), spi::Error> {
        self.chip_select.set_low();
        cortex_m::asm::delay(60);
        let mut result = Ok(());
        for op in operations.iter_mut() {
            result = self.run(op);
            if result.is_err() {
                break;
            }
        }
        let flushed = SpiBus::<u8>::flush(&mut self.bus);
        self.chip_select.set_high();
        cortex_m::asm::delay(60);
        result.and(flushed)
    }
}
