//! Links with the board's own memory layout (`board/memory.x`: 508 KiB image, the
//! configuration page, CCM SRAM and its `.ccmram_text` section), so that both builds
//! place code and data alike.
fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=../memory.x");
    let dir = std::env::var("CARGO_MANIFEST_DIR").unwrap_or_default();
    println!("cargo:rustc-link-search={dir}/..");
}
