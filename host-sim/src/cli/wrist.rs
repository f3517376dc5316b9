//! `host-sim identify-wrist` (Eq. 3 on a rig's free run, recorded as one
//! log per joint) and `host-sim simulate-wrist` (the simulated wrist's free
//! run written the same way): their arguments, runs and printing.

use std::path::{Path, PathBuf};

use anyhow::{ensure, Context, Result};
use cable_joint::wrist_dynamics::InverseDynamics;
use cable_joint::wrist_dynamics::{N_PARAMS, PARAM_NAMES};
use cable_joint::Config;
use serde::{Deserialize, Serialize};

use crate::cli;
use crate::ident::excite_wrist::WristDesign;
use crate::links::{self, fit_eq3, FreeRun, InverseDynamicsFit, Links, NoLoad};
use crate::output::Outputs;
use crate::plant::PlantParams;
use crate::report::render::fmt_num;
use crate::scenario::{oracle_config, tuned_gains};
use crate::wrist::{run_grasp, Eq3Model, Grasp, WristParams};
use crate::wrist_estimate;
use crate::wrist_log::{self, Holding, OnFault, WristRun, JOINT_NAMES};

/// A wrist's recorded run and what its logs cannot say: the options
/// `identify-wrist` and `estimate-wrist` share.
#[derive(clap::Args, Debug, Clone)]
pub struct WristRunArgs {
    /// Directory of the run: `roll.csv`, `pitch.csv`, `jaw_a.csv`,
    /// `jaw_b.csv`, each joint's log in the project's CSV schema
    /// (`host-sim link ... --record roll.csv` on each joint's controller,
    /// or `host-sim simulate-wrist`). Logs with the host's clock
    /// (`t_unix_s`, which `link` writes) are aligned on it; others must
    /// have been started together.
    #[arg(long, value_name = "DIR")]
    pub run: PathBuf,
    /// Every joint's configuration (TOML). Without it each joint's is the
    /// file beside its log (`roll.toml`, ...: its controller's own, as
    /// `host-sim identify` wrote it), else the datasheet values; which one
    /// each joint used is printed.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Gravity in the shaft frame, m/s², `GX,GY,GZ`: how the instrument was
    /// held (`cable_joint::wrist`'s frame: `z_0` along the shaft; the
    /// simulated prototype's `-8.496,-4.905,0`, shaft level and turned
    /// 30° about it). The logs cannot say it.
    #[arg(allow_hyphen_values = true, long, value_delimiter = ',', required = true,
          value_parser = cli::f64_in(-100.0, 100.0), value_name = "GX,GY,GZ")]
    pub gravity: Vec<f64>,
    /// Each jaw's angle from the wrist's axis where its controller homed
    /// (its `theta = 0`), degrees (the simulated wrist's: 20).
    #[arg(allow_negative_numbers = true, long, value_parser = cli::f64_in(-90.0, 90.0))]
    pub jaw_open_deg: f64,
    /// The logs have a row every N control ticks but no `tick` column (as
    /// `estimate --ticks-per-row`).
    #[arg(long, value_name = "N")]
    pub ticks_per_row: Option<u32>,
}

impl WristRunArgs {
    /// How the wrist was held and built, from `--gravity` and
    /// `--jaw-open-deg` (a note on stderr after `command: ` when the
    /// gravity given is not 9.81 m/s² long).
    fn holding(&self, command: &str) -> Result<Holding> {
        let gravity_m_s2: [f64; 3] = self.gravity.as_slice().try_into().map_err(|_| {
            anyhow::anyhow!(
                "--gravity: expected three components GX,GY,GZ (m/s²), got {}",
                self.gravity.len()
            )
        })?;
        let g = gravity_m_s2.iter().map(|x| x * x).sum::<f64>().sqrt();
        if (g - crate::scenario::G_M_S2).abs() > 0.05 * crate::scenario::G_M_S2 {
            eprintln!(
                "{command}: note: --gravity is {g:.2} m/s² long, not 9.81: the links' moments are fitted in its scale"
            );
        }
        Ok(Holding {
            gravity_m_s2,
            jaw_open_rad: self.jaw_open_deg.to_radians(),
        })
    }
}

/// Arguments of `host-sim identify-wrist`.
#[derive(clap::Args, Debug, Clone)]
pub struct IdentifyWristArgs {
    /// The free run to fit (nothing touching the jaws) and how it was held.
    #[command(flatten)]
    pub run: WristRunArgs,
    /// Directory of another free run, the same four files, that the fit
    /// does not see: each joint's no-load error is reported on it, with
    /// and without the model.
    #[arg(long, value_name = "DIR")]
    pub validate: Option<PathBuf>,
    /// Output: the fitted model, its `%sigma`, condition numbers, the
    /// held-out check and the validation (TOML).
    #[arg(long)]
    pub out: PathBuf,
    /// Also draw, as STEM.svg and STEM.png, each joint's friction sign as
    /// the fit saw it (its Coulomb column against its speed, with the
    /// width seen and the regressor's) and, with `--validate`, the
    /// validation run's no-load force at each joint's tip, as the joint
    /// estimated it and with the model taken out, with the bound.
    #[arg(long, value_name = "STEM")]
    pub plot: Option<PathBuf>,
}

/// Arguments of `host-sim simulate-wrist`.
#[derive(clap::Args, Debug, Clone)]
pub struct SimulateWristArgs {
    /// Directory for `roll.csv`, `pitch.csv`, `jaw_a.csv`, `jaw_b.csv`
    /// (created if missing; the four written together or none).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// The run: the hand-made identification run (20 s), the validation
    /// run (10 s, other amplitudes and frequencies), or `--excitation`'s.
    #[arg(long, value_enum, default_value_t = FreeRunArg::Identification)]
    pub free_run: FreeRunArg,
    /// A design of `host-sim excite --wrist --out w.toml` (the run it
    /// names; `--free-run` is then ignored).
    #[arg(long, value_name = "W.TOML")]
    pub excitation: Option<PathBuf>,
    /// The configuration every joint's controller runs (TOML; default:
    /// the simulated plant's true values with gains that work on it, as
    /// `simulate --oracle --tuned-gains`). Written beside each log.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Every joint's plant (TOML, as `simulate --plant` takes it, e.g. a
    /// report variant's `plant.toml`; default: the datasheet prototype).
    #[arg(long)]
    pub plant: Option<PathBuf>,
    /// Every link's mass and inertia times K (a heavier instrument of the
    /// same shapes, [`Links::scaled`]; the prototype's links put about
    /// 1.5 mN at a jaw's tip).
    #[arg(allow_negative_numbers = true, long, value_name = "K", default_value_t = 1.0,
          value_parser = cli::f64_in(0.0, 1e4))]
    pub links_scale: f64,
    /// Instead of a free run, a grasp: the jaws close on a soft object
    /// (10 mm wide) to the angle that squeezes it with N at rigid jaws,
    /// hold 3 s and open again (the report's grasp); each jaw's log holds
    /// the true contact force as `f_ext_n`. The input of `estimate-wrist`.
    #[arg(long, allow_negative_numbers = true, value_name = "N",
          conflicts_with_all = ["free_run", "excitation"], value_parser = cli::f64_in(0.01, 50.0))]
    pub grasp: Option<f64>,
    /// The grasped object's stiffness, N/m.
    #[arg(long, allow_negative_numbers = true, value_name = "N_PER_M",
          default_value_t = crate::report::wrist::STIFFNESS_N_M[0], requires = "grasp",
          value_parser = cli::f64_in(1.0, 1e7))]
    pub object_stiffness: f64,
    /// Noise seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// Arguments of `host-sim estimate-wrist`.
#[derive(clap::Args, Debug, Clone)]
pub struct EstimateWristArgs {
    /// The run to estimate and how it was held.
    #[command(flatten)]
    pub run: WristRunArgs,
    /// Eq. 3's model (`identify-wrist --out`), taken out of every joint's
    /// estimate before Eq. 4; without it, none (the links and the joints'
    /// residual friction stay in the forces).
    #[arg(long, value_name = "EQ3.TOML")]
    pub eq3: Option<PathBuf>,
    /// Output: per tick each joint's external torque and bound, each jaw's
    /// `F_y` bound, the clamp force and its bound, and the reference clamp
    /// force where the jaws' logs have `f_ext_n` (CSV).
    #[arg(long)]
    pub out: PathBuf,
    /// Also draw the clamp force in its bound (and the reference) and each
    /// joint's external torque against time, as STEM.svg and STEM.png.
    #[arg(long, value_name = "STEM")]
    pub plot: Option<PathBuf>,
    /// The largest force either jaw carries along any axis, N: it bounds
    /// the part of Eq. 5's total force the joints do not see. Default: the
    /// jaws' drive squeeze at their current limit (their configurations);
    /// your task's bound (a tissue's largest push) narrows the total's
    /// bound.
    #[arg(long, value_name = "N", allow_negative_numbers = true)]
    pub force_limit_n: Option<f32>,
}

/// `simulate-wrist --free-run`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum FreeRunArg {
    /// [`FreeRun::identification`].
    Identification,
    /// [`FreeRun::validation`].
    Validation,
}

/// The simulated wrist `simulate-wrist` runs: the default plant at every
/// joint with `config` (default: [`oracle_config`] of it with
/// [`tuned_gains`]), the prototype's links held as [`Links::prototype`]
/// says.
pub fn simulated_wrist(config: Option<Config>) -> WristParams {
    simulated_wrist_on(PlantParams::default(), config)
}

/// [`simulated_wrist`] with `plant` at every joint (the configuration's
/// default is that plant's true values).
pub fn simulated_wrist_on(plant: PlantParams, config: Option<Config>) -> WristParams {
    let config = config.unwrap_or_else(|| oracle_config(&plant, &tuned_gains(&Config::default())));
    WristParams {
        links: Some(Links::prototype()),
        ..WristParams::uniform(plant, config)
    }
}

/// `host-sim simulate-wrist`.
pub fn run_simulate(args: SimulateWristArgs) -> Result<()> {
    const COMMAND: &str = "simulate-wrist";
    let config = match &args.config {
        Some(p) => Some(crate::io::config::load_config(p)?),
        None => None,
    };
    let plant = crate::io::config::load_plant(args.plant.as_deref())?;
    let mut params = simulated_wrist_on(plant, config);
    params.links = params.links.map(|l| l.scaled(args.links_scale));
    let ticks = match args.grasp {
        Some(target_n) => {
            let grasp = Grasp {
                target_n,
                ..Grasp::default()
            };
            eprintln!(
                "{COMMAND}: a grasp of a {:.0} N/m object to {target_n} N: {:.1} s open, {:.1} s closing, {:.1} s holding, {:.1} s opening, {:.1} s open ...",
                args.object_stiffness,
                grasp.settle_s,
                grasp.move_s,
                grasp.hold_s,
                grasp.move_s,
                grasp.after_s
            );
            let object = crate::report::wrist::object(args.object_stiffness);
            run_grasp(&params, object, &grasp, args.seed)?
                .into_iter()
                .map(|(_, t)| t)
                .collect()
        }
        None => {
            let run = free_run(&args)?;
            eprintln!(
                "{COMMAND}: {:.1} s at rest, then {:.1} s of motion ...",
                run.settle_s, run.duration_s
            );
            links::run_free_settled(&params, &run, args.seed)?.0
        }
    };
    let logs = wrist_log::joint_logs(&params, &ticks)?;
    let mut out = Outputs::new();
    out.create_dir(&args.out)?;
    let paths = wrist_log::stage_joint_logs(&mut out, &args.out, &logs)?;
    for (name, config) in JOINT_NAMES.iter().zip(&params.configs) {
        crate::io::config::stage_config(&mut out, args.out.join(format!("{name}.toml")), config)?;
    }
    out.commit()?;
    let [gx, gy, gz] = Links::prototype().gravity_m_s2;
    let (what, command, out) = match args.grasp {
        Some(_) => (
            "estimate its forces",
            "estimate-wrist",
            "[--eq3 eq3.toml] --out forces.csv",
        ),
        None => ("fit Eq. 3", "identify-wrist", "--out eq3.toml"),
    };
    let next = format!(
        "{what} with `host-sim {command} --run {} --gravity {gx:.3},{gy:.3},{gz:.3} --jaw-open-deg {} {out}`",
        crate::cli::shell_word(&args.out),
        params.jaw_open_rad.to_degrees().round()
    );
    crate::stdoutln!(
        "wrote {} ({} ticks each) and each joint's configuration beside its log: {next}",
        paths
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", "),
        ticks.len(),
    );
    Ok(())
}

/// The free run `simulate-wrist` runs: `--excitation`'s design, else
/// `--free-run`'s.
fn free_run(args: &SimulateWristArgs) -> Result<FreeRun> {
    let Some(path) = &args.excitation else {
        return Ok(match args.free_run {
            FreeRunArg::Identification => FreeRun::identification(),
            FreeRunArg::Validation => FreeRun::validation(),
        });
    };
    let design: WristDesign =
        crate::io::read_toml(path, "a wrist design of `host-sim excite --wrist`")?;
    Ok(FreeRun::designed(&design))
}

/// What `estimate-wrist` and `simulate-wrist` read of `identify-wrist
/// --out`'s file.
#[derive(Deserialize)]
struct Eq3FileIn {
    parameter_names: Vec<String>,
    fit: Eq3FitIn,
}

/// The fit's fields [`load_eq3`] needs.
#[derive(Deserialize)]
struct Eq3FitIn {
    body: InverseDynamics,
    motion_bandwidth_hz: f32,
    kept: bool,
}

/// Eq. 3's model in `path` (`identify-wrist --out`), evaluated under
/// `gravity_m_s2`: its parameters are the links' mass moments, which do not
/// depend on how the instrument is held, so a model fitted held one way
/// serves a run held another (a note after `command: ` says so).
///
/// # Errors
/// Not such a file, another parameter list, a model its own run did not
/// keep, a parameter that is not finite.
pub fn load_eq3(path: &Path, gravity_m_s2: [f64; 3], command: &str) -> Result<Eq3Model> {
    let file: Eq3FileIn =
        crate::io::read_toml(path, "an Eq. 3 model of `host-sim identify-wrist --out`")?;
    ensure!(
        file.parameter_names
            .iter()
            .map(String::as_str)
            .eq(PARAM_NAMES),
        "{}: its parameters are [{}], this version's Eq. 3 has [{}]: fit it again with this \
         version's `identify-wrist`",
        path.display(),
        file.parameter_names.join(", "),
        PARAM_NAMES.join(", ")
    );
    ensure!(
        file.fit.kept,
        "{}: the model was not kept (it did not cut the torque on the part of its own run it \
         did not fit): run without it",
        path.display()
    );
    let mut body = file.fit.body;
    if let Some(k) = body.params.iter().position(|p| !p.is_finite()) {
        anyhow::bail!(
            "{}: parameter {} is {}",
            path.display(),
            PARAM_NAMES[k],
            body.params[k]
        );
    }
    if let Some(k) = body
        .std_dev
        .iter()
        .position(|s| !(s.is_finite() && *s >= 0.0))
    {
        anyhow::bail!(
            "{}: fit.body.std_dev of {} is {}: a standard deviation, finite and not negative",
            path.display(),
            PARAM_NAMES[k],
            body.std_dev[k]
        );
    }
    if let Some(j) = body
        .sign_speed_rad_s
        .iter()
        .position(|v| !(v.is_finite() && *v > 0.0))
    {
        anyhow::bail!(
            "{}: fit.body.sign_speed_rad_s of joint {} is {}: the speed at which its friction's \
             sign is tanh 1, a positive number of rad/s (zero, negative or not a number would \
             flip or break every friction torque)",
            path.display(),
            JOINT_NAMES[j],
            body.sign_speed_rad_s[j]
        );
    }
    ensure!(
        file.fit.motion_bandwidth_hz.is_finite() && file.fit.motion_bandwidth_hz > 0.0,
        "{}: fit.motion_bandwidth_hz is {}: a positive bandwidth, Hz",
        path.display(),
        file.fit.motion_bandwidth_hz
    );
    let g = gravity_m_s2.map(|x| x as f32);
    let apart = (0..3)
        .map(|i| (g[i] - body.gravity_m_s2[i]).abs())
        .fold(0.0, f32::max);
    if apart > 0.01 {
        eprintln!(
            "{command}: note: {} was fitted with gravity {:?} m/s² in the shaft frame, this run is held at {g:?}: the model is evaluated at this run's",
            path.display(),
            body.gravity_m_s2
        );
    }
    body.gravity_m_s2 = g;
    Ok(Eq3Model {
        body,
        motion_bandwidth_hz: file.fit.motion_bandwidth_hz,
    })
}

/// Most torque Eq. 3's model may put on a joint, as a multiple of what
/// the joint's drive holds at its current limit (the jaws' squeeze limit
/// at their length): a model that reaches a hundred times that on a run is
/// not a model of this wrist (a corrupt or hand-edited parameter), and its
/// torque would swamp every force and empty Eq. 5's total-force bound.
const EQ3_TORQUE_LIMIT_DRIVES: f64 = 100.0;

/// Eq. 3's torque on `run` (in `ticks`) within [`EQ3_TORQUE_LIMIT_DRIVES`]
/// times a joint's drive torque.
fn check_eq3_torque(
    path: &Path,
    ticks: &[wrist_estimate::WristEstimate],
    rate_hz: f64,
    drive_nm: f64,
) -> Result<()> {
    let limit_nm = EQ3_TORQUE_LIMIT_DRIVES * drive_nm;
    for (k, t) in ticks.iter().enumerate() {
        if let Some(j) = t
            .links_hat_nm
            .iter()
            .position(|v| !v.is_finite() || f64::from(*v).abs() > limit_nm)
        {
            anyhow::bail!(
                "{}: Eq. 3's torque on joint {} is {:e} N·m at t = {:.4} s of the run, beyond a \
                 hundred times the {drive_nm:.3} N·m a joint's drive holds ({limit_nm:.0} N·m): \
                 not a model of this wrist (check its parameters, or fit it again with \
                 `identify-wrist`)",
                path.display(),
                JOINT_NAMES[j],
                t.links_hat_nm[j],
                k as f64 / rate_hz
            );
        }
    }
    Ok(())
}

/// `host-sim estimate-wrist`.
pub fn run_estimate(args: EstimateWristArgs) -> Result<()> {
    const COMMAND: &str = "estimate-wrist";
    let holding = args.run.holding(COMMAND)?;
    let model = match &args.eq3 {
        Some(p) => Some(load_eq3(p, holding.gravity_m_s2, COMMAND)?),
        None => None,
    };
    if let Some(limit) = args.force_limit_n {
        ensure!(
            limit.is_finite() && limit > 0.0,
            "{COMMAND}: --force-limit-n {limit} is not a force limit: a positive number of \
             newtons (the largest force either jaw carries along any axis)"
        );
    }
    let dir = &args.run.run;
    let (_, mut run) = replay_run(dir, &args.run, &holding, OnFault::Cut, COMMAND)?;
    // A joint's drive torque: the jaws' squeeze at their current limit, at
    // their length (their configurations'; before --force-limit-n).
    let drive_nm = {
        let g = &run.setting.geometry;
        f64::from(g.force_limit_n) * f64::from(g.jaw_length_m)
    };
    if let Some(limit) = args.force_limit_n {
        run.setting.geometry.force_limit_n = limit;
    }
    let ticks = wrist_estimate::estimate(&run, model.as_ref());
    if let (Some(p), Some(_)) = (&args.eq3, &model) {
        check_eq3_torque(p, &ticks, run.rate_hz, drive_nm)?;
    }
    // Eq. 5's total solves 210 small systems a tick: once, for the CSV and
    // the summary.
    let g = &run.setting.geometry;
    let totals: Vec<_> = ticks.iter().map(|t| t.force.total(g)).collect();
    let log = wrist_estimate::to_log(&ticks, &totals, run.rate_hz)?;
    // The CSV and the figure are written together or not at all.
    let mut files = Outputs::new();
    log.stage(&mut files, &args.out)?;
    let figures = match &args.plot {
        Some(stem) => {
            let title = dir.display().to_string();
            let fig = wrist_estimate::figure(&log, &title, run.gripper_length_m)?;
            crate::plot::stage_figure(&mut files, &fig, stem)?.to_vec()
        }
        None => Vec::new(),
    };
    files.commit()?;
    crate::stdoutln!(
        "Eq. 3: {}",
        match &args.eq3 {
            Some(p) => format!("{} taken out of every joint's estimate", p.display()),
            None =>
                "none (no --eq3: the links and the joints' residual friction stay in)".to_owned(),
        }
    );
    report_total(&ticks, &totals, g.force_limit_n);
    match wrist_estimate::summary(&ticks) {
        Some(s) => report_summary(&s),
        None => crate::stdoutln!(
            "no reference: the jaws' logs have no f_ext_n, so the estimate is not judged"
        ),
    }
    crate::stdoutln!("wrote {} ({} rows)", args.out.display(), ticks.len());
    for f in &figures {
        crate::stdoutln!("wrote {}", f.display());
    }
    Ok(())
}

/// Print how much of Eq. 5's total force the joints see: each wrist axis'
/// median bound width and the force limit's share of it, over the ticks
/// the jaws hold at least [`wrist_estimate::HOLDING_N`] (by the reference,
/// else by the clamp estimate).
fn report_total(
    ticks: &[wrist_estimate::WristEstimate],
    totals: &[cable_joint::wrist::TotalForce],
    force_limit_n: f32,
) {
    // The limit is the user's claim on each jaw's force; a jaw whose own
    // Eq. 4 bound lies wholly beyond it on some component contradicts it.
    let beyond = |t: &wrist_estimate::WristEstimate| {
        t.force
            .jaws
            .iter()
            .flat_map(|j| j.force_n)
            .filter(|b| b.lo.is_finite() && b.hi.is_finite())
            .map(|b| b.abs().lo)
            .fold(0.0f32, f32::max)
    };
    let contradicted: Vec<f32> = ticks
        .iter()
        .map(beyond)
        .filter(|&f| f > force_limit_n)
        .collect();
    if let Some(most) = contradicted.iter().copied().reduce(f32::max) {
        crate::stdoutln!(
            "warning: the force limit ({} N) is below what the jaws' own estimates hold \
             on {} of {} ticks (a component's whole bound beyond ±limit, at least \
             {most:.3} N on one tick): there the total's bound rests on a limit the run \
             contradicts; give --force-limit-n at least {most:.3}",
            fmt_num(f64::from(force_limit_n)),
            contradicted.len(),
            ticks.len()
        );
    }
    let held: Vec<_> = ticks
        .iter()
        .zip(totals)
        .filter(|(t, _)| t.reference_n.unwrap_or(t.force.clamp_n) >= wrist_estimate::HOLDING_N)
        .map(|(_, total)| *total)
        .collect();
    let n = held.len();
    if n == 0 {
        return;
    }
    let s = crate::wrist::TotalSpread::of(&held);
    let axis = |k: usize| {
        format!(
            "{} {:.3} N ({:.0} % the limit's)",
            ["x", "y", "z"][k],
            s.width_n[k],
            100.0 * s.limit_share[k]
        )
    };
    crate::stdoutln!(
        "total force (Eq. 5, the four joints together; force limit {} N), \
         median bound width while holding ({n} ticks): {}, {}, {}; an axis mostly the limit's \
         is one the joints do not see (total_<axis>_limit_n in the CSV)",
        fmt_num(f64::from(force_limit_n)),
        axis(0),
        axis(1),
        axis(2)
    );
}

/// Print how the clamp estimate met the reference.
fn report_summary(s: &wrist_estimate::Summary) {
    if s.holding > 0 {
        crate::stdoutln!(
            "holding (reference clamp force >= {} N, {} ticks): clamp error RMS {:.3} N, worst {:.1} % of the reference; bound holds the reference {:.1} %",
            wrist_estimate::HOLDING_N,
            s.holding,
            s.holding_rms_n,
            s.holding_worst_pct,
            100.0 * s.holding_coverage
        );
    } else {
        crate::stdoutln!(
            "holding: no tick with a reference clamp force of {} N or more",
            wrist_estimate::HOLDING_N
        );
    }
    if s.open > 0 {
        crate::stdoutln!(
            "open (reference <= {} N, {} ticks): largest |clamp estimate| {:.3} N",
            wrist_estimate::OPEN_N,
            s.open,
            s.open_max_n
        );
    }
    crate::stdoutln!(
        "whole run ({} ticks with a reference): bound holds the reference {:.1} %",
        s.with_reference,
        100.0 * s.coverage
    );
}

/// What `identify-wrist --out` writes.
#[derive(Serialize)]
struct Eq3File<'a> {
    /// The command and its run.
    written_by: String,
    /// The parameters' names, in the model's order.
    parameter_names: [&'static str; N_PARAMS],
    /// The fit.
    fit: &'a InverseDynamicsFit,
    /// The validation run's no-load errors, if one was given.
    validation: Option<Validation>,
}

/// `identify-wrist --validate`'s figures.
#[derive(Serialize)]
struct Validation {
    /// The directory.
    run: String,
    /// Each joint's RMS estimate (true force zero) and bound coverage,
    /// raw and with the model (`links_rms_n` is not known on a log: 0).
    no_load: NoLoad,
}

/// The four logs of `dir`, read.
fn read_run(
    dir: &Path,
    ticks_per_row: Option<u32>,
    command: &str,
) -> Result<[(String, crate::log::Log); 4]> {
    ensure!(
        dir.is_dir(),
        "{} is not a directory: a wrist's run is a directory of {}",
        dir.display(),
        JOINT_NAMES.map(|n| format!("{n}.csv")).join(", ")
    );
    let mut logs = Vec::with_capacity(4);
    for name in JOINT_NAMES {
        let path = dir.join(format!("{name}.csv"));
        ensure!(
            path.is_file(),
            "{}: {}no log of joint {name} (the run needs {})",
            path.display(),
            if path.exists() {
                "not a regular file: "
            } else {
                ""
            },
            JOINT_NAMES.map(|n| format!("{n}.csv")).join(", ")
        );
        logs.push(wrist_log::read(&path, ticks_per_row, command)?);
    }
    logs.try_into()
        .map_err(|_| anyhow::anyhow!("four joints' logs"))
}

/// The four joints' configurations for the run in `dir` (its `logs`):
/// `config` for all, else the file beside each joint's log, else the
/// datasheet values; with what each one is. A file is taken at its log's
/// control rate (`io::config::load_config_for_logs`), what that changed
/// printed after `command: `.
fn configs(
    config: Option<&Path>,
    dir: &Path,
    logs: &[(String, crate::log::Log); 4],
    command: &str,
) -> Result<[(Config, String); 4]> {
    let load = |p: &Path, logs: &[(&str, &crate::log::Log)]| -> Result<Config> {
        let (c, notes) = crate::io::config::load_config_for_logs(p, logs)?;
        for n in notes {
            eprintln!("{command}: {}: {n}", p.display());
        }
        Ok(c)
    };
    if let Some(p) = config {
        let named: Vec<_> = logs.iter().map(|(n, l)| (n.as_str(), l)).collect();
        let c = load(p, &named)?;
        return Ok([0; 4].map(|_| (c, p.display().to_string())));
    }
    let mut out = Vec::with_capacity(4);
    for (name, (log_name, log)) in JOINT_NAMES.iter().zip(logs) {
        let path = dir.join(format!("{name}.toml"));
        out.push(if path.is_file() {
            (
                load(&path, &[(log_name.as_str(), log)])?,
                path.display().to_string(),
            )
        } else {
            (
                Config::default(),
                "the datasheet values (no --config, no file beside the log)".to_owned(),
            )
        });
    }
    out.try_into()
        .map_err(|_| anyhow::anyhow!("four joints' configurations"))
}

/// Read and replay the run in `dir`, its configurations as [`configs`]
/// finds them (`args.run` names the fitted run; `dir` may be another),
/// what it did printed after `command: `.
fn replay_run(
    dir: &Path,
    args: &WristRunArgs,
    holding: &Holding,
    on_fault: OnFault,
    command: &str,
) -> Result<([(String, crate::log::Log); 4], WristRun)> {
    let logs = read_run(dir, args.ticks_per_row, command)?;
    let configs = configs(args.config.as_deref(), dir, &logs, command)?;
    for ((name, log), (config, _)) in logs.iter().zip(&configs) {
        crate::estimate::check_reference_force(log, &config.machine)
            .with_context(|| name.clone())?;
    }
    for (name, (_, what)) in JOINT_NAMES.iter().zip(&configs) {
        eprintln!(
            "{command}: {}: {name}'s configuration: {what}",
            dir.display()
        );
    }
    let run = wrist_log::replay(&logs, &configs.map(|c| c.0), holding, on_fault)
        .with_context(|| format!("the run in {}", dir.display()))?;
    for n in &run.notes {
        eprintln!("{command}: {n}");
    }
    crate::stdoutln!(
        "{}: {} ticks at {} Hz ({:.1} s), four joints",
        dir.display(),
        run.samples.len(),
        run.rate_hz,
        run.samples.len() as f64 / run.rate_hz
    );
    Ok((logs, run))
}

/// `host-sim identify-wrist`.
pub fn run_identify(args: IdentifyWristArgs) -> Result<()> {
    const COMMAND: &str = "identify-wrist";
    let holding = args.run.holding(COMMAND)?;
    if let Some(v) = &args.validate {
        cli::refuse_reused_files(
            std::slice::from_ref(&args.run.run),
            std::slice::from_ref(v),
            &[],
        )?;
    }
    let dir = &args.run.run;
    let (logs, run) = replay_run(dir, &args.run, &holding, OnFault::Refuse, COMMAND)?;
    ensure!(
        run.samples.len() >= 100,
        "{}: {} ticks in common: too few to fit Eq. 3's {N_PARAMS} parameters",
        dir.display(),
        run.samples.len()
    );
    let fit = fit_eq3(&run.setting, &run.samples)
        .with_context(|| format!("fitting Eq. 3 on {}", dir.display()))?;
    report_fit(&fit, &run.setting.geometry);
    report_sign_width(&fit, &run.setting);
    // The model and the figure are written together or not at all.
    let mut files = Outputs::new();
    let mut panels = match &args.plot {
        Some(_) => {
            let rows = links::filtered_rows(&run.setting, &run.samples, fit.motion_bandwidth_hz);
            let title = dir.display().to_string();
            let v_s = run.setting.sign_speed_rad_s;
            links::sign_panels(&rows, fit.sign_width_seen_rad_s, v_s, &title)
        }
        None => Vec::new(),
    };
    let validation = match &args.validate {
        Some(dir) => {
            let (vlogs, vrun) = replay_run(dir, &args.run, &holding, OnFault::Refuse, COMMAND)?;
            let fitted: Vec<(&str, &crate::log::Log)> =
                logs.iter().map(|(n, l)| (n.as_str(), l)).collect();
            let unseen: Vec<(&str, &crate::log::Log)> =
                vlogs.iter().map(|(n, l)| (n.as_str(), l)).collect();
            cli::refuse_copies(&fitted, &unseen, &[])?;
            let model = Eq3Model {
                body: fit.body,
                motion_bandwidth_hz: fit.motion_bandwidth_hz,
            };
            let ticks = wrist_estimate::estimate(&vrun, Some(&model));
            let no_load = wrist_estimate::no_load(&vrun, &ticks);
            report_validation(dir, &no_load, fit.kept);
            if args.plot.is_some() {
                let title = dir.display().to_string();
                panels.extend(wrist_estimate::no_load_panels(&vrun, &ticks, &title));
            }
            Some(Validation {
                run: dir.display().to_string(),
                no_load,
            })
        }
        None => None,
    };
    let figures = match &args.plot {
        Some(stem) => {
            let fig = crate::plot::Figure::grid(panels, 2);
            crate::plot::stage_figure(&mut files, &fig, stem)?.to_vec()
        }
        None => Vec::new(),
    };
    let file = Eq3File {
        written_by: format!(
            "host-sim {} identify-wrist on {} ({} ticks at {} Hz)",
            env!("CARGO_PKG_VERSION"),
            dir.display(),
            run.samples.len(),
            run.rate_hz
        ),
        parameter_names: PARAM_NAMES,
        fit: &fit,
        validation,
    };
    files
        .bytes(&args.out, toml::to_string_pretty(&file)?.as_bytes())
        .with_context(|| format!("writing {}", args.out.display()))?;
    files.commit()?;
    crate::stdoutln!("wrote {}", args.out.display());
    for f in &figures {
        crate::stdoutln!("wrote {}", f.display());
    }
    Ok(())
}

/// Print each joint's friction sign as the fit saw it
/// ([`InverseDynamicsFit::sign_width_seen_rad_s`]) against the
/// regressor's own width.
fn report_sign_width(fit: &InverseDynamicsFit, setting: &links::Eq3Setting) {
    let each: Vec<String> = JOINT_NAMES
        .iter()
        .zip(fit.sign_width_seen_rad_s)
        .zip(setting.sign_speed_rad_s)
        .map(|((name, w), v_s)| format!("{name} {w:.3} ({v_s:.3})"))
        .collect();
    crate::stdoutln!(
        "friction sign as the fit sees it: tanh(|q'|/w) with w = {} rad/s (the regressor's v_s in brackets): \
         a w above v_s is the joint sticking and slipping at low speed, its sign averaged by Q; \
         below about w a run cannot tell its Coulomb from its viscous friction",
        each.join(", ")
    );
}

/// Print the fit.
fn report_fit(fit: &InverseDynamicsFit, geometry: &cable_joint::wrist::Geometry) {
    crate::stdoutln!(
        "Eq. 3 fit: {} rows; condition number of the equilibrated regressor {:.2} (every column {:.2}); residual RMS {:.3e} N·m",
        fit.rows,
        fit.condition,
        fit.condition_with_links,
        fit.rmse_nm
    );
    let tried: Vec<String> = fit
        .bandwidth_held_out_nm
        .iter()
        .map(|[hz, nm]| format!("{hz:.0} Hz {nm:.3e}"))
        .collect();
    crate::stdoutln!(
        "motion observer: {:.0} Hz, of {} (held-out torque RMS, N·m, each model fitted on the first 70 %)",
        fit.motion_bandwidth_hz,
        tried.join(", ")
    );
    if fit.links_observed {
        crate::stdoutln!(
            "links: observed (their moments fitted as real links could have them: links::unphysical_links)"
        );
    } else {
        let with_links: Vec<f64> = fit.with_links.iter().map(|[v, _]| *v).collect();
        crate::stdoutln!(
            "links: not observed (with every column {}: the estimates do not resolve the links; the model is each joint's friction alone)",
            links::unphysical_links(geometry, &with_links).join(", ")
        );
    }
    crate::stdoutln!("  {:<28} {:>12} {:>9}", "parameter", "value", "%sigma");
    for ((name, value), pct) in PARAM_NAMES.iter().zip(fit.body.params).zip(fit.pct_sigma) {
        if pct.is_nan() {
            crate::stdoutln!("  {name:<28} {:>12} {:>9}", "left out", "");
        } else {
            crate::stdoutln!("  {name:<28} {value:>12.4e} {pct:>9.1}");
        }
    }
    let [raw, left] = fit.held_out_rms_nm;
    crate::stdoutln!(
        "held out (fitted on the first 70 %, judged on the last 30 %): torque RMS {raw:.3e} -> {left:.3e} N·m: {}",
        if fit.kept {
            "the model helps on motion it did not see (kept = true)"
        } else {
            "the model does not cut it (kept = false): run the wrist without it"
        }
    );
}

/// Print the validation's no-load errors.
fn report_validation(dir: &Path, n: &NoLoad, kept: bool) {
    crate::stdoutln!(
        "validation on {} (unseen; true tip force zero){}:",
        dir.display(),
        if kept {
            ""
        } else {
            " (the model was not kept: shown for the record)"
        }
    );
    for (j, name) in JOINT_NAMES.iter().enumerate() {
        crate::stdoutln!(
            "  {name:<6} no-load RMS {:.3} -> {:.3} N; bound holds zero {:.1} % -> {:.1} %",
            n.raw_rms_n[j],
            n.corrected_rms_n[j],
            100.0 * n.raw_coverage[j],
            100.0 * n.coverage[j]
        );
    }
}
