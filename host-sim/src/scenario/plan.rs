//! The scenarios' plans: the catalogue ([`SCENARIOS`]), the loading
//! protocol's angles and weights, and [`plan`], which turns a scenario's name
//! into its segments; a [`Plan`] sets up the plant for itself and runs its
//! segments on a [`Sim`].

use std::f64::consts::PI;
use std::sync::OnceLock;

use cable_joint::trajectory::Trajectory;
use cable_joint::{Command, Mode};

use super::{Direction, Phase, ScenarioOptions, G_M_S2};
use crate::ident::excite::{self, Criterion, Design, DesignOptions};
use crate::plant::{PlantParams, TipObject};
use crate::sim::{ForceProfile, Recorder, Sim};

/// One step of a scenario.
#[derive(Clone, Debug, PartialEq)]
pub struct Segment {
    /// Phase tag of its ticks.
    pub phase: Phase,
    /// Duration, s (after scaling).
    pub duration_s: f64,
    /// New command at its start (`None`: keep the one in force).
    pub command: Option<Command>,
    /// New force profile at its start (`None`: keep).
    pub force: Option<ForceProfile>,
    /// New tip mass at its start, kg (`None`: keep).
    pub tip_mass_kg: Option<f64>,
    /// An object placed at the tip at its start (`None`: keep what is
    /// there); it stays for the rest of the run.
    pub object: Option<TipObject>,
}

/// A scenario ready to run.
#[derive(Clone, Debug, PartialEq)]
pub struct Plan {
    /// Scenario name.
    pub name: &'static str,
    /// The scenario's default seed.
    pub seed: u64,
    /// Run with the motor decoupled from the cable (`bm-noload`).
    pub motor_decoupled: bool,
    /// The magnetic encoder is fitted (calibration runs).
    pub magnetic_fitted: bool,
    /// Segments in order.
    pub segments: Vec<Segment>,
}

impl Plan {
    /// Total duration, s.
    pub fn duration_s(&self) -> f64 {
        self.segments.iter().map(|s| s.duration_s).sum()
    }

    /// Each command's trajectory and how long it is in force, s (a segment
    /// without a command extends the one before).
    pub fn references(&self) -> Vec<(Trajectory, f64)> {
        let mut out: Vec<(Trajectory, f64)> = Vec::new();
        for seg in &self.segments {
            match (seg.command, out.last_mut()) {
                (Some(c), _) => out.push((c.trajectory, seg.duration_s)),
                (None, Some(last)) => last.1 += seg.duration_s,
                (None, None) => {}
            }
        }
        out
    }

    /// Whether any command closes the loop on the estimated joint angle
    /// (`Mode::JointClosedLoop`).
    pub fn closes_loop_on_jae(&self) -> bool {
        self.segments
            .iter()
            .any(|s| s.command.is_some_and(|c| c.mode == Mode::JointClosedLoop))
    }

    /// Adjust the plant parameters for this scenario: the motor decoupled
    /// for `bm-noload`; the magnetic encoder removed if the plan does not
    /// fit it (a plant file can also remove it).
    pub fn apply(&self, plant: &mut PlantParams) {
        plant.motor_decoupled = self.motor_decoupled;
        plant.sensors.magnetic_fitted &= self.magnetic_fitted;
    }

    /// Run the segments on `sim`, recording every tick.
    pub fn run_on<R: Recorder + ?Sized>(&self, sim: &mut Sim, rec: &mut R) {
        for seg in &self.segments {
            if let Some(c) = seg.command {
                sim.set_command(c);
            }
            if let Some(f) = &seg.force {
                sim.set_external_force(f.clone());
            }
            if let Some(m) = seg.tip_mass_kg {
                sim.set_tip_mass(m);
            }
            if seg.object.is_some() {
                sim.set_object(seg.object);
            }
            sim.set_phase(seg.phase.code());
            sim.run_for(seg.duration_s, rec);
        }
    }
}

/// Catalogue entry.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ScenarioInfo {
    /// Name (`--scenario`).
    pub name: &'static str,
    /// Default seed.
    pub seed: u64,
    /// One line.
    pub description: &'static str,
}

/// Every scenario.
pub const SCENARIOS: [ScenarioInfo; 9] = [
    ScenarioInfo {
        name: "bm-noload",
        seed: 101,
        description: "motor decoupled from the cable, motor-encoder loop at several speeds (B_m, seed Fig. 14)",
    },
    ScenarioInfo {
        name: "jae-ident",
        seed: 102,
        description: "motor closed loop, joint open loop, magnetic encoder fitted; sine then complex (seed Fig. 8-9)",
    },
    ScenarioInfo {
        name: "track-motor",
        seed: 103,
        description: "±30° 0.5 Hz sine with motor-encoder feedback only (seed Fig. 10)",
    },
    ScenarioInfo {
        name: "track-jae",
        seed: 104,
        description: "±30° 0.5 Hz sine with the JAE as feedback (seed Fig. 11-12)",
    },
    ScenarioInfo {
        name: "robust-2n5",
        seed: 105,
        description: "complex trajectory, JAE feedback, 2.5 N at the tip (seed Fig. 13)",
    },
    ScenarioInfo {
        name: "tension-ident",
        seed: 106,
        description: "no-load JAE closed loop, sines and complex trajectory (models A/B/C, seed Fig. 16-17)",
    },
    ScenarioInfo {
        name: "loading",
        seed: 107,
        description: "held at 0°, 30°, -40°; 30/50/100/200/250 g at the tip, both directions (seed Fig. 20-26)",
    },
    ScenarioInfo {
        name: "grip",
        seed: 109,
        description: "close onto a soft object at the tip and regulate its force (Trajectory::Grip, motor angle), then open (--grip-n, --object-deg, --object-n-m)",
    },
    ScenarioInfo {
        name: "excite",
        seed: 108,
        description: "jae-ident's set-up and length with a Fourier series designed for conditioning (seed 001 Sect. 2.3; `host-sim excite`)",
    },
];

/// Held angles of the loading protocol, degrees.
pub const LOADING_ANGLES_DEG: [f64; 3] = [0.0, 30.0, -40.0];
/// Weights of the loading protocol, grams.
pub const LOADING_MASSES_G: [f64; 5] = [30.0, 50.0, 100.0, 200.0, 250.0];

fn deg(d: f64) -> f32 {
    (d * PI / 180.0) as f32
}

struct Builder {
    scale: f64,
    segments: Vec<Segment>,
    angle_rad: f32,
}

impl Builder {
    fn new(scale: f64) -> Self {
        Self {
            scale,
            segments: Vec::new(),
            angle_rad: 0.0,
        }
    }

    fn seg(&mut self, phase: Phase, duration_s: f64, command: Option<Command>) -> &mut Segment {
        self.segments.push(Segment {
            phase,
            duration_s: duration_s * self.scale,
            command,
            force: None,
            tip_mass_kg: None,
            object: None,
        });
        let last = self.segments.len() - 1;
        &mut self.segments[last]
    }

    fn hold(&mut self, phase: Phase, mode: Mode, duration_s: f64) -> &mut Segment {
        let a = self.angle_rad;
        self.seg(
            phase,
            duration_s,
            Some(Command {
                mode,
                trajectory: Trajectory::Hold { angle_rad: a },
            }),
        )
    }

    fn track(&mut self, mode: Mode, trajectory: Trajectory, duration_s: f64) {
        self.seg(Phase::Track, duration_s, Some(Command { mode, trajectory }));
        // Both trajectories used here return to 0 after whole periods only
        // approximately: the next segment starts from the reference's end.
        self.angle_rad = trajectory.at((duration_s * self.scale) as f32).angle_rad;
    }

    fn move_to(&mut self, mode: Mode, to_rad: f32, duration_s: f64) {
        let from = self.angle_rad;
        self.seg(
            Phase::Move,
            duration_s,
            Some(Command {
                mode,
                trajectory: Trajectory::PointToPoint {
                    from_rad: from,
                    to_rad,
                    duration_s: (duration_s * self.scale) as f32,
                },
            }),
        );
        self.angle_rad = to_rad;
    }
}

fn sine(amplitude_deg: f64, freq_hz: f32) -> Trajectory {
    Trajectory::Sine {
        offset_rad: 0.0,
        amplitude_rad: deg(amplitude_deg),
        freq_hz,
    }
}

fn complex(amplitude_deg: f64, base_freq_hz: f32) -> Trajectory {
    Trajectory::Complex {
        amplitude_rad: deg(amplitude_deg),
        base_freq_hz,
    }
}

/// `excite`'s hold before the series and its return to 0 after it, s each.
const EXCITE_SETTLE_S: f64 = 1.0;

/// `grip`: closing speed before contact, rad/s of the cascade's angle
/// (5.7°/s; the report's grips close at it too).
pub const GRIP_APPROACH_RAD_S: f64 = 0.1;
/// `grip`: force control, s (the approach included).
pub const GRIP_S: f64 = 8.0;

/// The design options of an `excite` run as long as `hand_made` and within
/// its reference's limits, and the series' length (`hand_made`'s less
/// `excite`'s hold and return), s.
pub fn excitation_replacing(hand_made: &Plan, criterion: Criterion) -> (DesignOptions, f64) {
    let series_s = hand_made.duration_s() - 2.0 * EXCITE_SETTLE_S;
    let opts = DesignOptions::replacing(&hand_made.references(), series_s, criterion);
    (opts, series_s)
}

/// The design `excite` runs unless told otherwise, for `jae-ident` by
/// `criterion` ([`excite::design_over_frequencies`]), once per process and
/// criterion.
pub fn default_excitation(criterion: Criterion) -> anyhow::Result<&'static Design> {
    static SIGMA: OnceLock<Result<Design, String>> = OnceLock::new();
    static CONDITION: OnceLock<Result<Design, String>> = OnceLock::new();
    let cell = match criterion {
        Criterion::Sigma => &SIGMA,
        Criterion::Condition => &CONDITION,
    };
    cell.get_or_init(|| {
        let hand_made =
            plan("jae-ident", &ScenarioOptions::default()).map_err(|e| e.to_string())?;
        let (opts, series_s) = excitation_replacing(&hand_made, criterion);
        excite::design_over_frequencies(&opts, series_s).map_err(|e| e.to_string())
    })
    .as_ref()
    .map_err(|e| anyhow::anyhow!("designing the default excitation ({criterion:?}): {e}"))
}

/// Build a scenario's plan: one `match` arm per scenario, each a short list
/// of segments, read best side by side (`loading`'s is the function `loading`).
pub fn plan(name: &str, opts: &ScenarioOptions) -> anyhow::Result<Plan> {
    anyhow::ensure!(
        opts.duration_scale.is_finite() && opts.duration_scale > 0.0,
        "duration scale must be > 0, got {}",
        opts.duration_scale
    );
    let info = SCENARIOS.iter().find(|s| s.name == name).ok_or_else(|| {
        let names: Vec<_> = SCENARIOS.iter().map(|s| s.name).collect();
        anyhow::anyhow!("unknown scenario `{name}` (known: {})", names.join(", "))
    })?;
    let mut b = Builder::new(opts.duration_scale);
    let mut motor_decoupled = false;
    let mp = Mode::MotorPosition;
    let jc = Mode::JointClosedLoop;
    match info.name {
        "bm-noload" => {
            // Joint-equivalent sines: the motor-velocity amplitude is
            // A 2π f z_i r / r_m = 293, 147 and 59 rad/s.
            motor_decoupled = true;
            b.hold(Phase::Hold, mp, 0.5);
            b.track(mp, sine(57.3, 2.0), 8.0);
            b.track(mp, sine(114.6, 0.5), 8.0);
            b.track(mp, sine(57.3, 0.4), 8.0);
        }
        "jae-ident" => {
            b.hold(Phase::Hold, mp, 1.0);
            b.track(mp, sine(30.0, 0.5), 20.0);
            b.move_to(mp, 0.0, 1.0);
            b.track(mp, complex(30.0, 0.2), 20.0);
        }
        "track-motor" => {
            b.hold(Phase::Hold, mp, 1.0);
            b.track(mp, sine(30.0, 0.5), 12.0);
        }
        "track-jae" => {
            b.hold(Phase::Hold, jc, 1.0);
            b.track(jc, sine(30.0, 0.5), 12.0);
        }
        "robust-2n5" => {
            b.hold(Phase::Hold, jc, 1.0);
            let load = b.hold(Phase::Loading, jc, 0.5);
            load.force = Some(ForceProfile::Ramp {
                from_n: 0.0,
                to_n: 2.5,
                duration_s: 0.5 * opts.duration_scale,
            });
            if opts.tip_inertia {
                load.tip_mass_kg = Some(2.5 / G_M_S2);
            }
            b.hold(Phase::Stable, jc, 1.0);
            b.track(jc, complex(30.0, 0.2), 25.0);
        }
        "tension-ident" => {
            b.hold(Phase::Hold, jc, 1.0);
            b.track(jc, sine(30.0, 0.5), 15.0);
            b.move_to(jc, 0.0, 1.0);
            b.track(jc, sine(40.0, 0.25), 16.0);
            b.move_to(jc, 0.0, 1.0);
            b.track(jc, complex(30.0, 0.2), 20.0);
        }
        "loading" => loading(&mut b, opts)?,
        "grip" => {
            // From rest at 0, close at the approach speed onto an object on
            // the set point's side and regulate its force, then open to 0
            // from the object's surface (the reference steps back by the
            // squeeze's depth, which the plan cannot know).
            let g = &opts.grip;
            let surface_deg = g.force_n.signum() * g.object_deg.abs();
            let object = TipObject::new(surface_deg, g.object_n_m)?;
            let grip = Trajectory::Grip {
                force_n: g.force_n as f32,
                approach_rad_s: GRIP_APPROACH_RAD_S as f32,
            };
            grip.validate()
                .map_err(|e| anyhow::anyhow!("--grip-n {} N: {e}", g.force_n))?;
            b.hold(Phase::Hold, mp, 1.0).object = Some(object);
            b.seg(
                Phase::Grip,
                GRIP_S,
                Some(Command {
                    mode: mp,
                    trajectory: grip,
                }),
            );
            b.angle_rad = deg(surface_deg);
            b.move_to(mp, 0.0, 1.0);
            b.hold(Phase::Hold, mp, 1.0);
        }
        "excite" => {
            // jae-ident's set-up (motor closed loop, joint open loop) and
            // length: 1 s hold, the series, 1 s back to 0.
            let design = match opts.excitation {
                Some(d) => d,
                None => *default_excitation(Criterion::Sigma)?,
            };
            b.hold(Phase::Hold, mp, EXCITE_SETTLE_S);
            b.track(mp, design.trajectory, design.duration_s);
            b.move_to(mp, 0.0, EXCITE_SETTLE_S);
        }
        _ => unreachable!("catalogue and match agree"),
    }
    Ok(Plan {
        name: info.name,
        seed: info.seed,
        motor_decoupled,
        magnetic_fitted: true,
        segments: b.segments,
    })
}

/// The `loading` protocol: a hold, then each held angle × weight ×
/// direction (narrowed by `opts`) as move, settle, no-load, load, stable,
/// unload and rest segments, then back to 0°. Refuses an angle beyond 80° or
/// a weight outside (0, 1000] g.
fn loading(b: &mut Builder, opts: &ScenarioOptions) -> anyhow::Result<()> {
    let jc = Mode::JointClosedLoop;
    let angles: Vec<f64> = match opts.angle_deg {
        Some(a) => vec![a],
        None => LOADING_ANGLES_DEG.to_vec(),
    };
    let masses: Vec<f64> = match opts.mass_g {
        Some(m) => vec![m],
        None => LOADING_MASSES_G.to_vec(),
    };
    let dirs: Vec<Direction> = match opts.direction {
        Some(d) => vec![d],
        None => vec![Direction::Pos, Direction::Neg],
    };
    for a in &angles {
        anyhow::ensure!(a.abs() <= 80.0, "loading angle {a}° out of range");
    }
    for m in &masses {
        anyhow::ensure!(*m > 0.0 && *m <= 1000.0, "loading mass {m} g out of range");
    }
    b.hold(Phase::Hold, jc, 1.0);
    let ramp = 0.5 * opts.duration_scale;
    for &a in &angles {
        for &m in &masses {
            for &d in &dirs {
                let target = deg(a);
                if target != b.angle_rad {
                    b.move_to(jc, target, 1.5);
                }
                b.hold(Phase::Adjust, jc, 1.0);
                b.hold(Phase::NoLoad, jc, 2.0);
                let f = d.sign() * m * 1e-3 * G_M_S2;
                let load = b.seg(Phase::Loading, 0.5, None);
                load.force = Some(ForceProfile::Ramp {
                    from_n: 0.0,
                    to_n: f,
                    duration_s: ramp,
                });
                if opts.tip_inertia {
                    load.tip_mass_kg = Some(m * 1e-3);
                }
                b.seg(Phase::Stable, 3.0, None);
                b.seg(Phase::Unloading, 0.5, None).force = Some(ForceProfile::Ramp {
                    from_n: f,
                    to_n: 0.0,
                    duration_s: ramp,
                });
                let rest = b.seg(Phase::NoLoad, 0.5, None);
                rest.tip_mass_kg = Some(0.0);
                rest.force = Some(ForceProfile::Constant(0.0));
            }
        }
    }
    if b.angle_rad != 0.0 {
        b.move_to(jc, 0.0, 1.5);
        b.hold(Phase::Adjust, jc, 0.5);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn excite_lasts_as_long_as_jae_ident_and_starts_and_ends_at_rest_at_zero() {
        let opts = ScenarioOptions::default();
        let (hand, designed) = (
            plan("jae-ident", &opts).unwrap(),
            plan("excite", &opts).unwrap(),
        );
        assert!((hand.duration_s() - designed.duration_s()).abs() < 1e-9);
        let refs = designed.references();
        let (series, len) = refs[1];
        assert!(matches!(series, Trajectory::Fourier { .. }));
        let (start, end) = (series.at(0.0), series.at(len as f32));
        assert!(
            start.angle_rad == 0.0 && start.vel_rad_s.abs() < 1e-6,
            "{start:?}"
        );
        assert!(
            end.angle_rad.abs() < 1e-3 && end.vel_rad_s.abs() < 1e-3,
            "{end:?}"
        );
        let back = refs[2].0.at(refs[2].1 as f32);
        assert_eq!(back.angle_rad, 0.0);
    }
}
