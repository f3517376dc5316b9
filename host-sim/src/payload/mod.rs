//! `host-sim payload`: tool payload identification and tool-end wrench
//! estimation (seed 001) on the measured KUKA wrist data set
//! (`tests/data/kuka-wrist`, CC BY 4.0).
//!
//! ```text
//! host-sim payload --dir host-sim/tests/data/kuka-wrist --fit 1-baseline \
//!     --validate 2-vibrations,3-vibrations-contact [--json OUT] [--plot DIR] [--csv DIR]
//! ```
//!
//! What it does, in order:
//!
//! 1. **Conventions from the static calibration file** (`0-calibration_fts-
//!    accel.csv`: wrench, accelerometer, gravity in the sensor frame and
//!    `r11..r33` for 24 poses): which of `R^T g_w` or `R g_w` (and which sign
//!    of the world's vertical) reproduces the file's gravity vectors
//!    ([`check_convention`]); an affine calibration of the accelerometer into
//!    the sensor frame, `g - a = K a_raw + c` ([`fit_accel_calibration`]);
//!    the payload identified from the 24 static poses alone, as a cross-check
//!    of the mass ([`static_identification`]).
//! 2. **Alignment** of the accelerometer (≈254 Hz) and orientation (100 Hz)
//!    streams onto the wrench time base (≈698 Hz) by linear interpolation,
//!    with the IMU lag as a parameter (`--accel-lag-ms`) or estimated by a grid
//!    search on the fit run's residual ([`estimate_accel_lag`]).
//! 3. **Identification** on the fit run ([`cable_joint::payload::PayloadIdentifier`],
//!    6 weighted rows per wrench sample; weights `1 / noise std` from
//!    `0-steady-state_wrench.csv`).
//! 4. **Validation**: the f32 estimator of the core
//!    ([`cable_joint::payload::PayloadModel`]) on every run; with no contact
//!    the estimate is the error. RMSE per axis of: the raw sensor minus its
//!    mean over the first `--tare-s` ("raw"), the identified model with the
//!    fit run's `F_0` ("ident"), the same with `F_0` re-zeroed by the
//!    [`cable_joint::payload::OffsetTracker`] during the first `--tare-s`
//!    (known no contact, "ident+tare"), and with the creep/drift terms chosen
//!    by validation error ("comp+tare").
//! 5. The contact run's estimated contact wrench; `--plot DIR` writes
//!    `payload_<run>.svg` and `.png` for every run, `--csv DIR` the samples.
//!
//! Method, results and the commands that reproduce them: `docs/payload.md`.
//!
//! Bad input files fail with one error naming the file, the line and the
//! column.
//!
//! # Where things are
//!
//! The options and [`analyse`] (here), reading the data set (`load.rs`), the
//! conventions from the static poses (`calib.rs`), the kinematics at the
//! wrench samples (`kinematics.rs`), the identification (`ident.rs`), the
//! estimator over a run and the error measures (`estimate.rs`), the report's
//! types (`report.rs`) and the `--csv` and `--plot` files (`write.rs`). The
//! command line and the printed report are [`crate::cli::payload`].

mod calib;
mod estimate;
mod ident;
mod kinematics;
mod load;
mod report;
mod write;

pub use calib::{
    check_convention, fit_accel_calibration, static_identification, AccelCalibration, Convention,
};
pub use estimate::{affine_residual, estimate, raw_minus_start, rms, weighted_score, Estimate};
pub use ident::{estimate_accel_lag, fit_affine_map, identify, identify_comp, MAX_PCT_SIGMA};
pub use kinematics::{angular_rates, filtered_run, kinematics, lowpass, KinOptions};
pub use load::{
    load_run, load_static_poses, steady_state_noise, Run, StaticPoses, Stream, ACCEL_COLS,
    ORIENT_COLS, WRENCH_COLS,
};
pub use report::{CandidateReport, ParamReport, Report, RunEstimates, RunReport};
pub use write::{plot_runs, write_csv};

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use cable_joint::payload::{CompConfig, IdentConfig, Kinematics, PayloadModel};
use nalgebra::Vector3;
use serde::Serialize;

use report::{axes_text, param_table};

/// What [`analyse`] reads and how (the defaults are those of
/// `host-sim payload`, whose arguments are [`crate::cli::payload::PayloadArgs`]).
#[derive(Clone, Debug, PartialEq)]
pub struct PayloadOptions {
    /// Directory of the data set (`<run>_wrench.csv`, `<run>_accel.csv`,
    /// `<run>_orientations.csv`, `0-calibration_fts-accel.csv`,
    /// `0-steady-state_wrench.csv`).
    pub dir: PathBuf,
    /// Run to identify on (no contact).
    pub fit: String,
    /// Runs to validate on. A run whose name contains "contact" is treated
    /// as having contact (no error statistics).
    pub validate: Vec<String>,
    /// Source of `g - a`.
    pub gravity: GravitySource,
    /// Lag of the IMU stream behind the wrench stream, ms (`None`: estimated
    /// on the fit run with [`GravitySource::Accel`], 0 with
    /// [`GravitySource::Orient`]).
    pub accel_lag_ms: Option<f64>,
    /// Low-pass cut-off applied identically to the wrench and to the
    /// kinematics (two cascaded first-order sections of the core's
    /// `LowPass1`, causal), Hz; 0 = unfiltered.
    pub lowpass_hz: f64,
    /// Include the rotational terms (angular velocity and acceleration from
    /// differentiated orientations).
    pub rotational: bool,
    /// Also identify the six inertia entries (meaningful with
    /// [`Self::rotational`]).
    pub inertia: bool,
    /// Candidate creep time constants, s, for the compensation selection.
    pub creep_taus: Vec<f32>,
    /// Known no-contact window at the start of each run, s (offset tracker).
    pub tare_s: f64,
}

impl Default for PayloadOptions {
    fn default() -> Self {
        Self {
            dir: PathBuf::from("host-sim/tests/data/kuka-wrist"),
            fit: "1-baseline".to_owned(),
            validate: vec!["2-vibrations".to_owned(), "3-vibrations-contact".to_owned()],
            gravity: GravitySource::Accel,
            accel_lag_ms: None,
            lowpass_hz: 10.0,
            rotational: false,
            inertia: false,
            creep_taus: vec![0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0],
            tare_s: 0.25,
        }
    }
}

impl PayloadOptions {
    /// The checks [`analyse`] makes before it reads anything.
    ///
    /// # Errors
    /// `tare_s` negative or NaN, `lowpass_hz` negative or not finite, a
    /// creep time constant not positive and finite.
    pub fn check(&self) -> Result<()> {
        if self.tare_s.is_nan() || self.tare_s < 0.0 {
            bail!("--tare-s must be non-negative");
        }
        if !(self.lowpass_hz >= 0.0 && self.lowpass_hz.is_finite()) {
            bail!("--lowpass-hz must be finite and non-negative");
        }
        if self.creep_taus.iter().any(|t| !(*t > 0.0 && t.is_finite())) {
            bail!("--creep-taus must be positive");
        }
        Ok(())
    }
}

/// Where `g - a` comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum GravitySource {
    /// Accelerometer (specific force), calibrated into the sensor frame.
    Accel,
    /// Orientation matrices: gravity only.
    Orient,
}

fn is_contact(name: &str) -> bool {
    name.contains("contact")
}

fn ident_config(inertia: bool, weight: [f64; 6], comp: CompConfig) -> IdentConfig {
    IdentConfig {
        inertia,
        comp,
        axis_weight: weight,
        ..IdentConfig::default()
    }
}

/// Run the whole analysis (no output files).
///
/// # Errors
/// The options fail [`PayloadOptions::check`]; a file is missing or bad; a
/// fit or an estimate fails.
pub fn analyse(opts: &PayloadOptions) -> Result<(Report, Vec<RunEstimates>)> {
    opts.check()?;
    let dir = &opts.dir;
    let poses = load_static_poses(&dir.join("0-calibration_fts-accel.csv"))?;
    let noise = steady_state_noise(&dir.join("0-steady-state_wrench.csv"))?;
    if noise.iter().any(|s| s.is_nan() || *s <= 0.0) {
        bail!("0-steady-state_wrench.csv: an axis has zero noise; cannot weight");
    }
    let weight = noise.map(|s| 1.0 / s);
    let conv = check_convention(&poses)?;
    let cal = fit_accel_calibration(&poses)?;
    let stat = static_identification(&poses, weight)?;
    let static_cfg = IdentConfig {
        inertia: false,
        axis_weight: weight,
        ..IdentConfig::default()
    };

    let fit_run = load_run(dir, &opts.fit).with_context(|| format!("loading run {}", opts.fit))?;
    if is_contact(&fit_run.name) {
        bail!(
            "fit run {} has contact; identify on a no-contact run",
            fit_run.name
        );
    }
    let mut val_runs = Vec::new();
    for v in &opts.validate {
        val_runs.push(load_run(dir, v).with_context(|| format!("loading run {v}"))?);
    }

    let (lag_s, lag_curve) = match (opts.accel_lag_ms, opts.gravity) {
        (Some(ms), _) => (ms * 1e-3, Vec::new()),
        (None, GravitySource::Orient) => (0.0, Vec::new()),
        (None, GravitySource::Accel) => {
            let grid: Vec<f64> = (-20..=60).map(|k| f64::from(k) * 0.5e-3).collect();
            let (l, c) = estimate_accel_lag(&fit_run, &conv, &cal, weight, &grid)?;
            (l, c.into_iter().map(|(l, r)| (l * 1e3, r)).collect())
        }
    };
    let kin_opts = KinOptions {
        gravity: opts.gravity,
        accel_lag_s: lag_s,
        rotational: opts.rotational,
        lowpass_hz: (opts.lowpass_hz > 0.0).then_some(opts.lowpass_hz),
    };
    // The lag is estimated on the unfiltered data (the vibration carries the
    // timing); everything from here on sees the filtered wrench.
    let fit_run = filtered_run(&fit_run, &kin_opts);
    let val_runs: Vec<Run> = val_runs
        .iter()
        .map(|r| filtered_run(r, &kin_opts))
        .collect();
    let fit_kin = kinematics(&fit_run, &kin_opts, &conv, &cal);
    let val_kin: Vec<Vec<Kinematics<f64>>> = val_runs
        .iter()
        .map(|r| kinematics(r, &kin_opts, &conv, &cal))
        .collect();

    // Base model.
    let base_cfg = ident_config(opts.inertia, weight, CompConfig::NONE);
    let (base_fit, ident_time_s) = identify(&fit_run, &fit_kin, base_cfg)?;

    // Rotational magnitude on the fit run (always from the orientation).
    let (wst, ast) = angular_rates(&fit_run.orient, conv.transpose);
    let max_w = wst
        .v
        .iter()
        .map(|v| Vector3::from(*v).norm())
        .fold(0.0, f64::max);
    let max_a = ast
        .v
        .iter()
        .map(|v| Vector3::from(*v).norm())
        .fold(0.0, f64::max);
    let mc = Vector3::new(
        base_fit.params.inertial[1],
        base_fit.params.inertial[2],
        base_fit.params.inertial[3],
    );
    let (mut sf, mut st) = (0.0, 0.0);
    for &t in &fit_run.wrench.t_s {
        let w = Vector3::from(wst.at(t));
        let a = Vector3::from(ast.at(t));
        sf += (a.cross(&mc) + w.cross(&w.cross(&mc))).norm_squared();
        let i_bound = base_fit.params.mass_kg().abs() * 0.01;
        st += (i_bound * (a.norm() + w.norm_squared())).powi(2);
    }
    let nf = fit_run.wrench.len() as f64;

    // Creep/drift candidates.
    let mut comps = vec![CompConfig::NONE, CompConfig::all_axes(None, true)];
    for &tau in &opts.creep_taus {
        for drift in [false, true] {
            comps.push(CompConfig::all_axes(Some(tau), drift));
        }
    }
    let nc_val: Vec<usize> = (0..val_runs.len())
        .filter(|&i| !is_contact(&val_runs[i].name))
        .collect();
    let mut candidates = Vec::new();
    let mut models = Vec::new();
    for comp in comps {
        let (fit, cfg) = if comp.n_cols() == 0 {
            (base_fit.clone(), base_cfg)
        } else {
            identify_comp(
                &fit_run,
                &fit_kin,
                ident_config(opts.inertia, weight, comp),
                &base_fit,
            )?
        };
        let model = PayloadModel::new(&fit.params, cfg.comp)?;
        let e_fit = estimate(&fit_run, &fit_kin, &model, opts.tare_s)?;
        let fit_score = weighted_score(&rms(&e_fit.tracked), &noise);
        let mut pooled = Vec::new();
        for &i in &nc_val {
            pooled.extend(estimate(&val_runs[i], &val_kin[i], &model, opts.tare_s)?.tracked);
        }
        let vr = rms(&pooled);
        let validation_score = if pooled.is_empty() {
            fit_score
        } else {
            weighted_score(&vr, &noise)
        };
        candidates.push(CandidateReport {
            creep_tau_s: comp.creep_tau_s,
            drift: comp.drift_axes.iter().any(|d| *d),
            creep_axes: axes_text(&cfg.comp.creep_axes, cfg.comp.creep_tau_s.is_some()),
            drift_axes: axes_text(&cfg.comp.drift_axes, true),
            fit_score,
            validation_score,
            validation_rmse: vr,
        });
        models.push((fit, model, cfg));
    }
    let selected = candidates
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.validation_score.total_cmp(&b.1.validation_score))
        .map(|c| c.0)
        .unwrap_or(0);
    let (sel_fit, sel_model, sel_cfg) = &models[selected];
    let base_model = PayloadModel::new(&base_fit.params, CompConfig::NONE)?;
    let affine = fit_affine_map(&fit_run, &fit_kin)?;

    let mut runs = Vec::new();
    let mut estimates = Vec::new();
    let mut contact_intervals = Vec::new();
    let all: Vec<(&Run, &Vec<Kinematics<f64>>)> = std::iter::once((&fit_run, &fit_kin))
        .chain(val_runs.iter().zip(val_kin.iter()))
        .collect();
    for (run, kin) in all {
        let base = estimate(run, kin, &base_model, opts.tare_s)?;
        let sel = estimate(run, kin, sel_model, opts.tare_s)?;
        let peak =
            std::array::from_fn(|k| sel.tracked.iter().map(|r| r[k].abs()).fold(0.0, f64::max));
        runs.push(RunReport {
            name: run.name.clone(),
            contact: is_contact(&run.name),
            samples: run.wrench.len(),
            raw: rms(&raw_minus_start(run, opts.tare_s)),
            ident: rms(&base.raw_model),
            ident_tare: rms(&base.tracked),
            comp_tare: rms(&sel.tracked),
            affine_tare: rms(&affine_residual(run, kin, &affine, opts.tare_s)),
            tare_correction: base
                .raw_model
                .last()
                .zip(base.tracked.last())
                .map(|(a, b)| std::array::from_fn(|k| a[k] - b[k]))
                .unwrap_or([0.0; 6]),
            peak,
        });
        if is_contact(&run.name) {
            let hits: Vec<f64> = sel
                .tracked
                .iter()
                .zip(&run.wrench.t_s)
                .filter(|(r, _)| Vector3::new(r[0], r[1], r[2]).norm() > 1.5)
                .map(|(_, t)| *t)
                .collect();
            if let (Some(a), Some(b)) = (hits.first(), hits.last()) {
                contact_intervals.push((run.name.clone(), *a, *b));
            }
        }
        estimates.push(RunEstimates {
            run: run.clone(),
            raw: raw_minus_start(run, opts.tare_s),
            base,
            selected: sel,
        });
    }

    let report = Report {
        convention: conv,
        accel_calibration: cal,
        noise_std: noise,
        static_params: param_table(&stat, &static_cfg),
        gravity: opts.gravity,
        accel_lag_ms: lag_s * 1e3,
        lag_curve,
        rotational: opts.rotational,
        lowpass_hz: opts.lowpass_hz,
        max_omega_rad_s: max_w,
        max_alpha_rad_s2: max_a,
        rot_force_rms_n: (sf / nf).sqrt(),
        rot_torque_bound_nm: (st / nf).sqrt(),
        fit_run: fit_run.name.clone(),
        fit_samples: base_fit.samples,
        fit_duration_s: fit_run.wrench.t_s.last().copied().unwrap_or(0.0),
        ident_time_s,
        condition: base_fit.lsq.condition,
        params: param_table(&base_fit, &base_cfg),
        candidates,
        selected,
        selected_params: param_table(sel_fit, sel_cfg),
        runs,
        contact_intervals,
    };
    Ok((report, estimates))
}
