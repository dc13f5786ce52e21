//! One module per subcommand, in pipeline order: each holds the subcommand's options
//! (clap) and the function that runs it through the stage libraries.
pub mod demo;
pub mod evaluate;
pub mod excite;
pub mod export;
pub mod identify;
pub mod import;
pub mod provision;
pub mod sil;
pub mod simulate;
pub mod telemetry;
pub mod train;
