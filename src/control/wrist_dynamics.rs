//! Eq. 3: the free wrist's torque in regressor form, `tau_hat = Y(q, q',
//! q'') pi`, with the parameters `pi` a no-contact run identifies by least
//! squares (seed 000 Sect. 2.3: "the parameters can be obtained by inverse
//! dynamics identification").
//!
//! # What it adds to the joints' own models
//!
//! Eq. 3's `tau_hat = D(q) q'' + H(q, q') + G(q) + tau_f`. Each joint's
//! pulley, cables and friction are in its own single-joint model (the DOB
//! and the stretch chain), so a joint's fused estimate reads everything
//! else as external torque: the links' inertia and gravity, the torque the
//! *other* joints' motion puts on it (`D`'s off-diagonal terms, `H`'s
//! Coriolis and centrifugal terms), and whatever friction its own model
//! leaves while it moves. This module is that remainder: the links'
//! `D q'' + H + G` and, per joint, a Coulomb and a viscous term `tau_f =
//! f_c tanh(q' / v_s) + f_v q'` (the seed's `tau_f`, here the part of the
//! joint's friction its own model misses: either sign), so `tau_ext =
//! (estimate l_e) - tau_hat` is Eq. 4's `tau - tau_hat`. The smooth sign's
//! width `v_s` is the joint's JAE sign-switch speed turned to the joint
//! (`jae.sign_switch_m_s / machine.pulley_radius_m`, 0.05 rad/s by default).
//!
//! # The links (assumed and stated)
//!
//! The chain and frames are [`crate::wrist`]'s: roll `q_1` about the shaft
//! `z_0`, pitch `q_2` about `y_1`, each jaw about `x_2` at `l_2` from the
//! pitch axis (jaw A by `-q_3^a`, jaw B, its mirror image, by `+q_3^b`).
//!
//! * The roll body's mass sits on its axis: it adds its inertia about the
//!   shaft, `I_1`, and nothing else.
//! * The wrist link (the clevis between the pitch and the jaw axes) and
//!   each jaw are slender: their mass lies along their axis (`d_2` from the
//!   pitch axis towards the jaws, `d_3` from the jaw axis along the jaw),
//!   their inertia about their own long axis is neglected. A slender body
//!   of mass density `mu(s)` along `s` enters the dynamics only through its
//!   moments `X = int s dm` and `XX = int s^2 dm` about its joint; a point
//!   mass `m` at `c` has `X = m c`, `XX = m c^2`, a uniform rod from its
//!   joint `m L / 2` and `m L^2 / 3`.
//! * A jaw's mass itself (its zeroth moment) acts as a point mass at the
//!   jaw axis, which is a point of the wrist link at `l_2`: it cannot be
//!   told from the wrist link's own moments and is folded into them (the
//!   base parameters below).
//! * Gravity `g` is a constant vector in the shaft's frame `x_0 y_0 z_0`
//!   (the instrument's holder knows how it is held).
//!
//! # Parameters ([`N_PARAMS`], order of [`PARAM_NAMES`])
//!
//! The links' base parameters ([`N_LINKS`]): `I_1`; the wrist link's `X_2 +
//! (m_a + m_b) l_2` and `XX_2 + (m_a + m_b) l_2^2`; jaw A's `X_a`, `XX_a`;
//! jaw B's `X_b`, `XX_b`. Then each joint's `f_c`, `f_v`. The regressor is
//! linear in them: with the link's unit point `d` moving with acceleration
//! `a_d` (per unit of `s`) and the joint axes `u_j`, a slender body adds
//! `XX (u_j x d) . a_d - X (u_j x d) . g` to joint `j` (plus, for a jaw,
//! the cross terms with the jaw axis' own motion), derived by Newton-Euler
//! on the unit points. `host-sim`'s links (rods under Lagrange's equations
//! by finite differences, an independent derivation) are checked against
//! it.
//!
//! # Arithmetic
//!
//! `f32`, no allocation, sines through [`crate::math`]: one regressor costs
//! a few hundred multiplications, within a tick on the MCU if a wrist
//! controller wants it there. Joint order `[roll, pitch, jaw A, jaw B]`
//! (the host's wrist and [`crate::joints::Joints`]); jaw angles are
//! [`crate::wrist`]'s `q_3`.

use crate::math;
use crate::wrist::Geometry;

/// Number of the links' base parameters (the first of [`PARAM_NAMES`]).
pub const N_LINKS: usize = 7;

/// Number of parameters: the links' and each joint's Coulomb and viscous
/// friction.
pub const N_PARAMS: usize = N_LINKS + 8;

/// The parameters' names with their units, in regressor order.
pub const PARAM_NAMES: [&str; N_PARAMS] = [
    "roll_inertia_kg_m2",
    "wrist_first_moment_kg_m",
    "wrist_second_moment_kg_m2",
    "jaw_a_first_moment_kg_m",
    "jaw_a_second_moment_kg_m2",
    "jaw_b_first_moment_kg_m",
    "jaw_b_second_moment_kg_m2",
    "roll_coulomb_nm",
    "roll_viscous_nm_s_rad",
    "pitch_coulomb_nm",
    "pitch_viscous_nm_s_rad",
    "jaw_a_coulomb_nm",
    "jaw_a_viscous_nm_s_rad",
    "jaw_b_coulomb_nm",
    "jaw_b_viscous_nm_s_rad",
];

/// Joint indices of the wrist (rows of the regressor).
pub const ROLL: usize = 0;
/// Pitch.
pub const PITCH: usize = 1;
/// Jaw A.
pub const JAW_A: usize = 2;
/// Jaw B.
pub const JAW_B: usize = 3;

type V3 = [f32; 3];

fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn dot(a: V3, b: V3) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn scale(k: f32, a: V3) -> V3 {
    [k * a[0], k * a[1], k * a[2]]
}

/// Acceleration of the point `r` (from a fixed point of the body's axis)
/// of a body turning at `w` with angular acceleration `alpha`, the axis
/// point at rest: `alpha x r + w x (w x r)`.
fn point_acc(alpha: V3, w: V3, r: V3) -> V3 {
    add(cross(alpha, r), cross(w, cross(w, r)))
}

/// The wrist's state: joint angles, speeds and accelerations, order
/// `[roll, pitch, jaw A, jaw B]`, rad, rad/s, rad/s².
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct WristMotion {
    /// Angles (jaws: [`crate::wrist`]'s `q_3`), rad.
    pub q_rad: [f32; 4],
    /// Speeds, rad/s.
    pub qd_rad_s: [f32; 4],
    /// Accelerations, rad/s².
    pub qdd_rad_s2: [f32; 4],
}

/// Eq. 3's regressor `Y` (rows roll, pitch, jaw A, jaw B; columns
/// [`PARAM_NAMES`]): `tau_hat = Y pi` is the torque each joint must add to
/// move the links as `m` says under gravity `gravity_m_s2` (shaft frame),
/// and its friction's remainder with the smooth sign's widths
/// `sign_speed_rad_s`; N·m per unit of each parameter.
pub fn regressor(
    g: &Geometry,
    gravity_m_s2: V3,
    sign_speed_rad_s: [f32; 4],
    m: &WristMotion,
) -> [[f32; N_PARAMS]; 4] {
    let [q1, q2, qa, qb] = m.q_rad;
    let [v1, v2, va, vb] = m.qd_rad_s;
    let [a1, a2, aa, ab] = m.qdd_rad_s2;
    let (s1, c1) = (math::sin(q1), math::cos(q1));
    let (s2, c2) = (math::sin(q2), math::cos(q2));
    // Axes and the wrist link's direction in the shaft frame.
    let u1: V3 = [0.0, 0.0, 1.0];
    let u2: V3 = [-s1, c1, 0.0]; // y_1 = y_2
    let x2: V3 = [c1 * c2, s1 * c2, -s2];
    let d2: V3 = [c1 * s2, s1 * s2, c2];
    let w1 = scale(v1, u1);
    let al1 = scale(a1, u1);
    let w2 = add(w1, scale(v2, u2));
    let al2 = add(add(al1, scale(a2, u2)), cross(w1, scale(v2, u2)));
    let a_d2 = point_acc(al2, w2, d2);
    let o3 = scale(g.pitch_to_jaw_m, d2);
    let a_o3 = point_acc(al2, w2, o3);
    let gv = gravity_m_s2;
    // The jaw axis' acceleration less gravity, shared by both jaws.
    let a_o3_g = add(a_o3, scale(-1.0, gv));
    // The roll and pitch rows: each axis with `u x d2`.
    let shared = [(ROLL, u1, cross(u1, d2)), (PITCH, u2, cross(u2, d2))];
    let mut y = [[0.0f32; N_PARAMS]; 4];
    y[ROLL][0] = a1;
    for (row, _, ud2) in shared {
        y[row][1] = -dot(ud2, gv);
        y[row][2] = dot(ud2, a_d2);
    }
    // Each jaw: its axis u3 (-x2 for A, +x2 for B), direction d3 (in the
    // plane of d2 and y2 = u2), column pair, joint row.
    let l2 = g.pitch_to_jaw_m;
    for (q3, v3, a3, sign, col, row) in
        [(qa, va, aa, 1.0f32, 3, JAW_A), (qb, vb, ab, -1.0, 5, JAW_B)]
    {
        let (s3, c3) = (math::sin(q3), math::cos(q3));
        let u3 = scale(-sign, x2);
        let d3 = add(scale(sign * s3, u2), scale(c3, d2));
        let w3 = add(w2, scale(v3, u3));
        let al3 = add(add(al2, scale(a3, u3)), cross(w2, scale(v3, u3)));
        let a_d3 = point_acc(al3, w3, d3);
        for (r, u, ud2) in shared {
            // p = o3 + s d3: J = u x o3 + s (u x d3), a = a_o3 + s a_d3.
            let ud3 = cross(u, d3);
            y[r][col] = l2 * dot(ud2, a_d3) + dot(ud3, a_o3_g);
            y[r][col + 1] = dot(ud3, a_d3);
        }
        let ud3 = cross(u3, d3);
        y[row][col] = dot(ud3, a_o3_g);
        y[row][col + 1] = dot(ud3, a_d3);
    }
    for (j, row) in y.iter_mut().enumerate() {
        let v = m.qd_rad_s[j];
        row[N_LINKS + 2 * j] = math::tanh(v / sign_speed_rad_s[j]);
        row[N_LINKS + 2 * j + 1] = v;
    }
    y
}

/// An identified Eq. 3 model: the parameters, their standard deviations,
/// the gravity they were identified under and the smooth signs' widths.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct InverseDynamics {
    /// Parameters, order of [`PARAM_NAMES`].
    pub params: [f32; N_PARAMS],
    /// Their standard deviations from the fit (same units).
    pub std_dev: [f32; N_PARAMS],
    /// Gravity in the shaft frame, m/s².
    pub gravity_m_s2: [f32; 3],
    /// Each joint's speed at which its friction's sign is `tanh 1`, rad/s.
    pub sign_speed_rad_s: [f32; 4],
}

impl InverseDynamics {
    /// `tau_rb = Y pi`, N·m per joint (order of [`WristMotion`]).
    pub fn torque_nm(&self, g: &Geometry, m: &WristMotion) -> [f32; 4] {
        self.torque_and_spread_nm(g, m).0
    }

    /// `tau_rb` and, per joint, `3 sum_k |Y_jk| sigma_k`: how far the
    /// parameters' uncertainty can move it (three standard deviations of
    /// each parameter, added in the worst direction), N·m.
    pub fn torque_and_spread_nm(&self, g: &Geometry, m: &WristMotion) -> ([f32; 4], [f32; 4]) {
        let y = regressor(g, self.gravity_m_s2, self.sign_speed_rad_s, m);
        let tau = core::array::from_fn(|r| (0..N_PARAMS).map(|k| y[r][k] * self.params[k]).sum());
        let spread = core::array::from_fn(|r| {
            3.0 * (0..N_PARAMS)
                .map(|k| math::abs(y[r][k]) * self.std_dev[k])
                .sum::<f32>()
        });
        (tau, spread)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// At rest the regressor is gravity alone (friction needs motion): no
    /// torque without gravity,
    /// and a jaw hanging along gravity carries none on its own joint.
    #[test]
    fn at_rest_only_gravity_loads_the_joints() {
        let g = Geometry::default();
        let mut params = [0.0; N_PARAMS];
        params[..N_LINKS].copy_from_slice(&[1e-8, 2e-5, 3e-7, 4e-6, 8e-8, 4e-6, 8e-8]);
        // Friction acts only in motion.
        params[N_LINKS..].copy_from_slice(&[1e-3; 8]);
        let body = InverseDynamics {
            params,
            std_dev: [0.0; N_PARAMS],
            gravity_m_s2: [0.0; 3],
            sign_speed_rad_s: [0.05; 4],
        };
        let rest = WristMotion {
            q_rad: [0.3, 0.4, 0.1, -0.2],
            ..WristMotion::default()
        };
        assert_eq!(body.torque_nm(&g, &rest), [0.0; 4]);
        // Straight wrist, gravity along the shaft: every link hangs along
        // it, nothing turns.
        let hanging = InverseDynamics {
            gravity_m_s2: [0.0, 0.0, -9.81],
            ..body
        };
        let straight = WristMotion::default();
        for t in hanging.torque_nm(&g, &straight) {
            assert!(t.abs() < 1e-12, "{t}");
        }
        // Gravity across the shaft along -y: jaw A (closing towards +y at
        // q_3 = 0) must push up against its weight, jaw B down.
        let across = InverseDynamics {
            gravity_m_s2: [0.0, -9.81, 0.0],
            ..body
        };
        let t = across.torque_nm(&g, &straight);
        let want = 9.81 * body.params[3];
        assert!((t[JAW_A] - want).abs() < 1e-6 * want, "{t:?}");
        assert!((t[JAW_B] + want).abs() < 1e-6 * want, "{t:?}");
    }
}
