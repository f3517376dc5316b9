//! The core's payload model (seed 001, Eq. 2-12) on hand-computed and
//! synthetic data: the regressor at a static pose, exact identification of
//! known parameters (offsets, mass, first moment, inertia, creep, drift) from
//! noise-free data, the f32 estimator recovering a known contact wrench, and
//! the offset tracker holding its correction during contact.

use cable_joint::lsq::RlsConfig;
use cable_joint::payload::{
    regressor, regressor_ext, CompConfig, CompState, IdentConfig, Kinematics, OffsetTracker,
    PayloadIdentifier, PayloadModel, PayloadParams, Wrench, N_INERTIAL,
};
use nalgebra::{SVector, Vector3};

/// Static pose, worked by hand: m = 2 kg, c = (0.1, 0, 0.05) m, gravity
/// along -z of the sensor (g_s = (0, 0, -9.81)).
/// f = m g = (0, 0, -19.62) N;
/// tau = (m c) x g = (0.2, 0, 0.1) x (0, 0, -9.81)
///     = (0*(-9.81) - 0.1*0, 0.1*0 - 0.2*(-9.81), 0.2*0 - 0*0)
///     = (0, 1.962, 0) N·m.
#[test]
fn static_pose_by_hand() {
    let k = Kinematics::static_pose(Vector3::new(0.0, 0.0, -9.81));
    let mut phi = SVector::<f64, N_INERTIAL>::zeros();
    phi[0] = 2.0;
    phi[1] = 0.2;
    phi[3] = 0.1;
    // Inertia must not matter at rest.
    phi[4] = 0.05;
    phi[9] = 0.03;
    let w = regressor(&k) * phi;
    let expect = [0.0, 0.0, -19.62, 0.0, 1.962, 0.0];
    for j in 0..6 {
        assert!(
            (w[j] - expect[j]).abs() < 1e-12,
            "axis {j}: {} vs {} (hand-computed)",
            w[j],
            expect[j]
        );
    }
    // Same pose, sensor tilted so gravity is along +x: f = (19.62, 0, 0),
    // tau = (0.2, 0, 0.1) x (9.81, 0, 0) = (0, 0.981, 0).
    let k = Kinematics::static_pose(Vector3::new(9.81, 0.0, 0.0));
    let w = regressor(&k) * phi;
    let expect = [19.62, 0.0, 0.0, 0.0, 0.981, 0.0];
    for j in 0..6 {
        assert!((w[j] - expect[j]).abs() < 1e-12, "axis {j}: {}", w[j]);
    }
    // The extended regressor adds the offsets one to one.
    let ext = regressor_ext(&k);
    let mut p = SVector::<f64, 16>::zeros();
    p.fixed_rows_mut::<6>(0)
        .copy_from_slice(&[1.0, 2.0, 3.0, 0.1, 0.2, 0.3]);
    p.fixed_rows_mut::<10>(6).copy_from(&phi);
    let w2 = ext * p;
    assert!((w2[0] - 20.62).abs() < 1e-12 && (w2[4] - 1.181).abs() < 1e-12);
}

/// Rich synthetic motion: gravity turning through all directions, linear
/// acceleration, angular velocity and acceleration all excited.
fn synthetic_kinematics(n: usize, dt: f64) -> Vec<Kinematics<f64>> {
    (0..n)
        .map(|i| {
            let t = i as f64 * dt;
            let (a1, a2) = (0.7 * t, 0.45 * t + 0.3);
            let g = Vector3::new(a1.cos() * a2.cos(), a1.sin() * a2.cos(), a2.sin()) * 9.81;
            Kinematics {
                gravity_m_s2: g,
                accel_m_s2: Vector3::new(
                    1.5 * (2.1 * t).sin(),
                    -(1.3 * t + 0.5).cos(),
                    0.8 * (3.7 * t).sin(),
                ),
                omega_rad_s: Vector3::new(
                    1.2 * (0.9 * t).sin(),
                    0.8 * (1.7 * t + 1.0).sin(),
                    1.5 * (0.6 * t).cos(),
                ),
                alpha_rad_s2: Vector3::new(
                    3.0 * (2.3 * t).cos(),
                    -2.0 * (1.1 * t).sin(),
                    2.5 * (2.9 * t + 0.2).sin(),
                ),
            }
        })
        .collect()
}

fn truth() -> PayloadParams {
    PayloadParams {
        offset: [9.1, -1.0, 10.2, 0.43, -0.69, -0.15],
        inertial: [
            1.25, 0.012, -0.03, 0.06, 0.011, 0.0012, -0.0021, 0.013, 0.0015, 0.0085,
        ],
        creep: [0.0; 6],
        drift_per_s: [0.0; 6],
    }
}

#[test]
fn identification_is_exact_on_noise_free_data() {
    let p = truth();
    let kin = synthetic_kinematics(3000, 0.005);
    let cfg = IdentConfig::default(); // inertia on, no creep/drift, unit weights
    let mut id = PayloadIdentifier::new(cfg).unwrap();
    for k in &kin {
        id.push(k, &p.predict_ext(k), 0.005).unwrap();
    }
    let fit = id.solve().unwrap();
    for k in 0..6 {
        assert!(
            (fit.params.offset[k] - p.offset[k]).abs() < 1e-9,
            "offset {k}: {} vs {}",
            fit.params.offset[k],
            p.offset[k]
        );
    }
    for j in 0..N_INERTIAL {
        assert!(
            (fit.params.inertial[j] - p.inertial[j]).abs() < 1e-9,
            "phi {j}: {} vs {}",
            fit.params.inertial[j],
            p.inertial[j]
        );
    }
    assert!(fit.lsq.rmse < 1e-9, "residual {}", fit.lsq.rmse);
    assert!(
        fit.lsq.condition < 1e4,
        "rich excitation is well conditioned: {}",
        fit.lsq.condition
    );
    assert_eq!(fit.samples, 3000);
    let c = fit.params.com_m().unwrap();
    assert!((c[2] - 0.06 / 1.25).abs() < 1e-9);
}

/// Without rotation the inertia columns are zero: the identifier reports
/// the rank deficiency instead of returning numbers.
#[test]
fn inertia_without_rotation_is_rank_deficient() {
    let p = truth();
    let mut kin = synthetic_kinematics(500, 0.01);
    for k in &mut kin {
        k.omega_rad_s = Vector3::zeros();
        k.alpha_rad_s2 = Vector3::zeros();
    }
    let mut id = PayloadIdentifier::new(IdentConfig::default()).unwrap();
    for k in &kin {
        id.push(k, &p.predict_ext(k), 0.01).unwrap();
    }
    let err = id.solve().unwrap_err();
    assert!(
        format!("{err}").contains("ill-conditioned"),
        "expected a rank-deficiency error, got {err}"
    );
    // Without the inertia columns the rest is exact.
    let cfg = IdentConfig {
        inertia: false,
        ..IdentConfig::default()
    };
    let mut id = PayloadIdentifier::new(cfg).unwrap();
    for k in &kin {
        id.push(k, &p.predict_ext(k), 0.01).unwrap();
    }
    let fit = id.solve().unwrap();
    assert!((fit.params.mass_kg() - 1.25).abs() < 1e-9);
    assert_eq!(fit.params.inertial[4..], [0.0; 6]);
}

/// Data generated with creep (driven by the payload load through the same
/// core code) and a linear drift: the identifier recovers rho and d exactly.
#[test]
fn creep_and_drift_are_recovered_exactly() {
    let mut p = truth();
    p.creep = [0.02, 0.0, 0.015, 0.01, 0.03, 0.0];
    p.drift_per_s = [0.01, -0.005, 0.002, 0.0, 1e-4, -2e-4];
    let comp = CompConfig {
        creep_tau_s: Some(2.0),
        creep_axes: [true, false, true, true, true, false],
        drift_axes: [true; 6],
    };
    let dt = 0.005;
    let kin = synthetic_kinematics(4000, dt);
    let mut gen_state = CompState::default();
    let phi = SVector::<f64, N_INERTIAL>::from(p.inertial);
    let cfg = IdentConfig {
        comp,
        creep_load: p.inertial,
        ..IdentConfig::default()
    };
    let mut id = PayloadIdentifier::new(cfg).unwrap();
    for k in &kin {
        let load = regressor(k) * phi;
        let cols = gen_state.update(&comp, &load.map(|v| v as f32), dt as f32);
        let mut y = p.predict_ext(k);
        for a in 0..6 {
            y[a] +=
                p.creep[a] * f64::from(cols.creep[a]) + p.drift_per_s[a] * f64::from(cols.time_s);
        }
        id.push(k, &y, dt).unwrap();
    }
    let fit = id.solve().unwrap();
    for a in 0..6 {
        assert!(
            (fit.params.creep[a] - p.creep[a]).abs() < 1e-8,
            "creep {a}: {} vs {}",
            fit.params.creep[a],
            p.creep[a]
        );
        assert!(
            (fit.params.drift_per_s[a] - p.drift_per_s[a]).abs() < 1e-9,
            "drift {a}: {} vs {}",
            fit.params.drift_per_s[a],
            p.drift_per_s[a]
        );
    }
    assert!((fit.params.mass_kg() - 1.25).abs() < 1e-8);
    assert_eq!(fit.lsq.n_params, 16 + 4 + 6);
}

fn to_f32(k: &Kinematics<f64>) -> Kinematics<f32> {
    Kinematics {
        gravity_m_s2: k.gravity_m_s2.map(|v| v as f32),
        accel_m_s2: k.accel_m_s2.map(|v| v as f32),
        omega_rad_s: k.omega_rad_s.map(|v| v as f32),
        alpha_rad_s2: k.alpha_rad_s2.map(|v| v as f32),
    }
}

/// The f32 estimator returns the contact wrench that was added to the
/// payload's wrench (Eq. 12), to f32 precision; the offset tracker learns a
/// zero shift while told "no contact" and holds it during contact.
#[test]
fn estimator_recovers_contact_and_tracker_holds() {
    let p = truth();
    let model = PayloadModel::new(&p, CompConfig::NONE).unwrap();
    let kin = synthetic_kinematics(2000, 0.005);
    let shift = [0.3, -0.2, 0.5, 0.01, -0.02, 0.005];
    let mut state = CompState::default();
    let mut tracker = OffsetTracker::new(RlsConfig {
        forgetting: 0.99,
        initial_covariance: 1e3,
        max_trace: 1e4,
    })
    .unwrap();
    for (i, k) in kin.iter().enumerate() {
        let contact_on = i >= 1000;
        let contact = if contact_on {
            let s = (i as f64 * 0.01).sin();
            [5.0 * s, -3.0, 2.0 * s, 0.1, -0.2 * s, 0.05]
        } else {
            [0.0; 6]
        };
        let mut y = p.predict_ext(k);
        for a in 0..6 {
            y[a] += contact[a] + shift[a];
        }
        let fe = model
            .estimate(&mut state, &to_f32(k), &y.map(|v| v as f32), 0.005)
            .unwrap();
        let out = tracker.process(&fe, !contact_on);
        for a in 0..6 {
            let scale = if a < 3 { 1e-3 } else { 1e-4 };
            assert!(
                (f64::from(fe[a]) - contact[a] - shift[a]).abs() < scale,
                "sample {i} axis {a}: F_e {} vs contact + shift {}",
                fe[a],
                contact[a] + shift[a]
            );
            if contact_on {
                assert!(
                    (f64::from(out[a]) - contact[a]).abs() < 2.0 * scale,
                    "sample {i} axis {a}: tracked {} vs contact {}",
                    out[a],
                    contact[a]
                );
            }
        }
    }
    let bad = Kinematics::<f32>::static_pose(Vector3::new(f32::NAN, 0.0, -9.81));
    assert!(model
        .estimate(&mut state, &bad, &Wrench::zeros(), 0.005)
        .is_err());
}
