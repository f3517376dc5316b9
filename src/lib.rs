#![doc = include_str!("../README.md")]
#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

#[cfg(test)]
extern crate std;

pub mod board;
pub mod config;
pub mod control;
pub mod fault;
pub mod ident;
#[cfg(feature = "link")]
pub mod link;
pub mod math;
pub mod telemetry;
pub mod units;

// The paths from before the grouping, kept: `crate::dob` is `control::dob`,
// `crate::lsq` is `ident::lsq`.
pub use control::{
    cascade, controller, dob, effects, filter, fusion, jae, model, probe, trajectory,
};
pub use ident::{lsq, payload};

pub use controller::{
    Command, Controller, Estimates, Mode, Output, PreparedConfig, RawSample, Stage, StageTimer,
};

pub use config::{Config, ConfigError};

pub use fault::Fault;
