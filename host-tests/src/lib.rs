//! Host-side proof for the firmware: builds the target binaries, runs the QEMU one,
//! and compares what the target computed with the same firmware functions on the
//! host, bit for bit.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod budget;
pub mod compare;
pub mod cycles;
pub mod disasm;
pub mod elf;
pub mod golden;
pub mod memory;
pub mod qemu;
pub mod target;
pub mod trace;
