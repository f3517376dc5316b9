//! Faults: a `Copy` enum with stable numeric codes.
//!
//! A fault disables the drive within the tick in which it is detected, is
//! latched by the [`crate::Controller`], and is cleared only by an explicit
//! [`crate::Controller::clear_fault`]. The host tool decodes telemetry with the
//! same numbers ([`Fault::from_code`]); never renumber a variant.

use core::fmt;

/// Which sensor a fault is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Sensor {
    /// Grating 1 (slider 1).
    Grating1,
    /// Grating 2 (slider 2).
    Grating2,
    /// Motor encoder.
    Motor,
    /// Magnetic joint encoder.
    Magnetic,
}

/// A latched fault. Codes are stable (`code()`), 0 means "no fault".
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Fault {
    /// A counter moved further in one tick than the mechanism can.
    EncoderJump(Sensor),
    /// The current-monitor ADC sits at a rail.
    AdcRail,
    /// A filter or estimator produced NaN or infinity.
    NonFinite,
    /// The joint-angle estimate left the mechanical range.
    AngleRange,
    /// The motor's velocity exceeded its limit.
    Overspeed,
    /// The measured current exceeded `limits.max_current_a` with the drive
    /// enabled: the drive is not limiting its current.
    OverCurrent,
    /// The winding's I²t state (the measured current squared, low-passed
    /// with the winding's thermal time constant) exceeded the square of the
    /// continuous current: the winding is overheating.
    I2t,
    /// The measured current did not follow the reference
    /// (`limits.max_current_error_a`, low-passed over
    /// `limits.current_error_time_s`): a broken motor lead, a drive that
    /// ignores its reference, or a supply that cannot deliver.
    CurrentTracking,
    /// Cable 1's tension, read off its stretch, fell below
    /// `limits.min_tension_fraction` of the preload: the cable is going
    /// slack or broke.
    TransmissionSlack,
    /// Cable 0 (rope wheel to slider 1) went slack: the motor's torque
    /// balance read its tension below the slack limit while the motor paid
    /// out more cable than slider 1 took up, by more than the cable could
    /// shorten between that limit and zero tension. Slider 1's friction can
    /// hold cable 1 taut (so [`Fault::TransmissionSlack`] stays quiet)
    /// while the motor unwinds without bound.
    Cable0Slack,
    /// The control task missed its deadline.
    Overrun,
    /// The drive reported a fault on its fault line.
    DriveFault,
    /// The origin switch triggered while the joint was moving in a mode that
    /// does not expect it.
    OriginDuringMotion,
    /// Start-up sensor check failed or homing did not find the origin.
    Homing,
    /// A program that asks for a heartbeat received no request within its
    /// `command_timeout_s` (the host or the link is gone).
    CommandTimeout,
    /// Slider 1 moved during a motor-only program (the no-load motor run,
    /// [`crate::board::HomingConfig::motor_only`]): the rope wheel is
    /// hooked to the cable after all, or slider 1 is not clamped.
    TransmissionHooked,
    /// The firmware panicked; reported at the next boot from a word kept in
    /// RAM through the reset.
    Panic,
    /// A HardFault (bad memory access, stack overflow into flip-link's
    /// guard); reported at the next boot like a panic.
    HardFault,
    /// The independent watchdog reset the MCU: the control task stopped
    /// completing its ticks. Reported at the next boot.
    Watchdog,
}

impl Fault {
    /// Stable numeric code (1..=255). Telemetry carries this number.
    pub const fn code(self) -> u8 {
        match self {
            Fault::EncoderJump(Sensor::Grating1) => 1,
            Fault::EncoderJump(Sensor::Grating2) => 2,
            Fault::EncoderJump(Sensor::Motor) => 3,
            Fault::EncoderJump(Sensor::Magnetic) => 4,
            // 5 is retired (a current-monitor "jump": the monitor has no
            // physical slew bound tighter than its range, so it was never
            // raised); never reuse it.
            Fault::AdcRail => 10,
            Fault::NonFinite => 11,
            Fault::AngleRange => 12,
            Fault::Overspeed => 13,
            Fault::TransmissionSlack => 14,
            Fault::OverCurrent => 15,
            Fault::I2t => 16,
            Fault::CurrentTracking => 17,
            Fault::Cable0Slack => 18,
            Fault::Overrun => 20,
            Fault::DriveFault => 21,
            Fault::OriginDuringMotion => 22,
            Fault::Homing => 23,
            Fault::CommandTimeout => 24,
            Fault::TransmissionHooked => 25,
            Fault::Panic => 30,
            Fault::HardFault => 31,
            Fault::Watchdog => 32,
        }
    }

    /// Decode a telemetry code; `None` for 0 or an unknown code.
    pub const fn from_code(code: u8) -> Option<Fault> {
        Some(match code {
            1 => Fault::EncoderJump(Sensor::Grating1),
            2 => Fault::EncoderJump(Sensor::Grating2),
            3 => Fault::EncoderJump(Sensor::Motor),
            4 => Fault::EncoderJump(Sensor::Magnetic),
            10 => Fault::AdcRail,
            11 => Fault::NonFinite,
            12 => Fault::AngleRange,
            13 => Fault::Overspeed,
            14 => Fault::TransmissionSlack,
            15 => Fault::OverCurrent,
            16 => Fault::I2t,
            17 => Fault::CurrentTracking,
            18 => Fault::Cable0Slack,
            20 => Fault::Overrun,
            21 => Fault::DriveFault,
            22 => Fault::OriginDuringMotion,
            23 => Fault::Homing,
            24 => Fault::CommandTimeout,
            25 => Fault::TransmissionHooked,
            30 => Fault::Panic,
            31 => Fault::HardFault,
            32 => Fault::Watchdog,
            _ => return None,
        })
    }

    /// Code of an optional fault (0 = none), as telemetry carries it.
    pub const fn code_of(fault: Option<Fault>) -> u8 {
        match fault {
            Some(f) => f.code(),
            None => 0,
        }
    }
}

impl fmt::Display for Fault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Fault::EncoderJump(s) => write!(f, "encoder jump beyond physical speed on {s:?}"),
            Fault::AdcRail => f.write_str("current-monitor ADC at a rail"),
            Fault::NonFinite => f.write_str("non-finite value in a filter or estimator"),
            Fault::AngleRange => f.write_str("joint-angle estimate out of mechanical range"),
            Fault::Overspeed => f.write_str("motor overspeed"),
            Fault::OverCurrent => f.write_str("measured current above its limit"),
            Fault::I2t => f.write_str("winding I2t above its continuous rating"),
            Fault::CurrentTracking => f.write_str("measured current does not follow the reference"),
            Fault::TransmissionSlack => f.write_str("cable slack: cable-1 tension below its limit"),
            Fault::Cable0Slack => {
                f.write_str("cable 0 slack: the motor paid out cable that slider 1 did not take up")
            }
            Fault::Overrun => f.write_str("control tick overran its deadline"),
            Fault::DriveFault => f.write_str("drive reported a fault"),
            Fault::OriginDuringMotion => f.write_str("origin switch hit during motion"),
            Fault::Homing => f.write_str("start-up check or homing failed"),
            Fault::CommandTimeout => f.write_str("no request within the program's command timeout"),
            Fault::TransmissionHooked => {
                f.write_str("slider 1 moved in a motor-only run: the rope wheel is hooked")
            }
            Fault::Panic => f.write_str("firmware panic (before the last reset)"),
            Fault::HardFault => f.write_str("HardFault (before the last reset)"),
            Fault::Watchdog => f.write_str("watchdog reset: the control task stopped"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_round_trip_and_are_unique() {
        let mut seen = [false; 256];
        for code in 0..=255u8 {
            if let Some(f) = Fault::from_code(code) {
                assert_eq!(f.code(), code);
                assert!(!seen[code as usize]);
                seen[code as usize] = true;
            }
        }
        assert_eq!(seen.iter().filter(|s| **s).count(), 22);
        assert_eq!(Fault::from_code(5), None, "code 5 is retired");
        assert_eq!(Fault::from_code(0), None);
        assert_eq!(Fault::code_of(None), 0);
    }
}
