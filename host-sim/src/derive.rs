//! Recompute, from a log, the signals and estimates the firmware computes
//! online, by replaying the log through the core's own
//! [`Controller::replay`] (the same differentiators, JAE, tension model and
//! DOB; nothing is re-implemented here).
//!
//! Positions are converted back to counts with the configuration's scales
//! (exact for logs that came from counts) and the logged current reference is
//! the current applied over each period. The control rate is taken from the
//! log's tick column when it has one ([`log_clock`]), else from its median
//! time step.

use anyhow::{bail, Context, Result};
use cable_joint::model::SIGNAL_NAMES;
use cable_joint::units::{AdcCode, GratingCount, MagneticCount, MotorCount};
use cable_joint::{Config, Controller, RawSample};

use crate::io::config::rate_adjustment_note;
use crate::log::Log;

/// Columns [`derive()`] adds beyond the run-time signals ([`SIGNAL_NAMES`]).
pub const EXTRA_COLUMNS: [&str; 14] = [
    "x1_acc_m_s2",
    "phi_acc_rad_s2",
    "theta_hat_rad",
    "tension1_hat_n",
    "tension1_model_n",
    "load_torque_nm",
    "f_ext_hat_n",
    "f_ext_stretch_n",
    "f_ext_fused_n",
    "f_ext_lo_n",
    "f_ext_hi_n",
    "fusion_flags",
    "tension1_stretch_n",
    "fault_code",
];

/// The core's held sign (`SignMemory`, as the estimators hold `sgn(v)`)
/// over a velocity column: ±1, or 0 before the first motion above
/// `switch_speed`. The one implementation the identification and the
/// residual loop share.
pub fn held_sign(vel: impl IntoIterator<Item = f32>, switch_speed: f32) -> Vec<f64> {
    let memory = cable_joint::filter::SignMemory { switch_speed };
    let mut sign = 0.0f32;
    vel.into_iter()
        .map(|v| f64::from(memory.update(&mut sign, v)))
        .collect()
}

/// Velocity and acceleration of `pos` through a tracking `observer` run
/// forward and run backward over the whole record, averaged: the forward
/// run lags by what the backward run leads, so the mean keeps the
/// observer's noise rejection without its phase. Offline only (it reads
/// the future). A sample that is not finite is NaN in both columns (the
/// observer holds the last finite sample over it); `None` when no sample
/// is finite.
pub fn zero_phase_kinematics(
    observer: &cable_joint::filter::TrackingObserver,
    pos: &[f32],
) -> Option<(Vec<f64>, Vec<f64>)> {
    let run = |order: &[usize]| -> Option<Vec<(f64, f64)>> {
        let mut held = order.iter().map(|&k| pos[k]).find(|x| x.is_finite())?;
        let mut st = cable_joint::filter::Kinematics::default();
        observer.reset(&mut st, held);
        let mut out = vec![(f64::NAN, f64::NAN); pos.len()];
        for &k in order {
            let finite = pos[k].is_finite();
            if finite {
                held = pos[k];
            }
            let est = observer.update(&mut st, held);
            if finite {
                out[k] = (f64::from(est.vel), f64::from(est.acc));
            }
        }
        Some(out)
    };
    let order: Vec<usize> = (0..pos.len()).collect();
    let forward = run(&order)?;
    let reversed: Vec<usize> = order.into_iter().rev().collect();
    let backward = run(&reversed)?;
    // Time reversed, a velocity changes sign and an acceleration does not.
    Some(
        forward
            .iter()
            .zip(&backward)
            .map(|((vf, af), (vb, ab))| (0.5 * (vf - vb), 0.5 * (af + ab)))
            .unzip(),
    )
}

/// The JAE's held sign of `x2'` (`SignMemory::update_travelled`): as
/// [`held_sign`], and a reversal needs slider 2 to travel `min_travel` m
/// (`jae.sign_travel_m`) as well. `vel` and `pos` are the log's columns.
pub fn held_sign_travelled(
    vel: &[f64],
    pos: &[f64],
    switch_speed: f32,
    min_travel: f32,
) -> Vec<f64> {
    let memory = cable_joint::filter::SignMemory { switch_speed };
    let mut held = cable_joint::filter::HeldSign::default();
    vel.iter()
        .zip(pos)
        .map(|(v, x)| {
            f64::from(memory.update_travelled(&mut held, *v as f32, *x as f32, min_travel))
        })
        .collect()
}

/// A first-order low-pass (the core's [`LowPass1`](cable_joint::filter::LowPass1),
/// e.g. the DOB's `Q`) over a whole column, started settled at its first
/// value (as the observer's reset does), in the core's `f32` arithmetic. The
/// one implementation the identification, the residual loop and the report
/// share.
pub fn low_pass_column<T: Copy + Into<f64>>(
    lp: cable_joint::filter::LowPass1,
    u: &[T],
) -> Vec<f64> {
    let mut y = u.first().map(|v| (*v).into() as f32).unwrap_or(0.0);
    u.iter()
        .map(|v| f64::from(lp.update(&mut y, (*v).into() as f32)))
        .collect()
}

/// Median time step of a log, s.
pub fn median_period_s(t_s: &[f64]) -> Option<f64> {
    if t_s.len() < 2 {
        return None;
    }
    let mut d: Vec<f64> = t_s.windows(2).map(|w| w[1] - w[0]).collect();
    d.sort_by(|a, b| a.total_cmp(b));
    Some(d[d.len() / 2])
}

/// [`median_period_s`] of a log's time column, refused when the log has
/// fewer than two rows or the median step is not positive.
fn median_row_step_s(t_s: &[f64]) -> Result<f64> {
    let dt = median_period_s(t_s).context("log has fewer than two rows")?;
    if !(dt.is_finite() && dt > 0.0) {
        bail!("log time step is not positive (median {dt} s)");
    }
    Ok(dt)
}

/// How a log's rows sit on the firmware's control clock.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Clock {
    /// The control period, s.
    pub period_s: f64,
    /// Control ticks from one row to the next in a regular stretch of the
    /// log (the telemetry decimation; 1 for a row every tick).
    pub decimation: u32,
    /// Whether the clock was read from the log's `tick` column (a recorded
    /// run) rather than from its time steps alone.
    pub from_ticks: bool,
}

impl Clock {
    /// The control rate, Hz.
    pub fn rate_hz(&self) -> f64 {
        1.0 / self.period_s
    }

    /// How the rate was found, for the command to print.
    pub fn source(&self) -> String {
        if self.from_ticks {
            let every = match self.decimation {
                1 => "a row every tick".to_owned(),
                d => format!("a row every {d} ticks"),
            };
            format!("from the log's tick column: {every}")
        } else {
            "from the log's median time step".to_owned()
        }
    }
}

/// The control clock of `log`. A recorded run carries the firmware's tick
/// counter: the period is the median of `dt / dtick` and the decimation the
/// smallest tick step, so neither a decimated recording nor one that lost
/// most of its rows (a median time step of two or three periods) is taken
/// for a slower loop. Without a `tick` column, every row is a tick and the
/// period is the median time step.
pub fn log_clock(log: &Log) -> Result<Clock> {
    let t = log.time_s()?;
    let tick = log.col("tick").filter(|c| c.iter().all(|v| v.is_finite()));
    let Some(tick) = tick else {
        let dt = median_row_step_s(t)?;
        return Ok(Clock {
            period_s: dt,
            decimation: 1,
            from_ticks: false,
        });
    };
    if t.len() < 2 {
        bail!("log has fewer than two rows");
    }
    let mut per_tick = Vec::with_capacity(t.len() - 1);
    let mut steps = Vec::with_capacity(t.len() - 1);
    for k in 1..t.len() {
        let dtick = tick[k] - tick[k - 1];
        if !(dtick >= 1.0 && dtick.fract() == 0.0) {
            bail!(
                "line {}, column tick: {} after {} (the firmware's tick counter must grow by a \
                 whole number of ticks from row to row)",
                crate::log::line_of_row(k),
                tick[k],
                tick[k - 1]
            );
        }
        per_tick.push((t[k] - t[k - 1]) / dtick);
        steps.push(dtick);
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(|a, b| a.total_cmp(b));
        v[v.len() / 2]
    };
    let period_s = median(&mut per_tick);
    if !(period_s.is_finite() && period_s > 0.0) {
        bail!("log time step per tick is not positive (median {period_s} s)");
    }
    // The smallest step: a decimated stream's steps are all multiples of
    // its decimation, and a lossy one's median step is not its decimation.
    let smallest = steps.iter().copied().fold(f64::INFINITY, f64::min);
    Ok(Clock {
        period_s,
        decimation: smallest.min(f64::from(u32::MAX)) as u32,
        from_ticks: true,
    })
}

/// Give a log recorded every `ticks_per_row` control ticks by another
/// logger (no firmware `tick` column, so [`log_clock`] would take its row
/// step for the control period) the tick column the firmware's records
/// carry: each row's tick is its time from the first row over the control
/// period, the median time step over `ticks_per_row`, rounded; a row
/// missing from the log is then a hole of the time it spans. Returns the
/// line the command prints about it.
///
/// # Errors
/// A log that has a `tick` column already, `ticks_per_row` of 0, or two
/// rows less than half a control period apart (they would be one tick);
/// each names the line.
pub fn set_ticks_per_row(log: &mut Log, ticks_per_row: u32) -> Result<String> {
    if ticks_per_row == 0 {
        bail!("--ticks-per-row must be at least 1");
    }
    if log.has("tick") {
        bail!(
            "the log has a tick column (the firmware's counter): its control clock is read from \
             it, so --ticks-per-row is for logs without one"
        );
    }
    let t = log.time_s()?;
    let row_s = median_row_step_s(t)?;
    let period_s = row_s / f64::from(ticks_per_row);
    let mut ticks = Vec::with_capacity(t.len());
    for (k, tk) in t.iter().enumerate() {
        let tick = ((tk - t[0]) / period_s).round();
        if let Some(&before) = ticks.last() {
            if tick <= before {
                bail!(
                    "line {}: t_s = {tk} is less than half a control period ({period_s:.3e} s at \
                     {ticks_per_row} ticks per row) after the row before, so the two would be \
                     one tick",
                    crate::log::line_of_row(k)
                );
            }
        }
        ticks.push(tick);
    }
    log.set_col("tick", ticks)?;
    Ok(format!(
        "a row every {ticks_per_row} control ticks (--ticks-per-row): the log's rows are {:.4} \
         ms apart at the median, so the control period is {:.4} ms",
        row_s * 1e3,
        period_s * 1e3
    ))
}

/// [`log_clock`], with the lines the replay prints about it: the control
/// rate and where it came from, then, when there is any, what the replay
/// fills between rows ([`Holes::note`]).
pub fn clock_noted(log: &Log, fill: CurrentFill) -> Result<(Clock, Vec<String>)> {
    let clock = log_clock(log)?;
    let mut notes = vec![format!(
        "control rate {:.1} Hz ({})",
        clock.rate_hz(),
        clock.source()
    )];
    let holes = Holes::of(log.time_s()?, &clock);
    let filled = holes
        .missing
        .saturating_mul(clock.decimation.max(1) as usize);
    // A hole too long alone is the replay's to name (by its line).
    let longest_alone = missing_ticks(holes.longest_s, clock.period_s) + 1 > MAX_FILLED_TICKS;
    if filled > MAX_FILLED_TICKS && !longest_alone {
        bail!(
            "the log misses {} rows in {} holes ({filled} control ticks, {:.1} s in all; the \
             longest {:.3} s at line {}): the replay fills at most {MAX_FILLED_TICKS} ticks \
             of lost time in a log; split it into the recordings it joins",
            holes.missing,
            holes.count,
            filled as f64 * clock.period_s,
            holes.longest_s,
            crate::log::line_of_row(holes.longest_row),
        );
    }
    notes.extend(holes.note(&clock, fill));
    Ok((clock, notes))
}

/// `config` at `clock`'s control rate, with a line for every setting
/// derived from the rate.
pub(crate) fn config_at_clock(clock: &Clock, config: &Config) -> Result<(Config, Vec<String>)> {
    let rate_hz = clock.rate_hz();
    let (c, changes) = config.at_rate(rate_hz as f32);
    c.validate()
        .map_err(|e| anyhow::anyhow!("{e} (control rate taken from the log: {rate_hz:.1} Hz)"))?;
    let notes = changes
        .iter()
        .map(|a| rate_adjustment_note(a, "the configuration's", c.control_rate_hz))
        .collect();
    Ok((c, notes))
}

/// Rows a log is missing: steps of its time column longer than the
/// clock's row step (telemetry a host could not keep up with, a dropped
/// serial frame).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Holes {
    /// Holes (a step of at least two rows).
    pub count: usize,
    /// Rows missing over all holes.
    pub missing: usize,
    /// The longest hole, s.
    pub longest_s: f64,
    /// The row after the longest hole (0-based).
    pub longest_row: usize,
}

impl Holes {
    /// The holes of the time column `t` on `clock` (a row every
    /// `clock.decimation` periods).
    pub fn of(t: &[f64], clock: &Clock) -> Self {
        let row_s = clock.period_s * f64::from(clock.decimation.max(1));
        let mut h = Self::default();
        for k in 1..t.len() {
            let n = missing_ticks(t[k] - t[k - 1], row_s);
            if n > 0 {
                h.count += 1;
                h.missing += n;
                if t[k] - t[k - 1] > h.longest_s {
                    h.longest_s = t[k] - t[k - 1];
                    h.longest_row = k;
                }
            }
        }
        h
    }

    /// What the replay does about the holes (and a decimated log's ticks
    /// between rows), for the command to print (`None` when there is
    /// nothing to fill), with the current filled as `fill` says.
    pub fn note(&self, clock: &Clock, fill: CurrentFill) -> Option<String> {
        let current = match fill {
            CurrentFill::Mean => {
                "the current held (the log's mean over each step, i_applied_a, when it has one)"
            }
            CurrentFill::Chatter => {
                "the current starting at the row before's reference and, when the log has its \
                 mean over each step (i_applied_a), going on chattering about that mean by as \
                 much, which the bound widens by as the board's did"
            }
        };
        let between = (clock.decimation > 1).then(|| {
            format!(
                "the log has a row every {} control ticks: the replay steps the core through \
                 the ticks between rows with the sensors interpolated and {current}",
                clock.decimation
            )
        });
        let hole_current = if between.is_some() {
            "the rest the same way"
        } else {
            current
        };
        let holes = (self.count > 0).then(|| {
            format!(
                "the log is missing {} rows in {} holes (the longest {:.4} s, before line {}): \
                 the replay steps the core through each hole with the sensors interpolated and \
                 {hole_current}",
                self.missing,
                self.count,
                self.longest_s,
                crate::log::line_of_row(self.longest_row)
            )
        });
        match (between, holes) {
            (Some(b), Some(h)) => Some(format!("{b}; {h}")),
            (b, h) => b.or(h),
        }
    }
}

/// Control ticks a time step `dt_s` skips at the period `period_s`: the
/// step in whole periods, less the one a row takes (0 for a regular step
/// or a non-positive one).
fn missing_ticks(dt_s: f64, period_s: f64) -> usize {
    let n = (dt_s / period_s).round();
    if n.is_finite() && n >= 2.0 {
        n as usize - 1
    } else {
        0
    }
}

/// How the replay fills the current over the ticks between a log's rows,
/// of which a decimated recording gives at most the mean (`i_applied_a`,
/// the board's mean over the ticks since the record before).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CurrentFill {
    /// The step's mean on every tick (the reference of the row before, held,
    /// when the log has no mean): each tick's least-squares guess, for the
    /// fits ([`TickReplay`]: identification, the residual loop), where a
    /// chatter the log does not give would only be noise in the regressors
    /// (on a drawn plant's calibration recorded every 10th tick at 2 kHz,
    /// the spring rate through the motor fits with 2.5 % sigma and 0.036 N
    /// residual held, 4.1 % and 0.060 N with [`Self::Chatter`]).
    Mean,
    /// The estimators' input ([`derive()`], `host-sim estimate`): the current
    /// does not sit at its mean but chatters from tick to tick (the loops'
    /// noise, a limit cycle), and the DOB's interval widens by that chatter
    /// (the fusion's ripple term), so a mean held hides it and narrows the
    /// bound where the board's was wide. The first tick's current is exact
    /// (the reference the row before recorded, applied over the period
    /// after it), and its departure `d` from the step's mean is the record's
    /// one sample of the chatter: the ticks carry it on, `mean ± d`
    /// alternating from the first, shifted so that their mean is the step's
    /// (exact for an even step; an odd one moves the rest by `-d / (ticks -
    /// 1)`). A hole is filled the same way: its mean covers it when the
    /// board dropped the records from its queue, only its last row step
    /// when a frame was lost after the board queued it, and the chatter
    /// about it is the best the log gives either way (a recording every
    /// 10th tick with a quarter of its rows lost at random, on drawn plants
    /// 61 and 64: coverage 98.4–99.6 % with the mean held in the holes,
    /// 99.7–100 % with the chatter carried through them, the board's
    /// 99.8–100 %).
    Chatter,
}

/// The current applied over tick `j` (1-based) of the `ticks` control
/// periods from one row of a log to the next, as the replay steps the core
/// through them ([`CurrentFill`]): `reference_before_a` is the row before's
/// current reference, `mean_a` the log's mean over the step when it has
/// one.
pub fn applied_in_step(
    fill: CurrentFill,
    reference_before_a: f64,
    mean_a: Option<f64>,
    j: usize,
    ticks: usize,
) -> f64 {
    if ticks == 1 || fill == CurrentFill::Mean {
        return mean_a.unwrap_or(reference_before_a);
    }
    let Some(mean_a) = mean_a.filter(|_| j > 1) else {
        return reference_before_a;
    };
    let d = reference_before_a - mean_a;
    let alternating = if j % 2 == 1 { d } else { -d };
    let shift = if ticks % 2 == 1 {
        -d / (ticks - 1) as f64
    } else {
        0.0
    };
    mean_a + alternating + shift
}

/// The log's current references (`i_ref_a`, and `i_applied_a` when it has
/// one) lie within what the board's DAC can command with these `scales`
/// (codes 0 to 4095, half a code either side for rounding): a current
/// beyond it was not commanded by a board with this configuration (a log in
/// milliamps, another drive's scales, a corrupt cell), and the replay
/// would drive the core's estimators with it. Blank and non-finite cells
/// are left to the log's own checks.
fn check_current_range(log: &Log, s: &cable_joint::units::Scales) -> Result<()> {
    use cable_joint::units::{DacCode, CODE_MAX_12BIT};
    let half = 0.5 * f64::from(s.dac_a_per_code).abs();
    let (a, b) = (
        f64::from(s.dac_a(DacCode(0))),
        f64::from(s.dac_a(DacCode(CODE_MAX_12BIT))),
    );
    let (lo, hi) = (a.min(b) - half, a.max(b) + half);
    for name in ["i_ref_a", "i_applied_a"] {
        let Some(col) = log.col(name) else { continue };
        if let Some(k) = col
            .iter()
            .position(|v| v.is_finite() && !(lo..=hi).contains(v))
        {
            let v = col[k];
            let value = crate::log::value_text(v);
            bail!(
                "line {}: column {} = {value} A is beyond the current the board's DAC can \
                 command, {:.3} to {:.3} A (scales.dac_a_per_code, scales.dac_zero_code): check \
                 the log's units or the configuration's scales",
                crate::log::line_of_row(k),
                crate::log::quoted(name),
                a.min(b),
                a.max(b)
            );
        }
    }
    Ok(())
}

/// Most control ticks the replay fills into one hole of a log, and into
/// all its holes together: 1e6, some eight minutes at 2 kHz. A longer step
/// of the time column is not a lost frame but another recording or a
/// broken clock, and is refused; so is a log that lost more in all.
pub const MAX_FILLED_TICKS: usize = 1_000_000;

/// Replay `log` (project schema) through the core; returns a log with `t_s`,
/// the run-time signals, [`EXTRA_COLUMNS`], and the log's `theta_rad`,
/// `f_ext_n` and `theta_ref_rad` when present: a row for each of the log's
/// rows. Between a decimated log's rows the core steps through the ticks
/// with the sensors interpolated and the current's chatter carried on
/// ([`CurrentFill::Chatter`]), as the estimators need.
pub fn derive(log: &Log, config: &Config) -> Result<Log> {
    derive_noted(log, config).map(|(d, _, _)| d)
}

/// [`derive()`], with the log's control clock and the lines the replay
/// prints about it and about the settings derived from its rate
/// ([`Config::at_rate`]).
pub fn derive_noted(log: &Log, config: &Config) -> Result<(Log, Clock, Vec<String>)> {
    let (clock, mut notes) = clock_noted(log, CurrentFill::Chatter)?;
    let (cfg, derived) = config_at_clock(&clock, config)?;
    notes.extend(derived);
    let (out, _) = replay(log, &cfg, CurrentFill::Chatter, false)?;
    Ok((out, clock, notes))
}

/// The replay of a log tick by tick: [`Log`] has a row for every control
/// tick the core stepped, the log's own rows and the ticks the replay fills
/// between them (a decimated log's, a hole's), whose time, sensors and the
/// log's `theta_rad`, `f_ext_n` and `theta_ref_rad` are interpolated and
/// whose current is the step's mean ([`CurrentFill::Mean`]: this replay
/// feeds the fits). Filters, observers, effect states
/// and differences over time computed on it advance tick by tick as on the
/// MCU, which on a decimated or lossy log a computation row by row does
/// not.
pub struct TickReplay {
    /// The replay, a row a tick.
    pub log: Log,
    /// For each of its rows, the log's row it is (`None` for a filled tick).
    pub source_row: Vec<Option<usize>>,
    /// The log's control clock ([`log_clock`]).
    pub clock: Clock,
    /// What [`clock_noted`] says of it: the control rate and what the
    /// replay fills between rows.
    pub clock_notes: Vec<String>,
    /// The configuration it was replayed with: the caller's at the log's
    /// control rate.
    pub config: Config,
}

impl TickReplay {
    /// Replay `log` through the core with `config` (set to the log's
    /// control rate), a row a tick.
    pub fn new(log: &Log, config: &Config) -> Result<Self> {
        let (clock, clock_notes) = clock_noted(log, CurrentFill::Mean)?;
        let (config, _) = config_at_clock(&clock, config)?;
        let (replayed, source_row) = replay(log, &config, CurrentFill::Mean, true)?;
        Ok(Self {
            log: replayed,
            source_row,
            clock,
            clock_notes,
            config,
        })
    }

    /// Whether row `k` is one of the log's own rows (measured), not a
    /// filled tick.
    pub fn measured(&self, k: usize) -> bool {
        self.source_row.get(k).is_some_and(Option::is_some)
    }

    /// The log's row of replay row `k`: its own, or for a filled tick the
    /// row that ends its step (for messages that name a line).
    pub fn log_row(&self, k: usize) -> usize {
        log_row_in(&self.source_row, k)
    }
}

/// The log's row of replay row `k` given each replay row's source row
/// ([`TickReplay::source_row`]): its own, or for a filled tick the row that
/// ends its step (the last row past the end).
pub fn log_row_in(source_row: &[Option<usize>], k: usize) -> usize {
    source_row
        .get(k..)
        .unwrap_or_default()
        .iter()
        .find_map(|r| *r)
        .or_else(|| source_row.iter().rev().find_map(|r| *r))
        .unwrap_or(0)
}

/// [`derive`] and [`TickReplay::new`]: the replay with `cfg` (already at
/// the log's control rate), with a row for each of the log's rows or
/// (`every_tick`) for every tick it steps, and for each row the log's row
/// it is.
fn replay(
    log: &Log,
    cfg: &Config,
    fill: CurrentFill,
    every_tick: bool,
) -> Result<(Log, Vec<Option<usize>>)> {
    let s = &cfg.scales;
    let t = log.time_s()?;
    let x1 = log.col_required("x1_m")?;
    let x2 = log.col_required("x2_m")?;
    let phi = log.col_required("phi_rad")?;
    let i_ref = log.col_required("i_ref_a")?;
    // The current applied over tick `j` of the `ticks` from row k - 1 to
    // row k ([`applied_in_step`]), from row k - 1's reference and the
    // recording's mean over the step (`i_applied_a`, telemetry format 3)
    // when the log carries it.
    let i_applied = log.col("i_applied_a");
    check_current_range(log, s)?;
    let applied = |k: usize, j: usize, ticks: usize| -> f64 {
        if k == 0 {
            return 0.0;
        }
        let mean_a = i_applied.map(|c| c[k]).filter(|v| v.is_finite());
        applied_in_step(fill, i_ref[k - 1], mean_a, j, ticks)
    };
    let i_meas = log.col("i_meas_a");
    let theta = log.col("theta_rad");
    let mut ctl = Controller::new(*cfg).map_err(|e| anyhow::anyhow!("{e}"))?;

    let mut names: Vec<&str> = vec!["t_s"];
    names.extend(SIGNAL_NAMES);
    names.extend(EXTRA_COLUMNS);
    let mut out = Log::with_columns(&names)?;
    // For each row of `out`: the log's row it ends at, and the fraction of
    // the way there from the row before (1 for the row itself).
    let mut at: Vec<(usize, f64)> = Vec::with_capacity(log.len());
    let two_pi = std::f64::consts::TAU;
    let period_s = f64::from(cfg.period_s());
    let mut magnetic = 0u16;
    // Counts per unit of each position sensor.
    let grating_per_m = 1.0 / s.grating_m_per_count as f64;
    let motor_per_rad = s.motor_counts_per_rev as f64 / two_pi;
    let magnetic_per_rad = s.magnetic_counts_per_rev as f64 / two_pi;
    // The control ticks of the step ending at each row (1 for the first).
    let steps: Vec<usize> = (0..log.len())
        .map(|k| match k {
            0 => 1,
            _ => missing_ticks(t[k] - t[k - 1], period_s) + 1,
        })
        .collect();
    // Row k's sensor readings in counts (the current in amperes), or those
    // a fraction `f` of the way from row k - 1 to row k (the ticks inside a
    // step): on the monotone cubic through the rows' whole counts
    // ([`fill_counts`]).
    let reading = |k: usize, f: f64| {
        let at = |c: &[f64], per_unit: f64| {
            if f < 1.0 {
                fill_counts(c, &steps, k, f, per_unit)
            } else {
                c[k] * per_unit
            }
        };
        let meas_at = |j: usize| {
            i_meas
                .map(|c| c[j])
                .filter(|v| v.is_finite())
                .unwrap_or(i_ref[j])
        };
        let meas = if f < 1.0 {
            meas_at(k - 1) + f * (meas_at(k) - meas_at(k - 1))
        } else {
            meas_at(k)
        };
        // A cell not measured holds the last reading (a jump to 0 would
        // latch an encoder-jump fault and end the replay).
        let th = theta.and_then(|c| {
            let a = if f < 1.0 { c[k - 1] } else { c[k] };
            (a.is_finite() && c[k].is_finite()).then(|| at(c, magnetic_per_rad))
        });
        (
            at(x1, grating_per_m),
            at(x2, grating_per_m),
            at(phi, motor_per_rad),
            th,
            meas,
        )
    };
    // To whole counts, ties to even: a filled tick halfway between rows a
    // count apart is an exact half count, and rounding half away from zero
    // (as `reading` once did on the interpolated angle, where the log's
    // `f32` cells made near-ties land away from zero 87 % of the time)
    // pushed every such tick away from the origin, the motor's by +0.37
    // count on average for φ > 0 and −0.37 for φ < 0. The motor observer
    // then read ∓0.1 rad/s at the rows, the DOB's tension ±0.04 N with the
    // sign of each sweep, and the spring fit through the motor took it as
    // a stiffer spring: 703 and 706 N/m from rows every 2nd and 4th tick of
    // a run whose every tick gives 642 (stop 69).
    let raw_of = |(x1, x2, phi, th, meas): (f64, f64, f64, Option<f64>, f64),
                  magnetic: &mut u16| {
        if let Some(v) = th {
            *magnetic = v.round_ties_even() as i64 as u16;
        }
        RawSample {
            grating1: GratingCount(x1.round_ties_even() as i32),
            grating2: GratingCount(x2.round_ties_even() as i32),
            motor: MotorCount(phi.round_ties_even() as i64 as u16),
            magnetic: MagneticCount(*magnetic),
            current: AdcCode(
                (meas as f32 / s.adc_a_per_code + s.adc_zero_code)
                    .round_ties_even()
                    .clamp(0.0, 4095.0) as u16,
            ),
        }
    };
    for k in 0..log.len() {
        // The ticks of the step ending at row k: a decimated log's row
        // step, or a hole's (rows the recording lost). The core steps
        // through the time that passed, its sensors interpolated, so a
        // hole is not a sensor jump.
        let ticks = steps[k];
        if ticks > MAX_FILLED_TICKS {
            bail!(
                "line {}: the time jumps by {:.3} s from the row before ({ticks} control \
                 periods); a hole this long is not a lost frame: split the log there",
                crate::log::line_of_row(k),
                t[k] - t[k - 1],
            );
        }
        for j in 1..ticks {
            let f = j as f64 / ticks as f64;
            let raw = raw_of(reading(k, f), &mut magnetic);
            let current_a = applied(k, j, ticks);
            let o = ctl.replay(&raw, current_a as f32);
            if every_tick {
                let t_f = t[k - 1] + f * (t[k] - t[k - 1]);
                out.push_row(&row_of(t_f, current_a, &o))?;
                at.push((k, f));
            }
        }
        let raw = raw_of(reading(k, 1.0), &mut magnetic);
        if k == 0 {
            ctl.set_origin(&raw);
        }
        let current_a = applied(k, ticks, ticks);
        let o = ctl.replay(&raw, current_a as f32);
        out.push_row(&row_of(t[k], current_a, &o))?;
        at.push((k, 1.0));
    }
    // Positions relative to the first sample: the replay zeroes the counters
    // there, so add the first sample back to keep the log's own origin.
    for (name, first) in [("x1_m", x1[0]), ("x2_m", x2[0]), ("phi_rad", phi[0])] {
        let v: Vec<f64> = out.col_required(name)?.iter().map(|x| x + first).collect();
        out.set_col(name, v)?;
    }
    // The log's own columns at each row: a filled tick's interpolated
    // between the rows around it when both are measured.
    for name in ["theta_rad", "f_ext_n", "theta_ref_rad"] {
        if let Some(v) = log.col_opt(name) {
            let col: Vec<Option<f64>> = at
                .iter()
                .map(|&(k, f)| match (f < 1.0, v[k]) {
                    (false, x) => x,
                    (true, Some(b)) => v[k - 1].map(|a| a + f * (b - a)),
                    (true, None) => None,
                })
                .collect();
            out.set_col_opt(name, &col)?;
        }
    }
    let source_row = at.iter().map(|&(k, f)| (f >= 1.0).then_some(k)).collect();
    Ok((out, source_row))
}

/// The reading a fraction `f` (0 < f < 1) of the way from row `k - 1` to
/// row `k` of column `c` (units of which `per_unit` make a count), in
/// counts: on the monotone cubic (Fritsch–Carlson / Butland tangents)
/// through the rows' whole counts, `steps[i]` the ticks from row `i - 1` to
/// row `i`. A straight line between two rows moves at the speed of the
/// step's middle, so at a row the core's observers, which follow the
/// filled ticks, read the speed of half a step before: on a row every
/// 10th tick of a 500 Hz run the motor's observer lagged 10 ms, the
/// DOB's inertial term (37 kg reflected to cable 0) read `g T/2` of the
/// acceleration wrong at the rows, and in a sweep, whose acceleration
/// follows its travel, the spring rate through the motor read 29 % soft.
/// The cubic's speed at a row is the rows' own, from both sides, so it
/// does not lag; it stays between the two rows' counts (flat where a
/// sensor stands still or turns at a row), so it adds no motion the rows
/// do not show. Each row's speed is taken over at least the step's ticks
/// either side. Without a row either side of the step (the log's ends, a
/// cell not finite) the fill is the straight line.
fn fill_counts(c: &[f64], steps: &[usize], k: usize, f: f64, per_unit: f64) -> f64 {
    let counts = |i: usize| (c[i] * per_unit).round();
    let (a, b) = (counts(k - 1), counts(k));
    let h = steps[k] as f64;
    // The slope from row `i` over at least the step's ticks the way `back`
    // or forward, counts per tick, and those ticks: over the rows' own
    // steps where the log is decimated evenly, over as many rows as a hole
    // spans where it is a hole in a log of every tick (a single tick's
    // slope of a counted sensor is its count's rounding).
    let slope = |i: usize, back: bool| -> Option<(f64, f64)> {
        let (mut j, mut ticks) = (i, 0usize);
        while (ticks as f64) < h {
            if back {
                if j == 0 {
                    break;
                }
                ticks += steps[j];
                j -= 1;
            } else {
                if j + 1 >= c.len() {
                    break;
                }
                j += 1;
                ticks += steps[j];
            }
        }
        let ends_finite = c[i].is_finite() && c[j].is_finite();
        (j != i && ends_finite).then(|| {
            let d = (counts(j) - counts(i)) / ticks as f64;
            (if back { -d } else { d }, ticks as f64)
        })
    };
    // The tangent at row `i`, counts per tick: zero at a turn or a stand,
    // else the Butland weighted harmonic mean of the slopes either side.
    let tangent = |i: usize| -> Option<f64> {
        let ((d0, h0), (d1, h1)) = (slope(i, true)?, slope(i, false)?);
        if d0 * d1 <= 0.0 {
            return Some(0.0);
        }
        let (w0, w1) = (2.0 * h1 + h0, h1 + 2.0 * h0);
        Some((w0 + w1) / (w0 / d0 + w1 / d1))
    };
    let (Some(m0), Some(m1)) = (tangent(k - 1), tangent(k)) else {
        return a + f * (b - a);
    };
    let (f2, f3) = (f * f, f * f * f);
    (2.0 * f3 - 3.0 * f2 + 1.0) * a
        + (f3 - 2.0 * f2 + f) * h * m0
        + (3.0 * f2 - 2.0 * f3) * b
        + (f3 - f2) * h * m1
}

/// One row of the replay's log: time `t_s`, the current applied over the
/// tick `i_ref_a`, and the core's outputs.
fn row_of(t_s: f64, i_ref_a: f64, o: &cable_joint::controller::Output) -> [f64; 25] {
    let e = &o.est;
    [
        t_s,
        e.x1_m as f64,
        e.x1_vel_m_s as f64,
        e.x2_m as f64,
        e.x2_vel_m_s as f64,
        e.x2_acc_m_s2 as f64,
        e.phi_rad as f64,
        e.phi_vel_rad_s as f64,
        i_ref_a,
        e.i_meas_a as f64,
        e.theta_motor_rad as f64,
        e.x1_acc_m_s2 as f64,
        e.phi_acc_rad_s2 as f64,
        e.theta_hat_rad as f64,
        e.tension1_n as f64,
        e.tension1_model_n as f64,
        e.load_torque_nm as f64,
        e.f_ext_hat_n as f64,
        e.f_ext_stretch_n as f64,
        e.f_ext_fused_n as f64,
        e.f_ext_lo_n as f64,
        e.f_ext_hi_n as f64,
        f64::from(e.fusion_flags),
        e.tension1_stretch_n as f64,
        cable_joint::Fault::code_of(o.fault) as f64,
    ]
}

#[cfg(test)]
mod tests {
    use super::{applied_in_step, fill_counts, zero_phase_kinematics, CurrentFill};
    use cable_joint::filter::{Kinematics, TrackingObserver};

    /// The ticks a replay fills between a decimated log's rows lie on a
    /// monotone cubic through the rows' counts: at a row its speed is the
    /// rows' own from either side (a straight line's is the speed of half
    /// a step before, on an accelerating sensor too slow by half a step's
    /// change); it stays between two rows' counts and is flat where the
    /// sensor stands; without a row beyond the step it is the straight
    /// line.
    #[test]
    fn the_ticks_between_rows_keep_the_rows_speed_without_overshoot() {
        let h = 10usize;
        // A uniformly accelerating sensor, 0.05 counts per tick squared,
        // sampled every 10th tick, then standing at its last count.
        let accel = 0.05;
        let mut c: Vec<f64> = (0..6)
            .map(|i| 0.5 * accel * ((i * h) as f64).powi(2))
            .collect();
        c.extend([c[5], c[5]]);
        let steps: Vec<usize> = (0..c.len()).map(|k| if k == 0 { 1 } else { h }).collect();
        let fill = |k: usize, f: f64| fill_counts(&c, &steps, k, f, 1.0);
        let at_row = |k: usize| c[k].round();
        // Row 3 (tick 30): the true speed 1.5 counts per tick.
        let truth = accel * 30.0;
        let left = at_row(3) - fill(3, 0.9);
        let right = fill(4, 0.1) - at_row(3);
        let line = (at_row(3) - at_row(2)) / h as f64;
        assert!((line - truth).abs() > 0.15, "the line's speed {line}");
        for speed in [left, right] {
            assert!((speed - truth).abs() < 0.1, "{speed} against {truth}");
        }
        // Between every two rows: within their counts, never going back.
        for k in 1..c.len() {
            let (a, b) = (at_row(k - 1), at_row(k));
            let mut last = a;
            for j in 1..h {
                let v = fill(k, j as f64 / h as f64);
                assert!(
                    v >= a.min(b) - 1e-9 && v <= a.max(b) + 1e-9,
                    "row {k}, tick {j}: {v}"
                );
                assert!(v >= last - 1e-9, "row {k}, tick {j}: {v} after {last}");
                last = v;
            }
        }
        // Standing: flat. The last step has no row beyond it: a line.
        assert!((1..h).all(|j| (fill(6, j as f64 / h as f64) - at_row(5)).abs() < 1e-9));
        let (a, b) = (at_row(6), at_row(7));
        c[7] = c[6] + 4.0;
        let line = fill_counts(&c, &steps, 7, 0.25, 1.0);
        assert_eq!(line, a + 0.25 * (b + 4.0 - a));
    }

    /// On a 12 Hz sine sampled at 2 kHz, the core's 30 Hz observer lags:
    /// its velocity is late by about a tenth of a radian. Run forward and
    /// backward, the same observer's velocity and acceleration are in phase
    /// with the sine's (the amplitude keeps the observer's gain); a NaN
    /// sample is NaN in the output and leaves its neighbours finite.
    #[test]
    fn the_zero_phase_kinematics_are_the_observers_without_its_lag() {
        use std::f64::consts::PI;
        let (rate_hz, f_hz) = (2000.0, 12.0);
        let w = 2.0 * PI * f_hz;
        let n = 4000;
        let t = |k: usize| k as f64 / rate_hz;
        let mut pos: Vec<f32> = (0..n).map(|k| (1e-3 * (w * t(k)).sin()) as f32).collect();
        let observer = TrackingObserver::new(30.0, (1.0 / rate_hz) as f32);
        let mut st = Kinematics::default();
        observer.reset(&mut st, pos[0]);
        let causal: Vec<f64> = pos
            .iter()
            .map(|x| f64::from(observer.update(&mut st, *x).vel))
            .collect();
        pos[2000] = f32::NAN;
        let (vel, acc) = zero_phase_kinematics(&observer, &pos).unwrap();
        // The phase of `est` behind `truth` (its component along `truth`'s
        // quadrature), over whole periods away from the ends' start-up.
        let lag_rad = |est: &[f64], truth: &dyn Fn(f64) -> f64| {
            let (mut along, mut across) = (0.0, 0.0);
            for k in (500..3500).filter(|&k| k != 2000) {
                along += est[k] * truth(w * t(k));
                across += est[k] * truth(w * t(k) - PI / 2.0);
            }
            across.atan2(along)
        };
        let cos = |x: f64| x.cos();
        let minus_sin = |x: f64| -x.sin();
        let late = lag_rad(&causal, &cos);
        assert!(late > 0.05, "the causal observer lags: {late} rad");
        let v_lag = lag_rad(&vel, &cos);
        assert!(
            v_lag.abs() < 0.01 * late,
            "velocity: {v_lag} rad against {late}"
        );
        let a_lag = lag_rad(&acc, &minus_sin);
        assert!(a_lag.abs() < 0.01 * late, "acceleration: {a_lag} rad");
        assert!(vel[2000].is_nan() && acc[2000].is_nan());
        assert!(vel[1999].is_finite() && vel[2001].is_finite());
    }

    /// The currents the replay applies over one step, ticks 1 to `ticks`.
    fn step(first_a: f64, mean_a: Option<f64>, ticks: usize) -> Vec<f64> {
        (1..=ticks)
            .map(|j| applied_in_step(CurrentFill::Chatter, first_a, mean_a, j, ticks))
            .collect()
    }

    #[test]
    fn a_decimated_step_starts_at_the_recorded_reference_and_keeps_the_recorded_mean() {
        for ticks in [2, 3, 4, 9, 10, 25] {
            let c = step(0.5, Some(0.2), ticks);
            assert_eq!(
                c[0], 0.5,
                "the first tick applies the row before's reference"
            );
            let mean = c.iter().sum::<f64>() / ticks as f64;
            assert!((mean - 0.2).abs() < 1e-12, "{ticks} ticks: mean {mean}");
            // The chatter the first tick shows goes on: each tick departs
            // from the mean by as much, the other way from the one before.
            for w in c.windows(2) {
                assert!((w[1] - w[0]).abs() > 0.5, "{ticks} ticks: {c:?}");
            }
        }
        // No chatter on record: the mean held.
        assert_eq!(step(0.2, Some(0.2), 10), vec![0.2; 10]);
    }

    #[test]
    fn without_the_mean_the_recorded_reference_is_held() {
        // No `i_applied_a`: the row before's reference over the step.
        assert_eq!(step(0.5, None, 10), vec![0.5; 10]);
        // A row every tick: the recorded mean is the one current applied.
        assert_eq!(step(0.5, Some(0.3), 1), vec![0.3]);
        assert_eq!(step(0.5, None, 1), vec![0.5]);
    }

    #[test]
    fn ticks_per_row_rebuilds_the_tick_column_from_the_times_and_names_a_bad_row() {
        use super::set_ticks_per_row;
        use crate::log::Log;
        let log = |t: &[f64]| {
            let mut l = Log::with_columns(&["t_s", "x1_m"]).unwrap();
            for v in t {
                l.push_row(&[*v, 0.0]).unwrap();
            }
            l
        };
        // Rows 5 ms apart, one lost: ticks of a 0.5 ms loop.
        let mut l = log(&[0.0, 0.005, 0.010, 0.020, 0.025]);
        let note = set_ticks_per_row(&mut l, 10).unwrap();
        assert!(note.contains("the control period is 0.5000 ms"), "{note}");
        assert_eq!(l.col("tick").unwrap(), [0.0, 10.0, 20.0, 40.0, 50.0]);
        // Two rows within half a period: named by line.
        let mut l = log(&[0.0, 0.005, 0.005_1, 0.010, 0.015]);
        let e = set_ticks_per_row(&mut l, 10).unwrap_err().to_string();
        assert!(e.starts_with("line 4: t_s = 0.0051"), "{e}");
        assert!(set_ticks_per_row(&mut log(&[0.0, 0.1]), 0).is_err());
    }

    #[test]
    fn the_fits_fill_a_step_with_its_mean() {
        for j in 1..=10 {
            let c = applied_in_step(CurrentFill::Mean, 0.5, Some(0.2), j, 10);
            assert_eq!(c, 0.2, "tick {j}");
            let c = applied_in_step(CurrentFill::Mean, 0.5, None, j, 10);
            assert_eq!(c, 0.5, "tick {j}: the reference held without a mean");
        }
    }
}
