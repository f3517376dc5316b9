//! The joint's torque balance: cable 1's stiffness and the pin's friction.

use cable_joint::lsq::{BatchLsq, LsqConfig};
use cable_joint::Config;
use serde::Serialize;

use super::Prepared;
use crate::stats::correlation_time;

/// The joint's torque balance (seed Eq. 9, 12, 13 with no load) on runs with
/// the magnetic encoder, while the joint slips:
/// `r K_w2 (r theta - x2) = K_w1 r (x1 - r theta) - f_efc sgn(theta') -
/// f_efv theta' - J_e theta'' - c`, with `K_w2` from [`Cable2Fit`] (cable
/// 2's stretch against the spring while slider 2 slips) and `K_w1`, the
/// pin's friction, its viscous term, the joint inertia and an offset
/// fitted. The joint speed and acceleration are zero-phase central
/// differences of the magnetic encoder over [`JOINT_DIFF_HALF_WINDOW_S`]:
/// a causal observer lags the slip bursts of a joint in stick-slip and
/// gives the pin's friction to the viscous term.
/// Rows count once the joint has moved [`JOINT_MIN_TRAVEL_RAD`] since its
/// last reversal (past presliding).
///
/// The fit is by instrumental variables, with the commanded angle
/// `theta_ref_rad` as the instrument of cable 1's stretch, where the log
/// has it. Least squares with the stretch as a regressor reads a pin in
/// stick-slip as a softer cable: the stretch is the pin's friction plus
/// the spring's share (`K_w1 r s = y + tau_f`), so whatever of the pin's
/// torque the Coulomb and viscous columns do not describe (its breakaway
/// peaks, the slips' transients) is in the regressor and in the equation's
/// error at once, and the slope shrinks by `var(y) / (var(y) +
/// var(eps))`. On the report's pin-friction plant (a 12 mN·m pin, 3 N at
/// the cable against the calibration run's 0.7 N RMS swing of cable 2)
/// that read cable 1 7 % to 11 % soft, and the probed holds' force 1.8 %
/// to 14.1 % low. The commanded angle moves the spring's share and the
/// stretch with it, but not the pin's stick-slip, which the program does
/// not command. Without it in the log, or when it explains too little of
/// the stretch (a weak instrument, first-stage F under
/// [`JOINT_MIN_INSTRUMENT_F`]), the fit is ordinary least squares and says
/// so.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct JointFit {
    /// Rows used (joint slipping, not faulted).
    pub rows: u64,
    /// How the parameters were estimated: instrumental variables with the
    /// commanded angle, or least squares and why.
    pub method: String,
    /// Cable 2's stiffness, the scale of `y`, and how it was measured.
    pub cable2: Cable2Fit,
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
    let r = f64::from(config.machine.pulley_radius_m);
    let cable2 = identify_cable2(preps, config, c4_rad_m);
    let k_w2 = cable2.k_w2_n_m.0;
    let empty = |note: String| JointFit {
        rows: 0,
        method: String::new(),
        cable2: cable2.clone(),
        k_w1_n_m: (f64::NAN, f64::NAN),
        pin_coulomb_nm: (f64::NAN, f64::NAN),
        pin_viscous_nm_s_rad: f64::NAN,
        residual_rms_nm: f64::NAN,
        note,
    };
    if k_w2.is_nan() {
        return empty(format!("not identified: {}", cable2.method));
    }
    // The joint slips when theta' is above the JAE's switching speed seen
    // at the joint (c4 x2').
    let switch = f64::from(config.jae.sign_switch_m_s) * c4_rad_m;
    let mut rows: Vec<JointRow> = Vec::new();
    for p in preps.iter().filter(|p| p.theta_source == "theta_rad") {
        let (Ok(theta), Ok(x1), Ok(x2)) = (p.theta(), p.col("x1_m"), p.col("x2_m")) else {
            continue;
        };
        let theta_ref = p.col("theta_ref_rad").ok();
        for (k, vel, acc) in slipping_ticks(p, theta, switch, JOINT_MIN_TRAVEL_RAD) {
            let phi = [r * (x1[k] - r * theta[k]), -vel.signum(), -vel, -acc, -1.0];
            let y = r * k_w2 * (r * theta[k] - x2[k]);
            if phi.iter().chain([&y]).all(|v| v.is_finite()) {
                let instrument = theta_ref.as_ref().map_or(f64::NAN, |t| t[k]);
                rows.push(JointRow { phi, instrument, y });
            }
        }
    }
    if rows.len() < 50 {
        return empty(format!(
            "not identified: {} rows with the magnetic encoder and the joint slipping (needs 50)",
            rows.len()
        ));
    }
    // The instrumental fit, or why least squares stands in for it.
    let instrumental = if rows.iter().all(|row| row.instrument.is_finite()) {
        iv_fit(&rows).map_err(|why| format!("least squares: {why}"))
    } else {
        Err("least squares: no theta_ref_rad in every row (a pin in stick-slip then reads as a softer cable 1)".into())
    };
    let (fit, method) = match instrumental {
        Ok(fit) => {
            let method = format!(
                "instrumental variables, theta_ref_rad the stretch's instrument (first-stage F {:.0})",
                fit.first_stage_f
            );
            (fit, method)
        }
        Err(method) => match ols_fit(&rows) {
            Ok(fit) => (fit, method),
            Err(e) => return empty(format!("not identified: {e}")),
        },
    };
    let pct = |k: usize| 100.0 * fit.std[k] / fit.params[k].abs();
    let sq = residual_sum_of_squares(&rows, &fit.params);
    JointFit {
        rows: rows.len() as u64,
        method,
        cable2,
        k_w1_n_m: (fit.params[0], pct(0)),
        pin_coulomb_nm: (fit.params[1], pct(1)),
        pin_viscous_nm_s_rad: fit.params[2],
        residual_rms_nm: (sq / rows.len() as f64).sqrt(),
        note: String::new(),
    }
}

/// Cable 2's stiffness (seed Eq. 10-12) on runs with the magnetic encoder,
/// while slider 2 slips: its stretch against the spring's force and slider
/// 2's friction and inertia, `r theta - x2 = (K_s x2 + f_sc2 sgn(x2') +
/// f_sv2 x2' + m_1 x2'') / K_w2 + c`, so `K_w2 = K_s / slope` with the
/// spring rate measured or the datasheet's. Speed and acceleration are
/// zero-phase central differences of grating 2 over
/// [`JOINT_DIFF_HALF_WINDOW_S`]; rows count where `|x2'|` is above the
/// JAE's switching speed and slider 2 has travelled
/// [`CABLE2_MIN_TRAVEL_M`] since its last reversal.
///
/// The JAE's `c4` gives the same stiffness as `K_s / (c4 r - 1)`, but
/// `c4 r - 1` is the stretch's share of the motion (0.06 with the
/// datasheet's constants), so `c4`'s error is multiplied about 18 times,
/// and the JAE fits every row: where slider 2 sticks the joint still
/// turns and only its cable stretches, which the sign term cannot follow.
/// On the report's slider-2-friction plant `c4` read 0.6 % low and cable 2
/// 12.7 % stiff, and cable 1's stiffness, fitted against this cable's
/// tension, inherited it (+12.2 %). The slipping rows read every report
/// variant's cable 2 within −0.39 % to +0.71 % of the plant's, the
/// configured spring rate's error taken out (docs/force.md, "Cable 2's
/// stiffness while slider 2 slips"). The configuration keeps `K_s / (c4 r - 1)`
/// for the firmware's cable-2 term: evaluated on the JAE's `theta_hat`,
/// that term is the spring's force whatever `c4`'s error, where the
/// cable's own stiffness would double the angle error's share of the
/// joint torque.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Cable2Fit {
    /// Rows used (slider 2 slipping, not faulted).
    pub rows: u64,
    /// How `k_w2_n_m` was found: the slipping fit, or `c4` and why.
    pub method: String,
    /// Cable 2's stiffness, N/m, and its effective `%sigma` (the
    /// residual's correlation time taken into account); NaN `%sigma` when
    /// it comes from `c4`.
    pub k_w2_n_m: (f64, f64),
    /// `K_s / (c4 r - 1)`, N/m, the value the configuration keeps.
    pub k_w2_from_c4_n_m: f64,
    /// The fit's own relative error, which no check on the run reveals:
    /// [`CABLE2_SYSTEMATIC`] on logs with a row every tick,
    /// [`CABLE2_DECIMATED_SYSTEMATIC`] on decimated ones.
    pub systematic: f64,
}

impl Cable2Fit {
    /// Whether the slipping fit measured the stiffness (rather than `c4`
    /// standing in for it).
    pub fn measured(&self) -> bool {
        self.k_w2_n_m.1.is_finite()
    }
}

/// Slider travel since its last reversal before a row enters the cable-2
/// fit, m: three presliding distances of a rolling guide at the upper end
/// of its range (50 µm; the plant's default 20 µm), past which the
/// slider's friction is at its kinetic level.
pub const CABLE2_MIN_TRAVEL_M: f64 = 150e-6;

/// The slipping fit's own error, which no check on the run reveals: the
/// largest measured against the plant's cable 2, the configured spring
/// rate's error taken out (both read against the same spring), −1.00 % to
/// +1.09 % on the 40 held-out plants of `scripts/heldout-chain.py`,
/// −0.39 % to +0.71 % on the report's ten variants (stiff stiction's
/// +0.71 %), −0.51 % to +0.17 % on the presliding family's twelve. Its
/// two effective standard deviations are 0.04 % to 0.7 %, so the force
/// bound's stiffness scale takes at least this (docs/force.md, "Cable 2's
/// stiffness while slider 2 slips").
pub const CABLE2_SYSTEMATIC: f64 = 0.011;

/// [`CABLE2_SYSTEMATIC`] on logs with a row every 10th tick (the board's
/// default stream): −2.43 % to +1.40 % on the same 40 plants calibrated
/// through `scripts/heldout-chain.py --every 10` (mean −0.46 %).
pub const CABLE2_DECIMATED_SYSTEMATIC: f64 = 0.025;

/// Fewest slipping rows for [`Cable2Fit`] before it falls back on `c4`.
const CABLE2_MIN_ROWS: usize = 200;

/// Fit [`Cable2Fit`] on the prepared runs.
fn identify_cable2(preps: &[Prepared], config: &Config, c4_rad_m: f64) -> Cable2Fit {
    let m = &config.machine;
    let r = f64::from(m.pulley_radius_m);
    let k_s = f64::from(m.spring_n_m);
    let from_c4 = cable_joint::config::StretchConfig::from_jae(
        c4_rad_m as f32,
        m.spring_n_m,
        m.pulley_radius_m,
    )
    .map_or(f64::NAN, |s| f64::from(s.cable2_n_m));
    let every_tick = preps
        .iter()
        .filter(|p| p.theta_source == "theta_rad")
        .all(Prepared::every_tick);
    let systematic = if every_tick {
        CABLE2_SYSTEMATIC
    } else {
        CABLE2_DECIMATED_SYSTEMATIC
    };
    let fallback = |why: String| Cable2Fit {
        rows: 0,
        method: if from_c4.is_nan() {
            format!(
                "{why}; c4 r = {:.4} gives no cable stiffness either",
                c4_rad_m * r
            )
        } else {
            format!("from c4 (K_s / (c4 r - 1)): {why}")
        },
        k_w2_n_m: (from_c4, f64::NAN),
        k_w2_from_c4_n_m: from_c4,
        systematic,
    };
    let switch = f64::from(config.jae.sign_switch_m_s);
    let mut phi_rows: Vec<[f64; 5]> = Vec::new();
    let mut stretch_m: Vec<f64> = Vec::new();
    for p in preps.iter().filter(|p| p.theta_source == "theta_rad") {
        let (Ok(theta), Ok(x2)) = (p.theta(), p.col("x2_m")) else {
            continue;
        };
        for (k, vel, acc) in slipping_ticks(p, &x2, switch, CABLE2_MIN_TRAVEL_M) {
            let phi = [x2[k], vel.signum(), vel, acc, 1.0];
            let y = r * theta[k] - x2[k];
            if phi.iter().chain([&y]).all(|v| v.is_finite()) {
                phi_rows.push(phi);
                stretch_m.push(y);
            }
        }
    }
    if phi_rows.len() < CABLE2_MIN_ROWS {
        return fallback(format!(
            "{} rows with slider 2 slipping (needs {CABLE2_MIN_ROWS})",
            phi_rows.len()
        ));
    }
    let solved = BatchLsq::<5>::new(5, LsqConfig::default()).and_then(|mut ls| {
        for (phi, y) in phi_rows.iter().zip(&stretch_m) {
            ls.push(phi, *y)?;
        }
        ls.solve()
    });
    let fit = match solved {
        Ok(fit) => fit,
        Err(e) => return fallback(format!("the slipping fit failed ({e:?})")),
    };
    let slope = fit.params[0];
    if slope.is_nan() || slope <= 0.0 || k_s.is_nan() || k_s <= 0.0 {
        return fallback(format!(
            "the slipping fit's stretch per spring travel is {slope:.5} with a spring rate of {k_s} N/m, no positive stiffness"
        ));
    }
    let residual: Vec<f64> = phi_rows
        .iter()
        .zip(&stretch_m)
        .map(|(phi, y)| y - predict(phi, fit.params.as_slice()))
        .collect();
    let pct_sigma_eff = 100.0 * fit.std_dev[0] / slope * correlation_time(&residual).sqrt();
    Cable2Fit {
        rows: phi_rows.len() as u64,
        method: format!("slider 2 slipping, {} rows", phi_rows.len()),
        k_w2_n_m: (k_s / slope, pct_sigma_eff),
        k_w2_from_c4_n_m: from_c4,
        systematic,
    }
}

/// The ticks of one run on which the coordinate `x` slips, with its speed
/// and acceleration there (zero-phase central differences over
/// [`JOINT_DIFF_HALF_WINDOW_S`]): usable, measured rows whose speed is
/// above `switch` and whose travel since the last reversal is at least
/// `min_travel`. An element in presliding (its friction still building up
/// after a reversal) is not at its kinetic level.
fn slipping_ticks(p: &Prepared, x: &[f64], switch: f64, min_travel: f64) -> Vec<(usize, f64, f64)> {
    let period_s = f64::from(p.config().period_s());
    let half = p.half_window(JOINT_DIFF_HALF_WINDOW_S);
    let (vel, acc) = central_kinematics(x, half, period_s);
    let mut ticks = Vec::new();
    let mut travel = 0.0;
    for k in 0..p.len() {
        travel = if k > 0 && vel[k].signum() == vel[k - 1].signum() {
            travel + (x[k] - x[k - 1]).abs()
        } else {
            0.0
        };
        if p.usable[k]
            && p.measured(k)
            && vel[k].is_finite()
            && acc[k].is_finite()
            && vel[k].abs() > switch
            && travel >= min_travel
        {
            ticks.push((k, vel[k], acc[k]));
        }
    }
    ticks
}

/// One row of the joint fit: the regressors `[r (x1 - r theta), -sgn,
/// -theta', -theta'', -1]`, the commanded angle (NaN where not logged) and
/// `r K_w2 (r theta - x2)`.
struct JointRow {
    phi: [f64; 5],
    instrument: f64,
    y: f64,
}

/// A fitted row's prediction, `phi . params`.
fn predict(phi: &[f64; 5], params: &[f64]) -> f64 {
    phi.iter().zip(params).map(|(a, b)| a * b).sum()
}

/// `sum (y - phi . params)^2` over the rows.
fn residual_sum_of_squares(rows: &[JointRow], params: &[f64; 5]) -> f64 {
    rows.iter()
        .map(|row| (row.y - predict(&row.phi, params)).powi(2))
        .sum()
}

/// A solved joint fit: parameters and their standard deviations.
struct Solved {
    params: [f64; 5],
    std: [f64; 5],
    first_stage_f: f64,
}

/// Least first-stage F of the commanded angle for the instrumental fit
/// (the rule of thumb of Staiger and Stock, 1997: below 10 an
/// instrumental estimate keeps much of least squares' bias and its
/// standard deviations mislead).
pub const JOINT_MIN_INSTRUMENT_F: f64 = 10.0;

/// Ordinary least squares through the core's [`BatchLsq`].
fn ols_fit(rows: &[JointRow]) -> Result<Solved, String> {
    let mut ls = BatchLsq::<5>::new(5, LsqConfig::default()).map_err(|e| format!("{e:?}"))?;
    for row in rows {
        ls.push(&row.phi, row.y).map_err(|e| format!("{e:?}"))?;
    }
    let fit = ls.solve().map_err(|e| format!("{e:?}"))?;
    Ok(Solved {
        params: core::array::from_fn(|k| fit.params[k]),
        std: core::array::from_fn(|k| fit.std_dev[k]),
        first_stage_f: f64::NAN,
    })
}

/// Instrumental variables, just identified: the stretch column's
/// instrument is the commanded angle, every other column its own.
/// `beta = (Z'X)^-1 Z'y`, covariance `s^2 (Z'X)^-1 Z'Z (X'Z)^-1` with `s^2`
/// the residual variance; columns scaled to unit RMS first (the stretch is
/// of order 1e-6 m^2, the acceleration of 1e2 rad/s^2).
fn iv_fit(rows: &[JointRow]) -> Result<Solved, String> {
    use nalgebra::{Matrix5, Vector5};
    let z_of = |row: &JointRow| {
        let mut z = row.phi;
        z[0] = row.instrument;
        z
    };
    let n = rows.len() as f64;
    let rms = |f: &dyn Fn(&JointRow) -> f64| {
        let v = (rows.iter().map(|row| f(row).powi(2)).sum::<f64>() / n).sqrt();
        if v > 0.0 {
            v
        } else {
            1.0
        }
    };
    let sx: [f64; 5] = core::array::from_fn(|k| rms(&|row| row.phi[k]));
    let sz: [f64; 5] = core::array::from_fn(|k| rms(&|row| z_of(row)[k]));
    let (mut zx, mut zz, mut zy) = (Matrix5::zeros(), Matrix5::zeros(), Vector5::zeros());
    for row in rows {
        let x = Vector5::from_fn(|k, _| row.phi[k] / sx[k]);
        let z = Vector5::from_fn(|k, _| z_of(row)[k] / sz[k]);
        zx += z * x.transpose();
        zz += z * z.transpose();
        zy += z * row.y;
    }
    // First stage: how much of the stretch the commanded angle explains
    // beyond the other columns (partial R^2, then F with one instrument).
    let stretch = Vector5::from_fn(|k, _| zx[(k, 0)]);
    let total: f64 = rows.iter().map(|row| (row.phi[0] / sx[0]).powi(2)).sum();
    let full = zz.lu().solve(&stretch).map(|c| c.dot(&stretch) / total);
    let others = zz
        .fixed_view::<4, 4>(1, 1)
        .into_owned()
        .lu()
        .solve(&stretch.fixed_rows::<4>(1).into_owned())
        .map(|c| c.dot(&stretch.fixed_rows::<4>(1)) / total);
    let (Some(full), Some(others)) = (full, others) else {
        return Err("the instruments' normal matrix is singular".into());
    };
    let partial = (full - others) / (1.0 - others).max(f64::MIN_POSITIVE);
    let first_stage_f = (n - 5.0) * partial / (1.0 - partial).max(f64::MIN_POSITIVE);
    if first_stage_f.is_nan() || first_stage_f < JOINT_MIN_INSTRUMENT_F {
        return Err(format!(
            "the commanded angle explains too little of cable 1's stretch (first-stage F {first_stage_f:.1}, needs {JOINT_MIN_INSTRUMENT_F})"
        ));
    }
    let inv = zx
        .try_inverse()
        .ok_or_else(|| "Z'X is singular".to_string())?;
    let beta = inv * zy;
    let params: [f64; 5] = core::array::from_fn(|k| beta[k] / sx[k]);
    let sq = residual_sum_of_squares(rows, &params);
    let cov = inv * zz * inv.transpose() * (sq / (n - 5.0));
    Ok(Solved {
        params,
        std: core::array::from_fn(|k| cov[(k, k)].max(0.0).sqrt() / sx[k]),
        first_stage_f,
    })
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
    /// bound, a cable 1 it could not identify is taken as cable 2's (its
    /// slipping fit's, else the configuration's).
    /// Returns what was written.
    pub(super) fn apply(&self, config: &mut Config) -> String {
        let (k1, pk1) = self.k_w1_n_m;
        let stiffness = if k1.is_finite() && k1 > 0.0 && pk1 < JOINT_MAX_PCT_SIGMA {
            config.stretch.cable1_n_m = k1 as f32;
            format!("stretch.cable1_n_m = {k1:.0} (%sigma {pk1:.1})")
        } else {
            let k2 = self.cable2.k_w2_n_m.0;
            if k2.is_finite() && k2 > 0.0 {
                config.stretch.cable1_n_m = k2 as f32;
            } else {
                config.stretch.cable1_n_m = config.stretch.cable2_n_m;
            }
            format!(
                "cable 1 stiffness not identifiable (K_w1 {k1:.0} N/m, %sigma {pk1:.1}): taken as cable 2's, {:.0} N/m",
                config.stretch.cable1_n_m
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
