//! Probing sweep: the loading protocol with the dither at several
//! frequencies and amplitudes, on chosen plant variants (the figures behind
//! `ProbeConfig`'s defaults, `docs/force.md`).
//!
//! ```text
//! cargo run --release -p host-sim --example probe_sweep -- \
//!     "default,slider-1 friction,pin friction,draw 11" "4,0.2;4,0.05;8,0.1;2,0.1"
//! ```
//!
//! The first argument names variants (comma-separated, as in the report);
//! the second lists `frequency_hz,amplitude_deg` pairs (semicolon-separated;
//! `0,0` runs the passive protocol). Each variant is identified once, as in
//! the report, then every setting runs the whole protocol.

use anyhow::{bail, Context, Result};
use cable_joint::Config;
use host_sim::report::programme::{identify_config, Settings};
use host_sim::report::variants::{run_protocol, variants};

fn settings(arg: &str) -> Result<Vec<(f32, f32)>> {
    arg.split(';')
        .map(|pair| {
            let v: Vec<&str> = pair.split(',').collect();
            if v.len() != 2 {
                bail!("`{pair}`: expected frequency_hz,amplitude_deg");
            }
            let f = v[0]
                .trim()
                .parse()
                .with_context(|| format!("frequency in `{pair}`"))?;
            let a = v[1]
                .trim()
                .parse()
                .with_context(|| format!("amplitude in `{pair}`"))?;
            Ok((f, a))
        })
        .collect()
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() != 2 {
        bail!("usage: probe_sweep \"<variant>,<variant>...\" \"<f_hz>,<amp_deg>;...\"");
    }
    let all = variants();
    let s = Settings::quiet();
    let pairs = settings(&args[1])?;
    println!("| variant | f [Hz] | A [°] | fused worst ≥1 N [%] | worst 0.3 N [%] | static no-load [N] | coverage [%] | tip motion [°] | faults |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for name in args[0].split(',') {
        let Some(v) = all.iter().find(|v| v.name == name.trim()) else {
            let names: Vec<_> = all.iter().map(|v| v.name.as_str()).collect();
            bail!("unknown variant `{name}` (known: {})", names.join(", "));
        };
        let (base, _) = Config::default().at_rate(v.rate_hz);
        let (config, _) = identify_config(&v.plant, &base, &s, &v.name)?;
        for &(f_hz, amp_deg) in &pairs {
            let mut c = config;
            c.probe.enabled = f_hz > 0.0;
            if c.probe.enabled {
                c.probe.frequency_hz = f_hz;
                c.probe.amplitude_rad = amp_deg.to_radians();
                if let Err(e) = c.validate() {
                    bail!("{f_hz} Hz, {amp_deg}°: {e}");
                }
            }
            let label = format!("variant/{}/probing", v.name);
            let p = run_protocol(&v.plant, &c, &s, &label);
            let fu = &p.sources[2];
            println!(
                "| {} | {f_hz} | {amp_deg} | {:.1} | {:.1} | {:.3} | {:.1} | {:.3} | {}/{} |",
                v.name,
                fu.above_1n_min_pct,
                fu.at_0n3_min_pct,
                fu.static_noload_n,
                100.0 * p.coverage,
                p.tip_motion_pp_deg,
                p.faults.len(),
                p.cases
            );
        }
    }
    Ok(())
}
