//! Effect terms added to the core's estimators at run time.
//!
//! The residual loop (host tool `host-sim residual`) selects effects from the
//! library in [`crate::effects`] and writes them, with their coefficients, into
//! the configuration. The controller then adds them to the joint-angle
//! estimate and to the no-load tension model every tick, so whatever the host
//! selected runs on the MCU.
//!
//! Terms read the run-time signal vector [`Signals`], indexed by the constants
//! in [`sig`]; the host tool uses the same names ([`SIGNAL_NAMES`]) for the
//! columns of a log, so a term fitted on a log means the same thing here.

use crate::effects::{Term, TermState};

/// Most terms one estimator can carry.
pub const MAX_TERMS: usize = 8;

/// Indices of the run-time signals.
pub mod sig {
    /// Slider 1 position, m.
    pub const X1_M: u8 = 0;
    /// Slider 1 speed, m/s.
    pub const X1_VEL_M_S: u8 = 1;
    /// Slider 2 position, m.
    pub const X2_M: u8 = 2;
    /// Slider 2 speed, m/s.
    pub const X2_VEL_M_S: u8 = 3;
    /// Slider 2 acceleration, m/s².
    pub const X2_ACC_M_S2: u8 = 4;
    /// Motor angle, rad.
    pub const PHI_RAD: u8 = 5;
    /// Motor speed, rad/s.
    pub const PHI_VEL_RAD_S: u8 = 6;
    /// Current reference applied over the last period, A.
    pub const I_REF_A: u8 = 7;
    /// Measured current, A.
    pub const I_MEAS_A: u8 = 8;
    /// Motor-implied joint angle, rad.
    pub const THETA_MOTOR_RAD: u8 = 9;
    /// Number of signals.
    pub const COUNT: usize = 10;
}

/// Column names of the run-time signals, in index order (log columns).
pub const SIGNAL_NAMES: [&str; sig::COUNT] = [
    "x1_m",
    "x1_vel_m_s",
    "x2_m",
    "x2_vel_m_s",
    "x2_acc_m_s2",
    "phi_rad",
    "phi_vel_rad_s",
    "i_ref_a",
    "i_meas_a",
    "theta_motor_rad",
];

/// Index of a signal by its column name.
pub fn signal_index(name: &str) -> Option<u8> {
    SIGNAL_NAMES
        .iter()
        .position(|n| *n == name)
        .map(|i| i as u8)
}

/// The run-time signal vector of one tick.
pub type Signals = [f32; sig::COUNT];

/// Up to [`MAX_TERMS`] effect terms with their coefficients (configuration).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, deny_unknown_fields))]
pub struct AddedTerms {
    /// Number of terms in use.
    pub len: u8,
    /// The terms (first `len` used).
    pub terms: [Term; MAX_TERMS],
    /// Their coefficients, in the estimator's output unit per term unit.
    pub coef: [f32; MAX_TERMS],
}

impl Default for AddedTerms {
    fn default() -> Self {
        Self {
            len: 0,
            terms: [Term::CONSTANT; MAX_TERMS],
            coef: [0.0; MAX_TERMS],
        }
    }
}

/// State of [`AddedTerms`].
pub type AddedState = [TermState; MAX_TERMS];

impl AddedTerms {
    /// Add a term; `false` when full.
    pub fn push(&mut self, term: Term, coef: f32) -> bool {
        let n = self.len as usize;
        if n >= MAX_TERMS {
            return false;
        }
        self.terms[n] = term;
        self.coef[n] = coef;
        self.len += 1;
        true
    }

    /// The terms in use.
    pub fn active(&self) -> &[Term] {
        &self.terms[..(self.len as usize).min(MAX_TERMS)]
    }

    /// Check lengths, indices and coefficients.
    pub fn validate(&self) -> Result<(), &'static str> {
        if self.len as usize > MAX_TERMS {
            return Err("len exceeds the maximum number of terms (8)");
        }
        for (k, t) in self.active().iter().enumerate() {
            if t.validate(k, sig::COUNT).is_err() {
                return Err("a term reads a signal index outside the run-time signals");
            }
            if !self.coef[k].is_finite() {
                return Err("a coefficient is not finite");
            }
        }
        Ok(())
    }

    /// Sum of `coef * term` for one tick (advances the terms' state).
    #[inline]
    pub fn eval(&self, state: &mut AddedState, signals: &Signals, dt_s: f32) -> f32 {
        let mut sum = 0.0;
        for (k, t) in self.active().iter().enumerate() {
            sum += self.coef[k] * t.update(&mut state[k], signals, dt_s);
        }
        sum
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::effects::EffectKind;

    #[test]
    fn names_and_indices_agree() {
        for (k, n) in SIGNAL_NAMES.iter().enumerate() {
            assert_eq!(signal_index(n), Some(k as u8));
        }
        assert_eq!(signal_index("nope"), None);
    }

    #[test]
    fn eval_sums_weighted_terms() {
        let mut a = AddedTerms::default();
        assert!(a.push(Term::new(EffectKind::Linear, sig::X2_M), 2.0));
        assert!(a.push(Term::CONSTANT, 0.5));
        a.validate().unwrap();
        let mut st = AddedState::default();
        let mut s = Signals::default();
        s[sig::X2_M as usize] = 0.25;
        assert!((a.eval(&mut st, &s, 5e-4) - 1.0).abs() < 1e-6);
        let mut bad = a;
        bad.terms[0].input = 42;
        assert!(bad.validate().is_err());
    }
}
