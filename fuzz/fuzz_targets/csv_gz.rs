//! Fuzz target: gzip-compressed CSV logs (see `check_csv_gz`).
#![no_main]

include!("../checks.rs");

libfuzzer_sys::fuzz_target!(|data: &[u8]| check_csv_gz(data));
