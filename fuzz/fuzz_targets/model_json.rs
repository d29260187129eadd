//! Fuzz target: drift model files (see `check_model_json`).
#![no_main]

include!("../checks.rs");

libfuzzer_sys::fuzz_target!(|data: &[u8]| check_model_json(data));
