//! What the fits return.

use serde::Serialize;

use super::{term, JointFit, ModelTerm, Regressor, SpringFit};
use crate::stats::ErrorStats;

/// One estimated parameter.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ParamEstimate {
    /// Its regressor.
    pub regressor: Regressor,
    /// The regressor's symbol.
    pub symbol: &'static str,
    /// Parameter name.
    pub name: &'static str,
    /// Parameter unit.
    pub unit: &'static str,
    /// Estimate.
    pub value: f64,
    /// Standard deviation.
    pub std: f64,
    /// `100 std / |value|`, %.
    pub pct_sigma: f64,
    /// `%sigma` scaled by `sqrt` of the residual's correlation time
    /// ([`FitReport::residual_corr_ticks`]): what it is with correlated
    /// residuals (reported; the pruning uses the seed's `%sigma`).
    pub pct_sigma_eff: f64,
}

/// A fitted model: its parameters, the fit's quality and its errors.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FitReport {
    /// Model name.
    pub model: String,
    /// Parameters in regressor order.
    pub params: Vec<ParamEstimate>,
    /// Rows used.
    pub rows: u64,
    /// Residual standard deviation `sqrt(RSS / (n - p))`, output unit.
    pub sigma: f64,
    /// Condition number of the equilibrated regressor matrix.
    pub condition: f64,
    /// Integrated autocorrelation time of the residual, ticks
    /// ([`correlation_time`](crate::stats::correlation_time)). The standard deviations (and `%sigma`)
    /// assume independent residuals; with correlated ones they are
    /// optimistic by about `sqrt` of this.
    pub residual_corr_ticks: f64,
    /// Errors on the identification data.
    pub errors: ErrorStats,
}

impl FitReport {
    /// The parameter of `regressor`, if the model has it.
    pub fn param(&self, regressor: Regressor) -> Option<&ParamEstimate> {
        self.params.iter().find(|p| p.regressor == regressor)
    }

    /// Standard deviation of the parameter of `regressor` with the
    /// residual's correlation taken into account, `std sqrt(tau)` (the
    /// `%sigma eff` column in the parameter's unit), if the model has it.
    pub fn std_eff(&self, regressor: Regressor) -> Option<f64> {
        self.param(regressor)
            .map(|p| p.std * self.residual_corr_ticks.max(1.0).sqrt())
    }

    /// Value of the parameter of `regressor`, 0 if the model lacks it.
    pub fn value(&self, regressor: Regressor) -> f64 {
        self.param(regressor).map_or(0.0, |p| p.value)
    }

    /// The model's terms.
    pub fn terms(&self) -> Vec<ModelTerm> {
        self.params
            .iter()
            .map(|p| term(p.regressor, p.name, p.unit))
            .collect()
    }
}

/// Error statistics of a model on a log not used for the fit.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Validation {
    /// The log (file name or label).
    pub log: String,
    /// Model name.
    pub model: String,
    /// Errors.
    pub errors: ErrorStats,
}

/// Result of [`identify_bm`](super::identify_bm).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BmResult {
    /// The fit (`B_m`, `tau_0`, optionally `tau_c`).
    pub fit: FitReport,
    /// `B_m`, N·m·s/rad.
    pub b_m_nm_s_rad: f64,
    /// Coulomb torque at the motor shaft, N·m, when fitted and kept. The
    /// core's DOB does not subtract it: in the coupled runs it appears in
    /// the tension (as `tau_c z_i / r_m`, inside model C's `f_sc1`).
    pub coulomb_nm: Option<f64>,
    /// `%sigma` of the Coulomb term when the pruning rule dropped it.
    pub coulomb_dropped_pct_sigma: Option<f64>,
}

/// Result of [`identify_jae`](super::identify_jae).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct JaeResult {
    /// The fit (`c1..c4`, offset).
    pub fit: FitReport,
    /// `chi_s = [c1, c2, c3, c4]` (Eq. 26).
    pub chi_s: [f64; 4],
    /// Constant offset, rad.
    pub offset_rad: f64,
    /// Identification error `theta_hat - theta`, degrees.
    pub error_deg: ErrorStats,
    /// The return spring's rate through the motor on the same runs (the
    /// force scale of the cable stiffnesses).
    pub spring: SpringFit,
    /// The joint's torque balance on the same runs (cable 1's stiffness and
    /// the pin's friction, for the stretch and fused force estimates).
    pub joint: JointFit,
    /// The cables' stiffness scale's relative uncertainty
    /// (`fusion.stiffness_tolerance`) and its two parts: `[total, spring
    /// rate, cable 2]` (cable 2's from its slipping fit, or from `c4`).
    pub stiffness_tolerance: [f64; 3],
}

/// Result of [`identify_tension`](super::identify_tension).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TensionResult {
    /// Where `theta` came from (`theta_rad`: magnetic encoder, or
    /// `theta_hat_rad`: the JAE).
    pub theta_source: String,
    /// `B_m` the DOB used for `tension1_hat_n`, N·m·s/rad.
    pub b_m_used_nm_s_rad: f64,
    /// Model A (Eq. 22), or why it could not be fitted.
    pub model_a: std::result::Result<FitReport, String>,
    /// Model B (Eq. 23), or why it could not be fitted.
    pub model_b: std::result::Result<FitReport, String>,
    /// Model C (Eq. 24/27).
    pub model_c: FitReport,
    /// Regressors the pruning dropped, with their `%sigma` when dropped.
    pub dropped: Vec<(Regressor, f64)>,
    /// Model C after pruning (the seed's simplified model C).
    pub simplified: FitReport,
    /// Refit on the core's structure (the kept ones of [`SIMPLIFIED_C`](super::SIMPLIFIED_C)):
    /// what goes into the configuration.
    pub core: FitReport,
    /// `chi_p = [f_sc1, f_cp2, K_s, F_0]` fitted on the core's structure,
    /// written to the configuration unless [`TensionResult::unphysical`]
    /// or [`TensionResult::unidentified`] (0 for a term the pruning
    /// dropped).
    pub chi_p: [f64; 4],
    /// Kept regressors outside the core's structure (not written).
    pub not_written: Vec<Regressor>,
    /// Slider 2's Coulomb term came out negative beside a positive slider
    /// 1's: `chi_p` is the refit with `f_cp2` at zero (the sentence says
    /// so, with both fits' figures; `None`: no such refit).
    pub slider2_at_zero: Option<String>,
    /// Why `chi_p` is not written, when physics forbids a value of it (a
    /// negative spring rate, preload or Coulomb friction): the
    /// configuration's tension model is kept (`None`: it is written).
    pub unphysical: Option<String>,
    /// Why the log does not identify the friction terms, when the fitted
    /// model's residual exceeds them: the configuration's tension model is
    /// kept (`None`: the log identifies them).
    pub unidentified: Option<String>,
    /// The friction went unidentified and the drive current changed by at
    /// least [`super::LIMIT_CYCLE_SHARE`] of its limit per tick on
    /// average (a limit cycle of the position loop's derivative through
    /// slider 2's mode): [`TensionResult::apply`] takes the derivative from
    /// the grating observer (`cascade.kd_on_observer_rate`), and the run
    /// is to be recorded again with that configuration.
    pub derivative_from_observer: bool,
    /// The drive current's mean change per tick over the logs, A.
    pub current_change_per_tick_a: Option<f64>,
    /// Cable 0's stiffness for the slack check's reach
    /// (`stretch.cable0_n_m`), or why the logs do not give it.
    pub cable0: std::result::Result<super::Cable0Stiffness, String>,
}

/// Everything `host-sim identify` found (the `--json` output).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct IdentifyReport {
    /// `B_m`.
    pub bm: Option<BmResult>,
    /// JAE.
    pub jae: Option<JaeResult>,
    /// Tension models.
    pub tension: Option<TensionResult>,
    /// The stretch estimate's force scale from known weights.
    pub weights: Option<super::WeightsFit>,
    /// Errors on the validation logs.
    pub validation: Vec<Validation>,
    /// Options used.
    pub options: Option<super::IdentOptions>,
}
