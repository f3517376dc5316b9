//! Sensors of the simulated prototype: counter quantization and wrap, the
//! current monitor's ADC with noise and offset, and the controller reading
//! them back.

use cable_joint::trajectory::Trajectory;
use cable_joint::{Command, Config, Mode};
use host_sim::plant::{Plant, PlantParams};
use host_sim::sim::{Sim, TickRecord};

/// Known positions give the counts of the sensors' resolutions, rounded, with
/// the 16-bit timers wrapping.
#[test]
fn counters_quantize_and_wrap() {
    let mut p = PlantParams::default();
    p.drive.monitor_noise_a = 0.0;
    p.drive.monitor_offset_a = 0.0;
    p.sensors.grating_initial_counts = [10, i32::MAX - 5];
    p.sensors.motor_initial_count = 65_000;
    p.sensors.magnetic_initial_count = 100;
    let mut plant = Plant::new(p, 1).unwrap();
    {
        let s = plant.state_mut();
        s.x1_m = 1.23449e-3; // 1234.49 counts
        s.x2_m = 10.4e-6; // 10.4 counts, beyond i32::MAX from the initial count
        s.phi_rad = (20.0 + 0.25) * std::f64::consts::TAU; // 81 000 counts
        s.theta_rad = -0.5; // -325.95 counts of 4096/rev
        s.current_a = 1.0;
    }
    let raw = plant.sample();
    assert_eq!(raw.grating1.0, 10 + 1234);
    assert_eq!(
        raw.grating2.0,
        (i32::MAX - 5).wrapping_add(10),
        "32-bit wrap"
    );
    assert_eq!(
        raw.motor.0,
        ((65_000 + 81_000) % 65_536) as u16,
        "16-bit wrap"
    );
    assert_eq!(raw.magnetic.0, (100i32 - 326).rem_euclid(65_536) as u16);
    // 1 A at 5/4096 A per code around 2048: 819.2 codes.
    assert_eq!(raw.current.0, 2048 + 819);

    // Without the magnetic encoder its timer stays at the initial count.
    p.sensors.magnetic_fitted = false;
    let mut plant = Plant::new(p, 1).unwrap();
    plant.state_mut().theta_rad = 0.3;
    assert_eq!(plant.sample().magnetic.0, 100);
}

/// The ADC code's mean is the current plus the monitor's offset, its spread
/// the monitor's noise (plus a uniform quantization error).
#[test]
fn current_monitor_noise_and_offset() {
    let p = PlantParams::default();
    let mut plant = Plant::new(p, 7).unwrap();
    let lsb = p.sensors.scales.adc_a_per_code as f64;
    let n = 20_000;
    let codes: Vec<f64> = (0..n).map(|_| plant.sample().current.0 as f64).collect();
    let mean = codes.iter().sum::<f64>() / n as f64;
    let var = codes.iter().map(|c| (c - mean).powi(2)).sum::<f64>() / n as f64;
    let want_mean = 2048.0 + (plant.holding_current_a() + p.drive.monitor_offset_a) / lsb;
    let want_sd = ((p.drive.monitor_noise_a / lsb).powi(2) + 1.0 / 12.0).sqrt();
    assert!(
        (mean - want_mean).abs() < 0.05,
        "mean code {mean} vs {want_mean}"
    );
    assert!(
        (var.sqrt() / want_sd - 1.0).abs() < 0.05,
        "code sd {} vs {want_sd}",
        var.sqrt()
    );
}

/// Over many motor revolutions (many 16-bit wraps) the controller's motor
/// angle stays within half a count of the truth: the raw samples carry the
/// quantized truth through the wraps. (The gratings' counts and their wrap
/// are `counters_quantize_and_wrap`'s; with the motor decoupled here the
/// sliders do not move.)
#[test]
fn controller_reads_the_quantized_truth() {
    let p = PlantParams {
        motor_decoupled: true,
        ..PlantParams::default()
    };
    let mut sim = Sim::new(p, Config::default(), 3).unwrap();
    // Joint-equivalent 1 rad sine at 2 Hz: 23 motor rad amplitude.
    sim.set_command(Command {
        mode: Mode::MotorPosition,
        trajectory: Trajectory::Sine {
            offset_rad: 0.0,
            amplitude_rad: 1.0,
            freq_hz: 2.0,
        },
    });
    let mut recs: Vec<TickRecord> = Vec::new();
    sim.run_for(1.0, &mut recs);
    let count = std::f64::consts::TAU / p.sensors.scales.motor_counts_per_rev as f64;
    let travel = recs
        .iter()
        .map(|r| r.state.phi_rad.abs())
        .fold(0.0, f64::max);
    assert!(
        travel > 20.0,
        "motor travelled only {travel} rad (3+ wraps needed)"
    );
    for r in &recs {
        let err = r.output.est.phi_rad as f64 - r.state.phi_rad;
        // f32 resolution of ~20 rad is 2e-6 rad, far below a count.
        assert!(
            err.abs() <= 0.5 * count + 1e-5,
            "t={}: phi read {} vs true {}",
            r.t_s,
            r.output.est.phi_rad,
            r.state.phi_rad
        );
        assert_eq!(r.output.fault, None);
    }
}
