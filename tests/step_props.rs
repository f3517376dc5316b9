//! Property tests of the control path: `Controller::step` driven by arbitrary
//! configurations that pass `validate()` and arbitrary raw samples, with
//! overflow checks on (the test profile), must
//!
//! * never panic;
//! * always command a finite current within the configured limit and a DAC
//!   code within the 12-bit range;
//! * have the drive off and zero current whenever a fault is latched;
//! * latch a fault (`NonFinite`) whenever an estimate is not finite.
//!
//! Case counts: `STEP_PROPS_CASES` (default 256) configurations, each
//! stepped through up to 300 samples.

use cable_joint::controller::{Command, Mode, RawSample};
use cable_joint::effects::{EffectKind, Term};
use cable_joint::trajectory::{Trajectory, HARMONICS};
use cable_joint::units::{AdcCode, GratingCount, MagneticCount, MotorCount};
use cable_joint::{Config, Controller, Fault};
use proptest::prelude::*;

fn cases() -> u32 {
    std::env::var("STEP_PROPS_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(256)
}

/// A factor of 10^u, u uniform in ±`decades`.
fn factor(decades: f32) -> impl Strategy<Value = f32> {
    (-decades..=decades).prop_map(|u| 10f32.powf(u))
}

/// Control rates the firmware and the tools use, and the extremes allowed.
fn rate() -> impl Strategy<Value = f32> {
    prop_oneof![
        Just(100.0f32),
        Just(1000.0),
        Just(2000.0),
        Just(20_000.0),
        100.0f32..=20_000.0
    ]
}

/// Configurations around the defaults: the rate derived as a user's would be
/// (`at_rate`), then gains, identified parameters, filters and limits scaled
/// by up to ±1.5 decades and the fitted signs flipped; the machine's
/// parameters, the sensor scales (encoder resolutions up to 1e6 counts), the
/// probe, and up to two effect terms of any kind with coefficients between
/// 1e-12 and 1e12. Those `validate()` rejects are discarded by the test.
fn config() -> impl Strategy<Value = Config> {
    let gains = (
        factor(1.5),
        (-1.5f32..=0.3).prop_map(|u| 10f32.powf(u)),
        factor(1.5),
        factor(1.5),
        0.0f32..1.0,
    );
    let model = (
        factor(1.5),
        factor(1.5),
        factor(1.5),
        factor(1.0),
        any::<[bool; 4]>(),
    );
    let tension = (
        factor(1.5),
        factor(1.5),
        factor(1.5),
        factor(1.0),
        factor(1.5),
    );
    let limits = (
        factor(1.0),
        factor(1.0),
        factor(1.0),
        0.0f32..0.9,
        0u16..=1023,
        factor(1.0),
        factor(1.0),
    );
    let filters = (
        factor(1.0),
        factor(1.0),
        factor(1.0),
        any::<bool>(),
        factor(1.0),
    );
    let machine = (
        factor(1.0),
        factor(1.0),
        factor(0.5),
        factor(0.5),
        factor(0.5),
        factor(0.5),
    );
    let scales = (
        factor(1.0),
        prop::sample::select(vec![64u32, 2000, 4096, 65_536, 1_000_000]),
        prop::sample::select(vec![256u32, 4096, 16_384, 1_000_000]),
        factor(0.5),
    );
    // The probe on or off, and up to two effect terms of any kind on any
    // run-time signal with a coefficient over 24 decades.
    let probe = (any::<bool>(), factor(1.0), factor(1.0));
    let term = (
        0usize..EFFECT_KINDS,
        0u8..cable_joint::model::sig::COUNT as u8,
        0u8..cable_joint::model::sig::COUNT as u8,
        factor(1.0),
        -12.0f32..=12.0,
        any::<bool>(),
    );
    let added = prop::collection::vec(term, 0..=2);
    let extra = (machine, scales, probe, added);
    (rate(), gains, model, tension, limits, filters, extra).prop_map(
        |(rate_hz, g, m, t, l, f, (mc, sc, pr, added))| {
            let mut c = Config::default();
            c.machine.torque_constant_nm_a *= mc.0;
            c.machine.rotor_inertia_kg_m2 *= mc.1;
            c.machine.gear_ratio *= mc.2;
            c.machine.rope_wheel_radius_m *= mc.3;
            c.machine.pulley_radius_m *= mc.4;
            c.machine.gripper_length_m *= mc.5;
            c.scales.grating_m_per_count *= sc.0;
            c.scales.motor_counts_per_rev = sc.1;
            c.scales.magnetic_counts_per_rev = sc.2;
            c.scales.adc_a_per_code *= sc.3;
            c.probe.enabled = pr.0;
            c.probe.amplitude_rad *= pr.1;
            c.probe.frequency_hz *= pr.2;
            for (kind, input, aux, param, log_coef, to_jae) in added {
                let term = Term {
                    kind: effect_kind(kind, param),
                    input,
                    aux,
                };
                let coef = 10f32.powf(log_coef);
                let terms = if to_jae {
                    &mut c.jae.added
                } else {
                    &mut c.tension.added
                };
                terms.push(term, coef);
            }
            c.cascade.kp_pos_1_s *= g.0;
            c.cascade.kp_vel_a_s_rad *= g.1;
            c.cascade.ki_vel_a_rad *= g.2;
            c.cascade.vel_feedforward = (c.cascade.vel_feedforward * g.3).min(2.0);
            c.cascade.kd_pos = g.4;
            let flip = |v: f32, s: bool| if s { -v } else { v };
            c.jae.c_acc_rad_s2_m = flip(c.jae.c_acc_rad_s2_m * m.0, m.4[0]);
            c.jae.c_vel_rad_s_m = flip(c.jae.c_vel_rad_s_m * m.1, m.4[1]);
            c.jae.c_sign_rad = flip(c.jae.c_sign_rad * m.2, m.4[2]);
            c.jae.c_pos_rad_m *= m.3;
            c.tension.f_sc1_n = flip(c.tension.f_sc1_n * t.0, m.4[3]);
            c.tension.f_cp2_n *= t.1;
            c.tension.k_s_n_m *= t.2;
            c.tension.f_0_n *= t.3;
            c.stretch.cable1_n_m *= t.4;
            c.limits.max_grating_speed_m_s *= l.0;
            c.limits.max_motor_speed_rad_s *= l.1;
            c.limits.max_joint_angle_rad *= l.2;
            c.limits.min_tension_fraction = l.3;
            c.scales.adc_rail_margin_codes = l.4;
            c.limits.continuous_current_a *= l.5;
            c.limits.max_current_error_a *= l.6;
            c.differentiators.grating_bandwidth_hz *= f.0;
            c.differentiators.motor_bandwidth_hz *= f.1;
            c.dob.cutoff_rad_s *= f.2;
            c.dob.use_measured_current = f.3;
            c.fusion.creep_distance_m *= f.4;
            // What a user's tool does at another rate: derive what the rate
            // cannot support (bandwidths, the position gain).
            let (mut c, _) = c.at_rate(rate_hz);
            c.cascade.vel_limit_rad_s = c
                .cascade
                .vel_limit_rad_s
                .min(c.limits.max_motor_speed_rad_s);
            c
        },
    )
}

/// Number of effect kinds [`effect_kind`] draws from.
const EFFECT_KINDS: usize = 21;

/// Every effect kind, its parameter set from `p` (a positive factor).
fn effect_kind(k: usize, p: f32) -> EffectKind {
    match k {
        0 => EffectKind::Constant,
        1 => EffectKind::Linear,
        2 => EffectKind::Time {
            scale_s: 3600.0 * p,
        },
        3 => EffectKind::Warmup { tau_s: p },
        4 => EffectKind::SmoothSign { v_eps: 1e-3 * p },
        5 => EffectKind::Stribeck {
            v_s: 1e-2 * p,
            v_eps: 1e-3 * p,
        },
        6 => EffectKind::Play {
            half_width: 1e-4 * p,
        },
        7 => EffectKind::Stop {
            half_width: 1e-4 * p,
        },
        8 => EffectKind::Dahl { length: 1e-4 * p },
        9 => EffectKind::LoadDahl { length: 1e-4 * p },
        10 => EffectKind::LoadCoulomb { v_eps: 1e-3 * p },
        11 => EffectKind::DeadZone {
            center: 0.0,
            half_width: 1e-4 * p,
        },
        12 => EffectKind::Product,
        13 => EffectKind::Relaxation { tau_s: p },
        14 => EffectKind::Creep { tau_s: p },
        15 => EffectKind::Thermal { tau_s: 10.0 * p },
        16 => EffectKind::SignedSquare,
        17 => EffectKind::Cube,
        18 => EffectKind::Time { scale_s: p },
        20 => EffectKind::BoucWen {
            length: 1e-4 * p,
            shape: 0.5,
            exponent: 3,
        },
        _ => EffectKind::Creep { tau_s: 1e-3 * p },
    }
}

/// A raw sample: counters near the last ones (a random walk) or anywhere
/// (a glitch, a wrap, a jump), the ADC anywhere in its 16-bit register.
fn samples() -> impl Strategy<Value = Vec<RawSample>> {
    let step = prop_oneof![
        8 => (-20i32..=20, -20i32..=20, -40i32..=40, -4i32..=4, 1500u16..=2600)
            .prop_map(|(g1, g2, m, mag, adc)| (false, g1, g2, m, mag, adc)),
        1 => (any::<i32>(), any::<i32>(), any::<i32>(), any::<i32>(), any::<u16>())
            .prop_map(|(g1, g2, m, mag, adc)| (true, g1, g2, m, mag, adc)),
    ];
    proptest::collection::vec(step, 1..300).prop_map(|steps| {
        let mut raw = RawSample {
            current: AdcCode(2048),
            ..Default::default()
        };
        steps
            .into_iter()
            .map(|(jump, g1, g2, m, mag, adc)| {
                if jump {
                    raw.grating1 = GratingCount(g1);
                    raw.grating2 = GratingCount(g2);
                    raw.motor = MotorCount(m as u16);
                    raw.magnetic = MagneticCount(mag as u16);
                } else {
                    raw.grating1 = GratingCount(raw.grating1.0.wrapping_add(g1));
                    raw.grating2 = GratingCount(raw.grating2.0.wrapping_add(g2));
                    raw.motor = MotorCount(raw.motor.0.wrapping_add(m as u16));
                    raw.magnetic = MagneticCount(raw.magnetic.0.wrapping_add(mag as u16));
                }
                raw.current = AdcCode(adc);
                raw
            })
            .collect()
    })
}

/// A Fourier excitation whose fifth harmonic makes it start at rest.
fn fourier_at_rest(offset_rad: f32, base_freq_hz: f32, s: [f32; 4], c: [f32; 4]) -> Trajectory {
    let (mut sin_rad, mut cos_rad) = ([0.0; HARMONICS], [0.0; HARMONICS]);
    sin_rad[..4].copy_from_slice(&s);
    cos_rad[..4].copy_from_slice(&c);
    let k = |i: usize| (i + 1) as f32;
    sin_rad[4] = -(0..4).map(|i| k(i) * s[i]).sum::<f32>() / 5.0;
    cos_rad[4] = -(0..4).map(|i| k(i) * k(i) * c[i]).sum::<f32>() / 25.0;
    Trajectory::Fourier {
        offset_rad,
        base_freq_hz,
        sin_rad,
        cos_rad,
    }
}

fn command() -> impl Strategy<Value = Command> {
    let mode = prop_oneof![
        Just(Mode::Idle),
        Just(Mode::MotorPosition),
        Just(Mode::JointClosedLoop)
    ];
    let trajectory = prop_oneof![
        (-1.5f32..1.5).prop_map(|a| Trajectory::Hold { angle_rad: a }),
        (-1.0f32..1.0, 0.0f32..1.0, 0.01f32..100.0).prop_map(|(o, a, f)| Trajectory::Sine {
            offset_rad: o,
            amplitude_rad: a,
            freq_hz: f,
        }),
        (-1.5f32..1.5, -1.5f32..1.5, 0.0f32..5.0).prop_map(|(a, b, d)| {
            Trajectory::PointToPoint {
                from_rad: a,
                to_rad: b,
                duration_s: d,
            }
        }),
        (0.0f32..1.0, 0.01f32..100.0).prop_map(|(a, f)| Trajectory::Complex {
            amplitude_rad: a,
            base_freq_hz: f,
        }),
        (
            -1.0f32..1.0,
            0.01f32..10.0,
            [-0.3f32..0.3, -0.3f32..0.3, -0.3f32..0.3, -0.3f32..0.3],
            [-0.3f32..0.3, -0.3f32..0.3, -0.3f32..0.3, -0.3f32..0.3],
        )
            .prop_map(|(o, f, s, c)| fourier_at_rest(o, f, s, c)),
    ];
    (mode, trajectory).prop_map(|(mode, trajectory)| Command { mode, trajectory })
}

/// What the operator does now and then: clear, re-home, a new command.
#[derive(Clone, Copy, Debug)]
enum Action {
    None,
    Clear,
    Origin,
    Command(Command),
}

fn actions() -> impl Strategy<Value = Vec<Action>> {
    let action = prop_oneof![
        30 => Just(Action::None),
        1 => Just(Action::Clear),
        1 => Just(Action::Origin),
        1 => command().prop_map(Action::Command),
    ];
    proptest::collection::vec(action, 300)
}

fn estimates_finite(e: &cable_joint::controller::Estimates) -> bool {
    [
        e.theta_ref_rad,
        e.theta_hat_rad,
        e.x1_vel_m_s,
        e.x2_vel_m_s,
        e.x2_acc_m_s2,
        e.phi_vel_rad_s,
        e.tension1_n,
        e.f_ext_hat_n,
        e.f_ext_stretch_n,
        e.f_ext_fused_n,
    ]
    .iter()
    .all(|v| v.is_finite())
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: cases(),
        max_global_rejects: 1_000_000,
        ..ProptestConfig::default()
    })]

    #[test]
    fn step_never_panics_and_never_drives_through_a_fault(
        cfg in config(),
        first in command(),
        raws in samples(),
        acts in actions(),
    ) {
        prop_assume!(cfg.validate().is_ok());
        let mut c = Controller::new(cfg).unwrap();
        c.set_command(first);
        let limit_a = cfg.cascade.current_limit_a;
        for (k, raw) in raws.iter().enumerate() {
            match acts[k] {
                Action::None => {}
                Action::Clear => c.clear_fault(),
                Action::Origin => c.set_origin(raw),
                Action::Command(cmd) => c.set_command(cmd),
            }
            let out = c.step(raw);
            prop_assert!(out.current_ref_a.is_finite(), "tick {}: {}", k, out.current_ref_a);
            prop_assert!(out.current_ref_a.abs() <= limit_a, "tick {}: {} A", k, out.current_ref_a);
            prop_assert!(out.dac.0 <= 4095, "tick {}: DAC {}", k, out.dac.0);
            if out.fault.is_some() {
                prop_assert!(!out.drive_enable, "tick {}: drive on with {:?}", k, out.fault);
                prop_assert_eq!(out.current_ref_a, 0.0);
            }
            if !estimates_finite(&out.est) {
                prop_assert!(out.fault.is_some(), "tick {}: non-finite estimate, no fault", k);
                prop_assert!(!out.drive_enable);
            }
        }
    }

    /// Configurations `validate()` rejects never build a controller, and the
    /// error names a field.
    #[test]
    fn rejected_configurations_name_their_field(cfg in config()) {
        match Controller::new(cfg) {
            Ok(_) => prop_assert!(cfg.validate().is_ok()),
            Err(e) => {
                prop_assert!(!e.field.is_empty() && !e.expected.is_empty());
                prop_assert_eq!(cfg.validate().unwrap_err(), e);
            }
        }
    }
}

/// The faults the property test's samples provoke are the ones a glitching
/// front end must provoke: a sample far from the last is an encoder jump.
#[test]
fn a_far_sample_is_an_encoder_jump_with_the_drive_off() {
    let mut c = Controller::new(Config::default()).unwrap();
    c.set_command(Command {
        mode: Mode::MotorPosition,
        trajectory: Trajectory::Hold { angle_rad: 0.0 },
    });
    let rest = RawSample {
        current: AdcCode(2048),
        ..Default::default()
    };
    c.step(&rest);
    let far = RawSample {
        grating1: GratingCount(i32::MIN),
        ..rest
    };
    let out = c.step(&far);
    assert!(matches!(out.fault, Some(Fault::EncoderJump(_))));
    assert!(!out.drive_enable);
}

/// The property test is not vacuous: at least a quarter of the generated
/// configurations pass `validate()` and reach `step()` (854 of 2000 at
/// stop 58; the rest are refused by the field the message names).
#[test]
fn at_least_a_quarter_of_generated_configurations_are_valid() {
    use proptest::strategy::ValueTree;
    let mut runner = proptest::test_runner::TestRunner::deterministic();
    let strategy = config();
    let n = 2000;
    let mut valid = 0;
    let mut first_errors = std::collections::BTreeMap::new();
    for _ in 0..n {
        let c = strategy.new_tree(&mut runner).unwrap().current();
        match c.validate() {
            Ok(()) => valid += 1,
            Err(e) => *first_errors.entry(e.field).or_insert(0) += 1,
        }
    }
    eprintln!("{valid} of {n} valid; rejected by: {first_errors:?}");
    assert!(
        valid * 4 >= n,
        "only {valid} of {n} valid: {first_errors:?}"
    );
}
