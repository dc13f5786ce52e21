//! The generic STM32G474RE board (the project's reference wiring, not a product):
//! TIM1's six outputs to a discrete bridge, three analog inputs, an AS5047P on SPI1,
//! the state bus on USART3. Copy this file for your own board and change the table.

use super::Function::{Alternate, Analog, Output};
use super::{Assignment, BoardPins, Bridge, Port::*, pin};

const fn af(peripheral: &'static str, signal: &'static str, af: u8) -> super::Function {
    Alternate {
        peripheral,
        signal,
        af,
    }
}

/// The generic board.
#[rustfmt::skip]
pub const BOARD: BoardPins = BoardPins {
    name: "generic",
    chip: "STM32G474RE",
    bridge: Bridge::Tim1SixOutputs,
    pins: &[
        Assignment { pin: pin(A, 4), function: Output { idle_high: true }, role: "encoder chip select" },
        Assignment { pin: pin(A, 5), function: af("SPI1", "SCK", 5), role: "encoder SCK" },
        Assignment { pin: pin(A, 6), function: af("SPI1", "MISO", 5), role: "encoder MISO" },
        Assignment { pin: pin(A, 7), function: af("SPI1", "MOSI", 5), role: "encoder MOSI" },
        Assignment { pin: pin(A, 8), function: af("TIM1", "CH1", 6), role: "phase a high side" },
        Assignment { pin: pin(A, 9), function: af("TIM1", "CH2", 6), role: "phase b high side" },
        Assignment { pin: pin(A, 10), function: af("TIM1", "CH3", 6), role: "phase c high side" },
        Assignment { pin: pin(B, 13), function: af("TIM1", "CH1N", 6), role: "phase a low side" },
        Assignment { pin: pin(B, 14), function: af("TIM1", "CH2N", 6), role: "phase b low side" },
        Assignment { pin: pin(B, 15), function: af("TIM1", "CH3N", 4), role: "phase c low side" },
        Assignment { pin: pin(B, 10), function: af("USART3", "TX", 7), role: "state bus TX" },
        Assignment { pin: pin(B, 11), function: af("USART3", "RX", 7), role: "state bus RX" },
        Assignment { pin: pin(A, 0), function: Analog { peripheral: "ADC1", signal: "IN1" }, role: "phase a current" },
        Assignment { pin: pin(A, 1), function: Analog { peripheral: "ADC1", signal: "IN2" }, role: "phase b current" },
        Assignment { pin: pin(B, 1), function: Analog { peripheral: "ADC1", signal: "IN12" }, role: "bus voltage" },
    ],
};
