//! The loading protocol summarised like the seed's Sect. 4.3: no-load
//! estimates, accuracy per class of weights and angles, the largest angle
//! errors under load.

use serde::Serialize;

use crate::report::experiments::LoadCase;
use crate::stats::{band, Summary};

/// Accuracy over a class of loading cases.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct AccuracyStats {
    /// Cases counted (not faulted).
    pub cases: usize,
    /// Faulted cases in the class (not counted).
    pub faulted: usize,
    /// Worst case, %.
    pub min_pct: f64,
    /// Mean over the cases, %.
    pub mean_pct: f64,
}

impl AccuracyStats {
    fn of<'a>(cases: impl IntoIterator<Item = &'a LoadCase>) -> Self {
        let (mut n, mut faulted, mut sum, mut min) = (0usize, 0usize, 0.0, f64::INFINITY);
        for c in cases {
            if c.fault.is_some() || !c.accuracy_pct.is_finite() {
                faulted += 1;
                continue;
            }
            n += 1;
            sum += c.accuracy_pct;
            min = min.min(c.accuracy_pct);
        }
        Self {
            cases: n,
            faulted,
            min_pct: if n > 0 { min } else { f64::NAN },
            mean_pct: if n > 0 { sum / n as f64 } else { f64::NAN },
        }
    }
}

/// Weights counted as "above 1 N": 100 g (0.98 N) and heavier.
pub fn above_1n(c: &LoadCase) -> bool {
    c.mass_g >= 100.0
}

/// The weight counted as "0.3 N": 30 g (0.29 N).
pub fn at_0n3(c: &LoadCase) -> bool {
    c.mass_g == 30.0
}

/// The loading protocol summarised like the seed's Sect. 4.3.
#[derive(Clone, Debug, Serialize)]
pub struct LoadingSummary {
    /// Cases run.
    pub cases: usize,
    /// Cases that latched a fault (left out of every figure below).
    pub faulted: usize,
    /// Faulted cases, described.
    pub faults: Vec<String>,
    /// Static no-load estimate, all angles, N.
    pub static_noload_n: Summary,
    /// Static no-load estimate at 0°, N.
    pub static_noload_0_n: Summary,
    /// Static no-load estimate at 30° and -40°, N.
    pub static_noload_30_m40_n: Summary,
    /// Dynamic no-load estimate (moving to 30°/-40° and settling) in the
    /// runs loaded in the positive direction, N.
    pub dynamic_noload_pos_n: Summary,
    /// The same in the runs loaded in the negative direction, N.
    pub dynamic_noload_neg_n: Summary,
    /// Accuracy, weights >= 100 g, all angles.
    pub above_1n: AccuracyStats,
    /// Accuracy, 30 g, all angles.
    pub at_0n3: AccuracyStats,
    /// Accuracy, weights >= 100 g, at 0°.
    pub above_1n_0: AccuracyStats,
    /// Accuracy, 30 g, at 0°.
    pub at_0n3_0: AccuracyStats,
    /// Accuracy, weights >= 100 g, at 30° and -40°.
    pub above_1n_30_m40: AccuracyStats,
    /// Accuracy, 30 g, at 30° and -40°.
    pub at_0n3_30_m40: AccuracyStats,
    /// Largest |desired − actual| with a load on, at 0°, °.
    pub max_angle_error_0_deg: f64,
    /// The same at 30° and -40°, °.
    pub max_angle_error_30_m40_deg: f64,
}

impl LoadingSummary {
    /// Summarise the cases.
    pub fn of(cases: &[LoadCase]) -> Self {
        let ok = |c: &&LoadCase| c.fault.is_none();
        let zero = |c: &&LoadCase| c.angle_deg == 0.0;
        let off = |c: &&LoadCase| c.angle_deg != 0.0;
        let max_angle = |f: &dyn Fn(&&LoadCase) -> bool| {
            cases
                .iter()
                .filter(ok)
                .filter(f)
                .map(|c| c.angle_error_loaded_deg.max_abs())
                .fold(f64::NAN, f64::max)
        };
        let dynamic = |dir: &str| {
            band(
                cases
                    .iter()
                    .filter(ok)
                    .filter(|c| c.direction == dir)
                    .filter_map(|c| c.dynamic_noload_n.as_ref()),
            )
        };
        let faults: Vec<String> = cases
            .iter()
            .filter_map(|c| {
                c.fault
                    .as_ref()
                    .map(|f| format!("{}° {} g {}: {f}", c.angle_deg, c.mass_g, c.direction))
            })
            .collect();
        Self {
            cases: cases.len(),
            faulted: faults.len(),
            faults,
            static_noload_n: band(cases.iter().filter(ok).map(|c| &c.static_noload_n)),
            static_noload_0_n: band(
                cases
                    .iter()
                    .filter(ok)
                    .filter(zero)
                    .map(|c| &c.static_noload_n),
            ),
            static_noload_30_m40_n: band(
                cases
                    .iter()
                    .filter(ok)
                    .filter(off)
                    .map(|c| &c.static_noload_n),
            ),
            dynamic_noload_pos_n: dynamic("pos"),
            dynamic_noload_neg_n: dynamic("neg"),
            above_1n: AccuracyStats::of(cases.iter().filter(|c| above_1n(c))),
            at_0n3: AccuracyStats::of(cases.iter().filter(|c| at_0n3(c))),
            above_1n_0: AccuracyStats::of(cases.iter().filter(zero).filter(|c| above_1n(c))),
            at_0n3_0: AccuracyStats::of(cases.iter().filter(zero).filter(|c| at_0n3(c))),
            above_1n_30_m40: AccuracyStats::of(cases.iter().filter(off).filter(|c| above_1n(c))),
            at_0n3_30_m40: AccuracyStats::of(cases.iter().filter(off).filter(|c| at_0n3(c))),
            max_angle_error_0_deg: max_angle(&zero),
            max_angle_error_30_m40_deg: max_angle(&off),
        }
    }
}
