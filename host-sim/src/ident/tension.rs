//! The no-load tension models A, B, C (Eq. 22-24) and the simplified model C.

use anyhow::{bail, Context, Result};
use cable_joint::Config;

use super::design::{design, evaluate, fit_terms, prepare_all, report, solve, Target};
use super::prune::{prune, Pruned};
use super::{
    FitReport, IdentOptions, ModelTerm, Regressor, TensionResult, MODEL_A, MODEL_B, MODEL_C,
    SIMPLIFIED_C,
};
use crate::log::Log;
use crate::stats::ErrorStats;

/// The tension models with the default options.
pub fn identify_tension(log: &Log, config: &Config) -> Result<TensionResult> {
    identify_tension_with(&[("log", log)], config, &IdentOptions::default())
}

/// No-load tension models A, B, C (Eq. 22-24) against the DOB's cable-1
/// tension (Eq. 21, recomputed by the replay with `config.dob.viscous_nm_s_rad`,
/// so pass the configuration with the identified `B_m`), the pruning to the
/// simplified model C, and the refit on the core's structure.
pub fn identify_tension_with(
    logs: &[(&str, &Log)],
    config: &Config,
    opts: &IdentOptions,
) -> Result<TensionResult> {
    let preps = prepare_all(logs, config, opts)?;
    let fit = |name: &str, terms: &[ModelTerm]| {
        fit_terms(name, &preps, terms, Target::Tension, opts, 1.0, "N")
    };
    let model_a = fit("model A (Eq. 22)", &MODEL_A).map_err(|e| format!("{e:#}"));
    let model_b = fit("model B (Eq. 23)", &MODEL_B).map_err(|e| format!("{e:#}"));

    // Model C and the pruning, on one design matrix.
    let regs: Vec<Regressor> = MODEL_C.iter().map(|t| t.regressor).collect();
    let d = design(&preps, &regs, Target::Tension, opts)?;
    let all: Vec<usize> = (0..MODEL_C.len()).collect();
    let fit_c = solve(&d, &all, opts).context("fitting model C (Eq. 24/27)")?;
    let model_c = report("model C (Eq. 24/27)", &d, &MODEL_C, &all, &fit_c, 1.0, "N");

    let Pruned {
        active,
        fit,
        dropped,
    } = prune(&d, &MODEL_C, fit_c, opts)?;
    let simplified = report(
        "simplified model C (Eq. 28-29)",
        &d,
        &MODEL_C,
        &active,
        &fit,
        1.0,
        "N",
    );

    // The core's structure: the kept ones of [sgn x1', sgn x2', x2, 1].
    let core_idx: Vec<usize> = active
        .iter()
        .copied()
        .filter(|j| SIMPLIFIED_C.contains(&MODEL_C[*j].regressor))
        .collect();
    let not_written: Vec<Regressor> = active
        .iter()
        .map(|j| MODEL_C[*j].regressor)
        .filter(|r| !SIMPLIFIED_C.contains(r))
        .collect();
    if core_idx.is_empty() {
        bail!("the pruning kept none of the core's tension terms (sgn x1', sgn x2', x2, 1)");
    }
    let core = if not_written.is_empty() {
        FitReport {
            model: "tension model written (core structure)".to_owned(),
            ..simplified.clone()
        }
    } else {
        let f = solve(&d, &core_idx, opts).context("refitting the core's tension model")?;
        report(
            "tension model written (core structure)",
            &d,
            &MODEL_C,
            &core_idx,
            &f,
            1.0,
            "N",
        )
    };
    // Slider 2's Coulomb term below zero while the rest is physical (slider
    // 1's and the sum positive, the spring's rate and preload too): the
    // two sign columns move together but in transients, so the run pins
    // their sum down and not the split; the fit bounded by physics puts
    // slider 2's at zero and the sum in slider 1's (whose band the force
    // bound widens by, so it stays as wide).
    let only_slider2 = |c: &FitReport| {
        let forbidden = forbidden_values(c);
        let sum_n = c.value(Regressor::SgnX1Vel) + c.value(Regressor::SgnX2Vel);
        match forbidden.as_slice() {
            [(Regressor::SgnX2Vel, why)] if sum_n > 0.0 => Some(why.clone()),
            _ => None,
        }
    };
    let (core, slider2_at_zero) = match only_slider2(&core) {
        Some(why) if core_idx.len() > 1 => {
            let bounded: Vec<usize> = core_idx
                .iter()
                .copied()
                .filter(|j| MODEL_C[*j].regressor != Regressor::SgnX2Vel)
                .collect();
            let f = solve(&d, &bounded, opts).context("refitting with f_cp2 at zero")?;
            let refit = report(
                "tension model written (core structure, f_cp2 at zero)",
                &d,
                &MODEL_C,
                &bounded,
                &f,
                1.0,
                "N",
            );
            let note = format!(
                "{why}: refitted with f_cp2 = 0, so f_sc1 = {:.4} N carries the sum the run \
                 identifies ({:.4} N before; the two sign columns move together but in \
                 transients, so their split is loose); residual {:.3} -> {:.3} N RMS",
                refit.value(Regressor::SgnX1Vel),
                core.value(Regressor::SgnX1Vel) + core.value(Regressor::SgnX2Vel),
                core.sigma,
                refit.sigma
            );
            (refit, Some(note))
        }
        _ => (core, None),
    };
    let chi_p = SIMPLIFIED_C.map(|r| core.value(r));
    let unphysical = unphysical_terms(&core, config);
    let cable0 = super::read_cable0_stiffness(&preps);
    let change_a = current_change_per_tick_a(logs);
    let unidentified = if unphysical.is_some() {
        None
    } else {
        friction_hidden(&core, chi_p, change_a, config)
    };
    // A limit cycle, not a quiet loop, behind it: the configuration written
    // takes the position loop's derivative from the grating observer, and
    // the run is to be recorded again with it.
    let derivative_from_observer = unidentified.is_some()
        && !config.cascade.kd_on_observer_rate
        && change_a
            .is_some_and(|a| a >= LIMIT_CYCLE_SHARE * f64::from(config.cascade.current_limit_a));
    Ok(TensionResult {
        theta_source: preps[0].theta_source.to_owned(),
        b_m_used_nm_s_rad: f64::from(preps[0].cfg.dob.viscous_nm_s_rad),
        model_a,
        model_b,
        model_c,
        dropped,
        simplified,
        core,
        chi_p,
        not_written,
        slider2_at_zero,
        unphysical,
        unidentified,
        derivative_from_observer,
        current_change_per_tick_a: change_a,
        cable0,
    })
}

/// How many of its (correlation-corrected) standard deviations a Coulomb
/// term may lie below zero and still be read as a friction the run could
/// not separate from its twin (model C's two sign columns move together
/// but in transients, so their split is loose): beyond it the fit has
/// used the term for something else.
pub const NEGATIVE_FRICTION_SIGMAS: f64 = 2.0;

/// What physics forbids in a fit of the core's tension model `[f_sc1,
/// f_cp2, K_s, F_0]`, each with the sentence that says so: a return
/// spring's rate and the preload are positive, a Coulomb friction is not
/// negative (beyond [`NEGATIVE_FRICTION_SIGMAS`]; a term the fit lacks is
/// 0 and forbidden only for `K_s` and `F_0`, which are never pruned).
fn forbidden_values(core: &FitReport) -> Vec<(Regressor, String)> {
    let mut out = Vec::new();
    for (r, name) in [
        (Regressor::SgnX1Vel, "f_sc1"),
        (Regressor::SgnX2Vel, "f_cp2"),
    ] {
        let value = core.value(r);
        let std_n = core.std_eff(r).unwrap_or(0.0);
        if value < -NEGATIVE_FRICTION_SIGMAS * std_n {
            out.push((
                r,
                format!(
                    "{name} = {value:.4} N (standard deviation {std_n:.3} N): a Coulomb \
                     friction is not negative"
                ),
            ));
        }
    }
    let k_s = core.value(Regressor::X2);
    if k_s.is_nan() || k_s <= 0.0 {
        out.push((
            Regressor::X2,
            format!("K_s = {k_s:.1} N/m: a return spring's rate is positive"),
        ));
    }
    let f_0 = core.value(Regressor::One);
    if f_0.is_nan() || f_0 <= 0.0 {
        out.push((
            Regressor::One,
            format!("F_0 = {f_0:.3} N: the return spring's preload is a positive tension"),
        ));
    }
    out
}

/// Why the written model may not be written ([`forbidden_values`]): such
/// a fit has not identified model C (a run cut short by a fault, a plant
/// the run did not excite, an effect the model lacks). The sentence says
/// which values and why, and [`TensionResult::apply`] keeps the
/// configuration's model (named in it) instead.
fn unphysical_terms(core: &FitReport, config: &Config) -> Option<String> {
    let why: Vec<String> = forbidden_values(core).into_iter().map(|(_, w)| w).collect();
    if why.is_empty() {
        return None;
    }
    Some(format!(
        "the tension model is not written: {} ({} rows fitted, residual {:.2} N RMS). The log \
         does not identify model C (a run cut short by a fault, a motion that did not excite \
         both sliders, or an effect the model lacks); {}. Record tension-ident again, whole, \
         before trusting the DOB and the force bound",
        why.join("; "),
        core.rows,
        core.sigma,
        kept_model(config)
    ))
}

/// The clause naming the tension model a configuration keeps when the
/// fitted one is not written.
fn kept_model(config: &Config) -> String {
    let t = &config.tension;
    format!(
        "the configuration keeps its model, chi_p = [{}, {}, {}, {}]",
        t.f_sc1_n, t.f_cp2_n, t.k_s_n_m, t.f_0_n
    )
}

/// Mean change of the drive current per tick, as a share of the current
/// limit, above which a log whose friction went unidentified is taken for
/// a limit cycle: the default prototype's quiet loop, 0.04 to 0.13 A at 1
/// and 2 kHz, lies below 0.2 A of the 2 A limit; the limit cycles that hid
/// the friction (500 Hz, a four times lighter slider 2 and presliding
/// friction at 1 kHz) measured 0.24 to 0.48 A. Over the report's ten
/// variants and twenty held-out draws the identified loops ran at 0.077
/// to 0.256 A: the share alone does not tell a cycle, the residual does
/// (README, "What keeps 1 kHz quiet").
pub const LIMIT_CYCLE_SHARE: f64 = 0.1;

/// The drive current's mean change per tick over `logs`, A (`None`
/// without an `i_ref_a` column).
fn current_change_per_tick_a(logs: &[(&str, &Log)]) -> Option<f64> {
    let (mut sum_a, mut n) = (0.0, 0usize);
    for (_, log) in logs {
        if let Some(i) = log.col("i_ref_a") {
            sum_a += i.windows(2).map(|w| (w[1] - w[0]).abs()).sum::<f64>();
            n += i.len().saturating_sub(1);
        }
    }
    (n > 0).then(|| sum_a / n as f64)
}

/// Model C's Coulomb terms are what the force bound's DOB side takes for
/// its friction bands. When the fitted model's residual (the DOB's
/// tension the model does not explain) is larger than those terms
/// together, the log cannot tell them from the rest, and a bound built on
/// them is not a bound: [`TensionResult::apply`] keeps the configuration's
/// model (the datasheet's, whose bound is the cable stretch's alone, or
/// one identified on an earlier run). On plant 8 of stop 73's held-out
/// set (`docs/force.md`, "A tension model whose friction the run did not
/// identify"), its tension run recorded at a row every 10th tick in
/// closed loop on the datasheet's JAE, the fitted model (residual 22.7 N
/// RMS against 4.3 N of friction) had let the bound hold the load on as
/// little as 81.8 % of a hold's settled samples (15 of 18 holds under
/// 99.5 %); with the datasheet's model kept, on 100 % of every hold. Returns
/// the sentence that says so, with the
/// drive current's mean change per tick as the first thing to look at: a
/// current limit cycle in closed loop on the JAE (measured at 500 Hz, and
/// at 1 kHz on a plant with a four times lighter slider 2) puts 10 to 20 N
/// RMS of rotor inertia into the DOB's tension (README, "Below 1 kHz the
/// chatter is a limit cycle").
fn friction_hidden(
    core: &FitReport,
    chi_p: [f64; 4],
    change_a: Option<f64>,
    config: &Config,
) -> Option<String> {
    let friction_n = chi_p[0].abs() + chi_p[1].abs();
    let residual_n = core.sigma;
    if residual_n <= friction_n {
        return None;
    }
    let chatter = if let Some(a) = change_a {
        format!(
            "; the drive current changes by {a:.3} A per tick on average (0.04 to 0.13 A \
             on the simulated prototype's quiet loop at 1 and 2 kHz, 0.24 to 0.48 A in the \
             limit cycles measured at 500 Hz and 1 kHz, which the DOB reads as rotor inertia)"
        )
    } else {
        String::new()
    };
    Some(format!(
        "the fitted tension model's residual ({residual_n:.2} N RMS) is larger than the \
         friction terms it fits (f_sc1 + f_cp2 = {friction_n:.2} N): this log does not \
         identify them, and the force bound's DOB side would rest on them{chatter}. The \
         model is not written: {} (the datasheet's leaves the bound to the cable stretch \
         alone). Record the run again with a quiet current (in the motor-encoder loop, or \
         on the JAE with `cascade.kd_on_observer_rate = true` and a lower \
         `differentiators.grating_bandwidth_hz`), whole, and identify the tension models \
         from it",
        kept_model(config)
    ))
}

/// Errors of every tension model on another no-load log (N): models A, B, C
/// (those that were fitted), the simplified one and the written one.
pub fn validate_tension(
    result: &TensionResult,
    log: &Log,
    config: &Config,
    opts: &IdentOptions,
) -> Result<Vec<(String, ErrorStats)>> {
    let preps = prepare_all(&[("validation", log)], config, opts)?;
    let mut out = Vec::new();
    let models = [
        result.model_a.as_ref().ok(),
        result.model_b.as_ref().ok(),
        Some(&result.model_c),
        Some(&result.simplified),
        Some(&result.core),
    ];
    for m in models.into_iter().flatten() {
        out.push((
            m.model.clone(),
            evaluate(m, &preps, Target::Tension, opts, 1.0, "N")?,
        ));
    }
    Ok(out)
}

impl TensionResult {
    /// Why `chi_p` is not written ([`TensionResult::unphysical`], else
    /// [`TensionResult::unidentified`]); `None`: [`TensionResult::apply`]
    /// writes it.
    pub fn why_not_written(&self) -> Option<&String> {
        self.unphysical.as_ref().or(self.unidentified.as_ref())
    }

    /// Write `chi_p` into the configuration (unless physics forbids it,
    /// [`TensionResult::unphysical`], or the log does not identify its
    /// friction terms, [`TensionResult::unidentified`]: the
    /// configuration's model is kept),
    /// cable 0's stiffness where the
    /// logs give it ([`TensionResult::cable0`]; else 0, cable 1's bound,
    /// whatever the configuration held: a stiffness read on another run,
    /// perhaps of another rope, must not shorten this one's slack check),
    /// and the position loop's derivative from the grating observer when
    /// the log limit-cycled ([`TensionResult::derivative_from_observer`]).
    pub fn apply(&self, config: &mut Config) {
        if self.derivative_from_observer {
            config.cascade.kd_on_observer_rate = true;
        }
        config.stretch.cable0_n_m = match &self.cable0 {
            Ok(k) => k.n_m as f32,
            Err(_) => 0.0,
        };
        if self.why_not_written().is_some() {
            return;
        }
        let t = &mut config.tension;
        t.f_sc1_n = self.chi_p[0] as f32;
        t.f_cp2_n = self.chi_p[1] as f32;
        t.k_s_n_m = self.chi_p[2] as f32;
        t.f_0_n = self.chi_p[3] as f32;
    }
}
