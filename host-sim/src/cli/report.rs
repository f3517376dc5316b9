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
    #[arg(allow_negative_numbers = true, long, default_value_t = ReportOptions::default().duration_scale,
          value_parser = crate::cli::f64_above(0.0, 100.0))]
    pub duration_scale: f64,
    /// Skip step 7 (unmodelled effects and the residual loop).
    #[arg(long)]
    pub no_effects: bool,
    /// Effects switched on in step 7, comma separated (default: all of
    /// presliding, creep, thermal, spring, drift).
    #[arg(long, value_delimiter = ',', conflicts_with = "no_effects", value_parser = effect_name)]
    pub effect: Vec<String>,
    /// Run on one thread.
    #[arg(long)]
    pub serial: bool,
    /// No progress lines on stderr.
    #[arg(long)]
    pub quiet: bool,
    /// Run the force sections (plant variants, excitation, wrist, grip) on
    /// drawn plants FIRST-LAST (every force-path parameter ±30 % from the
    /// seed, odd seeds at 2 kHz, even at 1 kHz) instead of the ten variants:
    /// an out-of-sample check on plants no default was tuned on. The report's
    /// own draws are 11, 12 and 13; at most 100 plants.
    #[arg(long, value_name = "FIRST-LAST", value_parser = parse_draws)]
    pub draws: Option<(u64, u64)>,
    /// With `--draws`: run every drawn plant at this control rate, Hz,
    /// instead of 2 kHz for odd seeds and 1 kHz for even ones (another
    /// board's rate; 250 to 10 000 Hz, every rate-dependent setting derived
    /// from it as `simulate` does).
    #[arg(long, allow_negative_numbers = true, value_name = "HZ", requires = "draws",
          value_parser = crate::cli::f64_in(250.0, 10_000.0))]
    pub draw_rate_hz: Option<f64>,
    /// Turn the payout stop on (`cascade.payout_stop`, off by default) in
    /// every plant variant's identified configuration (the force sections:
    /// loading protocol passive and with probing, wrist, grip): the motor
    /// unwinds no further once its reading has cable 0 nearly slack
    /// (README, "The payout stop").
    #[arg(long)]
    pub payout_stop: bool,
}

/// `FIRST-LAST` (or one seed `N`) of `--draws`.
fn parse_draws(s: &str) -> Result<(u64, u64), String> {
    let num = |t: &str| {
        t.trim().parse::<u64>().map_err(|_| {
            format!("`{t}` is not a seed (a whole number); expected FIRST-LAST, e.g. 21-40")
        })
    };
    let (first, last) = match s.split_once('-') {
        Some((a, b)) => (num(a)?, num(b)?),
        None => {
            let n = num(s)?;
            (n, n)
        }
    };
    if last < first {
        return Err(format!("{first}-{last}: the last seed is before the first"));
    }
    if last - first >= 100 {
        return Err(format!("{first}-{last}: at most 100 plants"));
    }
    Ok((first, last))
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
            draws: o.draws,
            draw_rate_hz: o.draw_rate_hz,
            payout_stop: o.payout_stop,
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
            draws: self.draws,
            draw_rate_hz: self.draw_rate_hz,
            payout_stop: self.payout_stop,
        }
    }
}

/// An effect's name `--effect` takes, checked before any work.
fn effect_name(s: &str) -> Result<String, String> {
    crate::plant::Effects::default()
        .enable(s)
        .map(|()| s.trim().to_owned())
        .map_err(|e| e.to_string())
}

/// Run the subcommand.
pub fn run(args: ReportArgs) -> Result<()> {
    crate::output::check_dir_target(&args.out)?;
    let mut r = generate(&args.options())?;
    let text = write(&mut r)?;
    crate::stdout!("{text}");
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `--draws` takes a range or one seed, and refuses a reversed range, a
    /// word or more than 100 plants with a message that names the value.
    #[test]
    fn draws_parse_a_range_and_name_what_is_wrong() {
        assert_eq!(parse_draws("21-40"), Ok((21, 40)));
        assert_eq!(parse_draws("7"), Ok((7, 7)));
        let reversed = parse_draws("40-21").unwrap_err();
        assert!(
            reversed.contains("40-21") && reversed.contains("before"),
            "{reversed}"
        );
        let word = parse_draws("a-3").unwrap_err();
        assert!(
            word.contains("`a`") && word.contains("FIRST-LAST"),
            "{word}"
        );
        assert!(parse_draws("1-101").unwrap_err().contains("at most 100"));
        assert_eq!(parse_draws("1-100"), Ok((1, 100)));
    }

    /// `--draw-rate-hz` reaches the drawn plants, only with `--draws`, and
    /// a rate outside 250-10 000 Hz is refused with the range named.
    #[test]
    fn draw_rate_sets_every_drawn_plant_s_rate_and_needs_draws() {
        use clap::Parser;
        #[derive(clap::Parser)]
        struct Cli {
            #[command(flatten)]
            report: ReportArgs,
        }
        let parse = |args: &[&str]| {
            Cli::try_parse_from(std::iter::once("report").chain(args.iter().copied()))
                .map(|c| c.report)
        };
        let a = parse(&["--draws", "70-72", "--draw-rate-hz", "500"]).unwrap();
        let rates: Vec<f32> = crate::report::variants::drawn_variants(
            70,
            72,
            a.options().draw_rate_hz.map(|hz| hz as f32),
        )
        .iter()
        .map(|v| v.rate_hz)
        .collect();
        assert_eq!(rates, [500.0; 3]);
        let native: Vec<f32> = crate::report::variants::drawn_variants(70, 71, None)
            .iter()
            .map(|v| v.rate_hz)
            .collect();
        assert_eq!(native, [1000.0, 2000.0]);
        assert!(parse(&["--draw-rate-hz", "500"]).is_err(), "needs --draws");
        let low = parse(&["--draws", "70", "--draw-rate-hz", "100"])
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(low.contains("250"), "{low}");
    }
}
