//! Fuzz target: the KUKA wrist readers (`payload::load_run`, `load_static_poses`, `steady_state_noise`).
//! The properties checked are in `host-sim/tests/fuzz_support/mod.rs`.
#![no_main]

#[path = "../../tests/fuzz_support/mod.rs"]
mod oracle;

libfuzzer_sys::fuzz_target!(|data: &[u8]| oracle::kuka(data));
