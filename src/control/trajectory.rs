//! Joint-angle reference generator: holds, sines, smooth point-to-point moves
//! and the seed's "complex trajectory" (Fig. 13), evaluated at a time since the
//! command started. Pure functions of time: no state, no allocation.

use crate::math::{self, PI};

/// A joint-angle reference, in joint radians.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
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
}

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
    /// bandwidth), durations within 0..=1e5 s. Returns what is wrong.
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
        }
    }
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
}
