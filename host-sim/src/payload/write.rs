//! The files of `--csv` and `--plot`: the per-sample estimates of every
//! run and one figure per run.

use std::path::{Path, PathBuf};

use anyhow::Result;
use cable_joint::payload::AXIS_NAMES;

use super::RunEstimates;
use crate::log::Log;
use crate::output::Outputs;

/// Stage `DIR/payload_<run>.csv` per run among the outputs (see `--csv`).
pub fn write_csv(out: &mut Outputs, runs: &[RunEstimates], dir: &Path) -> Result<Vec<PathBuf>> {
    crate::output::ensure_dir(dir)?;
    let mut names = vec!["t_s".to_owned()];
    for pre in ["raw", "fe_base", "fe_sel"] {
        for (k, a) in AXIS_NAMES.iter().enumerate() {
            names.push(format!("{pre}_{a}_{}", if k < 3 { "n" } else { "nm" }));
        }
    }
    let refs: Vec<&str> = names.iter().map(String::as_str).collect();
    let mut paths = Vec::new();
    for r in runs {
        let mut log = Log::with_columns(&refs)?;
        for (i, t) in r.run.wrench.t_s.iter().enumerate() {
            let mut row = vec![*t];
            row.extend_from_slice(&r.raw[i]);
            row.extend_from_slice(&r.base.tracked[i]);
            row.extend_from_slice(&r.selected.tracked[i]);
            log.push_row(&row)?;
        }
        let path = dir.join(format!("payload_{}.csv", r.run.name));
        log.stage(out, &path)?;
        paths.push(path);
    }
    Ok(paths)
}

/// Stage one figure per run (`DIR/payload_<run>.svg` and `.png`): the six
/// axes of the raw sensor (minus its start) and of the estimated `F_e`.
pub fn plot_runs(out: &mut Outputs, runs: &[RunEstimates], dir: &Path) -> Result<Vec<PathBuf>> {
    use crate::plot::{stage_figure, Figure, Panel, Series};
    crate::output::ensure_dir(dir)?;
    let mut paths = Vec::new();
    for r in runs {
        let t = r.run.wrench.t_s.clone();
        let col = |x: &[[f64; 6]], k: usize| x.iter().map(|v| v[k]).collect::<Vec<f64>>();
        let panels = (0..6)
            .map(|k| {
                let unit = if k < 3 { "N" } else { "N·m" };
                Panel::new(
                    format!("{} {}", r.run.name, AXIS_NAMES[k]),
                    "t [s]",
                    format!("{} [{unit}]", AXIS_NAMES[k]),
                )
                .with(Series::line("sensor - start", t.clone(), col(&r.raw, k)))
                .with(Series::line(
                    "F_e ident+tare",
                    t.clone(),
                    col(&r.base.tracked, k),
                ))
                .with(Series::line(
                    "F_e comp+tare",
                    t.clone(),
                    col(&r.selected.tracked, k),
                ))
            })
            .collect();
        let fig = Figure::grid(panels, 3);
        let [svg, png] = stage_figure(out, &fig, &dir.join(format!("payload_{}", r.run.name)))?;
        paths.push(svg);
        paths.push(png);
    }
    Ok(paths)
}
