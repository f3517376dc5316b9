//! The project's configuration: datasheet constants, identified parameters,
//! controller gains and fault limits, in SI units.
//!
//! Defaults are DESIGN.md's datasheet values and the seed's identified values.
//! [`Config::validate`] rejects impossible values with an error that names the
//! field; the hot path never checks again. With the `serde` feature the whole
//! struct (de)serializes (the host tool reads and writes it as TOML) without the
//! core depending on `std`.

use core::fmt;

use crate::math;
use crate::model::AddedTerms;
use crate::units::Scales;

/// Datasheet constants of the machine (DESIGN.md §1).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, deny_unknown_fields))]
pub struct Machine {
    /// Motor torque constant `K_m`, N·m/A (RE25 20 W: 23.4 mN·m/A).
    pub torque_constant_nm_a: f32,
    /// Rotor inertia `J_m`, kg·m² (RE25: 1.08e-6).
    pub rotor_inertia_kg_m2: f32,
    /// Gear ratio `z_i` (35).
    pub gear_ratio: f32,
    /// Rope wheel radius `r_m`, m (6 mm).
    pub rope_wheel_radius_m: f32,
    /// Joint pulley radius `r`, m (4 mm).
    pub pulley_radius_m: f32,
    /// Gripper length `l_e`, m (20 mm).
    pub gripper_length_m: f32,
    /// Return-spring stiffness `K_s`, N/m (nominal 656.6).
    pub spring_n_m: f32,
    /// Cable preload `F_0`, N (nominal 19.5).
    pub preload_n: f32,
    /// Drive current limit, A (±2).
    pub current_limit_a: f32,
}

impl Default for Machine {
    fn default() -> Self {
        Self {
            torque_constant_nm_a: 23.4e-3,
            rotor_inertia_kg_m2: 1.08e-6,
            gear_ratio: 35.0,
            rope_wheel_radius_m: 6e-3,
            pulley_radius_m: 4e-3,
            gripper_length_m: 20e-3,
            spring_n_m: 656.6,
            preload_n: 19.5,
            current_limit_a: 2.0,
        }
    }
}

impl Machine {
    /// Motor-shaft angle that winds 1 m of cable onto the rope wheel: `z_i / r_m`.
    #[inline]
    pub fn motor_rad_per_cable_m(&self) -> f32 {
        self.gear_ratio / self.rope_wheel_radius_m
    }

    /// Joint angle implied by the motor angle through rigid cables:
    /// `theta = phi * r_m / (z_i * r)` (the "motor-encoder-only" estimate).
    #[inline]
    pub fn joint_rad_from_motor_rad(&self, phi_rad: f32) -> f32 {
        phi_rad * self.rope_wheel_radius_m / (self.gear_ratio * self.pulley_radius_m)
    }
}

/// Differentiator / filter settings for the position signals.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, deny_unknown_fields))]
pub struct Differentiators {
    /// Bandwidth of the grating differentiators (x1, x2), Hz.
    pub grating_bandwidth_hz: f32,
    /// Bandwidth of the motor-encoder differentiator (phi), Hz.
    pub motor_bandwidth_hz: f32,
    /// Damping ratio of the second-order state-variable filters.
    pub damping: f32,
}

impl Default for Differentiators {
    fn default() -> Self {
        Self {
            grating_bandwidth_hz: 30.0,
            motor_bandwidth_hz: 150.0,
            damping: 0.9,
        }
    }
}

/// Joint-angle estimator (seed Eq. 16, 25-26):
/// `theta = c1 x2'' + c2 x2' + c3 sgn(x2') + c4 x2 + offset`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, deny_unknown_fields))]
pub struct JaeConfig {
    /// `c1 = m_1 / (K_w2 r)`, rad per m/s².
    pub c_acc_rad_s2_m: f32,
    /// `c2 = f_sv2 / (K_w2 r)`, rad per m/s.
    pub c_vel_rad_s_m: f32,
    /// `c3 = f_sc2 / (K_w2 r)`, rad.
    pub c_sign_rad: f32,
    /// `c4 = (K_s + K_w2) / (K_w2 r)`, rad per m.
    pub c_pos_rad_m: f32,
    /// Constant offset, rad (identification treats it as a parameter).
    pub offset_rad: f32,
    /// Slider-2 speed above which the friction sign switches, m/s. Below it the
    /// last sign is held (stiction keeps the presliding direction), so the sign
    /// term does not chatter at standstill.
    pub sign_switch_m_s: f32,
    /// Slider-2 travel, m, that must confirm a reversal before the sign
    /// switches (from its furthest point in the held direction); 0 switches
    /// on the speed alone. The grating's velocity estimate rings after a
    /// stop and can cross `sign_switch_m_s` with slider 2 at rest, which
    /// flips the sign term (`2 c3`, about 0.3°) with nothing moving and
    /// makes a hold on `theta_hat` hunt (README, "Tip motion"). One grating
    /// count (`scales.grating_m_per_count`) is the least travel a reversal
    /// shows; the default is one count of the default grating, 1 µm.
    pub sign_travel_m: f32,
    /// Effect terms added by the residual loop (rad per term unit); not written to a
    /// file when there are none.
    pub added: AddedTerms,
}

impl Default for JaeConfig {
    fn default() -> Self {
        // Seed Sect. 4.1: chi_s = [0.0805 0.5225 0.0025 264.356].
        Self {
            c_acc_rad_s2_m: 0.0805,
            c_vel_rad_s_m: 0.5225,
            c_sign_rad: 0.0025,
            c_pos_rad_m: 264.356,
            offset_rad: 0.0,
            sign_switch_m_s: 2e-4,
            sign_travel_m: crate::units::Scales::default().grating_m_per_count,
            added: AddedTerms::default(),
        }
    }
}

impl JaeConfig {
    /// Whether Eq. 26's coefficients and offset are still the datasheet's
    /// (the seed's machine's): no calibration run of this machine has
    /// fitted them.
    pub fn is_datasheet(&self) -> bool {
        let d = Self::default();
        (
            self.c_acc_rad_s2_m,
            self.c_vel_rad_s_m,
            self.c_sign_rad,
            self.c_pos_rad_m,
            self.offset_rad,
        ) == (
            d.c_acc_rad_s2_m,
            d.c_vel_rad_s_m,
            d.c_sign_rad,
            d.c_pos_rad_m,
            d.offset_rad,
        )
    }
}

/// PD position / PI velocity cascade (seed Fig. 11).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, deny_unknown_fields))]
pub struct CascadeConfig {
    /// Position-loop proportional gain: motor rad/s per joint rad of error.
    pub kp_pos_1_s: f32,
    /// Position-loop derivative gain: motor rad/s per joint rad/s of error rate.
    pub kd_pos: f32,
    /// Velocity-loop proportional gain, A per motor rad/s.
    pub kp_vel_a_s_rad: f32,
    /// Velocity-loop integral gain, A per motor rad.
    pub ki_vel_a_rad: f32,
    /// Motor-velocity reference limit, rad/s.
    pub vel_limit_rad_s: f32,
    /// Feed-forward of the motor-velocity reference from the trajectory's
    /// velocity (0 = none, 1 = full).
    pub vel_feedforward: f32,
    /// Feed-forward the current that holds the modelled cable tension
    /// (`F_1' r_m / (z_i K_m)`), so the integrator only trims.
    pub tension_feedforward: bool,
    /// In [`crate::Mode::JointClosedLoop`], blend the feedback: the
    /// motor-implied angle (collocated, stiff loop) corrected by the
    /// low-passed cable stretch `theta_hat - theta_motor` with this cut-off,
    /// Hz. 0 feeds back `theta_hat` itself (the seed's Fig. 11). The blend
    /// keeps the non-collocated cable resonance out of the position loop
    /// while the JAE still sets the steady angle.
    pub jae_blend_hz: f32,
    /// Position-error dead band while the reference is at rest, rad. Inside
    /// it the position loop asks for no motion, so the velocity integrator
    /// stops pushing against stiction and the hold does not hunt (stick-slip
    /// limit cycle). Keep it near the JAE's resolution (`c4` × 1 count).
    pub hold_deadband_rad: f32,
    /// Output current limit, A (at most the drive's limit).
    pub current_limit_a: f32,
    /// On `theta_hat` itself ([`crate::Mode::JointClosedLoop`] with
    /// `jae_blend_hz = 0`), take the error's rate for `kd_pos` from the
    /// grating's observer, `theta_ref' - c4 x2'`, instead of differencing
    /// the error over one tick. One grating count of `theta_hat` is
    /// 0.26 mrad, and differenced it steps the current by about 0.25 A at
    /// 2 kHz: the current chatters (README, "the PD term's current
    /// chatter", with what this option changes). Off by default: on the
    /// simulator's plants it moves the force figures both ways.
    pub kd_on_observer_rate: bool,
    /// The payout stop: while the motor's torque balance reads cable 0 below
    /// the slack limit and the motor has unwound more than half the rope's
    /// shortening from that limit to zero tension since
    /// (`limit / (2 max(K_w0, K_w1))`), the motor-velocity reference is held
    /// at or above zero, so the motor unwinds no further rope that a stuck
    /// slider 1 does not take up (the hold's error just outside its dead
    /// band asks for exactly that; the cable-0 checks then latch and drop
    /// the load). Off by default: on the simulator's plants it turns about
    /// a quarter of the heavy-load cable-0 faults into holds that run on,
    /// the rope at zero tension for up to 3.2 s with the drive on and no
    /// fault (README, "The payout stop"). Needs the slack checks on
    /// (`limits.min_tension_fraction > 0`).
    pub payout_stop: bool,
}

impl Default for CascadeConfig {
    fn default() -> Self {
        // Tuned on the simulated prototype (`host-sim simulate --scenario
        // track-jae --oracle`, sweep in the README): the position loop's
        // crossover must stay well below the slider-2 mode (~100 Hz) that sits
        // between the motor and the JAE's grating; kp 400 already rings.
        Self {
            kp_pos_1_s: 200.0,
            kd_pos: 0.5,
            kp_vel_a_s_rad: 0.04,
            ki_vel_a_rad: 2.0,
            vel_limit_rad_s: 500.0,
            vel_feedforward: 1.0,
            tension_feedforward: true,
            jae_blend_hz: 0.0,
            hold_deadband_rad: 5e-4,
            current_limit_a: 2.0,
            kd_on_observer_rate: false,
            payout_stop: false,
        }
    }
}

/// Disturbance observer and force estimator (seed Eq. 17-21, Fig. 5-6).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, deny_unknown_fields))]
pub struct DobConfig {
    /// Observer cut-off `g_dis`, rad/s.
    pub cutoff_rad_s: f32,
    /// Motor viscous damping `B_m`, N·m·s/rad (seed: 1.6934e-5).
    pub viscous_nm_s_rad: f32,
    /// Use the measured current instead of the reference in `K_m i`.
    pub use_measured_current: bool,
}

impl Default for DobConfig {
    fn default() -> Self {
        Self {
            cutoff_rad_s: 2.0 * crate::math::PI * 10.0,
            viscous_nm_s_rad: 1.6934e-5,
            use_measured_current: false,
        }
    }
}

/// No-load cable-1 tension, simplified model C (seed Eq. 28-29):
/// `F_1' = f_sc1 sgn(x1') + f_cp2 sgn(x2') + K_s x2 + F_0`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, deny_unknown_fields))]
pub struct TensionConfig {
    /// Slider-1 Coulomb term `f_sc1`, N.
    pub f_sc1_n: f32,
    /// Slider-2/joint Coulomb term `f_cp2`, N.
    pub f_cp2_n: f32,
    /// Spring term `K_s`, N/m.
    pub k_s_n_m: f32,
    /// Preload `F_0`, N.
    pub f_0_n: f32,
    /// Slider-1 speed above which its friction sign switches, m/s (held below).
    pub sign_switch_x1_m_s: f32,
    /// Slider-2 speed above which its friction sign switches, m/s (held below).
    pub sign_switch_x2_m_s: f32,
    /// Effect terms added by the residual loop (N per term unit); not written to a
    /// file when there are none.
    pub added: AddedTerms,
}

impl Default for TensionConfig {
    fn default() -> Self {
        // Seed Eq. 29 fit: chi_p = [3.879 N, 5.027 N, 707.7 N/m, 19.52 N].
        Self {
            f_sc1_n: 3.879,
            f_cp2_n: 5.027,
            k_s_n_m: 707.7,
            f_0_n: 19.52,
            sign_switch_x1_m_s: 2e-4,
            sign_switch_x2_m_s: 2e-4,
            added: AddedTerms::default(),
        }
    }
}

impl TensionConfig {
    /// Whether model C's parameters (Eq. 29's `chi_p`) are still the
    /// datasheet's (the seed's machine's): no calibration run of this
    /// machine has fitted them.
    pub fn is_datasheet(&self) -> bool {
        let d = Self::default();
        (self.f_sc1_n, self.f_cp2_n, self.k_s_n_m, self.f_0_n)
            == (d.f_sc1_n, d.f_cp2_n, d.k_s_n_m, d.f_0_n)
    }
}

/// Cable-stretch force estimator: the joint torque from the two cables'
/// stretch, measured by the gratings and the estimated joint angle,
/// `tau = r [K_w1 (x1 - r theta) - K_w2 (r theta - x2)]` (seed Eq. 9, 12, 13;
/// the preload cancels). It needs no motor current and is blind to the
/// sliders' friction, which sits outside the two cables.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, deny_unknown_fields))]
pub struct StretchConfig {
    /// Cable 1 stiffness `K_w1`, N/m.
    pub cable1_n_m: f32,
    /// Cable 2 stiffness `K_w2`, N/m.
    pub cable2_n_m: f32,
    /// Cable 0 stiffness `K_w0` (rope wheel to slider 1), N/m, as
    /// `identify --procedure tension` reads it where slider 1 stands still
    /// and the motor turns one way (the slope of the motor's torque balance,
    /// the DOB's low-pass undone, against the measured elongation: within a
    /// few percent of the rope's either side on the simulator's plants, and
    /// the check's margin holds a reading well above it). Only the cable-0
    /// slack check that bounds the rope's tension by cable 1's and slider
    /// 1's friction uses it. 0 = not identified: cable 1's stiffness
    /// stands in, a lower bound (cable 0 is the rope's shortest stretch).
    pub cable0_n_m: f32,
}

impl Default for StretchConfig {
    fn default() -> Self {
        // DESIGN.md: c4 = (K_s + K_w2) / (K_w2 r) of the seed's JAE gives
        // K_w2 near 11.4 N/mm; cable 1 is the same cable.
        Self {
            cable1_n_m: 11_400.0,
            cable2_n_m: 11_400.0,
            cable0_n_m: 0.0,
        }
    }
}

impl StretchConfig {
    /// Cable stiffnesses implied by a JAE position coefficient `c4` (rad/m)
    /// and the spring `K_s` (N/m): `K_w2 = K_s / (c4 r - 1)`, with cable 1
    /// taken as the same cable. `None` when `c4 r <= 1` (no finite stiffness).
    pub fn from_jae(c4_rad_m: f32, spring_n_m: f32, pulley_radius_m: f32) -> Option<Self> {
        let d = c4_rad_m * pulley_radius_m - 1.0;
        let k = spring_n_m / d;
        (d > 0.0 && k.is_finite() && k > 0.0).then_some(Self {
            cable1_n_m: k,
            cable2_n_m: k,
            cable0_n_m: 0.0,
        })
    }
}

/// Fused force estimate and its bound ([`crate::fusion`]): the friction bands
/// that the DOB and the stretch estimate cannot see through at standstill.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, deny_unknown_fields))]
pub struct FusionConfig {
    /// Joint-pin Coulomb friction `f_efc`, N·m. `identify` fits it on the
    /// calibration run (joint torque from both cables against the magnetic
    /// encoder). The default is the seed's upper bound: all of model C's
    /// `f_cp2` beyond slider 2's own friction placed on the pin,
    /// `(5.027 N - c3 K_w2 r) r` = 19.7 mN·m, which makes the bound wide
    /// (about ±1.5 N at the tip) but true.
    pub pin_coulomb_nm: f32,
    /// Whether `pin_coulomb_nm` is the pin's kinetic level as `identify`
    /// fitted it, rather than an upper bound (the default's, or
    /// `identify`'s when the runs cannot pin it down). Only a fitted level
    /// may stand as the pin's friction in a grip's point estimate
    /// ([`crate::grip`]): an upper bound there would read the force low by
    /// its excess, and the law would squeeze that much harder. While the
    /// chain slips, a fitted level bounds the pin's friction at `±
    /// kinetic_tolerance` about it, an upper bound anywhere from zero to it
    /// (times `1 + kinetic_tolerance`).
    pub pin_identified: bool,
    /// Largest ratio of static (breakaway) to kinetic friction the bound
    /// allows for a stuck element (1.5: the upper end of lubricated
    /// steel-on-steel and miniature linear guides).
    pub static_over_kinetic: f32,
    /// Relative uncertainty of an identified Coulomb level while its element
    /// slips (0.25 = ±25 %).
    pub kinetic_tolerance: f32,
    /// JAE error beyond the sign band the bound builds on `|c3|`, rad:
    /// model error, and the uncertainty of `c3` itself. The default is the
    /// seed's mean JAE identification error, 0.275°; `identify` writes two
    /// RMS of its own residual plus `2 (1 + static_over_kinetic)` effective
    /// standard deviations of `c3` (a run that cannot pin `c3` down widens
    /// the bound instead of narrowing it).
    pub jae_error_rad: f32,
    /// Relative uncertainty of the stretch estimate's force scale, the
    /// cables' stiffnesses (0.10 = ±10 %). They rest on the spring rate and
    /// on `c4` (Eq. 16, `K_w2 = K_s / (c4 r - 1)`), so a spring softer or
    /// stiffer than its datasheet scales every tension the stretch reads:
    /// the bound widens by this share of the stretch torque. The default is
    /// a stock compression spring's usual rate tolerance, ±10 %; `identify`
    /// writes the spring rate's uncertainty as the calibration run measured
    /// it when the measurement replaced the datasheet, else this tolerance
    /// widened to the measurement's disagreement with the datasheet, plus
    /// two effective standard deviations of `c4` carried through `c4 r - 1`.
    pub stiffness_tolerance: f32,
    /// Window over which a net displacement counts as a slow slip (creep), s.
    pub creep_window_s: f32,
    /// Net displacement within the window that counts as creep, m (three
    /// grating counts: above one count of quantisation either way).
    pub creep_distance_m: f32,
}

impl Default for FusionConfig {
    fn default() -> Self {
        let m = Machine::default();
        let k_w2 = StretchConfig::default().cable2_n_m;
        let c3 = JaeConfig::default().c_sign_rad;
        let f_cp2 = TensionConfig::default().f_cp2_n;
        Self {
            pin_coulomb_nm: (f_cp2 - c3 * k_w2 * m.pulley_radius_m) * m.pulley_radius_m,
            pin_identified: false,
            static_over_kinetic: 1.5,
            kinetic_tolerance: 0.25,
            jae_error_rad: 0.275 * crate::math::PI / 180.0,
            stiffness_tolerance: 0.10,
            creep_window_s: 0.1,
            creep_distance_m: 3e-6,
        }
    }
}

impl FusionConfig {
    /// The upper bound of the pin friction that model C and the JAE leave
    /// room for: `(|f_sc1| + |f_cp2| - |c3| K_w2 r) r`, N·m (at least 0).
    /// Model C's two sign columns move together except in short transients,
    /// so only their sum is pinned down by the data (an identification may
    /// put all of it in either term).
    pub fn pin_upper_bound_nm(config: &Config) -> f32 {
        let r = config.machine.pulley_radius_m;
        let slider2_n = crate::math::abs(config.jae.c_sign_rad) * config.stretch.cable2_n_m * r;
        let t = &config.tension;
        let v = (crate::math::abs(t.f_sc1_n) + crate::math::abs(t.f_cp2_n) - slider2_n) * r;
        if v > 0.0 {
            v
        } else {
            0.0
        }
    }
}

/// Optional probing motion at a hold ([`crate::probe`]): a sinusoidal dither
/// of the joint-angle reference that makes stuck friction slip, and the fused
/// estimate averaged over each whole dither period. Off unless asked; never
/// in identification runs (the dither would enter the fitted data).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, deny_unknown_fields))]
pub struct ProbeConfig {
    /// Dither the reference whenever the joint holds (reference at rest).
    pub enabled: bool,
    /// Joint-angle amplitude of the dither, rad. Against stiction the joint
    /// does not follow a small dither smoothly: it sticks and jumps, so the
    /// tip moves by the stick-slip step, not by twice the amplitude (the
    /// report measures it on every variant). Sweep on four variants at 4 Hz
    /// (`docs/force.md`): 0.05° and 0.2° gave the same worst-case accuracy
    /// within 4 points except on one drawn plant, 0.2° with 0.07° to 0.38°
    /// more tip motion; the default 0.1° lies between them. On the pin-friction
    /// variant 0.1° was the worst amplitude (50.6 % above 1 N, from one case,
    /// against 86 % to 87 % at 0.05°, 0.15° and 0.2°). Traced (stop 56): at a
    /// hold that starts at rest, no fixed small amplitude frees a stuck pin
    /// (the dither swings the cables' torque on it by far less than its
    /// static band); the hold's slow drift freed it, after a time that
    /// depends on where the pin stuck. The amplitude now grows while the
    /// joint does not follow (`max_amplitude_rad`).
    pub amplitude_rad: f32,
    /// Dither frequency, Hz (rounded so a period is eight blocks of whole
    /// ticks). 4 Hz: at 8 Hz (0.1°) the worst case at 0.3 N was 8 to 11
    /// points lower on the default and slider-1 variants (1 to 6 points higher
    /// on the two others); at 2 Hz it was lower on all four, and the
    /// one-period mean lags a load change by half a second.
    pub frequency_hz: f32,
    /// Largest amplitude the dither grows to while the joint does not
    /// follow it, rad ([`crate::probe::Probe::update`]: after each period
    /// in which slider 2 travelled no more than one grating count, the
    /// amplitude doubles, up to this; the first period the joint follows,
    /// it is `amplitude_rad` again). At or below `amplitude_rad` it never
    /// grows.
    pub max_amplitude_rad: f32,
}

impl Default for ProbeConfig {
    fn default() -> Self {
        Self {
            enabled: false,
            amplitude_rad: 0.1 * crate::math::PI / 180.0,
            frequency_hz: 4.0,
            max_amplitude_rad: 1.6 * crate::math::PI / 180.0,
        }
    }
}

/// Limits beyond which a reading is impossible (a fault).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, deny_unknown_fields))]
pub struct FaultLimits {
    /// Largest physically possible grating speed, m/s.
    pub max_grating_speed_m_s: f32,
    /// Largest physically possible motor speed, rad/s (RE25: about 11 000 rpm).
    pub max_motor_speed_rad_s: f32,
    /// Joint-angle range, rad (|theta_hat| beyond it is a fault).
    pub max_joint_angle_rad: f32,
    /// Cable 1 counts as slack (a fault) when both its tension read off its
    /// stretch, `K_w1 (x1 - r theta_hat) + F_0`, and the tension the motor
    /// holds less slider 1's friction band, `F_1_hat - F_sc1` (the DOB),
    /// fall below this fraction of the preload `F_0`. A physical threshold:
    /// with cable 1 near slack the joint loses its stiffness on that side
    /// and the JAE's cable model no longer holds. Both chains must agree
    /// because each has its own scale (spring rate, torque constant).
    /// 0 switches the check off (a decoupled motor, homing).
    pub min_tension_fraction: f32,
    /// With the drive enabled, a measured current beyond this is
    /// [`crate::Fault::OverCurrent`], A: the drive limits at
    /// `machine.current_limit_a` (2 A), so 12.5 % above it means it is not
    /// (and 2.25 A stays inside the monitor's ±2.5 A, where the rail check
    /// takes over).
    pub max_current_a: f32,
    /// Continuous current the winding can carry, A. The I²t state (the
    /// measured current squared, low-passed with
    /// [`FaultLimits::thermal_time_constant_s`]) above its square is
    /// [`crate::Fault::I2t`]. Default 1.2 A: the order of a Maxon RE25 20 W
    /// winding's rated torque (about 28 mN·m) over its `K_m`; take your
    /// motor's datasheet value.
    pub continuous_current_a: f32,
    /// Thermal time constant of the winding, s (RE25 class: about 12 s).
    /// From cold, the I²t fault trips after `-tau ln(1 - (I_c / I)^2)` at a
    /// constant current `I > I_c` (5.4 s at 2 A with the defaults).
    pub thermal_time_constant_s: f32,
    /// With the drive enabled, the measured current minus the reference of
    /// the last tick, low-passed over [`FaultLimits::current_error_time_s`],
    /// beyond this is [`crate::Fault::CurrentTracking`], A. 0 switches the
    /// check off (replays of logs from a drive that was not this one).
    pub max_current_error_a: f32,
    /// Time constant of the current-tracking error's low-pass, s: long
    /// against the drive's current loop (about 0.1–0.2 ms) and the monitor's
    /// noise, short against anything a broken lead does to the joint.
    pub current_error_time_s: f32,
}

impl Default for FaultLimits {
    fn default() -> Self {
        Self {
            max_grating_speed_m_s: 0.5,
            max_motor_speed_rad_s: 1200.0,
            max_joint_angle_rad: 1.6,
            min_tension_fraction: 0.2,
            max_current_a: 2.25,
            continuous_current_a: 1.2,
            thermal_time_constant_s: 12.0,
            max_current_error_a: 0.5,
            current_error_time_s: 0.02,
        }
    }
}

/// The largest per-tick step a 16-bit encoder count's jump limit may allow
/// (half the counter's range, with room for the limit's two-count margin).
pub const MAX_COUNTER_STEP: f32 = 16_000.0;

/// The whole configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, deny_unknown_fields))]
pub struct Config {
    /// Control rate, Hz (default 2 kHz, up to 20 kHz).
    pub control_rate_hz: f32,
    /// Datasheet constants.
    pub machine: Machine,
    /// Sensor and converter scales.
    pub scales: Scales,
    /// Differentiators.
    pub differentiators: Differentiators,
    /// Joint-angle estimator.
    pub jae: JaeConfig,
    /// Position/velocity cascade.
    pub cascade: CascadeConfig,
    /// Disturbance observer.
    pub dob: DobConfig,
    /// No-load tension model.
    pub tension: TensionConfig,
    /// Cable-stretch force estimator.
    pub stretch: StretchConfig,
    /// Fused force estimate and its bound.
    pub fusion: FusionConfig,
    /// Optional probing motion at a hold (off by default).
    pub probe: ProbeConfig,
    /// Fault limits.
    pub limits: FaultLimits,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            control_rate_hz: 2000.0,
            machine: Machine::default(),
            scales: Scales::default(),
            differentiators: Differentiators::default(),
            jae: JaeConfig::default(),
            cascade: CascadeConfig::default(),
            dob: DobConfig::default(),
            tension: TensionConfig::default(),
            stretch: StretchConfig::default(),
            fusion: FusionConfig::default(),
            probe: ProbeConfig::default(),
            limits: FaultLimits::default(),
        }
    }
}

/// A differentiator bandwidth [`Config::at_rate`] derives where the rate
/// cannot support the file's, as a share of the control rate (a fifth of
/// the Nyquist rate, inside the quarter [`Config::validate`] allows a
/// user's).
pub const DERIVED_BANDWIDTH_PER_RATE: f32 = 0.1;

/// The control rates the core runs at, Hz: 100 Hz is the slowest at which
/// the cascade's and differentiators' derived settings keep their
/// margins, 20 kHz the fastest tick the Cortex-M4F's budget allows
/// (checked by [`Config::validate`]; the host's tools refuse other rates
/// from the same constant).
pub const CONTROL_RATE_RANGE_HZ: core::ops::RangeInclusive<f32> = 100.0..=20_000.0;

/// Every setting [`Config::at_rate`] can derive from the control rate (a
/// [`RateAdjustment::field`] is one of them): a value a file gives for any
/// other setting has nothing to do with the rate.
pub const RATE_DERIVED_FIELDS: [&str; 6] = [
    "differentiators.grating_bandwidth_hz",
    "differentiators.motor_bandwidth_hz",
    "cascade.kp_vel_a_s_rad",
    "cascade.ki_vel_a_rad",
    "cascade.kp_pos_1_s",
    "cascade.kd_on_observer_rate",
];

/// A setting [`Config::at_rate`] derived from the control rate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RateAdjustment {
    /// Dotted path of the setting.
    pub field: &'static str,
    /// Value before, in the setting's unit (an on/off setting: 0 or 1).
    pub from: f32,
    /// Value derived from the rate.
    pub to: f32,
    /// The setting is on/off (`from` and `to` are 0 or 1).
    pub flag: bool,
}

impl RateAdjustment {
    /// The derived value as a configuration file writes it.
    pub fn to_text(&self) -> heapless::String<24> {
        let mut t = heapless::String::new();
        if self.flag {
            let _ = t.push_str(if self.to != 0.0 { "true" } else { "false" });
        } else {
            let _ = core::fmt::write(&mut t, format_args!("{}", self.to));
        }
        t
    }

    /// The value before, as a configuration file writes it.
    pub fn from_text(&self) -> heapless::String<24> {
        RateAdjustment {
            to: self.from,
            ..*self
        }
        .to_text()
    }
}

/// Why a configuration was rejected: the field and what is wrong with it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ConfigError {
    /// Dotted path of the offending field, e.g. `"machine.gear_ratio"`.
    pub field: &'static str,
    /// What a valid value is.
    pub expected: &'static str,
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "invalid configuration: `{}` must be {}",
            self.field, self.expected
        )
    }
}

impl crate::units::Scales {
    /// Check the board's scales (the `scales` table of a configuration, or
    /// a simulated board's); the error names the field under `scales.`.
    ///
    /// # Errors
    /// The first field out of its range.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let s = self;
        positive("scales.grating_m_per_count", s.grating_m_per_count)?;
        if s.motor_counts_per_rev == 0 {
            return Err(ConfigError {
                field: "scales.motor_counts_per_rev",
                expected: "> 0",
            });
        }
        if s.magnetic_counts_per_rev == 0 {
            return Err(ConfigError {
                field: "scales.magnetic_counts_per_rev",
                expected: "> 0",
            });
        }
        if s.motor_counts_per_rev > 1_000_000 || s.magnetic_counts_per_rev > 1_000_000 {
            return Err(ConfigError {
                field: if s.motor_counts_per_rev > 1_000_000 {
                    "scales.motor_counts_per_rev"
                } else {
                    "scales.magnetic_counts_per_rev"
                },
                expected: "at most 1000000 counts per revolution",
            });
        }
        within(
            "scales.grating_m_per_count",
            s.grating_m_per_count,
            1e-9..=1e-3,
            "between 1 nm and 1 mm per count",
        )?;
        within(
            "scales.adc_a_per_code",
            s.adc_a_per_code,
            1e-6..=1.0,
            "between 1e-6 and 1 A per code",
        )?;
        within(
            "scales.dac_a_per_code",
            s.dac_a_per_code,
            1e-6..=1.0,
            "between 1e-6 and 1 A per code",
        )?;
        // A wider band would flag ordinary currents as a rail (and beyond
        // half the range the band's arithmetic would wrap).
        if s.adc_rail_margin_codes > 1023 {
            return Err(ConfigError {
                field: "scales.adc_rail_margin_codes",
                expected: "at most 1023 (a quarter of the 12-bit range)",
            });
        }
        within(
            "scales.adc_zero_code",
            s.adc_zero_code,
            0.0..=4095.0,
            "within 0..=4095",
        )?;
        within(
            "scales.dac_zero_code",
            s.dac_zero_code,
            0.0..=4095.0,
            "within 0..=4095",
        )?;
        Ok(())
    }
}

fn positive(field: &'static str, v: f32) -> Result<(), ConfigError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(ConfigError {
            field,
            expected: "finite and > 0",
        })
    }
}

fn non_negative(field: &'static str, v: f32) -> Result<(), ConfigError> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(ConfigError {
            field,
            expected: "finite and >= 0",
        })
    }
}

pub(crate) fn within(
    field: &'static str,
    v: f32,
    range: impl core::ops::RangeBounds<f32>,
    expected: &'static str,
) -> Result<(), ConfigError> {
    if v.is_finite() && range.contains(&v) {
        Ok(())
    } else {
        Err(ConfigError { field, expected })
    }
}

/// Finite with `|v| <= max`: coefficients whose sign the fit decides, bounded
/// far beyond any physical value so that products with any sensor reading
/// stay finite in `f32`.
fn magnitude(
    field: &'static str,
    v: f32,
    max: f32,
    expected: &'static str,
) -> Result<(), ConfigError> {
    if v.is_finite() && v.abs() <= max {
        Ok(())
    } else {
        Err(ConfigError { field, expected })
    }
}

impl Config {
    /// Control period, s.
    #[inline]
    pub fn period_s(&self) -> f32 {
        1.0 / self.control_rate_hz
    }

    /// The slack check's threshold: `limits.min_tension_fraction` of the
    /// preload `tension.f_0_n`, N.
    #[inline]
    pub fn slack_limit_n(&self) -> f32 {
        self.limits.min_tension_fraction * self.tension.f_0_n
    }

    /// This configuration at another control rate, with every rate-dependent
    /// setting that the new rate cannot support derived from it, in order:
    ///
    /// 1. a differentiator bandwidth above a quarter of the Nyquist rate (what
    ///    [`Config::validate`] allows) becomes a fifth of it (`rate / 10`);
    /// 2. the velocity loop's crossover on the bare rotor, `kp_vel K_m / J_m`,
    ///    is kept at most the motor observer's bandwidth (the observer is the
    ///    loop's main lag: beyond it the gain margin falls from about 1.5 to
    ///    nothing, and the drive current chatters); when it is lowered by a
    ///    factor `s`, `ki_vel` is lowered by `s²`, which keeps the PI zero at
    ///    the same fraction of the crossover, and `ki_vel` is kept below
    ///    `kp_vel` times a tenth of the crossover (the PI zero a decade below
    ///    it);
    /// 3. the position loop's gain is kept at most a third of that crossover
    ///    (the cascade's separation);
    /// 4. the discrete PD position loop is kept inside Jury's bound;
    /// 5. where the velocity loop's crossover is below three times the
    ///    grating observer's bandwidth, the position loop's derivative is
    ///    taken from that observer (`cascade.kd_on_observer_rate`), whose
    ///    bandwidth becomes a third of the crossover.
    ///
    /// The settings that the rate can support are kept, so a user's choice
    /// survives. Returns the changes made, for the caller to say what it
    /// derived.
    pub fn at_rate(&self, rate_hz: f32) -> (Config, heapless::Vec<RateAdjustment, 9>) {
        let mut c = *self;
        let mut changes = heapless::Vec::new();
        c.control_rate_hz = rate_hz;
        let limit_hz = 0.125 * rate_hz;
        let derived_hz = DERIVED_BANDWIDTH_PER_RATE * rate_hz;
        let d = &mut c.differentiators;
        for (field, bw) in [
            (
                "differentiators.grating_bandwidth_hz",
                &mut d.grating_bandwidth_hz,
            ),
            (
                "differentiators.motor_bandwidth_hz",
                &mut d.motor_bandwidth_hz,
            ),
        ] {
            if *bw > limit_hz && derived_hz.is_finite() && derived_hz > 0.0 {
                let _ = changes.push(RateAdjustment {
                    field,
                    from: *bw,
                    to: derived_hz,
                    flag: false,
                });
                *bw = derived_hz;
            }
        }
        let cc = &mut c.cascade;
        let rotor_gain = c.machine.torque_constant_nm_a / c.machine.rotor_inertia_kg_m2;
        let observer_rad_s = 2.0 * math::PI * c.differentiators.motor_bandwidth_hz;
        let crossover_rad_s = cc.kp_vel_a_s_rad * rotor_gain;
        if crossover_rad_s > observer_rad_s && observer_rad_s.is_finite() {
            let scale = observer_rad_s / crossover_rad_s;
            for (field, gain, factor) in [
                ("cascade.kp_vel_a_s_rad", &mut cc.kp_vel_a_s_rad, scale),
                ("cascade.ki_vel_a_rad", &mut cc.ki_vel_a_rad, scale * scale),
            ] {
                let to = *gain * factor;
                let _ = changes.push(RateAdjustment {
                    field,
                    from: *gain,
                    to,
                    flag: false,
                });
                *gain = to;
            }
        }
        // The PI zero at most a decade below the crossover (ki / kp <= w_c /
        // 10): nearer, the integrator eats the phase the observer leaves.
        let ki_max = 0.1 * cc.kp_vel_a_s_rad * cc.kp_vel_a_s_rad * rotor_gain;
        if cc.ki_vel_a_rad > ki_max {
            let _ = changes.push(RateAdjustment {
                field: "cascade.ki_vel_a_rad",
                from: cc.ki_vel_a_rad,
                to: ki_max,
                flag: false,
            });
            cc.ki_vel_a_rad = ki_max;
        }
        // The velocity crossover as the rules above left it.
        let crossover_rad_s = cc.kp_vel_a_s_rad * rotor_gain;
        let position_max_1_s = crossover_rad_s / 3.0;
        if cc.kp_pos_1_s > position_max_1_s && position_max_1_s > 0.0 {
            let _ = changes.push(RateAdjustment {
                field: "cascade.kp_pos_1_s",
                from: cc.kp_pos_1_s,
                to: position_max_1_s,
                flag: false,
            });
            cc.kp_pos_1_s = position_max_1_s;
        }
        // The position loop's derivative on `theta_hat` sees slider 2's
        // mode, which sits between the motor and the grating the JAE reads,
        // and feeds it back into the velocity loop. Where the crossover is
        // derived down with the rate it drove a current limit cycle at the
        // crossover (500-800 Hz on the simulated prototype; README, "Below
        // 1 kHz the chatter is a limit cycle"). There, once the crossover is
        // below three times the grating observer's bandwidth, the
        // derivative comes from that observer (`kd_on_observer_rate`),
        // whose bandwidth becomes a third of the crossover: the cascade's
        // separation, as for `kp_pos` above.
        let crossover_hz = crossover_rad_s / (2.0 * math::PI);
        let grating_hz = c.differentiators.grating_bandwidth_hz;
        if crossover_hz < 3.0 * grating_hz && crossover_hz > 0.0 {
            if !cc.kd_on_observer_rate {
                let _ = changes.push(RateAdjustment {
                    field: "cascade.kd_on_observer_rate",
                    from: 0.0,
                    to: 1.0,
                    flag: true,
                });
                cc.kd_on_observer_rate = true;
            }
            let to = crossover_hz / 3.0;
            let _ = changes.push(RateAdjustment {
                field: "differentiators.grating_bandwidth_hz",
                from: grating_hz,
                to,
                flag: false,
            });
            c.differentiators.grating_bandwidth_hz = to;
        }
        // The discrete PD position loop needs kp T < 2 (1 - kd) (see
        // `validate`); at a rate too slow for the gain, derive half of that.
        let period_s = 1.0 / rate_hz;
        if cc.kd_pos < 1.0
            && cc.kp_pos_1_s * period_s >= 2.0 * (1.0 - cc.kd_pos)
            && period_s.is_finite()
        {
            let to = (1.0 - cc.kd_pos) / period_s;
            let _ = changes.push(RateAdjustment {
                field: "cascade.kp_pos_1_s",
                from: cc.kp_pos_1_s,
                to,
                flag: false,
            });
            cc.kp_pos_1_s = to;
        }
        (c, changes)
    }

    /// Check every field; the first impossible one is returned.
    ///
    /// Long (about 400 lines) on purpose: one check per field, in the order
    /// of the structs, so a new field's check goes next to its neighbours'
    /// and a reader can tick the fields off; splitting it would scatter the
    /// cross-field checks (rail margin against the ADC range, current limits
    /// against each other) across functions.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if !CONTROL_RATE_RANGE_HZ.contains(&self.control_rate_hz) {
            return Err(ConfigError {
                field: "control_rate_hz",
                expected: "between 100 and 20000 Hz",
            });
        }
        let m = &self.machine;
        // Ranges spanning every motor, gear and cable a joint of this kind
        // could use, several decades each side of the prototype's values.
        let ranges = [
            (
                "machine.torque_constant_nm_a",
                m.torque_constant_nm_a,
                1e-4,
                10.0,
                "between 1e-4 and 10 N·m/A",
            ),
            (
                "machine.rotor_inertia_kg_m2",
                m.rotor_inertia_kg_m2,
                1e-10,
                1e-2,
                "between 1e-10 and 1e-2 kg·m²",
            ),
            (
                "machine.gear_ratio",
                m.gear_ratio,
                0.01,
                1e4,
                "between 0.01 and 10000",
            ),
            (
                "machine.rope_wheel_radius_m",
                m.rope_wheel_radius_m,
                1e-4,
                1.0,
                "between 0.1 mm and 1 m",
            ),
            (
                "machine.pulley_radius_m",
                m.pulley_radius_m,
                1e-4,
                1.0,
                "between 0.1 mm and 1 m",
            ),
            (
                "machine.gripper_length_m",
                m.gripper_length_m,
                1e-4,
                1.0,
                "between 0.1 mm and 1 m",
            ),
            (
                "machine.spring_n_m",
                m.spring_n_m,
                0.0,
                1e7,
                "between 0 and 1e7 N/m",
            ),
            (
                "machine.preload_n",
                m.preload_n,
                0.0,
                1e4,
                "between 0 and 10000 N",
            ),
            (
                "machine.current_limit_a",
                m.current_limit_a,
                0.01,
                100.0,
                "between 0.01 and 100 A",
            ),
        ];
        for (field, v, lo, hi, expected) in ranges {
            within(field, v, lo..=hi, expected)?;
        }

        self.scales.validate()?;
        let s = &self.scales;

        let nyquist = 0.5 * self.control_rate_hz;
        let d = &self.differentiators;
        for (field, bw) in [
            (
                "differentiators.grating_bandwidth_hz",
                d.grating_bandwidth_hz,
            ),
            ("differentiators.motor_bandwidth_hz", d.motor_bandwidth_hz),
        ] {
            positive(field, bw)?;
            if bw > 0.25 * nyquist {
                return Err(ConfigError {
                    field,
                    expected: "below a quarter of the Nyquist rate",
                });
            }
        }
        within(
            "differentiators.damping",
            d.damping,
            0.1..=10.0,
            "between 0.1 and 10",
        )?;

        let j = &self.jae;
        const COEF: &str = "finite, magnitude at most 1e6";
        magnitude("jae.c_acc_rad_s2_m", j.c_acc_rad_s2_m, 1e6, COEF)?;
        magnitude("jae.c_vel_rad_s_m", j.c_vel_rad_s_m, 1e6, COEF)?;
        magnitude("jae.c_sign_rad", j.c_sign_rad, 1e6, COEF)?;
        positive("jae.c_pos_rad_m", j.c_pos_rad_m)?;
        magnitude("jae.c_pos_rad_m", j.c_pos_rad_m, 1e6, COEF)?;
        magnitude("jae.offset_rad", j.offset_rad, math::PI, "within ±pi rad")?;
        within(
            "jae.sign_switch_m_s",
            j.sign_switch_m_s,
            1e-9..=1.0,
            "between 1e-9 and 1 m/s",
        )?;
        within(
            "jae.sign_travel_m",
            j.sign_travel_m,
            0.0..=1e-3,
            "between 0 and 1e-3 m (one grating count is 1e-6)",
        )?;
        if let Err(expected) = j.added.validate() {
            return Err(ConfigError {
                field: "jae.added",
                expected,
            });
        }

        // The fault limits first: the cascade's and the counters' checks
        // below read them, and a bad limit is named as itself.
        self.limits.validate()?;

        let c = &self.cascade;
        non_negative("cascade.kp_pos_1_s", c.kp_pos_1_s)?;
        non_negative("cascade.kd_pos", c.kd_pos)?;
        non_negative("cascade.kp_vel_a_s_rad", c.kp_vel_a_s_rad)?;
        non_negative("cascade.ki_vel_a_rad", c.ki_vel_a_rad)?;
        positive("cascade.vel_limit_rad_s", c.vel_limit_rad_s)?;
        non_negative("cascade.vel_feedforward", c.vel_feedforward)?;
        positive("cascade.current_limit_a", c.current_limit_a)?;
        non_negative("cascade.jae_blend_hz", c.jae_blend_hz)?;
        non_negative("cascade.hold_deadband_rad", c.hold_deadband_rad)?;
        if c.current_limit_a > m.current_limit_a {
            return Err(ConfigError {
                field: "cascade.current_limit_a",
                expected: "at most machine.current_limit_a",
            });
        }
        // The position loop is a discrete integrator around the velocity
        // loop: e[k+1] = e[k] - T (kp e[k] + kd (e[k] - e[k-1]) / T). Jury's
        // test: stable iff kd < 1 and kp T < 2 (1 - kd).
        if c.kd_pos >= 1.0 {
            return Err(ConfigError {
                field: "cascade.kd_pos",
                expected: "below 1 (the discrete PD loop is unstable beyond)",
            });
        }
        if c.kp_pos_1_s * self.period_s() >= 2.0 * (1.0 - c.kd_pos) {
            return Err(ConfigError {
                field: "cascade.kp_pos_1_s",
                expected: "below 2 (1 - kd_pos) / T (the discrete PD loop is unstable beyond)",
            });
        }
        // One count of motor-velocity (2 pi / (counts T)) or motor-angle
        // resolution must not ask for more than the whole current: beyond
        // that the loop is bang-bang on quantisation noise.
        let count_rad = 2.0 * math::PI / s.motor_counts_per_rev as f32;
        if c.kp_vel_a_s_rad * count_rad / self.period_s() > c.current_limit_a {
            return Err(ConfigError {
                field: "cascade.kp_vel_a_s_rad",
                expected: "at most current_limit_a per count of motor-velocity resolution",
            });
        }
        if c.ki_vel_a_rad * count_rad > c.current_limit_a {
            return Err(ConfigError {
                field: "cascade.ki_vel_a_rad",
                expected: "at most current_limit_a per count of motor angle",
            });
        }
        // The 16-bit counters' extender tells motion from wrap-around only
        // for steps below half their range (32 768 counts). The jump limit,
        // the largest legal step per tick, must stay well inside it: beyond,
        // legal motion aliases and jump detection is silently off.
        let per_tick =
            |rad_s: f32, counts: u32| rad_s * self.period_s() * counts as f32 / (2.0 * math::PI);
        let motor_step = per_tick(self.limits.max_motor_speed_rad_s, s.motor_counts_per_rev);
        if motor_step.is_nan() || motor_step > MAX_COUNTER_STEP {
            return Err(ConfigError {
                field: "scales.motor_counts_per_rev",
                expected: "such that limits.max_motor_speed_rad_s moves the motor encoder at most 16 000 counts per tick (half the 16-bit counter's range)",
            });
        }
        let motor_per_joint = m.gear_ratio * m.pulley_radius_m / m.rope_wheel_radius_m;
        // The magnetic encoder's jump limit allows four times the joint speed.
        let magnetic_step = 4.0
            * per_tick(
                self.limits.max_motor_speed_rad_s / motor_per_joint,
                s.magnetic_counts_per_rev,
            );
        if magnetic_step.is_nan() || magnetic_step > MAX_COUNTER_STEP {
            return Err(ConfigError {
                field: "scales.magnetic_counts_per_rev",
                expected: "such that four times the joint speed limit moves the magnetic encoder at most 16 000 counts per tick (half the 16-bit counter's range)",
            });
        }
        if c.vel_limit_rad_s > self.limits.max_motor_speed_rad_s {
            return Err(ConfigError {
                field: "cascade.vel_limit_rad_s",
                expected: "at most limits.max_motor_speed_rad_s (else a command trips Overspeed)",
            });
        }
        within(
            "cascade.vel_feedforward",
            c.vel_feedforward,
            0.0..=2.0,
            "within 0..=2",
        )?;
        if c.jae_blend_hz > 0.125 * self.control_rate_hz {
            return Err(ConfigError {
                field: "cascade.jae_blend_hz",
                expected: "below a quarter of the Nyquist rate",
            });
        }
        within(
            "cascade.hold_deadband_rad",
            c.hold_deadband_rad,
            0.0..=0.1,
            "within 0..=0.1 rad",
        )?;
        if self.limits.max_current_a <= c.current_limit_a {
            return Err(ConfigError {
                field: "limits.max_current_a",
                expected: "above cascade.current_limit_a",
            });
        }

        let o = &self.dob;
        positive("dob.cutoff_rad_s", o.cutoff_rad_s)?;
        if o.cutoff_rad_s * self.period_s() > 1.0 {
            return Err(ConfigError {
                field: "dob.cutoff_rad_s",
                expected: "below the control rate (g*T <= 1)",
            });
        }
        within(
            "dob.viscous_nm_s_rad",
            o.viscous_nm_s_rad,
            0.0..=1.0,
            "within 0..=1 N·m·s/rad",
        )?;

        let t = &self.tension;
        const FORCE: &str = "finite, magnitude at most 10000 N";
        magnitude("tension.f_sc1_n", t.f_sc1_n, 1e4, FORCE)?;
        magnitude("tension.f_cp2_n", t.f_cp2_n, 1e4, FORCE)?;
        magnitude(
            "tension.k_s_n_m",
            t.k_s_n_m,
            1e8,
            "finite, magnitude at most 1e8 N/m",
        )?;
        magnitude("tension.f_0_n", t.f_0_n, 1e4, FORCE)?;
        within(
            "tension.sign_switch_x1_m_s",
            t.sign_switch_x1_m_s,
            1e-9..=1.0,
            "between 1e-9 and 1 m/s",
        )?;
        within(
            "tension.sign_switch_x2_m_s",
            t.sign_switch_x2_m_s,
            1e-9..=1.0,
            "between 1e-9 and 1 m/s",
        )?;
        if let Err(expected) = t.added.validate() {
            return Err(ConfigError {
                field: "tension.added",
                expected,
            });
        }

        const STIFF: &str = "between 1 and 1e8 N/m";
        within(
            "stretch.cable1_n_m",
            self.stretch.cable1_n_m,
            1.0..=1e8,
            STIFF,
        )?;
        within(
            "stretch.cable2_n_m",
            self.stretch.cable2_n_m,
            1.0..=1e8,
            STIFF,
        )?;
        if self.stretch.cable0_n_m != 0.0 {
            within(
                "stretch.cable0_n_m",
                self.stretch.cable0_n_m,
                1.0..=1e9,
                "0 (not identified) or between 1 and 1e9 N/m",
            )?;
        }

        let f = &self.fusion;
        within(
            "fusion.pin_coulomb_nm",
            f.pin_coulomb_nm,
            0.0..=10.0,
            "within 0..=10 N·m",
        )?;
        within(
            "fusion.static_over_kinetic",
            f.static_over_kinetic,
            1.0..=10.0,
            "within 1..=10",
        )?;
        within(
            "fusion.kinetic_tolerance",
            f.kinetic_tolerance,
            0.0..=1.0,
            "within 0..=1",
        )?;
        within(
            "fusion.jae_error_rad",
            f.jae_error_rad,
            0.0..=1.0,
            "within 0..=1 rad",
        )?;
        within(
            "fusion.stiffness_tolerance",
            f.stiffness_tolerance,
            0.0..=1.0,
            "within 0..=1",
        )?;
        within(
            "fusion.creep_window_s",
            f.creep_window_s,
            self.period_s()..=10.0,
            "between one control period and 10 s",
        )?;
        within(
            "fusion.creep_distance_m",
            f.creep_distance_m,
            1e-9..=1e-2,
            "between 1 nm and 10 mm",
        )?;

        let p = &self.probe;
        within(
            "probe.amplitude_rad",
            p.amplitude_rad,
            1e-5..=0.035,
            "between 1e-5 rad and 0.035 rad (2°)",
        )?;
        within(
            "probe.max_amplitude_rad",
            p.max_amplitude_rad,
            0.0..=0.035,
            "between 0 and 0.035 rad (2°)",
        )?;
        within(
            "probe.frequency_hz",
            p.frequency_hz,
            0.1..=self.control_rate_hz / (2.0 * crate::probe::BLOCKS as f32),
            "between 0.1 Hz and a sixteenth of the control rate",
        )?;
        Ok(())
    }
}

impl FaultLimits {
    /// Check the fault limits alone (see `Controller::set_limits`). Every
    /// limit has a physical range: a jump or speed limit beyond it would
    /// never trip, an angle limit below it would trip at rest.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let l = self;
        // A cable-driven slider or a geared RE25 cannot move faster; the
        // bounds also keep the per-tick count limits inside `i32`.
        within(
            "limits.max_grating_speed_m_s",
            l.max_grating_speed_m_s,
            1e-3..=10.0,
            "between 0.001 and 10 m/s",
        )?;
        within(
            "limits.max_motor_speed_rad_s",
            l.max_motor_speed_rad_s,
            1.0..=5000.0,
            "between 1 and 5000 rad/s",
        )?;
        // At least one degree; at most the widened range homing uses.
        within(
            "limits.max_joint_angle_rad",
            l.max_joint_angle_rad,
            0.0175..=10.0,
            "between 0.0175 and 10 rad",
        )?;
        within(
            "limits.min_tension_fraction",
            l.min_tension_fraction,
            0.0..1.0,
            "within 0..1 (0 = off)",
        )?;
        within(
            "limits.max_current_a",
            l.max_current_a,
            0.01..=100.0,
            "between 0.01 and 100 A",
        )?;
        within(
            "limits.continuous_current_a",
            l.continuous_current_a,
            0.01..=100.0,
            "between 0.01 and 100 A",
        )?;
        within(
            "limits.thermal_time_constant_s",
            l.thermal_time_constant_s,
            0.1..=3600.0,
            "between 0.1 and 3600 s",
        )?;
        within(
            "limits.max_current_error_a",
            l.max_current_error_a,
            0.0..=100.0,
            "between 0 (off) and 100 A",
        )?;
        within(
            "limits.current_error_time_s",
            l.current_error_time_s,
            1e-4..=10.0,
            "between 0.0001 and 10 s",
        )?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid() {
        Config::default().validate().unwrap();
    }

    /// An added term's bad parameter, signal or coefficient is refused as
    /// what it is, and `term_error` names the term.
    #[test]
    fn an_added_terms_fault_is_named_as_itself() {
        use crate::effects::{EffectError, EffectKind, Term};
        use crate::model::sig;
        let with = |term: Term, coef: f32| {
            let mut c = Config::default();
            assert!(c
                .jae
                .added
                .push(Term::new(EffectKind::Linear, sig::X2_M), 1.0));
            assert!(c.jae.added.push(term, coef));
            c
        };
        let stop = |half_width: f32| Term::new(EffectKind::Stop { half_width }, sig::X2_M);
        let e = with(stop(-1.0), 1.0).validate().unwrap_err();
        assert_eq!(e.field, "jae.added");
        assert_eq!(e.expected, "terms whose parameters are finite and positive");
        assert!(matches!(
            with(stop(f32::NAN), 1.0).jae.added.term_error(),
            Some(EffectError::BadParameter { term: 1, .. })
        ));
        let e = with(Term::new(EffectKind::Linear, 200), 1.0)
            .validate()
            .unwrap_err();
        assert_eq!(e.expected, "terms that read the run-time signals only");
        let e = with(stop(1e-5), f32::NAN).validate().unwrap_err();
        assert_eq!(e.expected, "terms with finite coefficients");
        assert_eq!(with(stop(1e-5), f32::NAN).jae.added.term_error(), None);
        with(stop(1e-5), 1.0).validate().unwrap();
    }

    /// A bad fault limit is named as itself, not as the counter or
    /// cascade check that reads it.
    #[test]
    fn a_bad_limit_is_named_before_the_checks_that_read_it() {
        for v in [f32::NAN, -1.0] {
            let mut c = Config::default();
            c.limits.max_motor_speed_rad_s = v;
            assert_eq!(
                c.validate().unwrap_err().field,
                "limits.max_motor_speed_rad_s",
                "{v}"
            );
        }
    }

    #[test]
    fn a_1_khz_rate_derives_the_motor_differentiator_and_validates() {
        let c = Config::default();
        assert!(
            Config {
                control_rate_hz: 1000.0,
                ..c
            }
            .validate()
            .is_err(),
            "the 2 kHz defaults do not fit 1 kHz"
        );
        let (at, changes) = c.at_rate(1000.0);
        at.validate().unwrap();
        let fields: std::vec::Vec<_> = changes.iter().map(|a| a.field).collect();
        assert_eq!(
            fields,
            [
                "differentiators.motor_bandwidth_hz",
                "cascade.kp_vel_a_s_rad",
                "cascade.ki_vel_a_rad"
            ]
        );
        assert_eq!(at.differentiators.motor_bandwidth_hz, 100.0);
        // Crossover at the observer's 100 Hz: kp = 2 pi 100 J_m / K_m.
        let kp = 2.0 * crate::math::PI * 100.0 * 1.08e-6 / 23.4e-3;
        assert!((at.cascade.kp_vel_a_s_rad - kp).abs() < 1e-6 * kp);
        assert_eq!(
            at.differentiators.grating_bandwidth_hz,
            c.differentiators.grating_bandwidth_hz
        );
        let (same, none) = c.at_rate(2000.0);
        assert_eq!((same, none.len()), (c, 0));
    }

    /// Every setting `at_rate` derives, from the defaults and from gains
    /// and bandwidths scaled up and down, at rates from the slowest to the
    /// fastest `validate` takes, is one `RATE_DERIVED_FIELDS` lists (the
    /// host's error for a rejected file names the rate only for those), and
    /// each listed one is derived somewhere in that sweep.
    #[test]
    fn rate_derived_fields_lists_every_setting_at_rate_derives() {
        let mut seen = [false; RATE_DERIVED_FIELDS.len()];
        for scale in [0.1_f32, 1.0, 10.0] {
            let mut c = Config::default();
            c.differentiators.grating_bandwidth_hz *= scale;
            c.differentiators.motor_bandwidth_hz *= scale;
            c.cascade.kp_vel_a_s_rad *= scale;
            c.cascade.ki_vel_a_rad *= scale * scale * scale;
            c.cascade.kp_pos_1_s *= scale;
            for rate_hz in [100.0, 250.0, 500.0, 1000.0, 2000.0, 5000.0, 20_000.0] {
                for a in c.at_rate(rate_hz).1.iter() {
                    let i = RATE_DERIVED_FIELDS.iter().position(|f| *f == a.field);
                    let i = i.unwrap_or_else(|| panic!("{} is not listed", a.field));
                    seen[i] = true;
                }
            }
        }
        for (field, seen) in RATE_DERIVED_FIELDS.iter().zip(seen) {
            assert!(seen, "{field} is listed but never derived");
        }
    }

    /// Below the rate where the derived velocity crossover falls under
    /// three times the grating observer's bandwidth (30 Hz: between 800 Hz
    /// and 1 kHz with the defaults), the position loop's derivative comes
    /// from the grating observer at a third of the crossover; at 1 kHz
    /// and above nothing of it changes.
    #[test]
    fn below_1_khz_the_derivative_comes_from_the_observer_at_a_third_of_the_crossover() {
        let c = Config::default();
        let rotor = c.machine.torque_constant_nm_a / c.machine.rotor_inertia_kg_m2;
        for rate_hz in [250.0, 500.0, 800.0] {
            let (at, changes) = c.at_rate(rate_hz);
            at.validate().unwrap();
            let crossover_hz = at.cascade.kp_vel_a_s_rad * rotor / (2.0 * crate::math::PI);
            assert!(at.cascade.kd_on_observer_rate, "{rate_hz} Hz");
            let bw = at.differentiators.grating_bandwidth_hz;
            assert!(
                (bw - crossover_hz / 3.0).abs() < 1e-4 * bw,
                "{rate_hz} Hz: {bw} Hz against a crossover of {crossover_hz} Hz"
            );
            let flag = changes
                .iter()
                .find(|a| a.field == "cascade.kd_on_observer_rate")
                .expect("noted");
            assert!(flag.flag && flag.to_text() == "true" && flag.from_text() == "false");
        }
        for rate_hz in [1000.0, 2000.0, 5000.0] {
            let (at, _) = c.at_rate(rate_hz);
            assert!(!at.cascade.kd_on_observer_rate, "{rate_hz} Hz");
            assert_eq!(
                at.differentiators.grating_bandwidth_hz,
                c.differentiators.grating_bandwidth_hz
            );
        }
        // A user's choice stands: already on, only the bandwidth is derived.
        let on = Config {
            cascade: CascadeConfig {
                kd_on_observer_rate: true,
                ..c.cascade
            },
            ..c
        };
        let (_, changes) = on.at_rate(500.0);
        assert!(!changes
            .iter()
            .any(|a| a.field == "cascade.kd_on_observer_rate"));
    }

    /// Spectral radius of the bare rotor under the PI velocity loop, fed
    /// back through the motor's tracking observer (the plant integrates the
    /// held current over one period), leaving out the one eigenvalue at 1
    /// (the angle the loop does not regulate).
    fn velocity_loop_radius(c: &Config, kp_scale: f64) -> f64 {
        use nalgebra::SMatrix;
        let t = c.period_s() as f64;
        let b = (c.machine.torque_constant_nm_a / c.machine.rotor_inertia_kg_m2) as f64;
        let obs = crate::filter::TrackingObserver::new(
            c.differentiators.motor_bandwidth_hz,
            c.period_s(),
        );
        let l = obs.gains().map(|g| g as f64);
        let kp = c.cascade.kp_vel_a_s_rad as f64 * kp_scale;
        let ki = c.cascade.ki_vel_a_rad as f64;
        let f = [[1.0, t, 0.5 * t * t], [0.0, 1.0, t], [0.0, 0.0, 1.0]];
        // State: angle, speed, the observer's previous estimate (3), integral.
        // This tick's estimate: (I - l H) F x_prev + l angle.
        let mut est = [[0.0f64; 6]; 3];
        for i in 0..3 {
            for j in 0..3 {
                est[i][2 + j] = f[i][j] - l[i] * f[0][j];
            }
            est[i][0] += l[i];
        }
        let mut u = [0.0f64; 6];
        for j in 0..6 {
            u[j] = -kp * est[1][j];
        }
        u[5] += 1.0;
        let mut a = SMatrix::<f64, 6, 6>::zeros();
        for j in 0..6 {
            let e = |i: usize| if i == j { 1.0 } else { 0.0 };
            a[(0, j)] = e(0) + t * e(1) + 0.5 * t * t * b * u[j];
            a[(1, j)] = e(1) + t * b * u[j];
            for i in 0..3 {
                a[(2 + i, j)] = est[i][j];
            }
            a[(5, j)] = e(5) - ki * t * est[1][j];
        }
        let norm = |re: f64, im: f64| libm::sqrt(re * re + im * im);
        let mut ev: std::vec::Vec<_> = a
            .complex_eigenvalues()
            .iter()
            .map(|z| (z.re, z.im))
            .collect();
        ev.sort_by(|x, y| norm(x.0 - 1.0, x.1).total_cmp(&norm(y.0 - 1.0, y.1)));
        ev[1..].iter().map(|z| norm(z.0, z.1)).fold(0.0, f64::max)
    }

    #[test]
    fn at_rate_keeps_the_bare_rotor_velocity_loop_stable_with_margin_at_every_rate() {
        // Without the derivation the defaults at 1 kHz are within 10 % of
        // instability (the drive current chatters on the unhooked motor).
        let (slow, _) = Config::default().at_rate(1000.0);
        let undrived = Config {
            cascade: Config::default().cascade,
            ..slow
        };
        assert!(velocity_loop_radius(&undrived, 1.0) < 1.0);
        assert!(velocity_loop_radius(&undrived, 1.1) >= 1.0);
        let mut machines = std::vec::Vec::new();
        for k in [0.3f32, 1.0, 3.0] {
            for j in [0.3f32, 1.0, 3.0] {
                let mut c = Config::default();
                c.machine.torque_constant_nm_a *= k;
                c.machine.rotor_inertia_kg_m2 *= j;
                machines.push(c);
            }
        }
        for base in &machines {
            for rate in [
                100.0, 150.0, 300.0, 500.0, 1000.0, 1500.0, 2000.0, 5000.0, 20000.0,
            ] {
                let (c, _) = base.at_rate(rate);
                let r = velocity_loop_radius(&c, 1.0);
                let margin = velocity_loop_radius(&c, 1.4);
                assert!(
                    r < 1.0 && margin < 1.0,
                    "{rate} Hz, K_m {} J_m {}: radius {r}, at 1.4 x kp_vel {margin}",
                    c.machine.torque_constant_nm_a,
                    c.machine.rotor_inertia_kg_m2
                );
                let w_c = c.cascade.kp_vel_a_s_rad * c.machine.torque_constant_nm_a
                    / c.machine.rotor_inertia_kg_m2;
                assert!(
                    c.cascade.kp_pos_1_s <= w_c / 3.0 * 1.0001,
                    "{rate} Hz: cascade separation"
                );
                c.validate().unwrap();
            }
        }
    }

    #[test]
    fn fusion_default_pin_friction_is_inside_model_cs_upper_bound() {
        let c = Config::default();
        let ub = FusionConfig::pin_upper_bound_nm(&c);
        // The default puts f_cp2 beyond slider 2 on the pin; the bound
        // allows all of model C's Coulomb total.
        assert!((c.fusion.pin_coulomb_nm - 19.65e-3).abs() < 0.1e-3);
        assert!((ub - 35.17e-3).abs() < 0.1e-3, "{ub}");
        assert!(c.fusion.pin_coulomb_nm <= ub);
        // The bound is the pin's share plus slider 1's band at the pulley.
        let slider1_nm = c.tension.f_sc1_n * c.machine.pulley_radius_m;
        assert!(
            (ub - c.fusion.pin_coulomb_nm - slider1_nm).abs() < 1e-6,
            "{ub}"
        );
        let mut lumped = c;
        lumped.tension.f_sc1_n += lumped.tension.f_cp2_n;
        lumped.tension.f_cp2_n = 0.0;
        assert_eq!(FusionConfig::pin_upper_bound_nm(&lumped), ub);
    }

    #[test]
    fn cable_stiffness_from_the_seeds_jae() {
        let m = Machine::default();
        let s = StretchConfig::from_jae(264.356, m.spring_n_m, m.pulley_radius_m).unwrap();
        assert!((s.cable2_n_m - 11_437.0).abs() < 20.0, "{}", s.cable2_n_m);
        assert!(StretchConfig::from_jae(200.0, m.spring_n_m, m.pulley_radius_m).is_none());
    }

    #[test]
    fn impossible_values_name_their_field() {
        let mut c = Config::default();
        c.machine.gear_ratio = -35.0;
        assert_eq!(c.validate().unwrap_err().field, "machine.gear_ratio");
        let mut c = Config::default();
        c.jae.c_pos_rad_m = f32::NAN;
        assert_eq!(c.validate().unwrap_err().field, "jae.c_pos_rad_m");
        let c = Config {
            control_rate_hz: 50_000.0,
            ..Config::default()
        };
        assert_eq!(c.validate().unwrap_err().field, "control_rate_hz");
        let mut c = Config::default();
        c.cascade.current_limit_a = 3.0;
        assert_eq!(c.validate().unwrap_err().field, "cascade.current_limit_a");
    }

    /// Values that would silently disable a check, trip it at rest, or
    /// overflow on the control path (issue 10's findings) are refused,
    /// each naming its field.
    #[test]
    fn values_that_would_disable_a_check_are_refused() {
        let refused = |edit: fn(&mut Config), field: &str| {
            let mut c = Config::default();
            edit(&mut c);
            assert_eq!(c.validate().unwrap_err().field, field);
        };
        // A rail margin beyond the ADC's range: every sample a rail fault.
        refused(
            |c| c.scales.adc_rail_margin_codes = 5000,
            "scales.adc_rail_margin_codes",
        );
        // A jump limit that wraps: jump detection off.
        refused(
            |c| c.limits.max_grating_speed_m_s = 1e30,
            "limits.max_grating_speed_m_s",
        );
        refused(|c| c.cascade.kp_pos_1_s = 1e30, "cascade.kp_pos_1_s");
        // An angle limit below the resolution: trips at rest.
        refused(
            |c| c.limits.max_joint_angle_rad = 1e-30,
            "limits.max_joint_angle_rad",
        );
        // A legal step beyond the 16-bit counter's half range: motion
        // aliases through the extender and jumps go unseen.
        refused(
            |c| c.scales.motor_counts_per_rev = 1_000_000,
            "scales.motor_counts_per_rev",
        );
        refused(
            |c| c.scales.magnetic_counts_per_rev = 1_000_000,
            "scales.magnetic_counts_per_rev",
        );
        // The same scales are fine at a rate whose step stays small.
        let mut c = Config::default();
        c.scales.motor_counts_per_rev = 20_000;
        c.validate().unwrap();
    }
}
