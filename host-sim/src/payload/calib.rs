//! Conventions from the static calibration poses: the orientation
//! convention, the accelerometer's calibration into the sensor frame and the
//! payload identified from the poses alone.

use anyhow::{anyhow, bail, Result};
use cable_joint::lsq::{BatchLsq, LsqConfig};
use cable_joint::payload::{IdentConfig, Kinematics, PayloadFit, PayloadIdentifier, Wrench};
use nalgebra::{Matrix3, Vector3};
use serde::Serialize;

use super::StaticPoses;

/// The row-major `r11..r33` as a matrix.
pub(super) fn mat(r: &[f64; 9]) -> Matrix3<f64> {
    Matrix3::from_row_slice(r)
}

/// Which orientation convention maps world gravity into the sensor frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Convention {
    /// `true`: `g_s = R^T g_w` (R maps sensor to world); `false`: `g_s = R g_w`.
    pub transpose: bool,
    /// World gravity `g_w`, m/s².
    pub world_gravity_m_s2: [f64; 3],
    /// Largest error of this convention over the poses, m/s².
    pub max_err_m_s2: f64,
    /// Largest error of the best *other* hypothesis, m/s².
    pub runner_up_max_err_m_s2: f64,
}

impl Convention {
    /// Gravity in the sensor frame for orientation `r`.
    pub fn gravity(&self, r: &[f64; 9]) -> Vector3<f64> {
        let m = mat(r);
        let gw = Vector3::from(self.world_gravity_m_s2);
        if self.transpose {
            m.transpose() * gw
        } else {
            m * gw
        }
    }
}

/// Try `R^T g_w` and `R g_w` with `g_w = (0, 0, ∓|g|)` on the calibration
/// poses; the hypothesis with the smallest largest error wins. `|g|` is the
/// mean norm of the file's gravity vectors.
pub fn check_convention(poses: &StaticPoses) -> Result<Convention> {
    let n = poses.gravity_m_s2.len() as f64;
    let g0 = poses
        .gravity_m_s2
        .iter()
        .map(|g| Vector3::from(*g).norm())
        .sum::<f64>()
        / n;
    let mut hyps = Vec::new();
    for transpose in [true, false] {
        for s in [-1.0, 1.0] {
            let mut c = Convention {
                transpose,
                world_gravity_m_s2: [0.0, 0.0, s * g0],
                max_err_m_s2: 0.0,
                runner_up_max_err_m_s2: 0.0,
            };
            c.max_err_m_s2 = poses
                .orient
                .iter()
                .zip(&poses.gravity_m_s2)
                .map(|(r, g)| (c.gravity(r) - Vector3::from(*g)).norm())
                .fold(0.0, f64::max);
            hyps.push(c);
        }
    }
    hyps.sort_by(|a, b| a.max_err_m_s2.total_cmp(&b.max_err_m_s2));
    let mut best = hyps[0];
    best.runner_up_max_err_m_s2 = hyps[1].max_err_m_s2;
    if best.max_err_m_s2 > 0.05 * g0 {
        bail!(
            "no orientation convention reproduces the calibration gravity (best max error {:.3} m/s²)",
            best.max_err_m_s2
        );
    }
    Ok(best)
}

/// Affine accelerometer calibration into the sensor frame:
/// `g - a = K a_raw + c` (m/s², `a_raw` in g).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct AccelCalibration {
    /// `K`, row major, m/s² per g.
    pub k: [[f64; 3]; 3],
    /// `c`, m/s².
    pub c: [f64; 3],
    /// RMS residual over the poses, m/s².
    pub rms_m_s2: f64,
    /// Nearest rotation to `-K / |K|` (IMU axes to sensor axes), row major.
    pub rotation: [[f64; 3]; 3],
}

impl AccelCalibration {
    /// `g - a` in the sensor frame from a raw reading (g).
    pub fn apply(&self, a_g: &[f64; 3]) -> Vector3<f64> {
        let k = Matrix3::from_fn(|i, j| self.k[i][j]);
        k * Vector3::from(*a_g) + Vector3::from(self.c)
    }
}

/// Fit [`AccelCalibration`] to the static poses (at rest `g - a = g`).
pub fn fit_accel_calibration(poses: &StaticPoses) -> Result<AccelCalibration> {
    let mut k = [[0.0; 3]; 3];
    let mut c = [0.0; 3];
    let mut rss = 0.0;
    for axis in 0..3 {
        let mut ls = BatchLsq::<4>::new(4, LsqConfig::default()).map_err(|e| anyhow!("{e}"))?;
        for (a, g) in poses.accel_g.iter().zip(&poses.gravity_m_s2) {
            ls.push(&[a[0], a[1], a[2], 1.0], g[axis])
                .map_err(|e| anyhow!("accelerometer calibration: {e}"))?;
        }
        let fit = ls
            .solve()
            .map_err(|e| anyhow!("accelerometer calibration: {e}"))?;
        k[axis] = [fit.params[0], fit.params[1], fit.params[2]];
        c[axis] = fit.params[3];
        rss += fit.rss;
    }
    let km = Matrix3::from_fn(|i, j| -k[i][j]);
    let svd = km.svd(true, true);
    let (u, vt) = (
        svd.u.ok_or_else(|| anyhow!("SVD failed"))?,
        svd.v_t.ok_or_else(|| anyhow!("SVD failed"))?,
    );
    let mut d = Matrix3::identity();
    d[(2, 2)] = (u * vt).determinant().signum();
    let rot = u * d * vt;
    Ok(AccelCalibration {
        k,
        c,
        rms_m_s2: (rss / (3.0 * poses.accel_g.len() as f64)).sqrt(),
        rotation: std::array::from_fn(|i| std::array::from_fn(|j| rot[(i, j)])),
    })
}

/// The payload (offsets, mass, first moment) from the static poses alone.
pub fn static_identification(poses: &StaticPoses, weight: [f64; 6]) -> Result<PayloadFit> {
    let cfg = IdentConfig {
        inertia: false,
        axis_weight: weight,
        ..IdentConfig::default()
    };
    let mut id = PayloadIdentifier::new(cfg)?;
    for (w, g) in poses.wrench.iter().zip(&poses.gravity_m_s2) {
        id.push(
            &Kinematics::static_pose(Vector3::from(*g)),
            &Wrench::from(*w),
            0.0,
        )?;
    }
    Ok(id.solve()?)
}
