#![doc = include_str!("../README.md")]
//!
//! ## Module map
//!
//! * [`control`], the control path, runs every tick in [`Controller::step`]:
//!   [`controller`] (the step, sensing and faults), [`filter`], [`jae`],
//!   [`model`] and [`effects`] (the effect terms added to the JAE and the
//!   tension model), [`dob`], [`fusion`], [`trajectory`], [`grip`],
//!   [`probe`], [`cascade`].
//! * [`ident`], the identification helpers (`no_std` too), called by the
//!   host tools and never in the tick: [`lsq`] (least squares), [`payload`]
//!   (seed 001's tool-end estimator).
//! * Shared by both, the firmware and the host tools: [`config`] (the
//!   configuration and its `validate()`), [`fault`] (stable fault codes),
//!   [`units`] (raw codes to SI), [`math`] (every transcendental function),
//!   [`telemetry`] (the defmt record and its parser), `link` (the host
//!   link's wire format, feature `link`), [`rtt`] (the firmware's RTT
//!   block as a probe sees it, and the ring arithmetic both ends share).
//! * [`board`]: the firmware's logic behind embedded-hal traits.
//!
//! The modules of [`control`] and [`ident`] are also re-exported at the root
//! under their names from before the grouping (`cable_joint::dob`,
//! `cable_joint::lsq`).
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
pub mod rtt;
pub mod telemetry;
#[cfg(test)]
mod test_rng;
pub mod units;

// The paths from before the grouping, kept: `crate::dob` is `control::dob`,
// `crate::lsq` is `ident::lsq`.
pub use control::{
    cascade, controller, dob, effects, filter, fusion, grip, jae, joints, model, probe, trajectory,
    wrist, wrist_dynamics,
};
pub use ident::{lsq, payload};

pub use controller::{
    Command, Controller, Estimates, Mode, Output, PreparedConfig, RawSample, Stage, StageTimer,
};

pub use config::{Config, ConfigError};

pub use fault::Fault;
