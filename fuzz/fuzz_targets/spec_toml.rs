#![no_main]

#[path = "../harness/jobs.rs"]
mod harness;

libfuzzer_sys::fuzz_target!(|data: &[u8]| harness::spec_toml(data));
