//! The report's figures: counterparts of the seed's Figs. 9, 10, 12-18 and
//! 20-26, and the accuracy comparison of step 7, through [`crate::plot`].

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use super::experiments::{LoadCase, TrackRun, TRACE_EVERY};
use super::programme::{Evaluation, Identification};
use super::regressors::Replay;
use crate::ident::FitReport;
use crate::output::Outputs;
use crate::plot::{stage_figure, Figure, Panel, Series};
use crate::scenario::LOADING_MASSES_G;
use crate::stats::DEG_PER_RAD;

/// One written figure: its file stem (relative to the report directory)
/// and caption.
#[derive(Clone, Debug)]
pub struct Written {
    /// Stem, e.g. `fig09_jae` (`.svg` and `.png` exist).
    pub stem: String,
    /// Caption for report.md.
    pub caption: String,
}

fn every<T: Copy>(v: &[T], k: usize) -> Vec<T> {
    v.iter().step_by(k.max(1)).copied().collect()
}

fn diff(a: &[f64], b: &[f64]) -> Vec<f64> {
    a.iter().zip(b).map(|(x, y)| x - y).collect()
}

fn scaled(v: &[f64], k: f64) -> Vec<f64> {
    v.iter().map(|x| x * k).collect()
}

/// Stages every figure among the report's outputs (written with the report,
/// or none is).
struct Writer<'a> {
    dir: &'a Path,
    out: &'a mut Outputs,
    written: Vec<Written>,
}

impl Writer<'_> {
    fn write(&mut self, stem: &str, caption: &str, fig: &Figure) -> Result<()> {
        let _: [PathBuf; 2] = stage_figure(self.out, fig, &self.dir.join(stem))
            .with_context(|| format!("figure {stem}"))?;
        self.written.push(Written {
            stem: stem.to_owned(),
            caption: caption.to_owned(),
        });
        Ok(())
    }
}

fn tracking_figure(run: &TrackRun, title: &str, with_estimate: bool) -> Figure {
    let t = &run.trace;
    let title = match &run.fault {
        Some(f) => format!("{title} — FAULT: {f}"),
        None => title.to_owned(),
    };
    let mut angles = Panel::new(title, "t [s]", "joint angle [°]")
        .with(Series::line(
            "desired",
            t.t_s.clone(),
            t.desired_deg.clone(),
        ))
        .with(Series::line(
            "actual (magnetic encoder)",
            t.t_s.clone(),
            t.actual_deg.clone(),
        ));
    if with_estimate {
        angles = angles.with(Series::line(
            "estimated (JAE)",
            t.t_s.clone(),
            t.estimated_deg.clone(),
        ));
    }
    let mut errors = Panel::new("errors", "t [s]", "error [°]").with(Series::line(
        "desired − actual",
        t.t_s.clone(),
        diff(&t.desired_deg, &t.actual_deg),
    ));
    if with_estimate {
        errors = errors.with(Series::line(
            "actual − estimated",
            t.t_s.clone(),
            diff(&t.actual_deg, &t.estimated_deg),
        ));
    }
    Figure::grid(vec![angles, errors], 1)
}

fn model_panels(
    replay: &Replay,
    fit: &FitReport,
    title: &str,
    target: &[f64],
    k: usize,
) -> Result<[Panel; 2]> {
    let t = every(replay.t_s()?, k);
    let pred = replay.predict(fit, true, false)?;
    let y = every(target, k);
    let p = every(&pred, k);
    Ok([
        Panel::new(title, "t [s]", "F1' [N]")
            .with(Series::line("DOB tension (Eq. 21)", t.clone(), y.clone()))
            .with(Series::line("model", t.clone(), p.clone())),
        Panel::new(format!("{title}: error"), "t [s]", "model − DOB [N]").with(Series::line(
            "",
            t,
            diff(&p, &y),
        )),
    ])
}

fn loading_figure(cases: &[&LoadCase], title: &str) -> Figure {
    let mut panels = Vec::new();
    for c in cases {
        let t = &c.trace;
        let mut p = Panel::new(
            format!(
                "{title}: {} g ({:+.2} N){}",
                c.mass_g,
                c.force_n,
                if c.fault.is_some() { " FAULT" } else { "" }
            ),
            "t [s]",
            "tip force [N]",
        )
        .with(Series::line("applied", t.t_s.clone(), t.f_ext_n.clone()))
        .with(Series::line(
            "estimated",
            t.t_s.clone(),
            t.f_ext_hat_n.clone(),
        ));
        if c.accuracy_pct.is_finite() {
            p.title = format!("{}, accuracy {:.1} %", p.title, c.accuracy_pct);
        }
        panels.push(p);
    }
    let mut err = Panel::new(
        format!("{title}: joint angle error"),
        "t [s]",
        "desired − actual [°]",
    );
    for c in cases {
        err = err.with(Series::line(
            format!("{} g", c.mass_g),
            c.trace.t_s.clone(),
            c.trace.angle_err_deg.clone(),
        ));
    }
    panels.push(err);
    Figure::grid(panels, 2)
}

/// Stage the clean programme's figures in `dir` among `out`.
pub fn programme_figures(
    dir: &Path,
    out: &mut Outputs,
    id: &Identification,
    ev: &Evaluation,
) -> Result<Vec<Written>> {
    let mut w = Writer {
        dir,
        out,
        written: Vec::new(),
    };
    jae_figure(&mut w, id)?;
    tracking_figures(&mut w, ev)?;
    bm_figure(&mut w, id)?;
    tension_figures(&mut w, id)?;
    loading_figures(&mut w, ev)?;
    Ok(w.written)
}

/// Fig. 9: the identified JAE on its identification run.
fn jae_figure(w: &mut Writer, id: &Identification) -> Result<()> {
    let k = TRACE_EVERY as usize;
    let r = Replay::new(&id.logs.jae, &id.config_jae)?;
    let t = every(r.t_s()?, k);
    let meas = scaled(&every(r.theta_rad(), k), DEG_PER_RAD);
    let est = scaled(&every(&r.col("theta_hat_rad")?, k), DEG_PER_RAD);
    w.write(
        "fig09_jae",
        "Fig. 9 counterpart: the identified JAE on its identification run (motor closed loop, joint open loop).",
        &Figure::grid(
            vec![
                Panel::new("JAE identification (jae-ident)", "t [s]", "joint angle [°]")
                    .with(Series::line("magnetic encoder", t.clone(), meas.clone()))
                    .with(Series::line("JAE (identified)", t.clone(), est.clone())),
                Panel::new("identification error", "t [s]", "JAE − encoder [°]")
                    .with(Series::line("", t, diff(&est, &meas))),
            ],
            1,
        ),
    )?;

    Ok(())
}

/// Figs. 10, 12, 13: tracking without and with the JAE, and under load.
fn tracking_figures(w: &mut Writer, ev: &Evaluation) -> Result<()> {
    w.write(
        "fig10_track_motor",
        "Fig. 10 counterpart: ±30° 0.5 Hz sine with motor-encoder feedback only.",
        &tracking_figure(&ev.track_motor, "tracking without JAE (track-motor)", false),
    )?;
    w.write(
        "fig12_track_jae",
        "Fig. 12 counterpart: the same sine with the JAE as the position feedback.",
        &tracking_figure(&ev.track_jae, "tracking with JAE (track-jae)", true),
    )?;
    w.write(
        "fig13_robust",
        "Fig. 13 counterpart: complex trajectory with 2.5 N on the tip, JAE feedback.",
        &tracking_figure(&ev.robust, "robustness under 2.5 N (robust-2n5)", true),
    )?;

    Ok(())
}

/// Figs. 14-15: `B_m` on its identification and a verification run.
fn bm_figure(w: &mut Writer, id: &Identification) -> Result<()> {
    let k = TRACE_EVERY as usize;
    let r = Replay::new(&id.logs.bm, &id.config)?;
    let y = r.motor_torque_nm()?;
    let w_filt = r.dob_filter(&r.col("phi_vel_rad_s")?);
    let pred = r.predict(&id.bm.fit, true, false)?;
    let rv = Replay::new(&id.logs.bm_val, &id.config)?;
    let tv = every(rv.t_s()?, k);
    let yv = every(&rv.motor_torque_nm()?, k);
    let pv = every(&rv.predict(&id.bm.fit, true, false)?, k);
    w.write(
        "fig14_15_bm",
        "Figs. 14-15 counterpart: no-load motor torque against speed with the identified B_m (identification run), and the model on a verification run with another seed.",
        &Figure::grid(
            vec![
                Panel::new("B_m identification (bm-noload)", "Q[phi'] [rad/s]", "Q[K_m i − J_m phi''] [N·m]")
                    .with(Series::points("measured", every(&w_filt, k), every(&y, k)))
                    .with(Series::points("model", every(&w_filt, k), every(&pred, k))),
                Panel::new("B_m verification (another run)", "t [s]", "torque [N·m]")
                    .with(Series::line("measured", tv.clone(), yv.clone()))
                    .with(Series::line("model", tv, pv)),
            ],
            1,
        ),
    )?;

    Ok(())
}

/// Figs. 16-18: the tension models on their identification run, and the
/// core's model on a verification run.
fn tension_figures(w: &mut Writer, id: &Identification) -> Result<()> {
    let k = TRACE_EVERY as usize;
    let r = Replay::new(&id.logs.tension, &id.config_jae)?;
    let y = r.col("tension1_hat_n")?;
    let mut panels = Vec::new();
    for (name, m) in [
        ("model A", id.tension.model_a.as_ref().ok()),
        ("model B", id.tension.model_b.as_ref().ok()),
        ("model C", Some(&id.tension.model_c)),
    ] {
        if let Some(m) = m {
            panels.extend(model_panels(&r, m, name, &y, k)?);
        }
    }
    w.write(
        "fig16_tension_models",
        "Fig. 16 counterpart: tension models A, B and C against the DOB's cable-1 tension on the identification run (JAE closed loop), with their errors.",
        &Figure::grid(panels, 2),
    )?;
    w.write(
        "fig17_model_c_simplified",
        "Fig. 17 counterpart: the simplified model C (after %σ pruning) on its identification run.",
        &Figure::grid(
            model_panels(&r, &id.tension.core, "simplified model C", &y, k)?.to_vec(),
            1,
        ),
    )?;

    // Fig. 18: verification run, the core's own model output.
    let r = Replay::new(&id.logs.tension_val, &id.config)?;
    let t = every(r.t_s()?, k);
    let y = every(&r.col("tension1_hat_n")?, k);
    let m = every(&r.col("tension1_model_n")?, k);
    w.write(
        "fig18_model_c_verification",
        "Fig. 18 counterpart: the simplified model C as the core evaluates it (Q[F1']) on a verification run with another seed.",
        &Figure::grid(
            vec![
                Panel::new("simplified model C, verification", "t [s]", "F1' [N]")
                    .with(Series::line("DOB tension", t.clone(), y.clone()))
                    .with(Series::line("model (core)", t.clone(), m.clone())),
                Panel::new("verification error", "t [s]", "model − DOB [N]")
                    .with(Series::line("", t, diff(&m, &y))),
            ],
            1,
        ),
    )?;

    Ok(())
}

/// Figs. 20-26: the loading protocol, and Fig. 22's regions of one case.
fn loading_figures(w: &mut Writer, ev: &Evaluation) -> Result<()> {
    let group = |angle: f64, dir: &str| -> Vec<&LoadCase> {
        ev.loading
            .iter()
            .filter(|c| c.angle_deg == angle && c.direction == dir)
            .collect()
    };
    let seed_figs = [
        ("fig20_loading_0deg_neg", 0.0, "neg", 20),
        ("fig21_loading_0deg_pos", 0.0, "pos", 21),
        ("fig23_loading_30deg_neg", 30.0, "neg", 23),
        ("fig24_loading_30deg_pos", 30.0, "pos", 24),
        ("fig25_loading_m40deg_pos", -40.0, "pos", 25),
        ("fig26_loading_m40deg_neg", -40.0, "neg", 26),
    ];
    for (stem, angle, dir, n) in seed_figs {
        let cases = group(angle, dir);
        let dir_word = if dir == "pos" { "positive" } else { "negative" };
        let extra = if n == 26 {
            " (the seed's Fig. 26 repeats the positive direction; the negative one is shown here)"
        } else {
            ""
        };
        w.write(
            stem,
            &format!(
                "Fig. {n} counterpart: {dir_word}-direction loading at {angle}°, {} g{extra}.",
                LOADING_MASSES_G.map(|m| m.to_string()).join(", ")
            ),
            &loading_figure(&cases, &format!("{angle}° {dir}")),
        )?;
    }
    if let Some(c) = ev
        .loading
        .iter()
        .find(|c| c.angle_deg == 30.0 && c.mass_g == 200.0 && c.direction == "pos")
    {
        let t = &c.trace;
        let region: Vec<f64> = t.phase.iter().map(|p| f64::from(*p)).collect();
        w.write(
            "fig22_partition",
            "Fig. 22 counterpart: the regions of one case (30°, 200 g, positive): 1 moving, 2 adjusting, 3 no-load, 4 loading, 5 stable, 6 unloading (0: hold at start).",
            &Figure::grid(
                vec![
                    Panel::new("30°, 200 g, positive", "t [s]", "tip force [N]")
                        .with(Series::line("applied", t.t_s.clone(), t.f_ext_n.clone()))
                        .with(Series::line("estimated", t.t_s.clone(), t.f_ext_hat_n.clone())),
                    Panel::new("region", "t [s]", "region")
                        .with(Series::line("", t.t_s.clone(), region)),
                ],
                1,
            ),
        )?;
    }
    Ok(())
}

/// Step 7's figure: accuracy of every loading case, per variant (staged).
pub fn accuracy_figure(
    dir: &Path,
    out: &mut Outputs,
    variants: &[(&str, &Evaluation)],
) -> Result<Vec<Written>> {
    let mut w = Writer {
        dir,
        out,
        written: Vec::new(),
    };
    let mut acc = Panel::new(
        "force accuracy per case (stable region)",
        "|F| [N]",
        "accuracy [%]",
    );
    let mut noise = Panel::new(
        "static no-load error per case",
        "|F| of the case [N]",
        "max |estimate| before loading [N]",
    );
    for (name, ev) in variants {
        let ok: Vec<&LoadCase> = ev.loading.iter().filter(|c| c.fault.is_none()).collect();
        acc = acc.with(Series::points(
            *name,
            ok.iter().map(|c| c.force_n.abs()).collect(),
            ok.iter().map(|c| c.accuracy_pct).collect(),
        ));
        noise = noise.with(Series::points(
            *name,
            ok.iter().map(|c| c.force_n.abs()).collect(),
            ok.iter().map(|c| c.static_noload_n.max_abs()).collect(),
        ));
    }
    w.write(
        "fig_accuracy_variants",
        "Force accuracy and static no-load error of every loading case: clean plant, plant with unmodelled effects (seed's model), and after the residual loop.",
        &Figure::grid(vec![acc, noise], 1),
    )?;
    Ok(w.written)
}
