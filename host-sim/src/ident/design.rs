//! The design matrix of a fit over replayed logs, the least squares on it and
//! the fit's report.

use anyhow::{anyhow, bail, Context, Result};
use cable_joint::lsq::{BatchLsq, Fit, LsqConfig};
use cable_joint::Config;

use super::replay::X2Switch;
use super::{
    FitReport, IdentOptions, ModelTerm, ParamEstimate, Prepared, Regressor, MAX_REGRESSORS,
};
use crate::log::Log;
use crate::stats::{correlation_time, ErrorStats};

fn to_anyhow(e: cable_joint::lsq::LsqError) -> anyhow::Error {
    anyhow!("{e}")
}

/// Rows one log lost in one fit, by reason.
#[derive(Default)]
pub(super) struct RowLoss {
    start_up: usize,
    faulted: usize,
    still: usize,
    /// Rows with a non-finite target or regressor: count, first (row, column).
    not_finite: usize,
    first_not_finite: Option<(usize, &'static str)>,
}

/// What a model explains.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Target {
    /// `K_m i - J_m phi''` through `Q` (no-load motor).
    MotorTorque,
    /// Magnetic encoder, rad.
    Theta,
    /// DOB cable-1 tension `tension1_hat_n` (Eq. 21).
    Tension,
}

/// Selected rows of one or more logs: regressor columns and the target.
pub(super) struct Design {
    pub(super) cols: Vec<Vec<f64>>,
    pub(super) y: Vec<f64>,
}

/// The design matrix of `regs` against `target` over the usable rows of
/// every replayed log (after the start-up, not faulted, not still for the
/// tension fits, finite), with a warning for each log that lost rows to its
/// data. One loop per log keeps each row's reason for being left out next
/// to the row count it goes into.
pub(super) fn design(
    preps: &[Prepared],
    regs: &[Regressor],
    target: Target,
    opts: &IdentOptions,
) -> Result<Design> {
    let mut d = Design {
        cols: vec![Vec::new(); regs.len()],
        y: Vec::new(),
    };
    let filtered = opts.filter_regressors && target != Target::Theta;
    let x2_switch = if target == Target::Theta {
        X2Switch::Jae
    } else {
        X2Switch::Tension
    };
    for p in preps {
        let mut cols = Vec::with_capacity(regs.len());
        for r in regs {
            let c = p.column(*r, x2_switch)?;
            cols.push(if filtered { p.dob_filter(&c) } else { c });
        }
        let y = match target {
            Target::Theta => p
                .replay
                .log
                .col_opt("theta_rad")
                .ok_or_else(|| {
                    anyhow!(
                        "{}: the JAE needs the magnetic encoder (column `theta_rad`)",
                        p.label
                    )
                })?
                .into_iter()
                .map(|v| v.unwrap_or(f64::NAN))
                .collect(),
            Target::Tension => p.col("tension1_hat_n")?,
            Target::MotorTorque => {
                // load_torque = Q[K_m i - B phi'] - J_m Q[phi''] (DOB), so
                // adding back B Q[phi'] leaves Q[K_m i - J_m phi''].
                let b = f64::from(p.cfg.dob.viscous_nm_s_rad);
                let vel = p.col("phi_vel_rad_s")?;
                let vel = if opts.filter_regressors {
                    p.dob_filter(&vel)
                } else {
                    vel
                };
                p.col("load_torque_nm")?
                    .iter()
                    .zip(&vel)
                    .map(|(tau, w)| tau + b * w)
                    .collect()
            }
        };
        let (cols, y) = if opts.post_filter_hz > 0.0 && target != Target::Theta {
            let lp = |c: &[f64]| p.low_pass(c, opts.post_filter_hz);
            (cols.iter().map(|c| lp(c)).collect::<Vec<_>>(), lp(&y))
        } else {
            (cols, y)
        };
        // Ticks with the joint (nearly) at rest, and the hold-off after them
        // (the DOB's Q remembers them for a few time constants).
        let holdoff = (opts.holdoff_s / p.cfg.period_s() as f64).round() as usize;
        let mut still = vec![false; p.len()];
        if target == Target::Tension && opts.min_joint_vel_rad_s > 0.0 {
            let w = &p.theta_kin()?.0;
            let mut since = usize::MAX;
            for (k, s) in still.iter_mut().enumerate() {
                since = if w[k].abs() < opts.min_joint_vel_rad_s {
                    0
                } else {
                    since.saturating_add(1)
                };
                *s = since <= holdoff;
            }
        }
        let fault = p.replay.log.col_required("fault_code")?;
        let mut loss = RowLoss::default();
        for k in (0..p.len()).filter(|&k| p.measured(k)) {
            let bad = (!y[k].is_finite()).then_some(target.column()).or_else(|| {
                (0..cols.len())
                    .find(|&j| !cols[j][k].is_finite())
                    .map(|j| regs[j].symbol())
            });
            if !p.usable[k] {
                if fault[k] != 0.0 {
                    loss.faulted += 1;
                } else {
                    loss.start_up += 1;
                }
            } else if still[k] {
                loss.still += 1;
            } else if let Some(col) = bad {
                loss.not_finite += 1;
                loss.first_not_finite.get_or_insert((p.log_row(k), col));
            } else {
                for (dc, c) in d.cols.iter_mut().zip(&cols) {
                    dc.push(c[k]);
                }
                d.y.push(y[k]);
            }
        }
        warn_row_loss(p, &loss, target, opts);
    }
    if d.y.is_empty() {
        let faults: Vec<String> = preps
            .iter()
            .filter_map(|p| {
                p.first_fault.map(|(t, code)| {
                    let name = crate::ingest::fault_words(code);
                    format!("{}: the replay latched {name} at t = {t:.3} s", p.label)
                })
            })
            .collect();
        bail!(
            "no usable rows (after the start-up, faults and the velocity limit){}{}",
            if faults.is_empty() { "" } else { "; " },
            faults.join("; ")
        );
    }
    Ok(d)
}

/// Prints (once per log and fit) how many rows a fit left out and why, when
/// rows were lost to the data rather than to the settings alone: a fault
/// the replay latched, a cell not measured or not finite, or a magnetic
/// encoder column with gaps (the joint angle then comes from the JAE).
fn warn_row_loss(p: &Prepared, loss: &RowLoss, target: Target, opts: &IdentOptions) {
    use std::sync::atomic::Ordering;
    let gap = p.loss.theta_gap.filter(|_| p.theta_source != "theta_rad");
    if loss.faulted == 0 && loss.not_finite == 0 && gap.is_none() {
        return;
    }
    if p.loss.warned.swap(true, Ordering::Relaxed) {
        return;
    }
    let n = p.measured_rows();
    let used = n - loss.start_up - loss.faulted - loss.still - loss.not_finite;
    let mut why = Vec::new();
    if loss.start_up > 0 {
        why.push(format!(
            "{} in the first {} s (--skip-start-s)",
            loss.start_up, opts.skip_start_s
        ));
    }
    if loss.faulted > 0 {
        let fault = p
            .loss
            .fault
            .as_deref()
            .unwrap_or("the replay latched a fault");
        why.push(format!("{} from where {fault}", loss.faulted));
    }
    if loss.still > 0 {
        why.push(format!(
            "{} with |theta'| below {} rad/s (--min-joint-vel-rad-s, theta' from {})",
            loss.still, opts.min_joint_vel_rad_s, p.theta_source
        ));
    }
    if let Some((row, col)) = loss.first_not_finite {
        why.push(format!(
            "{} with column {col} not measured or not finite (first at line {})",
            loss.not_finite,
            crate::log::line_of_row(row)
        ));
    }
    let mut text = format!(
        "warning: {}: the {} fit uses {used} of {n} rows; left out: {}",
        p.label,
        target.fit_name(),
        why.join(", ")
    );
    if let Some((rows, first)) = gap {
        text.push_str(&format!(
            ". Column theta_rad is not measured on {rows} row(s) (first at line {}), so the \
             joint angle of this log is the JAE estimate theta_hat_rad, not the magnetic encoder",
            crate::log::line_of_row(first)
        ));
    }
    eprintln!("{text}");
}

impl Target {
    /// The column a fit explains.
    fn column(self) -> &'static str {
        match self {
            Target::MotorTorque => "load_torque_nm",
            Target::Theta => "theta_rad",
            Target::Tension => "tension1_hat_n",
        }
    }

    /// The fit's name in messages.
    fn fit_name(self) -> &'static str {
        match self {
            Target::MotorTorque => "B_m",
            Target::Theta => "JAE",
            Target::Tension => "tension",
        }
    }
}

/// Least squares on the columns `active` of `d`.
pub(super) fn solve(
    d: &Design,
    active: &[usize],
    opts: &IdentOptions,
) -> Result<Fit<MAX_REGRESSORS>> {
    let mut ls = BatchLsq::<MAX_REGRESSORS>::new(
        active.len(),
        LsqConfig {
            max_condition: opts.max_condition,
        },
    )
    .map_err(to_anyhow)?;
    let mut row = [0.0f64; MAX_REGRESSORS];
    for k in 0..d.y.len() {
        for (slot, j) in row.iter_mut().zip(active) {
            *slot = d.cols[*j][k];
        }
        ls.push(&row, d.y[k]).map_err(to_anyhow)?;
    }
    ls.solve().map_err(to_anyhow)
}

pub(super) fn report(
    model: &str,
    d: &Design,
    terms: &[ModelTerm],
    active: &[usize],
    fit: &Fit<MAX_REGRESSORS>,
    err_scale: f64,
    err_unit: &'static str,
) -> FitReport {
    let params = active
        .iter()
        .enumerate()
        .map(|(k, j)| {
            let t = terms[*j];
            ParamEstimate {
                regressor: t.regressor,
                symbol: t.regressor.symbol(),
                name: t.param,
                unit: t.unit,
                value: fit.params[k],
                std: fit.std_dev[k],
                pct_sigma: fit.pct_sigma(k),
                pct_sigma_eff: f64::NAN,
            }
        })
        .collect::<Vec<_>>();
    let residual: Vec<f64> = (0..d.y.len())
        .map(|i| {
            let pred: f64 = active
                .iter()
                .enumerate()
                .map(|(k, j)| fit.params[k] * d.cols[*j][i])
                .sum();
            pred - d.y[i]
        })
        .collect();
    let errors = ErrorStats::of(residual.iter().copied(), err_scale, err_unit);
    let tau = correlation_time(&residual);
    let params = params
        .into_iter()
        .map(|p| ParamEstimate {
            pct_sigma_eff: p.pct_sigma * tau.sqrt(),
            ..p
        })
        .collect();
    FitReport {
        model: model.to_owned(),
        params,
        rows: fit.rows,
        sigma: fit.sigma,
        condition: fit.condition,
        residual_corr_ticks: tau,
        errors,
    }
}

pub(super) fn fit_terms(
    model: &str,
    preps: &[Prepared],
    terms: &[ModelTerm],
    target: Target,
    opts: &IdentOptions,
    err_scale: f64,
    err_unit: &'static str,
) -> Result<FitReport> {
    let regs: Vec<Regressor> = terms.iter().map(|t| t.regressor).collect();
    let d = design(preps, &regs, target, opts)?;
    let active: Vec<usize> = (0..terms.len()).collect();
    let fit = solve(&d, &active, opts).with_context(|| format!("fitting {model}"))?;
    Ok(report(model, &d, terms, &active, &fit, err_scale, err_unit))
}

/// Errors of an identified model on other logs (`model - measured`).
pub(super) fn evaluate(
    report: &FitReport,
    preps: &[Prepared],
    target: Target,
    opts: &IdentOptions,
    err_scale: f64,
    err_unit: &'static str,
) -> Result<ErrorStats> {
    let regs: Vec<Regressor> = report.params.iter().map(|p| p.regressor).collect();
    let d = design(preps, &regs, target, opts)?;
    Ok(ErrorStats::of(
        (0..d.y.len()).map(|i| {
            let pred: f64 = report
                .params
                .iter()
                .zip(&d.cols)
                .map(|(p, c)| p.value * c[i])
                .sum();
            pred - d.y[i]
        }),
        err_scale,
        err_unit,
    ))
}

pub(super) fn prepare_all(
    logs: &[(&str, &Log)],
    config: &Config,
    opts: &IdentOptions,
) -> Result<Vec<Prepared>> {
    opts.check()?;
    if logs.is_empty() {
        bail!("no log given");
    }
    logs.iter()
        .map(|(label, log)| Prepared::new(label, log, config, opts))
        .collect()
}
