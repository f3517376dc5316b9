//! Identification helpers: `no_std`, but not on the control path. Nothing in
//! [`Controller::step`](crate::Controller::step) or the board layer calls
//! them; the host tools do (identification, the residual loop, `payload`).
//!
//! * [`lsq`]: least squares, a streaming batch solver with parameter standard
//!   deviations (`f64`) and recursive least squares with forgetting (`f32`);
//! * [`payload`]: seed 001's tool payload identification and tool-end wrench
//!   estimator for a wrist force/torque sensor, on [`lsq`] and the effect
//!   terms of [`crate::control::effects`].
//!
//! Each module is also re-exported at the crate root under its name
//! (`cable_joint::lsq` is `cable_joint::ident::lsq`), so the paths used
//! before this grouping still work.

pub mod lsq;
pub mod payload;
