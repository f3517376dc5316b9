//! `host-sim pil`: the firmware binary on QEMU in closed loop with the
//! simulated prototype ([`crate::pil`]), compared with the host-only run.

use std::path::PathBuf;
use std::time::Duration;

use crate::cli;
use crate::cli::trace::RunArgs;
use crate::live::{ViewArg, Watch};
use crate::output::Outputs;
use crate::pil::{compare, PilOptions};

/// Arguments of `host-sim pil`.
#[derive(clap::Args, Debug, Clone)]
pub struct PilArgs {
    /// The PIL firmware (`cargo fw-pil` writes it here).
    #[arg(long, default_value = "target/thumbv7em-none-eabihf/release/firmware")]
    pub elf: PathBuf,
    /// Directory for the run: `pil.csv` (the firmware's telemetry as a
    /// CSV log), `host.csv` (the host-only run), `pil.txt` (the
    /// comparison), QEMU's defmt stream and stderr.
    #[arg(long, default_value = "target/pil")]
    pub out: PathBuf,
    /// Expose the firmware's link (USART2) on this local TCP port for
    /// `host-sim link --port tcp:127.0.0.1:PORT`. Requests it sends make
    /// the run differ from the host-only one from that tick on.
    #[arg(long)]
    pub link_port: Option<u16>,
    /// Open QEMU's GDB stub on this local TCP port, for the link over RTT
    /// channel 1: `host-sim link --port rtt:127.0.0.1:PORT`.
    #[arg(long)]
    pub gdb_port: Option<u16>,
    /// The live view of the PIL run.
    #[command(flatten)]
    pub view: ViewArg,
    /// Longest wait for one tick's answer, s.
    #[arg(allow_negative_numbers = true, long, default_value_t = 20.0, value_parser = cli::f64_above(0.0, 3600.0))]
    pub tick_timeout_s: f64,
    /// The closed-loop run.
    #[command(flatten)]
    pub run: RunArgs,
}

/// `host-sim pil`.
pub fn run(args: PilArgs) -> anyhow::Result<()> {
    let plant = crate::io::config::load_plant(args.run.plant.as_deref())?;
    let opts = args.run.options()?;
    let pil = PilOptions {
        link_port: args.link_port,
        gdb_port: args.gdb_port,
        tick_timeout: Duration::from_secs_f64(args.tick_timeout_s),
        ..PilOptions::new(args.elf.clone(), args.out.clone())
    };
    let config = opts.config();
    let mut watch = Watch::new(
        args.view,
        &format!("PIL: {} on QEMU", args.elf.display()),
        &config,
        "PIL {bar:40} {pos}/{len} ticks ({per_sec}, eta {eta})",
    )?;
    let cmp = compare(plant, &opts, &pil, &mut |k, n, o| watch.tick(k, n, o))?;
    let summary = cmp.to_string();
    let log_opts = crate::ingest::LogOptions::default();
    let mut out = Outputs::new();
    crate::ingest::to_log(&cmp.pil.telemetry(), &config, &log_opts)?
        .stage(&mut out, args.out.join("pil.csv"))?;
    crate::ingest::to_log(&cmp.host.telemetry(), &config, &log_opts)?
        .stage(&mut out, args.out.join("host.csv"))?;
    out.bytes(&args.out.join("pil.txt"), summary.as_bytes())?;
    out.commit()?;
    watch.finish(&format!(
        "wrote {}/{{pil.csv, host.csv, pil.txt}}",
        args.out.display()
    ))?;
    crate::stdoutln!("{summary}");
    eprintln!(
        "wrote {}/{{pil.csv, host.csv, pil.txt}}",
        args.out.display()
    );
    Ok(())
}
