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
//!    by [`BatchLsq`](cable_joint::lsq::BatchLsq) (parameters, standard deviations, condition number);
//! 4. the refitted model is judged on the validation rows: it is kept only if
//!    it cuts the validation RMSE by at least `min_gain` (relative). Otherwise
//!    it is set aside and the next-ranked candidate is tried; after `patience`
//!    candidates in a row are set aside, or `max_terms` terms are in, the
//!    selection stops. Training error never decides.
//!
//! Some effects are several columns that mean nothing apart: the three
//! parts of a `stroke_load` (a load the current carries with a gain and an
//! offset of each stroke's own, [`effect_groups`]). Such a group competes
//! as one candidate, with the error reduction ratio of its parts' span, is
//! judged and kept or set aside as one step, and counts as many terms as it
//! has parts. On the MRDLab runs each part alone raised the validation
//! error and was set aside, while the three together are the load estimate
//! the jaw's angle and torque need.
//!
//! Here: the problem's data ([`Problem`], [`RunData`]), the options,
//! [`select`] with its do-no-harm check and its per-run results. Steps 1-2
//! (the orthogonal basis, the ratios, the best candidate) are in
//! `search.rs`.

use std::ops::Range;

use anyhow::{bail, ensure, Result};
use cable_joint::effects::Term;
use cable_joint::filter::LowPass1;

use super::families::{effect_class, group_label, term_label};
use super::library::effect_groups;
use super::outcome::{Outcome, Rival, RunError, RunTrace, Step};
use super::search::{best, first_max, Search};
use super::split::{check, corr, diagnostics, gather, model_fit, residual, Split};
use crate::stats::rms;

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
    /// The baseline with its differentiated inputs taken without the
    /// core's observer filtering (without phase,
    /// [`zero_phase_kinematics`](crate::derive::zero_phase_kinematics); see
    /// [`unfiltered_gains`] for the bandwidths), column for column with
    /// `baseline`: what [`unfiltered_gains`] refits on. Empty: the model
    /// differentiates nothing, no check.
    pub unfiltered_baseline: Vec<Vec<f64>>,
    /// Signals read by the terms, in [`Problem::signal_names`] order.
    pub signals: Vec<Vec<f32>>,
    /// Rows used for fitting.
    pub fit_rows: Range<usize>,
    /// Rows used for validation.
    pub val_rows: Range<usize>,
    /// Rows of a test log (`--test`): judged once, after the selection,
    /// by the model it chose; never fitted and never used to choose.
    pub test_rows: Range<usize>,
    /// A run replayed tick by tick ([`crate::derive::TickReplay`]): for
    /// each row, the log's row it is (`None` for a tick filled between a
    /// decimated or lossy log's rows, which is computed but neither fitted
    /// nor judged). Empty: every row is the log's own.
    pub source_row: Vec<Option<usize>>,
}

impl RunData {
    /// Whether row `k` is one of the log's own rows (not a filled tick).
    pub fn measured(&self, k: usize) -> bool {
        self.source_row.is_empty() || self.source_row.get(k).is_some_and(Option::is_some)
    }

    /// The log's row of row `k` (a filled tick: the row that ends its
    /// step), for messages that name a line.
    pub fn log_row(&self, k: usize) -> usize {
        if self.source_row.is_empty() {
            return k;
        }
        crate::derive::log_row_in(&self.source_row, k)
    }

    /// The median time between the log's own rows, s (`None` with fewer
    /// than two).
    pub fn row_period_s(&self) -> Option<f64> {
        if self.source_row.is_empty() {
            return crate::derive::median_period_s(&self.t_s);
        }
        let t: Vec<f64> = (0..self.t_s.len())
            .filter(|&k| self.measured(k))
            .map(|k| self.t_s[k])
            .collect();
        crate::derive::median_period_s(&t)
    }
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

/// A rival family is named when its best candidate's ERR reaches this share
/// of the taken term's ERR.
pub const RIVAL_SHARE: f64 = 0.8;

/// Of the steps `set_aside` since the last term kept (each with the ERR
/// it had on the same training residual), the best of each family other
/// than `class` whose ERR is above `err`, largest first.
fn passed_over(set_aside: &[Rival], class: &str, err: f64) -> Vec<Rival> {
    let mut out: Vec<Rival> = Vec::new();
    for r in set_aside.iter().filter(|r| r.class != class && r.err > err) {
        match out.iter_mut().find(|o| o.class == r.class) {
            Some(o) if o.err < r.err => *o = r.clone(),
            Some(_) => {}
            None => out.push(r.clone()),
        }
    }
    out.sort_by(|a, b| b.err.total_cmp(&a.err));
    out
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
    let (fit, val, test) = gather(problem, opts.decimate)?;
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
    let names: Vec<String> = problem.baseline_names.clone();
    let (baseline, base_params) = model_fit(&fit, &val, &[], &names)
        .map_err(|e| anyhow::anyhow!("fitting the baseline model [{}]: {e}", names.join(", ")))?;
    let mut search = Search::new(&fit, &val, names, baseline.clone(), base_params.clone());
    let base_e = search.current_e.clone();
    let mut accepted: Vec<Step> = Vec::new();
    let mut rejected: Vec<Step> = Vec::new();
    let mut set_aside = vec![false; problem.candidates.len()];
    let groups = effect_groups(&problem.candidates);
    let mut group_aside = vec![false; groups.len()];
    let mut misses = 0usize;
    // The steps set aside since the last term kept, as rivals: a kept
    // term names those of other families that explained more.
    let mut since_kept: Vec<Rival> = Vec::new();
    while search.chosen.len() < opts.max_terms && misses < opts.patience {
        let Some(errs) = search.error_reduction_ratios(&set_aside) else {
            break;
        };
        // The best single term, and the best group of parts of one effect
        // that still fits in `max_terms`; a group competes with its ratio
        // as one effect.
        let room = opts.max_terms - search.chosen.len();
        let single = best(&errs, &classes, None);
        let group = first_max(
            groups
                .iter()
                .enumerate()
                .filter(|(g, m)| !group_aside[*g] && m.len() <= room)
                .filter_map(|(g, m)| search.group_err(m).map(|e| (g, e))),
        );
        let (members, err, group_label) = match (single, group) {
            (_, Some((g, ge))) if single.is_none_or(|(_, e)| ge > e) => {
                let parts: Vec<Term> = groups[g].iter().map(|&m| problem.candidates[m]).collect();
                (
                    groups[g].clone(),
                    ge,
                    Some((g, group_label(&parts, &problem.signal_names))),
                )
            }
            (Some((k, e)), _) => (vec![k], e, None),
            (None, _) => break,
        };
        let k = members[0];
        let rival = best(&errs, &classes, Some(&classes[k]))
            .filter(|&(_, e)| e >= RIVAL_SHARE * err)
            .map(|(j, e)| Rival {
                label: labels[j].clone(),
                class: classes[j].clone(),
                err: e,
            });
        let mut idx = search.chosen.clone();
        idx.extend(&members);
        let mut nm = search.names.clone();
        nm.extend(members.iter().map(|&m| labels[m].clone()));
        let set_aside_now = |set_aside: &mut [bool], group_aside: &mut [bool]| match group_label {
            Some((g, _)) => group_aside[g] = true,
            None => set_aside[k] = true,
        };
        let Ok((mf, p)) = model_fit(&fit, &val, &idx, &nm) else {
            // Numerically dependent on the model: never a candidate again.
            set_aside_now(&mut set_aside, &mut group_aside);
            continue;
        };
        let gain = (search.current.val_rmse - mf.val_rmse) / search.current.val_rmse;
        let cand_e = residual(&val, &idx, &p);
        // Against the model so far and against the baseline: steps that
        // each harm nothing significant may still add up to harm.
        let harm = worst_harm(problem, &val, &cand_e, &search.current_e, opts.min_gain)
            .or_else(|| worst_harm(problem, &val, &cand_e, &base_e, opts.min_gain));
        let step = |m: usize| Step {
            term: problem.candidates[m],
            candidate: m,
            label: labels[m].clone(),
            meaning: problem.candidates[m].meaning(),
            err,
            fit: mf.clone(),
            gain,
            class: classes[m].clone(),
            rival: rival.clone(),
            passed_over: Vec::new(),
            harm: None,
            evidence: None,
            unfiltered_gain: None,
            reclassified_from: None,
            group: group_label.as_ref().map(|(_, l)| l.clone()),
        };
        if gain >= opts.min_gain && harm.is_none() {
            let passed_over = passed_over(&since_kept, &classes[k], err);
            since_kept.clear();
            // Part by part into the basis; the fit is the whole group's.
            for &m in &members {
                search.accept(m, nm.clone(), mf.clone(), p.clone(), cand_e.clone());
                accepted.push(Step {
                    passed_over: passed_over.clone(),
                    ..step(m)
                });
            }
            misses = 0;
        } else {
            set_aside_now(&mut set_aside, &mut group_aside);
            misses += 1;
            let mut st = step(k);
            if let Some((_, l)) = &group_label {
                st.label = l.clone();
            }
            st.harm = harm.filter(|_| gain >= opts.min_gain);
            since_kept.push(Rival {
                label: st.label.clone(),
                class: st.class.clone(),
                err,
            });
            rejected.push(st);
        }
    }

    let e_before = residual(&val, &[], &base_params);
    let e_after = residual(&val, &search.chosen, &search.params);
    let before = diagnostics(problem, &val, &e_before, &labels, &search.usable, opts);
    let after = diagnostics(problem, &val, &e_after, &labels, &search.usable, opts);
    for step in &mut accepted {
        let c = &val.cand[step.candidate];
        step.evidence = Some((corr(&e_before, c), corr(&e_after, c)));
    }
    let unfiltered = unfiltered_gains(problem, opts, &accepted);
    for (step, unfiltered) in accepted.iter_mut().zip(unfiltered) {
        step.unfiltered_gain = unfiltered;
        if unfiltered.is_some_and(|g| g < FILTERING_SHARE * step.gain) {
            step.reclassified_from = Some(std::mem::replace(
                &mut step.class,
                OBSERVER_FILTERING.to_owned(),
            ));
        }
    }
    let (runs, traces) = run_results(problem, &val, &search, &e_before, &e_after);
    // The test runs, judged once by the model chosen without them.
    let test_runs = run_errors(
        problem,
        &test,
        &residual(&test, &[], &base_params),
        &residual(&test, &search.chosen, &search.params),
    );
    if !baseline.val_rmse.is_finite() {
        bail!("the baseline's validation error is not finite");
    }
    Ok(Outcome {
        n_fit: fit.len(),
        n_val: val.len(),
        n_candidates: search.usable.iter().filter(|u| **u).count(),
        baseline,
        accepted,
        rejected,
        final_fit: search.current,
        before,
        after,
        runs,
        traces,
        test_runs,
    })
}

/// The family of a kept term that stands in for what the core's observer
/// filters out of the baseline's differentiated inputs (its lag, and motion
/// above its bandwidth) rather than for an effect of the plant.
pub const OBSERVER_FILTERING: &str = "observer filtering";

/// A kept term is [`OBSERVER_FILTERING`] when, with the baseline's
/// differentiated inputs taken without the observer's filtering, it keeps
/// less than this share of its validation gain: most of what it explains
/// is then the observer, not the plant.
pub const FILTERING_SHARE: f64 = 0.5;

/// The observer check: each kept step's validation gain when the
/// baseline's differentiated inputs come from the core's observer run
/// forward and backward, without its lag ([`RunData::unfiltered_baseline`]):
/// the JAE's `x2'`, `x2''` and held sign also at a tenth of the rate (what
/// `Config::at_rate` derives) when that is wider than the core's, the
/// tension model's held signs at the core's own bandwidth (their switch
/// speeds are set for its noise). The kept terms are taken in the
/// same order (a group's parts together). A term that stands in for the
/// observer's lag, or for motion above its bandwidth (the motor current is
/// in phase with a limit cycle the observer does not follow), loses its
/// gain there; one that carries an effect of the plant keeps it. `None`
/// per step when a run has no such baseline, or no row of it can be used.
pub fn unfiltered_gains(
    problem: &Problem,
    opts: &SelectOptions,
    accepted: &[Step],
) -> Vec<Option<f64>> {
    let none = vec![None; accepted.len()];
    if accepted.is_empty()
        || problem.runs.iter().any(|r| {
            r.unfiltered_baseline.is_empty() || r.unfiltered_baseline.len() != r.baseline.len()
        })
    {
        return none;
    }
    let unfiltered = Problem {
        candidates: accepted.iter().map(|s| s.term).collect(),
        runs: problem
            .runs
            .iter()
            .map(|r| RunData {
                baseline: r.unfiltered_baseline.clone(),
                unfiltered_baseline: Vec::new(),
                ..r.clone()
            })
            .collect(),
        ..problem.clone()
    };
    let Ok((fit, val, _)) = gather(&unfiltered, opts.decimate) else {
        return none;
    };
    let mut names = problem.baseline_names.clone();
    names.extend(accepted.iter().map(|s| s.label.clone()));
    let val_rmse = |terms: usize| -> Option<f64> {
        let idx: Vec<usize> = (0..terms).collect();
        model_fit(
            &fit,
            &val,
            &idx,
            &names[..problem.baseline_names.len() + terms],
        )
        .ok()
        .map(|(mf, _)| mf.val_rmse)
    };
    let mut out = none;
    let mut start = 0;
    // The model of the steps before `start`, carried from step to step.
    let mut before = val_rmse(0);
    while start < accepted.len() {
        // A group's parts were taken in one step: judged together.
        let end = match &accepted[start].group {
            Some(g) => {
                start
                    + accepted[start..]
                        .iter()
                        .take_while(|s| s.group.as_ref() == Some(g))
                        .count()
            }
            None => start + 1,
        };
        let after = val_rmse(end);
        if let (Some(b), Some(a)) = (before, after) {
            let gain = (b - a) / b;
            for o in &mut out[start..end] {
                *o = gain.is_finite().then_some(gain);
            }
        }
        before = after;
        start = end;
    }
    out
}

/// Batches a validation run is cut into for the standard error of its
/// change in squared error (batch means: each batch, a tenth of a run, is
/// longer than the residual's correlation time on the logs at hand, about
/// 1 s on 20 s runs, so the batch means are nearly independent).
pub const HARM_BATCHES: usize = 10;

/// Student's t for `HARM_BATCHES - 1` degrees of freedom at 95 %
/// (two-sided): a rise smaller than this many standard errors is within
/// what the run's own noise and start-up state make of any refit.
pub const HARM_T: f64 = 2.262;

/// Do no harm: the validation run (regime) a candidate makes worse, the
/// worst first, with its relative rise of the RMSE. A run counts as made
/// worse when its RMSE rises by more than `min_gain` (the smallest gain that
/// keeps a term) and the rise of its mean squared error is significant:
/// more than [`HARM_T`] standard errors of the paired change `e_cand^2 -
/// e_now^2`, estimated by batch means over [`HARM_BATCHES`] batches. A
/// 1 % rise of one run among four, on 20 samples' worth of independent
/// error, is noise; a term that moves one regime's error systematically is
/// not.
fn worst_harm(
    problem: &Problem,
    val: &Split,
    cand_e: &[f64],
    current_e: &[f64],
    min_gain: f64,
) -> Option<(String, f64)> {
    val.runs
        .iter()
        .filter_map(|(ri, first, rows)| {
            let seg = *first..*first + rows.len();
            let (after, before) = (&cand_e[seg.clone()], &current_e[seg]);
            let rise = rms(after) / rms(before) - 1.0;
            let d: Vec<f64> = after
                .iter()
                .zip(before)
                .map(|(a, b)| a * a - b * b)
                .collect();
            let (mean, se) = batch_mean_se(&d, HARM_BATCHES)?;
            (rise > min_gain && mean > HARM_T * se).then(|| (problem.runs[*ri].name.clone(), rise))
        })
        .fold(None, |w: Option<(String, f64)>, (n, rise)| {
            if w.as_ref().is_none_or(|(_, r)| rise > *r) {
                Some((n, rise))
            } else {
                w
            }
        })
}

/// Mean of `d` and its standard error by batch means (`batches` equal
/// contiguous batches; the remainder rows go to the last); `None` for fewer
/// rows than batches or fewer than two batches.
fn batch_mean_se(d: &[f64], batches: usize) -> Option<(f64, f64)> {
    if batches < 2 || d.len() < batches {
        return None;
    }
    let n = d.len() / batches;
    let means: Vec<f64> = (0..batches)
        .map(|b| {
            let end = if b + 1 == batches {
                d.len()
            } else {
                (b + 1) * n
            };
            let s = &d[b * n..end];
            s.iter().sum::<f64>() / s.len() as f64
        })
        .collect();
    let mean = d.iter().sum::<f64>() / d.len() as f64;
    let m = means.iter().sum::<f64>() / batches as f64;
    let var = means.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (batches - 1) as f64;
    Some((mean, (var / batches as f64).sqrt()))
}

/// Each run of `split`: its RMSE before and after and its mean error after.
fn run_errors(
    problem: &Problem,
    split: &Split,
    e_before: &[f64],
    e_after: &[f64],
) -> Vec<RunError> {
    split
        .runs
        .iter()
        .map(|(ri, first, rows)| {
            let seg = *first..*first + rows.len();
            RunError {
                name: problem.runs[*ri].name.clone(),
                rows: rows.len(),
                before_rmse: rms(&e_before[seg.clone()]),
                after_rmse: rms(&e_after[seg.clone()]),
                after_mean: e_after[seg].iter().sum::<f64>() / rows.len().max(1) as f64,
            }
        })
        .collect()
}

/// Each validation run's errors before and after, and its traces for the
/// plots (target, model before and after, each kept term's input and
/// contribution).
fn run_results(
    problem: &Problem,
    val: &Split,
    search: &Search,
    e_before: &[f64],
    e_after: &[f64],
) -> (Vec<RunError>, Vec<RunTrace>) {
    let nb = problem.baseline_names.len();
    let runs = run_errors(problem, val, e_before, e_after);
    let mut traces = Vec::new();
    for (ri, first, rows) in &val.runs {
        let run = &problem.runs[*ri];
        let seg = *first..*first + rows.len();
        let target: Vec<f64> = rows.iter().map(|&k| run.target[k]).collect();
        let terms = search
            .chosen
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
                    .map(|i| search.params[nb + j] * val.cand[c][i])
                    .collect();
                (input, contrib)
            })
            .collect();
        let model = |e: &[f64]| -> Vec<f64> { target.iter().zip(e).map(|(y, e)| y - e).collect() };
        traces.push(RunTrace {
            name: run.name.clone(),
            t_s: rows.iter().map(|&k| run.t_s[k]).collect(),
            before: model(&e_before[seg.clone()]),
            after: model(&e_after[seg.clone()]),
            target,
            terms,
        });
    }
    (runs, traces)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::residual::families::term_column;
    use cable_joint::effects::{EffectKind, StrokePart};

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
                ..Default::default()
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

    /// A run of `y = 2 + 0.5 v + 0.3 stop(w)` whose baseline reads `v`
    /// 20 ms late (an observer's lag) and whose unfiltered baseline reads
    /// it on time; the signals are `a = v'` and `w`.
    fn lagged_run(name: &str, phase: f64, fit: bool) -> RunData {
        use std::f64::consts::PI;
        let n = 4000;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
        let (w1, w2) = (2.0 * PI * 1.3, 2.0 * PI * 4.7);
        let v = |t: f64| (w1 * t + phase).sin() + 0.5 * (w2 * t).sin();
        let a: Vec<f32> = t
            .iter()
            .map(|&t| (w1 * (w1 * t + phase).cos() + 0.5 * w2 * (w2 * t).cos()) as f32)
            .collect();
        let w: Vec<f32> = t
            .iter()
            .map(|&t| (2.0 * PI * 0.7 * t + 2.0 * phase).sin() as f32)
            .collect();
        let stop = Term::new(EffectKind::Stop { half_width: 0.1 }, 1);
        let signals = vec![a, w];
        let h = term_column(&stop, &signals, &t, None, None);
        let y: Vec<f64> = t
            .iter()
            .zip(&h)
            .map(|(&t, h)| 2.0 + 0.5 * v(t) + 0.3 * h)
            .collect();
        RunData {
            name: name.into(),
            fixed: vec![0.0; n],
            baseline: vec![t.iter().map(|&t| v(t - 0.02)).collect(), vec![1.0; n]],
            unfiltered_baseline: vec![t.iter().map(|&t| v(t)).collect(), vec![1.0; n]],
            signals,
            target: y,
            fit_rows: if fit { 0..n } else { 0..0 },
            val_rows: if fit { 0..0 } else { 0..n },
            t_s: t,
            ..Default::default()
        }
    }

    /// The observer check: a term that explains only the baseline's lag
    /// (`linear[a]`, `a` being the derivative of the late input) loses its
    /// gain on the unfiltered baseline and is classed
    /// [`OBSERVER_FILTERING`]; the planted effect (`stop[w]`) keeps its
    /// gain and its family.
    #[test]
    fn a_term_that_stands_in_for_the_observers_lag_is_classed_so_and_an_effect_keeps_its_family() {
        let problem = Problem {
            model: "generic".into(),
            target: "y".into(),
            baseline_names: vec!["v".into(), "const".into()],
            signal_names: vec!["a".into(), "w".into()],
            candidates: vec![
                Term::new(EffectKind::Linear, 0),
                Term::new(EffectKind::Stop { half_width: 0.1 }, 1),
            ],
            runs: vec![lagged_run("fit", 0.0, true), lagged_run("val", 1.0, false)],
            ..Default::default()
        };
        let out = select(&problem, &SelectOptions::default()).unwrap();
        let step = |candidate: usize| {
            out.accepted
                .iter()
                .find(|s| s.candidate == candidate)
                .unwrap_or_else(|| panic!("candidate {candidate} not kept: {:?}", out.accepted))
        };
        let (lag, effect) = (step(0), step(1));
        assert_eq!(lag.class, OBSERVER_FILTERING);
        // The renamed term keeps its kind's family (the one its rival was
        // weighed against); the effect was not renamed.
        assert_eq!(
            lag.reclassified_from.as_deref(),
            Some(effect_class(&lag.term, &problem.signal_names, &problem.other_sensors).as_str())
        );
        assert_eq!(lag.family(), lag.reclassified_from.as_deref().unwrap());
        assert_eq!(effect.reclassified_from, None);
        let g = lag.unfiltered_gain.unwrap();
        assert!(g < FILTERING_SHARE * lag.gain, "{g} against {}", lag.gain);
        assert_eq!(effect.class, "hysteresis");
        let g = effect.unfiltered_gain.unwrap();
        assert!(
            g >= FILTERING_SHARE * effect.gain,
            "{g} against {}",
            effect.gain
        );
        // Without an unfiltered baseline on one run, or on every run (a
        // model that differentiates nothing), there is no check.
        for runs in [vec![1], vec![0, 1]] {
            let mut unchecked = problem.clone();
            for r in runs {
                unchecked.runs[r].unfiltered_baseline.clear();
            }
            let out = select(&unchecked, &SelectOptions::default()).unwrap();
            assert!(out.accepted.iter().all(|s| s.unfiltered_gain.is_none()));
            assert!(out.accepted.iter().all(|s| s.class != OBSERVER_FILTERING));
        }
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
            ..Default::default()
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

    /// The batch-means test behind do no harm: a rise of one run's squared
    /// error that flips sign from batch to batch (what another refit makes
    /// of a run's noise) is not significant; the same mean rise held in
    /// every batch is.
    #[test]
    fn a_rise_within_a_runs_noise_is_not_harm_and_a_steady_one_is() {
        let n = 1000;
        // Batches alternate between +3 and -1: mean +1, standard error 0.67.
        let noisy: Vec<f64> = (0..n)
            .map(|k| if (k / 100) % 2 == 0 { 3.0 } else { -1.0 })
            .collect();
        let (mean, se) = batch_mean_se(&noisy, HARM_BATCHES).unwrap();
        assert!(
            (mean - 1.0).abs() < 1e-12 && mean < HARM_T * se,
            "{mean} {se}"
        );
        let steady: Vec<f64> = (0..n).map(|k| 1.0 + 0.1 * ((k % 7) as f64 - 3.0)).collect();
        let (mean, se) = batch_mean_se(&steady, HARM_BATCHES).unwrap();
        assert!(mean > HARM_T * se, "{mean} {se}");
        assert!(
            batch_mean_se(&steady[..5], HARM_BATCHES).is_none(),
            "too few rows"
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
            ..Default::default()
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

    /// A drift in the training rows only (a warm-up the validation run does
    /// not have) explains more of the fit's residual than a stiffness term
    /// does, but raises the validation error and is set aside; the
    /// stiffness term is kept and names drift as passed over, with its
    /// larger ERR.
    #[test]
    fn a_family_set_aside_with_a_larger_err_is_named_by_the_term_kept() {
        let n = 3000;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
        let u: Vec<f32> = t.iter().map(|t| (7.0 * t).sin() as f32).collect();
        let x: Vec<f32> = t.iter().map(|t| (19.0 * t).sin() as f32).collect();
        let y: Vec<f64> = (0..n)
            .map(|k| {
                let warm_up = if k < 2000 { 0.5 * t[k] } else { 0.0 };
                u[k] as f64 + 0.2 * x[k] as f64 + warm_up
            })
            .collect();
        let problem = Problem {
            model: "generic".into(),
            target: "y".into(),
            baseline_names: vec!["u".into(), "const".into()],
            signal_names: vec!["u".into(), "x_m".into()],
            candidates: vec![
                Term::new(EffectKind::Time { scale_s: 1.0 }, 0),
                Term::new(EffectKind::Linear, 1),
            ],
            runs: vec![RunData {
                name: "r".into(),
                fixed: vec![0.0; n],
                baseline: vec![u.iter().map(|v| *v as f64).collect(), vec![1.0; n]],
                signals: vec![u.clone(), x.clone()],
                target: y,
                fit_rows: 0..2000,
                val_rows: 2000..n,
                t_s: t,
                ..Default::default()
            }],
            ..Default::default()
        };
        let out = select(&problem, &SelectOptions::default()).unwrap();
        let kept = &out.accepted[0];
        assert_eq!(kept.class, "stiffness", "{:?}", out.accepted);
        let passed = &kept.passed_over;
        assert_eq!(passed.len(), 1, "{passed:?}");
        assert_eq!(passed[0].class, "drift");
        assert!(passed[0].err > kept.err, "{passed:?} against {}", kept.err);
        assert!(out.rejected.iter().any(|r| r.class == "drift"));
    }

    #[test]
    fn passed_over_keeps_the_best_of_each_other_family_above_the_kept_err() {
        let r = |class: &str, err: f64| Rival {
            label: format!("{class}{err}"),
            class: class.into(),
            err,
        };
        let aside = [
            r("drift", 0.10),
            r("thermal", 0.11),
            r("drift", 0.12),
            r("friction", 0.2),
            r("creep", 0.04),
        ];
        let out = passed_over(&aside, "friction", 0.06);
        let got: Vec<(&str, f64)> = out.iter().map(|o| (o.class.as_str(), o.err)).collect();
        assert_eq!(got, [("drift", 0.12), ("thermal", 0.11)]);
    }

    /// A load carried with a gain and an offset of each stroke's own:
    /// `y = u + 0.9 held(u) - 0.3 held(u sgn v) - 0.07 held(sgn v)`, the
    /// three `stroke_load` parts at one time constant. With only the
    /// stroke's level among the candidates, nothing matches the load;
    /// with all three parts the selection takes them in one step, as one
    /// effect (each step names the group), recovers the coefficients and
    /// leaves the noise.
    #[test]
    fn the_parts_of_one_stroke_load_are_taken_together() {
        let part = |part| EffectKind::StrokeHold {
            v_min: 0.05,
            tau_s: 0.3,
            part,
        };
        let parts = [StrokePart::Level, StrokePart::Signed, StrokePart::Direction];
        let mk = |name: &str, f_hz: f64, level: f64| {
            let n = 6000;
            let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
            let w = 2.0 * std::f64::consts::PI * f_hz;
            // Velocity and a load that depends on the stroke's direction.
            let v: Vec<f32> = t.iter().map(|t| (w * t).cos() as f32).collect();
            let u: Vec<f32> = v
                .iter()
                .zip(&t)
                .map(|(v, t)| {
                    (level * (1.0 + 0.4 * v.signum() as f64) + 0.05 * (7.0 * t).sin()) as f32
                })
                .collect();
            let signals = vec![u.clone(), v];
            let cols: Vec<Vec<f64>> = parts
                .iter()
                .map(|&p| term_column(&Term::with_aux(part(p), 0, 1), &signals, &t, None, None))
                .collect();
            let y: Vec<f64> = (0..n)
                .map(|k| {
                    f64::from(u[k]) + 0.9 * cols[0][k] - 0.3 * cols[1][k] - 0.07 * cols[2][k]
                        + 1e-4 * ((k * 7919 % 1000) as f64 / 500.0 - 1.0)
                })
                .collect();
            RunData {
                name: name.into(),
                fixed: vec![0.0; n],
                baseline: vec![u.iter().map(|x| f64::from(*x)).collect(), vec![1.0; n]],
                signals,
                target: y,
                fit_rows: 0..n,
                val_rows: 0..0,
                t_s: t,
                ..Default::default()
            }
        };
        let mut val = mk("val", 0.7, 1.5);
        (val.fit_rows, val.val_rows) = (0..0, 0..val.t_s.len());
        let problem = |candidates: Vec<Term>| Problem {
            model: "generic".into(),
            target: "y".into(),
            baseline_names: vec!["u".into(), "const".into()],
            signal_names: vec!["u".into(), "v".into()],
            candidates,
            runs: vec![mk("a", 0.5, 1.0), mk("b", 1.0, 2.0), val.clone()],
            ..Default::default()
        };
        let all: Vec<Term> = parts
            .iter()
            .map(|&p| Term::with_aux(part(p), 0, 1))
            .collect();
        let out = select(&problem(all), &SelectOptions::default()).unwrap();
        let labels: Vec<&String> = out.accepted.iter().map(|s| &s.label).collect();
        assert_eq!(out.accepted.len(), 3, "accepted {labels:?}");
        let group = out.accepted[0].group.clone().expect("taken as one effect");
        assert!(
            group.starts_with("stroke_load[u; u*sgn(v); sgn(v)]"),
            "{group}"
        );
        for (s, want) in out.accepted.iter().zip(parts) {
            assert_eq!(s.group.as_deref(), Some(group.as_str()));
            assert!(matches!(s.term.kind, EffectKind::StrokeHold { part, .. } if part == want));
        }
        for (c, want) in out.final_fit.coefs[2..].iter().zip([0.9, -0.3, -0.07]) {
            assert!(
                (c.value - want).abs() < 0.01,
                "{} = {} (want {want})",
                c.name,
                c.value
            );
        }
        assert!(
            out.after.rmse < 1e-3,
            "left {} of {}",
            out.after.rmse,
            out.before.rmse
        );
        // The level alone (no group to take) leaves most of the load.
        let level = vec![Term::with_aux(part(StrokePart::Level), 0, 1)];
        let alone = select(&problem(level), &SelectOptions::default()).unwrap();
        assert!(alone.accepted.iter().all(|s| s.group.is_none()));
        assert!(
            alone.after.rmse > 10.0 * out.after.rmse,
            "the level alone {} against the group {}",
            alone.after.rmse,
            out.after.rmse
        );
    }
}
