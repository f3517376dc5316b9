//! Where the project stands: its goals for every variant, step 7's table
//! (clean, effects with the seed's model, effects after the residual loop)
//! and the faults latched in any run.

use std::fmt::Write as _;

use super::keys::{
    variants, Accuracy, Diff, Estimate, Figure, Load, Loading, NoLoad, Stat, Track, Variant,
};
use super::programme::{Evaluation, Identification};
use super::render::fmt_num;
use super::Report;

/// One goal of the project.
#[derive(Clone, Copy, Debug)]
pub struct Goal {
    /// Text.
    pub goal: &'static str,
    /// The figure judged.
    pub figure: Figure,
    /// Limit, in the figure's unit.
    pub limit: f64,
    /// `true`: the value must be at least the limit; `false`: at most.
    pub at_least: bool,
    /// A count of faults that must be zero for the goal to be met (the
    /// figure is computed only up to a fault).
    pub faults: Option<Figure>,
}

/// The goals stated for the project.
pub const GOALS: [Goal; 7] = [
    Goal {
        goal: "force accuracy ≥ 98 % above 1 N (worst case, all angles and directions)",
        figure: Figure::accuracy(Estimate::Dob, Load::Above1n, Accuracy::MinPct),
        limit: 98.0,
        at_least: true,
        faults: Some(Figure::loading(Estimate::Dob, Loading::FaultedCases)),
    },
    Goal {
        goal: "force accuracy ≥ 95 % at 0.3 N (worst case)",
        figure: Figure::accuracy(Estimate::Dob, Load::At0n3, Accuracy::MinPct),
        limit: 95.0,
        at_least: true,
        faults: Some(Figure::loading(Estimate::Dob, Loading::FaultedCases)),
    },
    Goal {
        goal: "static no-load error within ±0.03 N",
        figure: Figure::no_load(Estimate::Dob, NoLoad::Static, Stat::MaxAbs),
        limit: 0.03,
        at_least: false,
        faults: None,
    },
    Goal {
        goal: "JAE max error ≤ 0.3° (identification run, through the core)",
        figure: Figure::jae_error(Stat::MaxAbs),
        limit: 0.3,
        at_least: false,
        faults: None,
    },
    Goal {
        goal: "JAE max error ≤ 0.3° in closed loop (track-jae, actual − estimated)",
        figure: Figure::track(Track::Jae, Diff::ActualMinusEstimated, Stat::MaxAbs),
        limit: 0.3,
        at_least: false,
        faults: Some(Figure::track_faulted(Track::Jae)),
    },
    Goal {
        goal: "tracking max error ≤ 0.5° (track-jae, desired − actual)",
        figure: Figure::track(Track::Jae, Diff::DesiredMinusActual, Stat::MaxAbs),
        limit: 0.5,
        at_least: false,
        faults: Some(Figure::track_faulted(Track::Jae)),
    },
    Goal {
        goal: "tracking max error ≤ 0.5° under 2.5 N (robust-2n5)",
        figure: Figure::track(Track::Robust, Diff::DesiredMinusActual, Stat::MaxAbs),
        limit: 0.5,
        at_least: false,
        faults: Some(Figure::track_faulted(Track::Robust)),
    },
];

/// Whether variant `v` meets goal `g`, and its value (none when the variant
/// lacks the figure).
pub fn goal_status(v: &Variant, g: &Goal) -> Option<(f64, bool)> {
    let x = g.figure.value(v)?;
    let faults = g.faults.and_then(|f| f.value(v)).unwrap_or(0.0);
    let ok = x.is_finite()
        && faults == 0.0
        && if g.at_least {
            x >= g.limit
        } else {
            x <= g.limit
        };
    Some((x, ok))
}

/// A goal's status as a table cell: the value and `met` or `NOT met`.
pub fn status_text(s: Option<(f64, bool)>) -> String {
    match s {
        Some((v, ok)) => format!("{} {}", fmt_num(v), if ok { "met" } else { "NOT met" }),
        None => "n/a".into(),
    }
}

/// Goals as a text table.
pub fn goals_table(r: &Report) -> String {
    let vs = variants(r);
    let mut s = String::new();
    let _ = write!(s, "{:<72}", "goal");
    for v in &vs {
        let _ = write!(s, " {:>22}", v.short_title);
    }
    let _ = writeln!(s);
    for g in &GOALS {
        let _ = write!(s, "{:<72}", g.goal);
        for v in &vs {
            let _ = write!(s, " {:>22}", status_text(goal_status(v, g)));
        }
        let _ = writeln!(s);
    }
    s
}

/// One row of step 7's table.
#[derive(Clone, Copy, Debug)]
pub struct Step7Row {
    /// The figure, of every variant.
    pub figure: Figure,
    /// What it is.
    pub quantity: &'static str,
    /// Unit (empty for a count).
    pub unit: &'static str,
}

impl Step7Row {
    /// The figure of variant `v` (NaN when it lacks it).
    pub fn value(&self, v: &Variant) -> f64 {
        self.figure.value(v).unwrap_or(f64::NAN)
    }
}

/// Step 7's rows.
pub const STEP7_ROWS: [Step7Row; 19] = [
    Step7Row {
        figure: Figure::jae_error(Stat::MeanAbs),
        quantity: "JAE error on jae-ident, mean |e|",
        unit: "°",
    },
    Step7Row {
        figure: Figure::jae_error(Stat::MaxAbs),
        quantity: "JAE error on jae-ident, max |e|",
        unit: "°",
    },
    Step7Row {
        figure: Figure::track(Track::Motor, Diff::DesiredMinusActual, Stat::MaxAbs),
        quantity: "track-motor, max |desired − actual|",
        unit: "°",
    },
    Step7Row {
        figure: Figure::track(Track::Jae, Diff::DesiredMinusActual, Stat::MeanAbs),
        quantity: "track-jae, mean |desired − actual|",
        unit: "°",
    },
    Step7Row {
        figure: Figure::track(Track::Jae, Diff::DesiredMinusActual, Stat::MaxAbs),
        quantity: "track-jae, max |desired − actual|",
        unit: "°",
    },
    Step7Row {
        figure: Figure::track(Track::Jae, Diff::ActualMinusEstimated, Stat::MaxAbs),
        quantity: "track-jae, max |actual − estimated|",
        unit: "°",
    },
    Step7Row {
        figure: Figure::track(Track::Jae, Diff::TrueMinusEstimated, Stat::MaxAbs),
        quantity: "track-jae, max |true − estimated| (the plant's angle)",
        unit: "°",
    },
    Step7Row {
        figure: Figure::track(Track::Robust, Diff::DesiredMinusActual, Stat::MaxAbs),
        quantity: "2.5 N, max |desired − actual|",
        unit: "°",
    },
    Step7Row {
        figure: Figure::track(Track::Robust, Diff::ActualMinusEstimated, Stat::MaxAbs),
        quantity: "2.5 N, max |actual − estimated|",
        unit: "°",
    },
    Step7Row {
        figure: Figure::track(Track::Robust, Diff::TrueMinusEstimated, Stat::MaxAbs),
        quantity: "2.5 N, max |true − estimated| (the plant's angle)",
        unit: "°",
    },
    Step7Row {
        figure: Figure::no_load(Estimate::Dob, NoLoad::Static, Stat::MaxAbs),
        quantity: "static no-load error (±)",
        unit: "N",
    },
    Step7Row {
        figure: Figure::no_load(Estimate::Dob, NoLoad::Static, Stat::Rms),
        quantity: "static no-load error, RMS",
        unit: "N",
    },
    Step7Row {
        figure: Figure::no_load(Estimate::Dob, NoLoad::DynamicPos, Stat::MaxAbs),
        quantity: "dynamic no-load error, positive runs (±)",
        unit: "N",
    },
    Step7Row {
        figure: Figure::no_load(Estimate::Dob, NoLoad::DynamicNeg, Stat::MaxAbs),
        quantity: "dynamic no-load error, negative runs (±)",
        unit: "N",
    },
    Step7Row {
        figure: Figure::accuracy(Estimate::Dob, Load::Above1n, Accuracy::MinPct),
        quantity: "accuracy ≥ 1 N, worst case",
        unit: "%",
    },
    Step7Row {
        figure: Figure::accuracy(Estimate::Dob, Load::Above1n, Accuracy::MeanPct),
        quantity: "accuracy ≥ 1 N, mean",
        unit: "%",
    },
    Step7Row {
        figure: Figure::accuracy(Estimate::Dob, Load::At0n3, Accuracy::MinPct),
        quantity: "accuracy at 0.3 N, worst case",
        unit: "%",
    },
    Step7Row {
        figure: Figure::accuracy(Estimate::Dob, Load::At0n3, Accuracy::MeanPct),
        quantity: "accuracy at 0.3 N, mean",
        unit: "%",
    },
    Step7Row {
        figure: Figure::loading(Estimate::Dob, Loading::FaultedCases),
        quantity: "loading cases with a latched fault",
        unit: "",
    },
];

/// Step 7 as a text table.
pub fn step7_table(r: &Report) -> String {
    let vs = variants(r);
    let mut s = String::new();
    let _ = write!(s, "{:<50}", "quantity");
    for v in &vs {
        let _ = write!(s, " {:>20}", v.short_title);
    }
    let _ = writeln!(s);
    for row in &STEP7_ROWS {
        let _ = write!(
            s,
            "{:<50}",
            if row.unit.is_empty() {
                row.quantity.to_owned()
            } else {
                format!("{} [{}]", row.quantity, row.unit)
            }
        );
        for v in &vs {
            let _ = write!(s, " {:>20}", fmt_num(row.value(v)));
        }
        let _ = writeln!(s);
    }
    s
}

/// Every fault latched in any run, as `variant: run: fault`.
pub fn fault_lines(r: &Report) -> Vec<String> {
    let mut out = Vec::new();
    let mut add = |variant: &str, id: Option<&Identification>, ev: &Evaluation| {
        if let Some(id) = id {
            for f in &id.faults {
                out.push(format!("{variant}: {f}"));
            }
        }
        for t in [&ev.track_motor, &ev.track_jae, &ev.robust] {
            if let Some(f) = &t.fault {
                out.push(format!("{variant}: {}: {f}", t.scenario));
            }
        }
        for f in &ev.loading_summary.faults {
            out.push(format!("{variant}: loading {f}"));
        }
    };
    add("clean", Some(&r.clean.0), &r.clean.1);
    if let Some(fx) = &r.effects {
        add("effects, seed's model", Some(&fx.id), &fx.before);
        add("effects + residual", None, &fx.after);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// report.json's `goals[].key`: scripts read them.
    #[test]
    fn goals_keep_their_keys() {
        let goals: Vec<String> = GOALS.iter().map(|g| g.figure.key()).collect();
        assert_eq!(
            goals,
            [
                "loading.accuracy.above_1n.min_pct",
                "loading.accuracy.at_0n3.min_pct",
                "loading.static_noload.max_abs_n",
                "jae.error.max_abs_deg",
                "track_jae.actual_minus_estimated.max_abs_deg",
                "track_jae.desired_minus_actual.max_abs_deg",
                "robust_2n5.desired_minus_actual.max_abs_deg",
            ]
        );
    }
}
