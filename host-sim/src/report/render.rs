//! The report's text: the flat figure map of report.json, the comparison
//! with the seed, the goals, the terminal table and report.md.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use serde_json::{json, Value};

use super::experiments::{LoadCase, Summary, TrackRun};
use super::goals::{fault_lines, goal_status, status_text, GOALS, STEP7_ROWS};
use super::keys::{self, Figure};
use super::programme::{Evaluation, Identification, LoadingSummary};
use super::seed::Row;
use super::{EffectsPart, Report};
use crate::ident::Regressor;
use crate::residual::Analysis;

// --- The flat figure map ---------------------------------------------------

/// Every figure of the report under a stable key: each [`Figure`] a
/// variant has under that variant's prefix (`clean.`,
/// `effects_seed_model.`, `effects_residual.`), and `runtime_s`.
pub fn figure_map(r: &Report) -> BTreeMap<String, f64> {
    let figures = Figure::all();
    let mut map = BTreeMap::new();
    for v in keys::variants(r) {
        for f in &figures {
            if let Some(x) = f.value(&v) {
                map.insert(format!("{}.{}", v.prefix, f.key()), x);
            }
        }
    }
    map.insert("runtime_s".into(), r.runtime_s);
    map
}

// --- Numbers in tables ------------------------------------------------------

/// A number for a table: `n/a` when not finite; an integer below 1e5
/// without decimals; otherwise in scientific notation with four decimals
/// outside [1e-3, 1e5), with two decimals from 10, with four below 10.
pub fn fmt_num(v: f64) -> String {
    if !v.is_finite() {
        return "n/a".into();
    }
    let a = v.abs();
    if v.fract() == 0.0 && a < 1e5 {
        format!("{v:.0}")
    } else if !(1e-3..1e5).contains(&a) {
        format!("{v:.4e}")
    } else if a >= 10.0 {
        format!("{v:.2}")
    } else {
        format!("{v:.4}")
    }
}

/// Text for a Markdown table cell (`|` escaped).
fn cell(s: &str) -> String {
    s.replace('|', "\\|")
}

// --- report.md -----------------------------------------------------------------

fn md_summary(s: &Summary, unit: &str) -> String {
    format!(
        "{} / {} / {} / {} / {} {unit}",
        fmt_num(s.mean),
        fmt_num(s.mean_abs),
        fmt_num(s.max),
        fmt_num(s.min),
        fmt_num(s.rms)
    )
}

fn md_figure(out: &mut String, r: &Report, stem: &str) {
    if let Some(w) = r.figures.iter().find(|w| w.stem == stem) {
        let _ = writeln!(
            out,
            "\n![{}]({stem}.png)\n\n*{}* ([SVG]({stem}.svg))\n",
            w.caption, w.caption
        );
    }
}

fn md_tracking(out: &mut String, name: &str, t: &TrackRun, seed: &str) {
    let _ = writeln!(
        out,
        "| {name} | {} | {} | {seed} |",
        md_summary(&t.desired_minus_actual, "°"),
        md_summary(&t.actual_minus_estimated, "°"),
    );
    if let Some(f) = &t.fault {
        let _ = writeln!(out, "\n**{name} latched a fault:** {f}\n");
    }
}

/// The accuracy bullets of one loading summary (all angles, 0°, 30°/−40°).
fn md_accuracies(o: &mut String, l: &LoadingSummary) {
    for (name, a) in [
        ("≥ 1 N, all angles", &l.above_1n),
        ("0.3 N, all angles", &l.at_0n3),
        ("≥ 1 N at 0° (seed 94 %)", &l.above_1n_0),
        ("0.3 N at 0° (seed 82 %)", &l.at_0n3_0),
        ("≥ 1 N at 30°/−40° (seed 95 %)", &l.above_1n_30_m40),
        ("0.3 N at 30°/−40° (seed 84 %)", &l.at_0n3_30_m40),
    ] {
        let _ = writeln!(
            o,
            "* accuracy {name}: worst {} %, mean {} % over {} cases ({} faulted)",
            fmt_num(a.min_pct),
            fmt_num(a.mean_pct),
            a.cases,
            a.faulted
        );
    }
}

fn md_cases(out: &mut String, cases: &[LoadCase]) {
    let _ = writeln!(
        out,
        "| angle | weight | dir | F [N] | mean estimate [N] | accuracy [%] | stable error RMS [N] | static no-load [min, max] [N] | dynamic no-load [min, max] [N] | max angle error loaded [°] | fault |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|---|---|---|---|---|---|");
    for c in cases {
        let dynamic = c
            .dynamic_noload_n
            .map(|d| format!("[{}, {}]", fmt_num(d.min), fmt_num(d.max)))
            .unwrap_or_else(|| "-".into());
        let _ = writeln!(
            out,
            "| {}° | {} g | {} | {:+.3} | {} | {} | {} | [{}, {}] | {dynamic} | {} | {} |",
            c.angle_deg,
            c.mass_g,
            c.direction,
            c.force_n,
            fmt_num(c.mean_estimate_n),
            fmt_num(c.accuracy_pct),
            fmt_num(c.stable_error_n.rms),
            fmt_num(c.static_noload_n.min),
            fmt_num(c.static_noload_n.max),
            fmt_num(c.angle_error_loaded_deg.max_abs()),
            c.fault.as_deref().unwrap_or("")
        );
    }
}

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
    let _ = writeln!(
        out,
        "| # | term | effect family | meaning | validation RMSE after [{unit}] | gain | residual–term correlation, before → after | a rival family as likely |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|---|---|---|");
    for (k, s) in o.accepted.iter().enumerate() {
        let evidence = s
            .evidence
            .map_or("–".into(), |(b, a)| format!("{b:+.2} → {a:+.2}"));
        let rival = s
            .rival
            .as_ref()
            .map_or("no".into(), |r| format!("{} (`{}`)", r.class, r.label));
        let _ = writeln!(
            out,
            "| {} | `{}` | {} | {} | {} | {:.1} % | {} | {} |",
            k + 1,
            s.label,
            s.class,
            s.meaning,
            fmt_num(s.fit.val_rmse * scale),
            100.0 * s.gain,
            evidence,
            rival
        );
    }
    if o.runs.len() > 1 {
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
    let _ = writeln!(out);
}

fn md_identification(out: &mut String, id: &Identification) {
    let bm = &id.bm;
    let p = bm.fit.param(Regressor::PhiVel);
    let _ = writeln!(
        out,
        "* **B_m** = {} N·m·s/rad (%σ {}; seed 1.6934e-5), Coulomb torque {}; verification run (another seed): RMSE {} N·m, mean {} N·m.",
        fmt_num(bm.b_m_nm_s_rad),
        p.map_or("n/a".into(), |p| format!("{:.3} %", p.pct_sigma)),
        bm.coulomb_nm
            .map_or("dropped by the %σ rule".into(), |c| format!("{} N·m", fmt_num(c))),
        fmt_num(id.bm_validation.rmse),
        fmt_num(id.bm_validation.mean),
    );
    let j = &id.jae;
    let _ = writeln!(
        out,
        "* **JAE** χ_s = [{}, {}, {}, {}], offset {} rad (seed [0.0805, 0.5225, 0.0025, 264.356]); least-squares residual on its run: mean {}°, mean |e| {}°, max {}°, min {}°.",
        fmt_num(j.chi_s[0]),
        fmt_num(j.chi_s[1]),
        fmt_num(j.chi_s[2]),
        fmt_num(j.chi_s[3]),
        fmt_num(j.offset_rad),
        fmt_num(j.error_deg.mean),
        fmt_num(j.error_deg.mean_abs),
        fmt_num(j.error_deg.max),
        fmt_num(j.error_deg.min),
    );
    let t = &id.tension;
    let model = |m: Result<&crate::ident::FitReport, &String>| match m {
        Ok(m) => format!(
            "mean {} N, RMSE {} N",
            fmt_num(m.errors.mean),
            fmt_num(m.errors.rmse)
        ),
        Err(e) => format!("not fitted ({e})"),
    };
    let _ = writeln!(
        out,
        "* **Tension models** on the identification run (seed: mean −0.0228, 0.0189, −0.0063 N; the mean of a least-squares residual with a constant term is zero by construction, so the RMSE is the informative figure): A {}; B {}; C {}.",
        model(t.model_a.as_ref()),
        model(t.model_b.as_ref()),
        model(Ok(&t.model_c)),
    );
    let _ = writeln!(
        out,
        "* **Model C** (Eq. 27) parameters and %σ, and the pruning (limit 5 %):\n"
    );
    let _ = writeln!(out, "| term | parameter | value | %σ | kept |");
    let _ = writeln!(out, "|---|---|---|---|---|");
    for p in &t.model_c.params {
        let kept = t.simplified.param(p.regressor).is_some();
        let _ = writeln!(
            out,
            "| `{}` | {} [{}] | {} | {} | {} |",
            p.symbol,
            p.name,
            p.unit,
            fmt_num(p.value),
            fmt_num(p.pct_sigma),
            if kept { "yes" } else { "no" }
        );
    }
    let _ = writeln!(
        out,
        "\n* **Simplified model C** written to the configuration: χ_p = [{}, {}, {}, {}] (f_sc1 N, f_cp2 N, K_s N/m, F_0 N; seed [3.879, 5.027, 707.7, 19.52]).",
        fmt_num(t.chi_p[0]),
        fmt_num(t.chi_p[1]),
        fmt_num(t.chi_p[2]),
        fmt_num(t.chi_p[3]),
    );
    for (name, e) in &id.tension_validation {
        let _ = writeln!(
            out,
            "  * verification run, {name}: mean {} N, RMSE {} N, max |e| {} N",
            fmt_num(e.mean),
            fmt_num(e.rmse),
            fmt_num(e.max_abs())
        );
    }
    if !id.faults.is_empty() {
        let _ = writeln!(
            out,
            "* **Faults in identification runs:** {}",
            id.faults.join("; ")
        );
    }
}

/// report.md.
pub fn markdown(r: &Report, rows: &[Row]) -> String {
    let mut o = String::new();
    let (id, ev) = (&r.clean.0, &r.clean.1);
    let _ = writeln!(
        o,
        "# The seed's experimental programme on the simulated prototype\n"
    );
    let _ = writeln!(
        o,
        "Generated by `cargo run --release -p host-sim -- report --seed {} --duration-scale {}` in {:.1} s. \
         Everything below was identified from simulated logs, step by step in the seed's order \
         (B_m → DOB; JAE → joint closed loop; tension model → force estimator), through the same \
         core (`cable_joint::Controller`) the firmware runs; the plant's true parameters are never read. \
         Seed: *Toward force detection of a cable-driven micromanipulator for a surgical robot based on \
         disturbance observer* (seed 000), Sect. 4.\n",
        r.options.seed, r.options.duration_scale, r.runtime_s
    );
    o.push_str(&super::variants::markdown(&r.variants));
    if r.options.duration_scale != 1.0 {
        let _ = writeln!(
            o,
            "**Note:** every scenario ran at {} of its full duration: the figures are not the full programme's.\n",
            r.options.duration_scale
        );
    }

    let _ = writeln!(o, "## Results against the seed\n");
    let _ = writeln!(
        o,
        "| quantity | seed | this project | ratio | verdict | note | seed source |"
    );
    let _ = writeln!(o, "|---|---|---|---|---|---|---|");
    for row in rows {
        let _ = writeln!(
            o,
            "| {} [{}] | {} | {} | {:.3} | {} | {} | {} |",
            cell(row.seed.quantity),
            row.seed.unit,
            fmt_num(row.seed.value),
            fmt_num(row.ours),
            row.ratio(),
            row.verdict(),
            row.note,
            row.seed.source
        );
    }
    let _ = writeln!(
        o,
        "\nRatio: |this| / |seed| for errors (below 1 is better), this / seed for accuracies (above 1 is better). \
         The seed reports the JAE's and the motor-feedback tracking's \"average\" error with a positive minimum \
         (0.964°) or next to a symmetric max/min: these are compared with the mean |error|. The signed means \
         and the extremes of the JAE-feedback runs are compared as signed values (ratio of magnitudes).\n"
    );

    let _ = writeln!(o, "## Where we stand\n");
    let vs = keys::variants(r);
    let _ = write!(o, "| goal |");
    for v in &vs {
        let _ = write!(o, " {} |", v.title);
    }
    let _ = writeln!(o);
    let _ = writeln!(o, "|---|{}", "---|".repeat(vs.len()));
    for g in &GOALS {
        let _ = write!(o, "| {} |", cell(g.goal));
        for v in &vs {
            let _ = write!(o, " {} |", status_text(goal_status(v, g)));
        }
        let _ = writeln!(o);
    }
    let _ = writeln!(
        o,
        "\n\"Above 1 N\" counts the 100 g (0.98 N), 200 g and 250 g weights; \"0.3 N\" is the 30 g weight (0.29 N). \
         Accuracy = 100 (1 − |mean estimate − applied| / applied) over the stable region, worst case over angles and \
         directions. A goal counts as met only if none of its runs latched a fault (statistics stop at a fault). The static no-load error is the \
         per-tick force estimate in the no-load region before each load (no averaging).\n"
    );

    let faults = fault_lines(r);
    if !faults.is_empty() {
        let _ = writeln!(o, "Faults latched (the controller disabled the drive; that run's statistics stop there):\n");
        for f in &faults {
            let _ = writeln!(o, "* {f}");
        }
        let _ = writeln!(o);
    }
    let _ = writeln!(o, "## 1. B_m (seed Sect. 4.2, Figs. 14-15), 2. JAE (Sect. 4.1, Figs. 8-9), 5. tension models (Figs. 16-18)\n");
    md_identification(&mut o, id);
    md_figure(&mut o, r, "fig14_15_bm");
    md_figure(&mut o, r, "fig09_jae");
    md_figure(&mut o, r, "fig16_tension_models");
    md_figure(&mut o, r, "fig17_model_c_simplified");
    md_figure(&mut o, r, "fig18_model_c_verification");

    let _ = writeln!(o, "## 3-4. Tracking (Figs. 10-13)\n");
    let _ = writeln!(
        o,
        "Statistics over the tracking phase; each cell is mean / mean |e| / max / min / RMS.\n"
    );
    let _ = writeln!(o, "| run | desired − actual | actual − estimated | seed (desired − actual; actual − estimated) |");
    let _ = writeln!(o, "|---|---|---|---|");
    md_tracking(
        &mut o,
        "track-motor (motor-encoder feedback)",
        &ev.track_motor,
        "mean 1.912°, max 4.134°, min 0.964°",
    );
    md_tracking(
        &mut o,
        "track-jae (JAE feedback)",
        &ev.track_jae,
        "−0.150 / 0.905 / −0.974°; 0.170 / 0.715 / −0.498°",
    );
    md_tracking(
        &mut o,
        "robust-2n5 (2.5 N, complex)",
        &ev.robust,
        "−0.105 / 1.202 / −1.271°; 0.076 / 0.508 / −0.454°",
    );
    let _ = writeln!(o, "\nThe tracking runs use the configuration after B_m and the JAE (the tension model is identified after them, as in the seed).");
    md_figure(&mut o, r, "fig10_track_motor");
    md_figure(&mut o, r, "fig12_track_jae");
    md_figure(&mut o, r, "fig13_robust");

    let l = &ev.loading_summary;
    let _ = writeln!(o, "## 6. Loading protocol (Figs. 19-26)\n");
    let _ = writeln!(
        o,
        "Each case is its own run (hold, move to the angle, adjust, 2 s no-load, 0.5 s loading ramp, 3 s stable, unloading), so a fault ends only that case. {} cases, {} faulted.\n",
        l.cases, l.faulted
    );
    for f in &l.faults {
        let _ = writeln!(o, "* fault: {f}");
    }
    let _ = writeln!(
        o,
        "\n* static no-load error: all angles [{}, {}] N (RMS {} N); at 0° ±{} N (seed ±0.1 N); at 30°/−40° ±{} N (seed ±0.15 N)",
        fmt_num(l.static_noload_n.min),
        fmt_num(l.static_noload_n.max),
        fmt_num(l.static_noload_n.rms),
        fmt_num(l.static_noload_0_n.max_abs()),
        fmt_num(l.static_noload_30_m40_n.max_abs()),
    );
    if l.static_noload_0_n.max_abs() < 1e-4 {
        let _ = writeln!(
            o,
            "* note: at 0° the estimate in the no-load region is the model itself to within {} N. With the joint inside the \
             hold dead band the current reference is the tension model's feed-forward alone, so the DOB sees exactly the \
             model and reports no force: this figure says nothing about the estimator's resolution.",
            fmt_num(l.static_noload_0_n.max_abs())
        );
    }
    let _ = writeln!(
        o,
        "* dynamic no-load error (moving to 30°/−40° and back, settling): positive-direction runs [{}, {}] N (seed ±0.15 N), negative-direction runs [{}, {}] N (seed ±0.2 N)",
        fmt_num(l.dynamic_noload_pos_n.min),
        fmt_num(l.dynamic_noload_pos_n.max),
        fmt_num(l.dynamic_noload_neg_n.min),
        fmt_num(l.dynamic_noload_neg_n.max),
    );
    md_accuracies(&mut o, l);
    let f_sc1 = id.tension.chi_p[0];
    let m = &id.config.machine;
    let tip_per_tension = f64::from(m.pulley_radius_m / m.gripper_length_m);
    let _ = writeln!(
        o,
        "* a likely cause of the force errors at standstill: the identified slider-1 Coulomb friction f_sc1 = {} N \
         enters the model only through the held sign of x1'. While the joint holds still the friction can take any \
         value within ±f_sc1 (the slider sticks), which is ±{} N at the tip (r / l_e = {}); the estimate \
         jumps when the slider sticks or slips (Figs. 22-26).",
        fmt_num(f_sc1),
        fmt_num(f_sc1 * tip_per_tension),
        fmt_num(tip_per_tension)
    );
    let _ = writeln!(
        o,
        "* largest joint-angle error with a load on: {}° at 0° (seed 1.25°), {}° at 30°/−40° (seed 1.4°)\n",
        fmt_num(l.max_angle_error_0_deg),
        fmt_num(l.max_angle_error_30_m40_deg)
    );
    md_cases(&mut o, &ev.loading);
    let ls = &ev.loading_stretch_summary;
    let _ = writeln!(
        o,
        "\n### The same cases, judged on the cable-stretch estimate\n\n\
         `f_ext_stretch_n` reads the joint torque off both cables' stretch (gratings 1 and 2 and the JAE, \
         `r [K_w1 (x1 - r theta) - K_w2 (r theta - x2)] / l_e`, cable stiffness from the identified c4). \
         The sliders' friction sits outside the two cables, so it does not enter; the joint pin's own friction does.\n"
    );
    let _ = writeln!(
        o,
        "* static no-load error: at 0° ±{} N, at 30°/−40° ±{} N; dynamic no-load: positive runs [{}, {}] N, negative runs [{}, {}] N",
        fmt_num(ls.static_noload_0_n.max_abs()),
        fmt_num(ls.static_noload_30_m40_n.max_abs()),
        fmt_num(ls.dynamic_noload_pos_n.min),
        fmt_num(ls.dynamic_noload_pos_n.max),
        fmt_num(ls.dynamic_noload_neg_n.min),
        fmt_num(ls.dynamic_noload_neg_n.max),
    );
    md_accuracies(&mut o, ls);
    let _ = writeln!(o);
    md_cases(&mut o, &ev.loading_stretch);
    for stem in [
        "fig20_loading_0deg_neg",
        "fig21_loading_0deg_pos",
        "fig22_partition",
        "fig23_loading_30deg_neg",
        "fig24_loading_30deg_pos",
        "fig25_loading_m40deg_pos",
        "fig26_loading_m40deg_neg",
    ] {
        md_figure(&mut o, r, stem);
    }

    if let Some(fx) = &r.effects {
        md_effects(&mut o, r, fx);
    }

    let _ = writeln!(o, "## Definitions\n");
    let _ = writeln!(
        o,
        "* Angles: desired = the trajectory reference, actual = the magnetic encoder (4096 counts/rev, quantised as on the prototype), estimated = the JAE.\n\
         * Tracking statistics are over the tracking phase of each run (not the initial hold).\n\
         * JAE error \"through the core\": the identification log replayed through `Controller::replay` with the identified configuration, estimate − encoder, after the first 0.2 s.\n\
         * Force regions: no-load (before the load is hung, after the adjustment), loading (0.5 s ramp), stable (3 s, the load on), as in the seed's Fig. 22.\n\
         * Every run has its own noise seed derived from `--seed` and the run's name; the same run gets the same noise on the clean and the effects plant, before and after the residual loop (paired comparison).\n\
         * report.json holds every figure under `figures` with stable keys (`clean.…`, `effects_seed_model.…`, `effects_residual.…`).\n\
         * The identified configurations are written beside this file: `config_clean.toml` (and with step 7 \
         `config_effects_seed_model.toml`, `config_effects_residual.toml`); `host-sim simulate --config FILE` runs a \
         scenario with one of them."
    );
    o
}

fn md_effects(o: &mut String, r: &Report, fx: &EffectsPart) {
    let _ = writeln!(o, "## 7. Unmodelled effects and the residual loop\n");
    let _ = writeln!(
        o,
        "The simulator's effects switched on (default magnitudes): {}. The whole programme ran again on that plant \
         with the seed's models (every identification repeated), then the residual loop \
         (`host_sim::residual`) ranked candidate effect terms on the `jae-ident` log (JAE) and the `tension-ident` log \
         (tension model), kept those that cut the error on the held-out last 30 % of each run and, for the JAE, \
         made none of two other regimes worse (a run under 2.5 N, `robust-2n5`, and one with JAE feedback, \
         `track-jae`, each a fresh run with its own seed), and wrote them into `config.jae.added` and \
         `config.tension.added`; steps 3, 4 and 6 then ran again with that configuration.\n",
        fx.names.join(", ")
    );
    let _ = writeln!(
        o,
        "| quantity | clean | effects, seed's model | effects, after the residual loop |"
    );
    let _ = writeln!(o, "|---|---|---|---|");
    let vs = keys::variants(r);
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
    md_residual(
        o,
        "JAE",
        &fx.residual.jae,
        super::experiments::DEG_PER_RAD,
        "°",
    );
    md_residual(o, "Tension model", &fx.residual.tension, 1.0, "N");
    let _ = writeln!(o, "Identification on the plant with effects:\n");
    md_identification(o, &fx.id);
    md_figure(o, r, "fig_accuracy_variants");
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
    if let Some(l) =
        (!fx.after.loading_summary.faults.is_empty()).then_some(&fx.after.loading_summary)
    {
        let _ = writeln!(
            o,
            "Faulted cases after the residual loop: {}\n",
            l.faults.join("; ")
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

// --- report.json ---------------------------------------------------------------

fn ident_json(id: &Identification) -> Value {
    json!({
        "bm": id.bm,
        "bm_verification": id.bm_validation,
        "jae": id.jae,
        "tension": id.tension,
        "tension_verification": id.tension_validation.iter()
            .map(|(n, e)| json!({"model": n, "errors": e})).collect::<Vec<_>>(),
        "faults": id.faults,
    })
}

fn eval_json(ev: &Evaluation) -> Value {
    json!({
        "loading_summary": ev.loading_summary,
        "loading_cases": ev.loading,
        "loading_stretch_summary": ev.loading_stretch_summary,
        "loading_stretch_cases": ev.loading_stretch,
        "faults": [
            ev.track_motor.fault, ev.track_jae.fault, ev.robust.fault,
        ],
    })
}

/// The goals with their status for every variant.
fn goals_json(r: &Report) -> Vec<Value> {
    let vs = keys::variants(r);
    GOALS
        .iter()
        .map(|g| {
            let mut j = json!({
                "goal": g.goal,
                "key": g.figure.key(),
                "limit": g.limit,
                "at_least": g.at_least,
            });
            for v in &vs {
                j[v.prefix] = match goal_status(v, g) {
                    Some((x, ok)) => json!({"value": x, "met": ok}),
                    None => Value::Null,
                };
            }
            j
        })
        .collect()
}

/// report.json.
pub fn json(r: &Report, map: &BTreeMap<String, f64>, rows: &[Row]) -> Value {
    let mut out = json!({
        "force_variants": serde_json::to_value(&r.variants).unwrap_or(Value::Null),
        "schema": 1,
        "seed": r.options.seed,
        "duration_scale": r.options.duration_scale,
        "runtime_s": r.runtime_s,
        "figures": map,
        "seed_comparison": rows.iter().map(|row| json!({
            "key": format!("clean.{}", row.seed.figure.key()),
            "quantity": row.seed.quantity,
            "unit": row.seed.unit,
            "seed": row.seed.value,
            "ours": row.ours,
            "ratio": row.ratio(),
            "verdict": row.verdict(),
            "source": row.seed.source,
            "note": row.note,
        })).collect::<Vec<_>>(),
        "goals": goals_json(r),
        "identification": {"clean": ident_json(&r.clean.0)},
        "evaluation": {"clean": eval_json(&r.clean.1)},
        "plots": r.figures.iter().map(|w| json!({"stem": w.stem, "caption": w.caption})).collect::<Vec<_>>(),
    });
    if let Some(fx) = &r.effects {
        out["effects"] = json!(fx.names);
        out["identification"]["effects"] = ident_json(&fx.id);
        out["evaluation"]["effects_seed_model"] = eval_json(&fx.before);
        out["evaluation"]["effects_residual"] = eval_json(&fx.after);
        out["residual"] = json!({
            "jae": crate::residual::report::json(&fx.residual.jae),
            "tension": crate::residual::report::json(&fx.residual.tension),
        });
    }
    out
}
