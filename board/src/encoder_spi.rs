//! SPI1 with one GPIO chip select (mode 1, 8-bit frames, f_PCLK / 32 = 5.3 MHz): an
//! embedded-hal 1.0 `SpiDevice` for `firmware::drivers::as5047p` (the encoder: PA4
//! on the generic board, PB11 on moteus) and `firmware::drivers::drv83x3` (the
//! moteus gate driver, PC4), chip select low for the whole transaction, every
//! wait bounded. One device owns SPI1 at a time (`release` gives it back). (`unsafe`: the PAC's raw multi-bit field writes, and byte-wide data
//! register access.)

use crate::boards::PinId;
use crate::{pac, pins, spin_until};
use embedded_hal::spi::{ErrorKind, ErrorType, Operation, SpiDevice};

/// SPI1 and the chip-select pin.
pub struct EncoderSpi {
    spi: pac::SPI1,
    cs: PinId,
}

/// A busy-wait ran out (the bus is stuck).
#[derive(Debug)]
pub struct SpiTimeout;

impl embedded_hal::spi::Error for SpiTimeout {
    fn kind(&self) -> ErrorKind {
        ErrorKind::Other
    }
}

impl ErrorType for EncoderSpi {
    type Error = SpiTimeout;
}

impl EncoderSpi {
    /// Clocks and enables SPI1: master, mode 1, 8-bit frames with the RX FIFO
    /// threshold at 8 bits, software chip select `cs` (an output set up by `pins`),
    /// f_PCLK / 32.
    pub fn init(rcc: &pac::RCC, s: pac::SPI1, cs: PinId) -> Self {
        rcc.apb2enr().modify(|_, w| w.spi1en().set_bit());
        s.cr1().write(|w| {
            unsafe { w.br().bits(0b100) }
                .cpha()
                .set_bit()
                .mstr()
                .set_bit()
                .ssm()
                .set_bit()
                .ssi()
                .set_bit()
        });
        s.cr2()
            .write(|w| unsafe { w.ds().bits(0b0111) }.frxth().set_bit());
        s.cr1().modify(|_, w| w.spe().set_bit());
        EncoderSpi { spi: s, cs }
    }

    /// Give SPI1 back (chip select left high).
    pub fn release(self) -> pac::SPI1 {
        self.spi
    }

    #[inline]
    fn exchange(&mut self, out: u8) -> Result<u8, SpiTimeout> {
        let spi = &self.spi;
        if !spin_until(|| spi.sr().read().txe().bit_is_set()) {
            return Err(SpiTimeout);
        }
        // SAFETY: byte-wide access to the data register (a 16- or 32-bit access
        // would push two frames in 8-bit mode); the address is the PAC's own.
        unsafe { core::ptr::write_volatile(spi.dr().as_ptr() as *mut u8, out) };
        if !spin_until(|| spi.sr().read().rxne().bit_is_set()) {
            return Err(SpiTimeout);
        }
        // SAFETY: as above, byte-wide read of the data register.
        Ok(unsafe { core::ptr::read_volatile(spi.dr().as_ptr() as *const u8) })
    }

    #[inline]
    fn run(&mut self, op: &mut Operation<'_, u8>) -> Result<(), SpiTimeout> {
        match op {
            Operation::Read(buf) => {
                for b in buf.iter_mut() {
                    *b = self.exchange(0)?;
                }
            }
            Operation::Write(buf) => {
                for &b in buf.iter() {
                    self.exchange(b)?;
                }
            }
            Operation::Transfer(read, write) => {
                for i in 0..read.len().max(write.len()) {
                    let r = self.exchange(write.get(i).copied().unwrap_or(0))?;
                    if let Some(slot) = read.get_mut(i) {
                        *slot = r;
                    }
                }
            }
            Operation::TransferInPlace(buf) => {
                for b in buf.iter_mut() {
                    *b = self.exchange(*b)?;
                }
            }
            Operation::DelayNs(ns) => cortex_m::asm::delay(ns.saturating_mul(17) / 100 + 1),
        }
        Ok(())
    }
}

impl SpiDevice for EncoderSpi {
    #[inline]
    fn transaction(&mut self, operations: &mut [Operation<'_, u8>]) -> Result<(), SpiTimeout> {
        pins::write(self.cs, false);
        // AS5047P: t_L (chip select low to first clock) >= 350 ns.
        cortex_m::asm::delay(60);
        let mut result = Ok(());
        for op in operations.iter_mut() {
            result = self.run(op);
            if result.is_err() {
                break;
            }
        }
        let spi = &self.spi;
        spin_until(|| spi.sr().read().bsy().bit_is_clear());
        pins::write(self.cs, true);
        // t_CSn (chip select high between frames) >= 350 ns.
        cortex_m::asm::delay(60);
        result
    }
}
