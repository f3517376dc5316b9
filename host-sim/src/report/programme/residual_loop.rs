//! Step 7's residual loop on an identification's logs (the JAE, then the
//! tension model), each model's terms also judged on other regimes.

use anyhow::{Context, Result};
use cable_joint::Config;

use super::{run_seed, Identification, Settings};
use crate::plant::PlantParams;
use crate::report::experiments;
use crate::residual::{self, Analysis, BuildOptions, ModelKind, NamedLog, SelectOptions};

/// Step 7's residual loop: the JAE on the `jae-ident` log, then the
/// tension model on the `tension-ident` log, each judged on the last 30 %
/// of its run (never fitted) and on its regimes ([`JAE_REGIMES`],
/// [`TENSION_REGIMES`]), the selected terms written into
/// `config.jae.added` and `config.tension.added`.
pub struct ResidualStep {
    /// The JAE analysis.
    pub jae: Analysis,
    /// The tension-model analysis.
    pub tension: Analysis,
    /// The configuration with both.
    pub config: Config,
}

/// The runs the JAE's residual loop must not make worse, besides the
/// held-out part of its identification run: another regime each.
pub const JAE_REGIMES: [&str; 2] = ["robust-2n5", "track-jae"];

/// The runs the tension model's residual loop must not make worse, besides
/// the held-out part of its identification run: the run under 2.5 N, whose
/// known load is taken out of the target (a term that reads the load as a
/// change of the model, as a stiffness on `x1` does, would otherwise eat
/// the force estimate under load). Each is one of [`JAE_REGIMES`], whose
/// runs are simulated once for both loops.
pub const TENSION_REGIMES: [&str; 1] = ["robust-2n5"];

/// Run the residual loop on an identification's logs. The JAE's terms are
/// also judged on [`JAE_REGIMES`] (fresh runs on `plant` with the
/// identified configuration and their own seeds): a term that makes one of
/// them worse is set aside (do no harm).
pub fn residual_loop(
    plant: &PlantParams,
    id: &Identification,
    s: &Settings,
    tag: &str,
) -> Result<ResidualStep> {
    let build = BuildOptions {
        holdout: 0.3,
        keep_added: false,
        holdout_with_validate: true,
        ..BuildOptions::default()
    };
    let select = SelectOptions {
        decimate: 0,
        ..SelectOptions::default()
    };
    s.progress.line(
        tag,
        "7/7 residual loop: JAE on jae-ident, tension on tension-ident",
    );
    let jae_log = NamedLog {
        name: "jae-ident".into(),
        log: id.logs.jae.clone(),
    };
    let mut regimes = Vec::new();
    for name in JAE_REGIMES {
        let (log, _) = experiments::logged(
            name,
            plant,
            &id.config,
            run_seed(s.seed, &format!("{name}/regime")),
            s.scale,
        )?;
        regimes.push(NamedLog {
            name: name.into(),
            log,
        });
    }
    let jae = residual::analyse(
        ModelKind::Jae,
        std::slice::from_ref(&jae_log),
        &regimes,
        &id.config,
        build,
        select,
    )
    .context("residual loop on the JAE")?;
    let config = residual::config_with(&jae, &id.config)?;
    let ten_log = NamedLog {
        name: "tension-ident".into(),
        log: id.logs.tension.clone(),
    };
    // The loaded regime judges the no-load tension model with its known
    // load taken out of the target (`f_ext_n`).
    let loaded: Vec<NamedLog> = regimes
        .into_iter()
        .filter(|r| TENSION_REGIMES.contains(&r.name.as_str()))
        .collect();
    // The tension regimes are runs the JAE's loop already simulated.
    debug_assert_eq!(loaded.len(), TENSION_REGIMES.len());
    let tension = residual::analyse(
        ModelKind::Tension,
        std::slice::from_ref(&ten_log),
        &loaded,
        &config,
        build,
        select,
    )
    .context("residual loop on the tension model")?;
    let config = residual::config_with(&tension, &config)?;
    Ok(ResidualStep {
        jae,
        tension,
        config,
    })
}
