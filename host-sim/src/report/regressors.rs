//! Model outputs over a whole log, for the figures of the identified models
//! (seed Figs. 14-17): the log is replayed through the core
//! ([`crate::derive::TickReplay`]) and each regressor column is built from the
//! replay's signals the way [`crate::ident`] builds its design (held signs
//! with the configuration's switching speeds, the joint angle's velocity
//! and acceleration from the core's tracking observer, every column of a
//! DOB-based model through the DOB's `Q`). The identified numbers
//! themselves come from [`crate::ident`]; this only draws them.

use anyhow::Result;

use cable_joint::Config;

use crate::ident::{FitReport, IdentOptions, Prepared};
use crate::log::Log;

/// A replayed log ready to evaluate models on: [`crate::ident`]'s own
/// replay, so the figures draw exactly the columns the fit used.
pub struct Replay {
    p: Prepared,
}

impl Replay {
    /// Replay `log` with `config`.
    pub fn new(log: &Log, config: &Config) -> Result<Self> {
        let p = Prepared::new("log", log, config, &IdentOptions::default())?;
        // The derived log always carries `theta_hat_rad`: the joint angle
        // and its kinematics exist.
        p.theta_kin()?;
        Ok(Self { p })
    }

    /// Time, s.
    pub fn t_s(&self) -> Result<&[f64]> {
        self.p.t_s()
    }

    /// A column of the replay.
    pub fn col(&self, name: &str) -> Result<Vec<f64>> {
        self.p.col(name)
    }

    /// The DOB's low-pass `Q` over a column (state starts at its first value).
    pub fn dob_filter(&self, col: &[f64]) -> Vec<f64> {
        self.p.dob_filter(col)
    }

    /// A fitted model's output on every tick: `sum value_k column_k`, each
    /// column through `Q` when `filtered` (the DOB-based models).
    pub fn predict(&self, fit: &FitReport, filtered: bool, jae: bool) -> Result<Vec<f64>> {
        let mut out = vec![0.0; self.t_s()?.len()];
        for p in &fit.params {
            let c = self.p.regressor_column(p.regressor, jae)?;
            let c = if filtered { self.dob_filter(&c) } else { c };
            for (o, v) in out.iter_mut().zip(&c) {
                *o += p.value * v;
            }
        }
        Ok(out)
    }

    /// The no-load motor's torque balance `Q[K_m i - J_m phi'']`, N·m (what
    /// `B_m` is fitted to): the DOB's load torque plus `B Q[phi']`.
    pub fn motor_torque_nm(&self) -> Result<Vec<f64>> {
        let b = f64::from(self.p.config().dob.viscous_nm_s_rad);
        let vel = self.dob_filter(&self.col("phi_vel_rad_s")?);
        Ok(self
            .col("load_torque_nm")?
            .iter()
            .zip(&vel)
            .map(|(tau, w)| tau + b * w)
            .collect())
    }

    /// The magnetic encoder, rad (or the JAE when the log has none).
    pub fn theta_rad(&self) -> &[f64] {
        self.p.theta().map_or(&[], Vec::as_slice)
    }

    /// Joint speed from the magnetic encoder through the tracking observer, rad/s.
    pub fn theta_vel_rad_s(&self) -> &[f64] {
        self.p.theta_kin().map_or(&[], |k| k.0.as_slice())
    }
}
