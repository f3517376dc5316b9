//! Raw codes at the board edge and their one conversion each to SI.
//!
//! Counters arrive as the timers hold them: the gratings on 32-bit timers
//! (TIM2/TIM5), the motor and magnetic encoders on 16-bit timers (TIM4/TIM3) that
//! wrap. [`Extender16`] turns a wrapping 16-bit count into a continuous `i32`
//! by assuming fewer than 32768 counts between two samples (at 20 kHz that is
//! 8192 rev/s of the motor, far beyond its 11 000 rpm rating).

use crate::math::PI;

/// Grating count, 1 µm per count by default (Renishaw RGS-40, Table 1).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct GratingCount(pub i32);

/// Motor encoder timer count (16-bit, wraps), 4000 counts/rev (quadrature).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct MotorCount(pub u16);

/// Magnetic joint encoder timer count (16-bit, wraps), 4096 counts/rev.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct MagneticCount(pub u16);

/// 12-bit ADC code of the drive's current monitor.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct AdcCode(pub u16);

/// 12-bit DAC code of the drive's current reference.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct DacCode(pub u16);

/// Scales of the sensors and converters (configuration, validated by
/// [`crate::Config::validate`]).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, deny_unknown_fields))]
pub struct Scales {
    /// Grating resolution, m per count (both gratings).
    pub grating_m_per_count: f32,
    /// Motor encoder counts per motor-shaft revolution (quadrature).
    pub motor_counts_per_rev: u32,
    /// Magnetic encoder counts per joint revolution.
    pub magnetic_counts_per_rev: u32,
    /// Current-monitor scale, A per ADC code.
    pub adc_a_per_code: f32,
    /// ADC code that means 0 A.
    pub adc_zero_code: f32,
    /// Codes this close to 0 or 4095 are a rail (sensor or wiring fault).
    pub adc_rail_margin_codes: u16,
    /// Current-reference scale, A per DAC code.
    pub dac_a_per_code: f32,
    /// DAC code that means 0 A.
    pub dac_zero_code: f32,
}

impl Default for Scales {
    fn default() -> Self {
        // The drive's ±10 V monitor/reference spans ±2.5 A; the board's
        // dividers/amplifiers map it onto the 12-bit 0..3.3 V range.
        Self {
            grating_m_per_count: 1e-6,
            motor_counts_per_rev: 4000,
            magnetic_counts_per_rev: 4096,
            adc_a_per_code: 5.0 / 4096.0,
            adc_zero_code: 2048.0,
            adc_rail_margin_codes: 8,
            dac_a_per_code: 5.0 / 4096.0,
            dac_zero_code: 2048.0,
        }
    }
}

/// Highest code of the 12-bit converters.
pub const CODE_MAX_12BIT: u16 = 4095;

impl Scales {
    /// Grating count to metres.
    #[inline]
    pub fn grating_m(&self, c: GratingCount) -> f32 {
        c.0 as f32 * self.grating_m_per_count
    }

    /// Continuous (extended) motor count to motor-shaft radians.
    #[inline]
    pub fn motor_rad(&self, counts: i32) -> f32 {
        counts as f32 * (2.0 * PI / self.motor_counts_per_rev as f32)
    }

    /// Continuous (extended) magnetic count to joint radians.
    #[inline]
    pub fn magnetic_rad(&self, counts: i32) -> f32 {
        counts as f32 * (2.0 * PI / self.magnetic_counts_per_rev as f32)
    }

    /// ADC code to amps.
    #[inline]
    pub fn adc_a(&self, c: AdcCode) -> f32 {
        (c.0 as f32 - self.adc_zero_code) * self.adc_a_per_code
    }

    /// Is the ADC code at (or within the margin of) a rail?
    #[inline]
    pub fn adc_at_rail(&self, c: AdcCode) -> bool {
        c.0 <= self.adc_rail_margin_codes || c.0 >= CODE_MAX_12BIT - self.adc_rail_margin_codes
    }

    /// Amps to the nearest DAC code, saturated to 0..=4095.
    #[inline]
    pub fn dac_code(&self, current_a: f32) -> DacCode {
        let code = current_a / self.dac_a_per_code + self.dac_zero_code + 0.5;
        let code = crate::math::clamp(code, 0.0, CODE_MAX_12BIT as f32);
        // NaN maps to 0 by `as`; the controller never passes NaN (it faults first).
        DacCode(code as u16)
    }

    /// DAC code back to amps (what the drive is actually told).
    #[inline]
    pub fn dac_a(&self, c: DacCode) -> f32 {
        (c.0 as f32 - self.dac_zero_code) * self.dac_a_per_code
    }

    /// Inverse of [`Scales::grating_m`], rounding to the nearest count (for the
    /// simulator's sensors).
    #[inline]
    pub fn grating_count(&self, x_m: f32) -> GratingCount {
        GratingCount(libm::roundf(x_m / self.grating_m_per_count) as i32)
    }
}

/// Extends a wrapping 16-bit timer count to a continuous `i32`.
///
/// Configuration-free state; the first sample sets the reference.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Extender16 {
    last: Option<u16>,
    total: i32,
}

impl Extender16 {
    /// Feed the timer's current count; returns the continuous count and the
    /// step since the last sample.
    #[inline]
    pub fn update(&mut self, raw: u16) -> (i32, i32) {
        let delta = match self.last {
            None => {
                self.total = raw as i16 as i32;
                0
            }
            Some(last) => raw.wrapping_sub(last) as i16 as i32,
        };
        self.last = Some(raw);
        self.total = self.total.wrapping_add(delta);
        (self.total, delta)
    }

    /// Continuous count after the last update.
    #[inline]
    pub fn value(&self) -> i32 {
        self.total
    }

    /// Forget the reference (next sample restarts from its own value).
    pub fn reset(&mut self) {
        *self = Self::default();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn extender_crosses_wrap_both_ways() {
        let mut e = Extender16::default();
        assert_eq!(e.update(65530), (-6, 0));
        assert_eq!(e.update(4), (4, 10));
        assert_eq!(e.update(65534), (-2, -6));
        // 1000 full turns of a 4000-count encoder accumulate without drift.
        let mut e = Extender16::default();
        let mut raw: u16 = 0;
        e.update(raw);
        for _ in 0..4_000_000 / 1000 {
            raw = raw.wrapping_add(1000);
            e.update(raw);
        }
        assert_eq!(e.value(), 4_000_000);
    }

    #[test]
    fn scales_round_trip() {
        let s = Scales::default();
        assert_eq!(s.grating_m(GratingCount(-1500)), -1.5e-3);
        assert!((s.motor_rad(4000) - 2.0 * PI).abs() < 1e-6);
        assert!((s.adc_a(AdcCode(2048 + 819)) - 0.99975586).abs() < 1e-6);
        let code = s.dac_code(1.0);
        assert!((s.dac_a(code) - 1.0).abs() <= s.dac_a_per_code / 2.0);
        assert_eq!(s.dac_code(100.0), DacCode(4095));
        assert_eq!(s.dac_code(-100.0), DacCode(0));
        assert!(s.adc_at_rail(AdcCode(3)) && s.adc_at_rail(AdcCode(4095)));
        assert!(!s.adc_at_rail(AdcCode(2048)));
        assert_eq!(s.grating_count(-2.4996e-3), GratingCount(-2500));
    }
}
