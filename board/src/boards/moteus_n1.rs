//! mjbots moteus-n1 (STM32G474CEU6, DRV8353, CAN-FD): its map, checked like the
//! others. No image is built for it: its gate driver's SPI pins (PC10, PC11, PC13)
//! are not one SPI peripheral's (moteus bit-bangs them), so it needs a bit-banged
//! `SpiDevice` and its own ADC wiring first. Facts: `fw/moteus_hw.cc`
//! `FindHardwarePins`, the family 1 branch (README table).

use super::Function::{Alternate, Analog, Input, Output};
use super::{Assignment, BoardPins, Bridge, Port::*, Pull, pin};

const fn af(peripheral: &'static str, signal: &'static str, af: u8) -> super::Function {
    Alternate {
        peripheral,
        signal,
        af,
    }
}

/// moteus-n1.
#[rustfmt::skip]
pub const BOARD: BoardPins = BoardPins {
    name: "moteus-n1",
    chip: "STM32G474CE",
    bridge: Bridge::GateDriverThreeInputs { timer: "TIM5" },
    pins: &[
        Assignment { pin: pin(A, 0), function: af("TIM5", "CH1", 2), role: "phase a PWM" },
        Assignment { pin: pin(A, 1), function: af("TIM5", "CH2", 2), role: "phase b PWM" },
        Assignment { pin: pin(A, 2), function: af("TIM5", "CH3", 2), role: "phase c PWM" },
        Assignment { pin: pin(C, 14), function: Output { idle_high: false }, role: "gate driver enable" },
        Assignment { pin: pin(C, 15), function: Output { idle_high: false }, role: "gate driver hiz" },
        Assignment { pin: pin(B, 0), function: Output { idle_high: true }, role: "gate driver chip select" },
        Assignment { pin: pin(C, 13), function: Output { idle_high: false }, role: "gate driver MOSI (bit-banged)" },
        Assignment { pin: pin(C, 11), function: Input { pull: Pull::Up }, role: "gate driver MISO (bit-banged)" },
        Assignment { pin: pin(C, 10), function: Output { idle_high: false }, role: "gate driver SCK (bit-banged)" },
        Assignment { pin: pin(B, 13), function: Input { pull: Pull::Up }, role: "gate driver nFAULT" },
        Assignment { pin: pin(B, 2), function: Output { idle_high: true }, role: "encoder chip select" },
        Assignment { pin: pin(A, 3), function: Analog { peripheral: "ADC1", signal: "IN4" }, role: "phase a current" },
        Assignment { pin: pin(A, 6), function: Analog { peripheral: "ADC2", signal: "IN3" }, role: "phase b current" },
        Assignment { pin: pin(B, 1), function: Analog { peripheral: "ADC3", signal: "IN1" }, role: "phase c current" },
        Assignment { pin: pin(A, 9), function: Analog { peripheral: "ADC5", signal: "IN2" }, role: "bus voltage" },
        Assignment { pin: pin(B, 12), function: Analog { peripheral: "ADC4", signal: "IN3" }, role: "board temperature" },
        Assignment { pin: pin(A, 8), function: Analog { peripheral: "ADC5", signal: "IN1" }, role: "motor temperature" },
        Assignment { pin: pin(B, 6), function: af("FDCAN2", "TX", 9), role: "CAN TX" },
        Assignment { pin: pin(B, 5), function: af("FDCAN2", "RX", 9), role: "CAN RX" },
        Assignment { pin: pin(B, 15), function: Output { idle_high: false }, role: "debug LED" },
        Assignment { pin: pin(C, 6), function: Output { idle_high: false }, role: "power LED" },
    ],
};
