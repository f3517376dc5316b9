//! The seed's published figures (seed 000 Sect. 4) and the comparison of
//! this project's figures with them: the rows of report.md's "Results
//! against the seed", report.json's `seed_comparison` and the terminal table.

use std::fmt::Write as _;

use super::keys::{
    variants, Accuracy, Diff, Estimate, Eval, Figure, ForceError, Ident, Load, Loading, NoLoad,
    Stat, Track, Variant,
};
use super::render::fmt_num;
use super::Report;

/// How a row compares.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Better {
    /// An error: smaller magnitude is better (ratio = |ours| / |seed|).
    Lower,
    /// An accuracy: higher is better (ratio = ours / seed).
    Higher,
    /// An identified parameter (ratio = ours / seed, no verdict).
    Info,
}

/// One figure the seed publishes and the figure of ours it is compared
/// with.
#[derive(Clone, Copy, Debug)]
pub struct SeedRow {
    /// Our figure, of the clean plant.
    pub figure: Figure,
    /// What it is.
    pub quantity: &'static str,
    /// Unit.
    pub unit: &'static str,
    /// The seed's value, in `unit`.
    pub value: f64,
    /// Comparison kind.
    pub better: Better,
    /// Where the seed states it.
    pub source: &'static str,
}

/// Every number of DESIGN.md's "results to beat" table, and the other
/// figures the seed's text gives for the same experiments, in the report's
/// order.
pub const SEED: &[SeedRow] = &[
    SeedRow {
        figure: Figure::jae_error(Stat::MeanAbs),
        quantity: "JAE identification error, mean |e|",
        unit: "°",
        value: 0.2750,
        better: Better::Lower,
        source: "Sect. 4.1, Fig. 9",
    },
    SeedRow {
        figure: Figure::jae_error(Stat::Max),
        quantity: "JAE identification error, max",
        unit: "°",
        value: 0.8355,
        better: Better::Lower,
        source: "Sect. 4.1, Fig. 9",
    },
    SeedRow {
        figure: Figure::jae_error(Stat::Min),
        quantity: "JAE identification error, min",
        unit: "°",
        value: -0.8321,
        better: Better::Lower,
        source: "Sect. 4.1, Fig. 9",
    },
    SeedRow {
        figure: Figure::track(Track::Motor, Diff::DesiredMinusActual, Stat::MeanAbs),
        quantity: "tracking without JAE, mean |desired − actual|",
        unit: "°",
        value: 1.912,
        better: Better::Lower,
        source: "Fig. 10",
    },
    SeedRow {
        figure: Figure::track(Track::Motor, Diff::DesiredMinusActual, Stat::MaxAbs),
        quantity: "tracking without JAE, max |desired − actual|",
        unit: "°",
        value: 4.134,
        better: Better::Lower,
        source: "Fig. 10",
    },
    SeedRow {
        figure: Figure::track(Track::Jae, Diff::DesiredMinusActual, Stat::Mean),
        quantity: "tracking with JAE, desired − actual, mean",
        unit: "°",
        value: -0.150,
        better: Better::Lower,
        source: "Fig. 12",
    },
    SeedRow {
        figure: Figure::track(Track::Jae, Diff::DesiredMinusActual, Stat::Max),
        quantity: "tracking with JAE, desired − actual, max",
        unit: "°",
        value: 0.905,
        better: Better::Lower,
        source: "Fig. 12",
    },
    SeedRow {
        figure: Figure::track(Track::Jae, Diff::DesiredMinusActual, Stat::Min),
        quantity: "tracking with JAE, desired − actual, min",
        unit: "°",
        value: -0.974,
        better: Better::Lower,
        source: "Fig. 12",
    },
    SeedRow {
        figure: Figure::track(Track::Jae, Diff::ActualMinusEstimated, Stat::Mean),
        quantity: "tracking with JAE, actual − estimated, mean",
        unit: "°",
        value: 0.170,
        better: Better::Lower,
        source: "Fig. 12 (text)",
    },
    SeedRow {
        figure: Figure::track(Track::Jae, Diff::ActualMinusEstimated, Stat::Max),
        quantity: "tracking with JAE, actual − estimated, max",
        unit: "°",
        value: 0.715,
        better: Better::Lower,
        source: "Fig. 12 (text)",
    },
    SeedRow {
        figure: Figure::track(Track::Jae, Diff::ActualMinusEstimated, Stat::Min),
        quantity: "tracking with JAE, actual − estimated, min",
        unit: "°",
        value: -0.498,
        better: Better::Lower,
        source: "Fig. 12 (text)",
    },
    SeedRow {
        figure: Figure::track(Track::Robust, Diff::DesiredMinusActual, Stat::Mean),
        quantity: "2.5 N on the tip, desired − actual, mean",
        unit: "°",
        value: -0.105,
        better: Better::Lower,
        source: "Fig. 13",
    },
    SeedRow {
        figure: Figure::track(Track::Robust, Diff::DesiredMinusActual, Stat::Max),
        quantity: "2.5 N on the tip, desired − actual, max",
        unit: "°",
        value: 1.202,
        better: Better::Lower,
        source: "Fig. 13",
    },
    SeedRow {
        figure: Figure::track(Track::Robust, Diff::DesiredMinusActual, Stat::Min),
        quantity: "2.5 N on the tip, desired − actual, min",
        unit: "°",
        value: -1.271,
        better: Better::Lower,
        source: "Fig. 13 (text)",
    },
    SeedRow {
        figure: Figure::track(Track::Robust, Diff::ActualMinusEstimated, Stat::Mean),
        quantity: "2.5 N on the tip, actual − estimated, mean",
        unit: "°",
        value: 0.076,
        better: Better::Lower,
        source: "Fig. 13 (text)",
    },
    SeedRow {
        figure: Figure::track(Track::Robust, Diff::ActualMinusEstimated, Stat::Max),
        quantity: "2.5 N on the tip, actual − estimated, max",
        unit: "°",
        value: 0.508,
        better: Better::Lower,
        source: "Fig. 13 (text)",
    },
    SeedRow {
        figure: Figure::track(Track::Robust, Diff::ActualMinusEstimated, Stat::Min),
        quantity: "2.5 N on the tip, actual − estimated, min",
        unit: "°",
        value: -0.454,
        better: Better::Lower,
        source: "Fig. 13 (text)",
    },
    SeedRow {
        figure: Figure::Ident(Ident::TensionVerification(ForceError::Mean)),
        quantity: "simplified model C, verification mean error",
        unit: "N",
        value: 0.011,
        better: Better::Lower,
        source: "Fig. 18",
    },
    SeedRow {
        figure: Figure::no_load(Estimate::Dob, NoLoad::Static0, Stat::MaxAbs),
        quantity: "static no-load error at 0° (±)",
        unit: "N",
        value: 0.1,
        better: Better::Lower,
        source: "Sect. 4.3, Figs. 20-21",
    },
    SeedRow {
        figure: Figure::no_load(Estimate::Dob, NoLoad::Static30M40, Stat::MaxAbs),
        quantity: "static no-load error at 30°/-40° (±)",
        unit: "N",
        value: 0.15,
        better: Better::Lower,
        source: "Sect. 4.3, Figs. 23-26",
    },
    SeedRow {
        figure: Figure::no_load(Estimate::Dob, NoLoad::DynamicPos, Stat::MaxAbs),
        quantity: "dynamic no-load error, positive runs (±)",
        unit: "N",
        value: 0.15,
        better: Better::Lower,
        source: "Sect. 4.3",
    },
    SeedRow {
        figure: Figure::no_load(Estimate::Dob, NoLoad::DynamicNeg, Stat::MaxAbs),
        quantity: "dynamic no-load error, negative runs (±)",
        unit: "N",
        value: 0.2,
        better: Better::Lower,
        source: "Sect. 4.3",
    },
    SeedRow {
        figure: Figure::accuracy(Estimate::Dob, Load::Above1n0, Accuracy::MinPct),
        quantity: "force accuracy ≥ 1 N at 0° (worst case)",
        unit: "%",
        value: 94.0,
        better: Better::Higher,
        source: "Sect. 4.3",
    },
    SeedRow {
        figure: Figure::accuracy(Estimate::Dob, Load::At0n3At0, Accuracy::MinPct),
        quantity: "force accuracy at 0.3 N at 0° (worst case)",
        unit: "%",
        value: 82.0,
        better: Better::Higher,
        source: "Sect. 4.3",
    },
    SeedRow {
        figure: Figure::accuracy(Estimate::Dob, Load::Above1n30M40, Accuracy::MinPct),
        quantity: "force accuracy ≥ 1 N at 30°/-40° (worst case)",
        unit: "%",
        value: 95.0,
        better: Better::Higher,
        source: "Sect. 4.3",
    },
    SeedRow {
        figure: Figure::accuracy(Estimate::Dob, Load::At0n330M40, Accuracy::MinPct),
        quantity: "force accuracy at 0.3 N at 30°/-40° (worst case)",
        unit: "%",
        value: 84.0,
        better: Better::Higher,
        source: "Sect. 4.3",
    },
    SeedRow {
        figure: Figure::loading(Estimate::Dob, Loading::MaxAngleError0Deg),
        quantity: "largest angle error with a load on, 0°",
        unit: "°",
        value: 1.25,
        better: Better::Lower,
        source: "Sect. 4.3",
    },
    SeedRow {
        figure: Figure::loading(Estimate::Dob, Loading::MaxAngleError30M40Deg),
        quantity: "largest angle error with a load on, 30°/-40°",
        unit: "°",
        value: 1.4,
        better: Better::Lower,
        source: "Sect. 4.3",
    },
    SeedRow {
        figure: Figure::no_load(Estimate::Stretch, NoLoad::Static0, Stat::MaxAbs),
        quantity: "static no-load error at 0° (±), stretch estimate",
        unit: "N",
        value: 0.1,
        better: Better::Lower,
        source: "Sect. 4.3, Figs. 20-21",
    },
    SeedRow {
        figure: Figure::no_load(Estimate::Stretch, NoLoad::Static30M40, Stat::MaxAbs),
        quantity: "static no-load error at 30°/-40° (±), stretch estimate",
        unit: "N",
        value: 0.15,
        better: Better::Lower,
        source: "Sect. 4.3, Figs. 23-26",
    },
    SeedRow {
        figure: Figure::no_load(Estimate::Stretch, NoLoad::DynamicPos, Stat::MaxAbs),
        quantity: "dynamic no-load error, positive runs (±), stretch estimate",
        unit: "N",
        value: 0.15,
        better: Better::Lower,
        source: "Sect. 4.3",
    },
    SeedRow {
        figure: Figure::no_load(Estimate::Stretch, NoLoad::DynamicNeg, Stat::MaxAbs),
        quantity: "dynamic no-load error, negative runs (±), stretch estimate",
        unit: "N",
        value: 0.2,
        better: Better::Lower,
        source: "Sect. 4.3",
    },
    SeedRow {
        figure: Figure::accuracy(Estimate::Stretch, Load::Above1n0, Accuracy::MinPct),
        quantity: "force accuracy ≥ 1 N at 0° (worst case), stretch estimate",
        unit: "%",
        value: 94.0,
        better: Better::Higher,
        source: "Sect. 4.3",
    },
    SeedRow {
        figure: Figure::accuracy(Estimate::Stretch, Load::At0n3At0, Accuracy::MinPct),
        quantity: "force accuracy at 0.3 N at 0° (worst case), stretch estimate",
        unit: "%",
        value: 82.0,
        better: Better::Higher,
        source: "Sect. 4.3",
    },
    SeedRow {
        figure: Figure::accuracy(Estimate::Stretch, Load::Above1n30M40, Accuracy::MinPct),
        quantity: "force accuracy ≥ 1 N at 30°/-40° (worst case), stretch estimate",
        unit: "%",
        value: 95.0,
        better: Better::Higher,
        source: "Sect. 4.3",
    },
    SeedRow {
        figure: Figure::accuracy(Estimate::Stretch, Load::At0n330M40, Accuracy::MinPct),
        quantity: "force accuracy at 0.3 N at 30°/-40° (worst case), stretch estimate",
        unit: "%",
        value: 84.0,
        better: Better::Higher,
        source: "Sect. 4.3",
    },
    SeedRow {
        figure: Figure::Ident(Ident::BmViscous),
        quantity: "identified B_m (plausibility)",
        unit: "N·m·s/rad",
        value: 1.6934e-5,
        better: Better::Info,
        source: "Sect. 4.2",
    },
];

/// The seed's figures report.md quotes beside ours in its text (the
/// identified parameters are not compared row by row: another prototype,
/// other units of the fit).
pub mod quoted {
    /// Tracking with motor-encoder feedback, desired − actual (Fig. 10).
    pub const TRACK_MOTOR: &str = "mean 1.912°, max 4.134°, min 0.964°";
    /// Tracking with JAE feedback, desired − actual; actual − estimated
    /// (Fig. 12), each mean / max / min.
    pub const TRACK_JAE: &str = "−0.150 / 0.905 / −0.974°; 0.170 / 0.715 / −0.498°";
    /// The same under 2.5 N on the tip (Fig. 13).
    pub const ROBUST_2N5: &str = "−0.105 / 1.202 / −1.271°; 0.076 / 0.508 / −0.454°";
    /// `B_m`, N·m·s/rad (Sect. 4.2).
    pub const B_M: &str = "1.6934e-5";
    /// The JAE's `chi_s` (Sect. 4.1).
    pub const CHI_S: &str = "[0.0805, 0.5225, 0.0025, 264.356]";
    /// The mean errors of tension models A, B, C (Fig. 16).
    pub const TENSION_MEANS: &str = "mean −0.0228, 0.0189, −0.0063 N";
    /// The simplified model C's `chi_p` (Eq. 29).
    pub const CHI_P: &str = "[3.879, 5.027, 707.7, 19.52]";
}

/// One row of the comparison: a seed figure, ours, and a caveat.
#[derive(Clone, Debug)]
pub struct Row {
    /// The seed's figure and what ours is.
    pub seed: &'static SeedRow,
    /// This project's figure (NaN when the clean plant has none).
    pub ours: f64,
    /// A caveat on this project's figure (a fault, an artefact), or empty.
    pub note: String,
}

impl Row {
    /// The ratio (see [`Better`]).
    pub fn ratio(&self) -> f64 {
        match self.seed.better {
            Better::Lower => self.ours.abs() / self.seed.value.abs(),
            Better::Higher | Better::Info => self.ours / self.seed.value,
        }
    }

    /// `better`, `worse`, `-` (no verdict), `fault` (the run faulted) or `n/a`.
    pub fn verdict(&self) -> &'static str {
        let r = self.ratio();
        match self.seed.better {
            _ if !r.is_finite() => "n/a",
            _ if self.note.starts_with("run faulted") => "fault",
            Better::Lower if r <= 1.0 => "better",
            Better::Higher if r >= 1.0 => "better",
            Better::Info => "-",
            _ => "worse",
        }
    }
}

/// The rows of [`SEED`] with the clean plant's figures.
pub fn comparison(r: &Report) -> Vec<Row> {
    let vs = variants(r);
    let clean = &vs[0];
    SEED.iter()
        .map(|s| Row {
            seed: s,
            ours: s.figure.value(clean).unwrap_or(f64::NAN),
            note: note(clean, s.figure),
        })
        .collect()
}

/// The caveat of our figure `f` of the clean plant.
fn note(clean: &Variant, f: Figure) -> String {
    match f {
        Figure::Eval(Eval::Track(t, ..) | Eval::TrackFaulted(t))
            if t.run(clean.ev).fault.is_some() =>
        {
            "run faulted: statistics up to the fault".into()
        }
        Figure::Eval(Eval::Loading(e, Loading::Accuracy(l, Accuracy::MinPct))) => {
            match Figure::accuracy(e, l, Accuracy::Faulted).value(clean) {
                Some(n) if n > 0.0 => format!("{n} faulted case(s) not counted"),
                _ => String::new(),
            }
        }
        Figure::Eval(Eval::Loading(
            Estimate::Dob,
            Loading::NoLoad(NoLoad::Static0, Stat::MaxAbs),
        )) if f.value(clean).is_some_and(|v| v < 1e-4) => {
            "estimate = model in the hold dead band".into()
        }
        _ => String::new(),
    }
}

/// The terminal table: seed | this project | ratio.
pub fn terminal_table(rows: &[Row]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{:<52} {:>11} {:>11} {:>7}  verdict (note)",
        "quantity (clean simulated prototype)", "seed", "this", "ratio"
    );
    let _ = writeln!(s, "{}", "-".repeat(92));
    for r in rows {
        let q = format!("{} [{}]", r.seed.quantity, r.seed.unit);
        let _ = writeln!(
            s,
            "{:<52} {:>11} {:>11} {:>7.3}  {}{}",
            q,
            fmt_num(r.seed.value),
            fmt_num(r.ours),
            r.ratio(),
            r.verdict(),
            if r.note.is_empty() {
                String::new()
            } else {
                format!(" ({})", r.note)
            }
        );
    }
    let _ = writeln!(
        s,
        "ratio: |this| / |seed| for errors (< 1 is better), this / seed for accuracies (> 1 is better)"
    );
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// report.json's `seed_comparison` keys (without `clean.`), in order:
    /// scripts read them.
    const KEYS: [&str; 37] = [
        "jae.error.mean_abs_deg",
        "jae.error.max_deg",
        "jae.error.min_deg",
        "track_motor.desired_minus_actual.mean_abs_deg",
        "track_motor.desired_minus_actual.max_abs_deg",
        "track_jae.desired_minus_actual.mean_deg",
        "track_jae.desired_minus_actual.max_deg",
        "track_jae.desired_minus_actual.min_deg",
        "track_jae.actual_minus_estimated.mean_deg",
        "track_jae.actual_minus_estimated.max_deg",
        "track_jae.actual_minus_estimated.min_deg",
        "robust_2n5.desired_minus_actual.mean_deg",
        "robust_2n5.desired_minus_actual.max_deg",
        "robust_2n5.desired_minus_actual.min_deg",
        "robust_2n5.actual_minus_estimated.mean_deg",
        "robust_2n5.actual_minus_estimated.max_deg",
        "robust_2n5.actual_minus_estimated.min_deg",
        "tension.verification.mean_error_n",
        "loading.static_noload_0.max_abs_n",
        "loading.static_noload_30_m40.max_abs_n",
        "loading.dynamic_noload_pos.max_abs_n",
        "loading.dynamic_noload_neg.max_abs_n",
        "loading.accuracy.above_1n_0.min_pct",
        "loading.accuracy.at_0n3_0.min_pct",
        "loading.accuracy.above_1n_30_m40.min_pct",
        "loading.accuracy.at_0n3_30_m40.min_pct",
        "loading.max_angle_error_0_deg",
        "loading.max_angle_error_30_m40_deg",
        "loading_stretch.static_noload_0.max_abs_n",
        "loading_stretch.static_noload_30_m40.max_abs_n",
        "loading_stretch.dynamic_noload_pos.max_abs_n",
        "loading_stretch.dynamic_noload_neg.max_abs_n",
        "loading_stretch.accuracy.above_1n_0.min_pct",
        "loading_stretch.accuracy.at_0n3_0.min_pct",
        "loading_stretch.accuracy.above_1n_30_m40.min_pct",
        "loading_stretch.accuracy.at_0n3_30_m40.min_pct",
        "bm.b_m_nm_s_rad",
    ];

    #[test]
    fn the_rows_keep_their_keys() {
        let keys: Vec<String> = SEED.iter().map(|s| s.figure.key()).collect();
        assert_eq!(keys, KEYS);
    }
}
