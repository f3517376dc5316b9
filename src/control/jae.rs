//! Joint-angle estimator (seed Eq. 16, 25-26):
//!
//! `theta_hat = c1 x2'' + c2 x2' + c3 sgn(x2') + c4 x2 + offset`
//!
//! from slider 2's position (grating 2) and its derivatives. The sign is a
//! [`SignMemory`]: it follows the velocity above a switching speed and holds
//! below it, so the `c3` term does not chatter at standstill.

use crate::config::JaeConfig;
use crate::filter::{HeldSign, Kinematics, SignMemory};

/// State of the estimator: the held friction sign.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct JaeState {
    /// Held sign of `x2'` (±1, or 0 before the first motion) and how far
    /// slider 2 has gone in its direction.
    pub sign: HeldSign,
}

/// Estimate the joint angle, rad, from slider 2's kinematics: `x2_m` is the
/// measured position, `k` the differentiator's output (velocity, acceleration).
#[inline]
pub fn estimate(cfg: &JaeConfig, state: &mut JaeState, x2_m: f32, k: &Kinematics) -> f32 {
    let sign = SignMemory {
        switch_speed: cfg.sign_switch_m_s,
    }
    .update_travelled(&mut state.sign, k.vel, x2_m, cfg.sign_travel_m);
    cfg.c_acc_rad_s2_m * k.acc
        + cfg.c_vel_rad_s_m * k.vel
        + cfg.c_sign_rad * sign
        + cfg.c_pos_rad_m * x2_m
        + cfg.offset_rad
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On exact data generated from the model itself the estimate is exact.
    #[test]
    fn exact_on_model_data() {
        let cfg = JaeConfig::default();
        let mut st = JaeState::default();
        for k in 0..200 {
            let t = k as f32 * 1e-3;
            let w = 2.0 * core::f32::consts::PI;
            let (x, v, a) = (
                2e-3 * libm::sinf(w * t),
                2e-3 * w * libm::cosf(w * t),
                -2e-3 * w * w * libm::sinf(w * t),
            );
            let kin = Kinematics {
                pos: x,
                vel: v,
                acc: a,
            };
            let got = estimate(&cfg, &mut st, x, &kin);
            let sign = if v > cfg.sign_switch_m_s {
                1.0
            } else if v < -cfg.sign_switch_m_s {
                -1.0
            } else {
                st.sign.sign
            };
            let want = cfg.c_acc_rad_s2_m * a
                + cfg.c_vel_rad_s_m * v
                + cfg.c_sign_rad * sign
                + cfg.c_pos_rad_m * x;
            assert!((got - want).abs() < 1e-6, "t={t}: {got} vs {want}");
        }
    }

    #[test]
    fn sign_term_does_not_chatter_at_standstill() {
        let cfg = JaeConfig::default();
        let mut st = JaeState::default();
        let moving = Kinematics {
            pos: 1e-3,
            vel: 1e-3,
            acc: 0.0,
        };
        let first = estimate(&cfg, &mut st, 1e-3, &moving);
        let mut prev = None;
        for k in 0..100 {
            // Quantization noise around zero speed.
            let v = if k % 2 == 0 { 3e-5 } else { -3e-5 };
            let th = estimate(
                &cfg,
                &mut st,
                1e-3,
                &Kinematics {
                    pos: 1e-3,
                    vel: v,
                    acc: 0.0,
                },
            );
            if let Some(p) = prev {
                let d: f32 = th - p;
                assert!(d.abs() < 2.0 * cfg.c_vel_rad_s_m * 3e-5 + 1e-7, "jump {d}");
            }
            prev = Some(th);
        }
        assert!(first > 0.0);
        assert_eq!(st.sign.sign, 1.0);
    }
}
