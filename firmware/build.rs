//! Adds `-Tdefmt.x` to the target binaries' link only when the `defmt` feature is on.
//! (`-Tlink.x` is in `.cargo/config.toml` for the thumb target; the board's memory
//! layout is the root `memory.x`, which the linker finds in the workspace root.)
fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    // `cfg(fw_dsp_asm)`: the Armv7E-M / Armv8-M Mainline DSP extension is there, so
    // `dsp.rs` uses its SMLAD assembly (stable Rust has no `target_feature = "dsp"`).
    println!("cargo::rustc-check-cfg=cfg(fw_dsp_asm)");
    // The compiled-in model: `FIRMWARE_MODEL` (a generated file) or the committed default.
    println!("cargo:rerun-if-env-changed=FIRMWARE_MODEL");
    let dir = std::env::var("CARGO_MANIFEST_DIR").unwrap_or_default();
    let model = match std::env::var("FIRMWARE_MODEL") {
        Ok(p) if !p.is_empty() => std::path::Path::new(&p).canonicalize().unwrap_or_else(|e| {
            println!("cargo:warning=FIRMWARE_MODEL={p}: {e}");
            std::process::exit(1)
        }),
        _ => std::path::Path::new(&dir).join("src/model/default_model.rs"),
    };
    println!("cargo:rerun-if-changed={}", model.display());
    println!("cargo:rustc-env=FIRMWARE_MODEL_PATH={}", model.display());
    let target = std::env::var("TARGET").unwrap_or_default();
    if target.starts_with("thumbv7em") || target.starts_with("thumbv8m.main") {
        println!("cargo:rustc-cfg=fw_dsp_asm");
    }
    let bare_metal = std::env::var("CARGO_CFG_TARGET_OS").is_ok_and(|os| os == "none");
    if bare_metal && std::env::var_os("CARGO_FEATURE_DEFMT").is_some() {
        println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    }
}
