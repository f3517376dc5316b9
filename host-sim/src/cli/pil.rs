//! `host-sim pil`: the firmware binary on QEMU in closed loop with the
//! simulated prototype ([`crate::pil`]), compared with the host-only run.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::Context;

use crate::cli;
use crate::cli::trace::RunArgs;
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
    /// Longest wait for one tick's answer, s.
    #[arg(long, default_value_t = 20.0, value_parser = cli::f64_above(0.0, 3600.0))]
    pub tick_timeout_s: f64,
    /// The closed-loop run.
    #[command(flatten)]
    pub run: RunArgs,
}

/// `host-sim pil`.
pub fn run(args: PilArgs) -> anyhow::Result<()> {
    let plant = crate::io::config::load_plant(args.run.plant.as_deref())?;
    let opts = args.run.options();
    let pil = PilOptions {
        elf: args.elf.clone(),
        out_dir: args.out.clone(),
        link_port: args.link_port,
        tick_timeout: Duration::from_secs_f64(args.tick_timeout_s),
    };
    let bar = indicatif::ProgressBar::new(0);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "PIL {bar:40} {pos}/{len} ticks ({per_sec}, eta {eta})",
        )
        .context("progress bar template")?,
    );
    let cmp = compare(plant, &opts, &pil, &mut |k, n| {
        if k == 1 {
            bar.set_length(n as u64);
        }
        bar.set_position(k as u64);
    })?;
    bar.finish_and_clear();
    let summary = cmp.to_string();
    let config = opts.config();
    let log_opts = crate::ingest::LogOptions::default();
    let mut out = Outputs::new();
    crate::ingest::to_log(&cmp.pil.telemetry(), &config, &log_opts)?
        .stage(&mut out, args.out.join("pil.csv"))?;
    crate::ingest::to_log(&cmp.host.telemetry(), &config, &log_opts)?
        .stage(&mut out, args.out.join("host.csv"))?;
    out.bytes(&args.out.join("pil.txt"), summary.as_bytes())?;
    out.commit()?;
    println!("{summary}");
    eprintln!(
        "wrote {}/{{pil.csv, host.csv, pil.txt}}",
        args.out.display()
    );
    Ok(())
}
