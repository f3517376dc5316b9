//! Motor damping `B_m` (seed Sect. 3.3/4.2).

use anyhow::{bail, Result};
use cable_joint::Config;

use super::design::{evaluate, fit_terms, prepare_all, Target};
use super::{BmResult, IdentOptions, ModelTerm, Regressor, BM_TERMS};
use crate::log::Log;
use crate::stats::ErrorStats;

fn bm_terms(opts: &IdentOptions) -> &'static [ModelTerm] {
    if opts.bm_coulomb {
        &BM_TERMS
    } else {
        &BM_TERMS[..2]
    }
}

/// `B_m` from a no-load motor run with the default options.
pub fn identify_bm(log: &Log, config: &Config) -> Result<BmResult> {
    identify_bm_with(&[("log", log)], config, &IdentOptions::default())
}

/// `B_m` (seed Sect. 3.3/4.2) from no-load motor runs `(label, log)`:
/// `Q[K_m i - J_m phi''] = B_m Q[phi'] + tau_0 (+ tau_c Q[sgn phi'])`.
pub fn identify_bm_with(
    logs: &[(&str, &Log)],
    config: &Config,
    opts: &IdentOptions,
) -> Result<BmResult> {
    for (label, log) in logs {
        check_unhooked(label, log, config)?;
    }
    let preps = prepare_all(logs, &decoupled(config), opts)?;
    let fit_with = |terms: &[ModelTerm]| {
        fit_terms(
            "B_m (no-load motor)",
            &preps,
            terms,
            Target::MotorTorque,
            opts,
            1.0,
            "N·m",
        )
    };
    let mut fit = fit_with(bm_terms(opts))?;
    let mut coulomb_dropped = None;
    if let Some(p) = fit.param(Regressor::SgnPhiVel) {
        if p.pct_sigma.is_nan() || p.pct_sigma > opts.max_pct_sigma {
            coulomb_dropped = Some(p.pct_sigma);
            fit = fit_with(&BM_TERMS[..2])?;
        }
    }
    let b = fit.value(Regressor::PhiVel);
    if !(b.is_finite() && b >= 0.0) {
        bail!("identified B_m = {b:e} N·m·s/rad is not physical (negative): is the motor really unloaded and moving?");
    }
    Ok(BmResult {
        b_m_nm_s_rad: b,
        coulomb_nm: fit.param(Regressor::SgnPhiVel).map(|p| p.value),
        coulomb_dropped_pct_sigma: coulomb_dropped,
        fit,
    })
}

/// A no-load run has its rope wheel unhooked: grating 1 (on cable 1)
/// stays where it is while the motor turns. Where it moves by more than a
/// tenth of the cable the motor winds (and by more than ten counts), the
/// cable is attached, the motor current carries its tension, and the fit
/// would call that tension damping.
fn check_unhooked(label: &str, log: &Log, config: &Config) -> Result<()> {
    let span = |name: &str| {
        let (lo, hi) = crate::stats::finite_range(log.col(name)?.iter().copied())?;
        Some(hi - lo)
    };
    let (Some(phi_rad), Some(x1_m)) = (span("phi_rad"), span("x1_m")) else {
        return Ok(());
    };
    let m = &config.machine;
    let wound_m = phi_rad * f64::from(m.rope_wheel_radius_m / m.gear_ratio);
    let counts = x1_m / f64::from(config.scales.grating_m_per_count);
    if x1_m > 0.1 * wound_m && counts > 10.0 {
        bail!(
            "{label}: grating 1 moves {:.3} mm while the motor winds {:.3} mm of cable: the \
             cable is attached, so the motor current carries its tension. B_m needs the \
             no-load motor run (rope wheel unhooked); give this log to the jae or tension \
             procedure",
            x1_m * 1e3,
            wound_m * 1e3
        );
    }
    Ok(())
}

/// Errors of an identified `B_m` model on another no-load log (N·m).
pub fn validate_bm(
    result: &BmResult,
    log: &Log,
    config: &Config,
    opts: &IdentOptions,
) -> Result<ErrorStats> {
    check_unhooked("validation", log, config)?;
    let preps = prepare_all(&[("validation", log)], &decoupled(config), opts)?;
    evaluate(&result.fit, &preps, Target::MotorTorque, opts, 1.0, "N·m")
}

/// The configuration for replaying a no-load motor run: with the rope wheel
/// unhooked the motor angle says nothing about the joint, so the
/// transmission-slack check (`limits.min_tension_fraction`) is switched off.
pub fn decoupled(config: &Config) -> Config {
    let mut c = *config;
    c.limits.min_tension_fraction = 0.0;
    c
}

impl BmResult {
    /// Write `B_m` into the configuration.
    pub fn apply(&self, config: &mut Config) {
        config.dob.viscous_nm_s_rad = self.b_m_nm_s_rad as f32;
    }
}
