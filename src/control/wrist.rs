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
//! * Eq. 5: the clamp force ([`clamp_force`]) and the total force `F^a +
//!   F^b` in the wrist frame after roll and pitch ([`total_force`]).
//!
//! The roll and pitch joints are shared by both jaws: their torques carry
//! both jaws' loads. Eq. 4 per jaw (as the seed writes it) therefore gives a
//! jaw's `F_x` and `F_z` only while the other jaw is free; in a grasp only
//! `F_y`, each from its own jaw's joint, is the jaw's, and the clamp force
//! uses `F_y` alone. Summing two such Eq. 4 forces would count the shared
//! joints' torques twice, so [`total_force`] solves the four torques for
//! the total jointly: six force components meet four torques, and what the
//! joints do not see of a component is bounded by a force limit the caller
//! states (in a grasp the pitch joint gives the total along `x_2`, and the
//! total along `z_2` is not observed).
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
    /// The largest force either jaw carries along any of its axes, N: what
    /// bounds the part of [`total_force`] the joints do not see. Default:
    /// the squeeze a jaw's drive holds at its current limit, `I_max K_m z_i
    /// r_3 / (r_m l_e)` with the prototype's datasheet values (54.6 N); a
    /// jaw that carried more would back-drive. Along the jaw's other axes
    /// the structure, not a drive, carries the load: there the default
    /// assumes the tissue pushes no harder than a jaw can squeeze. State
    /// your task's bound to narrow the total force's bound.
    pub force_limit_n: f32,
}

impl Default for Geometry {
    fn default() -> Self {
        let l2 = 9e-3;
        let s5 = math::sin(5.0f32.to_radians());
        let (r, l) = (4e-3, 20e-3);
        Self {
            pitch_to_jaw_m: l2,
            jaw_length_m: l,
            pulley_radius_m: [r; 3],
            min_lever_m: l2 * s5 * s5,
            force_limit_n: drive_squeeze_limit_n(&crate::config::Machine::default(), r, l),
        }
    }
}

impl Geometry {
    /// The default wrist with jaws of `machine`: its gripper length, and
    /// the squeeze its drive holds as the force limit.
    pub fn with_jaws_of(machine: &crate::config::Machine) -> Self {
        Self {
            jaw_length_m: machine.gripper_length_m,
            force_limit_n: drive_squeeze_limit_n(
                machine,
                machine.pulley_radius_m,
                machine.gripper_length_m,
            ),
            ..Self::default()
        }
    }
}

/// The squeeze a jaw's drive holds at its current limit, N: the cable
/// tension the motor pulls, `I_max K_m z_i / r_m`, on the jaw's pulley
/// radius, at the jaw's length.
pub fn drive_squeeze_limit_n(
    machine: &crate::config::Machine,
    pulley_radius_m: f32,
    jaw_length_m: f32,
) -> f32 {
    machine.current_limit_a * machine.torque_constant_nm_a * machine.gear_ratio
        / machine.rope_wheel_radius_m
        * pulley_radius_m
        / jaw_length_m
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

/// Eq. 5's total force `F^a + F^b` in a grasp, with its bound
/// ([`total_force`]).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TotalForce {
    /// `[x, y, z]` in the wrist frame after roll and pitch (`x_2`, `y_2`,
    /// `z_2`), N; [`Interval::UNBOUNDED`] where neither the joints nor the
    /// force limit bound it.
    pub force_n: [Interval; 3],
    /// The half-width of each bound that the force limit contributes, N
    /// (the mean of its two ends' shares): zero where the four joints alone
    /// fix the component at this pose, the whole bound where they see none
    /// of it.
    pub prior_n: [f32; 3],
}

/// Eq. 5's total force `F^a + F^b`, N, from the four joints' external
/// torques `[roll, pitch, jaw A, jaw B]` (N·m, as intervals) with both jaws
/// loaded.
///
/// The roll and pitch joints carry both jaws' loads, so the six force
/// components meet four torques: `tau = M f`, `M`'s rows each joint's
/// [`jaw_jacobian_t`] row for jaw A and, mirrored, jaw B (jaw B's roll row
/// enters with the other sign). A total component `c . f` is what the
/// joints see of it, `lambda . tau`, plus what they do not, `(c - M^T
/// lambda) . f`; `lambda` trades the joints' spread against the unseen
/// part. Every `lambda` gives a bound that holds whenever each torque lies
/// in its interval and every component of each jaw's force is within
/// `±force_limit_n`; each end takes its own `lambda`, the tightest (the
/// upper end is the least over `lambda` of a convex piecewise-linear
/// function, found at one of its 210 vertices: by linear-programming
/// duality the largest total any such forces give, exactly, and likewise
/// the lower). Where the ends cross (then no jaw forces within the limit
/// give torques inside the intervals) the narrowest bound centred on one
/// `lambda` is kept instead. [`TotalForce::prior_n`] says how much of
/// the bound the limit makes.
///
/// What this gives at a pose: along `x_2` the pitch joint sees `w_a
/// F_x^a + w_b F_x^b` (`w = l_2 + l_e cos q_3`), the total exactly when
/// the jaw angles are equal, widened in proportion to their difference
/// otherwise; along `y_2` the roll joint sees the jaws' `sin q_3`-weighted
/// pushes along themselves only through `sin q_2`, mixed with the jaws'
/// `F_x` difference; along `z_2` nothing in a grasp (both jaws' pushes
/// along themselves add there, the roll joint sees their `sin q_3`-weighted
/// difference, which is their sum only with the jaws parallel, `q_a =
/// -q_b`): that component is the force limit's.
///
/// `force_limit_n = f32::INFINITY` keeps only what the joints fix (to
/// `f32` rounding) and leaves the rest unbounded. A joint whose bound is
/// unbounded is left out; a `force_limit_n` that is not positive leaves
/// every component unbounded.
pub fn total_force(
    g: &Geometry,
    q_pitch_rad: f32,
    q_a_rad: f32,
    q_b_rad: f32,
    external_torque_nm: [Interval; 4],
    force_limit_n: f32,
) -> TotalForce {
    if force_limit_n.is_nan() || force_limit_n <= 0.0 {
        return TotalForce {
            force_n: [Interval::UNBOUNDED; 3],
            prior_n: [f32::INFINITY; 3],
        };
    }
    let mut m = grasp_matrix(g, q_pitch_rad, q_a_rad, q_b_rad);
    // An unbounded torque's row is left out (its lambda stays zero).
    let mut mid = [0.0f32; 4];
    let mut half = [0.0f32; 4];
    for (i, t) in external_torque_nm.iter().enumerate() {
        if t.lo.is_finite() && t.hi.is_finite() {
            mid[i] = t.mid();
            half[i] = 0.5 * t.width();
        } else {
            m[i] = [0.0; 6];
            half[i] = f32::INFINITY;
        }
    }
    let rows = total_rows(q_a_rad, q_b_rad);
    // The narrowest symmetric bound, and each end on its own (with the
    // limit's part of the half-width at that end's lambda).
    let mut force_n = [Interval::UNBOUNDED; 3];
    let mut prior_n = [f32::INFINITY; 3];
    let mut hi = [(f32::INFINITY, f32::INFINITY); 3];
    let mut lo = [(f32::NEG_INFINITY, f32::INFINITY); 3];
    // A bound's upper end for a given lambda, `lambda . mid + sum_i half_i
    // |lambda_i| + limit sum_j |(c - M^T lambda)_j|`, is convex and
    // piecewise linear in lambda (its half-width likewise, without the
    // first term, and the lower end mirrored): its least value lies where
    // four of its ten pieces vanish together (`lambda_i = 0` for the joints
    // left out, `(M^T lambda)_j = c_j` for as many force components).
    // Every choice of four (210) is solved, and each component keeps its
    // tightest ends (every lambda gives a bound that holds, so a choice
    // solved roughly costs width, never the bound).
    for pieces in 0u16..1 << 10 {
        if pieces.count_ones() != 4 {
            continue;
        }
        // The joints kept (lambda free) and the components solved for.
        let mut free = [0usize; 4];
        let mut solved = [0usize; 4];
        let (mut n, mut n_solved) = (0, 0);
        for i in 0..4 {
            if pieces & (1 << i) == 0 {
                free[n] = i;
                n += 1;
            }
        }
        for j in 0..6 {
            if pieces & (1 << (4 + j)) != 0 {
                solved[n_solved] = j;
                n_solved += 1;
            }
        }
        let mut a = [[0.0f32; 4]; 4];
        let mut rhs = [[0.0f32; 3]; 4];
        for r in 0..n {
            for (s, &i) in free[..n].iter().enumerate() {
                a[r][s] = m[i][solved[r]];
            }
            for (k, c) in rows.iter().enumerate() {
                rhs[r][k] = c[solved[r]];
            }
        }
        let Some(x) = solve_small(&mut a, &mut rhs, n) else {
            continue;
        };
        for (k, c) in rows.iter().enumerate() {
            let mut lambda = [0.0f32; 4];
            for (s, &i) in free[..n].iter().enumerate() {
                lambda[i] = x[s][k];
            }
            if let Some((point, joints, prior)) =
                total_bound(&m, c, &lambda, &mid, &half, force_limit_n)
            {
                let reach = joints + prior;
                if 2.0 * reach < force_n[k].width() {
                    force_n[k] = Interval::new(point - reach, point + reach);
                    prior_n[k] = prior;
                }
                if point + reach < hi[k].0 {
                    hi[k] = (point + reach, prior);
                }
                if point - reach > lo[k].0 {
                    lo[k] = (point - reach, prior);
                }
            }
        }
    }
    for k in 0..3 {
        if lo[k].0 <= hi[k].0 && hi[k].0 - lo[k].0 < force_n[k].width() {
            let half_width = 0.5 * (hi[k].0 - lo[k].0);
            force_n[k] = Interval::new(lo[k].0, hi[k].0);
            prior_n[k] = half_width.min(0.5 * (lo[k].1 + hi[k].1));
        }
    }
    TotalForce { force_n, prior_n }
}

/// `M` of [`total_force`]: the four joints' torques `[roll, pitch, jaw A,
/// jaw B]` from jaw A's `F_x, F_y, F_z` then jaw B's, each in its jaw
/// frame (jaw B's roll row mirrored).
fn grasp_matrix(g: &Geometry, q_pitch_rad: f32, q_a_rad: f32, q_b_rad: f32) -> [[f32; 6]; 4] {
    let jt_a = jaw_jacobian_t(g, q_pitch_rad, q_a_rad);
    let jt_b = jaw_jacobian_t(g, q_pitch_rad, q_b_rad);
    let mut m = [[0.0f32; 6]; 4];
    for k in 0..3 {
        m[0][k] = jt_a[joint::ROLL][k];
        m[0][3 + k] = -jt_b[joint::ROLL][k];
        m[1][k] = jt_a[joint::PITCH][k];
        m[1][3 + k] = jt_b[joint::PITCH][k];
        m[2][k] = jt_a[joint::JAW][k];
        m[3][3 + k] = jt_b[joint::JAW][k];
    }
    m
}

/// Rows `x_2`, `y_2`, `z_2` of `F^a + F^b` over [`grasp_matrix`]'s six
/// components: each jaw's frame turned into the wrist frame (jaw B
/// mirrored through the `x_2 z_2` plane, module docs).
fn total_rows(q_a_rad: f32, q_b_rad: f32) -> [[f32; 6]; 3] {
    let (sa, ca) = (math::sin(q_a_rad), math::cos(q_a_rad));
    let (sb, cb) = (math::sin(q_b_rad), math::cos(q_b_rad));
    [
        [1.0, 0.0, 0.0, 1.0, 0.0, 0.0],
        [0.0, ca, sa, 0.0, -cb, -sb],
        [0.0, -sa, ca, 0.0, -sb, cb],
    ]
}

/// `a x = rhs` for the leading `n x n` block (`n <= 4`), three right-hand
/// sides, by elimination with partial pivoting; `None` where a pivot is
/// below `1e-6` of the block's largest entry (the pieces chosen do not
/// meet in one point).
fn solve_small(a: &mut [[f32; 4]; 4], rhs: &mut [[f32; 3]; 4], n: usize) -> Option<[[f32; 3]; 4]> {
    let scale = a[..n]
        .iter()
        .flat_map(|row| row[..n].iter())
        .fold(0.0f32, |m, &x| m.max(math::abs(x)));
    for col in 0..n {
        let pivot = (col..n).fold(col, |best, r| {
            if math::abs(a[r][col]) > math::abs(a[best][col]) {
                r
            } else {
                best
            }
        });
        let size = math::abs(a[pivot][col]);
        if size.is_nan() || size <= 1e-6 * scale {
            return None;
        }
        a.swap(col, pivot);
        rhs.swap(col, pivot);
        let (pivot_row, pivot_rhs) = (a[col], rhs[col]);
        for r in col + 1..n {
            let f = a[r][col] / pivot_row[col];
            for (x, p) in a[r][col..n].iter_mut().zip(&pivot_row[col..n]) {
                *x -= f * p;
            }
            for (x, p) in rhs[r].iter_mut().zip(&pivot_rhs) {
                *x -= f * p;
            }
        }
    }
    let mut x = [[0.0f32; 3]; 4];
    for r in (0..n).rev() {
        for k in 0..3 {
            let mut v = rhs[r][k];
            for c in r + 1..n {
                v -= a[r][c] * x[c][k];
            }
            x[r][k] = v / a[r][r];
        }
    }
    Some(x)
}

/// The bound [`total_force`] reads off one `lambda` for the component `c`:
/// its middle, the joints' part of its half-width and the force limit's
/// part, N; `None` where it is not finite.
fn total_bound(
    m: &[[f32; 6]; 4],
    c: &[f32; 6],
    lambda: &[f32; 4],
    mid: &[f32; 4],
    half: &[f32; 4],
    force_limit_n: f32,
) -> Option<(f32, f32, f32)> {
    let mut unseen_l1 = 0.0f32;
    for j in 0..6 {
        let seen: f32 = (0..4).map(|i| m[i][j] * lambda[i]).sum();
        unseen_l1 += math::abs(c[j] - seen);
    }
    let (mut point, mut joints) = (0.0f32, 0.0f32);
    for i in 0..4 {
        // An unbounded torque counts only where lambda leaves it out.
        if lambda[i] != 0.0 {
            point += lambda[i] * mid[i];
            joints += math::abs(lambda[i]) * half[i];
        }
    }
    // Without a limit, what the joints leave unseen at f32 rounding counts
    // as nothing; anything more is unbounded.
    let prior = if force_limit_n.is_finite() {
        unseen_l1 * force_limit_n
    } else if unseen_l1 <= 1e-5 {
        0.0
    } else {
        f32::INFINITY
    };
    (point.is_finite() && (joints + prior).is_finite()).then_some((point, joints, prior))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Jaw A's tip in the wrist frame after roll (so roll turns it about z):
    /// `Ry(q2) ([0,0,l2] + Rx(-q3) [0,0,l])`, with the jaw frame's axes.
    fn tip_and_frame(g: &Geometry, q: [f64; 3]) -> ([f64; 3], [[f64; 3]; 3]) {
        jaw_tip_and_frame(g, q, false)
    }

    /// A jaw's tip and frame axes in the base frame; jaw B (`mirrored`) is
    /// jaw A's mirror image through the `x_2 z_2` plane, its closing
    /// direction (`y`) included. The axes are also returned in the wrist
    /// frame after roll and pitch (the third element).
    fn jaw_tip_and_frame(g: &Geometry, q: [f64; 3], mirrored: bool) -> ([f64; 3], [[f64; 3]; 3]) {
        let (tip, base, _) = jaw_tip_frames(g, q, mirrored);
        (tip, base)
    }

    type Frame = [[f64; 3]; 3];

    fn jaw_tip_frames(g: &Geometry, q: [f64; 3], mirrored: bool) -> ([f64; 3], Frame, Frame) {
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
        let mirror = |v: [f64; 3]| if mirrored { [v[0], -v[1], v[2]] } else { v };
        let jaw = mirror(rx(-q[2], [0.0, 0.0, l]));
        let tip = rz(q[0], ry(q[1], [jaw[0], jaw[1], jaw[2] + l2]));
        let in_wrist = |e: [f64; 3]| mirror(rx(-q[2], e));
        let e = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let wrist = e.map(in_wrist);
        let base = wrist.map(|v| rz(q[0], ry(q[1], v)));
        (tip, base, wrist)
    }

    /// The four joints' torques `[roll, pitch, jaw A, jaw B]` that hold the
    /// jaws' forces `fa`, `fb` (each in its jaw frame), by virtual work on
    /// the tips' positions (finite differences, independent of
    /// [`jaw_jacobian_t`]), and the total force `F^a + F^b` in the wrist
    /// frame.
    fn grasp_torques(
        g: &Geometry,
        q: [f64; 4],
        fa: [f64; 3],
        fb: [f64; 3],
    ) -> ([f64; 4], [f64; 3]) {
        let world = |frame: &Frame, f: [f64; 3]| -> [f64; 3] {
            core::array::from_fn(|k| (0..3).map(|a| f[a] * frame[a][k]).sum())
        };
        let tips = |q: [f64; 4]| {
            let (pa, _) = jaw_tip_and_frame(g, [q[0], q[1], q[2]], false);
            let (pb, _) = jaw_tip_and_frame(g, [q[0], q[1], q[3]], true);
            (pa, pb)
        };
        let (_, base_a, wrist_a) = jaw_tip_frames(g, [q[0], q[1], q[2]], false);
        let (_, base_b, wrist_b) = jaw_tip_frames(g, [q[0], q[1], q[3]], true);
        let (wa, wb) = (world(&base_a, fa), world(&base_b, fb));
        let mut tau = [0.0; 4];
        for (j, t) in tau.iter_mut().enumerate() {
            let h = 1e-6;
            let (mut qp, mut qm) = (q, q);
            qp[j] += h;
            qm[j] -= h;
            let ((pa, pb), (ma, mb)) = (tips(qp), tips(qm));
            *t = (0..3)
                .map(|k| ((pa[k] - ma[k]) * wa[k] + (pb[k] - mb[k]) * wb[k]) / (2.0 * h))
                .sum();
        }
        let (ta, tb) = (world(&wrist_a, fa), world(&wrist_b, fb));
        (tau, core::array::from_fn(|k| ta[k] + tb[k]))
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
        let mut rng = crate::test_rng::Rng(0x2545_f491_4f6c_dd1d);
        let mut next = || rng.unit() as f32;
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

    /// Eq. 5 on exact data: jaws squeezing an object with 2 N each at equal
    /// angles on a pitched wrist. The clamp force is 2 N; the torques of
    /// the shared joints, both jaws' loads together, give no net force
    /// along `x_2`, with nothing of the force limit in it. Each jaw's
    /// closing direction in the wrist frame is `(0, ±cos q3, -sin q3)`, so
    /// the squeeze pushes `-4 sin q3` N along `z_2`, which the joints do
    /// not see: its bound is the force limit's alone, and without a limit
    /// it is unbounded.
    #[test]
    fn eq5_a_squeeze_has_its_clamp_force_no_net_force_across_and_an_unseen_push_along() {
        let g = Geometry::default();
        let (q2, q3) = (0.6f32, 0.2f32);
        let q = [0.0, q2 as f64, q3 as f64, q3 as f64];
        let (tau, want) = grasp_torques(&g, q, [0.0, 2.0, 0.0], [0.0, 2.0, 0.0]);
        assert!((want[2] + 4.0 * (q3 as f64).sin()).abs() < 1e-9, "{want:?}");
        let tau = tau.map(|t| Interval::point(t as f32));
        let r = g.jaw_length_m;
        let cp = clamp_force(tau[2].scale(1.0 / r), tau[3].scale(1.0 / r));
        assert!((cp.mid() - 2.0).abs() < 1e-4 && cp.width() < 1e-5, "{cp:?}");
        let total = total_force(&g, q2, q3, q3, tau, 10.0);
        assert!(total.force_n[0].mid().abs() < 1e-4, "{total:?}");
        assert!(total.force_n[0].width() < 1e-3, "{total:?}");
        assert!(total.prior_n[0] < 1e-3, "{total:?}");
        assert!(total.force_n[2].contains(want[2] as f32), "{total:?}");
        assert!(total.prior_n[2] > 5.0, "{total:?}");
        let unlimited = total_force(&g, q2, q3, q3, tau, f32::INFINITY);
        assert!(unlimited.force_n[0].width() < 1e-3, "{unlimited:?}");
        assert_eq!(unlimited.force_n[2], Interval::UNBOUNDED);
    }

    /// The total force's bound holds the true total, on exact torques from
    /// any pose and any pair of jaw forces within the limit, each torque
    /// known only to an interval around its true value.
    #[test]
    fn eq5_the_total_force_bound_holds_the_true_total_of_both_jaws() {
        let g = Geometry::default();
        let limit = 5.0f32;
        let mut rng = crate::test_rng::Rng(0x9e37_79b9_7f4a_7c15);
        let mut next = || rng.unit();
        for _ in 0..2000 {
            let q = [
                next() * 6.0 - 3.0,
                next() * 2.4 - 1.2,
                next() * 1.2 - 0.3,
                next() * 1.2 - 0.3,
            ];
            let fa: [f64; 3] = core::array::from_fn(|_| (next() * 2.0 - 1.0) * limit as f64);
            let fb: [f64; 3] = core::array::from_fn(|_| (next() * 2.0 - 1.0) * limit as f64);
            let (tau, want) = grasp_torques(&g, q, fa, fb);
            let tau: [Interval; 4] = core::array::from_fn(|i| {
                let spread = next() * 2e-3;
                let at = tau[i] + (next() * 2.0 - 1.0) * spread;
                Interval::new((at - spread) as f32, (at + spread) as f32)
            });
            let out = total_force(&g, q[1] as f32, q[2] as f32, q[3] as f32, tau, limit);
            for (k, (b, w)) in out.force_n.iter().zip(want).enumerate() {
                // f32 rounding of the bound's ends.
                let tol = 1e-4 * (1.0 + b.lo.abs() + b.hi.abs());
                let w = w as f32;
                assert!(
                    b.lo - tol <= w && w <= b.hi + tol,
                    "q {q:?} component {k}: {w} outside {b:?}"
                );
                assert!(out.prior_n[k] >= 0.0);
            }
            // Both jaws' pushes along themselves add along z_2, and the
            // roll joint sees their sin q_3-weighted difference: the total
            // along z_2 is not observed unless the jaws are near parallel
            // (q_a = -q_b, the pair deflected, not a grasp).
            if (q[2] + q[3]).abs() > 0.2 {
                assert!(out.prior_n[2] > 0.1 * limit, "q {q:?}: {out:?}");
            }
        }
    }

    /// Along `x_2` the pitch joint weighs each jaw's `F_x` by its lever
    /// `l_2 + l_e cos q_3`: the total is fixed at equal jaw angles, and the
    /// force limit's share of its bound grows with their difference.
    #[test]
    fn eq5_the_total_along_the_pitch_normal_needs_the_limit_in_proportion_to_the_jaw_angle_difference(
    ) {
        let g = Geometry::default();
        let tau = [Interval::point(0.0); 4];
        let prior = |dq: f32| total_force(&g, 0.5, 0.3, 0.3 + dq, tau, 10.0).prior_n[0];
        let (p0, p1, p2) = (prior(0.0), prior(0.02), prior(0.2));
        assert!(p0 < 1e-3, "{p0}");
        assert!(p0 < p1 && p1 < p2, "{p0} {p1} {p2}");
        // Read off the pitch joint alone, the unseen part is the jaws' F_x
        // difference (up to 2 x 10 N) times half the lever difference over
        // the mean lever; the joint solve, the roll joint's F_x terms
        // included, does no worse.
        let w = |q: f32| g.pitch_to_jaw_m + g.jaw_length_m * q.cos();
        let pitch_alone = (w(0.3) - w(0.5)).abs() / (0.5 * (w(0.3) + w(0.5))) * 10.0;
        assert!(p2 <= pitch_alone, "{p2} vs {pitch_alone}");
        let unlimited = total_force(&g, 0.5, 0.3, 0.5, tau, f32::INFINITY);
        assert_eq!(unlimited.force_n[0], Interval::UNBOUNDED);
    }

    /// Each end of the total force's bound is the tightest its form
    /// allows: no `lambda` tried another way (zero, a ridge solve at
    /// weights from 1e-4 to 1e4 as the estimator once used, random ones
    /// near those) gives a lower upper end or a higher lower end, at random
    /// poses, limits and jaw forces within them, each torque known to an
    /// interval around its true value; nor a narrower bound where no force
    /// within the limit explains the torques.
    #[test]
    fn eq5_no_other_lambda_gives_a_tighter_total_force_bound() {
        use nalgebra::{Matrix4, SMatrix, Vector4, Vector6};
        let g = Geometry::default();
        let mut rng = crate::test_rng::Rng(0x2545_f491_4f6c_dd1d);
        let mut next = || rng.unit() as f32;
        let mut gained = 0.0f32;
        for case in 0..600 {
            let (q2, qa, qb) = (next() * 2.4 - 1.2, next() * 1.2 - 0.3, next() * 1.2 - 0.3);
            let limit = 1.0 + next() * 60.0;
            // Half the cases from jaw forces within the limit, half drawn
            // anyhow (mostly torques no force within the limit explains).
            let consistent = case % 2 == 0;
            let from_forces = {
                let f = [(); 6].map(|_| f64::from((next() * 2.0 - 1.0) * limit));
                let q = [0.0, f64::from(q2), f64::from(qa), f64::from(qb)];
                grasp_torques(&g, q, [f[0], f[1], f[2]], [f[3], f[4], f[5]]).0
            };
            let tau: [Interval; 4] = core::array::from_fn(|i| {
                let spread = next() * 5e-3;
                let at = if consistent {
                    from_forces[i] as f32 + (next() * 2.0 - 1.0) * spread
                } else {
                    (next() * 2.0 - 1.0) * 0.05
                };
                Interval::new(at - spread, at + spread)
            });
            let out = total_force(&g, q2, qa, qb, tau, limit);
            let m = grasp_matrix(&g, q2, qa, qb);
            let m_na = SMatrix::<f32, 4, 6>::from_fn(|i, j| m[i][j]);
            let mid = tau.map(|t| t.mid());
            let half = tau.map(|t| 0.5 * t.width());
            for (k, c) in total_rows(qa, qb).iter().enumerate() {
                let b = out.force_n[k];
                assert!(b.lo <= b.hi, "component {k}: a crossed bound {b:?}");
                let mut tried = heapless::Vec::<Vector4<f32>, 32>::new();
                tried.push(Vector4::zeros()).unwrap();
                for e in -4..=4 {
                    let weight = 10f32.powi(e);
                    let mut normal: Matrix4<f32> = m_na * m_na.transpose();
                    for i in 0..4 {
                        let r = half[i] / limit;
                        normal[(i, i)] += weight * r * r + 1e-9;
                    }
                    let lambda = normal
                        .cholesky()
                        .unwrap()
                        .solve(&(m_na * Vector6::from(*c)));
                    tried.push(lambda).unwrap();
                    let jiggle = Vector4::from_fn(|_, _| 1.0 + 0.2 * (next() - 0.5));
                    tried.push(lambda.component_mul(&jiggle)).unwrap();
                }
                for lambda in &tried {
                    let (point, joints, prior) =
                        total_bound(&m, c, &(*lambda).into(), &mid, &half, limit).unwrap();
                    let reach = joints + prior;
                    let tol = 1e-4 * (reach + point.abs()) + 1e-6;
                    assert!(
                        b.width() <= 2.0 * reach + tol,
                        "component {k}: {b:?} wider than {point} +- {reach} at {lambda:?}"
                    );
                    if consistent {
                        assert!(
                            b.hi <= point + reach + tol && point - reach - tol <= b.lo,
                            "component {k}: {b:?} not inside {point} +- {reach} at {lambda:?}"
                        );
                    }
                    gained = gained.max(1.0 - b.width() / (2.0 * reach));
                }
            }
        }
        assert!(gained > 0.0, "never narrower than the ridge's");
    }

    /// A limit that is not positive bounds nothing.
    #[test]
    fn eq5_a_force_limit_that_is_not_positive_leaves_the_total_unbounded() {
        let g = Geometry::default();
        for limit in [0.0, -1.0, f32::NAN] {
            let out = total_force(&g, 0.5, 0.3, 0.3, [Interval::point(0.0); 4], limit);
            assert_eq!(out.force_n, [Interval::UNBOUNDED; 3]);
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
