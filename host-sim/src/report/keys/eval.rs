//! The keys of steps 3, 4 and 6 and of the JAE error through the core,
//! which every variant has: `jae.error.…`, the tracking runs' `….…_deg`
//! and `….faulted`, the loading protocol's `loading.…` and
//! `loading_stretch.…`.

use super::Variant;
use crate::report::experiments::TrackRun;
use crate::report::programme::{AccuracyStats, Evaluation, LoadingSummary};
use crate::stats::Summary;

/// A statistic of a [`Summary`]; its key is `{name}_{unit}`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stat {
    /// Mean.
    Mean,
    /// Mean of the absolute value.
    MeanAbs,
    /// Root mean square.
    Rms,
    /// Largest value.
    Max,
    /// Smallest value.
    Min,
    /// Largest absolute value.
    MaxAbs,
}

impl Stat {
    /// Every statistic.
    pub const ALL: [Self; 6] = [
        Self::Mean,
        Self::MeanAbs,
        Self::Rms,
        Self::Max,
        Self::Min,
        Self::MaxAbs,
    ];

    fn name(self) -> &'static str {
        match self {
            Self::Mean => "mean",
            Self::MeanAbs => "mean_abs",
            Self::Rms => "rms",
            Self::Max => "max",
            Self::Min => "min",
            Self::MaxAbs => "max_abs",
        }
    }

    /// The statistic of `s`.
    pub fn of(self, s: &Summary) -> f64 {
        match self {
            Self::Mean => s.mean,
            Self::MeanAbs => s.mean_abs,
            Self::Rms => s.rms,
            Self::Max => s.max,
            Self::Min => s.min,
            Self::MaxAbs => s.max_abs(),
        }
    }
}

/// A tracking run of steps 3 and 4.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Track {
    /// `track_motor`: motor-encoder feedback (Fig. 10).
    Motor,
    /// `track_jae`: JAE feedback (Fig. 12).
    Jae,
    /// `robust_2n5`: 2.5 N on the tip, complex trajectory (Fig. 13).
    Robust,
}

impl Track {
    /// Every tracking run.
    pub const ALL: [Self; 3] = [Self::Motor, Self::Jae, Self::Robust];

    fn name(self) -> &'static str {
        match self {
            Self::Motor => "track_motor",
            Self::Jae => "track_jae",
            Self::Robust => "robust_2n5",
        }
    }

    /// The run in `ev`.
    pub fn run(self, ev: &Evaluation) -> &TrackRun {
        match self {
            Self::Motor => &ev.track_motor,
            Self::Jae => &ev.track_jae,
            Self::Robust => &ev.robust,
        }
    }
}

/// An angle difference of a tracking run, °.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Diff {
    /// Desired − actual (the magnetic encoder).
    DesiredMinusActual,
    /// Actual − estimated (the JAE).
    ActualMinusEstimated,
    /// The plant's true angle − estimated (the JAE): no encoder quantum.
    TrueMinusEstimated,
}

impl Diff {
    /// Every difference.
    pub const ALL: [Self; 3] = [
        Self::DesiredMinusActual,
        Self::ActualMinusEstimated,
        Self::TrueMinusEstimated,
    ];

    fn name(self) -> &'static str {
        match self {
            Self::DesiredMinusActual => "desired_minus_actual",
            Self::ActualMinusEstimated => "actual_minus_estimated",
            Self::TrueMinusEstimated => "true_minus_estimated",
        }
    }

    fn of(self, t: &TrackRun) -> &Summary {
        match self {
            Self::DesiredMinusActual => &t.desired_minus_actual,
            Self::ActualMinusEstimated => &t.actual_minus_estimated,
            Self::TrueMinusEstimated => &t.true_minus_estimated,
        }
    }
}

/// The force estimate the loading protocol judges.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Estimate {
    /// `loading`: the DOB.
    Dob,
    /// `loading_stretch`: the cable-stretch estimate.
    Stretch,
}

impl Estimate {
    /// Both estimates.
    pub const ALL: [Self; 2] = [Self::Dob, Self::Stretch];

    fn name(self) -> &'static str {
        match self {
            Self::Dob => "loading",
            Self::Stretch => "loading_stretch",
        }
    }

    /// The loading summary of this estimate in `ev`.
    pub fn summary(self, ev: &Evaluation) -> &LoadingSummary {
        match self {
            Self::Dob => &ev.loading_summary,
            Self::Stretch => &ev.loading_stretch_summary,
        }
    }
}

/// A no-load region of the loading protocol (errors in N).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NoLoad {
    /// `static_noload`: static, all angles.
    Static,
    /// `static_noload_0`: static at 0°.
    Static0,
    /// `static_noload_30_m40`: static at 30° and −40°.
    Static30M40,
    /// `dynamic_noload_pos`: moving, positive-direction runs.
    DynamicPos,
    /// `dynamic_noload_neg`: moving, negative-direction runs.
    DynamicNeg,
}

impl NoLoad {
    /// Every region.
    pub const ALL: [Self; 5] = [
        Self::Static,
        Self::Static0,
        Self::Static30M40,
        Self::DynamicPos,
        Self::DynamicNeg,
    ];

    fn name(self) -> &'static str {
        match self {
            Self::Static => "static_noload",
            Self::Static0 => "static_noload_0",
            Self::Static30M40 => "static_noload_30_m40",
            Self::DynamicPos => "dynamic_noload_pos",
            Self::DynamicNeg => "dynamic_noload_neg",
        }
    }

    fn of(self, l: &LoadingSummary) -> &Summary {
        match self {
            Self::Static => &l.static_noload_n,
            Self::Static0 => &l.static_noload_0_n,
            Self::Static30M40 => &l.static_noload_30_m40_n,
            Self::DynamicPos => &l.dynamic_noload_pos_n,
            Self::DynamicNeg => &l.dynamic_noload_neg_n,
        }
    }
}

/// The loads and angles an accuracy is taken over.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Load {
    /// `above_1n`: 100 g and above, all angles.
    Above1n,
    /// `at_0n3`: 30 g, all angles.
    At0n3,
    /// `above_1n_0`: 100 g and above at 0°.
    Above1n0,
    /// `at_0n3_0`: 30 g at 0°.
    At0n3At0,
    /// `above_1n_30_m40`: 100 g and above at 30° and −40°.
    Above1n30M40,
    /// `at_0n3_30_m40`: 30 g at 30° and −40°.
    At0n330M40,
}

impl Load {
    /// Every load class.
    pub const ALL: [Self; 6] = [
        Self::Above1n,
        Self::At0n3,
        Self::Above1n0,
        Self::At0n3At0,
        Self::Above1n30M40,
        Self::At0n330M40,
    ];

    fn name(self) -> &'static str {
        match self {
            Self::Above1n => "above_1n",
            Self::At0n3 => "at_0n3",
            Self::Above1n0 => "above_1n_0",
            Self::At0n3At0 => "at_0n3_0",
            Self::Above1n30M40 => "above_1n_30_m40",
            Self::At0n330M40 => "at_0n3_30_m40",
        }
    }

    fn of(self, l: &LoadingSummary) -> &AccuracyStats {
        match self {
            Self::Above1n => &l.above_1n,
            Self::At0n3 => &l.at_0n3,
            Self::Above1n0 => &l.above_1n_0,
            Self::At0n3At0 => &l.at_0n3_0,
            Self::Above1n30M40 => &l.above_1n_30_m40,
            Self::At0n330M40 => &l.at_0n3_30_m40,
        }
    }
}

/// A figure of an accuracy.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Accuracy {
    /// `min_pct`: worst case, %.
    MinPct,
    /// `mean_pct`: mean, %.
    MeanPct,
    /// `cases`: cases counted.
    Cases,
    /// `faulted`: cases left out because they latched a fault.
    Faulted,
}

impl Accuracy {
    /// Every figure of an accuracy.
    pub const ALL: [Self; 4] = [Self::MinPct, Self::MeanPct, Self::Cases, Self::Faulted];

    fn name(self) -> &'static str {
        match self {
            Self::MinPct => "min_pct",
            Self::MeanPct => "mean_pct",
            Self::Cases => "cases",
            Self::Faulted => "faulted",
        }
    }

    fn of(self, a: &AccuracyStats) -> f64 {
        match self {
            Self::MinPct => a.min_pct,
            Self::MeanPct => a.mean_pct,
            Self::Cases => a.cases as f64,
            Self::Faulted => a.faulted as f64,
        }
    }
}

/// A figure of the loading protocol (step 6) for one estimate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Loading {
    /// `cases`: cases run.
    Cases,
    /// `faulted_cases`: cases that latched a fault.
    FaultedCases,
    /// `{region}.{stat}_n`: a no-load error, N.
    NoLoad(NoLoad, Stat),
    /// `accuracy.{load}.{figure}`.
    Accuracy(Load, Accuracy),
    /// `max_angle_error_0_deg`: largest angle error with a load on at 0°, °.
    MaxAngleError0Deg,
    /// `max_angle_error_30_m40_deg`: the same at 30° and −40°, °.
    MaxAngleError30M40Deg,
}

impl Loading {
    fn all() -> Vec<Self> {
        let mut v = vec![Self::Cases, Self::FaultedCases];
        for r in NoLoad::ALL {
            v.extend(Stat::ALL.map(|s| Self::NoLoad(r, s)));
        }
        for l in Load::ALL {
            v.extend(Accuracy::ALL.map(|a| Self::Accuracy(l, a)));
        }
        v.extend([Self::MaxAngleError0Deg, Self::MaxAngleError30M40Deg]);
        v
    }

    fn key(self) -> String {
        match self {
            Self::Cases => "cases".into(),
            Self::FaultedCases => "faulted_cases".into(),
            Self::NoLoad(r, s) => format!("{}.{}_n", r.name(), s.name()),
            Self::Accuracy(l, a) => format!("accuracy.{}.{}", l.name(), a.name()),
            Self::MaxAngleError0Deg => "max_angle_error_0_deg".into(),
            Self::MaxAngleError30M40Deg => "max_angle_error_30_m40_deg".into(),
        }
    }

    fn value(self, l: &LoadingSummary) -> f64 {
        match self {
            Self::Cases => l.cases as f64,
            Self::FaultedCases => l.faulted as f64,
            Self::NoLoad(r, s) => s.of(r.of(l)),
            Self::Accuracy(load, a) => a.of(load.of(l)),
            Self::MaxAngleError0Deg => l.max_angle_error_0_deg,
            Self::MaxAngleError30M40Deg => l.max_angle_error_30_m40_deg,
        }
    }
}

/// A figure of steps 3, 4, 6 and the JAE error through the core (every
/// variant has them).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Eval {
    /// `jae.error.{stat}_deg`: JAE error through the core on `jae-ident`, °.
    JaeError(Stat),
    /// `{run}.{difference}.{stat}_deg`: a tracking error, °.
    Track(Track, Diff, Stat),
    /// `{run}.faulted`: 1 if the run latched a fault, else 0.
    TrackFaulted(Track),
    /// `loading.…` (the DOB) or `loading_stretch.…` (the cable-stretch
    /// estimate).
    Loading(Estimate, Loading),
}

impl Eval {
    pub(super) fn all() -> Vec<Self> {
        let mut v = Stat::ALL.map(Self::JaeError).to_vec();
        for t in Track::ALL {
            for d in Diff::ALL {
                v.extend(Stat::ALL.map(|s| Self::Track(t, d, s)));
            }
            v.push(Self::TrackFaulted(t));
        }
        for e in Estimate::ALL {
            v.extend(Loading::all().into_iter().map(|l| Self::Loading(e, l)));
        }
        v
    }

    pub(super) fn key(self) -> String {
        match self {
            Self::JaeError(s) => format!("jae.error.{}_deg", s.name()),
            Self::Track(t, d, s) => format!("{}.{}.{}_deg", t.name(), d.name(), s.name()),
            Self::TrackFaulted(t) => format!("{}.faulted", t.name()),
            Self::Loading(e, l) => format!("{}.{}", e.name(), l.key()),
        }
    }

    pub(super) fn value(self, v: &Variant) -> f64 {
        match self {
            Self::JaeError(s) => s.of(v.jae_error_deg),
            Self::Track(t, d, s) => s.of(d.of(t.run(v.ev))),
            Self::TrackFaulted(t) => f64::from(u8::from(t.run(v.ev).fault.is_some())),
            Self::Loading(e, l) => l.value(e.summary(v.ev)),
        }
    }
}
