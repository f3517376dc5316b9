//! Pins and converters as the control logic sees them.
//!
//! * [`SensorFrontEnd`]: the encoder timers, the current-monitor ADC and the
//!   current-reference DAC (embedded-hal has no trait for these).
//! * [`DriveEnable`]: the drive-enable output (embedded-hal `OutputPin`).
//! * [`InputLine`]: a digital input with its polarity (embedded-hal
//!   `InputPin`): the drive's fault line and the photoelectric origin switch.
//! * [`on_drive_fault_edge`] / [`on_origin_edge`]: the bodies of the two EXTI
//!   tasks. They run above the control task, cut the drive at once through a
//!   [`DriveKill`] (an atomic set/reset register write that needs no
//!   ownership of the pin) and leave the fault in [`Events`] for the control
//!   task, which latches it in the controller at its next tick.
//!
//! [`Events`] is lock-free (atomics), so the control task never waits for the
//! fault tasks and the fault tasks never wait for the control task.

use core::sync::atomic::{AtomicBool, AtomicU8, Ordering};

use embedded_hal::digital::{InputPin, OutputPin};

use crate::controller::RawSample;
use crate::fault::Fault;
use crate::telemetry::Inputs;
use crate::units::DacCode;

/// The board's sensors and the current-reference output.
pub trait SensorFrontEnd {
    /// Read every counter and the latest ADC conversion (one control tick).
    fn sample(&mut self) -> RawSample;
    /// Write the current reference to the DAC (applied by the hardware at the
    /// next control-timer update, so the output instant does not jitter).
    fn write_current(&mut self, dac: DacCode);
    /// Is the drive's fault line asserted *now*? Read every tick: the EXTI
    /// task sees only edges, and a line that stays asserted raises none.
    /// A line that cannot be read counts as asserted.
    fn drive_fault_asserted(&mut self) -> bool;
}

/// Cuts the drive enable line from any priority, without owning the pin (on
/// the STM32 a write to the GPIO's bit set/reset register). Also used by the
/// panic and HardFault handlers.
pub trait DriveKill {
    /// Drive the enable line to its disabled level.
    fn kill(&mut self);
}

/// A digital input and the level that means "asserted".
#[derive(Debug)]
pub struct InputLine<P> {
    pin: P,
    active_low: bool,
}

impl<P: InputPin> InputLine<P> {
    /// `active_low`: the line is asserted when the pin reads low (an
    /// open-collector fault output with a pull-up).
    pub fn new(pin: P, active_low: bool) -> Self {
        Self { pin, active_low }
    }

    /// Is the line asserted? A pin that cannot be read counts as asserted
    /// (fail safe).
    pub fn asserted(&mut self) -> bool {
        match self.pin.is_high() {
            Ok(high) => high != self.active_low,
            Err(_) => true,
        }
    }

    /// The pin, e.g. to clear its EXTI pending bit.
    pub fn pin_mut(&mut self) -> &mut P {
        &mut self.pin
    }
}

/// What the fault tasks tell the control task, lock-free.
///
/// One instance lives in a `static`; the fault tasks (higher priority) write,
/// the control task reads and clears.
#[derive(Debug, Default)]
pub struct Events {
    fault: AtomicU8,
    origin_edge: AtomicBool,
    origin_level: AtomicBool,
    drive_fault_level: AtomicBool,
    origin_expected: AtomicBool,
}

impl Events {
    /// No fault, no edge; an origin edge is expected (start-up).
    pub const fn new() -> Self {
        Self {
            fault: AtomicU8::new(0),
            origin_edge: AtomicBool::new(false),
            origin_level: AtomicBool::new(false),
            drive_fault_level: AtomicBool::new(false),
            origin_expected: AtomicBool::new(true),
        }
    }

    /// Leave a fault for the control task; the first one wins until taken.
    pub fn raise(&self, fault: Fault) {
        let _ = self
            .fault
            .compare_exchange(0, fault.code(), Ordering::SeqCst, Ordering::SeqCst);
    }

    /// Is a fault waiting to be latched?
    pub fn fault_pending(&self) -> bool {
        self.fault.load(Ordering::SeqCst) != 0
    }

    /// Take the waiting fault (control task).
    pub fn take_fault(&self) -> Option<Fault> {
        Fault::from_code(self.fault.swap(0, Ordering::SeqCst))
    }

    /// Take the "origin switch rose while expected" flag (control task).
    pub fn take_origin_edge(&self) -> bool {
        self.origin_edge.swap(false, Ordering::SeqCst)
    }

    /// Is the origin switch asserted (as of its last edge)?
    pub fn origin_level(&self) -> bool {
        self.origin_level.load(Ordering::SeqCst)
    }

    /// Is the drive fault line asserted (as of its last edge)?
    pub fn drive_fault_level(&self) -> bool {
        self.drive_fault_level.load(Ordering::SeqCst)
    }

    /// Record the drive fault line's level as the control task read it this
    /// tick; an asserted line leaves [`Fault::DriveFault`] (level-sensitive:
    /// it is raised again every tick while the line stays asserted).
    pub fn set_drive_fault_level(&self, asserted: bool) {
        self.drive_fault_level.store(asserted, Ordering::SeqCst);
        if asserted {
            self.raise(Fault::DriveFault);
        }
    }

    /// Both input levels, for telemetry.
    pub fn inputs(&self) -> Inputs {
        Inputs::new(self.origin_level(), self.drive_fault_level())
    }

    /// Set by the control task every tick: may the origin switch rise now
    /// (homing, or the joint estimate near zero)?
    pub fn set_origin_expected(&self, expected: bool) {
        self.origin_expected.store(expected, Ordering::SeqCst);
    }

    /// See [`Events::set_origin_expected`].
    pub fn origin_expected(&self) -> bool {
        self.origin_expected.load(Ordering::SeqCst)
    }

    /// Record the input levels read at start-up, before the EXTI lines are
    /// armed (an asserted drive fault line has no edge to report it).
    pub fn init_levels(&self, origin: bool, drive_fault: bool) {
        self.origin_level.store(origin, Ordering::SeqCst);
        self.set_drive_fault_level(drive_fault);
    }
}

/// Drive-fault EXTI task body: if the line is asserted, cut the drive and
/// leave [`Fault::DriveFault`] for the control task.
pub fn on_drive_fault_edge<P: InputPin, K: DriveKill>(
    line: &mut InputLine<P>,
    kill: &mut K,
    events: &Events,
) -> Option<Fault> {
    let asserted = line.asserted();
    events.set_drive_fault_level(asserted);
    if asserted {
        kill.kill();
        Some(Fault::DriveFault)
    } else {
        None
    }
}

/// Origin-switch EXTI task body (both edges). A rising edge while the
/// control task expects one (homing, or the joint estimate within the origin
/// tolerance) is left for the control task; a rising edge anywhere else means
/// the counters no longer agree with the joint (lost counts, a slipped cable):
/// cut the drive and leave [`Fault::OriginDuringMotion`].
pub fn on_origin_edge<P: InputPin, K: DriveKill>(
    line: &mut InputLine<P>,
    kill: &mut K,
    events: &Events,
) -> Option<Fault> {
    let active = line.asserted();
    let was = events.origin_level.swap(active, Ordering::SeqCst);
    if !active || was {
        return None;
    }
    if events.origin_expected() {
        events.origin_edge.store(true, Ordering::SeqCst);
        None
    } else {
        kill.kill();
        events.raise(Fault::OriginDuringMotion);
        Some(Fault::OriginDuringMotion)
    }
}

/// The drive-enable output, written by the control task every tick.
#[derive(Debug)]
pub struct DriveEnable<P> {
    pin: P,
    enabled: bool,
}

impl<P: OutputPin> DriveEnable<P> {
    /// Take the pin and drive it to "disabled".
    pub fn new(pin: P) -> Self {
        let mut d = Self { pin, enabled: true };
        d.disable();
        d
    }

    /// Enable the drive if `want`, no fault is waiting in `events` and the
    /// drive's fault line is not asserted.
    ///
    /// A fault task may cut the line between the check and the write; the
    /// line is checked again after enabling and cut if a fault arrived, so an
    /// enable never outlives a fault by more than the two instructions
    /// between the write and the re-check (far below a drive's enable-input
    /// filter time). Returns the level left on the line.
    pub fn apply(&mut self, want: bool, events: &Events) -> bool {
        let blocked = |e: &Events| e.fault_pending() || e.drive_fault_level();
        if !want || blocked(events) {
            self.disable();
            return false;
        }
        if self.pin.set_high().is_err() {
            self.disable();
            return false;
        }
        if blocked(events) {
            self.disable();
            return false;
        }
        self.enabled = true;
        true
    }

    /// Cut the drive (a failed write is retried once; the fault tasks and
    /// the panic handler cut it through the set/reset register as well).
    pub fn disable(&mut self) {
        if self.pin.set_low().is_err() {
            let _ = self.pin.set_low();
        }
        self.enabled = false;
    }

    /// Level last written.
    pub fn is_enabled(&self) -> bool {
        self.enabled
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::board::mock::{CountingKill, MockIn, MockOut};

    #[test]
    fn drive_starts_disabled_and_a_pending_fault_blocks_enable() {
        let pin = MockOut::default();
        let mut drive = DriveEnable::new(pin.clone());
        assert_eq!((pin.low_count(), pin.high_count()), (1, 0));
        assert!(!pin.is_high());
        let events = Events::new();
        assert!(drive.apply(true, &events));
        assert!(pin.is_high());
        events.raise(Fault::DriveFault);
        assert!(!drive.apply(true, &events), "pending fault wins");
        assert!(!pin.is_high());
        assert_eq!(pin.high_count(), 1, "never raised while a fault waits");
        assert_eq!(events.take_fault(), Some(Fault::DriveFault));
        assert!(!drive.apply(false, &events));
        assert!(!drive.is_enabled());
    }

    #[test]
    fn fault_arriving_during_enable_is_caught_by_the_recheck() {
        static EVENTS: Events = Events::new();
        let events = &EVENTS;
        // The pin raises a fault the moment it is driven high, as a fault
        // task preempting right after the write would.
        let pin = MockOut::default().with_fault_on_high(events);
        let mut drive = DriveEnable::new(pin.clone());
        assert!(!drive.apply(true, events));
        assert!(!pin.is_high(), "re-check cut the line");
        assert_eq!(pin.high_count(), 1);
        assert_eq!(pin.low_count(), 2);
    }

    #[test]
    fn drive_fault_edge_cuts_and_reports_only_when_asserted() {
        let events = Events::new();
        let pin = MockIn::new(true); // active low: high = healthy
        let mut line = InputLine::new(pin.clone(), true);
        let mut kill = CountingKill::default();
        assert_eq!(on_drive_fault_edge(&mut line, &mut kill, &events), None);
        assert_eq!(kill.count, 0);
        pin.set(false);
        assert_eq!(
            on_drive_fault_edge(&mut line, &mut kill, &events),
            Some(Fault::DriveFault)
        );
        assert_eq!(kill.count, 1);
        assert!(events.drive_fault_level());
        assert_eq!(events.take_fault(), Some(Fault::DriveFault));
        assert_eq!(events.take_fault(), None, "taken once");
    }

    #[test]
    fn origin_edge_is_homing_input_when_expected_and_a_fault_otherwise() {
        let events = Events::new();
        let pin = MockIn::new(false);
        let mut line = InputLine::new(pin.clone(), false);
        let mut kill = CountingKill::default();
        // Expected (start-up default): recorded for the control task.
        pin.set(true);
        assert_eq!(on_origin_edge(&mut line, &mut kill, &events), None);
        assert!(events.take_origin_edge());
        assert!(!events.take_origin_edge());
        // Falling edge: level only.
        pin.set(false);
        assert_eq!(on_origin_edge(&mut line, &mut kill, &events), None);
        assert!(!events.origin_level());
        // Not expected: drive cut, fault left.
        events.set_origin_expected(false);
        pin.set(true);
        assert_eq!(
            on_origin_edge(&mut line, &mut kill, &events),
            Some(Fault::OriginDuringMotion)
        );
        assert_eq!(kill.count, 1);
        assert!(!events.take_origin_edge());
        assert_eq!(events.take_fault(), Some(Fault::OriginDuringMotion));
        // A repeated interrupt at the same level (bounce) is not a new edge.
        assert_eq!(on_origin_edge(&mut line, &mut kill, &events), None);
        assert_eq!(kill.count, 1);
    }

    #[test]
    fn unreadable_input_counts_as_asserted_and_first_fault_wins() {
        let pin = MockIn::new(true).failing();
        let mut line = InputLine::new(pin, true);
        assert!(line.asserted());
        let events = Events::new();
        events.raise(Fault::Overrun);
        events.raise(Fault::DriveFault);
        assert_eq!(events.take_fault(), Some(Fault::Overrun));
        events.init_levels(false, true);
        assert_eq!(events.take_fault(), Some(Fault::DriveFault));
        assert_eq!(events.inputs(), Inputs::new(false, true));
    }
}
