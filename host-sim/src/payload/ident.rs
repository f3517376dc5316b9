//! Identification on a run: the base model, the IMU lag, the creep/drift
//! columns with the seed's pruning, and the diagnostic affine map.

use std::time::Instant;

use anyhow::{anyhow, bail, Result};
use cable_joint::lsq::{BatchLsq, LsqConfig, LsqError};
use cable_joint::payload::{
    Column, IdentConfig, Kinematics, PayloadError, PayloadFit, PayloadIdentifier, Wrench,
};

use super::{kinematics, AccelCalibration, Convention, GravitySource, KinOptions, Run};

/// Identify on one run; returns the fit and the wall time of the
/// accumulation and the solve, s.
pub fn identify(run: &Run, kin: &[Kinematics<f64>], cfg: IdentConfig) -> Result<(PayloadFit, f64)> {
    let start = Instant::now();
    let mut id = PayloadIdentifier::new(cfg)?;
    let mut prev = None;
    for (k, (t, w)) in kin.iter().zip(run.wrench.t_s.iter().zip(&run.wrench.v)) {
        let dt = prev.map_or(0.0, |p| t - p);
        prev = Some(*t);
        id.push(k, &Wrench::from(*w), dt)
            .map_err(|e| anyhow!("{}: sample at {t:.4} s: {e}", run.name))?;
    }
    let fit = id
        .solve()
        .map_err(|e| anyhow!("identification on {}: {e}", run.name))?;
    Ok((fit, start.elapsed().as_secs_f64()))
}

/// Estimate the IMU lag: the lag (grid, s) that minimises the residual of
/// the base model (no rotational terms, no compensation) on `run`.
pub fn estimate_accel_lag(
    run: &Run,
    conv: &Convention,
    cal: &AccelCalibration,
    weight: [f64; 6],
    grid_s: &[f64],
) -> Result<(f64, Vec<(f64, f64)>)> {
    let mut curve = Vec::new();
    for &lag in grid_s {
        let opts = KinOptions {
            gravity: GravitySource::Accel,
            accel_lag_s: lag,
            rotational: false,
            lowpass_hz: None,
        };
        let kin = kinematics(run, &opts, conv, cal);
        let cfg = IdentConfig {
            inertia: false,
            axis_weight: weight,
            ..IdentConfig::default()
        };
        let (fit, _) = identify(run, &kin, cfg)?;
        curve.push((lag, fit.lsq.rmse));
    }
    let best = curve
        .iter()
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|c| c.0)
        .ok_or_else(|| anyhow!("empty lag grid"))?;
    Ok((best, curve))
}

/// The seed's pruning rule (Sect. 4 of seed 000, applied here to the
/// creep/drift columns): a creep or drift column whose `%sigma` exceeds this
/// is dropped and the model refitted.
pub const MAX_PCT_SIGMA: f64 = 5.0;

/// Identify with creep/drift columns: the creep columns are driven by the
/// payload load of `base` (a fit without creep); columns that make the
/// problem rank deficient, or whose `%sigma` exceeds [`MAX_PCT_SIGMA`], are
/// dropped one round at a time; finally the creep load is refreshed with the
/// pruned fit's own inertial parameters and the model refitted once.
pub fn identify_comp(
    run: &Run,
    kin: &[Kinematics<f64>],
    mut cfg: IdentConfig,
    base: &PayloadFit,
) -> Result<(PayloadFit, IdentConfig)> {
    cfg.creep_load = base.params.inertial;
    let drop_col = |cfg: &mut IdentConfig, col: usize| -> bool {
        match cfg.column(col) {
            Some(Column::Creep(k)) => {
                cfg.comp.creep_axes[k] = false;
                true
            }
            Some(Column::Drift(k)) => {
                cfg.comp.drift_axes[k] = false;
                true
            }
            _ => false,
        }
    };
    let mut fit = None;
    for _round in 0..13 {
        if cfg.comp.n_cols() == 0 {
            break;
        }
        let res = PayloadIdentifier::new(cfg).and_then(|mut id| {
            let mut prev = None;
            for (k, (t, w)) in kin.iter().zip(run.wrench.t_s.iter().zip(&run.wrench.v)) {
                let dt = prev.map_or(0.0, |p| t - p);
                prev = Some(*t);
                id.push(k, &Wrench::from(*w), dt)?;
            }
            id.solve()
        });
        match res {
            Err(PayloadError::Lsq(LsqError::IllConditioned { column, .. })) => {
                if !drop_col(&mut cfg, usize::from(column)) {
                    bail!(
                        "identification on {}: the base model is rank deficient (column {column})",
                        run.name
                    );
                }
            }
            Err(e) => bail!("identification on {}: {e}", run.name),
            Ok(f) => {
                let flagged: Vec<usize> = (0..f.lsq.n_params)
                    .filter(|&c| {
                        matches!(cfg.column(c), Some(Column::Creep(_) | Column::Drift(_)))
                            && f.lsq.pct_sigma(c).partial_cmp(&MAX_PCT_SIGMA)
                                != Some(std::cmp::Ordering::Less)
                    })
                    .collect();
                if flagged.is_empty() {
                    fit = Some(f);
                    break;
                }
                // Drop from the last column so earlier indices stay valid.
                for &c in flagged.iter().rev() {
                    drop_col(&mut cfg, c);
                }
            }
        }
    }
    let Some(_) = fit else {
        // Every term pruned: the base model.
        return Ok((base.clone(), cfg));
    };
    // Refresh the creep load with the pruned model's own parameters.
    let mut cfg2 = cfg;
    if let Some(f) = &fit {
        cfg2.creep_load = f.params.inertial;
    }
    let (f2, _) = identify(run, kin, cfg2)?;
    Ok((f2, cfg2))
}

/// Diagnostic: a general affine map from `g - a` to each wrench axis,
/// `F_k = c_k0 + sum_j c_kj gamma_j` (24 parameters instead of the rigid
/// body's 6 + 4). It can represent sensor crosstalk, scale errors and a
/// misalignment between the sensor and the accelerometer/orientation frame,
/// which `f = m gamma`, `tau = m c x gamma` cannot. Returns the coefficients
/// per axis.
pub fn fit_affine_map(run: &Run, kin: &[Kinematics<f64>]) -> Result<[[f64; 4]; 6]> {
    let mut out = [[0.0; 4]; 6];
    for (k, o) in out.iter_mut().enumerate() {
        let mut ls = BatchLsq::<4>::new(4, LsqConfig::default()).map_err(|e| anyhow!("{e}"))?;
        for (kn, w) in kin.iter().zip(&run.wrench.v) {
            let g = kn.apparent_gravity_m_s2();
            ls.push(&[1.0, g.x, g.y, g.z], w[k])
                .map_err(|e| anyhow!("{}: affine map: {e}", run.name))?;
        }
        let fit = ls
            .solve()
            .map_err(|e| anyhow!("{}: affine map: {e}", run.name))?;
        *o = [fit.params[0], fit.params[1], fit.params[2], fit.params[3]];
    }
    Ok(out)
}
