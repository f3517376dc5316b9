//! The fitting and validation rows of a problem, the least squares on them
//! and the diagnostics of a validation residual.

use std::ops::Range;

use anyhow::{bail, ensure, Result};
use cable_joint::lsq::{BatchLsq, Fit, LsqConfig};

use super::families::term_column;
use super::outcome::{Coef, Diagnostics, ModelFit};
use super::select::{Problem, RunData, SelectOptions, MAX_COLUMNS};
use crate::stats::rms;

/// Rows and columns of one data split, column-major.
#[derive(Default)]
pub(super) struct Split {
    pub(super) y: Vec<f64>,
    pub(super) fixed: Vec<f64>,
    pub(super) base: Vec<Vec<f64>>,
    pub(super) cand: Vec<Vec<f64>>,
    /// (run, first row in this split, row indices in the run)
    pub(super) runs: Vec<(usize, usize, Vec<usize>)>,
}

impl Split {
    pub(super) fn len(&self) -> usize {
        self.y.len()
    }
}

pub(super) fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Why row `k` of `run` cannot be used: the first column (target,
/// baseline regressor or term signal) that is not finite there.
fn why_unusable(problem: &Problem, run: &RunData, k: usize) -> String {
    let name = |names: &[String], i: usize| {
        names
            .get(i)
            .map_or_else(|| format!("#{i}"), |n| crate::log::quoted(n))
    };
    let bad = if !run.target.get(k).is_some_and(|v| v.is_finite()) {
        Some(crate::log::quoted(&problem.target))
    } else if let Some(i) = run.baseline.iter().position(|c| !c[k].is_finite()) {
        Some(name(&problem.baseline_names, i))
    } else {
        run.signals
            .iter()
            .position(|c| !c[k].is_finite())
            .map(|i| name(&problem.signal_names, i))
    };
    bad.map_or_else(String::new, |c| {
        format!(
            " (the first, line {}: {c} is not finite)",
            crate::log::line_of_row(run.log_row(k))
        )
    })
}

/// The log's own rows of `range` (a tick replay's filled ticks left out),
/// every `decimate`-th, that are finite in the target, fixed part, baseline
/// and every signal.
fn rows_of(run: &RunData, range: &Range<usize>, decimate: usize) -> Vec<usize> {
    let end = range.end.min(run.t_s.len());
    (range.start..end)
        .filter(|&k| run.measured(k))
        .step_by(decimate.max(1))
        .filter(|&k| {
            run.target[k].is_finite()
                && run.fixed[k].is_finite()
                && run.baseline.iter().all(|c| c[k].is_finite())
                && run.signals.iter().all(|s| s[k].is_finite())
        })
        .collect()
}

pub(super) fn check(problem: &Problem) -> Result<()> {
    ensure!(!problem.runs.is_empty(), "no run to fit");
    let nb = problem.baseline_names.len();
    let ns = problem.signal_names.len();
    for r in &problem.runs {
        let n = r.t_s.len();
        ensure!(
            r.target.len() == n && r.fixed.len() == n,
            "run {}: target/fixed length differs from time",
            r.name
        );
        ensure!(
            r.baseline.len() == nb && r.baseline.iter().all(|c| c.len() == n),
            "run {}: baseline columns do not match",
            r.name
        );
        ensure!(
            r.signals.len() == ns && r.signals.iter().all(|c| c.len() == n),
            "run {}: signal columns do not match",
            r.name
        );
    }
    for (k, t) in problem.candidates.iter().enumerate() {
        t.validate(k, ns)
            .map_err(|e| anyhow::anyhow!("candidate {k} ({t}): {e}"))?;
    }
    Ok(())
}

/// The fitting, validation and test rows of every run, each split with the
/// target, the baseline and every candidate's column.
pub(super) fn gather(problem: &Problem, decimate: usize) -> Result<(Split, Split, Split)> {
    let mut fit = Split::default();
    let mut val = Split::default();
    let mut test = Split::default();
    let nb = problem.baseline_names.len();
    let nc = problem.candidates.len();
    for s in [&mut fit, &mut val, &mut test] {
        s.base = vec![Vec::new(); nb];
        s.cand = vec![Vec::new(); nc];
    }
    for (ri, run) in problem.runs.iter().enumerate() {
        let fit_rows = rows_of(run, &run.fit_rows, decimate);
        let val_rows = rows_of(run, &run.val_rows, decimate);
        let test_rows = rows_of(run, &run.test_rows, decimate);
        if fit_rows.is_empty() && val_rows.is_empty() && test_rows.is_empty() {
            continue;
        }
        let cols: Vec<Vec<f64>> = problem
            .candidates
            .iter()
            .map(|t| {
                term_column(
                    t,
                    &run.signals,
                    &run.t_s,
                    problem.term_dt_s,
                    problem.prefilter,
                )
            })
            .collect();
        for (s, rows) in [
            (&mut fit, fit_rows),
            (&mut val, val_rows),
            (&mut test, test_rows),
        ] {
            if rows.is_empty() {
                continue;
            }
            let first = s.len();
            for &k in &rows {
                s.y.push(run.target[k] - run.fixed[k]);
                s.fixed.push(run.fixed[k]);
                for (d, c) in s.base.iter_mut().zip(&run.baseline) {
                    d.push(c[k]);
                }
                for (d, c) in s.cand.iter_mut().zip(&cols) {
                    d.push(c[k]);
                }
            }
            s.runs.push((ri, first, rows));
        }
    }
    ensure!(
        fit.len() > nb + 1,
        "too few fitting rows ({}) for {nb} baseline parameters",
        fit.len()
    );
    if val.y.is_empty() {
        let runs: Vec<String> = problem
            .runs
            .iter()
            .filter(|r| !r.val_rows.is_empty())
            .map(|r| {
                let first = r.val_rows.clone().find(|&k| r.measured(k));
                format!(
                    "{}: lines {}..{} ({} rows), none usable{}",
                    r.name,
                    crate::log::line_of_row(r.log_row(r.val_rows.start)),
                    crate::log::line_of_row(r.log_row(r.val_rows.end.saturating_sub(1))),
                    r.val_rows.clone().filter(|&k| r.measured(k)).count(),
                    why_unusable(problem, r, first.unwrap_or(r.val_rows.start))
                )
            })
            .collect();
        bail!(
            "no validation rows: {}",
            if runs.is_empty() {
                "no log has a validation part (--validate gives none, or --holdout 0 or \
                 --settle longer than the logs leaves none)"
                    .to_owned()
            } else {
                format!(
                    "{} (a column not measured, or every row after a fault the replay latched)",
                    runs.join("; ")
                )
            }
        );
    }
    Ok((fit, val, test))
}

/// Least squares of `y` on the columns `idx_base` (baseline) and `idx_cand`
/// (candidates) of a split. Returns the fit (None when there is no column).
fn lsq(
    s: &Split,
    idx_cand: &[usize],
) -> Result<Option<Fit<MAX_COLUMNS>>, cable_joint::lsq::LsqError> {
    let nb = s.base.len();
    let p = nb + idx_cand.len();
    if p == 0 {
        return Ok(None);
    }
    let mut ls = BatchLsq::<MAX_COLUMNS>::new(p, LsqConfig::default())?;
    let mut row = [0.0f64; MAX_COLUMNS];
    for k in 0..s.len() {
        for (j, c) in s.base.iter().enumerate() {
            row[j] = c[k];
        }
        for (j, &c) in idx_cand.iter().enumerate() {
            row[nb + j] = s.cand[c][k];
        }
        ls.push(&row[..p], s.y[k])?;
    }
    ls.solve().map(Some)
}

/// Residual `y - fit` on a split (without the fixed part, which `y` excludes).
pub(super) fn residual(s: &Split, idx_cand: &[usize], params: &[f64]) -> Vec<f64> {
    let nb = s.base.len();
    (0..s.len())
        .map(|k| {
            let mut p = 0.0;
            for (j, c) in s.base.iter().enumerate() {
                p += params[j] * c[k];
            }
            for (j, &c) in idx_cand.iter().enumerate() {
                p += params[nb + j] * s.cand[c][k];
            }
            s.y[k] - p
        })
        .collect()
}

pub(super) fn model_fit(
    fit: &Split,
    val: &Split,
    idx: &[usize],
    names: &[String],
) -> Result<(ModelFit, Vec<f64>), cable_joint::lsq::LsqError> {
    let sol = lsq(fit, idx)?;
    let (params, coefs, condition) = match &sol {
        Some(f) => {
            let p = f.n_params;
            let params: Vec<f64> = f.params.iter().take(p).copied().collect();
            let coefs = (0..p)
                .map(|k| Coef {
                    name: names[k].clone(),
                    value: f.params[k],
                    std_dev: f.std_dev[k],
                    pct_sigma: f.pct_sigma(k),
                })
                .collect();
            (params, coefs, f.condition)
        }
        None => (Vec::new(), Vec::new(), 1.0),
    };
    let mf = ModelFit {
        coefs,
        train_rmse: rms(&residual(fit, idx, &params)),
        val_rmse: rms(&residual(val, idx, &params)),
        condition,
    };
    Ok((mf, params))
}

pub(super) fn corr(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len()) as f64;
    if n < 2.0 {
        return 0.0;
    }
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        let (dx, dy) = (x - ma, y - mb);
        sab += dx * dy;
        saa += dx * dx;
        sbb += dy * dy;
    }
    if saa <= 0.0 || sbb <= 0.0 {
        0.0
    } else {
        sab / (saa * sbb).sqrt()
    }
}

/// Diagnostics of a validation residual `e` (rows of `val`).
pub(super) fn diagnostics(
    problem: &Problem,
    val: &Split,
    e: &[f64],
    labels: &[String],
    usable: &[bool],
    opts: &SelectOptions,
) -> Diagnostics {
    let n = e.len().max(1) as f64;
    let mean = e.iter().sum::<f64>() / n;
    let var: f64 = e.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>();
    // Lags in rows of the split: every run contiguous, `decimate` of the
    // log's rows apart.
    let dt = problem
        .runs
        .first()
        .and_then(RunData::row_period_s)
        .unwrap_or(1.0)
        * opts.decimate.max(1) as f64;
    let acf = |lag: usize| -> f64 {
        let mut s = 0.0;
        for (_, first, rows) in &val.runs {
            let seg = &e[*first..*first + rows.len()];
            for k in lag..seg.len() {
                s += (seg[k] - mean) * (seg[k - lag] - mean);
            }
        }
        if var > 0.0 {
            s / var
        } else {
            0.0
        }
    };
    let mut autocorr = Vec::new();
    for lag_s in [dt, 0.01, 0.1, 1.0] {
        let lag = (lag_s / dt).round().max(1.0) as usize;
        if autocorr
            .last()
            .is_some_and(|(l, _): &(f64, f64)| (*l - lag as f64 * dt).abs() < 1e-12)
        {
            continue;
        }
        let longest = val.runs.iter().map(|r| r.2.len()).max().unwrap_or(0);
        if lag < longest {
            autocorr.push((lag as f64 * dt, acf(lag)));
        }
    }
    // Correlation time: first lag (on a doubling grid) below 1/e.
    let mut corr_time_s = None;
    let longest = val.runs.iter().map(|r| r.2.len()).max().unwrap_or(0);
    let mut lag = 1usize;
    while lag < longest / 2 {
        if acf(lag) < (-1.0f64).exp() {
            corr_time_s = Some(lag as f64 * dt);
            break;
        }
        lag = (lag * 2).max(lag + 1);
    }
    let mut cc: Vec<(String, f64)> = val
        .cand
        .iter()
        .enumerate()
        .filter(|(k, _)| usable[*k])
        .map(|(k, c)| (labels[k].clone(), corr(e, c)))
        .filter(|(_, r)| r.is_finite())
        .collect();
    cc.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
    cc.truncate(opts.top);
    Diagnostics {
        rmse: rms(e),
        mean,
        max_abs: e.iter().fold(0.0, |m, x| m.max(x.abs())),
        autocorr,
        corr_time_s,
        top_correlations: cc,
    }
}
