//! `host-sim excite`: design an identification excitation (seed 001 Sect.
//! 2.3, [`crate::ident::excite`]) for the envelope and length of a hand-made
//! run, and write it for `--scenario excite`.
//!
//! ```text
//! host-sim excite --out excitation.toml
//! host-sim simulate --scenario excite --excitation excitation.toml --out excite.csv
//! host-sim link --port /dev/ttyACM0 --scenario excite --excitation excitation.toml --magnetic --record excite.csv
//! ```
//!
//! With `--wrist` it designs the wrist's Eq. 3 excitation instead
//! ([`crate::ident::excite_wrist`]): four series designed together for the
//! limits and length of the hand-made free run
//! ([`FreeRun::identification`]), written as one file and, for each joint's
//! controller, as a file of the single joint's format
//! (`<out stem>.<joint>.toml`, for `--scenario excite --excitation`).

use std::path::PathBuf;

use anyhow::{ensure, Context};

use crate::cli;
use crate::ident::excite::{self, Criterion, Design, DesignOptions, Envelope, PREDICTION_RATE_HZ};
use crate::ident::excite_wrist::{self, WristDesignOptions};
use crate::links::FreeRun;
use crate::output::write_atomic;
use crate::scenario::{excitation_replacing, plan, ScenarioOptions};
use crate::wrist_log::JOINT_NAMES;

/// Arguments of `host-sim excite`.
#[derive(clap::Args, Debug, Clone)]
pub struct ExciteArgs {
    /// The hand-made run the excitation replaces: its reference's envelope
    /// gives the limits and its length less 2 s (hold and return) the
    /// series' length, unless set below.
    #[arg(long, default_value = "jae-ident")]
    pub like: String,
    /// Fundamental frequency, Hz (seed 001: 0.1 Hz; default: the best of
    /// 0.05 to 0.5 Hz rounded to whole periods).
    #[arg(allow_negative_numbers = true, long, value_parser = cli::f64_above(0.0, 10.0))]
    pub base_freq_hz: Option<f64>,
    /// What the search minimises: `sigma`, the largest predicted standard
    /// deviation of the q'', q' and q parameters relative to `--like`'s, or
    /// `condition`, seed 001's condition number.
    #[arg(long, value_enum, default_value_t = ObjectiveArg::Sigma)]
    pub objective: ObjectiveArg,
    /// Length of the series, s (rounded down to whole periods).
    #[arg(allow_negative_numbers = true, long, value_parser = cli::f64_above(0.0, 1e5))]
    pub duration_s: Option<f64>,
    /// Angle limit from the start angle, degrees.
    #[arg(allow_negative_numbers = true, long, value_parser = cli::f64_above(0.0, 180.0))]
    pub max_angle_deg: Option<f64>,
    /// Velocity limit, degrees/s.
    #[arg(allow_negative_numbers = true, long, value_parser = cli::f64_above(0.0, 1e5))]
    pub max_vel_deg_s: Option<f64>,
    /// Acceleration limit, degrees/s².
    #[arg(allow_negative_numbers = true, long, value_parser = cli::f64_above(0.0, 1e7))]
    pub max_acc_deg_s2: Option<f64>,
    /// Random starts of the search (per base frequency; default 4, with
    /// `--wrist` 2: forty coefficients cost more per start).
    #[arg(allow_negative_numbers = true, long, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub restarts: Option<u32>,
    /// Seed of the random starts.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Design the wrist's Eq. 3 excitation (four joints, seed 000 Eq. 3's
    /// regressor, the condition number) for the hand-made free run's
    /// limits and length, with the default configuration's geometry and
    /// the prototype links' gravity.
    #[arg(long, conflicts_with_all = ["like", "objective", "max_angle_deg", "max_vel_deg_s", "max_acc_deg_s2"])]
    pub wrist: bool,
    /// The designed excitation (TOML).
    #[arg(long)]
    pub out: PathBuf,
}

/// `--objective` ([`excite::Objective`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ObjectiveArg {
    /// Largest predicted standard-deviation ratio to `--like`'s run.
    Sigma,
    /// Seed 001's condition number.
    Condition,
}

fn show(e: &Envelope) -> String {
    format!(
        "|angle| {:.1}°, |velocity| {:.1}°/s, |acceleration| {:.1}°/s²",
        e.angle_rad.to_degrees(),
        e.vel_rad_s.to_degrees(),
        e.acc_rad_s2.to_degrees()
    )
}

/// Why a design of condition number `condition` (not finite) is refused.
fn no_excitation(condition: f64, hint: &str) -> String {
    format!(
        "the limits leave no motion that identifies every parameter (predicted condition \
         number {condition}): nothing written; {hint}"
    )
}

/// Run the subcommand.
pub fn run(args: ExciteArgs) -> anyhow::Result<()> {
    if args.wrist {
        return run_wrist(&args);
    }
    ensure!(
        args.like != "excite",
        "--like names the hand-made run the excitation replaces, not `excite` itself"
    );
    let hand_made = plan(&args.like, &ScenarioOptions::default())?;
    let references = hand_made.references();
    let criterion = match args.objective {
        ObjectiveArg::Condition => Criterion::Condition,
        ObjectiveArg::Sigma => Criterion::Sigma,
    };
    let (replacing, series_s) = excitation_replacing(&hand_made, criterion);
    let measured = replacing.limits;
    let duration_s = args.duration_s.unwrap_or(series_s);
    let opts = DesignOptions {
        limits: Envelope {
            angle_rad: args
                .max_angle_deg
                .map_or(measured.angle_rad, f64::to_radians),
            vel_rad_s: args
                .max_vel_deg_s
                .map_or(measured.vel_rad_s, f64::to_radians),
            acc_rad_s2: args
                .max_acc_deg_s2
                .map_or(measured.acc_rad_s2, f64::to_radians),
        },
        restarts: args.restarts.unwrap_or(4),
        seed: args.seed,
        ..replacing
    };
    let before = excite::condition(&references, PREDICTION_RATE_HZ);
    crate::stdoutln!(
        "{}: {:.1} s, {}; predicted condition number {before:.1}",
        args.like,
        hand_made.duration_s(),
        show(&measured)
    );
    eprintln!(
        "searching: {} starts of Nelder-Mead over {} coefficients{} ...",
        opts.restarts,
        2 * cable_joint::trajectory::HARMONICS,
        if args.base_freq_hz.is_none() {
            ", at each base frequency"
        } else {
            ""
        }
    );
    let design = match args.base_freq_hz {
        Some(f) => {
            let periods = ((duration_s * f).floor() as u32).max(1);
            excite::design(&DesignOptions {
                base_freq_hz: f,
                periods,
                ..opts
            })?
        }
        None => excite::design_over_frequencies(&opts, duration_s)?,
    };
    ensure!(
        design.condition.is_finite(),
        "{}",
        no_excitation(
            design.condition,
            "widen --max-angle-deg, --max-vel-deg-s or --max-acc-deg-s2"
        )
    );
    let run = plan(
        "excite",
        &ScenarioOptions {
            excitation: Some(design),
            ..ScenarioOptions::default()
        },
    )?;
    let run_references = run.references();
    let after = excite::condition(&run_references, PREDICTION_RATE_HZ);
    crate::stdoutln!(
        "excite: {:.1} s ({:.1} s of {:.3} Hz, 1 s hold, 1 s return), {}; predicted condition number {after:.1} ({:.2}x {}; the series alone, the file's `condition`, {:.2}), {} evaluations",
        run.duration_s(),
        design.duration_s,
        design.trajectory_base_freq_hz(),
        show(&design.envelope),
        after / before,
        args.like,
        design.condition,
        design.evaluations
    );
    let (a, b) = (
        excite::unit_std(&references, PREDICTION_RATE_HZ),
        excite::unit_std(&run_references, PREDICTION_RATE_HZ),
    );
    let ratios: Vec<String> = a
        .iter()
        .zip(b.iter())
        .map(|(a, b)| format!("{:.2}", b / a))
        .collect();
    crate::stdoutln!(
        "predicted std ratio per column [q'', q', sgn, q, 1]: {}",
        ratios.join(" ")
    );
    for (name, refs) in [
        (args.like.as_str(), &references),
        ("excite", &run_references),
    ] {
        let b = excite::pair_bound(refs, PREDICTION_RATE_HZ);
        crate::stdoutln!(
            "{name}: most correlated columns {} and {} (|cos| {:.3}): no regressor holding both goes under a condition number of {:.2}",
            excite::COLUMN_NAMES[b.columns.0],
            excite::COLUMN_NAMES[b.columns.1],
            b.correlation,
            b.condition_at_least
        );
    }
    write_atomic(&args.out, excite::to_toml(&design)?.as_bytes())
        .with_context(|| format!("writing {}", args.out.display()))?;
    crate::stdoutln!(
        "wrote {}: `host-sim simulate --scenario excite --excitation {1} --out run.csv`, on the rig `host-sim link ... --scenario excite --excitation {1} --magnetic --record run.csv`",
        args.out.display(),
        crate::cli::shell_word(&args.out)
    );
    Ok(())
}

/// `host-sim excite --wrist`.
fn run_wrist(args: &ExciteArgs) -> anyhow::Result<()> {
    let hand = FreeRun::identification();
    let duration_s = args.duration_s.unwrap_or(hand.duration_s);
    let defaults = WristDesignOptions::replacing_free_run();
    let shape = defaults.shape;
    let opts = WristDesignOptions {
        restarts: args.restarts.unwrap_or(defaults.restarts),
        seed: args.seed,
        ..defaults
    };
    let before = shape.condition(&hand.trajectories, hand.duration_s, PREDICTION_RATE_HZ);
    crate::stdoutln!(
        "hand-made free run: {:.1} s; predicted condition number of Eq. 3's regressor {before:.2}",
        hand.duration_s
    );
    for (name, l) in JOINT_NAMES.iter().zip(&opts.limits) {
        crate::stdoutln!("  {name}: {}", show(l));
    }
    eprintln!(
        "searching: {} starts of Nelder-Mead over {} coefficients{} ...",
        opts.restarts,
        8 * cable_joint::trajectory::HARMONICS,
        if args.base_freq_hz.is_none() {
            ", at each base frequency"
        } else {
            ""
        }
    );
    let design = match args.base_freq_hz {
        Some(f) => excite_wrist::design(&WristDesignOptions {
            base_freq_hz: f,
            periods: ((duration_s * f).floor() as u32).max(1),
            ..opts
        })?,
        None => excite_wrist::design_over_frequencies(&opts, duration_s)?,
    };
    ensure!(
        design.condition.is_finite(),
        "{}",
        no_excitation(
            design.condition,
            "lengthen --duration-s or choose another --base-freq-hz"
        )
    );
    crate::stdoutln!(
        "designed: {:.1} s; predicted condition number {:.2} ({:.2}x the hand-made run's), {} evaluations",
        design.duration_s,
        design.condition,
        design.condition / before,
        design.evaluations
    );
    for (name, e) in JOINT_NAMES.iter().zip(&design.envelopes) {
        crate::stdoutln!("  {name}: {}", show(e));
    }
    for (what, runs, s) in [
        ("hand-made", &hand.trajectories, hand.duration_s),
        ("designed", &design.trajectories, design.duration_s),
    ] {
        let b = shape.pair_bound(runs, s, PREDICTION_RATE_HZ);
        let names = cable_joint::wrist_dynamics::PARAM_NAMES;
        crate::stdoutln!(
            "{what}: most correlated columns {} and {} (|cos| {:.3}): no regressor holding both goes under a condition number of {:.2}",
            names[b.columns.0],
            names[b.columns.1],
            b.correlation,
            b.condition_at_least
        );
    }
    crate::stdoutln!(
        "these are predicted from the commanded motion: a fit sees the joints' actual motion, \
         whose friction sign is wider where they stick and slip at low speed (`identify-wrist` \
         prints its width), and measures a higher condition number (README, \"Eq. 3's designed excitation\")"
    );
    let stem = args.out.with_extension("");
    let mut files = crate::output::Outputs::new();
    let mut roll = PathBuf::new();
    for (j, name) in JOINT_NAMES.iter().enumerate() {
        // `with_extension` would take a dot in the stem (`w.v2`) for one.
        let mut path = stem.clone().into_os_string();
        path.push(format!(".{name}.toml"));
        let path = PathBuf::from(path);
        let tr = design.trajectories[j];
        let joint = Design {
            trajectory: tr,
            duration_s: design.duration_s,
            condition: excite::condition(&[(tr, design.duration_s)], PREDICTION_RATE_HZ),
            envelope: design.envelopes[j],
            objective: design.condition.log10(),
            evaluations: design.evaluations,
        };
        files.bytes(&path, excite::to_toml(&joint)?.as_bytes())?;
        if j == 0 {
            roll = path;
        }
    }
    files.bytes(&args.out, toml::to_string_pretty(&design)?.as_bytes())?;
    // The design and its joints' files are written together or not at all.
    files.commit()?;
    crate::stdoutln!(
        "wrote {} and one file per joint ({}.roll.toml, ...): on a joint's controller `host-sim link ... --scenario excite --excitation {} --magnetic --record roll.csv`",
        args.out.display(),
        stem.display(),
        crate::cli::shell_word(&roll)
    );
    Ok(())
}
