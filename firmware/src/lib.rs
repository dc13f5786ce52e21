//! Per-joint torque feedforward for a collaborative robot's joint drives.
//!
//! `no_std`, no heap. Every numeric function here is the single source of truth:
//! the host exporter and the tests call the same code that runs on the MCU, and
//! `host-tests` proves the results are bit-identical on both.
#![cfg_attr(not(test), no_std)]
#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod bench;
pub mod control;
pub mod drivers;
pub mod dsp;
pub mod dynamics;
pub mod features;
pub mod golden;
pub mod log;
pub mod lstm;
pub mod math;
pub mod model;
pub mod quant;
