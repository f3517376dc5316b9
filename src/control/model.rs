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

use crate::effects::{EffectError, Term, TermState};

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
///
/// In a configuration file only the terms in use are written, one table
/// each, the signals named by their log columns ([`SIGNAL_NAMES`]):
///
/// ```toml
/// [[jae.added]]
/// input = "x2_m"
/// coef = 54.8
///
/// [jae.added.kind.Stop]
/// half_width = 1.738e-5
/// ```
///
/// (`aux = "..."` for the kinds that read a second signal). The slot form
/// earlier versions wrote (`len`, `terms`, `coef` arrays) is still read.
#[derive(Clone, Copy, Debug, PartialEq)]
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

    /// No term in use.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The terms in use.
    pub fn active(&self) -> &[Term] {
        &self.terms[..(self.len as usize).min(MAX_TERMS)]
    }

    /// Check lengths, indices, parameters and coefficients; the error says
    /// what a valid bank is (a configuration error's `expected`), and
    /// [`AddedTerms::term_error`] which term breaks it.
    pub fn validate(&self) -> Result<(), &'static str> {
        if self.len as usize > MAX_TERMS {
            return Err("at most 8 terms (`len` is larger)");
        }
        for (k, t) in self.active().iter().enumerate() {
            match t.validate(k, sig::COUNT) {
                Err(EffectError::BadParameter { .. }) => {
                    return Err("terms whose parameters are finite and positive");
                }
                Err(_) => return Err("terms that read the run-time signals only"),
                Ok(()) => {}
            }
            if !self.coef[k].is_finite() {
                return Err("terms with finite coefficients");
            }
        }
        Ok(())
    }

    /// The first term whose signals or parameters [`AddedTerms::validate`]
    /// refuses, with why (its position counted from 0).
    pub fn term_error(&self) -> Option<EffectError> {
        self.active()
            .iter()
            .enumerate()
            .find_map(|(k, t)| t.validate(k, sig::COUNT).err())
    }

    /// Put the active terms' state back at rest (`state[..len]`). The slots
    /// past the bank are never advanced while it is in force and stay at
    /// rest ([`AddedTerms::retire`] keeps them so when a bank is replaced),
    /// so homing need not rewrite all [`MAX_TERMS`] of them on its tick.
    #[inline]
    pub fn restart(&self, state: &mut AddedState) {
        for s in state.iter_mut().take(self.active().len()) {
            *s = TermState::default();
        }
    }

    /// `next` replaces this bank: the state of the terms this bank advanced
    /// and `next` does not have goes back to rest, so every slot past the
    /// bank in force is at rest.
    #[inline]
    pub fn retire(&self, next: &AddedTerms, state: &mut AddedState) {
        let (kept, used) = (next.active().len(), self.active().len());
        for s in state.iter_mut().take(used).skip(kept) {
            *s = TermState::default();
        }
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

#[cfg(feature = "serde")]
mod file_form {
    //! [`AddedTerms`] in a configuration file: the terms in use only, each
    //! with its signals named. In a binary format (the host link's
    //! `postcard`, which is not self-describing and says so through
    //! `is_human_readable`), the slot form: `len`, the terms and the
    //! coefficients, as a tuple.

    use core::fmt;

    use serde::de::{self, Deserializer, MapAccess, SeqAccess, Visitor};
    use serde::ser::{SerializeSeq, Serializer};
    use serde::{Deserialize, Serialize};

    use super::{signal_index, AddedTerms, MAX_TERMS, SIGNAL_NAMES};
    use crate::effects::{EffectKind, Term};

    /// One term as written (the kind last: it is a table in TOML).
    #[derive(Serialize)]
    struct TermOut<'a> {
        input: &'a str,
        #[serde(skip_serializing_if = "Option::is_none")]
        aux: Option<&'a str>,
        coef: f32,
        kind: &'a EffectKind,
    }

    /// One term as read.
    #[derive(Deserialize)]
    #[serde(deny_unknown_fields)]
    struct TermIn {
        input: Signal,
        #[serde(default)]
        aux: Option<Signal>,
        coef: f32,
        kind: EffectKind,
    }

    /// The slot form of earlier versions.
    #[derive(Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Slots {
        #[serde(default)]
        len: u8,
        #[serde(default = "constant_terms")]
        terms: [Term; MAX_TERMS],
        #[serde(default)]
        coef: [f32; MAX_TERMS],
    }

    fn constant_terms() -> [Term; MAX_TERMS] {
        AddedTerms::default().terms
    }

    /// A run-time signal named by its log column.
    struct Signal(u8);

    impl<'de> Deserialize<'de> for Signal {
        fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
            struct Name;
            impl Visitor<'_> for Name {
                type Value = Signal;
                fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                    f.write_str("a run-time signal's column name")
                }
                fn visit_str<E: de::Error>(self, v: &str) -> Result<Signal, E> {
                    signal_index(v)
                        .map(Signal)
                        .ok_or_else(|| E::invalid_value(de::Unexpected::Str(v), &OneOfTheSignals))
                }
            }
            d.deserialize_str(Name)
        }
    }

    /// "one of x1_m, x1_vel_m_s, ...": the names of [`SIGNAL_NAMES`].
    struct OneOfTheSignals;

    impl de::Expected for OneOfTheSignals {
        fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
            f.write_str("one of ")?;
            for (k, n) in SIGNAL_NAMES.iter().enumerate() {
                if k > 0 {
                    f.write_str(", ")?;
                }
                f.write_str(n)?;
            }
            Ok(())
        }
    }

    fn name(index: u8) -> &'static str {
        SIGNAL_NAMES.get(usize::from(index)).copied().unwrap_or("?")
    }

    impl Serialize for AddedTerms {
        fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
            if !s.is_human_readable() {
                return (self.len, &self.terms, &self.coef).serialize(s);
            }
            let active = self.active();
            let mut seq = s.serialize_seq(Some(active.len()))?;
            for (t, coef) in active.iter().zip(self.coef) {
                seq.serialize_element(&TermOut {
                    input: name(t.input),
                    aux: t.kind.uses_aux().then(|| name(t.aux)),
                    coef,
                    kind: &t.kind,
                })?;
            }
            seq.end()
        }
    }

    impl<'de> Deserialize<'de> for AddedTerms {
        fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
            if !d.is_human_readable() {
                let (len, terms, coef) =
                    <(u8, [Term; MAX_TERMS], [f32; MAX_TERMS])>::deserialize(d)?;
                return Ok(AddedTerms { len, terms, coef });
            }
            struct Form;
            impl<'de> Visitor<'de> for Form {
                type Value = AddedTerms;
                fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                    f.write_str("a list of effect terms (input, coef, kind)")
                }
                fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<AddedTerms, A::Error> {
                    let mut out = AddedTerms::default();
                    while let Some(t) = seq.next_element::<TermIn>()? {
                        let term = Term {
                            kind: t.kind,
                            input: t.input.0,
                            aux: t.aux.map_or(0, |a| a.0),
                        };
                        if !out.push(term, t.coef) {
                            return Err(de::Error::invalid_length(
                                MAX_TERMS + 1,
                                &"at most 8 effect terms",
                            ));
                        }
                    }
                    Ok(out)
                }
                fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<AddedTerms, A::Error> {
                    let s = Slots::deserialize(de::value::MapAccessDeserializer::new(map))?;
                    Ok(AddedTerms {
                        len: s.len,
                        terms: s.terms,
                        coef: s.coef,
                    })
                }
            }
            d.deserialize_any(Form)
        }
    }
}
