//! The fused force bound and the slack check on drawn plants the project
//! was not tuned on (every force-path parameter ±30 %, `report::variants::
//! drawn`), identified from their own calibration runs and run through the
//! seed's loading protocol, passive and with probing, as the report does.
//!
//! Draws 25 and 39 come from a set of twenty (`host-sim report --draws
//! 21-40`) run after the ten report variants, to test the bound out of
//! sample. With the cables'
//! stiffness scale taken as exact, draw 25's bound covered 90.1 % of the hold
//! samples and draw 39 latched two false slack faults (cable 1 read below
//! its limit while it carried 8.1 and 8.4 N): its spring is 28 % softer than
//! the datasheet, and the calibration run's spring fit (479 N/m, %sigma 5.1)
//! was too loose to replace it.

use host_sim::report::programme::Settings;
use host_sim::report::variants::{drawn_variants, run_variant, VariantResult};
use host_sim::report::wrist::{object, STIFFNESS_N_M};
use host_sim::wrist::{grasp_stats, run_grasp, Grasp, WristParams};

/// One drawn plant as `host-sim report --draws N-N` runs it (odd seeds at
/// 2 kHz).
fn run(seed: u64) -> VariantResult {
    let v = &drawn_variants(seed, seed, None)[0];
    let s = Settings::quiet();
    let r = run_variant(v, &s);
    assert_eq!(r.error, None, "draw {seed}: identification failed");
    r
}

/// The bound carries the stiffness scale's uncertainty (the datasheet
/// spring's tolerance, widened to the calibration fit's disagreement with
/// it): it covers the load in at least 95 % of the hold samples, passive and
/// with probing, and no fault latches that the plant's state does not
/// confirm.
#[test]
fn on_drawn_plants_the_bound_covers_the_load_and_no_fault_is_false() {
    for seed in [25, 39] {
        let r = run(seed);
        let probing = r.probing.as_ref().expect("probing ran");
        for (mode, p) in [("passive", &r.passive), ("probing", probing)] {
            assert!(
                p.coverage >= 0.95,
                "draw {seed} {mode}: coverage {:.1} %; notes {:?}",
                100.0 * p.coverage,
                r.notes
            );
            assert_eq!(
                p.false_faults, 0,
                "draw {seed} {mode}: false faults {:?}",
                p.faults
            );
        }
    }
}

/// The wrist's clamp force (seed 000 Eq. 4-5, each joint's fused bound
/// carried through by interval arithmetic) on drawn plants no figure of the
/// project was measured on, 2 kHz and 1 kHz, every joint with the
/// configuration identified on its plant: while the jaws hold a soft and a
/// ten times firmer object at 2 N, the clamp bound holds the true contact
/// force on at least 95 % of the hold's ticks (issue 14's coverage goal),
/// and no joint latches a fault.
#[test]
fn on_drawn_plants_the_clamp_force_bound_holds_the_true_squeeze() {
    for seed in [97, 98] {
        let r = run(seed);
        let config = r.config.expect("an identified configuration");
        let params = WristParams::uniform(r.plant, config);
        for k in STIFFNESS_N_M {
            let ticks = run_grasp(&params, object(k), &Grasp::default(), seed).unwrap();
            let s = grasp_stats(&params.geometry, &ticks);
            eprintln!("draw {seed} ({} Hz), {k} N/m: {s:?}", r.rate_hz);
            assert_eq!(s.fault, None, "draw {seed}, {k} N/m");
            assert!(
                s.hold_true_n > 1.0,
                "draw {seed}, {k} N/m: the jaws squeeze: {s:?}"
            );
            assert!(
                s.hold_coverage >= 0.95,
                "draw {seed}, {k} N/m: the bound holds the squeeze on {:.1} % of the hold",
                100.0 * s.hold_coverage
            );
        }
    }
}
