//! Host side of the joint feedforward: everything from robot description and logs
//! to the fixed-size arrays the firmware compiles in.
#![deny(unsafe_code)] // one exception: nn::gemm (a checked wrapper around sgemm)
#![warn(missing_docs)]

pub mod base;
pub mod cli;
pub mod demo;
pub mod dynamics;
pub mod excite;
pub mod export;
pub mod fuzz;
pub mod identify;
pub mod logs;
pub mod model_file;
pub mod nn;
pub mod robot;
pub mod sil;
pub mod sim;
