//! Adds `-Tdefmt.x` to the target binaries' link only when the `defmt` feature is on.
//! (`-Tlink.x` is in `.cargo/config.toml` for the thumb target; the board's memory
//! layout is the root `memory.x`, which the linker finds in the workspace root.)
fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    // `cfg(fw_dsp_asm)`: the Armv7E-M / Armv8-M Mainline DSP extension is there, so
    // `dsp.rs` uses its SMLAD assembly (stable Rust has no `target_feature = "dsp"`).
    println!("cargo::rustc-check-cfg=cfg(fw_dsp_asm)");
    let target = std::env::var("TARGET").unwrap_or_default();
    if target.starts_with("thumbv7em") || target.starts_with("thumbv8m.main") {
        println!("cargo:rustc-cfg=fw_dsp_asm");
    }
    let bare_metal = std::env::var("CARGO_CFG_TARGET_OS").is_ok_and(|os| os == "none");
    if bare_metal && std::env::var_os("CARGO_FEATURE_DEFMT").is_some() {
        println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    }
}
