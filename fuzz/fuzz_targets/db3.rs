#![no_main]
//! `model_export::fuzz::db3_target` under libFuzzer.
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    model_export::fuzz::db3_target(data);
});
