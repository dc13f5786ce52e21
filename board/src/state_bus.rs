//! USART3 (8N1 with FIFO, receive interrupt): the state bus carrying
//! `JointStateMessage` frames between the joints, standing in for EtherCAT.
//! (`unsafe`: the PAC's raw baud-rate and data register writes, and the receive
//! side's own handle on USART3 in its interrupt.)

use crate::{pac, spin_until};

/// USART3's transmit side.
pub struct Bus {
    usart: pac::USART3,
}

impl Bus {
    /// Clocks and enables USART3 at `baud` from `kernel_clock_hz` (8N1, FIFO, receive
    /// interrupt enabled, masked in the NVIC until the binary unmasks it).
    pub fn init(rcc: &pac::RCC, u: pac::USART3, kernel_clock_hz: u32, baud: u32) -> Self {
        rcc.apb1enr1().modify(|_, w| w.usart3en().set_bit());
        let brr = kernel_clock_hz.checked_div(baud).unwrap_or(0);
        u.brr().write(|w| unsafe { w.bits(brr) });
        u.cr1().write(|w| {
            w.fifoen()
                .set_bit()
                .rxneie()
                .set_bit()
                .re()
                .set_bit()
                .te()
                .set_bit()
                .ue()
                .set_bit()
        });
        Bus { usart: u }
    }

    /// Send a frame (bounded wait per byte; a stuck bus drops the rest).
    pub fn send(&mut self, bytes: &[u8]) {
        let u = &self.usart;
        for &b in bytes {
            if !spin_until(|| u.isr().read().txe().bit_is_set()) {
                return;
            }
            u.tdr().write(|w| unsafe { w.tdr().bits(b as u16) });
        }
    }
}

/// One received byte, if any (clears an overrun). Call from the USART3 interrupt only.
pub fn read_byte() -> Option<u8> {
    // SAFETY: only the USART3 interrupt reads RDR/ISR/ICR of USART3; thread mode only
    // writes TDR through `Bus`.
    let u = unsafe { pac::USART3::steal() };
    let isr = u.isr().read();
    if isr.ore().bit_is_set() {
        u.icr().write(|w| w.orecf().clear_bit_by_one());
    }
    if isr.rxne().bit_is_set() {
        Some(u.rdr().read().rdr().bits() as u8)
    } else {
        None
    }
}
