//! `host-sim link`: operate the firmware over its link (the prototype's
//! USART2, or QEMU's through `host-sim pil --link-port`): load a
//! configuration, clear a fault, set the telemetry rate, run a scenario's
//! commands, and record the telemetry stream as the project's CSV log.
//!
//! Time is the firmware's: a scenario's commands are sent when the
//! streamed tick counter reaches each segment's start, and recording ends
//! after `--duration-s` of firmware ticks, so the same command drives the
//! prototype in real time and QEMU at whatever speed it runs.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{bail, ensure, Context};
use cable_joint::board::{HomingConfig, Phase, Program};
use cable_joint::controller::{Command, Mode};
use cable_joint::link::Down;
use cable_joint::telemetry::Record;
use cable_joint::trajectory::Trajectory;
use cable_joint::Config;

use crate::cli;
use crate::cli::simulate::GripArgs;
use crate::derive::log_clock;
use crate::ident::excite::{self, Design};
use crate::ingest::{to_log, LogOptions};
use crate::live::{Live, Screen, ViewArg};
use crate::log::Log;
use crate::operator::{is_serial, open, serial_shortfall, Client, Losses};
use crate::output::Outputs;
use crate::scenario::{plan, GripOptions, ScenarioOptions};

/// Arguments of `host-sim link`.
#[derive(clap::Args, Debug, Clone)]
pub struct LinkArgs {
    /// The firmware link: `tcp:HOST:PORT` (QEMU: `host-sim pil
    /// --link-port`) or a serial device (the prototype's USART2, set to
    /// 460 800 baud raw with stty).
    #[arg(long)]
    pub port: String,
    /// Clear the latched fault first (refused while its cause persists).
    #[arg(long)]
    pub clear_fault: bool,
    /// Load this configuration (TOML, e.g. from `host-sim identify`):
    /// checked by `validate()` here, sent, checked and prepared again on the
    /// MCU, applied between two ticks.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// One telemetry record every this many ticks.
    #[arg(allow_negative_numbers = true, long, value_parser = clap::value_parser!(u32).range(1..))]
    pub decimation: Option<u32>,
    /// Run a scenario's commands (the names of `host-sim simulate`; e.g.
    /// `jae-ident`, `track-motor`, `loading`): sensor check and homing, then
    /// each segment's command at its start. Weights and forces are the
    /// operator's to apply on the rig.
    #[arg(long)]
    pub scenario: Option<String>,
    /// `--scenario excite`: run this designed series (`host-sim excite
    /// --out`; default: the design for `jae-ident`'s envelope).
    #[arg(long)]
    pub excitation: Option<PathBuf>,
    /// `--scenario grip`: the set point, and where the object is.
    #[command(flatten)]
    pub grip: GripArgs,
    /// Scale of every segment of `--scenario` (1 = the full programme; the
    /// same scale as `host-sim simulate --duration-scale`).
    #[arg(allow_negative_numbers = true, long, default_value_t = 1.0, value_parser = cli::f64_above(0.0, 1e3))]
    pub duration_scale: f64,
    /// Record the telemetry stream to this CSV log.
    #[arg(long)]
    pub record: Option<PathBuf>,
    /// The magnetic joint encoder is fitted (calibration runs): the log
    /// gets its angle as `theta_rad`, which `host-sim identify` needs.
    #[arg(long)]
    pub magnetic: bool,
    /// Firmware seconds to record (default: the scenario's length plus
    /// homing, else 1 s).
    #[arg(allow_negative_numbers = true, long, value_parser = cli::f64_above(0.0, 1e5))]
    pub duration_s: Option<f64>,
    /// The live view of the stream (recording goes on behind it; `q`
    /// stops early and keeps what was recorded).
    #[command(flatten)]
    pub view: ViewArg,
    /// Start the scenario's motion at this wall-clock time (Unix time, s;
    /// e.g. `$(( $(date +%s) + 30 ))`) instead of when homing ends: the
    /// joint holds where its first command starts until then. Four `link`
    /// processes given one time start a wrist's four joints together
    /// (each joint's homing takes its own time). Homing still running at
    /// that time is an error.
    #[arg(long, allow_negative_numbers = true, value_name = "UNIX_S", requires = "scenario",
          value_parser = cli::f64_above(0.0, 1e11))]
    pub start_at: Option<f64>,
    /// Give up when no telemetry arrives for this long (wall clock), s.
    #[arg(allow_negative_numbers = true, long, default_value_t = 60.0, value_parser = cli::f64_above(0.0, 1e5))]
    pub idle_timeout_s: f64,
}

/// A scenario for the firmware: the program that starts it, every command
/// with its time (s after homing), and its length, s.
struct Schedule {
    program: Program,
    commands: Vec<(f64, Command)>,
    length_s: f64,
}

/// A scenario's commands at their firmware times, every segment's length
/// scaled by `duration_scale`.
fn schedule(
    name: &str,
    duration_scale: f64,
    excitation: Option<Design>,
    grip: GripOptions,
    start_at: Option<f64>,
    config: &Config,
) -> anyhow::Result<Schedule> {
    let opts = ScenarioOptions {
        duration_scale,
        excitation,
        grip,
        ..ScenarioOptions::default()
    };
    let p = plan(name, &opts)?;
    if name == "excite" {
        crate::scenario::check_excitation_range(&p.references(), config)?;
    }
    let mut t = 0.0;
    let mut commands = Vec::new();
    for seg in &p.segments {
        if let Some(c) = seg.command {
            commands.push((t, c));
        }
        t += seg.duration_s;
    }
    let hold = Command {
        mode: Mode::JointClosedLoop,
        trajectory: Trajectory::Hold { angle_rad: 0.0 },
    };
    let first = commands.first().map_or(hold, |&(_, c)| c);
    // Started at a wall-clock time: hold where the first command starts
    // until then; every command, the first included, is sent then.
    let first = match start_at {
        Some(_) => Command {
            mode: first.mode,
            trajectory: Trajectory::Hold {
                angle_rad: first.trajectory.at(0.0).angle_rad,
            },
        },
        None => first,
    };
    let program = Program {
        // `bm-noload` runs with the rope wheel unhooked: no homing, and
        // the firmware faults if slider 1 moves (HomingConfig::motor_only).
        homing: HomingConfig {
            motor_only: p.motor_decoupled,
            ..HomingConfig::default()
        },
        command: first,
        // The host sends a heartbeat every 0.2 s of firmware time.
        command_timeout_s: 1.0,
    };
    Ok(Schedule {
        program,
        commands,
        length_s: t,
    })
}

/// The furthest ahead `--start-at` may be, s (a larger value is more
/// likely milliseconds or a typo than a plan).
const MAX_START_WAIT_S: f64 = 3600.0;

/// Scenarios whose run rests on the force estimate (`loading` judges it,
/// `grip` regulates it): `link` warns before them when the configuration
/// it loads still has force parameters of the datasheet plant.
const FORCE_SCENARIOS: [&str; 2] = ["loading", "grip"];

/// `host-sim link`.
pub fn run(args: LinkArgs) -> anyhow::Result<()> {
    let config = crate::io::config::load_or_default(args.config.as_deref())?;
    let excitation = args.excitation.as_deref().map(excite::load).transpose()?;
    // A rig's run cannot be repeated: a recording that could not be
    // written is refused before the link opens, not after the run.
    if let Some(path) = &args.record {
        crate::output::check_file_target(path)
            .map_err(|e| anyhow::anyhow!("--record {e}: nothing was sent to the firmware"))?;
    }
    let scenario = args
        .scenario
        .as_deref()
        .map(|name| {
            schedule(
                name,
                args.duration_scale,
                excitation,
                args.grip.options(),
                args.start_at,
                &config,
            )
        })
        .transpose()?;
    // The wait before the motion starts, host clock, s.
    let wait_s = match args.start_at {
        Some(at) => {
            let wait_s = at - unix_now_s();
            ensure!(
                wait_s > 0.0,
                "--start-at {at} is {:.1} s in the past (the host's clock now: {:.1})",
                -wait_s,
                unix_now_s()
            );
            ensure!(
                wait_s <= MAX_START_WAIT_S,
                "--start-at {at} is {wait_s:.0} s away, more than {MAX_START_WAIT_S} s: \
                 a Unix time in seconds, e.g. $(( $(date +%s) + 30 ))"
            );
            wait_s
        }
        None => 0.0,
    };
    // Before the board is touched: a run that acts on the force estimate
    // (a grip regulates it) with force parameters of the datasheet plant.
    if let (Some(path), Some(name)) = (&args.config, args.scenario.as_deref()) {
        if FORCE_SCENARIOS.contains(&name) {
            let what = path.display().to_string();
            if let Some(w) = crate::io::config::datasheet_force_warning(&config, &what) {
                eprintln!("{w}");
            }
        }
    }
    let mut client = Client::new(open(&args.port)?)?;
    // First, always: a frame the firmware could take for a resend of the
    // last session's last request (link::Repeats) is then a heartbeat.
    client.request(&Down::Heartbeat)?;
    eprintln!("connected to {}", args.port);
    if args.clear_fault {
        client.request(&Down::ClearFault)?;
        eprintln!("fault cleared");
    }
    if let Some(path) = &args.config {
        client.request(&Down::SetConfig(config))?;
        eprintln!("configuration {} loaded", path.display());
    }
    if let Some(n) = args.decimation {
        client.request(&Down::SetDecimation(n))?;
        eprintln!("telemetry every {n} ticks");
        if let Some(w) = is_serial(&args.port)
            .then(|| serial_shortfall(f64::from(config.control_rate_hz), n))
            .flatten()
        {
            eprintln!("warning: {w}");
        }
    }
    let rate_hz = f64::from(config.control_rate_hz);
    let mut pending: Vec<(f64, Command)> = Vec::new();
    let duration_s = match &scenario {
        Some(s) => {
            client.request(&Down::Program(s.program))?;
            // The first command runs with the program after homing, unless
            // the motion starts at a wall-clock time.
            let sent = usize::from(args.start_at.is_none());
            pending = s.commands.iter().skip(sent).rev().copied().collect();
            eprintln!(
                "scenario {}: check, {}then {} commands over {:.1} s",
                args.scenario.as_deref().unwrap_or_default(),
                if s.program.homing.motor_only {
                    "no homing (motor only: the rope wheel unhooked, slider 1 clamped; \
                     slider 1 moving is a fault), "
                } else {
                    "homing, "
                },
                s.commands.len(),
                s.length_s
            );
            args.duration_s.unwrap_or(s.length_s + 3.0 + wait_s)
        }
        None => args.duration_s.unwrap_or(1.0),
    };
    let want_ticks = (duration_s * rate_hz).round() as u64;
    let bar = if args.view.view {
        indicatif::ProgressBar::hidden()
    } else {
        indicatif::ProgressBar::new(want_ticks)
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{bar:40} {pos}/{len} firmware ticks, phase {msg} (eta {eta})",
        )
        .context("progress bar template")?,
    );
    let mut view = if args.view.view {
        Some((
            Screen::open()?,
            Live::new(&args.port, rate_hz, config.scales).asked_every(args.decimation),
        ))
    } else {
        None
    };
    let recording = match &args.record {
        Some(p) => format!("recording {}", p.display()),
        None => "not recording".to_string(),
    };
    let mut stopped = false;
    let mut records: Vec<Record> = Vec::new();
    // The newest tick of each batch received and the host's clock then:
    // the log's `t_unix_s` (ingest::host_clock_offset_s).
    let mut arrivals: Vec<(u32, f64)> = Vec::new();
    let (mut first_tick, mut homed_tick, mut last_beat) = (None::<u32>, None::<u32>, 0u32);
    let mut origin_tick: Option<u32> = None;
    let mut elapsed = 0u64;
    let mut last_data = Instant::now();
    let idle = Duration::from_secs_f64(args.idle_timeout_s);
    // What was received is written even when the link fails part way.
    // Ctrl-C (or kill) stops the run as `q` does (crate::interrupt), and
    // until the recording is written only a second one stops at once.
    let _interrupt = crate::interrupt::Graceful::new();
    let outcome = (|| -> anyhow::Result<()> {
        loop {
            if crate::interrupt::requested() {
                stopped = true;
                break;
            }
            let got = client.poll()?;
            let mut now = None;
            for r in &got {
                if let Record::Tick(t) = r {
                    now = Some(t.tick);
                    bar.set_message(format!("{} fault {}", t.phase, t.fault));
                    if homed_tick.is_none() && t.phase == Phase::Running.code() {
                        homed_tick = Some(t.tick);
                    }
                    if let Some((_, live)) = &mut view {
                        live.push(t);
                    }
                }
            }
            if let Some(now) = now {
                elapsed = u64::from(now.wrapping_sub(*first_tick.get_or_insert(now)));
                arrivals.push((now, unix_now_s()));
            }
            if let Some((screen, live)) = &mut view {
                live.set_note(format!(
                    "{recording} · {:.1} of {duration_s:.1} s · {} damaged frames",
                    elapsed as f64 / rate_hz,
                    client.damaged
                ));
                if screen.refresh(live)? {
                    stopped = true;
                    break;
                }
            }
            if got.is_empty() {
                if last_data.elapsed() > idle {
                    bail!(
                        "no telemetry for {:.0} s (after {} records): is the firmware running?",
                        args.idle_timeout_s,
                        records.len()
                    );
                }
                continue;
            }
            last_data = Instant::now();
            records.extend(got);
            let Some(now) = now else { continue };
            bar.set_position(elapsed.min(want_ticks));
            // The tick the scenario's time counts from: homing's end, or
            // the board's tick at --start-at.
            if origin_tick.is_none() {
                origin_tick = match (homed_tick, args.start_at) {
                    (Some(homed), None) => Some(homed),
                    (Some(_), Some(at)) => {
                        let late_s = unix_now_s() - at;
                        (late_s >= 0.0).then(|| now.wrapping_sub((late_s * rate_hz).round() as u32))
                    }
                    (None, Some(at)) => {
                        let late_s = unix_now_s() - at;
                        ensure!(
                            late_s < 0.0,
                            "homing had not ended {late_s:.1} s after --start-at: the joint \
                             cannot start its motion with the others; give a later --start-at"
                        );
                        None
                    }
                    (None, None) => None,
                };
                if let (Some(_), Some(at)) = (origin_tick, args.start_at) {
                    eprintln!(
                        "the scenario's motion starts now (--start-at {at}, {:.3} s ago on the host's clock)",
                        unix_now_s() - at
                    );
                }
            }
            if let Some(origin) = origin_tick {
                let since_s = f64::from(now.wrapping_sub(origin)) / rate_hz;
                while pending.last().is_some_and(|&(t, _)| t <= since_s) {
                    let (_, c) = pending.pop().expect("checked");
                    client.request(&Down::SetCommand(c))?;
                    last_beat = now;
                }
            }
            if scenario.is_some() && f64::from(now.wrapping_sub(last_beat)) / rate_hz > 0.2 {
                client.request(&Down::Heartbeat)?;
                last_beat = now;
            }
            if elapsed >= want_ticks {
                break;
            }
        }
        Ok(())
    })();
    records.extend(client.take_telemetry());
    // Records taken while a request waited for its answer arrived before
    // now: a late stamp, which the least-delay estimate may use.
    if let Some(last) = records.iter().rev().find_map(|r| match r {
        Record::Tick(t) => Some(t.tick),
        _ => None,
    }) {
        arrivals.push((last, unix_now_s()));
    }
    bar.finish_and_clear();
    let mut written = String::from("nothing recorded");
    let ticks = tick_records(&records);
    let log = to_log(
        &records,
        &config,
        &LogOptions {
            magnetic: args.magnetic,
            arrivals: &arrivals,
            ..LogOptions::default()
        },
    );
    let lost = log
        .as_ref()
        .map_or_else(|_| String::new(), |l| lost_records(l, args.decimation));
    if let Some(path) = args
        .record
        .as_ref()
        .filter(|_| outcome.is_ok() || ticks > 0)
    {
        let mut out = Outputs::new();
        log?.stage(&mut out, path)?;
        out.commit()?;
        written = format!("wrote {}", path.display());
    }
    if let Err(e) = outcome {
        drop(view);
        return Err(match &args.record {
            Some(p) if ticks > 0 => e.context(format!(
                "the run ended early, after {ticks} tick records{lost}: those are in {}",
                p.display()
            )),
            _ => e,
        });
    }
    if let Some((mut screen, mut live)) = view {
        if !stopped {
            live.set_note(&written);
            screen.hold(&mut live)?;
        }
    }
    if stopped {
        eprintln!("stopped with q or Ctrl-C before the end; what was received is kept");
    }
    eprintln!(
        "received {ticks} tick records{lost} ({} damaged frames, {} requests sent again)",
        client.damaged, client.resent
    );
    if args.record.is_some() {
        eprintln!("{written}");
    }
    Ok(())
}

/// The host's wall clock, Unix time in seconds (0 if the clock is set
/// before 1970).
fn unix_now_s() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

/// Tick records among `records`.
fn tick_records(records: &[Record]) -> usize {
    records
        .iter()
        .filter(|r| matches!(r, Record::Tick(_)))
        .count()
}

/// What the stream lost, from the tick counter of the records received
/// ([`Losses`], at the decimation `requested` when the run asked for one),
/// for the summary: empty with fewer than two records.
fn lost_records(log: &Log, requested: Option<u32>) -> String {
    let (Ok(clock), Some(tick)) = (log_clock(log), log.col("tick")) else {
        return String::new();
    };
    let mut losses = Losses::new(requested);
    for &t in tick {
        losses.push(t as u32);
    }
    let g = losses.gaps();
    let every = match g.decimation {
        0 => return String::new(),
        1 => "every tick".to_owned(),
        d => format!("every {d} ticks"),
    };
    let since = if g.from > 0 {
        format!(" from line {}", crate::log::line_of_row(g.from))
    } else {
        String::new()
    };
    if g.count == 0 {
        format!(" at a record {every}, none lost{since}")
    } else {
        format!(
            " at a record {every}; {} lost{since} in {} of the tick counter (the longest {:.4} s, \
             before line {}), which a replay of the log fills tick by tick",
            g.missing,
            match g.count {
                1 => "a gap".to_owned(),
                n => format!("{n} gaps"),
            },
            f64::from(g.longest_ticks) * clock.period_s,
            crate::log::line_of_row(g.longest_after)
        )
    }
}
