//! The constants the integration derives once from the parameters and the
//! step, and the stability bound that refuses a step too coarse for the
//! stiffest mode (the plant module's "Integration").

use super::friction::{Bristle, Element};
use super::params::{PlantParams, SliderParams};

/// Constants derived once from the parameters and the step.
#[derive(Clone, Copy, Debug)]
pub(super) struct Derived {
    pub(super) dt: f64,
    /// Cable metres per motor radian, `r_m / z_i`.
    pub(super) rw: f64,
    pub(super) drive_alpha: f64,
    pub(super) motor: Element,
    pub(super) slider1: Element,
    pub(super) joint: Element,
    pub(super) slider2: Element,
    pub(super) bristles: Option<[Bristle; 3]>,
    pub(super) creep_alpha: f64,
    pub(super) cubic: f64,
    pub(super) omega_max: f64,
    pub(super) damping_max: f64,
}

impl Derived {
    /// The constants of `p`; fails when `w_max dt` or the fastest damping
    /// rate times `dt` exceeds `integration.max_omega_dt`.
    pub(super) fn new(p: &PlantParams) -> anyhow::Result<Self> {
        let dt = 1.0 / p.integration.step_hz;
        let rw = p.motor.rope_wheel_radius_m / p.motor.gear_ratio;
        let r = p.joint.pulley_radius_m;
        let elem = |s: &SliderParams| Element {
            b: s.viscous_n_s_m,
            fc: s.coulomb_n,
            fs: s.static_n,
        };
        let bristles = p.effects.presliding.map(|pre| {
            let slider = |s: &SliderParams| {
                let sigma0 = s.coulomb_n.max(1e-9) / pre.slider_presliding_m;
                Bristle {
                    sigma0,
                    sigma1: 2.0 * pre.damping_ratio * (sigma0 * s.mass_kg).sqrt(),
                    stribeck: pre.slider_stribeck_m_s,
                }
            };
            let j0 = p.joint.coulomb_nm.max(1e-12) / pre.joint_presliding_rad;
            [
                slider(&p.slider1),
                Bristle {
                    sigma0: j0,
                    sigma1: 2.0 * pre.damping_ratio * (j0 * p.joint.inertia_kg_m2).sqrt(),
                    stribeck: pre.joint_stribeck_rad_s,
                },
                slider(&p.slider2),
            ]
        });

        // Mass-normalised stiffness and damping matrices in cable coordinates
        // u = [rw phi, x1, r theta, x2]; Gershgorin bounds their largest
        // eigenvalues.
        let m = [
            p.motor.rotor_inertia_kg_m2 / (rw * rw),
            p.slider1.mass_kg,
            p.joint.inertia_kg_m2 / (r * r),
            p.slider2.mass_kg,
        ];
        let (k0, c0) = if p.motor_decoupled {
            (0.0, 0.0)
        } else {
            (p.cable0.stiffness_n_m, p.cable0.damping_n_s_m)
        };
        let cubic = p.effects.spring_hardening.map_or(0.0, |h| h.cubic_n_m3);
        // Tangent stiffness of the spring up to 10 mm of travel.
        let ks = p.spring.stiffness_n_m + 3.0 * cubic.abs() * 1e-4;
        let links = [
            (0, 1, k0, c0),
            (1, 2, p.cable1.stiffness_n_m, p.cable1.damping_n_s_m),
            (2, 3, p.cable2.stiffness_n_m, p.cable2.damping_n_s_m),
        ];
        let mut kk = [[0.0f64; 4]; 4];
        let mut cc = [[0.0f64; 4]; 4];
        for (i, j, k, c) in links {
            kk[i][i] += k;
            kk[j][j] += k;
            kk[i][j] -= k;
            kk[j][i] -= k;
            cc[i][i] += c;
            cc[j][j] += c;
            cc[i][j] -= c;
            cc[j][i] -= c;
        }
        kk[3][3] += ks;
        if let Some(b) = &bristles {
            kk[1][1] += b[0].sigma0;
            kk[2][2] += b[1].sigma0 / (r * r);
            kk[3][3] += b[2].sigma0;
            cc[1][1] += b[0].sigma1;
            cc[2][2] += b[1].sigma1 / (r * r);
            cc[3][3] += b[2].sigma1;
        }
        // Gershgorin's row sums, and the row (the mass) that gives the
        // largest: what a too coarse step has to be told about.
        let bound = |a: &[[f64; 4]; 4]| {
            (0..4)
                .map(|i| {
                    let sum: f64 = (0..4).map(|j| a[i][j].abs() / (m[i] * m[j]).sqrt()).sum();
                    (sum, i)
                })
                .fold((0.0, 0), |best, x| if x.0 > best.0 { x } else { best })
        };
        const MASSES: [&str; 4] = [
            "the motor (rotor_inertia_kg_m2 through the rope wheel)",
            "slider1.mass_kg",
            "the joint (joint.inertia_kg_m2 at the pulley)",
            "slider2.mass_kg",
        ];
        let (omega_sq, stiff_row) = bound(&kk);
        let omega_max = omega_sq.sqrt();
        let (damping_max, damped_row) = bound(&cc);
        let lim = p.integration.max_omega_dt;
        anyhow::ensure!(
            omega_max * dt <= lim && damping_max * dt <= lim,
            "plant step {dt:e} s too coarse: w_max = {omega_max:.0} rad/s (at {}) gives w dt = \
             {:.3}, damping rate {damping_max:.0} 1/s (at {}) gives {:.3} (limit {lim}); raise \
             integration.step_hz, or check that element's mass and its cables' stiffness and \
             damping",
            MASSES[stiff_row],
            omega_max * dt,
            MASSES[damped_row],
            damping_max * dt
        );
        Ok(Derived {
            dt,
            rw,
            drive_alpha: 1.0 - (-2.0 * std::f64::consts::PI * p.drive.bandwidth_hz * dt).exp(),
            motor: Element {
                b: p.motor.viscous_nm_s_rad,
                fc: p.motor.coulomb_nm,
                fs: p.motor.coulomb_nm,
            },
            slider1: elem(&p.slider1),
            joint: Element {
                b: p.joint.viscous_nm_s_rad,
                fc: p.joint.coulomb_nm,
                fs: p.joint.static_nm,
            },
            slider2: elem(&p.slider2),
            bristles,
            creep_alpha: p.effects.creep.map_or(0.0, |c| 1.0 - (-dt / c.tau_s).exp()),
            cubic,
            omega_max,
            damping_max,
        })
    }
}
