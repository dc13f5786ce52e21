//! The per-board configuration block: the last 2 KiB of flash (`BOARD_CONFIG` in
//! `memory.x`, in the last 4 KiB page of the single-bank flash, which the image never
//! covers, so flashing new firmware keeps it), read at
//! start-up; its layout and the decision are `firmware::control::startup`.
//! (`unsafe`: the read of the page through its linker-script address.)

use firmware::control::JointConfigBlock;

unsafe extern "C" {
    /// First byte of the configuration page (`memory.x`).
    static __board_config: [u8; JointConfigBlock::LEN];
}

/// The block's bytes as they are in flash (0xFF where the page is erased).
pub fn read() -> [u8; JointConfigBlock::LEN] {
    // SAFETY: `memory.x` places `__board_config` at the start of the BOARD_CONFIG
    // region, 2 KiB of flash that nothing in the image writes: always readable, and
    // a volatile read takes whatever bytes a programmer put there.
    unsafe { core::ptr::read_volatile(&raw const __board_config) }
}
