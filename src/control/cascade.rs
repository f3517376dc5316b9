//! PD position loop → PI velocity loop → current reference (seed Fig. 11).
//!
//! * Position loop in joint space: `w_joint = ff * theta_ref' + kp e + kd e'`,
//!   `e = theta_ref - theta_fb`, where `theta_fb` is the estimated joint angle
//!   (Fig. 11) or the motor-implied angle (motor-encoder-only, Fig. 10).
//!   `e'` is the difference quotient of `e` over one tick, unless the caller
//!   gives the feedback's rate from the tracking observers
//!   ([`CascadeIn::vel_fb_rad_s`], `cascade.kd_on_observer_rate`); then it
//!   is `theta_ref' - theta_fb'`.
//! * The joint-rate reference becomes a motor-rate reference through the rigid
//!   transmission ratio `z_i r / r_m`, limited to `vel_limit_rad_s`.
//! * PI velocity loop on the motor speed; output current limited to
//!   `current_limit_a`. Anti-windup by conditional integration: the
//!   integrator does not move in the direction that deepens saturation, and is
//!   clamped so that it alone never exceeds the limit.
//! * While the reference is at rest, a small dead band on the position error
//!   stops the hold from hunting against stiction.
//! * Feed-forward current `i_ff` (the modelled tension's holding current) is
//!   added before the limit, so the integrator only trims.
//! * Optionally (`cascade.payout_stop`), the payout stop: the controller
//!   asks the cascade to hold the motor-velocity reference at or above
//!   zero while cable 0 is nearly slack ([`CascadeIn::no_payout`]).

use crate::config::CascadeConfig;
use crate::math::clamp;

/// State of the cascade.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CascadeState {
    /// Velocity-loop integrator, A.
    pub integral_a: f32,
    /// Last position error, rad (for the derivative).
    pub last_error_rad: f32,
    /// Has `last_error_rad` been set since the last reset?
    pub primed: bool,
}

/// What one cascade step produced (for telemetry and tests).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CascadeOut {
    /// Motor-velocity reference, rad/s.
    pub motor_vel_ref_rad_s: f32,
    /// Current reference after limiting, A.
    pub current_a: f32,
    /// Was the output limited?
    pub saturated: bool,
}

/// Inputs of one step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CascadeIn {
    /// Joint-angle reference, rad.
    pub angle_ref_rad: f32,
    /// Joint-rate reference, rad/s.
    pub vel_ref_rad_s: f32,
    /// Joint-angle feedback, rad.
    pub angle_fb_rad: f32,
    /// The feedback angle's rate from the tracking observers, rad/s, for
    /// the error's rate; `None` differences the error over one tick.
    pub vel_fb_rad_s: Option<f32>,
    /// Motor speed, rad/s.
    pub motor_vel_rad_s: f32,
    /// Feed-forward current, A.
    pub current_ff_a: f32,
    /// Motor rad per joint rad of the rigid transmission (`z_i r / r_m`).
    pub motor_per_joint: f32,
    /// The reference is at rest: apply the hold dead band.
    pub hold: bool,
    /// The payout stop: hold the motor-velocity reference at or above zero
    /// (a negative motor speed unwinds cable 0). The controller sets it
    /// while the motor's reading says cable 0 is nearly slack and the motor
    /// has kept unwinding (`cascade.payout_stop`, [`crate::controller`]).
    pub no_payout: bool,
}

/// One step of the cascade with period `period_s`.
#[inline]
pub fn step(
    cfg: &CascadeConfig,
    s: &mut CascadeState,
    inp: &CascadeIn,
    period_s: f32,
) -> CascadeOut {
    let mut e = inp.angle_ref_rad - inp.angle_fb_rad;
    let mut inside = false;
    if inp.hold {
        // Continuous dead band: zero inside, shifted linear outside.
        let within = clamp(e, -cfg.hold_deadband_rad, cfg.hold_deadband_rad);
        inside = within == e;
        e -= within;
    }
    let de = match inp.vel_fb_rad_s {
        // The dead-banded error does not move inside the band.
        Some(_) if inside => 0.0,
        Some(vel_fb) => inp.vel_ref_rad_s - vel_fb,
        None if s.primed => (e - s.last_error_rad) / period_s,
        None => 0.0,
    };
    s.last_error_rad = e;
    s.primed = true;
    let w_joint = cfg.vel_feedforward * inp.vel_ref_rad_s + cfg.kp_pos_1_s * e + cfg.kd_pos * de;
    let mut w_ref = clamp(
        w_joint * inp.motor_per_joint,
        -cfg.vel_limit_rad_s,
        cfg.vel_limit_rad_s,
    );
    if inp.no_payout {
        w_ref = w_ref.max(0.0);
    }
    let ev = w_ref - inp.motor_vel_rad_s;
    let lim = cfg.current_limit_a;
    let unsat = inp.current_ff_a + cfg.kp_vel_a_s_rad * ev + s.integral_a;
    let pushing_out = (unsat > lim && ev > 0.0) || (unsat < -lim && ev < 0.0);
    if !pushing_out {
        s.integral_a = clamp(s.integral_a + cfg.ki_vel_a_rad * ev * period_s, -lim, lim);
    }
    let raw = inp.current_ff_a + cfg.kp_vel_a_s_rad * ev + s.integral_a;
    let current_a = clamp(raw, -lim, lim);
    CascadeOut {
        motor_vel_ref_rad_s: w_ref,
        current_a,
        saturated: current_a != raw,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Closed loop around a pure inertia `J w' = K i`: the velocity loop's step
    /// response settles on the reference with no steady-state error, and the
    /// output respects the current limit throughout.
    #[test]
    fn velocity_step_on_inertia_settles_within_limits() {
        let cfg = CascadeConfig::default();
        let (j, k, t) = (1.08e-6f32, 23.4e-3f32, 1.0 / 2000.0);
        let mut s = CascadeState::default();
        let mut w = 0.0f32;
        let load = 2e-3; // N·m constant load: the integrator must cancel it
        for _ in 0..4000 {
            let out = step(
                &cfg,
                &mut s,
                &CascadeIn {
                    vel_ref_rad_s: 100.0 / 23.33,
                    motor_vel_rad_s: w,
                    motor_per_joint: 23.33,
                    ..Default::default()
                },
                t,
            );
            assert!(out.current_a.abs() <= cfg.current_limit_a);
            // 20 substeps of the plant per tick.
            for _ in 0..20 {
                w += (k * out.current_a - load) / j * (t / 20.0);
            }
        }
        assert!((w - 100.0).abs() < 0.5, "motor speed {w} rad/s");
    }

    /// Anti-windup: after a long saturation the integrator is bounded and the
    /// loop recovers quickly.
    #[test]
    fn integrator_does_not_wind_up() {
        let cfg = CascadeConfig::default();
        let mut s = CascadeState::default();
        let inp = CascadeIn {
            vel_ref_rad_s: 10.0,
            motor_per_joint: 23.33,
            ..Default::default()
        };
        for _ in 0..100_000 {
            let out = step(&cfg, &mut s, &inp, 5e-4);
            assert!(out.saturated);
        }
        assert!(s.integral_a.abs() <= cfg.current_limit_a);
        // Reference reverses: output leaves the positive rail within a few ticks.
        let back = CascadeIn {
            vel_ref_rad_s: -10.0,
            motor_vel_rad_s: 300.0,
            ..inp
        };
        let out = step(&cfg, &mut s, &back, 5e-4);
        assert!(
            out.current_a < cfg.current_limit_a,
            "still saturated: {}",
            out.current_a
        );
    }

    #[test]
    fn hold_dead_band_asks_for_no_motion_inside_and_is_continuous_outside() {
        let cfg = CascadeConfig {
            vel_feedforward: 0.0,
            kd_pos: 0.0,
            ..Default::default()
        };
        let db = cfg.hold_deadband_rad;
        let run = |e: f32, hold: bool| {
            let mut s = CascadeState::default();
            let inp = CascadeIn {
                angle_ref_rad: e,
                motor_per_joint: 23.33,
                hold,
                ..Default::default()
            };
            step(&cfg, &mut s, &inp, 5e-4).motor_vel_ref_rad_s
        };
        assert_eq!(run(0.9 * db, true), 0.0);
        assert!(run(0.9 * db, false) > 0.0, "no dead band while tracking");
        let just_out = run(1.01 * db, true);
        assert!(
            just_out > 0.0 && just_out < cfg.kp_pos_1_s * 0.02 * db * 23.33,
            "{just_out}"
        );
    }

    /// A joint angle creeping up one quantization step at a time: the
    /// difference quotient turns every step into a spike of the
    /// motor-velocity reference (`kd` times a count over one tick); with the
    /// observer's rate only the proportional term's step is left.
    #[test]
    fn the_observer_rate_keeps_quantization_steps_out_of_the_damping() {
        let cfg = CascadeConfig::default();
        let (t, count, per_joint) = (5e-4f32, 2.6e-4f32, 23.33f32);
        let vel = count / (10.0 * t); // one count every ten ticks
        let largest_jump = |observer: bool| {
            let mut s = CascadeState::default();
            let mut last: Option<f32> = None;
            let mut jump = 0.0f32;
            for k in 0..200 {
                let exact = vel * t * k as f32;
                let quantized = count * ((exact / count) as i32) as f32;
                let out = step(
                    &cfg,
                    &mut s,
                    &CascadeIn {
                        angle_ref_rad: exact,
                        vel_ref_rad_s: vel,
                        angle_fb_rad: quantized,
                        vel_fb_rad_s: observer.then_some(vel),
                        motor_per_joint: per_joint,
                        ..Default::default()
                    },
                    t,
                );
                if let Some(l) = last {
                    jump = jump.max(crate::math::abs(out.motor_vel_ref_rad_s - l));
                }
                last = Some(out.motor_vel_ref_rad_s);
            }
            jump
        };
        // A count's step through the proportional term, and through the
        // difference quotient as well.
        let proportional = cfg.kp_pos_1_s * count * per_joint;
        let spike = proportional + cfg.kd_pos * count / t * per_joint;
        assert!(spike > 4.0 * proportional);
        assert!(
            largest_jump(false) > 0.95 * spike,
            "{}",
            largest_jump(false)
        );
        assert!(
            largest_jump(true) < 1.01 * proportional,
            "{} against {proportional}",
            largest_jump(true)
        );
    }

    /// The payout stop: a position error that asks the motor to unwind
    /// gets a motor-velocity reference of zero, one that asks it to wind in
    /// is left as it is, and without the stop both pass.
    #[test]
    fn the_payout_stop_keeps_the_motor_from_unwinding_and_only_that() {
        let cfg = CascadeConfig::default();
        let run = |error_rad: f32, no_payout: bool| {
            let mut s = CascadeState::default();
            let inp = CascadeIn {
                angle_ref_rad: error_rad,
                motor_per_joint: 23.33,
                no_payout,
                ..Default::default()
            };
            step(&cfg, &mut s, &inp, 5e-4).motor_vel_ref_rad_s
        };
        assert!(run(-0.01, false) < 0.0);
        assert_eq!(run(-0.01, true), 0.0);
        assert!(run(0.01, true) > 0.0);
        assert_eq!(run(0.01, true), run(0.01, false));
    }

    #[test]
    fn position_error_drives_velocity_reference() {
        let cfg = CascadeConfig {
            vel_feedforward: 0.0,
            ..Default::default()
        };
        let mut s = CascadeState::default();
        let out = step(
            &cfg,
            &mut s,
            &CascadeIn {
                angle_ref_rad: 0.01,
                motor_per_joint: 23.33,
                ..Default::default()
            },
            5e-4,
        );
        let expected = clamp(
            cfg.kp_pos_1_s * 0.01 * 23.33,
            -cfg.vel_limit_rad_s,
            cfg.vel_limit_rad_s,
        );
        assert!((out.motor_vel_ref_rad_s - expected).abs() < 1e-3);
    }
}
