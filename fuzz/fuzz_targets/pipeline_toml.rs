//! Fuzz target: pipeline files (see `check_pipeline_toml`).
#![no_main]

include!("../checks.rs");

libfuzzer_sys::fuzz_target!(|data: &[u8]| check_pipeline_toml(data));
