//! `host-sim ingest FILE --out run.csv`: firmware telemetry → project CSV log.
//!
//! Input: the decoded defmt text that `probe-rs run` (hardware, RTT) or
//! `defmt-print` (QEMU, semihosting) prints. Lines carrying a telemetry
//! record (`tlm [..]`, see [`cable_joint::telemetry`]) are decoded; all other
//! lines (log messages, locations) are skipped. A malformed record is an
//! error naming the file and the line.
//!
//! Conversion to SI units happens here, on the host, with the same
//! [`Scales`] functions the core uses: counters are taken relative to the
//! latest origin record (the controller's own zero), the 16-bit motor and
//! magnetic counters are extended across records (at most 32767 counts
//! between two records: at the default 200 Hz telemetry rate that is
//! 1030 rad/s of the motor, near its speed limit; lower the decimation for
//! faster motion). Output columns: DESIGN.md §2's `t_s`, `x1_m`, `x2_m`,
//! `phi_rad`, `i_ref_a`, `i_meas_a`, (`theta_rad` with `--magnetic`),
//! `theta_ref_rad`, then `theta_hat_rad`, `f_ext_hat_n`, `f_ext_fused_n`,
//! `f_ext_lo_n`, `f_ext_hi_n`, `i_applied_a` (the mean current applied
//! since the row before, which the replay holds over a decimated log's
//! ticks between rows), `dac_code`, `mode`, `fault_code`, `drive_enable`, `fw_phase`, `origin_switch`,
//! `drive_fault_line`, `tick` and the cycle counts `cycles`,
//! `cycles_sensing`, `cycles_jae`, `cycles_dob`, `cycles_cascade`.
//!
//! `--stats` prints min/median/max of the cycle counts per stage.

use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;

use anyhow::{bail, Context};
use cable_joint::board::Phase;
use cable_joint::telemetry::{parse_line, Record, StartRecord, TickRecord};
use cable_joint::units::{Extender16, GratingCount, Scales};
use cable_joint::Config;

use crate::log::Log;

/// Options of the conversion.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LogOptions<'a> {
    /// Add `theta_rad` from the magnetic encoder.
    pub magnetic: bool,
    /// When records arrived on the host (`host-sim link`): each a tick
    /// counter received and the host's wall clock then (Unix time, s).
    /// Not empty, the log gets [`HOST_CLOCK_COLUMN`] ([`host_clock_offset_s`]).
    pub arrivals: &'a [(u32, f64)],
    /// Each record's line in the file it was read from
    /// ([`parse_stream_lines`]), for the errors to name; empty for a live
    /// stream.
    pub lines: &'a [usize],
}

/// The host's wall clock at each tick (Unix time, s), estimated from when
/// its records arrived ([`host_clock_offset_s`]): logs recorded by several
/// `host-sim link` processes on one computer share it, so a wrist's four
/// joints' logs can be aligned on it (`host_sim::wrist_log`).
pub const HOST_CLOCK_COLUMN: &str = "t_unix_s";

/// The host's wall clock at tick zero, s: the least `arrived - tick /
/// rate_hz` over `arrivals` (tick, Unix time of arrival). A record cannot
/// arrive before it was made, and the fastest arrival is the closest to
/// it, so the least difference is the estimate least delayed by the link
/// (its error is the link's shortest delay plus the drift between the
/// board's crystal and the host's clock over the run: 50 ppm, 3 ms a
/// minute). `None` without arrivals.
pub fn host_clock_offset_s(arrivals: &[(u32, f64)], rate_hz: f64) -> Option<f64> {
    arrivals
        .iter()
        .map(|&(tick, unix_s)| unix_s - f64::from(tick) / rate_hz)
        .filter(|x| x.is_finite())
        .reduce(f64::min)
}

/// Read every telemetry record of a decoded defmt text. `name` is used in
/// error messages.
pub fn parse_stream(reader: impl Read, name: &str) -> anyhow::Result<Vec<Record>> {
    parse_stream_lines(reader, name).map(|(records, _)| records)
}

/// [`parse_stream`], with each record's line in the input (1-based), for
/// [`LogOptions::lines`].
pub fn parse_stream_lines(
    reader: impl Read,
    name: &str,
) -> anyhow::Result<(Vec<Record>, Vec<usize>)> {
    let mut out = Vec::new();
    let mut lines = Vec::new();
    for (i, line) in BufReader::new(reader).lines().enumerate() {
        let line = line.with_context(|| format!("{name}:{}: reading", i + 1))?;
        if let Some(rec) = parse_line(&line) {
            let rec = rec.map_err(|e| anyhow::anyhow!("{name}:{}: {e}", i + 1))?;
            if let Record::Tick(t) = &rec {
                if let Some((field, v)) = non_finite_field(t) {
                    bail!(
                        "{name}:{}: tick {}: {field} is {v}; the firmware never sends a \
                         non-finite value (it faults instead), so this record is corrupt",
                        i + 1,
                        t.tick
                    );
                }
            }
            out.push(rec);
            lines.push(i + 1);
        }
    }
    Ok((out, lines))
}

/// The first real-valued field of a tick record that is NaN or infinite.
fn non_finite_field(t: &TickRecord) -> Option<(&'static str, f32)> {
    [
        ("current_ref_a", t.current_ref_a),
        ("current_applied_a", t.current_applied_a),
        ("theta_ref_rad", t.theta_ref_rad),
        ("theta_hat_rad", t.theta_hat_rad),
        ("f_ext_hat_n", t.f_ext_hat_n),
        ("f_ext_fused_n", t.f_ext_fused_n),
        ("f_ext_lo_n", t.f_ext_lo_n),
        ("f_ext_hi_n", t.f_ext_hi_n),
    ]
    .into_iter()
    .find(|(_, v)| !v.is_finite())
}

/// What messages call the stream at `path`: the path, or "standard
/// input" for `-`.
pub fn source_name(path: &Path) -> String {
    if path == Path::new("-") {
        "standard input".to_owned()
    } else {
        path.display().to_string()
    }
}

/// Read a stream from a file (`-` for standard input), with each record's
/// line ([`parse_stream_lines`]); messages name it by [`source_name`].
pub fn read_stream(path: &Path) -> anyhow::Result<(Vec<Record>, Vec<usize>)> {
    let name = source_name(path);
    if path == Path::new("-") {
        parse_stream_lines(std::io::stdin().lock(), &name)
    } else {
        crate::output::note_input(path);
        let f = File::open(path).with_context(|| format!("opening {name}"))?;
        parse_stream_lines(f, &name)
    }
}

/// The estimates a firmware record carries, computed on line at every
/// control tick: columns of [`to_log`], and of a simulated recording
/// ([`crate::sim::recorded_every`]).
pub const ONBOARD_COLUMNS: [&str; 5] = [
    "theta_hat_rad",
    "f_ext_hat_n",
    "f_ext_fused_n",
    "f_ext_lo_n",
    "f_ext_hi_n",
];

/// Column names of [`to_log`].
pub fn columns(opts: &LogOptions) -> Vec<&'static str> {
    let mut c = vec!["t_s", "x1_m", "x2_m", "phi_rad", "i_ref_a", "i_meas_a"];
    if opts.magnetic {
        c.push("theta_rad");
    }
    c.push("theta_ref_rad");
    c.extend(ONBOARD_COLUMNS);
    c.extend([
        "i_applied_a",
        "dac_code",
        "mode",
        "fault_code",
        "drive_enable",
        "fw_phase",
        "origin_switch",
        "drive_fault_line",
        "tick",
        "cycles",
        "cycles_sensing",
        "cycles_jae",
        "cycles_dob",
        "cycles_cascade",
    ]);
    if !opts.arrivals.is_empty() {
        c.push(HOST_CLOCK_COLUMN);
    }
    c
}

/// A firmware log from its first row after homing. The rows of the sensor
/// check and homing (`fw_phase` below 4) count positions from power-on,
/// not from the origin homing takes, so a replay through them would see
/// the origin as a jump; they are left out, and the note says where the
/// log now starts. A log without `fw_phase`, or running from its first
/// row, is returned whole and without a note. One that never reaches the
/// running phase is refused: its program never ran, and its positions
/// count from power-on, so it holds no run to replay (the error says how
/// start-up ended).
pub fn after_homing(log: Log) -> anyhow::Result<(Log, Option<String>)> {
    let Some(phase) = log.col("fw_phase") else {
        return Ok((log, None));
    };
    let running = f64::from(Phase::Running.code());
    match phase.iter().position(|&p| p == running) {
        Some(0) => Ok((log, None)),
        Some(first) => {
            let t = log.col("t_s").map_or(f64::NAN, |t| t[first]);
            // A motor-only program (the no-load motor run) has no homing.
            let homed = phase[..first].iter().any(|&p| {
                p == f64::from(Phase::Leaving.code()) || p == f64::from(Phase::Homing.code())
            });
            let (before, ended) = if homed {
                ("sensor check and homing", "homing ended")
            } else {
                ("sensor check", "the check ended (no homing)")
            };
            let note = format!(
                "the log starts with {first} rows of {before} (fw_phase < 4), counted from \
                 power-on: replayed from row {} (t = {t:.3} s), where {ended}",
                first + 1
            );
            let n = log.len();
            Ok((log.rows(first..n), Some(note)))
        }
        None => {
            let last = phase.last().map_or_else(
                || "it has no rows".to_string(),
                |&p| {
                    let name = Phase::from_code(p as u8)
                        .filter(|_| p.fract() == 0.0 && (0.0..=255.0).contains(&p))
                        .map_or_else(|| "an unknown phase".into(), |ph| format!("{ph:?}"));
                    format!("its last row is in phase {p} ({name})")
                },
            );
            let fault = first_recorded_fault(&log).map_or_else(String::new, |(k, code)| {
                format!(
                    ", after {} at line {}{}",
                    fault_words(code),
                    crate::log::line_of_row(k),
                    log.col("t_s")
                        .map_or_else(String::new, |t| format!(" (t = {:.3} s)", t[k]))
                )
            });
            bail!(
                "fw_phase never reaches 4 (running): start-up did not end ({last}{fault}), so \
                 the program never ran and the positions count from power-on; there is no run \
                 to replay (record again once the sensor check and homing pass)"
            )
        }
    }
}

/// A fault code in words, with the code: "measured current above its
/// limit (code 15)", or "code 99" for a code no fault has.
pub fn fault_words(code: u8) -> String {
    cable_joint::Fault::from_code(code)
        .map_or_else(|| format!("code {code}"), |f| format!("{f} (code {code})"))
}

/// The first row whose `fault_code` is not 0, and the code.
pub fn first_recorded_fault(log: &Log) -> Option<(usize, u8)> {
    let fault = log.col("fault_code")?;
    let k = fault.iter().position(|&f| f != 0.0)?;
    Some((k, fault[k].clamp(0.0, 255.0) as u8))
}

/// Where a replay of a firmware log ends.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReplayEnd {
    /// At the log's last row (`estimate`: what the board estimated after a
    /// fault is shown as well).
    LastRow,
    /// Before the firmware's first latched fault (`identify`, `residual`):
    /// from there on the drive is off and the mechanism relaxes, which no
    /// fitted model describes, and a fault of the board's own (homing,
    /// command timeout, drive fault line) is not one the core's replay
    /// latches again.
    BeforeFault,
}

/// [`ReplayEnd::BeforeFault`]: the rows of `log` before its first
/// recorded fault, with a note when rows were left out (naming the line of
/// the file, whose first `first_row` rows are not in `log`); an error when
/// the fault was latched on its first row.
pub fn before_recorded_fault(
    log: Log,
    name: &str,
    first_row: usize,
) -> anyhow::Result<(Log, Option<String>)> {
    let Some((k, code)) = first_recorded_fault(&log) else {
        return Ok((log, None));
    };
    let t = log
        .col("t_s")
        .map_or_else(String::new, |t| format!(" (t = {:.3} s)", t[k]));
    if k == 0 {
        bail!(
            "{name}: {} is latched on the log's first replayed row{t}: there are no rows \
             with the drive under control to replay",
            fault_words(code)
        );
    }
    let note = format!(
        "the firmware latched {} at line {}{t}: the {} rows from there on (the drive off) \
         are left out",
        fault_words(code),
        crate::log::line_of_row(first_row + k),
        log.len() - k
    );
    Ok((log.rows(0..k), Some(note)))
}

/// Read a project log for a command that replays it: with `ticks_per_row`
/// (a log kept at a row every N control ticks without the firmware's tick
/// counter) its tick column is rebuilt from the times
/// ([`crate::derive::set_ticks_per_row`]), then [`trim_for_replay`].
pub fn read_for_replay(
    path: &std::path::Path,
    ticks_per_row: Option<u32>,
    command: &str,
    end: ReplayEnd,
) -> anyhow::Result<Log> {
    let name = path.display().to_string();
    let mut log = Log::read(path)?;
    if let Some(n) = ticks_per_row {
        let note = crate::derive::set_ticks_per_row(&mut log, n)
            .with_context(|| format!("{name}: --ticks-per-row {n}"))?;
        eprintln!("{command}: {name}: {note}");
    }
    trim_for_replay(log, &name, command, end)
}

/// The rows of the log `name` a command replays: the rows before the end
/// of homing are dropped ([`after_homing`]), and with
/// [`ReplayEnd::BeforeFault`] the rows from the firmware's first latched
/// fault on ([`before_recorded_fault`]); the notes go to stderr, each
/// after `command: `.
pub fn trim_for_replay(log: Log, name: &str, command: &str, end: ReplayEnd) -> anyhow::Result<Log> {
    let rows = log.len();
    let (log, note) = after_homing(log).with_context(|| name.to_string())?;
    if let Some(note) = note {
        eprintln!("{command}: {name}: {note}");
    }
    match end {
        ReplayEnd::LastRow => Ok(log),
        ReplayEnd::BeforeFault => {
            let homing_rows = rows - log.len();
            let (log, note) = before_recorded_fault(log, name, homing_rows)?;
            if let Some(note) = note {
                eprintln!("{command}: {name}: {note}");
            }
            Ok(log)
        }
    }
}

/// Convert a telemetry stream to the project's CSV log.
pub fn to_log(records: &[Record], config: &Config, opts: &LogOptions) -> anyhow::Result<Log> {
    let start: Option<StartRecord> = records.iter().find_map(|r| match r {
        Record::Start(s) => Some(*s),
        _ => None,
    });
    let rate_hz = start.map_or(config.control_rate_hz, |s| s.control_rate_hz);
    // The range the core accepts (Config::validate), at that rate.
    if let Err(e) = config.at_rate(rate_hz).0.validate() {
        if e.field == "control_rate_hz" {
            bail!(
                "{} gives a control rate of {rate_hz} Hz: it must be {}",
                if start.is_some() {
                    "the telemetry start record"
                } else {
                    "the configuration"
                },
                e.expected
            );
        }
    }
    let s: &Scales = &config.scales;
    let mut log = Log::with_columns(&columns(opts))?;
    let host_offset_s = host_clock_offset_s(opts.arrivals, f64::from(rate_hz));
    if host_offset_s.is_none() && !opts.arrivals.is_empty() {
        bail!("no arrival time of the records is a finite wall-clock time");
    }
    let mut motor = Extender16::default();
    let mut magnetic = Extender16::default();
    let mut origin = (0i32, 0i32, 0i32, 0i32);
    let mut last_tick: Option<u32> = None;
    let mut starts = 0;
    let mut row = Vec::with_capacity(32);
    // Start-up seen since the last running tick, and an origin record
    // since then (homing ends with one).
    let (mut starting, mut origin_seen) = (false, false);
    // Where record `i` is, for an error: its line in the file, if known.
    let at = |i: usize| {
        opts.lines
            .get(i)
            .map_or_else(String::new, |l| format!("line {l}: "))
    };
    for (i, rec) in records.iter().enumerate() {
        match rec {
            Record::Start(_) => {
                starts += 1;
                if starts > 1 {
                    bail!(
                        "{}a second start record: the firmware restarted; split the file there",
                        at(i)
                    );
                }
            }
            Record::Origin(o) => {
                let (m, _) = motor.update(o.raw.motor.0);
                let (g, _) = magnetic.update(o.raw.magnetic.0);
                origin = (o.raw.grating1.0, o.raw.grating2.0, m, g);
                origin_seen = true;
            }
            Record::Tick(t) => {
                if let Some(prev) = last_tick {
                    if t.tick <= prev {
                        bail!(
                            "{}tick {} after tick {prev}: the firmware restarted or the \
                             stream is out of order",
                            at(i),
                            t.tick
                        );
                    }
                }
                last_tick = Some(t.tick);
                if t.phase < Phase::Running.code() {
                    starting = true;
                } else if t.phase == Phase::Running.code() && starting {
                    if !origin_seen {
                        eprintln!(
                            "warning: homing ended by tick {} but its origin record is not in \
                             the stream (lost on the way): the positions after it are counted \
                             from the origin before (power-on), off by a constant",
                            t.tick
                        );
                    }
                    (starting, origin_seen) = (false, false);
                }
                let (m, _) = motor.update(t.raw.motor.0);
                let (g, _) = magnetic.update(t.raw.magnetic.0);
                row.clear();
                row.push(t.tick as f64 / rate_hz as f64);
                row.push(s.grating_m(GratingCount(t.raw.grating1.0.wrapping_sub(origin.0))) as f64);
                row.push(s.grating_m(GratingCount(t.raw.grating2.0.wrapping_sub(origin.1))) as f64);
                row.push(s.motor_rad(m.wrapping_sub(origin.2)) as f64);
                row.push(t.current_ref_a as f64);
                row.push(s.adc_a(t.raw.current) as f64);
                if opts.magnetic {
                    row.push(s.magnetic_rad(g.wrapping_sub(origin.3)) as f64);
                }
                row.extend(tick_columns(t));
                if let Some(offset_s) = host_offset_s {
                    row.push(offset_s + f64::from(t.tick) / f64::from(rate_hz));
                }
                log.push_row(&row)?;
            }
        }
    }
    Ok(log)
}

fn tick_columns(t: &TickRecord) -> [f64; 20] {
    [
        t.theta_ref_rad as f64,
        t.theta_hat_rad as f64,
        t.f_ext_hat_n as f64,
        t.f_ext_fused_n as f64,
        t.f_ext_lo_n as f64,
        t.f_ext_hi_n as f64,
        t.current_applied_a as f64,
        t.dac.0 as f64,
        t.mode as f64,
        t.fault as f64,
        t.drive_enable as u8 as f64,
        t.phase as f64,
        t.inputs.origin() as u8 as f64,
        t.inputs.drive_fault() as u8 as f64,
        t.tick as f64,
        t.cycles as f64,
        t.stage_cycles[0] as f64,
        t.stage_cycles[1] as f64,
        t.stage_cycles[2] as f64,
        t.stage_cycles[3] as f64,
    ]
}

/// Minimum, median and maximum of a set of counts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Spread {
    /// Smallest.
    pub min: u32,
    /// Median (lower middle for an even count).
    pub median: u32,
    /// Largest.
    pub max: u32,
}

impl Spread {
    /// Spread of `values`; `None` when empty.
    pub fn of(mut values: Vec<u32>) -> Option<Spread> {
        values.sort_unstable();
        Some(Spread {
            min: *values.first()?,
            median: values[(values.len() - 1) / 2],
            max: *values.last()?,
        })
    }
}

/// Cycle (or instruction) counts per stage over the tick records.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CycleStats {
    /// Ticks counted.
    pub ticks: usize,
    /// Sensing, JAE, DOB, cascade.
    pub stages: [Spread; 4],
    /// The whole `step_timed` (sum of the stages).
    pub step: Spread,
    /// The whole tick (task body: sample to drive line).
    pub tick: Spread,
}

/// Stage statistics over `ticks`; `None` without ticks.
pub fn cycle_stats(ticks: &[TickRecord]) -> Option<CycleStats> {
    let stage = |i: usize| Spread::of(ticks.iter().map(|t| t.stage_cycles[i] as u32).collect());
    Some(CycleStats {
        ticks: ticks.len(),
        stages: [stage(0)?, stage(1)?, stage(2)?, stage(3)?],
        step: Spread::of(ticks.iter().map(|t| t.step_cycles()).collect())?,
        tick: Spread::of(ticks.iter().map(|t| t.cycles).collect())?,
    })
}

impl std::fmt::Display for CycleStats {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "{} ticks", self.ticks)?;
        writeln!(
            f,
            "{:<10} {:>8} {:>8} {:>8}",
            "stage", "min", "median", "max"
        )?;
        let names = ["sensing", "jae", "dob", "cascade"];
        for (name, s) in names.iter().zip(self.stages.iter()) {
            writeln!(f, "{name:<10} {:>8} {:>8} {:>8}", s.min, s.median, s.max)?;
        }
        let (s, t) = (self.step, self.tick);
        writeln!(
            f,
            "{:<10} {:>8} {:>8} {:>8}",
            "step", s.min, s.median, s.max
        )?;
        write!(
            f,
            "{:<10} {:>8} {:>8} {:>8}",
            "tick", t.min, t.median, t.max
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The host's clock at tick zero is the least arrival less the tick's
    /// time: with every record delayed by a link latency of at least 2 ms,
    /// it is late by about that least latency, never early.
    #[test]
    fn the_host_clock_offset_is_the_least_delayed_arrival() {
        let (zero_s, rate_hz) = (1.7e9, 2000.0);
        let arrivals: Vec<(u32, f64)> = (0..200u32)
            .map(|k| {
                let tick = 100 * k;
                let latency_s = 0.002 + 0.02 * f64::from((k * 37) % 11) / 11.0;
                (tick, zero_s + f64::from(tick) / rate_hz + latency_s)
            })
            .collect();
        let offset = host_clock_offset_s(&arrivals, rate_hz).unwrap();
        assert!(
            (offset - zero_s - 0.002).abs() < 1e-6,
            "{}",
            offset - zero_s
        );
        assert_eq!(host_clock_offset_s(&[], rate_hz), None);
    }
    use cable_joint::telemetry::{OriginRecord, FORMAT_VERSION, MAX_RECORD_LEN};
    use cable_joint::units::{AdcCode, MagneticCount, MotorCount};
    use cable_joint::RawSample;

    fn phased(phases: &[f64]) -> Log {
        let mut log = Log::with_columns(&["t_s", "x1_m", "fw_phase"]).unwrap();
        for (k, &p) in phases.iter().enumerate() {
            log.push_row(&[k as f64 * 0.5e-3, k as f64, p]).unwrap();
        }
        log
    }

    #[test]
    fn after_homing_starts_a_firmware_log_where_homing_ended() {
        let (log, note) = after_homing(phased(&[0.0, 1.0, 3.0, 3.0, 4.0, 4.0, 5.0])).unwrap();
        assert_eq!(log.col("x1_m").unwrap(), [4.0, 5.0, 6.0]);
        assert_eq!(log.col("fw_phase").unwrap(), [4.0, 4.0, 5.0]);
        let note = note.expect("a cut is noted");
        assert!(note.contains("4 rows of sensor check and homing"), "{note}");
        assert!(note.contains("row 5 (t = 0.002 s)"), "{note}");
        // A motor-only program: a check, no homing.
        let (log, note) = after_homing(phased(&[0.0, 1.0, 1.0, 4.0])).unwrap();
        assert_eq!(log.len(), 1);
        let note = note.unwrap();
        assert!(
            note.contains("3 rows of sensor check (fw_phase < 4)")
                && note.contains("the check ended (no homing)"),
            "{note}"
        );
    }

    #[test]
    fn after_homing_keeps_a_log_running_from_its_start_or_without_phases() {
        let (log, note) = after_homing(phased(&[4.0, 4.0])).unwrap();
        assert_eq!((log.len(), note), (2, None));
        let mut plain = Log::with_columns(&["t_s"]).unwrap();
        plain.push_row(&[0.0]).unwrap();
        let (log, note) = after_homing(plain).unwrap();
        assert_eq!((log.len(), note), (1, None));
    }

    #[test]
    fn after_homing_refuses_a_log_whose_start_up_never_ended_naming_the_fault() {
        let mut log = Log::with_columns(&["t_s", "fault_code", "fw_phase"]).unwrap();
        for (k, (fault, phase)) in [(0.0, 1.0), (0.0, 3.0), (23.0, 5.0), (23.0, 5.0)]
            .into_iter()
            .enumerate()
        {
            log.push_row(&[k as f64 * 0.5, fault, phase]).unwrap();
        }
        let e = trim_for_replay(log, "bm.csv", "identify", ReplayEnd::LastRow).unwrap_err();
        let e = format!("{e:#}");
        for part in [
            "bm.csv",
            "never reaches 4",
            "phase 5 (Failed)",
            "code 23",
            "line 4",
            "t = 1.000 s",
        ] {
            assert!(e.contains(part), "`{part}` missing from: {e}");
        }
    }

    #[test]
    fn a_replay_before_the_fault_ends_on_the_row_before_the_firmware_latched_one() {
        let mut log = Log::with_columns(&["t_s", "x1_m", "fault_code"]).unwrap();
        for (k, fault) in [0.0, 0.0, 0.0, 24.0, 24.0].into_iter().enumerate() {
            log.push_row(&[k as f64 * 0.5, k as f64, fault]).unwrap();
        }
        let (cut, note) = before_recorded_fault(log.clone(), "run.csv", 10).unwrap();
        assert_eq!(cut.col("x1_m").unwrap(), [0.0, 1.0, 2.0]);
        let note = note.unwrap();
        assert!(note.contains("code 24"), "{note}");
        assert!(
            note.contains("line 15") && note.contains("the 2 rows"),
            "{note}"
        );
        let whole = log.rows(0..3);
        assert_eq!(before_recorded_fault(whole, "run.csv", 0).unwrap().1, None);
        let e = before_recorded_fault(log.rows(3..5), "run.csv", 0).unwrap_err();
        assert!(format!("{e}").contains("run.csv: "), "{e}");
    }

    fn line(rec: &Record) -> String {
        let mut buf = [0u8; MAX_RECORD_LEN];
        let bytes = rec.encode(&mut buf);
        let items: Vec<String> = bytes.iter().map(|b| b.to_string()).collect();
        format!("0.000500 INFO  tlm [{}]", items.join(", "))
    }

    fn tick(k: u32, g2: i32, motor: u16) -> TickRecord {
        TickRecord {
            tick: k,
            raw: RawSample {
                grating2: GratingCount(g2),
                motor: MotorCount(motor),
                magnetic: MagneticCount(0),
                current: AdcCode(2048 + 82),
                ..Default::default()
            },
            current_ref_a: 0.25,
            stage_cycles: [k as u16, 10, 20, 30],
            cycles: 100 + k,
            ..Default::default()
        }
    }

    #[test]
    fn stream_becomes_si_columns_relative_to_the_origin_across_the_motor_wrap() {
        let origin_raw = RawSample {
            grating2: GratingCount(1000),
            motor: MotorCount(65_000),
            ..Default::default()
        };
        let records = [
            Record::Start(StartRecord {
                version: FORMAT_VERSION,
                control_rate_hz: 2000.0,
                decimation: 10,
            }),
            Record::Origin(OriginRecord {
                tick: 5,
                raw: origin_raw,
            }),
            Record::Tick(tick(10, 1500, 65_500)),
            Record::Tick(tick(20, 2000, 464)), // 1000 counts past the origin, wrapped
        ];
        let mut text = String::from("INFO  firmware up\n");
        for r in &records {
            text.push_str(&line(r));
            text.push_str("\n└─ firmware @ src/bin/firmware.rs:10\n");
        }
        let parsed = parse_stream(text.as_bytes(), "run.txt").unwrap();
        assert_eq!(parsed, records);
        let log = to_log(&parsed, &Config::default(), &LogOptions::default()).unwrap();
        assert_eq!(log.len(), 2);
        assert_eq!(log.col("t_s").unwrap(), [0.005, 0.01]);
        let x2 = log.col("x2_m").unwrap();
        assert!((x2[0] - 0.5e-3).abs() < 1e-9 && (x2[1] - 1.0e-3).abs() < 1e-9);
        let phi = log.col("phi_rad").unwrap();
        let rev = 2.0 * std::f64::consts::PI;
        assert!((phi[0] - 500.0 / 4000.0 * rev).abs() < 1e-5, "{}", phi[0]);
        assert!((phi[1] - 1000.0 / 4000.0 * rev).abs() < 1e-5, "{}", phi[1]);
        let i = log.col("i_meas_a").unwrap();
        assert!((i[0] - 82.0 * 5.0 / 4096.0).abs() < 1e-6);
        assert_eq!(log.col("i_ref_a").unwrap(), [0.25, 0.25]);
        assert!(!log.has("theta_rad"));
        let stats = cycle_stats(&[tick(1, 0, 0), tick(2, 0, 0), tick(9, 0, 0)]).unwrap();
        assert_eq!(
            stats.stages[0],
            Spread {
                min: 1,
                median: 2,
                max: 9
            }
        );
        assert_eq!(
            stats.step,
            Spread {
                min: 61,
                median: 62,
                max: 69
            }
        );
    }

    #[test]
    fn bad_streams_are_errors_naming_the_line() {
        let err = parse_stream("INFO hello\ntlm [3, 1]\n".as_bytes(), "run.txt").unwrap_err();
        assert!(err.to_string().starts_with("run.txt:2:"), "{err}");
        let mut nan = tick(10, 0, 0);
        nan.f_ext_lo_n = f32::NAN;
        let text = format!("INFO hello\n{}\n", line(&Record::Tick(nan)));
        let err = parse_stream(text.as_bytes(), "run.txt").unwrap_err();
        assert!(
            err.to_string()
                .starts_with("run.txt:2: tick 10: f_ext_lo_n is NaN"),
            "{err}"
        );
        let back = [Record::Tick(tick(10, 0, 0)), Record::Tick(tick(10, 0, 0))];
        let err = to_log(&back, &Config::default(), &LogOptions::default()).unwrap_err();
        assert!(err.to_string().contains("restarted"), "{err}");
    }
}
