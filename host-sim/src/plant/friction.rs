//! The friction elements of the plant (motor, slider 1, joint pin, slider
//! 2): an implicit Coulomb + viscous update, or LuGre bristles, and the end
//! stops.

/// A friction element's constants.
#[derive(Clone, Copy, Debug)]
pub(super) struct Element {
    /// Viscous coefficient (implicit).
    pub(super) b: f64,
    /// Kinetic friction.
    pub(super) fc: f64,
    /// Static friction.
    pub(super) fs: f64,
}

/// LuGre constants of one element.
#[derive(Clone, Copy, Debug)]
pub(super) struct Bristle {
    pub(super) sigma0: f64,
    pub(super) sigma1: f64,
    pub(super) stribeck: f64,
}

fn sign(x: f64) -> f64 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// Inelastic end stop: a position beyond `limit` is put back on it and the
/// velocity into the stop is removed (a plastic impact; unconditionally
/// stable, unlike a stiff contact spring).
#[inline]
pub(super) fn end_stop(x: &mut f64, v: &mut f64, limit: f64) {
    if *x > limit {
        *x = limit;
        *v = v.min(0.0);
    } else if *x < -limit {
        *x = -limit;
        *v = v.max(0.0);
    }
}

/// Implicit Coulomb + viscous update of one element (see the module docs).
#[inline]
pub(super) fn coulomb_step(v: f64, m: f64, f_other: f64, e: &Element, dt: f64) -> f64 {
    let p = m * v + dt * f_other;
    let limit = if v == 0.0 { e.fs } else { e.fc };
    if p.abs() <= limit * dt {
        0.0
    } else {
        (p - sign(p) * e.fc * dt) / (m + e.b * dt)
    }
}

/// LuGre update of one element: bristle state exactly for the step's
/// velocity, then the velocity with the bristle force (viscous implicit).
#[inline]
pub(super) fn lugre_step(
    v: f64,
    m: f64,
    f_other: f64,
    e: &Element,
    br: &Bristle,
    z: &mut f64,
    dt: f64,
) -> f64 {
    let z_old = *z;
    if v != 0.0 {
        let g = e.fc + (e.fs - e.fc) * (-(v / br.stribeck).powi(2)).exp();
        if g > 0.0 {
            let z_ss = sign(v) * g / br.sigma0;
            let rate = br.sigma0 * v.abs() / g;
            *z = z_ss + (z_old - z_ss) * (-rate * dt).exp();
        } else {
            *z = 0.0;
        }
    }
    let f_fric = br.sigma0 * *z + br.sigma1 * (*z - z_old) / dt;
    (m * v + dt * (f_other - f_fric)) / (m + e.b * dt)
}
