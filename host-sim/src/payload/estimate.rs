//! The core's f32 estimator over a run and the error measures of the
//! report.

use anyhow::{anyhow, Result};
use cable_joint::lsq::RlsConfig;
use cable_joint::payload::{CompState, Kinematics, OffsetTracker, PayloadModel, Wrench};

use super::Run;

/// The estimator's output on a run: per sample `F_e`, without and with the
/// offset tracker (updated during `t < tare_s`).
pub struct Estimate {
    /// `F_e` with the model's `F_0`.
    pub raw_model: Vec<[f64; 6]>,
    /// `F_e` after the offset tracker.
    pub tracked: Vec<[f64; 6]>,
}

/// Run the core's f32 estimator over a run.
pub fn estimate(
    run: &Run,
    kin: &[Kinematics<f64>],
    model: &PayloadModel,
    tare_s: f64,
) -> Result<Estimate> {
    let mut state = CompState::default();
    let mut tracker = OffsetTracker::new(RlsConfig {
        forgetting: 1.0,
        initial_covariance: 1e3,
        max_trace: 1e4,
    })?;
    let mut out = Estimate {
        raw_model: Vec::with_capacity(kin.len()),
        tracked: Vec::with_capacity(kin.len()),
    };
    let mut prev = None;
    let rows = kin.iter().zip(run.wrench.t_s.iter().zip(&run.wrench.v));
    for (row, (k, (t, w))) in rows.enumerate() {
        let dt = prev.map_or(0.0, |p| t - p) as f32;
        prev = Some(*t);
        let k32 = Kinematics {
            gravity_m_s2: k.gravity_m_s2.map(|v| v as f32),
            accel_m_s2: k.accel_m_s2.map(|v| v as f32),
            omega_rad_s: k.omega_rad_s.map(|v| v as f32),
            alpha_rad_s2: k.alpha_rad_s2.map(|v| v as f32),
        };
        let meas = Wrench::<f32>::from(w.map(|v| v as f32));
        let fe = model.estimate(&mut state, &k32, &meas, dt).map_err(|e| {
            // The wrench row's line (header on line 1) and its values: a
            // reading the core's f32 cannot hold, or whose products
            // overflow, is named where it is.
            let name = &run.name;
            anyhow!(
                "{name}: estimate at {t:.4} s ({name}_wrench.csv line {}, wrench {w:?}): {e}",
                row + 2
            )
        })?;
        let tr = tracker.process(&fe, *t < tare_s);
        out.raw_model
            .push(std::array::from_fn(|i| f64::from(fe[i])));
        out.tracked.push(std::array::from_fn(|i| f64::from(tr[i])));
    }
    Ok(out)
}

/// RMS per axis.
pub fn rms(x: &[[f64; 6]]) -> [f64; 6] {
    let n = x.len().max(1) as f64;
    std::array::from_fn(|k| (x.iter().map(|r| r[k] * r[k]).sum::<f64>() / n).sqrt())
}

/// The raw sensor minus its mean over the first `tare_s`.
pub fn raw_minus_start(run: &Run, tare_s: f64) -> Vec<[f64; 6]> {
    let idx: Vec<usize> = (0..run.wrench.len())
        .filter(|&i| run.wrench.t_s[i] < tare_s)
        .collect();
    let n = idx.len().max(1) as f64;
    let m: [f64; 6] =
        std::array::from_fn(|k| idx.iter().map(|&i| run.wrench.v[i][k]).sum::<f64>() / n);
    run.wrench
        .v
        .iter()
        .map(|r| std::array::from_fn(|k| r[k] - m[k]))
        .collect()
}

/// `F_s - map(gamma)`, re-zeroed by its mean over `t < tare_s`.
pub fn affine_residual(
    run: &Run,
    kin: &[Kinematics<f64>],
    map: &[[f64; 4]; 6],
    tare_s: f64,
) -> Vec<[f64; 6]> {
    let mut r: Vec<[f64; 6]> = kin
        .iter()
        .zip(&run.wrench.v)
        .map(|(kn, w)| {
            let g = kn.apparent_gravity_m_s2();
            std::array::from_fn(|k| {
                let c = &map[k];
                w[k] - (c[0] + c[1] * g.x + c[2] * g.y + c[3] * g.z)
            })
        })
        .collect();
    let idx: Vec<usize> = (0..r.len())
        .filter(|&i| run.wrench.t_s[i] < tare_s)
        .collect();
    if !idx.is_empty() {
        let n = idx.len() as f64;
        let m: [f64; 6] = std::array::from_fn(|k| idx.iter().map(|&i| r[i][k]).sum::<f64>() / n);
        for row in &mut r {
            for k in 0..6 {
                row[k] -= m[k];
            }
        }
    }
    r
}

/// Mean of `(rmse_k / sigma_k)^2` over the axes: one number that weighs
/// forces and torques like the identification does.
pub fn weighted_score(rmse: &[f64; 6], sigma: &[f64; 6]) -> f64 {
    rmse.iter()
        .zip(sigma)
        .map(|(r, s)| (r / s).powi(2))
        .sum::<f64>()
        / 6.0
}
