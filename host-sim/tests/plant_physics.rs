//! Mechanics of the simulated prototype: rest with preload, static equilibrium
//! under a tip force against the analytic stiffness chain, stick-slip.

use host_sim::plant::{Plant, PlantParams, TipObject};

fn frictionless() -> PlantParams {
    let mut p = PlantParams::default();
    p.motor.coulomb_nm = 0.0;
    for s in [&mut p.slider1, &mut p.slider2] {
        s.coulomb_n = 0.0;
        s.static_n = 0.0;
    }
    p.joint.coulomb_nm = 0.0;
    p.joint.static_nm = 0.0;
    p
}

/// At rest with the holding current, every tension is `F_0` and nothing
/// moves, with and without friction.
#[test]
fn rest_with_preload_is_an_equilibrium() {
    for params in [PlantParams::default(), frictionless()] {
        let mut plant = Plant::new(params, 1).unwrap();
        let f0 = params.spring.preload_n;
        let i0 = f0 * params.motor.rope_wheel_radius_m
            / (params.motor.gear_ratio * params.motor.torque_constant_nm_a);
        assert!((plant.holding_current_a() - i0).abs() < 1e-15);
        assert_eq!(plant.state().current_a, plant.holding_current_a());
        plant.advance(2.0);
        let s = plant.state();
        for (name, v) in [
            ("phi", s.phi_rad),
            ("x1", s.x1_m),
            ("theta", s.theta_rad),
            ("x2", s.x2_m),
        ] {
            assert!(v.abs() < 1e-12, "{name} moved to {v:e} at rest");
        }
        let t = plant.tensions();
        for (name, f) in [
            ("rope", t.rope_n),
            ("cable 1", t.cable1_n),
            ("cable 2", t.cable2_n),
            ("spring", t.spring_n),
        ] {
            assert!((f - f0).abs() < 1e-9, "{name} tension {f} != F_0 {f0}");
        }
    }
}

/// Without friction, constant motor torque and a tip force: every tension
/// and position follows from the stiffness chain (DESIGN.md §1 equations at
/// rest).
#[test]
fn static_equilibrium_under_tip_force_matches_stiffness_chain() {
    let p = frictionless();
    let mut plant = Plant::new(p, 1).unwrap();
    let f_ext = 0.3;
    plant.set_external_force(f_ext);
    plant.advance(15.0);

    let f0 = p.spring.preload_n;
    let (r, le) = (p.joint.pulley_radius_m, p.joint.gripper_length_m);
    let rw = p.motor.rope_wheel_radius_m / p.motor.gear_ratio;
    // Motor torque K_m i0 balances the rope: F_1 = F_0. Slider 1 without
    // friction: F_w1 = F_1. Joint: (F_w1 - F_w2) r = F_ext l_e. Slider 2:
    // F_w2 = F_0 + K_s x2.
    let f1 = f0;
    let fw1 = f1;
    let fw2 = fw1 - f_ext * le / r;
    let x2 = (fw2 - f0) / p.spring.stiffness_n_m;
    let theta = (x2 + (fw2 - f0) / p.cable2.stiffness_n_m) / r;
    let x1 = r * theta + (fw1 - f0) / p.cable1.stiffness_n_m;
    let phi = (x1 + (f1 - f0) / p.cable0.stiffness_n_m) / rw;

    let s = plant.state();
    let t = plant.tensions();
    let close = |name: &str, got: f64, want: f64| {
        assert!(
            (got - want).abs() <= 1e-4 * want.abs().max(1e-3),
            "{name}: simulated {got:.6e}, analytic {want:.6e}"
        );
    };
    close("x2", s.x2_m, x2);
    close("theta", s.theta_rad, theta);
    close("x1", s.x1_m, x1);
    close("phi", s.phi_rad, phi);
    close("F_w2", t.cable2_n, fw2);
    close("F_w1", t.cable1_n, fw1);
    close("F_1", t.rope_n, f1);
    close("spring", t.spring_n, fw2);
    assert!(s.theta_vel_rad_s.abs() < 1e-6, "settled");
    // The tip force opposes positive rotation: the joint turned negative.
    assert!(theta < -0.5, "0.3 N turns the joint by {theta} rad");
}

/// The joint's static friction holds a tip force below breakaway with zero
/// drift, and lets go above it; after slipping it sticks again.
#[test]
fn joint_stiction_holds_below_breakaway_and_slips_above() {
    let p = PlantParams::default();
    let le = p.joint.gripper_length_m;
    let breakaway_n = p.joint.static_nm / le;

    let mut plant = Plant::new(p, 1).unwrap();
    plant.set_external_force(0.9 * breakaway_n);
    plant.advance(1.0);
    let s = *plant.state();
    assert_eq!(s.theta_rad, 0.0, "stuck joint must not creep");
    assert_eq!(s.theta_vel_rad_s, 0.0);
    assert_eq!(s.x2_m, 0.0);
    assert_eq!(s.x1_m, 0.0);

    let mut plant = Plant::new(p, 1).unwrap();
    plant.set_external_force(1.3 * breakaway_n);
    plant.advance(1.0);
    let s = *plant.state();
    // Slipping stops where cable stretch takes the excess over the kinetic
    // level: of the order (F l_e - f_c) / ((K_w1 + K_w2) r^2), i.e. a few
    // hundredths of a radian, never beyond the static band.
    let k_theta =
        (p.cable1.stiffness_n_m + p.cable2.stiffness_n_m) * p.joint.pulley_radius_m.powi(2);
    let excess = 1.3 * breakaway_n * le - p.joint.coulomb_nm;
    assert!(
        s.theta_rad < -0.2 * excess / k_theta,
        "joint slipped only to {} rad",
        s.theta_rad
    );
    assert!(
        s.theta_rad > -(1.3 * breakaway_n * le + p.joint.static_nm) / (0.5 * k_theta),
        "joint ran away to {} rad",
        s.theta_rad
    );
    assert_eq!(s.theta_vel_rad_s, 0.0, "stuck again after slipping");
    let held = s.theta_rad;
    plant.advance(0.5);
    assert_eq!(plant.state().theta_rad, held, "holds after slipping");
}

/// One plant step under the tip force `f_ext_n` with the motor shaft held
/// at its rest angle (what the two stick-slip bands below assume).
fn step_with_motor_held(plant: &mut Plant, f_ext_n: f64) -> host_sim::plant::PlantState {
    plant.set_external_force(f_ext_n);
    plant.step();
    let s = plant.state_mut();
    s.phi_rad = 0.0;
    s.phi_vel_rad_s = 0.0;
    *s
}

/// The joint's first slip with the motor held and a tip force ramped slowly
/// past the pin's breakaway (°, or `None` if it never slipped and stuck).
fn first_pin_slip_deg(p: PlantParams) -> Option<f64> {
    let mut plant = Plant::new(p, 1).unwrap();
    let ramp_n_s = 0.2 * p.joint.static_nm / p.joint.gripper_length_m;
    let mut moving = false;
    for k in 0..(10.0 / plant.dt_s()) as usize {
        let f_ext_n = ramp_n_s * k as f64 * plant.dt_s();
        let s = step_with_motor_held(&mut plant, f_ext_n);
        if s.theta_vel_rad_s != 0.0 {
            moving = true;
        } else if moving {
            return Some(s.theta_rad.abs().to_degrees());
        }
    }
    None
}

/// The pin's stick-slip step the report quotes as the hold's tip-motion
/// floor (`pin_stick_slip_step_rad`): without damping the first slip lies
/// between the stiffest chain's step (both sliders stuck) and the softest's
/// (both free); the plant's damping shortens it.
#[test]
fn the_pin_slips_by_the_stick_slip_step_with_the_motor_held() {
    for static_over_kinetic in [1.2, 1.5, 2.0] {
        let mut p = PlantParams::default();
        p.joint.static_nm = static_over_kinetic * p.joint.coulomb_nm;
        let [stiffest, softest] = p.pin_stick_slip_step_rad().map(f64::to_degrees);
        assert!(stiffest > 0.0 && stiffest < softest);
        let mut undamped = p;
        undamped.joint.viscous_nm_s_rad = 0.0;
        for c in [
            &mut undamped.cable0,
            &mut undamped.cable1,
            &mut undamped.cable2,
        ] {
            c.damping_n_s_m = 0.0;
        }
        for s in [&mut undamped.slider1, &mut undamped.slider2] {
            s.viscous_n_s_m = 0.0;
        }
        let free = first_pin_slip_deg(undamped).expect("undamped pin slips and sticks");
        let damped = first_pin_slip_deg(p).expect("pin slips and sticks");
        eprintln!(
            "static/kinetic {static_over_kinetic}: slip {free:.4}° undamped, {damped:.4}° damped \
             (step {stiffest:.4}° to {softest:.4}°)"
        );
        assert!(
            free >= 0.98 * stiffest && free <= 1.02 * softest,
            "static/kinetic {static_over_kinetic}: undamped slip {free:.4}° outside the \
             chain's step {stiffest:.4}° to {softest:.4}°"
        );
        assert!(
            damped < free && damped > 0.5 * stiffest,
            "static/kinetic {static_over_kinetic}: damped slip {damped:.4}° against {free:.4}° undamped"
        );
    }
}

/// A joint turned slowly with the motor held and the pin frictionless
/// moves slider 2 (the JAE's only sensor) only once cable 2's tension has
/// changed by slider 2's static friction: half the blind band the report
/// quotes (`jae_blind_band_rad`, edge to edge of the band).
#[test]
fn slider_2_stays_at_rest_until_the_joint_has_turned_half_the_blind_band() {
    for scale in [1.0, 4.0, 8.0] {
        let mut p = PlantParams::default();
        p.joint.coulomb_nm = 0.0;
        p.joint.static_nm = 0.0;
        p.slider2.coulomb_n *= scale;
        p.slider2.static_n *= scale;
        let half = 0.5 * p.jae_blind_band_rad();
        let mut plant = Plant::new(p, 1).unwrap();
        // A tip force ramp that turns the joint at about 0.5 mrad/s.
        let k_theta =
            (p.cable1.stiffness_n_m + p.cable2.stiffness_n_m) * p.joint.pulley_radius_m.powi(2);
        let ramp_n_s = 5e-4 * k_theta / p.joint.gripper_length_m;
        let mut first = None;
        for k in 0..(4.0 * half / 5e-4 / plant.dt_s()) as usize {
            let f_ext_n = -ramp_n_s * k as f64 * plant.dt_s();
            let s = step_with_motor_held(&mut plant, f_ext_n);
            if s.x2_m != 0.0 {
                first = Some(s.theta_rad.abs());
                break;
            }
        }
        let turned = first.expect("slider 2 moved");
        assert!(
            (turned - half).abs() <= 0.05 * half,
            "slider 2 x{scale}: it moved at {:.4}°, half the band is {:.4}°",
            turned.to_degrees(),
            half.to_degrees()
        );
    }
}

/// The same for slider 2 through cable 2: slider 2's breakaway is tiny
/// (0.14 N), so a small extra spring preload moves it, a force within the
/// static band does not.
#[test]
fn slider_stiction_band() {
    let p = PlantParams::default();
    let band = p.slider2.static_n;
    for (extra, moves) in [(0.8 * band, false), (1.5 * band, true)] {
        let mut plant = Plant::new(p, 1).unwrap();
        // Displace slider 2 so the spring pulls `extra` more than cable 2.
        let dx = extra / (p.spring.stiffness_n_m + p.cable2.stiffness_n_m);
        plant.state_mut().x2_m = dx;
        plant.advance(0.5);
        let s = plant.state();
        assert_eq!(
            s.x2_m != dx,
            moves,
            "imbalance {extra:.3} N vs static {band:.3} N: x2 {} -> {}",
            dx,
            s.x2_m
        );
        assert_eq!(s.x2_vel_m_s, 0.0, "at rest at the end");
    }
}

/// A cable that would be compressed carries no tension (cables only pull).
#[test]
fn slack_cable_has_no_tension() {
    let p = PlantParams::default();
    let mut plant = Plant::new(p, 1).unwrap();
    // Wind cable 0 out by more than its preload stretch.
    let rw = p.motor.rope_wheel_radius_m / p.motor.gear_ratio;
    plant.state_mut().phi_rad = -2.0 * p.spring.preload_n / p.cable0.stiffness_n_m / rw;
    assert_eq!(plant.tensions().rope_n, 0.0);
    assert!(plant.tensions().cable1_n > 0.0);
    // Twice the preload's stretch wound out from rest: one stretch's worth
    // of rope hangs loose.
    let loose_m = p.spring.preload_n / p.cable0.stiffness_n_m;
    let slack_m = plant.tensions().slack_m;
    assert!(
        (slack_m - loose_m).abs() < 1e-3 * loose_m,
        "{slack_m} m loose, expected {loose_m}"
    );
    plant.state_mut().phi_rad = 0.0;
    assert_eq!(plant.tensions().slack_m, 0.0, "taut at rest");
}

/// The step-size guard: the default 40 kHz resolves the stiffest mode with
/// margin, and the bound is a true upper bound of the chain's frequencies.
#[test]
fn stiffest_mode_is_resolved() {
    let p = PlantParams::default();
    let plant = Plant::new(p, 1).unwrap();
    let w_dt = plant.omega_max_rad_s() * plant.dt_s();
    assert!(w_dt < 0.2, "w_max dt = {w_dt}");
    // Slider 1 between cables 0 and 1 alone: sqrt((K_w0 + K_w1) / m_0) must
    // lie below the bound.
    let w_slider1 = ((p.cable0.stiffness_n_m + p.cable1.stiffness_n_m) / p.slider1.mass_kg).sqrt();
    assert!(w_slider1 <= plant.omega_max_rad_s());
    // 20 kHz is still accepted; a much lighter joint is refused at 20 kHz.
    let mut q = p;
    q.integration.step_hz = 20_000.0;
    assert!(Plant::new(q, 1).is_ok());
    q.joint.inertia_kg_m2 = 1e-10;
    assert!(Plant::new(q, 1).is_err());
}

/// A soft object at the tip pushes only where the tip has entered it, with
/// its stiffness times the penetration, against the motion into it: a tip
/// force that would turn the frictionless joint far past the object's
/// surface settles where the chain's compliance and the object's push
/// balance, as the linear chain predicts.
#[test]
fn a_tip_object_pushes_back_in_proportion_to_its_penetration() {
    let p = frictionless();
    let le = p.joint.gripper_length_m;
    let f_ext = 0.3;
    // The chain's compliance from a free run: joint angle per newton.
    let mut free = Plant::new(p, 1).unwrap();
    free.set_external_force(f_ext);
    free.advance(15.0);
    let c = free.state().theta_rad / f_ext;
    assert!(c < 0.0);

    let object = TipObject::new(-10.0, 500.0).unwrap();
    let mut plant = Plant::new(p, 1).unwrap();
    plant.set_object(Some(object));
    plant.advance(1.0);
    assert_eq!(plant.contact_force_n(), 0.0, "at rest outside the object");
    plant.set_external_force(f_ext);
    plant.advance(15.0);
    // theta = c (f_ext - k l_e (theta_s - theta)), the push opposing the
    // negative rotation.
    let (k, ts) = (object.stiffness_n_m, object.surface_rad);
    let theta = (c * f_ext - c * k * le * ts) / (1.0 - c * k * le);
    let got = plant.state().theta_rad;
    assert!(
        (got - theta).abs() < 1e-3 * theta.abs(),
        "settled at {got} rad, the linear chain says {theta} rad"
    );
    let push = k * le * (ts - got);
    assert!(push > 0.0, "the tip entered the object");
    assert!(
        (plant.contact_force_n() + push).abs() < 1e-9,
        "push {push} N, recorded {} N",
        plant.contact_force_n()
    );
    assert!(TipObject::new(0.0, 500.0).is_err());
    assert!(TipObject::new(10.0, 0.0).is_err());
}
