//! The kinematics at every wrench sample: angular rates from the
//! orientations, `g - a` from the accelerometer or the orientation, the
//! low-pass shared by the wrench and the kinematics.

use cable_joint::filter::LowPass1;
use cable_joint::payload::Kinematics;
use nalgebra::Vector3;

use super::calib::mat;
use super::{AccelCalibration, Convention, GravitySource, Run, Stream};

/// Angular velocity (at the midpoints) and acceleration (at the samples) of
/// the sensor frame from the orientation stream, in the sensor frame
/// (`R` maps sensor to world if `transpose`, so `R^T dR/dt = [omega]x`).
pub fn angular_rates(orient: &Stream<9>, transpose: bool) -> (Stream<3>, Stream<3>) {
    let rot = |r: &[f64; 9]| {
        let m = mat(r);
        if transpose {
            m
        } else {
            m.transpose()
        }
    };
    let mut w = Stream {
        t_s: Vec::new(),
        v: Vec::new(),
    };
    for k in 0..orient.len().saturating_sub(1) {
        let dt = orient.t_s[k + 1] - orient.t_s[k];
        let m = rot(&orient.v[k]).transpose() * rot(&orient.v[k + 1]);
        // Rotation vector of m (log map).
        let s = Vector3::new(
            m[(2, 1)] - m[(1, 2)],
            m[(0, 2)] - m[(2, 0)],
            m[(1, 0)] - m[(0, 1)],
        ) * 0.5;
        let cos = ((m.trace() - 1.0) * 0.5).clamp(-1.0, 1.0);
        let ang = s.norm().atan2(cos);
        let sin = s.norm();
        let scale = if sin > 1e-12 { ang / sin } else { 1.0 };
        w.t_s.push(0.5 * (orient.t_s[k] + orient.t_s[k + 1]));
        w.v.push((s * (scale / dt)).into());
    }
    let mut a = Stream {
        t_s: Vec::new(),
        v: Vec::new(),
    };
    for k in 0..w.len().saturating_sub(1) {
        let dt = w.t_s[k + 1] - w.t_s[k];
        a.t_s.push(orient.t_s[k + 1]);
        a.v.push(std::array::from_fn(|i| (w.v[k + 1][i] - w.v[k][i]) / dt));
    }
    (w, a)
}

/// How the kinematics of a run are built.
#[derive(Clone, Copy, Debug)]
pub struct KinOptions {
    /// Source of `g - a`.
    pub gravity: GravitySource,
    /// IMU lag behind the wrench, s.
    pub accel_lag_s: f64,
    /// Include angular velocity and acceleration.
    pub rotational: bool,
    /// Low-pass cut-off for wrench and kinematics, Hz (`None`: unfiltered).
    pub lowpass_hz: Option<f64>,
}

/// Two cascaded first-order low-passes ([`cable_joint::filter::LowPass1`],
/// the firmware's filter) at `cutoff_hz`, sampled at `period_s`, applied in
/// place; the state starts settled on the first row.
pub fn lowpass<const N: usize>(rows: &mut [[f64; N]], cutoff_hz: f64, period_s: f64) {
    let lp = LowPass1::new(
        (2.0 * std::f64::consts::PI * cutoff_hz) as f32,
        period_s as f32,
    );
    let Some(first) = rows.first().copied() else {
        return;
    };
    let mut s1 = first.map(|v| v as f32);
    let mut s2 = s1;
    for r in rows.iter_mut() {
        for k in 0..N {
            let y1 = lp.update(&mut s1[k], r[k] as f32);
            r[k] = f64::from(lp.update(&mut s2[k], y1));
        }
    }
}

fn mean_period_s(t: &[f64]) -> f64 {
    match (t.first(), t.last()) {
        (Some(a), Some(b)) if t.len() > 1 => (b - a) / (t.len() - 1) as f64,
        _ => 1.0,
    }
}

/// The run with its wrench low-passed as `opts` says (a copy).
pub fn filtered_run(run: &Run, opts: &KinOptions) -> Run {
    let mut r = run.clone();
    if let Some(fc) = opts.lowpass_hz {
        let p = mean_period_s(&r.wrench.t_s);
        lowpass(&mut r.wrench.v, fc, p);
    }
    r
}

/// The kinematics at every wrench sample.
pub fn kinematics(
    run: &Run,
    opts: &KinOptions,
    conv: &Convention,
    cal: &AccelCalibration,
) -> Vec<Kinematics<f64>> {
    let (w, a) = angular_rates(&run.orient, conv.transpose);
    let kin: Vec<Kinematics<f64>> = run
        .wrench
        .t_s
        .iter()
        .map(|&t| {
            let gam = match opts.gravity {
                GravitySource::Accel => cal.apply(&run.accel_g.at(t + opts.accel_lag_s)),
                GravitySource::Orient => conv.gravity(&run.orient.at(t)),
            };
            let (omega, alpha) = if opts.rotational {
                (Vector3::from(w.at(t)), Vector3::from(a.at(t)))
            } else {
                (Vector3::zeros(), Vector3::zeros())
            };
            Kinematics {
                gravity_m_s2: gam,
                accel_m_s2: Vector3::zeros(),
                omega_rad_s: omega,
                alpha_rad_s2: alpha,
            }
        })
        .collect();
    let Some(fc) = opts.lowpass_hz else {
        return kin;
    };
    let mut rows: Vec<[f64; 9]> = kin
        .iter()
        .map(|k| {
            let mut r = [0.0; 9];
            r[..3].copy_from_slice(k.gravity_m_s2.as_slice());
            r[3..6].copy_from_slice(k.omega_rad_s.as_slice());
            r[6..].copy_from_slice(k.alpha_rad_s2.as_slice());
            r
        })
        .collect();
    lowpass(&mut rows, fc, mean_period_s(&run.wrench.t_s));
    rows.iter()
        .map(|r| Kinematics {
            gravity_m_s2: Vector3::new(r[0], r[1], r[2]),
            accel_m_s2: Vector3::zeros(),
            omega_rad_s: Vector3::new(r[3], r[4], r[5]),
            alpha_rad_s2: Vector3::new(r[6], r[7], r[8]),
        })
        .collect()
}
