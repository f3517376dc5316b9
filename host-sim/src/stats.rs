//! Statistics of errors and residuals, one place for the whole host crate.

use serde::Serialize;

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
