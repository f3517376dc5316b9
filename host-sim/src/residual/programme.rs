//! The undeclared-effect programme (issue 12, item 5): does the residual
//! loop name an effect its models lack, and cut the error it causes, on
//! plants it was never tuned on and at the sizes a real joint shows?
//!
//! For every drawn plant (every force-path parameter ±30 %,
//! [`crate::report::variants::drawn`], on seeds no test or default was
//! tuned on) and every control rate:
//!
//! 1. a clean calibration run (`jae-ident`, 42 s) gives the declared model:
//!    the JAE and model C, each with the terms the loop finds on clean data
//!    (at most 4, as `host-sim report` does);
//! 2. the same run, same noise, with one effect on, then with every pair, at
//!    each size ([`Size`]); the loop continues from the declared model (at
//!    most 8 terms) and is judged on the held-out last 30 % of the run;
//! 3. the loop also runs, the same way, on the clean run: what it adds there
//!    is what the declared model (at most 4 terms) still lacks on this plant,
//!    not the effect, so those terms (same kind on the same signal) are set
//!    apart from the effect run's;
//! 4. per effect and model: is the effect visible at all (does it raise the
//!    declared model's validation error to at least [`VISIBLE_RISE`] times
//!    the clean run's?), the family of the first term the loop adds that it
//!    did not add on the clean run, every family it adds, the validation
//!    error before and after, and the share of the effect's excess error
//!    (before, less the clean run's) it removed.
//!
//! Each effect acts on one model's target: cable creep and spring
//! hardening move the joint angle the JAE predicts from slider 2; presliding
//! friction, winding heating and the current sensor's drift move the tension
//! model C predicts from the motor. A case's verdict for an effect is read
//! on that model only.

use anyhow::{Context, Result};
use cable_joint::Config;
use serde::Serialize;

use super::outcome::Step;
use super::select::OBSERVER_FILTERING;
use super::{analyse, config_with, Analysis, BuildOptions, ModelKind, NamedLog, SelectOptions};
use crate::plant::{Creep, OffsetDrift, PlantParams, Presliding, SpringHardening, Thermal};
use crate::report::programme::run_seed;
use crate::scenario::{self, SimulateOptions};

/// An effect is visible when it raises the declared model's validation
/// RMSE to at least this many times the clean run's (the same plant, noise
/// and trajectory without the effect). Below, the loop has nothing to find
/// and the case says so instead of counting a miss.
pub const VISIBLE_RISE: f64 = 1.2;

/// The two models, in the order the programme keeps their references.
const TARGETS: [Target; 2] = [Target::Jae, Target::Tension];

/// The model an effect moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Target {
    /// The joint-angle estimator (`theta_rad` from slider 2).
    Jae,
    /// Model C (`tension1_hat_n` from the motor).
    Tension,
}

impl Target {
    fn kind(self) -> ModelKind {
        match self {
            Target::Jae => ModelKind::Jae,
            Target::Tension => ModelKind::Tension,
        }
    }

    /// The model's name.
    pub fn name(self) -> &'static str {
        match self {
            Target::Jae => "JAE",
            Target::Tension => "tension",
        }
    }
}

/// How large an effect is made.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Size {
    /// The plant's defaults, each from a datasheet or a measured order of
    /// magnitude ([`crate::plant::Effects`]).
    Datasheet,
    /// The upper end of the physical range, stated per effect
    /// ([`Effect::upper`]).
    Upper,
}

impl Size {
    /// Its name.
    pub fn name(self) -> &'static str {
        match self {
            Size::Datasheet => "datasheet",
            Size::Upper => "upper",
        }
    }
}

/// The plant effects the programme switches on, one per field of
/// [`crate::plant::Effects`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// Wire-rope creep ([`Creep`]).
    Creep,
    /// A hardening return spring ([`SpringHardening`]).
    Spring,
    /// Presliding friction ([`Presliding`]).
    Presliding,
    /// Winding heating ([`Thermal`]).
    Thermal,
    /// Current-sensor offset drift ([`OffsetDrift`]).
    Drift,
}

impl Kind {
    /// Its name, as `simulate --effect` takes it.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Creep => "creep",
            Kind::Spring => "spring",
            Kind::Presliding => "presliding",
            Kind::Thermal => "thermal",
            Kind::Drift => "drift",
        }
    }
}

/// An effect the estimators' models lack.
#[derive(Clone, Copy, Debug)]
pub struct Effect {
    /// Which plant effect.
    pub kind: Kind,
    /// The model it moves.
    pub target: Target,
    /// The family a term explaining it belongs to
    /// ([`effect_class`](super::families::effect_class)).
    pub class: &'static str,
    /// The physics of the datasheet size.
    pub datasheet: &'static str,
    /// The physics of the upper size.
    pub upper: &'static str,
}

/// The five effects the plant can add.
pub const EFFECTS: [Effect; 5] = [
    Effect {
        kind: Kind::Creep,
        target: Target::Jae,
        class: "creep / relaxation",
        datasheet: "steel wire rope: strand bedding, 10 % of the elastic stretch, 30 s",
        upper: "polymer-core or fibre rope: 30 % of the elastic stretch, 10 s",
    },
    Effect {
        kind: Kind::Spring,
        target: Target::Jae,
        class: "stiffness",
        datasheet: "cylindrical coil spring: k3 = 3.6e6 N/m³, 5 % extra force at 3 mm",
        upper: "progressive (conical or variable-pitch) spring: k3 = 1.8e7 N/m³, 25 % at 3 mm",
    },
    Effect {
        kind: Kind::Presliding,
        target: Target::Tension,
        class: "hysteresis",
        datasheet: "rolling guides 20 µm, pin 3 mrad (LuGre)",
        upper: "rolling guides 50 µm (the upper end of 10-50 µm), a worn pin 10 mrad",
    },
    Effect {
        kind: Kind::Thermal,
        target: Target::Tension,
        class: "thermal",
        datasheet: "25 mm motor: 2.3 Ω, 12.5 s winding, 600 s housing, K_m -0.4 %/K",
        upper: "16 mm motor: 7 Ω, 6 s winding, 30 K/W to ambient, K_m -0.4 %/K",
    },
    Effect {
        kind: Kind::Drift,
        target: Target::Tension,
        class: "drift",
        datasheet: "current-sensor offset 0.1 mA/s ramp, 0.2 mA/√s walk",
        upper: "a Hall sensor warming up: 0.5 mA/s (30 mA a minute)",
    },
];

impl Effect {
    /// Its name, as `simulate --effect` takes it.
    pub fn name(&self) -> &'static str {
        self.kind.name()
    }

    /// Switch this effect on in `p` at `size`.
    pub fn apply(&self, p: &mut PlantParams, size: Size) {
        let e = &mut p.effects;
        let upper = size == Size::Upper;
        match self.kind {
            Kind::Creep => {
                let mut c = Creep::default();
                if upper {
                    c.ratio = 0.3;
                    c.tau_s = 10.0;
                }
                e.creep = Some(c);
            }
            Kind::Spring => {
                let mut s = SpringHardening::default();
                if upper {
                    s.cubic_n_m3 = 1.8e7;
                }
                e.spring_hardening = Some(s);
            }
            Kind::Presliding => {
                let mut s = Presliding::default();
                if upper {
                    s.slider_presliding_m = 50e-6;
                    s.joint_presliding_rad = 1e-2;
                }
                e.presliding = Some(s);
            }
            Kind::Thermal => {
                let mut t = Thermal::default();
                if upper {
                    t.resistance_ohm = 7.0;
                    t.tau_winding_s = 6.0;
                    t.housing_ambient_k_w = 30.0;
                }
                e.thermal = Some(t);
            }
            Kind::Drift => {
                let mut d = OffsetDrift::default();
                if upper {
                    d.rate_a_s = 5e-4;
                }
                e.offset_drift = Some(d);
            }
        }
    }
}

/// The programme's settings.
#[derive(Clone, Debug)]
pub struct ProgrammeOptions {
    /// Seeds of the drawn plants.
    pub draws: Vec<u64>,
    /// Control rates, Hz.
    pub rates_hz: Vec<f32>,
    /// Effect sizes.
    pub sizes: Vec<Size>,
    /// Also every pair of effects.
    pub pairs: bool,
    /// Base of every run's noise seed.
    pub seed: u64,
    /// Progress lines on stderr.
    pub progress: bool,
    /// Every run recorded as the board streams it: a row every this many
    /// control ticks, with `tick` and the mean current since the row before
    /// (`sim::recorded_every`); 1 is every tick.
    pub record_every: usize,
}

impl Default for ProgrammeOptions {
    fn default() -> Self {
        Self {
            draws: vec![31, 32],
            rates_hz: vec![2000.0, 1000.0],
            sizes: vec![Size::Datasheet, Size::Upper],
            pairs: true,
            seed: 1,
            progress: true,
            record_every: 1,
        }
    }
}

/// One case on one model: what the loop found against what was there.
#[derive(Clone, Debug, Serialize)]
pub struct CaseRow {
    /// The effects switched on.
    pub effects: Vec<&'static str>,
    /// Their size.
    pub size: Size,
    /// Control rate, Hz.
    pub rate_hz: f32,
    /// Seed of the drawn plant.
    pub draw: u64,
    /// The model judged.
    pub model: Target,
    /// The families of the effects that act on this model.
    pub expected: Vec<&'static str>,
    /// Validation RMSE of the declared model on the clean run.
    pub clean_rmse: f64,
    /// Validation RMSE of the declared model on this run.
    pub before_rmse: f64,
    /// Validation RMSE after the loop's terms.
    pub after_rmse: f64,
    /// Share of the effect's excess error removed,
    /// `(before - after) / (before - clean)`.
    pub excess_removed: f64,
    /// The verdict.
    pub verdict: Verdict,
    /// Every term added, in order (label).
    pub terms: Vec<String>,
    /// Their families, in order.
    pub classes: Vec<String>,
    /// Which of them the loop also added on the clean run (the declared
    /// model's own deficit on this plant, not the effect).
    pub also_clean: Vec<bool>,
    /// A rival family for the first term the verdict counts (neither kept
    /// on the clean run too nor observer filtering), when the data do not
    /// tell them apart.
    pub rival: Option<String>,
}

/// What a case shows for its model.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// The effects raise the validation error by less than
    /// [`VISIBLE_RISE`]: nothing to find, whatever was added.
    BelowNoise,
    /// Visible, and every expected family is among the terms added (for a
    /// single effect: it is the first one).
    Named,
    /// Visible, and an expected family is missing (or, for a single effect,
    /// not first).
    Missed,
}

/// The verdict for one model: `expected` families against the `classes`
/// added (in order; those the loop also added on the clean run, marked in
/// `also_clean`, and those that stand in for the core's observer,
/// [`OBSERVER_FILTERING`], do not count), with the validation errors of
/// the clean run and of this run before the loop.
pub fn verdict(
    expected: &[&str],
    classes: &[String],
    also_clean: &[bool],
    clean_rmse: f64,
    before_rmse: f64,
) -> Verdict {
    // NaN (no clean reference) is below the noise too.
    let visible = before_rmse >= VISIBLE_RISE * clean_rmse;
    if !visible {
        return Verdict::BelowNoise;
    }
    let new: Vec<&String> = counted(classes.iter().map(String::as_str), also_clean)
        .map(|k| &classes[k])
        .collect();
    let named = match expected {
        [one] => new.first().is_some_and(|c| c == one),
        many => many.iter().all(|e| new.iter().any(|c| c == e)),
    };
    if named {
        Verdict::Named
    } else {
        Verdict::Missed
    }
}

/// The positions of the kept terms [`verdict`] counts, in order: not
/// kept on the clean run too (`also_clean`, missing entries false), not
/// [`OBSERVER_FILTERING`].
fn counted<'a>(
    classes: impl Iterator<Item = &'a str> + 'a,
    also_clean: &'a [bool],
) -> impl Iterator<Item = usize> + 'a {
    classes
        .zip(also_clean.iter().chain(std::iter::repeat(&false)))
        .enumerate()
        .filter(|(_, (c, clean))| !**clean && *c != OBSERVER_FILTERING)
        .map(|(k, _)| k)
}

/// The first kept step [`verdict`] counts (the term whose rival family
/// the row names).
fn first_counted<'a>(accepted: &'a [Step], also_clean: &[bool]) -> Option<&'a Step> {
    counted(accepted.iter().map(|s| s.class.as_str()), also_clean)
        .next()
        .map(|k| &accepted[k])
}

/// What one drawn plant's clean run gave, per model.
#[derive(Clone, Debug, Serialize)]
pub struct CleanRef {
    /// Seed of the drawn plant.
    pub draw: u64,
    /// Control rate, Hz.
    pub rate_hz: f32,
    /// The model.
    pub model: Target,
    /// The declared model's terms (the loop on the clean run from the
    /// datasheet model, at most 4).
    pub declared: Vec<String>,
    /// The declared model's validation RMSE on the clean run.
    pub rmse: f64,
    /// What the loop adds to the declared model on the same clean run.
    pub added: Vec<String>,
}

/// The programme's result.
#[derive(Clone, Debug, Serialize)]
pub struct Programme {
    /// Every drawn plant's clean reference.
    pub clean: Vec<CleanRef>,
    /// Every case on every model it touches.
    pub rows: Vec<CaseRow>,
    /// Visibility threshold used.
    pub visible_rise: f64,
    /// Every run recorded with a row every this many control ticks.
    pub record_every: usize,
}

/// The calibration run (`jae-ident`) through `host-sim simulate`'s own
/// path, recorded with a row every `every` control ticks as `simulate
/// --record-every` writes it (every tick: the simulator's own log).
fn simulate(plant: PlantParams, config: Config, seed: u64, every: usize) -> Result<NamedLog> {
    let opts = SimulateOptions {
        scenario: "jae-ident".to_owned(),
        seed: Some(seed),
        ..SimulateOptions::default()
    };
    let log = scenario::simulate(plant, config, &opts)?.log.to_log()?;
    Ok(NamedLog {
        name: opts.scenario.clone(),
        log: match every {
            0 | 1 => log,
            n => crate::sim::recorded_every(&log, n, true)?,
        },
    })
}

fn fit(
    target: Target,
    log: &NamedLog,
    config: &Config,
    keep: bool,
    max: usize,
) -> Result<Analysis> {
    analyse(
        target.kind(),
        std::slice::from_ref(log),
        &[],
        config,
        BuildOptions {
            holdout: 0.3,
            keep_added: keep,
            ..BuildOptions::default()
        },
        SelectOptions {
            max_terms: max,
            decimate: 0,
            ..SelectOptions::default()
        },
    )
}

/// The cases: every effect alone, then (with `pairs`) every pair.
pub fn cases(pairs: bool) -> Vec<Vec<Effect>> {
    let mut out: Vec<Vec<Effect>> = EFFECTS.iter().map(|e| vec![*e]).collect();
    if pairs {
        for (i, a) in EFFECTS.iter().enumerate() {
            for b in &EFFECTS[i + 1..] {
                out.push(vec![*a, *b]);
            }
        }
    }
    out
}

/// Run the programme.
///
/// # Errors
/// A simulation or an analysis that fails (named with its case).
pub fn run(opts: &ProgrammeOptions) -> Result<Programme> {
    let cases = cases(opts.pairs);
    let total = opts.draws.len() * opts.rates_hz.len() * (1 + opts.sizes.len() * cases.len());
    let mut done = 0usize;
    let started = std::time::Instant::now();
    let mut rows = Vec::new();
    let mut refs = Vec::new();
    for &draw in &opts.draws {
        let base = crate::report::variants::drawn(draw);
        for &rate_hz in &opts.rates_hz {
            let (config, _) = scenario::tuned_gains(&Config::default()).at_rate(rate_hz);
            let seed = run_seed(opts.seed, &format!("undeclared/{draw}/{rate_hz}"));
            let tag = format!("draw {draw}, {rate_hz} Hz");
            let clean = simulate(base, config, seed, opts.record_every)
                .with_context(|| format!("{tag}: clean run"))?;
            let jae = fit(Target::Jae, &clean, &config, false, 4)?;
            let with_jae = config_with(&jae, &config)?;
            let tension = fit(Target::Tension, &clean, &with_jae, false, 4)?;
            let declared = config_with(&tension, &with_jae)?;
            // The loop on the clean run, from the declared model: the
            // reference error, and the terms that are not the effect's (kind
            // and signal), per model in the order of `TARGETS`.
            let mut clean_rmse = [f64::NAN; 2];
            let mut clean_keys: [Vec<(&'static str, u8)>; 2] = Default::default();
            for (i, first) in [&jae, &tension].into_iter().enumerate() {
                let target = TARGETS[i];
                let a = fit(target, &clean, &declared, true, 8)
                    .with_context(|| format!("{tag}: clean run, {}", target.name()))?;
                clean_rmse[i] = a.outcome.baseline.val_rmse;
                clean_keys[i] = a
                    .outcome
                    .accepted
                    .iter()
                    .map(|s| (s.term.kind.name(), s.term.input))
                    .collect();
                refs.push(CleanRef {
                    draw,
                    rate_hz,
                    model: target,
                    declared: first
                        .outcome
                        .accepted
                        .iter()
                        .map(|s| s.label.clone())
                        .collect(),
                    rmse: a.outcome.baseline.val_rmse,
                    added: a.outcome.accepted.iter().map(|s| s.label.clone()).collect(),
                });
            }
            done += 1;
            for &size in &opts.sizes {
                for case in &cases {
                    let mut plant = base;
                    for e in case {
                        e.apply(&mut plant, size);
                    }
                    let names: Vec<&'static str> = case.iter().map(|e| e.name()).collect();
                    let label = format!("{tag}, {} {}", names.join(" + "), size.name());
                    let log = simulate(plant, config, seed, opts.record_every)
                        .with_context(|| label.clone())?;
                    for (i, target) in TARGETS.into_iter().enumerate() {
                        let expected: Vec<&'static str> = case
                            .iter()
                            .filter(|e| e.target == target)
                            .map(|e| e.class)
                            .collect();
                        if expected.is_empty() {
                            continue;
                        }
                        let a = fit(target, &log, &declared, true, 8)
                            .with_context(|| format!("{label}: {}", target.name()))?;
                        let o = &a.outcome;
                        let (clean_rmse, clean_keys) = (clean_rmse[i], &clean_keys[i]);
                        let classes: Vec<String> =
                            o.accepted.iter().map(|s| s.class.clone()).collect();
                        let also_clean: Vec<bool> = o
                            .accepted
                            .iter()
                            .map(|s| clean_keys.contains(&(s.term.kind.name(), s.term.input)))
                            .collect();
                        let (before, after) = (o.baseline.val_rmse, o.final_fit.val_rmse);
                        let rival = first_counted(&o.accepted, &also_clean)
                            .and_then(|s| s.rival.as_ref())
                            .map(|r| r.class.clone());
                        let row = CaseRow {
                            effects: names.clone(),
                            size,
                            rate_hz,
                            draw,
                            model: target,
                            verdict: verdict(&expected, &classes, &also_clean, clean_rmse, before),
                            expected,
                            clean_rmse,
                            before_rmse: before,
                            after_rmse: after,
                            excess_removed: (before - after) / (before - clean_rmse),
                            terms: o.accepted.iter().map(|s| s.label.clone()).collect(),
                            classes,
                            also_clean,
                            rival,
                        };
                        rows.push(row);
                    }
                    done += 1;
                    if opts.progress {
                        eprintln!(
                            "[{done}/{total}, {:.0} s] {label}",
                            started.elapsed().as_secs_f64()
                        );
                    }
                }
            }
        }
    }
    Ok(Programme {
        clean: refs,
        rows,
        visible_rise: VISIBLE_RISE,
        record_every: opts.record_every.max(1),
    })
}

/// A summary line per size and rate: single effects visible, named first,
/// and with the validation error at most half of before; pairs named.
pub fn summary(p: &Programme) -> Vec<String> {
    let mut keys: Vec<(Size, u32)> = Vec::new();
    for r in &p.rows {
        let k = (r.size, r.rate_hz as u32);
        if !keys.contains(&k) {
            keys.push(k);
        }
    }
    keys.iter()
        .map(|&(size, rate)| {
            let of = |single: bool| {
                p.rows
                    .iter()
                    .filter(move |r| {
                        r.size == size && r.rate_hz as u32 == rate && (r.effects.len() == 1) == single
                    })
                    .collect::<Vec<_>>()
            };
            let singles = of(true);
            let visible: Vec<_> = singles
                .iter()
                .filter(|r| r.verdict != Verdict::BelowNoise)
                .collect();
            let named = visible.iter().filter(|r| r.verdict == Verdict::Named).count();
            let halved = visible
                .iter()
                .filter(|r| r.after_rmse <= 0.5 * r.before_rmse)
                .count();
            let excess = visible
                .iter()
                .filter(|r| r.excess_removed >= 0.5)
                .count();
            let pairs = of(false);
            let pv: Vec<_> = pairs
                .iter()
                .filter(|r| r.verdict != Verdict::BelowNoise)
                .collect();
            let pn = pv.iter().filter(|r| r.verdict == Verdict::Named).count();
            format!(
                "{} size, {rate} Hz: single effects visible {}/{}; of those named first {named}, error halved {halved}, half the effect's excess removed {excess}; pairs (per model) visible {}/{}, every family named {pn}/{}",
                size.name(),
                visible.len(),
                singles.len(),
                pv.len(),
                pairs.len(),
                pv.len()
            )
        })
        .collect()
}

/// The programme as Markdown: the method, the sizes with their physics,
/// the summary, and every case.
pub fn markdown(p: &Programme) -> String {
    use std::fmt::Write;
    let mut s = String::from("# Undeclared effects: the residual loop on drawn plants\n\n");
    let _ = writeln!(
        s,
        "Each case: a 42 s calibration run (`jae-ident`) of a drawn plant (every force-path \
         parameter ±30 %) with the effects on, the loop continuing from the model declared on the \
         same plant's clean run, judged on the held-out last 30 %. An effect is *visible* when it \
         raises the declared model's validation RMSE to at least {:.1}× the clean run's; below that \
         the loop has nothing to find and the case is not counted. The loop also runs on the \
         clean run: the terms it adds there (same kind on the same signal) are the declared \
         model's own deficit on this plant, marked and not counted. *Named*: a single effect's \
         family is the first of the other terms; for a pair, every family on that model is among \
         them. *Excess removed*: `(before - after) / (before - clean)`.\n",
        p.visible_rise
    );
    if p.record_every > 1 {
        let _ = writeln!(
            s,
            "Every run is recorded as the board streams it: a row every {} control ticks with \
             `tick` and the mean current since the row before (`simulate --record-every {}`); the \
             loop replays each log tick by tick and judges its own rows only.\n",
            p.record_every, p.record_every
        );
    }
    let _ = writeln!(
        s,
        "| effect | model | family | datasheet size | upper size |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|");
    for e in EFFECTS {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} |",
            e.name(),
            e.target.name(),
            e.class,
            e.datasheet,
            e.upper
        );
    }
    let _ = writeln!(s, "\n## Summary\n");
    for l in summary(p) {
        let _ = writeln!(s, "* {l}");
    }
    let _ = writeln!(s, "\n## The clean runs\n");
    let _ = writeln!(
        s,
        "| draw | rate | model | declared terms | validation RMSE | the loop adds on the clean run |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|");
    for c in &p.clean {
        let list = |v: &[String]| {
            if v.is_empty() {
                "none".to_owned()
            } else {
                v.iter()
                    .map(|t| format!("`{t}`"))
                    .collect::<Vec<_>>()
                    .join(", ")
            }
        };
        let (u, k) = match c.model {
            Target::Jae => ("°", 180.0 / std::f64::consts::PI),
            Target::Tension => (" N", 1.0),
        };
        let _ = writeln!(
            s,
            "| {} | {} Hz | {} | {} | {:.4}{u} | {} |",
            c.draw,
            c.rate_hz,
            c.model.name(),
            list(&c.declared),
            c.rmse * k,
            list(&c.added)
        );
    }
    let _ = writeln!(s, "\n## Every case\n");
    let _ = writeln!(
        s,
        "| effects | size | rate | draw | model | rise over clean | verdict | terms added (families) | validation RMSE before → after | excess removed |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|");
    for r in &p.rows {
        let terms = if r.terms.is_empty() {
            "none".to_owned()
        } else {
            r.terms
                .iter()
                .zip(&r.classes)
                .zip(&r.also_clean)
                .map(|((t, c), clean)| {
                    let mark = if *clean {
                        ", also on the clean run"
                    } else {
                        ""
                    };
                    format!("`{t}` ({c}{mark})")
                })
                .collect::<Vec<_>>()
                .join(", ")
        };
        let rival = r
            .rival
            .as_ref()
            .map(|c| format!("; {c} as likely"))
            .unwrap_or_default();
        let unit = match r.model {
            Target::Jae => ("°", 180.0 / std::f64::consts::PI),
            Target::Tension => (" N", 1.0),
        };
        let _ = writeln!(
            s,
            "| {} | {} | {} Hz | {} | {} | ×{:.2} | {:?} | {terms}{rival} | {:.4}{u} → {:.4}{u} | {:.0} % |",
            r.effects.join(" + "),
            r.size.name(),
            r.rate_hz,
            r.draw,
            r.model.name(),
            r.before_rmse / r.clean_rmse,
            r.verdict,
            r.before_rmse * unit.1,
            r.after_rmse * unit.1,
            100.0 * r.excess_removed,
            u = unit.0
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(classes: &[&str]) -> Vec<String> {
        classes.iter().map(|c| (*c).to_owned()).collect()
    }

    #[test]
    fn an_effect_that_does_not_raise_the_error_is_below_the_noise_whatever_was_added() {
        assert_eq!(
            verdict(&["thermal"], &v(&["thermal"]), &[], 1.0, 1.19),
            Verdict::BelowNoise
        );
        assert_eq!(
            verdict(&["thermal"], &v(&[]), &[], 1.0, 1.2),
            Verdict::Missed
        );
        assert_eq!(
            verdict(&["thermal"], &v(&["thermal"]), &[false], 1.0, 1.2),
            Verdict::Named
        );
    }

    #[test]
    fn a_term_that_stands_in_for_the_observer_does_not_count_as_the_first() {
        let e = ["creep / relaxation"];
        let classes = v(&[OBSERVER_FILTERING, "creep / relaxation"]);
        assert_eq!(
            verdict(&e, &classes, &[false, false], 1.0, 3.0),
            Verdict::Named
        );
        assert_eq!(
            verdict(&e, &v(&[OBSERVER_FILTERING]), &[false], 1.0, 3.0),
            Verdict::Missed
        );
    }

    /// A kept step of family `class` whose rival family is `rival`.
    fn kept(class: &str, rival: &str) -> Step {
        Step {
            term: cable_joint::effects::Term::new(cable_joint::effects::EffectKind::Linear, 0),
            candidate: 0,
            label: format!("a {class} term"),
            meaning: "",
            err: 0.5,
            fit: super::super::outcome::ModelFit {
                coefs: Vec::new(),
                train_rmse: 1.0,
                val_rmse: 1.0,
                condition: 1.0,
            },
            gain: 0.2,
            class: class.to_owned(),
            rival: Some(super::super::outcome::Rival {
                label: format!("a {rival} term"),
                class: rival.to_owned(),
                err: 0.45,
            }),
            passed_over: Vec::new(),
            harm: None,
            evidence: None,
            unfiltered_gain: None,
            reclassified_from: None,
            group: None,
        }
    }

    /// The row's rival family is the one of the term the verdict counts
    /// first: not a term the clean run kept too, not observer filtering.
    #[test]
    fn the_rival_named_is_the_first_counted_terms() {
        let steps = [
            kept("stiffness", "drift"),
            kept(OBSERVER_FILTERING, "friction"),
            kept("creep / relaxation", "thermal"),
        ];
        let first = |clean: &[bool]| {
            first_counted(&steps, clean)
                .and_then(|s| s.rival.as_ref())
                .map(|r| r.class.as_str())
        };
        assert_eq!(first(&[false, false, false]), Some("drift"));
        assert_eq!(first(&[true]), Some("thermal"));
        assert_eq!(first(&[true, false, true]), None);
    }

    #[test]
    fn a_single_effect_is_named_only_when_its_family_comes_first() {
        let e = ["creep / relaxation"];
        assert_eq!(
            verdict(
                &e,
                &v(&["stiffness", "creep / relaxation"]),
                &[false, false],
                1.0,
                3.0
            ),
            Verdict::Missed
        );
        assert_eq!(
            verdict(
                &e,
                &v(&["creep / relaxation", "stiffness"]),
                &[false, false],
                1.0,
                3.0
            ),
            Verdict::Named
        );
        // A term the loop adds on the clean run too is the declared model's
        // deficit: the effect's family after it still comes first.
        assert_eq!(
            verdict(
                &e,
                &v(&["stiffness", "creep / relaxation"]),
                &[true, false],
                1.0,
                3.0
            ),
            Verdict::Named
        );
    }

    #[test]
    fn a_pair_on_one_model_is_named_when_both_families_are_among_the_terms() {
        let e = ["thermal", "drift"];
        assert_eq!(
            verdict(&e, &v(&["drift", "load", "thermal"]), &[false; 3], 1.0, 2.0),
            Verdict::Named
        );
        assert_eq!(
            verdict(&e, &v(&["drift", "load"]), &[false; 2], 1.0, 2.0),
            Verdict::Missed
        );
        assert_eq!(
            verdict(&e, &v(&["drift", "thermal"]), &[false, true], 1.0, 2.0),
            Verdict::Missed,
            "a family found only in a term the clean run has too does not count"
        );
    }

    #[test]
    fn every_effect_alone_and_every_pair_once_each_acting_on_its_model() {
        let c = cases(true);
        assert_eq!(c.len(), 5 + 10);
        let mut names: Vec<String> = c
            .iter()
            .map(|k| k.iter().map(|e| e.name()).collect::<Vec<_>>().join("+"))
            .collect();
        names.sort();
        names.dedup();
        assert_eq!(names.len(), 15);
        // Each size switches on exactly its effect, the upper size larger.
        for e in EFFECTS {
            let mut d = PlantParams::default();
            e.apply(&mut d, Size::Datasheet);
            let mut u = PlantParams::default();
            e.apply(&mut u, Size::Upper);
            assert_eq!(d.effects.enabled(), vec![e.name()], "{}", e.name());
            assert_eq!(u.effects.enabled(), vec![e.name()], "{}", e.name());
            assert_ne!(d, u, "{}: the upper size differs", e.name());
        }
    }

    #[test]
    fn a_run_recorded_as_the_board_streams_it_keeps_every_tenth_tick_with_its_tick() {
        let plant = crate::report::variants::drawn(31);
        let config = scenario::tuned_gains(&Config::default());
        let every = simulate(plant, config, 5, 1).unwrap().log;
        let tenth = simulate(plant, config, 5, 10).unwrap().log;
        assert_eq!(tenth.len(), every.len().div_ceil(10));
        let tick = tenth.col_required("tick").unwrap();
        assert_eq!((tick[0], tick[1], tick[7]), (0.0, 10.0, 70.0));
        assert!(tenth.col("i_applied_a").is_some());
        let theta = |l: &crate::log::Log, k: usize| l.col_required("theta_rad").unwrap()[k];
        assert_eq!(theta(&tenth, 7), theta(&every, 70));
    }
}
