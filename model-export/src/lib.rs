//! Host side of the joint feedforward: everything from robot description and logs
//! to the fixed-size arrays the firmware compiles in.
#![deny(unsafe_code)] // one exception: nn::gemm (a checked wrapper around sgemm)
#![warn(missing_docs)]

pub mod cli;
pub mod nn;
