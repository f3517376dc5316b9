//! `host-sim undeclared`: the undeclared-effect programme
//! ([`crate::residual::programme`]): every effect the plant can add, alone
//! and in pairs, at the datasheet's size and at the upper end of the
//! physical range, on drawn plants at 2 kHz and 1 kHz; what the residual
//! loop names and how much of the error it removes.
//!
//! ```text
//! host-sim undeclared --out undeclared            # 2 draws x 2 rates x 2 sizes x 15 cases
//! host-sim undeclared --draw 41 --rate 1000 --size upper --singles --out u
//! host-sim undeclared --record-every 10 --singles --out u10  # as the board streams
//! ```
//!
//! Writes `undeclared.md` (method, sizes with their physics, summary, every
//! case) and `undeclared.json` into `--out`, together or not at all; prints
//! the summary; progress on stderr.

use std::path::PathBuf;

use anyhow::Result;

use crate::cli;
use crate::output::Outputs;
use crate::residual::programme::{self, ProgrammeOptions, Size};

/// Arguments of `host-sim undeclared`.
#[derive(clap::Args, Debug, Clone)]
pub struct UndeclaredArgs {
    /// Output directory (created if missing).
    #[arg(long, default_value = "undeclared")]
    pub out: PathBuf,
    /// Seeds of the drawn plants (every force-path parameter ±30 %;
    /// default 31 and 32, seeds nothing was tuned on).
    #[arg(long = "draw", num_args = 1.., default_values_t = [31u64, 32])]
    pub draws: Vec<u64>,
    /// Control rates, Hz.
    #[arg(allow_negative_numbers = true, long = "rate", num_args = 1.., default_values_t = [2000.0f32, 1000.0],
          value_parser = cli::f32_in(
              *cable_joint::config::CONTROL_RATE_RANGE_HZ.start(),
              *cable_joint::config::CONTROL_RATE_RANGE_HZ.end()))]
    pub rates_hz: Vec<f32>,
    /// Effect sizes.
    #[arg(long = "size", num_args = 1.., value_enum, default_values_t = [Size::Datasheet, Size::Upper])]
    pub sizes: Vec<Size>,
    /// Only the single effects (no pairs).
    #[arg(long)]
    pub singles: bool,
    /// Base of the runs' noise seeds.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Record every run as the board streams it: a row every N control
    /// ticks with `tick` and the mean current since the row before, as
    /// `simulate --record-every N` writes it (the firmware's default is
    /// 10); the loop replays each log tick by tick.
    #[arg(allow_negative_numbers = true, long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub record_every: u32,
    /// No progress lines.
    #[arg(long)]
    pub quiet: bool,
}

/// Run `host-sim undeclared`.
///
/// # Errors
/// A run or an analysis that fails, or an output that cannot be written.
pub fn run(args: UndeclaredArgs) -> Result<()> {
    crate::output::check_dir_target(&args.out)?;
    // The same plant or rate twice would count its runs twice.
    if let Some(d) = repeated(&args.draws) {
        anyhow::bail!("--draw {d} is given twice: each plant once");
    }
    if let Some(r) = repeated(&args.rates_hz) {
        anyhow::bail!("--rate {r} is given twice: each rate once");
    }
    if let Some(s) = repeated(&args.sizes) {
        anyhow::bail!(
            "--size {} is given twice: each size once",
            cli::value_name(&s)
        );
    }
    let opts = ProgrammeOptions {
        draws: args.draws,
        rates_hz: args.rates_hz,
        sizes: args.sizes,
        pairs: !args.singles,
        seed: args.seed,
        progress: !args.quiet,
        record_every: args.record_every as usize,
    };
    let p = programme::run(&opts)?;
    let mut out = Outputs::new();
    out.create_dir(&args.out)?;
    let md = args.out.join("undeclared.md");
    let json = args.out.join("undeclared.json");
    out.bytes(&md, programme::markdown(&p).as_bytes())?;
    out.bytes(&json, serde_json::to_string_pretty(&p)?.as_bytes())?;
    out.commit()?;
    for l in programme::summary(&p) {
        crate::stdoutln!("{l}");
    }
    crate::stdoutln!("wrote {} and {}", md.display(), json.display());
    Ok(())
}

/// The first value `values` holds twice, if any.
fn repeated<T: PartialEq + Copy>(values: &[T]) -> Option<T> {
    values
        .iter()
        .enumerate()
        .find(|(k, v)| values[..*k].contains(v))
        .map(|(_, v)| *v)
}
