//! The candidate effect terms of a problem: the core's library on the
//! signals of each role (positions, velocities, currents, loads), less what
//! a model's physics rules out.

use cable_joint::effects::{EffectKind, Term};
use cable_joint::model::sig;

use super::families::reads_other_sensor;
use super::library::{candidate_library, LibrarySpec, SignalRange};
use super::problem::{BuildOptions, ModelKind};
use super::select::{Problem, RunData};

/// Signals by role for the candidate library.
#[derive(Clone, Debug, Default)]
struct Roles {
    position: Vec<u8>,
    velocity: Vec<u8>,
    current: Vec<u8>,
    load: Vec<u8>,
}

/// Per-signal range over the fitting rows of all runs.
fn signal_range(runs: &[RunData], index: u8) -> Option<SignalRange> {
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    for r in runs {
        let s = &r.signals[index as usize];
        for k in r.fit_rows.clone() {
            let v = s[k];
            if v.is_finite() {
                lo = lo.min(v);
                hi = hi.max(v);
            }
        }
    }
    (lo.is_finite() && hi > lo).then_some(SignalRange {
        index,
        min: lo,
        max: hi,
    })
}

/// The union of [`candidate_library`] over the roles' signals (without
/// repeats): each position, velocity and current alone, each load with the
/// first position and the first velocity (for the load x position products
/// and the load-dependent friction).
fn library(roles: &Roles, runs: &[RunData], period_s: f64, duration_s: f64) -> Vec<Term> {
    let base = LibrarySpec {
        position: None,
        velocity: None,
        current: None,
        load: None,
        sample_period_s: period_s as f32,
        duration_s: duration_s as f32,
    };
    let range = |i: u8| signal_range(runs, i);
    let mut specs = vec![base];
    for &p in &roles.position {
        specs.push(LibrarySpec {
            position: range(p),
            ..base
        });
    }
    for &v in &roles.velocity {
        specs.push(LibrarySpec {
            velocity: range(v),
            ..base
        });
    }
    for &c in &roles.current {
        specs.push(LibrarySpec {
            current: range(c),
            ..base
        });
    }
    for &l in &roles.load {
        specs.push(LibrarySpec {
            load: range(l),
            position: roles.position.first().and_then(|&p| range(p)),
            velocity: roles.velocity.first().and_then(|&v| range(v)),
            ..base
        });
    }
    let mut out: Vec<Term> = Vec::new();
    for s in specs {
        for t in candidate_library(&s) {
            if !out.contains(&t) {
                out.push(t);
            }
        }
    }
    out
}

fn duration_s(runs: &[RunData]) -> f64 {
    runs.iter()
        .filter(|r| !r.fit_rows.is_empty())
        .map(|r| r.t_s[r.fit_rows.end - 1] - r.t_s[r.fit_rows.start])
        .fold(0.0, f64::max)
}

/// The problem's sensors the model does not read and its candidate terms
/// (built after its runs, whose signal ranges size the terms).
pub(super) fn offer_candidates(
    kind: &ModelKind,
    problem: &mut Problem,
    period0: f64,
    opts: BuildOptions,
) {
    let roles = roles_of(kind, &problem.signal_names);
    problem.other_sensors = other_sensors_of(kind);
    problem.candidates = candidates(kind, &roles, problem, period0, opts);
}

/// The signals each role's candidates read.
fn roles_of(kind: &ModelKind, signal_names: &[String]) -> Roles {
    match kind {
        ModelKind::Jae => Roles {
            position: vec![sig::X2_M, sig::X1_M, sig::THETA_MOTOR_RAD],
            velocity: vec![sig::X2_VEL_M_S, sig::X1_VEL_M_S, sig::PHI_VEL_RAD_S],
            current: vec![sig::I_REF_A],
            load: vec![sig::I_REF_A],
        },
        ModelKind::Tension => Roles {
            position: vec![sig::X2_M, sig::X1_M],
            velocity: vec![sig::X1_VEL_M_S, sig::X2_VEL_M_S, sig::PHI_VEL_RAD_S],
            current: vec![sig::I_REF_A],
            load: vec![],
        },
        ModelKind::Force => Roles {
            position: vec![sig::X2_M, sig::X1_M],
            velocity: vec![sig::X1_VEL_M_S, sig::X2_VEL_M_S, sig::PHI_VEL_RAD_S],
            current: vec![sig::I_REF_A],
            load: vec![sig::I_REF_A],
        },
        ModelKind::Generic { .. } => generic_roles(signal_names),
    }
}

/// The signals of sensors the model does not read (terms on them are
/// fusion, offered only when asked).
fn other_sensors_of(kind: &ModelKind) -> Vec<u8> {
    // The JAE (Eq. 26) reads slider 2 alone: the motor encoder and grating 1
    // are other sensors for it. The tension and force models read both
    // sliders and the motor's speed; the motor's angle is not in them.
    match kind {
        ModelKind::Jae => vec![
            sig::X1_M,
            sig::X1_VEL_M_S,
            sig::PHI_RAD,
            sig::PHI_VEL_RAD_S,
            sig::THETA_MOTOR_RAD,
        ],
        ModelKind::Tension | ModelKind::Force => vec![sig::PHI_RAD, sig::THETA_MOTOR_RAD],
        ModelKind::Generic { .. } => Vec::new(),
    }
}

/// The candidate effect terms for `kind`: the library on its roles, less
/// what its physics rules out.
fn candidates(
    kind: &ModelKind,
    roles: &Roles,
    problem: &Problem,
    period0: f64,
    opts: BuildOptions,
) -> Vec<Term> {
    let mut lib = library(roles, &problem.runs, period0, duration_s(&problem.runs));
    if !opts.other_sensors {
        lib.retain(|t| !reads_other_sensor(t, &problem.other_sensors));
    }
    if !matches!(kind, ModelKind::Generic { .. }) {
        // The load memory stands for a transmission that self-locks when
        // back-driven, so the current stops carrying the load on one stroke
        // (the da Vinci tool). The prototype's drive is back-drivable (the
        // DOB rests on it): its current carries the load on both strokes.
        // The stroke hold stands for the same drive's efficiency that differs
        // between its strokes.
        lib.retain(|t| {
            !matches!(
                t.kind,
                EffectKind::LoadMemory { .. } | EffectKind::StrokeHold { .. }
            )
        });
    }
    if *kind == ModelKind::Jae {
        // The JAE maps slider 2 to the joint through cable 2 and the return
        // spring: the current reaches it only as a load (cable stretch,
        // load-dependent friction), never through the winding's heat.
        lib.retain(|t| !matches!(t.kind, EffectKind::Thermal { .. }));
    }
    if *kind == ModelKind::Tension {
        // Current only through the winding temperature (see the module doc).
        lib.retain(|t| {
            let reads_current = t.kind.uses_input()
                && (t.input == sig::I_REF_A
                    || (t.kind == EffectKind::Product && t.aux == sig::I_REF_A));
            !reads_current || matches!(t.kind, EffectKind::Thermal { .. })
        });
    }
    lib
}

fn generic_roles(names: &[String]) -> Roles {
    let mut r = Roles::default();
    for (k, n) in names.iter().enumerate() {
        let k = k as u8;
        if n.ends_with("_m_s2") || n.ends_with("_rad_s2") {
            continue;
        } else if n.ends_with("_m_s") || n.ends_with("_rad_s") {
            r.velocity.push(k);
        } else if n.ends_with("_m") || n.ends_with("_rad") {
            r.position.push(k);
        } else if n.ends_with("_a") {
            r.current.push(k);
        } else if n.ends_with("_n") || n.ends_with("_nm") {
            r.load.push(k);
        }
    }
    if r.load.is_empty() {
        r.load = r.current.clone();
    }
    r
}
