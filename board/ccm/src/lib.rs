//! Start-up copy of what is linked to live in CCM SRAM: the `.ccmram_text` (code) and
//! `.ccmram_data` (model data) sections of `memory.x` (run address in CCM SRAM, load
//! image in flash). Its own crate so that the board images and the QEMU images
//! (`firmware/qemu`, their own workspace) start the same way from one source; for
//! `thumbv7em-none-eabihf` only (built for the host it is empty).
#![no_std]
#![cfg(target_os = "none")]

unsafe extern "C" {
    static mut __sccmram_text: u32;
    static mut __eccmram_text: u32;
    static __siccmram_text: u32;
    static mut __sccmram_data: u32;
    static mut __eccmram_data: u32;
    static __siccmram_data: u32;
}

/// Copies `.ccmram_text` and `.ccmram_data` from their load images to CCM SRAM. Call
/// first thing in `main`, before any code of that section runs or its data is read.
pub fn copy_code() {
    // SAFETY: `memory.x` defines the six symbols: each section's run addresses
    // [start, end), word aligned, in CCM SRAM where nothing else is placed, and its
    // load image of the same length in flash; none of its code has run and none of its
    // data has been read yet, so nothing reads the words while they are written.
    unsafe {
        let start = &raw mut __sccmram_text;
        let end = &raw mut __eccmram_text;
        let words = (end as usize - start as usize) / 4;
        core::ptr::copy_nonoverlapping(&raw const __siccmram_text, start, words);
        let start = &raw mut __sccmram_data;
        let end = &raw mut __eccmram_data;
        let words = (end as usize - start as usize) / 4;
        core::ptr::copy_nonoverlapping(&raw const __siccmram_data, start, words);
    }
    // The copied words are instructions: complete the writes before fetching them.
    cortex_m::asm::dsb();
    cortex_m::asm::isb();
}
