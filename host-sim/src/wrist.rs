//! The simulated four-joint wrist (seed 000 Sect. 2.2-2.3): roll, pitch and
//! the two jaws, every joint the single-joint cable plant with its own
//! controller, run together by the core's [`Joints`], grasping a soft object.
//!
//! # Model
//!
//! * Joint 0 is the roll, 1 the pitch, 2 jaw A, 3 jaw B. Each is a
//!   [`Plant`] (motor, cables, sliders, return spring, sensors, noise) with
//!   its own parameters and seed, controlled by a [`cable_joint::Controller`]
//!   with its own identified configuration, all four stepped in one
//!   [`Joints::step`].
//! * Each jaw's joint angle `theta` is zero with the jaw open by
//!   [`WristParams::jaw_open_rad`] from the wrist's axis and grows as the
//!   jaw closes; jaw B is the mirror image of jaw A
//!   ([`cable_joint::wrist`]'s frames: `q_3 = theta - jaw_open`).
//! * The object ([`SoftObject`]) sits centred between the jaw tips: a
//!   spring–damper across the tips' gap `l_e (sin(a - theta_a) + sin(a -
//!   theta_b))`, pushing only (no adhesion), its force normal to each jaw
//!   (frictionless contact) at the jaw's tip. Each jaw's plant takes it as
//!   its external tip force (`F_ext > 0` opposes closing). A squeeze is an
//!   internal force: the roll and pitch joints carry none of it.
//! * The links are massless unless [`WristParams::links`] gives them
//!   masses ([`crate::links`]: Eq. 1's `D(q)`, `H` and `G`, each joint's
//!   plant taking its share). Massless, the joints are dynamically
//!   decoupled and gravity is left out as in seed 000's single joint (the
//!   prototype's links weigh grams and put millinewtons at the tips), and
//!   each joint's no-load model (its DOB and stretch chain) is Eq. 3's
//!   `tau_hat` for that joint; [`WristParams::inverse_dynamics`] adds
//!   the rest of Eq. 3 ([`cable_joint::wrist_dynamics`]).
//!
//! # Estimate
//!
//! Every tick each joint's fused force estimate and its bound become an
//! external torque `F l_e` with its bound, less Eq. 3's model if one is
//! set; [`cable_joint::wrist::jaw_force`]
//! (Eq. 4) gives each jaw's force and [`cable_joint::wrist::clamp_force`]
//! (Eq. 5) the clamp force with its bound.

use anyhow::{ensure, Context, Result};
use cable_joint::filter::{Kinematics, LowPass1, TrackingObserver};
use cable_joint::joints::Joints;
use cable_joint::trajectory::Trajectory;
use cable_joint::wrist::{self, Geometry, Interval};
use cable_joint::wrist_dynamics::{InverseDynamics, WristMotion};
use cable_joint::{Command, Config, Controller, Mode, Output, RawSample};

use serde::Serialize;

use crate::links::{self, Links};
use crate::plant::{contact_push_n, Plant, PlantParams};
pub use crate::stats::GripStats;
use crate::stats::{grip_stats_of, GripSample};

/// Joint indices.
pub const ROLL: usize = 0;
/// Pitch joint.
pub const PITCH: usize = 1;
/// Jaw A.
pub const JAW_A: usize = 2;
/// Jaw B.
pub const JAW_B: usize = 3;

/// The object between the jaws: a spring–damper across the tips' gap.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SoftObject {
    /// Width at rest, m.
    pub width_m: f64,
    /// Stiffness across the jaws, N/m.
    pub stiffness_n_m: f64,
    /// Damping across the jaws, N·s/m.
    pub damping_n_s_m: f64,
}

/// The wrist: four joints' plants and configurations, the geometry, the
/// jaws' opening and the pose the roll and pitch hold.
#[derive(Clone, Debug)]
pub struct WristParams {
    /// Plants of roll, pitch, jaw A, jaw B.
    pub plants: [PlantParams; 4],
    /// Configurations of roll, pitch, jaw A, jaw B (the same control rate).
    pub configs: [Config; 4],
    /// The wrist's dimensions (its jaw length must be each jaw
    /// configuration's gripper length).
    pub geometry: Geometry,
    /// Each jaw's angle from the wrist axis at `theta = 0`, rad.
    pub jaw_open_rad: f64,
    /// Pitch angle the wrist holds, rad.
    pub pitch_rad: f64,
    /// The links' masses under gravity (Eq. 1's `D`, `H`, `G`), or
    /// massless links ([`crate::links`]: at the prototype's scale they put
    /// 1.5 mN at a jaw's tip).
    pub links: Option<Links>,
    /// Eq. 3's model the estimates are corrected with
    /// ([`crate::links::fit_inverse_dynamics`]), or none.
    pub inverse_dynamics: Option<Eq3Model>,
}

impl WristParams {
    /// Every joint the same machine (`plant`, `config`), the seed's
    /// geometry, jaws open by 20° each, the wrist pitched by 30°.
    pub fn uniform(plant: PlantParams, config: Config) -> Self {
        let geometry = Geometry::with_jaws_of(&config.machine);
        Self {
            plants: [plant; 4],
            configs: [config; 4],
            geometry,
            jaw_open_rad: 20f64.to_radians(),
            pitch_rad: 30f64.to_radians(),
            links: None,
            inverse_dynamics: None,
        }
    }

    /// How Eq. 3 is read against the joints' estimates ([`Eq3Timing`]).
    pub fn eq3_timing(&self) -> Eq3Timing {
        Eq3Timing {
            period_s: 1.0 / f64::from(self.configs[0].control_rate_hz),
            q_cutoff_rad_s: self.configs[0].dob.cutoff_rad_s,
            jaw_open_rad: self.jaw_open_rad,
        }
    }

    /// The jaws' tip gap at jaw angles `theta_a`, `theta_b`, m.
    pub fn gap_m(&self, theta_a: f64, theta_b: f64) -> f64 {
        let l = f64::from(self.geometry.jaw_length_m);
        l * ((self.jaw_open_rad - theta_a).sin() + (self.jaw_open_rad - theta_b).sin())
    }

    /// Refuse an object that does not fit between the open jaws.
    pub fn check_fits(&self, object: &SoftObject) -> Result<()> {
        let open_gap = self.gap_m(0.0, 0.0);
        ensure!(
            object.width_m < open_gap,
            "the object ({:.1} mm) does not fit between the open jaws ({:.1} mm)",
            object.width_m * 1e3,
            open_gap * 1e3
        );
        Ok(())
    }

    /// The jaw angle (both jaws alike) at which the gap is `gap_m`, rad.
    pub fn theta_for_gap(&self, gap_m: f64) -> f64 {
        let l = f64::from(self.geometry.jaw_length_m);
        self.jaw_open_rad - (0.5 * gap_m / l).clamp(-1.0, 1.0).asin()
    }
}

/// One tick of the wrist.
#[derive(Clone, Copy, Debug)]
pub struct WristTick {
    /// Time, s.
    pub t_s: f64,
    /// The four joints' outputs.
    pub outputs: [Output; 4],
    /// True joint angles, rad.
    pub theta_rad: [f64; 4],
    /// True contact force (each jaw's squeeze), N.
    pub contact_n: f64,
    /// Eq. 5's clamp force from the joints' point estimates, N.
    pub clamp_n: f64,
    /// Its bound, from the joints' bounds through Eq. 4 and 5, N.
    pub clamp_bound_n: Interval,
    /// Eq. 4's force of jaw A and B (from the bounds), jaw frames, N
    /// ([`WristForce::jaws`]).
    pub jaws: [wrist::JawForce; 2],
    /// The pose Eq. 4–5 read, as the joints estimate it (the core's
    /// `[q_2, q_3^a, q_3^b]`), rad: with [`Self::torque_bound_nm`] it gives
    /// Eq. 5's total force ([`total_force`]).
    pub pose_rad: [f32; 3],
    /// The true total force: each jaw's squeeze along its closing direction
    /// (`(0, cos q_a, -sin q_a)` and `(0, -cos q_b, -sin q_b)` in the wrist
    /// frame, the true jaw angles), N.
    pub total_true_n: [f64; 3],
    /// The joints' motion as their estimates give it (angles from the
    /// JAE, speeds and accelerations from tracking observers: at the
    /// model's bandwidth with an Eq. 3 model, else at `Q`'s), jaws as the
    /// core's `q_3`.
    pub motion: WristMotion,
    /// The links' true torque on each joint (zero for massless links), N·m.
    pub links_true_nm: [f64; 4],
    /// Eq. 3's torque taken out of each joint's estimate (zero without a
    /// model), N·m.
    pub links_hat_nm: [f32; 4],
    /// Each joint's external torque bound after Eq. 3 was taken out: the
    /// estimate's own joined with the one the model shifts and its
    /// parameters' spread widens, N·m.
    pub torque_bound_nm: [Interval; 4],
}

/// The four plants under [`Joints`], with the object between the jaws.
pub struct WristSim {
    params: WristParams,
    object: SoftObject,
    plants: [Plant; 4],
    joints: Joints<4>,
    period_s: f64,
    substeps: usize,
    tick: u64,
    contact_n: f64,
    /// The joints' true accelerations over the last tick (the links'
    /// coupling terms use them a tick late).
    true_qdd: [f64; 4],
    /// The wrist's motion as the joints estimate it, at `Q`'s bandwidth
    /// (without a model).
    motion: MotionEstimator,
    /// The model applied (with one).
    eq3: Option<Eq3Filter>,
}

/// The wrist's motion as the joints estimate it: each joint's JAE angle
/// differentiated by a tracking observer, the jaws as the core's `q_3`
/// (`theta - jaw_open`). The simulated wrist and a rig's recorded run
/// ([`crate::wrist_log`]) both read their motion through it.
#[derive(Clone, Debug)]
pub struct MotionEstimator {
    observer: TrackingObserver,
    kinematics: [Kinematics; 4],
    jaw_open_rad: f32,
    started: bool,
}

impl MotionEstimator {
    /// An observer of bandwidth `bandwidth_hz` at the control period
    /// `period_s`, jaws open by `jaw_open_rad` at `theta = 0`.
    pub fn new(bandwidth_hz: f32, period_s: f64, jaw_open_rad: f64) -> Self {
        Self {
            observer: TrackingObserver::new(bandwidth_hz, period_s as f32),
            kinematics: [Kinematics::default(); 4],
            jaw_open_rad: jaw_open_rad as f32,
            started: false,
        }
    }

    /// The motion after a tick whose JAE angles are `theta_hat_rad` (the
    /// first tick starts the observers there, at rest).
    pub fn update(&mut self, theta_hat_rad: [f32; 4]) -> WristMotion {
        for (k, theta) in self.kinematics.iter_mut().zip(theta_hat_rad) {
            if !self.started {
                self.observer.reset(k, theta);
            }
            self.observer.update(k, theta);
        }
        self.started = true;
        let open = self.jaw_open_rad;
        let k = &self.kinematics;
        WristMotion {
            q_rad: core::array::from_fn(|j| {
                if j >= JAW_A {
                    k[j].pos - open
                } else {
                    k[j].pos
                }
            }),
            qd_rad_s: core::array::from_fn(|j| k[j].vel),
            qdd_rad_s2: core::array::from_fn(|j| k[j].acc),
        }
    }
}

/// How the wrist reads Eq. 3 against its joints' estimates: each joint's
/// estimate is its torque through the force estimate's low-pass `Q =
/// g/(s+g)` (the DOB's, `dob.cutoff_rad_s`), so the model's torque goes
/// through the same `Q` (the core's [`LowPass1`]) before it is compared or
/// taken out, computed on the motion of an observer of its own bandwidth
/// (fast enough that its lag is not `Q`'s; [`Eq3Model::motion_bandwidth_hz`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Eq3Timing {
    /// The control period, s.
    pub period_s: f64,
    /// `Q`'s cutoff `g`, rad/s.
    pub q_cutoff_rad_s: f32,
    /// Each jaw's angle from the wrist axis at `theta = 0`, rad.
    pub jaw_open_rad: f64,
}

impl Eq3Timing {
    /// `Q`'s bandwidth, Hz.
    pub fn q_bandwidth_hz(&self) -> f32 {
        self.q_cutoff_rad_s / (2.0 * core::f32::consts::PI)
    }
}

/// Eq. 3's model as the wrist applies it: the core's parameters and the
/// bandwidth of the observer its motion comes from ([`Eq3Timing`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Eq3Model {
    /// The parameters.
    pub body: InverseDynamics,
    /// The motion observer's bandwidth, Hz.
    pub motion_bandwidth_hz: f32,
}

/// A model of Eq. 3 applied tick by tick ([`Eq3Timing`]): the motion, and
/// the model's torque and its parameters' spread through `Q`.
#[derive(Clone, Debug)]
pub struct Eq3Filter {
    model: Eq3Model,
    motion: MotionEstimator,
    q: LowPass1,
    /// `Q`'s states of the torque and the spread (none before the first
    /// tick, which starts them at their value).
    state: Option<([f32; 4], [f32; 4])>,
}

impl Eq3Filter {
    /// For `model` at `timing`.
    pub fn new(model: &Eq3Model, timing: &Eq3Timing) -> Self {
        Self {
            model: *model,
            motion: MotionEstimator::new(
                model.motion_bandwidth_hz,
                timing.period_s,
                timing.jaw_open_rad,
            ),
            q: LowPass1::new(timing.q_cutoff_rad_s, timing.period_s as f32),
            state: None,
        }
    }

    /// One tick: the motion from the JAE angles `theta_hat_rad`, and the
    /// model's torque and spread through `Q`, N·m.
    pub fn update(
        &mut self,
        g: &Geometry,
        theta_hat_rad: [f32; 4],
    ) -> (WristMotion, [f32; 4], [f32; 4]) {
        let motion = self.motion.update(theta_hat_rad);
        let (tau, spread) = self.model.body.torque_and_spread_nm(g, &motion);
        let (y_tau, y_spread) = self.state.get_or_insert((tau, spread));
        for j in 0..4 {
            self.q.update(&mut y_tau[j], tau[j]);
            self.q.update(&mut y_spread[j], spread[j]);
        }
        (motion, *y_tau, *y_spread)
    }
}

/// One joint's force estimate at its tip, as its controller gives it
/// (`f_ext_fused_n`, `f_ext_lo_n`, `f_ext_hi_n`), N.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TipForce {
    /// The fused point estimate.
    pub point_n: f32,
    /// Its bound's lower end.
    pub lo_n: f32,
    /// Its bound's upper end.
    pub hi_n: f32,
}

impl TipForce {
    /// The estimate of a controller's tick.
    pub fn of(e: &cable_joint::Estimates) -> Self {
        Self {
            point_n: e.f_ext_fused_n,
            lo_n: e.f_ext_lo_n,
            hi_n: e.f_ext_hi_n,
        }
    }
}

/// The wrist's forces of one tick (Eq. 4–5), from the joints' estimates.
#[derive(Clone, Copy, Debug)]
pub struct WristForce {
    /// Each joint's external torque from its point estimate, Eq. 3 taken
    /// out, N·m.
    pub torque_nm: [f32; 4],
    /// Each joint's external torque bound, Eq. 3 taken out ([`torque_bound_nm`]), N·m.
    pub torque_bound_nm: [Interval; 4],
    /// Eq. 4's force of jaw A and B (from the bounds), jaw frames, N; each
    /// jaw's `F_x` and `F_z` are its own only while the other jaw is free
    /// (the core's wrist module docs), `F_y` always.
    pub jaws: [wrist::JawForce; 2],
    /// Eq. 5's clamp force bound, N.
    pub clamp_bound_n: Interval,
    /// Eq. 5's clamp force from the joints' point estimates, N.
    pub clamp_n: f64,
    /// The pose Eq. 4–5 read, as the joints estimate it (the core's
    /// `[q_2, q_3^a, q_3^b]`), rad.
    pub pose_rad: [f32; 3],
}

impl WristForce {
    /// Eq. 5's total force of both jaws ([`total_force`]).
    pub fn total(&self, g: &Geometry) -> wrist::TotalForce {
        total_force(g, self.pose_rad, self.torque_bound_nm)
    }
}

/// Eq. 5's total force of both jaws from the four joints' torque bounds
/// together at `pose_rad` (`[q_2, q_3^a, q_3^b]`), wrist frame, N, with
/// the geometry's force limit bounding what the joints do not see
/// (`cable_joint::wrist::total_force`). Computed where it is asked for,
/// not every tick: it solves 210 small systems.
pub fn total_force(
    g: &Geometry,
    pose_rad: [f32; 3],
    torque_bound_nm: [Interval; 4],
) -> wrist::TotalForce {
    let [q2, qa, qb] = pose_rad;
    wrist::total_force(g, q2, qa, qb, torque_bound_nm, g.force_limit_n)
}

/// Eq. 4–5 on one tick: each joint's estimate at its tip `tip[j]` times
/// its tip distance `l_m[j]` is its external torque, less Eq. 3's
/// `links_hat_nm` (its bound widened by `spread_nm`, [`torque_bound_nm`]);
/// the pose is the joints' estimated angles `theta_hat_rad` (the jaws'
/// zero `jaw_open_rad` from the wrist's axis). The simulated wrist and a
/// recorded wrist's replay (`host-sim estimate-wrist`) both compute it
/// here.
pub fn wrist_force(
    g: &Geometry,
    jaw_open_rad: f32,
    theta_hat_rad: [f32; 4],
    tip: [TipForce; 4],
    l_m: [f32; 4],
    links_hat_nm: [f32; 4],
    spread_nm: [f32; 4],
) -> WristForce {
    // Each joint's external torque, Eq. 3 taken out.
    let torque_bound_nm: [Interval; 4] = core::array::from_fn(|j| {
        torque_bound_nm(
            tip[j].lo_n * l_m[j],
            tip[j].hi_n * l_m[j],
            links_hat_nm[j],
            spread_nm[j],
        )
    });
    let torque_nm: [f32; 4] = core::array::from_fn(|j| tip[j].point_n * l_m[j] - links_hat_nm[j]);
    // The wrist's pose as the joints estimate it (the JAE of each).
    let q2 = theta_hat_rad[PITCH];
    let qa = theta_hat_rad[JAW_A] - jaw_open_rad;
    let qb = theta_hat_rad[JAW_B] - jaw_open_rad;
    // Jaw B is jaw A's mirror image: its roll torque enters with the
    // other sign (wrist module docs).
    let [roll, pitch, tau_a, tau_b] = torque_bound_nm;
    let jaw_a = wrist::jaw_force(g, q2, qa, [roll, pitch, tau_a]);
    let jaw_b = wrist::jaw_force(g, q2, qb, [roll.scale(-1.0), pitch, tau_b]);
    let clamp_bound_n = wrist::clamp_force(jaw_a.force_n[1], jaw_b.force_n[1]);
    let pa = Interval::point(torque_nm[JAW_A]).scale(1.0 / g.jaw_length_m);
    let pb = Interval::point(torque_nm[JAW_B]).scale(1.0 / g.jaw_length_m);
    WristForce {
        torque_nm,
        torque_bound_nm,
        jaws: [jaw_a, jaw_b],
        clamp_bound_n,
        clamp_n: f64::from(wrist::clamp_force(pa, pb).mid()),
        pose_rad: [q2, qa, qb],
    }
}

/// A joint's external torque with Eq. 3 taken out, as a bound: the
/// estimate's own `[lo, hi]` (N·m), shifted by the model's torque `hat`
/// and widened by its parameters' `spread`, joined with the unshifted one
/// (the model's structure can be wrong where its parameters are not).
pub fn torque_bound_nm(lo: f32, hi: f32, hat: f32, spread: f32) -> Interval {
    let (shifted_lo, shifted_hi) = (lo - hat - spread, hi - hat + spread);
    Interval::new(lo.min(shifted_lo), hi.max(shifted_hi))
}

/// The contact force of `object` at gap `gap_m` closing at `gap_rate`, N.
fn contact(object: &SoftObject, gap_m: f64, gap_rate_m_s: f64) -> f64 {
    contact_push_n(
        object.stiffness_n_m,
        object.damping_n_s_m,
        object.width_m - gap_m,
        -gap_rate_m_s,
    )
}

impl WristSim {
    /// Every plant at rest, every controller homed on its first sample and
    /// idle. `seed` drives the noise (each joint its own stream).
    pub fn new(params: WristParams, object: SoftObject, seed: u64) -> Result<Self> {
        let rate = params.configs[0].control_rate_hz;
        ensure!(
            params.configs.iter().all(|c| c.control_rate_hz == rate),
            "every joint of the wrist must run at one control rate"
        );
        ensure!(
            params.configs[JAW_A..]
                .iter()
                .all(|c| c.machine.gripper_length_m == params.geometry.jaw_length_m),
            "the wrist's jaw length must be each jaw configuration's gripper length"
        );
        ensure!(
            params
                .configs
                .iter()
                .all(|c| c.dob.cutoff_rad_s == params.configs[0].dob.cutoff_rad_s),
            "every joint of the wrist must low-pass its force estimate alike (one dob.cutoff_rad_s: Eq. 3 is read through it)"
        );
        let period_s = 1.0 / f64::from(rate);
        let timing = params.eq3_timing();
        let motion = MotionEstimator::new(timing.q_bandwidth_hz(), period_s, params.jaw_open_rad);
        let eq3 = params.inverse_dynamics.map(|m| Eq3Filter::new(&m, &timing));
        if let Some(l) = &params.links {
            links::check(l)?;
        }
        let mut plants = Vec::with_capacity(4);
        let mut controllers = Vec::with_capacity(4);
        // One sub-step for all four plants (the contact couples the jaws at
        // every sub-step): the finest any plant asks for, whole per period.
        let substeps = params
            .plants
            .iter()
            .map(|p| (p.integration.step_hz * period_s - 1e-9).ceil().max(1.0) as usize)
            .max()
            .unwrap_or(1);
        for (j, (p, c)) in params.plants.iter().zip(&params.configs).enumerate() {
            let mut p = *p;
            p.integration.step_hz = substeps as f64 / period_s;
            let seed_j = seed ^ (0x9e37_79b9_7f4a_7c15u64.wrapping_mul(j as u64 + 1));
            let name = crate::wrist_log::JOINT_NAMES[j];
            plants.push(Plant::new(p, seed_j).with_context(|| format!("wrist joint {name}"))?);
            controllers.push(
                Controller::new(*c)
                    .map_err(|e| anyhow::anyhow!("wrist joint {name}'s configuration: {e}"))?,
            );
        }
        let mut plants: [Plant; 4] = plants
            .try_into()
            .map_err(|_| anyhow::anyhow!("four plants"))?;
        let controllers: [Controller; 4] = controllers
            .try_into()
            .map_err(|_| anyhow::anyhow!("four controllers"))?;
        let mut joints = Joints::new(controllers);
        let raw: [RawSample; 4] = core::array::from_fn(|j| plants[j].sample());
        joints.set_origin(&raw);
        Ok(Self {
            params,
            object,
            plants,
            joints,
            period_s,
            substeps,
            tick: 0,
            contact_n: 0.0,
            true_qdd: [0.0; 4],
            motion,
            eq3,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &WristParams {
        &self.params
    }

    /// The control period, s.
    pub fn period_s(&self) -> f64 {
        self.period_s
    }

    /// The joints.
    pub fn joints(&self) -> &Joints<4> {
        &self.joints
    }

    /// Declare jaws A and B a gripping pair (or not): see
    /// [`Joints::set_pair`].
    pub fn set_pair(&mut self, pair: bool) -> Result<()> {
        self.joints
            .set_pair(pair.then_some((JAW_A, JAW_B)))
            .map_err(|e| anyhow::anyhow!("wrist: pair refused: {}", refused_text(e)))
    }

    /// Give joint `j` a command (refused while a fault is latched).
    pub fn set_command(&mut self, j: usize, command: Command) -> Result<()> {
        self.joints.set_command(j, command).map_err(|e| {
            anyhow::anyhow!(
                "wrist joint {}: command refused: {}",
                joint_name(j),
                refused_text(e)
            )
        })
    }

    /// A wrist for a grasp or a grip: `object` checked to fit between the
    /// open jaws, the roll and both jaws holding at zero, the pitch moving
    /// to its angle over `pitch_move_s`, every joint closed on its JAE.
    fn opened(
        params: &WristParams,
        object: SoftObject,
        seed: u64,
        pitch_move_s: f64,
    ) -> Result<Self> {
        params.check_fits(&object)?;
        let mut sim = Self::new(params.clone(), object, seed)?;
        let hold = Command {
            mode: Mode::JointClosedLoop,
            trajectory: Trajectory::Hold { angle_rad: 0.0 },
        };
        for j in [ROLL, JAW_A, JAW_B] {
            sim.set_command(j, hold)?;
        }
        let pitch = joint_move(Mode::JointClosedLoop, 0.0, params.pitch_rad, pitch_move_s);
        sim.set_command(PITCH, pitch)?;
        Ok(sim)
    }

    /// Step for `seconds`, every tick recorded in `out` with `phase`.
    fn run(&mut self, phase: Phase, seconds: f64, out: &mut Vec<(Phase, WristTick)>) {
        for _ in 0..(seconds / self.period_s).round() as u64 {
            out.push((phase, self.step()));
        }
    }

    /// Time of the next tick, s.
    pub fn time_s(&self) -> f64 {
        self.tick as f64 * self.period_s
    }

    /// One control tick of every joint, then the plants over one period
    /// with the contact force updated at every sub-step.
    pub fn step(&mut self) -> WristTick {
        let t_s = self.time_s();
        let raw: [RawSample; 4] = core::array::from_fn(|j| self.plants[j].sample());
        let theta_rad: [f64; 4] = core::array::from_fn(|j| self.plants[j].state().theta_rad);
        let outputs = self.joints.step(&raw);
        let g = &self.params.geometry;
        let open = self.params.jaw_open_rad as f32;
        let theta_hat: [f32; 4] = core::array::from_fn(|j| outputs[j].est.theta_hat_rad);
        let (motion, links_hat_nm, spread_nm) = match &mut self.eq3 {
            Some(f) => f.update(g, theta_hat),
            None => (self.motion.update(theta_hat), [0.0; 4], [0.0; 4]),
        };
        let forces = wrist_force(
            g,
            open,
            theta_hat,
            core::array::from_fn(|j| TipForce::of(&outputs[j].est)),
            core::array::from_fn(|j| self.params.configs[j].machine.gripper_length_m),
            links_hat_nm,
            spread_nm,
        );
        // The links' true torques: D_jj as each plant's own inertia, the
        // rest (gravity, Coriolis, the other joints' accelerations a tick
        // late) as a load at its tip.
        let mut true_q = theta_rad;
        for j in [JAW_A, JAW_B] {
            true_q[j] -= self.params.jaw_open_rad;
        }
        let true_qd: [f64; 4] = core::array::from_fn(|j| self.plants[j].state().theta_vel_rad_s);
        let (links_true_nm, links_force_n) = match &self.params.links {
            None => ([0.0; 4], [0.0; 4]),
            Some(links) => {
                let d = links.inertia_kg_m2(g, true_q);
                let rest = links.torque_nm(g, true_q, true_qd, [0.0; 4]);
                let qdd = self.true_qdd;
                let le: [f64; 4] =
                    core::array::from_fn(|j| self.plants[j].params().joint.gripper_length_m);
                let mut tau = [0.0; 4];
                let mut force = [0.0; 4];
                for j in 0..4 {
                    let off: f64 = (0..4).filter(|&k| k != j).map(|k| d[j][k] * qdd[k]).sum();
                    tau[j] = rest[j] + off + d[j][j] * qdd[j];
                    force[j] = (rest[j] + off) / le[j];
                    self.plants[j].set_tip_mass(d[j][j] / (le[j] * le[j]));
                }
                (tau, force)
            }
        };
        let record = WristTick {
            t_s,
            outputs,
            theta_rad,
            contact_n: self.contact_n,
            clamp_n: forces.clamp_n,
            clamp_bound_n: forces.clamp_bound_n,
            jaws: forces.jaws,
            pose_rad: forces.pose_rad,
            total_true_n: [
                0.0,
                self.contact_n * (true_q[JAW_A].cos() - true_q[JAW_B].cos()),
                -self.contact_n * (true_q[JAW_A].sin() + true_q[JAW_B].sin()),
            ],
            motion,
            links_true_nm,
            links_hat_nm,
            torque_bound_nm: forces.torque_bound_nm,
        };
        for (p, o) in self.plants.iter_mut().zip(&outputs) {
            let i_a = if o.drive_enable {
                p.params().sensors.scales.dac_a(o.dac) as f64
            } else {
                0.0
            };
            p.set_current_command(i_a);
        }
        for _ in 0..self.substeps {
            let (a, b) = (*self.plants[JAW_A].state(), *self.plants[JAW_B].state());
            let gap = self.params.gap_m(a.theta_rad, b.theta_rad);
            let l = f64::from(self.params.geometry.jaw_length_m);
            let open = self.params.jaw_open_rad;
            let gap_rate = -l
                * ((open - a.theta_rad).cos() * a.theta_vel_rad_s
                    + (open - b.theta_rad).cos() * b.theta_vel_rad_s);
            self.contact_n = contact(&self.object, gap, gap_rate);
            for (j, p) in self.plants.iter_mut().enumerate() {
                let contact_n = if j >= JAW_A { self.contact_n } else { 0.0 };
                p.set_external_force(contact_n + links_force_n[j]);
                p.step();
            }
        }
        let qd_now: [f64; 4] = core::array::from_fn(|j| self.plants[j].state().theta_vel_rad_s);
        self.true_qdd = core::array::from_fn(|j| (qd_now[j] - true_qd[j]) / self.period_s);
        self.tick += 1;
        record
    }
}

/// A smooth move of one joint from `from` to `to` (rad) over `seconds`.
fn joint_move(mode: Mode, from: f64, to: f64, seconds: f64) -> Command {
    Command {
        mode,
        trajectory: Trajectory::PointToPoint {
            from_rad: from as f32,
            to_rad: to as f32,
            duration_s: seconds as f32,
        },
    }
}

/// A grasp: close both jaws onto the object to the angle that would squeeze
/// it with `target_n` at rigid jaws, hold, open again.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grasp {
    /// Squeeze the closing angle aims at, N.
    pub target_n: f64,
    /// Settling before the grasp, s.
    pub settle_s: f64,
    /// Closing (and opening) move, s.
    pub move_s: f64,
    /// Hold, s.
    pub hold_s: f64,
    /// After opening, s.
    pub after_s: f64,
}

impl Default for Grasp {
    fn default() -> Self {
        Self {
            target_n: 2.0,
            settle_s: 1.0,
            move_s: 1.0,
            hold_s: 3.0,
            after_s: 1.0,
        }
    }
}

/// Phases of a grasp run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    /// Jaws open, before the grasp.
    Open,
    /// Closing onto the object.
    Grasp,
    /// Holding (the stable region is its second half).
    Hold,
    /// Opening.
    Release,
    /// Open after the release.
    After,
}

/// Run one grasp; returns every tick with its phase.
pub fn run_grasp(
    params: &WristParams,
    object: SoftObject,
    grasp: &Grasp,
    seed: u64,
) -> Result<Vec<(Phase, WristTick)>> {
    ensure!(
        grasp.target_n > 0.0 && object.stiffness_n_m > 0.0,
        "a grasp needs a positive target force and a positive object stiffness"
    );
    let mut sim = WristSim::opened(params, object, seed, grasp.move_s)?;
    let close = params.theta_for_gap(object.width_m - grasp.target_n / object.stiffness_n_m);
    let move_to = |from: f64, to: f64| joint_move(Mode::JointClosedLoop, from, to, grasp.move_s);
    let mut out = Vec::new();
    sim.run(Phase::Open, grasp.settle_s, &mut out);
    for j in [JAW_A, JAW_B] {
        sim.set_command(j, move_to(0.0, close))?;
    }
    sim.run(Phase::Grasp, grasp.move_s, &mut out);
    sim.run(Phase::Hold, grasp.hold_s, &mut out);
    for j in [JAW_A, JAW_B] {
        sim.set_command(j, move_to(close, 0.0))?;
    }
    sim.run(Phase::Release, grasp.move_s, &mut out);
    sim.run(Phase::After, grasp.after_s, &mut out);
    Ok(out)
}

/// A grip under force control ([`cable_joint::grip`]): from open jaws, the
/// jaws (both as a pair, or jaw A alone with jaw B held open) are given a
/// force set point and close on the object on their own; after the hold
/// they open again under position control.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GripRun {
    /// Clamp force set point, N.
    pub set_n: f64,
    /// Closing speed before contact, rad/s.
    pub approach_rad_s: f64,
    /// Both jaws as a pair (the clamp force), or jaw A alone (its tip force).
    pub pair: bool,
    /// The mode the grip runs in: [`Mode::MotorPosition`] (the cascade on
    /// the motor's angle) or [`Mode::JointClosedLoop`] (on the estimated
    /// angle).
    pub mode: Mode,
    /// Settling before the grip, s.
    pub settle_s: f64,
    /// Force control, s (the approach included).
    pub grip_s: f64,
    /// Opening move, and open after it, s.
    pub release_s: f64,
}

impl Default for GripRun {
    fn default() -> Self {
        Self {
            set_n: 2.0,
            approach_rad_s: 0.05,
            pair: true,
            mode: Mode::MotorPosition,
            settle_s: 1.0,
            grip_s: 6.0,
            release_s: 1.0,
        }
    }
}

/// The force a grip regulates, with its bound: the clamp force of a pair
/// (Eq. 5 from both jaws' estimates) or jaw A's own squeeze.
pub fn gripped_force(t: &WristTick, pair: bool) -> (f64, Interval) {
    if pair {
        (t.clamp_n, t.clamp_bound_n)
    } else {
        let e = &t.outputs[JAW_A].est;
        (
            f64::from(e.f_ext_fused_n),
            Interval::new(e.f_ext_lo_n, e.f_ext_hi_n),
        )
    }
}

/// Run one grip; every tick with its phase ([`Phase::Grasp`] while under
/// force control, [`Phase::Release`] and [`Phase::After`] on the way out).
pub fn run_grip(
    params: &WristParams,
    object: SoftObject,
    run: &GripRun,
    seed: u64,
) -> Result<Vec<(Phase, WristTick)>> {
    ensure!(
        run.set_n > 0.0 && run.approach_rad_s > 0.0 && object.stiffness_n_m > 0.0,
        "a grip needs a positive set point, approach speed and object stiffness"
    );
    let mut sim = WristSim::opened(params, object, seed, run.settle_s)?;
    sim.set_pair(run.pair)?;
    let mut out = Vec::new();
    sim.run(Phase::Open, run.settle_s, &mut out);
    let grip = Command {
        mode: run.mode,
        trajectory: Trajectory::Grip {
            force_n: run.set_n as f32,
            approach_rad_s: run.approach_rad_s as f32,
        },
    };
    sim.set_command(JAW_A, grip)?;
    if run.pair {
        sim.set_command(JAW_B, grip)?;
    }
    sim.run(Phase::Grasp, run.grip_s, &mut out);
    // Open in the mode the grip ran in (its reference is that mode's
    // angle), from where each jaw's reference stands (its last tick's).
    let last = out.last().map(|(_, t): &(Phase, WristTick)| t.outputs);
    for j in [JAW_A, JAW_B] {
        let from = last.map_or(0.0, |o| o[j].est.theta_ref_rad);
        sim.set_command(j, joint_move(run.mode, f64::from(from), 0.0, run.release_s))?;
    }
    sim.run(Phase::Release, run.release_s, &mut out);
    sim.run(Phase::After, run.release_s, &mut out);
    Ok(out)
}

/// Summarise a grip run (`pair` as it ran).
pub fn grip_stats(ticks: &[(Phase, WristTick)], set_n: f64, pair: bool) -> GripStats {
    let grip: Vec<GripSample> = ticks
        .iter()
        .filter(|(p, _)| *p == Phase::Grasp)
        .map(|(_, t)| {
            let (est_n, bound) = gripped_force(t, pair);
            GripSample {
                t_s: t.t_s,
                true_n: t.contact_n,
                est_n,
                lo_n: f64::from(bound.lo),
                hi_n: f64::from(bound.hi),
            }
        })
        .collect();
    GripStats {
        fault: first_fault(ticks),
        ..grip_stats_of(&grip, set_n)
    }
}

/// The first fault any joint latched in a run, as "joint NAME: fault".
fn first_fault(ticks: &[(Phase, WristTick)]) -> Option<String> {
    ticks.iter().find_map(|(_, t)| {
        t.outputs.iter().enumerate().find_map(|(j, o)| {
            o.fault
                .map(|f| format!("joint {}: {f}", crate::wrist_log::JOINT_NAMES[j]))
        })
    })
}

/// What a grasp run measured.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct GraspStats {
    /// Mean true contact force in the stable hold (the hold's second half), N.
    pub hold_true_n: f64,
    /// Mean clamp estimate there, N.
    pub hold_est_n: f64,
    /// `100 (1 - |est - true| / true)` of those means, %.
    pub hold_accuracy_pct: f64,
    /// Share of all ticks whose true clamp force is inside the bound.
    pub coverage: f64,
    /// The same over the hold's ticks.
    pub hold_coverage: f64,
    /// Mean bound width in the stable hold, N.
    pub hold_bound_width_n: f64,
    /// Share of the hold's ticks whose total-force bound (Eq. 5, the four
    /// joints together) holds the true total, per component of the wrist
    /// frame.
    pub hold_total_coverage: [f64; 3],
    /// The total force's bound widths in the stable hold.
    pub hold_total: TotalSpread,
    /// Largest |estimate| with the jaws open (before and after), N.
    pub open_max_n: f64,
    /// The first fault a joint latched (joint and fault), if any.
    pub fault: Option<String>,
}

/// How wide Eq. 5's total-force bound is over some ticks, and how much of
/// it the force limit makes (what the joints do not see), per wrist-frame
/// component.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct TotalSpread {
    /// Median bound width, N (infinite where more than half are unbounded).
    pub width_n: [f64; 3],
    /// Mean share of the width the force limit makes: 0 where the joints
    /// fix the component, 1 where they see none of it (an unbounded tick
    /// counts 1).
    pub limit_share: [f64; 3],
}

impl TotalSpread {
    /// Over `totals` (zeros when there are none).
    pub fn of(totals: &[wrist::TotalForce]) -> Self {
        let n = totals.len();
        if n == 0 {
            return Self::default();
        }
        let per = |k: usize| {
            let mut w: Vec<f64> = totals
                .iter()
                .map(|t| f64::from(t.force_n[k].width()))
                .collect();
            w.sort_by(f64::total_cmp);
            let share: f64 = totals
                .iter()
                .map(|t| {
                    let w = f64::from(t.force_n[k].width());
                    if w > 0.0 && w.is_finite() {
                        2.0 * f64::from(t.prior_n[k]) / w
                    } else {
                        1.0
                    }
                })
                .sum();
            (w[n / 2], share / n as f64)
        };
        let [x, y, z] = [0, 1, 2].map(per);
        Self {
            width_n: [x.0, y.0, z.0],
            limit_share: [x.1, y.1, z.1],
        }
    }
}

/// Summarise a grasp run.
pub fn grasp_stats(g: &Geometry, ticks: &[(Phase, WristTick)]) -> GraspStats {
    let hold: Vec<&WristTick> = ticks
        .iter()
        .filter(|(p, _)| *p == Phase::Hold)
        .map(|(_, t)| t)
        .collect();
    let stable = &hold[hold.len() / 2..];
    let mean = |f: &dyn Fn(&WristTick) -> f64, v: &[&WristTick]| {
        v.iter().map(|t| f(t)).sum::<f64>() / v.len().max(1) as f64
    };
    let inside = |t: &WristTick| {
        let c = t.contact_n as f32;
        t.clamp_bound_n.lo <= c + 1e-6 && c - 1e-6 <= t.clamp_bound_n.hi
    };
    let hold_true_n = mean(&|t| t.contact_n, stable);
    let hold_totals: Vec<wrist::TotalForce> = hold
        .iter()
        .map(|t| total_force(g, t.pose_rad, t.torque_bound_nm))
        .collect();
    let hold_est_n = mean(&|t| t.clamp_n, stable);
    GraspStats {
        hold_true_n,
        hold_est_n,
        hold_accuracy_pct: 100.0 * (1.0 - (hold_est_n - hold_true_n).abs() / hold_true_n),
        coverage: ticks.iter().filter(|(_, t)| inside(t)).count() as f64
            / ticks.len().max(1) as f64,
        hold_coverage: hold.iter().filter(|t| inside(t)).count() as f64 / hold.len().max(1) as f64,
        hold_bound_width_n: mean(&|t| f64::from(t.clamp_bound_n.width()), stable),
        hold_total_coverage: core::array::from_fn(|k| {
            let inside = hold.iter().zip(&hold_totals).filter(|(t, total)| {
                let b = total.force_n[k];
                let x = t.total_true_n[k] as f32;
                b.lo <= x + 1e-6 && x - 1e-6 <= b.hi
            });
            inside.count() as f64 / hold.len().max(1) as f64
        }),
        hold_total: TotalSpread::of(&hold_totals[hold.len() / 2..]),
        open_max_n: ticks
            .iter()
            .filter(|(p, _)| matches!(p, Phase::Open | Phase::After))
            .map(|(_, t)| t.clamp_n.abs())
            .fold(0.0, f64::max),
        fault: first_fault(ticks),
    }
}

/// Joint `j`'s name ([`crate::wrist_log::JOINT_NAMES`]), or what it is.
fn joint_name(j: usize) -> String {
    crate::wrist_log::JOINT_NAMES
        .get(j)
        .map_or_else(|| format!("{j} (no such joint)"), |n| (*n).to_owned())
}

/// Why the wrist's joints refused a command, for a person.
fn refused_text(e: cable_joint::joints::Refused) -> String {
    use cable_joint::joints::Refused;
    match e {
        Refused::NoSuchJoint(j) => format!("no joint {j}"),
        Refused::NotAPair(j) => format!("joint {} cannot pair with itself", joint_name(j)),
        Refused::Faulted { joint, fault } => format!(
            "joint {} has latched a fault: {fault} (no drive runs until it is cleared)",
            joint_name(joint)
        ),
        Refused::CausePersists(j) => format!(
            "joint {}'s fault cannot be cleared while its cause persists",
            joint_name(j)
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn object(k: f64) -> SoftObject {
        SoftObject {
            width_m: 10e-3,
            stiffness_n_m: k,
            damping_n_s_m: 0.5,
        }
    }

    #[test]
    fn the_gap_and_the_closing_angle_agree() {
        let p = WristParams::uniform(PlantParams::default(), Config::default());
        let th = p.theta_for_gap(8e-3);
        assert!((p.gap_m(th, th) - 8e-3).abs() < 1e-12);
        assert!(p.gap_m(0.0, 0.0) > 13e-3, "jaws 20° open, 20 mm long");
    }

    #[test]
    fn the_object_only_pushes() {
        let o = object(1000.0);
        assert_eq!(contact(&o, 11e-3, 0.0), 0.0);
        assert!((contact(&o, 9e-3, 0.0) - 1.0).abs() < 1e-12);
        assert_eq!(contact(&o, 9.99e-3, 1.0), 0.0, "opening fast: no pull");
    }
}
