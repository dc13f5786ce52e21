//! Pin maps, one per board, in one place: every pin a board image uses, with its
//! function (alternate function number and the peripheral signal it carries, analog
//! input and its ADC channel, or plain output / input). Pure data, built on the host
//! too: `board/tests/pin_map.rs` checks every entry against the STM32G474's own
//! metadata (`stm32-metapac`). Each binary names its board's map (`board`: generic,
//! `board-moteus`: moteus r4.11); `pins::init` sets the GPIO registers from it.
//!
//! A user with their own STM32G474 board copies `generic.rs`, changes the table,
//! adds it to [`ALL`] and names it in `src/main.rs`.

pub mod generic;
pub mod moteus_n1;
pub mod moteus_r4_11;

/// A GPIO port.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Port {
    /// GPIOA.
    A,
    /// GPIOB.
    B,
    /// GPIOC.
    C,
    /// GPIOD.
    D,
    /// GPIOF.
    F,
    /// GPIOG.
    G,
}

impl Port {
    /// The port's letter.
    pub const fn letter(self) -> char {
        match self {
            Port::A => 'A',
            Port::B => 'B',
            Port::C => 'C',
            Port::D => 'D',
            Port::F => 'F',
            Port::G => 'G',
        }
    }
    /// Index from GPIOA (GPIOx base = 0x4800_0000 + 0x400 * index).
    pub const fn index(self) -> u8 {
        match self {
            Port::A => 0,
            Port::B => 1,
            Port::C => 2,
            Port::D => 3,
            Port::F => 5,
            Port::G => 6,
        }
    }
}

/// A pin: port and number (0..=15).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PinId {
    /// Port.
    pub port: Port,
    /// Number in the port, 0..=15.
    pub number: u8,
}

/// Shorthand for a [`PinId`].
pub const fn pin(port: Port, number: u8) -> PinId {
    PinId { port, number }
}

/// Pull resistor of an input.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pull {
    /// None.
    None,
    /// Pull-up.
    Up,
    /// Pull-down.
    Down,
}

/// What a pin does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Function {
    /// Alternate function `af` carrying `peripheral`'s `signal` (metapac's names,
    /// e.g. "SPI1" "SCK").
    Alternate {
        /// Peripheral, e.g. "TIM1".
        peripheral: &'static str,
        /// Signal, e.g. "CH1N".
        signal: &'static str,
        /// AF number, 0..=15.
        af: u8,
    },
    /// Analog input of an ADC channel (e.g. "ADC1" "IN12").
    Analog {
        /// ADC, e.g. "ADC1".
        peripheral: &'static str,
        /// Channel, e.g. "IN12".
        signal: &'static str,
    },
    /// Push-pull output at its idle level after `pins::init`.
    Output {
        /// Idle level high.
        idle_high: bool,
    },
    /// Digital input.
    Input {
        /// Pull resistor.
        pull: Pull,
    },
}

/// One pin of a board's map.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Assignment {
    /// The pin.
    pub pin: PinId,
    /// Its function.
    pub function: Function,
    /// What it is on the board (e.g. "encoder chip select").
    pub role: &'static str,
}

/// How the board drives its bridge.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bridge {
    /// TIM1's six outputs (CHx and CHxN, dead time in TIM1), MOE as bridge enable.
    Tim1SixOutputs,
    /// A DRV8323/DRV8353 gate driver in 3-input mode on a timer's CH1..3 (the gate
    /// driver makes the low sides and the dead time), ENABLE as bridge enable.
    GateDriverThreeInputs {
        /// The timer, e.g. "TIM5".
        timer: &'static str,
    },
}

/// A board: its name, its MCU package and its pin map.
#[derive(Clone, Copy, Debug)]
pub struct BoardPins {
    /// Name (the cargo feature that selects it).
    pub name: &'static str,
    /// The MCU part as `stm32-metapac` names it (package included).
    pub chip: &'static str,
    /// How the bridge is driven.
    pub bridge: Bridge,
    /// Every pin the image uses.
    pub pins: &'static [Assignment],
}

impl BoardPins {
    /// The assignment with this role.
    pub fn by_role(&self, role: &str) -> Option<&'static Assignment> {
        self.pins.iter().find(|a| a.role == role)
    }
}

/// Every board map (the host test checks each).
pub const ALL: [&BoardPins; 3] = [&generic::BOARD, &moteus_r4_11::BOARD, &moteus_n1::BOARD];
