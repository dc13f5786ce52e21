//! Logging shim: forwards to `defmt` when the `defmt` feature is on and compiles to
//! nothing otherwise, so host builds never need a defmt logger.

#[cfg(feature = "defmt")]
pub use defmt;

/// Info-level log message (defmt syntax); a no-op without the `defmt` feature.
#[cfg(feature = "defmt")]
#[macro_export]
macro_rules! fw_info { ($($arg:tt)*) => { $crate::log::defmt::info!($($arg)*) }; }
/// Info-level log message (defmt syntax); a no-op without the `defmt` feature.
#[cfg(not(feature = "defmt"))]
#[macro_export]
macro_rules! fw_info {
    ($($arg:tt)*) => {{}};
}

/// Warning-level log message (defmt syntax); a no-op without the `defmt` feature.
#[cfg(feature = "defmt")]
#[macro_export]
macro_rules! fw_warn { ($($arg:tt)*) => { $crate::log::defmt::warn!($($arg)*) }; }
/// Warning-level log message (defmt syntax); a no-op without the `defmt` feature.
#[cfg(not(feature = "defmt"))]
#[macro_export]
macro_rules! fw_warn {
    ($($arg:tt)*) => {{}};
}

/// Error-level log message (defmt syntax); a no-op without the `defmt` feature.
#[cfg(feature = "defmt")]
#[macro_export]
macro_rules! fw_error { ($($arg:tt)*) => { $crate::log::defmt::error!($($arg)*) }; }
/// Error-level log message (defmt syntax); a no-op without the `defmt` feature.
#[cfg(not(feature = "defmt"))]
#[macro_export]
macro_rules! fw_error {
    ($($arg:tt)*) => {{}};
}
