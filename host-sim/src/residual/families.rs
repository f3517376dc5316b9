//! Effect terms by physical family: their names with signal names, their
//! family, and their columns over a run.

use cable_joint::effects::{EffectKind, StrokePart, Term, TermState};
use cable_joint::filter::LowPass1;

use crate::derive::low_pass_column;

/// Signal kinds, from the unit suffix of the signal's name.
fn is_velocity(name: &str) -> bool {
    name.contains("_vel") || name.ends_with("_m_s") || name.ends_with("_rad_s")
}

fn is_load(name: &str) -> bool {
    name.ends_with("_a") || name.ends_with("_n") || name.ends_with("_nm")
}

/// Does `t` read a signal of `other` (as its input or its second signal)?
pub fn reads_other_sensor(t: &Term, other: &[u8]) -> bool {
    (t.kind.uses_input() && other.contains(&t.input))
        || (t.kind.uses_aux() && other.contains(&t.aux))
}

/// The physical family of a term: `drift`, `stiffness` (a static function
/// of a position), `friction` (of a velocity), `hysteresis`, `creep /
/// relaxation`, `thermal`, `load` (a function of a current or force), or
/// `fusion: <signal>` when it reads a sensor the model does not (see
/// [`Problem::other_sensors`](super::Problem::other_sensors)).
pub fn effect_class(t: &Term, names: &[String], other: &[u8]) -> String {
    if reads_other_sensor(t, other) {
        let i = if t.kind.uses_input() && other.contains(&t.input) {
            t.input
        } else {
            t.aux
        };
        let name = names.get(i as usize).map_or("?", String::as_str);
        return format!("fusion: {name}");
    }
    let input = names.get(t.input as usize).map_or("", String::as_str);
    let static_of_input = if is_velocity(input) {
        "friction"
    } else if is_load(input) {
        "load"
    } else {
        "stiffness"
    };
    match t.kind {
        EffectKind::Constant | EffectKind::Time { .. } | EffectKind::Warmup { .. } => "drift",
        EffectKind::Linear
        | EffectKind::SignedSquare
        | EffectKind::Cube
        | EffectKind::DeadZone { .. } => static_of_input,
        EffectKind::SmoothSign { .. }
        | EffectKind::Stribeck { .. }
        | EffectKind::LoadCoulomb { .. } => "friction",
        EffectKind::Play { .. }
        | EffectKind::Stop { .. }
        | EffectKind::Dahl { .. }
        | EffectKind::BoucWen { .. }
        | EffectKind::LoadDahl { .. }
        | EffectKind::LoadMemory { .. }
        | EffectKind::StrokeHold { .. } => "hysteresis",
        EffectKind::Relaxation { .. } | EffectKind::Creep { .. } => "creep / relaxation",
        EffectKind::Thermal { .. } => "thermal",
        EffectKind::Product => "load",
    }
    .to_string()
}

/// A signal's name, `#i` when it has none.
fn signal_name(names: &[String], i: u8) -> String {
    names
        .get(i as usize)
        .cloned()
        .unwrap_or_else(|| format!("#{i}"))
}

/// What a `stroke_load` part holds, with signal names: `u`, `u*sgn(v)` or
/// `sgn(v)`.
fn stroke_held(t: &Term, part: StrokePart, names: &[String]) -> String {
    let sig = |i: u8| signal_name(names, i);
    match part {
        StrokePart::Level => sig(t.input),
        StrokePart::Signed => format!("{}*sgn({})", sig(t.input), sig(t.aux)),
        StrokePart::Direction => format!("sgn({})", sig(t.aux)),
    }
}

/// The label of parts taken together as one effect
/// ([`effect_groups`](super::library::effect_groups)): for a `stroke_load`
/// every part's held signal in one bracket,
/// `stroke_load[u; u*sgn(v); sgn(v)](vmin=..,tau=..)`; otherwise the first
/// part's label.
pub fn group_label(parts: &[Term], names: &[String]) -> String {
    let Some(first) = parts.first() else {
        return String::new();
    };
    match first.kind {
        EffectKind::StrokeHold { v_min, tau_s, .. } => {
            let held: Vec<String> = parts
                .iter()
                .filter_map(|t| match t.kind {
                    EffectKind::StrokeHold { part, .. } => Some(stroke_held(t, part, names)),
                    _ => None,
                })
                .collect();
            format!(
                "{}[{}](vmin={v_min:.3e},tau={tau_s:.4}s)",
                first.name(),
                held.join("; ")
            )
        }
        _ => term_label(first, names),
    }
}

/// A term's name with signal names in place of indices.
pub fn term_label(t: &Term, names: &[String]) -> String {
    let sig = |i: u8| signal_name(names, i);
    let n = t.name();
    match t.kind {
        EffectKind::Constant => n.to_owned(),
        EffectKind::Time { scale_s } => format!("{n}(per {scale_s}s)"),
        EffectKind::Warmup { tau_s } => format!("{n}(tau={tau_s:.4}s)"),
        EffectKind::Linear | EffectKind::SignedSquare | EffectKind::Cube => {
            format!("{n}[{}]", sig(t.input))
        }
        EffectKind::Product => format!("{n}[{}*{}]", sig(t.input), sig(t.aux)),
        EffectKind::SmoothSign { v_eps } => format!("{n}[{}](eps={v_eps:.3e})", sig(t.input)),
        EffectKind::Stribeck { v_s, v_eps } => {
            format!("{n}[{}](vs={v_s:.3e},eps={v_eps:.3e})", sig(t.input))
        }
        EffectKind::Play { half_width } | EffectKind::Stop { half_width } => {
            format!("{n}[{}](w={half_width:.3e})", sig(t.input))
        }
        EffectKind::Dahl { length } => format!("{n}[{}](L={length:.3e})", sig(t.input)),
        EffectKind::BoucWen {
            length,
            shape,
            exponent,
        } => format!(
            "{n}[{}](L={length:.3e},shape={shape},n={exponent})",
            sig(t.input)
        ),
        EffectKind::LoadCoulomb { v_eps } => {
            format!("{n}[{}*|{}|](eps={v_eps:.3e})", sig(t.input), sig(t.aux))
        }
        EffectKind::LoadDahl { length } => {
            format!("{n}[{}*|{}|](L={length:.3e})", sig(t.input), sig(t.aux))
        }
        EffectKind::DeadZone { center, half_width } => {
            format!("{n}[{}](c={center:.3e},w={half_width:.3e})", sig(t.input))
        }
        EffectKind::Relaxation { tau_s }
        | EffectKind::Creep { tau_s }
        | EffectKind::Thermal { tau_s }
        | EffectKind::LoadMemory { tau_s } => format!("{n}[{}](tau={tau_s:.4}s)", sig(t.input)),
        EffectKind::StrokeHold { v_min, tau_s, part } => {
            let held = stroke_held(t, part, names);
            format!("{n}[{held}](vmin={v_min:.3e},tau={tau_s:.4}s)")
        }
    }
}

/// Compute a term's column over a whole run (every sample, from its start),
/// then pass it through `prefilter` if given.
pub fn term_column(
    term: &Term,
    signals: &[Vec<f32>],
    t_s: &[f64],
    dt_s: Option<f32>,
    prefilter: Option<LowPass1>,
) -> Vec<f64> {
    let n = t_s.len();
    let mut st = TermState::default();
    let mut row = vec![0.0f32; signals.len()];
    let mut out = Vec::with_capacity(n);
    for k in 0..n {
        for (r, s) in row.iter_mut().zip(signals) {
            *r = s.get(k).copied().unwrap_or(f32::NAN);
        }
        let dt = match dt_s {
            Some(d) => d,
            None if k > 0 => (t_s[k] - t_s[k - 1]) as f32,
            None => 0.0,
        };
        out.push(term.update(&mut st, &row, dt));
    }
    match prefilter {
        Some(lp) => low_pass_column(lp, &out),
        None => out.into_iter().map(f64::from).collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn effect_families_follow_the_kind_and_the_signal_and_other_sensors_are_fusion() {
        let names: Vec<String> = ["x2_m", "x2_vel_m_s", "i_ref_a", "theta_motor_rad"]
            .map(String::from)
            .to_vec();
        let other = [3u8];
        let class = |t: Term| effect_class(&t, &names, &other);
        assert_eq!(class(Term::new(EffectKind::Linear, 0)), "stiffness");
        assert_eq!(class(Term::new(EffectKind::Cube, 0)), "stiffness");
        assert_eq!(class(Term::new(EffectKind::Linear, 1)), "friction");
        assert_eq!(class(Term::new(EffectKind::Linear, 2)), "load");
        assert_eq!(
            class(Term::new(EffectKind::Stop { half_width: 0.1 }, 0)),
            "hysteresis"
        );
        assert_eq!(
            class(Term::new(EffectKind::Creep { tau_s: 1.0 }, 0)),
            "creep / relaxation"
        );
        assert_eq!(
            class(Term::new(EffectKind::Thermal { tau_s: 1.0 }, 2)),
            "thermal"
        );
        assert_eq!(
            class(Term::new(EffectKind::Time { scale_s: 1.0 }, 0)),
            "drift"
        );
        assert_eq!(
            class(Term::new(EffectKind::Linear, 3)),
            "fusion: theta_motor_rad"
        );
    }
}
