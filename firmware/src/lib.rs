//! Per-joint torque feedforward for a collaborative robot's joint drives.
//!
//! `no_std`, no heap. Every numeric function here is the single source of truth:
//! the host exporter and the tests call the same code that runs on the MCU, and
//! `host-tests` proves the results are bit-identical on both. The modules in data-flow
//! order: numerics (`math`, `dsp`), the rigid-body model (`dynamics`), the drive's
//! features (`features`), the training envelope (`envelope`), the network (`nn`), the online friction adaptation
//! (`adaptation`), the do-no-harm monitor (`monitor`), the compiled-in model (`model`), the
//! control loop (`control`), the encoder driver (`drivers`) and logging (`log`).
#![cfg_attr(not(test), no_std)]
#![deny(unsafe_code)]
#![warn(missing_docs)]

// Generated model files name the firmware as `firmware::...`, so that the same text
// compiles here (the default model) and in crates that depend on the firmware.
extern crate self as firmware;

pub mod adaptation;
pub mod control;
pub mod drivers;
pub mod dsp;
pub mod dynamics;
pub mod envelope;
pub mod features;
pub mod log;
pub mod math;
pub mod model;
pub mod monitor;
pub mod nn;
