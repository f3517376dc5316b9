//! The firmware's sensor trace replayed through the core on the host, and
//! compared tick by tick, bit for bit, with what the firmware computed from
//! the same trace under QEMU.
//!
//! * `committed_trace_replays_through_the_firmware_sequence` (always runs):
//!   the trace embedded by `cargo fw-qemu` (`firmware/trace.bin`) drives the
//!   firmware's sequence (`board::Harness`: fault inputs, start-up, control
//!   tick) to homing, motion and the final drive fault.
//! * `qemu_firmware_matches_host_replay_bit_for_bit` (ignored by default;
//!   `.ci/qemu.sh` runs it): reads the decoded defmt output of the QEMU run
//!   (`CABLE_JOINT_QEMU_LOG`) and the trace the firmware embedded
//!   (`CABLE_JOINT_TRACE`, default `firmware/trace.bin`), replays the trace
//!   with the same `Config`, program and decimation, and requires every
//!   record to be identical: raw counts, inputs, DAC code, mode, fault,
//!   phase, drive line, and the current reference, joint-angle reference,
//!   `theta_hat` and `F_ext_hat` compared as `f32::to_bits`. Only the cycle
//!   counts (a property of the machine, not of the math) are not compared.
//! * `qemu_watchdog_reset_latches_fault_32_with_the_drive_off_at_the_next_boot`
//!   (ignored likewise): the same for the boot after the watchdog reset the
//!   QEMU run injects (`CABLE_JOINT_QEMU_RESET_LOG`), against a replay with
//!   fault 32 latched at start-up.

use std::path::PathBuf;

use cable_joint::board::{firmware_config, ControlLoop, Harness, Phase, Program, Request, Trace};
use cable_joint::telemetry::{parse_line, Record, TickRecord};
use cable_joint::{Fault, Mode};

/// Replay `trace` exactly as the QEMU firmware runs it (decimation 1, the
/// program requested before the first tick) and return its telemetry stream:
/// the first `limit` samples, with `boot_fault` latched at start-up as a
/// recovery boot does.
fn replay(trace: &Trace, boot_fault: Option<Fault>, limit: usize) -> Vec<Record> {
    // The configuration the trace was recorded with (probing on if its
    // header says so), as the QEMU board boots with.
    let mut control = ControlLoop::new(trace.config(), 1).expect("built-in configuration");
    if let Some(fault) = boot_fault {
        control.report_boot_fault(fault);
    }
    let mut records = vec![Record::Start(control.start_record())];
    let mut harness = Harness::new(control);
    for (k, sample) in trace.iter().take(limit).enumerate() {
        let request = (k == 0).then_some(Request::Program(Program::default()));
        let out = harness.tick(&sample, request);
        if let Some(origin) = out.origin {
            records.push(Record::Origin(origin));
        }
        if out.telemetry_due {
            records.push(Record::Tick(out.record));
        }
    }
    records
}

fn ticks(records: &[Record]) -> Vec<TickRecord> {
    records
        .iter()
        .filter_map(|r| match r {
            Record::Tick(t) => Some(*t),
            _ => None,
        })
        .collect()
}

#[test]
fn committed_trace_replays_through_the_firmware_sequence() {
    let bytes = include_bytes!("../firmware/trace.bin");
    let trace = Trace::parse(bytes).expect("firmware/trace.bin is a trace");
    assert_eq!(
        trace.control_rate_hz(),
        firmware_config().control_rate_hz,
        "the trace must be recorded at the firmware's control rate"
    );
    let records = replay(&trace, None, usize::MAX);
    let ticks = ticks(&records);
    assert_eq!(ticks.len(), trace.len());
    // The drive stays off through the sensor check.
    let check = (Program::default().homing.check_s * trace.control_rate_hz()) as usize;
    assert!(ticks[..check]
        .iter()
        .all(|t| !t.drive_enable && t.phase == Phase::Check.code()));
    // Homing ends on the first rising edge of the replayed origin switch, and
    // the counters are zeroed on that sample.
    let homed = ticks
        .iter()
        .position(|t| t.phase == Phase::Running.code())
        .expect(
            "the replay homes; if the core's behaviour changed, record the trace again: \
             cargo run -p host-sim -- trace --out firmware/trace.bin",
        );
    let edge = trace
        .iter()
        .enumerate()
        .skip(check)
        .position(|(_, s)| s.inputs.origin())
        .map(|i| i + check)
        .expect("the trace has an origin edge");
    assert_eq!(homed, edge, "homed on the edge's tick");
    let origin = records
        .iter()
        .rev()
        .find_map(|r| match r {
            Record::Origin(o) => Some(*o),
            _ => None,
        })
        .expect("an origin record");
    assert_eq!(origin.tick as usize, homed);
    assert_eq!(origin.raw, ticks[homed].raw);
    // The program moves the joint: the reference rises toward 30 degrees and
    // the drive is on while no fault is latched.
    let running = &ticks[homed..];
    assert!(running.iter().any(|t| t.theta_ref_rad > 0.2));
    assert!(running
        .iter()
        .all(|t| t.drive_enable == (t.fault == 0 && t.mode == Mode::JointClosedLoop.code())));
    // The drive fault at the end of the trace is latched with the drive off.
    let last = ticks.last().expect("ticks");
    assert!(last.inputs.drive_fault());
    assert_ne!(last.fault, 0);
    assert!(!last.drive_enable && last.current_ref_a == 0.0);
    let first_fault = ticks.iter().find(|t| t.fault != 0).expect("a fault");
    if first_fault.inputs.drive_fault() {
        assert_eq!(first_fault.fault, Fault::DriveFault.code());
    }
}

/// Field-by-field comparison; `f32`s by their bits.
fn differences(fw: &TickRecord, host: &TickRecord) -> Vec<String> {
    let mut d = Vec::new();
    let mut f = |name: &str, a: f32, b: f32| {
        if a.to_bits() != b.to_bits() {
            d.push(format!(
                "{name}: firmware {a:e} host {b:e} (diff {:e})",
                a - b
            ));
        }
    };
    f("current_ref_a", fw.current_ref_a, host.current_ref_a);
    f(
        "current_applied_a",
        fw.current_applied_a,
        host.current_applied_a,
    );
    f("theta_ref_rad", fw.theta_ref_rad, host.theta_ref_rad);
    f("theta_hat_rad", fw.theta_hat_rad, host.theta_hat_rad);
    f("f_ext_hat_n", fw.f_ext_hat_n, host.f_ext_hat_n);
    f("f_ext_fused_n", fw.f_ext_fused_n, host.f_ext_fused_n);
    f("f_ext_lo_n", fw.f_ext_lo_n, host.f_ext_lo_n);
    f("f_ext_hi_n", fw.f_ext_hi_n, host.f_ext_hi_n);
    let ints = [
        ("tick", fw.tick as i64, host.tick as i64),
        ("dac", fw.dac.0 as i64, host.dac.0 as i64),
        ("mode", fw.mode as i64, host.mode as i64),
        ("fault", fw.fault as i64, host.fault as i64),
        ("phase", fw.phase as i64, host.phase as i64),
        (
            "drive_enable",
            fw.drive_enable as i64,
            host.drive_enable as i64,
        ),
        ("inputs", fw.inputs.0 as i64, host.inputs.0 as i64),
    ];
    for (name, a, b) in ints {
        if a != b {
            d.push(format!("{name}: firmware {a} host {b}"));
        }
    }
    if fw.raw != host.raw {
        d.push(format!("raw: firmware {:?} host {:?}", fw.raw, host.raw));
    }
    d
}

/// The telemetry records in a decoded defmt log named by `var`.
fn firmware_records(var: &str) -> (PathBuf, String, Vec<Record>) {
    let log = PathBuf::from(
        std::env::var_os(var)
            .unwrap_or_else(|| panic!("set {var} to the decoded defmt output of the QEMU run")),
    );
    let text =
        std::fs::read_to_string(&log).unwrap_or_else(|e| panic!("reading {}: {e}", log.display()));
    let mut records = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if let Some(rec) = parse_line(line) {
            records.push(rec.unwrap_or_else(|e| panic!("{}:{}: {e}", log.display(), i + 1)));
        }
    }
    (log, text, records)
}

/// The trace the QEMU firmware embedded (`CABLE_JOINT_TRACE`, default
/// `firmware/trace.bin`).
fn embedded_trace() -> Vec<u8> {
    let path = std::env::var_os("CABLE_JOINT_TRACE")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("firmware/trace.bin"));
    std::fs::read(&path).unwrap_or_else(|e| panic!("reading {}: {e}", path.display()))
}

/// Start and origin records equal, and every tick record equal bit for bit.
fn assert_identical(firmware: &[Record], host: &[Record]) {
    assert_eq!(firmware.first(), host.first(), "start records differ");
    let origins = |r: &[Record]| -> Vec<Record> {
        r.iter()
            .filter(|r| matches!(r, Record::Origin(_)))
            .copied()
            .collect()
    };
    assert_eq!(origins(firmware), origins(host), "origin records differ");
    let (fw, ho) = (ticks(firmware), ticks(host));
    assert_eq!(
        fw.len(),
        ho.len(),
        "the firmware logged {} ticks, the replay has {}",
        fw.len(),
        ho.len()
    );
    let mut report = Vec::new();
    let mut mismatched = 0;
    for (a, b) in fw.iter().zip(&ho) {
        let d = differences(a, b);
        if !d.is_empty() {
            mismatched += 1;
            if report.len() < 10 {
                report.push(format!("tick {}: {}", b.tick, d.join("; ")));
            }
        }
    }
    assert!(
        mismatched == 0,
        "{mismatched} of {} ticks differ; first:\n{}",
        fw.len(),
        report.join("\n")
    );
}

#[test]
#[ignore = "needs the QEMU firmware's decoded output: run .ci/qemu.sh"]
fn qemu_firmware_matches_host_replay_bit_for_bit() {
    let (log, text, firmware) = firmware_records("CABLE_JOINT_QEMU_LOG");
    assert!(
        text.contains("trace played"),
        "{}: the firmware did not report the end of the trace",
        log.display()
    );
    let bytes = embedded_trace();
    let trace = Trace::parse(&bytes).expect("trace");
    let host = replay(&trace, None, usize::MAX);
    assert_identical(&firmware, &host);
    // The run covers what it should: homing, motion, a latched fault.
    let fw = ticks(&firmware);
    assert!(fw.iter().any(|t| t.phase == Phase::Running.code()));
    assert!(fw.iter().any(|t| t.fault != 0));
}

/// The boot after the injected watchdog reset (`.ci/qemu.sh` splits it off
/// as `qemu-reset.txt`): fault 32 latched from the first record on, the
/// drive never enabled, the program refused, and every record identical
/// to the host's replay of the same samples with the same boot fault.
#[test]
#[ignore = "needs the QEMU firmware's decoded output: run .ci/qemu.sh"]
fn qemu_watchdog_reset_latches_fault_32_with_the_drive_off_at_the_next_boot() {
    let (log, text, firmware) = firmware_records("CABLE_JOINT_QEMU_RESET_LOG");
    assert!(
        text.contains("recovery boot done"),
        "{}: the recovery boot did not finish",
        log.display()
    );
    let fw = ticks(&firmware);
    assert!(!fw.is_empty(), "{}: no tick records", log.display());
    for t in &fw {
        assert_eq!(t.fault, Fault::Watchdog.code(), "tick {}", t.tick);
        assert!(!t.drive_enable && t.current_ref_a == 0.0, "tick {}", t.tick);
        assert_ne!(t.phase, Phase::Running.code(), "tick {}", t.tick);
    }
    let bytes = embedded_trace();
    let trace = Trace::parse(&bytes).expect("trace");
    let host = replay(&trace, Some(Fault::Watchdog), fw.len());
    assert_identical(&firmware, &host);
}
