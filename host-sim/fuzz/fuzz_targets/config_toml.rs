//! Fuzz target: the TOML configuration loaders and the plant parameters' parser.
//! The properties checked are in `host-sim/tests/fuzz_support/mod.rs`.
#![no_main]

#[path = "../../tests/fuzz_support/mod.rs"]
mod oracle;

libfuzzer_sys::fuzz_target!(|data: &[u8]| oracle::config_toml(data));
