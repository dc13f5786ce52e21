//! The LSTM compensation network on the host: datasets, candle training with a fused
//! LSTM op, PyTorch safetensors interchange, and evaluation through the firmware step.
#![deny(unsafe_code)] // one exception: gemm (a checked wrapper around sgemm)
#![warn(missing_docs)]
pub mod adaptation;
pub mod baseline;
pub mod data;
pub mod envelope;
pub mod eval;
pub mod fused;
pub mod fused_net;
pub mod gemm;
pub mod io;
pub mod model;
pub mod monitor;
pub mod onnx;
pub mod plot;
pub mod report;
pub mod train;

pub use model::{LstmModel, Net, Streamer};

pub use artifacts::write_atomic;
