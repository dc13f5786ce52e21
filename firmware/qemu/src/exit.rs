//! How both QEMU binaries end: through semihosting, success or failure; a panic or a
//! HardFault prints one `@panic` / `@hardfault` line and exits with failure.
use core::fmt::Write;
use cortex_m_rt::{ExceptionFrame, exception};
use cortex_m_semihosting::{debug, hio};

/// Exits QEMU with failure.
pub fn fail() -> ! {
    exit(debug::EXIT_FAILURE)
}

/// Exits QEMU with success.
pub fn pass() -> ! {
    exit(debug::EXIT_SUCCESS)
}

fn exit(status: debug::ExitStatus) -> ! {
    debug::exit(status);
    loop {
        cortex_m::asm::bkpt();
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    if let Ok(mut host) = hio::hstdout() {
        let _ = writeln!(host, "@panic {info}");
    }
    fail()
}

#[exception]
unsafe fn HardFault(frame: &ExceptionFrame) -> ! {
    if let Ok(mut host) = hio::hstdout() {
        let _ = writeln!(host, "@hardfault pc={:#010x}", frame.pc());
    }
    fail()
}
