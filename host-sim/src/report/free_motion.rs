//! The report's Eq. 3 section (issue "beyond one joint", item 2): the
//! simulated wrist with massive links under gravity ([`crate::links`])
//! moves free, the core's Eq. 3 model
//! ([`cable_joint::wrist_dynamics`]) is identified on one no-contact run,
//! and is judged on another it never saw (each joint's no-load error and
//! its bound's coverage, raw and with Eq. 3 taken out) and on grasps (do
//! no harm: the clamp force's hold accuracy and the largest estimate with
//! the jaws open, without and with it), on every plant variant with the
//! configuration the variant section identified.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};
use cable_joint::wrist::Interval;
use cable_joint::wrist_dynamics::{N_LINKS, N_PARAMS, PARAM_NAMES};
use serde::Serialize;

use super::programme::run_seed;
use super::variants::VariantResult;
use super::wrist::{object, section_tail, STIFFNESS_N_M};
use crate::ident::excite::{samples, PairBound, PREDICTION_RATE_HZ};
use crate::ident::excite_wrist::{self, WristDesign, WristDesignOptions};
use crate::links::{
    fit_inverse_dynamics, no_load, run_free, FreeRun, InverseDynamicsFit, Links, NoLoad,
};
use crate::output::Outputs;
use crate::plot::{stage_figure, Figure, Panel, Series};
use crate::wrist::{grasp_stats, run_grasp, Grasp, GraspStats, WristParams, WristTick, JAW_A};

/// One variant.
#[derive(Clone, Debug, Serialize)]
pub struct FreeMotionRow {
    /// Plant variant (every joint of the wrist is this plant).
    pub variant: String,
    /// Control rate, Hz.
    pub rate_hz: f32,
    /// The fitted parameters, their `%sigma`, the condition number.
    pub params: [f64; N_PARAMS],
    /// `%sigma` of each parameter.
    pub pct_sigma: [f64; N_PARAMS],
    /// The torques' RMS on the identification run's last 30 %, raw and
    /// less the model fitted on the rest, as forces at the tips, N.
    pub held_out_rms_n: [f64; 2],
    /// The links' parameters and `%sigma` as the fit with every column
    /// found them.
    pub with_links: [[f64; 2]; N_LINKS],
    /// Grasps without Eq. 3 and with it (one per object stiffness).
    pub grasps: Vec<(GraspStats, GraspStats)>,
    /// Eq. 3 identified on the hand-made run (the figures above: its
    /// condition number, whether it was kept, whether the links were
    /// seen, the validation run's no-load errors) and on the designed
    /// excitation, judged alike.
    pub excitations: [ExcitationFit; 2],
}

impl FreeMotionRow {
    /// The fit on the hand-made run.
    fn hand_made(&self) -> &ExcitationFit {
        &self.excitations[0]
    }
}

/// Eq. 3 identified on one excitation and validated on the run it never
/// saw.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct ExcitationFit {
    /// Condition number of the fit with every column.
    pub condition_with_links: f64,
    /// Condition number of the fit as kept (links left out or not).
    pub condition: f64,
    /// Largest `%sigma` of the fit with every column.
    pub worst_pct_sigma_with_links: f64,
    /// Its parameter (index into [`PARAM_NAMES`]).
    pub worst_with_links: usize,
    /// Largest `%sigma` of the fit as kept.
    pub worst_pct_sigma: f64,
    /// Its parameter.
    pub worst_kept: usize,
    /// Whether the links' columns fitted values real links could have.
    pub links_observed: bool,
    /// Whether the model was kept.
    pub kept: bool,
    /// The motion observer's bandwidth the fit chose, Hz.
    pub motion_bandwidth_hz: f32,
    /// The widest friction sign the fit's joints show, rad/s
    /// ([`InverseDynamicsFit::sign_width_seen_rad_s`]).
    pub sign_width_seen_rad_s: f64,
    /// The validation run's no-load errors with this fit's model.
    pub validation: NoLoad,
}

impl ExcitationFit {
    fn of(fit: &InverseDynamicsFit, validation: NoLoad) -> Self {
        // The largest `%sigma` of those fitted, and its parameter.
        let worst = |p: &[f64; N_PARAMS]| {
            (0..N_PARAMS)
                .filter(|&k| !p[k].is_nan())
                .fold((f64::NAN, 0), |(w, b), k| {
                    if w.is_nan() || p[k] > w {
                        (p[k], k)
                    } else {
                        (w, b)
                    }
                })
        };
        let (every, kept) = (worst(&fit.pct_sigma_with_links), worst(&fit.pct_sigma));
        Self {
            motion_bandwidth_hz: fit.motion_bandwidth_hz,
            condition_with_links: fit.condition_with_links,
            condition: fit.condition,
            worst_pct_sigma_with_links: every.0,
            worst_with_links: every.1,
            worst_pct_sigma: kept.0,
            worst_kept: kept.1,
            links_observed: fit.links_observed,
            kept: fit.kept,
            sign_width_seen_rad_s: max4(&fit.sign_width_seen_rad_s),
            validation,
        }
    }
}

/// The section.
#[derive(Clone, Debug, Serialize)]
pub struct FreeMotionSection {
    /// The links every variant carries.
    pub links: Links,
    /// Their true base parameters (the first of the fitted ones).
    pub links_params: [f64; N_LINKS],
    /// Every variant that ran.
    pub rows: Vec<FreeMotionRow>,
    /// Variants that could not run, and why.
    pub skipped: Vec<String>,
    /// The designed excitation every variant was also identified on.
    pub design: WristDesign,
    /// Predicted condition numbers of the hand-made run and the design.
    pub predicted_condition: [f64; 2],
    /// Each one's most correlated pair of columns.
    pub pair_bounds: [PairBound; 2],
}

/// The wrist of variant `v` with configuration `c` and the prototype's
/// links.
fn wrist_of(v: &VariantResult, c: cable_joint::Config) -> WristParams {
    WristParams {
        links: Some(Links::prototype()),
        ..WristParams::uniform(v.plant, c)
    }
}

/// Variant `v`'s wrist with configuration `config` and Eq. 3 as fitted
/// on the identification run `run` (if kept), the fit, and the validation
/// run with the model taken out (its seed the same whatever `run`).
fn identified(
    v: &VariantResult,
    config: cable_joint::Config,
    run: &FreeRun,
    run_label: &str,
    base_seed: u64,
) -> Result<(WristParams, InverseDynamicsFit, Vec<WristTick>)> {
    let params = wrist_of(v, config);
    let label = |what: &str| format!("eq3/{}/{what}", v.name);
    let id = run_free(&params, run, run_seed(base_seed, &label(run_label)))
        .with_context(|| label(run_label))?;
    let fit = fit_inverse_dynamics(&params, &id, Links::prototype().gravity_m_s2)
        .with_context(|| label("fit"))?;
    let params = WristParams {
        inverse_dynamics: fit.model(),
        ..params
    };
    let val = run_free(
        &params,
        &FreeRun::validation(),
        run_seed(base_seed, &label("validation")),
    )
    .with_context(|| label("validation"))?;
    Ok((params, fit, val))
}

/// Every variant with an identified configuration, passive, as identified;
/// with the figure's panels from the same validation runs: the first
/// variant's jaw A, and the variant other than it where the kept model cut
/// the worst joint's no-load RMS most (that joint), if any.
pub fn run_all(
    variants: &[VariantResult],
    base_seed: u64,
) -> Result<(FreeMotionSection, Vec<Panel>)> {
    let links = Links::prototype();
    let opts = WristDesignOptions::replacing_free_run();
    let design = excite_wrist::design_over_frequencies(&opts, opts.duration_s())
        .context("designing the wrist's excitation")?;
    let hand = FreeRun::identification();
    let designed = FreeRun::designed(&design);
    let runs = [&hand, &designed];
    let predicted = |r: &FreeRun| {
        (
            opts.shape
                .condition(&r.trajectories, r.duration_s, PREDICTION_RATE_HZ),
            opts.shape
                .pair_bound(&r.trajectories, r.duration_s, PREDICTION_RATE_HZ),
        )
    };
    let mut sec = FreeMotionSection {
        links,
        links_params: [0.0; N_LINKS],
        rows: Vec::new(),
        skipped: Vec::new(),
        design,
        predicted_condition: runs.map(|r| predicted(r).0),
        pair_bounds: runs.map(|r| predicted(r).1),
    };
    let mut first: Option<Panel> = None;
    let mut best: Option<(f64, Panel)> = None;
    for v in variants {
        let Some(config) = v.config else {
            sec.skipped.push(format!(
                "{}: no identified configuration ({})",
                v.name,
                v.error.as_deref().unwrap_or("identification did not run")
            ));
            continue;
        };
        let (with, fit, val) = identified(v, config, &hand, "identification", base_seed)?;
        let (with_d, fit_d, val_d) = identified(v, config, &designed, "designed", base_seed)?;
        let excitations = [
            ExcitationFit::of(&fit, no_load(&with, &val)),
            ExcitationFit::of(&fit_d, no_load(&with_d, &val_d)),
        ];
        sec.links_params = links.base_params(&with.geometry);
        let label = |what: &str| format!("eq3/{}/{what}", v.name);
        let params = WristParams {
            inverse_dynamics: None,
            ..with.clone()
        };
        let mut grasps = Vec::new();
        for k in STIFFNESS_N_M {
            let seed = run_seed(base_seed, &label(&format!("grasp/{k}")));
            let grasp = |p: &WristParams| {
                run_grasp(p, object(k), &Grasp::default(), seed)
                    .map(|t| grasp_stats(&p.geometry, &t))
                    .with_context(|| label(&format!("grasp/{k}")))
            };
            grasps.push((grasp(&params)?, grasp(&with)?));
        }
        sec.rows.push(FreeMotionRow {
            variant: v.name.clone(),
            rate_hz: v.rate_hz,
            params: core::array::from_fn(|k| f64::from(fit.body.params[k])),
            pct_sigma: fit.pct_sigma,
            held_out_rms_n: fit
                .held_out_rms_nm
                .map(|x| x / f64::from(params.geometry.jaw_length_m)),
            with_links: fit.with_links,
            grasps,
            excitations,
        });
        let validation = &excitations[0].validation;
        if first.is_none() {
            first = Some(panel_of(&v.name, &with, fit.kept, &val, JAW_A));
        } else if fit.kept {
            let raw = &validation.raw_rms_n;
            let j = (0..4).fold(0, |b, j| if raw[j] > raw[b] { j } else { b });
            let cut = raw[j] - validation.corrected_rms_n[j];
            if cut > 0.0 && best.as_ref().is_none_or(|(c, _)| cut >= *c) {
                best = Some((cut, panel_of(&v.name, &with, fit.kept, &val, j)));
            }
        }
    }
    let panels = first.into_iter().chain(best.map(|(_, p)| p)).collect();
    Ok((sec, panels))
}

fn max4(x: &[f64; 4]) -> f64 {
    x.iter().copied().fold(f64::NAN, f64::max)
}

fn min4(x: &[f64; 4]) -> f64 {
    x.iter().copied().fold(f64::NAN, f64::min)
}

/// The section in markdown.
pub fn markdown(
    sec: &FreeMotionSection,
    figure: Option<&str>,
    excitation_figure: Option<&str>,
) -> String {
    let mut o = String::new();
    let _ = writeln!(o, "## The wrist in free motion (seed 000 Eq. 3)\n");
    let l = &sec.links;
    let _ = writeln!(
        o,
        "The wrist of the section above with massive links (`host-sim/src/links.rs`: steel \
         jaws of {:.2} g, a wrist link of {:.2} g, gravity 9.81 m/s² across the level shaft, \
         30° turned; the links' torques from Lagrange's equations). Each variant's wrist moves \
         free on the seed's three-sine trajectory at every joint (0.6 rad roll and pitch, \
         0.3 rad jaws, 20 s); Eq. 3's model (`cable_joint::wrist_dynamics`: the links' seven \
         base parameters and each joint's Coulomb and viscous friction that its own model \
         leaves) is fitted to the four joints' fused estimates by the core's least squares, \
         its regressor read as the estimates read the torque: through their own low-pass `Q` \
         (the DOB's), on the motion of an observer whose bandwidth (1 to 12 times \
         `Q`'s) the fit chooses by the held-out check below; then judged on a 10 s run with other amplitudes and frequencies that it never saw \
         (the true external force is zero throughout: every newton is error), and on the \
         grasps of 2 N at 1000 and 10 000 N/m without and with it. The links' columns are left out when \
         they fit values no real links have (`links::unphysical_links`: a negative inertia or \
         moment, or a second moment above a body's length times its first moment, mass beyond \
         its end): what they took is not links, the friction staying. The model is kept only if, \
         fitted on the identification run's first 70 %, it cuts the torques' RMS on its last \
         30 %; a model not kept is not used (its columns read as without). With a model the \
         bound is the estimate's own joined with the one Eq. 3 shifts and widens by three \
         standard deviations of its parameters. Reproduce: `cargo run --release -p host-sim` \
         (this section).\n",
        1e3 * l.jaw_kg[0],
        1e3 * l.wrist_link_kg,
    );
    let _ = writeln!(
        o,
        "| variant | rate | links' torque at the tips, RMS (largest joint) | links' columns | Eq. 3 kept? observer (identification run's last 30 %: raw → model) | no-load RMS, worst joint: raw → Eq. 3 | mean of joints: raw → Eq. 3 | least bound coverage: raw → Eq. 3 | hold accuracy, 1000 / 10 000 N/m: without → with | largest \\|estimate\\| jaws open: without → with |"
    );
    let _ = writeln!(o, "|---|---|---|---|---|---|---|---|---|---|");
    for r in &sec.rows {
        let h = r.hand_made();
        let v = &h.validation;
        let mean = |x: &[f64; 4]| x.iter().sum::<f64>() / 4.0;
        let acc = |f: &dyn Fn(&(GraspStats, GraspStats)) -> f64| {
            r.grasps
                .iter()
                .map(|g| format!("{:.1}", f(g)))
                .collect::<Vec<_>>()
                .join(" / ")
        };
        let open = |f: &dyn Fn(&(GraspStats, GraspStats)) -> f64| {
            r.grasps.iter().map(f).fold(0.0, f64::max)
        };
        let _ = writeln!(
            o,
            "| {} | {:.0} Hz | {:.4} N | {} | {} at {:.0} Hz ({:.3} → {:.3} N) | {:.3} → {:.3} N | {:.3} → {:.3} N | {:.1} → {:.1} % | {} → {} % | {:.3} → {:.3} N |",
            r.variant,
            r.rate_hz,
            max4(&v.links_rms_n),
            if h.links_observed {
                "fitted"
            } else {
                "left out (not physical)"
            },
            if h.kept { "kept" } else { "**not kept**" },
            h.motion_bandwidth_hz,
            r.held_out_rms_n[0],
            r.held_out_rms_n[1],
            max4(&v.raw_rms_n),
            max4(&v.corrected_rms_n),
            mean(&v.raw_rms_n),
            mean(&v.corrected_rms_n),
            100.0 * min4(&v.raw_coverage),
            100.0 * min4(&v.coverage),
            acc(&|g| g.0.hold_accuracy_pct),
            acc(&|g| g.1.hold_accuracy_pct),
            open(&|g| g.0.open_max_n),
            open(&|g| g.1.open_max_n),
        );
    }
    if let Some(first) = sec.rows.first() {
        let _ = writeln!(
            o,
            "\nThe fitted parameters on {} against the links' true base parameters (the \
             friction terms have no true value: they are what the joints' own models miss):\n",
            first.variant
        );
        let _ = writeln!(
            o,
            "| parameter | true | fitted with every column (%σ) | fitted as kept | %σ |"
        );
        let _ = writeln!(o, "|---|---|---|---|---|");
        for (k, name) in PARAM_NAMES.iter().enumerate() {
            let truth = sec
                .links_params
                .get(k)
                .map_or("-".to_owned(), |x| format!("{x:.3e}"));
            let (fitted, pct) = if first.pct_sigma[k].is_nan() {
                ("left out".to_owned(), "-".to_owned())
            } else {
                (
                    format!("{:.3e}", first.params[k]),
                    format!("{:.1}", first.pct_sigma[k]),
                )
            };
            let every = first
                .with_links
                .get(k)
                .map_or("-".to_owned(), |[x, p]| format!("{x:.3e} ({p:.1})"));
            let _ = writeln!(o, "| {name} | {truth} | {every} | {fitted} | {pct} |");
        }
        let _ = writeln!(o, "\nCondition number {:.1}.", first.hand_made().condition);
    }
    let _ = writeln!(
        o,
        "\nWhat the numbers say: at the prototype's scale the links' own torques are \
         millinewtons at the tips (third column), below what the joints' estimates resolve, so \
         a no-contact run cannot weigh them: fitted, the links' columns take the estimates' \
         errors that go with acceleration and pose, orders above the true values and of \
         either sign, and the fit says so by leaving them out. What Eq. 3 can still learn is \
         its `tau_f`: the torque a joint's fused estimate reads against its speed while it \
         moves. Where that holds on the identification run's held-out part it is kept, and \
         the table shows what it does on the run it never saw and in the grasps."
    );
    section_tail(
        &mut o,
        &sec.skipped,
        figure,
        "no-load estimates in free motion, raw and with Eq. 3",
    );
    excitation_markdown(&mut o, sec, excitation_figure);
    o
}

/// The designed excitation's part of the section.
fn excitation_markdown(o: &mut String, sec: &FreeMotionSection, figure: Option<&str>) {
    let d = &sec.design;
    let [hand, designed] = sec.predicted_condition;
    let base_freq_hz = match d.trajectories[0] {
        cable_joint::trajectory::Trajectory::Fourier { base_freq_hz, .. } => {
            f64::from(base_freq_hz)
        }
        _ => f64::NAN,
    };
    let _ = writeln!(
        o,
        "\n### Designed excitation for Eq. 3 (seed 001 Sect. 2.3)\n\n\
         `host-sim excite --wrist --out w.toml` (`host_sim::ident::excite_wrist`) designs one \
         five-harmonic Fourier series per joint (the firmware's `Trajectory::Fourier`, from rest), \
         the four together, to minimise the condition number of Eq. 3's equilibrated regressor \
         (all {} columns) predicted from the references, each joint under the angle, velocity and \
         acceleration peaks of the hand-made run and at its length ({:.0} s). The search found \
         {:.3} Hz; predicted condition number {hand:.2} → {designed:.2} ({:.2}×). What floors \
         it is a pair of columns, as on one joint: a joint's Coulomb term against its viscous \
         one (its speed against its sign), |cos| {:.3} on the hand-made run ({} and {}: no \
         regressor holding both goes under {:.2}) and {:.3} on the design ({} and {}: {:.2}); \
         a third of the hand-made run's figure ({:.2}) needs that pair at |cos| ≤ {:.2} on \
         every joint, a joint that stands still most of the time and moves in bursts. Every \
         variant is identified on both runs (the same fit, the same checks) and validated on \
         the same run it never saw.\n",
        N_PARAMS,
        d.duration_s,
        base_freq_hz,
        designed / hand,
        sec.pair_bounds[0].correlation,
        PARAM_NAMES[sec.pair_bounds[0].columns.0],
        PARAM_NAMES[sec.pair_bounds[0].columns.1],
        sec.pair_bounds[0].condition_at_least,
        sec.pair_bounds[1].correlation,
        PARAM_NAMES[sec.pair_bounds[1].columns.0],
        PARAM_NAMES[sec.pair_bounds[1].columns.1],
        sec.pair_bounds[1].condition_at_least,
        hand / 3.0,
        // sqrt((1 + r) / (1 - r)) = c  <=>  r = (c^2 - 1) / (c^2 + 1)
        ((hand / 3.0).powi(2) - 1.0) / ((hand / 3.0).powi(2) + 1.0),
    );
    let _ = writeln!(
        o,
        "| variant | condition, every column: hand-made → designed | ≤ 1/3? | condition as kept | worst %σ, every column | halved? | worst %σ as kept | links' columns (hand-made / designed) | Eq. 3 kept | no-load RMS on the validation run, worst joint: hand-made's model → designed's | least bound coverage | friction sign seen, widest joint: hand-made → designed |"
    );
    let _ = writeln!(o, "|---|---|---|---|---|---|---|---|---|---|---|---|");
    let (mut third, mut halved, mut n) = (0, 0, 0);
    let (mut kept, mut lower) = ([0, 0], 0);
    for r in &sec.rows {
        let [a, b] = &r.excitations;
        let cond_met = b.condition_with_links <= a.condition_with_links / 3.0;
        let sigma_met = b.worst_pct_sigma_with_links <= a.worst_pct_sigma_with_links / 2.0;
        n += 1;
        third += usize::from(cond_met);
        halved += usize::from(sigma_met);
        kept[0] += usize::from(a.kept);
        kept[1] += usize::from(b.kept);
        lower +=
            usize::from(max4(&b.validation.corrected_rms_n) < max4(&a.validation.corrected_rms_n));
        let verdict = |m: bool| if m { "met" } else { "**not met**" };
        let links = |f: &ExcitationFit| {
            if f.links_observed {
                "fitted"
            } else {
                "left out"
            }
        };
        let kept = |f: &ExcitationFit| if f.kept { "kept" } else { "**not kept**" };
        let _ = writeln!(
            o,
            "| {} | {:.2} → {:.2} ({:.2}×) | {} | {:.2} → {:.2} | {:.1} ({}) → {:.1} % ({}) | {} | {:.1} ({}) → {:.1} % ({}) | {} / {} | {} / {} | {:.3} → {:.3} N | {:.1} / {:.1} % | {:.2} → {:.2} rad/s |",
            r.variant,
            a.condition_with_links,
            b.condition_with_links,
            b.condition_with_links / a.condition_with_links,
            verdict(cond_met),
            a.condition,
            b.condition,
            a.worst_pct_sigma_with_links,
            PARAM_NAMES[a.worst_with_links],
            b.worst_pct_sigma_with_links,
            PARAM_NAMES[b.worst_with_links],
            verdict(sigma_met),
            a.worst_pct_sigma,
            PARAM_NAMES[a.worst_kept],
            b.worst_pct_sigma,
            PARAM_NAMES[b.worst_kept],
            links(a),
            links(b),
            kept(a),
            kept(b),
            max4(&a.validation.corrected_rms_n),
            max4(&b.validation.corrected_rms_n),
            100.0 * min4(&a.validation.coverage),
            100.0 * min4(&b.validation.coverage),
            a.sign_width_seen_rad_s,
            b.sign_width_seen_rad_s,
        );
    }
    let _ =
        writeln!(
        o,
        "\nGoals (issue \"beyond one joint\", measured condition number and `%σ` of the fit with \
         every column, equal length): condition number at most a third of the hand-made run's: \
         met on {third} of {n} variants ({}); worst parameter `%σ` at least halved: met on \
         {halved} of {n} ({}). The table names each fit's worst parameter; a parameter the fit \
         puts near zero (a link the data does not see, a friction term a joint's own model \
         already holds) has a large relative deviation whatever the excitation. The last column \
         says why the predicted figure does not carry over: the design is predicted from the \
         commanded motion, the fit sees the joints' actual motion, and a joint that sticks and \
         slips at low speed has its Coulomb column (the sign of its speed, averaged by `Q`) \
         follow its speed up to that width instead of the design's `v_s` ({:.2} rad/s), \
         where the design counted on the two columns parting (`identify-wrist` prints it per \
         joint). Reproduce: \
         `cargo run --release -p host-sim` (this section); the design alone: `host-sim excite \
         --wrist --out w.toml`.\n\n\
         What the fits did with each run: Eq. 3 was kept (it cut its own run's held-out \
         torques) on {} of {n} variants identified on the hand-made run and on {} of {n} \
         identified on the design; the design's model left the lower worst-joint no-load RMS \
         on the validation run on {lower} of {n}.\n",
        if third == n && n > 0 { "met" } else { "**not met**" },
        if halved == n && n > 0 { "met" } else { "**not met**" },
        WristDesignOptions::replacing_free_run().shape.sign_speed_rad_s[0],
        kept[0],
        kept[1],
    );
    section_tail(
        o,
        &[],
        figure,
        "Eq. 3's identification runs: hand-made and designed references per joint",
    );
}

/// The joints' names in the figure.
const JOINT_NAMES: [&str; 4] = ["roll", "pitch", "jaw A", "jaw B"];

/// One panel: variant `name`'s validation run `val` on `params`, joint
/// `j`'s estimate as a force at its `l_e`, raw and with Eq. 3 taken out
/// (its bound), against the true zero.
fn panel_of(name: &str, params: &WristParams, kept: bool, val: &[WristTick], j: usize) -> Panel {
    let le = f64::from(params.configs[j].machine.gripper_length_m);
    let t: Vec<f64> = val.iter().map(|x| x.t_s).collect();
    let col = |f: &dyn Fn(&WristTick) -> f64| -> Vec<f64> { val.iter().map(f).collect() };
    let raw = |x: &WristTick| f64::from(x.outputs[j].est.f_ext_fused_n);
    let bound = |x: &WristTick| -> Interval { x.torque_bound_nm[j] };
    let model = if kept {
        "Eq. 3 taken out"
    } else {
        "Eq. 3 not kept (= raw)"
    };
    Panel::new(
        format!("{name}: {} in free motion (true force 0)", JOINT_NAMES[j]),
        "t [s]",
        "force at l_e [N]",
    )
    .with(Series::line("raw estimate", t.clone(), col(&raw)))
    .with(Series::line(
        model,
        t.clone(),
        col(&|x| raw(x) - f64::from(x.links_hat_nm[j]) / le),
    ))
    .with(Series::line(
        "bound, low",
        t.clone(),
        col(&|x| f64::from(bound(x).lo) / le),
    ))
    .with(Series::line(
        "bound, high",
        t,
        col(&|x| f64::from(bound(x).hi) / le),
    ))
}

/// The figure of [`run_all`]'s panels (none: no figure).
pub fn stage_figure_for(
    panels: Vec<Panel>,
    out: &mut Outputs,
    dir: &Path,
) -> Result<Option<String>> {
    if panels.is_empty() {
        return Ok(None);
    }
    let stem = "fig_wrist_free_motion";
    stage_figure(out, &Figure::grid(panels, 1), &dir.join(stem))?;
    Ok(Some(stem.to_owned()))
}

/// The figure of the hand-made and the designed excitation's references,
/// a panel per joint (none if the section did not run).
pub fn stage_excitation_figure(
    sec: Option<&FreeMotionSection>,
    out: &mut Outputs,
    dir: &Path,
) -> Result<Option<String>> {
    let Some(sec) = sec else {
        return Ok(None);
    };
    let hand = FreeRun::identification();
    let series = |name: &str, tr, duration_s| {
        let s = samples(&[(tr, duration_s)], PREDICTION_RATE_HZ);
        let t = (0..s.len())
            .map(|i| i as f64 / PREDICTION_RATE_HZ)
            .collect();
        Series::line(
            name,
            t,
            s.iter().map(|x| x.angle_rad.to_degrees()).collect(),
        )
    };
    let panels = (0..4)
        .map(|j| {
            Panel::new(
                format!("{}: Eq. 3's identification run", JOINT_NAMES[j]),
                "t [s]",
                "reference [deg]",
            )
            .with(series("hand-made", hand.trajectories[j], hand.duration_s))
            .with(series(
                "designed (condition number)",
                sec.design.trajectories[j],
                sec.design.duration_s,
            ))
        })
        .collect();
    let stem = "fig_wrist_excitation";
    stage_figure(out, &Figure::grid(panels, 2), &dir.join(stem))?;
    Ok(Some(stem.to_owned()))
}
