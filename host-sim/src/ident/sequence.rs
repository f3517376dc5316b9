//! The seed's order of identification: `B_m` (for the DOB), then the JAE,
//! then the tension models (on the DOB with the identified `B_m`), each on
//! its own runs and validated on others.

use anyhow::{Context, Result};
use cable_joint::Config;

use super::{
    identify_bm_with, identify_jae_with, identify_tension_with, validate_bm, validate_jae,
    validate_tension, IdentOptions, IdentifyReport, Validation,
};
use crate::log::Log;

/// The logs of one procedure: `(label, log)` fitted on, and validated on.
#[derive(Clone, Debug, Default)]
pub struct Runs<'a> {
    /// Fitted on (at least one).
    pub fit: Vec<(&'a str, &'a Log)>,
    /// Validated on (not used for the fit).
    pub validate: Vec<(&'a str, &'a Log)>,
}

/// `B_m`, the JAE and the tension models in that order, each on its runs
/// (`None`: not identified), each result applied to the configuration
/// before the next step uses it. Returns the report and `base` with every
/// result applied.
pub fn identify_in_order(
    bm: Option<&Runs>,
    jae: Option<&Runs>,
    tension: Option<&Runs>,
    base: Config,
    opts: &IdentOptions,
) -> Result<(IdentifyReport, Config)> {
    opts.check()?;
    let mut config = base;
    let mut rep = IdentifyReport {
        options: Some(*opts),
        ..IdentifyReport::default()
    };
    let validation = |log: &str, model: &str, errors| Validation {
        log: log.to_owned(),
        model: model.to_owned(),
        errors,
    };
    if let Some(runs) = bm {
        let r = identify_bm_with(&runs.fit, &config, opts)?;
        r.apply(&mut config);
        for (name, log) in &runs.validate {
            let e = validate_bm(&r, log, &config, opts)
                .with_context(|| format!("validating B_m on {name}"))?;
            rep.validation.push(validation(name, &r.fit.model, e));
        }
        rep.bm = Some(r);
    }
    if let Some(runs) = jae {
        let r = identify_jae_with(&runs.fit, &config, opts)?;
        r.apply(&mut config);
        for (name, log) in &runs.validate {
            let e = validate_jae(&r, log, &config, opts)
                .with_context(|| format!("validating the JAE on {name}"))?;
            rep.validation.push(validation(name, &r.fit.model, e));
        }
        rep.jae = Some(r);
    }
    if let Some(runs) = tension {
        let r = identify_tension_with(&runs.fit, &config, opts)?;
        r.apply(&mut config);
        for (name, log) in &runs.validate {
            let v = validate_tension(&r, log, &config, opts)
                .with_context(|| format!("validating the tension models on {name}"))?;
            for (model, e) in v {
                rep.validation.push(validation(name, &model, e));
            }
        }
        rep.tension = Some(r);
    }
    Ok((rep, config))
}
