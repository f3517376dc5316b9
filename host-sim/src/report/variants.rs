//! The force estimate on plants it was not tuned to (issue: force at
//! standstill): plant variants with friction placed elsewhere, stiff
//! stiction, presliding, every parameter drawn ±30 %, 1 kHz and 2 kHz
//! control. On each, the user's path: identify the configuration on the
//! variant's own calibration runs (steps 1, 2 and 5), then run the seed's
//! loading protocol (joint held on `theta_hat` at 0°, 30°, -40°; 30, 100 and
//! 250 g; both directions) and judge every estimate on the same runs: the
//! DOB as published, the cable stretch, the fused estimate and, for the
//! comparison of point estimates, the fused bound's midpoint.

use cable_joint::{Config, Fault};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use super::programme::{identify_config, run_seed, Settings};
use crate::plant::PlantParams;
use crate::report::kalman::{Design, KalmanForce, FRICTION_TAU_S};
use crate::scenario::{self, Direction, Phase, ScenarioOptions, G_M_S2};
use crate::sim::{Recorder, TickRecord};
use crate::stats::Acc;
use crate::stats::DEG_PER_RAD;

/// Angles, weights of the protocol as run on every variant.
const ANGLES_DEG: [f64; 3] = [0.0, 30.0, -40.0];
const MASSES_G: [f64; 3] = [30.0, 100.0, 250.0];

/// The estimates judged: the DOB as published, the stretch, the fused
/// set-membership estimate and its bound's midpoint, and the two Kalman
/// filters the fusion's design is measured against ([`KALMAN`]).
pub const SOURCES: [&str; 6] = [
    "DOB (seed)",
    "stretch",
    "fused",
    "fused midpoint",
    "Kalman, white bands",
    "Kalman, friction states",
];

/// The Kalman filters of [`SOURCES`]' last two rows, in order.
pub const KALMAN: [Design; 2] = [
    Design::White,
    Design::FrictionStates {
        tau_s: FRICTION_TAU_S,
    },
];

/// Where the Kalman filters' rows start in [`SOURCES`].
pub const FIRST_KALMAN: usize = 4;

const N: usize = SOURCES.len();

/// One plant variant.
#[derive(Clone, Debug)]
pub struct Variant {
    /// Name in the tables.
    pub name: String,
    /// What differs from the default plant.
    pub what: String,
    /// The plant.
    pub plant: PlantParams,
    /// Control rate, Hz.
    pub rate_hz: f32,
}

fn variant(name: impl Into<String>, what: &str, plant: PlantParams, rate_hz: f32) -> Variant {
    Variant {
        name: name.into(),
        what: what.into(),
        plant,
        rate_hz,
    }
}

fn stick(p: &mut PlantParams, ratio: f64) {
    p.slider1.static_n = ratio * p.slider1.coulomb_n;
    p.slider2.static_n = ratio * p.slider2.coulomb_n;
    p.joint.static_nm = ratio * p.joint.coulomb_nm;
}

/// Every parameter that shapes the force path drawn uniformly within ±30 %
/// of the default, and the static/kinetic ratio within 1.05..1.45.
pub fn drawn(seed: u64) -> PlantParams {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut f = || rng.gen_range(0.7..1.3);
    let mut p = PlantParams::default();
    p.motor.coulomb_nm *= f();
    p.motor.viscous_nm_s_rad *= f();
    p.slider1.mass_kg *= f();
    p.slider1.coulomb_n *= f();
    p.slider1.viscous_n_s_m *= f();
    p.slider2.mass_kg *= f();
    p.slider2.coulomb_n *= f();
    p.slider2.viscous_n_s_m *= f();
    p.joint.coulomb_nm *= f();
    p.joint.viscous_nm_s_rad *= f();
    p.cable0.stiffness_n_m *= f();
    p.cable1.stiffness_n_m *= f();
    p.cable2.stiffness_n_m *= f();
    p.spring.stiffness_n_m *= f();
    p.spring.preload_n *= f();
    let ratio = 1.05 + 0.4 * (f() - 0.7) / 0.6;
    stick(&mut p, ratio);
    p
}

/// The variants (fixed seeds: the same plants every run).
pub fn variants() -> Vec<Variant> {
    let d = PlantParams::default();
    let mut v = vec![variant(
        "default",
        "the project's simulated prototype",
        d,
        2000.0,
    )];
    let mut slider1 = d;
    slider1.slider1.coulomb_n *= 1.5;
    slider1.joint.coulomb_nm *= 0.5;
    slider1.motor.coulomb_nm *= 0.5;
    stick(&mut slider1, 1.2);
    v.push(variant(
        "slider-1 friction",
        "slider 1 ×1.5, pin and motor ×0.5",
        slider1,
        2000.0,
    ));
    let mut pin = d;
    pin.joint.coulomb_nm *= 3.0;
    pin.slider1.coulomb_n *= 0.5;
    stick(&mut pin, 1.2);
    v.push(variant(
        "pin friction",
        "joint pin ×3 (12 mN·m), slider 1 ×0.5",
        pin,
        2000.0,
    ));
    let mut slider2 = d;
    slider2.slider2.coulomb_n *= 8.0;
    slider2.joint.coulomb_nm *= 0.5;
    stick(&mut slider2, 1.2);
    v.push(variant(
        "slider-2 friction",
        "slider 2 ×8 (0.9 N), pin ×0.5",
        slider2,
        2000.0,
    ));
    let mut rigid = d;
    stick(&mut rigid, 1.45);
    v.push(variant(
        "stiff stiction",
        "static/kinetic 1.45 everywhere",
        rigid,
        2000.0,
    ));
    let mut pre = d;
    if pre.effects.enable("presliding").is_ok() {
        v.push(variant(
            "presliding",
            "presliding (Dahl) friction on",
            pre,
            2000.0,
        ));
    }
    for seed in [11u64, 12] {
        v.push(variant(
            format!("draw {seed}"),
            "every parameter ±30 %",
            drawn(seed),
            2000.0,
        ));
    }
    v.push(variant(
        "default 1 kHz",
        "the default plant, 1 kHz control",
        d,
        1000.0,
    ));
    v.push(variant(
        "draw 13, 1 kHz",
        "every parameter ±30 %, 1 kHz control",
        drawn(13),
        1000.0,
    ));
    v
}

/// Drawn plants `first..=last` ([`drawn`]): plants no default was tuned
/// on, for an out-of-sample check of the estimator and its bound (`host-sim
/// report --draws`). Each runs at `rate_hz` if given (`--draw-rate-hz`),
/// else odd seeds at 2 kHz and even ones at 1 kHz.
pub fn drawn_variants(first: u64, last: u64, rate_hz: Option<f32>) -> Vec<Variant> {
    (first..=last)
        .map(|seed| {
            let rate_hz = rate_hz.unwrap_or(if seed % 2 == 0 { 1000.0 } else { 2000.0 });
            let what = if rate_hz == 2000.0 {
                "every parameter ±30 %".to_string()
            } else if rate_hz % 1000.0 == 0.0 {
                format!("every parameter ±30 %, {} kHz control", rate_hz / 1000.0)
            } else {
                format!("every parameter ±30 %, {rate_hz} Hz control")
            };
            variant(format!("draw {seed}"), &what, drawn(seed), rate_hz)
        })
        .collect()
}

/// The variants a report runs: the ten of [`variants`], or the drawn
/// plants its settings ask for.
pub fn for_settings(s: &Settings) -> Vec<Variant> {
    match s.draws {
        Some((first, last)) => drawn_variants(first, last, s.draw_rate_hz),
        None => variants(),
    }
}

/// One estimate on one variant.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct SourceStats {
    /// Worst accuracy over the cases >= 100 g, %.
    pub above_1n_min_pct: f64,
    /// Mean accuracy over the cases >= 100 g, %.
    pub above_1n_mean_pct: f64,
    /// Worst accuracy at 30 g (0.29 N), %.
    pub at_0n3_min_pct: f64,
    /// Largest |estimate| in the static no-load regions (the second half of
    /// each, after the estimate settled), N.
    pub static_noload_n: f64,
    /// Largest |estimate| while moving to 30°/-40° and settling, N.
    pub dynamic_noload_n: f64,
}

/// One variant's result.
#[derive(Clone, Debug, Serialize)]
pub struct VariantResult {
    /// Variant name.
    pub name: String,
    /// What differs.
    pub what: String,
    /// Control rate, Hz.
    pub rate_hz: f32,
    /// Identification failure, if any (then nothing else is filled).
    pub error: Option<String>,
    /// Notes from the identification (faults latched there, what was
    /// identified against the plant's values).
    pub notes: Vec<String>,
    /// The identified pin friction seen at the tip, `f_efc / l_e`, N: a
    /// stuck pin can hold at least this much of a load (and up to its static
    /// level) without any sensor seeing it, so it bounds what a passive
    /// estimate can resolve at standstill.
    pub pin_at_tip_n: f64,
    /// The plant's own pin stick-slip step with the motor held, °, stiffest
    /// and softest chain ([`PlantParams::pin_stick_slip_step_rad`]): what
    /// a hold that frees the pin moves the tip by, from the plant's true
    /// parameters (no estimator sees them).
    pub pin_stick_slip_step_deg: [f64; 2],
    /// The plant's JAE blind band while slider 2 sticks, °
    /// ([`PlantParams::jae_blind_band_rad`]).
    pub jae_blind_band_deg: f64,
    /// The loading protocol, passive (its fields appear at this level in
    /// the JSON).
    #[serde(flatten)]
    pub passive: Protocol,
    /// The same protocol with probing on ([`cable_joint::probe`], the
    /// configuration's default dither).
    pub probing: Option<Protocol>,
    /// The plant (written beside the report, so a case can be rerun).
    #[serde(skip)]
    pub plant: PlantParams,
    /// The configuration identified on it (`None` if identification failed).
    #[serde(skip)]
    pub config: Option<Config>,
}

impl VariantResult {
    /// The variant's directory name under the report's `variants/`
    /// ([`dir_name`]).
    pub fn slug(&self) -> String {
        dir_name(&self.name)
    }
}

/// The first variant with an identified configuration, and that
/// configuration: the one the sections' figures show (the default plant
/// when it identified).
pub fn first_identified(variants: &[VariantResult]) -> Option<(&VariantResult, Config)> {
    variants.iter().find_map(|v| v.config.map(|c| (v, c)))
}

/// A variant's directory name: its name, lower case, every run of other
/// characters one `-`.
pub fn dir_name(name: &str) -> String {
    let mut out = String::new();
    for c in name.chars() {
        if c.is_ascii_alphanumeric() {
            out.push(c.to_ascii_lowercase());
        } else if !out.is_empty() && !out.ends_with('-') {
            out.push('-');
        }
    }
    out.trim_end_matches('-').to_owned()
}

#[derive(Default)]
struct CaseRec {
    moved: bool,
    stable: [Acc; N],
    static_noload: [Acc; N],
    /// The current no-load region's estimates (its second half goes into
    /// `static_noload` when the region ends).
    noload: Vec<[f64; N]>,
    dynamic: [Acc; N],
    hold_n: u64,
    hold_in: u64,
    width: Acc,
    /// The Kalman filters ([`KALMAN`]), their hold samples inside `±2σ`
    /// and their interval widths.
    kalman: Vec<KalmanForce>,
    kalman_in: [u64; 2],
    kalman_width: [Acc; 2],
    theta_stable: Acc,
    fault: Option<String>,
    /// The plant's true state at the fault shows its cause.
    fault_confirmed: bool,
    /// The slack check's threshold, N (the controller's own).
    slack_limit_n: f64,
    /// When the current stretch of a truly slack cable (cable 0 or 1
    /// carrying no tension, drive on, no fault yet) began, s.
    slack_since_s: Option<f64>,
    /// The longest such stretch, s.
    slack_undetected_s: f64,
    /// The most rope that hung loose meanwhile, m.
    slack_undetected_m: f64,
    /// The range check's limit, rad.
    range_rad: f64,
}

impl CaseRec {
    /// End of a no-load region: its second half, after every estimate has
    /// settled (the DOB's `Q`, the probed mean's one-period window), counts
    /// as static.
    fn close_noload(&mut self) {
        let half = self.noload.len() / 2;
        for v in &self.noload[half..] {
            for (acc, x) in self.static_noload.iter_mut().zip(v) {
                acc.push(*x);
            }
        }
        self.noload.clear();
    }

    /// The fault against the plant's truth at the tick it latched: the
    /// message gains what the plant shows, and whether it confirms it.
    fn judge(&mut self, r: &TickRecord, f: Fault) -> String {
        let t = &r.tensions;
        let cable_slack = t.transmission_n() < self.slack_limit_n;
        let (confirmed, truth) = match f {
            Fault::TransmissionSlack | Fault::Cable0Slack => (
                cable_slack,
                format!(
                    "true tensions: cable 0 {:.2} N, cable 1 {:.2} N, limit {:.2} N",
                    t.rope_n, t.cable1_n, self.slack_limit_n
                ),
            ),
            // Out of range, or the transmission lost (a cable slack): the
            // joint is then free to run, and stopping it is right.
            Fault::AngleRange => (
                r.state.theta_rad.abs() > self.range_rad || cable_slack,
                format!(
                    "true joint angle {:.1}°, limit ±{:.1}°; true tensions: cable 0 {:.2} N, cable 1 {:.2} N",
                    r.state.theta_rad.to_degrees(),
                    self.range_rad.to_degrees(),
                    t.rope_n,
                    t.cable1_n
                ),
            ),
            _ => (false, String::from("no plant check for this fault")),
        };
        self.fault_confirmed = confirmed;
        format!(
            "{f} (t = {:.2} s; {truth}: {})",
            r.t_s,
            if confirmed { "a true fault" } else { "FALSE" }
        )
    }
}

impl Recorder for CaseRec {
    fn record(&mut self, r: &TickRecord) {
        // A slack cable (no tension at all; the checks' limit, a fraction
        // of the preload, is their margin) that the checks have not caught
        // yet: the drive still on and no fault (on the tick a fault latches
        // the drive is off).
        let t = &r.tensions;
        if self.fault.is_none() && r.output.drive_enable && t.transmission_n() <= 0.0 {
            let since = *self.slack_since_s.get_or_insert(r.t_s);
            self.slack_undetected_s = self.slack_undetected_s.max(r.t_s - since);
            self.slack_undetected_m = self.slack_undetected_m.max(t.slack_m);
        } else {
            self.slack_since_s = None;
        }
        if self.fault.is_none() {
            if let Some(f) = r.output.fault {
                self.fault = Some(self.judge(r, f));
            }
        }
        if !r.output.drive_enable || self.fault.is_some() {
            return;
        }
        let e = &r.output.est;
        let kf: Vec<(f64, f64, f64)> = self
            .kalman
            .iter_mut()
            .map(|k| k.update(&r.sources))
            .collect();
        let est = [
            f64::from(e.f_ext_hat_n),
            f64::from(e.f_ext_stretch_n),
            f64::from(e.f_ext_fused_n),
            0.5 * f64::from(e.f_ext_lo_n + e.f_ext_hi_n),
            kf.first().map_or(f64::NAN, |k| k.0),
            kf.get(1).map_or(f64::NAN, |k| k.0),
        ];
        let p = r.phase;
        if p != Phase::NoLoad.code() && !self.noload.is_empty() {
            self.close_noload();
        }
        let hold = p == Phase::NoLoad.code() || p == Phase::Stable.code();
        if hold {
            self.hold_n += 1;
            let (lo, hi) = (f64::from(e.f_ext_lo_n), f64::from(e.f_ext_hi_n));
            if lo <= r.f_ext_n && r.f_ext_n <= hi {
                self.hold_in += 1;
            }
            self.width.push(hi - lo);
            for (j, &(_, lo, hi)) in kf.iter().enumerate() {
                if lo <= r.f_ext_n && r.f_ext_n <= hi {
                    self.kalman_in[j] += 1;
                }
                self.kalman_width[j].push(hi - lo);
            }
        }
        for (k, v) in est.iter().enumerate() {
            if p == Phase::Stable.code() {
                self.stable[k].push(*v);
            } else if (p == Phase::Move.code() || p == Phase::Adjust.code()) && self.moved {
                self.dynamic[k].push(*v);
            }
        }
        if p == Phase::NoLoad.code() {
            self.noload.push(est);
        }
        if p == Phase::Stable.code() {
            self.theta_stable.push(r.state.theta_rad * DEG_PER_RAD);
        }
    }
}

/// What identification found against the plant's own values (the
/// simulator's truth, read here only to report, never to configure). The
/// stretch estimate's scale rests on the spring rate through `c4` (Eq. 16):
/// measured through the motor when the calibration run pins it down, else
/// the datasheet's.
/// `K_w0` as the identification wrote it, as a share of the plant's rope
/// stiffness; `None` where it was not read (0: cable 1's bound stands in).
pub fn cable0_share(c: &Config, p: &PlantParams) -> Option<f64> {
    let k_n_m = f64::from(c.stretch.cable0_n_m);
    (k_n_m > 0.0).then(|| k_n_m / p.cable0.stiffness_n_m)
}

fn identified_vs_plant(c: &Config, p: &PlantParams) -> String {
    let datasheet = cable_joint::config::Machine::default().spring_n_m;
    let spring = if c.machine.spring_n_m == datasheet {
        "the datasheet spring"
    } else {
        "the spring measured through the motor"
    };
    let rope_n_m = p.cable0.stiffness_n_m;
    let cable0 = match cable0_share(c, p) {
        Some(share) => format!(
            "K_w0 {:.0} N/m, {share:.3} of the plant's {rope_n_m:.0}",
            c.stretch.cable0_n_m
        ),
        None => format!("K_w0 not read (plant {rope_n_m:.0} N/m; cable 1's bound)"),
    };
    format!(
        "identified pin Coulomb {:.2} mN·m (plant {:.2} kinetic, {:.2} static); \
         K_w1 {:.0} N/m (plant {:.0}; read against cable 2's fit while slider 2 slips), \
         the cable-2 term's K_s / (c4 r - 1) {:.0} N/m (plant's cable {:.0}) from {spring}, {:.0} N/m (plant {:.0}); \
         {cable0}; \
         JAE sign term {:.3}°, JAE floor {:.3}° (model error and the sign term's uncertainty)",
        1e3 * c.fusion.pin_coulomb_nm,
        1e3 * p.joint.coulomb_nm,
        1e3 * p.joint.static_nm,
        c.stretch.cable1_n_m,
        p.cable1.stiffness_n_m,
        c.stretch.cable2_n_m,
        p.cable2.stiffness_n_m,
        c.machine.spring_n_m,
        p.spring.stiffness_n_m,
        f64::from(c.jae.c_sign_rad) * DEG_PER_RAD,
        f64::from(c.fusion.jae_error_rad) * DEG_PER_RAD,
    )
}

/// The loading protocol's results for one configuration on one plant.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Protocol {
    /// Per estimate, in [`SOURCES`] order.
    pub sources: Vec<SourceStats>,
    /// Share of hold samples (no-load and stable regions) whose applied
    /// force lies inside the fused bound.
    pub coverage: f64,
    /// Mean width of the bound in the hold samples, N.
    pub mean_bound_width_n: f64,
    /// The same two for the Kalman filters' `±2σ` intervals, in
    /// [`KALMAN`] order.
    pub kalman_coverage: Vec<f64>,
    /// Mean width of the Kalman filters' `±2σ` intervals, N.
    pub kalman_width_n: Vec<f64>,
    /// Largest peak-to-peak joint motion in a stable region, °.
    pub tip_motion_pp_deg: f64,
    /// Loading cases run.
    pub cases: usize,
    /// Faulted cases, described.
    pub faults: Vec<String>,
    /// Faults whose cause the plant's true state does not show (a slack
    /// fault with both cables above the limit, a range fault with the joint
    /// inside its range and both cables taut, any other fault): the false
    /// ones.
    pub false_faults: usize,
    /// The longest time a cable was truly slack (cable 0 or 1 carrying no
    /// tension) with the drive on and no fault latched, s: how late the
    /// checks catch a lost transmission (0 when it never happened).
    pub slack_undetected_s: f64,
    /// The case of that longest stretch (empty when none).
    pub slack_undetected_case: String,
    /// The most rope that hung loose (cable 0 or 1 shorter than its
    /// zero-tension length, [`crate::plant::Tensions::slack_m`]) with the
    /// drive on and no fault latched, m, over every case: how far a slack
    /// cable was let go before the checks or the payout stop caught it.
    pub slack_undetected_m: f64,
}

/// Run the seed's loading protocol (every angle, weight and direction) on
/// `plant` with `config`; `label` names the runs (seeds, progress).
pub fn run_protocol(plant: &PlantParams, config: &Config, s: &Settings, label: &str) -> Protocol {
    let mut out = Protocol::default();
    let mut above: [Vec<f64>; N] = Default::default();
    let mut at03: [Vec<f64>; N] = Default::default();
    let (mut stat, mut dyn_) = ([0.0f64; N], [0.0f64; N]);
    let (mut hold_n, mut hold_in, mut width, mut pp) = (0u64, 0u64, Acc::default(), 0.0f64);
    let (mut kalman_in, mut kalman_width) = ([0u64; 2], [Acc::default(), Acc::default()]);
    for a in ANGLES_DEG {
        for m in MASSES_G {
            for d in [Direction::Pos, Direction::Neg] {
                out.cases += 1;
                let case = format!("{label}/{a}/{m}/{d:?}");
                let seed = run_seed(s.seed, &case);
                let opts = ScenarioOptions {
                    duration_scale: s.scale,
                    angle_deg: Some(a),
                    mass_g: Some(m),
                    direction: Some(d),
                    ..ScenarioOptions::default()
                };
                let mut rec = CaseRec {
                    moved: a != 0.0,
                    slack_limit_n: f64::from(config.slack_limit_n()),
                    range_rad: f64::from(config.limits.max_joint_angle_rad),
                    kalman: KALMAN.map(|d| KalmanForce::new(d, config)).to_vec(),
                    ..CaseRec::default()
                };
                if let Err(e) =
                    scenario::run("loading", *plant, *config, Some(seed), &opts, &mut rec)
                {
                    out.faults
                        .push(format!("{a}° {m} g {d:?} (seed {seed}): {e:#}"));
                    out.false_faults += 1;
                    continue;
                }
                rec.close_noload();
                out.slack_undetected_m = out.slack_undetected_m.max(rec.slack_undetected_m);
                if rec.slack_undetected_s > out.slack_undetected_s {
                    out.slack_undetected_s = rec.slack_undetected_s;
                    out.slack_undetected_case = format!("{a}° {m} g {d:?}");
                }
                if let Some(f) = rec.fault {
                    out.faults
                        .push(format!("{a}° {m} g {d:?} (seed {seed}): {f}"));
                    out.false_faults += usize::from(!rec.fault_confirmed);
                    continue;
                }
                let force = d.sign() * m * 1e-3 * G_M_S2;
                for k in 0..N {
                    let mean = rec.stable[k].summary(1.0).mean;
                    let acc = 100.0 * (1.0 - (mean - force).abs() / force.abs());
                    if m >= 100.0 {
                        above[k].push(acc);
                    } else {
                        at03[k].push(acc);
                    }
                    stat[k] = stat[k].max(rec.static_noload[k].summary(1.0).max_abs());
                    if rec.moved {
                        dyn_[k] = dyn_[k].max(rec.dynamic[k].summary(1.0).max_abs());
                    }
                }
                hold_n += rec.hold_n;
                hold_in += rec.hold_in;
                width.merge(&rec.width);
                for j in 0..2 {
                    kalman_in[j] += rec.kalman_in[j];
                    kalman_width[j].merge(&rec.kalman_width[j]);
                }
                let t = rec.theta_stable.summary(1.0);
                if t.n > 0 {
                    pp = pp.max(t.max - t.min);
                }
            }
        }
    }
    let min = |v: &[f64]| v.iter().copied().fold(f64::NAN, f64::min);
    let mean = |v: &[f64]| {
        if v.is_empty() {
            f64::NAN
        } else {
            v.iter().sum::<f64>() / v.len() as f64
        }
    };
    out.sources = (0..N)
        .map(|k| SourceStats {
            above_1n_min_pct: min(&above[k]),
            above_1n_mean_pct: mean(&above[k]),
            at_0n3_min_pct: min(&at03[k]),
            static_noload_n: stat[k],
            dynamic_noload_n: dyn_[k],
        })
        .collect();
    out.coverage = if hold_n > 0 {
        hold_in as f64 / hold_n as f64
    } else {
        f64::NAN
    };
    out.mean_bound_width_n = width.summary(1.0).mean;
    let share = |n: u64| {
        if hold_n > 0 {
            n as f64 / hold_n as f64
        } else {
            f64::NAN
        }
    };
    out.kalman_coverage = kalman_in.map(share).to_vec();
    out.kalman_width_n = kalman_width.map(|w| w.summary(1.0).mean).to_vec();
    out.tip_motion_pp_deg = pp;
    out
}

/// Run one variant: identify its configuration, then the protocol passive
/// and with probing.
pub fn run_variant(v: &Variant, s: &Settings) -> VariantResult {
    let tag = format!("variant {}", v.name);
    let mut out = VariantResult {
        name: v.name.clone(),
        what: v.what.clone(),
        rate_hz: v.rate_hz,
        error: None,
        notes: Vec::new(),
        pin_at_tip_n: f64::NAN,
        pin_stick_slip_step_deg: v.plant.pin_stick_slip_step_rad().map(|r| r * DEG_PER_RAD),
        jae_blind_band_deg: v.plant.jae_blind_band_rad() * DEG_PER_RAD,
        passive: Protocol {
            coverage: f64::NAN,
            mean_bound_width_n: f64::NAN,
            tip_motion_pp_deg: f64::NAN,
            ..Protocol::default()
        },
        probing: None,
        plant: v.plant,
        config: None,
    };
    let (base, _) = Config::default().at_rate(v.rate_hz);
    let config = match identify_config(&v.plant, &base, s, &tag) {
        Ok((mut c, notes)) => {
            c.cascade.payout_stop = s.payout_stop;
            out.notes = notes;
            out.notes.push(identified_vs_plant(&c, &v.plant));
            out.pin_at_tip_n = f64::from(c.fusion.pin_coulomb_nm / c.machine.gripper_length_m);
            c
        }
        Err(e) => {
            out.error = Some(format!("{e:#}"));
            return out;
        }
    };
    out.config = Some(config);
    out.passive = run_protocol(&v.plant, &config, s, &format!("variant/{}", v.name));
    let mut probed = config;
    probed.probe.enabled = true;
    out.probing = Some(run_protocol(
        &v.plant,
        &probed,
        s,
        &format!("variant/{}/probing", v.name),
    ));
    s.progress.line(
        &tag,
        &format!(
            "done: coverage {:.1} %, fused worst >= 1 N {:.1} %, with probing {:.1} %",
            100.0 * out.passive.coverage,
            out.passive
                .sources
                .get(2)
                .map_or(f64::NAN, |x| x.above_1n_min_pct),
            out.probing
                .as_ref()
                .and_then(|p| p.sources.get(2))
                .map_or(f64::NAN, |x| x.above_1n_min_pct)
        ),
    );
    out
}

/// Run every variant.
pub fn run_all(s: &Settings) -> Vec<VariantResult> {
    for_settings(s).iter().map(|v| run_variant(v, s)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plant::{PlantState, Tensions};
    use cable_joint::{Output, RawSample};

    /// The variant's note gives cable 0's stiffness as read against the
    /// plant's rope, or says it was not read and the check keeps cable 1's
    /// bound.
    #[test]
    fn the_note_gives_cable_0_s_reading_against_the_plant_s_rope() {
        let plant = PlantParams::default();
        let mut c = Config::default();
        c.stretch.cable0_n_m = (0.9 * plant.cable0.stiffness_n_m) as f32;
        let read = identified_vs_plant(&c, &plant);
        assert!(read.contains("0.900 of the plant's"), "{read}");
        c.stretch.cable0_n_m = 0.0;
        let unread = identified_vs_plant(&c, &plant);
        assert!(unread.contains("K_w0 not read"), "{unread}");
    }

    fn tick(rope_n: f64, cable1_n: f64, theta_rad: f64) -> TickRecord {
        TickRecord {
            tick: 10,
            t_s: 1.5,
            raw: RawSample::default(),
            output: Output::default(),
            sources: Default::default(),
            drive_ref_a: 0.0,
            state: PlantState {
                theta_rad,
                ..PlantState::default()
            },
            tensions: Tensions {
                rope_n,
                cable1_n,
                ..Tensions::default()
            },
            torque_constant_nm_a: 0.0234,
            f_ext_n: 0.0,
            phase: 0,
            origin: RawSample::default(),
        }
    }

    /// A case recorder with the default plant's slack limit and range.
    fn case_rec() -> CaseRec {
        CaseRec {
            slack_limit_n: 3.9,
            range_rad: 1.5,
            ..CaseRec::default()
        }
    }

    #[test]
    fn a_fault_is_true_only_when_the_plants_state_shows_its_cause() {
        let mut rec = case_rec();
        let msg = rec.judge(&tick(0.2, 6.0, 0.0), Fault::TransmissionSlack);
        assert!(rec.fault_confirmed, "cable 0 slack: {msg}");
        rec.judge(&tick(6.0, 3.0, 0.0), Fault::TransmissionSlack);
        assert!(rec.fault_confirmed, "cable 1 slack");
        let msg = rec.judge(&tick(4.3, 4.5, 0.0), Fault::TransmissionSlack);
        assert!(!rec.fault_confirmed && msg.ends_with("FALSE)"), "{msg}");
        rec.judge(&tick(10.0, 10.0, -1.6), Fault::AngleRange);
        assert!(rec.fault_confirmed, "out of range");
        rec.judge(&tick(10.0, 10.0, -1.4), Fault::AngleRange);
        assert!(!rec.fault_confirmed, "inside the range");
        rec.judge(&tick(0.0, 6.0, -1.4), Fault::AngleRange);
        assert!(
            rec.fault_confirmed,
            "inside the range, but cable 0 slack: the joint runs free"
        );
        rec.judge(&tick(10.0, 10.0, 0.0), Fault::Overrun);
        assert!(!rec.fault_confirmed, "no plant check: counted false");
        rec.judge(&tick(0.0, 6.0, 0.0), Fault::Cable0Slack);
        assert!(rec.fault_confirmed, "cable 0 slack, read by the motor");
        rec.judge(&tick(5.0, 6.0, 0.0), Fault::Cable0Slack);
        assert!(!rec.fault_confirmed, "both cables above the limit");
    }

    #[test]
    fn every_variant_has_its_own_directory_name() {
        let names: Vec<String> = variants().iter().map(|v| dir_name(&v.name)).collect();
        assert!(names.contains(&"draw-13-1-khz".to_owned()), "{names:?}");
        let mut unique = names.clone();
        unique.sort();
        unique.dedup();
        assert_eq!(unique.len(), names.len(), "{names:?}");
        for n in &names {
            assert!(
                !n.is_empty()
                    && n.chars()
                        .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-')
            );
        }
    }

    /// A cable carrying no tension with the drive on counts as undetected
    /// until the tick its fault latches (drive off); a taut tick in
    /// between (even one below the checks' limit) ends a stretch. The most
    /// rope loose is taken over the same ticks.
    #[test]
    fn slack_counts_as_undetected_from_the_first_slack_tick_to_the_fault() {
        let mut rec = case_rec();
        let at = |t_s: f64, rope_n: f64, fault: Option<Fault>| {
            let mut r = tick(rope_n, 6.0, 0.0);
            r.t_s = t_s;
            r.output.drive_enable = fault.is_none();
            r.output.fault = fault;
            // The rope's slack grows with time while it carries nothing.
            r.tensions.slack_m = if rope_n > 0.0 { 0.0 } else { 1e-6 * t_s };
            r
        };
        rec.record(&at(1.0, 0.0, None));
        rec.record(&at(1.1, 0.0, None));
        rec.record(&at(1.2, 1.0, None));
        assert!((rec.slack_undetected_s - 0.1).abs() < 1e-12);
        for k in 0..=30 {
            rec.record(&at(2.0 + 0.01 * f64::from(k), 0.0, None));
        }
        rec.record(&at(2.35, 0.0, Some(Fault::Cable0Slack)));
        rec.record(&at(3.0, 0.0, None));
        assert!(
            (rec.slack_undetected_s - 0.3).abs() < 1e-9,
            "{}",
            rec.slack_undetected_s
        );
        assert!(rec.fault_confirmed);
        // The most rope loose before the fault (2.30 s), not at or after it.
        assert!(
            (rec.slack_undetected_m - 2.30e-6).abs() < 1e-12,
            "{}",
            rec.slack_undetected_m
        );
    }
}
