//! Effects of the real prototype that the core's estimators do not model.
//!
//! Each is off by default (`None`) and switched on with its parameters, from
//! the plant TOML (`[effects.creep]`, ...) or by name
//! ([`Effects::enable`], the CLI's `--effect creep,thermal`). The defaults of
//! each effect are physically plausible magnitudes for this prototype; tests
//! and scenarios can exaggerate them.

use serde::{Deserialize, Serialize};

/// The switchable effects.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Effects {
    /// Presliding hysteresis (LuGre) in place of pure Coulomb friction on
    /// both sliders and the joint.
    pub presliding: Option<Presliding>,
    /// Cable creep: the cables' rest lengths relax under tension.
    pub creep: Option<Creep>,
    /// Winding temperature: `K_m` drops as the winding heats.
    pub thermal: Option<Thermal>,
    /// Cubic hardening of the return spring.
    pub spring_hardening: Option<SpringHardening>,
    /// Slow drift of the current sensor's offset.
    pub offset_drift: Option<OffsetDrift>,
}

/// Presliding friction, the LuGre model (Canudas de Wit et al., 1995).
///
/// Pure Coulomb friction holds an element rigidly until breakaway. Real
/// contacts (the guide's balls, the joint pin) first deflect elastically
/// ("presliding", micrometres), so a reversal is not a jump of the friction
/// force but a hysteretic transition over a short distance, and a small
/// oscillating force moves the element a little without gross sliding. LuGre
/// models the contact as bristles of mean deflection `z`:
///
/// ```text
/// z' = v - sigma0 |v| z / g(v),   g(v) = F_c + (F_s - F_c) exp(-(v / v_s)^2)
/// F  = sigma0 z + sigma1 z' (+ the element's viscous friction b v)
/// ```
///
/// `sigma0 = F_c / presliding` (the bristle stiffness that reaches the
/// Coulomb level over the presliding distance), `sigma1 = 2 ζ sqrt(sigma0 m)`
/// (critically damped bristles for `ζ = 1`). The JAE's held-sign term and
/// model C's sign terms cannot represent the gradual transition.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Presliding {
    /// Presliding distance of the sliders, m (rolling guides: 10-50 µm).
    pub slider_presliding_m: f64,
    /// Presliding angle of the joint, rad (a few µm at a ~1.5 mm pin).
    pub joint_presliding_rad: f64,
    /// Stribeck speed of the sliders, m/s.
    pub slider_stribeck_m_s: f64,
    /// Stribeck speed of the joint, rad/s.
    pub joint_stribeck_rad_s: f64,
    /// Damping ratio of the bristle mode.
    pub damping_ratio: f64,
}

impl Default for Presliding {
    fn default() -> Self {
        Self {
            slider_presliding_m: 20e-6,
            joint_presliding_rad: 3e-3,
            slider_stribeck_m_s: 1e-3,
            joint_stribeck_rad_s: 0.25,
            damping_ratio: 1.0,
        }
    }
}

/// Cable creep: viscoelastic lengthening of a steel wire rope under tension
/// (strand bedding and polymer-core creep), as a first-order relaxation of
/// each cable's rest length `δ`:
///
/// ```text
/// tau δ' = ratio (F - F_ref) / K - δ,    F = K (stretch - δ) + F_0
/// ```
///
/// so a cable held at constant length loses tension (the preload relaxes),
/// and one held at constant tension keeps lengthening towards `ratio` times its
/// elastic stretch. `δ = 0` at the start (tension `F_0` at rest). `F_ref` is
/// the preload for cables that have settled under it ([`Creep::fresh`]
/// false: creep follows the load history from rest, nothing moves at rest)
/// and 0 for freshly tensioned cables (the preload itself relaxes).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Creep {
    /// Final creep as a fraction of the elastic stretch under the same load.
    pub ratio: f64,
    /// Time constant, s.
    pub tau_s: f64,
    /// Cables freshly tensioned at the start (the preload relaxes at rest).
    pub fresh: bool,
}

impl Default for Creep {
    fn default() -> Self {
        Self {
            ratio: 0.1,
            tau_s: 30.0,
            fresh: false,
        }
    }
}

/// Winding temperature: a two-node thermal model of the motor (winding and
/// housing, as the maxon datasheets give it) heated by the copper loss
/// `i² R(T)`:
///
/// ```text
/// C_w T_w' = i² R (1 + a_R (T_w - T_a)) - (T_w - T_h) / R_wh
/// C_h T_h' = (T_w - T_h) / R_wh - (T_h - T_a) / R_ha
/// K_m(T_w) = K_m0 (1 - a_K (T_w - T_a))
/// ```
///
/// with `C_w = tau_w / R_wh`, `C_h = tau_h / R_ha`. The controller and the
/// DOB keep the nominal `K_m`, so the force estimate drifts as the motor warms.
/// Defaults: RE25 20 W order of magnitude (R ≈ 2.3 Ω, 3.1 K/W and 14 K/W,
/// 12.5 s and 600 s); `a_K` = 0.4 %/K as the project's issue specifies (NdFeB
/// remanence alone gives about 0.12 %/K, so this is a pessimistic value).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Thermal {
    /// Terminal resistance at ambient, Ω.
    pub resistance_ohm: f64,
    /// Temperature coefficient of the copper resistance, 1/K.
    pub resistance_tc_1_k: f64,
    /// Thermal resistance winding to housing, K/W.
    pub winding_housing_k_w: f64,
    /// Thermal resistance housing to ambient, K/W.
    pub housing_ambient_k_w: f64,
    /// Thermal time constant of the winding, s.
    pub tau_winding_s: f64,
    /// Thermal time constant of the housing, s.
    pub tau_housing_s: f64,
    /// Ambient (and initial) temperature, °C.
    pub ambient_c: f64,
    /// Relative drop of `K_m` per kelvin of winding temperature rise, 1/K.
    pub km_tc_1_k: f64,
}

impl Default for Thermal {
    fn default() -> Self {
        Self {
            resistance_ohm: 2.32,
            resistance_tc_1_k: 0.0039,
            winding_housing_k_w: 3.1,
            housing_ambient_k_w: 14.0,
            tau_winding_s: 12.5,
            tau_housing_s: 600.0,
            ambient_c: 25.0,
            km_tc_1_k: 0.004,
        }
    }
}

/// Cubic hardening of the return spring: `F_s = F_0 + K_s x2 + k3 x2³`.
/// Coil springs stiffen as coils approach contact or the hooks straighten;
/// the JAE's `c4` and model C's `K_s` are linear and absorb only an average.
/// Default `k3 = 3.6e6 N/m³`: 5 % extra force at `x2 = 3 mm` (≈ 45° of joint).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SpringHardening {
    /// Cubic coefficient `k3`, N/m³.
    pub cubic_n_m3: f64,
}

impl Default for SpringHardening {
    fn default() -> Self {
        Self { cubic_n_m3: 3.6e6 }
    }
}

/// Where the drifting current-sensor offset sits.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DriftLocation {
    /// In the drive's own current sensor: the drive regulates the sensed
    /// current, so the winding current is `i_ref - offset` while the monitor
    /// (which reports the sensed current) still reads `i_ref`. The torque is
    /// wrong and nothing measured shows it: the DOB sees it as a load.
    #[default]
    DriveSensor,
    /// In the monitor path (the board's ADC buffer): only the measured
    /// current is wrong.
    Monitor,
}

/// Slow drift of a current-sensor offset: a ramp plus a random walk (Hall or
/// shunt-amplifier offset with temperature and time, seed 001's "zero drift"):
///
/// ```text
/// offset(t) = rate t + sigma W(t)
/// ```
///
/// `W` a standard Wiener process (random-walk steps drawn from the plant's
/// seeded generator).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OffsetDrift {
    /// Ramp, A/s (default 0.1 mA/s: 6 mA, about 5 codes, per minute).
    pub rate_a_s: f64,
    /// Random-walk intensity, A/√s.
    pub random_walk_a_sqrt_s: f64,
    /// Where the offset acts.
    pub location: DriftLocation,
}

impl Default for OffsetDrift {
    fn default() -> Self {
        Self {
            rate_a_s: 1e-4,
            random_walk_a_sqrt_s: 2e-4,
            location: DriftLocation::DriveSensor,
        }
    }
}

impl Effects {
    /// Names accepted by [`Effects::enable`].
    pub const NAMES: [&'static str; 5] = ["presliding", "creep", "thermal", "spring", "drift"];

    /// Switch one effect on with its default parameters. Accepts the names
    /// of [`Effects::NAMES`] and the aliases `lugre`, `hysteresis`,
    /// `hardening`, `offset-drift`.
    pub fn enable(&mut self, name: &str) -> anyhow::Result<()> {
        match name.trim() {
            "presliding" | "lugre" | "hysteresis" => {
                self.presliding.get_or_insert_with(Presliding::default);
            }
            "creep" => {
                self.creep.get_or_insert_with(Creep::default);
            }
            "thermal" => {
                self.thermal.get_or_insert_with(Thermal::default);
            }
            "spring" | "hardening" => {
                self.spring_hardening
                    .get_or_insert_with(SpringHardening::default);
            }
            "drift" | "offset-drift" => {
                self.offset_drift.get_or_insert_with(OffsetDrift::default);
            }
            other => anyhow::bail!(
                "unknown effect `{other}` (known: {})",
                Self::NAMES.join(", ")
            ),
        }
        Ok(())
    }

    /// Names of the effects that are on.
    pub fn enabled(&self) -> Vec<&'static str> {
        let mut v = Vec::new();
        if self.presliding.is_some() {
            v.push("presliding");
        }
        if self.creep.is_some() {
            v.push("creep");
        }
        if self.thermal.is_some() {
            v.push("thermal");
        }
        if self.spring_hardening.is_some() {
            v.push("spring");
        }
        if self.offset_drift.is_some() {
            v.push("drift");
        }
        v
    }

    /// Check the parameters of the effects that are on.
    pub fn validate(&self) -> anyhow::Result<()> {
        fn pos(name: &str, v: f64) -> anyhow::Result<()> {
            anyhow::ensure!(
                v.is_finite() && v > 0.0,
                "plant.effects.{name} must be finite and > 0, got {v}"
            );
            Ok(())
        }
        fn nonneg(name: &str, v: f64) -> anyhow::Result<()> {
            anyhow::ensure!(
                v.is_finite() && v >= 0.0,
                "plant.effects.{name} must be finite and >= 0, got {v}"
            );
            Ok(())
        }
        if let Some(p) = &self.presliding {
            pos("presliding.slider_presliding_m", p.slider_presliding_m)?;
            pos("presliding.joint_presliding_rad", p.joint_presliding_rad)?;
            pos("presliding.slider_stribeck_m_s", p.slider_stribeck_m_s)?;
            pos("presliding.joint_stribeck_rad_s", p.joint_stribeck_rad_s)?;
            nonneg("presliding.damping_ratio", p.damping_ratio)?;
        }
        if let Some(c) = &self.creep {
            nonneg("creep.ratio", c.ratio)?;
            pos("creep.tau_s", c.tau_s)?;
        }
        if let Some(t) = &self.thermal {
            pos("thermal.resistance_ohm", t.resistance_ohm)?;
            nonneg("thermal.resistance_tc_1_k", t.resistance_tc_1_k)?;
            pos("thermal.winding_housing_k_w", t.winding_housing_k_w)?;
            pos("thermal.housing_ambient_k_w", t.housing_ambient_k_w)?;
            pos("thermal.tau_winding_s", t.tau_winding_s)?;
            pos("thermal.tau_housing_s", t.tau_housing_s)?;
            anyhow::ensure!(
                t.ambient_c.is_finite(),
                "plant.effects.thermal.ambient_c must be finite"
            );
            nonneg("thermal.km_tc_1_k", t.km_tc_1_k)?;
        }
        if let Some(s) = &self.spring_hardening {
            anyhow::ensure!(
                s.cubic_n_m3.is_finite(),
                "plant.effects.spring_hardening.cubic_n_m3 must be finite"
            );
        }
        if let Some(d) = &self.offset_drift {
            anyhow::ensure!(
                d.rate_a_s.is_finite(),
                "plant.effects.offset_drift.rate_a_s must be finite"
            );
            nonneg("offset_drift.random_walk_a_sqrt_s", d.random_walk_a_sqrt_s)?;
        }
        Ok(())
    }
}
