//! Every fault class, injected into the closed loop of the firmware's logic
//! (`board::Harness`, the tick the firmware runs) on the simulated
//! prototype: the drive is off in the tick the fault is reported, with the
//! right code, and stays off.
//!
//! The loop is `host-sim`'s trace recorder (`trace::record_with`): boot with
//! the drive off, sensor check, homing on the origin switch, the built-in
//! program (joint to 30° in 1 s, then hold), with one fault injected at
//! `INJECT_S` (after homing, during the hold) unless the scenario says
//! otherwise.

use cable_joint::board::{firmware_config, Harness, Program, Request, TraceSample};
use cable_joint::fault::Sensor;
use cable_joint::telemetry::Inputs;
use cable_joint::units::{AdcCode, GratingCount, MagneticCount, MotorCount};
use cable_joint::{Config, Fault};
use host_sim::plant::PlantParams;
use host_sim::trace::{record_with, Inject, NoInjection, Recorded, TraceOptions};

const RATE_HZ: f64 = 2000.0;
/// Homing ends near 1.75 s and the move to 30° one second later.
const INJECT_S: f64 = 3.0;
const INJECT_TICK: usize = (INJECT_S * RATE_HZ) as usize;

fn options(duration_s: f64) -> TraceOptions {
    TraceOptions {
        duration_s,
        load_n: 0.0,
        drive_fault_at_s: -1.0,
        ..TraceOptions::default()
    }
}

fn run(config: Config, duration_s: f64, inject: &mut dyn Inject) -> Recorded {
    record_with(PlantParams::default(), &options(duration_s), config, inject)
        .expect("the closed loop runs")
}

/// The closed loop with the firmware's configuration and a tip force of
/// `load_n` applied at `INJECT_S` (ramped in over 50 ms), nothing injected.
fn run_with_tip_force(load_n: f64) -> Recorded {
    let opts = TraceOptions {
        load_n,
        load_at_s: INJECT_S,
        ..options(3.6)
    };
    record_with(
        PlantParams::default(),
        &opts,
        firmware_config(),
        &mut NoInjection,
    )
    .expect("the closed loop runs")
}

/// The first fault: its tick and code; the drive off (and the DAC at zero
/// current) from that tick to the end.
fn first_fault(rec: &Recorded) -> (usize, Fault) {
    let zero = firmware_config().scales.dac_code(0.0);
    let k = rec
        .outcomes
        .iter()
        .position(|o| o.record.fault != 0)
        .expect("a fault must be reported");
    let fault = Fault::from_code(rec.outcomes[k].record.fault).expect("a known code");
    for (j, o) in rec.outcomes[k..].iter().enumerate() {
        assert!(
            !o.record.drive_enable,
            "{fault:?}: drive on at tick {} after the fault at {k}",
            k + j
        );
        assert_eq!(o.record.dac, zero, "{fault:?}: current at tick {}", k + j);
        assert_eq!(o.record.current_ref_a, 0.0);
    }
    (k, fault)
}

/// The fault `expected`, reported no earlier than the injection and within
/// `latency_ticks` of it, with the drive on just before the injection.
fn assert_caught(rec: &Recorded, expected: Fault, at: usize, latency_ticks: usize) {
    assert!(
        rec.outcomes[at - 1].record.drive_enable,
        "{expected:?}: the joint was not running before the injection"
    );
    let (k, fault) = first_fault(rec);
    assert_eq!(fault, expected, "first fault at tick {k}");
    assert!(
        k >= at && k <= at + latency_ticks,
        "{expected:?} at tick {k}, injected at {at}, allowed {latency_ticks}"
    );
}

/// A change of the samples from `at` on.
struct SampleFault<F: FnMut(usize, &mut TraceSample)> {
    at: usize,
    f: F,
}

impl<F: FnMut(usize, &mut TraceSample)> Inject for SampleFault<F> {
    fn sample(&mut self, tick: usize, _t_s: f64, s: &mut TraceSample) {
        if tick >= self.at {
            (self.f)(tick - self.at, s);
        }
    }
}

fn sample_fault(
    f: impl FnMut(usize, &mut TraceSample),
) -> SampleFault<impl FnMut(usize, &mut TraceSample)> {
    SampleFault { at: INJECT_TICK, f }
}

#[test]
fn encoder_jumps_on_every_counter_cut_the_drive_in_the_tick() {
    type Glitch = fn(&mut TraceSample);
    let cases: [(Fault, Glitch); 4] = [
        (Fault::EncoderJump(Sensor::Grating1), |s| {
            s.raw.grating1 = GratingCount(s.raw.grating1.0.wrapping_add(5000))
        }),
        (Fault::EncoderJump(Sensor::Grating2), |s| {
            s.raw.grating2 = GratingCount(s.raw.grating2.0.wrapping_sub(5000))
        }),
        (Fault::EncoderJump(Sensor::Motor), |s| {
            s.raw.motor = MotorCount(s.raw.motor.0.wrapping_add(2000))
        }),
        (Fault::EncoderJump(Sensor::Magnetic), |s| {
            s.raw.magnetic = MagneticCount(s.raw.magnetic.0.wrapping_add(2000))
        }),
    ];
    for (fault, glitch) in cases {
        let rec = run(firmware_config(), 3.2, &mut sample_fault(|_, s| glitch(s)));
        assert_caught(&rec, fault, INJECT_TICK, 0);
    }
}

#[test]
fn adc_at_a_rail_and_over_current_cut_the_drive_in_the_tick() {
    let rec = run(
        firmware_config(),
        3.2,
        &mut sample_fault(|_, s| s.raw.current = AdcCode(4095)),
    );
    assert_caught(&rec, Fault::AdcRail, INJECT_TICK, 0);
    // 2.4 A on the monitor (2048 + 2.4 / (5 / 4096)): above the 2.25 A
    // limit, inside the ±2.5 A range.
    let rec = run(
        firmware_config(),
        3.2,
        &mut sample_fault(|_, s| s.raw.current = AdcCode(4014)),
    );
    assert_caught(&rec, Fault::OverCurrent, INJECT_TICK, 0);
}

#[test]
fn a_joint_estimate_driven_out_of_range_is_caught() {
    // Grating 2 runs inwards 100 counts per tick (0.2 m/s, below the 250
    // count jump limit), faster than the loop can follow (its motor-speed
    // limit moves x2 by about 43 counts per tick at most): theta_hat runs from
    // +30° past -1.6 rad within about 0.1 s.
    // (Outwards, cable 1 would read slack first: theta_hat up, x1 still.)
    let rec = run(
        firmware_config(),
        3.6,
        &mut sample_fault(|n, s| {
            s.raw.grating2 = GratingCount(s.raw.grating2.0.wrapping_sub(100 * (n as i32 + 1)))
        }),
    );
    assert_caught(&rec, Fault::AngleRange, INJECT_TICK, 400);
}

#[test]
fn a_motor_counter_faster_than_the_motor_can_turn_is_overspeed() {
    // 383 counts per tick is 1203 rad/s: within the per-tick jump limit
    // (383 counts), above the 1200 rad/s speed limit.
    let rec = run(
        firmware_config(),
        3.2,
        &mut sample_fault(|n, s| {
            s.raw.motor = MotorCount(s.raw.motor.0.wrapping_add((383 * (n + 1)) as u16))
        }),
    );
    assert_caught(&rec, Fault::Overspeed, INJECT_TICK, 100);
}

#[test]
fn cable_one_unloaded_by_a_tip_force_beyond_its_preload_is_slack() {
    // A tip force against positive rotation takes `F_ext l_e / r` = 5 F_ext
    // off cable 1 (DESIGN.md's sign convention): -4.5 N takes 22 N, more
    // than the 19.5 N preload, so the transmission goes slack in the hold
    // and both cable 1's stretch and the motor's torque balance read it so.
    let rec = run_with_tip_force(-4.5);
    let (k, _) = first_fault(&rec);
    // The drive, saturated against the load, may pull cable 0 slack first.
    let t = rec.tensions_true[k];
    assert!(
        t.transmission_n() < f64::from(firmware_config().slack_limit_n()),
        "the fault at tick {k} with cable 0 at {:.2} N and cable 1 at {:.2} N is no slack",
        t.rope_n,
        t.cable1_n
    );
    assert_caught(&rec, Fault::TransmissionSlack, INJECT_TICK, 400);
}

#[test]
fn a_tip_force_the_preload_still_carries_is_no_fault() {
    // -2.5 N takes 12.5 N off cable 1: about a third of the preload is
    // left, above the 20 % limit.
    let rec = run_with_tip_force(-2.5);
    assert!(rec.outcomes.iter().all(|o| o.record.fault == 0));
}

/// The winding gets no current from `at` on (a broken lead) while the
/// monitor reads what flows: nothing.
struct BrokenLead {
    at: usize,
}

impl Inject for BrokenLead {
    fn applied_current(&mut self, tick: usize, commanded_a: f64) -> f64 {
        if tick >= self.at {
            0.0
        } else {
            commanded_a
        }
    }
}

#[test]
fn a_broken_motor_lead_is_a_current_tracking_fault() {
    let rec = run(firmware_config(), 3.6, &mut BrokenLead { at: INJECT_TICK });
    // The joint sags under the preload, the loop asks for current, none
    // flows: the 20 ms low-pass crosses 0.5 A within tens of milliseconds.
    assert_caught(&rec, Fault::CurrentTracking, INJECT_TICK, 400);
}

#[test]
fn a_winding_carrying_more_than_its_continuous_current_trips_i2t() {
    // A fast winding (tau 1 s) and the monitor reading 1.5 A from the
    // injection on, the tracking check off (it would see 1.5 A of error):
    // I²t crosses 1.2² after at most -ln(1 - 0.64) = 1.02 s (from cold;
    // sooner from the state homing and the hold left).
    let mut config = firmware_config();
    config.limits.thermal_time_constant_s = 1.0;
    config.limits.max_current_error_a = 0.0;
    let rec = run(
        config,
        4.6,
        &mut sample_fault(|_, s| s.raw.current = AdcCode(2048 + 1229)),
    );
    assert_caught(&rec, Fault::I2t, INJECT_TICK, 2100);
    let (k, _) = first_fault(&rec);
    assert!(
        k >= INJECT_TICK + 400,
        "the winding takes time to heat: tick {k}"
    );
}

/// Overrun of the control task at `at`.
struct Overrun {
    at: usize,
}

impl Inject for Overrun {
    fn before_tick(&mut self, tick: usize, harness: &mut Harness) {
        if tick == self.at {
            harness.overrun();
        }
    }
}

#[test]
fn an_overrun_cuts_the_drive_at_once() {
    let rec = run(firmware_config(), 3.2, &mut Overrun { at: INJECT_TICK });
    assert_caught(&rec, Fault::Overrun, INJECT_TICK, 0);
}

/// The drive's fault line asserted from `at` on and never released; the
/// operator asks for a clear every 0.1 s.
struct StuckDriveFault {
    at: usize,
}

impl Inject for StuckDriveFault {
    fn sample(&mut self, tick: usize, _t_s: f64, s: &mut TraceSample) {
        if tick >= self.at {
            s.inputs = Inputs::new(s.inputs.origin(), true);
        }
    }
    fn request(&mut self, tick: usize) -> Option<Request> {
        match tick {
            0 => Some(Request::Program(Program::default())),
            k if k > self.at && k % 200 == 0 => Some(Request::ClearFault),
            _ => None,
        }
    }
}

#[test]
fn a_drive_fault_line_that_stays_asserted_is_never_cleared() {
    let rec = run(
        firmware_config(),
        4.0,
        &mut StuckDriveFault { at: INJECT_TICK },
    );
    assert_caught(&rec, Fault::DriveFault, INJECT_TICK, 0);
    // `first_fault` checked the drive stayed off through five clears.
    let last = rec.outcomes.last().unwrap().record;
    assert_eq!(last.fault, Fault::DriveFault.code());
}

#[test]
fn the_origin_switch_during_the_hold_is_a_fault() {
    // At 30° the switch is already made (it reads theta >= 0): a glitch
    // drops it for one tick, and it rises again away from zero.
    let rec = run(
        firmware_config(),
        3.2,
        &mut sample_fault(|n, s| s.inputs = Inputs::new(n > 0, s.inputs.drive_fault())),
    );
    assert_caught(&rec, Fault::OriginDuringMotion, INJECT_TICK + 1, 0);
}

#[test]
fn no_origin_edge_is_a_homing_fault() {
    let mut never = SampleFault {
        at: 0,
        f: |_, s: &mut TraceSample| s.inputs = Inputs::new(false, s.inputs.drive_fault()),
    };
    let rec = run(firmware_config(), 4.0, &mut never);
    let (k, fault) = first_fault(&rec);
    assert_eq!(fault, Fault::Homing);
    // The search (2.5 rad at up to 2 rad/s, minimum jerk: 2.34 s) plus 20 %.
    let limit = (0.05 + 1.2 * 1.875 * 2.5 / 2.0) * RATE_HZ;
    assert!(
        (k as f64 - limit).abs() < 10.0,
        "tick {k}, expected {limit}"
    );
}

/// A host-driven program (0.2 s timeout) whose host goes silent.
struct SilentHost;

impl Inject for SilentHost {
    fn request(&mut self, tick: usize) -> Option<Request> {
        (tick == 0).then_some(Request::Program(Program {
            command_timeout_s: 0.2,
            ..Program::default()
        }))
    }
}

#[test]
fn a_silent_host_ends_its_program_with_a_timeout() {
    let rec = run(firmware_config(), 1.0, &mut SilentHost);
    assert_caught(&rec, Fault::CommandTimeout, 390, 20);
}

/// The previous run ended in `fault` (a panic, a HardFault or the
/// watchdog): the firmware latches it at boot.
struct AfterReset {
    fault: Fault,
}

impl Inject for AfterReset {
    fn before_tick(&mut self, tick: usize, harness: &mut Harness) {
        if tick == 0 {
            harness.control.report_boot_fault(self.fault);
        }
    }
}

#[test]
fn a_panic_hardfault_or_watchdog_reset_keeps_the_drive_off_after_boot() {
    for fault in [Fault::Panic, Fault::HardFault, Fault::Watchdog] {
        let rec = run(firmware_config(), 2.0, &mut AfterReset { fault });
        let (k, f) = first_fault(&rec);
        assert_eq!((k, f), (0, fault));
        assert!(rec.outcomes.iter().all(|o| !o.record.drive_enable));
    }
}

/// Fault 11 (non-finite). The firmware's sensors are integer counts and an
/// ADC code, so a non-finite estimate comes from the configuration (an
/// effect term that overflows: `tests/step_props.rs` drives arbitrary valid
/// configurations and asserts the fault whenever an estimate is not finite)
/// or, on the host, from a replayed log whose applied current is beyond
/// `f32`, injected here: the controller latches fault 11, outputs no
/// current, and its estimators restart from the sensors, finite from the
/// next tick.
#[test]
fn a_non_finite_replayed_current_is_fault_11_and_the_estimators_restart() {
    let mut c = cable_joint::Controller::new(firmware_config()).expect("config");
    let raw = cable_joint::RawSample {
        current: AdcCode(2048),
        ..Default::default()
    };
    c.set_origin(&raw);
    for _ in 0..100 {
        let out = c.replay(&raw, 0.0);
        assert_eq!(out.fault, None);
    }
    let out = c.replay(&raw, f32::INFINITY);
    assert_eq!(out.fault, Some(Fault::NonFinite));
    assert_eq!(Fault::NonFinite.code(), 11);
    assert!(!out.drive_enable && out.current_ref_a == 0.0);
    let next = c.replay(&raw, 0.0);
    assert_eq!(next.fault, Some(Fault::NonFinite), "latched");
    let e = &next.est;
    for (name, v) in [
        ("theta_hat_rad", e.theta_hat_rad),
        ("f_ext_hat_n", e.f_ext_hat_n),
        ("f_ext_fused_n", e.f_ext_fused_n),
        ("tension1_n", e.tension1_n),
    ] {
        assert!(v.is_finite(), "{name} = {v} after the restart");
    }
}
