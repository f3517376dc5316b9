//! Named scenarios: the seed's experimental programme as sequences of
//! segments (command, external force, tip mass, duration) on a [`Sim`].
//!
//! | name | seed | what |
//! |---|---|---|
//! | `bm-noload` | Sect. 4.2, Fig. 14 | motor decoupled from the cable, motor-encoder loop at several speeds: `B_m` |
//! | `jae-ident` | Sect. 4.1, Fig. 8-9 | motor closed loop, joint open loop, magnetic encoder fitted; sine then complex trajectory |
//! | `track-motor` | Fig. 10 | ±30° sine with motor-encoder feedback only |
//! | `track-jae` | Fig. 11-12 | the same sine with the JAE as feedback |
//! | `robust-2n5` | Fig. 13 | complex trajectory with 2.5 N at the tip, JAE feedback |
//! | `tension-ident` | Sect. 4.2, Fig. 16-17 | no-load JAE closed loop, sines and complex: models A/B/C |
//! | `loading` | Sect. 4.3, Fig. 20-26 | held at 0°, 30°, -40°; 30-250 g both directions |
//!
//! `loading` note: a load in the negative direction assists the joint and
//! unloads cable 1 (by `F l_e / r`, 12.3 N at 250 g). At -40° the spring
//! side carries less than `F_0`, so with 200-250 g cable 1 falls below
//! slider 1's breakaway friction; the motor then pays out cable 0 faster than
//! slider 1 follows and cable 0 goes slack until the load is removed (a
//! transient of tens of degrees on unloading). The seed shows only positive
//! loading at -40° (Figs. 25-26). The scenario runs the case anyway.
//!
//! Every scenario takes a duration scale ([`ScenarioOptions::duration_scale`])
//! so tests can run short versions; `loading` can be narrowed to one
//! angle / mass / direction. Each segment tags its ticks with a [`Phase`]
//! (the `phase` column of the log).

use std::f64::consts::PI;

use cable_joint::trajectory::Trajectory;
use cable_joint::{Command, Config, Fault, Mode};

use crate::plant::PlantParams;
use crate::sim::{AngleErrors, ForceProfile, Recorder, Sim, TickRecord};
use crate::stats::Summary;

/// Standard gravity, m/s² (weights on the tip: `F = m g`).
pub const G_M_S2: f64 = 9.81;

/// What a segment of a scenario is doing (the log's `phase` column).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum Phase {
    /// Holding at rest before the run.
    Hold = 0,
    /// Moving to a set-point (seed Fig. 22b, region 1).
    Move = 1,
    /// Settling at the set-point (Fig. 22b, region 2).
    Adjust = 2,
    /// No-load region (Fig. 22, region 1/3).
    NoLoad = 3,
    /// Weight being hung (ramp).
    Loading = 4,
    /// Stable loaded region.
    Stable = 5,
    /// Weight being removed (ramp).
    Unloading = 6,
    /// Tracking a trajectory.
    Track = 7,
}

impl Phase {
    /// Code in the log.
    pub const fn code(self) -> u32 {
        self as u32
    }

    /// Name for summaries.
    pub const fn name(self) -> &'static str {
        match self {
            Phase::Hold => "hold",
            Phase::Move => "move",
            Phase::Adjust => "adjust",
            Phase::NoLoad => "no-load",
            Phase::Loading => "loading",
            Phase::Stable => "stable",
            Phase::Unloading => "unloading",
            Phase::Track => "track",
        }
    }
}

/// Direction of a tip load.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    /// `F_ext > 0`: opposes positive rotation (raises cable 1's tension).
    Pos,
    /// `F_ext < 0`.
    Neg,
}

impl Direction {
    /// +1 or -1.
    pub fn sign(self) -> f64 {
        match self {
            Direction::Pos => 1.0,
            Direction::Neg => -1.0,
        }
    }
}

/// Options common to all scenarios.
#[derive(Clone, Debug, PartialEq)]
pub struct ScenarioOptions {
    /// Multiplies every segment's duration (1 = the full programme).
    pub duration_scale: f64,
    /// `loading` only: run just this held angle, degrees.
    pub angle_deg: Option<f64>,
    /// `loading` only: run just this weight, grams.
    pub mass_g: Option<f64>,
    /// `loading` only: run just this direction.
    pub direction: Option<Direction>,
    /// Weights add their inertia `m l_e²` to the joint rigidly. Off by
    /// default: a weight on a thread decouples from the tip above the thread's
    /// bounce mode (a few Hz), so at the loop's frequencies it acts as a pure
    /// force. On, the 250 g weight puts the loaded joint mode near 60 rad/s,
    /// below the JAE position loop's crossover (a stress case).
    pub tip_inertia: bool,
}

impl Default for ScenarioOptions {
    fn default() -> Self {
        Self {
            duration_scale: 1.0,
            angle_deg: None,
            mass_g: None,
            direction: None,
            tip_inertia: false,
        }
    }
}

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
pub const SCENARIOS: [ScenarioInfo; 7] = [
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

/// Build a scenario's plan. Long by design: one `match` arm per scenario,
/// each a short list of segments, read best side by side.
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
        "loading" => {
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

/// Result of a scenario run.
#[derive(Clone, Debug, PartialEq)]
pub struct RunSummary {
    /// Scenario name.
    pub name: &'static str,
    /// Seed used.
    pub seed: u64,
    /// Control ticks (= log rows).
    pub ticks: u64,
    /// Simulated time, s.
    pub duration_s: f64,
    /// Tracking error (desired − magnetic encoder; desired − motor-implied
    /// angle for `bm-noload`) over the `Track` phases, or over every enabled
    /// tick if the scenario has none.
    pub tracking: Option<Summary>,
    /// JAE error (estimate − magnetic encoder), same ticks.
    pub jae: Option<Summary>,
    /// Force-estimate error in the `Stable` phases (estimate − applied), N:
    /// `(mean, max |error|)`.
    pub force_error_n: Option<(f64, f64)>,
    /// The same for the cable-stretch estimate `f_ext_stretch_n`.
    pub force_stretch_error_n: Option<(f64, f64)>,
    /// The same for the fused estimate `f_ext_fused_n`.
    pub force_fused_error_n: Option<(f64, f64)>,
    /// Share of the `Stable` samples whose applied force lies inside the
    /// fused bound `[f_ext_lo_n, f_ext_hi_n]`.
    pub force_bound_coverage: Option<f64>,
    /// Latched fault at the end, if any.
    pub fault: Option<Fault>,
}

impl Plan {
    /// Total duration, s.
    pub fn duration_s(&self) -> f64 {
        self.segments.iter().map(|s| s.duration_s).sum()
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
            sim.set_phase(seg.phase.code());
            sim.run_for(seg.duration_s, rec);
        }
    }
}

#[derive(Default)]
struct ForceAcc {
    n: u64,
    sum: f64,
    max_abs: f64,
    stretch_sum: f64,
    stretch_max_abs: f64,
    fused_sum: f64,
    fused_max_abs: f64,
    inside_bound: u64,
}

impl Recorder for ForceAcc {
    fn record(&mut self, r: &TickRecord) {
        if r.phase == Phase::Stable.code() && r.output.drive_enable {
            let e = r.output.est.f_ext_hat_n as f64 - r.f_ext_n;
            let es = r.output.est.f_ext_stretch_n as f64 - r.f_ext_n;
            self.stretch_sum += es;
            self.stretch_max_abs = self.stretch_max_abs.max(es.abs());
            let est = &r.output.est;
            let ef = f64::from(est.f_ext_fused_n) - r.f_ext_n;
            self.fused_sum += ef;
            self.fused_max_abs = self.fused_max_abs.max(ef.abs());
            if f64::from(est.f_ext_lo_n) <= r.f_ext_n && r.f_ext_n <= f64::from(est.f_ext_hi_n) {
                self.inside_bound += 1;
            }
            self.n += 1;
            self.sum += e;
            self.max_abs = self.max_abs.max(e.abs());
        }
    }
}

/// Build, set up and run a scenario: `plant` and `config` as given (the plan
/// adjusts the plant for itself), `seed` or the scenario's default, every
/// tick to `rec`.
pub fn run<R: Recorder + ?Sized>(
    name: &str,
    plant: PlantParams,
    config: Config,
    seed: Option<u64>,
    opts: &ScenarioOptions,
    rec: &mut R,
) -> anyhow::Result<RunSummary> {
    let plan = plan(name, opts)?;
    let mut plant = plant;
    plan.apply(&mut plant);
    let seed = seed.unwrap_or(plan.seed);
    // (A decoupled motor's slack check is switched off by `Sim::new`.)
    let mut sim = Sim::new(plant, config, seed)?;
    let has_track = plan.segments.iter().any(|s| s.phase == Phase::Track);
    let mut errors = AngleErrors::new(0.0);
    errors.against_motor = plan.motor_decoupled;
    if has_track {
        errors.phases = vec![Phase::Track.code()];
    }
    let mut force = ForceAcc::default();
    plan.run_on(&mut sim, &mut (&mut errors, &mut force, rec));
    Ok(RunSummary {
        name: plan.name,
        seed,
        ticks: sim.ticks(),
        duration_s: sim.time_s(),
        tracking: errors.tracking(),
        jae: errors.jae(),
        force_error_n: (force.n > 0).then(|| (force.sum / force.n as f64, force.max_abs)),
        force_stretch_error_n: (force.n > 0)
            .then(|| (force.stretch_sum / force.n as f64, force.stretch_max_abs)),
        force_fused_error_n: (force.n > 0)
            .then(|| (force.fused_sum / force.n as f64, force.fused_max_abs)),
        force_bound_coverage: (force.n > 0).then(|| force.inside_bound as f64 / force.n as f64),
        fault: sim.output().fault,
    })
}

/// A configuration whose identified parts are the plant's true values (an
/// oracle identification): machine constants, JAE coefficients (Eq. 26),
/// simplified model C (Eq. 29) and `B_m`. Gains, filters and limits are
/// kept from `base`. Useful to separate estimator-structure errors from
/// identification errors.
pub fn oracle_config(plant: &PlantParams, base: &Config) -> Config {
    let mut c = *base;
    let m = &mut c.machine;
    m.torque_constant_nm_a = plant.motor.torque_constant_nm_a as f32;
    m.rotor_inertia_kg_m2 = plant.motor.rotor_inertia_kg_m2 as f32;
    m.gear_ratio = plant.motor.gear_ratio as f32;
    m.rope_wheel_radius_m = plant.motor.rope_wheel_radius_m as f32;
    m.pulley_radius_m = plant.joint.pulley_radius_m as f32;
    m.gripper_length_m = plant.joint.gripper_length_m as f32;
    m.spring_n_m = plant.spring.stiffness_n_m as f32;
    m.preload_n = plant.spring.preload_n as f32;
    let j = plant.jae_coefficients();
    c.jae.c_acc_rad_s2_m = j[0] as f32;
    c.jae.c_vel_rad_s_m = j[1] as f32;
    c.jae.c_sign_rad = j[2] as f32;
    c.jae.c_pos_rad_m = j[3] as f32;
    c.jae.offset_rad = 0.0;
    let t = plant.model_c_coefficients();
    c.tension.f_sc1_n = t[0] as f32;
    c.tension.f_cp2_n = t[1] as f32;
    c.tension.k_s_n_m = t[2] as f32;
    c.tension.f_0_n = t[3] as f32;
    c.dob.viscous_nm_s_rad = plant.motor.viscous_nm_s_rad as f32;
    c
}

/// Cascade gains that work on the default plant (measured with
/// `host-sim simulate --scenario track-jae --oracle --tuned-gains`): the
/// position loop well below the velocity loop's bandwidth
/// (`K_m kp_vel / J_m ≈ 870 rad/s`), as the seed's `K_p1 = 98`.
pub fn tuned_gains(base: &Config) -> Config {
    let mut c = *base;
    c.cascade.kp_pos_1_s = 200.0;
    c.cascade.kd_pos = 0.5;
    c.cascade.kp_vel_a_s_rad = 0.04;
    c.cascade.ki_vel_a_rad = 2.0;
    c
}
