#![no_main]
//! `model_export::fuzz::rosbag2_folder_target` under libFuzzer.
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    model_export::fuzz::rosbag2_folder_target(data);
});
