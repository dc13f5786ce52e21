//! Adds `-Tdefmt.x` to the target binaries' link only when the `defmt` feature is on.
//! (`-Tlink.x` is in `.cargo/config.toml` for the thumb target; the board's memory
//! layout is the root `memory.x`, which the linker finds in the workspace root.)
fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    let bare_metal = std::env::var("CARGO_CFG_TARGET_OS").is_ok_and(|os| os == "none");
    if bare_metal && std::env::var_os("CARGO_FEATURE_DEFMT").is_some() {
        println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    }
}
