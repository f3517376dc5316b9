//! The standard candidate effect terms for a log (host-side: the firmware
//! only evaluates the terms the residual loop chose, `cable_joint::model`).
//! Widths and time constants are computed in `f32` through the core's
//! `math` module, as the core computes its terms.

use cable_joint::effects::{EffectKind, StrokePart, Term};
use cable_joint::math;

/// Lengths (half-widths) of the hysteresis candidates (`stop`, `dahl`,
/// `bouc_wen`, `load_dahl`) as fractions of the input's span.
const HYSTERESIS_SPAN_FRACTIONS: [f32; 3] = [0.005, 0.02, 0.08];

/// Unloading shape of the library's Bouc–Wen candidates: 0, elastic
/// unloading (a cable's stretch relaxes before the friction reverses; the
/// Dahl state, shape 1, is a candidate of its own). Chosen from that
/// physics before any fit was run with it.
pub const BOUC_WEN_SHAPE: f32 = 0.0;

/// Exponent of the library's Bouc–Wen candidates: 2, a knee between the
/// Dahl state's (1) and the stop operator's corner.
pub const BOUC_WEN_EXPONENT: u8 = 2;

/// A signal of the log for the [`candidate_library`]: its index and the range
/// it covers in the data at hand.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SignalRange {
    /// Index in the per-sample slice.
    pub index: u8,
    /// Smallest value in the log.
    pub min: f32,
    /// Largest value in the log.
    pub max: f32,
}

impl SignalRange {
    fn span(&self) -> Option<f32> {
        let s = self.max - self.min;
        (s > 0.0 && s.is_finite()).then_some(s)
    }

    fn magnitude(&self) -> f32 {
        let (a, b) = (math::abs(self.min), math::abs(self.max));
        if a > b {
            a
        } else {
            b
        }
    }
}

/// What the [`candidate_library`] knows about a log.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LibrarySpec {
    /// A position signal (e.g. `x2_m`), or none.
    pub position: Option<SignalRange>,
    /// A velocity signal (e.g. the differentiated `x2`), or none.
    pub velocity: Option<SignalRange>,
    /// A motor current signal (`i_ref_a` / `i_meas_a`), or none.
    pub current: Option<SignalRange>,
    /// A load signal (tension or force), or none.
    pub load: Option<SignalRange>,
    /// Sample period, s.
    pub sample_period_s: f32,
    /// Length of the log, s.
    pub duration_s: f32,
}

/// A stroke ([`EffectKind::StrokeHold`]) is a motion faster than this share
/// of the log's largest speed: slow enough to count most of a sine's
/// stroke, fast enough that encoder noise at rest does not.
pub const STROKE_SPEED_SHARE: f32 = 0.05;

/// The standard candidate set for a log, with widths scaled to each signal's
/// range and time constants spread between the sample rate and the log length:
///
/// * always: `const`, `time` (per hour), `warmup` at three time constants;
/// * position: linear, `sqr_sign`, `cube`, `stop`, `dahl` and `bouc_wen`
///   (elastic unloading, exponent 2: [`BOUC_WEN_SHAPE`],
///   [`BOUC_WEN_EXPONENT`]) at 0.5/2/8 % of the span, `deadzone` at 1/5 % of the span (centred on 0 when the range
///   holds 0, else mid-range), `creep` at three time constants;
/// * velocity: linear (viscous), `coulomb` at 0.5/2 % and `stribeck` at 5/20 %
///   of the largest speed;
/// * current: linear, `thermal` at three time constants;
/// * load: linear, `load x position`, `load^2`, `creep` at three time constants;
///   with a velocity, `load_coulomb` at the `coulomb` widths and the
///   `stroke_load` parts (load, load x direction, direction) at the three
///   time constants; with a position, `load_dahl` at the `dahl` lengths.
///
/// Time constants are `tau_lo = max(20 dt, T/100)`, `tau_hi = T/3` and their
/// geometric mean. `play` and `relax` are left out because with the linear
/// term present they span the same space as `stop` and `creep`. Signals with
/// an empty range are skipped.
pub fn candidate_library(spec: &LibrarySpec) -> Vec<Term> {
    let mut v = Vec::new();
    let mut add = |t: Term| v.push(t);
    let dt = if spec.sample_period_s > 0.0 {
        spec.sample_period_s
    } else {
        1e-3
    };
    let t_total = if spec.duration_s > dt {
        spec.duration_s
    } else {
        dt
    };
    let lo = (20.0 * dt).max(t_total / 100.0);
    let hi = (t_total / 3.0).max(lo);
    let taus = [lo, math::sqrt(lo * hi), hi];

    add(Term::CONSTANT);
    add(Term::new(EffectKind::Time { scale_s: 3600.0 }, 0));
    for tau_s in taus {
        add(Term::new(EffectKind::Warmup { tau_s }, 0));
    }
    let pos = spec.position.filter(|s| s.span().is_some());
    if let Some(p) = pos {
        let (i, span) = (p.index, p.span().unwrap_or(1.0));
        add(Term::new(EffectKind::Linear, i));
        add(Term::new(EffectKind::SignedSquare, i));
        add(Term::new(EffectKind::Cube, i));
        for f in HYSTERESIS_SPAN_FRACTIONS {
            add(Term::new(
                EffectKind::Stop {
                    half_width: f * span,
                },
                i,
            ));
        }
        for f in HYSTERESIS_SPAN_FRACTIONS {
            add(Term::new(EffectKind::Dahl { length: f * span }, i));
        }
        for f in HYSTERESIS_SPAN_FRACTIONS {
            add(Term::new(
                EffectKind::BoucWen {
                    length: f * span,
                    shape: BOUC_WEN_SHAPE,
                    exponent: BOUC_WEN_EXPONENT,
                },
                i,
            ));
        }
        let center = if p.min < 0.0 && p.max > 0.0 {
            0.0
        } else {
            0.5 * (p.min + p.max)
        };
        for f in [0.01, 0.05] {
            let half_width = f * span;
            add(Term::new(EffectKind::DeadZone { center, half_width }, i));
        }
        for tau_s in taus {
            add(Term::new(EffectKind::Creep { tau_s }, i));
        }
    }
    let vel = spec.velocity.filter(|s| s.span().is_some());
    if let Some(s) = vel {
        let (i, m) = (s.index, s.magnitude());
        add(Term::new(EffectKind::Linear, i));
        for f in [0.005, 0.02] {
            add(Term::new(EffectKind::SmoothSign { v_eps: f * m }, i));
        }
        for f in [0.05, 0.2] {
            let kind = EffectKind::Stribeck {
                v_s: f * m,
                v_eps: 0.005 * m,
            };
            add(Term::new(kind, i));
        }
    }
    if let Some(s) = spec.current.filter(|s| s.span().is_some()) {
        add(Term::new(EffectKind::Linear, s.index));
        for tau_s in taus {
            add(Term::new(EffectKind::Thermal { tau_s }, s.index));
        }
    }
    if let Some(s) = spec.load.filter(|s| s.span().is_some()) {
        add(Term::new(EffectKind::Linear, s.index));
        if let Some(p) = pos {
            add(Term::product(s.index, p.index));
        }
        add(Term::product(s.index, s.index));
        for tau_s in taus {
            add(Term::new(EffectKind::Creep { tau_s }, s.index));
        }
        for tau_s in taus {
            add(Term::new(EffectKind::LoadMemory { tau_s }, s.index));
        }
        if let Some(w) = vel {
            for f in [0.005, 0.02] {
                let kind = EffectKind::LoadCoulomb {
                    v_eps: f * w.magnitude(),
                };
                add(Term::with_aux(kind, w.index, s.index));
            }
            let v_min = STROKE_SPEED_SHARE * w.magnitude();
            for tau_s in taus {
                for part in [StrokePart::Level, StrokePart::Signed, StrokePart::Direction] {
                    let kind = EffectKind::StrokeHold { v_min, tau_s, part };
                    add(Term::with_aux(kind, s.index, w.index));
                }
            }
        }
        if let Some(p) = pos {
            let span = p.span().unwrap_or(1.0);
            for f in HYSTERESIS_SPAN_FRACTIONS {
                let kind = EffectKind::LoadDahl { length: f * span };
                add(Term::with_aux(kind, p.index, s.index));
            }
        }
    }
    v
}

/// Candidates that are parts of one effect and are taken together: the
/// three parts of a `stroke_load` (the held load, the load times the
/// direction, the direction) at one speed threshold and time constant. A
/// load that the current carries with a gain and an offset of each stroke's
/// own is `a u + b u sgn(v) + c sgn(v)`; one part alone is no such load
/// estimate, and a forward selection that adds one column at a time may
/// rank each part low (on the MRDLab runs each part alone raised the
/// validation error) while the three together explain most of the
/// residual. Each group is a list of indices into `candidates`, in the
/// order Level, Signed, Direction; parts whose siblings are missing form
/// no group.
pub fn effect_groups(candidates: &[Term]) -> Vec<Vec<usize>> {
    let part_of = |t: &Term| match t.kind {
        EffectKind::StrokeHold { v_min, tau_s, part } => Some((t.input, t.aux, v_min, tau_s, part)),
        _ => None,
    };
    let mut groups = Vec::new();
    for (k, t) in candidates.iter().enumerate() {
        let Some((input, aux, v_min, tau_s, StrokePart::Level)) = part_of(t) else {
            continue;
        };
        let find = |want: StrokePart| {
            candidates
                .iter()
                .position(|c| part_of(c) == Some((input, aux, v_min, tau_s, want)))
        };
        if let (Some(s), Some(d)) = (find(StrokePart::Signed), find(StrokePart::Direction)) {
            groups.push(vec![k, s, d]);
        }
    }
    groups
}

#[cfg(test)]
mod tests {
    use super::*;
    use cable_joint::effects::EffectBank;

    #[test]
    fn library_is_valid_and_scaled() {
        let spec = LibrarySpec {
            position: Some(SignalRange {
                index: 0,
                min: -2e-3,
                max: 6e-3,
            }),
            velocity: Some(SignalRange {
                index: 1,
                min: -0.02,
                max: 0.01,
            }),
            current: Some(SignalRange {
                index: 2,
                min: -1.0,
                max: 1.5,
            }),
            load: Some(SignalRange {
                index: 3,
                min: 10.0,
                max: 30.0,
            }),
            sample_period_s: 5e-4,
            duration_s: 60.0,
        };
        let lib = candidate_library(&spec);
        assert_eq!(lib.len(), 54);
        let bank = EffectBank::<64>::new(&lib, 4);
        assert!(bank.is_ok(), "{:?}", bank.err());
        for t in &lib {
            match t.kind {
                EffectKind::Stop { half_width } => {
                    assert!((0.005 * 8e-3 * 0.99..=0.08 * 8e-3 * 1.01).contains(&half_width))
                }
                EffectKind::SmoothSign { v_eps } | EffectKind::LoadCoulomb { v_eps } => {
                    assert!(v_eps <= 0.02 * 0.02 * 1.001)
                }
                EffectKind::LoadDahl { length } => {
                    assert!((0.005 * 8e-3 * 0.99..=0.08 * 8e-3 * 1.01).contains(&length));
                    assert_eq!((t.input, t.aux), (0, 3), "position x load");
                }
                EffectKind::BoucWen {
                    length,
                    shape,
                    exponent,
                } => {
                    assert!((0.005 * 8e-3 * 0.99..=0.08 * 8e-3 * 1.01).contains(&length));
                    assert_eq!((shape, exponent), (BOUC_WEN_SHAPE, BOUC_WEN_EXPONENT));
                    assert_eq!(t.input, 0, "of the position");
                }
                EffectKind::Creep { tau_s } | EffectKind::Thermal { tau_s } => {
                    assert!((0.6 * 0.99..=20.0 * 1.01).contains(&tau_s), "tau {tau_s}")
                }
                EffectKind::DeadZone { center, .. } => assert_eq!(center, 0.0),
                EffectKind::StrokeHold { v_min, tau_s, .. } => {
                    assert_eq!((t.input, t.aux), (3, 1), "load held by velocity");
                    assert!((v_min - STROKE_SPEED_SHARE * 0.02).abs() < 1e-9);
                    assert!((0.6 * 0.99..=20.0 * 1.01).contains(&tau_s), "tau {tau_s}")
                }
                _ => {}
            }
            assert!(!t.name().is_empty() && t.meaning().len() > 10);
        }
        // A signal without range is skipped; no signal at all leaves the
        // time terms.
        let empty = LibrarySpec {
            position: None,
            velocity: None,
            current: None,
            load: Some(SignalRange {
                index: 0,
                min: 1.0,
                max: 1.0,
            }),
            ..spec
        };
        assert_eq!(candidate_library(&empty).len(), 5);
    }

    /// The three parts of each `stroke_load` form one group, in the order
    /// level, signed, direction, at their own time constant; nothing else
    /// is grouped, and a part without its siblings forms no group.
    #[test]
    fn the_parts_of_a_stroke_load_are_grouped_and_nothing_else() {
        let mut lib = vec![
            Term::new(EffectKind::Linear, 0),
            Term::new(EffectKind::Cube, 0),
        ];
        for tau_s in [0.5, 2.0] {
            for part in [StrokePart::Direction, StrokePart::Level, StrokePart::Signed] {
                let kind = EffectKind::StrokeHold {
                    v_min: 0.1,
                    tau_s,
                    part,
                };
                lib.push(Term::with_aux(kind, 3, 1));
            }
        }
        let groups = effect_groups(&lib);
        assert_eq!(groups, vec![vec![3, 4, 2], vec![6, 7, 5]]);
        // Without its direction part the first is no group.
        lib.remove(2);
        assert_eq!(effect_groups(&lib), vec![vec![5, 6, 4]]);
    }
}
