//! The residual loop: fit a model, rank candidate effects by how much of the
//! residual each explains, add them one at a time while the error on
//! validation data falls, and write the result where the firmware runs it.
//!
//! ```text
//! host-sim residual --log FILE... [--model jae|tension|force | --target COL [--inputs COL,...]]
//!                   [--validate FILE...] [--test FILE...] [--json OUT] [--plots DIR]
//!                   [--config CFG] [--config-out OUT.toml]
//! ```
//!
//! * Fitting logs (`--log`, one or more runs) and validation logs
//!   (`--validate`); without validation logs the last `--holdout` share of
//!   each fitting log is held out. Project CSV logs and MRDLab raw runs
//!   (`.TXT`, `.TXT.gz`, imported on the fly) are accepted.
//! * Models ([`problem`]): `jae`, `tension`, `force`, or a generic
//!   `--target`/`--inputs` fit. Reference columns (`theta_rad`, `f_ext_n`,
//!   `tau_ext_nm`, `tau_in_nm`, simulator truth) are inputs only when named.
//! * Selection ([`mod@select`]): forward regression by error reduction ratio,
//!   stopped by the validation error (never by the training error).
//! * Output: a table (baseline, each added effect with its meaning,
//!   parameters and validation error, the final error, residual diagnostics
//!   before and after), `--json` with the same content (keys `before_rmse`,
//!   `after_rmse`, `effects`, ...), `--plots` (residual over time and against
//!   each effect's signal, SVG and PNG), and for `jae`/`tension`/`force`
//!   `--config-out`: the configuration with the fitted coefficients and the
//!   selected terms in `added` (at most [`MAX_TERMS`]), which the core's
//!   estimators evaluate at run time.

mod candidates;
pub mod families;
mod generic;
pub mod library;
pub mod outcome;
pub mod problem;
pub mod programme;
pub mod report;
mod search;
pub mod select;
mod split;

use std::path::PathBuf;

use anyhow::{bail, ensure, Context, Result};
use cable_joint::model::{AddedTerms, MAX_TERMS};
use cable_joint::Config;

use crate::import::MrdlabZero;

pub use outcome::Outcome;
pub use problem::{
    build, build_tested, is_reference, load_log, BuildOptions, ModelKind, NamedLog,
    REFERENCE_COLUMNS,
};
pub use select::{select, Problem, SelectOptions};

/// Fitting rows the automatic decimation aims at.
pub const AUTO_FIT_ROWS: usize = 30_000;

/// A finished analysis: what was fitted and what was found.
#[derive(Clone, Debug)]
pub struct Analysis {
    /// The model.
    pub kind: ModelKind,
    /// The problem (runs, candidates).
    pub problem: Problem,
    /// The selection's result.
    pub outcome: Outcome,
    /// Options used (with the decimation resolved).
    pub options: SelectOptions,
    /// Fitting log names.
    pub fit_logs: Vec<String>,
    /// Validation log names (empty: held-out part).
    pub validate_logs: Vec<String>,
    /// Test log names (`--test`: judged once by the chosen model).
    pub test_logs: Vec<String>,
    /// Share held out when no validation log was given.
    pub holdout: Option<f64>,
    /// How the problem was built.
    pub build: BuildOptions,
}

/// Keep only the rows with `t_s <= t_max_s`.
pub fn truncate(log: &crate::log::Log, t_max_s: f64) -> Result<crate::log::Log> {
    let t = log.time_s()?;
    let n = t.partition_point(|v| *v <= t_max_s);
    ensure!(n >= 10, "fewer than 10 rows before t = {t_max_s} s");
    Ok(log.rows(0..n))
}

/// Read logs (see [`load_log`]), optionally truncated (after the tick
/// column is rebuilt, so the ticks count from the log's first row).
pub fn read_logs(
    paths: &[PathBuf],
    project: bool,
    zero: MrdlabZero,
    t_max_s: Option<f64>,
    ticks_per_row: Option<u32>,
) -> Result<Vec<NamedLog>> {
    paths
        .iter()
        .map(|p| {
            let mut log = load_log(p, project, zero, ticks_per_row)?;
            if let Some(t) = t_max_s {
                log = truncate(&log, t).with_context(|| p.display().to_string())?;
            }
            Ok(NamedLog {
                name: p
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_else(|| p.display().to_string()),
                log,
            })
        })
        .collect()
}

/// Most effects a generic fit (`--target`) adds. It writes no
/// configuration, so the estimators' [`MAX_TERMS`] does not bind it; its
/// terms are the core's and run on the MCU in an
/// [`EffectBank`](cable_joint::effects::EffectBank) of this size. With a
/// baseline of a few inputs it stays within [`select::MAX_COLUMNS`].
pub const GENERIC_MAX_TERMS: usize = 24;

/// Run the whole loop on logs already read. `options.decimate == 0` means
/// automatic ([`AUTO_FIT_ROWS`]).
pub fn analyse(
    kind: ModelKind,
    fit: &[NamedLog],
    validate: &[NamedLog],
    config: &Config,
    build_opts: BuildOptions,
    options: SelectOptions,
) -> Result<Analysis> {
    analyse_tested(kind, fit, validate, &[], config, build_opts, options)
}

/// [`analyse`] with test logs: replayed like the validation logs, never
/// fitted and never used to choose a term, judged once by the model the
/// selection chose ([`Outcome::test_runs`]).
/// The validation error decides what is kept, so it is a selected
/// figure; the test logs' is not.
pub fn analyse_tested(
    kind: ModelKind,
    fit: &[NamedLog],
    validate: &[NamedLog],
    test: &[NamedLog],
    config: &Config,
    build_opts: BuildOptions,
    mut options: SelectOptions,
) -> Result<Analysis> {
    let (cap, why) = kind.max_terms();
    ensure!(
        options.max_terms <= cap,
        "at most {cap} effects ({why}), got {}",
        options.max_terms
    );
    let (problem, _) = build_tested(&kind, fit, validate, test, config, build_opts)?;
    // The limit counts the terms the model already keeps.
    let used = match kind {
        ModelKind::Force => config.tension.added.len as usize,
        _ => problem.kept.len(),
    };
    options.max_terms = options.max_terms.min(cap.saturating_sub(used));
    if options.decimate == 0 {
        let rows: usize = problem
            .runs
            .iter()
            .map(|r| r.fit_rows.clone().filter(|&k| r.measured(k)).count())
            .sum();
        options.decimate = rows.div_ceil(AUTO_FIT_ROWS).max(1);
    }
    let outcome = select(&problem, &options)?;
    Ok(Analysis {
        kind,
        problem,
        outcome,
        options,
        fit_logs: fit.iter().map(|l| l.name.clone()).collect(),
        validate_logs: validate.iter().map(|l| l.name.clone()).collect(),
        test_logs: test.iter().map(|l| l.name.clone()).collect(),
        holdout: (validate.is_empty() || build_opts.holdout_with_validate)
            .then_some(build_opts.holdout),
        build: build_opts,
    })
}

/// The configuration `base` with the analysis' model written in: for `jae`
/// the Eq. 26 coefficients, the offset and `jae.added`; for `tension` model
/// C's coefficients and `tension.added`; for `force` the selected terms
/// appended to `tension.added` (coefficient `-c l_e / r`: a term `c w` added
/// to the force estimate is `-c w l_e / r` in the no-load tension).
pub fn config_with(a: &Analysis, base: &Config) -> Result<Config> {
    let mut cfg = *base;
    let b = a.outcome.baseline_coefs();
    // Kept terms (the baseline's last columns) first, then the new ones.
    let nk = a.problem.kept.len();
    let mut effects: Vec<(cable_joint::effects::Term, f64)> = a
        .problem
        .kept
        .iter()
        .zip(&b[b.len() - nk..])
        .map(|(t, c)| (*t, *c))
        .collect();
    effects.extend(a.outcome.effect_coefs());
    let added = |start: AddedTerms, scale: f64| -> Result<AddedTerms> {
        let mut t = start;
        for (term, c) in &effects {
            if !t.push(*term, (c * scale) as f32) {
                bail!("more than {MAX_TERMS} run-time terms");
            }
        }
        Ok(t)
    };
    match a.kind {
        ModelKind::Jae => {
            let j = &mut cfg.jae;
            j.c_acc_rad_s2_m = b[0] as f32;
            j.c_vel_rad_s_m = b[1] as f32;
            j.c_sign_rad = b[2] as f32;
            j.c_pos_rad_m = b[3] as f32;
            j.offset_rad = b[4] as f32;
            j.added = added(AddedTerms::default(), 1.0)?;
        }
        ModelKind::Tension => {
            let t = &mut cfg.tension;
            t.f_sc1_n = b[0] as f32;
            t.f_cp2_n = b[1] as f32;
            t.k_s_n_m = b[2] as f32;
            t.f_0_n = b[3] as f32;
            t.added = added(AddedTerms::default(), 1.0)?;
        }
        ModelKind::Force => {
            let m = &cfg.machine;
            let scale = -f64::from(m.gripper_length_m) / f64::from(m.pulley_radius_m);
            cfg.tension.added = added(cfg.tension.added, scale)?;
        }
        ModelKind::Generic { .. } => {
            bail!("--config-out needs --model jae, tension or force (a generic fit does not map onto the core)")
        }
    }
    cfg.validate()
        .map_err(|e| anyhow::anyhow!("the fitted configuration is invalid: {e}"))?;
    Ok(cfg)
}
