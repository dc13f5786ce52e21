//! Option groups shared by several subcommands.
pub mod choice;
pub mod logs;
pub mod robot;
