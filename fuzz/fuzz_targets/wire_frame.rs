#![no_main]
//! `model_export::fuzz::wire_frame_target` under libFuzzer.
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| model_export::fuzz::wire_frame_target(data));
