//! Identification excitation for the wrist's Eq. 3 (seed 001 Sect. 2.3
//! applied to seed 000 Eq. 3): one Fourier series per joint
//! ([`Trajectory::Fourier`], the same series [`super::excite`] designs for
//! one joint and the firmware runs), the four designed together to
//! minimise the condition number of Eq. 3's regressor
//! ([`cable_joint::wrist_dynamics::regressor`], fifteen columns: the links'
//! seven base parameters and each joint's Coulomb and viscous friction)
//! under each joint's angle, velocity and acceleration limits, taken from
//! the hand-made run it replaces at that run's length.
//!
//! # What differs from one joint
//!
//! The regressor is not linear in the motion (gravity turns with roll and
//! pitch, the Coriolis terms are products of speeds, the friction's sign
//! is `tanh(q'/v_s)`), so its conditioning depends on each joint's scale:
//! every joint's series is scaled to its own tightest limit *before* its
//! rows are computed, and the search sees the scaled runs. The columns are
//! predicted from the references, the accelerations by the same central
//! difference as [`super::excite`]; the condition number is the core's
//! ([`BatchLsq::solve`](cable_joint::lsq::BatchLsq::solve), column-equilibrated). The forty coefficients are
//! searched by the same Nelder–Mead from seeded random starts, at each of
//! [`BASE_FREQS_HZ`](super::excite::BASE_FREQS_HZ) rounded to whole periods of the run. Deterministic
//! for a seed.
//!
//! # What it cannot promise
//!
//! A condition number weighs the columns' directions, not their size: at
//! the prototype's scale the links' torques are millinewtons at the tips
//! ([`crate::links`]), so a design that decorrelates their columns does not
//! make them observable; the report measures what the fits make of it.

use anyhow::{ensure, Result};
use cable_joint::trajectory::Trajectory;
use cable_joint::wrist::Geometry;
use cable_joint::wrist_dynamics::{regressor, WristMotion, N_PARAMS};
use serde::{Deserialize, Serialize};

use crate::links::{sign_speeds_rad_s, FreeRun, Links};
use crate::plant::PlantParams;
use crate::wrist::WristParams;

use super::excite::{
    at_rest, best_over_periods, condition_of_rows, envelope, envelope_of, samples, scaled, search,
    Envelope, PairBound, Sample, DIM, PREDICTION_RATE_HZ,
};

/// Joints of the wrist (roll, pitch, jaw A, jaw B).
const JOINTS: usize = 4;
/// Coefficients of the four series.
const WRIST_DIM: usize = JOINTS * DIM;
/// Samples per period of the search's objective (the fifth harmonic gets
/// 25: enough for a condition number, which [`WristDesign::condition`]
/// then states at [`PREDICTION_RATE_HZ`] over the whole run).
const SAMPLES_PER_PERIOD: f64 = 125.0;
/// Evaluations per start of the search (forty coefficients).
const EVALUATIONS_PER_START: usize = 6000;

/// What Eq. 3's regressor needs besides the motion.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Eq3Shape {
    /// The wrist's dimensions.
    pub geometry: Geometry,
    /// Gravity in the shaft's frame, m/s².
    pub gravity_m_s2: [f32; 3],
    /// Each joint's smooth-sign width, rad/s.
    pub sign_speed_rad_s: [f32; 4],
}

impl Eq3Shape {
    /// Condition number of the equilibrated regressor of the four joints'
    /// references `runs` over `duration_s` sampled at `rate_hz` (infinite
    /// when a column is all zero).
    pub fn condition(&self, runs: &[Trajectory; JOINTS], duration_s: f64, rate_hz: f64) -> f64 {
        let per_joint = runs.map(|tr| samples(&[(tr, duration_s)], rate_hz));
        self.condition_of(&per_joint)
    }

    /// The pair of columns of the equilibrated regressor of `runs` that
    /// bounds its condition number from below ([`PairBound`], its columns
    /// indices into [`PARAM_NAMES`](cable_joint::wrist_dynamics::PARAM_NAMES)).
    pub fn pair_bound(
        &self,
        runs: &[Trajectory; JOINTS],
        duration_s: f64,
        rate_hz: f64,
    ) -> PairBound {
        let per_joint = runs.map(|tr| samples(&[(tr, duration_s)], rate_hz));
        let mut gram = nalgebra::SMatrix::<f64, N_PARAMS, N_PARAMS>::zeros();
        self.for_each_row(&per_joint, |row| {
            let phi = nalgebra::SVector::<f64, N_PARAMS>::from(row.map(f64::from));
            gram += phi * phi.transpose();
        });
        PairBound::of_gram(&gram)
    }

    /// Each regressor row of the four joints' samples.
    fn for_each_row(&self, per_joint: &[Vec<Sample>; JOINTS], mut f: impl FnMut(&[f32; N_PARAMS])) {
        let n = per_joint.iter().map(Vec::len).min().unwrap_or(0);
        for i in 0..n {
            let s = |f: fn(&Sample) -> f64| per_joint.each_ref().map(|x| f(&x[i]) as f32);
            let motion = WristMotion {
                q_rad: s(|x| x.angle_rad),
                qd_rad_s: s(|x| x.vel_rad_s),
                qdd_rad_s2: s(|x| x.acc_rad_s2),
            };
            let y = regressor(
                &self.geometry,
                self.gravity_m_s2,
                self.sign_speed_rad_s,
                &motion,
            );
            y.iter().for_each(&mut f);
        }
    }

    fn condition_of(&self, per_joint: &[Vec<Sample>; JOINTS]) -> f64 {
        condition_of_rows::<N_PARAMS>(|push| {
            self.for_each_row(per_joint, |row| push(&row.map(f64::from)));
        })
    }
}

/// What [`design`] designs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WristDesignOptions {
    /// The regressor's geometry, gravity and sign widths.
    pub shape: Eq3Shape,
    /// Each joint's limits (angle from the start, velocity, acceleration).
    pub limits: [Envelope; JOINTS],
    /// Fundamental frequency, Hz.
    pub base_freq_hz: f64,
    /// Whole periods the run lasts.
    pub periods: u32,
    /// Random starts of the search.
    pub restarts: u32,
    /// Seed of the random starts.
    pub seed: u64,
}

impl WristDesignOptions {
    /// The design that replaces the hand-made run `references` of
    /// `duration_s`: each joint's envelope its limits, seed 001's 0.1 Hz,
    /// as many whole periods as fit.
    pub fn replacing(shape: Eq3Shape, references: &[Trajectory; JOINTS], duration_s: f64) -> Self {
        let base_freq_hz = 0.1;
        Self {
            shape,
            limits: references.map(|tr| envelope(&[(tr, duration_s)], PREDICTION_RATE_HZ)),
            base_freq_hz,
            periods: ((duration_s * base_freq_hz).floor() as u32).max(1),
            restarts: 2,
            seed: 1,
        }
    }

    /// [`Self::replacing`] the hand-made free run
    /// ([`FreeRun::identification`]) for the default configuration's wrist
    /// (its geometry and sign widths) under the prototype links' gravity:
    /// what `host-sim excite --wrist` and the report design.
    pub fn replacing_free_run() -> Self {
        let params = WristParams::uniform(PlantParams::default(), cable_joint::Config::default());
        let shape = Eq3Shape {
            geometry: params.geometry,
            gravity_m_s2: Links::prototype().gravity_m_s2.map(|x| x as f32),
            sign_speed_rad_s: sign_speeds_rad_s(&params.configs),
        };
        let hand = FreeRun::identification();
        Self::replacing(shape, &hand.trajectories, hand.duration_s)
    }

    /// Length of the designed run, s.
    pub fn duration_s(&self) -> f64 {
        f64::from(self.periods) / self.base_freq_hz
    }

    fn check(&self) -> Result<()> {
        ensure!(
            self.base_freq_hz.is_finite() && self.base_freq_hz > 0.0 && self.base_freq_hz <= 10.0,
            "the wrist excitation's base frequency must be in (0, 10] Hz, got {}",
            self.base_freq_hz
        );
        ensure!(
            self.periods >= 1,
            "the wrist excitation needs at least one period"
        );
        for (j, l) in self.limits.iter().enumerate() {
            l.check_as_limits(&format!("the wrist excitation's joint {j}:"))?;
        }
        ensure!(
            self.restarts >= 1,
            "the wrist excitation's search needs at least one start"
        );
        Ok(())
    }
}

/// A designed wrist excitation.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WristDesign {
    /// Each joint's series (roll, pitch, jaw A, jaw B), starting at 0 rad
    /// at rest.
    pub trajectories: [Trajectory; JOINTS],
    /// The run's length (whole periods), s.
    pub duration_s: f64,
    /// Predicted condition number over the run at [`PREDICTION_RATE_HZ`].
    pub condition: f64,
    /// Each joint's envelope: its tightest limit is reached.
    pub envelopes: [Envelope; JOINTS],
    /// Objective evaluations the search made.
    pub evaluations: u64,
}

/// The four series of coefficients `p`, each at rest and scaled to its
/// joint's limits (a thousandth below: the sampled peak is within 1e-4 of
/// the true one), with their samples over one period at `rate_hz`; `None`
/// if a series does not move.
fn series(
    p: &[f64; WRIST_DIM],
    opts: &WristDesignOptions,
    rate_hz: f64,
) -> Option<([Trajectory; JOINTS], [Vec<Sample>; JOINTS])> {
    let period_s = 1.0 / opts.base_freq_hz;
    let mut runs = [Trajectory::Hold { angle_rad: 0.0 }; JOINTS];
    let mut per_joint: [Vec<Sample>; JOINTS] = Default::default();
    for j in 0..JOINTS {
        let coefficients: [f64; DIM] = std::array::from_fn(|i| p[j * DIM + i]);
        let unit = at_rest(&coefficients, opts.base_freq_hz);
        let mut s = samples(&[(unit, period_s)], rate_hz);
        let by = envelope_of(&s).room_in(&opts.limits[j]) * 0.999;
        if !(by.is_finite() && by > 0.0) {
            return None;
        }
        // The series is linear in its coefficients: so are its samples.
        for x in &mut s {
            x.angle_rad *= by;
            x.vel_rad_s *= by;
            x.acc_rad_s2 *= by;
        }
        runs[j] = scaled(unit, by);
        per_joint[j] = s;
    }
    Some((runs, per_joint))
}

/// `log10` of the predicted condition number of the scaled series of `p`,
/// over one period.
fn objective(p: &[f64; WRIST_DIM], opts: &WristDesignOptions) -> f64 {
    let Some((_, per_joint)) = series(p, opts, SAMPLES_PER_PERIOD * opts.base_freq_hz) else {
        return f64::MAX;
    };
    let c = opts.shape.condition_of(&per_joint);
    if c.is_finite() && c > 0.0 {
        c.log10()
    } else {
        f64::MAX
    }
}

/// Design the wrist's excitation at `opts`' base frequency: the four
/// series of least predicted condition number, each scaled to its limits.
pub fn design(opts: &WristDesignOptions) -> Result<WristDesign> {
    opts.check()?;
    let (p, _, evaluations) = search(
        &mut |p: &[f64; WRIST_DIM]| objective(p, opts),
        opts.restarts,
        opts.seed,
        EVALUATIONS_PER_START,
    );
    let rate_hz = super::excite::SAMPLES_PER_PERIOD * opts.base_freq_hz;
    let (trajectories, _) = series(&p, opts, rate_hz)
        .ok_or_else(|| anyhow::anyhow!("the designed wrist series do not move"))?;
    for (j, tr) in trajectories.iter().enumerate() {
        tr.validate().map_err(|e| {
            anyhow::anyhow!("the designed series of joint {j} is not a valid trajectory: {e}")
        })?;
    }
    let duration_s = opts.duration_s();
    Ok(WristDesign {
        trajectories,
        duration_s,
        condition: opts
            .shape
            .condition(&trajectories, duration_s, PREDICTION_RATE_HZ),
        envelopes: trajectories.map(|tr| envelope(&[(tr, duration_s)], rate_hz)),
        evaluations,
    })
}

/// [`design`] at each of [`BASE_FREQS_HZ`](super::excite::BASE_FREQS_HZ) rounded to whole periods of
/// `duration_s`; the design of least predicted condition number.
pub fn design_over_frequencies(opts: &WristDesignOptions, duration_s: f64) -> Result<WristDesign> {
    let (best, evaluations) = best_over_periods(
        duration_s,
        |n| {
            design(&WristDesignOptions {
                base_freq_hz: f64::from(n) / duration_s,
                periods: n,
                ..*opts
            })
        },
        |d| (d.condition, d.evaluations),
    )?;
    Ok(WristDesign {
        evaluations,
        ..best
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use cable_joint::wrist_dynamics::N_LINKS;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn shape() -> Eq3Shape {
        WristDesignOptions::replacing_free_run().shape
    }

    #[test]
    fn the_wrist_design_beats_the_hand_made_run_within_every_joints_limits() {
        let hand = FreeRun::identification();
        let shape = shape();
        let opts = WristDesignOptions {
            restarts: 1,
            ..WristDesignOptions::replacing(shape, &hand.trajectories, hand.duration_s)
        };
        let d = design(&opts).unwrap();
        assert_eq!(d.duration_s, hand.duration_s, "equal length");
        let before = shape.condition(&hand.trajectories, hand.duration_s, PREDICTION_RATE_HZ);
        assert!(
            d.condition < before,
            "designed {} against hand-made {before}",
            d.condition
        );
        for (j, (e, l)) in d.envelopes.iter().zip(&opts.limits).enumerate() {
            let used = [
                e.angle_rad / l.angle_rad,
                e.vel_rad_s / l.vel_rad_s,
                e.acc_rad_s2 / l.acc_rad_s2,
            ];
            assert!(used.iter().all(|&u| u <= 1.0), "joint {j}: {used:?}");
            assert!(used.iter().any(|&u| u > 0.99), "joint {j}: {used:?}");
            assert_eq!(d.trajectories[j].validate(), Ok(()), "joint {j}");
        }
    }

    /// Every pair of equilibrated columns at `|cos| = r` floors the
    /// condition number at `sqrt((1 + r) / (1 - r))`; on the hand-made run
    /// the tightest pair is one joint's Coulomb and viscous friction (its
    /// speed against its sign, as on one joint).
    #[test]
    fn the_pair_bound_floors_the_wrist_condition_and_is_a_joints_friction_pair() {
        let shape = shape();
        let hand = FreeRun::identification();
        let b = shape.pair_bound(&hand.trajectories, hand.duration_s, PREDICTION_RATE_HZ);
        let c = shape.condition(&hand.trajectories, hand.duration_s, PREDICTION_RATE_HZ);
        assert!(b.condition_at_least <= c, "{b:?} against {c}");
        let (i, k) = b.columns;
        assert!(
            i >= N_LINKS && (i - N_LINKS).is_multiple_of(2) && k == i + 1,
            "{b:?}"
        );
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let opts = WristDesignOptions::replacing(shape, &hand.trajectories, hand.duration_s);
        for _ in 0..3 {
            let p: [f64; WRIST_DIM] = std::array::from_fn(|_| rng.gen_range(-1.0..1.0));
            let (runs, _) = series(&p, &opts, 100.0).unwrap();
            let (b, c) = (
                shape.pair_bound(&runs, 20.0, PREDICTION_RATE_HZ),
                shape.condition(&runs, 20.0, PREDICTION_RATE_HZ),
            );
            assert!(
                b.condition_at_least <= c * (1.0 + 1e-9),
                "{b:?} against {c}"
            );
        }
    }

    #[test]
    fn the_wrist_design_refuses_limits_it_cannot_meet_by_joint() {
        let hand = FreeRun::identification();
        let mut opts = WristDesignOptions::replacing(shape(), &hand.trajectories, hand.duration_s);
        opts.limits[2].vel_rad_s = 0.0;
        let e = design(&opts).unwrap_err().to_string();
        assert!(e.contains("joint 2: velocity limit"), "{e}");
    }
}
