//! Seed 000 Eq. 3 on the wrist: the core's inverse-dynamics model
//! (`cable_joint::wrist_dynamics`) fitted by `host_sim::links` on a
//! no-contact run, and what it does to the joints' no-load estimates.

use cable_joint::wrist_dynamics::{regressor, InverseDynamics, WristMotion, N_LINKS, N_PARAMS};
use cable_joint::Config;
use host_sim::ident::excite;
use host_sim::ident::excite_wrist::{self, WristDesign, WristDesignOptions};
use host_sim::links::{
    filtered_rows, fit_inverse_dynamics, fit_rows, no_load, run_free, sign_speeds_rad_s,
    sign_width_seen_rad_s, Eq3Rows, Eq3Sample, Eq3Setting, FreeRun, Links, NoLoad,
};
use host_sim::plant::PlantParams;
use host_sim::scenario;
use host_sim::wrist::{Eq3Model, WristParams};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The regressor's rows at random motions and the torques `truth` gives
/// there, plus `extra` of each motion: exact data for the least-squares
/// layer of the fit ([`fit_rows`]).
fn exact_rows(
    params: &WristParams,
    truth: &InverseDynamics,
    extra: &dyn Fn(&WristMotion) -> [f32; 4],
) -> (Vec<Eq3Rows>, Vec<[f64; 4]>) {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let mut next = || rng.gen_range(-1.0f32..1.0);
    (0..4000)
        .map(|_| {
            let motion = WristMotion {
                q_rad: core::array::from_fn(|_| 0.8 * next()),
                qd_rad_s: core::array::from_fn(|_| 2.0 * next()),
                qdd_rad_s2: core::array::from_fn(|_| 20.0 * next()),
            };
            let y = regressor(
                &params.geometry,
                truth.gravity_m_s2,
                truth.sign_speed_rad_s,
                &motion,
            );
            let tau = truth.torque_nm(&params.geometry, &motion);
            let more = extra(&motion);
            (
                y.map(|r| r.map(f64::from)),
                core::array::from_fn(|j| f64::from(tau[j] + more[j])),
            )
        })
        .unzip()
}

/// The fit's setting for `params` held as `truth` says.
fn setting(params: &WristParams, truth: &InverseDynamics) -> Eq3Setting {
    Eq3Setting {
        geometry: params.geometry,
        sign_speed_rad_s: truth.sign_speed_rad_s,
        gravity_m_s2: truth.gravity_m_s2.map(f64::from),
        timing: params.eq3_timing(),
    }
}

fn wrist() -> WristParams {
    WristParams::uniform(PlantParams::default(), Config::default())
}

/// A heavy wrist's links (a thousand times the prototype's masses) and
/// some friction: the model that made the torques.
fn heavy(params: &WristParams) -> InverseDynamics {
    let links = Links::prototype().scaled(1000.0);
    let mut p = [0.0f32; N_PARAMS];
    for (x, v) in p.iter_mut().zip(links.base_params(&params.geometry)) {
        *x = v as f32;
    }
    p[N_LINKS..].copy_from_slice(&[2e-3, 1e-3, -1e-3, 5e-4, 3e-3, -2e-4, 1e-3, 0.0]);
    InverseDynamics {
        params: p,
        std_dev: [0.0; N_PARAMS],
        gravity_m_s2: links.gravity_m_s2.map(|x| x as f32),
        sign_speed_rad_s: sign_speeds_rad_s(&params.configs),
    }
}

/// On torques that Eq. 3 itself made, the fit finds its parameters again,
/// keeps the links (they are physical) and keeps the model.
#[test]
fn eq3_fit_recovers_the_parameters_of_exact_torques() {
    let params = wrist();
    let truth = heavy(&params);
    let (rows, torques) = exact_rows(&params, &truth, &|_| [0.0; 4]);
    let fit = fit_rows(&setting(&params, &truth), &rows, &torques).unwrap();
    assert!(fit.links_observed && fit.kept, "{fit:?}");
    for k in 0..N_PARAMS {
        let (got, want) = (fit.body.params[k], truth.params[k]);
        // Relative to the parameter, or to a floor for the zero friction.
        let scale = want.abs().max(if k < N_LINKS { 1e-9 } else { 1e-6 });
        assert!(
            (got - want).abs() < 1e-3 * scale,
            "parameter {k}: {got} vs {want}"
        );
    }
}

/// Torques that go against acceleration (a negative inertia on jaw A, as
/// a joint estimate that lags its motor's inertia reads) cannot be links:
/// the fit says so, leaves the links' columns out and keeps the friction.
#[test]
fn eq3_leaves_out_links_that_are_not_physical() {
    let params = wrist();
    let mut truth = heavy(&params);
    truth.params[..N_LINKS].fill(0.0);
    let (rows, torques) = exact_rows(&params, &truth, &|m| {
        [0.0, 0.0, -2e-4 * m.qdd_rad_s2[2], 0.0]
    });
    let fit = fit_rows(&setting(&params, &truth), &rows, &torques).unwrap();
    assert!(!fit.links_observed, "{fit:?}");
    assert!(fit.body.params[..N_LINKS].iter().all(|p| *p == 0.0));
    assert!(fit.pct_sigma[..N_LINKS].iter().all(|p| p.is_nan()));
    for k in N_LINKS..N_PARAMS {
        let (got, want) = (fit.body.params[k], truth.params[k]);
        assert!(
            (got - want).abs() < 0.05 * 3e-3,
            "parameter {k}: {got} vs {want}"
        );
    }
}

/// On the simulated wrist with the prototype's links and the default
/// plant's true parameters, the links are too light to see (the fit
/// leaves them out), and the friction Eq. 3 learns on the identification
/// run cuts the joints' no-load error on a free run with other amplitudes
/// and frequencies to under 30 % (read through the estimates' low-pass on
/// a faster observer's motion; the regressor on the motion of an observer
/// at the low-pass's bandwidth, unfiltered, left about 45 %); the bound
/// holds the true zero at least as often as the estimate's own.
#[test]
fn eq3_learned_on_one_free_run_cuts_the_no_load_error_on_another() {
    let (params, links) = prototype_wrist();
    let id = run_free(&params, &FreeRun::identification(), 1).unwrap();
    let fit = fit_inverse_dynamics(&params, &id, links.gravity_m_s2).unwrap();
    eprintln!("{fit:?}");
    assert!(!fit.links_observed, "{fit:?}");
    assert!(fit.kept, "{fit:?}");
    let n = unseen_no_load(&params, fit.model());
    assert!(
        mean(n.corrected_rms_n) < 0.3 * mean(n.raw_rms_n),
        "{:?} vs {:?}",
        n.corrected_rms_n,
        n.raw_rms_n
    );
    for j in 0..4 {
        assert!(n.coverage[j] >= n.raw_coverage[j], "joint {j}: {n:?}");
        assert!(
            n.links_rms_n[j] < 0.02,
            "joint {j}: the links are light: {n:?}"
        );
    }
}

/// The default plant's wrist with its true parameters (the oracle
/// configuration) and the prototype's links.
fn prototype_wrist() -> (WristParams, Links) {
    let p = PlantParams::default();
    let c = scenario::oracle_config(&p, &scenario::tuned_gains(&Config::default()));
    let links = Links::prototype();
    let params = WristParams {
        links: Some(links),
        ..WristParams::uniform(p, c)
    };
    (params, links)
}

/// The no-load figures of the validation run on `params` with `model`
/// taken out.
fn unseen_no_load(params: &WristParams, model: Option<Eq3Model>) -> NoLoad {
    let params = WristParams {
        inverse_dynamics: model,
        ..params.clone()
    };
    let val = run_free(&params, &FreeRun::validation(), 2).unwrap();
    let n = no_load(&params, &val);
    eprintln!("{n:?}");
    n
}

fn mean(x: [f64; 4]) -> f64 {
    x.iter().sum::<f64>() / 4.0
}

/// The designed excitation (seed 001 Sect. 2.3 for Eq. 3's regressor) runs
/// on the simulated wrist within the limits of the hand-made run without a
/// fault, and the model it gives cuts the no-load error on a run neither
/// saw. (Whether the fit on it is better conditioned than the fit on the
/// hand-made run is measured per plant in the report, not asserted: the
/// design minimises the condition number predicted from its references,
/// the fit sees the joints' actual motion, which sticks and slips at low
/// speed (the next test), and on this plant the measured one came out 5.83
/// against 5.61.)
#[test]
fn the_designed_wrist_excitation_runs_and_its_model_cuts_the_no_load_error() {
    let (params, links) = prototype_wrist();
    let opts = WristDesignOptions {
        base_freq_hz: 0.25,
        periods: 5,
        restarts: 1,
        ..WristDesignOptions::replacing_free_run()
    };
    let design = excite_wrist::design(&opts).unwrap();
    let hand = FreeRun::identification();
    assert_eq!(design.duration_s, hand.duration_s, "equal length");
    let ticks = run_free(&params, &FreeRun::designed(&design), 1).unwrap();
    let b = fit_inverse_dynamics(&params, &ticks, links.gravity_m_s2).unwrap();
    eprintln!("designed {b:?}");
    assert!(b.kept, "{b:?}");
    let n = unseen_no_load(&params, b.model());
    assert!(
        mean(n.corrected_rms_n) < mean(n.raw_rms_n),
        "{:?} vs {:?}",
        n.corrected_rms_n,
        n.raw_rms_n
    );
}

/// Why a design's predicted conditioning does not reach the fit (README,
/// "Eq. 3's designed excitation"): through the same motion observer and
/// `Q`, the commanded angles' friction sign keeps about the regressor's own
/// width, while the simulated joints' actual motion, which sticks and slips
/// at low speed, shows a sign several times wider, so its
/// Coulomb column follows its speed where the design counted on them
/// parting. On the hand-made run and the default plant.
#[test]
fn the_joints_actual_motion_widens_the_friction_sign_the_fit_sees() {
    let (params, _) = prototype_wrist();
    let run = FreeRun::identification();
    let ticks = run_free(&params, &run, 1).unwrap();
    let actual: Vec<Eq3Sample> = ticks
        .iter()
        .map(|t| Eq3Sample::of_tick(&params, t))
        .collect();
    let commanded: Vec<Eq3Sample> = ticks
        .iter()
        .zip(&actual)
        .map(|(t, s)| Eq3Sample {
            theta_hat_rad: core::array::from_fn(|j| t.outputs[j].est.theta_ref_rad),
            ..*s
        })
        .collect();
    let setting = Eq3Setting {
        geometry: params.geometry,
        sign_speed_rad_s: sign_speeds_rad_s(&params.configs),
        gravity_m_s2: [0.0, 0.0, -9.81],
        timing: params.eq3_timing(),
    };
    let bandwidth_hz = 3.0 * setting.timing.q_bandwidth_hz();
    let seen = sign_width_seen_rad_s(&filtered_rows(&setting, &actual, bandwidth_hz));
    let asked = sign_width_seen_rad_s(&filtered_rows(&setting, &commanded, bandwidth_hz));
    eprintln!(
        "sign width seen: actual {seen:?}, commanded {asked:?}, v_s {:?}",
        setting.sign_speed_rad_s
    );
    for j in 0..4 {
        let v_s = f64::from(setting.sign_speed_rad_s[j]);
        assert!(asked[j] < 2.0 * v_s, "joint {j}: commanded {asked:?}");
        assert!(seen[j] > 3.0 * v_s, "joint {j}: actual {seen:?}");
    }
}

/// `host-sim excite --wrist` writes the wrist's design and, for each
/// joint's controller, the same series in the single joint's format (what
/// `--scenario excite --excitation` loads); it refuses the single joint's
/// options by name.
#[test]
fn excite_wrist_writes_the_design_and_a_file_per_joint_the_firmware_runs() {
    let dir = tempfile::tempdir().unwrap();
    // A dot in the stem stays in the per-joint files' names.
    let out = dir.path().join("w.v2.toml");
    let run = |extra: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_host-sim"))
            .args([
                "excite",
                "--wrist",
                "--base-freq-hz",
                "0.25",
                "--restarts",
                "1",
            ])
            .args(extra)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap()
    };
    let o = run(&[]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(stdout.contains("predicted condition number"), "{stdout}");
    let design: WristDesign = toml::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(design.duration_s, FreeRun::identification().duration_s);
    for (j, name) in ["roll", "pitch", "jaw_a", "jaw_b"].iter().enumerate() {
        let joint = excite::load(&dir.path().join(format!("w.v2.{name}.toml"))).unwrap();
        assert_eq!(joint.trajectory, design.trajectories[j], "{name}");
        assert_eq!(joint.duration_s, design.duration_s, "{name}");
    }
    let o = run(&["--like", "jae-ident"]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        stderr.contains("'--wrist' cannot be used with '--like"),
        "{stderr}"
    );
}
