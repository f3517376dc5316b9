//! Identification excitation designed for conditioning (seed 001 Sect. 2.3):
//! a Fourier series of [`HARMONICS`] harmonics ([`Trajectory::Fourier`],
//! which the firmware runs like any other trajectory) whose coefficients
//! minimise the condition number of the identification regressor under the
//! angle, velocity and acceleration limits of the run it replaces.
//!
//! # The regressor it is designed for
//!
//! The JAE (seed 000 Eq. 25) and the tension models (Eq. 22-24) are linear in
//! `[q'', q', sgn(q'), q, 1]` of one slider's position `q`. Both sliders
//! follow the joint angle through their cables, up to a gain, an offset and
//! the stretch the fit itself explains; the design predicts the columns from
//! the *reference* `theta_ref(t)` (its velocity from [`Trajectory::at`], its
//! acceleration by a central difference of that velocity, the sign held
//! below 1 mrad/s as the firmware's sign memory holds it). The condition
//! number is the core's ([`BatchLsq::solve`]): that of the
//! column-equilibrated matrix, so the unknown gains drop out and the figure
//! does not depend on units. It is the same number `identify` prints for a
//! fit on measured rows (`condition`), where the cable's lag and friction
//! change it somewhat; `host-sim excite` reports both predictions, and the
//! report measures the fits.
//!
//! # The search
//!
//! The ten coefficients are first projected onto the series that start at
//! rest (`sum k a_k = 0`, `sum k^2 b_k = 0`: [`Trajectory::validate`]'s
//! rule), then scaled so that the tightest of the three limits is reached
//! (largest excitation, best signal-to-noise; the equilibrated condition
//! number does not change with the scale). Nelder-Mead from
//! [`DesignOptions::restarts`] seeded random starts minimises `log10` of the
//! condition number; the best design is kept. Deterministic for a seed.

use std::path::Path;

use anyhow::{ensure, Context, Result};
use cable_joint::lsq::{BatchLsq, LsqConfig, LsqError};
use cable_joint::trajectory::{Trajectory, HARMONICS};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// Columns of the predicted regressor `[q'', q', sgn(q'), q, 1]`.
pub const COLUMNS: usize = 5;

/// Below this reference speed the predicted sign keeps its last value (the
/// firmware's [`SignMemory`](cable_joint::filter::SignMemory) holds it the
/// same way), rad/s.
const SIGN_HOLD_RAD_S: f64 = 1e-3;

/// Sample rate of every reported predicted condition number, Hz (the
/// condition number of a periodic run does not depend on it once it
/// resolves the fastest harmonic).
pub const PREDICTION_RATE_HZ: f64 = 100.0;

/// Half-step of the central difference that gives the acceleration, s.
const ACC_STEP_S: f64 = 1e-3;

/// Peak magnitudes of a run's reference: its angle from the start angle,
/// its velocity and its acceleration.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Envelope {
    /// Largest `|theta - theta(0)|`, rad.
    pub angle_rad: f64,
    /// Largest `|theta'|`, rad/s.
    pub vel_rad_s: f64,
    /// Largest `|theta''|`, rad/s².
    pub acc_rad_s2: f64,
}

impl Envelope {
    /// Checked as limits: each finite and > 0, the angle at most 10 rad
    /// ([`Trajectory::validate`]); `whose` starts the message.
    pub(crate) fn check_as_limits(&self, whose: &str) -> Result<()> {
        for (name, v) in [
            ("angle", self.angle_rad),
            ("velocity", self.vel_rad_s),
            ("acceleration", self.acc_rad_s2),
        ] {
            ensure!(
                v.is_finite() && v > 0.0,
                "{whose} {name} limit must be finite and > 0, got {v}"
            );
        }
        ensure!(
            self.angle_rad <= 10.0,
            "{whose} angle limit must be at most 10 rad (Trajectory::validate), got {}",
            self.angle_rad
        );
        Ok(())
    }

    /// The largest factor by which `self` can be scaled and stay within
    /// `limits` on all three.
    pub(crate) fn room_in(&self, limits: &Envelope) -> f64 {
        let ratio = |lim: f64, peak: f64| {
            if peak > 0.0 {
                lim / peak
            } else {
                f64::INFINITY
            }
        };
        ratio(limits.angle_rad, self.angle_rad)
            .min(ratio(limits.vel_rad_s, self.vel_rad_s))
            .min(ratio(limits.acc_rad_s2, self.acc_rad_s2))
    }
}

/// One reference sample: angle, velocity, acceleration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Sample {
    pub(crate) angle_rad: f64,
    pub(crate) vel_rad_s: f64,
    pub(crate) acc_rad_s2: f64,
}

/// The reference of consecutive `(trajectory, duration_s)` segments (each
/// evaluated from its own start, as the firmware evaluates a command),
/// sampled at `rate_hz`.
pub(crate) fn samples(segments: &[(Trajectory, f64)], rate_hz: f64) -> Vec<Sample> {
    let mut out = Vec::new();
    for &(tr, duration_s) in segments {
        let n = (duration_s * rate_hz).round() as usize;
        for i in 0..n {
            // The times as the trajectory sees them (f32), so that the
            // difference quotient divides by the step actually taken.
            let t = (i as f64 / rate_hz) as f32;
            let after = (f64::from(t) + ACC_STEP_S) as f32;
            let before = (f64::from(t) - ACC_STEP_S).max(0.0) as f32;
            let vel = |t: f32| f64::from(tr.at(t).vel_rad_s);
            let now = tr.at(t);
            out.push(Sample {
                angle_rad: f64::from(now.angle_rad),
                vel_rad_s: f64::from(now.vel_rad_s),
                acc_rad_s2: (vel(after) - vel(before)) / f64::from(after - before),
            });
        }
    }
    out
}

/// The envelope of `segments`' reference sampled at `rate_hz`.
pub fn envelope(segments: &[(Trajectory, f64)], rate_hz: f64) -> Envelope {
    envelope_of(&samples(segments, rate_hz))
}

pub(crate) fn envelope_of(samples: &[Sample]) -> Envelope {
    let start = samples.first().map_or(0.0, |s| s.angle_rad);
    samples.iter().fold(Envelope::default(), |e, s| Envelope {
        angle_rad: e.angle_rad.max((s.angle_rad - start).abs()),
        vel_rad_s: e.vel_rad_s.max(s.vel_rad_s.abs()),
        acc_rad_s2: e.acc_rad_s2.max(s.acc_rad_s2.abs()),
    })
}

/// Condition number of the equilibrated regressor `[q'', q', sgn(q'), q, 1]`
/// predicted from `segments`' reference sampled at `rate_hz` (the core's
/// least squares computes it). Infinite when a column is all zero.
pub fn condition(segments: &[(Trajectory, f64)], rate_hz: f64) -> f64 {
    condition_of(&samples(segments, rate_hz))
}

fn condition_of(samples: &[Sample]) -> f64 {
    condition_of_rows::<COLUMNS>(|push| for_each_row(samples, |row| push(&row)))
}

/// Condition number of the equilibrated regressor of `N` columns whose
/// rows `rows` hands to its argument, by the core's least squares
/// ([`BatchLsq::solve`]); infinite when a column is all zero or a row is
/// refused.
pub(crate) fn condition_of_rows<const N: usize>(rows: impl FnOnce(&mut dyn FnMut(&[f64]))) -> f64 {
    let config = LsqConfig {
        max_condition: f64::MAX,
    };
    let Ok(mut lsq) = BatchLsq::<N>::new(N, config) else {
        return f64::INFINITY;
    };
    let mut pushed = true;
    rows(&mut |row| pushed &= lsq.push(row, 0.0).is_ok());
    if !pushed {
        return f64::INFINITY;
    }
    match lsq.solve() {
        Ok(fit) => fit.condition,
        Err(LsqError::IllConditioned { condition, .. }) if !condition.is_nan() => condition,
        Err(_) => f64::INFINITY,
    }
}

/// Names of the columns of `[q'', q', sgn(q'), q, 1]`, for messages.
pub const COLUMN_NAMES: [&str; COLUMNS] = ["q''", "q'", "sgn(q')", "q", "1"];

/// The two most correlated columns of the equilibrated regressor predicted
/// from `segments`' reference, and what they alone force on the condition
/// number.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct PairBound {
    /// The columns (indices into [`COLUMN_NAMES`]), first < second.
    pub columns: (usize, usize),
    /// `|cos|` of the angle between them.
    pub correlation: f64,
    /// `sqrt((1 + r) / (1 - r))`: no regressor holding both columns has a
    /// smaller condition number once they are equilibrated (two unit
    /// columns at `|cos| = r` give `|A u|² = 1 ± r` along `u = (e_i ±
    /// e_j) / sqrt 2`, so `sigma_max² >= 1 + r` and `sigma_min² <= 1 - r`).
    pub condition_at_least: f64,
}

/// The pair of columns that bounds the predicted condition number from
/// below ([`PairBound`]): what a design has to decorrelate to go lower.
pub fn pair_bound(segments: &[(Trajectory, f64)], rate_hz: f64) -> PairBound {
    pair_bound_of(&samples(segments, rate_hz))
}

fn pair_bound_of(samples: &[Sample]) -> PairBound {
    PairBound::of_gram(&gram_of(samples))
}

impl PairBound {
    /// The most correlated pair of columns of the regressor whose `A^T A`
    /// is `gram`.
    pub(crate) fn of_gram<const N: usize>(gram: &nalgebra::SMatrix<f64, N, N>) -> Self {
        let mut best = PairBound {
            columns: (0, 1),
            correlation: f64::NAN,
            condition_at_least: f64::NAN,
        };
        for i in 0..N {
            for j in i + 1..N {
                let r = (gram[(i, j)] / (gram[(i, i)] * gram[(j, j)]).sqrt()).abs();
                if r.is_finite() && (best.correlation.is_nan() || r > best.correlation) {
                    best = PairBound {
                        columns: (i, j),
                        correlation: r,
                        condition_at_least: ((1.0 + r) / (1.0 - r)).sqrt(),
                    };
                }
            }
        }
        best
    }
}

/// Standard deviation of each parameter of `[q'', q', sgn(q'), q, 1]` that
/// a fit on `segments`' predicted regressor at `rate_hz` would give with a
/// residual of unit standard deviation: `sqrt(diag((A^T A)^-1))`. The ratio
/// of two runs' figures is the ratio of their parameters' `%sigma` when the
/// noise is the same. Infinite when the columns are dependent.
pub fn unit_std(segments: &[(Trajectory, f64)], rate_hz: f64) -> [f64; COLUMNS] {
    unit_std_of(&samples(segments, rate_hz))
}

fn unit_std_of(samples: &[Sample]) -> [f64; COLUMNS] {
    match gram_of(samples).try_inverse() {
        Some(inv) => std::array::from_fn(|k| inv[(k, k)].max(0.0).sqrt()),
        None => [f64::INFINITY; COLUMNS],
    }
}

/// `A^T A` of the predicted regressor `A` of `samples` (its rows from
/// [`for_each_row`]).
fn gram_of(samples: &[Sample]) -> nalgebra::SMatrix<f64, COLUMNS, COLUMNS> {
    let mut m = nalgebra::SMatrix::<f64, COLUMNS, COLUMNS>::zeros();
    for_each_row(samples, |row| {
        let phi = nalgebra::SVector::<f64, COLUMNS>::from(row);
        m += phi * phi.transpose();
    });
    m
}

/// Each predicted regressor row of `samples`, the sign held as the
/// firmware holds it.
fn for_each_row(samples: &[Sample], mut f: impl FnMut([f64; COLUMNS])) {
    let mut sign = 0.0;
    for s in samples {
        if s.vel_rad_s.abs() > SIGN_HOLD_RAD_S {
            sign = s.vel_rad_s.signum();
        }
        f([s.acc_rad_s2, s.vel_rad_s, sign, s.angle_rad, 1.0]);
    }
}

/// What the search minimises.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Objective {
    /// Seed 001's: the condition number of the equilibrated regressor. It
    /// ignores how much each column moves: a slow series of small
    /// acceleration can be well conditioned and still identify the inertial
    /// term worse than the run it replaces.
    Condition,
    /// The largest ratio of the predicted standard deviations of the
    /// `q''`, `q'` and `q` parameters to those of a reference run of the
    /// same length and rate ([`std_per_row`] of the reference): the ratio
    /// of `%sigma` the identification will see, with the same noise. The
    /// `sgn(q')` and offset parameters are left out: at equal length their
    /// information is the number of rows, whatever the trajectory (their
    /// ratios are reported).
    Sigma {
        /// The reference run's [`std_per_row`].
        reference: [f64; COLUMNS],
    },
}

/// Which [`Objective`] to design for, before the reference run is known.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Criterion {
    /// [`Objective::Sigma`] against the run the excitation replaces.
    Sigma,
    /// [`Objective::Condition`].
    Condition,
}

/// [`unit_std`] times the square root of the rows: the standard deviation
/// per row, so that runs of one length and rate compare directly.
pub fn std_per_row(segments: &[(Trajectory, f64)], rate_hz: f64) -> [f64; COLUMNS] {
    let s = samples(segments, rate_hz);
    let n = (s.len() as f64).sqrt();
    unit_std_of(&s).map(|v| v * n)
}

/// Columns whose information the trajectory sets: `q''`, `q'` and `q`.
const SHAPED: [usize; 3] = [0, 1, 3];

/// What [`design`] designs.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct DesignOptions {
    /// Fundamental frequency, Hz (seed 001: `omega_f = 0.2 pi` rad/s, 0.1 Hz).
    pub base_freq_hz: f64,
    /// Whole periods the run lasts.
    pub periods: u32,
    /// Limits of the reference (angle from the start, velocity,
    /// acceleration).
    pub limits: Envelope,
    /// What the search minimises.
    pub objective: Objective,
    /// Random starts of the search.
    pub restarts: u32,
    /// Seed of the random starts.
    pub seed: u64,
}

impl DesignOptions {
    /// Seed 001's series (0.1 Hz, [`HARMONICS`] harmonics, condition
    /// number), as many whole periods as fit in `duration_s`, under
    /// `limits`.
    pub fn for_run(duration_s: f64, limits: Envelope) -> Self {
        let base_freq_hz = 0.1;
        Self {
            base_freq_hz,
            periods: ((duration_s * base_freq_hz).floor() as u32).max(1),
            limits,
            objective: Objective::Condition,
            restarts: 4,
            seed: 1,
        }
    }

    /// The design of a series of `series_s` that replaces the run
    /// `references`: that run's envelope as the limits and, for
    /// [`Criterion::Sigma`], its predicted standard deviations as the
    /// reference.
    pub fn replacing(
        references: &[(Trajectory, f64)],
        series_s: f64,
        criterion: Criterion,
    ) -> Self {
        let limits = envelope(references, PREDICTION_RATE_HZ);
        let objective = match criterion {
            Criterion::Condition => Objective::Condition,
            Criterion::Sigma => Objective::Sigma {
                reference: std_per_row(references, PREDICTION_RATE_HZ),
            },
        };
        Self {
            objective,
            ..Self::for_run(series_s, limits)
        }
    }

    /// Length of the designed run, s.
    pub fn duration_s(&self) -> f64 {
        f64::from(self.periods) / self.base_freq_hz
    }

    /// The same design at `periods` whole periods of `duration_s`.
    pub fn at_periods(&self, duration_s: f64, periods: u32) -> Self {
        Self {
            base_freq_hz: f64::from(periods) / duration_s,
            periods,
            ..*self
        }
    }

    fn check(&self) -> Result<()> {
        ensure!(
            self.base_freq_hz.is_finite() && self.base_freq_hz > 0.0 && self.base_freq_hz <= 10.0,
            "the excitation's base frequency must be in (0, 10] Hz, got {}",
            self.base_freq_hz
        );
        ensure!(
            self.periods >= 1,
            "the excitation needs at least one period"
        );
        self.limits.check_as_limits("the excitation's")?;
        if let Objective::Sigma { reference } = self.objective {
            ensure!(
                reference.iter().all(|v| v.is_finite() && *v > 0.0),
                "the reference run's predicted standard deviations must be finite and > 0 (is the reference's regressor of full rank?), got {reference:?}"
            );
        }
        ensure!(self.restarts >= 1, "the search needs at least one start");
        Ok(())
    }
}

/// A designed excitation.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Design {
    /// The series, starting at 0 rad at rest.
    pub trajectory: Trajectory,
    /// Its length (whole periods), s.
    pub duration_s: f64,
    /// Predicted condition number over the series alone ([`condition`];
    /// the scenario's hold and return after it are not counted).
    pub condition: f64,
    /// Its envelope: the tightest limit is reached.
    pub envelope: Envelope,
    /// The objective's value at the design (`log10` of the condition
    /// number, or of the largest standard-deviation ratio).
    pub objective: f64,
    /// Objective evaluations the search made.
    pub evaluations: u64,
}

/// Samples per period of the design's objective.
pub(crate) const SAMPLES_PER_PERIOD: f64 = 1000.0;
/// Evaluations per start of the search.
const EVALUATIONS_PER_START: usize = 1500;
/// Free coefficients: sine and cosine of each harmonic.
pub(crate) const DIM: usize = 2 * HARMONICS;

/// The series of coefficients `p` (sines then cosines), projected onto the
/// series that start at rest, centred on 0 rad.
pub(crate) fn at_rest(p: &[f64; DIM], base_freq_hz: f64) -> Trajectory {
    let mut sin_rad = [0.0f32; HARMONICS];
    let mut cos_rad = [0.0f32; HARMONICS];
    let k = |i: usize| (i + 1) as f64;
    // Remove the component along (k) from the sines and along (k^2) from
    // the cosines: the orthogonal projection onto each constraint's plane.
    let (mut ds, mut ns, mut dc, mut nc) = (0.0, 0.0, 0.0, 0.0);
    for i in 0..HARMONICS {
        ds += k(i) * p[i];
        ns += k(i) * k(i);
        dc += k(i) * k(i) * p[HARMONICS + i];
        nc += k(i).powi(4);
    }
    for i in 0..HARMONICS {
        sin_rad[i] = (p[i] - ds / ns * k(i)) as f32;
        cos_rad[i] = (p[HARMONICS + i] - dc / nc * k(i) * k(i)) as f32;
    }
    Trajectory::Fourier {
        offset_rad: 0.0,
        base_freq_hz: base_freq_hz as f32,
        sin_rad,
        cos_rad,
    }
}

/// `tr` (a series centred on 0) with its coefficients scaled by `by`.
pub(crate) fn scaled(tr: Trajectory, by: f64) -> Trajectory {
    match tr {
        Trajectory::Fourier {
            offset_rad,
            base_freq_hz,
            sin_rad,
            cos_rad,
        } => Trajectory::Fourier {
            offset_rad,
            base_freq_hz,
            sin_rad: sin_rad.map(|c| (f64::from(c) * by) as f32),
            cos_rad: cos_rad.map(|c| (f64::from(c) * by) as f32),
        },
        other => other,
    }
}

/// The objective, `log10` of [`Objective`]'s figure for the series of
/// coefficients `p` scaled to the limits, from one period.
fn objective(p: &[f64; DIM], opts: &DesignOptions) -> f64 {
    let tr = at_rest(p, opts.base_freq_hz);
    let period = [(tr, 1.0 / opts.base_freq_hz)];
    let samples = samples(&period, SAMPLES_PER_PERIOD * opts.base_freq_hz);
    let value = match opts.objective {
        Objective::Condition => condition_of(&samples),
        Objective::Sigma { reference } => {
            // The shaped columns scale with the series, their standard
            // deviations inversely (A^T A = D M D with D diagonal).
            let by = envelope_of(&samples).room_in(&opts.limits);
            let rows = (samples.len() as f64).sqrt();
            let std = unit_std_of(&samples);
            SHAPED
                .iter()
                .map(|&k| std[k] * rows / by / reference[k])
                .fold(0.0, f64::max)
        }
    };
    if value.is_finite() && value > 0.0 {
        value.log10()
    } else {
        f64::MAX
    }
}

/// Nelder-Mead from `start` with initial steps `step`: the best point and
/// its value after `budget` evaluations.
pub(crate) fn nelder_mead<const D: usize>(
    f: &mut dyn FnMut(&[f64; D]) -> f64,
    start: [f64; D],
    step: f64,
    budget: usize,
) -> ([f64; D], f64) {
    let mut simplex: Vec<([f64; D], f64)> = Vec::with_capacity(D + 1);
    simplex.push((start, f(&start)));
    for i in 0..D {
        let mut x = start;
        x[i] += step;
        simplex.push((x, f(&x)));
    }
    let mut evaluations = D + 1;
    let along = |a: &[f64; D], b: &[f64; D], t: f64| -> [f64; D] {
        std::array::from_fn(|i| a[i] + t * (b[i] - a[i]))
    };
    while evaluations < budget {
        simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
        let (worst, worst_f) = simplex[D];
        let centroid: [f64; D] =
            std::array::from_fn(|i| simplex[..D].iter().map(|v| v.0[i]).sum::<f64>() / D as f64);
        let reflected = along(&worst, &centroid, 2.0);
        let fr = f(&reflected);
        evaluations += 1;
        if fr < simplex[0].1 {
            let expanded = along(&worst, &centroid, 3.0);
            let fe = f(&expanded);
            evaluations += 1;
            simplex[D] = if fe < fr {
                (expanded, fe)
            } else {
                (reflected, fr)
            };
        } else if fr < simplex[D - 1].1 {
            simplex[D] = (reflected, fr);
        } else {
            let contracted = along(&worst, &centroid, if fr < worst_f { 1.5 } else { 0.5 });
            let fc = f(&contracted);
            evaluations += 1;
            if fc < fr.min(worst_f) {
                simplex[D] = (contracted, fc);
            } else {
                // Shrink towards the best vertex.
                let best = simplex[0].0;
                for v in simplex.iter_mut().skip(1) {
                    v.0 = along(&best, &v.0, 0.5);
                    v.1 = f(&v.0);
                }
                evaluations += D;
            }
        }
    }
    simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
    simplex[0]
}

/// Nelder-Mead from `restarts` (at least one) random starts in `[-1,
/// 1]^D` drawn from `seed`, `budget` evaluations each: the best point, its
/// value and the evaluations made.
pub(crate) fn search<const D: usize>(
    f: &mut dyn FnMut(&[f64; D]) -> f64,
    restarts: u32,
    seed: u64,
    budget: usize,
) -> ([f64; D], f64, u64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut evaluations = 0u64;
    let mut counted = |p: &[f64; D]| {
        evaluations += 1;
        f(p)
    };
    let mut start = || -> [f64; D] { std::array::from_fn(|_| rng.gen_range(-1.0..1.0)) };
    let mut best = nelder_mead(&mut counted, start(), 0.5, budget);
    for _ in 1..restarts {
        let found = nelder_mead(&mut counted, start(), 0.5, budget);
        if found.1 < best.1 {
            best = found;
        }
    }
    (best.0, best.1, evaluations)
}

/// The whole numbers of periods of `duration_s` at each of
/// [`BASE_FREQS_HZ`] (at least one, repeats dropped).
fn periods_to_try(duration_s: f64) -> Result<Vec<u32>> {
    ensure!(
        duration_s.is_finite() && duration_s > 0.0,
        "the excitation's length must be > 0 s, got {duration_s}"
    );
    let mut periods: Vec<u32> = BASE_FREQS_HZ
        .iter()
        .map(|f| ((duration_s * f).round() as u32).max(1))
        .collect();
    periods.dedup();
    Ok(periods)
}

/// Design the excitation: the series of least predicted condition number,
/// scaled to the limits.
pub fn design(opts: &DesignOptions) -> Result<Design> {
    opts.check()?;
    let (p, value, evaluations) = search(
        &mut |p: &[f64; DIM]| objective(p, opts),
        opts.restarts,
        opts.seed,
        EVALUATIONS_PER_START,
    );
    let unit = at_rest(&p, opts.base_freq_hz);
    let period_s = 1.0 / opts.base_freq_hz;
    let rate_hz = SAMPLES_PER_PERIOD * opts.base_freq_hz;
    let unit_envelope = envelope(&[(unit, period_s)], rate_hz);
    // A thousandth below the limit: the sampled peak is within 1e-4 of the
    // true one at 1000 samples per period of the fifth harmonic's 200.
    let by = unit_envelope.room_in(&opts.limits) * 0.999;
    ensure!(
        by.is_finite() && by > 0.0,
        "the designed series does not move (every coefficient is zero)"
    );
    let trajectory = scaled(unit, by);
    trajectory
        .validate()
        .map_err(|e| anyhow::anyhow!("the designed series is not a valid trajectory: {e}"))?;
    let duration_s = opts.duration_s();
    let run = [(trajectory, duration_s)];
    Ok(Design {
        trajectory,
        duration_s,
        condition: condition(&run, PREDICTION_RATE_HZ),
        envelope: envelope(&run, rate_hz),
        objective: value,
        evaluations,
    })
}

impl Design {
    /// The series' fundamental frequency, Hz (0 if it is not a series).
    pub fn trajectory_base_freq_hz(&self) -> f64 {
        match self.trajectory {
            Trajectory::Fourier { base_freq_hz, .. } => f64::from(base_freq_hz),
            _ => 0.0,
        }
    }
}

/// Fundamental frequencies [`design_over_frequencies`] tries, Hz: seed 001's
/// 0.1 Hz and others up to 0.5 Hz (whose fifth harmonic, 2.5 Hz, is still
/// well inside the joint's bandwidth).
pub const BASE_FREQS_HZ: [f64; 7] = [0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.5];

/// [`design`] at each of [`BASE_FREQS_HZ`] rounded to whole periods of
/// `duration_s`; the design of least objective.
pub fn design_over_frequencies(opts: &DesignOptions, duration_s: f64) -> Result<Design> {
    let (best, evaluations) = best_over_periods(
        duration_s,
        |p| design(&opts.at_periods(duration_s, p)),
        |d| (d.objective, d.evaluations),
    )?;
    Ok(Design {
        evaluations,
        ..best
    })
}

/// `design_at(n)` for each whole number `n` of periods of `duration_s` at
/// [`BASE_FREQS_HZ`]: the design of least score, and the evaluations of
/// all (`key` gives a design's score and evaluations).
pub(crate) fn best_over_periods<T>(
    duration_s: f64,
    mut design_at: impl FnMut(u32) -> Result<T>,
    key: impl Fn(&T) -> (f64, u64),
) -> Result<(T, u64)> {
    let mut best: Option<T> = None;
    let mut evaluations = 0;
    for n in periods_to_try(duration_s)? {
        let d = design_at(n)?;
        evaluations += key(&d).1;
        if best.as_ref().is_none_or(|b| key(&d).0 < key(b).0) {
            best = Some(d);
        }
    }
    let best = best.ok_or_else(|| anyhow::anyhow!("no base frequency to try"))?;
    Ok((best, evaluations))
}

/// The design as the TOML file `host-sim excite` writes and `--excitation`
/// reads.
pub fn to_toml(design: &Design) -> Result<String> {
    Ok(toml::to_string_pretty(design)?)
}

/// Read a design written by [`to_toml`]: its trajectory passes
/// [`Trajectory::validate`] and its duration is within (0, 1e5] s, or the
/// error names the file and what is wrong.
pub fn load(path: &Path) -> Result<Design> {
    crate::output::note_input(path);
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("reading the excitation {}", path.display()))?;
    let design: Design = toml::from_str(&text)
        .with_context(|| format!("parsing the excitation {}", path.display()))?;
    design
        .trajectory
        .validate()
        .map_err(|e| anyhow::anyhow!("the excitation {}: `trajectory`: {e}", path.display()))?;
    ensure!(
        design.duration_s.is_finite() && design.duration_s > 0.0 && design.duration_s <= 1e5,
        "the excitation {}: `duration_s` must be in (0, 1e5] s, got {}",
        path.display(),
        design.duration_s
    );
    Ok(design)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sine(amplitude_rad: f32, freq_hz: f32) -> Trajectory {
        Trajectory::Sine {
            offset_rad: 0.0,
            amplitude_rad,
            freq_hz,
        }
    }

    #[test]
    fn a_single_sine_is_ill_conditioned_because_its_acceleration_is_its_angle() {
        // q'' = -w^2 q exactly: two columns of the regressor are parallel.
        let c = condition(&[(sine(0.5, 0.5), 20.0)], 200.0);
        assert!(c > 1e3, "condition {c}");
        // Two sines of different frequencies break the dependence.
        let c2 = condition(&[(sine(0.5, 0.5), 10.0), (sine(0.5, 0.23), 10.0)], 200.0);
        assert!(c2 < c / 10.0, "{c2} vs {c}");
    }

    /// A sine's velocity and its sign correlate `2 sqrt 2 / pi` (0.90), so
    /// no run of sines at constant speed sign changes goes under 4.36; the
    /// pair bound of any run is at most its condition number, and a
    /// single sine's is its acceleration against its angle (parallel).
    #[test]
    fn the_pair_bound_is_the_most_correlated_columns_and_never_above_the_condition() {
        // Whole periods of two sines of equal peak speed.
        let two = [(sine(0.5, 0.5), 10.0), (sine(1.0, 0.25), 8.0)];
        let b = pair_bound(&two, 200.0);
        assert_eq!(b.columns, (1, 2), "{b:?}");
        let r = 2.0 * 2.0_f64.sqrt() / std::f64::consts::PI;
        assert!((b.correlation - r).abs() < 0.01, "{b:?}");
        assert!((b.condition_at_least - 4.36).abs() < 0.1, "{b:?}");
        assert!(b.condition_at_least <= condition(&two, 200.0));
        let one = pair_bound(&[(sine(0.5, 0.5), 20.0)], 200.0);
        assert_eq!(one.columns, (0, 3), "{one:?}");
        assert!(one.correlation > 0.999, "{one:?}");
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..5 {
            let p: [f64; DIM] = std::array::from_fn(|_| rng.gen_range(-1.0..1.0));
            let run = [(at_rest(&p, 0.1), 20.0)];
            let (b, c) = (pair_bound(&run, 100.0), condition(&run, 100.0));
            assert!(
                b.condition_at_least <= c * (1.0 + 1e-9),
                "{b:?} against {c}"
            );
        }
    }

    #[test]
    fn the_envelope_of_a_sine_is_its_amplitude_and_its_derivatives() {
        let e = envelope(&[(sine(0.5, 0.5), 4.0)], 1000.0);
        let w = std::f64::consts::PI;
        assert!((e.angle_rad - 0.5).abs() < 1e-4, "{e:?}");
        assert!((e.vel_rad_s - 0.5 * w).abs() < 1e-3, "{e:?}");
        assert!((e.acc_rad_s2 - 0.5 * w * w).abs() < 1e-2, "{e:?}");
    }

    #[test]
    fn the_projection_gives_a_series_that_starts_at_rest() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..20 {
            let p: [f64; DIM] = std::array::from_fn(|_| rng.gen_range(-1.0..1.0));
            let tr = at_rest(&p, 0.2);
            assert_eq!(tr.validate(), Ok(()), "{tr:?}");
            let s = samples(&[(tr, 0.01)], 1000.0);
            assert!(s[0].angle_rad.abs() < 1e-9 && s[0].vel_rad_s.abs() < 1e-5);
        }
    }

    /// Limits of the small designs the tests make.
    const LIMITS: Envelope = Envelope {
        angle_rad: 0.5,
        vel_rad_s: 1.5,
        acc_rad_s2: 4.0,
    };

    #[test]
    fn the_design_beats_random_series_at_rest_and_keeps_every_limit() {
        let opts = DesignOptions {
            restarts: 3,
            ..DesignOptions::for_run(20.0, LIMITS)
        };
        let d = design(&opts).unwrap();
        assert_eq!(d.duration_s, 20.0);
        let e = d.envelope;
        assert!(
            e.angle_rad <= 0.5 && e.vel_rad_s <= 1.5 && e.acc_rad_s2 <= 4.0,
            "{e:?}"
        );
        let tight = [e.angle_rad / 0.5, e.vel_rad_s / 1.5, e.acc_rad_s2 / 4.0];
        assert!(
            tight.iter().any(|&r| r > 0.99),
            "no limit reached: {tight:?}"
        );
        // Better than any of a few random series at rest.
        let mut rng = ChaCha8Rng::seed_from_u64(99);
        for _ in 0..10 {
            let p: [f64; DIM] = std::array::from_fn(|_| rng.gen_range(-1.0..1.0));
            let random = condition(&[(at_rest(&p, 0.1), 20.0)], 100.0);
            assert!(d.condition < random, "{} vs random {random}", d.condition);
        }
        assert_eq!(design(&opts).unwrap(), d, "deterministic for a seed");
    }

    #[test]
    fn a_design_survives_its_file_and_a_bad_file_is_refused_by_name() {
        let opts = DesignOptions {
            restarts: 1,
            ..DesignOptions::for_run(10.0, LIMITS)
        };
        let d = design(&opts).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("excitation.toml");
        std::fs::write(&path, to_toml(&d).unwrap()).unwrap();
        assert_eq!(load(&path).unwrap(), d);
        // A series that does not start at rest.
        let mut moving = d;
        if let Trajectory::Fourier { sin_rad, .. } = &mut moving.trajectory {
            sin_rad[0] += 0.3;
        }
        std::fs::write(&path, to_toml(&moving).unwrap()).unwrap();
        let e = format!("{:#}", load(&path).unwrap_err());
        assert!(
            e.contains("excitation.toml") && e.contains("start at rest"),
            "{e}"
        );
        let long = to_toml(&d)
            .unwrap()
            .replace("duration_s = 10.0", "duration_s = -1.0");
        std::fs::write(&path, long).unwrap();
        let e = format!("{:#}", load(&path).unwrap_err());
        assert!(e.contains("duration_s"), "{e}");
    }

    #[test]
    fn design_refuses_limits_it_cannot_meet() {
        let bad = DesignOptions::for_run(
            20.0,
            Envelope {
                angle_rad: 0.0,
                vel_rad_s: 1.0,
                acc_rad_s2: 1.0,
            },
        );
        let e = design(&bad).unwrap_err().to_string();
        assert!(e.contains("angle limit"), "{e}");
    }

    #[test]
    fn the_sigma_objective_beats_its_reference_on_every_shaped_column() {
        let reference = [
            (sine(0.2, 0.2), 10.0),
            (
                Trajectory::Complex {
                    amplitude_rad: 0.2,
                    base_freq_hz: 0.2,
                },
                10.0,
            ),
        ];
        let limits = envelope(&reference, PREDICTION_RATE_HZ);
        let opts = DesignOptions {
            objective: Objective::Sigma {
                reference: std_per_row(&reference, PREDICTION_RATE_HZ),
            },
            restarts: 2,
            ..DesignOptions::for_run(20.0, limits)
        };
        let d = design_over_frequencies(&opts, 20.0).unwrap();
        let (a, b) = (
            unit_std(&reference, PREDICTION_RATE_HZ),
            unit_std(&[(d.trajectory, d.duration_s)], PREDICTION_RATE_HZ),
        );
        for k in SHAPED {
            assert!(b[k] < a[k], "column {k}: {} vs reference {}", b[k], a[k]);
        }
    }
}
