//! Host-side simulator and tools for the cable-joint core.

pub mod cli;
pub mod derive;
pub mod estimate;
pub mod gdb_rtt;
pub mod ident;
pub mod import;
pub mod ingest;
pub mod io;
pub mod links;
pub mod live;
pub mod log;
pub mod operator;
pub mod output;
pub mod payload;
pub mod pil;
pub mod plant;
pub mod plot;
pub mod report;
pub mod residual;
pub mod scenario;
pub mod sim;
pub mod stats;
pub mod trace;
pub mod wrist;
pub mod wrist_estimate;
pub mod wrist_log;
