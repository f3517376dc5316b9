//! The figure map's keys, typed. Every figure of report.json's `figures` is
//! one [`Figure`] of one [`Variant`]: its key string ([`Figure::key`]) and
//! its value ([`Figure::value`]) are both defined here, so a table that
//! names a figure names one that exists, and shows the value the map holds.
//! The parts of a key: [`eval`] for steps 3, 4, 6, [`ident`] for steps 1,
//! 2, 5; those of the residual loop are here.

pub mod eval;
pub mod ident;

pub use eval::{Accuracy, Diff, Estimate, Eval, Load, Loading, NoLoad, Stat, Track};
pub use ident::{ChiP, ChiS, ErrorDeg, ForceError, Ident, TensionModel};

use super::programme::{Evaluation, Identification, ResidualStep};
use super::Report;
use crate::residual::Analysis;
use crate::stats::Summary;

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

// --- The residual loop ---------------------------------------------------------

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
        // 32 of steps 1, 2, 5; 179 of steps 3, 4, 6; 6 of the residual loop.
        assert_eq!(all.len(), 32 + 179 + 6);
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
