//! The residual loop: fit a model, rank candidate effects by how much of the
//! residual each explains, add them one at a time while the error on
//! validation data falls, and write the result where the firmware runs it.
//!
//! ```text
//! host-sim residual --log FILE... [--model jae|tension|force | --target COL [--inputs COL,...]]
//!                   [--validate FILE...] [--json OUT] [--plots DIR]
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

pub mod problem;
pub mod report;
pub mod select;

use std::path::PathBuf;

use anyhow::{bail, ensure, Context, Result};
use cable_joint::model::{AddedTerms, MAX_TERMS};
use cable_joint::Config;

use crate::cli;
use crate::output::Outputs;

pub use problem::{
    build, is_reference, load_log, BuildOptions, ModelKind, MrdlabZero, NamedLog, REFERENCE_COLUMNS,
};
pub use select::{select, Outcome, Problem, SelectOptions};

/// Model choice on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ModelArg {
    /// Joint-angle estimator, target `theta_rad`.
    Jae,
    /// No-load tension model, target `tension1_hat_n`.
    Tension,
    /// External force on top of the DOB, target `f_ext_n`.
    Force,
}

/// Arguments of `host-sim residual`.
#[derive(clap::Args, Debug, Clone)]
pub struct ResidualArgs {
    /// Logs to fit (project CSV, or MRDLab .TXT/.TXT.gz).
    #[arg(long = "log", required = true, num_args = 1..)]
    pub logs: Vec<PathBuf>,
    /// Model to fit.
    #[arg(long, value_enum, conflicts_with_all = ["target", "inputs"])]
    pub model: Option<ModelArg>,
    /// Target column of a generic fit.
    #[arg(long)]
    pub target: Option<String>,
    /// Input columns of a generic fit (default: every non-reference column).
    #[arg(long, value_delimiter = ',', requires = "target")]
    pub inputs: Option<Vec<String>>,
    /// Logs to judge on (default: the last --holdout share of each --log).
    #[arg(long = "validate", num_args = 1..)]
    pub validate: Vec<PathBuf>,
    /// Share of each fitting log held out when no --validate is given.
    #[arg(long, default_value_t = 0.3, value_parser = cli::f64_in(0.0, 0.95))]
    pub holdout: f64,
    /// Write the result as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write plots (SVG and PNG) into this directory.
    #[arg(long)]
    pub plots: Option<PathBuf>,
    /// Configuration (TOML; default: the datasheet values).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Write the configuration with the fitted model (jae, tension, force).
    #[arg(long = "config-out")]
    pub config_out: Option<PathBuf>,
    /// Most effects added.
    #[arg(long, default_value_t = MAX_TERMS, value_parser = cli::usize_in(0, MAX_TERMS))]
    pub max_terms: usize,
    /// Smallest relative cut of the validation RMSE that keeps an effect.
    #[arg(long, default_value_t = 0.01, value_parser = cli::f64_in(0.0, 1.0))]
    pub min_gain: f64,
    /// Candidates set aside in a row before the selection stops.
    #[arg(long, default_value_t = 20, value_parser = cli::usize_in(0, 100_000))]
    pub patience: usize,
    /// Fit on every N-th row (default: enough to keep about 30 000 fitting rows).
    #[arg(long, value_parser = cli::usize_in(1, 1_000_000))]
    pub decimate: Option<usize>,
    /// Use only the first SECONDS of every log.
    #[arg(long = "t-max", value_parser = cli::f64_above(0.0, 1e6))]
    pub t_max_s: Option<f64>,
    /// Leave the first SECONDS of every log out of fitting and validation
    /// (the terms still run from the first sample).
    #[arg(long = "settle", default_value_t = 0.0, value_parser = cli::f64_in(0.0, 1e6))]
    pub settle_s: f64,
    /// jae/tension: keep the terms already in the configuration's `added`
    /// (refitted with the baseline) and add new ones after them.
    #[arg(long = "keep-added")]
    pub keep_added: bool,
    /// MRDLab runs: keep the importer's per-run zero of the angles (each
    /// run's first sample) instead of the encoders' common zero.
    #[arg(long = "mrdlab-first-zero")]
    pub mrdlab_first_zero: bool,
    /// jae/tension/force: also offer terms that read sensors the model does
    /// not (for the JAE the motor encoder and grating 1). Such a term is
    /// sensor fusion, not a physical effect, and is labelled `fusion`.
    #[arg(long = "other-sensors")]
    pub other_sensors: bool,
}

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
    let mut out = crate::log::Log::new();
    for name in log.names() {
        let col = log.col_opt(name).unwrap_or_default();
        out.set_col_opt(name, &col[..n])?;
    }
    Ok(out)
}

/// Read logs (see [`load_log`]), optionally truncated.
pub fn read_logs(
    paths: &[PathBuf],
    project: bool,
    zero: MrdlabZero,
    t_max_s: Option<f64>,
) -> Result<Vec<NamedLog>> {
    paths
        .iter()
        .map(|p| {
            let mut log = load_log(p, project, zero)?;
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

/// Run the whole loop on logs already read. `options.decimate == 0` means
/// automatic ([`AUTO_FIT_ROWS`]).
pub fn analyse(
    kind: ModelKind,
    fit: &[NamedLog],
    validate: &[NamedLog],
    config: &Config,
    build_opts: BuildOptions,
    mut options: SelectOptions,
) -> Result<Analysis> {
    ensure!(
        options.max_terms <= MAX_TERMS,
        "at most {MAX_TERMS} effects (the core's capacity), got {}",
        options.max_terms
    );
    let (problem, _) = build(&kind, fit, validate, config, build_opts)?;
    // The core holds MAX_TERMS run-time terms per estimator.
    let used = match kind {
        ModelKind::Force => config.tension.added.len as usize,
        _ => problem.kept.len(),
    };
    options.max_terms = options.max_terms.min(MAX_TERMS.saturating_sub(used));
    if options.decimate == 0 {
        let rows: usize = problem.runs.iter().map(|r| r.fit_rows.len()).sum();
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

/// Run the subcommand.
pub fn run(args: ResidualArgs) -> Result<()> {
    let kind = match (&args.model, &args.target) {
        (Some(ModelArg::Jae), _) => ModelKind::Jae,
        (Some(ModelArg::Tension), _) => ModelKind::Tension,
        (Some(ModelArg::Force), _) => ModelKind::Force,
        (None, Some(t)) => ModelKind::Generic {
            target: t.clone(),
            inputs: args.inputs.clone(),
        },
        (None, None) => bail!("give --model jae|tension|force or --target COLUMN"),
    };
    if args.config_out.is_some() && matches!(kind, ModelKind::Generic { .. }) {
        bail!("--config-out needs --model jae, tension or force");
    }
    let config = match &args.config {
        Some(p) => crate::io::config::load_config(p)?,
        None => Config::default(),
    };
    let project = !matches!(kind, ModelKind::Generic { .. });
    let zero = if args.mrdlab_first_zero {
        MrdlabZero::FirstSample
    } else {
        MrdlabZero::Encoder
    };
    let fit = read_logs(&args.logs, project, zero, args.t_max_s)?;
    let validate = read_logs(&args.validate, project, zero, args.t_max_s)?;
    let options = SelectOptions {
        max_terms: args.max_terms,
        min_gain: args.min_gain,
        patience: args.patience,
        decimate: args.decimate.unwrap_or(0),
        ..SelectOptions::default()
    };
    let build_opts = BuildOptions {
        holdout: args.holdout,
        keep_added: args.keep_added,
        settle_s: args.settle_s,
        other_sensors: args.other_sensors,
        holdout_with_validate: false,
    };
    let a = analyse(kind, &fit, &validate, &config, build_opts, options)?;
    print!("{}", report::table(&a));
    // Every output is staged first and written only if all of them can be:
    // a failure leaves every existing file as it was.
    let mut out = Outputs::new();
    if let Some(path) = &args.config_out {
        let cfg = config_with(&a, &config)?;
        crate::io::config::stage_config(&mut out, path, &cfg)?;
    }
    if let Some(path) = &args.json {
        let mut v = report::json(&a);
        if let Some(c) = &args.config_out {
            v["config_out"] = serde_json::Value::String(c.display().to_string());
        }
        let text = serde_json::to_string_pretty(&v)?;
        out.bytes(path, text.as_bytes())?;
    }
    if let Some(dir) = &args.plots {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        report::stage_plots(&mut out, &a, dir)?;
    }
    let written: Vec<String> = out
        .commit()?
        .iter()
        .map(|p| p.display().to_string())
        .collect();
    if !written.is_empty() {
        println!("wrote {}", written.join(", "));
    }
    Ok(())
}
