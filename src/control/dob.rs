//! Disturbance observer and external-force estimator (seed Eq. 17-21,
//! Fig. 5-6), and the no-load tension model (simplified model C, Eq. 28-29).
//!
//! Motor (Eq. 7/17): `J_m phi'' = K_m i - B_m phi' - (r_m / z_i) F_1`. The
//! observer low-passes the torque balance with `Q(s) = g/(s+g)`:
//!
//! `tau_hat = Q[K_m i - B_m phi'] - J_m g (phi' - Q[phi'])`
//!
//! where the second term is `Q[J_m phi'']` written with the pseudo-derivative
//! `s Q(s) = g (1 - Q(s))`, so no double differentiation is needed. In
//! discrete time, with the core's `Q` (pole `a = exp(-g T)`) and the motor's
//! acceleration over a tick its speed's backward difference `D phi'` (the
//! tick over which the current was applied), the same identity holds with
//! `g` replaced by `g_d = (1 - a) / (a T)`: `Q[D phi'] = g_d (phi' -
//! Q[phi'])`. `g` itself would take out the motor's inertial torque `g T /
//! 2` short (6.3 % at 500 Hz, 1.6 % at 2 kHz with `g` = 62.8 rad/s), and of
//! the motor's inertia reflected to the cable, about 37 kg, that is a spring
//! of `-g T / 2 x 37 kg x omega^2` on a sweep of `omega` (docs/force.md, "The
//! DOB's discrete inertial term (stop 78)"). Then
//!
//! * cable-1 tension seen by the motor: `F_1_hat = tau_hat z_i / r_m` (Eq. 21),
//! * modelled no-load tension through the same filter: `Q[F_1']`,
//! * external tip force (Eq. 19-20 with DESIGN.md's sign convention,
//!   `F_1 = F_1' + F_ext l_e / r`): `F_ext_hat = (F_1_hat - Q[F_1']) r / l_e`.

use crate::config::{DobConfig, Machine, TensionConfig};
use crate::filter::{LowPass1, SignMemory};

/// Precomputed constants of the observer (configuration).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dob {
    lp: LowPass1,
    /// `g_d = (1 - a) / (a T)`, rad/s: the pseudo-derivative's gain that
    /// makes `g_d (phi' - Q[phi'])` equal `Q` of the speed's backward
    /// difference (module docs).
    inertial_gain_rad_s: f32,
    k_m: f32,
    j_m: f32,
    b_m: f32,
    /// `z_i / r_m`: N of cable tension per N·m at the motor.
    tension_per_torque: f32,
    /// `r / l_e`: tip force per unit of cable-tension change.
    tip_per_tension: f32,
}

/// State of the observer.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DobState {
    /// `Q[K_m i - B_m phi']`, N·m.
    pub drive_nm: f32,
    /// `Q[phi']`, rad/s.
    pub vel_rad_s: f32,
    /// `Q[F_1']`, N.
    pub model_n: f32,
}

/// What the observer estimates in one tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DobOut {
    /// Low-passed load torque at the motor shaft (without `B_m phi'`), N·m.
    pub load_torque_nm: f32,
    /// Cable-1 tension seen by the motor, N.
    pub tension1_n: f32,
    /// Modelled no-load tension through the same filter, N.
    pub tension1_model_n: f32,
    /// External tip force, N (> 0 opposes positive rotation).
    pub f_ext_n: f32,
}

impl Dob {
    /// Build from the configuration and control period.
    pub fn new(cfg: &DobConfig, m: &Machine, period_s: f32) -> Self {
        let lp = LowPass1::new(cfg.cutoff_rad_s, period_s);
        let a = lp.pole();
        Self {
            lp,
            inertial_gain_rad_s: (1.0 - a) / (a * period_s),
            k_m: m.torque_constant_nm_a,
            j_m: m.rotor_inertia_kg_m2,
            b_m: cfg.viscous_nm_s_rad,
            tension_per_torque: m.gear_ratio / m.rope_wheel_radius_m,
            tip_per_tension: m.pulley_radius_m / m.gripper_length_m,
        }
    }

    /// Start at rest with the modelled tension `model_n` and the motor
    /// holding it (no transient on the first ticks).
    pub fn reset(&self, s: &mut DobState, model_n: f32) {
        *s = DobState {
            drive_nm: model_n / self.tension_per_torque,
            vel_rad_s: 0.0,
            model_n,
        };
    }

    /// One tick: `current_a` is the current applied over the last period,
    /// `motor_vel_rad_s` the motor speed, `model_n` the no-load tension model.
    #[inline]
    pub fn update(
        &self,
        s: &mut DobState,
        current_a: f32,
        motor_vel_rad_s: f32,
        model_n: f32,
    ) -> DobOut {
        let drive = self.lp.update(
            &mut s.drive_nm,
            self.k_m * current_a - self.b_m * motor_vel_rad_s,
        );
        let vel_lp = self.lp.update(&mut s.vel_rad_s, motor_vel_rad_s);
        let inertial = self.j_m * self.inertial_gain_rad_s * (motor_vel_rad_s - vel_lp);
        let load_torque_nm = drive - inertial;
        let tension1_n = load_torque_nm * self.tension_per_torque;
        let tension1_model_n = self.lp.update(&mut s.model_n, model_n);
        DobOut {
            load_torque_nm,
            tension1_n,
            tension1_model_n,
            f_ext_n: (tension1_n - tension1_model_n) * self.tip_per_tension,
        }
    }
}

/// State of the tension model: the held friction signs of both sliders.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TensionState {
    /// Held sign of `x1'`.
    pub sign_x1: f32,
    /// Held sign of `x2'`.
    pub sign_x2: f32,
}

/// No-load cable-1 tension `F_1'`, N (simplified model C, Eq. 28-29).
#[inline]
pub fn tension_model(
    cfg: &TensionConfig,
    s: &mut TensionState,
    x1_vel_m_s: f32,
    x2_m: f32,
    x2_vel_m_s: f32,
) -> f32 {
    let s1 = SignMemory {
        switch_speed: cfg.sign_switch_x1_m_s,
    }
    .update(&mut s.sign_x1, x1_vel_m_s);
    let s2 = SignMemory {
        switch_speed: cfg.sign_switch_x2_m_s,
    }
    .update(&mut s.sign_x2, x2_vel_m_s);
    cfg.f_sc1_n * s1 + cfg.f_cp2_n * s2 + cfg.k_s_n_m * x2_m + cfg.f_0_n
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The datasheet machine's observer at `rate_hz`, fresh state, and the
    /// motor's inertia, torque constant and damping `(J, K, B)` a test's
    /// motor-only plant steps with.
    fn motor_only(rate_hz: f32) -> (Machine, DobConfig, Dob, DobState, (f32, f32, f32)) {
        let m = Machine::default();
        let cfg = DobConfig::default();
        let dob = Dob::new(&cfg, &m, 1.0 / rate_hz);
        let jkb = (
            m.rotor_inertia_kg_m2,
            m.torque_constant_nm_a,
            cfg.viscous_nm_s_rad,
        );
        (m, cfg, dob, DobState::default(), jkb)
    }

    /// A motor-only plant `J w' = K i - B w - tau_load`: the observer recovers
    /// a step of load torque with the first-order response of `Q`.
    #[test]
    fn recovers_load_step_on_motor_only_plant() {
        let rate_hz = 2000.0;
        let (m, cfg, dob, mut s, (j, k, b)) = motor_only(rate_hz);
        let t = 1.0 / rate_hz;
        let mut w = 0.0f32;
        let load = 3e-3f32; // N·m, applied from t = 0.1 s
        let mut last = DobOut::default();
        for n in 0..2000 {
            let time = n as f32 * t;
            let i = 0.1 + 0.05 * crate::math::sin(2.0 * core::f32::consts::PI * 3.0 * time);
            let tl = if time >= 0.1 { load } else { 0.0 };
            for _ in 0..50 {
                w += (k * i - b * w - tl) / j * (t / 50.0);
            }
            last = dob.update(&mut s, i, w, 0.0);
            if (0.1 + 0.02..0.1 + 0.03).contains(&time) {
                // After 1.26 time constants the estimate has risen by 1 - e^-x.
                let x = cfg.cutoff_rad_s * (time - 0.1);
                let expect = load * (1.0 - crate::math::exp(-x));
                assert!(
                    (last.load_torque_nm - expect).abs() < 0.08 * load,
                    "t={time}: {} vs {expect}",
                    last.load_torque_nm
                );
            }
        }
        assert!(
            (last.load_torque_nm - load).abs() < 0.01 * load,
            "final {}",
            last.load_torque_nm
        );
        // Tension and tip force follow from the geometry.
        let f1 = load * m.gear_ratio / m.rope_wheel_radius_m;
        assert!((last.tension1_n - f1).abs() < 0.01 * f1);
        assert!((last.f_ext_n - f1 * m.pulley_radius_m / m.gripper_length_m).abs() < 0.01 * f1);
    }

    /// A motor-only plant stepped exactly as the observer sees it (the
    /// speed changes by `T (K i - B w - load) / J` over each tick of held
    /// current, `w` the tick's end speed), swept by a sine at 500 Hz: the observer's load torque
    /// stays on the plant's, whose zero it must read while the motor
    /// accelerates. With the continuous `g` in the inertial term it would
    /// read `g T / 2` of the inertial torque (6.3 % at 500 Hz).
    #[test]
    fn the_inertial_term_is_exact_for_the_discrete_motor_at_a_slow_rate() {
        let rate_hz = 500.0;
        let (_, _, dob, mut s, (j, k, b)) = motor_only(rate_hz);
        let t = 1.0 / rate_hz;
        let load = 1e-3f32;
        let mut w = 0.0f32;
        let mut worst_error = 0.0f32;
        let mut worst_inertial = 0.0f32;
        for n in 0..5000 {
            let time = n as f32 * t;
            // 0.5 A at 2 Hz: an inertial torque of the order of the load.
            let i = 0.5 * crate::math::sin(2.0 * core::f32::consts::PI * 2.0 * time);
            let w_before = w;
            // Viscous friction at the tick's end speed, as the observer
            // takes it.
            w = (w + t * (k * i - load) / j) / (1.0 + t * b / j);
            let out = dob.update(&mut s, i, w, 0.0);
            if time > 1.0 {
                worst_error = worst_error.max((out.load_torque_nm - load).abs());
                worst_inertial = worst_inertial.max((j * (w - w_before) / t).abs());
            }
        }
        assert!(
            worst_error < 0.01 * worst_inertial,
            "load torque off by up to {worst_error:e} N·m against an inertial torque of \
             {worst_inertial:e} N·m"
        );
    }

    #[test]
    fn tension_model_is_eq_29() {
        let cfg = TensionConfig::default();
        let mut s = TensionState::default();
        let f = tension_model(&cfg, &mut s, 1e-3, 2e-3, -1e-3);
        let want = cfg.f_sc1_n - cfg.f_cp2_n + cfg.k_s_n_m * 2e-3 + cfg.f_0_n;
        assert!((f - want).abs() < 1e-5);
    }
}
