//! The figure map's keys, typed. Every figure of report.json's `figures` is
//! one [`Figure`] of one [`Variant`]: its key string ([`Figure::key`]) and
//! its value ([`Figure::value`]) are both defined here, so a table that
//! names a figure names one that exists, and shows the value the map holds.

use super::experiments::{Summary, TrackRun};
use super::programme::{AccuracyStats, Evaluation, Identification, LoadingSummary, ResidualStep};
use super::Report;
use crate::ident::{FitReport, Regressor};
use crate::residual::Analysis;
use crate::stats::ErrorStats;

// --- Variants ------------------------------------------------------------------

/// One variant of the programme, as the figure map and the tables see it.
pub struct Variant<'a> {
    /// Prefix of its keys: `clean`, `effects_seed_model`, `effects_residual`.
    pub prefix: &'static str,
    /// Title in report.md's tables.
    pub title: &'static str,
    /// Title in the terminal's tables.
    pub short_title: &'static str,
    /// Steps 1, 2, 5 (none after the residual loop, which identifies nothing
    /// again).
    pub id: Option<&'a Identification>,
    /// Steps 3, 4, 6.
    pub ev: &'a Evaluation,
    /// JAE error through the core on `jae-ident`, °.
    pub jae_error_deg: &'a Summary,
    /// The residual loop (after the residual loop only).
    pub residual: Option<&'a ResidualStep>,
}

/// The variants present: the clean plant, and with step 7 the plant with
/// effects before and after the residual loop.
pub fn variants(r: &Report) -> Vec<Variant<'_>> {
    let mut v = vec![Variant {
        prefix: "clean",
        title: "clean plant",
        short_title: "clean",
        id: Some(&r.clean.0),
        ev: &r.clean.1,
        jae_error_deg: &r.clean_jae_error_deg,
        residual: None,
    }];
    if let Some(fx) = &r.effects {
        v.push(Variant {
            prefix: "effects_seed_model",
            title: "effects on, seed's model",
            short_title: "effects, seed model",
            id: Some(&fx.id),
            ev: &fx.before,
            jae_error_deg: &fx.jae_error_before_deg,
            residual: None,
        });
        v.push(Variant {
            prefix: "effects_residual",
            title: "effects on, after the residual loop",
            short_title: "effects + residual",
            id: None,
            ev: &fx.after,
            jae_error_deg: &fx.jae_error_after_deg,
            residual: Some(&fx.residual),
        });
    }
    v
}

// --- Parts of a key --------------------------------------------------------------

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
}

impl Diff {
    /// Both differences.
    pub const ALL: [Self; 2] = [Self::DesiredMinusActual, Self::ActualMinusEstimated];

    fn name(self) -> &'static str {
        match self {
            Self::DesiredMinusActual => "desired_minus_actual",
            Self::ActualMinusEstimated => "actual_minus_estimated",
        }
    }

    fn of(self, t: &TrackRun) -> &Summary {
        match self {
            Self::DesiredMinusActual => &t.desired_minus_actual,
            Self::ActualMinusEstimated => &t.actual_minus_estimated,
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
    fn all() -> Vec<Self> {
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

    fn key(self) -> String {
        match self {
            Self::JaeError(s) => format!("jae.error.{}_deg", s.name()),
            Self::Track(t, d, s) => format!("{}.{}.{}_deg", t.name(), d.name(), s.name()),
            Self::TrackFaulted(t) => format!("{}.faulted", t.name()),
            Self::Loading(e, l) => format!("{}.{}", e.name(), l.key()),
        }
    }

    fn value(self, v: &Variant) -> f64 {
        match self {
            Self::JaeError(s) => s.of(v.jae_error_deg),
            Self::Track(t, d, s) => s.of(d.of(t.run(v.ev))),
            Self::TrackFaulted(t) => f64::from(u8::from(t.run(v.ev).fault.is_some())),
            Self::Loading(e, l) => l.value(e.summary(v.ev)),
        }
    }
}

/// A coefficient of the JAE's `chi_s`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChiS {
    /// `c1`.
    C1,
    /// `c2`.
    C2,
    /// `c3`.
    C3,
    /// `c4`.
    C4,
}

impl ChiS {
    /// Every coefficient, in `chi_s`'s order.
    pub const ALL: [Self; 4] = [Self::C1, Self::C2, Self::C3, Self::C4];

    fn index(self) -> usize {
        self as usize
    }
}

/// A statistic of an [`ErrorStats`] in degrees; its key is `{name}_deg`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ErrorDeg {
    /// Mean.
    Mean,
    /// Mean absolute error.
    MeanAbs,
    /// Largest error.
    Max,
    /// Smallest error.
    Min,
    /// Root-mean-square error.
    Rmse,
}

impl ErrorDeg {
    /// Every statistic.
    pub const ALL: [Self; 5] = [Self::Mean, Self::MeanAbs, Self::Max, Self::Min, Self::Rmse];

    fn name(self) -> &'static str {
        match self {
            Self::Mean => "mean",
            Self::MeanAbs => "mean_abs",
            Self::Max => "max",
            Self::Min => "min",
            Self::Rmse => "rmse",
        }
    }

    fn of(self, e: &ErrorStats) -> f64 {
        match self {
            Self::Mean => e.mean,
            Self::MeanAbs => e.mean_abs,
            Self::Max => e.max,
            Self::Min => e.min,
            Self::Rmse => e.rmse,
        }
    }
}

/// A tension model of step 5.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TensionModel {
    /// `model_a` (NaN when it was not fitted).
    A,
    /// `model_b` (NaN when it was not fitted).
    B,
    /// `model_c`.
    C,
    /// `simplified`: model C after the `%σ` pruning.
    Simplified,
}

impl TensionModel {
    /// Every model.
    pub const ALL: [Self; 4] = [Self::A, Self::B, Self::C, Self::Simplified];

    fn name(self) -> &'static str {
        match self {
            Self::A => "model_a",
            Self::B => "model_b",
            Self::C => "model_c",
            Self::Simplified => "simplified",
        }
    }

    fn fit(self, id: &Identification) -> Option<&FitReport> {
        let t = &id.tension;
        match self {
            Self::A => t.model_a.as_ref().ok(),
            Self::B => t.model_b.as_ref().ok(),
            Self::C => Some(&t.model_c),
            Self::Simplified => Some(&t.simplified),
        }
    }
}

/// A force error of a tension model, N.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ForceError {
    /// `mean_error_n`: mean.
    Mean,
    /// `rmse_n`: root-mean-square error.
    Rmse,
    /// `max_abs_n`: largest absolute error (the verification run only).
    MaxAbs,
}

impl ForceError {
    fn name(self) -> &'static str {
        match self {
            Self::Mean => "mean_error_n",
            Self::Rmse => "rmse_n",
            Self::MaxAbs => "max_abs_n",
        }
    }

    fn of(self, e: &ErrorStats) -> f64 {
        match self {
            Self::Mean => e.mean,
            Self::Rmse => e.rmse,
            Self::MaxAbs => e.max_abs(),
        }
    }
}

/// A parameter of the simplified model C written to the configuration
/// (`chi_p`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChiP {
    /// `f_sc1_n`: slider-1 Coulomb friction, N.
    FSc1N,
    /// `f_cp2_n`: slider-2 friction, N.
    FCp2N,
    /// `k_s_n_m`: spring stiffness, N/m.
    KSNM,
    /// `f_0_n`: preload, N.
    F0N,
}

impl ChiP {
    /// Every parameter, in `chi_p`'s order.
    pub const ALL: [Self; 4] = [Self::FSc1N, Self::FCp2N, Self::KSNM, Self::F0N];

    fn name(self) -> &'static str {
        match self {
            Self::FSc1N => "f_sc1_n",
            Self::FCp2N => "f_cp2_n",
            Self::KSNM => "k_s_n_m",
            Self::F0N => "f_0_n",
        }
    }
}

/// A figure of steps 1, 2 and 5 (the variants that identify).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ident {
    /// `bm.b_m_nm_s_rad`: identified `B_m`, N·m·s/rad.
    BmViscous,
    /// `bm.coulomb_nm`: motor Coulomb torque, N·m (0 when the `%σ` rule
    /// dropped it).
    BmCoulomb,
    /// `bm.b_m_pct_sigma`: `%σ` of `B_m` (NaN without the term).
    BmPctSigma,
    /// `bm.verification_rmse_nm`: RMSE on the verification run, N·m.
    BmVerificationRmse,
    /// `bm.verification_mean_nm`: mean error on the verification run, N·m.
    BmVerificationMean,
    /// `jae.c1` … `jae.c4`: the JAE's `chi_s`.
    JaeChiS(ChiS),
    /// `jae.offset_rad`: the JAE's offset, rad.
    JaeOffset,
    /// `jae.ident.{stat}_deg`: least-squares residual on `jae-ident`, °.
    JaeResidual(ErrorDeg),
    /// `tension.{model}.{error}`: a model's error on `tension-ident`, N
    /// (mean and RMSE only).
    TensionModel(TensionModel, ForceError),
    /// `tension.chi_p.{name}`: the simplified model C.
    ChiP(ChiP),
    /// `tension.dropped_terms`: terms the `%σ` pruning dropped.
    TensionDropped,
    /// `tension.verification.{error}`: the last verification model's error,
    /// N (absent without a verification run).
    TensionVerification(ForceError),
    /// `identification_faults`: faults latched in the identification runs.
    Faults,
}

impl Ident {
    fn all() -> Vec<Self> {
        let mut v = vec![
            Self::BmViscous,
            Self::BmCoulomb,
            Self::BmPctSigma,
            Self::BmVerificationRmse,
            Self::BmVerificationMean,
        ];
        v.extend(ChiS::ALL.map(Self::JaeChiS));
        v.push(Self::JaeOffset);
        v.extend(ErrorDeg::ALL.map(Self::JaeResidual));
        for m in TensionModel::ALL {
            v.extend([ForceError::Mean, ForceError::Rmse].map(|e| Self::TensionModel(m, e)));
        }
        v.extend(ChiP::ALL.map(Self::ChiP));
        v.push(Self::TensionDropped);
        v.extend(
            [ForceError::Mean, ForceError::Rmse, ForceError::MaxAbs].map(Self::TensionVerification),
        );
        v.push(Self::Faults);
        v
    }

    fn key(self) -> String {
        match self {
            Self::BmViscous => "bm.b_m_nm_s_rad".into(),
            Self::BmCoulomb => "bm.coulomb_nm".into(),
            Self::BmPctSigma => "bm.b_m_pct_sigma".into(),
            Self::BmVerificationRmse => "bm.verification_rmse_nm".into(),
            Self::BmVerificationMean => "bm.verification_mean_nm".into(),
            Self::JaeChiS(c) => format!("jae.c{}", c.index() + 1),
            Self::JaeOffset => "jae.offset_rad".into(),
            Self::JaeResidual(s) => format!("jae.ident.{}_deg", s.name()),
            Self::TensionModel(m, e) => format!("tension.{}.{}", m.name(), e.name()),
            Self::ChiP(p) => format!("tension.chi_p.{}", p.name()),
            Self::TensionDropped => "tension.dropped_terms".into(),
            Self::TensionVerification(e) => format!("tension.verification.{}", e.name()),
            Self::Faults => "identification_faults".into(),
        }
    }

    fn value(self, id: &Identification) -> Option<f64> {
        let bm = &id.bm;
        Some(match self {
            Self::BmViscous => bm.b_m_nm_s_rad,
            Self::BmCoulomb => bm.coulomb_nm.unwrap_or(0.0),
            Self::BmPctSigma => bm
                .fit
                .param(Regressor::PhiVel)
                .map_or(f64::NAN, |p| p.pct_sigma),
            Self::BmVerificationRmse => id.bm_validation.rmse,
            Self::BmVerificationMean => id.bm_validation.mean,
            Self::JaeChiS(c) => id.jae.chi_s[c.index()],
            Self::JaeOffset => id.jae.offset_rad,
            Self::JaeResidual(s) => s.of(&id.jae.error_deg),
            Self::TensionModel(m, e) => m.fit(id).map_or(f64::NAN, |f| e.of(&f.errors)),
            Self::ChiP(p) => id.tension.chi_p[p as usize],
            Self::TensionDropped => id.tension.dropped.len() as f64,
            Self::TensionVerification(e) => e.of(&id.tension_validation.last()?.1),
            Self::Faults => id.faults.len() as f64,
        })
    }
}

/// A model the residual loop extends.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ResidualModel {
    /// `jae`: the JAE.
    Jae,
    /// `tension`: the tension model.
    Tension,
}

impl ResidualModel {
    /// Both models.
    pub const ALL: [Self; 2] = [Self::Jae, Self::Tension];

    fn name(self) -> &'static str {
        match self {
            Self::Jae => "jae",
            Self::Tension => "tension",
        }
    }

    fn of(self, r: &ResidualStep) -> &Analysis {
        match self {
            Self::Jae => &r.jae,
            Self::Tension => &r.tension,
        }
    }
}

/// A figure of the residual loop for one model (validation RMSE in the
/// model's own unit: rad for the JAE, N for the tension model).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ResidualFigure {
    /// `before_rmse`: validation RMSE of the seed's model.
    BeforeRmse,
    /// `after_rmse`: validation RMSE with the terms added.
    AfterRmse,
    /// `terms_added`: terms the loop kept.
    TermsAdded,
}

impl ResidualFigure {
    /// Every figure.
    pub const ALL: [Self; 3] = [Self::BeforeRmse, Self::AfterRmse, Self::TermsAdded];

    fn name(self) -> &'static str {
        match self {
            Self::BeforeRmse => "before_rmse",
            Self::AfterRmse => "after_rmse",
            Self::TermsAdded => "terms_added",
        }
    }

    fn of(self, a: &Analysis) -> f64 {
        let o = &a.outcome;
        match self {
            Self::BeforeRmse => o.baseline.val_rmse,
            Self::AfterRmse => o.final_fit.val_rmse,
            Self::TermsAdded => o.accepted.len() as f64,
        }
    }
}

// --- Figures ---------------------------------------------------------------------

/// One figure of a variant: its key in the figure map is
/// `{variant prefix}.{key()}`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Figure {
    /// Steps 1, 2, 5 (`clean`, `effects_seed_model`).
    Ident(Ident),
    /// Steps 3, 4, 6 and the JAE error through the core (every variant).
    Eval(Eval),
    /// `residual.{model}.{figure}`: the residual loop (`effects_residual`).
    Residual(ResidualModel, ResidualFigure),
}

impl Figure {
    /// `jae.error.{stat}_deg`.
    pub const fn jae_error(s: Stat) -> Self {
        Self::Eval(Eval::JaeError(s))
    }

    /// `{run}.{difference}.{stat}_deg`.
    pub const fn track(t: Track, d: Diff, s: Stat) -> Self {
        Self::Eval(Eval::Track(t, d, s))
    }

    /// `{run}.faulted`.
    pub const fn track_faulted(t: Track) -> Self {
        Self::Eval(Eval::TrackFaulted(t))
    }

    /// A figure of the loading protocol under estimate `e`.
    pub const fn loading(e: Estimate, l: Loading) -> Self {
        Self::Eval(Eval::Loading(e, l))
    }

    /// `{loading}.{region}.{stat}_n`.
    pub const fn no_load(e: Estimate, r: NoLoad, s: Stat) -> Self {
        Self::loading(e, Loading::NoLoad(r, s))
    }

    /// `{loading}.accuracy.{load}.{figure}`.
    pub const fn accuracy(e: Estimate, l: Load, a: Accuracy) -> Self {
        Self::loading(e, Loading::Accuracy(l, a))
    }

    /// Every figure any variant can have.
    pub fn all() -> Vec<Self> {
        let mut v: Vec<Self> = Ident::all().into_iter().map(Self::Ident).collect();
        v.extend(Eval::all().into_iter().map(Self::Eval));
        for m in ResidualModel::ALL {
            v.extend(ResidualFigure::ALL.map(|f| Self::Residual(m, f)));
        }
        v
    }

    /// The key without the variant's prefix.
    pub fn key(self) -> String {
        match self {
            Self::Ident(i) => i.key(),
            Self::Eval(e) => e.key(),
            Self::Residual(m, f) => format!("residual.{}.{}", m.name(), f.name()),
        }
    }

    /// The figure of variant `v`, if that variant has it.
    pub fn value(self, v: &Variant) -> Option<f64> {
        match self {
            Self::Ident(i) => i.value(v.id?),
            Self::Eval(e) => Some(e.value(v)),
            Self::Residual(m, f) => Some(f.of(m.of(v.residual?))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_key_is_unique() {
        let all = Figure::all();
        let keys: std::collections::BTreeSet<String> = all.iter().map(|f| f.key()).collect();
        assert_eq!(keys.len(), all.len(), "two figures share a key");
        // 32 of steps 1, 2, 5; 161 of steps 3, 4, 6; 6 of the residual loop.
        assert_eq!(all.len(), 32 + 161 + 6);
    }

    #[test]
    fn keys_are_the_published_ones() {
        for (f, key) in [
            (
                Figure::Eval(Eval::Track(
                    Track::Jae,
                    Diff::DesiredMinusActual,
                    Stat::MaxAbs,
                )),
                "track_jae.desired_minus_actual.max_abs_deg",
            ),
            (
                Figure::Eval(Eval::Loading(
                    Estimate::Stretch,
                    Loading::Accuracy(Load::At0n330M40, Accuracy::MinPct),
                )),
                "loading_stretch.accuracy.at_0n3_30_m40.min_pct",
            ),
            (
                Figure::Eval(Eval::Loading(
                    Estimate::Dob,
                    Loading::NoLoad(NoLoad::Static0, Stat::MaxAbs),
                )),
                "loading.static_noload_0.max_abs_n",
            ),
            (Figure::Ident(Ident::JaeChiS(ChiS::C4)), "jae.c4"),
            (
                Figure::Ident(Ident::TensionModel(
                    TensionModel::Simplified,
                    ForceError::Rmse,
                )),
                "tension.simplified.rmse_n",
            ),
            (
                Figure::Residual(ResidualModel::Tension, ResidualFigure::TermsAdded),
                "residual.tension.terms_added",
            ),
        ] {
            assert_eq!(f.key(), key);
        }
    }
}
