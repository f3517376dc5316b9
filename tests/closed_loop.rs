//! Host integration tests of the core against the simulated prototype: the
//! seed's identification chain on simulated logs, then tracking with and
//! without JAE feedback, and the DOB force estimate under static loads at the
//! three held angles. Everything the controller uses is identified from logs;
//! the plant's true parameters are never read.

use cable_joint::Config;
use host_sim::ident::{decoupled, identify_bm, identify_jae, identify_tension};
use host_sim::plant::PlantParams;
use host_sim::scenario::{self, Direction, ScenarioOptions, G_M_S2};
use host_sim::sim::{LogRecorder, NullRecorder};

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
        motor.mean_abs_deg,
        motor.max_abs_deg(),
        track.mean_abs_deg,
        track.max_abs_deg(),
        est.mean_abs_deg
    );
    // Cable stretch makes motor-encoder feedback err by degrees (seed Fig. 10).
    assert!(
        motor.mean_abs_deg > 1.0,
        "motor-only error implausibly small: {motor:?}"
    );
    assert!(
        track.mean_abs_deg < motor.mean_abs_deg / 5.0,
        "JAE feedback mean error {:.3}° not 5x below motor-only {:.3}°",
        track.mean_abs_deg,
        motor.mean_abs_deg
    );
    assert!(
        track.max_abs_deg() < motor.max_abs_deg() / 2.0,
        "JAE feedback max error {:.3}° not 2x below motor-only {:.3}°",
        track.max_abs_deg(),
        motor.max_abs_deg()
    );
    assert!(
        est.mean_abs_deg < 0.3,
        "JAE estimate error {:.3}°",
        est.mean_abs_deg
    );
}

#[test]
fn dob_force_estimate_under_static_loads_at_three_angles() {
    let config = identified_config();
    for angle_deg in [0.0, 30.0, -40.0] {
        for mass_g in [100.0, 250.0] {
            let opts = ScenarioOptions {
                duration_scale: 0.6,
                angle_deg: Some(angle_deg),
                mass_g: Some(mass_g),
                direction: Some(Direction::Pos),
                ..Default::default()
            };
            let s = scenario::run(
                "loading",
                PlantParams::default(),
                config,
                None,
                &opts,
                &mut NullRecorder,
            )
            .unwrap_or_else(|e| panic!("loading {angle_deg}° {mass_g} g: {e:#}"));
            let (dob_mean, dob_max) = s.force_error_n.expect("stable region present");
            let (mean_err, max_err) = s.force_stretch_error_n.expect("stable region present");
            let load_n = mass_g * 1e-3 * G_M_S2;
            eprintln!(
                "{angle_deg:>5}° {mass_g:>5} g ({load_n:.2} N): stretch mean error {mean_err:+.3} N \
                 (max {max_err:.3}), DOB mean error {dob_mean:+.3} N (max {dob_max:.3})"
            );
            assert_eq!(s.fault, None);
            // The joint's own friction (inside the cables) bounds the static
            // accuracy of any cable-side estimate; 0.25 N covers the plant's
            // 4 mN·m pin friction seen at the 20 mm tip.
            assert!(
                mean_err.abs() < 0.25 + 0.1 * load_n,
                "{angle_deg}° {mass_g} g: stretch force mean error {mean_err:+.3} N at {load_n:.2} N"
            );
        }
    }
}
