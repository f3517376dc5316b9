//! Statistics of errors and residuals, one place for the whole host crate:
//!
//! * [`Acc`] / [`Summary`]: running moments of a signal over a run (the
//!   simulator's recorders, the report, `estimate`), merged across runs with
//!   [`Acc::merge`] or, from summaries alone, [`band`];
//! * [`ErrorStats`]: a fitted model's error over the rows of a fit, with its
//!   unit (`identify`, the residual loop);
//! * [`correlation_time`]: the integrated autocorrelation time of a residual;
//! * [`GripStats`]: a grip under force control judged on the true force
//!   ([`grip_stats_of`]; the single joint's `grip` scenario and the wrist).

use serde::Serialize;

/// Degrees per radian.
pub const DEG_PER_RAD: f64 = 180.0 / std::f64::consts::PI;

/// Running statistics of a signal.
#[derive(Clone, Copy, Debug, Default)]
pub struct Acc {
    n: u64,
    sum: f64,
    sum_abs: f64,
    sum_sq: f64,
    max: f64,
    min: f64,
}

impl Acc {
    /// Samples counted.
    pub fn n(&self) -> u64 {
        self.n
    }

    /// The statistics in degrees of a signal in radians, if any sample.
    pub fn degrees(&self) -> Option<Summary> {
        (self.n > 0).then(|| self.summary(DEG_PER_RAD))
    }

    /// Add a value (non-finite values are skipped).
    pub fn push(&mut self, v: f64) {
        if !v.is_finite() {
            return;
        }
        if self.n == 0 {
            self.max = v;
            self.min = v;
        }
        self.n += 1;
        self.sum += v;
        self.sum_abs += v.abs();
        self.sum_sq += v * v;
        self.max = self.max.max(v);
        self.min = self.min.min(v);
    }

    /// Merge another accumulator into this one.
    pub fn merge(&mut self, o: &Acc) {
        if o.n == 0 {
            return;
        }
        if self.n == 0 {
            *self = *o;
            return;
        }
        self.n += o.n;
        self.sum += o.sum;
        self.sum_abs += o.sum_abs;
        self.sum_sq += o.sum_sq;
        self.max = self.max.max(o.max);
        self.min = self.min.min(o.min);
    }

    /// The statistics, each value multiplied by `scale` (NaN when empty).
    pub fn summary(&self, scale: f64) -> Summary {
        if self.n == 0 {
            return Summary {
                n: 0,
                mean: f64::NAN,
                mean_abs: f64::NAN,
                rms: f64::NAN,
                max: f64::NAN,
                min: f64::NAN,
            };
        }
        let n = self.n as f64;
        Summary {
            n: self.n,
            mean: self.sum / n * scale,
            mean_abs: self.sum_abs / n * scale.abs(),
            rms: (self.sum_sq / n).sqrt() * scale.abs(),
            max: if scale >= 0.0 { self.max } else { self.min } * scale,
            min: if scale >= 0.0 { self.min } else { self.max } * scale,
        }
    }
}

/// Statistics of an error signal (`max`/`min` signed; NaN when `n == 0`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Summary {
    /// Samples.
    pub n: u64,
    /// Mean.
    pub mean: f64,
    /// Mean of the absolute value.
    pub mean_abs: f64,
    /// Root mean square.
    pub rms: f64,
    /// Largest value.
    pub max: f64,
    /// Smallest value.
    pub min: f64,
}

impl Summary {
    /// Largest absolute value.
    pub fn max_abs(&self) -> f64 {
        self.max.abs().max(self.min.abs())
    }
}

/// Accumulate the f_ext estimate of several cases' regions into one band.
pub fn band<'a>(cases: impl IntoIterator<Item = &'a Summary>) -> Summary {
    // Recombine from the summaries: n-weighted mean and rms, extremes.
    let mut n = 0u64;
    let (mut s, mut sa, mut sq) = (0.0, 0.0, 0.0);
    let (mut max, mut min) = (f64::NEG_INFINITY, f64::INFINITY);
    for c in cases {
        if c.n == 0 {
            continue;
        }
        let k = c.n as f64;
        n += c.n;
        s += c.mean * k;
        sa += c.mean_abs * k;
        sq += c.rms * c.rms * k;
        max = max.max(c.max);
        min = min.min(c.min);
    }
    if n == 0 {
        return Acc::default().summary(1.0);
    }
    let k = n as f64;
    Summary {
        n,
        mean: s / k,
        mean_abs: sa / k,
        rms: (sq / k).sqrt(),
        max,
        min,
    }
}

/// Error statistics of a model's output against the measured one
/// (`model - measured`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ErrorStats {
    /// Samples.
    pub n: usize,
    /// Mean error.
    pub mean: f64,
    /// Mean absolute error.
    pub mean_abs: f64,
    /// Largest error.
    pub max: f64,
    /// Smallest (most negative) error.
    pub min: f64,
    /// Root-mean-square error.
    pub rmse: f64,
    /// Unit of the numbers.
    pub unit: &'static str,
}

impl ErrorStats {
    /// Statistics of `errors`, each multiplied by `scale`.
    pub fn of(errors: impl IntoIterator<Item = f64>, scale: f64, unit: &'static str) -> Self {
        let (mut n, mut sum, mut sum_abs, mut sum_sq) = (0usize, 0.0, 0.0, 0.0);
        let (mut max, mut min) = (f64::NEG_INFINITY, f64::INFINITY);
        for e in errors {
            let e = e * scale;
            n += 1;
            sum += e;
            sum_abs += e.abs();
            sum_sq += e * e;
            max = max.max(e);
            min = min.min(e);
        }
        let d = n.max(1) as f64;
        Self {
            n,
            mean: sum / d,
            mean_abs: sum_abs / d,
            max: if n > 0 { max } else { f64::NAN },
            min: if n > 0 { min } else { f64::NAN },
            rmse: (sum_sq / d).sqrt(),
            unit,
        }
    }

    /// Largest absolute error.
    pub fn max_abs(&self) -> f64 {
        self.max.abs().max(self.min.abs())
    }

    /// The same statistics of the errors multiplied by `k` (a change of
    /// unit; the unit's name is the caller's to set).
    pub fn scaled(&self, k: f64) -> Self {
        Self {
            mean: self.mean * k,
            mean_abs: self.mean_abs * k,
            max: self.max * k,
            min: self.min * k,
            rmse: self.rmse * k,
            ..*self
        }
    }
}

/// The least and the greatest finite value of `values` (blank cells,
/// NaN and infinities left out); `None` when there is none.
pub fn finite_range(values: impl IntoIterator<Item = f64>) -> Option<(f64, f64)> {
    values
        .into_iter()
        .filter(|v| v.is_finite())
        .fold(None, |r, v| match r {
            None => Some((v, v)),
            Some((lo, hi)) => Some((f64::min(lo, v), f64::max(hi, v))),
        })
}

/// Root mean square of `v` (NaN when empty).
pub fn rms(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
}

/// Integrated autocorrelation time of a series, in samples, by batch
/// means: for blocks of `L = 1, 2, 4, ...` samples (at least 20 blocks),
/// `tau_L = L var(block means) / var(samples)`; the largest is returned. It
/// is 1 for white noise and about the correlation length for a correlated
/// series, and unlike a truncated sum of autocorrelations it is not fooled
/// by an oscillating component (the velocity loop's) on top of a slow one.
pub fn correlation_time(x: &[f64]) -> f64 {
    let n = x.len();
    if n < 40 {
        return 1.0;
    }
    let mean = x.iter().sum::<f64>() / n as f64;
    let var = x.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n as f64;
    if var.is_nan() || var <= 0.0 {
        return 1.0;
    }
    let mut tau = 1.0f64;
    let mut len = 2;
    while n / len >= 20 {
        let blocks = n / len;
        let var_means = x
            .chunks_exact(len)
            .map(|b| {
                let m = b.iter().sum::<f64>() / len as f64 - mean;
                m * m
            })
            .sum::<f64>()
            / blocks as f64;
        tau = tau.max(len as f64 * var_means / var);
        len *= 2;
    }
    tau
}

/// What a grip under force control measured, judged on the true contact
/// force.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct GripStats {
    /// Set point, N.
    pub set_n: f64,
    /// Mean true contact force over the grip's last second, N.
    pub steady_true_n: f64,
    /// Its error, `100 (true - set) / set`, %.
    pub steady_error_pct: f64,
    /// Largest true contact force under force control above the set point,
    /// `100 (max - set) / set` (0 if never above), %.
    pub overshoot_pct: f64,
    /// Time from the grip command until the true force enters ±5 % of the
    /// set point for good, s (`None`: it never does).
    pub settling_s: Option<f64>,
    /// Mean of the regulated estimate over the last second, N.
    pub steady_est_n: f64,
    /// Mean bound over the last second, N: the true force the estimate can
    /// promise at the set point.
    pub steady_lo_n: f64,
    /// Its upper end, N.
    pub steady_hi_n: f64,
    /// Share of the last second's ticks whose true force lies in the bound.
    pub steady_coverage: f64,
    /// The first fault latched (which joint, on the wrist), if any.
    pub fault: Option<String>,
}

/// One tick of a grip: the true force, the regulated estimate and its bound,
/// in the set point's direction.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GripSample {
    /// Time, s.
    pub t_s: f64,
    /// True contact force, N.
    pub true_n: f64,
    /// The estimate the grip law regulates, N.
    pub est_n: f64,
    /// Lower end of its bound, N.
    pub lo_n: f64,
    /// Upper end of its bound, N.
    pub hi_n: f64,
}

/// Judge the ticks under force control (`grip`, in time order) against a
/// positive set point `set_n`; the fault is the caller's to fill in.
pub fn grip_stats_of(grip: &[GripSample], set_n: f64) -> GripStats {
    let (t0, t_end) = match (grip.first(), grip.last()) {
        (Some(a), Some(b)) => (a.t_s, b.t_s),
        _ => return GripStats::default(),
    };
    let last: Vec<&GripSample> = grip.iter().filter(|t| t.t_s > t_end - 1.0).collect();
    let n = last.len().max(1) as f64;
    let mean = |f: &dyn Fn(&GripSample) -> f64| last.iter().map(|t| f(t)).sum::<f64>() / n;
    let steady_true_n = mean(&|t| t.true_n);
    let peak = grip.iter().map(|t| t.true_n).fold(0.0, f64::max);
    let band = 0.05 * set_n;
    let settling_s = match grip.iter().rposition(|t| (t.true_n - set_n).abs() > band) {
        Some(k) if k + 1 < grip.len() => Some(grip[k + 1].t_s - t0),
        Some(_) => None,
        None => Some(0.0),
    };
    GripStats {
        set_n,
        steady_true_n,
        steady_error_pct: 100.0 * (steady_true_n - set_n) / set_n,
        overshoot_pct: (100.0 * (peak - set_n) / set_n).max(0.0),
        settling_s,
        steady_est_n: mean(&|t| t.est_n),
        steady_lo_n: mean(&|t| t.lo_n),
        steady_hi_n: mean(&|t| t.hi_n),
        steady_coverage: last
            .iter()
            .filter(|t| t.lo_n <= t.true_n + 1e-6 && t.true_n - 1e-6 <= t.hi_n)
            .count() as f64
            / n,
        fault: None,
    }
}

#[cfg(test)]
pub(crate) mod test_rng {
    /// xorshift64*, uniform in [-1, 1).
    pub(crate) struct Rng(pub(crate) u64);
    impl Rng {
        pub(crate) fn uniform(&mut self) -> f64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            let u = self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11;
            u as f64 / (1u64 << 52) as f64 - 1.0
        }
        pub(crate) fn normal(&mut self) -> f64 {
            (0..12).map(|_| 0.5 * (self.uniform() + 1.0)).sum::<f64>() - 6.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::test_rng::Rng;
    use super::*;

    #[test]
    fn finite_range_leaves_out_what_is_not_a_value() {
        assert_eq!(finite_range([]), None);
        assert_eq!(finite_range([f64::NAN, f64::INFINITY]), None);
        assert_eq!(
            finite_range([f64::NAN, 2.0, f64::NEG_INFINITY, -1.0, 0.5]),
            Some((-1.0, 2.0))
        );
    }

    #[test]
    fn summary_and_band_agree_with_direct_statistics() {
        let a: Vec<f64> = vec![1.0, -2.0, 3.0];
        let b: Vec<f64> = vec![0.5, 4.0];
        let (mut x, mut y, mut all) = (Acc::default(), Acc::default(), Acc::default());
        a.iter().for_each(|v| x.push(*v));
        b.iter().for_each(|v| y.push(*v));
        a.iter().chain(&b).for_each(|v| all.push(*v));
        let direct = all.summary(1.0);
        let merged = band([&x.summary(1.0), &y.summary(1.0)]);
        assert_eq!(merged.n, 5);
        assert!((merged.mean - direct.mean).abs() < 1e-12);
        assert!((merged.rms - direct.rms).abs() < 1e-12);
        assert_eq!((merged.max, merged.min), (4.0, -2.0));
        // A negative scale swaps the extremes.
        let neg = x.summary(-1.0);
        assert_eq!((neg.max, neg.min), (2.0, -3.0));
        let mut z = x;
        z.merge(&y);
        assert_eq!(z.summary(1.0), direct);
        assert!(Acc::default().summary(1.0).mean.is_nan());
    }

    #[test]
    fn correlation_time_of_white_and_ar1_noise() {
        let mut rng = Rng(7);
        let white: Vec<f64> = (0..20_000).map(|_| rng.normal()).collect();
        let tau = correlation_time(&white);
        assert!(tau < 1.5, "white noise: {tau}");
        // AR(1) with phi = 0.9: tau = (1 + phi) / (1 - phi) = 19.
        let mut x = 0.0;
        let ar: Vec<f64> = (0..100_000)
            .map(|_| {
                x = 0.9 * x + rng.normal();
                x
            })
            .collect();
        let tau = correlation_time(&ar);
        assert!((tau - 19.0).abs() < 4.0, "AR(1): {tau}");
    }

    #[test]
    fn error_stats() {
        let s = ErrorStats::of([1.0, -3.0, 2.0], 2.0, "x");
        assert_eq!((s.n, s.max, s.min), (3, 4.0, -6.0));
        assert!((s.mean - 0.0).abs() < 1e-12);
        assert!((s.mean_abs - 4.0).abs() < 1e-12);
        assert!((s.rmse - (56.0f64 / 3.0).sqrt()).abs() < 1e-12);
        assert_eq!(s.max_abs(), 6.0);
    }
}
