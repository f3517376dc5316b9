//! The wrist's links as rigid bodies (seed 000 Eq. 1's `D(q) q'' + H(q,
//! q') + G(q)`): the simulator's truth, and the no-contact run that
//! identifies the core's Eq. 3 model ([`cable_joint::wrist_dynamics`]).
//!
//! # The simulator's links
//!
//! [`Links`]: the roll body's inertia about the shaft, and three uniform
//! slender rods: the wrist link from the pitch axis to the jaws' axis
//! (`l_2`) and each jaw from its axis to its tip (`l_e`), under gravity `g`
//! fixed in the shaft's frame. Their torques come from Lagrange's equations
//! by finite differences of the bodies' positions, written with rotation
//! matrices: an independent path from the core's Newton–Euler regressor,
//! which a test checks against it.
//!
//! Each joint's plant takes the links' torque on it as part of its
//! external tip force (`tau / l_e`, positive a load), and its own diagonal
//! `D_jj(q)` as a tip mass, so the plant's integrator carries the links'
//! inertia on its own joint implicitly; the other joints' accelerations
//! enter from the previous tick (they change little in 0.5 ms, and the
//! off-diagonal terms are small against the cables' reflected inertia).
//!
//! # The prototype's scale
//!
//! The seed gives no masses. [`Links::prototype`] assumes stainless-steel
//! parts (7.9 g/cm³) of an 8 mm instrument: a jaw of 20 × 2 × 1 mm
//! (0.32 g), a wrist link of 9 mm with a 5 × 5 mm section, half of it hollow
//! (0.89 g), the roll body's inertia that of a 1 g ring of 3 mm radius. At
//! that scale gravity puts at most `0.32 g × 9.81 × 10 mm ≈ 3e-5 N·m` on a
//! jaw, 1.5 mN at its tip: far below what the joints' estimates resolve
//! (their no-load error in motion is 0.05-0.5 N RMS). [`Links::scaled`]
//! makes a heavier instrument (the tests use it where the torques must
//! stand above rounding; under the prototype's tuning a wrist ten times
//! heavier latched a fault in free motion).

use anyhow::{ensure, Result};
use cable_joint::filter::LowPass1;
use cable_joint::lsq::{compact_row, BatchLsq, LsqConfig};
use cable_joint::trajectory::Trajectory;
use cable_joint::wrist::{Geometry, Interval};
use cable_joint::wrist_dynamics::{regressor, InverseDynamics, N_LINKS, N_PARAMS, PARAM_NAMES};
use cable_joint::{Command, Config, Mode};
use serde::Serialize;

use crate::ident::excite_wrist::WristDesign;
use crate::plot::{Panel, Series};
use crate::scenario::G_M_S2;
use crate::stats::rms;
use crate::wrist::{
    Eq3Model, Eq3Timing, MotionEstimator, SoftObject, WristParams, WristSim, WristTick, ROLL,
};
use crate::wrist_log::JOINT_NAMES;

/// The wrist's links (module docs).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Links {
    /// The roll body's inertia about the shaft, kg·m².
    pub roll_inertia_kg_m2: f64,
    /// The wrist link's mass (a rod from the pitch axis to the jaws' axis), kg.
    pub wrist_link_kg: f64,
    /// Each jaw's mass (a rod from its axis to its tip), kg.
    pub jaw_kg: [f64; 2],
    /// Gravity in the shaft frame, m/s².
    pub gravity_m_s2: [f64; 3],
}

impl Links {
    /// The prototype's scale (module docs), held with the shaft level and
    /// turned 30° about it: gravity `9.81 (-cos 30°, -sin 30°, 0)`, so it
    /// loads the pitch and both jaws.
    pub fn prototype() -> Self {
        let steel_kg_m3 = 7900.0;
        let jaw = steel_kg_m3 * 20e-3 * 2e-3 * 1e-3;
        let link = steel_kg_m3 * 9e-3 * 25e-6 * 0.5;
        let (s, c) = 30f64.to_radians().sin_cos();
        Self {
            roll_inertia_kg_m2: 1e-3 * 3e-3 * 3e-3,
            wrist_link_kg: link,
            jaw_kg: [jaw, jaw],
            gravity_m_s2: [-G_M_S2 * c, -G_M_S2 * s, 0.0],
        }
    }

    /// Every mass and inertia times `k` (the same shapes, a heavier
    /// instrument).
    pub fn scaled(self, k: f64) -> Self {
        Self {
            roll_inertia_kg_m2: k * self.roll_inertia_kg_m2,
            wrist_link_kg: k * self.wrist_link_kg,
            jaw_kg: self.jaw_kg.map(|m| k * m),
            ..self
        }
    }

    /// The core's base parameters of these links (the first [`N_LINKS`] of
    /// [`cable_joint::wrist_dynamics::PARAM_NAMES`]): a uniform rod of
    /// mass `m` and length `L` from its joint has `X = m L / 2`, `XX = m
    /// L^2 / 3`; the jaws' masses fold into the wrist link's moments at
    /// `l_2`.
    pub fn base_params(&self, g: &Geometry) -> [f64; N_LINKS] {
        let l2 = f64::from(g.pitch_to_jaw_m);
        let le = f64::from(g.jaw_length_m);
        let [ma, mb] = self.jaw_kg;
        let m2 = self.wrist_link_kg;
        [
            self.roll_inertia_kg_m2,
            m2 * l2 / 2.0 + (ma + mb) * l2,
            m2 * l2 * l2 / 3.0 + (ma + mb) * l2 * l2,
            ma * le / 2.0,
            ma * le * le / 3.0,
            mb * le / 2.0,
            mb * le * le / 3.0,
        ]
    }

    /// The rods as point masses at two-point Gauss nodes (exact for the
    /// moments up to the second, all a rod's dynamics needs): positions in
    /// the shaft frame at `q` (jaw angles are the core's `q_3`).
    fn points(&self, g: &Geometry, q: [f64; 4]) -> [(f64, [f64; 3]); 6] {
        let l2 = f64::from(g.pitch_to_jaw_m);
        let le = f64::from(g.jaw_length_m);
        let node = |len: f64, k: usize| {
            let u = 1.0 / 3f64.sqrt();
            0.5 * len * if k == 0 { 1.0 - u } else { 1.0 + u }
        };
        let wrist = |v: [f64; 3]| rot_z(q[0], rot_y(q[1], v));
        let jaw = |angle: f64, s: f64| {
            let v = rot_x(angle, [0.0, 0.0, s]);
            wrist([v[0], v[1], v[2] + l2])
        };
        let [ma, mb] = self.jaw_kg;
        let m2 = self.wrist_link_kg;
        [
            (m2 / 2.0, wrist([0.0, 0.0, node(l2, 0)])),
            (m2 / 2.0, wrist([0.0, 0.0, node(l2, 1)])),
            (ma / 2.0, jaw(-q[2], node(le, 0))),
            (ma / 2.0, jaw(-q[2], node(le, 1))),
            (mb / 2.0, jaw(q[3], node(le, 0))),
            (mb / 2.0, jaw(q[3], node(le, 1))),
        ]
    }

    /// `L = T - V` at `(q, q')`, speeds of the points by central
    /// differences along `q'`.
    fn lagrangian(&self, g: &Geometry, q: [f64; 4], qd: [f64; 4]) -> f64 {
        let h = 1e-6;
        let plus = self.points(g, core::array::from_fn(|j| q[j] + h * qd[j]));
        let minus = self.points(g, core::array::from_fn(|j| q[j] - h * qd[j]));
        let here = self.points(g, q);
        let mut l = 0.5 * self.roll_inertia_kg_m2 * qd[0] * qd[0];
        for ((m, p), ((_, pp), (_, pm))) in here.iter().zip(plus.iter().zip(&minus)) {
            let v2: f64 = (0..3).map(|i| ((pp[i] - pm[i]) / (2.0 * h)).powi(2)).sum();
            let height: f64 = (0..3).map(|i| self.gravity_m_s2[i] * p[i]).sum();
            l += 0.5 * m * v2 + m * height;
        }
        l
    }

    /// The torque each joint must add to move the links along `q(t) = q +
    /// q' t + q'' t^2 / 2` at `t = 0`, N·m (order roll, pitch, jaw A, jaw
    /// B): Lagrange's `d/dt dL/dq'_j - dL/dq_j` by finite differences.
    pub fn torque_nm(&self, g: &Geometry, q: [f64; 4], qd: [f64; 4], qdd: [f64; 4]) -> [f64; 4] {
        // L is quadratic in the speeds: a wide step there is exact and
        // keeps rounding out of the time derivative.
        let dl_dqd = |t: f64, j: usize| {
            let qt: [f64; 4] = core::array::from_fn(|i| q[i] + qd[i] * t + 0.5 * qdd[i] * t * t);
            let vt: [f64; 4] = core::array::from_fn(|i| qd[i] + qdd[i] * t);
            let (mut vp, mut vm) = (vt, vt);
            vp[j] += 0.5;
            vm[j] -= 0.5;
            self.lagrangian(g, qt, vp) - self.lagrangian(g, qt, vm)
        };
        core::array::from_fn(|j| {
            let dt = 1e-3;
            let ddt = (dl_dqd(dt, j) - dl_dqd(-dt, j)) / (2.0 * dt);
            let e = 1e-5;
            let (mut qp, mut qm) = (q, q);
            qp[j] += e;
            qm[j] -= e;
            let dq = (self.lagrangian(g, qp, qd) - self.lagrangian(g, qm, qd)) / (2.0 * e);
            ddt - dq
        })
    }

    /// The inertia matrix `D(q)`, kg·m²: `D_jk = sum m (dp/dq_j . dp/dq_k)`
    /// plus the roll body's inertia.
    pub fn inertia_kg_m2(&self, g: &Geometry, q: [f64; 4]) -> [[f64; 4]; 4] {
        let e = 1e-6;
        let cols: [[(f64, [f64; 3]); 6]; 4] = core::array::from_fn(|j| {
            let (mut qp, mut qm) = (q, q);
            qp[j] += e;
            qm[j] -= e;
            let (p, m) = (self.points(g, qp), self.points(g, qm));
            core::array::from_fn(|k| {
                let d: [f64; 3] = core::array::from_fn(|i| (p[k].1[i] - m[k].1[i]) / (2.0 * e));
                (p[k].0, d)
            })
        });
        let mut d = [[0.0; 4]; 4];
        d[ROLL][ROLL] = self.roll_inertia_kg_m2;
        for (j, row) in d.iter_mut().enumerate() {
            for (k, x) in row.iter_mut().enumerate() {
                *x += (0..6)
                    .map(|p| {
                        let (m, a) = cols[j][p];
                        let b = cols[k][p].1;
                        m * (a[0] * b[0] + a[1] * b[1] + a[2] * b[2])
                    })
                    .sum::<f64>();
            }
        }
        d
    }
}

fn rot_z(a: f64, v: [f64; 3]) -> [f64; 3] {
    let (s, c) = a.sin_cos();
    [c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]]
}

fn rot_y(a: f64, v: [f64; 3]) -> [f64; 3] {
    let (s, c) = a.sin_cos();
    [c * v[0] + s * v[2], v[1], -s * v[0] + c * v[2]]
}

fn rot_x(a: f64, v: [f64; 3]) -> [f64; 3] {
    let (s, c) = a.sin_cos();
    [v[0], c * v[1] - s * v[2], s * v[1] + c * v[2]]
}

/// A free-motion run of the wrist (no object): each joint on its own
/// trajectory from rest at 0 rad.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct FreeRun {
    /// Each joint's trajectory (roll, pitch, jaw A, jaw B).
    pub trajectories: [Trajectory; 4],
    /// Settling at rest before the motion (left out of fits), s.
    pub settle_s: f64,
    /// Motion, s.
    pub duration_s: f64,
}

impl FreeRun {
    /// Every joint on the seed's three-sine "complex" trajectory with its
    /// own peak amplitude and base frequency.
    fn complex(amplitude_rad: [f32; 4], base_freq_hz: [f32; 4], duration_s: f64) -> Self {
        Self {
            trajectories: core::array::from_fn(|j| Trajectory::Complex {
                amplitude_rad: amplitude_rad[j],
                base_freq_hz: base_freq_hz[j],
            }),
            settle_s: 2.0,
            duration_s,
        }
    }

    /// The identification run, hand-made: the seed's three-sine trajectory
    /// at every joint, base frequencies incommensurate between joints so
    /// the poses, speeds and accelerations mix; 0.6 rad of roll and pitch,
    /// 0.3 rad of each jaw (opening past the rest and closing, never onto
    /// each other), 20 s.
    pub fn identification() -> Self {
        Self::complex([0.6, 0.6, 0.3, 0.3], [0.23, 0.31, 0.41, 0.37], 20.0)
    }

    /// A run the fit never saw: other amplitudes and frequencies, 10 s.
    pub fn validation() -> Self {
        Self::complex([0.5, 0.7, 0.25, 0.35], [0.29, 0.19, 0.33, 0.47], 10.0)
    }

    /// The designed excitation `design` after the same settling.
    pub fn designed(design: &WristDesign) -> Self {
        Self {
            trajectories: design.trajectories,
            settle_s: 2.0,
            duration_s: design.duration_s,
        }
    }
}

/// Run the wrist free (no object) on `run`, with `params`' Eq. 3 model
/// (if any) taken out of the joints' torques; every tick after the
/// settling.
pub fn run_free(params: &WristParams, run: &FreeRun, seed: u64) -> Result<Vec<WristTick>> {
    let (mut ticks, start) = run_free_settled(params, run, seed)?;
    Ok(ticks.split_off(start))
}

/// [`run_free`] with the settling's ticks kept: every tick from the
/// controllers' start, and the index of the first tick of the motion.
pub fn run_free_settled(
    params: &WristParams,
    run: &FreeRun,
    seed: u64,
) -> Result<(Vec<WristTick>, usize)> {
    let nothing = SoftObject {
        width_m: 0.0,
        stiffness_n_m: 0.0,
        damping_n_s_m: 0.0,
    };
    let mut sim = WristSim::new(params.clone(), nothing, seed)?;
    let period_s = sim.period_s();
    let hold = Command {
        mode: Mode::JointClosedLoop,
        trajectory: Trajectory::Hold { angle_rad: 0.0 },
    };
    for j in 0..4 {
        sim.set_command(j, hold)?;
    }
    let mut ticks: Vec<WristTick> = (0..(run.settle_s / period_s).round() as u64)
        .map(|_| sim.step())
        .collect();
    let start = ticks.len();
    for j in 0..4 {
        sim.set_command(
            j,
            Command {
                mode: Mode::JointClosedLoop,
                trajectory: run.trajectories[j],
            },
        )?;
    }
    ticks.extend((0..(run.duration_s / period_s).round() as u64).map(|_| sim.step()));
    if let Some((j, f)) = ticks.iter().find_map(|t| {
        t.outputs
            .iter()
            .enumerate()
            .find_map(|(j, o)| o.fault.map(|f| (j, f)))
    }) {
        anyhow::bail!("the free run latched a fault on joint {j}: {f}");
    }
    Ok((ticks, start))
}

/// A joint's torque as its fused estimate reads it, N·m.
fn estimated_torque_nm(params: &WristParams, t: &WristTick, j: usize) -> f64 {
    f64::from(t.outputs[j].est.f_ext_fused_n)
        * f64::from(params.configs[j].machine.gripper_length_m)
}

/// One tick of a free run as Eq. 3's fit reads it: the joints' JAE angles
/// (the motion is differentiated from them by the fit's observer) and
/// each joint's torque as its fused estimate reads it (the estimate times
/// `l_e`), from the simulated wrist or a rig's logs ([`crate::wrist_log`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Eq3Sample {
    /// Each joint's JAE angle, rad.
    pub theta_hat_rad: [f32; 4],
    /// Each joint's estimated torque, N·m.
    pub torque_nm: [f64; 4],
    /// Each joint's bound on it, `[lo, hi]`, N·m (the estimate's own,
    /// times `l_e`).
    pub bound_nm: [[f32; 2]; 4],
}

impl Eq3Sample {
    /// A simulated wrist's tick.
    pub fn of_tick(params: &WristParams, t: &WristTick) -> Self {
        let l = |j: usize| params.configs[j].machine.gripper_length_m;
        Self {
            theta_hat_rad: core::array::from_fn(|j| t.outputs[j].est.theta_hat_rad),
            torque_nm: core::array::from_fn(|j| estimated_torque_nm(params, t, j)),
            bound_nm: core::array::from_fn(|j| {
                let e = &t.outputs[j].est;
                [e.f_ext_lo_n * l(j), e.f_ext_hi_n * l(j)]
            }),
        }
    }
}

/// What Eq. 3's fit needs besides the samples: the wrist's dimensions,
/// each joint's smooth-sign width ([`sign_speeds_rad_s`]), gravity in the
/// shaft frame (the holder's) and how the model is read against the
/// estimates ([`Eq3Timing`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Eq3Setting {
    /// The wrist's dimensions.
    pub geometry: Geometry,
    /// Each joint's smooth-sign width, rad/s.
    pub sign_speed_rad_s: [f32; 4],
    /// Gravity in the shaft frame, m/s².
    pub gravity_m_s2: [f64; 3],
    /// The period, the estimates' low-pass and the jaws' opening.
    pub timing: Eq3Timing,
}

/// The motion observer's bandwidths the fit tries, as multiples of `Q`'s:
/// at `Q`'s own the observer's third-order lag is not `Q`'s first-order
/// one, and the friction and the links' columns soak up the difference;
/// faster, the observer lags less and lets more of the JAE's noise into
/// the accelerations. Which is best depends on the run's noise, so the
/// fit chooses on held-out data ([`fit_eq3`]).
pub const MOTION_BANDWIDTH_MULTIPLES: [f32; 7] = [1.0, 2.0, 3.0, 4.0, 6.0, 8.0, 12.0];

/// What the Eq. 3 fit found.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct InverseDynamicsFit {
    /// The model, ready for [`WristParams::inverse_dynamics`].
    pub body: InverseDynamics,
    /// The motion observer's bandwidth the fit chose, Hz.
    pub motion_bandwidth_hz: f32,
    /// For each of [`MOTION_BANDWIDTH_MULTIPLES`]: the bandwidth (Hz) and
    /// the held-out torque RMS of its model (N·m, the raw RMS where its
    /// model was not kept), which chose it.
    pub bandwidth_held_out_nm: [[f64; 2]; MOTION_BANDWIDTH_MULTIPLES.len()],
    /// Each parameter's relative standard deviation, % (NaN where left
    /// out).
    pub pct_sigma: [f64; N_PARAMS],
    /// The column-equilibrated regressor's condition number (of the
    /// columns kept).
    pub condition: f64,
    /// The same with every column (the links' too).
    pub condition_with_links: f64,
    /// Each parameter's `%sigma` in the fit with every column.
    pub pct_sigma_with_links: [f64; N_PARAMS],
    /// Residual RMS of the fit, N·m.
    pub rmse_nm: f64,
    /// Rows fitted (four per tick).
    pub rows: u64,
    /// Whether the links' columns fitted values real links could have
    /// (else they are left out and the model is each joint's friction).
    pub links_observed: bool,
    /// The links' parameters and their `%sigma` as the fit with every
    /// column found them (what [`Self::links_observed`] judged).
    pub with_links: [[f64; 2]; N_LINKS],
    /// The torques' RMS on the run's last 30 %, raw and less the model
    /// fitted on the first 70 %, N·m.
    pub held_out_rms_nm: [f64; 2],
    /// Whether the model cut the held-out RMS (else it is not used).
    pub kept: bool,
    /// Each joint's friction sign as the chosen bandwidth's rows show it,
    /// rad/s ([`sign_width_seen_rad_s`]; NaN from [`fit_rows`] alone).
    pub sign_width_seen_rad_s: [f64; 4],
}

impl InverseDynamicsFit {
    /// The model if it was kept.
    pub fn model(&self) -> Option<Eq3Model> {
        self.kept.then_some(Eq3Model {
            body: self.body,
            motion_bandwidth_hz: self.motion_bandwidth_hz,
        })
    }
}

/// Each joint's smooth-sign width for Eq. 3's friction: its JAE's
/// sign-switch speed at slider 2 turned to the joint, rad/s.
pub fn sign_speeds_rad_s(configs: &[Config; 4]) -> [f32; 4] {
    configs.map(|c| c.jae.sign_switch_m_s / c.machine.pulley_radius_m)
}

/// Fit Eq. 3's parameters to a simulated free run ([`fit_eq3`] on its
/// ticks), gravity `gravity_m_s2` (the holder's).
pub fn fit_inverse_dynamics(
    params: &WristParams,
    ticks: &[WristTick],
    gravity_m_s2: [f64; 3],
) -> Result<InverseDynamicsFit> {
    let samples: Vec<Eq3Sample> = ticks
        .iter()
        .map(|t| Eq3Sample::of_tick(params, t))
        .collect();
    let setting = Eq3Setting {
        geometry: params.geometry,
        sign_speed_rad_s: sign_speeds_rad_s(&params.configs),
        gravity_m_s2,
        timing: params.eq3_timing(),
    };
    fit_eq3(&setting, &samples)
}

/// One sample's four rows of Eq. 3's regressor, one per joint.
pub type Eq3Rows = [[f64; N_PARAMS]; 4];

/// The regressor's rows of `samples` as the estimates see the torque: the
/// motion from an observer of `bandwidth_hz`, every column through `Q`
/// ([`Eq3Timing`]; started at its first value).
pub fn filtered_rows(
    setting: &Eq3Setting,
    samples: &[Eq3Sample],
    bandwidth_hz: f32,
) -> Vec<Eq3Rows> {
    let t = &setting.timing;
    let mut motion = MotionEstimator::new(bandwidth_hz, t.period_s, t.jaw_open_rad);
    let q = LowPass1::new(t.q_cutoff_rad_s, t.period_s as f32);
    let gravity = setting.gravity_m_s2.map(|x| x as f32);
    let mut state: Option<[[f32; N_PARAMS]; 4]> = None;
    samples
        .iter()
        .map(|s| {
            let m = motion.update(s.theta_hat_rad);
            let y = regressor(&setting.geometry, gravity, setting.sign_speed_rad_s, &m);
            let z = state.get_or_insert(y);
            for (zr, yr) in z.iter_mut().zip(&y) {
                for (zc, yc) in zr.iter_mut().zip(yr) {
                    q.update(zc, *yc);
                }
            }
            z.map(|r| r.map(f64::from))
        })
        .collect()
}

/// Fit Eq. 3's parameters to a free run: every sample's four joint
/// torques against the regressor's rows as the estimates see them
/// ([`filtered_rows`]), by the core's least squares ([`fit_rows`]), at each
/// of [`MOTION_BANDWIDTH_MULTIPLES`] of `Q`'s bandwidth; the one whose
/// model leaves the least torque on the run's held-out last 30 % is
/// chosen (the raw torque counts where a model is not kept).
pub fn fit_eq3(setting: &Eq3Setting, samples: &[Eq3Sample]) -> Result<InverseDynamicsFit> {
    let torques: Vec<[f64; 4]> = samples.iter().map(|s| s.torque_nm).collect();
    let base_hz = setting.timing.q_bandwidth_hz();
    let mut best: Option<InverseDynamicsFit> = None;
    let mut tried = [[0.0; 2]; MOTION_BANDWIDTH_MULTIPLES.len()];
    for (k, m) in MOTION_BANDWIDTH_MULTIPLES.iter().enumerate() {
        let bandwidth_hz = m * base_hz;
        let rows = filtered_rows(setting, samples, bandwidth_hz);
        let fit = fit_rows(setting, &rows, &torques)?;
        let left = fit.held_out_rms_nm[usize::from(fit.kept)];
        tried[k] = [f64::from(bandwidth_hz), left];
        let better = best
            .as_ref()
            .is_none_or(|b| left < b.held_out_rms_nm[usize::from(b.kept)]);
        if better {
            best = Some(InverseDynamicsFit {
                motion_bandwidth_hz: bandwidth_hz,
                ..fit
            });
        }
    }
    let best = best.ok_or_else(|| anyhow::anyhow!("Eq. 3 fit: no bandwidth tried"))?;
    // The chosen bandwidth's rows again (cheaper than keeping them).
    let rows = filtered_rows(setting, samples, best.motion_bandwidth_hz);
    Ok(InverseDynamicsFit {
        bandwidth_held_out_nm: tried,
        sign_width_seen_rad_s: sign_width_seen_rad_s(&rows),
        ..best
    })
}

/// Joint `j`'s Coulomb and viscous columns in Eq. 3's regressor (after
/// the links' [`N_LINKS`]; `cable_joint::wrist_dynamics`'s order).
fn friction_columns(j: usize) -> [usize; 2] {
    [N_LINKS + 2 * j, N_LINKS + 2 * j + 1]
}

/// Each joint's friction sign as a fit sees it, rad/s: the width `w`
/// whose `tanh(|q'| / w)` best follows (least squares over the run) the
/// joint's Coulomb column against its viscous column, both as
/// [`filtered_rows`] gives them (the observed speed's sign, and the speed,
/// through `Q`). On smooth motion `w` is the regressor's own
/// [`Eq3Setting::sign_speed_rad_s`]; where the joint sticks and slips at
/// low speed `Q` averages its sign over the slips, the Coulomb column
/// grows in proportion to the speed up to about `w`,
/// and below that speed a run cannot tell Coulomb from viscous friction.
/// NaN for a joint that never moves.
pub fn sign_width_seen_rad_s(rows: &[Eq3Rows]) -> [f64; 4] {
    core::array::from_fn(|j| {
        let [c, v] = friction_columns(j);
        let pairs: Vec<(f64, f64)> = rows
            .iter()
            .map(|r| (r[j][c].abs(), r[j][v].abs()))
            .filter(|(_, speed)| *speed > 0.0)
            .collect();
        if pairs.is_empty() {
            return f64::NAN;
        }
        let misfit = |log_w: f64| {
            let w = log_w.exp();
            pairs
                .iter()
                .map(|(sign, speed)| (sign - (speed / w).tanh()).powi(2))
                .sum::<f64>()
        };
        // Golden-section search on ln w over 1 mrad/s to 100 rad/s (each
        // row's misfit is unimodal in w, `tanh(v / w)` falling as w grows;
        // the unit test checks the search finds known widths).
        let (mut a, mut b) = (1e-3f64.ln(), 100f64.ln());
        let phi = (5f64.sqrt() - 1.0) / 2.0;
        let (mut x1, mut x2) = (b - phi * (b - a), a + phi * (b - a));
        let (mut f1, mut f2) = (misfit(x1), misfit(x2));
        while b - a > 1e-4 {
            if f1 <= f2 {
                (b, x2, f2) = (x2, x1, f1);
                x1 = b - phi * (b - a);
                f1 = misfit(x1);
            } else {
                (a, x1, f1) = (x1, x2, f2);
                x2 = a + phi * (b - a);
                f2 = misfit(x2);
            }
        }
        (0.5 * (a + b)).exp()
    })
}

/// One panel per joint of what [`sign_width_seen_rad_s`] fitted: the
/// Coulomb column's magnitude against the speed's (a point every `stride`
/// rows), with `tanh(|q'| / w)` at the width seen and at the regressor's
/// `v_s`.
pub fn sign_panels(
    rows: &[Eq3Rows],
    seen_rad_s: [f64; 4],
    v_s_rad_s: [f32; 4],
    title: &str,
) -> Vec<Panel> {
    let stride = (rows.len() / 2000).max(1);
    (0..4)
        .map(|j| {
            let [c, v] = friction_columns(j);
            let (speed, sign): (Vec<f64>, Vec<f64>) = rows
                .iter()
                .step_by(stride)
                .map(|r| (r[j][v].abs(), r[j][c].abs()))
                .unzip();
            let top = speed.iter().copied().fold(0.0, f64::max);
            let grid: Vec<f64> = (0..=100).map(|k| top * f64::from(k) / 100.0).collect();
            let curve = |w: f64| grid.iter().map(|x| (x / w).tanh()).collect::<Vec<f64>>();
            let v_s = f64::from(v_s_rad_s[j]);
            Panel::new(
                format!(
                    "{title}: {}, friction sign as the fit sees it",
                    JOINT_NAMES[j]
                ),
                "|q'| through Q [rad/s]",
                "|Coulomb column|",
            )
            .with(Series::points("rows", speed, sign))
            .with(Series::line(
                format!("tanh(|q'|/w), w = {:.3} rad/s seen", seen_rad_s[j]),
                grid.clone(),
                curve(seen_rad_s[j]),
            ))
            .with(Series::line(
                format!("tanh(|q'|/v_s), v_s = {v_s:.3} rad/s"),
                grid.clone(),
                curve(v_s),
            ))
        })
        .collect()
}

/// Fit Eq. 3's parameters to `torques` against `rows` (one of each per
/// sample, in time order), by the core's least squares.
///
/// * The links' columns are kept only if what they fit could be links
///   ([`unphysical_links`]: a negative inertia or moment, or a second
///   moment that puts mass beyond a body's length): else the estimates do
///   not see the links (their columns took other errors) and the model
///   keeps each joint's friction alone
///   ([`InverseDynamicsFit::links_observed`]).
/// * The model is kept only if it helps on motion it did not see: fitted
///   first on the run's first 70 %, it must cut the torques' RMS on the
///   last 30 % ([`InverseDynamicsFit::kept`]); the model returned is then
///   fitted on the whole run.
///
/// The bandwidth fields and the sign width are left for the caller
/// ([`fit_eq3`]).
pub fn fit_rows(
    setting: &Eq3Setting,
    rows: &[Eq3Rows],
    torques: &[[f64; 4]],
) -> Result<InverseDynamicsFit> {
    ensure!(
        rows.len() == torques.len(),
        "Eq. 3 fit: {} samples of rows against {} of torques",
        rows.len(),
        torques.len()
    );
    // A fit on samples `part` with the columns `drop` left out; its
    // parameters and deviations put back in regressor order (zero where
    // dropped).
    let fit_on = |part: std::ops::Range<usize>, drop: &[bool; N_PARAMS]| {
        // The condition number is reported, not a reason to refuse.
        let config = LsqConfig {
            max_condition: f64::INFINITY,
        };
        let active = drop.iter().filter(|d| !**d).count();
        let mut lsq = BatchLsq::<N_PARAMS>::new(active, config)
            .map_err(|e| anyhow::anyhow!("Eq. 3 fit: {e}"))?;
        let mut phi = [0.0; N_PARAMS];
        for (r, y) in rows[part.clone()].iter().zip(&torques[part]) {
            for (j, (row, y)) in r.iter().zip(y).enumerate() {
                let n = compact_row(row, drop, &mut phi);
                lsq.push(&phi[..n], *y)
                    .map_err(|e| anyhow::anyhow!("Eq. 3 fit, joint {j}: {e}"))?;
            }
        }
        let fit = lsq.solve().map_err(|e| anyhow::anyhow!("Eq. 3 fit: {e}"))?;
        let mut out = ([0.0; N_PARAMS], [0.0; N_PARAMS], [f64::NAN; N_PARAMS]);
        let kept = (0..N_PARAMS).filter(|k| !drop[*k]);
        for (i, k) in kept.enumerate() {
            out.0[k] = fit.params[i];
            out.1[k] = fit.std_dev[i];
            out.2[k] = fit.pct_sigma(i);
        }
        Ok::<_, anyhow::Error>((out, fit.condition, fit.rmse, fit.rows))
    };
    let n = rows.len();
    let mut drop = [false; N_PARAMS];
    let every = fit_on(0..n, &drop)?;
    let ((whole, _, whole_pct), condition_with_links, _, _) = every;
    let links_observed = unphysical_links(&setting.geometry, &whole[..N_LINKS]).is_empty();
    if !links_observed {
        drop[..N_LINKS].fill(true);
    }
    let split = n * 7 / 10;
    let ((first, _, _), _, _, _) = fit_on(0..split, &drop)?;
    let (mut raw, mut left) = (Vec::new(), Vec::new());
    for (r, y) in rows[split..].iter().zip(&torques[split..]) {
        for (phi, y) in r.iter().zip(y) {
            let pred: f64 = phi.iter().zip(&first).map(|(a, b)| a * b).sum();
            raw.push(*y);
            left.push(y - pred);
        }
    }
    let held_out_rms_nm = [rms(&raw), rms(&left)];
    // With the links seen, the model is the fit with every column.
    let ((p, sd, pct), condition, rmse_nm, rows_fitted) = if links_observed {
        every
    } else {
        fit_on(0..n, &drop)?
    };
    let gravity = setting.gravity_m_s2.map(|x| x as f32);
    Ok(InverseDynamicsFit {
        body: InverseDynamics {
            params: p.map(|x| x as f32),
            std_dev: sd.map(|x| x as f32),
            gravity_m_s2: gravity,
            sign_speed_rad_s: setting.sign_speed_rad_s,
        },
        motion_bandwidth_hz: setting.timing.q_bandwidth_hz(),
        bandwidth_held_out_nm: [[f64::NAN; 2]; MOTION_BANDWIDTH_MULTIPLES.len()],
        pct_sigma: pct,
        condition,
        condition_with_links,
        pct_sigma_with_links: whole_pct,
        rmse_nm,
        rows: rows_fitted,
        links_observed,
        with_links: core::array::from_fn(|k| [whole[k], whole_pct[k]]),
        held_out_rms_nm,
        kept: held_out_rms_nm[1] < held_out_rms_nm[0],
        sign_width_seen_rad_s: [f64::NAN; 4],
    })
}

/// What makes Eq. 3's link parameters `p` (the first [`N_LINKS`] of
/// [`PARAM_NAMES`]) impossible
/// for links of geometry `g` as [`cable_joint::wrist_dynamics`] models
/// them, one line each; empty if they could be real links. The roll
/// inertia is not negative. The wrist link and each jaw are slender
/// bodies whose mass lies along their axis between their joint and their
/// far end (`l_2`, the jaws' axis, for the wrist link, the jaws' masses
/// folded in there; `l_e` for a jaw): so for each, with `X = int s dm` and
/// `XX = int s^2 dm` over `0 <= s <= L`, `X >= 0` and `0 <= XX <= L X`.
pub fn unphysical_links(g: &Geometry, p: &[f64]) -> Vec<String> {
    let mut out = Vec::new();
    if p[0] < 0.0 {
        out.push(format!("{} = {:.3e} < 0", PARAM_NAMES[0], p[0]));
    }
    let bodies = [
        (1, f64::from(g.pitch_to_jaw_m), "l_2"),
        (3, f64::from(g.jaw_length_m), "l_e"),
        (5, f64::from(g.jaw_length_m), "l_e"),
    ];
    for (k, length_m, name) in bodies {
        let (x, xx) = (p[k], p[k + 1]);
        if x < 0.0 {
            out.push(format!("{} = {x:.3e} < 0", PARAM_NAMES[k]));
        }
        if xx < 0.0 {
            out.push(format!("{} = {xx:.3e} < 0", PARAM_NAMES[k + 1]));
        } else if x >= 0.0 && xx > length_m * x {
            out.push(format!(
                "{} = {xx:.3e} > {name} {} = {:.3e} (mass beyond the body's length)",
                PARAM_NAMES[k + 1],
                PARAM_NAMES[k],
                length_m * x
            ));
        }
    }
    out
}

/// Each joint's no-load error on a free run, as a force at `l_e`, N: the
/// links' true torque (what the estimate reads unless Eq. 3 takes it out)
/// and the estimate's error against the true zero, raw and with the run's
/// Eq. 3 model taken out.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct NoLoad {
    /// RMS of the links' true torque over `l_e`, N.
    pub links_rms_n: [f64; 4],
    /// RMS of the raw estimate (Eq. 3 left in), N.
    pub raw_rms_n: [f64; 4],
    /// RMS of the estimate with the run's Eq. 3 model taken out, N.
    pub corrected_rms_n: [f64; 4],
    /// Share of ticks whose own bound holds the true zero, per joint.
    pub raw_coverage: [f64; 4],
    /// Share of ticks whose bound (Eq. 3 taken out, its uncertainty added)
    /// holds the true zero, per joint.
    pub coverage: [f64; 4],
}

/// [`NoLoad`] of a simulated free run, the model its wrist ran with (as
/// it applied it, tick by tick).
pub fn no_load(params: &WristParams, ticks: &[WristTick]) -> NoLoad {
    let l = params
        .configs
        .map(|c| f64::from(c.machine.gripper_length_m));
    let links_rms_n = core::array::from_fn(|j| {
        rms(&ticks
            .iter()
            .map(|t| t.links_true_nm[j] / l[j])
            .collect::<Vec<_>>())
    });
    let per_tick = ticks.iter().map(|t| {
        let s = Eq3Sample::of_tick(params, t);
        (s, t.links_hat_nm, t.torque_bound_nm)
    });
    NoLoad {
        links_rms_n,
        ..no_load_stats(per_tick, l)
    }
}

/// [`NoLoad`]'s error figures from each tick's sample, the model's torque
/// taken out and the bound with it taken out (the links' true torque is
/// left zero: a simulated wrist's caller fills it, [`no_load`]; a rig's
/// samples do not know it, `wrist_estimate::no_load`).
pub fn no_load_stats(
    per_tick: impl Iterator<Item = (Eq3Sample, [f32; 4], [Interval; 4])>,
    l: [f64; 4],
) -> NoLoad {
    let (mut raw, mut corrected) = (vec![Vec::new(); 4], vec![Vec::new(); 4]);
    let (mut raw_held, mut held, mut n) = ([0usize; 4], [0usize; 4], 0usize);
    for (s, hat, bound) in per_tick {
        n += 1;
        for j in 0..4 {
            raw[j].push(s.torque_nm[j] / l[j]);
            corrected[j].push((s.torque_nm[j] - f64::from(hat[j])) / l[j]);
            let [lo, hi] = s.bound_nm[j];
            raw_held[j] += usize::from(Interval::new(lo, hi).contains(0.0));
            held[j] += usize::from(bound[j].contains(0.0));
        }
    }
    let share = |c: usize| c as f64 / n.max(1) as f64;
    NoLoad {
        links_rms_n: [0.0; 4],
        raw_rms_n: core::array::from_fn(|j| rms(&raw[j])),
        corrected_rms_n: core::array::from_fn(|j| rms(&corrected[j])),
        raw_coverage: raw_held.map(share),
        coverage: held.map(share),
    }
}

/// Checked: the links' masses are finite and not negative.
pub fn check(links: &Links) -> Result<()> {
    let all = [
        links.roll_inertia_kg_m2,
        links.wrist_link_kg,
        links.jaw_kg[0],
        links.jaw_kg[1],
    ];
    ensure!(
        all.iter().all(|x| x.is_finite() && *x >= 0.0)
            && links.gravity_m_s2.iter().all(|x| x.is_finite()),
        "the wrist's links need finite, non-negative masses and a finite gravity: {links:?}"
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use cable_joint::wrist_dynamics::WristMotion;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::*;

    /// A [`WristMotion`] from angles, speeds and accelerations.
    fn wrist_motion(q: [f64; 4], qd: [f64; 4], qdd: [f64; 4]) -> WristMotion {
        WristMotion {
            q_rad: q.map(|x| x as f32),
            qd_rad_s: qd.map(|x| x as f32),
            qdd_rad_s2: qdd.map(|x| x as f32),
        }
    }

    /// The sign width a run shows is the `tanh` width its Coulomb column
    /// follows: recovered from exact rows of widths 0.05 and 0.4 rad/s
    /// (smooth motion, and a joint that sticks and slips), NaN for a joint
    /// that never moves.
    #[test]
    fn the_sign_width_seen_is_the_width_the_coulomb_column_follows() {
        let widths = [0.05, 0.4, 0.4, f64::NAN];
        let rows: Vec<Eq3Rows> = (0..2000)
            .map(|k| {
                let speed = 1.5 * (k as f64 * 0.01).sin();
                let mut r = [[0.0; N_PARAMS]; 4];
                for (j, w) in widths.iter().enumerate() {
                    if w.is_finite() {
                        let [c, v] = friction_columns(j);
                        r[j][c] = (speed / w).tanh();
                        r[j][v] = speed;
                    }
                }
                r
            })
            .collect();
        let seen = sign_width_seen_rad_s(&rows);
        for j in 0..3 {
            assert!(
                (seen[j] / widths[j] - 1.0).abs() < 1e-3,
                "{j}: {seen:?} for {widths:?}"
            );
        }
        assert!(seen[3].is_nan(), "{seen:?}");
    }

    /// Real links pass the physical check at any mass (uniform rods from
    /// their joints, the jaws' masses folded in at `l_2`), also with the
    /// jaws' mass concentrated at their tips (`XX = l_e X`, the limit); a
    /// second moment that puts mass beyond a body's length, a negative
    /// first moment or inertia fails it, naming the parameter.
    #[test]
    fn only_moments_real_links_can_have_pass_the_links_check() {
        let g = Geometry::default();
        for k in [0.1, 1.0, 100.0] {
            let p = Links::prototype().scaled(k).base_params(&g);
            assert!(unphysical_links(&g, &p).is_empty(), "{k}: {p:?}");
        }
        let mut p = Links::prototype().base_params(&g);
        let le = f64::from(g.jaw_length_m);
        p[4] = le * p[3];
        assert!(
            unphysical_links(&g, &p).is_empty(),
            "mass at the tip: {p:?}"
        );
        p[4] = 1.01 * le * p[3];
        let e = unphysical_links(&g, &p);
        assert!(e.len() == 1 && e[0].contains(PARAM_NAMES[4]), "{e:?}");
        // Fitted on a run whose estimates do not resolve the links (the
        // report's default variant): every sign right on the wrist link,
        // a second moment 60 times what its length allows.
        let mut p = Links::prototype().base_params(&g);
        p[1] = 1.791e-5;
        p[2] = 9.943e-6;
        let e = unphysical_links(&g, &p);
        assert!(e.len() == 1 && e[0].contains(PARAM_NAMES[2]), "{e:?}");
        // A negative inertia and jaw B's negative first moment besides
        // (its second moment then needs no bound of its own).
        p[0] = -1e-9;
        p[5] = -1e-6;
        let e = unphysical_links(&g, &p);
        assert!(
            e.len() == 3 && e[0].contains(PARAM_NAMES[0]) && e[2].contains(PARAM_NAMES[5]),
            "{e:?}"
        );
    }

    /// The core's Eq. 3 regressor times these links' base parameters is
    /// the simulator's Lagrangian torque of the rods (two independent
    /// derivations), on random poses, speeds and accelerations, at a
    /// heavy scale so the torques stand well above rounding.
    #[test]
    fn the_cores_eq3_regressor_is_the_simulated_links_lagrangian_torque() {
        let g = Geometry::default();
        let links = Links::prototype().scaled(1000.0);
        let mut params = [0.0; N_PARAMS];
        for (p, x) in params.iter_mut().zip(links.base_params(&g)) {
            *p = x as f32;
        }
        let body = InverseDynamics {
            params,
            std_dev: [0.0; N_PARAMS],
            gravity_m_s2: links.gravity_m_s2.map(|x| x as f32),
            sign_speed_rad_s: [0.05; 4],
        };
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut next = || rng.gen_range(-1.0..1.0);
        for _ in 0..30 {
            let q: [f64; 4] = core::array::from_fn(|_| 1.5 * next());
            let qd: [f64; 4] = core::array::from_fn(|_| 5.0 * next());
            let qdd: [f64; 4] = core::array::from_fn(|_| 50.0 * next());
            let want = links.torque_nm(&g, q, qd, qdd);
            let got = body.torque_nm(&g, &wrist_motion(q, qd, qdd));
            let scale = want.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            for j in 0..4 {
                assert!(
                    (f64::from(got[j]) - want[j]).abs() < 1e-4 * scale,
                    "q {q:?} qd {qd:?} qdd {qdd:?} joint {j}: {} vs {}",
                    got[j],
                    want[j]
                );
            }
        }
    }

    /// `D(q)` is the torque's derivative in the accelerations: symmetric,
    /// and `D q''` is the torque less its part at `q'' = 0`.
    #[test]
    fn the_inertia_matrix_is_the_torques_acceleration_part() {
        let g = Geometry::default();
        let links = Links::prototype().scaled(1000.0);
        let q = [0.4, -0.6, 0.2, -0.3];
        let qd = [0.5, -1.0, 2.0, 1.5];
        let qdd = [10.0, -20.0, 30.0, 5.0];
        let d = links.inertia_kg_m2(&g, q);
        let t1 = links.torque_nm(&g, q, qd, qdd);
        let t0 = links.torque_nm(&g, q, qd, [0.0; 4]);
        for j in 0..4 {
            for k in 0..4 {
                assert!((d[j][k] - d[k][j]).abs() < 1e-9 * d[j][j].abs().max(1e-12));
            }
            let dq: f64 = (0..4).map(|k| d[j][k] * qdd[k]).sum();
            assert!(
                (t1[j] - t0[j] - dq).abs() < 1e-4 * dq.abs().max(1e-9),
                "joint {j}: {} vs {dq}",
                t1[j] - t0[j]
            );
        }
    }
}
