//! Fused tip-force estimate with a guaranteed-style bound (set membership).
//!
//! Two passive estimates of the tip force see the joint through different
//! friction (DESIGN.md §4):
//!
//! * the **DOB** (seed Eq. 17-21) sees cable 1's tension at the motor, so the
//!   friction of the motor/gearhead and of slider 1 (model C's `f_sc1` term)
//!   and of slider 2 and the joint pin (its `f_cp2` term) sit between it and
//!   the tip;
//! * the **cable stretch** (`tau = r [K_w1 (x1 - r theta) - K_w2 (r theta -
//!   x2)]`) sees the torque the two cables put on the joint, so only the
//!   joint pin's friction and the JAE's error (slider 2's friction band
//!   through `theta_hat`) sit between it and the tip.
//!
//! While an element slips its friction is its kinetic level with the sign of
//! the slip; while it sticks, its friction can be anything inside its static
//! band, and no passive sensor can tell which. So each estimate is an
//! **interval** of tip forces consistent with the measurements and the
//! friction bands:
//!
//! * element slipping (speed above the switching speed, or a net creep of
//!   [`crate::config::FusionConfig::creep_distance_m`] within
//!   [`crate::config::FusionConfig::creep_window_s`], and both sliders
//!   moving one way at speeds within [`TOGETHER_RATIO`] of each other, so
//!   the whole chain slips as one): friction `s f_c (1 ± kappa)`,
//!   `kappa` = [`crate::config::FusionConfig::kinetic_tolerance`];
//!   the joint pin's level may be only an upper bound
//!   ([`crate::config::FusionConfig::pin_identified`] false: the default's,
//!   or what `identify` writes when its runs cannot pin the pin down), and
//!   its slip friction is then anything in `s [0, f_c (1 + kappa)]`;
//! * element stuck: friction in `[-rho f_c, +rho f_c]`, `rho` =
//!   [`crate::config::FusionConfig::static_over_kinetic`].
//!
//! The fused estimate is the intersection of the DOB's and the stretch
//! interval (the set of forces both agree on). The DOB's interval narrows
//! it only when the JAE and model C are this machine's: with either still
//! the datasheet's ([`crate::config::JaeConfig::is_datasheet`],
//! [`crate::config::TensionConfig::is_datasheet`]) the elastic part it
//! subtracts is another machine's, and the bound is the stretch interval.
//! Its point estimate is the stretch estimate projected onto the
//! intersection: the pin's friction at
//! its kinetic level while both sliders slip one way (at any speeds: the
//! point's best guess of the sign; the middle of its slip band when the
//! level is only an upper bound); otherwise, when the command presses
//! toward a known side (a grip closing onto its object,
//! [`FusionIn::pressing_sign`]), its kinetic level against that side, and
//! zero when nothing says which side; the value is moved into the bound
//! when the bound rules it out. The report measures it against the
//! intersection's midpoint (the minimax point) on every plant variant.
//! When the two intervals do not overlap the models disagree (an
//! unmodelled effect, a wrong parameter): the bound becomes the hull of
//! both, the point the middle of the gap, and [`flags::INCONSISTENT`] is set,
//! so the bound widens instead of hiding the disagreement.
//!
//! Why set membership rather than a Kalman filter: the dominant error at
//! standstill is a bounded, *non-random*, slowly varying friction force
//! whose distribution nobody knows; a Kalman filter would need it as a
//! Gaussian with a variance and would report a covariance that is not a
//! bound. The report measures the bound's coverage on plant variants the
//! estimator was not tuned to.
//!
//! Every input is a quantity the core already has (grating positions and
//! speeds, the JAE, the DOB), so the fusion adds a few dozen floating-point
//! operations to the tick and no transcendental function.

use crate::filter::LowPass1;
use crate::math;

/// Bits of [`FusionOut::flags`].
pub mod flags {
    /// Slider 1 (with the motor side) is stuck: the DOB is blind to its
    /// friction band.
    pub const SLIDER1_STUCK: u8 = 1;
    /// Slider 2 is stuck: the JAE carries its friction band.
    pub const SLIDER2_STUCK: u8 = 2;
    /// The chain does not slip as one (sliders stuck or moving apart): every
    /// friction sign is unknown and its static band applies.
    pub const JOINT_STUCK: u8 = 4;
    /// The DOB and stretch intervals do not overlap (models disagree).
    pub const INCONSISTENT: u8 = 8;
    /// The estimate and bound are the means over the last whole period of
    /// the probing dither ([`crate::probe`]), not this tick's values.
    pub const PROBED: u8 = 16;
    /// Set by the controller, not the fusion: the payout stop
    /// (`cascade.payout_stop`) held the motor from unwinding this tick (its
    /// reading put cable 0 near slack while the motor kept paying out).
    pub const PAYOUT_STOPPED: u8 = 32;
    /// Set by the controller with [`PROBED`]: the joint did not follow the
    /// dither over the last whole period (slider 2 travelled no more than
    /// one grating count), so the period's mean is a
    /// passive estimate averaged, not friction averaged out; the dither's
    /// amplitude grows until the joint follows ([`crate::probe`]).
    pub const PROBE_STUCK: u8 = 64;
}

/// Largest ratio of the two sliders' speeds at which the chain still counts
/// as slipping as one (a factor of two: chosen before it was measured; the
/// report's coverage and accuracy barely move between 1.5 and 3,
/// docs/force.md).
pub const TOGETHER_RATIO: f32 = 2.0;

/// Friction bands and model constants the fusion needs, precomputed from the
/// configuration (see [`crate::config::FusionConfig`] and [`Fusion::new`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fusion {
    /// The DOB's `Q = g/(s+g)`: every band goes through it like the signals.
    q: LowPass1,
    /// `r / l_e`: tip force per N of cable tension.
    tip_per_tension: f32,
    /// `z_i / r_m`: N of cable tension per N·m at the motor.
    tension_per_torque: f32,
    /// `1 / l_e`, 1/m.
    tip_per_torque: f32,
    /// Model C's Coulomb terms, N (absolute values).
    f_sc1_n: f32,
    f_cp2_n: f32,
    /// Joint-pin Coulomb friction, N·m.
    pin_nm: f32,
    /// Whether `pin_nm` is a fitted level, not an upper bound: only then
    /// does [`FusionIn::pressing_sign`] count.
    pin_identified: bool,
    /// The pin's friction while the chain slips one way, as a centre and
    /// a half-width with the slip's sign to come, N·m: a fitted level
    /// `f (1 ± kappa)`; an upper bound anything from zero to `f (1 +
    /// kappa)` (its middle, `f (1 + kappa) / 2`, both ways).
    pin_slip_nm: f32,
    pin_slip_half_nm: f32,
    /// Torque error per rad of JAE error: `r² (K_w1 + K_w2)`, N·m/rad.
    torque_per_theta: f32,
    /// JAE band from slider 2's friction: `|c3|`, rad.
    c3_rad: f32,
    /// JAE band independent of friction (model error + one grating count), rad.
    theta_floor_rad: f32,
    rho: f32,
    kappa: f32,
    /// Relative uncertainty of the stretch torque's scale (the cables'
    /// stiffnesses).
    scale_tol: f32,
    v1_m_s: f32,
    v2_m_s: f32,
    creep_ticks: u32,
    creep_m: f32,
    /// Whether the DOB's interval may narrow the bound: the JAE and model
    /// C are this machine's, not the datasheet's (see [`Fusion::update`]).
    dob_narrows: bool,
}

/// Slip detector of one element: velocity above the switching speed, or a
/// slow creep, i.e. a net displacement over a whole window in which the
/// element never moved fast (so the end of a fast motion is not taken for
/// creep).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SlipState {
    /// Position at the start of the current creep window, m.
    anchor_m: f32,
    /// Ticks since the window started.
    ticks: u32,
    /// Whether the element moved fast in the current window.
    fast_in_window: bool,
    /// Creep direction found over the last full window (±1, 0 = none).
    creep_sign: f32,
    /// Direction of the slip in this tick (±1, 0 = stuck).
    pub sign: f32,
    primed: bool,
}

impl SlipState {
    /// One tick: returns the slip direction (±1, 0 while stuck).
    #[inline]
    fn update(
        &mut self,
        pos_m: f32,
        vel_m_s: f32,
        switch_m_s: f32,
        ticks: u32,
        creep_m: f32,
    ) -> f32 {
        if !self.primed {
            *self = Self {
                anchor_m: pos_m,
                primed: true,
                ..Self::default()
            };
        }
        let fast = math::sign_eps(vel_m_s, switch_m_s);
        self.fast_in_window |= fast != 0.0;
        self.ticks += 1;
        if self.ticks >= ticks {
            self.creep_sign = if self.fast_in_window {
                0.0
            } else {
                math::sign_eps(pos_m - self.anchor_m, creep_m)
            };
            self.anchor_m = pos_m;
            self.ticks = 0;
            self.fast_in_window = false;
        }
        // A fast motion against the creep direction ends the creep.
        if fast != 0.0 && fast != self.creep_sign {
            self.creep_sign = 0.0;
        }
        self.sign = if fast != 0.0 { fast } else { self.creep_sign };
        self.sign
    }
}

/// State of the fusion (snapshot-able with the controller's state).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FusionState {
    /// Slider 1 (x1).
    pub slider1: SlipState,
    /// Slider 2 (x2), which also sets the joint's slip (the JAE's input).
    pub slider2: SlipState,
    /// `Q` of the lower and upper friction bound in cable 1's tension (the
    /// DOB's blind part), N.
    dob_friction_n: (f32, f32),
    /// `Q` of the lower and upper pin-friction bound, N·m.
    pin_nm: (f32, f32),
    /// `Q` of the pin friction the point estimate assumes, N·m.
    pin_point_nm: f32,
    /// Largest pressing torque (`pressing_sign` times the stretch torque)
    /// since the chain last slipped one way or the command last pressed
    /// toward no side, N·m (`None` since then).
    press_peak_nm: Option<f32>,
    /// `Q` of the stretch torque's error bound from the JAE, N·m.
    tau_err_nm: f32,
    /// `Q` of the drive torque's part above `Q`'s band, N·m.
    ripple_nm: f32,
    /// `Q` of the point estimate (`Q²` of the force), N: its distance from
    /// the point is the filter's lag, see [`Fusion::update`].
    point_q_n: f32,
    /// The two intervals this tick's bound was made of.
    pub sources: Sources,
    primed: bool,
}

/// The interval of tip forces each estimate allows in one tick, before
/// they are intersected (and before the bound widens by the low-pass's
/// lag): what another way of combining them would start from, e.g. the
/// Kalman filters the report measures this design against.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sources {
    /// The DOB's interval `(lo, hi)`, N.
    pub dob_n: (f32, f32),
    /// The cable stretch's interval `(lo, hi)`, N.
    pub stretch_n: (f32, f32),
}

/// What the fusion reads in one tick (all already computed by the step).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FusionIn {
    /// Slider 1 position and speed, m, m/s.
    pub x1_m: f32,
    /// Slider 1 speed, m/s.
    pub x1_vel_m_s: f32,
    /// Slider 2 position, m.
    pub x2_m: f32,
    /// Slider 2 speed, m/s.
    pub x2_vel_m_s: f32,
    /// DOB's cable-1 tension `Q[F_1_hat]`, N.
    pub tension1_dob_n: f32,
    /// The model's no-load tension through the same filter, `Q[F_1']`, N.
    pub tension1_model_n: f32,
    /// The Coulomb part of `F_1'` (model C's sign terms) through the same
    /// filter, N.
    pub tension1_friction_n: f32,
    /// Low-passed joint torque from the cables' stretch, N·m.
    pub joint_torque_nm: f32,
    /// Drive torque at the motor `K_m i - B_m phi'` in this tick, N·m.
    pub drive_torque_nm: f32,
    /// The same through `Q` (the DOB's state), N·m.
    pub drive_torque_q_nm: f32,
    /// The side the joint presses toward when the command knows it (±1: a
    /// grip, whose object is on the side of its set point), else 0. Counted
    /// only when the pin's level is a fitted one
    /// ([`crate::config::FusionConfig::pin_identified`]). While
    /// the chain does not slip one way, the point estimate takes the pin's
    /// friction at its kinetic level against that side instead of zero,
    /// less what the pressing torque has given back since its peak; the
    /// bound does not use it.
    pub pressing_sign: f32,
}

/// The fused estimate.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FusionOut {
    /// Point estimate (midpoint of the bound's core), N.
    pub f_ext_n: f32,
    /// Lower end of the bound, N.
    pub lo_n: f32,
    /// Upper end of the bound, N.
    pub hi_n: f32,
    /// [`flags`] bits.
    pub flags: u8,
}

/// Friction interval `[lo, hi]` of one Coulomb element of level `f`.
#[inline]
fn band(slipping: bool, sign: f32, f: f32, rho: f32, kappa: f32) -> (f32, f32) {
    if slipping {
        let c = sign * f;
        (c - kappa * f, c + kappa * f)
    } else {
        (-rho * f, rho * f)
    }
}

impl Fusion {
    /// Precompute from the configuration; `period_s` is the control period.
    pub fn new(c: &crate::Config, period_s: f32) -> Self {
        let m = &c.machine;
        let f = &c.fusion;
        let r = m.pulley_radius_m;
        let (pin_slip_nm, pin_slip_half_nm) = if f.pin_identified {
            (f.pin_coulomb_nm, f.kinetic_tolerance * f.pin_coulomb_nm)
        } else {
            let half = 0.5 * (1.0 + f.kinetic_tolerance) * f.pin_coulomb_nm;
            (half, half)
        };
        let ticks = (f.creep_window_s / period_s) as u32;
        Self {
            q: LowPass1::new(c.dob.cutoff_rad_s, period_s),
            tip_per_tension: r / m.gripper_length_m,
            tension_per_torque: m.gear_ratio / m.rope_wheel_radius_m,
            tip_per_torque: 1.0 / m.gripper_length_m,
            f_sc1_n: math::abs(c.tension.f_sc1_n),
            f_cp2_n: math::abs(c.tension.f_cp2_n),
            pin_nm: f.pin_coulomb_nm,
            pin_identified: f.pin_identified,
            pin_slip_nm,
            pin_slip_half_nm,
            torque_per_theta: r * r * (c.stretch.cable1_n_m + c.stretch.cable2_n_m),
            c3_rad: math::abs(c.jae.c_sign_rad),
            theta_floor_rad: f.jae_error_rad + c.jae.c_pos_rad_m * c.scales.grating_m_per_count,
            rho: f.static_over_kinetic,
            scale_tol: f.stiffness_tolerance,
            kappa: f.kinetic_tolerance,
            v1_m_s: c.tension.sign_switch_x1_m_s,
            v2_m_s: c.jae.sign_switch_m_s,
            creep_ticks: if ticks == 0 { 1 } else { ticks },
            creep_m: f.creep_distance_m,
            dob_narrows: !(c.jae.is_datasheet() || c.tension.is_datasheet()),
        }
    }

    /// One tick.
    #[inline]
    pub fn update(&self, s: &mut FusionState, i: &FusionIn) -> FusionOut {
        let s1 = s.slider1.update(
            i.x1_m,
            i.x1_vel_m_s,
            self.v1_m_s,
            self.creep_ticks,
            self.creep_m,
        );
        let s2 = s.slider2.update(
            i.x2_m,
            i.x2_vel_m_s,
            self.v2_m_s,
            self.creep_ticks,
            self.creep_m,
        );
        let (rho, kappa) = (self.rho, self.kappa);
        // Model C lumps frictions whose elements may move apart (the motor's
        // with slider 1's or slider 2's, depending on the machine), and the
        // JAE does not see the pin directly: a friction sign is taken as
        // known only while the whole chain slips one way, together. When
        // the chain slides as one, both sliders follow the joint
        // (`x1' ≈ x2' ≈ r theta'`, the cables' stretch rates small); when
        // their speeds differ by more than [`TOGETHER_RATIO`], a cable is
        // stretching or relaxing against something stuck (after a stick-slip
        // jump of the pin, slider 1 runs on at many times slider 2's speed
        // while the joint stands still), and the pin's sign is not known.
        let v1 = math::abs(i.x1_vel_m_s);
        let v2 = math::abs(i.x2_vel_m_s);
        let together = (v1 <= TOGETHER_RATIO * v2 && v2 <= TOGETHER_RATIO * v1)
            || (v1 < self.v1_m_s && v2 < self.v2_m_s);
        // The point estimate takes the pin's kinetic level whenever both
        // sliders slip one way (its best guess of the sign); only the bound
        // needs them to slip together.
        let one_way = s1 != 0.0 && s1 == s2;
        let coherent = one_way && together;

        // Instantaneous friction bounds; `Q` (a positive filter) of a bound
        // bounds `Q` of the friction, so they are filtered like the signals.
        let (a_lo, a_hi) = band(coherent, s1, self.f_sc1_n, rho, kappa);
        let (b_lo, b_hi) = band(coherent, s2, self.f_cp2_n, rho, kappa);
        // The pin's slip band is its own: an upper bound (a level no run
        // pinned down) says nothing of how far below it the pin slides.
        let (p_lo, p_hi) = if coherent {
            let c = s2 * self.pin_slip_nm;
            (c - self.pin_slip_half_nm, c + self.pin_slip_half_nm)
        } else {
            (-rho * self.pin_nm, rho * self.pin_nm)
        };
        let theta_band = self.theta_floor_rad
            + if coherent {
                kappa * self.c3_rad
            } else {
                (1.0 + rho) * self.c3_rad
            };
        let tau_err = self.torque_per_theta * theta_band;
        // The point's pin friction: a one-way slip's kinetic level with its
        // sign; else, while the command presses toward a known side (a grip
        // closing onto its object: the pin last slid that way, and the
        // drive's torque has pressed that way since), the kinetic level
        // against that side, less whatever the pressing torque has given
        // back since its peak (a stuck joint on an elastic object holds its
        // force, so the pin takes the change), down to zero; else zero.
        let pressing = if self.pin_identified {
            i.pressing_sign
        } else {
            0.0
        };
        let (pp_lo, pp_hi) = if one_way {
            s.press_peak_nm = None;
            (s2 * self.pin_slip_nm, s2 * self.pin_slip_nm)
        } else if pressing != 0.0 {
            let press_nm = pressing * i.joint_torque_nm;
            let peak_nm = match s.press_peak_nm {
                Some(peak_nm) if peak_nm >= press_nm => peak_nm,
                _ => press_nm,
            };
            s.press_peak_nm = Some(peak_nm);
            let given_back_nm = peak_nm - press_nm;
            let f = pressing * math::clamp(self.pin_nm - given_back_nm, 0.0, self.pin_nm);
            (f, f)
        } else {
            s.press_peak_nm = None;
            (0.0, 0.0)
        };
        let first = !s.primed;
        if first {
            s.dob_friction_n = (a_lo + b_lo, a_hi + b_hi);
            s.pin_nm = (p_lo, p_hi);
            s.pin_point_nm = 0.5 * (pp_lo + pp_hi);
            s.tau_err_nm = tau_err;
            s.ripple_nm = 0.0;
            s.primed = true;
        }
        let q = &self.q;
        let f_lo = q.update(&mut s.dob_friction_n.0, a_lo + b_lo);
        let f_hi = q.update(&mut s.dob_friction_n.1, a_hi + b_hi);
        let pin_lo = q.update(&mut s.pin_nm.0, p_lo);
        let pin_hi = q.update(&mut s.pin_nm.1, p_hi);
        let pin_point_nm = q.update(&mut s.pin_point_nm, 0.5 * (pp_lo + pp_hi));
        let tau_err = q.update(&mut s.tau_err_nm, tau_err);
        // Drive torque above Q's band mostly accelerates the rotor, and the
        // DOB's inertial term sees that through a differentiator: while the
        // current chatters (a limit cycle, a fast move) the DOB's tension is
        // no better than that ripple, so its interval widens by it.
        let ripple_nm = q.update(
            &mut s.ripple_nm,
            math::abs(i.drive_torque_nm - i.drive_torque_q_nm),
        );
        let ripple_n = ripple_nm * self.tension_per_torque;

        // DOB interval: F_ext = (F_1_hat - elastic - friction) r / l_e with the
        // Coulomb terms of model C in their bands.
        // With the datasheet's JAE or model C (a configuration not yet
        // identified on this machine) the elastic part subtracted here is
        // the seed's machine's, and its error is in no band: the interval
        // is then everything, so it does not narrow the bound. On drawn
        // plants at 500 Hz it had held the true zero in 58 % of a no-load
        // run's ticks (docs/force.md, "A datasheet configuration at 500 Hz").
        let base_n = i.tension1_dob_n - (i.tension1_model_n - i.tension1_friction_n);
        let (dob_lo, dob_hi) = if self.dob_narrows {
            (
                (base_n - f_hi - ripple_n) * self.tip_per_tension,
                (base_n - f_lo + ripple_n) * self.tip_per_tension,
            )
        } else {
            (f32::NEG_INFINITY, f32::INFINITY)
        };

        // Stretch interval: F_ext = (tau - pin friction) / l_e, with tau's own
        // error from the JAE band (slider 2's friction and the model floor)
        // and from the cables' stiffness scale (a share of tau itself).
        let tau_err = tau_err + self.scale_tol * math::abs(i.joint_torque_nm);
        let str_lo = (i.joint_torque_nm - tau_err - pin_hi) * self.tip_per_torque;
        let str_hi = (i.joint_torque_nm + tau_err - pin_lo) * self.tip_per_torque;
        s.sources = Sources {
            dob_n: (dob_lo, dob_hi),
            stretch_n: (str_lo, str_hi),
        };

        let mut flags = 0;
        if s1 == 0.0 {
            flags |= flags::SLIDER1_STUCK;
        }
        if s2 == 0.0 {
            flags |= flags::SLIDER2_STUCK;
        }
        if !coherent {
            flags |= flags::JOINT_STUCK;
        }
        let lo = if dob_lo > str_lo { dob_lo } else { str_lo };
        let hi = if dob_hi < str_hi { dob_hi } else { str_hi };
        let mut out = if lo <= hi {
            // The stretch estimate with the pin's friction at its point
            // value (its kinetic level in a one-way slip, else zero), moved
            // into the bound when the bound rules it out.
            let stretch_n = (i.joint_torque_nm - pin_point_nm) * self.tip_per_torque;
            FusionOut {
                f_ext_n: math::clamp(stretch_n, lo, hi),
                lo_n: lo,
                hi_n: hi,
                flags,
            }
        } else {
            // No overlap: the middle of the gap, the hull as the bound.
            FusionOut {
                f_ext_n: 0.5 * (lo + hi),
                lo_n: if dob_lo < str_lo { dob_lo } else { str_lo },
                hi_n: if dob_hi > str_hi { dob_hi } else { str_hi },
                flags: flags | flags::INCONSISTENT,
            }
        };
        // Everything above bounds `Q[F]`, the force through the DOB's
        // low-pass, not `F`. For a first-order `Q`, `F - Q[F] = Q[F]' / g`:
        // while the force changes, it runs ahead of the bound by its rate
        // over `g`. That lag, through `Q` once more, is `Q[F] - Q²[F]`,
        // computed here from the point estimate without differentiating.
        // The bound widens by it on the side the force is moving to. (It
        // sees a ramp's lag one `1/g` late and holds it as long after the
        // ramp ends, so it never narrows the bound, and at rest it is the
        // point's own noise through a band-pass.)
        if first {
            s.point_q_n = out.f_ext_n;
        }
        let lag_n = out.f_ext_n - self.q.update(&mut s.point_q_n, out.f_ext_n);
        if lag_n > 0.0 {
            out.hi_n += lag_n;
        } else {
            out.lo_n += lag_n;
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Config;

    /// The datasheet configuration with the JAE's offset and model C's
    /// preload moved off the datasheet's, as an identification on this
    /// machine leaves them: the DOB's interval counts.
    fn identified() -> Config {
        let mut c = Config::default();
        c.jae.offset_rad = 1e-5;
        c.tension.f_0_n += 0.01;
        c
    }

    fn fusion() -> (Fusion, Config) {
        let c = identified();
        (Fusion::new(&c, c.period_s()), c)
    }

    /// At rest with no load, both intervals contain zero and the bound is
    /// the narrower stretch band: pin friction and the JAE band.
    #[test]
    fn at_rest_the_bound_is_the_stretch_band() {
        let (f, c) = fusion();
        let mut s = FusionState::default();
        let input = FusionIn {
            tension1_dob_n: c.tension.f_0_n,
            tension1_model_n: c.tension.f_0_n,
            ..FusionIn::default()
        };
        let mut out = FusionOut::default();
        for _ in 0..1000 {
            out = f.update(&mut s, &input);
        }
        assert_eq!(
            out.flags & (flags::SLIDER1_STUCK | flags::SLIDER2_STUCK),
            flags::SLIDER1_STUCK | flags::SLIDER2_STUCK
        );
        assert!(out.lo_n < 0.0 && out.hi_n > 0.0, "{out:?}");
        let rho = c.fusion.static_over_kinetic;
        let r = c.machine.pulley_radius_m;
        let theta = c.fusion.jae_error_rad
            + c.jae.c_pos_rad_m * c.scales.grating_m_per_count
            + (1.0 + rho) * c.jae.c_sign_rad;
        let half = (rho * c.fusion.pin_coulomb_nm
            + r * r * (c.stretch.cable1_n_m + c.stretch.cable2_n_m) * theta)
            / c.machine.gripper_length_m;
        assert!((out.hi_n - half).abs() < 1e-4 && (out.lo_n + half).abs() < 1e-4);
        assert!(out.f_ext_n.abs() < 1e-5);
    }

    /// A held load: the stretch interval widens by the stiffness scale's
    /// share of the stretch torque, `tol |tau| / l_e` on each side, and not
    /// at all without a load; the point estimate does not move. A stretch
    /// that reads a load 10 % high (a spring 10 % stiffer than the plant's)
    /// is still bounded with the default ±10 %.
    #[test]
    fn the_stretch_interval_widens_by_the_stiffness_scale_under_a_load() {
        let held = |tol: f32, load_n: f32| {
            let mut c = Config::default();
            c.fusion.stiffness_tolerance = tol;
            // A DOB interval wide enough that the stretch interval decides,
            // and no friction or JAE band: the scale's share stands alone.
            c.tension.f_sc1_n = 50.0;
            c.fusion.pin_coulomb_nm = 0.0;
            c.fusion.jae_error_rad = 0.0;
            c.jae.c_sign_rad = 0.0;
            let f = Fusion::new(&c, c.period_s());
            let mut s = FusionState::default();
            let mut out = FusionOut::default();
            for _ in 0..2000 {
                out = f.update(
                    &mut s,
                    &FusionIn {
                        tension1_dob_n: c.tension.f_0_n,
                        tension1_model_n: c.tension.f_0_n,
                        joint_torque_nm: load_n * c.machine.gripper_length_m,
                        ..FusionIn::default()
                    },
                );
            }
            out
        };
        let c = Config::default();
        let tol = c.fusion.stiffness_tolerance;
        assert!(tol > 0.0);
        let (bare, scaled) = (held(0.0, 2.0), held(tol, 2.0));
        let widened = (scaled.hi_n - bare.hi_n, bare.lo_n - scaled.lo_n);
        assert!(
            (widened.0 - tol * 2.0).abs() < 1e-4 && (widened.1 - tol * 2.0).abs() < 1e-4,
            "{widened:?} for {tol} of 2 N"
        );
        assert!((scaled.f_ext_n - bare.f_ext_n).abs() < 1e-6);
        let (bare0, scaled0) = (held(0.0, 0.0), held(tol, 0.0));
        assert!(
            (scaled0.hi_n - bare0.hi_n).abs() < 1e-6 && (scaled0.lo_n - bare0.lo_n).abs() < 1e-6
        );
        // A stretch reading 10 % high: the true 2 N is outside the bare
        // interval and inside the scaled one.
        assert!(held(0.0, 2.2).lo_n > 2.0);
        let high = held(tol, 2.2);
        assert!(high.lo_n <= 2.0, "{high:?}");
    }

    /// A load seen by both estimates: the bound contains it, and where the
    /// two intervals overlap without one holding the other (here the
    /// stretch reads 0.3 N high, inside its band) the intersection is
    /// tighter than either interval alone.
    #[test]
    fn intersection_is_tighter_than_either_and_contains_a_consistent_load() {
        // The pin slips at its fitted level.
        let (_, mut c) = fusion();
        c.fusion.pin_identified = true;
        let f = Fusion::new(&c, c.period_s());
        let m = &c.machine;
        let load_n = 1.0;
        let tension = load_n * m.gripper_length_m / m.pulley_radius_m;
        let fric = c.tension.f_sc1_n + c.tension.f_cp2_n;
        let mut s = FusionState::default();
        let mut input = FusionIn {
            x1_vel_m_s: 1e-3,
            x2_vel_m_s: 1e-3,
            tension1_dob_n: c.tension.f_0_n + fric + tension,
            tension1_model_n: c.tension.f_0_n + fric,
            tension1_friction_n: fric,
            joint_torque_nm: (load_n + 0.3) * m.gripper_length_m + c.fusion.pin_coulomb_nm,
            ..FusionIn::default()
        };
        let mut out = FusionOut::default();
        for k in 0..100 {
            input.x1_m = k as f32 * 1e-3 / c.control_rate_hz;
            input.x2_m = input.x1_m;
            out = f.update(&mut s, &input);
        }
        assert_eq!(out.flags, 0, "both sliders slip, consistent");
        assert!(out.lo_n <= load_n && load_n <= out.hi_n, "{out:?}");
        let width = |(lo, hi): (f32, f32)| hi - lo;
        let (dob, stretch) = (s.sources.dob_n, s.sources.stretch_n);
        assert!(
            dob.0 < stretch.0 && dob.1 < stretch.1,
            "overlapping, not nested: {:?}",
            s.sources
        );
        let fused = out.hi_n - out.lo_n;
        assert!(
            fused < width(dob) - 0.1 && fused < width(stretch) - 0.1,
            "{fused} N against {:?}",
            s.sources
        );
        assert!((out.f_ext_n - load_n).abs() < 0.5 * (out.hi_n - out.lo_n) + 1e-6);
    }

    /// A force that ramps runs ahead of everything filtered by `Q` by its
    /// rate over `g`; the bound widens by that lag on the side the force
    /// moves to, covers the true force through the ramp, and narrows back
    /// to the rest band once the force holds still.
    #[test]
    fn a_ramping_force_stays_inside_the_bound_despite_the_filter_lag() {
        // The lag alone: without the stiffness scale's share of the held
        // torque, the bound at the held force is the rest band again.
        let mut c = Config::default();
        c.fusion.stiffness_tolerance = 0.0;
        let f = Fusion::new(&c, c.period_s());
        let m = &c.machine;
        let g = c.dob.cutoff_rad_s;
        let dt = c.period_s();
        let q = LowPass1::new(g, dt);
        let rest = |s: &mut FusionState| {
            let mut out = FusionOut::default();
            for _ in 0..1000 {
                out = f.update(
                    s,
                    &FusionIn {
                        tension1_dob_n: c.tension.f_0_n,
                        tension1_model_n: c.tension.f_0_n,
                        ..FusionIn::default()
                    },
                );
            }
            out
        };
        let mut s = FusionState::default();
        let band = rest(&mut s);
        let half_n = band.hi_n;
        // Lag at the ramp's steady state: four half bands.
        let rate_n_s = 4.0 * half_n * g;
        let ramp_ticks = (8.0 / (g * dt)) as usize;
        let mut q_force_n = 0.0;
        let mut out = band;
        let mut beyond_filtered_band = 0;
        for k in 0..ramp_ticks + (20.0 / (g * dt)) as usize {
            let force_n = rate_n_s * dt * k.min(ramp_ticks) as f32;
            let filtered_n = q.update(&mut q_force_n, force_n);
            out = f.update(
                &mut s,
                &FusionIn {
                    tension1_dob_n: c.tension.f_0_n
                        + filtered_n * m.gripper_length_m / m.pulley_radius_m,
                    tension1_model_n: c.tension.f_0_n,
                    joint_torque_nm: filtered_n * m.gripper_length_m,
                    ..FusionIn::default()
                },
            );
            if k as f32 * g * dt > 3.0 {
                assert!(
                    out.lo_n <= force_n && force_n <= out.hi_n,
                    "tick {k}: {force_n} N outside {out:?}"
                );
                if force_n > filtered_n + half_n {
                    beyond_filtered_band += 1;
                }
            }
        }
        assert!(
            beyond_filtered_band > ramp_ticks / 2,
            "the ramp must outrun the unwidened bound ({beyond_filtered_band} ticks)"
        );
        let held_n = rate_n_s * dt * ramp_ticks as f32;
        assert!(
            (out.hi_n - out.lo_n - (band.hi_n - band.lo_n)).abs() < 1e-3 * held_n,
            "{out:?} against the rest band {band:?}"
        );
    }

    /// A pin level that is only an upper bound (the default's, or what
    /// `identify` writes when its runs cannot pin the pin down) bounds a
    /// slip's pin friction from zero to that level, not about it: a chain
    /// slipping with no load and a pin that slides at a fifth of the
    /// bound (the datasheet plant's 4 mN·m under the seed's 19.7) is held
    /// by the bound, where a fitted level at the bound rules it out; the
    /// point takes the band's middle.
    #[test]
    fn an_upper_bound_pin_level_bounds_a_slip_from_zero_to_it() {
        let run = |identified: bool| {
            let mut c = Config::default();
            c.fusion.pin_identified = identified;
            let f = Fusion::new(&c, c.period_s());
            let pin_nm = 0.2 * c.fusion.pin_coulomb_nm;
            let fric = c.tension.f_sc1_n + c.tension.f_cp2_n;
            let v = 10.0 * c.tension.sign_switch_x1_m_s.max(c.jae.sign_switch_m_s);
            let mut s = FusionState::default();
            let mut out = FusionOut::default();
            for k in 0..2000 {
                let x = v * k as f32 / c.control_rate_hz;
                out = f.update(
                    &mut s,
                    &FusionIn {
                        x1_m: x,
                        x1_vel_m_s: v,
                        x2_m: x,
                        x2_vel_m_s: v,
                        tension1_dob_n: c.tension.f_0_n + fric,
                        tension1_model_n: c.tension.f_0_n + fric,
                        tension1_friction_n: fric,
                        joint_torque_nm: pin_nm,
                        ..FusionIn::default()
                    },
                );
            }
            (out, c)
        };
        let (bound_only, c) = run(false);
        assert_eq!(bound_only.flags, 0, "{bound_only:?}");
        assert!(
            bound_only.lo_n <= 0.0 && 0.0 <= bound_only.hi_n,
            "{bound_only:?}"
        );
        let l_e = c.machine.gripper_length_m;
        let (pin, kappa) = (c.fusion.pin_coulomb_nm, c.fusion.kinetic_tolerance);
        let middle_n = (0.2 * pin - 0.5 * (1.0 + kappa) * pin) / l_e;
        let point = math::clamp(middle_n, bound_only.lo_n, bound_only.hi_n);
        assert!(
            math::abs(bound_only.f_ext_n - point) < 1e-4,
            "{bound_only:?} against {middle_n}"
        );
        let (fitted, _) = run(true);
        assert!(fitted.hi_n < 0.0, "a fitted level: {fitted:?}");
    }

    /// Both sliders moving one way at very different speeds (slider 1
    /// running on while a cable relaxes after a stick-slip jump of the
    /// joint) is no slip of the whole chain: the pin's sign is unknown and
    /// its static band applies; at equal speeds the kinetic band does.
    #[test]
    fn sliders_moving_apart_do_not_count_as_the_chain_slipping() {
        let (f, c) = fusion();
        let v = 10.0 * c.tension.sign_switch_x1_m_s;
        let run = |v1: f32, v2: f32| {
            let mut s = FusionState::default();
            let mut out = FusionOut::default();
            for k in 0..200 {
                let t = k as f32 / c.control_rate_hz;
                out = f.update(
                    &mut s,
                    &FusionIn {
                        x1_m: v1 * t,
                        x1_vel_m_s: v1,
                        x2_m: v2 * t,
                        x2_vel_m_s: v2,
                        tension1_dob_n: c.tension.f_0_n,
                        tension1_model_n: c.tension.f_0_n,
                        ..FusionIn::default()
                    },
                );
            }
            out
        };
        // Slider 1 five times as fast as slider 2, both above their
        // switching speeds.
        let apart = run(v, 2.0 * c.jae.sign_switch_m_s);
        assert!(v / (2.0 * c.jae.sign_switch_m_s) > TOGETHER_RATIO);
        assert_ne!(apart.flags & flags::JOINT_STUCK, 0, "{apart:?}");
        assert!(apart.lo_n < 0.0 && apart.hi_n > 0.0, "{apart:?}");
        let together = run(v, v);
        assert_eq!(together.flags & flags::JOINT_STUCK, 0, "{together:?}");
    }

    /// At rest, the DOB reading cable 1 100 N above model C's elastic part:
    /// its interval lies far from the stretch interval's.
    fn dob_100_n_above_its_model(c: &Config) -> FusionIn {
        FusionIn {
            tension1_dob_n: c.tension.f_0_n + 100.0,
            tension1_model_n: c.tension.f_0_n,
            ..FusionIn::default()
        }
    }

    /// Two intervals that do not overlap: the bound is the hull and the flag
    /// says so.
    #[test]
    fn disagreement_widens_the_bound_and_is_flagged() {
        let (f, c) = fusion();
        let mut s = FusionState::default();
        let out = f.update(&mut s, &dob_100_n_above_its_model(&c));
        assert_ne!(out.flags & flags::INCONSISTENT, 0);
        assert!(out.lo_n < 0.0 && out.hi_n > 15.0, "{out:?}");
        // The hull of the two intervals, the point in the middle of the gap.
        let (d, st) = (s.sources.dob_n, s.sources.stretch_n);
        assert!(d.0 > st.1 || st.0 > d.1, "they overlap: {:?}", s.sources);
        let near = |a: f32, b: f32| math::abs(a - b) < 1e-4;
        assert!(
            near(out.lo_n, d.0.min(st.0)) && near(out.hi_n, d.1.max(st.1)),
            "{out:?} from {:?}",
            s.sources
        );
        let gap = 0.5 * (d.0.max(st.0) + d.1.min(st.1));
        assert!(near(out.f_ext_n, gap), "{out:?} from {:?}", s.sources);
    }

    /// The same disagreement with the datasheet's JAE or model C (no
    /// identification on this machine yet): the DOB's interval rests on
    /// the seed's machine, so it narrows nothing. The bound is the stretch
    /// interval, nothing is flagged, and the point is the stretch estimate.
    /// Identified, the same inputs give the hull and the flag.
    #[test]
    fn a_datasheet_jae_or_tension_model_leaves_the_bound_to_the_stretch_interval() {
        for datasheet in [
            Config::default(),
            {
                let mut c = identified();
                c.jae = Config::default().jae;
                c
            },
            {
                let mut c = identified();
                c.tension = Config::default().tension;
                c
            },
        ] {
            let f = Fusion::new(&datasheet, datasheet.period_s());
            let mut s = FusionState::default();
            let out = f.update(&mut s, &dob_100_n_above_its_model(&datasheet));
            assert_eq!(out.flags & flags::INCONSISTENT, 0, "{out:?}");
            let st = s.sources.stretch_n;
            assert_eq!(s.sources.dob_n, (f32::NEG_INFINITY, f32::INFINITY));
            let near = |a: f32, b: f32| math::abs(a - b) < 1e-4;
            assert!(
                near(out.lo_n, st.0) && near(out.hi_n, st.1),
                "{out:?} from {st:?}"
            );
            assert!(out.lo_n <= 0.0 && out.hi_n >= 0.0, "{out:?}");
        }
        let (f, c) = fusion();
        let mut s = FusionState::default();
        let out = f.update(&mut s, &dob_100_n_above_its_model(&c));
        assert_ne!(out.flags & flags::INCONSISTENT, 0);
    }

    /// A slow creep below the switching speed still counts as a slip after
    /// one window, with its direction.
    #[test]
    fn slow_creep_is_detected_as_slip() {
        let (f, c) = fusion();
        let mut s = FusionState::default();
        let rate = c.control_rate_hz;
        let v = 0.2 * c.tension.sign_switch_x1_m_s; // 40 µm/s
        let mut out = FusionOut::default();
        for k in 0..(rate as usize) {
            let x = -v * k as f32 / rate;
            out = f.update(
                &mut s,
                &FusionIn {
                    x1_m: x,
                    x1_vel_m_s: -v,
                    tension1_dob_n: c.tension.f_0_n,
                    tension1_model_n: c.tension.f_0_n,
                    ..FusionIn::default()
                },
            );
        }
        assert_eq!(out.flags & flags::SLIDER1_STUCK, 0);
        assert_eq!(s.slider1.sign, -1.0);
    }

    /// A grip presses toward its object: with the chain stuck, the point
    /// estimate takes the pin's friction at its kinetic level against that
    /// side (`(tau - s f_pin) / l_e`), where it took zero, less the torque
    /// given back since the pressing peak (the estimate holds the peak's
    /// reading until the pin's kinetic level is given back, then follows
    /// the torque again); the bound stays the stuck band's; a one-way
    /// slip's measured sign still wins.
    #[test]
    fn the_pressing_side_sets_the_pins_friction_in_the_point_not_in_the_bound() {
        let (_, mut c) = fusion();
        c.fusion.pin_identified = true;
        let f = Fusion::new(&c, c.period_s());
        let l_e = c.machine.gripper_length_m;
        let pin_n = c.fusion.pin_coulomb_nm / l_e;
        assert!(pin_n > 0.05, "{pin_n}");
        // Tip-equivalent stretch forces held 1 s each; the last tick's output.
        let held = |pressing_sign: f32, vel_m_s: f32, forces_n: &[f32]| {
            let mut s = FusionState::default();
            let mut out = FusionOut::default();
            for &force_n in forces_n {
                for _ in 0..(c.control_rate_hz as usize) {
                    out = f.update(
                        &mut s,
                        &FusionIn {
                            x1_vel_m_s: vel_m_s,
                            x2_vel_m_s: vel_m_s,
                            tension1_dob_n: c.tension.f_0_n,
                            tension1_model_n: c.tension.f_0_n,
                            joint_torque_nm: force_n * l_e,
                            pressing_sign,
                            ..FusionIn::default()
                        },
                    );
                }
            }
            out
        };
        let near = |a: f32, b: f32| math::abs(a - b) < 1e-3;
        let none = held(0.0, 0.0, &[1.0]);
        let plus = held(1.0, 0.0, &[1.0]);
        let minus = held(-1.0, 0.0, &[-1.0]);
        assert_ne!(plus.flags & flags::JOINT_STUCK, 0);
        assert!(near(none.f_ext_n, 1.0), "{none:?}");
        assert!(near(plus.f_ext_n, 1.0 - pin_n), "{plus:?}");
        assert!(near(minus.f_ext_n, -1.0 + pin_n), "{minus:?}");
        assert_eq!((plus.lo_n, plus.hi_n), (none.lo_n, none.hi_n));
        // Pressing on to 1.2 N and giving back half the pin's level: the
        // reading stays the peak's; giving back twice its level: the torque
        // with the pin at zero, as without a side.
        let half = held(1.0, 0.0, &[1.0, 1.2, 1.2 - 0.5 * pin_n]);
        assert!(near(half.f_ext_n, 1.2 - pin_n), "{half:?}");
        let back = held(1.0, 0.0, &[1.0, 1.2, 1.2 - 2.0 * pin_n]);
        assert!(near(back.f_ext_n, 1.2 - 2.0 * pin_n), "{back:?}");
        // A pin level that is only an upper bound (the default's): no side.
        let mut bound_only = c;
        bound_only.fusion.pin_identified = false;
        let fb = Fusion::new(&bound_only, c.period_s());
        let mut s = FusionState::default();
        let mut out = FusionOut::default();
        for _ in 0..(c.control_rate_hz as usize) {
            out = fb.update(
                &mut s,
                &FusionIn {
                    tension1_dob_n: c.tension.f_0_n,
                    tension1_model_n: c.tension.f_0_n,
                    joint_torque_nm: l_e,
                    pressing_sign: 1.0,
                    ..FusionIn::default()
                },
            );
        }
        assert!(near(out.f_ext_n, none.f_ext_n), "{out:?}");
        // Both sliders slipping backwards: the slip's sign, not the side.
        let v = -10.0 * c.tension.sign_switch_x1_m_s.max(c.jae.sign_switch_m_s);
        let slipping = held(1.0, v, &[1.0]);
        assert_eq!(slipping.flags & flags::JOINT_STUCK, 0);
        assert!(near(slipping.f_ext_n, 1.0 + pin_n), "{slipping:?}");
    }
}
