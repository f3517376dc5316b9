//! The one place where transcendental functions are called.
//!
//! `x.sin()` resolves to `std` on the host and to nothing (or micromath) on the
//! target, so the simulator would not test the firmware's arithmetic. Every
//! transcendental in the core goes through this module, with explicit paths, so
//! host and target run bit-identical code (TOOLCHAIN pitfall 3).
//!
//! * `libm` (a pure-Rust port of musl's libm, correctly rounded to within 1 ulp)
//!   for everything whose accuracy matters: filter discretization, square roots,
//!   exponentials, the trajectory generator.
//! * `micromath` is kept for [`fast_sin`], an approximation (about 1e-3 abs.
//!   error) that is cheap on a Cortex-M4F; it is used nowhere on the estimate
//!   path.

/// Sine, radians in.
#[inline]
pub fn sin(x: f32) -> f32 {
    libm::sinf(x)
}

/// Cosine, radians in.
#[inline]
pub fn cos(x: f32) -> f32 {
    libm::cosf(x)
}

/// `e^x`.
#[inline]
pub fn exp(x: f32) -> f32 {
    libm::expf(x)
}

/// Square root (NaN for negative input).
#[inline]
pub fn sqrt(x: f32) -> f32 {
    libm::sqrtf(x)
}

/// Hyperbolic tangent.
#[inline]
pub fn tanh(x: f32) -> f32 {
    libm::tanhf(x)
}

/// Absolute value (no transcendental, but `f32::abs` is `std`-only before 1.85
/// in `no_std` code paths of some crates; keep it here for uniformity).
#[inline]
pub fn abs(x: f32) -> f32 {
    libm::fabsf(x)
}

/// Cheap sine from `micromath` (max abs. error about 1e-3). Not used on the
/// estimate path.
#[inline]
pub fn fast_sin(x: f32) -> f32 {
    micromath::F32Ext::sin(x)
}

/// `f64` square root for host-side least squares helpers that run in the core.
#[inline]
pub fn sqrt_f64(x: f64) -> f64 {
    libm::sqrt(x)
}

/// Clamp `x` into `[lo, hi]`; NaN passes through (callers check finiteness).
#[inline]
pub fn clamp(x: f32, lo: f32, hi: f32) -> f32 {
    if x < lo {
        lo
    } else if x > hi {
        hi
    } else {
        x
    }
}

/// Sign with a dead zone: `+1` above `eps`, `-1` below `-eps`, `0` inside.
#[inline]
pub fn sign_eps(x: f32, eps: f32) -> f32 {
    if x > eps {
        1.0
    } else if x < -eps {
        -1.0
    } else {
        0.0
    }
}

/// π as `f32`.
pub const PI: f32 = core::f32::consts::PI;

#[cfg(test)]
mod tests {
    use super::*;

    /// Golden values: the same bits must come out on the target (the QEMU test
    /// of the firmware compares whole ticks bit for bit).
    #[test]
    fn golden_values_are_bit_exact() {
        assert_eq!(sin(0.6173).to_bits(), 0.578_835_55_f32.to_bits());
        assert_eq!(exp(-0.1).to_bits(), 0.904_837_4_f32.to_bits());
        assert_eq!(sqrt(2.0).to_bits(), core::f32::consts::SQRT_2.to_bits());
    }

    #[test]
    fn clamp_and_sign() {
        assert_eq!(clamp(3.0, -1.0, 1.0), 1.0);
        assert_eq!(clamp(-3.0, -1.0, 1.0), -1.0);
        assert_eq!(sign_eps(0.5, 1.0), 0.0);
        assert_eq!(sign_eps(-2.0, 1.0), -1.0);
    }
}
