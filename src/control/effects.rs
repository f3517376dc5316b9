//! Effect library: candidate regressor columns for the residual analysis.
//!
//! The seed's models (JAE Eq. 26, tension model C Eq. 24) are linear in their
//! parameters, with regressors built from the measured signals. Effects the
//! seed leaves out (presliding hysteresis, backlash, cable creep, winding
//! heating, slow zero drift, nonlinear stiffness) are added the same way: each
//! is one more column `w_k(t)` computed from the log's signals, sample by
//! sample, with an unknown coefficient fitted by [`crate::lsq`]. The host's
//! residual tool ranks its candidate library (host-side) against a model's residual;
//! the selected [`Term`]s go into the configuration and the firmware evaluates
//! them at run time with an [`EffectBank`], the same code.
//!
//! A term reads its input(s) from a per-sample slice of signals by index
//! (`input`, and `aux` for products); the host maps CSV columns to indices.
//! Configuration ([`Term`]) is apart from state ([`TermState`]).
//!
//! Conventions of the stateful terms: on the first sample after a reset the
//! state is initialised from the input (filters start settled, play operators
//! centred, the Dahl state at 0, time at 0), so a log that starts at rest has
//! no start-up transient. `dt_s` is the time since the previous sample; a
//! non-positive or non-finite `dt_s` advances nothing. A non-finite input
//! returns NaN and leaves the state unchanged. First-order states are kept in
//! `f64`: with time constants of minutes at 2 kHz the per-sample increment is
//! far below one `f32` ulp.

use core::fmt;

use crate::math;

/// One kind of effect column and its parameters. Widths, lengths and
/// velocity scales are in the unit of the term's input signal.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum EffectKind {
    /// `1`: an offset (preload `F_0`, sensor zero).
    Constant,
    /// `u`: a stiffness (on a position), viscous friction (on a velocity), a
    /// gain (on a current or a force).
    Linear,
    /// `t / scale_s`, `t` the time since the reset: a linear zero drift
    /// (seed 001's sensor zero-drift); `scale_s = 3600` gives drift per hour.
    Time {
        /// Time unit of the coefficient, s.
        scale_s: f32,
    },
    /// `1 - exp(-t / tau_s)`: a warm-up drift that settles after power-on.
    Warmup {
        /// Settling time constant, s.
        tau_s: f32,
    },
    /// `tanh(v / v_eps)`: Coulomb friction with a smooth sign (seed's
    /// `f_sc sgn(x')`), `v_eps` the velocity below which it is linear.
    SmoothSign {
        /// Smoothing velocity (input unit).
        v_eps: f32,
    },
    /// `exp(-(v / v_s)^2) tanh(v / v_eps)`: the Stribeck excess of static over
    /// Coulomb friction, fading above the Stribeck velocity `v_s`.
    Stribeck {
        /// Stribeck velocity (input unit).
        v_s: f32,
        /// Smoothing velocity of the sign (input unit).
        v_eps: f32,
    },
    /// Play (backlash) operator `y = clamp(y, u - w, u + w)`: the position
    /// passed through a gap of total width `2 w` (the output lags the input by
    /// `w` after each reversal).
    Play {
        /// Half width of the play, input unit.
        half_width: f32,
    },
    /// Stop operator `u - play(u)`, in `[-w, w]`: elasto-plastic presliding
    /// hysteresis, a spring of deflection up to `w` that slips beyond it
    /// (coefficient = presliding stiffness). Equals `Linear - Play`.
    Stop {
        /// Slip deflection, input unit.
        half_width: f32,
    },
    /// Dahl friction state `z` in `[-1, 1]`, `dz/dx = (1 - z sgn(dx)) / L`:
    /// smooth rate-independent presliding hysteresis, `L` the displacement
    /// over which friction builds up after a reversal (coefficient = Coulomb
    /// level).
    Dahl {
        /// Characteristic length `L`, input unit.
        length: f32,
    },
    /// Dead zone `u - clamp(u, c - w, c + w)`: zero inside a gap around `c`,
    /// linear outside: backlash on a position (slack cable).
    DeadZone {
        /// Centre of the gap, input unit.
        center: f32,
        /// Half width of the gap, input unit.
        half_width: f32,
    },
    /// `u * a`: load-dependent stretch (e.g. tension times position, the
    /// stiffening or softening of a cable with load), or `u^2` with `a = u`.
    Product,
    /// `|a| tanh(v / v_eps)`, `v` the input (a velocity), `a` the second
    /// signal (a load): Coulomb friction proportional to the force the
    /// element transmits (a cable wrapped on a pulley, a loaded gear: the
    /// capstan effect, a load-dependent efficiency). Coefficient = friction
    /// per unit of load.
    LoadCoulomb {
        /// Smoothing velocity of the sign (input unit).
        v_eps: f32,
    },
    /// `|a| z`, `z` the [`Dahl`](EffectKind::Dahl) state of the input (a
    /// position), `a` the second signal (a load): presliding hysteresis whose
    /// level grows with the transmitted load.
    LoadDahl {
        /// Characteristic length `L`, input unit.
        length: f32,
    },
    /// First-order lag `y' = (u - y) / tau`: the part of a response that
    /// follows the input slowly (viscoelastic relaxation).
    Relaxation {
        /// Time constant, s.
        tau_s: f32,
    },
    /// `u - lag(u)`: creep, the deformation still to come after a change of
    /// the input (cable creep under tension); decays as `exp(-t / tau)`.
    Creep {
        /// Time constant, s.
        tau_s: f32,
    },
    /// First-order lag of `u^2` (unit DC gain): winding temperature rise
    /// driven by `i^2 R` losses, with the thermal time constant `tau`.
    Thermal {
        /// Thermal time constant, s.
        tau_s: f32,
    },
    /// The load remembered from the driven stroke: the peak of `|u|`,
    /// decaying as `exp(-t / tau)` while `|u|` stays below it. On a
    /// back-driven, nearly self-locking stroke the motor current drops to
    /// about zero while the load stays: the state keeps the level the
    /// driven stroke measured.
    LoadMemory {
        /// Decay time constant, s.
        tau_s: f32,
    },
    /// The load measured on the last stroke: a first-order lag of `u`,
    /// `u sgn(v)` or `sgn(v)` ([`StrokePart`]) that moves only while the
    /// velocity `v` (the second signal, `aux`) exceeds `v_min` in
    /// magnitude, and holds through reversals and rest; 0 until the first
    /// such sample, then started there. A transmission whose efficiency
    /// differs between the driven and the back-driven stroke maps the load
    /// to the current with a gain and an offset that depend on the
    /// direction: the three parts together carry `a u + b u sgn(v) +
    /// c sgn(v)`, the load as the strokes measured it.
    StrokeHold {
        /// Speed below which the state holds (unit of `aux`).
        v_min: f32,
        /// Time constant of the lag while moving, s.
        tau_s: f32,
        /// What the state follows.
        part: StrokePart,
    },
    /// `u |u|`: quadratic stiffening, odd in `u`.
    SignedSquare,
    /// `u^3`: cubic stiffening.
    Cube,
    /// Bouc–Wen hysteresis state `z` of the input (a position), rate
    /// independent and normalized to saturate at `|z| = 1`:
    /// `dz/dx = (1 - (beta sgn(dx z) + gamma) |z|^n) / L` with
    /// `beta + gamma = 1`. Moving the way `z` points it builds up as
    /// `(1 - |z|^n) / L`; after a reversal it unloads at
    /// `(1 + shape |z|^n) / L`, `shape = beta - gamma` in `[0, 1]`. `shape =
    /// 1` with `n = 1` is the [`Dahl`](EffectKind::Dahl) state; `shape = 0`
    /// unloads elastically (slope `1 / L`, a cable that relaxes before the
    /// friction reverses); a larger `n` turns the knee sharper, toward the
    /// elasto-plastic [`Stop`](EffectKind::Stop) operator. (A negative
    /// shape would let a saturated state unload at zero slope and never
    /// leave saturation.) Coefficient = the hysteresis' level.
    BoucWen {
        /// Characteristic length `L`, input unit.
        length: f32,
        /// Unloading shape `beta - gamma`, in `[0, 1]`.
        shape: f32,
        /// Exponent `n`, 1 to [`BOUC_WEN_MAX_EXPONENT`].
        exponent: u8,
    },
}

/// Largest exponent of an [`EffectKind::BoucWen`] state (`|z|^n` by
/// multiplication, no transcendental function).
pub const BOUC_WEN_MAX_EXPONENT: u8 = 8;

/// What an [`EffectKind::StrokeHold`] state follows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum StrokePart {
    /// The input `u` (the load's common part).
    Level,
    /// `u sgn(v)`: the gain that differs between the strokes.
    Signed,
    /// `sgn(v)`: the offset that differs between the strokes.
    Direction,
}

impl StrokePart {
    /// Short name for labels.
    pub const fn name(self) -> &'static str {
        match self {
            StrokePart::Level => "u",
            StrokePart::Signed => "u*sgn",
            StrokePart::Direction => "sgn",
        }
    }
}

/// One candidate column: a kind, its input signal index and (for
/// [`EffectKind::Product`]) the second signal's index.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Term {
    /// What to compute.
    pub kind: EffectKind,
    /// Index of the input signal in the per-sample slice.
    pub input: u8,
    /// Index of the second signal (products only; ignored otherwise).
    pub aux: u8,
}

/// State of one [`Term`] (zero-size in meaning for stateless kinds).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TermState {
    started: bool,
    /// Filter output, play output or Dahl state.
    y: f64,
    /// Previous input (Dahl) or elapsed time (Time, Warmup), s.
    aux: f64,
    /// Step of the cached filter coefficient and the coefficient.
    dt_cached_s: f32,
    alpha: f64,
}

/// Why a term set was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EffectError {
    /// A term reads a signal index that the sample will not have.
    InputOutOfRange {
        /// Position of the term in the set.
        term: u8,
        /// The index it reads.
        index: u8,
        /// Number of signals per sample.
        n_signals: u8,
    },
    /// A width, length, velocity scale or time constant is not finite and
    /// positive.
    BadParameter {
        /// Position of the term in the set.
        term: u8,
        /// Name of the parameter.
        name: &'static str,
    },
    /// More terms than the bank holds.
    TooManyTerms {
        /// Terms given.
        given: usize,
        /// Capacity `M`.
        capacity: usize,
    },
}

impl fmt::Display for EffectError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            EffectError::InputOutOfRange {
                term,
                index,
                n_signals,
            } => write!(
                f,
                "term {term} reads signal {index}, but a sample has {n_signals} signals"
            ),
            EffectError::BadParameter { term, name } => {
                write!(f, "term {term}: `{name}` must be finite and positive")
            }
            EffectError::TooManyTerms { given, capacity } => {
                write!(f, "{given} terms given, the bank holds {capacity}")
            }
        }
    }
}

/// `1 - exp(-x)` for `x >= 0` in `f64`, accurate also for tiny `x` (where
/// `1 - exp(-x)` in `f32` would lose all digits): a Taylor series of
/// `-expm1(-x)` (plain arithmetic) below 0.25, the `f32` exponential above.
fn one_minus_exp_neg(x: f64) -> f64 {
    if x >= 0.25 {
        return 1.0 - f64::from(math::exp(-(x as f32)));
    }
    // x - x^2/2 + x^3/6 - ... ; 10 terms: truncation below 0.25^11/11! ~ 1e-14.
    let (mut term, mut sum) = (x, x);
    for k in 2..=10 {
        term *= -x / k as f64;
        sum += term;
    }
    sum
}

impl EffectKind {
    /// Short name for reports and CSV headers.
    pub const fn name(&self) -> &'static str {
        match self {
            EffectKind::Constant => "const",
            EffectKind::Linear => "linear",
            EffectKind::Time { .. } => "time",
            EffectKind::Warmup { .. } => "warmup",
            EffectKind::SmoothSign { .. } => "coulomb",
            EffectKind::Stribeck { .. } => "stribeck",
            EffectKind::Play { .. } => "play",
            EffectKind::Stop { .. } => "stop",
            EffectKind::Dahl { .. } => "dahl",
            EffectKind::DeadZone { .. } => "deadzone",
            EffectKind::Product => "product",
            EffectKind::LoadCoulomb { .. } => "load_coulomb",
            EffectKind::LoadDahl { .. } => "load_dahl",
            EffectKind::Relaxation { .. } => "relax",
            EffectKind::Creep { .. } => "creep",
            EffectKind::Thermal { .. } => "thermal",
            EffectKind::LoadMemory { .. } => "load_memory",
            EffectKind::StrokeHold { .. } => "stroke_load",
            EffectKind::SignedSquare => "sqr_sign",
            EffectKind::Cube => "cube",
            EffectKind::BoucWen { .. } => "bouc_wen",
        }
    }

    /// One-sentence physical meaning for reports.
    pub const fn meaning(&self) -> &'static str {
        match self {
            EffectKind::Constant => "constant offset (preload, sensor zero)",
            EffectKind::Linear => "linear in the signal: stiffness, viscous friction or gain",
            EffectKind::Time { .. } => "linear drift of the zero over time",
            EffectKind::Warmup { .. } => "exponentially settling drift after power-on (warm-up)",
            EffectKind::SmoothSign { .. } => {
                "Coulomb friction with a smoothed sign of the velocity"
            }
            EffectKind::Stribeck { .. } => {
                "Stribeck excess of static over Coulomb friction at low speed"
            }
            EffectKind::Play { .. } => "position passed through a backlash gap (play operator)",
            EffectKind::Stop { .. } => "elasto-plastic presliding hysteresis (stop operator)",
            EffectKind::Dahl { .. } => {
                "Dahl presliding friction state building up over a characteristic length"
            }
            EffectKind::DeadZone { .. } => "dead zone on a position: slack cable or backlash",
            EffectKind::Product => "product of two signals: load-dependent stretch or stiffness",
            EffectKind::LoadCoulomb { .. } => {
                "Coulomb friction growing with the transmitted load (capstan, load-dependent efficiency)"
            }
            EffectKind::LoadDahl { .. } => {
                "presliding hysteresis (Dahl) whose level grows with the transmitted load"
            }
            EffectKind::Relaxation { .. } => {
                "first-order lagged copy of the signal: viscoelastic relaxation"
            }
            EffectKind::Creep { .. } => {
                "signal minus its lagged copy: creep still to come after a change"
            }
            EffectKind::Thermal { .. } => {
                "first-order lag of the squared current: winding temperature rise"
            }
            EffectKind::LoadMemory { .. } => {
                "load remembered from the driven stroke (peak of |u|, slowly decaying): carries the load through a back-driven stroke"
            }
            EffectKind::StrokeHold { .. } => {
                "load as the last stroke measured it (held through reversals): a direction-dependent efficiency"
            }
            EffectKind::SignedSquare => "odd quadratic stiffening",
            EffectKind::Cube => "cubic stiffening",
            EffectKind::BoucWen { .. } => {
                "Bouc-Wen hysteresis state: friction or cable hysteresis with its own unloading shape and knee"
            }
        }
    }

    /// Whether the kind reads its `input` signal.
    pub const fn uses_input(&self) -> bool {
        !matches!(
            self,
            EffectKind::Constant | EffectKind::Time { .. } | EffectKind::Warmup { .. }
        )
    }

    /// Whether the kind reads a second signal (`aux`).
    pub const fn uses_aux(&self) -> bool {
        matches!(
            self,
            EffectKind::Product
                | EffectKind::LoadCoulomb { .. }
                | EffectKind::LoadDahl { .. }
                | EffectKind::StrokeHold { .. }
        )
    }

    /// The positive parameters of the kind, with their names.
    fn positive_params(&self) -> [(&'static str, f32); 2] {
        const NONE: (&str, f32) = ("", 1.0);
        match *self {
            EffectKind::Time { scale_s } => [("scale_s", scale_s), NONE],
            EffectKind::Warmup { tau_s }
            | EffectKind::Relaxation { tau_s }
            | EffectKind::Creep { tau_s }
            | EffectKind::Thermal { tau_s }
            | EffectKind::LoadMemory { tau_s } => [("tau_s", tau_s), NONE],
            EffectKind::SmoothSign { v_eps } | EffectKind::LoadCoulomb { v_eps } => {
                [("v_eps", v_eps), NONE]
            }
            EffectKind::Stribeck { v_s, v_eps } => [("v_s", v_s), ("v_eps", v_eps)],
            EffectKind::StrokeHold { v_min, tau_s, .. } => [("v_min", v_min), ("tau_s", tau_s)],
            EffectKind::Play { half_width } | EffectKind::Stop { half_width } => {
                [("half_width", half_width), NONE]
            }
            EffectKind::DeadZone { center, half_width } => {
                // The centre may be any finite value: map finite to 1.
                let c = if center.is_finite() { 1.0 } else { f32::NAN };
                [("half_width", half_width), ("center", c)]
            }
            EffectKind::Dahl { length } | EffectKind::LoadDahl { length } => {
                [("length", length), NONE]
            }
            EffectKind::BoucWen {
                length,
                shape,
                exponent,
            } => {
                // The shape and the exponent have ranges, not a sign: map
                // an admissible value to 1.
                let ok = |b: bool| if b { 1.0 } else { f32::NAN };
                [
                    ("length", length),
                    (
                        "shape in [0, 1], exponent in [1, 8]",
                        ok((0.0..=1.0).contains(&shape)
                            && (1..=BOUC_WEN_MAX_EXPONENT).contains(&exponent)),
                    ),
                ]
            }
            EffectKind::Constant
            | EffectKind::Linear
            | EffectKind::Product
            | EffectKind::SignedSquare
            | EffectKind::Cube => [NONE, NONE],
        }
    }
}

impl Term {
    /// A constant-1 term (also the filler of unused bank slots).
    pub const CONSTANT: Term = Term {
        kind: EffectKind::Constant,
        input: 0,
        aux: 0,
    };

    /// A single-input term.
    pub const fn new(kind: EffectKind, input: u8) -> Self {
        Self {
            kind,
            input,
            aux: 0,
        }
    }

    /// The product `signal[a] * signal[b]`.
    pub const fn product(a: u8, b: u8) -> Self {
        Self {
            kind: EffectKind::Product,
            input: a,
            aux: b,
        }
    }

    /// A two-signal term: `kind` reads `input` and `aux` (the load of
    /// [`EffectKind::LoadCoulomb`] and [`EffectKind::LoadDahl`]).
    pub const fn with_aux(kind: EffectKind, input: u8, aux: u8) -> Self {
        Self { kind, input, aux }
    }

    /// Short name of the kind.
    pub const fn name(&self) -> &'static str {
        self.kind.name()
    }

    /// One-sentence meaning of the kind.
    pub const fn meaning(&self) -> &'static str {
        self.kind.meaning()
    }

    /// Check the indices against `n_signals` and the parameters (`term` is the
    /// position reported in the error).
    pub fn validate(&self, term: usize, n_signals: usize) -> Result<(), EffectError> {
        let term_u8 = term.min(u8::MAX as usize) as u8;
        let out = |index: u8| EffectError::InputOutOfRange {
            term: term_u8,
            index,
            n_signals: n_signals.min(u8::MAX as usize) as u8,
        };
        if self.kind.uses_input() && self.input as usize >= n_signals {
            return Err(out(self.input));
        }
        if self.kind.uses_aux() && self.aux as usize >= n_signals {
            return Err(out(self.aux));
        }
        for (name, v) in self.kind.positive_params() {
            if !(v > 0.0 && v.is_finite()) {
                return Err(EffectError::BadParameter {
                    term: term_u8,
                    name,
                });
            }
        }
        Ok(())
    }

    /// Compute this term's column for one sample and advance its state.
    /// Out-of-range indices read 0 (validate first to rule them out).
    pub fn update(&self, state: &mut TermState, signals: &[f32], dt_s: f32) -> f32 {
        let u = signals.get(self.input as usize).copied().unwrap_or(0.0);
        if self.kind.uses_input() && !u.is_finite() {
            return f32::NAN;
        }
        let a = signals.get(self.aux as usize).copied().unwrap_or(0.0);
        if self.kind.uses_aux() && !a.is_finite() {
            return f32::NAN;
        }
        let dt_s = if dt_s > 0.0 && dt_s.is_finite() {
            dt_s
        } else {
            0.0
        };
        let first = !state.started;
        state.started = true;
        match self.kind {
            EffectKind::Constant => 1.0,
            EffectKind::Linear => u,
            EffectKind::Time { scale_s } => {
                if !first {
                    state.aux += f64::from(dt_s);
                }
                (state.aux / f64::from(scale_s)) as f32
            }
            EffectKind::Warmup { tau_s } => {
                state.y = if first {
                    0.0
                } else {
                    lag(state, state.y, 1.0, dt_s, tau_s)
                };
                state.y as f32
            }
            EffectKind::SmoothSign { v_eps } => math::tanh(u / v_eps),
            EffectKind::Stribeck { v_s, v_eps } => {
                let r = u / v_s;
                math::exp(-r * r) * math::tanh(u / v_eps)
            }
            EffectKind::Play { half_width } => play(state, u, half_width, first) as f32,
            EffectKind::Stop { half_width } => {
                (f64::from(u) - play(state, u, half_width, first)) as f32
            }
            EffectKind::Dahl { length } => dahl(state, u, length, first) as f32,
            EffectKind::LoadDahl { length } => {
                (dahl(state, u, length, first) * f64::from(math::abs(a))) as f32
            }
            EffectKind::LoadCoulomb { v_eps } => math::abs(a) * math::tanh(u / v_eps),
            EffectKind::DeadZone { center, half_width } => {
                u - math::clamp(u, center - half_width, center + half_width)
            }
            EffectKind::Product => u * a,
            EffectKind::Relaxation { tau_s } => {
                let x = f64::from(u);
                state.y = if first {
                    x
                } else {
                    lag(state, state.y, x, dt_s, tau_s)
                };
                state.y as f32
            }
            EffectKind::Creep { tau_s } => {
                let x = f64::from(u);
                state.y = if first {
                    x
                } else {
                    lag(state, state.y, x, dt_s, tau_s)
                };
                (x - state.y) as f32
            }
            EffectKind::Thermal { tau_s } => {
                let x = f64::from(u) * f64::from(u);
                state.y = if first {
                    x
                } else {
                    lag(state, state.y, x, dt_s, tau_s)
                };
                state.y as f32
            }
            EffectKind::LoadMemory { tau_s } => {
                let level = f64::from(math::abs(u));
                state.y = if first {
                    level
                } else {
                    // The peak decays toward zero; a larger load replaces it.
                    let decayed = lag(state, state.y, 0.0, dt_s, tau_s);
                    if level > decayed {
                        level
                    } else {
                        decayed
                    }
                };
                state.y as f32
            }
            EffectKind::StrokeHold { v_min, tau_s, part } => {
                stroke_hold(state, u, a, v_min, tau_s, part, dt_s) as f32
            }
            EffectKind::SignedSquare => u * math::abs(u),
            EffectKind::Cube => u * u * u,
            EffectKind::BoucWen {
                length,
                shape,
                exponent,
            } => bouc_wen(state, u, length, shape, exponent, first) as f32,
        }
    }
}

/// One step of `y' = (x - y) / tau` with this sample's input `x` held since the
/// previous sample (exact for a piecewise-constant input): `y += (1 - exp(-dt/tau)) (x - y)`. The
/// coefficient is cached for the last `dt`.
fn lag(state: &mut TermState, y: f64, x: f64, dt_s: f32, tau_s: f32) -> f64 {
    if dt_s != state.dt_cached_s {
        state.dt_cached_s = dt_s;
        state.alpha = one_minus_exp_neg(f64::from(dt_s) / f64::from(tau_s));
    }
    y + state.alpha * (x - y)
}

/// [`EffectKind::StrokeHold`]: the lag moves only while `|v| > v_min`
/// (`aux` is 1 once a moving sample has started the state, 0 before).
fn stroke_hold(
    state: &mut TermState,
    u: f32,
    v: f32,
    v_min: f32,
    tau_s: f32,
    part: StrokePart,
    dt_s: f32,
) -> f64 {
    if math::abs(v) > v_min {
        let s = if v > 0.0 { 1.0 } else { -1.0 };
        let x = match part {
            StrokePart::Level => f64::from(u),
            StrokePart::Signed => f64::from(u) * s,
            StrokePart::Direction => s,
        };
        state.y = if state.aux == 0.0 {
            x
        } else {
            lag(state, state.y, x, dt_s, tau_s)
        };
        state.aux = 1.0;
    }
    state.y
}

/// Dahl state `z` of the position `u`: `dz/dx = (1 - z sgn(dx)) / L`, solved
/// exactly over each monotone step, `z = s - (s - z0) exp(-|dx| / L)`; 0 at
/// the first sample.
fn dahl(state: &mut TermState, u: f32, length: f32, first: bool) -> f64 {
    let x = f64::from(u);
    if first {
        state.y = 0.0;
    } else {
        let dx = x - state.aux;
        if dx != 0.0 {
            let s = if dx > 0.0 { 1.0 } else { -1.0 };
            let a = one_minus_exp_neg(if dx > 0.0 { dx } else { -dx } / f64::from(length));
            state.y += (s - state.y) * a;
        }
    }
    state.aux = x;
    state.y
}

/// Bouc–Wen state `z` of the position `u` ([`EffectKind::BoucWen`]), 0 at
/// the first sample. Each sample's step is split into equal pieces of at
/// most a twentieth of `L`, each taken by the midpoint rule and kept in
/// `[-1, 1]`: within about 3 parts in 10⁴ of the saturation level of the
/// exact state (the test compares the Dahl corner with its closed form).
/// Of a step longer than 32 such pieces (1.6 `L` in one sample, far beyond
/// any motion between two ticks) the part beyond them moves the state
/// toward saturation as the Dahl state would (exactly so at the Dahl
/// corner), and the last 1.6 `L` are integrated as above.
fn bouc_wen(state: &mut TermState, u: f32, length: f32, shape: f32, n: u8, first: bool) -> f64 {
    let x = f64::from(u);
    if first {
        state.y = 0.0;
        state.aux = x;
        return 0.0;
    }
    let dx = x - state.aux;
    state.aux = x;
    if dx == 0.0 {
        return state.y;
    }
    let l = f64::from(length);
    let rho = f64::from(shape);
    // dz/dx at z for a step of sign `s`.
    let slope = |z: f64, s: f64| {
        let mut p = if z < 0.0 { -z } else { z };
        let a = p;
        for _ in 1..n {
            p *= a;
        }
        let loading = z * s > 0.0;
        (if loading { 1.0 - p } else { 1.0 + rho * p }) / l
    };
    let s = if dx > 0.0 { 1.0 } else { -1.0 };
    let travel = if dx > 0.0 { dx } else { -dx };
    let fine = 32.0 * 0.05 * l;
    let mut z = state.y;
    let rest = if travel > fine {
        z += (s - z) * one_minus_exp_neg((travel - fine) / l);
        s * fine
    } else {
        dx
    };
    let pieces = ((if rest > 0.0 { rest } else { -rest }) / (0.05 * l)).min(31.0) as u32 + 1;
    let h = rest / f64::from(pieces);
    for _ in 0..pieces {
        let mid = (z + 0.5 * h * slope(z, s)).clamp(-1.0, 1.0);
        z = (z + h * slope(mid, s)).clamp(-1.0, 1.0);
    }
    state.y = z;
    z
}

/// Play operator: the output stays put until the input is more than `w` away,
/// then is dragged along at distance `w`.
fn play(state: &mut TermState, u: f32, w: f32, first: bool) -> f64 {
    let x = f64::from(u);
    let w = f64::from(w);
    // max/min, not clamp: no panic even for an unvalidated negative width.
    state.y = if first {
        x
    } else {
        state.y.max(x - w).min(x + w)
    };
    state.y
}

impl fmt::Display for Term {
    /// `name[input]` with the parameters, e.g. `creep[3](tau=12.5s)`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let n = self.name();
        match self.kind {
            EffectKind::Constant => write!(f, "{n}"),
            EffectKind::Time { scale_s } => write!(f, "{n}(per {scale_s}s)"),
            EffectKind::Warmup { tau_s } => write!(f, "{n}(tau={tau_s}s)"),
            EffectKind::Linear | EffectKind::SignedSquare | EffectKind::Cube => {
                write!(f, "{n}[{}]", self.input)
            }
            EffectKind::Product => write!(f, "{n}[{}*{}]", self.input, self.aux),
            EffectKind::SmoothSign { v_eps } => write!(f, "{n}[{}](eps={v_eps:e})", self.input),
            EffectKind::Stribeck { v_s, v_eps } => {
                write!(f, "{n}[{}](vs={v_s:e},eps={v_eps:e})", self.input)
            }
            EffectKind::Play { half_width } | EffectKind::Stop { half_width } => {
                write!(f, "{n}[{}](w={half_width:e})", self.input)
            }
            EffectKind::Dahl { length } => write!(f, "{n}[{}](L={length:e})", self.input),
            EffectKind::LoadCoulomb { v_eps } => {
                write!(f, "{n}[{}*|{}|](eps={v_eps:e})", self.input, self.aux)
            }
            EffectKind::LoadDahl { length } => {
                write!(f, "{n}[{}*|{}|](L={length:e})", self.input, self.aux)
            }
            EffectKind::DeadZone { center, half_width } => {
                write!(f, "{n}[{}](c={center:e},w={half_width:e})", self.input)
            }
            EffectKind::Relaxation { tau_s }
            | EffectKind::Creep { tau_s }
            | EffectKind::Thermal { tau_s }
            | EffectKind::LoadMemory { tau_s } => write!(f, "{n}[{}](tau={tau_s}s)", self.input),
            EffectKind::StrokeHold { v_min, tau_s, part } => write!(
                f,
                "{n}[{}: {}, v {}](vmin={v_min:e},tau={tau_s}s)",
                part.name(),
                self.input,
                self.aux
            ),
            EffectKind::BoucWen {
                length,
                shape,
                exponent,
            } => write!(
                f,
                "{n}[{}](L={length:e},shape={shape},n={exponent})",
                self.input
            ),
        }
    }
}

/// Up to `M` terms with their states: computes all selected columns of one
/// sample.
#[derive(Clone, Debug, PartialEq)]
pub struct EffectBank<const M: usize> {
    terms: [Term; M],
    states: [TermState; M],
    len: usize,
}

impl<const M: usize> EffectBank<M> {
    /// A bank of `terms`, validated against `n_signals` signals per sample.
    pub fn new(terms: &[Term], n_signals: usize) -> Result<Self, EffectError> {
        if terms.len() > M {
            return Err(EffectError::TooManyTerms {
                given: terms.len(),
                capacity: M,
            });
        }
        let mut bank = Self {
            terms: [Term::CONSTANT; M],
            states: [TermState::default(); M],
            len: terms.len(),
        };
        for (k, (t, slot)) in terms.iter().zip(bank.terms.iter_mut()).enumerate() {
            t.validate(k, n_signals)?;
            *slot = *t;
        }
        Ok(bank)
    }

    /// The terms, in column order.
    pub fn terms(&self) -> &[Term] {
        self.terms.get(..self.len).unwrap_or(&[])
    }

    /// Number of terms (columns).
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether the bank has no terms.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Compute the columns of one sample into `out` (as many as fit) and
    /// advance the states; returns the number of columns written.
    pub fn update(&mut self, signals: &[f32], dt_s: f32, out: &mut [f32]) -> usize {
        let mut n = 0;
        for ((t, s), o) in self
            .terms
            .iter()
            .zip(self.states.iter_mut())
            .take(self.len)
            .zip(out.iter_mut())
        {
            *o = t.update(s, signals, dt_s);
            n += 1;
        }
        n
    }

    /// Forget all states (the next sample re-initialises them).
    pub fn reset(&mut self) {
        self.states = [TermState::default(); M];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(
        term: Term,
        inputs: impl IntoIterator<Item = f32>,
        dt_s: f32,
    ) -> heapless::Vec<f32, 4096> {
        let mut st = TermState::default();
        let mut out = heapless::Vec::new();
        for u in inputs {
            out.push(term.update(&mut st, &[u, 0.0], dt_s)).unwrap();
        }
        out
    }

    /// Triangle wave between -a and a, `n` samples per half period.
    fn triangle(a: f32, n: usize, periods: usize) -> impl Iterator<Item = f32> {
        (0..2 * n * periods + 1).map(move |k| {
            let ph = (k % (2 * n)) as f32 / n as f32; // 0..2
            if ph <= 1.0 {
                -a + 2.0 * a * ph
            } else {
                a - 2.0 * a * (ph - 1.0)
            }
        })
    }

    /// The load memory follows a rising load at once, keeps its peak while
    /// the load drops to zero (a back-driven stroke), decaying with its time
    /// constant, and takes a new larger load at once.
    #[test]
    fn load_memory_holds_the_driven_strokes_peak_and_decays() {
        let t = Term::new(EffectKind::LoadMemory { tau_s: 1.0 }, 0);
        let dt = 1e-3;
        let u = (0..100)
            .map(|k| -0.01 * k as f32)
            .chain(core::iter::repeat_n(0.0, 1000))
            .chain(core::iter::once(2.0));
        let y = run(t, u, dt);
        assert!((y[99] - 0.99).abs() < 1e-6, "follows |u|: {}", y[99]);
        let after_1s = y[1099];
        let expected = 0.99 * (-1.0f32).exp();
        assert!(
            (after_1s - expected).abs() < 2e-3,
            "{after_1s} vs {expected}"
        );
        assert_eq!(y[1100], 2.0, "a larger load at once");
    }

    /// The stroke hold is 0 until the velocity first exceeds `v_min`, starts
    /// at that sample's value, follows its part with the lag while moving
    /// and keeps its value through a reversal (`|v| <= v_min`).
    #[test]
    fn the_stroke_load_follows_while_moving_and_holds_through_a_reversal() {
        let dt = 1e-3;
        let term = |part| {
            Term::with_aux(
                EffectKind::StrokeHold {
                    v_min: 0.5,
                    tau_s: 0.1,
                    part,
                },
                0,
                1,
            )
        };
        // (current, velocity): at rest, a driven stroke at -1 with 0.3 A
        // settling for 1 s, a reversal at rest with the current at 0, a
        // back stroke at +1 with -0.1 A.
        let samples: heapless::Vec<(f32, f32), 4096> = core::iter::repeat_n((0.7, 0.0), 10)
            .chain(core::iter::repeat_n((0.3, -1.0), 1000))
            .chain(core::iter::repeat_n((0.0, 0.2), 200))
            .chain(core::iter::repeat_n((-0.1, 1.0), 1000))
            .collect();
        let run2 = |part| {
            let (t, mut st) = (term(part), TermState::default());
            let y: heapless::Vec<f32, 4096> = samples
                .iter()
                .map(|&(i, v)| t.update(&mut st, &[i, v], dt))
                .collect();
            y
        };
        let (level, signed, dir) = (
            run2(StrokePart::Level),
            run2(StrokePart::Signed),
            run2(StrokePart::Direction),
        );
        assert_eq!(
            (level[9], signed[9], dir[9]),
            (0.0, 0.0, 0.0),
            "not started"
        );
        assert_eq!(
            (level[10], signed[10], dir[10]),
            (0.3, -0.3, -1.0),
            "started"
        );
        let held = 10 + 1000 + 199;
        assert_eq!(level[held], level[1009], "held through the reversal");
        assert_eq!(dir[held], -1.0);
        let end = samples.len() - 1;
        assert!((level[end] + 0.1).abs() < 1e-4, "follows: {}", level[end]);
        assert!((signed[end] + 0.1).abs() < 1e-4, "{}", signed[end]);
        assert!((dir[end] - 1.0).abs() < 1e-4, "{}", dir[end]);
        // The lag: one time constant into the back stroke, 63 % of the way.
        let k = held + 100;
        let expected = 0.3 + (-0.1 - 0.3) * (1.0 - (-1.0f32).exp());
        assert!(
            (level[k] - expected).abs() < 5e-3,
            "{} vs {expected}",
            level[k]
        );
    }

    #[test]
    fn play_operator_gives_the_backlash_loop() {
        let (a, w) = (1.0f32, 0.25f32);
        let inputs: heapless::Vec<f32, 1024> = triangle(a, 100, 3).collect();
        let play = run(
            Term::new(EffectKind::Play { half_width: w }, 0),
            inputs.iter().copied(),
            1e-3,
        );
        let stop = run(
            Term::new(EffectKind::Stop { half_width: w }, 0),
            inputs.iter().copied(),
            1e-3,
        );
        // After the first half period the loop is periodic: rising branch
        // y = u - w, falling branch y = u + w, flat for 2w after each reversal.
        for k in 200..inputs.len() {
            let (u, y, s) = (inputs[k], play[k], stop[k]);
            assert!((u - y - s).abs() < 1e-6, "stop = u - play at {k}");
            assert!(s.abs() <= w + 1e-6, "stop bounded by w at {k}: {s}");
            let ph = k % 200;
            if (50..=100).contains(&ph) {
                // rising, at least 2w past the minimum
                assert!(
                    (y - (u - w)).abs() < 1e-5,
                    "rising branch at {k}: {y} vs {}",
                    u - w
                );
            } else if ph >= 150 {
                assert!(
                    (y - (u + w)).abs() < 1e-5,
                    "falling branch at {k}: {y} vs {}",
                    u + w
                );
            } else if (1..25).contains(&ph) {
                // just after the minimum: output held at -a + w
                assert!(
                    (y - (-a + w)).abs() < 1e-5,
                    "held after reversal at {k}: {y}"
                );
            }
        }
    }

    #[test]
    fn relaxation_and_creep_step_response() {
        let (tau, dt) = (0.05f32, 1e-3f32);
        let step = (0..400).map(|k| if k == 0 { 0.0 } else { 1.0 });
        let relax = run(
            Term::new(EffectKind::Relaxation { tau_s: tau }, 0),
            step.clone(),
            dt,
        );
        let creep = run(Term::new(EffectKind::Creep { tau_s: tau }, 0), step, dt);
        for k in 1..400 {
            // The input steps to 1 at sample 1 (held since sample 0).
            let t = k as f32 * dt;
            let want = 1.0 - math::exp(-t / tau);
            assert!(
                (relax[k] - want).abs() < 2e-6,
                "relax at t={t}: {} vs {want}",
                relax[k]
            );
            assert!((creep[k] - (1.0 - want)).abs() < 2e-6, "creep at t={t}");
        }
        // Very slow filter (tau = 1e5 samples): f32 increments would vanish.
        let slow = run(
            Term::new(EffectKind::Relaxation { tau_s: 100.0 }, 0),
            (0..2001).map(|k| if k == 0 { 0.0 } else { 1.0 }),
            5e-4,
        );
        let want = 1.0 - math::exp(-2000.0 * 5e-4 / 100.0);
        assert!(
            (slow[2000] - want).abs() / want < 1e-4,
            "slow lag {} vs {want}",
            slow[2000]
        );
    }

    #[test]
    fn thermal_steady_state_is_i_squared() {
        let (tau, dt) = (0.2f32, 1e-3f32);
        for i_a in [0.5f32, -1.0, 2.0] {
            // Starts cold (zero current), then a constant current.
            let th = run(
                Term::new(EffectKind::Thermal { tau_s: tau }, 0),
                (0..4000).map(|k| if k == 0 { 0.0 } else { i_a }),
                dt,
            );
            let last = th[th.len() - 1];
            assert!(
                (last - i_a * i_a).abs() < 1e-5 * i_a * i_a,
                "i={i_a}: {last}"
            );
            // One time constant in: 63 %.
            let at_tau = th[(tau / dt + 0.5) as usize];
            assert!((at_tau / (i_a * i_a) - (1.0 - math::exp(-1.0))).abs() < 1e-4);
        }
    }

    #[test]
    fn smooth_sign_and_stribeck_shapes() {
        let c = Term::new(EffectKind::SmoothSign { v_eps: 0.01 }, 0);
        let s = Term::new(
            EffectKind::Stribeck {
                v_s: 0.1,
                v_eps: 0.001,
            },
            0,
        );
        let mut st = TermState::default();
        for k in -200..=200 {
            let v = k as f32 * 1e-3;
            let (p, n) = (
                c.update(&mut st, &[v], 1e-3),
                c.update(&mut st, &[-v], 1e-3),
            );
            assert_eq!(p, -n, "odd at v={v}");
            assert!(p.abs() <= 1.0, "bounded");
            let (sp, sn) = (
                s.update(&mut st, &[v], 1e-3),
                s.update(&mut st, &[-v], 1e-3),
            );
            assert_eq!(sp, -sn, "stribeck odd at v={v}");
        }
        assert!(
            (c.update(&mut st, &[0.1], 0.0) - 1.0).abs() < 1e-6,
            "saturates at 10 v_eps"
        );
        assert!(
            (c.update(&mut st, &[0.001], 0.0) - 0.1).abs() < 1e-3,
            "linear below v_eps"
        );
        // Stribeck: ~1 just above v_eps, exp(-1) at v_s, ~0 far above.
        assert!((s.update(&mut st, &[0.005], 0.0) - 1.0).abs() < 0.01);
        assert!((s.update(&mut st, &[0.1], 0.0) - math::exp(-1.0)).abs() < 1e-5);
        assert!(s.update(&mut st, &[0.4], 0.0).abs() < 1e-6);
    }

    #[test]
    fn dahl_saturates_in_large_motion_and_is_rate_independent() {
        let l = 0.01f32;
        let t = Term::new(EffectKind::Dahl { length: l }, 0);
        let z = run(t, triangle(1.0, 500, 2), 1e-3);
        // At the top of a stroke (200 L of travel): +1; at the bottom -1.
        assert!((z[1500] - 1.0).abs() < 1e-6, "top {}", z[1500]);
        assert!((z[2000] + 1.0).abs() < 1e-6, "bottom {}", z[2000]);
        // After a reversal from +1, moving back by d: z = 1 - 2 (1 - exp(-d/L)).
        let d = 2.0 * 10.0 / 500.0; // 10 samples of a 2/500 slope
        let want = 1.0 - 2.0 * (1.0 - math::exp(-d / l));
        assert!(
            (z[1510] - want).abs() < 1e-5,
            "after reversal {} vs {want}",
            z[1510]
        );
        // Same path at a tenth of the sample density -> same z at the same x.
        let z2 = run(t, triangle(1.0, 50, 2), 1e-3);
        assert!((z2[151] - z[1510]).abs() < 1e-5, "rate independent");
        // Bounded everywhere.
        assert!(z.iter().all(|v| v.abs() <= 1.0));
    }

    /// Bouc–Wen with `shape = 1`, `n = 1` is the Dahl state; it saturates,
    /// is rate independent, unloads elastically with `shape = 0` and turns
    /// its knee sharper with a larger exponent.
    #[test]
    fn bouc_wen_is_dahl_at_its_corner_and_shapes_the_loop_elsewhere() {
        let l = 0.01f32;
        let bw = |shape: f32, exponent: u8| {
            Term::new(
                EffectKind::BoucWen {
                    length: l,
                    shape,
                    exponent,
                },
                0,
            )
        };
        let dahl = run(
            Term::new(EffectKind::Dahl { length: l }, 0),
            triangle(1.0, 500, 2),
            1e-3,
        );
        let corner = run(bw(1.0, 1), triangle(1.0, 500, 2), 1e-3);
        let worst = dahl
            .iter()
            .zip(&corner)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        assert!(worst < 5e-4, "Dahl against Bouc-Wen(1, 1): {worst}");
        // Saturated at the ends of a stroke, bounded everywhere.
        let elastic = run(bw(0.0, 2), triangle(1.0, 500, 2), 1e-3);
        assert!((elastic[1500] - 1.0).abs() < 1e-4 && (elastic[2000] + 1.0).abs() < 1e-4);
        assert!(elastic.iter().all(|v| v.abs() <= 1.0));
        // Rate independent: half the samples on the same path (steps of
        // 0.8 L).
        let coarse = run(bw(0.0, 2), triangle(1.0, 250, 2), 1e-3);
        assert!(
            (coarse[755] - elastic[1510]).abs() < 1e-3,
            "rate independent: {} against {}",
            coarse[755],
            elastic[1510]
        );
        // A step of a hundred lengths in one sample saturates the state.
        let leap = run(bw(0.5, 3), [0.0, 100.0 * l], 1e-3);
        assert!((leap[1] - 1.0).abs() < 1e-6, "{}", leap[1]);
        // Shape 0 unloads at slope 1/L: half a length back from +1 is 0.5.
        let back = [0.0, 1.0, 1.0 - 0.5 * l];
        let z = run(bw(0.0, 3), back, 1e-3);
        assert!((z[2] - 0.5).abs() < 1e-4, "elastic unloading {}", z[2]);
        // A larger exponent keeps the slope near 1/L longer: from rest,
        // one length of travel builds more of the state.
        let one = run(bw(0.0, 1), [0.0, l], 1e-3);
        let four = run(bw(0.0, 4), [0.0, l], 1e-3);
        assert!(
            (one[1] - (1.0 - math::exp(-1.0))).abs() < 1e-3,
            "{}",
            one[1]
        );
        assert!(four[1] > one[1] + 0.1, "{} vs {}", four[1], one[1]);
        // Out of range: the shape, the exponent.
        for bad in [bw(-0.5, 1), bw(1.5, 1), bw(0.0, 0), bw(0.0, 9)] {
            assert!(bad.validate(0, 1).is_err(), "{bad}");
        }
    }

    #[test]
    fn deadzone_polynomials_product_time() {
        let dz = Term::new(
            EffectKind::DeadZone {
                center: 0.5,
                half_width: 0.25,
            },
            0,
        );
        let mut st = TermState::default();
        for (u, want) in [
            (0.5, 0.0),
            (0.7, 0.0),
            (1.0, 0.25),
            (0.0, -0.25),
            (0.3, 0.0),
        ] {
            assert!(
                (dz.update(&mut st, &[u], 1e-3) - want).abs() < 1e-6,
                "deadzone({u})"
            );
        }
        let ss = Term::new(EffectKind::SignedSquare, 0);
        assert_eq!(ss.update(&mut st, &[-3.0], 0.0), -9.0);
        assert_eq!(
            Term::new(EffectKind::Cube, 0).update(&mut st, &[-2.0], 0.0),
            -8.0
        );
        assert_eq!(
            Term::product(0, 1).update(&mut st, &[3.0, -4.0], 0.0),
            -12.0
        );
        // Time: 0 at the first sample, then the sum of dt, in hours.
        let tt = run(
            Term::new(EffectKind::Time { scale_s: 3600.0 }, 0),
            core::iter::repeat_n(0.0, 3601),
            1.0,
        );
        assert_eq!(tt[0], 0.0);
        assert!((tt[3600] - 1.0).abs() < 1e-6);
        // Warm-up: 1 - exp(-t/tau).
        let wu = run(
            Term::new(EffectKind::Warmup { tau_s: 10.0 }, 0),
            core::iter::repeat_n(0.0, 11),
            1.0,
        );
        assert!(
            (wu[10] - (1.0 - math::exp(-1.0))).abs() < 1e-6,
            "warmup {}",
            wu[10]
        );
        // NaN input: NaN out, state kept.
        let r = Term::new(EffectKind::Relaxation { tau_s: 1.0 }, 0);
        let mut st = TermState::default();
        r.update(&mut st, &[2.0], 0.1);
        assert!(r.update(&mut st, &[f32::NAN], 0.1).is_nan());
        assert_eq!(r.update(&mut st, &[2.0], 0.1), 2.0);
    }

    #[test]
    fn load_friction_scales_with_the_load() {
        // load_coulomb = |load| x coulomb, load_dahl = |load| x dahl, sample
        // by sample, whatever the sign of the load.
        let (ve, l) = (0.01f32, 0.05f32);
        let lc = Term::with_aux(EffectKind::LoadCoulomb { v_eps: ve }, 0, 1);
        let c = Term::new(EffectKind::SmoothSign { v_eps: ve }, 0);
        let ld = Term::with_aux(EffectKind::LoadDahl { length: l }, 0, 1);
        let d = Term::new(EffectKind::Dahl { length: l }, 0);
        let (mut s1, mut s2, mut s3, mut s4) = Default::default();
        let u: heapless::Vec<f32, 1024> = triangle(1.0, 100, 3).collect();
        for (k, &x) in u.iter().enumerate() {
            let load = 2.0 * libm::sinf(k as f32 * 0.03) - 0.5;
            let v = if k > 0 { (x - u[k - 1]) * 100.0 } else { 0.0 };
            let got = lc.update(&mut s1, &[v, load], 1e-2);
            let want = libm::fabsf(load) * c.update(&mut s2, &[v, 0.0], 1e-2);
            assert!(
                (got - want).abs() < 1e-6,
                "load_coulomb at {k}: {got} vs {want}"
            );
            let got = ld.update(&mut s3, &[x, load], 1e-2);
            let want = libm::fabsf(load) * d.update(&mut s4, &[x, 0.0], 1e-2);
            assert!(
                (got - want).abs() < 1e-6,
                "load_dahl at {k}: {got} vs {want}"
            );
        }
        // Reads the load: validated against the signal count, NaN load gives
        // NaN and leaves the Dahl state as it was.
        assert_eq!(
            ld.validate(0, 1),
            Err(EffectError::InputOutOfRange {
                term: 0,
                index: 1,
                n_signals: 1
            })
        );
        let before = s3;
        assert!(ld.update(&mut s3, &[0.3, f32::NAN], 1e-2).is_nan());
        assert_eq!(s3, before, "state untouched by a NaN load");
        assert_eq!(
            Term::with_aux(EffectKind::LoadCoulomb { v_eps: 0.0 }, 0, 1).validate(0, 2),
            Err(EffectError::BadParameter {
                term: 0,
                name: "v_eps"
            })
        );
    }

    #[test]
    fn bank_validates_and_computes() {
        let terms = [
            Term::CONSTANT,
            Term::new(EffectKind::Linear, 1),
            Term::product(0, 1),
            Term::new(EffectKind::Creep { tau_s: 1.0 }, 0),
        ];
        assert_eq!(
            EffectBank::<4>::new(&terms, 1),
            Err(EffectError::InputOutOfRange {
                term: 1,
                index: 1,
                n_signals: 1
            })
        );
        assert_eq!(
            EffectBank::<3>::new(&terms, 2),
            Err(EffectError::TooManyTerms {
                given: 4,
                capacity: 3
            })
        );
        let bad = [Term::new(EffectKind::Dahl { length: 0.0 }, 0)];
        assert_eq!(
            EffectBank::<4>::new(&bad, 2),
            Err(EffectError::BadParameter {
                term: 0,
                name: "length"
            })
        );
        let mut bank = EffectBank::<6>::new(&terms, 2).unwrap();
        let mut out = [0.0; 6];
        assert_eq!(bank.update(&[2.0, 3.0], 0.01, &mut out), 4);
        assert_eq!(&out[..4], &[1.0, 3.0, 6.0, 0.0]);
        bank.update(&[4.0, 3.0], 0.01, &mut out);
        assert!(
            out[3] > 1.9 && out[3] < 2.0,
            "creep after a step of 2: {}",
            out[3]
        );
        // Short inputs read 0 instead of panicking; short outputs get a prefix.
        let mut short = [0.0; 2];
        assert_eq!(bank.update(&[], 0.01, &mut short), 2);
        assert_eq!(short, [1.0, 0.0]);
        bank.reset();
        bank.update(&[4.0, 3.0], 0.01, &mut out);
        assert_eq!(out[3], 0.0, "reset re-initialises the creep filter");
    }
}
