//! The joint's torque balance: cable 1's stiffness and the pin's friction.

use cable_joint::lsq::{BatchLsq, LsqConfig};
use cable_joint::Config;
use serde::Serialize;

use super::Prepared;

/// The joint's torque balance (seed Eq. 9, 12, 13 with no load) on runs with
/// the magnetic encoder, while the joint slips:
/// `r K_w2 (r theta - x2) = K_w1 r (x1 - r theta) - f_efc sgn(theta') -
/// f_efv theta' - J_e theta'' - c`, with `K_w2` from the JAE's `c4` and the
/// datasheet spring and `K_w1`, the pin's friction, its viscous term, the
/// joint inertia and an offset fitted. The joint speed and acceleration are
/// zero-phase central differences of the magnetic encoder over
/// [`JOINT_DIFF_HALF_WINDOW_S`]: a causal observer lags the slip bursts of a
/// joint in stick-slip and gives the pin's friction to the viscous term.
/// Rows count once the joint has moved [`JOINT_MIN_TRAVEL_RAD`] since its
/// last reversal (past presliding).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct JointFit {
    /// Rows used (joint slipping, not faulted).
    pub rows: u64,
    /// Cable 2 stiffness from `c4` and the datasheet spring, N/m.
    pub k_w2_n_m: f64,
    /// Cable 1 stiffness, N/m, and its `%sigma`.
    pub k_w1_n_m: (f64, f64),
    /// Pin Coulomb friction, N·m, and its `%sigma`.
    pub pin_coulomb_nm: (f64, f64),
    /// Pin viscous friction, N·m·s/rad.
    pub pin_viscous_nm_s_rad: f64,
    /// RMS residual, N·m.
    pub residual_rms_nm: f64,
    /// What was written, or why not.
    pub note: String,
}

/// Largest `%sigma` at which a joint-fit parameter is written.
const JOINT_MAX_PCT_SIGMA: f64 = 30.0;

/// Fit [`JointFit`] on the prepared runs; `c4` is the identified JAE
/// position coefficient.
pub(super) fn identify_joint(preps: &[Prepared], config: &Config, c4_rad_m: f64) -> JointFit {
    let m = &config.machine;
    let r = f64::from(m.pulley_radius_m);
    let k_w2 = cable_joint::config::StretchConfig::from_jae(
        c4_rad_m as f32,
        m.spring_n_m,
        m.pulley_radius_m,
    )
    .map_or(f64::NAN, |s| f64::from(s.cable2_n_m));
    let empty = |note: String| JointFit {
        rows: 0,
        k_w2_n_m: k_w2,
        k_w1_n_m: (f64::NAN, f64::NAN),
        pin_coulomb_nm: (f64::NAN, f64::NAN),
        pin_viscous_nm_s_rad: f64::NAN,
        residual_rms_nm: f64::NAN,
        note,
    };
    if k_w2.is_nan() {
        return empty(format!(
            "not identified: c4 r = {} gives no cable stiffness",
            c4_rad_m * r
        ));
    }
    // The joint slips when theta' is above the JAE's switching speed seen
    // at the joint (c4 x2').
    let switch = f64::from(config.jae.sign_switch_m_s) * c4_rad_m;
    let mut ls = match BatchLsq::<5>::new(5, LsqConfig::default()) {
        Ok(l) => l,
        Err(e) => return empty(format!("not identified: {e:?}")),
    };
    let mut rows = Vec::new();
    for p in preps.iter().filter(|p| p.theta_source == "theta_rad") {
        let (Ok(theta), Ok(x1), Ok(x2)) = (p.theta(), p.col("x1_m"), p.col("x2_m")) else {
            continue;
        };
        let period_s = f64::from(p.config().period_s());
        let half = p.half_window(JOINT_DIFF_HALF_WINDOW_S);
        let (vel, acc) = central_kinematics(theta, half, period_s);
        // Travel since the last reversal: a pin in presliding (its friction
        // still building up after a reversal) is not at its kinetic level.
        let mut travel_rad = 0.0;
        for k in 0..p.len() {
            travel_rad = if k > 0 && vel[k].signum() == vel[k - 1].signum() {
                travel_rad + (theta[k] - theta[k - 1]).abs()
            } else {
                0.0
            };
            if !p.usable[k]
                || !p.measured(k)
                || !vel[k].is_finite()
                || !acc[k].is_finite()
                || vel[k].abs() <= switch
                || travel_rad < JOINT_MIN_TRAVEL_RAD
            {
                continue;
            }
            let y = r * k_w2 * (r * theta[k] - x2[k]);
            let phi = [
                r * (x1[k] - r * theta[k]),
                -vel[k].signum(),
                -vel[k],
                -acc[k],
                -1.0,
            ];
            if ls.push(&phi, y).is_ok() {
                rows.push((phi, y));
            }
        }
    }
    if rows.len() < 50 {
        return empty(format!(
            "not identified: {} rows with the magnetic encoder and the joint slipping (needs 50)",
            rows.len()
        ));
    }
    let fit = match ls.solve() {
        Ok(f) => f,
        Err(e) => return empty(format!("not identified: {e:?}")),
    };
    let sq: f64 = rows
        .iter()
        .map(|(phi, y)| (y - fit.predict(phi)).powi(2))
        .sum();
    JointFit {
        rows: rows.len() as u64,
        k_w2_n_m: k_w2,
        k_w1_n_m: (fit.params[0], fit.pct_sigma(0)),
        pin_coulomb_nm: (fit.params[1], fit.pct_sigma(1)),
        pin_viscous_nm_s_rad: fit.params[2],
        residual_rms_nm: (sq / rows.len() as f64).sqrt(),
        note: String::new(),
    }
}

/// Half-width of the central differences the joint fit takes of the
/// magnetic encoder, s: long enough that one encoder count over the window
/// is a small speed, short against a slip burst of a joint in stick-slip
/// (tens of milliseconds).
pub const JOINT_DIFF_HALF_WINDOW_S: f64 = 0.005;

/// Joint travel since the last reversal before a row enters the joint fit,
/// rad: three presliding distances of a worn pin (10 mrad, the upper end of
/// the plant's effects table; the datasheet's pin 3 mrad), after which a
/// bristle (LuGre) friction state has come within 5 % of its sliding
/// level, so the friction is at its kinetic level. At 5 mrad cable 1's
/// stiffness read 12 % to 26 % soft on drawn plants whose pins preslide
/// over 4 to 8.5 mrad (docs/force.md, "Presliding guides and the spring
/// fit").
pub const JOINT_MIN_TRAVEL_RAD: f64 = 30e-3;

/// Zero-phase speed and acceleration of `x` sampled every `period_s`: central
/// differences over `half` samples either side (NaN within `2 half` of
/// either end).
pub(super) fn central_kinematics(x: &[f64], half: usize, period_s: f64) -> (Vec<f64>, Vec<f64>) {
    let diff = |u: &[f64]| -> Vec<f64> {
        (0..u.len())
            .map(|k| {
                if k < half || k + half >= u.len() {
                    f64::NAN
                } else {
                    (u[k + half] - u[k - half]) / (2.0 * half as f64 * period_s)
                }
            })
            .collect()
    };
    let vel = diff(x);
    let acc = diff(&vel);
    (vel, acc)
}

impl JointFit {
    /// Write cable 1's stiffness and the pin friction the data identified;
    /// a pin friction the data could not identify becomes model C's upper
    /// bound, a cable 1 it could not identify stays equal to cable 2.
    /// Returns what was written.
    pub(super) fn apply(&self, config: &mut Config) -> String {
        let (k1, pk1) = self.k_w1_n_m;
        let stiffness = if k1.is_finite() && k1 > 0.0 && pk1 < JOINT_MAX_PCT_SIGMA {
            config.stretch.cable1_n_m = k1 as f32;
            format!("stretch.cable1_n_m = {k1:.0} (%sigma {pk1:.1})")
        } else {
            config.stretch.cable1_n_m = config.stretch.cable2_n_m;
            format!(
                "cable 1 stiffness not identifiable (K_w1 {k1:.0} N/m, %sigma {pk1:.1}): taken as cable 2's"
            )
        };
        let (f, pf) = self.pin_coulomb_nm;
        let pin = if f.is_finite() && pf < JOINT_MAX_PCT_SIGMA {
            config.fusion.pin_coulomb_nm = f.max(0.0) as f32;
            config.fusion.pin_identified = true;
            format!("fusion.pin_coulomb_nm = {:.5} (%sigma {pf:.1})", f.max(0.0))
        } else {
            config.fusion.pin_coulomb_nm =
                cable_joint::config::FusionConfig::pin_upper_bound_nm(config);
            config.fusion.pin_identified = false;
            "pin friction not identifiable from these runs: the force bound takes model C's upper bound"
                .into()
        };
        format!("{stiffness}; {pin}")
    }
}
