//! The STM32G474RE joint-drive board: one module per peripheral, each with its
//! register access (`stm32g4` PAC) and its `unsafe` behind a safe interface. The
//! binaries (`board`, `board-bench`) wire them to the `firmware` library.
//!
//! For `thumbv7em-none-eabihf` only: built for the host the crate holds only the pin
//! maps (`boards`, pure data, checked by `tests/pin_map.rs`), so that
//! `cargo test --workspace` and `cargo clippy --workspace` pass over it.
#![cfg_attr(target_os = "none", no_std)]
#![deny(unsafe_code)]
#![warn(missing_docs)]

#[cfg(target_os = "none")]
#[allow(unsafe_code)]
pub mod adc;
pub mod boards;
/// The start-up copy of the CCM SRAM code (its own crate: the QEMU images share it).
#[cfg(target_os = "none")]
pub use board_ccm as ccm;
#[cfg(target_os = "none")]
#[allow(unsafe_code)]
pub mod clock;
#[cfg(target_os = "none")]
#[allow(unsafe_code)]
pub mod config_block;
#[cfg(target_os = "none")]
#[allow(unsafe_code)]
pub mod encoder_spi;
#[cfg(target_os = "none")]
#[allow(unsafe_code)]
pub mod fdcan;
#[cfg(target_os = "none")]
#[allow(unsafe_code)]
pub mod pins;
#[cfg(target_os = "none")]
#[allow(unsafe_code)]
pub mod pwm;
#[cfg(target_os = "none")]
pub mod session;
#[cfg(target_os = "none")]
#[allow(unsafe_code)]
pub mod state_bus;
#[cfg(target_os = "none")]
pub mod tick;

#[cfg(target_os = "none")]
pub use stm32g4::stm32g474 as pac;

/// Bound of every busy-wait on a peripheral flag, iterations.
#[cfg(target_os = "none")]
const SPIN_LIMIT: u32 = 100_000;

/// Polls `cond` at most [`SPIN_LIMIT`] times; whether it became true.
#[cfg(target_os = "none")]
#[inline]
fn spin_until(mut cond: impl FnMut() -> bool) -> bool {
    for _ in 0..SPIN_LIMIT {
        if cond() {
            return true;
        }
    }
    false
}
