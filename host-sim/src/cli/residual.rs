//! `host-sim residual`: its arguments and its run (the analysis is
//! [`crate::residual`]).

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use cable_joint::Config;

use crate::cli;
use crate::import::MrdlabZero;
use crate::output::Outputs;
use crate::residual::{
    analyse_tested, config_with, read_logs, report, BuildOptions, ModelKind, NamedLog,
    SelectOptions, GENERIC_MAX_TERMS,
};

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
    /// Logs to test on: replayed like --validate, never fitted and never
    /// used to choose a term, judged once by the chosen model (the
    /// validation error decides what is kept, so it is a selected figure;
    /// this one is not).
    #[arg(long = "test", num_args = 1..)]
    pub test: Vec<PathBuf>,
    /// Share of each fitting log held out when no --validate is given.
    #[arg(allow_negative_numbers = true, long, default_value_t = 0.3, value_parser = cli::f64_in(0.0, 0.95))]
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
    /// Most effects added (default and limit: the core's capacity per
    /// estimator for jae, tension and force, 24 for a generic fit)
    #[arg(allow_negative_numbers = true, long, value_parser = cli::usize_in(0, GENERIC_MAX_TERMS))]
    pub max_terms: Option<usize>,
    /// Smallest relative cut of the validation RMSE that keeps an effect.
    #[arg(allow_negative_numbers = true, long, default_value_t = 0.01, value_parser = cli::f64_in(0.0, 1.0))]
    pub min_gain: f64,
    /// Candidates set aside in a row before the selection stops.
    #[arg(allow_negative_numbers = true, long, default_value_t = 20, value_parser = cli::usize_in(0, 100_000))]
    pub patience: usize,
    /// Fit on every N-th row (default: enough to keep about 30 000 fitting rows).
    #[arg(allow_negative_numbers = true, long, value_parser = cli::usize_in(1, 1_000_000))]
    pub decimate: Option<usize>,
    /// Use only the first SECONDS of every log.
    #[arg(allow_negative_numbers = true, long = "t-max", value_parser = cli::f64_above(0.0, 1e6))]
    pub t_max_s: Option<f64>,
    /// Leave the first SECONDS of every log out of fitting and validation
    /// (the terms still run from the first sample).
    #[arg(allow_negative_numbers = true, long = "settle", default_value_t = 0.0, value_parser = cli::f64_in(0.0, 1e6))]
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
    /// jae/tension/force: every log has a row every N control ticks but no
    /// `tick` column (a logger other than the firmware's link): the control
    /// period is the median time step over N (as `estimate --ticks-per-row`).
    #[arg(long, value_name = "N", requires = "model")]
    pub ticks_per_row: Option<u32>,
}

/// Run the subcommand.
pub fn run(args: ResidualArgs) -> Result<()> {
    if let Some(dir) = &args.plots {
        crate::output::check_dir_target(dir)?;
    }
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
    let project = !matches!(kind, ModelKind::Generic { .. });
    let zero = if args.mrdlab_first_zero {
        MrdlabZero::FirstSample
    } else {
        MrdlabZero::Encoder
    };
    super::refuse_reused_files(&args.logs, &args.validate, &args.test)?;
    let fit = read_logs(&args.logs, project, zero, args.t_max_s, args.ticks_per_row)?;
    let validate = read_logs(
        &args.validate,
        project,
        zero,
        args.t_max_s,
        args.ticks_per_row,
    )?;
    let test = read_logs(&args.test, project, zero, args.t_max_s, args.ticks_per_row)?;
    // The same run under two names (a copy, the `.gz` and its unpacked
    // file) passes the path checks above; its data do not.
    fn named(logs: &[NamedLog]) -> Vec<(&str, &crate::log::Log)> {
        logs.iter().map(|l| (l.name.as_str(), &l.log)).collect()
    }
    super::refuse_copies(&named(&fit), &named(&validate), &named(&test))?;
    // A project model's configuration at the logs' control rate (the
    // firmware ran at it), as `estimate` takes it.
    let config = match &args.config {
        Some(p) if project => {
            let all: Vec<_> = [&fit, &validate, &test]
                .into_iter()
                .flat_map(|l| named(l))
                .collect();
            let (config, notes) = crate::io::config::load_config_for_logs(p, &all)?;
            for n in notes {
                eprintln!("residual: {}: {n}", p.display());
            }
            config
        }
        Some(p) => crate::io::config::load_config(p)?,
        None => Config::default(),
    };
    if project {
        for l in fit.iter().chain(&validate).chain(&test) {
            crate::estimate::check_reference_force(&l.log, &config.machine)
                .with_context(|| l.name.clone())?;
        }
    }
    let options = SelectOptions {
        max_terms: args.max_terms.unwrap_or(kind.max_terms().0),
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
    let a = analyse_tested(kind, &fit, &validate, &test, &config, build_opts, options)?;
    crate::stdout!("{}", report::table(&a));
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
        crate::output::ensure_dir(dir)?;
        report::stage_plots(&mut out, &a, dir)?;
    }
    let written: Vec<String> = out
        .commit()?
        .iter()
        .map(|p| p.display().to_string())
        .collect();
    if !written.is_empty() {
        crate::stdoutln!("wrote {}", written.join(", "));
    }
    Ok(())
}
