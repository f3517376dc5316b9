#![doc = include_str!("../README.md")]
#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

#[cfg(test)]
extern crate std;

pub mod board;
pub mod cascade;
pub mod config;
pub mod controller;
pub mod dob;
pub mod effects;
pub mod fault;
pub mod filter;
pub mod fusion;
pub mod jae;
#[cfg(feature = "link")]
pub mod link;
pub mod lsq;
pub mod math;
pub mod model;
pub mod payload;
pub mod probe;
pub mod telemetry;
pub mod trajectory;
pub mod units;

pub use controller::{
    Command, Controller, Estimates, Mode, Output, PreparedConfig, RawSample, Stage, StageTimer,
};

pub use config::{Config, ConfigError};

pub use fault::Fault;
