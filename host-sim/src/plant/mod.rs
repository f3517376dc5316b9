//! The simulated prototype: motor, cables, sliders, joint, spring, sensors.
//!
//! # Model (seed 000 Eq. 6-16, DESIGN.md §1)
//!
//! Four mechanical degrees of freedom and the drive current:
//!
//! ```text
//! motor     J_m phi''  = K_m i - B_m phi' - f_m sgn(phi') - (r_m / z_i) F_1
//! slider 1  m_0 x1''   = F_1 - F_w1 - f_sv1 x1' - f_sc1 sgn(x1')
//! joint     J_e theta''= (F_w1 - F_w2) r - f_efv theta' - f_efc sgn(theta') - F_ext l_e
//! slider 2  m_1 x2''   = F_w2 - F_s - f_sv2 x2' - f_sc2 sgn(x2')
//! drive     i'         = 2π f_bw (clamp(i_ref, ±i_max) - i)
//!
//! cable 0   F_1  = max(0, K_w0 (r_m phi / z_i - x1) + c_w0 (...)' + F_0)
//! cable 1   F_w1 = max(0, K_w1 (x1 - r theta)     + c_w1 (...)' + F_0)
//! cable 2   F_w2 = max(0, K_w2 (r theta - x2)     + c_w2 (...)' + F_0)
//! spring    F_s  = max(0, F_0 + K_s x2)
//! ```
//!
//! Every cable carries the preload `F_0` at rest (Eq. 6) and can only pull
//! (a slack cable has no tension). `F_ext > 0` opposes positive rotation
//! (DESIGN.md), so it raises cable 1's tension. At rest the motor must hold
//! `F_0 r_m / z_i` ([`Plant::holding_current_a`]): with the drive off, the
//! preload back-drives the gearhead.
//!
//! The sliders and the joint have end stops (inelastic: the motion into the
//! stop is removed), so an unpowered loop that the preload collapses comes
//! to rest on them.
//!
//! # Integration
//!
//! Fixed-step semi-implicit (symplectic) Euler: forces from the positions
//! (and, for the cable dampers, the velocities) at the start of the step, new
//! velocities, then new positions from the new velocities. Viscous friction
//! is implicit. Each Coulomb element is updated implicitly, which gives true
//! stick-slip without sign chatter: with `p = m v + dt F_other` the momentum
//! the element would have without Coulomb friction, the friction impulse can
//! be anything up to `F_lim dt`, so
//!
//! * `|p| <= F_lim dt`: the element stops (or stays stuck), `v = 0` exactly;
//! * otherwise `v = (p - sgn(p) F_c dt) / (m + b dt)`,
//!
//! with `F_lim` the static friction if the element is stuck (`v == 0`) and the
//! Coulomb level if it is moving. Stiction therefore holds any load below
//! breakaway with zero drift, and a reversal passes through an exact stop.
//!
//! The step must resolve the stiffest mode: [`Plant::new`] bounds the highest
//! natural frequency `w_max` (Gershgorin on the mass-normalised stiffness
//! matrix, LuGre bristles included) and refuses `w_max dt` above
//! `integration.max_omega_dt`.
//!
//! # Sensors
//!
//! [`Plant::sample`] returns what the board reads: gratings rounded to the
//! count on 32-bit timers, the motor encoder (4000 counts/rev) and the
//! magnetic joint encoder (4096 counts/rev) on wrapping 16-bit timers, the
//! current monitor with noise and offset through the 12-bit ADC. Noise comes
//! from a ChaCha generator seeded with the plant's `seed`.
//!
//! # Files
//!
//! Here: the state, [`Plant`] and its step. The parameters are in
//! `params.rs`, the unmodelled effects in `effects.rs`, the friction elements
//! and end stops in `friction.rs`, the constants derived from the parameters
//! (and the step's bound) in `derived.rs`, the sensors ([`Plant::sample`]) in
//! `sensors.rs`.

mod derived;
mod effects;
mod friction;
mod params;
mod sensors;

use derived::Derived;
use friction::{coulomb_step, end_stop, lugre_step};

pub use effects::{
    Creep, DriftLocation, Effects, OffsetDrift, Presliding, SpringHardening, Thermal,
};
pub use params::{
    CableParams, DriveParams, IntegrationParams, JointParams, MotorParams, PlantParams,
    SensorParams, SliderParams, SpringParams, CABLE_DAMPING_RATIO, K_W0_N_M, K_W1_N_M, K_W2_N_M,
    STATIC_OVER_KINETIC,
};

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// The plant's state, SI units. Positions are zero at the homed rest
/// position, where every cable carries `F_0`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PlantState {
    /// Plant time, s.
    pub t_s: f64,
    /// Motor-shaft angle, rad.
    pub phi_rad: f64,
    /// Motor speed, rad/s.
    pub phi_vel_rad_s: f64,
    /// Slider 1 position, m.
    pub x1_m: f64,
    /// Slider 1 speed, m/s.
    pub x1_vel_m_s: f64,
    /// Joint angle, rad.
    pub theta_rad: f64,
    /// Joint speed, rad/s.
    pub theta_vel_rad_s: f64,
    /// Slider 2 position, m.
    pub x2_m: f64,
    /// Slider 2 speed, m/s.
    pub x2_vel_m_s: f64,
    /// Winding current, A.
    pub current_a: f64,
    /// Creep lengthening of cables 0, 1, 2 since the start, m ([`Creep`]).
    pub creep_m: [f64; 3],
    /// LuGre bristle deflections: slider 1 (m), joint (rad), slider 2 (m)
    /// ([`Presliding`]).
    pub bristle: [f64; 3],
    /// Winding temperature, °C ([`Thermal`]).
    pub winding_c: f64,
    /// Housing temperature, °C ([`Thermal`]).
    pub housing_c: f64,
    /// Current-sensor offset drift, A ([`OffsetDrift`]).
    pub drift_a: f64,
}

/// Tensions in the loop, N.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Tensions {
    /// Cable 0 at the rope wheel: the motor's load `F_1` (what the DOB's
    /// `tension1` estimates).
    pub rope_n: f64,
    /// Cable 1 (`F_w1`).
    pub cable1_n: f64,
    /// Cable 2 (`F_w2`).
    pub cable2_n: f64,
    /// Return spring (`F_s`).
    pub spring_n: f64,
    /// Rope hanging loose in the transmission, m: the longer of cable 0's
    /// and cable 1's slack (how far each is shorter than its zero-tension
    /// length by its stiffness term; 0 while both are taut). A rope at
    /// zero tension with a few micrometres to spare is another thing than
    /// one that has paid out millimetres.
    pub slack_m: f64,
}

impl Tensions {
    /// The lesser of cable 0 and cable 1, N: the transmission between the
    /// motor and the joint is slack when this is (the slack checks' truth).
    pub fn transmission_n(&self) -> f64 {
        self.rope_n.min(self.cable1_n)
    }
}

/// The force of a spring–damper contact that can only push: stiffness
/// times penetration plus damping times its rate, never below zero, and zero
/// without contact, N. One law for every object the simulator grips (the
/// single joint's [`TipObject`], the wrist's object between the jaws).
pub fn contact_push_n(
    stiffness_n_m: f64,
    damping_n_s_m: f64,
    penetration_m: f64,
    penetration_rate_m_s: f64,
) -> f64 {
    if penetration_m <= 0.0 {
        return 0.0;
    }
    (stiffness_n_m * penetration_m + damping_n_s_m * penetration_rate_m_s).max(0.0)
}

/// Damping of the simulator's soft objects, N·s/m: against 1000 N/m a time
/// constant of 0.5 ms, against 10 000 N/m 0.05 ms. Tissue's own loss is not
/// known here, so the contact is lightly damped.
pub const OBJECT_DAMPING_N_S_M: f64 = 0.5;

/// A soft object at the tip of the single joint, for grips: its surface
/// sits at `surface_rad` and the object fills the side away from zero
/// (`theta > surface_rad` for a positive surface, `theta < surface_rad` for
/// a negative one). Its push opposes the motion into it, so it adds to the
/// external force with the surface's sign (> 0 opposes positive rotation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TipObject {
    /// Joint angle at which the tip touches the object, rad (not zero).
    pub surface_rad: f64,
    /// Stiffness at the tip, N/m.
    pub stiffness_n_m: f64,
    /// Damping at the tip, N·s/m.
    pub damping_n_s_m: f64,
}

impl TipObject {
    /// An object whose surface is at `surface_deg`, `stiffness_n_m` at the
    /// tip and [`OBJECT_DAMPING_N_S_M`]. Refuses a surface at zero or
    /// beyond ±90°, and a stiffness that is not positive.
    pub fn new(surface_deg: f64, stiffness_n_m: f64) -> anyhow::Result<Self> {
        anyhow::ensure!(
            surface_deg.is_finite() && surface_deg != 0.0 && surface_deg.abs() < 90.0,
            "the object's surface must be at a joint angle other than 0 and within ±90°, got {surface_deg}°"
        );
        anyhow::ensure!(
            stiffness_n_m.is_finite() && stiffness_n_m > 0.0,
            "the object's stiffness must be > 0 N/m, got {stiffness_n_m}"
        );
        Ok(Self {
            surface_rad: surface_deg.to_radians(),
            stiffness_n_m,
            damping_n_s_m: OBJECT_DAMPING_N_S_M,
        })
    }

    /// The object's push at joint angle `theta_rad` moving at
    /// `theta_vel_rad_s`, as an external tip force (sign convention of
    /// [`Plant::set_external_force`]), for a tip `gripper_length_m` long.
    pub fn force_n(&self, gripper_length_m: f64, theta_rad: f64, theta_vel_rad_s: f64) -> f64 {
        let side = self.surface_rad.signum();
        let push = contact_push_n(
            self.stiffness_n_m,
            self.damping_n_s_m,
            side * gripper_length_m * (theta_rad - self.surface_rad),
            side * gripper_length_m * theta_vel_rad_s,
        );
        side * push
    }
}

/// The simulated prototype (configuration, derived constants, state, noise).
#[derive(Clone, Debug)]
pub struct Plant {
    p: PlantParams,
    d: Derived,
    s: PlantState,
    rng: ChaCha8Rng,
    current_cmd_a: f64,
    f_ext_n: f64,
    tip_mass_kg: f64,
    object: Option<TipObject>,
}

impl Plant {
    /// Build a plant at rest at the origin, holding the preload (drive
    /// current at [`Plant::holding_current_a`]). Fails on an impossible
    /// parameter or a step too coarse for the stiffest mode.
    pub fn new(params: PlantParams, seed: u64) -> anyhow::Result<Self> {
        params.validate()?;
        let d = Derived::new(&params)?;
        let mut plant = Self {
            p: params,
            d,
            s: PlantState::default(),
            rng: ChaCha8Rng::seed_from_u64(seed),
            current_cmd_a: 0.0,
            f_ext_n: 0.0,
            tip_mass_kg: 0.0,
            object: None,
        };
        let ambient = params.effects.thermal.map_or(25.0, |t| t.ambient_c);
        plant.s.winding_c = ambient;
        plant.s.housing_c = ambient;
        let hold = if params.motor_decoupled {
            0.0
        } else {
            plant.holding_current_a()
        };
        plant.s.current_a = hold;
        plant.current_cmd_a = hold;
        Ok(plant)
    }

    /// The parameters.
    pub fn params(&self) -> &PlantParams {
        &self.p
    }

    /// The state.
    pub fn state(&self) -> &PlantState {
        &self.s
    }

    /// The state, to set up a test or a scenario (positions, velocities, ...).
    pub fn state_mut(&mut self) -> &mut PlantState {
        &mut self.s
    }

    /// Integration step, s.
    pub fn dt_s(&self) -> f64 {
        self.d.dt
    }

    /// Gershgorin bound on the highest natural frequency, rad/s.
    pub fn omega_max_rad_s(&self) -> f64 {
        self.d.omega_max
    }

    /// Bound on the fastest explicit damping rate, 1/s.
    pub fn damping_rate_max_1_s(&self) -> f64 {
        self.d.damping_max
    }

    /// Current that holds the preload at rest: `F_0 r_m / (z_i K_m)`, A.
    pub fn holding_current_a(&self) -> f64 {
        self.p.spring.preload_n * self.d.rw / self.p.motor.torque_constant_nm_a
    }

    /// Current reference the drive regulates to (clamped to its limit), A.
    pub fn set_current_command(&mut self, current_a: f64) {
        let lim = self.p.drive.current_limit_a;
        self.current_cmd_a = if current_a.is_finite() {
            current_a.clamp(-lim, lim)
        } else {
            0.0
        };
    }

    /// The drive's current reference in force, A.
    pub fn current_command_a(&self) -> f64 {
        self.current_cmd_a
    }

    /// External tip force, N (> 0 opposes positive rotation).
    pub fn set_external_force(&mut self, f_ext_n: f64) {
        self.f_ext_n = f_ext_n;
    }

    /// The applied external tip force in force, N (without an object's
    /// push: [`Plant::contact_force_n`]).
    pub fn external_force_n(&self) -> f64 {
        self.f_ext_n
    }

    /// Put an object at the tip (or take it away): from now on its push
    /// adds to the applied external force at every step.
    pub fn set_object(&mut self, object: Option<TipObject>) {
        self.object = object;
    }

    /// The object's push on the tip in this state, N (0 without an object
    /// or contact; sign convention of [`Plant::set_external_force`]).
    pub fn contact_force_n(&self) -> f64 {
        self.object.map_or(0.0, |o| {
            o.force_n(
                self.p.joint.gripper_length_m,
                self.s.theta_rad,
                self.s.theta_vel_rad_s,
            )
        })
    }

    /// Mass hanging from the tip, kg: adds `m l_e²` to the joint inertia (a
    /// weight on a thread moves with the tip).
    pub fn set_tip_mass(&mut self, mass_kg: f64) {
        self.tip_mass_kg = mass_kg.max(0.0);
    }

    /// Torque constant now (lower when the winding is hot), N·m/A.
    pub fn torque_constant_nm_a(&self) -> f64 {
        let k = self.p.motor.torque_constant_nm_a;
        match &self.p.effects.thermal {
            Some(t) => k * (1.0 - t.km_tc_1_k * (self.s.winding_c - t.ambient_c)),
            None => k,
        }
    }

    /// Tensions from the state, N.
    pub fn tensions(&self) -> Tensions {
        let p = &self.p;
        let s = &self.s;
        let r = p.joint.pulley_radius_m;
        let f0 = p.spring.preload_n;
        // Cables 0 and 1 stretched from their preloaded rest lengths, m
        // (their tensions' stiffness terms, and their slack).
        let e0_m = self.d.rw * s.phi_rad - s.x1_m - s.creep_m[0];
        let e1_m = s.x1_m - r * s.theta_rad - s.creep_m[1];
        // How far each is shorter than its zero-tension length, m.
        let short0_m = -(e0_m + f0 / p.cable0.stiffness_n_m);
        let short1_m = -(e1_m + f0 / p.cable1.stiffness_n_m);
        let slack_m = if p.motor_decoupled {
            short1_m.max(0.0)
        } else {
            short0_m.max(short1_m).max(0.0)
        };
        let rope_n = if p.motor_decoupled {
            0.0
        } else {
            (p.cable0.stiffness_n_m * e0_m
                + p.cable0.damping_n_s_m * (self.d.rw * s.phi_vel_rad_s - s.x1_vel_m_s)
                + f0)
                .max(0.0)
        };
        let cable1_n = (p.cable1.stiffness_n_m * e1_m
            + p.cable1.damping_n_s_m * (s.x1_vel_m_s - r * s.theta_vel_rad_s)
            + f0)
            .max(0.0);
        let cable2_n = (p.cable2.stiffness_n_m * (r * s.theta_rad - s.x2_m - s.creep_m[2])
            + p.cable2.damping_n_s_m * (r * s.theta_vel_rad_s - s.x2_vel_m_s)
            + f0)
            .max(0.0);
        let spring_n =
            (f0 + p.spring.stiffness_n_m * s.x2_m + self.d.cubic * s.x2_m * s.x2_m * s.x2_m)
                .max(0.0);
        Tensions {
            rope_n,
            cable1_n,
            cable2_n,
            spring_n,
            slack_m,
        }
    }

    /// Advance by one integration step.
    pub fn step(&mut self) {
        let dt = self.d.dt;
        let p = &self.p;
        let d = &self.d;

        // Offset drift (ramp + random walk).
        if let Some(od) = &p.effects.offset_drift {
            let n: f64 = StandardNormal.sample(&mut self.rng);
            self.s.drift_a += od.rate_a_s * dt + od.random_walk_a_sqrt_s * dt.sqrt() * n;
        }
        let drive_offset = match p.effects.offset_drift {
            Some(OffsetDrift {
                location: DriftLocation::DriveSensor,
                ..
            }) => self.s.drift_a,
            _ => 0.0,
        };

        // Drive: first-order current loop, exact for a constant reference.
        let target = self.current_cmd_a - drive_offset;
        self.s.current_a += (target - self.s.current_a) * d.drive_alpha;
        let i = self.s.current_a;

        // Winding temperature.
        if let Some(th) = &p.effects.thermal {
            let c_w = th.tau_winding_s / th.winding_housing_k_w;
            let c_h = th.tau_housing_s / th.housing_ambient_k_w;
            let r_ohm = th.resistance_ohm
                * (1.0 + th.resistance_tc_1_k * (self.s.winding_c - th.ambient_c));
            let q_wh = (self.s.winding_c - self.s.housing_c) / th.winding_housing_k_w;
            let q_ha = (self.s.housing_c - th.ambient_c) / th.housing_ambient_k_w;
            self.s.winding_c += dt * (i * i * r_ohm - q_wh) / c_w;
            self.s.housing_c += dt * (q_wh - q_ha) / c_h;
        }
        let k_m = self.torque_constant_nm_a();
        let f_tip_n = self.f_ext_n + self.contact_force_n();

        let t = self.tensions();
        let s = &mut self.s;

        // Motor.
        let j_m = p.motor.rotor_inertia_kg_m2;
        let tau = k_m * i - d.rw * t.rope_n;
        s.phi_vel_rad_s = coulomb_step(s.phi_vel_rad_s, j_m, tau, &d.motor, dt);
        s.phi_rad += dt * s.phi_vel_rad_s;

        if !p.motor_decoupled {
            let r = p.joint.pulley_radius_m;
            let le = p.joint.gripper_length_m;
            let j_e = p.joint.inertia_kg_m2 + self.tip_mass_kg * le * le;
            let f1 = t.rope_n - t.cable1_n;
            let tj = (t.cable1_n - t.cable2_n) * r - f_tip_n * le;
            let f2 = t.cable2_n - t.spring_n;
            match &d.bristles {
                None => {
                    s.x1_vel_m_s =
                        coulomb_step(s.x1_vel_m_s, p.slider1.mass_kg, f1, &d.slider1, dt);
                    s.theta_vel_rad_s = coulomb_step(s.theta_vel_rad_s, j_e, tj, &d.joint, dt);
                    s.x2_vel_m_s =
                        coulomb_step(s.x2_vel_m_s, p.slider2.mass_kg, f2, &d.slider2, dt);
                }
                Some(b) => {
                    let [z1, zj, z2] = &mut s.bristle;
                    s.x1_vel_m_s = lugre_step(
                        s.x1_vel_m_s,
                        p.slider1.mass_kg,
                        f1,
                        &d.slider1,
                        &b[0],
                        z1,
                        dt,
                    );
                    s.theta_vel_rad_s =
                        lugre_step(s.theta_vel_rad_s, j_e, tj, &d.joint, &b[1], zj, dt);
                    s.x2_vel_m_s = lugre_step(
                        s.x2_vel_m_s,
                        p.slider2.mass_kg,
                        f2,
                        &d.slider2,
                        &b[2],
                        z2,
                        dt,
                    );
                }
            }
            s.x1_m += dt * s.x1_vel_m_s;
            s.theta_rad += dt * s.theta_vel_rad_s;
            s.x2_m += dt * s.x2_vel_m_s;
            end_stop(&mut s.x1_m, &mut s.x1_vel_m_s, p.slider1.travel_m);
            end_stop(&mut s.theta_rad, &mut s.theta_vel_rad_s, p.joint.range_rad);
            end_stop(&mut s.x2_m, &mut s.x2_vel_m_s, p.slider2.travel_m);

            if let Some(c) = &p.effects.creep {
                let f0 = p.spring.preload_n;
                let forces = [t.rope_n, t.cable1_n, t.cable2_n];
                let ks = [
                    p.cable0.stiffness_n_m,
                    p.cable1.stiffness_n_m,
                    p.cable2.stiffness_n_m,
                ];
                // Settled cables creep with the load above the preload they
                // have settled under; fresh ones with their whole tension.
                let f_ref = if c.fresh { 0.0 } else { f0 };
                for k in 0..3 {
                    let target = c.ratio * (forces[k] - f_ref) / ks[k];
                    s.creep_m[k] += (target - s.creep_m[k]) * d.creep_alpha;
                }
            }
        }
        s.t_s += dt;
    }

    /// Advance by `n` integration steps.
    pub fn advance_steps(&mut self, n: usize) {
        for _ in 0..n {
            self.step();
        }
    }

    /// Advance by (the nearest whole number of steps to) `duration_s`.
    pub fn advance(&mut self, duration_s: f64) {
        let n = (duration_s / self.d.dt).round().max(0.0) as usize;
        self.advance_steps(n);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_stable_at_40khz() {
        let p = PlantParams::default();
        let mut plant = Plant::new(p, 1).unwrap();
        assert!(
            (plant.dt_s() - 1.0 / 40_000.0).abs() < 1e-12,
            "{}",
            plant.dt_s()
        );
        assert!(
            plant.omega_max_rad_s() * plant.dt_s() < 0.2,
            "w_max dt = {}",
            plant.omega_max_rad_s() * plant.dt_s()
        );
        // Stepped: released 0.2 rad from rest with no current, the joint
        // swings back under the spring and friction and the integration
        // stays bounded (an unstable step grows without end within a
        // second at 40 000 steps).
        plant.state_mut().theta_rad = 0.2;
        let mut largest = 0.0f64;
        for _ in 0..40_000 {
            plant.step();
            let s = plant.state();
            assert!(s.theta_rad.is_finite() && s.x1_m.is_finite() && s.phi_rad.is_finite());
            largest = largest.max(s.theta_rad.abs());
        }
        assert!(largest <= 0.2 + 1e-3, "the swing grew to {largest} rad");
        assert!(
            plant.state().theta_vel_rad_s.abs() < 1.0,
            "{:?}",
            plant.state()
        );
        assert!(plant.state().theta_rad.abs() < 0.05, "{:?}", plant.state());
    }

    #[test]
    fn too_coarse_step_is_refused() {
        let mut p = PlantParams::default();
        p.joint.inertia_kg_m2 = 1e-11;
        let err = Plant::new(p, 1).unwrap_err().to_string();
        assert!(err.contains("too coarse"), "{err}");
    }

    #[test]
    fn toml_round_trip_and_partial_table_keeps_role_defaults() {
        let p = PlantParams::default();
        let text = p.to_toml_string().unwrap();
        assert_eq!(PlantParams::from_toml_str(&text).unwrap(), p);
        let q =
            PlantParams::from_toml_str("[slider1]\nmass_kg = 0.05\n[effects.creep]\ntau_s = 5.0\n")
                .unwrap();
        assert_eq!(q.slider1.mass_kg, 0.05);
        assert_eq!(
            q.slider1.coulomb_n, p.slider1.coulomb_n,
            "slider-1 default kept"
        );
        assert_eq!(q.effects.creep.unwrap().tau_s, 5.0);
        assert_eq!(q.effects.creep.unwrap().ratio, Creep::default().ratio);
        assert!(PlantParams::from_toml_str("[slider1]\nmass = 1.0\n").is_err());
    }
}
