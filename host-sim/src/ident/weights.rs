//! The stretch estimate's force scale from known weights.
//!
//! The cables' stiffnesses, and with them the stretch estimate, the fused
//! estimate and the slack check, take their force scale from the return
//! spring's rate (`K_w2 = K_s / slope`, cable 2's stretch per unit of
//! spring travel while slider 2 slips, Eq. 10-12). `identify` measures
//! that rate through the motor, but where slider 1 sticks and slips along
//! the calibration's sweeps the DOB's tension saws by its friction band and
//! the fit cannot pin the rate down (a drawn plant with slider 1's static
//! friction 1.43 times its kinetic: 412 N/m, `%sigma` 17.7, for a spring of
//! 476 N/m; see `docs/force.md`); the datasheet's rate then stands, with a
//! tolerance that says how far it may be off. A load the user knows measures
//! the scale directly: hang weights at the tip while the joint holds, record
//! the holds with the reference force in `f_ext_n`, and
//! `identify --procedure weights` compares the stretch estimate with it (a
//! recording without the column takes the weights as steps by its time,
//! [`parse_reference_steps`]).
//!
//! # The fit
//!
//! Each log is replayed through the core with the configuration
//! ([`crate::estimate::estimate`], rate derived from the log), up to a latched
//! fault. A hold is a run of rows whose reference stays within
//! [`WeightsOptions::level_band_n`] of its first value; its settled part
//! starts [`WeightsOptions::settle_s`] after it began (the report's hold
//! rule), and gives one point: the means of the reference and of the
//! stretch estimate. Within a log the points are taken about their means
//! (each log's own zero: the estimate at an unloaded hold carries the
//! friction the joint stopped with), and the stretch estimate's change is
//! fitted as `s` times the reference's change over all logs by least
//! squares, with the standard deviation of `s` from the points' scatter.
//! Since every force of the stretch estimate is a stiffness times a
//! measured length, `s` is the ratio of the configured stiffnesses to the
//! machine's, and the calibration divides `machine.spring_n_m` and both
//! cable stiffnesses by it. `fusion.stiffness_tolerance` becomes the
//! scale's 95 % half-width (Student's t on the holds' degrees of freedom
//! times its standard deviation), or the difference of the scales fitted on
//! the logs loaded one way and the other if larger, relative to `s`, plus
//! the reference's own tolerance ([`WeightsOptions::reference_tolerance`]).
//! A pin friction the joint's torque balance fitted
//! ([`cable_joint::config::FusionConfig::pin_identified`]) is divided by
//! `s` too: that balance reads cable 2's torque through the same spring
//! rate (`r K_w2 (r theta - x2)`, `K_w2` from the spring and `c4`), so every
//! torque it fits carries the same scale (on drawn plant 82, 5.73 mN·m
//! before, above the plant's static 5.31, and 4.22 after, between its
//! kinetic 3.70 and its static level). Model C's upper bound, which the
//! tension model sets through the motor's torque constant, is left as it
//! is. The calibration is written only when its
//! tolerance is narrower than the configuration's (the weights know the
//! scale better than what the configuration had); otherwise it is an error
//! and nothing is written. Where the weights' scale and the configuration's
//! (1 within its tolerance) differ by more than the 95 % half-width of
//! their difference, one of them is off by more than it says and nothing
//! here tells which ([`scale_disagreement`]): the tolerance written widens
//! by that ratio and `identify` warns. Combining the two scales by their
//! tolerances instead of replacing one by the other was measured at stop
//! 81 and not kept (`docs/force.md`, "The weights combined with the
//! identification").
//!
//! Every log fitted and every validation log is replayed again with the
//! calibrated configuration, and the report gives each hold's stretch and
//! fused estimate before and after. A hold that only one of the two
//! replays settled (a fault latched before it in the other: the slack
//! check reads cable 1's tension through the stiffnesses the calibration
//! changed) is left out of that comparison and named; the scale is fitted
//! on the replay with the configuration given either way.

use anyhow::{bail, Context, Result};
use cable_joint::Config;
use serde::Serialize;

use crate::log::Log;

/// Options of the weights calibration.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct WeightsOptions {
    /// Time after a hold's reference settled before its rows count, s.
    pub settle_s: f64,
    /// Shortest settled part of a hold that gives a point, s.
    pub min_settled_s: f64,
    /// Band within which the reference counts as one hold, N (a reference
    /// sensor's noise; weights give a step function).
    pub level_band_n: f64,
    /// Smallest change of the reference within a log that the fit uses, N.
    pub min_step_n: f64,
    /// Relative tolerance of the reference force itself (the weights' mass
    /// and the lever arm at which they hang), added to the scale's own.
    pub reference_tolerance: f64,
}

impl Default for WeightsOptions {
    fn default() -> Self {
        Self {
            settle_s: 1.0,
            min_settled_s: 0.2,
            level_band_n: 0.05,
            min_step_n: 0.1,
            reference_tolerance: 0.01,
        }
    }
}

/// One settled hold.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct WeightsHold {
    /// The log's label.
    pub log: String,
    /// Whether it entered the fit (else a validation log's).
    pub fitted: bool,
    /// Settled part: first and last time, s.
    pub t_s: (f64, f64),
    /// Mean reference force, N.
    pub reference_n: f64,
    /// Mean stretch estimate with the configuration given, N.
    pub stretch_before_n: f64,
    /// Mean stretch estimate with the calibrated configuration, N.
    pub stretch_after_n: f64,
    /// Mean fused estimate with the configuration given, N.
    pub fused_before_n: f64,
    /// Mean fused estimate with the calibrated configuration, N.
    pub fused_after_n: f64,
}

/// Result of [`calibrate_weights`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct WeightsFit {
    /// Every settled hold, fitted and validation.
    pub holds: Vec<WeightsHold>,
    /// Logs whose holds entered the fit (two reference levels or more).
    pub logs_fitted: usize,
    /// The stretch estimate's change per unit of the reference's, and its
    /// `%sigma`.
    pub scale: (f64, f64),
    /// `machine.spring_n_m` before and after, N/m.
    pub spring_n_m: (f64, f64),
    /// `fusion.stiffness_tolerance` before and after.
    pub stiffness_tolerance: (f64, f64),
    /// The weights' scale against the configuration's
    /// ([`scale_disagreement`]): above 1 they disagree by more than both
    /// tolerances allow, and the tolerance written was widened by it.
    pub disagreement: f64,
    /// `fusion.pin_coulomb_nm` before and after, N·m, when it is a fitted
    /// level; `None` when it is model C's upper bound, left as it is.
    pub pin_coulomb_nm: Option<(f64, f64)>,
    /// Holds only one of the two replays (with the configuration given and
    /// with the calibrated one) settled, because a fault latched before
    /// them in the other: left out of the comparison (the scale is fitted
    /// on the replay with the configuration given).
    pub unmatched: Vec<String>,
    /// RMS over the fitted holds of the stretch estimate's change less the
    /// reference's (each log about its own zero), before and after, N.
    pub fit_error_n: (f64, f64),
    /// The same over the validation logs' holds (NaN without any), N.
    pub validation_error_n: (f64, f64),
}

/// A step reference written as `T0=F0,T1=F1,...`: the force `F_k`, N,
/// from the log's time `T_k`, s, until the next step (strictly increasing
/// times; before the first, not measured).
pub fn parse_reference_steps(spec: &str) -> Result<Vec<(f64, f64)>> {
    let mut steps: Vec<(f64, f64)> = Vec::new();
    for part in spec.split(',') {
        let parsed = part.split_once('=').and_then(|(t, f)| {
            let (t, f) = (t.trim().parse::<f64>().ok()?, f.trim().parse::<f64>().ok()?);
            (t.is_finite() && f.is_finite()).then_some((t, f))
        });
        let Some((t, f)) = parsed else {
            bail!(
                "`{part}` in the reference steps `{spec}` is not TIME_S=FORCE_N (finite numbers)"
            );
        };
        if let Some(&(before, _)) = steps.last() {
            if t <= before {
                let how = if t == before {
                    "repeat a time"
                } else {
                    "go back in time"
                };
                bail!("the reference steps `{spec}` {how} at `{part}` (after {before} s)");
            }
        }
        steps.push((t, f));
    }
    Ok(steps)
}

/// Write the step reference `steps` ([`parse_reference_steps`]) into
/// `log`'s `f_ext_n` by its `t_s`; refused when the log has its own.
pub fn set_reference_steps(log: &mut Log, steps: &[(f64, f64)], label: &str) -> Result<()> {
    if log.has("f_ext_n") {
        bail!(
            "`{label}` has its own f_ext_n column: give the reference steps or the column, \
             not both"
        );
    }
    let t = log.time_s()?.to_vec();
    if let (Some(&first), Some(&last)) = (t.first(), t.last()) {
        if let Some((from, f)) = steps.iter().find(|(from, _)| *from > last) {
            bail!(
                "the reference step `{from}={f}` lies after `{label}`'s last row: the log runs \
                 from {first} s to {last} s (steps are times in the log's own t_s)"
            );
        }
    }
    let values: Vec<Option<f64>> = t
        .iter()
        .map(|&t| {
            steps
                .iter()
                .rev()
                .find(|(from, _)| t >= *from)
                .map(|&(_, f)| f)
        })
        .collect();
    log.set_col_opt("f_ext_n", &values)?;
    Ok(())
}

/// A settled hold's means.
#[derive(Clone, Copy)]
struct Point {
    log: usize,
    t_s: (f64, f64),
    reference_n: f64,
    stretch_n: f64,
    fused_n: f64,
}

/// The settled holds of `log` replayed with `config`.
fn holds(
    label: &str,
    index: usize,
    log: &Log,
    config: &Config,
    opts: &WeightsOptions,
) -> Result<Vec<Point>> {
    let Some(reference) = log.col("f_ext_n") else {
        bail!(
            "`{label}` has no f_ext_n column: the weights calibration needs the reference \
             force at the tip (the weights' force, N) in every row of a hold"
        );
    };
    let (out, _) =
        crate::estimate::estimate(log, config).with_context(|| format!("replaying `{label}`"))?;
    let t = out.col_required("t_s")?;
    let (stretch, fused, fault) = (
        out.col_required("f_ext_stretch_n")?,
        out.col_required("f_ext_fused_n")?,
        out.col_required("fault_code")?,
    );
    let live = fault.iter().position(|c| *c != 0.0).unwrap_or(fault.len());
    let mut points = Vec::new();
    let mut k = 0;
    while k < live {
        if !reference[k].is_finite() {
            k += 1;
            continue;
        }
        let (start, level) = (k, reference[k]);
        while k < live
            && reference[k].is_finite()
            && (reference[k] - level).abs() <= opts.level_band_n
        {
            k += 1;
        }
        let settled: Vec<usize> = (start..k)
            .filter(|&j| t[j] - t[start] >= opts.settle_s)
            .collect();
        let (Some(&first), Some(&last)) = (settled.first(), settled.last()) else {
            continue;
        };
        if t[last] - t[first] < opts.min_settled_s {
            continue;
        }
        let mean = |v: &[f64]| settled.iter().map(|&j| v[j]).sum::<f64>() / settled.len() as f64;
        points.push(Point {
            log: index,
            t_s: (t[first], t[last]),
            reference_n: mean(reference),
            stretch_n: mean(stretch),
            fused_n: mean(fused),
        });
    }
    Ok(points)
}

/// Each point's `(reference, stretch estimate)` about its log's means, for
/// the logs whose reference changes by at least `min_step_n`, and how many
/// logs those are.
fn about_log_means(points: &[Point], min_step_n: f64) -> (Vec<(f64, f64)>, usize) {
    let (mut out, mut used) = (Vec::new(), 0);
    let mut logs: Vec<usize> = points.iter().map(|p| p.log).collect();
    logs.dedup();
    for log in logs {
        let idx: Vec<usize> = (0..points.len())
            .filter(|&i| points[i].log == log)
            .collect();
        let refs = idx.iter().map(|&i| points[i].reference_n);
        let span = refs.clone().fold(f64::NEG_INFINITY, f64::max)
            - refs.clone().fold(f64::INFINITY, f64::min);
        if idx.len() < 2 || span < min_step_n {
            continue;
        }
        let n = idx.len() as f64;
        let r0 = refs.sum::<f64>() / n;
        let e0 = idx.iter().map(|&i| points[i].stretch_n).sum::<f64>() / n;
        out.extend(
            idx.iter()
                .map(|&i| (points[i].reference_n - r0, points[i].stretch_n - e0)),
        );
        used += 1;
    }
    (out, used)
}

/// The scale fitted on the logs loaded one way less that on the logs
/// loaded the other (a log's way: the sign of its largest reference), or
/// zero unless both ways have a log.
fn direction_spread(points: &[Point], min_step_n: f64) -> f64 {
    let way = |log: usize| {
        points
            .iter()
            .filter(|p| p.log == log)
            .map(|p| p.reference_n)
            .fold(0.0_f64, |a, r| if r.abs() > a.abs() { r } else { a })
            .signum()
    };
    let scale = |sign: f64| {
        let own: Vec<Point> = points
            .iter()
            .filter(|p| way(p.log) == sign)
            .copied()
            .collect();
        slope(&about_log_means(&own, min_step_n).0)
    };
    match (scale(1.0), scale(-1.0)) {
        (Some(a), Some(b)) => (a - b).abs(),
        _ => 0.0,
    }
}

/// The least-squares slope through the origin of `(reference, estimate)`
/// pairs (`None` when the reference does not change).
fn slope(pairs: &[(f64, f64)]) -> Option<f64> {
    let sxx: f64 = pairs.iter().map(|(r, _)| r * r).sum();
    (sxx > 0.0).then(|| pairs.iter().map(|(r, e)| r * e).sum::<f64>() / sxx)
}

/// The two-sided 95 % quantile of Student's t with `dof` degrees of
/// freedom (1.96 beyond 30): the scale's half-width from few holds.
fn student_t_975(dof: usize) -> f64 {
    const T: [f64; 30] = [
        12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160,
        2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056,
        2.052, 2.048, 2.045, 2.042,
    ];
    dof.checked_sub(1)
        .and_then(|i| T.get(i))
        .copied()
        .unwrap_or(1.96)
}

/// RMS of the stretch estimate less the reference about each log's means
/// (NaN when no log changes its reference).
fn change_error_n(points: &[Point], min_step_n: f64) -> f64 {
    let (d, _) = about_log_means(points, min_step_n);
    crate::stats::rms(&d.iter().map(|(r, e)| e - r).collect::<Vec<_>>())
}

/// Keep the holds both replays settled (the same log, settled from the
/// same time), in order; returns a line for each left out. A fault latched
/// in one replay and not the other (the slack check reads cable 1's
/// tension through the stiffnesses the calibration changed) ends that
/// replay's holds early.
fn keep_common_holds(
    before: &mut Vec<Point>,
    after: &mut Vec<Point>,
    labels: &[&str],
) -> Vec<String> {
    let same = |a: &Point, b: &Point| a.log == b.log && a.t_s.0 == b.t_s.0;
    let mut left_out = Vec::new();
    for (one, other, replay) in [
        (&*before, &*after, "the calibrated configuration"),
        (&*after, &*before, "the configuration given"),
    ] {
        for p in one.iter().filter(|p| !other.iter().any(|o| same(p, o))) {
            left_out.push(format!(
                "`{}`, the hold settled from {:.2} s: not settled in the replay with {replay} \
                 (a fault latched before it), so not compared",
                labels.get(p.log).copied().unwrap_or("?"),
                p.t_s.0
            ));
        }
    }
    let (b0, a0) = (before.clone(), after.clone());
    before.retain(|b| a0.iter().any(|a| same(a, b)));
    after.retain(|a| b0.iter().any(|b| same(a, b)));
    left_out
}

/// The scale fitted on the settled holds' points: `s`, its `%sigma`, the
/// tolerance it gives, and the logs that entered; an error when the holds
/// cannot pin it down better than `prior` (the configuration's tolerance).
fn fit_scale(
    fitted: &[Point],
    opts: &WeightsOptions,
    prior: f64,
    logs_given: usize,
) -> Result<ScaleFit> {
    let (pairs, logs_fitted) = about_log_means(fitted, opts.min_step_n);
    let dof = pairs.len() as i64 - logs_fitted as i64 - 1;
    let Some(s) = slope(&pairs).filter(|_| logs_fitted > 0) else {
        bail!(
            "no log changes its reference force by {} N or more between settled holds \
             ({} holds of at least {} s, {} s after the reference settled, in {} logs): \
             record each weight on and off the tip in one log (with `FILE@T0=F0,...` the \
             reference is unknown before the first step: start at the log's first time, e.g. \
             `0=0`)",
            opts.min_step_n,
            fitted.len(),
            opts.min_settled_s,
            opts.settle_s,
            logs_given
        );
    };
    if dof < 2 {
        bail!(
            "{} settled holds in {} logs leave {} degrees of freedom for the scale's \
             uncertainty, at least 2 needed: record more holds (several weights, both \
             directions)",
            pairs.len(),
            logs_fitted,
            dof.max(0)
        );
    }
    let sxx: f64 = pairs.iter().map(|(r, _)| r * r).sum();
    let sse: f64 = pairs.iter().map(|(r, e)| (e - s * r).powi(2)).sum();
    let std = (sse / dof as f64 / sxx).sqrt();
    let pct = 100.0 * std / s.abs();
    // The loads one way and the other: a machine's scale does not depend on
    // the direction, so their disagreement bounds what the scatter misses.
    let spread = direction_spread(fitted, opts.min_step_n);
    let half_width = student_t_975(dof as usize) * std;
    let tolerance = half_width.max(spread) / s + opts.reference_tolerance;
    if !(s > 0.0 && tolerance < prior) {
        bail!(
            "the weights do not pin the force scale down better than the configuration: the \
             stretch estimate changes by {s:.3} N per newton of reference (%sigma {pct:.1}, {} \
             holds in {} logs), a tolerance of {tolerance:.3} against the configuration's \
             {prior:.3}: heavier weights or more holds; the configuration is not written",
            pairs.len(),
            logs_fitted
        );
    }
    Ok(ScaleFit {
        scale: s,
        pct_sigma: pct,
        tolerance,
        logs_fitted,
    })
}

/// What [`fit_scale`] found.
#[derive(Clone, Copy, Debug)]
struct ScaleFit {
    scale: f64,
    pct_sigma: f64,
    tolerance: f64,
    logs_fitted: usize,
}

/// How far the weights' scale `s` (relative tolerance `weights_tol`)
/// lies from the configuration's, 1 within `config_tol`, in units of the
/// 95 % half-width of their difference (both tolerances, 95 % half-widths
/// in units of the scale, in quadrature). Above 1, one of the two is off by
/// more than it claims: a weight's mass or lever arm mistyped, or an
/// identification biased beyond its tolerance.
pub fn scale_disagreement(s: f64, weights_tol: f64, config_tol: f64) -> f64 {
    let apart = (weights_tol * s).hypot(config_tol);
    if apart > 0.0 {
        (s - 1.0).abs() / apart
    } else {
        0.0
    }
}

/// Calibrate the stretch estimate's force scale on `fit` (label, log)
/// pairs with a reference force, check it on `validate`; returns the
/// result and `config` with it applied.
pub fn calibrate_weights(
    fit: &[(&str, &Log)],
    validate: &[(&str, &Log)],
    config: &Config,
    opts: &WeightsOptions,
) -> Result<(WeightsFit, Config)> {
    let mut fitted = Vec::new();
    for (i, (label, log)) in fit.iter().enumerate() {
        fitted.extend(holds(label, i, log, config, opts)?);
    }
    let ScaleFit {
        scale: s,
        pct_sigma: pct,
        tolerance,
        logs_fitted,
    } = fit_scale(
        &fitted,
        opts,
        f64::from(config.fusion.stiffness_tolerance),
        fit.len(),
    )?;
    let mut calibrated = *config;
    calibrated.machine.spring_n_m = (f64::from(config.machine.spring_n_m) / s) as f32;
    calibrated.stretch.cable1_n_m = (f64::from(config.stretch.cable1_n_m) / s) as f32;
    calibrated.stretch.cable2_n_m = (f64::from(config.stretch.cable2_n_m) / s) as f32;
    let disagreement =
        scale_disagreement(s, tolerance, f64::from(config.fusion.stiffness_tolerance));
    calibrated.fusion.stiffness_tolerance = (tolerance * disagreement.max(1.0)).min(1.0) as f32;
    if config.fusion.pin_identified {
        calibrated.fusion.pin_coulomb_nm = (f64::from(config.fusion.pin_coulomb_nm) / s) as f32;
    }
    calibrated
        .validate()
        .map_err(|e| anyhow::anyhow!("the calibrated configuration is invalid: {e}"))?;

    let mut holds_out = Vec::new();
    let mut unmatched = Vec::new();
    let mut errors = [(f64::NAN, f64::NAN); 2];
    for (set, runs) in [fit, validate].into_iter().enumerate() {
        // The fitted logs' holds with the configuration given are `fitted`.
        let replayed = set == 0;
        let mut before = if replayed {
            std::mem::take(&mut fitted)
        } else {
            Vec::new()
        };
        let mut after = Vec::new();
        for (i, (label, log)) in runs.iter().enumerate() {
            if !replayed {
                before.extend(holds(label, i, log, config, opts)?);
            }
            after.extend(holds(label, i, log, &calibrated, opts)?);
        }
        let labels: Vec<&str> = runs.iter().map(|(l, _)| *l).collect();
        unmatched.extend(keep_common_holds(&mut before, &mut after, &labels));
        for (b, a) in before.iter().zip(&after) {
            holds_out.push(WeightsHold {
                log: runs[b.log].0.to_owned(),
                fitted: set == 0,
                t_s: b.t_s,
                reference_n: b.reference_n,
                stretch_before_n: b.stretch_n,
                stretch_after_n: a.stretch_n,
                fused_before_n: b.fused_n,
                fused_after_n: a.fused_n,
            });
        }
        errors[set] = (
            change_error_n(&before, opts.min_step_n),
            change_error_n(&after, opts.min_step_n),
        );
    }
    Ok((
        WeightsFit {
            holds: holds_out,
            logs_fitted,
            scale: (s, pct),
            spring_n_m: (
                f64::from(config.machine.spring_n_m),
                f64::from(calibrated.machine.spring_n_m),
            ),
            stiffness_tolerance: (
                f64::from(config.fusion.stiffness_tolerance),
                f64::from(calibrated.fusion.stiffness_tolerance),
            ),
            disagreement,
            pin_coulomb_nm: config.fusion.pin_identified.then(|| {
                (
                    f64::from(config.fusion.pin_coulomb_nm),
                    f64::from(calibrated.fusion.pin_coulomb_nm),
                )
            }),
            unmatched,
            fit_error_n: errors[0],
            validation_error_n: errors[1],
        },
        calibrated,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A point of log `log` at reference `r` reading `e`.
    fn point(log: usize, r: f64, e: f64) -> Point {
        Point {
            log,
            t_s: (0.0, 1.0),
            reference_n: r,
            stretch_n: e,
            fused_n: e,
        }
    }

    #[test]
    fn the_scale_of_exact_holds_is_their_ratio_whatever_each_logs_zero() {
        // Each log reads 1.3 times the load about its own zero (0.2, -0.1, 0, 0.4 N).
        let zeros = [0.2, -0.1, 0.0, 0.4];
        let loads = [1.0, -1.0, 2.5, -2.5];
        let pts: Vec<Point> = (0..4)
            .flat_map(|l| {
                [
                    point(l, 0.0, zeros[l]),
                    point(l, loads[l], zeros[l] + 1.3 * loads[l]),
                ]
            })
            .collect();
        let f = fit_scale(&pts, &WeightsOptions::default(), 0.5, 4).unwrap();
        assert!((f.scale - 1.3).abs() < 1e-12, "{f:?}");
        assert!(f.pct_sigma < 1e-9, "{f:?}");
        // Exact data: only the reference's own tolerance is left.
        let tol = WeightsOptions::default().reference_tolerance;
        assert!((f.tolerance - tol).abs() < 1e-9, "{f:?}");
        assert_eq!(f.logs_fitted, 4);
    }

    #[test]
    fn loads_one_way_reading_another_scale_than_the_other_widen_the_tolerance() {
        // Positive loads read 1.2, negative 1.0: scatter and spread both.
        let pts: Vec<Point> = [(0, 1.0, 1.2), (1, 2.0, 1.2), (2, -1.0, 1.0), (3, -2.0, 1.0)]
            .into_iter()
            .flat_map(|(l, f, s)| [point(l, 0.0, 0.0), point(l, f, s * f)])
            .collect();
        let f = fit_scale(&pts, &WeightsOptions::default(), 1.0, 4).unwrap();
        assert!((f.scale - 1.1).abs() < 1e-12, "{f:?}");
        let spread = direction_spread(&pts, 0.1);
        assert!((spread - 0.2).abs() < 1e-12, "spread {spread}");
        assert!(f.tolerance >= 0.2 / 1.1, "{f:?}");
    }

    #[test]
    fn a_calibration_no_narrower_than_the_configurations_is_refused() {
        let pts: Vec<Point> = [(0, 1.0, 1.2), (1, 2.0, 1.2), (2, -1.0, 1.0), (3, -2.0, 1.0)]
            .into_iter()
            .flat_map(|(l, f, s)| [point(l, 0.0, 0.0), point(l, f, s * f)])
            .collect();
        let e = fit_scale(&pts, &WeightsOptions::default(), 0.05, 4).unwrap_err();
        assert!(e.to_string().contains("not written"), "{e}");
    }

    /// A weighing within what both tolerances allow of the configuration
    /// is below 1; one three half-widths off reads 3; exact agreement 0.
    #[test]
    fn the_scales_disagreement_is_their_difference_over_its_half_width() {
        let (t_w, t_c) = (0.03_f64, 0.04);
        assert_eq!(scale_disagreement(1.0, t_w, t_c), 0.0);
        let s = 1.0 + 3.0 * (t_w * t_w + t_c * t_c).sqrt();
        assert!((scale_disagreement(s, t_w / s, t_c) - 3.0).abs() < 1e-12);
        assert!(scale_disagreement(1.04, t_w, t_c) < 1.0);
        assert!(
            scale_disagreement(0.4, t_w, t_c) > 1.0,
            "weights typed at 2.5 times their mass"
        );
    }

    #[test]
    fn holds_without_a_change_of_load_or_too_few_are_refused_with_the_reason() {
        let flat: Vec<Point> = (0..3)
            .flat_map(|l| [point(l, 0.0, 0.1), point(l, 0.02, 0.1)])
            .collect();
        let e = fit_scale(&flat, &WeightsOptions::default(), 1.0, 3).unwrap_err();
        assert!(
            e.to_string().contains("no log changes its reference force"),
            "{e}"
        );
        let two: Vec<Point> = (0..2)
            .flat_map(|l| [point(l, 0.0, 0.0), point(l, 1.0, 1.1)])
            .collect();
        let e = fit_scale(&two, &WeightsOptions::default(), 1.0, 2).unwrap_err();
        assert!(e.to_string().contains("degrees of freedom"), "{e}");
    }

    #[test]
    fn reference_steps_fill_the_load_from_each_time_and_refuse_what_they_cannot_read() {
        assert_eq!(
            parse_reference_steps("0=0, 5.5=0.981,9=0").unwrap(),
            vec![(0.0, 0.0), (5.5, 0.981), (9.0, 0.0)]
        );
        for (bad, says) in [
            ("0=0,5", "is not TIME_S=FORCE_N"),
            ("0=0,x=1", "is not TIME_S=FORCE_N"),
            ("0=0,inf=1", "is not TIME_S=FORCE_N"),
            ("1=0,1=2", "repeat a time at `1=2`"),
            ("2=0,1=2", "go back in time at `1=2`"),
        ] {
            let e = parse_reference_steps(bad).unwrap_err().to_string();
            assert!(e.contains(says), "{bad}: {e}");
        }
        let mut log = Log::with_columns(&["t_s", "x1_m"]).unwrap();
        for k in 0..8 {
            log.push_row(&[f64::from(k), 0.0]).unwrap();
        }
        set_reference_steps(&mut log, &[(1.0, 0.0), (3.0, 2.0), (6.0, 0.0)], "w").unwrap();
        let f = log.col_opt("f_ext_n").unwrap();
        let want = [
            None,
            Some(0.0),
            Some(0.0),
            Some(2.0),
            Some(2.0),
            Some(2.0),
            Some(0.0),
            Some(0.0),
        ];
        assert_eq!(f, want);
        let e = set_reference_steps(&mut log, &[(0.0, 1.0)], "w")
            .unwrap_err()
            .to_string();
        assert!(e.contains("its own f_ext_n"), "{e}");
        // A step the log never reaches is a typo, not a hold.
        log.remove_col("f_ext_n");
        let e = set_reference_steps(&mut log, &[(0.0, 0.0), (70.0, 2.0)], "w")
            .unwrap_err()
            .to_string();
        assert!(e.contains("`70=2`") && e.contains("from 0 s to 7 s"), "{e}");
        assert!(!log.has("f_ext_n"), "nothing written on refusal");
    }

    #[test]
    fn students_t_quantile_falls_to_the_normal_one() {
        assert_eq!(student_t_975(1), 12.706);
        assert_eq!(student_t_975(3), 3.182);
        assert_eq!(student_t_975(30), 2.042);
        assert_eq!(student_t_975(200), 1.96);
        assert_eq!(student_t_975(0), 1.96);
    }

    /// A fault that ends one replay's holds early (here the calibrated
    /// one's, in the second log after its first hold) leaves those holds
    /// out of both sides and names them, instead of refusing the whole
    /// calibration; holds both replays settled stay paired in order.
    #[test]
    fn holds_only_one_replay_settled_are_left_out_and_named() {
        let at = |log, t0: f64, e| Point {
            t_s: (t0, t0 + 2.0),
            ..point(log, 1.0, e)
        };
        let mut before = vec![
            at(0, 1.0, 0.0),
            at(0, 5.5, 1.1),
            at(1, 1.0, 0.0),
            at(1, 5.5, 2.2),
        ];
        let mut after = vec![at(0, 1.0, 0.0), at(0, 5.5, 1.0), at(1, 1.0, 0.0)];
        let left_out = keep_common_holds(&mut before, &mut after, &["w100", "w250"]);
        assert_eq!(before.len(), 3);
        assert_eq!(after.len(), 3);
        for (b, a) in before.iter().zip(&after) {
            assert_eq!((b.log, b.t_s), (a.log, a.t_s));
        }
        assert_eq!(left_out.len(), 1, "{left_out:?}");
        assert!(
            left_out[0].contains("`w250`") && left_out[0].contains("5.50 s"),
            "{left_out:?}"
        );
        assert!(
            left_out[0].contains("the calibrated configuration"),
            "{left_out:?}"
        );
    }
}
