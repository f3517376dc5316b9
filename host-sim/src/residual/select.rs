//! Forward selection of effect terms by error reduction ratio (OLS-ERR),
//! stopped by the error on validation data.
//!
//! The model is `y = fixed + B b + sum_k c_k w_k`: `fixed` a prediction taken
//! as given (e.g. the DOB's force estimate), `B` the baseline regressors
//! (e.g. the seed's Eq. 26 columns and a constant), `w_k` the selected effect
//! columns. Each step:
//!
//! 1. every candidate column is orthogonalised (on the fitting rows) against
//!    the columns already in the model; a candidate with less than
//!    [`COLLINEAR_REL`] of its norm left is a combination of them and is
//!    skipped;
//! 2. its error reduction ratio is the share of the current residual's energy
//!    that its orthogonal part explains, `<w_perp, r>^2 / (|w_perp|^2 |r|^2)`;
//! 3. the candidate with the largest ratio is added and the whole model refitted
//!    by [`BatchLsq`] (parameters, standard deviations, condition number);
//! 4. the refitted model is judged on the validation rows: it is kept only if
//!    it cuts the validation RMSE by at least `min_gain` (relative). Otherwise
//!    it is set aside and the next-ranked candidate is tried; after `patience`
//!    candidates in a row are set aside, or `max_terms` terms are in, the
//!    selection stops. Training error never decides.

use std::ops::Range;

use anyhow::{bail, ensure, Result};
use cable_joint::effects::{EffectKind, Term, TermState};
use cable_joint::filter::LowPass1;
use cable_joint::lsq::{BatchLsq, Fit, LsqConfig};

use crate::derive::low_pass_column;

/// Largest number of regressors (baseline plus effects) in one fit.
pub const MAX_COLUMNS: usize = 32;

/// A candidate whose orthogonalised norm falls below this fraction of its
/// own norm is treated as collinear with the model and skipped.
pub const COLLINEAR_REL: f64 = 1e-4;

/// One run (log) of a problem: the target, the baseline regressors and the
/// signals the effect terms read, sample by sample.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RunData {
    /// Name for reports (the file name).
    pub name: String,
    /// Time since the start of the run, s.
    pub t_s: Vec<f64>,
    /// What the model must reproduce.
    pub target: Vec<f64>,
    /// Part of the prediction that is not fitted (zeros when none).
    pub fixed: Vec<f64>,
    /// Baseline regressor columns, in [`Problem::baseline_names`] order.
    pub baseline: Vec<Vec<f64>>,
    /// Signals read by the terms, in [`Problem::signal_names`] order.
    pub signals: Vec<Vec<f32>>,
    /// Rows used for fitting.
    pub fit_rows: Range<usize>,
    /// Rows used for validation.
    pub val_rows: Range<usize>,
}

/// What to fit and which effects to try.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Problem {
    /// Model name (`jae`, `tension`, `force`, `generic`).
    pub model: String,
    /// Target column name (its unit suffix sets the display unit).
    pub target: String,
    /// Names of the baseline regressors.
    pub baseline_names: Vec<String>,
    /// Names of the signals the terms read (index = term input).
    pub signal_names: Vec<String>,
    /// Candidate effect terms.
    pub candidates: Vec<Term>,
    /// Signals from sensors the model itself does not read (for the JAE:
    /// the motor encoder and grating 1). A term that reads one explains the
    /// residual by sensor fusion, not by a physical effect; such terms are
    /// candidates only when the user asks for them (and are labelled so).
    pub other_sensors: Vec<u8>,
    /// Terms of the configuration kept in the baseline (its last columns).
    pub kept: Vec<Term>,
    /// Step given to the terms, s; `None`: the log's own time steps.
    pub term_dt_s: Option<f32>,
    /// Low-pass applied to every candidate column before fitting (the DOB's
    /// `Q` for tension and force models); the baseline columns come filtered.
    pub prefilter: Option<LowPass1>,
    /// The runs.
    pub runs: Vec<RunData>,
}

/// Settings of the selection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SelectOptions {
    /// Most effect terms added.
    pub max_terms: usize,
    /// Smallest relative cut of the validation RMSE that keeps a term.
    pub min_gain: f64,
    /// Candidates set aside in a row before the selection stops.
    pub patience: usize,
    /// Use every `decimate`-th row (terms are still computed on every row).
    pub decimate: usize,
    /// Candidates listed in the correlation diagnostics.
    pub top: usize,
}

impl Default for SelectOptions {
    fn default() -> Self {
        Self {
            max_terms: cable_joint::model::MAX_TERMS,
            min_gain: 0.01,
            patience: 20,
            decimate: 1,
            top: 5,
        }
    }
}

/// One fitted coefficient.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Coef {
    /// Regressor name.
    pub name: String,
    /// Value, target unit per regressor unit.
    pub value: f64,
    /// Standard deviation.
    pub std_dev: f64,
    /// `100 std / |value|`.
    pub pct_sigma: f64,
}

/// A fitted model: coefficients and errors.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ModelFit {
    /// Baseline coefficients then effect coefficients.
    pub coefs: Vec<Coef>,
    /// RMSE on the fitting rows.
    pub train_rmse: f64,
    /// RMSE on the validation rows.
    pub val_rmse: f64,
    /// Condition number of the equilibrated regressor matrix (1 when empty).
    pub condition: f64,
}

/// One tried effect.
#[derive(Clone, Debug, PartialEq)]
pub struct Step {
    /// The term.
    pub term: Term,
    /// Index in [`Problem::candidates`].
    pub candidate: usize,
    /// Name with signal names, e.g. `stop[x2_m](w=4e-5)`.
    pub label: String,
    /// Physical meaning.
    pub meaning: &'static str,
    /// Share of the current training residual's energy it explains.
    pub err: f64,
    /// The model with it.
    pub fit: ModelFit,
    /// Relative cut of the validation RMSE it brought.
    pub gain: f64,
    /// The physical family it belongs to ([`effect_class`]).
    pub class: String,
    /// The best candidate of another family at the step it was taken, when
    /// that one explains at least [`RIVAL_SHARE`] of what this one does: the
    /// data do not tell the two families apart.
    pub rival: Option<Rival>,
    /// A validation run whose error it would have raised by more than the
    /// smallest gain (do no harm), with that rise (relative); only for
    /// set-aside terms.
    pub harm: Option<(String, f64)>,
    /// Correlation of the validation residual with the term's column,
    /// before (baseline) and after (final model); only for kept terms.
    pub evidence: Option<(f64, f64)>,
}

/// A candidate of another effect family that explains the residual nearly
/// as well as the one taken.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Rival {
    /// Its label.
    pub label: String,
    /// Its family.
    pub class: String,
    /// Its error reduction ratio at that step.
    pub err: f64,
}

/// A rival family is named when its best candidate's ERR reaches this share
/// of the taken term's ERR.
pub const RIVAL_SHARE: f64 = 0.8;

/// Signal kinds, from the unit suffix of the signal's name.
fn is_velocity(name: &str) -> bool {
    name.contains("_vel") || name.ends_with("_m_s") || name.ends_with("_rad_s")
}

fn is_load(name: &str) -> bool {
    name.ends_with("_a") || name.ends_with("_n") || name.ends_with("_nm")
}

/// Does `t` read a signal of `other` (as its input or its second signal)?
pub fn reads_other_sensor(t: &Term, other: &[u8]) -> bool {
    (t.kind.uses_input() && other.contains(&t.input))
        || (t.kind.uses_aux() && other.contains(&t.aux))
}

/// The physical family of a term: `drift`, `stiffness` (a static function
/// of a position), `friction` (of a velocity), `hysteresis`, `creep /
/// relaxation`, `thermal`, `load` (a function of a current or force), or
/// `fusion: <signal>` when it reads a sensor the model does not (see
/// [`Problem::other_sensors`]).
pub fn effect_class(t: &Term, names: &[String], other: &[u8]) -> String {
    if reads_other_sensor(t, other) {
        let i = if t.kind.uses_input() && other.contains(&t.input) {
            t.input
        } else {
            t.aux
        };
        let name = names.get(i as usize).map_or("?", String::as_str);
        return format!("fusion: {name}");
    }
    let input = names.get(t.input as usize).map_or("", String::as_str);
    let static_of_input = if is_velocity(input) {
        "friction"
    } else if is_load(input) {
        "load"
    } else {
        "stiffness"
    };
    match t.kind {
        EffectKind::Constant | EffectKind::Time { .. } | EffectKind::Warmup { .. } => "drift",
        EffectKind::Linear
        | EffectKind::SignedSquare
        | EffectKind::Cube
        | EffectKind::DeadZone { .. } => static_of_input,
        EffectKind::SmoothSign { .. }
        | EffectKind::Stribeck { .. }
        | EffectKind::LoadCoulomb { .. } => "friction",
        EffectKind::Play { .. }
        | EffectKind::Stop { .. }
        | EffectKind::Dahl { .. }
        | EffectKind::LoadDahl { .. }
        | EffectKind::LoadMemory { .. } => "hysteresis",
        EffectKind::Relaxation { .. } | EffectKind::Creep { .. } => "creep / relaxation",
        EffectKind::Thermal { .. } => "thermal",
        EffectKind::Product => "load",
    }
    .to_string()
}

/// Residual diagnostics on the validation rows.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Diagnostics {
    /// RMSE.
    pub rmse: f64,
    /// Mean.
    pub mean: f64,
    /// Largest absolute value.
    pub max_abs: f64,
    /// Autocorrelation at lags (s) after removing the mean: `(lag_s, r)`.
    pub autocorr: Vec<(f64, f64)>,
    /// Shortest lag at which the autocorrelation falls below `1/e`, s.
    pub corr_time_s: Option<f64>,
    /// Candidates most correlated with the residual: `(label, r)`.
    pub top_correlations: Vec<(String, f64)>,
}

/// Validation-run traces for plots.
#[derive(Clone, Debug, PartialEq)]
pub struct RunTrace {
    /// Run name.
    pub name: String,
    /// Time, s.
    pub t_s: Vec<f64>,
    /// Target.
    pub target: Vec<f64>,
    /// Baseline prediction.
    pub before: Vec<f64>,
    /// Final prediction.
    pub after: Vec<f64>,
    /// Per accepted term: its input signal and its fitted contribution.
    pub terms: Vec<(Vec<f64>, Vec<f64>)>,
}

/// Validation RMSE of one run before and after.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RunError {
    /// Run name.
    pub name: String,
    /// Validation rows used.
    pub rows: usize,
    /// Baseline RMSE.
    pub before_rmse: f64,
    /// Final RMSE.
    pub after_rmse: f64,
    /// Mean of the final residual (an offset of this run's zero).
    pub after_mean: f64,
}

/// Everything the selection found.
#[derive(Clone, Debug, PartialEq)]
pub struct Outcome {
    /// Fitting rows used.
    pub n_fit: usize,
    /// Validation rows used.
    pub n_val: usize,
    /// Candidates offered.
    pub n_candidates: usize,
    /// The baseline model.
    pub baseline: ModelFit,
    /// Effects kept, in order.
    pub accepted: Vec<Step>,
    /// Effects tried and set aside (did not cut the validation error).
    pub rejected: Vec<Step>,
    /// The final model (= the baseline when nothing was kept).
    pub final_fit: ModelFit,
    /// Residual diagnostics of the baseline.
    pub before: Diagnostics,
    /// Residual diagnostics of the final model.
    pub after: Diagnostics,
    /// Per validation run.
    pub runs: Vec<RunError>,
    /// Traces of the validation runs.
    pub traces: Vec<RunTrace>,
}

impl Outcome {
    /// The terms kept, with their coefficients (after the baseline ones).
    pub fn effect_coefs(&self) -> Vec<(Term, f64)> {
        let nb = self.baseline.coefs.len();
        self.accepted
            .iter()
            .zip(self.final_fit.coefs.iter().skip(nb))
            .map(|(s, c)| (s.term, c.value))
            .collect()
    }

    /// The final baseline coefficients.
    pub fn baseline_coefs(&self) -> Vec<f64> {
        let nb = self.baseline.coefs.len();
        self.final_fit.coefs[..nb].iter().map(|c| c.value).collect()
    }
}

/// A term's name with signal names in place of indices.
pub fn term_label(t: &Term, names: &[String]) -> String {
    let sig = |i: u8| {
        names
            .get(i as usize)
            .cloned()
            .unwrap_or_else(|| format!("#{i}"))
    };
    let n = t.name();
    match t.kind {
        EffectKind::Constant => n.to_owned(),
        EffectKind::Time { scale_s } => format!("{n}(per {scale_s}s)"),
        EffectKind::Warmup { tau_s } => format!("{n}(tau={tau_s:.4}s)"),
        EffectKind::Linear | EffectKind::SignedSquare | EffectKind::Cube => {
            format!("{n}[{}]", sig(t.input))
        }
        EffectKind::Product => format!("{n}[{}*{}]", sig(t.input), sig(t.aux)),
        EffectKind::SmoothSign { v_eps } => format!("{n}[{}](eps={v_eps:.3e})", sig(t.input)),
        EffectKind::Stribeck { v_s, v_eps } => {
            format!("{n}[{}](vs={v_s:.3e},eps={v_eps:.3e})", sig(t.input))
        }
        EffectKind::Play { half_width } | EffectKind::Stop { half_width } => {
            format!("{n}[{}](w={half_width:.3e})", sig(t.input))
        }
        EffectKind::Dahl { length } => format!("{n}[{}](L={length:.3e})", sig(t.input)),
        EffectKind::LoadCoulomb { v_eps } => {
            format!("{n}[{}*|{}|](eps={v_eps:.3e})", sig(t.input), sig(t.aux))
        }
        EffectKind::LoadDahl { length } => {
            format!("{n}[{}*|{}|](L={length:.3e})", sig(t.input), sig(t.aux))
        }
        EffectKind::DeadZone { center, half_width } => {
            format!("{n}[{}](c={center:.3e},w={half_width:.3e})", sig(t.input))
        }
        EffectKind::Relaxation { tau_s }
        | EffectKind::Creep { tau_s }
        | EffectKind::Thermal { tau_s }
        | EffectKind::LoadMemory { tau_s } => format!("{n}[{}](tau={tau_s:.4}s)", sig(t.input)),
    }
}

/// Compute a term's column over a whole run (every sample, from its start),
/// then pass it through `prefilter` if given.
pub fn term_column(
    term: &Term,
    signals: &[Vec<f32>],
    t_s: &[f64],
    dt_s: Option<f32>,
    prefilter: Option<LowPass1>,
) -> Vec<f64> {
    let n = t_s.len();
    let mut st = TermState::default();
    let mut row = vec![0.0f32; signals.len()];
    let mut out = Vec::with_capacity(n);
    for k in 0..n {
        for (r, s) in row.iter_mut().zip(signals) {
            *r = s.get(k).copied().unwrap_or(f32::NAN);
        }
        let dt = match dt_s {
            Some(d) => d,
            None if k > 0 => (t_s[k] - t_s[k - 1]) as f32,
            None => 0.0,
        };
        out.push(term.update(&mut st, &row, dt));
    }
    match prefilter {
        Some(lp) => low_pass_column(lp, &out),
        None => out.into_iter().map(f64::from).collect(),
    }
}

/// Rows and columns of one data split, column-major.
#[derive(Default)]
struct Split {
    y: Vec<f64>,
    fixed: Vec<f64>,
    base: Vec<Vec<f64>>,
    cand: Vec<Vec<f64>>,
    /// (run, first row in this split, row indices in the run)
    runs: Vec<(usize, usize, Vec<usize>)>,
}

impl Split {
    fn len(&self) -> usize {
        self.y.len()
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn rms(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    (dot(v, v) / v.len() as f64).sqrt()
}

/// Rows of `range` that are finite in the target, fixed part, baseline and
/// every signal, every `decimate`-th.
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
            crate::log::line_of_row(k)
        )
    })
}

/// RMSE of `e` (over the validation rows) on each validation run.
fn run_rmses(val: &Split, e: &[f64]) -> Vec<f64> {
    val.runs
        .iter()
        .map(|(_, first, rows)| rms(&e[*first..*first + rows.len()]))
        .collect()
}

fn rows_of(run: &RunData, range: &Range<usize>, decimate: usize) -> Vec<usize> {
    let end = range.end.min(run.t_s.len());
    (range.start..end)
        .step_by(decimate.max(1))
        .filter(|&k| {
            run.target[k].is_finite()
                && run.fixed[k].is_finite()
                && run.baseline.iter().all(|c| c[k].is_finite())
                && run.signals.iter().all(|s| s[k].is_finite())
        })
        .collect()
}

fn check(problem: &Problem) -> Result<()> {
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

fn gather(problem: &Problem, decimate: usize) -> Result<(Split, Split)> {
    let mut fit = Split::default();
    let mut val = Split::default();
    let nb = problem.baseline_names.len();
    let nc = problem.candidates.len();
    for s in [&mut fit, &mut val] {
        s.base = vec![Vec::new(); nb];
        s.cand = vec![Vec::new(); nc];
    }
    for (ri, run) in problem.runs.iter().enumerate() {
        let fit_rows = rows_of(run, &run.fit_rows, decimate);
        let val_rows = rows_of(run, &run.val_rows, decimate);
        if fit_rows.is_empty() && val_rows.is_empty() {
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
        for (s, rows) in [(&mut fit, fit_rows), (&mut val, val_rows)] {
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
                format!(
                    "{}: lines {}..{} ({} rows), none usable{}",
                    r.name,
                    r.val_rows.start + 2,
                    r.val_rows.end + 1,
                    r.val_rows.len(),
                    why_unusable(problem, r, r.val_rows.start)
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
    Ok((fit, val))
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
fn residual(s: &Split, idx_cand: &[usize], params: &[f64]) -> Vec<f64> {
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

fn model_fit(
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

fn corr(a: &[f64], b: &[f64]) -> f64 {
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
fn diagnostics(
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
    // Lags in rows of the split: every run contiguous, `decimate` samples apart.
    let dt = problem
        .runs
        .first()
        .and_then(|r| crate::derive::median_period_s(&r.t_s))
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

/// Run the selection.
pub fn select(problem: &Problem, opts: &SelectOptions) -> Result<Outcome> {
    check(problem)?;
    ensure!(opts.decimate >= 1, "decimate must be at least 1");
    let nb = problem.baseline_names.len();
    ensure!(
        nb + opts.max_terms <= MAX_COLUMNS,
        "{nb} baseline columns and {} terms exceed {MAX_COLUMNS} regressors",
        opts.max_terms
    );
    let (fit, val) = gather(problem, opts.decimate)?;
    let labels: Vec<String> = problem
        .candidates
        .iter()
        .map(|t| term_label(t, &problem.signal_names))
        .collect();
    let classes: Vec<String> = problem
        .candidates
        .iter()
        .map(|t| effect_class(t, &problem.signal_names, &problem.other_sensors))
        .collect();
    let mut names: Vec<String> = problem.baseline_names.clone();

    // Usable candidates: finite on every fitting and validation row, not flat.
    let usable: Vec<bool> = (0..problem.candidates.len())
        .map(|k| {
            fit.cand[k]
                .iter()
                .chain(&val.cand[k])
                .all(|v| v.is_finite())
                && dot(&fit.cand[k], &fit.cand[k]) > 0.0
        })
        .collect();

    let (baseline, base_params) = model_fit(&fit, &val, &[], &names)
        .map_err(|e| anyhow::anyhow!("fitting the baseline model [{}]: {e}", names.join(", ")))?;

    // Orthonormal basis of the model's columns on the fitting rows (modified
    // Gram-Schmidt, re-orthogonalised once).
    let mut basis: Vec<Vec<f64>> = Vec::new();
    let orth = |v: &mut Vec<f64>, basis: &[Vec<f64>]| {
        for _ in 0..2 {
            for q in basis {
                let a = dot(v, q);
                v.iter_mut().zip(q).for_each(|(x, qk)| *x -= a * qk);
            }
        }
    };
    for c in &fit.base {
        let mut v = c.clone();
        let n0 = dot(&v, &v).sqrt();
        orth(&mut v, &basis);
        let n = dot(&v, &v).sqrt();
        if n > COLLINEAR_REL * n0 && n > 0.0 {
            v.iter_mut().for_each(|x| *x /= n);
            basis.push(v);
        }
    }
    let mut r = fit.y.clone();
    orth(&mut r, &basis);
    let mut perp: Vec<Vec<f64>> = fit.cand.clone();
    let norms0: Vec<f64> = fit.cand.iter().map(|c| dot(c, c).sqrt()).collect();
    for (k, w) in perp.iter_mut().enumerate() {
        if usable[k] {
            orth(w, &basis);
        }
    }

    let mut chosen: Vec<usize> = Vec::new();
    let mut set_aside = vec![false; problem.candidates.len()];
    let mut accepted: Vec<Step> = Vec::new();
    let mut rejected: Vec<Step> = Vec::new();
    let mut current = baseline.clone();
    let mut params = base_params.clone();
    let mut misses = 0usize;
    let mut current_runs = run_rmses(&val, &residual(&val, &[], &base_params));
    while chosen.len() < opts.max_terms && misses < opts.patience {
        let rr = dot(&r, &r);
        if rr <= 0.0 {
            break;
        }
        let mut errs: Vec<Option<f64>> = vec![None; perp.len()];
        for k in 0..perp.len() {
            if !usable[k] || set_aside[k] || chosen.contains(&k) {
                continue;
            }
            let nn = dot(&perp[k], &perp[k]);
            if nn.is_nan() || nn.sqrt() <= COLLINEAR_REL * norms0[k] {
                continue;
            }
            let err = dot(&perp[k], &r).powi(2) / (nn * rr);
            if err.is_finite() {
                errs[k] = Some(err);
            }
        }
        let best = |skip_class: Option<&str>| -> Option<(usize, f64)> {
            errs.iter()
                .enumerate()
                .filter(|(k, _)| skip_class.is_none_or(|c| classes[*k] != c))
                .filter_map(|(k, e)| e.map(|e| (k, e)))
                .fold(None, |b: Option<(usize, f64)>, (k, e)| {
                    if b.is_none_or(|(_, be)| e > be) {
                        Some((k, e))
                    } else {
                        b
                    }
                })
        };
        let Some((k, err)) = best(None) else { break };
        let rival = best(Some(&classes[k]))
            .filter(|&(_, e)| e >= RIVAL_SHARE * err)
            .map(|(j, e)| Rival {
                label: labels[j].clone(),
                class: classes[j].clone(),
                err: e,
            });
        let mut idx = chosen.clone();
        idx.push(k);
        let mut nm = names.clone();
        nm.push(labels[k].clone());
        let term = problem.candidates[k];
        let (mf, p) = match model_fit(&fit, &val, &idx, &nm) {
            Ok(x) => x,
            Err(_) => {
                // Numerically dependent on the model: never a candidate again.
                set_aside[k] = true;
                continue;
            }
        };
        let gain = (current.val_rmse - mf.val_rmse) / current.val_rmse;
        // Do no harm: no validation run (regime) may get worse by more than
        // the smallest gain that keeps a term.
        let cand_runs = run_rmses(&val, &residual(&val, &idx, &p));
        let harm = val
            .runs
            .iter()
            .zip(cand_runs.iter().zip(&current_runs))
            .map(|((ri, _, _), (&after, &before))| {
                (problem.runs[*ri].name.clone(), after / before - 1.0)
            })
            .filter(|(_, rise)| *rise > opts.min_gain)
            .fold(None, |w: Option<(String, f64)>, (n, rise)| {
                if w.as_ref().is_none_or(|(_, r)| rise > *r) {
                    Some((n, rise))
                } else {
                    w
                }
            });
        let mut step = Step {
            term,
            candidate: k,
            label: labels[k].clone(),
            meaning: term.meaning(),
            err,
            fit: mf.clone(),
            gain,
            class: classes[k].clone(),
            rival,
            harm: None,
            evidence: None,
        };
        if gain >= opts.min_gain && harm.is_none() {
            current_runs = cand_runs;
            chosen.push(k);
            names = nm;
            current = mf;
            params = p;
            misses = 0;
            accepted.push(step);
            let mut q = perp[k].clone();
            let n = dot(&q, &q).sqrt();
            q.iter_mut().for_each(|x| *x /= n);
            let a = dot(&r, &q);
            r.iter_mut().zip(&q).for_each(|(x, qk)| *x -= a * qk);
            basis.push(q);
            let last = basis.len() - 1;
            for (j, w) in perp.iter_mut().enumerate() {
                if usable[j] && !chosen.contains(&j) {
                    orth(w, &basis[last..]);
                }
            }
        } else {
            set_aside[k] = true;
            misses += 1;
            step.harm = harm.filter(|_| gain >= opts.min_gain);
            rejected.push(step);
        }
    }

    let e_before = residual(&val, &[], &base_params);
    let e_after = residual(&val, &chosen, &params);
    let before = diagnostics(problem, &val, &e_before, &labels, &usable, opts);
    let after = diagnostics(problem, &val, &e_after, &labels, &usable, opts);
    for step in &mut accepted {
        let c = &val.cand[step.candidate];
        step.evidence = Some((corr(&e_before, c), corr(&e_after, c)));
    }

    let mut runs = Vec::new();
    let mut traces = Vec::new();
    for (ri, first, rows) in &val.runs {
        let run = &problem.runs[*ri];
        let seg = *first..*first + rows.len();
        runs.push(RunError {
            name: run.name.clone(),
            rows: rows.len(),
            before_rmse: rms(&e_before[seg.clone()]),
            after_rmse: rms(&e_after[seg.clone()]),
            after_mean: e_after[seg.clone()].iter().sum::<f64>() / rows.len().max(1) as f64,
        });
        let target: Vec<f64> = rows.iter().map(|&k| run.target[k]).collect();
        let terms = chosen
            .iter()
            .enumerate()
            .map(|(j, &c)| {
                let t = problem.candidates[c];
                let input: Vec<f64> = if t.kind.uses_input() {
                    rows.iter()
                        .map(|&k| f64::from(run.signals[t.input as usize][k]))
                        .collect()
                } else {
                    rows.iter().map(|&k| run.t_s[k]).collect()
                };
                let contrib: Vec<f64> = seg
                    .clone()
                    .map(|i| params[nb + j] * val.cand[c][i])
                    .collect();
                (input, contrib)
            })
            .collect();
        traces.push(RunTrace {
            name: run.name.clone(),
            t_s: rows.iter().map(|&k| run.t_s[k]).collect(),
            before: target
                .iter()
                .zip(&e_before[seg.clone()])
                .map(|(y, e)| y - e)
                .collect(),
            after: target
                .iter()
                .zip(&e_after[seg.clone()])
                .map(|(y, e)| y - e)
                .collect(),
            target,
            terms,
        });
    }
    if !baseline.val_rmse.is_finite() {
        bail!("the baseline's validation error is not finite");
    }
    Ok(Outcome {
        n_fit: fit.len(),
        n_val: val.len(),
        n_candidates: usable.iter().filter(|u| **u).count(),
        baseline,
        accepted,
        rejected,
        final_fit: current,
        before,
        after,
        runs,
        traces,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A run where `y = 2 + 0.5 u + 0.3 stop(u)`: the stop term must be found
    /// and its coefficient recovered; nothing else must be added.
    #[test]
    fn finds_a_planted_term_and_stops() {
        let mk = |name: &str, phase: f64| {
            let n = 4000;
            let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
            let u: Vec<f32> = t
                .iter()
                .map(|t| {
                    ((2.0 * std::f64::consts::PI * 1.3 * t + phase).sin()
                        + 0.3 * (2.0 * std::f64::consts::PI * 3.1 * t).sin())
                        as f32
                })
                .collect();
            let stop = Term::new(EffectKind::Stop { half_width: 0.1 }, 0);
            let w = term_column(&stop, std::slice::from_ref(&u), &t, None, None);
            // deterministic small "noise"
            let y: Vec<f64> = (0..n)
                .map(|k| {
                    2.0 + 0.5 * u[k] as f64
                        + 0.3 * w[k]
                        + 1e-3 * ((k * 7919 % 1000) as f64 / 500.0 - 1.0)
                })
                .collect();
            RunData {
                name: name.into(),
                fixed: vec![0.0; n],
                baseline: vec![u.iter().map(|v| *v as f64).collect(), vec![1.0; n]],
                signals: vec![u],
                target: y,
                fit_rows: 0..n,
                val_rows: 0..0,
                t_s: t,
            }
        };
        let mut val = mk("val", 1.0);
        val.fit_rows = 0..0;
        val.val_rows = 0..val.t_s.len();
        let problem = Problem {
            model: "generic".into(),
            target: "y".into(),
            baseline_names: vec!["u".into(), "const".into()],
            signal_names: vec!["u".into()],
            candidates: vec![
                Term::new(EffectKind::Cube, 0),
                Term::new(EffectKind::Stop { half_width: 0.1 }, 0),
                Term::new(EffectKind::Stop { half_width: 0.4 }, 0),
                Term::new(EffectKind::Time { scale_s: 1.0 }, 0),
                Term::CONSTANT,
            ],
            runs: vec![mk("fit", 0.0), val],
            ..Default::default()
        };
        let out = select(&problem, &SelectOptions::default()).unwrap();
        assert_eq!(
            out.accepted.len(),
            1,
            "accepted {:?}",
            out.accepted.iter().map(|s| &s.label).collect::<Vec<_>>()
        );
        assert_eq!(out.accepted[0].candidate, 1);
        let c = &out.final_fit.coefs[2];
        assert!((c.value - 0.3).abs() < 0.01, "stop coefficient {}", c.value);
        assert!(
            out.after.rmse < 0.1 * out.before.rmse,
            "{} vs {}",
            out.after.rmse,
            out.before.rmse
        );
        assert!(
            out.after.rmse < 1e-3,
            "noise level left: {}",
            out.after.rmse
        );
        assert!(
            !out.rejected.is_empty(),
            "a second term was tried and set aside"
        );
    }

    /// A run of `y = 2 + 0.5 u + c stop(u)`; `c` is the effect's size in it.
    fn stop_run(name: &str, n: usize, phase: f64, c: f64) -> RunData {
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
        let u: Vec<f32> = t
            .iter()
            .map(|t| ((2.0 * std::f64::consts::PI * 1.3 * t + phase).sin()) as f32)
            .collect();
        let stop = Term::new(EffectKind::Stop { half_width: 0.1 }, 0);
        let w = term_column(&stop, std::slice::from_ref(&u), &t, None, None);
        let y: Vec<f64> = (0..n).map(|k| 2.0 + 0.5 * u[k] as f64 + c * w[k]).collect();
        RunData {
            name: name.into(),
            fixed: vec![0.0; n],
            baseline: vec![u.iter().map(|v| *v as f64).collect(), vec![1.0; n]],
            signals: vec![u],
            target: y,
            fit_rows: 0..0,
            val_rows: 0..n,
            t_s: t,
        }
    }

    fn stop_problem(runs: Vec<RunData>) -> Problem {
        Problem {
            model: "generic".into(),
            target: "y".into(),
            baseline_names: vec!["u".into(), "const".into()],
            signal_names: vec!["u".into()],
            candidates: vec![Term::new(EffectKind::Stop { half_width: 0.1 }, 0)],
            runs,
            ..Default::default()
        }
    }

    /// Do no harm: the effect is in the fitted regime and in validation run
    /// `a`, and reversed in the shorter run `b` (another regime). The term
    /// cuts the pooled validation error by about 40 % but multiplies `b`'s:
    /// it is set aside and `b` is named. Without `b` it is kept.
    #[test]
    fn a_term_that_helps_the_pool_but_raises_one_regime_is_set_aside() {
        let mut fit = stop_run("fit", 4000, 0.0, 0.3);
        (fit.fit_rows, fit.val_rows) = (0..4000, 0..0);
        let a = stop_run("a", 4000, 1.0, 0.3);
        let b = stop_run("b", 1000, 2.0, -0.05);
        let out = select(
            &stop_problem(vec![fit.clone(), a.clone(), b]),
            &SelectOptions::default(),
        )
        .unwrap();
        assert!(out.accepted.is_empty());
        let s = &out.rejected[0];
        assert!(s.gain > 0.3, "the pool improves: gain {}", s.gain);
        let (run, rise) = s.harm.clone().expect("the harm is named");
        assert_eq!(run, "b");
        assert!(rise > 1.0, "b's error rises by {rise}");
        let out = select(&stop_problem(vec![fit, a]), &SelectOptions::default()).unwrap();
        assert_eq!(out.accepted.len(), 1, "kept where it harms nothing");
        let (before, _) = out.accepted[0].evidence.expect("evidence");
        assert!(
            before.abs() > 0.9,
            "the residual followed the term: {before}"
        );
    }

    #[test]
    fn effect_families_follow_the_kind_and_the_signal_and_other_sensors_are_fusion() {
        let names: Vec<String> = ["x2_m", "x2_vel_m_s", "i_ref_a", "theta_motor_rad"]
            .map(String::from)
            .to_vec();
        let other = [3u8];
        let class = |t: Term| effect_class(&t, &names, &other);
        assert_eq!(class(Term::new(EffectKind::Linear, 0)), "stiffness");
        assert_eq!(class(Term::new(EffectKind::Cube, 0)), "stiffness");
        assert_eq!(class(Term::new(EffectKind::Linear, 1)), "friction");
        assert_eq!(class(Term::new(EffectKind::Linear, 2)), "load");
        assert_eq!(
            class(Term::new(EffectKind::Stop { half_width: 0.1 }, 0)),
            "hysteresis"
        );
        assert_eq!(
            class(Term::new(EffectKind::Creep { tau_s: 1.0 }, 0)),
            "creep / relaxation"
        );
        assert_eq!(
            class(Term::new(EffectKind::Thermal { tau_s: 1.0 }, 2)),
            "thermal"
        );
        assert_eq!(
            class(Term::new(EffectKind::Time { scale_s: 1.0 }, 0)),
            "drift"
        );
        assert_eq!(
            class(Term::new(EffectKind::Linear, 3)),
            "fusion: theta_motor_rad"
        );
    }

    /// A drift over time and a signal that happens to be a ramp explain the
    /// residual equally: the kept one names the other family as a rival.
    #[test]
    fn two_families_that_explain_the_residual_equally_are_named() {
        let n = 3000;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
        let u: Vec<f32> = t.iter().map(|t| (7.0 * t).sin() as f32).collect();
        let ramp: Vec<f32> = t.iter().map(|t| *t as f32).collect();
        let y: Vec<f64> = (0..n).map(|k| 1.0 + u[k] as f64 + 0.2 * t[k]).collect();
        let run = |fit: bool| RunData {
            name: "r".into(),
            fixed: vec![0.0; n],
            baseline: vec![u.iter().map(|v| *v as f64).collect(), vec![1.0; n]],
            signals: vec![u.clone(), ramp.clone()],
            target: y.clone(),
            fit_rows: if fit { 0..2000 } else { 0..0 },
            val_rows: if fit { 2000..n } else { 0..0 },
            t_s: t.clone(),
        };
        let problem = Problem {
            model: "generic".into(),
            target: "y".into(),
            baseline_names: vec!["u".into(), "const".into()],
            signal_names: vec!["u".into(), "ramp_m".into()],
            candidates: vec![
                Term::new(EffectKind::Time { scale_s: 1.0 }, 0),
                Term::new(EffectKind::Linear, 1),
            ],
            runs: vec![run(true)],
            ..Default::default()
        };
        let out = select(&problem, &SelectOptions::default()).unwrap();
        let kept = &out.accepted[0];
        let rival = kept.rival.as_ref().expect("the rival family is named");
        let mut families = [kept.class.as_str(), rival.class.as_str()];
        families.sort_unstable();
        assert_eq!(families, ["drift", "stiffness"]);
        assert!(rival.err >= RIVAL_SHARE * kept.err);
    }
}
