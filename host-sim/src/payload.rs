//! `host-sim payload`: tool payload identification and tool-end wrench
//! estimation (seed 001) on the measured KUKA wrist data set
//! (`tests/data/kuka-wrist`, CC BY 4.0).
//!
//! ```text
//! host-sim payload --dir host-sim/tests/data/kuka-wrist --fit 1-baseline \
//!     --validate 2-vibrations,3-vibrations-contact [--json OUT] [--plot DIR] [--csv DIR]
//! ```
//!
//! What it does, in order:
//!
//! 1. **Conventions from the static calibration file** (`0-calibration_fts-
//!    accel.csv`: wrench, accelerometer, gravity in the sensor frame and
//!    `r11..r33` for 24 poses): which of `R^T g_w` or `R g_w` (and which sign
//!    of the world's vertical) reproduces the file's gravity vectors
//!    ([`check_convention`]); an affine calibration of the accelerometer into
//!    the sensor frame, `g - a = K a_raw + c` ([`fit_accel_calibration`]);
//!    the payload identified from the 24 static poses alone, as a cross-check
//!    of the mass ([`static_identification`]).
//! 2. **Alignment** of the accelerometer (≈254 Hz) and orientation (100 Hz)
//!    streams onto the wrench time base (≈698 Hz) by linear interpolation,
//!    with the IMU lag as a parameter (`--accel-lag-ms`) or estimated by a grid
//!    search on the fit run's residual ([`estimate_accel_lag`]).
//! 3. **Identification** on the fit run ([`cable_joint::payload::PayloadIdentifier`],
//!    6 weighted rows per wrench sample; weights `1 / noise std` from
//!    `0-steady-state_wrench.csv`).
//! 4. **Validation**: the f32 estimator of the core
//!    ([`cable_joint::payload::PayloadModel`]) on every run; with no contact
//!    the estimate is the error. RMSE per axis of: the raw sensor minus its
//!    mean over the first `--tare-s` ("raw"), the identified model with the
//!    fit run's `F_0` ("ident"), the same with `F_0` re-zeroed by the
//!    [`cable_joint::payload::OffsetTracker`] during the first `--tare-s`
//!    (known no contact, "ident+tare"), and with the creep/drift terms chosen
//!    by validation error ("comp+tare").
//! 5. The contact run's estimated contact wrench; `--plot DIR` writes
//!    `payload_<run>.svg` and `.png` for every run, `--csv DIR` the samples.
//!
//! Method, results and the commands that reproduce them: `docs/payload.md`.
//!
//! Bad input files fail with one error naming the file, the line and the
//! column.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{anyhow, bail, Context, Result};
use cable_joint::filter::LowPass1;
use cable_joint::lsq::{BatchLsq, LsqConfig, LsqError, RlsConfig};
use cable_joint::payload::{
    Column, CompConfig, CompState, IdentConfig, Kinematics, OffsetTracker, PayloadError,
    PayloadFit, PayloadIdentifier, PayloadModel, Wrench, AXIS_NAMES, INERTIAL_NAMES,
};
use nalgebra::{Matrix3, Vector3};
use serde::Serialize;

use crate::log::{Log, Schema};
use crate::output::Outputs;

/// What [`analyse`] reads and how (the defaults are those of
/// `host-sim payload`, whose arguments are [`crate::cli::payload::PayloadArgs`]).
#[derive(Clone, Debug, PartialEq)]
pub struct PayloadOptions {
    /// Directory of the data set (`<run>_wrench.csv`, `<run>_accel.csv`,
    /// `<run>_orientations.csv`, `0-calibration_fts-accel.csv`,
    /// `0-steady-state_wrench.csv`).
    pub dir: PathBuf,
    /// Run to identify on (no contact).
    pub fit: String,
    /// Runs to validate on. A run whose name contains "contact" is treated
    /// as having contact (no error statistics).
    pub validate: Vec<String>,
    /// Source of `g - a`.
    pub gravity: GravitySource,
    /// Lag of the IMU stream behind the wrench stream, ms (`None`: estimated
    /// on the fit run with [`GravitySource::Accel`], 0 with
    /// [`GravitySource::Orient`]).
    pub accel_lag_ms: Option<f64>,
    /// Low-pass cut-off applied identically to the wrench and to the
    /// kinematics (two cascaded first-order sections of the core's
    /// `LowPass1`, causal), Hz; 0 = unfiltered.
    pub lowpass_hz: f64,
    /// Include the rotational terms (angular velocity and acceleration from
    /// differentiated orientations).
    pub rotational: bool,
    /// Also identify the six inertia entries (meaningful with
    /// [`Self::rotational`]).
    pub inertia: bool,
    /// Candidate creep time constants, s, for the compensation selection.
    pub creep_taus: Vec<f32>,
    /// Known no-contact window at the start of each run, s (offset tracker).
    pub tare_s: f64,
}

impl Default for PayloadOptions {
    fn default() -> Self {
        Self {
            dir: PathBuf::from("host-sim/tests/data/kuka-wrist"),
            fit: "1-baseline".to_owned(),
            validate: vec!["2-vibrations".to_owned(), "3-vibrations-contact".to_owned()],
            gravity: GravitySource::Accel,
            accel_lag_ms: None,
            lowpass_hz: 10.0,
            rotational: false,
            inertia: false,
            creep_taus: vec![0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0],
            tare_s: 0.25,
        }
    }
}

impl PayloadOptions {
    /// The checks [`analyse`] makes before it reads anything.
    ///
    /// # Errors
    /// `tare_s` negative or NaN, `lowpass_hz` negative or not finite, a
    /// creep time constant not positive and finite.
    pub fn check(&self) -> Result<()> {
        if self.tare_s.is_nan() || self.tare_s < 0.0 {
            bail!("--tare-s must be non-negative");
        }
        if !(self.lowpass_hz >= 0.0 && self.lowpass_hz.is_finite()) {
            bail!("--lowpass-hz must be finite and non-negative");
        }
        if self.creep_taus.iter().any(|t| !(*t > 0.0 && t.is_finite())) {
            bail!("--creep-taus must be positive");
        }
        Ok(())
    }
}

/// Where `g - a` comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum GravitySource {
    /// Accelerometer (specific force), calibrated into the sensor frame.
    Accel,
    /// Orientation matrices: gravity only.
    Orient,
}

// ---------------------------------------------------------------- data

/// A time series of `N`-vectors, time in s.
#[derive(Clone, Debug, PartialEq)]
pub struct Stream<const N: usize> {
    /// Sample times, s, strictly increasing.
    pub t_s: Vec<f64>,
    /// Values.
    pub v: Vec<[f64; N]>,
}

impl<const N: usize> Stream<N> {
    /// Linear interpolation at `t` (held at the ends).
    pub fn at(&self, t: f64) -> [f64; N] {
        let n = self.t_s.len();
        if n == 0 {
            return [f64::NAN; N];
        }
        let i = self.t_s.partition_point(|&x| x <= t);
        if i == 0 {
            return self.v[0];
        }
        if i >= n {
            return self.v[n - 1];
        }
        let (t0, t1) = (self.t_s[i - 1], self.t_s[i]);
        let s = (t - t0) / (t1 - t0);
        let (a, b) = (&self.v[i - 1], &self.v[i]);
        std::array::from_fn(|k| a[k] + s * (b[k] - a[k]))
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t_s.len()
    }

    /// No sample.
    pub fn is_empty(&self) -> bool {
        self.t_s.is_empty()
    }
}

/// Optional time column and rows of a CSV.
type Columns<const N: usize> = (Option<Vec<f64>>, Vec<[f64; N]>);

/// Read the named columns of a CSV into rows (errors name file, line,
/// column).
fn read_columns<const N: usize>(
    path: &Path,
    cols: [&str; N],
    time: Option<&str>,
    min_rows: usize,
) -> Result<Columns<N>> {
    let mut required: Vec<&str> = cols.to_vec();
    if let Some(t) = time {
        required.push(t);
    }
    let schema = Schema::with_required(&required)
        .time_column(time)
        .min_rows(min_rows);
    let log = Log::read_with(path, &schema)?;
    let c: Vec<&[f64]> = cols
        .iter()
        .map(|n| log.col_required(n))
        .collect::<std::result::Result<_, _>>()?;
    let rows = (0..log.len())
        .map(|r| std::array::from_fn(|k| c[k][r]))
        .collect();
    let t = match time {
        Some(t) => Some(log.col_required(t)?.to_vec()),
        None => None,
    };
    Ok((t, rows))
}

/// One measured run: the three streams on a common clock (s since the first
/// wrench sample).
#[derive(Clone, Debug)]
pub struct Run {
    /// Run name (file prefix).
    pub name: String,
    /// Wrench, N and N·m.
    pub wrench: Stream<6>,
    /// Accelerometer, g.
    pub accel_g: Stream<3>,
    /// Orientation `r11..r33`, row major.
    pub orient: Stream<9>,
}

/// Wrench column names in the data set.
pub const WRENCH_COLS: [&str; 6] = ["fx", "fy", "fz", "tx", "ty", "tz"];
/// Accelerometer column names.
pub const ACCEL_COLS: [&str; 3] = ["ax", "ay", "az"];
/// Orientation column names.
pub const ORIENT_COLS: [&str; 9] = [
    "r11", "r12", "r13", "r21", "r22", "r23", "r31", "r32", "r33",
];

/// Load `<dir>/<prefix>_{wrench,accel,orientations}.csv` (timestamps in µs,
/// rebased to s after the first wrench sample; a time that is no longer
/// finite and increasing once rebased is an error naming the file and line).
pub fn load_run(dir: &Path, prefix: &str) -> Result<Run> {
    let p = |s: &str| dir.join(format!("{prefix}_{s}.csv"));
    let (tw, w) = read_columns(&p("wrench"), WRENCH_COLS, Some("t"), 10)?;
    let (ta, a) = read_columns(&p("accel"), ACCEL_COLS, Some("t"), 10)?;
    let (to, o) = read_columns(&p("orientations"), ORIENT_COLS, Some("t"), 10)?;
    let (tw, ta, to) = (
        tw.unwrap_or_default(),
        ta.unwrap_or_default(),
        to.unwrap_or_default(),
    );
    let t0 = tw[0];
    Ok(Run {
        name: prefix.to_owned(),
        wrench: Stream {
            t_s: rebase_us(&p("wrench"), &tw, t0)?,
            v: w,
        },
        accel_g: Stream {
            t_s: rebase_us(&p("accel"), &ta, t0)?,
            v: a,
        },
        orient: Stream {
            t_s: rebase_us(&p("orientations"), &to, t0)?,
            v: o,
        },
    })
}

/// Times in µs to s since `t0_us` (the first wrench sample).
///
/// # Errors
/// A time that is not finite, or no longer after the previous one, once
/// rebased (times too large or too far from `t0_us` for an `f64`), naming
/// the file and the line.
fn rebase_us(path: &Path, t_us: &[f64], t0_us: f64) -> Result<Vec<f64>> {
    let t_s: Vec<f64> = t_us.iter().map(|x| (x - t0_us) * 1e-6).collect();
    for k in 0..t_s.len() {
        let what = if !t_s[k].is_finite() {
            "not a finite time"
        } else if k > 0 && t_s[k] <= t_s[k - 1] {
            "not after the previous sample's"
        } else {
            continue;
        };
        bail!(
            "{}:{}: column \"t\": {:e} µs is {:e} s after the first wrench sample: {what} (times too \
             large or too far apart)",
            path.display(),
            crate::log::line_of_row(k),
            t_us[k],
            t_s[k],
        );
    }
    Ok(t_s)
}

/// The static calibration poses.
#[derive(Clone, Debug)]
pub struct StaticPoses {
    /// Wrench per pose, N and N·m.
    pub wrench: Vec<[f64; 6]>,
    /// Accelerometer per pose, g.
    pub accel_g: Vec<[f64; 3]>,
    /// Gravity in the sensor frame per pose, m/s² (from the file).
    pub gravity_m_s2: Vec<[f64; 3]>,
    /// `r11..r33` per pose.
    pub orient: Vec<[f64; 9]>,
}

/// Load `0-calibration_fts-accel.csv`.
pub fn load_static_poses(path: &Path) -> Result<StaticPoses> {
    let (_, wrench) = read_columns(path, WRENCH_COLS, None, 6)?;
    let (_, accel_g) = read_columns(path, ACCEL_COLS, None, 6)?;
    let (_, gravity_m_s2) = read_columns(path, ["gx", "gy", "gz"], None, 6)?;
    let (_, orient) = read_columns(path, ORIENT_COLS, None, 6)?;
    Ok(StaticPoses {
        wrench,
        accel_g,
        gravity_m_s2,
        orient,
    })
}

/// Per-axis standard deviation of `0-steady-state_wrench.csv` (sensor at
/// rest), N and N·m. An axis whose deviation overflows (finite but huge
/// cells) is an error naming the file and the column.
pub fn steady_state_noise(path: &Path) -> Result<[f64; 6]> {
    let (_, w) = read_columns(path, WRENCH_COLS, None, 10)?;
    let n = w.len() as f64;
    let sd: [f64; 6] = std::array::from_fn(|k| {
        let m = w.iter().map(|r| r[k]).sum::<f64>() / n;
        (w.iter().map(|r| (r[k] - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
    });
    // Finite cells can still overflow the sum or the squares; an infinite
    // standard deviation would silently give its axis a zero weight.
    if let Some(k) = sd.iter().position(|s| !s.is_finite()) {
        bail!(
            "{}: column \"{}\": the standard deviation is {}: values too large",
            path.display(),
            WRENCH_COLS[k],
            sd[k]
        );
    }
    Ok(sd)
}

// ---------------------------------------------------------- conventions

fn mat(r: &[f64; 9]) -> Matrix3<f64> {
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

// ----------------------------------------------------------- kinematics

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

// ------------------------------------------------- identify and evaluate

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
    for (k, (t, w)) in kin.iter().zip(run.wrench.t_s.iter().zip(&run.wrench.v)) {
        let dt = prev.map_or(0.0, |p| t - p) as f32;
        prev = Some(*t);
        let k32 = Kinematics {
            gravity_m_s2: k.gravity_m_s2.map(|v| v as f32),
            accel_m_s2: k.accel_m_s2.map(|v| v as f32),
            omega_rad_s: k.omega_rad_s.map(|v| v as f32),
            alpha_rad_s2: k.alpha_rad_s2.map(|v| v as f32),
        };
        let meas = Wrench::<f32>::from(w.map(|v| v as f32));
        let fe = model
            .estimate(&mut state, &k32, &meas, dt)
            .map_err(|e| anyhow!("{}: estimate at {t:.4} s: {e}", run.name))?;
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

// --------------------------------------------------------------- report

/// Parameters with their standard deviations, for the report.
#[derive(Clone, Debug, Serialize)]
pub struct ParamReport {
    /// Name with unit.
    pub name: String,
    /// Value.
    pub value: f64,
    /// Standard deviation.
    pub std: f64,
    /// `100 std / |value|`.
    pub pct_sigma: f64,
}

fn param_table(fit: &PayloadFit, cfg: &IdentConfig) -> Vec<ParamReport> {
    let mut out = Vec::new();
    let mut push = |name: String, v: f64, s: f64| {
        out.push(ParamReport {
            name,
            value: v,
            std: s,
            pct_sigma: 100.0 * s / v.abs(),
        });
    };
    let (p, s) = (&fit.params, &fit.std_dev);
    for (k, axis) in AXIS_NAMES.iter().enumerate() {
        let unit = if k < 3 { "n" } else { "nm" };
        push(format!("f0_{axis}_{unit}"), p.offset[k], s.offset[k]);
    }
    let n_phi = if cfg.inertia { 10 } else { 4 };
    for (k, name) in INERTIAL_NAMES.iter().enumerate().take(n_phi) {
        push((*name).to_owned(), p.inertial[k], s.inertial[k]);
    }
    for (k, axis) in AXIS_NAMES.iter().enumerate() {
        if cfg.comp.creep_on(k) {
            push(format!("creep_{axis}"), p.creep[k], s.creep[k]);
        }
    }
    for (k, axis) in AXIS_NAMES.iter().enumerate() {
        if cfg.comp.drift_on(k) {
            let unit = if k < 3 { "n_s" } else { "nm_s" };
            push(
                format!("drift_{axis}_{unit}"),
                p.drift_per_s[k],
                s.drift_per_s[k],
            );
        }
    }
    out
}

/// Error statistics of one run.
#[derive(Clone, Debug, Serialize)]
pub struct RunReport {
    /// Run name.
    pub name: String,
    /// Whether the run has contact (then the numbers are not errors).
    pub contact: bool,
    /// Samples.
    pub samples: usize,
    /// RMS of the raw sensor minus its start mean, per axis.
    pub raw: [f64; 6],
    /// RMS of `F_e` with the identified `F_0`.
    pub ident: [f64; 6],
    /// RMS of `F_e` after the start tare (offset tracker).
    pub ident_tare: [f64; 6],
    /// RMS of `F_e` with the selected creep/drift terms, after the tare.
    pub comp_tare: [f64; 6],
    /// RMS of the diagnostic affine map's residual ([`fit_affine_map`] on the
    /// fit run), after the tare.
    pub affine_tare: [f64; 6],
    /// The offset tracker's correction at the end of the tare window: the
    /// zero drift of this run relative to the fit run's `F_0` (base model).
    pub tare_correction: [f64; 6],
    /// Largest `|F_e|` (selected model, after the tare), per axis.
    pub peak: [f64; 6],
}

/// One creep/drift candidate and its scores.
#[derive(Clone, Debug, Serialize)]
pub struct CandidateReport {
    /// Creep time constant, s (`None`: no creep).
    pub creep_tau_s: Option<f32>,
    /// Linear drift offered.
    pub drift: bool,
    /// Axes that kept a creep column after pruning.
    pub creep_axes: String,
    /// Axes that kept a drift column after pruning.
    pub drift_axes: String,
    /// Weighted score on the fit run (in-sample, tracked).
    pub fit_score: f64,
    /// Weighted score on the no-contact validation runs (tracked).
    pub validation_score: f64,
    /// RMSE per axis on the no-contact validation runs (tracked), pooled.
    pub validation_rmse: [f64; 6],
}

/// A run with its estimates (for plots and tests).
pub struct RunEstimates {
    /// The run.
    pub run: Run,
    /// Raw sensor minus its start mean.
    pub raw: Vec<[f64; 6]>,
    /// Base model.
    pub base: Estimate,
    /// Selected creep/drift model.
    pub selected: Estimate,
}

/// Stage `DIR/payload_<run>.csv` per run among the outputs (see `--csv`).
pub fn write_csv(out: &mut Outputs, runs: &[RunEstimates], dir: &Path) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
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
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
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

/// The whole report.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// Orientation convention found on the calibration poses.
    pub convention: Convention,
    /// Accelerometer calibration.
    pub accel_calibration: AccelCalibration,
    /// Steady-state noise std per axis (identification weights are its
    /// inverse).
    pub noise_std: [f64; 6],
    /// Static-pose identification (cross-check).
    pub static_params: Vec<ParamReport>,
    /// Source of `g - a`.
    pub gravity: GravitySource,
    /// IMU lag used, ms.
    pub accel_lag_ms: f64,
    /// Lag curve (lag ms, fit RMSE of the weighted rows), when estimated.
    pub lag_curve: Vec<(f64, f64)>,
    /// Rotational terms included.
    pub rotational: bool,
    /// Low-pass cut-off of wrench and kinematics, Hz (0: none).
    pub lowpass_hz: f64,
    /// Largest |omega| (rad/s) and |alpha| (rad/s²) on the fit run.
    pub max_omega_rad_s: f64,
    /// See `max_omega_rad_s`.
    pub max_alpha_rad_s2: f64,
    /// RMS over the fit run of the rotational force terms
    /// `|alpha x mc + omega x (omega x mc)|`, N, with the identified `mc`.
    pub rot_force_rms_n: f64,
    /// Upper bound of the RMS inertia torque `|I alpha + omega x I omega|`,
    /// N·m, for `|I| <= m r^2` with `r` = 0.1 m.
    pub rot_torque_bound_nm: f64,
    /// Fit run.
    pub fit_run: String,
    /// Samples of the fit run.
    pub fit_samples: u64,
    /// Duration of the fit run, s.
    pub fit_duration_s: f64,
    /// Identification wall time (accumulate + solve) of the base model, s.
    pub ident_time_s: f64,
    /// Condition number of the base model's (weighted, equilibrated) regressor.
    pub condition: f64,
    /// Base model (`F_0`, `m`, `m c`, inertia if asked).
    pub params: Vec<ParamReport>,
    /// Creep/drift candidates.
    pub candidates: Vec<CandidateReport>,
    /// The selected candidate (index into `candidates`).
    pub selected: usize,
    /// Parameters of the selected model.
    pub selected_params: Vec<ParamReport>,
    /// Per-run statistics (fit run first).
    pub runs: Vec<RunReport>,
    /// Contact runs: detected contact interval (|f| > 1.5 N), s.
    pub contact_intervals: Vec<(String, f64, f64)>,
}

fn axes_text(on: &[bool; 6], enabled: bool) -> String {
    let v: Vec<&str> = (0..6)
        .filter(|&k| enabled && on[k])
        .map(|k| AXIS_NAMES[k])
        .collect();
    if v.is_empty() {
        "-".to_owned()
    } else {
        v.join(",")
    }
}

fn is_contact(name: &str) -> bool {
    name.contains("contact")
}

fn ident_config(inertia: bool, weight: [f64; 6], comp: CompConfig) -> IdentConfig {
    IdentConfig {
        inertia,
        comp,
        axis_weight: weight,
        ..IdentConfig::default()
    }
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

/// Run the whole analysis (no output files).
///
/// # Errors
/// The options fail [`PayloadOptions::check`]; a file is missing or bad; a
/// fit or an estimate fails.
pub fn analyse(opts: &PayloadOptions) -> Result<(Report, Vec<RunEstimates>)> {
    opts.check()?;
    let dir = &opts.dir;
    let poses = load_static_poses(&dir.join("0-calibration_fts-accel.csv"))?;
    let noise = steady_state_noise(&dir.join("0-steady-state_wrench.csv"))?;
    if noise.iter().any(|s| s.is_nan() || *s <= 0.0) {
        bail!("0-steady-state_wrench.csv: an axis has zero noise; cannot weight");
    }
    let weight = noise.map(|s| 1.0 / s);
    let conv = check_convention(&poses)?;
    let cal = fit_accel_calibration(&poses)?;
    let stat = static_identification(&poses, weight)?;
    let static_cfg = IdentConfig {
        inertia: false,
        axis_weight: weight,
        ..IdentConfig::default()
    };

    let fit_run = load_run(dir, &opts.fit).with_context(|| format!("loading run {}", opts.fit))?;
    if is_contact(&fit_run.name) {
        bail!(
            "fit run {} has contact; identify on a no-contact run",
            fit_run.name
        );
    }
    let mut val_runs = Vec::new();
    for v in &opts.validate {
        val_runs.push(load_run(dir, v).with_context(|| format!("loading run {v}"))?);
    }

    let (lag_s, lag_curve) = match (opts.accel_lag_ms, opts.gravity) {
        (Some(ms), _) => (ms * 1e-3, Vec::new()),
        (None, GravitySource::Orient) => (0.0, Vec::new()),
        (None, GravitySource::Accel) => {
            let grid: Vec<f64> = (-20..=60).map(|k| f64::from(k) * 0.5e-3).collect();
            let (l, c) = estimate_accel_lag(&fit_run, &conv, &cal, weight, &grid)?;
            (l, c.into_iter().map(|(l, r)| (l * 1e3, r)).collect())
        }
    };
    let kin_opts = KinOptions {
        gravity: opts.gravity,
        accel_lag_s: lag_s,
        rotational: opts.rotational,
        lowpass_hz: (opts.lowpass_hz > 0.0).then_some(opts.lowpass_hz),
    };
    // The lag is estimated on the unfiltered data (the vibration carries the
    // timing); everything from here on sees the filtered wrench.
    let fit_run = filtered_run(&fit_run, &kin_opts);
    let val_runs: Vec<Run> = val_runs
        .iter()
        .map(|r| filtered_run(r, &kin_opts))
        .collect();
    let fit_kin = kinematics(&fit_run, &kin_opts, &conv, &cal);
    let val_kin: Vec<Vec<Kinematics<f64>>> = val_runs
        .iter()
        .map(|r| kinematics(r, &kin_opts, &conv, &cal))
        .collect();

    // Base model.
    let base_cfg = ident_config(opts.inertia, weight, CompConfig::NONE);
    let (base_fit, ident_time_s) = identify(&fit_run, &fit_kin, base_cfg)?;

    // Rotational magnitude on the fit run (always from the orientation).
    let (wst, ast) = angular_rates(&fit_run.orient, conv.transpose);
    let max_w = wst
        .v
        .iter()
        .map(|v| Vector3::from(*v).norm())
        .fold(0.0, f64::max);
    let max_a = ast
        .v
        .iter()
        .map(|v| Vector3::from(*v).norm())
        .fold(0.0, f64::max);
    let mc = Vector3::new(
        base_fit.params.inertial[1],
        base_fit.params.inertial[2],
        base_fit.params.inertial[3],
    );
    let (mut sf, mut st) = (0.0, 0.0);
    for &t in &fit_run.wrench.t_s {
        let w = Vector3::from(wst.at(t));
        let a = Vector3::from(ast.at(t));
        sf += (a.cross(&mc) + w.cross(&w.cross(&mc))).norm_squared();
        let i_bound = base_fit.params.mass_kg().abs() * 0.01;
        st += (i_bound * (a.norm() + w.norm_squared())).powi(2);
    }
    let nf = fit_run.wrench.len() as f64;

    // Creep/drift candidates.
    let mut comps = vec![CompConfig::NONE, CompConfig::all_axes(None, true)];
    for &tau in &opts.creep_taus {
        for drift in [false, true] {
            comps.push(CompConfig::all_axes(Some(tau), drift));
        }
    }
    let nc_val: Vec<usize> = (0..val_runs.len())
        .filter(|&i| !is_contact(&val_runs[i].name))
        .collect();
    let mut candidates = Vec::new();
    let mut models = Vec::new();
    for comp in comps {
        let (fit, cfg) = if comp.n_cols() == 0 {
            (base_fit.clone(), base_cfg)
        } else {
            identify_comp(
                &fit_run,
                &fit_kin,
                ident_config(opts.inertia, weight, comp),
                &base_fit,
            )?
        };
        let model = PayloadModel::new(&fit.params, cfg.comp)?;
        let e_fit = estimate(&fit_run, &fit_kin, &model, opts.tare_s)?;
        let fit_score = weighted_score(&rms(&e_fit.tracked), &noise);
        let mut pooled = Vec::new();
        for &i in &nc_val {
            pooled.extend(estimate(&val_runs[i], &val_kin[i], &model, opts.tare_s)?.tracked);
        }
        let vr = rms(&pooled);
        let validation_score = if pooled.is_empty() {
            fit_score
        } else {
            weighted_score(&vr, &noise)
        };
        candidates.push(CandidateReport {
            creep_tau_s: comp.creep_tau_s,
            drift: comp.drift_axes.iter().any(|d| *d),
            creep_axes: axes_text(&cfg.comp.creep_axes, cfg.comp.creep_tau_s.is_some()),
            drift_axes: axes_text(&cfg.comp.drift_axes, true),
            fit_score,
            validation_score,
            validation_rmse: vr,
        });
        models.push((fit, model, cfg));
    }
    let selected = candidates
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.validation_score.total_cmp(&b.1.validation_score))
        .map(|c| c.0)
        .unwrap_or(0);
    let (sel_fit, sel_model, sel_cfg) = &models[selected];
    let base_model = PayloadModel::new(&base_fit.params, CompConfig::NONE)?;
    let affine = fit_affine_map(&fit_run, &fit_kin)?;

    let mut runs = Vec::new();
    let mut estimates = Vec::new();
    let mut contact_intervals = Vec::new();
    let all: Vec<(&Run, &Vec<Kinematics<f64>>)> = std::iter::once((&fit_run, &fit_kin))
        .chain(val_runs.iter().zip(val_kin.iter()))
        .collect();
    for (run, kin) in all {
        let base = estimate(run, kin, &base_model, opts.tare_s)?;
        let sel = estimate(run, kin, sel_model, opts.tare_s)?;
        let peak =
            std::array::from_fn(|k| sel.tracked.iter().map(|r| r[k].abs()).fold(0.0, f64::max));
        runs.push(RunReport {
            name: run.name.clone(),
            contact: is_contact(&run.name),
            samples: run.wrench.len(),
            raw: rms(&raw_minus_start(run, opts.tare_s)),
            ident: rms(&base.raw_model),
            ident_tare: rms(&base.tracked),
            comp_tare: rms(&sel.tracked),
            affine_tare: rms(&affine_residual(run, kin, &affine, opts.tare_s)),
            tare_correction: base
                .raw_model
                .last()
                .zip(base.tracked.last())
                .map(|(a, b)| std::array::from_fn(|k| a[k] - b[k]))
                .unwrap_or([0.0; 6]),
            peak,
        });
        if is_contact(&run.name) {
            let hits: Vec<f64> = sel
                .tracked
                .iter()
                .zip(&run.wrench.t_s)
                .filter(|(r, _)| Vector3::new(r[0], r[1], r[2]).norm() > 1.5)
                .map(|(_, t)| *t)
                .collect();
            if let (Some(a), Some(b)) = (hits.first(), hits.last()) {
                contact_intervals.push((run.name.clone(), *a, *b));
            }
        }
        estimates.push(RunEstimates {
            run: run.clone(),
            raw: raw_minus_start(run, opts.tare_s),
            base,
            selected: sel,
        });
    }

    let report = Report {
        convention: conv,
        accel_calibration: cal,
        noise_std: noise,
        static_params: param_table(&stat, &static_cfg),
        gravity: opts.gravity,
        accel_lag_ms: lag_s * 1e3,
        lag_curve,
        rotational: opts.rotational,
        lowpass_hz: opts.lowpass_hz,
        max_omega_rad_s: max_w,
        max_alpha_rad_s2: max_a,
        rot_force_rms_n: (sf / nf).sqrt(),
        rot_torque_bound_nm: (st / nf).sqrt(),
        fit_run: fit_run.name.clone(),
        fit_samples: base_fit.samples,
        fit_duration_s: fit_run.wrench.t_s.last().copied().unwrap_or(0.0),
        ident_time_s,
        condition: base_fit.lsq.condition,
        params: param_table(&base_fit, &base_cfg),
        candidates,
        selected,
        selected_params: param_table(sel_fit, sel_cfg),
        runs,
        contact_intervals,
    };
    Ok((report, estimates))
}
