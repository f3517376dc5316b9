//! `host-sim report` (the default command): the seed's whole experimental
//! programme (seed 000 Sect. 4) on the simulated prototype, through the core
//! the firmware runs, with a report to put beside the paper.
//!
//! ```text
//! cargo run --release -p host-sim                       # = host-sim report
//! host-sim report --out report --seed 1 [--duration-scale 1] [--no-effects] [--effect creep,thermal]
//! ```
//!
//! Steps, in the seed's order, each identification feeding the next step's
//! configuration (nothing is taken from the plant's true parameters):
//!
//! 1. `bm-noload`: `B_m` with the motor unhooked ([`crate::ident::identify_bm_with`],
//!    replayed with [`crate::ident::decoupled`]); verified on another run → the DOB.
//! 2. `jae-ident`: the JAE (Eq. 25-26), motor closed loop, joint open loop,
//!    magnetic encoder fitted → the joint closed loop.
//! 3. `track-motor`, `track-jae`: tracking without and with the JAE (Figs. 10-12).
//! 4. `robust-2n5`: the complex trajectory under 2.5 N (Fig. 13).
//! 5. `tension-ident`: models A, B, C and the simplified model C by `%σ`
//!    pruning (Figs. 16-18), verified on another run → the force estimator.
//! 6. `loading`: 0°, 30°, −40° × 30-250 g × both directions, each case its own
//!    run; no-load (static, dynamic), loading and stable regions; accuracy per
//!    load (Figs. 19-26).
//! 7. The programme again on the plant with the simulator's unmodelled effects
//!    on: first with the seed's models, then after the residual loop
//!    ([`crate::residual`]) added the effects it found to `config.jae.added`
//!    and `config.tension.added`.
//!
//! Output: a table on stdout (the seed's figure, this project's, the ratio),
//! progress lines on stderr, and in `--out` (default `report/`): `report.md`
//! (tables, goals, embedded plots), `report.json` (every figure under
//! `figures` with stable keys), the plots as SVG and PNG, and the identified
//! configurations (`config_clean.toml`, `config_effects_*.toml`), and for
//! every plant variant its plant and identified configuration
//! (`variants/<name>/plant.toml`, `config.toml`, `config_probing.toml`), from
//! which `host-sim simulate` reruns any loading case with the seed the report
//! prints beside its fault. Every file is
//! written through a temporary file and renamed. Results depend only on
//! `--seed` and `--duration-scale` (each run's noise seed is derived from
//! `--seed` and the run's name); the clean and the effects programmes run on
//! two threads.

pub mod excitation;
pub mod experiments;
pub mod figures;
pub mod free_motion;
pub mod goals;
pub mod grip;
pub mod kalman;
pub mod keys;
pub mod markdown;
pub mod programme;
pub mod progress;
pub mod regressors;
pub mod render;
pub mod seed;
pub mod variants;
pub mod weigh;
pub mod wrist;

use std::path::{Path, PathBuf};

use anyhow::{ensure, Result};
use cable_joint::Config;

use crate::io::config::stage_config;
use crate::log::Log;
use crate::output::Outputs;
use crate::plant::{Effects, PlantParams};
use crate::stats::{Acc, Summary, DEG_PER_RAD};
use figures::Written;
use programme::{Evaluation, Identification, ResidualStep, Settings};
use progress::Progress;

/// What `host-sim report` runs (the command line is
/// [`crate::cli::report`]).
#[derive(Debug, Clone, PartialEq)]
pub struct ReportOptions {
    /// Output directory (created if missing).
    pub out: PathBuf,
    /// Base seed of every run's noise.
    pub seed: u64,
    /// Scale of every scenario's duration (1 = the full programme; refused
    /// up front when one run would exceed `simulate`'s 1e6-tick limit,
    /// above about 11.9).
    pub duration_scale: f64,
    /// Skip step 7 (unmodelled effects and the residual loop).
    pub no_effects: bool,
    /// Effects switched on in step 7 (default, empty: all of presliding,
    /// creep, thermal, spring, drift).
    pub effect: Vec<String>,
    /// Run on one thread.
    pub serial: bool,
    /// No progress lines on stderr.
    pub quiet: bool,
    /// Run the force sections (plant variants, excitation, wrist, grip) on
    /// drawn plants `first..=last` instead of the ten variants.
    pub draws: Option<(u64, u64)>,
    /// With `draws`: every drawn plant's control rate, Hz (default: 2 kHz
    /// for odd seeds, 1 kHz for even ones).
    pub draw_rate_hz: Option<f64>,
    /// Turn the payout stop on (`cascade.payout_stop`) in every plant
    /// variant's identified configuration (the force sections).
    pub payout_stop: bool,
}

impl Default for ReportOptions {
    fn default() -> Self {
        Self {
            out: PathBuf::from("report"),
            seed: 1,
            duration_scale: 1.0,
            no_effects: false,
            effect: Vec::new(),
            serial: false,
            quiet: false,
            draws: None,
            draw_rate_hz: None,
            payout_stop: false,
        }
    }
}

impl ReportOptions {
    /// The `host-sim` arguments that make this report again (the output
    /// directory left out).
    pub fn command(&self) -> String {
        let mut c = format!(
            "report --seed {} --duration-scale {}",
            self.seed, self.duration_scale
        );
        if self.no_effects {
            c.push_str(" --no-effects");
        } else if !self.effect.is_empty() {
            c.push_str(&format!(" --effect {}", self.effect.join(",")));
        }
        if let Some((first, last)) = self.draws {
            c.push_str(&format!(" --draws {first}-{last}"));
        }
        if let Some(hz) = self.draw_rate_hz {
            c.push_str(&format!(" --draw-rate-hz {hz}"));
        }
        if self.payout_stop {
            c.push_str(" --payout-stop");
        }
        c
    }
}

/// Step 7's results.
pub struct EffectsPart {
    /// Effects switched on.
    pub names: Vec<&'static str>,
    /// Steps 1, 2, 5 on the plant with effects.
    pub id: Identification,
    /// Steps 3, 4, 6 with the seed's models.
    pub before: Evaluation,
    /// The residual loop.
    pub residual: ResidualStep,
    /// Steps 3, 4, 6 after the residual loop.
    pub after: Evaluation,
    /// JAE error through the core on `jae-ident`, seed's model, °.
    pub jae_error_before_deg: Summary,
    /// The same after the residual loop, °.
    pub jae_error_after_deg: Summary,
}

/// Everything the report shows.
pub struct Report {
    /// The options it ran with.
    pub options: ReportOptions,
    /// Wall-clock time of the whole run, s.
    pub runtime_s: f64,
    /// Steps 1-6 on the clean plant.
    pub clean: (Identification, Evaluation),
    /// JAE error through the core on the clean `jae-ident` run, °.
    pub clean_jae_error_deg: Summary,
    /// Step 7 (absent with `--no-effects`).
    pub effects: Option<EffectsPart>,
    /// Figures written.
    pub figures: Vec<Written>,
    /// The force estimate on plant variants.
    pub variants: Vec<variants::VariantResult>,
    /// The designed excitations against `jae-ident` on the plant variants
    /// (`Err`: why the section could not run).
    pub excitation: Result<excitation::ExcitationSection, String>,
    /// The wrist's clamp force on the plant variants (`Err`: why the
    /// section could not run).
    pub wrist: Result<wrist::WristSection, String>,
    /// The wrist section's figure (its stem), if drawn.
    pub wrist_figure: Option<String>,
    /// The wrist in free motion, Eq. 3 identified and judged (`Err`: why
    /// the section could not run).
    pub free_motion: Result<free_motion::FreeMotionSection, String>,
    /// Its figure (its stem), if drawn.
    pub free_motion_figure: Option<String>,
    /// Stem of the figure of Eq. 3's identification runs, if staged.
    pub free_motion_excitation_figure: Option<String>,
    /// Grip-force control on the plant variants (`Err`: why the section
    /// could not run).
    pub grip: Result<grip::GripSection, String>,
    /// The grip section's figure (its stem), if drawn.
    pub grip_figure: Option<String>,
    /// The figures, staged: [`write()`] commits them with the report, so a
    /// run that fails leaves the output directory as it was.
    pub staged: Outputs,
}

/// The JAE of `config` on a log with the magnetic encoder, replayed through
/// the core: `theta_hat - theta` in degrees after the first 0.2 s, on ticks
/// without a fault.
pub fn jae_error_deg(log: &Log, config: &Config) -> Result<Summary> {
    let r = regressors::Replay::new(log, config)?;
    let t = r.t_s()?.to_vec();
    let hat = r.col("theta_hat_rad")?;
    let fault = r.col("fault_code")?;
    let mag = r.theta_rad();
    let t0 = t.first().copied().unwrap_or(0.0) + 0.2;
    let mut acc = Acc::default();
    for k in 0..t.len() {
        if t[k] >= t0 && fault[k] == 0.0 {
            acc.push(hat[k] - mag[k]);
        }
    }
    Ok(acc.summary(DEG_PER_RAD))
}

fn effects_plant(names: &[String]) -> Result<(PlantParams, Vec<&'static str>)> {
    let mut plant = PlantParams::default();
    let mut fx = Effects::default();
    if names.is_empty() {
        for n in Effects::NAMES {
            fx.enable(n)?;
        }
    } else {
        for n in names {
            fx.enable(n)?;
        }
    }
    plant.effects = fx;
    plant.validate()?;
    let on = plant.effects.enabled();
    Ok((plant, on))
}

/// Step 7 on its own thread.
fn effects_part(names: &[String], s: &Settings) -> Result<EffectsPart> {
    let tag = "effects";
    let (plant, on) = effects_plant(names)?;
    s.progress.line(
        tag,
        &format!("plant with unmodelled effects: {}", on.join(", ")),
    );
    let (id, before) = programme::programme(&plant, &Config::default(), s, tag)?;
    let jae_error_before_deg = jae_error_deg(&id.logs.jae, &id.config_jae)?;
    let residual = programme::residual_loop(&plant, &id, s, tag)?;
    s.progress.line(
        tag,
        &format!(
            "residual loop added {} JAE and {} tension terms; evaluating again",
            residual.jae.outcome.accepted.len(),
            residual.tension.outcome.accepted.len()
        ),
    );
    let jae_error_after_deg = jae_error_deg(&id.logs.jae, &residual.config)?;
    let after = programme::evaluate(&plant, &residual.config, s, "effects+residual")?;
    Ok(EffectsPart {
        names: on,
        id,
        before,
        residual,
        after,
        jae_error_before_deg,
        jae_error_after_deg,
    })
}

/// The clean programme, its JAE error, its figures and their staged files.
struct CleanPart {
    programme: (Identification, Evaluation),
    jae_error_deg: Summary,
    figures: Vec<Written>,
    staged: Outputs,
}

/// The clean programme and its figures (staged).
fn clean_part(s: &Settings, dir: &Path) -> Result<CleanPart> {
    let tag = "clean";
    s.progress.line(tag, "plant without unmodelled effects");
    let (id, ev) = programme::programme(&PlantParams::default(), &Config::default(), s, tag)?;
    let jae = jae_error_deg(&id.logs.jae, &id.config_jae)?;
    s.progress.line(tag, "figures");
    let mut staged = Outputs::new();
    let figures = figures::programme_figures(dir, &mut staged, &id, &ev)?;
    Ok(CleanPart {
        programme: (id, ev),
        jae_error_deg: jae,
        figures,
        staged,
    })
}

/// Run the programme and write the figures into `args.out`; returns the
/// report (report.md and report.json are written by [`write()`]).
pub fn generate(args: &ReportOptions) -> Result<Report> {
    ensure!(
        args.duration_scale.is_finite() && args.duration_scale > 0.0,
        "--duration-scale must be > 0, got {}",
        args.duration_scale
    );
    // Every run is kept in memory: each scenario at this scale must fit the
    // limit one simulated run has (`simulate`'s), checked before any work.
    let rate_hz = f64::from(Config::default().control_rate_hz);
    for info in crate::scenario::SCENARIOS {
        let mut opts = crate::scenario::ScenarioOptions {
            duration_scale: args.duration_scale,
            ..Default::default()
        };
        if info.name == "loading" {
            // The report runs the loading protocol one case at a time.
            opts.angle_deg = Some(-40.0);
            opts.mass_g = Some(250.0);
            opts.direction = Some(crate::scenario::Direction::Pos);
        }
        crate::sim::check_ticks(
            &format!(
                "--duration-scale {} (scenario {})",
                args.duration_scale, info.name
            ),
            crate::scenario::plan(info.name, &opts)?.duration_s(),
            rate_hz,
        )?;
    }
    let progress = Progress::new(args.quiet);
    // The spinner is cleared however the report ends (an error included).
    struct ClearOnExit(Progress);
    impl Drop for ClearOnExit {
        fn drop(&mut self) {
            self.0.finish();
        }
    }
    let _clear = ClearOnExit(progress);
    let s = Settings {
        seed: args.seed,
        scale: args.duration_scale,
        progress,
        draws: args.draws,
        draw_rate_hz: args.draw_rate_hz.map(|hz| hz as f32),
        payout_stop: args.payout_stop,
    };
    let dir = &args.out;
    crate::output::ensure_dir(dir)?;
    if !args.no_effects {
        // Check the effect names before an hour of work... or a minute.
        effects_plant(&args.effect)?;
    }
    let (clean, fx) = if args.serial || args.no_effects {
        let clean = clean_part(&s, dir)?;
        let fx = if args.no_effects {
            None
        } else {
            Some(effects_part(&args.effect, &s)?)
        };
        (clean, fx)
    } else {
        std::thread::scope(|scope| -> Result<_> {
            let h = scope.spawn(|| effects_part(&args.effect, &s));
            let clean = clean_part(&s, dir);
            let fx = h
                .join()
                .map_err(|_| anyhow::anyhow!("the effects thread panicked"))?;
            Ok((clean?, Some(fx?)))
        })?
    };
    let CleanPart {
        programme: (id, ev),
        jae_error_deg: clean_jae,
        figures: mut figs,
        mut staged,
    } = clean;
    progress.line("report", "force estimate on plant variants");
    let variant_results = variants::run_all(&s);
    progress.line("report", "designed excitations on plant variants");
    let excitation = excitation::run_all(&s).map_err(|e| format!("{e:#}"));
    progress.line(
        "report",
        "the force scale from known weights on plant variants",
    );
    let weighed = weigh::run_all(&variant_results, s.seed);
    progress.line("report", "the wrist's clamp force on plant variants");
    let wrist_section =
        wrist::run_all(&variant_results, &weighed, s.seed).map_err(|e| format!("{e:#}"));
    let wrist_figure = wrist::stage_figure_for(&variant_results, s.seed, &mut staged, dir)?;
    progress.line(
        "report",
        "the wrist in free motion (Eq. 3) on plant variants",
    );
    let (free_motion_section, free_motion_panels) =
        match free_motion::run_all(&variant_results, s.seed) {
            Ok((sec, panels)) => (Ok(sec), panels),
            Err(e) => (Err(format!("{e:#}")), Vec::new()),
        };
    let free_motion_figure = free_motion::stage_figure_for(free_motion_panels, &mut staged, dir)?;
    let free_motion_excitation_figure =
        free_motion::stage_excitation_figure(free_motion_section.as_ref().ok(), &mut staged, dir)?;
    progress.line("report", "grip-force control on plant variants");
    let grip_section =
        grip::run_all(&variant_results, &weighed, s.seed).map_err(|e| format!("{e:#}"));
    let grip_figure = grip::stage_figure_for(&variant_results, s.seed, &mut staged, dir)?;
    if let Some(fx) = &fx {
        progress.line("report", "step 7 figures");
        figs.extend(figures::accuracy_figure(
            dir,
            &mut staged,
            &[
                ("clean", &ev),
                ("effects, seed model", &fx.before),
                ("effects + residual", &fx.after),
            ],
        )?);
        for (name, a) in [("jae", &fx.residual.jae), ("tension", &fx.residual.tension)] {
            let sub = format!("residual_{name}");
            let d = dir.join(&sub);
            staged.create_dir(&d)?;
            for p in crate::residual::report::stage_plots(&mut staged, a, &d)? {
                if p.extension().is_some_and(|e| e == "svg") {
                    if let Some(stem) = p.file_stem() {
                        figs.push(Written {
                            stem: format!("{sub}/{}", stem.to_string_lossy()),
                            caption: format!("residual loop, {name}"),
                        });
                    }
                }
            }
        }
    }
    Ok(Report {
        options: args.clone(),
        runtime_s: progress.elapsed_s(),
        clean: (id, ev),
        clean_jae_error_deg: clean_jae,
        effects: fx,
        figures: figs,
        variants: variant_results,
        excitation,
        wrist: wrist_section,
        wrist_figure,
        free_motion: free_motion_section,
        free_motion_figure,
        free_motion_excitation_figure,
        grip: grip_section,
        grip_figure,
        staged,
    })
}

/// A section's goal lines on the terminal under `title`, each marked met or
/// not, or why the section could not run.
fn goal_block(text: &mut String, title: &str, lines: Result<Vec<(String, bool)>, &String>) {
    text.push_str(&format!("\n{title}\n"));
    match lines {
        Ok(lines) => {
            for (g, ok) in lines {
                text.push_str(&format!(
                    "  {} {g}\n",
                    if ok { "met    " } else { "NOT met" }
                ));
            }
        }
        Err(e) => text.push_str(&format!("  could not run: {e}\n")),
    }
}

/// Write report.md, report.json, the configurations and the staged figures
/// into the output directory, all or none; returns the terminal text
/// (comparison, goals, step 7).
pub fn write(r: &mut Report) -> Result<String> {
    // The figures, the configurations and the report are written together,
    // or none is.
    let mut out = std::mem::take(&mut r.staged);
    let r = &*r;
    let map = render::figure_map(r);
    let rows = seed::comparison(r);
    let dir = &r.options.out;
    stage_config(&mut out, dir.join("config_clean.toml"), &r.clean.0.config)?;
    if let Some(fx) = &r.effects {
        stage_config(
            &mut out,
            dir.join("config_effects_seed_model.toml"),
            &fx.id.config,
        )?;
        stage_config(
            &mut out,
            dir.join("config_effects_residual.toml"),
            &fx.residual.config,
        )?;
    }
    for v in &r.variants {
        let d = dir.join("variants").join(v.slug());
        out.create_dir(&d)?;
        out.bytes(&d.join("plant.toml"), v.plant.to_toml_string()?.as_bytes())?;
        if let Some(c) = &v.config {
            stage_config(&mut out, d.join("config.toml"), c)?;
            let mut probed = *c;
            probed.probe.enabled = true;
            stage_config(&mut out, d.join("config_probing.toml"), &probed)?;
        }
    }
    let md = markdown::markdown(r, &rows);
    out.bytes(&dir.join("report.md"), md.as_bytes())?;
    let json = serde_json::to_string_pretty(&render::json(r, &map, &rows))?;
    out.bytes(&dir.join("report.json"), json.as_bytes())?;
    out.commit()?;
    let mut text = String::from("Force estimate on plant variants (passive)\n");
    for v in &r.variants {
        let goals = markdown::goal_lines(v);
        let met = goals.iter().filter(|(_, ok)| *ok).count();
        text.push_str(&format!(
            "  {:<18} {:>6} Hz  {met}/{} goals met\n",
            v.name,
            v.rate_hz,
            goals.len()
        ));
        for (g, _) in goals.iter().filter(|(_, ok)| !*ok) {
            text.push_str(&format!("      NOT met: {g}\n"));
        }
    }
    goal_block(
        &mut text,
        "Designed excitations against jae-ident (JAE fit)",
        r.excitation.as_ref().map(excitation::goal_lines),
    );
    goal_block(
        &mut text,
        "The wrist's clamp force (Eq. 4-5) on plant variants",
        r.wrist.as_ref().map(wrist::goal_lines),
    );
    goal_block(
        &mut text,
        "Grip-force control on plant variants",
        r.grip.as_ref().map(grip::goal_lines),
    );
    text.push('\n');
    text.push_str(&seed::terminal_table(&rows));
    text.push_str("\nWhere we stand\n");
    text.push_str(&goals::goals_table(r));
    if r.effects.is_some() {
        text.push_str("\nStep 7: unmodelled effects on, before and after the residual loop\n");
        text.push_str(&goals::step7_table(r));
    }
    let faults = goals::fault_lines(r);
    if !faults.is_empty() {
        text.push_str("\nFaults latched (statistics of those runs stop there)\n");
        for f in faults {
            text.push_str(&format!("  {f}\n"));
        }
    }
    text.push_str(&format!(
        "\nwrote {} and {} ({} figures) in {:.1} s\n",
        dir.join("report.md").display(),
        dir.join("report.json").display(),
        r.figures.len(),
        r.runtime_s
    ));
    Ok(text)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The report's header names the arguments that make it again: the
    /// default run's as before, a held-out run's with its draws, rate,
    /// `--no-effects` and the payout stop.
    #[test]
    fn the_command_in_the_header_reproduces_the_run() {
        assert_eq!(
            ReportOptions::default().command(),
            "report --seed 1 --duration-scale 1"
        );
        let held_out = ReportOptions {
            no_effects: true,
            draws: Some((70, 79)),
            draw_rate_hz: Some(500.0),
            payout_stop: true,
            ..ReportOptions::default()
        };
        assert_eq!(
            held_out.command(),
            "report --seed 1 --duration-scale 1 --no-effects --draws 70-79 --draw-rate-hz 500 \
             --payout-stop"
        );
        let effects = ReportOptions {
            effect: vec!["creep".into(), "drift".into()],
            ..ReportOptions::default()
        };
        assert!(effects.command().ends_with("--effect creep,drift"));
    }
}
