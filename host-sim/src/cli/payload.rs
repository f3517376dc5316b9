//! `host-sim payload`: its arguments, its run and what it prints (the
//! analysis is [`crate::payload`]).

use std::fmt::Write as _;
use std::path::PathBuf;
use std::sync::OnceLock;

use anyhow::Result;

use crate::cli;
use crate::output::Outputs;
use crate::payload::{
    analyse, plot_runs, write_csv, GravitySource, ParamReport, PayloadOptions, Report,
    MAX_ACCEL_LAG_MS, MAX_LOWPASS_HZ, MAX_WINDOW_S,
};

/// Arguments of `host-sim payload`.
#[derive(clap::Args, Debug, Clone)]
pub struct PayloadArgs {
    /// Directory of the data set (`<run>_wrench.csv`, `<run>_accel.csv`,
    /// `<run>_orientations.csv`, `0-calibration_fts-accel.csv`,
    /// `0-steady-state_wrench.csv`).
    #[arg(long, default_value_os_t = PayloadOptions::default().dir)]
    pub dir: PathBuf,
    /// Run to identify on (no contact).
    #[arg(long, default_value_t = PayloadOptions::default().fit)]
    pub fit: String,
    /// Runs to validate on, comma separated. A run whose name contains
    /// "contact" is treated as having contact (no error statistics).
    #[arg(long, value_delimiter = ',', default_value = default_validate())]
    pub validate: Vec<String>,
    /// Source of `g - a`: `accel` (accelerometer, includes the linear
    /// acceleration) or `orient` (gravity from the orientation, no linear
    /// acceleration).
    #[arg(long, value_enum,
          default_value_t = GravityArg::from(PayloadOptions::default().gravity))]
    pub gravity: GravityArg,
    /// Lag of the IMU stream behind the wrench stream, ms (default: estimated
    /// on the fit run).
    #[arg(long, allow_negative_numbers = true, value_parser = cli::f64_in(-MAX_ACCEL_LAG_MS, MAX_ACCEL_LAG_MS))]
    pub accel_lag_ms: Option<f64>,
    /// Low-pass cut-off applied identically to the wrench and to the
    /// kinematics (two cascaded first-order sections of the core's
    /// `LowPass1`, causal), Hz; 0 = unfiltered.
    #[arg(allow_negative_numbers = true, long, default_value_t = PayloadOptions::default().lowpass_hz,
          value_parser = cli::f64_in(0.0, MAX_LOWPASS_HZ))]
    pub lowpass_hz: f64,
    /// Include the rotational terms (angular velocity and acceleration from
    /// differentiated orientations).
    #[arg(long)]
    pub rotational: bool,
    /// Also identify the six inertia entries (needs `--rotational`).
    #[arg(long, requires = "rotational")]
    pub inertia: bool,
    /// Candidate creep time constants, s, for the compensation selection.
    #[arg(allow_hyphen_values = true, long, value_delimiter = ',', default_value = default_creep_taus(),
          value_parser = cli::f32_above(0.0, MAX_WINDOW_S as f32))]
    pub creep_taus: Vec<f32>,
    /// Known no-contact window at the start of each run, s (offset tracker).
    #[arg(allow_negative_numbers = true, long, default_value_t = PayloadOptions::default().tare_s,
          value_parser = cli::f64_in(0.0, MAX_WINDOW_S))]
    pub tare_s: f64,
    /// Write the report as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write the per-sample estimates of every run as CSV
    /// (`DIR/payload_<run>.csv`: `t_s`, the raw sensor minus its start, `F_e`
    /// of the base and of the selected model, after the tare).
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Write one figure per run (SVG and PNG) into this directory.
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

/// `--gravity` ([`GravitySource`] on the command line).
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum GravityArg {
    /// Accelerometer (specific force), calibrated into the sensor frame.
    Accel,
    /// Orientation matrices: gravity only.
    Orient,
}

impl From<GravitySource> for GravityArg {
    fn from(g: GravitySource) -> Self {
        match g {
            GravitySource::Accel => Self::Accel,
            GravitySource::Orient => Self::Orient,
        }
    }
}

impl From<GravityArg> for GravitySource {
    fn from(g: GravityArg) -> Self {
        match g {
            GravityArg::Accel => Self::Accel,
            GravityArg::Orient => Self::Orient,
        }
    }
}

/// The default of a comma-separated option as `--help` shows it: the items
/// joined by commas (clap would join several default values by spaces).
fn comma_joined<T: ToString>(items: &[T]) -> String {
    items
        .iter()
        .map(ToString::to_string)
        .collect::<Vec<_>>()
        .join(",")
}

/// `--validate`'s default, from [`PayloadOptions::default`].
fn default_validate() -> &'static str {
    static TEXT: OnceLock<String> = OnceLock::new();
    TEXT.get_or_init(|| comma_joined(&PayloadOptions::default().validate))
}

/// `--creep-taus`' default, from [`PayloadOptions::default`].
fn default_creep_taus() -> &'static str {
    static TEXT: OnceLock<String> = OnceLock::new();
    TEXT.get_or_init(|| comma_joined(&PayloadOptions::default().creep_taus))
}

impl PayloadArgs {
    /// The analysis these arguments ask for.
    pub fn options(&self) -> PayloadOptions {
        PayloadOptions {
            dir: self.dir.clone(),
            fit: self.fit.clone(),
            validate: self.validate.clone(),
            gravity: self.gravity.into(),
            accel_lag_ms: self.accel_lag_ms,
            lowpass_hz: self.lowpass_hz,
            rotational: self.rotational,
            inertia: self.inertia,
            creep_taus: self.creep_taus.clone(),
            tare_s: self.tare_s,
        }
    }
}

/// `host-sim payload`.
pub fn run(args: PayloadArgs) -> Result<()> {
    for dir in [&args.csv, &args.plot].into_iter().flatten() {
        crate::output::check_dir_target(dir)?;
    }
    let (report, estimates) = analyse(&args.options())?;
    crate::stdout!("{}", format_report(&report));
    for (name, from_s, _) in &report.contact_intervals {
        if *from_s < args.tare_s {
            eprintln!(
                "warning: {name}: contact from {from_s:.2} s, inside the {} s no-contact window \
                 (--tare-s): the tare took part of the contact for the sensor's offset; give a \
                 window that ends before it",
                args.tare_s
            );
        }
    }
    // Every output is written, or none is.
    let mut out = Outputs::new();
    if let Some(path) = &args.json {
        let text = serde_json::to_string_pretty(&report)?;
        out.bytes(path, text.as_bytes())?;
    }
    if let Some(dir) = &args.csv {
        write_csv(&mut out, &estimates, dir)?;
    }
    if let Some(dir) = &args.plot {
        plot_runs(&mut out, &estimates, dir)?;
    }
    for p in out.commit()? {
        crate::stdoutln!("wrote {}", p.display());
    }
    Ok(())
}

fn row6(out: &mut String, label: &str, v: &[f64; 6]) {
    let _ = writeln!(
        out,
        "  {label:<12} {:>7.3} {:>7.3} {:>7.3}   {:>7.4} {:>7.4} {:>7.4}",
        v[0], v[1], v[2], v[3], v[4], v[5]
    );
}

fn params_text(out: &mut String, title: &str, ps: &[ParamReport]) {
    let _ = writeln!(out, "{title}");
    for p in ps {
        let _ = writeln!(
            out,
            "  {:<16} {:>12.5} ± {:<10.3e} ({:.2} %σ)",
            p.name, p.value, p.std, p.pct_sigma
        );
    }
}

/// The human-readable report (what `host-sim payload` prints).
pub fn format_report(r: &Report) -> String {
    let mut s = String::new();
    let c = &r.convention;
    let _ = writeln!(
        s,
        "orientation convention: g_s = {} g_w, g_w = ({:.5}, {:.5}, {:.5}) m/s² (max error {:.2e} m/s²; best alternative {:.2} m/s²)",
        if c.transpose { "R^T" } else { "R" },
        c.world_gravity_m_s2[0],
        c.world_gravity_m_s2[1],
        c.world_gravity_m_s2[2],
        c.max_err_m_s2,
        c.runner_up_max_err_m_s2
    );
    let rot = &r.accel_calibration.rotation;
    let _ = writeln!(
        s,
        "accelerometer -> sensor frame: rotation rows {:?} {:?} {:?}, offset c = {:.3?} m/s², rms residual {:.3} m/s²",
        rot[0].map(|v| (v * 1e3).round() / 1e3),
        rot[1].map(|v| (v * 1e3).round() / 1e3),
        rot[2].map(|v| (v * 1e3).round() / 1e3),
        r.accel_calibration.c,
        r.accel_calibration.rms_m_s2
    );
    let _ = writeln!(s, "steady-state noise std (weights^-1):");
    row6(&mut s, "", &r.noise_std);
    params_text(
        &mut s,
        "static calibration poses (24) -> payload:",
        &r.static_params,
    );
    let _ = writeln!(
        s,
        "g - a from: {:?}; low-pass {} Hz; IMU lag {:.1} ms{}; rotational terms: {}",
        r.gravity,
        r.lowpass_hz,
        r.accel_lag_ms,
        if r.lag_curve.is_empty() {
            " (given)"
        } else {
            " (estimated)"
        },
        r.rotational
    );
    let _ = writeln!(
        s,
        "fit run {}: max |omega| {:.3} rad/s, max |alpha| {:.2} rad/s²; rms rotational force {:.4} N; inertia torque bound {:.4} N·m",
        r.fit_run, r.max_omega_rad_s, r.max_alpha_rad_s2, r.rot_force_rms_n, r.rot_torque_bound_nm
    );
    let _ = writeln!(
        s,
        "identification: {} samples ({:.2} s of data), {:.1} ms wall time, condition number {:.1}",
        r.fit_samples,
        r.fit_duration_s,
        r.ident_time_s * 1e3,
        r.condition
    );
    params_text(&mut s, "identified (base model):", &r.params);
    let _ = writeln!(
        s,
        "creep/drift candidates (weighted score = mean (rmse/sigma)^2, after tare):"
    );
    for (i, c) in r.candidates.iter().enumerate() {
        let _ = writeln!(
            s,
            " {} creep tau {:>6} drift {:<5} kept creep {:<17} drift {:<17} fit {:>7.2} validation {:>7.2}",
            if i == r.selected { "*" } else { " " },
            c.creep_tau_s.map_or("-".to_owned(), |t| format!("{t}s")),
            c.drift,
            c.creep_axes,
            c.drift_axes,
            c.fit_score,
            c.validation_score
        );
    }
    params_text(&mut s, "selected model:", &r.selected_params);
    for run in &r.runs {
        let _ = writeln!(
            s,
            "run {} ({} samples{}):          fx      fy      fz        tx      ty      tz",
            run.name,
            run.samples,
            if run.contact {
                ", CONTACT: F_e is the contact wrench, not an error"
            } else {
                ""
            }
        );
        row6(&mut s, "raw-start", &run.raw);
        row6(&mut s, "ident", &run.ident);
        row6(&mut s, "ident+tare", &run.ident_tare);
        row6(&mut s, "comp+tare", &run.comp_tare);
        row6(&mut s, "affine+tare", &run.affine_tare);
        row6(&mut s, "tare corr.", &run.tare_correction);
        row6(&mut s, "peak |F_e|", &run.peak);
    }
    for (name, a, b) in &r.contact_intervals {
        let _ = writeln!(s, "{name}: |f_e| > 1.5 N from {a:.2} s to {b:.2} s");
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        args: PayloadArgs,
    }

    #[test]
    fn defaults_are_the_options_defaults() {
        let args = Cli::parse_from(["payload"]).args;
        assert_eq!(args.options(), PayloadOptions::default());
        assert_eq!(default_validate(), "2-vibrations,3-vibrations-contact");
        assert_eq!(default_creep_taus(), "0.25,0.5,1,2,4,8,16");
    }

    #[test]
    fn flags_reach_the_options() {
        let o = Cli::parse_from([
            "payload",
            "--gravity",
            "orient",
            "--rotational",
            "--inertia",
            "--accel-lag-ms",
            "-2.5",
            "--creep-taus",
            "1,4",
            "--validate",
            "2-vibrations",
            "--tare-s",
            "0.5",
            "--lowpass-hz",
            "0",
        ])
        .args
        .options();
        assert_eq!(o.gravity, GravitySource::Orient);
        assert!(o.rotational && o.inertia);
        assert_eq!(o.accel_lag_ms, Some(-2.5));
        assert_eq!(o.creep_taus, vec![1.0, 4.0]);
        assert_eq!(o.validate, vec!["2-vibrations".to_owned()]);
        assert_eq!((o.tare_s, o.lowpass_hz), (0.5, 0.0));
    }
}
