//! Filters and differentiators, configuration split from state.
//!
//! * [`LowPass1`]: the DOB's `g/(s+g)`, discretized exactly (zero-order hold):
//!   `y[k+1] = a y[k] + (1 - a) u[k]`, `a = exp(-g T)`.
//! * [`TrackingObserver`]: position, velocity and acceleration from a quantized
//!   position, as a third-order tracking observer (constant-acceleration model,
//!   predictor-corrector, all three discrete poles at `exp(-w T)`). It tracks a
//!   ramp and a parabola without steady-state error, so its velocity has no lag
//!   at constant acceleration. This is the differentiator the core uses.
//! * [`Svf2`]: the classic second-order state-variable filter, kept as the
//!   comparison: its filtered position lags by `2ζ/ω` and its velocity and
//!   acceleration carry the phase lag of a low-pass. `filter::tests::
//!   observer_beats_svf_on_quantized_sine` measures both on the same quantized
//!   sine; the README quotes the numbers.
//! * [`SignMemory`]: a friction-direction sign that switches only above a speed
//!   threshold and holds below it, so a sign term does not chatter at
//!   standstill (stiction keeps the presliding direction).

use crate::math;

/// Exactly discretized first-order low-pass `g/(s+g)` (configuration).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LowPass1 {
    a: f32,
}

impl LowPass1 {
    /// Cut-off `g` in rad/s, period `T` in s.
    pub fn new(cutoff_rad_s: f32, period_s: f32) -> Self {
        Self {
            a: math::exp(-cutoff_rad_s * period_s),
        }
    }

    /// Pole `a = exp(-g T)`.
    pub fn pole(&self) -> f32 {
        self.a
    }

    /// One step: returns the new output `y[k+1]` from `y[k]` (state) and `u[k]`.
    #[inline]
    pub fn update(&self, y: &mut f32, u: f32) -> f32 {
        *y = self.a * *y + (1.0 - self.a) * u;
        *y
    }
}

/// State of a [`TrackingObserver`] or [`Svf2`]: position, velocity, acceleration.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Kinematics {
    /// Position (filtered / estimated), signal unit.
    pub pos: f32,
    /// Velocity, unit/s.
    pub vel: f32,
    /// Acceleration, unit/s².
    pub acc: f32,
}

/// Third-order tracking observer (configuration: period and gains).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackingObserver {
    t: f32,
    l: [f32; 3],
}

/// Characteristic-polynomial coefficients `[c2, c1, c0]` of `z^3 + c2 z^2 +
/// c1 z + c0` for the closed-loop matrix `(I - L H) F`.
fn observer_char_poly(t: f64, l: [f64; 3]) -> [f64; 3] {
    let f = [[1.0, t, 0.5 * t * t], [0.0, 1.0, t], [0.0, 0.0, 1.0]];
    // M = (I - L H) F, H = [1 0 0]: row i of M = F_i - l_i F_0.
    let mut m = [[0.0f64; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            m[i][j] = f[i][j] - l[i] * f[0][j];
        }
    }
    let tr = m[0][0] + m[1][1] + m[2][2];
    let minors = m[0][0] * m[1][1] - m[0][1] * m[1][0] + m[0][0] * m[2][2] - m[0][2] * m[2][0]
        + m[1][1] * m[2][2]
        - m[1][2] * m[2][1];
    let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    [-tr, minors, -det]
}

fn det3(a: [[f64; 3]; 3]) -> f64 {
    a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
        - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
        + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
}

impl TrackingObserver {
    /// Observer with all three discrete poles at `exp(-2π bw T)`.
    ///
    /// The characteristic polynomial of `(I - L H) F` is affine in the gain
    /// vector `L`, so the gains that place the poles solve a 3×3 linear system
    /// (computed once, in `f64`).
    pub fn new(bandwidth_hz: f32, period_s: f32) -> Self {
        let t = period_s as f64;
        let p = libm::exp(-2.0 * core::f64::consts::PI * bandwidth_hz as f64 * t);
        let want = [-3.0 * p, 3.0 * p * p, -p * p * p];
        let c0 = observer_char_poly(t, [0.0; 3]);
        let mut jac = [[0.0f64; 3]; 3];
        for k in 0..3 {
            let mut e = [0.0; 3];
            e[k] = 1.0;
            let ck = observer_char_poly(t, e);
            for (i, row) in jac.iter_mut().enumerate() {
                row[k] = ck[i] - c0[i];
            }
        }
        let rhs = [want[0] - c0[0], want[1] - c0[1], want[2] - c0[2]];
        let d = det3(jac);
        let mut l = [0.0f32; 3];
        for (k, lk) in l.iter_mut().enumerate() {
            let mut a = jac;
            for i in 0..3 {
                a[i][k] = rhs[i];
            }
            *lk = (det3(a) / d) as f32;
        }
        Self { t: period_s, l }
    }

    /// The gains `[l_pos, l_vel, l_acc]` (for inspection and tests).
    pub fn gains(&self) -> [f32; 3] {
        self.l
    }

    /// Initialise the state at rest at `pos`.
    pub fn reset(&self, state: &mut Kinematics, pos: f32) {
        *state = Kinematics {
            pos,
            vel: 0.0,
            acc: 0.0,
        };
    }

    /// One step with the new measurement `y`; returns the updated estimate.
    #[inline]
    pub fn update(&self, s: &mut Kinematics, y: f32) -> Kinematics {
        let t = self.t;
        let pos = s.pos + t * s.vel + 0.5 * t * t * s.acc;
        let vel = s.vel + t * s.acc;
        let e = y - pos;
        s.pos = pos + self.l[0] * e;
        s.vel = vel + self.l[1] * e;
        s.acc += self.l[2] * e;
        *s
    }
}

/// Second-order state-variable filter `w²/(s² + 2ζws + w²)`, exactly
/// discretized (zero-order hold). Kept for comparison with the observer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Svf2 {
    phi: [[f32; 2]; 2],
    gamma: [f32; 2],
    w: f32,
    zeta: f32,
}

impl Svf2 {
    /// Filter with natural frequency `bw` Hz and damping `zeta`.
    pub fn new(bandwidth_hz: f32, zeta: f32, period_s: f32) -> Self {
        let w = 2.0 * core::f64::consts::PI * bandwidth_hz as f64;
        let z = zeta as f64;
        let t = period_s as f64;
        // e^{A t} by scaling and squaring of a Taylor series (2×2, f64).
        let a = [[0.0, 1.0], [-w * w, -2.0 * z * w]];
        let mut sq = 0u32;
        let mut h = t;
        while h * w > 0.05 {
            h *= 0.5;
            sq += 1;
        }
        let mul = |x: [[f64; 2]; 2], y: [[f64; 2]; 2]| {
            let mut r = [[0.0; 2]; 2];
            for i in 0..2 {
                for j in 0..2 {
                    r[i][j] = x[i][0] * y[0][j] + x[i][1] * y[1][j];
                }
            }
            r
        };
        let ah = [[a[0][0] * h, a[0][1] * h], [a[1][0] * h, a[1][1] * h]];
        let mut e = [[1.0, 0.0], [0.0, 1.0]];
        let mut term = [[1.0, 0.0], [0.0, 1.0]];
        for k in 1..12 {
            term = mul(term, ah);
            let inv = 1.0 / k as f64;
            for i in 0..2 {
                for j in 0..2 {
                    term[i][j] *= inv;
                    e[i][j] += term[i][j];
                }
            }
        }
        for _ in 0..sq {
            e = mul(e, e);
        }
        // Gamma = A^-1 (Phi - I) B with B = [0, w²]; A^-1 = [[-2ζ/w, -1/w²], [1, 0]].
        let pm = [[e[0][0] - 1.0, e[0][1]], [e[1][0], e[1][1] - 1.0]];
        let col = [pm[0][1] * w * w, pm[1][1] * w * w];
        let ainv = [[-2.0 * z / w, -1.0 / (w * w)], [1.0, 0.0]];
        let gamma = [
            ainv[0][0] * col[0] + ainv[0][1] * col[1],
            ainv[1][0] * col[0] + ainv[1][1] * col[1],
        ];
        Self {
            phi: [
                [e[0][0] as f32, e[0][1] as f32],
                [e[1][0] as f32, e[1][1] as f32],
            ],
            gamma: [gamma[0] as f32, gamma[1] as f32],
            w: w as f32,
            zeta,
        }
    }

    /// Initialise at rest at `pos`.
    pub fn reset(&self, state: &mut Kinematics, pos: f32) {
        *state = Kinematics {
            pos,
            vel: 0.0,
            acc: 0.0,
        };
    }

    /// One step with input `u`: acceleration is evaluated from the states
    /// before the update (`w²(u - x) - 2ζw v`), position and velocity after.
    #[inline]
    pub fn update(&self, s: &mut Kinematics, u: f32) -> Kinematics {
        let acc = self.w * self.w * (u - s.pos) - 2.0 * self.zeta * self.w * s.vel;
        let pos = self.phi[0][0] * s.pos + self.phi[0][1] * s.vel + self.gamma[0] * u;
        let vel = self.phi[1][0] * s.pos + self.phi[1][1] * s.vel + self.gamma[1] * u;
        *s = Kinematics { pos, vel, acc };
        *s
    }
}

/// Friction-direction sign with memory (configuration: the switching speed).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SignMemory {
    /// Speed above which the sign follows the velocity.
    pub switch_speed: f32,
}

impl SignMemory {
    /// Update the held sign (`state`, ±1 or 0 before the first motion).
    #[inline]
    pub fn update(&self, state: &mut f32, vel: f32) -> f32 {
        if vel > self.switch_speed {
            *state = 1.0;
        } else if vel < -self.switch_speed {
            *state = -1.0;
        }
        *state
    }

    /// The same, and the sign switches only once the position `pos` has
    /// also travelled `min_travel` from its extreme in the held direction
    /// (`state.anchor`): a differentiator that rings after a stop can cross
    /// the switching speed with the slider at rest, and only travel shows a
    /// reversal. `min_travel <= 0` is [`SignMemory::update`] exactly (the
    /// anchor is then not kept); the first sign (from 0) needs the speed
    /// alone.
    #[inline]
    pub fn update_travelled(
        &self,
        state: &mut HeldSign,
        vel: f32,
        pos: f32,
        min_travel: f32,
    ) -> f32 {
        if min_travel <= 0.0 {
            // Off: the plain sign, and the anchor is not kept.
            return self.update(&mut state.sign, vel);
        }
        let held = state.sign;
        if held == 0.0 {
            self.update(&mut state.sign, vel);
        } else if held < 0.0 && vel > self.switch_speed && pos - state.anchor >= min_travel {
            state.sign = 1.0;
        } else if held > 0.0 && vel < -self.switch_speed && state.anchor - pos >= min_travel {
            state.sign = -1.0;
        }
        // The furthest point in the held direction, by plain comparisons:
        // `f32::max`/`min` are calls into `fmaxf`/`fminf` on the Cortex-M4F
        // for their NaN rules, and positions are never NaN (grating counts
        // on the target, a log's cells are refused unless finite).
        let behind =
            (state.sign > 0.0 && pos < state.anchor) || (state.sign < 0.0 && pos > state.anchor);
        if state.sign != held || !behind {
            state.anchor = pos;
        }
        state.sign
    }
}

/// A [`SignMemory`]'s state with the position it has reached in the held
/// direction ([`SignMemory::update_travelled`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct HeldSign {
    /// Held sign (±1, or 0 before the first motion).
    pub sign: f32,
    /// Furthest position in the held direction since the sign was taken.
    pub anchor: f32,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::PI;

    /// A velocity that rings past the switching speed with the position at
    /// rest flips the plain sign and not the travelled one; a real reversal
    /// flips both, the travelled one once the slider has moved `min_travel`.
    #[test]
    fn a_ringing_velocity_at_rest_does_not_flip_the_travelled_sign() {
        let m = SignMemory { switch_speed: 2e-4 };
        let (mut plain, mut held) = (0.0f32, HeldSign::default());
        // Moving down 10 counts, then stopped at -10 um while the velocity
        // estimate overshoots to +2.4e-4 m/s.
        for k in 0..10 {
            let pos = -1e-6 * k as f32;
            m.update(&mut plain, -1e-3);
            m.update_travelled(&mut held, -1e-3, pos, 1e-6);
        }
        for v in [-5e-4, -1e-4, 1e-4, 2.4e-4, 1e-4, 0.0] {
            m.update(&mut plain, v);
            m.update_travelled(&mut held, v, -9e-6, 1e-6);
        }
        assert_eq!(plain, 1.0, "the plain sign follows the ringing");
        assert_eq!(held.sign, -1.0, "the travelled sign holds at rest");
        // A real reversal: up by half a count (held), then one count (flips).
        m.update_travelled(&mut held, 5e-4, -8.5e-6, 1e-6);
        assert_eq!(held.sign, -1.0);
        m.update_travelled(&mut held, 5e-4, -8e-6, 1e-6);
        assert_eq!(held.sign, 1.0);
        assert_eq!(held.anchor, -8e-6);
        // With no travel asked it is the plain sign, tick for tick.
        let (mut a, mut b) = (0.0f32, HeldSign::default());
        for (k, v) in [3e-4, -1e-4, -3e-4, 2.5e-4, 0.0, -2.1e-4]
            .iter()
            .enumerate()
        {
            let pos = 1e-6 * k as f32;
            assert_eq!(
                m.update(&mut a, *v),
                m.update_travelled(&mut b, *v, pos, 0.0)
            );
        }
    }

    /// The travel of a reversal counts from the furthest point reached in
    /// the held direction, in either direction: a slider that drifts back
    /// half a count slowly and then 0.7 of a count fast has travelled 1.2
    /// counts from its furthest point and flips; measured from where it
    /// stood before the fast part it would not.
    #[test]
    fn the_reversal_travel_counts_from_the_furthest_point_either_way() {
        let m = SignMemory { switch_speed: 2e-4 };
        for dir in [1.0f32, -1.0] {
            let mut held = HeldSign::default();
            for k in 0..=5 {
                m.update_travelled(&mut held, dir * 1e-3, dir * 1e-6 * k as f32, 1e-6);
            }
            assert_eq!((held.sign, held.anchor), (dir, dir * 5e-6));
            // Back half a count, slowly: held, and the furthest point kept.
            m.update_travelled(&mut held, -dir * 1e-4, dir * 4.5e-6, 1e-6);
            assert_eq!((held.sign, held.anchor), (dir, dir * 5e-6));
            // Back 0.7 of a count, fast: 1.2 counts from the furthest point.
            m.update_travelled(&mut held, -dir * 1e-3, dir * 3.8e-6, 1e-6);
            assert_eq!((held.sign, held.anchor), (-dir, dir * 3.8e-6));
        }
    }

    #[test]
    fn low_pass_step_matches_analytic_response() {
        let (g, t) = (2.0 * PI * 10.0, 1.0 / 2000.0);
        let lp = LowPass1::new(g, t);
        let mut y = 0.0;
        for k in 1..=400 {
            lp.update(&mut y, 1.0);
            let exact = 1.0 - libm::expf(-g * t * k as f32);
            assert!((y - exact).abs() < 2e-5, "step {k}: {y} vs {exact}");
        }
    }

    /// The observer as it runs (its `update`, in `f32`), not the gain
    /// design's polynomial: from an initial error with no measurement the
    /// estimate follows the error dynamics `(I - L H) F`, so with all three
    /// poles at `p` every later estimate satisfies Cayley–Hamilton's
    /// recurrence `x[k+3] = 3p x[k+2] - 3p² x[k+1] + p³ x[k]`. An observer
    /// designed 1 % off (40.4 Hz) breaks it by far more than `f32` rounding.
    #[test]
    fn observer_poles_are_where_asked() {
        let t = 1.0 / 2000.0f32;
        let p = libm::exp(-2.0 * core::f64::consts::PI * 40.0 * t as f64);
        let largest_residue = |bw: f32| {
            let obs = TrackingObserver::new(bw, t);
            let mut s = Kinematics {
                pos: 1.0,
                vel: 0.0,
                acc: 0.0,
            };
            let x: [f64; 60] = core::array::from_fn(|_| f64::from(obs.update(&mut s, 0.0).pos));
            // The estimate does decay (the recurrence alone holds for zero).
            assert!(x[0].abs() > 0.1 && x[59].abs() < 0.1 * x[0].abs());
            x.windows(4)
                .map(|w| (w[3] - 3.0 * p * w[2] + 3.0 * p * p * w[1] - p * p * p * w[0]).abs())
                .fold(0.0, f64::max)
        };
        let (here, off) = (largest_residue(40.0), largest_residue(40.4));
        assert!(here < 1e-6, "recurrence residue {here}");
        assert!(off > 20.0 * here, "1 % off: {off} against {here}");
    }

    #[test]
    fn observer_tracks_a_parabola_without_lag() {
        let t = 1.0 / 2000.0;
        let obs = TrackingObserver::new(30.0, t);
        let mut s = Kinematics::default();
        let acc = 0.2; // m/s²
        for k in 0..4000 {
            let time = k as f32 * t;
            obs.update(&mut s, 0.5 * acc * time * time);
        }
        let time = 3999.0 * t;
        assert!(
            (s.vel - acc * time).abs() < 1e-4,
            "vel {} vs {}",
            s.vel,
            acc * time
        );
        assert!((s.acc - acc).abs() < 1e-3, "acc {}", s.acc);
    }

    #[test]
    fn svf_step_settles_and_velocity_of_ramp_is_exact() {
        let t = 1.0 / 2000.0;
        let f = Svf2::new(30.0, 0.9, t);
        let mut s = Kinematics::default();
        for _ in 0..2000 {
            f.update(&mut s, 1.0);
        }
        assert!((s.pos - 1.0).abs() < 1e-4 && s.vel.abs() < 1e-3);
        let mut s = Kinematics::default();
        for k in 0..4000 {
            f.update(&mut s, 0.01 * k as f32 * t);
        }
        assert!((s.vel - 0.01).abs() < 1e-5, "ramp velocity {}", s.vel);
    }

    /// The measured comparison behind the choice of differentiator: a 1 Hz,
    /// 2 mm sine (slider 2 in a tracking run) quantized to 1 µm at 2 kHz.
    #[test]
    fn observer_beats_svf_on_quantized_sine() {
        let t = 1.0 / 2000.0;
        let (amp, w) = (2e-3f32, 2.0 * PI * 1.0);
        let obs = TrackingObserver::new(30.0, t);
        let svf = Svf2::new(30.0, 0.9, t);
        let (mut so, mut ss) = (Kinematics::default(), Kinematics::default());
        let (mut eo, mut es, mut n) = (0.0f64, 0.0f64, 0);
        for k in 0..8000 {
            let time = k as f32 * t;
            let x = libm::roundf(amp * math::sin(w * time) / 1e-6) * 1e-6;
            obs.update(&mut so, x);
            svf.update(&mut ss, x);
            if k >= 2000 {
                let v = amp * w * math::cos(w * time);
                eo += ((so.vel - v) as f64).powi(2);
                es += ((ss.vel - v) as f64).powi(2);
                n += 1;
            }
        }
        let (ro, rs) = (libm::sqrt(eo / n as f64), libm::sqrt(es / n as f64));
        assert!(
            ro < 0.5 * rs,
            "observer velocity RMSE {ro} m/s vs SVF {rs} m/s"
        );
    }

    #[test]
    fn sign_memory_holds_at_standstill() {
        let sm = SignMemory { switch_speed: 1e-4 };
        let mut s = 0.0;
        assert_eq!(sm.update(&mut s, 5e-5), 0.0);
        assert_eq!(sm.update(&mut s, 2e-4), 1.0);
        for v in [5e-5, -5e-5, 0.0, 9e-5] {
            assert_eq!(sm.update(&mut s, v), 1.0, "held through noise {v}");
        }
        assert_eq!(sm.update(&mut s, -2e-4), -1.0);
    }
}
