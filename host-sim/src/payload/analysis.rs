//! [`analyse`]: the analysis step by step, from the calibration files to
//! every run's statistics.

use std::path::Path;

use anyhow::{bail, Context, Result};
use cable_joint::payload::{CompConfig, IdentConfig, Kinematics, PayloadFit, PayloadModel};
use nalgebra::Vector3;

use super::report::{axes_text, param_table};
use super::{
    affine_residual, angular_rates, check_convention, estimate, estimate_accel_lag, filtered_run,
    fit_accel_calibration, fit_affine_map, identify, identify_comp, kinematics, load_run,
    load_static_poses, raw_minus_start, rms, static_identification, steady_state_noise,
    weighted_score, AccelCalibration, CandidateReport, Convention, Estimate, GravitySource,
    KinOptions, ParamReport, PayloadOptions, Report, Run, RunEstimates, RunReport,
};

/// A run whose name contains "contact" has contact.
fn is_contact(name: &str) -> bool {
    name.contains("contact")
}

/// The identification's configuration: inertia entries or not, the
/// creep/drift columns `comp`, rows weighted by `weight`.
fn ident_config(inertia: bool, weight: [f64; 6], comp: CompConfig) -> IdentConfig {
    IdentConfig {
        inertia,
        comp,
        axis_weight: weight,
        ..IdentConfig::default()
    }
}

/// The tare window (`--tare-s`, no contact at the start of each run) at
/// most half of every run's wrench: a longer one would take the contact
/// it is meant to find for the sensor's offset.
fn check_tare_window<'a>(tare_s: f64, runs: impl Iterator<Item = &'a Run>) -> Result<()> {
    for run in runs {
        let t = &run.wrench.t_s;
        let length_s = match (t.first(), t.last()) {
            (Some(a), Some(b)) => b - a,
            _ => continue,
        };
        anyhow::ensure!(
            tare_s <= 0.5 * length_s,
            "--tare-s {tare_s}: run {} lasts {length_s:.3} s; the no-contact window at its start \
             can be at most half of it ({:.3} s), or it takes the contact for the sensor's \
             offset",
            run.name,
            // Rounded down: the figure printed is itself a window taken.
            (0.5 * length_s * 1e3).floor() / 1e3
        );
    }
    Ok(())
}

/// Run the whole analysis (no output files): the calibration files, the
/// runs, the IMU lag, the filtered runs' kinematics, the base model, the
/// creep/drift candidates and the selected one, and every run through the
/// base and the selected model (one private function per step, below).
///
/// # Errors
/// The options fail [`PayloadOptions::check`]; a file is missing or bad; a
/// fit or an estimate fails.
pub fn analyse(opts: &PayloadOptions) -> Result<(Report, Vec<RunEstimates>)> {
    opts.check()?;
    let c = calibrate(&opts.dir)?;
    let (fit_run, val_runs) = load_runs(opts)?;
    check_tare_window(opts.tare_s, std::iter::once(&fit_run).chain(&val_runs))?;
    let (lag_s, lag_curve) = imu_lag(opts, &fit_run, &c)?;
    let kin_opts = KinOptions {
        gravity: opts.gravity,
        accel_lag_s: lag_s,
        rotational: opts.rotational,
        lowpass_hz: (opts.lowpass_hz > 0.0).then_some(opts.lowpass_hz),
    };
    // The lag is estimated on the unfiltered data (the vibration carries the
    // timing); everything from here on sees the filtered wrench.
    let data = prepare(&fit_run, &val_runs, &kin_opts, &c);

    // Base model.
    let base_cfg = ident_config(opts.inertia, c.weight, CompConfig::NONE);
    let (base_fit, ident_time_s) = identify(&data.fit_run, &data.fit_kin, base_cfg)?;
    let rotation = rotation_magnitude(&data.fit_run, &c.conv, &base_fit);

    let (candidates, models) = fit_candidates(opts, &data, &c, &base_fit, base_cfg)?;
    let selected = select(&candidates);
    let (sel_fit, sel_model, sel_cfg) = &models[selected];
    let base_model = PayloadModel::new(&base_fit.params, CompConfig::NONE)?;
    let affine = fit_affine_map(&data.fit_run, &data.fit_kin)?;
    let models = RunModels {
        base: &base_model,
        selected: sel_model,
        affine: &affine,
    };
    let evaluated = evaluate_runs(&data, &models, opts.tare_s)?;

    let report = Report {
        convention: c.conv,
        accel_calibration: c.cal,
        noise_std: c.noise,
        static_params: c.static_params,
        gravity: opts.gravity,
        accel_lag_ms: lag_s * 1e3,
        lag_curve,
        rotational: opts.rotational,
        lowpass_hz: opts.lowpass_hz,
        max_omega_rad_s: rotation.max_omega_rad_s,
        max_alpha_rad_s2: rotation.max_alpha_rad_s2,
        rot_force_rms_n: rotation.rot_force_rms_n,
        rot_torque_bound_nm: rotation.rot_torque_bound_nm,
        fit_run: data.fit_run.name.clone(),
        fit_samples: base_fit.samples,
        fit_duration_s: data.fit_run.wrench.t_s.last().copied().unwrap_or(0.0),
        ident_time_s,
        condition: base_fit.lsq.condition,
        params: param_table(&base_fit, &base_cfg),
        candidates,
        selected,
        selected_params: param_table(sel_fit, sel_cfg),
        runs: evaluated.runs,
        contact_intervals: evaluated.contact_intervals,
    };
    Ok((report, evaluated.estimates))
}

/// What the two calibration files give.
struct Calibration {
    /// Steady-state noise std per axis.
    noise: [f64; 6],
    /// Identification weights per axis, `1 / noise`.
    weight: [f64; 6],
    /// Orientation convention.
    conv: Convention,
    /// Accelerometer calibration.
    cal: AccelCalibration,
    /// The payload from the static poses alone (cross-check).
    static_params: Vec<ParamReport>,
}

/// The static calibration poses and the steady-state noise of the data set
/// in `dir`: weights, conventions and the static cross-check.
fn calibrate(dir: &Path) -> Result<Calibration> {
    let poses = load_static_poses(&dir.join("0-calibration_fts-accel.csv"))?;
    let noise = steady_state_noise(&dir.join("0-steady-state_wrench.csv"))?;
    if noise.iter().any(|s| s.is_nan() || *s <= 0.0) {
        bail!("0-steady-state_wrench.csv: an axis has zero noise; cannot weight");
    }
    let weight = noise.map(|s| 1.0 / s);
    let conv = check_convention(&poses)?;
    let cal = fit_accel_calibration(&poses)?;
    let stat = static_identification(&poses, weight)?;
    let static_cfg = IdentConfig {
        inertia: false,
        axis_weight: weight,
        ..IdentConfig::default()
    };
    Ok(Calibration {
        noise,
        weight,
        conv,
        cal,
        static_params: param_table(&stat, &static_cfg),
    })
}

/// The fit run (which must have no contact) and the validation runs, as
/// read.
fn load_runs(opts: &PayloadOptions) -> Result<(Run, Vec<Run>)> {
    let dir = &opts.dir;
    let fit_run = load_run(dir, &opts.fit).with_context(|| format!("loading run {}", opts.fit))?;
    if is_contact(&fit_run.name) {
        bail!(
            "fit run {} has contact; identify on a no-contact run",
            fit_run.name
        );
    }
    let mut val_runs = Vec::new();
    for v in &opts.validate {
        val_runs.push(load_run(dir, v).with_context(|| format!("loading run {v}"))?);
    }
    Ok((fit_run, val_runs))
}

/// The IMU lag, s: given, 0 for the orientation, or estimated on the
/// (unfiltered) fit run; with the lag curve (lag ms, fit RMSE) when
/// estimated.
fn imu_lag(
    opts: &PayloadOptions,
    fit_run: &Run,
    c: &Calibration,
) -> Result<(f64, Vec<(f64, f64)>)> {
    Ok(match (opts.accel_lag_ms, opts.gravity) {
        (Some(ms), _) => (ms * 1e-3, Vec::new()),
        (None, GravitySource::Orient) => (0.0, Vec::new()),
        (None, GravitySource::Accel) => {
            let grid: Vec<f64> = (-20..=60).map(|k| f64::from(k) * 0.5e-3).collect();
            let (l, c) = estimate_accel_lag(fit_run, &c.conv, &c.cal, c.weight, &grid)?;
            (l, c.into_iter().map(|(l, r)| (l * 1e3, r)).collect())
        }
    })
}

/// The runs as the identification and the estimator see them, with their
/// kinematics.
struct Prepared {
    /// The fit run, filtered.
    fit_run: Run,
    /// Its kinematics.
    fit_kin: Vec<Kinematics<f64>>,
    /// The validation runs, filtered.
    val_runs: Vec<Run>,
    /// Their kinematics.
    val_kin: Vec<Vec<Kinematics<f64>>>,
}

impl Prepared {
    /// Every run with its kinematics, the fit run first.
    fn all(&self) -> impl Iterator<Item = (&Run, &Vec<Kinematics<f64>>)> {
        std::iter::once((&self.fit_run, &self.fit_kin))
            .chain(self.val_runs.iter().zip(self.val_kin.iter()))
    }
}

/// The runs low-passed as `kin_opts` says, and their kinematics.
fn prepare(fit_run: &Run, val_runs: &[Run], kin_opts: &KinOptions, c: &Calibration) -> Prepared {
    let fit_run = filtered_run(fit_run, kin_opts);
    let val_runs: Vec<Run> = val_runs.iter().map(|r| filtered_run(r, kin_opts)).collect();
    let fit_kin = kinematics(&fit_run, kin_opts, &c.conv, &c.cal);
    let val_kin: Vec<Vec<Kinematics<f64>>> = val_runs
        .iter()
        .map(|r| kinematics(r, kin_opts, &c.conv, &c.cal))
        .collect();
    Prepared {
        fit_run,
        fit_kin,
        val_runs,
        val_kin,
    }
}

/// How large the rotational terms are on the fit run (the [`Report`]'s
/// fields of the same names).
struct Rotation {
    max_omega_rad_s: f64,
    max_alpha_rad_s2: f64,
    rot_force_rms_n: f64,
    rot_torque_bound_nm: f64,
}

/// The rotational magnitudes on the fit run, always from the orientation
/// (whatever the gravity source and the rotational flag), with the first
/// moment and the mass of `base_fit`.
fn rotation_magnitude(fit_run: &Run, conv: &Convention, base_fit: &PayloadFit) -> Rotation {
    let (wst, ast) = angular_rates(&fit_run.orient, conv.transpose);
    let max_w = wst
        .v
        .iter()
        .map(|v| Vector3::from(*v).norm())
        .fold(0.0, f64::max);
    let max_a = ast
        .v
        .iter()
        .map(|v| Vector3::from(*v).norm())
        .fold(0.0, f64::max);
    let mc = Vector3::new(
        base_fit.params.inertial[1],
        base_fit.params.inertial[2],
        base_fit.params.inertial[3],
    );
    let (mut sf, mut st) = (0.0, 0.0);
    for &t in &fit_run.wrench.t_s {
        let w = Vector3::from(wst.at(t));
        let a = Vector3::from(ast.at(t));
        sf += (a.cross(&mc) + w.cross(&w.cross(&mc))).norm_squared();
        let i_bound = base_fit.params.mass_kg().abs() * 0.01;
        st += (i_bound * (a.norm() + w.norm_squared())).powi(2);
    }
    let nf = fit_run.wrench.len() as f64;
    Rotation {
        max_omega_rad_s: max_w,
        max_alpha_rad_s2: max_a,
        rot_force_rms_n: (sf / nf).sqrt(),
        rot_torque_bound_nm: (st / nf).sqrt(),
    }
}

/// The creep/drift configurations offered: none, drift alone, then each
/// creep time constant without and with drift.
fn comp_candidates(creep_taus: &[f32]) -> Vec<CompConfig> {
    let mut comps = vec![CompConfig::NONE, CompConfig::all_axes(None, true)];
    for &tau in creep_taus {
        for drift in [false, true] {
            comps.push(CompConfig::all_axes(Some(tau), drift));
        }
    }
    comps
}

/// A candidate's fit, the core's model of it and its configuration after
/// the pruning.
type Candidate = (PayloadFit, PayloadModel, IdentConfig);

/// Every creep/drift candidate fitted on the fit run ([`identify_comp`];
/// the one without columns is the base model) and scored, in the order of
/// [`comp_candidates`].
fn fit_candidates(
    opts: &PayloadOptions,
    data: &Prepared,
    c: &Calibration,
    base_fit: &PayloadFit,
    base_cfg: IdentConfig,
) -> Result<(Vec<CandidateReport>, Vec<Candidate>)> {
    let nc_val: Vec<usize> = (0..data.val_runs.len())
        .filter(|&i| !is_contact(&data.val_runs[i].name))
        .collect();
    let mut candidates = Vec::new();
    let mut models = Vec::new();
    for comp in comp_candidates(&opts.creep_taus) {
        let (fit, cfg) = if comp.n_cols() == 0 {
            (base_fit.clone(), base_cfg)
        } else {
            identify_comp(
                &data.fit_run,
                &data.fit_kin,
                ident_config(opts.inertia, c.weight, comp),
                base_fit,
            )?
        };
        let model = PayloadModel::new(&fit.params, cfg.comp)?;
        let (fit_score, validation_score, vr) =
            score_candidate(data, &nc_val, &model, opts.tare_s, &c.noise)?;
        candidates.push(CandidateReport {
            creep_tau_s: comp.creep_tau_s,
            drift: comp.drift_axes.iter().any(|d| *d),
            creep_axes: axes_text(&cfg.comp.creep_axes, cfg.comp.creep_tau_s.is_some()),
            drift_axes: axes_text(&cfg.comp.drift_axes, true),
            fit_score,
            validation_score,
            validation_rmse: vr,
        });
        models.push((fit, model, cfg));
    }
    Ok((candidates, models))
}

/// A candidate's scores (tracked estimates): on the fit run, on the
/// no-contact validation runs `nc_val` pooled (the fit run's score when
/// there is none), and the pooled RMSE per axis.
fn score_candidate(
    data: &Prepared,
    nc_val: &[usize],
    model: &PayloadModel,
    tare_s: f64,
    noise: &[f64; 6],
) -> Result<(f64, f64, [f64; 6])> {
    let e_fit = estimate(&data.fit_run, &data.fit_kin, model, tare_s)?;
    let fit_score = weighted_score(&rms(&e_fit.tracked), noise);
    let mut pooled = Vec::new();
    for &i in nc_val {
        pooled.extend(estimate(&data.val_runs[i], &data.val_kin[i], model, tare_s)?.tracked);
    }
    let vr = rms(&pooled);
    let validation_score = if pooled.is_empty() {
        fit_score
    } else {
        weighted_score(&vr, noise)
    };
    Ok((fit_score, validation_score, vr))
}

/// The candidate with the smallest validation score (the first of equal
/// ones; 0 when there is none).
fn select(candidates: &[CandidateReport]) -> usize {
    candidates
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.validation_score.total_cmp(&b.1.validation_score))
        .map(|c| c.0)
        .unwrap_or(0)
}

/// The models every run goes through.
struct RunModels<'a> {
    /// Base model (no creep/drift).
    base: &'a PayloadModel,
    /// Selected creep/drift model.
    selected: &'a PayloadModel,
    /// The diagnostic affine map of the fit run.
    affine: &'a [[f64; 4]; 6],
}

/// Every run's statistics, estimates and (contact runs) contact interval.
struct Evaluated {
    runs: Vec<RunReport>,
    estimates: Vec<RunEstimates>,
    contact_intervals: Vec<(String, f64, f64)>,
}

/// Every run, the fit run first, through the models.
fn evaluate_runs(data: &Prepared, models: &RunModels, tare_s: f64) -> Result<Evaluated> {
    let mut out = Evaluated {
        runs: Vec::new(),
        estimates: Vec::new(),
        contact_intervals: Vec::new(),
    };
    for (run, kin) in data.all() {
        let base = estimate(run, kin, models.base, tare_s)?;
        let sel = estimate(run, kin, models.selected, tare_s)?;
        out.runs
            .push(run_report(run, kin, &base, &sel, models.affine, tare_s));
        if is_contact(&run.name) {
            out.contact_intervals.extend(contact_interval(run, &sel));
        }
        out.estimates.push(RunEstimates {
            run: run.clone(),
            raw: raw_minus_start(run, tare_s),
            base,
            selected: sel,
        });
    }
    Ok(out)
}

/// One run's statistics from its base (`base`) and selected (`sel`)
/// estimates.
fn run_report(
    run: &Run,
    kin: &[Kinematics<f64>],
    base: &Estimate,
    sel: &Estimate,
    affine: &[[f64; 4]; 6],
    tare_s: f64,
) -> RunReport {
    let peak = std::array::from_fn(|k| sel.tracked.iter().map(|r| r[k].abs()).fold(0.0, f64::max));
    RunReport {
        name: run.name.clone(),
        contact: is_contact(&run.name),
        samples: run.wrench.len(),
        raw: rms(&raw_minus_start(run, tare_s)),
        ident: rms(&base.raw_model),
        ident_tare: rms(&base.tracked),
        comp_tare: rms(&sel.tracked),
        affine_tare: rms(&affine_residual(run, kin, affine, tare_s)),
        tare_correction: base
            .raw_model
            .last()
            .zip(base.tracked.last())
            .map(|(a, b)| std::array::from_fn(|k| a[k] - b[k]))
            .unwrap_or([0.0; 6]),
        peak,
    }
}

/// The first and the last time at which the selected model's `|f_e|`
/// exceeds 1.5 N (`None`: never).
fn contact_interval(run: &Run, sel: &Estimate) -> Option<(String, f64, f64)> {
    let hits: Vec<f64> = sel
        .tracked
        .iter()
        .zip(&run.wrench.t_s)
        .filter(|(r, _)| Vector3::new(r[0], r[1], r[2]).norm() > 1.5)
        .map(|(_, t)| *t)
        .collect();
    match (hits.first(), hits.last()) {
        (Some(a), Some(b)) => Some((run.name.clone(), *a, *b)),
        _ => None,
    }
}
