//! Fuzz target: recordings replayed by `ingest.mcap` (see `check_recording`).
#![no_main]

include!("../checks.rs");

libfuzzer_sys::fuzz_target!(|data: &[u8]| check_recording(data));
