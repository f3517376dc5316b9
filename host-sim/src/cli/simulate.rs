//! `host-sim simulate`: run one scenario on the simulated prototype and write
//! the CSV log (and optionally the raw trace for firmware replay).
//!
//! ```text
//! host-sim simulate --scenario track-motor --out run.csv
//! host-sim simulate --scenario loading --angle-deg 30 --mass-g 100 --direction pos --out l.csv
//! host-sim simulate --scenario track-jae --effect creep,thermal --seed 7 --duration 5 --out r.csv
//! host-sim simulate --scenario jae-ident --record-every 10 --out board.csv
//! host-sim simulate --list
//! host-sim simulate --print-plant > plant.toml
//! ```
//!
//! `--config` is the controller's TOML (default: the core's defaults),
//! `--plant` the plant's TOML (merged onto the default plant). `--oracle`
//! replaces the identified parts of the configuration with the plant's true
//! values; `--tuned-gains` uses cascade gains that work on the default plant
//! ([`crate::scenario::tuned_gains`]). The run itself is
//! [`crate::scenario::simulate()`]; here: the arguments, the plant and
//! configuration files, the output files and what is printed.

use std::path::PathBuf;

use anyhow::Context;
use cable_joint::Config;

use crate::cli;
use crate::output::Outputs;
use crate::scenario::{simulate, Direction, GripOptions, SimulateOptions, SCENARIOS};
use crate::stats::Summary;

/// `--direction` of `host-sim simulate` ([`Direction`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum DirectionArg {
    /// `F_ext > 0`: opposes positive rotation (raises cable 1's tension).
    Pos,
    /// `F_ext < 0`.
    Neg,
}

impl From<DirectionArg> for Direction {
    fn from(d: DirectionArg) -> Self {
        match d {
            DirectionArg::Pos => Direction::Pos,
            DirectionArg::Neg => Direction::Neg,
        }
    }
}
/// Arguments of `host-sim simulate`.
#[derive(clap::Args, Debug, Clone)]
pub struct SimulateArgs {
    /// Scenario name (see `--list`).
    #[arg(long)]
    pub scenario: Option<String>,
    /// Output CSV log (DESIGN.md columns + estimates + ground truth).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Also write the raw per-tick trace (counts, ADC/DAC codes, outputs).
    #[arg(long)]
    pub raw_out: Option<PathBuf>,
    /// Seed of the noise generator (default: the scenario's).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Controller configuration (TOML).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Plant parameters (TOML, merged onto the defaults).
    #[arg(long)]
    pub plant: Option<PathBuf>,
    /// Effects to switch on, comma separated: presliding, creep, thermal,
    /// spring, drift.
    #[arg(long, value_delimiter = ',')]
    pub effect: Vec<String>,
    /// Total simulated duration, s (scales every segment; at most 1e6
    /// control ticks, all kept in memory).
    #[arg(allow_negative_numbers = true, long, conflicts_with = "duration_scale", value_parser = cli::f64_above(0.0, f64::MAX))]
    pub duration: Option<f64>,
    /// Scale of every segment's duration.
    #[arg(allow_negative_numbers = true, long, value_parser = cli::f64_above(0.0, f64::MAX))]
    pub duration_scale: Option<f64>,
    /// `loading`: run only this held angle, degrees.
    #[arg(long, allow_negative_numbers = true, value_parser = cli::f64_in(-180.0, 180.0))]
    pub angle_deg: Option<f64>,
    /// `loading`: run only this weight, grams.
    #[arg(allow_negative_numbers = true, long, value_parser = cli::f64_in(0.0, 10_000.0))]
    pub mass_g: Option<f64>,
    /// `loading`: run only this direction.
    #[arg(long, value_enum)]
    pub direction: Option<DirectionArg>,
    /// Weights add their inertia rigidly to the joint (stress case; default:
    /// pure force, as through a compliant thread).
    #[arg(long)]
    pub tip_inertia: bool,
    /// Use the plant's true values for the identified parameters.
    #[arg(long)]
    pub oracle: bool,
    /// Use cascade gains that work on the default plant.
    #[arg(long)]
    pub tuned_gains: bool,
    /// `excite`: run this designed series (`host-sim excite --out`; default:
    /// the design for `jae-ident`'s envelope).
    #[arg(long)]
    pub excitation: Option<PathBuf>,
    /// `grip`: the set point and the object.
    #[command(flatten)]
    pub grip: GripArgs,
    /// List the scenarios and exit.
    #[arg(long)]
    pub list: bool,
    /// Print the plant parameters (after `--plant` and `--effect`) as TOML and exit.
    #[arg(long)]
    pub print_plant: bool,
    /// Write the log as a board streaming a record every N-th control tick
    /// records it (`link --decimation N`): the measured columns (`t_s` to
    /// `f_ext_n`), `tick`, and `i_applied_a`, the mean current reference
    /// since the record before (default: a row every tick, every column).
    #[arg(allow_negative_numbers = true, long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub record_every: Option<u32>,
}

impl SimulateArgs {
    /// The run these arguments ask for, of scenario `name` (the library
    /// takes plain options).
    pub fn options(&self, name: &str) -> anyhow::Result<SimulateOptions> {
        let excitation = self
            .excitation
            .as_deref()
            .map(crate::ident::excite::load)
            .transpose()?;
        Ok(SimulateOptions {
            scenario: name.to_owned(),
            seed: self.seed,
            duration: self.duration,
            duration_scale: self.duration_scale,
            angle_deg: self.angle_deg,
            mass_g: self.mass_g,
            direction: self.direction.map(Direction::from),
            tip_inertia: self.tip_inertia,
            oracle: self.oracle,
            tuned_gains: self.tuned_gains,
            raw_trace: self.raw_out.is_some(),
            excitation,
            grip: self.grip.options(),
        })
    }
}

/// `--scenario grip`'s set point and object (`host-sim simulate`, `host-sim
/// link`).
#[derive(clap::Args, Debug, Clone)]
pub struct GripArgs {
    /// `grip`: the tip-force set point, N (its sign is the side the object
    /// is on; |F| at most 10 N).
    #[arg(long, default_value_t = GripOptions::default().force_n, allow_negative_numbers = true,
          value_parser = cli::f64_in(-10.0, 10.0))]
    pub grip_n: f64,
    /// `grip`: the object's surface, degrees from 0 on the set point's side
    /// (the simulator's object; on a rig, where the object is, so that the
    /// jaw opens from there).
    #[arg(allow_negative_numbers = true, long, default_value_t = GripOptions::default().object_deg,
          value_parser = cli::f64_above(0.0, 80.0))]
    pub object_deg: f64,
    /// `grip`: the object's stiffness at the tip, N/m (the simulator's).
    #[arg(allow_negative_numbers = true, long, default_value_t = GripOptions::default().object_n_m,
          value_parser = cli::f64_above(0.0, 1e6))]
    pub object_n_m: f64,
}

impl GripArgs {
    /// The options these arguments ask for.
    pub fn options(&self) -> GripOptions {
        GripOptions {
            force_n: self.grip_n,
            object_deg: self.object_deg,
            object_n_m: self.object_n_m,
        }
    }
}

fn fmt_stats(s: &Option<Summary>) -> String {
    match s {
        Some(s) => format!(
            "mean {:+.3}°, mean|e| {:.3}°, max {:+.3}°, min {:+.3}°",
            s.mean, s.mean_abs, s.max, s.min
        ),
        None => "n/a".to_owned(),
    }
}

/// Run the subcommand.
pub fn run(args: SimulateArgs) -> anyhow::Result<()> {
    if args.list {
        for s in SCENARIOS {
            crate::stdoutln!("{:<14} seed {:<4} {}", s.name, s.seed, s.description);
        }
        return Ok(());
    }
    let mut plant = crate::io::config::load_plant(args.plant.as_deref())?;
    for e in &args.effect {
        if !e.trim().is_empty() {
            plant.effects.enable(e)?;
        }
    }
    plant.validate()?;
    if args.print_plant {
        crate::stdout!("{}", plant.to_toml_string()?);
        return Ok(());
    }
    let name = args
        .scenario
        .as_deref()
        .context("--scenario NAME is required (see --list)")?;
    let out = args.out.as_ref().context("--out PATH is required")?;
    let config = match &args.config {
        Some(p) => crate::io::config::load_config(p)?,
        None => Config::default(),
    };
    let opts = args.options(name)?;
    let sim = simulate(plant, config, &opts)?;
    let summary = sim.summary;
    // The log and the raw trace are written together, or neither is.
    let mut outputs = Outputs::new();
    let log = sim.log.to_log()?;
    let log = match args.record_every {
        Some(n) => crate::sim::recorded_every(&log, n as usize, true)?,
        None => log,
    };
    log.stage(&mut outputs, out)?;
    if let (Some(p), Some(raw)) = (&args.raw_out, &sim.raw) {
        raw.to_table().to_log()?.stage(&mut outputs, p)?;
    }
    outputs.commit()?;
    let effects = plant.effects.enabled();
    crate::stdoutln!(
        "{}: seed {}, {} rows{}, {:.2} s simulated{} -> {}",
        summary.name,
        summary.seed,
        log.len(),
        match args.record_every {
            Some(n) => format!(" (a record every {n} of {} ticks)", summary.ticks),
            None => String::new(),
        },
        summary.duration_s,
        if effects.is_empty() {
            String::new()
        } else {
            format!(", effects: {}", effects.join(","))
        },
        out.display()
    );
    // Under a grip the reference is the force law's, not a trajectory:
    // its distance from the joint says nothing about tracking.
    if summary.grip.is_none() {
        crate::stdoutln!(
            "  tracking (desired - magnetic): {}",
            fmt_stats(&summary.tracking)
        );
    }
    crate::stdoutln!(
        "  JAE (estimate - magnetic):     {}",
        fmt_stats(&summary.jae)
    );
    if let Some((mean, max)) = summary.force_error_n {
        crate::stdoutln!(
            "  force estimate (DOB) in stable regions: mean error {mean:+.3} N, max |error| {max:.3} N"
        );
    }
    if let Some((mean, max)) = summary.force_stretch_error_n {
        crate::stdoutln!(
            "  force estimate (stretch) in stable regions: mean error {mean:+.3} N, max |error| {max:.3} N"
        );
    }
    if let Some(g) = &summary.grip {
        crate::stdoutln!(
            "  grip at {:.2} N, true force over its last second: {:.3} N ({:+.1} %), overshoot {:.1} %, within ±5 % {}",
            g.set_n,
            g.steady_true_n,
            g.steady_error_pct,
            g.overshoot_pct,
            g.settling_s
                .map_or("never".to_owned(), |t| format!("after {t:.2} s")),
        );
        crate::stdoutln!(
            "  grip: fused estimate {:.3} N, bound [{:.3}, {:.3}] N, covers the true force on {:.0} % of that second",
            g.steady_est_n,
            g.steady_lo_n,
            g.steady_hi_n,
            100.0 * g.steady_coverage
        );
    }
    if let Some(f) = summary.fault {
        crate::stdoutln!("  FAULT latched: {f} (code {})", f.code());
        // Whether the run closed the loop on `theta_hat` (its own plan;
        // with `--oracle` the plant's JAE stood in for the configuration's).
        let on_jae = !opts.oracle
            && opts
                .scenario_options()
                .and_then(|o| crate::scenario::plan(name, &o))
                .is_ok_and(|p| p.closes_loop_on_jae());
        if let Some(hint) = datasheet_jae_hint(f, &config, on_jae) {
            crate::stdoutln!("  {hint}");
        }
    }
    Ok(())
}

/// Why an I²t fault may be the configuration's, not the plant's: with the
/// datasheet's JAE (the seed's `c1` = +0.0805) a run that closes the loop on
/// `theta_hat` drives the current into a limit cycle that heats the winding
/// (README, "What keeps 1 kHz quiet"; `tension-ident` latches it 13 s in on
/// the default plant). `None` for any other fault, an identified JAE, or a
/// run that did not close the loop on the JAE (`on_jae` false).
fn datasheet_jae_hint(
    fault: cable_joint::fault::Fault,
    config: &Config,
    on_jae: bool,
) -> Option<String> {
    let datasheet = config.jae == Config::default().jae;
    (fault == cable_joint::fault::Fault::I2t && datasheet && on_jae).then(|| {
        "note: this configuration's JAE is still the datasheet's (the seed's c1 = +0.0805): \
         closed on it, the loop's current chatters and heats the winding. Identify the JAE on \
         this machine first (`simulate --scenario jae-ident`, `identify --procedure jae \
         --config-out jae.toml`) and run with `--config jae.toml`, as the README's rig \
         workflow does"
            .to_owned()
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use cable_joint::fault::Fault;

    /// The hint names the datasheet JAE only for an I²t fault under the
    /// datasheet's JAE in a run on the JAE: an identified JAE, another
    /// fault, or a run on the motor's angle gets none.
    #[test]
    fn the_i2t_hint_is_given_only_under_the_datasheet_jae() {
        let datasheet = Config::default();
        let hint = datasheet_jae_hint(Fault::I2t, &datasheet, true).expect("a hint");
        assert!(hint.contains("identify --procedure jae"), "{hint}");
        let mut identified = datasheet;
        identified.jae.c_acc_rad_s2_m = -0.011;
        assert_eq!(datasheet_jae_hint(Fault::I2t, &identified, true), None);
        assert_eq!(datasheet_jae_hint(Fault::AdcRail, &datasheet, true), None);
        assert_eq!(datasheet_jae_hint(Fault::I2t, &datasheet, false), None);
    }
}
