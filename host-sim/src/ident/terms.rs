//! The regressors and the seed's models as lists of terms.

use serde::Serialize;

/// Most regressors one model has (model B, Eq. 23).
pub const MAX_REGRESSORS: usize = 12;

/// One regressor column, computed from the replayed log.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Regressor {
    /// Joint velocity `theta'`, rad/s.
    ThetaVel,
    /// Joint acceleration `theta''`, rad/s².
    ThetaAcc,
    /// Held sign of `theta'`.
    SgnThetaVel,
    /// Joint angle `theta`, rad.
    Theta,
    /// Slider 1 acceleration `x1''`, m/s².
    X1Acc,
    /// Slider 1 velocity `x1'`, m/s.
    X1Vel,
    /// Held sign of `x1'`.
    SgnX1Vel,
    /// Slider 1 position `x1`, m.
    X1,
    /// Slider 2 acceleration `x2''`, m/s².
    X2Acc,
    /// Slider 2 velocity `x2'`, m/s.
    X2Vel,
    /// Held sign of `x2'`.
    SgnX2Vel,
    /// Slider 2 position `x2`, m.
    X2,
    /// Motor velocity `phi'`, rad/s.
    PhiVel,
    /// Held sign of `phi'`.
    SgnPhiVel,
    /// The constant 1.
    One,
}

impl Regressor {
    /// Symbol as the seed writes it.
    pub fn symbol(self) -> &'static str {
        match self {
            Regressor::ThetaVel => "theta'",
            Regressor::ThetaAcc => "theta''",
            Regressor::SgnThetaVel => "sgn(theta')",
            Regressor::Theta => "theta",
            Regressor::X1Acc => "x1''",
            Regressor::X1Vel => "x1'",
            Regressor::SgnX1Vel => "sgn(x1')",
            Regressor::X1 => "x1",
            Regressor::X2Acc => "x2''",
            Regressor::X2Vel => "x2'",
            Regressor::SgnX2Vel => "sgn(x2')",
            Regressor::X2 => "x2",
            Regressor::PhiVel => "phi'",
            Regressor::SgnPhiVel => "sgn(phi')",
            Regressor::One => "1",
        }
    }
}

/// A regressor with the name and unit of its parameter in one model.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct ModelTerm {
    /// The column.
    pub regressor: Regressor,
    /// The parameter's name (seed notation).
    pub param: &'static str,
    /// The parameter's unit.
    pub unit: &'static str,
}

pub(super) const fn term(
    regressor: Regressor,
    param: &'static str,
    unit: &'static str,
) -> ModelTerm {
    ModelTerm {
        regressor,
        param,
        unit,
    }
}

/// Motor damping (seed Sect. 3.3/4.2) with an offset, optionally Coulomb.
pub const BM_TERMS: [ModelTerm; 3] = [
    term(Regressor::PhiVel, "B_m", "N·m·s/rad"),
    term(Regressor::One, "tau_0", "N·m"),
    term(Regressor::SgnPhiVel, "tau_c", "N·m"),
];

/// Joint-angle estimator (Eq. 25-26) with an offset.
pub const JAE_TERMS: [ModelTerm; 5] = [
    term(Regressor::X2Acc, "c1", "rad·s²/m"),
    term(Regressor::X2Vel, "c2", "rad·s/m"),
    term(Regressor::SgnX2Vel, "c3", "rad"),
    term(Regressor::X2, "c4", "rad/m"),
    term(Regressor::One, "offset", "rad"),
];

/// Tension model A (Eq. 22).
pub const MODEL_A: [ModelTerm; 6] = [
    term(Regressor::X1Acc, "m_0", "kg"),
    term(Regressor::X1Vel, "f_sv1", "N·s/m"),
    term(Regressor::SgnX1Vel, "f_sc1", "N"),
    term(Regressor::X1, "K_w1", "N/m"),
    term(Regressor::Theta, "-K_w1 r", "N/rad"),
    term(Regressor::One, "F_0", "N"),
];

/// Tension model B (Eq. 23).
pub const MODEL_B: [ModelTerm; 12] = [
    term(Regressor::ThetaAcc, "J_e/r", "N·s²/rad"),
    term(Regressor::ThetaVel, "f_efv/r", "N·s/rad"),
    term(Regressor::SgnThetaVel, "f_efc/r", "N"),
    term(Regressor::Theta, "K_w2 r", "N/rad"),
    term(Regressor::X1Acc, "m_0", "kg"),
    term(Regressor::X1Vel, "f_sv1", "N·s/m"),
    term(Regressor::SgnX1Vel, "f_sc1", "N"),
    term(Regressor::X2Acc, "m_1", "kg"),
    term(Regressor::X2Vel, "f_sv2", "N·s/m"),
    term(Regressor::SgnX2Vel, "f_sc2", "N"),
    term(Regressor::X2, "-K_w2", "N/m"),
    term(Regressor::One, "F_0", "N"),
];

/// Tension model C (Eq. 24), regressors in the order of Eq. 27.
pub const MODEL_C: [ModelTerm; 11] = [
    term(Regressor::ThetaVel, "f_efv/r", "N·s/rad"),
    term(Regressor::ThetaAcc, "J_e/r", "N·s²/rad"),
    term(Regressor::SgnThetaVel, "f_efc/r", "N"),
    term(Regressor::X1Acc, "m_0", "kg"),
    term(Regressor::X1Vel, "f_sv1", "N·s/m"),
    term(Regressor::SgnX1Vel, "f_sc1", "N"),
    term(Regressor::X2Acc, "m_1", "kg"),
    term(Regressor::X2Vel, "f_vp2", "N·s/m"),
    term(Regressor::SgnX2Vel, "f_cp2", "N"),
    term(Regressor::X2, "K_s", "N/m"),
    term(Regressor::One, "F_0", "N"),
];

/// The simplified model C the core evaluates (Eq. 28-29), in the order of
/// [`cable_joint::config::TensionConfig`]'s fields.
pub const SIMPLIFIED_C: [Regressor; 4] = [
    Regressor::SgnX1Vel,
    Regressor::SgnX2Vel,
    Regressor::X2,
    Regressor::One,
];

/// Regressors whose coefficient is a mass, a damping or a Coulomb friction
/// in every model the project fits (model C's `m_0`, `f_sv1`, `f_sc1`,
/// `m_1`, `f_vp2`, `f_cp2` and the pin's `J_e / r`, `f_efv / r`,
/// `f_efc / r`; the JAE's `c1..c3`; `B_m`): none can be negative, so a fit
/// that makes one negative has used it for something else.
pub fn nonnegative_by_physics(r: Regressor) -> bool {
    matches!(
        r,
        Regressor::ThetaVel
            | Regressor::ThetaAcc
            | Regressor::SgnThetaVel
            | Regressor::X1Acc
            | Regressor::X1Vel
            | Regressor::SgnX1Vel
            | Regressor::X2Acc
            | Regressor::X2Vel
            | Regressor::SgnX2Vel
            | Regressor::PhiVel
            | Regressor::SgnPhiVel
    )
}

/// Regressors a model needs by physics: the spring/stiffness, the
/// preload/offset, and the guides' Coulomb friction (a guide always has
/// some; a `%sigma` above the limit says the run could not separate it, not
/// that it is zero, and a zero would make the force bound claim the DOB
/// sees through slider 1).
pub fn physically_required(r: Regressor) -> bool {
    matches!(
        r,
        Regressor::X2 | Regressor::One | Regressor::SgnX1Vel | Regressor::SgnX2Vel
    )
}
