//! Fuzz target: CSV logs, fast reader against the reference reader (see `check_csv`).
#![no_main]

include!("../checks.rs");

libfuzzer_sys::fuzz_target!(|data: &[u8]| check_csv(data));
