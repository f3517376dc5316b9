//! Tool payload identification and tool-end wrench estimation (seed 001) on
//! the measured KUKA wrist data set (`tests/data/kuka-wrist`, CC BY 4.0):
//! [`analyse`] with [`PayloadOptions`], behind `host-sim payload` (the
//! command-line flags below are the options' names).
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
//! The options (here), [`analyse`] step by step (`analysis.rs`), reading the
//! data set (`load.rs`), the conventions from the static poses (`calib.rs`),
//! the kinematics at the wrench samples (`kinematics.rs`), the
//! identification (`ident.rs`), the estimator over a run and the error
//! measures (`estimate.rs`), the report's types (`report.rs`) and the
//! `--csv` and `--plot` files (`write.rs`). The command line and the printed
//! report are [`crate::cli::payload`].

mod analysis;
mod calib;
mod estimate;
mod ident;
mod kinematics;
mod load;
mod report;
mod write;

pub use analysis::analyse;
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

use anyhow::{bail, Result};
use serde::Serialize;

/// Largest `--tare-s` and `--creep-taus`, s.
pub const MAX_WINDOW_S: f64 = 1e4;
/// Largest `--lowpass-hz`, Hz.
pub const MAX_LOWPASS_HZ: f64 = 1000.0;
/// Largest `|--accel-lag-ms|`, ms.
pub const MAX_ACCEL_LAG_MS: f64 = 1000.0;

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
    /// creep time constant not positive and finite, a validation run that
    /// is empty or the fit run.
    pub fn check(&self) -> Result<()> {
        // The same ranges the command line's parsers enforce, so that a
        // library caller cannot pass what the command refuses.
        let within = |v: f64, lo: f64, hi: f64| v.is_finite() && (lo..=hi).contains(&v);
        if !within(self.tare_s, 0.0, MAX_WINDOW_S) {
            bail!(
                "--tare-s must be in [0, {MAX_WINDOW_S:e}] s, got {}",
                self.tare_s
            );
        }
        if !within(self.lowpass_hz, 0.0, MAX_LOWPASS_HZ) {
            bail!(
                "--lowpass-hz must be in [0, {MAX_LOWPASS_HZ}] Hz, got {}",
                self.lowpass_hz
            );
        }
        if self
            .creep_taus
            .iter()
            .any(|t| !(*t > 0.0 && within(f64::from(*t), 0.0, MAX_WINDOW_S)))
        {
            bail!("--creep-taus must be positive and at most {MAX_WINDOW_S:e} s");
        }
        if let Some(lag) = self.accel_lag_ms {
            if !within(lag, -MAX_ACCEL_LAG_MS, MAX_ACCEL_LAG_MS) {
                bail!("--accel-lag-ms must be in [-{MAX_ACCEL_LAG_MS}, {MAX_ACCEL_LAG_MS}] ms, got {lag}");
            }
        }
        if self.inertia && !self.rotational {
            bail!("--inertia needs --rotational (the inertia multiplies the rotational terms)");
        }
        // Validation is on runs the identification did not see.
        if self.validate.iter().any(|v| v.trim().is_empty()) {
            bail!("--validate names an empty run (a doubled or trailing comma?)");
        }
        if let Some(v) = self.validate.iter().find(|v| v.trim() == self.fit.trim()) {
            bail!(
                "--validate names the fit run {v}: validation needs runs the identification \
                 did not see"
            );
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
