//! Each switchable effect changes what it should, and nothing when off.

use host_sim::plant::{
    Creep, DriftLocation, OffsetDrift, Plant, PlantParams, Presliding, SpringHardening, Thermal,
};

fn frictionless(mut p: PlantParams) -> PlantParams {
    p.motor.coulomb_nm = 0.0;
    for s in [&mut p.slider1, &mut p.slider2] {
        s.coulomb_n = 0.0;
        s.static_n = 0.0;
    }
    p.joint.coulomb_nm = 0.0;
    p.joint.static_nm = 0.0;
    p
}

/// Thermal: a sustained 1.5 A heats the winding as the two-node model
/// predicts, `K_m` drops by `a_K` per kelvin, and the free-running motor's
/// speed drops with it. Off, nothing changes.
#[test]
fn thermal_km_drops_under_sustained_current() {
    let mut p = PlantParams {
        motor_decoupled: true,
        ..PlantParams::default()
    };
    let th = Thermal::default();
    let (i, t_run) = (1.5, 20.0);
    let run = |p: PlantParams| {
        let mut plant = Plant::new(p, 1).unwrap();
        plant.set_current_command(i);
        plant.advance(t_run);
        plant
    };
    let cold = run(p);
    p.effects.thermal = Some(th);
    let hot = run(p);

    // Two-node estimate: the winding rises by P R_wh (1 - e^{-t/tau_w}) over
    // the housing, the housing by about P t / C_h (t << tau_h).
    let p_w = i * i * th.resistance_ohm;
    let c_h = th.tau_housing_s / th.housing_ambient_k_w;
    let est = p_w * th.winding_housing_k_w * (1.0 - (-t_run / th.tau_winding_s).exp())
        + p_w * t_run / c_h;
    let rise = hot.state().winding_c - th.ambient_c;
    // Copper resistance grows with temperature: up to ~10 % more loss here.
    assert!(
        rise > 0.9 * est && rise < 1.25 * est,
        "winding rise {rise:.2} K vs two-node estimate {est:.2} K"
    );
    let km0 = p.motor.torque_constant_nm_a;
    let km = hot.torque_constant_nm_a();
    assert!(
        ((1.0 - km / km0) - th.km_tc_1_k * rise).abs() < 1e-9,
        "K_m drop {} vs {} per K",
        1.0 - km / km0,
        th.km_tc_1_k
    );
    assert_eq!(cold.torque_constant_nm_a(), km0, "no drop when off");
    assert_eq!(cold.state().winding_c, 25.0);
    // Free-running speed (K_m i - f_m) / B_m follows K_m.
    let speed = |k: f64| (k * i - p.motor.coulomb_nm) / p.motor.viscous_nm_s_rad;
    let ratio = hot.state().phi_vel_rad_s / cold.state().phi_vel_rad_s;
    assert!(
        (ratio - speed(km) / speed(km0)).abs() < 2e-3,
        "speed ratio {ratio} vs {}",
        speed(km) / speed(km0)
    );
}

/// Creep: with the motor locked (a displacement-controlled loop) and freshly
/// tensioned cables, the preload relaxes to the analytic value
/// `ΔF = -ratio F_0 C / (S + ratio C)` (C: cable compliances, S: all
/// compliances in the loop), with the creep time constant.
#[test]
fn creep_relaxes_the_preload_of_a_held_loop() {
    let mut p = frictionless(PlantParams::default());
    let creep = Creep {
        ratio: 0.1,
        tau_s: 1.0,
        fresh: true,
    };
    p.effects.creep = Some(creep);
    let mut plant = Plant::new(p, 1).unwrap();
    let f0 = p.spring.preload_n;
    let c =
        1.0 / p.cable0.stiffness_n_m + 1.0 / p.cable1.stiffness_n_m + 1.0 / p.cable2.stiffness_n_m;
    let s = c + 1.0 / p.spring.stiffness_n_m;
    let df = -creep.ratio * f0 * c / (s + creep.ratio * c);
    let lock = |plant: &mut Plant| {
        let st = plant.state_mut();
        st.phi_rad = 0.0;
        st.phi_vel_rad_s = 0.0;
    };
    let steps_per_s = (1.0 / plant.dt_s()).round() as usize;
    for _ in 0..steps_per_s {
        plant.step();
        lock(&mut plant);
    }
    let after_tau = plant.tensions().spring_n - f0;
    for _ in 0..9 * steps_per_s {
        plant.step();
        lock(&mut plant);
    }
    let t = plant.tensions();
    for (name, f) in [
        ("rope", t.rope_n),
        ("cable 1", t.cable1_n),
        ("cable 2", t.cable2_n),
        ("spring", t.spring_n),
    ] {
        assert!(
            (f - (f0 + df)).abs() < 0.02 * df.abs(),
            "{name}: {f:.4} N vs relaxed {:.4} N",
            f0 + df
        );
    }
    // First order: 63 % of the drop after one time constant (the loop's own
    // mechanical response is much faster).
    assert!(
        (after_tau / df - (1.0 - (-1.0f64).exp())).abs() < 0.05,
        "after tau: {after_tau:.4} of {df:.4}"
    );

    // Settled cables (not fresh) do not creep at rest.
    p.effects.creep = Some(Creep {
        fresh: false,
        ..creep
    });
    let mut plant = Plant::new(p, 1).unwrap();
    plant.advance(3.0);
    assert!((plant.tensions().spring_n - f0).abs() < 1e-9);
}

/// Creep under a tip load: with the motor torque-controlled the tensions
/// cannot relax, so cables 0 and 1, loaded above their settled preload, keep
/// lengthening and the motor winds in by their creep.
#[test]
fn creep_lets_a_loaded_joint_drift() {
    let mut p = frictionless(PlantParams::default());
    // Well above the ~1 s mechanical settling, so the tensions are constant
    // over almost all of the creep.
    let tau = 20.0;
    let f_ext = 0.5;
    let extra = f_ext * p.joint.gripper_length_m / p.joint.pulley_radius_m;
    let run = |p: PlantParams| {
        let mut plant = Plant::new(p, 1).unwrap();
        // Motor torque for F_0 + extra: the joint stays near 0 against the load.
        plant.set_current_command(
            (p.spring.preload_n + extra) * p.motor.rope_wheel_radius_m
                / (p.motor.gear_ratio * p.motor.torque_constant_nm_a),
        );
        plant.set_external_force(f_ext);
        plant.advance(0.25 * tau);
        let early = plant.state().phi_rad;
        plant.advance(tau);
        plant.state().phi_rad - early
    };
    let rigid = run(p);
    p.effects.creep = Some(Creep {
        ratio: 0.1,
        tau_s: tau,
        fresh: false,
    });
    let creeping = run(p);
    // The mechanical settling is the same in both runs; the difference is
    // the creep of cables 0 and 1 under `extra` between tau/4 and 5 tau/4.
    let rw = p.motor.rope_wheel_radius_m / p.motor.gear_ratio;
    let creep_len = 0.1 * extra * (1.0 / p.cable0.stiffness_n_m + 1.0 / p.cable1.stiffness_n_m);
    let want = creep_len * ((-0.25f64).exp() - (-1.25f64).exp());
    let wound = (creeping - rigid) * rw;
    assert!(
        (wound / want - 1.0).abs() < 0.1,
        "motor wound {wound:e} m more with creep, creep predicts {want:e} m"
    );
}

/// Spring hardening: the static equilibrium solves the cubic spring law.
#[test]
fn spring_hardening_follows_the_cubic_law() {
    let mut p = frictionless(PlantParams::default());
    let k3 = 4e7;
    p.effects.spring_hardening = Some(SpringHardening { cubic_n_m3: k3 });
    let f_ext = 0.3;
    let mut plant = Plant::new(p, 1).unwrap();
    plant.set_external_force(-f_ext);
    plant.advance(15.0);
    // Cable 2 and the spring carry F_0 + f_ext l_e / r (the joint turns
    // positive): K_s x + k3 x^3 = f_ext l_e / r, solved by Newton.
    let target = f_ext * p.joint.gripper_length_m / p.joint.pulley_radius_m;
    let ks = p.spring.stiffness_n_m;
    let mut x = target / ks;
    for _ in 0..50 {
        x -= (ks * x + k3 * x * x * x - target) / (ks + 3.0 * k3 * x * x);
    }
    let got = plant.state().x2_m;
    assert!((got - x).abs() < 1e-4 * x, "x2 {got:e} vs cubic root {x:e}");
    let linear = target / ks;
    assert!(
        linear - got > 0.05 * linear,
        "hardening shortens the travel: {got:e} vs linear {linear:e}"
    );
}

/// Presliding (LuGre): a tip force below breakaway deflects the joint a
/// little (pure Coulomb: not at all), by the order of `F l_e / sigma0`,
/// between the bounds the bristle and the cables set; near breakaway the deflection is
/// hysteretic (a residual deflection remains when the force is removed).
#[test]
fn presliding_gives_small_hysteretic_deflection_below_breakaway() {
    let p = PlantParams::default();
    let pre = Presliding::default();
    let le = p.joint.gripper_length_m;
    let f = 0.9 * p.joint.coulomb_nm / le;

    let mut coulomb = Plant::new(p, 1).unwrap();
    coulomb.set_external_force(f);
    coulomb.advance(0.5);
    assert_eq!(coulomb.state().theta_rad, 0.0);

    let mut q = p;
    q.effects.presliding = Some(pre);
    let mut lugre = Plant::new(q, 1).unwrap();
    lugre.advance(0.2);
    assert!(
        lugre.state().theta_rad.abs() < 1e-9,
        "LuGre at rest without load stays put: {}",
        lugre.state().theta_rad
    );
    lugre.set_external_force(f);
    lugre.advance(0.5);
    let loaded = lugre.state().theta_rad;
    let r = p.joint.pulley_radius_m;
    let k_theta = (p.cable1.stiffness_n_m + p.cable2.stiffness_n_m) * r * r;
    let sigma0 = p.joint.coulomb_nm / pre.joint_presliding_rad;
    // Between two physical bounds (measured 1.17 presliding angles): at
    // least the torque over the bristle's initial stiffness `sigma0` with
    // the cables in parallel on rigid sliders (the stiffest the joint can
    // be held: 0.71 presliding angles); at most the bristle alone along its
    // Dahl curve `z = (F_c / sigma0)(1 - e^(-sigma0 theta / F_c))` to 0.9 of
    // breakaway, `ln 10` presliding angles (the cables only stiffen it).
    let least = f * le / (sigma0 + k_theta);
    let most = 10f64.ln() * pre.joint_presliding_rad;
    assert!(
        -loaded >= least && -loaded <= most,
        "presliding deflection {loaded:e} rad, bounds {least:e} to {most:e}"
    );
    lugre.set_external_force(0.0);
    lugre.advance(0.5);
    let residual = lugre.state().theta_rad;
    assert!(
        residual < 0.1 * loaded,
        "hysteresis: residual {residual:e} after {loaded:e}"
    );
    assert!(residual.abs() < loaded.abs(), "partly recovered");
}

/// Offset drift in the drive's sensor: the winding current falls behind the
/// reference by the drift while the monitor still reads the reference; in
/// the monitor path only the reading moves.
#[test]
fn offset_drift_moves_torque_or_reading() {
    let mut p = PlantParams {
        motor_decoupled: true,
        ..PlantParams::default()
    };
    p.drive.monitor_noise_a = 0.0;
    p.drive.monitor_offset_a = 0.0;
    let rate = 2e-3;
    let lsb = p.sensors.scales.adc_a_per_code as f64;
    for location in [DriftLocation::DriveSensor, DriftLocation::Monitor] {
        p.effects.offset_drift = Some(OffsetDrift {
            rate_a_s: rate,
            random_walk_a_sqrt_s: 0.0,
            location,
        });
        let mut plant = Plant::new(p, 1).unwrap();
        plant.set_current_command(0.5);
        plant.advance(10.0);
        let drift = rate * 10.0;
        assert!((plant.state().drift_a - drift).abs() < 1e-9);
        let i = plant.state().current_a;
        let code = plant.sample().current.0 as f64;
        let read = (code - 2048.0) * lsb;
        match location {
            DriftLocation::DriveSensor => {
                assert!((i - (0.5 - drift)).abs() < 1e-6, "winding {i}");
                assert!((read - 0.5).abs() <= 0.5 * lsb + 1e-9, "monitor {read}");
            }
            DriftLocation::Monitor => {
                assert!((i - 0.5).abs() < 1e-6, "winding {i}");
                assert!(
                    (read - (0.5 + drift)).abs() <= 0.5 * lsb + 1e-9,
                    "monitor {read}"
                );
            }
        }
    }
}

/// Effects are switched on by name; unknown names are an error.
#[test]
fn effects_enable_by_name() {
    let mut p = PlantParams::default();
    assert!(p.effects.enabled().is_empty(), "all off by default");
    for n in ["presliding", "creep", "thermal", "spring", "drift"] {
        p.effects.enable(n).unwrap();
    }
    assert_eq!(p.effects.enabled().len(), 5);
    assert!(p.effects.enable("backlash").is_err());
    assert!(Plant::new(p, 1).is_ok(), "all effects on is still stable");
}
