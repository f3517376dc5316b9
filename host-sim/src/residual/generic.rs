//! Generic models (`--target COLUMN --inputs ...`): any log's columns as
//! the signals, the effect terms on them.

use anyhow::{ensure, Context, Result};
use cable_joint::filter::TrackingObserver;
use cable_joint::Config;

use super::problem::{f32s, is_reference, warn_unmeasured, NamedLog, BOOKKEEPING};
use super::select::{Problem, RunData};
use crate::derive::median_period_s;
use crate::log::Log;

/// Inputs and derived velocities `(position input, velocity name)` of a
/// generic model.
type GenericCols = (Vec<String>, Vec<(String, String)>);

pub(super) fn generic_columns(
    first: &NamedLog,
    target: &str,
    inputs: &Option<Vec<String>>,
) -> Result<GenericCols> {
    let log = &first.log;
    ensure!(
        log.has(target),
        "{}: no target column {} (columns: {})",
        first.name,
        crate::log::quoted(target),
        column_list(log)
    );
    let inputs: Vec<String> = match inputs {
        Some(v) => v.clone(),
        None => log
            .names()
            .into_iter()
            .filter(|n| *n != target && !BOOKKEEPING.contains(n) && !is_reference(n))
            .map(str::to_owned)
            .collect(),
    };
    ensure!(!inputs.is_empty(), "no input columns");
    ensure!(
        !inputs.iter().any(|i| i == target),
        "the target `{target}` is also an input"
    );
    ensure!(
        inputs.len() + 1 + cable_joint::model::MAX_TERMS <= super::select::MAX_COLUMNS,
        "{} inputs: too many for one fit; name them with --inputs",
        inputs.len()
    );
    let mut vel = Vec::new();
    for i in &inputs {
        let v = if let Some(stem) = i.strip_suffix("_rad") {
            format!("{stem}_vel_rad_s")
        } else if let Some(stem) = i.strip_suffix("_m") {
            format!("{stem}_vel_m_s")
        } else {
            continue;
        };
        if !inputs.contains(&v) {
            vel.push((i.clone(), v));
        }
    }
    Ok((inputs, vel))
}

pub(super) fn generic_run(
    nl: &NamedLog,
    target: &str,
    inputs: &[String],
    velocities: &[(String, String)],
    config: &Config,
    problem: &mut Problem,
) -> Result<RunData> {
    let log = &nl.log;
    let t_s = log.time_s()?.to_vec();
    let n = t_s.len();
    let period = median_period_s(&t_s).context("log too short")? as f32;
    let col = |name: &str| -> Result<Vec<f64>> {
        log.col(name).map(<[f64]>::to_vec).with_context(|| {
            format!(
                "{}: no column {} (columns: {})",
                nl.name,
                crate::log::quoted(name),
                column_list(log)
            )
        })
    };
    let target_v = col(target)?;
    warn_unmeasured(&nl.name, target, &target_v);
    let mut baseline = Vec::new();
    let mut signals = Vec::new();
    for i in inputs {
        let v = col(i)?;
        warn_unmeasured(&nl.name, i, &v);
        signals.push(f32s(&v));
        baseline.push(v);
    }
    baseline.push(vec![1.0; n]);
    for (pos, _) in velocities {
        let bw = if pos.ends_with("_rad") {
            config.differentiators.motor_bandwidth_hz
        } else {
            config.differentiators.grating_bandwidth_hz
        };
        let obs = TrackingObserver::new(bw, period);
        let x = col(pos)?;
        let mut st = Default::default();
        // A cell not measured holds the last reading (as the core's replay
        // does), so one empty cell does not poison every later velocity.
        let mut held = x.iter().copied().find(|v| v.is_finite()).unwrap_or(0.0);
        obs.reset(&mut st, held as f32);
        signals.push(
            x.iter()
                .map(|v| {
                    if v.is_finite() {
                        held = *v;
                    }
                    obs.update(&mut st, held as f32).vel
                })
                .collect(),
        );
    }
    problem.baseline_names = inputs.iter().cloned().chain(["const".to_owned()]).collect();
    problem.signal_names = inputs
        .iter()
        .cloned()
        .chain(velocities.iter().map(|v| v.1.clone()))
        .collect();
    problem.term_dt_s = None;
    Ok(RunData {
        name: nl.name.clone(),
        t_s,
        target: target_v,
        fixed: vec![0.0; n],
        baseline,
        unfiltered_baseline: Vec::new(),
        signals,
        fit_rows: 0..0,
        val_rows: 0..0,
        test_rows: 0..0,
        source_row: Vec::new(),
    })
}

/// The log's column names for a message, each cut by [`crate::log::quoted`]
/// (a 5 MB header cell never floods the terminal).
fn column_list(log: &Log) -> String {
    log.names()
        .iter()
        .map(|n| crate::log::quoted(n))
        .collect::<Vec<_>>()
        .join(", ")
}
