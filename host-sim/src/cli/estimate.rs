//! `host-sim estimate`: its arguments, its run and what it prints.

use std::path::PathBuf;

use anyhow::{Context, Result};
use cable_joint::Config;

use crate::estimate::{estimate, EstimateSummary};
use crate::output::Outputs;

/// Arguments of `host-sim estimate`.
#[derive(clap::Args, Debug, Clone)]
pub struct EstimateArgs {
    /// Input log (project CSV schema, any control rate).
    #[arg(long)]
    pub log: PathBuf,
    /// Controller configuration (TOML; default: the datasheet values).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Output CSV with every estimate.
    #[arg(long)]
    pub out: PathBuf,
    /// The log has a row every N control ticks but no `tick` column (a
    /// logger other than the firmware's link, recording at a fraction of
    /// the control rate): the control period is the median time step over
    /// N, not the time step itself. A log with the firmware's `tick` column
    /// needs nothing: its decimation is read from it.
    #[arg(long, value_name = "N")]
    pub ticks_per_row: Option<u32>,
    /// Also draw the tip force (the fused estimate inside its bound, the
    /// DOB, the stretch estimate, the log's reference force) and the joint
    /// angle against time, as STEM.svg and STEM.png.
    #[arg(long, value_name = "STEM")]
    pub plot: Option<PathBuf>,
}

/// `host-sim estimate`.
pub fn run(args: EstimateArgs) -> Result<()> {
    let name = args.log.display().to_string();
    let log = crate::ingest::read_for_replay(
        &args.log,
        args.ticks_per_row,
        "estimate",
        crate::ingest::ReplayEnd::LastRow,
    )?;
    // The configuration at the log's rate (the firmware ran at it).
    let config = match &args.config {
        Some(p) => {
            let (config, notes) = crate::io::config::load_config_for_logs(p, &[(&name, &log)])?;
            for n in notes {
                eprintln!("estimate: {}: {n}", p.display());
            }
            config
        }
        None => Config::default(),
    };
    let what = args.config.as_ref().map_or_else(
        || "no --config (the datasheet defaults)".to_owned(),
        |p| p.display().to_string(),
    );
    if let Some(w) = crate::io::config::datasheet_force_warning(&config, &what) {
        eprintln!("estimate: {w}");
    }
    let (out, s) = estimate(&log, &config).with_context(|| format!("replaying {name}"))?;
    for d in &s.derived {
        eprintln!("estimate: {d}");
    }
    for w in row_loss_warnings(&name, &s) {
        eprintln!("{w}");
    }
    // The CSV and the figure are written together or not at all.
    let mut files = Outputs::new();
    out.stage(&mut files, &args.out)?;
    let figures = match &args.plot {
        Some(stem) => {
            let fig = crate::estimate::figure(&out, &name, &s)?;
            crate::plot::stage_figure(&mut files, &fig, stem)?.to_vec()
        }
        None => Vec::new(),
    };
    files.commit()?;
    crate::stdoutln!("{}", format_summary(&name, &s));
    crate::stdoutln!("wrote {} ({} rows)", args.out.display(), s.rows);
    for f in &figures {
        crate::stdoutln!("wrote {}", f.display());
    }
    Ok(())
}

/// Warnings about rows the comparison with the reference left out.
pub fn row_loss_warnings(name: &str, s: &EstimateSummary) -> Vec<String> {
    let mut w = Vec::new();
    let Some(r) = &s.against_reference else {
        return w;
    };
    if let (n, Some(first)) = r.not_measured {
        w.push(format!(
            "warning: {name}: column f_ext_n is not measured on {n} of {} rows (first at line {}): \
             they are left out of the comparison with the reference",
            s.rows,
            first + 2
        ));
    }
    if r.faulted > 0 {
        w.push(format!(
            "warning: {name}: {} of {} rows are left out of the comparison with the reference: \
             {}",
            r.faulted,
            s.rows,
            summary_end(s).unwrap_or_default()
        ));
    }
    w
}

/// Where the summary's figures end, when a fault ends them
/// ([`EstimateSummary::ending_fault`]): the log's own (the board's drive
/// off from there) or the replay's, in words.
fn summary_end(s: &EstimateSummary) -> Option<String> {
    s.ending_fault().map(|(k, code, recorded)| {
        let line = crate::log::line_of_row(k);
        match (&s.first_fault, recorded) {
            (Some((_, _, text)), false) => {
                format!("the replay latched {text} (code {code}) at line {line}")
            }
            _ => format!(
                "the log records {} at line {line} (the board's drive off from there)",
                crate::ingest::fault_words(code)
            ),
        }
    })
}

/// A share as a percentage to a tenth, rounded down: a bound that misses
/// 5 rows of 12000 covers 99.9 %, not "100.0 %" (the 1e-9 absorbs the
/// share's own rounding: a log has at most 1e6 rows).
fn share_floor_pct(share: f64) -> String {
    format!("{:.1}", (1000.0 * share + 1e-9).floor() / 10.0)
}

/// The terminal summary.
pub fn format_summary(name: &str, s: &EstimateSummary) -> String {
    use std::fmt::Write as _;
    let mut t = String::new();
    let _ = writeln!(t, "{name}: {} rows replayed through the core", s.rows);
    if let Some((k, code)) = s.recorded_fault {
        let _ = writeln!(
            t,
            "  the log records {} at line {}: the board's drive was off from there, and the \
             figures below end there",
            crate::ingest::fault_words(code),
            crate::log::line_of_row(k)
        );
    }
    match &s.first_fault {
        Some((k, code, text)) => {
            let _ = writeln!(
                t,
                "  the replay latched a fault at line {} (code {code}: {text}); estimates after it are the idle replay's",
                crate::log::line_of_row(*k)
            );
        }
        None => {
            let _ = writeln!(t, "  the replay latched no fault");
        }
    }
    let ended = s.ending_fault().is_some();
    let rows = if ended {
        "of the rows before the fault"
    } else {
        "of rows"
    };
    let _ = writeln!(
        t,
        "  slider 1 stuck in {:.1} % {rows} (DOB blind to its friction band there); DOB and stretch disagree in {:.1} %",
        100.0 * s.slider1_stuck_share,
        100.0 * s.inconsistent_share
    );
    let _ = writeln!(
        t,
        "  mean width of the force bound: {:.3} N{}; it excludes zero force in {:.1} % {rows} \
         (elsewhere the estimate cannot tell a load from none, nor its direction)",
        s.mean_bound_width_n,
        if ended { " (before the fault)" } else { "" },
        100.0 * s.excludes_zero_share
    );
    if let Some(d) = &s.against_log {
        let theta = d.theta_rad.map_or(String::new(), |t| {
            format!(
                "; joint angle rms {:.4}°, max |d| {:.4}°",
                t.rms.to_degrees(),
                t.max_abs().to_degrees()
            )
        });
        let _ = writeln!(
            t,
            "  against the log's own estimate on {} rows (computed on line every tick, with the \
             run's configuration): fused force replay − log mean {:+.3} N, rms {:.3} N, max |d| \
             {:.3} N{theta}",
            d.rows,
            d.fused_n.mean,
            d.fused_n.rms,
            d.fused_n.max_abs()
        );
        if d.decimation > 1 {
            let _ = writeln!(
                t,
                "    the log has a row every {} ticks: between rows the replay interpolates the \
                 sensors and rebuilds the current from its mean and one sample of its chatter, \
                 where the board had every tick's; where they part, the log's own estimate is the \
                 one measured",
                d.decimation
            );
        }
    }
    if let Some(r) = &s.against_reference {
        let _ = writeln!(
            t,
            "  against the logged f_ext_n on {} of {} rows (estimate − reference, N):",
            r.rows, s.rows
        );
        for (label, e) in [
            ("DOB (seed)", &r.dob_n),
            ("stretch", &r.stretch_n),
            ("fused", &r.fused_n),
        ] {
            let _ = writeln!(
                t,
                "    {label:<11} mean {:+.3}  rms {:.3}  max |e| {:.3}",
                e.mean,
                e.rms,
                e.max_abs()
            );
        }
        let board = s
            .against_log
            .and_then(|d| d.board_coverage)
            .map(|c| format!(" (the board's own bound: {} %)", share_floor_pct(c)))
            .unwrap_or_default();
        let missed = if r.outside > 0 {
            format!(" ({} of {} outside it)", r.outside, r.rows)
        } else {
            String::new()
        };
        let _ = writeln!(
            t,
            "  bound covers the reference in {} % of rows{missed}{board}",
            share_floor_pct(r.coverage)
        );
    }
    t.trim_end().to_owned()
}

#[cfg(test)]
mod tests {
    use super::share_floor_pct;

    #[test]
    fn a_share_is_rounded_down_to_a_tenth_of_a_percent() {
        assert_eq!(share_floor_pct(11_995.0 / 12_000.0), "99.9");
        assert_eq!(share_floor_pct(1.0), "100.0");
        assert_eq!(share_floor_pct(999.0 / 1000.0), "99.9");
        assert_eq!(share_floor_pct(0.0), "0.0");
    }
}
