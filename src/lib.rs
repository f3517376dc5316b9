#![doc = include_str!("../README.md")]
#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod config;
pub mod controller;
pub mod dob;
pub mod effects;
pub mod fault;
pub mod filter;
pub mod jae;
pub mod cascade;
pub mod lsq;
pub mod math;
pub mod trajectory;
pub mod units;

pub use config::{Config, ConfigError};

pub use fault::Fault;
