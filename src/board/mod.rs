//! The firmware's logic above the pins, generic over the hardware and tested
//! on the host.
//!
//! The RTIC app (`src/bin/firmware.rs`) is wiring; what its tasks *do* lives
//! here, generic over embedded-hal 1.0 traits (digital in/out) and a few
//! project traits where embedded-hal has none, so host tests run it with mock
//! pins that count calls (moteus-style) and the trace generator and the QEMU
//! replay test run exactly the firmware's sequence:
//!
//! * [`io`]: the [`SensorFrontEnd`] trait (encoder timers, ADC, DAC), the
//!   drive-enable output ([`DriveEnable`]), the fault-input handlers of the
//!   EXTI tasks ([`on_drive_fault_edge`], [`on_origin_edge`]) and the
//!   lock-free [`Events`] they share with the control task.
//! * [`sequencer`]: start-up (sensor check, homing on the origin switch, then
//!   the selected [`Program`]).
//! * [`control`]: one control tick ([`ControlLoop::tick`]): sample, apply
//!   pending requests and events, `Controller::step_timed`, DAC, drive line,
//!   telemetry record.
//! * [`boot`]: the fault a panic, HardFault or watchdog reset left for the
//!   next boot.
//! * [`timing`]: per-stage cycle stamps ([`StageStamps`]) over a
//!   [`CycleCounter`] (DWT on hardware, TIM2 under QEMU).
//! * [`trace`]: the recorded sensor trace the QEMU build replays
//!   ([`Trace`], [`ReplayFrontEnd`]) and the single-threaded [`Harness`] that
//!   runs the tasks in the order the firmware does.
//!
//! Register-level code (clocks, timers, ADC, DAC, EXTI, the panic handler) is
//! in the firmware binary's own modules, the only code that touches registers.

pub mod boot;
pub mod control;
pub mod io;
pub mod sequencer;
pub mod timing;
pub mod trace;

pub use control::{ControlLoop, Request, TickOutcome};
pub use io::{
    on_drive_fault_edge, on_origin_edge, DriveEnable, DriveKill, Events, InputLine, SensorFrontEnd,
};
pub use sequencer::{HomingConfig, Phase, Program, Sequencer};
pub use timing::{CycleCounter, StageStamps};
pub use trace::{Harness, ReplayFrontEnd, Trace, TraceSample};

#[cfg(test)]
pub(crate) mod mock;

/// Control rate of the firmware, Hz: the TIM6 update rate, set once at boot
/// (100 Hz to 20 kHz, as [`crate::Config::validate`] allows).
pub const CONTROL_RATE_HZ: f32 = 2000.0;

/// The configuration the firmware is built with: the core's defaults at
/// [`CONTROL_RATE_HZ`]. The trace generator and the replay test use the same.
pub fn firmware_config() -> crate::Config {
    crate::Config {
        control_rate_hz: CONTROL_RATE_HZ,
        ..crate::Config::default()
    }
}

/// [`firmware_config`] with probing on or off: what a trace is recorded
/// with (`host-sim trace --probe`) and replayed with (the trace header's
/// probing flag, [`Trace::config`]).
pub fn firmware_config_probing(probing: bool) -> crate::Config {
    let mut c = firmware_config();
    c.probe.enabled = probing;
    c
}
