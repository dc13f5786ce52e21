//! Option groups shared by several subcommands.
pub mod choice;
pub mod joints;
pub mod logs;
pub mod renamed;
pub mod robot;
