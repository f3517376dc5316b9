//! Settings of the identification.

use anyhow::{bail, Result};
use serde::Serialize;

/// Settings of the identification.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct IdentOptions {
    /// Leading time of every log left out (observer start-up), s.
    pub skip_start_s: f64,
    /// Tension fits: leave out ticks with `|theta'|` below this, rad/s
    /// (0 keeps every tick).
    pub min_joint_vel_rad_s: f64,
    /// Tension fits: also leave out this long after a tick below
    /// [`Self::min_joint_vel_rad_s`], s.
    pub holdoff_s: f64,
    /// Pass the regressors of the DOB-based fits (`B_m`, tension) through the
    /// DOB's own low-pass `Q` (see the module documentation).
    pub filter_regressors: bool,
    /// Pruning limit on `%sigma`, % (seed: 5).
    pub max_pct_sigma: f64,
    /// Pruning as the seed did: drop every parameter above the limit at
    /// once. Default (`false`): one at a time, the worst first, refitting
    /// after each drop, so that of a collinear group (the three friction
    /// signs agree whenever the joint moves) one member is kept.
    pub prune_all_at_once: bool,
    /// DOB-based fits: an extra first-order low-pass at this frequency, Hz,
    /// on both sides of the regression (0 = none).
    pub post_filter_hz: f64,
    /// Fit a Coulomb term `sgn(phi')` next to `B_m` (brushes and gearhead);
    /// it is dropped again if its `%sigma` exceeds [`Self::max_pct_sigma`].
    pub bm_coulomb: bool,
    /// Largest accepted condition number of the equilibrated regressor matrix.
    pub max_condition: f64,
}

impl Default for IdentOptions {
    fn default() -> Self {
        Self {
            skip_start_s: 0.2,
            min_joint_vel_rad_s: 0.05,
            holdoff_s: 0.0,
            filter_regressors: true,
            max_pct_sigma: 5.0,
            prune_all_at_once: false,
            post_filter_hz: 0.0,
            bm_coulomb: true,
            max_condition: 1e10,
        }
    }
}

impl IdentOptions {
    pub(crate) fn check(&self) -> Result<()> {
        if !(self.skip_start_s.is_finite() && self.skip_start_s >= 0.0) {
            bail!("skip_start_s must be finite and >= 0");
        }
        if !(self.min_joint_vel_rad_s.is_finite() && self.min_joint_vel_rad_s >= 0.0) {
            bail!("min_joint_vel_rad_s must be finite and >= 0");
        }
        if !(self.holdoff_s.is_finite() && self.holdoff_s >= 0.0) {
            bail!("holdoff_s must be finite and >= 0");
        }
        if !(self.post_filter_hz.is_finite() && self.post_filter_hz >= 0.0) {
            bail!("post_filter_hz must be finite and >= 0");
        }
        if !(self.max_pct_sigma.is_finite() && self.max_pct_sigma > 0.0) {
            bail!("max_pct_sigma must be finite and > 0");
        }
        if self.max_condition.is_nan() || self.max_condition <= 1.0 {
            bail!("max_condition must be > 1");
        }
        Ok(())
    }
}
