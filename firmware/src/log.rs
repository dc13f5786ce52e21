//! Logging shim: forwards to `defmt` when the `defmt` feature is on and compiles to
//! nothing otherwise, so host builds never need a defmt logger; [`TickStats`], the
//! per-tick cycle statistics the board reports.

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

/// Per-tick cycle statistics (min, max, mean) over a reporting window (DWT CYCCNT
/// cycles): the board keeps one for its compensator tick, the board bench binary one
/// per workload, and both report them over defmt.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TickStats {
    /// Fewest cycles of one tick in the window.
    pub min_cycles: u32,
    /// Most cycles of one tick in the window.
    pub max_cycles: u32,
    /// Sum of the window's cycles (u64: no overflow for 2^32 ticks of 2^32 cycles).
    pub sum_cycles: u64,
    /// Ticks in the window.
    pub ticks: u32,
}

impl Default for TickStats {
    fn default() -> Self {
        Self::new()
    }
}

impl TickStats {
    /// An empty window.
    pub const fn new() -> Self {
        TickStats {
            min_cycles: u32::MAX,
            max_cycles: 0,
            sum_cycles: 0,
            ticks: 0,
        }
    }

    /// Adds one tick's cycles.
    pub fn record(&mut self, cycles: u32) {
        self.min_cycles = self.min_cycles.min(cycles);
        self.max_cycles = self.max_cycles.max(cycles);
        self.sum_cycles += u64::from(cycles);
        self.ticks = self.ticks.saturating_add(1);
    }

    /// Mean cycles per tick (rounded down); 0 for an empty window.
    pub fn mean_cycles(&self) -> u32 {
        match self.ticks {
            0 => 0,
            n => (self.sum_cycles / u64::from(n)) as u32,
        }
    }

    /// Returns the window's statistics and starts a new one.
    pub fn take(&mut self) -> TickStats {
        core::mem::take(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_stats_min_max_mean() {
        let mut s = TickStats::new();
        assert_eq!(s.mean_cycles(), 0);
        for c in [10, 30, 20] {
            s.record(c);
        }
        assert_eq!(
            (s.min_cycles, s.max_cycles, s.mean_cycles(), s.ticks),
            (10, 30, 20, 3)
        );
        let old = s.take();
        assert_eq!(old.ticks, 3);
        assert_eq!(s, TickStats::new());
    }
}
