//! `host-sim identify`: arguments, the run over the logs it names, and the
//! printed report.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use cable_joint::Config;
use serde::Serialize;

use crate::cli;
use crate::ident::{
    calibrate_weights, identify_in_order, parse_reference_steps, set_reference_steps, FitReport,
    IdentOptions, IdentifyReport, Runs, WeightsFit, WeightsOptions,
};
use crate::io::config::stage_config;
use crate::log::Log;
use crate::output::Outputs;
use crate::stats::ErrorStats;

/// What `host-sim identify` identifies.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Procedure {
    /// Motor damping `B_m` from a no-load motor run.
    Bm,
    /// Joint-angle estimator from a run with the magnetic encoder.
    Jae,
    /// Tension models A, B, C and the simplified model C.
    Tension,
    /// All three, in that order (each uses the previous results).
    All,
    /// The stretch estimate's force scale from holds with known weights at
    /// the tip (the reference force in `f_ext_n`), after `all`.
    Weights,
}

/// Arguments of `host-sim identify`.
#[derive(clap::Args, Debug, Clone)]
pub struct IdentifyArgs {
    /// Which model(s) to identify.
    #[arg(long, value_enum)]
    pub procedure: Procedure,
    /// Logs to fit (CSV). With `all`: three logs in the order bm, jae,
    /// tension, or any number as `bm=FILE`, `jae=FILE`, `tension=FILE`
    /// (`bm=` may be left out: `B_m` then stays the configuration's). With
    /// `weights`: logs with the reference force in `f_ext_n`, or
    /// `FILE@T0=F0,T1=F1,...` giving it as steps (force F_k N from the
    /// log's time T_k s).
    #[arg(long, num_args = 1.., required = true)]
    pub log: Vec<String>,
    /// Logs to validate on (not used for the fit); same form as `--log`.
    #[arg(long, num_args = 1..)]
    pub validate: Vec<String>,
    /// Configuration to start from (TOML; default: the datasheet values).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Where to write the configuration with the identified parameters.
    #[arg(long)]
    pub config_out: PathBuf,
    /// Also write every result as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Leading seconds of each log left out (observer start-up).
    #[arg(allow_negative_numbers = true, long, default_value_t = IdentOptions::default().skip_start_s,
          value_parser = cli::f64_in(0.0, 1e6))]
    pub skip_start_s: f64,
    /// Tension fits: leave out ticks with |theta'| below this, rad/s (0: keep all).
    #[arg(allow_negative_numbers = true, long, default_value_t = IdentOptions::default().min_joint_vel_rad_s,
          value_parser = cli::f64_in(0.0, 1e3))]
    pub min_joint_vel_rad_s: f64,
    /// Tension fits: also leave out this long after the joint was still, s.
    #[arg(allow_negative_numbers = true, long, default_value_t = IdentOptions::default().holdoff_s,
          value_parser = cli::f64_in(0.0, 1e6))]
    pub holdoff_s: f64,
    /// Weights: relative tolerance of the reference force itself (the
    /// weights' mass and the lever arm they hang at).
    #[arg(allow_negative_numbers = true, long, default_value_t = WeightsOptions::default().reference_tolerance,
          value_parser = cli::f64_in(0.0, 1.0))]
    pub reference_tolerance: f64,
    /// Weights: time after the reference settled before a hold's rows count, s.
    #[arg(allow_negative_numbers = true, long, default_value_t = WeightsOptions::default().settle_s,
          value_parser = cli::f64_in(0.0, 1e6))]
    pub settle_s: f64,
    /// Do not pass the regressors through the DOB's low-pass (the seed's plain fit).
    #[arg(long)]
    pub no_filter: bool,
    /// Pruning limit on %sigma, %.
    #[arg(allow_negative_numbers = true, long, default_value_t = IdentOptions::default().max_pct_sigma,
          value_parser = cli::f64_above(0.0, 1e6))]
    pub max_pct_sigma: f64,
    /// Prune as the seed did: every parameter above the limit at once.
    #[arg(long)]
    pub prune_all_at_once: bool,
    /// DOB-based fits: extra low-pass on both sides, Hz (0: none).
    #[arg(allow_negative_numbers = true, long, default_value_t = IdentOptions::default().post_filter_hz,
          value_parser = cli::f64_in(0.0, 1e4))]
    pub post_filter_hz: f64,
    /// Fit B_m without the Coulomb term sgn(phi') (the seed's model).
    #[arg(long)]
    pub bm_no_coulomb: bool,
    /// Every log has a row every N control ticks but no `tick` column (a
    /// logger other than the firmware's link): the control period is the
    /// median time step over N (as `estimate --ticks-per-row`).
    #[arg(long, value_name = "N")]
    pub ticks_per_row: Option<u32>,
}

/// Split `--log`/`--validate` arguments by procedure.
fn assign(files: &[String], procedure: Procedure) -> Result<Vec<(Procedure, PathBuf)>> {
    let order = [Procedure::Bm, Procedure::Jae, Procedure::Tension];
    let tagged = |s: &str| -> Option<(Procedure, PathBuf)> {
        let (tag, file) = s.split_once('=')?;
        let p = match tag {
            "bm" => Procedure::Bm,
            "jae" => Procedure::Jae,
            "tension" => Procedure::Tension,
            "weights" => Procedure::Weights,
            _ => return None,
        };
        Some((p, PathBuf::from(file)))
    };
    let mut out = Vec::new();
    let untagged: Vec<&String> = files.iter().filter(|s| tagged(s).is_none()).collect();
    if procedure == Procedure::All && !untagged.is_empty() {
        if untagged.len() != files.len() || files.len() != 3 {
            bail!(
                "with --procedure all give three logs in the order bm, jae, tension, \
                 or tag each one: bm=FILE jae=FILE tension=FILE"
            );
        }
        for (p, f) in order.iter().zip(files) {
            out.push((*p, PathBuf::from(f)));
        }
        return Ok(out);
    }
    for f in files {
        match tagged(f) {
            Some((p, path)) => {
                if path.as_os_str().is_empty() {
                    bail!("`{f}` names no file: tag a log as TAG=FILE");
                }
                if procedure != Procedure::All && p != procedure {
                    bail!(
                        "`{f}` is tagged for another procedure than {}",
                        crate::cli::value_name(&procedure)
                    );
                }
                out.push((p, path));
            }
            None => out.push((procedure, PathBuf::from(f))),
        }
    }
    Ok(out)
}

fn read_logs(
    files: &[(Procedure, PathBuf)],
    p: Procedure,
    ticks_per_row: Option<u32>,
) -> Result<Vec<(String, Log)>> {
    files
        .iter()
        .filter(|(q, _)| *q == p)
        .map(|(_, f)| Ok((f.display().to_string(), read_replay(f, ticks_per_row)?)))
        .collect()
}

/// One log as `identify` replays it: from the end of homing to the first
/// latched fault.
fn read_replay(path: &std::path::Path, ticks_per_row: Option<u32>) -> Result<Log> {
    crate::ingest::read_for_replay(
        path,
        ticks_per_row,
        "identify",
        crate::ingest::ReplayEnd::BeforeFault,
    )
}

/// A weights argument's file and its reference steps, if it has them
/// (`FILE@T0=F0,T1=F1,...`).
fn file_and_steps(arg: &Path) -> (PathBuf, Option<String>) {
    let text = arg.display().to_string();
    match text.rsplit_once('@') {
        Some((path, spec)) if spec.contains('=') => (PathBuf::from(path), Some(spec.to_owned())),
        _ => (arg.to_path_buf(), None),
    }
}

/// The weights procedure's logs, each `FILE` with its own `f_ext_n` or
/// `FILE@T0=F0,T1=F1,...` with the reference force as steps by the log's
/// time (a rig's recording, which has none). A step's force is checked
/// as a log's reference is ([`crate::estimate::reference_force_refusal`]),
/// naming the argument it came from.
fn read_weight_logs(
    files: &[(Procedure, PathBuf)],
    ticks_per_row: Option<u32>,
    machine: &cable_joint::config::Machine,
) -> Result<Vec<(String, Log)>> {
    let mut out = Vec::new();
    for (_, arg) in files.iter().filter(|(q, _)| *q == Procedure::Weights) {
        let (path, spec) = file_and_steps(arg);
        let steps = spec.as_deref().map(parse_reference_steps).transpose()?;
        for &(t_s, f_n) in steps.iter().flatten() {
            if let Some(why) = crate::estimate::reference_force_refusal(f_n, machine) {
                bail!(
                    "`{}`: the reference step `{t_s}={}` {why}; the steps are forces in N",
                    arg.display(),
                    crate::log::value_text(f_n)
                );
            }
        }
        let mut log = read_replay(&path, ticks_per_row)?;
        let label = path.display().to_string();
        if let Some(steps) = steps {
            set_reference_steps(&mut log, &steps, &label)?;
        }
        out.push((label, log));
    }
    Ok(out)
}

fn refs(logs: &[(String, Log)]) -> Vec<(&str, &Log)> {
    logs.iter().map(|(l, g)| (l.as_str(), g)).collect()
}

/// Run the identification(s) the arguments ask for; returns the report and
/// the configuration with the results applied.
pub fn identify(args: &IdentifyArgs) -> Result<(IdentifyReport, Config)> {
    let opts = IdentOptions {
        skip_start_s: args.skip_start_s,
        min_joint_vel_rad_s: args.min_joint_vel_rad_s,
        holdoff_s: args.holdoff_s,
        filter_regressors: !args.no_filter,
        max_pct_sigma: args.max_pct_sigma,
        prune_all_at_once: args.prune_all_at_once,
        post_filter_hz: args.post_filter_hz,
        bm_coulomb: !args.bm_no_coulomb,
        ..IdentOptions::default()
    };
    opts.check()?;
    let config = crate::io::config::load_or_default(args.config.as_deref())?;
    let fits = assign(&args.log, args.procedure)?;
    let vals = assign(&args.validate, args.procedure)?;
    // Per model: a log fitted for one may validate another. A weights
    // log's reference steps (`FILE@T0=F0,...`) do not make it another
    // recording.
    for q in [
        Procedure::Bm,
        Procedure::Jae,
        Procedure::Tension,
        Procedure::Weights,
    ] {
        let files = |v: &[(Procedure, PathBuf)]| -> Vec<PathBuf> {
            v.iter()
                .filter(|(p, _)| *p == q)
                .map(|(_, f)| file_and_steps(f).0)
                .collect()
        };
        let (fit_files, val_files) = (files(&fits), files(&vals));
        super::refuse_reused_files(&fit_files, &val_files, &[])?;
    }
    if args.procedure == Procedure::Weights {
        let wopts = WeightsOptions {
            settle_s: args.settle_s,
            reference_tolerance: args.reference_tolerance,
            ..WeightsOptions::default()
        };
        let (fit, val) = (
            read_weight_logs(&fits, args.ticks_per_row, &config.machine)?,
            read_weight_logs(&vals, args.ticks_per_row, &config.machine)?,
        );
        let (w, calibrated) = calibrate_weights(&refs(&fit), &refs(&val), &config, &wopts)?;
        let rep = IdentifyReport {
            weights: Some(w),
            ..IdentifyReport::default()
        };
        return Ok((rep, calibrated));
    }
    if let Some((_, f)) = fits
        .iter()
        .chain(&vals)
        .find(|(p, _)| *p == Procedure::Weights)
    {
        bail!(
            "`{}` is tagged weights=: the weights calibration runs on its own, after \
             the other procedures (--procedure weights --config <their output>)",
            f.display()
        );
    }
    let wants = |p: Procedure| args.procedure == p || args.procedure == Procedure::All;
    // Every log is read before the first fit: a bad file fails fast.
    let mut read = Vec::new();
    for p in [Procedure::Bm, Procedure::Jae, Procedure::Tension] {
        if !wants(p) {
            continue;
        }
        let logs = read_logs(&fits, p, args.ticks_per_row)?;
        if logs.is_empty() && p == Procedure::Bm && args.procedure == Procedure::All {
            // The seed's no-load motor run needs the rope wheel unhooked;
            // a user may not have one.
            if vals.iter().any(|(q, _)| *q == Procedure::Bm) {
                bail!("a bm= log to validate on, but no bm= log to fit B_m on");
            }
            eprintln!(
                "note: no bm= log: B_m is not identified, and the configuration's \
                 dob.viscous_nm_s_rad = {:e} N·m·s/rad is kept (it enters the DOB as B_m phi', \
                 in motion and not at a hold)",
                config.dob.viscous_nm_s_rad
            );
            continue;
        }
        if logs.is_empty() {
            bail!("no log for the {} procedure", crate::cli::value_name(&p));
        }
        let val_logs = read_logs(&vals, p, args.ticks_per_row)?;
        // One run under two names passes the path checks; its data do not.
        fn named(v: &[(String, Log)]) -> Vec<(&str, &Log)> {
            v.iter().map(|(n, l)| (n.as_str(), l)).collect()
        }
        super::refuse_copies(&named(&logs), &named(&val_logs), &[])?;
        read.push((p, logs, val_logs));
    }
    let config = at_the_logs_rate(config, read.iter().flat_map(|(_, f, v)| f.iter().chain(v)))?;
    let runs = |p: Procedure| {
        read.iter().find(|(q, _, _)| *q == p).map(|(_, f, v)| Runs {
            fit: refs(f),
            validate: refs(v),
        })
    };
    identify_in_order(
        runs(Procedure::Bm).as_ref(),
        runs(Procedure::Jae).as_ref(),
        runs(Procedure::Tension).as_ref(),
        config,
        &opts,
    )
}

/// `config` at the control rate the logs were recorded at, so that the
/// configuration written is one the board that recorded them takes (its
/// firmware refuses another rate): where every log runs at one rate (within
/// 1 %) and the configuration's is another, the configuration is moved to
/// it (as the replay does, `derive::config_at_clock`, a note for each
/// setting derived); logs at
/// different rates keep the configuration's, with a warning.
fn at_the_logs_rate<'a>(
    config: Config,
    logs: impl IntoIterator<Item = &'a (String, Log)>,
) -> Result<Config> {
    let mut clocks: Vec<(&str, crate::derive::Clock)> = Vec::new();
    for (name, log) in logs {
        let clock =
            crate::derive::log_clock(log).with_context(|| format!("the control rate of {name}"))?;
        clocks.push((name.as_str(), clock));
    }
    let Some((first, clock)) = clocks.first() else {
        return Ok(config);
    };
    let rate_hz = clock.rate_hz();
    let same = |r: f64| (r - rate_hz).abs() <= 0.01 * rate_hz;
    if let Some((other, c)) = clocks.iter().find(|(_, c)| !same(c.rate_hz())) {
        eprintln!(
            "warning: the logs run at different control rates ({first} at {rate_hz:.1} Hz, \
             {other} at {:.1} Hz): the configuration written keeps control_rate_hz = {}",
            c.rate_hz(),
            config.control_rate_hz
        );
        return Ok(config);
    }
    let given_hz = f64::from(config.control_rate_hz);
    if same(given_hz) {
        return Ok(config);
    }
    let (moved, notes) = crate::derive::config_at_clock(clock, &config)?;
    let hint = if clock.from_ticks {
        None
    } else {
        crate::io::config::ticks_per_row_hint(given_hz, rate_hz)
    };
    eprintln!(
        "note: the logs run at {rate_hz:.1} Hz: the configuration written is for that rate \
         (control_rate_hz = {}, not {given_hz}; the board that recorded them refuses another){}",
        moved.control_rate_hz,
        hint.map_or_else(String::new, |h| format!("; {h}"))
    );
    for n in notes {
        eprintln!("note: {n}");
    }
    Ok(moved)
}

fn fmt_num(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        format!("{v}")
    } else if (1e-3..1e5).contains(&v.abs()) {
        format!("{v:.5}")
    } else {
        format!("{v:.4e}")
    }
}

fn fmt_pct(p: f64) -> String {
    if p.is_finite() {
        format!("{p:.3} %")
    } else {
        "inf".to_owned()
    }
}

/// A fit as a readable table.
pub fn format_fit(f: &FitReport) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{}: {} rows, residual std {}, condition {:.3e}, residual correlation {:.0} ticks",
        f.model,
        f.rows,
        fmt_num(f.sigma),
        f.condition,
        f.residual_corr_ticks
    );
    let _ = writeln!(
        s,
        "  {:<12} {:<9} {:>13} {:>12} {:>11} {:>11}  unit",
        "regressor", "parameter", "value", "std", "%sigma", "%sigma eff"
    );
    for p in &f.params {
        let _ = writeln!(
            s,
            "  {:<12} {:<9} {:>13} {:>12} {:>11} {:>11}  {}",
            p.symbol,
            p.name,
            fmt_num(p.value),
            fmt_num(p.std),
            fmt_pct(p.pct_sigma),
            fmt_pct(p.pct_sigma_eff),
            p.unit
        );
    }
    let _ = writeln!(s, "  errors: {}", format_stats(&f.errors));
    s
}

/// Error statistics in one line.
pub fn format_stats(e: &ErrorStats) -> String {
    format!(
        "n {}, mean {} {u}, mean|e| {} {u}, max {} {u}, min {} {u}, RMSE {} {u}",
        e.n,
        fmt_num(e.mean),
        fmt_num(e.mean_abs),
        fmt_num(e.max),
        fmt_num(e.min),
        fmt_num(e.rmse),
        u = e.unit
    )
}

/// The weights calibration as text: the scale, what it wrote, and every
/// hold before and after.
fn format_weights(w: &WeightsFit) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "force scale from known weights ({} holds, {} logs fitted): the stretch estimate changes by {:.4} N per newton of reference (%sigma {:.2})",
        w.holds.iter().filter(|h| h.fitted).count(),
        w.logs_fitted,
        w.scale.0,
        w.scale.1
    );
    if w.disagreement > 1.0 {
        let _ = writeln!(
            s,
            "  warning: the weights' scale and the configuration's (1 within its tolerance {:.3}) disagree by {:.1} times what both tolerances allow: one of them is off by more than it says (the weights' mass or lever arm, or the identification's spring rate); the tolerance written is widened by that ratio",
            w.stiffness_tolerance.0,
            w.disagreement
        );
    }
    let _ = writeln!(
        s,
        "  -> machine.spring_n_m {:.1} -> {:.1} N/m, the stretch cables' stiffnesses with it; \
         fusion.stiffness_tolerance {:.3} -> {:.3}; {}",
        w.spring_n_m.0,
        w.spring_n_m.1,
        w.stiffness_tolerance.0,
        w.stiffness_tolerance.1,
        w.pin_coulomb_nm.map_or_else(
            || "fusion.pin_coulomb_nm kept (model C's upper bound, not a fitted level)".to_owned(),
            |(before, after)| format!(
                "fusion.pin_coulomb_nm {before:.5} -> {after:.5} N·m (fitted through the same \
                 spring rate, so on the same scale)"
            )
        ),
    );
    let validation = if w.validation_error_n.0.is_nan() {
        "no validation log with a change of load".to_owned()
    } else {
        format!(
            "validation {:.4} -> {:.4} N",
            w.validation_error_n.0, w.validation_error_n.1
        )
    };
    let _ = writeln!(
        s,
        "  the stretch estimate's change less the reference's, RMS over the holds (each log about its own zero): fitted {:.4} -> {:.4} N, {validation}",
        w.fit_error_n.0, w.fit_error_n.1
    );
    let _ = writeln!(
        s,
        "  {:<28} {:>6} {:>15} {:>10} {:>20} {:>20}",
        "log", "set", "settled, s", "ref, N", "stretch before/after", "fused before/after"
    );
    for h in &w.holds {
        let _ = writeln!(
            s,
            "  {:<28} {:>6} {:>7.1}-{:<7.1} {:>10.3} {:>9.3} {:>10.3} {:>9.3} {:>10.3}",
            h.log,
            if h.fitted { "fit" } else { "valid." },
            h.t_s.0,
            h.t_s.1,
            h.reference_n,
            h.stretch_before_n,
            h.stretch_after_n,
            h.fused_before_n,
            h.fused_after_n
        );
    }
    for u in &w.unmatched {
        let _ = writeln!(s, "  {u}");
    }
    s
}

/// The whole report as text.
pub fn format_report(r: &IdentifyReport) -> String {
    let mut s = String::new();
    if let Some(w) = &r.weights {
        s.push_str(&format_weights(w));
    }
    if let Some(b) = &r.bm {
        s.push_str(&format_fit(&b.fit));
        if let Some(p) = b.coulomb_dropped_pct_sigma {
            let _ = writeln!(
                s,
                "  Coulomb term sgn(phi') dropped (%sigma {})",
                fmt_pct(p)
            );
        }
        let _ = writeln!(
            s,
            "  -> dob.viscous_nm_s_rad = {:e} (seed: 1.6934e-5)\n",
            b.b_m_nm_s_rad
        );
    }
    if let Some(j) = &r.jae {
        s.push_str(&format_fit(&j.fit));
        let _ = writeln!(s, "  identification error: {}", format_stats(&j.error_deg));
        let _ = writeln!(
            s,
            "  -> jae: chi_s = [{}, {}, {}, {}], offset {} rad (seed: [0.0805, 0.5225, 0.0025, 264.356], error mean 0.275°, max 0.836°)",
            fmt_num(j.chi_s[0]),
            fmt_num(j.chi_s[1]),
            fmt_num(j.chi_s[2]),
            fmt_num(j.chi_s[3]),
            fmt_num(j.offset_rad)
        );
        let c3_std = j.sign_term_std_eff_rad();
        let _ = writeln!(
            s,
            "  -> fusion.jae_error_rad: 2 RMS of the residual ({} rad) plus 2 (1 + fusion.static_over_kinetic) times the sign term's effective std ({} rad){}\n",
            fmt_num(2.0 * j.error_deg.rmse.to_radians()),
            fmt_num(c3_std),
            if j.sign_term_identified() {
                String::new()
            } else {
                format!(
                    ". This run does not identify slider 2's sign term: c3 = {} rad with an effective std of {} rad; \
                     the force bound widens by its uncertainty. Sweeps at several speeds, or longer holds between \
                     reversals, separate c3 from the viscous c2",
                    fmt_num(j.chi_s[2]),
                    fmt_num(c3_std)
                )
            }
        );
        let sp = &j.spring;
        let _ = writeln!(
            s,
            "spring rate through the motor ({} sweeps, {} ticks, {}): K_s {} N/m (%sigma {:.1}), residual rms {} N\n  -> {}",
            sp.sweeps,
            sp.rows,
            if sp.per_tick {
                "per tick"
            } else {
                "one row per sweep"
            },
            fmt_num(sp.k_s_n_m.0),
            sp.k_s_n_m.1,
            fmt_num(sp.residual_rms_n),
            sp.note
        );
        let [tol, tol_spring, tol_c2] = j.stiffness_tolerance;
        let floor = if tol > tol_spring + tol_c2 {
            " (at least the configuration's tolerance, the datasheet's or an earlier \
             identification's, with its spring rate kept)"
        } else {
            ""
        };
        let _ = writeln!(
            s,
            "  -> fusion.stiffness_tolerance = {tol:.3}: the spring rate's relative uncertainty {tol_spring:.3} plus cable 2's ({}), {tol_c2:.3}{floor}",
            if j.joint.cable2.measured() { "its slipping fit, at least the fit's measured systematic error" } else { "c4's through c4 r - 1" }
        );
        let jf = &j.joint;
        let c2 = &jf.cable2;
        let _ = writeln!(
            s,
            "cable 2 stiffness ({}): K_w2 {} N/m (%sigma eff {:.2}); K_s / (c4 r - 1) = {} N/m, kept for the firmware's cable-2 term on theta_hat",
            c2.method,
            fmt_num(c2.k_w2_n_m.0),
            c2.k_w2_n_m.1,
            fmt_num(c2.k_w2_from_c4_n_m),
        );
        let _ = writeln!(
            s,
            "joint torque balance ({} rows, joint slipping; {}): K_w2 {} N/m, K_w1 {} N/m (%sigma {:.1}), pin friction {} N·m (%sigma {:.1}), residual rms {} N·m\n  -> {}\n",
            jf.rows,
            jf.method,
            fmt_num(c2.k_w2_n_m.0),
            fmt_num(jf.k_w1_n_m.0),
            jf.k_w1_n_m.1,
            fmt_num(jf.pin_coulomb_nm.0),
            jf.pin_coulomb_nm.1,
            fmt_num(jf.residual_rms_nm),
            jf.note
        );
    }
    if let Some(t) = &r.tension {
        let _ = writeln!(
            s,
            "tension models: theta from {}, DOB with B_m = {:e} N·m·s/rad",
            t.theta_source, t.b_m_used_nm_s_rad
        );
        for m in [&t.model_a, &t.model_b] {
            match m {
                Ok(f) => s.push_str(&format_fit(f)),
                Err(e) => {
                    let _ = writeln!(s, "  not fitted: {e}");
                }
            }
        }
        s.push_str(&format_fit(&t.model_c));
        let dropped: Vec<String> = t
            .dropped
            .iter()
            .map(|(r, p)| format!("{} ({})", r.symbol(), fmt_pct(*p)))
            .collect();
        let _ = writeln!(s, "pruned (%sigma above the limit): {}", dropped.join(", "));
        s.push_str(&format_fit(&t.simplified));
        if !t.not_written.is_empty() {
            let nw: Vec<&str> = t.not_written.iter().map(|r| r.symbol()).collect();
            let _ = writeln!(
                s,
                "  kept terms the core's model does not evaluate (not written): {}",
                nw.join(", ")
            );
            s.push_str(&format_fit(&t.core));
        }
        let _ = writeln!(
            s,
            "  {}: chi_p = [f_sc1 {}, f_cp2 {}, K_s {}, F_0 {}] (seed: [3.879, 5.027, 707.7, 19.52])\n",
            if t.why_not_written().is_some() {
                "fitted, not written (see the warning below)"
            } else {
                "-> tension"
            },
            fmt_num(t.chi_p[0]),
            fmt_num(t.chi_p[1]),
            fmt_num(t.chi_p[2]),
            fmt_num(t.chi_p[3])
        );
        match &t.cable0 {
            Ok(k) => {
                let _ = writeln!(
                    s,
                    "  -> stretch.cable0_n_m = {:.0} (standard error {:.0}, {:.0} % of it): cable \
                     0's stiffness over {} stretches ({} rows, {:.2} s) where slider 1 stood still \
                     and the motor turned one way (the cable-0 slack check's reach; more reversals \
                     in the tension run narrow it)\n",
                    k.n_m,
                    k.std_error_n_m,
                    100.0 * k.std_error_n_m / k.n_m,
                    k.stretches,
                    k.rows,
                    k.seconds
                );
            }
            Err(why) => {
                let _ = writeln!(
                    s,
                    "  note: cable 0's stiffness not read ({why}); stretch.cable0_n_m = 0, so the \
                     cable-0 slack check takes cable 1's stiffness as its bound (a value the \
                     configuration held from another run is not kept)\n"
                );
            }
        }
        if let Some(note) = &t.slider2_at_zero {
            let _ = writeln!(s, "  note: {note}\n");
        }
        if let Some(why) = t.why_not_written() {
            let _ = writeln!(s, "  warning: {why}\n");
        }
        if t.derivative_from_observer {
            let _ = writeln!(
                s,
                "  -> cascade.kd_on_observer_rate = true: the current changed by {:.3} A per tick, \
                 a limit cycle of the position loop's derivative; record tension-ident again with \
                 the configuration written and identify the tension models from that run\n",
                t.current_change_per_tick_a.unwrap_or(f64::NAN)
            );
        }
    }
    if !r.validation.is_empty() {
        let _ = writeln!(
            s,
            "validation (model - measured, data not used for the fit):"
        );
        for v in &r.validation {
            let _ = writeln!(s, "  {} on {}: {}", v.model, v.log, format_stats(&v.errors));
        }
    }
    s
}

/// Run the subcommand.
pub fn run(args: IdentifyArgs) -> Result<()> {
    let (rep, config) = identify(&args)?;
    crate::stdout!("{}", format_report(&rep));
    // The configuration and the report are written together, or neither is.
    let mut out = Outputs::new();
    stage_config(&mut out, &args.config_out, &config)?;
    if let Some(p) = &args.json {
        let text = serde_json::to_string_pretty(&rep).context("serializing the report")?;
        out.bytes(p, text.as_bytes())?;
    }
    out.commit()?;
    crate::stdoutln!("configuration written to {}", args.config_out.display());
    let written = args.config_out.display().to_string();
    if let Some(w) = crate::io::config::datasheet_force_warning(&config, &written) {
        eprintln!("{w}");
    }
    if let Some(p) = &args.json {
        crate::stdoutln!("report written to {}", p.display());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn logs_are_assigned_to_procedures() {
        let v = |a: &[&str]| a.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        let a = assign(&v(&["a", "b", "c"]), Procedure::All).unwrap();
        assert_eq!(
            a.iter().map(|(p, _)| *p).collect::<Vec<_>>(),
            vec![Procedure::Bm, Procedure::Jae, Procedure::Tension]
        );
        let a = assign(&v(&["tension=t.csv", "bm=b.csv"]), Procedure::All).unwrap();
        assert_eq!(a[0], (Procedure::Tension, PathBuf::from("t.csv")));
        assert!(assign(&v(&["a", "b"]), Procedure::All).is_err());
        assert!(assign(&v(&["jae=j.csv"]), Procedure::Bm).is_err());
        let a = assign(&v(&["x.csv", "y.csv"]), Procedure::Jae).unwrap();
        assert!(a.iter().all(|(p, _)| *p == Procedure::Jae));
    }
}
