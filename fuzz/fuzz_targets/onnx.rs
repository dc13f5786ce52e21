#![no_main]
//! `model_export::fuzz::onnx_target` under libFuzzer (corpus: any of `corpus/onnx_*`).
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| model_export::fuzz::onnx_target(data));
