//! Fuzz target: the firmware's sensor trace (`Trace::parse`) and its replay.
//! The properties checked are in `host-sim/tests/fuzz_support/mod.rs`.
#![no_main]

#[path = "../../tests/fuzz_support/mod.rs"]
mod oracle;

libfuzzer_sys::fuzz_target!(|data: &[u8]| oracle::trace(data));
