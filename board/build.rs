//! Links the board binaries: the board's memory layout `memory.x` (next to this file)
//! on the linker's search path for cortex-m-rt's `link.x` (`-Tlink.x` is in
//! `.cargo/config.toml` for the thumb target), and `-Tdefmt.x` when the `defmt`
//! feature is on.
fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=memory.x");
    let bare_metal = std::env::var("CARGO_CFG_TARGET_OS").is_ok_and(|os| os == "none");
    if !bare_metal {
        return;
    }
    let dir = std::env::var("CARGO_MANIFEST_DIR").unwrap_or_default();
    println!("cargo:rustc-link-search={dir}");
    if std::env::var_os("CARGO_FEATURE_DEFMT").is_some() {
        println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    }
}
