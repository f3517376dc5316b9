//! Host-side simulator and tools for the cable-joint core.

pub mod derive;
pub mod import;
pub mod log;
