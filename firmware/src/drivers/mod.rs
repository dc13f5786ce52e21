//! Peripheral drivers behind embedded-hal 1.0 traits.
