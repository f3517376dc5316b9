//! From logs to a selection [`Problem`]: the target, the baseline regressors
//! and the candidate effect library of each model.
//!
//! * `jae`: target `theta_rad` (magnetic encoder, calibration runs); baseline
//!   the seed's Eq. 26 columns `[x2'', x2', sgn x2', x2]` and an offset, on the
//!   signals the core derives from the log ([`crate::derive`]); candidates
//!   read only the run-time signals ([`SIGNAL_NAMES`]), so the selected model
//!   can be written to `config.jae` and run by the firmware.
//! * `tension`: target the DOB's cable-1 tension `tension1_hat_n` (no-load
//!   runs); baseline the simplified model C `[sgn x1', sgn x2', x2, 1]`. The
//!   core compares the DOB's tension with `Q[F_1']` (the model through the
//!   observer's low-pass), so every column is passed through the same `Q`.
//!   The motor current enters only through the thermal terms: a term linear
//!   in the current would copy the DOB's own input and hide any load.
//! * `force`: target the reference tip force `f_ext_n`; baseline the DOB's
//!   `f_ext_hat_n` as it is. Candidates are run-time signals through `Q`; a
//!   selected term maps onto `config.tension.added` (the force estimate is
//!   `(F_1_hat - Q[F_1']) r / l_e`).
//! * generic (`--target`, `--inputs`): baseline linear in the inputs plus a
//!   constant; candidates from the inputs, by unit suffix (`_m`, `_rad`:
//!   position, with a velocity from the core's tracking observer; `_m_s`,
//!   `_rad_s`: velocity; `_a`: current, also the load when no force or torque
//!   input is given; `_n`, `_nm`: load).
//!
//! Reference columns (ground truth and reference sensors: [`is_reference`])
//! are inputs only when `--inputs` names them.

use std::path::Path;

use anyhow::{bail, ensure, Context, Result};
use cable_joint::config::DERIVED_BANDWIDTH_PER_RATE;
use cable_joint::filter::{LowPass1, TrackingObserver};
use cable_joint::model::{sig, SIGNAL_NAMES};
use cable_joint::Config;

use super::candidates::offer_candidates;
use super::families::{term_column, term_label};
use super::generic::{generic_columns, generic_run};
use super::select::{Problem, RunData};
use crate::derive::{
    held_sign, held_sign_travelled, low_pass_column, median_period_s, zero_phase_kinematics,
    TickReplay,
};
use crate::import::{import_mrdlab_run, is_mrdlab_path, MrdlabZero};
use crate::ingest::ReplayEnd;
use crate::log::{Log, Schema};

/// Which model to fit.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ModelKind {
    /// Joint-angle estimator (`theta_rad`).
    Jae,
    /// No-load cable-1 tension model (`tension1_hat_n`).
    Tension,
    /// External tip force (`f_ext_n`) on top of the DOB's estimate.
    Force,
    /// Any column from any inputs.
    Generic {
        /// Target column.
        target: String,
        /// Input columns (`None`: every column that is not a reference).
        inputs: Option<Vec<String>>,
    },
}

impl ModelKind {
    /// Most effects the loop may add for this model, and why: the core's
    /// capacity per estimator (jae, tension, force: the terms go into the
    /// configuration), or [`GENERIC_MAX_TERMS`](super::GENERIC_MAX_TERMS) for
    /// a generic fit, which writes no configuration.
    pub fn max_terms(&self) -> (usize, &'static str) {
        match self {
            ModelKind::Generic { .. } => (super::GENERIC_MAX_TERMS, "a generic fit's limit"),
            _ => (
                cable_joint::model::MAX_TERMS,
                "the core's capacity per estimator",
            ),
        }
    }

    /// Short name.
    pub fn name(&self) -> &'static str {
        match self {
            ModelKind::Jae => "jae",
            ModelKind::Tension => "tension",
            ModelKind::Force => "force",
            ModelKind::Generic { .. } => "generic",
        }
    }

    /// The target column.
    pub fn target(&self) -> &str {
        match self {
            ModelKind::Jae => "theta_rad",
            ModelKind::Tension => "tension1_hat_n",
            ModelKind::Force => "f_ext_n",
            ModelKind::Generic { target, .. } => target,
        }
    }
}

/// Columns that exist only in calibration or as ground truth: never inputs
/// unless named. Also any column containing `_true` (simulator truth).
pub const REFERENCE_COLUMNS: [&str; 6] = [
    "theta_rad",
    "theta_mag_rad",
    "f_ext_n",
    "tau_ext_nm",
    "tau_in_nm",
    "theta_ref_rad",
];

/// Bookkeeping columns, never inputs.
pub(super) const BOOKKEEPING: [&str; 4] = ["t_s", "mode", "fault_code", "phase"];

/// Whether a column is a reference (ground truth or a reference sensor).
pub fn is_reference(name: &str) -> bool {
    REFERENCE_COLUMNS.contains(&name) || name.contains("_true")
}

/// Read a log: MRDLab raw runs (`.TXT`, `.TXT.gz`) are imported with their
/// angles on `zero` ([`MrdlabRun::set_zero`](crate::import::MrdlabRun::set_zero)), anything else is read as a
/// CSV log (`project`: with the project's required columns, through
/// [`read_for_replay`](crate::ingest::read_for_replay), so `ticks_per_row`
/// rebuilds a missing tick column; otherwise any columns, `t_s` required),
/// both from where homing ended to the row before the firmware's first
/// latched fault ([`trim_for_replay`](crate::ingest::trim_for_replay)).
/// `ticks_per_row` is refused on anything but a project log: an MRDLab run
/// and a generic fit are not replayed tick by tick.
pub fn load_log(
    path: &Path,
    project: bool,
    zero: MrdlabZero,
    ticks_per_row: Option<u32>,
) -> Result<Log> {
    let refuse_ticks = |what: &str| -> Result<()> {
        if let Some(n) = ticks_per_row {
            bail!(
                "{}: --ticks-per-row {n} applies to a project log replayed through the core \
                 (--model jae, tension or force); {what}",
                path.display()
            );
        }
        Ok(())
    };
    if is_mrdlab_path(path) {
        refuse_ticks("this is an MRDLab run, read on its own clock")?;
        let mut run = import_mrdlab_run(path)?;
        run.set_zero(zero)?;
        return Ok(run.log);
    }
    if project {
        return crate::ingest::read_for_replay(
            path,
            ticks_per_row,
            "residual",
            ReplayEnd::BeforeFault,
        );
    }
    refuse_ticks("a generic fit (--target) reads the rows as they are")?;
    let log = Log::read_with(path, &Schema::with_required(&["t_s"]))?;
    let name = path.display().to_string();
    crate::ingest::trim_for_replay(log, &name, "residual", ReplayEnd::BeforeFault)
}

/// A log with its name.
#[derive(Clone, Debug)]
pub struct NamedLog {
    /// File name for reports.
    pub name: String,
    /// The data.
    pub log: Log,
}

/// How the problem is built.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BuildOptions {
    /// Share of each fitting run held out for validation when no validation
    /// log is given (its last part).
    pub holdout: f64,
    /// `jae`/`tension`: the terms already in the configuration's `added`
    /// join the baseline (their coefficients are refitted), so the loop
    /// continues from the model the estimator already runs.
    pub keep_added: bool,
    /// Leave the first seconds of every run out of fitting and validation
    /// (start-up transients of runs that begin at rest).
    pub settle_s: f64,
    /// Offer terms that read sensors the model itself does not read
    /// ([`Problem::other_sensors`]): sensor fusion, reported as such.
    pub other_sensors: bool,
    /// Hold out the last `holdout` share of each fitting log even when
    /// validation logs are given: the held-out parts and the validation logs
    /// are then all judged, each a regime that no kept term may make worse.
    pub holdout_with_validate: bool,
}

impl Default for BuildOptions {
    fn default() -> Self {
        Self {
            holdout: 0.3,
            keep_added: false,
            settle_s: 0.0,
            other_sensors: false,
            holdout_with_validate: false,
        }
    }
}

pub(super) fn f32s(v: &[f64]) -> Vec<f32> {
    v.iter().map(|x| *x as f32).collect()
}

/// The run-time signals of a log as the core sees them tick by tick
/// (positions relative to the first sample, as after `set_origin`), the
/// replay they come from ([`TickReplay`]: on a decimated or lossy log the
/// ticks between its rows are stepped and kept, so the terms' states and
/// the observer's `Q` advance as on the MCU; its `config` is the
/// configuration at the log's control rate).
fn runtime_signals(log: &Log, config: &Config) -> Result<(Vec<Vec<f32>>, TickReplay)> {
    let replay = TickReplay::new(log, config)?;
    let d = &replay.log;
    let mut signals = Vec::with_capacity(SIGNAL_NAMES.len());
    for name in SIGNAL_NAMES {
        let v = d.col_required(name)?;
        let first = match name {
            "x1_m" | "x2_m" | "phi_rad" => log.col_required(name)?[0],
            _ => 0.0,
        };
        signals.push(v.iter().map(|x| (x - first) as f32).collect());
    }
    Ok((signals, replay))
}

/// Column `name` of a tick replay at the log's own rows, NaN at the ticks
/// filled between them and where the log does not measure it (neither
/// fitted nor judged).
fn at_log_rows(replay: &TickReplay, name: &str) -> Result<Vec<f64>> {
    let col = replay
        .log
        .col(name)
        .with_context(|| format!("internal: the replay has no column {name}"))?;
    Ok(col
        .iter()
        .enumerate()
        .map(|(k, v)| if replay.measured(k) { *v } else { f64::NAN })
        .collect())
}

/// What the core's configuration needs to take a `jae`/`tension` result.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BuildInfo {
    /// Configuration at the logs' control rate.
    pub config: Config,
}

/// Build the problem for `kind` from fitting and validation logs.
pub fn build(
    kind: &ModelKind,
    fit: &[NamedLog],
    validate: &[NamedLog],
    config: &Config,
    opts: BuildOptions,
) -> Result<(Problem, BuildInfo)> {
    build_tested(kind, fit, validate, &[], config, opts)
}

/// [`build`] with test logs: each becomes a run whose rows (after
/// `settle_s`) are test rows ([`RunData::test_rows`]), neither fitted nor
/// used to choose a term.
pub fn build_tested(
    kind: &ModelKind,
    fit: &[NamedLog],
    validate: &[NamedLog],
    test: &[NamedLog],
    config: &Config,
    opts: BuildOptions,
) -> Result<(Problem, BuildInfo)> {
    ensure!(!fit.is_empty(), "no log to fit");
    ensure!(
        (0.0..1.0).contains(&opts.holdout),
        "holdout must be in [0, 1), got {}",
        opts.holdout
    );
    ensure!(
        opts.settle_s >= 0.0 && opts.settle_s.is_finite(),
        "settle time must be >= 0, got {}",
        opts.settle_s
    );
    let mut problem = Problem {
        model: kind.name().to_owned(),
        target: kind.target().to_owned(),
        ..Default::default()
    };
    let period0 = median_period_s(fit[0].log.time_s()?).context("log too short")?;
    let logs = Logs {
        fit,
        validate,
        test,
    };
    let (runs, info) = build_runs(kind, &logs, config, opts, period0, &mut problem)?;
    problem.runs = runs;
    offer_candidates(kind, &mut problem, period0, opts);
    Ok((problem, info))
}

/// The logs of a problem by their use.
struct Logs<'a> {
    fit: &'a [NamedLog],
    validate: &'a [NamedLog],
    test: &'a [NamedLog],
}

/// What a log is for.
#[derive(Clone, Copy, PartialEq)]
enum Use {
    Fit,
    Validate,
    Test,
}

/// Every log replayed into a run (its signals, target and baseline), with
/// its fitting, validation or test rows; the configuration at the logs'
/// rate.
fn build_runs(
    kind: &ModelKind,
    logs: &Logs,
    config: &Config,
    opts: BuildOptions,
    period0: f64,
    problem: &mut Problem,
) -> Result<(Vec<RunData>, BuildInfo)> {
    let (fit, validate) = (logs.fit, logs.validate);
    let mut info = BuildInfo { config: *config };
    let all = fit
        .iter()
        .map(|l| (l, Use::Fit))
        .chain(validate.iter().map(|l| (l, Use::Validate)))
        .chain(logs.test.iter().map(|l| (l, Use::Test)));
    let generic_cols = match kind {
        ModelKind::Generic { target, inputs } => Some(generic_columns(&fit[0], target, inputs)?),
        _ => None,
    };
    let mut runs = Vec::new();
    let mut control_period_s: Option<f32> = None;
    for (nl, use_) in all {
        let p = median_period_s(nl.log.time_s()?).context("log too short")?;
        ensure!(
            p.is_finite() && p > 0.0,
            "{}: the median time step of t_s is {p} s: the sample period must be a positive \
             finite number (are the times too large for their differences to be represented?)",
            nl.name
        );
        let mut run = match kind {
            ModelKind::Generic { target, .. } => {
                ensure!(
                    (p - period0).abs() <= 0.01 * period0,
                    "{}: sample period {p} s differs from the first log's {period0} s",
                    nl.name
                );
                let (inputs, velocities) = generic_cols.as_ref().map(|c| (&c.0, &c.1)).unwrap();
                generic_run(nl, target, inputs, velocities, config, problem)?
            }
            _ => {
                // Replayed tick by tick, logs recorded at other decimations
                // mix; their control rate must not differ (the terms' states
                // step at it on the MCU).
                let (run, cfg) = core_run(kind, nl, config, opts.keep_added, problem)?;
                let period_s = cfg.period_s();
                let first = *control_period_s.get_or_insert(period_s);
                ensure!(
                    (period_s - first).abs() <= 0.01 * first,
                    "{}: control period {period_s} s differs from the first log's {first} s: \
                     the model's terms step at one control rate",
                    nl.name
                );
                info.config = cfg;
                run
            }
        };
        let n = run.t_s.len();
        // Rows before `settle_s` are computed (the terms' states run from
        // the first sample) but neither fitted nor judged.
        let t0 = run.t_s.first().copied().unwrap_or(0.0);
        let start = run.t_s.partition_point(|t| *t < t0 + opts.settle_s).min(n);
        let (f, v) = if use_ == Use::Test {
            run.test_rows = start..n;
            (0..0, 0..0)
        } else if use_ == Use::Validate {
            (0..0, start..n)
        } else if validate.is_empty() || opts.holdout_with_validate {
            let cut = ((1.0 - opts.holdout) * n as f64).round() as usize;
            (start.min(cut)..cut, cut.max(start)..n)
        } else {
            (start..n, 0..0)
        };
        run.fit_rows = f;
        run.val_rows = v;
        runs.push(run);
    }
    Ok((runs, info))
}

fn core_run(
    kind: &ModelKind,
    nl: &NamedLog,
    config: &Config,
    keep_added: bool,
    problem: &mut Problem,
) -> Result<(RunData, Config)> {
    let log = &nl.log;
    let missing: Vec<&str> = crate::log::REQUIRED_COLUMNS
        .into_iter()
        .filter(|c| !log.has(c))
        .collect();
    ensure!(
        missing.is_empty(),
        "{}: the {} model replays a prototype log through the core, which needs the columns {}; missing: {} (for other data use --target/--inputs)",
        nl.name,
        kind.name(),
        crate::log::REQUIRED_COLUMNS.join(", "),
        missing.join(", ")
    );
    let (signals, replay) =
        runtime_signals(log, config).with_context(|| format!("replaying {}", nl.name))?;
    let cfg = replay.config;
    let d = &replay.log;
    let t_s = d.time_s()?.to_vec();
    let n = t_s.len();
    let s = |i: u8| &signals[i as usize];
    let to64 = |v: &[f32]| v.iter().map(|x| f64::from(*x)).collect::<Vec<f64>>();
    let lp = LowPass1::new(cfg.dob.cutoff_rad_s, cfg.period_s());
    problem.signal_names = SIGNAL_NAMES.iter().map(|s| (*s).to_owned()).collect();
    problem.term_dt_s = Some(cfg.period_s());
    // A reference column at the log's own rows (NaN at filled ticks),
    // warned about when the log does not measure it everywhere.
    let need = |name: &str, what: &str| -> Result<Vec<f64>> {
        let on_rows = log.col(name).with_context(|| {
            format!(
                "{}: the {} model needs the column `{name}` ({what})",
                nl.name,
                kind.name()
            )
        })?;
        warn_unmeasured(&nl.name, name, on_rows);
        at_log_rows(&replay, name)
    };
    // The observer check's derivatives (`select::unfiltered_gains`): the
    // core's grating observer without its phase, for the JAE's linear
    // terms also at a tenth of the rate (what `Config::at_rate` derives)
    // where that is wider than the core's (a noisier regressor costs the
    // fit a little; motion above the core's band is what a term may stand
    // in for).
    let core_hz = cfg.differentiators.grating_bandwidth_hz;
    let grating_observer = TrackingObserver::new(core_hz, cfg.period_s());
    let wideband = TrackingObserver::new(
        core_hz.max(DERIVED_BANDWIDTH_PER_RATE / cfg.period_s()),
        cfg.period_s(),
    );
    let (mut target, fixed, mut baseline, mut unfiltered_baseline, names) = match kind {
        ModelKind::Jae => {
            let target = need("theta_rad", "the magnetic encoder of a calibration run")?;
            let sign = held_sign_travelled(
                &to64(s(sig::X2_VEL_M_S)),
                &to64(s(sig::X2_M)),
                cfg.jae.sign_switch_m_s,
                cfg.jae.sign_travel_m,
            );
            let jae_baseline = |acc: Vec<f64>, vel: Vec<f64>, sign: Vec<f64>| {
                vec![acc, vel, sign, to64(s(sig::X2_M)), vec![1.0; n]]
            };
            let unfiltered = zero_phase_kinematics(&wideband, s(sig::X2_M));
            let unfiltered_baseline = unfiltered.map_or_else(Vec::new, |(vel, acc)| {
                let sign = held_sign_travelled(
                    &vel,
                    &to64(s(sig::X2_M)),
                    cfg.jae.sign_switch_m_s,
                    cfg.jae.sign_travel_m,
                );
                jae_baseline(acc, vel, sign)
            });
            (
                target,
                vec![0.0; n],
                jae_baseline(to64(s(sig::X2_ACC_M_S2)), to64(s(sig::X2_VEL_M_S)), sign),
                unfiltered_baseline,
                ["x2_acc_m_s2", "x2_vel_m_s", "sgn(x2_vel)", "x2_m", "offset"],
            )
        }
        ModelKind::Tension => {
            let mut target = at_log_rows(&replay, "tension1_hat_n")?;
            take_out_known_load(&nl.name, d, &cfg, lp, &mut target);
            let tension_baseline = |s1: Vec<f64>, s2: Vec<f64>| {
                vec![
                    low_pass_column(lp, &s1),
                    low_pass_column(lp, &s2),
                    low_pass_column(lp, s(sig::X2_M)),
                    vec![1.0; n],
                ]
            };
            let signs = |x1_vel: &[f32], x2_vel: &[f32]| {
                (
                    held_sign(x1_vel.iter().copied(), cfg.tension.sign_switch_x1_m_s),
                    held_sign(x2_vel.iter().copied(), cfg.tension.sign_switch_x2_m_s),
                )
            };
            let (s1, s2) = signs(s(sig::X1_VEL_M_S), s(sig::X2_VEL_M_S));
            // The signs' velocities without the observer's lag but at its
            // bandwidth: the switch speeds are set for its noise, and a wider
            // band would chatter the signs at rest.
            let unlagged = |i: u8| zero_phase_kinematics(&grating_observer, s(i));
            let unfiltered_baseline = match (unlagged(sig::X1_M), unlagged(sig::X2_M)) {
                (Some((v1, _)), Some((v2, _))) => {
                    let to32 = |v: Vec<f64>| v.into_iter().map(|x| x as f32).collect::<Vec<f32>>();
                    let (s1, s2) = signs(&to32(v1), &to32(v2));
                    tension_baseline(s1, s2)
                }
                _ => Vec::new(),
            };
            problem.prefilter = Some(lp);
            (
                target,
                vec![0.0; n],
                tension_baseline(s1, s2),
                unfiltered_baseline,
                ["Q[sgn(x1_vel)]", "Q[sgn(x2_vel)]", "Q[x2_m]", "F_0", ""],
            )
        }
        ModelKind::Force => {
            let target = need("f_ext_n", "a reference force")?;
            let fixed = d.col_required("f_ext_hat_n")?.to_vec();
            problem.prefilter = Some(lp);
            (target, fixed, Vec::new(), Vec::new(), ["", "", "", "", ""])
        }
        ModelKind::Generic { .. } => bail!("internal: generic model in core_run"),
    };
    drop_faulted_rows(&nl.name, &replay, &mut target);
    problem.baseline_names = names
        .iter()
        .take(baseline.len())
        .map(|s| (*s).to_owned())
        .collect();
    if keep_added {
        let declared = baseline.len();
        keep_added_terms(kind, &cfg, &signals, &t_s, &mut baseline, problem);
        // The kept terms read the core's own signals in either baseline.
        if !unfiltered_baseline.is_empty() {
            unfiltered_baseline.extend(baseline[declared..].iter().cloned());
        }
    }
    Ok((
        RunData {
            name: nl.name.clone(),
            t_s,
            target,
            fixed,
            baseline,
            unfiltered_baseline,
            signals,
            fit_rows: 0..0,
            val_rows: 0..0,
            test_rows: 0..0,
            source_row: replay.source_row,
        },
        cfg,
    ))
}

/// Ticks the replay flags as faulted are neither fitted nor judged: their
/// target becomes NaN, with one warning naming the first fault.
fn drop_faulted_rows(name: &str, replay: &TickReplay, target: &mut [f64]) {
    let d = &replay.log;
    let (Some(fault), Ok(t_s)) = (d.col("fault_code"), d.time_s()) else {
        return;
    };
    if let Some(k) = fault.iter().position(|f| *f != 0.0) {
        let code = fault[k] as u8;
        let what = crate::ingest::fault_words(code);
        let rows = |faulted: bool| {
            (0..fault.len())
                .filter(|&j| replay.measured(j) && (!faulted || fault[j] != 0.0))
                .count()
        };
        eprintln!(
            "warning: {name}: the replay latched {what} at line {} (t = {:.4} s): {} of {} rows \
             are neither fitted nor judged",
            crate::log::line_of_row(replay.log_row(k)),
            t_s[k],
            rows(true),
            rows(false)
        );
    }
    for (y, f) in target.iter_mut().zip(fault) {
        if *f != 0.0 {
            *y = f64::NAN;
        }
    }
}

/// `--keep-added`: the configuration's terms already in the model become
/// baseline columns (the tension's through the DOB's `Q`), so the loop
/// continues from them.
fn keep_added_terms(
    kind: &ModelKind,
    cfg: &Config,
    signals: &[Vec<f32>],
    t_s: &[f64],
    baseline: &mut Vec<Vec<f64>>,
    problem: &mut Problem,
) {
    let lp = LowPass1::new(cfg.dob.cutoff_rad_s, cfg.period_s());
    let (added, prefilter) = match kind {
        ModelKind::Jae => (cfg.jae.added, None),
        ModelKind::Tension => (cfg.tension.added, Some(lp)),
        // The force estimate already contains config.tension.added.
        _ => (Default::default(), None),
    };
    for t in added.active() {
        baseline.push(term_column(
            t,
            signals,
            t_s,
            Some(cfg.period_s()),
            prefilter,
        ));
        problem
            .baseline_names
            .push(term_label(t, &problem.signal_names));
    }
    problem.kept = added.active().to_vec();
}

/// A run with a known tip load (a reference force `f_ext_n`, not zero
/// everywhere: weights hung on the tip, a force sensor) validates the
/// no-load tension model too: the load adds `f_ext l_e / r` to cable 1's
/// tension (the inverse of the DOB's force, `(F_1_hat - Q[F_1']) r /
/// l_e`), so the target becomes the DOB's tension less `Q[f_ext] l_e / r`,
/// through the observer's low-pass like every column. A term that reads
/// the load as a change of the model (a stiffness on `x1`, which the load
/// stretches) then shows on such a run as the harm it does.
fn take_out_known_load(name: &str, log: &Log, cfg: &Config, lp: LowPass1, target: &mut [f64]) {
    let Some(force) = log.col("f_ext_n") else {
        return;
    };
    if !force.iter().any(|f| f.is_finite() && *f != 0.0) {
        return;
    }
    let m = &cfg.machine;
    let tension_per_tip = f64::from(m.gripper_length_m / m.pulley_radius_m);
    let finite: Vec<f64> = force
        .iter()
        .map(|f| if f.is_finite() { *f } else { 0.0 })
        .collect();
    for (t, q) in target.iter_mut().zip(low_pass_column(lp, &finite)) {
        *t -= q * tension_per_tip;
    }
    let peak = finite.iter().fold(0.0f64, |a, f| a.max(f.abs()));
    eprintln!(
        "note: {name}: the reference force f_ext_n (up to {peak:.2} N at the tip) is taken out of \
         the tension target, {tension_per_tip:.2} N of cable 1 per N: a loaded run judges the no-load model"
    );
}

/// Warns on stderr when a column (the target or an input) is not measured
/// (or not finite) on some rows: those rows are neither fitted nor judged.
pub(super) fn warn_unmeasured(log: &str, column: &str, target: &[f64]) {
    if let Some(k) = target.iter().position(|v| !v.is_finite()) {
        eprintln!(
            "warning: {log}: column {column} is not measured on {} of {} rows (first at line {}): \
             those rows are neither fitted nor judged",
            target.iter().filter(|v| !v.is_finite()).count(),
            target.len(),
            crate::log::line_of_row(k)
        );
    }
}
