//! Processor in the loop: the firmware binary on QEMU closes the loop on
//! the simulated prototype (`host_sim::pil`), and every tick must equal the
//! host-only run of the same firmware logic bit for bit (instruction counts
//! and the applied mean current aside, `host_sim::pil::compare`): the same plant, noise, load and drive fault, the same requests.
//!
//! Needs QEMU and the PIL firmware (`cargo fw-pil`); `.ci/qemu.sh` runs it
//! with `CABLE_JOINT_PIL_ELF` set:
//!
//! ```text
//! cargo fw-pil
//! CABLE_JOINT_PIL_ELF=target/thumbv7em-none-eabihf/release/firmware \
//!     cargo test --test pil -- --include-ignored
//! ```

use std::path::PathBuf;
use std::time::Duration;

use cable_joint::board::{Phase, Program, Request};
use cable_joint::controller::{Command, Mode};
use cable_joint::trajectory::Trajectory;
use cable_joint::Fault;
use host_sim::pil::{compare_with, Comparison, PilOptions};
use host_sim::plant::PlantParams;
use host_sim::trace::{Inject, TraceOptions};

fn pil_options(name: &str) -> PilOptions {
    let elf = std::env::var_os("CABLE_JOINT_PIL_ELF")
        .map(PathBuf::from)
        .expect("set CABLE_JOINT_PIL_ELF to the PIL firmware (cargo fw-pil)");
    PilOptions {
        tick_timeout: Duration::from_secs(30),
        ..PilOptions::new(elf, PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name))
    }
}

/// The seed's loading protocol, shortened: home, 30° in one second, hold,
/// hang 50 g once the joint is still, then the drive's fault line.
fn loading() -> TraceOptions {
    TraceOptions {
        duration_s: 4.0,
        load_at_s: 3.0,
        drive_fault_at_s: 3.9,
        ..TraceOptions::default()
    }
}

/// An operator who, once the hold has begun, moves the set point to 20°
/// over the link and raises the telemetry rate.
struct Operator;

const RETARGET_TICK: usize = 5400;

impl Inject for Operator {
    fn request(&mut self, tick: usize) -> Option<Request> {
        match tick {
            0 => Some(Request::Program(Program::default())),
            RETARGET_TICK => Some(Request::SetCommand(Command {
                mode: Mode::JointClosedLoop,
                trajectory: Trajectory::PointToPoint {
                    from_rad: 30f32.to_radians(),
                    to_rad: 20f32.to_radians(),
                    duration_s: 0.2,
                },
            })),
            5401 => Some(Request::SetDecimation(5)),
            _ => None,
        }
    }
}

fn check_identical(cmp: &Comparison) {
    let n = cmp.pil.outcomes.len();
    assert_eq!(cmp.host.outcomes.len(), n);
    assert_eq!(
        (cmp.identical_ticks, cmp.first_difference),
        (n, None),
        "PIL and host runs differ:\n{cmp}"
    );
    // Bit for bit, NaN (no loaded tick) included.
    let bits = |e: &host_sim::pil::RunErrors| {
        (
            e.tracking_rms_rad.to_bits(),
            e.tracking_max_rad.to_bits(),
            e.force_mean_abs_n.to_bits(),
            e.ticks,
        )
    };
    assert_eq!(bits(&cmp.errors[0]), bits(&cmp.errors[1]));
    let stats = cmp.instructions.expect("the controller stepped");
    assert!(stats.tick.median > stats.step.median && stats.step.median > 0);
}

#[test]
#[ignore = "needs QEMU and the PIL firmware: .ci/qemu.sh"]
fn pil_closed_loop_tracks_holds_and_faults_as_the_host_run_bit_for_bit() {
    let opts = loading();
    let cmp = compare_with(
        PlantParams::default(),
        &opts,
        &pil_options("pil-loading"),
        &|| Box::new(host_sim::trace::NoInjection),
        &mut |_, _, _| Ok(()),
    )
    .unwrap();
    check_identical(&cmp);
    let run = &cmp.pil;
    let period = 1.0 / f64::from(run.control_rate_hz);
    // The real binary closed the loop: homed, moved to 30° and held it
    // while the weight hung (true angle within 0.5°).
    let homed = run
        .outcomes
        .iter()
        .position(|o| o.record.phase == Phase::Running.code())
        .expect("homed");
    assert!(homed > 0 && run.outcomes[homed].origin.is_some());
    let held = ((opts.load_at_s + 0.5) / period) as usize;
    assert!(
        (run.theta_true_rad[held].to_degrees() - 30.0).abs() < 0.5,
        "held at {:.2}°",
        run.theta_true_rad[held].to_degrees()
    );
    // The force estimate's accuracy at rest is issue 9's (the DOB's error
    // while held is in the comparison's table, the same in both runs).
    // The fault line cut the drive within the tick and latched the fault.
    let fault_tick = (opts.drive_fault_at_s / period).ceil() as usize;
    for o in &run.outcomes[fault_tick..] {
        assert!(!o.drive_enabled && !o.record.drive_enable);
        assert_eq!(o.record.fault, Fault::DriveFault.code());
    }
}

/// The operator's run over `pil`'s link port, checked bit for bit against
/// the host run, and the new set point reached.
fn operator_run(pil: &PilOptions) {
    let opts = TraceOptions {
        duration_s: 3.0,
        drive_fault_at_s: -1.0,
        ..loading()
    };
    let cmp = compare_with(
        PlantParams::default(),
        &opts,
        pil,
        &|| Box::new(Operator),
        &mut |_, _, _| Ok(()),
    )
    .unwrap();
    check_identical(&cmp);
    // The new set point reached the controller: half way 0.1 s later.
    let r = cmp.pil.outcomes[RETARGET_TICK + 200].record;
    assert!(
        (r.theta_ref_rad.to_degrees() - 25.0).abs() < 1.0,
        "theta_ref {}°",
        r.theta_ref_rad.to_degrees()
    );
    let end = cmp.pil.outcomes.last().unwrap().record;
    assert!((end.theta_ref_rad.to_degrees() - 20.0).abs() < 1e-3);
}

/// The line also loses the acknowledgement of the new set point: the host
/// sends the frame again, and the firmware acknowledges the resend without
/// queuing the command twice (applied twice, the trajectory would restart
/// a tick later and the decimation act a tick late: not bit for bit).
#[test]
#[ignore = "needs QEMU and the PIL firmware: .ci/qemu.sh"]
fn pil_requests_over_the_link_act_at_the_same_tick_as_on_the_host() {
    operator_run(&PilOptions {
        lost_acks: vec![0],
        ..pil_options("pil-operator")
    });
}

/// The same requests over the link's other port, RTT channel 1, which the
/// firmware's idle loop polls (QEMU's GDB stub standing in for the probe),
/// an acknowledgement lost there too: the same ticks, bit for bit.
#[test]
#[ignore = "needs QEMU and the PIL firmware: .ci/qemu.sh"]
fn pil_requests_over_rtt_act_at_the_same_tick_as_on_the_host() {
    operator_run(&PilOptions {
        rtt: true,
        lost_acks: vec![0],
        ..pil_options("pil-operator-rtt")
    });
}

/// An operator who, once the joint holds 30°, asks for a 1 N grip on the
/// motor's angle.
struct Gripper;

const GRIP_TICK: usize = 5400;
const GRIP_N: f32 = 1.0;

impl Inject for Gripper {
    fn request(&mut self, tick: usize) -> Option<Request> {
        match tick {
            0 => Some(Request::Program(Program::default())),
            GRIP_TICK => Some(Request::SetCommand(Command {
                mode: Mode::MotorPosition,
                trajectory: Trajectory::Grip {
                    force_n: GRIP_N,
                    approach_rad_s: 0.1,
                },
            })),
            _ => None,
        }
    }
}

/// The grip law in the binary: a soft object 2° beyond the held 30°, a
/// grip command over the link; the binary closes onto the object and
/// regulates its fused estimate as the host run does, bit for bit.
#[test]
#[ignore = "needs QEMU and the PIL firmware: .ci/qemu.sh"]
fn pil_grips_an_object_as_the_host_run_bit_for_bit() {
    let opts = TraceOptions {
        duration_s: 8.0,
        drive_fault_at_s: -1.0,
        load_n: 0.0,
        object: Some(host_sim::plant::TipObject::new(32.0, 1000.0).unwrap()),
        ..loading()
    };
    let cmp = compare_with(
        PlantParams::default(),
        &opts,
        &pil_options("pil-grip"),
        &|| Box::new(Gripper),
        &mut |_, _, _| Ok(()),
    )
    .unwrap();
    check_identical(&cmp);
    let run = &cmp.pil;
    let last_s = (run.control_rate_hz * 0.5) as usize;
    let tail = &run.outcomes[run.outcomes.len() - last_s..];
    assert!(tail.iter().all(|o| o.record.fault == 0 && o.drive_enabled));
    let mean = |f: &dyn Fn(usize) -> f64| {
        (run.outcomes.len() - last_s..run.outcomes.len())
            .map(f)
            .sum::<f64>()
            / last_s as f64
    };
    let est_n = mean(&|k| f64::from(run.outcomes[k].record.f_ext_fused_n));
    let true_n = mean(&|k| run.f_ext_true_n[k]);
    let trace: Vec<String> = (0..16)
        .map(|k| {
            let o = &run.outcomes[k * run.outcomes.len() / 16];
            format!(
                "{:.2} s: est {:.3} N, true {:.3} N",
                o.record.tick as f32 / run.control_rate_hz,
                o.record.f_ext_fused_n,
                run.f_ext_true_n[k * run.outcomes.len() / 16]
            )
        })
        .collect();
    eprintln!("PIL grip, last 0.5 s: estimate {est_n:.3} N, true {true_n:.3} N; {trace:#?}");
    assert!(
        (est_n - f64::from(GRIP_N)).abs() < 0.1,
        "the binary's grip holds its estimate at {est_n:.3} N: {trace:#?}"
    );
    assert!(true_n > 0.5, "the object pushes back with {true_n:.3} N");
}
