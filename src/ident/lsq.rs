//! Least squares: a streaming batch solver with parameter standard deviations,
//! and recursive least squares with forgetting.
//!
//! # Batch ([`BatchLsq`])
//!
//! The seed identifies every model (JAE Eq. 25-26, motor damping, no-load
//! tension model C Eq. 24/27) by ordinary least squares `y = W chi + rho`, and
//! judges each parameter by its relative standard deviation
//! `%sigma = 100 std(chi_k) / |chi_k|` (Sect. 4: parameters above 5 % are
//! dropped, model C -> the simplified model of Eq. 28-29).
//!
//! [`BatchLsq`] keeps the square-root information form: an upper-triangular
//! `R` (`p x p`) and `z = Q^T y`, updated row by row with Givens rotations, so a
//! log of any length is fitted in `O(N^2)` memory and no allocation. Each row's
//! left-over after the rotations is that row's contribution to the residual, so
//! `RSS = sum e_k^2` comes out without a second pass. Then
//!
//! * `chi = R^-1 z`,
//! * `sigma^2 = RSS / (n - p)`, `cov(chi) = sigma^2 (R^T R)^-1 = sigma^2 R^-1 R^-T`,
//! * the condition number is that of `R` with its columns scaled to unit norm
//!   (the data matrix `W` equilibrated), computed from its singular values. The
//!   scaling makes it independent of units (`x2` in m next to a constant 1), so
//!   it measures collinearity only. A large value is reported with the column
//!   that is closest to a combination of the columns before it (smallest scaled
//!   diagonal of `R`).
//!
//! Everything inside is `f64`: identification is not on the 2 kHz path.
//!
//! # Recursive ([`Rls`])
//!
//! Exponentially weighted RLS in `f32` for on-line tracking of slowly varying
//! parameters (the zero drift of seed 001, Sect. 2.2), with a bound on the trace
//! of the covariance against wind-up when the regressors stop exciting it.

use core::fmt;

use nalgebra::{SMatrix, SVector};

use crate::math;

/// Why a least-squares problem could not be solved or set up.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LsqError {
    /// Not enough rows for the standard deviations: need `rows > params`.
    TooFewRows {
        /// Rows accumulated.
        rows: u64,
        /// Active parameters.
        params: u8,
    },
    /// The columns are (nearly) linearly dependent.
    IllConditioned {
        /// Condition number of the column-equilibrated regressor matrix
        /// (infinite for an exactly dependent or all-zero column).
        condition: f64,
        /// The column (0-based) nearest to a combination of the earlier ones.
        column: u8,
    },
    /// A row held NaN or infinity; it was not accumulated.
    NonFinite {
        /// 0-based index of the offending row among the rows offered.
        row: u64,
    },
    /// A row had fewer entries than active columns.
    RowLength {
        /// Entries given.
        got: usize,
        /// Active columns.
        need: u8,
    },
    /// A configuration value is out of range.
    InvalidConfig {
        /// Name of the field.
        field: &'static str,
    },
}

impl fmt::Display for LsqError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            LsqError::TooFewRows { rows, params } => write!(
                f,
                "too few rows: {rows} rows for {params} parameters (need more rows than parameters)"
            ),
            LsqError::IllConditioned { condition, column } => write!(
                f,
                "rank deficient/ill-conditioned (condition number {condition:.3e}, column {column})"
            ),
            LsqError::NonFinite { row } => write!(f, "row {row} holds NaN or infinity"),
            LsqError::RowLength { got, need } => {
                write!(f, "row has {got} entries, {need} columns are active")
            }
            LsqError::InvalidConfig { field } => write!(f, "invalid value for `{field}`"),
        }
    }
}

fn abs64(x: f64) -> f64 {
    if x < 0.0 {
        -x
    } else {
        x
    }
}

/// Settings of the batch solver.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, deny_unknown_fields))]
pub struct LsqConfig {
    /// Largest accepted condition number of the equilibrated regressor matrix.
    /// With `f64` and the QR form the parameters keep about
    /// `16 - log10(condition)` significant digits.
    pub max_condition: f64,
}

impl Default for LsqConfig {
    fn default() -> Self {
        Self { max_condition: 1e8 }
    }
}

/// Streaming batch least squares over at most `N` regressors.
///
/// ```
/// use cable_joint::lsq::{BatchLsq, LsqConfig};
/// // y = 2 + 3 x, exactly
/// let mut ls = BatchLsq::<4>::new(2, LsqConfig::default()).unwrap();
/// for k in 0..10 {
///     let x = k as f64;
///     ls.push(&[1.0, x], 2.0 + 3.0 * x).unwrap();
/// }
/// let fit = ls.solve().unwrap();
/// assert!((fit.params[0] - 2.0).abs() < 1e-12 && (fit.params[1] - 3.0).abs() < 1e-12);
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct BatchLsq<const N: usize> {
    config: LsqConfig,
    active: usize,
    /// Upper-triangular factor (only the leading `active x active` block is used).
    r: SMatrix<f64, N, N>,
    /// `Q^T y` (leading `active` entries).
    z: SVector<f64, N>,
    rss: f64,
    rows: u64,
    offered: u64,
}

/// The result of [`BatchLsq::solve`]. Entries past `n_params` are zero.
#[derive(Clone, Debug, PartialEq)]
pub struct Fit<const N: usize> {
    /// Estimated parameters `chi`.
    pub params: SVector<f64, N>,
    /// Their standard deviations `sqrt(cov_kk)`.
    pub std_dev: SVector<f64, N>,
    /// Parameter covariance `sigma^2 (R^T R)^-1`.
    pub covariance: SMatrix<f64, N, N>,
    /// Number of active parameters `p`.
    pub n_params: usize,
    /// Number of rows `n`.
    pub rows: u64,
    /// Residual sum of squares.
    pub rss: f64,
    /// Root-mean-square residual `sqrt(RSS / n)`.
    pub rmse: f64,
    /// Residual standard deviation `sqrt(RSS / (n - p))`.
    pub sigma: f64,
    /// Condition number of the column-equilibrated regressor matrix.
    pub condition: f64,
}

impl<const N: usize> BatchLsq<N> {
    /// A solver with `active <= N` columns.
    pub fn new(active: usize, config: LsqConfig) -> Result<Self, LsqError> {
        if active == 0 || active > N || N > u8::MAX as usize {
            return Err(LsqError::InvalidConfig { field: "active" });
        }
        if config.max_condition.is_nan() || config.max_condition <= 1.0 {
            return Err(LsqError::InvalidConfig {
                field: "max_condition",
            });
        }
        Ok(Self {
            config,
            active,
            r: SMatrix::zeros(),
            z: SVector::zeros(),
            rss: 0.0,
            rows: 0,
            offered: 0,
        })
    }

    /// Number of active columns.
    pub fn active(&self) -> usize {
        self.active
    }

    /// Rows accumulated so far.
    pub fn rows(&self) -> u64 {
        self.rows
    }

    /// Residual sum of squares of the least-squares fit to the rows so far.
    pub fn rss(&self) -> f64 {
        self.rss
    }

    /// Forget all rows.
    pub fn reset(&mut self) {
        self.r = SMatrix::zeros();
        self.z = SVector::zeros();
        self.rss = 0.0;
        self.rows = 0;
        self.offered = 0;
    }

    /// Accumulate one row `phi . chi = y` (`phi` holds at least `active`
    /// entries; extra entries are ignored). A row with NaN or infinity is
    /// rejected and leaves the solver unchanged.
    pub fn push(&mut self, phi: &[f64], y: f64) -> Result<(), LsqError> {
        let p = self.active;
        let row = self.offered;
        self.offered += 1;
        let Some(phi) = phi.get(..p) else {
            return Err(LsqError::RowLength {
                got: phi.len(),
                need: p as u8,
            });
        };
        if !y.is_finite() || phi.iter().any(|v| !v.is_finite()) {
            return Err(LsqError::NonFinite { row });
        }
        let mut a = [0.0f64; N];
        a.iter_mut().zip(phi).for_each(|(d, s)| *d = *s);
        let mut b = y;
        // Rotate [a | b] into [R | z]: row k of R absorbs a[k], zeroing it.
        for k in 0..p {
            let ak = a[k];
            if ak == 0.0 {
                continue;
            }
            let rkk = self.r[(k, k)];
            let rho = math::sqrt_f64(rkk * rkk + ak * ak);
            let (c, s) = (rkk / rho, ak / rho);
            for (j, aj) in a.iter_mut().enumerate().take(p).skip(k) {
                let t = self.r[(k, j)];
                self.r[(k, j)] = c * t + s * *aj;
                *aj = c * *aj - s * t;
            }
            let t = self.z[k];
            self.z[k] = c * t + s * b;
            b = c * b - s * t;
        }
        self.rss += b * b;
        self.rows += 1;
        Ok(())
    }

    /// [`push`](Self::push) for `f32` rows (effect columns, log samples).
    pub fn push_f32(&mut self, phi: &[f32], y: f32) -> Result<(), LsqError> {
        let mut a = [0.0f64; N];
        let n = phi.len().min(N);
        a.iter_mut().zip(phi).for_each(|(d, s)| *d = f64::from(*s));
        if n < self.active {
            self.offered += 1;
            return Err(LsqError::RowLength {
                got: phi.len(),
                need: self.active as u8,
            });
        }
        self.push(&a, f64::from(y))
    }

    /// Solve for the parameters, their standard deviations and the
    /// condition number.
    pub fn solve(&self) -> Result<Fit<N>, LsqError> {
        let p = self.active;
        if self.rows <= p as u64 {
            return Err(LsqError::TooFewRows {
                rows: self.rows,
                params: p as u8,
            });
        }
        // Column norms of R = column norms of W (Q is orthogonal).
        let mut norm = [0.0f64; N];
        for (j, nj) in norm.iter_mut().enumerate().take(p) {
            let s: f64 = (0..=j).map(|i| self.r[(i, j)] * self.r[(i, j)]).sum();
            *nj = math::sqrt_f64(s);
            if nj.is_nan() || *nj <= 0.0 {
                return Err(LsqError::IllConditioned {
                    condition: f64::INFINITY,
                    column: j as u8,
                });
            }
        }
        // Equilibrated factor Rs = R diag(1/norm).
        let mut rs = SMatrix::<f64, N, N>::zeros();
        for j in 0..p {
            for i in 0..=j {
                rs[(i, j)] = self.r[(i, j)] / norm[j];
            }
        }
        let condition = condition_number(&rs, p);
        if condition.is_nan() || condition > self.config.max_condition {
            let column = (0..p)
                .min_by(|&a, &b| abs64(rs[(a, a)]).total_cmp(&abs64(rs[(b, b)])))
                .unwrap_or(0);
            return Err(LsqError::IllConditioned {
                condition,
                column: column as u8,
            });
        }
        // R^-1 = diag(1/norm) Rs^-1 (upper triangular, back substitution).
        let mut rinv = SMatrix::<f64, N, N>::zeros();
        for c in 0..p {
            for i in (0..=c).rev() {
                let mut s = if i == c { 1.0 } else { 0.0 };
                for k in i + 1..=c {
                    s -= rs[(i, k)] * rinv[(k, c)];
                }
                rinv[(i, c)] = s / rs[(i, i)];
            }
        }
        for i in 0..p {
            for c in i..p {
                rinv[(i, c)] /= norm[i];
            }
        }
        let params = rinv * self.z;
        let n = self.rows as f64;
        let dof = n - p as f64;
        let sigma2 = self.rss / dof;
        let covariance = rinv * rinv.transpose() * sigma2;
        let std_dev = SVector::<f64, N>::from_fn(|k, _| math::sqrt_f64(covariance[(k, k)]));
        Ok(Fit {
            params,
            std_dev,
            covariance,
            n_params: p,
            rows: self.rows,
            rss: self.rss,
            rmse: math::sqrt_f64(self.rss / n),
            sigma: math::sqrt_f64(sigma2),
            condition,
        })
    }
}

/// 2-norm condition number `sigma_max / sigma_min` of the leading `p x p`
/// block of `a`, by one-sided Jacobi (Hestenes) orthogonalisation of its
/// columns: after convergence the singular values are the column norms. It is
/// accurate for small singular values of a column-scaled matrix, which is
/// exactly the rank-deficiency question.
fn condition_number<const N: usize>(a: &SMatrix<f64, N, N>, p: usize) -> f64 {
    let mut a = *a;
    for _sweep in 0..60 {
        let mut rotated = false;
        for i in 0..p {
            for j in i + 1..p {
                let (mut al, mut be, mut ga) = (0.0, 0.0, 0.0);
                for k in 0..p {
                    al += a[(k, i)] * a[(k, i)];
                    be += a[(k, j)] * a[(k, j)];
                    ga += a[(k, i)] * a[(k, j)];
                }
                if abs64(ga) <= 1e-15 * math::sqrt_f64(al * be) {
                    continue;
                }
                rotated = true;
                let zeta = (be - al) / (2.0 * ga);
                let t = if zeta >= 0.0 { 1.0 } else { -1.0 }
                    / (abs64(zeta) + math::sqrt_f64(1.0 + zeta * zeta));
                let c = 1.0 / math::sqrt_f64(1.0 + t * t);
                let s = c * t;
                for k in 0..p {
                    let (x, y) = (a[(k, i)], a[(k, j)]);
                    a[(k, i)] = c * x - s * y;
                    a[(k, j)] = s * x + c * y;
                }
            }
        }
        if !rotated {
            break;
        }
    }
    let (mut smax, mut smin) = (0.0f64, f64::INFINITY);
    for j in 0..p {
        let s = math::sqrt_f64((0..p).map(|k| a[(k, j)] * a[(k, j)]).sum());
        smax = smax.max(s);
        smin = smin.min(s);
    }
    if smin > 0.0 {
        smax / smin
    } else {
        f64::INFINITY
    }
}

impl<const N: usize> Fit<N> {
    /// The seed's relative standard deviation `100 std_k / |chi_k|` in %
    /// (infinite for a zero parameter, NaN past `n_params`).
    pub fn pct_sigma(&self, k: usize) -> f64 {
        if k >= self.n_params {
            return f64::NAN;
        }
        100.0 * self.std_dev[k] / abs64(self.params[k])
    }

    /// Prediction `phi . chi` for one row.
    pub fn predict(&self, phi: &[f64]) -> f64 {
        phi.iter()
            .zip(self.params.iter())
            .take(self.n_params)
            .map(|(a, b)| a * b)
            .sum()
    }

    /// The seed's pruning rule (Sect. 4, Eq. 27 -> 28-29): `true` for every
    /// active parameter whose `%sigma` exceeds `max_pct_sigma` (5 in the
    /// seed). Refit without them (see [`compact_row`]).
    pub fn uncertain_params(&self, max_pct_sigma: f64) -> [bool; N] {
        let mut out = [false; N];
        for (k, o) in out.iter_mut().enumerate().take(self.n_params) {
            let pct = self.pct_sigma(k);
            *o = pct.is_nan() || pct > max_pct_sigma;
        }
        out
    }
}

/// Copy the entries of `row` whose `drop` flag is `false` to the front of
/// `out`, in order; returns how many were written (the pruned row for a refit
/// with [`Fit::uncertain_params`]).
pub fn compact_row<const N: usize>(row: &[f64], drop: &[bool; N], out: &mut [f64]) -> usize {
    let kept = row.iter().zip(drop).filter(|(_, d)| !**d).map(|(v, _)| *v);
    let mut n = 0;
    for (o, v) in out.iter_mut().zip(kept) {
        *o = v;
        n += 1;
    }
    n
}

/// Settings of [`Rls`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, deny_unknown_fields))]
pub struct RlsConfig {
    /// Forgetting factor `lambda` in `(0, 1]`; the memory is about
    /// `1 / (1 - lambda)` samples.
    pub forgetting: f32,
    /// Initial (and reset) covariance `P0 = initial_covariance * I`.
    pub initial_covariance: f32,
    /// Wind-up guard: `trace(P)` is scaled back to this bound when exceeded.
    pub max_trace: f32,
}

impl Default for RlsConfig {
    fn default() -> Self {
        Self {
            forgetting: 0.999,
            initial_covariance: 1e3,
            max_trace: 1e4,
        }
    }
}

impl RlsConfig {
    /// Check the ranges (for `N` parameters: `max_trace >= N * P0`).
    pub fn validate(&self, n: usize) -> Result<(), LsqError> {
        if !(self.forgetting > 0.0 && self.forgetting <= 1.0) {
            return Err(LsqError::InvalidConfig {
                field: "forgetting",
            });
        }
        if !(self.initial_covariance > 0.0 && self.initial_covariance.is_finite()) {
            return Err(LsqError::InvalidConfig {
                field: "initial_covariance",
            });
        }
        if !(self.max_trace >= n as f32 * self.initial_covariance && self.max_trace.is_finite()) {
            return Err(LsqError::InvalidConfig { field: "max_trace" });
        }
        Ok(())
    }
}

/// Recursive least squares with exponential forgetting:
///
/// ```text
/// e = y - phi^T chi                      (a-priori error, returned)
/// k = P phi / (lambda + phi^T P phi)
/// chi += k e
/// P = (P - k phi^T P) / lambda           (symmetrised, trace bounded)
/// ```
///
/// A non-finite input leaves the state unchanged and returns NaN; a covariance
/// that turns non-finite or loses positivity is reset to `P0`.
#[derive(Clone, Debug, PartialEq)]
pub struct Rls<const N: usize> {
    /// Settings (validated by [`Rls::new`]).
    config: RlsConfig,
    chi: SVector<f32, N>,
    p: SMatrix<f32, N, N>,
}

impl<const N: usize> Rls<N> {
    /// Zero parameters, covariance `P0`.
    pub fn new(config: RlsConfig) -> Result<Self, LsqError> {
        config.validate(N)?;
        Ok(Self {
            config,
            chi: SVector::zeros(),
            p: SMatrix::identity() * config.initial_covariance,
        })
    }

    /// The settings.
    pub fn config(&self) -> &RlsConfig {
        &self.config
    }

    /// Current parameter estimate.
    pub fn params(&self) -> &SVector<f32, N> {
        &self.chi
    }

    /// Set the parameters (e.g. from a batch fit); the covariance is kept.
    pub fn set_params(&mut self, chi: &[f32; N]) {
        self.chi = SVector::from(*chi);
    }

    /// Current covariance `P` (scaled by the noise variance, as usual for RLS).
    pub fn covariance(&self) -> &SMatrix<f32, N, N> {
        &self.p
    }

    /// Back to `P0` (e.g. after a known change of the plant); parameters kept.
    pub fn reset_covariance(&mut self) {
        self.p = SMatrix::identity() * self.config.initial_covariance;
    }

    /// Zero parameters and `P0`.
    pub fn reset(&mut self) {
        self.chi = SVector::zeros();
        self.reset_covariance();
    }

    /// Prediction `phi^T chi`.
    pub fn predict(&self, phi: &[f32; N]) -> f32 {
        self.chi.dot(&SVector::from(*phi))
    }

    /// One update with regressor `phi` and measurement `y`; returns the
    /// a-priori prediction error `y - phi^T chi`.
    pub fn update(&mut self, phi: &[f32; N], y: f32) -> f32 {
        if !y.is_finite() || phi.iter().any(|v| !v.is_finite()) {
            return f32::NAN;
        }
        let phi = SVector::from(*phi);
        let e = y - self.chi.dot(&phi);
        let pphi = self.p * phi;
        let denom = self.config.forgetting + phi.dot(&pphi);
        if !(denom > 0.0 && denom.is_finite()) {
            self.reset_covariance();
            return e;
        }
        let k = pphi / denom;
        self.chi += k * e;
        // P phi phi^T P / denom = k (P phi)^T, P symmetric.
        let p = (self.p - k * pphi.transpose()) / self.config.forgetting;
        self.p = (p + p.transpose()) * 0.5;
        let tr = self.p.trace();
        if !tr.is_finite() || self.p.iter().any(|v| !v.is_finite()) {
            self.reset_covariance();
        } else if tr > self.config.max_trace {
            self.p *= self.config.max_trace / tr;
        }
        e
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::Rng;

    fn close(a: f64, b: f64, rel: f64) -> bool {
        abs64(a - b) <= rel * abs64(b)
    }

    #[test]
    fn exact_recovery_noise_free() {
        // Seed-like scales: a constant, a position in m, a sign, a velocity.
        let truth = [19.52, 707.7, 5.027, 3.879];
        let mut ls = BatchLsq::<6>::new(4, LsqConfig::default()).unwrap();
        for k in 0..500 {
            let t = k as f64 * 1e-2;
            let x = 3e-3 * math::sqrt_f64(2.0 + f64::from(math::sin(t as f32))) - 4e-3;
            let v = 3e-3 * f64::from(math::cos(1.7 * t as f32));
            let row = [1.0, x, f64::from(math::tanh((v / 1e-4) as f32)), v];
            let y: f64 = row.iter().zip(&truth).map(|(a, b)| a * b).sum();
            ls.push(&row, y).unwrap();
        }
        let fit = ls.solve().unwrap();
        for (k, t) in truth.iter().enumerate() {
            assert!(
                close(fit.params[k], *t, 1e-9),
                "param {k}: {} vs {t}",
                fit.params[k]
            );
        }
        assert!(fit.rss < 1e-18, "rss {}", fit.rss);
        assert_eq!(fit.rows, 500);
        assert_eq!(fit.params[4], 0.0);
        assert!(
            fit.condition > 1.0 && fit.condition < 1e3,
            "cond {}",
            fit.condition
        );
    }

    /// Straight line with noise: the reported standard deviations match the
    /// analytic `sigma^2 (W^T W)^-1` and the Monte-Carlo spread of the estimates.
    #[test]
    fn std_devs_match_analytic_and_monte_carlo() {
        let (a0, b0, noise) = (2.0, -0.5, 0.3);
        let n = 400;
        let xs: [f64; 400] = core::array::from_fn(|k| 10.0 * k as f64 / n as f64);
        // Analytic covariance of (a, b) for y = a + b x: sigma^2 (W^T W)^-1.
        let (s0, s1, s2) = (
            n as f64,
            xs.iter().sum::<f64>(),
            xs.iter().map(|x| x * x).sum::<f64>(),
        );
        let det = s0 * s2 - s1 * s1;
        let sd_a = noise * math::sqrt_f64(s2 / det);
        let sd_b = noise * math::sqrt_f64(s0 / det);

        let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
        let trials = 300;
        let (mut ma, mut mb, mut qa, mut qb, mut rep_a, mut rep_b) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        for _ in 0..trials {
            let mut ls = BatchLsq::<2>::new(2, LsqConfig::default()).unwrap();
            for x in xs {
                ls.push(&[1.0, x], a0 + b0 * x + noise * rng.normal())
                    .unwrap();
            }
            let fit = ls.solve().unwrap();
            ma += fit.params[0];
            mb += fit.params[1];
            qa += fit.params[0] * fit.params[0];
            qb += fit.params[1] * fit.params[1];
            rep_a += fit.std_dev[0];
            rep_b += fit.std_dev[1];
            assert!(close(fit.sigma, noise, 0.15), "sigma {}", fit.sigma);
        }
        let t = trials as f64;
        let (ma, mb) = (ma / t, mb / t);
        let emp_a = math::sqrt_f64(qa / t - ma * ma);
        let emp_b = math::sqrt_f64(qb / t - mb * mb);
        let (rep_a, rep_b) = (rep_a / t, rep_b / t);
        assert!(close(rep_a, sd_a, 0.03), "reported {rep_a} analytic {sd_a}");
        assert!(close(rep_b, sd_b, 0.03), "reported {rep_b} analytic {sd_b}");
        // 300 trials: the empirical std has about 4 % relative error.
        assert!(
            close(emp_a, sd_a, 0.15),
            "monte carlo {emp_a} analytic {sd_a}"
        );
        assert!(
            close(emp_b, sd_b, 0.15),
            "monte carlo {emp_b} analytic {sd_b}"
        );
        assert!(close(ma, a0, 0.01) && close(mb, b0, 0.01), "bias {ma} {mb}");
    }

    #[test]
    fn identical_columns_are_rank_deficient() {
        let mut ls = BatchLsq::<3>::new(3, LsqConfig::default()).unwrap();
        for k in 0..50 {
            let x = 1e-3 * k as f64;
            ls.push(&[1.0, x, x], 1.0 + x).unwrap();
        }
        match ls.solve() {
            Err(LsqError::IllConditioned { condition, column }) => {
                assert_eq!(column, 2, "the duplicate is the later column");
                assert!(condition > 1e12, "condition {condition}");
            }
            other => panic!("expected IllConditioned, got {other:?}"),
        }
        // Nearly collinear (1e-12 relative difference) is caught too, and the
        // message says what and where.
        let mut ls = BatchLsq::<3>::new(3, LsqConfig::default()).unwrap();
        let mut rng = Rng(7);
        for k in 0..50 {
            let x = k as f64;
            ls.push(&[x, 1.0, x * (1.0 + 1e-12 * rng.uniform())], x)
                .unwrap();
        }
        let err = ls.solve().unwrap_err();
        let mut msg = heapless::String::<128>::new();
        core::fmt::write(&mut msg, format_args!("{err}")).unwrap();
        assert!(msg.starts_with("rank deficient/ill-conditioned"), "{msg}");
        assert!(msg.ends_with("column 2)"), "{msg}");
        // An all-zero column.
        let mut ls = BatchLsq::<2>::new(2, LsqConfig::default()).unwrap();
        for k in 0..5 {
            ls.push(&[k as f64, 0.0], 1.0).unwrap();
        }
        assert_eq!(
            ls.solve(),
            Err(LsqError::IllConditioned {
                condition: f64::INFINITY,
                column: 1
            })
        );
    }

    #[test]
    fn bad_scaling_alone_is_not_ill_conditioned() {
        // Micrometre positions next to a constant: raw condition ~1e6+, but
        // the columns are independent.
        let mut ls = BatchLsq::<2>::new(2, LsqConfig::default()).unwrap();
        for k in 0..100 {
            let x = 1e-6 * k as f64;
            ls.push(&[1.0, x], 19.5 + 700.0 * x).unwrap();
        }
        let fit = ls.solve().unwrap();
        assert!(fit.condition < 10.0, "condition {}", fit.condition);
        assert!(close(fit.params[1], 700.0, 1e-8), "{}", fit.params[1]);
    }

    #[test]
    fn too_few_rows_and_bad_rows() {
        let mut ls = BatchLsq::<3>::new(3, LsqConfig::default()).unwrap();
        for k in 0..3 {
            ls.push(&[1.0, k as f64, (k * k) as f64], 0.0).unwrap();
        }
        assert_eq!(ls.solve(), Err(LsqError::TooFewRows { rows: 3, params: 3 }));
        assert_eq!(
            ls.push(&[1.0, f64::NAN, 0.0], 1.0),
            Err(LsqError::NonFinite { row: 3 })
        );
        assert_eq!(
            ls.push(&[1.0], 1.0),
            Err(LsqError::RowLength { got: 1, need: 3 })
        );
        assert_eq!(ls.rows(), 3, "rejected rows are not accumulated");
        assert!(BatchLsq::<3>::new(4, LsqConfig::default()).is_err());
        assert!(BatchLsq::<3>::new(0, LsqConfig::default()).is_err());
    }

    /// The seed's pruning: an irrelevant regressor has a large %sigma, the
    /// real ones small; the compacted refit keeps the real values.
    #[test]
    fn pruning_flags_irrelevant_terms() {
        let mut rng = Rng(12345);
        let mut ls = BatchLsq::<4>::new(3, LsqConfig::default()).unwrap();
        let mut rows = [[0.0f64; 4]; 300];
        for row in rows.iter_mut() {
            let x = rng.uniform();
            let junk = rng.uniform();
            *row = [1.0, x, junk, 2.0 + 3.0 * x + 0.05 * rng.normal()];
            ls.push(&row[..3], row[3]).unwrap();
        }
        let fit = ls.solve().unwrap();
        assert!(fit.pct_sigma(0) < 5.0 && fit.pct_sigma(1) < 5.0);
        assert!(fit.pct_sigma(2) > 5.0, "junk %sigma {}", fit.pct_sigma(2));
        assert!(fit.pct_sigma(3).is_nan());
        let drop = fit.uncertain_params(5.0);
        assert_eq!(drop, [false, false, true, false]);
        let mut refit = BatchLsq::<4>::new(2, LsqConfig::default()).unwrap();
        for row in &rows {
            let mut out = [0.0; 4];
            assert_eq!(compact_row(&row[..3], &drop, &mut out), 2);
            refit.push(&out, row[3]).unwrap();
        }
        let fit2 = refit.solve().unwrap();
        assert!(close(fit2.params[0], 2.0, 0.01) && close(fit2.params[1], 3.0, 0.01));
        assert!(close(fit2.predict(&[1.0, 0.5]), 3.5, 0.01));
    }

    #[test]
    fn rls_converges_noise_free() {
        let mut rls = Rls::<3>::new(RlsConfig {
            forgetting: 1.0,
            ..RlsConfig::default()
        })
        .unwrap();
        let truth = [0.7f32, -1.5, 4.0];
        let mut rng = Rng(3);
        for _ in 0..200 {
            let phi = [1.0, rng.uniform() as f32, rng.uniform() as f32];
            let y = phi.iter().zip(&truth).map(|(a, b)| a * b).sum();
            rls.update(&phi, y);
        }
        for (k, (est, t)) in rls.params().iter().zip(&truth).enumerate() {
            assert!((est - t).abs() < 1e-3, "param {k}: {est} vs {t}");
        }
        let e = rls.update(&[1.0, 0.2, 0.3], 0.7 - 0.3 + 1.2);
        assert!(e.abs() < 1e-3, "prediction error {e}");
    }

    /// A step in a parameter: with forgetting the estimate follows within a few
    /// memory lengths; without it, it stays stuck near the average.
    #[test]
    fn rls_tracks_step_with_forgetting() {
        let run = |lambda: f32| {
            let mut rls = Rls::<2>::new(RlsConfig {
                forgetting: lambda,
                ..RlsConfig::default()
            })
            .unwrap();
            let mut rng = Rng(99);
            let mut est = 0.0;
            for k in 0..3000 {
                let offset = if k < 1500 { 1.0 } else { 1.5 };
                let x = rng.uniform() as f32;
                let y = offset + 2.0 * x + 0.01 * rng.normal() as f32;
                rls.update(&[1.0, x], y);
                est = rls.params()[0];
            }
            est
        };
        // lambda = 0.99: memory ~100 samples, 1500 samples after the step.
        let tracked = run(0.99);
        assert!((tracked - 1.5).abs() < 0.01, "tracked offset {tracked}");
        let stuck = run(1.0);
        assert!(
            (stuck - 1.25).abs() < 0.05,
            "no forgetting averages: {stuck}"
        );
    }

    #[test]
    fn rls_windup_bounded_without_excitation() {
        let cfg = RlsConfig {
            forgetting: 0.95,
            initial_covariance: 10.0,
            max_trace: 100.0,
        };
        let mut rls = Rls::<2>::new(cfg).unwrap();
        for k in 0..2000 {
            // Only the first direction is excited: the second would wind up as
            // P0 / lambda^k (above the bound after ~45 samples) without the guard.
            rls.update(&[1.0, 0.0], 3.0);
            let tr = rls.covariance().trace();
            assert!(tr <= 100.0 * 1.0001, "trace {tr} at {k}");
        }
        // Held at the bound (not reset to P0 by an overflow).
        let tr = rls.covariance().trace();
        assert!(tr > 99.0, "trace {tr}");
        assert!((rls.params()[0] - 3.0).abs() < 1e-4);
        assert!(rls.update(&[f32::NAN, 0.0], 1.0).is_nan());
        assert!((rls.params()[0] - 3.0).abs() < 1e-4, "NaN row ignored");
        assert!(Rls::<2>::new(RlsConfig {
            forgetting: 1.5,
            ..cfg
        })
        .is_err());
    }
}
