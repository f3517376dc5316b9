//! A log replayed through the core, with the columns the models need.

use anyhow::{anyhow, Context, Result};
use cable_joint::filter::{Kinematics, LowPass1, TrackingObserver};
use cable_joint::Config;

use super::{IdentOptions, Regressor};
use crate::derive::{held_sign, held_sign_travelled, low_pass_column, TickReplay};
use crate::log::Log;

/// A log replayed through the core, with the columns the models need (the
/// report draws the identified models on the same columns).
pub struct Prepared {
    pub(super) label: String,
    /// The replay, a row every control tick ([`TickReplay`]): filters,
    /// observers and differences over it advance as on the MCU whatever
    /// the log's decimation or holes; the fits take only the log's own
    /// rows ([`Prepared::measured`]).
    pub(super) replay: TickReplay,
    pub(super) cfg: Config,
    /// Rows usable at all: after the start-up, not faulted.
    pub(super) usable: Vec<bool>,
    /// Share of the control ticks whose applied current the log carries:
    /// all when it has the recorded mean over each step (`i_applied_a`),
    /// else its own rows'.
    pub(super) current_ticks_share: f64,
    /// Time and code of the first fault the replay latched.
    pub(super) first_fault: Option<(f64, u8)>,
    pub(super) theta: Option<Vec<f64>>,
    pub(super) theta_kin: Option<(Vec<f64>, Vec<f64>)>,
    pub(super) theta_source: &'static str,
    /// Why rows are lost, for the warning [`design`] prints.
    pub(super) loss: LossNotes,
}

/// What [`Prepared::new`] found that costs rows, for the row-loss warning.
#[derive(Default)]
pub(super) struct LossNotes {
    /// The first faulted row: "the replay latched ... at line L ...".
    pub(super) fault: Option<String>,
    /// `theta_rad` is present but not measured everywhere: (rows, first row).
    pub(super) theta_gap: Option<(usize, usize)>,
    /// The warning was printed (once per log and procedure).
    pub(super) warned: std::sync::atomic::AtomicBool,
}

impl LossNotes {
    fn new(log: &Log, replay: &TickReplay, t: &[f64], fault: &[f64]) -> Self {
        let fault = fault.iter().position(|f| *f != 0.0).map(|tick| {
            let code = fault[tick] as u8;
            let k = replay.log_row(tick);
            let name = crate::ingest::fault_words(code);
            // A value the core's f32 cannot hold is the likely cause.
            let cause = (k.saturating_sub(2)..=k)
                .flat_map(|r| log.names().into_iter().map(move |c| (r, c)))
                .find(|(r, c)| {
                    log.col(c)
                        .is_some_and(|v| v[*r].is_finite() && v[*r].abs() > f64::from(f32::MAX))
                })
                .map(|(r, c)| {
                    format!(
                        "; column {c} = {:e} on line {} is beyond the core's f32 range",
                        log.col(c).map_or(0.0, |v| v[r]),
                        crate::log::line_of_row(r)
                    )
                })
                .unwrap_or_default();
            format!(
                "the replay latched {name} at line {} (t = {:.4} s){cause}",
                crate::log::line_of_row(k),
                t[tick]
            )
        });
        let theta_gap = log.col_opt("theta_rad").and_then(|v| {
            let first = v.iter().position(Option::is_none)?;
            Some((v.iter().filter(|x| x.is_none()).count(), first))
        });
        Self {
            fault,
            theta_gap,
            warned: Default::default(),
        }
    }
}

/// Which switching speed the `sgn(x2')` column uses.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum X2Switch {
    Jae,
    Tension,
}

impl Prepared {
    /// Replay `log` (named `label` in errors) through the core with `config`.
    pub fn new(label: &str, log: &Log, config: &Config, opts: &IdentOptions) -> Result<Self> {
        let replay = TickReplay::new(log, config).with_context(|| format!("replaying {label}"))?;
        let cfg = replay.config;
        let applied_mean = log
            .col("i_applied_a")
            .is_some_and(|c| c.iter().skip(1).all(|v| v.is_finite()));
        let current_ticks_share = if applied_mean {
            1.0
        } else {
            log.len() as f64 / replay.log.len().max(1) as f64
        };
        let derived = &replay.log;
        let t = derived.time_s()?.to_vec();
        // The rate line only for a recorded run (what its tick counter
        // gave); a simulated log's rate is the one it was run at.
        let skip = usize::from(!replay.clock.from_ticks);
        for note in replay.clock_notes.iter().skip(skip) {
            eprintln!("note: {label}: {note}");
        }
        let fault = derived.col_required("fault_code")?;
        let t0 = t.first().copied().unwrap_or(0.0);
        let usable: Vec<bool> = t
            .iter()
            .zip(fault)
            .map(|(t, f)| *t >= t0 + opts.skip_start_s && *f == 0.0)
            .collect();
        let first_fault = t
            .iter()
            .zip(fault)
            .find(|(_, f)| **f != 0.0)
            .map(|(t, f)| (*t, *f as u8));
        // The magnetic encoder when it is measured on every row, else the JAE.
        let (theta, theta_source) = match derived.col_opt("theta_rad") {
            Some(v) if v.iter().all(Option::is_some) => {
                (Some(v.into_iter().flatten().collect()), "theta_rad")
            }
            _ => (
                derived.col("theta_hat_rad").map(<[f64]>::to_vec),
                "theta_hat_rad",
            ),
        };
        let theta_kin = theta.as_ref().map(|th| {
            let obs =
                TrackingObserver::new(cfg.differentiators.grating_bandwidth_hz, cfg.period_s());
            let mut st = Kinematics::default();
            obs.reset(&mut st, th.first().copied().unwrap_or(0.0) as f32);
            let (mut v, mut a) = (Vec::with_capacity(th.len()), Vec::with_capacity(th.len()));
            for x in th {
                let k = obs.update(&mut st, *x as f32);
                v.push(k.vel as f64);
                a.push(k.acc as f64);
            }
            (v, a)
        });
        let loss = LossNotes::new(log, &replay, &t, fault);
        Ok(Self {
            label: label.to_owned(),
            first_fault,
            loss,
            replay,
            cfg,
            usable,
            current_ticks_share,
            theta,
            theta_kin,
            theta_source,
        })
    }

    /// Rows of the replay: control ticks.
    pub(super) fn len(&self) -> usize {
        self.replay.log.len()
    }

    /// Whether replay row `k` is one of the log's own rows (the fits take
    /// only these), not a tick the replay filled between them.
    pub(super) fn measured(&self, k: usize) -> bool {
        self.replay.measured(k)
    }

    /// The log's row of replay row `k`, for messages that name a line.
    pub(super) fn log_row(&self, k: usize) -> usize {
        self.replay.log_row(k)
    }

    /// Samples either side of a central difference over about `window_s`
    /// of the replay: at least one of the log's row steps, so that the
    /// difference spans measured rows and not only the curve the replay
    /// filled between two of them.
    pub(super) fn half_window(&self, window_s: f64) -> usize {
        let ticks = (window_s / f64::from(self.cfg.period_s())).round();
        (ticks.max(1.0) as usize).max(self.replay.clock.decimation as usize)
    }

    /// Whether the log has a row every control tick (not decimated).
    pub(super) fn every_tick(&self) -> bool {
        self.replay.clock.decimation <= 1
    }

    /// The log's own rows among them.
    pub(super) fn measured_rows(&self) -> usize {
        self.replay.source_row.iter().flatten().count()
    }

    /// A column of the replay.
    pub fn col(&self, name: &str) -> Result<Vec<f64>> {
        Ok(self
            .replay
            .log
            .col(name)
            .ok_or_else(|| anyhow!("{}: replay has no column `{name}`", self.label))?
            .to_vec())
    }

    /// The magnetic encoder when measured on every row, else the JAE, rad.
    pub fn theta(&self) -> Result<&Vec<f64>> {
        self.theta.as_ref().ok_or_else(|| {
            anyhow!(
                "{}: no joint angle (theta_rad or theta_hat_rad)",
                self.label
            )
        })
    }

    /// Joint speed and acceleration of [`Prepared::theta`] through the
    /// core's tracking observer.
    pub fn theta_kin(&self) -> Result<&(Vec<f64>, Vec<f64>)> {
        self.theta_kin.as_ref().ok_or_else(|| {
            anyhow!(
                "{}: no joint angle (theta_rad or theta_hat_rad)",
                self.label
            )
        })
    }

    /// Time, s.
    pub fn t_s(&self) -> Result<&[f64]> {
        Ok(self.replay.log.time_s()?)
    }

    /// The configuration the log was replayed with (its own control rate).
    pub fn config(&self) -> &Config {
        &self.cfg
    }

    /// The unfiltered column of `r`; `jae`: `sgn(x2')` with the JAE's
    /// switching speed (else the tension model's).
    pub fn regressor_column(&self, r: Regressor, jae: bool) -> Result<Vec<f64>> {
        self.column(
            r,
            if jae {
                X2Switch::Jae
            } else {
                X2Switch::Tension
            },
        )
    }

    /// The unfiltered column of `r`.
    pub(super) fn column(&self, r: Regressor, x2_switch: X2Switch) -> Result<Vec<f64>> {
        let c = &self.cfg;
        Ok(match r {
            Regressor::ThetaVel => self.theta_kin()?.0.clone(),
            Regressor::ThetaAcc => self.theta_kin()?.1.clone(),
            Regressor::SgnThetaVel => {
                // Slider 2 moves about r theta: the same switching speed.
                let sw = c.tension.sign_switch_x2_m_s / c.machine.pulley_radius_m;
                held_sign(self.theta_kin()?.0.iter().map(|v| *v as f32), sw)
            }
            Regressor::Theta => self.theta()?.clone(),
            Regressor::X1Acc => self.col("x1_acc_m_s2")?,
            Regressor::X1Vel => self.col("x1_vel_m_s")?,
            Regressor::SgnX1Vel => held_sign(
                self.col("x1_vel_m_s")?.iter().map(|v| *v as f32),
                c.tension.sign_switch_x1_m_s,
            ),
            Regressor::X1 => self.col("x1_m")?,
            Regressor::X2Acc => self.col("x2_acc_m_s2")?,
            Regressor::X2Vel => self.col("x2_vel_m_s")?,
            Regressor::SgnX2Vel => match x2_switch {
                X2Switch::Jae => held_sign_travelled(
                    &self.col("x2_vel_m_s")?,
                    &self.col("x2_m")?,
                    c.jae.sign_switch_m_s,
                    c.jae.sign_travel_m,
                ),
                X2Switch::Tension => held_sign(
                    self.col("x2_vel_m_s")?.iter().map(|v| *v as f32),
                    c.tension.sign_switch_x2_m_s,
                ),
            },
            Regressor::X2 => self.col("x2_m")?,
            Regressor::PhiVel => self.col("phi_vel_rad_s")?,
            Regressor::SgnPhiVel => {
                // Slider 1's switching speed at the motor shaft.
                let sw = c.tension.sign_switch_x1_m_s * c.machine.motor_rad_per_cable_m();
                held_sign(self.col("phi_vel_rad_s")?.iter().map(|v| *v as f32), sw)
            }
            Regressor::One => vec![1.0; self.len()],
        })
    }

    /// A first-order low-pass at `cutoff_hz` over a whole column.
    pub(super) fn low_pass(&self, col: &[f64], cutoff_hz: f64) -> Vec<f64> {
        let lp = LowPass1::new(
            (2.0 * std::f64::consts::PI * cutoff_hz) as f32,
            self.cfg.period_s(),
        );
        low_pass_column(lp, col)
    }

    /// The DOB's low-pass `Q` over a whole column (state starts at the first
    /// value: the log starts at rest).
    pub fn dob_filter(&self, col: &[f64]) -> Vec<f64> {
        low_pass_column(
            LowPass1::new(self.cfg.dob.cutoff_rad_s, self.cfg.period_s()),
            col,
        )
    }
}
