//! Reading the data set: the three streams of a run on one clock, the
//! static calibration poses and the steady-state noise (errors name the
//! file, the line and the column).

use std::path::Path;

use anyhow::{bail, Result};
use nalgebra::Matrix3;

use crate::log::{Log, Schema};

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
    check_rotations(&p("orientations"), &o)?;
    check_wrench(&p("wrench"), &w)?;
    check_accel(&p("accel"), &a)?;
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

/// Largest magnitude a force cell may have, N: beyond the range of any
/// six-axis force sensor made for a robot's wrist (the largest reach tens
/// of kilonewtons), so a cell past it is another unit or a corrupt cell.
pub const MAX_FORCE_N: f64 = 1e5;
/// Largest magnitude of a torque cell, N·m (as [`MAX_FORCE_N`]).
pub const MAX_TORQUE_NM: f64 = 1e4;
/// Largest magnitude of an accelerometer cell, g (MEMS accelerometers
/// reach a few hundred g).
pub const MAX_ACCEL_G: f64 = 1e3;
/// Largest magnitude of a gravity cell of the static poses, m/s².
pub const MAX_GRAVITY_M_S2: f64 = 100.0;

/// Every cell of `rows` (columns `names`) within `limit` in magnitude;
/// the error names the file, the line and the column.
fn check_magnitudes<const N: usize>(
    path: &Path,
    names: [&str; N],
    rows: &[[f64; N]],
    limit: impl Fn(usize) -> (f64, &'static str),
) -> Result<()> {
    for (k, r) in rows.iter().enumerate() {
        for (c, v) in r.iter().enumerate() {
            let (max, unit) = limit(c);
            if v.abs() > max {
                bail!(
                    "{}: line {}: column \"{}\" = {v:e} {unit} is beyond any sensor's range \
                     (at most {max:e} {unit}): check the file's units, or a corrupt cell",
                    path.display(),
                    crate::log::line_of_row(k),
                    names[c]
                );
            }
        }
    }
    Ok(())
}

/// [`check_magnitudes`] for a wrench (forces then torques).
fn check_wrench(path: &Path, rows: &[[f64; 6]]) -> Result<()> {
    check_magnitudes(path, WRENCH_COLS, rows, |c| {
        if c < 3 {
            (MAX_FORCE_N, "N")
        } else {
            (MAX_TORQUE_NM, "N·m")
        }
    })
}

/// [`check_magnitudes`] for an accelerometer, g.
fn check_accel(path: &Path, rows: &[[f64; 3]]) -> Result<()> {
    check_magnitudes(path, ACCEL_COLS, rows, |_| (MAX_ACCEL_G, "g"))
}

/// Largest departure of an orientation row from a rotation that is taken
/// as rounding: `|R^T R - I|` per entry and `|det R - 1|`. The data set's
/// rows depart by about 1.4e-6 (six decimals); a row beyond this is not an
/// orientation at all (a corrupt cell, a zero matrix).
pub const ROTATION_TOLERANCE: f64 = 1e-3;

/// Each row `r11..r33` of `path` is a rotation within
/// [`ROTATION_TOLERANCE`]; the error names the file, the line and how far
/// the row is from one.
fn check_rotations(path: &Path, rows: &[[f64; 9]]) -> Result<()> {
    for (k, r) in rows.iter().enumerate() {
        let m = super::calib::mat(r);
        let off = (m.transpose() * m - Matrix3::identity()).abs().max();
        let det = m.determinant();
        // Not `>`: a NaN (an overflowed product) is refused as well.
        if !(off <= ROTATION_TOLERANCE && (det - 1.0).abs() <= ROTATION_TOLERANCE) {
            bail!(
                "{}: line {}: r11..r33 is not a rotation (|R^T R - I| up to {off:.3e}, det \
                 {det:.6e}; a rotation's are 0 and 1 within {ROTATION_TOLERANCE:e})",
                path.display(),
                crate::log::line_of_row(k)
            );
        }
    }
    Ok(())
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
    check_time_gaps(path, &t_s)?;
    Ok(t_s)
}

/// Most a sample step may exceed the stream's median step: a step a
/// thousand times longer is not a dropped sample but a corrupt time (the
/// last row's 1e30 µs made a 6 s run last 1e24 s, and a no-contact window
/// half of that).
const MAX_STEP_OVER_MEDIAN: f64 = 1000.0;

/// No step of `t_s` (increasing) longer than [`MAX_STEP_OVER_MEDIAN`]
/// times the median step; the error names the file and the line.
fn check_time_gaps(path: &Path, t_s: &[f64]) -> Result<()> {
    let Some(median_s) = crate::derive::median_period_s(t_s) else {
        return Ok(());
    };
    let limit_s = MAX_STEP_OVER_MEDIAN * median_s;
    let steps: Vec<f64> = t_s.windows(2).map(|w| w[1] - w[0]).collect();
    if let Some(k) = steps.iter().position(|d| *d > limit_s) {
        bail!(
            "{}: line {}: column \"t\" jumps {:e} s after the sample before, more than \
             {MAX_STEP_OVER_MEDIAN} times the stream's median step ({median_s:e} s): a corrupt time, \
             or two recordings in one file",
            path.display(),
            crate::log::line_of_row(k + 1),
            steps[k]
        );
    }
    Ok(())
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
    check_rotations(path, &orient)?;
    check_wrench(path, &wrench)?;
    check_accel(path, &accel_g)?;
    check_magnitudes(path, ["gx", "gy", "gz"], &gravity_m_s2, |_| {
        (MAX_GRAVITY_M_S2, "m/s²")
    })?;
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
    check_wrench(path, &w)?;
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
