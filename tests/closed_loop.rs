//! Host integration tests of the core against the simulated prototype: the
//! seed's identification chain on simulated logs, then tracking with and
//! without JAE feedback, and the DOB force estimate under static loads at the
//! three held angles. Everything the controller uses is identified from logs;
//! the plant's true parameters are never read.

use cable_joint::{Config, Fault};
use host_sim::ident::{decoupled, identify_bm, identify_jae, identify_tension};
use host_sim::plant::{PlantParams, Tensions};
use host_sim::scenario::{self, Direction, ScenarioOptions, G_M_S2};
use host_sim::sim::{FnRecorder, LogRecorder, NullRecorder, TickRecord};

fn log_of(name: &str, config: &Config, scale: f64) -> host_sim::log::Log {
    let mut rec = LogRecorder::new(true);
    let opts = ScenarioOptions {
        duration_scale: scale,
        ..Default::default()
    };
    let summary = scenario::run(name, PlantParams::default(), *config, None, &opts, &mut rec)
        .unwrap_or_else(|e| panic!("scenario {name}: {e:#}"));
    assert_eq!(summary.fault, None, "{name} ended in a fault");
    rec.to_log().expect("log")
}

/// The seed's chain: B_m (no-load motor), JAE (motor loop, joint open),
/// tension model (JAE closed loop, no load).
fn identified_config() -> Config {
    let mut config = Config::default();
    let bm = identify_bm(&log_of("bm-noload", &decoupled(&config), 0.5), &config).expect("B_m");
    bm.apply(&mut config);
    let jae = identify_jae(&log_of("jae-ident", &config, 0.5), &config).expect("JAE");
    jae.apply(&mut config);
    let tension =
        identify_tension(&log_of("tension-ident", &config, 0.5), &config).expect("tension");
    tension.apply(&mut config);
    config
        .validate()
        .expect("identified configuration is valid");
    config
}

#[test]
fn jae_feedback_tracks_better_than_motor_encoder_feedback() {
    let config = identified_config();
    let opts = ScenarioOptions {
        duration_scale: 0.5,
        ..Default::default()
    };
    let run = |name| {
        scenario::run(
            name,
            PlantParams::default(),
            config,
            None,
            &opts,
            &mut NullRecorder,
        )
        .unwrap_or_else(|e| panic!("{name}: {e:#}"))
    };
    let motor = run("track-motor")
        .tracking
        .expect("motor-only tracking stats");
    let jae = run("track-jae");
    let (track, est) = (jae.tracking.expect("tracking"), jae.jae.expect("JAE stats"));
    eprintln!(
        "motor-only: mean|e| {:.3}° max {:.3}°; JAE: mean|e| {:.3}° max {:.3}°, estimate mean|e| {:.3}°",
        motor.mean_abs,
        motor.max_abs(),
        track.mean_abs,
        track.max_abs(),
        est.mean_abs
    );
    // Cable stretch makes motor-encoder feedback err by degrees (seed Fig. 10).
    assert!(
        motor.mean_abs > 1.0,
        "motor-only error implausibly small: {motor:?}"
    );
    assert!(
        track.mean_abs < motor.mean_abs / 5.0,
        "JAE feedback mean error {:.3}° not 5x below motor-only {:.3}°",
        track.mean_abs,
        motor.mean_abs
    );
    assert!(
        track.max_abs() < motor.max_abs() / 2.0,
        "JAE feedback max error {:.3}° not 2x below motor-only {:.3}°",
        track.max_abs(),
        motor.max_abs()
    );
    assert!(
        est.mean_abs < 0.3,
        "JAE estimate error {:.3}°",
        est.mean_abs
    );
}

/// One case of the seed's loading protocol on the clean plant, with the
/// plant's true tensions at the tick a fault latched.
fn loading(
    config: &Config,
    angle_deg: f64,
    mass_g: f64,
    direction: Direction,
    duration_scale: f64,
) -> (scenario::RunSummary, Option<Tensions>) {
    let opts = ScenarioOptions {
        duration_scale,
        angle_deg: Some(angle_deg),
        mass_g: Some(mass_g),
        direction: Some(direction),
        ..Default::default()
    };
    let mut at_fault = None;
    let mut rec = FnRecorder(|r: &TickRecord| {
        if at_fault.is_none() && r.output.fault.is_some() {
            at_fault = Some(r.tensions);
        }
    });
    let summary = scenario::run(
        "loading",
        PlantParams::default(),
        *config,
        None,
        &opts,
        &mut rec,
    )
    .unwrap_or_else(|e| panic!("loading {angle_deg}° {mass_g} g {direction:?}: {e:#}"));
    (summary, at_fault)
}

/// The seed's loading protocol on the clean plant with the identified
/// configuration: the DOB (printed: at standstill it is blind to slider 1's
/// friction band, seed Fig. 20-26), the stretch estimate and the fused
/// estimate with its bound. The fused estimate must stay within the pin's
/// friction seen at the tip plus 10 % of the load, never further from the
/// load than the stretch estimate by more than 0.02 N, and
/// its bound must contain the load in at least 95 % of the held samples.
#[test]
fn stretch_and_fused_force_estimates_under_static_loads_at_three_angles() {
    let config = identified_config();
    let m = &config.machine;
    // The identified pin friction, static at most 1.5 times kinetic, at the
    // tip: what no cable-side sensor sees while the pin sticks.
    let pin_tip_n = f64::from(
        config.fusion.static_over_kinetic * config.fusion.pin_coulomb_nm / m.gripper_length_m,
    );
    eprintln!("pin friction band at the tip: ±{pin_tip_n:.3} N");
    for angle_deg in [0.0, 30.0, -40.0] {
        for mass_g in [100.0, 250.0] {
            let (s, _) = loading(&config, angle_deg, mass_g, Direction::Pos, 0.6);
            let (dob_mean, dob_max) = s.force_error_n.expect("stable region present");
            let (st_mean, st_max) = s.force_stretch_error_n.expect("stable region present");
            let (fu_mean, fu_max) = s.force_fused_error_n.expect("stable region present");
            let coverage = s.force_bound_coverage.expect("stable region present");
            let load_n = mass_g * 1e-3 * G_M_S2;
            eprintln!(
                "{angle_deg:>5}° {mass_g:>5} g ({load_n:.2} N): fused mean error {fu_mean:+.3} N \
                 (max {fu_max:.3}, bound covers {:.1} %), stretch {st_mean:+.3} N (max {st_max:.3}), \
                 DOB {dob_mean:+.3} N (max {dob_max:.3})",
                100.0 * coverage
            );
            assert_eq!(s.fault, None, "{angle_deg}° {mass_g} g faulted");
            let tol = pin_tip_n + 0.1 * load_n;
            assert!(
                st_mean.abs() < tol,
                "{angle_deg}° {mass_g} g: stretch mean error {st_mean:+.3} N beyond {tol:.3} N"
            );
            assert!(
                fu_mean.abs() < tol,
                "{angle_deg}° {mass_g} g: fused mean error {fu_mean:+.3} N beyond {tol:.3} N"
            );
            assert!(
                fu_mean.abs() <= st_mean.abs() + 0.02,
                "{angle_deg}° {mass_g} g: fused {fu_mean:+.3} N worse than stretch {st_mean:+.3} N"
            );
            assert!(
                coverage >= 0.95,
                "{angle_deg}° {mass_g} g: the fused bound holds the load in only {:.1} % of the held samples",
                100.0 * coverage
            );
        }
    }
}

/// Probing on the clean plant with the identified configuration: the dither
/// makes the stuck chain slip, and the fused estimate's mean over each whole
/// dither period must come within 8 % of the load plus 0.05 N at 30° and
/// -40°, light and heavy, both directions: the passive estimate misses the
/// 0.3 N load by the pin's friction band (about 0.2 N), so a regression to
/// passive behaviour fails. The bound must still hold the load in 95 % of
/// the held samples. The heavy load at -40° pulls against cable 0 and can
/// unload it completely (the report's passive protocol faults there on four
/// of its ten variants, every time with cable 0 at 0 N): a slack fault is
/// accepted only if the plant's cable was below the slack limit at the tick
/// it latched, and at most that one case may end in it.
#[test]
fn probing_brings_the_fused_estimate_at_rest_within_eight_percent_of_the_load_plus_50_mn() {
    let mut config = identified_config();
    config.probe.enabled = true;
    let limit_n = f64::from(config.slack_limit_n());
    let mut measured = 0;
    for angle_deg in [30.0, -40.0] {
        for (mass_g, direction) in [(30.0, Direction::Pos), (250.0, Direction::Neg)] {
            let (s, at_fault) = loading(&config, angle_deg, mass_g, direction, 1.0);
            if let Some(fault) = s.fault {
                let t = at_fault.expect("a fault has a latching tick");
                let (cable0_n, cable1_n) = (t.rope_n, t.cable1_n);
                eprintln!(
                    "{angle_deg:>5}° {mass_g:>5} g {direction:?}, probing: {fault} \
                     (true tensions: cable 0 {cable0_n:.2} N, cable 1 {cable1_n:.2} N, limit {limit_n:.2} N)"
                );
                assert!(
                    matches!(fault, Fault::Cable0Slack | Fault::TransmissionSlack)
                        && t.transmission_n() < limit_n
                        && (angle_deg, mass_g) == (-40.0, 250.0),
                    "{angle_deg}° {mass_g} g {direction:?}: false fault {fault} \
                     (cable 0 {cable0_n:.2} N, cable 1 {cable1_n:.2} N, limit {limit_n:.2} N)"
                );
                continue;
            }
            measured += 1;
            let (fu_mean, fu_max) = s.force_fused_error_n.expect("stable region present");
            let coverage = s.force_bound_coverage.expect("stable region present");
            let load_n = mass_g * 1e-3 * G_M_S2;
            eprintln!(
                "{angle_deg:>5}° {mass_g:>5} g {direction:?} ({load_n:.2} N), probing: fused mean error \
                 {fu_mean:+.3} N (max {fu_max:.3}, bound covers {:.1} %)",
                100.0 * coverage
            );
            let tol = 0.08 * load_n + 0.05;
            assert!(
                fu_mean.abs() < tol,
                "{angle_deg}° {mass_g} g {direction:?}: probed mean error {fu_mean:+.3} N beyond {tol:.3} N"
            );
            assert!(
                coverage >= 0.95,
                "{angle_deg}° {mass_g} g: the probed bound holds the load in only {:.1} % of the held samples",
                100.0 * coverage
            );
        }
    }
    assert!(measured >= 3, "only {measured} of 4 cases ran to the end");
}
