//! The simulated four-joint wrist (`host_sim::wrist`): the clamp force of
//! seed 000 Eq. 4-5, from the four joints' fused estimates, against the true
//! contact force of a soft object between the jaws.

use cable_joint::Config;
use host_sim::plant::PlantParams;
use host_sim::scenario;
use host_sim::wrist::{grasp_stats, run_grasp, Grasp, Phase, SoftObject, WristParams};

fn params(probing: bool) -> WristParams {
    let p = PlantParams::default();
    let mut c = scenario::oracle_config(&p, &scenario::tuned_gains(&Config::default()));
    c.probe.enabled = probing;
    WristParams::uniform(p, c)
}

fn soft() -> SoftObject {
    SoftObject {
        width_m: 10e-3,
        stiffness_n_m: 1000.0,
        damping_n_s_m: 0.5,
    }
}

/// Holding a 2 N squeeze on the default plant with its true parameters,
/// the clamp estimate's hold mean is within 15 % of the true contact force
/// (the report measures 92 % to 99 % with identified parameters; the
/// pin's friction band at the tip, 0.2 N, is 10 % of 2 N), and the bound
/// holds the true force on at least 95 % of the hold's ticks.
#[test]
fn the_clamp_force_estimate_follows_the_true_squeeze_while_holding() {
    let ticks = run_grasp(&params(false), soft(), &Grasp::default(), 11).unwrap();
    let s = grasp_stats(&ticks);
    eprintln!("{s:?}");
    assert_eq!(s.fault, None);
    assert!(s.hold_true_n > 1.0, "the jaws squeeze the object: {s:?}");
    assert!(s.hold_accuracy_pct >= 85.0, "{s:?}");
    assert!(s.hold_coverage >= 0.95, "{s:?}");
    // Jaws open: no contact, and the bound allows no squeeze on at least
    // 95 % of those ticks (the estimate itself wanders inside the friction
    // bands: 0.49 N at most here).
    let open: Vec<_> = ticks.iter().filter(|(p, _)| *p == Phase::Open).collect();
    assert!(open.iter().all(|(_, t)| t.contact_n == 0.0));
    let zero_inside = open
        .iter()
        .filter(|(_, t)| t.clamp_bound_n.contains(0.0))
        .count();
    assert!(
        zero_inside as f64 >= 0.95 * open.len() as f64,
        "{zero_inside} of {}",
        open.len()
    );
}

/// A squeeze is an internal force of the wrist: the roll and pitch joints
/// carry none of it, and their estimates stay near zero while the jaws'
/// read the squeeze.
#[test]
fn a_squeeze_loads_the_jaws_and_not_the_shared_joints() {
    let ticks = run_grasp(&params(false), soft(), &Grasp::default(), 12).unwrap();
    let hold: Vec<_> = ticks.iter().filter(|(p, _)| *p == Phase::Hold).collect();
    let half = &hold[hold.len() / 2..];
    let mean = |j: usize| {
        half.iter()
            .map(|(_, t)| f64::from(t.outputs[j].est.f_ext_fused_n))
            .sum::<f64>()
            / half.len() as f64
    };
    let contact = half.iter().map(|(_, t)| t.contact_n).sum::<f64>() / half.len() as f64;
    for j in [host_sim::wrist::ROLL, host_sim::wrist::PITCH] {
        assert!(mean(j).abs() < 0.3, "joint {j} reads {}", mean(j));
    }
    for j in [host_sim::wrist::JAW_A, host_sim::wrist::JAW_B] {
        assert!(
            (mean(j) - contact).abs() < 0.3 * contact,
            "jaw {j}: {} vs {contact}",
            mean(j)
        );
    }
}

/// An object wider than the open jaws is refused with a clear error.
#[test]
fn an_object_that_does_not_fit_is_refused() {
    let mut o = soft();
    o.width_m = 20e-3;
    let e = run_grasp(&params(false), o, &Grasp::default(), 1).unwrap_err();
    assert!(format!("{e:#}").contains("does not fit"), "{e:#}");
}
