//! Joint-angle reference generator: holds, sines, smooth point-to-point moves,
//! the seed's "complex trajectory" (Fig. 13) and seed 001's Fourier-series
//! excitation (Eq. 9), evaluated at a time since the command started. Pure
//! functions of time: no state, no allocation.

use crate::math::{self, PI};

/// A joint-angle reference, in joint radians.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub enum Trajectory {
    /// Hold one angle.
    Hold {
        /// Angle, rad.
        angle_rad: f32,
    },
    /// `offset + amplitude * sin(2π f t)`.
    Sine {
        /// Centre, rad.
        offset_rad: f32,
        /// Amplitude, rad.
        amplitude_rad: f32,
        /// Frequency, Hz.
        freq_hz: f32,
    },
    /// Minimum-jerk (quintic) move from `from` to `to` in `duration`, then hold.
    PointToPoint {
        /// Start, rad.
        from_rad: f32,
        /// End, rad.
        to_rad: f32,
        /// Duration, s.
        duration_s: f32,
    },
    /// The seed's "complex trajectory": three incommensurate sines whose
    /// amplitudes sum to `amplitude`, faded in over the first period so the
    /// reference starts at rest at zero.
    Complex {
        /// Peak amplitude (sum of the three components), rad.
        amplitude_rad: f32,
        /// Base frequency, Hz (components at 1, 2.3 and 3.7 times it).
        base_freq_hz: f32,
    },
    /// An identification excitation (seed 001, Eq. 9): a Fourier series of
    /// [`HARMONICS`] harmonics of `base_freq_hz`, written so that it starts
    /// at `offset_rad`,
    /// `theta(t) = offset + sum_k [ sin_k sin(k w t) + cos_k (cos(k w t) - 1) ]`
    /// with `w = 2 pi base_freq_hz`. [`Trajectory::validate`] asks that it
    /// also start at rest (`sum_k k sin_k = 0`, zero velocity, and
    /// `sum_k k^2 cos_k = 0`, zero acceleration), so it is periodic and ends
    /// at rest after any whole number of periods: seed 001 appends a
    /// polynomial for the same purpose. `host-sim excite` designs the
    /// coefficients.
    Fourier {
        /// Start angle, rad.
        offset_rad: f32,
        /// Fundamental frequency, Hz.
        base_freq_hz: f32,
        /// Sine coefficients of harmonics 1..=HARMONICS, rad.
        sin_rad: [f32; HARMONICS],
        /// Cosine coefficients of harmonics 1..=HARMONICS, rad.
        cos_rad: [f32; HARMONICS],
    },
    /// Grip-force control: close until the fused force estimate reads
    /// `force_n`, and hold it there ([`crate::grip`]: an admittance law
    /// moves the angle reference, leashed to the cascade's feedback angle,
    /// and the cascade follows it). Under [`crate::Mode::MotorPosition`]
    /// (the default for a grip: the motor's angle has no stick band) or
    /// [`crate::Mode::JointClosedLoop`]. It has no law of time, so
    /// [`Trajectory::at`] gives a zero reference for it.
    Grip {
        /// Force set point, N; its sign says which way the jaw closes
        /// (positive: towards positive angles).
        force_n: f32,
        /// Closing speed until the contact's stiffness is measured, rad/s
        /// (then the law's own pace, at least this).
        approach_rad_s: f32,
    },
}

/// Largest grip set point a command may ask for, N (four times the seed's
/// heaviest load, 250 g at 20 mm).
pub const MAX_GRIP_N: f32 = 10.0;
/// Fastest grip approach a command may ask for, rad/s.
pub const MAX_APPROACH_RAD_S: f32 = 1.0;

/// Harmonics of [`Trajectory::Fourier`] (seed 001 uses N = 5).
pub const HARMONICS: usize = 5;

/// Reference at one instant.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Reference {
    /// Angle, rad.
    pub angle_rad: f32,
    /// Angular velocity, rad/s.
    pub vel_rad_s: f32,
}

const COMPLEX: [(f32, f32); 3] = [(0.5, 1.0), (0.3, 2.3), (0.2, 3.7)];

impl Trajectory {
    /// Check an operator's trajectory before it reaches the control path:
    /// every value finite, angles within ±10 rad (the widest range homing
    /// uses), frequencies within 0 < f <= 100 Hz (far above the joint's
    /// bandwidth), durations within 0..=1e5 s, a Fourier series starting at
    /// rest, a grip's set point within 0 < |F| <= [`MAX_GRIP_N`] and its
    /// approach within 0 < v <= [`MAX_APPROACH_RAD_S`]. Returns what is
    /// wrong.
    pub fn validate(&self) -> Result<(), &'static str> {
        let angle = |a: f32| a.is_finite() && a.abs() <= 10.0;
        let freq = |f: f32| f.is_finite() && f > 0.0 && f <= 100.0;
        let ok = match *self {
            Trajectory::Hold { angle_rad } => angle(angle_rad),
            Trajectory::Sine {
                offset_rad,
                amplitude_rad,
                freq_hz,
            } => angle(offset_rad) && angle(amplitude_rad) && freq(freq_hz),
            Trajectory::PointToPoint {
                from_rad,
                to_rad,
                duration_s,
            } => {
                angle(from_rad)
                    && angle(to_rad)
                    && duration_s.is_finite()
                    && (0.0..=1e5).contains(&duration_s)
            }
            Trajectory::Complex {
                amplitude_rad,
                base_freq_hz,
            } => angle(amplitude_rad) && freq(base_freq_hz),
            Trajectory::Fourier {
                offset_rad,
                base_freq_hz,
                sin_rad,
                cos_rad,
            } => {
                let fine = angle(offset_rad)
                    && freq(base_freq_hz)
                    && sin_rad.iter().chain(&cos_rad).all(|&c| angle(c));
                if fine && !fourier_starts_at_rest(&sin_rad, &cos_rad) {
                    return Err("a Fourier series must start at rest: sum k sin_k = 0 and sum k^2 cos_k = 0");
                }
                fine
            }
            Trajectory::Grip {
                force_n,
                approach_rad_s,
            } => {
                let force = force_n.is_finite() && force_n != 0.0 && force_n.abs() <= MAX_GRIP_N;
                let speed = approach_rad_s.is_finite()
                    && approach_rad_s > 0.0
                    && approach_rad_s <= MAX_APPROACH_RAD_S;
                if !(force && speed) {
                    return Err(
                        "a grip needs 0 < |force_n| <= 10 N and 0 < approach_rad_s <= 1 rad/s",
                    );
                }
                true
            }
        };
        if ok {
            Ok(())
        } else {
            Err("finite, angles within ±10 rad, 0 < frequency <= 100 Hz, 0 <= duration <= 1e5 s")
        }
    }

    /// Evaluate at `t_s` seconds after the command started (`t_s >= 0`).
    pub fn at(&self, t_s: f32) -> Reference {
        let t_s = if t_s > 0.0 { t_s } else { 0.0 };
        match *self {
            Trajectory::Hold { angle_rad } => Reference {
                angle_rad,
                vel_rad_s: 0.0,
            },
            Trajectory::Sine {
                offset_rad,
                amplitude_rad,
                freq_hz,
            } => {
                let w = 2.0 * PI * freq_hz;
                Reference {
                    angle_rad: offset_rad + amplitude_rad * math::sin(w * t_s),
                    vel_rad_s: amplitude_rad * w * math::cos(w * t_s),
                }
            }
            Trajectory::PointToPoint {
                from_rad,
                to_rad,
                duration_s,
            } => {
                if duration_s <= 0.0 || t_s >= duration_s {
                    return Reference {
                        angle_rad: to_rad,
                        vel_rad_s: 0.0,
                    };
                }
                let s = t_s / duration_s;
                let s3 = s * s * s;
                // 10 s^3 - 15 s^4 + 6 s^5 and its derivative 30 s^2 (1 - s)^2.
                let p = s3 * (10.0 - 15.0 * s + 6.0 * s * s);
                let dp = 30.0 * s * s * (1.0 - s) * (1.0 - s) / duration_s;
                let span = to_rad - from_rad;
                Reference {
                    angle_rad: from_rad + span * p,
                    vel_rad_s: span * dp,
                }
            }
            Trajectory::Complex {
                amplitude_rad,
                base_freq_hz,
            } => {
                let w0 = 2.0 * PI * base_freq_hz;
                let (mut a, mut v) = (0.0, 0.0);
                for (share, mult) in COMPLEX {
                    let w = w0 * mult;
                    a += share * math::sin(w * t_s);
                    v += share * w * math::cos(w * t_s);
                }
                // Fade-in over the first base period: f(s) = s^2 (3 - 2 s).
                let period_s = 1.0 / base_freq_hz;
                let (f, df) = if t_s < period_s {
                    let s = t_s / period_s;
                    (s * s * (3.0 - 2.0 * s), 6.0 * s * (1.0 - s) / period_s)
                } else {
                    (1.0, 0.0)
                };
                Reference {
                    angle_rad: amplitude_rad * f * a,
                    vel_rad_s: amplitude_rad * (f * v + df * a),
                }
            }
            Trajectory::Fourier {
                offset_rad,
                base_freq_hz,
                sin_rad,
                cos_rad,
            } => {
                // Phase within the period, so that the argument stays small
                // however long the run (the cast saturates, never panics).
                let cycles = t_s * base_freq_hz;
                let phase = 2.0 * PI * (cycles - (cycles as u32) as f32);
                let w = 2.0 * PI * base_freq_hz;
                let (s1, c1) = (math::sin(phase), math::cos(phase));
                // sin/cos of k * phase by the angle-sum recurrence: two
                // transcendentals per tick instead of ten.
                let (mut sk, mut ck) = (s1, c1);
                let (mut a, mut v) = (0.0, 0.0);
                for (k, (&sa, &ca)) in sin_rad.iter().zip(cos_rad.iter()).enumerate() {
                    let kw = (k + 1) as f32 * w;
                    a += sa * sk + ca * (ck - 1.0);
                    v += kw * (sa * ck - ca * sk);
                    (sk, ck) = (sk * c1 + ck * s1, ck * c1 - sk * s1);
                }
                Reference {
                    angle_rad: offset_rad + a,
                    vel_rad_s: v,
                }
            }
            Trajectory::Grip { .. } => Reference::default(),
        }
    }

    /// Is this a grip (a force set point, not an angle law)?
    pub const fn is_grip(&self) -> bool {
        matches!(self, Trajectory::Grip { .. })
    }
}

/// Whether a Fourier series of these coefficients starts at rest: zero
/// velocity (`sum k sin_k = 0`) and zero acceleration (`sum k^2 cos_k = 0`),
/// to 1e-4 of the sums of magnitudes (TOML's decimal round trip and `f32`
/// rounding stay far below it).
fn fourier_starts_at_rest(sin_rad: &[f32; HARMONICS], cos_rad: &[f32; HARMONICS]) -> bool {
    let (mut vel, mut vel_scale, mut acc, mut acc_scale) = (0.0, 0.0, 0.0, 0.0);
    for (k, (&sa, &ca)) in sin_rad.iter().zip(cos_rad.iter()).enumerate() {
        let kf = (k + 1) as f32;
        vel += kf * sa;
        vel_scale += kf * math::abs(sa);
        acc += kf * kf * ca;
        acc_scale += kf * kf * math::abs(ca);
    }
    math::abs(vel) <= 1e-4 * vel_scale + 1e-9 && math::abs(acc) <= 1e-4 * acc_scale + 1e-9
}

#[cfg(test)]
mod tests {
    use super::*;

    fn numeric_velocity(tr: &Trajectory, t: f32) -> f32 {
        let h = 1e-3;
        (tr.at(t + h).angle_rad - tr.at(t - h).angle_rad) / (2.0 * h)
    }

    #[test]
    fn velocities_match_numeric_derivatives() {
        let cases = [
            Trajectory::Sine {
                offset_rad: 0.1,
                amplitude_rad: 0.5,
                freq_hz: 0.5,
            },
            Trajectory::PointToPoint {
                from_rad: -0.3,
                to_rad: 0.5,
                duration_s: 2.0,
            },
            Trajectory::Complex {
                amplitude_rad: 0.6,
                base_freq_hz: 0.2,
            },
            FOURIER,
        ];
        for tr in &cases {
            for k in 1..40 {
                let t = k as f32 * 0.13;
                let (an, nu) = (tr.at(t).vel_rad_s, numeric_velocity(tr, t));
                assert!(
                    (an - nu).abs() < 2e-3,
                    "{tr:?} at {t}: analytic {an} vs numeric {nu}"
                );
            }
        }
    }

    #[test]
    fn point_to_point_starts_and_ends_at_rest() {
        let tr = Trajectory::PointToPoint {
            from_rad: 0.0,
            to_rad: 0.6,
            duration_s: 1.5,
        };
        assert_eq!(tr.at(0.0).angle_rad, 0.0);
        assert_eq!(tr.at(0.0).vel_rad_s, 0.0);
        assert_eq!(tr.at(1.5).angle_rad, 0.6);
        assert_eq!(tr.at(9.0).vel_rad_s, 0.0);
        assert!(
            (tr.at(0.75).angle_rad - 0.3).abs() < 1e-6,
            "midpoint is half way"
        );
    }

    #[test]
    fn complex_starts_at_rest_and_stays_within_amplitude() {
        let tr = Trajectory::Complex {
            amplitude_rad: 0.5,
            base_freq_hz: 0.25,
        };
        assert_eq!(tr.at(0.0).angle_rad, 0.0);
        assert_eq!(tr.at(0.0).vel_rad_s, 0.0);
        let peak = (0..4000)
            .map(|k| tr.at(k as f32 * 0.005).angle_rad.abs())
            .fold(0.0, f32::max);
        assert!(peak <= 0.5 + 1e-6 && peak > 0.3, "peak {peak}");
    }

    /// Starts at rest: sum k sin_k = 0.1 - 0.2 + 0.3 - 0.2 + 0 = 0 and
    /// sum k^2 cos_k = 0.2 - 0.2 + 0 + 0 + 0 = 0 (up to rounding).
    const FOURIER: Trajectory = Trajectory::Fourier {
        offset_rad: 0.2,
        base_freq_hz: 0.3,
        sin_rad: [0.1, -0.1, 0.1, -0.05, 0.0],
        cos_rad: [0.2, -0.05, 0.0, 0.0, 0.0],
    };

    #[test]
    fn fourier_starts_at_its_offset_at_rest_and_repeats_every_period() {
        assert_eq!(FOURIER.validate(), Ok(()));
        let start = FOURIER.at(0.0);
        assert_eq!(start.angle_rad, 0.2);
        assert!(start.vel_rad_s.abs() < 1e-6, "{start:?}");
        let period_s = 1.0 / 0.3;
        for k in 0..50 {
            let t = k as f32 * 0.071;
            let (a, b) = (FOURIER.at(t), FOURIER.at(t + 3.0 * period_s));
            assert!(
                (a.angle_rad - b.angle_rad).abs() < 1e-5,
                "{t}: {a:?} vs {b:?}"
            );
            assert!(
                (a.vel_rad_s - b.vel_rad_s).abs() < 1e-4,
                "{t}: {a:?} vs {b:?}"
            );
        }
    }

    #[test]
    fn fourier_recurrence_matches_the_series_written_out() {
        let Trajectory::Fourier {
            offset_rad,
            base_freq_hz,
            sin_rad,
            cos_rad,
        } = FOURIER
        else {
            unreachable!()
        };
        for k in 0..200 {
            let t = k as f64 * 0.0173;
            let w = 2.0 * core::f64::consts::PI * f64::from(base_freq_hz);
            let mut want = f64::from(offset_rad);
            for h in 0..HARMONICS {
                let x = (h + 1) as f64 * w * t;
                want += f64::from(sin_rad[h]) * libm::sin(x)
                    + f64::from(cos_rad[h]) * (libm::cos(x) - 1.0);
            }
            let got = f64::from(FOURIER.at(t as f32).angle_rad);
            assert!((got - want).abs() < 2e-6, "t {t}: {got} vs {want}");
        }
    }

    #[test]
    fn validate_refuses_a_fourier_series_that_does_not_start_at_rest() {
        let moving = Trajectory::Fourier {
            offset_rad: 0.0,
            base_freq_hz: 0.2,
            sin_rad: [0.1, 0.0, 0.0, 0.0, 0.0],
            cos_rad: [0.0; HARMONICS],
        };
        assert!(moving.validate().unwrap_err().contains("start at rest"));
        let jerking = Trajectory::Fourier {
            offset_rad: 0.0,
            base_freq_hz: 0.2,
            sin_rad: [0.0; HARMONICS],
            cos_rad: [0.1, 0.0, 0.0, 0.0, 0.0],
        };
        assert!(jerking.validate().is_err());
        let huge = Trajectory::Fourier {
            offset_rad: 0.0,
            base_freq_hz: 0.2,
            sin_rad: [20.0, -10.0, 0.0, 0.0, 0.0],
            cos_rad: [0.0; HARMONICS],
        };
        assert!(huge.validate().unwrap_err().contains("10 rad"));
    }
}
