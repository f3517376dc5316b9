//! The wrist's tip forces and clamp force (seed 000 Sect. 2.3, Eq. 1-5).
//!
//! # The machine
//!
//! Seed 000's micromanipulator has four joints (Sect. 2.2): a rotary joint
//! (roll, about the shaft), one pitch joint, and one deflection joint per
//! jaw; grippers A and B are the jaws. Each jaw's chain is roll → pitch →
//! jaw, `q_i = [q_1, q_2, q_3^i]`, and each joint is a motor–cable–spring
//! loop like the prototype, so each joint's external torque is estimated by
//! its own [`Controller`](crate::Controller) (the fused estimate and its
//! bound, [`crate::fusion`]).
//!
//! The seed gives no wrist drawing with dimensions. Assumed here, each one
//! a field of [`Geometry`]:
//!
//! * the roll axis (the shaft, `z_0`) meets the pitch axis (`y_1`, normal
//!   to the shaft);
//! * the jaw axes are parallel to each other, normal to the pitch axis and
//!   to the wrist link, `l_2` from the pitch axis (`Geometry::pitch_to_jaw_m`,
//!   default 9 mm, an 8 mm instrument's wrist);
//! * each jaw carries its load at `l_e` from its axis
//!   (`Geometry::jaw_length_m`, the prototype's 20 mm gripper);
//! * jaw A turns by `-q_3^a` about the jaw axis `x_2`, so a positive jaw
//!   angle closes it towards `+y_2`; jaw B is its mirror image through the
//!   `x_2 z_2` plane (positive closes it towards `-y_2`).
//!
//! # Frames and signs
//!
//! Jaw `i`'s force `F^i` is the force **the jaw applies to what it holds**,
//! in the jaw's own frame: `y` along the direction the tip moves when the
//! jaw closes, `z` along the jaw, `x` along the pitch axis' normal in the
//! jaw plane. So `F_y^i` is the squeeze of jaw `i`, the same quantity as a
//! single joint's `F_ext` (DESIGN.md: positive opposes positive rotation),
//! and Eq. 5's clamp force is `(|F_y^a| + |F_y^b|) / 2`.
//!
//! # The chain (Eq. 2-5)
//!
//! * Eq. 2: each joint's torque is `r (F_M - F_S)`, the difference of its
//!   driving cables' tensions ([`joint_torque`]).
//! * Eq. 3: `tau_hat`, the torque the free wrist needs, is what each
//!   joint's no-load model gives, plus what [`crate::wrist_dynamics`] adds
//!   (the links' `D q'' + H + G` and the friction a joint's own model
//!   leaves); the difference `tau - tau_hat` is each joint's external
//!   torque, `F_ext l_e` of its single-joint estimate less that model, with
//!   the estimate's bound.
//! * Eq. 4: `F^i = J_i^-T (tau_i - tau_hat_i)` ([`jaw_force`]). In the
//!   jaw's frame `J_i^T` ([`jaw_jacobian_t`]) has the rows
//!
//!   ```text
//!   roll   ( -l s3 c2,  s2 (l + l2 c3),  l2 s2 s3 )
//!   pitch  (  l2 + l c3,       0,            0     )
//!   jaw    (      0,           l,            0     )
//!   ```
//!
//!   with `s2 = sin q_2`, `c3 = cos q_3`, `l = l_e`. So the jaw's own joint
//!   gives `F_y` alone, the pitch joint `F_x`, and only the roll joint sees
//!   the force along the jaw, `F_z`, with the lever `l2 sin q_2 sin q_3`:
//!   **`F_z` is unobservable unless the wrist is both pitched and the jaw
//!   deflected** (the straight wrist's `J` is singular). [`jaw_force`]
//!   reports it unobservable, with an unbounded bound, below
//!   [`Geometry::min_lever_m`] instead of dividing by a near-zero lever.
//! * Eq. 5: the total force `F^a + F^b` (in the wrist frame after roll and
//!   pitch, [`total_force`]) and the clamp force ([`clamp_force`]).
//!
//! The roll and pitch joints are shared by both jaws: their torques carry
//! both jaws' loads. Eq. 4 per jaw (as the seed writes it) therefore gives a
//! jaw's `F_x` and `F_z` correctly only while the other jaw is free; in a
//! grasp the two jaws' `x` and `z` loads cancel in the shared joints (a
//! squeeze is an internal force) and only `F_y`, each from its own jaw's
//! joint, is the jaw's. The clamp force uses `F_y` alone.
//!
//! # Bounds
//!
//! Every quantity is an [`Interval`]: the joints' bounds propagate through
//! Eq. 4 and 5 by interval arithmetic (a sum of intervals, a scaling, an
//! absolute value), so the bound on the clamp force contains the true clamp
//! force whenever each joint's bound contains its true external torque.

use core::ops::{Add, Sub};

use crate::math;

/// A closed interval `[lo, hi]` of a physical quantity; `lo <= hi`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Interval {
    /// Lower end.
    pub lo: f32,
    /// Upper end.
    pub hi: f32,
}

impl Interval {
    /// The interval between `a` and `b`, in either order.
    pub fn new(a: f32, b: f32) -> Self {
        if a <= b {
            Self { lo: a, hi: b }
        } else {
            Self { lo: b, hi: a }
        }
    }

    /// A single value.
    pub fn point(x: f32) -> Self {
        Self { lo: x, hi: x }
    }

    /// Every value: what cannot be observed.
    pub const UNBOUNDED: Self = Self {
        lo: f32::NEG_INFINITY,
        hi: f32::INFINITY,
    };

    /// Midpoint (the point estimate).
    pub fn mid(&self) -> f32 {
        0.5 * (self.lo + self.hi)
    }

    /// Width `hi - lo`.
    pub fn width(&self) -> f32 {
        self.hi - self.lo
    }

    /// Whether `x` lies in the interval.
    pub fn contains(&self, x: f32) -> bool {
        self.lo <= x && x <= self.hi
    }

    /// `k x` for every `x` in the interval (`0 x` is `0` even for an
    /// unbounded interval: a component with no weight adds nothing).
    pub fn scale(self, k: f32) -> Self {
        if k == 0.0 {
            return Self::point(0.0);
        }
        Self::new(k * self.lo, k * self.hi)
    }

    /// `|x|` for every `x` in the interval.
    pub fn abs(self) -> Self {
        if self.lo >= 0.0 {
            self
        } else if self.hi <= 0.0 {
            Self {
                lo: -self.hi,
                hi: -self.lo,
            }
        } else {
            Self {
                lo: 0.0,
                hi: if -self.lo > self.hi {
                    -self.lo
                } else {
                    self.hi
                },
            }
        }
    }
}

impl Add for Interval {
    type Output = Self;
    /// `x + y` for every `x` here and `y` in `other`.
    fn add(self, other: Self) -> Self {
        Self {
            lo: self.lo + other.lo,
            hi: self.hi + other.hi,
        }
    }
}

impl Sub for Interval {
    type Output = Self;
    /// `x - y` for every `x` here and `y` in `other`.
    fn sub(self, other: Self) -> Self {
        Self {
            lo: self.lo - other.hi,
            hi: self.hi - other.lo,
        }
    }
}

/// The wrist's dimensions (module docs: which are assumed and why).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, deny_unknown_fields))]
pub struct Geometry {
    /// Pitch axis to the jaws' axis, `l_2`, m.
    pub pitch_to_jaw_m: f32,
    /// Jaw axis to the point the jaw's load acts at, `l_e`, m.
    pub jaw_length_m: f32,
    /// Pulley radii of the roll, pitch and jaw joints (Eq. 2's `r_1`,
    /// `r_2`, `r_3`), m.
    pub pulley_radius_m: [f32; 3],
    /// Smallest lever the roll joint must have on the force along a jaw for
    /// that force to count as observed, m. Below it `F_z` is reported
    /// unobservable. Default: a tenth of `l_2` times `sin 5°` squared
    /// (pitch and jaw both beyond about 5° from straight).
    pub min_lever_m: f32,
}

impl Default for Geometry {
    fn default() -> Self {
        let l2 = 9e-3;
        let s5 = math::sin(5.0f32.to_radians());
        Self {
            pitch_to_jaw_m: l2,
            jaw_length_m: 20e-3,
            pulley_radius_m: [4e-3; 3],
            min_lever_m: l2 * s5 * s5,
        }
    }
}

/// Which joint of a jaw's chain.
pub mod joint {
    /// The rotary joint about the shaft.
    pub const ROLL: usize = 0;
    /// The pitch joint.
    pub const PITCH: usize = 1;
    /// The jaw's own deflection joint.
    pub const JAW: usize = 2;
}

/// Eq. 2: a joint's torque from its driving cables' tensions, `r (F_M -
/// F_S)`, N·m (both tensions as intervals, N).
pub fn joint_torque(pulley_radius_m: f32, f_m: Interval, f_s: Interval) -> Interval {
    (f_m - f_s).scale(pulley_radius_m)
}

/// `J^T` of a jaw's chain in the jaw's frame (module docs), rows roll,
/// pitch, jaw; `q_pitch` and `q_jaw` in rad (the roll angle does not enter).
/// `tau = J^T F` is the torque the joints must add to hold a force `F`
/// that the jaw applies to its surroundings.
pub fn jaw_jacobian_t(g: &Geometry, q_pitch_rad: f32, q_jaw_rad: f32) -> [[f32; 3]; 3] {
    let (s2, c2) = (math::sin(q_pitch_rad), math::cos(q_pitch_rad));
    let (s3, c3) = (math::sin(q_jaw_rad), math::cos(q_jaw_rad));
    let (l, l2) = (g.jaw_length_m, g.pitch_to_jaw_m);
    [
        [-l * s3 * c2, s2 * (l + l2 * c3), l2 * s2 * s3],
        [l2 + l * c3, 0.0, 0.0],
        [0.0, l, 0.0],
    ]
}

/// A jaw's force (Eq. 4) with its bound, in the jaw's frame, N.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct JawForce {
    /// `[F_x, F_y, F_z]`; an unobservable component is
    /// [`Interval::UNBOUNDED`].
    pub force_n: [Interval; 3],
    /// Whether each component is observed by the joints at this pose.
    pub observable: [bool; 3],
}

/// Eq. 4: the force a jaw applies, `F = J^-T (tau - tau_hat)`, from the
/// external torques of its chain's joints (rows as in [`jaw_jacobian_t`]),
/// bound propagated. `F_z` is unobservable where the roll joint's lever on
/// it is below [`Geometry::min_lever_m`].
pub fn jaw_force(
    g: &Geometry,
    q_pitch_rad: f32,
    q_jaw_rad: f32,
    external_torque_nm: [Interval; 3],
) -> JawForce {
    let jt = jaw_jacobian_t(g, q_pitch_rad, q_jaw_rad);
    let [roll, pitch, jaw] = external_torque_nm;
    let fx = pitch.scale(1.0 / jt[joint::PITCH][0]);
    let fy = jaw.scale(1.0 / jt[joint::JAW][1]);
    let lever = jt[joint::ROLL][2];
    let (fz, z_seen) = if math::abs(lever) >= g.min_lever_m {
        // roll = a F_x + b F_y + c F_z  =>  F_z = (roll - a F_x - b F_y) / c
        let rest = roll - fx.scale(jt[joint::ROLL][0]) - fy.scale(jt[joint::ROLL][1]);
        (rest.scale(1.0 / lever), true)
    } else {
        (Interval::UNBOUNDED, false)
    };
    JawForce {
        force_n: [fx, fy, fz],
        observable: [true, true, z_seen],
    }
}

/// Eq. 5, the clamp force `(|F_y^a| + |F_y^b|) / 2`, N, from each jaw's
/// squeeze.
pub fn clamp_force(fy_a: Interval, fy_b: Interval) -> Interval {
    (fy_a.abs() + fy_b.abs()).scale(0.5)
}

/// A jaw's force turned from its frame into the wrist frame after roll and
/// pitch (`x_2`, `y_2`, `z_2`): jaw A by `-q_jaw` about `x`, jaw B (the
/// mirror image, `mirrored = true`) by `+q_jaw` with its `y` reversed.
/// Interval rotation: each output component is bounded by the sum of the
/// rotated inputs' ranges.
pub fn to_wrist_frame(f: &JawForce, q_jaw_rad: f32, mirrored: bool) -> [Interval; 3] {
    let (s, c) = (math::sin(q_jaw_rad), math::cos(q_jaw_rad));
    // Jaw A: R = Rx(-q): y2 = c y - (-s) z = c y + s z ... written out:
    // [x2]   [1  0   0] [x]
    // [y2] = [0  c   s] [y]
    // [z2]   [0 -s   c] [z]
    // Jaw B mirrors y: y2 -> -y2 with the jaw turned the other way, which
    // flips the sign of the y2 row.
    let [fx, fy, fz] = f.force_n;
    let sign = if mirrored { -1.0 } else { 1.0 };
    let y2 = fy.scale(sign * c) + fz.scale(sign * s);
    let z2 = fy.scale(-s) + fz.scale(c);
    [fx, y2, z2]
}

/// Eq. 5, the total force `F^a + F^b` in the wrist frame, N: jaw A's and
/// jaw B's forces with their jaw angles. Shared-joint caveat in the module
/// docs: in a grasp only the `y` components are each jaw's own.
pub fn total_force(a: &JawForce, q_a_rad: f32, b: &JawForce, q_b_rad: f32) -> [Interval; 3] {
    let fa = to_wrist_frame(a, q_a_rad, false);
    let fb = to_wrist_frame(b, q_b_rad, true);
    [fa[0] + fb[0], fa[1] + fb[1], fa[2] + fb[2]]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Jaw A's tip in the wrist frame after roll (so roll turns it about z):
    /// `Ry(q2) ([0,0,l2] + Rx(-q3) [0,0,l])`, with the jaw frame's axes.
    fn tip_and_frame(g: &Geometry, q: [f64; 3]) -> ([f64; 3], [[f64; 3]; 3]) {
        let (l, l2) = (g.jaw_length_m as f64, g.pitch_to_jaw_m as f64);
        let rz = |a: f64, v: [f64; 3]| {
            [
                a.cos() * v[0] - a.sin() * v[1],
                a.sin() * v[0] + a.cos() * v[1],
                v[2],
            ]
        };
        let ry = |a: f64, v: [f64; 3]| {
            [
                a.cos() * v[0] + a.sin() * v[2],
                v[1],
                -a.sin() * v[0] + a.cos() * v[2],
            ]
        };
        let rx = |a: f64, v: [f64; 3]| {
            [
                v[0],
                a.cos() * v[1] - a.sin() * v[2],
                a.sin() * v[1] + a.cos() * v[2],
            ]
        };
        let jaw = rx(-q[2], [0.0, 0.0, l]);
        let tip = rz(q[0], ry(q[1], [jaw[0], jaw[1], jaw[2] + l2]));
        let axis = |e: [f64; 3]| rz(q[0], ry(q[1], rx(-q[2], e)));
        (
            tip,
            [
                axis([1.0, 0.0, 0.0]),
                axis([0.0, 1.0, 0.0]),
                axis([0.0, 0.0, 1.0]),
            ],
        )
    }

    /// `J^T` against finite differences of the tip position: column `j` of
    /// `J` in the jaw frame is `d tip / d q_j` projected on the jaw's axes.
    /// Jaw closing moves the tip along the jaw frame's `+y`.
    #[test]
    fn the_jacobian_is_the_derivative_of_the_tip_position() {
        let g = Geometry::default();
        for &q in &[
            [0.0, 0.0, 0.0],
            [0.3, 0.5, -0.2],
            [-1.0, -0.7, 0.9],
            [2.0, 1.2, 0.4],
        ] {
            let jt = jaw_jacobian_t(&g, q[1] as f32, q[2] as f32);
            let (_, frame) = tip_and_frame(&g, q);
            for j in 0..3 {
                let h = 1e-6;
                let (mut qp, mut qm) = (q, q);
                qp[j] += h;
                qm[j] -= h;
                let (p, _) = tip_and_frame(&g, qp);
                let (m, _) = tip_and_frame(&g, qm);
                let d: [f64; 3] = core::array::from_fn(|k| (p[k] - m[k]) / (2.0 * h));
                for (axis, e) in frame.iter().enumerate() {
                    let proj: f64 = (0..3).map(|k| d[k] * e[k]).sum();
                    assert!(
                        (proj - jt[j][axis] as f64).abs() < 1e-6,
                        "q {q:?} joint {j} axis {axis}: {proj} vs {}",
                        jt[j][axis]
                    );
                }
            }
        }
    }

    fn tau_of(g: &Geometry, q2: f32, q3: f32, f: [f32; 3]) -> [Interval; 3] {
        let jt = jaw_jacobian_t(g, q2, q3);
        core::array::from_fn(|r| Interval::point((0..3).map(|k| jt[r][k] * f[k]).sum()))
    }

    /// Eq. 4 on exact torques gives back the force that made them, at a
    /// pose where all three components are observed.
    #[test]
    fn eq4_recovers_the_jaw_force_from_exact_joint_torques() {
        let g = Geometry::default();
        let f = [0.4f32, -1.3, 0.7];
        let out = jaw_force(&g, 0.6, 0.5, tau_of(&g, 0.6, 0.5, f));
        assert_eq!(out.observable, [true, true, true]);
        for (got, want) in out.force_n.iter().zip(f) {
            assert!((got.mid() - want).abs() < 1e-4, "{got:?} vs {want}");
            assert!(got.width() < 1e-5);
        }
    }

    /// On the straight wrist the roll joint has no lever on the force along
    /// the jaw: it is reported unobservable, and the squeeze still comes out.
    #[test]
    fn the_force_along_a_straight_jaw_is_unobservable_and_said_so() {
        let g = Geometry::default();
        let f = [0.2f32, 1.5, 3.0];
        let out = jaw_force(&g, 0.0, 0.3, tau_of(&g, 0.0, 0.3, f));
        assert_eq!(out.observable, [true, true, false]);
        assert_eq!(out.force_n[2], Interval::UNBOUNDED);
        assert!((out.force_n[1].mid() - 1.5).abs() < 1e-5);
        assert!((out.force_n[0].mid() - 0.2).abs() < 1e-5);
    }

    /// Bounds propagate: for torques drawn anywhere inside the joints'
    /// intervals, the force they produce lies inside Eq. 4's bound, and the
    /// clamp force inside Eq. 5's.
    #[test]
    fn the_bounds_contain_every_force_the_torque_bounds_allow() {
        let g = Geometry::default();
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f32 / (1u64 << 53) as f32
        };
        for _ in 0..500 {
            let (q2, q3a, q3b) = (next() * 2.0 - 1.0, next() - 0.5, next() - 0.5);
            let tau_a: [Interval; 3] = core::array::from_fn(|_| {
                let c = next() * 0.1 - 0.05;
                Interval::new(c - next() * 0.01, c + next() * 0.01)
            });
            let tau_b: [Interval; 3] = core::array::from_fn(|_| {
                let c = next() * 0.1 - 0.05;
                Interval::new(c - next() * 0.01, c + next() * 0.01)
            });
            let a = jaw_force(&g, q2, q3a, tau_a);
            let b = jaw_force(&g, q2, q3b, tau_b);
            let cp = clamp_force(a.force_n[1], b.force_n[1]);
            for _ in 0..20 {
                let pick = |t: &[Interval; 3], u: [f32; 3]| -> [Interval; 3] {
                    core::array::from_fn(|k| Interval::point(t[k].lo + u[k] * t[k].width()))
                };
                let ua = [next(), next(), next()];
                let ub = [next(), next(), next()];
                let pa = jaw_force(&g, q2, q3a, pick(&tau_a, ua));
                let pb = jaw_force(&g, q2, q3b, pick(&tau_b, ub));
                let tol = 1e-4;
                for k in 0..3 {
                    let (x, bound) = (pa.force_n[k].mid(), a.force_n[k]);
                    if a.observable[k] {
                        assert!(
                            bound.lo - tol <= x && x <= bound.hi + tol,
                            "{k}: {x} {bound:?}"
                        );
                    }
                }
                let c = 0.5 * (pa.force_n[1].mid().abs() + pb.force_n[1].mid().abs());
                assert!(cp.lo - 1e-4 <= c && c <= cp.hi + 1e-4, "{c} {cp:?}");
            }
        }
    }

    /// Eq. 5 on exact data: jaws squeezing an object with 2 N each give a
    /// clamp force of 2 N and no net force across the closing direction,
    /// at a pose where every component is observed (pitched wrist). Jaw
    /// A's closing direction in the wrist frame is `y2` turned by `-q3`
    /// about `x2`, `(0, cos q3, -sin q3)`, jaw B's its mirror image through
    /// the `x2 z2` plane, `(0, -cos q3, -sin q3)`: the `x` and `y` parts of
    /// the squeeze cancel and the `z` parts add to `-4 sin q3` N (both
    /// jaws push the object out along the wrist's axis).
    #[test]
    fn eq5_a_pure_squeeze_has_its_clamp_force_and_no_net_force() {
        let g = Geometry::default();
        let (q2, q3) = (0.6, 0.2);
        let squeeze = [0.0f32, 2.0, 0.0];
        let a = jaw_force(&g, q2, q3, tau_of(&g, q2, q3, squeeze));
        let b = jaw_force(&g, q2, q3, tau_of(&g, q2, q3, squeeze));
        assert_eq!(a.observable, [true, true, true]);
        let cp = clamp_force(a.force_n[1], b.force_n[1]);
        assert!((cp.mid() - 2.0).abs() < 1e-5 && cp.width() < 1e-5);
        let total = total_force(&a, q3, &b, q3);
        let want = [0.0, 0.0, -4.0 * q3.sin()];
        for (got, want) in total.iter().zip(want) {
            assert!((got.mid() - want).abs() < 1e-4, "{total:?}");
            assert!(got.width() < 1e-4, "{total:?}");
        }
    }

    #[test]
    fn eq2_is_the_pulley_radius_times_the_tension_difference() {
        let t = joint_torque(4e-3, Interval::new(20.0, 21.0), Interval::new(18.0, 18.5));
        assert!((t.lo - 4e-3 * 1.5).abs() < 1e-7 && (t.hi - 4e-3 * 3.0).abs() < 1e-7);
    }

    #[test]
    fn interval_abs_covers_both_signs() {
        assert_eq!(Interval::new(-3.0, 1.0).abs(), Interval::new(0.0, 3.0));
        assert_eq!(Interval::new(-3.0, -1.0).abs(), Interval::new(1.0, 3.0));
        assert_eq!(Interval::new(1.0, 2.0).abs(), Interval::new(1.0, 2.0));
    }
}
