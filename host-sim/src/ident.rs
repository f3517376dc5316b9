//! Identification of the seed's models from logs (seed 000 Sect. 3.3 and 4):
//! motor damping `B_m`, the joint-angle estimator `chi_s` (Eq. 25-26) and the
//! no-load tension models A, B, C (Eq. 22-24, 27) with the seed's pruning by
//! `%sigma` to the simplified model C (Eq. 28-29). Results go into the
//! project's TOML configuration.
//!
//! ```text
//! host-sim identify --procedure bm      --log bm.csv      --config-out c.toml
//! host-sim identify --procedure jae     --log jae.csv     --validate jae2.csv --config-out c.toml
//! host-sim identify --procedure tension --log ten.csv     --config c.toml --config-out c.toml
//! host-sim identify --procedure all --log bm.csv jae.csv ten.csv \
//!     --validate bm2.csv jae2.csv ten2.csv --config-out c.toml --json ident.json
//! ```
//!
//! # Data
//!
//! Every log is first replayed through the core ([`crate::derive::derive`]):
//! the regressors are the firmware's own signals (the tracking-observer
//! velocities and accelerations, the held friction signs of
//! [`SignMemory`](cable_joint::filter::SignMemory) with the configuration's switching speeds, the DOB's
//! outputs), not a second implementation of them.
//!
//! * **Filtering.** The DOB's outputs (`load_torque_nm`, `tension1_hat_n`) are
//!   `Q = g/(s+g)` of the torque balance (Eq. 18). The models are linear in
//!   their parameters, so `Q[W chi] = Q[W] chi`: by default every regressor
//!   column is passed through the same discrete `Q` (the core's
//!   [`LowPass1`], same cut-off and rate) before the fit, which removes the
//!   observer's lag from the residual. This is also exactly what the firmware
//!   compares the model with (`tension1_model_n = Q[F_1']`).
//!   [`IdentOptions::filter_regressors`] `= false` gives the seed's plain fit.
//! * **Samples used.** The first [`IdentOptions::skip_start_s`] (0.2 s: the
//!   observers start at rest and the DOB's `Q` has a 16 ms time constant) and
//!   ticks the replay flags as faulted are dropped. For the tension models the
//!   seed notes larger errors at zero joint velocity (hysteresis: the cable is
//!   not rigid) and trusts the identification where the joint moves; ticks
//!   with `|theta'| <` [`IdentOptions::min_joint_vel_rad_s`] (default
//!   0.05 rad/s, about 3 °/s, `theta'` from the magnetic encoder through the
//!   core's tracking observer) are left out of the tension fits. A hold-off
//!   after each still tick ([`IdentOptions::holdoff_s`]) is available but off:
//!   on the simulator it removes the reversals, the only data that tells
//!   `sgn(x1')` from `sgn(x2')`, and the model it leaves fits the moving
//!   ticks but is 2.4 times worse over a whole validation run.
//! * **Offsets.** Every model carries a constant (seed 001's zero drift: no
//!   sensor is assumed to read zero at rest): `tau_0` for `B_m`, the JAE's
//!   `offset_rad`, `F_0` in the tension models. The `B_m` fit also carries
//!   the motor's Coulomb torque `tau_c sgn(phi')` (dropped by the `%sigma`
//!   rule when it is not there): leaving it out biases `B_m`.
//!
//! # Pruning (seed Sect. 4.2)
//!
//! Model C's parameters whose `%sigma = 100 std / |value|` exceeds
//! [`IdentOptions::max_pct_sigma`] (5 %) are dropped. The seed dropped all of
//! them at once ([`IdentOptions::prune_all_at_once`]); by default they are
//! dropped one at a time, the worst first, with a refit after each: when the
//! joint moves, `sgn(theta')`, `sgn(x1')` and `sgn(x2')` are nearly the same
//! column, each of them alone is poorly determined, and dropping all three
//! at once loses the friction altogether. The seed's data ended at
//! `[sgn x1', sgn x2', x2, 1] = [f_sc1, f_cp2, K_s, F_0]` (Eq. 29), which is
//! the structure the core evaluates; the configuration receives a refit on
//! those of the four that survived (a dropped one is written as 0), and kept
//! terms outside them are reported, not written.
//!
//! `%sigma` assumes independent residuals. At 2 kHz they are not (the DOB's
//! `Q`, the velocity loop's oscillation, unmodelled friction transients):
//! each fit reports the residual's correlation time ([`correlation_time`])
//! and `%sigma eff`, the `%sigma` scaled by its square root. The pruning
//! keeps the seed's rule on the plain `%sigma`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Context, Result};
use cable_joint::filter::{Kinematics, LowPass1, TrackingObserver};
use cable_joint::lsq::{BatchLsq, Fit, LsqConfig};
use cable_joint::Config;
use serde::Serialize;

use crate::cli;
use crate::derive::held_sign;
use crate::derive::{config_for_log, derive};
use crate::log::{toml_error, Log};
use crate::output::Outputs;

/// Most regressors one model has (model B, Eq. 23).
pub const MAX_REGRESSORS: usize = 12;

/// One regressor column, computed from the replayed log.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Regressor {
    /// Joint velocity `theta'`, rad/s.
    ThetaVel,
    /// Joint acceleration `theta''`, rad/s².
    ThetaAcc,
    /// Held sign of `theta'`.
    SgnThetaVel,
    /// Joint angle `theta`, rad.
    Theta,
    /// Slider 1 acceleration `x1''`, m/s².
    X1Acc,
    /// Slider 1 velocity `x1'`, m/s.
    X1Vel,
    /// Held sign of `x1'`.
    SgnX1Vel,
    /// Slider 1 position `x1`, m.
    X1,
    /// Slider 2 acceleration `x2''`, m/s².
    X2Acc,
    /// Slider 2 velocity `x2'`, m/s.
    X2Vel,
    /// Held sign of `x2'`.
    SgnX2Vel,
    /// Slider 2 position `x2`, m.
    X2,
    /// Motor velocity `phi'`, rad/s.
    PhiVel,
    /// Held sign of `phi'`.
    SgnPhiVel,
    /// The constant 1.
    One,
}

impl Regressor {
    /// Symbol as the seed writes it.
    pub fn symbol(self) -> &'static str {
        match self {
            Regressor::ThetaVel => "theta'",
            Regressor::ThetaAcc => "theta''",
            Regressor::SgnThetaVel => "sgn(theta')",
            Regressor::Theta => "theta",
            Regressor::X1Acc => "x1''",
            Regressor::X1Vel => "x1'",
            Regressor::SgnX1Vel => "sgn(x1')",
            Regressor::X1 => "x1",
            Regressor::X2Acc => "x2''",
            Regressor::X2Vel => "x2'",
            Regressor::SgnX2Vel => "sgn(x2')",
            Regressor::X2 => "x2",
            Regressor::PhiVel => "phi'",
            Regressor::SgnPhiVel => "sgn(phi')",
            Regressor::One => "1",
        }
    }
}

/// A regressor with the name and unit of its parameter in one model.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct ModelTerm {
    /// The column.
    pub regressor: Regressor,
    /// The parameter's name (seed notation).
    pub param: &'static str,
    /// The parameter's unit.
    pub unit: &'static str,
}

const fn term(regressor: Regressor, param: &'static str, unit: &'static str) -> ModelTerm {
    ModelTerm {
        regressor,
        param,
        unit,
    }
}

/// Motor damping (seed Sect. 3.3/4.2) with an offset, optionally Coulomb.
pub const BM_TERMS: [ModelTerm; 3] = [
    term(Regressor::PhiVel, "B_m", "N·m·s/rad"),
    term(Regressor::One, "tau_0", "N·m"),
    term(Regressor::SgnPhiVel, "tau_c", "N·m"),
];

/// Joint-angle estimator (Eq. 25-26) with an offset.
pub const JAE_TERMS: [ModelTerm; 5] = [
    term(Regressor::X2Acc, "c1", "rad·s²/m"),
    term(Regressor::X2Vel, "c2", "rad·s/m"),
    term(Regressor::SgnX2Vel, "c3", "rad"),
    term(Regressor::X2, "c4", "rad/m"),
    term(Regressor::One, "offset", "rad"),
];

/// Tension model A (Eq. 22).
pub const MODEL_A: [ModelTerm; 6] = [
    term(Regressor::X1Acc, "m_0", "kg"),
    term(Regressor::X1Vel, "f_sv1", "N·s/m"),
    term(Regressor::SgnX1Vel, "f_sc1", "N"),
    term(Regressor::X1, "K_w1", "N/m"),
    term(Regressor::Theta, "-K_w1 r", "N/rad"),
    term(Regressor::One, "F_0", "N"),
];

/// Tension model B (Eq. 23).
pub const MODEL_B: [ModelTerm; 12] = [
    term(Regressor::ThetaAcc, "J_e/r", "N·s²/rad"),
    term(Regressor::ThetaVel, "f_efv/r", "N·s/rad"),
    term(Regressor::SgnThetaVel, "f_efc/r", "N"),
    term(Regressor::Theta, "K_w2 r", "N/rad"),
    term(Regressor::X1Acc, "m_0", "kg"),
    term(Regressor::X1Vel, "f_sv1", "N·s/m"),
    term(Regressor::SgnX1Vel, "f_sc1", "N"),
    term(Regressor::X2Acc, "m_1", "kg"),
    term(Regressor::X2Vel, "f_sv2", "N·s/m"),
    term(Regressor::SgnX2Vel, "f_sc2", "N"),
    term(Regressor::X2, "-K_w2", "N/m"),
    term(Regressor::One, "F_0", "N"),
];

/// Tension model C (Eq. 24), regressors in the order of Eq. 27.
pub const MODEL_C: [ModelTerm; 11] = [
    term(Regressor::ThetaVel, "f_efv/r", "N·s/rad"),
    term(Regressor::ThetaAcc, "J_e/r", "N·s²/rad"),
    term(Regressor::SgnThetaVel, "f_efc/r", "N"),
    term(Regressor::X1Acc, "m_0", "kg"),
    term(Regressor::X1Vel, "f_sv1", "N·s/m"),
    term(Regressor::SgnX1Vel, "f_sc1", "N"),
    term(Regressor::X2Acc, "m_1", "kg"),
    term(Regressor::X2Vel, "f_vp2", "N·s/m"),
    term(Regressor::SgnX2Vel, "f_cp2", "N"),
    term(Regressor::X2, "K_s", "N/m"),
    term(Regressor::One, "F_0", "N"),
];

/// The simplified model C the core evaluates (Eq. 28-29), in the order of
/// [`cable_joint::config::TensionConfig`]'s fields.
pub const SIMPLIFIED_C: [Regressor; 4] = [
    Regressor::SgnX1Vel,
    Regressor::SgnX2Vel,
    Regressor::X2,
    Regressor::One,
];

/// Settings of the identification.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct IdentOptions {
    /// Leading time of every log left out (observer start-up), s.
    pub skip_start_s: f64,
    /// Tension fits: leave out ticks with `|theta'|` below this, rad/s
    /// (0 keeps every tick).
    pub min_joint_vel_rad_s: f64,
    /// Tension fits: also leave out this long after a tick below
    /// [`Self::min_joint_vel_rad_s`], s.
    pub holdoff_s: f64,
    /// Pass the regressors of the DOB-based fits (`B_m`, tension) through the
    /// DOB's own low-pass `Q` (see the module documentation).
    pub filter_regressors: bool,
    /// Pruning limit on `%sigma`, % (seed: 5).
    pub max_pct_sigma: f64,
    /// Pruning as the seed did: drop every parameter above the limit at
    /// once. Default (`false`): one at a time, the worst first, refitting
    /// after each drop, so that of a collinear group (the three friction
    /// signs agree whenever the joint moves) one member is kept.
    pub prune_all_at_once: bool,
    /// DOB-based fits: an extra first-order low-pass at this frequency, Hz,
    /// on both sides of the regression (0 = none).
    pub post_filter_hz: f64,
    /// Fit a Coulomb term `sgn(phi')` next to `B_m` (brushes and gearhead);
    /// it is dropped again if its `%sigma` exceeds [`Self::max_pct_sigma`].
    pub bm_coulomb: bool,
    /// Largest accepted condition number of the equilibrated regressor matrix.
    pub max_condition: f64,
}

impl Default for IdentOptions {
    fn default() -> Self {
        Self {
            skip_start_s: 0.2,
            min_joint_vel_rad_s: 0.05,
            holdoff_s: 0.0,
            filter_regressors: true,
            max_pct_sigma: 5.0,
            prune_all_at_once: false,
            post_filter_hz: 0.0,
            bm_coulomb: true,
            max_condition: 1e10,
        }
    }
}

impl IdentOptions {
    fn check(&self) -> Result<()> {
        if !(self.skip_start_s.is_finite() && self.skip_start_s >= 0.0) {
            bail!("skip_start_s must be finite and >= 0");
        }
        if !(self.min_joint_vel_rad_s.is_finite() && self.min_joint_vel_rad_s >= 0.0) {
            bail!("min_joint_vel_rad_s must be finite and >= 0");
        }
        if !(self.holdoff_s.is_finite() && self.holdoff_s >= 0.0) {
            bail!("holdoff_s must be finite and >= 0");
        }
        if !(self.post_filter_hz.is_finite() && self.post_filter_hz >= 0.0) {
            bail!("post_filter_hz must be finite and >= 0");
        }
        if !(self.max_pct_sigma.is_finite() && self.max_pct_sigma > 0.0) {
            bail!("max_pct_sigma must be finite and > 0");
        }
        if self.max_condition.is_nan() || self.max_condition <= 1.0 {
            bail!("max_condition must be > 1");
        }
        Ok(())
    }
}

/// Error statistics of a model's output against the measured one
/// (`model - measured`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ErrorStats {
    /// Samples.
    pub n: usize,
    /// Mean error.
    pub mean: f64,
    /// Mean absolute error.
    pub mean_abs: f64,
    /// Largest error.
    pub max: f64,
    /// Smallest (most negative) error.
    pub min: f64,
    /// Root-mean-square error.
    pub rmse: f64,
    /// Unit of the numbers.
    pub unit: &'static str,
}

impl ErrorStats {
    /// Statistics of `errors`, each multiplied by `scale`.
    pub fn of(errors: impl IntoIterator<Item = f64>, scale: f64, unit: &'static str) -> Self {
        let (mut n, mut sum, mut sum_abs, mut sum_sq) = (0usize, 0.0, 0.0, 0.0);
        let (mut max, mut min) = (f64::NEG_INFINITY, f64::INFINITY);
        for e in errors {
            let e = e * scale;
            n += 1;
            sum += e;
            sum_abs += e.abs();
            sum_sq += e * e;
            max = max.max(e);
            min = min.min(e);
        }
        let d = n.max(1) as f64;
        Self {
            n,
            mean: sum / d,
            mean_abs: sum_abs / d,
            max: if n > 0 { max } else { f64::NAN },
            min: if n > 0 { min } else { f64::NAN },
            rmse: (sum_sq / d).sqrt(),
            unit,
        }
    }

    /// Largest absolute error.
    pub fn max_abs(&self) -> f64 {
        self.max.abs().max(self.min.abs())
    }
}

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
    /// ([`correlation_time`]). The standard deviations (and `%sigma`)
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

/// Result of [`identify_bm`].
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

/// Result of [`identify_jae`].
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
}

/// The return spring's rate `K_s` measured through the motor. While the
/// transmission slides one way, every friction in the loop (motor, gearhead,
/// slider 1, the pin, slider 2) sits at its kinetic level, so across one
/// such sweep the DOB's tension changes by `K_s dx2` plus viscous and
/// inertial terms, whatever the friction's size: per sweep, the means over
/// its last third less those over its first third give one row
/// `dF_1_hat = K_s dx2 + b dx2' + m dx2''`, and the rows of all sweeps are
/// fitted by least squares. The window means average a stick-slip cycle
/// out (a fit on every tick reads its slip bursts as a softer spring).
/// `x2`, `x2'`, `x2''` go through the DOB's `Q` like the target. A sweep is
/// a run of ticks in which `x1` and `x2` both move the same way faster than
/// the tension model's switching speeds; ticks count once both sliders have
/// moved [`SPRING_MIN_TRAVEL_M`] and three DOB time constants have passed
/// since the sweep began (past presliding and the breakaway).
///
/// The cables' stiffnesses follow from the spring through the JAE's `c4`
/// (Eq. 16), so this rate, not the datasheet's, sets the force scale of the
/// stretch estimate, the fused bound and the slack check. Its own scale is
/// the torque constant's, as the DOB's. Written only when the data pin it
/// down (`%sigma` within the seed's 5 % rule) and contradict the datasheet:
/// the datasheet's rate lies farther from it than its uncertainty, two
/// standard deviations or the disagreement of the fits on the earlier and
/// the later half of the sweeps, whichever is larger (a machine constant
/// does not depend on the trajectory; on the seed's calibration run the
/// halves are the sine and the complex trajectory). Otherwise the datasheet
/// stands: on the simulator's plants with friction-driven stick-slip the
/// fit reads the spring up to 7 % soft within a %sigma of 3.4.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SpringFit {
    /// Ticks inside the sweeps' windows.
    pub rows: u64,
    /// Sweeps (one fitted row each).
    pub sweeps: u64,
    /// `K_s`, N/m, and its `%sigma`.
    pub k_s_n_m: (f64, f64),
    /// The datasheet rate the configuration had, N/m.
    pub datasheet_n_m: f64,
    /// RMS residual, N.
    pub residual_rms_n: f64,
    /// `K_s` fitted on the earlier and on the later half of the sweeps, N/m.
    pub halves_n_m: (f64, f64),
    /// What was written, or why not.
    pub note: String,
}

/// Travel of both sliders since a sweep began before its ticks enter the
/// spring fit, m: several times the micrometre presliding of a guide.
pub const SPRING_MIN_TRAVEL_M: f64 = 20e-6;

/// Largest `%sigma` at which the measured spring rate is written.
const SPRING_MAX_PCT_SIGMA: f64 = 5.0;

/// Fewest sweeps the spring fit needs (one row each, three parameters).
const SPRING_MIN_SWEEPS: usize = 6;

/// Fit [`SpringFit`] on the prepared runs.
fn identify_spring(preps: &[Prepared], config: &Config) -> SpringFit {
    let datasheet = f64::from(config.machine.spring_n_m);
    let mut fit = SpringFit {
        rows: 0,
        sweeps: 0,
        k_s_n_m: (f64::NAN, f64::NAN),
        datasheet_n_m: datasheet,
        residual_rms_n: f64::NAN,
        halves_n_m: (f64::NAN, f64::NAN),
        note: String::new(),
    };
    // Rows [x2, x2', x2'', y], demeaned per sweep.
    let mut rows: Vec<[f64; 4]> = Vec::new();
    for p in preps {
        let cols = (
            p.col("x1_m"),
            p.col("x2_m"),
            p.col("x2_vel_m_s"),
            p.col("x2_acc_m_s2"),
            p.col("tension1_hat_n"),
        );
        let (Ok(x1), Ok(x2), Ok(v2), Ok(a2), Ok(y)) = cols else {
            continue;
        };
        let q = [p.dob_filter(&x2), p.dob_filter(&v2), p.dob_filter(&a2)];
        let period_s = f64::from(p.config().period_s());
        let half = (JOINT_DIFF_HALF_WINDOW_S / period_s).round().max(1.0) as usize;
        let (w1, _) = central_kinematics(&x1, half, period_s);
        let (w2, _) = central_kinematics(&x2, half, period_s);
        // The DOB's Q has forgotten the breakaway after three time constants.
        let settle_s = 3.0 / f64::from(p.cfg.dob.cutoff_rad_s);
        let sw1 = f64::from(p.cfg.tension.sign_switch_x1_m_s);
        let sw2 = f64::from(p.cfg.tension.sign_switch_x2_m_s);
        let mut sweep: Vec<[f64; 4]> = Vec::new();
        let mut start: Option<(usize, f64)> = None;
        // One row per sweep: its last third's means less its first third's.
        let flush = |sweep: &mut Vec<[f64; 4]>, rows: &mut Vec<[f64; 4]>, ticks: &mut u64| {
            let third = sweep.len() / 3;
            if third >= 10 {
                let mean = |part: &[[f64; 4]]| -> [f64; 4] {
                    let m = part.len() as f64;
                    core::array::from_fn(|j| part.iter().map(|r| r[j]).sum::<f64>() / m)
                };
                let (a, b) = (mean(&sweep[..third]), mean(&sweep[sweep.len() - third..]));
                rows.push(core::array::from_fn(|j| b[j] - a[j]));
                *ticks += 2 * third as u64;
            }
            sweep.clear();
        };
        for k in 0..p.len() {
            let dir = w2[k].signum();
            let row = [q[0][k], q[1][k], q[2][k], y[k]];
            let sliding = p.usable[k]
                && w1[k].abs() > sw1
                && w2[k].abs() > sw2
                && w1[k].signum() == dir
                && row.iter().all(|v| v.is_finite());
            match start {
                Some((k0, d)) if sliding && d == dir => {
                    let far = (x1[k] - x1[k0]).abs() >= SPRING_MIN_TRAVEL_M
                        && (x2[k] - x2[k0]).abs() >= SPRING_MIN_TRAVEL_M
                        && (k - k0) as f64 * period_s >= settle_s;
                    if far {
                        sweep.push(row);
                    }
                }
                _ => {
                    flush(&mut sweep, &mut rows, &mut fit.rows);
                    start = sliding.then_some((k, dir));
                }
            }
        }
        flush(&mut sweep, &mut rows, &mut fit.rows);
    }
    fit.sweeps = rows.len() as u64;
    if rows.len() < SPRING_MIN_SWEEPS {
        fit.note = format!(
            "spring rate not measured ({} sweeps of the transmission sliding one way; \
             needs {SPRING_MIN_SWEEPS}): the datasheet's {datasheet:.0} N/m kept",
            rows.len()
        );
        return fit;
    }
    let solve = |rows: &[[f64; 4]]| {
        BatchLsq::<3>::new(3, LsqConfig::default()).and_then(|mut ls| {
            for r in rows {
                ls.push(&[r[0], r[1], r[2]], r[3])?;
            }
            ls.solve()
        })
    };
    let sol = match solve(&rows) {
        Ok(s) => s,
        Err(e) => {
            fit.note = format!(
                "spring rate not measured ({e:?}): the datasheet's {datasheet:.0} N/m kept"
            );
            return fit;
        }
    };
    // A constant of the machine does not depend on the trajectory: the
    // earlier and the later half of the sweeps (on the seed's calibration,
    // the sine and the complex trajectory) bound the fit's own error
    // (`SpringFit::uncertainty_n_m`).
    let (early, late) = rows.split_at(rows.len() / 2);
    if let (Ok(a), Ok(b)) = (solve(early), solve(late)) {
        fit.halves_n_m = (a.params[0], b.params[0]);
    }
    fit.k_s_n_m = (sol.params[0], 100.0 * sol.std_dev[0] / sol.params[0].abs());
    fit.residual_rms_n = sol.rmse;
    fit
}

impl SpringFit {
    /// The measured rate when the data pinned it down, else `None`.
    pub fn value(&self) -> Option<f64> {
        let (k, pct) = self.k_s_n_m;
        let pinned = k.is_finite() && k > 0.0 && pct < SPRING_MAX_PCT_SIGMA;
        (pinned && (k - self.datasheet_n_m).abs() > self.uncertainty_n_m()).then_some(k)
    }

    /// How far the rate may be off, N/m: two standard deviations, or the
    /// disagreement of the earlier and later half of the sweeps (a machine
    /// constant does not depend on the trajectory) when that is larger.
    pub fn uncertainty_n_m(&self) -> f64 {
        let (k, pct) = self.k_s_n_m;
        let spread = (self.halves_n_m.0 - self.halves_n_m.1).abs();
        (0.02 * pct * k.abs()).max(if spread.is_finite() {
            spread
        } else {
            f64::INFINITY
        })
    }

    /// Write the measured rate into `machine.spring_n_m`; returns what was
    /// written, or why not.
    fn apply(&self, config: &mut Config) -> String {
        let (k, pct) = self.k_s_n_m;
        if k.is_nan() {
            return self.note.clone();
        }
        match self.value() {
            Some(k) => {
                config.machine.spring_n_m = k as f32;
                format!(
                    "machine.spring_n_m = {k:.0} ± {:.0} (%sigma {pct:.1}, {} sweeps; the datasheet's {:.0} is outside)",
                    self.uncertainty_n_m(),
                    self.sweeps,
                    self.datasheet_n_m
                )
            }
            None if pct >= SPRING_MAX_PCT_SIGMA => format!(
                "spring rate not pinned down ({k:.0} N/m, %sigma {pct:.1}): the datasheet's {:.0} N/m kept",
                self.datasheet_n_m
            ),
            None => format!(
                "spring rate {k:.0} ± {:.0} N/m ({:.0} and {:.0} on the earlier and later half of the \
                 sweeps) agrees with the datasheet's {:.0} N/m, which is kept",
                self.uncertainty_n_m(),
                self.halves_n_m.0,
                self.halves_n_m.1,
                self.datasheet_n_m
            ),
        }
    }
}

/// The joint's torque balance (seed Eq. 9, 12, 13 with no load) on runs with
/// the magnetic encoder, while the joint slips:
/// `r K_w2 (r theta - x2) = K_w1 r (x1 - r theta) - f_efc sgn(theta') -
/// f_efv theta' - J_e theta'' - c`, with `K_w2` from the JAE's `c4` and the
/// datasheet spring and `K_w1`, the pin's friction, its viscous term, the
/// joint inertia and an offset fitted. The joint speed and acceleration are
/// zero-phase central differences of the magnetic encoder over
/// [`JOINT_DIFF_HALF_WINDOW_S`]: a causal observer lags the slip bursts of a
/// joint in stick-slip and gives the pin's friction to the viscous term.
/// Rows count once the joint has moved [`JOINT_MIN_TRAVEL_RAD`] since its
/// last reversal (past presliding).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct JointFit {
    /// Rows used (joint slipping, not faulted).
    pub rows: u64,
    /// Cable 2 stiffness from `c4` and the datasheet spring, N/m.
    pub k_w2_n_m: f64,
    /// Cable 1 stiffness, N/m, and its `%sigma`.
    pub k_w1_n_m: (f64, f64),
    /// Pin Coulomb friction, N·m, and its `%sigma`.
    pub pin_coulomb_nm: (f64, f64),
    /// Pin viscous friction, N·m·s/rad.
    pub pin_viscous_nm_s_rad: f64,
    /// RMS residual, N·m.
    pub residual_rms_nm: f64,
    /// What was written, or why not.
    pub note: String,
}

/// Largest `%sigma` at which a joint-fit parameter is written.
const JOINT_MAX_PCT_SIGMA: f64 = 30.0;

/// Fit [`JointFit`] on the prepared runs; `c4` is the identified JAE
/// position coefficient.
fn identify_joint(preps: &[Prepared], config: &Config, c4_rad_m: f64) -> JointFit {
    let m = &config.machine;
    let r = f64::from(m.pulley_radius_m);
    let k_w2 = cable_joint::config::StretchConfig::from_jae(
        c4_rad_m as f32,
        m.spring_n_m,
        m.pulley_radius_m,
    )
    .map_or(f64::NAN, |s| f64::from(s.cable2_n_m));
    let empty = |note: String| JointFit {
        rows: 0,
        k_w2_n_m: k_w2,
        k_w1_n_m: (f64::NAN, f64::NAN),
        pin_coulomb_nm: (f64::NAN, f64::NAN),
        pin_viscous_nm_s_rad: f64::NAN,
        residual_rms_nm: f64::NAN,
        note,
    };
    if k_w2.is_nan() {
        return empty(format!(
            "not identified: c4 r = {} gives no cable stiffness",
            c4_rad_m * r
        ));
    }
    // The joint slips when theta' is above the JAE's switching speed seen
    // at the joint (c4 x2').
    let switch = f64::from(config.jae.sign_switch_m_s) * c4_rad_m;
    let mut ls = match BatchLsq::<5>::new(5, LsqConfig::default()) {
        Ok(l) => l,
        Err(e) => return empty(format!("not identified: {e:?}")),
    };
    let mut rows = Vec::new();
    for p in preps.iter().filter(|p| p.theta_source == "theta_rad") {
        let (Ok(theta), Ok(x1), Ok(x2)) = (p.theta(), p.col("x1_m"), p.col("x2_m")) else {
            continue;
        };
        let period_s = f64::from(p.config().period_s());
        let half = (JOINT_DIFF_HALF_WINDOW_S / period_s).round().max(1.0) as usize;
        let (vel, acc) = central_kinematics(theta, half, period_s);
        // Travel since the last reversal: a pin in presliding (its friction
        // still building up after a reversal) is not at its kinetic level.
        let mut travel_rad = 0.0;
        for k in 0..p.len() {
            travel_rad = if k > 0 && vel[k].signum() == vel[k - 1].signum() {
                travel_rad + (theta[k] - theta[k - 1]).abs()
            } else {
                0.0
            };
            if !p.usable[k]
                || !vel[k].is_finite()
                || !acc[k].is_finite()
                || vel[k].abs() <= switch
                || travel_rad < JOINT_MIN_TRAVEL_RAD
            {
                continue;
            }
            let y = r * k_w2 * (r * theta[k] - x2[k]);
            let phi = [
                r * (x1[k] - r * theta[k]),
                -vel[k].signum(),
                -vel[k],
                -acc[k],
                -1.0,
            ];
            if ls.push(&phi, y).is_ok() {
                rows.push((phi, y));
            }
        }
    }
    if rows.len() < 50 {
        return empty(format!(
            "not identified: {} rows with the magnetic encoder and the joint slipping (needs 50)",
            rows.len()
        ));
    }
    let fit = match ls.solve() {
        Ok(f) => f,
        Err(e) => return empty(format!("not identified: {e:?}")),
    };
    let sq: f64 = rows
        .iter()
        .map(|(phi, y)| (y - fit.predict(phi)).powi(2))
        .sum();
    JointFit {
        rows: rows.len() as u64,
        k_w2_n_m: k_w2,
        k_w1_n_m: (fit.params[0], fit.pct_sigma(0)),
        pin_coulomb_nm: (fit.params[1], fit.pct_sigma(1)),
        pin_viscous_nm_s_rad: fit.params[2],
        residual_rms_nm: (sq / rows.len() as f64).sqrt(),
        note: String::new(),
    }
}

/// Half-width of the central differences the joint fit takes of the
/// magnetic encoder, s: long enough that one encoder count over the window
/// is a small speed, short against a slip burst of a joint in stick-slip
/// (tens of milliseconds).
pub const JOINT_DIFF_HALF_WINDOW_S: f64 = 0.005;

/// Joint travel since the last reversal before a row enters the joint fit,
/// rad: 20 µm at a 4 mm pulley, several times the micrometre presliding
/// distance of a pin or a guide, so the friction is at its kinetic level.
pub const JOINT_MIN_TRAVEL_RAD: f64 = 5e-3;

/// Zero-phase speed and acceleration of `x` sampled every `period_s`: central
/// differences over `half` samples either side (NaN within `2 half` of
/// either end).
fn central_kinematics(x: &[f64], half: usize, period_s: f64) -> (Vec<f64>, Vec<f64>) {
    let diff = |u: &[f64]| -> Vec<f64> {
        (0..u.len())
            .map(|k| {
                if k < half || k + half >= u.len() {
                    f64::NAN
                } else {
                    (u[k + half] - u[k - half]) / (2.0 * half as f64 * period_s)
                }
            })
            .collect()
    };
    let vel = diff(x);
    let acc = diff(&vel);
    (vel, acc)
}

impl JointFit {
    /// Write cable 1's stiffness and the pin friction the data identified;
    /// a pin friction the data could not identify becomes model C's upper
    /// bound, a cable 1 it could not identify stays equal to cable 2.
    /// Returns what was written.
    fn apply(&self, config: &mut Config) -> String {
        let (k1, pk1) = self.k_w1_n_m;
        let stiffness = if k1.is_finite() && k1 > 0.0 && pk1 < JOINT_MAX_PCT_SIGMA {
            config.stretch.cable1_n_m = k1 as f32;
            format!("stretch.cable1_n_m = {k1:.0} (%sigma {pk1:.1})")
        } else {
            config.stretch.cable1_n_m = config.stretch.cable2_n_m;
            format!(
                "cable 1 stiffness not identifiable (K_w1 {k1:.0} N/m, %sigma {pk1:.1}): taken as cable 2's"
            )
        };
        let (f, pf) = self.pin_coulomb_nm;
        let pin = if f.is_finite() && pf < JOINT_MAX_PCT_SIGMA {
            config.fusion.pin_coulomb_nm = f.max(0.0) as f32;
            format!("fusion.pin_coulomb_nm = {:.5} (%sigma {pf:.1})", f.max(0.0))
        } else {
            config.fusion.pin_coulomb_nm =
                cable_joint::config::FusionConfig::pin_upper_bound_nm(config);
            "pin friction not identifiable from these runs: the force bound takes model C's upper bound"
                .into()
        };
        format!("{stiffness}; {pin}")
    }
}

/// Result of [`identify_tension`].
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
    /// Refit on the core's structure (the kept ones of [`SIMPLIFIED_C`]):
    /// what goes into the configuration.
    pub core: FitReport,
    /// `chi_p = [f_sc1, f_cp2, K_s, F_0]` written to the configuration
    /// (0 for a term the pruning dropped).
    pub chi_p: [f64; 4],
    /// Kept regressors outside the core's structure (not written).
    pub not_written: Vec<Regressor>,
}

fn to_anyhow(e: cable_joint::lsq::LsqError) -> anyhow::Error {
    anyhow!("{e}")
}

/// A log replayed through the core, with the columns the models need (the
/// report draws the identified models on the same columns).
pub struct Prepared {
    label: String,
    derived: Log,
    cfg: Config,
    /// Rows usable at all: after the start-up, not faulted.
    usable: Vec<bool>,
    /// Time and code of the first fault the replay latched.
    first_fault: Option<(f64, u8)>,
    theta: Option<Vec<f64>>,
    theta_kin: Option<(Vec<f64>, Vec<f64>)>,
    theta_source: &'static str,
    /// Why rows are lost, for the warning [`design`] prints.
    loss: LossNotes,
}

/// What [`Prepared::new`] found that costs rows, for the row-loss warning.
#[derive(Default)]
struct LossNotes {
    /// The first faulted row: "the replay latched ... at line L ...".
    fault: Option<String>,
    /// `theta_rad` is present but not measured everywhere: (rows, first row).
    theta_gap: Option<(usize, usize)>,
    /// The warning was printed (once per log and procedure).
    warned: std::sync::atomic::AtomicBool,
}

impl LossNotes {
    fn new(log: &Log, t: &[f64], fault: &[f64]) -> Self {
        let fault = fault.iter().position(|f| *f != 0.0).map(|k| {
            let code = fault[k] as u8;
            let name = cable_joint::Fault::from_code(code)
                .map_or_else(|| format!("code {code}"), |f| format!("{f} (code {code})"));
            // A value the core's f32 cannot hold is the likely cause.
            let cause = (k.saturating_sub(2)..=k)
                .flat_map(|r| log.names().into_iter().map(move |c| (r, c)))
                .find(|(r, c)| {
                    log.col(c)
                        .is_some_and(|v| v[*r].is_finite() && v[*r].abs() > f64::from(f32::MAX))
                })
                .map(|(r, c)| {
                    format!(
                        "; column {c} = {:e} on line {} is beyond the core's f32 range",
                        log.col(c).map_or(0.0, |v| v[r]),
                        crate::log::line_of_row(r)
                    )
                })
                .unwrap_or_default();
            format!(
                "the replay latched {name} at line {} (t = {} s){cause}",
                crate::log::line_of_row(k),
                t[k]
            )
        });
        let theta_gap = log.col_opt("theta_rad").and_then(|v| {
            let first = v.iter().position(Option::is_none)?;
            Some((v.iter().filter(|x| x.is_none()).count(), first))
        });
        Self {
            fault,
            theta_gap,
            warned: Default::default(),
        }
    }
}

/// Rows one log lost in one fit, by reason.
#[derive(Default)]
struct RowLoss {
    start_up: usize,
    faulted: usize,
    still: usize,
    /// Rows with a non-finite target or regressor: count, first (row, column).
    not_finite: usize,
    first_not_finite: Option<(usize, &'static str)>,
}

/// Which switching speed the `sgn(x2')` column uses.
#[derive(Clone, Copy, PartialEq, Eq)]
enum X2Switch {
    Jae,
    Tension,
}

impl Prepared {
    /// Replay `log` (named `label` in errors) through the core with `config`.
    pub fn new(label: &str, log: &Log, config: &Config, opts: &IdentOptions) -> Result<Self> {
        let cfg = config_for_log(log, config).with_context(|| label.to_owned())?;
        let derived = derive(log, config).with_context(|| format!("replaying {label}"))?;
        let t = derived.time_s()?.to_vec();
        let fault = derived.col_required("fault_code")?;
        let t0 = t.first().copied().unwrap_or(0.0);
        let usable: Vec<bool> = t
            .iter()
            .zip(fault)
            .map(|(t, f)| *t >= t0 + opts.skip_start_s && *f == 0.0)
            .collect();
        let first_fault = t
            .iter()
            .zip(fault)
            .find(|(_, f)| **f != 0.0)
            .map(|(t, f)| (*t, *f as u8));
        // The magnetic encoder when it is measured on every row, else the JAE.
        let (theta, theta_source) = match derived.col_opt("theta_rad") {
            Some(v) if v.iter().all(Option::is_some) => {
                (Some(v.into_iter().flatten().collect()), "theta_rad")
            }
            _ => (
                derived.col("theta_hat_rad").map(<[f64]>::to_vec),
                "theta_hat_rad",
            ),
        };
        let theta_kin = theta.as_ref().map(|th| {
            let obs =
                TrackingObserver::new(cfg.differentiators.grating_bandwidth_hz, cfg.period_s());
            let mut st = Kinematics::default();
            obs.reset(&mut st, th.first().copied().unwrap_or(0.0) as f32);
            let (mut v, mut a) = (Vec::with_capacity(th.len()), Vec::with_capacity(th.len()));
            for x in th {
                let k = obs.update(&mut st, *x as f32);
                v.push(k.vel as f64);
                a.push(k.acc as f64);
            }
            (v, a)
        });
        let loss = LossNotes::new(log, &t, fault);
        Ok(Self {
            label: label.to_owned(),
            first_fault,
            loss,
            derived,
            cfg,
            usable,
            theta,
            theta_kin,
            theta_source,
        })
    }

    fn len(&self) -> usize {
        self.derived.len()
    }

    /// A column of the replay.
    pub fn col(&self, name: &str) -> Result<Vec<f64>> {
        Ok(self
            .derived
            .col(name)
            .ok_or_else(|| anyhow!("{}: replay has no column `{name}`", self.label))?
            .to_vec())
    }

    /// The magnetic encoder when measured on every row, else the JAE, rad.
    pub fn theta(&self) -> Result<&Vec<f64>> {
        self.theta.as_ref().ok_or_else(|| {
            anyhow!(
                "{}: no joint angle (theta_rad or theta_hat_rad)",
                self.label
            )
        })
    }

    /// Joint speed and acceleration of [`Prepared::theta`] through the
    /// core's tracking observer.
    pub fn theta_kin(&self) -> Result<&(Vec<f64>, Vec<f64>)> {
        self.theta_kin.as_ref().ok_or_else(|| {
            anyhow!(
                "{}: no joint angle (theta_rad or theta_hat_rad)",
                self.label
            )
        })
    }

    /// Time, s.
    pub fn t_s(&self) -> Result<&[f64]> {
        Ok(self.derived.time_s()?)
    }

    /// The configuration the log was replayed with (its own control rate).
    pub fn config(&self) -> &Config {
        &self.cfg
    }

    /// The unfiltered column of `r`; `jae`: `sgn(x2')` with the JAE's
    /// switching speed (else the tension model's).
    pub fn regressor_column(&self, r: Regressor, jae: bool) -> Result<Vec<f64>> {
        self.column(
            r,
            if jae {
                X2Switch::Jae
            } else {
                X2Switch::Tension
            },
        )
    }

    /// The unfiltered column of `r`.
    fn column(&self, r: Regressor, x2_switch: X2Switch) -> Result<Vec<f64>> {
        let c = &self.cfg;
        Ok(match r {
            Regressor::ThetaVel => self.theta_kin()?.0.clone(),
            Regressor::ThetaAcc => self.theta_kin()?.1.clone(),
            Regressor::SgnThetaVel => {
                // Slider 2 moves about r theta: the same switching speed.
                let sw = c.tension.sign_switch_x2_m_s / c.machine.pulley_radius_m;
                held_sign(self.theta_kin()?.0.iter().map(|v| *v as f32), sw)
            }
            Regressor::Theta => self.theta()?.clone(),
            Regressor::X1Acc => self.col("x1_acc_m_s2")?,
            Regressor::X1Vel => self.col("x1_vel_m_s")?,
            Regressor::SgnX1Vel => held_sign(
                self.col("x1_vel_m_s")?.iter().map(|v| *v as f32),
                c.tension.sign_switch_x1_m_s,
            ),
            Regressor::X1 => self.col("x1_m")?,
            Regressor::X2Acc => self.col("x2_acc_m_s2")?,
            Regressor::X2Vel => self.col("x2_vel_m_s")?,
            Regressor::SgnX2Vel => {
                let sw = match x2_switch {
                    X2Switch::Jae => c.jae.sign_switch_m_s,
                    X2Switch::Tension => c.tension.sign_switch_x2_m_s,
                };
                held_sign(self.col("x2_vel_m_s")?.iter().map(|v| *v as f32), sw)
            }
            Regressor::X2 => self.col("x2_m")?,
            Regressor::PhiVel => self.col("phi_vel_rad_s")?,
            Regressor::SgnPhiVel => {
                // Slider 1's switching speed at the motor shaft.
                let sw = c.tension.sign_switch_x1_m_s * c.machine.motor_rad_per_cable_m();
                held_sign(self.col("phi_vel_rad_s")?.iter().map(|v| *v as f32), sw)
            }
            Regressor::One => vec![1.0; self.len()],
        })
    }

    /// A first-order low-pass at `cutoff_hz` over a whole column.
    fn low_pass(&self, col: &[f64], cutoff_hz: f64) -> Vec<f64> {
        let lp = LowPass1::new(
            (2.0 * std::f64::consts::PI * cutoff_hz) as f32,
            self.cfg.period_s(),
        );
        let mut y = col.first().copied().unwrap_or(0.0) as f32;
        col.iter()
            .map(|u| f64::from(lp.update(&mut y, *u as f32)))
            .collect()
    }

    /// The DOB's low-pass `Q` over a whole column (state starts at the first
    /// value: the log starts at rest).
    pub fn dob_filter(&self, col: &[f64]) -> Vec<f64> {
        let lp = LowPass1::new(self.cfg.dob.cutoff_rad_s, self.cfg.period_s());
        let mut y = col.first().copied().unwrap_or(0.0) as f32;
        col.iter()
            .map(|u| f64::from(lp.update(&mut y, *u as f32)))
            .collect()
    }
}

/// What a model explains.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Target {
    /// `K_m i - J_m phi''` through `Q` (no-load motor).
    MotorTorque,
    /// Magnetic encoder, rad.
    Theta,
    /// DOB cable-1 tension `tension1_hat_n` (Eq. 21).
    Tension,
}

/// Selected rows of one or more logs: regressor columns and the target.
struct Design {
    cols: Vec<Vec<f64>>,
    y: Vec<f64>,
}

fn design(
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
                .derived
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
        let fault = p.derived.col_required("fault_code")?;
        let mut loss = RowLoss::default();
        for k in 0..p.len() {
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
                loss.first_not_finite.get_or_insert((k, col));
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
                    let name = cable_joint::Fault::from_code(code)
                        .map_or_else(|| format!("code {code}"), |f| format!("{f} (code {code})"));
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
    let n = p.len();
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
fn solve(d: &Design, active: &[usize], opts: &IdentOptions) -> Result<Fit<MAX_REGRESSORS>> {
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

fn report(
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

/// Integrated autocorrelation time of a series, in samples, by batch
/// means: for blocks of `L = 1, 2, 4, ...` samples (at least 20 blocks),
/// `tau_L = L var(block means) / var(samples)`; the largest is returned. It
/// is 1 for white noise and about the correlation length for a correlated
/// series, and unlike a truncated sum of autocorrelations it is not fooled
/// by an oscillating component (the velocity loop's) on top of a slow one.
pub fn correlation_time(x: &[f64]) -> f64 {
    let n = x.len();
    if n < 40 {
        return 1.0;
    }
    let mean = x.iter().sum::<f64>() / n as f64;
    let var = x.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n as f64;
    if var.is_nan() || var <= 0.0 {
        return 1.0;
    }
    let mut tau = 1.0f64;
    let mut len = 2;
    while n / len >= 20 {
        let blocks = n / len;
        let var_means = x
            .chunks_exact(len)
            .map(|b| {
                let m = b.iter().sum::<f64>() / len as f64 - mean;
                m * m
            })
            .sum::<f64>()
            / blocks as f64;
        tau = tau.max(len as f64 * var_means / var);
        len *= 2;
    }
    tau
}

fn fit_terms(
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
fn evaluate(
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

fn prepare_all(
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

fn bm_terms(opts: &IdentOptions) -> &'static [ModelTerm] {
    if opts.bm_coulomb {
        &BM_TERMS
    } else {
        &BM_TERMS[..2]
    }
}

/// `B_m` from a no-load motor run with the default options.
pub fn identify_bm(log: &Log, config: &Config) -> Result<BmResult> {
    identify_bm_with(&[("log", log)], config, &IdentOptions::default())
}

/// `B_m` (seed Sect. 3.3/4.2) from no-load motor runs `(label, log)`:
/// `Q[K_m i - J_m phi''] = B_m Q[phi'] + tau_0 (+ tau_c Q[sgn phi'])`.
pub fn identify_bm_with(
    logs: &[(&str, &Log)],
    config: &Config,
    opts: &IdentOptions,
) -> Result<BmResult> {
    let preps = prepare_all(logs, &decoupled(config), opts)?;
    let fit_with = |terms: &[ModelTerm]| {
        fit_terms(
            "B_m (no-load motor)",
            &preps,
            terms,
            Target::MotorTorque,
            opts,
            1.0,
            "N·m",
        )
    };
    let mut fit = fit_with(bm_terms(opts))?;
    let mut coulomb_dropped = None;
    if let Some(p) = fit.param(Regressor::SgnPhiVel) {
        if p.pct_sigma.is_nan() || p.pct_sigma > opts.max_pct_sigma {
            coulomb_dropped = Some(p.pct_sigma);
            fit = fit_with(&BM_TERMS[..2])?;
        }
    }
    let b = fit.value(Regressor::PhiVel);
    if !(b.is_finite() && b >= 0.0) {
        bail!("identified B_m = {b:e} N·m·s/rad is not physical (negative): is the motor really unloaded and moving?");
    }
    Ok(BmResult {
        b_m_nm_s_rad: b,
        coulomb_nm: fit.param(Regressor::SgnPhiVel).map(|p| p.value),
        coulomb_dropped_pct_sigma: coulomb_dropped,
        fit,
    })
}

/// Errors of an identified `B_m` model on another no-load log (N·m).
pub fn validate_bm(
    result: &BmResult,
    log: &Log,
    config: &Config,
    opts: &IdentOptions,
) -> Result<ErrorStats> {
    let preps = prepare_all(&[("validation", log)], &decoupled(config), opts)?;
    evaluate(&result.fit, &preps, Target::MotorTorque, opts, 1.0, "N·m")
}

/// The configuration for replaying a no-load motor run: with the rope wheel
/// unhooked the motor angle says nothing about the joint, so the
/// transmission-slack check (`limits.min_tension_fraction`) is switched off.
pub fn decoupled(config: &Config) -> Config {
    let mut c = *config;
    c.limits.min_tension_fraction = 0.0;
    c
}

impl BmResult {
    /// Write `B_m` into the configuration.
    pub fn apply(&self, config: &mut Config) {
        config.dob.viscous_nm_s_rad = self.b_m_nm_s_rad as f32;
    }
}

/// The JAE with the default options.
pub fn identify_jae(log: &Log, config: &Config) -> Result<JaeResult> {
    identify_jae_with(&[("log", log)], config, &IdentOptions::default())
}

/// The joint-angle estimator (Eq. 25-26) from runs with the magnetic encoder:
/// `theta = c1 x2'' + c2 x2' + c3 sgn(x2') + c4 x2 + offset`.
pub fn identify_jae_with(
    logs: &[(&str, &Log)],
    config: &Config,
    opts: &IdentOptions,
) -> Result<JaeResult> {
    let preps = prepare_all(logs, config, opts)?;
    let fit = fit_terms(
        "JAE (Eq. 25-26)",
        &preps,
        &JAE_TERMS,
        Target::Theta,
        opts,
        1.0,
        "rad",
    )?;
    let error_deg = ErrorStats {
        unit: "deg",
        ..scale_stats(&fit.errors, 180.0 / std::f64::consts::PI)
    };
    let mut spring = identify_spring(&preps, config);
    let mut measured = *config;
    spring.note = spring.apply(&mut measured);
    let mut joint = identify_joint(&preps, &measured, fit.value(Regressor::X2));
    if joint.note.is_empty() {
        joint.note = joint.apply(&mut measured);
    }
    Ok(JaeResult {
        spring,
        joint,
        chi_s: [
            fit.value(Regressor::X2Acc),
            fit.value(Regressor::X2Vel),
            fit.value(Regressor::SgnX2Vel),
            fit.value(Regressor::X2),
        ],
        offset_rad: fit.value(Regressor::One),
        error_deg,
        fit,
    })
}

fn scale_stats(s: &ErrorStats, k: f64) -> ErrorStats {
    ErrorStats {
        mean: s.mean * k,
        mean_abs: s.mean_abs * k,
        max: s.max * k,
        min: s.min * k,
        rmse: s.rmse * k,
        ..*s
    }
}

/// Errors of an identified JAE on another log with the magnetic encoder (deg).
pub fn validate_jae(
    result: &JaeResult,
    log: &Log,
    config: &Config,
    opts: &IdentOptions,
) -> Result<ErrorStats> {
    let preps = prepare_all(&[("validation", log)], config, opts)?;
    evaluate(
        &result.fit,
        &preps,
        Target::Theta,
        opts,
        180.0 / std::f64::consts::PI,
        "deg",
    )
}

impl JaeResult {
    /// Write `chi_s` and the offset into the configuration.
    pub fn apply(&self, config: &mut Config) {
        let j = &mut config.jae;
        j.c_acc_rad_s2_m = self.chi_s[0] as f32;
        j.c_vel_rad_s_m = self.chi_s[1] as f32;
        j.c_sign_rad = self.chi_s[2] as f32;
        j.c_pos_rad_m = self.chi_s[3] as f32;
        j.offset_rad = self.offset_rad as f32;
        // The position coefficient fixes the cable stiffness (Eq. 16):
        // c4 = (K_s + K_w2) / (K_w2 r), with the spring rate measured
        // through the motor, or the datasheet's when it could not be.
        self.spring.apply(config);
        let m = &config.machine;
        if let Some(s) = cable_joint::config::StretchConfig::from_jae(
            config.jae.c_pos_rad_m,
            m.spring_n_m,
            m.pulley_radius_m,
        ) {
            config.stretch = s;
        }
        // The JAE's error beyond slider 2's friction, for the force bound:
        // two RMS of the identification residual.
        let err_rad = 2.0 * self.error_deg.rmse.to_radians();
        if err_rad.is_finite() {
            config.fusion.jae_error_rad = err_rad as f32;
        }
        self.joint.apply(config);
    }
}

/// What the pruning kept and dropped.
struct Pruned {
    /// Kept columns of the design.
    active: Vec<usize>,
    /// The fit on them.
    fit: Fit<MAX_REGRESSORS>,
    /// Dropped regressors with their `%sigma` when dropped, in order.
    dropped: Vec<(Regressor, f64)>,
}

/// The seed's pruning of a fit on all columns of `d` (see the module
/// documentation and [`IdentOptions::prune_all_at_once`]). The spring
/// `K_s x2`, the preload `F_0` (and the JAE's `c4 x2`) and the guides'
/// Coulomb terms are physics the model cannot do without
/// ([`physically_required`]): they are never pruned, whatever their
/// `%sigma` (a poorly excited run says so in the fit's table instead).
fn prune(
    d: &Design,
    terms: &[ModelTerm],
    first: Fit<MAX_REGRESSORS>,
    opts: &IdentOptions,
) -> Result<Pruned> {
    let mut dropped: Vec<(Regressor, f64)> = Vec::new();
    let mut active: Vec<usize> = (0..terms.len()).collect();
    let mut fit = first;
    let pct = |fit: &Fit<MAX_REGRESSORS>, k: usize| {
        let p = fit.pct_sigma(k);
        if p.is_nan() {
            f64::INFINITY
        } else {
            p
        }
    };
    if opts.prune_all_at_once {
        // The seed: every parameter above the limit at once, then refit.
        let mut next = Vec::new();
        for (k, j) in active.iter().enumerate() {
            let p = pct(&fit, k);
            if p > opts.max_pct_sigma && !physically_required(terms[*j].regressor) {
                dropped.push((terms[*j].regressor, p));
            } else {
                next.push(*j);
            }
        }
        if next.is_empty() {
            bail!(
                "pruning at {} % dropped every regressor",
                opts.max_pct_sigma
            );
        }
        if next.len() < active.len() {
            active = next;
            fit = solve(d, &active, opts).context("refitting the pruned model")?;
        }
    }
    // Backward elimination: drop the worst while one is above the limit.
    loop {
        let worst = (0..active.len())
            .filter(|k| !physically_required(terms[active[*k]].regressor))
            .map(|k| (k, pct(&fit, k)))
            .filter(|(_, p)| *p > opts.max_pct_sigma)
            .max_by(|a, b| a.1.total_cmp(&b.1));
        let Some((k, p)) = worst else { break };
        dropped.push((terms[active[k]].regressor, p));
        active.remove(k);
        if active.is_empty() {
            bail!(
                "pruning at {} % dropped every regressor",
                opts.max_pct_sigma
            );
        }
        fit = solve(d, &active, opts).context("refitting the pruned model")?;
    }
    Ok(Pruned {
        active,
        fit,
        dropped,
    })
}

/// Regressors a model needs by physics: the spring/stiffness, the
/// preload/offset, and the guides' Coulomb friction (a guide always has
/// some; a `%sigma` above the limit says the run could not separate it, not
/// that it is zero, and a zero would make the force bound claim the DOB
/// sees through slider 1).
pub fn physically_required(r: Regressor) -> bool {
    matches!(
        r,
        Regressor::X2 | Regressor::One | Regressor::SgnX1Vel | Regressor::SgnX2Vel
    )
}

/// The tension models with the default options.
pub fn identify_tension(log: &Log, config: &Config) -> Result<TensionResult> {
    identify_tension_with(&[("log", log)], config, &IdentOptions::default())
}

/// No-load tension models A, B, C (Eq. 22-24) against the DOB's cable-1
/// tension (Eq. 21, recomputed by the replay with `config.dob.viscous_nm_s_rad`,
/// so pass the configuration with the identified `B_m`), the pruning to the
/// simplified model C, and the refit on the core's structure.
pub fn identify_tension_with(
    logs: &[(&str, &Log)],
    config: &Config,
    opts: &IdentOptions,
) -> Result<TensionResult> {
    let preps = prepare_all(logs, config, opts)?;
    let fit = |name: &str, terms: &[ModelTerm]| {
        fit_terms(name, &preps, terms, Target::Tension, opts, 1.0, "N")
    };
    let model_a = fit("model A (Eq. 22)", &MODEL_A).map_err(|e| format!("{e:#}"));
    let model_b = fit("model B (Eq. 23)", &MODEL_B).map_err(|e| format!("{e:#}"));

    // Model C and the pruning, on one design matrix.
    let regs: Vec<Regressor> = MODEL_C.iter().map(|t| t.regressor).collect();
    let d = design(&preps, &regs, Target::Tension, opts)?;
    let all: Vec<usize> = (0..MODEL_C.len()).collect();
    let fit_c = solve(&d, &all, opts).context("fitting model C (Eq. 24/27)")?;
    let model_c = report("model C (Eq. 24/27)", &d, &MODEL_C, &all, &fit_c, 1.0, "N");

    let Pruned {
        active,
        fit,
        dropped,
    } = prune(&d, &MODEL_C, fit_c, opts)?;
    let simplified = report(
        "simplified model C (Eq. 28-29)",
        &d,
        &MODEL_C,
        &active,
        &fit,
        1.0,
        "N",
    );

    // The core's structure: the kept ones of [sgn x1', sgn x2', x2, 1].
    let core_idx: Vec<usize> = active
        .iter()
        .copied()
        .filter(|j| SIMPLIFIED_C.contains(&MODEL_C[*j].regressor))
        .collect();
    let not_written: Vec<Regressor> = active
        .iter()
        .map(|j| MODEL_C[*j].regressor)
        .filter(|r| !SIMPLIFIED_C.contains(r))
        .collect();
    if core_idx.is_empty() {
        bail!("the pruning kept none of the core's tension terms (sgn x1', sgn x2', x2, 1)");
    }
    let core = if not_written.is_empty() {
        FitReport {
            model: "tension model written (core structure)".to_owned(),
            ..simplified.clone()
        }
    } else {
        let f = solve(&d, &core_idx, opts).context("refitting the core's tension model")?;
        report(
            "tension model written (core structure)",
            &d,
            &MODEL_C,
            &core_idx,
            &f,
            1.0,
            "N",
        )
    };
    let chi_p = SIMPLIFIED_C.map(|r| core.value(r));
    Ok(TensionResult {
        theta_source: preps[0].theta_source.to_owned(),
        b_m_used_nm_s_rad: f64::from(preps[0].cfg.dob.viscous_nm_s_rad),
        model_a,
        model_b,
        model_c,
        dropped,
        simplified,
        core,
        chi_p,
        not_written,
    })
}

/// Errors of every tension model on another no-load log (N): models A, B, C
/// (those that were fitted), the simplified one and the written one.
pub fn validate_tension(
    result: &TensionResult,
    log: &Log,
    config: &Config,
    opts: &IdentOptions,
) -> Result<Vec<(String, ErrorStats)>> {
    let preps = prepare_all(&[("validation", log)], config, opts)?;
    let mut out = Vec::new();
    let models = [
        result.model_a.as_ref().ok(),
        result.model_b.as_ref().ok(),
        Some(&result.model_c),
        Some(&result.simplified),
        Some(&result.core),
    ];
    for m in models.into_iter().flatten() {
        out.push((
            m.model.clone(),
            evaluate(m, &preps, Target::Tension, opts, 1.0, "N")?,
        ));
    }
    Ok(out)
}

impl TensionResult {
    /// Write `chi_p` into the configuration.
    pub fn apply(&self, config: &mut Config) {
        let t = &mut config.tension;
        t.f_sc1_n = self.chi_p[0] as f32;
        t.f_cp2_n = self.chi_p[1] as f32;
        t.k_s_n_m = self.chi_p[2] as f32;
        t.f_0_n = self.chi_p[3] as f32;
    }
}

// --- Configuration files -------------------------------------------------

/// Read and check a configuration file (TOML). Missing tables and keys take
/// the datasheet defaults; an unknown key, a type error or a value that
/// [`Config::validate`] rejects is an error naming the file and the field.
pub fn load_config(path: impl AsRef<Path>) -> Result<Config> {
    let path = path.as_ref();
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("reading configuration {}", path.display()))?;
    let config: Config = toml::from_str(&text)
        .map_err(|e| anyhow!("{}: {}", path.display(), toml_error(&text, &e)))?;
    config
        .validate()
        .map_err(|e| anyhow!("{}: {e}", path.display()))?;
    Ok(config)
}

/// Write `config` as TOML, atomically ([`crate::output`]). An invalid
/// configuration is refused before the file system is touched.
pub fn write_config(path: impl AsRef<Path>, config: &Config) -> Result<()> {
    let mut out = Outputs::new();
    stage_config(&mut out, path, config)?;
    out.commit()?;
    Ok(())
}

/// Stage `config` as TOML among a command's outputs (written by
/// [`Outputs::commit`], all or none); checked as [`write_config`].
pub fn stage_config(out: &mut Outputs, path: impl AsRef<Path>, config: &Config) -> Result<()> {
    let path = path.as_ref();
    config
        .validate()
        .map_err(|e| anyhow!("refusing to write {}: {e}", path.display()))?;
    let text = toml::to_string_pretty(config).context("serializing the configuration")?;
    let header = "# cable-joint configuration (SI units), written by `host-sim identify`.\n\n";
    out.bytes(path, format!("{header}{text}").as_bytes())?;
    Ok(())
}

// --- Command line --------------------------------------------------------

/// What `host-sim identify` identifies.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Procedure {
    /// Motor damping `B_m` from a no-load motor run.
    Bm,
    /// Joint-angle estimator from a run with the magnetic encoder.
    Jae,
    /// Tension models A, B, C and the simplified model C.
    Tension,
    /// All three, in that order (each uses the previous results).
    All,
}

/// Arguments of `host-sim identify`.
#[derive(clap::Args, Debug, Clone)]
pub struct IdentifyArgs {
    /// Which model(s) to identify.
    #[arg(long, value_enum)]
    pub procedure: Procedure,
    /// Logs to fit (CSV). With `all`: three logs in the order bm, jae,
    /// tension, or any number as `bm=FILE`, `jae=FILE`, `tension=FILE`.
    #[arg(long, num_args = 1.., required = true)]
    pub log: Vec<String>,
    /// Logs to validate on (not used for the fit); same form as `--log`.
    #[arg(long, num_args = 1..)]
    pub validate: Vec<String>,
    /// Configuration to start from (TOML; default: the datasheet values).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Where to write the configuration with the identified parameters.
    #[arg(long)]
    pub config_out: PathBuf,
    /// Also write every result as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Leading seconds of each log left out (observer start-up).
    #[arg(long, default_value_t = IdentOptions::default().skip_start_s,
          value_parser = cli::f64_in(0.0, 1e6))]
    pub skip_start_s: f64,
    /// Tension fits: leave out ticks with |theta'| below this, rad/s (0: keep all).
    #[arg(long, default_value_t = IdentOptions::default().min_joint_vel_rad_s,
          value_parser = cli::f64_in(0.0, 1e3))]
    pub min_joint_vel_rad_s: f64,
    /// Tension fits: also leave out this long after the joint was still, s.
    #[arg(long, default_value_t = IdentOptions::default().holdoff_s,
          value_parser = cli::f64_in(0.0, 1e6))]
    pub holdoff_s: f64,
    /// Do not pass the regressors through the DOB's low-pass (the seed's plain fit).
    #[arg(long)]
    pub no_filter: bool,
    /// Pruning limit on %sigma, %.
    #[arg(long, default_value_t = IdentOptions::default().max_pct_sigma,
          value_parser = cli::f64_above(0.0, 1e6))]
    pub max_pct_sigma: f64,
    /// Prune as the seed did: every parameter above the limit at once.
    #[arg(long)]
    pub prune_all_at_once: bool,
    /// DOB-based fits: extra low-pass on both sides, Hz (0: none).
    #[arg(long, default_value_t = IdentOptions::default().post_filter_hz,
          value_parser = cli::f64_in(0.0, 1e4))]
    pub post_filter_hz: f64,
    /// Fit B_m without the Coulomb term sgn(phi') (the seed's model).
    #[arg(long)]
    pub bm_no_coulomb: bool,
}

/// Split `--log`/`--validate` arguments by procedure.
fn assign(files: &[String], procedure: Procedure) -> Result<Vec<(Procedure, PathBuf)>> {
    let order = [Procedure::Bm, Procedure::Jae, Procedure::Tension];
    let tagged = |s: &str| -> Option<(Procedure, PathBuf)> {
        let (tag, file) = s.split_once('=')?;
        let p = match tag {
            "bm" => Procedure::Bm,
            "jae" => Procedure::Jae,
            "tension" => Procedure::Tension,
            _ => return None,
        };
        Some((p, PathBuf::from(file)))
    };
    let mut out = Vec::new();
    let untagged: Vec<&String> = files.iter().filter(|s| tagged(s).is_none()).collect();
    if procedure == Procedure::All && !untagged.is_empty() {
        if untagged.len() != files.len() || files.len() != 3 {
            bail!(
                "with --procedure all give three logs in the order bm, jae, tension, \
                 or tag each one: bm=FILE jae=FILE tension=FILE"
            );
        }
        for (p, f) in order.iter().zip(files) {
            out.push((*p, PathBuf::from(f)));
        }
        return Ok(out);
    }
    for f in files {
        match tagged(f) {
            Some((p, path)) => {
                if procedure != Procedure::All && p != procedure {
                    bail!("`{f}` is tagged for another procedure than {procedure:?}");
                }
                out.push((p, path));
            }
            None => out.push((procedure, PathBuf::from(f))),
        }
    }
    Ok(out)
}

fn read_logs(files: &[(Procedure, PathBuf)], p: Procedure) -> Result<Vec<(String, Log)>> {
    files
        .iter()
        .filter(|(q, _)| *q == p)
        .map(|(_, f)| Ok((f.display().to_string(), Log::read(f)?)))
        .collect()
}

fn refs(logs: &[(String, Log)]) -> Vec<(&str, &Log)> {
    logs.iter().map(|(l, g)| (l.as_str(), g)).collect()
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
    /// Errors on the validation logs.
    pub validation: Vec<Validation>,
    /// Options used.
    pub options: Option<IdentOptions>,
}

/// Run the identification(s) the arguments ask for; returns the report and
/// the configuration with the results applied.
pub fn identify(args: &IdentifyArgs) -> Result<(IdentifyReport, Config)> {
    let opts = IdentOptions {
        skip_start_s: args.skip_start_s,
        min_joint_vel_rad_s: args.min_joint_vel_rad_s,
        holdoff_s: args.holdoff_s,
        filter_regressors: !args.no_filter,
        max_pct_sigma: args.max_pct_sigma,
        prune_all_at_once: args.prune_all_at_once,
        post_filter_hz: args.post_filter_hz,
        bm_coulomb: !args.bm_no_coulomb,
        ..IdentOptions::default()
    };
    opts.check()?;
    let mut config = match &args.config {
        Some(p) => load_config(p)?,
        None => Config::default(),
    };
    let fits = assign(&args.log, args.procedure)?;
    let vals = assign(&args.validate, args.procedure)?;
    let wants = |p: Procedure| args.procedure == p || args.procedure == Procedure::All;
    let mut rep = IdentifyReport {
        options: Some(opts),
        ..IdentifyReport::default()
    };
    for p in [Procedure::Bm, Procedure::Jae, Procedure::Tension] {
        if !wants(p) {
            continue;
        }
        let logs = read_logs(&fits, p)?;
        if logs.is_empty() {
            bail!("no log for the {p:?} procedure");
        }
        let vlogs = read_logs(&vals, p)?;
        let logs = refs(&logs);
        match p {
            Procedure::Bm => {
                let r = identify_bm_with(&logs, &config, &opts)?;
                r.apply(&mut config);
                for (name, log) in &vlogs {
                    let e = validate_bm(&r, log, &config, &opts)
                        .with_context(|| format!("validating B_m on {name}"))?;
                    rep.validation.push(Validation {
                        log: name.clone(),
                        model: r.fit.model.clone(),
                        errors: e,
                    });
                }
                rep.bm = Some(r);
            }
            Procedure::Jae => {
                let r = identify_jae_with(&logs, &config, &opts)?;
                r.apply(&mut config);
                for (name, log) in &vlogs {
                    let e = validate_jae(&r, log, &config, &opts)
                        .with_context(|| format!("validating the JAE on {name}"))?;
                    rep.validation.push(Validation {
                        log: name.clone(),
                        model: r.fit.model.clone(),
                        errors: e,
                    });
                }
                rep.jae = Some(r);
            }
            Procedure::Tension => {
                let r = identify_tension_with(&logs, &config, &opts)?;
                r.apply(&mut config);
                for (name, log) in &vlogs {
                    let v = validate_tension(&r, log, &config, &opts)
                        .with_context(|| format!("validating the tension models on {name}"))?;
                    for (model, e) in v {
                        rep.validation.push(Validation {
                            log: name.clone(),
                            model,
                            errors: e,
                        });
                    }
                }
                rep.tension = Some(r);
            }
            Procedure::All => unreachable!("expanded above"),
        }
    }
    Ok((rep, config))
}

fn fmt_num(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        format!("{v}")
    } else if (1e-3..1e5).contains(&v.abs()) {
        format!("{v:.5}")
    } else {
        format!("{v:.4e}")
    }
}

fn fmt_pct(p: f64) -> String {
    if p.is_finite() {
        format!("{p:.3} %")
    } else {
        "inf".to_owned()
    }
}

/// A fit as a readable table.
pub fn format_fit(f: &FitReport) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{}: {} rows, residual std {}, condition {:.3e}, residual correlation {:.0} ticks",
        f.model,
        f.rows,
        fmt_num(f.sigma),
        f.condition,
        f.residual_corr_ticks
    );
    let _ = writeln!(
        s,
        "  {:<12} {:<9} {:>13} {:>12} {:>11} {:>11}  unit",
        "regressor", "parameter", "value", "std", "%sigma", "%sigma eff"
    );
    for p in &f.params {
        let _ = writeln!(
            s,
            "  {:<12} {:<9} {:>13} {:>12} {:>11} {:>11}  {}",
            p.symbol,
            p.name,
            fmt_num(p.value),
            fmt_num(p.std),
            fmt_pct(p.pct_sigma),
            fmt_pct(p.pct_sigma_eff),
            p.unit
        );
    }
    let _ = writeln!(s, "  errors: {}", format_stats(&f.errors));
    s
}

/// Error statistics in one line.
pub fn format_stats(e: &ErrorStats) -> String {
    format!(
        "n {}, mean {} {u}, mean|e| {} {u}, max {} {u}, min {} {u}, RMSE {} {u}",
        e.n,
        fmt_num(e.mean),
        fmt_num(e.mean_abs),
        fmt_num(e.max),
        fmt_num(e.min),
        fmt_num(e.rmse),
        u = e.unit
    )
}

/// The whole report as text.
pub fn format_report(r: &IdentifyReport) -> String {
    let mut s = String::new();
    if let Some(b) = &r.bm {
        s.push_str(&format_fit(&b.fit));
        if let Some(p) = b.coulomb_dropped_pct_sigma {
            let _ = writeln!(
                s,
                "  Coulomb term sgn(phi') dropped (%sigma {})",
                fmt_pct(p)
            );
        }
        let _ = writeln!(
            s,
            "  -> dob.viscous_nm_s_rad = {:e} (seed: 1.6934e-5)\n",
            b.b_m_nm_s_rad
        );
    }
    if let Some(j) = &r.jae {
        s.push_str(&format_fit(&j.fit));
        let _ = writeln!(s, "  identification error: {}", format_stats(&j.error_deg));
        let _ = writeln!(
            s,
            "  -> jae: chi_s = [{}, {}, {}, {}], offset {} rad (seed: [0.0805, 0.5225, 0.0025, 264.356], error mean 0.275°, max 0.836°)\n",
            fmt_num(j.chi_s[0]),
            fmt_num(j.chi_s[1]),
            fmt_num(j.chi_s[2]),
            fmt_num(j.chi_s[3]),
            fmt_num(j.offset_rad)
        );
        let sp = &j.spring;
        let _ = writeln!(
            s,
            "spring rate through the motor ({} sweeps, {} ticks): K_s {} N/m (%sigma {:.1}), residual rms {} N\n  -> {}",
            sp.sweeps,
            sp.rows,
            fmt_num(sp.k_s_n_m.0),
            sp.k_s_n_m.1,
            fmt_num(sp.residual_rms_n),
            sp.note
        );
        let jf = &j.joint;
        let _ = writeln!(
            s,
            "joint torque balance ({} rows, joint slipping): K_w2 {} N/m (from c4), K_w1 {} N/m (%sigma {:.1}), pin friction {} N·m (%sigma {:.1}), residual rms {} N·m\n  -> {}\n",
            jf.rows,
            fmt_num(jf.k_w2_n_m),
            fmt_num(jf.k_w1_n_m.0),
            jf.k_w1_n_m.1,
            fmt_num(jf.pin_coulomb_nm.0),
            jf.pin_coulomb_nm.1,
            fmt_num(jf.residual_rms_nm),
            jf.note
        );
    }
    if let Some(t) = &r.tension {
        let _ = writeln!(
            s,
            "tension models: theta from {}, DOB with B_m = {:e} N·m·s/rad",
            t.theta_source, t.b_m_used_nm_s_rad
        );
        for m in [&t.model_a, &t.model_b] {
            match m {
                Ok(f) => s.push_str(&format_fit(f)),
                Err(e) => {
                    let _ = writeln!(s, "  not fitted: {e}");
                }
            }
        }
        s.push_str(&format_fit(&t.model_c));
        let dropped: Vec<String> = t
            .dropped
            .iter()
            .map(|(r, p)| format!("{} ({})", r.symbol(), fmt_pct(*p)))
            .collect();
        let _ = writeln!(s, "pruned (%sigma above the limit): {}", dropped.join(", "));
        s.push_str(&format_fit(&t.simplified));
        if !t.not_written.is_empty() {
            let nw: Vec<&str> = t.not_written.iter().map(|r| r.symbol()).collect();
            let _ = writeln!(
                s,
                "  kept terms the core's model does not evaluate (not written): {}",
                nw.join(", ")
            );
            s.push_str(&format_fit(&t.core));
        }
        let _ = writeln!(
            s,
            "  -> tension: chi_p = [f_sc1 {}, f_cp2 {}, K_s {}, F_0 {}] (seed: [3.879, 5.027, 707.7, 19.52])\n",
            fmt_num(t.chi_p[0]),
            fmt_num(t.chi_p[1]),
            fmt_num(t.chi_p[2]),
            fmt_num(t.chi_p[3])
        );
    }
    if !r.validation.is_empty() {
        let _ = writeln!(
            s,
            "validation (model - measured, data not used for the fit):"
        );
        for v in &r.validation {
            let _ = writeln!(s, "  {} on {}: {}", v.model, v.log, format_stats(&v.errors));
        }
    }
    s
}

/// Run the subcommand.
pub fn run(args: IdentifyArgs) -> Result<()> {
    let (rep, config) = identify(&args)?;
    print!("{}", format_report(&rep));
    // The configuration and the report are written together, or neither is.
    let mut out = Outputs::new();
    stage_config(&mut out, &args.config_out, &config)?;
    if let Some(p) = &args.json {
        let text = serde_json::to_string_pretty(&rep).context("serializing the report")?;
        out.bytes(p, text.as_bytes())?;
    }
    out.commit()?;
    println!("configuration written to {}", args.config_out.display());
    if let Some(p) = &args.json {
        println!("report written to {}", p.display());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// xorshift64*, uniform in [-1, 1).
    struct Rng(u64);
    impl Rng {
        fn uniform(&mut self) -> f64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            let u = self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11;
            u as f64 / (1u64 << 52) as f64 - 1.0
        }
        fn normal(&mut self) -> f64 {
            (0..12).map(|_| 0.5 * (self.uniform() + 1.0)).sum::<f64>() - 6.0
        }
    }

    const TERMS: [ModelTerm; 5] = [
        term(Regressor::SgnX1Vel, "f_sc1", "N"),
        term(Regressor::SgnX2Vel, "f_cp2", "N"),
        term(Regressor::X2, "K_s", "N/m"),
        term(Regressor::One, "F_0", "N"),
        term(Regressor::X1Acc, "m_0", "kg"),
    ];

    /// `y = 6 s1 + 2 s2 + 650 x2 + 19.5 + noise n`, with `s2` equal to `s1`
    /// except on `split` of the rows, and a junk column (`x1''`-like) that
    /// does not enter `y`.
    fn design(split: usize, noise: f64, rng: &mut Rng) -> Design {
        let n = 4000;
        let mut d = Design {
            cols: vec![Vec::new(); 5],
            y: Vec::new(),
        };
        for k in 0..n {
            let t = k as f64 * 1e-3;
            let s1 = if (t * 3.0).sin() >= 0.0 { 1.0 } else { -1.0 };
            let s2 = if k % (n / split.max(1)) < 1 && split > 0 {
                -s1
            } else {
                s1
            };
            let x2 = 3e-3 * (t * 1.3).sin();
            let junk = 1e-3 * rng.normal();
            let y = 6.0 * s1 + 2.0 * s2 + 650.0 * x2 + 19.5 + noise * rng.normal();
            for (c, v) in d.cols.iter_mut().zip([s1, s2, x2, 1.0, junk]) {
                c.push(v);
            }
            d.y.push(y);
        }
        d
    }

    fn kept(d: &Design, opts: &IdentOptions) -> (Vec<Regressor>, Fit<MAX_REGRESSORS>) {
        let all: Vec<usize> = (0..TERMS.len()).collect();
        let first = solve(d, &all, opts).unwrap();
        let p = prune(d, &TERMS, first, opts).unwrap();
        (
            p.active.iter().map(|j| TERMS[*j].regressor).collect(),
            p.fit,
        )
    }

    #[test]
    fn pruning_drops_the_junk_and_keeps_the_physics() {
        let mut rng = Rng(0x1234_5678_9abc_def1);
        // s1 and s2 differ on 400 rows: both are determined.
        let d = design(400, 0.3, &mut rng);
        let opts = IdentOptions::default();
        let (kept, fit) = kept(&d, &opts);
        assert_eq!(
            kept,
            vec![
                Regressor::SgnX1Vel,
                Regressor::SgnX2Vel,
                Regressor::X2,
                Regressor::One
            ]
        );
        for (k, want) in [6.0, 2.0, 650.0, 19.5].iter().enumerate() {
            assert!(
                (fit.params[k] - want).abs() < 0.05 * want,
                "param {k}: {} vs {want}",
                fit.params[k]
            );
        }
    }

    #[test]
    fn collinear_friction_signs_are_kept_with_their_sum_determined() {
        let mut rng = Rng(42);
        // s1 and s2 differ on 4 rows only: each alone is poorly determined,
        // their sum (8 N) is not.
        let d = design(4, 2.0, &mut rng);
        let full = solve(&d, &[0, 1, 2, 3, 4], &IdentOptions::default()).unwrap();
        assert!(full.pct_sigma(0) > 5.0 && full.pct_sigma(1) > 5.0);
        for opts in [
            IdentOptions::default(),
            // The seed's all-at-once rule dropped both and lost the friction.
            IdentOptions {
                prune_all_at_once: true,
                ..IdentOptions::default()
            },
        ] {
            let (kept, fit) = kept(&d, &opts);
            assert_eq!(
                kept,
                vec![
                    Regressor::SgnX1Vel,
                    Regressor::SgnX2Vel,
                    Regressor::X2,
                    Regressor::One
                ],
                "the junk term goes, the guides' friction stays"
            );
            let sum = fit.params[0] + fit.params[1];
            assert!((sum - 8.0).abs() < 0.1, "friction sum {sum}");
        }
    }

    #[test]
    fn correlation_time_of_white_and_ar1_noise() {
        let mut rng = Rng(7);
        let white: Vec<f64> = (0..20_000).map(|_| rng.normal()).collect();
        let tau = correlation_time(&white);
        assert!(tau < 1.5, "white noise: {tau}");
        // AR(1) with phi = 0.9: tau = (1 + phi) / (1 - phi) = 19.
        let mut x = 0.0;
        let ar: Vec<f64> = (0..100_000)
            .map(|_| {
                x = 0.9 * x + rng.normal();
                x
            })
            .collect();
        let tau = correlation_time(&ar);
        assert!((tau - 19.0).abs() < 4.0, "AR(1): {tau}");
    }

    #[test]
    fn error_stats() {
        let s = ErrorStats::of([1.0, -3.0, 2.0], 2.0, "x");
        assert_eq!((s.n, s.max, s.min), (3, 4.0, -6.0));
        assert!((s.mean - 0.0).abs() < 1e-12);
        assert!((s.mean_abs - 4.0).abs() < 1e-12);
        assert!((s.rmse - (56.0f64 / 3.0).sqrt()).abs() < 1e-12);
        assert_eq!(s.max_abs(), 6.0);
    }

    #[test]
    fn logs_are_assigned_to_procedures() {
        let v = |a: &[&str]| a.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        let a = assign(&v(&["a", "b", "c"]), Procedure::All).unwrap();
        assert_eq!(
            a.iter().map(|(p, _)| *p).collect::<Vec<_>>(),
            vec![Procedure::Bm, Procedure::Jae, Procedure::Tension]
        );
        let a = assign(&v(&["tension=t.csv", "bm=b.csv"]), Procedure::All).unwrap();
        assert_eq!(a[0], (Procedure::Tension, PathBuf::from("t.csv")));
        assert!(assign(&v(&["a", "b"]), Procedure::All).is_err());
        assert!(assign(&v(&["jae=j.csv"]), Procedure::Bm).is_err());
        let a = assign(&v(&["x.csv", "y.csv"]), Procedure::Jae).unwrap();
        assert!(a.iter().all(|(p, _)| *p == Procedure::Jae));
    }
}
