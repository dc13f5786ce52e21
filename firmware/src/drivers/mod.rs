//! Peripheral drivers behind embedded-hal 1.0 traits (host-tested with mocks).

pub mod as5047p;
pub mod drv83x3;
