//! AS5047P 14-bit magnetic rotary encoder over SPI (mode 1, 16-bit frames, chip
//! select high between frames), generic over an embedded-hal 1.0 [`SpiDevice`].
//!
//! Frames: a command is `PAR | R/W | ADDR[13:0]` (even parity over bits 14..0);
//! the answer to a command arrives in the NEXT frame as `PAR | EF | DATA[13:0]`.

use embedded_hal::spi::SpiDevice;

/// Register addresses.
pub mod reg {
    /// No operation (reads as 0).
    pub const NOP: u16 = 0x0000;
    /// Error flags (framing, command invalid, parity); cleared by reading.
    pub const ERRFL: u16 = 0x0001;
    /// Diagnostics and automatic gain control.
    pub const DIAAGC: u16 = 0x3FFC;
    /// Measured angle without dynamic angle error compensation.
    pub const ANGLEUNC: u16 = 0x3FFE;
    /// Measured angle with dynamic angle error compensation.
    pub const ANGLECOM: u16 = 0x3FFF;
}

/// Counts per revolution.
pub const COUNTS_PER_TURN: u16 = 1 << 14;

/// Driver errors.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Error<E> {
    /// The SPI bus failed.
    Spi(E),
    /// The answer's parity bit was wrong.
    Parity,
    /// The sensor set its error flag (read ERRFL for the cause).
    ErrorFlag,
}

/// Even parity bit for bits 14..0 of a frame: set when their count of ones is odd.
#[inline]
pub const fn parity_bit(frame: u16) -> u16 {
    ((frame & 0x7FFF).count_ones() as u16 & 1) << 15
}

/// The read command frame for a register.
#[inline]
pub const fn read_command(addr: u16) -> u16 {
    let f = 0x4000 | (addr & 0x3FFF);
    f | parity_bit(f)
}

/// Check an answer frame and return its 14 data bits.
pub fn decode_answer<E>(frame: u16) -> Result<u16, Error<E>> {
    if parity_bit(frame) != frame & 0x8000 {
        return Err(Error::Parity);
    }
    if frame & 0x4000 != 0 {
        return Err(Error::ErrorFlag);
    }
    Ok(frame & 0x3FFF)
}

/// The AS5047P.
#[derive(Debug)]
pub struct As5047p<SPI> {
    spi: SPI,
}

impl<SPI: SpiDevice> As5047p<SPI> {
    /// A driver on an SPI device (mode 1, up to 10 MHz, chip select managed by it).
    pub fn new(spi: SPI) -> Self {
        Self { spi }
    }

    /// Give the SPI device back.
    pub fn release(self) -> SPI {
        self.spi
    }

    fn frame(&mut self, command: u16) -> Result<u16, Error<SPI::Error>> {
        let mut buf = command.to_be_bytes();
        self.spi.transfer_in_place(&mut buf).map_err(Error::Spi)?;
        Ok(u16::from_be_bytes(buf))
    }

    /// Read a register (two frames: the command, then a NOP that brings the answer).
    pub fn read_register(&mut self, addr: u16) -> Result<u16, Error<SPI::Error>> {
        self.frame(read_command(addr))?;
        let answer = self.frame(read_command(reg::NOP))?;
        decode_answer(answer)
    }

    /// The compensated angle, counts (0..16384), fresh (two frames).
    pub fn read_angle_counts(&mut self) -> Result<u16, Error<SPI::Error>> {
        self.read_register(reg::ANGLECOM)
    }

    /// The compensated angle in one frame: returns the angle requested by the
    /// PREVIOUS call (one call of latency), for a fixed one-frame cost per control
    /// tick. The first call after a register read returns that read's answer,
    /// so discard it.
    pub fn read_angle_counts_pipelined(&mut self) -> Result<u16, Error<SPI::Error>> {
        let answer = self.frame(read_command(reg::ANGLECOM))?;
        decode_answer(answer)
    }

    /// Read and clear the error flags (ERRFL: bit 0 framing, 1 invalid command, 2 parity).
    pub fn read_error_flags(&mut self) -> Result<u16, Error<SPI::Error>> {
        self.read_register(reg::ERRFL)
    }
}

/// Counts to radians in [0, 2 pi).
#[inline]
pub fn counts_to_rad(counts: u16) -> f32 {
    (counts & 0x3FFF) as f32 * (core::f32::consts::TAU / COUNTS_PER_TURN as f32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use embedded_hal::spi::{ErrorKind, ErrorType, Operation};

    /// Emulates the sensor: answers each frame with the previous command's result.
    struct MockSensor {
        angle: u16,
        pending: u16,
        frames: u32,
        transactions: u32,
        corrupt_parity: bool,
        set_error_flag: bool,
        fail_bus: bool,
    }

    #[derive(Debug, PartialEq)]
    struct BusError;
    impl embedded_hal::spi::Error for BusError {
        fn kind(&self) -> ErrorKind {
            ErrorKind::Other
        }
    }
    impl ErrorType for MockSensor {
        type Error = BusError;
    }

    impl MockSensor {
        fn new(angle: u16) -> Self {
            Self {
                angle,
                pending: 0,
                frames: 0,
                transactions: 0,
                corrupt_parity: false,
                set_error_flag: false,
                fail_bus: false,
            }
        }
        fn exchange(&mut self, cmd: u16) -> u16 {
            self.frames += 1;
            assert_eq!(parity_bit(cmd), cmd & 0x8000, "driver sent a bad parity");
            let mut data = self.pending;
            if self.set_error_flag {
                data |= 0x4000;
            }
            let mut out = data | parity_bit(data);
            if self.corrupt_parity {
                out ^= 0x8000;
            }
            self.pending = match cmd & 0x3FFF {
                reg::ANGLECOM | reg::ANGLEUNC => self.angle,
                reg::ERRFL => 0x0004,
                _ => 0,
            };
            out
        }
    }

    impl SpiDevice for MockSensor {
        fn transaction(&mut self, ops: &mut [Operation<'_, u8>]) -> Result<(), BusError> {
            self.transactions += 1;
            if self.fail_bus {
                return Err(BusError);
            }
            for op in ops {
                if let Operation::TransferInPlace(buf) = op {
                    assert_eq!(buf.len(), 2, "16-bit frames");
                    let r = self.exchange(u16::from_be_bytes([buf[0], buf[1]]));
                    buf.copy_from_slice(&r.to_be_bytes());
                } else {
                    panic!("unexpected operation");
                }
            }
            Ok(())
        }
    }

    #[test]
    fn command_frames_have_even_parity() {
        assert_eq!(read_command(reg::ANGLECOM), 0xFFFF);
        assert_eq!(read_command(reg::NOP), 0xC000);
        assert_eq!(read_command(reg::ERRFL), 0x4001);
    }

    #[test]
    fn reads_the_angle_fresh_and_pipelined() {
        let mut enc = As5047p::new(MockSensor::new(12_345));
        assert_eq!(enc.read_angle_counts(), Ok(12_345));
        // Each frame is its own transaction (chip select high between frames).
        assert_eq!((enc.spi.frames, enc.spi.transactions), (2, 2));
        enc.spi.angle = 100;
        let _ = enc.read_angle_counts_pipelined();
        assert_eq!(enc.read_angle_counts_pipelined(), Ok(100));
        assert_eq!(enc.read_error_flags(), Ok(4));
        assert!((counts_to_rad(8192) - core::f32::consts::PI).abs() < 1e-6);
        assert!(counts_to_rad(16383) < core::f32::consts::TAU);
    }

    #[test]
    fn rejects_parity_error_flag_and_bus_errors() {
        let mut enc = As5047p::new(MockSensor::new(7));
        enc.spi.corrupt_parity = true;
        assert_eq!(enc.read_angle_counts(), Err(Error::Parity));
        enc.spi.corrupt_parity = false;
        enc.spi.set_error_flag = true;
        assert_eq!(enc.read_angle_counts(), Err(Error::ErrorFlag));
        enc.spi.set_error_flag = false;
        enc.spi.fail_bus = true;
        assert!(matches!(enc.read_angle_counts(), Err(Error::Spi(_))));
        enc.spi.fail_bus = false;
        assert_eq!(enc.read_angle_counts(), Ok(7));
    }
}
