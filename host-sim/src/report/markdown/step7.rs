//! report.md's step 7: the programme again on the plant with the
//! simulator's unmodelled effects, with the seed's models and after the
//! residual loop.

use std::fmt::Write as _;

use super::{md_figure, md_identification};
use crate::report::goals::STEP7_ROWS;
use crate::report::keys::variants;
use crate::report::render::{cell, fmt_num};
use crate::report::{EffectsPart, Report};
use crate::residual::{Analysis, Outcome};

/// Step 7: the programme again on the plant with effects, before and after
/// the residual loop.
pub(super) fn md_step_7(o: &mut String, r: &Report, fx: &EffectsPart) {
    let _ = writeln!(o, "## 7. Unmodelled effects and the residual loop\n");
    let _ = writeln!(
        o,
        "The simulator's effects switched on (default magnitudes): {}. The whole programme ran again on that plant \
         with the seed's models (every identification repeated), then the residual loop \
         (`host_sim::residual`) ranked candidate effect terms on the `jae-ident` log (JAE) and the `tension-ident` log \
         (tension model), kept those that cut the error on the held-out last 30 % of each run and \
         made no other regime worse: for the JAE a run under 2.5 N, `robust-2n5`, and one with JAE feedback, \
         `track-jae`, each a fresh run with its own seed; for the tension model the same `robust-2n5` run with \
         its known load taken out of the target (`f_ext l_e / r` of cable-1 tension), and wrote them into `config.jae.added` and \
         `config.tension.added`; steps 3, 4 and 6 then ran again with that configuration. \
         Each kept term's gain is also measured with the baseline's derivatives taken without the \
         observer's lag (the core's observer run forward and backward, for the JAE also at a tenth of the \
         rate, wider than the core's band): a term that keeps less than half of its gain there stands in \
         for the observer, not for the plant, and its family reads \"observer filtering\".\n",
        fx.names.join(", ")
    );
    md_step7_table(o, r);
    let counts = cable_joint::Config::default()
        .scales
        .magnetic_counts_per_rev;
    let _ = writeln!(
        o,
        "\"Actual\" is the magnetic encoder, as in the seed, read to its count ({:.3}° at {counts} counts a \
         turn); the rows \"true − estimated\" take the plant's own angle instead, a figure only the \
         simulator has, so a change smaller than a count shows there.\n",
        360.0 / f64::from(counts)
    );
    md_residual(o, "JAE", &fx.residual.jae, crate::stats::DEG_PER_RAD, "°");
    md_residual(o, "Tension model", &fx.residual.tension, 1.0, "N");
    let _ = writeln!(o, "Identification on the plant with effects:\n");
    md_identification(o, &fx.id);
    md_figure(o, r, "fig_accuracy_variants");
    md_residual_plots(o, r);
    md_step7_faults(o, fx);
}

/// Step 7's table: [`STEP7_ROWS`] for every variant (all three are present).
fn md_step7_table(o: &mut String, r: &Report) {
    let vs = variants(r);
    let _ = writeln!(
        o,
        "| quantity | clean | effects, seed's model | effects, after the residual loop |"
    );
    let _ = writeln!(o, "|---|---|---|---|");
    for row in &STEP7_ROWS {
        let _ = write!(o, "| {}", cell(row.quantity));
        if !row.unit.is_empty() {
            let _ = write!(o, " [{}]", row.unit);
        }
        let _ = write!(o, " |");
        for v in &vs {
            let _ = write!(o, " {} |", fmt_num(row.value(v)));
        }
        let _ = writeln!(o);
    }
    let _ = writeln!(o);
}

/// The residual loop's plots over time, for the models that have one.
fn md_residual_plots(o: &mut String, r: &Report) {
    for (name, dir) in [
        ("JAE", "residual_jae"),
        ("tension model", "residual_tension"),
    ] {
        if r.figures
            .iter()
            .any(|w| w.stem == format!("{dir}/residual_time"))
        {
            let _ = writeln!(
                o,
                "\n![residual loop, {name}]({dir}/residual_time.png)\n\n*Residual loop, {name}: residual before and after on the held-out part.* ([SVG]({dir}/residual_time.svg))\n"
            );
        }
    }
}

/// The loading cases that faulted on the plant with effects, after and
/// before the residual loop.
fn md_step7_faults(o: &mut String, fx: &EffectsPart) {
    if !fx.after.loading_summary.faults.is_empty() {
        let _ = writeln!(
            o,
            "Faulted cases after the residual loop: {}\n",
            fx.after.loading_summary.faults.join("; ")
        );
    }
    if !fx.before.loading_summary.faults.is_empty() {
        let _ = writeln!(
            o,
            "Faulted cases with the seed's model on the effects plant: {}\n",
            fx.before.loading_summary.faults.join("; ")
        );
    }
}

/// The residual loop on one model: the validation error before and after,
/// the terms added, the error per validation run and the terms set aside.
/// `scale` converts the model's unit to `unit`.
fn md_residual(out: &mut String, name: &str, a: &Analysis, scale: f64, unit: &str) {
    let o = &a.outcome;
    let _ = writeln!(
        out,
        "**{name}** ({} candidates, fitted on the rest of the run, judged on {}; terms reading a sensor the model does not read, for the JAE grating 1 and the motor encoder, are sensor fusion and not offered): validation RMSE {} → {} {unit}.\n",
        o.n_candidates,
        crate::residual::report::validation_description(a),
        fmt_num(o.baseline.val_rmse * scale),
        fmt_num(o.final_fit.val_rmse * scale),
    );
    if o.accepted.is_empty() {
        let _ = writeln!(
            out,
            "No effect cut the validation error by 1 % or more: nothing added.\n"
        );
        return;
    }
    md_terms_added(out, o, scale, unit);
    if o.runs.len() > 1 {
        md_validation_runs(out, o, scale, unit);
    }
    md_set_aside(out, o);
    let _ = writeln!(out);
}

/// The terms the residual loop added, in order.
fn md_terms_added(out: &mut String, o: &Outcome, scale: f64, unit: &str) {
    let _ = writeln!(
        out,
        "| # | term | effect family | meaning | validation RMSE after [{unit}] | gain | gain without the observer's lag | residual–term correlation, before → after | a rival family as likely |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|---|---|---|---|");
    for (k, s) in o.accepted.iter().enumerate() {
        let evidence = s
            .evidence
            .map_or("–".into(), |(b, a)| format!("{b:+.2} → {a:+.2}"));
        let rival = s
            .rival
            .as_ref()
            .map_or("no".into(), |r| format!("{} (`{}`)", r.class, r.label));
        let label = match &s.group {
            Some(g) => format!("`{}` (one part of `{g}`, taken together)", s.label),
            None => format!("`{}`", s.label),
        };
        let unfiltered = s
            .unfiltered_gain
            .map_or("–".into(), |g| format!("{:.1} %", 100.0 * g));
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {:.1} % | {} | {} | {} |",
            k + 1,
            label,
            crate::residual::report::class_text(s),
            s.meaning,
            fmt_num(s.fit.val_rmse * scale),
            100.0 * s.gain,
            unfiltered,
            evidence,
            rival
        );
    }
}

/// The validation error of each validation run, before and after.
fn md_validation_runs(out: &mut String, o: &Outcome, scale: f64, unit: &str) {
    let _ = writeln!(
        out,
        "\n| validation run | RMSE before [{unit}] | after [{unit}] |\n|---|---|---|"
    );
    for r in &o.runs {
        let _ = writeln!(
            out,
            "| {} | {} | {} |",
            r.name,
            fmt_num(r.before_rmse * scale),
            fmt_num(r.after_rmse * scale)
        );
    }
}

/// The terms set aside because they raise one validation run's error
/// (nothing when there is none).
fn md_set_aside(out: &mut String, o: &Outcome) {
    let harmed: Vec<String> = o
        .rejected
        .iter()
        .filter_map(|s| {
            s.harm
                .as_ref()
                .map(|(run, rise)| format!("`{}` (raises {run} by {:.1} %)", s.label, 100.0 * rise))
        })
        .collect();
    if !harmed.is_empty() {
        let _ = writeln!(
            out,
            "\nSet aside because they raise one validation run's error (do no harm): {}.",
            harmed.join(", ")
        );
    }
}
