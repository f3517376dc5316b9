//! `host-sim report` (the default command): its arguments and its run (the
//! programme is [`crate::report`]).

use std::path::PathBuf;

use anyhow::Result;

use crate::report::{generate, write, ReportOptions};

/// Arguments of `host-sim report`.
#[derive(clap::Args, Debug, Clone, PartialEq)]
pub struct ReportArgs {
    /// Output directory (created if missing).
    #[arg(long, default_value_os_t = ReportOptions::default().out)]
    pub out: PathBuf,
    /// Base seed of every run's noise.
    #[arg(long, default_value_t = ReportOptions::default().seed)]
    pub seed: u64,
    /// Scale of every scenario's duration (1 = the full programme; refused
    /// up front when one run would exceed `simulate`'s 1e6-tick limit,
    /// above about 11.9).
    #[arg(long, default_value_t = ReportOptions::default().duration_scale,
          value_parser = crate::cli::f64_above(0.0, 100.0))]
    pub duration_scale: f64,
    /// Skip step 7 (unmodelled effects and the residual loop).
    #[arg(long)]
    pub no_effects: bool,
    /// Effects switched on in step 7, comma separated (default: all of
    /// presliding, creep, thermal, spring, drift).
    #[arg(long, value_delimiter = ',')]
    pub effect: Vec<String>,
    /// Run on one thread.
    #[arg(long)]
    pub serial: bool,
    /// No progress lines on stderr.
    #[arg(long)]
    pub quiet: bool,
}

impl From<ReportOptions> for ReportArgs {
    fn from(o: ReportOptions) -> Self {
        Self {
            out: o.out,
            seed: o.seed,
            duration_scale: o.duration_scale,
            no_effects: o.no_effects,
            effect: o.effect,
            serial: o.serial,
            quiet: o.quiet,
        }
    }
}

impl Default for ReportArgs {
    fn default() -> Self {
        ReportOptions::default().into()
    }
}

impl ReportArgs {
    /// The run these arguments ask for.
    pub fn options(&self) -> ReportOptions {
        ReportOptions {
            out: self.out.clone(),
            seed: self.seed,
            duration_scale: self.duration_scale,
            no_effects: self.no_effects,
            effect: self.effect.clone(),
            serial: self.serial,
            quiet: self.quiet,
        }
    }
}

/// Run the subcommand.
pub fn run(args: ReportArgs) -> Result<()> {
    let mut r = generate(&args.options())?;
    let text = write(&mut r)?;
    print!("{text}");
    Ok(())
}
