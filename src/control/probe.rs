//! Active sensing at a hold: a small sinusoidal dither of the joint-angle
//! reference and a force estimate synchronous to it (issue 9, off unless
//! [`crate::config::ProbeConfig::enabled`]).
//!
//! Why it helps: at standstill a stuck slider or pin can carry any friction
//! inside its static band, and no passive sensor tells which, so the passive
//! bound ([`crate::fusion`]) stays as wide as the band. A dither that makes the
//! chain slip back and forth turns that unknown static friction into kinetic
//! friction of alternating sign. Over one whole period of the dither the
//! friction's mean is (for a symmetric band) zero, and so is the mean of every
//! other periodic term (inertia, the cables' elastic swing), while the
//! external force, constant over the period, stays. The probed estimate is
//! therefore the mean of the fused estimate over the last whole period.
//!
//! The physics that sets the frequency: the motor inertia reflected to cable
//! 0, `J_m (z_i / r_m)^2` (about 37 kg on the prototype), against cable 0's
//! stiffness low-passes the current's effect on slider 1 at a few hertz, so
//! the dither is a *position* dither slow enough for the cascade to track
//! (the joint really moves, which is the price: the tip moves by twice the
//! amplitude peak to peak). The report measures accuracy against tip motion
//! on every plant variant.
//!
//! The same window also averages two quantities the cable-0 slack check
//! needs (`crate::control::controller`): the motor's reading of the cable
//! tension and cable 0's elongation. The dither's currents swing that
//! reading above the slack limit once a period even with the rope hanging
//! slack, so while probing the check compares period means.
//!
//! Cost per tick: a phasor rotation (four multiplications; no
//! transcendental function, the phasor is reset exactly once per period),
//! five additions, two comparisons for slider 2's range and two
//! multiplications by the amplitude's factor; at each block's end, the
//! ring's sums (forty additions); at each period's end, whether the joint
//! followed and the next amplitude (see [`Probe::update`]).
//! The window is exact without a buffer of every sample: the period is
//! eight blocks of whole ticks, each block's sums go into an eight-slot
//! ring, and the mean over the ring (one whole period) is refreshed at every
//! block's end.

use crate::config::ProbeConfig;
use crate::math;

/// Blocks per dither period (the ring's size).
pub const BLOCKS: usize = 8;

/// Quantities averaged over a period (the fields of [`Averaged`]).
const VALUES: usize = 5;

/// Factor by which the dither's amplitude grows after a period in which the
/// joint did not follow it (see [`Probe::update`]).
pub const GROWTH: f32 = 2.0;

/// Constants derived from [`ProbeConfig`] and the control period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Probe {
    enabled: bool,
    amplitude_rad: f32,
    /// `A ω`, rad/s.
    amplitude_rad_s: f32,
    /// Phasor rotation per tick, `cos(ω T)`, `sin(ω T)`.
    rot_cos: f32,
    rot_sin: f32,
    /// Ticks per block (the period is [`BLOCKS`] blocks).
    block_ticks: u32,
    /// `1 / ticks per period`.
    inv_period_ticks: f32,
    /// Largest factor on the amplitude
    /// ([`ProbeConfig::max_amplitude_rad`] over [`ProbeConfig::amplitude_rad`]).
    max_gain: f32,
    /// Slider 2's travel over a period below which the joint counts as not
    /// following the dither: one and a half grating counts (a travel of one
    /// count is the reading's flicker at a count's edge, not motion), m.
    follow_m: f32,
}

/// State of the dither and of its synchronous mean.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProbeState {
    /// Phasor `(cos, sin)` of the dither's phase.
    phasor: (f32, f32),
    /// Tick within the current block.
    tick: u32,
    /// Block within the current period (the phasor is reset at 0).
    block: usize,
    /// Sums of the current block.
    acc: [f32; VALUES],
    /// Sums of the last [`BLOCKS`] blocks.
    ring: [[f32; VALUES]; BLOCKS],
    /// Blocks completed since the hold began (saturating).
    blocks_done: u32,
    /// The means over the last whole period, refreshed at each block's end
    /// once the first period of the hold has passed.
    mean: Option<Averaged>,
    /// Factor on the configured amplitude for the current period.
    gain: f32,
    /// Slider 2's least and greatest position in the current period, m
    /// (infinities before its first tick).
    x2_lo_m: f32,
    x2_hi_m: f32,
    /// Whether slider 2 travelled no more than a grating count in the last
    /// whole period: the joint did not follow the dither, so its friction
    /// did not average out.
    stuck: bool,
    /// Whether the payout stop held the motor in any tick of the current
    /// period.
    hold_growth: bool,
    /// Whether a period at the largest amplitude ended stuck: the dither
    /// cannot free what holds the joint, so it stays at the configured
    /// amplitude until slider 2 moves.
    gave_up: bool,
}

impl Default for ProbeState {
    fn default() -> Self {
        Self {
            phasor: (1.0, 0.0),
            tick: 0,
            block: 0,
            acc: [0.0; VALUES],
            ring: [[0.0; VALUES]; BLOCKS],
            blocks_done: 0,
            mean: None,
            gain: 1.0,
            x2_lo_m: f32::INFINITY,
            x2_hi_m: f32::NEG_INFINITY,
            stuck: false,
            hold_growth: false,
            gave_up: false,
        }
    }
}

impl ProbeState {
    /// Start a new hold: phase, block and sums back to their start. The ring
    /// is left as it is: [`Probe::update`] reads it only after two whole
    /// periods, by which time every slot has been written again, so clearing
    /// its 160 bytes would cost a control tick instructions for nothing.
    pub fn restart(&mut self) {
        self.phasor = (1.0, 0.0);
        self.tick = 0;
        self.block = 0;
        self.acc = [0.0; VALUES];
        self.blocks_done = 0;
        self.mean = None;
        self.gain = 1.0;
        self.x2_lo_m = f32::INFINITY;
        self.x2_hi_m = f32::NEG_INFINITY;
        self.stuck = false;
        self.hold_growth = false;
        self.gave_up = false;
    }

    /// The means over the last whole dither period, once published (the
    /// value [`Probe::update`] last returned).
    pub fn mean(&self) -> Option<Averaged> {
        self.mean
    }

    /// Whether the joint did not follow the dither over the last whole
    /// period (slider 2 travelled no more than one grating count): a mean
    /// over such a period is a passive estimate averaged, not a probed one.
    pub fn stuck(&self) -> bool {
        self.stuck
    }

    /// The factor on the configured amplitude in this period.
    pub fn gain(&self) -> f32 {
        self.gain
    }
}

/// The quantities the probe averages: one tick's values in, their means
/// over the last whole dither period out.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Averaged {
    /// Fused point estimate, N.
    pub f_ext_n: f32,
    /// Lower end of the fused bound, N.
    pub lo_n: f32,
    /// Upper end of the fused bound, N.
    pub hi_n: f32,
    /// The motor's torque-balance reading of the cable tension (the DOB's
    /// `T_1`), N.
    pub tension1_dob_n: f32,
    /// Cable 0's elongation `phi r_m / z_i - x1`, m.
    pub cable0_m: f32,
}

impl Averaged {
    fn to_array(self) -> [f32; VALUES] {
        [
            self.f_ext_n,
            self.lo_n,
            self.hi_n,
            self.tension1_dob_n,
            self.cable0_m,
        ]
    }

    fn from_array(v: [f32; VALUES]) -> Self {
        let [f_ext_n, lo_n, hi_n, tension1_dob_n, cable0_m] = v;
        Self {
            f_ext_n,
            lo_n,
            hi_n,
            tension1_dob_n,
            cable0_m,
        }
    }
}

impl Probe {
    /// Ticks per block for `config` at `period_s`: the period rounded to a
    /// whole number of blocks of whole ticks (at least one tick per block).
    pub fn block_ticks(config: &ProbeConfig, period_s: f32) -> u32 {
        let ticks = 1.0 / (config.frequency_hz * period_s * BLOCKS as f32);
        let rounded = (ticks + 0.5) as u32;
        rounded.max(1)
    }

    /// Precompute from the configuration; `period_s` is the control period.
    /// The frequency actually used is the one whose period is a whole number
    /// of blocks (see [`Probe::block_ticks`]).
    /// `grating_m_per_count` is slider 2's reading's resolution.
    pub fn new(config: &ProbeConfig, period_s: f32, grating_m_per_count: f32) -> Self {
        let block_ticks = Self::block_ticks(config, period_s);
        let period_ticks = block_ticks * BLOCKS as u32;
        let step_rad = 2.0 * math::PI / period_ticks as f32;
        let omega_rad_s = step_rad / period_s;
        Self {
            enabled: config.enabled,
            amplitude_rad: config.amplitude_rad,
            amplitude_rad_s: config.amplitude_rad * omega_rad_s,
            rot_cos: math::cos(step_rad),
            rot_sin: math::sin(step_rad),
            block_ticks,
            inv_period_ticks: 1.0 / period_ticks as f32,
            max_gain: if config.amplitude_rad > 0.0
                && config.max_amplitude_rad > config.amplitude_rad
            {
                config.max_amplitude_rad / config.amplitude_rad
            } else {
                1.0
            },
            follow_m: 1.5 * grating_m_per_count,
        }
    }

    /// Whether the probing motion is configured on.
    pub fn enabled(&self) -> bool {
        self.enabled
    }

    /// One tick of a hold with probing on: the dither to add to the
    /// reference, `(angle, rate)` in rad and rad/s, for this tick.
    #[inline]
    pub fn dither(&self, st: &ProbeState) -> (f32, f32) {
        let (c, s) = st.phasor;
        (
            st.gain * self.amplitude_rad * s,
            st.gain * self.amplitude_rad_s * c,
        )
    }

    /// A period's end: whether slider 2 stood still over it, and the next
    /// period's amplitude (see [`Probe::update`]). Once a period, so kept
    /// out of the tick's inlined path.
    #[inline(never)]
    fn end_period(&self, st: &mut ProbeState) {
        st.stuck = st.x2_hi_m - st.x2_lo_m < self.follow_m;
        if !st.stuck {
            st.gave_up = false;
        } else if st.gain >= self.max_gain && self.max_gain > 1.0 {
            st.gave_up = true;
        }
        // A load the last published mean is sure of (its bound excludes
        // zero) presses the joint against something.
        let loaded = matches!(st.mean, Some(m) if m.lo_n > 0.0 || m.hi_n < 0.0);
        st.gain = if st.stuck && !st.hold_growth && !st.gave_up && !loaded {
            math::clamp(GROWTH * st.gain, 1.0, self.max_gain)
        } else {
            1.0
        };
        st.x2_lo_m = f32::INFINITY;
        st.x2_hi_m = f32::NEG_INFINITY;
        st.hold_growth = false;
    }

    /// Add this tick's values, advance the phase, and return their means
    /// over the last whole period once the first period of the hold (the
    /// settling of the dither) has passed.
    ///
    /// `x2_m` is slider 2's position (the JAE's input). A period in which
    /// it travelled no more than one grating count is one in which the
    /// JAE saw nothing move: the chain stuck, its friction held whatever
    /// torque the cables put on it, and nothing averaged out. The next
    /// period's amplitude is then [`GROWTH`] times this one's, up to
    /// [`ProbeConfig::max_amplitude_rad`], until the joint follows; the
    /// first period it follows, the amplitude is the configured one again.
    /// (A dither of the reference swings the motor, and the cables' torque
    /// on a stuck joint, by an amount proportional to the amplitude; a stuck
    /// pin whose static band that swing does not span never slips, and the
    /// hold's own slow drift was all that freed it, seconds later.) The
    /// amplitude changes only when a period starts, where the dither's
    /// angle is zero.
    ///
    /// The amplitude does not grow, and returns to the configured one, when
    /// `hold_growth` was set in any tick of the period (the payout stop held
    /// the motor from unwinding, `cascade.payout_stop`: the chain stands
    /// still because cable 0 is nearly slack, and a larger swing would only
    /// pay out more rope on its unwinding half), or when the last published
    /// mean's bound excludes zero (a load is known to press the joint:
    /// against an object a larger swing squeezes it, and the force the
    /// probe averages is no longer constant over a period). And a period at
    /// the largest amplitude that still ends stuck gives up: whatever holds
    /// the joint, the dither cannot free it, so the amplitude stays the
    /// configured one until slider 2 moves.
    #[inline]
    pub fn update(
        &self,
        st: &mut ProbeState,
        values: Averaged,
        x2_m: f32,
        hold_growth: bool,
    ) -> Option<Averaged> {
        st.hold_growth |= hold_growth;
        for (a, v) in st.acc.iter_mut().zip(values.to_array()) {
            *a += v;
        }
        // Plain comparisons: the M4F has no single-instruction min/max.
        if x2_m < st.x2_lo_m {
            st.x2_lo_m = x2_m;
        }
        if x2_m > st.x2_hi_m {
            st.x2_hi_m = x2_m;
        }
        let (c, s) = st.phasor;
        st.phasor = (
            c * self.rot_cos - s * self.rot_sin,
            s * self.rot_cos + c * self.rot_sin,
        );
        st.tick += 1;
        if st.tick >= self.block_ticks {
            // `block` stays below BLOCKS (wrapped just below); the modulo
            // says so to the compiler, so no bounds check (and no panic
            // path) is left in the tick.
            st.ring[st.block % BLOCKS] = st.acc;
            st.acc = [0.0; VALUES];
            st.tick = 0;
            st.block += 1;
            if st.block >= BLOCKS {
                st.block = 0;
                // Exact phase once per period: no drift of the rotation.
                st.phasor = (1.0, 0.0);
                self.end_period(st);
            }
            st.blocks_done = st.blocks_done.saturating_add(1);
            // The ring changes only here: the mean is summed once a block,
            // not on every tick.
            if st.blocks_done >= 2 * BLOCKS as u32 {
                let mut sum = [0.0f32; VALUES];
                for block in &st.ring {
                    for (s, b) in sum.iter_mut().zip(block) {
                        *s += *b;
                    }
                }
                for s in &mut sum {
                    *s *= self.inv_period_ticks;
                }
                st.mean = Some(Averaged::from_array(sum));
            }
        }
        st.mean
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn probe(rate_hz: f32, f_hz: f32) -> Probe {
        let c = ProbeConfig {
            enabled: true,
            frequency_hz: f_hz,
            ..ProbeConfig::default()
        };
        Probe::new(&c, 1.0 / rate_hz, 1e-6)
    }

    #[test]
    fn the_period_is_a_whole_number_of_blocks_of_whole_ticks() {
        let ticks = |f_hz: f32, period_s: f32| {
            let c = ProbeConfig {
                frequency_hz: f_hz,
                ..ProbeConfig::default()
            };
            Probe::block_ticks(&c, period_s)
        };
        assert_eq!(ticks(5.0, 5e-4), 50);
        assert_eq!(ticks(4.0, 1e-3), 31);
        assert_eq!(ticks(1e4, 1e-3), 1);
    }

    #[test]
    fn the_dither_is_a_sine_of_the_configured_amplitude_that_returns_to_zero_each_period() {
        let p = probe(2000.0, 4.0);
        let mut st = ProbeState::default();
        let n = p.block_ticks * BLOCKS as u32;
        let (mut max, mut min) = (f32::MIN, f32::MAX);
        for _ in 0..3 * n {
            let (a, _) = p.dither(&st);
            max = max.max(a);
            min = min.min(a);
            // A joint that follows: slider 2 swings with it.
            p.update(&mut st, Averaged::default(), 4e-3 * a, false);
        }
        let amp = ProbeConfig::default().amplitude_rad;
        assert!((max - amp).abs() < 1e-3 * amp, "{max} vs {amp}");
        assert!((min + amp).abs() < 1e-3 * amp, "{min} vs {amp}");
        // After whole periods the phase is exactly zero again.
        assert_eq!(p.dither(&st).0, 0.0);
    }

    #[test]
    fn the_mean_removes_a_friction_that_follows_the_dithers_direction() {
        // Estimate = true force + a Coulomb term of the slip's sign + an
        // inertial swing: the period mean is the true force.
        let p = probe(1000.0, 5.0);
        let mut st = ProbeState::default();
        let force_n = 0.29;
        let mut last = None;
        for _ in 0..4 * p.block_ticks * BLOCKS as u32 {
            let (angle, rate) = p.dither(&st);
            let friction = 1.5 * math::sign_eps(rate, 0.0);
            let v = force_n + friction + 40.0 * angle;
            last = p.update(
                &mut st,
                Averaged {
                    f_ext_n: v,
                    lo_n: v - 2.0,
                    hi_n: v + 2.0,
                    tension1_dob_n: v,
                    cable0_m: 1e-3 * angle,
                },
                4e-3 * angle,
                false,
            );
        }
        let out = last.expect("published after the settling period");
        assert!((out.f_ext_n - force_n).abs() < 0.02, "{out:?}");
        assert!(out.lo_n < force_n && force_n < out.hi_n);
        assert_eq!(out.tension1_dob_n, out.f_ext_n);
        assert!(out.cable0_m.abs() < 1e-9, "{out:?}");
    }

    #[test]
    fn nothing_is_published_during_the_first_period() {
        let p = probe(2000.0, 4.0);
        let mut st = ProbeState::default();
        let ones = Averaged::from_array([1.0; VALUES]);
        for _ in 0..2 * p.block_ticks * BLOCKS as u32 - 1 {
            assert!(p.update(&mut st, ones, 0.0, false).is_none());
        }
        assert_eq!(p.update(&mut st, ones, 0.0, false), Some(ones));
    }

    /// A joint that does not follow (slider 2 still): the amplitude doubles
    /// each period up to the configured largest, and the period is flagged
    /// stuck; once slider 2 follows the grown dither for a whole period the
    /// amplitude is the configured one again. The amplitude only changes
    /// where a period starts (the dither's angle is zero there).
    #[test]
    fn the_dither_grows_while_the_joint_does_not_follow_and_returns_once_it_does() {
        let c = ProbeConfig {
            enabled: true,
            ..ProbeConfig::default()
        };
        let (r, count) = (4e-3, 1e-6);
        let p = Probe::new(&c, 1.0 / 2000.0, count);
        let n = p.block_ticks * BLOCKS as u32;
        let mut st = ProbeState::default();
        let mut peaks = [0.0f32; 7];
        for peak in &mut peaks {
            for _ in 0..n {
                let (a, _) = p.dither(&st);
                *peak = peak.max(a.abs());
                let before = st.gain();
                p.update(&mut st, Averaged::default(), 0.0, false);
                if st.tick != 0 || st.block != 0 {
                    assert_eq!(st.gain(), before, "changed inside a period");
                }
            }
            assert!(st.stuck());
        }
        let amp = c.amplitude_rad;
        for (k, peak) in peaks.iter().take(5).enumerate() {
            let expected = (amp * GROWTH.powi(k as i32)).min(c.max_amplitude_rad);
            assert!(
                (peak - expected).abs() < 1e-3 * expected,
                "period {k}: {peak} vs {expected}"
            );
        }
        assert!(peaks[4] >= c.max_amplitude_rad * 0.999 && peaks[4] <= c.max_amplitude_rad * 1.001);
        // A period at the largest amplitude that ended stuck gave up: the
        // configured amplitude from then on, while slider 2 stands still.
        assert!((peaks[5] - amp).abs() < 1e-3 * amp && (peaks[6] - amp).abs() < 1e-3 * amp);
        // Slider 2 follows the grown dither: back to the configured amplitude.
        for _ in 0..n {
            let (a, _) = p.dither(&st);
            p.update(&mut st, Averaged::default(), r * a, false);
        }
        assert!(!st.stuck());
        assert_eq!(st.gain(), 1.0);
        // A reading that flickers by one count still counts as stuck; two
        // counts of travel do not.
        for k in 0..n {
            p.update(&mut st, Averaged::default(), count * (k % 2) as f32, false);
        }
        assert!(st.stuck());
        assert_eq!(st.gain(), GROWTH);
        for k in 0..n {
            p.update(&mut st, Averaged::default(), count * (k % 3) as f32, false);
        }
        assert!(!st.stuck());
        assert_eq!(st.gain(), 1.0);
        // The payout stop held the motor for one tick of a stuck period: no
        // growth, back to the configured amplitude; still flagged stuck.
        for _ in 0..n {
            p.update(&mut st, Averaged::default(), 0.0, false);
        }
        assert_eq!(st.gain(), GROWTH);
        for k in 0..n {
            p.update(&mut st, Averaged::default(), 0.0, k == n / 2);
        }
        assert!(st.stuck());
        assert_eq!(st.gain(), 1.0);
        // A load the published mean is sure of (its bound 1..3 N excludes
        // zero): a stuck joint pressed against something, no growth.
        let loaded = Averaged {
            lo_n: 1.0,
            hi_n: 3.0,
            ..Averaged::default()
        };
        let mut pressed = ProbeState::default();
        for _ in 0..4 * n {
            p.update(&mut pressed, loaded, 0.0, false);
        }
        assert!(pressed.stuck() && pressed.mean().is_some());
        assert_eq!(pressed.gain(), 1.0);
        // A configured largest at or below the amplitude: it never grows.
        let fixed = Probe::new(
            &ProbeConfig {
                max_amplitude_rad: 0.5 * amp,
                ..c
            },
            1.0 / 2000.0,
            count,
        );
        let mut st = ProbeState::default();
        for _ in 0..3 * n {
            fixed.update(&mut st, Averaged::default(), 0.0, false);
        }
        assert!(st.stuck());
        assert_eq!(st.gain(), 1.0);
    }
}
