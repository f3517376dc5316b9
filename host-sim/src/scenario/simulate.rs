//! `host-sim simulate`'s work (the command line and its printing are
//! [`crate::cli::simulate`]): one scenario on a plant with a configuration,
//! recorded tick by tick into the CSV log and, when asked, the raw trace for
//! firmware replay.

use anyhow::Result;
use cable_joint::trajectory::Trajectory;
use cable_joint::Config;

use super::{
    oracle_config, plan, run, tuned_gains_noted, Direction, GripOptions, RunSummary,
    ScenarioOptions,
};
use crate::ident::excite::Design;
use crate::io::config::rate_adjustment_note;
use crate::plant::PlantParams;
use crate::sim::{check_ticks, LogRecorder, RawTrace};

/// What [`simulate`] runs. The durations' names are the command line's
/// (`--duration`, `--duration-scale`): the messages that refuse them say so.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SimulateOptions {
    /// Scenario name ([`super::SCENARIOS`]).
    pub scenario: String,
    /// Seed of the noise generator (`None`: the scenario's).
    pub seed: Option<u64>,
    /// Total simulated duration, s (scales every segment). At most one of
    /// `duration` and `duration_scale` (both are refused, as the command
    /// line refuses both flags).
    pub duration: Option<f64>,
    /// Scale of every segment's duration (`None`: 1).
    pub duration_scale: Option<f64>,
    /// `loading`: run only this held angle, degrees.
    pub angle_deg: Option<f64>,
    /// `loading`: run only this weight, grams.
    pub mass_g: Option<f64>,
    /// `loading`: run only this direction.
    pub direction: Option<Direction>,
    /// Weights add their inertia rigidly to the joint
    /// ([`ScenarioOptions::tip_inertia`]).
    pub tip_inertia: bool,
    /// Use the plant's true values for the identified parameters
    /// ([`oracle_config`]).
    pub oracle: bool,
    /// Use cascade gains that work on the default plant ([`super::tuned_gains`]).
    pub tuned_gains: bool,
    /// Also record the raw trace ([`RawTrace`]).
    pub raw_trace: bool,
    /// `excite`: the designed series ([`ScenarioOptions::excitation`]).
    pub excitation: Option<Design>,
    /// `grip`: the set point and the object ([`ScenarioOptions::grip`]).
    pub grip: GripOptions,
}

impl SimulateOptions {
    /// The scenario's options, with `duration` turned into a scale of the
    /// scenario's full length.
    pub fn scenario_options(&self) -> Result<ScenarioOptions> {
        anyhow::ensure!(
            self.duration.is_none() || self.duration_scale.is_none(),
            "--duration and --duration-scale exclude each other"
        );
        let mut opts = ScenarioOptions {
            angle_deg: self.angle_deg,
            mass_g: self.mass_g,
            direction: self.direction,
            tip_inertia: self.tip_inertia,
            excitation: self.excitation,
            grip: self.grip,
            ..ScenarioOptions::default()
        };
        if let Some(s) = self.duration_scale {
            opts.duration_scale = s;
        }
        if let Some(d) = self.duration {
            anyhow::ensure!(d > 0.0, "--duration must be > 0");
            let full = plan(&self.scenario, &opts)?.duration_s();
            opts.duration_scale = d / full;
            anyhow::ensure!(
                opts.duration_scale > 0.0,
                "--duration {d}: too short a part of the scenario's {full} s to run"
            );
        }
        Ok(opts)
    }
}

/// A finished simulation: its summary and what was recorded.
#[derive(Clone, Debug)]
pub struct Simulation {
    /// The run's summary (errors, force errors, fault).
    pub summary: RunSummary,
    /// Every tick as a row of the CSV log.
    pub log: LogRecorder,
    /// Every tick's raw counts and codes (with [`SimulateOptions::raw_trace`]).
    pub raw: Option<RawTrace>,
}

/// Run `opts.scenario` on `plant` with `config` (replaced in part by
/// `opts.oracle` and `opts.tuned_gains`). Refused up front when the run
/// would record more than [`crate::sim::MAX_TICKS`] ticks.
pub fn simulate(plant: PlantParams, config: Config, opts: &SimulateOptions) -> Result<Simulation> {
    let name = opts.scenario.as_str();
    let mut config = config;
    if opts.oracle {
        config = oracle_config(&plant, &config);
    }
    if opts.tuned_gains {
        let (tuned, derived) = tuned_gains_noted(&config);
        for a in derived {
            eprintln!(
                "note: --tuned-gains: {}",
                rate_adjustment_note(&a, "the tuned", tuned.control_rate_hz)
            );
        }
        config = tuned;
    }
    let scenario_opts = opts.scenario_options()?;
    let what = match (opts.duration, opts.duration_scale) {
        (Some(d), _) => format!("--duration {d}"),
        (None, Some(s)) => format!("--duration-scale {s}"),
        (None, None) => format!("scenario {name}"),
    };
    let the_plan = plan(name, &scenario_opts)?;
    if name == "excite" {
        check_excitation_range(&the_plan.references(), &config)?;
    }
    let duration_s = the_plan.duration_s();
    let rate_hz = f64::from(config.control_rate_hz);
    // A log the other commands read has at least this many rows.
    let min_ticks = crate::log::DEFAULT_MIN_ROWS;
    anyhow::ensure!(
        duration_s * rate_hz >= min_ticks as f64,
        "{what}: {duration_s} s is {:.3} control ticks at {rate_hz} Hz; a log needs at least \
         {min_ticks} rows ({} s at this rate): lengthen it",
        duration_s * rate_hz,
        min_ticks as f64 / rate_hz
    );
    check_ticks(&what, duration_s, rate_hz).map_err(|e| {
        let part = if name == "loading" {
            ", or run one part of it (`--angle-deg`, `--mass-g`, `--direction`)"
        } else {
            ""
        };
        anyhow::anyhow!("{e}: shorten it (`--duration`, `--duration-scale`){part}")
    })?;
    let mut log = LogRecorder::new(plant.sensors.magnetic_fitted);
    let mut raw = RawTrace::new();
    let summary = if opts.raw_trace {
        run(
            name,
            plant,
            config,
            opts.seed,
            &scenario_opts,
            &mut (&mut log, &mut raw),
        )?
    } else {
        run(name, plant, config, opts.seed, &scenario_opts, &mut log)?
    };
    Ok(Simulation {
        summary,
        log,
        raw: opts.raw_trace.then_some(raw),
    })
}

/// The excitation's references (`references`: trajectory and how long it
/// runs) stay inside the configuration's joint-angle limit
/// (`limits.max_joint_angle_rad`): beyond it the run would latch
/// `AngleRange` (fault 12) and record a faulted run, not an identification
/// run. Sampled every millisecond (at most a million samples each).
/// [`simulate`] checks its `excite` runs with it, `host-sim link` the run
/// it sends.
///
/// # Errors
/// The first reference that leaves the limit, with its peak and when.
pub fn check_excitation_range(references: &[(Trajectory, f64)], config: &Config) -> Result<()> {
    let limit_rad = f64::from(config.limits.max_joint_angle_rad);
    let mut start_s = 0.0;
    for (trajectory, duration_s) in references {
        let step_s = (duration_s / 1e6).max(1e-3);
        let samples = (duration_s / step_s).ceil() as usize;
        let (peak_rad, at_s) = (0..=samples)
            .map(|k| {
                let t_s = k as f64 * step_s;
                (f64::from(trajectory.at(t_s as f32).angle_rad).abs(), t_s)
            })
            .fold((0.0, 0.0), |m, x| if x.0 > m.0 { x } else { m });
        anyhow::ensure!(
            peak_rad <= limit_rad,
            "the excitation's angle reaches {:.1}° at {:.3} s of the run, beyond the \
             configuration's limits.max_joint_angle_rad ({:.1}°): the run would latch \
             AngleRange (fault 12); check the excitation's offset and amplitudes, or design it \
             again with a smaller --max-angle-deg",
            peak_rad.to_degrees(),
            start_s + at_s,
            limit_rad.to_degrees()
        );
        start_s += duration_s;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_duration_is_a_scale_of_the_full_plan() {
        let opts = SimulateOptions {
            scenario: "track-motor".into(),
            duration: Some(2.6),
            ..SimulateOptions::default()
        };
        let full = plan("track-motor", &ScenarioOptions::default())
            .unwrap()
            .duration_s();
        let s = opts.scenario_options().unwrap();
        assert!((s.duration_scale - 2.6 / full).abs() < 1e-12);
        let p = plan("track-motor", &s).unwrap();
        assert!((p.duration_s() - 2.6).abs() < 1e-9, "{}", p.duration_s());
        let both = SimulateOptions {
            duration_scale: Some(0.5),
            ..opts
        };
        let err = both.scenario_options().unwrap_err().to_string();
        assert!(err.contains("exclude each other"), "{err}");
    }

    #[test]
    fn the_raw_trace_is_recorded_only_when_asked() {
        let mut opts = SimulateOptions {
            scenario: "track-motor".into(),
            duration: Some(0.05),
            ..SimulateOptions::default()
        };
        let sim = simulate(PlantParams::default(), Config::default(), &opts).unwrap();
        assert!(sim.raw.is_none());
        assert_eq!(sim.log.len() as u64, sim.summary.ticks);
        opts.raw_trace = true;
        let sim = simulate(PlantParams::default(), Config::default(), &opts).unwrap();
        let raw = sim.raw.expect("raw trace asked for");
        assert_eq!(raw.records.len(), sim.log.len());
    }

    #[test]
    fn a_run_above_the_tick_limit_is_refused_before_it_starts() {
        let opts = SimulateOptions {
            scenario: "loading".into(),
            duration_scale: Some(50.0),
            ..SimulateOptions::default()
        };
        let err = simulate(PlantParams::default(), Config::default(), &opts)
            .unwrap_err()
            .to_string();
        assert!(err.starts_with("--duration-scale 50:"), "{err}");
    }
}
