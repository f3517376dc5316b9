//! `host-sim estimate`: replay any log through the core and write every
//! estimate, the fused tip force and its bound included.
//!
//! ```text
//! host-sim estimate --log run.csv --config identified.toml --out est.csv
//! ```
//!
//! The control rate is the log's (median time step); every rate-dependent
//! setting the configuration cannot keep at that rate is derived from it
//! ([`cable_joint::Config::at_rate`]) and printed, so a rig's 1 kHz log runs
//! with the default configuration. The output has `t_s`, the run-time
//! signals, the estimates ([`crate::derive::EXTRA_COLUMNS`]: DOB
//! `f_ext_hat_n`, stretch `f_ext_stretch_n`, fused `f_ext_fused_n` with its
//! bound `f_ext_lo_n`..`f_ext_hi_n`, `fusion_flags`, cable-1 tension,
//! `fault_code`) and the log's `theta_rad`, `f_ext_n`, `theta_ref_rad` when
//! present. With a reference force (`f_ext_n`) the summary gives each
//! estimate's error and the bound's coverage.

use anyhow::{bail, Result};
use cable_joint::fusion::flags;
use cable_joint::Config;

use crate::derive::derive_noted;
use crate::log::Log;
use crate::plot::{Figure, Panel, Series};
use crate::stats::{Acc, Summary};

/// What a replay found, for the terminal.
#[derive(Clone, Debug)]
pub struct EstimateSummary {
    /// Rows replayed.
    pub rows: usize,
    /// Settings derived from the log (rate and what followed from it).
    pub derived: Vec<String>,
    /// First fault the replay latched: (row, code, text).
    pub first_fault: Option<(usize, u8, String)>,
    /// First fault the log itself records (`fault_code`, the board's):
    /// (row, code). From there the board's drive was off, so the summary's
    /// figures end at the earlier of the two.
    pub recorded_fault: Option<(usize, u8)>,
    /// Share of rows with slider 1 stuck (DOB blind to its band), of the
    /// rows before the first fault.
    pub slider1_stuck_share: f64,
    /// Share of rows whose DOB and stretch intervals disagree, of the rows
    /// before the first fault.
    pub inconsistent_share: f64,
    /// Mean width of the bound over the rows before the first fault, N
    /// (NaN when the fault came at the first row).
    pub mean_bound_width_n: f64,
    /// Share of the rows before the first fault whose bound excludes zero
    /// force (`lo > 0` or `hi < 0`): where it does not, the estimate cannot
    /// tell a load from none, nor its direction.
    pub excludes_zero_share: f64,
    /// With a reference force: errors of the DOB, stretch and fused estimate
    /// (estimate − reference), N, and the bound's coverage (share of rows
    /// whose reference lies inside it).
    pub against_reference: Option<ReferenceErrors>,
    /// With the log's own on-line estimate (a recording's `f_ext_fused_n`,
    /// computed every tick on the board): how far the replay's is from it.
    pub against_log: Option<LogDifference>,
}

/// The earlier of a log's own first fault and the replay's, each (row,
/// code): (row, code, whether it is the log's); the log's on a tie.
fn earlier_fault(
    recorded: Option<(usize, u8)>,
    replayed: Option<(usize, u8)>,
) -> Option<(usize, u8, bool)> {
    let recorded = recorded.map(|(k, code)| (k, code, true));
    let replayed = replayed.map(|(k, code)| (k, code, false));
    recorded.into_iter().chain(replayed).min_by_key(|f| f.0)
}

impl EstimateSummary {
    /// The fault that ends the summary's figures: the earlier of the log's
    /// own ([`Self::recorded_fault`]) and the replay's
    /// ([`Self::first_fault`]), as (row, code, whether it is the log's).
    pub fn ending_fault(&self) -> Option<(usize, u8, bool)> {
        earlier_fault(
            self.recorded_fault,
            self.first_fault.as_ref().map(|(k, code, _)| (*k, *code)),
        )
    }
}

/// The replay's estimates against those a recording carries (the board's,
/// computed on line at every tick, with the configuration of the run).
#[derive(Clone, Copy, Debug)]
pub struct LogDifference {
    /// Fused force, replay − log, N.
    pub fused_n: Summary,
    /// Joint angle, replay − log, rad (when the log has `theta_hat_rad`).
    pub theta_rad: Option<Summary>,
    /// Rows compared (before the replay's first fault and the log's, both
    /// finite).
    pub rows: usize,
    /// The log's row step in control ticks (1: every tick).
    pub decimation: u32,
    /// With a reference force and the board's bound (`f_ext_lo_n`,
    /// `f_ext_hi_n`): the share of the rows compared whose reference lies
    /// inside the board's bound, beside the replay's
    /// ([`ReferenceErrors::coverage`]).
    pub board_coverage: Option<f64>,
}

/// Errors against a logged reference force.
#[derive(Clone, Copy, Debug)]
pub struct ReferenceErrors {
    /// DOB as published.
    pub dob_n: Summary,
    /// Cable stretch.
    pub stretch_n: Summary,
    /// Fused.
    pub fused_n: Summary,
    /// Share of rows with the reference inside `[lo, hi]`.
    pub coverage: f64,
    /// Rows compared.
    pub rows: usize,
    /// Rows compared whose reference lies outside `[lo, hi]`.
    pub outside: usize,
    /// Rows left out because the reference is not measured there, and the
    /// first of them (0-based).
    pub not_measured: (usize, Option<usize>),
    /// Rows left out because the replay had latched a fault or the log
    /// records one (the drive off).
    pub faulted: usize,
}

/// Most tip force a reference may give, as a multiple of the squeeze the
/// joint's drive holds at its current limit
/// ([`cable_joint::wrist::drive_squeeze_limit_n`]: 54.6 N with the
/// datasheet's values): a hundred times that pulls its cable with some
/// 27 kN, far past what a surgical instrument's cable carries before it
/// breaks, so such a cell is not a force in newtons (another unit, a
/// corrupt cell) and would swamp every statistic of the summary.
pub const REFERENCE_FORCE_LIMIT_DRIVES: f32 = 100.0;

/// Why `value_n` is no reference force in newtons: beyond
/// [`REFERENCE_FORCE_LIMIT_DRIVES`] times the squeeze `machine`'s drive
/// holds (the text follows the value's name: "= 1e30 N is beyond ...");
/// `None` for a force the joint can carry, and for a non-finite value,
/// which the log's own checks name.
pub fn reference_force_refusal(
    value_n: f64,
    machine: &cable_joint::config::Machine,
) -> Option<String> {
    let drive_n = cable_joint::wrist::drive_squeeze_limit_n(
        machine,
        machine.pulley_radius_m,
        machine.gripper_length_m,
    );
    let limit_n = f64::from(REFERENCE_FORCE_LIMIT_DRIVES * drive_n);
    (value_n.is_finite() && value_n.abs() > limit_n).then(|| {
        format!(
            "= {} N is beyond any tip force the joint can carry ({REFERENCE_FORCE_LIMIT_DRIVES} \
             times the {drive_n:.1} N its drive holds at machine.current_limit_a = {} A, \
             {limit_n:.0} N): not a reference force in newtons",
            crate::log::value_text(value_n),
            machine.current_limit_a
        )
    })
}

/// The log's reference force (`f_ext_n`) within
/// [`REFERENCE_FORCE_LIMIT_DRIVES`] times the drive's squeeze
/// ([`reference_force_refusal`]); blank and non-finite cells are left to
/// the log's own checks. Every command that judges an estimate against
/// the reference calls it (`estimate`, `residual`'s project models,
/// `estimate-wrist`'s jaws, `identify`'s weights through `estimate`).
///
/// # Errors
/// The first cell beyond it, by line.
pub fn check_reference_force(log: &Log, machine: &cable_joint::config::Machine) -> Result<()> {
    let Some(reference) = log.col("f_ext_n") else {
        return Ok(());
    };
    for (k, &v) in reference.iter().enumerate() {
        if let Some(why) = reference_force_refusal(v, machine) {
            bail!(
                "line {}: column \"f_ext_n\" {why}; check the log's units",
                crate::log::line_of_row(k)
            );
        }
    }
    Ok(())
}

/// Replay `log` with `config` (rate derived from the log) and summarise.
pub fn estimate(log: &Log, config: &Config) -> Result<(Log, EstimateSummary)> {
    check_reference_force(log, &config.machine)?;
    let (out, clock, derived) = derive_noted(log, config)?;
    check_finite(log, &out)?;
    let col = |n: &str| out.col_required(n).map(<[f64]>::to_vec);
    let (fault, fl) = (col("fault_code")?, col("fusion_flags")?);
    let (lo, hi, fused) = (
        col("f_ext_lo_n")?,
        col("f_ext_hi_n")?,
        col("f_ext_fused_n")?,
    );
    let rows = out.len();
    let first_fault = fault.iter().position(|c| *c != 0.0).map(|k| {
        let code = fault[k] as u8;
        let text = cable_joint::Fault::from_code(code)
            .map(|f| f.to_string())
            .unwrap_or_else(|| "unknown".into());
        (k, code, text)
    });
    // The shares and the bound's width describe the estimator on the log's
    // data: the rows before a latched fault (after it the replay idles and
    // its bound grows without a measurement behind it), and before a fault
    // the log records (the board's drive off: the joint falls or relaxes,
    // which no estimate of a controlled joint's load is judged on).
    let recorded_fault = crate::ingest::first_recorded_fault(log);
    let live = earlier_fault(
        recorded_fault,
        first_fault.as_ref().map(|(k, code, _)| (*k, *code)),
    )
    .map_or(rows, |f| f.0);
    let share = |bit: u8| {
        fl[..live].iter().filter(|f| (**f as u8) & bit != 0).count() as f64 / live.max(1) as f64
    };
    let (mut width, mut excludes_zero) = (Acc::default(), 0usize);
    for k in 0..live {
        width.push(hi[k] - lo[k]);
        excludes_zero += usize::from(lo[k] > 0.0 || hi[k] < 0.0);
    }
    let against_reference = match log.col("f_ext_n") {
        Some(reference) => {
            let (dob, stretch) = (col("f_ext_hat_n")?, col("f_ext_stretch_n")?);
            let (mut ed, mut es, mut ef) = (Acc::default(), Acc::default(), Acc::default());
            let (mut inside, mut n) = (0usize, 0usize);
            let (mut not_measured, mut faulted) = ((0usize, None), 0usize);
            for k in 0..rows {
                let f = reference[k];
                if !f.is_finite() {
                    not_measured.0 += 1;
                    not_measured.1.get_or_insert(k);
                    continue;
                }
                if k >= live {
                    faulted += 1;
                    continue;
                }
                ed.push(dob[k] - f);
                es.push(stretch[k] - f);
                ef.push(fused[k] - f);
                n += 1;
                if lo[k] <= f && f <= hi[k] {
                    inside += 1;
                }
            }
            (n > 0).then(|| ReferenceErrors {
                dob_n: ed.summary(1.0),
                stretch_n: es.summary(1.0),
                fused_n: ef.summary(1.0),
                coverage: inside as f64 / n as f64,
                rows: n,
                outside: n - inside,
                not_measured,
                faulted,
            })
        }
        None => None,
    };
    let against_log = match log.col("f_ext_fused_n") {
        Some(board) => {
            let board_theta = log.col("theta_hat_rad");
            let theta = col("theta_hat_rad")?;
            let board_bound = log.col("f_ext_lo_n").zip(log.col("f_ext_hi_n"));
            let reference = log.col("f_ext_n");
            let (mut ef, mut et) = (Acc::default(), Acc::default());
            let (mut inside, mut judged) = (0usize, 0usize);
            for k in 0..live {
                if board[k].is_finite() {
                    ef.push(fused[k] - board[k]);
                }
                if let (Some((lo, hi)), Some(f)) = (board_bound, reference) {
                    if f[k].is_finite() && lo[k].is_finite() && hi[k].is_finite() {
                        judged += 1;
                        inside += usize::from(lo[k] <= f[k] && f[k] <= hi[k]);
                    }
                }
                if let Some(b) = board_theta.filter(|b| b[k].is_finite()) {
                    et.push(theta[k] - b[k]);
                }
            }
            let (fused_n, theta) = (ef.summary(1.0), et.summary(1.0));
            (fused_n.n > 0).then(|| LogDifference {
                fused_n,
                theta_rad: (theta.n > 0).then_some(theta),
                rows: fused_n.n as usize,
                decimation: clock.decimation,
                board_coverage: (judged > 0).then(|| inside as f64 / judged as f64),
            })
        }
        None => None,
    };
    Ok((
        out,
        EstimateSummary {
            rows,
            derived,
            first_fault,
            recorded_fault,
            slider1_stuck_share: share(flags::SLIDER1_STUCK),
            inconsistent_share: share(flags::INCONSISTENT),
            mean_bound_width_n: width.summary(1.0).mean,
            excludes_zero_share: excludes_zero as f64 / live.max(1) as f64,
            against_reference,
            against_log,
        },
    ))
}

/// The figure `estimate --plot` writes from the replay's output `out`: the
/// tip force (the fused estimate inside its bound, the DOB as published,
/// the stretch estimate, and the log's reference `f_ext_n` where it has
/// one) and the joint angle (the JAE's, and the log's `theta_rad` where it
/// has one), against time. `title` heads the force panel (the log's name;
/// the first fault, the log's own or the replay's, is added to it).
///
/// # Errors
/// A column the replay always writes is missing from `out`.
pub fn figure(out: &Log, title: &str, s: &EstimateSummary) -> Result<Figure> {
    let t = out.time_s()?.to_vec();
    let col = |n: &str| out.col_required(n).map(<[f64]>::to_vec);
    let fault = s
        .ending_fault()
        .map_or(String::new(), |(k, code, recorded)| {
            let what = if recorded {
                format!("the log records fault {code}")
            } else {
                format!("fault {code} latched")
            };
            format!(" ({what} at t = {:.3} s)", t[k])
        });
    let mut force = Panel::new(format!("{title}: tip force{fault}"), "t [s]", "F_ext [N]")
        // In drawing order: the noisy DOB underneath, the fused estimate
        // and the reference on top.
        .with(Series::line("DOB (seed)", t.clone(), col("f_ext_hat_n")?))
        .with(Series::line("stretch", t.clone(), col("f_ext_stretch_n")?))
        .with(Series::line("bound, low", t.clone(), col("f_ext_lo_n")?))
        .with(Series::line("bound, high", t.clone(), col("f_ext_hi_n")?))
        .with(Series::line("fused", t.clone(), col("f_ext_fused_n")?));
    if let Some(reference) = out.col("f_ext_n") {
        force = force.with(Series::line(
            "reference f_ext_n",
            t.clone(),
            reference.to_vec(),
        ));
    }
    let deg = |v: &[f64]| v.iter().map(|r| r.to_degrees()).collect::<Vec<_>>();
    let mut angle = Panel::new("joint angle", "t [s]", "theta [deg]").with(Series::line(
        "JAE theta_hat",
        t.clone(),
        deg(&col("theta_hat_rad")?),
    ));
    if let Some(theta) = out.col("theta_rad") {
        angle = angle.with(Series::line("magnetic encoder theta_rad", t, deg(theta)));
    }
    let mut fig = Figure::grid(vec![force, angle], 1);
    fig.panel_px = (1000, 420);
    Ok(fig)
}

/// Every estimate the replay wrote is finite; else the error names the
/// input's line and, when one is the cause, the input cell beyond the core's
/// `f32` range (an `inf` would otherwise surface as a write error naming the
/// output file).
fn check_finite(input: &Log, out: &Log) -> Result<()> {
    // Copied from the input, where a blank cell stays blank.
    const COPIED: [&str; 5] = ["t_s", "i_ref_a", "theta_rad", "f_ext_n", "theta_ref_rad"];
    for name in out.names() {
        let Some(values) = out.col(name).filter(|_| !COPIED.contains(&name)) else {
            continue;
        };
        if let Some(k) = values.iter().position(|v| !v.is_finite()) {
            // The replay reads the previous row's current command, so the
            // cause may sit one line above.
            let cause = (k.saturating_sub(1)..=k)
                .rev()
                .flat_map(|row| {
                    input
                        .names()
                        .into_iter()
                        .filter_map(move |n| input.col(n).map(|c| (row, n, c[row])))
                })
                .find(|(_, _, v)| v.is_finite() && v.abs() > f64::from(f32::MAX))
                .map(|(row, n, v)| {
                    format!(
                        "; column {} = {v:e} on line {} is beyond the core's f32 range",
                        crate::log::quoted(n),
                        crate::log::line_of_row(row)
                    )
                })
                .unwrap_or_default();
            bail!(
                "line {}: the core's {} is {}{cause}",
                crate::log::line_of_row(k),
                crate::log::quoted(name),
                values[k]
            );
        }
    }
    Ok(())
}
