#![no_main]
//! `model_export::fuzz::log_csv_target` under libFuzzer (one scratch folder per process).
use libfuzzer_sys::fuzz_target;
use std::sync::LazyLock;

static DIR: LazyLock<tempfile::TempDir> =
    LazyLock::new(|| tempfile::tempdir().expect("a scratch folder"));

fuzz_target!(|data: &[u8]| {
    model_export::fuzz::log_csv_target(DIR.path(), data);
});
