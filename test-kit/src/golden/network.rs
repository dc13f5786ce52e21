//! Golden inputs of the quantised networks' self-check and of the QEMU suites: the
//! firmware's self-check stream and digest (`firmware::model::self_check`, the one source
//! the exporter uses too), and the suites' length.
pub use firmware::model::self_check::{Digest, input, inputs};

/// Streaming steps of the bit-exact suites (host vs QEMU).
pub const STEPS: usize = 10_000;
