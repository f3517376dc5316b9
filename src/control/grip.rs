//! Grip-force control: an admittance law on top of the position cascade
//! (issue "beyond one joint", item 3; seed 001 closes its loop on the
//! estimated contact force the same way, through the position controller).
//!
//! The command [`Trajectory::Grip`](crate::trajectory::Trajectory::Grip)
//! asks for a tip force `F_set` instead of an angle. Every tick the joint's
//! angle reference moves at
//!
//! ```text
//! theta_ref' = clamp( K (F_set - F_hat)  -  w_c (theta_ref - theta_ref_partner) / 2 , ±v_max )
//! ```
//!
//! and the PD/PI cascade follows it as in any joint-closed-loop command, so
//! every fault check of the control path stays in force. `F_hat` is the
//! fused estimate ([`crate::fusion`]); the second term exists only for a
//! pair of jaws closing on one object ([`GripPartner`], set each tick by
//! [`crate::joints::Joints::set_pair`]).
//!
//! # The gain, from the loop's physics
//!
//! In contact the tip force grows with the angle at the contact's stiffness
//! `k = dF/dtheta` (N/rad: the object's stiffness times the jaw's lever,
//! unknown before contact and ten times apart from soft to firm tissue).
//! The estimate reaches the law through the DOB's low-pass `Q` (cut-off
//! `g`, [`crate::config::DobConfig::cutoff_rad_s`]); the position loop is
//! much faster (`kp_pos` = 200 1/s by default) and is neglected. The loop
//! is then an integrator behind one lag, `L(s) = w_c g / (s (s + g))` with
//! `w_c = K k`; its damping is `0.5 sqrt(g / w_c)`. [`BANDWIDTH_OF_Q`] puts
//! `w_c` at `g / 8` (damping 1.4: no overshoot in the linear regime, with
//! margin for the cables' lag), and `K = w_c / k_hat` with `k_hat` measured
//! on the way in, so the force settles in about the same time on soft and
//! firm objects:
//!
//! * **Approach**: no stiffness measured yet, `K = 2 v_approach / |F_set|`
//!   and `v_max = v_approach`, so the jaw closes at the operator's
//!   `v_approach` until the estimate reads half the set point.
//! * **Contact** is declared when the estimate reaches [`CONTACT_SHARE`] of
//!   the set point; the angle and force there are kept. From then on the
//!   secant `k = (F_hat - F_c) / (theta_f - theta_c)` is measured whenever
//!   the jaw has moved [`MIN_SECANT_RAD`] beyond the contact point (or the
//!   force has risen by another [`CONTACT_SHARE`] of the set point, which a
//!   firm contact does first), with
//!   `theta_f` the cascade's feedback angle through the same low-pass `Q` as the force
//!   (so the estimate's lag does not bias the slope). `k_hat` keeps the
//!   largest secant seen: the gain only falls, the loop never speeds up on
//!   a noisy reading. `v_max` becomes `K |F_set|` (the law's own pace, at
//!   least `v_approach`): a soft object needs a long travel that the
//!   approach speed must not slow. A reading that falls back below half the
//!   contact threshold before any stiffness was measured was the estimate's
//!   own swing in free space (friction transients): contact is withdrawn.
//!
//! # What the law cannot promise
//!
//! It regulates the *estimate*. While a pair holds its object on the
//! motor's angle, each jaw's pin sticks with its friction against the
//! object's side: the jaw slid onto the object, and its drive's torque has
//! pressed that way since. The fused point estimate then takes that side's
//! kinetic level for the pin ([`crate::fusion::FusionIn::pressing_sign`];
//! at a hold with no such knowledge it takes zero, and reads the pin's
//! friction as force). Where that premise fails it is not used: a jaw
//! alone, pressing its object against the other jaw, which holds its
//! position stiffly, is thrown back at contact (invisibly to the gratings
//! while slider 2 sticks), and a pair on the JAE's angle rings, sliding
//! both ways; their pins' friction then sits anywhere in the band
//! (measured: docs/force.md, "The pin's friction in a grip"). The true
//! force still differs from the estimate by what remains of its error,
//! which the fused estimate's bound `[lo, hi]` brackets: at rest under
//! stiction that bound can be wide ([`crate::fusion`]), and no
//! force loop can hold the true force tighter than that. The host report
//! gives, per plant variant and object, the true force's error beside the
//! bound's width at the set point.
//!
//! # Safety
//!
//! * The reference never leads the cascade's feedback angle by more than
//!   [`LEASH_S`] of motion at the law's largest rate, so a jaw blocked by something rigid
//!   (or an estimate stuck low) cannot wind the reference up.
//! * The reference stays inside 90 % of the joint-angle fault limit.
//! * Probing ([`crate::probe`]) does not run during a grip: the reference
//!   is never at rest there.

use crate::filter::LowPass1;
use crate::math;
use crate::trajectory::Reference;

/// Crossover of the force loop as a share of the estimate's low-pass
/// cut-off (damping `0.5 sqrt(8)` = 1.4).
pub const BANDWIDTH_OF_Q: f32 = 0.125;
/// Share of the set point at which contact is declared.
pub const CONTACT_SHARE: f32 = 0.25;
/// Smallest motion past the contact point that measures the contact's
/// stiffness, rad (0.11°: twenty grating counts on the prototype's 5 mm
/// pulley, far above the grating's noise).
pub const MIN_SECANT_RAD: f32 = 2e-3;
/// How far the reference may lead the feedback angle, in seconds at the
/// largest rate the law allows.
pub const LEASH_S: f32 = 0.5;

/// The other jaw of a pair closing on one object: its force estimate and
/// its estimated angle, from the last tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GripPartner {
    /// The partner's fused force estimate, N.
    pub force_n: f32,
    /// The partner's angle reference, rad.
    pub angle_ref_rad: f32,
}

/// The law's constants, from the configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grip {
    /// Crossover `w_c`, rad/s.
    bandwidth_rad_s: f32,
    /// The estimate's low-pass, applied to the angle for the secant.
    q: LowPass1,
    period_s: f32,
}

/// The law's state; restarted with every new command.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GripState {
    /// Has the first tick of this grip set the reference?
    pub started: bool,
    /// Angle reference, rad.
    pub angle_ref_rad: f32,
    /// The feedback angle through `Q`, rad.
    pub theta_f_rad: f32,
    /// Contact point (filtered angle, force), once declared.
    pub contact: Option<(f32, f32)>,
    /// Largest contact stiffness measured, N/rad (0 until measured).
    pub stiffness_n_rad: f32,
}

/// One tick's inputs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GripIn {
    /// Set point, N (its sign says which way the jaw closes).
    pub set_n: f32,
    /// Free-space closing speed, rad/s (> 0).
    pub approach_rad_s: f32,
    /// This joint's fused force estimate, N.
    pub force_n: f32,
    /// The angle the cascade closes its loop on (the estimated angle in
    /// [`crate::Mode::JointClosedLoop`], the motor-implied angle in
    /// [`crate::Mode::MotorPosition`]), rad.
    pub angle_fb_rad: f32,
    /// The other jaw of a pair, if any.
    pub partner: Option<GripPartner>,
    /// The joint-angle fault limit, rad.
    pub max_angle_rad: f32,
}

/// The side a grip closes toward and presses on: its set point's sign
/// (+1 for a set point of zero).
pub fn side(set_n: f32) -> f32 {
    if set_n < 0.0 {
        -1.0
    } else {
        1.0
    }
}

impl Grip {
    /// The law for an estimate low-passed at `q_cutoff_rad_s`, ticking every
    /// `period_s`.
    pub fn new(q_cutoff_rad_s: f32, period_s: f32) -> Self {
        Self {
            bandwidth_rad_s: BANDWIDTH_OF_Q * q_cutoff_rad_s,
            q: LowPass1::new(q_cutoff_rad_s, period_s),
            period_s,
        }
    }

    /// One tick: the angle reference and its rate.
    pub fn update(&self, st: &mut GripState, inp: &GripIn) -> Reference {
        if !st.started {
            *st = GripState {
                started: true,
                angle_ref_rad: inp.angle_fb_rad,
                theta_f_rad: inp.angle_fb_rad,
                ..GripState::default()
            };
        }
        let theta_f = self.q.update(&mut st.theta_f_rad, inp.angle_fb_rad);
        let sign = side(inp.set_n);
        let set_abs = math::abs(inp.set_n).max(f32::MIN_POSITIVE);
        // A pair regulates the mean of both jaws' estimates: Eq. 5's clamp
        // force, signed so that a reading against the grip counts against.
        let force_n = match inp.partner {
            Some(p) => 0.5 * (inp.force_n + p.force_n),
            None => inp.force_n,
        };
        match st.contact {
            None => {
                if sign * force_n >= CONTACT_SHARE * set_abs {
                    st.contact = Some((theta_f, force_n));
                }
            }
            // A reading that falls back below half the threshold before
            // any stiffness was measured was the estimate's own swing in
            // free space (friction transients), not a contact.
            Some(_)
                if st.stiffness_n_rad == 0.0 && sign * force_n < 0.5 * CONTACT_SHARE * set_abs =>
            {
                st.contact = None;
            }
            Some((theta_c, f_c)) => {
                let moved = sign * (theta_f - theta_c);
                let rise = sign * (force_n - f_c);
                // A firm contact reaches the set point within less than
                // MIN_SECANT_RAD: it is measured as soon as the force has
                // risen by another CONTACT_SHARE of the set point.
                if rise > 0.0
                    && moved > 0.0
                    && (moved >= MIN_SECANT_RAD || rise >= CONTACT_SHARE * set_abs)
                {
                    st.stiffness_n_rad = st.stiffness_n_rad.max(rise / moved);
                }
            }
        }
        // Before the stiffness is known the reference moves at most at the
        // approach speed; after, the linear law sets the pace (up to its
        // own rate at an error of the whole set point: a soft object needs
        // a long travel, which the approach speed must not slow).
        let (gain, max_rate) = if st.stiffness_n_rad > 0.0 {
            let gain = self.bandwidth_rad_s / st.stiffness_n_rad;
            (gain, (gain * set_abs).max(inp.approach_rad_s))
        } else {
            (2.0 * inp.approach_rad_s / set_abs, inp.approach_rad_s)
        };
        let mut rate = gain * (inp.set_n - force_n);
        if let Some(p) = inp.partner {
            rate -= 0.5 * self.bandwidth_rad_s * (st.angle_ref_rad - p.angle_ref_rad);
        }
        let rate = math::clamp(rate, -max_rate, max_rate);
        let leash = LEASH_S * max_rate;
        let limit = 0.9 * inp.max_angle_rad;
        let next = st.angle_ref_rad + rate * self.period_s;
        let next = math::clamp(next, inp.angle_fb_rad - leash, inp.angle_fb_rad + leash);
        st.angle_ref_rad = math::clamp(next, -limit, limit);
        Reference {
            angle_rad: st.angle_ref_rad,
            vel_rad_s: rate,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A jaw that follows its reference exactly against a spring of
    /// `k` N/rad from `theta_c`, the estimate the true force through `Q`.
    fn close_on_spring(k: f32, set_n: f32, seconds: f32) -> (f32, f32, f32) {
        let period_s = 5e-4;
        let cutoff = 2.0 * math::PI * 10.0;
        let grip = Grip::new(cutoff, period_s);
        let q = LowPass1::new(cutoff, period_s);
        let (mut st, mut f_hat) = (GripState::default(), 0.0);
        let (theta_c, mut theta) = (0.05, 0.0);
        let mut peak: f32 = 0.0;
        let force = |theta: f32| {
            if theta > theta_c {
                k * (theta - theta_c)
            } else {
                0.0
            }
        };
        for _ in 0..(seconds / period_s) as usize {
            let r = grip.update(
                &mut st,
                &GripIn {
                    set_n,
                    approach_rad_s: 0.1,
                    force_n: f_hat,
                    angle_fb_rad: theta,
                    partner: None,
                    max_angle_rad: 1.5,
                },
            );
            theta = r.angle_rad;
            let f = force(theta);
            q.update(&mut f_hat, f);
            peak = peak.max(f);
        }
        (force(theta), peak, st.stiffness_n_rad)
    }

    #[test]
    fn the_force_settles_on_the_set_point_on_soft_and_firm_contacts_without_overshoot() {
        for k in [40.0, 400.0] {
            let (f, peak, k_hat) = close_on_spring(k, 2.0, 3.0);
            assert!((f - 2.0).abs() < 0.02, "k {k}: force {f}");
            // No overshoot beyond the settling tolerance.
            assert!(peak < 2.0 + 0.02, "k {k}: peak {peak}");
            assert!(
                k_hat > 0.5 * k && k_hat < 1.5 * k,
                "k {k}: measured {k_hat}"
            );
        }
    }

    #[test]
    fn a_negative_set_point_closes_the_other_way() {
        let period_s = 5e-4;
        let grip = Grip::new(60.0, period_s);
        let mut st = GripState::default();
        let r = grip.update(
            &mut st,
            &GripIn {
                set_n: -1.0,
                approach_rad_s: 0.1,
                max_angle_rad: 1.5,
                ..GripIn::default()
            },
        );
        assert!(r.vel_rad_s < 0.0 && r.angle_rad < 0.0);
    }

    #[test]
    fn the_reference_cannot_wind_up_against_a_blocked_jaw() {
        let period_s = 5e-4;
        let grip = Grip::new(60.0, period_s);
        let mut st = GripState::default();
        let mut r = Reference::default();
        for _ in 0..20_000 {
            // The jaw stays at 0 and the estimate reads nothing.
            r = grip.update(
                &mut st,
                &GripIn {
                    set_n: 1.0,
                    approach_rad_s: 0.1,
                    max_angle_rad: 1.5,
                    ..GripIn::default()
                },
            );
        }
        assert!(
            (r.angle_rad - LEASH_S * 0.1).abs() < 1e-6,
            "{}",
            r.angle_rad
        );
    }

    #[test]
    fn a_pair_regulates_the_mean_force_and_pulls_the_jaws_together() {
        let period_s = 5e-4;
        let grip = Grip::new(60.0, period_s);
        let mut st = GripState::default();
        let inp = GripIn {
            set_n: 1.0,
            approach_rad_s: 0.1,
            force_n: 1.4,
            angle_fb_rad: 0.0,
            partner: Some(GripPartner {
                force_n: 0.6,
                angle_ref_rad: 0.0,
            }),
            max_angle_rad: 1.5,
        };
        // Mean 1.0 N and the jaws level: nothing to do.
        assert_eq!(grip.update(&mut st, &inp).vel_rad_s, 0.0);
        // This jaw ahead of its partner: it backs off.
        let ahead = GripIn {
            partner: Some(GripPartner {
                force_n: 0.6,
                angle_ref_rad: -0.01,
            }),
            ..inp
        };
        assert!(grip.update(&mut st, &ahead).vel_rad_s < 0.0);
    }
}
