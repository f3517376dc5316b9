//! The seed's experimental programme on one simulated plant: the
//! identifications in the seed's order, each feeding the next step's
//! configuration, and the evaluation runs.
//!
//! Here: the settings and run seeds, the steps and what they return. The
//! loading protocol's summary is in `loading_summary.rs`
//! ([`LoadingSummary`]), step 7's residual loop in `residual_loop.rs`
//! ([`residual_loop`]).

mod loading_summary;
mod residual_loop;

use anyhow::{Context, Result};
use cable_joint::Config;

use super::experiments::{self, LoadCase, TrackRun};
use super::progress::Progress;
use crate::ident::{self, BmResult, IdentOptions, JaeResult, TensionResult};
use crate::log::Log;
use crate::plant::PlantParams;
use crate::scenario::{Direction, LOADING_ANGLES_DEG, LOADING_MASSES_G};
use crate::stats::ErrorStats;

pub use loading_summary::{above_1n, at_0n3, AccuracyStats, LoadingSummary};
pub use residual_loop::{residual_loop, ResidualStep, JAE_REGIMES, TENSION_REGIMES};

/// The seed of one run: a mix of the report's seed and the run's label, so
/// every run has its own noise and the same label gets the same noise on
/// every plant and configuration (paired comparisons).
pub fn run_seed(base: u64, label: &str) -> u64 {
    // FNV-1a of the label, then splitmix64.
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in label.bytes() {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    let mut z = base ^ h;
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Settings shared by every run of a report.
#[derive(Clone, Copy, Debug)]
pub struct Settings {
    /// Base seed.
    pub seed: u64,
    /// Duration scale of every scenario.
    pub scale: f64,
    /// Progress output.
    pub progress: Progress,
    /// Run the force sections on drawn plants `first..=last`
    /// ([`crate::report::variants::drawn_variants`]) instead of the report's
    /// ten variants.
    pub draws: Option<(u64, u64)>,
    /// With `draws`: every drawn plant's control rate, Hz (`None`: 2 kHz
    /// for odd seeds, 1 kHz for even ones).
    pub draw_rate_hz: Option<f32>,
    /// The payout stop (`cascade.payout_stop`) on in every plant variant's
    /// identified configuration.
    pub payout_stop: bool,
}

impl Settings {
    /// A full-length report's settings (seed 1, the ten variants) with no
    /// progress lines: what tests and examples run one variant with.
    pub fn quiet() -> Self {
        Self {
            seed: 1,
            scale: 1.0,
            progress: Progress::new(true),
            draws: None,
            draw_rate_hz: None,
            payout_stop: false,
        }
    }
}

/// Logs of the identification runs (kept for the figures and the residual
/// loop).
pub struct IdentLogs {
    /// `bm-noload` (identification).
    pub bm: Log,
    /// `bm-noload`, another seed (verification, Fig. 15).
    pub bm_val: Log,
    /// `jae-ident`.
    pub jae: Log,
    /// `tension-ident`.
    pub tension: Log,
    /// `tension-ident`, another seed, with the identified model (Fig. 18).
    pub tension_val: Log,
}

/// Steps 1, 2 and 5: what was identified.
pub struct Identification {
    /// `B_m` (Sect. 4.2).
    pub bm: BmResult,
    /// `B_m` model on the verification run, N·m.
    pub bm_validation: ErrorStats,
    /// JAE (Sect. 4.1).
    pub jae: JaeResult,
    /// Tension models A/B/C and the simplified model C.
    pub tension: TensionResult,
    /// Every tension model on the verification run, N.
    pub tension_validation: Vec<(String, ErrorStats)>,
    /// Configuration after `B_m` and the JAE (runs the tracking tests).
    pub config_jae: Config,
    /// Configuration after all three (runs the loading protocol).
    pub config: Config,
    /// The logs.
    pub logs: IdentLogs,
    /// Faults latched in identification runs.
    pub faults: Vec<String>,
}

/// Steps 3, 4 and 6: tracking, robustness and the loading protocol.
pub struct Evaluation {
    /// Fig. 10: motor-encoder feedback.
    pub track_motor: TrackRun,
    /// Figs. 11-12: JAE feedback.
    pub track_jae: TrackRun,
    /// Fig. 13: complex trajectory under 2.5 N.
    pub robust: TrackRun,
    /// Figs. 19-26: every case.
    pub loading: Vec<LoadCase>,
    /// Their summary.
    pub loading_summary: LoadingSummary,
    /// The same cases judged on the cable-stretch estimate.
    pub loading_stretch: Vec<LoadCase>,
    /// Their summary.
    pub loading_stretch_summary: LoadingSummary,
}

/// One identification run of the programme: `scenario` on `plant` with
/// `config`, its noise seeded by `label` (a verification run's label ends
/// in `/verify`), `scale` times the report's duration; a fault it latched is
/// noted in `faults`.
fn ident_run(
    plant: &PlantParams,
    s: &Settings,
    faults: &mut Vec<String>,
    (scenario, label, scale): (&str, &str, f64),
    config: &Config,
) -> Result<Log> {
    let (log, f) = experiments::logged(
        scenario,
        plant,
        config,
        run_seed(s.seed, label),
        scale * s.scale,
    )?;
    note_fault(faults, &label.replace("/verify", " (verification)"), f);
    Ok(log)
}

fn note_fault(faults: &mut Vec<String>, what: &str, f: Option<String>) {
    if let Some(f) = f {
        faults.push(format!("{what}: {f}"));
    }
}

/// Steps 1-2: `B_m`, its verification, the JAE, the configuration, and the
/// logs (`bm-noload`, its verification, `jae-ident`).
type BmJaeStep = (BmResult, ErrorStats, JaeResult, Config, Log, Log, Log);

/// Step 5: the tension models, their verification, the configuration, and
/// the logs (identification, verification).
type TensionStep = (TensionResult, Vec<(String, ErrorStats)>, Config, Log, Log);

/// Steps 1 and 2: `B_m` from the no-load motor, then the JAE.
fn identify_bm_jae(
    plant: &PlantParams,
    base: &Config,
    s: &Settings,
    tag: &str,
    faults: &mut Vec<String>,
) -> Result<BmJaeStep> {
    let opts = IdentOptions::default();
    let p = &s.progress;
    // 1. B_m: motor decoupled from the cable (no slack check: ident::decoupled).
    p.line(tag, "1/6 bm-noload: identify B_m (seed Fig. 14-15)");
    let dec = ident::decoupled(base);
    let bm_log = ident_run(plant, s, faults, ("bm-noload", "bm-noload", 1.0), &dec)?;
    let bm = ident::identify_bm_with(&[("bm-noload", &bm_log)], base, &opts)
        .context("identifying B_m")?;
    let mut config = *base;
    bm.apply(&mut config);
    let verify = ("bm-noload", "bm-noload/verify", 0.5);
    let bm_val_log = ident_run(plant, s, faults, verify, &ident::decoupled(&config))?;
    let bm_validation =
        ident::validate_bm(&bm, &bm_val_log, &config, &opts).context("verifying B_m")?;

    // 2. JAE: motor closed loop, joint open loop, magnetic encoder fitted.
    p.line(tag, "2/6 jae-ident: identify the JAE (seed Fig. 8-9)");
    let jae_log = ident_run(plant, s, faults, ("jae-ident", "jae-ident", 1.0), &config)?;
    let jae = ident::identify_jae_with(&[("jae-ident", &jae_log)], &config, &opts)
        .context("identifying the JAE")?;
    jae.apply(&mut config);
    Ok((bm, bm_validation, jae, config, bm_log, bm_val_log, jae_log))
}

/// Step 5: the tension models on the JAE closed loop.
fn identify_tension(
    plant: &PlantParams,
    config_jae: &Config,
    s: &Settings,
    tag: &str,
    faults: &mut Vec<String>,
) -> Result<TensionStep> {
    let opts = IdentOptions::default();
    s.progress.line(
        tag,
        "5/6 tension-ident: models A, B, C and the simplified model C (seed Fig. 16-18)",
    );
    let run = ("tension-ident", "tension-ident", 1.0);
    let mut log = ident_run(plant, s, faults, run, config_jae)?;
    let mut tension = ident::identify_tension_with(&[("tension-ident", &log)], config_jae, &opts)
        .context("identifying the tension models")?;
    let mut config = *config_jae;
    if tension.derivative_from_observer {
        // As a user does on the command's advice: the run again with the
        // derivative from the grating observer, and the models from it.
        faults.push(format!(
            "tension-ident: the current changed by {:.3} A per tick (a limit cycle of the \
             position loop's derivative; model C's friction went unidentified), so the run was \
             recorded again with cascade.kd_on_observer_rate = true",
            tension.current_change_per_tick_a.unwrap_or(f64::NAN)
        ));
        config.cascade.kd_on_observer_rate = true;
        log = ident_run(plant, s, faults, run, &config)?;
        tension = ident::identify_tension_with(&[("tension-ident", &log)], &config, &opts)
            .context("identifying the tension models again")?;
    }
    tension.apply(&mut config);
    let verify = ("tension-ident", "tension-ident/verify", 0.5);
    let val_log = ident_run(plant, s, faults, verify, &config)?;
    let validation = ident::validate_tension(&tension, &val_log, &config, &opts)
        .context("verifying the tension models")?;
    Ok((tension, validation, config, log, val_log))
}

/// Steps 3 and 4: tracking with motor-encoder and JAE feedback, and the
/// robustness test under 2.5 N.
fn tracking(
    plant: &PlantParams,
    config: &Config,
    s: &Settings,
    tag: &str,
) -> Result<(TrackRun, TrackRun, TrackRun)> {
    s.progress.line(
        tag,
        "3/6 track-motor, track-jae: tracking without and with the JAE (seed Fig. 10-12)",
    );
    // Each run has its own noise seed, from its name.
    let run = |name: &'static str| {
        experiments::tracking(name, plant, config, run_seed(s.seed, name), s.scale)
    };
    let tm = run("track-motor")?;
    let tj = run("track-jae")?;
    s.progress.line(
        tag,
        "4/6 robust-2n5: complex trajectory under 2.5 N (seed Fig. 13)",
    );
    let rb = run("robust-2n5")?;
    Ok((tm, tj, rb))
}

/// Steps 1, 2 and 5 alone: the configuration a user identifies on `plant`
/// from `base`, and the faults latched in those runs (with a note when the
/// tension run does not identify model C's friction terms).
pub fn identify_config(
    plant: &PlantParams,
    base: &Config,
    s: &Settings,
    tag: &str,
) -> Result<(Config, Vec<String>)> {
    let mut faults = Vec::new();
    let (_, _, _, config_jae, ..) = identify_bm_jae(plant, base, s, tag, &mut faults)?;
    let (tension, _, config, ..) = identify_tension(plant, &config_jae, s, tag, &mut faults)?;
    faults.extend(
        [
            tension.slider2_at_zero,
            tension.unphysical,
            tension.unidentified,
        ]
        .into_iter()
        .flatten()
        .map(|why| format!("tension-ident: {why}")),
    );
    Ok((config, faults))
}

/// Step 6: every case of the loading protocol, each as its own run.
fn loading(
    plant: &PlantParams,
    config: &Config,
    s: &Settings,
    tag: &str,
    source: experiments::ForceSource,
) -> Result<Vec<LoadCase>> {
    s.progress.line(
        tag,
        &format!("6/6 loading: 0°, 30°, -40° x 30-250 g x both directions (seed Fig. 19-26), {source:?} estimate"),
    );
    let mut cases = Vec::new();
    for a in LOADING_ANGLES_DEG {
        for m in LOADING_MASSES_G {
            for d in [Direction::Pos, Direction::Neg] {
                let label = format!("loading/{a}/{m}/{d:?}");
                cases.push(experiments::loading_case(
                    plant,
                    config,
                    run_seed(s.seed, &label),
                    s.scale,
                    (a, m, d),
                    source,
                )?);
            }
        }
        s.progress.line(tag, &format!("      loading at {a}° done"));
    }
    Ok(cases)
}

/// The whole programme (steps 1-6) on `plant`, starting from `base`.
pub fn programme(
    plant: &PlantParams,
    base: &Config,
    s: &Settings,
    tag: &str,
) -> Result<(Identification, Evaluation)> {
    let mut faults = Vec::new();
    let (bm, bm_validation, jae, config_jae, bm_log, bm_val_log, jae_log) =
        identify_bm_jae(plant, base, s, tag, &mut faults)?;
    let (track_motor, track_jae, robust) = tracking(plant, &config_jae, s, tag)?;
    let (tension, tension_validation, config, tension_log, tension_val_log) =
        identify_tension(plant, &config_jae, s, tag, &mut faults)?;
    let loading_cases = loading(plant, &config, s, tag, experiments::ForceSource::Dob)?;
    let loading_summary = LoadingSummary::of(&loading_cases);
    let loading_stretch = loading(plant, &config, s, tag, experiments::ForceSource::Stretch)?;
    let loading_stretch_summary = LoadingSummary::of(&loading_stretch);
    Ok((
        Identification {
            bm,
            bm_validation,
            jae,
            tension,
            tension_validation,
            config_jae,
            config,
            logs: IdentLogs {
                bm: bm_log,
                bm_val: bm_val_log,
                jae: jae_log,
                tension: tension_log,
                tension_val: tension_val_log,
            },
            faults,
        },
        Evaluation {
            track_motor,
            track_jae,
            robust,
            loading: loading_cases,
            loading_summary,
            loading_stretch,
            loading_stretch_summary,
        },
    ))
}

/// Steps 3, 4 and 6 with a given configuration.
pub fn evaluate(
    plant: &PlantParams,
    config: &Config,
    s: &Settings,
    tag: &str,
) -> Result<Evaluation> {
    let (track_motor, track_jae, robust) = tracking(plant, config, s, tag)?;
    let loading_cases = loading(plant, config, s, tag, experiments::ForceSource::Dob)?;
    let loading_summary = LoadingSummary::of(&loading_cases);
    let loading_stretch = loading(plant, config, s, tag, experiments::ForceSource::Stretch)?;
    let loading_stretch_summary = LoadingSummary::of(&loading_stretch);
    Ok(Evaluation {
        track_motor,
        track_jae,
        robust,
        loading: loading_cases,
        loading_summary,
        loading_stretch,
        loading_stretch_summary,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn run_seeds_are_stable_and_distinct() {
        // Fixed values: a change would silently change every report. Known
        // answers from outside this code: FNV-1a of "" is its offset basis
        // and of "a" 0xaf63dc4c8601ec8c (the published test vectors), so
        // both labels below take splitmix64 to state 0, whose first output
        // is the published 0xe220a8397b1dcdaf; the report's "track-jae"
        // seed at base 1 was computed by a separate Python implementation
        // of both.
        const SPLITMIX64_AT_0: u64 = 0xe220_a839_7b1d_cdaf;
        const FNV_BASIS: u64 = 0xcbf2_9ce4_8422_2325;
        assert_eq!(run_seed(FNV_BASIS, ""), SPLITMIX64_AT_0);
        assert_eq!(run_seed(0xaf63_dc4c_8601_ec8c, "a"), SPLITMIX64_AT_0);
        assert_eq!(run_seed(1, "track-jae"), 0x7a1f_3021_f685_6e00);
        let labels = [
            "bm-noload",
            "jae-ident",
            "track-jae",
            "loading/0/30/Pos",
            "loading/0/30/Neg",
        ];
        let mut seeds: Vec<u64> = labels.iter().map(|l| run_seed(1, l)).collect();
        seeds.extend(labels.iter().map(|l| run_seed(2, l)));
        let n = seeds.len();
        seeds.sort_unstable();
        seeds.dedup();
        assert_eq!(seeds.len(), n, "two runs share a noise seed");
    }
}
