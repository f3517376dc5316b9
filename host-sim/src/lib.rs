//! Host-side simulator and tools for the cable-joint core.

pub mod import;
pub mod log;
