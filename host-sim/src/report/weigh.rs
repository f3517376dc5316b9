//! The force scale from known weights on every report variant, the user's
//! step after identification (`identify --procedure weights`, README, "The
//! force scale from known weights"): the grip and the wrist sections run
//! their default way a second time with the configuration it writes
//! ("weighed").

use anyhow::{Context, Result};
use cable_joint::Config;
use serde::Serialize;

use super::programme::run_seed;
use super::variants::VariantResult;
use crate::ident::{calibrate_weights, WeightsOptions};
use crate::scenario::{self, Direction, ScenarioOptions};
use crate::sim::LogRecorder;

/// The force scale from known weights on one variant: holds at 0° with
/// [`WEIGHT_HOLDS_G`] each way, recorded with the configuration as
/// identified (probing off), a row every tick.
#[derive(Clone, Debug, Serialize)]
pub struct Weighing {
    /// Plant variant.
    pub variant: String,
    /// The stretch estimate's change per unit of the weights' and its
    /// `%sigma`; `None` when the calibration was refused.
    pub scale: Option<(f64, f64)>,
    /// `machine.spring_n_m` before and after, N/m (unchanged when refused).
    pub spring_n_m: (f64, f64),
    /// The plant's spring, N/m: the simulator's truth, which a calibrated
    /// scale should bring the rate toward (the two cables' stiffnesses
    /// drawn apart move it off that).
    pub plant_spring_n_m: f64,
    /// `fusion.stiffness_tolerance` before and after.
    pub stiffness_tolerance: (f64, f64),
    /// `fusion.pin_coulomb_nm` before and after, N·m, when it is a fitted
    /// level (the weights rescale it with the stiffnesses; unchanged when
    /// refused); `None` when it is model C's upper bound.
    pub pin_coulomb_nm: Option<(f64, f64)>,
    /// The plant's pin friction, kinetic and static, N·m (the simulator's
    /// truth).
    pub plant_pin_nm: (f64, f64),
    /// Why the calibration was refused (empty when it was written).
    pub refused: String,
}

/// The weights hung for [`Weighing`], g: the seed's two heavier loads.
pub const WEIGHT_HOLDS_G: [f64; 2] = [100.0, 250.0];

/// `config` as it stands on `v`, nothing calibrated yet.
fn unweighed(v: &VariantResult, config: &Config) -> Weighing {
    let spring = f64::from(config.machine.spring_n_m);
    let tolerance = f64::from(config.fusion.stiffness_tolerance);
    Weighing {
        variant: v.name.clone(),
        scale: None,
        spring_n_m: (spring, spring),
        plant_spring_n_m: v.plant.spring.stiffness_n_m,
        stiffness_tolerance: (tolerance, tolerance),
        pin_coulomb_nm: config.fusion.pin_identified.then(|| {
            let pin = f64::from(config.fusion.pin_coulomb_nm);
            (pin, pin)
        }),
        plant_pin_nm: (v.plant.joint.coulomb_nm, v.plant.joint.static_nm),
        refused: String::new(),
    }
}

/// Hold [`WEIGHT_HOLDS_G`] at 0° both ways on `v`'s plant with `config`,
/// and calibrate the force scale on them; the configuration the user ends
/// up with (unchanged when the calibration is refused).
fn weigh(v: &VariantResult, config: &Config, base_seed: u64) -> Result<(Weighing, Config)> {
    let mut logs = Vec::new();
    for mass_g in WEIGHT_HOLDS_G {
        for direction in [Direction::Pos, Direction::Neg] {
            // The seed's label from when only the grip section weighed
            // (kept, so the holds' noise and every weighed figure stay).
            let label = format!("grip/weights/{}/{mass_g}/{direction:?}", v.name);
            let opts = ScenarioOptions {
                angle_deg: Some(0.0),
                mass_g: Some(mass_g),
                direction: Some(direction),
                ..ScenarioOptions::default()
            };
            let mut rec = LogRecorder::new(false);
            scenario::run(
                "loading",
                v.plant,
                *config,
                Some(run_seed(base_seed, &label)),
                &opts,
                &mut rec,
            )
            .with_context(|| label.clone())?;
            let log = rec.to_log().with_context(|| label.clone())?;
            logs.push((label, log));
        }
    }
    let fit: Vec<(&str, &crate::log::Log)> = logs.iter().map(|(l, g)| (l.as_str(), g)).collect();
    let mut w = unweighed(v, config);
    match calibrate_weights(&fit, &[], config, &WeightsOptions::default()) {
        Ok((f, calibrated)) => {
            w.scale = Some(f.scale);
            w.spring_n_m = f.spring_n_m;
            w.stiffness_tolerance = f.stiffness_tolerance;
            w.pin_coulomb_nm = f.pin_coulomb_nm;
            Ok((w, calibrated))
        }
        Err(e) => {
            w.refused = format!("{e:#}");
            Ok((w, *config))
        }
    }
}

/// What [`run_all`] found for one variant: the calibration and the
/// configuration the user ends up with (probing off; as identified when
/// the calibration was refused).
#[derive(Clone, Debug)]
pub struct Weighed {
    /// The calibration.
    pub weighing: Weighing,
    /// The configuration after it.
    pub config: Config,
}

/// Weigh every variant with an identified configuration, in order (`None`
/// where there is none). A variant whose weight holds did not run is
/// recorded as refused, with the reason.
pub fn run_all(variants: &[VariantResult], base_seed: u64) -> Vec<Option<Weighed>> {
    variants
        .iter()
        .map(|v| {
            let mut config = v.config?;
            config.probe.enabled = false;
            Some(match weigh(v, &config, base_seed) {
                Ok((weighing, config)) => Weighed { weighing, config },
                Err(e) => {
                    let mut weighing = unweighed(v, &config);
                    weighing.refused = format!("the weight holds did not run: {e:#}");
                    Weighed { weighing, config }
                }
            })
        })
        .collect()
}
