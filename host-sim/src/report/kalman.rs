//! Two Kalman filters of the tip force, measured against the fused
//! set-membership bound (`cable_joint::fusion`) on the same runs: the
//! comparison behind the fusion's design choice (issue "force at
//! standstill", item 1; `docs/force.md`). Not on the MCU.
//!
//! Both read, every tick, exactly what the fusion intersects: the DOB's and
//! the cable stretch's intervals of tip forces
//! ([`cable_joint::fusion::Sources`]). Each interval becomes a measurement,
//! its centre, with the variance of a uniform distribution over it,
//! `h² / 3` for a half-width `h` (the friction can sit anywhere in its
//! band). The force is a random walk whose process noise puts the filter's
//! bandwidth at the DOB's low-pass `g` (`q = (g dt)² R` per tick, `R` the
//! two measurements' combined variance), so it follows a load change as
//! fast as the signals it reads. The reported interval is `±2σ`.
//!
//! * [`Design::White`], the textbook filter: the band's variance is white
//!   measurement noise, so the filter averages it down over its time
//!   constant.
//! * [`Design::FrictionStates`]: each source's friction is a state of its
//!   own, a first-order Gauss–Markov process with the band's variance and
//!   correlation time [`FRICTION_TAU_S`] (a stuck element keeps its
//!   friction until it slips), on top of white noise of one count of the
//!   source's sensor (a grating count of stretch, a current-monitor code).

use cable_joint::fusion::Sources;
use cable_joint::Config;
use nalgebra::{Matrix3, RowVector3, Vector3};

/// Correlation time of a friction state, s: a stuck element's friction
/// holds for about a hold of the protocol (its loading steps are 1 to 3 s
/// apart); chosen before it was measured, `docs/force.md` gives 0.1 s and
/// 10 s beside it.
pub const FRICTION_TAU_S: f64 = 1.0;

/// Which filter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Design {
    /// The bands as white measurement noise.
    White,
    /// The bands as coloured friction states with correlation time `tau_s`.
    FrictionStates {
        /// Correlation time, s.
        tau_s: f64,
    },
}

impl Design {
    /// The row name in the report's table.
    pub fn name(&self) -> &'static str {
        match self {
            Self::White => "Kalman, white bands",
            Self::FrictionStates { .. } => "Kalman, friction states",
        }
    }
}

/// The filter: state `[F, b_dob, b_stretch]` (the last two only in
/// [`Design::FrictionStates`]), N.
#[derive(Clone, Debug)]
pub struct KalmanForce {
    design: Design,
    /// Control period, s.
    dt_s: f64,
    /// The DOB's low-pass, rad/s.
    g_rad_s: f64,
    /// White noise of the DOB's and the stretch's measurement, N² (friction
    /// states only).
    white_n2: (f64, f64),
    x: Vector3<f64>,
    p: Matrix3<f64>,
    primed: bool,
}

/// Variance of a uniform distribution over an interval, N², and its centre.
fn centre_and_variance((lo, hi): (f32, f32)) -> (f64, f64) {
    let (lo, hi) = (f64::from(lo), f64::from(hi));
    let h = 0.5 * (hi - lo).abs();
    (0.5 * (lo + hi), (h * h / 3.0).max(1e-12))
}

impl KalmanForce {
    /// A filter for a controller configured by `c`.
    pub fn new(design: Design, c: &Config) -> Self {
        let m = &c.machine;
        let s = &c.scales;
        let tip_per_tension = f64::from(m.pulley_radius_m / m.gripper_length_m);
        // One current-monitor code through the DOB's chain, and one grating
        // count of stretch on cable 1, as tip forces; uniform quantization.
        let dob_code_n = f64::from(s.adc_a_per_code * m.torque_constant_nm_a * m.gear_ratio)
            / f64::from(m.rope_wheel_radius_m)
            * tip_per_tension;
        let stretch_count_n =
            f64::from(c.stretch.cable1_n_m * s.grating_m_per_count) * tip_per_tension;
        Self {
            design,
            dt_s: f64::from(c.period_s()),
            g_rad_s: f64::from(c.dob.cutoff_rad_s),
            white_n2: (
                dob_code_n * dob_code_n / 12.0,
                stretch_count_n * stretch_count_n / 12.0,
            ),
            x: Vector3::zeros(),
            p: Matrix3::zeros(),
            primed: false,
        }
    }

    /// One tick on the fusion's two intervals; returns the estimate and
    /// its `±2σ` interval `(F, lo, hi)`, N.
    pub fn update(&mut self, src: &Sources) -> (f64, f64, f64) {
        let (zd, rd) = centre_and_variance(src.dob_n);
        let (zs, rs) = centre_and_variance(src.stretch_n);
        let combined = rd * rs / (rd + rs);
        let gdt = self.g_rad_s * self.dt_s;
        let q_force = gdt * gdt * combined;
        match self.design {
            Design::White => {
                if !self.primed {
                    self.x[0] = (zd / rd + zs / rs) * combined;
                    self.p[(0, 0)] = combined;
                    self.primed = true;
                }
                let mut p = self.p[(0, 0)] + q_force;
                let mut x = self.x[0];
                for (z, r) in [(zd, rd), (zs, rs)] {
                    let k = p / (p + r);
                    x += k * (z - x);
                    p *= 1.0 - k;
                }
                self.x[0] = x;
                self.p[(0, 0)] = p;
            }
            Design::FrictionStates { tau_s } => {
                if !self.primed {
                    // Nothing known of the force beforehand: its prior is
                    // far wider than either band.
                    self.x = Vector3::new((zd / rd + zs / rs) * combined, 0.0, 0.0);
                    self.p = Matrix3::from_diagonal(&Vector3::new(1e4 * (rd + rs), rd, rs));
                    self.primed = true;
                }
                // Predict: F a random walk, each friction a Gauss-Markov
                // process whose stationary variance is its band's now.
                let a = (-self.dt_s / tau_s).exp();
                let f = Matrix3::from_diagonal(&Vector3::new(1.0, a, a));
                let q = Matrix3::from_diagonal(&Vector3::new(
                    q_force,
                    (1.0 - a * a) * rd,
                    (1.0 - a * a) * rs,
                ));
                self.x = f * self.x;
                self.p = f * self.p * f.transpose() + q;
                let rows = [
                    (RowVector3::new(1.0, 1.0, 0.0), zd, self.white_n2.0),
                    (RowVector3::new(1.0, 0.0, 1.0), zs, self.white_n2.1),
                ];
                for (h, z, r) in rows {
                    let ph = self.p * h.transpose();
                    let s = (h * ph)[(0, 0)] + r;
                    let k = ph / s;
                    self.x += k * (z - (h * self.x)[(0, 0)]);
                    self.p -= k * h * self.p;
                    self.p = 0.5 * (self.p + self.p.transpose());
                }
            }
        }
        let sigma = self.p[(0, 0)].max(0.0).sqrt();
        (self.x[0], self.x[0] - 2.0 * sigma, self.x[0] + 2.0 * sigma)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sources(dob: (f32, f32), stretch: (f32, f32)) -> Sources {
        Sources {
            dob_n: dob,
            stretch_n: stretch,
        }
    }

    /// Two intervals held still: the white-band filter converges on their
    /// inverse-variance mean and its `2σ` shrinks far below either band
    /// (it takes a held friction for noise it can average); the
    /// friction-state filter converges on the same mean but keeps a `2σ`
    /// near the combined band's, since a held friction does not average out.
    #[test]
    fn held_bands_average_down_as_white_noise_but_not_as_friction_states() {
        let c = Config::default();
        let src = sources((-1.0, 3.0), (0.0, 1.0));
        let (rd, rs): (f64, f64) = (4.0 / 3.0, 0.25 / 3.0);
        let expected = (1.0 / rd + 0.5 / rs) / (1.0 / rd + 1.0 / rs);
        let combined_2sigma = 2.0 * (rd * rs / (rd + rs)).sqrt();
        let run = |design| {
            let mut k = KalmanForce::new(design, &c);
            let mut out = (0.0, 0.0, 0.0);
            for _ in 0..(5.0 * c.control_rate_hz) as usize {
                out = k.update(&src);
            }
            out
        };
        let white = run(Design::White);
        let states = run(Design::FrictionStates { tau_s: 1e3 });
        assert!((white.0 - expected).abs() < 1e-6, "{white:?} vs {expected}");
        assert!(
            (states.0 - expected).abs() < 1e-3,
            "{states:?} vs {expected}"
        );
        let half = |o: (f64, f64, f64)| 0.5 * (o.2 - o.1);
        assert!(half(white) < 0.3 * combined_2sigma, "{white:?}");
        assert!(
            (half(states) - combined_2sigma).abs() < 0.1 * combined_2sigma,
            "{states:?} against {combined_2sigma}"
        );
    }

    /// A step of both intervals by 1 N: the white-band filter follows it
    /// within a few time constants of the DOB's low-pass; the
    /// friction-state filter takes most of it at once and puts the rest on
    /// the frictions, which it lets go at their correlation time.
    #[test]
    fn a_load_step_is_followed_at_the_low_passes_pace_or_the_frictions() {
        let c = Config::default();
        let rate = f64::from(c.control_rate_hz);
        let g = f64::from(c.dob.cutoff_rad_s);
        let tau_s = 0.5;
        let step = |design, ticks: usize| {
            let mut k = KalmanForce::new(design, &c);
            for _ in 0..2000 {
                k.update(&sources((-1.0, 1.0), (-0.2, 0.2)));
            }
            let mut out = Vec::new();
            for _ in 0..ticks {
                out.push(k.update(&sources((0.0, 2.0), (0.8, 1.2))).0);
            }
            out
        };
        let white = step(Design::White, (5.0 / g * rate) as usize);
        assert!((white.last().unwrap() - 1.0).abs() < 0.02, "{white:?}");
        // At the low-pass's pace: a first-order response's 1 - e^-1 and
        // 1 - e^-2 one and two time constants `1/g` after the step.
        assert!(white[0] < 0.2, "{}", white[0]);
        for n in [1.0, 2.0] {
            let got = white[(n / g * rate) as usize];
            let want = 1.0 - (-n).exp();
            assert!((got - want).abs() < 0.05, "{n}/g: {got} against {want}");
        }
        let states = step(
            Design::FrictionStates { tau_s },
            (5.0 * tau_s * rate) as usize,
        );
        assert!(states[0] > 0.5, "{}", states[0]);
        assert!(
            (states[states.len() - 1] - 1.0).abs() < 0.05,
            "{:?}",
            states.last()
        );
        let at_tau = states[(tau_s * rate) as usize];
        assert!(
            at_tau < 0.95,
            "{at_tau}: the frictions let go at their own pace"
        );
    }
}
