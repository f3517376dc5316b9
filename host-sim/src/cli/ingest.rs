//! `host-sim ingest`: its arguments and its run.

use std::path::PathBuf;

use anyhow::{bail, Context};
use cable_joint::telemetry::{Record, TickRecord};

use crate::ingest::{cycle_stats, read_stream, source_name, to_log, LogOptions};
use crate::log::DEFAULT_MIN_ROWS;

/// Arguments of `host-sim ingest`.
#[derive(clap::Args, Debug, Clone)]
pub struct IngestArgs {
    /// Decoded defmt text (from `probe-rs run` or `defmt-print`); `-` reads
    /// standard input.
    pub file: PathBuf,
    /// CSV log to write (written to a temporary file, then renamed).
    #[arg(long)]
    pub out: PathBuf,
    /// Core configuration (TOML) for the sensor scales; defaults to the
    /// datasheet values the firmware is built with.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// The magnetic joint encoder is fitted: add the `theta_rad` column.
    #[arg(long)]
    pub magnetic: bool,
    /// Print min/median/max cycle counts per control stage.
    #[arg(long)]
    pub stats: bool,
}

/// `host-sim ingest`.
pub fn run(args: IngestArgs) -> anyhow::Result<()> {
    let config = crate::io::config::load_or_default(args.config.as_deref())?;
    let (records, lines) = read_stream(&args.file)?;
    let name = source_name(&args.file);
    let ticks: Vec<TickRecord> = records
        .iter()
        .filter_map(|r| match r {
            Record::Tick(t) => Some(*t),
            _ => None,
        })
        .collect();
    if ticks.is_empty() {
        bail!("{name}: no telemetry record (`tlm [..]` lines) found");
    }
    let opts = LogOptions {
        magnetic: args.magnetic,
        lines: &lines,
        ..LogOptions::default()
    };
    let log = to_log(&records, &config, &opts).with_context(|| name.clone())?;
    anyhow::ensure!(
        log.len() >= DEFAULT_MIN_ROWS,
        "{}: {} tick records; a log needs at least {DEFAULT_MIN_ROWS} rows (the other commands \
         would refuse it)",
        name,
        log.len()
    );
    log.write(&args.out)?;
    eprintln!(
        "{name}: {} tick records -> {}",
        ticks.len(),
        args.out.display()
    );
    if args.stats {
        if let Some(s) = cycle_stats(&ticks) {
            crate::stdoutln!("{s}");
        }
    }
    Ok(())
}
