//! Adds `-Tdefmt.x` to the board bench binary's link when the `defmt` feature is on
//! (as `firmware/build.rs` does for the firmware's binaries).
fn main() {
    let bare_metal = std::env::var("CARGO_CFG_TARGET_OS").is_ok_and(|os| os == "none");
    if bare_metal && std::env::var_os("CARGO_FEATURE_DEFMT").is_some() {
        println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    }
}
