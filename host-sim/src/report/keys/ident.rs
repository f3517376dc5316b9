//! The keys of steps 1, 2 and 5, which the variants that identify have:
//! `bm.…`, `jae.…` (other than `jae.error.…`), `tension.…` and
//! `identification_faults`.

use crate::ident::{FitReport, Regressor};
use crate::report::programme::Identification;
use crate::stats::ErrorStats;

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
    pub(super) fn all() -> Vec<Self> {
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

    pub(super) fn key(self) -> String {
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

    pub(super) fn value(self, id: &Identification) -> Option<f64> {
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
