//! report.json: the flat figure map (`figures`, built from the typed keys of
//! [`super::keys`]) and the JSON around it; and the number format every
//! table of the report shares.

use std::collections::BTreeMap;

use serde_json::{json, Value};

use super::goals::{goal_status, GOALS};
use super::keys::{variants, Figure};
use super::programme::{Evaluation, Identification};
use super::seed::Row;
use super::Report;

/// Every figure of the report under a stable key: each [`Figure`] a
/// variant has under that variant's prefix (`clean.`,
/// `effects_seed_model.`, `effects_residual.`), and `runtime_s`.
pub fn figure_map(r: &Report) -> BTreeMap<String, f64> {
    let figures = Figure::all();
    let mut map = BTreeMap::new();
    for v in variants(r) {
        for f in &figures {
            if let Some(x) = f.value(&v) {
                map.insert(format!("{}.{}", v.prefix, f.key()), x);
            }
        }
    }
    map.insert("runtime_s".into(), r.runtime_s);
    map
}

/// A number for a table: `n/a` when not finite; an integer below 1e5
/// without decimals; otherwise in scientific notation with four decimals
/// outside [1e-3, 1e5), with two decimals from 10, with four below 10.
pub fn fmt_num(v: f64) -> String {
    if !v.is_finite() {
        return "n/a".into();
    }
    let a = v.abs();
    if v.fract() == 0.0 && a < 1e5 {
        format!("{v:.0}")
    } else if !(1e-3..1e5).contains(&a) {
        format!("{v:.4e}")
    } else if a >= 10.0 {
        format!("{v:.2}")
    } else {
        format!("{v:.4}")
    }
}

/// Text for a Markdown table cell (`|` escaped).
pub fn cell(s: &str) -> String {
    s.replace('|', "\\|")
}

/// Steps 1, 2 and 5 of one identifying variant.
fn ident_json(id: &Identification) -> Value {
    json!({
        "bm": id.bm,
        "bm_verification": id.bm_validation,
        "jae": id.jae,
        "tension": id.tension,
        "tension_verification": id.tension_validation.iter()
            .map(|(n, e)| json!({"model": n, "errors": e})).collect::<Vec<_>>(),
        "faults": id.faults,
    })
}

/// Step 6's cases and summaries of one variant, and the tracking runs'
/// faults.
fn eval_json(ev: &Evaluation) -> Value {
    json!({
        "loading_summary": ev.loading_summary,
        "loading_cases": ev.loading,
        "loading_stretch_summary": ev.loading_stretch_summary,
        "loading_stretch_cases": ev.loading_stretch,
        "faults": [
            ev.track_motor.fault, ev.track_jae.fault, ev.robust.fault,
        ],
    })
}

/// The goals with their status for every variant.
fn goals_json(r: &Report) -> Vec<Value> {
    let vs = variants(r);
    GOALS
        .iter()
        .map(|g| {
            let mut j = json!({
                "goal": g.goal,
                "key": g.figure.key(),
                "limit": g.limit,
                "at_least": g.at_least,
            });
            for v in &vs {
                j[v.prefix] = match goal_status(v, g) {
                    Some((x, ok)) => json!({"value": x, "met": ok}),
                    None => Value::Null,
                };
            }
            j
        })
        .collect()
}

/// The comparison with the seed, one object per row.
fn comparison_json(rows: &[Row]) -> Vec<Value> {
    rows.iter()
        .map(|row| {
            json!({
                "key": format!("clean.{}", row.seed.figure.key()),
                "quantity": row.seed.quantity,
                "unit": row.seed.unit,
                "seed": row.seed.value,
                "ours": row.ours,
                "ratio": row.ratio(),
                "verdict": row.verdict(),
                "source": row.seed.source,
                "note": row.note,
            })
        })
        .collect()
}

/// report.json.
pub fn json(r: &Report, map: &BTreeMap<String, f64>, rows: &[Row]) -> Value {
    let mut out = json!({
        "force_variants": serde_json::to_value(&r.variants).unwrap_or(Value::Null),
        "excitation": match &r.excitation {
            Ok(x) => serde_json::to_value(x).unwrap_or(Value::Null),
            Err(e) => json!({"error": e}),
        },
        "wrist": match &r.wrist {
            Ok(x) => serde_json::to_value(x).unwrap_or(Value::Null),
            Err(e) => json!({"error": e}),
        },
        "free_motion": match &r.free_motion {
            Ok(x) => serde_json::to_value(x).unwrap_or(Value::Null),
            Err(e) => json!({"error": e}),
        },
        "grip": match &r.grip {
            Ok(x) => serde_json::to_value(x).unwrap_or(Value::Null),
            Err(e) => json!({"error": e}),
        },
        "schema": 1,
        "seed": r.options.seed,
        "duration_scale": r.options.duration_scale,
        "runtime_s": r.runtime_s,
        "figures": map,
        "seed_comparison": comparison_json(rows),
        "goals": goals_json(r),
        "identification": {"clean": ident_json(&r.clean.0)},
        "evaluation": {"clean": eval_json(&r.clean.1)},
        "plots": r.figures.iter().map(|w| json!({"stem": w.stem, "caption": w.caption})).collect::<Vec<_>>(),
    });
    if let Some(fx) = &r.effects {
        out["effects"] = json!(fx.names);
        out["identification"]["effects"] = ident_json(&fx.id);
        out["evaluation"]["effects_seed_model"] = eval_json(&fx.before);
        out["evaluation"]["effects_residual"] = eval_json(&fx.after);
        out["residual"] = json!({
            "jae": crate::residual::report::json(&fx.residual.jae),
            "tension": crate::residual::report::json(&fx.residual.tension),
        });
    }
    out
}
