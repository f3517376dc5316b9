//! What the selection returns: each tried step, the fits, the validation
//! runs' errors and traces, the residual's diagnostics.

use cable_joint::effects::Term;

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
    /// Index in [`Problem::candidates`](super::Problem::candidates).
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
    /// The physical family it belongs to ([`effect_class`](super::families::effect_class)).
    pub class: String,
    /// The best candidate of another family at the step it was taken, when
    /// that one explains at least [`RIVAL_SHARE`](super::select::RIVAL_SHARE) of what this one does: the
    /// data do not tell the two families apart.
    pub rival: Option<Rival>,
    /// Families passed over before it was taken (only for kept terms):
    /// the best candidate of each other family that explained more of the
    /// same training residual (a larger ERR) but was set aside on
    /// validation since the last term kept. The data favour them in the
    /// fit and this one on validation; the output says so, so that a
    /// kept term is not read as the only family the residual fits.
    pub passed_over: Vec<Rival>,
    /// A validation run whose error it would have raised by more than the
    /// smallest gain (do no harm), with that rise (relative); only for
    /// set-aside terms.
    pub harm: Option<(String, f64)>,
    /// Correlation of the validation residual with the term's column,
    /// before (baseline) and after (final model); only for kept terms.
    pub evidence: Option<(f64, f64)>,
    /// Its validation gain when the baseline's differentiated inputs are
    /// taken without the core's observer's lag (the JAE's also at a wider
    /// band; [`unfiltered_gains`](super::select::unfiltered_gains); only
    /// for kept terms of a model that differentiates). Below
    /// [`FILTERING_SHARE`](super::select::FILTERING_SHARE) of `gain`, the
    /// term stands in for that filtering and its `class` is
    /// [`OBSERVER_FILTERING`](super::select::OBSERVER_FILTERING).
    pub unfiltered_gain: Option<f64>,
    /// The family the term's kind belongs to when the observer check
    /// renamed `class` [`OBSERVER_FILTERING`](super::select::OBSERVER_FILTERING)
    /// (its `rival` and `passed_over` were weighed against that family).
    pub reclassified_from: Option<String>,
    /// When the term is one part of an effect taken with its other parts
    /// in the same step ([`effect_groups`](super::library::effect_groups)):
    /// that effect's label. `err`, `fit` and `gain` are then the group's.
    pub group: Option<String>,
}

impl Step {
    /// The family of the term's kind, whatever the observer check named
    /// it (the family its `rival` and `passed_over` were weighed against).
    pub fn family(&self) -> &str {
        self.reclassified_from.as_deref().unwrap_or(&self.class)
    }
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
    /// Rows judged (validation or test).
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
    /// Per test run (`--test`: never fitted, never used to choose a term),
    /// before and after; empty without test logs.
    pub test_runs: Vec<RunError>,
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

    /// The pooled RMSE over the test runs, before and after (`None`
    /// without test logs).
    pub fn test_rmse(&self) -> Option<(f64, f64)> {
        let n: usize = self.test_runs.iter().map(|r| r.rows).sum();
        (n > 0).then(|| {
            let pooled = |f: fn(&RunError) -> f64| {
                let ss: f64 = self
                    .test_runs
                    .iter()
                    .map(|r| r.rows as f64 * f(r).powi(2))
                    .sum();
                (ss / n as f64).sqrt()
            };
            (pooled(|r| r.before_rmse), pooled(|r| r.after_rmse))
        })
    }

    /// The final baseline coefficients.
    pub fn baseline_coefs(&self) -> Vec<f64> {
        let nb = self.baseline.coefs.len();
        self.final_fit.coefs[..nb].iter().map(|c| c.value).collect()
    }
}
