#![no_main]
//! `model_export::fuzz::budget_toml_target` under libFuzzer (one scratch folder per process).
use libfuzzer_sys::fuzz_target;
use std::sync::LazyLock;

static DIR: LazyLock<tempfile::TempDir> =
    LazyLock::new(|| tempfile::tempdir().expect("a scratch folder"));

fuzz_target!(|data: &[u8]| {
    model_export::fuzz::budget_toml_target(DIR.path(), data);
    // The budget tool's own reader of the same file.
    let _ = host_tests::budget::Budgets::load(&DIR.path().join("budgets.toml"));
});
