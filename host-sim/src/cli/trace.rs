//! `host-sim trace`: its arguments and its run (the recording is
//! [`crate::trace`]).

use std::path::PathBuf;

use anyhow::Context;

use crate::cli;
use crate::output::Outputs;

use crate::live::{ViewArg, Watch};
use crate::plant::TipObject;
use crate::scenario::GripOptions;
use crate::trace::{record_watched, NoInjection, TraceOptions};

/// Arguments of `host-sim trace`.
#[derive(clap::Args, Debug, Clone)]
pub struct TraceArgs {
    /// Trace file to write (the qemu firmware embeds `firmware/trace.bin`).
    #[arg(long, default_value = "firmware/trace.bin")]
    pub out: PathBuf,
    /// Also write the firmware logic's telemetry as a CSV log.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// The live view (the run then goes at real time).
    #[command(flatten)]
    pub view: ViewArg,
    /// The closed-loop run.
    #[command(flatten)]
    pub run: RunArgs,
}

/// The closed-loop run of the firmware's logic on the simulated prototype
/// (`host-sim trace`, `host-sim pil`).
#[derive(clap::Args, Debug, Clone)]
pub struct RunArgs {
    /// Plant parameters (TOML, merged over the prototype's defaults).
    #[arg(long)]
    pub plant: Option<PathBuf>,
    /// Seconds recorded after boot (at most 1e6 control ticks).
    #[arg(allow_negative_numbers = true, long, default_value_t = TraceOptions::default().duration_s,
          value_parser = cli::f64_above(0.0, f64::MAX))]
    pub duration_s: f64,
    /// Seconds the mechanism relaxes with the drive off before boot.
    #[arg(allow_negative_numbers = true, long, default_value_t = TraceOptions::default().relax_s,
          value_parser = cli::f64_in(0.0, f64::MAX))]
    pub relax_s: f64,
    /// Weight hung on the tip during the hold, N.
    #[arg(long, default_value_t = TraceOptions::default().load_n, allow_negative_numbers = true,
          value_parser = cli::f64_in(-100.0, 100.0))]
    pub load_n: f64,
    /// When the weight is hung (ramped in over 50 ms), s after boot.
    #[arg(allow_negative_numbers = true, long, default_value_t = TraceOptions::default().load_at_s,
          value_parser = cli::f64_in(0.0, 1e6))]
    pub load_at_s: f64,
    /// When the drive's fault line is asserted, s after boot (negative:
    /// never).
    #[arg(long, default_value_t = TraceOptions::default().drive_fault_at_s,
          allow_negative_numbers = true, value_parser = cli::f64_in(-1e6, 1e6))]
    pub drive_fault_at_s: f64,
    /// Noise seed.
    #[arg(long, default_value_t = TraceOptions::default().seed)]
    pub seed: u64,
    /// Record with probing on (the default dither during the hold); the
    /// trace's header tells the QEMU firmware to run the same way.
    #[arg(long)]
    pub probe: bool,
    /// Put a soft object at the tip, its surface at this joint angle,
    /// degrees (not 0; the object fills the side away from 0), for a grip
    /// sent over the link (`host-sim link --scenario grip`).
    #[arg(long, allow_negative_numbers = true, value_parser = cli::f64_in(-80.0, 80.0))]
    pub object_at_deg: Option<f64>,
    /// The object's stiffness at the tip, N/m (with `--object-at-deg`).
    #[arg(allow_negative_numbers = true, long, requires = "object_at_deg", default_value_t = GripOptions::default().object_n_m,
          value_parser = cli::f64_above(0.0, 1e6))]
    pub object_n_m: f64,
}

impl RunArgs {
    /// The run these arguments ask for (refused: an object at 0°).
    pub fn options(&self) -> anyhow::Result<TraceOptions> {
        if self.object_at_deg == Some(0.0) {
            anyhow::bail!(
                "--object-at-deg 0: the object's surface must be at a joint angle other than 0 \
                 (within ±80°; it fills the side away from 0)"
            );
        }
        let object = self
            .object_at_deg
            .map(|deg| TipObject::new(deg, self.object_n_m))
            .transpose()
            .context("--object-at-deg")?;
        Ok(TraceOptions {
            duration_s: self.duration_s,
            relax_s: self.relax_s,
            load_n: self.load_n,
            load_at_s: self.load_at_s,
            drive_fault_at_s: self.drive_fault_at_s,
            seed: self.seed,
            probing: self.probe,
            object,
        })
    }
}

/// `host-sim trace`.
pub fn run(args: TraceArgs) -> anyhow::Result<()> {
    let plant = crate::io::config::load_plant(args.run.plant.as_deref())?;
    let opts = args.run.options()?;
    let config = opts.config();
    let mut watch = Watch::new(
        args.view,
        "simulated prototype (host-sim trace)",
        &config,
        "{bar:40} {pos}/{len} ticks (eta {eta})",
    )?;
    let rec = record_watched(plant, &opts, config, &mut NoInjection, &mut |k, n, o| {
        watch.tick(k, n, o)
    })?;
    let min_ticks = crate::log::DEFAULT_MIN_ROWS;
    anyhow::ensure!(
        rec.samples.len() >= min_ticks,
        "--duration-s {}: {} control ticks at {} Hz; a trace needs at least {min_ticks} (a log \
         of it does, for every command that reads one): lengthen it",
        args.run.duration_s,
        rec.samples.len(),
        rec.control_rate_hz
    );
    // The trace and the CSV log are written together, or neither is.
    let mut out = Outputs::new();
    if let Some(dir) = args.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        crate::output::ensure_dir(dir)?;
    }
    out.bytes(&args.out, &rec.trace_bytes())?;
    if let Some(csv) = &args.csv {
        let log = crate::ingest::to_log(
            &rec.telemetry(),
            &config,
            &crate::ingest::LogOptions::default(),
        )?;
        log.stage(&mut out, csv)?;
    }
    out.commit()?;
    watch.finish(&format!("wrote {}", args.out.display()))?;
    let homed = rec
        .outcomes
        .iter()
        .rev()
        .find_map(|o| o.origin)
        .map(|o| o.tick);
    eprintln!(
        "wrote {} ({} ticks at {} Hz, probing {}; {})",
        args.out.display(),
        rec.samples.len(),
        rec.control_rate_hz,
        if rec.probing { "on" } else { "off" },
        homed.map_or_else(
            || "not homed".to_owned(),
            |tick| format!("homed at tick {tick}")
        )
    );
    if let Some(csv) = &args.csv {
        eprintln!("wrote {}", csv.display());
    }
    Ok(())
}
