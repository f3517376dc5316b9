//! `host-sim import`: its arguments, its run and the line it prints.

use std::fmt::Write as _;
use std::path::PathBuf;

use crate::import::{import_mrdlab_run, MrdlabRun};
use crate::stats::DEG_PER_RAD;

/// Input formats `host-sim import` understands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ImportFormat {
    /// MRDLab da Vinci tool characterisation run (`XY.TXT`, `XY.TXT.gz`).
    Mrdlab,
}

/// `host-sim import FORMAT IN --out OUT`: convert a measured run to the
/// project's CSV log.
#[derive(Debug, Clone, clap::Args)]
pub struct ImportArgs {
    /// Format of the input file.
    #[arg(value_enum)]
    pub format: ImportFormat,
    /// Input file (`.gz` is decompressed).
    pub input: PathBuf,
    /// Output CSV log (written atomically; `.csv.gz` is compressed).
    #[arg(long, short)]
    pub out: PathBuf,
}

/// One line describing an imported run.
pub fn summary(run: &MrdlabRun) -> String {
    let log = &run.log;
    let mut s = format!("{} ({}): {} rows", run.meta.source, run.meta, log.len());
    if let Ok(t) = log.time_s() {
        if let (Some(first), Some(last)) = (t.first(), t.last()) {
            let dur = last - first;
            let _ = write!(s, ", {dur:.3} s");
            if t.len() > 1 && dur > 0.0 {
                let _ = write!(s, " at {:.0} Hz", (t.len() - 1) as f64 / dur);
            }
        }
    }
    // Each column in its own (SI) unit, and where that reads poorly in
    // the unit a person would use.
    for (name, unit, scale) in [
        ("phi_rad", "", 1.0),
        ("theta_rad", "°", DEG_PER_RAD),
        ("i_meas_a", "", 1.0),
        ("tau_in_nm", " mN·m", 1e3),
        ("tau_ext_nm", " mN·m", 1e3),
    ] {
        if let Some((lo, hi)) = log
            .col(name)
            .and_then(|c| crate::stats::finite_range(c.iter().copied()))
        {
            let _ = write!(s, "; {name} {lo:.4}..{hi:.4}");
            if !unit.is_empty() {
                let _ = write!(s, " ({:.1}..{:.1}{unit})", lo * scale, hi * scale);
            }
        }
    }
    s
}

/// Runs `host-sim import`.
///
/// # Errors
/// The input cannot be imported or the output cannot be written.
pub fn run(args: ImportArgs) -> anyhow::Result<()> {
    match args.format {
        ImportFormat::Mrdlab => {
            let run = import_mrdlab_run(&args.input)?;
            run.log.write(&args.out)?;
            crate::stdoutln!("{} -> {}", summary(&run), args.out.display());
        }
    }
    Ok(())
}
