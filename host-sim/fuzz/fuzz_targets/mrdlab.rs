//! Fuzz target: the MRDLab importer (`read_mrdlab`).
//! The properties checked are in `host-sim/tests/fuzz_support/mod.rs`.
#![no_main]

#[path = "../../tests/fuzz_support/mod.rs"]
mod oracle;

libfuzzer_sys::fuzz_target!(|data: &[u8]| oracle::mrdlab(data));
