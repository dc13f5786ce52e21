//! The firmware's test kit: what the bit-exact suites and the cycle budgets run the
//! firmware on, kept out of the product.
//!
//! `no_std`, no heap, built for the host (the host side of the bit-exact comparison,
//! the exporter's self-check) and for the target (the QEMU test and bench binaries,
//! the board bench binary): [`golden`] the deterministic golden inputs, [`fixtures`]
//! the fixture models, [`bench`](mod@bench) the per-tick workloads of the cycle budgets,
//! [`proof`] the training envelope's proof on a compiled-in trained model.
#![cfg_attr(not(test), no_std)]
#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod bench;
pub mod fixtures;
pub mod golden;
pub mod proof;
