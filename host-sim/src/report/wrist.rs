//! The report's wrist section (issue "beyond one joint", item 2): the clamp
//! force (seed 000 Eq. 4-5) of the simulated four-joint wrist
//! ([`crate::wrist`]) against the true contact force, grasping, holding and
//! releasing soft objects, on every plant variant with the configuration
//! the variant section identified for it, passive and with probing, and
//! both again with the force scale from known weights
//! ([`super::weigh`]).

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};
use serde::Serialize;

use super::programme::run_seed;
use super::variants::VariantResult;
use super::weigh::Weighed;
use crate::output::Outputs;
use crate::plot::{stage_figure, Figure, Panel, Series};
use crate::wrist::{
    grasp_stats, run_grasp, Grasp, GraspStats, Phase, SoftObject, WristParams, WristTick,
};
use cable_joint::wrist::Interval;

/// Object stiffnesses across the jaws, N/m: tissue-soft and ten times
/// stiffer (the "objects 10x apart in stiffness").
pub const STIFFNESS_N_M: [f64; 2] = [1000.0, 10_000.0];
/// Squeezes the closing angle aims at, N.
pub const TARGETS_N: [f64; 3] = [1.0, 2.0, 4.0];
/// The object's width at rest, m (the open jaws' tips are 13.7 mm apart).
pub const OBJECT_WIDTH_M: f64 = 10e-3;
/// The object's damping across the jaws, N·s/m (the simulator's).
pub use crate::plant::OBJECT_DAMPING_N_S_M;

/// One grasp on one variant.
#[derive(Clone, Debug, Serialize)]
pub struct WristRow {
    /// Plant variant (every joint of the wrist is this plant).
    pub variant: String,
    /// Control rate, Hz.
    pub rate_hz: f32,
    /// Probing on.
    pub probing: bool,
    /// The configuration after the weights' calibration
    /// ([`super::weigh`]), or as identified.
    pub weighed: bool,
    /// Object stiffness, N/m.
    pub stiffness_n_m: f64,
    /// Target squeeze, N.
    pub target_n: f64,
    /// What the run measured.
    pub stats: GraspStats,
}

/// The section.
#[derive(Clone, Debug, Serialize)]
pub struct WristSection {
    /// Every grasp.
    pub rows: Vec<WristRow>,
    /// Variants that could not run (no identified configuration), and why.
    pub skipped: Vec<String>,
}

/// The report's object of stiffness `k` N/m.
pub fn object(k: f64) -> SoftObject {
    SoftObject {
        width_m: OBJECT_WIDTH_M,
        stiffness_n_m: k,
        damping_n_s_m: OBJECT_DAMPING_N_S_M,
    }
}

/// The modes a variant runs in: (probing, weighed).
const MODES: [(bool, bool); 4] = [(false, false), (true, false), (false, true), (true, true)];

/// A mode's name in the tables.
fn mode_label(probing: bool, weighed: bool) -> &'static str {
    match (probing, weighed) {
        (false, false) => "passive",
        (true, false) => "probing",
        (false, true) => "passive, weighed",
        (true, true) => "probing, weighed",
    }
}

/// Every variant with an identified configuration, passive and probing,
/// each as identified and weighed (`weighed` is
/// [`super::weigh::run_all`]'s for the same variants), every object and
/// target; `base_seed` seeds the runs.
pub fn run_all(
    variants: &[VariantResult],
    weighed: &[Option<Weighed>],
    base_seed: u64,
) -> Result<WristSection> {
    let mut sec = WristSection {
        rows: Vec::new(),
        skipped: Vec::new(),
    };
    for (v, w) in variants.iter().zip(weighed) {
        let (Some(config), Some(w)) = (v.config, w) else {
            sec.skipped.push(format!(
                "{}: no identified configuration ({})",
                v.name,
                v.error.as_deref().unwrap_or("identification did not run")
            ));
            continue;
        };
        for (probing, weighed) in MODES {
            let mut c = if weighed { w.config } else { config };
            c.probe.enabled = probing;
            let params = WristParams::uniform(v.plant, c);
            for k in STIFFNESS_N_M {
                for target in TARGETS_N {
                    // (The label of the modes without the weights as before.)
                    let label = if weighed {
                        format!("wrist/{}/{probing}/weighed/{k}/{target}", v.name)
                    } else {
                        format!("wrist/{}/{probing}/{k}/{target}", v.name)
                    };
                    let grasp = Grasp {
                        target_n: target,
                        ..Grasp::default()
                    };
                    let ticks = run_grasp(&params, object(k), &grasp, run_seed(base_seed, &label))
                        .with_context(|| label.clone())?;
                    sec.rows.push(WristRow {
                        variant: v.name.clone(),
                        rate_hz: v.rate_hz,
                        probing,
                        weighed,
                        stiffness_n_m: k,
                        target_n: target,
                        stats: grasp_stats(&params.geometry, &ticks),
                    });
                }
            }
        }
    }
    Ok(sec)
}

/// One variant and mode, summarised over its grasps.
struct Summary {
    name: String,
    rate_hz: f32,
    probing: bool,
    weighed: bool,
    /// Worst hold accuracy over the grasps whose true squeeze is >= 1 N, %.
    worst_pct: f64,
    /// Least coverage over whole grasps (open, grasp, hold, release).
    coverage: f64,
    /// Least coverage over the holds.
    hold_coverage: f64,
    /// Largest |estimate| with the jaws open, N.
    open_n: f64,
    faults: usize,
}

impl Summary {
    fn met(&self) -> bool {
        self.worst_pct >= 90.0 && self.coverage >= 0.95 && self.faults == 0
    }
}

fn summary(sec: &WristSection) -> Vec<Summary> {
    let mut out: Vec<Summary> = Vec::new();
    for r in &sec.rows {
        if out
            .iter()
            .any(|s| s.name == r.variant && s.probing == r.probing && s.weighed == r.weighed)
        {
            continue;
        }
        let rows: Vec<&WristRow> = sec
            .rows
            .iter()
            .filter(|x| x.variant == r.variant && x.probing == r.probing && x.weighed == r.weighed)
            .collect();
        let worst = rows
            .iter()
            .filter(|x| x.stats.fault.is_none() && x.stats.hold_true_n >= 1.0)
            .map(|x| x.stats.hold_accuracy_pct)
            .fold(f64::NAN, f64::min);
        let coverage = rows
            .iter()
            .map(|x| x.stats.coverage)
            .fold(f64::NAN, f64::min);
        let open = rows.iter().map(|x| x.stats.open_max_n).fold(0.0, f64::max);
        let hold_coverage = rows
            .iter()
            .map(|x| x.stats.hold_coverage)
            .fold(f64::NAN, f64::min);
        let faults = rows.iter().filter(|x| x.stats.fault.is_some()).count();
        out.push(Summary {
            name: r.variant.clone(),
            rate_hz: r.rate_hz,
            probing: r.probing,
            weighed: r.weighed,
            worst_pct: worst,
            coverage,
            hold_coverage,
            open_n: open,
            faults,
        });
    }
    out
}

/// The goals, per variant and mode, met or not.
pub fn goal_lines(sec: &WristSection) -> Vec<(String, bool)> {
    summary(sec)
        .into_iter()
        .map(|s| {
            let mode = mode_label(s.probing, s.weighed);
            (
                format!(
                    "wrist, {}, {mode}: clamp force worst case while holding {:.1} % \
                     (goal >= 90 %), bound coverage {:.1} % (goal >= 95 %; {:.1} % over the \
                     holds), {} faulted grasps",
                    s.name,
                    s.worst_pct,
                    100.0 * s.coverage,
                    100.0 * s.hold_coverage,
                    s.faults
                ),
                s.met(),
            )
        })
        .collect()
}

/// The section in markdown.
pub fn markdown(sec: &WristSection, figure: Option<&str>) -> String {
    let mut o = String::new();
    let _ = writeln!(o, "## The wrist's clamp force (seed 000 Eq. 1-5)\n");
    let _ = writeln!(
        o,
        "Four joints (roll, pitch, jaw A, jaw B), each the single-joint cable plant of the \
         variant with its own noise, each controlled by the core with the configuration the \
         variant section identified, all four stepped by `cable_joint::joints::Joints`. The wrist \
         pitches to 30° and the jaws (20 mm, open 20° each) close on a soft object 10 mm wide \
         at their tips (a spring–damper across the gap, pushing only, normal to the jaws), hold \
         3 s and open again. The clamp force is Eq. 5 on Eq. 4's jaw forces from each joint's \
         fused estimate and bound (`cable_joint::wrist`). Accuracy: the mean estimate against \
         the mean true contact force over the hold's second half; coverage: the share of every \
         tick (open, grasp, hold, release) whose true contact force lies in the bound. Every \
         assumption (geometry, decoupled joints, no gravity) is in `host-sim/src/wrist.rs` and \
         `src/control/wrist.rs`. \"Weighed\": the same again with the force scale \
         calibrated on known weights first (the grip section's table below gives each \
         calibration). Reproduce: `cargo run --release -p host-sim` (this section).\n"
    );
    let _ = writeln!(
        o,
        "| variant | rate | mode | worst hold accuracy, true ≥ 1 N | least coverage, whole grasp | least coverage, hold | largest \\|estimate\\| jaws open | faulted grasps | goals |"
    );
    let _ = writeln!(o, "|---|---|---|---|---|---|---|---|---|");
    for s in summary(sec) {
        let _ = writeln!(
            o,
            "| {} | {:.0} Hz | {} | {:.1} % | {:.1} % | {:.1} % | {:.3} N | {} | {} |",
            s.name,
            s.rate_hz,
            mode_label(s.probing, s.weighed),
            s.worst_pct,
            100.0 * s.coverage,
            100.0 * s.hold_coverage,
            s.open_n,
            s.faults,
            if s.met() { "met" } else { "**not met**" }
        );
    }
    let _ = writeln!(
        o,
        "\nWhat the bound allows for: each joint's estimate and bound pass through the DOB's \
         low-pass `Q` (`cable_joint::fusion`), so while the squeeze rises or falls the true \
         force runs ahead of both by about `F'/g`; the bound widens by that lag \
         (`Q[F] - Q^2[F]`) on the side the force moves to. It also carries the JAE sign term's \
         own uncertainty (`fusion.jae_error_rad`) and the cables' stiffness scale, a share \
         `fusion.stiffness_tolerance` of each joint's stretch torque, which is why it widens \
         with the squeeze. What still escapes is in the coverage columns."
    );
    total_force_paragraph(&mut o, sec);
    let _ = writeln!(
        o,
        "\nEvery grasp (k: object stiffness; target: the squeeze the closing angle aims at with \
         rigid jaws; the joints' position error sets the true squeeze):\n"
    );
    let _ = writeln!(
        o,
        "| variant | mode | k [N/m] | target [N] | true hold [N] | estimate [N] | accuracy | coverage (all / hold) | bound width | fault |"
    );
    let _ = writeln!(o, "|---|---|---|---|---|---|---|---|---|---|");
    for r in &sec.rows {
        let s = &r.stats;
        let _ = writeln!(
            o,
            "| {} | {} | {:.0} | {:.0} | {:.3} | {:.3} | {:.1} % | {:.1} / {:.1} % | {:.3} N | {} |",
            r.variant,
            mode_label(r.probing, r.weighed),
            r.stiffness_n_m,
            r.target_n,
            s.hold_true_n,
            s.hold_est_n,
            s.hold_accuracy_pct,
            100.0 * s.coverage,
            100.0 * s.hold_coverage,
            s.hold_bound_width_n,
            s.fault.as_deref().unwrap_or("-")
        );
    }
    section_tail(
        &mut o,
        &sec.skipped,
        figure,
        "clamp force estimate and bound against the true contact force",
    );
    o
}

/// Eq. 5's total force over every grasp: per wrist-frame component, the
/// least hold coverage, the median bound width and the force limit's mean
/// share of it.
fn total_force_paragraph(o: &mut String, sec: &WristSection) {
    if sec.rows.is_empty() {
        return;
    }
    let per = |k: usize| {
        let least = sec
            .rows
            .iter()
            .map(|r| r.stats.hold_total_coverage[k])
            .fold(f64::INFINITY, f64::min);
        let mut widths: Vec<f64> = sec
            .rows
            .iter()
            .map(|r| r.stats.hold_total.width_n[k])
            .collect();
        widths.sort_by(f64::total_cmp);
        let median = widths[widths.len() / 2];
        let share = sec
            .rows
            .iter()
            .map(|r| r.stats.hold_total.limit_share[k])
            .sum::<f64>()
            / sec.rows.len() as f64;
        (100.0 * least, median, 100.0 * share)
    };
    let [x, y, z] = [0, 1, 2].map(per);
    let _ = writeln!(
        o,
        "\nEq. 5's total force `F^a + F^b` (`cable_joint::wrist::total_force`): the four \
         joints' torque bounds solved together, since the roll and pitch joints carry both \
         jaws (summing the two jaws' Eq. 4 forces would count their torques twice); six \
         force components meet four torques, and what the joints do not see is bounded by \
         the force limit, each jaw's drive squeeze at its current limit. Over every grasp's \
         hold, per wrist-frame axis (least coverage of the true total; median bound width; \
         the limit's mean share of the width): `x_2`, the pitch joint's, {:.1} %, {:.3} N, \
         {:.1} % (the jaws close at nearly equal angles, so the pitch joint sees the \
         total; the simulated squeeze loads only the jaws, so that total is zero here and \
         the figure shows the bound's width, not a tracked push); `y_2`, across the jaws, {:.1} %, {:.1} N, {:.1} %; `z_2`, along the wrist, \
         {:.1} %, {:.1} N, {:.1} %. Along `y_2` and `z_2` the joints see little or nothing \
         of a grasp's total (both jaws' pushes along themselves add there, the roll joint \
         sees their difference): the bound says only that it is within the limit.",
        x.0, x.1, x.2, y.0, y.1, y.2, z.0, z.1, z.2
    );
}

/// The figure: one grasp on the first variant with a configuration (the
/// default plant), 1000 N/m and a 2 N target, passive and with probing:
/// the true contact force, the clamp estimate and its bound over time.
pub fn stage_figure_for(
    variants: &[VariantResult],
    base_seed: u64,
    out: &mut Outputs,
    dir: &Path,
) -> Result<Option<String>> {
    let Some((v, config)) = super::variants::first_identified(variants) else {
        return Ok(None);
    };
    let mut panels = Vec::new();
    for probing in [false, true] {
        let mut c = config;
        c.probe.enabled = probing;
        let params = WristParams::uniform(v.plant, c);
        let label = format!("wrist/figure/{}/{probing}", v.name);
        let ticks = run_grasp(
            &params,
            object(STIFFNESS_N_M[0]),
            &Grasp::default(),
            run_seed(base_seed, &label),
        )?;
        let mode = mode_label(probing, false);
        panels.push(force_panel(
            format!("{}: clamp force, {mode}", v.name),
            &ticks,
            "estimate (Eq. 5)",
            &|x| (x.clamp_n, x.clamp_bound_n),
        ));
    }
    let stem = "fig_wrist_clamp";
    stage_figure(out, &Figure::grid(panels, 1), &dir.join(stem))?;
    Ok(Some(stem.to_owned()))
}

/// A wrist section's end in report.md: the variants that could not run,
/// and its figure under `caption`.
pub fn section_tail(o: &mut String, skipped: &[String], figure: Option<&str>, caption: &str) {
    for s in skipped {
        let _ = writeln!(o, "\nNot run: {s}");
    }
    if let Some(stem) = figure {
        let _ = writeln!(o, "\n![{caption}]({stem}.svg)\n");
    }
}

/// A panel of a run's true contact force against an estimate and its
/// bound over time (`force` gives the estimate and bound of a tick).
pub fn force_panel(
    title: String,
    ticks: &[(Phase, WristTick)],
    estimate: &str,
    force: &dyn Fn(&WristTick) -> (f64, Interval),
) -> Panel {
    let t: Vec<f64> = ticks.iter().map(|(_, x)| x.t_s).collect();
    let col =
        |f: &dyn Fn(&WristTick) -> f64| -> Vec<f64> { ticks.iter().map(|(_, x)| f(x)).collect() };
    Panel::new(title, "t [s]", "force [N]")
        .with(Series::line(
            "true contact",
            t.clone(),
            col(&|x| x.contact_n),
        ))
        .with(Series::line(estimate, t.clone(), col(&|x| force(x).0)))
        .with(Series::line(
            "bound, low",
            t.clone(),
            col(&|x| f64::from(force(x).1.lo)),
        ))
        .with(Series::line(
            "bound, high",
            t,
            col(&|x| f64::from(force(x).1.hi)),
        ))
}
