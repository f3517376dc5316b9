//! The report's experiments: scenario runs with recorders that keep the
//! statistics the seed reports and decimated traces for the figures.

use cable_joint::{Config, Mode};
use serde::Serialize;

use crate::log::Log;
use crate::plant::PlantParams;
use crate::scenario::{self, Direction, Phase, ScenarioOptions};
use crate::sim::{LogRecorder, Recorder, TickRecord};
use crate::stats::Acc;
use crate::stats::{Summary, DEG_PER_RAD};

/// Keep every `TRACE_EVERY`-th tick in the figure traces (500 Hz at 2 kHz).
pub const TRACE_EVERY: u64 = 4;

fn fault_text(r: &TickRecord) -> Option<String> {
    r.output.fault.map(|f| format!("{f} (t = {:.2} s)", r.t_s))
}

/// Whether the controller was running this tick.
fn active(r: &TickRecord) -> bool {
    r.output.drive_enable && r.output.mode != Mode::Idle && r.output.fault.is_none()
}

/// Decimated trace of a tracking run, degrees.
#[derive(Clone, Debug, Default)]
pub struct TrackTrace {
    /// Time, s.
    pub t_s: Vec<f64>,
    /// Desired angle, °.
    pub desired_deg: Vec<f64>,
    /// Actual angle (magnetic encoder), °.
    pub actual_deg: Vec<f64>,
    /// Estimated angle (JAE), °.
    pub estimated_deg: Vec<f64>,
    /// Applied tip force, N.
    pub f_ext_n: Vec<f64>,
    /// Estimated tip force, N.
    pub f_ext_hat_n: Vec<f64>,
}

/// Result of a tracking scenario (seed Figs. 10, 12, 13).
#[derive(Clone, Debug)]
pub struct TrackRun {
    /// Scenario.
    pub scenario: &'static str,
    /// Noise seed.
    pub seed: u64,
    /// Desired − actual (magnetic encoder), °, over the tracking phase.
    pub desired_minus_actual: Summary,
    /// Actual − estimated (JAE), °, same ticks.
    pub actual_minus_estimated: Summary,
    /// The plant's true joint angle − estimated (JAE), °, same ticks: the
    /// estimator's error without the magnetic encoder's quantum (a
    /// simulator's figure; a rig has only the encoder).
    pub true_minus_estimated: Summary,
    /// Latched fault, if any.
    pub fault: Option<String>,
    /// Figure trace (every phase).
    pub trace: TrackTrace,
}

#[derive(Default)]
struct TrackRec {
    da: Acc,
    ae: Acc,
    te: Acc,
    fault: Option<String>,
    trace: TrackTrace,
}

impl Recorder for TrackRec {
    fn record(&mut self, r: &TickRecord) {
        if self.fault.is_none() {
            self.fault = fault_text(r);
        }
        let e = &r.output.est;
        if r.tick.is_multiple_of(TRACE_EVERY) {
            let t = &mut self.trace;
            t.t_s.push(r.t_s);
            t.desired_deg.push(f64::from(e.theta_ref_rad) * DEG_PER_RAD);
            t.actual_deg.push(f64::from(e.theta_mag_rad) * DEG_PER_RAD);
            t.estimated_deg
                .push(f64::from(e.theta_hat_rad) * DEG_PER_RAD);
            t.f_ext_n.push(r.f_ext_n);
            t.f_ext_hat_n.push(f64::from(e.f_ext_hat_n));
        }
        if active(r) && r.phase == Phase::Track.code() {
            self.da.push(f64::from(e.theta_ref_rad - e.theta_mag_rad));
            self.ae.push(f64::from(e.theta_mag_rad - e.theta_hat_rad));
            self.te.push(r.state.theta_rad - f64::from(e.theta_hat_rad));
        }
    }
}

/// Run a tracking scenario (`track-motor`, `track-jae`, `robust-2n5`).
pub fn tracking(
    name: &'static str,
    plant: &PlantParams,
    config: &Config,
    seed: u64,
    scale: f64,
) -> anyhow::Result<TrackRun> {
    let opts = ScenarioOptions {
        duration_scale: scale,
        ..ScenarioOptions::default()
    };
    let mut rec = TrackRec::default();
    scenario::run(name, *plant, *config, Some(seed), &opts, &mut rec)?;
    Ok(TrackRun {
        scenario: name,
        seed,
        desired_minus_actual: rec.da.summary(DEG_PER_RAD),
        actual_minus_estimated: rec.ae.summary(DEG_PER_RAD),
        true_minus_estimated: rec.te.summary(DEG_PER_RAD),
        fault: rec.fault,
        trace: rec.trace,
    })
}

/// Run a scenario and keep its full CSV log (for the identifications), and
/// the fault it latched.
pub fn logged(
    name: &str,
    plant: &PlantParams,
    config: &Config,
    seed: u64,
    scale: f64,
) -> anyhow::Result<(Log, Option<String>)> {
    let opts = ScenarioOptions {
        duration_scale: scale,
        ..ScenarioOptions::default()
    };
    logged_with(name, plant, config, seed, &opts)
}

/// [`logged`] with every scenario option.
pub fn logged_with(
    name: &str,
    plant: &PlantParams,
    config: &Config,
    seed: u64,
    opts: &ScenarioOptions,
) -> anyhow::Result<(Log, Option<String>)> {
    let mut rec = LogRecorder::new(true);
    let s = scenario::run(name, *plant, *config, Some(seed), opts, &mut rec)?;
    let fault = s.fault.map(|f| f.to_string());
    Ok((rec.to_log()?, fault))
}

/// Which tip-force estimate a loading case is judged on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ForceSource {
    /// The disturbance observer (seed Fig. 6): `f_ext_hat_n`.
    Dob,
    /// The cable-stretch estimate from both gratings: `f_ext_stretch_n`.
    Stretch,
}

impl ForceSource {
    fn of(self, e: &cable_joint::Estimates) -> f64 {
        f64::from(match self {
            ForceSource::Dob => e.f_ext_hat_n,
            ForceSource::Stretch => e.f_ext_stretch_n,
        })
    }
}

/// Decimated trace of one loading case.
#[derive(Clone, Debug, Default)]
pub struct CaseTrace {
    /// Time, s.
    pub t_s: Vec<f64>,
    /// Applied tip force, N.
    pub f_ext_n: Vec<f64>,
    /// Estimated tip force, N.
    pub f_ext_hat_n: Vec<f64>,
    /// Desired − actual joint angle, °.
    pub angle_err_deg: Vec<f64>,
    /// Scenario phase code.
    pub phase: Vec<u32>,
}

/// One case of the loading protocol (seed Sect. 4.3).
#[derive(Clone, Debug, Serialize)]
pub struct LoadCase {
    /// Held joint angle, °.
    pub angle_deg: f64,
    /// Weight, g.
    pub mass_g: f64,
    /// `pos` or `neg`.
    pub direction: &'static str,
    /// Applied force in the stable region (signed), N.
    pub force_n: f64,
    /// Mean estimate in the stable region, N.
    pub mean_estimate_n: f64,
    /// `100 (1 - |mean estimate - force| / |force|)`, %.
    pub accuracy_pct: f64,
    /// Estimate − applied in the stable region, N.
    pub stable_error_n: Summary,
    /// Estimate in the no-load region before the load (static), N.
    pub static_noload_n: Summary,
    /// Estimate while moving to the angle and settling (dynamic no-load), N;
    /// only for angles other than 0° (no motion there).
    pub dynamic_noload_n: Option<Summary>,
    /// Desired − actual joint angle while the load is on (loading, stable,
    /// unloading), °.
    pub angle_error_loaded_deg: Summary,
    /// Latched fault, if any.
    pub fault: Option<String>,
    /// Noise seed.
    pub seed: u64,
    /// Figure trace.
    #[serde(skip)]
    pub trace: CaseTrace,
}

struct CaseRec {
    source: ForceSource,
    moved: bool,
    loaded: bool,
    stable_est: Acc,
    stable_err: Acc,
    stable_force: Acc,
    static_noload: Acc,
    dynamic: Acc,
    angle: Acc,
    fault: Option<String>,
    trace: CaseTrace,
}

impl Recorder for CaseRec {
    fn record(&mut self, r: &TickRecord) {
        if self.fault.is_none() {
            self.fault = fault_text(r);
        }
        let e = &r.output.est;
        let f_hat = self.source.of(e);
        let ang = f64::from(e.theta_ref_rad - e.theta_mag_rad) * DEG_PER_RAD;
        if r.tick.is_multiple_of(TRACE_EVERY) {
            let t = &mut self.trace;
            t.t_s.push(r.t_s);
            t.f_ext_n.push(r.f_ext_n);
            t.f_ext_hat_n.push(f_hat);
            t.angle_err_deg.push(ang);
            t.phase.push(r.phase);
        }
        if !active(r) {
            return;
        }
        let p = r.phase;
        if p == Phase::Loading.code() {
            self.loaded = true;
        }
        if p == Phase::Move.code() || p == Phase::Adjust.code() {
            if self.moved {
                self.dynamic.push(f_hat);
            }
        } else if p == Phase::NoLoad.code() && !self.loaded {
            self.static_noload.push(f_hat);
        } else if p == Phase::Stable.code() {
            self.stable_est.push(f_hat);
            self.stable_err.push(f_hat - r.f_ext_n);
            self.stable_force.push(r.f_ext_n);
        }
        if p == Phase::Loading.code() || p == Phase::Stable.code() || p == Phase::Unloading.code() {
            self.angle.push(ang);
        }
    }
}

/// Run one case of the loading protocol on its own (a fault ends only this
/// case): `(angle_deg, mass_g, direction)`, judged on `source`.
pub fn loading_case(
    plant: &PlantParams,
    config: &Config,
    seed: u64,
    scale: f64,
    (angle_deg, mass_g, direction): (f64, f64, Direction),
    source: ForceSource,
) -> anyhow::Result<LoadCase> {
    let opts = ScenarioOptions {
        duration_scale: scale,
        angle_deg: Some(angle_deg),
        mass_g: Some(mass_g),
        direction: Some(direction),
        ..ScenarioOptions::default()
    };
    let mut rec = CaseRec {
        source,
        moved: angle_deg != 0.0,
        loaded: false,
        stable_est: Acc::default(),
        stable_err: Acc::default(),
        stable_force: Acc::default(),
        static_noload: Acc::default(),
        dynamic: Acc::default(),
        angle: Acc::default(),
        fault: None,
        trace: CaseTrace::default(),
    };
    scenario::run("loading", *plant, *config, Some(seed), &opts, &mut rec)?;
    let force_n = direction.sign() * mass_g * 1e-3 * scenario::G_M_S2;
    let est = rec.stable_est.summary(1.0);
    let accuracy_pct = 100.0 * (1.0 - (est.mean - force_n).abs() / force_n.abs());
    Ok(LoadCase {
        angle_deg,
        mass_g,
        direction: match direction {
            Direction::Pos => "pos",
            Direction::Neg => "neg",
        },
        force_n,
        mean_estimate_n: est.mean,
        accuracy_pct,
        stable_error_n: rec.stable_err.summary(1.0),
        static_noload_n: rec.static_noload.summary(1.0),
        dynamic_noload_n: rec.moved.then(|| rec.dynamic.summary(1.0)),
        angle_error_loaded_deg: rec.angle.summary(1.0),
        fault: rec.fault,
        seed,
        trace: rec.trace,
    })
}
