//! The RNG (clocked by HSI48): one random number per start for the state bus's
//! session, so that the other joints resynchronise after this board restarts.

use crate::{pac, spin_until};

/// A fresh bus session number from the RNG (0 if it did not deliver); the RNG is
/// switched off again.
pub fn draw(rcc: &pac::RCC, rng: &pac::RNG) -> u16 {
    // HSI48 feeds the RNG (CLK48SEL's reset value).
    rcc.crrcr().modify(|_, w| w.hsi48on().set_bit());
    spin_until(|| rcc.crrcr().read().hsi48rdy().bit_is_set());
    rcc.ahb2enr().modify(|_, w| w.rngen().set_bit());
    rng.cr().modify(|_, w| w.rngen().set_bit());
    let session = if spin_until(|| rng.sr().read().drdy().bit_is_set()) {
        rng.dr().read().bits() as u16
    } else {
        0
    };
    rng.cr().modify(|_, w| w.rngen().clear_bit());
    session
}
