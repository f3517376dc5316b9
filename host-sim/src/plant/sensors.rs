//! What the board reads from the plant: quantized counters and the current
//! monitor through the noisy 12-bit ADC (the plant module's "Sensors").

use cable_joint::units::{AdcCode, GratingCount, MagneticCount, MotorCount, CODE_MAX_12BIT};
use cable_joint::RawSample;
use rand_distr::{Distribution, StandardNormal};

use super::Plant;

impl Plant {
    /// What the current monitor reports now (before the ADC), A: the sensed
    /// current plus the monitor's offset, drift (if in the monitor path) and
    /// noise. With the drift in the drive's sensor, the sensed current is the
    /// winding current plus that offset.
    fn monitor_a(&mut self) -> f64 {
        let dr = &self.p.drive;
        let drift = if self.p.effects.offset_drift.is_some() {
            self.s.drift_a
        } else {
            0.0
        };
        let noise: f64 = StandardNormal.sample(&mut self.rng);
        self.s.current_a + dr.monitor_offset_a + drift + dr.monitor_noise_a * noise
    }

    /// Read every sensor as the board does (quantized counters, noisy ADC).
    pub fn sample(&mut self) -> RawSample {
        let sc = self.p.sensors;
        let scales = &sc.scales;
        let s = self.s;
        let grating = |x_m: f64, init: i32| {
            let counts = (x_m / scales.grating_m_per_count as f64).round() as i64;
            GratingCount((init as i64).wrapping_add(counts) as i32)
        };
        let wrap16 = |angle_rad: f64, per_rev: u32, init: u16| {
            let counts = (angle_rad * per_rev as f64 / std::f64::consts::TAU).round() as i64;
            (init as i64 + counts).rem_euclid(1 << 16) as u16
        };
        let magnetic = if sc.magnetic_fitted {
            wrap16(
                s.theta_rad,
                scales.magnetic_counts_per_rev,
                sc.magnetic_initial_count,
            )
        } else {
            sc.magnetic_initial_count
        };
        let i_mon = self.monitor_a();
        let code = (i_mon / scales.adc_a_per_code as f64 + scales.adc_zero_code as f64).round();
        let code = if code.is_finite() {
            code.clamp(0.0, CODE_MAX_12BIT as f64) as u16
        } else {
            0
        };
        RawSample {
            grating1: grating(s.x1_m, sc.grating_initial_counts[0]),
            grating2: grating(s.x2_m, sc.grating_initial_counts[1]),
            motor: MotorCount(wrap16(
                s.phi_rad,
                scales.motor_counts_per_rev,
                sc.motor_initial_count,
            )),
            magnetic: MagneticCount(magnetic),
            current: AdcCode(code),
        }
    }
}
