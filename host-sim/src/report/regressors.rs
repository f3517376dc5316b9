//! Model outputs over a whole log, for the figures of the identified models
//! (seed Figs. 14-17): the log is replayed through the core
//! ([`crate::derive::derive`]) and each regressor column is built from the
//! replay's signals the way [`crate::ident`] builds its design (held signs
//! with the configuration's switching speeds, the joint angle's velocity
//! and acceleration from the core's tracking observer, every column of a
//! DOB-based model through the DOB's `Q`). The identified numbers
//! themselves come from [`crate::ident`]; this only draws them.

use anyhow::{anyhow, Result};
use cable_joint::filter::{Kinematics, LowPass1, SignMemory, TrackingObserver};
use cable_joint::Config;

use crate::derive::{config_for_log, derive};
use crate::ident::{FitReport, Regressor};
use crate::log::Log;

/// A replayed log ready to evaluate models on.
pub struct Replay {
    /// The replay (core signals and estimates).
    pub derived: Log,
    cfg: Config,
    theta: Vec<f64>,
    theta_vel: Vec<f64>,
    theta_acc: Vec<f64>,
}

impl Replay {
    /// Replay `log` with `config`.
    pub fn new(log: &Log, config: &Config) -> Result<Self> {
        let cfg = config_for_log(log, config)?;
        let derived = derive(log, config)?;
        let theta: Vec<f64> = match derived.col_opt("theta_rad") {
            Some(v) if v.iter().all(Option::is_some) => v.into_iter().flatten().collect(),
            _ => derived.col_required("theta_hat_rad")?.to_vec(),
        };
        let obs = TrackingObserver::new(cfg.differentiators.grating_bandwidth_hz, cfg.period_s());
        let mut st = Kinematics::default();
        obs.reset(&mut st, theta.first().copied().unwrap_or(0.0) as f32);
        let (mut theta_vel, mut theta_acc) = (Vec::new(), Vec::new());
        for x in &theta {
            let k = obs.update(&mut st, *x as f32);
            theta_vel.push(f64::from(k.vel));
            theta_acc.push(f64::from(k.acc));
        }
        Ok(Self {
            derived,
            cfg,
            theta,
            theta_vel,
            theta_acc,
        })
    }

    /// Time, s.
    pub fn t_s(&self) -> Result<&[f64]> {
        Ok(self.derived.time_s()?)
    }

    /// A column of the replay.
    pub fn col(&self, name: &str) -> Result<Vec<f64>> {
        Ok(self
            .derived
            .col(name)
            .ok_or_else(|| anyhow!("replay has no column `{name}`"))?
            .to_vec())
    }

    fn signs(vel: &[f64], switch_speed: f32) -> Vec<f64> {
        let sm = SignMemory { switch_speed };
        let mut s = 0.0f32;
        vel.iter()
            .map(|v| f64::from(sm.update(&mut s, *v as f32)))
            .collect()
    }

    /// The raw column of `r`; `jae`: the JAE's switching speed for
    /// `sgn(x2')` (else the tension model's).
    pub fn column(&self, r: Regressor, jae: bool) -> Result<Vec<f64>> {
        let c = &self.cfg;
        Ok(match r {
            Regressor::ThetaVel => self.theta_vel.clone(),
            Regressor::ThetaAcc => self.theta_acc.clone(),
            Regressor::SgnThetaVel => Self::signs(
                &self.theta_vel,
                c.tension.sign_switch_x2_m_s / c.machine.pulley_radius_m,
            ),
            Regressor::Theta => self.theta.clone(),
            Regressor::X1Acc => self.col("x1_acc_m_s2")?,
            Regressor::X1Vel => self.col("x1_vel_m_s")?,
            Regressor::SgnX1Vel => {
                Self::signs(&self.col("x1_vel_m_s")?, c.tension.sign_switch_x1_m_s)
            }
            Regressor::X1 => self.col("x1_m")?,
            Regressor::X2Acc => self.col("x2_acc_m_s2")?,
            Regressor::X2Vel => self.col("x2_vel_m_s")?,
            Regressor::SgnX2Vel => {
                let sw = if jae {
                    c.jae.sign_switch_m_s
                } else {
                    c.tension.sign_switch_x2_m_s
                };
                Self::signs(&self.col("x2_vel_m_s")?, sw)
            }
            Regressor::X2 => self.col("x2_m")?,
            Regressor::PhiVel => self.col("phi_vel_rad_s")?,
            Regressor::SgnPhiVel => Self::signs(
                &self.col("phi_vel_rad_s")?,
                c.tension.sign_switch_x1_m_s * c.machine.motor_rad_per_cable_m(),
            ),
            Regressor::One => vec![1.0; self.derived.len()],
        })
    }

    /// The DOB's low-pass `Q` over a column (state starts at its first value).
    pub fn dob_filter(&self, col: &[f64]) -> Vec<f64> {
        let lp = LowPass1::new(self.cfg.dob.cutoff_rad_s, self.cfg.period_s());
        let mut y = col.first().copied().unwrap_or(0.0) as f32;
        col.iter()
            .map(|u| f64::from(lp.update(&mut y, *u as f32)))
            .collect()
    }

    /// A fitted model's output on every tick: `sum value_k column_k`, each
    /// column through `Q` when `filtered` (the DOB-based models).
    pub fn predict(&self, fit: &FitReport, filtered: bool, jae: bool) -> Result<Vec<f64>> {
        let mut out = vec![0.0; self.derived.len()];
        for p in &fit.params {
            let c = self.column(p.regressor, jae)?;
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
        let b = f64::from(self.cfg.dob.viscous_nm_s_rad);
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
        &self.theta
    }

    /// Joint speed from the magnetic encoder through the tracking observer, rad/s.
    pub fn theta_vel_rad_s(&self) -> &[f64] {
        &self.theta_vel
    }
}
