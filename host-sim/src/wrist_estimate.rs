//! A recorded wrist's forces (Eq. 4–5) from its four joints' logs: the
//! replayed run of [`crate::wrist_log::replay`] through Eq. 3's model, if
//! one is given, and [`crate::wrist::wrist_force`], tick by tick, exactly
//! as the simulated wrist computes them (`host-sim estimate-wrist`).
//!
//! Per tick: each joint's external torque with its bound (Eq. 3 taken
//! out), each jaw's `F_y` bound (Eq. 4), and the clamp force with its
//! bound (Eq. 5). Where both jaws' logs carry a reference tip force
//! (`f_ext_n`: a reference sensor's, or the simulator's truth) the
//! reference clamp force `(|F_a| + |F_b|) / 2` is written beside it and
//! the estimate is judged against it ([`Summary`]).

use anyhow::{ensure, Result};
use cable_joint::wrist;

use crate::links::{no_load_stats, NoLoad};
use crate::log::Log;
use crate::plot::{Figure, Panel, Series};
use crate::wrist::{wrist_force, Eq3Filter, Eq3Model, WristForce};
use crate::wrist_log::{WristRun, JOINT_NAMES};

/// A reference clamp force at or above this is "holding" in [`Summary`], N
/// (the threshold for the clamp goal).
pub const HOLDING_N: f64 = 1.0;
/// A reference clamp force at or below this is "open" in [`Summary`], N.
pub const OPEN_N: f64 = 0.05;

/// One tick of a recorded wrist.
#[derive(Clone, Copy, Debug)]
pub struct WristEstimate {
    /// Eq. 4–5 on the tick.
    pub force: WristForce,
    /// Eq. 3's torque taken out of each joint (zero without a model), N·m.
    pub links_hat_nm: [f32; 4],
    /// The reference clamp force, where both jaws have a reference, N.
    pub reference_n: Option<f64>,
}

/// Eq. 4–5 on every tick of `run`, Eq. 3's `model` taken out if given (as
/// the simulated wrist applies it: [`Eq3Filter`] on the joints' estimated
/// angles).
pub fn estimate(run: &WristRun, model: Option<&Eq3Model>) -> Vec<WristEstimate> {
    let mut filter = model.map(|m| Eq3Filter::new(m, &run.setting.timing));
    let g = &run.setting.geometry;
    let open = run.setting.timing.jaw_open_rad as f32;
    let l_m = run.gripper_length_m.map(|l| l as f32);
    run.samples
        .iter()
        .zip(&run.tip_n)
        .enumerate()
        .map(|(k, (s, tip))| {
            let (hat, spread) = match &mut filter {
                Some(f) => {
                    let (_, hat, spread) = f.update(g, s.theta_hat_rad);
                    (hat, spread)
                }
                None => ([0.0; 4], [0.0; 4]),
            };
            let reference_n = run.reference_n.as_ref().and_then(|r| {
                let [a, b] = r[k];
                let c = 0.5 * (a.abs() + b.abs());
                c.is_finite().then_some(c)
            });
            WristEstimate {
                force: wrist_force(g, open, s.theta_hat_rad, *tip, l_m, hat, spread),
                links_hat_nm: hat,
                reference_n,
            }
        })
        .collect()
}

/// [`NoLoad`] of a free run (nothing touches the tips: the true torque is
/// zero) from [`estimate`]'s `ticks` of it: each joint's estimate against
/// zero, raw and with the model's torque taken out, and how often each
/// bound holds zero; the links' true torque is not known from logs (zero).
pub fn no_load(run: &WristRun, ticks: &[WristEstimate]) -> NoLoad {
    let per_tick = run
        .samples
        .iter()
        .zip(ticks)
        .map(|(s, t)| (*s, t.links_hat_nm, t.force.torque_bound_nm));
    no_load_stats(per_tick, run.gripper_length_m)
}

/// The output log's columns for each joint (prefixed by its name).
const JOINT_COLUMNS: [&str; 4] = ["tau_ext_nm", "tau_ext_lo_nm", "tau_ext_hi_nm", "eq3_nm"];

/// The ticks as a CSV log: `t_s` (since the run's first replayed tick),
/// each joint's external torque with its bound and Eq. 3's torque taken
/// out (`roll_tau_ext_nm`, ...), each jaw's `F_y` bound
/// (`jaw_a_fy_lo_n`, ...), the clamp force and its bound, Eq. 5's total
/// force per wrist-frame axis with the force limit's share of its bound
/// (`total_x_lo_n`, `total_x_hi_n`, `total_x_limit_n`, ...; empty where
/// unbounded; `totals[k]` is tick `k`'s [`WristForce::total`]), and the
/// reference clamp force where the run has one.
pub fn to_log(ticks: &[WristEstimate], totals: &[wrist::TotalForce], rate_hz: f64) -> Result<Log> {
    ensure!(
        totals.len() == ticks.len(),
        "{} totals for {} ticks: one Eq. 5 total per tick",
        totals.len(),
        ticks.len()
    );
    let with_reference = ticks.iter().any(|t| t.reference_n.is_some());
    let mut names: Vec<String> = vec!["t_s".to_owned()];
    for j in JOINT_NAMES {
        names.extend(JOINT_COLUMNS.map(|c| format!("{j}_{c}")));
    }
    for j in ["jaw_a", "jaw_b"] {
        names.extend(["fy_lo_n", "fy_hi_n"].map(|c| format!("{j}_{c}")));
    }
    names.extend(["clamp_n", "clamp_lo_n", "clamp_hi_n"].map(str::to_owned));
    for axis in ["x", "y", "z"] {
        names.extend(["lo_n", "hi_n", "limit_n"].map(|c| format!("total_{axis}_{c}")));
    }
    if with_reference {
        names.push("clamp_ref_n".to_owned());
    }
    let refs: Vec<&str> = names.iter().map(String::as_str).collect();
    let mut log = Log::with_columns(&refs)?;
    let mut row: Vec<Option<f64>> = Vec::with_capacity(names.len());
    for (k, (t, total)) in ticks.iter().zip(totals).enumerate() {
        let f = &t.force;
        row.clear();
        row.push(Some(k as f64 / rate_hz));
        for j in 0..4 {
            let b = f.torque_bound_nm[j];
            row.extend([f.torque_nm[j], b.lo, b.hi, t.links_hat_nm[j]].map(|v| Some(f64::from(v))));
        }
        for jaw in &f.jaws {
            row.extend([jaw.force_n[1].lo, jaw.force_n[1].hi].map(|v| Some(f64::from(v))));
        }
        row.extend(
            [
                f.clamp_n,
                f64::from(f.clamp_bound_n.lo),
                f64::from(f.clamp_bound_n.hi),
            ]
            .map(Some),
        );
        // Empty where the total is unbounded.
        for (b, prior) in total.force_n.iter().zip(total.prior_n) {
            row.extend([b.lo, b.hi, prior].map(|v| v.is_finite().then_some(f64::from(v))));
        }
        if with_reference {
            // Empty where a jaw's reference is not measured.
            row.push(t.reference_n);
        }
        log.push_row_opt(&row)?;
    }
    Ok(log)
}

/// How the clamp estimate compares with the reference.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Summary {
    /// Ticks with a reference.
    pub with_reference: usize,
    /// Ticks whose reference clamp force is at least [`HOLDING_N`].
    pub holding: usize,
    /// RMS of `estimate - reference` over those, N.
    pub holding_rms_n: f64,
    /// Largest `|estimate - reference| / reference` over those, %.
    pub holding_worst_pct: f64,
    /// Share of those whose bound holds the reference.
    pub holding_coverage: f64,
    /// Share of every tick with a reference whose bound holds it.
    pub coverage: f64,
    /// Ticks whose reference is at most [`OPEN_N`] (jaws free).
    pub open: usize,
    /// Largest |estimate| over those, N.
    pub open_max_n: f64,
}

/// [`Summary`] of the ticks (`None` without a reference).
pub fn summary(ticks: &[WristEstimate]) -> Option<Summary> {
    let mut s = Summary::default();
    let (mut sq, mut held_in, mut all_in) = (0.0, 0usize, 0usize);
    for t in ticks {
        let Some(r) = t.reference_n else { continue };
        s.with_reference += 1;
        let b = t.force.clamp_bound_n;
        let inside = b.lo <= r as f32 + 1e-6 && r as f32 - 1e-6 <= b.hi;
        all_in += usize::from(inside);
        let e = t.force.clamp_n - r;
        if r >= HOLDING_N {
            s.holding += 1;
            sq += e * e;
            s.holding_worst_pct = s.holding_worst_pct.max(100.0 * e.abs() / r);
            held_in += usize::from(inside);
        } else if r <= OPEN_N {
            s.open += 1;
            s.open_max_n = s.open_max_n.max(t.force.clamp_n.abs());
        }
    }
    if s.with_reference == 0 {
        return None;
    }
    s.holding_rms_n = (sq / s.holding.max(1) as f64).sqrt();
    s.holding_coverage = held_in as f64 / s.holding.max(1) as f64;
    s.coverage = all_in as f64 / s.with_reference as f64;
    Some(s)
}

/// The clamp force inside its bound (with the reference where the log has
/// one), the total force's bound across the pitch axis, and each joint's
/// external torque at its tip against time, from the log [`to_log`]
/// wrote.
pub fn figure(out: &Log, title: &str, l_m: [f64; 4]) -> Result<Figure> {
    let t = out.time_s()?.to_vec();
    let col = |n: &str| out.col_required(n).map(<[f64]>::to_vec);
    let mut clamp = Panel::new(format!("{title}: clamp force (Eq. 5)"), "t [s]", "F_cp [N]")
        .with(Series::line("bound, low", t.clone(), col("clamp_lo_n")?))
        .with(Series::line("bound, high", t.clone(), col("clamp_hi_n")?))
        .with(Series::line("estimate", t.clone(), col("clamp_n")?));
    if let Some(r) = out.col("clamp_ref_n") {
        clamp = clamp.with(Series::line("reference", t.clone(), r.to_vec()));
    }
    let mut joints = Panel::new(
        "each joint's external torque over its tip distance (Eq. 3 taken out)",
        "t [s]",
        "tau_ext / l_e [N]",
    );
    for (j, name) in JOINT_NAMES.iter().enumerate() {
        let tau = col(&format!("{name}_tau_ext_nm"))?;
        joints = joints.with(Series::line(
            *name,
            t.clone(),
            tau.iter().map(|x| x / l_m[j]).collect(),
        ));
    }
    // The one total-force axis the joints see in a grasp (x_2, the pitch
    // joint's): its bound, and the part of it the force limit makes.
    let (lo, hi, limit) = (
        col("total_x_lo_n")?,
        col("total_x_hi_n")?,
        col("total_x_limit_n")?,
    );
    let total = Panel::new(
        "total force across the pitch axis (Eq. 5, x_2; the axis the joints see in a grasp)",
        "t [s]",
        "F_x [N]",
    )
    .with(Series::line("bound, low", t.clone(), lo))
    .with(Series::line("bound, high", t.clone(), hi))
    .with(Series::line(
        "the force limit's half-width",
        t.clone(),
        limit,
    ));
    let mut fig = Figure::grid(vec![clamp, total, joints], 1);
    fig.panel_px = (1000, 420);
    Ok(fig)
}

/// A free run's no-load force at each joint's tip (the truth is zero):
/// the estimate as the joint gave it, with Eq. 3 taken out, and the bound
/// with it taken out, one panel a joint; `ticks` are [`estimate`]'s of
/// `run` with the model.
pub fn no_load_panels(run: &WristRun, ticks: &[WristEstimate], title: &str) -> Vec<Panel> {
    let t: Vec<f64> = (0..ticks.len()).map(|k| k as f64 / run.rate_hz).collect();
    let l = run.gripper_length_m;
    JOINT_NAMES
        .iter()
        .enumerate()
        .map(|(j, name)| {
            let over = |f: &dyn Fn(usize) -> f64| (0..ticks.len()).map(f).collect::<Vec<f64>>();
            Panel::new(
                format!("{title}: {name}, no load (truth 0)"),
                "t [s]",
                "tau_ext / l_e [N]",
            )
            .with(Series::line(
                "bound, low (Eq. 3 out)",
                t.clone(),
                over(&|k| f64::from(ticks[k].force.torque_bound_nm[j].lo) / l[j]),
            ))
            .with(Series::line(
                "bound, high (Eq. 3 out)",
                t.clone(),
                over(&|k| f64::from(ticks[k].force.torque_bound_nm[j].hi) / l[j]),
            ))
            .with(Series::line(
                "estimate",
                t.clone(),
                over(&|k| run.samples[k].torque_nm[j] / l[j]),
            ))
            .with(Series::line(
                "Eq. 3 taken out",
                t.clone(),
                over(&|k| f64::from(ticks[k].force.torque_nm[j]) / l[j]),
            ))
        })
        .collect()
}
