//! The `model-export` command line: one subcommand per pipeline stage, each parsing its
//! options and running the stage libraries (`robot`, `excitation`, `plant-sim`, `logs`,
//! `identify`, `compnet`, `fw-export`, `sil`). The only crate that parses arguments.
#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod args;
pub mod cli;
pub mod cmd;
pub mod fuzz;
