//! Writes the activation tables (`nn::act`) to `OUT_DIR`, selects the DSP assembly and
//! the compiled-in model. (The board binaries' link set-up is the `board` crate's.)
/// Entries of each activation table (`nn::act::TABLE_LEN`).
const TABLE_LEN: i32 = 8192;

/// `round(f((k - 4096 + 0.5) / 512) * 32768)` clamped to `lo..=32767`, `k = 0..8192`: the
/// value at each interval's midpoint, by `libm` (the same bits on every build machine).
fn table(f: fn(f64) -> f64, lo: i32) -> String {
    let mut s = String::from("[");
    for k in 0..TABLE_LEN {
        let x = (k - TABLE_LEN / 2) as f64 / 512.0 + 1.0 / 1024.0;
        let v = (libm::round(f(x) * 32768.0) as i32).clamp(lo, 32767);
        s.push_str(&v.to_string());
        s.push(',');
    }
    s.push(']');
    s
}

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    let out = std::env::var("OUT_DIR").unwrap_or_default();
    let sigmoid = |x: f64| 1.0 / (1.0 + libm::exp(-x));
    let tables = format!(
        "/// The tables' values, [sigmoid, tanh], see `nn::act`: the one definition of the two\n/// statics that hold them (a `const` only ever read at compile time).\n#[allow(clippy::large_const_arrays)]\npub const ACT_TABLE_VALUES: [[i16; {TABLE_LEN}]; 2] = [{}, {}];\n",
        table(sigmoid, 0),
        table(libm::tanh, -32767)
    );
    if let Err(e) = std::fs::write(std::path::Path::new(&out).join("act_tables.rs"), tables) {
        println!("cargo:warning=act_tables.rs: {e}");
        std::process::exit(1)
    }
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
}
