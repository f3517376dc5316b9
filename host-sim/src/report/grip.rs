//! The report's grip-force section (issue "beyond one joint", item 3): the
//! simulated wrist ([`crate::wrist`]) closes on soft objects under the
//! core's grip-force law ([`cable_joint::grip`]) and the true contact force
//! is judged against the set point, on every plant variant with the
//! configuration the variant section identified for it.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};
use cable_joint::Mode;
use serde::Serialize;

use super::programme::run_seed;
use super::variants::VariantResult;
use super::weigh::{Weighed, Weighing, WEIGHT_HOLDS_G};
use super::wrist::{force_panel, object, section_tail, STIFFNESS_N_M, TARGETS_N};
use crate::output::Outputs;
use crate::plot::{stage_figure, Figure, Series};
use crate::scenario::{GRIP_APPROACH_RAD_S, GRIP_S};
use crate::wrist::{grip_stats, gripped_force, run_grip, GripRun, GripStats, WristParams};

/// How a grip ran: the cascade's mode, whether both jaws grip as a pair,
/// and whether the configuration's force scale was calibrated with known
/// weights first.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct How {
    /// The cascade on the motor's angle (`true`) or on the JAE's.
    pub motor: bool,
    /// Both jaws as a pair (the clamp force), or jaw A alone.
    pub pair: bool,
    /// The variant's configuration after `identify --procedure weights` on
    /// four holds of known weights ([`super::weigh`]), or as identified.
    pub weighed: bool,
}

impl How {
    /// The four ways the report runs: the pair and jaw A alone on the
    /// motor's angle (the default), the pair on the JAE's angle, and the
    /// default way again after the weights.
    pub const ALL: [How; 4] = [
        How {
            motor: true,
            pair: true,
            weighed: false,
        },
        How {
            motor: true,
            pair: false,
            weighed: false,
        },
        How {
            motor: false,
            pair: true,
            weighed: false,
        },
        How {
            motor: true,
            pair: true,
            weighed: true,
        },
    ];

    fn mode(self) -> Mode {
        if self.motor {
            Mode::MotorPosition
        } else {
            Mode::JointClosedLoop
        }
    }

    fn label(self) -> &'static str {
        match (self.motor, self.pair, self.weighed) {
            (true, true, false) => "pair, motor angle",
            (true, true, true) => "pair, motor angle, weighed",
            (true, false, false) => "jaw A alone, motor angle",
            (true, false, true) => "jaw A alone, motor angle, weighed",
            (false, true, false) => "pair, JAE angle",
            (false, true, true) => "pair, JAE angle, weighed",
            (false, false, false) => "jaw A alone, JAE angle",
            (false, false, true) => "jaw A alone, JAE angle, weighed",
        }
    }
}

/// One grip on one variant.
#[derive(Clone, Debug, Serialize)]
pub struct GripRow {
    /// Plant variant (every joint of the wrist is this plant).
    pub variant: String,
    /// Control rate, Hz.
    pub rate_hz: f32,
    /// How it ran.
    pub how: How,
    /// Object stiffness, N/m.
    pub stiffness_n_m: f64,
    /// What the run measured (its set point among it).
    pub stats: GripStats,
}

/// The section.
#[derive(Clone, Debug, Serialize)]
pub struct GripSection {
    /// Closing speed before contact, rad/s.
    pub approach_rad_s: f64,
    /// Every grip.
    pub rows: Vec<GripRow>,
    /// The weights' calibration of every variant that ran.
    pub weighings: Vec<Weighing>,
    /// Variants that could not run, and why.
    pub skipped: Vec<String>,
}

/// Every variant with an identified configuration (probing off: a grip
/// never probes), every way, object and set point; `weighed` is
/// [`super::weigh::run_all`]'s for the same variants; `base_seed` seeds the
/// runs.
pub fn run_all(
    variants: &[VariantResult],
    weighed: &[Option<Weighed>],
    base_seed: u64,
) -> Result<GripSection> {
    let mut sec = GripSection {
        approach_rad_s: GRIP_APPROACH_RAD_S,
        rows: Vec::new(),
        weighings: Vec::new(),
        skipped: Vec::new(),
    };
    for (v, w) in variants.iter().zip(weighed) {
        let (Some(mut config), Some(w)) = (v.config, w) else {
            sec.skipped.push(format!(
                "{}: no identified configuration ({})",
                v.name,
                v.error.as_deref().unwrap_or("identification did not run")
            ));
            continue;
        };
        config.probe.enabled = false;
        sec.weighings.push(w.weighing.clone());
        for how in How::ALL {
            let params = WristParams::uniform(v.plant, if how.weighed { w.config } else { config });
            for k in STIFFNESS_N_M {
                for set_n in TARGETS_N {
                    let label = format!("grip/{}/{}/{k}/{set_n}", v.name, how.label());
                    let run = grip_run(how, set_n);
                    let ticks = run_grip(&params, object(k), &run, run_seed(base_seed, &label))
                        .with_context(|| label.clone())?;
                    sec.rows.push(GripRow {
                        variant: v.name.clone(),
                        rate_hz: v.rate_hz,
                        how,
                        stiffness_n_m: k,
                        stats: grip_stats(&ticks, set_n, how.pair),
                    });
                }
            }
        }
    }
    Ok(sec)
}

fn grip_run(how: How, set_n: f64) -> GripRun {
    GripRun {
        set_n,
        approach_rad_s: GRIP_APPROACH_RAD_S,
        pair: how.pair,
        mode: how.mode(),
        grip_s: GRIP_S,
        ..GripRun::default()
    }
}

/// One variant and way, over its objects and set points.
struct Summary {
    name: String,
    rate_hz: f32,
    how: How,
    /// Largest |steady-state error| of the true force, %.
    worst_error_pct: f64,
    /// Largest overshoot, %.
    worst_overshoot_pct: f64,
    /// Slowest settling into ±5 % (`None` if a run never settles).
    slowest_settling_s: Option<f64>,
    /// Widest bound at the set point, N.
    widest_bound_n: f64,
    faults: usize,
}

impl Summary {
    fn met(&self) -> bool {
        self.worst_error_pct <= 5.0 && self.worst_overshoot_pct <= 20.0 && self.faults == 0
    }
}

fn summary(sec: &GripSection) -> Vec<Summary> {
    let mut out: Vec<Summary> = Vec::new();
    for r in &sec.rows {
        if out.iter().any(|s| s.name == r.variant && s.how == r.how) {
            continue;
        }
        let rows: Vec<&GripRow> = sec
            .rows
            .iter()
            .filter(|x| x.variant == r.variant && x.how == r.how)
            .collect();
        let max = |f: &dyn Fn(&GripStats) -> f64| {
            rows.iter().map(|x| f(&x.stats)).fold(f64::NAN, f64::max)
        };
        let slowest = rows
            .iter()
            .map(|x| x.stats.settling_s)
            .try_fold(0.0f64, |acc, s| s.map(|s| acc.max(s)));
        out.push(Summary {
            name: r.variant.clone(),
            rate_hz: r.rate_hz,
            how: r.how,
            worst_error_pct: max(&|s| s.steady_error_pct.abs()),
            worst_overshoot_pct: max(&|s| s.overshoot_pct),
            slowest_settling_s: slowest,
            widest_bound_n: max(&|s| s.steady_hi_n - s.steady_lo_n),
            faults: rows.iter().filter(|x| x.stats.fault.is_some()).count(),
        });
    }
    out
}

/// The goals, per variant and way, met or not.
pub fn goal_lines(sec: &GripSection) -> Vec<(String, bool)> {
    summary(sec)
        .into_iter()
        .map(|s| {
            (
                format!(
                    "grip, {}, {}: worst steady-state error of the true force {:.1} % \
                     (goal <= 5 %), worst overshoot {:.1} % (goal <= 20 %), {} faulted grips",
                    s.name,
                    s.how.label(),
                    s.worst_error_pct,
                    s.worst_overshoot_pct,
                    s.faults
                ),
                s.met(),
            )
        })
        .collect()
}

/// The weights' calibration per variant: the scale it found against the
/// simulator's truth (the plant's spring), and what it wrote.
fn weighings_markdown(o: &mut String, weighings: &[Weighing]) {
    if weighings.is_empty() {
        return;
    }
    let _ = writeln!(
        o,
        "\nThe weights' calibration behind the \"weighed\" rows (scale: the stretch \
         estimate's change per unit of the weights' change; the spring rate the configuration \
         carries before → after, against the plant's, which the simulator knows and a rig \
         does not; a calibrated rate off the plant's spring where the two cables were drawn \
         apart is the stretch estimate's scale, not the spring's; the pin's fitted friction \
         is rescaled with it, against the plant's kinetic and static level):\n"
    );
    let _ = writeln!(
        o,
        "| variant | scale (%σ) | spring rate [N/m] | plant's spring [N/m] | stiffness tolerance | pin [mN·m] | plant's pin [mN·m] | written |"
    );
    let _ = writeln!(o, "|---|---|---|---|---|---|---|---|");
    for w in weighings {
        let scale = w
            .scale
            .map_or_else(|| "-".to_owned(), |(s, p)| format!("{s:.3} ({p:.1})"));
        let written = if w.refused.is_empty() {
            "yes".to_owned()
        } else {
            format!("refused: {}", w.refused.replace('|', "\\|"))
        };
        let pin = w.pin_coulomb_nm.map_or_else(
            || "model C's upper bound, kept".to_owned(),
            |(a, b)| format!("{:.2} → {:.2}", 1e3 * a, 1e3 * b),
        );
        let _ = writeln!(
            o,
            "| {} | {scale} | {:.0} → {:.0} | {:.0} | {:.3} → {:.3} | {pin} | {:.2}, {:.2} | {written} |",
            w.variant,
            w.spring_n_m.0,
            w.spring_n_m.1,
            w.plant_spring_n_m,
            w.stiffness_tolerance.0,
            w.stiffness_tolerance.1,
            1e3 * w.plant_pin_nm.0,
            1e3 * w.plant_pin_nm.1,
        );
    }
}

fn settling(s: Option<f64>) -> String {
    s.map_or_else(|| "never".to_owned(), |s| format!("{s:.2} s"))
}

/// The section in markdown.
pub fn markdown(sec: &GripSection, figure: Option<&str>) -> String {
    let mut o = String::new();
    let _ = writeln!(o, "## Grip-force control\n");
    let _ = writeln!(
        o,
        "The simulated wrist of the section above, its jaws under the core's grip law \
         (`cable_joint::grip`: an admittance law moves each jaw's angle reference until the \
         fused force estimate reads the set point; its gain follows the contact stiffness \
         measured on the way in, its crossover an eighth of the estimate's low-pass). From \
         open jaws, the command `Trajectory::Grip` closes at {:.2} rad/s until contact, \
         regulates for {:.0} s, then the jaws open under position control. Four ways: both \
         jaws as a pair regulating the clamp force (Eq. 5) and kept level, on the motor's \
         angle (the default), jaw A alone on the motor's angle, the pair on the JAE's angle, \
         and the default way again with the force scale calibrated on known weights \
         (\"weighed\": the user's step after identification, `identify --procedure weights` \
         on four holds at 0° of {} g each way, table below; where the calibration is \
         refused the configuration stays as identified). Judged on the true contact force: steady-state error over the last second, \
         overshoot above the set point, time to enter ±5 % for good. The bound is the \
         regulated estimate's over the last second: the law makes the estimate read the set \
         point, so the bound is all it can promise about the true force. On the motor's \
         angle a pair's estimate takes each jaw's pin friction at its identified kinetic \
         level against the object's side (`fusion.pin_identified`); jaw A alone and the pair \
         on the JAE's angle read it as zero (docs/force.md, \"The pin's friction in a \
         grip\"). Probing is off (a grip never probes). Reproduce: `cargo run --release -p \
         host-sim` (this section).\n",
        sec.approach_rad_s,
        GRIP_S,
        WEIGHT_HOLDS_G.map(|g| format!("{g:.0}")).join(" and ")
    );
    let _ = writeln!(
        o,
        "| variant | rate | way | worst \\|error\\| | worst overshoot | slowest settling (±5 %) | widest bound at the set point | faulted | goals |"
    );
    let _ = writeln!(o, "|---|---|---|---|---|---|---|---|---|");
    for s in summary(sec) {
        let _ = writeln!(
            o,
            "| {} | {:.0} Hz | {} | {:.1} % | {:.1} % | {} | {:.2} N | {} | {} |",
            s.name,
            s.rate_hz,
            s.how.label(),
            s.worst_error_pct,
            s.worst_overshoot_pct,
            settling(s.slowest_settling_s),
            s.widest_bound_n,
            s.faults,
            if s.met() { "met" } else { "**not met**" }
        );
    }
    weighings_markdown(&mut o, &sec.weighings);
    let _ = writeln!(
        o,
        "\nEvery grip (k: object stiffness; error and overshoot of the true force against the \
         set point; estimate and bound: means over the last second):\n"
    );
    let _ = writeln!(
        o,
        "| variant | way | k [N/m] | set [N] | true [N] | error | overshoot | settling | estimate [N] | bound [N] | coverage | fault |"
    );
    let _ = writeln!(o, "|---|---|---|---|---|---|---|---|---|---|---|---|");
    for r in &sec.rows {
        let s = &r.stats;
        let _ = writeln!(
            o,
            "| {} | {} | {:.0} | {:.0} | {:.3} | {:+.1} % | {:.1} % | {} | {:.3} | [{:.2}, {:.2}] | {:.0} % | {} |",
            r.variant,
            r.how.label(),
            r.stiffness_n_m,
            s.set_n,
            s.steady_true_n,
            s.steady_error_pct,
            s.overshoot_pct,
            settling(s.settling_s),
            s.steady_est_n,
            s.steady_lo_n,
            s.steady_hi_n,
            100.0 * s.steady_coverage,
            s.fault.as_deref().unwrap_or("-")
        );
    }
    section_tail(
        &mut o,
        &sec.skipped,
        figure,
        "grip force: true contact force, estimate and bound against the set point",
    );
    o
}

/// The figure: the first variant with a configuration (the default
/// plant), the pair on the motor's angle, 2 N on the soft and the firm
/// object: the true contact force, the regulated estimate and its bound.
pub fn stage_figure_for(
    variants: &[VariantResult],
    base_seed: u64,
    out: &mut Outputs,
    dir: &Path,
) -> Result<Option<String>> {
    let Some((v, mut config)) = super::variants::first_identified(variants) else {
        return Ok(None);
    };
    config.probe.enabled = false;
    let params = WristParams::uniform(v.plant, config);
    let how = How::ALL[0];
    let set_n = 2.0;
    let mut panels = Vec::new();
    for k in STIFFNESS_N_M {
        let label = format!("grip/figure/{}/{k}", v.name);
        let ticks = run_grip(
            &params,
            object(k),
            &grip_run(how, set_n),
            run_seed(base_seed, &label),
        )?;
        let panel = force_panel(
            format!("{}: {} N grip, {k:.0} N/m, {}", v.name, set_n, how.label()),
            &ticks,
            "estimate (regulated)",
            &|x| gripped_force(x, how.pair),
        );
        let t: Vec<f64> = ticks.iter().map(|(_, x)| x.t_s).collect();
        let n = t.len();
        panels.push(panel.with(Series::line("set point", t, vec![set_n; n])));
    }
    let stem = "fig_grip";
    stage_figure(out, &Figure::grid(panels, 1), &dir.join(stem))?;
    Ok(Some(stem.to_owned()))
}
