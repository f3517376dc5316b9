//! Printed table, JSON and plots of an [`Analysis`].

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Result;
use cable_joint::effects::Term;
use serde_json::{json, Value};

use super::outcome::{Coef, Diagnostics, Outcome, RunError, Step};
use super::Analysis;
use crate::output::Outputs;
use crate::plot::{stage_figure, Figure, Panel, Series};

/// Display unit of a target by its name's suffix: `(unit, factor from SI)`.
pub fn display_unit(target: &str) -> (&'static str, f64) {
    if target.ends_with("_rad") {
        ("deg", 180.0 / std::f64::consts::PI)
    } else if target.ends_with("_nm") {
        ("mN·m", 1e3)
    } else if target.ends_with("_n") {
        ("N", 1.0)
    } else if target.ends_with("_m") {
        ("µm", 1e6)
    } else if target.ends_with("_a") {
        ("mA", 1e3)
    } else {
        ("", 1.0)
    }
}

/// SI unit of a target by its name's suffix.
pub fn si_unit(target: &str) -> &'static str {
    for (suffix, unit) in [
        ("_rad", "rad"),
        ("_nm", "N·m"),
        ("_n", "N"),
        ("_m", "m"),
        ("_a", "A"),
    ] {
        if target.ends_with(suffix) {
            return unit;
        }
    }
    ""
}

fn baseline_label(a: &Analysis) -> String {
    let kept = a.problem.kept.len();
    let base = baseline_kind_label(a);
    if kept > 0 {
        format!("{base} + the {kept} terms already in the configuration")
    } else {
        base
    }
}

fn baseline_kind_label(a: &Analysis) -> String {
    match a.kind {
        super::ModelKind::Jae => "seed Eq. 26 [x2'', x2', sgn x2', x2] + offset".into(),
        super::ModelKind::Tension => {
            "simplified model C [sgn x1', sgn x2', x2, 1] (through Q)".into()
        }
        super::ModelKind::Force => "DOB estimate f_ext_hat_n".into(),
        super::ModelKind::Generic { .. } => {
            format!(
                "linear in [{}] + constant",
                a.problem.baseline_names[..a.problem.baseline_names.len() - 1].join(", ")
            )
        }
    }
}

/// The kind's parameters as a JSON object (`{}` for kinds without any).
fn params_json(t: &Term) -> Value {
    match serde_json::to_value(t.kind) {
        Ok(Value::Object(m)) => m.into_iter().next().map(|(_, v)| v).unwrap_or(json!({})),
        _ => json!({}),
    }
}

fn signal(a: &Analysis, i: u8) -> Value {
    a.problem
        .signal_names
        .get(i as usize)
        .map(|s| Value::String(s.clone()))
        .unwrap_or(Value::Null)
}

/// A kept term's family as the tables print it: the observer check's
/// renaming with the family of the term's kind beside it.
pub fn class_text(st: &Step) -> String {
    match &st.reclassified_from {
        Some(family) => format!("{} (a {family} term)", st.class),
        None => st.class.clone(),
    }
}

fn step_json(a: &Analysis, s: &Step, coef: Option<&Coef>) -> Value {
    let t = &s.term;
    let last = s.fit.coefs.last();
    let c = coef.or(last);
    json!({
        "name": s.label,
        "kind": t.name(),
        "meaning": s.meaning,
        "signal": if t.kind.uses_input() { signal(a, t.input) } else { Value::Null },
        "aux_signal": if t.kind.uses_aux() { signal(a, t.aux) } else { Value::Null },
        "parameters": params_json(t),
        "term": serde_json::to_value(t).unwrap_or(Value::Null),
        "coef": c.map(|c| c.value),
        "coef_std": c.map(|c| c.std_dev),
        "pct_sigma": c.map(|c| c.pct_sigma),
        "err": s.err,
        "train_rmse": s.fit.train_rmse,
        "val_rmse": s.fit.val_rmse,
        "gain": s.gain,
        "class": s.class,
        "reclassified_from": s.reclassified_from,
        "rival": s.rival,
        "passed_over": s.passed_over,
        "group": s.group,
        "harm": s.harm.as_ref().map(|(run, rise)| json!({ "run": run, "rise": rise })),
        "unfiltered_gain": s.unfiltered_gain,
        "evidence": s.evidence.map(|(before, after)| json!({
            "corr_before": before,
            "corr_after": after,
        })),
    })
}

/// The analysis as JSON: `model`, `target`, `unit`, `before_rmse`,
/// `after_rmse` (validation, SI unit), `baseline`, `effects` (kept, in
/// order: `name`, `kind`, `meaning`, `signal`, `parameters`, `coef`,
/// `val_rmse` after adding it, ...), `set_aside`, `final`, `diagnostics`,
/// `runs`, `test` (with `--test`: the test logs, `before_rmse`,
/// `after_rmse` pooled and `runs`; else null).
pub fn json(a: &Analysis) -> Value {
    let o = &a.outcome;
    let nb = o.baseline.coefs.len();
    let (du, ds) = display_unit(&a.problem.target);
    json!({
        "model": a.kind.name(),
        "target": a.problem.target,
        "unit": si_unit(&a.problem.target),
        "display_unit": du,
        "display_scale": ds,
        "fit_logs": a.fit_logs,
        "validate_logs": a.validate_logs,
        "holdout": a.holdout,
        "settle_s": a.build.settle_s,
        "keep_added": a.build.keep_added,
        "decimate": a.options.decimate,
        "min_gain": a.options.min_gain,
        "other_sensors": a.build.other_sensors,
        "other_sensor_signals": a.problem.other_sensors.iter()
            .map(|&i| signal(a, i))
            .collect::<Vec<_>>(),
        "n_fit": o.n_fit,
        "n_val": o.n_val,
        "n_candidates": o.n_candidates,
        "baseline": {
            "model": baseline_label(a),
            "coefs": o.baseline.coefs,
            "train_rmse": o.baseline.train_rmse,
            "val_rmse": o.baseline.val_rmse,
            "condition": o.baseline.condition,
        },
        "before_rmse": o.baseline.val_rmse,
        "after_rmse": o.final_fit.val_rmse,
        "effects": o.accepted.iter().enumerate()
            .map(|(k, s)| step_json(a, s, o.final_fit.coefs.get(nb + k)))
            .collect::<Vec<_>>(),
        "set_aside": o.rejected.iter().map(|s| step_json(a, s, None)).collect::<Vec<_>>(),
        "final": o.final_fit,
        "diagnostics": { "before": o.before, "after": o.after },
        "runs": o.runs,
        "test": o.test_rmse().map(|(before, after)| json!({
            "logs": a.test_logs,
            "before_rmse": before,
            "after_rmse": after,
            "runs": o.test_runs,
        })),
    })
}

fn diag_rows(out: &mut String, b: &Diagnostics, f: &Diagnostics, scale: f64, unit: &str) {
    let _ = writeln!(
        out,
        "\nresidual diagnostics (validation)      before        after"
    );
    let row = |out: &mut String, name: &str, x: f64, y: f64, u: &str| {
        let _ = writeln!(out, "  {name:<34} {x:>10.4} {y:>12.4} {u}");
    };
    row(out, "RMSE", b.rmse * scale, f.rmse * scale, unit);
    row(out, "mean", b.mean * scale, f.mean * scale, unit);
    row(out, "max |e|", b.max_abs * scale, f.max_abs * scale, unit);
    for ((lag, x), (_, y)) in b.autocorr.iter().zip(&f.autocorr) {
        row(out, &format!("autocorrelation at {lag:.3} s"), *x, *y, "");
    }
    let ct = |c: Option<f64>| c.map(|v| format!("{v:.3} s")).unwrap_or_else(|| "-".into());
    let _ = writeln!(
        out,
        "  {:<34} {:>10} {:>12}",
        "correlation time (acf < 1/e)",
        ct(b.corr_time_s),
        ct(f.corr_time_s)
    );
    for (name, d) in [("before", b), ("after", f)] {
        let _ = writeln!(
            out,
            "  candidates most correlated with the residual {name}:"
        );
        for (l, r) in &d.top_correlations {
            let _ = writeln!(out, "    {r:+.3}  {l}");
        }
    }
}

/// What the analysis was judged on: the held-out part of each fitting log,
/// the validation logs, or both.
pub fn validation_description(a: &Analysis) -> String {
    let held = a
        .holdout
        .map(|h| format!("the last {:.0} % of each fitting log", 100.0 * h));
    match (held, a.validate_logs.is_empty()) {
        (Some(h), true) => h,
        (Some(h), false) => format!("{h} and {}", a.validate_logs.join(", ")),
        (None, _) => a.validate_logs.join(", "),
    }
}

/// The printed table.
pub fn table(a: &Analysis) -> String {
    let o = &a.outcome;
    let (unit, scale) = display_unit(&a.problem.target);
    let mut s = String::new();
    let val = validation_description(a);
    let _ = writeln!(
        s,
        "residual: model {}, target {}\n  fit on: {}\n  validate on: {}{}\n  {} fitting rows, {} validation rows (every {} sample), {} candidate effects",
        a.kind.name(),
        a.problem.target,
        a.fit_logs.join(" "),
        val,
        if a.build.settle_s > 0.0 {
            format!(" (first {} s of every log left out)", a.build.settle_s)
        } else {
            String::new()
        },
        o.n_fit,
        o.n_val,
        a.options.decimate,
        o.n_candidates
    );
    let _ = writeln!(s, "\nbaseline: {}", baseline_label(a));
    for c in &o.final_fit.coefs[..o.baseline.coefs.len()] {
        let _ = writeln!(
            s,
            "  {:<28} {:>+14.6e} ± {:.2e}  ({:.2} %σ)",
            c.name, c.value, c.std_dev, c.pct_sigma
        );
    }
    let _ = writeln!(
        s,
        "\n{:<4}{:<44} {:>12} {:>12} {:>8} {:>8}",
        "",
        "model (validation RMSE decides)",
        format!("val [{unit}]"),
        format!("fit [{unit}]"),
        "ERR",
        "gain"
    );
    let _ = writeln!(
        s,
        "{:<4}{:<44} {:>12.4} {:>12.4}",
        "",
        "baseline",
        o.baseline.val_rmse * scale,
        o.baseline.train_rmse * scale
    );
    accepted_rows(&mut s, o, scale);
    let _ = writeln!(
        s,
        "{:<4}{:<44} {:>12.4} {:>12.4}   ({:.1} % lower than the baseline)",
        "",
        "final",
        o.final_fit.val_rmse * scale,
        o.final_fit.train_rmse * scale,
        100.0 * (1.0 - o.final_fit.val_rmse / o.baseline.val_rmse)
    );
    rejected_rows(&mut s, a, scale, unit);
    other_sensors_row(&mut s, a);
    diag_rows(&mut s, &o.before, &o.after, scale, unit);
    run_rows(&mut s, o, scale, unit);
    s
}

/// Each kept term: its errors, family, meaning and coefficient, its
/// evidence and a rival family.
fn accepted_rows(s: &mut String, o: &Outcome, scale: f64) {
    let nb = o.baseline.coefs.len();
    for (k, st) in o.accepted.iter().enumerate() {
        // A group's parts share one step: its figures on the first part's
        // row, the others named under it.
        let later_part = k > 0 && st.group.is_some() && o.accepted[k - 1].group == st.group;
        if let (Some(g), false) = (&st.group, later_part) {
            let parts = o.accepted[k..]
                .iter()
                .take_while(|a| a.group.as_ref() == Some(g))
                .count();
            let _ = writeln!(s, "    one effect in {parts} parts, taken together: {g}");
        }
        if later_part {
            let _ = writeln!(
                s,
                "{:<4}{:<44} (same step)",
                format!("+{}", k + 1),
                st.label
            );
        } else {
            let _ = writeln!(
                s,
                "{:<4}{:<44} {:>12.4} {:>12.4} {:>7.1}% {:>7.1}%",
                format!("+{}", k + 1),
                st.label,
                st.fit.val_rmse * scale,
                st.fit.train_rmse * scale,
                100.0 * st.err,
                100.0 * st.gain
            );
        }
        if let Some(c) = o.final_fit.coefs.get(nb + k) {
            let _ = writeln!(
                s,
                "      {}: {}; coef {:+.4e} ± {:.1e} ({:.1} %σ)",
                class_text(st),
                st.meaning,
                c.value,
                c.std_dev,
                c.pct_sigma
            );
        }
        if let Some((before, after)) = st.evidence {
            let _ = writeln!(
                s,
                "      evidence: correlation of the validation residual with the term {before:+.3} before, {after:+.3} after"
            );
        }
        if let (Some(g), false) = (st.unfiltered_gain, later_part) {
            let verdict = if st.class == super::select::OBSERVER_FILTERING {
                "it stands in for the observer's filtering, not for an effect of the plant"
            } else {
                "not the observer's filtering"
            };
            let _ = writeln!(
                s,
                "      observer check: with the baseline's derivatives taken without the observer's \
                 lag (offline, forward and backward; the JAE's also at a tenth of the rate) it \
                 cuts the validation RMSE by {:.1} % ({:.1} % with the MCU's): {verdict}",
                100.0 * g,
                100.0 * st.gain
            );
        }
        if let Some(r) = &st.rival {
            let _ = writeln!(
                s,
                "      ambiguous: {} ({}) explains nearly as much (ERR {:.1} % against {:.1} %); the data do not tell {} from {}",
                r.label,
                r.class,
                100.0 * r.err,
                100.0 * st.err,
                st.family(),
                r.class
            );
        }
        if !st.passed_over.is_empty() && !later_part {
            let names: Vec<String> = st
                .passed_over
                .iter()
                .map(|r| format!("{} ({}, ERR {:.1} %)", r.class, r.label, 100.0 * r.err))
                .collect();
            let _ = writeln!(
                s,
                "      passed over: {} explained more of the same residual (ERR {:.1} % for this \
                 term) but {} set aside on validation (below): the fit favours {}, the \
                 validation this one",
                names.join("; "),
                100.0 * st.err,
                if names.len() == 1 { "was" } else { "were" },
                if names.len() == 1 { "it" } else { "them" }
            );
        }
    }
}

/// The terms set aside and why.
fn rejected_rows(s: &mut String, a: &Analysis, scale: f64, unit: &str) {
    let o = &a.outcome;
    if !o.rejected.is_empty() {
        let _ = writeln!(
            s,
            "set aside (cut the validation RMSE by less than {:.1} %, or raised one validation run's by more):",
            100.0 * a.options.min_gain
        );
        for st in &o.rejected {
            let harm = st
                .harm
                .as_ref()
                .map(|(run, rise)| format!("; raises {run} by {:.1} %", 100.0 * rise))
                .unwrap_or_default();
            let _ = writeln!(
                s,
                "    {:<44} ERR {:.1} %, validation {:.4} {unit} ({:+.1} %){harm}",
                st.label,
                100.0 * st.err,
                st.fit.val_rmse * scale,
                -100.0 * st.gain
            );
        }
    }
}

/// Whether terms on other sensors were offered.
fn other_sensors_row(s: &mut String, a: &Analysis) {
    if !a.problem.other_sensors.is_empty() {
        let names: Vec<&str> = a
            .problem
            .other_sensors
            .iter()
            .filter_map(|&i| a.problem.signal_names.get(i as usize).map(String::as_str))
            .collect();
        let _ = writeln!(
            s,
            "other sensors ({}): {}",
            names.join(", "),
            if a.build.other_sensors {
                "offered (--other-sensors); a term that reads one is labelled fusion"
            } else {
                "not offered (a term reading one would be sensor fusion; --other-sensors offers them)"
            }
        );
    }
}

/// Each validation run's error before and after (with several runs), and
/// each test run's (with `--test`).
fn run_rows(s: &mut String, o: &Outcome, scale: f64, unit: &str) {
    if o.runs.len() > 1 {
        let _ = writeln!(s);
        run_table(s, "per validation run", &o.runs, scale, unit);
    }
    if let Some((before, after)) = o.test_rmse() {
        let _ = writeln!(
            s,
            "\ntest (never fitted, never used to choose a term): RMSE {:.4} -> {:.4} {unit}",
            before * scale,
            after * scale
        );
        run_table(s, "per test run", &o.test_runs, scale, unit);
    } else if !o.accepted.is_empty() {
        let _ = writeln!(
            s,
            "\nnote: the validation rows chose the terms, so their RMSE is a selected figure: on \
             runs that chose nothing it is higher, the more so the fewer validation runs \
             (MRDLab, one run validating: 0.25-0.33 deg on it, 0.52-0.67 deg on the others; \
             docs/residual.md). For an error to quote, keep runs back with --test"
        );
    }
}

/// One row per run: RMSE before and after, and the mean after.
fn run_table(s: &mut String, title: &str, runs: &[RunError], scale: f64, unit: &str) {
    let _ = writeln!(
        s,
        "{title:<26}RMSE before [{unit}]   after [{unit}]   mean after [{unit}]"
    );
    for r in runs {
        let _ = writeln!(
            s,
            "  {:<26} {:>12.4} {:>14.4} {:>16.4}",
            r.name,
            r.before_rmse * scale,
            r.after_rmse * scale,
            r.after_mean * scale
        );
    }
}

/// Stage `residual_time` (residual before and after over time, per
/// validation run) and, when effects were kept, `residual_effects` (for each
/// effect: the baseline residual and the effect's fitted contribution against
/// its input signal) among a command's outputs ([`crate::output`]); returns
/// their paths.
pub fn stage_plots(out: &mut Outputs, a: &Analysis, dir: &Path) -> Result<Vec<PathBuf>> {
    let o = &a.outcome;
    let (unit, scale) = display_unit(&a.problem.target);
    let mut files = Vec::new();
    let mut panels = Vec::new();
    for tr in o.traces.iter().take(6) {
        let e = |p: &[f64]| -> Vec<f64> {
            tr.target
                .iter()
                .zip(p)
                .map(|(y, q)| (y - q) * scale)
                .collect()
        };
        panels.push(
            Panel::new(
                format!("{}: residual of {} (validation)", tr.name, a.problem.target),
                "t [s]",
                format!("residual [{unit}]"),
            )
            .with(Series::line("baseline", tr.t_s.clone(), e(&tr.before)))
            .with(Series::line(
                format!("with {} effect(s)", o.accepted.len()),
                tr.t_s.clone(),
                e(&tr.after),
            )),
        );
    }
    let cols = if panels.len() > 1 { 2 } else { 1 };
    files.extend(stage_figure(
        out,
        &Figure::grid(panels, cols),
        &dir.join("residual_time"),
    )?);

    if !o.accepted.is_empty() {
        let mut panels = Vec::new();
        for (j, st) in o.accepted.iter().enumerate() {
            let (mut x, mut before, mut contrib, mut partial) =
                (Vec::new(), Vec::new(), Vec::new(), Vec::new());
            for tr in &o.traces {
                let (input, c) = &tr.terms[j];
                for k in 0..tr.t_s.len() {
                    x.push(input[k]);
                    before.push((tr.target[k] - tr.before[k]) * scale);
                    contrib.push(c[k] * scale);
                    partial.push((tr.target[k] - tr.after[k] + c[k]) * scale);
                }
            }
            let xname = if st.term.kind.uses_input() {
                a.problem.signal_names[st.term.input as usize].clone()
            } else {
                "t_s".to_owned()
            };
            panels.push(
                Panel::new(
                    format!("+{} {}", j + 1, st.label),
                    xname,
                    format!("[{unit}]"),
                )
                .with(Series::points("baseline residual", x.clone(), before))
                .with(Series::points(
                    "final residual + this effect",
                    x.clone(),
                    partial,
                ))
                .with(Series::points("this effect (fitted)", x, contrib)),
            );
        }
        let cols = if panels.len() > 1 { 2 } else { 1 };
        files.extend(stage_figure(
            out,
            &Figure::grid(panels, cols),
            &dir.join("residual_effects"),
        )?);
    }
    Ok(files)
}
