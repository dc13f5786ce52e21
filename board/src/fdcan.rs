//! FDCAN1 (CAN-FD, 1 Mbit/s arbitration, 5 Mbit/s data with bit-rate switching):
//! the state bus of boards with a CAN-FD transceiver (moteus). Frames are
//! `firmware::control::canfd::CanFdFrame`s; their meaning, MAC and bus time are the
//! `canfd` module's, this one only moves them.
//!
//! Register level on the PAC, like every other peripheral of the crate (board README,
//! "The state bus on FDCAN1"): the message RAM (SRAMCAN, RM0440 44.3.3) has a fixed
//! layout on the G4: per instance 28 standard filters, 8 extended filters, Rx FIFO 0
//! and 1 of 3 elements each, a Tx event FIFO of 3 and 3 Tx buffers, each Rx/Tx
//! element 18 words (2 header words, 64 data bytes). No filter is set: every
//! standard data frame goes to Rx FIFO 0 (the `canfd::BusNode` ignores identifiers
//! that are not the bus's), extended and remote frames are rejected. The receive
//! interrupt is FDCAN1 interrupt 0 on "Rx FIFO 0 new message".
//! (`unsafe`: the PAC's raw multi-bit field writes, and the message RAM, which the
//! PAC does not describe, read and written through volatile pointers at its fixed
//! address.)

use crate::{pac, spin_until};
use firmware::control::canfd::CanFdFrame;

/// Start of FDCAN1's part of the message RAM (SRAMCAN), RM0440 table 3.
const SRAMCAN_FDCAN1: usize = 0x4000_A400;
/// Byte offset of Rx FIFO 0 in an instance's message RAM (RM0440 44.3.3).
const RX_FIFO0: usize = 0x0B0;
/// Byte offset of the Tx buffers.
const TX_BUFFERS: usize = 0x278;
/// Bytes per Rx FIFO / Tx buffer element (18 words).
const ELEMENT: usize = 72;
/// Elements of Rx FIFO 0 and of the Tx FIFO.
const ELEMENTS: u8 = 3;

/// Bit timing at a 170 MHz FDCAN kernel clock (PCLK1): nominal 1 Mbit/s = 170 time
/// quanta (prescaler 1, 1 + 135 + 34: sample point 80 %), data 5 Mbit/s = 34 time
/// quanta (1 + 26 + 7: 79 %), transmitter delay compensation at the data sample
/// point. The register fields hold each value minus one.
pub const NOMINAL_SEG1_TQ: u8 = 135;
/// Nominal phase segment 2, time quanta.
pub const NOMINAL_SEG2_TQ: u8 = 34;
/// Data phase segment 1, time quanta.
pub const DATA_SEG1_TQ: u8 = 26;
/// Data phase segment 2, time quanta.
pub const DATA_SEG2_TQ: u8 = 7;

/// CAN-FD payload length of a DLC code (ISO 11898-1).
pub const fn dlc_to_len(dlc: u32) -> u8 {
    match dlc & 0xF {
        d @ 0..=8 => d as u8,
        9 => 12,
        10 => 16,
        11 => 20,
        12 => 24,
        13 => 32,
        14 => 48,
        _ => 64,
    }
}

/// The smallest DLC code whose length holds `len` bytes.
pub const fn len_to_dlc(len: u8) -> u32 {
    match len {
        0..=8 => len as u32,
        9..=12 => 9,
        13..=16 => 10,
        17..=20 => 11,
        21..=24 => 12,
        25..=32 => 13,
        33..=48 => 14,
        _ => 15,
    }
}

fn ram_word(offset: usize) -> *mut u32 {
    (SRAMCAN_FDCAN1 + offset) as *mut u32
}

/// Why FDCAN1 did not start.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StartError {
    /// The controller did not enter initialisation mode.
    NoInit,
    /// The controller did not leave initialisation mode: it waits for 11 recessive
    /// bits, so the bus is held dominant or the transceiver is off.
    BusNotIdle,
}

/// FDCAN1's transmit side (the receive side is [`receive`], from its interrupt).
pub struct Can {
    can: pac::FDCAN1,
    dropped: u32,
}

impl Can {
    /// Clocks FDCAN1 from PCLK1 (170 MHz), sets the bit timing above, CAN-FD with
    /// bit-rate switching, the Tx FIFO, no filters (standard frames to Rx FIFO 0),
    /// the "new message in Rx FIFO 0" interrupt on line 0 (masked in the NVIC until
    /// the binary unmasks it), and starts it; bounded waits.
    pub fn init(rcc: &pac::RCC, can: pac::FDCAN1) -> Result<Self, StartError> {
        rcc.ccipr().modify(|_, w| w.fdcansel().pclk());
        rcc.apb1enr1().modify(|_, w| w.fdcanen().set_bit());
        can.cccr().modify(|_, w| w.init().set_bit());
        if !spin_until(|| can.cccr().read().init().bit_is_set()) {
            return Err(StartError::NoInit);
        }
        can.cccr()
            .modify(|_, w| w.cce().set_bit().fdoe().set_bit().brse().set_bit());
        can.nbtp().write(|w| unsafe {
            w.nbrp()
                .bits(0)
                .ntseg1()
                .bits(NOMINAL_SEG1_TQ - 1)
                .ntseg2()
                .bits(NOMINAL_SEG2_TQ - 1)
                .nsjw()
                .bits(NOMINAL_SEG2_TQ - 1)
        });
        can.dbtp().write(|w| unsafe {
            w.dbrp()
                .bits(0)
                .dtseg1()
                .bits(DATA_SEG1_TQ - 1)
                .dtseg2()
                .bits(DATA_SEG2_TQ - 1)
                .dsjw()
                .bits(DATA_SEG2_TQ - 1)
                .tdc()
                .set_bit()
        });
        // Secondary sample point: the transceiver loop delay plus the data sample
        // point (1 + segment 1 time quanta).
        can.tdcr()
            .write(|w| unsafe { w.tdco().bits(DATA_SEG1_TQ + 1).tdcf().bits(0) });
        // No filter elements; non-matching standard frames to FIFO 0, extended
        // frames rejected, remote frames rejected.
        can.rxgfc().write(|w| unsafe {
            w.lss()
                .bits(0)
                .lse()
                .bits(0)
                .anfs()
                .bits(0)
                .anfe()
                .bits(2)
                .rrfs()
                .set_bit()
                .rrfe()
                .set_bit()
        });
        can.txbc().write(|w| w.tfqm().clear_bit());
        can.ie().write(|w| w.rf0ne().set_bit());
        can.ils().write(|w| w.rxfifo0().clear_bit());
        can.ile().write(|w| w.eint0().set_bit());
        can.cccr().modify(|_, w| w.init().clear_bit());
        if !spin_until(|| can.cccr().read().init().bit_is_clear()) {
            return Err(StartError::BusNotIdle);
        }
        Ok(Can { can, dropped: 0 })
    }

    /// Queue `frame` for transmission (CAN-FD with bit-rate switching, standard
    /// identifier); false, and counted, when the three Tx buffers are all pending.
    pub fn send(&mut self, frame: &CanFdFrame) -> bool {
        let fqs = self.can.txfqs().read();
        if fqs.tfqf().bit_is_set() {
            self.dropped = self.dropped.saturating_add(1);
            return false;
        }
        let index = fqs.tfqpi().bits() % ELEMENTS;
        let base = TX_BUFFERS + usize::from(index) * ELEMENT;
        let payload = frame.payload();
        let dlc = len_to_dlc(payload.len() as u8);
        let t0 = u32::from(frame.id & 0x7FF) << 18;
        let t1 = (1 << 21) | (1 << 20) | (dlc << 16);
        // SAFETY: the Tx buffer element `index` lies inside FDCAN1's message RAM and
        // is free (TFQPI names a free buffer while TFQF is clear); nothing else
        // writes the Tx buffers.
        unsafe {
            ram_word(base).write_volatile(t0);
            ram_word(base + 4).write_volatile(t1);
            let words = usize::from(dlc_to_len(dlc)).div_ceil(4);
            for w in 0..words {
                let mut b = [0u8; 4];
                for (k, byte) in b.iter_mut().enumerate() {
                    *byte = payload.get(4 * w + k).copied().unwrap_or(0);
                }
                ram_word(base + 8 + 4 * w).write_volatile(u32::from_le_bytes(b));
            }
        }
        self.can.txbar().write(|w| unsafe { w.bits(1 << index) });
        true
    }

    /// Frames not sent since start because the Tx FIFO was full (saturating).
    pub fn dropped(&self) -> u32 {
        self.dropped
    }

    /// Transmit and receive error counters (ECR: TEC, REC).
    pub fn error_counters(&self) -> (u8, u8) {
        let e = self.can.ecr().read();
        (e.tec().bits(), e.rec().bits())
    }
}

/// The oldest frame of Rx FIFO 0, if any (acknowledged, so the FIFO moves on), and
/// clears the interrupt flag. Call from FDCAN1 interrupt 0 only.
pub fn receive() -> Option<CanFdFrame> {
    // SAFETY: only FDCAN1 interrupt 0 reads Rx FIFO 0 and writes RXF0A and IR; thread
    // mode only uses the Tx registers and buffers through `Can`.
    let can = unsafe { pac::FDCAN1::steal() };
    // IR bits clear on writing 1 (RM0440 FDCAN_IR); the others are written 0.
    can.ir().write(|w| w.rf0n().set_bit());
    let s = can.rxf0s().read();
    if s.f0fl().bits() == 0 {
        return None;
    }
    let index = s.f0gi().bits() % ELEMENTS;
    let base = RX_FIFO0 + usize::from(index) * ELEMENT;
    let mut frame = CanFdFrame {
        id: 0,
        len: 0,
        data: [0; 64],
    };
    // SAFETY: the Rx FIFO 0 element `index` (F0GI, the get index of a non-empty
    // FIFO) lies inside FDCAN1's message RAM and is not overwritten until
    // acknowledged below.
    let (r0, r1) = unsafe {
        (
            ram_word(base).read_volatile(),
            ram_word(base + 4).read_volatile(),
        )
    };
    // Standard identifier in bits 28..18; an extended (XTD) or remote (RTR) frame is
    // passed on with identifier 0xFFFF, which no node reads.
    frame.id = if r0 & (3 << 29) == 0 {
        ((r0 >> 18) & 0x7FF) as u16
    } else {
        0xFFFF
    };
    frame.len = dlc_to_len(r1 >> 16);
    let words = usize::from(frame.len).div_ceil(4);
    for w in 0..words {
        // SAFETY: as above; at most 16 data words of the element.
        let word = unsafe { ram_word(base + 8 + 4 * w).read_volatile() };
        if let Some(d) = frame.data.get_mut(4 * w..4 * w + 4) {
            d.copy_from_slice(&word.to_le_bytes());
        }
    }
    can.rxf0a().write(|w| unsafe { w.f0ai().bits(index) });
    Some(frame)
}
