//! Pin functions from a board's pin map (`crate::boards`): every pin of the map is
//! set up in one pass (alternate function, analog, output at its idle level, input
//! with its pull), so the map is the one place a board's wiring is written.
//! (`unsafe`: the GPIO registers are reached by address, port by port, because the
//! PAC gives each port its own register-block type; every address is inside the
//! GPIOx blocks of RM0440 section 2.2.2, and each write is a read-modify-write of the
//! pin's own field.)

use crate::boards::{Assignment, BoardPins, Function, PinId, Pull};
use crate::pac;

/// GPIOA's base; GPIOx is `GPIO_BASE + 0x400 * index` (RM0440 table 4).
const GPIO_BASE: usize = 0x4800_0000;
const MODER: usize = 0x00;
const OSPEEDR: usize = 0x08;
const PUPDR: usize = 0x0C;
const BSRR: usize = 0x18;
const AFRL: usize = 0x20;

fn reg(pin: PinId, offset: usize) -> *mut u32 {
    (GPIO_BASE + 0x400 * pin.port.index() as usize + offset) as *mut u32
}

/// Read-modify-write of `width` bits at `shift` of a GPIO register.
fn set_field(pin: PinId, offset: usize, width: u32, shift: u32, value: u32) {
    let mask = ((1u32 << width) - 1) << shift;
    let r = reg(pin, offset);
    // SAFETY: `r` is a register of a GPIO port's block (see the module doc); the
    // pins are set up once, at start-up, before any interrupt is unmasked.
    unsafe {
        let v = core::ptr::read_volatile(r);
        core::ptr::write_volatile(r, (v & !mask) | ((value << shift) & mask));
    }
}

/// Drives an output pin high or low (BSRR: one write, no read-modify-write).
pub fn write(pin: PinId, high: bool) {
    let n = pin.number as u32 & 15;
    let bit = if high { 1 << n } else { 1 << (n + 16) };
    // SAFETY: BSRR of the pin's port; a write sets or resets only this pin.
    unsafe { core::ptr::write_volatile(reg(pin, BSRR), bit) };
}

/// Reads an input pin (IDR).
pub fn read(pin: PinId) -> bool {
    // SAFETY: IDR (offset 0x10) of the pin's port, read only.
    let v = unsafe { core::ptr::read_volatile(reg(pin, 0x10)) };
    v & (1 << (pin.number & 15)) != 0
}

fn configure(a: &Assignment) {
    let p = a.pin;
    let n = p.number as u32 & 15;
    match a.function {
        Function::Alternate { af, .. } => {
            set_field(p, AFRL + 4 * (n as usize / 8), 4, 4 * (n % 8), af as u32);
            set_field(p, OSPEEDR, 2, 2 * n, 0b10);
            set_field(p, MODER, 2, 2 * n, 0b10);
        }
        Function::Analog { .. } => set_field(p, MODER, 2, 2 * n, 0b11),
        Function::Output { idle_high } => {
            write(p, idle_high);
            set_field(p, OSPEEDR, 2, 2 * n, 0b10);
            set_field(p, MODER, 2, 2 * n, 0b01);
        }
        Function::Input { pull } => {
            let bits = match pull {
                Pull::None => 0b00,
                Pull::Up => 0b01,
                Pull::Down => 0b10,
            };
            set_field(p, PUPDR, 2, 2 * n, bits);
            set_field(p, MODER, 2, 2 * n, 0b00);
        }
    }
}

/// Clocks every GPIO port the board's map uses and sets every pin of it.
pub fn init(rcc: &pac::RCC, board: &BoardPins) {
    let mut enable = 0u32;
    for a in board.pins {
        enable |= 1 << a.pin.port.index();
    }
    // SAFETY: GPIOxEN are bits 0..=6 of AHB2ENR (RM0440 7.4.16), one per port index.
    rcc.ahb2enr()
        .modify(|r, w| unsafe { w.bits(r.bits() | enable) });
    // Two AHB cycles before the first access to a newly clocked port.
    cortex_m::asm::dsb();
    for a in board.pins {
        configure(a);
    }
}

/// A map's output pin as an embedded-hal [`OutputPin`](embedded_hal::digital::OutputPin).
#[derive(Clone, Copy, Debug)]
pub struct Output(pub PinId);

impl embedded_hal::digital::ErrorType for Output {
    type Error = core::convert::Infallible;
}

impl embedded_hal::digital::OutputPin for Output {
    fn set_low(&mut self) -> Result<(), Self::Error> {
        write(self.0, false);
        Ok(())
    }
    fn set_high(&mut self) -> Result<(), Self::Error> {
        write(self.0, true);
        Ok(())
    }
}
