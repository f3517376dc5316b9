//! The joint-angle estimator (Eq. 25-26), with the spring rate and the
//! joint's torque balance fitted on the same runs.

use anyhow::Result;
use cable_joint::Config;

use super::design::{evaluate, fit_terms, prepare_all, Target};
use super::joint::identify_joint;
use super::spring::identify_spring;
use super::{IdentOptions, JaeResult, Regressor, JAE_TERMS};
use crate::log::Log;
use crate::stats::ErrorStats;

/// The JAE with the default options.
pub fn identify_jae(log: &Log, config: &Config) -> Result<JaeResult> {
    identify_jae_with(&[("log", log)], config, &IdentOptions::default())
}

/// The joint-angle estimator (Eq. 25-26) from runs with the magnetic encoder:
/// `theta = c1 x2'' + c2 x2' + c3 sgn(x2') + c4 x2 + offset`.
pub fn identify_jae_with(
    logs: &[(&str, &Log)],
    config: &Config,
    opts: &IdentOptions,
) -> Result<JaeResult> {
    let preps = prepare_all(logs, config, opts)?;
    let fit = fit_terms(
        "JAE (Eq. 25-26)",
        &preps,
        &JAE_TERMS,
        Target::Theta,
        opts,
        1.0,
        "rad",
    )?;
    let error_deg = ErrorStats {
        unit: "deg",
        ..fit.errors.scaled(180.0 / std::f64::consts::PI)
    };
    let mut spring = identify_spring(&preps, config);
    let mut measured = *config;
    spring.note = spring.apply(&mut measured);
    let mut joint = identify_joint(&preps, &measured, fit.value(Regressor::X2));
    if joint.note.is_empty() {
        joint.note = joint.apply(&mut measured);
    }
    let mut result = JaeResult {
        spring,
        joint,
        chi_s: [
            fit.value(Regressor::X2Acc),
            fit.value(Regressor::X2Vel),
            fit.value(Regressor::SgnX2Vel),
            fit.value(Regressor::X2),
        ],
        offset_rad: fit.value(Regressor::One),
        error_deg,
        fit,
        stiffness_tolerance: [f64::NAN; 3],
    };
    result.stiffness_tolerance = result.scale_tolerance(
        f64::from(config.fusion.stiffness_tolerance),
        f64::from(config.machine.pulley_radius_m),
    );
    Ok(result)
}

/// Errors of an identified JAE on another log with the magnetic encoder (deg).
pub fn validate_jae(
    result: &JaeResult,
    log: &Log,
    config: &Config,
    opts: &IdentOptions,
) -> Result<ErrorStats> {
    let preps = prepare_all(&[("validation", log)], config, opts)?;
    evaluate(
        &result.fit,
        &preps,
        Target::Theta,
        opts,
        180.0 / std::f64::consts::PI,
        "deg",
    )
}

impl JaeResult {
    /// The sign term `c3`'s standard deviation with the residual's
    /// correlation taken into account (`std sqrt(tau)`, the `%sigma eff`
    /// column), rad.
    pub fn sign_term_std_eff_rad(&self) -> f64 {
        self.fit.std_eff(Regressor::SgnX2Vel).unwrap_or(f64::NAN)
    }

    /// Whether the run pins `c3` down: its effective `%sigma` below 100 %.
    /// Stick-slip at the reversals and a viscous term that takes up the
    /// Coulomb level at near-constant sweep speeds can leave it free.
    pub fn sign_term_identified(&self) -> bool {
        self.sign_term_std_eff_rad() < self.chi_s[2].abs()
    }

    /// Relative uncertainty of the cables' stiffnesses, the stretch
    /// estimate's force scale (`fusion.stiffness_tolerance`), given the
    /// configuration's `prior_tol`: the spring rate's
    /// ([`SpringFit::relative_uncertainty`](super::SpringFit::relative_uncertainty),
    /// with the datasheet's tolerance the lesser of `prior_tol` and a stock
    /// spring's, the default configuration's 10 %) plus cable 2's, two
    /// effective standard deviations of its slipping fit
    /// ([`Cable2Fit`](super::Cable2Fit), which scales cable 1's through
    /// the joint fit) and at least that fit's measured systematic error
    /// ([`Cable2Fit::systematic`](super::Cable2Fit::systematic)) or, when
    /// that fit fell back on `c4`, `c4`'s carried through `K_w2 = K_s / (c4
    /// r - 1)`, `2 r std_eff(c4) / (c4 r - 1)`. When the configuration's
    /// spring rate stands, `prior_tol` is also the floor of the total: a
    /// configuration an earlier identification wrote carries its measured
    /// rate as the datasheet's and the uncertainty it was measured with,
    /// which stays. So identifying again from a configuration `identify`
    /// wrote, on the same log, writes the same tolerance; until stop 45
    /// each pass added `c4`'s part once more. Returns the tolerance and
    /// its two parts ([`JaeResult::stiffness_tolerance`]).
    fn scale_tolerance(&self, prior_tol: f64, pulley_radius_m: f64) -> [f64; 3] {
        let stock_tol = f64::from(Config::default().fusion.stiffness_tolerance);
        let spring = self.spring.relative_uncertainty(prior_tol.min(stock_tol));
        let excess = self.chi_s[3] * pulley_radius_m - 1.0;
        let cable2 = &self.joint.cable2;
        let cable2_part = if cable2.measured() {
            (2.0 * cable2.k_w2_n_m.1 / 100.0).max(cable2.systematic)
        } else {
            self.fit
                .std_eff(Regressor::X2)
                .map(|std| 2.0 * pulley_radius_m * std / excess)
                .filter(|v| excess > 0.0 && v.is_finite())
                .unwrap_or(0.0)
        };
        let measured = spring + cable2_part;
        let total = match self.spring.value() {
            Some(_) => measured,
            None => measured.max(prior_tol),
        };
        [total.min(1.0), spring, cable2_part]
    }

    /// The JAE error the force bound allows beyond the sign band it builds
    /// on `|c3|` (`fusion.jae_error_rad`), rad: two RMS of the
    /// identification residual, plus two effective standard deviations of
    /// `c3` times `1 + static_over_kinetic` (the band's widest width per
    /// unit of `c3`, a stuck slider 2), so that a sign term the run could
    /// not pin down widens the bound instead of narrowing it.
    pub fn bound_error_rad(&self, static_over_kinetic: f64) -> f64 {
        2.0 * self.error_deg.rmse.to_radians()
            + 2.0 * (1.0 + static_over_kinetic) * self.sign_term_std_eff_rad()
    }

    /// Write `chi_s` and the offset into the configuration.
    pub fn apply(&self, config: &mut Config) {
        let j = &mut config.jae;
        j.c_acc_rad_s2_m = self.chi_s[0] as f32;
        j.c_vel_rad_s_m = self.chi_s[1] as f32;
        j.c_sign_rad = self.chi_s[2] as f32;
        j.c_pos_rad_m = self.chi_s[3] as f32;
        j.offset_rad = self.offset_rad as f32;
        // The position coefficient fixes the cable stiffness (Eq. 16):
        // c4 = (K_s + K_w2) / (K_w2 r), with the spring rate measured
        // through the motor, or the datasheet's when it could not be.
        self.spring.apply(config);
        let m = &config.machine;
        if let Some(s) = cable_joint::config::StretchConfig::from_jae(
            config.jae.c_pos_rad_m,
            m.spring_n_m,
            m.pulley_radius_m,
        ) {
            config.stretch = s;
        }
        let tol = self.stiffness_tolerance[0];
        if tol.is_finite() {
            config.fusion.stiffness_tolerance = tol as f32;
        }
        let err_rad = self.bound_error_rad(f64::from(config.fusion.static_over_kinetic));
        if err_rad.is_finite() {
            config.fusion.jae_error_rad = err_rad as f32;
        }
        self.joint.apply(config);
    }
}
