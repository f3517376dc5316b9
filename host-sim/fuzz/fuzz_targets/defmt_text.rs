//! Fuzz target: `host-sim ingest`: the defmt telemetry text (`parse_stream`, `to_log`).
//! The properties checked are in `host-sim/tests/fuzz_support/mod.rs`.
#![no_main]

#[path = "../../tests/fuzz_support/mod.rs"]
mod oracle;

libfuzzer_sys::fuzz_target!(|data: &[u8]| oracle::defmt_text(data));
