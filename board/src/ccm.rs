//! Start-up copy of the code linked to run from CCM SRAM: the `.ccmram_text`
//! section of `memory.x` (run address in CCM SRAM, load image in flash).

unsafe extern "C" {
    static mut __sccmram_text: u32;
    static mut __eccmram_text: u32;
    static __siccmram_text: u32;
}

/// Copies `.ccmram_text` from its load image to CCM SRAM. Call first thing in
/// `main`, before any code of that section runs.
pub fn copy_code() {
    // SAFETY: `memory.x` defines the three symbols: the section's run addresses
    // [__sccmram_text, __eccmram_text), word aligned, in CCM SRAM where nothing else
    // is placed, and its load image of the same length at __siccmram_text; none of
    // its code has run yet, so nothing reads the words while they are written.
    unsafe {
        let start = &raw mut __sccmram_text;
        let end = &raw mut __eccmram_text;
        let words = (end as usize - start as usize) / 4;
        core::ptr::copy_nonoverlapping(&raw const __siccmram_text, start, words);
    }
    // The copied words are instructions: complete the writes before fetching them.
    cortex_m::asm::dsb();
    cortex_m::asm::isb();
}
