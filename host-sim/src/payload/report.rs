//! The report: its types (serialised as the `--json` file) and the tables
//! of parameters.

use cable_joint::payload::{IdentConfig, PayloadFit, AXIS_NAMES, INERTIAL_NAMES};
use serde::Serialize;

use super::{AccelCalibration, Convention, Estimate, GravitySource, Run};

/// Parameters with their standard deviations, for the report.
#[derive(Clone, Debug, Serialize)]
pub struct ParamReport {
    /// Name with unit.
    pub name: String,
    /// Value.
    pub value: f64,
    /// Standard deviation.
    pub std: f64,
    /// `100 std / |value|`.
    pub pct_sigma: f64,
}

pub(super) fn param_table(fit: &PayloadFit, cfg: &IdentConfig) -> Vec<ParamReport> {
    let mut out = Vec::new();
    let mut push = |name: String, v: f64, s: f64| {
        out.push(ParamReport {
            name,
            value: v,
            std: s,
            pct_sigma: 100.0 * s / v.abs(),
        });
    };
    let (p, s) = (&fit.params, &fit.std_dev);
    for (k, axis) in AXIS_NAMES.iter().enumerate() {
        let unit = if k < 3 { "n" } else { "nm" };
        push(format!("f0_{axis}_{unit}"), p.offset[k], s.offset[k]);
    }
    let n_phi = if cfg.inertia { 10 } else { 4 };
    for (k, name) in INERTIAL_NAMES.iter().enumerate().take(n_phi) {
        push((*name).to_owned(), p.inertial[k], s.inertial[k]);
    }
    for (k, axis) in AXIS_NAMES.iter().enumerate() {
        if cfg.comp.creep_on(k) {
            push(format!("creep_{axis}"), p.creep[k], s.creep[k]);
        }
    }
    for (k, axis) in AXIS_NAMES.iter().enumerate() {
        if cfg.comp.drift_on(k) {
            let unit = if k < 3 { "n_s" } else { "nm_s" };
            push(
                format!("drift_{axis}_{unit}"),
                p.drift_per_s[k],
                s.drift_per_s[k],
            );
        }
    }
    out
}

/// Error statistics of one run.
#[derive(Clone, Debug, Serialize)]
pub struct RunReport {
    /// Run name.
    pub name: String,
    /// Whether the run has contact (then the numbers are not errors).
    pub contact: bool,
    /// Samples.
    pub samples: usize,
    /// RMS of the raw sensor minus its start mean, per axis.
    pub raw: [f64; 6],
    /// RMS of `F_e` with the identified `F_0`.
    pub ident: [f64; 6],
    /// RMS of `F_e` after the start tare (offset tracker).
    pub ident_tare: [f64; 6],
    /// RMS of `F_e` with the selected creep/drift terms, after the tare.
    pub comp_tare: [f64; 6],
    /// RMS of the diagnostic affine map's residual
    /// ([`fit_affine_map`](super::fit_affine_map) on the fit run), after the
    /// tare.
    pub affine_tare: [f64; 6],
    /// The offset tracker's correction at the end of the tare window: the
    /// zero drift of this run relative to the fit run's `F_0` (base model).
    pub tare_correction: [f64; 6],
    /// Largest `|F_e|` (selected model, after the tare), per axis.
    pub peak: [f64; 6],
}

/// One creep/drift candidate and its scores.
#[derive(Clone, Debug, Serialize)]
pub struct CandidateReport {
    /// Creep time constant, s (`None`: no creep).
    pub creep_tau_s: Option<f32>,
    /// Linear drift offered.
    pub drift: bool,
    /// Axes that kept a creep column after pruning.
    pub creep_axes: String,
    /// Axes that kept a drift column after pruning.
    pub drift_axes: String,
    /// Weighted score on the fit run (in-sample, tracked).
    pub fit_score: f64,
    /// Weighted score on the no-contact validation runs (tracked).
    pub validation_score: f64,
    /// RMSE per axis on the no-contact validation runs (tracked), pooled.
    pub validation_rmse: [f64; 6],
}

/// A run with its estimates (for plots and tests).
pub struct RunEstimates {
    /// The run.
    pub run: Run,
    /// Raw sensor minus its start mean.
    pub raw: Vec<[f64; 6]>,
    /// Base model.
    pub base: Estimate,
    /// Selected creep/drift model.
    pub selected: Estimate,
}

/// The whole report.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// Orientation convention found on the calibration poses.
    pub convention: Convention,
    /// Accelerometer calibration.
    pub accel_calibration: AccelCalibration,
    /// Steady-state noise std per axis (identification weights are its
    /// inverse).
    pub noise_std: [f64; 6],
    /// Static-pose identification (cross-check).
    pub static_params: Vec<ParamReport>,
    /// Source of `g - a`.
    pub gravity: GravitySource,
    /// IMU lag used, ms.
    pub accel_lag_ms: f64,
    /// Lag curve (lag ms, fit RMSE of the weighted rows), when estimated.
    pub lag_curve: Vec<(f64, f64)>,
    /// Rotational terms included.
    pub rotational: bool,
    /// Low-pass cut-off of wrench and kinematics, Hz (0: none).
    pub lowpass_hz: f64,
    /// Largest |omega| (rad/s) and |alpha| (rad/s²) on the fit run.
    pub max_omega_rad_s: f64,
    /// See `max_omega_rad_s`.
    pub max_alpha_rad_s2: f64,
    /// RMS over the fit run of the rotational force terms
    /// `|alpha x mc + omega x (omega x mc)|`, N, with the identified `mc`.
    pub rot_force_rms_n: f64,
    /// Upper bound of the RMS inertia torque `|I alpha + omega x I omega|`,
    /// N·m, for `|I| <= m r^2` with `r` = 0.1 m.
    pub rot_torque_bound_nm: f64,
    /// Fit run.
    pub fit_run: String,
    /// Samples of the fit run.
    pub fit_samples: u64,
    /// Duration of the fit run, s.
    pub fit_duration_s: f64,
    /// Identification wall time (accumulate + solve) of the base model, s.
    pub ident_time_s: f64,
    /// Condition number of the base model's (weighted, equilibrated) regressor.
    pub condition: f64,
    /// Base model (`F_0`, `m`, `m c`, inertia if asked).
    pub params: Vec<ParamReport>,
    /// Creep/drift candidates.
    pub candidates: Vec<CandidateReport>,
    /// The selected candidate (index into `candidates`).
    pub selected: usize,
    /// Parameters of the selected model.
    pub selected_params: Vec<ParamReport>,
    /// Per-run statistics (fit run first).
    pub runs: Vec<RunReport>,
    /// Contact runs: detected contact interval (|f| > 1.5 N), s.
    pub contact_intervals: Vec<(String, f64, f64)>,
}

pub(super) fn axes_text(on: &[bool; 6], enabled: bool) -> String {
    let v: Vec<&str> = (0..6)
        .filter(|&k| enabled && on[k])
        .map(|k| AXIS_NAMES[k])
        .collect();
    if v.is_empty() {
        "-".to_owned()
    } else {
        v.join(",")
    }
}
