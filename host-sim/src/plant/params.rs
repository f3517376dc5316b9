//! Parameters of the simulated prototype, with the derivation of every default.
//!
//! # Where the defaults come from
//!
//! Three kinds of numbers:
//!
//! 1. **Datasheet constants** (DESIGN.md §1): `K_m`, `J_m`, `z_i`, `r_m`, `r`,
//!    `l_e`, `K_s`, `F_0`, the sensor resolutions and the ±2 A limit.
//! 2. **Values the seed identified**, inverted through the seed's own
//!    parameterisation (`r = 4 mm`):
//!    * JAE, Eq. 16/26: `c4 = (K_s + K_w2) / (K_w2 r) = 264.356` gives
//!      `K_w2 = K_s / (c4 r - 1) = 656.6 / 0.057424 = 11 434 N/m`;
//!      `c3 = f_sc2 / (K_w2 r) = 0.0025` gives slider 2's Coulomb friction
//!      `f_sc2 = 0.0025 · 45.74 N = 0.114 N`; `c2 = f_sv2 / (K_w2 r) =
//!      0.5225` gives its viscous friction `f_sv2 = 23.9 N·s/m`.
//!      `c1 = m_1 / (K_w2 r) = 0.0805` would mean a 3.7 kg slider, which a
//!      MISUMI SSEBZ8 miniature guide is not: `c1` is ill-conditioned in the
//!      seed's fit (its regressor, `x2''`, is tiny) and is **not** used; the
//!      slider mass is estimated instead (below).
//!    * Simplified model C, Eq. 29: the Coulomb terms `f_sc1 sgn(x1') +
//!      f_cp2 sgn(x2')` total 3.879 + 5.027 = 8.906 N of cable-1 tension.
//!      `x1'`, `x2'` (and `phi'`) have the same sign except for short
//!      transients, so the *sum* is what the data pins down; the split is
//!      placed by physics and by the seed's other observations (below).
//!    * `B_m = 1.6934e-5 N·m·s/rad` (seed Sect. 4.2), used as the true motor
//!      damping (it lumps the gearhead's losses at the motor shaft).
//! 3. **Estimates** where the seed gives nothing, each argued at its field:
//!    slider masses, joint inertia, viscous joint friction, the static/kinetic
//!    friction ratio, cable damping, the drive's bandwidth and noise, and the
//!    drive-side cable stiffness `K_w0`.
//!
//! ## Where the 8.9 N of Coulomb friction sits
//!
//! * **Slider 2**: only `f_sc2 = 0.114 N` (the JAE's `c3`; more would show
//!   as θ-x2 hysteresis that the seed's JAE fit, 0.28° mean error, excludes).
//! * **Joint pin**: `f_efc = 4 mN·m` (μ ≈ 0.1 on a ≈ 1 mm pin radius under the
//!   two cables' 2 F_0 ≈ 39 N), i.e. 1.0 N of cable tension and 0.2 N at the
//!   tip. Putting all of `f_cp2` here (20 mN·m, 1 N at the tip) would let
//!   joint stiction swallow the seed's 0.3 N test loads (82 % accuracy) and
//!   its ±0.1 N static no-load error: the tip-equivalent pin friction must be
//!   of that order.
//! * **Slider 1** (guide, idlers): the seed's `f_sc1 = 3.879 N` as identified.
//! * **Motor and gearhead**: the rest of `f_cp2`, `5.027 - 0.114 - 1.0 =
//!   3.91 N` of rope tension, i.e. 0.67 mN·m at the motor shaft (RE25 brush
//!   and bearing friction, about 0.5 mN·m from its no-load current, plus the
//!   planetary gearhead). It has the sign of `phi'`, which the seed's fit
//!   cannot tell from `sgn(x2')` during motion. Friction here, rather than on
//!   slider 1, is what lets cable 1 drag slider 1 back when a 250 g load
//!   assists the joint (cable 1 then carries only ≈ 7 N).
//!
//! An identification of model C on this plant returns roughly
//! `f_sc1 + f_cp2 = 8.9 N`, split by the reversal transients.
//!
//! ## Cable stiffness and the seed's Fig. 10
//!
//! Cables 1 and 2 run the same path from the drive unit through the shaft to
//! the joint, so `K_w1 = K_w2 = 11 434 N/m`. Cable 0 is short (≈ 60 mm from
//! the rope wheel to slider 1 on the drive base; a 0.45 mm 7×7 steel rope has
//! `EA ≈ 1.2e4 N`): `K_w0 = 2e5 N/m`. With the motor in closed loop on its
//! encoder (Fig. 8/10) the joint lags the motor-implied angle by the stretch
//! of cables 0 and 1, `e = (ΔF_1 / K_w0 + ΔF_w1 / K_w1) / r`. At the end of a
//! positive ±30° stroke `ΔF_w1 ≈ K_s' r θ + f_efc / r + f_sc2 ≈ 1.3 + 1.0 +
//! 0.1 = 2.4 N` (`K_s'` = spring in series with cable 2, 620 N/m) and
//! `ΔF_1 ≈ 2.4 + 3.9 (+ viscous) ≈ 6.4 N`: `e ≈ (0.032 + 0.21) mm / 4 mm
//! = 0.061 rad = 3.5°`, against the seed's 4.1° worst error. `host-sim
//! simulate --scenario track-motor` measures it.

use cable_joint::units::Scales;
use serde::{Deserialize, Serialize};

use super::effects::Effects;

/// Drive motor, gearhead and rope wheel (seed Eq. 7).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MotorParams {
    /// Torque constant `K_m` at the reference temperature, N·m/A (RE25: 23.4 mN·m/A).
    pub torque_constant_nm_a: f64,
    /// Rotor inertia `J_m`, kg·m² (RE25: 1.08e-6; the gearhead adds ~5 %, not modelled).
    pub rotor_inertia_kg_m2: f64,
    /// Viscous damping at the motor shaft `B_m`, N·m·s/rad (seed: 1.6934e-5).
    pub viscous_nm_s_rad: f64,
    /// Coulomb friction torque at the motor shaft (brushes, bearings,
    /// gearhead), N·m; static equals kinetic. It has the sign of `phi'`,
    /// hence of `x1'`, so model C's `f_sc1` absorbs it.
    pub coulomb_nm: f64,
    /// Gear ratio `z_i` (35).
    pub gear_ratio: f64,
    /// Rope-wheel radius `r_m`, m (6 mm).
    pub rope_wheel_radius_m: f64,
}

impl Default for MotorParams {
    fn default() -> Self {
        Self {
            torque_constant_nm_a: 23.4e-3,
            rotor_inertia_kg_m2: 1.08e-6,
            viscous_nm_s_rad: 1.6934e-5,
            coulomb_nm: MOTOR_COULOMB_NM,
            gear_ratio: 35.0,
            rope_wheel_radius_m: 6e-3,
        }
    }
}

/// Current-controlled drive (Copley ACI-055-18) and its current monitor.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DriveParams {
    /// Closed-loop current bandwidth, Hz (first order). Analogue PWM drives of
    /// this class close the current loop at 1-2 kHz.
    pub bandwidth_hz: f64,
    /// Current limit, A (±2 A set-up).
    pub current_limit_a: f64,
    /// Standard deviation of the current monitor's noise, A (analogue noise of
    /// the ±10 V monitor through the board's divider; about 4 ADC codes).
    pub monitor_noise_a: f64,
    /// Constant offset of the current monitor, A (a few ADC codes).
    pub monitor_offset_a: f64,
}

impl Default for DriveParams {
    fn default() -> Self {
        Self {
            bandwidth_hz: 1500.0,
            current_limit_a: 2.0,
            monitor_noise_a: 5e-3,
            monitor_offset_a: 3e-3,
        }
    }
}

/// A cable segment: a spring (and damper) that can only pull.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CableParams {
    /// Axial stiffness, N/m.
    pub stiffness_n_m: f64,
    /// Axial damping in parallel with the spring, N·s/m (0 = none).
    pub damping_n_s_m: f64,
}

impl Default for CableParams {
    fn default() -> Self {
        Self {
            stiffness_n_m: K_W2_N_M,
            damping_n_s_m: 0.0,
        }
    }
}

/// A guide slider with its idler (seed Eq. 8 and 11).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SliderParams {
    /// Moving mass, kg.
    pub mass_kg: f64,
    /// Viscous friction, N·s/m.
    pub viscous_n_s_m: f64,
    /// Kinetic (Coulomb) friction, N.
    pub coulomb_n: f64,
    /// Static (breakaway) friction, N (>= Coulomb).
    pub static_n: f64,
    /// Travel either side of the rest position, m (end stops; the SSEBZ8L-85
    /// rail leaves about ±30 mm).
    pub travel_m: f64,
}

impl Default for SliderParams {
    fn default() -> Self {
        SLIDER2
    }
}

/// The gripper joint (seed Eq. 13).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct JointParams {
    /// Inertia about the joint axis `J_e`, kg·m².
    pub inertia_kg_m2: f64,
    /// Viscous friction `f_efv`, N·m·s/rad.
    pub viscous_nm_s_rad: f64,
    /// Coulomb friction `f_efc`, N·m.
    pub coulomb_nm: f64,
    /// Static (breakaway) friction, N·m (>= Coulomb).
    pub static_nm: f64,
    /// Pulley radius `r`, m (4 mm).
    pub pulley_radius_m: f64,
    /// Gripper length `l_e` (lever of the tip force), m (20 mm).
    pub gripper_length_m: f64,
    /// Mechanical range either side of 0, rad (end stops, 100°).
    pub range_rad: f64,
}

impl Default for JointParams {
    fn default() -> Self {
        JOINT
    }
}

/// Return spring on slider 2 (seed Eq. 10) and the loop preload.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SpringParams {
    /// Spring rate `K_s`, N/m (KSSC2189: 0.6566 N/mm).
    pub stiffness_n_m: f64,
    /// Preload `F_0`, N: every cable and the spring carry it at rest (Eq. 6).
    pub preload_n: f64,
}

impl Default for SpringParams {
    fn default() -> Self {
        Self {
            stiffness_n_m: 656.6,
            preload_n: 19.5,
        }
    }
}

/// Sensors: resolutions (the same [`Scales`] type the controller is
/// configured with, here as the *true* scales) and power-on counter values.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SensorParams {
    /// True scales of the gratings, encoders, ADC and DAC.
    pub scales: Scales,
    /// Grating timer counts at the rest position (power-on value), `[x1, x2]`.
    pub grating_initial_counts: [i32; 2],
    /// Motor-encoder timer count at the rest position. The default sits near
    /// the 16-bit wrap so that every run crosses it.
    pub motor_initial_count: u16,
    /// Magnetic-encoder timer count at the rest position.
    pub magnetic_initial_count: u16,
    /// Is the magnetic joint encoder fitted? (Calibration runs; when not
    /// fitted the timer stays at its initial count.)
    pub magnetic_fitted: bool,
}

impl Default for SensorParams {
    fn default() -> Self {
        Self {
            scales: Scales::default(),
            grating_initial_counts: [0, 0],
            motor_initial_count: 65_000,
            magnetic_initial_count: 100,
            magnetic_fitted: true,
        }
    }
}

/// Integration settings.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct IntegrationParams {
    /// Plant step rate, Hz (at least 20 kHz). The closed-loop runner rounds it
    /// up to a whole number of steps per control period.
    pub step_hz: f64,
    /// Largest accepted `w_max · dt`, where `w_max` bounds the highest natural
    /// frequency (Gershgorin bound on the mass-normalised stiffness matrix).
    /// Symplectic Euler is stable below 2; 0.5 keeps the phase error of the
    /// fastest mode small.
    pub max_omega_dt: f64,
}

impl Default for IntegrationParams {
    fn default() -> Self {
        Self {
            step_hz: 40_000.0,
            max_omega_dt: 0.5,
        }
    }
}

/// Everything the plant needs.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PlantParams {
    /// Motor, gearhead, rope wheel.
    pub motor: MotorParams,
    /// Current drive and monitor.
    pub drive: DriveParams,
    /// Cable 0: rope wheel to slider 1.
    pub cable0: CableParams,
    /// Slider 1 (grating 1, `x1`).
    pub slider1: SliderParams,
    /// Cable 1: slider 1 to the joint pulley (`K_w1`).
    pub cable1: CableParams,
    /// Gripper joint.
    pub joint: JointParams,
    /// Cable 2: joint pulley to slider 2 (`K_w2`).
    pub cable2: CableParams,
    /// Slider 2 (grating 2, `x2`).
    pub slider2: SliderParams,
    /// Return spring and preload.
    pub spring: SpringParams,
    /// Sensors.
    pub sensors: SensorParams,
    /// Integration.
    pub integration: IntegrationParams,
    /// Switchable effects the estimators do not model (all off by default).
    pub effects: Effects,
    /// Motor decoupled from the cable (rope wheel unhooked, slider 1
    /// clamped): the no-load run that identifies `B_m` (seed Sect. 4.2). The
    /// cable side then stays at rest.
    pub motor_decoupled: bool,
}

/// `K_w2` from the seed's `c4` (see the module documentation), N/m.
pub const K_W2_N_M: f64 = 656.6 / (264.356 * 4e-3 - 1.0);

/// Damping ratio assumed for every cable against the slider it drives:
/// steel wire rope has a loss factor of a few percent (inter-strand friction),
/// `c = 2 ζ sqrt(K m)` with `ζ = 0.05`.
pub const CABLE_DAMPING_RATIO: f64 = 0.05;

/// Static over kinetic friction of the guides and the joint pin: 1.2 (dry
/// steel-on-steel and greased guides sit between 1.1 and 1.5).
pub const STATIC_OVER_KINETIC: f64 = 1.2;

/// Slider 2: friction from the seed's JAE (`c2`, `c3`), mass estimated: a
/// SSEBZ8 carriage (~10 g), the idler bracket and the grating scale clamp
/// (~15 g) and a third of the spring (~2 g): 30 g.
const SLIDER2: SliderParams = SliderParams {
    mass_kg: 0.030,
    viscous_n_s_m: 0.5225 * K_W2_N_M * 4e-3,
    coulomb_n: 0.0025 * K_W2_N_M * 4e-3,
    static_n: STATIC_OVER_KINETIC * 0.0025 * K_W2_N_M * 4e-3,
    travel_m: 0.03,
};

/// Joint pin Coulomb torque, N·m.
pub const JOINT_COULOMB_NM: f64 = 4e-3;

/// Motor and gearhead Coulomb torque at the motor shaft, N·m: the part of
/// the seed's `f_cp2` that is neither slider 2 nor the joint pin, through
/// `r_m / z_i`.
pub const MOTOR_COULOMB_NM: f64 =
    (5.027 - 0.0025 * K_W2_N_M * 4e-3 - JOINT_COULOMB_NM / 4e-3) * 6e-3 / 35.0;

/// Slider 1 Coulomb friction: the seed's `f_sc1`, N.
pub const SLIDER1_COULOMB_N: f64 = 3.879;

/// Slider 1: Coulomb friction as identified; the same guide type as slider 2, so
/// the same viscous friction; mass as slider 2 plus the cable-0 termination
/// (~10 g): 40 g.
const SLIDER1: SliderParams = SliderParams {
    mass_kg: 0.040,
    viscous_n_s_m: 0.5225 * K_W2_N_M * 4e-3,
    coulomb_n: SLIDER1_COULOMB_N,
    static_n: STATIC_OVER_KINETIC * SLIDER1_COULOMB_N,
    travel_m: 0.03,
};

/// Joint: Coulomb torque of the pin (see the module documentation),
/// 4 mN·m. Inertia: a 20 mm stainless jaw of about 1 g about its end
/// (`m l² / 3 ≈ 1.3e-7`), the 4 mm pulley and the magnet ring of the encoder:
/// 2e-7 kg·m². Viscous: a greased pin, 2e-5 N·m·s/rad (0.1 mN·m at the fastest
/// 5 rad/s; unidentifiable in the seed, whose model-C `f_efv/r` had a 27 %
/// standard deviation).
const JOINT: JointParams = JointParams {
    inertia_kg_m2: 2e-7,
    viscous_nm_s_rad: 2e-5,
    coulomb_nm: JOINT_COULOMB_NM,
    static_nm: STATIC_OVER_KINETIC * JOINT_COULOMB_NM,
    pulley_radius_m: 4e-3,
    gripper_length_m: 20e-3,
    range_rad: 100.0 * std::f64::consts::PI / 180.0,
};

/// Cable 0 stiffness, N/m (see the module documentation).
pub const K_W0_N_M: f64 = 2.0e5;

/// Cable 1 stiffness, N/m: the same cable and path as cable 2.
pub const K_W1_N_M: f64 = K_W2_N_M;

/// Deep-merge `over` onto `base` (tables key by key, everything else replaced).
fn merge_toml(base: &mut toml::Value, over: toml::Value) {
    match (base, over) {
        (toml::Value::Table(b), toml::Value::Table(o)) => {
            for (k, v) in o {
                match b.get_mut(&k) {
                    Some(slot) => merge_toml(slot, v),
                    None => {
                        b.insert(k, v);
                    }
                }
            }
        }
        (slot, v) => *slot = v,
    }
}

fn cable_damping(k_n_m: f64, mass_kg: f64) -> f64 {
    2.0 * CABLE_DAMPING_RATIO * (k_n_m * mass_kg).sqrt()
}

impl Default for PlantParams {
    fn default() -> Self {
        Self {
            motor: MotorParams::default(),
            drive: DriveParams::default(),
            cable0: CableParams {
                stiffness_n_m: K_W0_N_M,
                damping_n_s_m: cable_damping(K_W0_N_M, SLIDER1.mass_kg),
            },
            slider1: SLIDER1,
            cable1: CableParams {
                stiffness_n_m: K_W1_N_M,
                damping_n_s_m: cable_damping(K_W1_N_M, SLIDER1.mass_kg),
            },
            joint: JOINT,
            cable2: CableParams {
                stiffness_n_m: K_W2_N_M,
                damping_n_s_m: cable_damping(K_W2_N_M, SLIDER2.mass_kg),
            },
            slider2: SLIDER2,
            spring: SpringParams::default(),
            sensors: SensorParams::default(),
            integration: IntegrationParams::default(),
            effects: Effects::default(),
            motor_decoupled: false,
        }
    }
}

impl PlantParams {
    /// Parse a TOML file's text. The text is merged key by key onto the
    /// defaults, so a partial table (e.g. `[slider1]` with only `mass_kg`)
    /// keeps the *slider-1* defaults for its other fields; an unknown key is
    /// an error.
    pub fn from_toml_str(text: &str) -> anyhow::Result<Self> {
        let toml_err = |e: toml::de::Error| anyhow::anyhow!(crate::log::toml_error(text, &e));
        let user: toml::Value = toml::from_str(text).map_err(toml_err)?;
        let mut merged = toml::Value::try_from(Self::default())?;
        merge_toml(&mut merged, user);
        merged.try_into().map_err(toml_err)
    }

    /// The parameters as TOML.
    pub fn to_toml_string(&self) -> anyhow::Result<String> {
        Ok(toml::to_string_pretty(self)?)
    }

    /// What the seed's JAE coefficients (Eq. 26) are for these parameters:
    /// `[m_1, f_sv2, f_sc2, K_s + K_w2] / (K_w2 r)`.
    pub fn jae_coefficients(&self) -> [f64; 4] {
        let kr = self.cable2.stiffness_n_m * self.joint.pulley_radius_m;
        [
            self.slider2.mass_kg / kr,
            self.slider2.viscous_n_s_m / kr,
            self.slider2.coulomb_n / kr,
            (self.spring.stiffness_n_m + self.cable2.stiffness_n_m) / kr,
        ]
    }

    /// What simplified model C (Eq. 29) is for these parameters, as the DOB
    /// sees the load: `[f_sc1 + f_m z_i / r_m, f_sc2 + f_efc / r, K_s, F_0]`
    /// (the motor's Coulomb torque appears as rope tension with the sign of
    /// `x1'`).
    pub fn model_c_coefficients(&self) -> [f64; 4] {
        let m = &self.motor;
        [
            self.slider1.coulomb_n + m.coulomb_nm * m.gear_ratio / m.rope_wheel_radius_m,
            self.slider2.coulomb_n + self.joint.coulomb_nm / self.joint.pulley_radius_m,
            self.spring.stiffness_n_m,
            self.spring.preload_n,
        ]
    }

    /// The joint's undamped stick-slip step, rad, as `[stiffest, softest]`:
    /// a pin stuck at its static torque `tau_s` that breaks loose slides
    /// until its kinetic torque `tau_k` has let the cables' torque swing as
    /// far past the balance as it started before it, `2 (tau_s - tau_k) /
    /// k_theta`, with `k_theta = r^2 (k_1 + k_2)` the cables' rotational
    /// stiffness about the pin with the motor held. The stiffest chain has
    /// both sliders stuck (`k_1 = K_w1`, `k_2 = K_w2`); the softest has them
    /// free (`k_1` = cable 1 in series with cable 0, `k_2` = cable 2 in
    /// series with the return spring). Damping and presliding shorten the
    /// real step; a hold that frees the pin moves the tip by about this much
    /// whatever its estimator does.
    pub fn pin_stick_slip_step_rad(&self) -> [f64; 2] {
        let series = |a: f64, b: f64| a * b / (a + b);
        let r2 = self.joint.pulley_radius_m * self.joint.pulley_radius_m;
        let (k1, k2) = (self.cable1.stiffness_n_m, self.cable2.stiffness_n_m);
        let k1_free = series(self.cable0.stiffness_n_m, k1);
        let k2_free = series(k2, self.spring.stiffness_n_m);
        let band = 2.0 * (self.joint.static_nm - self.joint.coulomb_nm).max(0.0);
        [band / (r2 * (k1 + k2)), band / (r2 * (k1_free + k2_free))]
    }

    /// The joint angle the JAE cannot see while slider 2 sticks, rad: a
    /// turn of the joint changes cable 2's tension by `K_w2 r` per radian
    /// and slider 2 does not move until that change reaches its static
    /// friction, so from one edge of its band to the other the joint turns
    /// `2 F_s2 / (K_w2 r)` with the grating at rest (the spring side is
    /// held by the stuck slider). A hold on `theta_hat` that has to correct
    /// wanders across this band before its sensor answers.
    pub fn jae_blind_band_rad(&self) -> f64 {
        2.0 * self.slider2.static_n / (self.cable2.stiffness_n_m * self.joint.pulley_radius_m)
    }

    /// Check that every value is physically possible; the error names the field.
    pub fn validate(&self) -> anyhow::Result<()> {
        fn pos(name: &str, v: f64) -> anyhow::Result<()> {
            anyhow::ensure!(
                v.is_finite() && v > 0.0,
                "plant.{name} must be finite and > 0, got {v}"
            );
            Ok(())
        }
        fn nonneg(name: &str, v: f64) -> anyhow::Result<()> {
            anyhow::ensure!(
                v.is_finite() && v >= 0.0,
                "plant.{name} must be finite and >= 0, got {v}"
            );
            Ok(())
        }
        let m = &self.motor;
        pos("motor.torque_constant_nm_a", m.torque_constant_nm_a)?;
        pos("motor.rotor_inertia_kg_m2", m.rotor_inertia_kg_m2)?;
        nonneg("motor.viscous_nm_s_rad", m.viscous_nm_s_rad)?;
        nonneg("motor.coulomb_nm", m.coulomb_nm)?;
        pos("motor.gear_ratio", m.gear_ratio)?;
        pos("motor.rope_wheel_radius_m", m.rope_wheel_radius_m)?;
        let d = &self.drive;
        pos("drive.bandwidth_hz", d.bandwidth_hz)?;
        pos("drive.current_limit_a", d.current_limit_a)?;
        nonneg("drive.monitor_noise_a", d.monitor_noise_a)?;
        anyhow::ensure!(
            d.monitor_offset_a.is_finite(),
            "plant.drive.monitor_offset_a must be finite"
        );
        for (name, c) in [
            ("cable0", &self.cable0),
            ("cable1", &self.cable1),
            ("cable2", &self.cable2),
        ] {
            pos(&format!("{name}.stiffness_n_m"), c.stiffness_n_m)?;
            nonneg(&format!("{name}.damping_n_s_m"), c.damping_n_s_m)?;
        }
        for (name, s) in [("slider1", &self.slider1), ("slider2", &self.slider2)] {
            pos(&format!("{name}.mass_kg"), s.mass_kg)?;
            nonneg(&format!("{name}.viscous_n_s_m"), s.viscous_n_s_m)?;
            nonneg(&format!("{name}.coulomb_n"), s.coulomb_n)?;
            nonneg(&format!("{name}.static_n"), s.static_n)?;
            pos(&format!("{name}.travel_m"), s.travel_m)?;
            anyhow::ensure!(
                s.static_n >= s.coulomb_n,
                "plant.{name}.static_n ({}) must be >= coulomb_n ({})",
                s.static_n,
                s.coulomb_n
            );
        }
        let j = &self.joint;
        pos("joint.inertia_kg_m2", j.inertia_kg_m2)?;
        nonneg("joint.viscous_nm_s_rad", j.viscous_nm_s_rad)?;
        nonneg("joint.coulomb_nm", j.coulomb_nm)?;
        nonneg("joint.static_nm", j.static_nm)?;
        anyhow::ensure!(
            j.static_nm >= j.coulomb_nm,
            "plant.joint.static_nm must be >= coulomb_nm"
        );
        pos("joint.pulley_radius_m", j.pulley_radius_m)?;
        pos("joint.gripper_length_m", j.gripper_length_m)?;
        pos("joint.range_rad", j.range_rad)?;
        pos("spring.stiffness_n_m", self.spring.stiffness_n_m)?;
        nonneg("spring.preload_n", self.spring.preload_n)?;
        // The simulated board's scales, checked as a configuration's.
        self.sensors
            .scales
            .validate()
            .map_err(|e| anyhow::anyhow!("plant.sensors.{} must be {}", e.field, e.expected))?;
        // Above 1e7 Hz a second of a run is over ten million steps: a
        // typing error, not a finer model.
        anyhow::ensure!(
            self.integration.step_hz.is_finite()
                && (20_000.0..=1e7).contains(&self.integration.step_hz),
            "plant.integration.step_hz must be between 20000 and 1e7 Hz, got {}",
            self.integration.step_hz
        );
        pos("integration.max_omega_dt", self.integration.max_omega_dt)?;
        self.effects.validate()
    }
}
