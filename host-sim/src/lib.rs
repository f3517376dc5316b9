//! Host-side simulator and tools for the cable-joint core.
