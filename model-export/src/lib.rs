//! Host side of the joint feedforward: everything from robot description and logs
//! to the fixed-size arrays the firmware compiles in.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod cli;
pub mod sim;
